"""The engine's fast path for the most common spacecraft scene: one rigid body on a free hinge.

A rigid spacecraft bus with wheels, thrusters and sensors attached to its nodes is, for the engine, a
single rigid body on a free (6-DOF) hinge to the world. The general recursion of :mod:`dynamics.kernels`
handles it correctly, but through the machinery of trees (motion subspaces, articulated inertias, the
hinge elimination, per-body workspace views), which costs microseconds per call where the physics is a
6 x 6 solve. :func:`dynamics.engine.forward_dynamics`, :func:`~dynamics.engine.node_kinematics` and
:func:`~dynamics.engine.node_kinematics_after_dynamics` call the functions below instead when
:func:`applies` holds (checked per call on the integer topology, so a reconfigured system never takes a
stale path); everything else (trees, flexible bodies, prescribed DOFs, frames on the body's outboard side)
takes the general path.

Equations (the free hinge's conventions, :mod:`dynamics.hinges`): ``q = [q_w, q_x, q_y, q_z, p]`` with the
quaternion body -> world (outboard frame = body frame) and ``p`` the body origin in the hinge's inboard
frame; ``u = V = [omega; v]``, the body's spatial velocity in body axes (the motion subspace is the
identity). With the constant spatial inertia about the body origin ``I = [[J, m c~], [-m c~, m 1]]``
(body axes, :class:`dynamics.system.MultibodySystem`'s params), Newton-Euler in body axes reads
(Featherstone, RBDA 2008, eqs. 2.72 and 7.1-7.4 for a single body):

    I a + V x* (I V) = f,   f = tau + sum_nodes X_n^T f_n,   a = udot + X_0 a_ground

so ``udot = I^-1 (tau - p) - X_0 a_ground`` with the bias ``p = V x* (I V) - sum_nodes X_n^T f_n`` and
``a_ground = [0; -g]`` (gravity as an upward acceleration of the ground, RBDA sec. 5.3). ``I`` is
factored per call (a 6 x 6 Cholesky: mass properties may change during a run).

The velocity-product bias is :func:`dynamics.kernels.body_terms.rigid_bias_add`, shared with the general path's rigid
bodies: it leaves out ``v x (m v)``, zero in exact arithmetic but, in floating point, a torque of order
``eps m |v|^2`` on a body that carries its orbital velocity in body axes (1e-5 N m for 750 kg at 7 km/s).

Node kinematics are those of :func:`dynamics.kernels.node_kinematics` for a rigid body: a node with
constant frame ``(R_n, l_n)`` on the body has ``R_Wn = R_WB R_n``, ``p_n = p + R_WB l_n``, velocity
``X_n V`` and classical acceleration ``X_n a + [0; omega_n x v_n]``. On exit of :func:`forward_dynamics`
the workspace holds what the general path leaves there for later readers (pose, velocity, bias, bias
force, acceleration including the ground's), so :func:`node_kinematics_after_dynamics` can reuse it.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from dynamics.hinges import FREE
from dynamics.kernels.body_terms import rigid_bias_add
from dynamics.layout import (
    FLEXIBLE, GENERAL, GROUND_ACCEL, HINGE_TYPE, INBOARD, INERTIA, MAT_IA, NODE_FRAME, N_MODES, N_PRESCRIBED,
    OUTBOARD_IDENTITY, PARENT, Q_START, ROT_FM, ROT_PB, ROT_WB, U_START, VEC_A, VEC_C, VEC_D, VEC_P, VEC_POS, VEC_V,
    VEC_WPOS)
from dynamics.spatial import quaternion_to_rotation


@njit(cache=True, inline="always")
def applies(topology):
    """True when the system is one rigid body on a free hinge to the world with no prescribed DOF and
    its outboard frame equal to the body frame (the inboard frame may be anything)."""
    return (topology.shape[0] == 1 and topology[0, HINGE_TYPE] == FREE and topology[0, PARENT] < 0
            and topology[0, GENERAL] == 0 and topology[0, FLEXIBLE] == 0 and topology[0, N_MODES] == 0
            and topology[0, N_PRESCRIBED] == 0 and topology[0, OUTBOARD_IDENTITY] == 1)


@njit(cache=True, inline="always")
def _pose(topology, joint_rot, joint_vec, q, ws_rot, ws_vec):
    """Body pose into the workspace: ``R_WB = R_PF R(q)`` (``ROT_FM``, ``ROT_PB``, ``ROT_WB``),
    ``p = p_PF + R_PF p_FM`` (``VEC_POS``, ``VEC_WPOS``), as the general path's ``compose_body_pose``."""
    q0 = topology[0, Q_START]
    R_FM = ws_rot[0, ROT_FM]
    quaternion_to_rotation(q[q0], q[q0 + 1], q[q0 + 2], q[q0 + 3], R_FM)
    R_PF = joint_rot[0, INBOARD]
    p_PF = joint_vec[0, INBOARD]
    p0, p1, p2 = q[q0 + 4], q[q0 + 5], q[q0 + 6]
    for a in range(3):
        for b in range(3):
            r = R_PF[a, 0] * R_FM[0, b] + R_PF[a, 1] * R_FM[1, b] + R_PF[a, 2] * R_FM[2, b]
            ws_rot[0, ROT_PB, a, b] = r
            ws_rot[0, ROT_WB, a, b] = r
        s = p_PF[a] + R_PF[a, 0] * p0 + R_PF[a, 1] * p1 + R_PF[a, 2] * p2
        ws_vec[0, VEC_POS, a] = s
        ws_vec[0, VEC_WPOS, a] = s
        ws_vec[0, VEC_POS, 3 + a] = q[q0 + 4 + a]


