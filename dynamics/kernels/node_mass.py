"""The terms C1 and J2 of a flexible body's mass matrix summed over its nodes (numba): O(N n) per evaluation.

C1 (the first-order rigid/modal coupling, integrals F1 and E1 of TM-2020-5008164 eq. E.2.5) and J2 (the
second-order rotational inertia, eq. E.2.4) are sums over every node j with mass of products of its mode shapes
(``lambda_j``, ``gamma_j``: rotation and translation, 3 x n), its mass ``m``, undeformed position ``l0``, CG
offset ``p`` and inertia ``J`` about the node (:mod:`dynamics.flex.modal_integrals`). As tables they are
``3 n^2`` (``6 n^2`` with CG offsets) and ``9 n^2`` numbers that every evaluation reads whole (4.6 MB at 196
modes); contracted with ``eta`` first they need only each node's ``theta = lambda_j eta``, ``u = gamma_j eta``
and ``d = theta x p``. With those (``~`` the cross-product matrix) the blocks of ``M(eta)`` are, per node (the
terms of ``Y_j' M_nd,j Y_j``, E.1.34, linear and quadratic in eta; point masses keep the first term of each),

    C(eta) = sum_r eta_r C1[r] = sum_j [m (u + d)~ gamma_j + B_j lambda_j;  -m d~ lambda_j]     (6 x n)
    with B_j = theta~ J - J theta~ - m u~ p~ - m l0~ d~,
    J2 eta eta = sum_j Q_j,  Q_j = -m u~ u~ - theta~ J theta~ - m (u~ d~ + d~ u~)                 (3 x 3)

(F1, E1 and J2 of :func:`dynamics.flex.modal_integrals.modal_integrals` contracted with eta). The body's
equations take from the kinetic energy ``T_C = V' C(eta) e + 1/2 omega' (J2 eta eta) omega`` what
:func:`dynamics.flexible_kernels.modal_mass_and_bias` takes from the tables (Lagrange for eta,
Euler-Poincare for the reference frame):

    M_re += C(eta),  M_rr[omega, omega] += sum_j Q_j,
    b_r += ad*_V (dh) + [Qdot omega; 0] + C(e) e,    dh = [sum_j Q_j omega; 0] + C(eta) e,
    b_m += C(e)' V - dT_C/deta,

``Qdot`` the rate of ``sum_j Q_j`` (``theta``, ``u``, ``d`` replaced by their rates in each factor in turn) and
``C(e)`` the coupling with eta replaced by the modal rates. ``C(e) e``, ``C(e)' V`` and ``dT_C/deta`` need only
per-node 3-vectors: ``b_m`` gains ``Lambda' a + Gamma' z`` with the per-node coefficients (``w = omega``,
``v`` the body's linear velocity, ``thd = lambda e``, ``ud = gamma e``, ``dd = thd x p``)

    z = m w x (ud + dd) - m ud x w + m (p x thd) x w                                        [C1]
        + m w x (w x u) - m w x (d x w)                                                     [J2]
    a = -J (thd x w) + thd x (J w) - m p x (ud x w) - m dd x (l0 x w) + m dd x v
        - (J thd) x w + thd x (J w) - p x (m ud x w - m thd x (w x l0) - m thd x v)         [C1]
        - w x (J (theta x w)) - m p x (w x (u x w))                                          [J2]

(the gradients of ``V' C(eta) e`` and ``1/2 omega' Q omega`` with respect to ``theta`` and ``u``, ``d`` through
``theta``). Per evaluation: one pass over the stacked translation shapes ``Gamma`` (n x 3N, node-minor as in
:mod:`dynamics.kernels.node_inertia`) for ``u`` and ``ud``, one for ``C(eta)``'s three rows and ``Gamma' z``
together, and the same two over ``Lambda`` when nodes have rotary inertia or CG offsets (a third pass for the
translational rows ``-m d~ lambda`` with CG offsets; the passes are node_inertia's,
:func:`dynamics.kernels.node_inertia.shapes_times` four rows of the shapes at a time and
:func:`dynamics.kernels.node_inertia.columns_times` two: :func:`node_mass_terms` 0.82x and 0.70x of its passes one row
at a time at 20 and 196 modes, 2026-12-07): 6 multiply-adds per entry of each 3N x n shape array
(``12 x 3N n`` with rotary inertia), against 3 per entry of the C1 table (``3 n^2``) and one per entry of J2
(``9 n^2``), and ``4 x 3N n`` numbers read against ``12 n^2``: the node sums win where the modes outnumber the
nodes (at order 2 from about 1.5 N modes, at order 1, C1 alone, from about 4 N on the tube of
``benchmarks/flexible_scaling.py``); :func:`dynamics.flexible_body.node_mass_is_cheaper` chooses per body. Geometric
stiffening adds stiffness-derived parts to C1 and J2 that are not node sums: such a body keeps its tables.
The per-node algebra runs as :mod:`dynamics.kernels.node_inertia`'s does: in loops over the nodes without branches
(a CG offset's terms are zero without one, a term left out is a loop not run) that store at most three node-minor
streams (a row of ``m (u + d)~``, of ``B_j``, of ``-m d~``; the C1 and the J2 parts of ``Lambda' a``; ``Z``) or only
sum into scalars (``Q``; ``C(eta) e``; ``C(e) e``; ``Qdot omega``), and that read the node data through views of
params (``params[ma:ma + N]``, ...): indexed ``params[ma + j]`` each load carries numba's wraparound select for a
possibly negative index and the loops were not vectorized (measured 2026-12-07, 105 nodes with rotary inertia,
20 modes, random data, interleaved against the one loop with a branch per term: 1.2x with forces split into loops
but indexed, 0.77x with forces and 0.79x without through views; ``benchmarks/node_terms_passes.py --before``,
load 0.85: C1 and J2 with forces 0.93x on the 196-mode tube, 0.73x on the 20-mode hub beam, with node_inertia's
shared pass 0.94x and 0.82x).
The result equals the tables' to round-off (``tests/flexible/test_node_mass.py``).

Where the nodes are those of the terms G1, F2, G2 over the nodes (:mod:`dynamics.kernels.node_inertia`: every
node with mass has rotary inertia, as on the beams and shells of real decks; :func:`dynamics.flexible_body.same_nodes`)
the two kernels share their shapes and passes: the params hold ``Lambda`` and ``Gamma`` once (node_inertia's), the
shapes times eta and the rates are :func:`dynamics.kernels.node_inertia.node_inertia_pass`'s (with ``u``), ``B_j``
joins that pass's ``Q_j`` (the omega rows of ``M_re`` take ``sum_j (B_j + Q_j) lambda_j``) and the coefficients of
``lambda'`` and ``gamma'`` in ``b_m`` add up, so one sweep back over each shape array serves both: of the eight
sweeps over a ``3N x n`` array the two kernels made apart, four remain (the tube of
``benchmarks/flexible_scaling.py`` at 196 modes: both kernels with their forces 0.69x-0.75x of apart, 2026-12-07,
``benchmarks/node_terms_passes.py --before``; the choice between node sums and tables counts the shared passes).

Data (:mod:`dynamics.layout`): ``FX_MASS_NODES`` points at what :func:`node_mass_params` packs for
``FX_MASS_NODE_COUNT`` nodes; ``FX_MASS_NODE_TERMS`` says which terms (``MASS_C1``, ``MASS_J2``);
``FX_P_MASS_NODES`` holds ``MASS_NODE_STATE`` numbers per node of scratch.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from dynamics.flexible_kernels import FAST_SUMS
from dynamics.kernels.node_inertia import (S_W, add_cross3, columns_times, cross3, mat3_times, node_inertia3, node_slot,
                                           node_vector, node_vectors, shapes_at, shapes_times, store_node_vector)
from dynamics.layout import MASS_C1, MASS_J2, NODE_F2

# where each node's numbers sit in the body's FX_P_MASS_NODES block, in units of the node count N (node-minor):
# theta, u, their rates and the coefficients of lambda' and gamma' in b_m first, 3 N each, as in node_inertia
# (:func:`dynamics.kernels.node_inertia.node_vectors`), then
S_WG = 18  # m (u + d)~ (9 N, entry (a, b) at (3 a + b) N): C(eta)[:3] += sum_j W_j gamma_j
S_WL = 27  # B_j (9 N), then -m d~ (9 N): C(eta) += sum_j W_j lambda_j
MASS_NODE_STATE = 45
"""Pool numbers per node (:data:`dynamics.layout.FX_P_MASS_NODES`)."""


def node_mass_params(mass, cg, inertia, positions, shapes, shared=False):
    """The node data as :func:`node_mass_terms` reads them from params: ``[rotary, offset, shared, m (N),
    l0 (3 N), p (3 N), J (9 N), Gamma (n x 3 N), Lambda (n x 3 N) if rotary]``, node-minor; ``rotary``: any node
    has an inertia or CG offset (else the rotation shapes are not needed), ``offset``: any has a CG offset. From
    the masses (N), CG offsets (N, 3), inertias (N, 3, 3), positions (N, 3) and shapes ``[lambda; gamma]``
    (N, 6, n). ``shared``: the nodes are those of the body's :mod:`dynamics.kernels.node_inertia` terms, in the
    same order with the same data (:func:`dynamics.flexible_body.same_nodes`): the shapes are left out and read
    from there (module docstring)."""
    count, _, n = shapes.shape
    cg = np.asarray(cg, dtype=np.float64)
    inertia = np.asarray(inertia, dtype=np.float64)
    offset = bool(np.any(cg != 0.0))
    rotary = offset or bool(np.any(inertia != 0.0))
    parts = [[float(rotary), float(offset), float(shared)], np.asarray(mass, dtype=np.float64),
             np.asarray(positions, dtype=np.float64).T.ravel(), cg.T.ravel(), inertia.reshape(count, 9).T.ravel()]
    if not shared:
        parts.append(np.transpose(shapes[:, 3:, :], (2, 1, 0)).reshape(n, 3 * count).ravel())
        if rotary:
            parts.append(np.transpose(shapes[:, :3, :], (2, 1, 0)).reshape(n, 3 * count).ravel())
    return np.concatenate(parts)


@njit(cache=True, fastmath=FAST_SUMS, inline="always")
def _skew_rows(out, mv, pv, th, uu, N, ku, sign):
    """``sign m (ku u + theta x p)~`` of every node into ``out`` node-minor (entry (a, b) at ``(3 a + b) N``), a
    loop per row storing three streams (module docstring: LLVM vectorizes it)."""
    for a in range(3):
        a1 = (a + 1) % 3
        a2 = (a + 2) % 3
        Ra = out[3 * a * N:3 * (a + 1) * N]
        for j in range(N):
            m = sign * mv[j]
            t0, t1, t2 = node_vector(th, N, j)
            p0, p1, p2 = node_vector(pv, N, j)
            d0, d1, d2 = cross3(t0, t1, t2, p0, p1, p2)
            x0, x1, x2 = ku * uu[j] + d0, ku * uu[N + j] + d1, ku * uu[2 * N + j] + d2
            xa1 = x1 if a1 == 1 else (x2 if a1 == 2 else x0)
            xa2 = x2 if a2 == 2 else (x0 if a2 == 0 else x1)
            Ra[a * N + j] = 0.0
            Ra[a1 * N + j] = -m * xa2
            Ra[a2 * N + j] = m * xa1


@njit(cache=True, fastmath=FAST_SUMS, inline="always")
def _b_row(mv, pv, lv, th, uu, Ja, J1, J2, N, j, a, a1, a2):
    """Row a of node j's ``B = theta~ J - J theta~ - m u~ p~ - m l0~ d~``: ``t[a+1] J_(a+2) - t[a+2] J_(a+1)
    - J_a x theta - m (p_a u + d_a l0) + m (u . p + l0 . d) e_a`` (``J_k`` the rows of J, ``Ja``, ``J1``, ``J2``
    rows a, a + 1, a + 2 of every node's, node-minor; ``a~ b~ = b a' - (a . b) 1``)."""
    m = mv[j]
    t0, t1, t2 = node_vector(th, N, j)
    u0, u1, u2 = node_vector(uu, N, j)
    p0, p1, p2 = node_vector(pv, N, j)
    l0, l1, l2 = node_vector(lv, N, j)
    d0, d1, d2 = cross3(t0, t1, t2, p0, p1, p2)
    ta1, ta2 = th[a1 * N + j], th[a2 * N + j]
    x0, x1, x2 = node_vector(J1, N, j)
    y0, y1, y2 = node_vector(J2, N, j)
    r0, r1, r2 = node_vector(Ja, N, j)
    P0, P1, P2 = cross3(r0, r1, r2, t0, t1, t2)
    pa_ = p0 if a == 0 else (p1 if a == 1 else p2)
    da_ = d0 if a == 0 else (d1 if a == 1 else d2)
    s = u0 * p0 + u1 * p1 + u2 * p2 + l0 * d0 + l1 * d1 + l2 * d2
    return (ta1 * y0 - ta2 * x0 - P0 - m * (pa_ * u0 + da_ * l0 - (s if a == 0 else 0.0)),
            ta1 * y1 - ta2 * x1 - P1 - m * (pa_ * u1 + da_ * l1 - (s if a == 1 else 0.0)),
            ta1 * y2 - ta2 * x2 - P2 - m * (pa_ * u2 + da_ * l2 - (s if a == 2 else 0.0)))


@njit(cache=True, fastmath=FAST_SUMS)
def node_mass_terms(params, o, count, n, terms, eta, V, e, with_bias, Mrr, Mre, br, bm, state, inertia_o,
                    inertia_terms, inertia_state):
    """Add the node terms C1 and J2 (module docstring; ``terms``: MASS_C1, MASS_J2 bits) to ``Mrr`` (6 x 6) and
    ``Mre`` (6 x n), and with ``with_bias`` to ``br`` (6) and ``bm`` (n), after
    :func:`dynamics.flexible_kernels.modal_mass_and_bias` has formed the rest. ``o``: params offset of the
    :func:`node_mass_params` of ``count`` nodes; ``V``, ``e``: body velocity and modal rates; ``state``:
    ``MASS_NODE_STATE * count`` numbers of scratch. Nodes shared with the node-inertia terms (``shared`` in the
    params): ``inertia_o``, ``inertia_terms``, ``inertia_state`` are those terms' params offset, NODE_* bits and
    scratch after :func:`dynamics.kernels.node_inertia.node_inertia_pass` (with ``u``), whose products back this
    function's sweeps include; otherwise unread."""
    c1 = (terms & MASS_C1) != 0
    j2 = (terms & MASS_J2) != 0
    N = count
    width = 3 * N
    rotary = params[o] != 0.0
    offset = params[o + 1] != 0.0
    shared = params[o + 2] != 0.0
    ma = o + 3
    la = ma + N
    pa = la + 3 * N
    ja = pa + 3 * N
    WG = node_slot(state, N, S_WG, 9)
    mv = params[ma:ma + N]  # views: their indices j + k N are not negative (no wraparound select per load)
    pv = params[pa:pa + 3 * N]
    lv = params[la:la + 3 * N]
    jv = params[ja:ja + 9 * N]
    WL = node_slot(state, N, S_WL, 18)
    if shared:
        # theta, u, their rates and the coefficients of lambda', gamma' are the node-inertia pass's; B_j joins its Q_j
        lam, gam = shapes_at(inertia_o, N, n)
        th, uu, thd, ud, A, Z = node_vectors(inertia_state, N)
        WB = node_slot(inertia_state, N, S_W, 9)
        add_b = (inertia_terms & NODE_F2) != 0
    else:
        gam = ja + 9 * N
        lam = gam + 3 * N * n
        th, uu, thd, ud, A, Z = node_vectors(state, N)
        WB = WL[:9 * N]
        add_b = False
        shapes_times(params, gam, n, width, eta, e, uu, ud, with_bias)
        if rotary:
            shapes_times(params, lam, n, width, eta, e, th, thd, with_bias)
    if not rotary and not shared:  # point masses: theta and its rate zero for the loops below (no rotation shapes)
        for r in range(width):
            th[r] = 0.0
            thd[r] = 0.0
    w0, w1, w2 = V[0], V[1], V[2]
    v0, v1, v2 = V[3], V[4], V[5]
    # the per-node algebra in loops over the nodes without branches (a CG offset's terms are zero without one) that
    # store at most three node-minor streams each, or only sum into scalars: LLVM vectorizes these
    # (:mod:`dynamics.kernels.node_inertia`'s forces, module docstring); the one loop with a branch per term did not
    if c1:
        _skew_rows(WG, mv, pv, th, uu, N, 1.0, 1.0)  # m (u + d)~
        if offset:
            _skew_rows(WL[9 * N:], mv, pv, th, uu, N, 0.0, -1.0)  # -m d~
        if rotary:
            # B = theta~ J - J theta~ - m u~ p~ - m l0~ d~, row a: t[a+1] J_(a+2) - t[a+2] J_(a+1) - J_a x theta
            # - m (p_a u + d_a l0) + m (u . p + l0 . d) e_a (J_k the rows of J; a~ b~ = b a' - (a . b) 1)
            for a in range(3):
                a1 = (a + 1) % 3
                a2 = (a + 2) % 3
                Ja = jv[3 * a * N:3 * (a + 1) * N]
                J1 = jv[3 * a1 * N:3 * (a1 + 1) * N]
                J2 = jv[3 * a2 * N:3 * (a2 + 1) * N]
                Ba = WB[3 * a * N:3 * (a + 1) * N]
                if add_b:  # B_j + Q_j: one product with lambda_j for C(eta) and F2
                    for j in range(N):
                        b0, b1, b2 = _b_row(mv, pv, lv, th, uu, Ja, J1, J2, N, j, a, a1, a2)
                        Ba[j] += b0
                        Ba[N + j] += b1
                        Ba[2 * N + j] += b2
                else:
                    for j in range(N):
                        b0, b1, b2 = _b_row(mv, pv, lv, th, uu, Ja, J1, J2, N, j, a, a1, a2)
                        store_node_vector(Ba, N, j, b0, b1, b2)
    # Q = sum_j -m u~ u~ - theta~ J theta~ - m (u~ d~ + d~ u~) (symmetric), a~ b~ = b a' - (a . b) 1
    q00 = q01 = q02 = q11 = q12 = q22 = 0.0
    if j2:
        for j in range(N):
            m = mv[j]
            u0, u1, u2 = node_vector(uu, N, j)
            t0, t1, t2 = node_vector(th, N, j)
            p0, p1, p2 = node_vector(pv, N, j)
            d0, d1, d2 = cross3(t0, t1, t2, p0, p1, p2)
            J00, J01, J02, J10, J11, J12, J20, J21, J22 = node_inertia3(jv, 0, N, j)
            uu_ = u0 * u0 + u1 * u1 + u2 * u2
            ud_ = u0 * d0 + u1 * d1 + u2 * d2
            # theta~ J theta~ = theta~ (J theta~): columns of J theta~ are J (theta x e_b)
            X01 = t0 * J02 - t2 * J00
            X02 = t1 * J00 - t0 * J01
            X10 = t2 * J11 - t1 * J12
            X12 = t1 * J10 - t0 * J11
            X20 = t2 * J21 - t1 * J22
            X21 = t0 * J22 - t2 * J20
            X11 = t0 * J12 - t2 * J10
            X22 = t1 * J20 - t0 * J21
            q00 += m * (uu_ - u0 * u0) - (t1 * X20 - t2 * X10) - m * (2.0 * d0 * u0 - 2.0 * ud_)
            q01 += -m * u0 * u1 - (t1 * X21 - t2 * X11) - m * (d0 * u1 + u0 * d1)
            q02 += -m * u0 * u2 - (t1 * X22 - t2 * X12) - m * (d0 * u2 + u0 * d2)
            q11 += m * (uu_ - u1 * u1) - (t2 * X01 - t0 * X21) - m * (2.0 * d1 * u1 - 2.0 * ud_)
            q12 += -m * u1 * u2 - (t2 * X02 - t0 * X22) - m * (d1 * u2 + u1 * d2)
            q22 += m * (uu_ - u2 * u2) - (t0 * X12 - t1 * X02) - m * (2.0 * d2 * u2 - 2.0 * ud_)
        Mrr[0, 0] += q00
        Mrr[0, 1] += q01
        Mrr[0, 2] += q02
        Mrr[1, 0] += q01
        Mrr[1, 1] += q11
        Mrr[1, 2] += q12
        Mrr[2, 0] += q02
        Mrr[2, 1] += q12
        Mrr[2, 2] += q22
    if with_bias:
        if not shared:  # the coefficients of lambda' and gamma' are this kernel's alone; else added to the pass's
            for r in range(width):
                A[r] = 0.0
                Z[r] = 0.0
        kc = 1.0 if c1 else 0.0
        kj = 1.0 if j2 else 0.0
        h0 = h1 = h2 = h3 = h4 = h5 = 0.0  # C(eta) e
        k0 = k1 = k2 = k3 = k4 = k5 = 0.0  # C(e) e
        g0 = g1 = g2 = 0.0  # Qdot w
        if c1:
            for j in range(N):
                # m (u + d) x ud + B thd, B thd = theta x (J thd) - J (theta x thd) - m u x (p x thd)
                # - m l0 x (d x thd); rows 3-5: -m d x thd
                m = mv[j]
                u0, u1, u2 = node_vector(uu, N, j)
                e0, e1, e2 = node_vector(ud, N, j)
                t0, t1, t2 = node_vector(th, N, j)
                s0, s1, s2 = node_vector(thd, N, j)
                p0, p1, p2 = node_vector(pv, N, j)
                l0, l1, l2 = node_vector(lv, N, j)
                J = node_inertia3(jv, 0, N, j)
                d0, d1, d2 = cross3(t0, t1, t2, p0, p1, p2)
                h0, h1, h2 = add_cross3(h0, h1, h2, m, u0 + d0, u1 + d1, u2 + d2, e0, e1, e2)
                js0, js1, js2 = mat3_times(J, s0, s1, s2)
                h0, h1, h2 = add_cross3(h0, h1, h2, 1.0, t0, t1, t2, js0, js1, js2)
                x0, x1, x2 = cross3(t0, t1, t2, s0, s1, s2)
                y0, y1, y2 = mat3_times(J, x0, x1, x2)
                x0, x1, x2 = cross3(p0, p1, p2, s0, s1, s2)
                h0, h1, h2 = add_cross3(h0 - y0, h1 - y1, h2 - y2, -m, u0, u1, u2, x0, x1, x2)
                x0, x1, x2 = cross3(d0, d1, d2, s0, s1, s2)
                h0, h1, h2 = add_cross3(h0, h1, h2, -m, l0, l1, l2, x0, x1, x2)
                h3 -= m * x0
                h4 -= m * x1
                h5 -= m * x2
            for j in range(N):
                # m (ud + dd) x ud + thd x (J thd) - m l0 x (dd x thd) - m ud x (p x thd); rows 3-5: -m dd x thd
                m = mv[j]
                e0, e1, e2 = node_vector(ud, N, j)
                s0, s1, s2 = node_vector(thd, N, j)
                p0, p1, p2 = node_vector(pv, N, j)
                l0, l1, l2 = node_vector(lv, N, j)
                J = node_inertia3(jv, 0, N, j)
                f0, f1, f2 = cross3(s0, s1, s2, p0, p1, p2)
                k0, k1, k2 = add_cross3(k0, k1, k2, m, e0 + f0, e1 + f1, e2 + f2, e0, e1, e2)
                js0, js1, js2 = mat3_times(J, s0, s1, s2)
                k0, k1, k2 = add_cross3(k0, k1, k2, 1.0, s0, s1, s2, js0, js1, js2)
                x0, x1, x2 = cross3(f0, f1, f2, s0, s1, s2)
                k3 -= m * x0
                k4 -= m * x1
                k5 -= m * x2
                k0, k1, k2 = add_cross3(k0, k1, k2, -m, l0, l1, l2, x0, x1, x2)
                x0, x1, x2 = cross3(p0, p1, p2, s0, s1, s2)
                k0, k1, k2 = add_cross3(k0, k1, k2, -m, e0, e1, e2, x0, x1, x2)
        if j2:
            for j in range(N):
                # -m (ud x (u x w) + u x (ud x w)) - thd x (J (theta x w)) - theta x (J (thd x w))
                # - m (ud x (d x w) + u x (dd x w) + dd x (u x w) + d x (ud x w))
                m = mv[j]
                u0, u1, u2 = node_vector(uu, N, j)
                e0, e1, e2 = node_vector(ud, N, j)
                t0, t1, t2 = node_vector(th, N, j)
                s0, s1, s2 = node_vector(thd, N, j)
                p0, p1, p2 = node_vector(pv, N, j)
                J = node_inertia3(jv, 0, N, j)
                d0, d1, d2 = cross3(t0, t1, t2, p0, p1, p2)
                f0, f1, f2 = cross3(s0, s1, s2, p0, p1, p2)
                x0, x1, x2 = cross3(u0 + d0, u1 + d1, u2 + d2, w0, w1, w2)
                g0, g1, g2 = add_cross3(g0, g1, g2, -m, e0, e1, e2, x0, x1, x2)
                x0, x1, x2 = cross3(e0 + f0, e1 + f1, e2 + f2, w0, w1, w2)
                g0, g1, g2 = add_cross3(g0, g1, g2, -m, u0, u1, u2, x0, x1, x2)
                x0, x1, x2 = cross3(u0, u1, u2, w0, w1, w2)
                g0, g1, g2 = add_cross3(g0, g1, g2, -m, f0, f1, f2, x0, x1, x2)
                x0, x1, x2 = cross3(e0, e1, e2, w0, w1, w2)
                g0, g1, g2 = add_cross3(g0, g1, g2, -m, d0, d1, d2, x0, x1, x2)
                x0, x1, x2 = cross3(t0, t1, t2, w0, w1, w2)
                y0, y1, y2 = mat3_times(J, x0, x1, x2)
                g0, g1, g2 = add_cross3(g0, g1, g2, -1.0, s0, s1, s2, y0, y1, y2)
                x0, x1, x2 = cross3(s0, s1, s2, w0, w1, w2)
                y0, y1, y2 = mat3_times(J, x0, x1, x2)
                g0, g1, g2 = add_cross3(g0, g1, g2, -1.0, t0, t1, t2, y0, y1, y2)
        for j in range(N):
            # z: m w x (ud + dd) - m ud x w + m (p x thd) x w [C1], m w x (w x u) - m w x (d x w) [J2]
            m = mv[j]
            u0, u1, u2 = node_vector(uu, N, j)
            e0, e1, e2 = node_vector(ud, N, j)
            t0, t1, t2 = node_vector(th, N, j)
            s0, s1, s2 = node_vector(thd, N, j)
            p0, p1, p2 = node_vector(pv, N, j)
            d0, d1, d2 = cross3(t0, t1, t2, p0, p1, p2)
            f0, f1, f2 = cross3(s0, s1, s2, p0, p1, p2)
            x0, x1, x2 = cross3(w0, w1, w2, e0 + f0, e1 + f1, e2 + f2)
            y0, y1, y2 = cross3(e0, e1, e2, w0, w1, w2)
            c0, c1_, c2 = cross3(p0, p1, p2, s0, s1, s2)
            z0, z1, z2 = add_cross3(x0 - y0, x1 - y1, x2 - y2, 1.0, c0, c1_, c2, w0, w1, w2)
            x0, x1, x2 = cross3(w0, w1, w2, u0 + d0, u1 + d1, u2 + d2)  # -w x (d x w) = w x (w x d)
            r0, r1, r2 = add_cross3(0.0, 0.0, 0.0, 1.0, w0, w1, w2, x0, x1, x2)
            mc = m * kc
            mj = m * kj
            Z[j] += mc * z0 + mj * r0
            Z[N + j] += mc * z1 + mj * r1
            Z[2 * N + j] += mc * z2 + mj * r2
        if rotary and c1:
            for j in range(N):
                # a: -J (thd x w) + 2 thd x (J w) - (J thd) x w
                s0, s1, s2 = node_vector(thd, N, j)
                J = node_inertia3(jv, 0, N, j)
                x0, x1, x2 = cross3(s0, s1, s2, w0, w1, w2)
                y0, y1, y2 = mat3_times(J, x0, x1, x2)
                jw0, jw1, jw2 = mat3_times(J, w0, w1, w2)
                js0, js1, js2 = mat3_times(J, s0, s1, s2)
                b0, b1, b2 = add_cross3(-y0, -y1, -y2, 2.0, s0, s1, s2, jw0, jw1, jw2)
                b0, b1, b2 = add_cross3(b0, b1, b2, -1.0, js0, js1, js2, w0, w1, w2)
                A[j] += b0
                A[N + j] += b1
                A[2 * N + j] += b2
        if offset and c1:
            for j in range(N):
                # a: - m p x (ud x w) - m dd x (l0 x w) + m dd x v - p x (m ud x w - m thd x (w x l0 + v))
                m = mv[j]
                e0, e1, e2 = node_vector(ud, N, j)
                s0, s1, s2 = node_vector(thd, N, j)
                p0, p1, p2 = node_vector(pv, N, j)
                l0, l1, l2 = node_vector(lv, N, j)
                f0, f1, f2 = cross3(s0, s1, s2, p0, p1, p2)
                x0, x1, x2 = cross3(e0, e1, e2, w0, w1, w2)  # ud x w (twice: C(e)' V and -d/dtheta)
                b0, b1, b2 = cross3(p0, p1, p2, x0, x1, x2)
                y0, y1, y2 = cross3(l0, l1, l2, w0, w1, w2)
                b0, b1, b2 = add_cross3(-2.0 * b0, -2.0 * b1, -2.0 * b2, 1.0, f0, f1, f2, v0 - y0, v1 - y1, v2 - y2)
                c0, c1_, c2 = cross3(s0, s1, s2, v0 - y0, v1 - y1, v2 - y2)  # thd x (w x l0 + v)
                b0, b1, b2 = add_cross3(b0, b1, b2, 1.0, p0, p1, p2, c0, c1_, c2)
                A[j] += m * b0
                A[N + j] += m * b1
                A[2 * N + j] += m * b2
        if rotary and j2:
            for j in range(N):
                # a: -w x (J (theta x w)) - m p x (w x (u x w))
                m = mv[j]
                u0, u1, u2 = node_vector(uu, N, j)
                t0, t1, t2 = node_vector(th, N, j)
                p0, p1, p2 = node_vector(pv, N, j)
                J = node_inertia3(jv, 0, N, j)
                x0, x1, x2 = cross3(t0, t1, t2, w0, w1, w2)
                y0, y1, y2 = mat3_times(J, x0, x1, x2)
                r0, r1, r2 = cross3(y0, y1, y2, w0, w1, w2)
                x0, x1, x2 = cross3(u0, u1, u2, w0, w1, w2)
                y0, y1, y2 = cross3(w0, w1, w2, x0, x1, x2)
                r0, r1, r2 = add_cross3(r0, r1, r2, -m, p0, p1, p2, y0, y1, y2)
                A[j] += r0
                A[N + j] += r1
                A[2 * N + j] += r2
        if j2:
            h0 += q00 * w0 + q01 * w1 + q02 * w2
            h1 += q01 * w0 + q11 * w1 + q12 * w2
            h2 += q02 * w0 + q12 * w1 + q22 * w2
    columns_times(params, gam, n, width, WG, Z, 0, c1, with_bias, Mre, bm)
    if rotary:
        columns_times(params, lam, n, width, WB, A, 0, c1 or add_b, with_bias, Mre, bm)
        if offset and c1:
            columns_times(params, lam, n, width, WL[9 * N:], A, 3, True, False, Mre, bm)
    if not with_bias:
        return
    # b_r += ad*_V (dh) + [Qdot w; 0] + C(e) e
    br[0] += w1 * h2 - w2 * h1 + v1 * h5 - v2 * h4 + g0 + k0
    br[1] += w2 * h0 - w0 * h2 + v2 * h3 - v0 * h5 + g1 + k1
    br[2] += w0 * h1 - w1 * h0 + v0 * h4 - v1 * h3 + g2 + k2
    br[3] += w1 * h5 - w2 * h4 + k3
    br[4] += w2 * h3 - w0 * h5 + k4
    br[5] += w0 * h4 - w1 * h3 + k5
