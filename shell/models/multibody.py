"""The multibody engine as one shell model: hinge/node inputs in, kinematics out, states (q, u).

The compiled :class:`dynamics.MultibodySystem` enters the component framework as a single model
(docs/architecture.md, TM-2020-5008164 App. D.1: the DARTS engine inside Dshell). Its continuous states are
the generalized coordinates ``q`` and velocities ``u`` (docs/conventions.md ordering); the derivative is
``[q_dot(q, u); forward_dynamics(q, u, tau, node forces, prescribed accelerations)]`` and hinge
quaternions are renormalized by the integrator's ``normalize`` hook after every step.

A scene with closure ``constraints:`` or ``forces:`` (force elements between nodes and on hinges; a
:class:`dynamics.constraints.ConstrainedSystem`) takes a fourth path, ``"constrained"``: its accelerations are the
constrained forward dynamics of :mod:`dynamics.constraint_kernels` (the force elements' node forces added to the
applied ones; index-1 form, multipliers from ``G M^-1 G'``, no Baumgarte terms), and its drift is removed by
projection after every accepted step in the same ``normalize`` hook: the quaternions renormalized, then the positions
projected onto ``phi(q) = 0`` (Newton along ``M^-1 G'``, to :data:`PROJECTION_TOLERANCE`) and the velocities onto ``G
u = 0`` (M-orthogonal), the choice docs/closure_constraints.md measures (benchmarks/closure_drift.py). Its per-run
data carry the constraint data and loads besides the engine's (the compiled loop takes either by reference: one loop
for both).

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
  ``<constraint>.load``        (6,) [torque N m; force N]: the wrench node A exerts on node B through the
                               constraint, A's axes, about B's origin (feedthrough; constrained scenes)
  ``<body>.hinge_load``        (6,) [torque N m; force N]: the spatial force the body's hinge transmits from its
                               parent (or the ground) to the body, about the origin of the hinge's outboard frame
                               (the body side, M), in M's axes; its projection on the hinge's axes is
                               ``inverse_dynamics``' generalized force (feedthrough; ``outputs: [hinge_load]``)
  ``energy``                   (4,) J: kinetic, gravity and elastic potential, force elements' potential, total
                               (``outputs: [energy]``)
Asked-for outputs (``outputs:``) are computed by the constrained path's kernel (a scene without constraints or force
elements takes it when it asks for them), in the stage their kind runs in: hinge loads with the feedthrough outputs
(a Newton-Euler pass after the forward dynamics), the energy with the state outputs; a scene that does not ask has
neither port and pays nothing.

Attaching a model to node N binds its inputs named attitude, rotation, position, angular_velocity,
linear_velocity, angular_acceleration, linear_acceleration to N's outputs, and its outputs named torque
and force to N's inputs; attaching to hinge B binds q, u, u_dot, and torque/prescribed_accel outputs.

Node kinematics are computed only for the nodes whose outputs something reads ("model no more than a scene
needs"): a connection (decided when the diagram is built), a logged signal, a linearization's output or a name read
later (:meth:`MultibodyModel.output_read`, called by :meth:`shell.diagram.Diagram.note_read`). The choice is an
int64 mask in the per-run data (``EnginePorts.node_read``, shared by every run of the model), read by the one compiled
kernel of the path; the outputs of a node nothing reads are NaN, and the run summary names those nodes. A node that
only receives a force needs no kinematics: the forward dynamics projects its force (and skips an exactly-zero one).
Within a derivative evaluation (the integrator's right-hand side: the op codes
:data:`shell.kernel_protocol.STATE_OUTPUTS_FOR_DERIVATIVES` and
:data:`~shell.kernel_protocol.FEEDTHROUGH_OUTPUTS_FOR_DERIVATIVES`) only the nodes a derivative reads are computed
(``EnginePorts.node_read_in_derivatives``: a connection to a model with continuous states, or through feedthrough
stages to one, such as an IMU integrating its node's motion); the outputs of the nodes read only at samples, by logs
or by name are NaN there, and computed at the evaluations that read them (a sample's, a log's, ``evaluate``). The state
outputs (poses and velocities) come from the kinematics of only the bodies those nodes ride on and their ancestors
(:func:`dynamics.kernels.node_frames.node_velocities_selected`).

Hinge ports of mixed dimension (free: [rad, m] coordinates, [rad/s, m/s] velocities) are declared
without a unit and carry SI values; single-kind hinges declare rad, m, rad/s, N m or N.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit

from dynamics import constraint_kernels as CK
from dynamics import engine as E
from dynamics import kernels as K
from dynamics import single_body as SB
from dynamics.kernels.node_frames import (node_kinematics_after_dynamics_selected, node_kinematics_selected,
                                          node_velocities_selected)
from dynamics.errors import ModelDefinitionError
from dynamics.hinges import HINGE_NQ, HINGE_NU, HINGE_TYPES, HINGES

from shell.kernel_protocol import (DERIVATIVES, DERIVATIVES_AFTER_FEEDTHROUGH, FEEDTHROUGH_OUTPUTS,
                                   FEEDTHROUGH_OUTPUTS_FOR_DERIVATIVES, NORMALIZE, STATE_OUTPUTS,
                                   STATE_OUTPUTS_FOR_DERIVATIVES)
from shell.model import InputPort, Model, ModelError, OutputPort, State
from shell.ports import NODE_INPUTS, NODE_OUTPUTS
from shell.registry import register_model
from shell.schema.multibody import OPTIONAL_OUTPUTS, initial_targets
from shell.units import UnitError, to_magnitude

# unit of (q, u, u_dot, generalized force) per hinge type; "" = mixed or dimensionless (SI values)
HINGE_UNITS = {h.name: h.units for h in HINGES}


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
    node_read: np.ndarray       # (nnodes,) int64: 1 for a node whose outputs something reads (MultibodyModel.output_read)
    node_read_in_derivatives: np.ndarray  # (nnodes,) int64: 1 for a node whose outputs a derivative evaluation reads


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
    bodies: np.ndarray          # (nb,) int64 scratch: the bodies the selected nodes' poses and velocities need
    status: np.ndarray          # (1,) int64: 0, or 1 + the body whose articulated inertia was singular


@njit(cache=True, inline="always")
def _gather_inputs(x, u, d):
    """Scatter the input ports into the engine's arrays: hinge forces, node forces and the prescribed
    accelerations (``work.udot``, zero elsewhere) that the forward dynamics reads."""
    engine, ports, work = d
    for k in range(ports.tau_src.shape[0]):
        work.tau[ports.tau_dst[k]] = u[ports.tau_src[k]]
    for k in range(ports.force_src.shape[0]):
        f = ports.force_dst[k]
        work.node_forces[f // 6, f % 6] = u[ports.force_src[k]]
    for k in range(ports.nu):
        work.udot[k] = 0.0
    for k in range(ports.acc_src.shape[0]):
        work.udot[ports.acc_dst[k]] = u[ports.acc_src[k]]


@njit(cache=True, inline="always")
def _record_status(status, d):
    """A singular articulated inertia records the body in ``work.status`` and makes the accelerations NaN,
    which the simulation reports with the body's name (``MultibodyModel.failure_message``)."""
    engine, ports, work = d
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


