"""System modes of a multibody model at rest and their comparison with a finite-element solution.

Linearization at rest without gravity is exact with the engine's own matrices: the generalized
stiffness ``K`` (modal stiffness blocks) and the mass matrix ``M(q0)`` (composite-body algorithm
over the modal-integral mass matrices, TM-2020-5008164 eq. E.2.6). Closure constraints restrict the
velocities to the null space ``Z`` of their Jacobian ``G(q0)``; at rest the constraint forces vanish,
so the constrained system modes solve ``Z'KZ x = omega^2 Z'MZ x`` with ``phi = Z x`` exactly (FModal
paper, "Modal comparisons" and "Closure Constraints").

Mode shapes are compared on FE grids: the multibody's node motion per unit modal amplitude (the node
velocities for ``u = phi``, which are the linearized node displacements) against the FE eigenvector
at the same grids, both as ``[translation; rotation]`` in world (basic) axes. Each mode is scaled to
unit Euclidean norm over the compared DOFs and its sign aligned before the Frobenius norm of the
difference of the two shape matrices is taken.

Also the NASTRAN bulk-data writer used to build whole-structure decks (GRID, CBEAM, PBEAM, MAT1,
RBE2, SPC1, CONM2) for those comparisons.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np
import scipy.linalg as sla

DEFAULT_RIGID_THRESHOLD_HZ = 1e-4


class SystemModes(NamedTuple):
    frequencies_hz: np.ndarray  # (k,) flexible modes, ascending
    vectors: np.ndarray  # (nu, k) u-space shapes, phi' M phi = I
    n_rigid: int  # modes below the rigid threshold (removed)


def system_modes(system, q0, constrained=None, rigid_threshold_hz=DEFAULT_RIGID_THRESHOLD_HZ):
    """Flexible system modes at rest: ``K phi = omega^2 M(q0) phi`` on the admissible velocities.

    ``constrained``: a :class:`dynamics.constraints.ConstrainedSystem` over ``system`` (closure
    constraints), or None. Refuses gravity (the linearization would need its geometric stiffness). A mass
    matrix singular in some directions (quasi-static modes that nothing with inertia is attached to) is
    solved by the inverted problem, which condenses those directions statically.
    """
    if np.any(system.gravity):
        raise ValueError(f"system_modes linearizes at rest without gravity; the system has gravity "
                         f"{system.gravity.tolist()} m/s^2 (build it with gravity=(0, 0, 0))")
    M = system.mass_matrix(q0)
    K = system.stiffness_matrix()
    if constrained is not None:
        Z = constrained.null_space(q0)
        M = Z.T @ M @ Z
        K = Z.T @ K @ Z
    else:
        Z = np.eye(system.nu)
    M, K = 0.5 * (M + M.T), 0.5 * (K + K.T)
    mass_range = np.linalg.eigvalsh(M)
    if mass_range[0] <= 1e-12 * mass_range[-1]:
        # directions without inertia: a quasi-static mode of a body whose interface drives only massless
        # motion in the scene (a lumped-mass frame's joint rotation about the next beam's axis). The structure
        # responds there statically, as a FE model's massless DOFs do: the inverted problem drops them.
        from dynamics.flex.modes import solve_dense
        sol = solve_dense(K, M)
        w2, X = sol.eigenvalues, sol.vectors
    else:
        w2, X = sla.eigh(K, M)
    freq = np.sqrt(np.abs(w2)) / (2.0 * np.pi)
    flexible = freq > rigid_threshold_hz
    return SystemModes(freq[flexible], Z @ X[:, flexible], int(np.count_nonzero(~flexible)))


def node_motion(system, q0, vectors, nodes):
    """(k, len(nodes), 6) linearized motion ``[translation; rotation]`` of nodes, world axes, per mode."""
    index = [system.node_index(n) for n in nodes]
    out = np.empty((vectors.shape[1], len(index), 6))
    for m in range(vectors.shape[1]):
        kin = system.node_kinematics(q0, vectors[:, m])
        R = kin.rotation[index]
        out[m, :, :3] = np.einsum("nab,nb->na", R, kin.linear_velocity[index])
        out[m, :, 3:] = np.einsum("nab,nb->na", R, kin.angular_velocity[index])
    return out


def fe_grid_motion(body, grids, n):
    """(n, len(grids), 6) ``[translation; rotation]`` of the first n modes of a ModalBody (basic axes)."""
    ids = np.asarray(body.grid_ids)
    rows = np.array([int(np.flatnonzero(ids == g)[0]) for g in grids])
    out = np.empty((n, len(rows), 6))
    out[:, :, :3] = body.translation_shapes[rows, :, :n].transpose(2, 0, 1)
    out[:, :, 3:] = body.rotation_shapes[rows, :, :n].transpose(2, 0, 1)
    return out


@dataclass
class ModeComparison:
    frequencies_fe_hz: np.ndarray
    frequencies_mb_hz: np.ndarray
    frequency_difference_hz: np.ndarray  # multibody - FE
    shape_difference: np.ndarray  # per mode, unit-norm shapes after sign alignment
    mac: np.ndarray  # modal assurance criterion per mode pair

    @property
    def max_frequency_difference_hz(self):
        return float(np.abs(self.frequency_difference_hz).max())

    @property
    def shape_frobenius(self):
        """Frobenius norm of the difference of the (unit-norm, sign-aligned) shape matrices."""
        return float(np.sqrt(np.sum(self.shape_difference ** 2)))


def compare_modes(freq_fe, shapes_fe, freq_mb, shapes_mb):
    """Compare the first ``k = len(freq_fe)`` modes; shapes are (k, grids, 6) as from node_motion."""
    k = len(freq_fe)
    A = shapes_fe[:k].reshape(k, -1)
    B = shapes_mb[:k].reshape(k, -1)
    A = A / np.linalg.norm(A, axis=1, keepdims=True)
    B = B / np.linalg.norm(B, axis=1, keepdims=True)
    dots = np.sum(A * B, axis=1)
    B = B * np.where(dots < 0.0, -1.0, 1.0)[:, None]
    return ModeComparison(np.asarray(freq_fe[:k]), np.asarray(freq_mb[:k]),
                          np.asarray(freq_mb[:k]) - np.asarray(freq_fe[:k]),
                          np.linalg.norm(A - B, axis=1), dots ** 2)


def rest_body_data(body, modes=None, interface_grid=None):
    """:class:`dynamics.flexible_body.FlexibleBodyData` at order 0 straight from a ModalBody's nodes.

    ``M0 = sum_j Y_j' M_j Y_j`` (TM eq. E.1.34 at eta = 0) with the node spatial inertia ``M_j``
    (mass, CG offset, inertia about the grid, from the lumped mass matrix) and ``Y_j = [[I, 0, lambda_j],
    [-l0_j~, I, gamma_j]]`` mapping ``[omega; v; eta_dot]`` to the node's spatial velocity. This is all a
    linearization at rest needs; it costs O(N n^2) where the full modal integrals of
    ``fem2modal(..., modal_integrals=True)`` cost O(N n^3) to O(N n^4), so complete mode sets (hundreds
    of modes) can be assembled. Order 0 keeps ``M(eta) = M0``: use it for modes at rest, not for motion.

    ``interface_grid``: measure the deformation relative to that grid's frame, i.e. subtract from every
    mode the rigid motion that carries the grid's own deformation (``lambda_j -= lambda_g``,
    ``gamma_j -= gamma_g + lambda_g x (l0_j - l0_g)``). The grid then does not deform, so a hinge at the
    body frame placed on that grid holds the deformed grid, as a hinge attached to a node of the child
    would. For a free FE body the rigid motion stores no strain energy, so the modal stiffness is
    unchanged; the mass matrix follows from the new shapes.
    """
    from dynamics.flexible_body import FlexibleBodyData
    from dynamics.spatial import skew

    keep = np.arange(body.n_modes) if modes is None else np.asarray(modes, dtype=np.int64)
    n = keep.size
    lam = body.rotation_shapes[:, :, keep]
    gam = body.translation_shapes[:, :, keep]
    if interface_grid is not None:
        g = int(np.flatnonzero(np.asarray(body.grid_ids) == interface_grid)[0])
        arm = body.grid_positions - body.grid_positions[g]
        gam = gam - gam[g][None] - np.einsum("jab,bk->jak", -skew_rows(arm), lam[g])
        lam = lam - lam[g][None]
    N = 6 + n
    M0 = np.zeros((N, N))
    Y = np.zeros((6, N))
    for j in range(len(body.grid_ids)):
        m = body.node_mass[j]
        Jn = body.node_inertia[j]
        if m == 0.0 and not np.any(Jn):
            continue
        c = body.node_cm_offset[j]
        Mj = np.zeros((6, 6))
        Mj[:3, :3] = Jn
        Mj[:3, 3:] = m * skew(c)
        Mj[3:, :3] = -m * skew(c)
        Mj[3:, 3:] = m * np.eye(3)
        Y[:, :] = 0.0
        Y[:3, :3] = np.eye(3)
        Y[3:, :3] = -skew(body.grid_positions[j])
        Y[3:, 3:6] = np.eye(3)
        Y[:3, 6:] = lam[j]
        Y[3:, 6:] = gam[j]
        M0 += Y.T @ Mj @ Y
    M0 = 0.5 * (M0 + M0.T)
    shapes = np.concatenate([lam, gam], axis=1)
    return FlexibleBodyData(n_modes=n, order=0, M0=M0, M1=np.zeros((n, N, N)), M2=np.zeros((n, n, 0, 0)),
                            stiffness=np.asarray(body.modal_stiffness)[np.ix_(keep, keep)],
                            damping=np.asarray(body.modal_damping)[np.ix_(keep, keep)],
                            grid_ids=np.asarray(body.grid_ids), grid_positions=np.asarray(body.grid_positions),
                            grid_shapes=shapes, frequencies_hz=np.asarray(body.frequencies_hz)[keep],
                            source=f"{body.source} (order 0, rest)")


def skew_rows(v):
    """(k, 3) -> (k, 3, 3) cross-product matrices."""
    S = np.zeros(v.shape + (3,))
    S[:, 0, 1], S[:, 0, 2], S[:, 1, 2] = -v[:, 2], v[:, 1], -v[:, 0]
    S[:, 1, 0], S[:, 2, 0], S[:, 2, 1] = v[:, 2], -v[:, 1], v[:, 0]
    return S


# ---------------------------------------------------------------------- bulk-data writer
@dataclass
class BeamDeck:
    """A NASTRAN bulk-data deck of CBEAMs on one PBEAM/MAT1, written with :meth:`write`.

    Material and section default to the FModal paper's single-length beam (Appendix C), including its
    PBEAM continuation lines, which set the shear factors K1 = K2 = 0 (Euler-Bernoulli elements)."""

    E: float = 2.0e9
    G: float = 775193798.449612
    rho: float = 8000.0
    area: float = 2.0e-2
    I1: float = 6.66666667e-05
    I2: float = 1.66666667e-05
    J: float = 8.33333333e-05
    grids: dict = field(default_factory=dict)  # id -> (x, y, z)
    beams: list = field(default_factory=list)  # (eid, ga, gb, orientation vector)
    rbe2: list = field(default_factory=list)  # (eid, independent grid, components, dependent grid)
    spc: list = field(default_factory=list)  # (grid, components)
    conm2: list = field(default_factory=list)  # (eid, grid, mass, CG offset from the grid, inertia about the CG)

    def add_line(self, first_id, start, direction, length, n_elements, orientation, first_eid,
                 start_grid=None):
        """Grids ``first_id, ...`` from ``start`` along ``direction`` and the CBEAMs joining them.

        ``start_grid`` reuses an existing grid as the first node (a welded joint). Returns the ids."""
        direction = np.asarray(direction, dtype=float)
        ids = []
        for k in range(n_elements + 1):
            if k == 0 and start_grid is not None:
                ids.append(start_grid)
                continue
            gid = first_id + k
            self.grids[gid] = np.asarray(start, dtype=float) + direction * (length * k / n_elements)
            ids.append(gid)
        for k in range(n_elements):
            self.beams.append((first_eid + k, ids[k], ids[k + 1], np.asarray(orientation, dtype=float)))
        return ids

    def write(self, path, title="generated by dynamics.modal_analysis.BeamDeck"):
        f = _field
        lines = [f"$ {title}"]
        for gid in sorted(self.grids):
            x = self.grids[gid]
            lines.append(f"GRID, {gid}, 0, {f(x[0])}, {f(x[1])}, {f(x[2])}, 0")
        for eid, ga, gb, v in self.beams:
            lines.append(f"CBEAM, {eid}, 1, {ga}, {gb}, {f(v[0])}, {f(v[1])}, {f(v[2])}")
        for eid, gn, cm, gm in self.rbe2:
            lines.append(f"RBE2, {eid}, {gn}, {cm}, {gm}")
        for gid, comps in self.spc:
            lines.append(f"SPC1, 1, {comps}, {gid}")
        for eid, gid, mass, offset, J in self.conm2:
            J = np.asarray(J, dtype=float)
            x = np.asarray(offset, dtype=float)
            lines.append(f"CONM2, {eid}, {gid}, 0, {f(mass)}, {f(x[0])}, {f(x[1])}, {f(x[2])}")
            # CONM2 I21, I31, I32 are the negated off-diagonal entries of the inertia matrix (NASTRAN
            # sign convention, as dynamics.flex.elements.conm2_inertia reads them back)
            lines.append(f", {f(J[0, 0])}, {f(-J[1, 0])}, {f(J[1, 1])}, {f(-J[2, 0])}, {f(-J[2, 1])}, {f(J[2, 2])}")
        lines.append(f"MAT1, 1, {f(self.E)}, {f(self.G)}, , {f(self.rho)}")
        lines.append(f"PBEAM, 1, 1, {f(self.area)}, {f(self.I1)}, {f(self.I2)}, 0., {f(self.J)}, 0.")
        lines.append(", 0., 0., 0., 0., 0., 0., 0., 0.")
        lines.append(", 0., 0., 0., 0., 0., 0., 0., 0.")
        lines.append(", 0., 0., 0., 0., 0., 0., 0., 0.")  # K1 = K2 = 0: no shear flexibility
        lines.append("ENDDATA")
        with open(path, "w") as fh:
            fh.write("\n".join(lines) + "\n")
        return path


def _field(x):
    """A free-field real with 16 significant digits' worth of the value NASTRAN will read back."""
    return repr(float(x))
