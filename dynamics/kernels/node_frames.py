"""Node kinematics: pose, spatial velocity and classical acceleration of frames on (deforming) bodies,
after a kinematics pass or reusing the workspace of a forward-dynamics call; of every node, or (the ``_selected``
variants, a mask array in the caller's data) of the nodes a scene reads; and (:func:`node_velocities_selected`) the
poses and velocities alone of the nodes a mask selects, from the kinematics of only the bodies they ride on and their
ancestors (a model's outputs that need no accelerations).

A flexible body's node costs O(n) sums over its shape (:func:`dynamics.flexible_kernels.node_motion`: the pose from
``lambda eta``, ``gamma eta``, the velocity from ``lambda eta_dot``, ``gamma eta_dot``, the acceleration's
``Psi eta_ddot`` from ``lambda eta_ddot``, ``gamma eta_ddot``), never the 6 x n ``Psi`` itself.
"""

from __future__ import annotations

from numba import njit

from dynamics import flexible_kernels as FK
from dynamics.kernels.kinematics import (
    accumulate_world_poses, add_hinge_acceleration, body_kinematics, body_motion, parent_acceleration, world_pose)
from dynamics.layout import (
    GROUND_ACCEL, NODE_BODY, NODE_FRAME, NODE_SHAPE, NQ_HINGE, NU_HINGE, N_MODES, PARENT, POOL_HEADER, P_L, P_R,
    P_TMP83, P_V1, P_V2, P_W, P_WD, P_ZERO, Q_START, ROT_WB, U_START, VEC_A, VEC_V, VEC_WPOS, view)
from dynamics.spatial import motion_cross_motion_add, motion_to_child


@njit(cache=True)
def _node_outputs(topology, nodes, params, q, u, udot, ground_linear, rotation, position, velocity, acceleration,
                  ws_rot, ws_vec, pool, active, with_acceleration):
    """Per node, from the bodies' world poses, velocities and (``with_acceleration``) accelerations in the
    workspace (minus the uniform ``ground_linear`` acceleration they may include): pose, velocity and classical
    acceleration of the (deformed) node (see :func:`node_kinematics`); with a non-empty ``active`` (nnodes,) only
    the nodes with ``active[n] != 0`` (the rows of the others are left as they are); without
    ``with_acceleration`` the ``acceleration`` rows are left as they are."""
    tmp83 = view(pool, P_TMP83, 8, 3)
    w = pool[P_W:P_W + 6]
    wd = pool[P_WD:P_WD + 6]
    tmp = pool[P_V1:P_V1 + 6]
    Xw = pool[P_V2:P_V2 + 6]
    psi_acc = pool[POOL_HEADER:POOL_HEADER + 6]  # the header's scratch of one node's Psi (6 x nmax)
    selected = active.shape[0] > 0
    for nd in range(nodes.shape[0]):
        if selected and active[nd] == 0:
            continue
        b = nodes[nd, NODE_BODY]
        n = topology[b, N_MODES]
        fr = nodes[nd, NODE_FRAME]
        if n > 0:
            qe = topology[b, Q_START] + topology[b, NQ_HINGE]
            ue = topology[b, U_START] + topology[b, NU_HINGE]
            Rn = view(pool, P_R, 3, 3)
            l = pool[P_L:P_L + 3]
            FK.node_motion(view(params, nodes[nd, NODE_SHAPE], 6, n), params[fr + 9:fr + 12], view(params, fr, 3, 3),
                           q[qe:qe + n], n, u[ue:ue + n], udot[ue:ue + (n if with_acceleration else 0)], Rn, l, w, wd,
                           psi_acc, tmp83)
        else:
            Rn = view(params, fr, 3, 3)
            l = params[fr + 9:fr + 12]
        R_WB = ws_rot[b, ROT_WB]
        pw = ws_vec[b, VEC_WPOS]
        for a in range(3):
            position[nd, a] = pw[a] + R_WB[a, 0] * l[0] + R_WB[a, 1] * l[1] + R_WB[a, 2] * l[2]
            for k in range(3):
                rotation[nd, a, k] = R_WB[a, 0] * Rn[0, k] + R_WB[a, 1] * Rn[1, k] + R_WB[a, 2] * Rn[2, k]
        V = ws_vec[b, VEC_V]
        if n > 0:
            for a in range(6):
                tmp[a] = V[a] + w[a]
            motion_to_child(Rn, l, tmp, velocity[nd])
        else:
            motion_to_child(Rn, l, V, velocity[nd])
        if not with_acceleration:
            continue
        A = ws_vec[b, VEC_A]
        for a in range(3):
            tmp[a] = A[a]
            tmp[3 + a] = A[3 + a] - (R_WB[0, a] * ground_linear[0] + R_WB[1, a] * ground_linear[1]
                                     + R_WB[2, a] * ground_linear[2])
        if n > 0:
            for a in range(6):
                tmp[a] += psi_acc[a] + wd[a]
            motion_to_child(Rn, l, tmp, acceleration[nd])
            motion_to_child(Rn, l, w, Xw)
            motion_cross_motion_add(velocity[nd], Xw, acceleration[nd])
        else:
            motion_to_child(Rn, l, tmp, acceleration[nd])
        v = velocity[nd]
        acc = acceleration[nd]
        acc[3] += v[1] * v[5] - v[2] * v[4]
        acc[4] += v[2] * v[3] - v[0] * v[5]
        acc[5] += v[0] * v[4] - v[1] * v[3]


