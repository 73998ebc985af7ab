"""O(N) dynamics of trees that contain flexible bodies (numba, ``cache=True``).

Every body k carries an *augmented* velocity ``x_k = [V_k; eta_dot_k]`` of size ``N_k = 6 + n_k`` (rigid
bodies: n_k = 0). With ``u_k = [hinge rates; eta_dot_k]`` the kinematics of the tree read

    x_k = P_k x_p + H_k u_k,   P_k = [X_k [I, Psi_k]; 0],   H_k = [[S_k, 0], [0, I]]

where ``X_k`` is the rigid motion transform from the parent frame to body k (through the deformed pose
of the parent node the hinge is attached to) and ``Psi_k`` (6 x n_p) is the spatial velocity, at the
parent origin in parent axes, of that node per unit modal rate: ``Psi = [A; gamma + l~ A]`` with
``A = J_l(lambda eta) lambda`` (``J_l`` the left Jacobian of SO(3), so the node's rotation
``exp((lambda eta)~)`` and its angular velocity are exactly consistent) and ``l = l0 + gamma eta``.
Differentiating gives ``xdot_k = P_k xdot_p + H_k udot_k + c_k`` with the velocity-product term

    c_k = [X_k w' + c_J + V_k x (X_k w + S u) + (X_k w) x (S u); 0],   w = Psi eta_dot_p,
    w' = [Adot eta_dot; (gamma eta_dot) x (A eta_dot) + l~ Adot eta_dot]

(derivation: Featherstone, RBDA, eqs. 2.39-2.43, for a parent frame that itself moves relative to the
parent body). When the hinge's outboard frame sits on a deforming node c of body k itself (a flexible
child attached at its interface grid), body k moves relative to that node with ``-w_c``,
``w_c = Psi_c eta_dot_k``: the modal columns of ``H_k`` gain the rigid part ``-Psi_c``, ``S_k`` follows the
node's pose, and ``c_k`` gains ``w_c x (S u) - w'_c`` with ``v_kp = X_k w + S u - w_c`` in the terms above. The body equations come from its kinetic energy ``T = 1/2 x' M(eta) x`` with
``M(eta) = M0 + M1 eta + M2 eta eta`` (:mod:`dynamics.flexible_body`, TM-2020-5008164 eq. E.2.6):
Euler-Poincare (Kirchhoff) equations for the quasi-velocity V and Lagrange's equations for eta give

    F_k = M xdot + b,   b = Mdot x + [omega x h_w + v x h_v; omega x h_v; -1/2 x' dM/deta_r x + K eta + C eta_dot]

with ``h = M x``. The articulated-body recursion (RBDA Table 7.1) then runs unchanged in the
augmented spaces (Jain, *Robot and Multibody Dynamics*, ch. 13: the flexible-body ABA), the modal
coordinates being free "hinge" DOFs with identity subspace. Gravity enters as the ground acceleration.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from dynamics.kernels import (
    HINGE_TYPE,
    MAT_TMP,
    accumulate_energy_momentum,
    accumulate_world_poses,
    compose_body_pose,
    INBOARD,
    MAT_S,
    N_FREE,
    N_MODES,
    N_PRESCRIBED,
    NQ_HINGE,
    NU_HINGE,
    OUTBOARD,
    OUTBOARD_IDENTITY,
    PARENT,
    Q_START,
    ROT_1,
    ROT_2,
    ROT_BM,
    ROT_FM,
    ROT_PB,
    ROT_WB,
    U_START,
    UJOINT,
    VEC_POS,
    VEC_WPOS,
    _body_motion_subspace,
    _spd_inverse,
    motion_subspace_in_body,
)
from dynamics.hinges import hinge_transform
from dynamics.spatial import (
    force_to_parent_add,
    inertia_to_parent_add,
    motion_cross_motion_add,
    motion_to_child,
)

# topology columns for flexible systems: the parent node a hinge is attached to (-1: the parent frame)
# and the node of the body itself that carries the hinge's outboard frame (-1: the body frame)
PARENT_NODE = 10
OUTBOARD_NODE = 11

# flex_index columns (nb, 6)
FX_N = 0
FX_M0 = 1
FX_M1 = 2
FX_M2 = 3
FX_K = 4  # stiffness, then damping right after it (n*n each)
FX_ORDER = 5
FX_M2_EXTENT = 6  # M2 is stored on its leading k x k block only (k = 3 for point-mass nodes: only J2)
N_FX = 7

# augmented vector slots (nb, N_FV, NM)
FV_X = 0  # x = [V; eta_dot]
FV_C = 1  # velocity-product bias
FV_P = 2  # articulated bias force pA / body force in RNEA
FV_A = 3  # augmented acceleration
FV_D = 4  # joint-space residual
FV_PA = 5  # pa
FV_H = 6  # scratch: momentum, M x, ...
FV_Y = 7  # scratch
FV_W = 8  # [0:6] X_k w (attachment velocity in body axes), [6:12] w' (parent axes)
FV_OUT = 9  # outboard node: [0:3] p_BM(eta), [3:6] scratch, [6:12] its w' (body axes)
N_FV = 10

# augmented matrix slots (nb, N_FM, NM, NM)
FM_IA = 0
FM_U = 1
FM_DINV = 2
FM_IAP = 3
FM_TMP = 4
FM_L = 5
FM_M = 6  # body mass matrix M(eta)
N_FM = 7


@njit(cache=True, inline="always")
def _so3_coefficients(phi):
    """theta-functions of exp and the left Jacobian, and their derivatives divided by theta.

    R = I + a phi~ + b phi~^2; J_l = I + b phi~ + c phi~^2; returns a, b, c, b'/theta, c'/theta
    (series below theta = 0.05, where the closed forms lose digits to cancellation)."""
    t2 = phi[0] * phi[0] + phi[1] * phi[1] + phi[2] * phi[2]
    if t2 < 0.0025:
        a = 1.0 - t2 / 6.0 + t2 * t2 / 120.0 - t2 * t2 * t2 / 5040.0
        b = 0.5 - t2 / 24.0 + t2 * t2 / 720.0 - t2 * t2 * t2 / 40320.0
        c = 1.0 / 6.0 - t2 / 120.0 + t2 * t2 / 5040.0 - t2 * t2 * t2 / 362880.0
        db = -1.0 / 12.0 + t2 / 180.0 - t2 * t2 / 6720.0 + t2 * t2 * t2 / 453600.0
        dc = -1.0 / 60.0 + t2 / 1260.0 - t2 * t2 / 60480.0 + t2 * t2 * t2 / 4989600.0
    else:
        t = np.sqrt(t2)
        s = np.sin(t)
        co = np.cos(t)
        a = s / t
        b = (1.0 - co) / t2
        c = (t - s) / (t2 * t)
        db = s / (t2 * t) - 2.0 * (1.0 - co) / (t2 * t2)
        dc = (1.0 - co) / (t2 * t2) - 3.0 * (t - s) / (t2 * t2 * t)
    return a, b, c, db, dc


@njit(cache=True, inline="always")
def _skew_apply(p, x, out):
    out[0] = p[1] * x[2] - p[2] * x[1]
    out[1] = p[2] * x[0] - p[0] * x[2]
    out[2] = p[0] * x[1] - p[1] * x[0]


@njit(cache=True)
def node_deformation(shape, l0, R0, eta, n, eta_dot, R, pos, Psi, wdot, tmp):
    """Deformed pose of a node and its relative motion per unit modal rate.

    ``shape`` (6, >=n) = Pi = [lambda; gamma]; ``l0``, ``R0`` undeformed position and node -> body
    rotation. Writes ``R = exp((lambda eta)~) R0``, ``pos = l0 + gamma eta``, ``Psi`` (6, n) the node's
    spatial velocity at the body origin per unit eta_dot, and ``wdot`` (6) the velocity-product part of
    d/dt (Psi eta_dot). ``tmp`` is a (8, 3) scratch array.
    """
    phi = tmp[0]
    phidot = tmp[1]
    for a in range(3):
        s = 0.0
        sd = 0.0
        g = l0[a]
        gd = 0.0
        for r in range(n):
            s += shape[a, r] * eta[r]
            sd += shape[a, r] * eta_dot[r]
            g += shape[3 + a, r] * eta[r]
            gd += shape[3 + a, r] * eta_dot[r]
        phi[a] = s
        phidot[a] = sd
        pos[a] = g
        tmp[2, a] = gd  # gamma eta_dot
    ca, cb, cc, dbt, dct = _so3_coefficients(phi)
    # exp(phi~) = I + a phi~ + b phi~^2 ; phi~^2 = phi phi' - |phi|^2 I
    t2 = phi[0] * phi[0] + phi[1] * phi[1] + phi[2] * phi[2]
    E = tmp[3:6]
    for i in range(3):
        for j in range(3):
            E[i, j] = cb * (phi[i] * phi[j] - (t2 if i == j else 0.0)) + (1.0 if i == j else 0.0)
    E[0, 1] -= ca * phi[2]
    E[0, 2] += ca * phi[1]
    E[1, 0] += ca * phi[2]
    E[1, 2] -= ca * phi[0]
    E[2, 0] -= ca * phi[1]
    E[2, 1] += ca * phi[0]
    for i in range(3):
        for j in range(3):
            R[i, j] = E[i, 0] * R0[0, j] + E[i, 1] * R0[1, j] + E[i, 2] * R0[2, j]
    # Psi columns: A e_r = J_l lambda_r = lambda_r + b phi x lambda_r + c phi x (phi x lambda_r)
    col = tmp[6]
    cr = tmp[7]
    for r in range(n):
        for a in range(3):
            col[a] = shape[a, r]
        _skew_apply(phi, col, cr)
        _skew_apply(phi, cr, tmp[5])  # tmp[5] = phi x (phi x lambda) (E no longer needed)
        for a in range(3):
            Psi[a, r] = col[a] + cb * cr[a] + cc * tmp[5, a]
        for a in range(3):
            col[a] = Psi[a, r]
        _skew_apply(pos, col, cr)
        for a in range(3):
            Psi[3 + a, r] = shape[3 + a, r] + cr[a]
    # omega_r = A eta_dot ; Adot eta_dot = Jdot phidot with
    # Jdot = bdot phi~ + b phidot~ + cdot phi~^2 + c (phidot~ phi~ + phi~ phidot~)
    pd = phi[0] * phidot[0] + phi[1] * phidot[1] + phi[2] * phidot[2]
    bdot = dbt * pd
    cdot = dct * pd
    # terms applied to phidot: phi~ phidot, phidot~ phidot = 0, phi~^2 phidot,
    # (phidot~ phi~ + phi~ phidot~) phidot = phidot x (phi x phidot) + phi x 0
    v1 = tmp[3]
    v2 = tmp[4]
    v3 = tmp[5]
    _skew_apply(phi, phidot, v1)  # phi x phidot
    _skew_apply(phi, v1, v2)  # phi x (phi x phidot)
    _skew_apply(phidot, v1, v3)  # phidot x (phi x phidot)
    om = tmp[6]
    for a in range(3):
        om[a] = phidot[a] + cb * v1[a] + cc * v2[a]  # omega_r = J_l phidot
        wdot[a] = bdot * v1[a] + cdot * v2[a] + cc * v3[a]  # Adot eta_dot
    # linear: (gamma eta_dot) x omega_r + l~ Adot eta_dot
    _skew_apply(tmp[2], om, v1)
    _skew_apply(pos, wdot[0:3], v2)
    for a in range(3):
        wdot[3 + a] = v1[a] + v2[a]


@njit(cache=True)
def body_mass_matrix(fx, flex_data, eta, n, M):
    """M(eta) = M0 + M1 eta + M2 eta eta of a body (N x N into ``M``)."""
    N = 6 + n
    o0 = fx[FX_M0]
    for i in range(N):
        for j in range(N):
            M[i, j] = flex_data[o0 + i * N + j]
    order = fx[FX_ORDER]
    if n == 0 or order == 0:
        return
    NN = N * N
    o1 = fx[FX_M1]
    for r in range(n):
        e = eta[r]
        base = o1 + r * NN
        for i in range(N):
            for j in range(N):
                M[i, j] += e * flex_data[base + i * N + j]
    if order == 2:
        o2 = fx[FX_M2]
        k = fx[FX_M2_EXTENT]
        kk = k * k
        for r in range(n):
            for s in range(n):
                e = eta[r] * eta[s]
                base = o2 + (r * n + s) * kk
                for i in range(k):
                    for j in range(k):
                        M[i, j] += e * flex_data[base + i * k + j]


@njit(cache=True)
def body_bias(fx, flex_data, eta, x, n, M, h, out, y):
    """Gyroscopic, Coriolis, centrifugal and elastic terms of one body: ``out = b`` (N).

    ``M`` must hold M(eta); ``h``, ``y`` are N-vector scratch arrays."""
    N = 6 + n
    for i in range(N):
        s = 0.0
        for j in range(N):
            s += M[i, j] * x[j]
        h[i] = s
        out[i] = 0.0
    # rigid rows: ad*_V h  (Kirchhoff)
    w0, w1, w2 = x[0], x[1], x[2]
    v0, v1, v2 = x[3], x[4], x[5]
    out[0] = w1 * h[2] - w2 * h[1] + v1 * h[5] - v2 * h[4]
    out[1] = w2 * h[0] - w0 * h[2] + v2 * h[3] - v0 * h[5]
    out[2] = w0 * h[1] - w1 * h[0] + v0 * h[4] - v1 * h[3]
    out[3] = w1 * h[5] - w2 * h[4]
    out[4] = w2 * h[3] - w0 * h[5]
    out[5] = w0 * h[4] - w1 * h[3]
    if n == 0:
        return
    order = fx[FX_ORDER]
    NN = N * N
    if order >= 1:
        o1 = fx[FX_M1]
        o2 = fx[FX_M2]
        for r in range(n):
            # y = dM/deta_r x = M1[r] x + 2 sum_s eta_s M2[r, s] x
            base = o1 + r * NN
            for i in range(N):
                s = 0.0
                for j in range(N):
                    s += flex_data[base + i * N + j] * x[j]
                y[i] = s
            if order == 2:
                k = fx[FX_M2_EXTENT]
                kk = k * k
                for s_ in range(n):
                    e = 2.0 * eta[s_]
                    if e == 0.0:
                        continue
                    base = o2 + (r * n + s_) * kk
                    for i in range(k):
                        acc = 0.0
                        for j in range(k):
                            acc += flex_data[base + i * k + j] * x[j]
                        y[i] += e * acc
            q = 0.0
            for i in range(N):
                q += x[i] * y[i]
            out[6 + r] -= 0.5 * q
            ed = x[6 + r]  # Mdot x = sum_r eta_dot_r dM/deta_r x
            for i in range(N):
                out[i] += ed * y[i]
    ok = fx[FX_K]
    od = ok + n * n
    for r in range(n):
        s = 0.0
        for c in range(n):
            s += flex_data[ok + r * n + c] * eta[c] + flex_data[od + r * n + c] * x[6 + c]
        out[6 + r] += s


@njit(cache=True)
def _flex_position_kinematics(i, topology, joint_rot, joint_vec, node_shape, node_rot, node_pos, q, u,
                              ws_rot, ws_vec, ws_mat, psi, fv, tmp83):
    """Pose of body i in its parent (through the deformed parent node), its motion subspace, and the
    attachment terms Psi (``psi[i]``) and w' (``fv[i, FV_W, 6:12]``)."""
    hinge_type = topology[i, HINGE_TYPE]
    parent = topology[i, PARENT]
    jnode = topology[i, PARENT_NODE]
    R_FM = ws_rot[i, ROT_FM]
    pos = ws_vec[i, VEC_POS]
    p_FM = pos[3:6]
    axes = joint_vec[i, 2:4]
    hinge_transform(hinge_type, q, topology[i, Q_START], axes, R_FM, p_FM, ws_rot[i, ROT_1], ws_rot[i, ROT_2])
    if hinge_type == UJOINT:
        _body_motion_subspace(i, topology, joint_rot, joint_vec, ws_rot, ws_mat)
    # inboard frame F in the parent: R_PF, p_PF (deformed when attached to a node of a flexible parent)
    R_PF = ws_rot[i, ROT_1]
    p_PF = ws_vec[i, VEC_WPOS, 3:6]
    n_p = topology[parent, N_MODES] if parent >= 0 else 0
    wd = fv[i, FV_W, 6:12]
    for a in range(6):
        wd[a] = 0.0
    if jnode >= 0 and n_p > 0:
        q_eta = topology[parent, Q_START] + topology[parent, NQ_HINGE]
        u_eta = topology[parent, U_START] + topology[parent, NU_HINGE]
        R_PN = ws_rot[i, ROT_WB]  # scratch until world poses are needed
        l_j = ws_vec[i, VEC_WPOS, 0:3]
        node_deformation(node_shape[jnode], node_pos[jnode], node_rot[jnode], q[q_eta:q_eta + n_p], n_p,
                         u[u_eta:u_eta + n_p], R_PN, l_j, psi[i], wd, tmp83)
        R_NF = joint_rot[i, INBOARD]
        p_NF = joint_vec[i, INBOARD]
        for a in range(3):
            for b in range(3):
                R_PF[a, b] = R_PN[a, 0] * R_NF[0, b] + R_PN[a, 1] * R_NF[1, b] + R_PN[a, 2] * R_NF[2, b]
        for a in range(3):
            p_PF[a] = l_j[a] + R_PN[a, 0] * p_NF[0] + R_PN[a, 1] * p_NF[1] + R_PN[a, 2] * p_NF[2]
    else:
        for a in range(3):
            p_PF[a] = joint_vec[i, INBOARD, a]
            for b in range(3):
                R_PF[a, b] = joint_rot[i, INBOARD, a, b]
    T = ws_rot[i, ROT_2] if hinge_type != UJOINT else tmp83[3:6]
    onode = topology[i, OUTBOARD_NODE]
    if onode < 0:
        compose_body_pose(R_PF, p_PF, R_FM, p_FM, topology[i, OUTBOARD_IDENTITY], joint_rot[i, OUTBOARD],
                          joint_vec[i, OUTBOARD], T, ws_rot[i, ROT_PB], pos)
        return
    # outboard frame M on the body's own deforming node c: R_BM = R_Bc R_cM, p_BM = l_c + R_Bc p_cM
    n = topology[i, N_MODES]
    q_eta = topology[i, Q_START] + topology[i, NQ_HINGE]
    u_eta = topology[i, U_START] + topology[i, NU_HINGE]
    R_Bc = ws_rot[i, ROT_WB]  # scratch until world poses are needed
    out = fv[i, FV_OUT]
    node_deformation(node_shape[onode], node_pos[onode], node_rot[onode], q[q_eta:q_eta + n], n,
                     u[u_eta:u_eta + n], R_Bc, out[3:6], psi[i, 6:12], out[6:12], tmp83)
    R_cM = joint_rot[i, OUTBOARD]
    p_cM = joint_vec[i, OUTBOARD]
    R_BM = ws_rot[i, ROT_BM]
    for a in range(3):
        for b in range(3):
            R_BM[a, b] = R_Bc[a, 0] * R_cM[0, b] + R_Bc[a, 1] * R_cM[1, b] + R_Bc[a, 2] * R_cM[2, b]
        out[a] = out[3 + a] + R_Bc[a, 0] * p_cM[0] + R_Bc[a, 1] * p_cM[1] + R_Bc[a, 2] * p_cM[2]
    T = ws_rot[i, ROT_2] if hinge_type != UJOINT else tmp83[3:6]
    compose_body_pose(R_PF, p_PF, R_FM, p_FM, 0, R_BM, out[0:3], T, ws_rot[i, ROT_PB], pos)
    motion_subspace_in_body(hinge_type, axes, ws_rot[i, ROT_2], R_BM, out[0:3], topology[i, NU_HINGE],
                            ws_mat[i, MAT_S], ws_mat[i, MAT_TMP])


