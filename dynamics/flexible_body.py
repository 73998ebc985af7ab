"""Flexible-body data for the engine: the deformation-dependent mass matrix as a polynomial in eta.

A flexible body's generalized velocity is ``x = [V; eta_dot]`` (its reference frame's spatial velocity
``V = [omega; v]`` in body axes, then the modal rates). Its kinetic energy is ``T = 1/2 x' M(eta) x`` with

    M(eta) = M0 + sum_r M1[r] eta_r + sum_rs M2[r, s] eta_r eta_s            (N x N, N = 6 + n)

the body mass matrix of TM-2020-5008164 eqs. E.1.34 and E.2.6 (blocks from the modal integrals
E.2.2-E.2.5), re-ordered here as [omega, v, eta]. ``M2[r, s]`` is stored symmetric in (r, s) and as a
matrix. The modal-integral ``order`` selects the fidelity (issue 4): 0 keeps ``M0`` only (constant
mass matrix, rigid/elastic coupling through the participation factors F0, E0 only: the "linear
superposition" level of TM Section 7.2), 1 adds the first-order terms, 2 is the full expansion.

The equations of motion follow from Lagrange's equations for ``eta`` and the Euler-Poincare (Kirchhoff)
equations for the quasi-velocity ``V`` (see :mod:`dynamics.flexible_kernels`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from dynamics.builder import ModelDefinitionError
from dynamics.spatial import skew


@dataclass
class FlexibleBodyData:
    """Modal data of one flexible body, ready for the engine (SI units, body frame)."""

    n_modes: int
    order: int
    M0: np.ndarray  # (N, N)
    M1: np.ndarray  # (n, N, N) at order >= 1, else empty
    M2: np.ndarray  # (n, n, N, N) at order 2, else empty
    stiffness: np.ndarray  # (n, n) modal stiffness
    damping: np.ndarray  # (n, n) modal damping
    grid_ids: np.ndarray  # (G,) grids whose shapes are available for nodes
    grid_positions: np.ndarray  # (G, 3) undeformed positions l0 in the body frame
    grid_shapes: np.ndarray  # (G, 6, n) Pi(j) = [lambda; gamma]
    frequencies_hz: np.ndarray  # (n,)
    source: str = "arrays"

    @property
    def mass(self):
        return float(self.M0[3, 3])

    def grid_index(self, grid_id):
        hits = np.flatnonzero(self.grid_ids == grid_id)
        if hits.size == 0:
            raise ModelDefinitionError(f"grid {grid_id} is not in the flexible body's modal data "
                                       f"({self.source}); grids run from {self.grid_ids.min()} to "
                                       f"{self.grid_ids.max()}")
        return int(hits[0])


def mass_matrix_polynomial(mi, order):
    """(M0, M1, M2) in [omega, v, eta] order from a ``dynamics.flex.modal_integrals.ModalIntegrals``.

    Only the terms of the requested order are allocated (M2 alone is n^2 (6 + n)^2 numbers)."""
    n = mi.p1.shape[0]
    N = 6 + n
    M0 = np.zeros((N, N))
    M1 = np.zeros((n, N, N) if order >= 1 else (0, N, N))
    M2 = np.zeros((n, n, N, N) if order >= 2 else (0, 0, N, N))
    m = float(mi.mass)
    M0[:3, :3] = mi.J0
    M0[:3, 3:6] = m * skew(mi.p0)
    M0[3:6, :3] = -m * skew(mi.p0)
    M0[3:6, 3:6] = m * np.eye(3)
    M0[:3, 6:] = mi.F0.T
    M0[3:6, 6:] = mi.E0.T
    M0[6:, 6:] = mi.G0
    if order >= 1:
        for r in range(n):
            M1[r, :3, :3] = mi.J1[r] + mi.J1[r].T
            M1[r, :3, 3:6] = m * skew(mi.p1[r])
            M1[r, 3:6, :3] = -m * skew(mi.p1[r])
            M1[r, :3, 6:] = mi.F1[:, r, :].T  # F(s) gains F1[s, r] eta_r
            M1[r, 3:6, 6:] = mi.E1[:, r, :].T
            M1[r, 6:, 6:] = mi.G1[:, :, r] + mi.G1[:, :, r].T
    if order >= 2:
        J2 = 0.5 * (mi.J2 + mi.J2.transpose(1, 0, 3, 2))  # symmetric in (r, s) as matrices
        M2[:, :, :3, :3] = 0.5 * (J2 + J2.transpose(0, 1, 3, 2))
        F2 = 0.5 * (mi.F2 + mi.F2.transpose(0, 2, 1, 3))  # (r, s, l, a) symmetric in (s, l)
        M2[:, :, :3, 6:] = F2.transpose(1, 2, 3, 0)
        if mi.G2 is not None:
            G2 = 0.25 * (mi.G2 + mi.G2.transpose(1, 0, 2, 3) + mi.G2.transpose(0, 1, 3, 2)
                         + mi.G2.transpose(1, 0, 3, 2))
            M2[:, :, 6:, 6:] = G2.transpose(2, 3, 0, 1)
    # the modal/rigid blocks mirror the rigid/modal ones (the rigid and modal diagonal blocks are
    # symmetric by construction above)
    M0[6:, :6] = M0[:6, 6:].T
    for r in range(M1.shape[0]):
        M1[r, 6:, :6] = M1[r, :6, 6:].T
        for s in range(M2.shape[1] if r < M2.shape[0] else 0):
            M2[r, s, 6:, :6] = M2[r, s, :6, 6:].T
    return M0, M1, M2


def flexible_body_from_modal_body(body, modes=None, order=2, damping_ratio=None, integrals="general"):
    """Build :class:`FlexibleBodyData` from a ``dynamics.flex.body_file.ModalBody`` (a body file).

    ``modes``: indices of the modes to keep (default all); ``order``: modal-integral order 0, 1, 2;
    ``damping_ratio``: overrides the file's damping (scalar or per kept mode); ``integrals``:
    ``"general"`` (nodes with their own inertia and offsets, E.2.2-E.2.5) or ``"point_mass"`` (E.3.1).
    """
    if order not in (0, 1, 2):
        raise ModelDefinitionError(f"modal-integral order must be 0, 1 or 2, got {order!r}")
    mi = body.modal_integrals if integrals == "general" else body.point_mass_integrals
    if mi is None:
        raise ModelDefinitionError(
            f"{body.source}: the body file has no {integrals} modal integrals; regenerate it with "
            f"`flexshell fem2modal ... --modal-integrals`")
    n_all = body.n_modes
    keep = np.arange(n_all) if modes is None else np.asarray(modes, dtype=np.int64)
    if keep.size == 0 or keep.min() < 0 or keep.max() >= n_all:
        raise ModelDefinitionError(f"{body.source}: modes {keep.tolist()} out of range 0..{n_all - 1}")
    if order == 2 and mi.G2 is None and integrals == "general" and np.any(body.node_inertia):
        raise ModelDefinitionError(
            f"{body.source}: order-2 modal integrals need G2, which the body file omits (too many modes "
            f"for the n^4 table); select fewer modes when generating it, or use order 1")
    sub = _select_modes(mi, keep)
    M0, M1, M2 = mass_matrix_polynomial(sub, order)
    K = np.asarray(body.modal_stiffness)[np.ix_(keep, keep)]
    if damping_ratio is None:
        C = np.asarray(body.modal_damping)[np.ix_(keep, keep)]
    else:
        zeta = np.broadcast_to(np.asarray(damping_ratio, dtype=float), keep.shape)
        omega = 2.0 * np.pi * np.asarray(body.frequencies_hz)[keep]
        C = np.diag(2.0 * zeta * omega)
    shapes = np.concatenate([body.rotation_shapes[:, :, keep], body.translation_shapes[:, :, keep]], axis=1)
    return FlexibleBodyData(n_modes=int(keep.size), order=order, M0=M0, M1=M1, M2=M2, stiffness=K,
                            damping=C, grid_ids=np.asarray(body.grid_ids), grid_positions=body.grid_positions,
                            grid_shapes=shapes, frequencies_hz=np.asarray(body.frequencies_hz)[keep],
                            source=body.source)


def _select_modes(mi, keep):
    from dynamics.flex.modal_integrals import ModalIntegrals

    ix = np.ix_
    return ModalIntegrals(
        mass=mi.mass, p0=mi.p0, J0=mi.J0, p1=mi.p1[keep], J1=mi.J1[keep], J2=mi.J2[ix(keep, keep)],
        F0=mi.F0[keep], F1=mi.F1[ix(keep, keep)], F2=mi.F2[ix(keep, keep, keep)], E0=mi.E0[keep],
        E1=mi.E1[ix(keep, keep)], G0=mi.G0[ix(keep, keep)], G1=mi.G1[ix(keep, keep, keep)],
        G2=None if mi.G2 is None else mi.G2[ix(keep, keep, keep, keep)])
