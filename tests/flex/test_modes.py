"""Eigen-solver paths agree; cutoff selection; Craig-Bampton fixed-interface modes of the
101-grid beam against the clamped Euler-Bernoulli closed form; the block shift-invert Lanczos
(block sizes, thick restart, repeated eigenvalues, few DOFs with mass) and its Sturm check
against dense LAPACK on the same matrices."""

import os
import warnings

import numpy as np
import pytest
from numpy.testing import assert_allclose

from dynamics.flex.assembly import assemble
from dynamics.flex.bulk_data import read_bulk_data
from dynamics.flex.modes import (default_shift, factorize, rayleigh_quotients, shift_invert_lanczos,
                                 solve_dense, solve_sparse, sturm_count)
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


def test_massless_craig_bampton_direction_is_kept_as_a_quasi_static_mode(tmp_path):
    """Lumped-mass beam (20 elements: no rotary inertia on the bending rotations), grid 1 in the a-set.
    Once the fixed-interface modes span every interior translation of a bending plane, the constraint
    mode of grid 1's massless rotation differs from a combination of them only in massless DOFs, so
    M_n is singular up to round-off (cond 1e16 at 40 modes). That direction has stiffness and no mass: it
    is kept as a quasi-static mode (issue 33; it used to be dropped, and before that it came out as a
    spurious mode at -5.3e7 Hz): the last mode, infinite frequency, zero modal mass, modal stiffness the
    largest flexible eigenvalue. Mounted at grid 1 the body is the clamped beam: with every fixed-interface
    mode that has mass the basis is complete, and the first ten modes agree to round-off (measured 5e-12)."""
    from dynamics import Multibody
    from dynamics.modal_analysis import BeamDeck, rest_body_data, system_modes

    deck = BeamDeck()
    deck.add_line(1, (0.0, 0.0, 0.0), (1.0, 0.0, 0.0), 9.0, 20, (0.0, 1.0, 0.0), 1)
    path = str(deck.write(tmp_path / "beam20.dat"))
    body = fem2modal(path, Fem2ModalOptions(n_modes=40, aset=[(1, [1, 2, 3, 4, 5, 6])]))
    assert body.n_modes == 40 and body.n_quasi_static == 1 and body.n_rigid_modes_removed == 6
    assert np.isposinf(body.frequencies_hz[-1]) and np.all(np.isfinite(body.frequencies_hz[:-1]))
    assert_allclose(body.modal_mass, np.diag(np.r_[np.ones(39), 0.0]), atol=1e-9)
    assert_allclose(body.modal_stiffness[-1, -1], body.modal_stiffness[-2, -2], rtol=1e-12)
    assert np.abs(body.modal_stiffness[-1, :-1]).max() < 1e-9 * body.modal_stiffness[-1, -1]
    whole = fem2modal(path, Fem2ModalOptions(n_modes=8))
    f, reference = body.frequencies_hz[:8], whole.frequencies_hz
    # Rayleigh-Ritz: the component-mode frequencies bound the whole-beam ones from above; with 40
    # fixed-interface modes the truncation error of the first eight is <= 1.4e-5 (measured)
    assert np.all(f >= reference * (1.0 - 1e-12))
    assert_allclose(f, reference, rtol=5e-5)
    deck.spc.append((1, 123456))
    clamped = fem2modal(str(deck.write(tmp_path / "clamped.dat")), Fem2ModalOptions(n_modes=10))
    mb = Multibody()
    mb.add_flexible_body("beam", None, modal=rest_body_data(body), hinge="locked", child_grid=1)
    system = mb.compile()
    assert "quasi-static" in system.solver_reason and system.solver == "dense"
    modes = system_modes(system, system.neutral_configuration())
    assert_allclose(modes.frequencies_hz[:10], clamped.frequencies_hz, rtol=1e-10)


@pytest.fixture(scope="module")
def free_plate(tmp_path_factory):
    """Free lumped-mass plate, 16 x 8 CQUAD4 (918 DOFs, 459 of them massless rotations)."""
    import decks
    path = tmp_path_factory.mktemp("free") / "free.dat"
    path.write_text(decks.plate_deck(16, a=2.0, b=1.0, t=0.005, edges="FFFF", coupled=False,
                                     in_plane_held=False, ny=8))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sm = assemble(read_bulk_data(str(path)))
    K, M = sm.stiffness_f(), sm.mass_f()
    dense = solve_dense(K, M)
    # reference: LAPACK's vectors (massless rotations condensed) with double-double quotients
    return K, M, sm.f_dofs // 6, rayleigh_quotients(K, M, dense.vectors)