@njit(cache=True)
def _flex_velocity(i, topology, joint_vec, q, u, ws_rot, ws_vec, ws_mat, psi, fv):
    """Augmented velocity x_i and velocity-product bias c_i (see the module docstring)."""
    parent = topology[i, PARENT]
    u0 = topology[i, U_START]
    nu = topology[i, NU_HINGE]
    n = topology[i, N_MODES]
    S = ws_mat[i, MAT_S]
    R = ws_rot[i, ROT_PB]
    r = ws_vec[i, VEC_POS]
    x = fv[i, FV_X]
    c = fv[i, FV_C]
    vJ = fv[i, FV_Y]
    tmp = fv[i, FV_H]
    Xw = fv[i, FV_W, 0:6]
    wd = fv[i, FV_W, 6:12]
    for a in range(6):
        s_ = 0.0
        for k in range(nu):
            s_ += S[a, k] * u[u0 + k]
        vJ[a] = s_
        c[a] = 0.0
        Xw[a] = 0.0
    n_p = topology[parent, N_MODES] if parent >= 0 else 0
    if parent >= 0:
        xp = fv[parent, FV_X]
        for a in range(6):
            tmp[a] = xp[a]
        if topology[i, PARENT_NODE] >= 0 and n_p > 0:
            P = psi[i]
            for a in range(6):
                s_ = 0.0
                for rr in range(n_p):
                    s_ += P[a, rr] * xp[6 + rr]
                tmp[6 + a] = s_  # w
                tmp[a] += s_
            motion_to_child(R, r, tmp[6:12], Xw)
            motion_to_child(R, r, wd, c)  # X w'
        motion_to_child(R, r, tmp[0:6], x[0:6])
        for a in range(6):
            x[a] += vJ[a]
    else:
        for a in range(6):
            x[a] = vJ[a]
    for k in range(n):
        x[6 + k] = u[u0 + nu + k]
        c[6 + k] = 0.0
    onode = topology[i, OUTBOARD_NODE]
    wc = fv[i, FV_D, 0:6]  # free until the articulated-body pass
    for a in range(6):
        wc[a] = 0.0
    if onode >= 0:
        # the body moves relative to its hinge node with -w_c, w_c = Psi_c eta_dot
        Pc = psi[i, 6:12]
        out = fv[i, FV_OUT]
        for a in range(6):
            s_ = 0.0
            for k in range(n):
                s_ += Pc[a, k] * x[6 + k]
            wc[a] = s_
            x[a] -= s_
            c[a] -= out[6 + a]
        motion_cross_motion_add(wc, vJ, c)
    if topology[i, HINGE_TYPE] == UJOINT:
        p_BM = joint_vec[i, OUTBOARD] if onode < 0 else fv[i, FV_OUT, 0:3]
        g = u[u0] * u[u0 + 1]
        c0 = g * (S[1, 0] * S[2, 1] - S[2, 0] * S[1, 1])
        c1 = g * (S[2, 0] * S[0, 1] - S[0, 0] * S[2, 1])
        c2 = g * (S[0, 0] * S[1, 1] - S[1, 0] * S[0, 1])
        c[0] += c0
        c[1] += c1
        c[2] += c2
        c[3] += p_BM[1] * c2 - p_BM[2] * c1
        c[4] += p_BM[2] * c0 - p_BM[0] * c2
        c[5] += p_BM[0] * c1 - p_BM[1] * c0
    # V x (X w + S u - w_c) + (X w) x (S u - w_c)
    for a in range(6):
        tmp[a] = Xw[a] + vJ[a] - wc[a]
        tmp[6 + a] = vJ[a] - wc[a]
    motion_cross_motion_add(x[0:6], tmp[0:6], c)
    motion_cross_motion_add(Xw, tmp[6:12], c)


