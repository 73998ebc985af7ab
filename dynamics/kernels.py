"""The engine's compiled algorithms: one augmented-body recursion for rigid and flexible bodies (numba).

Every body k carries an *augmented* velocity ``x_k = [V_k; eta_dot_k]`` of size ``6 + n_k`` (rigid bodies:
``n_k = 0``). With ``u_k = [hinge rates; eta_dot_k]`` the kinematics of the tree read

    x_k = P_k x_p + H_k u_k,   P_k = [X_k [I, Psi_k]; 0],   H_k = [[S_k, -Pc_k], [0, I]]

where ``X_k`` is the rigid motion transform from the parent frame to body k (through the deformed pose of
the parent node the hinge is attached to, when the parent is flexible), ``Psi_k`` (6 x n_p) the spatial
velocity of that node per unit modal rate of the parent (:func:`dynamics.flexible_kernels.node_deformation`),
``S_k`` the hinge's motion subspace, and ``Pc_k`` (6 x n_k) the ``Psi`` of a node of body k itself when the
hinge's outboard frame sits on it (``child_grid``; zero otherwise). Differentiating gives
``xdot_k = P_k xdot_p + H_k udot_k + c_k`` with the velocity-product term

    c_k = [X_k w' + c_J + V_k x (X_k w + S u - w_c) + (X_k w) x (S u - w_c) + w_c x (S u) - w'_c; 0],
    w = Psi_k eta_dot_p,  w_c = Pc_k eta_dot_k,  w', w'_c the velocity products of d/dt (Psi eta_dot)

(Featherstone, *Rigid Body Dynamics Algorithms* (RBDA), 2008, eqs. 2.39-2.43, for a parent frame that
itself moves relative to the parent body). Each body's equations ``F_k = M_k(eta) xdot_k + b_k`` follow
from its kinetic energy (:mod:`dynamics.flexible_kernels`; a rigid body has ``M = I``,
``b = V x* I V``). The algorithms are the rigid-body ones run in these augmented spaces (Jain, *Robot and
Multibody Dynamics*, 2011, ch. 13: the flexible-body ABA):

* :func:`forward_dynamics` - articulated-body algorithm (RBDA Table 7.1) with prescribed hinge DOFs (their
  known accelerations enter the bias, their forces come from ``IA a + pA``, RBDA sec. 9.3). A flexible
  body's modal DOFs are eliminated before its hinge DOFs by a Schur complement whose modal block,
  ``E' = G + L' Q L``, is the constant modal mass ``G`` plus updates of rank 6 per node that children
  hang from (and 12 for a hinge on a node of the body), so ``E'^-1`` comes from the precomputed ``G^-1``
  and a small dense solve (Woodbury): O(n^2) per body at orders 0 and 1 (O(n) with a diagonal ``G``),
  see :func:`_condense_modes`. When G1 or G2 make ``G`` depend on eta it is factored per call, O(n^3);
* :func:`forward_dynamics_dense` - the same accelerations from ``M(q) udot = tau - h`` (CRBA, RNEA and a
  dense Cholesky factorization): chosen at compile time when it is cheaper (``MultibodySystem.solver``);
* :func:`inverse_dynamics` - recursive Newton-Euler (RBDA Table 5.1);
* :func:`mass_matrix` - composite-rigid-body algorithm (RBDA Table 6.2), exactly symmetric;
* :func:`node_kinematics` and :func:`node_kinematics_after_dynamics` - pose, spatial velocity and
  classical acceleration of frames on (deforming) bodies;
* :func:`energy_momentum` - kinetic and potential energy, linear and angular momentum in the world.

A body without modal data whose hinge is not on a deforming node (topology column ``GENERAL`` = 0) runs the
6 x 6 rigid-body code (the rigid fast path); every other body runs the augmented code, which reduces to
the same equations for zero modes (``tests/dynamics/test_zero_modes.py`` compares the two to round-off).
Gravity enters as a fictitious upward acceleration of the ground, ``a_0 = [0; -g]`` (RBDA sec. 5.3).
External forces: per body (about the body origin, body axes) and per node (node axes, at the deformed
node).

Data (built by :class:`dynamics.system.MultibodySystem`): ``topology`` (one int row per body, columns
below), ``nodes`` (one int row per node), ``joint_rot``/``joint_vec`` (hinge frames and axes), ``params``
(every other float of the description: ground acceleration, body inertias, modal data, node frames and
mode shapes) and the workspace ``ws_rot``, ``ws_vec``, ``ws_mat`` (6 x 6 quantities per body) and
``pool`` (everything sized by modes). Kernels write their results into output arguments and allocate
nothing.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from dynamics import flexible_kernels as FK
from dynamics.flexible_kernels import GINV_FACTORED, OUTBOARD_NODE, PARENT_NODE, PV_FORCE, PV_RHS, PV_TMP, PV_Y
from dynamics.hinges import UJOINT, hinge_coordinate_rates, hinge_motion_subspace, hinge_transform
from dynamics.spatial import (
    force_to_parent_add,
    force_to_parent_inplace,
    inertia_to_parent_add,
    mat6_vec,
    motion_cross_motion_add,
    motion_to_child,
)

# topology columns (one int64 row per body)
PARENT = 0
HINGE_TYPE = 1
Q_START = 2
NQ_HINGE = 3
U_START = 4
NU_HINGE = 5
N_MODES = 6
N_FREE = 7
N_PRESCRIBED = 8
OUTBOARD_IDENTITY = 9  # 1 when the hinge outboard frame is the body frame (saves a frame product)
GENERAL = 10  # 1: the augmented path (flexible, or hinged on a deforming node); 0: the rigid fast path
INERTIA = 11  # params offset of the constant rigid block M0[:6, :6] (the spatial inertia), 36 numbers
FREE_DOFS = 12  # 6 columns: local indices of the free hinge DOFs
PRESCRIBED_DOFS = 18  # 6 columns: local indices of the prescribed hinge DOFs
# 24 PARENT_NODE and 25 OUTBOARD_NODE: hinges on deforming nodes (dynamics.flexible_kernels)
FLEXIBLE = 26  # 1: the body has modal data (possibly zero modes) and the FLEX columns describe it
FIRST_SLOT = 27  # first node of this body that children hang from (chained by NODE_NEXT_SLOT), or -1
FLEX = 28  # the flexible-body columns dynamics.flexible_kernels.FX_* start here
TOPOLOGY_COLUMNS = FLEX + FK.N_FX

# node table columns (one int64 row per node)
NODE_BODY = 0
NODE_FRAME = 1  # params offset: node -> body rotation R0 (9, row major), then position l0 (3)
NODE_SHAPE = 2  # params offset of Pi = [lambda; gamma] (6 x n) on a flexible body, -1 on a rigid one
NODE_SHAPE_GINV = 3  # params offset of Pi G0^-1 (6 x n): slot nodes of constant-G bodies, else -1
NODE_SLOT = 4  # pool offset of the node's slot (children hang from it, or it carries the body's hinge)
NODE_NEXT_SLOT = 5  # the next child-attachment node of the same body, or -1
NODE_COLUMNS = 6

# params: [0:6] ground acceleration, then the bodies' 6 x 6 inertias, then modal data and node frames
GROUND_ACCEL = 0

# a slot: the deformed node (R, l), w = Psi eta_dot, w', the children's articulated inertia Y and force
# g summed in this node's body axes, then Psi (6 x n) and Z = Psi G^-1 (6 x n)
SL_R = 0
SL_L = 9
SL_W = 12
SL_WD = 18
SL_Y = 24
SL_G = 60
SL_PSI = 66

# pool header: scratch of the node loops, then the Psi of one node (6 x nmax), then body blocks
P_TMP83 = 0  # (8, 3) for node_deformation
P_R = 24
P_L = 33
P_W = 36
P_WD = 42
P_V1 = 48
P_V2 = 54
P_ZERO = 60  # 6 zeros: the ground acceleration of node kinematics
P_T33 = 66  # 3 x 3
POOL_HEADER = 80

# joint_rot slots: (nb, 2, 3, 3) and joint_vec slots: (nb, 4, 3)
INBOARD = 0  # rotation R_PF / position of F in the parent frame (or in the parent node's frame)
OUTBOARD = 1  # rotation R_BM / position of M in the body frame (or in the outboard node's frame)
AXIS1 = 2
AXIS2 = 3

# workspace slots
ROT_PB = 0  # body -> parent rotation
ROT_FM = 1
ROT_1 = 2  # U-joint scratch, then R_PF of a hinge on a deforming parent node
ROT_2 = 3
ROT_WB = 4  # body -> world rotation
ROT_BM = 5  # outboard frame on a deforming node of the body
N_ROT = 6

VEC_V = 0  # spatial velocity of the body
VEC_C = 1  # velocity-product (and prescribed) bias acceleration
VEC_P = 2  # articulated bias force pA (ABA) / body force f (RNEA)
VEC_A = 3  # spatial acceleration
VEC_D = 4  # joint-space residual d (ABA)
VEC_POS = 5  # [0:3] position of the body origin in the parent, [3:6] p_FM
VEC_AUX = 6  # hinge velocity S u, then ABA's pa
VEC_WPOS = 7  # [0:3] body origin in the world, [3:6] p_PF on a deforming parent node
VEC_XW = 8  # X w: the parent node's velocity relative to the parent, in body axes
VEC_WC = 9  # w_c: the outboard node's velocity relative to the body
VEC_PBM = 10  # [0:3] p_BM of an outboard frame on a deforming node
N_VEC = 11

MAT_S = 0  # motion subspace in body axes (6 x nu)
MAT_IA = 1  # articulated (ABA) or composite (CRBA) inertia, rigid block
MAT_U = 2  # U = IA S_free (ABA) / F = Ic S (CRBA)
MAT_DINV = 3  # (S^T IA S)^-1 over the free DOFs
MAT_IAP = 4  # IA - U D^-1 U^T; dM_rr/dt scratch of a flexible body
MAT_TMP = 5
N_MAT = 6


@njit(cache=True, inline="always")
def rigid_bias_add(params, o, V, out):
    """``out += V x* (I V)`` for the rigid spatial inertia ``I = [[J, m c~], [-m c~, m 1]]`` at ``params[o:o+36]``
    (row major), leaving out ``v x (m v)``: zero in exact arithmetic, but in floating point a torque of
    order ``eps m |v|^2`` on a body whose hinge carries a large velocity in body axes (an orbiting free
    body: 1e-5 N m for 750 kg at 7 km/s). Terms: ``[w x (J w + m c~ v) + v x (-m c~ w); w x (I V)_lin]``."""
    w0, w1, w2, v0, v1, v2 = V[0], V[1], V[2], V[3], V[4], V[5]
    h0 = params[o + 0] * w0 + params[o + 1] * w1 + params[o + 2] * w2
    h1 = params[o + 6] * w0 + params[o + 7] * w1 + params[o + 8] * w2
    h2 = params[o + 12] * w0 + params[o + 13] * w1 + params[o + 14] * w2
    h0 += params[o + 3] * v0 + params[o + 4] * v1 + params[o + 5] * v2
    h1 += params[o + 9] * v0 + params[o + 10] * v1 + params[o + 11] * v2
    h2 += params[o + 15] * v0 + params[o + 16] * v1 + params[o + 17] * v2
    k0 = params[o + 18] * w0 + params[o + 19] * w1 + params[o + 20] * w2
    k1 = params[o + 24] * w0 + params[o + 25] * w1 + params[o + 26] * w2
    k2 = params[o + 30] * w0 + params[o + 31] * w1 + params[o + 32] * w2
    g0 = k0 + params[o + 21] * v0 + params[o + 22] * v1 + params[o + 23] * v2
    g1 = k1 + params[o + 27] * v0 + params[o + 28] * v1 + params[o + 29] * v2
    g2 = k2 + params[o + 33] * v0 + params[o + 34] * v1 + params[o + 35] * v2
    out[0] += w1 * h2 - w2 * h1 + v1 * k2 - v2 * k1
    out[1] += w2 * h0 - w0 * h2 + v2 * k0 - v0 * k2
    out[2] += w0 * h1 - w1 * h0 + v0 * k1 - v1 * k0
    out[3] += w1 * g2 - w2 * g1
    out[4] += w2 * g0 - w0 * g2
    out[5] += w0 * g1 - w1 * g0


@njit(cache=True)
def _view(a, offset, rows, cols):
    """The (rows x cols) matrix stored row-major in ``a[offset:]``."""
    return a[offset:offset + rows * cols].reshape((rows, cols))


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


# ---------------------------------------------------------------------------------------- kinematics
@njit(cache=True, inline="always")
def _rigid_position(i, topology, joint_rot, joint_vec, q, ws_rot, ws_vec, ws_mat):
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
def _rigid_velocity(i, topology, joint_vec, u, ws_rot, ws_vec, ws_mat):
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
    tmp83 = _view(pool, P_TMP83, 8, 3)
    FK.node_deformation(_view(params, nodes[nd, NODE_SHAPE], 6, n), params[fr + 9:fr + 12], _view(params, fr, 3, 3),
                        eta, n, eta_dot, _view(pool, s + SL_R, 3, 3), pool[s + SL_L:s + SL_L + 3],
                        _view(pool, s + SL_PSI, 6, n), pool[s + SL_W:s + SL_W + 6], pool[s + SL_WD:s + SL_WD + 6],
                        tmp83)
    for a in range(42):
        pool[s + SL_Y + a] = 0.0
    if with_z:
        FK.psi_times_inverse_modal_mass(_view(params, nodes[nd, NODE_SHAPE_GINV], 6, n), n, tmp83[0],
                                        pool[s + SL_L:s + SL_L + 3], _view(pool, s + SL_PSI + 6 * n, 6, n))


@njit(cache=True)
def _update_slots(i, topology, nodes, params, q, u, pool):
    """The slots of every node of body i that children hang from (see :func:`_deform_slot`)."""
    nd = topology[i, FIRST_SLOT]
    if nd < 0:
        return
    n = topology[i, N_MODES]
    qe = topology[i, Q_START] + topology[i, NQ_HINGE]
    ue = topology[i, U_START] + topology[i, NU_HINGE]
    with_z = topology[i, FLEX + FK.FX_GINV_KIND] != GINV_FACTORED
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
    T = ws_rot[i, ROT_2] if hinge_type != UJOINT else _view(pool, P_T33, 3, 3)
    R_PF = ws_rot[i, ROT_1]
    p_PF = ws_vec[i, VEC_WPOS, 3:6]
    jnode = topology[i, PARENT_NODE]
    if jnode >= 0:
        slot = nodes[jnode, NODE_SLOT]
        R_PN = _view(pool, slot + SL_R, 3, 3)
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
                 topology[i, FLEX + FK.FX_GINV_KIND] != GINV_FACTORED, pool)
    slot = nodes[onode, NODE_SLOT]
    R_Bc = _view(pool, slot + SL_R, 3, 3)
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
def _general_kinematics(i, topology, nodes, joint_rot, joint_vec, params, q, u, ws_rot, ws_vec, ws_mat, pool,
                        velocity):
    """Pose (and, with ``velocity``, velocity and bias) of a body on the augmented path, and the slots of
    its nodes."""
    _general_position(i, topology, nodes, joint_rot, joint_vec, params, q, u, ws_rot, ws_vec, ws_mat, pool)
    if velocity:
        _general_velocity(i, topology, nodes, joint_vec, u, ws_rot, ws_vec, ws_mat, pool)
    if topology[i, FLEXIBLE]:
        _update_slots(i, topology, nodes, params, q, u, pool)


@njit(cache=True, inline="always")
def _kinematics(i, topology, nodes, joint_rot, joint_vec, params, q, u, ws_rot, ws_vec, ws_mat, pool, velocity):
    """Pose (and velocity and bias) of body i: the rigid fast path inline, the augmented path called."""
    if topology[i, GENERAL]:
        _general_kinematics(i, topology, nodes, joint_rot, joint_vec, params, q, u, ws_rot, ws_vec, ws_mat, pool,
                            velocity)
    else:
        _rigid_position(i, topology, joint_rot, joint_vec, q, ws_rot, ws_vec, ws_mat)
        if velocity:
            _rigid_velocity(i, topology, joint_vec, u, ws_rot, ws_vec, ws_mat)


@njit(cache=True)
def _flexible_body_terms(i, topology, params, q, u, ws_vec, ws_mat, pool, with_bias, form_G):
    """``M_rr(eta)`` into the pool (``FX_P_MRR``), ``M_re(eta)`` and (``form_G``) ``G(eta)`` into the pool and,
    with ``with_bias``, the body forces ``b`` into ``ws_vec[i, VEC_P]`` and the pool (``PV_FORCE``)."""
    n = topology[i, N_MODES]
    qe = topology[i, Q_START] + topology[i, NQ_HINGE]
    ue = topology[i, U_START] + topology[i, NU_HINGE]
    fx = topology[i, FLEX:FLEX + FK.N_FX]
    Mrr = _view(pool, topology[i, FLEX + FK.FX_P_MRR], 6, 6)
    o = topology[i, INERTIA]
    for a in range(6):
        for b in range(6):
            Mrr[a, b] = params[o + 6 * a + b]
    pv = fx[FK.FX_P_VEC]
    FK.modal_mass_and_bias(fx, params, n, q[qe:qe + n], ws_vec[i, VEC_V], u[ue:ue + n], with_bias, form_G, Mrr,
                           _view(pool, fx[FK.FX_P_MRE], 6, n), _view(pool, fx[FK.FX_P_G], n, n), ws_vec[i, VEC_P],
                           pool[pv + PV_FORCE * n:pv + (PV_FORCE + 1) * n], ws_mat[i, MAT_IAP],
                           _view(pool, fx[FK.FX_P_MDRE], 6, n))


@njit(cache=True)
def _apply_node_forces(topology, nodes, params, q, node_forces, ws_vec, pool, sign):
    """Body forces ``ws_vec[:, VEC_P]`` (and modal forces of flexible bodies) ``+= sign`` times the
    generalized forces of the node forces (node axes, at the deformed node): ``[X'; Psi' X'] f``."""
    tmp83 = _view(pool, P_TMP83, 8, 3)
    Rn = _view(pool, P_R, 3, 3)
    l = pool[P_L:P_L + 3]
    f6 = pool[P_V1:P_V1 + 6]
    for nd in range(node_forces.shape[0]):
        f = node_forces[nd]
        if f[0] == 0.0 and f[1] == 0.0 and f[2] == 0.0 and f[3] == 0.0 and f[4] == 0.0 and f[5] == 0.0:
            continue
        b = nodes[nd, NODE_BODY]
        n = topology[b, N_MODES]
        fr = nodes[nd, NODE_FRAME]
        for a in range(6):
            f6[a] = 0.0
        if n > 0:
            qe = topology[b, Q_START] + topology[b, NQ_HINGE]
            shape = _view(params, nodes[nd, NODE_SHAPE], 6, n)
            FK.node_pose(shape, params[fr + 9:fr + 12], _view(params, fr, 3, 3), q[qe:qe + n], n, Rn, l, tmp83)
            force_to_parent_add(Rn, l, f, f6)
            pv = topology[b, FLEX + FK.FX_P_VEC] + PV_FORCE * n
            FK.node_modal_force(shape, n, tmp83[0], Rn, f, sign, pool[pv:pv + n])
        else:
            force_to_parent_add(_view(params, fr, 3, 3), params[fr + 9:fr + 12], f, f6)
        P = ws_vec[b, VEC_P]
        for a in range(6):
            P[a] += sign * f6[a]


@njit(cache=True)
def _parent_acceleration_modal(i, topology, nodes, udot, ws_rot, ws_vec, pool, A):
    """A = X_i (a_parent + Psi_i etaddot_parent) for a body hanging from a node of a flexible parent."""
    parent = topology[i, PARENT]
    n_p = topology[parent, N_MODES]
    Ap = ws_vec[parent, VEC_A]
    tmp = pool[P_V2:P_V2 + 6]
    Psi = _view(pool, nodes[topology[i, PARENT_NODE], NODE_SLOT] + SL_PSI, 6, n_p)
    ue = topology[parent, U_START] + topology[parent, NU_HINGE]
    for a in range(6):
        s_ = Ap[a]
        for rr in range(n_p):
            s_ += Psi[a, rr] * udot[ue + rr]
        tmp[a] = s_
    motion_to_child(ws_rot[i, ROT_PB], ws_vec[i, VEC_POS], tmp, A)


@njit(cache=True)
def _parent_acceleration_general(i, topology, nodes, ground, udot, ws_rot, ws_vec, pool, A):
    """:func:`_parent_acceleration` called (the forward dynamics' inner loop keeps it out of line)."""
    _parent_acceleration(i, topology, nodes, ground, udot, ws_rot, ws_vec, pool, A)


@njit(cache=True, inline="always")
def _parent_acceleration(i, topology, nodes, ground, udot, ws_rot, ws_vec, pool, A):
    """A = X_i (a_parent + Psi_i etaddot_parent) (the ground's acceleration ``ground`` for a root body)."""
    parent = topology[i, PARENT]
    if parent < 0:
        motion_to_child(ws_rot[i, ROT_PB], ws_vec[i, VEC_POS], ground, A)
    elif topology[i, PARENT_NODE] >= 0 and topology[parent, N_MODES] > 0:
        _parent_acceleration_modal(i, topology, nodes, udot, ws_rot, ws_vec, pool, A)
    else:
        motion_to_child(ws_rot[i, ROT_PB], ws_vec[i, VEC_POS], ws_vec[parent, VEC_A], A)


@njit(cache=True)
def _accelerations(topology, nodes, ground, udot, ws_rot, ws_vec, ws_mat, pool):
    """Spatial accelerations a_i = X_i (a_p + Psi etaddot_p) + c_i + S udot_i - Pc etaddot_i for given
    accelerations ``udot`` (into ``ws_vec[:, VEC_A]``), with ``ground`` the ground's acceleration."""
    for i in range(topology.shape[0]):
        A = ws_vec[i, VEC_A]
        _parent_acceleration(i, topology, nodes, ground, udot, ws_rot, ws_vec, pool, A)
        _add_hinge_acceleration(i, topology, nodes, udot, ws_vec, ws_mat, pool, A)


@njit(cache=True, inline="always")
def _add_hinge_acceleration(i, topology, nodes, udot, ws_vec, ws_mat, pool, A):
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
        Pc = _view(pool, nodes[onode, NODE_SLOT] + SL_PSI, 6, n)
        for a in range(6):
            s_ = 0.0
            for rr in range(n):
                s_ += Pc[a, rr] * udot[u0 + nu + rr]
            A[a] -= s_


# ---------------------------------------------------------------------------------------- forward dynamics
@njit(cache=True, inline="always")
def _spd_inverse(D, n, tol, L, out):
    """Inverse of the leading n x n block of a symmetric positive definite matrix, into ``out``.

    Cholesky ``D = L L^T`` (``L`` a scratch matrix), then one forward and one back substitution per
    column. Returns False when a pivot is not above ``tol`` (a numerically singular articulated
    inertia: D is assembled from the entries of IA, so a pivot below ~eps * trace(IA) is round-off)."""
    if n == 1:
        if not D[0, 0] > tol:
            return False
        out[0, 0] = 1.0 / D[0, 0]
        return True
    for j in range(n):
        s = D[j, j]
        for k in range(j):
            s -= L[j, k] * L[j, k]
        if not s > tol:
            return False
        L[j, j] = np.sqrt(s)
        for i in range(j + 1, n):
            s = D[i, j]
            for k in range(j):
                s -= L[i, k] * L[j, k]
            L[i, j] = s / L[j, j]
    for j in range(n):
        for i in range(n):
            s = 1.0 if i == j else 0.0
            for k in range(i):
                s -= L[i, k] * out[k, j]
            out[i, j] = s / L[i, i]
        for i in range(n - 1, -1, -1):
            s = out[i, j]
            for k in range(i + 1, n):
                s -= L[k, i] * out[k, j]
            out[i, j] = s / L[i, i]
    return True


@njit(cache=True, inline="always")
def _eliminate_hinge(i, topology, tau, ws_mat, ws_vec):
    """Articulated-body step of body i's free hinge DOFs (RBDA Table 7.1): U = IA S, D = S' U,
    d = tau - S' pA, Ia = IA - U D^-1 U', pa = pA + Ia c + U D^-1 d (the last two only for a body with a
    parent: what a root would pass inward is never read). False when D is singular."""
    S = ws_mat[i, MAT_S]
    IA = ws_mat[i, MAT_IA]
    U = ws_mat[i, MAT_U]
    Dinv = ws_mat[i, MAT_DINV]
    Ia = ws_mat[i, MAT_IAP]
    pA = ws_vec[i, VEC_P]
    c = ws_vec[i, VEC_C]
    d = ws_vec[i, VEC_D]
    pa = ws_vec[i, VEC_AUX]
    nf = topology[i, N_FREE]
    u0 = topology[i, U_START]
    if nf == 1:
        # the common 1-DOF hinge without the loops over DOFs (the same operations in the same order)
        k = topology[i, FREE_DOFS]
        D0 = 0.0
        d0 = tau[u0 + k]
        for a in range(6):
            s = 0.0
            for b in range(6):
                s += IA[a, b] * S[b, k]
            U[a, 0] = s
        for a in range(6):
            D0 += S[a, k] * U[a, 0]
            d0 -= S[a, k] * pA[a]
        d[0] = d0
        if not D0 > 1e-14 * (IA[0, 0] + IA[1, 1] + IA[2, 2] + IA[3, 3] + IA[4, 4] + IA[5, 5]):
            return False
        dinv = 1.0 / D0
        Dinv[0, 0] = dinv
        for a in range(6):
            for b in range(a, 6):
                s = IA[a, b] - U[a, 0] * (dinv * U[b, 0])
                Ia[a, b] = s
                Ia[b, a] = s
        mat6_vec(Ia, c, pa)
        t = dinv * d0
        for a in range(6):
            pa[a] += pA[a]
            pa[a] += U[a, 0] * t
        return True
    for kk in range(nf):
        k = topology[i, FREE_DOFS + kk]
        for a in range(6):
            s = 0.0
            for b in range(6):
                s += IA[a, b] * S[b, k]
            U[a, kk] = s
    D = ws_mat[i, MAT_TMP]
    for kk in range(nf):
        k = topology[i, FREE_DOFS + kk]
        for ll in range(nf):
            s = 0.0
            for a in range(6):
                s += S[a, k] * U[a, ll]
            D[kk, ll] = s
        s = tau[u0 + k]
        for a in range(6):
            s -= S[a, k] * pA[a]
        d[kk] = s
    if nf > 0:
        tol = 1e-14 * (IA[0, 0] + IA[1, 1] + IA[2, 2] + IA[3, 3] + IA[4, 4] + IA[5, 5])
        if not _spd_inverse(D, nf, tol, ws_mat[i, MAT_IAP], Dinv):
            return False
    if topology[i, PARENT] < 0 and topology[i, PARENT_NODE] < 0:
        return True  # a root body passes nothing inward: Ia, pa are never read (skips 6 x 6 x nf^2 work)
    for a in range(6):
        for b in range(a, 6):
            s = IA[a, b]
            for kk in range(nf):
                t = 0.0
                for ll in range(nf):
                    t += Dinv[kk, ll] * U[b, ll]
                s -= U[a, kk] * t
            Ia[a, b] = s
            Ia[b, a] = s
    mat6_vec(Ia, c, pa)
    for a in range(6):
        pa[a] += pA[a]
    for kk in range(nf):
        t = 0.0
        for ll in range(nf):
            t += Dinv[kk, ll] * d[ll]
        for a in range(6):
            pa[a] += U[a, kk] * t
    return True


@njit(cache=True)
def _woodbury_rows(i, b, topology, nodes, pool, n, inverse):
    """Row block b of L = [Psi_1; ...; Psi_m; Pc; M_re] (or, with ``inverse``, of L G^-1) of body i."""
    nd = topology[i, FIRST_SLOT]
    k = 0
    shift = 6 * n if inverse else 0
    while nd >= 0:
        if k == b:
            return _view(pool, nodes[nd, NODE_SLOT] + SL_PSI + shift, 6, n)
        k += 1
        nd = nodes[nd, NODE_NEXT_SLOT]
    if b == k:
        return _view(pool, nodes[topology[i, OUTBOARD_NODE], NODE_SLOT] + SL_PSI + shift, 6, n)
    return _view(pool, topology[i, FLEX + (FK.FX_P_ZM if inverse else FK.FX_P_MRE)], 6, n)


@njit(cache=True)
def _gauss_solve(Aug, r, m):
    """Solve ``Aug[:, :r] X = Aug[:, r:r + m]`` in place (Gaussian elimination with partial pivoting, the
    solution left in ``Aug[:, r:]``); False when a pivot is negligible against the matrix."""
    scale = 0.0
    for a in range(r):
        for b in range(r):
            scale = max(scale, abs(Aug[a, b]))
    for col in range(r):
        piv = col
        big = abs(Aug[col, col])
        for row in range(col + 1, r):
            if abs(Aug[row, col]) > big:
                big = abs(Aug[row, col])
                piv = row
        if not big > 1e-14 * scale:
            return False
        if piv != col:
            for b in range(col, r + m):
                t = Aug[col, b]
                Aug[col, b] = Aug[piv, b]
                Aug[piv, b] = t
        for row in range(col + 1, r):
            f = Aug[row, col] / Aug[col, col]
            if f != 0.0:
                for b in range(col, r + m):
                    Aug[row, b] -= f * Aug[col, b]
    for col in range(r - 1, -1, -1):
        for b in range(r, r + m):
            s_ = Aug[col, b]
            for k in range(col + 1, r):
                s_ -= Aug[col, k] * Aug[k, b]
            Aug[col, b] = s_ / Aug[col, col]
    return True


@njit(cache=True)
def _psd_factor(Y, L, piv):
    """Pivoted Cholesky of a symmetric positive semidefinite 6 x 6 ``Y`` (read-only here):
    ``Y[piv[a], piv[b]] = (L L')[a, b]`` with ``L`` lower triangular; columns past the numerical rank
    (pivot below 1e-14 of the largest diagonal entry, round-off for an articulated inertia) are zero.
    ``L`` is used as the working copy; ``piv`` receives the permutation (as floats)."""
    for a in range(6):
        piv[a] = a
        for b in range(6):
            L[a, b] = Y[a, b]
    biggest = 0.0
    for a in range(6):
        biggest = max(biggest, L[a, a])
    for k in range(6):
        j = k
        for a in range(k + 1, 6):
            if L[a, a] > L[j, j]:
                j = a
        if j != k:
            for b in range(6):
                t = L[k, b]
                L[k, b] = L[j, b]
                L[j, b] = t
            for a in range(6):
                t = L[a, k]
                L[a, k] = L[a, j]
                L[a, j] = t
            t = piv[k]
            piv[k] = piv[j]
            piv[j] = t
        if not L[k, k] > 1e-14 * biggest:
            for a in range(k, 6):
                for b in range(k, 6):
                    L[a, b] = 0.0
            break
        d = np.sqrt(L[k, k])
        L[k, k] = d
        for a in range(k + 1, 6):
            L[a, k] /= d
        for a in range(k + 1, 6):  # the whole trailing block, so that later swaps see it symmetric
            for b in range(k + 1, 6):
                L[a, b] -= L[a, k] * L[b, k]
    for a in range(6):
        for b in range(a + 1, 6):
            L[a, b] = 0.0


@njit(cache=True)
def _symmetric_eigen(A, r, V):
    """Cyclic Jacobi eigen-decomposition of the symmetric ``A`` (r x r): on return ``A`` is diagonal with
    the eigenvalues and ``A_in = V diag(A) V'`` (accurate to round-off relative to the largest entry)."""
    for a in range(r):
        for b in range(r):
            V[a, b] = 1.0 if a == b else 0.0
    for sweep in range(60):
        off = 0.0
        scale = 0.0
        for a in range(r):
            scale += A[a, a] * A[a, a]
            for b in range(a + 1, r):
                off += A[a, b] * A[a, b]
        if off <= 1e-32 * (scale + off):
            return
        for p in range(r - 1):
            for q in range(p + 1, r):
                apq = A[p, q]
                if apq == 0.0:
                    continue
                theta = (A[q, q] - A[p, p]) / (2.0 * apq)
                if abs(theta) > 1e150:
                    t = 0.5 / theta
                else:
                    t = (1.0 if theta >= 0.0 else -1.0) / (abs(theta) + np.sqrt(theta * theta + 1.0))
                c = 1.0 / np.sqrt(t * t + 1.0)
                s = t * c
                for k in range(r):
                    akp = A[k, p]
                    akq = A[k, q]
                    A[k, p] = c * akp - s * akq
                    A[k, q] = s * akp + c * akq
                for k in range(r):
                    apk = A[p, k]
                    aqk = A[q, k]
                    A[p, k] = c * apk - s * aqk
                    A[q, k] = s * apk + c * aqk
                for k in range(r):
                    vkp = V[k, p]
                    vkq = V[k, q]
                    V[k, p] = c * vkp - s * vkq
                    V[k, q] = s * vkp + c * vkq


@njit(cache=True)
def _condense_modes(i, topology, nodes, params, tau, ws_mat, ws_vec, pool):
    """Eliminate the modal DOFs of flexible body i before its hinge DOFs (forward dynamics, pass 2).

    With the articulated inertia ``IA = [[A, B], [B', E]]`` of the body and its children (A 6 x 6, B 6 x n,
    E n x n) and the modal subspace ``H_m = [-Pc; I]``: ``B' = B - A Pc``, ``E' = H_m' IA H_m``, and the
    body's rigid block after the modal elimination is ``A'' = A - B' E'^-1 B''``. Children hang from nodes
    j with ``Psi_j`` and pass ``Y_j`` (their articulated inertia) and ``g_j`` (force), so ``A = A0 + sum Y_j``,
    ``B = M_re + sum Y_j Psi_j`` and

        E' = G + L' Q L,  L = [Psi_1; ...; Psi_m; Pc; M_re],
        Q = [[Y_j on the diagonal, -Y_j against Pc], [-Y_j, A, -I], [0, -I, 0]]

    (rank 6 m, plus 12 with Pc). Woodbury in symmetric form: with ``Q = V diag(lam) V'``,
    ``U = |lam|^1/2 V' L`` and ``S = sign(lam)``, ``E' = G + U' S U`` and
    ``E'^-1 v = G^-1 v - Z' (S + U Z')^-1 U G^-1 v``, ``Z = U G^-1`` (r x r solve), where
    ``Psi_j G^-1`` comes from the precomputed ``Pi G^-1`` in O(n)
    (:func:`dynamics.flexible_kernels.psi_times_inverse_modal_mass`). The symmetric form matters: with
    heavy children (``|Q K|`` >> 1) the textbook ``(I + Q K)^-1`` is ill-conditioned even when E' is not
    (a 500 kg mass on a beam tip: condition 6e5, Schur complement wrong in the 11th digit, against 60
    and the 15th digit here). Writes ``A''`` into
    ``ws_mat[i, MAT_IA]``, the rigid force after the modal elimination ``pA + sum g_j + B' E'^-1 d_m``
    into ``ws_vec[i, VEC_P]`` (so that the rigid hinge step follows unchanged), and keeps
    ``W' = B' E'^-1`` and ``y = E'^-1 d_m`` for the acceleration pass: ``etaddot = y - W' a``.
    Returns False when the modal mass is singular."""
    n = topology[i, N_MODES]
    A = ws_mat[i, MAT_IA]
    pA = ws_vec[i, VEC_P]
    nd = topology[i, FIRST_SLOT]
    while nd >= 0:
        s = nodes[nd, NODE_SLOT]
        for a in range(6):
            pA[a] += pool[s + SL_G + a]
            for b in range(6):
                A[a, b] += pool[s + SL_Y + 6 * a + b]
        nd = nodes[nd, NODE_NEXT_SLOT]
    if n == 0:
        return True
    fx = topology[i, FLEX:FLEX + FK.N_FX]
    onode = topology[i, OUTBOARD_NODE]
    Mre = _view(pool, fx[FK.FX_P_MRE], 6, n)
    ZM = _view(pool, fx[FK.FX_P_ZM], 6, n)
    Gm = _view(pool, fx[FK.FX_P_G], n, n)
    if fx[FK.FX_GINV_KIND] == GINV_FACTORED:
        if FK.cholesky_in_place(Gm, n) >= 0:
            return False
        nd = topology[i, FIRST_SLOT]
        while nd >= 0:
            s = nodes[nd, NODE_SLOT]
            FK.modal_mass_solve_rows(fx, params, n, Gm, _view(pool, s + SL_PSI, 6, n), 6,
                                     _view(pool, s + SL_PSI + 6 * n, 6, n))
            nd = nodes[nd, NODE_NEXT_SLOT]
        if onode >= 0:
            s = nodes[onode, NODE_SLOT]
            FK.modal_mass_solve_rows(fx, params, n, Gm, _view(pool, s + SL_PSI, 6, n), 6,
                                     _view(pool, s + SL_PSI + 6 * n, 6, n))
        FK.modal_mass_solve_rows(fx, params, n, Gm, Mre, 6, ZM)
    elif fx[FK.FX_C1] >= 0 or fx[FK.FX_F2] >= 0:
        FK.modal_mass_solve_rows(fx, params, n, Gm, Mre, 6, ZM)
    else:
        o = fx[FK.FX_ZM0]
        for a in range(6):
            for s in range(n):
                ZM[a, s] = params[o + a * n + s]
    # B' = M_re - A Pc + sum_j Y_j Psi_j, and B' G^-1 (kept in the W' block, solved in place below)
    Bp = _view(pool, fx[FK.FX_P_BP], 6, n)
    W = _view(pool, fx[FK.FX_P_W], 6, n)
    for a in range(6):
        for s in range(n):
            Bp[a, s] = Mre[a, s]
            W[a, s] = ZM[a, s]
    if onode >= 0:
        so = nodes[onode, NODE_SLOT]
        Pc = _view(pool, so + SL_PSI, 6, n)
        Zc = _view(pool, so + SL_PSI + 6 * n, 6, n)
        for a in range(6):
            for b in range(6):
                y_ = A[a, b]
                for s in range(n):
                    Bp[a, s] -= y_ * Pc[b, s]
                    W[a, s] -= y_ * Zc[b, s]
    nd = topology[i, FIRST_SLOT]
    while nd >= 0:
        so = nodes[nd, NODE_SLOT]
        Psi = _view(pool, so + SL_PSI, 6, n)
        Z = _view(pool, so + SL_PSI + 6 * n, 6, n)
        for a in range(6):
            for b in range(6):
                y_ = pool[so + SL_Y + 6 * a + b]
                for s in range(n):
                    Bp[a, s] += y_ * Psi[b, s]
                    W[a, s] += y_ * Z[b, s]
        nd = nodes[nd, NODE_NEXT_SLOT]
    # G^-1 d_m, d_m = tau_m - (modal bias - applied modal forces) - sum_j Psi_j' g_j + Pc' pA
    pv = fx[FK.FX_P_VEC]
    u_eta = topology[i, U_START] + topology[i, NU_HINGE]
    rhs = _view(pool, pv + PV_TMP * n, 1, n)
    Gd = _view(pool, pv + PV_RHS * n, 1, n)
    for s in range(n):
        rhs[0, s] = tau[u_eta + s] - pool[pv + PV_FORCE * n + s]
    FK.modal_mass_solve_rows(fx, params, n, Gm, rhs, 1, Gd)
    nd = topology[i, FIRST_SLOT]
    while nd >= 0:
        so = nodes[nd, NODE_SLOT]
        Z = _view(pool, so + SL_PSI + 6 * n, 6, n)
        for b in range(6):
            g = pool[so + SL_G + b]
            for s in range(n):
                Gd[0, s] -= Z[b, s] * g
        nd = nodes[nd, NODE_NEXT_SLOT]
    if onode >= 0:
        Zc = _view(pool, nodes[onode, NODE_SLOT] + SL_PSI + 6 * n, 6, n)
        for b in range(6):
            for s in range(n):
                Gd[0, s] += Zc[b, s] * pA[b]
    y = pool[pv + PV_Y * n:pv + (PV_Y + 1) * n]
    for s in range(n):
        y[s] = Gd[0, s]
    r = fx[FK.FX_RANK]
    if r > 0:
        # E' = G + L' Q L = G + U' S U with Q = V diag(lam) V' (Jacobi), U = |lam|^1/2 V' L, S = sign(lam);
        # E'^-1 v = G^-1 v - Z' C^-1 (U G^-1 v), Z = U G^-1, C = S + U Z' (symmetric, and positive definite
        # with condition number of the order of E''s when Q is: the children's inertias, no Pc)
        so = fx[FK.FX_P_SMALL]
        Vq = _view(pool, so, r, r)
        Q = _view(pool, so + r * r, r, r)
        Aug = _view(pool, so + 2 * r * r, r, r + 7)
        Ut = _view(pool, so + 3 * r * r + 7 * r, r, n)
        Zt = _view(pool, so + 3 * r * r + 7 * r + r * n, r, n)
        for a in range(r):
            for b in range(r):
                Q[a, b] = 0.0
        blocks = r // 6
        m = blocks - 2 if onode >= 0 else blocks
        nd = topology[i, FIRST_SLOT]
        j = 0
        while nd >= 0:
            sl = nodes[nd, NODE_SLOT]
            for a in range(6):
                for b in range(6):
                    y_ = pool[sl + SL_Y + 6 * a + b]
                    Q[6 * j + a, 6 * j + b] = y_
                    if onode >= 0:
                        Q[6 * j + a, 6 * m + b] = -y_
                        Q[6 * m + a, 6 * j + b] = -y_
            j += 1
            nd = nodes[nd, NODE_NEXT_SLOT]
        if onode >= 0:
            for a in range(6):
                for b in range(6):
                    Q[6 * m + a, 6 * m + b] = A[a, b]
                Q[6 * m + a, 6 * m + 6 + a] = -1.0
                Q[6 * m + 6 + a, 6 * m + a] = -1.0
        for k in range(r):
            for s in range(n):
                Ut[k, s] = 0.0
                Zt[k, s] = 0.0
        if onode < 0:
            # Q = blockdiag(Y_j), each positive semidefinite: Y_j = P L L' P' (pivoted Cholesky), U_j = L' P' Psi_j
            for b in range(blocks):
                L = _view(pool, so + 36 * b, 6, 6)  # in the V block (r^2 >= 36 blocks)
                piv = pool[P_TMP83:P_TMP83 + 6]
                _psd_factor(Q[6 * b:6 * b + 6, 6 * b:6 * b + 6], L, piv)
                Lb = _woodbury_rows(i, b, topology, nodes, pool, n, False)
                Zb = _woodbury_rows(i, b, topology, nodes, pool, n, True)
                for k in range(6):
                    for a in range(6):
                        v_ = L[a, k]
                        if v_ != 0.0:
                            pa_ = int(piv[a])
                            for s in range(n):
                                Ut[6 * b + k, s] += v_ * Lb[pa_, s]
                                Zt[6 * b + k, s] += v_ * Zb[pa_, s]
                for k in range(6):
                    Q[6 * b + k, 6 * b + k] = 1.0  # the signs S
        else:
            # with Pc, Q is indefinite: Q = V diag(lam) V' (Jacobi), U = |lam|^1/2 V' L, S = sign(lam)
            _symmetric_eigen(Q, r, Vq)
            for b in range(blocks):
                Lb = _woodbury_rows(i, b, topology, nodes, pool, n, False)
                Zb = _woodbury_rows(i, b, topology, nodes, pool, n, True)
                for k in range(r):
                    root = np.sqrt(abs(Q[k, k]))
                    for a in range(6):
                        v_ = Vq[6 * b + a, k] * root
                        if v_ != 0.0:
                            for s in range(n):
                                Ut[k, s] += v_ * Lb[a, s]
                                Zt[k, s] += v_ * Zb[a, s]
        for a in range(r):
            for b in range(a, r):
                t = 0.0
                for s in range(n):
                    t += Ut[a, s] * Zt[b, s]
                if a == b:
                    t += 1.0 if Q[a, a] >= 0.0 else -1.0
                Aug[a, b] = t
                Aug[b, a] = t
            for c in range(6):
                t = 0.0
                for s in range(n):
                    t += Ut[a, s] * W[c, s]
                Aug[a, r + c] = t
            t = 0.0
            for s in range(n):
                t += Ut[a, s] * Gd[0, s]
            Aug[a, r + 6] = t
        if not _gauss_solve(Aug, r, 7):
            return False
        for k in range(r):
            for c in range(6):
                x_ = Aug[k, r + c]
                for s in range(n):
                    W[c, s] -= x_ * Zt[k, s]
            x_ = Aug[k, r + 6]
            for s in range(n):
                y[s] -= x_ * Zt[k, s]
    # A'' = A - B' W'' (symmetric by construction), pA + B' y
    for a in range(6):
        for b in range(a, 6):
            t = 0.0
            for s in range(n):
                t += Bp[a, s] * W[b, s]
            v = A[a, b] - t
            A[a, b] = v
            A[b, a] = v
        t = 0.0
        for s in range(n):
            t += Bp[a, s] * y[s]
        pA[a] += t
    return True


@njit(cache=True)
def _to_slot(i, topology, nodes, Ia, pa, ws_rot, ws_vec, ws_mat, pool):
    """Add body i's articulated inertia and force to the slot of the flexible parent's node it hangs from
    (summed there per node for :func:`_condense_modes`)."""
    slot = nodes[topology[i, PARENT_NODE], NODE_SLOT]
    inertia_to_parent_add(ws_rot[i, ROT_PB], ws_vec[i, VEC_POS], Ia, _view(pool, slot + SL_Y, 6, 6), ws_mat[i, MAT_TMP])
    force_to_parent_add(ws_rot[i, ROT_PB], ws_vec[i, VEC_POS], pa, pool[slot + SL_G:slot + SL_G + 6])


@njit(cache=True)
def _modal_accelerations(i, topology, nodes, tau, udot, tau_out, ws_vec, pool):
    """Forward dynamics, pass 3, flexible body i: modal accelerations ``y - W' a`` (``a`` the rigid
    acceleration before the modal DOFs), then the ``-Pc etaddot`` of a hinge on a node of the body."""
    n = topology[i, N_MODES]
    A = ws_vec[i, VEC_A]
    pv = topology[i, FLEX + FK.FX_P_VEC]
    W = _view(pool, topology[i, FLEX + FK.FX_P_W], 6, n)
    ue = topology[i, U_START] + topology[i, NU_HINGE]
    for s in range(n):
        t = pool[pv + PV_Y * n + s]
        for a in range(6):
            t -= W[a, s] * A[a]
        udot[ue + s] = t
        tau_out[ue + s] = tau[ue + s]
    onode = topology[i, OUTBOARD_NODE]
    if onode >= 0:
        Pc = _view(pool, nodes[onode, NODE_SLOT] + SL_PSI, 6, n)
        for a in range(6):
            t = 0.0
            for s in range(n):
                t += Pc[a, s] * udot[ue + s]
            A[a] -= t


@njit(cache=True)
def _flexible_inertia_and_bias(i, topology, params, q, u, body_forces, ws_vec, ws_mat, pool):
    """Pass 1 of the ABA at a flexible body: IA = M_rr(eta) and pA = b - f_ext (modal rows in the pool)."""
    _flexible_body_terms(i, topology, params, q, u, ws_vec, ws_mat, pool, True,
                         topology[i, FLEX + FK.FX_GINV_KIND] == GINV_FACTORED)
    IA = ws_mat[i, MAT_IA]
    pA = ws_vec[i, VEC_P]
    M = _view(pool, topology[i, FLEX + FK.FX_P_MRR], 6, 6)
    for a in range(6):
        pA[a] -= body_forces[i, a]
        for b in range(6):
            IA[a, b] = M[a, b]


@njit(cache=True)
def forward_dynamics(topology, nodes, joint_rot, joint_vec, params, q, u, tau, node_forces, body_forces, udot,
                     tau_out, ws_rot, ws_vec, ws_mat, pool):
    """Articulated-body forward dynamics with prescribed DOFs (module docstring).

    On entry ``udot`` holds the prescribed accelerations at the prescribed DOFs (other entries are
    ignored); on exit it holds all accelerations. ``tau`` gives the generalized forces of the free DOFs
    (modal DOFs are always free: ``tau`` there is an applied modal force); ``tau_out`` receives ``tau`` at
    free DOFs and the generalized force realizing the prescribed motion at prescribed DOFs. Returns 0, or
    1 + the index of the first body whose articulated inertia is singular. On exit the workspace holds
    every body's pose, velocity and acceleration (the latter including the ground's ``[0; -g]``).

    Rigid bodies on fixed frames run inline 6 x 6 code (the rigid fast path); the augmented path's steps
    (kinematics through deforming nodes, modal terms, modal elimination, slots) are calls.
    """
    nb = topology.shape[0]
    ground = params[GROUND_ACCEL:GROUND_ACCEL + 6]
    for i in range(nb):
        if topology[i, GENERAL]:
            _general_kinematics(i, topology, nodes, joint_rot, joint_vec, params, q, u, ws_rot, ws_vec, ws_mat, pool,
                                True)
        else:
            _rigid_position(i, topology, joint_rot, joint_vec, q, ws_rot, ws_vec, ws_mat)
            _rigid_velocity(i, topology, joint_vec, u, ws_rot, ws_vec, ws_mat)
        S = ws_mat[i, MAT_S]
        c = ws_vec[i, VEC_C]
        u0 = topology[i, U_START]
        for kk in range(topology[i, N_PRESCRIBED]):
            k = topology[i, PRESCRIBED_DOFS + kk]
            acc = udot[u0 + k]
            for a in range(6):
                c[a] += S[a, k] * acc
        if topology[i, FLEXIBLE]:
            _flexible_inertia_and_bias(i, topology, params, q, u, body_forces, ws_vec, ws_mat, pool)
            continue
        IA = ws_mat[i, MAT_IA]
        pA = ws_vec[i, VEC_P]
        o = topology[i, INERTIA]
        for a in range(6):
            for b in range(6):
                IA[a, b] = params[o + 6 * a + b]
            pA[a] = -body_forces[i, a]
        rigid_bias_add(params, o, ws_vec[i, VEC_V], pA)
    _apply_node_forces(topology, nodes, params, q, node_forces, ws_vec, pool, -1.0)

    for i in range(nb - 1, -1, -1):
        if topology[i, FLEXIBLE]:
            if not _condense_modes(i, topology, nodes, params, tau, ws_mat, ws_vec, pool):
                return 1 + i
        if not _eliminate_hinge(i, topology, tau, ws_mat, ws_vec):
            return 1 + i
        parent = topology[i, PARENT]
        if topology[i, PARENT_NODE] >= 0:
            _to_slot(i, topology, nodes, ws_mat[i, MAT_IAP], ws_vec[i, VEC_AUX], ws_rot, ws_vec, ws_mat, pool)
        elif parent >= 0:
            R = ws_rot[i, ROT_PB]
            r = ws_vec[i, VEC_POS]
            inertia_to_parent_add(R, r, ws_mat[i, MAT_IAP], ws_mat[parent, MAT_IA], ws_mat[i, MAT_TMP])
            force_to_parent_add(R, r, ws_vec[i, VEC_AUX], ws_vec[parent, VEC_P])

    for i in range(nb):
        A = ws_vec[i, VEC_A]
        parent = topology[i, PARENT]
        if topology[i, GENERAL]:
            _parent_acceleration_general(i, topology, nodes, ground, udot, ws_rot, ws_vec, pool, A)
        elif parent >= 0:
            motion_to_child(ws_rot[i, ROT_PB], ws_vec[i, VEC_POS], ws_vec[parent, VEC_A], A)
        else:
            motion_to_child(ws_rot[i, ROT_PB], ws_vec[i, VEC_POS], ground, A)
        c = ws_vec[i, VEC_C]
        for a in range(6):
            A[a] += c[a]
        S = ws_mat[i, MAT_S]
        U = ws_mat[i, MAT_U]
        Dinv = ws_mat[i, MAT_DINV]
        d = ws_vec[i, VEC_D]
        nf = topology[i, N_FREE]
        u0 = topology[i, U_START]
        # udot_free = Dinv (d - U^T A'), then A = A' + S_free udot_free
        if nf == 1:
            k = topology[i, FREE_DOFS]
            t = d[0]
            for a in range(6):
                t -= U[a, 0] * A[a]
            acc = 0.0 + Dinv[0, 0] * t
            udot[u0 + k] = acc
            tau_out[u0 + k] = tau[u0 + k]
            for a in range(6):
                A[a] += S[a, k] * acc
            nf = 0
        for kk in range(nf):
            s = 0.0
            for ll in range(nf):
                t = d[ll]
                for a in range(6):
                    t -= U[a, ll] * A[a]
                s += Dinv[kk, ll] * t
            k = topology[i, FREE_DOFS + kk]
            udot[u0 + k] = s
            tau_out[u0 + k] = tau[u0 + k]
        for kk in range(nf):
            k = topology[i, FREE_DOFS + kk]
            acc = udot[u0 + k]
            for a in range(6):
                A[a] += S[a, k] * acc
        npres = topology[i, N_PRESCRIBED]
        if npres > 0:
            f = ws_vec[i, VEC_AUX]
            mat6_vec(ws_mat[i, MAT_IA], A, f)
            pA = ws_vec[i, VEC_P]
            for kk in range(npres):
                k = topology[i, PRESCRIBED_DOFS + kk]
                s = 0.0
                for a in range(6):
                    s += S[a, k] * (f[a] + pA[a])
                tau_out[u0 + k] = s
        if topology[i, N_MODES] > 0:
            _modal_accelerations(i, topology, nodes, tau, udot, tau_out, ws_vec, pool)
    return 0


@njit(cache=True)
def forward_dynamics_dense(topology, nodes, joint_rot, joint_vec, params, q, u, tau, node_forces, body_forces, udot,
                           tau_out, ws_rot, ws_vec, ws_mat, pool):
    """The contract of :func:`forward_dynamics` solved densely: ``h`` from :func:`inverse_dynamics` at the
    prescribed accelerations, ``M`` from :func:`mass_matrix`, then ``M_ff udot_f = tau_f - h_f`` by a
    Cholesky factorization of M with its prescribed rows and columns replaced by the identity; the
    prescribed DOFs' forces from a second inverse dynamics when there are any. O(nu^3); uses the last
    ``nu^2 + 2 nu`` numbers of ``pool``. Returns 0, or 1 + the index of the body owning a DOF at which
    the mass matrix is singular."""
    nb = topology.shape[0]
    last = nb - 1
    nu = topology[last, U_START] + topology[last, NU_HINGE] + topology[last, N_MODES]
    base = pool.shape[0] - nu * nu - 2 * nu
    M = _view(pool, base, nu, nu)
    h = pool[base + nu * nu:base + nu * nu + nu]
    a0 = pool[base + nu * nu + nu:base + nu * nu + 2 * nu]
    for k in range(nu):
        a0[k] = 0.0
    npres = 0
    for i in range(nb):
        u0 = topology[i, U_START]
        for kk in range(topology[i, N_PRESCRIBED]):
            k = u0 + topology[i, PRESCRIBED_DOFS + kk]
            a0[k] = udot[k]
            npres += 1
    inverse_dynamics(topology, nodes, joint_rot, joint_vec, params, q, u, a0, node_forces, body_forces, h, ws_rot,
                     ws_vec, ws_mat, pool)
    mass_matrix(topology, nodes, joint_rot, joint_vec, params, q, u, M, ws_rot, ws_vec, ws_mat, pool)
    for k in range(nu):
        h[k] = tau[k] - h[k]
    for i in range(nb):
        u0 = topology[i, U_START]
        for kk in range(topology[i, N_PRESCRIBED]):
            k = u0 + topology[i, PRESCRIBED_DOFS + kk]
            for j in range(nu):
                M[k, j] = 0.0
                M[j, k] = 0.0
            M[k, k] = 1.0
            h[k] = 0.0
    bad = FK.cholesky_in_place(M, nu)
    if bad >= 0:
        for i in range(nb):
            if bad < topology[i, U_START] + topology[i, NU_HINGE] + topology[i, N_MODES]:
                return 1 + i
    for s in range(nu):
        t = h[s]
        for k in range(s):
            t -= M[s, k] * h[k]
        h[s] = t / M[s, s]
    for s in range(nu - 1, -1, -1):
        t = h[s]
        for k in range(s + 1, nu):
            t -= M[k, s] * h[k]
        h[s] = t / M[s, s]
    for k in range(nu):
        udot[k] = h[k]
        tau_out[k] = tau[k]
    for i in range(nb):
        u0 = topology[i, U_START]
        for kk in range(topology[i, N_PRESCRIBED]):
            k = u0 + topology[i, PRESCRIBED_DOFS + kk]
            udot[k] = a0[k]
    if npres > 0:
        inverse_dynamics(topology, nodes, joint_rot, joint_vec, params, q, u, udot, node_forces, body_forces, a0,
                         ws_rot, ws_vec, ws_mat, pool)
        for i in range(nb):
            u0 = topology[i, U_START]
            for kk in range(topology[i, N_PRESCRIBED]):
                k = u0 + topology[i, PRESCRIBED_DOFS + kk]
                tau_out[k] = a0[k]
    else:
        _accelerations(topology, nodes, params[GROUND_ACCEL:GROUND_ACCEL + 6], udot, ws_rot, ws_vec, ws_mat, pool)
    return 0


# ---------------------------------------------------------------------------------------- inverse dynamics, CRBA
@njit(cache=True)
def inverse_dynamics(topology, nodes, joint_rot, joint_vec, params, q, u, udot, node_forces, body_forces, tau,
                     ws_rot, ws_vec, ws_mat, pool):
    """Recursive Newton-Euler in augmented form: F_i = M_i a_i + b_i - f_ext,i; tau_i = H_i' F_i;
    F_parent += P_i' F_i (module docstring)."""
    nb = topology.shape[0]
    ground = params[GROUND_ACCEL:GROUND_ACCEL + 6]
    for i in range(nb):
        _kinematics(i, topology, nodes, joint_rot, joint_vec, params, q, u, ws_rot, ws_vec, ws_mat, pool, True)
        A = ws_vec[i, VEC_A]
        _parent_acceleration(i, topology, nodes, ground, udot, ws_rot, ws_vec, pool, A)
        _add_hinge_acceleration(i, topology, nodes, udot, ws_vec, ws_mat, pool, A)
        f = ws_vec[i, VEC_P]
        if topology[i, FLEXIBLE]:
            n = topology[i, N_MODES]
            fx = topology[i, FLEX:FLEX + FK.N_FX]
            _flexible_body_terms(i, topology, params, q, u, ws_vec, ws_mat, pool, True,
                                 fx[FK.FX_GINV_KIND] == GINV_FACTORED)
            # F_r = b_r + M_rr a + M_re etaddot - f_ext, F_m = b_m + M_re' a + G etaddot
            M = _view(pool, topology[i, FLEX + FK.FX_P_MRR], 6, 6)
            Mre = _view(pool, fx[FK.FX_P_MRE], 6, n)
            ue = topology[i, U_START] + topology[i, NU_HINGE]
            am = udot[ue:ue + n]
            for a in range(6):
                s_ = 0.0
                for b in range(6):
                    s_ += M[a, b] * A[b]
                for s in range(n):
                    s_ += Mre[a, s] * am[s]
                f[a] += s_ - body_forces[i, a]
            pv = fx[FK.FX_P_VEC]
            Ga = pool[pv + PV_TMP * n:pv + (PV_TMP + 1) * n]
            FK.modal_mass_times(fx, params, n, _view(pool, fx[FK.FX_P_G], n, n), am, Ga)
            for s in range(n):
                t = Ga[s]
                for a in range(6):
                    t += Mre[a, s] * A[a]
                pool[pv + PV_FORCE * n + s] += t
        else:
            o = topology[i, INERTIA]
            for a in range(6):
                s_ = 0.0
                for b in range(6):
                    s_ += params[o + 6 * a + b] * A[b]
                f[a] = s_
            rigid_bias_add(params, o, ws_vec[i, VEC_V], f)
            for a in range(6):
                f[a] -= body_forces[i, a]
    _apply_node_forces(topology, nodes, params, q, node_forces, ws_vec, pool, -1.0)
    for i in range(nb - 1, -1, -1):
        S = ws_mat[i, MAT_S]
        f = ws_vec[i, VEC_P]
        u0 = topology[i, U_START]
        nu = topology[i, NU_HINGE]
        for k in range(nu):
            s_ = 0.0
            for a in range(6):
                s_ += S[a, k] * f[a]
            tau[u0 + k] = s_
        n = topology[i, N_MODES]
        if n > 0:
            pv = topology[i, FLEX + FK.FX_P_VEC]
            onode = topology[i, OUTBOARD_NODE]
            for s in range(n):
                t = pool[pv + PV_FORCE * n + s]
                if onode >= 0:
                    so = nodes[onode, NODE_SLOT] + SL_PSI
                    for a in range(6):
                        t -= pool[so + a * n + s] * f[a]
                tau[u0 + nu + s] = t
        parent = topology[i, PARENT]
        if parent >= 0:
            jnode = topology[i, PARENT_NODE]
            n_p = topology[parent, N_MODES]
            if jnode >= 0 and n_p > 0:
                y = pool[P_V1:P_V1 + 6]
                for a in range(6):
                    y[a] = 0.0
                force_to_parent_add(ws_rot[i, ROT_PB], ws_vec[i, VEC_POS], f, y)
                fp = ws_vec[parent, VEC_P]
                Psi = _view(pool, nodes[jnode, NODE_SLOT] + SL_PSI, 6, n_p)
                pv = topology[parent, FLEX + FK.FX_P_VEC] + PV_FORCE * n_p
                for a in range(6):
                    fp[a] += y[a]
                for s in range(n_p):
                    t = 0.0
                    for a in range(6):
                        t += Psi[a, s] * y[a]
                    pool[pv + s] += t
            else:
                force_to_parent_add(ws_rot[i, ROT_PB], ws_vec[i, VEC_POS], f, ws_vec[parent, VEC_P])


@njit(cache=True)
def mass_matrix(topology, nodes, joint_rot, joint_vec, params, q, u, M, ws_rot, ws_vec, ws_mat, pool):
    """Composite-rigid-body algorithm in augmented form: the joint-space mass matrix ``M`` (nu x nu,
    overwritten). The composite inertia of a flexible body ``Ic = M(eta) + sum_c P_c' Ic_c P_c`` keeps
    its full ``6 + n`` block; ``u`` only feeds velocity terms the result does not depend on."""
    nb = topology.shape[0]
    for i in range(nb):
        _kinematics(i, topology, nodes, joint_rot, joint_vec, params, q, u, ws_rot, ws_vec, ws_mat, pool, False)
        Ic = ws_mat[i, MAT_IA]
        if topology[i, FLEXIBLE]:
            _flexible_body_terms(i, topology, params, q, u, ws_vec, ws_mat, pool, False, True)
            Mrr = _view(pool, topology[i, FLEX + FK.FX_P_MRR], 6, 6)
            for a in range(6):
                for b in range(6):
                    Ic[a, b] = Mrr[a, b]
        else:
            o = topology[i, INERTIA]
            for a in range(6):
                for b in range(6):
                    Ic[a, b] = params[o + 6 * a + b]
    for i in range(nb - 1, -1, -1):
        parent = topology[i, PARENT]
        if parent < 0:
            continue
        jnode = topology[i, PARENT_NODE]
        n_p = topology[parent, N_MODES]
        if jnode >= 0 and n_p > 0:
            # Ic_p += [I, Psi]' Y [I, Psi], Y = X' Ic_rr X
            Y = ws_mat[i, MAT_IAP]
            for a in range(6):
                for b in range(6):
                    Y[a, b] = 0.0
            inertia_to_parent_add(ws_rot[i, ROT_PB], ws_vec[i, VEC_POS], ws_mat[i, MAT_IA], Y, ws_mat[i, MAT_TMP])
            Psi = _view(pool, nodes[jnode, NODE_SLOT] + SL_PSI, 6, n_p)
            fxp = topology[parent, FLEX:FLEX + FK.N_FX]
            Icre = _view(pool, fxp[FK.FX_P_MRE], 6, n_p)
            Icee = _view(pool, fxp[FK.FX_P_G], n_p, n_p)
            YPsi = _view(pool, fxp[FK.FX_P_BP], 6, n_p)
            Icp = ws_mat[parent, MAT_IA]
            for a in range(6):
                for b in range(6):
                    Icp[a, b] += Y[a, b]
                for s in range(n_p):
                    t = 0.0
                    for b in range(6):
                        t += Y[a, b] * Psi[b, s]
                    YPsi[a, s] = t
                    Icre[a, s] += t
            for s in range(n_p):
                for l in range(s, n_p):
                    t = 0.0
                    for a in range(6):
                        t += Psi[a, s] * YPsi[a, l]
                    Icee[s, l] += t
                    if l != s:
                        Icee[l, s] += t
        else:
            inertia_to_parent_add(ws_rot[i, ROT_PB], ws_vec[i, VEC_POS], ws_mat[i, MAT_IA], ws_mat[parent, MAT_IA],
                                  ws_mat[i, MAT_TMP])
    M[:, :] = 0.0
    for i in range(nb):
        nu_i = topology[i, NU_HINGE]
        n = topology[i, N_MODES]
        ncol = nu_i + n
        if ncol == 0:
            continue
        onode = topology[i, OUTBOARD_NODE]
        ui = topology[i, U_START]
        S = ws_mat[i, MAT_S]
        Ic = ws_mat[i, MAT_IA]
        fx = topology[i, FLEX:FLEX + FK.N_FX]
        F = _view(pool, fx[FK.FX_P_F], 6, ncol) if topology[i, FLEXIBLE] else ws_mat[i, MAT_U]
        Icre = _view(pool, fx[FK.FX_P_MRE], 6, n) if n > 0 else _view(pool, 0, 6, 0)
        Pc = _view(pool, nodes[onode, NODE_SLOT] + SL_PSI, 6, n) if onode >= 0 else _view(pool, 0, 6, 0)
        for k in range(nu_i):
            for a in range(6):
                s = 0.0
                for b in range(6):
                    s += Ic[a, b] * S[b, k]
                F[a, k] = s
        if n > 0:
            # modal columns: the rigid rows of Ic H_m = Ic_re - Ic_rr Pc
            for s in range(n):
                for a in range(6):
                    F[a, nu_i + s] = Icre[a, s]
            if onode >= 0:
                for s in range(n):
                    for a in range(6):
                        t = 0.0
                        for b in range(6):
                            t += Ic[a, b] * Pc[b, s]
                        F[a, nu_i + s] -= t
        for k in range(nu_i):
            for l in range(k, ncol):  # symmetric by construction, not by round-off
                s = 0.0
                for a in range(6):
                    s += S[a, k] * F[a, l]
                M[ui + k, ui + l] = s
                M[ui + l, ui + k] = s
        if n > 0:
            Icee = _view(pool, fx[FK.FX_P_G], n, n)
            um = ui + nu_i
            for s in range(n):
                for l in range(s, n):
                    v = Icee[s, l]
                    if onode >= 0:
                        for a in range(6):
                            v -= Pc[a, s] * F[a, nu_i + l] + Icre[a, s] * Pc[a, l]
                    M[um + s, um + l] = v
                    M[um + l, um + s] = v
        j = i
        while topology[j, PARENT] >= 0:
            for k in range(ncol):
                force_to_parent_inplace(ws_rot[j, ROT_PB], ws_vec[j, VEC_POS], F[:, k])
            jnode = topology[j, PARENT_NODE]
            j = topology[j, PARENT]
            nu_j = topology[j, NU_HINGE]
            uj = topology[j, U_START]
            Sj = ws_mat[j, MAT_S]
            for k in range(nu_j):
                for l in range(ncol):
                    s = 0.0
                    for a in range(6):
                        s += Sj[a, k] * F[a, l]
                    M[uj + k, ui + l] = s
                    M[ui + l, uj + k] = s
            n_j = topology[j, N_MODES]
            if n_j > 0:
                # modal rows of H_j' P' F: (Psi of the node the path hangs from - Pc_j)' F
                ponode = topology[j, OUTBOARD_NODE]
                um = uj + nu_j
                for s in range(n_j):
                    for l in range(ncol):
                        t = 0.0
                        if jnode >= 0:
                            so = nodes[jnode, NODE_SLOT] + SL_PSI
                            for a in range(6):
                                t += pool[so + a * n_j + s] * F[a, l]
                        if ponode >= 0:
                            so = nodes[ponode, NODE_SLOT] + SL_PSI
                            for a in range(6):
                                t -= pool[so + a * n_j + s] * F[a, l]
                        M[um + s, ui + l] = t
                        M[ui + l, um + s] = t


# ---------------------------------------------------------------------------------------- node kinematics, energy
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


@njit(cache=True)
def accumulate_world_poses(topology, ws_rot, ws_vec):
    """Body -> world rotations (``ws_rot[:, ROT_WB]``) and body origins in the world
    (``ws_vec[:, VEC_WPOS, 0:3]``) from the parent-relative poses."""
    for i in range(topology.shape[0]):
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
def _node_outputs(topology, nodes, params, q, u, udot, ground_linear, rotation, position, velocity, acceleration,
                  ws_rot, ws_vec, pool):
    """Per node, from the bodies' world poses, velocities and accelerations in the workspace (minus the
    uniform ``ground_linear`` acceleration they may include): pose, velocity and classical acceleration
    of the (deformed) node (see :func:`node_kinematics`)."""
    tmp83 = _view(pool, P_TMP83, 8, 3)
    w = pool[P_W:P_W + 6]
    wd = pool[P_WD:P_WD + 6]
    tmp = pool[P_V1:P_V1 + 6]
    Xw = pool[P_V2:P_V2 + 6]
    for nd in range(nodes.shape[0]):
        b = nodes[nd, NODE_BODY]
        n = topology[b, N_MODES]
        fr = nodes[nd, NODE_FRAME]
        if n > 0:
            qe = topology[b, Q_START] + topology[b, NQ_HINGE]
            ue = topology[b, U_START] + topology[b, NU_HINGE]
            Rn = _view(pool, P_R, 3, 3)
            l = pool[P_L:P_L + 3]
            Psi = _view(pool, POOL_HEADER, 6, n)
            FK.node_deformation(_view(params, nodes[nd, NODE_SHAPE], 6, n), params[fr + 9:fr + 12],
                                _view(params, fr, 3, 3), q[qe:qe + n], n, u[ue:ue + n], Rn, l, Psi, w, wd, tmp83)
        else:
            Rn = _view(params, fr, 3, 3)
            l = params[fr + 9:fr + 12]
        R_WB = ws_rot[b, ROT_WB]
        pw = ws_vec[b, VEC_WPOS]
        for a in range(3):
            position[nd, a] = pw[a] + R_WB[a, 0] * l[0] + R_WB[a, 1] * l[1] + R_WB[a, 2] * l[2]
            for k in range(3):
                rotation[nd, a, k] = R_WB[a, 0] * Rn[0, k] + R_WB[a, 1] * Rn[1, k] + R_WB[a, 2] * Rn[2, k]
        V = ws_vec[b, VEC_V]
        A = ws_vec[b, VEC_A]
        for a in range(3):
            tmp[a] = A[a]
            tmp[3 + a] = A[3 + a] - (R_WB[0, a] * ground_linear[0] + R_WB[1, a] * ground_linear[1]
                                     + R_WB[2, a] * ground_linear[2])
        if n > 0:
            ue = topology[b, U_START] + topology[b, NU_HINGE]
            for a in range(6):
                s_ = 0.0
                for rr in range(n):
                    s_ += Psi[a, rr] * udot[ue + rr]
                tmp[a] += s_ + wd[a]
            motion_to_child(Rn, l, tmp, acceleration[nd])
            for a in range(6):
                tmp[a] = V[a] + w[a]
            motion_to_child(Rn, l, tmp, velocity[nd])
            motion_to_child(Rn, l, w, Xw)
            motion_cross_motion_add(velocity[nd], Xw, acceleration[nd])
        else:
            motion_to_child(Rn, l, V, velocity[nd])
            motion_to_child(Rn, l, tmp, acceleration[nd])
        v = velocity[nd]
        acc = acceleration[nd]
        acc[3] += v[1] * v[5] - v[2] * v[4]
        acc[4] += v[2] * v[3] - v[0] * v[5]
        acc[5] += v[0] * v[4] - v[1] * v[3]


@njit(cache=True)
def node_kinematics(topology, nodes, joint_rot, joint_vec, params, q, u, udot, rotation, position, velocity,
                    acceleration, ws_rot, ws_vec, ws_mat, pool):
    """Pose, spatial velocity and acceleration of every node (a frame on a body, deforming with it).

    Outputs per node n: ``rotation[n]`` node -> world, ``position[n]`` in the world, ``velocity[n]`` the
    spatial velocity ``[omega; v]`` of the node frame in node axes (v: velocity of the node origin), and
    ``acceleration[n] = [omega_dot; a]`` in node axes with ``a`` the classical (not spatial) acceleration
    of the node origin, ``a = a_spatial + omega x v``. Accelerations are relative to the inertial frame:
    gravity is *not* included (an accelerometer reads ``a - g``).
    """
    nb = topology.shape[0]
    zero = pool[P_ZERO:P_ZERO + 6]
    for a in range(6):
        zero[a] = 0.0
    for i in range(nb):
        _kinematics(i, topology, nodes, joint_rot, joint_vec, params, q, u, ws_rot, ws_vec, ws_mat, pool, True)
        A = ws_vec[i, VEC_A]
        _parent_acceleration(i, topology, nodes, zero, udot, ws_rot, ws_vec, pool, A)
        _add_hinge_acceleration(i, topology, nodes, udot, ws_vec, ws_mat, pool, A)
    accumulate_world_poses(topology, ws_rot, ws_vec)
    _node_outputs(topology, nodes, params, q, u, udot, zero[0:3], rotation, position, velocity, acceleration,
                  ws_rot, ws_vec, pool)


@njit(cache=True)
def node_kinematics_after_dynamics(topology, nodes, joint_rot, joint_vec, params, q, u, udot, rotation, position,
                                   velocity, acceleration, ws_rot, ws_vec, ws_mat, pool):
    """:func:`node_kinematics` reusing the workspace of a :func:`forward_dynamics` (or
    :func:`forward_dynamics_dense`) call at the same ``q``, ``u`` that returned ``udot``: only the world
    poses and the per-node terms are computed (O(N + nodes x n)), and the ground's fictitious acceleration
    ``[0; -g]`` contained in the forward-dynamics accelerations is removed. Precondition (not checked):
    no other kernel used the workspace in between."""
    accumulate_world_poses(topology, ws_rot, ws_vec)
    _node_outputs(topology, nodes, params, q, u, udot, params[GROUND_ACCEL + 3:GROUND_ACCEL + 6], rotation, position,
                  velocity, acceleration, ws_rot, ws_vec, pool)


@njit(cache=True)
def accumulate_energy_momentum(Mrr, h, ke, R, p, ground_accel, out):
    """Add one body's kinetic energy ``ke / 2``, gravity potential and world momentum to ``out``.

    ``Mrr`` (rigid block ``[[J, m c~], [-m c~, m I]]`` of the body's mass matrix about its origin) gives
    the mass and centre of mass, ``h`` (6) the momentum's rigid rows (``M x``), ``R``/``p`` the world pose."""
    out[0] += 0.5 * ke
    m = Mrr[3, 3]
    # center of mass from the coupling block m skew(c): c = (M[2,4], M[0,5], M[1,3]) / m
    cx = Mrr[2, 4] / m
    cy = Mrr[0, 5] / m
    cz = Mrr[1, 3] / m
    for a in range(3):
        com_w = p[a] + R[a, 0] * cx + R[a, 1] * cy + R[a, 2] * cz
        out[1] += m * ground_accel[3 + a] * com_w  # ground_accel = [0; -g]
    Pw0 = R[0, 0] * h[3] + R[0, 1] * h[4] + R[0, 2] * h[5]
    Pw1 = R[1, 0] * h[3] + R[1, 1] * h[4] + R[1, 2] * h[5]
    Pw2 = R[2, 0] * h[3] + R[2, 1] * h[4] + R[2, 2] * h[5]
    out[2] += Pw0
    out[3] += Pw1
    out[4] += Pw2
    out[5] += R[0, 0] * h[0] + R[0, 1] * h[1] + R[0, 2] * h[2] + p[1] * Pw2 - p[2] * Pw1
    out[6] += R[1, 0] * h[0] + R[1, 1] * h[1] + R[1, 2] * h[2] + p[2] * Pw0 - p[0] * Pw2
    out[7] += R[2, 0] * h[0] + R[2, 1] * h[1] + R[2, 2] * h[2] + p[0] * Pw1 - p[1] * Pw0


@njit(cache=True)
def energy_momentum(topology, nodes, joint_rot, joint_vec, params, q, u, out, ws_rot, ws_vec, ws_mat, pool):
    """``out = [kinetic, potential, P_x, P_y, P_z, L_x, L_y, L_z]``: the potential of the uniform field
    ``-sum m g . r_com`` plus the elastic ``1/2 eta' K eta``, the angular momentum about the world origin,
    world axes. Leaves the world poses and body velocities in the workspace."""
    nb = topology.shape[0]
    ground = params[GROUND_ACCEL:GROUND_ACCEL + 6]
    for i in range(nb):
        _kinematics(i, topology, nodes, joint_rot, joint_vec, params, q, u, ws_rot, ws_vec, ws_mat, pool, True)
    accumulate_world_poses(topology, ws_rot, ws_vec)
    for a in range(8):
        out[a] = 0.0
    for i in range(nb):
        V = ws_vec[i, VEC_V]
        h = ws_vec[i, VEC_AUX]
        if topology[i, FLEXIBLE]:
            n = topology[i, N_MODES]
            fx = topology[i, FLEX:FLEX + FK.N_FX]
            _flexible_body_terms(i, topology, params, q, u, ws_vec, ws_mat, pool, False,
                                 fx[FK.FX_GINV_KIND] == GINV_FACTORED)
            Mrr = _view(pool, topology[i, FLEX + FK.FX_P_MRR], 6, 6)
            Mre = _view(pool, fx[FK.FX_P_MRE], 6, n)
            qe = topology[i, Q_START] + topology[i, NQ_HINGE]
            ue = topology[i, U_START] + topology[i, NU_HINGE]
            e = u[ue:ue + n]
            ke = 0.0
            for a in range(6):
                s_ = 0.0
                for b in range(6):
                    s_ += Mrr[a, b] * V[b]
                for s in range(n):
                    s_ += Mre[a, s] * e[s]
                h[a] = s_
                ke += V[a] * s_
            pv = fx[FK.FX_P_VEC]
            Ge = pool[pv + PV_TMP * n:pv + (PV_TMP + 1) * n]
            FK.modal_mass_times(fx, params, n, _view(pool, fx[FK.FX_P_G], n, n), e, Ge)
            for s in range(n):
                t = Ge[s]
                for a in range(6):
                    t += Mre[a, s] * V[a]
                ke += e[s] * t
            accumulate_energy_momentum(Mrr, h, ke, ws_rot[i, ROT_WB], ws_vec[i, VEC_WPOS], ground, out)
            ok = fx[FK.FX_K]
            el = 0.0
            for r in range(n):
                for s in range(n):
                    el += q[qe + r] * params[ok + r * n + s] * q[qe + s]
            out[1] += 0.5 * el
        else:
            I = _view(params, topology[i, INERTIA], 6, 6)
            mat6_vec(I, V, h)
            ke = 0.0
            for a in range(6):
                ke += V[a] * h[a]
            accumulate_energy_momentum(I, h, ke, ws_rot[i, ROT_WB], ws_vec[i, VEC_WPOS], ground, out)
