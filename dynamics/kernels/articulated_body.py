"""Forward dynamics by the articulated-body algorithm (RBDA Table 7.1) in augmented form, O(N), with
prescribed hinge DOFs (their known accelerations enter the bias, their forces come from ``IA a + pA``, RBDA
sec. 9.3); a flexible body's modal DOFs are eliminated by :mod:`dynamics.kernels.modal_condensation`.

The inward pass is split, per body, into an inertia part (the articulated inertias and their factorizations:
:func:`dynamics.kernels.modal_condensation.condense_inertia`, the hinge's ``D^-1``) and a bias part (the
articulated forces: :func:`~dynamics.kernels.modal_condensation.condense_bias`, the hinge's ``d``, ``pa``), so
that the same factorizations solve for another right-hand side at the cost of the bias and acceleration passes
alone. The forward dynamics uses that to refine: a flexible body whose modal mass depends on its deformation
through the terms of its nodes with rotary inertia, ``G(eta) = G0 + dG(eta)`` (``FX_REFINE``, terms G1, G2 of
:mod:`dynamics.kernels.node_inertia`), is eliminated with the constant ``G0`` (precomputed ``G0^-1``, O(n) or
O(n^2)), and the system ``(K0 + dK) udot = f`` is solved by the iteration ``K0 udot_{k+1} = f - dK udot_k``
(Richardson, converging as ``rho^k`` with ``rho`` the spectral radius of ``K0^-1 dK``, of the order of the
nodes' elastic rotation angles: three to five passes to round-off for deformations of 1e-4..1e-3 rad),
each pass one product with ``dG`` over the nodes (O(N_r n)) and the bias and acceleration passes (the latter over
the bodies up to the last refined one: those after it, in body order, are no refined body's ancestors, and get
their accelerations once, from the accepted iterate). Richardson is kept because nothing cheaper converges
faster here: the spectrum of ``K0^-1 dK`` is symmetric about zero and spread (each node's ``dJ = theta~ J - J
theta~`` is a commutator, indefinite with a zero diagonal in the modal basis), so CG or Chebyshev gain about half a
pass, and neither ``diag(dG)`` nor the exact ``dG`` of the 10..80 highest or lowest modes in the preconditioner
lowers ``rho`` by 10 % (measured 2026-12-07 on the 196-mode tube of ``benchmarks/flexible_scaling.py``). Once
an iterate changes by less than ``SINGLE_BELOW`` = 1e-7 of the modal accelerations, a pass's product is the
correction ``dG (x_k - x_(k-1))`` added to the last product, its sweeps over the nodes' shapes in single precision
(:func:`dynamics.kernels.node_inertia.node_inertia_times_single`: 0.46x of the double product on the 196-mode tube of
``benchmarks/flexible_scaling.py``, 7.5 against 14-17 us, its five products 54 against 71 us, over mode-major
copies; from 96 modes both products sweep node-major copies once, 6.9 and 13.7 us there, 2026-12-07): its
error, about 1e-8 of the summands' size of a correction below 1e-7 of the accelerations, is below the round-off
of the accelerations (on that tube, where ``rho`` is about 0.01 and the third to fifth passes' products are so
taken: the kept product differs from the double one by 3e-17 of the modal accelerations, and the result from the
factored modal mass's by 4.1e-15 as with double products alone). The iteration stops when the next change of the
modal accelerations would be below 1e-14 of their size (the round-off of the sums that form them), or stagnates at
round-off;
when the passes it still needs (predicted from its contraction rate) would cost more than forming ``G(eta)``
and factoring it (the body's budget, ``dynamics.system.refinement_budget``: node rotations of a tenth of a
radian and more on a body of a few tens of modes), the forward dynamics is solved again with ``G(eta)``
formed and factored (O(N_r n^2 + n^3)), the result being the same to round-off either way. A body whose budget
is below ``dynamics.system.MIN_REFINEMENT_BUDGET`` (few modes for its nodes: the formation, a tiled matrix product,
costs less than the four or five refinements deformations of 1e-4..1e-3 rad take) is not refined at all: its
``G(eta)`` is formed and factored on every evaluation.

Where an evaluation's time goes (``benchmarks/derivative_profile.py``, each step timed alone in compiled loops,
2026-12-07, load 1.4-2 on 2 cores: compare rows, not runs). The hub beam of ``benchmarks/flexible_vs_exudyn.py --case
beam`` (105 nodes with rotary inertia, 20 modes, order 2, ``G(eta)`` formed and factored), 24-34 us in all:
node_inertia_terms (G1, F2, G2 with their forces) 28 %, node_inertia_modal_mass (``G(eta)`` formed) 26 %, the
tables' terms (modal_mass_and_bias: R1, C1, J2 and the copy of G0) 13 %, the modal elimination's inertia part
(Cholesky of ``G(eta)``, ``M_re G^-1``, the 6 x 6 Schur complement) 9 %, its bias part 3 %, the hinge step 3 %,
kinematics, node forces and the acceleration pass 2 % each. ``M_re G^-1`` took 3.3 us (six rows solved one at a
time) before its rows were solved six at a time (0.75 us, :func:`dynamics.flexible_kernels.modal_mass_solve_rows`).
Refining this body's modal mass instead of factoring it measured 1.2x the factored evaluation at a 3 cm tip
deflection (five passes) and 1.35x at 0.3 m (two passes, then the fall-back): the budget's choice stands.
A refinement pass of the 196-mode tube with a wheel (``benchmarks/flexible_scaling.py --deck-only``) costs about
2.5 us besides its product with ``dG`` (15 us in double, 7 in single precision over the mode-major copies; 13.7
and 6.9 over the node-major ones): the bias pass 1.6 (of which the
modal elimination's bias part 1.4, its Woodbury and ``B'`` rows taken six per sweep: 0.87x of a sweep per row), the
acceleration pass 0.6, the convergence check 0.2. What a pass recomputes unchanged is small and was left: the
modal right-hand side without ``dG`` and the children's slot terms (a third of the bias part's multiply-adds with
one child node: about 0.4 us a pass, 1 % of the evaluation, for a split of :func:`condense_bias` into a fixed and a
per-pass part that holds only when no refined body hangs below another), the bias steps of the bodies after the
last refined one (the wheel's: 0.13 us).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from dynamics.kernels.body_terms import apply_node_forces, flexible_body_terms, rigid_bias_add
from dynamics.kernels.kinematics import general_kinematics, parent_acceleration_general, rigid_position, rigid_velocity
from dynamics.kernels.modal_condensation import (
    condense_bias, condense_inertia, force_to_slot, inertia_to_slot, modal_accelerations, modal_mass_kind)
from dynamics.kernels.node_inertia import NODE_STATE, node_inertia_times, node_inertia_times_single
from dynamics.kernels.small_linalg import spd_inverse
from dynamics.layout import (
    FIRST_SLOT, FLEX, FLEXIBLE, FREE_DOFS, FX_NODES, FX_NODE_COUNT, FX_NODE_TERMS, FX_P_MRR, FX_P_NODES, FX_P_VEC,
    FX_REFINE, GENERAL, GINV_FACTORED, GROUND_ACCEL, INERTIA, MAT_DINV, MAT_IA, MAT_IAP, MAT_S, MAT_TMP, MAT_U,
    NODE_NEXT_SLOT, NODE_SLOT, NU_HINGE, N_FREE, N_FX, N_MODES, N_PRESCRIBED, PARENT, PARENT_NODE, PRESCRIBED_DOFS,
    PV_DG, PV_PREV, P_REFINEMENTS, ROT_PB, SL_G, U_START, VEC_A, VEC_AUX, VEC_C, VEC_D, VEC_P, VEC_P0, VEC_POS, VEC_V,
    view)
from dynamics.spatial import force_to_parent_add, inertia_to_parent_add, mat6_vec, motion_to_child

NOT_CONVERGED = -1
"""Status of a pass whose refinement of the modal mass would cost more than factoring it (solved again so)."""
REFINED = 1e-14
"""The refinement stops when its next correction would be below this fraction of the largest modal acceleration:
the round-off of the sums over modes and nodes that form them."""
SINGLE_BELOW = 1e-7
"""A refinement's product with ``dG`` is the correction ``dG (x_k - x_(k-1))`` in single precision
(:func:`dynamics.kernels.node_inertia.node_inertia_times_single`) once the iterate changed by less than this
fraction of the largest modal acceleration (module docstring)."""


@njit(cache=True, inline="always")
def _hinge_inertia(i, topology, ws_mat):
    """Articulated-body step of body i's free hinge DOFs (RBDA Table 7.1), inertia part: U = IA S, D = S' U,
    its inverse, and Ia = IA - U D^-1 U' (only for a body with a parent: what a root would pass inward is never
    read). False when D is singular."""
    S = ws_mat[i, MAT_S]
    IA = ws_mat[i, MAT_IA]
    U = ws_mat[i, MAT_U]
    Dinv = ws_mat[i, MAT_DINV]
    Ia = ws_mat[i, MAT_IAP]
    nf = topology[i, N_FREE]
    root = topology[i, PARENT] < 0 and topology[i, PARENT_NODE] < 0
    tol = 1e-14 * (IA[0, 0] + IA[1, 1] + IA[2, 2] + IA[3, 3] + IA[4, 4] + IA[5, 5])
    if nf == 1:
        # the common 1-DOF hinge without the loops over DOFs
        k = topology[i, FREE_DOFS]
        D0 = 0.0
        for a in range(6):
            s = 0.0
            for b in range(6):
                s += IA[a, b] * S[b, k]
            U[a, 0] = s
        for a in range(6):
            D0 += S[a, k] * U[a, 0]
        if not D0 > tol:
            return False
        dinv = 1.0 / D0
        Dinv[0, 0] = dinv
        if root:
            return True
        for a in range(6):
            for b in range(a, 6):
                s = IA[a, b] - U[a, 0] * (dinv * U[b, 0])
                Ia[a, b] = s
                Ia[b, a] = s
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
    if nf > 0:
        if not spd_inverse(D, nf, tol, ws_mat[i, MAT_IAP], Dinv):
            return False
    if root:
        return True  # a root body passes nothing inward (skips 6 x 6 x nf^2 work)
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
    return True


@njit(cache=True, inline="always")
def _hinge_bias(i, topology, tau, ws_mat, ws_vec):
    """Articulated-body step of body i's free hinge DOFs, bias part (after :func:`_hinge_inertia`):
    d = tau - S' pA and, for a body with a parent, pa = pA + Ia c + U D^-1 d."""
    S = ws_mat[i, MAT_S]
    U = ws_mat[i, MAT_U]
    Dinv = ws_mat[i, MAT_DINV]
    pA = ws_vec[i, VEC_P]
    d = ws_vec[i, VEC_D]
    nf = topology[i, N_FREE]
    u0 = topology[i, U_START]
    for kk in range(nf):
        k = topology[i, FREE_DOFS + kk]
        s = tau[u0 + k]
        for a in range(6):
            s -= S[a, k] * pA[a]
        d[kk] = s
    if topology[i, PARENT] < 0 and topology[i, PARENT_NODE] < 0:
        return
    pa = ws_vec[i, VEC_AUX]
    mat6_vec(ws_mat[i, MAT_IAP], ws_vec[i, VEC_C], pa)
    for a in range(6):
        pa[a] += pA[a]
    for kk in range(nf):
        t = 0.0
        for ll in range(nf):
            t += Dinv[kk, ll] * d[ll]
        for a in range(6):
            pa[a] += U[a, kk] * t