@njit(cache=True)
def _flex_kinematics_pass(topology, joint_rot, joint_vec, flex_index, flex_data, node_shape, node_rot,
                          node_pos, q, u, ws_rot, ws_vec, ws_mat, psi, fv, fm, tmp83, with_bias):
    """Positions, velocities, body mass matrices (``fm[i, FM_M]``) and, with ``with_bias``, body bias
    forces (``fv[i, FV_P]``) for every body."""
    for i in range(topology.shape[0]):
        _flex_position_kinematics(i, topology, joint_rot, joint_vec, node_shape, node_rot, node_pos, q, u,
                                  ws_rot, ws_vec, ws_mat, psi, fv, tmp83)
        _flex_velocity(i, topology, joint_vec, q, u, ws_rot, ws_vec, ws_mat, psi, fv)
        n = topology[i, N_MODES]
        q_eta = topology[i, Q_START] + topology[i, NQ_HINGE]
        body_mass_matrix(flex_index[i], flex_data, q[q_eta:q_eta + n], n, fm[i, FM_M])
        if with_bias:
            body_bias(flex_index[i], flex_data, q[q_eta:q_eta + n], fv[i, FV_X], n, fm[i, FM_M],
                      fv[i, FV_H], fv[i, FV_P], fv[i, FV_Y])


