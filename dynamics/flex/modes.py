"""Generalized symmetric eigen-solutions (K - omega^2 M) phi = 0 and free-free normal modes.

TM-2020-5008164 eqs. A.1.4-A.1.7: mass-normalized modes, Pi' M Pi = I, Pi' K Pi = diag(omega^2).
Large problems use scipy.sparse.linalg.eigsh in shift-invert mode (one sparse factorization of
K - sigma M: CHOLMOD's Cholesky when the cholespy wheel is installed, else SuperLU's LU; ARPACK
Lanczos on the inverted operator); small ones (<= ``DENSE_LIMIT`` DOFs) use LAPACK dense
solvers, which give the 1e-16-level agreement the five-particle comparisons of TM Table A1 show.
The shift is negative so that K - sigma M is non-singular for free-free bodies (K singular) and
the rigid-body modes come out first. DOFs without mass (rotations of lumped-mass beams) give
infinite eigenvalues that the inverted problem maps to zero and never returns.

Every returned eigenpair is refined by one step of subspace iteration with the shifted
factorization and a Rayleigh-Ritz solve whose quotients are summed in extended precision
(:func:`refine`, :func:`rayleigh_quotients`): ARPACK's lowest eigenvalue of a long cantilever
was 2e-8 off; refined, it agrees with a 40-digit solution of the same matrices to 1e-11
(tests/flex/test_defects.py).

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
    """Eigenvalues omega^2 [rad^2/s^2] ascending and mass-normalized vectors (columns)."""

    eigenvalues: np.ndarray
    vectors: np.ndarray

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
    idx = np.argmax(np.abs(vectors), axis=0)
    signs = np.sign(vectors[idx, np.arange(vectors.shape[1])])
    signs[signs == 0] = 1.0
    return vectors * signs


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
    the working precision. A compiled kernel over the columns of a CSR matrix: 100 vectors of a
    100k-DOF plate take about a second (the earlier np.longdouble sums, 30 s).
    """
    X = np.ascontiguousarray(vectors, dtype=float)
    if X.ndim == 1:
        X = X[:, None]
    forms = []
    for A in (K, M):
        C = sp.csr_matrix(A)
        C.sort_indices()
        forms.append(_quadratic_forms_dd(C.indptr.astype(np.int64), C.indices.astype(np.int64),
                                         C.data.astype(float), X))
    return forms[0] / forms[1]


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
    """x_j' A x_j for every column j of X (n x m, C order), double-double (Dot2)."""
    n, m = X.shape
    out = np.zeros(m)
    x_hi = np.empty((n, m))
    x_lo = np.empty((n, m))
    for i in range(n):
        for j in range(m):
            x_hi[i, j], x_lo[i, j] = _split(X[i, j])
    s = np.zeros(m)
    c = np.zeros(m)
    for i in range(n):
        for k in range(indptr[i], indptr[i + 1]):
            col = indices[k]
            v = data[k]
            v_hi, v_lo = _split(v)
            for j in range(m):
                # t + et = v x_col exactly; then (t + et) x_i with t x_i exact, et x_i rounded
                # (its error is eps^2 of the term)
                t, et = _two_prod(v, v_hi, v_lo, X[col, j], x_hi[col, j], x_lo[col, j])
                t_hi, t_lo = _split(t)
                p, ep = _two_prod(t, t_hi, t_lo, X[i, j], x_hi[i, j], x_lo[i, j])
                # TwoSum of s and p
                snew = s[j] + p
                bv = snew - s[j]
                es = (s[j] - (snew - bv)) + (p - bv)
                s[j] = snew
                c[j] += es + ep + et * X[i, j]
    for j in range(m):
        out[j] = s[j] + c[j]
    return out


def rayleigh_ritz(K, M, W: np.ndarray, drop: float = 1e-10) -> EigenSolution:
    """Ritz pairs of (K, M) on span(W), directions with M-norm below ``drop`` of the largest
    dropped (TM eq. A.2.9 is the same projection for the Craig-Bampton basis)."""
    G = W.T @ (M @ W)
    s, U = np.linalg.eigh(0.5 * (G + G.T))
    keep = s > drop * max(s.max(initial=0.0), 1e-300)
    Q = W @ (U[:, keep] / np.sqrt(s[keep]))
    H = Q.T @ (K @ Q)
    lam, Y = np.linalg.eigh(0.5 * (H + H.T))
    vec = _mass_normalize(Q @ Y, M)
    lam = rayleigh_quotients(K, M, vec)
    order = np.argsort(lam)
    return EigenSolution(lam[order], _sign_convention(vec[:, order]))


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


