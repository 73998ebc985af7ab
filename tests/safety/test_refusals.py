"""The refusal catalogue (issue 17): every bad input is refused by the command line with exit status 1,
a message naming the file, the line and the key, and no traceback.

Each case is a change of the tiny ramp scene (``RAMP``, conftest), or of the command line, or of a
campaign; ``key`` is the dotted key the message must name and ``needle`` a text on the line it must
name (None: the refusal concerns the command line or the whole file, and the message names that).
"""

import os
import re

import h5py
import pytest

from tests.safety.conftest import RAMP, ROOT, line_of

BOMB = "".join(f"{a}: &{a} [{', '.join([f'*{p}'] * 9) if p else ', '.join(['x'] * 9)}]\n"
               for p, a in zip(["", "a", "b", "c", "d", "e"], ["a", "b", "c", "d", "e", "f"]))

# anchors nesting each other 40 levels deeper at every link: 1600 levels once the aliases are followed
ALIAS_CHAIN = "[&a0 x, " + ", ".join(f"&a{i} " + "[" * 40 + f"*a{i - 1}" + "]" * 40 for i in range(1, 40)) + "]"
FLOW_BOMB = "[&a [x, x, x, x, x, x, x, x, x], " + ", ".join(
    f"&{a} [{', '.join([f'*{p}'] * 9)}]" for p, a in zip("abcde", "bcdef")) + "]"


def change(old, new):
    assert old in RAMP, old
    return RAMP.replace(old, new, 1)