@njit(cache=True, inline="always")
def _deformed_node(nd, topology, node_body, node_shape, node_rot, node_pos, q, u, Rn, l, node_psi, wd, tmp83):
    """Deformed pose, Psi and w' of node ``nd`` on its body (see :func:`node_deformation`); returns the
    body index and its number of modes."""
    b = node_body[nd]
    n = topology[b, N_MODES]
    q_eta = topology[b, Q_START] + topology[b, NQ_HINGE]
    u_eta = topology[b, U_START] + topology[b, NU_HINGE]
    node_deformation(node_shape[nd], node_pos[nd], node_rot[nd], q[q_eta:q_eta + n], n, u[u_eta:u_eta + n],
                     Rn, l, node_psi, wd, tmp83)
    return b, n


@njit(cache=True)
def _apply_external_forces(topology, node_body, node_shape, node_rot, node_pos, node_forces, body_forces,
                           q, u, psi, fv, tmp83, scratch, sign):
    """fv[:, FV_P] += sign * (generalized external forces): node forces (node axes, at the deformed node)
    through [X^T; Psi^T X^T], body forces (body axes, body origin) on the rigid rows.
    ``scratch`` is a (4, 6, 6) work array."""
    nb = topology.shape[0]
    node_psi = psi[nb]
    for i in range(nb):
        P = fv[i, FV_P]
        for a in range(6):
            P[a] += sign * body_forces[i, a]
    Rn = scratch[0, 0:3, 0:3]
    l = scratch[1, 0, 0:3]
    wd = scratch[1, 1]
    f6 = scratch[1, 2]
    for nd in range(node_body.shape[0]):
        b, n = _deformed_node(nd, topology, node_body, node_shape, node_rot, node_pos, q, u, Rn, l, node_psi,
                              wd, tmp83)
        for a in range(6):
            f6[a] = 0.0
        force_to_parent_add(Rn, l, node_forces[nd], f6)
        P = fv[b, FV_P]
        for a in range(6):
            P[a] += sign * f6[a]
        for rr in range(n):
            s_ = 0.0
            for a in range(6):
                s_ += node_psi[a, rr] * f6[a]
            P[6 + rr] += sign * s_