@njit(cache=True)
def _flexible_inertia_and_bias(i, topology, params, q, u, body_forces, factored, ws_vec, ws_mat, pool):
    """Pass 1 of the ABA at a flexible body: IA = M_rr(eta) and pA = b - f_ext (modal rows in the pool)."""
    flexible_body_terms(i, topology, params, q, u, ws_vec, ws_mat, pool, True,
                        modal_mass_kind(topology[i, FLEX:FLEX + N_FX], factored) == GINV_FACTORED)
    IA = ws_mat[i, MAT_IA]
    pA = ws_vec[i, VEC_P]
    M = view(pool, topology[i, FLEX + FX_P_MRR], 6, 6)
    for a in range(6):
        pA[a] -= body_forces[i, a]
        for b in range(6):
            IA[a, b] = M[a, b]


@njit(cache=True)
def _acceleration_pass(topology, nodes, ground, tau, udot, tau_out, ws_rot, ws_vec, ws_mat, pool, first, stop):
    """Pass 3 (outward) over bodies ``first`` to ``stop - 1`` (their parents' accelerations known): their
    accelerations, the free DOFs' accelerations, the prescribed DOFs' forces and the modal accelerations."""
    for i in range(first, stop):
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


@njit(cache=True)
def _bias_pass(topology, nodes, params, tau, factored, ws_rot, ws_vec, ws_mat, pool):
    """The inward pass again for other forces, on the factorizations of the last full pass: every body's force
    from its pass-1 value (``VEC_P0``), the children's and the modal elimination's."""
    nb = topology.shape[0]
    for i in range(nb):
        pA = ws_vec[i, VEC_P]
        p0 = ws_vec[i, VEC_P0]
        for a in range(6):
            pA[a] = p0[a]
        if topology[i, FLEXIBLE]:
            nd = topology[i, FIRST_SLOT]
            while nd >= 0:
                s = nodes[nd, NODE_SLOT]
                for a in range(6):
                    pool[s + SL_G + a] = 0.0
                nd = nodes[nd, NODE_NEXT_SLOT]
    for i in range(nb - 1, -1, -1):
        if topology[i, FLEXIBLE]:
            condense_bias(i, topology, nodes, params, tau, factored, ws_vec, pool)
        _hinge_bias(i, topology, tau, ws_mat, ws_vec)
        parent = topology[i, PARENT]
        if topology[i, PARENT_NODE] >= 0:
            force_to_slot(i, topology, nodes, ws_vec[i, VEC_AUX], ws_rot, ws_vec, pool)
        elif parent >= 0:
            force_to_parent_add(ws_rot[i, ROT_PB], ws_vec[i, VEC_POS], ws_vec[i, VEC_AUX], ws_vec[parent, VEC_P])