def refine(K, M, vectors: np.ndarray, solve, rigid: np.ndarray | None = None,
           steps: int = 1) -> EigenSolution:
    """One step of subspace (inverse) iteration with the shifted factorization, then Rayleigh-
    Ritz (Bathe, Finite Element Procedures, 1996, sec. 11.6; Parlett, The Symmetric Eigenvalue
    Problem, ch. 11).

    A computed eigenvector carries errors along the other modes of relative size
    ~ eps ||K|| / gap, mostly along the stiff ones; one application of (K - sigma M)^-1 M damps
    the component along mode j by (lambda_1 - sigma) / (lambda_j - sigma), and the Ritz values
    of the refined subspace err by the square of what remains. Directions along ``rigid``
    (M-orthonormal columns) are projected out before and after the step.
    """
    W = vectors
    if rigid is not None and rigid.shape[1]:
        W = W - rigid @ (rigid.T @ (M @ W))
    W = solve(M @ W)
    if rigid is not None and rigid.shape[1]:
        W = W - rigid @ (rigid.T @ (M @ W))
        W = W - rigid @ (rigid.T @ (M @ W))
    # unit M-norm columns: the step scales mode j by 1/(lambda_j - sigma), and the Ritz
    # solve must drop only linearly dependent directions, not the stiff ones
    W = W / np.sqrt(np.maximum(np.einsum("ij,ij->j", W, M @ W), 1e-300))
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


def solve_sparse(K, M, n_modes: int, shift: float | None = None, tol: float = 0.0,
                 lu=None, groups: np.ndarray | None = None, refined: bool = True) -> EigenSolution:
    """Lowest ``n_modes`` eigenpairs by shift-invert Lanczos (scipy eigsh, ARPACK).

    ``groups``: grid index of every DOF, for the fill-reducing ordering of :class:`SymmetricLU`.
    ``refined``: apply :func:`refine` (callers that refine anyway pass False and get ARPACK's
    vectors with their Rayleigh quotients).
    """
    n = K.shape[0]
    if n_modes >= n - 1:
        return solve_dense(K, M, n_modes, shift)
    sigma = default_shift(K, M) if shift is None else shift
    if lu is None:
        lu = factorize(K - sigma * M, groups)
    ncv = min(n, max(2 * n_modes + 1, n_modes + 32))
    for _ in range(3):
        op = spla.LinearOperator((n, n), matvec=lu.solve, dtype=float)
        try:
            _, vec = spla.eigsh(K, k=n_modes, M=M, sigma=sigma, which="LM", OPinv=op,
                                tol=tol, ncv=ncv)
            break
        except spla.ArpackNoConvergence:
            # the shift is far above the wanted eigenvalues, so their inverted values
            # cluster at 1/|sigma|: move it 1000 times closer to zero
            sigma *= 1e-3
            lu = factorize(K - sigma * M, groups)
    else:
        raise EigenSolutionError(f"Lanczos did not converge for {n_modes} modes with shifts "
                                 f"down to {sigma:.3g}")
    if not refined:
        vec = _mass_normalize(vec, M)
        lam = rayleigh_quotients(K, M, vec)
        order = np.argsort(lam)
        return EigenSolution(lam[order], vec[:, order])
    # one step with extended-precision quotients: a long cantilever's lowest eigenvalue to
    # 1e-12 - 1e-11 (ARPACK alone: 2e-8; float64 quotients: up to 4e-9)
    return refine(K, M, vec, lu.solve)