# (id, scenario text, extra check arguments, key named, text on the line named, further text expected)
SCENARIO_CASES = [
    # a bare number under rate: was read as a period in seconds
    ("rate-bare-integer", change("rate: 10 Hz", "rate: 10"), [], "models.sensor.rate", "rate: 10", "10 Hz"),
    ("rate-bare-float", change("rate: 10 Hz", "rate: 2.5"), [], "models.sensor.rate", "rate: 2.5", "Hz"),
    ("rate-bare-text", change("rate: 10 Hz", "rate: '10'"), [], "models.sensor.rate", "rate: '10'", "Hz"),
    ("log-rate-bare", change("  rate: 10 Hz\n  signals", "  rate: 10\n  signals"), [], "log.rate", "  rate: 10", "Hz"),
    ("log-signal-rate-bare", change("signals: [sensor.y]", "signals: [{signal: sensor.y, rate: 5}]"), [],
     "log.signals[0].rate", "signals: [", "Hz"),
    ("rate-inf", change("rate: 10 Hz", "rate: .inf"), [], "models.sensor.rate", "rate: .inf", "finite"),
    ("rate-inf-hz", change("rate: 10 Hz", "rate: .inf Hz"), [], "models.sensor.rate", "rate: .inf Hz", None),
    ("rate-nan", change("rate: 10 Hz", "rate: .nan"), [], "models.sensor.rate", "rate: .nan", None),
    ("rate-absurd", change("rate: 10 Hz", "rate: 1e12 Hz"), [], "models.sensor.rate", "rate: 1e12 Hz", None),
    ("model-samples-absurd", change("rate: 10 Hz", "rate: 100 MHz"), [], "models.sensor.rate", "rate: 100 MHz",
     "samples"),
    ("log-rate-absurd", change("  rate: 10 Hz\n  signals", "  rate: 1e12 Hz\n  signals"), [], "log.rate",
     "rate: 1e12 Hz", None),
    ("log-samples-absurd", change("time: 2 s", "time: 1e6 s").replace("  rate: 10 Hz\n  signals",
                                                                      "  rate: 1 kHz\n  signals"),
     [], "log.rate", "rate: 1 kHz", "samples"),
    ("stop-inf", change("time: 2 s", "time: .inf"), [], "stop.time", "time: .inf", "finite"),
    ("stop-1e999", change("time: 2 s", "time: 1e999 s"), [], "stop.time", "time: 1e999 s", "finite"),
    ("stop-nan", change("time: 2 s", "time: .nan"), [], "stop.time", "time: .nan", None),
    ("stop-nan-text", change("time: 2 s", "time: nan s"), [], "stop.time", "time: nan s", None),
    ("step-huge", change("step: 0.01 s", "step: 1e300 s"), [], "integrator.step", "step: 1e300 s", "longer"),
    ("step-count-absurd", change("step: 0.01 s", "step: 1e-12 s"), [], "integrator.step", "step: 1e-12 s", "steps"),
    ("method-list", change("method: rk4", "method: [rk4]"), [], "integrator.method", "method: [rk4]", "list"),
    ("method-mapping", change("method: rk4", "method: {a: 1}"), [], "integrator.method", "method: {a: 1}", None),
    ("method-misspelt", change("method: rk4", "method: rk5"), [], "integrator.method", "method: rk5",
     "did you mean"),
    ("option-nan", change("step: 0.01 s", "step: 0.01 s\n  options: {rtol: .nan}"), [],
     "integrator.options.rtol", "options:", None),
    ("option-negative", change("step: 0.01 s", "step: 0.01 s\n  options: {atol: -1}"), [],
     "integrator.options.atol", "options:", None),
    ("option-inf", change("step: 0.01 s", "step: 0.01 s\n  options: {max_step: .inf}"), [],
     "integrator.options.max_step", "options:", None),
    ("initial-nan", change("config: {unit: m}\n  sensor", "config: {unit: m}\n    initial: {x: .nan}\n  sensor"),
     [], "models.position.initial.x", "initial: {x: .nan}", None),
    ("parameter-nan", change("parameters: {value: 1 m/s}", "parameters: {value: .nan}"), [],
     "models.rate.parameters.value", "parameters: {value: .nan}", None),
    ("key-is-a-list", RAMP + "? [a, b]\n: 1\n", [], None, "? [a, b]", "key"),
    ("key-is-a-mapping", RAMP + "? {a: 1}\n: 1\n", [], None, "? {a: 1}", "key"),
    ("deep-list", RAMP + "description: " + "[" * 3000 + "]" * 3000 + "\n", [], None, "description:", "nested"),
    ("deep-mapping", RAMP + "description: " + "{a: " * 2000 + "1" + "}" * 2000 + "\n", [], None,
     "description:", "nested"),
    ("deep-block", RAMP + "description:\n" + "".join(" " * k + "- \n" for k in range(0, 400, 2)), [], None,
     None, "nested"),
    ("alias-bomb", RAMP + BOMB + "g: [*f, *f, *f, *f, *f, *f, *f, *f, *f]\n", [], None, "f: &f", "aliases"),
    # --set: the message names the file and the override (a command-line value has no line)
    ("set-stop-inf", RAMP, ["--set", "stop.time=.inf"], "stop.time", "time: 2 s", "finite"),
    ("set-method-list", RAMP, ["--set", "integrator.method=[rk4]"], "integrator.method", "method: rk4", "list"),
    ("set-deep", RAMP, ["--set", "seed=" + "[" * 3000], "--set", None, "nested"),
    ("set-bare-rate", RAMP, ["--set", "sensor.rate=10"], "models.sensor.rate", "    rate: 10 Hz", "Hz"),
    ("set-nan-rate", RAMP, ["--set", "sensor.rate=.nan"], "models.sensor.rate", "    rate: 10 Hz", None),
    ("set-step-huge", RAMP, ["--set", "integrator.step=1e300 s"], "integrator.step", "step: 0.01 s", "longer"),
    ("set-log-rate-absurd", RAMP, ["--set", "log.rate=1e12 Hz"], "log.rate", "  rate: 10 Hz", None),
    ("set-initial-nan", RAMP, ["--set", "position.initial.x=.nan"], "models.position.initial.x", "position:",
     None),
    ("set-model-is-text", change("  position:\n    type: Integrator\n    config: {unit: m}", "  position: x"),
     ["--set", "position.initial.x=1"], "--set position.initial.x=1", None, "not a mapping"),
    ("period-samples-absurd", change("rate: 10 Hz", "period: 1 ns"), [], "models.sensor.period", "period: 1 ns",
     "samples"),
    ("period-inf", change("rate: 10 Hz", "period: .inf"), [], "models.sensor.period", "period: .inf", None),
    ("offset-nan", change("rate: 10 Hz", "rate: 10 Hz\n    offset: .nan"), [], "models.sensor.offset",
     "offset: .nan", "NaN"),
    ("log-rate-nan", change("  rate: 10 Hz\n  signals", "  rate: .nan\n  signals"), [], "log.rate", "rate: .nan",
     None),
    ("log-rate-inf", change("  rate: 10 Hz\n  signals", "  rate: .inf Hz\n  signals"), [], "log.rate",
     "rate: .inf Hz", None),
    ("log-signal-rate-inf", change("signals: [sensor.y]", "signals: [{signal: sensor.y, rate: .inf Hz}]"), [],
     "log.signals[0].rate", "signals: [", None),
    ("stop-steps-absurd", change("time: 2 s", "time: 1e300 s"), [], "integrator.step", "step: 0.01 s", "steps"),
    ("events-tolerance-inf", RAMP + "events:\n  tolerance: .inf\n", [], "events.tolerance", "tolerance:", None),
    ("option-max-step-nan", change("step: 0.01 s", "step: 0.01 s\n  options: {max_step: .nan}"), [],
     "integrator.options.max_step", "options:", None),
    ("alias-chain-depth", RAMP + "description: " + ALIAS_CHAIN + "\n", [], None, "description:", "through aliases"),
    ("set-unclosed-list-value", RAMP, ["--set", "sensor.sigma=[[["], "models.sensor.parameters.sigma",
     "parameters: {sigma: 0.01 m}", "[[["),
    ("set-alias-bomb", RAMP, ["--set", "description=" + FLOW_BOMB], "--set description=", None, "aliases"),
    ("set-control-character", RAMP, ["--set", "name=a\x07b"], "--set name=", None, "control characters"),
]