@njit(cache=True, inline="always")
def _coordinate_outputs(x, ports, out):
    """``q``, ``u`` and the per-body coordinate outputs from the state ``x``."""
    nq, nu = ports.nq, ports.nu
    for k in range(nq):
        out[ports.q_out + k] = x[k]
    for k in range(nu):
        out[ports.u_out + k] = x[nq + k]
    _copy_blocks(x, ports.hinge_q, out)
    _copy_blocks(x[nq:], ports.hinge_u, out)


@njit(cache=True, inline="always")
def _acceleration_outputs(ports, work, active, out):
    """The nodes' angular and linear accelerations (left in ``work.acceleration``) into the output block; NaN for a
    node not in ``active`` (its kinematics were not computed: see :meth:`MultibodyModel.output_read`)."""
    for n in range(ports.accel_offsets.shape[0]):
        a, b = ports.accel_offsets[n, 0], ports.accel_offsets[n, 1]
        read = active[n] != 0
        for k in range(3):
            out[a + k] = work.acceleration[n, k] if read else np.nan
            out[b + k] = work.acceleration[n, 3 + k] if read else np.nan


@njit(cache=True, inline="always")
def _tree_node_velocities(d, q, u, active, work):
    """Poses and velocities of the nodes with ``active[n] != 0`` from the kinematics of the bodies they need
    (articulated and dense paths, constrained scenes: the state outputs)."""
    node_velocities_selected(d.topology, d.nodes, d.joint_rot, d.joint_vec, d.params, q, u, work.rotation,
                             work.position, work.velocity, d.ws_rot, d.ws_vec, d.ws_mat, d.pool, active, work.bodies)


@njit(cache=True, inline="always")
def _tree_node_kinematics(d, q, u, udot, active, rotation, position, velocity, acceleration):
    """Node kinematics of the nodes with ``active[n] != 0`` (articulated and dense paths, constrained scenes)."""
    node_kinematics_selected(d.topology, d.nodes, d.joint_rot, d.joint_vec, d.params, q, u, udot, rotation, position,
                             velocity, acceleration, d.ws_rot, d.ws_vec, d.ws_mat, d.pool, active)


