"""Attitude guidance: inertial, nadir and Sun pointing references and an eigenaxis slew profile.

Each model outputs a reference for an attitude controller (``MrpFeedback``'s reference inputs, the
convention of Basilisk's attitude reference message): ``reference_attitude`` (quaternion, reference
frame -> world), ``reference_angular_velocity`` and ``reference_angular_acceleration`` (world axes).

``InertialPointing``: a fixed target (``target``: quaternion, axis-angle, Euler angles or a body axis
pointed at a direction, ``shell.attitude_target``); zero rates.

``NadirPointing`` (attach to the spacecraft's node: it reads ``position`` (world), ``linear_velocity``
(node axes) and ``rotation``): the body axis ``boresight`` points at the central body (``-r``) and the
body axis ``secondary`` towards the velocity, in the orbit plane (the TRIAD construction, Markley and
Crassidis 2014 sec. 5.2.1). The frame turns about the orbit normal at ``omega = (r x v) / |r|^2``
with ``omega' = -2 (r . v) / |r|^2 omega``, exact for Keplerian motion (the orbit normal is fixed
and ``d(theta)/dt = h / r^2``).

``SunPointing``: ``boresight`` at the unit Sun direction (input ``sun_direction``, world axes, e.g.
the Sun ephemeris model or a constant), ``secondary`` towards the world direction
``secondary_direction`` (the first world axis of z, x farther than 10 deg from the Sun line
replaces it, so the frame is always defined). Zero reference rates: the Sun line moves about
2e-7 rad/s in Earth orbit, a tracking error of ``P 2e-7 / K`` (MRP) with MrpFeedback's gains.

``SunSafePointing``: Sun pointing from a Sun direction measured in node axes (``SunDirectionEstimate``
on the coarse sun sensors), with no attitude estimate (the law of Basilisk's ``sunSafePoint``). With the
unit ``boresight`` b and the measured direction s, the reference frame R is the node frame turned by the
shortest rotation taking b onto s (angle ``theta = acos(b . s)`` about ``e = b x s / |b x s|``); R's
boresight is on the Sun, so ``C_RB s = b`` and::

    q_BR = [cos(theta/2), -sin(theta/2) e]        (node -> R; MRP -tan(theta/4) e)

Output ``attitude`` is q_BR: wire it to ``MrpFeedback.attitude`` with the controller's reference inputs
unconnected (identity, zero rates) and a gyro on its ``angular_velocity``; MrpFeedback's
``-K sigma - P omega`` then turns b about e onto the Sun and damps the rate (the Sun line moves about
2e-7 rad/s in Earth orbit). Antiparallel (theta = pi) e is any axis perpendicular to b; with ``valid``
below 0.5 (eclipse, fewer than three lit cells) the output is the identity: rate damping only. Output
``pointing_error`` theta.

``EigenaxisSlew`` (sampled): holds the attitude measured at its first sample; at the first sample
at or after ``start_time`` with ``trigger`` >= 0.5 (unconnected: always) it captures the measured
attitude ``q_0`` and rotates about the fixed eigenaxis ``e`` of ``q_0^* (x) q_target`` by the angle
``theta_f`` with a bang-coast-bang profile of acceleration ``a`` and rate ``w`` (Wie, "Space Vehicle
Dynamics and Control", 2nd ed., sec. 7.3.4)::

    theta_f >= w^2 / a:  t_a = w / a, t_c = theta_f / w - w / a, peak rate w
    otherwise:           t_a = sqrt(theta_f / a), t_c = 0, peak rate a t_a           (bang-bang)
    theta(tau) = a tau^2 / 2                              0 <= tau < t_a
               = a t_a^2 / 2 + w_p (tau - t_a)            t_a <= tau < t_a + t_c
               = theta_f - a (T - tau)^2 / 2              t_a + t_c <= tau < T = 2 t_a + t_c
    q_R = q_0 (x) q(e, theta),   omega_RN = R(q_0) e theta',   omega_RN' = R(q_0) e theta''

Before the start the outputs are the reference on the ``hold_*`` inputs when one is connected (e.g. a
``SunPointing`` the slew takes over from; an all-zero ``hold_attitude``, the unconnected default, means
none) or else the attitude measured at the first sample, with zero rates. The outputs are functions of
time and of the hold inputs (feedthrough), exact at any instant a controller samples them. Discrete
states name the captured start and the profile's numbers.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from shell.attitude_target import parse_attitude_target
from shell.model import Declarations, InputPort, Model, ModelError, OutputPort, Parameter, State
from shell.attitude import (axis_angle_quaternion, cross, dot, quaternion_conjugate, quaternion_multiply,
                            quaternion_to_axis_angle, rotate, two_axis_frame_quaternion, unit)
from shell.ports import attitude_reference_outputs, node_inputs
from shell.registry import register_model

REFERENCE_OUTPUTS = attitude_reference_outputs()
TARGET = Parameter("target_attitude", "", (1.0, 0.0, 0.0, 0.0), (4,), (-1.0, 1.0),
                   "target quaternion, target -> world (give `target:` in any form of shell.attitude_target)")
AXES = (Parameter("boresight", "", (0.0, 0.0, 1.0), (3,), None, "body axis pointed at the target direction"),
        Parameter("secondary", "", (1.0, 0.0, 0.0), (3,), None, "body axis towards the secondary direction"))


class _TargetModel(Model):
    """Accepts ``target`` in any form of :mod:`shell.attitude_target` for ``target_attitude``."""

    def __init__(self, name: str, *, target=None, **kwargs):
        if target is not None:
            if "target_attitude" in kwargs:
                raise ModelError(f"model {name}: parameter target: give target or target_attitude, not both")
            kwargs["target_attitude"] = parse_attitude_target(target, f"model {name}: parameter target").tolist()
        super().__init__(name, **kwargs)

    def configure(self):
        q = self.parameter("target_attitude")
        if abs(float(np.linalg.norm(q)) - 1.0) > 1e-6:
            raise ModelError(f"model {self.path}: parameter target_attitude: expected a unit quaternion, given "
                             f"norm {float(np.linalg.norm(q)):.9g}")
        q /= np.linalg.norm(q)


def _check_axes(model: Model) -> None:
    b, s = (model.parameter(n) for n in ("boresight", "secondary"))
    for name, v in (("boresight", b), ("secondary", s)):
        if np.linalg.norm(v) < 1e-12:
            raise ModelError(f"model {model.path}: parameter {name}: expected a nonzero vector, given {v.tolist()}")
    if np.linalg.norm(np.cross(b, s)) < 1e-6 * np.linalg.norm(b) * np.linalg.norm(s):
        raise ModelError(f"model {model.path}: parameter secondary: must not be parallel to boresight "
                         f"{b.tolist()}, given {s.tolist()}")


# ------------------------------------------------------------------------------------------------
INERTIAL = Declarations(parameters=(TARGET,), outputs=REFERENCE_OUTPUTS)
P_INERTIAL, Y_REF = INERTIAL.P, INERTIAL.Y


@njit(cache=True)
def _inertial_reference(t, x, z, u, p, y):
    for i in range(4):
        y[Y_REF.reference_attitude + i] = p[P_INERTIAL.target_attitude + i]
    for i in range(3):
        y[Y_REF.reference_angular_velocity + i] = 0.0
        y[Y_REF.reference_angular_acceleration + i] = 0.0


@register_model
class InertialPointing(_TargetModel):
    """Fixed inertial attitude reference; see the module docstring."""

    summary = "inertial pointing reference: target as quaternion, axis-angle, Euler angles or pointing"
    declarations = INERTIAL
    state_outputs = staticmethod(_inertial_reference)


# ------------------------------------------------------------------------------------------------
NADIR_INPUTS = node_inputs("position", "linear_velocity", "rotation", feedthrough=True,
                           position="spacecraft position from the central body, world axes",
                           linear_velocity="inertial velocity, node axes", rotation="rotation node -> world")
NADIR_OUTPUTS = attitude_reference_outputs(feedthrough=True)
NADIR = Declarations(parameters=AXES, inputs=NADIR_INPUTS, outputs=NADIR_OUTPUTS)
P_AXES, U_NADIR = NADIR.P, NADIR.U


@njit(cache=True)
def _nadir_reference(t, x, z, u, p, y):
    r = (u[U_NADIR.position], u[U_NADIR.position + 1], u[U_NADIR.position + 2])
    R, vb = U_NADIR.rotation, U_NADIR.linear_velocity
    v = (u[R] * u[vb] + u[R + 1] * u[vb + 1] + u[R + 2] * u[vb + 2],
         u[R + 3] * u[vb] + u[R + 4] * u[vb + 1] + u[R + 5] * u[vb + 2],
         u[R + 6] * u[vb] + u[R + 7] * u[vb + 1] + u[R + 8] * u[vb + 2])
    b = (p[P_AXES.boresight], p[P_AXES.boresight + 1], p[P_AXES.boresight + 2])
    s = (p[P_AXES.secondary], p[P_AXES.secondary + 1], p[P_AXES.secondary + 2])
    q = two_axis_frame_quaternion(b, s, (-r[0], -r[1], -r[2]), v)
    r2 = dot(r, r)
    h = cross(r, v)
    rate = -2.0 * dot(r, v) / r2
    for i in range(4):
        y[Y_REF.reference_attitude + i] = q[i]
    for i in range(3):
        y[Y_REF.reference_angular_velocity + i] = h[i] / r2
        y[Y_REF.reference_angular_acceleration + i] = rate * h[i] / r2


@register_model
class NadirPointing(Model):
    """Nadir-pointing reference from the node's orbit state; see the module docstring."""

    summary = "nadir pointing reference (attach to the spacecraft node): boresight at -r, secondary along v"
    declarations = NADIR
    feedthrough_outputs = staticmethod(_nadir_reference)

    def configure(self):
        _check_axes(self)