@njit(cache=True)
def node_kinematics(topology, nodes, joint_rot, joint_vec, params, q, u, udot, rotation, position, velocity,
                    acceleration, ws_rot, ws_vec, ws_mat, pool):
    """:func:`node_kinematics_selected` of every node."""
    node_kinematics_selected(topology, nodes, joint_rot, joint_vec, params, q, u, udot, rotation, position, velocity,
                             acceleration, ws_rot, ws_vec, ws_mat, pool, nodes[0:0, 0])


@njit(cache=True)
def node_kinematics_selected(topology, nodes, joint_rot, joint_vec, params, q, u, udot, rotation, position, velocity,
                             acceleration, ws_rot, ws_vec, ws_mat, pool, active):
    """Pose, spatial velocity and acceleration of every node (a frame on a body, deforming with it).

    Outputs per node n: ``rotation[n]`` node -> world, ``position[n]`` in the world, ``velocity[n]`` the
    spatial velocity ``[omega; v]`` of the node frame in node axes (v: velocity of the node origin), and
    ``acceleration[n] = [omega_dot; a]`` in node axes with ``a`` the classical (not spatial) acceleration
    of the node origin, ``a = a_spatial + omega x v``. Accelerations are relative to the inertial frame:
    gravity is *not* included (an accelerometer reads ``a - g``).

    ``active`` (nnodes,) int64: only the nodes with ``active[n] != 0`` are computed (a scene's model computes the
    nodes whose outputs something reads; the rows of the others are left unchanged); empty: every node. The
    bodies' kinematics pass is done in full either way (a node's pose needs its body's).
    """
    nb = topology.shape[0]
    zero = pool[P_ZERO:P_ZERO + 6]
    for a in range(6):
        zero[a] = 0.0
    for i in range(nb):
        body_kinematics(i, topology, nodes, joint_rot, joint_vec, params, q, u, ws_rot, ws_vec, ws_mat, pool, True)
        A = ws_vec[i, VEC_A]
        parent_acceleration(i, topology, nodes, zero, udot, ws_rot, ws_vec, pool, A)
        add_hinge_acceleration(i, topology, nodes, udot, ws_vec, ws_mat, pool, A)
    accumulate_world_poses(topology, ws_rot, ws_vec)
    _node_outputs(topology, nodes, params, q, u, udot, zero[0:3], rotation, position, velocity, acceleration,
                  ws_rot, ws_vec, pool, active, True)


