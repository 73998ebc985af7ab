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

from dynamics.kernels.node_inertia import (S_W, add_cross3, add_scaled3, columns_times, cross3, node_slot, node_vector,
                                           node_vectors, shapes_at, shapes_times, store_node_vector)
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


@njit(cache=True, inline="always")
def _store_skew(out, N, j, scale, x0, x1, x2):
    """Node j's ``scale x~`` into ``out`` node-minor (entry (a, b) at ``out[(3 a + b) N + j]``)."""
    out[j] = 0.0
    out[N + j] = -scale * x2
    out[2 * N + j] = scale * x1
    out[3 * N + j] = scale * x2
    out[4 * N + j] = 0.0
    out[5 * N + j] = -scale * x0
    out[6 * N + j] = -scale * x1
    out[7 * N + j] = scale * x0
    out[8 * N + j] = 0.0


@njit(cache=True)
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
    w0, w1, w2 = V[0], V[1], V[2]
    v0, v1, v2 = V[3], V[4], V[5]
    # sums over the nodes: Q (3 x 3), C(eta) e and C(e) e (6 each), Qdot w (3)
    q00 = q01 = q02 = q11 = q12 = q22 = 0.0
    h0 = h1 = h2 = h3 = h4 = h5 = 0.0
    k0 = k1 = k2 = k3 = k4 = k5 = 0.0
    g0 = g1 = g2 = 0.0
    for j in range(N):
        m = params[ma + j]
        u0, u1, u2 = node_vector(uu, N, j)
        if with_bias:
            e0, e1, e2 = node_vector(ud, N, j)
        else:
            e0 = e1 = e2 = 0.0
        t0 = t1 = t2 = s0 = s1 = s2 = 0.0  # theta, theta_dot
        d0 = d1 = d2 = f0 = f1 = f2 = 0.0  # d = theta x p, dd = theta_dot x p
        p0 = p1 = p2 = 0.0
        l0 = l1 = l2 = 0.0
        J00 = J01 = J02 = J10 = J11 = J12 = J20 = J21 = J22 = 0.0
        if rotary:
            t0, t1, t2 = node_vector(th, N, j)
            if with_bias:
                s0, s1, s2 = node_vector(thd, N, j)
            J00, J01, J02 = params[ja + j], params[ja + N + j], params[ja + 2 * N + j]
            J10, J11, J12 = params[ja + 3 * N + j], params[ja + 4 * N + j], params[ja + 5 * N + j]
            J20, J21, J22 = params[ja + 6 * N + j], params[ja + 7 * N + j], params[ja + 8 * N + j]
            if offset:
                p0, p1, p2 = params[pa + j], params[pa + N + j], params[pa + 2 * N + j]
                l0, l1, l2 = params[la + j], params[la + N + j], params[la + 2 * N + j]
                d0, d1, d2 = cross3(t0, t1, t2, p0, p1, p2)
                f0, f1, f2 = cross3(s0, s1, s2, p0, p1, p2)
        if shared and with_bias:
            a0, a1, a2 = node_vector(A, N, j)
            z0, z1, z2 = node_vector(Z, N, j)
        else:
            a0 = a1 = a2 = z0 = z1 = z2 = 0.0
        B00 = B01 = B02 = B10 = B11 = B12 = B20 = B21 = B22 = 0.0
        if c1:
            _store_skew(WG, N, j, m, u0 + d0, u1 + d1, u2 + d2)
            if rotary:
                # B = theta~ J - J theta~ - m u~ p~ - m l0~ d~, with a~ b~ = b a' - (a . b) 1
                B00 = t1 * J20 - t2 * J10 - (J01 * t2 - J02 * t1)
                B01 = t1 * J21 - t2 * J11 - (J02 * t0 - J00 * t2)
                B02 = t1 * J22 - t2 * J12 - (J00 * t1 - J01 * t0)
                B10 = t2 * J00 - t0 * J20 - (J11 * t2 - J12 * t1)
                B11 = t2 * J01 - t0 * J21 - (J12 * t0 - J10 * t2)
                B12 = t2 * J02 - t0 * J22 - (J10 * t1 - J11 * t0)
                B20 = t0 * J10 - t1 * J00 - (J21 * t2 - J22 * t1)
                B21 = t0 * J11 - t1 * J01 - (J22 * t0 - J20 * t2)
                B22 = t0 * J12 - t1 * J02 - (J20 * t1 - J21 * t0)
                if offset:
                    up = u0 * p0 + u1 * p1 + u2 * p2
                    ld = l0 * d0 + l1 * d1 + l2 * d2
                    B00 -= m * (p0 * u0 - up + d0 * l0 - ld)
                    B01 -= m * (p0 * u1 + d0 * l1)
                    B02 -= m * (p0 * u2 + d0 * l2)
                    B10 -= m * (p1 * u0 + d1 * l0)
                    B11 -= m * (p1 * u1 - up + d1 * l1 - ld)
                    B12 -= m * (p1 * u2 + d1 * l2)
                    B20 -= m * (p2 * u0 + d2 * l0)
                    B21 -= m * (p2 * u1 + d2 * l1)
                    B22 -= m * (p2 * u2 - up + d2 * l2 - ld)
                    _store_skew(WL[9 * N:], N, j, -m, d0, d1, d2)
                if add_b:  # B_j + Q_j: one product with lambda_j for C(eta) and F2
                    WB[j] += B00
                    WB[N + j] += B01
                    WB[2 * N + j] += B02
                    WB[3 * N + j] += B10
                    WB[4 * N + j] += B11
                    WB[5 * N + j] += B12
                    WB[6 * N + j] += B20
                    WB[7 * N + j] += B21
                    WB[8 * N + j] += B22
                else:
                    WB[j] = B00
                    WB[N + j] = B01
                    WB[2 * N + j] = B02
                    WB[3 * N + j] = B10
                    WB[4 * N + j] = B11
                    WB[5 * N + j] = B12
                    WB[6 * N + j] = B20
                    WB[7 * N + j] = B21
                    WB[8 * N + j] = B22
            if with_bias:
                # C(eta) e and C(e) e: m (u + d) x ud + B thd, -m d x thd (and with the rates)
                x0, x1, x2 = cross3(u0 + d0, u1 + d1, u2 + d2, e0, e1, e2)
                y0, y1, y2 = cross3(e0 + f0, e1 + f1, e2 + f2, e0, e1, e2)
                h0, h1, h2 = add_scaled3(h0, h1, h2, m, x0, x1, x2)
                k0, k1, k2 = add_scaled3(k0, k1, k2, m, y0, y1, y2)
                # w x (ud + dd) and the gradient in u: z = m w x (ud + dd) - m ud x w + m (p x thd) x w
                x0, x1, x2 = cross3(w0, w1, w2, e0 + f0, e1 + f1, e2 + f2)
                y0, y1, y2 = cross3(e0, e1, e2, w0, w1, w2)
                z0 += m * (x0 - y0)
                z1 += m * (x1 - y1)
                z2 += m * (x2 - y2)
                if rotary:
                    h0 += B00 * s0 + B01 * s1 + B02 * s2
                    h1 += B10 * s0 + B11 * s1 + B12 * s2
                    h2 += B20 * s0 + B21 * s1 + B22 * s2
                    # B(thd, ud) thd = thd x (J thd) - m ud x (p x thd) - m l0 x (dd x thd)
                    js0 = J00 * s0 + J01 * s1 + J02 * s2
                    js1 = J10 * s0 + J11 * s1 + J12 * s2
                    js2 = J20 * s0 + J21 * s1 + J22 * s2
                    k0, k1, k2 = add_cross3(k0, k1, k2, 1.0, s0, s1, s2, js0, js1, js2)
                    jw0 = J00 * w0 + J01 * w1 + J02 * w2
                    jw1 = J10 * w0 + J11 * w1 + J12 * w2
                    jw2 = J20 * w0 + J21 * w1 + J22 * w2
                    # a: -J (thd x w) + thd x (J w) [C(e)' V] - (J thd) x w + thd x (J w) [-d/dtheta]
                    x0, x1, x2 = cross3(s0, s1, s2, w0, w1, w2)
                    y0, y1, y2 = cross3(s0, s1, s2, jw0, jw1, jw2)
                    c0, c1_, c2 = cross3(js0, js1, js2, w0, w1, w2)
                    a0 += -(J00 * x0 + J01 * x1 + J02 * x2) + 2.0 * y0 - c0
                    a1 += -(J10 * x0 + J11 * x1 + J12 * x2) + 2.0 * y1 - c1_
                    a2 += -(J20 * x0 + J21 * x1 + J22 * x2) + 2.0 * y2 - c2
                    if offset:
                        h3 -= m * (d1 * s2 - d2 * s1)
                        h4 -= m * (d2 * s0 - d0 * s2)
                        h5 -= m * (d0 * s1 - d1 * s0)
                        x0, x1, x2 = cross3(f0, f1, f2, s0, s1, s2)  # dd x thd
                        k3 -= m * x0
                        k4 -= m * x1
                        k5 -= m * x2
                        k0, k1, k2 = add_cross3(k0, k1, k2, -m, l0, l1, l2, x0, x1, x2)
                        x0, x1, x2 = cross3(p0, p1, p2, s0, s1, s2)  # p x thd
                        k0, k1, k2 = add_cross3(k0, k1, k2, -m, e0, e1, e2, x0, x1, x2)  # ud x (p x thd)
                        z0, z1, z2 = add_cross3(z0, z1, z2, m, x0, x1, x2, w0, w1, w2)  # (p x thd) x w
                        # a (C(e)' V): -m p x (ud x w) - m dd x (l0 x w) + m dd x v
                        x0, x1, x2 = cross3(e0, e1, e2, w0, w1, w2)
                        a0, a1, a2 = add_cross3(a0, a1, a2, -m, p0, p1, p2, x0, x1, x2)
                        x0, x1, x2 = cross3(l0, l1, l2, w0, w1, w2)
                        a0, a1, a2 = add_cross3(a0, a1, a2, -m, f0, f1, f2, x0, x1, x2)
                        a0, a1, a2 = add_cross3(a0, a1, a2, m, f0, f1, f2, v0, v1, v2)
                        # a (-d/dtheta through d): -p x g, g = m ud x w - m thd x (w x l0) - m thd x v
                        x0, x1, x2 = cross3(e0, e1, e2, w0, w1, w2)
                        y0, y1, y2 = cross3(w0, w1, w2, l0, l1, l2)
                        c0, c1_, c2 = cross3(s0, s1, s2, y0 + v0, y1 + v1, y2 + v2)
                        a0, a1, a2 = add_cross3(a0, a1, a2, -1.0, p0, p1, p2, m * (x0 - c0), m * (x1 - c1_),
                                                m * (x2 - c2))
        if j2:
            # Q = -m u~ u~ - theta~ J theta~ - m (u~ d~ + d~ u~) (symmetric), a~ b~ = b a' - (a . b) 1
            uu_ = u0 * u0 + u1 * u1 + u2 * u2
            q00 += m * (uu_ - u0 * u0)
            q01 -= m * u0 * u1
            q02 -= m * u0 * u2
            q11 += m * (uu_ - u1 * u1)
            q12 -= m * u1 * u2
            q22 += m * (uu_ - u2 * u2)
            if with_bias:
                # Qdot w = -m (ud x (u x w) + u x (ud x w)) - ...; gradient in u: -m w x (w x u) + m w x (d x w)
                x0, x1, x2 = cross3(u0, u1, u2, w0, w1, w2)
                g0, g1, g2 = add_cross3(g0, g1, g2, -m, e0, e1, e2, x0, x1, x2)
                x0, x1, x2 = cross3(e0, e1, e2, w0, w1, w2)
                g0, g1, g2 = add_cross3(g0, g1, g2, -m, u0, u1, u2, x0, x1, x2)
                x0, x1, x2 = cross3(w0, w1, w2, u0, u1, u2)
                z0, z1, z2 = add_cross3(z0, z1, z2, m, w0, w1, w2, x0, x1, x2)
            if rotary:
                # theta~ J theta~ = theta~ (J theta~): columns of J theta~ are J (theta x e_b)
                X00 = t2 * J01 - t1 * J02
                X01 = t0 * J02 - t2 * J00
                X02 = t1 * J00 - t0 * J01
                X10 = t2 * J11 - t1 * J12
                X11 = t0 * J12 - t2 * J10
                X12 = t1 * J10 - t0 * J11
                X20 = t2 * J21 - t1 * J22
                X21 = t0 * J22 - t2 * J20
                X22 = t1 * J20 - t0 * J21
                q00 -= t1 * X20 - t2 * X10
                q01 -= t1 * X21 - t2 * X11
                q02 -= t1 * X22 - t2 * X12
                q11 -= t2 * X01 - t0 * X21
                q12 -= t2 * X02 - t0 * X22
                q22 -= t0 * X12 - t1 * X02
                if offset:
                    ud_ = u0 * d0 + u1 * d1 + u2 * d2
                    q00 -= m * (2.0 * d0 * u0 - 2.0 * ud_)
                    q01 -= m * (d0 * u1 + u0 * d1)
                    q02 -= m * (d0 * u2 + u0 * d2)
                    q11 -= m * (2.0 * d1 * u1 - 2.0 * ud_)
                    q12 -= m * (d1 * u2 + u1 * d2)
                    q22 -= m * (2.0 * d2 * u2 - 2.0 * ud_)
                if with_bias:
                    # Qdot w: -(thd x (J (theta x w)) + theta x (J (thd x w)))
                    x0, x1, x2 = cross3(t0, t1, t2, w0, w1, w2)
                    y0 = J00 * x0 + J01 * x1 + J02 * x2
                    y1 = J10 * x0 + J11 * x1 + J12 * x2
                    y2 = J20 * x0 + J21 * x1 + J22 * x2
                    g0, g1, g2 = add_cross3(g0, g1, g2, -1.0, s0, s1, s2, y0, y1, y2)
                    # gradient in theta: w x (J (theta x w))
                    a0, a1, a2 = add_cross3(a0, a1, a2, -1.0, w0, w1, w2, y0, y1, y2)
                    x0, x1, x2 = cross3(s0, s1, s2, w0, w1, w2)
                    y0 = J00 * x0 + J01 * x1 + J02 * x2
                    y1 = J10 * x0 + J11 * x1 + J12 * x2
                    y2 = J20 * x0 + J21 * x1 + J22 * x2
                    g0, g1, g2 = add_cross3(g0, g1, g2, -1.0, t0, t1, t2, y0, y1, y2)
                    if offset:
                        # Qdot w: -m (ud x (d x w) + u x (dd x w) + dd x (u x w) + d x (ud x w))
                        x0, x1, x2 = cross3(d0, d1, d2, w0, w1, w2)
                        g0, g1, g2 = add_cross3(g0, g1, g2, -m, e0, e1, e2, x0, x1, x2)
                        # gradient in u: m w x (d x w)
                        z0, z1, z2 = add_cross3(z0, z1, z2, -m, w0, w1, w2, x0, x1, x2)
                        x0, x1, x2 = cross3(f0, f1, f2, w0, w1, w2)
                        g0, g1, g2 = add_cross3(g0, g1, g2, -m, u0, u1, u2, x0, x1, x2)
                        x0, x1, x2 = cross3(u0, u1, u2, w0, w1, w2)
                        g0, g1, g2 = add_cross3(g0, g1, g2, -m, f0, f1, f2, x0, x1, x2)
                        # gradient in theta through d: m p x (w x (u x w))
                        y0, y1, y2 = cross3(w0, w1, w2, x0, x1, x2)
                        a0, a1, a2 = add_cross3(a0, a1, a2, -m, p0, p1, p2, y0, y1, y2)
                        x0, x1, x2 = cross3(e0, e1, e2, w0, w1, w2)
                        g0, g1, g2 = add_cross3(g0, g1, g2, -m, d0, d1, d2, x0, x1, x2)
        if with_bias:
            store_node_vector(A, N, j, a0, a1, a2)
            store_node_vector(Z, N, j, z0, z1, z2)
    if j2:
        Mrr[0, 0] += q00
        Mrr[0, 1] += q01
        Mrr[0, 2] += q02
        Mrr[1, 0] += q01
        Mrr[1, 1] += q11
        Mrr[1, 2] += q12
        Mrr[2, 0] += q02
        Mrr[2, 1] += q12
        Mrr[2, 2] += q22
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