ALL_HINGE_DOFS = np.arange(6)
"""Column indices of every hinge DOF (the mass matrix uses all of them, ABA only the free ones)."""


@njit(cache=True, inline="always")
def _inertia_times_subspace(I, S, cols, nh, n, N, Pc, has_pc, out):
    """out (N x (nh + n)) = I H for the hinge columns ``S[:, cols[:nh]]`` and the modal columns
    ``e_(6+r) - [Pc[:, r]; 0]`` (``Pc`` only when the hinge sits on a deforming node of the body)."""
    for kk in range(nh):
        k = cols[kk]
        for a in range(N):
            s_ = 0.0
            for b in range(6):
                s_ += I[a, b] * S[b, k]
            out[a, kk] = s_
    for rr in range(n):
        for a in range(N):
            s_ = I[a, 6 + rr]
            if has_pc:
                for b in range(6):
                    s_ -= I[a, b] * Pc[b, rr]
            out[a, nh + rr] = s_


@njit(cache=True, inline="always")
def _subspace_transpose_times(S, cols, nh, n, Pc, has_pc, F, ncol, out, row0, col0):
    """out[row0 + k, col0 + l] = (H' F)[k, l] for the hinge rows ``S[:, cols[:nh]]'`` and modal rows."""
    for kk in range(nh + n):
        for ll in range(ncol):
            if kk < nh:
                k = cols[kk]
                s_ = 0.0
                for a in range(6):
                    s_ += S[a, k] * F[a, ll]
            else:
                rr = kk - nh
                s_ = F[6 + rr, ll]
                if has_pc:
                    for a in range(6):
                        s_ -= Pc[a, rr] * F[a, ll]
            out[row0 + kk, col0 + ll] = s_


@njit(cache=True, inline="always")
def _modal_projection(F, r, Pc, has_pc):
    """(H' F) at modal DOF r: F[6 + r] - Pc[:, r] . F[0:6]."""
    s_ = F[6 + r]
    if has_pc:
        for a in range(6):
            s_ -= Pc[a, r] * F[a]
    return s_


@njit(cache=True)
def _inertia_to_parent(i, parent, Ia, IA_p, ws_rot, ws_vec, psi, n_p, fm):
    """IA_p += P_i^T Ia P_i with P_i = [X_i [I, Psi_i]; 0]: only Ia's rigid block reaches the parent."""
    Y = fm[i, FM_TMP]
    for a in range(6):
        for b in range(6):
            Y[a, b] = 0.0
    inertia_to_parent_add(ws_rot[i, ROT_PB], ws_vec[i, VEC_POS], Ia[0:6, 0:6], Y, fm[i, FM_L])
    for a in range(6):
        for b in range(6):
            IA_p[a, b] += Y[a, b]
    if n_p > 0:
        P = psi[i]
        for cc in range(n_p):  # Y Psi into Y[:, 6 + cc]
            for a in range(6):
                s_ = 0.0
                for b in range(6):
                    s_ += Y[a, b] * P[b, cc]
                Y[a, 6 + cc] = s_
        for cc in range(n_p):
            for a in range(6):
                IA_p[a, 6 + cc] += Y[a, 6 + cc]
                IA_p[6 + cc, a] += Y[a, 6 + cc]
            for dd in range(n_p):
                s_ = 0.0
                for a in range(6):
                    s_ += P[a, cc] * Y[a, 6 + dd]
                IA_p[6 + cc, 6 + dd] += s_


@njit(cache=True)
def _force_to_parent(i, f, p_parent, ws_rot, ws_vec, psi, n_p, y):
    """p_parent += P_i^T f (only the rigid part of f reaches the parent); y is a 6-vector scratch."""
    for a in range(6):
        y[a] = 0.0
    force_to_parent_add(ws_rot[i, ROT_PB], ws_vec[i, VEC_POS], f[0:6], y)
    for a in range(6):
        p_parent[a] += y[a]
    if n_p > 0:
        P = psi[i]
        for cc in range(n_p):
            s_ = 0.0
            for a in range(6):
                s_ += P[a, cc] * y[a]
            p_parent[6 + cc] += s_


