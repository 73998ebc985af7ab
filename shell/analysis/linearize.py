"""Numerical linearization of a built simulation: A, B, C, D between named inputs and outputs.

For the scene's continuous dynamics ``x' = f(t, x, u)`` and outputs ``y = g(t, x, u)`` about an
operating point ``(t0, x0, u0)`` (discrete states held), the Jacobians

    A = df/dx,  B = df/du,  C = dg/dx,  D = dg/du

are computed column by column with central differences (TM-2020-5008164 Sec. 7.1.3: two- and
four-point central difference schemes, Richardson extrapolation, step sizes from a user relative-error
tolerance, verified against analytic linear models as in Sec. 7.3):

    D2(h) = (F(h) - F(-h)) / (2 h)                       truncation O(h^2)
    D4(h) = (4 D2(h) - D2(2h)) / 3                        the four-point scheme, O(h^4)
    Richardson on D2: (4 D2(h) - D2(2h)) / 3 = D4(h);     on D4: (16 D4(h) - D4(2h)) / 15, O(h^6)

The reported error estimate of every entry is the size of the last correction (the difference
between the two levels of the scheme, which for an un-extrapolated result is about (2^p - 1) times
its truncation error and for an extrapolated one bounds the error of the less accurate level it
improves on) plus a round-off term ``16 eps max|F| / h``. The step of variable j is
``h_j = scale_j * tol^(1/p)``, with ``p`` the order of the final result and ``scale_j`` the larger of
``|x0_j|`` and the variable's typical size (1 in SI units unless the user gives one), so that the
truncation error relative to the derivative is about ``tol``. The typical size of a flexible body's modal
coordinate (mass-normalized: its size depends on the body's mass, not on SI units) is the amplitude at which
the mode's largest grid rotation reaches 1 rad or its largest grid translation the body's extent (largest
grid distance from the body frame), and at most 1: the physical step rule, applied to the deformation
(issue 15: a step of 0.09 in the modes of a 1 kg beam bent it by radians and made its geometrically
stiffened mass matrix indefinite). Modal rates keep the typical size 1 (they enter the equations at most quadratically).

States are minimal coordinates: each unit quaternion of a model that declares
``quaternion_w_indices`` (hinge quaternions of the engine) is replaced by a rotation vector ``phi``
with ``q = q0 (x) Exp(phi)`` (a right, body-frame perturbation), whose rate is
``phi' = Jr(phi)^-1 omega``, ``omega = 2 vec(q* (x) q')``, with the inverse right Jacobian of SO(3)
``Jr^-1(phi) = I + [phi x]/2 + (1/|phi|^2 - (1 + cos|phi|) / (2 |phi| sin|phi|)) [phi x]^2``.
A therefore has no rank deficiency from the quaternion norm.

In a scene with closure constraints (``multibody.constraints:``) the states are minimal coordinates of the
constraint manifold ``{phi(q) = 0, G(q) u = 0}`` by coordinate partitioning (:class:`ConstraintManifold`): the
independent hinge coordinates and rates keep their names, the dependent ones follow from the constraints at every
evaluation (Newton on the positions, a linear solve for the rates), so A has neither the constraint directions' zero
modes nor spurious ones, and trim moves on the manifold. Force elements alone (``multibody.forces:``) keep every
coordinate: their stiffness and damping enter A through the derivatives.

Inputs are input ports (or elements ``port[k]``) of the scene. A connected input is opened for the
linearization: its value is held at the operating-point value plus the perturbation, and the model
driving it no longer reaches it (the plant seen from that input, as for controller design).
Outputs are any port or state (or element) by dotted name, in their declared units.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field

import numpy as np
import scipy.linalg as sla

from shell.model import ModelError
from shell.units import format_unit

EPS = np.finfo(float).eps
SCHEMES = {  # (points, richardson) -> order of the result
    (2, False): 2, (2, True): 4, (4, False): 4, (4, True): 6,
}


class LinearizationError(ModelError):
    """A linearization request that cannot be carried out; the message names the port or state."""


@dataclass
class LinearModel:
    """``x' = A x + B u``, ``y = C x + D u`` in deviations from the operating point (SI / declared units)."""

    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    D: np.ndarray
    state_names: list
    state_units: list
    input_names: list
    input_units: list
    output_names: list
    output_units: list
    #: estimated absolute error of each entry of A, B, C, D (same shapes)
    errors: dict
    #: t, x (full state, quaternions included), z, u (inputs), y (outputs), xdot (tangent rates)
    operating_point: dict
    #: port/state name -> (indices into the state, input or output vector)
    state_index: dict
    input_index: dict
    output_index: dict
    method: dict = field(default_factory=dict)
    metadata: dict = field(default_factory=dict)

    @property
    def max_error(self) -> float:
        return max(float(np.max(e, initial=0.0)) for e in self.errors.values())

    def __str__(self) -> str:
        n, m, p = self.A.shape[0], self.B.shape[1], self.C.shape[0]
        return (f"linear model: {n} states, {m} inputs, {p} outputs; {self.method.get('points')}-point central "
                f"differences{' with Richardson extrapolation' if self.method.get('richardson') else ''}, "
                f"tolerance {self.method.get('tolerance'):g}; largest estimated entry error {self.max_error:.3g}")


