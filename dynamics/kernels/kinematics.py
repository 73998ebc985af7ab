"""Kinematics of the augmented-body recursion: body poses, velocities, velocity-product biases and
accelerations through hinges on fixed frames (the rigid fast path) and on deforming nodes.

With ``u_k = [hinge rates; eta_dot_k]`` the tree's velocities are ``x_k = P_k x_p + H_k u_k`` (the package
docstring, :mod:`dynamics.kernels`); this module computes per body k its pose in the parent (through the
deformed pose of the parent node the hinge is attached to, and the deformed node of its own that carries the
outboard frame), ``V_k``, the bias ``c_k`` (Featherstone, *Rigid Body Dynamics Algorithms* (RBDA), 2008,
eqs. 2.39-2.43, for a parent frame that itself moves relative to the parent body) and, for given
accelerations, ``a_k = X_k (a_p + Psi eta_ddot_p) + c_k + S udot_k - Pc eta_ddot_k``. It also fills the
*slots* of the nodes children hang from (deformed pose, ``Psi``, ``w = Psi eta_dot``, ``w'``; see
:mod:`dynamics.layout`) and gives the coordinate rates ``q_dot = f(q, u)`` and the world poses.
"""

from __future__ import annotations

from numba import njit

from dynamics import flexible_kernels as FK
from dynamics.hinges import UJOINT, hinge_coordinate_rates, hinge_motion_subspace, hinge_transform
from dynamics.layout import (
    AXIS1, AXIS2, FIRST_SLOT, FLEX, FLEXIBLE, FX_GINV_KIND, GENERAL, GINV_FACTORED, HINGE_TYPE, INBOARD, MAT_S,
    MAT_TMP, NODE_FRAME, NODE_NEXT_SLOT, NODE_SHAPE, NODE_SHAPE_GINV, NODE_SLOT, NQ_HINGE, NU_HINGE, N_MODES,
    OUTBOARD, OUTBOARD_IDENTITY, OUTBOARD_NODE, PARENT, PARENT_NODE, P_T33, P_TMP83, P_V2, Q_START, ROT_1, ROT_2,
    ROT_BM, ROT_FM, ROT_PB, ROT_WB, SL_L, SL_PSI, SL_R, SL_W, SL_WD, SL_Y, U_START, VEC_A, VEC_AUX, VEC_C, VEC_D,
    VEC_PBM, VEC_POS, VEC_V, VEC_WC, VEC_WPOS, VEC_XW, view)
from dynamics.spatial import motion_cross_motion_add, motion_to_child


@njit(cache=True, inline="always")
def compose_body_pose(R_PF, p_PF, R_FM, p_FM, outboard_identity, R_BM, p_BM, T, R_PB, pos):
    """Body pose in its parent through the hinge: ``R_PB = R_PF R_FM R_BM^T`` and
    ``pos[0:3] = p_PF + R_PF (p_FM - R_FM R_BM^T p_BM)``; ``T`` is a 3x3 scratch."""
    if outboard_identity:
        for a in range(3):
            for b in range(3):
                R_PB[a, b] = R_PF[a, 0] * R_FM[0, b] + R_PF[a, 1] * R_FM[1, b] + R_PF[a, 2] * R_FM[2, b]
            pos[a] = p_PF[a] + R_PF[a, 0] * p_FM[0] + R_PF[a, 1] * p_FM[1] + R_PF[a, 2] * p_FM[2]
        return
    for a in range(3):
        for b in range(3):
            T[a, b] = R_FM[a, 0] * R_BM[b, 0] + R_FM[a, 1] * R_BM[b, 1] + R_FM[a, 2] * R_BM[b, 2]
    for a in range(3):
        for b in range(3):
            R_PB[a, b] = R_PF[a, 0] * T[0, b] + R_PF[a, 1] * T[1, b] + R_PF[a, 2] * T[2, b]
    d0 = p_FM[0] - (T[0, 0] * p_BM[0] + T[0, 1] * p_BM[1] + T[0, 2] * p_BM[2])
    d1 = p_FM[1] - (T[1, 0] * p_BM[0] + T[1, 1] * p_BM[1] + T[1, 2] * p_BM[2])
    d2 = p_FM[2] - (T[2, 0] * p_BM[0] + T[2, 1] * p_BM[1] + T[2, 2] * p_BM[2])
    for a in range(3):
        pos[a] = p_PF[a] + R_PF[a, 0] * d0 + R_PF[a, 1] * d1 + R_PF[a, 2] * d2


