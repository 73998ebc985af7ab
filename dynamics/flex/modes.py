"""Generalized symmetric eigen-solutions (K - omega^2 M) phi = 0 and free-free normal modes.

TM-2020-5008164 eqs. A.1.4-A.1.7: mass-normalized modes, Pi' M Pi = I, Pi' K Pi = diag(omega^2).
Large problems use scipy.sparse.linalg.eigsh in shift-invert mode (one sparse LU of K - sigma M,
ARPACK Lanczos on the inverted operator); small ones (<= ``DENSE_LIMIT`` DOFs) use LAPACK dense
solvers, which give the 1e-16-level agreement the five-particle comparisons of TM Table A1 show.
The shift is negative so that K - sigma M is non-singular for free-free bodies (K singular) and
the rigid-body modes come out first. DOFs without mass (rotations of lumped-mass beams) give
infinite eigenvalues that the inverted problem maps to zero and never returns.

Rigid-body modes are identified by a frequency threshold (FModal's rigid_body_mode_thresh) and
removed from the flexible mode set.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp
import scipy.sparse.linalg as spla

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
    """
    kd = np.abs(K.diagonal())
    md = np.abs(M.diagonal())
    mask = md > 0
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


def solve_dense(K: np.ndarray, M: np.ndarray, n_modes: int | None = None,
                shift: float | None = None) -> EigenSolution:
    """All (or the lowest ``n_modes``) eigenpairs by LAPACK; M may be singular (massless DOFs)."""
    K = np.asarray(K.toarray() if sp.issparse(K) else K, dtype=float)
    M = np.asarray(M.toarray() if sp.issparse(M) else M, dtype=float)
    try:
        mass_range = sla.eigvalsh(M)
        if mass_range[0] <= MASSLESS_RATIO * mass_range[-1]:
            raise np.linalg.LinAlgError("M is numerically singular")
        lam, vec = sla.eigh(K, M)
        # Rayleigh quotients: LAPACK's eigenvalues of rigid-body modes carry round-off of order
        # eps ||M^-1 K||, the quotients of the (accurate) vectors of order eps^2 ||M^-1 K||.
        lam = np.einsum("ij,ij->j", vec, K @ vec) / np.einsum("ij,ij->j", vec, M @ vec)
    except np.linalg.LinAlgError:
        # M singular (massless DOFs): M x = mu (K - sigma M) x, lambda = sigma + 1/mu.
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


class SymmetricLU:
    """Sparse LU of a symmetric positive-definite matrix with a fill-reducing grid ordering.

    When ``groups`` (the grid of every DOF) is given, COLAMD orders the grid graph and the
    DOFs of a grid are kept together (about a third less fill than ordering the DOFs of a
    beam lattice directly); the factorization then runs without pivoting in SuperLU's
    symmetric mode. Without groups, SuperLU's default (COLAMD on the DOFs, partial pivoting).
    """

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
                 lu=None, groups: np.ndarray | None = None) -> EigenSolution:
    """Lowest ``n_modes`` eigenpairs by shift-invert Lanczos (scipy eigsh, ARPACK).

    ``groups``: grid index of every DOF, for the fill-reducing ordering of :class:`SymmetricLU`.
    """
    n = K.shape[0]
    if n_modes >= n - 1:
        return solve_dense(K, M, n_modes, shift)
    sigma = default_shift(K, M) if shift is None else shift
    if lu is None:
        lu = SymmetricLU(K - sigma * M, groups)
    op = spla.LinearOperator((n, n), matvec=lu.solve, dtype=float)
    ncv = min(n, max(2 * n_modes + 1, n_modes + 32))
    lam, vec = spla.eigsh(K, k=n_modes, M=M, sigma=sigma, which="LM", OPinv=op,
                          tol=tol, ncv=ncv)
    order = np.argsort(lam)
    lam, vec = lam[order], vec[:, order]
    vec = _mass_normalize(vec, M)
    return EigenSolution(lam, _sign_convention(vec))


def lowest_modes(K, M, n_modes: int | None = None, cutoff_hz: float | None = None,
                 extra: int = 0, shift: float | None = None,
                 groups: np.ndarray | None = None) -> EigenSolution:
    """Lowest modes: ``n_modes + extra`` of them, or all below ``cutoff_hz`` (plus ``extra``).

    With a cutoff the sparse solver is re-run with a doubled count until the highest returned
    frequency exceeds the cutoff.
    """
    n = K.shape[0]
    if (n_modes is None) == (cutoff_hz is None):
        raise ValueError("give exactly one of n_modes or cutoff_hz")
    if n <= DENSE_LIMIT:
        sol = solve_dense(K, M, shift=shift)
    elif n_modes is not None:
        sol = solve_sparse(K, M, min(n_modes + extra, n - 2), shift, groups=groups)
    else:
        sigma = default_shift(K, M) if shift is None else shift
        lu = SymmetricLU(K - sigma * M, groups)
        k = max(20, extra + 10)
        while True:
            sol = solve_sparse(K, M, min(k, n - 2), sigma, lu=lu)
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


def split_rigid(sol: EigenSolution, threshold_hz: float) -> tuple[EigenSolution, EigenSolution]:
    """(rigid-body modes with |f| < threshold, flexible modes)."""
    rigid = np.abs(sol.frequencies_hz) < threshold_hz
    return (EigenSolution(sol.eigenvalues[rigid], sol.vectors[:, rigid]),
            EigenSolution(sol.eigenvalues[~rigid], sol.vectors[:, ~rigid]))


def free_free_modes(K, M, n_modes: int | None = None, cutoff_hz: float | None = None,
                    rigid_threshold_hz: float = 1e-4, max_rigid: int = 6,
                    shift: float | None = None, groups: np.ndarray | None = None):
    """Rigid-body modes and ``n_modes`` flexible modes (or all flexible below ``cutoff_hz``)."""
    if n_modes is not None:
        sol = lowest_modes(K, M, n_modes=n_modes, extra=max_rigid, shift=shift, groups=groups)
    else:
        sol = lowest_modes(K, M, cutoff_hz=cutoff_hz, shift=shift, groups=groups)
    rigid, flex = split_rigid(sol, rigid_threshold_hz)
    if np.any(flex.eigenvalues < 0.0):
        raise EigenSolutionError(f"negative eigenvalue {flex.eigenvalues.min():.3e} above the "
                                 "rigid-body threshold: K is not positive semi-definite")
    if n_modes is not None:
        if len(flex.eigenvalues) < n_modes:
            raise EigenSolutionError(f"only {len(flex.eigenvalues)} flexible modes available, "
                                     f"{n_modes} requested")
        flex = EigenSolution(flex.eigenvalues[:n_modes], flex.vectors[:, :n_modes])
    return rigid, flex
