"""Spatial-algebra primitives shared by every engine kernel (numba, float64, no allocation).

Conventions (docs/conventions.md; TM-2020-5008164 Appendix E; Featherstone, *Rigid Body
Dynamics Algorithms*, 2008, ch. 2):

* spatial velocity/acceleration ``[omega; v]`` (angular first), spatial force ``[torque; force]``;
* a body's quantities are expressed in its own frame, about its frame origin;
* ``R_pc`` maps vectors in the child frame ``c`` into the parent frame ``p``; ``r`` is the child origin
  in the parent frame. The motion transform parent -> child is
  ``omega_c = R^T omega_p``, ``v_c = R^T (v_p + omega_p x r)`` and its dual (force) transform child ->
  parent is ``n_p = R n_c + r x (R f_c)``, ``f_p = R f_c`` (Featherstone eqs. 2.24-2.26 in the
  angular-first ordering);
* quaternions are scalar first ``[w, x, y, z]`` and rotate child-frame vectors into the parent frame.

Every function writes into an output argument so that kernels allocate nothing per step.
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True, inline="always")
def cross_into(a, b, out):
    """out = a x b (3-vectors; out must not alias a or b)."""
    out[0] = a[1] * b[2] - a[2] * b[1]
    out[1] = a[2] * b[0] - a[0] * b[2]
    out[2] = a[0] * b[1] - a[1] * b[0]


@njit(cache=True, inline="always")
def quaternion_to_rotation(w, x, y, z, R):
    """Rotation matrix of a unit quaternion (scalar first, Hamilton); R maps child to parent."""
    R[0, 0] = 1.0 - 2.0 * (y * y + z * z)
    R[0, 1] = 2.0 * (x * y - w * z)
    R[0, 2] = 2.0 * (x * z + w * y)
    R[1, 0] = 2.0 * (x * y + w * z)
    R[1, 1] = 1.0 - 2.0 * (x * x + z * z)
    R[1, 2] = 2.0 * (y * z - w * x)
    R[2, 0] = 2.0 * (x * z - w * y)
    R[2, 1] = 2.0 * (y * z + w * x)
    R[2, 2] = 1.0 - 2.0 * (x * x + y * y)


@njit(cache=True, inline="always")
def axis_angle_to_rotation(a, angle, R):
    """Rodrigues' formula: rotation by ``angle`` about the unit axis ``a``."""
    c = np.cos(angle)
    s = np.sin(angle)
    t = 1.0 - c
    x, y, z = a[0], a[1], a[2]
    R[0, 0] = t * x * x + c
    R[0, 1] = t * x * y - s * z
    R[0, 2] = t * x * z + s * y
    R[1, 0] = t * x * y + s * z
    R[1, 1] = t * y * y + c
    R[1, 2] = t * y * z - s * x
    R[2, 0] = t * x * z - s * y
    R[2, 1] = t * y * z + s * x
    R[2, 2] = t * z * z + c


@njit(cache=True, inline="always")
def motion_to_child(R, r, m, out):
    """out = X m: a parent-frame spatial motion vector expressed in the child frame at its origin."""
    w0 = m[0]
    w1 = m[1]
    w2 = m[2]
    # velocity of the child origin, parent axes: v + omega x r
    v0 = m[3] + w1 * r[2] - w2 * r[1]
    v1 = m[4] + w2 * r[0] - w0 * r[2]
    v2 = m[5] + w0 * r[1] - w1 * r[0]
    out[0] = R[0, 0] * w0 + R[1, 0] * w1 + R[2, 0] * w2
    out[1] = R[0, 1] * w0 + R[1, 1] * w1 + R[2, 1] * w2
    out[2] = R[0, 2] * w0 + R[1, 2] * w1 + R[2, 2] * w2
    out[3] = R[0, 0] * v0 + R[1, 0] * v1 + R[2, 0] * v2
    out[4] = R[0, 1] * v0 + R[1, 1] * v1 + R[2, 1] * v2
    out[5] = R[0, 2] * v0 + R[1, 2] * v1 + R[2, 2] * v2


@njit(cache=True, inline="always")
def force_to_parent_add(R, r, f, out):
    """out += X^T f: a child-frame spatial force moved to the parent origin, parent axes."""
    f0 = R[0, 0] * f[3] + R[0, 1] * f[4] + R[0, 2] * f[5]
    f1 = R[1, 0] * f[3] + R[1, 1] * f[4] + R[1, 2] * f[5]
    f2 = R[2, 0] * f[3] + R[2, 1] * f[4] + R[2, 2] * f[5]
    n0 = R[0, 0] * f[0] + R[0, 1] * f[1] + R[0, 2] * f[2]
    n1 = R[1, 0] * f[0] + R[1, 1] * f[1] + R[1, 2] * f[2]
    n2 = R[2, 0] * f[0] + R[2, 1] * f[1] + R[2, 2] * f[2]
    out[0] += n0 + r[1] * f2 - r[2] * f1
    out[1] += n1 + r[2] * f0 - r[0] * f2
    out[2] += n2 + r[0] * f1 - r[1] * f0
    out[3] += f0
    out[4] += f1
    out[5] += f2


