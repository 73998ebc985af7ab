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

from dynamics.flex.modes import (MASSLESS_RATIO, EigenSolution, default_shift, lowest_modes,
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


@dataclass
class ComponentModes:
    """Normalized component modes (:func:`normalized_component_modes`), each set over the f-set.

    rigid: the rigid-body (and zero-energy) modes removed; flexible: mass-normalized, K-diagonal;
    quasi_static: directions of the Craig-Bampton basis without mass but with stiffness (the constraint mode
    of a massless interface DOF, e.g. the relative twist of a lumped-mass CBAR line between its interface
    grids), K-orthogonal to each other and to the flexible modes, modal stiffness ``omega_ref^2`` each (the
    largest flexible eigenvalue), modal mass zero; split: the rigid/flexible report; n_massless_rigid: massless
    directions without stiffness (the spin of a lumped CBAR line, which its interface carries), removed."""

    rigid: EigenSolution
    flexible: EigenSolution
    quasi_static: EigenSolution
    split: object
    n_massless_rigid: int


def normalized_component_modes(cb: CraigBamptonModel, rigid_vectors: np.ndarray) -> ComponentModes:
    """:class:`ComponentModes` of a Craig-Bampton model (A.2.9-A.2.15), massless directions kept.

    ``rigid_vectors`` (n_f, r): the f-set rigid-body vectors; in Craig-Bampton coordinates they are
    [0; R_b] (no fixed-interface participation, the boundary values).

    The Craig-Bampton mass M_n is singular when a constraint mode of a massless interface DOF moves no mass
    (lumped-mass beams: a twist, or a bending rotation once the fixed-interface modes span the interior
    translations). With Z_q such directions of positive stiffness and Z_m those of none (M_n Z = 0, and
    K_n Z_m = 0 since K_n is positive semi-definite), the finite modes follow by static condensation of Z_q
    (exact for the eigen-problem: its rows read K_qw w + K_qq z = 0 for every eigenvalue) and are K- and
    M-orthogonal to Z_q (K x = lambda M x, M Z_q = 0); Z_q are kept as quasi-static modes: in an assembly the
    bodies attached at the interface give them inertia (the whole structure's massless DOFs are there too).
    Z_m are rigid motions without mass (the interface's hinge carries them) and are removed."""
    Mn, Kn = cb.mass, cb.stiffness
    n = Mn.shape[0]
    # unit M-norm columns (directions of different units compared), a massless column left at the scale of
    # the heaviest one
    d = np.maximum(np.diag(Mn), 0.0)
    scale = 1.0 / np.sqrt(np.where(d > 1e-12 * d.max(initial=0.0), d, max(d.max(initial=0.0), 1e-300)))
    Ms = scale[:, None] * Mn * scale
    w, V = np.linalg.eigh(0.5 * (Ms + Ms.T))
    massless = w <= MASSLESS_RATIO * w.max()
    Vw, Vz = V[:, ~massless], V[:, massless]
    quasi = np.zeros((n, 0))
    n_mech = 0
    if Vz.shape[1]:
        Z = scale[:, None] * Vz
        Kz = Z.T @ Kn @ Z
        s, U = np.linalg.eigh(0.5 * (Kz + Kz.T))
        stiff = s > 1e-10 * max(float(np.abs(np.diag(Kn) * scale * scale).max(initial=0.0)), 1e-300)
        n_mech = int(np.sum(~stiff))
        quasi = Z @ U[:, stiff]
    W = scale[:, None] * Vw
    Kw, Mw = W.T @ Kn @ W, W.T @ Mn @ W
    if quasi.shape[1]:
        Kwq = W.T @ Kn @ quasi
        Kqq = quasi.T @ Kn @ quasi
        X = -np.linalg.solve(0.5 * (Kqq + Kqq.T), Kwq.T)        # z_q = X w
        Kc = Kw + Kwq @ X
        expand = W + quasi @ X
    else:
        Kc, expand = Kw, W
    nm = cb.n_modes
    c_rigid = np.zeros((n, rigid_vectors.shape[1]))
    c_rigid[nm:] = rigid_vectors[cb.boundary]
    # rigid vectors in the condensed coordinates (their massless parts drop out: M_n-orthogonal to Z)
    c_rigid_w = np.linalg.lstsq(expand, c_rigid, rcond=None)[0]
    Kc, Mw = 0.5 * (Kc + Kc.T), 0.5 * (Mw + Mw.T)
    sol = solve_dense(Kc, Mw)
    solve = shifted_solver(Kc, Mw, default_shift(Kc, Mw, 1e-3))
    rigid, flex, split = separate_rigid_body_modes(Kc, Mw, sol.vectors, sol.eigenvalues, c_rigid_w, solve)
    flex_cb = expand @ flex.vectors
    if quasi.shape[1]:
        # K-orthogonal among themselves; scaled to the largest flexible eigenvalue, so that their coordinates
        # are commensurate with the mass-normalized ones (and convert between unit systems the same way)
        Kq = quasi.T @ Kn @ quasi
        kq, Uq = np.linalg.eigh(0.5 * (Kq + Kq.T))
        target = flex.eigenvalues.max(initial=0.0) if len(flex.eigenvalues) else kq.max()
        quasi = quasi @ (Uq * np.sqrt(target / kq))
        quasi *= np.sign(quasi[np.argmax(np.abs(quasi), axis=0), np.arange(quasi.shape[1])])
        q_lam = np.full(quasi.shape[1], np.inf)
    else:
        q_lam = np.zeros(0)
    return ComponentModes(rigid=EigenSolution(rigid.eigenvalues, cb.basis @ (expand @ rigid.vectors)),
                          flexible=EigenSolution(flex.eigenvalues, cb.basis @ flex_cb),
                          quasi_static=EigenSolution(q_lam, cb.basis @ quasi), split=split, n_massless_rigid=n_mech)


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
