"""``modal_integrals_order: auto`` (the YAML default) and the warning for a spinning body without geometric
stiffness (issue 28 items 3 and 4), through the user's path: a CBAR deck with CONM2 rotary inertia ->
``flexshell fem2modal`` -> YAML scenes -> ``flexshell check`` and ``flexshell run``.

What is checked is the decision and what the user is told (dynamics.modal_order's table): the order and the
terms left out follow the scene's rates against the body's first frequency, the note names the figures, an
explicit order is kept, and a body spun at (Omega/omega_1)^2 above 1e-3 without geometric stiffness is warned
about by name with the ratio and the flag. That the orders themselves are right is the subject of
test_brute_force.py and test_node_inertia.py.
"""

from __future__ import annotations

import numpy as np
import pytest

from dynamics.flex.body_file import read_body_file
from shell.cli import main

N_ELEMENTS = 12
LENGTH = 3.0


def beam_deck():
    """A free-free 3 m aluminium tube (12 CBAR) with a CONM2 carrying rotary inertia on every grid."""
    lines = ["MAT1,1,70.0e9,,0.33,2700.0", "PBAR,10,1,6.0e-4,7.0e-7,7.0e-7,1.4e-6"]
    for i in range(N_ELEMENTS + 1):
        lines.append(f"GRID,{i + 1},,{LENGTH * i / N_ELEMENTS:.6f},0.0,0.0")
        lines.append(f"CONM2,{1001 + i},{i + 1},,0.5,0.0,0.0,0.0")
        lines.append(",0.002,,0.01,,,0.01")
    lines += [f"CBAR,{101 + i},10,{i + 1},{i + 2},0.0,1.0,0.0" for i in range(N_ELEMENTS)]
    return "\n".join(lines + ["ENDDATA"]) + "\n"