# Refusals that the code before issue 17 already made; kept in the catalogue (the issue asks for "the
# earlier ones" too) so that the new checks do not lose them or their file:line: key.
KEPT_CASES = [
    ("rate-zero", change("rate: 10 Hz", "rate: 0 Hz"), [], "models.sensor.rate", "rate: 0 Hz", None),
    ("rate-negative", change("rate: 10 Hz", "rate: -5 Hz"), [], "models.sensor.rate", "rate: -5 Hz", None),
    ("rate-not-a-rate", change("rate: 10 Hz", "rate: fast"), [], "models.sensor.rate", "rate: fast", None),
    ("rate-wrong-unit", change("rate: 10 Hz", "rate: 10 kg"), [], "models.sensor.rate", "rate: 10 kg", None),
    ("rate-list", change("rate: 10 Hz", "rate: [10 Hz]"), [], "models.sensor.rate", "rate: [10 Hz]", None),
    ("period-negative", change("rate: 10 Hz", "period: -1 s"), [], "models.sensor.period", "period: -1 s", None),
    ("rate-and-period", change("rate: 10 Hz", "rate: 10 Hz\n    period: 0.1 s"), [], "models.sensor.period",
     "period: 0.1 s", "not both"),
    ("stop-negative", change("time: 2 s", "time: -1 s"), [], "stop.time", "time: -1 s", None),
    ("stop-zero", change("time: 2 s", "time: 0 s"), [], "stop.time", "time: 0 s", None),
    ("stop-wrong-unit", change("time: 2 s", "time: 5 m"), [], "stop.time", "time: 5 m", None),
    ("stop-list", change("time: 2 s", "time: [1, 2]"), [], "stop.time", "time: [1, 2]", None),
    ("stop-events-text", change("time: 2 s", "time: 2 s\n  events: sensor.hit"), [], "stop.events",
     "events: sensor.hit", None),
    ("step-nan", change("step: 0.01 s", "step: .nan"), [], "integrator.step", "step: .nan", None),
    ("step-negative", change("step: 0.01 s", "step: -0.01 s"), [], "integrator.step", "step: -0.01 s", None),
    ("step-zero", change("step: 0.01 s", "step: 0 s"), [], "integrator.step", "step: 0 s", None),
    ("step-wrong-unit", change("step: 0.01 s", "step: 1 kg"), [], "integrator.step", "step: 1 kg", None),
    ("method-number", change("method: rk4", "method: 4"), [], "integrator.method", "method: 4", None),
    ("option-unknown", change("step: 0.01 s", "step: 0.01 s\n  options: {speed: 2}"), [],
     "integrator.options.speed", "options:", None),
    ("events-detection-list", RAMP + "events:\n  detection: [subdivided]\n", [], "events.detection",
     "detection:", None),
    ("events-tolerance-nan", RAMP + "events:\n  tolerance: .nan\n", [], "events.tolerance", "tolerance:", None),
    ("events-tolerance-negative", RAMP + "events:\n  tolerance: -1 s\n", [], "events.tolerance", "tolerance:",
     None),
    ("seed-negative", change("seed: 0", "seed: -1"), [], "seed", "seed: -1", None),
    ("seed-text", change("seed: 0", "seed: abc"), [], "seed", "seed: abc", None),
    ("seed-float", change("seed: 0", "seed: 1.5"), [], "seed", "seed: 1.5", None),
    ("duplicate-key", RAMP + "seed: 3\n", [], None, "seed: 3", "duplicate key"),
    ("unknown-top-key", RAMP + "stopp: {time: 2 s}\n", [], "stopp", "stopp:", "did you mean"),
    ("unknown-model-key", change("type: Integrator", "type: Integrator\n    ratee: 10 Hz"), [],
     "models.position.ratee", "ratee:", "did you mean"),
    ("models-a-list", change("models:\n  rate:", "models:\n- rate:").replace("\n  position:", "\n- position:"),
     [], "models", "models:", None),
    ("model-not-a-mapping", change("  position:\n    type: Integrator\n    config: {unit: m}",
                                   "  position: Integrator"), [], "models.position", "position: Integrator", None),
    ("model-type-list", change("type: Integrator", "type: [Integrator]"), [], "models.position.type",
     "type: [Integrator]", None),
    ("model-type-unknown", change("type: Integrator", "type: Integrater"), [], "models.position.type",
     "type: Integrater", "did you mean"),
    ("model-name-invalid", change("  position:\n", "  posi-tion:\n"), [], "models.posi-tion", "posi-tion:", None),
    ("connection-number", change("  - rate.y -> position.u", "  - 42"), [], "connections[0]", "  - 42", None),
    ("connection-no-arrow", change("  - rate.y -> position.u", "  - rate.y position.u"), [], "connections[0]",
     "rate.y position.u", None),
    ("connections-mapping", change("connections:\n  - rate.y -> position.u\n  - position.y -> sensor.u",
                                   "connections:\n  a: b"), [], "connections", "connections:", None),
    ("log-signals-text", change("signals: [sensor.y]", "signals: sensor.y"), [], "log.signals",
     "signals: sensor.y", None),
    ("log-file-list", change("signals: [sensor.y]", "signals: [sensor.y]\n  file: [a.h5]"), [], "log.file",
     "file: [a.h5]", None),
    ("invalid-yaml", change("method: rk4", "method: [rk4"), [], None, None, "not valid YAML"),
    ("top-level-list", "- a\n- b\n", [], None, "- a", "mapping at the top level"),
    ("set-without-equals", RAMP, ["--set", "stop.time"], "--set stop.time", None, "key.path=value"),
    ("set-unclosed-list", RAMP, ["--set", "controller.kp=[[["], "--set controller.kp=[[[", None,
     "neither a model"),
    ("set-into-list", RAMP, ["--set", "log.signals.x=1"], "--set log.signals.x=1", None, "not a mapping"),
    ("set-stop-negative", RAMP, ["--set", "stop.time=-3 s"], "stop.time", "time: 2 s", None),
    ("set-unknown-section", RAMP, ["--set", "stopp.time=3 s"], "--set stopp.time=3 s", None, "known"),
    ("set-empty-key", RAMP, ["--set", "=5"], "--set =5", None, "key.path=value"),
    ("set-multibody-missing", RAMP, ["--set", "multibody.bus.mass=3 kg"], "--set multibody.bus.mass=3 kg",
     None, "neither a model"),
]


