"""Star tracker: attitude of the sensor frame with noise per axis, misalignment, rate, latency,
Sun / Earth / Moon exclusion angles and random dropouts.

Attach to a node (``attach: {node: ...}``: rotation node -> world, position from the Earth's center) and
wire the Sun and, optionally, the Moon (``SunMoonEphemeris.sun_position`` / ``moon_position``); an
unconnected Sun or Moon input (zero vector) switches that exclusion off. The sensor frame is the node
frame rotated by ``mounting`` (sensor -> node); the boresight is the sensor z axis. Each sample
(Markley & Crassidis, "Fundamentals of Spacecraft Attitude Determination and Control", sec. 6.2 and 7.3:
the measured attitude as the true one times a small error rotation)::

    q_true = q_node (x) q_mount         sensor -> world, q_node from the node's rotation (Shepperd)
    q_meas = q_true (x) exp( (delta + diag(sigma) w) / 2 )             w ~ N(0, I), sensor axes

with ``delta`` a fixed misalignment (rotation vector, sensor axes), ``sigma`` the noise per axis (two
cross-boresight, one about the boresight, the larger one for a real tracker) and ``exp`` the exact
rotation-vector quaternion. The measurement is invalid (``valid = 0``, the attitude output holds the
previous one) when the boresight is within ``sun_exclusion`` of the Sun, within ``moon_exclusion`` of the
Moon, within ``earth_exclusion`` of the Earth's limb (angle to the Earth's center below
``asin(R / |r|) + earth_exclusion``), or when a uniform draw falls below ``dropout_probability``. Outputs
appear ``latency`` (a whole number of sample periods) after their sample. Outputs (keep the names):
``attitude`` (quaternion [w, x, y, z], sensor -> world, the hemisphere of w >= 0) and ``valid`` (1 / 0).

Layout: the output shift register ``records`` is the last discrete state, ``latency / period + 1`` records
of ``RECORD_PARTS``, the newest first, the oldest (what the outputs show) last.
"""

from __future__ import annotations

from dataclasses import replace
from math import erfc

import numpy as np
from numba import njit

from shell.attitude import matrix_at_to_quaternion, quaternion_multiply, rotation_vector_quaternion
from shell.model import (Declarations, InputPort, Layout, Model, ModelError, OutputPort, Parameter, State,
                         named_offsets, parse_period)
from shell.models.gravity import EARTH_RADIUS
from shell.ports import node_inputs
from shell.registry import register_model

PARAMETERS = (
    Parameter("mounting", "", (1.0, 0.0, 0.0, 0.0), (4,), (-1.0, 1.0), "quaternion sensor -> node [w, x, y, z]"),
    Parameter("noise", "rad", (0.0, 0.0, 0.0), (3,), (0.0, None),
              "1-sigma error per sensor axis (x, y cross-boresight, z about the boresight)"),
    Parameter("misalignment", "rad", (0.0, 0.0, 0.0), (3,), (-0.1, 0.1), "fixed error rotation vector, sensor axes"),
    Parameter("sun_exclusion", "rad", 0.0, (), (0.0, np.pi), "half-angle of the Sun exclusion cone (0: none)"),
    Parameter("earth_exclusion", "rad", 0.0, (), (-np.pi / 2, np.pi), "margin above the Earth's limb (0: the limb)"),
    Parameter("moon_exclusion", "rad", 0.0, (), (0.0, np.pi), "half-angle of the Moon exclusion cone (0: none)"),
    Parameter("dropout_probability", "", 0.0, (), (0.0, 1.0), "probability that a sample is lost"),
    Parameter("body_radius", "m", EARTH_RADIUS, (), (0.0, None), "radius of the central body (Earth exclusion)"),
    Parameter("latency", "s", 0.0, (), (0.0, None), "output latency, a whole number of sample periods"),
)
INPUTS = (
    *node_inputs("rotation", "position",
                 rotation="rotation node -> world (an input named attitude would clash with the output)",
                 position="node position from the central body, world axes"),
    InputPort("sun_position", "m", (3,), "central body -> Sun, world axes (zero: no Sun exclusion)", required=False),
    InputPort("moon_position", "m", (3,), "central body -> Moon, world axes (zero: no Moon exclusion)",
              required=False),
)
OUTPUTS = (
    OutputPort("attitude", "", (4,), "measured quaternion sensor -> world [w, x, y, z] (held)"),
    OutputPort("valid", "", (), "1: valid measurement, 0: excluded or dropped (attitude held)"),
)
RECORD_PARTS = (State("attitude", "", (4,)), State("valid", "", ()))
RECORD_SIZE = Layout.of(RECORD_PARTS).size
DISCRETE = (State("last_attitude", "", (4,), (1.0, 0.0, 0.0, 0.0), "last valid measurement"),)
RECORDS = State("records", "", (RECORD_SIZE,), None, "output shift register (latency)")
NOISE_PARTS = (State("attitude", "", (3,)), State("dropout", "", ()))
TRACKER = Declarations(parameters=PARAMETERS, inputs=INPUTS, outputs=OUTPUTS, discrete=DISCRETE + (RECORDS,),
                       sized=("records",))
