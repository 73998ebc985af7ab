"""Per-body primitives of flexible bodies for the engine's recursion (numba, ``cache=True``).

The tree recursion itself (:mod:`dynamics.kernels`) treats every body as an *augmented* body with
velocity ``x = [V; eta_dot]`` of size ``6 + n`` (rigid bodies: n = 0). This module holds what only a
flexible body (n > 0) needs, each function over plain arrays:

* :func:`node_deformation` / :func:`node_pose`: the deformed pose of a node, ``R = exp((lambda eta)~)
  R0``, ``l = l0 + gamma eta``, its relative spatial velocity per unit modal rate
  ``Psi = [A; gamma + l~ A]``, ``A = J_l(lambda eta) lambda`` (``J_l`` the left Jacobian of SO(3), so the
  node's rotation and angular velocity are exactly consistent), and the velocity-product term ``w'``
  of ``d/dt (Psi eta_dot)``; :func:`node_motion` the same without forming ``Psi`` (``Psi eta_ddot`` from sums
  over the shape: a node's acceleration);
* :func:`psi_times_inverse_modal_mass`: ``Psi G^-1`` in O(n) from the precomputed ``Pi G^-1``;
* :func:`modal_mass_and_bias`: the body mass matrix ``M(eta) = M0 + M1 eta + M2 eta eta`` (TM-2020-5008164
  eqs. E.2.2-E.2.6, stored as the blocks of :class:`dynamics.flexible_body.ModalMassTerms`) and the body's
  gyroscopic, Coriolis and elastic forces from its kinetic energy ``T = 1/2 x' M(eta) x``:
  Euler-Poincare (Kirchhoff) equations for the quasi-velocity ``V`` and Lagrange's equations for eta,

      b = Mdot x + [omega x h_w + v x h_v; omega x h_v; -1/2 x' dM/deta_r x + K eta + C eta_dot],

  ``h = M x``, each block contracted in one pass over its table (cost per block in
  :mod:`dynamics.flexible_body`);
* :func:`modal_mass_solve_rows` and :func:`cholesky_in_place`: products with the inverse modal mass
  ``G^-1``, either precomputed at compile time (constant G: orders 0 and 1 without G1) or factored
  per call (G1 or G2 present).

Layout of a flexible body's data (:mod:`dynamics.layout`): the ``FX_*`` columns of its topology row (from
column ``FLEX`` on) hold offsets into the float ``params`` array (immutable description) and into the float
``pool`` (workspace).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from dynamics.layout import (
    FX_C, FX_C1, FX_C1_ROWS, FX_C_DIAGONAL, FX_F2, FX_G0, FX_G1, FX_G2, FX_GINV, FX_GINV_KIND, FX_J2, FX_K,
    FX_K_DIAGONAL, FX_M0RE, FX_P2, FX_R1, GINV_DENSE, GINV_DIAGONAL, GINV_FACTORED)

FAST_SUMS = {"reassoc", "contract"}
"""numba's fastmath flags of the kernels whose cost is long sums over modes (tables, node shapes, the modal
mass's factorization): reassociation lets LLVM vectorize a sum (measured 2-3x on the 196-mode beam of
benchmarks/flexible_scaling.py), contraction fuses its multiply-adds. The result changes by round-off only
(the order of the additions), and the same on every call: no finite-math or signed-zero assumptions."""


@njit(cache=True, inline="always")
def so3_coefficients(phi):
    """theta-functions of exp and the left Jacobian, and their derivatives divided by theta.

    R = I + a phi~ + b phi~^2; J_l = I + b phi~ + c phi~^2; returns a, b, c, b'/theta, c'/theta
    (series below theta = 0.05, where the closed forms lose digits to cancellation)."""
    t2 = phi[0] * phi[0] + phi[1] * phi[1] + phi[2] * phi[2]
    if t2 < 0.0025:
        a = 1.0 - t2 / 6.0 + t2 * t2 / 120.0 - t2 * t2 * t2 / 5040.0
        b = 0.5 - t2 / 24.0 + t2 * t2 / 720.0 - t2 * t2 * t2 / 40320.0
        c = 1.0 / 6.0 - t2 / 120.0 + t2 * t2 / 5040.0 - t2 * t2 * t2 / 362880.0
        db = -1.0 / 12.0 + t2 / 180.0 - t2 * t2 / 6720.0 + t2 * t2 * t2 / 453600.0
        dc = -1.0 / 60.0 + t2 / 1260.0 - t2 * t2 / 60480.0 + t2 * t2 * t2 / 4989600.0
    else:
        t = np.sqrt(t2)
        s = np.sin(t)
        co = np.cos(t)
        a = s / t
        b = (1.0 - co) / t2
        c = (t - s) / (t2 * t)
        db = s / (t2 * t) - 2.0 * (1.0 - co) / (t2 * t2)
        dc = (1.0 - co) / (t2 * t2) - 3.0 * (t - s) / (t2 * t2 * t)
    return a, b, c, db, dc


@njit(cache=True, inline="always")
def _skew_apply(p, x, out):
    out[0] = p[1] * x[2] - p[2] * x[1]
    out[1] = p[2] * x[0] - p[0] * x[2]
    out[2] = p[0] * x[1] - p[1] * x[0]


@njit(cache=True, fastmath=FAST_SUMS, inline="always")
def dots6(r0, r1, r2, r3, r4, r5, x, n, zero=0.0):
    """The six dot products ``r_i . x`` over the first ``n`` entries in one sweep over ``x`` (one load of ``x`` per six
    multiply-adds; vectorized over the entries), summed in the type of ``zero`` (``np.float32(0.0)`` for the
    single-precision products): the register tile that the modal elimination's six rows
    (:mod:`dynamics.kernels.modal_condensation`) and the node-major products of two nodes' or one node's six rows
    (:mod:`dynamics.kernels.node_inertia`) share."""
    c0 = c1 = c2 = c3 = c4 = c5 = zero
    for s in range(n):
        xs = x[s]
        c0 += r0[s] * xs
        c1 += r1[s] * xs
        c2 += r2[s] * xs
        c3 += r3[s] * xs
        c4 += r4[s] * xs
        c5 += r5[s] * xs
    return c0, c1, c2, c3, c4, c5


@njit(cache=True, fastmath=FAST_SUMS)
def _shape_sums(shape, n, x, rotation, translation):
    """``rotation = lambda x``, ``translation = gamma x`` (``shape`` = Pi = [lambda; gamma], 6 x >=n): six sums over
    the modes, each over a contiguous row (reassociated: vectorized, see :data:`FAST_SUMS`)."""
    for a in range(3):
        s = 0.0
        g = 0.0
        for r in range(n):
            s += shape[a, r] * x[r]
            g += shape[3 + a, r] * x[r]
        rotation[a] = s
        translation[a] = g


@njit(cache=True, inline="always")
def _deformed_pose(shape, l0, R0, eta, n, R, pos, tmp):
    """``phi = lambda eta`` into ``tmp[0]``, ``pos = l0 + gamma eta``, ``R = exp(phi~) R0`` (``tmp[3:6]`` scratch);
    returns the SO(3) coefficients of ``phi`` (:func:`so3_coefficients`)."""
    phi = tmp[0]
    _shape_sums(shape, n, eta, phi, pos)
    for a in range(3):
        pos[a] += l0[a]
    ca, cb, cc, dbt, dct = so3_coefficients(phi)
    # exp(phi~) = I + a phi~ + b phi~^2 ; phi~^2 = phi phi' - |phi|^2 I
    t2 = phi[0] * phi[0] + phi[1] * phi[1] + phi[2] * phi[2]
    E = tmp[3:6]
    for i in range(3):
        for j in range(3):
            E[i, j] = cb * (phi[i] * phi[j] - (t2 if i == j else 0.0)) + (1.0 if i == j else 0.0)
    E[0, 1] -= ca * phi[2]
    E[0, 2] += ca * phi[1]
    E[1, 0] += ca * phi[2]
    E[1, 2] -= ca * phi[0]
    E[2, 0] -= ca * phi[1]
    E[2, 1] += ca * phi[0]
    for i in range(3):
        for j in range(3):
            R[i, j] = E[i, 0] * R0[0, j] + E[i, 1] * R0[1, j] + E[i, 2] * R0[2, j]
    return ca, cb, cc, dbt, dct


@njit(cache=True, inline="always")
def _relative_velocity(pos, cb, cc, dbt, dct, w, wdot, tmp):
    """``w = Psi eta_dot`` and ``w'`` (the velocity-product part of d/dt (Psi eta_dot)) from ``phi = tmp[0]``,
    ``phidot = lambda eta_dot = tmp[1]`` and ``gamma eta_dot = tmp[2]`` (``tmp[3:7]`` scratch)."""
    phi = tmp[0]
    phidot = tmp[1]
    # omega_r = A eta_dot ; Adot eta_dot = Jdot phidot with
    # Jdot = bdot phi~ + b phidot~ + cdot phi~^2 + c (phidot~ phi~ + phi~ phidot~)
    pd = phi[0] * phidot[0] + phi[1] * phidot[1] + phi[2] * phidot[2]
    bdot = dbt * pd
    cdot = dct * pd
    # terms applied to phidot: phi~ phidot, phidot~ phidot = 0, phi~^2 phidot,
    # (phidot~ phi~ + phi~ phidot~) phidot = phidot x (phi x phidot) + phi x 0
    v1 = tmp[3]
    v2 = tmp[4]
    v3 = tmp[5]
    _skew_apply(phi, phidot, v1)  # phi x phidot
    _skew_apply(phi, v1, v2)  # phi x (phi x phidot)
    _skew_apply(phidot, v1, v3)  # phidot x (phi x phidot)
    om = tmp[6]
    for a in range(3):
        om[a] = phidot[a] + cb * v1[a] + cc * v2[a]  # omega_r = J_l phidot
        wdot[a] = bdot * v1[a] + cdot * v2[a] + cc * v3[a]  # Adot eta_dot
    # linear: (gamma eta_dot) x omega_r + l~ Adot eta_dot
    _skew_apply(tmp[2], om, v1)
    _skew_apply(pos, wdot[0:3], v2)
    for a in range(3):
        wdot[3 + a] = v1[a] + v2[a]
    # w = [omega_r; gamma eta_dot + l x omega_r]
    _skew_apply(pos, om, v1)
    for a in range(3):
        w[a] = om[a]
        w[3 + a] = tmp[2, a] + v1[a]


@njit(cache=True, inline="always")
def _psi_columns(src, n, phi, pos, cb, cc, out):
    """``out = [J_l a; g + l~ J_l a]`` (6 x n) for the columns ``[a; g]`` of ``src`` (6, >=n), with
    ``J_l = I + b phi~ + c (phi phi' - |phi|^2 I)`` (``cb``, ``cc`` from :func:`so3_coefficients` of ``phi``) and
    ``l = pos``: ``Psi`` from the shape ``Pi`` (:func:`node_deformation`), ``Psi G^-1`` from ``Pi G^-1``
    (:func:`psi_times_inverse_modal_mass`)."""
    t2 = phi[0] * phi[0] + phi[1] * phi[1] + phi[2] * phi[2]
    J00 = 1.0 + cc * (phi[0] * phi[0] - t2)
    J11 = 1.0 + cc * (phi[1] * phi[1] - t2)
    J22 = 1.0 + cc * (phi[2] * phi[2] - t2)
    J01 = -cb * phi[2] + cc * phi[0] * phi[1]
    J10 = cb * phi[2] + cc * phi[0] * phi[1]
    J02 = cb * phi[1] + cc * phi[0] * phi[2]
    J20 = -cb * phi[1] + cc * phi[0] * phi[2]
    J12 = -cb * phi[0] + cc * phi[1] * phi[2]
    J21 = cb * phi[0] + cc * phi[1] * phi[2]
    x, y, z = pos[0], pos[1], pos[2]
    for r in range(n):
        a0 = src[0, r]
        a1 = src[1, r]
        a2 = src[2, r]
        b0 = J00 * a0 + J01 * a1 + J02 * a2
        b1 = J10 * a0 + J11 * a1 + J12 * a2
        b2 = J20 * a0 + J21 * a1 + J22 * a2
        out[0, r] = b0
        out[1, r] = b1
        out[2, r] = b2
        out[3, r] = src[3, r] + y * b2 - z * b1
        out[4, r] = src[4, r] + z * b0 - x * b2
        out[5, r] = src[5, r] + x * b1 - y * b0


@njit(cache=True)
def node_deformation(shape, l0, R0, eta, n, eta_dot, R, pos, Psi, w, wdot, tmp):
    """Deformed pose of a node and its relative motion per unit modal rate.

    ``shape`` (6, >=n) = Pi = [lambda; gamma]; ``l0``, ``R0`` undeformed position and node -> body
    rotation. Writes ``R = exp((lambda eta)~) R0``, ``pos = l0 + gamma eta``, ``Psi`` (6, n) the node's
    spatial velocity at the body origin per unit eta_dot, ``w = Psi eta_dot`` (6) and ``wdot`` (6) the
    velocity-product part of d/dt (Psi eta_dot). ``tmp`` is a (8, 3) scratch array; on return
    ``tmp[0]`` holds ``phi = lambda eta``. Cost: the four sums ``lambda eta``, ``gamma eta``, ``lambda eta_dot``,
    ``gamma eta_dot`` over the modes and ``Psi = [J_l lambda; gamma + l~ J_l lambda]`` (two 3 x 3 matrices applied
    to the shape's columns): about 30 n flops. Where ``Psi`` is needed only times a vector (a node's acceleration),
    :func:`node_motion` forms that product from the shape without ``Psi``.
    """
    ca, cb, cc, dbt, dct = _deformed_pose(shape, l0, R0, eta, n, R, pos, tmp)
    _shape_sums(shape, n, eta_dot, tmp[1], tmp[2])
    _psi_columns(shape, n, tmp[0], pos, cb, cc, Psi)
    _relative_velocity(pos, cb, cc, dbt, dct, w, wdot, tmp)


@njit(cache=True)
def node_motion(shape, l0, R0, eta, n, eta_dot, eta_ddot, R, pos, w, wdot, psi_acc, tmp):
    """:func:`node_deformation` without ``Psi``: the deformed pose ``R``, ``pos``, ``w = Psi eta_dot``, ``w'`` and,
    with a non-empty ``eta_ddot`` (n), ``psi_acc = Psi eta_ddot = [J_l (lambda eta_ddot); gamma eta_ddot + l x
    J_l (lambda eta_ddot)]`` (linear in eta_ddot, so formed from two more sums over the shape instead of the 6 x n
    ``Psi``): what a node's pose, velocity and acceleration need, in six (eight) sums over the modes plus O(1).
    ``tmp`` (8, 3) scratch, ``tmp[0] = phi = lambda eta`` on return."""
    ca, cb, cc, dbt, dct = _deformed_pose(shape, l0, R0, eta, n, R, pos, tmp)
    if eta_ddot.shape[0] > 0:
        la = tmp[6]
        v1 = tmp[3]
        v2 = tmp[4]
        _shape_sums(shape, n, eta_ddot, la, tmp[7])
        phi = tmp[0]
        _skew_apply(phi, la, v1)
        _skew_apply(phi, v1, v2)
        for a in range(3):
            psi_acc[a] = la[a] + cb * v1[a] + cc * v2[a]
        _skew_apply(pos, psi_acc[0:3], v1)
        for a in range(3):
            psi_acc[3 + a] = tmp[7, a] + v1[a]
    _shape_sums(shape, n, eta_dot, tmp[1], tmp[2])
    _relative_velocity(pos, cb, cc, dbt, dct, w, wdot, tmp)


@njit(cache=True)
def node_pose(shape, l0, R0, eta, n, R, pos, tmp):
    """Deformed pose of a node only: ``R = exp((lambda eta)~) R0``, ``pos = l0 + gamma eta`` (O(n));
    ``tmp`` (8, 3) scratch, ``tmp[0] = phi = lambda eta`` on return."""
    phi = tmp[0]
    for a in range(3):
        s = 0.0
        g = l0[a]
        for r in range(n):
            s += shape[a, r] * eta[r]
            g += shape[3 + a, r] * eta[r]
        phi[a] = s
        pos[a] = g
    ca, cb, cc, dbt, dct = so3_coefficients(phi)
    t2 = phi[0] * phi[0] + phi[1] * phi[1] + phi[2] * phi[2]
    E = tmp[3:6]
    for i in range(3):
        for j in range(3):
            E[i, j] = cb * (phi[i] * phi[j] - (t2 if i == j else 0.0)) + (1.0 if i == j else 0.0)
    E[0, 1] -= ca * phi[2]
    E[0, 2] += ca * phi[1]
    E[1, 0] += ca * phi[2]
    E[1, 2] -= ca * phi[0]
    E[2, 0] -= ca * phi[1]
    E[2, 1] += ca * phi[0]
    for i in range(3):
        for j in range(3):
            R[i, j] = E[i, 0] * R0[0, j] + E[i, 1] * R0[1, j] + E[i, 2] * R0[2, j]


@njit(cache=True)
def node_modal_force(shape, n, phi, R, f, sign, out):
    """``out += sign * Psi' f6`` for a force ``f = [torque; force]`` in node axes at the deformed node,
    ``f6`` its resultant at the body origin: ``Psi' f6 = lambda' J_l' (R torque) + gamma' (R force)``
    (the torque about the node itself only turns the node, the force also moves it). O(n)."""
    ca, cb, cc, dbt, dct = so3_coefficients(phi)
    t0 = R[0, 0] * f[0] + R[0, 1] * f[1] + R[0, 2] * f[2]
    t1 = R[1, 0] * f[0] + R[1, 1] * f[1] + R[1, 2] * f[2]
    t2 = R[2, 0] * f[0] + R[2, 1] * f[1] + R[2, 2] * f[2]
    F0 = R[0, 0] * f[3] + R[0, 1] * f[4] + R[0, 2] * f[5]
    F1 = R[1, 0] * f[3] + R[1, 1] * f[4] + R[1, 2] * f[5]
    F2 = R[2, 0] * f[3] + R[2, 1] * f[4] + R[2, 2] * f[5]
    # J_l' t = t - b phi x t + c phi x (phi x t)
    c0 = phi[1] * t2 - phi[2] * t1
    c1 = phi[2] * t0 - phi[0] * t2
    c2 = phi[0] * t1 - phi[1] * t0
    d0 = phi[1] * c2 - phi[2] * c1
    d1 = phi[2] * c0 - phi[0] * c2
    d2 = phi[0] * c1 - phi[1] * c0
    j0 = sign * (t0 - cb * c0 + cc * d0)
    j1 = sign * (t1 - cb * c1 + cc * d1)
    j2 = sign * (t2 - cb * c2 + cc * d2)
    F0 *= sign
    F1 *= sign
    F2 *= sign
    for r in range(n):
        out[r] += (shape[0, r] * j0 + shape[1, r] * j1 + shape[2, r] * j2
                   + shape[3, r] * F0 + shape[4, r] * F1 + shape[5, r] * F2)


@njit(cache=True)
def psi_times_inverse_modal_mass(shape_ginv, n, phi, pos, Z):
    """``Z = Psi G^-1`` (6 x n) from the precomputed ``Pi G^-1 = [lambda G^-1; gamma G^-1]`` in O(n):
    ``Psi G^-1 = [J_l (lambda G^-1); gamma G^-1 + l~ J_l (lambda G^-1)]`` (``phi``, ``pos`` from
    :func:`node_deformation`)."""
    ca, cb, cc, dbt, dct = so3_coefficients(phi)
    _psi_columns(shape_ginv, n, phi, pos, cb, cc, Z)


@njit(cache=True, fastmath=FAST_SUMS)
def modal_mass_and_bias(fx, params, n, eta, V, e, with_bias, form_G, Mrr, Mre, Gm, br, bm, Mdrr, Mdre):
    """Blocks of ``M(eta)`` and, with ``with_bias``, the body forces ``b`` (module docstring).

    ``fx``: the body's FX_* columns; ``V`` (6) and ``e`` (n): the body velocity and modal rates.
    ``Mrr`` (6 x 6) must hold the constant rigid block ``M0[:6, :6]`` on entry and receives
    ``M_rr(eta)``; ``Mre`` (6 x n) receives ``M_re(eta)``; ``Gm`` (n x n) receives ``G(eta)`` when
    ``form_G``; ``br`` (6) and ``bm`` (n) receive ``b``; ``Mdrr`` (6 x 6) and ``Mdre`` (6 x n) are
    scratch (``dM/dt`` blocks). Cost: one pass over each present term's table."""
    o = fx[FX_M0RE]
    for a in range(6):
        for s in range(n):
            Mre[a, s] = params[o + a * n + s]
    if form_G:
        o = fx[FX_G0]
        for s in range(n):
            for l in range(n):
                Gm[s, l] = params[o + s * n + l]
    if with_bias:
        for a in range(6):
            for b in range(6):
                Mdrr[a, b] = 0.0
            for s in range(n):
                Mdre[a, s] = 0.0
        for s in range(n):
            bm[s] = 0.0
    w0, w1, w2 = V[0], V[1], V[2]
    if fx[FX_R1] >= 0:
        o = fx[FX_R1]
        for r in range(n):
            er = eta[r]
            dr = e[r]
            q = 0.0
            base = o + 36 * r
            for a in range(6):
                t = 0.0
                for b in range(6):
                    c = params[base + 6 * a + b]
                    Mrr[a, b] += er * c
                    t += c * V[b]
                    if with_bias:
                        Mdrr[a, b] += dr * c
                q += V[a] * t
            if with_bias:
                bm[r] -= 0.5 * q
    if fx[FX_C1] >= 0:
        o = fx[FX_C1]
        rows = fx[FX_C1_ROWS]
        for r in range(n):
            er = eta[r]
            dr = e[r]
            q = 0.0
            for a in range(rows):
                base = o + (r * rows + a) * n
                t = 0.0
                if with_bias:
                    for s in range(n):
                        c = params[base + s]
                        Mre[a, s] += er * c
                        Mdre[a, s] += dr * c
                        t += c * e[s]
                    q += V[a] * t
                else:
                    for s in range(n):
                        Mre[a, s] += er * params[base + s]
            if with_bias:
                bm[r] -= q  # -1/2 (2 V' C1_r e)
    if fx[FX_G1] >= 0 and (with_bias or form_G):
        o = fx[FX_G1]
        for r in range(n):
            er = eta[r]
            dr = e[r]
            q = 0.0
            for s in range(n):
                base = o + (r * n + s) * n
                h = 0.0
                if form_G:
                    for l in range(n):
                        c = params[base + l]
                        Gm[s, l] += er * c
                        h += c * e[l]
                else:
                    for l in range(n):
                        h += params[base + l] * e[l]
                if with_bias:
                    bm[s] += dr * h  # (dM_ee/dt) e
                    q += e[s] * h
            if with_bias:
                bm[r] -= 0.5 * q
    if fx[FX_J2] >= 0:
        o = fx[FX_J2]
        for r in range(n):
            J00 = J01 = J02 = J10 = J11 = J12 = J20 = J21 = J22 = 0.0
            for s in range(n):
                es = eta[s]
                base = o + 9 * (r * n + s)
                J00 += es * params[base]
                J01 += es * params[base + 1]
                J02 += es * params[base + 2]
                J10 += es * params[base + 3]
                J11 += es * params[base + 4]
                J12 += es * params[base + 5]
                J20 += es * params[base + 6]
                J21 += es * params[base + 7]
                J22 += es * params[base + 8]
            er = eta[r]
            Mrr[0, 0] += er * J00
            Mrr[0, 1] += er * J01
            Mrr[0, 2] += er * J02
            Mrr[1, 0] += er * J10
            Mrr[1, 1] += er * J11
            Mrr[1, 2] += er * J12
            Mrr[2, 0] += er * J20
            Mrr[2, 1] += er * J21
            Mrr[2, 2] += er * J22
            if with_bias:
                d2 = 2.0 * e[r]
                Mdrr[0, 0] += d2 * J00
                Mdrr[0, 1] += d2 * J01
                Mdrr[0, 2] += d2 * J02
                Mdrr[1, 0] += d2 * J10
                Mdrr[1, 1] += d2 * J11
                Mdrr[1, 2] += d2 * J12
                Mdrr[2, 0] += d2 * J20
                Mdrr[2, 1] += d2 * J21
                Mdrr[2, 2] += d2 * J22
                bm[r] -= (w0 * (J00 * w0 + J01 * w1 + J02 * w2) + w1 * (J10 * w0 + J11 * w1 + J12 * w2)
                          + w2 * (J20 * w0 + J21 * w1 + J22 * w2))
    if fx[FX_P2] >= 0:
        # geometric stiffening (dynamics.flexible_body): M_rr[:3, 3:6] += skew(p), M_rr[3:6, :3] -= skew(p),
        # p = sum_rs eta_r eta_s P2[r, s]; T gains omega . (p x v) = (v x omega) . p
        o = fx[FX_P2]
        p0 = p1 = p2 = 0.0
        d0 = d1 = d2 = 0.0
        x0 = V[4] * w2 - V[5] * w1  # v x omega
        x1 = V[5] * w0 - V[3] * w2
        x2 = V[3] * w1 - V[4] * w0
        for r in range(n):
            g0 = g1 = g2 = 0.0
            for s in range(n):
                es = eta[s]
                base = o + 3 * (r * n + s)
                g0 += es * params[base]
                g1 += es * params[base + 1]
                g2 += es * params[base + 2]
            er = eta[r]
            p0 += er * g0
            p1 += er * g1
            p2 += er * g2
            if with_bias:
                dr = 2.0 * e[r]
                d0 += dr * g0
                d1 += dr * g1
                d2 += dr * g2
                bm[r] -= 2.0 * (x0 * g0 + x1 * g1 + x2 * g2)
        Mrr[0, 4] -= p2
        Mrr[0, 5] += p1
        Mrr[1, 3] += p2
        Mrr[1, 5] -= p0
        Mrr[2, 3] -= p1
        Mrr[2, 4] += p0
        Mrr[4, 0] -= p2
        Mrr[5, 0] += p1
        Mrr[3, 1] += p2
        Mrr[5, 1] -= p0
        Mrr[3, 2] -= p1
        Mrr[4, 2] += p0
        if with_bias:
            Mdrr[0, 4] -= d2
            Mdrr[0, 5] += d1
            Mdrr[1, 3] += d2
            Mdrr[1, 5] -= d0
            Mdrr[2, 3] -= d1
            Mdrr[2, 4] += d0
            Mdrr[4, 0] -= d2
            Mdrr[5, 0] += d1
            Mdrr[3, 1] += d2
            Mdrr[5, 1] -= d0
            Mdrr[3, 2] -= d1
            Mdrr[4, 2] += d0
    if fx[FX_F2] >= 0:
        o = fx[FX_F2]
        for r in range(n):
            er = eta[r]
            dr = 2.0 * e[r]
            q = 0.0
            for s in range(n):
                es = eta[s]
                ers = er * es
                drs = dr * es
                for a in range(3):
                    base = o + ((r * n + s) * 3 + a) * n
                    t = 0.0
                    for l in range(n):
                        c = params[base + l]
                        Mre[a, l] += ers * c
                        if with_bias:
                            Mdre[a, l] += drs * c
                            t += c * e[l]
                    q += es * V[a] * t
            if with_bias:
                bm[r] -= 2.0 * q
    if fx[FX_G2] >= 0 and (with_bias or form_G):
        o = fx[FX_G2]
        for r in range(n):
            er = eta[r]
            dr = 2.0 * e[r]
            q = 0.0
            for s in range(n):
                es = eta[s]
                for l in range(n):
                    base = o + ((r * n + s) * n + l) * n
                    h = 0.0
                    if form_G:
                        ers = er * es
                        for m in range(n):
                            c = params[base + m]
                            Gm[l, m] += ers * c
                            h += c * e[m]
                    else:
                        for m in range(n):
                            h += params[base + m] * e[m]
                    if with_bias:
                        bm[l] += dr * es * h
                        q += es * e[l] * h
            if with_bias:
                bm[r] -= q
    if not with_bias:
        return
    # h_r = M_rr V + M_re e; rigid rows: dM/dt x + ad*_V h (Kirchhoff)
    h = br  # br is written last; use it for h first
    for a in range(6):
        s_ = 0.0
        for b in range(6):
            s_ += Mrr[a, b] * V[b]
        for s in range(n):
            s_ += Mre[a, s] * e[s]
        h[a] = s_
    v0, v1, v2 = V[3], V[4], V[5]
    c0 = w1 * h[2] - w2 * h[1] + v1 * h[5] - v2 * h[4]
    c1 = w2 * h[0] - w0 * h[2] + v2 * h[3] - v0 * h[5]
    c2 = w0 * h[1] - w1 * h[0] + v0 * h[4] - v1 * h[3]
    c3 = w1 * h[5] - w2 * h[4]
    c4 = w2 * h[3] - w0 * h[5]
    c5 = w0 * h[4] - w1 * h[3]
    br[0] = c0
    br[1] = c1
    br[2] = c2
    br[3] = c3
    br[4] = c4
    br[5] = c5
    for a in range(6):
        s_ = 0.0
        for b in range(6):
            s_ += Mdrr[a, b] * V[b]
        for s in range(n):
            s_ += Mdre[a, s] * e[s]
        br[a] += s_
    for s in range(n):
        t = 0.0
        for a in range(6):
            t += Mdre[a, s] * V[a]
        bm[s] += t
    o = fx[FX_K]
    if fx[FX_K_DIAGONAL]:
        for s in range(n):
            bm[s] += params[o + s * n + s] * eta[s]
    else:
        for s in range(n):
            t = 0.0
            for l in range(n):
                t += params[o + s * n + l] * eta[l]
            bm[s] += t
    o = fx[FX_C]
    if fx[FX_C_DIAGONAL]:
        for s in range(n):
            bm[s] += params[o + s * n + s] * e[s]
    else:
        for s in range(n):
            t = 0.0
            for l in range(n):
                t += params[o + s * n + l] * e[l]
            bm[s] += t


@njit(cache=True)
def modal_mass_times(fx, params, n, Gm, a, out):
    """``out = G a`` with the body's modal mass as its ``FX_GINV_KIND`` holds it: the constant ``G0``
    (diagonal or dense), or the ``G(eta)`` formed in ``Gm`` (when tables of G1 or G2 are present). The node
    terms of a refined body (``FX_REFINE``) are added by the caller
    (:func:`dynamics.kernels.body_terms.modal_mass_times`)."""
    if fx[FX_GINV_KIND] == GINV_FACTORED:
        for s in range(n):
            t = 0.0
            for l in range(n):
                t += Gm[s, l] * a[l]
            out[s] = t
        return
    o = fx[FX_G0]
    if fx[FX_GINV_KIND] == GINV_DIAGONAL:
        for s in range(n):
            out[s] = params[o + s * n + s] * a[s]
        return
    for s in range(n):
        t = 0.0
        for l in range(n):
            t += params[o + s * n + l] * a[l]
        out[s] = t


@njit(cache=True, fastmath=FAST_SUMS)
def cholesky_in_place(G, n):
    """Lower Cholesky factor of the symmetric ``G`` (n x n) in its lower triangle. Returns -1, or the first
    column whose pivot is not positive relative to its diagonal entry (a matrix that is not positive
    definite to round-off)."""
    for j in range(n):
        s = G[j, j]
        for k in range(j):
            s -= G[j, k] * G[j, k]
        if not s > 1e-14 * abs(G[j, j]):
            return j
        d = np.sqrt(s)
        G[j, j] = d
        for i in range(j + 1, n):
            t = G[i, j]
            for k in range(j):
                t -= G[i, k] * G[j, k]
            G[i, j] = t / d
    return -1


@njit(cache=True)
def cholesky_solve(L, n, y):
    """``y <- (L L')^-1 y`` in place for the lower Cholesky factor in ``L[:n, :n]`` (:func:`cholesky_in_place`):
    :func:`cholesky_substitutions` without reassociated sums (the dense solver's and the constraints' solves)."""
    cholesky_substitutions(L, n, y)


@njit(cache=True, inline="always")
def cholesky_substitutions(L, n, y):
    """``y <- (L L')^-1 y`` in place: forward, then backward substitution, both reading rows of L (the latter as
    updates of the entries above by each solved one: a column's entries are n apart; 0.62x of the sums down the
    columns at n = 30, 0.51x at n = 200, 2026-12-07). Inlined, so that it sums as its caller's flags say
    (:func:`cholesky_solve` exactly, the one-row modal-mass solve of :func:`modal_mass_solve_rows` reassociated)."""
    for s in range(n):
        t = y[s]
        for j in range(s):
            t -= L[s, j] * y[j]
        y[s] = t / L[s, s]
    for s in range(n - 1, -1, -1):
        z = y[s] / L[s, s]
        y[s] = z
        for j in range(s):
            y[j] -= L[s, j] * z


@njit(cache=True, fastmath=FAST_SUMS)
def modal_mass_solve_rows(fx, kind, params, n, L, X, rows, out):
    """``out[:rows] = X[:rows] G^-1`` (each row a vector of length n; ``out`` must not be ``X``): with the
    precomputed inverse (``kind`` GINV_DIAGONAL or GINV_DENSE) or the Cholesky factor ``L`` of ``G(eta)``
    (GINV_FACTORED)."""
    if kind == GINV_DIAGONAL:
        o = fx[FX_GINV]
        for a in range(rows):
            for s in range(n):
                out[a, s] = X[a, s] * params[o + s]
        return
    if kind == GINV_DENSE:
        o = fx[FX_GINV]
        for a in range(rows):
            for l in range(n):
                out[a, l] = 0.0
        # (X G^-1)[a, l] = sum_s X[a, s] Ginv[s, l]: rows of Ginv streamed once for all rows of X
        for s in range(n):
            base = o + s * n
            for a in range(rows):
                x = X[a, s]
                for l in range(n):
                    out[a, l] += x * params[base + l]
        return
    if rows == 1:
        # L L' z = x: forward substitution by dot products with the rows of L (reassociated: vectorized), back
        # substitution as updates of the entries above by each solved one (row s of L again, not column s: a
        # column's entries are n apart); 2026-12-07: 0.40 against 0.54 us at n = 20, 8.2 against 36 us at n = 196
        # (both sweeps as dot products); both as updates 0.42 and 26 us
        # L L' z = x by rows of L (2026-12-07: 0.40 against 0.54 us at n = 20, 8.2 against 36 us at n = 196 with both
        # sweeps as dot products; both as updates 0.42 and 26 us)
        o = out[0]
        for s in range(n):
            o[s] = X[0, s]
        cholesky_substitutions(L, n, o)
        return
    for b in range(0, rows, 6):
        _factored_solve_six(L, n, X, out, b, rows)


@njit(cache=True, fastmath=FAST_SUMS, inline="always")
def _factored_solve_six(L, n, X, out, b, rows):
    """``out[i] = X[i] (L L')^-1`` for the six rows ``i = b .. b + 5`` (past ``rows - 1``: the last row again, the
    same numbers written twice) at once: one load of each ``L[s, k]`` per six multiply-adds, six independent sums
    (one row at a time waits on each sum's additions and loads ``L`` six times: 3.3 against 0.75 us for the
    six rows of ``M_re`` at 20 modes, 2026-12-07). The back substitution reads column s of ``L``; as updates by
    row s instead (as the one-row solve) it measured 1.2x at 20 modes and 0.54x at 196 (where the modal mass is
    factored only when its refinement does not converge), 2026-12-07."""
    i0, i1, i2 = b, min(b + 1, rows - 1), min(b + 2, rows - 1)
    i3, i4, i5 = min(b + 3, rows - 1), min(b + 4, rows - 1), min(b + 5, rows - 1)
    for s in range(n):
        t0, t1, t2, t3, t4, t5 = X[i0, s], X[i1, s], X[i2, s], X[i3, s], X[i4, s], X[i5, s]
        for k in range(s):
            c = L[s, k]
            t0 -= c * out[i0, k]
            t1 -= c * out[i1, k]
            t2 -= c * out[i2, k]
            t3 -= c * out[i3, k]
            t4 -= c * out[i4, k]
            t5 -= c * out[i5, k]
        d = 1.0 / L[s, s]  # one division per step, not six
        out[i0, s] = t0 * d
        out[i1, s] = t1 * d
        out[i2, s] = t2 * d
        out[i3, s] = t3 * d
        out[i4, s] = t4 * d
        out[i5, s] = t5 * d
    for s in range(n - 1, -1, -1):
        t0, t1, t2, t3, t4, t5 = out[i0, s], out[i1, s], out[i2, s], out[i3, s], out[i4, s], out[i5, s]
        for k in range(s + 1, n):
            c = L[k, s]
            t0 -= c * out[i0, k]
            t1 -= c * out[i1, k]
            t2 -= c * out[i2, k]
            t3 -= c * out[i3, k]
            t4 -= c * out[i4, k]
            t5 -= c * out[i5, k]
        d = 1.0 / L[s, s]  # one division per step, not six
        out[i0, s] = t0 * d
        out[i1, s] = t1 * d
        out[i2, s] = t2 * d
        out[i3, s] = t3 * d
        out[i4, s] = t4 * d
        out[i5, s] = t5 * d