# --------------------------------------------------------------------------------------------------
# quaternion tangent coordinates
def _quat_multiply(a, b):
    w1, x1, y1, z1 = a
    w2, x2, y2, z2 = b
    return np.array([w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2,
                     w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
                     w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2,
                     w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2])


def quaternion_log(q):
    """Rotation vector phi of the unit quaternion q (scalar first): ``q = Exp(phi)``, ``norm(phi) <= pi`` (the
    inverse of :func:`quaternion_exp`; q and -q give the same phi)."""
    q = np.asarray(q, dtype=float)
    if q[0] < 0.0:
        q = -q
    s = float(np.linalg.norm(q[1:]))
    if s < 1e-8:  # 2 atan2(s, w) / s = (2 / w) (1 - s^2 / (3 w^2) + ...): the first term is exact to 1e-16 here
        return 2.0 * q[1:] / q[0]
    return 2.0 * np.arctan2(s, q[0]) / s * q[1:]


def quaternion_exp(phi):
    """Unit quaternion of the rotation vector phi (scalar first)."""
    angle = float(np.linalg.norm(phi))
    half = 0.5 * angle
    s = 0.5 - angle * angle / 48.0 if angle < 1e-4 else np.sin(half) / angle
    return np.concatenate(([np.cos(half)], s * np.asarray(phi, dtype=float)))


def _skew(v):
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


def inverse_right_jacobian(phi):
    """Jr^-1(phi) of SO(3): phi' = Jr^-1(phi) omega for q = q0 (x) Exp(phi), omega in the body frame."""
    angle = float(np.linalg.norm(phi))
    S = _skew(phi)
    if angle < 1e-4:
        c = 1.0 / 12.0 + angle * angle / 720.0
    else:
        c = 1.0 / angle ** 2 - (1.0 + np.cos(angle)) / (2.0 * angle * np.sin(angle))
    return np.eye(3) + 0.5 * S + c * (S @ S)


# --------------------------------------------------------------------------------------------------
_ELEMENT = re.compile(r"^(.*)\[(\d+)\]$")


def _split_element(name: str):
    match = _ELEMENT.match(name.strip())
    if match:
        return match.group(1), int(match.group(2))
    return name.strip(), None