@pytest.fixture(scope="module")
def body_files(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("modal_order")
    (tmp / "beam.dat").write_text(beam_deck())
    for name, extra in (("beam.h5", []), ("beam_gs.h5", ["--geometric-stiffness"])):
        assert main(["fem2modal", str(tmp / "beam.dat"), "--modes", "6", "--modal-integrals", "-q", *extra,
                     "-o", str(tmp / name)]) == 0
    return tmp


def scene(body_file, *, hub=None, rate=None, order=None):
    """A free beam (``hub`` None) or a beam clamped to a hub on a revolute hinge (``hub``: "free" or
    "prescribed"), turning at ``rate`` (rad/s) about its y axis."""
    beam = f"body_file: {body_file}" + (f", modal_integrals_order: {order}" if order is not None else "")
    if hub is None:
        initial = f", initial: {{angular_velocity: '[0, {rate}, 0] rad/s'}}" if rate else ""
        bodies = f"    - {{name: beam, hinge: free, {beam}{initial}}}\n"
    else:
        prescribed = "true" if hub == "prescribed" else "false"
        bodies = (f"    - {{name: hub, hinge: revolute, axis: [0, 1, 0], prescribed: {prescribed}, mass: 50 kg, "
                  f"inertia: '[5, 5, 5] kg*m^2', initial: {{angle_rate: '{rate or 0} rad/s'}}}}\n"
                  f"    - {{name: beam, parent: hub, hinge: locked, {beam}}}\n")
    return f"""name: modal_order
multibody:
  bodies:
{bodies}integrator: {{method: rk4, step: 1 ms}}
stop: {{time: 2 ms}}
"""


def check(tmp, text, capsys, name="scene.yaml"):
    (tmp / name).write_text(text)
    assert main(["check", str(tmp / name)]) == 0
    out = capsys.readouterr()
    return out.out, out.err


def first_frequency(path):
    return 2 * np.pi * float(read_body_file(path).frequencies_hz[0])


def test_auto_order_follows_the_scene(body_files, capsys):
    tmp = body_files
    omega1 = first_frequency(tmp / "beam.h5")
    out, _ = check(tmp, scene("beam.h5"), capsys)
    assert "body 'beam': modal integrals order 0 (auto): angular rate at most 0 rad/s in the initial state" in out
    slow = 0.01 * omega1  # Omega/omega_1 = 1e-2 > 1e-3, its square 1e-4 < 1e-3: order 1
    out, _ = check(tmp, scene("beam.h5", rate=slow), capsys)
    assert "modal integrals order 1 (auto)" in out and "terms G1 left out" in out
    fast = 0.1 * omega1  # (Omega/omega_1)^2 = 1e-2: order 2
    out, _ = check(tmp, scene("beam_gs.h5", rate=fast), capsys)
    assert "modal integrals order 2 (auto)" in out
    out, _ = check(tmp, scene("beam.h5", hub="prescribed"), capsys)
    assert "modal integrals order 2 (auto): prescribed hinge(s) 'hub' turn it at rates not known before the run" in out
    out, _ = check(tmp, scene("beam.h5", rate=fast, order=1), capsys)
    assert "(auto)" not in out  # an explicit order is the user's


def test_auto_choice_in_the_run_summary_and_the_compiled_body(body_files, capsys, tmp_path):
    tmp = body_files
    (tmp / "run.yaml").write_text(scene("beam.h5", rate=0.01 * first_frequency(tmp / "beam.h5")))
    assert main(["run", str(tmp / "run.yaml"), "-o", str(tmp_path / "run.h5")]) == 0
    out = capsys.readouterr().out
    assert "note: multibody: body 'beam': modal integrals order 1 (auto)" in out


def test_spinning_body_without_geometric_stiffness_is_warned_about(body_files, capsys):
    tmp = body_files
    omega1 = first_frequency(tmp / "beam.h5")
    fast = 0.1 * omega1  # (Omega/omega_1)^2 = 1e-2
    out, err = check(tmp, scene("beam.h5", rate=fast, order=2), capsys)
    assert ("flexshell check: warning: " in err and "scene.yaml:" in err and "body 'beam' spins at "
            in err and "rad/s, (Omega/omega_1)^2 = 0.01 above 0.001, without the centrifugal stiffening (its body "
            "file has no geometric stiffness: regenerate it with `flexshell fem2modal ... --geometric-stiffness`)"
            in err)
    assert "warning: body 'beam' spins" in out  # also among the notes
    for quiet in (scene("beam_gs.h5", rate=fast, order=2), scene("beam.h5", rate=0.01 * omega1, order=2)):
        out, err = check(tmp, quiet, capsys)  # with the stiffness, or below the ratio: nothing to say
        assert "warning" not in err and "warning" not in out


def test_omit_terms_through_yaml(body_files, capsys):
    tmp = body_files
    text = scene("beam.h5", rate=0.1 * first_frequency(tmp / "beam.h5"), order=2)
    kept = text.replace("modal_integrals_order: 2", "modal_integrals_order: 2, omit_terms: [G1, F2, G2]")
    assert kept != text
    check(tmp, kept, capsys)
    (tmp / "bad.yaml").write_text(text.replace("modal_integrals_order: 2", "modal_integrals_order: 2, "
                                                                           "omit_terms: [G3]"))
    assert main(["check", str(tmp / "bad.yaml")]) != 0
    err = capsys.readouterr().err
    assert "bad.yaml:" in err and "omit_terms" in err and "expected a list of G1, F2, G2, given ['G3']" in err


def test_check_says_the_modal_stiffness_is_applied_as_its_diagonal(body_files, capsys):
    """fem2modal's Phi' K Phi is diagonal to round-off; the engine applies its diagonal and `flexshell check`
    says so, with the largest ratio dropped (dynamics.system.MODAL_DIAGONAL_TOLERANCE)."""
    from dynamics.system import MODAL_DIAGONAL_TOLERANCE, _offdiagonal_ratio

    ratio = _offdiagonal_ratio(np.asarray(read_body_file(body_files / "beam.h5").modal_stiffness))
    assert 0.0 < ratio <= MODAL_DIAGONAL_TOLERANCE
    out, _ = check(body_files, scene("beam.h5"), capsys)
    assert (f"body 'beam': modal stiffness applied as its diagonal (largest off-diagonal entry {ratio:.1e} of the "
            "geometric mean of its diagonal entries") in out
