"""The engine's one entry point for compiled callers: every array in one tuple, numba functions over it.

The shell's compiled loop (:mod:`shell.compiled_loop`) calls the engine from inside numba code, where
there is no Python object to call methods on. :func:`engine_data` packs what the kernels need into an
:class:`EngineData` named tuple of plain arrays; the ``@njit`` functions below take it as their first
argument and write their results into caller-owned arrays (no allocation, no Python):

* :func:`forward_dynamics` - accelerations ``u_dot`` of all DOFs (and the generalized forces) from
  ``q``, ``u``, hinge forces ``tau``, node forces and prescribed accelerations (the O(N) articulated-body
  algorithm of :mod:`dynamics.kernels`, or its dense solve when the system chose it);
* :func:`node_kinematics` - pose, spatial velocity and classical acceleration of every node;
* :func:`node_kinematics_after_dynamics` - the same right after :func:`forward_dynamics`, reusing its
  workspace;
* :func:`coordinate_rates` - ``q_dot(q, u)``;
* :func:`normalize_quaternions` - hinge quaternions back to unit norm in place.

A system of one rigid body on a free hinge (a rigid spacecraft bus with its nodes: the most common scene)
runs :mod:`dynamics.single_body` instead of the general recursion (same outputs to round-off, about 4x less
time). The functions above choose that path, the articulated-body recursion or the dense solve per call; each
path also has its own entry points (:data:`PATHS`, :func:`path_of`), so that a caller compiled for one system
contains only that path's code: the engine model compiles one kernel per path it meets, and a rigid-body scene
does not wait for the recursion's compilation (most of a cold start's time, issue 31).

Speed: the entry points are ``inline="always"`` (the engine model's kernel calls them with the data
tuple, which numba passes flattened, ~13 words an array: one call level cost 0.3-0.5 us), and
:func:`borrowed` lets compiled callers use the arrays without numba's atomic reference counting.

This interface (argument order, array shapes, the meaning of every field) is what the shell depends on;
the algorithms underneath may change freely. ``MultibodySystem`` keeps the same arrays, so Python callers
(``system.forward_dynamics(...)``) and compiled callers compute the same numbers.

Ownership: the description arrays (topology, joint frames, node tables) are the immutable model's
(:class:`dynamics.model.Model`) and never change. ``params`` and the workspace are the data's
(:class:`dynamics.data.Data`): the rigid inertias in ``params`` may change during a run
(:func:`dynamics.algorithms.set_mass_properties`, mass depletion; written in place, which is why
:func:`engine_data` gives the data its own copy of them) and the workspace is scratch, so an
:class:`EngineData` serves one simulation at a time: :func:`engine_data` of ``model`` and another
``model.create_data()`` (or of ``system.copy()``) gives an independent one.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from llvmlite import ir
from numba import njit, types
from numba.extending import intrinsic

from dynamics import kernels as K
from dynamics import single_body as SB


def strip_references(context, builder, typ, value):
    """``value`` of numba type ``typ`` with every array's (and numpy Generator's) meminfo and parent set to null: see
    :func:`borrowed`."""
    if isinstance(typ, (types.Array, types.NumPyRandomGeneratorType)):
        model = context.data_model_manager[typ]
        for field in ("meminfo", "parent"):
            index = model.get_field_position(field)
            value = builder.insert_value(value, ir.Constant(value.type.elements[index], None), index)
        return value
    if isinstance(typ, types.BaseTuple):
        for index, member in enumerate(typ.types):
            if isinstance(member, (types.Array, types.BaseTuple)):
                stripped = strip_references(context, builder, member, builder.extract_value(value, index))
                value = builder.insert_value(value, stripped, index)
    return value


@intrinsic
def borrowed(typingctx, value):
    """``value`` (an array, or a tuple / named tuple of arrays, nested) as *borrowed* references: the
    same arrays with their meminfo set to null, so numba's reference counting of them (an atomic
    increment and decrement each time one is passed to or taken from a function, ~32 arrays per engine
    call) becomes a null test. Valid only while the owner keeps the arrays alive: the engine's arrays
    belong to the simulation's context, which outlives every compiled call on them. Measured on the
    reaction-wheel scene: see ``shell.models.multibody.ENGINE_KERNELS``."""
    if not isinstance(value, (types.Array, types.BaseTuple)):
        return None

    def codegen(context, builder, sig, args):
        return strip_references(context, builder, sig.args[0], args[0])

    return value(value), codegen


class EngineData(NamedTuple):
    """Arrays of a compiled multibody system and its workspace (see the module docstring)."""

    dense: bool                   # the forward-dynamics solver: False articulated-body, True dense
    # the model's description (immutable), but params: the data's (its rigid inertias change with mass depletion)
    topology: np.ndarray          # (nb, TOPOLOGY_COLUMNS) int64, dynamics.kernels column constants
    nodes: np.ndarray             # (nnodes, NODE_COLUMNS) int64
    joint_rot: np.ndarray         # (nb, 2, 3, 3) inboard / outboard frame rotations
    joint_vec: np.ndarray         # (nb, 4, 3) inboard / outboard positions, hinge axes
    params: np.ndarray            # (m,) ground acceleration, inertias, modal data, node frames and shapes
    quaternion_q: np.ndarray      # (k,) int64: position in q of each hinge quaternion's w
    # the data's workspace
    ws_rot: np.ndarray
    ws_vec: np.ndarray
    ws_mat: np.ndarray
    pool: np.ndarray
    zero_body_forces: np.ndarray  # (nb, 6) zeros


def engine_data(model, data=None) -> EngineData:
    """The :class:`EngineData` of a :class:`dynamics.model.Model` and one of its :class:`dynamics.data.Data` (or of a
    ``dynamics.MultibodySystem``: its model and data), sharing their arrays: the model's description, the data's
    workspace and mass properties. The data gets its own copy of the mass properties first
    (:meth:`dynamics.data.Data.own_mass_properties`): a compiled caller holds these arrays for a whole run, so a
    later change (mass depletion) must write into the array it holds rather than replace it."""
    if data is None:
        model, data = model.model, model.data
    elif data.model is not model:
        raise ValueError(f"{data!r} is not a data of {model!r}: use model.create_data()")
    data.own_mass_properties()
    return EngineData(
        model.solver == "dense", model.topology, model.nodes, model.joint_rot, model.joint_vec, data.params,
        np.array(model.quaternion_q_indices, dtype=np.int64), data.ws_rot, data.ws_vec, data.ws_mat, data.pool,
        np.zeros((model.nbodies, 6)))


# -- the paths: a compiled caller that knows its system's path (:func:`path_of`) calls that path's functions and
# contains only its code; the functions without a suffix choose the path per call and contain all three.

@njit(cache=True, inline="always")
def forward_dynamics_single_body(d, q, u, tau, node_forces, udot, tau_out):
    """:func:`forward_dynamics` of a system whose path is ``"single_body"``."""
    return SB.forward_dynamics(d.topology, d.nodes, d.joint_rot, d.joint_vec, d.params, q, u, tau, node_forces,
                               d.zero_body_forces, udot, tau_out, d.ws_rot, d.ws_vec, d.ws_mat)


@njit(cache=True, inline="always")
def forward_dynamics_dense(d, q, u, tau, node_forces, udot, tau_out):
    """:func:`forward_dynamics` of a system whose path is ``"dense"``."""
    return K.forward_dynamics_dense(d.topology, d.nodes, d.joint_rot, d.joint_vec, d.params, q, u, tau, node_forces,
                                    d.zero_body_forces, udot, tau_out, d.ws_rot, d.ws_vec, d.ws_mat, d.pool)


@njit(cache=True, inline="always")
def forward_dynamics_articulated(d, q, u, tau, node_forces, udot, tau_out):
    """:func:`forward_dynamics` of a system whose path is ``"articulated"``."""
    return K.forward_dynamics(d.topology, d.nodes, d.joint_rot, d.joint_vec, d.params, q, u, tau, node_forces,
                              d.zero_body_forces, udot, tau_out, d.ws_rot, d.ws_vec, d.ws_mat, d.pool)


@njit(cache=True, inline="always")
def node_kinematics_single_body(d, q, u, udot, rotation, position, velocity, acceleration):
    """:func:`node_kinematics` of a system whose path is ``"single_body"``."""
    SB.node_kinematics(d.topology, d.nodes, d.joint_rot, d.joint_vec, d.params, q, u, udot, rotation, position,
                       velocity, acceleration, d.ws_rot, d.ws_vec)


@njit(cache=True, inline="always")
def node_kinematics_tree(d, q, u, udot, rotation, position, velocity, acceleration):
    """:func:`node_kinematics` of a system whose path is ``"articulated"`` or ``"dense"``."""
    K.node_kinematics(d.topology, d.nodes, d.joint_rot, d.joint_vec, d.params, q, u, udot, rotation, position,
                      velocity, acceleration, d.ws_rot, d.ws_vec, d.ws_mat, d.pool)


@njit(cache=True, inline="always")
def node_kinematics_after_dynamics_single_body(d, q, u, udot, rotation, position, velocity, acceleration):
    """:func:`node_kinematics_after_dynamics` of a system whose path is ``"single_body"``."""
    SB.node_kinematics_after_dynamics(d.nodes, d.params, rotation, position, velocity, acceleration, d.ws_rot,
                                      d.ws_vec)


@njit(cache=True, inline="always")
def node_kinematics_after_dynamics_tree(d, q, u, udot, rotation, position, velocity, acceleration):
    """:func:`node_kinematics_after_dynamics` of a system whose path is ``"articulated"`` or ``"dense"``."""
    K.node_kinematics_after_dynamics(d.topology, d.nodes, d.joint_rot, d.joint_vec, d.params, q, u, udot, rotation,
                                     position, velocity, acceleration, d.ws_rot, d.ws_vec, d.ws_mat, d.pool)


class EnginePath(NamedTuple):
    """The entry points of one path (same arguments and results as the functions without a suffix)."""

    name: str
    forward_dynamics: object
    node_kinematics: object
    node_kinematics_after_dynamics: object


#: path name -> its entry points
PATHS = {
    "single_body": EnginePath("single_body", forward_dynamics_single_body, node_kinematics_single_body,
                              node_kinematics_after_dynamics_single_body),
    "articulated": EnginePath("articulated", forward_dynamics_articulated, node_kinematics_tree,
                              node_kinematics_after_dynamics_tree),
    "dense": EnginePath("dense", forward_dynamics_dense, node_kinematics_tree, node_kinematics_after_dynamics_tree),
}


def path_of(system) -> str:
    """The path a compiled caller of ``system`` takes: ``"single_body"`` (one rigid body on a free hinge,
    :func:`dynamics.single_body.applies`), else the solver the system chose (``"articulated"`` or ``"dense"``).
    Fixed for the system's life: its topology and solver do not change after ``Multibody.compile``."""
    if SB.applies(system.topology):
        return "single_body"
    return "dense" if system.solver == "dense" else "articulated"