class TangentStates:
    """Tangent coordinates of the simulation's continuous state (quaternions -> rotation vectors); on the constraint
    manifold of a scene with closure constraints, its independent coordinates only (:class:`ConstraintManifold`)."""

    def __init__(self, sim, x0, scales):
        quaternion_starts = {int(k) for k in sim.diagram.quaternion_w_indices()}
        self.x0 = np.array(x0, dtype=float)
        self.plain = []          # (tangent index, x index)
        self.quaternions = []    # (tangent start, x start, q0)
        self.names, self.units, self.index = [], [], {}
        for key, sl, decl in sim.x_states():
            label = f"{key[0]}.{key[1]}"
            unit = format_unit(decl.unit)
            members = []
            k = sl.start
            while k < sl.stop:
                if k in quaternion_starts:
                    start = len(self.names)
                    self.quaternions.append((start, k, self.x0[k:k + 4].copy()))
                    for axis in range(3):
                        self.names.append(f"{label}[{k - sl.start}:{k - sl.start + 4}].rotation_vector[{axis}]")
                        self.units.append("rad")
                        members.append(start + axis)
                    k += 4
                else:
                    self.plain.append((len(self.names), k))
                    self.names.append(f"{label}[{k - sl.start}]" if sl.stop - sl.start > 1 else label)
                    self.units.append(unit)
                    members.append(len(self.names) - 1)
                    k += 1
            self.index[label] = np.asarray(members, dtype=np.int64)
        self.n = len(self.names)
        self.modal_sizes = []   # (tangent rows, typical size) of flexible bodies' modal coordinates
        self._add_body_indices(sim)
        typical = np.ones(self.n)
        for rows, size in self.modal_sizes:
            typical[rows] = size
        for name, given in scales.items():  # a model state or a per-body entry (later entries win)
            if name in self.index:
                typical[self.index[name]] = np.broadcast_to(np.asarray(given, dtype=float), self.index[name].shape)
        self._plain_t = np.array([t for t, _ in self.plain], dtype=np.int64)
        self._plain_x = np.array([x for _, x in self.plain], dtype=np.int64)
        self.value = np.zeros(self.n)           # tangent coordinates of x0 (rotation vectors are 0)
        self.value[self._plain_t] = self.x0[self._plain_x]
        #: index in the full state x of each tangent row (a quaternion's three rows: its w)
        self.x_rows = np.zeros(self.n, dtype=np.int64)
        self.x_rows[self._plain_t] = self._plain_x
        for t, k, _ in self.quaternions:
            self.x_rows[t:t + 3] = k
        self.scale = np.maximum(np.abs(self.value), typical)
        #: the constrained models' manifolds (:class:`ConstraintManifold`); empty: every tangent coordinate is one
        self.manifolds = [ConstraintManifold(self, sim, m) for m in sim.diagram.models if _closes_loops(m)]
        #: tangent rows of the full coordinates that are minimal coordinates (None: all of them)
        self.kept = None
        if self.manifolds:
            self._restrict_to_manifolds()

    def _restrict_to_manifolds(self) -> None:
        """Keep the independent coordinates only: names, units, index, values and scales of those rows."""
        dependent = np.concatenate([mf.dependent_rows for mf in self.manifolds])
        keep = np.ones(self.n, dtype=bool)
        keep[dependent] = False
        self.kept = np.flatnonzero(keep)
        row_of = np.full(self.n, -1, dtype=np.int64)
        row_of[self.kept] = np.arange(self.kept.size)
        self.full_n, self.full_names = self.n, list(self.names)
        self.names = [self.names[r] for r in self.kept]
        self.units = [self.units[r] for r in self.kept]
        self.index = {name: row_of[rows][row_of[rows] >= 0] for name, rows in self.index.items()}
        self.index = {name: rows for name, rows in self.index.items() if rows.size}
        self.value, self.scale, self.n = self.value[self.kept], self.scale[self.kept], self.kept.size
        self.x_rows = self.x_rows[self.kept]
        self.x0 = self.retract(np.zeros(self.n))  # on the manifold to the chart's tolerance

    def _modal_sizes(self, system, model_path) -> None:
        """Typical size of each flexible body's modal coordinates (the step rule's scale; module docstring):
        the amplitude at which the mode's largest grid rotation reaches 1 rad or its largest grid translation
        the body's extent (largest grid distance from the body frame; 1 m when it has no extent), at most 1."""
        for b, body in enumerate(system.body_names):
            flexible = system.definitions[0][b].flexible
            rows = self.index.get(f"{model_path}.{body}.modal_q")
            if flexible is None or rows is None or len(rows) != flexible.n_modes:
                continue
            shapes = np.asarray(flexible.grid_shapes, dtype=float)  # (G, 6, n): rotation rows, translation rows
            extent = float(np.max(np.linalg.norm(flexible.grid_positions, axis=1), initial=0.0)) or 1.0
            rot = np.max(np.linalg.norm(shapes[:, :3], axis=1), axis=0, initial=0.0)
            trans = np.max(np.linalg.norm(shapes[:, 3:], axis=1), axis=0, initial=0.0)
            with np.errstate(divide="ignore"):
                size = np.minimum(np.where(rot > 0.0, 1.0 / rot, np.inf), np.where(trans > 0.0, extent / trans, np.inf))
            # never above the SI default of 1: a heavy body's coordinates were well served by it (larger steps
            # there lost accuracy against the analytic launch-vehicle model of tests/linearize)
            self.modal_sizes.append((rows, np.minimum(np.where(np.isfinite(size), size, 1.0), 1.0)))

    def _add_body_indices(self, sim) -> None:
        """Index entries per body of an engine model, as in the TM G.4 delivery file's state_index
        (``bus_rotational_pos``, ``bus_modal_pos``, ...): ``<model>.<body>.hinge_q`` / ``.modal_q`` /
        ``.hinge_u`` / ``.modal_u`` (tangent rows of that body's hinge and modal coordinates)."""
        tangent_of = {}
        for t, k in self.plain:
            tangent_of[k] = [t]
        for t, k, _ in self.quaternions:
            tangent_of[k] = [t, t + 1, t + 2]
            for j in range(1, 4):
                tangent_of[k + j] = []
        for m in sim.models:
            system = getattr(m, "system", None)
            if system is None or not hasattr(system, "q_slices"):
                continue
            from dynamics.hinges import HINGE_NQ, HINGE_NU, HINGE_TYPES

            block = sim.diagram.x_block[sim.model_index[m.path]].start
            for b, body in enumerate(system.body_names):
                hinge = HINGE_TYPES[system.hinge_names[b]]
                for kind, sl, offset, n_hinge in (("q", system.q_slices[b], 0, int(HINGE_NQ[hinge])),
                                                  ("u", system.u_slices[b], system.nq, int(HINGE_NU[hinge]))):
                    start = block + offset + sl.start
                    for part, lo, hi in (("hinge", start, start + n_hinge), ("modal", start + n_hinge,
                                                                                 block + offset + sl.stop)):
                        rows = [t for k in range(lo, hi) for t in tangent_of.get(k, [])]
                        if rows:
                            self.index[f"{m.path}.{body}.{part}_{kind}"] = np.asarray(rows, dtype=np.int64)
            self._modal_sizes(system, m.path)

    def retract(self, xi):
        """Full state for tangent coordinates ``xi`` (deviations from x0); on a constraint manifold the dependent
        coordinates follow from the independent ones (:meth:`ConstraintManifold.complete`)."""
        if self.kept is None:
            return self._retract_full(xi)
        full = np.zeros(self.full_n)
        full[self.kept] = xi
        x = self._retract_full(full)
        for manifold in self.manifolds:
            manifold.complete(x)
        return x

    def _retract_full(self, xi):
        x = self.x0.copy()
        x[self._plain_x] += xi[self._plain_t]
        for t, k, q0 in self.quaternions:
            x[k:k + 4] = _quat_multiply(q0, quaternion_exp(xi[t:t + 3]))
        return x

    def between(self, x, reference):
        """Tangent coordinates of the full state x relative to the full state ``reference`` (the inverse of
        :meth:`retract` when ``reference`` is x0): differences, and ``Log(q_ref^* (x) q)`` for quaternions."""
        out = self._between_full(x, reference)
        return out if self.kept is None else out[self.kept]

    def _between_full(self, x, reference):
        out = np.empty(len(self._plain_t) + 3 * len(self.quaternions))
        out[self._plain_t] = x[self._plain_x] - reference[self._plain_x]
        for t, k, _ in self.quaternions:
            q_ref = reference[k:k + 4]
            out[t:t + 3] = quaternion_log(_quat_multiply(q_ref * np.array([1.0, -1.0, -1.0, -1.0]), x[k:k + 4]))
        return out

    def tangent_rate(self, xi, x, xdot):
        """Rates of the tangent coordinates from the full state derivative (on a constraint manifold the
        independent coordinates' rates: the chart's, as the dependent coordinates follow them)."""
        if self.kept is not None:
            return self._tangent_rate_full(self._between_full(x, self.x0), x, xdot)[self.kept]
        return self._tangent_rate_full(xi, x, xdot)

    def _tangent_rate_full(self, xi, x, xdot):
        out = np.empty(len(self._plain_t) + 3 * len(self.quaternions))
        out[self._plain_t] = xdot[self._plain_x]
        for t, k, _ in self.quaternions:
            q, qd = x[k:k + 4], xdot[k:k + 4]
            omega = 2.0 * _quat_multiply(np.array([q[0], -q[1], -q[2], -q[3]]), qd)[1:]
            out[t:t + 3] = inverse_right_jacobian(xi[t:t + 3]) @ omega
        return out