@pytest.mark.parametrize("block", [1, 4, 16])
def test_block_lanczos_ritz_values_match_dense_lapack(free_plate, block):
    """Ritz values of the block Lanczos (converged to 1e-9 in the inverted problem) against the
    dense reference: 40 lowest, rigid-body ones included. theta errs by ~tol^2 theta for a
    converged pair; lambda = sigma + 1/theta then carries eps |sigma| of cancellation (sigma
    = -3e3 here): bound 1e-9 of the largest of the 40 (measured 1.3e-13 - 2.5e-13); vectors
    M-orthonormal to 1e-11 (Cholesky QR of the blocks: measured 2.3e-12 with blocks of 4)."""
    K, M, groups, reference = free_plate
    sigma = default_shift(K, M)
    lu = factorize(K - sigma * M, groups)
    sol, complete = shift_invert_lanczos(lu.solve, M, sigma, 40, block=block, tol=1e-9)
    assert not complete and len(sol.eigenvalues) == 40
    assert_allclose(sol.eigenvalues, reference[:40], rtol=0, atol=1e-9 * reference[39])
    assert_allclose(sol.vectors.T @ (M @ sol.vectors), np.eye(40), rtol=0, atol=1e-11)
    # the images are (K - sigma M)^-1 M times the vectors: residual at the round-off of
    # (K - sigma M) times them (backward-stable solves; measured 2e-16 of |A| |x|)
    A = K - sigma * M
    residual = np.abs(A @ sol.images - M @ sol.vectors).max()
    assert residual <= 1e-13 * (abs(A) @ np.abs(sol.images)).max()


def test_refined_modes_match_dense_lapack(free_plate):
    """solve_sparse (block Lanczos, refinement with the Lanczos images, Sturm check) against
    the dense reference: eigenvalues of the 34 flexible modes to 1e-12 (measured 3e-16; the
    rigid-body ones are round-off, below 1e-8 of the first flexible one: measured 3e-10)."""
    K, M, groups, reference = free_plate
    sol = solve_sparse(K, M, 40, groups=groups)
    assert_allclose(sol.eigenvalues[6:], reference[6:40], rtol=1e-12)
    assert np.abs(sol.eigenvalues[:6]).max() < 1e-8 * reference[6]


def test_thick_restart_gives_the_same_modes(free_plate, monkeypatch):
    """A basis of 1.5 vectors per wanted pair forces thick restarts (4 with blocks of 4); the
    refined eigenvalues equal the dense reference to 1e-12 (measured 2e-16)."""
    import dynamics.flex.modes as modes
    K, M, groups, reference = free_plate
    sigma = default_shift(K, M)
    lu = factorize(K - sigma * M, groups)
    messages = []
    monkeypatch.setattr(modes, "LANCZOS_BASIS", 1.5)
    sol, _ = shift_invert_lanczos(lu.solve, M, sigma, 40, block=4, progress=messages.append)
    restarts = int(messages[-1].split(",")[-1].split()[0])
    assert restarts >= 1
    refined = modes.refine(K, M, sol.vectors, lu.solve, images=sol.images)
    assert_allclose(refined.eigenvalues[6:40], reference[6:40], rtol=1e-12)


def test_repeated_eigenvalues_are_all_found():
    """Four uncoupled copies of one free beam: every eigenvalue four times. A block of 16
    finds every copy (the Sturm check passes) and the eigenvalues equal the single beam's dense
    ones to 1e-9 (measured 4.4e-11: the lumped beam's stiffness-to-mass range is 1e9, the
    float64 floor of its lowest eigenvalues; test_sparse_shift_invert_matches_dense_lapack)."""
    import scipy.sparse as sp
    deck = os.path.join(os.path.dirname(__file__), "data", "single_length_beam.dat")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sm = assemble(read_bulk_data(deck))
    K1, M1 = sm.stiffness_f(), sm.mass_f()
    single = solve_dense(K1, M1)
    K = sp.block_diag([K1] * 4).tocsr()
    M = sp.block_diag([M1] * 4).tocsr()
    sol = solve_sparse(K, M, 4 * 14)
    expected = np.repeat(single.eigenvalues[6:14], 4)
    assert_allclose(sol.eigenvalues[24:], expected, rtol=1e-9)
    assert np.abs(sol.eigenvalues[:24]).max() < 1e-8 * expected[0]


