"""Inverse dynamics: recursive Newton-Euler (RBDA Table 5.1) in augmented form,
``F_k = M_k(eta) xdot_k + b_k - f_ext,k``, ``tau_k = H_k' F_k``, ``F_parent += P_k' F_k``.
"""

from __future__ import annotations

from numba import njit

from dynamics.kernels.body_terms import apply_node_forces, flexible_body_terms, modal_mass_times, rigid_bias_add
from dynamics.kernels.kinematics import add_hinge_acceleration, body_kinematics, parent_acceleration
from dynamics.layout import (
    FLEX, FLEXIBLE, FX_GINV_KIND, FX_P_MRE, FX_P_MRR, FX_P_VEC, GINV_FACTORED, GROUND_ACCEL, INERTIA, MAT_S,
    NODE_SLOT, NU_HINGE, N_FX, N_MODES, OUTBOARD_NODE, PARENT, PARENT_NODE, PV_FORCE, PV_TMP, P_V1, ROT_PB, SL_PSI,
    U_START, VEC_A, VEC_P, VEC_POS, VEC_V, view)
from dynamics.spatial import force_to_parent_add


@njit(cache=True)
def inverse_dynamics(topology, nodes, joint_rot, joint_vec, params, q, u, udot, node_forces, body_forces, tau,
                     ws_rot, ws_vec, ws_mat, pool):
    """Recursive Newton-Euler in augmented form: F_i = M_i a_i + b_i - f_ext,i; tau_i = H_i' F_i;
    F_parent += P_i' F_i (module docstring)."""
    nb = topology.shape[0]
    ground = params[GROUND_ACCEL:GROUND_ACCEL + 6]
    for i in range(nb):
        body_kinematics(i, topology, nodes, joint_rot, joint_vec, params, q, u, ws_rot, ws_vec, ws_mat, pool, True)
        A = ws_vec[i, VEC_A]
        parent_acceleration(i, topology, nodes, ground, udot, ws_rot, ws_vec, pool, A)
        add_hinge_acceleration(i, topology, nodes, udot, ws_vec, ws_mat, pool, A)
        f = ws_vec[i, VEC_P]
        if topology[i, FLEXIBLE]:
            n = topology[i, N_MODES]
            fx = topology[i, FLEX:FLEX + N_FX]
            flexible_body_terms(i, topology, params, q, u, ws_vec, ws_mat, pool, True,
                                 fx[FX_GINV_KIND] == GINV_FACTORED)
            # F_r = b_r + M_rr a + M_re etaddot - f_ext, F_m = b_m + M_re' a + G etaddot
            M = view(pool, topology[i, FLEX + FX_P_MRR], 6, 6)
            Mre = view(pool, fx[FX_P_MRE], 6, n)
            ue = topology[i, U_START] + topology[i, NU_HINGE]
            am = udot[ue:ue + n]
            for a in range(6):
                s_ = 0.0
                for b in range(6):
                    s_ += M[a, b] * A[b]
                for s in range(n):
                    s_ += Mre[a, s] * am[s]
                f[a] += s_ - body_forces[i, a]
            pv = fx[FX_P_VEC]
            Ga = pool[pv + PV_TMP * n:pv + (PV_TMP + 1) * n]
            modal_mass_times(i, topology, params, pool, am, Ga)
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
    apply_node_forces(topology, nodes, params, q, node_forces, ws_vec, pool, -1.0)
    transmit_forces(topology, nodes, tau, ws_rot, ws_vec, ws_mat, pool)


@njit(cache=True)
def transmit_forces(topology, nodes, tau, ws_rot, ws_vec, ws_mat, pool):
    """The backward pass of :func:`inverse_dynamics`: each body's force ``ws_vec[i, VEC_P]`` (and a flexible
    body's modal force in the pool) carried to its parent, ``F_parent += P_i' F_i``, and projected on its
    hinge and modes, ``tau_i = H_i' F_i``. On exit ``ws_vec[i, VEC_P]`` is the spatial force the parent
    transmits to body i through its hinge (body axes, about the body origin)."""
    nb = topology.shape[0]
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
            pv = topology[i, FLEX + FX_P_VEC]
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
                Psi = view(pool, nodes[jnode, NODE_SLOT] + SL_PSI, 6, n_p)
                pv = topology[parent, FLEX + FX_P_VEC] + PV_FORCE * n_p
                for a in range(6):
                    fp[a] += y[a]
                for s in range(n_p):
                    t = 0.0
                    for a in range(6):
                        t += Psi[a, s] * y[a]
                    pool[pv + s] += t
            else:
                force_to_parent_add(ws_rot[i, ROT_PB], ws_vec[i, VEC_POS], f, ws_vec[parent, VEC_P])
