"""The terms G1, F2, G2 of a flexible body's mass matrix summed over its nodes (numba): O(N_r n) per evaluation.

They come only from nodes whose own inertia turns with their elastic rotation (rotary inertia J_j about the
node, or a centre-of-mass offset p_j; TM-2020-5008164 eq. E.1.3 with the first-order attitude ``I + theta~``
of E.1.17). Per node j, with ``theta = lambda_j eta``, ``u = gamma_j eta`` and their rates, ``dP = (theta x p)~``,
the part of the body's kinetic energy they carry is (the blocks of ``Y_j' M_nd,j Y_j``, E.1.34, that the tables
G1, F2, G2 of :mod:`dynamics.flexible_body` hold)

    T_j = 1/2 theta_dot' dJ theta_dot + m theta_dot' dP u_dot + omega' Q theta_dot,
    dJ = (theta~ J - J theta~)  [G1]  - theta~ J theta~  [G2],      Q = -theta~ J theta~ - m u~ dP  [F2],

(the offset term of G1 with G1; order 1 keeps G1 only). The body's equations take from it (Lagrange for eta,
Euler-Poincare for the reference frame, as :func:`dynamics.flexible_kernels.modal_mass_and_bias` does for the
tables): the modal mass ``G0 + sum_j lambda_j' dJ lambda_j + m (lambda_j' dP gamma_j + gamma_j' dP' lambda_j)``,
the coupling ``M_re[omega rows] += Q lambda_j``, and the velocity terms

    b_m += lambda_j' (d/dt dpi_theta - dT/dtheta) + gamma_j' (d/dt dpi_u - dT/du),
    b_r[omega rows] += dQ/dt theta_dot + omega x (Q theta_dot),

with the per-node momenta ``pi_theta = dJ theta_dot + m dP u_dot + Q' omega``, ``pi_u = -m dP theta_dot``
differentiated at zero acceleration. Written out (cross products; G1: ``2 thd x (J thd)``, offsets
``m ((thd x p) x ud - p x (ud x thd))`` and ``m thd x (thd x p)``; G2: ``-2 thd x (J (th x thd))``; F2 below)
each node costs a pass over its 6 x n shapes to form ``theta, u`` and their rates and one to project back,
instead of contractions of n^3 and n^4 tables. The result equals the tables' to round-off
(``tests/flexible/test_node_inertia.py``).

Data (:mod:`dynamics.layout`): ``FX_NODES`` points at ``FX_NODE_COUNT`` records ``[m, p, J, offset flag]`` +
shapes, ``FX_NODE_TERMS`` says which terms, ``FX_P_NODES`` keeps each node's ``theta`` and ``u`` for the products
with the modal mass of the same evaluation (:func:`node_inertia_times`, :func:`node_inertia_modal_mass`).
"""

from __future__ import annotations

from numba import njit

from dynamics.flexible_kernels import FAST_SUMS
from dynamics.layout import NODE_F2, NODE_G1, NODE_G2, NODE_RECORD


@njit(cache=True, inline="always")
def _cross(a0, a1, a2, b0, b1, b2):
    return a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0


@njit(cache=True, inline="always")
def _times_inertia(params, j, x0, x1, x2):
    """J x for the row-major 3 x 3 ``J`` at ``params[j:j + 9]``."""
    return (params[j] * x0 + params[j + 1] * x1 + params[j + 2] * x2,
            params[j + 3] * x0 + params[j + 4] * x1 + params[j + 5] * x2,
            params[j + 6] * x0 + params[j + 7] * x1 + params[j + 8] * x2)


@njit(cache=True, inline="always")
def _q_times(params, j, m, t0, t1, t2, u0, u1, u2, c0, c1, c2, x0, x1, x2):
    """``Q x = -theta x (J (theta x x)) - m u x ((theta x p) x x)`` with ``c = theta x p``."""
    a0, a1, a2 = _cross(t0, t1, t2, x0, x1, x2)
    j0, j1, j2 = _times_inertia(params, j, a0, a1, a2)
    q0, q1, q2 = _cross(t0, t1, t2, j0, j1, j2)
    d0, d1, d2 = _cross(c0, c1, c2, x0, x1, x2)
    e0, e1, e2 = _cross(u0, u1, u2, d0, d1, d2)
    return -q0 - m * e0, -q1 - m * e1, -q2 - m * e2


@njit(cache=True, inline="always")
def _node_record(params, o, k, n):
    """The ``k``-th node record at ``o``: mass m, CG offset p, the params offset of J, whether p is non-zero,
    and the params offsets of its lambda (3 x n) and gamma (3 x n) rows."""
    b = o + k * (NODE_RECORD + 6 * n)
    lam = b + NODE_RECORD
    return params[b], params[b + 1], params[b + 2], params[b + 3], b + 4, params[b + 13] != 0.0, lam, lam + 3 * n


