"""Per-body inertia and forces for the recursions: the rigid bias ``V x* I V``, a flexible body's ``M(eta)``
blocks and gyroscopic, Coriolis and elastic forces (:func:`dynamics.flexible_kernels.modal_mass_and_bias`,
TM-2020-5008164 eqs. E.2.2-E.2.6, the terms of nodes with rotary inertia summed over the nodes by
:mod:`dynamics.kernels.node_inertia`, C1 and J2 over every node by :mod:`dynamics.kernels.node_mass`, with
node_inertia's passes where their nodes are the same), products with its modal mass, and the generalized forces of
node forces ``[X'; Psi' X'] f`` (a force in node axes at the deformed node).
"""

from __future__ import annotations

from numba import njit

from dynamics import flexible_kernels as FK
from dynamics.kernels.node_inertia import (NODE_STATE, node_inertia_modal_mass, node_inertia_pass, node_inertia_terms,
                                           node_inertia_times)
from dynamics.kernels.node_mass import MASS_NODE_STATE, node_mass_terms
from dynamics.layout import (
    FLEX, FX_MASS_NODE_COUNT, FX_MASS_NODE_TERMS, FX_MASS_NODES, FX_NODES, FX_NODE_COUNT, FX_NODE_TERMS, FX_P_G,
    FX_P_MASS_NODES, FX_P_MDRE, FX_P_MRE, FX_P_MRR, FX_P_NODES, FX_P_VEC, FX_REFINE, INERTIA, MAT_IAP, NODE_BODY,
    NODE_FRAME, NODE_SHAPE, NQ_HINGE, NU_HINGE, N_FX, N_MODES, PV_FORCE, P_L, P_R, P_TMP83, P_V1, Q_START, U_START,
    VEC_P, VEC_V, view)
from dynamics.spatial import force_to_parent_add


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
def flexible_body_terms(i, topology, params, q, u, ws_vec, ws_mat, pool, with_bias, form_G):
    """``M_rr(eta)`` into the pool (``FX_P_MRR``), ``M_re(eta)`` and (``form_G``) ``G(eta)`` into the pool and,
    with ``with_bias``, the body forces ``b`` into ``ws_vec[i, VEC_P]`` and the pool (``PV_FORCE``)."""
    n = topology[i, N_MODES]
    qe = topology[i, Q_START] + topology[i, NQ_HINGE]
    ue = topology[i, U_START] + topology[i, NU_HINGE]
    fx = topology[i, FLEX:FLEX + N_FX]
    Mrr = view(pool, topology[i, FLEX + FX_P_MRR], 6, 6)
    o = topology[i, INERTIA]
    for a in range(6):
        for b in range(6):
            Mrr[a, b] = params[o + 6 * a + b]
    pv = fx[FX_P_VEC]
    Mre = view(pool, fx[FX_P_MRE], 6, n)
    Gm = view(pool, fx[FX_P_G], n, n)
    bm = pool[pv + PV_FORCE * n:pv + (PV_FORCE + 1) * n]
    FK.modal_mass_and_bias(fx, params, n, q[qe:qe + n], ws_vec[i, VEC_V], u[ue:ue + n], with_bias, form_G, Mrr,
                           Mre, Gm, ws_vec[i, VEC_P], bm, ws_mat[i, MAT_IAP], view(pool, fx[FX_P_MDRE], 6, n))
    nodes = fx[FX_NODES]
    mass_nodes = fx[FX_MASS_NODES]
    shared = mass_nodes >= 0 and params[mass_nodes + 2] != 0.0  # C1, J2 over the node-inertia nodes
    count = fx[FX_NODE_COUNT]
    state = pool[fx[FX_P_NODES]:fx[FX_P_NODES] + NODE_STATE * count]
    if nodes >= 0:
        if shared:  # its products back in node_mass_terms's sweeps
            node_inertia_pass(params, nodes, count, n, fx[FX_NODE_TERMS], q[qe:qe + n], ws_vec[i, VEC_V],
                              u[ue:ue + n], with_bias, ws_vec[i, VEC_P], state, True)
        else:
            node_inertia_terms(params, nodes, count, n, fx[FX_NODE_TERMS], q[qe:qe + n], ws_vec[i, VEC_V],
                               u[ue:ue + n], with_bias, Mre, ws_vec[i, VEC_P], bm, state)
    if mass_nodes >= 0:
        mcount = fx[FX_MASS_NODE_COUNT]
        node_mass_terms(params, mass_nodes, mcount, n, fx[FX_MASS_NODE_TERMS], q[qe:qe + n], ws_vec[i, VEC_V],
                        u[ue:ue + n], with_bias, Mrr, Mre, ws_vec[i, VEC_P], bm,
                        pool[fx[FX_P_MASS_NODES]:fx[FX_P_MASS_NODES] + MASS_NODE_STATE * mcount], nodes,
                        fx[FX_NODE_TERMS], state)
    if nodes >= 0 and form_G:  # last: its blocks of modes overwrite the pass coefficients node_mass_terms reads
        node_inertia_modal_mass(params, nodes, count, n, fx[FX_NODE_TERMS], state, Gm)


@njit(cache=True)
def modal_mass_times(i, topology, params, pool, a, out):
    """``out = G a`` with flexible body i's modal mass of this evaluation (after :func:`flexible_body_terms`):
    ``G(eta)`` when formed, else ``G0`` plus the node terms of a refined body."""
    n = topology[i, N_MODES]
    fx = topology[i, FLEX:FLEX + N_FX]
    FK.modal_mass_times(fx, params, n, view(pool, fx[FX_P_G], n, n), a, out)
    if fx[FX_REFINE]:
        count = fx[FX_NODE_COUNT]
        node_inertia_times(params, fx[FX_NODES], count, n, fx[FX_NODE_TERMS],
                           pool[fx[FX_P_NODES]:fx[FX_P_NODES] + NODE_STATE * count], a, out)


@njit(cache=True)
def apply_node_forces(topology, nodes, params, q, node_forces, ws_vec, pool, sign):
    """Body forces ``ws_vec[:, VEC_P]`` (and modal forces of flexible bodies) ``+= sign`` times the
    generalized forces of the node forces (node axes, at the deformed node): ``[X'; Psi' X'] f``."""
    tmp83 = view(pool, P_TMP83, 8, 3)
    Rn = view(pool, P_R, 3, 3)
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
            shape = view(params, nodes[nd, NODE_SHAPE], 6, n)
            FK.node_pose(shape, params[fr + 9:fr + 12], view(params, fr, 3, 3), q[qe:qe + n], n, Rn, l, tmp83)
            force_to_parent_add(Rn, l, f, f6)
            pv = topology[b, FLEX + FX_P_VEC] + PV_FORCE * n
            FK.node_modal_force(shape, n, tmp83[0], Rn, f, sign, pool[pv:pv + n])
        else:
            force_to_parent_add(view(params, fr, 3, 3), params[fr + 9:fr + 12], f, f6)
        P = ws_vec[b, VEC_P]
        for a in range(6):
            P[a] += sign * f6[a]