@pytest.mark.parametrize("name, text, extra, key, needle, expected", SCENARIO_CASES + KEPT_CASES,
                         ids=[c[0] for c in SCENARIO_CASES] + [f"kept-{c[0]}" for c in KEPT_CASES])
def test_check_refuses(name, text, extra, key, needle, expected, put, cli):
    path = put("scene.yaml", text)
    code, out, err = cli("check", path, *extra)
    assert code == 1, (out, err)
    assert "Traceback" not in err
    assert str(path) in err
    if needle is not None:
        assert f"{path}:{line_of(text, needle)}:" in err, err
    if key is not None:
        assert key in err, err
    if expected is not None:
        assert expected in err, err
    assert len(err) < 2000, "a refusal prints the value cut short"


FILE_CASES = [
    ("binary", b"\x00\x01\x02name: x\n", "not a text file"),
    ("utf16", RAMP.encode("utf-16"), "UTF-16"),
    ("utf16-big-endian", b"\xfe\xff" + RAMP.encode("utf-16-be"), "UTF-16"),
    ("latin1", "name: caf\xe9\n".encode("latin-1"), "not UTF-8"),
    ("control-character", b"name: a\x07b\n", "not a text file"),
    ("huge", b"# " + b"x" * (17 * 2**20) + b"\n", "larger than"),
]


@pytest.mark.parametrize("name, content, expected", FILE_CASES, ids=[c[0] for c in FILE_CASES])
def test_check_refuses_files_that_are_not_yaml_text(name, content, expected, put, cli):
    path = put("scene.yaml", content)
    code, _, err = cli("check", path)
    assert code == 1 and "Traceback" not in err
    assert f"{path}:1:" in err and expected in err, err