@njit(cache=True, inline="always")
def motion_cross_motion_add(V, m, out):
    """out += V x_m m  =  [w x mw ; w x mv + v x mw]  (Featherstone eq. 2.31)."""
    w0, w1, w2 = V[0], V[1], V[2]
    v0, v1, v2 = V[3], V[4], V[5]
    a0, a1, a2 = m[0], m[1], m[2]
    b0, b1, b2 = m[3], m[4], m[5]
    out[0] += w1 * a2 - w2 * a1
    out[1] += w2 * a0 - w0 * a2
    out[2] += w0 * a1 - w1 * a0
    out[3] += w1 * b2 - w2 * b1 + v1 * a2 - v2 * a1
    out[4] += w2 * b0 - w0 * b2 + v2 * a0 - v0 * a2
    out[5] += w0 * b1 - w1 * b0 + v0 * a1 - v1 * a0


@njit(cache=True, inline="always")
def motion_cross_force_add(V, f, out):
    """out += V x_f f  =  [w x n + v x f ; w x f]  (Featherstone eq. 2.32)."""
    w0, w1, w2 = V[0], V[1], V[2]
    v0, v1, v2 = V[3], V[4], V[5]
    n0, n1, n2 = f[0], f[1], f[2]
    g0, g1, g2 = f[3], f[4], f[5]
    out[0] += w1 * n2 - w2 * n1 + v1 * g2 - v2 * g1
    out[1] += w2 * n0 - w0 * n2 + v2 * g0 - v0 * g2
    out[2] += w0 * n1 - w1 * n0 + v0 * g1 - v1 * g0
    out[3] += w1 * g2 - w2 * g1
    out[4] += w2 * g0 - w0 * g2
    out[5] += w0 * g1 - w1 * g0


@njit(cache=True, inline="always")
def mat6_vec(M, x, out):
    """out = M x for a 6x6 matrix."""
    for i in range(6):
        s = 0.0
        for j in range(6):
            s += M[i, j] * x[j]
        out[i] = s


@njit(cache=True, inline="always")
def inertia_to_parent_add(R, r, I, out, tmp):
    """out += X^T I X: a child-frame 6x6 spatial inertia (symmetric) moved to the parent frame.

    With the blocks ``I = [[A, B], [B^T, C]]`` rotated into parent axes (``A' = R A R^T`` etc.) and
    ``S = skew(r)``: ``A_p = A' - B'S + S B'^T - S C' S``, ``B_p = B' + S C'``, ``C_p = C'``.
    ``tmp`` is a 6x6 scratch matrix.
    """
    # tmp = blockdiag(R, R) I blockdiag(R, R)^T, computed as (R I_blk) R^T block by block
    for bi in range(2):
        for bj in range(2):
            oi = 3 * bi
            oj = 3 * bj
            for i in range(3):
                # row i of R times block (bi, bj): h_k = sum_l R[i,l] I[oi+l, oj+k]
                h0 = R[i, 0] * I[oi, oj] + R[i, 1] * I[oi + 1, oj] + R[i, 2] * I[oi + 2, oj]
                h1 = R[i, 0] * I[oi, oj + 1] + R[i, 1] * I[oi + 1, oj + 1] + R[i, 2] * I[oi + 2, oj + 1]
                h2 = R[i, 0] * I[oi, oj + 2] + R[i, 1] * I[oi + 1, oj + 2] + R[i, 2] * I[oi + 2, oj + 2]
                for j in range(3):
                    tmp[oi + i, oj + j] = h0 * R[j, 0] + h1 * R[j, 1] + h2 * R[j, 2]
    x, y, z = r[0], r[1], r[2]
    # With B' = tmp[0:3, 3:6] and C' = tmp[3:6, 3:6] (rotated blocks):
    # B_p = B' + S C'  (S = skew(r); rows of S: (0,-z,y), (z,0,-x), (-y,x,0))
    for j in range(3):
        c0 = tmp[3, 3 + j]
        c1 = tmp[4, 3 + j]
        c2 = tmp[5, 3 + j]
        b0 = tmp[0, 3 + j] - z * c1 + y * c2
        b1 = tmp[1, 3 + j] + z * c0 - x * c2
        b2 = tmp[2, 3 + j] - y * c0 + x * c1
        out[0, 3 + j] += b0
        out[1, 3 + j] += b1
        out[2, 3 + j] += b2
        out[3 + j, 0] += b0
        out[3 + j, 1] += b1
        out[3 + j, 2] += b2
        out[3, 3 + j] += c0
        out[4, 3 + j] += c1
        out[5, 3 + j] += c2
    # A_p = A' - B'S + S B'^T - S C' S = A' + K + K^T - S C' S with K = S B'^T, since
    # (S B'^T)^T = -B'S. K is kept in the unused lower-left block of tmp: tmp[3+i, j] = K[i, j].
    for j in range(3):
        bj0 = tmp[j, 3]
        bj1 = tmp[j, 4]
        bj2 = tmp[j, 5]
        tmp[3, j] = -z * bj1 + y * bj2
        tmp[4, j] = z * bj0 - x * bj2
        tmp[5, j] = -y * bj0 + x * bj1
    # S C' S, rows of S C' then columns of S: (0,z,-y), (-z,0,x), (y,-x,0)
    for i in range(3):
        if i == 0:
            r0 = -z * tmp[4, 3] + y * tmp[5, 3]
            r1 = -z * tmp[4, 4] + y * tmp[5, 4]
            r2 = -z * tmp[4, 5] + y * tmp[5, 5]
        elif i == 1:
            r0 = z * tmp[3, 3] - x * tmp[5, 3]
            r1 = z * tmp[3, 4] - x * tmp[5, 4]
            r2 = z * tmp[3, 5] - x * tmp[5, 5]
        else:
            r0 = -y * tmp[3, 3] + x * tmp[4, 3]
            r1 = -y * tmp[3, 4] + x * tmp[4, 4]
            r2 = -y * tmp[3, 5] + x * tmp[4, 5]
        scs0 = r1 * z - r2 * y
        scs1 = -r0 * z + r2 * x
        scs2 = r0 * y - r1 * x
        out[i, 0] += tmp[i, 0] + tmp[3 + i, 0] + tmp[3, i] - scs0
        out[i, 1] += tmp[i, 1] + tmp[3 + i, 1] + tmp[4, i] - scs1
        out[i, 2] += tmp[i, 2] + tmp[3 + i, 2] + tmp[5, i] - scs2