def test_sturm_check_catches_a_missed_mode(free_plate, monkeypatch):
    """A Lanczos run that loses one converged pair (simulated) is caught: the inertia of
    K - s M counts one eigenvalue more below the check shift than the solver returned."""
    import dynamics.flex.modes as modes
    from dynamics.flex.modes import EigenSolution, EigenSolutionError
    K, M, groups, _ = free_plate
    real = modes.shift_invert_lanczos

    def lossy(*args, **kwargs):
        sol, complete = real(*args, **kwargs)
        keep = np.r_[0:10, 11:len(sol.eigenvalues)]
        return EigenSolution(sol.eigenvalues[keep], sol.vectors[:, keep],
                             sol.images[:, keep]), complete

    monkeypatch.setattr(modes, "shift_invert_lanczos", lossy)
    with pytest.raises(EigenSolutionError, match="Sturm check failed: .* the Lanczos solver "
                                                 "found .*: eigenvalues were missed"):
        solve_sparse(K, M, 30, groups=groups)


def test_sturm_count_against_dense_eigenvalues(free_plate):
    """sturm_count = number of dense eigenvalues below the shift, at shifts between them (the
    six rigid-body eigenvalues are round-off, of either sign: the first shift is above them)."""
    K, M, groups, reference = free_plate
    for k in (6, 7, 25, 60):
        s = 0.5 * (reference[k - 1] + reference[k])
        assert sturm_count(K, M, s, groups) == k


def test_few_dofs_with_mass_give_every_finite_mode():
    """A long chain whose mass sits on eight grids only (the rest massless): fewer DOFs with
    mass than a Krylov basis would need, so the inverted operator on them is formed whole;
    all eight eigenvalues of the 1-D spring-mass chain equal the dense solution to 1e-10
    (measured 5.6e-13), and asking for more modes than the model has names the reason."""
    import scipy.sparse as sp
    from dynamics.flex.modes import EigenSolutionError, lowest_modes
    n = 800
    k = np.ones(n + 1)
    K = sp.diags([k[:-1] + k[1:], -k[1:-1], -k[1:-1]], [0, 1, -1]).tocsr()   # grounded chain
    m = np.zeros(n)
    m[::100] = 1.0 + np.arange(8)
    M = sp.diags(m).tocsr()
    dense = solve_dense(K.toarray(), M.toarray())
    sol = lowest_modes(K, M, n_modes=8)
    assert_allclose(sol.eigenvalues, dense.eigenvalues[:8], rtol=1e-10)
    with pytest.raises(EigenSolutionError, match="asked for 9 modes but the model has only 8"):
        lowest_modes(K, M, n_modes=9)


def test_cutoff_with_the_lanczos_path(free_plate):
    """Every mode up to a cutoff, through the sparse solver's own stopping rule, equals the
    dense reference below it (1e-12; measured 2e-16)."""
    from dynamics.flex.modes import lowest_modes
    K, M, groups, reference = free_plate
    cut_hz = np.sqrt(0.5 * (reference[49] + reference[50])) / (2 * np.pi)
    sol = lowest_modes(K, M, cutoff_hz=cut_hz, groups=groups)
    assert len(sol.eigenvalues) == 50
    assert_allclose(sol.eigenvalues[6:], reference[6:50], rtol=1e-12)


def test_progress_gives_cpu_time_by_step_and_the_solver_lines(beam101):
    """Every progress message carries wall and CPU time since the start; the sparse solver
    reports its factorization, its Lanczos iteration and its Sturm check, and the last message
    the CPU time of every step, which add up to the total."""
    import re
    deck, _ = beam101
    messages = []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        fem2modal(deck, Fem2ModalOptions(n_modes=20), progress=messages.append)
    stamp = re.compile(r"^\[ *\d+\.\d\d s, CPU +\d+\.\d\d s\] ")
    assert all(stamp.match(m) for m in messages)
    text = [stamp.sub("", m) for m in messages]
    assert any(t.startswith("factorization of K - sigma M") and "supernodal Cholesky" in t
               for t in text)
    assert any(t.startswith("block Lanczos: ") for t in text)
    assert any(re.match(r"Sturm check: \d+ eigenvalues below .* Hz .*, as found", t) for t in text)
    summary = re.match(r"done; CPU time by step: (.*); total (\d+\.\d\d) s$", text[-1])
    steps = {part.rsplit(" ", 2)[0]: float(part.rsplit(" ", 2)[1])
             for part in summary.group(1).split(", ")}
    assert list(steps)[:3] == ["read", "assembly", "eigen-solution"]
    assert abs(sum(steps.values()) - float(summary.group(2))) <= 0.01 * len(steps)