@njit(cache=True, inline="always")
def forward_dynamics(d, q, u, tau, node_forces, udot, tau_out):
    """Accelerations of all DOFs into ``udot`` (which holds the prescribed accelerations on entry) and the
    generalized forces into ``tau_out`` (``tau`` at free DOFs, the force realizing the prescribed motion
    at prescribed DOFs). ``node_forces`` (nnodes, 6): ``[torque; force]`` per node, node axes, about the
    node origin. Returns 0, or 1 + the index of a body whose articulated inertia is singular."""
    if SB.applies(d.topology):
        return forward_dynamics_single_body(d, q, u, tau, node_forces, udot, tau_out)
    if d.dense:
        return forward_dynamics_dense(d, q, u, tau, node_forces, udot, tau_out)
    return forward_dynamics_articulated(d, q, u, tau, node_forces, udot, tau_out)


@njit(cache=True, inline="always")
def node_kinematics(d, q, u, udot, rotation, position, velocity, acceleration):
    """Per node: ``rotation`` (nnodes, 3, 3) node -> world, ``position`` (nnodes, 3) world,
    ``velocity`` (nnodes, 6) ``[omega; v]`` and ``acceleration`` (nnodes, 6) ``[omega_dot; a]`` (classical
    acceleration of the node origin, gravity not included), node axes; elastic motion included."""
    if SB.applies(d.topology):
        node_kinematics_single_body(d, q, u, udot, rotation, position, velocity, acceleration)
        return
    node_kinematics_tree(d, q, u, udot, rotation, position, velocity, acceleration)