# ------------------------------------------------------------------------------------------------
SUN_PARAMETERS = AXES + (Parameter("secondary_direction", "", (0.0, 0.0, 1.0), (3,), None,
                                   "world direction the secondary axis turns towards"),)
SUN_INPUTS = (InputPort("sun_direction", "", (3,), "unit vector to the Sun, world axes", feedthrough=True),)
SUN = Declarations(parameters=SUN_PARAMETERS, inputs=SUN_INPUTS, outputs=NADIR_OUTPUTS)
P_SUN, U_SUN = SUN.P, SUN.U
#: the secondary direction is replaced when within 10 deg of the Sun line
_SIN_MIN_SEPARATION = np.sin(np.radians(10.0))


@njit(cache=True)
def _sun_reference(t, x, z, u, p, y):
    sun = unit((u[U_SUN.sun_direction], u[U_SUN.sun_direction + 1], u[U_SUN.sun_direction + 2]))
    b = (p[P_SUN.boresight], p[P_SUN.boresight + 1], p[P_SUN.boresight + 2])
    s = (p[P_SUN.secondary], p[P_SUN.secondary + 1], p[P_SUN.secondary + 2])
    n2 = unit((p[P_SUN.secondary_direction], p[P_SUN.secondary_direction + 1], p[P_SUN.secondary_direction + 2]))
    c = cross(sun, n2)
    if np.sqrt(dot(c, c)) < _SIN_MIN_SEPARATION:
        n2 = (0.0, 0.0, 1.0)
        c = cross(sun, n2)
        if np.sqrt(dot(c, c)) < _SIN_MIN_SEPARATION:
            n2 = (1.0, 0.0, 0.0)
    q = two_axis_frame_quaternion(b, s, sun, n2)
    for i in range(4):
        y[Y_REF.reference_attitude + i] = q[i]
    for i in range(3):
        y[Y_REF.reference_angular_velocity + i] = 0.0
        y[Y_REF.reference_angular_acceleration + i] = 0.0