@njit(cache=True)
def _refinement_products(topology, params, udot, pool, single):
    """``(G(eta) - G0) etaddot`` of every refined body into its ``PV_DG`` vector, or with ``single`` the correction
    ``(G(eta) - G0) (etaddot - PV_PREV)`` added to it in single precision (module docstring); ``etaddot`` kept in
    ``PV_PREV`` (the iterate the products are of)."""
    for i in range(topology.shape[0]):
        if not topology[i, FLEXIBLE] or not topology[i, FLEX + FX_REFINE]:
            continue
        n = topology[i, N_MODES]
        fx = topology[i, FLEX:FLEX + N_FX]
        pv = fx[FX_P_VEC]
        ue = topology[i, U_START] + topology[i, NU_HINGE]
        dg = pool[pv + PV_DG * n:pv + (PV_DG + 1) * n]
        prev = pool[pv + PV_PREV * n:pv + (PV_PREV + 1) * n]
        x = udot[ue:ue + n]
        count = fx[FX_NODE_COUNT]
        state = pool[fx[FX_P_NODES]:fx[FX_P_NODES] + NODE_STATE * count]
        if single:
            node_inertia_times_single(params, fx[FX_NODES], count, n, fx[FX_NODE_TERMS], state, x, prev, dg)
        else:
            for s in range(n):
                dg[s] = 0.0
            node_inertia_times(params, fx[FX_NODES], count, n, fx[FX_NODE_TERMS], state, x, dg)
        for s in range(n):
            prev[s] = x[s]