def _closes_loops(model) -> bool:
    """Whether ``model`` is an engine model with active closure constraints (force elements alone keep the tree's
    coordinates minimal)."""
    constrained = getattr(model, "constrained", None)
    return constrained is not None and len(constrained.jacobian(_initial_q(model))) > 0


def _initial_q(model):
    return np.asarray(model.continuous_states[0].initial, dtype=float)


class ConstraintManifold:
    """Minimal coordinates of one engine model with closure constraints by coordinate partitioning (Wehage and Haug,
    J. Mech. Design 104, 1982): of the model's tangent coordinates ``[dq; u]``
    (:meth:`dynamics.constraints.ConstrainedSystem.tangent_map`), ``nu - rank G`` positions and as many velocities are independent, the others
    follow from ``phi(q) = 0`` (Newton on the dependent positions, to :data:`CHART_TOLERANCE`) and ``G(q) u = 0``
    (solved for the dependent velocities). This is a chart of the state manifold ``{phi = 0, G u = 0}``, so the
    rates of the independent coordinates are exactly the chart's equations: ``A`` of the minimal model is the
    independent rows of the full Jacobian along the chart's tangent (no curvature term even away from an
    equilibrium, which an orthonormal tangent basis ``V' A V`` would miss), has neither the constraints' zero modes
    nor their Baumgarte modes, and its states keep their names and units.

    The dependent coordinates are chosen from the last to the first (modified Gram-Schmidt on the columns of ``G
    N^-1``, a column joining when its part outside the others' span exceeds :data:`PIVOT_TOLERANCE` of the largest
    column): the earliest coordinates of the tree stay independent (a crank rather than its rocker), unless that
    would leave the dependent ones ill-conditioned. The same choice serves the velocities when ``G`` restricted to
    it is well conditioned, else its own by the same rule. A quaternion whose rotation vector is partly dependent is
    corrected by right multiplication, so its independent components move at second order in the correction: the
    chart is still smooth and its tangent the partition's."""

    def __init__(self, states: TangentStates, sim, model):
        self.constrained = cs = model.constrained
        self.nq, self.nu = cs.system.nq, cs.system.nu
        self.start = sim.diagram.x_block[sim.model_index[model.path]].start
        q0 = states.x0[self.start:self.start + self.nq]
        G = cs.jacobian(q0)
        Gt = G @ np.linalg.inv(cs.tangent_map(q0))
        self.rank = int(np.linalg.matrix_rank(Gt))
        self.dependent_q = _dependent_columns(Gt, self.rank)
        self.dependent_u = self.dependent_q if _well_conditioned(G[:, self.dependent_q]) else \
            _dependent_columns(G, self.rank)
        self.independent_u = np.setdiff1d(np.arange(self.nu), self.dependent_u)
        rows = {}  # x index -> tangent rows
        for t, k in states.plain:
            rows[k] = [t]
        for t, k, _ in states.quaternions:
            rows[k] = [t, t + 1, t + 2]
        q_rows = [r for k in range(self.start, self.start + self.nq) for r in rows.get(k, [])]
        u_rows = [r for k in range(self.start + self.nq, self.start + self.nq + self.nu) for r in rows.get(k, [])]
        #: tangent rows of the full coordinates that follow from the independent ones
        self.dependent_rows = np.asarray([q_rows[j] for j in self.dependent_q] + [u_rows[j] for j in self.dependent_u],
                                         dtype=np.int64)

    def complete(self, x) -> None:
        """Dependent positions and velocities of the model's block of ``x`` (in place) from its independent ones."""
        cs, nq = self.constrained, self.nq
        q = close_loops(cs, x[self.start:self.start + nq], self.dependent_q)
        u = x[self.start + nq:self.start + nq + self.nu]
        G = cs.jacobian(q)
        u[self.dependent_u] = -np.linalg.lstsq(G[:, self.dependent_u], G[:, self.independent_u] @ u[self.independent_u],
                                               rcond=None)[0]
        x[self.start:self.start + nq] = q


