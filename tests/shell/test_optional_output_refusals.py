"""The optional outputs of the multibody section (``multibody: outputs: [hinge_load, energy]``) exist as ports only
when asked for: a scene that logs or connects ``multibody.<body>.hinge_load`` or ``multibody.energy`` without asking
is refused by ``flexshell check`` with file, line and key, and the message names the ``outputs:`` entry to add, not
only the ports the model has."""

from __future__ import annotations

from pathlib import Path

import pytest

from shell.cli import main

FOUR_BAR = (Path(__file__).resolve().parents[2] / "configs" / "four_bar.yaml").read_text()
LOGGED = "    - multibody.pin.load\n"
CONNECTED = ("models:\n  meter: {type: Gain, config: {unit: '1', shape: [6]}, parameters: {k: 1}}\n"
             "connections:\n  - multibody.crank.hinge_load -> meter.u\n\nintegrator:")


@pytest.mark.parametrize("old, new, key, wanted", [
    (LOGGED, LOGGED + "    - multibody.crank.hinge_load\n", "log.signals[5]", "hinge_load"),
    (LOGGED, LOGGED + "    - multibody.energy\n", "log.signals[5]", "energy"),
    ("integrator:", CONNECTED, "connection multibody.crank.hinge_load -> meter.u", "hinge_load"),
])
def test_an_optional_output_not_asked_for_is_refused_with_the_outputs_entry_to_add(tmp_path, capsys, old, new, key,
                                                                                   wanted):
    text = FOUR_BAR.replace(old, new, 1)
    assert text != FOUR_BAR
    scene = tmp_path / "scene.yaml"
    scene.write_text(text)
    assert main(["check", str(scene)]) == 1
    error = capsys.readouterr().err
    port = "multibody.energy" if wanted == "energy" else "multibody.crank.hinge_load"
    line = next(n for n, row in enumerate(text.splitlines(), 1) if port in row)
    assert f"scene.yaml:{line}: {key}" in error, error
    assert f"multibody: outputs: [{wanted}]" in error, error
    asked = text.replace("multibody:\n", f"multibody:\n  outputs: [{wanted}]\n", 1)
    scene.write_text(asked)
    assert main(["check", str(scene)]) == 0, capsys.readouterr().err   # asked for: the same scene is accepted