@njit(cache=True, inline="always")
def _dj_times(params, j, g1, g2, t0, t1, t2, x0, x1, x2):
    """``dJ x``, the change of the node's inertia ``J`` (at ``params[j:j + 9]``) turned by ``theta`` applied to
    ``x``: ``theta x (J x) - J (theta x x)`` (first order, G1) and ``- theta x J (theta x x)`` (second order, G2)."""
    a0 = a1 = a2 = 0.0
    if g1 or g2:
        c0, c1, c2 = _cross(t0, t1, t2, x0, x1, x2)
        k0, k1, k2 = _times_inertia(params, j, c0, c1, c2)
        if g1:
            j0, j1, j2 = _times_inertia(params, j, x0, x1, x2)
            y0, y1, y2 = _cross(t0, t1, t2, j0, j1, j2)
            a0 += y0 - k0
            a1 += y1 - k1
            a2 += y2 - k2
        if g2:
            y0, y1, y2 = _cross(t0, t1, t2, k0, k1, k2)
            a0 -= y0
            a1 -= y1
            a2 -= y2
    return a0, a1, a2


@njit(cache=True, inline="always")
def _block_times_two(params, at, n, x, y):
    """``(A x, A y)`` for the 3 x n block ``A`` stored row by row at ``params[at:]``."""
    a0 = a1 = a2 = b0 = b1 = b2 = 0.0
    for s in range(n):
        xs = x[s]
        ys = y[s]
        r0 = params[at + s]
        r1 = params[at + n + s]
        r2 = params[at + 2 * n + s]
        a0 += r0 * xs
        a1 += r1 * xs
        a2 += r2 * xs
        b0 += r0 * ys
        b1 += r1 * ys
        b2 += r2 * ys
    return a0, a1, a2, b0, b1, b2