def close_loops(constrained, q, dependent):
    """The configuration ``q`` with its ``dependent`` tangent coordinates (indices in u's order,
    :meth:`dynamics.constraints.ConstrainedSystem.tangent_map`) moved by Newton until the closure constraints hold to
    :data:`CHART_TOLERANCE`, the others kept; :class:`LinearizationError` when it does not converge."""
    q = np.array(q, dtype=float)
    for _ in range(CHART_ITERATIONS):
        phi = constrained.residual(q)
        if np.max(np.abs(phi), initial=0.0) <= CHART_TOLERANCE:
            return q
        Gt = constrained.jacobian(q) @ np.linalg.inv(constrained.tangent_map(q))
        step = np.zeros(constrained.system.nu)
        step[dependent] = -np.linalg.lstsq(Gt[:, dependent], phi, rcond=None)[0]
        q = constrained.retract(q, step)
    raise LinearizationError(f"the closure constraints of {list(constrained.system.body_names)} cannot be met near "
                             f"this state (|phi| = {np.max(np.abs(constrained.residual(q))):.3g} after "
                             f"{CHART_ITERATIONS} Newton steps on the dependent coordinates): a step or trim move too "
                             "large for the mechanism, or a singular position")


CHART_TOLERANCE = 1e-14
"""Constraint residual (m or rad) the chart's Newton iteration reaches: below the round-off of the differences."""
CHART_ITERATIONS = 30
PIVOT_TOLERANCE = 1e-3
"""Smallest part of a column of ``G N^-1`` outside the span of the dependent ones chosen before it, relative to the
largest column, for it to be a dependent coordinate (:class:`ConstraintManifold`): a smaller one would make the
dependent coordinates' solve ill-conditioned, and the column-pivoted QR choice is taken instead."""


def _dependent_columns(G, rank):
    """``rank`` columns of G, chosen from the last (modified Gram-Schmidt, :data:`PIVOT_TOLERANCE`), or else the
    first ``rank`` pivots of G's column-pivoted QR (the best-conditioned choice); sorted."""
    largest = float(np.max(np.linalg.norm(G, axis=0), initial=0.0))
    chosen, basis = [], []
    for j in range(G.shape[1] - 1, -1, -1):
        v = G[:, j].copy()
        for b in basis:
            v -= (b @ v) * b
        size = float(np.linalg.norm(v))
        if size > PIVOT_TOLERANCE * largest:
            chosen.append(j)
            basis.append(v / size)
            if len(chosen) == rank:
                return np.sort(np.asarray(chosen, dtype=np.int64))
    return np.sort(sla.qr(G, pivoting=True, mode="r")[1][:rank]).astype(np.int64)


