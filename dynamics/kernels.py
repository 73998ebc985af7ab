"""Compiled multibody algorithms over the arrays of a compiled system (numba, ``cache=True``).

Every kernel takes the immutable system arrays (``topology``, ``hinge_dofs``, ``joint_rot``,
``joint_vec``, ``spatial_inertia``, node tables) and the mutable workspace (``ws_rot``, ``ws_vec``,
``ws_mat``) created by :class:`dynamics.system.MultibodySystem`, and writes its results into output
arguments: nothing is allocated per call except where noted.

Algorithms (Featherstone, *Rigid Body Dynamics Algorithms* (RBDA), 2008; the same recursions are the
spatial-operator O(N) forms of TM-2020-5008164 Appendix B / Jain, *Robot and Multibody Dynamics*, 2011):

* :func:`forward_dynamics` - articulated-body algorithm (RBDA Table 7.1), extended with prescribed hinge
  DOFs: their known accelerations enter the velocity-product bias and their generalized forces are
  recovered from the articulated force ``IA a + pA`` (RBDA sec. 7.3 / 9.3 "mixed" dynamics);
* :func:`inverse_dynamics` - recursive Newton-Euler (RBDA Table 5.1);
* :func:`mass_matrix` - composite-rigid-body algorithm (RBDA Table 6.2);
* :func:`node_kinematics` - pose, spatial velocity and acceleration of frames fixed on bodies;
* :func:`energy_momentum` - kinetic and potential energy, linear and angular momentum in the world.

Gravity enters as a fictitious upward acceleration of the ground, ``ground_accel = a_0 = [0; -g]``
(RBDA sec. 5.3).
External forces are spatial forces per body, about the body origin, in body axes.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from dynamics.hinges import UJOINT, hinge_coordinate_rates, hinge_motion_subspace, hinge_transform
from dynamics.spatial import (
    force_to_parent_add,
    force_to_parent_inplace,
    inertia_to_parent_add,
    mat6_vec,
    motion_cross_force_add,
    motion_cross_motion_add,
    motion_to_child,
)

# topology columns
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
# columns 10 PARENT_NODE and 11 OUTBOARD_NODE are used by dynamics.flexible_kernels (hinges on deforming
# nodes); the rigid kernels fold node offsets into the hinge frames
TOPOLOGY_COLUMNS = 12

# joint_rot slots: (nb, 2, 3, 3) and joint_vec slots: (nb, 4, 3)
INBOARD = 0  # rotation R_PF / position of F in the parent frame
OUTBOARD = 1  # rotation R_BM / position of M in the body frame
AXIS1 = 2
AXIS2 = 3

# workspace slots
ROT_PB = 0  # body -> parent rotation
ROT_FM = 1
ROT_1 = 2
ROT_2 = 3
ROT_WB = 4  # body -> world rotation
ROT_BM = 5  # outboard frame on a deforming node of a flexible body (dynamics.flexible_kernels)
N_ROT = 6

VEC_V = 0  # spatial velocity of the body
VEC_C = 1  # velocity-product (and prescribed) bias acceleration
VEC_P = 2  # articulated bias force pA (ABA) / body force f (RNEA)
VEC_A = 3  # spatial acceleration
VEC_D = 4  # joint-space residual d (ABA)
VEC_POS = 5  # [0:3] position of the body origin in the parent, [3:6] p_FM
VEC_AUX = 6  # hinge velocity S u, then ABA's pa
VEC_WPOS = 7  # [0:3] body origin in the world
N_VEC = 8

MAT_S = 0  # motion subspace in body axes (6 x nu)
MAT_IA = 1  # articulated (ABA) or composite (CRBA) inertia
MAT_U = 2  # U = IA S_free (ABA) / F = Ic S (CRBA)
MAT_DINV = 3  # (S^T IA S)^-1 over the free DOFs
MAT_IAP = 4  # IA - U D^-1 U^T
MAT_TMP = 5
N_MAT = 6


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
def _body_position_kinematics(i, topology, joint_rot, joint_vec, q, ws_rot, ws_vec, ws_mat):
    """Pose of body i in its parent (``ws_rot[i, ROT_PB]``, ``ws_vec[i, VEC_POS, 0:3]``); for a U-joint
    also its configuration-dependent motion subspace (the others are constant, see
    :func:`initialize_workspace`)."""
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
    """Write the constant motion subspaces (every hinge but the U-joint) into a fresh workspace."""
    for i in range(topology.shape[0]):
        if topology[i, HINGE_TYPE] != UJOINT:
            _body_motion_subspace(i, topology, joint_rot, joint_vec, ws_rot, ws_mat)


@njit(cache=True, inline="always")
def _body_velocity_kinematics(i, topology, joint_vec, u, ws_rot, ws_vec, ws_mat):
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
        # c_J = (s1 u1) x (s2 u2) on the angular rows, carried to the body origin: p_BM x (.)
        p_BM = joint_vec[i, OUTBOARD]
        g = u[u0] * u[u0 + 1]
        c[0] = g * (S[1, 0] * S[2, 1] - S[2, 0] * S[1, 1])
        c[1] = g * (S[2, 0] * S[0, 1] - S[0, 0] * S[2, 1])
        c[2] = g * (S[0, 0] * S[1, 1] - S[1, 0] * S[0, 1])
        c[3] = p_BM[1] * c[2] - p_BM[2] * c[1]
        c[4] = p_BM[2] * c[0] - p_BM[0] * c[2]
        c[5] = p_BM[0] * c[1] - p_BM[1] * c[0]
    motion_cross_motion_add(V, vJ, c)


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


@njit(cache=True)
def forward_dynamics(topology, hinge_dofs, joint_rot, joint_vec, spatial_inertia, ground_accel,
                     q, u, tau, body_forces, udot, tau_out, ws_rot, ws_vec, ws_mat):
    """Articulated-body forward dynamics with prescribed DOFs.

    On entry ``udot`` holds the prescribed accelerations at the prescribed DOFs (other entries are
    ignored); on exit it holds all accelerations. ``tau`` gives the generalized forces of the free DOFs;
    ``tau_out`` receives ``tau`` at free DOFs and the generalized force realizing the prescribed motion at
    prescribed DOFs. Returns 0, or 1 + the index of the first body whose articulated inertia is singular.
    """
    nb = topology.shape[0]
    for i in range(nb):
        _body_position_kinematics(i, topology, joint_rot, joint_vec, q, ws_rot, ws_vec, ws_mat)
        _body_velocity_kinematics(i, topology, joint_vec, u, ws_rot, ws_vec, ws_mat)
        S = ws_mat[i, MAT_S]
        c = ws_vec[i, VEC_C]
        u0 = topology[i, U_START]
        for kk in range(topology[i, N_PRESCRIBED]):
            k = hinge_dofs[i, 1, kk]
            acc = udot[u0 + k]
            for a in range(6):
                c[a] += S[a, k] * acc
        IA = ws_mat[i, MAT_IA]
        I = spatial_inertia[i]
        for a in range(6):
            for b in range(6):
                IA[a, b] = I[a, b]
        V = ws_vec[i, VEC_V]
        h = ws_vec[i, VEC_AUX]
        mat6_vec(I, V, h)
        pA = ws_vec[i, VEC_P]
        for a in range(6):
            pA[a] = -body_forces[i, a]
        motion_cross_force_add(V, h, pA)

    for i in range(nb - 1, -1, -1):
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
        for kk in range(nf):
            k = hinge_dofs[i, 0, kk]
            for a in range(6):
                s = 0.0
                for b in range(6):
                    s += IA[a, b] * S[b, k]
                U[a, kk] = s
        D = ws_mat[i, MAT_TMP]
        for kk in range(nf):
            k = hinge_dofs[i, 0, kk]
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
                return 1 + i
        # Ia = IA - U Dinv U^T ; pa = pA + Ia c + U Dinv d
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
        parent = topology[i, PARENT]
        if parent >= 0:
            R = ws_rot[i, ROT_PB]
            r = ws_vec[i, VEC_POS]
            inertia_to_parent_add(R, r, Ia, ws_mat[parent, MAT_IA], ws_mat[i, MAT_TMP])
            force_to_parent_add(R, r, pa, ws_vec[parent, VEC_P])

    for i in range(nb):
        A = ws_vec[i, VEC_A]
        parent_acceleration(i, topology, ground_accel, ws_rot, ws_vec, A)
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
        for kk in range(nf):
            s = 0.0
            for ll in range(nf):
                t = d[ll]
                for a in range(6):
                    t -= U[a, ll] * A[a]
                s += Dinv[kk, ll] * t
            k = hinge_dofs[i, 0, kk]
            udot[u0 + k] = s
            tau_out[u0 + k] = tau[u0 + k]
        for kk in range(nf):
            k = hinge_dofs[i, 0, kk]
            acc = udot[u0 + k]
            for a in range(6):
                A[a] += S[a, k] * acc
        npres = topology[i, N_PRESCRIBED]
        if npres > 0:
            f = ws_vec[i, VEC_AUX]
            mat6_vec(ws_mat[i, MAT_IA], A, f)
            pA = ws_vec[i, VEC_P]
            for kk in range(npres):
                k = hinge_dofs[i, 1, kk]
                s = 0.0
                for a in range(6):
                    s += S[a, k] * (f[a] + pA[a])
                tau_out[u0 + k] = s
    return 0


@njit(cache=True)
def inverse_dynamics(topology, joint_rot, joint_vec, spatial_inertia, ground_accel,
                     q, u, udot, body_forces, tau, ws_rot, ws_vec, ws_mat):
    """Recursive Newton-Euler: generalized forces ``tau`` realizing the accelerations ``udot``."""
    nb = topology.shape[0]
    for i in range(nb):
        _body_position_kinematics(i, topology, joint_rot, joint_vec, q, ws_rot, ws_vec, ws_mat)
        _body_velocity_kinematics(i, topology, joint_vec, u, ws_rot, ws_vec, ws_mat)
        A = ws_vec[i, VEC_A]
        parent_acceleration(i, topology, ground_accel, ws_rot, ws_vec, A)
        S = ws_mat[i, MAT_S]
        c = ws_vec[i, VEC_C]
        u0 = topology[i, U_START]
        nu = topology[i, NU_HINGE]
        for a in range(6):
            s = A[a] + c[a]
            for k in range(nu):
                s += S[a, k] * udot[u0 + k]
            A[a] = s
        I = spatial_inertia[i]
        f = ws_vec[i, VEC_P]
        mat6_vec(I, A, f)
        h = ws_vec[i, VEC_AUX]
        mat6_vec(I, ws_vec[i, VEC_V], h)
        motion_cross_force_add(ws_vec[i, VEC_V], h, f)
        for a in range(6):
            f[a] -= body_forces[i, a]
    for i in range(nb - 1, -1, -1):
        S = ws_mat[i, MAT_S]
        f = ws_vec[i, VEC_P]
        u0 = topology[i, U_START]
        for k in range(topology[i, NU_HINGE]):
            s = 0.0
            for a in range(6):
                s += S[a, k] * f[a]
            tau[u0 + k] = s
        parent = topology[i, PARENT]
        if parent >= 0:
            force_to_parent_add(ws_rot[i, ROT_PB], ws_vec[i, VEC_POS], f, ws_vec[parent, VEC_P])


@njit(cache=True)
def mass_matrix(topology, joint_rot, joint_vec, spatial_inertia, q, M, ws_rot, ws_vec, ws_mat):
    """Composite-rigid-body algorithm: the joint-space mass matrix ``M`` (nu x nu, overwritten)."""
    nb = topology.shape[0]
    for i in range(nb):
        _body_position_kinematics(i, topology, joint_rot, joint_vec, q, ws_rot, ws_vec, ws_mat)
        Ic = ws_mat[i, MAT_IA]
        I = spatial_inertia[i]
        for a in range(6):
            for b in range(6):
                Ic[a, b] = I[a, b]
    for i in range(nb - 1, -1, -1):
        parent = topology[i, PARENT]
        if parent >= 0:
            inertia_to_parent_add(ws_rot[i, ROT_PB], ws_vec[i, VEC_POS], ws_mat[i, MAT_IA],
                                  ws_mat[parent, MAT_IA], ws_mat[i, MAT_TMP])
    M[:, :] = 0.0
    for i in range(nb):
        nu_i = topology[i, NU_HINGE]
        if nu_i == 0:
            continue
        ui = topology[i, U_START]
        S = ws_mat[i, MAT_S]
        Ic = ws_mat[i, MAT_IA]
        F = ws_mat[i, MAT_U]
        for k in range(nu_i):
            for a in range(6):
                s = 0.0
                for b in range(6):
                    s += Ic[a, b] * S[b, k]
                F[a, k] = s
        for k in range(nu_i):
            for l in range(k, nu_i):  # symmetric by construction, not by round-off
                s = 0.0
                for a in range(6):
                    s += S[a, k] * F[a, l]
                M[ui + k, ui + l] = s
                M[ui + l, ui + k] = s
        j = i
        while topology[j, PARENT] >= 0:
            for k in range(nu_i):
                force_to_parent_inplace(ws_rot[j, ROT_PB], ws_vec[j, VEC_POS], F[:, k])
            j = topology[j, PARENT]
            nu_j = topology[j, NU_HINGE]
            uj = topology[j, U_START]
            Sj = ws_mat[j, MAT_S]
            for k in range(nu_j):
                for l in range(nu_i):
                    s = 0.0
                    for a in range(6):
                        s += Sj[a, k] * F[a, l]
                    M[uj + k, ui + l] = s
                    M[ui + l, uj + k] = s


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
def world_poses(topology, joint_rot, joint_vec, q, ws_rot, ws_vec, ws_mat):
    """World poses of every body (see :func:`accumulate_world_poses`); also leaves the parent-relative
    poses and motion subspaces in the workspace."""
    for i in range(topology.shape[0]):
        _body_position_kinematics(i, topology, joint_rot, joint_vec, q, ws_rot, ws_vec, ws_mat)
    accumulate_world_poses(topology, ws_rot, ws_vec)


@njit(cache=True, inline="always")
def parent_acceleration(i, topology, ground_accel, ws_rot, ws_vec, A):
    """A = X_i a_parent (the ground's acceleration ``ground_accel`` for a root body)."""
    parent = topology[i, PARENT]
    if parent >= 0:
        motion_to_child(ws_rot[i, ROT_PB], ws_vec[i, VEC_POS], ws_vec[parent, VEC_A], A)
    else:
        motion_to_child(ws_rot[i, ROT_PB], ws_vec[i, VEC_POS], ground_accel, A)


@njit(cache=True)
def accumulate_energy_momentum(M, x, h, n, R, p, ground_accel, out):
    """Add one body's kinetic energy 1/2 x'Mx, gravity potential and world momentum to ``out``.

    ``M`` (n x n, rigid block first: ``[[J, m c~], [-m c~, m I]]``) is the body's mass matrix about its
    origin, ``x`` its velocity (``[omega; v]`` then modal rates), ``R``/``p`` its world pose; ``h`` is an
    n-vector scratch that receives the momentum ``M x``."""
    ke = 0.0
    for a in range(n):
        s = 0.0
        for b in range(n):
            s += M[a, b] * x[b]
        h[a] = s
        ke += x[a] * s
    out[0] += 0.5 * ke
    m = M[3, 3]
    # center of mass from the coupling block m skew(c): c = (M[2,4], M[0,5], M[1,3]) / m
    cx = M[2, 4] / m
    cy = M[0, 5] / m
    cz = M[1, 3] / m
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
def node_kinematics(topology, joint_rot, joint_vec, node_body, node_rot, node_pos,
                    q, u, udot, rotation, position, velocity, acceleration, ws_rot, ws_vec, ws_mat):
    """Pose, spatial velocity and acceleration of every node (a frame fixed on a body).

    Outputs per node n: ``rotation[n]`` node -> world, ``position[n]`` in the world, ``velocity[n]`` the
    spatial velocity ``[omega; v]`` of the node frame in node axes (v: velocity of the node origin), and
    ``acceleration[n] = [omega_dot; a]`` in node axes with ``a`` the classical (not spatial) acceleration
    of the node origin, ``a = a_spatial + omega x v``. Accelerations are relative to the inertial frame:
    gravity is *not* included (an accelerometer reads ``a - g``).
    """
    nb = topology.shape[0]
    world_poses(topology, joint_rot, joint_vec, q, ws_rot, ws_vec, ws_mat)
    for i in range(nb):
        _body_velocity_kinematics(i, topology, joint_vec, u, ws_rot, ws_vec, ws_mat)
        parent = topology[i, PARENT]
        A = ws_vec[i, VEC_A]
        if parent >= 0:
            motion_to_child(ws_rot[i, ROT_PB], ws_vec[i, VEC_POS], ws_vec[parent, VEC_A], A)
        else:
            for a in range(6):
                A[a] = 0.0
        S = ws_mat[i, MAT_S]
        c = ws_vec[i, VEC_C]
        u0 = topology[i, U_START]
        for a in range(6):
            s = A[a] + c[a]
            for k in range(topology[i, NU_HINGE]):
                s += S[a, k] * udot[u0 + k]
            A[a] = s
    for n in range(node_body.shape[0]):
        b = node_body[n]
        R_BN = node_rot[n]
        p_BN = node_pos[n]
        R_WB = ws_rot[b, ROT_WB]
        pw = ws_vec[b, VEC_WPOS]
        for a in range(3):
            position[n, a] = pw[a] + R_WB[a, 0] * p_BN[0] + R_WB[a, 1] * p_BN[1] + R_WB[a, 2] * p_BN[2]
            for k in range(3):
                rotation[n, a, k] = R_WB[a, 0] * R_BN[0, k] + R_WB[a, 1] * R_BN[1, k] + R_WB[a, 2] * R_BN[2, k]
        motion_to_child(R_BN, p_BN, ws_vec[b, VEC_V], velocity[n])
        motion_to_child(R_BN, p_BN, ws_vec[b, VEC_A], acceleration[n])
        w = velocity[n]
        acc = acceleration[n]
        acc[3] += w[1] * w[5] - w[2] * w[4]
        acc[4] += w[2] * w[3] - w[0] * w[5]
        acc[5] += w[0] * w[4] - w[1] * w[3]


@njit(cache=True)
def node_forces_to_bodies(node_body, node_rot, node_pos, node_forces, body_forces):
    """Sum node spatial forces (node axes, about the node origin) into body forces (body axes, origin)."""
    body_forces[:, :] = 0.0
    for n in range(node_body.shape[0]):
        force_to_parent_add(node_rot[n], node_pos[n], node_forces[n], body_forces[node_body[n]])


@njit(cache=True)
def energy_momentum(topology, joint_rot, joint_vec, spatial_inertia, ground_accel, q, u, out,
                    ws_rot, ws_vec, ws_mat):
    """``out = [kinetic, potential, P_x, P_y, P_z, L_x, L_y, L_z]`` with the potential of the uniform
    field ``-sum m g . r_com`` and the angular momentum about the world origin, world axes."""
    nb = topology.shape[0]
    world_poses(topology, joint_rot, joint_vec, q, ws_rot, ws_vec, ws_mat)
    for a in range(8):
        out[a] = 0.0
    for i in range(nb):
        _body_velocity_kinematics(i, topology, joint_vec, u, ws_rot, ws_vec, ws_mat)
        accumulate_energy_momentum(spatial_inertia[i], ws_vec[i, VEC_V], ws_vec[i, VEC_AUX], 6,
                                   ws_rot[i, ROT_WB], ws_vec[i, VEC_WPOS], ground_accel, out)