@njit(cache=True, inline="always")
def motion_subspace_in_body(hinge_type, axes, R2, R_BM, p_BM, nu, S, tmp):
    """S_B = X_{B<-M} S_M: omega_B = R_BM omega_M, v_B = R_BM v_M + p_BM x omega_B (``tmp`` 6x6 scratch)."""
    hinge_motion_subspace(hinge_type, axes, R2, tmp)
    for k in range(nu):
        for a in range(3):
            S[a, k] = R_BM[a, 0] * tmp[0, k] + R_BM[a, 1] * tmp[1, k] + R_BM[a, 2] * tmp[2, k]
        for a in range(3):
            S[3 + a, k] = R_BM[a, 0] * tmp[3, k] + R_BM[a, 1] * tmp[4, k] + R_BM[a, 2] * tmp[5, k]
        w0, w1, w2 = S[0, k], S[1, k], S[2, k]
        S[3, k] += p_BM[1] * w2 - p_BM[2] * w1
        S[4, k] += p_BM[2] * w0 - p_BM[0] * w2
        S[5, k] += p_BM[0] * w1 - p_BM[1] * w0


@njit(cache=True, inline="always")
def _body_motion_subspace(i, topology, joint_rot, joint_vec, ws_rot, ws_mat):
    """The motion subspace of body i's hinge in body axes (``ws_mat[i, MAT_S]``)."""
    motion_subspace_in_body(topology[i, HINGE_TYPE], joint_vec[i, AXIS1:AXIS2 + 1], ws_rot[i, ROT_2],
                            joint_rot[i, OUTBOARD], joint_vec[i, OUTBOARD], topology[i, NU_HINGE],
                            ws_mat[i, MAT_S], ws_mat[i, MAT_TMP])


@njit(cache=True)
def initialize_workspace(topology, joint_rot, joint_vec, ws_rot, ws_mat):
    """Write the constant motion subspaces (every hinge but the U-joint and hinges on deforming nodes of
    the body itself, which are recomputed per call) into a fresh workspace."""
    for i in range(topology.shape[0]):
        if topology[i, HINGE_TYPE] != UJOINT and topology[i, OUTBOARD_NODE] < 0:
            _body_motion_subspace(i, topology, joint_rot, joint_vec, ws_rot, ws_mat)


@njit(cache=True, inline="always")
def rigid_position(i, topology, joint_rot, joint_vec, q, ws_rot, ws_vec, ws_mat):
    """Pose of body i in its parent (``ws_rot[i, ROT_PB]``, ``ws_vec[i, VEC_POS, 0:3]``); for a U-joint
    also its configuration-dependent motion subspace (the others are constant)."""
    hinge_type = topology[i, HINGE_TYPE]
    q0 = topology[i, Q_START]
    R_FM = ws_rot[i, ROT_FM]
    pos = ws_vec[i, VEC_POS]
    p_FM = pos[3:6]
    axes = joint_vec[i, AXIS1:AXIS2 + 1]
    hinge_transform(hinge_type, q, q0, axes, R_FM, p_FM, ws_rot[i, ROT_1], ws_rot[i, ROT_2])
    compose_body_pose(joint_rot[i, INBOARD], joint_vec[i, INBOARD], R_FM, p_FM, topology[i, OUTBOARD_IDENTITY],
                      joint_rot[i, OUTBOARD], joint_vec[i, OUTBOARD], ws_rot[i, ROT_1], ws_rot[i, ROT_PB], pos)
    if hinge_type == UJOINT:
        _body_motion_subspace(i, topology, joint_rot, joint_vec, ws_rot, ws_mat)