@register_model
class SunPointing(Model):
    """Sun-pointing reference from a Sun direction input; see the module docstring."""

    summary = "Sun pointing reference: boresight at sun_direction (unit, world), secondary towards a direction"
    declarations = SUN
    feedthrough_outputs = staticmethod(_sun_reference)

    def configure(self):
        _check_axes(self)
        if np.linalg.norm(self.parameter("secondary_direction")) < 1e-12:
            raise ModelError(f"model {self.path}: parameter secondary_direction: expected a nonzero vector")


# ------------------------------------------------------------------------------------------------
SLEW_PARAMETERS = (
    TARGET,
    Parameter("start_time", "s", 0.0, (), (0.0, None), "earliest start of the slew"),
    Parameter("max_rate", "rad/s", None, (), (1e-12, None), "rate limit w (coast rate)"),
    Parameter("max_acceleration", "rad/s^2", None, (), (1e-12, None), "acceleration limit a"),
)
SLEW_INPUTS = (
    InputPort("attitude", "", (4,), "measured quaternion, node -> world (captured at the start)"),
    InputPort("trigger", "", (), "the slew starts at the first sample after start_time with trigger >= 0.5",
              required=False, default=1.0),
    InputPort("hold_attitude", "", (4,), "reference passed through before the start (unconnected, zero: hold "
              "the attitude measured at the first sample)", feedthrough=True, required=False),
    InputPort("hold_angular_velocity", "rad/s", (3,), "its angular velocity, world axes", feedthrough=True,
              required=False),
    InputPort("hold_angular_acceleration", "rad/s^2", (3,), "its angular acceleration, world axes",
              feedthrough=True, required=False),
)
SLEW_OUTPUTS = attitude_reference_outputs(feedthrough=True) + (
    OutputPort("slew_angle", "rad", (), "profile angle theta(t) (0 before the start)", feedthrough=True),
    OutputPort("complete", "", (), "1 once the profile has ended, else 0", feedthrough=True),
)
SLEW_DISCRETE = (
    State("start_attitude", "", (4,), (1.0, 0.0, 0.0, 0.0), "q_0: held attitude, then the slew's start"),
    State("axis", "", (3,), (1.0, 0.0, 0.0), "eigenaxis e, start-frame (= target-frame) axes"),
    State("angle", "rad", (), 0.0, "slew angle theta_f"),
    State("start", "s", (), -1.0, "time the slew started (-1: not yet)"),
    State("accel_time", "s", (), 0.0, "t_a"),
    State("coast_time", "s", (), 0.0, "t_c"),
    State("peak_rate", "rad/s", (), 0.0, "coast rate"),
    State("held", "", (), 0.0, "1 once the attitude to hold has been captured"),
)
SLEW = Declarations(parameters=SLEW_PARAMETERS, inputs=SLEW_INPUTS, outputs=SLEW_OUTPUTS, discrete=SLEW_DISCRETE)
P_SLEW, U_SLEW, Y_SLEW, Z_SLEW = SLEW.P, SLEW.U, SLEW.Y, SLEW.Z