@njit(cache=True)
def forward_dynamics(topology, nodes, joint_rot, joint_vec, params, q, u, tau, node_forces, body_forces, udot,
                     tau_out, ws_rot, ws_vec, ws_mat):
    """:func:`dynamics.kernels.forward_dynamics` for a system where :func:`applies` holds (same arguments
    but the pool, same outputs and return value: 0, or 1 when the spatial inertia is not positive definite)."""
    _pose(topology, joint_rot, joint_vec, q, ws_rot, ws_vec)
    u0 = topology[0, U_START]
    o = topology[0, INERTIA]
    # bias force p = V x* (I V) - body force (without v x (m v): kernels.rigid_bias_add)
    P = ws_vec[0, VEC_P]
    V = ws_vec[0, VEC_V]
    for a in range(6):
        V[a] = u[u0 + a]
        P[a] = -body_forces[0, a]
    rigid_bias_add(params, o, V, P)
    # node forces (node axes, at the node) moved to the body origin
    for nd in range(nodes.shape[0]):
        f = node_forces[nd]
        if f[0] == 0.0 and f[1] == 0.0 and f[2] == 0.0 and f[3] == 0.0 and f[4] == 0.0 and f[5] == 0.0:
            continue
        fr = nodes[nd, NODE_FRAME]
        # force_to_parent with R = params[fr:fr+9] (node -> body), r = params[fr+9:fr+12]
        f0 = params[fr + 0] * f[3] + params[fr + 1] * f[4] + params[fr + 2] * f[5]
        f1 = params[fr + 3] * f[3] + params[fr + 4] * f[4] + params[fr + 5] * f[5]
        f2 = params[fr + 6] * f[3] + params[fr + 7] * f[4] + params[fr + 8] * f[5]
        n0 = params[fr + 0] * f[0] + params[fr + 1] * f[1] + params[fr + 2] * f[2]
        n1 = params[fr + 3] * f[0] + params[fr + 4] * f[1] + params[fr + 5] * f[2]
        n2 = params[fr + 6] * f[0] + params[fr + 7] * f[1] + params[fr + 8] * f[2]
        r0, r1, r2 = params[fr + 9], params[fr + 10], params[fr + 11]
        P[0] -= n0 + r1 * f2 - r2 * f1
        P[1] -= n1 + r2 * f0 - r0 * f2
        P[2] -= n2 + r0 * f1 - r1 * f0
        P[3] -= f0
        P[4] -= f1
        P[5] -= f2
    # Cholesky I = L L^T (lower triangle into MAT_IA), then solve I x = tau - p
    L = ws_mat[0, MAT_IA]
    for j in range(6):
        s = params[o + 7 * j]
        for k in range(j):
            s -= L[j, k] * L[j, k]
        if not s > 0.0:
            for k in range(6):
                udot[u0 + k] = np.nan
            return 1
        d = np.sqrt(s)
        L[j, j] = d
        for i in range(j + 1, 6):
            s = params[o + 6 * i + j]
            for k in range(j):
                s -= L[i, k] * L[j, k]
            L[i, j] = s / d
    y = ws_vec[0, VEC_D]
    for i in range(6):
        s = tau[u0 + i] - P[i]
        for k in range(i):
            s -= L[i, k] * y[k]
        y[i] = s / L[i, i]
    for i in range(5, -1, -1):
        s = y[i]
        for k in range(i + 1, 6):
            s -= L[k, i] * y[k]
        y[i] = s / L[i, i]
    # ground acceleration in body axes, X_0 a_ground (motion_to_child with R_WB, p)
    R = ws_rot[0, ROT_WB]
    p = ws_vec[0, VEC_WPOS]
    ga0, ga1, ga2 = params[GROUND_ACCEL], params[GROUND_ACCEL + 1], params[GROUND_ACCEL + 2]
    gl0 = params[GROUND_ACCEL + 3] + ga1 * p[2] - ga2 * p[1]
    gl1 = params[GROUND_ACCEL + 4] + ga2 * p[0] - ga0 * p[2]
    gl2 = params[GROUND_ACCEL + 5] + ga0 * p[1] - ga1 * p[0]
    A = ws_vec[0, VEC_A]
    A[0] = R[0, 0] * ga0 + R[1, 0] * ga1 + R[2, 0] * ga2
    A[1] = R[0, 1] * ga0 + R[1, 1] * ga1 + R[2, 1] * ga2
    A[2] = R[0, 2] * ga0 + R[1, 2] * ga1 + R[2, 2] * ga2
    A[3] = R[0, 0] * gl0 + R[1, 0] * gl1 + R[2, 0] * gl2
    A[4] = R[0, 1] * gl0 + R[1, 1] * gl1 + R[2, 1] * gl2
    A[5] = R[0, 2] * gl0 + R[1, 2] * gl1 + R[2, 2] * gl2
    C = ws_vec[0, VEC_C]
    for a in range(6):
        udot[u0 + a] = y[a] - A[a]
        tau_out[u0 + a] = tau[u0 + a]
        A[a] = y[a]  # a = udot + X_0 a_ground
        C[a] = 0.0
    return 0