def _well_conditioned(columns) -> bool:
    s = np.linalg.svd(columns, compute_uv=False)
    return s.size > 0 and s[-1] > PIVOT_TOLERANCE * s[0]


class NamedSignals:
    """Named ports/states (with optional ``[k]`` element) resolved to buffer indices."""

    def __init__(self, sim, names, what):
        self.names, self.units, self.index, self.kinds, self.positions = [], [], {}, [], []
        for name in names:
            base, element = _split_element(name)
            try:
                kind, sl, decl = sim.diagram.locate(base)
            except ModelError as exc:
                raise LinearizationError(f"{what} {name!r}: {exc}") from None
            positions = np.arange(sl.start, sl.stop)
            if element is not None:
                if element >= positions.size:
                    raise LinearizationError(f"{what} {name!r}: {base} has {positions.size} elements "
                                             f"(shape {tuple(decl.shape)}), element {element} does not exist")
                positions = positions[element:element + 1]
            if name in self.index:
                raise LinearizationError(f"{what} {name!r} is listed twice")
            start = len(self.names)
            for k, pos in enumerate(positions):
                label = name if positions.size == 1 else f"{name}[{k}]"
                self.names.append(label)
                self.units.append(format_unit(decl.unit))
                self.kinds.append(kind)
                self.positions.append(int(pos))
            self.index[name] = np.arange(start, len(self.names), dtype=np.int64)
        self.positions = np.asarray(self.positions, dtype=np.int64)
        self.kinds = list(self.kinds)
        #: (kind, where in the result, positions in that buffer) per kind: one gather per buffer (a read per element in
        #: Python was ~20 % of a 400-state linearization)
        kinds = np.asarray(self.kinds, dtype=object)
        self._groups = [(kind, np.flatnonzero(kinds == kind), self.positions[kinds == kind])
                        for kind in ("signal", "x", "z") if (kinds == kind).any()]

    def read(self, sim):
        sources = {"signal": sim.signals, "x": sim.x, "z": sim.z}
        values = np.empty(len(self.kinds))
        for kind, where, positions in self._groups:
            values[where] = sources[kind][positions]
        return values


def input_signals(sim, names):
    inputs = NamedSignals(sim, names, "input")
    input_ports = {sl.start for key, sl in sim.port_slices.items()
                   if key[1] in {port.name for port in sim.models[sim.model_index[key[0]]].inputs}}
    for name, idx in inputs.index.items():
        base, _ = _split_element(name)
        kind, sl, decl = sim.diagram.locate(base)
        if kind != "signal" or sl.start not in input_ports:
            raise LinearizationError(f"input {name!r} is not an input port (a state or an output port); "
                                     "linearize from an input port such as a hinge torque or a node force")
    return inputs


class Evaluation:
    """f and g at one perturbed point, running only the output stages that the derivatives or the
    requested outputs need (a flexible body's node accelerations, say, are skipped unless asked for),
    on the diagram opened at the inputs (their drivers no longer reach them)."""

    def __init__(self, sim, states: TangentStates, inputs: NamedSignals, outputs: NamedSignals, parameters=None):
        diagram = sim.diagram
        self.sim, self.states, self.inputs, self.outputs = sim, states, inputs, outputs
        #: named parameters the evaluations perturb (:class:`NamedParameters`), or None
        self.parameters = parameters
        self.opened = diagram.opened(inputs.positions)
        pending = list(diagram.stages_needed_by_derivatives())
        for name in outputs.index:
            path, _, leaf = diagram.split_name(_split_element(name)[0])
            model = diagram.models[diagram.model_index[path]]
            for port in model.outputs:
                if port.name == leaf:
                    pending.append((path, "feedthrough" if port.feedthrough else "state"))
            if (path, leaf) in diagram.driver:
                c = diagram.driver[(path, leaf)]
                port = diagram.port_info[(c.source_model.path, c.source_port)]
                pending.append((c.source_model.path, "feedthrough" if port.feedthrough else "state"))
        self.stages = diagram.stages_for(diagram.stages_closure(pending))

    def __call__(self, t, u0, xi, v, w=None):
        """[tangent state rates; outputs] at the operating point moved by ``xi`` (tangent states), ``v`` (inputs)
        and ``w`` (the named parameters' elements)."""
        context = self.sim.context
        if w is not None:
            self.parameters.apply(w)
        x = self.states.retract(xi)
        context.signals[self.inputs.positions] = u0 + v
        context.x[:] = x
        self.derivatives_into(t)
        return np.concatenate((self.states.tangent_rate(xi, x, context.xdot), self.outputs.read(self.sim)))

    def derivatives_into(self, t) -> None:
        """Derivatives at the context's state into its xdot: compiled when the scene is (the same numbers)."""
        self.sim.plan.derivatives_into(t, self.stages, self.opened.gather_source, self.opened.gather_factor)


