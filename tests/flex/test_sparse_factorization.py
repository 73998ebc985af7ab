"""The sparse factorization behind the shift-invert Lanczos solver and the refinement:
CHOLMOD (cholespy) against SuperLU on the same matrices, the fallback, and the compensated
Rayleigh quotients."""

import warnings

import numpy as np
import pytest
import scipy.sparse as sp
from numpy.testing import assert_allclose

import decks
from dynamics.flex import modes
from dynamics.flex.assembly import assemble
from dynamics.flex.bulk_data import read_bulk_data


@pytest.fixture(scope="module")
def plate(tmp_path_factory):
    path = tmp_path_factory.mktemp("plate") / "plate.dat"
    path.write_text(decks.plate_deck(24, edges="SSSS"))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sm = assemble(read_bulk_data(str(path)))
    return sm.stiffness_f(), sm.mass_f(), sm.f_dofs // 6


def test_cholmod_and_superlu_give_the_same_modes(plate):
    """Same 12 eigenpairs with either factorization: eigenvalues to 1e-11 relative (the refined
    Rayleigh quotients of both carry ~1e-13; measured 1e-14), solves to 1e-9."""
    pytest.importorskip("cholespy")
    K, M, groups = plate
    assert K.shape[0] > modes.DENSE_LIMIT
    sigma = modes.default_shift(K, M)
    A = K - sigma * M
    chol = modes.factorize(A, groups)
    lu = modes.SymmetricLU(A, groups)
    assert isinstance(chol, modes.SparseCholesky)
    b = np.random.default_rng(0).standard_normal((K.shape[0], 3))
    assert_allclose(chol.solve(b), lu.solve(b), rtol=1e-9, atol=1e-9 * np.abs(lu.solve(b)).max())
    a = modes.solve_sparse(K, M, 12, sigma, lu=chol, groups=groups)
    c = modes.solve_sparse(K, M, 12, sigma, lu=lu, groups=groups)
    assert_allclose(a.eigenvalues, c.eigenvalues, rtol=1e-11)
    r = np.linalg.norm(K @ a.vectors - (M @ a.vectors) * a.eigenvalues, axis=0)
    assert np.all(r <= 1e-8 * np.linalg.norm(K @ a.vectors, axis=0))


def test_indefinite_matrix_falls_back_to_lu_and_names_the_mechanism():
    """CHOLMOD refuses a matrix that is not positive definite; the LU fallback then reports a
    singular matrix as a mechanism without mass."""
    n = modes.DENSE_LIMIT + 10
    A = sp.diags(np.r_[np.ones(n - 1), 0.0]).tocsc()
    with pytest.raises(modes.EigenSolutionError, match="mechanism without mass"):
        modes.factorize(A)


def test_rayleigh_quotients_survive_cancellation():
    """x' K x with terms 1e12 times the result: the double-double sums give the exact rational
    value (computed with Python fractions) to 1e-15; plain float64 sums lose ~1e-4 here."""
    from fractions import Fraction
    rng = np.random.default_rng(3)
    n = 200
    # K = D' D + 1e-12-scale part: a stiff spring chain with a soft ground spring
    d = rng.uniform(1.0, 2.0, n - 1) * 1e6
    K = sp.diags([np.r_[d, 0.0] + np.r_[0.0, d], -d, -d], [0, 1, -1]).tolil()
    K[0, 0] += 1e-3
    K = K.tocsr()
    M = sp.identity(n, format="csr")
    x = np.ones(n) + 1e-9 * rng.standard_normal(n)
    C = K.tocoo()
    exact = sum(Fraction(float(v)) * Fraction(float(x[i])) * Fraction(float(x[j]))
                for i, j, v in zip(C.row, C.col, C.data))
    exact /= sum(Fraction(float(v)) ** 2 for v in x)
    q = modes.rayleigh_quotients(K, M, x[:, None])[0]
    assert abs(q - float(exact)) <= 1e-15 * abs(float(exact)) + 1e-30
    plain = (x @ (K @ x)) / (x @ x)
    assert abs(plain - float(exact)) > 1e-8 * abs(float(exact))


def test_massless_mechanism_search_above_the_dense_limit(write_deck):
    """More than DENSE_NULL_LIMIT massless DOFs (the sparse branch: one symmetric LU of K_oo,
    eigsh when it is singular). A lumped-mass CBAR line of 1100 grids (3300 massless rotations)
    has exactly one massless mechanism, the spin about its axis: one x-rotation is held. A
    lumped 32 x 32 CQUAD4 plate (3267 massless rotations, drilling penalty) has none."""
    from dynamics.flex.assembly import DENSE_NULL_LIMIT, massless_mechanism_dofs

    def assembled(text):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            return assemble(read_bulk_data(write_deck(text)))

    sm = assembled(decks.beam_deck(1099, length=20.0, card="CBAR", coupled=False))
    K, M = sm.stiffness_f(), sm.mass_f()
    assert int(np.sum(modes.massless_dofs(M))) + len(sm.mechanisms) > DENSE_NULL_LIMIT
    assert len(sm.mechanisms) == 1 and "component 4" in sm.mechanisms[0]
    assert len(massless_mechanism_dofs(K, M)) == 0     # none left in the f-set
    sm = assembled(decks.plate_deck(32, edges="FFFF", coupled=False, in_plane_held=False))
    K, M = sm.stiffness_f(), sm.mass_f()
    assert int(np.sum(modes.massless_dofs(M))) > DENSE_NULL_LIMIT
    assert len(sm.mechanisms) == 0
    assert len(massless_mechanism_dofs(K, M)) == 0