def test_check_refuses_a_directory_and_a_missing_file(tmp_path, cli):
    for path, expected in ((tmp_path, "is a directory"), (tmp_path / "missing.yaml", "No such file")):
        code, _, err = cli("check", path)
        assert code == 1 and "Traceback" not in err
        assert str(path) in err and expected in err, err


# ------------------------------------------------------------------------------------------------
# flexshell run: outputs and the stop time, refused before the scene is built
RUN_CASES = [
    ("t-final-negative", ["--t-final", "-5"], "--t-final", "a finite number of seconds"),
    ("t-final-nan", ["--t-final", "nan"], "--t-final", "a finite number of seconds"),
    ("t-final-inf", ["--t-final", "inf s"], "--t-final", "a finite number of seconds"),
    ("t-final-wrong-unit", ["--t-final", "5 kg"], "--t-final", None),
    ("t-final-text", ["--t-final", "soon"], "--t-final", None),
    ("t-final-zero", ["--t-final", "0"], "--t-final", "a finite number of seconds"),
    ("t-final-minus-inf", ["--t-final=-inf"], "--t-final", "a finite number of seconds"),
    ("t-final-absurd-steps", ["--t-final", "1e9 s"], "integrator.step", "steps"),
    ("t-final-absurd-samples", ["--t-final", "1e6 s", "--set", "integrator.step=1 s", "--set", "log.rate=1 kHz"],
     "log.rate", "samples"),
]


@pytest.mark.parametrize("name, extra, key, expected", RUN_CASES, ids=[c[0] for c in RUN_CASES])
def test_run_refuses_stop_times(name, extra, key, expected, put, cli, tmp_path):
    path = put("scene.yaml", RAMP)
    code, out, err = cli("run", path, "-o", tmp_path / "out.h5", "--quiet", *extra)
    assert code == 1 and "Traceback" not in err, err
    assert str(path) in err and key in err, err
    if expected:
        assert expected in err
    assert not (tmp_path / "out.h5").exists()


def _campaign_results(path):
    with h5py.File(path, "w") as f:
        f.attrs["format"] = "flexshell-campaign"


OUTPUT_CASES = [
    ("output-is-the-scenario", lambda d: d / "scene.yaml", "the scenario itself"),
    ("output-is-text", lambda d: (d / "notes.txt").write_text("keep me") and d / "notes.txt", "not an HDF5 file"),
    ("output-is-a-campaign", lambda d: _campaign_results(d / "c.h5") or d / "c.h5", "flexshell-campaign"),
    ("output-is-a-directory", lambda d: (d / "dir").mkdir() or d / "dir", "is a directory"),
    ("output-in-missing-directory", lambda d: d / "nowhere" / "out.h5", "does not exist"),
]


@pytest.mark.parametrize("name, make, expected", OUTPUT_CASES, ids=[c[0] for c in OUTPUT_CASES])
def test_run_refuses_outputs(name, make, expected, put, cli, tmp_path):
    scenario = put("scene.yaml", RAMP)
    output = make(tmp_path)
    before = output.read_bytes() if output.is_file() else None
    code, _, err = cli("run", scenario, "-o", output, "--quiet")
    assert code == 1 and "Traceback" not in err, err
    assert str(output) in err and expected in err, err
    if before is not None:
        assert output.read_bytes() == before, "the file refused as output is untouched"


def test_run_refuses_a_log_file_key_in_a_missing_directory(put, cli, tmp_path, monkeypatch):
    text = change("signals: [sensor.y]", "signals: [sensor.y]\n  file: nowhere/out.h5")
    scenario = put("scene.yaml", text)
    monkeypatch.chdir(tmp_path)
    code, _, err = cli("run", scenario, "--quiet")
    assert code == 1 and "Traceback" not in err
    assert f"{scenario}:{line_of(text, 'file: nowhere')}: log.file" in err and "does not exist" in err, err


def test_run_refuses_save_state_in_a_missing_directory(put, cli, tmp_path):
    scenario = put("scene.yaml", RAMP)
    code, _, err = cli("run", scenario, "-o", tmp_path / "o.h5", "--save-state", tmp_path / "no" / "r.h5")
    assert code == 1 and "Traceback" not in err
    assert str(tmp_path / "no" / "r.h5") in err and "does not exist" in err, err


@pytest.mark.skipif(os.geteuid() == 0, reason="root writes into read-only directories")
def test_run_refuses_a_read_only_directory(put, cli, tmp_path):
    scenario = put("scene.yaml", RAMP)
    locked = tmp_path / "locked"
    locked.mkdir(mode=0o555)
    code, _, err = cli("run", scenario, "-o", locked / "out.h5", "--quiet")
    assert code == 1 and "not writable" in err