class NamedParameters:
    """Named parameters of the scene (:mod:`shell.names`) as elements to perturb: a model parameter's elements in the
    run's ``p``, a rigid body's mass, center of mass and inertia (the six distinct entries of its symmetric matrix,
    each moved with its partner) in the run's engine system. :meth:`apply` writes the operating values plus ``w``,
    ``apply(None)`` the operating values again. A parameter that a model's ``configure`` reads (it builds the model
    again) and a state, rate or initial value are refused."""

    def __init__(self, sim, names):
        index, context = sim.diagram.names, sim.context
        self.sim = sim
        self.names, self.units, self.index = [], [], {}
        self._p0 = context.p.copy()
        self._plain = []   # (element, position in p)
        self._own = []     # (entry, operating value, [(element, index into the value)])
        for name in names:
            try:
                entry = index[name]
            except ModelError as exc:
                raise LinearizationError(f"parameter {name!r}: {exc}") from None
            if name in self.index:
                raise LinearizationError(f"parameter {name!r} is listed twice")
            start = len(self.names)
            if entry.kind == "parameter" and not entry.configured:
                shape = entry.shape
                for k, position in enumerate(range(entry.where.start, entry.where.stop)):
                    self._plain.append((len(self.names), position))
                    self.names.append(name if not shape else f"{name}[{k}]")
            elif entry.kind == "model" and not entry.initial:
                value = np.array(context.get(name), dtype=float)
                cells = [(i, j) for i in range(3) for j in range(i, 3)] if value.shape == (3, 3) else \
                    list(np.ndindex(*value.shape))
                elements = []
                for cell in cells:
                    elements.append((len(self.names), cell))
                    self.names.append(name if not cell else f"{name}[{','.join(str(c) for c in cell)}]")
                self._own.append((entry, value, elements))
            else:
                what = "a parameter that its model's configure reads (a change builds the model again)" \
                    if entry.kind == "parameter" else "not a parameter (a state, a rate or an initial value)"
                raise LinearizationError(f"parameter {name!r}: {what}")
            self.units += [format_unit(entry.unit)] * (len(self.names) - start)
            self.index[name] = np.arange(start, len(self.names), dtype=np.int64)
        self.n = len(self.names)
        self.value = np.zeros(self.n)  # operating values of the elements
        for k, position in self._plain:
            self.value[k] = self._p0[position]
        for _, value, elements in self._own:
            for k, cell in elements:
                self.value[k] = value[cell]

    def apply(self, w) -> None:
        context, models = self.sim.context, self.sim.diagram.models
        for k, position in self._plain:
            context.p[position] = self._p0[position] + (0.0 if w is None else w[k])
        for entry, value, elements in self._own:
            moved = value.copy()
            for k, cell in elements:
                moved[cell] = value[cell] + (0.0 if w is None else w[k])
                if len(cell) == 2:
                    moved[cell[::-1]] = moved[cell]
            models[entry.model].assign_named([(entry.leaf, moved)], context.hosts[entry.model],
                                             context.x[self.sim.diagram.x_block[entry.model]])