@njit(cache=True, inline="always")
def rigid_velocity(i, topology, joint_vec, u, ws_rot, ws_vec, ws_mat):
    """Spatial velocity V_i = X_i V_parent + S u and the bias c_i = c_J + V_i x_m (S u)."""
    parent = topology[i, PARENT]
    u0 = topology[i, U_START]
    nu = topology[i, NU_HINGE]
    S = ws_mat[i, MAT_S]
    V = ws_vec[i, VEC_V]
    vJ = ws_vec[i, VEC_AUX]
    c = ws_vec[i, VEC_C]
    for a in range(6):
        s = 0.0
        for k in range(nu):
            s += S[a, k] * u[u0 + k]
        vJ[a] = s
    if parent >= 0:
        motion_to_child(ws_rot[i, ROT_PB], ws_vec[i, VEC_POS], ws_vec[parent, VEC_V], V)
        for a in range(6):
            V[a] += vJ[a]
    else:
        for a in range(6):
            V[a] = vJ[a]
    for a in range(6):
        c[a] = 0.0
    if topology[i, HINGE_TYPE] == UJOINT:
        _ujoint_bias(S, u[u0] * u[u0 + 1], joint_vec[i, OUTBOARD], c)
    motion_cross_motion_add(V, vJ, c)


@njit(cache=True, inline="always")
def _ujoint_bias(S, g, p_BM, c):
    """c += c_J = (s1 u1) x (s2 u2) on the angular rows, carried to the body origin: p_BM x (.)"""
    c0 = g * (S[1, 0] * S[2, 1] - S[2, 0] * S[1, 1])
    c1 = g * (S[2, 0] * S[0, 1] - S[0, 0] * S[2, 1])
    c2 = g * (S[0, 0] * S[1, 1] - S[1, 0] * S[0, 1])
    c[0] += c0
    c[1] += c1
    c[2] += c2
    c[3] += p_BM[1] * c2 - p_BM[2] * c1
    c[4] += p_BM[2] * c0 - p_BM[0] * c2
    c[5] += p_BM[0] * c1 - p_BM[1] * c0


@njit(cache=True)
def _deform_slot(nd, n, nodes, params, eta, eta_dot, with_z, pool):
    """Deformed pose, Psi, w and w' of node ``nd`` into its slot (and Z = Psi G^-1 from the precomputed
    Pi G^-1 when ``with_z``); clears the slot's sums of the children's inertia and force."""
    s = nodes[nd, NODE_SLOT]
    fr = nodes[nd, NODE_FRAME]
    tmp83 = view(pool, P_TMP83, 8, 3)
    FK.node_deformation(view(params, nodes[nd, NODE_SHAPE], 6, n), params[fr + 9:fr + 12], view(params, fr, 3, 3),
                        eta, n, eta_dot, view(pool, s + SL_R, 3, 3), pool[s + SL_L:s + SL_L + 3],
                        view(pool, s + SL_PSI, 6, n), pool[s + SL_W:s + SL_W + 6], pool[s + SL_WD:s + SL_WD + 6],
                        tmp83)
    for a in range(42):
        pool[s + SL_Y + a] = 0.0
    if with_z:
        FK.psi_times_inverse_modal_mass(view(params, nodes[nd, NODE_SHAPE_GINV], 6, n), n, tmp83[0],
                                        pool[s + SL_L:s + SL_L + 3], view(pool, s + SL_PSI + 6 * n, 6, n))


@njit(cache=True)
def _update_slots(i, topology, nodes, params, q, u, pool):
    """The slots of every node of body i that children hang from (see :func:`_deform_slot`)."""
    nd = topology[i, FIRST_SLOT]
    if nd < 0:
        return
    n = topology[i, N_MODES]
    qe = topology[i, Q_START] + topology[i, NQ_HINGE]
    ue = topology[i, U_START] + topology[i, NU_HINGE]
    with_z = topology[i, FLEX + FX_GINV_KIND] != GINV_FACTORED
    while nd >= 0:
        _deform_slot(nd, n, nodes, params, q[qe:qe + n], u[ue:ue + n], with_z, pool)
        nd = nodes[nd, NODE_NEXT_SLOT]