@njit(cache=True)
def _parent_acceleration(i, topology, ground_accel, ws_rot, ws_vec, psi, fv, out):
    """out[0:6] = X_i (a_p + Psi_i etaddot_p) (the rigid part of P_i a_p)."""
    parent = topology[i, PARENT]
    tmp = fv[i, FV_H]
    if parent < 0:
        for a in range(6):
            tmp[a] = ground_accel[a]
    else:
        ap = fv[parent, FV_A]
        for a in range(6):
            tmp[a] = ap[a]
        n_p = topology[parent, N_MODES]
        if topology[i, PARENT_NODE] >= 0 and n_p > 0:
            P = psi[i]
            for a in range(6):
                s_ = 0.0
                for cc in range(n_p):
                    s_ += P[a, cc] * ap[6 + cc]
                tmp[a] += s_
    motion_to_child(ws_rot[i, ROT_PB], ws_vec[i, VEC_POS], tmp[0:6], out)


@njit(cache=True)
def flex_forward_dynamics(topology, hinge_dofs, joint_rot, joint_vec, flex_index, flex_data, node_body,
                          node_shape, node_rot, node_pos, ground_accel, q, u, tau, node_forces, body_forces,
                          udot, tau_out, ws_rot, ws_vec, ws_mat, psi, fv, fm, tmp83, scratch):
    """Articulated-body forward dynamics of a tree with flexible bodies (module docstring).

    Same contract as :func:`dynamics.kernels.forward_dynamics`: ``udot`` holds prescribed hinge
    accelerations on entry, all accelerations on exit; ``tau_out`` the generalized forces. Modal DOFs are
    always free; ``tau`` at a modal DOF is an applied modal force. Returns 0 or 1 + a singular body.
    """
    nb = topology.shape[0]
    _flex_kinematics_pass(topology, joint_rot, joint_vec, flex_index, flex_data, node_shape, node_rot,
                          node_pos, q, u, ws_rot, ws_vec, ws_mat, psi, fv, fm, tmp83, True)
    _apply_external_forces(topology, node_body, node_shape, node_rot, node_pos, node_forces, body_forces,
                           q, u, psi, fv, tmp83, scratch, -1.0)
    for i in range(nb):
        N = 6 + topology[i, N_MODES]
        IA = fm[i, FM_IA]
        M = fm[i, FM_M]
        for a in range(N):
            for b in range(N):
                IA[a, b] = M[a, b]
        S = ws_mat[i, MAT_S]
        c = fv[i, FV_C]
        u0 = topology[i, U_START]
        for kk in range(topology[i, N_PRESCRIBED]):
            k = hinge_dofs[i, 1, kk]
            acc = udot[u0 + k]
            for a in range(6):
                c[a] += S[a, k] * acc

    for i in range(nb - 1, -1, -1):
        n = topology[i, N_MODES]
        N = 6 + n
        nfh = topology[i, N_FREE]
        nf = nfh + n
        nu = topology[i, NU_HINGE]
        u0 = topology[i, U_START]
        S = ws_mat[i, MAT_S]
        IA = fm[i, FM_IA]
        U = fm[i, FM_U]
        Dinv = fm[i, FM_DINV]
        Ia = fm[i, FM_IAP]
        D = fm[i, FM_TMP]
        pA = fv[i, FV_P]
        c = fv[i, FV_C]
        d = fv[i, FV_D]
        pa = fv[i, FV_PA]
        Pc = psi[i, 6:12]
        has_pc = topology[i, OUTBOARD_NODE] >= 0
        _inertia_times_subspace(IA, S, hinge_dofs[i, 0], nfh, n, N, Pc, has_pc, U)
        _subspace_transpose_times(S, hinge_dofs[i, 0], nfh, n, Pc, has_pc, U, nf, D, 0, 0)
        for kk in range(nf):
            if kk < nfh:
                k = hinge_dofs[i, 0, kk]
                s_ = tau[u0 + k]
                for a in range(6):
                    s_ -= S[a, k] * pA[a]
            else:
                s_ = tau[u0 + nu + kk - nfh] - _modal_projection(pA, kk - nfh, Pc, has_pc)
            d[kk] = s_
        if nf > 0:
            tr = 0.0
            for a in range(N):
                tr += IA[a, a]
            if not _spd_inverse(D, nf, 1e-14 * tr, fm[i, FM_L], Dinv):
                return 1 + i
        # T = U Dinv (kept in D's storage), Ia = IA - T U^T, pa = pA + Ia c + T d
        T = D
        for a in range(N):
            for kk in range(nf):
                s_ = 0.0
                for ll in range(nf):
                    s_ += U[a, ll] * Dinv[ll, kk]
                fm[i, FM_L, 0, kk] = s_
            for kk in range(nf):
                T[a, kk] = fm[i, FM_L, 0, kk]
        for a in range(N):
            for b in range(a, N):
                s_ = IA[a, b]
                for kk in range(nf):
                    s_ -= T[a, kk] * U[b, kk]
                Ia[a, b] = s_
                Ia[b, a] = s_
        for a in range(N):
            s_ = pA[a]
            for b in range(N):
                s_ += Ia[a, b] * c[b]
            for kk in range(nf):
                s_ += T[a, kk] * d[kk]
            pa[a] = s_
        parent = topology[i, PARENT]
        if parent >= 0:
            n_p = topology[parent, N_MODES] if topology[i, PARENT_NODE] >= 0 else 0
            _inertia_to_parent(i, parent, Ia, fm[parent, FM_IA], ws_rot, ws_vec, psi, n_p, fm)
            _force_to_parent(i, pa, fv[parent, FV_P], ws_rot, ws_vec, psi, n_p, fv[i, FV_Y])

    for i in range(nb):
        n = topology[i, N_MODES]
        N = 6 + n
        nfh = topology[i, N_FREE]
        nf = nfh + n
        nu = topology[i, NU_HINGE]
        u0 = topology[i, U_START]
        A = fv[i, FV_A]
        _parent_acceleration(i, topology, ground_accel, ws_rot, ws_vec, psi, fv, A)
        c = fv[i, FV_C]
        for a in range(6):
            A[a] += c[a]
        for a in range(6, N):
            A[a] = c[a]
        S = ws_mat[i, MAT_S]
        U = fm[i, FM_U]
        Dinv = fm[i, FM_DINV]
        d = fv[i, FV_D]
        y = fv[i, FV_Y]
        for kk in range(nf):
            t = d[kk]
            for a in range(N):
                t -= U[a, kk] * A[a]
            y[kk] = t
        for kk in range(nf):
            s_ = 0.0
            for ll in range(nf):
                s_ += Dinv[kk, ll] * y[ll]
            if kk < nfh:
                k = hinge_dofs[i, 0, kk]
                udot[u0 + k] = s_
                tau_out[u0 + k] = tau[u0 + k]
                for a in range(6):
                    A[a] += S[a, k] * s_
            else:
                rr = kk - nfh
                udot[u0 + nu + rr] = s_
                tau_out[u0 + nu + rr] = tau[u0 + nu + rr]
                A[6 + rr] += s_
                if topology[i, OUTBOARD_NODE] >= 0:
                    for a in range(6):
                        A[a] -= psi[i, 6 + a, rr] * s_
        npres = topology[i, N_PRESCRIBED]
        if npres > 0:
            IA = fm[i, FM_IA]
            pA = fv[i, FV_P]
            for kk in range(npres):
                k = hinge_dofs[i, 1, kk]
                s_ = 0.0
                for a in range(6):
                    f = pA[a]
                    for b in range(N):
                        f += IA[a, b] * A[b]
                    s_ += S[a, k] * f
                tau_out[u0 + k] = s_
    return 0


