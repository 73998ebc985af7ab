"""Hinge (joint) types: one record per type (:class:`Hinge`, :data:`HINGES`) that the builder, the engine's layout,
the shell's ports, YAML initial values and plots read, and the type's kernels (position kinematics, motion
subspace, coordinate rates), which branch on its code.

A hinge connects an inboard frame F, fixed on the parent body (or the ground), to an outboard frame M,
fixed on the child body. The hinge coordinates ``q`` give the pose of M relative to F and the velocity
coordinates ``u`` the relative spatial velocity of M with respect to F, expressed in M:

===========  ==  ==  ================================================================================
type         nq  nu  coordinates (docs/conventions.md)
===========  ==  ==  ================================================================================
locked        0   0  none
revolute      1   1  angle about the unit axis a1 (same in F and M)
prismatic     1   1  displacement along the unit axis a1
ujoint        2   2  angles about a1 (in F) then a2 (in the intermediate frame = in M): R_FM = R(a1,q1) R(a2,q2)
spherical     4   3  quaternion [w,x,y,z] of M in F; u = angular velocity of M relative to F, in M
free          7   6  quaternion of M in F, then position of M's origin in F; u = [omega; v] of M, in M
translation   3   3  position of M's origin in F, M parallel to F; u = its velocity (in M = in F)
===========  ==  ==  ================================================================================

The motion subspace in M is ``S_M`` (``V_rel = S_M u``); its apparent derivative ``c_J = dS_M/dt u`` is
non-zero only for the U-joint, ``c_J = [(R2^T a1 u1) x (a2 u2); 0]`` (Featherstone, RBDA, sec. 4.4).
The engine carries both into the body frame B with the constant transform B <- M.

A new hinge type is a :class:`Hinge` record appended to :data:`HINGES` (its code is its index) and its branches in
:func:`hinge_transform`, :func:`hinge_motion_subspace` and :func:`hinge_coordinate_rates`; a type whose motion
subspace depends on ``q`` (as the U-joint's) also needs it recomputed per evaluation, with its ``c_J``, in
:mod:`dynamics.kernels.kinematics`.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit

from dynamics.spatial import axis_angle_to_rotation, quaternion_to_rotation


class Hinge(NamedTuple):
    """What the builder, the engine and the shell know of one hinge type (its kernels branch on its code)."""

    name: str
    nq: int
    nu: int
    n_axes: int               # user axes it takes: 0, 1 (``axis``) or 2 (``axes``)
    rotation: str             # how it turns the body, for the inertia it needs: "none", "axes" (about its axes),
    #                           "point" (about the hinge point, any axis), "free" (about the center of mass)
    quaternion: bool          # q starts with a unit quaternion [w, x, y, z] of M in F, u with M's angular velocity
    element_dofs: int         # how many of its DOFs (angles, displacements) a hinge spring or damper can act on
    units: tuple              # of (q, u, u_dot, generalized force); "" for mixed or dimensionless (SI values)
    labels: tuple             # (labels of q, labels of u) in plots
    initial: tuple            # YAML ``initial:`` keys: (key, "q" or "u", first, end, unit) in the hinge's coordinates
    neutral: tuple            # q at rest: zero angles and displacements, identity quaternions


_ANGLE = ("rad", "rad/s", "rad/s^2", "N*m")
_LENGTH = ("m", "m/s", "m/s^2", "N")
_ATTITUDE = (("attitude", "q", 0, 4, ""), ("angular_velocity", "u", 0, 3, "rad/s"))

#: the hinge types; a type's code (the engine's ``HINGE_TYPE`` column) is its index
HINGES = (
    Hinge("locked", 0, 0, 0, "none", False, 0, ("", "", "", ""), ((), ()), (), ()),
    Hinge("revolute", 1, 1, 1, "axes", False, 1, _ANGLE, (("revolute",), ("revolute",)),
          (("angle", "q", 0, 1, "rad"), ("angle_rate", "u", 0, 1, "rad/s")), (0.0,)),
    Hinge("prismatic", 1, 1, 1, "none", False, 1, _LENGTH, (("prismatic",), ("prismatic",)),
          (("displacement", "q", 0, 1, "m"), ("displacement_rate", "u", 0, 1, "m/s")), (0.0,)),
    Hinge("ujoint", 2, 2, 2, "axes", False, 2, _ANGLE, (("angle1", "angle2"), ("rate1", "rate2")),
          (("angle", "q", 0, 2, "rad"), ("angle_rate", "u", 0, 2, "rad/s")), (0.0, 0.0)),
    Hinge("spherical", 4, 3, 0, "point", True, 0, ("", "rad/s", "rad/s^2", "N*m"),
          (("qw", "qx", "qy", "qz"), ("ωx", "ωy", "ωz")), _ATTITUDE, (1.0, 0.0, 0.0, 0.0)),
    Hinge("free", 7, 6, 0, "free", True, 0, ("", "", "", ""),
          (("qw", "qx", "qy", "qz", "x", "y", "z"), ("ωx", "ωy", "ωz", "vx", "vy", "vz")),
          _ATTITUDE + (("position", "q", 4, 7, "m"), ("velocity", "u", 3, 6, "m/s")), (1.0, 0.0, 0.0, 0.0, 0, 0, 0)),
    Hinge("translation", 3, 3, 0, "none", False, 3, _LENGTH, (("x", "y", "z"), ("vx", "vy", "vz")),
          (("position", "q", 0, 3, "m"), ("velocity", "u", 0, 3, "m/s")), (0.0, 0.0, 0.0)),
)

HINGE_TYPES = {h.name: code for code, h in enumerate(HINGES)}
# the codes the kernels branch on
LOCKED, REVOLUTE, PRISMATIC, UJOINT, SPHERICAL, FREE, TRANSLATION = (
    HINGE_TYPES[name] for name in ("locked", "revolute", "prismatic", "ujoint", "spherical", "free", "translation"))
HINGE_NQ = np.array([h.nq for h in HINGES], dtype=np.int64)
HINGE_NU = np.array([h.nu for h in HINGES], dtype=np.int64)


def hinge(name_or_code) -> Hinge:
    """The record of a hinge type, by name or code."""
    return HINGES[HINGE_TYPES[name_or_code] if isinstance(name_or_code, str) else int(name_or_code)]


def neutral_hinge_coordinates(hinge_type):
    """The hinge's coordinates at rest: zero angles and displacements, identity quaternions."""
    return np.array(HINGES[hinge_type].neutral, dtype=np.float64)


