"""Default finite-difference steps of modal coordinates (issue 15): scaled to the mode's size.

A mass-normalized modal coordinate of a light body is not ~1 SI unit: for the 1 kg, 1 m rotating cantilever of
:mod:`tests.flex.rotating_beam` a modal coordinate of 0.09 (the default 4-point Richardson step of a variable
of typical size 1) bends its 16th mode by about 9 rad, where the second-order stiffening terms of M(eta) make
the mass matrix indefinite (before the change: "non-finite derivative"). The step rule now takes the typical
size of a modal coordinate as the amplitude at which the mode's largest grid rotation reaches 1 rad or its
largest grid translation the body's extent (docs/linearization.md). Checked: the default linearization of the
spinning cantilever (lambda 5, stiffening on) gives the first flapwise and chordwise frequencies of the
power series to the 1e-3 of the issue (the 40-element discretization error, 1e-4 .. 1e-3), and equals the
2-point small-step linearization that the rotating-cantilever tests use to 1e-6 relative.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from shell.analysis.linearize import linearize
from shell.cli import main
from shell.scenario import build_simulation, load_scenario
from tests.flex.rotating_beam import rotating_beam_deck, rotating_beam_frequencies, spinning_scene


@pytest.fixture(scope="module")
def spinning(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("modal_steps")
    (tmp / "beam.dat").write_text(rotating_beam_deck(40))
    assert main(["fem2modal", str(tmp / "beam.dat"), "--modes", "16", "--aset", "1:123456", "--modal-integrals",
                 "--geometric-stiffness", "-q", "-o", str(tmp / "beam.h5")]) == 0
    scene = tmp / "scene.yaml"
    scene.write_text(spinning_scene("beam.h5", 5.0, tip_grid=41))
    return scene


def frequencies(model):
    A = model.A
    n = A.shape[0] // 2
    keep = [i for i in range(2 * n) if i % n >= 1]  # the prescribed hub's states decouple
    ev = np.linalg.eigvals(A[np.ix_(keep, keep)])
    return np.sort(np.abs(ev.imag[ev.imag > 1e-6]))


def build(scene):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return build_simulation(load_scenario(str(scene), []))


def test_default_linearization_of_a_light_stiffened_body(spinning):
    model = linearize(build(spinning), ["multibody.beam.modal_force"], ["multibody.tip.position"])
    got = frequencies(model)
    flap, chord = rotating_beam_frequencies(5.0), rotating_beam_frequencies(5.0, chordwise=True)
    for ref in (flap[:2], chord[:2]):
        near = np.array([got[np.argmin(np.abs(got - r))] for r in ref])
        np.testing.assert_allclose(near, ref, rtol=1e-3)
    small = linearize(build(spinning), ["multibody.beam.modal_force"], ["multibody.tip.position"], points=2,
                      richardson=False, tolerance=1e-12)
    np.testing.assert_allclose(got[:8], frequencies(small)[:8], rtol=1e-6)
    # the modal coordinates' steps follow their size: a high mode gets a much smaller step than the first
    steps = model.method["state_steps"][model.state_index["multibody.beam.modal_q"]]
    assert steps.max() < 0.05 and steps.min() < steps.max() / 10


def test_user_scale_still_wins(spinning):
    model = linearize(build(spinning), ["multibody.beam.modal_force"], ["multibody.tip.position"], points=2,
                      richardson=False, tolerance=1e-12, scales={"multibody.beam.modal_q": 1e-3})
    steps = model.method["state_steps"][model.state_index["multibody.beam.modal_q"]]
    np.testing.assert_allclose(steps, 1e-3 * 1e-6, rtol=1e-9)
