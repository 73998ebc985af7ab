"""Closure constraints (cut joints) on a tree: closed loops, fixed-fixed and multiply supported bodies.

A closed-chain system is cut into a spanning tree (a :class:`dynamics.MultibodySystem`) plus closure
constraints, each tying a node frame B to a node frame A (FModal paper, IEEE Aerospace 2023,
"Closure Constraints"; Jain, *Robot and Multibody Dynamics*, 2011, ch. 11). Nodes on flexible bodies
move with their elastic deformation, so a constraint holds the *deformed* node frames together.

Constraint coordinates (frame A = node ``node_a``; frame B = node ``node_b``, or a fixed world pose):

    phi(q)      = S [ log(R_A' R_B) ; R_A' (p_B - p_A) ]                       position residual
                  (revolute: n x (R_A' R_B n) replaces the log, so that d phi/dt = G u exactly)
    G(q) u      = S [ R_A' (w_B - w_A) ; R_A' (v_B - v_A) ]                    relative velocity, A axes
    G u_dot + k = S [ R_A'(dw_B - dw_A) - w_A x R_A'(w_B - w_A) ;
                      R_A'(a_B - a_A)  - w_A x R_A'(v_B - v_A) ]               relative acceleration

with world-axes angular/linear velocities ``w, v`` and accelerations ``dw, a`` of the node origins,
``w_A`` in A axes in the cross products, and ``k = G_dot u`` obtained from the node accelerations at
``u_dot = 0`` (the engine's node kinematics are affine in ``u_dot``). ``S`` selects the constrained
directions: all six (``weld``), the three translations (``ball``), or the translations and the two
rotations perpendicular to an axis fixed in A (``revolute``).

Dynamics (index-1 form with Baumgarte stabilization, Baumgarte 1972):

    M u_dot = tau - bias + G' lambda,
    G u_dot = -k - 2 alpha G u - beta^2 phi,

solved by eliminating ``u_dot``: ``(G M^-1 G') lambda = -k - 2 alpha G u - beta^2 phi - G M^-1 (tau -
bias)``. Redundant constraints (a planar loop closed by a spatial revolute) make ``G M^-1 G'``
singular; the minimum-norm multipliers of its pseudo-inverse are used (rank from an SVD, relative
tolerance 1e-10), so the motion is unique and the reactions are the minimum-norm set. ``lambda`` is
the spatial force ``[torque; force]`` that A exerts on B, in A axes, at the origin of B.

Drift: Baumgarte terms damp constraint errors during integration; :meth:`ConstrainedSystem.project`
removes them after a step (Newton iterations on ``phi(q) = 0`` along the minimum-kinetic-energy
direction ``dq = M^-1 G' (G M^-1 G')^+ phi``, then the velocity projection ``u <- u - M^-1 G' (G M^-1
G')^+ G u``, which is the M-orthogonal projection onto ``G u = 0``). See docs/closure_constraints.md.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np
import scipy.linalg as sla
from scipy.spatial.transform import Rotation

CONSTRAINT_KINDS = {"weld": 6, "ball": 3, "revolute": 5}
_RANK_TOLERANCE = 1e-10


class ConstraintError(ValueError):
    """A closure constraint that cannot be built on the given system."""


@dataclass
class ClosureConstraint:
    """A cut joint between node frame B (``node_b``, or a fixed world pose) and node frame A.

    ``kind``: ``"weld"`` (B fixed to A), ``"ball"`` (origins coincide), ``"revolute"`` (origins
    coincide, B turns relative to A only about ``axis``, a unit vector in A's axes). With
    ``node_b=None``, B is the world frame ``(world_rotation, world_position)``; leaving them ``None``
    takes the pose of node A at the reference configuration given to :class:`ConstrainedSystem`.
    """

    node_a: str
    node_b: str | None = None
    kind: str = "weld"
    axis: tuple | None = None
    world_rotation: np.ndarray | None = None
    world_position: np.ndarray | None = None
    name: str = ""
    selection: np.ndarray = field(init=False, repr=False)

    def __post_init__(self):
        if self.kind not in CONSTRAINT_KINDS:
            raise ConstraintError(f"constraint '{self.label}': unknown kind {self.kind!r}; expected one of "
                                  f"{sorted(CONSTRAINT_KINDS)}")
        if self.kind == "revolute":
            if self.axis is None:
                raise ConstraintError(f"constraint '{self.label}': a revolute closure needs an axis "
                                      f"(unit vector in node '{self.node_a}' axes)")
            a = np.asarray(self.axis, dtype=float)
            if a.shape != (3,) or abs(np.linalg.norm(a) - 1.0) > 1e-9:
                raise ConstraintError(f"constraint '{self.label}': axis must be a unit 3-vector, got "
                                      f"{self.axis!r}")
            self.axis_vector = a
            perp = sla.null_space(a[None, :]).T  # (2, 3), orthonormal, perpendicular to the axis
            S = np.zeros((5, 6))
            S[:2, :3] = perp
            S[2:, 3:] = np.eye(3)
        elif self.axis is not None:
            raise ConstraintError(f"constraint '{self.label}': only revolute closures take an axis")
        elif self.kind == "weld":
            S = np.eye(6)
        else:
            S = np.zeros((3, 6))
            S[:, 3:] = np.eye(3)
        self.selection = S

    @property
    def label(self):
        return self.name or f"{self.kind} {self.node_a}-{self.node_b or 'world'}"

    @property
    def size(self):
        return CONSTRAINT_KINDS[self.kind]


class ConstrainedAccelerations(NamedTuple):
    u_dot: np.ndarray  # (nu,)
    multipliers: list  # one array per constraint: [torque; force] of A on B in A axes, selected rows
    residual: np.ndarray  # (m,) position residual phi(q)


def rotation_log(R):
    """Rotation vector of a rotation matrix (angle in [0, pi])."""
    return Rotation.from_matrix(R).as_rotvec()


class ConstrainedSystem:
    """A tree :class:`dynamics.MultibodySystem` with closure constraints.

    ``baumgarte=(alpha, beta)`` [1/s] stabilizes the acceleration-level constraint
    ``G u_dot + k = -2 alpha G u - beta^2 phi`` (zero: no stabilization). ``q_reference`` supplies
    the world pose of constraints on the world that do not give one.
    """

    def __init__(self, system, constraints, baumgarte=(0.0, 0.0), q_reference=None):
        if np.any(system.prescribed_dofs):
            raise ConstraintError("closure constraints on systems with prescribed DOFs are not supported; "
                                  "prescribe the motion through a constraint on the world instead")
        self.system = system
        self.constraints = list(constraints)
        if not self.constraints:
            raise ConstraintError("no closure constraints given")
        self.alpha, self.beta = (float(b) for b in baumgarte)
        names = set(system.node_names)
        rows = 0
        self._slices = []
        for c in self.constraints:
            for nd in (c.node_a, c.node_b):
                if nd is not None and nd not in names:
                    raise ConstraintError(f"constraint '{c.label}': unknown node '{nd}'; nodes: "
                                          f"{list(system.node_names)}")
            self._slices.append(slice(rows, rows + c.size))
            rows += c.size
        self.m = rows
        self._index_a = np.array([system.node_index(c.node_a) for c in self.constraints])
        self._index_b = np.array([-1 if c.node_b is None else system.node_index(c.node_b)
                                  for c in self.constraints])
        self._world = []
        kin0 = None
        for c in self.constraints:
            if c.node_b is not None:
                self._world.append(None)
                continue
            R, p = c.world_rotation, c.world_position
            if R is None or p is None:
                if q_reference is None:
                    raise ConstraintError(f"constraint '{c.label}': give world_rotation/world_position or "
                                          f"q_reference (the configuration that defines the fixed pose)")
                if kin0 is None:
                    kin0 = system.node_kinematics(q_reference, np.zeros(system.nu))
                k = system.node_index(c.node_a)
                R = kin0.rotation[k] if R is None else R
                p = kin0.position[k] if p is None else p
            self._world.append((np.asarray(R, dtype=float), np.asarray(p, dtype=float)))

    # ------------------------------------------------------------------ constraint kinematics
    def _frames(self, kin, c_index):
        """(R_A, p_A, w_A, v_A, dw_A, a_A) and the same for B; world axes."""
        out = []
        for k in (self._index_a[c_index], self._index_b[c_index]):
            if k < 0:
                R, p = self._world[c_index]
                z = np.zeros(3)
                out.append((R, p, z, z, z, z))
                continue
            R = kin.rotation[k]
            out.append((R, kin.position[k], R @ kin.angular_velocity[k], R @ kin.linear_velocity[k],
                        R @ kin.angular_acceleration[k], R @ kin.linear_acceleration[k]))
        return out

    def residual(self, q):
        """Position residual phi(q) (m,): rotation vectors [rad] and offsets [m] in A axes, selected."""
        kin = self.system.node_kinematics(q, np.zeros(self.system.nu))
        phi = np.empty(self.m)
        for i, c in enumerate(self.constraints):
            (RA, pA, *_), (RB, pB, *_) = self._frames(kin, i)
            R_rel = RA.T @ RB
            if c.kind == "revolute":  # n x (R_rel n): zero iff the axes align; its rate is S G u
                rot = np.cross(c.axis_vector, R_rel @ c.axis_vector)
            else:
                rot = rotation_log(R_rel)
            full = np.concatenate([rot, RA.T @ (pB - pA)])
            phi[self._slices[i]] = c.selection @ full
        return phi

    def jacobian(self, q):
        """Constraint Jacobian G(q) (m, nu): relative spatial velocity of B w.r.t. A in A axes per unit u.

        Column k is the relative velocity for ``u = e_k`` (node velocities are linear in u)."""
        sysm = self.system
        G = np.empty((self.m, sysm.nu))
        e = np.zeros(sysm.nu)
        for k in range(sysm.nu):
            e[k] = 1.0
            G[:, k] = self._relative(sysm.node_kinematics(q, e))[0]
            e[k] = 0.0
        return G

    def _relative(self, kin):
        """(G u, k) from node kinematics at (q, u, u_dot = 0)."""
        vel = np.empty(self.m)
        acc = np.empty(self.m)
        for i, c in enumerate(self.constraints):
            (RA, _, wA, vA, dwA, aA), (_, _, wB, vB, dwB, aB) = self._frames(kin, i)
            wA_local = RA.T @ wA
            rel_w = RA.T @ (wB - wA)
            rel_v = RA.T @ (vB - vA)
            vel[self._slices[i]] = c.selection @ np.concatenate([rel_w, rel_v])
            acc[self._slices[i]] = c.selection @ np.concatenate([
                RA.T @ (dwB - dwA) - np.cross(wA_local, rel_w),
                RA.T @ (aB - aA) - np.cross(wA_local, rel_v)])
        return vel, acc

    def velocity_residual(self, q, u):
        """G(q) u (m,)."""
        return self._relative(self.system.node_kinematics(q, u))[0]

    # ------------------------------------------------------------------ dynamics
    def _constraint_solve(self, Minv_Gt, G, rhs):
        """Minimum-norm lambda of (G M^-1 G') lambda = rhs."""
        A = G @ Minv_Gt
        A = 0.5 * (A + A.T)
        w, V = np.linalg.eigh(A)
        keep = w > _RANK_TOLERANCE * max(w.max(), 1e-300)
        return V[:, keep] @ ((V[:, keep].T @ rhs) / w[keep])

    def forward_dynamics(self, q, u, tau=None, node_forces=None, body_forces=None):
        """Accelerations and constraint forces; returns :class:`ConstrainedAccelerations`.

        The tree's mass matrix (composite-body algorithm) is factored once per call (Cholesky);
        the unconstrained accelerations come from the engine's O(N) forward dynamics."""
        sysm = self.system
        q = np.asarray(q, dtype=float)
        u = np.asarray(u, dtype=float)
        M = sysm.mass_matrix(q)
        chol = sla.cho_factor(M)
        u_dot_free = sysm.forward_dynamics(q, u, tau=tau, node_forces=node_forces, body_forces=body_forces)
        G = self.jacobian(q)
        vel, k = self._relative(sysm.node_kinematics(q, u))
        phi = self.residual(q) if self.beta else np.zeros(self.m)
        rhs = -k - 2.0 * self.alpha * vel - self.beta ** 2 * phi - G @ u_dot_free
        Minv_Gt = sla.cho_solve(chol, G.T)
        lam = self._constraint_solve(Minv_Gt, G, rhs)
        u_dot = u_dot_free + Minv_Gt @ lam
        return ConstrainedAccelerations(u_dot, [lam[s] for s in self._slices], phi)

    def constraint_node_forces(self, q, multipliers):
        """Node forces (nnodes, 6) [torque; force] in node axes equivalent to the multipliers.

        A exerts ``S' lambda`` (A axes) on B at B's origin and the opposite on A (at B's origin, which
        coincides with A's on the constraint manifold)."""
        sysm = self.system
        kin = sysm.node_kinematics(q, np.zeros(sysm.nu))
        F = np.zeros((sysm.nnodes, 6))
        for i, c in enumerate(self.constraints):
            wrench_A = c.selection.T @ multipliers[i]
            RA = kin.rotation[self._index_a[i]]
            kb = self._index_b[i]
            if kb >= 0:
                RB = kin.rotation[kb]
                F[kb, :3] += RB.T @ RA @ wrench_A[:3]
                F[kb, 3:] += RB.T @ RA @ wrench_A[3:]
            F[self._index_a[i]] -= wrench_A
        return F

    def rates(self, t, y, tau=None):
        """``d/dt [q; u]`` for ODE integrators (state ``y = [q; u]``)."""
        nq = self.system.nq
        q, u = y[:nq], y[nq:]
        return np.concatenate([self.system.q_dot(q, u), self.forward_dynamics(q, u, tau=tau).u_dot])

    # ------------------------------------------------------------------ drift removal
    def project(self, q, u, tol=1e-12, max_iterations=20):
        """(q, u) on the constraint manifold: Newton on phi(q) = 0 along M^-1 G' directions (minimum
        kinetic-energy correction), then the M-orthogonal velocity projection onto G u = 0.

        Stops when |phi| <= tol (rad, m); raises :class:`ConstraintError` when it does not converge."""
        sysm = self.system
        q = np.array(q, dtype=float)
        for _ in range(max_iterations):
            phi = self.residual(q)
            if np.abs(phi).max(initial=0.0) <= tol:
                break
            G = self.jacobian(q)
            Minv_Gt = sla.cho_solve(sla.cho_factor(sysm.mass_matrix(q)), G.T)
            dq_u = -Minv_Gt @ self._constraint_solve(Minv_Gt, G, phi)
            q = q + sysm.q_dot(q, dq_u)
            sysm.normalize_quaternions(q)
        else:
            raise ConstraintError(f"position projection did not converge in {max_iterations} iterations "
                                  f"(|phi| = {np.abs(self.residual(q)).max():.3e})")
        G = self.jacobian(q)
        Minv_Gt = sla.cho_solve(sla.cho_factor(sysm.mass_matrix(q)), G.T)
        u = np.asarray(u, dtype=float) - Minv_Gt @ self._constraint_solve(Minv_Gt, G, G @ u)
        return q, u

    def null_space(self, q, rcond=1e-10):
        """Orthonormal basis Z (nu, nu - rank G) of the admissible velocities G(q) u = 0."""
        return sla.null_space(self.jacobian(q), rcond=rcond)

    def energy(self, q, u):
        """Kinetic plus potential (gravity and elastic) energy of the tree."""
        return self.system.kinetic_energy(q, u) + self.system.potential_energy(q)