@njit(cache=True)
def _flex_accelerations(topology, ground_accel, udot, ws_rot, ws_vec, ws_mat, psi, fv):
    """Augmented accelerations a_i = P_i a_p + H_i udot_i + c_i for given udot (into fv[:, FV_A])."""
    for i in range(topology.shape[0]):
        n = topology[i, N_MODES]
        nu = topology[i, NU_HINGE]
        u0 = topology[i, U_START]
        A = fv[i, FV_A]
        _parent_acceleration(i, topology, ground_accel, ws_rot, ws_vec, psi, fv, A)
        c = fv[i, FV_C]
        S = ws_mat[i, MAT_S]
        for a in range(6):
            s_ = A[a] + c[a]
            for k in range(nu):
                s_ += S[a, k] * udot[u0 + k]
            A[a] = s_
        has_pc = topology[i, OUTBOARD_NODE] >= 0
        for rr in range(n):
            e = udot[u0 + nu + rr]
            A[6 + rr] = c[6 + rr] + e
            if has_pc:
                for a in range(6):
                    A[a] -= psi[i, 6 + a, rr] * e


@njit(cache=True)
def flex_inverse_dynamics(topology, joint_rot, joint_vec, flex_index, flex_data, node_body, node_shape,
                          node_rot, node_pos, ground_accel, q, u, udot, node_forces, body_forces, tau,
                          ws_rot, ws_vec, ws_mat, psi, fv, fm, tmp83, scratch):
    """Recursive Newton-Euler in augmented form: F_i = M_i a_i + b_i - f_ext,i; tau_i = H_i^T F_i;
    F_parent += P_i^T F_i."""
    nb = topology.shape[0]
    _flex_kinematics_pass(topology, joint_rot, joint_vec, flex_index, flex_data, node_shape, node_rot,
                          node_pos, q, u, ws_rot, ws_vec, ws_mat, psi, fv, fm, tmp83, True)
    _apply_external_forces(topology, node_body, node_shape, node_rot, node_pos, node_forces, body_forces,
                           q, u, psi, fv, tmp83, scratch, -1.0)
    _flex_accelerations(topology, ground_accel, udot, ws_rot, ws_vec, ws_mat, psi, fv)
    for i in range(nb):
        N = 6 + topology[i, N_MODES]
        M = fm[i, FM_M]
        A = fv[i, FV_A]
        F = fv[i, FV_P]
        for a in range(N):
            s_ = 0.0
            for b in range(N):
                s_ += M[a, b] * A[b]
            F[a] += s_
    for i in range(nb - 1, -1, -1):
        n = topology[i, N_MODES]
        nu = topology[i, NU_HINGE]
        u0 = topology[i, U_START]
        S = ws_mat[i, MAT_S]
        F = fv[i, FV_P]
        for k in range(nu):
            s_ = 0.0
            for a in range(6):
                s_ += S[a, k] * F[a]
            tau[u0 + k] = s_
        for rr in range(n):
            tau[u0 + nu + rr] = _modal_projection(F, rr, psi[i, 6:12], topology[i, OUTBOARD_NODE] >= 0)
        parent = topology[i, PARENT]
        if parent >= 0:
            n_p = topology[parent, N_MODES] if topology[i, PARENT_NODE] >= 0 else 0
            _force_to_parent(i, F, fv[parent, FV_P], ws_rot, ws_vec, psi, n_p, fv[i, FV_Y])