P, U, Y, Z = TRACKER.P, TRACKER.U, TRACKER.Y, TRACKER.Z
R, N = named_offsets(RECORD_PARTS), named_offsets(NOISE_PARTS)


@njit(cache=True)
def _angle_below(b0, b1, b2, d0, d1, d2, limit):
    """The angle between unit b and d (not normalized) is below limit; False for a zero d."""
    dn = np.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
    if dn == 0.0:
        return False
    c = (b0 * d0 + b1 * d1 + b2 * d2) / dn
    return np.arccos(max(-1.0, min(1.0, c))) < limit


@njit(cache=True)
def _body_excluded(b0, b1, b2, u, r, body, limit):
    """The boresight is within limit of the body at u[body:body + 3] seen from u[r:r + 3]; False for a
    zero limit or an unconnected (zero) body position."""
    if limit <= 0.0 or (u[body] == 0.0 and u[body + 1] == 0.0 and u[body + 2] == 0.0):
        return False
    return _angle_below(b0, b1, b2, u[body] - u[r], u[body + 1] - u[r + 1], u[body + 2] - u[r + 2], limit)


@njit(cache=True)
def _tracker_outputs(t, x, z, u, p, y):
    oldest = z.shape[0] - RECORD_SIZE
    for i in range(4):
        y[Y.attitude + i] = z[oldest + R.attitude + i]
    y[Y.valid] = z[oldest + R.valid]


@njit(cache=True)
def _tracker_sample(t, x, z, u, p, noise):
    r0 = Z.records
    for k in range((z.shape[0] - r0) // RECORD_SIZE - 1, 0, -1):
        for m in range(RECORD_SIZE):
            z[r0 + k * RECORD_SIZE + m] = z[r0 + (k - 1) * RECORD_SIZE + m]
    mnt = P.mounting
    qn = matrix_at_to_quaternion(u, U.rotation)
    qt = quaternion_multiply(qn, (p[mnt], p[mnt + 1], p[mnt + 2], p[mnt + 3]))
    e = rotation_vector_quaternion(p[P.misalignment] + p[P.noise] * noise[N.attitude],
                                   p[P.misalignment + 1] + p[P.noise + 1] * noise[N.attitude + 1],
                                   p[P.misalignment + 2] + p[P.noise + 2] * noise[N.attitude + 2])
    qm = quaternion_multiply(qt, e)
    sign = 1.0 if qm[0] >= 0.0 else -1.0
    # boresight (sensor z) in world axes: third column of the rotation of the true sensor attitude
    w, qx, qy, qz = qt
    b0, b1, b2 = 2.0 * (qx * qz + w * qy), 2.0 * (qy * qz - w * qx), 1.0 - 2.0 * (qx * qx + qy * qy)
    r = U.position
    rn = np.sqrt(u[r] ** 2 + u[r + 1] ** 2 + u[r + 2] ** 2)
    valid = not (_body_excluded(b0, b1, b2, u, r, U.sun_position, p[P.sun_exclusion])
                 or _body_excluded(b0, b1, b2, u, r, U.moon_position, p[P.moon_exclusion]))
    if rn > p[P.body_radius]:
        limb = np.arcsin(p[P.body_radius] / rn) + p[P.earth_exclusion]
        if _angle_below(b0, b1, b2, -u[r], -u[r + 1], -u[r + 2], limb):
            valid = False
    uniform = 0.5 * erfc(-noise[N.dropout] / np.sqrt(2.0))
    if uniform < p[P.dropout_probability]:
        valid = False
    if valid:
        for i in range(4):
            z[Z.last_attitude + i] = sign * qm[i]
    for i in range(4):
        z[r0 + R.attitude + i] = z[Z.last_attitude + i]
    z[r0 + R.valid] = 1.0 if valid else 0.0


@register_model
class StarTracker(Model):
    """Star tracker: noisy misaligned sensor attitude, exclusion angles, dropouts, latency."""

    summary = "star tracker at a node: attitude (sensor -> world) and valid; noise, misalignment, exclusions, dropouts"
    declarations = TRACKER
    noise_size = Layout.of(NOISE_PARTS).size
    default_period = "0.2 s"
    state_outputs = staticmethod(_tracker_outputs)
    update = staticmethod(_tracker_sample)

    def __init__(self, name: str, *, period=None, offset=0.0, **parameter_values):
        self._given_period = period
        super().__init__(name, period=period, offset=offset, **parameter_values)

    def configure(self):
        self.require_unit_norm("mounting")
        period = parse_period(self._given_period if self._given_period is not None else self.default_period,
                              f"model {self.path}: period")
        latency = float(self.parameter("latency"))
        samples = round(latency / float(period))
        if abs(samples * float(period) - latency) > 1e-9 * max(1.0, latency):
            raise ModelError(f"model {self.path}: parameter latency: expected a whole number of sample periods "
                             f"({float(period):g} s), given {latency:g} s")
        record = np.zeros(RECORD_SIZE)
        record[R.attitude] = 1.0  # identity quaternion, invalid, until the first sample
        initial = np.tile(record, samples + 1)
        self.discrete_states = DISCRETE + (replace(RECORDS, shape=((samples + 1) * RECORD_SIZE,), initial=initial),)
