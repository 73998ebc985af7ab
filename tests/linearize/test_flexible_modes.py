"""System modes from the linearized flexible multibody scene versus the engine's at-rest M, K
eigen-solution and the whole-structure FE solution (the lumped-mass case of the flexible-dynamics
validation, tests/flexible/test_system_modes.py; TM-2020-5008164 App. G.4, Fig. G.4.1: frequency
differences "on the order of the truncation error used to linearize").

Scene: the FModal single-length beam (normalized component modes, grid 101 in the a-set) on a free
hinge with a 500 kg lumped mass locked at grid 101; FE reference: the beam deck plus a CONM2.
The linearized A (through the shell: MultibodyModel, free-hinge quaternion in tangent coordinates)
gives frequencies equal to K phi = w^2 M(q0) phi to round-off (measured 3e-13 Hz with N = 20,
3e-12 Hz with N = 60), so the linearization adds nothing to the Craig-Bampton truncation error
against FE; with N = 200 modes the first six agree with FE to better than 1e-7 Hz (slow test).
"""

from __future__ import annotations

import numpy as np
import pytest

from dynamics.flex import Fem2ModalOptions, fem2modal
from dynamics.modal_analysis import system_modes
from shell.analysis.linearize import linearize
from shell.analysis.system_modes import compare_frequencies, state_space_modes
from shell.assembly import Assembly
from shell.models.multibody import MultibodyModel
from shell.simulation import Simulation
from tests.flexible.test_system_modes import ALL, case_lumped_mass, single_beam

N_COMPARED = 10


def lumped_mass_case(tmp, n_modes):
    deck = str(single_beam().write(tmp / "single_beam.dat"))
    bodies = {"a101": fem2modal(deck, Fem2ModalOptions(n_modes=n_modes, aset=[(101, ALL)]))}
    fe, _, system, q0, _, _ = case_lumped_mass(bodies, tmp, True)
    scene = Assembly("scene")
    scene.add(MultibodyModel("multibody", system, initial_q=q0))
    return fe, system, q0, Simulation(scene)


@pytest.mark.parametrize("points,richardson", [(2, False), (4, True)])
def test_linearized_flexible_frequencies_equal_engine_and_fe(points, richardson, tmp_path):
    fe, system, q0, sim = lumped_mass_case(tmp_path, 20)
    model = linearize(sim, ["multibody.beam_101.force"], ["multibody.beam_1.position"], points=points,
                      richardson=richardson)
    modes = state_space_modes(model.A)
    reference = system_modes(system, q0)
    # per-body index maps as in the TM G.4 delivery file (bus_rotational_pos, bus_modal_pos, ...)
    np.testing.assert_array_equal(model.state_index["multibody.beam.hinge_q"], np.arange(6))
    np.testing.assert_array_equal(model.state_index["multibody.beam.modal_q"], np.arange(6, 26))
    np.testing.assert_array_equal(model.state_index["multibody.beam.modal_u"], np.arange(32, 52))
    assert not any(name.startswith("multibody.mass.") for name in model.state_index)  # locked: no states
    assert modes.n_rigid == 12  # six rigid-body modes, each a double zero eigenvalue of A
    # linearization vs the engine's exact at-rest eigenproblem: round-off level (measured 3e-13 Hz)
    assert np.max(np.abs(compare_frequencies(modes.frequencies_hz, reference.frequencies_hz, N_COMPARED))) < 1e-9
    # hence vs FE: the same differences as the exact synthesis (Craig-Bampton truncation with 20 modes)
    df_linear = compare_frequencies(modes.frequencies_hz, fe.frequencies_hz, N_COMPARED)
    df_exact = compare_frequencies(reference.frequencies_hz, fe.frequencies_hz, N_COMPARED)
    np.testing.assert_allclose(df_linear, df_exact, rtol=0, atol=1e-9)
    np.testing.assert_allclose(modes.damping_ratios, 0.0, atol=1e-12)  # undamped structure


def test_damping_ratio_and_frequency_of_a_known_oscillator():
    """x'' + 2 zeta w x' + w^2 x = 0 with w = 2 pi 3 Hz, zeta = 0.05 gives exactly those numbers."""
    w, zeta = 2 * np.pi * 3.0, 0.05
    modes = state_space_modes(np.array([[0.0, 1.0], [-w * w, -2 * zeta * w]]))
    np.testing.assert_allclose(modes.frequencies_hz, [3.0], rtol=1e-14)
    np.testing.assert_allclose(modes.damping_ratios, [zeta], rtol=1e-13)
    overdamped = state_space_modes(np.array([[0.0, 1.0], [-1.0, -3.0]]))
    assert overdamped.frequencies_hz.size == 0
    np.testing.assert_allclose(overdamped.real_eigenvalues, np.sort(np.roots([1.0, 3.0, 1.0])), rtol=1e-14)
    with pytest.raises(ValueError, match="comparing 5 modes"):
        compare_frequencies([1.0, 2.0], [1.0, 2.0, 3.0], 5)


@pytest.mark.slow
def test_linearized_frequencies_equal_fe_below_1e7_hz_with_200_modes(tmp_path):
    """N = 200 fixed-interface modes: the first six system modes of the linearized scene (4-point
    central differences with Richardson) agree with the whole-structure FE solution to < 1e-7 Hz."""
    fe, system, q0, sim = lumped_mass_case(tmp_path, 200)
    model = linearize(sim, ["multibody.beam_101.force"], ["multibody.beam_1.position"])
    modes = state_space_modes(model.A)
    assert np.max(np.abs(compare_frequencies(modes.frequencies_hz, fe.frequencies_hz, 6))) < 1e-7