@njit(cache=True)
def _general_position(i, topology, nodes, joint_rot, joint_vec, params, q, u, ws_rot, ws_vec, ws_mat, pool):
    """Pose of body i in its parent through the deformed parent node, and through the deformed node of
    its own that carries the hinge's outboard frame (then also its motion subspace and that node's slot)."""
    hinge_type = topology[i, HINGE_TYPE]
    R_FM = ws_rot[i, ROT_FM]
    pos = ws_vec[i, VEC_POS]
    p_FM = pos[3:6]
    axes = joint_vec[i, AXIS1:AXIS2 + 1]
    hinge_transform(hinge_type, q, topology[i, Q_START], axes, R_FM, p_FM, ws_rot[i, ROT_1], ws_rot[i, ROT_2])
    T = ws_rot[i, ROT_2] if hinge_type != UJOINT else view(pool, P_T33, 3, 3)
    R_PF = ws_rot[i, ROT_1]
    p_PF = ws_vec[i, VEC_WPOS, 3:6]
    jnode = topology[i, PARENT_NODE]
    if jnode >= 0:
        slot = nodes[jnode, NODE_SLOT]
        R_PN = view(pool, slot + SL_R, 3, 3)
        l_j = pool[slot + SL_L:slot + SL_L + 3]
        R_NF = joint_rot[i, INBOARD]
        p_NF = joint_vec[i, INBOARD]
        for a in range(3):
            for b in range(3):
                R_PF[a, b] = R_PN[a, 0] * R_NF[0, b] + R_PN[a, 1] * R_NF[1, b] + R_PN[a, 2] * R_NF[2, b]
            p_PF[a] = l_j[a] + R_PN[a, 0] * p_NF[0] + R_PN[a, 1] * p_NF[1] + R_PN[a, 2] * p_NF[2]
    else:
        for a in range(3):
            p_PF[a] = joint_vec[i, INBOARD, a]
            for b in range(3):
                R_PF[a, b] = joint_rot[i, INBOARD, a, b]
    onode = topology[i, OUTBOARD_NODE]
    if onode < 0:
        compose_body_pose(R_PF, p_PF, R_FM, p_FM, topology[i, OUTBOARD_IDENTITY], joint_rot[i, OUTBOARD],
                          joint_vec[i, OUTBOARD], T, ws_rot[i, ROT_PB], pos)
        if hinge_type == UJOINT:
            _body_motion_subspace(i, topology, joint_rot, joint_vec, ws_rot, ws_mat)
        return
    # outboard frame M on the body's own deforming node c: R_BM = R_Bc R_cM, p_BM = l_c + R_Bc p_cM
    n = topology[i, N_MODES]
    qe = topology[i, Q_START] + topology[i, NQ_HINGE]
    ue = topology[i, U_START] + topology[i, NU_HINGE]
    _deform_slot(onode, n, nodes, params, q[qe:qe + n], u[ue:ue + n],
                 topology[i, FLEX + FX_GINV_KIND] != GINV_FACTORED, pool)
    slot = nodes[onode, NODE_SLOT]
    R_Bc = view(pool, slot + SL_R, 3, 3)
    l_c = pool[slot + SL_L:slot + SL_L + 3]
    R_cM = joint_rot[i, OUTBOARD]
    p_cM = joint_vec[i, OUTBOARD]
    R_BM = ws_rot[i, ROT_BM]
    p_BM = ws_vec[i, VEC_PBM, 0:3]
    for a in range(3):
        for b in range(3):
            R_BM[a, b] = R_Bc[a, 0] * R_cM[0, b] + R_Bc[a, 1] * R_cM[1, b] + R_Bc[a, 2] * R_cM[2, b]
        p_BM[a] = l_c[a] + R_Bc[a, 0] * p_cM[0] + R_Bc[a, 1] * p_cM[1] + R_Bc[a, 2] * p_cM[2]
    compose_body_pose(R_PF, p_PF, R_FM, p_FM, 0, R_BM, p_BM, T, ws_rot[i, ROT_PB], pos)
    motion_subspace_in_body(hinge_type, axes, ws_rot[i, ROT_2], R_BM, p_BM, topology[i, NU_HINGE],
                            ws_mat[i, MAT_S], ws_mat[i, MAT_TMP])


