"""The attitude library: quaternions, rotation vectors, MRPs and rotation matrices, written once.

Conventions (docs/conventions.md): quaternions scalar first ``[w, x, y, z]``, Hamilton product, a body's
quaternion rotates body-axis vectors into the parent (world) frame, ``v_N = q (x) v_B (x) q^*``.
Modified Rodrigues parameters ``sigma = v / (1 + w)`` (Schaub and Junkins, "Analytical Mechanics of
Space Systems", 4th ed., sec. 3.7), taken on the short rotation (``w >= 0``, so ``|sigma| <= 1``).

Every model kernel uses these (numba, tuples in and out, no allocation; numba inlines them into the
kernel). The same formulas serve analysis and charts on arrays of samples: :func:`quaternion_products`,
:func:`quaternion_error` and :func:`euler_321` take ``(..., 4)`` arrays (numpy, not compiled), and
:func:`quaternion_products` evaluates the very expression the kernels compile, so a chart and a kernel
agree to the last bit.
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True)
def quaternion_multiply(a, b):
    """Hamilton product a (x) b of two 4-tuples."""
    aw, ax, ay, az = a
    bw, bx, by, bz = b
    return (aw * bw - ax * bx - ay * by - az * bz,
            aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw)


@njit(cache=True)
def quaternion_conjugate(q):
    return (q[0], -q[1], -q[2], -q[3])


@njit(cache=True)
def quaternion_normalized(q):
    n = np.sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3])
    return (q[0] / n, q[1] / n, q[2] / n, q[3] / n)


@njit(cache=True)
def error_rotation_vector(reference, q):
    """``2 sign(w_e) v_e`` of the error quaternion ``q_e = reference^* (x) q`` (rotation from the reference to
    the actual frame): the rotation vector of the error for small angles, the short way round (Wie, "Space
    Vehicle Dynamics and Control", 2nd ed., sec. 7.3, quaternion-feedback regulator; Markley and Crassidis
    2014, sec. 7.2.4, the star-tracker innovation)."""
    e = quaternion_multiply(quaternion_conjugate(reference), q)
    s = 2.0 if e[0] >= 0.0 else -2.0
    return (s * e[1], s * e[2], s * e[3])


@njit(cache=True)
def rotation_vector_quaternion(v0, v1, v2):
    """exp(v / 2): the unit quaternion of the rotation vector v (exact)."""
    angle = np.sqrt(v0 * v0 + v1 * v1 + v2 * v2)
    if angle < 1e-300:
        return 1.0, 0.0, 0.0, 0.0
    s = np.sin(0.5 * angle) / angle
    return np.cos(0.5 * angle), s * v0, s * v1, s * v2


@njit(cache=True)
def quaternion_to_matrix(w, x, y, z):
    """Row-major rotation matrix (9-tuple) of the unit quaternion [w, x, y, z] (child -> parent)."""
    return (1.0 - 2.0 * (y * y + z * z), 2.0 * (x * y - w * z), 2.0 * (x * z + w * y),
            2.0 * (x * y + w * z), 1.0 - 2.0 * (x * x + z * z), 2.0 * (y * z - w * x),
            2.0 * (x * z - w * y), 2.0 * (y * z + w * x), 1.0 - 2.0 * (x * x + y * y))


@njit(cache=True)
def rotate(q, v):
    """q (x) v (x) q^*: a vector from the quaternion's child frame into its parent frame."""
    w, x, y, z = q
    # v + 2 w (r x v) + 2 r x (r x v), r = (x, y, z)
    cx, cy, cz = y * v[2] - z * v[1], z * v[0] - x * v[2], x * v[1] - y * v[0]
    return (v[0] + 2.0 * (w * cx + y * cz - z * cy),
            v[1] + 2.0 * (w * cy + z * cx - x * cz),
            v[2] + 2.0 * (w * cz + x * cy - y * cx))


@njit(cache=True)
def rotate_inverse(q, v):
    """q^* (x) v (x) q: a vector from the parent frame into the child frame."""
    return rotate(quaternion_conjugate(q), v)


