"""Craig-Bampton reduction and normalized component modes (TM-2020-5008164 Appendix A.2).

Partition the f-set into boundary (a-set) DOFs b and interior DOFs e (eq. A.2.1). Constraint
modes Pi_b = -K_ee^-1 K_eb (eq. A.2.3, one sparse LU of K_ee); fixed-interface modes Pi_e from
(K_ee - zeta M_ee) phi = 0 (eqs. A.2.4-A.2.7). The Craig-Bampton basis
Pi_c = [[Pi_e, Pi_b], [0, I]] (eq. A.2.2) gives M_n = Pi_c' M Pi_c, K_n = Pi_c' K Pi_c
(eqs. A.2.8, A.2.10-A.2.11). Normalized component modes solve (K_n - zeta M_n) Pi_hat = 0 (eq.
A.2.9) and Pi_n = Pi_c Pi_hat (eq. A.2.12) is mass-normalized and diagonalizes K (eqs.
A.2.13-A.2.15); its rigid-body modes, the span of the geometry's rigid-body vectors (which
the constraint modes reproduce: Pi_b R_b = R_e when K R = 0), are removed as in
:func:`dynamics.flex.modes.separate_rigid_body_modes`. Because span(Pi_n) =
span(Pi_c), constraining the interface DOFs of the normalized component model recovers the
retained fixed-interface modes exactly (TM Table A1, comparison 4).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from dynamics.flex.modes import (EigenSolution, default_shift, lowest_modes,
                                 separate_rigid_body_modes, shifted_solver, solve_dense)


class CraigBamptonError(ValueError):
    """A Craig-Bampton reduction that cannot be formed (e.g. singular interior stiffness)."""


@dataclass
class CraigBamptonModel:
    """Craig-Bampton reduction of an f-set model.

    boundary : (n_b,) f-set indices of the a-set DOFs.
    fixed_interface : fixed-interface modes (eigenvalues [rad^2/s^2], vectors over the interior).
    basis : (n_f, n_m + n_b) dense Pi_c in f-set DOF order; columns [modes, constraint modes].
    mass, stiffness : (n_m + n_b)^2 reduced matrices M_n, K_n.
    """

    boundary: np.ndarray
    interior: np.ndarray
    fixed_interface: EigenSolution
    basis: np.ndarray
    mass: np.ndarray
    stiffness: np.ndarray

    @property
    def n_modes(self) -> int:
        return len(self.fixed_interface.eigenvalues)


def _check_factor(lu, K_ee, interior, describe) -> None:
    d = np.abs(lu.U.diagonal())
    if d.size and (d.min() <= 1e-12 * d.max()):
        worst = lu.perm_c[int(np.argmin(d))]
        raise CraigBamptonError(
            "interior stiffness K_ee is singular: the a-set does not restrain every rigid-body "
            f"or mechanism motion of the body (first null pivot at {describe(interior[worst])}); "
            "add the interface DOFs that hold the body to the a-set")


def craig_bampton(K, M, boundary: np.ndarray, n_modes: int | None = None,
                  cutoff_hz: float | None = None, describe=str,
                  groups: np.ndarray | None = None) -> CraigBamptonModel:
    """Craig-Bampton model for boundary DOFs ``boundary`` (f-set indices).

    ``describe(f_index)`` names a DOF in error messages (e.g. "grid 12 component 3");
    ``groups`` (grid of each f-set DOF) orders the sparse factorizations.
    """
    K = sp.csr_matrix(K)
    M = sp.csr_matrix(M)
    n = K.shape[0]
    boundary = np.unique(np.asarray(boundary, dtype=np.int64))
    if len(boundary) == 0:
        raise CraigBamptonError("empty a-set")
    interior = np.setdiff1d(np.arange(n), boundary)
    if len(interior) == 0:
        raise CraigBamptonError("the a-set holds every DOF; nothing is left to reduce")
    K_ee = K[interior][:, interior].tocsc()
    M_ee = M[interior][:, interior].tocsr()
    K_eb = K[interior][:, boundary]
    try:
        lu = spla.splu(K_ee)
    except RuntimeError as exc:
        raise CraigBamptonError(
            "interior stiffness K_ee is exactly singular: the a-set does not restrain the "
            f"body ({exc}); add the interface DOFs that hold the body to the a-set") from exc
    _check_factor(lu, K_ee, interior, describe)
    constraint = -lu.solve(np.asarray(K_eb.todense()))
    if n_modes == 0:
        fixed = EigenSolution(np.zeros(0), np.zeros((len(interior), 0)))
    else:
        fixed = lowest_modes(K_ee, M_ee, n_modes=n_modes, cutoff_hz=cutoff_hz,
                             groups=None if groups is None else groups[interior])
    nm, nb = fixed.vectors.shape[1], len(boundary)
    basis = np.zeros((n, nm + nb))
    basis[interior, :nm] = fixed.vectors
    basis[interior, nm:] = constraint
    basis[boundary, nm:] = np.eye(nb)
    Mn = basis.T @ (M @ basis)
    Kn = basis.T @ (K @ basis)
    return CraigBamptonModel(boundary=boundary, interior=interior, fixed_interface=fixed,
                             basis=basis, mass=0.5 * (Mn + Mn.T), stiffness=0.5 * (Kn + Kn.T))


def normalized_component_modes(cb: CraigBamptonModel, rigid_vectors: np.ndarray):
    """(rigid, flexible, RigidSplit) normalized component modes over the f-set (A.2.9-A.2.15).

    ``rigid_vectors`` (n_f, r): the f-set rigid-body vectors; in Craig-Bampton coordinates they
    are [0; R_b] (no fixed-interface participation, the boundary values).
    """
    sol = solve_dense(cb.stiffness, cb.mass)
    nm = cb.n_modes
    c_rigid = np.zeros((cb.mass.shape[0], rigid_vectors.shape[1]))
    c_rigid[nm:] = rigid_vectors[cb.boundary]
    solve = shifted_solver(cb.stiffness, cb.mass, default_shift(cb.stiffness, cb.mass, 1e-3))
    rigid, flex, split = separate_rigid_body_modes(cb.stiffness, cb.mass, sol.vectors,
                                                   sol.eigenvalues, c_rigid, solve)
    return (EigenSolution(rigid.eigenvalues, cb.basis @ rigid.vectors),
            EigenSolution(flex.eigenvalues, cb.basis @ flex.vectors), split)


def constrained_modes(modes: np.ndarray, stiffness: np.ndarray, mass: np.ndarray,
                      constrained_rows: np.ndarray) -> EigenSolution:
    """Modes of a reduced model u = modes @ eta with u[constrained_rows] = 0 enforced.

    The admissible coordinates are the null space of modes[constrained_rows]; the result is
    returned as physical vectors. Used to check that normalized component modes reproduce the
    fixed-interface modes when the interface is held (TM Appendix A.3, comparisons 2 and 4).
    """
    Z = sla.null_space(modes[constrained_rows], rcond=1e-10)
    sol = solve_dense(Z.T @ stiffness @ Z, Z.T @ mass @ Z)
    return EigenSolution(sol.eigenvalues, modes @ (Z @ sol.vectors))
