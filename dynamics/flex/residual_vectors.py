"""Residual vectors (modal truncation vectors) for chosen load DOFs (FModal paper, Appendix A).

For load directions P (one unit-load column per chosen DOF) and retained mass-normalized modes
Pi, the part of the static response that the truncated modes miss is
R = K^-1 (I - M Pi Pi') P. For a free-free body Pi includes the rigid-body modes, so the
projected load is self-equilibrated and K^-1 is applied as the inertia-relief solution of the
sparse saddle-point system [[K, M Phi_r], [Phi_r' M, 0]] [x; lam] = [f; 0] (x M-orthogonal to
the rigid-body modes). R is made M-orthogonal to Pi, and the reduced eigen-problem
(R' K R) Gamma = omega_R^2 (R' M R) Gamma gives residual vectors Pi_R = R Gamma that are
mass-normalized and K-orthogonal (FModal paper App. A). When Pi are exact eigenvectors the
appended set [Pi, Pi_R] stays diagonal; for Ritz sets (normalized component modes) the
combined basis is re-diagonalized by one more small Ritz solve so that Pi' M Pi = I and
Pi' K Pi = diag hold for the whole set. Either way the enlarged set reproduces the full static
response to loads in span(P).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from dynamics.flex.modes import EigenSolution, solve_dense


def static_solve(K, M, F: np.ndarray, rigid_modes: np.ndarray | None) -> np.ndarray:
    """K x = F; for a free body (``rigid_modes`` given) the inertia-relief solution."""
    K = sp.csc_matrix(K)
    if rigid_modes is None or rigid_modes.shape[1] == 0:
        return spla.splu(K).solve(F)
    C = sp.csc_matrix(M @ rigid_modes)
    nr = C.shape[1]
    A = sp.bmat([[K, C], [C.T, sp.csc_matrix((nr, nr))]], format="csc")
    rhs = np.vstack([F, np.zeros((nr, F.shape[1]))])
    return spla.splu(A).solve(rhs)[: K.shape[0]]


def residual_vectors(K, M, modes: np.ndarray, load_dofs: np.ndarray,
                     rigid_modes: np.ndarray | None = None) -> EigenSolution:
    """Mass-normalized residual vectors for unit loads at ``load_dofs`` (f-set indices)."""
    n = K.shape[0]
    P = np.zeros((n, len(load_dofs)))
    P[np.asarray(load_dofs), np.arange(len(load_dofs))] = 1.0
    basis = modes if rigid_modes is None else np.hstack([rigid_modes, modes])
    F = P - M @ (basis @ (basis.T @ P))
    R = static_solve(K, M, F, rigid_modes)
    R = R - basis @ (basis.T @ (M @ R))
    R = R - basis @ (basis.T @ (M @ R))   # second pass: Gram-Schmidt twice is enough
    Mr = R.T @ (M @ R)
    # drop directions already represented (load DOFs whose static response the modes span)
    w, V = np.linalg.eigh(0.5 * (Mr + Mr.T))
    keep = w > 1e-10 * max(w.max(initial=0.0), 1e-300)
    R = R @ (V[:, keep] / np.sqrt(w[keep]))
    sol = solve_dense(R.T @ (K @ R), R.T @ (M @ R))
    return EigenSolution(sol.eigenvalues, R @ sol.vectors)


def append_residual_vectors(K, M, modes: EigenSolution, residual: EigenSolution,
                            tol: float = 1e-9) -> EigenSolution:
    """[modes, residual]; re-diagonalized by a Ritz solve if they are K-coupled above ``tol``."""
    B = np.hstack([modes.vectors, residual.vectors])
    lam = np.concatenate([modes.eigenvalues, residual.eigenvalues])
    Kr = B.T @ (K @ B)
    scale = max(np.abs(lam).max(initial=0.0), 1e-300)
    if np.abs(Kr - np.diag(np.diag(Kr))).max(initial=0.0) <= tol * scale:
        return EigenSolution(lam, B)
    sol = solve_dense(0.5 * (Kr + Kr.T), B.T @ (M @ B))
    return EigenSolution(sol.eigenvalues, B @ sol.vectors)