@njit(cache=True, inline="always")
def _node_outputs(nodes, params, ws_rot, ws_vec, gl0, gl1, gl2, rotation, position, velocity, acceleration):
    """Per node from the body's pose ``ws_rot[0, ROT_WB]``, ``ws_vec[0, VEC_WPOS]``, velocity ``VEC_V`` and
    acceleration ``VEC_A`` minus the uniform linear ground acceleration ``gl`` (world axes) it includes."""
    R = ws_rot[0, ROT_WB]
    p = ws_vec[0, VEC_WPOS]
    V = ws_vec[0, VEC_V]
    A = ws_vec[0, VEC_A]
    w0, w1, w2, v0, v1, v2 = V[0], V[1], V[2], V[3], V[4], V[5]
    b0, b1, b2 = A[0], A[1], A[2]
    a0 = A[3] - (R[0, 0] * gl0 + R[1, 0] * gl1 + R[2, 0] * gl2)
    a1 = A[4] - (R[0, 1] * gl0 + R[1, 1] * gl1 + R[2, 1] * gl2)
    a2 = A[5] - (R[0, 2] * gl0 + R[1, 2] * gl1 + R[2, 2] * gl2)
    for nd in range(nodes.shape[0]):
        fr = nodes[nd, NODE_FRAME]
        l0, l1, l2 = params[fr + 9], params[fr + 10], params[fr + 11]
        for a in range(3):
            position[nd, a] = p[a] + R[a, 0] * l0 + R[a, 1] * l1 + R[a, 2] * l2
            for k in range(3):
                rotation[nd, a, k] = R[a, 0] * params[fr + k] + R[a, 1] * params[fr + 3 + k] + R[a, 2] * params[fr + 6 + k]
        # X_n: omega_n = R_n^T omega, v_n = R_n^T (v + omega x l)
        u0 = v0 + w1 * l2 - w2 * l1
        u1 = v1 + w2 * l0 - w0 * l2
        u2 = v2 + w0 * l1 - w1 * l0
        c0 = a0 + b1 * l2 - b2 * l1
        c1 = a1 + b2 * l0 - b0 * l2
        c2 = a2 + b0 * l1 - b1 * l0
        for k in range(3):
            velocity[nd, k] = params[fr + k] * w0 + params[fr + 3 + k] * w1 + params[fr + 6 + k] * w2
            velocity[nd, 3 + k] = params[fr + k] * u0 + params[fr + 3 + k] * u1 + params[fr + 6 + k] * u2
            acceleration[nd, k] = params[fr + k] * b0 + params[fr + 3 + k] * b1 + params[fr + 6 + k] * b2
            acceleration[nd, 3 + k] = params[fr + k] * c0 + params[fr + 3 + k] * c1 + params[fr + 6 + k] * c2
        # classical acceleration of the node origin: a_spatial + omega_n x v_n
        acceleration[nd, 3] += velocity[nd, 1] * velocity[nd, 5] - velocity[nd, 2] * velocity[nd, 4]
        acceleration[nd, 4] += velocity[nd, 2] * velocity[nd, 3] - velocity[nd, 0] * velocity[nd, 5]
        acceleration[nd, 5] += velocity[nd, 0] * velocity[nd, 4] - velocity[nd, 1] * velocity[nd, 3]