LINEARIZE_CASES = [
    ("output-is-the-scenario", lambda d: ["-o", d / "scene.yaml"], "the scenario itself"),
    ("output-is-text", lambda d: ["-o", (d / "a.txt").write_text("keep") and d / "a.txt"], "not an HDF5 file"),
    ("mat-in-missing-directory", lambda d: ["-o", d / "lin.h5", "--mat", d / "no" / "lin.mat"], "does not exist"),
    ("at-nan", lambda d: ["-o", d / "lin.h5", "--at", "nan"], "--at"),
    ("at-negative", lambda d: ["-o", d / "lin.h5", "--at=-1"], "--at"),
]


@pytest.mark.parametrize("name, arguments, expected", LINEARIZE_CASES, ids=[c[0] for c in LINEARIZE_CASES])
def test_linearize_refuses_outputs_and_times_first(name, arguments, expected, put, cli, tmp_path):
    scenario = put("scene.yaml", RAMP)
    before = scenario.read_text()
    code, _, err = cli("linearize", scenario, "--inputs", "rate.y", "--outputs", "sensor.y", *arguments(tmp_path))
    assert code == 1 and "Traceback" not in err, err
    assert expected in err, err
    assert scenario.read_text() == before and not (tmp_path / "lin.h5").exists()


def test_plot_refuses_an_image_in_a_missing_directory(cli, tmp_path):
    from tests.safety.test_logs import write_log

    write_log(tmp_path / "run.h5")
    code, _, err = cli("plot", tmp_path / "run.h5", "-o", tmp_path / "no" / "run.png")
    assert code == 1 and "Traceback" not in err and "does not exist" in err, err


def test_report_refuses_an_output_that_is_a_file(cli, tmp_path, put):
    from shell.montecarlo.campaign import load_campaign
    from shell.montecarlo.results import open_results

    put("scene.yaml", RAMP)
    results = open_results(tmp_path / "out.h5", load_campaign(put("campaign.yaml", CAMPAIGN), validate=False))
    results.close("partial")
    notes = put("notes.txt", "keep me")
    code, _, err = cli("report", tmp_path / "out.h5", "-o", notes)
    assert code == 1 and "Traceback" not in err and "not a directory" in err, err
    assert notes.read_text() == "keep me"


# ------------------------------------------------------------------------------------------------
# user code: checked without being run
USER_CODE_CASES = [
    ("syntax-error", "def unload(t, s:\n    return {}\n", "fsw.py:unload", "syntax error"),
    # refused before issue 17 too (by importing the file; now by reading it)
    ("kept-missing-file", None, "nowhere.py:unload", "not found"),
    ("kept-name-not-defined", "def other(t, s):\n    return {}\n", "fsw.py:unload", "has no 'unload'"),
    ("kept-no-colon", "def unload(t, s):\n    return {}\n", "fsw.py", "expected 'file.py:name'"),
    ("kept-no-module", None, "no_such_module_for_flexshell:unload", "no module"),
]


@pytest.mark.parametrize("name, code_text, function, expected", USER_CODE_CASES, ids=[c[0] for c in USER_CODE_CASES])
def test_check_refuses_user_functions(name, code_text, function, expected, put, cli, tmp_path):
    if code_text is not None:
        put("fsw.py", code_text)
    if function.startswith("fsw.py") or function.startswith("nowhere"):
        function = str(tmp_path / function)
    text = RAMP.replace("connections:", f"""\
  fsw:
    type: UserFunction
    rate: 1 Hz
    config:
      function: {function}
      inputs: {{position: {{unit: m}}}}
      outputs: {{command: {{unit: m/s}}}}
connections:""")
    scenario = put("scene.yaml", text)
    code, _, err = cli("check", scenario)
    assert code == 1 and "Traceback" not in err, err
    assert f"{scenario}:{line_of(text, '  fsw:')}: models.fsw" in err and expected in err, err


# ------------------------------------------------------------------------------------------------
# a port driven twice: a controller attached to the bus whose torque also commands another model
def test_check_refuses_an_attached_output_also_wired_elsewhere(put, cli):
    demo = (ROOT / "configs" / "demo_attitude_hold.yaml").read_text()
    text = demo.replace("\nintegrator:", """
  wheels_command:                 # stands for a wheel cluster commanded by the same torque
    type: Gain
    config: {unit: N*m, shape: [3]}
connections:
  - controller.torque -> wheels_command.u

integrator:""", 1)
    scenario = put("scene.yaml", text)
    code, _, err = cli("check", scenario)
    assert code == 1 and "Traceback" not in err, err
    assert f"{scenario}:{line_of(text, 'attach: {node: acs}')}" in err, err
    assert "controller.torque" in err and "wheels_command.u" in err and "twice" in err, err


