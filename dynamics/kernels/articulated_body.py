"""Forward dynamics by the articulated-body algorithm (RBDA Table 7.1) in augmented form, O(N), with
prescribed hinge DOFs (their known accelerations enter the bias, their forces come from ``IA a + pA``, RBDA
sec. 9.3); a flexible body's modal DOFs are eliminated by :mod:`dynamics.kernels.modal_condensation`.
"""

from __future__ import annotations

from numba import njit

from dynamics.kernels.body_terms import apply_node_forces, flexible_body_terms, rigid_bias_add
from dynamics.kernels.kinematics import general_kinematics, parent_acceleration_general, rigid_position, rigid_velocity
from dynamics.kernels.modal_condensation import condense_modes, modal_accelerations, to_slot
from dynamics.kernels.small_linalg import spd_inverse
from dynamics.layout import (
    FLEX, FLEXIBLE, FREE_DOFS, FX_GINV_KIND, FX_P_MRR, GENERAL, GINV_FACTORED, GROUND_ACCEL, INERTIA, MAT_DINV,
    MAT_IA, MAT_IAP, MAT_S, MAT_TMP, MAT_U, N_FREE, N_MODES, N_PRESCRIBED, PARENT, PARENT_NODE, PRESCRIBED_DOFS,
    ROT_PB, U_START, VEC_A, VEC_AUX, VEC_C, VEC_D, VEC_P, VEC_POS, VEC_V, view)
from dynamics.spatial import force_to_parent_add, inertia_to_parent_add, mat6_vec, motion_to_child


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
        if not spd_inverse(D, nf, tol, ws_mat[i, MAT_IAP], Dinv):
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
def _flexible_inertia_and_bias(i, topology, params, q, u, body_forces, ws_vec, ws_mat, pool):
    """Pass 1 of the ABA at a flexible body: IA = M_rr(eta) and pA = b - f_ext (modal rows in the pool)."""
    flexible_body_terms(i, topology, params, q, u, ws_vec, ws_mat, pool, True,
                         topology[i, FLEX + FX_GINV_KIND] == GINV_FACTORED)
    IA = ws_mat[i, MAT_IA]
    pA = ws_vec[i, VEC_P]
    M = view(pool, topology[i, FLEX + FX_P_MRR], 6, 6)
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
            general_kinematics(i, topology, nodes, joint_rot, joint_vec, params, q, u, ws_rot, ws_vec, ws_mat, pool,
                                True)
        else:
            rigid_position(i, topology, joint_rot, joint_vec, q, ws_rot, ws_vec, ws_mat)
            rigid_velocity(i, topology, joint_vec, u, ws_rot, ws_vec, ws_mat)
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
    apply_node_forces(topology, nodes, params, q, node_forces, ws_vec, pool, -1.0)

    for i in range(nb - 1, -1, -1):
        if topology[i, FLEXIBLE]:
            if not condense_modes(i, topology, nodes, params, tau, ws_mat, ws_vec, pool):
                return 1 + i
        if not _eliminate_hinge(i, topology, tau, ws_mat, ws_vec):
            return 1 + i
        parent = topology[i, PARENT]
        if topology[i, PARENT_NODE] >= 0:
            to_slot(i, topology, nodes, ws_mat[i, MAT_IAP], ws_vec[i, VEC_AUX], ws_rot, ws_vec, ws_mat, pool)
        elif parent >= 0:
            R = ws_rot[i, ROT_PB]
            r = ws_vec[i, VEC_POS]
            inertia_to_parent_add(R, r, ws_mat[i, MAT_IAP], ws_mat[parent, MAT_IA], ws_mat[i, MAT_TMP])
            force_to_parent_add(R, r, ws_vec[i, VEC_AUX], ws_vec[parent, VEC_P])

    for i in range(nb):
        A = ws_vec[i, VEC_A]
        parent = topology[i, PARENT]
        if topology[i, GENERAL]:
            parent_acceleration_general(i, topology, nodes, ground, udot, ws_rot, ws_vec, pool, A)
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
            modal_accelerations(i, topology, nodes, tau, udot, tau_out, ws_vec, pool)
    return 0
