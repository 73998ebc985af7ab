"""Closure constraints (cut joints) and force elements on a tree: closed loops, multiply supported bodies,
latches and contacts, with their Python API.

A closed-chain system is cut into a spanning tree (a :class:`dynamics.MultibodySystem`) plus closure
constraints, each tying a node frame B to a node frame A (FModal paper, IEEE Aerospace 2023, "Closure
Constraints"; Jain, *Robot and Multibody Dynamics*, 2011, ch. 11). Nodes on flexible bodies move with their
elastic deformation, so a constraint holds the *deformed* node frames together. Force elements
(:mod:`dynamics.force_elements`) act between nodes and on hinges.

:class:`ConstrainedSystem` holds the tree, the constraints, the force elements and the compiled data
(:class:`dynamics.constraint_kernels.ConstraintData`); its methods call the compiled kernels of
:mod:`dynamics.constraint_kernels`, whose docstring gives the equations (constraint kinematics, the index-1
dynamics with Baumgarte stabilization, minimum-norm multipliers for redundant rows, the projections). This
module adds what runs outside a step:

* **assembly**: :meth:`ConstrainedSystem.assemble` moves an initial state that violates a constraint onto
  the manifold and says how far it moved, or refuses beyond a tolerance;
* **switching a constraint on or off** during a run (a latch, a release): :meth:`ConstrainedSystem.switch_on`
  applies the perfectly plastic impact ``u+ = u - M^-1 G' (G M^-1 G')^+ G u``, which conserves momentum (the
  impulse is internal) and loses ``dE = 1/2 (G u)' (G M^-1 G')^+ (G u)``, then closes the gap (position
  projection, the distance reported, refused beyond a tolerance). Closing a gap moves the bodies; their
  velocities in body axes are kept, so a gap in rotation turns their momentum by the angle closed (a latch
  that catches two bodies where they are, without moving them, is :meth:`ConstrainedSystem.reconfigure`'s
  ``attach``);
* **minimal coordinates for linearization**: :meth:`ConstrainedSystem.tangent_basis` spans the tangent
  space of the state manifold ``{phi(q) = 0, G(q) u = 0}`` in the tangent coordinates of
  :mod:`shell.analysis.linearize`; a linear model restricted to it (:func:`restrict`) has neither the zero
  modes of the constraint directions nor the Baumgarte modes.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
import scipy.linalg as sla

from dynamics import constraint_kernels as CK
from dynamics import kernels as K
from dynamics.engine import engine_data
from dynamics.errors import ModelDefinitionError
from dynamics import force_elements as FE
from dynamics.force_elements import Bushing, SpringDamper, element_tables
from dynamics.hinges import FREE, SPHERICAL
from dynamics.definitions import suggest
from dynamics.layout import HINGE_TYPE, NQ_HINGE, NU_HINGE, N_MODES, Q_START, U_START
from dynamics.reconfigure import attach_moves
from dynamics.spatial import quaternion_to_rotation

CONSTRAINT_KINDS = {name: CK.ROWS[code] for name, code in CK.KINDS.items()}
"""Constraint kinds and their number of rows."""

DEFAULT_ASSEMBLY_TOLERANCE = 1e-6
"""Largest constraint residual (m or rad) an initial state may have for :meth:`ConstrainedSystem.assemble`
to project it without being asked to."""


class ConstraintError(ModelDefinitionError):
    """A closure constraint that cannot be built on the given system, or a state that cannot satisfy it."""


def _perpendicular(n):
    """Two orthonormal rows perpendicular to the unit vector n."""
    return sla.null_space(np.asarray(n, dtype=float)[None, :]).T


@dataclass
class ClosureConstraint:
    """A cut joint between node frame B (``node_b``, or a fixed world pose) and node frame A.

    ``kind``: ``"weld"`` (B fixed to A), ``"ball"`` (origins coincide), ``"revolute"`` (origins coincide, B turns
    relative to A only about ``axis``, a unit vector in A's axes), ``"prismatic"`` (B slides along ``axis``
    without turning), ``"distance"`` (the origins stay ``length`` apart: a rod with ball ends; None: the
    distance at the reference configuration). With ``node_b=None``, B is the world frame
    ``(world_rotation, world_position)``; leaving them ``None`` takes node A's pose at the reference
    configuration. ``active=False`` declares a constraint that an event switches on later (a latch).
    """

    node_a: str
    node_b: str | None = None
    kind: str = "weld"
    axis: tuple | None = None
    world_rotation: np.ndarray | None = None
    world_position: np.ndarray | None = None
    name: str = ""
    length: float | None = None
    active: bool = True

    def __post_init__(self):
        if self.kind not in CONSTRAINT_KINDS:
            raise ConstraintError(f"constraint '{self.label}': unknown kind {self.kind!r}; expected one of "
                                  f"{sorted(CONSTRAINT_KINDS)}")
        if self.kind in ("revolute", "prismatic"):
            if self.axis is None:
                raise ConstraintError(f"constraint '{self.label}': a {self.kind} closure needs an axis (unit "
                                      f"vector in node '{self.node_a}' axes)")
            a = np.asarray(self.axis, dtype=float)
            if a.shape != (3,) or abs(np.linalg.norm(a) - 1.0) > 1e-9:
                raise ConstraintError(f"constraint '{self.label}': axis must be a unit 3-vector, got {self.axis!r}")
            self.axis_vector = a
        elif self.axis is not None:
            raise ConstraintError(f"constraint '{self.label}': only revolute and prismatic closures take an axis")
        if self.length is not None and self.kind != "distance":
            raise ConstraintError(f"constraint '{self.label}': only distance constraints take a length")
        if self.length is not None and not float(self.length) > 0.0:
            raise ConstraintError(f"constraint '{self.label}': length must be positive, got {self.length!r}")
        S = np.zeros((6, 6))
        if self.kind == "weld":
            S = np.eye(6)
        elif self.kind == "ball":
            S[:3, 3:] = np.eye(3)
        elif self.kind == "revolute":
            S[:2, :3] = _perpendicular(self.axis_vector)
            S[2:5, 3:] = np.eye(3)
        elif self.kind == "prismatic":
            S[:3, :3] = np.eye(3)
            S[3:5, 3:] = _perpendicular(self.axis_vector)
        self.selection = S[:self.size]

    @property
    def label(self):
        return self.name or f"{self.kind} {self.node_a}-{self.node_b or 'world'}"

    @property
    def size(self):
        return CONSTRAINT_KINDS[self.kind]


class ConstrainedAccelerations(NamedTuple):
    u_dot: np.ndarray  # (nu,)
    multipliers: list  # one array per constraint: its rows' multipliers (zeros when switched off)
    residual: np.ndarray  # (m,) position residual phi(q) of the active rows
    loads: np.ndarray  # (nc, 6) each constraint's wrench [torque; force] of A on B, A's axes, at B's origin
    tau: np.ndarray  # (nu,) generalized forces (applied and hinge elements; at prescribed DOFs those realizing them)


class AssemblyReport(NamedTuple):
    residual: float  # largest constraint residual before (m or rad)
    worst: str  # the constraint it belonged to
    moved: float  # largest change of a coordinate of q
    velocity_change: float  # largest change of a coordinate of u
    energy_lost: float  # kinetic energy removed by the plastic impact (and the small move that closes the gap) [J]
    tolerance: float = DEFAULT_ASSEMBLY_TOLERANCE  # the largest residual that was allowed (m or rad)


class ConstrainedSystem:
    """A tree :class:`dynamics.MultibodySystem` with closure constraints and force elements.

    ``baumgarte=(alpha, beta)`` [1/s] stabilizes the acceleration-level constraint
    ``G u_dot + k = -2 alpha G u - beta^2 phi`` (zero: no stabilization; the projections of :meth:`project`
    after each step are the drift control docs/closure_constraints.md recommends). ``q_reference`` supplies
    the world pose of constraints on the world that do not give one, the length of distance constraints and
    the free lengths and relaxed poses of force elements that do not give them.
    """

    def __init__(self, system, constraints=(), forces=(), baumgarte=(0.0, 0.0), q_reference=None):
        self._build(system, constraints, forces, baumgarte, q_reference, allow_locked=False)

    def _build(self, system, constraints, forces, baumgarte, q_reference, allow_locked):
        self.system = system
        self.constraints = list(constraints)
        self.forces = list(forces)
        self.alpha, self.beta = (float(b) for b in baumgarte)
        self.q_reference = None if q_reference is None else np.array(q_reference, dtype=float)
        reference = None if q_reference is None else system.node_kinematics(self.q_reference, np.zeros(system.nu))
        names = set()
        for c in self.constraints:
            if c.label in names:
                raise ConstraintError(f"constraint '{c.label}': duplicate name")
            names.add(c.label)
        self._c_int, self._c_float = self._constraint_tables(reference)
        self._f_int, self._f_float = element_tables(self.forces, system, reference, allow_locked)
        self._slices = []
        rows = 0
        for c in self.constraints:
            self._slices.append(slice(rows, rows + c.size))
            rows += c.size
        self.m = rows
        self.data = self._allocate(system)
        self.engine = engine_data(system)

    # ------------------------------------------------------------------ construction
    def _constraint_tables(self, reference):
        system = self.system
        nc = len(self.constraints)
        ints = np.zeros((nc, CK.C_INT_COLUMNS), dtype=np.int64)
        floats = np.zeros((nc, CK.C_FLOAT_COLUMNS))
        for i, c in enumerate(self.constraints):
            where = f"constraint '{c.label}'"
            for role, nd in (("node_a", c.node_a), ("node_b", c.node_b)):
                if nd is not None and nd not in system.node_names:
                    raise ConstraintError(f"{where}: unknown node '{nd}' ({role}); nodes: {list(system.node_names)}"
                                          + suggest(nd, system.node_names))
            a = system.node_index(c.node_a)
            b = -1 if c.node_b is None else system.node_index(c.node_b)
            if b >= 0:
                body = system.node_bodies[a]
                if body == system.node_bodies[b] and not system.topology[system.body_index(body), N_MODES]:
                    raise ConstraintError(f"{where}: nodes '{c.node_a}' and '{c.node_b}' are both on the rigid body "
                                          f"'{body}' (a constraint between two frames of one rigid body holds nothing)")
            ints[i, CK.C_KIND] = CK.KINDS[c.kind]
            ints[i, CK.C_NODE_A] = a
            ints[i, CK.C_NODE_B] = b
            ints[i, CK.C_ROWS] = c.size
            ints[i, CK.C_ACTIVE] = bool(c.active)
            floats[i, CK.C_WORLD_R:CK.C_WORLD_R + 9] = np.eye(3).ravel()
            if c.axis is not None:
                floats[i, CK.C_AXIS:CK.C_AXIS + 3] = c.axis_vector
            if c.kind != "distance":
                floats[i, CK.C_SELECT:CK.C_SELECT + 6 * c.size] = c.selection.ravel()
            if b < 0:
                R, p = c.world_rotation, c.world_position
                if R is None or p is None:
                    if reference is None:
                        raise ConstraintError(f"{where}: give world_rotation/world_position or q_reference (the "
                                              f"configuration that defines the fixed pose)")
                    R = reference.rotation[a] if R is None else R
                    p = reference.position[a] if p is None else p
                floats[i, CK.C_WORLD_R:CK.C_WORLD_R + 9] = np.asarray(R, dtype=float).ravel()
                floats[i, CK.C_WORLD_P:CK.C_WORLD_P + 3] = np.asarray(p, dtype=float)
            if c.kind == "distance":
                length = c.length
                if length is None:
                    if reference is None:
                        raise ConstraintError(f"{where}: give the length or q_reference (the configuration that "
                                              f"defines it)")
                    pb = floats[i, CK.C_WORLD_P:CK.C_WORLD_P + 3] if b < 0 else reference.position[b]
                    length = float(np.linalg.norm(pb - reference.position[a]))
                    if not length > 0.0:
                        raise ConstraintError(f"{where}: nodes '{c.node_a}' and '{c.node_b or 'world'}' coincide at "
                                              f"the reference configuration; give the length")
                floats[i, CK.C_LENGTH] = float(length)
        return ints, floats

    def _allocate(self, system):
        nn, nu, m = system.nnodes, system.nu, max(self.m, 1)
        return CK.ConstraintData(
            self._c_int, self._c_float, np.array([self.alpha, self.beta]), self._f_int, self._f_float,
            np.zeros((nn, 3, 3)), np.zeros((nn, 3)), np.zeros((nn, 6)), np.zeros((nn, 6)), np.zeros((nn, 6)),
            np.zeros((nn, 6)), np.zeros(nu), np.zeros(nu), np.zeros(nu), np.zeros((m, nu)), np.zeros((m, nu)),
            np.zeros((nu, nu)), np.zeros((nu, nu)), np.zeros((m, m)), np.zeros((m, m)), np.zeros(m), np.zeros(m),
            np.zeros(m), np.zeros(m), np.zeros(m), np.zeros(32), np.zeros((2, 3, 3)), np.zeros(system.nq))

    def copy(self):
        """An independent copy (its own engine workspace and constraint switches): one per simulation."""
        return self.on(self.system.copy(mass_properties=True))

    def on(self, system):
        """The same constraints, force elements and switches on ``system``, a copy of this tree (a run's own, with its
        mass properties), with a workspace of its own."""
        other = object.__new__(ConstrainedSystem)
        other.__dict__.update(self.__dict__)
        other.system = system
        other._c_int = self._c_int.copy()
        other.data = other._allocate(system)
        other.engine = engine_data(system)
        return other

    def takes_reference(self) -> bool:
        """Whether a constraint or force element takes a pose or a length from ``q_reference`` (a world pose, a
        distance, a free length or relaxed pose it was not given): a scene whose initial state is the reference
        defines them with it, so another initial state makes another scene."""
        try:
            ConstrainedSystem(self.system, self.constraints, self.forces)
        except ModelDefinitionError:
            return True
        return False

    # ------------------------------------------------------------------ queries
    def index(self, name):
        for i, c in enumerate(self.constraints):
            if c.label == name:
                return i
        labels = [c.label for c in self.constraints]
        raise ConstraintError(f"unknown constraint '{name}'; constraints: {labels}" + suggest(name, labels))

    def is_active(self, name):
        return bool(self._c_int[self.index(name), CK.C_ACTIVE])

    def _active_slices(self):
        """Row slices of each constraint inside the active rows (None when switched off)."""
        out, row = [], 0
        for i, c in enumerate(self.constraints):
            if self._c_int[i, CK.C_ACTIVE]:
                out.append(slice(row, row + c.size))
                row += c.size
            else:
                out.append(None)
        return out, row

    def _q(self, q):
        return np.array(q, dtype=float)

    def residual(self, q):
        """Position residual phi(q) of the active rows: rotation vectors [rad] and offsets [m] in A's axes."""
        CK.residual(self.engine, self.data, self._q(q))
        return self.data.phi[:self._active_slices()[1]].copy()

    def velocity_residual(self, q, u):
        """G(q) u of the active rows."""
        q = self._q(q)
        u = np.asarray(u, dtype=float)
        d = self.data
        K.node_kinematics(self.system.topology, self.system.nodes, self.system.joint_rot, self.system.joint_vec,
                          self.system.params, q, u, d.zero_u, d.rotation, d.position, d.velocity, d.acceleration,
                          self.system.ws_rot, self.system.ws_vec, self.system.ws_mat, self.system.pool)
        m = CK.constraint_rows(d.c_int, d.c_float, d.rotation, d.position, d.velocity, d.acceleration, d.phi, d.gu,
                               d.k, d.scratch, d.frames)
        return d.gu[:m].copy()

    def jacobian(self, q):
        """Constraint Jacobian G(q) (m, nu) of the active rows: relative spatial velocity rows per unit u."""
        q = self._q(q)
        CK.residual(self.engine, self.data, q)
        m = self._active_slices()[1]
        CK.constraint_jacobian(self.engine, self.data, q, m)
        return self.data.G[:m].copy()

    def null_space(self, q, rcond=1e-10):
        """Orthonormal basis Z (nu, nu - rank G) of the admissible velocities G(q) u = 0."""
        G = self.jacobian(q)
        return sla.null_space(G, rcond=rcond) if len(G) else np.eye(self.system.nu)

    # ------------------------------------------------------------------ dynamics
    def forward_dynamics(self, q, u, tau=None, node_forces=None, prescribed_accel=None):
        """Accelerations, multipliers and loads; returns :class:`ConstrainedAccelerations`."""
        sysm = self.system
        q = self._q(q)
        u = np.array(u, dtype=float)
        tau = np.zeros(sysm.nu) if tau is None else np.array(tau, dtype=float)
        F = np.zeros((sysm.nnodes, 6)) if node_forces is None else np.array(node_forces, dtype=float)
        udot = np.zeros(sysm.nu) if prescribed_accel is None else np.array(prescribed_accel, dtype=float)
        tau_out = np.empty(sysm.nu)
        loads = np.zeros((len(self.constraints), 6))
        status = CK.forward_dynamics(self.engine, self.data, q, u, tau, F, udot, tau_out, loads)
        self._check(status)
        slices, m = self._active_slices()
        multipliers = [np.zeros(c.size) if s is None else self.data.lam[s].copy()
                       for c, s in zip(self.constraints, slices)]
        return ConstrainedAccelerations(udot, multipliers, self.data.phi[:m].copy(), loads, tau_out)

    def _check(self, status):
        if status > 0:
            from dynamics.errors import SingularConfigurationError

            raise SingularConfigurationError(f"articulated inertia of body '{self.system.body_names[status - 1]}' is "
                                             f"singular")
        if status < 0:
            raise ConstraintError("the mass matrix is not positive definite")

    def hinge_loads(self, q, u, tau=None, node_forces=None, prescribed_accel=None):
        """The spatial force ``[torque; force]`` each hinge transmits to its body (nb, 6), at the hinge's
        outboard frame, in its axes; with the constraint and force-element forces of the motion."""
        acc = self.forward_dynamics(q, u, tau, node_forces, prescribed_accel)
        out = np.empty((self.system.nbodies, 6))
        CK.hinge_loads(self.engine, self.data, self._q(q), np.array(u, dtype=float), acc.u_dot, out)
        return out

    def constraint_node_forces(self, q, multipliers):
        """Node forces (nnodes, 6) [torque; force] in node axes equivalent to the multipliers (one array per
        constraint, as :meth:`forward_dynamics` returns them)."""
        CK.residual(self.engine, self.data, self._q(q))
        F = np.zeros((self.system.nnodes, 6))
        for i, c in enumerate(self.constraints):
            lam = np.asarray(multipliers[i], dtype=float)
            if c.kind == "distance":
                wrench = np.zeros(6)
                CK.row_wrench(self._c_int, self._c_float, i, 0, self.data.rotation, self.data.position, wrench)
                wrench *= lam[0]
            else:
                wrench = c.selection.T @ lam
            CK.add_constraint_wrench(self._c_int, self._c_float, i, self.data.rotation, self.data.position, wrench, F)
        return F

    def rates(self, t, y, tau=None):
        """``d/dt [q; u]`` for ODE integrators (state ``y = [q; u]``)."""
        nq = self.system.nq
        q, u = y[:nq], y[nq:]
        return np.concatenate([self.system.q_dot(q, u), self.forward_dynamics(q, u, tau=tau).u_dot])

    # ------------------------------------------------------------------ energy
    def element_forces(self, q, u):
        """The force elements' ``(node forces (nnodes, 6), generalized forces J' F + tau (nu,))`` at (q, u)."""
        out = np.empty(self.system.nu)
        CK.element_forces(self.engine, self.data, self._q(q), np.array(u, dtype=float), out)
        return self.data.forces.copy(), out

    def force_element_energy(self, q):
        """Potential energy of the force elements [J]."""
        return float(CK.potential_energy(self.engine, self.data, self._q(q)))

    def energy(self, q, u):
        """Kinetic plus potential energy: gravity and elastic energy of the tree and the force elements'."""
        return self.system.kinetic_energy(q, u) + self.system.potential_energy(q) + self.force_element_energy(q)

    # ------------------------------------------------------------------ drift and assembly
    def project(self, q, u, tol=1e-12, max_iterations=20):
        """(q, u) on the constraint manifold: Newton on phi(q) = 0 along M^-1 G' directions (the least
        kinetic-energy correction), then the M-orthogonal velocity projection onto G u = 0.

        Stops when ``|phi| <= tol`` (rad, m); raises :class:`ConstraintError` when it does not converge."""
        q = self._q(q)
        u = np.array(u, dtype=float)
        if CK.project_positions(self.engine, self.data, q, tol, max_iterations) < 0:
            raise ConstraintError(f"position projection did not converge in {max_iterations} iterations "
                                  f"(|phi| = {np.abs(self.residual(q)).max(initial=0.0):.3e}); the constraints "
                                  f"cannot be met near this configuration")
        self._check(CK.project_velocities(self.engine, self.data, q, u))
        return q, u

    def worst_residual(self, q):
        """(largest ``|phi|`` of the active rows, the constraint it belongs to)."""
        phi = self.residual(q)
        slices, _ = self._active_slices()
        worst, name = 0.0, ""
        for c, s in zip(self.constraints, slices):
            if s is not None and len(phi[s]) and np.abs(phi[s]).max() > worst:
                worst, name = float(np.abs(phi[s]).max()), c.label
        return worst, name

    def assemble(self, q, u, tolerance=DEFAULT_ASSEMBLY_TOLERANCE):
        """An initial state moved onto the constraint manifold: returns ``(q, u, AssemblyReport)``. Refuses
        (:class:`ConstraintError`, naming the constraint) a state whose residual exceeds ``tolerance`` [m or
        rad]: a state that far off was not meant to satisfy the constraints."""
        worst, name = self.worst_residual(q)
        if worst > tolerance:
            raise ConstraintError(f"constraint '{name}' is violated by {worst:.6g} (m or rad) in the initial state, "
                                  f"more than the assembly tolerance {tolerance:.3g}; give an initial state that "
                                  f"satisfies it (or a larger tolerance to let it be projected)")
        q0, u0 = self._q(q), np.array(u, dtype=float)
        # the plastic impact where the state is, then the gap closed and the small velocity defect the move
        # leaves removed: moving bodies that already share a rigid motion changes no momentum
        u1 = self.impact(q0, u0)[0]
        q1, u1 = self.project(q0, u1)
        lost = self.system.kinetic_energy(q0, u0) - self.system.kinetic_energy(q1, u1)
        return q1, u1, AssemblyReport(worst, name, float(np.abs(q1 - q0).max(initial=0.0)),
                                      float(np.abs(u1 - u0).max(initial=0.0)), float(lost), float(tolerance))

    # ------------------------------------------------------------------ switching constraints
    def impact(self, q, u):
        """The perfectly plastic impact of the active constraints: ``(u+, energy lost [J])`` with
        ``u+ = u - M^-1 G' (G M^-1 G')^+ G u`` (momentum conserved: the impulse is internal)."""
        q = self._q(q)
        u1 = np.array(u, dtype=float)
        self._check(CK.project_velocities(self.engine, self.data, q, u1))
        return u1, self.system.kinetic_energy(q, u) - self.system.kinetic_energy(q, u1)

    def switch_on(self, name, q, u, tolerance=DEFAULT_ASSEMBLY_TOLERANCE):
        """Switch constraint ``name`` on at state (q, u) (a latch closing): the gap is closed by the position
        projection (refused beyond ``tolerance``), then the plastic impact. Returns ``(q, u, AssemblyReport)``."""
        i = self.index(name)
        if self._c_int[i, CK.C_ACTIVE]:
            raise ConstraintError(f"constraint '{name}' is already on")
        self._c_int[i, CK.C_ACTIVE] = 1
        try:
            return self.assemble(q, u, tolerance)
        except ConstraintError:
            self._c_int[i, CK.C_ACTIVE] = 0
            raise

    def switch_off(self, name):
        """Switch constraint ``name`` off (a release): the state is unchanged."""
        i = self.index(name)
        if not self._c_int[i, CK.C_ACTIVE]:
            raise ConstraintError(f"constraint '{name}' is already off")
        self._c_int[i, CK.C_ACTIVE] = 0

    # ------------------------------------------------------------------ changes of the tree
    def resolved_constraints(self):
        """The constraint definitions with what the reference configuration supplied written in (world poses,
        lengths) and their current switches: definitions that hold on any system with the same nodes."""
        out = []
        for i, c in enumerate(self.constraints):
            row = self._c_float[i]
            world = {} if c.node_b is not None else dict(
                world_rotation=row[CK.C_WORLD_R:CK.C_WORLD_R + 9].reshape(3, 3).copy(),
                world_position=row[CK.C_WORLD_P:CK.C_WORLD_P + 3].copy())
            length = {"length": float(row[CK.C_LENGTH])} if c.kind == "distance" else {}
            out.append(dataclasses.replace(c, active=bool(self._c_int[i, CK.C_ACTIVE]), **world, **length))
        return out

    def resolved_forces(self):
        """The force elements with their free lengths and relaxed world poses written in (see
        :meth:`resolved_constraints`)."""
        out = []
        for e, element in enumerate(self.forces):
            row = self._f_float[e]
            if isinstance(element, SpringDamper) and element.free_length is None:
                element = dataclasses.replace(element, free_length=float(row[FE.F_LENGTH]))
            elif isinstance(element, Bushing) and element.node_b is None:
                element = dataclasses.replace(element, world_rotation=row[FE.F_WORLD_R:FE.F_WORLD_R + 9].reshape(3, 3),
                                              world_position=row[FE.F_WORLD_P:FE.F_WORLD_P + 3].copy())
            out.append(element)
        return out

    def reconfigure(self, q, u, *, lock=(), unlock=(), detach=(), attach=None, mass_properties=None,
                    tolerance=DEFAULT_ASSEMBLY_TOLERANCE):
        """The tree changed as :func:`dynamics.reconfigure.reconfigure` does, with the constraints and force
        elements carried over: returns ``(ConstrainedSystem, q, u, report)``. The impacts include the active
        constraints: an ``attach`` latch is the plastic impact of its weld together with them (``report``: its
        :class:`AssemblyReport`, the frames' misalignment at the latch as the residual, refused beyond
        ``tolerance``; or None), a ``lock`` is followed by the projection onto the constraints in the locked system
        (two nested M-orthogonal projections are the projection onto both). Hinge elements on a hinge that becomes
        locked are switched off."""
        q = self._q(q)
        u = np.array(u, dtype=float)
        constraints = self.resolved_constraints()
        report = None
        if attach:
            bodies = {b.name: b for b in self.system.definitions[0]}
            joints = {b.joint_name: b for b in self.system.definitions[0]}

            def find(name, what):
                if name not in bodies and name not in joints:
                    raise ConstraintError(f"{what}: unknown body or hinge '{name}' (bodies: {list(bodies)})"
                                          + suggest(name, list(bodies)))
                return bodies.get(name) or joints[name]
            welds = [ClosureConstraint(body_node, target, "weld", name=f"attach {body.name}")
                     for body, body_node, target in attach_moves(list(bodies.values()), self.system.definitions[1],
                                                                 attach, find)]
            gap, worst = ConstrainedSystem(self.system, welds).worst_residual(q)
            if gap > tolerance:
                raise ConstraintError(f"attach: the frames of '{worst}' are {gap:.6g} (m or rad) apart, more than "
                                      f"the latch tolerance {tolerance:.3g}")
            latch = ConstrainedSystem(self.system, constraints + welds)
            u_latched, lost = latch.impact(q, u)
            report = AssemblyReport(gap, worst, 0.0, float(np.abs(u_latched - u).max(initial=0.0)), float(lost),
                                    float(tolerance))
            u = u_latched
        system, q, u = self.system.reconfigure(q, u, lock=lock, unlock=unlock, detach=detach, attach=attach,
                                               mass_properties=mass_properties)
        new = ConstrainedSystem.__new__(ConstrainedSystem)
        new._build(system, constraints, self.resolved_forces(), (self.alpha, self.beta), None, allow_locked=True)
        if lock:
            u = new.impact(q, u)[0]
        return new, q, u, report

    # ------------------------------------------------------------------ minimal coordinates
    def tangent_map(self, q):
        """N (nu x nu): rates of the tangent coordinates per unit u at q (identity but for a free hinge's
        position, whose rate is ``R_FM v``). Tangent coordinates as in :mod:`shell.analysis.linearize`: each
        hinge quaternion as a body-frame rotation vector (``q = q0 Exp(phi)``), every other coordinate itself."""
        sysm = self.system
        N = np.eye(sysm.nu)
        q = np.asarray(q, dtype=float)
        for t in sysm.topology:
            if t[HINGE_TYPE] == FREE:
                R = np.empty((3, 3))
                quaternion_to_rotation(*q[t[Q_START]:t[Q_START] + 4], R)
                u0 = t[U_START] + 3
                N[u0:u0 + 3, u0:u0 + 3] = R
        return N

    def retract(self, q, dq):
        """Configuration at tangent coordinates ``dq`` (nu) from q (see :meth:`tangent_map`)."""
        sysm = self.system
        q = np.array(q, dtype=float)
        for t in sysm.topology:
            q0, u0, nh, n = t[Q_START], t[U_START], t[NU_HINGE], t[N_MODES]
            if t[HINGE_TYPE] in (SPHERICAL, FREE):
                phi = dq[u0:u0 + 3]
                angle = np.linalg.norm(phi)
                e = np.concatenate([[np.cos(angle / 2)], np.sinc(angle / (2 * np.pi)) / 2 * phi])
                w, x, y, z = q[q0:q0 + 4]
                a, b, c, d = e
                q[q0:q0 + 4] = [w * a - x * b - y * c - z * d, w * b + x * a + y * d - z * c,
                                w * c - x * d + y * a + z * b, w * d + x * c - y * b + z * a]
                if t[HINGE_TYPE] == FREE:
                    q[q0 + 4:q0 + 7] += dq[u0 + 3:u0 + 6]
                q[q0 + t[NQ_HINGE]:q0 + t[NQ_HINGE] + n] += dq[u0 + nh:u0 + nh + n]
            else:
                q[q0:q0 + t[NQ_HINGE] + n] += dq[u0:u0 + nh + n]
        return q

    def tangent_basis(self, q, u, step=1e-6, rcond=1e-9):
        """Orthonormal basis V (2 nu x r) of the tangent space at (q, u) of the state manifold ``{phi(q) = 0,
        G(q) u = 0}``, in the coordinates ``[dq (tangent, :meth:`tangent_map`); du]``: the null space of
        ``[[G N^-1, 0], [d(G u)/dq, G]]`` (``d phi/dq = G N^-1`` because ``phi_dot = G u``; ``d(G u)/dq`` by central
        differences with step ``step``, zero at rest). Without active constraints: the identity."""
        nu = self.system.nu
        G = self.jacobian(q)
        if not len(G):
            return np.eye(2 * nu)
        N = self.tangent_map(q)
        Gq = np.zeros((len(G), nu))
        u = np.asarray(u, dtype=float)
        if np.any(u):
            for k in range(nu):
                e = np.zeros(nu)
                e[k] = step
                Gq[:, k] = (self.velocity_residual(self.retract(q, e), u)
                            - self.velocity_residual(self.retract(q, -e), u)) / (2 * step)
        C = np.block([[G @ np.linalg.inv(N), np.zeros_like(G)], [Gq, G]])
        return sla.null_space(C, rcond=rcond)


def restrict(A, B, C, basis):
    """A linear model ``x' = A x + B w, y = C x`` restricted to the invariant subspace spanned by the
    orthonormal ``basis`` V (the constraint manifold's tangent space, :meth:`ConstrainedSystem.tangent_basis`):
    ``(V' A V, V' B, C V)`` and the invariance defect ``|A V - V (V' A V)| / |A V|`` (round-off and the
    linearization's truncation error when V spans an invariant subspace of A)."""
    V = np.asarray(basis, dtype=float)
    AV = A @ V
    Ar = V.T @ AV
    defect = np.linalg.norm(AV - V @ Ar) / max(np.linalg.norm(AV), 1e-300)
    return Ar, V.T @ B, C @ V, float(defect)