DEMO = (ROOT / "configs" / "demo_attitude_hold.yaml").read_text()
SECOND_CONTROLLER = """
  controller2:
    type: PdAttitudeController
    rate: 10 Hz
    attach: {node: acs}
    parameters: {kp: "[1, 1, 1] N*m/rad", kd: "[1, 1, 1] N*m*s/rad", attitude_command: [1, 0, 0, 0]}

integrator:"""
ENGINE_CASES = [
    ("multibody-initial-inf", DEMO.replace('"[2, -1, 3] deg/s"', '"[1e999, -1, 3] deg/s"'),
     "multibody.bodies[0](bus).initial.angular_velocity", "angular_velocity:", "not finite"),
    ("multibody-initial-nan", DEMO.replace('"[2, -1, 3] deg/s"', '"[NaN, -1, 3] deg/s"'),
     "multibody.bodies[0](bus).initial.angular_velocity", "angular_velocity:", "not finite"),
    ("kept-multibody-mass-inf", DEMO.replace("mass: 500 kg", "mass: 1e999 kg"), "multibody.bodies[0](bus)",
     "- name: bus", "finite"),  # the engine's own check names the body's line
]


@pytest.mark.parametrize("name, text, key, needle, expected", ENGINE_CASES, ids=[c[0] for c in ENGINE_CASES])
def test_check_refuses_engine_values(name, text, key, needle, expected, put, cli):
    scenario = put("scene.yaml", text)
    code, _, err = cli("check", scenario)
    assert code == 1 and "Traceback" not in err, err
    assert f"{scenario}:{line_of(text, needle)}: {key}" in err and expected in err, err


def test_check_refuses_two_attachments_driving_one_node_input(put, cli):
    """Kept from before issue 17: the diagram refuses an input driven twice, naming both lines."""
    text = DEMO.replace("\nintegrator:", SECOND_CONTROLLER, 1)
    scenario = put("scene.yaml", text)
    code, _, err = cli("check", scenario)
    assert code == 1 and "Traceback" not in err, err
    assert "driven twice" in err and f"{scenario}:{line_of(text, 'attach: {node: acs}  ')}" in err, err
    assert f"{scenario}:{line_of(text, '  controller2:') + 3}" in err, err


def test_check_accepts_the_attached_controller_alone(cli):
    """The refusal above is about the second use, not about attach (the shipped demo checks)."""
    code, out, err = cli("check", ROOT / "configs" / "demo_attitude_hold.yaml")
    assert code == 0, err


# ------------------------------------------------------------------------------------------------
# campaigns
CAMPAIGN = """\
name: ramp_campaign
scenario: scene.yaml
runs: 4
seed: 7
dispersions:
  rate.value: {distribution: normal, mean: 100 cm/s, sigma: 10 cm/s}
metrics:
  final_position: {signal: sensor.y, statistic: final, unit: m}
"""

CAMPAIGN_CASES = [
    ("runs-absurd", CAMPAIGN.replace("runs: 4", "runs: 10000000000"), [], "runs", "runs: 1", "at most"),
    ("campaign-yaml-error", CAMPAIGN.replace("runs: 4", "runs: [4"), [], None, None, "not valid YAML"),
    ("campaign-scenario-binary", CAMPAIGN, [], "scenario", "scenario:", "not a text file"),
    ("campaign-utf16", CAMPAIGN.encode("utf-16"), [], None, None, "UTF-16"),
    # found by the fuzzer: a NUL in the file name was a bare ValueError (embedded null byte)
    ("campaign-scenario-nul", CAMPAIGN.replace("scenario: scene.yaml", 'scenario: "scene\\0.yaml"'), [], "scenario",
     "scenario:", "expected the scenario's file name"),
    ("campaign-scenario-list", CAMPAIGN.replace("scenario: scene.yaml", "scenario: [scene.yaml]"), [], "scenario",
     "scenario:", "expected the scenario's file name"),
    ("kept-runs-zero", CAMPAIGN.replace("runs: 4", "runs: 0"), [], "runs", "runs: 0", None),
    ("kept-runs-text", CAMPAIGN.replace("runs: 4", "runs: many"), [], "runs", "runs: many", None),
]