@njit(cache=True)
def _general_velocity(i, topology, nodes, joint_vec, u, ws_rot, ws_vec, ws_mat, pool):
    """Velocity V_i and velocity-product bias c_i of a body hinged on deforming nodes (module docstring)."""
    parent = topology[i, PARENT]
    u0 = topology[i, U_START]
    nu = topology[i, NU_HINGE]
    S = ws_mat[i, MAT_S]
    R = ws_rot[i, ROT_PB]
    r = ws_vec[i, VEC_POS]
    x = ws_vec[i, VEC_V]
    c = ws_vec[i, VEC_C]
    vJ = ws_vec[i, VEC_AUX]
    Xw = ws_vec[i, VEC_XW]
    wc = ws_vec[i, VEC_WC]
    t1 = ws_vec[i, VEC_D]  # scratch until the articulated-body pass
    t2 = ws_vec[i, VEC_A]  # scratch until the acceleration pass
    for a in range(6):
        s_ = 0.0
        for k in range(nu):
            s_ += S[a, k] * u[u0 + k]
        vJ[a] = s_
        c[a] = 0.0
        Xw[a] = 0.0
        wc[a] = 0.0
    if parent >= 0:
        Vp = ws_vec[parent, VEC_V]
        jnode = topology[i, PARENT_NODE]
        if jnode >= 0:
            slot = nodes[jnode, NODE_SLOT]
            w = pool[slot + SL_W:slot + SL_W + 6]
            for a in range(6):
                t1[a] = Vp[a] + w[a]
            motion_to_child(R, r, t1, x)
            motion_to_child(R, r, w, Xw)
            motion_to_child(R, r, pool[slot + SL_WD:slot + SL_WD + 6], c)  # X w'
        else:
            motion_to_child(R, r, Vp, x)
        for a in range(6):
            x[a] += vJ[a]
    else:
        for a in range(6):
            x[a] = vJ[a]
    onode = topology[i, OUTBOARD_NODE]
    if onode >= 0:
        # the body moves relative to its hinge node with -w_c
        slot = nodes[onode, NODE_SLOT]
        for a in range(6):
            wc[a] = pool[slot + SL_W + a]
            x[a] -= wc[a]
            c[a] -= pool[slot + SL_WD + a]
        motion_cross_motion_add(wc, vJ, c)
    if topology[i, HINGE_TYPE] == UJOINT:
        _ujoint_bias(S, u[u0] * u[u0 + 1], joint_vec[i, OUTBOARD] if onode < 0 else ws_vec[i, VEC_PBM, 0:3], c)
    # V x (X w + S u - w_c) + (X w) x (S u - w_c)
    for a in range(6):
        t1[a] = Xw[a] + vJ[a] - wc[a]
        t2[a] = vJ[a] - wc[a]
    motion_cross_motion_add(x, t1, c)
    motion_cross_motion_add(Xw, t2, c)


@njit(cache=True)
def general_kinematics(i, topology, nodes, joint_rot, joint_vec, params, q, u, ws_rot, ws_vec, ws_mat, pool,
                        velocity):
    """Pose (and, with ``velocity``, velocity and bias) of a body on the augmented path, and the slots of
    its nodes."""
    _general_position(i, topology, nodes, joint_rot, joint_vec, params, q, u, ws_rot, ws_vec, ws_mat, pool)
    if velocity:
        _general_velocity(i, topology, nodes, joint_vec, u, ws_rot, ws_vec, ws_mat, pool)
    if topology[i, FLEXIBLE]:
        _update_slots(i, topology, nodes, params, q, u, pool)


@njit(cache=True, inline="always")
def body_kinematics(i, topology, nodes, joint_rot, joint_vec, params, q, u, ws_rot, ws_vec, ws_mat, pool, velocity):
    """Pose (and velocity and bias) of body i: the rigid fast path inline, the augmented path called."""
    if topology[i, GENERAL]:
        general_kinematics(i, topology, nodes, joint_rot, joint_vec, params, q, u, ws_rot, ws_vec, ws_mat, pool,
                            velocity)
    else:
        rigid_position(i, topology, joint_rot, joint_vec, q, ws_rot, ws_vec, ws_mat)
        if velocity:
            rigid_velocity(i, topology, joint_vec, u, ws_rot, ws_vec, ws_mat)


@njit(cache=True)
def _motion_slot(nd, n, nodes, params, eta, eta_dot, pool):
    """Deformed pose, w and w' of node ``nd`` into its slot, without its ``Psi`` (:func:`FK.node_motion`): what a
    child's pose and velocity read (its ``Psi`` and Z are left as they are)."""
    s = nodes[nd, NODE_SLOT]
    fr = nodes[nd, NODE_FRAME]
    FK.node_motion(view(params, nodes[nd, NODE_SHAPE], 6, n), params[fr + 9:fr + 12], view(params, fr, 3, 3), eta, n,
                   eta_dot, eta[0:0], view(pool, s + SL_R, 3, 3), pool[s + SL_L:s + SL_L + 3],
                   pool[s + SL_W:s + SL_W + 6], pool[s + SL_WD:s + SL_WD + 6], pool[s + SL_WD:s + SL_WD],
                   view(pool, P_TMP83, 8, 3))


