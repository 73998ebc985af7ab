"""The sparse factorization behind the shift-invert Lanczos solver and the refinement: the
supernodal L L' / L D L' of dynamics.flex.supernodal against dense LAPACK, SuperLU and CHOLMOD
(cholespy) on the same matrices, its inertia against dense eigenvalues, the fallback, and the
compensated Rayleigh quotients."""

import warnings

import numpy as np
import pytest
import scipy.linalg as sla
import scipy.sparse as sp
from numpy.testing import assert_allclose

import decks
from dynamics.flex import modes, supernodal
from dynamics.flex.assembly import assemble
from dynamics.flex.bulk_data import read_bulk_data


def _assembled(path, text):
    path.write_text(text)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return assemble(read_bulk_data(str(path)))


@pytest.fixture(scope="module")
def plate(tmp_path_factory):
    sm = _assembled(tmp_path_factory.mktemp("plate") / "plate.dat",
                    decks.plate_deck(24, edges="SSSS"))
    return sm.stiffness_f(), sm.mass_f(), sm.f_dofs // 6


@pytest.fixture(scope="module")
def free_plate(tmp_path_factory):
    """Free lumped-mass plate, 16 x 8 CQUAD4 (918 DOFs, half of them massless rotations): the
    membrane and bending DOFs of every grid are two nodes of the ordering graph."""
    sm = _assembled(tmp_path_factory.mktemp("free") / "free.dat",
                    decks.plate_deck(16, a=2.0, b=1.0, t=0.005, edges="FFFF", coupled=False,
                                     in_plane_held=False, ny=8))
    return sm.stiffness_f(), sm.mass_f(), sm.f_dofs // 6


def _dense_factor(F):
    """L (dense, factor order) of a SupernodalFactor, assembled from its supernode blocks."""
    S = F.symbolic
    L = np.zeros((S.n, S.n))
    for s in range(len(S.first)):
        c0, w, r = S.first[s], S.width[s], S.n_rows[s]
        block = F.values[S.value_ptr[s]:S.value_ptr[s + 1]].reshape(w, w + r).T
        rows = np.concatenate([np.arange(c0, c0 + w), S.rows[S.row_ptr[s]:S.row_ptr[s + 1]]])
        L[rows, c0:c0 + w] = np.tril(block)
    return L


@pytest.mark.parametrize("grouped", [True, False], ids=["grid-groups", "supervariables"])
def test_supernodal_cholesky_reproduces_the_matrix(free_plate, grouped):
    """L L' = P A P' to 1e-15 of max |A| (round-off of the dense blocks: measured 4e-16) and
    solves equal to dense LAPACK's to 1e-9 (K - sigma M with sigma 1e-6 of the stiffness scale
    is conditioned ~1e10: both carry ~eps cond, measured 1e-11), for one vector and a block."""
    K, M, groups = free_plate
    A = (K - modes.default_shift(K, M) * M).tocsr()
    F = supernodal.SupernodalFactor(A, groups if grouped else None)
    S = F.symbolic
    assert sorted(S.perm) == list(range(A.shape[0]))
    L = _dense_factor(F)
    Ap = A.toarray()[np.ix_(S.perm, S.perm)]
    assert np.abs(L @ L.T - Ap).max() <= 1e-15 * np.abs(Ap).max()
    assert_allclose(F.pivots, np.diag(L) ** 2, rtol=1e-15)
    b = np.random.default_rng(0).standard_normal((A.shape[0], 5))
    exact = sla.solve(A.toarray(), b, assume_a="pos")
    assert_allclose(F.solve(b), exact, rtol=0, atol=1e-9 * np.abs(exact).max())
    assert_allclose(F.solve(b[:, 2]), exact[:, 2], rtol=0, atol=1e-9 * np.abs(exact).max())


def test_grid_groups_split_a_flat_plate_into_membrane_and_bending(free_plate):
    """A flat plate's membrane (T1, T2, R3) and bending (T3, R1, R2) stiffness do not couple:
    each grid is two nodes of the ordering graph, and the factor holds under 0.6 of the entries
    of the same pattern with a coupling added between the two parts of every grid (measured
    0.41; values 1e-30, since only the pattern is analysed)."""
    K, M, groups = free_plate
    A = (K - modes.default_shift(K, M) * M).tocsr()
    ptr, _, _, _ = supernodal._node_graph(A, groups)
    assert len(ptr) - 1 == 2 * len(np.unique(groups))
    n = A.shape[0]
    link = sp.csr_matrix((np.full(n - 2, 1e-30), (np.arange(n - 2), np.arange(2, n))),
                         shape=A.shape)
    coupled = A + link + link.T
    ptr, _, _, _ = supernodal._node_graph(coupled, groups)
    assert len(ptr) - 1 == len(np.unique(groups))
    split = supernodal.analyse(A, groups).factor_entries
    assert split < 0.6 * supernodal.analyse(coupled, groups).factor_entries