@njit(cache=True, fastmath=FAST_SUMS)
def node_inertia_terms(params, o, count, n, terms, eta, V, e, with_bias, Mre, br, bm, nodes_state):
    """Add the node terms (module docstring) to ``Mre`` (6 x n: the omega rows, F2), and with ``with_bias`` to
    ``br`` (6) and ``bm`` (n); keep each node's ``theta`` and ``u`` in ``nodes_state`` (6 per node).
    ``o``: params offset of the ``count`` records; ``terms``: NODE_* bits; ``V``, ``e``: body velocity and
    modal rates."""
    g1 = (terms & NODE_G1) != 0
    g2 = (terms & NODE_G2) != 0
    f2 = (terms & NODE_F2) != 0
    w0, w1, w2 = V[0], V[1], V[2]
    for k in range(count):
        m, p0, p1, p2, jb, offset, lam, gam = _node_record(params, o, k, n)
        t0, t1, t2, d0, d1, d2 = _block_times_two(params, lam, n, eta, e)  # theta = lambda eta, lambda e
        u0 = u1 = u2 = v0 = v1 = v2 = 0.0
        if offset:
            u0, u1, u2, v0, v1, v2 = _block_times_two(params, gam, n, eta, e)  # u = gamma eta, gamma e
        st = 6 * k
        nodes_state[st] = t0
        nodes_state[st + 1] = t1
        nodes_state[st + 2] = t2
        nodes_state[st + 3] = u0
        nodes_state[st + 4] = u1
        nodes_state[st + 5] = u2
        c0, c1, c2 = _cross(t0, t1, t2, p0, p1, p2)  # theta x p (zero without an offset)
        # coefficients of lambda' and gamma' in b_m
        a0 = a1 = a2 = 0.0
        z0 = z1 = z2 = 0.0
        if with_bias:
            if g1:
                j0, j1, j2 = _times_inertia(params, jb, d0, d1, d2)
                x0, x1, x2 = _cross(d0, d1, d2, j0, j1, j2)
                a0 += 2.0 * x0
                a1 += 2.0 * x1
                a2 += 2.0 * x2
                if offset:
                    h0, h1, h2 = _cross(d0, d1, d2, p0, p1, p2)  # thd x p
                    x0, x1, x2 = _cross(h0, h1, h2, v0, v1, v2)
                    y0, y1, y2 = _cross(v0, v1, v2, d0, d1, d2)
                    yy0, yy1, yy2 = _cross(p0, p1, p2, y0, y1, y2)
                    a0 += m * (x0 - yy0)
                    a1 += m * (x1 - yy1)
                    a2 += m * (x2 - yy2)
                    x0, x1, x2 = _cross(d0, d1, d2, h0, h1, h2)
                    z0 += m * x0
                    z1 += m * x1
                    z2 += m * x2
            if g2 or f2:
                y0, y1, y2 = _cross(t0, t1, t2, d0, d1, d2)  # theta x thd
                jw0, jw1, jw2 = _times_inertia(params, jb, y0, y1, y2)
                x0, x1, x2 = _cross(d0, d1, d2, jw0, jw1, jw2)  # thd x J (theta x thd)
                if g2:
                    a0 -= 2.0 * x0
                    a1 -= 2.0 * x1
                    a2 -= 2.0 * x2
                if f2:
                    # b_r += dQ/dt thd + omega x (Q thd)
                    q0, q1, q2 = _q_times(params, jb, m, t0, t1, t2, u0, u1, u2, c0, c1, c2, d0, d1, d2)
                    r0, r1, r2 = _cross(w0, w1, w2, q0, q1, q2)
                    br[0] += r0 - x0
                    br[1] += r1 - x1
                    br[2] += r2 - x2
                    # b_m (lambda'): dQ/dt' omega - dT/dtheta
                    y0, y1, y2 = _cross(t0, t1, t2, w0, w1, w2)  # theta x omega
                    ja0, ja1, ja2 = _times_inertia(params, jb, y0, y1, y2)
                    y0, y1, y2 = _cross(d0, d1, d2, w0, w1, w2)  # thd x omega
                    jb0, jb1, jb2 = _times_inertia(params, jb, y0, y1, y2)
                    x0, x1, x2 = _cross(d0, d1, d2, ja0, ja1, ja2)
                    y0, y1, y2 = _cross(t0, t1, t2, jb0, jb1, jb2)
                    s0, s1, s2 = _cross(w0, w1, w2, jw0, jw1, jw2)
                    a0 -= 2.0 * x0 + y0 + s0
                    a1 -= 2.0 * x1 + y1 + s1
                    a2 -= 2.0 * x2 + y2 + s2
                    if offset:
                        h0, h1, h2 = _cross(d0, d1, d2, p0, p1, p2)  # thd x p
                        # b_r: - m [ud x ((theta x p) x thd) + u x ((thd x p) x thd)]
                        x0, x1, x2 = _cross(c0, c1, c2, d0, d1, d2)
                        y0, y1, y2 = _cross(v0, v1, v2, x0, x1, x2)
                        s0, s1, s2 = _cross(h0, h1, h2, d0, d1, d2)
                        r0, r1, r2 = _cross(u0, u1, u2, s0, s1, s2)
                        br[0] -= m * (y0 + r0)
                        br[1] -= m * (y1 + r1)
                        br[2] -= m * (y2 + r2)
                        # gamma': - m omega x ((theta x p) x thd)
                        y0, y1, y2 = _cross(w0, w1, w2, x0, x1, x2)
                        z0 -= m * y0
                        z1 -= m * y1
                        z2 -= m * y2
                        # lambda': - m [(thd x p) x (u x omega) + (theta x p) x (ud x omega)]
                        #          + m p x (thd x (omega x u))
                        x0, x1, x2 = _cross(u0, u1, u2, w0, w1, w2)
                        y0, y1, y2 = _cross(h0, h1, h2, x0, x1, x2)
                        x0, x1, x2 = _cross(v0, v1, v2, w0, w1, w2)
                        s0, s1, s2 = _cross(c0, c1, c2, x0, x1, x2)
                        x0, x1, x2 = _cross(w0, w1, w2, u0, u1, u2)
                        r0, r1, r2 = _cross(d0, d1, d2, x0, x1, x2)
                        x0, x1, x2 = _cross(p0, p1, p2, r0, r1, r2)
                        a0 += m * (x0 - y0 - s0)
                        a1 += m * (x1 - y1 - s1)
                        a2 += m * (x2 - y2 - s2)
        if f2:
            # the columns of Q: M_re[omega rows] += Q lambda
            qa0, qa1, qa2 = _q_times(params, jb, m, t0, t1, t2, u0, u1, u2, c0, c1, c2, 1.0, 0.0, 0.0)
            qb0, qb1, qb2 = _q_times(params, jb, m, t0, t1, t2, u0, u1, u2, c0, c1, c2, 0.0, 1.0, 0.0)
            qc0, qc1, qc2 = _q_times(params, jb, m, t0, t1, t2, u0, u1, u2, c0, c1, c2, 0.0, 0.0, 1.0)
            for s in range(n):
                l0_ = params[lam + s]
                l1_ = params[lam + n + s]
                l2_ = params[lam + 2 * n + s]
                Mre[0, s] += qa0 * l0_ + qb0 * l1_ + qc0 * l2_
                Mre[1, s] += qa1 * l0_ + qb1 * l1_ + qc1 * l2_
                Mre[2, s] += qa2 * l0_ + qb2 * l1_ + qc2 * l2_
        if with_bias:
            for s in range(n):
                bm[s] += params[lam + s] * a0 + params[lam + n + s] * a1 + params[lam + 2 * n + s] * a2
            if offset:
                for s in range(n):
                    bm[s] += params[gam + s] * z0 + params[gam + n + s] * z1 + params[gam + 2 * n + s] * z2