@njit(cache=True)
def hinge_transform(hinge_type, q, q0, axes, R_FM, p_FM, R1, R2):
    """Pose of the outboard frame M in the inboard frame F: ``R_FM`` and ``p_FM`` (written in place).

    ``q0`` is the hinge's first index in ``q``; ``axes`` its (2, 3) unit axes. ``R1``/``R2`` are 3x3
    scratch matrices; for the U-joint they return the two elementary rotations (``R2`` is needed by
    :func:`hinge_motion_subspace`).
    """
    p_FM[0] = 0.0
    p_FM[1] = 0.0
    p_FM[2] = 0.0
    if hinge_type == REVOLUTE:
        axis_angle_to_rotation(axes[0], q[q0], R_FM)
    elif hinge_type == UJOINT:
        axis_angle_to_rotation(axes[0], q[q0], R1)
        axis_angle_to_rotation(axes[1], q[q0 + 1], R2)
        for i in range(3):
            for j in range(3):
                R_FM[i, j] = R1[i, 0] * R2[0, j] + R1[i, 1] * R2[1, j] + R1[i, 2] * R2[2, j]
    elif hinge_type == SPHERICAL or hinge_type == FREE:
        quaternion_to_rotation(q[q0], q[q0 + 1], q[q0 + 2], q[q0 + 3], R_FM)
        if hinge_type == FREE:
            p_FM[0] = q[q0 + 4]
            p_FM[1] = q[q0 + 5]
            p_FM[2] = q[q0 + 6]
    else:  # locked, prismatic, translation
        for i in range(3):
            for j in range(3):
                R_FM[i, j] = 1.0 if i == j else 0.0
        if hinge_type == PRISMATIC:
            for i in range(3):
                p_FM[i] = axes[0, i] * q[q0]
        elif hinge_type == TRANSLATION:
            for i in range(3):
                p_FM[i] = q[q0 + i]


