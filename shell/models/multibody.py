"""The multibody engine as one shell model: hinge/node inputs in, kinematics out, states (q, u).

The compiled :class:`dynamics.MultibodySystem` enters the component framework as a single model
(ARCHITECTURE.md, TM-2020-5008164 App. D.1: the DARTS engine inside Dshell). Its continuous states are
the generalized coordinates ``q`` and velocities ``u`` (CONVENTIONS.md ordering); the derivative is
``[q_dot(q, u); forward_dynamics(q, u, tau, node forces, prescribed accelerations)]`` and hinge
quaternions are renormalized by the integrator's ``normalize`` hook after every step.

Ports (``<body>`` a body name, i.e. its inboard hinge; ``<node>`` a node name):

inputs (all optional, zero when unconnected; they feed through to the accelerations)
  ``<body>.torque``            (nu_hinge,) generalized force of the hinge's free DOFs
  ``<body>.prescribed_accel``  (nu_hinge,) acceleration of a hinge with prescribed DOFs
  ``<body>.modal_force``       (n_modes,) N m, generalized force on a flexible body's modal coordinates
  ``<node>.torque``            (3,) N m, about the node origin, node axes
  ``<node>.force``             (3,) N, at the node origin, node axes
outputs
  ``q``, ``u``                 all coordinates and velocities
  ``<body>.q``, ``<body>.u``   the hinge's coordinates and velocities; ``<body>.u_dot`` (feedthrough)
  ``<body>.modal_q``, ``<body>.modal_u``, ``<body>.modal_u_dot``  a flexible body's modal coordinates
                               (dimensionless), velocities (1/s), accelerations (1/s^2, feedthrough),
                               apart from its hinge's (whose ports keep the hinge's units)
  ``<node>.attitude``          (4,) quaternion [w, x, y, z] node -> world; ``<node>.rotation`` (3, 3)
  ``<node>.position``          (3,) m, world; ``<node>.angular_velocity`` (3,) rad/s and
  ``<node>.linear_velocity``   (3,) m/s, node axes
  ``<node>.angular_acceleration``, ``<node>.linear_acceleration`` node axes (feedthrough: they need
                               the forward dynamics of the current inputs)

Attaching a model to node N binds its inputs named attitude, rotation, position, angular_velocity,
linear_velocity, angular_acceleration, linear_acceleration to N's outputs, and its outputs named torque
and force to N's inputs; attaching to hinge B binds q, u, u_dot, and torque/prescribed_accel outputs.

Hinge ports of mixed dimension (free: [rad, m] coordinates, [rad/s, m/s] velocities) are declared
without a unit and carry SI values; single-kind hinges declare rad, m, rad/s, N m or N.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit

from dynamics import engine as E
from dynamics import kernels as K
from dynamics.hinges import HINGE_NQ, HINGE_NU, HINGE_TYPES
from dynamics.modal_order import resolve_modal_orders

from shell.model import InputPort, Model, ModelError, OutputPort, State
from shell.registry import register_model
from shell.units import UnitError, to_magnitude

NODE_OUTPUTS = {  # signal -> (unit, shape, description, feedthrough)
    "attitude": ("", (4,), "quaternion [w, x, y, z] rotating node axes into world axes", False),
    "rotation": ("", (3, 3), "rotation matrix node -> world", False),
    "position": ("m", (3,), "node origin in the world frame", False),
    "angular_velocity": ("rad/s", (3,), "inertial angular velocity, node axes", False),
    "linear_velocity": ("m/s", (3,), "inertial velocity of the node origin, node axes", False),
    "angular_acceleration": ("rad/s^2", (3,), "inertial angular acceleration, node axes", True),
    "linear_acceleration": ("m/s^2", (3,), "classical acceleration of the node origin, node axes", True),
}
NODE_INPUTS = {
    "torque": ("N*m", (3,), "external torque about the node origin, node axes"),
    "force": ("N", (3,), "external force at the node origin, node axes"),
}
# unit of (q, u, u_dot, generalized force) per hinge type; "" = mixed or dimensionless (SI values)
HINGE_UNITS = {
    "locked": ("", "", "", ""),
    "revolute": ("rad", "rad/s", "rad/s^2", "N*m"),
    "prismatic": ("m", "m/s", "m/s^2", "N"),
    "ujoint": ("rad", "rad/s", "rad/s^2", "N*m"),
    "spherical": ("", "rad/s", "rad/s^2", "N*m"),
    "free": ("", "", "", ""),
}
BODY_KEYS = {
    "name": "body name", "parent": "parent body name or world", "hinge": "locked, revolute, prismatic, "
    "ujoint, spherical or free", "mass": "mass (kg)", "com": "center of mass in the body frame (m)",
    "inertia": "inertia about the center of mass, 3x3 or 3 principal moments (kg m^2)",
    "axis": "hinge axis (unit vector)", "axes": "two U-joint axes", "inboard_position": "m",
    "inboard_rotation": "3x3 or quaternion", "outboard_position": "m", "outboard_rotation": "3x3 or quaternion",
    "prescribed": "bool or one bool per hinge DOF", "initial": "initial hinge state",
    "parent_node": "node of a flexible parent the hinge attaches at",
    "body_file": "flexible body file (HDF5, from flexshell fem2modal), relative to the scenario",
    "modes": "indices of the body file's modes to keep (default all)",
    "max_frequency": "keep the body file's modes at or below this frequency, e.g. 100 Hz (with modes: the listed "
                     "modes below it)",
    "modal_integrals_order": "0, 1, 2 or auto: order of the deformation-dependent modal integrals (default auto: "
                             "the order the scene needs at its initial state, dynamics.modal_order)",
    "omit_terms": "terms of the nodes' rotary inertia to leave out: a list of G1, F2, G2 (auto chooses otherwise)",
    "damping_ratio": "modal damping ratio overriding the body file's",
    "integrals": "general or point_mass modal integrals (default general)",
    "child_grid": "grid of this flexible body that the hinge holds (its deforming interface grid)",
    "geometric_stiffening": "true/false: stiffening by the rigid-motion stresses (default: on when the body "
                            "file has them, fem2modal --geometric-stiffness)",
    "preload": "mapping preload name -> scale of the body file's named preloads (fem2modal --preload)",
}
FLEXIBLE_ONLY = ("modes", "max_frequency", "modal_integrals_order", "omit_terms", "damping_ratio", "integrals",
                 "child_grid", "geometric_stiffening", "preload")
INITIAL_KEYS = {  # key -> (unit, applies to, which slice)
    "q": ("", "all"), "u": ("", "all"),
    "angle": ("rad", "revolute ujoint"), "angle_rate": ("rad/s", "revolute ujoint"),
    "displacement": ("m", "prismatic"), "displacement_rate": ("m/s", "prismatic"),
    "attitude": ("", "spherical free"), "angular_velocity": ("rad/s", "spherical free"),
    "position": ("m", "free"), "velocity": ("m/s", "free"),
    "modal": ("", "flexible"), "modal_rate": ("1/s", "flexible"),
}


@njit(cache=True)
def rotation_to_quaternion_into(R, out):
    """Scalar-first unit quaternion (w >= 0) of rotation matrix R, Shepperd's method (as
    dynamics.spatial.rotation_to_quaternion, compiled and allocation-free for the output port)."""
    tr = R[0, 0] + R[1, 1] + R[2, 2]
    if tr > 0.0:
        s = 2.0 * np.sqrt(1.0 + tr)
        out[0] = 0.25 * s
        out[1] = (R[2, 1] - R[1, 2]) / s
        out[2] = (R[0, 2] - R[2, 0]) / s
        out[3] = (R[1, 0] - R[0, 1]) / s
    else:
        k = 0
        if R[1, 1] > R[k, k]:
            k = 1
        if R[2, 2] > R[k, k]:
            k = 2
        i = (k + 1) % 3
        j = (k + 2) % 3
        s = 2.0 * np.sqrt(1.0 + R[k, k] - R[i, i] - R[j, j])
        out[0] = (R[j, i] - R[i, j]) / s
        out[1 + k] = 0.25 * s
        out[1 + i] = (R[i, k] + R[k, i]) / s
        out[1 + j] = (R[j, k] + R[k, j]) / s
    if out[0] < 0.0:
        for m in range(4):
            out[m] = -out[m]
    norm = np.sqrt(out[0] ** 2 + out[1] ** 2 + out[2] ** 2 + out[3] ** 2)
    for m in range(4):
        out[m] /= norm


class EnginePorts(NamedTuple):
    """Where the engine model's ports sit in its input and output blocks (built once per model)."""

    nq: int
    nu: int
    q_out: int                  # start of output q in y
    u_out: int                  # start of output u in y
    tau_src: np.ndarray         # input element -> generalized force index
    tau_dst: np.ndarray
    acc_src: np.ndarray         # input element -> prescribed acceleration index
    acc_dst: np.ndarray
    force_src: np.ndarray       # input element -> flat index into node_forces (nnodes x 6)
    force_dst: np.ndarray
    node_offsets: np.ndarray    # (nnodes, 5) y starts of attitude, rotation, position, angular/linear velocity
    accel_offsets: np.ndarray   # (nnodes, 2) y starts of angular and linear acceleration
    hinge_q: np.ndarray         # (k, 3) [y start, q start, count] of <body>.q and <body>.modal_q outputs
    hinge_u: np.ndarray         # (k, 3) the same for <body>.u and <body>.modal_u
    hinge_udot: np.ndarray      # (k, 3) the same for <body>.u_dot and <body>.modal_u_dot