@njit(cache=True)
def _refinement_change(topology, udot, pool):
    """(largest change of a refined body's modal acceleration since the iterate of the last products (``PV_PREV``),
    largest modal acceleration)."""
    change = 0.0
    scale = 0.0
    for i in range(topology.shape[0]):
        if not topology[i, FLEXIBLE] or not topology[i, FLEX + FX_REFINE]:
            continue
        n = topology[i, N_MODES]
        pv = topology[i, FLEX + FX_P_VEC]
        ue = topology[i, U_START] + topology[i, NU_HINGE]
        for s in range(n):
            a = udot[ue + s]
            change = max(change, abs(a - pool[pv + PV_PREV * n + s]))
            scale = max(scale, abs(a))
    return change, scale


@njit(cache=True)
def _forward_dynamics(topology, nodes, joint_rot, joint_vec, params, q, u, tau, node_forces, body_forces, udot,
                      tau_out, ws_rot, ws_vec, ws_mat, pool, factored):
    """:func:`forward_dynamics` with refined modal masses (``factored`` False; may return NOT_CONVERGED) or
    factored (True)."""
    nb = topology.shape[0]
    ground = params[GROUND_ACCEL:GROUND_ACCEL + 6]
    refine = False
    last = -1
    budget = 1 << 30
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
            _flexible_inertia_and_bias(i, topology, params, q, u, body_forces, factored, ws_vec, ws_mat, pool)
            if topology[i, FLEX + FX_REFINE] and not factored:
                refine = True
                last = i
                budget = min(budget, topology[i, FLEX + FX_REFINE])
                n = topology[i, N_MODES]
                pv = topology[i, FLEX + FX_P_VEC]
                for s in range(n):
                    pool[pv + PV_DG * n + s] = 0.0
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
    if refine:
        for i in range(nb):
            for a in range(6):
                ws_vec[i, VEC_P0, a] = ws_vec[i, VEC_P, a]

    for i in range(nb - 1, -1, -1):
        if topology[i, FLEXIBLE]:
            if not condense_inertia(i, topology, nodes, params, factored, ws_mat, pool):
                return 1 + i
            condense_bias(i, topology, nodes, params, tau, factored, ws_vec, pool)
        if not _hinge_inertia(i, topology, ws_mat):
            return 1 + i
        _hinge_bias(i, topology, tau, ws_mat, ws_vec)
        parent = topology[i, PARENT]
        if topology[i, PARENT_NODE] >= 0:
            inertia_to_slot(i, topology, nodes, ws_mat[i, MAT_IAP], ws_rot, ws_vec, ws_mat, pool)
            force_to_slot(i, topology, nodes, ws_vec[i, VEC_AUX], ws_rot, ws_vec, pool)
        elif parent >= 0:
            R = ws_rot[i, ROT_PB]
            r = ws_vec[i, VEC_POS]
            inertia_to_parent_add(R, r, ws_mat[i, MAT_IAP], ws_mat[parent, MAT_IA], ws_mat[i, MAT_TMP])
            force_to_parent_add(R, r, ws_vec[i, VEC_AUX], ws_vec[parent, VEC_P])

    if not refine:
        _acceleration_pass(topology, nodes, ground, tau, udot, tau_out, ws_rot, ws_vec, ws_mat, pool, 0, nb)
        pool[P_REFINEMENTS] = 0.0
        return 0
    # the bodies after the last refined one are no refined body's ancestors: their accelerations are computed once,
    # from the accepted iterate
    stop = last + 1
    _acceleration_pass(topology, nodes, ground, tau, udot, tau_out, ws_rot, ws_vec, ws_mat, pool, 0, stop)
    status = _refine(topology, nodes, params, tau, udot, tau_out, ground, ws_rot, ws_vec, ws_mat, pool, budget, stop)
    if status == 0:
        _acceleration_pass(topology, nodes, ground, tau, udot, tau_out, ws_rot, ws_vec, ws_mat, pool, stop, nb)
    return status


