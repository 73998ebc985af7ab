"""Generalized symmetric eigen-solutions (K - omega^2 M) phi = 0 and free-free normal modes.

TM-2020-5008164 eqs. A.1.4-A.1.7: mass-normalized modes, Pi' M Pi = I, Pi' K Pi = diag(omega^2).
Large problems use block shift-invert Lanczos (:func:`shift_invert_lanczos`; Grimes, Lewis and
Simon, SIAM J. Matrix Anal. Appl. 15(1), 1994) on (K - sigma M)^-1 M with one sparse
factorization of K - sigma M (the supernodal Cholesky of :mod:`dynamics.flex.supernodal`;
SuperLU's LU when it is not positive definite); small ones (<= ``DENSE_LIMIT`` DOFs) use LAPACK
dense solvers, which give the 1e-16-level agreement the five-particle comparisons of TM Table
A1 show. The shift is negative so that K - sigma M is non-singular for free-free bodies (K
singular) and the rigid-body modes come out first. DOFs without mass (rotations of lumped-mass
beams and shells) give infinite eigenvalues that the inverted problem maps to zero and never
returns; the Lanczos vectors live on the DOFs with mass. The number of eigenvalues found is
checked by a Sturm sequence: the inertia of L D L' = K - s M for s in a gap just above them
(:func:`sturm_count`).

Every returned eigenpair is refined by one step of subspace iteration with the shifted
factorization (the Lanczos images: no further solve) and a Rayleigh-Ritz solve whose quotients
are summed in extended precision (:func:`refine`, :func:`rayleigh_quotients`): ARPACK's lowest
eigenvalue of a long cantilever was 2e-8 off; refined, it agrees with a 40-digit solution of
the same matrices to 1e-11 (tests/flex/test_defects.py).

Rigid-body modes are the span of the geometry's rigid-body vectors, not modes below a
frequency threshold (:func:`free_free_modes`, :func:`separate_rigid_body_modes`).
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from numba import njit

from dynamics.flex.supernodal import FactorizationError, SupernodalFactor

DENSE_LIMIT = 600
# A mass matrix whose smallest eigenvalue is below this fraction of its largest is treated as
# singular: LAPACK's Cholesky of M may still succeed (a Craig-Bampton M_n whose fixed-interface modes
# span the interior part of a constraint mode of a massless boundary DOF is singular only up to
# round-off), but the near-massless direction then comes out as a spurious mode of arbitrary
# frequency. The inverted problem below drops it as the infinite eigenvalue it is.
MASSLESS_RATIO = 1e-12
TWO_PI = 2.0 * np.pi


class EigenSolutionError(RuntimeError):
    """The eigen-problem could not be solved as asked; the message says why."""


@dataclass
class EigenSolution:
    """Eigenvalues omega^2 [rad^2/s^2] ascending and mass-normalized vectors (columns).

    ``images``: (K - sigma M)^-1 M vectors for the shift sigma of the factorization that
    produced them, when the solver has them at no cost (the block Lanczos keeps them): the
    refinement step (:func:`refine`) then needs no further solve.
    """

    eigenvalues: np.ndarray
    vectors: np.ndarray
    images: np.ndarray | None = None

    @property
    def frequencies_hz(self) -> np.ndarray:
        return np.sqrt(np.abs(self.eigenvalues)) * np.sign(self.eigenvalues) / TWO_PI


def default_shift(K, M, fraction: float = 1e-6) -> float:
    """A negative shift: ``fraction`` of the median diagonal stiffness-to-mass ratio.

    For Lanczos (1e-6) close enough to zero that the lowest modes dominate the inverted
    spectrum (fast convergence), far enough that K - sigma M is safely non-singular for
    free-free bodies; the dense inverted solve uses 1e-3 for a better conditioned K - sigma M.
    DOFs with less than 1e-6 of the largest diagonal mass are left out of the median: the
    rotary inertia of a thin shell (rho t^3 / 12) would otherwise put the shift 1e6 times
    above its lowest eigenvalues.
    """
    kd = np.abs(K.diagonal())
    md = np.abs(M.diagonal())
    mask = md > 1e-6 * md.max(initial=0.0)
    if not np.any(mask):
        raise EigenSolutionError("mass matrix has no positive diagonal entry")
    scale = np.median(kd[mask] / md[mask])
    if not np.isfinite(scale) or scale <= 0.0:
        scale = 1.0
    return -fraction * scale


def _mass_normalize(vectors: np.ndarray, M) -> np.ndarray:
    mm = np.einsum("ij,ij->j", vectors, M @ vectors)
    if np.any(mm <= 0.0):
        raise EigenSolutionError("an eigenvector has zero or negative generalized mass")
    return vectors / np.sqrt(mm)


def _sign_convention(vectors: np.ndarray) -> np.ndarray:
    """Largest-magnitude entry of each vector positive (makes results reproducible)."""
    signs = largest_entry_signs(np.ascontiguousarray(vectors, dtype=float))
    return vectors * signs


@njit(cache=True)
def largest_entry_signs(X):
    """Sign of the first largest-magnitude entry of every column (+1 for a zero column); one
    pass over the rows of a C-ordered block (numpy's argmax along axis 0 strides through it)."""
    n, m = X.shape
    best = np.full(m, -1.0)
    signs = np.ones(m)
    for i in range(n):
        for j in range(m):
            v = abs(X[i, j])
            if v > best[j]:
                best[j] = v
                signs[j] = -1.0 if X[i, j] < 0.0 else 1.0
    return signs


def massless_dofs(M) -> np.ndarray:
    """True for DOFs whose row of M is zero (to round-off)."""
    row = np.asarray(abs(M).sum(axis=1)).ravel()
    return row <= 1e-14 * max(row.max(initial=0.0), 1e-300)


def solve_dense(K: np.ndarray, M: np.ndarray, n_modes: int | None = None,
                shift: float | None = None) -> EigenSolution:
    """All (or the lowest ``n_modes``) eigenpairs by LAPACK; M may be singular (massless DOFs).

    DOFs whose rows of M are zero are condensed statically first (Guyan reduction, exact here:
    the o rows of (K - lambda M) u = 0 read K_oa u_a + K_oo u_o = 0 for every lambda), so the
    eigenvalues come from the regular pencil (K_aa - K_ao K_oo^-1 K_oa, M_aa).
    """
    K = np.asarray(K.toarray() if sp.issparse(K) else K, dtype=float)
    M = np.asarray(M.toarray() if sp.issparse(M) else M, dtype=float)
    o = massless_dofs(M)
    if not np.any(o) or np.all(o):
        return _solve_dense_pencil(K, M, n_modes, shift)
    a = ~o
    try:
        factor = sla.cho_factor(K[np.ix_(o, o)])
    except np.linalg.LinAlgError as exc:
        raise EigenSolutionError(
            "the stiffness of the massless DOFs is singular: a mechanism without mass (e.g. "
            "free rotation about a CBAR/CROD axis with lumped mass: use PARAM COUPMASS 1, CBEAM, "
            "or constrain it)") from exc
    X = -sla.cho_solve(factor, K[np.ix_(o, a)])
    Kc = K[np.ix_(a, a)] + K[np.ix_(a, o)] @ X
    sub = _solve_dense_pencil(0.5 * (Kc + Kc.T), M[np.ix_(a, a)], n_modes, shift)
    vec = np.zeros((K.shape[0], sub.vectors.shape[1]))
    vec[a] = sub.vectors
    vec[o] = X @ sub.vectors
    return EigenSolution(sub.eigenvalues, _sign_convention(vec))


def _solve_dense_pencil(K: np.ndarray, M: np.ndarray, n_modes, shift) -> EigenSolution:
    try:
        mass_range = sla.eigvalsh(M)
        if mass_range[0] <= MASSLESS_RATIO * mass_range[-1]:
            raise np.linalg.LinAlgError("M is numerically singular")
        lam, vec = sla.eigh(K, M)
        # Rayleigh quotients: LAPACK's eigenvalues of rigid-body modes carry round-off of order
        # eps ||M^-1 K||, the quotients of the (accurate) vectors of order eps^2 ||M^-1 K||.
        lam = np.einsum("ij,ij->j", vec, K @ vec) / np.einsum("ij,ij->j", vec, M @ vec)
    except np.linalg.LinAlgError:
        # M singular in a direction that is no DOF (e.g. a Craig-Bampton M_n):
        # M x = mu (K - sigma M) x, lambda = sigma + 1/mu.
        sigma = default_shift(sp.csr_matrix(K), sp.csr_matrix(M), 1e-3) if shift is None \
            else shift
        A = K - sigma * M
        try:
            mu, vec = sla.eigh(M, 0.5 * (A + A.T))
        except np.linalg.LinAlgError as exc:
            raise EigenSolutionError(
                "K - sigma M is not positive definite: the structure has a mechanism without "
                "mass (e.g. free rotation about a CBAR/CROD axis with lumped mass: use PARAM "
                "COUPMASS 1, CBEAM, or constrain it) or K is indefinite") from exc
        keep = mu > 1e-13 * np.max(np.abs(mu))
        vec = _mass_normalize(vec[:, keep], M)
        lam = np.einsum("ij,ij->j", vec, K @ vec)      # Rayleigh quotients (M-normalized)
        order = np.argsort(lam)
        lam, vec = lam[order], vec[:, order]
    if n_modes is not None:
        lam, vec = lam[:n_modes], vec[:, :n_modes]
    return EigenSolution(lam, _sign_convention(vec))


def rayleigh_quotients(K, M, vectors: np.ndarray) -> np.ndarray:
    """x' K x / x' M x per column, each quadratic form in double-double arithmetic.

    The quotient is stationary, so its error is the square of the vector's; what limits it in
    float64 is the sum itself: for a long cantilever the terms of x' K x are ~1e9 times the
    result, and float64 left 1e-11 - 4e-9 of the lowest eigenvalue (depending on ARPACK's start
    vector). Every product K_ij x_i x_j is formed exactly (Dekker's TwoProduct) and summed with
    its rounding error carried (Knuth's TwoSum): the compensated dot product of Ogita, Rump and
    Oishi (SIAM J. Sci. Comput. 26(6), 2005, algorithm Dot2), accurate as if computed in twice
    the working precision. A compiled kernel over the rows of a CSR matrix: 110 vectors of a
    100k-DOF plate take about 0.4 s (the earlier np.longdouble sums, 30 s).
    """
    X = np.ascontiguousarray(vectors, dtype=float)
    if X.ndim == 1:
        X = X[:, None]
    return quadratic_forms(K, X) / quadratic_forms(M, X)


def quadratic_forms(A, X: np.ndarray) -> np.ndarray:
    """x' A x for every column of X (n x m), in double-double arithmetic (see
    :func:`rayleigh_quotients`)."""
    C = sp.csr_matrix(A)
    return _quadratic_forms_dd(C.indptr.astype(np.int64), C.indices.astype(np.int64),
                               C.data.astype(float), np.ascontiguousarray(X, dtype=float))


@njit(cache=True)
def _split(a):
    """Dekker's split: a = hi + lo, each with at most 26 significant bits."""
    c = 134217729.0 * a          # 2^27 + 1
    hi = c - (c - a)
    return hi, a - hi


@njit(cache=True)
def _two_prod(a, a_hi, a_lo, b, b_hi, b_lo):
    """p + e = a b exactly, from the pre-split factors (Dekker / Veltkamp)."""
    p = a * b
    e = a_lo * b_lo - (((p - a_hi * b_hi) - a_lo * b_hi) - a_hi * b_lo)
    return p, e


@njit(cache=True)
def _quadratic_forms_dd(indptr, indices, data, X):
    """x_j' A x_j for every column j of X (n x m, C order), double-double (Dot2).

    Row by row: (A x)_i is summed as an unevaluated pair hi + lo (TwoProduct of every term,
    TwoSum into the pair), then hi x_i is formed exactly and lo x_i rounded (an eps^2-relative
    term) and both are summed over the rows with TwoSum, so the result carries the accuracy of
    Dot2 over all the products K_ik x_k x_i with about half the operations per nonzero.
    """
    n, m = X.shape
    out = np.zeros(m)
    x_hi = np.empty((n, m))
    x_lo = np.empty((n, m))
    for i in range(n):
        for j in range(m):
            x_hi[i, j], x_lo[i, j] = _split(X[i, j])
    s = np.zeros(m)
    c = np.zeros(m)
    rs = np.empty(m)
    rc = np.empty(m)
    for i in range(n):
        rs[:] = 0.0
        rc[:] = 0.0
        for k in range(indptr[i], indptr[i + 1]):
            col = indices[k]
            v = data[k]
            v_hi, v_lo = _split(v)
            for j in range(m):
                p, e = _two_prod(v, v_hi, v_lo, X[col, j], x_hi[col, j], x_lo[col, j])
                t = rs[j] + p
                bv = t - rs[j]
                rc[j] += ((rs[j] - (t - bv)) + (p - bv)) + e
                rs[j] = t
        for j in range(m):
            r_hi, r_lo = _split(rs[j])
            p, e = _two_prod(rs[j], r_hi, r_lo, X[i, j], x_hi[i, j], x_lo[i, j])
            t = s[j] + p
            bv = t - s[j]
            c[j] += ((s[j] - (t - bv)) + (p - bv)) + e + rc[j] * X[i, j]
            s[j] = t
    for j in range(m):
        out[j] = s[j] + c[j]
    return out


def rayleigh_ritz(K, M, W: np.ndarray, drop: float = 1e-10) -> EigenSolution:
    """Ritz pairs of (K, M) on span(W) (TM eq. A.2.9 is the same projection for the Craig-
    Bampton basis), as mass-normalized vectors with their Rayleigh quotients (double-double).

    The columns of W are taken at unit M-norm (the Gram matrix scaled by its diagonal), so that
    only linearly dependent directions are dropped: those with M-norm below ``drop`` of the
    largest in the scaled Gram matrix's eigen-decomposition.
    """
    G = W.T @ (M @ W)
    scale = 1.0 / np.sqrt(np.maximum(np.diag(G), 1e-300))
    G = scale[:, None] * (0.5 * (G + G.T)) * scale
    s, U = np.linalg.eigh(G)
    keep = s > drop * max(s.max(initial=0.0), 1e-300)
    T = scale[:, None] * U[:, keep] / np.sqrt(s[keep])      # Q = W T is M-orthonormal
    H = T.T @ (W.T @ (K @ W)) @ T
    _, Y = np.linalg.eigh(0.5 * (H + H.T))
    vec = W @ (T @ Y)
    mass = quadratic_forms(M, vec)
    if np.any(mass <= 0.0):
        raise EigenSolutionError("an eigenvector has zero or negative generalized mass")
    lam = quadratic_forms(K, vec) / mass
    order = np.argsort(lam)
    if np.any(order != np.arange(len(order))):
        vec, mass, lam = vec[:, order], mass[order], lam[order]
    vec *= largest_entry_signs(vec) / np.sqrt(mass)
    return EigenSolution(lam, vec)


def shifted_solver(K, M, sigma: float, groups: np.ndarray | None = None):
    """x = (K - sigma M)^-1 b: dense LU up to ``DENSE_LIMIT`` DOFs, else a sparse LU.

    The dense factorization pivots: a Craig-Bampton K_n carries rigid-body round-off of either
    sign (~1e-11 of its largest entry), which can make K_n - sigma M_n slightly indefinite.
    """
    if K.shape[0] <= DENSE_LIMIT:
        A = (K.toarray() if sp.issparse(K) else np.asarray(K)) - sigma * (
            M.toarray() if sp.issparse(M) else np.asarray(M))
        with warnings.catch_warnings():
            warnings.simplefilter("error", sla.LinAlgWarning)
            try:
                factor = sla.lu_factor(0.5 * (A + A.T))
            except (np.linalg.LinAlgError, sla.LinAlgWarning) as exc:
                raise EigenSolutionError("K - sigma M is singular: a mechanism without mass"
                                         ) from exc
        return lambda b: sla.lu_solve(factor, b)
    return factorize(K - sigma * M, groups).solve


def refine(K, M, vectors: np.ndarray | None, solve, rigid: np.ndarray | None = None,
           images: np.ndarray | None = None) -> EigenSolution:
    """One step of subspace (inverse) iteration with the shifted factorization, then Rayleigh-
    Ritz (Bathe, Finite Element Procedures, 1996, sec. 11.6; Parlett, The Symmetric Eigenvalue
    Problem, ch. 11).

    A computed eigenvector carries errors along the other modes of relative size
    ~ eps ||K|| / gap, mostly along the stiff ones; one application of (K - sigma M)^-1 M damps
    the component along mode j by (lambda_1 - sigma) / (lambda_j - sigma), and the Ritz values
    of the refined subspace err by the square of what remains. Directions along ``rigid``
    (M-orthonormal columns) are projected out before and after the step. ``images``: the step
    already taken, (K - sigma M)^-1 M times the vectors with the rigid directions projected out
    (the block Lanczos keeps the images of its vectors); ``vectors`` is then not used.
    """
    projected = rigid is not None and rigid.shape[1]
    if images is None:
        W = vectors
        if projected:
            W = W - rigid @ (rigid.T @ (M @ W))
        W = solve(M @ W)
    else:
        W = images
    if projected:
        W = W - rigid @ (rigid.T @ (M @ W))
        W -= rigid @ (rigid.T @ (M @ W))
    return rayleigh_ritz(K, M, W)


def factorize(A, groups: np.ndarray | None = None):
    """A factorization of the sparse symmetric positive-definite K - sigma M with ``.solve(b)``
    (b a vector or an n x m block) and ``.method`` (what was used, for the reports).

    The supernodal Cholesky of :mod:`dynamics.flex.supernodal` (``groups``: the grid of every
    DOF, for its ordering); a matrix that is not positive definite goes to :class:`SymmetricLU`
    (SuperLU), which factors an indefinite one and names the mechanism of a singular one. On the
    98,826-DOF plate of tests/flex/test_speed.py the supernodal factorization takes 0.5 s and
    solves blocks of 8 right-hand sides at 7 ms per column, against 1.7 s and 9.5 ms for
    CHOLMOD's simplicial factorization (cholespy) and 13 - 20 s for SuperLU
    (benchmarks/fem2modal_speed.py, docs/fem2modal.md).
    """
    if A.shape[0] > DENSE_LIMIT:
        try:
            return SupernodalFactor(A, groups)
        except FactorizationError:
            pass
    return SymmetricLU(A, groups)


class SymmetricLU:
    """Sparse LU of a symmetric positive-definite matrix with a fill-reducing grid ordering.

    When ``groups`` (the grid of every DOF) is given, COLAMD orders the grid graph and the
    DOFs of a grid are kept together (about a third less fill than ordering the DOFs of a
    beam lattice directly); the factorization then runs without pivoting in SuperLU's
    symmetric mode. Without groups, SuperLU's default (COLAMD on the DOFs, partial pivoting).
    """

    method = "SuperLU sparse LU (symmetric mode, grid ordering)"

    def __init__(self, A, groups: np.ndarray | None = None):
        A = sp.csc_matrix(A)
        self.perm = None
        try:
            if groups is None:
                self.lu = spla.splu(A)
                return
            C = A.tocoo()
            ng = int(groups.max()) + 1
            P = sp.csc_matrix((np.ones(C.nnz), (groups[C.row], groups[C.col])), shape=(ng, ng))
            P = (P + P.T + sp.identity(ng) * (P.nnz + 1.0)).tocsc()
            grid_order = np.argsort(spla.splu(P, permc_spec="COLAMD").perm_c)
            rank = np.empty(ng, dtype=np.int64)
            rank[grid_order] = np.arange(ng)
            self.perm = np.argsort(rank[groups], kind="stable")
            Ap = A[self.perm][:, self.perm].tocsc()
            self.lu = spla.splu(Ap, permc_spec="NATURAL", diag_pivot_thresh=0.0,
                                options=dict(SymmetricMode=True))
        except RuntimeError as exc:
            raise EigenSolutionError(
                f"K - sigma M is singular ({exc}): the structure has a mechanism without mass "
                "(e.g. free rotation about a CBAR/CROD axis with lumped mass: use PARAM "
                "COUPMASS 1, CBEAM, or constrain it)") from exc

    def solve(self, b: np.ndarray) -> np.ndarray:
        if self.perm is None:
            return self.lu.solve(b)
        x = np.empty_like(b)
        x[self.perm] = self.lu.solve(b[self.perm])
        return x


# Block shift-invert Lanczos (:func:`shift_invert_lanczos`): block size (the supernodal solves
# cost 4.2 ms per column of the 98,826-DOF plate in blocks of 16, 6.7 ms in blocks of 8; at
# tolerance 1e-8 the larger block needed 352 basis vectors for its 112 pairs instead of 280,
# and the iteration took 4.2 s instead of 4.8 s), the convergence tolerance on the relative
# residual of the inverted problem (1e-8 and 1e-7 gave the same refined eigenvalues to 3e-16,
# 0.3 s sooner, but relative residuals of the highest modes up to 4e-10 instead of 3e-11), and
# the largest basis, in vectors per wanted mode, before a thick restart.
LANCZOS_BLOCK = 16
LANCZOS_TOL = 1e-9
LANCZOS_BASIS = 4


class LanczosNoConvergence(EigenSolutionError):
    """The Lanczos iteration used its budget of solves without converging."""


def _m_orthonormalize(Z: np.ndarray, M_aa, Q: np.ndarray, rng):
    """(Q_new, R, complete): Z = Q_new R with Q_new' M Q_new = I, by Cholesky QR (Stathopoulos
    and Wu, SIAM J. Sci. Comput. 23(6), 2002) of a block already M-orthogonal to ``Q``.

    Directions of Z that vanished in the projection (an invariant subspace) are replaced by
    random vectors M-orthogonal to ``Q`` and to the rest, with zero rows of R (the block Lanczos
    starts afresh in those directions). ``complete`` is True when no such vector can be found:
    ``Q`` and the kept directions already span every direction with mass.
    """
    G = Z.T @ (M_aa @ Z)
    G = 0.5 * (G + G.T)
    scale = max(float(np.max(np.diag(G), initial=0.0)), 1e-300)
    s, U = np.linalg.eigh(G)
    if s[0] > 1e-20 * scale:
        R = np.linalg.cholesky(G).T
        return sla.solve_triangular(R, Z.T, trans="T").T, R, False
    keep = s > 1e-24 * scale
    k = int(keep.sum())
    Q_new = np.empty_like(Z)
    R = np.zeros((Z.shape[1], Z.shape[1]))
    Q_new[:, :k] = Z @ (U[:, keep] / np.sqrt(s[keep]))
    R[:k] = (U[:, keep] * np.sqrt(s[keep])).T
    for j in range(k, Z.shape[1]):
        basis = np.hstack([Q, Q_new[:, :j]])
        v = rng.standard_normal(Z.shape[0])
        before = float(np.sqrt(v @ (M_aa @ v)))
        for _ in range(2):
            v -= basis @ (basis.T @ (M_aa @ v))
        after = float(np.sqrt(max(v @ (M_aa @ v), 0.0)))
        if not after > 1e-8 * before:
            return Q_new, R, True
        Q_new[:, j] = v / after
    return Q_new, R, False


def shift_invert_lanczos(solve, M, sigma: float, n_wanted: int, cutoff: float | None = None,
                         extra: int = 0, fence: int = 0, block: int = LANCZOS_BLOCK,
                         tol: float = LANCZOS_TOL, seed: int = 0,
                         progress=None) -> tuple[EigenSolution, bool]:
    """Lowest eigenpairs of (K, M) by block Lanczos on (K - sigma M)^-1 M with full
    reorthogonalization (Grimes, Lewis and Simon, SIAM J. Matrix Anal. Appl. 15(1), 1994: the
    shifted block Lanczos of MSC Nastran; thick restart: Wu and Simon, SIAM J. Matrix Anal. Appl.
    22(2), 2000).

    ``solve(b)``: (K - sigma M)^-1 b for an n x p block (one multiple right-hand-side solve per
    step). The operator is self-adjoint in the M inner product, with eigenvalues theta =
    1 / (lambda - sigma): the lowest lambda are the largest theta. Massless DOFs (zero rows of M)
    take no part in the M inner product, so the Lanczos vectors live on the DOFs with mass only
    (half of a lumped-mass shell model). The images of the converged Ritz vectors are solved for
    once more at the end, as one block: they complete the vectors' massless rows and are one
    step of inverse iteration on them, which damps what the Krylov basis carries along the
    stiff modes. (Combinations of the Lanczos blocks' own images, or the Lanczos relation
    theta y + Q_next B s_last, carry that round-off undamped: on the plate of
    tests/flex/test_speed.py the membrane rows of its bending modes then held 1e-8 of the
    residual, and the largest relative residual of the refined modes was 8e-8 or 1.5e-7
    instead of 7e-8.) Each new block is M-orthogonalized against the whole basis twice
    (classical Gram-Schmidt in level-3 BLAS; one pass left a basis orthogonal to 6e-11 instead
    of 2e-15 on the plate of tests/flex/test_speed.py, a loss that grows from step to step) and
    normalized by Cholesky QR.

    With T = Q' M (K - sigma M)^-1 M Q, a Ritz pair (theta, y = Q s) has the residual
    (K - sigma M)^-1 M y - theta y = Q_next B s_last (M-norm |B s_last|); it has converged when
    that is at most ``tol`` theta. The iteration stops when the ``n_wanted`` largest theta have
    converged, or, with ``cutoff`` (an eigenvalue), when the converged ones reach past it and
    ``extra`` more; ``fence`` further pairs are converged and returned above those (for the
    Sturm check of :func:`sturm_count`). Returns (pairs, complete): eigenvalues sigma + 1/theta,
    vectors y (massless rows from the images) and the images (K - sigma M)^-1 M y;
    ``complete`` when they are all the eigenpairs with finite eigenvalue (fewer DOFs with mass
    than wanted). ``progress(message)``: the iteration's size when it is done.
    """
    M = sp.csr_matrix(M)
    n = M.shape[0]
    massless = massless_dofs(M)
    a = np.nonzero(~massless)[0]
    o = np.nonzero(massless)[0]
    M_aa = M[a][:, a].tocsr()
    n_a = len(a)
    p = max(1, min(block, n_a))
    rng = np.random.default_rng(seed)
    cap = int(max(LANCZOS_BASIS * (n_wanted + fence), n_wanted + fence + 4 * p))
    if n_a <= cap + 2 * p:
        return _all_pairs(solve, M_aa, a, o, n, sigma, n_wanted, cutoff, extra, fence)

    def needed(lam, converged):
        """Pairs to return once enough have converged, else None; and the count to keep."""
        lead = int(np.argmin(converged)) if not converged.all() else len(converged)
        if cutoff is None:
            k = n_wanted + fence
            return (k if lead >= k else None), k
        below = int(np.sum(lam[:lead] <= cutoff))
        k = max(below + extra, below + 1) + fence
        return (k if lead >= k else None), max(k + p, n_wanted)

    # column-major: the Gram-Schmidt products and the final Q S read contiguous columns
    # (a third faster than row-major on the plate of tests/flex/test_speed.py)
    Q = np.zeros((n_a, cap + p), order="F")
    T = np.zeros((cap + p, cap + p))
    Q[:, :p], _, _ = _m_orthonormalize(rng.standard_normal((n_a, p)), M_aa, Q[:, :0], rng)
    m = 0
    rhs = np.zeros((n, p))
    solves = 0
    restarts = 0
    while True:
        if m + 2 * p > n_a:
            return _all_pairs(solve, M_aa, a, o, n, sigma, n_wanted, cutoff, extra, fence)
        J = slice(m, m + p)
        rhs[a] = M_aa @ Q[:, J]
        Z = solve(rhs)[a]
        solves += p
        basis = Q[:, :m + p]
        C = basis.T @ (M_aa @ Z)
        Z -= basis @ C
        C2 = basis.T @ (M_aa @ Z)
        Z -= basis @ C2
        C += C2
        T[:m + p, J] = C
        T[J, :m + p] = C.T
        Q_next, R, complete = _m_orthonormalize(Z, M_aa, basis, rng)
        if complete:
            return _all_pairs(solve, M_aa, a, o, n, sigma, n_wanted, cutoff, extra, fence)
        m += p
        if cutoff is None and m < n_wanted:
            Q[:, m:m + p] = Q_next
            T[m:m + p, m - p:m] = R
            T[m - p:m, m:m + p] = R.T
            continue
        theta, S = np.linalg.eigh(T[:m, :m])
        theta, S = theta[::-1], S[:, ::-1]
        residual = np.linalg.norm(R @ S[m - p:m], axis=0)
        converged = (theta > 0.0) & (residual <= tol * np.abs(theta))
        lam = sigma + 1.0 / np.where(theta > 0.0, theta, np.inf)
        k, need = needed(lam, converged)
        if k is not None:
            break
        if solves > 20 * cap:
            raise LanczosNoConvergence(
                f"block Lanczos did not converge: {int(converged.sum())} of the wanted "
                f"eigenpairs after {solves} solves with shift {sigma:.3g}")
        if m + p <= cap:
            Q[:, m:m + p] = Q_next
            T[m:m + p, m - p:m] = R
            T[m - p:m, m:m + p] = R.T
            continue
        if LANCZOS_BASIS * need > cap:
            # more modes below the cutoff than the basis was sized for: enlarge it
            cap = int(max(LANCZOS_BASIS * need, 2 * cap))
            Q = np.asfortranarray(np.hstack([Q, np.zeros((n_a, cap + p - Q.shape[1]))]))
            T = np.pad(T, (0, cap + p - T.shape[0]))
            Q[:, m:m + p] = Q_next
            T[m:m + p, m - p:m] = R
            T[m - p:m, m:m + p] = R.T
            continue
        # thick restart: keep the leading Ritz vectors (their projection is diagonal) and go on
        # from the residual block, which couples to them through B s_last
        restarts += 1
        keep = min(max(need + p, 2 * cap // 3), cap - 2 * p)
        Q[:, :keep] = Q[:, :m] @ S[:, :keep]
        T[:] = 0.0
        T[np.arange(keep), np.arange(keep)] = theta[:keep]
        coupling = R @ S[m - p:m, :keep]
        m = keep
        Q[:, m:m + p] = Q_next
        T[m:m + p, :m] = coupling
        T[:m, m:m + p] = coupling.T
    S, theta = S[:, :k], theta[:k]
    vectors = np.zeros((n, k))
    vectors[a] = Q[:, :m] @ S
    rhs = np.zeros((n, k))
    rhs[a] = M_aa @ vectors[a]
    images = solve(rhs)
    vectors[o] = images[o] / theta
    if progress is not None:
        progress(f"block Lanczos: {k} pairs converged to {tol:g} with {solves} + {k} solves "
                 f"in blocks of {p} ({m} basis vectors on the {n_a} DOFs with mass, "
                 f"{restarts} thick restart(s))")
    return EigenSolution(sigma + 1.0 / theta, vectors, images), False


def _all_pairs(solve, M_aa, a, o, n, sigma, n_wanted, cutoff, extra, fence):
    """The wanted eigenpairs when the DOFs with mass are too few for a Krylov basis to pay:
    C = ((K - sigma M)^-1)_aa from one solve per DOF with mass (in blocks of 64), then the dense
    M_aa x = theta C^-1 x, theta = 1 / (lambda - sigma); directions without mass (theta = 0,
    infinite lambda) are dropped."""
    n_a = len(a)
    C = np.empty((n_a, n_a))
    for start in range(0, n_a, 64):
        cols = np.arange(start, min(start + 64, n_a))
        rhs = np.zeros((n, len(cols)))
        rhs[a[cols], np.arange(len(cols))] = 1.0
        C[:, cols] = solve(rhs)[a]
    theta, X = sla.eigh(M_aa.toarray(), np.linalg.inv(0.5 * (C + C.T)))
    keep = theta > 1e-13 * max(float(np.max(np.abs(theta), initial=0.0)), 1e-300)
    theta, X = theta[keep][::-1], X[:, keep][:, ::-1]
    lam = sigma + 1.0 / theta
    if cutoff is None:
        k = n_wanted + fence
    else:
        k = max(int(np.sum(lam <= cutoff)) + extra, int(np.sum(lam <= cutoff)) + 1) + fence
    complete = k >= len(theta)
    k = min(k, len(theta))
    theta, X = theta[:k], X[:, :k]
    rhs = np.zeros((n, k))
    rhs[a] = M_aa @ X
    images = solve(rhs)
    vectors = images / theta
    vectors[a] = X
    return EigenSolution(lam[:k], vectors, images), complete


# pairs converged above the wanted ones, among whose gaps the Sturm check's shift is placed
STURM_FENCE = 2


def sturm_count(K, M, shift: float, groups: np.ndarray | None = None,
                symbolic=None) -> int:
    """Eigenvalues of (K, M) below ``shift``: the negative pivots of L D L' = K - shift M
    (:mod:`dynamics.flex.supernodal`; Sylvester's law of inertia). DOFs without mass (infinite
    eigenvalues) do not count, since K is positive definite on them. ``symbolic``: an analysis
    of the pattern of K - s M to reuse."""
    return SupernodalFactor(sp.csr_matrix(K - shift * M), groups, ldl=True,
                            symbolic=symbolic).inertia[0]


def _lowest_sparse(K, M, n_wanted: int, cutoff: float | None, extra: int, shift, lu, groups,
                   tol: float = 0.0, progress=None) -> EigenSolution:
    """Block Lanczos with the factorization ``lu`` of K - shift M (made here when None), its
    pair count checked by a Sturm sequence.

    ``STURM_FENCE`` pairs are converged above the wanted ones; the check shift is the midpoint
    of the widest relative gap among them, and the number of eigenvalues below it
    (:func:`sturm_count`) must be the number of pairs found below it: every returned pair the
    callers keep lies below it, so none was missed. With all the finite eigenvalues found (few
    DOFs with mass), the shift is above them all.

    When the budget of solves runs out, the wanted eigenvalues cluster at 1/|sigma| (a shift
    far above them): the shift moves 1000 times closer to zero, up to three times. The images
    then belong to another shift than the caller's factorization and are not returned.
    """
    sigma = default_shift(K, M) if shift is None else shift
    if lu is None:
        lu = factorize(K - sigma * M, groups)
    own = True
    for _ in range(3):
        try:
            sol, complete = shift_invert_lanczos(lu.solve, M, sigma, n_wanted, cutoff, extra,
                                                 fence=STURM_FENCE, tol=tol or LANCZOS_TOL,
                                                 progress=progress)
            break
        except LanczosNoConvergence:
            sigma *= 1e-3
            lu = factorize(K - sigma * M, groups)
            own = False
    else:
        raise EigenSolutionError(f"Lanczos did not converge for the lowest modes with shifts "
                                 f"down to {sigma:.3g}")
    lam = sol.eigenvalues
    if complete:
        below, check = len(lam), 2.0 * float(np.max(np.abs(lam), initial=1.0)) + 1.0
    else:
        top = np.arange(len(lam) - STURM_FENCE, len(lam))
        gaps = (lam[top] - lam[top - 1]) / np.maximum(np.abs(lam[top]), 1e-300)
        below = int(top[np.argmax(gaps)])
        check = 0.5 * (lam[below - 1] + lam[below])
    symbolic = getattr(lu, "symbolic", None) if own else None
    count = sturm_count(K, M, check, groups, symbolic)
    if count != below:
        raise EigenSolutionError(
            f"Sturm check failed: {count} eigenvalues of (K, M) lie below {check:.6g} rad^2/s^2 "
            f"({np.sqrt(max(check, 0.0)) / TWO_PI:.6g} Hz; inertia of K - s M), the Lanczos "
            f"solver found {below}: eigenvalues were missed")
    if progress is not None:
        progress(f"Sturm check: {count} eigenvalues below "
                 f"{np.sqrt(max(check, 0.0)) / TWO_PI:.6g} Hz (inertia of K - s M), as found")
    return sol if own else EigenSolution(sol.eigenvalues, sol.vectors)


def solve_sparse(K, M, n_modes: int, shift: float | None = None, tol: float = 0.0,
                 lu=None, groups: np.ndarray | None = None, refined: bool = True) -> EigenSolution:
    """Lowest ``n_modes`` eigenpairs by block shift-invert Lanczos (:func:`shift_invert_lanczos`).

    ``tol``: Lanczos tolerance (0: ``LANCZOS_TOL``). ``groups``: grid index of every DOF, for the
    fill-reducing ordering of the factorization. ``refined``: apply :func:`refine`, whose
    inverse-iteration step is the Lanczos images (no further solve); callers that refine anyway
    pass False and get the Lanczos vectors (M-orthonormal) with their Ritz values and images.
    """
    n = K.shape[0]
    if n_modes >= n - 1:
        return solve_dense(K, M, n_modes, shift)
    sigma = default_shift(K, M) if shift is None else shift
    if lu is None:
        lu = factorize(K - sigma * M, groups)
    sol = _lowest_sparse(K, M, n_modes, None, 0, sigma, lu, groups, tol)
    if refined:
        # one step with extended-precision quotients: a long cantilever's lowest eigenvalue to
        # 1e-12 - 1e-11 (Lanczos Ritz values alone: 2e-8; float64 quotients: up to 4e-9)
        sol = refine(K, M, sol.vectors, lu.solve, images=sol.images)
    images = None if sol.images is None else sol.images[:, :n_modes]
    return EigenSolution(sol.eigenvalues[:n_modes], sol.vectors[:, :n_modes], images)


def lowest_modes(K, M, n_modes: int | None = None, cutoff_hz: float | None = None,
                 extra: int = 0, shift: float | None = None,
                 groups: np.ndarray | None = None, lu=None,
                 refined: bool = True, progress=None) -> EigenSolution:
    """Lowest modes: ``n_modes + extra`` of them, or all below ``cutoff_hz`` (plus ``extra``).

    With a cutoff the Lanczos basis grows until its converged pairs reach past the cutoff.
    ``lu``: a factorization of K - shift M to reuse (:func:`factorize`). ``refined`` False: the
    sparse solver's pairs as :func:`solve_sparse` gives them unrefined.
    """
    n = K.shape[0]
    if (n_modes is None) == (cutoff_hz is None):
        raise ValueError("give exactly one of n_modes or cutoff_hz")
    if n <= DENSE_LIMIT:
        sol = solve_dense(K, M, shift=shift)
    else:
        sigma = default_shift(K, M) if shift is None else shift
        if lu is None:
            lu = factorize(K - sigma * M, groups)
        if n_modes is not None:
            sol = _lowest_sparse(K, M, n_modes + extra, None, 0, sigma, lu, groups,
                                 progress=progress)
        else:
            sol = _lowest_sparse(K, M, max(20, extra + 10), (TWO_PI * cutoff_hz) ** 2, extra,
                                 sigma, lu, groups, progress=progress)
        if refined:
            sol = refine(K, M, sol.vectors, lu.solve, images=sol.images)
    if n_modes is not None:
        if n_modes > len(sol.eigenvalues):
            raise EigenSolutionError(f"asked for {n_modes} modes but the model has only "
                                     f"{len(sol.eigenvalues)} DOFs with mass")
        count = min(n_modes + extra, len(sol.eigenvalues))
    else:
        count = min(int(np.sum(sol.frequencies_hz <= cutoff_hz)) + extra, len(sol.eigenvalues))
    images = None if sol.images is None else sol.images[:, :count]
    return EigenSolution(sol.eigenvalues[:count], sol.vectors[:, :count], images)


@dataclass
class RigidSplit:
    """How the rigid-body (and mechanism) modes were told from the flexible ones.

    n_rigid : dimension of the rigid-body space given by the geometry.
    n_mechanisms : further zero-energy modes (a pin or free hinge inside the FE model).
    computed_rigid_hz : largest |f| the eigen-solver returned for the rigid-body modes (round-off).
    zero_hz : the frequency below which a mode counts as zero-energy (module docstring).
    mechanism_hz : largest |f| of the mechanism modes removed (0 without any).
    first_flexible_hz : lowest flexible frequency kept; gap = first_flexible_hz / the largest
        zero-energy frequency.
    alignment : smallest cosine between the rigid space and the eigen-solver's lowest modes
        (1 when they contain the rigid-body motions).
    """

    n_rigid: int
    computed_rigid_hz: float
    first_flexible_hz: float
    alignment: float
    n_mechanisms: int = 0
    mechanism_hz: float = 0.0
    zero_hz: float = 0.0

    @property
    def gap(self) -> float:
        return self.first_flexible_hz / max(self.computed_rigid_hz, self.mechanism_hz, 1e-300)

    def line(self) -> str:
        if self.n_rigid == 0 and self.n_mechanisms == 0:
            return "no rigid-body motion is free (the constraints or springs hold the body)"
        text = (f"{self.n_rigid} rigid-body modes from the geometry (free translations and "
                f"rotations the constraints allow, no strain energy); the eigen-solver's "
                f"{self.n_rigid} lowest modes reach {self.computed_rigid_hz:.3g} Hz (round-off)")
        if self.n_mechanisms:
            text += (f"; {self.n_mechanisms} mechanism mode(s) (zero-energy motion that is not "
                     f"rigid: a pin or free hinge in the FE model) below the zero level "
                     f"{self.zero_hz:.3g} Hz, the largest at {self.mechanism_hz:.3g} Hz, removed "
                     "with them")
        return text + f"; first flexible {self.first_flexible_hz:.6g} Hz, gap {self.gap:.3g}"


def stiffness_scale(K, M) -> float:
    """Largest diagonal stiffness-to-mass ratio over DOFs with mass (>= 1e-6 of the largest):
    the scale of the round-off of every computed eigenvalue (~1e-16 of it)."""
    kd = np.abs(K.diagonal())
    md = np.abs(M.diagonal())
    mask = md > 1e-6 * md.max(initial=0.0)
    return float(np.max(kd[mask] / md[mask])) if np.any(mask) else 1.0


# A flexible Ritz value below ZERO_RELATIVE x stiffness_scale (or below 1e3 x the round-off the
# geometric rigid-body modes showed) is a zero-energy mode: computed zero eigenvalues sit at
# ~1e-16 - 1e-15 of the scale (1.3e-3 Hz for a 100k-DOF plate whose scale puts this level at
# 0.02 Hz and whose first mode is at 6.5 Hz).
ZERO_RELATIVE = 1e-13


def separate_rigid_body_modes(K, M, vectors: np.ndarray, eigenvalues: np.ndarray,
                              rigid_vectors: np.ndarray, solve, images: np.ndarray | None = None):
    """(rigid, flexible, RigidSplit): rigid modes = span of the geometric rigid-body vectors.

    ``vectors`` (ascending ``eigenvalues``) are computed eigenvectors that include the rigid-
    body modes. The rigid-body modes returned are ``rigid_vectors`` M-orthonormalized (eigenvalue
    zero); the flexible ones are the refined Ritz pairs (:func:`refine`) of the computed vectors
    projected on the M-orthogonal complement, so no rigid-body motion leaks into them and no
    near-zero round-off mode is kept as flexible, whatever its frequency. Ritz pairs at the zero
    level (``ZERO_RELATIVE``) are mechanism modes: returned after the rigid-body ones.
    ``images``: (K - sigma M)^-1 M vectors for ``solve``'s shift, when the eigen-solver has them
    (the refinement then takes no solve but that of the rigid-body vectors).
    """
    r = rigid_vectors.shape[1]
    if r:
        G = rigid_vectors.T @ (M @ rigid_vectors)
        s, U = np.linalg.eigh(0.5 * (G + G.T))
        if s.min() <= 1e-12 * s.max():
            raise EigenSolutionError("a rigid-body motion of the geometry carries no mass; the "
                                     "body cannot be a free flexible body")
        Phi_r = rigid_vectors @ (U / np.sqrt(s))
        # the r directions of span(vectors) closest to the rigid space are the computed
        # rigid-body modes: leave them out (projecting them would leave round-off vectors)
        MV = M @ vectors
        mm = np.einsum("ij,ij->j", vectors, MV)
        if np.any(mm <= 0.0):
            raise EigenSolutionError("an eigenvector has zero or negative generalized mass")
        B = (Phi_r.T @ MV) / np.sqrt(mm)
        _, _, Vt = np.linalg.svd(B, full_matrices=True)
        T = Vt[r:].T / np.sqrt(mm)[:, None]        # the complement, unit M-norm columns
        if images is None:
            W = vectors @ T
        else:
            # the step on vectors @ T minus its rigid part: the solve of M Phi_r only
            W = None
            images = images @ T - solve(np.ascontiguousarray(M @ Phi_r)) @ (B @ Vt[r:].T)
        computed = float(np.sqrt(np.abs(eigenvalues[:r]).max()) / TWO_PI)
    else:
        Phi_r = np.zeros((K.shape[0], 0))
        W = vectors
        computed = 0.0
    flex = refine(K, M, W, solve, Phi_r, images)
    zero = max(ZERO_RELATIVE * stiffness_scale(K, M), 1e3 * (TWO_PI * computed) ** 2)
    mech = np.abs(flex.eigenvalues) <= zero
    m = int(mech.sum())
    mech_hz = float(np.abs(flex.frequencies_hz[mech]).max()) if m else 0.0
    if r:
        low = _mass_normalize(vectors[:, :r + m], M)
        cosines = np.linalg.svd(Phi_r.T @ (M @ low), compute_uv=False)
        alignment = float(cosines.min())
    else:
        alignment = 1.0
    rigid = EigenSolution(np.concatenate([np.zeros(r), flex.eigenvalues[mech]]),
                          np.hstack([Phi_r, flex.vectors[:, mech]]))
    if m:
        flex = EigenSolution(flex.eigenvalues[~mech], flex.vectors[:, ~mech])
    first = float(flex.frequencies_hz[0]) if len(flex.eigenvalues) else float("inf")
    return rigid, flex, RigidSplit(r, computed, first, alignment, m, mech_hz,
                                   float(np.sqrt(zero) / TWO_PI))


def free_free_modes(K, M, n_modes: int | None = None, cutoff_hz: float | None = None,
                    rigid_vectors: np.ndarray | None = None, shift: float | None = None,
                    groups: np.ndarray | None = None, guard: int = 4, progress=None):
    """(rigid, flexible, RigidSplit): ``n_modes`` flexible modes or all below ``cutoff_hz``.

    The rigid-body modes are the span of ``rigid_vectors`` (the geometry's rigid-body motions,
    :meth:`~dynamics.flex.assembly.StructuralModel.rigid_body_vectors`), not a frequency
    threshold: round-off puts the computed rigid-body frequencies anywhere from 1e-8 Hz to
    1e-3 Hz (or makes them negative) for stiff, finely meshed models. ``guard`` extra modes are
    computed so that the highest kept mode has converged. ``progress(message)`` hears of the
    factorization, the Lanczos iteration and the Sturm check.
    """
    n = K.shape[0]
    r = 0 if rigid_vectors is None else rigid_vectors.shape[1]
    if rigid_vectors is None:
        rigid_vectors = np.zeros((n, 0))
    sigma = default_shift(K, M) if shift is None else shift
    lu = factorize(K - sigma * M, groups) if n > DENSE_LIMIT else None
    solve = lu.solve if lu is not None else shifted_solver(K, M, sigma, groups)
    if lu is not None and progress is not None:
        size = (f", {lu.symbolic.factor_entries / 1e6:.3g}M factor entries"
                if hasattr(lu, "symbolic") else "")
        progress(f"factorization of K - sigma M, sigma = {sigma:.4g}: {lu.method}{size}")
    # one factorization for Lanczos and the refinement; refined once, after the rigid split.
    # ``guard`` also covers up to that many mechanism modes (a pin in the FE model).
    if n_modes is not None:
        sol = lowest_modes(K, M, n_modes=min(n_modes + r, n), extra=guard, shift=sigma,
                           groups=groups, lu=lu, refined=False, progress=progress)
    else:
        sol = lowest_modes(K, M, cutoff_hz=cutoff_hz, extra=r + guard, shift=sigma,
                           groups=groups, lu=lu, refined=False, progress=progress)
    eigenvalues = sol.eigenvalues
    if n > DENSE_LIMIT and r:
        # the Lanczos Ritz values of the rigid-body modes carry only the cancellation in
        # sigma + 1/theta; the Rayleigh quotients of their vectors show the round-off that
        # sets the zero level of the split
        eigenvalues = np.concatenate([rayleigh_quotients(K, M, sol.vectors[:, :r]),
                                      eigenvalues[r:]])
    rigid, flex, split = separate_rigid_body_modes(K, M, sol.vectors, eigenvalues,
                                                   rigid_vectors, solve, sol.images)
    if np.any(flex.eigenvalues < 0.0):
        raise EigenSolutionError(f"negative eigenvalue {flex.eigenvalues.min():.3e} of a "
                                 "flexible mode: K is not positive semi-definite")
    keep = n_modes if n_modes is not None else int(np.sum(flex.frequencies_hz <= cutoff_hz))
    if n_modes is not None and len(flex.eigenvalues) < n_modes:
        raise EigenSolutionError(f"only {len(flex.eigenvalues)} flexible modes available, "
                                 f"{n_modes} requested")
    flex = EigenSolution(flex.eigenvalues[:keep], flex.vectors[:, :keep])
    return rigid, flex, split