@njit(cache=True)
def flex_mass_matrix(topology, joint_rot, joint_vec, flex_index, flex_data, node_shape, node_rot, node_pos,
                     q, u_zero, Mout, ws_rot, ws_vec, ws_mat, psi, fv, fm, tmp83):
    """Joint-space mass matrix by composite augmented inertias (CRBA with P_i, H_i); ``u_zero`` is a
    zero velocity vector (velocities do not enter the mass matrix)."""
    nb = topology.shape[0]
    _flex_kinematics_pass(topology, joint_rot, joint_vec, flex_index, flex_data, node_shape, node_rot,
                          node_pos, q, u_zero, ws_rot, ws_vec, ws_mat, psi, fv, fm, tmp83, False)
    for i in range(nb):
        N = 6 + topology[i, N_MODES]
        Ic = fm[i, FM_IA]
        M = fm[i, FM_M]
        for a in range(N):
            for b in range(N):
                Ic[a, b] = M[a, b]
    for i in range(nb - 1, -1, -1):
        parent = topology[i, PARENT]
        if parent >= 0:
            n_p = topology[parent, N_MODES] if topology[i, PARENT_NODE] >= 0 else 0
            _inertia_to_parent(i, parent, fm[i, FM_IA], fm[parent, FM_IA], ws_rot, ws_vec, psi, n_p, fm)
    Mout[:, :] = 0.0
    for i in range(nb):
        n = topology[i, N_MODES]
        N = 6 + n
        nu = topology[i, NU_HINGE]
        ncol = nu + n
        if ncol == 0:
            continue
        ui = topology[i, U_START]
        S = ws_mat[i, MAT_S]
        Ic = fm[i, FM_IA]
        F = fm[i, FM_U]  # F = Ic H_i  (N x ncol)
        has_pc = topology[i, OUTBOARD_NODE] >= 0
        _inertia_times_subspace(Ic, S, ALL_HINGE_DOFS, nu, n, N, psi[i, 6:12], has_pc, F)
        _subspace_transpose_times(S, ALL_HINGE_DOFS, nu, n, psi[i, 6:12], has_pc, F, ncol, Mout, ui, ui)
        for k in range(ncol):  # symmetric by construction, not by round-off
            for l in range(k + 1, ncol):
                Mout[ui + l, ui + k] = Mout[ui + k, ui + l]
        j = i
        Fc = fm[i, FM_DINV]  # the force columns carried up the tree
        for a in range(N):
            for k in range(ncol):
                Fc[a, k] = F[a, k]
        while topology[j, PARENT] >= 0:
            parent = topology[j, PARENT]
            n_p = topology[parent, N_MODES] if topology[j, PARENT_NODE] >= 0 else 0
            y = fv[j, FV_Y]
            col = fv[j, FV_H]
            for k in range(ncol):
                for a in range(6):
                    col[a] = Fc[a, k]
                tmpf = fv[j, FV_PA]
                for a in range(6 + topology[parent, N_MODES]):
                    tmpf[a] = 0.0
                _force_to_parent(j, col, tmpf, ws_rot, ws_vec, psi, n_p, y)
                for a in range(6 + topology[parent, N_MODES]):
                    Fc[a, k] = tmpf[a]
            j = parent
            nj = topology[j, N_MODES]
            nuj = topology[j, NU_HINGE]
            uj = topology[j, U_START]
            Sj = ws_mat[j, MAT_S]
            _subspace_transpose_times(Sj, ALL_HINGE_DOFS, nuj, nj, psi[j, 6:12], topology[j, OUTBOARD_NODE] >= 0,
                                      Fc, ncol, Mout, uj, ui)
            for k in range(nuj + nj):
                for l in range(ncol):
                    Mout[ui + l, uj + k] = Mout[uj + k, ui + l]


@njit(cache=True)
def flex_node_kinematics(topology, joint_rot, joint_vec, flex_index, flex_data, node_body, node_shape,
                         node_rot, node_pos, q, u, udot, rotation, position, velocity, acceleration,
                         ws_rot, ws_vec, ws_mat, psi, fv, fm, tmp83, scratch):
    """Deformed node poses, spatial velocities and classical accelerations (same outputs as
    :func:`dynamics.kernels.node_kinematics`), elastic motion included."""
    nb = topology.shape[0]
    _flex_kinematics_pass(topology, joint_rot, joint_vec, flex_index, flex_data, node_shape, node_rot,
                          node_pos, q, u, ws_rot, ws_vec, ws_mat, psi, fv, fm, tmp83, False)
    zero_g = scratch[2, 0]
    for a in range(6):
        zero_g[a] = 0.0
    _flex_accelerations(topology, zero_g, udot, ws_rot, ws_vec, ws_mat, psi, fv)
    accumulate_world_poses(topology, ws_rot, ws_vec)
    node_psi = psi[nb]
    Rn = scratch[0, 0:3, 0:3]
    l = scratch[1, 0, 0:3]
    wd = scratch[1, 1]
    tmp = scratch[1, 2]
    w = scratch[1, 3]
    Xw = scratch[1, 4]
    for nd in range(node_body.shape[0]):
        b, n = _deformed_node(nd, topology, node_body, node_shape, node_rot, node_pos, q, u, Rn, l, node_psi,
                              wd, tmp83)
        R_WB = ws_rot[b, ROT_WB]
        pw = ws_vec[b, VEC_WPOS]
        for a in range(3):
            position[nd, a] = pw[a] + R_WB[a, 0] * l[0] + R_WB[a, 1] * l[1] + R_WB[a, 2] * l[2]
            for k in range(3):
                rotation[nd, a, k] = R_WB[a, 0] * Rn[0, k] + R_WB[a, 1] * Rn[1, k] + R_WB[a, 2] * Rn[2, k]
        x = fv[b, FV_X]
        A = fv[b, FV_A]
        for a in range(6):
            s_ = 0.0
            for rr in range(n):
                s_ += node_psi[a, rr] * x[6 + rr]
            w[a] = s_
            tmp[a] = x[a] + s_
        motion_to_child(Rn, l, tmp, velocity[nd])
        for a in range(6):
            sa = 0.0
            for rr in range(n):
                sa += node_psi[a, rr] * A[6 + rr]
            tmp[a] = A[a] + sa + wd[a]
        motion_to_child(Rn, l, tmp, acceleration[nd])
        motion_to_child(Rn, l, w, Xw)
        motion_cross_motion_add(velocity[nd], Xw, acceleration[nd])
        v = velocity[nd]
        acc = acceleration[nd]
        acc[3] += v[1] * v[5] - v[2] * v[4]
        acc[4] += v[2] * v[3] - v[0] * v[5]
        acc[5] += v[0] * v[4] - v[1] * v[3]


@njit(cache=True)
def flex_energy_momentum(topology, joint_rot, joint_vec, flex_index, flex_data, node_shape, node_rot,
                         node_pos, ground_accel, q, u, out, ws_rot, ws_vec, ws_mat, psi, fv, fm, tmp83):
    """``out = [kinetic, potential (gravity + elastic), P (3), L about the world origin (3)]``."""
    nb = topology.shape[0]
    _flex_kinematics_pass(topology, joint_rot, joint_vec, flex_index, flex_data, node_shape, node_rot,
                          node_pos, q, u, ws_rot, ws_vec, ws_mat, psi, fv, fm, tmp83, False)
    accumulate_world_poses(topology, ws_rot, ws_vec)
    for a in range(8):
        out[a] = 0.0
    for i in range(nb):
        n = topology[i, N_MODES]
        accumulate_energy_momentum(fm[i, FM_M], fv[i, FV_X], fv[i, FV_H], 6 + n, ws_rot[i, ROT_WB],
                                   ws_vec[i, VEC_WPOS], ground_accel, out)
        if n > 0:
            ok = flex_index[i, FX_K]
            q_eta = topology[i, Q_START] + topology[i, NQ_HINGE]
            e = 0.0
            for r in range(n):
                for s_ in range(n):
                    e += q[q_eta + r] * flex_data[ok + r * n + s_] * q[q_eta + s_]
            out[1] += 0.5 * e