@pytest.mark.parametrize("name, text, extra, key, needle, expected", CAMPAIGN_CASES, ids=[c[0] for c in CAMPAIGN_CASES])
def test_montecarlo_refuses(name, text, extra, key, needle, expected, put, cli, tmp_path):
    put("scene.yaml", b"\x00\x01" if name == "campaign-scenario-binary" else RAMP)
    campaign = put("campaign.yaml", text)
    code, _, err = cli("montecarlo", campaign, "-o", tmp_path / "out.h5", "--quiet", *extra)
    assert code == 1 and "Traceback" not in err, err
    assert str(campaign) in err
    if isinstance(text, bytes):
        assert f"{campaign}:1:" in err
    if needle is not None:
        assert f"{campaign}:{line_of(text, needle)}:" in err, err
    if key is not None:
        assert key in err
    if expected is not None:
        assert expected in err, err


COMMAND_LINE_CASES = [
    ("scheduler-unreachable", ["--executor", "dask", "--scheduler", "tcp://127.0.0.1:9"], "no Dask scheduler"),
    ("scheduler-garbage", ["--executor", "dask", "--scheduler", "tcp://"], "expected an address"),
    ("scheduler-without-dask", ["--scheduler", "tcp://127.0.0.1:9"], "--executor dask"),
    ("workers-zero", ["--executor", "pool", "--workers", "0"], "--workers"),
]


@pytest.mark.parametrize("name, extra, expected", COMMAND_LINE_CASES, ids=[c[0] for c in COMMAND_LINE_CASES])
def test_montecarlo_refuses_command_lines_fast(name, extra, expected, put, cli, tmp_path):
    import time

    put("scene.yaml", RAMP)
    campaign = put("campaign.yaml", CAMPAIGN)
    start = time.perf_counter()
    code, _, err = cli("montecarlo", campaign, "-o", tmp_path / "out.h5", "--quiet", *extra)
    assert code == 1 and "Traceback" not in err, err
    assert expected in err, err
    assert time.perf_counter() - start < 10, "refused before the campaign is built (no 60 s wait)"


def test_montecarlo_refuses_an_output_in_a_missing_directory_before_building(put, cli, tmp_path):
    import time

    put("scene.yaml", RAMP)
    campaign = put("campaign.yaml", CAMPAIGN)
    start = time.perf_counter()
    code, _, err = cli("montecarlo", campaign, "-o", tmp_path / "no" / "out.h5", "--quiet")
    assert code == 1 and "Traceback" not in err and "does not exist" in err, err
    assert time.perf_counter() - start < 10


def test_montecarlo_refuses_a_run_it_does_not_have(put, cli, tmp_path):
    put("scene.yaml", RAMP)
    campaign = put("campaign.yaml", CAMPAIGN)
    code, out, err = cli("montecarlo", campaign, "--print-overrides", "99")
    assert code == 1 and "Traceback" not in err and out == ""
    assert "--print-overrides 99" in err and "0..3" in err, err


def test_montecarlo_refuses_a_file_that_is_not_a_campaign(put, cli, tmp_path):
    """Until issue 34, --overwrite refused it too; it now replaces it, as --overwrite does for every verb
    (tests/safety/test_outputs.py)."""
    put("scene.yaml", RAMP)
    campaign = put("campaign.yaml", CAMPAIGN)
    output = put("precious.h5", "not a campaign")
    code, _, err = cli("montecarlo", campaign, "-o", output, "--quiet")
    assert code == 1 and "Traceback" not in err
    assert str(output) in err and "refusing to overwrite" in err and "--overwrite" in err
    assert output.read_text() == "not a campaign"


def test_refusals_print_no_traceback_in_a_real_process(put, tmp_path):
    """The in-process cases above catch exceptions escaping main(); these run the real executable."""
    from tests.safety.conftest import flexshell

    scenario = put("scene.yaml", change("rate: 10 Hz", "rate: 10"))
    deep = put("deep.yaml", RAMP + "description: " + "[" * 5000 + "]" * 5000 + "\n")
    bomb = put("bomb.yaml", RAMP + BOMB + "g: [*f, *f, *f, *f, *f, *f, *f, *f, *f]\n")
    for argv, expected in ((["check", scenario], "models.sensor.rate"),
                           (["check", deep], "nested"),
                           (["check", bomb], "aliases"),
                           (["check", scenario, "--set", "controller.kp=[[["], "--set"),
                           (["run", put("ok.yaml", RAMP), "-o", scenario], "refusing to overwrite")):
        result = flexshell(argv, cwd=tmp_path, timeout=120)
        assert result.returncode == 1, result.stderr
        assert "Traceback" not in result.stderr and expected in result.stderr, result.stderr
        assert re.search(r"\.yaml(:\d+)?: ", result.stderr), result.stderr