def lowest_modes(K, M, n_modes: int | None = None, cutoff_hz: float | None = None,
                 extra: int = 0, shift: float | None = None,
                 groups: np.ndarray | None = None, lu=None,
                 refined: bool = True) -> EigenSolution:
    """Lowest modes: ``n_modes + extra`` of them, or all below ``cutoff_hz`` (plus ``extra``).

    With a cutoff the sparse solver is re-run with a doubled count until the highest returned
    frequency exceeds the cutoff. ``lu``: a :class:`SymmetricLU` of K - shift M to reuse.
    """
    n = K.shape[0]
    if (n_modes is None) == (cutoff_hz is None):
        raise ValueError("give exactly one of n_modes or cutoff_hz")
    if n <= DENSE_LIMIT:
        sol = solve_dense(K, M, shift=shift)
    elif n_modes is not None:
        sol = solve_sparse(K, M, min(n_modes + extra, n - 2), shift, groups=groups, lu=lu,
                           refined=refined)
    else:
        sigma = default_shift(K, M) if shift is None else shift
        if lu is None:
            lu = factorize(K - sigma * M, groups)
        k = max(20, extra + 10)
        while True:
            sol = solve_sparse(K, M, min(k, n - 2), sigma, lu=lu, refined=refined)
            if sol.frequencies_hz[-1] > cutoff_hz or k >= n - 2:
                break
            k *= 2
    if n_modes is not None:
        if n_modes > len(sol.eigenvalues):
            raise EigenSolutionError(f"asked for {n_modes} modes but the model has only "
                                     f"{len(sol.eigenvalues)} DOFs with mass")
        count = min(n_modes + extra, len(sol.eigenvalues))
    else:
        count = min(int(np.sum(sol.frequencies_hz <= cutoff_hz)) + extra, len(sol.eigenvalues))
    return EigenSolution(sol.eigenvalues[:count], sol.vectors[:, :count])


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
                              rigid_vectors: np.ndarray, solve):
    """(rigid, flexible, RigidSplit): rigid modes = span of the geometric rigid-body vectors.

    ``vectors`` (ascending ``eigenvalues``) are computed eigenvectors that include the rigid-
    body modes. The rigid-body modes returned are ``rigid_vectors`` M-orthonormalized (eigenvalue
    zero); the flexible ones are the refined Ritz pairs (:func:`refine`) of the computed vectors
    projected on the M-orthogonal complement, so no rigid-body motion leaks into them and no
    near-zero round-off mode is kept as flexible, whatever its frequency. Ritz pairs at the zero
    level (``ZERO_RELATIVE``) are mechanism modes: returned after the rigid-body ones.
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
        W = _mass_normalize(vectors, M)
        _, _, Vt = np.linalg.svd(Phi_r.T @ (M @ W), full_matrices=True)
        W = W @ Vt[r:].T
        computed = float(np.sqrt(np.abs(eigenvalues[:r]).max()) / TWO_PI)
    else:
        Phi_r = np.zeros((K.shape[0], 0))
        W = vectors
        computed = 0.0
    flex = refine(K, M, W, solve, Phi_r)
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
    flex = EigenSolution(flex.eigenvalues[~mech], flex.vectors[:, ~mech])
    first = float(flex.frequencies_hz[0]) if len(flex.eigenvalues) else float("inf")
    return rigid, flex, RigidSplit(r, computed, first, alignment, m, mech_hz,
                                   float(np.sqrt(zero) / TWO_PI))


def free_free_modes(K, M, n_modes: int | None = None, cutoff_hz: float | None = None,
                    rigid_vectors: np.ndarray | None = None, shift: float | None = None,
                    groups: np.ndarray | None = None, guard: int = 4):
    """(rigid, flexible, RigidSplit): ``n_modes`` flexible modes or all below ``cutoff_hz``.

    The rigid-body modes are the span of ``rigid_vectors`` (the geometry's rigid-body motions,
    :meth:`~dynamics.flex.assembly.StructuralModel.rigid_body_vectors`), not a frequency
    threshold: round-off puts the computed rigid-body frequencies anywhere from 1e-8 Hz to
    1e-3 Hz (or makes them negative) for stiff, finely meshed models. ``guard`` extra modes are
    computed so that the highest kept mode has converged.
    """
    n = K.shape[0]
    r = 0 if rigid_vectors is None else rigid_vectors.shape[1]
    if rigid_vectors is None:
        rigid_vectors = np.zeros((n, 0))
    sigma = default_shift(K, M) if shift is None else shift
    lu = factorize(K - sigma * M, groups) if n > DENSE_LIMIT else None
    solve = lu.solve if lu is not None else shifted_solver(K, M, sigma, groups)
    # one factorization for Lanczos and the refinement; refined once, after the rigid split.
    # ``guard`` also covers up to that many mechanism modes (a pin in the FE model).
    if n_modes is not None:
        sol = lowest_modes(K, M, n_modes=min(n_modes + r, n), extra=guard, shift=sigma,
                           groups=groups, lu=lu, refined=False)
    else:
        sol = lowest_modes(K, M, cutoff_hz=cutoff_hz, extra=r + guard, shift=sigma,
                           groups=groups, lu=lu, refined=False)
    rigid, flex, split = separate_rigid_body_modes(K, M, sol.vectors, sol.eigenvalues,
                                                   rigid_vectors, solve)
    if np.any(flex.eigenvalues < 0.0):
        raise EigenSolutionError(f"negative eigenvalue {flex.eigenvalues.min():.3e} of a "
                                 "flexible mode: K is not positive semi-definite")
    keep = n_modes if n_modes is not None else int(np.sum(flex.frequencies_hz <= cutoff_hz))
    if n_modes is not None and len(flex.eigenvalues) < n_modes:
        raise EigenSolutionError(f"only {len(flex.eigenvalues)} flexible modes available, "
                                 f"{n_modes} requested")
    flex = EigenSolution(flex.eigenvalues[:keep], flex.vectors[:, :keep])
    return rigid, flex, split
