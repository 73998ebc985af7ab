"""Eigen-solver paths agree; cutoff selection; Craig-Bampton fixed-interface modes of the
101-grid beam against the clamped Euler-Bernoulli closed form."""

import os
import warnings

import numpy as np
import pytest
from numpy.testing import assert_allclose

from dynamics.flex.assembly import assemble
from dynamics.flex.bulk_data import read_bulk_data
from dynamics.flex.modes import solve_dense, solve_sparse
from dynamics.flex.pipeline import Fem2ModalOptions, fem2modal


@pytest.fixture(scope="module")
def beam101():
    deck = os.path.join(os.path.dirname(__file__), "data", "single_length_beam.dat")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sm = assemble(read_bulk_data(deck))
    return deck, sm


def test_sparse_shift_invert_matches_dense_lapack(beam101):
    _, sm = beam101
    K, M = sm.stiffness_f(), sm.mass_f()
    sparse = solve_sparse(K, M, 16)
    dense = solve_dense(K, M, 16)
    flex = slice(6, 16)
    # The lowest flexible eigenvalue (15.9 rad^2/s^2) sits ~1e9 below the largest stiffness-to-
    # mass ratio of this lumped model, so eps * 1e9 * |lambda| ~ 1e-7 absolute is the round-off
    # floor: ARPACK, the LAPACK inverted solve and a Guyan-condensed LAPACK solve of the
    # massless rotations agree to 5e-10 relative. Bound 2e-9.
    assert_allclose(sparse.eigenvalues[flex], dense.eigenvalues[flex], rtol=2e-9)
    assert np.abs(sparse.eigenvalues[:6]).max() < 1e-8 * sparse.eigenvalues[6]
    Mx = sparse.vectors.T @ (M @ sparse.vectors)
    assert_allclose(Mx, np.eye(16), atol=1e-10)


def test_cutoff_keeps_every_mode_below_it(beam101):
    deck, _ = beam101
    ref = fem2modal(deck, Fem2ModalOptions(n_modes=20))
    cut = 10.0
    body = fem2modal(deck, Fem2ModalOptions(cutoff_hz=cut))
    expected = ref.frequencies_hz[ref.frequencies_hz <= cut]
    assert_allclose(body.frequencies_hz, expected, rtol=1e-10)
    assert body.frequencies_hz.max() <= cut


def test_fixed_interface_modes_of_the_101_grid_beam_are_cantilever_modes(beam101):
    deck, _ = beam101
    body = fem2modal(deck, Fem2ModalOptions(n_modes=6, aset=[(1, [1, 2, 3, 4, 5, 6])]))
    E, rho, A, L = 2.0e9, 8000.0, 2.0e-2, 9.0
    I2 = 1.66666667e-05                                   # weaker plane: lowest modes
    beta = np.array([1.8751040687120, 4.6940911329742])
    exact = beta**2 * np.sqrt(E * I2 / (rho * A * L**4)) / (2 * np.pi)
    f = body.craig_bampton.frequencies_hz
    # lumped mass, 100 elements: relative error O(h^2) ~ 1e-4 for the first two modes
    assert_allclose(f[[0, 2]], exact, rtol=5e-4)
    assert body.mode_set == "normalized-component"
    assert body.n_rigid_modes_removed == 6
    assert body.n_modes == 6                              # 6 fixed-interface + 6 - 6 rigid
    assert_allclose(body.modal_mass, np.eye(6), atol=1e-10)


def test_massless_craig_bampton_direction_is_dropped_with_a_warning(tmp_path):
    """Lumped-mass beam (20 elements: no rotary inertia on the bending rotations), grid 1 in the a-set.
    Once the fixed-interface modes span every interior translation of a bending plane, the constraint
    mode of grid 1's massless rotation differs from a combination of them only in massless DOFs, so
    M_n is singular up to round-off (cond 1e16 at 40 modes). That direction is an infinite-frequency
    mode: it must be dropped (with a warning naming the cause), not returned as a spurious mode of
    arbitrary frequency (it came out at -5.3e7 Hz, with two rigid-body modes leaking into the flexible
    set, before the singular-M check in solve_dense)."""
    from dynamics.modal_analysis import BeamDeck

    deck = BeamDeck()
    deck.add_line(1, (0.0, 0.0, 0.0), (1.0, 0.0, 0.0), 9.0, 20, (0.0, 1.0, 0.0), 1)
    path = str(deck.write(tmp_path / "beam20.dat"))
    with pytest.warns(UserWarning, match="1 direction.*carry no mass.*39 flexible modes instead of 40"):
        body = fem2modal(path, Fem2ModalOptions(n_modes=40, aset=[(1, [1, 2, 3, 4, 5, 6])]))
    assert body.n_modes == 39 and body.n_rigid_modes_removed == 6
    assert_allclose(body.modal_mass, np.eye(39), atol=1e-9)
    whole = fem2modal(path, Fem2ModalOptions(n_modes=8))
    f, reference = body.frequencies_hz[:8], whole.frequencies_hz
    # Rayleigh-Ritz: the component-mode frequencies bound the whole-beam ones from above; with 40
    # fixed-interface modes the truncation error of the first eight is <= 1.4e-5 (measured)
    assert np.all(f >= reference * (1.0 - 1e-12))
    assert_allclose(f, reference, rtol=5e-5)