@njit(cache=True, inline="always")
def _tree_node_kinematics_after_dynamics(d, q, u, udot, active, rotation, position, velocity, acceleration):
    """:func:`_tree_node_kinematics` reusing the forward dynamics' workspace
    (:func:`dynamics.engine.node_kinematics_after_dynamics`)."""
    node_kinematics_after_dynamics_selected(d.topology, d.nodes, d.joint_rot, d.joint_vec, d.params, q, u, udot,
                                            rotation, position, velocity, acceleration, d.ws_rot, d.ws_vec, d.ws_mat,
                                            d.pool, active)


@njit(cache=True, inline="always")
def _single_body_node_velocities(d, q, u, active, work):
    """Every node of a single rigid body (:func:`_single_body_node_kinematics`, accelerations for zero ``udot``)."""
    SB.node_kinematics(d.topology, d.nodes, d.joint_rot, d.joint_vec, d.params, q, u, work.zero_u, work.rotation,
                       work.position, work.velocity, work.acceleration, d.ws_rot, d.ws_vec)


@njit(cache=True, inline="always")
def _single_body_node_kinematics(d, q, u, udot, active, rotation, position, velocity, acceleration):
    """Every node of a single rigid body (a few flops per node: not worth a mask; the outputs of the nodes nothing
    reads are still made NaN by the writers)."""
    SB.node_kinematics(d.topology, d.nodes, d.joint_rot, d.joint_vec, d.params, q, u, udot, rotation, position,
                       velocity, acceleration, d.ws_rot, d.ws_vec)


@njit(cache=True, inline="always")
def _single_body_node_kinematics_after_dynamics(d, q, u, udot, active, rotation, position, velocity, acceleration):
    SB.node_kinematics_after_dynamics(d.nodes, d.params, rotation, position, velocity, acceleration, d.ws_rot,
                                      d.ws_vec)


#: path name -> (node poses and velocities, node kinematics after the forward dynamics) taking the node mask
_NODE_KINEMATICS = {"single_body": (_single_body_node_velocities, _single_body_node_kinematics_after_dynamics),
                    "articulated": (_tree_node_velocities, _tree_node_kinematics_after_dynamics),
                    "dense": (_tree_node_velocities, _tree_node_kinematics_after_dynamics)}


def _engine_kernel(path):
    """The engine model's kernel for the systems of one path (:data:`dynamics.engine.PATHS`): it contains that
    path's code only, so a rigid single-body scene compiles neither the articulated-body recursion nor the
    dense solver (measured on the demo from an empty cache: see docs/benchmarks.md, "Compile time")."""
    forward_dynamics = path.forward_dynamics
    node_velocities, node_kinematics_after_dynamics = _NODE_KINEMATICS[path.name]

    def engine_kernel(op, t, x, z, u, p, d, out):
        """Every kernel of the engine model in one compiled function, its op kernel (:mod:`shell.kernel_protocol`:
        ``op`` selects it), so the engine's code is compiled once, not once per kernel: state outputs, feedthrough
        outputs (forward dynamics and node accelerations), each of every node read or (``*_FOR_DERIVATIVES``) of
        the nodes a derivative reads, derivatives (solving, or reusing the feedthrough stage's accelerations), and
        the quaternion normalization of ``x`` (``out`` unused). The engine's arrays are used as borrowed
        references (:func:`dynamics.engine.borrowed`): their reference counting was about a third of the
        derivative of a single-body scene."""
        d = E.borrowed(d)
        engine, ports, work = d
        nq, nu = ports.nq, ports.nu
        if op == STATE_OUTPUTS or op == STATE_OUTPUTS_FOR_DERIVATIVES:
            _coordinate_outputs(x, ports, out)
            if ports.node_offsets.shape[0]:
                active = ports.node_read if op == STATE_OUTPUTS else ports.node_read_in_derivatives
                node_velocities(engine, x[:nq], x[nq:], active, work)
                _node_outputs(work.rotation, work.position, work.velocity, out, ports.node_offsets, active)
        elif op == FEEDTHROUGH_OUTPUTS or op == FEEDTHROUGH_OUTPUTS_FOR_DERIVATIVES:
            _gather_inputs(x, u, d)
            _record_status(forward_dynamics(engine, x[:nq], x[nq:], work.tau, work.node_forces, work.udot,
                                            work.tau_out), d)
            _copy_blocks(work.udot, ports.hinge_udot, out)
            if ports.accel_offsets.shape[0]:  # reusing the workspace the forward dynamics just left
                active = ports.node_read if op == FEEDTHROUGH_OUTPUTS else ports.node_read_in_derivatives
                node_kinematics_after_dynamics(engine, x[:nq], x[nq:], work.udot, active, work.rotation,
                                               work.position, work.velocity, work.acceleration)
                _acceleration_outputs(ports, work, active, out)
        elif op == DERIVATIVES or op == DERIVATIVES_AFTER_FEEDTHROUGH:
            if op == DERIVATIVES:
                _gather_inputs(x, u, d)
                _record_status(forward_dynamics(engine, x[:nq], x[nq:], work.tau, work.node_forces, work.udot,
                                                work.tau_out), d)
            for k in range(nu):
                out[nq + k] = work.udot[k]
            E.coordinate_rates(engine, x[:nq], x[nq:], out[:nq])
        else:
            E.normalize_quaternions(engine, x)

    # a name of its own per path: compiled code is named after the function, and the three closures share one
    # code object (loaded from the cache into one process, same-named kernels would resolve to one another)
    engine_kernel.__name__ = engine_kernel.__qualname__ = f"engine_kernel_{path.name}"
    return njit(cache=True)(engine_kernel)


