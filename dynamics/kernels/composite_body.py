"""The joint-space mass matrix: composite-rigid-body algorithm (RBDA Table 6.2) in augmented form,
exactly symmetric; a flexible body's composite inertia keeps its full ``6 + n`` block.
"""

from __future__ import annotations

from numba import njit

from dynamics.kernels.body_terms import flexible_body_terms
from dynamics.kernels.kinematics import body_kinematics
from dynamics.layout import (
    FLEX, FLEXIBLE, FX_P_BP, FX_P_F, FX_P_G, FX_P_MRE, FX_P_MRR, INERTIA, MAT_IA, MAT_IAP, MAT_S, MAT_TMP, MAT_U,
    NODE_SLOT, NU_HINGE, N_FX, N_MODES, OUTBOARD_NODE, PARENT, PARENT_NODE, ROT_PB, SL_PSI, U_START, VEC_POS, view)
from dynamics.spatial import force_to_parent_inplace, inertia_to_parent_add


@njit(cache=True)
def mass_matrix(topology, nodes, joint_rot, joint_vec, params, q, u, M, ws_rot, ws_vec, ws_mat, pool):
    """Composite-rigid-body algorithm in augmented form: the joint-space mass matrix ``M`` (nu x nu,
    overwritten). The composite inertia of a flexible body ``Ic = M(eta) + sum_c P_c' Ic_c P_c`` keeps
    its full ``6 + n`` block; ``u`` only feeds velocity terms the result does not depend on."""
    nb = topology.shape[0]
    for i in range(nb):
        body_kinematics(i, topology, nodes, joint_rot, joint_vec, params, q, u, ws_rot, ws_vec, ws_mat, pool, False)
        Ic = ws_mat[i, MAT_IA]
        if topology[i, FLEXIBLE]:
            flexible_body_terms(i, topology, params, q, u, ws_vec, ws_mat, pool, False, True)
            Mrr = view(pool, topology[i, FLEX + FX_P_MRR], 6, 6)
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
            Psi = view(pool, nodes[jnode, NODE_SLOT] + SL_PSI, 6, n_p)
            fxp = topology[parent, FLEX:FLEX + N_FX]
            Icre = view(pool, fxp[FX_P_MRE], 6, n_p)
            Icee = view(pool, fxp[FX_P_G], n_p, n_p)
            YPsi = view(pool, fxp[FX_P_BP], 6, n_p)
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
        fx = topology[i, FLEX:FLEX + N_FX]
        F = view(pool, fx[FX_P_F], 6, ncol) if topology[i, FLEXIBLE] else ws_mat[i, MAT_U]
        Icre = view(pool, fx[FX_P_MRE], 6, n) if n > 0 else view(pool, 0, 6, 0)
        Pc = view(pool, nodes[onode, NODE_SLOT] + SL_PSI, 6, n) if onode >= 0 else view(pool, 0, 6, 0)
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
            Icee = view(pool, fx[FX_P_G], n, n)
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