@njit(cache=True)
def bang_coast_bang(tau, angle, accel, accel_time, coast_time, peak_rate):
    """(theta, theta', theta'') of the profile at tau after its start (module docstring)."""
    total = 2.0 * accel_time + coast_time
    if tau <= 0.0:
        return 0.0, 0.0, 0.0
    if tau < accel_time:
        return 0.5 * accel * tau * tau, accel * tau, accel
    if tau < accel_time + coast_time:
        return 0.5 * accel * accel_time * accel_time + peak_rate * (tau - accel_time), peak_rate, 0.0
    if tau < total:
        s = total - tau
        return angle - 0.5 * accel * s * s, accel * s, -accel
    return angle, 0.0, 0.0


@njit(cache=True)
def _slew_outputs(t, x, z, u, p, y):
    Z = Z_SLEW
    q0 = (z[Z.start_attitude], z[Z.start_attitude + 1], z[Z.start_attitude + 2], z[Z.start_attitude + 3])
    e = (z[Z.axis], z[Z.axis + 1], z[Z.axis + 2])
    theta, rate, accel = 0.0, 0.0, 0.0
    done = 0.0
    if z[Z.start] >= 0.0:
        theta, rate, accel = bang_coast_bang(t - z[Z.start], z[Z.angle], p[P_SLEW.max_acceleration],
                                             z[Z.accel_time], z[Z.coast_time], z[Z.peak_rate])
        if t - z[Z.start] >= 2.0 * z[Z.accel_time] + z[Z.coast_time]:
            done = 1.0
    h = U_SLEW.hold_attitude
    if z[Z.start] < 0.0 and (u[h] * u[h] + u[h + 1] * u[h + 1] + u[h + 2] * u[h + 2] + u[h + 3] * u[h + 3]) > 0.25:
        for i in range(4):
            y[Y_SLEW.reference_attitude + i] = u[h + i]
        for i in range(3):
            y[Y_SLEW.reference_angular_velocity + i] = u[U_SLEW.hold_angular_velocity + i]
            y[Y_SLEW.reference_angular_acceleration + i] = u[U_SLEW.hold_angular_acceleration + i]
        y[Y_SLEW.slew_angle] = 0.0
        y[Y_SLEW.complete] = 0.0
        return
    q = quaternion_multiply(q0, axis_angle_quaternion(e, theta))
    e_world = rotate(q0, e)
    for i in range(4):
        y[Y_SLEW.reference_attitude + i] = q[i]
    for i in range(3):
        y[Y_SLEW.reference_angular_velocity + i] = e_world[i] * rate
        y[Y_SLEW.reference_angular_acceleration + i] = e_world[i] * accel
    y[Y_SLEW.slew_angle] = theta
    y[Y_SLEW.complete] = done