@njit(cache=True, inline="always")
def force_to_parent_inplace(R, r, f):
    """f <- X^T f: move a spatial force (possibly a strided column) from child to parent frame."""
    f0 = R[0, 0] * f[3] + R[0, 1] * f[4] + R[0, 2] * f[5]
    f1 = R[1, 0] * f[3] + R[1, 1] * f[4] + R[1, 2] * f[5]
    f2 = R[2, 0] * f[3] + R[2, 1] * f[4] + R[2, 2] * f[5]
    n0 = R[0, 0] * f[0] + R[0, 1] * f[1] + R[0, 2] * f[2]
    n1 = R[1, 0] * f[0] + R[1, 1] * f[1] + R[1, 2] * f[2]
    n2 = R[2, 0] * f[0] + R[2, 1] * f[1] + R[2, 2] * f[2]
    f[0] = n0 + r[1] * f2 - r[2] * f1
    f[1] = n1 + r[2] * f0 - r[0] * f2
    f[2] = n2 + r[0] * f1 - r[1] * f0
    f[3] = f0
    f[4] = f1
    f[5] = f2


def spatial_inertia(mass, com, inertia_com):
    """6x6 spatial inertia about the frame origin from mass, center of mass and inertia about the COM.

    ``M = [[J_o, m skew(c)], [-m skew(c), m I]]`` with ``J_o = J_c + m (|c|^2 I - c c^T)``
    (parallel-axis theorem; docs/conventions.md).
    """
    c = np.asarray(com, dtype=np.float64)
    Jc = np.asarray(inertia_com, dtype=np.float64)
    skew_c = np.array([[0.0, -c[2], c[1]], [c[2], 0.0, -c[0]], [-c[1], c[0], 0.0]])
    M = np.zeros((6, 6))
    M[:3, :3] = Jc + mass * (c @ c * np.eye(3) - np.outer(c, c))
    M[:3, 3:] = mass * skew_c
    M[3:, :3] = -mass * skew_c
    M[3:, 3:] = mass * np.eye(3)
    return M


def skew(v):
    """3x3 cross-product matrix: skew(a) @ b == a x b."""
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


def rotation_to_quaternion(R):
    """Unit quaternion [w, x, y, z] (w >= 0) of a rotation matrix (Shepperd's method)."""
    R = np.asarray(R, dtype=np.float64)
    tr = np.trace(R)
    if tr > 0.0:
        s = 2.0 * np.sqrt(1.0 + tr)
        q = np.array([0.25 * s, (R[2, 1] - R[1, 2]) / s, (R[0, 2] - R[2, 0]) / s, (R[1, 0] - R[0, 1]) / s])
    else:
        k = int(np.argmax(np.diag(R)))
        i, j = (k + 1) % 3, (k + 2) % 3
        s = 2.0 * np.sqrt(1.0 + R[k, k] - R[i, i] - R[j, j])
        q = np.empty(4)
        q[0] = (R[j, i] - R[i, j]) / s
        q[1 + k] = 0.25 * s
        q[1 + i] = (R[i, k] + R[k, i]) / s
        q[1 + j] = (R[j, k] + R[k, j]) / s
    if q[0] < 0.0:
        q = -q
    return q / np.linalg.norm(q)


def rotation_from_rpy(roll, pitch, yaw):
    """URDF convention: R = Rz(yaw) Ry(pitch) Rx(roll) (fixed-axis X-Y-Z)."""
    cr, sr = np.cos(roll), np.sin(roll)
    cp, sp = np.cos(pitch), np.sin(pitch)
    cy, sy = np.cos(yaw), np.sin(yaw)
    return np.array([
        [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
        [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
        [-sp, cp * sr, cp * cr],
    ])
