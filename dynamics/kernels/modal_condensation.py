"""The modal elimination of a flexible body inside the articulated-body algorithm (Jain, *Robot and
Multibody Dynamics*, 2011, ch. 13): a body's modal DOFs are eliminated before its hinge DOFs by a Schur
complement whose modal block ``E' = G + L' Q L`` is the modal mass ``G`` plus updates of rank 6 per node
that children hang from (12 more for a hinge on a node of the body), inverted with a symmetric Woodbury
identity (:func:`condense_inertia`, then :func:`condense_bias` for the forces: the split lets the forward
dynamics solve again with other modal forces, as its refinement of an eta-dependent modal mass does); the
children's articulated inertias and forces are summed per node (:func:`inertia_to_slot`, :func:`force_to_slot`)
and the modal accelerations follow from the rigid acceleration (:func:`modal_accelerations`).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from dynamics import flexible_kernels as FK
from dynamics.flexible_kernels import FAST_SUMS
from dynamics.kernels.small_linalg import lu_factor, lu_solve_column, psd_factor, symmetric_eigen
from dynamics.layout import (
    FIRST_SLOT, FLEX, FX_C1, FX_F2, FX_GINV_KIND, FX_NODE_TERMS, FX_P_BP, FX_P_G, FX_P_MRE, FX_P_SMALL, FX_P_VEC,
    FX_P_W, FX_P_ZM, FX_RANK, FX_REFINE, FX_ZM0, GINV_FACTORED, MAT_IA, MAT_TMP, NODE_F2, NODE_NEXT_SLOT, NODE_SLOT,
    NU_HINGE, N_FX, N_MODES, OUTBOARD_NODE, PARENT_NODE, PV_DG, PV_FORCE, PV_RHS, PV_TMP, PV_Y, P_TMP83, ROT_PB, SL_G,
    SL_PSI, SL_Y, U_START, VEC_A, VEC_P, VEC_POS, view)
from dynamics.layout import FX_MASS_NODE_TERMS, MASS_C1
from dynamics.spatial import force_to_parent_add, inertia_to_parent_add


@njit(cache=True)
def _woodbury_rows(i, b, topology, nodes, pool, n, inverse):
    """Row block b of L = [Psi_1; ...; Psi_m; Pc; M_re] (or, with ``inverse``, of L G^-1) of body i."""
    nd = topology[i, FIRST_SLOT]
    k = 0
    shift = 6 * n if inverse else 0
    while nd >= 0:
        if k == b:
            return view(pool, nodes[nd, NODE_SLOT] + SL_PSI + shift, 6, n)
        k += 1
        nd = nodes[nd, NODE_NEXT_SLOT]
    if b == k:
        return view(pool, nodes[topology[i, OUTBOARD_NODE], NODE_SLOT] + SL_PSI + shift, 6, n)
    return view(pool, topology[i, FLEX + (FX_P_ZM if inverse else FX_P_MRE)], 6, n)


@njit(cache=True)
def condense_inertia(i, topology, nodes, params, factored, ws_mat, pool):
    """Eliminate the modal DOFs of flexible body i before its hinge DOFs (forward dynamics, pass 2): the
    inertia part, which the bias part :func:`condense_bias` (solved again by every refinement) reuses.

    With the articulated inertia ``IA = [[A, B], [B', E]]`` of the body and its children (A 6 x 6, B 6 x n,
    E n x n) and the modal subspace ``H_m = [-Pc; I]``: ``B' = B - A Pc``, ``E' = H_m' IA H_m``, and the
    body's rigid block after the modal elimination is ``A'' = A - B' E'^-1 B''``. Children hang from nodes
    j with ``Psi_j`` and pass ``Y_j`` (their articulated inertia) and ``g_j`` (force), so ``A = A0 + sum Y_j``,
    ``B = M_re + sum Y_j Psi_j`` and

        E' = G + L' Q L,  L = [Psi_1; ...; Psi_m; Pc; M_re],
        Q = [[Y_j on the diagonal, -Y_j against Pc], [-Y_j, A, -I], [0, -I, 0]]

    (rank 6 m, plus 12 with Pc). Woodbury in symmetric form: with ``Q = V diag(lam) V'``,
    ``U = |lam|^1/2 V' L`` and ``S = sign(lam)``, ``E' = G + U' S U`` and
    ``E'^-1 v = G^-1 v - Z' (S + U Z')^-1 U G^-1 v``, ``Z = U G^-1`` (r x r solve, its LU kept for the bias
    part), where ``Psi_j G^-1`` comes from the precomputed ``Pi G^-1`` in O(n)
    (:func:`dynamics.flexible_kernels.psi_times_inverse_modal_mass`). The symmetric form matters: with
    heavy children (``|Q K|`` >> 1) the textbook ``(I + Q K)^-1`` is ill-conditioned even when E' is not
    (a 500 kg mass on a beam tip: condition 6e5, Schur complement wrong in the 11th digit, against 60
    and the 15th digit here). ``G`` is the body's modal mass, or the constant ``G0`` of a body whose
    ``G(eta) - G0`` the forward dynamics refines (``FX_REFINE``); ``factored`` treats such a body's ``G(eta)``
    (formed in pass 1) as factored per call. Writes ``A''`` into ``ws_mat[i, MAT_IA]`` and keeps
    ``W' = B' E'^-1``. Returns False when the modal mass is singular."""
    n = topology[i, N_MODES]
    A = ws_mat[i, MAT_IA]
    nd = topology[i, FIRST_SLOT]
    while nd >= 0:
        s = nodes[nd, NODE_SLOT]
        for a in range(6):
            for b in range(6):
                A[a, b] += pool[s + SL_Y + 6 * a + b]
        nd = nodes[nd, NODE_NEXT_SLOT]
    if n == 0:
        return True
    fx = topology[i, FLEX:FLEX + N_FX]
    kind = modal_mass_kind(fx, factored)
    onode = topology[i, OUTBOARD_NODE]
    Mre = view(pool, fx[FX_P_MRE], 6, n)
    ZM = view(pool, fx[FX_P_ZM], 6, n)
    Gm = view(pool, fx[FX_P_G], n, n)
    if kind == GINV_FACTORED:
        if FK.cholesky_in_place(Gm, n) >= 0:
            return False
        nd = topology[i, FIRST_SLOT]
        while nd >= 0:
            s = nodes[nd, NODE_SLOT]
            FK.modal_mass_solve_rows(fx, kind, params, n, Gm, view(pool, s + SL_PSI, 6, n), 6,
                                     view(pool, s + SL_PSI + 6 * n, 6, n))
            nd = nodes[nd, NODE_NEXT_SLOT]
        if onode >= 0:
            s = nodes[onode, NODE_SLOT]
            FK.modal_mass_solve_rows(fx, kind, params, n, Gm, view(pool, s + SL_PSI, 6, n), 6,
                                     view(pool, s + SL_PSI + 6 * n, 6, n))
        FK.modal_mass_solve_rows(fx, kind, params, n, Gm, Mre, 6, ZM)
    elif (fx[FX_C1] >= 0 or fx[FX_F2] >= 0 or (fx[FX_NODE_TERMS] & NODE_F2) != 0
          or (fx[FX_MASS_NODE_TERMS] & MASS_C1) != 0):
        FK.modal_mass_solve_rows(fx, kind, params, n, Gm, Mre, 6, ZM)
    else:
        o = fx[FX_ZM0]
        for a in range(6):
            for s in range(n):
                ZM[a, s] = params[o + a * n + s]
    # B' = M_re - A Pc + sum_j Y_j Psi_j, and B' G^-1 (kept in the W' block, solved in place below)
    Bp = view(pool, fx[FX_P_BP], 6, n)
    W = view(pool, fx[FX_P_W], 6, n)
    for a in range(6):
        for s in range(n):
            Bp[a, s] = Mre[a, s]
            W[a, s] = ZM[a, s]
    if onode >= 0:
        so = nodes[onode, NODE_SLOT]
        Pc = view(pool, so + SL_PSI, 6, n)
        Zc = view(pool, so + SL_PSI + 6 * n, 6, n)
        for a in range(6):
            for b in range(6):
                y_ = A[a, b]
                for s in range(n):
                    Bp[a, s] -= y_ * Pc[b, s]
                    W[a, s] -= y_ * Zc[b, s]
    nd = topology[i, FIRST_SLOT]
    while nd >= 0:
        so = nodes[nd, NODE_SLOT]
        Psi = view(pool, so + SL_PSI, 6, n)
        Z = view(pool, so + SL_PSI + 6 * n, 6, n)
        for a in range(6):
            for b in range(6):
                y_ = pool[so + SL_Y + 6 * a + b]
                for s in range(n):
                    Bp[a, s] += y_ * Psi[b, s]
                    W[a, s] += y_ * Z[b, s]
        nd = nodes[nd, NODE_NEXT_SLOT]
    r = fx[FX_RANK]
    if r > 0:
        # E' = G + L' Q L = G + U' S U with Q = V diag(lam) V' (Jacobi), U = |lam|^1/2 V' L, S = sign(lam);
        # E'^-1 v = G^-1 v - Z' C^-1 (U G^-1 v), Z = U G^-1, C = S + U Z' (symmetric, and positive definite
        # with condition number of the order of E''s when Q is: the children's inertias, no Pc)
        so = fx[FX_P_SMALL]
        Vq = view(pool, so, r, r)
        Q = view(pool, so + r * r, r, r)
        Aug = view(pool, so + 2 * r * r, r, r + 7)
        Ut = view(pool, so + 3 * r * r + 7 * r, r, n)
        Zt = view(pool, so + 3 * r * r + 7 * r + r * n, r, n)
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
                L = view(pool, so + 36 * b, 6, 6)  # in the V block (r^2 >= 36 blocks)
                piv = pool[P_TMP83:P_TMP83 + 6]
                psd_factor(Q[6 * b:6 * b + 6, 6 * b:6 * b + 6], L, piv)
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
            symmetric_eigen(Q, r, Vq)
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
        piv = Q[0]  # Q is not needed past this point: its first row keeps the LU pivots for the bias part
        if not lu_factor(Aug, r, piv):
            return False
        for c in range(6):
            lu_solve_column(Aug, r, piv, r + c)
            for k in range(r):
                x_ = Aug[k, r + c]
                for s in range(n):
                    W[c, s] -= x_ * Zt[k, s]
    # A'' = A - B' W'' (symmetric by construction)
    for a in range(6):
        for b in range(a, 6):
            t = 0.0
            for s in range(n):
                t += Bp[a, s] * W[b, s]
            v = A[a, b] - t
            A[a, b] = v
            A[b, a] = v
    return True


@njit(cache=True, inline="always")
def _rows_times_add(R, x0, x1, x2, x3, x4, x5, sign, out, n):
    """``out += sign * R' x`` for the 6 x n rows ``R`` and the 6-vector ``x`` (one sweep over the modes, the six
    rows at once: vectorized over the modes, no store and reload of ``out`` per row)."""
    r0, r1, r2, r3, r4, r5 = R[0], R[1], R[2], R[3], R[4], R[5]
    for s in range(n):
        out[s] += sign * (r0[s] * x0 + r1[s] * x1 + r2[s] * x2 + r3[s] * x3 + r4[s] * x4 + r5[s] * x5)


@njit(cache=True, fastmath=FAST_SUMS, inline="always")
def _rows_dot6(R, x, n):
    """``R x`` for the 6 x n rows ``R``: the six dot products in one sweep over ``x`` (vectorized over the modes)."""
    return FK.dots6(R[0], R[1], R[2], R[3], R[4], R[5], x, n)


@njit(cache=True, fastmath=FAST_SUMS)
def condense_bias(i, topology, nodes, params, tau, factored, ws_vec, pool):
    """The bias part of the modal elimination of flexible body i (after :func:`condense_inertia`): the rigid
    force after the modal elimination ``pA + sum g_j + B' E'^-1 d_m`` into ``ws_vec[i, VEC_P]`` (so that the
    rigid hinge step follows unchanged), and ``y = E'^-1 d_m`` kept for the acceleration pass
    (``etaddot = y - W' a``), with ``d_m = tau_m - (modal bias - applied modal forces) - (G(eta) - G0) etaddot
    - sum_j Psi_j' g_j + Pc' pA`` (the third term: the refinement's, zero on a first pass). Sums over modes
    reassociated (``FAST_SUMS``: vectorized; round-off only). About (9 + 2 r + 6 m) n multiply-adds with a
    diagonal G0 (m nodes with children, the outboard node counted). The Woodbury rows ``U``, ``Z'`` and ``B'`` are
    taken six per sweep over the modes (:func:`_rows_dot6`, :func:`_rows_times_add`): 0.87x of a sweep per row on
    the 196-mode tube with a wheel of ``benchmarks/flexible_scaling.py`` (1.49 against 1.71 us, interleaved, load
    1.8, 2026-12-07), which every refinement pass runs."""
    n = topology[i, N_MODES]
    pA = ws_vec[i, VEC_P]
    nd = topology[i, FIRST_SLOT]
    while nd >= 0:
        s = nodes[nd, NODE_SLOT]
        for a in range(6):
            pA[a] += pool[s + SL_G + a]
        nd = nodes[nd, NODE_NEXT_SLOT]
    if n == 0:
        return
    fx = topology[i, FLEX:FLEX + N_FX]
    kind = modal_mass_kind(fx, factored)
    onode = topology[i, OUTBOARD_NODE]
    Gm = view(pool, fx[FX_P_G], n, n)
    pv = fx[FX_P_VEC]
    u_eta = topology[i, U_START] + topology[i, NU_HINGE]
    rhs = view(pool, pv + PV_TMP * n, 1, n)
    Gd = view(pool, pv + PV_RHS * n, 1, n)
    r_ = rhs[0]
    force = pool[pv + PV_FORCE * n:pv + (PV_FORCE + 1) * n]
    if fx[FX_REFINE] and not factored:
        dg = pool[pv + PV_DG * n:pv + (PV_DG + 1) * n]
        for s in range(n):
            r_[s] = tau[u_eta + s] - force[s] - dg[s]
    else:
        for s in range(n):
            r_[s] = tau[u_eta + s] - force[s]
    FK.modal_mass_solve_rows(fx, kind, params, n, Gm, rhs, 1, Gd)
    y = pool[pv + PV_Y * n:pv + (PV_Y + 1) * n]
    for s in range(n):
        y[s] = Gd[0, s]
    nd = topology[i, FIRST_SLOT]
    while nd >= 0:
        so = nodes[nd, NODE_SLOT]
        g = pool[so + SL_G:so + SL_G + 6]
        _rows_times_add(view(pool, so + SL_PSI + 6 * n, 6, n), g[0], g[1], g[2], g[3], g[4], g[5], -1.0, y, n)
        nd = nodes[nd, NODE_NEXT_SLOT]
    if onode >= 0:
        _rows_times_add(view(pool, nodes[onode, NODE_SLOT] + SL_PSI + 6 * n, 6, n), pA[0], pA[1], pA[2], pA[3],
                        pA[4], pA[5], 1.0, y, n)
    r = fx[FX_RANK]
    if r > 0:
        # y -= Z' C^-1 (U y): the Woodbury correction (condense_inertia), G^-1 d_m in y on entry
        # six rows of U (of Z') per sweep over y (r is a multiple of 6): one load of y per six multiply-adds
        so = fx[FX_P_SMALL]
        piv = view(pool, so + r * r, r, r)[0]
        Aug = view(pool, so + 2 * r * r, r, r + 7)
        ut = so + 3 * r * r + 7 * r
        zt = ut + r * n
        for b in range(0, r, 6):
            c0, c1, c2, c3, c4, c5 = _rows_dot6(view(pool, ut + b * n, 6, n), y, n)
            Aug[b, r + 6] = c0
            Aug[b + 1, r + 6] = c1
            Aug[b + 2, r + 6] = c2
            Aug[b + 3, r + 6] = c3
            Aug[b + 4, r + 6] = c4
            Aug[b + 5, r + 6] = c5
        lu_solve_column(Aug, r, piv, r + 6)
        for b in range(0, r, 6):
            _rows_times_add(view(pool, zt + b * n, 6, n), Aug[b, r + 6], Aug[b + 1, r + 6], Aug[b + 2, r + 6],
                            Aug[b + 3, r + 6], Aug[b + 4, r + 6], Aug[b + 5, r + 6], -1.0, y, n)
    c0, c1, c2, c3, c4, c5 = _rows_dot6(view(pool, fx[FX_P_BP], 6, n), y, n)
    pA[0] += c0
    pA[1] += c1
    pA[2] += c2
    pA[3] += c3
    pA[4] += c4
    pA[5] += c5


@njit(cache=True, inline="always")
def modal_mass_kind(fx, factored):
    """How the modal elimination applies ``G^-1`` to body ``fx``: its ``FX_GINV_KIND``, or ``GINV_FACTORED`` for
    a refined body when ``factored`` (the fall-back of :func:`dynamics.kernels.articulated_body.forward_dynamics`
    when the refinement does not converge)."""
    if factored and fx[FX_REFINE]:
        return GINV_FACTORED
    return fx[FX_GINV_KIND]


@njit(cache=True)
def inertia_to_slot(i, topology, nodes, Ia, ws_rot, ws_vec, ws_mat, pool):
    """Add body i's articulated inertia to the slot of the flexible parent's node it hangs from (summed there
    per node for :func:`condense_inertia`)."""
    slot = nodes[topology[i, PARENT_NODE], NODE_SLOT]
    inertia_to_parent_add(ws_rot[i, ROT_PB], ws_vec[i, VEC_POS], Ia, view(pool, slot + SL_Y, 6, 6), ws_mat[i, MAT_TMP])


@njit(cache=True)
def force_to_slot(i, topology, nodes, pa, ws_rot, ws_vec, pool):
    """Add body i's articulated force to the slot of the flexible parent's node it hangs from (summed there per
    node for :func:`condense_bias`)."""
    slot = nodes[topology[i, PARENT_NODE], NODE_SLOT]
    force_to_parent_add(ws_rot[i, ROT_PB], ws_vec[i, VEC_POS], pa, pool[slot + SL_G:slot + SL_G + 6])


@njit(cache=True, fastmath=FAST_SUMS)
def modal_accelerations(i, topology, nodes, tau, udot, tau_out, ws_vec, pool):
    """Forward dynamics, pass 3, flexible body i: modal accelerations ``y - W' a`` (``a`` the rigid
    acceleration before the modal DOFs), then the ``-Pc etaddot`` of a hinge on a node of the body."""
    n = topology[i, N_MODES]
    A = ws_vec[i, VEC_A]
    pv = topology[i, FLEX + FX_P_VEC]
    ue = topology[i, U_START] + topology[i, NU_HINGE]
    acc = udot[ue:ue + n]
    y = pool[pv + PV_Y * n:pv + (PV_Y + 1) * n]
    for s in range(n):
        acc[s] = y[s]
        tau_out[ue + s] = tau[ue + s]
    _rows_times_add(view(pool, topology[i, FLEX + FX_P_W], 6, n), A[0], A[1], A[2], A[3], A[4], A[5], -1.0, acc, n)
    onode = topology[i, OUTBOARD_NODE]
    if onode >= 0:
        Pc = view(pool, nodes[onode, NODE_SLOT] + SL_PSI, 6, n)
        for a in range(6):
            row = Pc[a]
            t = 0.0
            for s in range(n):
                t += row[s] * acc[s]
            A[a] -= t