@njit(cache=True)
def body_motion(i, topology, nodes, joint_rot, joint_vec, params, q, u, ws_rot, ws_vec, ws_mat, pool, bodies):
    """Pose and velocity of body i (as :func:`body_kinematics` with ``velocity``) where only the bodies with
    ``bodies[j] != 0`` are computed (body i's ancestors among them): the slot of a deforming parent node gets its
    pose, ``w`` and ``w'`` (not ``Psi``) from the first of those bodies hanging from it; the slots of body i's own
    nodes are left to its children. For the poses and velocities of nodes (:func:`dynamics.kernels.node_frames.
    node_velocities_selected`)."""
    if not topology[i, GENERAL]:
        rigid_position(i, topology, joint_rot, joint_vec, q, ws_rot, ws_vec, ws_mat)
        rigid_velocity(i, topology, joint_vec, u, ws_rot, ws_vec, ws_mat)
        return
    parent = topology[i, PARENT]
    jnode = topology[i, PARENT_NODE]
    if jnode >= 0 and parent >= 0 and topology[parent, FLEXIBLE]:
        first = True
        for j in range(parent + 1, i):
            if bodies[j] != 0 and topology[j, PARENT_NODE] == jnode:
                first = False
                break
        if first:
            n = topology[parent, N_MODES]
            qe = topology[parent, Q_START] + topology[parent, NQ_HINGE]
            ue = topology[parent, U_START] + topology[parent, NU_HINGE]
            _motion_slot(jnode, n, nodes, params, q[qe:qe + n], u[ue:ue + n], pool)
    _general_position(i, topology, nodes, joint_rot, joint_vec, params, q, u, ws_rot, ws_vec, ws_mat, pool)
    _general_velocity(i, topology, nodes, joint_vec, u, ws_rot, ws_vec, ws_mat, pool)


@njit(cache=True, fastmath=FK.FAST_SUMS)
def _rows_times(M, x, n, out):
    """``out[a] = sum_r M[a, r] x[r]`` for the six rows of a 6 x n ``Psi`` (reassociated sums: vectorized, see
    :data:`dynamics.flexible_kernels.FAST_SUMS`; a sum over 196 modes in order is bound by the latency of its
    additions, ~4x the vectorized time)."""
    for a in range(6):
        s = 0.0
        for r in range(n):
            s += M[a, r] * x[r]
        out[a] = s


@njit(cache=True)
def _parent_acceleration_modal(i, topology, nodes, udot, ws_rot, ws_vec, pool, A):
    """A = X_i (a_parent + Psi_i etaddot_parent) for a body hanging from a node of a flexible parent."""
    parent = topology[i, PARENT]
    n_p = topology[parent, N_MODES]
    Ap = ws_vec[parent, VEC_A]
    tmp = pool[P_V2:P_V2 + 6]
    Psi = view(pool, nodes[topology[i, PARENT_NODE], NODE_SLOT] + SL_PSI, 6, n_p)
    ue = topology[parent, U_START] + topology[parent, NU_HINGE]
    _rows_times(Psi, udot[ue:ue + n_p], n_p, tmp)
    for a in range(6):
        tmp[a] += Ap[a]
    motion_to_child(ws_rot[i, ROT_PB], ws_vec[i, VEC_POS], tmp, A)


@njit(cache=True)
def parent_acceleration_general(i, topology, nodes, ground, udot, ws_rot, ws_vec, pool, A):
    """:func:`parent_acceleration` called (the forward dynamics' inner loop keeps it out of line)."""
    parent_acceleration(i, topology, nodes, ground, udot, ws_rot, ws_vec, pool, A)


@njit(cache=True, inline="always")
def parent_acceleration(i, topology, nodes, ground, udot, ws_rot, ws_vec, pool, A):
    """A = X_i (a_parent + Psi_i etaddot_parent) (the ground's acceleration ``ground`` for a root body)."""
    parent = topology[i, PARENT]
    if parent < 0:
        motion_to_child(ws_rot[i, ROT_PB], ws_vec[i, VEC_POS], ground, A)
    elif topology[i, PARENT_NODE] >= 0 and topology[parent, N_MODES] > 0:
        _parent_acceleration_modal(i, topology, nodes, udot, ws_rot, ws_vec, pool, A)
    else:
        motion_to_child(ws_rot[i, ROT_PB], ws_vec[i, VEC_POS], ws_vec[parent, VEC_A], A)