@njit(cache=True, fastmath=FAST_SUMS)
def node_inertia_times(params, o, count, n, terms, nodes_state, x, out):
    """``out += (G(eta) - G0 - tabled terms) x``: the node terms of the modal mass times ``x`` (n), with the
    ``theta`` and ``u`` that :func:`node_inertia_terms` kept in ``nodes_state``. O(count n)."""
    g1 = (terms & NODE_G1) != 0
    g2 = (terms & NODE_G2) != 0
    if not (g1 or g2):
        return
    for k in range(count):
        m, p0, p1, p2, jb, offset, lam, gam = _node_record(params, o, k, n)
        st = 6 * k
        t0, t1, t2 = nodes_state[st], nodes_state[st + 1], nodes_state[st + 2]
        al0 = al1 = al2 = be0 = be1 = be2 = 0.0
        for s in range(n):
            xs = x[s]
            al0 += params[lam + s] * xs
            al1 += params[lam + n + s] * xs
            al2 += params[lam + 2 * n + s] * xs
        if offset and g1:
            for s in range(n):
                xs = x[s]
                be0 += params[gam + s] * xs
                be1 += params[gam + n + s] * xs
                be2 += params[gam + 2 * n + s] * xs
        a0, a1, a2 = _dj_times(params, jb, g1, g2, t0, t1, t2, al0, al1, al2)
        z0 = z1 = z2 = 0.0
        if g1 and offset:
            c0, c1, c2 = _cross(t0, t1, t2, p0, p1, p2)
            x0, x1, x2 = _cross(c0, c1, c2, be0, be1, be2)
            a0 += m * x0
            a1 += m * x1
            a2 += m * x2
            z0, z1, z2 = _cross(al0, al1, al2, c0, c1, c2)
            z0 *= m
            z1 *= m
            z2 *= m
        for s in range(n):
            out[s] += params[lam + s] * a0 + params[lam + n + s] * a1 + params[lam + 2 * n + s] * a2
        if offset and g1:
            for s in range(n):
                out[s] += params[gam + s] * z0 + params[gam + n + s] * z1 + params[gam + 2 * n + s] * z2


@njit(cache=True, fastmath=FAST_SUMS)
def node_inertia_modal_mass(params, o, count, n, terms, nodes_state, G, scratch):
    """``G += sum_j lambda_j' dJ_j lambda_j + m_j (lambda_j' dP_j gamma_j + gamma_j' dP_j' lambda_j)`` (n x n):
    the node terms of the modal mass formed, O(count n^2) (for the composite-inertia mass matrix and a
    factored modal mass); ``scratch`` holds 3 n numbers."""
    g1 = (terms & NODE_G1) != 0
    g2 = (terms & NODE_G2) != 0
    if not (g1 or g2):
        return
    for k in range(count):
        m, p0, p1, p2, jb, offset, lam, gam = _node_record(params, o, k, n)
        st = 6 * k
        t0, t1, t2 = nodes_state[st], nodes_state[st + 1], nodes_state[st + 2]
        # X = dJ lambda (3 x n, in scratch), then G += lambda' X
        for s in range(n):
            x0 = params[lam + s]
            x1 = params[lam + n + s]
            x2 = params[lam + 2 * n + s]
            a0, a1, a2 = _dj_times(params, jb, g1, g2, t0, t1, t2, x0, x1, x2)
            scratch[s] = a0
            scratch[n + s] = a1
            scratch[2 * n + s] = a2
        for r in range(n):
            l0_ = params[lam + r]
            l1_ = params[lam + n + r]
            l2_ = params[lam + 2 * n + r]
            for s in range(n):
                G[r, s] += l0_ * scratch[s] + l1_ * scratch[n + s] + l2_ * scratch[2 * n + s]
        if offset and g1:
            # Y = m dP gamma: G += lambda' Y + Y' lambda
            c0, c1, c2 = _cross(t0, t1, t2, p0, p1, p2)
            for s in range(n):
                y0, y1, y2 = _cross(c0, c1, c2, params[gam + s], params[gam + n + s], params[gam + 2 * n + s])
                scratch[s] = m * y0
                scratch[n + s] = m * y1
                scratch[2 * n + s] = m * y2
            for r in range(n):
                l0_ = params[lam + r]
                l1_ = params[lam + n + r]
                l2_ = params[lam + 2 * n + r]
                y0, y1, y2 = scratch[r], scratch[n + r], scratch[2 * n + r]
                for s in range(n):
                    G[r, s] += (l0_ * scratch[s] + l1_ * scratch[n + s] + l2_ * scratch[2 * n + s]
                                + y0 * params[lam + s] + y1 * params[lam + n + s] + y2 * params[lam + 2 * n + s])