def linearize(sim, inputs, outputs, *, tolerance: float = 1e-10, points: int = 4, richardson: bool = True,
              t=None, x=None, input_values=None, scales=None, metadata=None) -> LinearModel:
    """Linearize ``sim`` about its current (or the given) operating point.

    inputs: input port names (``"multibody.bus.torque"``) or elements (``"...torque[2]"``).
    outputs: port or state names or elements.
    tolerance: relative truncation error aimed at (sets the steps, see the module docstring).
    points: 2 or 4 (central-difference scheme); richardson: extrapolate one level further.
    t, x: operating time and full continuous state (default: the simulation's current ones).
    input_values: {input name: value} at the operating point (default: the values the scene gives).
    scales: {input or state name: typical size} for variables whose natural size is not ~1 SI unit.
    """
    if (points, bool(richardson)) not in SCHEMES:
        raise LinearizationError(f"points = {points}: expected 2 or 4 (central differences)")
    if not tolerance > 0.0 or tolerance >= 1.0:
        raise LinearizationError(f"tolerance = {tolerance}: expected a relative error in (0, 1)")
    order = SCHEMES[(points, bool(richardson))]
    scales = dict(scales or {})
    t0 = sim.t if t is None else float(t)
    x_saved, signals_saved = sim.x.copy(), sim.signals.copy()
    x0 = sim.x.copy() if x is None else np.asarray(x, dtype=float).copy()
    if x0.shape != sim.x.shape:
        raise LinearizationError(f"operating state has shape {x0.shape}, the scene's state has {sim.x.shape}")
    sim.diagram.normalize(sim.context, x0)  # the operating point lies on the unit-quaternion manifold
    states = TangentStates(sim, x0, scales)
    ins = input_signals(sim, inputs)
    outs = NamedSignals(sim, outputs, "output")
    for name in scales:
        if name not in states.index and name not in ins.index:
            raise LinearizationError(f"scale given for {name!r}, which is neither a state nor a listed input; "
                                     f"states: {sorted(states.index)}; inputs: {list(ins.index)}")
    sim.x[:] = x0
    sim.evaluate(t0)
    u0 = sim.signals[ins.positions].copy()
    for name, value in (input_values or {}).items():
        if name not in ins.index:
            raise LinearizationError(f"operating value given for {name!r}, which is not a listed input "
                                     f"({list(ins.index)})")
        u0[ins.index[name]] = np.asarray(value, dtype=float).reshape(-1)
    input_scale = np.ones(len(ins.names))
    for name, idx in ins.index.items():
        if name in scales:
            input_scale[idx] = np.broadcast_to(np.asarray(scales[name], dtype=float), idx.shape)
    input_scale = np.maximum(np.abs(u0), input_scale)

    n, m = states.n, len(ins.names)
    p = len(outs.names)
    try:
        evaluate = Evaluation(sim, states, ins, outs)
        F0 = evaluate(t0, u0, np.zeros(n), np.zeros(m))
        jac = np.empty((n + p, n + m))
        err = np.empty((n + p, n + m))
        steps = np.empty(n + m)
        for j in range(n + m):
            scale = states.scale[j] if j < n else input_scale[j - n]

            def at(delta, j=j):
                xi, v = np.zeros(n), np.zeros(m)
                if j < n:
                    xi[j] = delta
                else:
                    v[j - n] = delta
                return evaluate(t0, u0, xi, v)

            jac[:, j], err[:, j], steps[j] = difference_column(at, scale, F0, tolerance, points, richardson,
                                                               (states.names + ins.names)[j])
    finally:
        sim.x[:] = x_saved
        sim.signals[:] = signals_saved
    A, B = jac[:n, :n], jac[:n, n:]
    C, D = jac[n:, :n], jac[n:, n:]
    errors = {"A": err[:n, :n], "B": err[:n, n:], "C": err[n:, :n], "D": err[n:, n:]}
    op = {"t": t0, "x": x0, "z": sim.z.copy(), "u": u0, "y": F0[n:], "xdot": F0[:n], "tangent": states.value,
          "x_rows": states.x_rows}
    return LinearModel(A, B, C, D, states.names, states.units, ins.names, ins.units, outs.names, outs.units,
                       errors, op, states.index, ins.index, outs.index,
                       method={"points": points, "richardson": bool(richardson), "tolerance": tolerance,
                               "order": order, "state_steps": steps[:n], "input_steps": steps[n:]},
                       metadata=dict(metadata or {}))


def difference_column(at, scale: float, F0, tolerance: float, points: int, richardson: bool, label: str):
    """(column, error estimate, step) of the derivative of ``at(delta)`` (a vector) at ``delta = 0`` by the
    module docstring's scheme: step ``scale * tolerance^(1/order)``, central differences at 1, 2 (and 4) steps,
    Richardson; the error the last correction plus the round-off of the largest value seen (``F0`` = at(0))."""
    order = SCHEMES[(points, bool(richardson))]
    h = scale * tolerance ** (1.0 / order)
    h = float((scale + h) - scale) or h  # a step representable against the variable
    levels = (1, 2) if points == 2 else (1, 2, 4)  # step multiples: the scheme and its error estimate
    diffs, fmax = {}, float(np.max(np.abs(F0), initial=0.0))
    for level in levels:
        plus, minus = at(level * h), at(-level * h)
        for F, sign in ((plus, 1.0), (minus, -1.0)):
            if not np.all(np.isfinite(F)):
                raise LinearizationError(f"non-finite derivative or output perturbing {label} by {sign * level * h:.3g}")
            fmax = max(fmax, float(np.max(np.abs(F), initial=0.0)))
        diffs[level] = (plus - minus) / (2.0 * level * h)
    column, correction = _combine(diffs, points, richardson)
    return column, np.abs(correction) + 16.0 * EPS * fmax / h, h


def _combine(diffs, points, richardson):
    """Result and last correction from the central differences D2(level h)."""
    if points == 2:
        if not richardson:
            return diffs[1], diffs[1] - diffs[2]
        d4 = (4.0 * diffs[1] - diffs[2]) / 3.0
        return d4, d4 - diffs[1]
    d4_h = (4.0 * diffs[1] - diffs[2]) / 3.0
    d4_2h = (4.0 * diffs[2] - diffs[4]) / 3.0
    if not richardson:
        return d4_h, d4_h - d4_2h
    r = (16.0 * d4_h - d4_2h) / 15.0
    return r, r - d4_h