@njit(cache=True)
def accelerations(topology, nodes, ground, udot, ws_rot, ws_vec, ws_mat, pool):
    """Spatial accelerations a_i = X_i (a_p + Psi etaddot_p) + c_i + S udot_i - Pc etaddot_i for given
    accelerations ``udot`` (into ``ws_vec[:, VEC_A]``), with ``ground`` the ground's acceleration."""
    for i in range(topology.shape[0]):
        A = ws_vec[i, VEC_A]
        parent_acceleration(i, topology, nodes, ground, udot, ws_rot, ws_vec, pool, A)
        add_hinge_acceleration(i, topology, nodes, udot, ws_vec, ws_mat, pool, A)


@njit(cache=True, inline="always")
def add_hinge_acceleration(i, topology, nodes, udot, ws_vec, ws_mat, pool, A):
    """A += c_i + S udot_hinge - Pc etaddot (the rigid rows of c + H udot)."""
    S = ws_mat[i, MAT_S]
    c = ws_vec[i, VEC_C]
    u0 = topology[i, U_START]
    nu = topology[i, NU_HINGE]
    for a in range(6):
        s_ = A[a] + c[a]
        for k in range(nu):
            s_ += S[a, k] * udot[u0 + k]
        A[a] = s_
    onode = topology[i, OUTBOARD_NODE]
    if onode >= 0:
        n = topology[i, N_MODES]
        tmp = pool[P_V2:P_V2 + 6]
        _rows_times(view(pool, nodes[onode, NODE_SLOT] + SL_PSI, 6, n), udot[u0 + nu:u0 + nu + n], n, tmp)
        for a in range(6):
            A[a] -= tmp[a]


@njit(cache=True)
def coordinate_rates(topology, q, u, qdot):
    """``q_dot = f(q, u)`` for the whole system (quaternion kinematics per hinge)."""
    for i in range(topology.shape[0]):
        hinge_coordinate_rates(topology[i, HINGE_TYPE], q, topology[i, Q_START], u,
                               topology[i, U_START], qdot)
        nm = topology[i, N_MODES]
        q0 = topology[i, Q_START] + topology[i, NQ_HINGE]
        u0 = topology[i, U_START] + topology[i, NU_HINGE]
        for k in range(nm):
            qdot[q0 + k] = u[u0 + k]


@njit(cache=True, inline="always")
def world_pose(i, topology, ws_rot, ws_vec):
    """Body i's body -> world rotation (``ws_rot[i, ROT_WB]``) and origin in the world (``ws_vec[i, VEC_WPOS,
    0:3]``) from its parent-relative pose and its parent's world pose (already computed)."""
    parent = topology[i, PARENT]
    R_PB = ws_rot[i, ROT_PB]
    r = ws_vec[i, VEC_POS]
    R_WB = ws_rot[i, ROT_WB]
    p = ws_vec[i, VEC_WPOS]
    if parent < 0:
        for a in range(3):
            p[a] = r[a]
            for b in range(3):
                R_WB[a, b] = R_PB[a, b]
    else:
        R_WP = ws_rot[parent, ROT_WB]
        pp = ws_vec[parent, VEC_WPOS]
        for a in range(3):
            p[a] = pp[a] + R_WP[a, 0] * r[0] + R_WP[a, 1] * r[1] + R_WP[a, 2] * r[2]
            for b in range(3):
                R_WB[a, b] = R_WP[a, 0] * R_PB[0, b] + R_WP[a, 1] * R_PB[1, b] + R_WP[a, 2] * R_PB[2, b]


@njit(cache=True)
def accumulate_world_poses(topology, ws_rot, ws_vec):
    """Body -> world rotations (``ws_rot[:, ROT_WB]``) and body origins in the world
    (``ws_vec[:, VEC_WPOS, 0:3]``) from the parent-relative poses."""
    for i in range(topology.shape[0]):
        world_pose(i, topology, ws_rot, ws_vec)