@njit(cache=True)
def hinge_motion_subspace(hinge_type, axes, R2, S_M):
    """Columns of the motion subspace in M (6 x nu, written into the leading columns of ``S_M``).

    ``R2`` is the U-joint's second elementary rotation from :func:`hinge_transform`.
    """
    for i in range(6):
        for j in range(6):
            S_M[i, j] = 0.0
    if hinge_type == REVOLUTE:
        for k in range(3):
            S_M[k, 0] = axes[0, k]
    elif hinge_type == PRISMATIC:
        for k in range(3):
            S_M[3 + k, 0] = axes[0, k]
    elif hinge_type == UJOINT:
        for k in range(3):
            # R2^T a1: the first axis seen from M
            S_M[k, 0] = R2[0, k] * axes[0, 0] + R2[1, k] * axes[0, 1] + R2[2, k] * axes[0, 2]
            S_M[k, 1] = axes[1, k]
    elif hinge_type == SPHERICAL:
        for k in range(3):
            S_M[k, k] = 1.0
    elif hinge_type == FREE:
        for k in range(6):
            S_M[k, k] = 1.0
    elif hinge_type == TRANSLATION:
        for k in range(3):
            S_M[3 + k, k] = 1.0


@njit(cache=True)
def hinge_coordinate_rates(hinge_type, q, q0, u, u0, qdot):
    """``q_dot = f(q, u)`` for one hinge: identity for angles/displacements, quaternion kinematics
    ``dq/dt = 1/2 q (x) [0, omega]`` (omega in the child frame) and ``dp/dt = R_FM v`` for the free hinge
    (``R_FM = 1`` for the translation)."""
    if hinge_type == REVOLUTE or hinge_type == PRISMATIC:
        qdot[q0] = u[u0]
    elif hinge_type == UJOINT:
        qdot[q0] = u[u0]
        qdot[q0 + 1] = u[u0 + 1]
    elif hinge_type == TRANSLATION:
        for k in range(3):
            qdot[q0 + k] = u[u0 + k]
    elif hinge_type == SPHERICAL or hinge_type == FREE:
        w, x, y, z = q[q0], q[q0 + 1], q[q0 + 2], q[q0 + 3]
        ox, oy, oz = u[u0], u[u0 + 1], u[u0 + 2]
        qdot[q0] = 0.5 * (-x * ox - y * oy - z * oz)
        qdot[q0 + 1] = 0.5 * (w * ox + y * oz - z * oy)
        qdot[q0 + 2] = 0.5 * (w * oy + z * ox - x * oz)
        qdot[q0 + 3] = 0.5 * (w * oz + x * oy - y * ox)
        if hinge_type == FREE:
            # rotate v by the (unit) quaternion: v + 2 w (e x v) + 2 e x (e x v), e = [x, y, z]
            vx, vy, vz = u[u0 + 3], u[u0 + 4], u[u0 + 5]
            tx = 2.0 * (y * vz - z * vy)
            ty = 2.0 * (z * vx - x * vz)
            tz = 2.0 * (x * vy - y * vx)
            qdot[q0 + 4] = vx + w * tx + (y * tz - z * ty)
            qdot[q0 + 5] = vy + w * ty + (z * tx - x * tz)
            qdot[q0 + 6] = vz + w * tz + (x * ty - y * tx)