@njit(cache=True)
def _refine(topology, nodes, params, tau, udot, tau_out, ground, ws_rot, ws_vec, ws_mat, pool, budget, stop):
    """The refinement passes of :func:`_forward_dynamics` (module docstring) after its first solve, over the bodies
    before ``stop``: 0 when converged, NOT_CONVERGED when the passes it predicts exceed ``budget``."""
    pool[P_REFINEMENTS] = 0.0
    _refinement_products(topology, params, udot, pool, False)
    previous = 0.0
    for it in range(1, budget + 1):
        _bias_pass(topology, nodes, params, tau, False, ws_rot, ws_vec, ws_mat, pool)
        _acceleration_pass(topology, nodes, ground, tau, udot, tau_out, ws_rot, ws_vec, ws_mat, pool, 0, stop)
        pool[P_REFINEMENTS] = it
        change, scale = _refinement_change(topology, udot, pool)
        if change <= REFINED * scale:
            return 0
        if it > 1:
            # contraction rate from the last two changes: done when the next change would be below round-off;
            # given up where the passes still needed exceed the budget (or it no longer contracts: at round-off
            # already, or rho >= 1)
            rate = change / previous
            if rate < 1.0 and rate * change <= REFINED * scale:
                return 0
            if rate >= 1.0 or it + np.log(REFINED * scale / change) / np.log(rate) > budget:
                return 0 if change <= 10.0 * REFINED * scale else NOT_CONVERGED
        previous = change
        _refinement_products(topology, params, udot, pool, change <= SINGLE_BELOW * scale)
    return NOT_CONVERGED


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
    status = _forward_dynamics(topology, nodes, joint_rot, joint_vec, params, q, u, tau, node_forces, body_forces,
                               udot, tau_out, ws_rot, ws_vec, ws_mat, pool, False)
    if status == NOT_CONVERGED:
        passes = pool[P_REFINEMENTS]
        status = _forward_dynamics(topology, nodes, joint_rot, joint_vec, params, q, u, tau, node_forces,
                                   body_forces, udot, tau_out, ws_rot, ws_vec, ws_mat, pool, True)
        pool[P_REFINEMENTS] = -passes  # negative: that many passes, then G(eta) factored
    return status