@njit(cache=True)
def node_kinematics(topology, nodes, joint_rot, joint_vec, params, q, u, udot, rotation, position, velocity,
                    acceleration, ws_rot, ws_vec):
    """:func:`dynamics.kernels.node_kinematics` (same outputs, no gravity in the accelerations) where
    :func:`applies` holds: the body's acceleration is ``udot`` itself (no velocity-product bias)."""
    _pose(topology, joint_rot, joint_vec, q, ws_rot, ws_vec)
    u0 = topology[0, U_START]
    for a in range(6):
        ws_vec[0, VEC_V, a] = u[u0 + a]
        ws_vec[0, VEC_C, a] = 0.0
        ws_vec[0, VEC_A, a] = udot[u0 + a]
    _node_outputs(nodes, params, ws_rot, ws_vec, 0.0, 0.0, 0.0, rotation, position, velocity, acceleration)


@njit(cache=True)
def node_kinematics_after_dynamics(nodes, params, rotation, position, velocity, acceleration, ws_rot, ws_vec):
    """:func:`dynamics.kernels.node_kinematics_after_dynamics` after this module's :func:`forward_dynamics`
    (the workspace holds the body's pose, velocity and acceleration including the ground's)."""
    _node_outputs(nodes, params, ws_rot, ws_vec, params[GROUND_ACCEL + 3], params[GROUND_ACCEL + 4],
                  params[GROUND_ACCEL + 5], rotation, position, velocity, acceleration)
