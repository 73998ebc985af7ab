"""A scenario can run code (UserFunction): `flexshell check` reads that code without running it unless
given --trust, and a broken user file is reported with its name, not with a traceback."""

import pytest

from tests.safety.conftest import RAMP, line_of

USER_CODE = """\
import pathlib
pathlib.Path({marker!r}).write_text("ran")
{body}
def unload(t, signals):
    return {{"command": -signals["position"]}}
"""


def scene(tmp_path, body=""):
    marker = tmp_path / "user_code_ran"
    (tmp_path / "fsw.py").write_text(USER_CODE.format(marker=str(marker), body=body))
    text = RAMP.replace("connections:", f"""\
  fsw:
    type: UserFunction
    rate: 1 Hz
    config:
      function: {tmp_path / 'fsw.py'}:unload
      inputs: {{position: {{unit: m}}}}
      outputs: {{command: {{unit: m/s}}}}
connections:
  - position.y -> fsw.position""")
    path = tmp_path / "scene.yaml"
    path.write_text(text)
    return path, text, marker


def test_check_reads_user_code_without_running_it(tmp_path, cli):
    path, _, marker = scene(tmp_path)
    code, out, err = cli("check", path)
    assert code == 0, err
    assert not marker.exists(), "check ran the scenario's user code"
    code, out, err = cli("check", path, "--trust")
    assert code == 0, err
    assert marker.exists(), "--trust imports the user code"


@pytest.mark.parametrize("body, expected", [
    ("raise RuntimeError('no hardware here')", "RuntimeError: no hardware here"),
    ("import no_such_module_for_flexshell", "ModuleNotFoundError"),
])
def test_run_reports_a_user_file_that_fails_to_import(tmp_path, cli, body, expected):
    path, text, _ = scene(tmp_path, body)
    code, _, err = cli("run", path, "-o", tmp_path / "out.h5", "--quiet")
    assert code == 1 and "Traceback" not in err, err
    assert f"{path}:{line_of(text, '  fsw:')}: models.fsw" in err and expected in err and "fsw.py" in err, err
    assert not (tmp_path / "out.h5").exists()