@njit(cache=True, inline="always")
def node_kinematics_after_dynamics(d, q, u, udot, rotation, position, velocity, acceleration):
    """:func:`node_kinematics` (same outputs) for the ``udot`` that :func:`forward_dynamics` just returned
    at the same ``q``, ``u`` with the same ``d``: it reuses the poses, velocities and accelerations left in
    the workspace, so it costs O(N + nnodes n) instead of a kinematics pass and the modal mass terms.
    Precondition (not checked): no other engine function ran on ``d`` in between."""
    if SB.applies(d.topology):
        node_kinematics_after_dynamics_single_body(d, q, u, udot, rotation, position, velocity, acceleration)
        return
    node_kinematics_after_dynamics_tree(d, q, u, udot, rotation, position, velocity, acceleration)


@njit(cache=True, inline="always")
def coordinate_rates(d, q, u, qdot):
    """``qdot = f(q, u)`` (quaternion kinematics for spherical and free hinges, identity elsewhere)."""
    K.coordinate_rates(d.topology, q, u, qdot)


@njit(cache=True, inline="always")
def normalize_quaternions(d, q):
    """Divide every hinge quaternion of ``q`` by its norm, in place (a sequential sum of squares, the
    same arithmetic in the interpreted and the compiled loop)."""
    for k in d.quaternion_q:
        norm = np.sqrt(q[k] * q[k] + q[k + 1] * q[k + 1] + q[k + 2] * q[k + 2] + q[k + 3] * q[k + 3])
        for j in range(4):
            q[k + j] /= norm