PROJECTION_TOLERANCE = 1e-10
"""Largest constraint residual (m or rad) left by the projection after each step of a constrained scene."""
PROJECTION_ITERATIONS = 20


class ConstraintPorts(NamedTuple):
    """What a constrained scene's data carry besides the engine's: the constraints and their loads, and the optional
    outputs (``multibody.outputs:``) with their scratch."""

    data: CK.ConstraintData     # constraints, force elements, scratch (dynamics.constraints.ConstrainedSystem)
    loads: np.ndarray           # (nc, 6) each constraint's wrench of the last forward dynamics
    load_out: np.ndarray        # (nc,) y start of <constraint>.load
    hinge_loads: np.ndarray     # (nb, 6) each hinge's spatial force of the last forward dynamics
    hinge_load_out: np.ndarray  # (nb,) y start of <body>.hinge_load, or empty (not asked for)
    energy: np.ndarray          # (8,) scratch of the energy and momentum kernel
    energy_out: np.ndarray      # (1,) y start of energy, or empty (not asked for)


@njit(cache=True)
def engine_kernel_constrained(op, t, x, z, u, p, d, out):
    """The engine model's op kernel for a scene with closure constraints (module docstring): the kernels of
    :func:`_engine_kernel` with the constrained forward dynamics, node accelerations from a full kinematics pass
    (the constrained solve leaves the tree's workspace changed), the constraint loads, and the projection of
    ``x`` onto the constraints after the quaternion normalization. A projection that does not converge records
    status 2 in ``work.status[1]`` and makes the velocities NaN (the simulation stops and reports it)."""
    d = E.borrowed(d)
    engine, ports, work, closure = d
    tree = (engine, ports, work)
    c = closure.data
    nq, nu = ports.nq, ports.nu
    if op == STATE_OUTPUTS or op == STATE_OUTPUTS_FOR_DERIVATIVES:
        _coordinate_outputs(x, ports, out)
        if ports.node_offsets.shape[0]:
            active = ports.node_read if op == STATE_OUTPUTS else ports.node_read_in_derivatives
            _tree_node_velocities(engine, x[:nq], x[nq:], active, work)
            _node_outputs(work.rotation, work.position, work.velocity, out, ports.node_offsets, active)
        if closure.energy_out.shape[0]:
            _energy_output(engine, c, x[:nq], x[nq:], closure, out)
    elif op == FEEDTHROUGH_OUTPUTS or op == FEEDTHROUGH_OUTPUTS_FOR_DERIVATIVES or op == DERIVATIVES:
        _gather_inputs(x, u, tree)
        _record_status(CK.forward_dynamics(engine, c, x[:nq], x[nq:], work.tau, work.node_forces, work.udot,
                                           work.tau_out, closure.loads), tree)
        if op != DERIVATIVES:
            _copy_blocks(work.udot, ports.hinge_udot, out)
            for i in range(closure.load_out.shape[0]):
                for k in range(6):
                    out[closure.load_out[i] + k] = closure.loads[i, k]
            if ports.accel_offsets.shape[0]:
                active = ports.node_read if op == FEEDTHROUGH_OUTPUTS else ports.node_read_in_derivatives
                _tree_node_kinematics(engine, x[:nq], x[nq:], work.udot, active, work.rotation,
                                      work.position, work.velocity, work.acceleration)
                _acceleration_outputs(ports, work, active, out)
            if closure.hinge_load_out.shape[0]:  # last: its Newton-Euler pass reuses the engine's workspace
                CK.hinge_loads(engine, c, x[:nq], x[nq:], work.udot, closure.hinge_loads)
                for i in range(closure.hinge_load_out.shape[0]):
                    for k in range(6):
                        out[closure.hinge_load_out[i] + k] = closure.hinge_loads[i, k]
        else:
            _constrained_rates(engine, ports, work, x, out)
    elif op == DERIVATIVES_AFTER_FEEDTHROUGH:
        _constrained_rates(engine, ports, work, x, out)
    else:
        E.normalize_quaternions(engine, x)
        if (CK.project_positions(engine, c, x[:nq], PROJECTION_TOLERANCE, PROJECTION_ITERATIONS) < 0
                or CK.project_velocities(engine, c, x[:nq], x[nq:]) < 0):
            work.status[1] = 2
            for k in range(nu):
                x[nq + k] = np.nan