@njit(cache=True)
def node_kinematics_after_dynamics(topology, nodes, joint_rot, joint_vec, params, q, u, udot, rotation, position,
                                   velocity, acceleration, ws_rot, ws_vec, ws_mat, pool):
    """:func:`node_kinematics_after_dynamics_selected` of every node."""
    node_kinematics_after_dynamics_selected(topology, nodes, joint_rot, joint_vec, params, q, u, udot, rotation,
                                            position, velocity, acceleration, ws_rot, ws_vec, ws_mat, pool,
                                            nodes[0:0, 0])


@njit(cache=True)
def node_kinematics_after_dynamics_selected(topology, nodes, joint_rot, joint_vec, params, q, u, udot, rotation,
                                            position, velocity, acceleration, ws_rot, ws_vec, ws_mat, pool, active):
    """:func:`node_kinematics_selected` reusing the workspace of a :func:`forward_dynamics` (or
    :func:`forward_dynamics_dense`) call at the same ``q``, ``u`` that returned ``udot``: only the world
    poses and the per-node terms are computed (O(N + nodes x n)), and the ground's fictitious acceleration
    ``[0; -g]`` contained in the forward-dynamics accelerations is removed. Precondition (not checked):
    no other kernel used the workspace in between."""
    accumulate_world_poses(topology, ws_rot, ws_vec)
    _node_outputs(topology, nodes, params, q, u, udot, params[GROUND_ACCEL + 3:GROUND_ACCEL + 6], rotation, position,
                  velocity, acceleration, ws_rot, ws_vec, pool, active, True)


@njit(cache=True)
def bodies_of_nodes(topology, nodes, active, bodies):
    """``bodies[i] = 1`` for every body that a node with ``active[n] != 0`` rides on and every ancestor of those
    (what their poses and velocities need), 0 for the others; an empty ``active``: every body. O(bodies + nodes)."""
    nb = topology.shape[0]
    if active.shape[0] == 0:
        for i in range(nb):
            bodies[i] = 1
        return
    for i in range(nb):
        bodies[i] = 0
    for nd in range(nodes.shape[0]):
        if active[nd] == 0:
            continue
        b = nodes[nd, NODE_BODY]
        while b >= 0 and bodies[b] == 0:
            bodies[b] = 1
            b = topology[b, PARENT]


@njit(cache=True)
def node_velocities_selected(topology, nodes, joint_rot, joint_vec, params, q, u, rotation, position, velocity,
                             ws_rot, ws_vec, ws_mat, pool, active, bodies):
    """:func:`node_kinematics_selected` without accelerations (``rotation``, ``position``, ``velocity`` of the nodes
    with ``active[n] != 0``, every node for an empty ``active``; the other rows and every acceleration are left as
    they are), computing the kinematics of only the bodies those nodes need: ``bodies`` (nb,) int64 scratch receives
    them (:func:`bodies_of_nodes`), and each of them gets its pose and velocity (:func:`body_motion`: a deforming
    parent node's pose and relative velocity without its ``Psi``). The workspace's other bodies, accelerations and
    slot ``Psi`` are left as they are (stale: a forward dynamics or a full kinematics pass computes them again)."""
    bodies_of_nodes(topology, nodes, active, bodies)
    for i in range(topology.shape[0]):
        if bodies[i] == 0:
            continue
        body_motion(i, topology, nodes, joint_rot, joint_vec, params, q, u, ws_rot, ws_vec, ws_mat, pool, bodies)
        world_pose(i, topology, ws_rot, ws_vec)
    _node_outputs(topology, nodes, params, q, u, u[0:0], params[GROUND_ACCEL + 3:GROUND_ACCEL + 6], rotation, position,
                  velocity, velocity, ws_rot, ws_vec, pool, active, False)