@njit(cache=True)
def _slew_update(t, x, z, u, p):
    Z = Z_SLEW
    a = U_SLEW.attitude
    if z[Z.start] >= 0.0:
        return
    starting = t >= p[P_SLEW.start_time] and u[U_SLEW.trigger] >= 0.5
    if z[Z.held] > 0.5 and not starting:
        return
    q0 = (u[a], u[a + 1], u[a + 2], u[a + 3])
    for i in range(4):
        z[Z.start_attitude + i] = q0[i]
    z[Z.held] = 1.0
    if not starting:
        return
    tq = P_SLEW.target_attitude
    relative = quaternion_multiply(quaternion_conjugate(q0), (p[tq], p[tq + 1], p[tq + 2], p[tq + 3]))
    e, angle = quaternion_to_axis_angle(relative)
    w, acc = p[P_SLEW.max_rate], p[P_SLEW.max_acceleration]
    if angle >= w * w / acc:
        t_a, t_c, peak = w / acc, angle / w - w / acc, w
    else:
        t_a = np.sqrt(angle / acc)
        t_c, peak = 0.0, acc * t_a
    for i in range(3):
        z[Z.axis + i] = e[i]
    z[Z.angle] = angle
    z[Z.accel_time] = t_a
    z[Z.coast_time] = t_c
    z[Z.peak_rate] = peak
    z[Z.start] = t


@register_model
class EigenaxisSlew(_TargetModel):
    """Eigenaxis slew with rate and acceleration limits (bang-coast-bang); see the module docstring."""

    summary = "eigenaxis slew reference, bang-coast-bang with rate and acceleration limits (target in any form)"
    declarations = SLEW
    default_period = "0.1 s"
    feedthrough_outputs = staticmethod(_slew_outputs)
    update = staticmethod(_slew_update)


def slew_duration(angle: float, max_rate: float, max_acceleration: float) -> float:
    """Duration of the bang-coast-bang profile (for users and tests)."""
    if angle >= max_rate**2 / max_acceleration:
        return angle / max_rate + max_rate / max_acceleration
    return 2.0 * np.sqrt(angle / max_acceleration)


# ------------------------------------------------------------------------------------------------
SAFE_PARAMETERS = (Parameter("boresight", "", (0.0, 0.0, 1.0), (3,), None, "body axis pointed at the Sun"),)
SAFE_INPUTS = (
    InputPort("sun_direction", "", (3,), "measured Sun direction, node axes (SunDirectionEstimate)", feedthrough=True),
    InputPort("valid", "", (), "the measurement is usable (>= 0.5)", feedthrough=True, required=False, default=1.0),
)
SAFE_OUTPUTS = (
    OutputPort("attitude", "", (4,), "q_BR, node -> Sun-pointing frame (MrpFeedback.attitude)", feedthrough=True),
    OutputPort("pointing_error", "rad", (), "angle between the boresight and the measured Sun direction",
               feedthrough=True),
)
SAFE = Declarations(parameters=SAFE_PARAMETERS, inputs=SAFE_INPUTS, outputs=SAFE_OUTPUTS)
P_SAFE, U_SAFE, Y_SAFE = SAFE.P, SAFE.U, SAFE.Y


@njit(cache=True)
def _sun_safe_attitude(t, x, z, u, p, y):
    b = unit((p[P_SAFE.boresight], p[P_SAFE.boresight + 1], p[P_SAFE.boresight + 2]))
    d = (u[U_SAFE.sun_direction], u[U_SAFE.sun_direction + 1], u[U_SAFE.sun_direction + 2])
    q = (1.0, 0.0, 0.0, 0.0)
    theta = 0.0
    if u[U_SAFE.valid] >= 0.5 and dot(d, d) > 0.0:
        s = unit(d)
        c = cross(b, s)
        sine = np.sqrt(dot(c, c))
        theta = np.arctan2(sine, dot(b, s))
        if sine > 1e-12:
            e = (c[0] / sine, c[1] / sine, c[2] / sine)
        else:  # parallel (theta = 0: no turn) or antiparallel: any axis perpendicular to b
            h = (1.0, 0.0, 0.0) if abs(b[0]) < 0.9 else (0.0, 1.0, 0.0)
            e = unit(cross(b, h))
        q = axis_angle_quaternion(e, -theta)
    for i in range(4):
        y[Y_SAFE.attitude + i] = q[i]
    y[Y_SAFE.pointing_error] = theta


@register_model
class SunSafePointing(Model):
    """Sun pointing from a measured Sun direction (node axes), no attitude estimate; see the module docstring."""

    summary = "Sun-safe pointing from a measured Sun direction (node axes): q_BR for MrpFeedback, no attitude estimate"
    declarations = SAFE
    feedthrough_outputs = staticmethod(_sun_safe_attitude)

    def configure(self):
        if np.linalg.norm(self.parameter("boresight")) < 1e-12:
            raise ModelError(f"model {self.path}: parameter boresight: expected a nonzero vector")