@njit(cache=True)
def quaternion_rotation_vector(q):
    """Log(q): the rotation vector phi with ``q = exp(phi / 2)`` on the short rotation (``|phi| <= pi``), the
    exact inverse of :func:`rotation_vector_quaternion` (``phi = 2 atan2(|v|, w) v / |v|`` with ``w >= 0``;
    Sola, "Quaternion kinematics for the error-state Kalman filter", 2017, eq. 105). ``q`` need not be unit:
    atan2 takes the ratio."""
    s = 1.0 if q[0] >= 0.0 else -1.0
    vx, vy, vz = s * q[1], s * q[2], s * q[3]
    n = np.sqrt(vx * vx + vy * vy + vz * vz)
    w = s * q[0]
    if n < 1e-8 * w:  # 2 atan2(n, w) / n = (2 / w) (1 - (n / w)^2 / 3 + ...): the series, exact to round-off
        k = 2.0 / w * (1.0 - n * n / (3.0 * w * w))
    else:
        k = 2.0 * np.arctan2(n, w) / n
    return (k * vx, k * vy, k * vz)


@njit(cache=True)
def quaternion_to_mrp(q):
    """MRP of the short rotation: sigma = v / (1 + w) with the sign making w >= 0."""
    s = 1.0 if q[0] >= 0.0 else -1.0
    d = 1.0 + s * q[0]
    return (s * q[1] / d, s * q[2] / d, s * q[3] / d)


@njit(cache=True)
def axis_angle_quaternion(e, angle):
    """Rotation by ``angle`` about the unit axis ``e``."""
    s = np.sin(0.5 * angle)
    return (np.cos(0.5 * angle), s * e[0], s * e[1], s * e[2])


@njit(cache=True)
def quaternion_to_axis_angle(q):
    """(unit axis, angle in [0, pi]) of the short rotation; axis (1, 0, 0) at zero angle."""
    s = 1.0 if q[0] >= 0.0 else -1.0
    vx, vy, vz = s * q[1], s * q[2], s * q[3]
    n = np.sqrt(vx * vx + vy * vy + vz * vz)
    angle = 2.0 * np.arctan2(n, s * q[0])
    if n < 1e-300:
        return (1.0, 0.0, 0.0), 0.0
    return (vx / n, vy / n, vz / n), angle


@njit(cache=True)
def cross(a, b):
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


@njit(cache=True)
def dot(a, b):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


@njit(cache=True)
def unit(a):
    n = np.sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2])
    return (a[0] / n, a[1] / n, a[2] / n)


@njit(cache=True)
def matrix_to_quaternion(r00, r01, r02, r10, r11, r12, r20, r21, r22):
    """Quaternion (w >= 0) of a rotation matrix given row by row (Shepperd's method: the largest of the four
    squared components first, the others from sums and differences of off-diagonal pairs)."""
    trace = r00 + r11 + r22
    if trace >= r00 and trace >= r11 and trace >= r22:
        w = 0.5 * np.sqrt(1.0 + trace)
        f = 0.25 / w
        q = (w, (r21 - r12) * f, (r02 - r20) * f, (r10 - r01) * f)
    elif r00 >= r11 and r00 >= r22:
        x = 0.5 * np.sqrt(1.0 + r00 - r11 - r22)
        f = 0.25 / x
        q = ((r21 - r12) * f, x, (r01 + r10) * f, (r02 + r20) * f)
    elif r11 >= r22:
        y = 0.5 * np.sqrt(1.0 - r00 + r11 - r22)
        f = 0.25 / y
        q = ((r02 - r20) * f, (r01 + r10) * f, y, (r12 + r21) * f)
    else:
        z = 0.5 * np.sqrt(1.0 - r00 - r11 + r22)
        f = 0.25 / z
        q = ((r10 - r01) * f, (r02 + r20) * f, (r12 + r21) * f, z)
    if q[0] < 0.0:
        q = (-q[0], -q[1], -q[2], -q[3])
    return q


@njit(cache=True)
def two_axis_frame_quaternion(b1, b2, n1, n2):
    """Quaternion (frame R -> world) of the frame R whose axis ``b1`` (R axes) points along the world
    direction ``n1`` and whose axis ``b2`` lies in the half-plane of ``n2`` about ``n1`` (the TRIAD
    construction, Markley and Crassidis 2014 sec. 5.2.1). b1, b2 and n1, n2 must not be parallel."""
    r1 = unit(b1)
    r2 = unit(cross(b1, b2))
    r3 = cross(r1, r2)
    s1 = unit(n1)
    s2 = unit(cross(n1, n2))
    s3 = cross(s1, s2)
    # R = S B^T with S = [s1 s2 s3], B = [r1 r2 r3]
    return matrix_to_quaternion(
        s1[0] * r1[0] + s2[0] * r2[0] + s3[0] * r3[0], s1[0] * r1[1] + s2[0] * r2[1] + s3[0] * r3[1],
        s1[0] * r1[2] + s2[0] * r2[2] + s3[0] * r3[2],
        s1[1] * r1[0] + s2[1] * r2[0] + s3[1] * r3[0], s1[1] * r1[1] + s2[1] * r2[1] + s3[1] * r3[1],
        s1[1] * r1[2] + s2[1] * r2[2] + s3[1] * r3[2],
        s1[2] * r1[0] + s2[2] * r2[0] + s3[2] * r3[0], s1[2] * r1[1] + s2[2] * r2[1] + s3[2] * r3[1],
        s1[2] * r1[2] + s2[2] * r2[2] + s3[2] * r3[2])