@njit(cache=True)
def _energy_output(engine, c, q, u, closure, out):
    """``energy`` = [kinetic, gravity and elastic potential, force elements' potential, total] (J)."""
    K.energy_momentum(engine.topology, engine.nodes, engine.joint_rot, engine.joint_vec, engine.params, q, u,
                      closure.energy, engine.ws_rot, engine.ws_vec, engine.ws_mat, engine.pool)
    elements = CK.potential_energy(engine, c, q)
    o = closure.energy_out[0]
    out[o] = closure.energy[0]
    out[o + 1] = closure.energy[1]
    out[o + 2] = elements
    out[o + 3] = closure.energy[0] + closure.energy[1] + elements


@njit(cache=True, inline="always")
def _constrained_rates(engine, ports, work, x, out):
    nq, nu = ports.nq, ports.nu
    for k in range(nu):
        out[nq + k] = work.udot[k]
    E.coordinate_rates(engine, x[:nq], x[nq:], out[:nq])


#: path name -> the engine model's kernel for systems of that path (each compiled on first use); a scene with
#: closure constraints takes :func:`engine_kernel_constrained`
ENGINE_KERNELS = {name: _engine_kernel(path) for name, path in E.PATHS.items()}


@njit(cache=True)
def _node_outputs(rotation, position, velocity, y, offsets, read):
    """Write node kinematics into the output block; offsets[n] = (attitude, rotation, position,
    angular_velocity, linear_velocity) start indices in y; NaN for a node with ``read[n] == 0`` (nothing reads its
    outputs: its kinematics were not computed)."""
    for n in range(offsets.shape[0]):
        o = offsets[n]
        if read[n] == 0:
            for k in range(4):
                y[o[0] + k] = np.nan
            for k in range(9):
                y[o[1] + k] = np.nan
            for k in range(3):
                y[o[2] + k] = np.nan
                y[o[3] + k] = np.nan
                y[o[4] + k] = np.nan
            continue
        rotation_to_quaternion_into(rotation[n], y[o[0]:o[0] + 4])
        for a in range(3):
            for b in range(3):
                y[o[1] + 3 * a + b] = rotation[n, a, b]
            y[o[2] + a] = position[n, a]
            y[o[3] + a] = velocity[n, a]
            y[o[4] + a] = velocity[n, 3 + a]


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
        "<body>.modal_u [1/s], <body>.modal_u_dot [1/s^2] (flexible bodies), q, u; <constraint>.load (constraints:); "
        "<body>.hinge_load, energy [J] (outputs: [hinge_load, energy])",
        "continuous states: q, u (docs/scenario_schema.md, section multibody)",
    )

    def __init__(self, name: str, system, *, initial_q=None, initial_u=None, written_q=None, constrained=None,
                 assembly=None, outputs=()):
        self.system = system
        #: the optional outputs asked for (:data:`OPTIONAL_OUTPUTS`); they are computed on the constrained path
        self.optional_outputs = tuple(outputs)
        unknown = [o for o in self.optional_outputs if o not in OPTIONAL_OUTPUTS]
        if unknown or (self.optional_outputs and constrained is None):
            raise ModelError(f"model {name}: optional outputs {unknown or list(self.optional_outputs)}: expected "
                             f"some of {list(OPTIONAL_OUTPUTS)}, on a system with a ConstrainedSystem (the "
                             "constrained path computes them)")
        #: the closure constraints and force elements (a dynamics.constraints.ConstrainedSystem on ``system``), or None
        self.constrained = constrained
        #: how far the initial state was moved onto the constraints (dynamics.constraints.AssemblyReport), or None
        self.assembly = assembly
        #: the engine's path for this system (its kernel compiles that path only)
        self.engine_path = "constrained" if constrained is not None else E.path_of(system)
        self._initial_q = system.neutral_configuration() if initial_q is None else np.asarray(initial_q, float)
        self._initial_u = np.zeros(system.nu) if initial_u is None else np.asarray(initial_u, float)
        #: the initial coordinates as written, before their quaternions were normalized: a run that changes a
        #: body's initial value normalizes from these, as the scene built with that value does
        self.written_q = self._initial_q.copy() if written_q is None else np.asarray(written_q, float)
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
        skipped = [n for n, r in zip(s.node_names, self.ports.node_read) if not r]
        if skipped:
            notes.append(f"{self.path}: node kinematics of {len(s.node_names) - len(skipped)} of {len(s.node_names)} "
                         f"nodes (those whose outputs are connected, logged or read); not computed, outputs NaN until "
                         f"read: {', '.join(skipped)}")
        sampled = [n for n, r, d in zip(s.node_names, self.ports.node_read, self.ports.node_read_in_derivatives)
                   if r and not d]
        if sampled:
            derivatives = ", ".join(self.nodes_read_in_derivatives) or "no node"
            notes.append(f"{self.path}: between samples (the integrator's derivative evaluations) node kinematics of "
                         f"{derivatives} only; computed at the samples, logs and reads that need them: "
                         f"{', '.join(sampled)}")
        if self.constrained is not None and self.constrained.forces:
            from dynamics.force_elements import ELEMENT_TYPES

            kinds = {cls: kind for kind, cls in ELEMENT_TYPES.items()}
            notes.append(f"{self.path}: force elements "
                         + ", ".join(f"{f.name} ({kinds[type(f)]})" for f in self.constrained.forces))
        if self.optional_outputs and not (self.constrained.constraints or self.constrained.forces):
            notes.append(f"{self.path}: {' and '.join(self.optional_outputs)} asked for: the constrained path "
                         "computes them (no constraints, no force elements)")
        if self.constrained is not None and self.constrained.constraints:
            names = ", ".join(f"{c.label} ({c.kind})" for c in self.constrained.constraints)
            notes.append(f"{self.path}: closure constraints {names}; drift removed by projection after each step "
                         f"(to {PROJECTION_TOLERANCE:g})")
            a = self.assembly
            if a is not None and a.residual > 0.0:
                notes.append(f"{self.path}: initial state assembled onto the constraints: residual {a.residual:.3e} "
                             f"({a.worst}), coordinates moved by at most {a.moved:.3e}, velocities by "
                             f"{a.velocity_change:.3e}")
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
        for c in self.constrained.constraints if self.constrained is not None else ():
            outputs.append(OutputPort(f"{c.label}.load", "", (6,), f"[torque N*m; force N] of node {c.node_a} on "
                                      f"node {c.node_b or 'world'} through {c.label}, {c.node_a} axes, about "
                                      f"{c.node_b or 'world'}'s origin", feedthrough=True))
        if "hinge_load" in self.optional_outputs:
            for body in s.body_names:
                outputs.append(OutputPort(f"{body}.hinge_load", "", (6,), f"[torque N*m; force N] the hinge of {body} "
                                          "transmits from its parent (or the ground) to it, about and in the axes of "
                                          "its outboard frame (the body-side hinge frame)", feedthrough=True))
        if "energy" in self.optional_outputs:
            outputs.append(OutputPort("energy", "J", (4,), "[kinetic, gravity and elastic potential, force elements' "
                                      "potential, total] energy"))
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
            blocks("q"), blocks("u"), blocks("u_dot"), np.zeros(len(s.node_names), dtype=np.int64),
            np.zeros(len(s.node_names), dtype=np.int64))
        self._node_index = {node: n for n, node in enumerate(s.node_names)}
        self._load_out = as_index([y_layout.offsets[f"{c.label}.load"] for c in
                                   (self.constrained.constraints if self.constrained is not None else ())])
        self._hinge_load_out = as_index([y_layout.offsets[f"{body}.hinge_load"] for body in s.body_names
                                         if "hinge_load" in self.optional_outputs])
        self._energy_out = as_index([y_layout.offsets["energy"]] if "energy" in self.optional_outputs else [])

    def create_data(self, own: bool = False):
        """(the engine system of the run, (EngineData, EnginePorts, EngineWork)); ``own``: a private copy
        of the system (own workspace and mass properties) for an additional context."""
        constrained = self.constrained
        if constrained is not None:
            constrained = constrained.copy() if own else constrained
            system = constrained.system
        else:
            system = _private_system(self.system) if own else self.system
        nu, nn = system.nu, system.nnodes
        work = EngineWork(np.zeros(nu), np.zeros(nu), np.zeros(nu), np.zeros(nu), np.zeros((nn, 6)),
                          np.zeros((nn, 3, 3)), np.zeros((nn, 3)), np.zeros((nn, 6)), np.zeros((nn, 6)),
                          np.zeros(system.nbodies, dtype=np.int64), np.zeros(1 if constrained is None else 2,
                                                                             dtype=np.int64))
        if constrained is None:
            return system, (E.engine_data(system), self.ports, work)
        loads = np.zeros((len(constrained.constraints), 6))
        return system, (constrained.engine, self.ports, work,
                        ConstraintPorts(constrained.data, loads, self._load_out, np.zeros((system.nbodies, 6)),
                                        self._hinge_load_out, np.zeros(8), self._energy_out))

    def failure_message(self, data) -> str | None:
        """Why the last forward dynamics failed (singular articulated inertia), or None."""
        if data[2].status.shape[0] > 1 and data[2].status[1]:
            return (f"the projection onto the closure constraints did not converge in {PROJECTION_ITERATIONS} "
                    f"iterations (to {PROJECTION_TOLERANCE:g}): the constraints cannot be met near this configuration "
                    "(a singular position of the mechanism, or a step too large)")
        status = int(data[2].status[0])
        if status == 0:
            return None
        if status < 0:
            return "the mass matrix of the constrained system is not positive definite"
        s = self.system
        return (f"articulated inertia of hinge '{s.joint_names[status - 1]}' (body '{s.body_names[status - 1]}') "
                "is singular: the subtree it moves has no inertia along a free DOF (massless subtree, or a "
                "configuration where the hinge axes align)")

    # -- named values (shell.names): mass properties and initial values a run may change ------------------------
    def named_values(self) -> dict:
        """``<body>.mass``, ``.com``, ``.inertia`` of each rigid body (a run's own engine system takes them:
        :meth:`dynamics.MultibodySystem.set_mass_properties`) and ``<body>.initial.<key>`` of each body (the
        scenario's initial keys its hinge takes): {leaf: (unit, shape, description, is an initial value)}; an
        inertia takes 3 principal moments or a 3 x 3 matrix (shape None)."""
        s = self.system
        values = {}
        for b, body in enumerate(s.body_names):
            if not s.topology[b, K.FLEXIBLE]:
                values[f"{body}.mass"] = ("kg", (), f"mass of {body}", False)
                values[f"{body}.com"] = ("m", (3,), f"center of mass of {body}, body frame", False)
                values[f"{body}.inertia"] = ("kg*m^2", None, f"inertia of {body} about its center of mass", False)
            for key, (_, _, shape, unit) in initial_targets(s, b).items():
                values[f"{body}.initial.{key}"] = (unit, shape, f"initial {key} of {body}'s hinge", True)
        return values

    def named_value(self, leaf: str, system):
        """The value of named value ``leaf`` in the run whose engine system is ``system``."""
        body, _, key = leaf.partition(".")
        if key.startswith("initial."):
            target, sl, shape, _ = initial_targets(system, system.body_index(body))[key[len("initial."):]]
            return (self.written_q if target == "q" else self._initial_u)[sl].reshape(shape).copy()
        definition = system.definitions[0][system.body_index(body)]
        return np.array(getattr(definition, key), dtype=float)

    def assign_named(self, items, system, x) -> None:
        """Named values ``items`` ((leaf, value) pairs) into the run's engine ``system`` (mass properties) and its
        state ``x`` (initial values: the coordinates as written, the changed ones replaced, quaternions then
        normalized, so the run starts where the scene built with those values starts)."""
        masses: dict[str, dict] = {}
        initial = []
        for leaf, value in items:
            body, _, key = leaf.partition(".")
            if key.startswith("initial."):
                initial.append((body, key[len("initial."):], value))
            else:
                masses.setdefault(body, {})[key] = value
        for body, given in masses.items():
            definition = system.definitions[0][system.body_index(body)]
            mass = float(_converted(given["mass"], "kg", (), f"{body}.mass")) if "mass" in given else definition.mass
            com = _converted(given["com"], "m", (3,), f"{body}.com") if "com" in given else definition.com
            inertia = definition.inertia
            if "inertia" in given:
                inertia = _converted(given["inertia"], "kg*m^2", None, f"{body}.inertia")
                inertia = np.diag(inertia) if inertia.shape == (3,) else inertia
                if inertia.shape != (3, 3):
                    raise ModelError(f"{self.path}.{body}.inertia: expected a 3x3 matrix or 3 principal moments, "
                                     f"given shape {inertia.shape}")
            try:
                system.set_mass_properties(body, mass, com, inertia)
            except ValueError as exc:
                raise ModelError(f"{self.path}.{body}: {exc}") from None
        if initial and self.constrained is not None and self.constrained.takes_reference():
            from shell.names import StructuralChange

            raise StructuralChange(f"{self.path}.{initial[0][0]}.initial.{initial[0][1]}: a constraint or force "
                                   "element of this scene takes its pose or length from the initial state (none "
                                   "given), so a run with another initial state is another scene")
        if initial:
            q, u = self.written_q.copy(), self._initial_u.copy()
            for body, key, value in initial:
                target, sl, shape, unit = initial_targets(system, system.body_index(body))[key]
                value_si = _converted(value, unit, None, f"{body}.initial.{key}")
                value_si = value_si.reshape(1) if value_si.shape == () and shape == (1,) else value_si
                if value_si.shape != shape:
                    raise ModelError(f"{self.path}.{body}.initial.{key}: expected shape {shape}, given "
                                     f"{value_si.shape}")
                if key == "attitude" and abs(np.linalg.norm(value_si) - 1.0) > 1e-9:
                    raise ModelError(f"{self.path}.{body}.initial.attitude: expected a unit quaternion [w, x, y, z], "
                                     f"given norm {np.linalg.norm(value_si):.12g}")
                (q if target == "q" else u)[sl] = value_si
            system.normalize_quaternions(q)
            if self.assembly is not None:  # onto the closure constraints, as the scene built with these values
                try:
                    q, u, _ = self.constrained.on(system).assemble(q, u, self.assembly.tolerance)
                except ModelDefinitionError as exc:
                    changed = ", ".join(f"{body}.initial.{key}" for body, key, _ in initial)
                    raise ModelError(f"{self.path}: the initial state with {changed} cannot be assembled: "
                                     f"{exc}") from None
            x[:system.nq] = q
            x[system.nq:] = u

    def output_read(self, name: str, in_derivatives: bool = False) -> bool:
        """A node's kinematics are computed only for the nodes whose outputs something reads ("model no more than a
        scene needs"): a connection (a model attached to the node), a logged signal, a linearization's output, a
        name read (:meth:`shell.diagram.Diagram.note_read`). Marks the node of output ``name`` read (in
        ``ports.node_read``, which every run's data share: a mask in the data, one compiled kernel for every scene)
        and, ``in_derivatives``, read by derivative evaluations too (``ports.node_read_in_derivatives``); True when it
        was not read until now. The outputs of a node nothing reads are NaN, never a stale value; so are, within a
        derivative evaluation, those of a node only samples, logs and names read."""
        node, _, signal = name.rpartition(".")
        index = self._node_index.get(node)
        if index is None or signal not in NODE_OUTPUTS:
            return False
        if in_derivatives:
            self.ports.node_read_in_derivatives[index] = 1
        if self.ports.node_read[index]:
            return False
        self.ports.node_read[index] = 1
        return True

    @property
    def nodes_read_in_derivatives(self) -> tuple:
        """The names of the nodes whose kinematics derivative evaluations compute (:meth:`output_read`)."""
        return tuple(n for n, r in zip(self.system.node_names, self.ports.node_read_in_derivatives) if r)

    @property
    def nodes_read(self) -> tuple:
        """The names of the nodes whose kinematics the engine model computes (:meth:`output_read`)."""
        return tuple(n for n, r in zip(self.system.node_names, self.ports.node_read) if r)

    def missing_port_hint(self, name: str) -> str:
        """The optional outputs are ports only when the scene asks for them: name the ``outputs:`` entry that would
        make ``name`` one."""
        body, _, leaf = name.rpartition(".")
        wanted = "hinge_load" if leaf == "hinge_load" and body in self.system.body_names else \
            "energy" if name == "energy" else None
        if wanted is None or wanted in self.optional_outputs:
            return ""
        return (f" ({wanted} is an optional output, computed only when asked for: add it to the section, "
                f"{self.name}: outputs: [{wanted}])")

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

    @property
    def compiled_kernel(self):
        """The op kernel serving every kernel below in the compiled loop (:mod:`shell.kernel_protocol`): the one for
        this model's system (:data:`ENGINE_KERNELS`, by :func:`dynamics.engine.path_of`; a copy of the system, as a
        run's own, takes the same path), or :func:`engine_kernel_constrained` for a scene with closure constraints."""
        if self.constrained is not None:
            return engine_kernel_constrained
        return ENGINE_KERNELS[self.engine_path]

    def state_outputs(self, t, x, z, u, p, d, y):
        self.compiled_kernel(STATE_OUTPUTS, t, x, z, u, p, d, y)

    def feedthrough_outputs(self, t, x, z, u, p, d, y):
        self.compiled_kernel(FEEDTHROUGH_OUTPUTS, t, x, z, u, p, d, y)

    def state_outputs_for_derivatives(self, t, x, z, u, p, d, y):
        self.compiled_kernel(STATE_OUTPUTS_FOR_DERIVATIVES, t, x, z, u, p, d, y)

    def feedthrough_outputs_for_derivatives(self, t, x, z, u, p, d, y):
        self.compiled_kernel(FEEDTHROUGH_OUTPUTS_FOR_DERIVATIVES, t, x, z, u, p, d, y)

    def derivatives(self, t, x, z, u, p, d, xdot):
        self.compiled_kernel(DERIVATIVES, t, x, z, u, p, d, xdot)

    def derivatives_after_feedthrough(self, t, x, z, u, p, d, xdot):
        self.compiled_kernel(DERIVATIVES_AFTER_FEEDTHROUGH, t, x, z, u, p, d, xdot)

    def normalize_state(self, x, d):
        """Renormalize hinge quaternions in place (the integrator's normalize hook)."""
        self.compiled_kernel(NORMALIZE, 0.0, x, x, x, x, d, x)

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


def _converted(value, unit, shape, name):
    try:
        return to_magnitude(value, unit, shape, name)
    except UnitError as exc:
        raise ModelError(str(exc)) from None