class EngineWork(NamedTuple):
    """Per-run scratch of the engine model: engine inputs, accelerations and node kinematics."""

    tau: np.ndarray             # (nu,) generalized forces from the hinge torque ports
    udot: np.ndarray            # (nu,) accelerations (prescribed ones on entry to the engine)
    tau_out: np.ndarray         # (nu,)
    zero_u: np.ndarray          # (nu,) zeros: node kinematics without accelerations
    node_forces: np.ndarray     # (nnodes, 6) [torque; force] per node, node axes
    rotation: np.ndarray        # (nnodes, 3, 3)
    position: np.ndarray        # (nnodes, 3)
    velocity: np.ndarray        # (nnodes, 6)
    acceleration: np.ndarray    # (nnodes, 6)
    status: np.ndarray          # (1,) int64: 0, or 1 + the body whose articulated inertia was singular


@njit(cache=True, inline="always")
def _solve_accelerations(x, u, d):
    """Scatter the input ports into the engine's arrays and run its forward dynamics into ``work.udot``.
    A singular articulated inertia records the body in ``work.status`` and makes the accelerations NaN,
    which the simulation reports with the body's name (``MultibodyModel.failure_message``)."""
    engine, ports, work = d
    nq = ports.nq
    for k in range(ports.tau_src.shape[0]):
        work.tau[ports.tau_dst[k]] = u[ports.tau_src[k]]
    for k in range(ports.force_src.shape[0]):
        f = ports.force_dst[k]
        work.node_forces[f // 6, f % 6] = u[ports.force_src[k]]
    for k in range(ports.nu):
        work.udot[k] = 0.0
    for k in range(ports.acc_src.shape[0]):
        work.udot[ports.acc_dst[k]] = u[ports.acc_src[k]]
    status = E.forward_dynamics(engine, x[:nq], x[nq:], work.tau, work.node_forces, work.udot, work.tau_out)
    work.status[0] = status
    if status != 0:
        for k in range(ports.nu):
            work.udot[k] = np.nan


@njit(cache=True, inline="always")
def _copy_blocks(source, blocks, y):
    for b in range(blocks.shape[0]):
        y0, s0, n = blocks[b, 0], blocks[b, 1], blocks[b, 2]
        for k in range(n):
            y[y0 + k] = source[s0 + k]


# operations of engine_kernel
STATE_OUTPUTS, FEEDTHROUGH_OUTPUTS, DERIVATIVES, DERIVATIVES_AFTER_FEEDTHROUGH, NORMALIZE = range(5)


@njit(cache=True)
def engine_kernel(op, t, x, z, u, p, d, out):
    """Every kernel of the engine model in one compiled function (``op`` selects it), so the engine's
    code is compiled once, not once per kernel: state outputs, feedthrough outputs (forward dynamics and
    node accelerations), derivatives (solving, or reusing the feedthrough stage's accelerations), and the
    quaternion normalization of ``x`` (``out`` unused). The engine's arrays are used as borrowed
    references (:func:`dynamics.engine.borrowed`): their reference counting was about a third of the
    derivative of a single-body scene."""
    d = E.borrowed(d)
    engine, ports, work = d
    nq, nu = ports.nq, ports.nu
    if op == STATE_OUTPUTS:
        for k in range(nq):
            out[ports.q_out + k] = x[k]
        for k in range(nu):
            out[ports.u_out + k] = x[nq + k]
        _copy_blocks(x, ports.hinge_q, out)
        _copy_blocks(x[nq:], ports.hinge_u, out)
        if ports.node_offsets.shape[0]:
            E.node_kinematics(engine, x[:nq], x[nq:], work.zero_u, work.rotation, work.position, work.velocity,
                              work.acceleration)
            _node_outputs(work.rotation, work.position, work.velocity, out, ports.node_offsets)
    elif op == FEEDTHROUGH_OUTPUTS:
        _solve_accelerations(x, u, d)
        _copy_blocks(work.udot, ports.hinge_udot, out)
        if ports.accel_offsets.shape[0]:  # reusing the workspace the forward dynamics just left
            E.node_kinematics_after_dynamics(engine, x[:nq], x[nq:], work.udot, work.rotation, work.position,
                                             work.velocity, work.acceleration)
            for n in range(ports.accel_offsets.shape[0]):
                a, b = ports.accel_offsets[n, 0], ports.accel_offsets[n, 1]
                for k in range(3):
                    out[a + k] = work.acceleration[n, k]
                    out[b + k] = work.acceleration[n, 3 + k]
    elif op == DERIVATIVES or op == DERIVATIVES_AFTER_FEEDTHROUGH:
        if op == DERIVATIVES:
            _solve_accelerations(x, u, d)
        for k in range(nu):
            out[nq + k] = work.udot[k]
        E.coordinate_rates(engine, x[:nq], x[nq:], out[:nq])
    else:
        E.normalize_quaternions(engine, x)


@njit(cache=True)
def no_engine_kernel(op, t, x, z, u, p, d, out):
    """Fills the compiled loop's engine slot in a scene without the engine model. Such a scene has no engine
    op, so this is never called; it exists so that such a scene does not compile :func:`engine_kernel`, the
    whole engine (measured: 200 trivial models compiled from an empty cache in 155 s CPU, the engine's
    share being most of it)."""
    return


def _engine_state_outputs(t, x, z, u, p, d, y):
    engine_kernel(STATE_OUTPUTS, t, x, z, u, p, d, y)


def _engine_feedthrough_outputs(t, x, z, u, p, d, y):
    engine_kernel(FEEDTHROUGH_OUTPUTS, t, x, z, u, p, d, y)


def _engine_derivatives(t, x, z, u, p, d, xdot):
    engine_kernel(DERIVATIVES, t, x, z, u, p, d, xdot)


def _engine_derivatives_after_feedthrough(t, x, z, u, p, d, xdot):
    engine_kernel(DERIVATIVES_AFTER_FEEDTHROUGH, t, x, z, u, p, d, xdot)


def _engine_normalize(x, d):
    engine_kernel(NORMALIZE, 0.0, x, x, x, x, d, x)


@njit(cache=True)
def _node_outputs(rotation, position, velocity, y, offsets):
    """Write node kinematics into the output block; offsets[n] = (attitude, rotation, position,
    angular_velocity, linear_velocity) start indices in y."""
    for n in range(offsets.shape[0]):
        o = offsets[n]
        rotation_to_quaternion_into(rotation[n], y[o[0]:o[0] + 4])
        for a in range(3):
            for b in range(3):
                y[o[1] + 3 * a + b] = rotation[n, a, b]
            y[o[2] + a] = position[n, a]
            y[o[3] + a] = velocity[n, a]
            y[o[4] + a] = velocity[n, 3 + a]


def probe_engine_data():
    """The data tuple of a one-body engine model: its numba type is that of every engine model's data
    (the compiled loop's signature), and it stands in where a scene has no engine."""
    from dynamics import Multibody

    builder = Multibody()
    builder.add_body("probe", None, mass=1.0, inertia=[1.0, 1.0, 1.0], hinge="free")
    builder.add_node("probe_node", "probe")
    return MultibodyModel("probe", builder.compile()).create_data()[1]


def _private_system(system):
    """A copy of ``system`` with its own workspace and its own mass properties (a run that changes mass
    properties must not change another run's)."""
    return system.copy(mass_properties=True)


@register_model
class MultibodyModel(Model):
    """The multibody engine (dynamics.MultibodySystem) as a model; see the module docstring."""

    summary = "multibody engine: hinge/node forces in, node/hinge kinematics out (from the multibody: section)"
    scenario_section = "multibody"
    #: shown by `flexshell models` in place of per-instance ports
    port_summary = (
        "inputs (optional, zero when unconnected): <node>.torque [N*m] (3,), <node>.force [N] (3,), "
        "<body>.torque (hinge nu,), <body>.prescribed_accel (hinge nu,), <body>.modal_force [N*m] (modes,)",
        "outputs: <node>.attitude (4,) node->world, <node>.rotation (3,3), <node>.position [m], "
        "<node>.angular_velocity [rad/s], <node>.linear_velocity [m/s], <node>.angular_acceleration, "
        "<node>.linear_acceleration (feedthrough), <body>.q, <body>.u, <body>.u_dot (hinge), <body>.modal_q, "
        "<body>.modal_u [1/s], <body>.modal_u_dot [1/s^2] (flexible bodies), q, u",
        "continuous states: q, u (docs/scenario_schema.md, section multibody)",
    )

    def __init__(self, name: str, system, *, initial_q=None, initial_u=None):
        self.system = system
        self._initial_q = system.neutral_configuration() if initial_q is None else np.asarray(initial_q, float)
        self._initial_u = np.zeros(system.nu) if initial_u is None else np.asarray(initial_u, float)
        super().__init__(name)

    @property
    def notes(self) -> tuple:
        """Choices the engine made for the user, for the run summary: the forward-dynamics solver of a
        scene with flexible bodies (and why), the engine's notes (default modal-integral orders, O(n^3)
        terms kept)."""
        s = self.system
        notes = [f"{self.path}: {note}" for note in s.notes]
        if s.topology[:, K.FLEXIBLE].any():
            notes.insert(0, f"{self.path}: forward dynamics by {s.solver_reason}")
        return tuple(notes)

    # -- declarations ----------------------------------------------------------------------------------
    def declare(self):
        s = self.system
        inputs, outputs = [], []
        outputs.append(OutputPort("q", "", (s.nq,), "generalized coordinates (SI)"))
        outputs.append(OutputPort("u", "", (s.nu,), "generalized velocities (SI)"))
        self._hinge_torque_ports, self._hinge_accel_ports = [], []
        #: per output port kind, (port, first coordinate in q or u, count): hinge and modal parts apart
        self._coordinate_ports = {"q": [], "u": [], "u_dot": []}
        for b, body in enumerate(s.body_names):
            hinge = s.hinge_names[b]
            q0, u0 = s.q_slices[b].start, s.u_slices[b].start
            nq = int(HINGE_NQ[HINGE_TYPES[hinge]])  # the hinge's own coordinates (modal ones follow them)
            nu = int(HINGE_NU[HINGE_TYPES[hinge]])
            n_modes = s.u_slices[b].stop - u0 - nu
            uq, uu, uud, uf = HINGE_UNITS[hinge]
            if nq:
                outputs.append(OutputPort(f"{body}.q", uq, (nq,), f"{hinge} hinge coordinates of {body}"))
                self._coordinate_ports["q"].append((f"{body}.q", q0, nq))
            if nu:
                outputs.append(OutputPort(f"{body}.u", uu, (nu,), f"{hinge} hinge velocities of {body}"))
                outputs.append(OutputPort(f"{body}.u_dot", uud, (nu,), f"{hinge} hinge accelerations of {body}",
                                          feedthrough=True))
                self._coordinate_ports["u"].append((f"{body}.u", u0, nu))
                self._coordinate_ports["u_dot"].append((f"{body}.u_dot", u0, nu))
                prescribed = s.prescribed_dofs[u0:u0 + nu]
                if np.any(~prescribed):
                    inputs.append(InputPort(f"{body}.torque", uf, (nu,), f"generalized force on the free DOFs of "
                                            f"the {hinge} hinge of {body}", feedthrough=True, required=False))
                    self._hinge_torque_ports.append((f"{body}.torque", slice(u0, u0 + nu)))
                if np.any(prescribed):
                    inputs.append(InputPort(f"{body}.prescribed_accel", uud, (nu,), f"accelerations of the "
                                            f"prescribed DOFs of {body}", feedthrough=True, required=False))
                    self._hinge_accel_ports.append((f"{body}.prescribed_accel", slice(u0, u0 + nu)))
            if n_modes:
                # modal coordinates eta are dimensionless (mode shapes are metres and radians per unit eta);
                # a modal force is the work per unit eta of the loads on the body, N m
                outputs.append(OutputPort(f"{body}.modal_q", "", (n_modes,), f"modal coordinates eta of {body}"))
                outputs.append(OutputPort(f"{body}.modal_u", "1/s", (n_modes,), f"modal velocities of {body}"))
                outputs.append(OutputPort(f"{body}.modal_u_dot", "1/s^2", (n_modes,),
                                          f"modal accelerations of {body}", feedthrough=True))
                self._coordinate_ports["q"].append((f"{body}.modal_q", q0 + nq, n_modes))
                self._coordinate_ports["u"].append((f"{body}.modal_u", u0 + nu, n_modes))
                self._coordinate_ports["u_dot"].append((f"{body}.modal_u_dot", u0 + nu, n_modes))
                inputs.append(InputPort(f"{body}.modal_force", "N*m", (n_modes,), f"generalized forces on the modal "
                                        f"coordinates of {body} (added to those of the node loads)",
                                        feedthrough=True, required=False))
                self._hinge_torque_ports.append((f"{body}.modal_force", slice(u0 + nu, u0 + nu + n_modes)))
        for node in s.node_names:
            for signal, (unit, shape, description, feedthrough) in NODE_OUTPUTS.items():
                outputs.append(OutputPort(f"{node}.{signal}", unit, shape, description, feedthrough))
            for signal, (unit, shape, description) in NODE_INPUTS.items():
                inputs.append(InputPort(f"{node}.{signal}", unit, shape, description, feedthrough=True,
                                        required=False))
        self.inputs = tuple(inputs)
        self.outputs = tuple(outputs)
        self.continuous_states = (State("q", "", (s.nq,), self._initial_q, "generalized coordinates"),
                                  State("u", "", (s.nu,), self._initial_u, "generalized velocities"))

    def configure(self):
        from shell.model import Layout

        s = self.system
        u_layout, y_layout = Layout.of(self.inputs), Layout.of(self.outputs)
        tau_src, tau_dst, acc_src, acc_dst, f_src, f_dst = [], [], [], [], [], []
        for port, sl in self._hinge_torque_ports:
            tau_src.extend(range(u_layout.slice(port).start, u_layout.slice(port).stop))
            tau_dst.extend(range(sl.start, sl.stop))
        for port, sl in self._hinge_accel_ports:
            acc_src.extend(range(u_layout.slice(port).start, u_layout.slice(port).stop))
            acc_dst.extend(range(sl.start, sl.stop))
        for n, node in enumerate(s.node_names):
            for signal, column in (("torque", 0), ("force", 3)):
                start = u_layout.offsets[f"{node}.{signal}"]
                f_src.extend(range(start, start + 3))
                f_dst.extend(range(6 * n + column, 6 * n + column + 3))
        as_index = lambda values: np.asarray(values, dtype=np.int64)  # noqa: E731

        def blocks(kind):
            return as_index([[y_layout.offsets[port], start, count]
                             for port, start, count in self._coordinate_ports[kind]]).reshape(-1, 3)

        self.ports = EnginePorts(
            s.nq, s.nu, y_layout.offsets["q"], y_layout.offsets["u"], as_index(tau_src), as_index(tau_dst),
            as_index(acc_src), as_index(acc_dst), as_index(f_src), as_index(f_dst),
            as_index([[y_layout.offsets[f"{node}.{k}"] for k in
                       ("attitude", "rotation", "position", "angular_velocity", "linear_velocity")]
                      for node in s.node_names]).reshape(-1, 5),
            as_index([[y_layout.offsets[f"{node}.angular_acceleration"],
                       y_layout.offsets[f"{node}.linear_acceleration"]] for node in s.node_names]).reshape(-1, 2),
            blocks("q"), blocks("u"), blocks("u_dot"))

    def create_data(self, own: bool = False):
        """(the engine system of the run, (EngineData, EnginePorts, EngineWork)); ``own``: a private copy
        of the system (own workspace and mass properties) for an additional context."""
        system = _private_system(self.system) if own else self.system
        nu, nn = system.nu, system.nnodes
        work = EngineWork(np.zeros(nu), np.zeros(nu), np.zeros(nu), np.zeros(nu), np.zeros((nn, 6)),
                          np.zeros((nn, 3, 3)), np.zeros((nn, 3)), np.zeros((nn, 6)), np.zeros((nn, 6)),
                          np.zeros(1, dtype=np.int64))
        return system, (E.engine_data(system), self.ports, work)

    def failure_message(self, data) -> str | None:
        """Why the last forward dynamics failed (singular articulated inertia), or None."""
        status = int(data[2].status[0])
        if status == 0:
            return None
        s = self.system
        return (f"articulated inertia of hinge '{s.joint_names[status - 1]}' (body '{s.body_names[status - 1]}') "
                "is singular: the subtree it moves has no inertia along a free DOF (massless subtree, or a "
                "configuration where the hinge axes align)")

    def attachment_ports(self, kind: str, target: str):
        s = self.system
        if kind == "node":
            if target not in s.node_names:
                raise ModelError(f"model {self.path}: no node {target!r}; nodes: {list(s.node_names)}")
            return ({k: f"{target}.{k}" for k in NODE_OUTPUTS}, {k: f"{target}.{k}" for k in NODE_INPUTS})
        if target not in s.body_names:
            raise ModelError(f"model {self.path}: no hinge of body {target!r}; bodies: {list(s.body_names)}")
        names = {p.name for p in self.inputs + self.outputs}
        outputs = {k: f"{target}.{k}" for k in ("q", "u", "u_dot") if f"{target}.{k}" in names}
        inputs = {k: f"{target}.{k}" for k in ("torque", "prescribed_accel") if f"{target}.{k}" in names}
        return outputs, inputs

    # -- kernels (dynamics.engine under the uniform signature, with the per-run data d) ------------------
    uses_data = True
    state_outputs = staticmethod(_engine_state_outputs)
    feedthrough_outputs = staticmethod(_engine_feedthrough_outputs)
    derivatives = staticmethod(_engine_derivatives)
    derivatives_after_feedthrough = staticmethod(_engine_derivatives_after_feedthrough)
    #: renormalize hinge quaternions in place (the integrator's normalize hook): ``normalize_state(x, d)``
    normalize_state = staticmethod(_engine_normalize)

    def stiff_linear_part(self, x, system=None):
        """(indices into this model's [q; u], L): the linear modal dynamics at the configuration of ``x`` that
        an exponential integrator propagates exactly (:func:`dynamics.modal_linear_part.modal_linear_part`);
        ``system``: the run's engine system (a Monte Carlo context's own mass properties), default the model's."""
        from dynamics.modal_linear_part import modal_linear_part

        system = self.system if system is None else system
        return modal_linear_part(system, x[:system.nq], x[system.nq:])

    def quaternion_w_indices(self) -> list[int]:
        """Positions in this model's state of each hinge quaternion's w (for the integrator's error norm)."""
        return [int(k) for k in self.system.quaternion_q_indices]

    # -- construction from a scenario -------------------------------------------------------------------
    @classmethod
    def from_description(cls, description, where) -> "MultibodyModel":
        """Build from the scenario's ``multibody:`` mapping; ``where`` locates errors (file, line, key)."""
        from dynamics import ModelDefinitionError, Multibody

        from shell.diagnostics import located
        from shell.scenario import _expect_list, _expect_mapping, _expect_name

        _expect_mapping(description, where, {"name": "engine model name (default multibody)",
                                             "gravity": "uniform gravity, world axes (m/s^2)",
                                             "bodies": "list of bodies", "nodes": "list of nodes"},
                        required=("bodies",))
        name = description.get("name", "multibody")
        gravity = _vector(description, "gravity", "m/s^2", (3,), where, (0.0, 0.0, 0.0))
        builder = Multibody(gravity=tuple(gravity))
        bodies = _expect_list(description["bodies"], where.child(description, "bodies"), "bodies")
        # nodes are added right after their body, so that a later body's hinge can attach to them
        pending_nodes = {}
        nodes = _expect_list(description.get("nodes", []), where.child(description, "nodes"), "nodes")
        for k, node in enumerate(nodes):
            here = where.child(description, "nodes").child(nodes, k)
            _expect_mapping(node, here, {"name": "node name", "body": "body it is fixed on",
                                         "position": "in the body frame (m)", "rotation": "node -> body",
                                         "grid": "FE grid id (nodes on flexible bodies)"},
                            required=("name", "body"))
            grid = node.get("grid")
            if grid is not None and (isinstance(grid, bool) or not isinstance(grid, int)):
                raise here.child(node, "grid").error(f"expected an FE grid id (integer), given {grid!r}")
            node_name = _expect_name(node["name"], here.child(node, "name"), "a node name")
            node_body = _expect_name(node["body"], here.child(node, "body"), "a body name")
            position = _vector(node, "position", "m", (3,), here) if "position" in node else None
            rotation = _rotation(node, "rotation", here)

            def add(node_name=node_name, node_body=node_body, position=position, rotation=rotation, grid=grid,
                    here=here):
                try:
                    builder.add_node(node_name, node_body, position=position, rotation=rotation, grid=grid)
                except ModelDefinitionError as exc:
                    raise here.error(str(exc)) from None

            pending_nodes.setdefault(node_body, []).append(add)
        initial = []
        for k, body in enumerate(bodies):
            here = where.child(description, "bodies").child(bodies, k)
            flexible = isinstance(body, dict) and "body_file" in body
            _expect_mapping(body, here, BODY_KEYS,
                            required=("name", "hinge") if flexible else ("name", "hinge", "mass", "inertia"))
            body_name = _expect_name(body["name"], here.child(body, "name"), "a body name")
            here = _rename(here, body_name)
            for key in (("mass", "inertia", "com") if flexible else FLEXIBLE_ONLY):
                if key in body:
                    raise here.child(body, key).error(
                        "the body file gives the mass properties of a flexible body" if flexible else
                        f"{key!r} applies to flexible bodies (with body_file:)")
            parent = body.get("parent", "world")
            if parent is not None:
                parent = _expect_name(parent, here.child(body, "parent"), "a body name or world")
            kwargs = dict(
                hinge=_expect_name(body["hinge"], here.child(body, "hinge"), "a hinge type"),
                inboard_position=_vector(body, "inboard_position", "m", (3,), here, (0, 0, 0)),
                outboard_position=_vector(body, "outboard_position", "m", (3,), here, (0, 0, 0)),
                inboard_rotation=_rotation(body, "inboard_rotation", here),
                outboard_rotation=_rotation(body, "outboard_rotation", here),
            )
            if "axis" in body:
                kwargs["axis"] = _vector(body, "axis", "", (3,), here)
            if "axes" in body:
                kwargs["axes"] = _vector(body, "axes", "", (2, 3), here)
            if "prescribed" in body:
                kwargs["prescribed"] = body["prescribed"]
            if "parent_node" in body:
                kwargs["parent_node"] = _expect_name(body["parent_node"], here.child(body, "parent_node"), "a node")
            parent = None if parent in (None, "world") else parent
            try:
                with located(here):  # the engine's warnings about this body, with its file, line and key
                    if flexible:
                        builder.add_flexible_body(body_name, parent, **_flexible_options(body, here), **kwargs)
                    else:
                        mass, com, inertia = rigid_mass_properties(body, here)
                        builder.add_body(body_name, parent, mass=mass, inertia=inertia, com=com, **kwargs)
            except (ModelDefinitionError, OSError, KeyError) as exc:
                raise here.error(str(exc.args[0] if isinstance(exc, KeyError) else exc)) from None
            for add in pending_nodes.pop(body_name, []):
                add()
            initial.append((body_name, body.get("initial"), here, body))
        for node_body in list(pending_nodes):  # nodes of bodies that do not exist: named by add_node
            for add in pending_nodes.pop(node_body):
                add()
        try:
            system = builder.compile()
        except ModelDefinitionError as exc:
            raise where.error(str(exc)) from None
        q0, u0 = initial_state(system, [(spec, here, body) for _, spec, here, body in initial])
        places = {body_name: here for body_name, _, here, _ in initial}  # the stiffening warning names its body
        with located(lambda text: next((h for b, h in places.items() if f"body '{b}'" in text), where)):
            system, _ = resolve_modal_orders(system, q0, u0)  # modal_integrals_order: auto
        return cls(name, system, initial_q=q0, initial_u=u0)


def rigid_mass_properties(body, where):
    """(mass, com, inertia about the COM) of a rigid body's scenario entry, SI."""
    return (float(_vector(body, "mass", "kg", (), where)), _vector(body, "com", "m", (3,), where, (0, 0, 0)),
            _matrix_or_diagonal(body, where))


def initial_state(system, entries):
    """(q0, u0) from each body's ``initial:`` entry (``entries``: (spec or None, where, body entry) in body
    order), quaternions normalized."""
    q0, u0 = system.neutral_configuration(), np.zeros(system.nu)
    for b, (spec, here, body) in enumerate(entries):
        if spec is not None:
            _apply_initial(system, b, spec, here.child(body, "initial"), q0, u0)
    system.normalize_quaternions(q0)
    return q0, u0


def body_entries(description, where):
    """[(body entry, where)] of the multibody: section, in order, ``where`` naming each body."""
    from shell.scenario import _expect_list

    bodies = _expect_list(description["bodies"], where.child(description, "bodies"), "bodies")
    out = []
    for k, body in enumerate(bodies):
        here = where.child(description, "bodies").child(bodies, k)
        out.append((body, _rename(here, str(body.get("name"))) if isinstance(body, dict) else here))
    return out


def _flexible_options(body, where) -> dict:
    from pathlib import Path

    path = Path(str(body["body_file"]))
    if not path.is_absolute():
        path = Path(where.file).parent / path
    if not path.exists():
        raise where.child(body, "body_file").error(f"no body file {str(path)!r} (paths are relative to the scenario)")
    options = {"modal": str(path)}
    if "modes" in body:
        modes = body["modes"]
        if not isinstance(modes, list) or not all(isinstance(m, int) and not isinstance(m, bool) for m in modes):
            raise where.child(body, "modes").error(f"expected a list of mode indices, given {modes!r}")
        options["modes"] = list(modes)
    if "max_frequency" in body:
        options.update(_max_frequency_options(body, where, path, options.get("modes")))
    order = body.get("modal_integrals_order", "auto")
    if isinstance(order, bool) or order not in (0, 1, 2, "auto"):
        raise where.child(body, "modal_integrals_order").error(f"expected 0, 1, 2 or auto, given {order!r}")
    options["order"] = order
    if "omit_terms" in body:
        omit = body["omit_terms"]
        if not isinstance(omit, list) or not set(omit) <= {"G1", "F2", "G2"}:
            raise where.child(body, "omit_terms").error(f"expected a list of G1, F2, G2, given {omit!r}")
        options["omit_terms"] = tuple(omit)
    if "damping_ratio" in body:
        options["damping_ratio"] = float(_vector(body, "damping_ratio", "", (), where))
    if "integrals" in body:
        if body["integrals"] not in ("general", "point_mass"):
            raise where.child(body, "integrals").error(f"expected general or point_mass, given {body['integrals']!r}")
        options["integrals"] = body["integrals"]
    if "child_grid" in body:
        grid = body["child_grid"]
        if not isinstance(grid, int) or isinstance(grid, bool):
            raise where.child(body, "child_grid").error(f"expected an FE grid id (integer), given {grid!r}")
        options["child_grid"] = grid
    if "geometric_stiffening" in body:
        flag = body["geometric_stiffening"]
        if not isinstance(flag, bool):
            raise where.child(body, "geometric_stiffening").error(f"expected true or false, given {flag!r}")
        options["geometric_stiffening"] = flag
    if "preload" in body:
        pre = body["preload"]
        if (not isinstance(pre, dict) or not all(isinstance(k, str) for k in pre)
                or not all(isinstance(v, (int, float)) and not isinstance(v, bool) and np.isfinite(v)
                           for v in pre.values())):
            raise where.child(body, "preload").error(f"expected a mapping preload name -> scale (number), "
                                                     f"e.g. {{thrust: 1.0}}, given {pre!r}")
        options["preload"] = {k: float(v) for k, v in pre.items()}
    return options


def _max_frequency_options(body, where, path, modes) -> dict:
    """``modal`` (the body file, read once) and ``modes`` kept by the ``max_frequency:`` cutoff
    (:func:`dynamics.mode_selection.select_modes`); the value must carry a cyclic-frequency unit."""
    import warnings

    from dynamics.flex.body_file import read_body_file
    from dynamics.mode_selection import select_modes

    from shell.units import ureg

    here = where.child(body, "max_frequency")
    value = body["max_frequency"]
    f_max = float(_vector(body, "max_frequency", "Hz", (), where))  # refuses what is not a frequency
    if isinstance(value, dict):
        quantity = ureg.Quantity(1.0, value["unit"])
    else:
        quantity = ureg.Quantity(value) if isinstance(value, str) else None
    if quantity is None or quantity.unitless:
        raise here.error(f"expected a frequency with its unit, e.g. '100 Hz', given {value!r}")
    if "radian" in str(quantity.to_root_units().units):  # pint takes rad as 1: 628 rad/s would pass as 628 Hz
        raise here.error(f"max_frequency is a cyclic frequency: give it in Hz, not in an angular unit (given "
                         f"{value!r}, i.e. {f_max / (2 * np.pi):.6g} Hz)")
    modal = read_body_file(path)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            keep = select_modes(modal.frequencies_hz, modes, f_max)
        except ValueError as exc:
            raise here.error(str(exc).replace("select_modes: ", "")) from None
    for warning in caught:
        warnings.warn(f"{here}: {str(warning.message).replace('select_modes: ', '')}", stacklevel=2)
    return {"modal": modal, "modes": keep.tolist()}


def _rename(where, body_name):
    from shell.scenario import _Where

    return _Where(where.file, where.line, f"{where.key}({body_name})")


def _vector(mapping, key, unit, shape, where, default=None):
    if key not in mapping:
        if default is None:
            raise where.error(f"missing required key {key!r}")
        return np.asarray(default, dtype=float).reshape(shape)
    try:
        return to_magnitude(mapping[key], unit, shape, key)
    except UnitError as exc:
        raise where.child(mapping, key).error(str(exc)) from None


def _matrix_or_diagonal(body, where):
    try:
        inertia = to_magnitude(body["inertia"], "kg*m^2", None, "inertia")
    except UnitError as exc:
        raise where.child(body, "inertia").error(str(exc)) from None
    if inertia.shape == (3,):
        inertia = np.diag(inertia)
    if inertia.shape != (3, 3):
        raise where.child(body, "inertia").error(f"expected a 3x3 matrix or 3 principal moments, given shape "
                                                 f"{inertia.shape}")
    return inertia


def _rotation(mapping, key, where):
    if key not in mapping:
        return None
    value = to_magnitude(mapping[key], "", None, key)
    if value.shape == (4,):
        from dynamics.spatial import quaternion_to_rotation

        norm = np.linalg.norm(value)
        if abs(norm - 1.0) > 1e-9:
            raise where.child(mapping, key).error(f"expected a unit quaternion [w, x, y, z], given norm {norm:.12g}")
        rotation = np.empty((3, 3))
        quaternion_to_rotation(value[0], value[1], value[2], value[3], rotation)
        return rotation
    if value.shape != (3, 3):
        raise where.child(mapping, key).error(f"expected a 3x3 rotation matrix or a quaternion [w, x, y, z], "
                                              f"given shape {value.shape}")
    return value


def _apply_initial(system, b, spec, where, q0, u0) -> None:
    from shell.scenario import _expect_mapping

    hinge = system.hinge_names[b]
    _expect_mapping(spec, where, {k: f"{unit or 'SI'} ({applies})" for k, (unit, applies) in INITIAL_KEYS.items()})
    qs, us = system.q_slices[b], system.u_slices[b]
    nq, nu = qs.stop - qs.start, us.stop - us.start
    hinge_nq, hinge_nu = int(HINGE_NQ[HINGE_TYPES[hinge]]), int(HINGE_NU[HINGE_TYPES[hinge]])
    n_modes = nq - hinge_nq
    kinds = hinge.split() + (["flexible"] if n_modes else [])
    for key, value in spec.items():
        unit, applies = INITIAL_KEYS[key]
        if applies != "all" and not set(applies.split()) & set(kinds):
            raise where.child(spec, key).error(f"{key!r} does not apply to a {hinge} hinge; use "
                                               f"{[k for k, (_, a) in INITIAL_KEYS.items() if a == 'all' or hinge in a.split()]}")
        target, sl, shape = {
            "q": (q0, slice(0, nq), (nq,)), "u": (u0, slice(0, nu), (nu,)),
            "angle": (q0, slice(0, hinge_nq), (hinge_nq,)), "angle_rate": (u0, slice(0, hinge_nu), (hinge_nu,)),
            "displacement": (q0, slice(0, 1), (1,)), "displacement_rate": (u0, slice(0, 1), (1,)),
            "attitude": (q0, slice(0, 4), (4,)), "angular_velocity": (u0, slice(0, 3), (3,)),
            "position": (q0, slice(4, 7), (3,)), "velocity": (u0, slice(3, 6), (3,)),
            "modal": (q0, slice(hinge_nq, nq), (n_modes,)), "modal_rate": (u0, slice(hinge_nu, nu), (n_modes,)),
        }[key]
        value_si = _vector(spec, key, unit, None, where)
        if value_si.shape == () and shape == (1,):
            value_si = value_si.reshape(1)
        if value_si.shape != shape:
            raise where.child(spec, key).error(f"expected shape {shape} for a {hinge} hinge, given {value_si.shape}")
        if key == "attitude" and abs(np.linalg.norm(value_si) - 1.0) > 1e-9:
            raise where.child(spec, key).error(f"expected a unit quaternion [w, x, y, z], given norm "
                                               f"{np.linalg.norm(value_si):.12g}")
        base = qs.start if target is q0 else us.start
        target[base + sl.start:base + sl.stop] = value_si