@njit(cache=True)
def matrix_at_to_quaternion(u, at):
    """Unit quaternion [w, x, y, z] (w >= 0) of the row-major rotation matrix ``u[at:at + 9]`` (a rotation
    input port): Shepperd's method as :func:`matrix_to_quaternion`, with each pivot from ``1 + 2 r_ii - trace``
    and the other components divided by four times the pivot."""
    r00, r01, r02 = u[at], u[at + 1], u[at + 2]
    r10, r11, r12 = u[at + 3], u[at + 4], u[at + 5]
    r20, r21, r22 = u[at + 6], u[at + 7], u[at + 8]
    trace = r00 + r11 + r22
    if trace >= r00 and trace >= r11 and trace >= r22:
        w = 0.5 * np.sqrt(1.0 + trace)
        q = (w, (r21 - r12) / (4.0 * w), (r02 - r20) / (4.0 * w), (r10 - r01) / (4.0 * w))
    elif r00 >= r11 and r00 >= r22:
        x = 0.5 * np.sqrt(1.0 + 2.0 * r00 - trace)
        q = ((r21 - r12) / (4.0 * x), x, (r01 + r10) / (4.0 * x), (r02 + r20) / (4.0 * x))
    elif r11 >= r22:
        y = 0.5 * np.sqrt(1.0 + 2.0 * r11 - trace)
        q = ((r02 - r20) / (4.0 * y), (r01 + r10) / (4.0 * y), y, (r12 + r21) / (4.0 * y))
    else:
        z = 0.5 * np.sqrt(1.0 + 2.0 * r22 - trace)
        q = ((r10 - r01) / (4.0 * z), (r02 + r20) / (4.0 * z), (r12 + r21) / (4.0 * z), z)
    sign = 1.0 if q[0] >= 0.0 else -1.0
    return sign * q[0], sign * q[1], sign * q[2], sign * q[3]


# ------------------------------------------------------------------------------------------------------
# arrays of samples (analysis, charts, views): numpy over (..., 4) arrays, the kernels' own formulas
def quaternion_products(a, b) -> np.ndarray:
    """``a (x) b`` for quaternions stacked along the last axis (broadcasting), evaluated by the Python body of
    :func:`quaternion_multiply` on whole component arrays."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    return np.stack(quaternion_multiply.py_func(np.moveaxis(a, -1, 0), np.moveaxis(b, -1, 0)), axis=-1)


def quaternion_error(q, reference) -> np.ndarray:
    """Error quaternions ``e = r^* (x) q`` of samples ``q`` (N, 4) against one reference ``r``."""
    q = np.asarray(q, float).reshape(-1, 4)
    return quaternion_products(quaternion_conjugate.py_func(np.asarray(reference, float)), q)


def attitude_error(q, reference=(1.0, 0.0, 0.0, 0.0)) -> np.ndarray:
    """Rotation angle (rad, in [0, pi]) from ``reference`` to each attitude sample, the short way round:
    ``2 atan2(|v_e|, |w_e|)`` of the error quaternion."""
    e = quaternion_error(q, reference)
    return 2.0 * np.arctan2(np.linalg.norm(e[:, 1:], axis=1), np.abs(e[:, 0]))


def euler_321(q) -> np.ndarray:
    """(N, 3) yaw, pitch, roll (rad) of the 3-2-1 sequence of quaternions ``q`` (N, 4), normalized first (Diebel
    2006, "Representing attitude", eq. 290: yaw = atan2(2(xy + wz), w² + x² - y² - z²), pitch = -asin(2(xz - wy)),
    roll = atan2(2(yz + wx), w² - x² - y² + z²))."""
    q = np.asarray(q, float).reshape(-1, 4)
    q = q / np.linalg.norm(q, axis=1, keepdims=True)
    w, x, y, z = q.T
    yaw = np.arctan2(2.0 * (x * y + w * z), w * w + x * x - y * y - z * z)
    pitch = -np.arcsin(np.clip(2.0 * (x * z - w * y), -1.0, 1.0))
    roll = np.arctan2(2.0 * (y * z + w * x), w * w - x * x - y * y + z * z)
    return np.column_stack([yaw, pitch, roll])
