"""The warning channel (shell/diagnostics.py, issue 34): scenario and deck diagnostics reach the user as
``flexshell VERB: warning: FILE:LINE: KEY: ...``, once each, never as Python's ``x.py:569: UserWarning`` with a
line of flexshell's source; what no body can be (an inertia violating the triangle inequality) is refused."""

import shutil

from tests.safety.conftest import RAMP, ROOT, flexshell, line_of

TRIANGLE = """\
name: triangle
multibody:
  bodies:
    - name: bus
      hinge: free
      mass: 10 kg
      inertia: "[1, 1, 5] kg*m^2"
stop:
  time: 1 s
"""

# a Profile that jumps from 1 m/s to 0 after its last breakpoint: allowed, and worth a warning
JUMP = RAMP.replace("""  rate:
    type: Constant
    config: {unit: m/s}
    parameters: {value: 1 m/s}
""", """  rate:
    type: Profile
    config: {unit: m/s}
    parameters:
      times: "[0, 1] s"
      c0: "[1] m/s"
""")


def no_python_warning(err):
    assert "Warning:" not in err and ".py:" not in err and "Traceback" not in err, err


def test_an_inertia_no_body_has_is_refused_naming_file_line_and_key(put, cli):
    scene = put("triangle.yaml", TRIANGLE)
    code, _, err = cli("check", scene)
    assert code == 1, err
    assert f"{scene}:{line_of(TRIANGLE, '    - name: bus')}: multibody.bodies[0](bus)" in err, err
    assert "triangle inequality" in err and "[1.0, 1.0, 5.0]" in err, err
    no_python_warning(err)
    disk = put("disk.yaml", TRIANGLE.replace("[1, 1, 5]", "[2.5, 2.5, 5]"))  # a thin disk: the equality
    assert cli("check", disk)[0] == 0


def test_a_model_warning_is_a_flexshell_message_with_its_location_once(put, cli):
    scene = put("jump.yaml", JUMP)
    code, out, err = cli("check", scene)
    assert code == 0, err
    expected = f"flexshell check: warning: {scene}:{line_of(JUMP, '  rate:')}: models.rate: model rate: Profile jumps"
    assert err.count(expected) == 1, err
    no_python_warning(err)


def test_deck_warnings_are_flexshell_messages_even_when_quiet(cli, tmp_path):
    deck = tmp_path / "five.dat"
    shutil.copy(ROOT / "configs" / "fem" / "five_particle.dat", deck)
    code, _, err = cli("fem2modal", deck, "--modes", "2", "--damping", "1.5", "-q", "-o", tmp_path / "five.h5")
    assert code == 0, err
    assert err.startswith("flexshell fem2modal: warning: --damping 1.5: ratios >= 1"), err
    no_python_warning(err)


def test_a_real_process_prints_no_python_warning(put, tmp_path):
    result = flexshell(["check", put("jump.yaml", JUMP)], cwd=tmp_path, timeout=300)
    assert result.returncode == 0, result.stderr
    assert "flexshell check: warning:" in result.stderr
    no_python_warning(result.stderr)