def test_ldl_inertia_counts_the_eigenvalues_below_the_shift(free_plate):
    """Sylvester: negative pivots of L D L' of K - s M = eigenvalues of (K, M) below s, for
    shifts between the dense LAPACK eigenvalues of the same matrices (the massless rotations'
    infinite eigenvalues never count); the factor of an indefinite matrix solves it too."""
    K, M, groups = free_plate
    lam = modes.solve_dense(K, M).eigenvalues
    symbolic = supernodal.analyse(K - M, groups)
    for k in (6, 7, 30, 100):
        s = 0.5 * (lam[k - 1] + lam[k])
        F = supernodal.SupernodalFactor((K - s * M).tocsr(), ldl=True, symbolic=symbolic)
        assert F.inertia == (k, 0, K.shape[0] - k)
    b = np.random.default_rng(1).standard_normal((K.shape[0], 3))
    A = (K - s * M).toarray()
    assert_allclose(A @ F.solve(b), b, rtol=0, atol=1e-8 * np.abs(b).max())


def test_not_positive_definite_names_the_dof():
    """L L' of a matrix with a negative diagonal entry: the error names that DOF (original
    numbering); L D L' of a singular diagonal names its zero pivot."""
    n = 40
    d = np.ones(n)
    d[17] = -1.0
    with pytest.raises(supernodal.FactorizationError,
                       match="not positive definite at DOF 17") as err:
        supernodal.SupernodalFactor(sp.diags(d).tocsr())
    assert err.value.dof == 17
    d[17] = 0.0
    with pytest.raises(supernodal.FactorizationError, match="zero pivot at DOF 17"):
        supernodal.SupernodalFactor(sp.diags(d).tocsr(), ldl=True)


def test_supernodal_superlu_and_cholmod_give_the_same_modes(plate):
    """Same 12 eigenpairs with the supernodal factorization and with SuperLU: eigenvalues to
    1e-11 relative (the refined Rayleigh quotients of both carry ~1e-13; measured 1e-14); solves
    equal to SuperLU's and to CHOLMOD's (cholespy, an independent implementation) to 1e-9."""
    K, M, groups = plate
    assert K.shape[0] > modes.DENSE_LIMIT
    sigma = modes.default_shift(K, M)
    A = K - sigma * M
    chol = modes.factorize(A, groups)
    lu = modes.SymmetricLU(A, groups)
    assert isinstance(chol, supernodal.SupernodalFactor)
    b = np.random.default_rng(0).standard_normal((K.shape[0], 3))
    assert_allclose(chol.solve(b), lu.solve(b), rtol=1e-9, atol=1e-9 * np.abs(lu.solve(b)).max())
    cholespy = pytest.importorskip("cholespy")
    L = sp.tril(sp.csc_matrix(A)).tocsc()
    L.sort_indices()
    peer = cholespy.CholeskySolverD(K.shape[0], L.indptr.astype(np.int32),
                                    L.indices.astype(np.int32), L.data.astype(float),
                                    cholespy.MatrixType.CSC)
    x = np.empty_like(b)
    peer.solve(np.ascontiguousarray(b), x)
    assert_allclose(chol.solve(b), x, rtol=1e-9, atol=1e-9 * np.abs(x).max())
    a = modes.solve_sparse(K, M, 12, sigma, lu=chol, groups=groups)
    c = modes.solve_sparse(K, M, 12, sigma, lu=lu, groups=groups)
    assert_allclose(a.eigenvalues, c.eigenvalues, rtol=1e-11)
    r = np.linalg.norm(K @ a.vectors - (M @ a.vectors) * a.eigenvalues, axis=0)
    assert np.all(r <= 1e-8 * np.linalg.norm(K @ a.vectors, axis=0))


def test_indefinite_matrix_falls_back_to_lu_and_names_the_mechanism():
    """The Cholesky refuses a matrix that is not positive definite; the LU fallback then
    reports a singular matrix as a mechanism without mass."""
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
