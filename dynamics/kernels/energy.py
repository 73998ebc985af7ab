"""Energy and momentum of the system in the world frame: kinetic energy, potential energy (uniform gravity
and the modal strain energy ``1/2 eta' K eta``), linear and angular momentum.
"""

from __future__ import annotations

from numba import njit

from dynamics.kernels.body_terms import flexible_body_terms, modal_mass_times
from dynamics.kernels.kinematics import accumulate_world_poses, body_kinematics
from dynamics.layout import (
    FLEX, FLEXIBLE, FX_GINV_KIND, FX_K, FX_P_MRE, FX_P_MRR, FX_P_VEC, GINV_FACTORED, GROUND_ACCEL, INERTIA, NQ_HINGE,
    NU_HINGE, N_FX, N_MODES, PV_TMP, Q_START, ROT_WB, U_START, VEC_AUX, VEC_V, VEC_WPOS, view)
from dynamics.spatial import mat6_vec


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
    ``-sum m g^T r_com`` plus the elastic ``1/2 eta' K eta``, the angular momentum about the world origin,
    world axes. Leaves the world poses and body velocities in the workspace."""
    nb = topology.shape[0]
    ground = params[GROUND_ACCEL:GROUND_ACCEL + 6]
    for i in range(nb):
        body_kinematics(i, topology, nodes, joint_rot, joint_vec, params, q, u, ws_rot, ws_vec, ws_mat, pool, True)
    accumulate_world_poses(topology, ws_rot, ws_vec)
    for a in range(8):
        out[a] = 0.0
    for i in range(nb):
        V = ws_vec[i, VEC_V]
        h = ws_vec[i, VEC_AUX]
        if topology[i, FLEXIBLE]:
            n = topology[i, N_MODES]
            fx = topology[i, FLEX:FLEX + N_FX]
            flexible_body_terms(i, topology, params, q, u, ws_vec, ws_mat, pool, False,
                                 fx[FX_GINV_KIND] == GINV_FACTORED)
            Mrr = view(pool, topology[i, FLEX + FX_P_MRR], 6, 6)
            Mre = view(pool, fx[FX_P_MRE], 6, n)
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
            pv = fx[FX_P_VEC]
            Ge = pool[pv + PV_TMP * n:pv + (PV_TMP + 1) * n]
            modal_mass_times(i, topology, params, pool, e, Ge)
            for s in range(n):
                t = Ge[s]
                for a in range(6):
                    t += Mre[a, s] * V[a]
                ke += e[s] * t
            accumulate_energy_momentum(Mrr, h, ke, ws_rot[i, ROT_WB], ws_vec[i, VEC_WPOS], ground, out)
            ok = fx[FX_K]
            el = 0.0
            for r in range(n):
                for s in range(n):
                    el += q[qe + r] * params[ok + r * n + s] * q[qe + s]
            out[1] += 0.5 * el
        else:
            I = view(params, topology[i, INERTIA], 6, 6)
            mat6_vec(I, V, h)
            ke = 0.0
            for a in range(6):
                ke += V[a] * h[a]
            accumulate_energy_momentum(I, h, ke, ws_rot[i, ROT_WB], ws_vec[i, VEC_WPOS], ground, out)
