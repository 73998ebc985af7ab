"""The engine's one entry point for compiled callers: every array in one tuple, numba functions over it.

The shell's compiled loop (``shell.codegen``) calls the engine from inside generated numba code, where
there is no Python object to call methods on. :func:`engine_data` packs what the kernels need into an
:class:`EngineData` named tuple of plain arrays; the ``@njit`` functions below take it as their first
argument and write their results into caller-owned arrays (no allocation, no Python):

* :func:`forward_dynamics` - accelerations ``u_dot`` of all DOFs (and the generalized forces) from
  ``q``, ``u``, hinge forces ``tau``, node forces and prescribed accelerations (O(N) articulated-body
  algorithm, :mod:`dynamics.kernels` / :mod:`dynamics.flexible_kernels`);
* :func:`node_kinematics` - pose, spatial velocity and classical acceleration of every node;
* :func:`coordinate_rates` - ``q_dot(q, u)``;
* :func:`normalize_quaternions` - hinge quaternions back to unit norm in place.

This interface (argument order, array shapes, the meaning of every field) is what the shell depends on;
the algorithms underneath may change freely. ``MultibodySystem`` keeps the same arrays, so Python callers
(``system.forward_dynamics(...)``) and compiled callers compute the same numbers.

Ownership: the description arrays (topology, joint frames, node tables) never change after
``Multibody.compile``. The mass-property arrays (``spatial_inertia``, ``flex_data``) may change during a
run (``MultibodySystem.set_mass_properties``, mass depletion) and the workspace is scratch, so an
:class:`EngineData` serves one simulation at a time: :func:`engine_data` of ``system.copy()`` gives an
independent one.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit

from dynamics import flexible_kernels as FK
from dynamics import kernels as K


class EngineData(NamedTuple):
    """Arrays of a compiled multibody system and its workspace (see the module docstring)."""

    flexible: bool
    # description (immutable)
    topology: np.ndarray          # (nb, TOPOLOGY_COLUMNS) int64, dynamics.kernels column constants
    hinge_dofs: np.ndarray        # (nb, 2, 6) int64: free DOF indices, prescribed DOF indices per hinge
    joint_rot: np.ndarray         # (nb, 2, 3, 3) inboard / outboard frame rotations
    joint_vec: np.ndarray         # (nb, 4, 3) inboard / outboard positions, hinge axes
    ground_accel: np.ndarray      # (6,) [0; -g]
    node_body: np.ndarray         # (nnodes,) int64
    node_rot: np.ndarray          # (nnodes, 3, 3) node -> body
    node_pos: np.ndarray          # (nnodes, 3) node origin in the body frame
    quaternion_q: np.ndarray      # (k,) int64: position in q of each hinge quaternion's w
    # mass properties (may change during a run)
    spatial_inertia: np.ndarray   # (nb, 6, 6) about the body origin, body axes
    flex_index: np.ndarray        # (nb, N_FX) int64 offsets into flex_data (zeros for rigid systems)
    flex_data: np.ndarray         # (m,) packed M0, M1, M2, K, C of flexible bodies
    node_shape: np.ndarray        # (nnodes, 6, nmax) mode shapes [lambda; gamma] at nodes
    # workspace
    ws_rot: np.ndarray
    ws_vec: np.ndarray
    ws_mat: np.ndarray
    fw_psi: np.ndarray
    fw_vec: np.ndarray
    fw_mat: np.ndarray
    fw_tmp: np.ndarray
    fw_scratch: np.ndarray
    body_forces: np.ndarray       # (nb, 6) scratch: node forces summed per body (rigid path)
    zero_body_forces: np.ndarray  # (nb, 6) zeros


def engine_data(system) -> EngineData:
    """The :class:`EngineData` of ``system``, sharing its arrays (mass properties and workspace too)."""
    nb, nn = system.nbodies, system.nnodes
    if system.is_flexible:
        flex = (system.flex_index, system.flex_data, system.node_shape, system.fw_psi, system.fw_vec,
                system.fw_mat, system.fw_tmp, system.fw_scratch)
    else:  # placeholders of the same types (read-only like a flexible system's), so both kinds share code
        flex = (_readonly(np.zeros((nb, FK.N_FX), dtype=np.int64)), _readonly(np.zeros(1)),
                _readonly(np.zeros((nn, 6, 1))), np.zeros((1, 1, 1)), np.zeros((1, 1, 1)), np.zeros((1, 1, 1, 1)),
                np.zeros((8, 3)), np.zeros((4, 6, 6)))
    flex_index, flex_data, node_shape, psi, fv, fm, tmp, scratch = flex
    return EngineData(
        bool(system.is_flexible), system.topology, system.hinge_dofs, system.joint_rot, system.joint_vec,
        system.ground_accel, system.node_body, system.node_rot.reshape(nn, 3, 3), system.node_pos.reshape(nn, 3),
        np.ascontiguousarray(system.quaternion_q_indices, dtype=np.int64), system.spatial_inertia, flex_index,
        flex_data, node_shape, system.ws_rot, system.ws_vec, system.ws_mat, psi, fv, fm, tmp, scratch,
        np.zeros((nb, 6)), np.zeros((nb, 6)))


def _readonly(a):
    a.setflags(write=False)
    return a


@njit(cache=True)
def forward_dynamics(d, q, u, tau, node_forces, udot, tau_out):
    """Accelerations of all DOFs into ``udot`` (which holds the prescribed accelerations on entry) and the
    generalized forces into ``tau_out`` (``tau`` at free DOFs, the force realizing the prescribed motion
    at prescribed DOFs). ``node_forces`` (nnodes, 6): ``[torque; force]`` per node, node axes, about the
    node origin. Returns 0, or 1 + the index of a body whose articulated inertia is singular."""
    if d.flexible:
        return FK.flex_forward_dynamics(d.topology, d.hinge_dofs, d.joint_rot, d.joint_vec, d.flex_index,
                                        d.flex_data, d.node_body, d.node_shape, d.node_rot, d.node_pos,
                                        d.ground_accel, q, u, tau, node_forces, d.zero_body_forces, udot,
                                        tau_out, d.ws_rot, d.ws_vec, d.ws_mat, d.fw_psi, d.fw_vec, d.fw_mat,
                                        d.fw_tmp, d.fw_scratch)
    K.node_forces_to_bodies(d.node_body, d.node_rot, d.node_pos, node_forces, d.body_forces)
    return K.forward_dynamics(d.topology, d.hinge_dofs, d.joint_rot, d.joint_vec, d.spatial_inertia,
                              d.ground_accel, q, u, tau, d.body_forces, udot, tau_out, d.ws_rot, d.ws_vec,
                              d.ws_mat)


@njit(cache=True)
def node_kinematics(d, q, u, udot, rotation, position, velocity, acceleration):
    """Per node: ``rotation`` (nnodes, 3, 3) node -> world, ``position`` (nnodes, 3) world,
    ``velocity`` (nnodes, 6) ``[omega; v]`` and ``acceleration`` (nnodes, 6) ``[omega_dot; a]`` (classical
    acceleration of the node origin, gravity not included), node axes; elastic motion included."""
    if d.flexible:
        FK.flex_node_kinematics(d.topology, d.joint_rot, d.joint_vec, d.flex_index, d.flex_data, d.node_body,
                                d.node_shape, d.node_rot, d.node_pos, q, u, udot, rotation, position, velocity,
                                acceleration, d.ws_rot, d.ws_vec, d.ws_mat, d.fw_psi, d.fw_vec, d.fw_mat,
                                d.fw_tmp, d.fw_scratch)
    else:
        K.node_kinematics(d.topology, d.joint_rot, d.joint_vec, d.node_body, d.node_rot, d.node_pos, q, u, udot,
                          rotation, position, velocity, acceleration, d.ws_rot, d.ws_vec, d.ws_mat)


@njit(cache=True)
def coordinate_rates(d, q, u, qdot):
    """``qdot = f(q, u)`` (quaternion kinematics for spherical and free hinges, identity elsewhere)."""
    K.coordinate_rates(d.topology, q, u, qdot)


@njit(cache=True)
def normalize_quaternions(d, q):
    """Divide every hinge quaternion of ``q`` by its norm, in place (a sequential sum of squares, the
    same arithmetic in the interpreted and the compiled loop)."""
    for k in d.quaternion_q:
        norm = np.sqrt(q[k] * q[k] + q[k + 1] * q[k + 1] + q[k + 2] * q[k + 2] + q[k + 3] * q[k + 3])
        for j in range(4):
            q[k + j] /= norm
