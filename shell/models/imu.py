"""Strapdown IMU (rate gyro + accelerometer triad) at an engine node, with the full error model.

Mounted at a node (``attach: {node: ...}``), the IMU senses that node's inertial angular velocity and
classical acceleration, which include elastic motion on flexible bodies and the lever-arm terms
``alpha x r + omega x (omega x r)`` of its offset from the body's center of mass (the engine computes
them at the node). Specific force is ``f = a - R^T g`` with ``g`` the uniform field in world axes
(parameter ``gravity``, the field the engine applies) plus an optional ``gravitational_acceleration``
input in node axes (from a central-body gravity model, whose acceleration the engine sees as a force).

Each sample period T the true increments ``dtheta = int omega dt`` and ``dv = int f dt`` come from two
continuous integrals (so coning and sculling inside the sample are integrated, not sampled), then each
channel (gyro: angle, accelerometer: velocity) applies, per axis, the IEEE Std 952-1997 error model
(TM-2020-5008164 App. D.1 IMU noise terms; SSSIM sensor menu)::

    d_meas = (I + diag(s)) (I + M) d_true                scale factor s (ppm), misalignment M (rad)
           + (b0 + b_rw,k + b_gm,k + R t_mid) T           turn-on bias, rate random walk, bias
                                                         instability, rate ramp
           + N sqrt(T) w_k                               angle (velocity) random walk
           + Q (v_k - v_{k-1})                           angle (velocity) white noise
    b_rw,k = b_rw,k-1 + K sqrt(T) w'_k                   rate (acceleration) random walk
    b_gm,k = phi b_gm,k-1 + sigma sqrt(1 - phi^2) w''_k  first-order Gauss-Markov, phi = exp(-T/Tc)

Allan-deviation signatures (IEEE Std 952 App. C): N/sqrt(tau), K sqrt(tau/3), R tau/sqrt(2),
sqrt(3) Q/tau. Bias instability B is modeled as a Gauss-Markov process with correlation time Tc whose
Allan-deviation peak (0.6199 sigma at tau = 1.89 Tc) equals the flicker floor 0.664 B of the datasheet
value, i.e. sigma = 0.664 B / 0.6199. The measured increment is then quantized by an integer counter
of resolution ``lsb`` with the remainder carried to the next sample (no information is lost, the
quantization noise is sqrt(3) (lsb/sqrt(12)) / tau in Allan deviation). Outputs are held for
``latency`` (a whole number of sample periods) before they appear.

Datasheet units work directly: ``"0.15 deg/hour**0.5"`` (ARW), ``"0.5 deg/hour"`` (bias instability),
``"100 ppm"``, ``"20 arcsec"``, ``"0.05 m/s/hour**0.5"`` (VRW), ``"50e-6 g_0"``.

Array layouts are named throughout: the module-level declarations give ``P``, ``U``, ``Y``, ``X``, ``Z``;
each channel's parameters are gathered by name (``GYRO``, ``ACCEL``: a ``ChannelParameters`` named tuple
of offsets into p); the parts of the per-channel error states and of the 24 standard normals drawn
each sample (``noise_size``; gyro channel first, in the order of ``NOISE_PARTS``, the order the draws
have always had) and of the last sampled integrals are named offsets of their ``*_PARTS`` declarations,
fixed whatever the order of the model's declarations. The output shift register ``records``
is the last discrete state (its length depends on the latency): records of ``RECORD_PARTS`` (the
outputs of one sample), the newest first, the oldest (what the outputs show) last.
"""

from __future__ import annotations

from collections import namedtuple
from dataclasses import replace

import numpy as np
from numba import njit

from shell.model import (Declarations, InputPort, Layout, Model, ModelError, OutputPort, Parameter, State,
                         named_offsets, parse_period)
from shell.ports import node_inputs
from shell.registry import register_model

#: ratio of the Gauss-Markov sigma to the datasheet bias instability B: 0.664 B (the 1/f Allan floor,
#: sqrt(2 ln 2 / pi) B) divided by the peak of the Gauss-Markov Allan deviation in units of sigma
FLICKER_FLOOR = float(np.sqrt(2.0 * np.log(2.0) / np.pi))


def gauss_markov_allan_variance(tau, sigma, correlation_time):
    """Allan variance of a continuous first-order Gauss-Markov rate (IEEE Std 952 App. C)."""
    x = np.asarray(tau, float) / correlation_time
    return sigma**2 * (2.0 * x - 3.0 + 4.0 * np.exp(-x) - np.exp(-2.0 * x)) / x**2


def _gauss_markov_peak() -> float:
    x = np.linspace(0.5, 5.0, 200001)
    return float(np.sqrt(gauss_markov_allan_variance(x, 1.0, 1.0).max()))


GAUSS_MARKOV_PEAK = _gauss_markov_peak()  # 0.6199 sigma

def _channel_parameters(prefix, quantity, rate_unit, increment_unit):
    """Parameter declarations of one channel; ``rate_unit`` is the sensed quantity's unit."""
    q = quantity
    return (
        Parameter(f"{prefix}_random_walk", f"{rate_unit}*s**0.5", 0.0, (), (0.0, None),
                  f"{q} random walk N (white noise on the {q}; datasheet e.g. deg/hour**0.5)"),
        Parameter(f"{prefix}_bias_instability", rate_unit, 0.0, (), (0.0, None),
                  "bias instability B (Allan floor 0.664 B; datasheet e.g. deg/hour)"),
        Parameter(f"{prefix}_bias_correlation_time", "s", 100.0, (), (1e-9, None),
                  "correlation time of the Gauss-Markov bias-instability process"),
        Parameter(f"{prefix}_bias_random_walk", f"{rate_unit}/s**0.5", 0.0, (), (0.0, None),
                  "rate (acceleration) random walk K"),
        Parameter(f"{prefix}_ramp", f"{rate_unit}/s", 0.0, (), None, "rate (acceleration) ramp R"),
        Parameter(f"{prefix}_white_noise", increment_unit, 0.0, (), (0.0, None),
                  f"white noise on the integrated {q} (angle / velocity white noise Q)"),
        Parameter(f"{prefix}_lsb", increment_unit, 0.0, (), (0.0, None),
                  "resolution of the integer increment counter (0: no quantization)"),
        Parameter(f"{prefix}_bias", rate_unit, (0.0, 0.0, 0.0), (3,), None, "turn-on bias per axis"),
        Parameter(f"{prefix}_scale_factor", "", (0.0, 0.0, 0.0), (3,), (-0.5, 0.5),
                  "scale-factor error per axis (datasheet ppm)"),
        Parameter(f"{prefix}_misalignment", "rad", np.zeros((3, 3)), (3, 3), (-0.1, 0.1),
                  "small-angle misalignment / non-orthogonality: sensed_i += M_ij true_j (diagonal zero)"),
    )


PARAMETERS = (
    *_channel_parameters("gyro", "angle", "rad/s", "rad"),
    *_channel_parameters("accel", "velocity", "m/s^2", "m/s"),
    Parameter("gravity", "m/s^2", (0.0, 0.0, 0.0), (3,), None,
              "uniform gravitational field, world axes (the engine's multibody gravity)"),
    Parameter("latency", "s", 0.0, (), (0.0, None), "output latency, a whole number of sample periods"),
)
INPUTS = (
    *node_inputs("angular_velocity", "linear_acceleration", "rotation",
                 angular_velocity="inertial angular velocity of the node, node axes",
                 linear_acceleration="classical acceleration of the node, node axes"),
    InputPort("gravitational_acceleration", "m/s^2", (3,), "gravity not in the engine, node axes",
              required=False),
)
OUTPUTS = (
    OutputPort("angular_rate", "rad/s", (3,), "measured angular rate (delta angle / period)"),
    OutputPort("specific_force", "m/s^2", (3,), "measured specific force (delta velocity / period)"),
    OutputPort("delta_angle", "rad", (3,), "quantized delta angle of the last sample"),
    OutputPort("delta_velocity", "m/s", (3,), "quantized delta velocity of the last sample"),
    OutputPort("delta_angle_counts", "", (3,), "integer delta-angle counts (0 without lsb)"),
    OutputPort("delta_velocity_counts", "", (3,), "integer delta-velocity counts (0 without lsb)"),
)
CONTINUOUS = (State("angle_integral", "rad", (3,), None, "integral of the true angular velocity"),
              State("velocity_integral", "m/s", (3,), None, "integral of the true specific force"))
#: inside the discrete state last_integrals
LAST_INTEGRAL_PARTS = (State("angle", "rad", (3,)), State("velocity", "m/s", (3,)))
#: per channel, inside the discrete state error_states (gyro channel first)
CHANNEL_STATE_PARTS = (State("bias_random_walk", "", (3,), None, "random-walk bias"),
                       State("bias_gauss_markov", "", (3,), None, "Gauss-Markov bias"),
                       State("white_noise", "", (3,), None, "previous white noise (its difference is the output)"),
                       State("quantizer_carry", "", (3,), None, "remainder carried by the increment counter"))
#: per channel, the standard normals of one sample, in draw order (gyro channel first)
NOISE_PARTS = (State("random_walk", "", (3,)), State("bias_random_walk", "", (3,)),
               State("gauss_markov", "", (3,)), State("white", "", (3,)))
CHANNEL_STATE_SIZE, CHANNEL_NOISE_SIZE = Layout.of(CHANNEL_STATE_PARTS).size, Layout.of(NOISE_PARTS).size
#: one record of the output shift register: the outputs of one sample
RECORD_PARTS = (State("angular_rate", "rad/s", (3,)), State("specific_force", "m/s^2", (3,)),
                State("delta_angle", "rad", (3,)), State("delta_velocity", "m/s", (3,)),
                State("delta_angle_counts", "", (3,)), State("delta_velocity_counts", "", (3,)))
RECORD_SIZE = Layout.of(RECORD_PARTS).size
DISCRETE = (
    State("sample_period", "s", (), None, "the sample period (from the rate)"),
    State("last_integrals", "", (Layout.of(LAST_INTEGRAL_PARTS).size,), None,
          "angle and velocity integrals at the last sample"),
    State("error_states", "", (2 * CHANNEL_STATE_SIZE,), None,
          "per channel: random-walk bias, Gauss-Markov bias, last white noise, quantizer carry"),
)
#: the output shift register, appended after DISCRETE with (latency samples + 1) records
RECORDS = State("records", "", (RECORD_SIZE,), None, "output shift register (latency)")

IMU = Declarations(parameters=PARAMETERS, inputs=INPUTS, outputs=OUTPUTS, continuous=CONTINUOUS,
                   discrete=DISCRETE + (RECORDS,), sized=("records",))
P, U, Y, X, Z = IMU.P, IMU.U, IMU.Y, IMU.X, IMU.Z
S, N, R = named_offsets(CHANNEL_STATE_PARTS), named_offsets(NOISE_PARTS), named_offsets(RECORD_PARTS)
LAST = named_offsets(LAST_INTEGRAL_PARTS)
X_SIZE, U_SIZE = Layout.of(CONTINUOUS).size, Layout.of(INPUTS).size

ChannelParameters = namedtuple("ChannelParameters", [p.name[len("gyro_"):] for p in _channel_parameters(
    "gyro", "", "", "")])
GYRO = ChannelParameters(*(getattr(P, "gyro_" + name) for name in ChannelParameters._fields))
ACCEL = ChannelParameters(*(getattr(P, "accel_" + name) for name in ChannelParameters._fields))


@njit(cache=True)
def channel_increment(d_true, p, c, z, s, noise, n0, t_prev, t_now, r, increment, counts):
    """One sample of one sensor channel (gyro or accelerometer), see the module docstring.

    d_true: the true increments (3-tuple); c: the channel's parameter offsets (ChannelParameters);
    z[s:]: the channel's error states (CHANNEL_STATE_PARTS); noise[n0:]: its standard normals
    (NOISE_PARTS). Writes the measured increment (quantized) at z[r + increment:] and the integer
    counts (0 when lsb = 0) at z[r + counts:].
    """
    period = t_now - t_prev
    sq = np.sqrt(period)
    arw, b_inst, tc = p[c.random_walk], p[c.bias_instability], p[c.bias_correlation_time]
    rrw, ramp, white, lsb = p[c.bias_random_walk], p[c.ramp], p[c.white_noise], p[c.lsb]
    sigma_gm = FLICKER_FLOOR * b_inst / GAUSS_MARKOV_PEAK
    phi = np.exp(-period / tc)
    gm_drive = sigma_gm * np.sqrt(1.0 - phi * phi)
    t_start = max(t_prev, 0.0)  # the ramp starts at t = 0
    ramp_integral = 0.5 * ramp * (t_now * t_now - t_start * t_start)
    walk, markov, last_white, carry = s + S.bias_random_walk, s + S.bias_gauss_markov, s + S.white_noise, \
        s + S.quantizer_carry
    for i in range(3):
        aligned = d_true[i]
        for j in range(3):
            aligned += p[c.misalignment + 3 * i + j] * d_true[j]
        z[walk + i] += rrw * sq * noise[n0 + N.bias_random_walk + i]
        z[markov + i] = phi * z[markov + i] + gm_drive * noise[n0 + N.gauss_markov + i]
        w = white * noise[n0 + N.white + i]
        value = ((1.0 + p[c.scale_factor + i]) * aligned + (p[c.bias + i] + z[walk + i] + z[markov + i]) * period
                 + ramp_integral + arw * sq * noise[n0 + N.random_walk + i] + w - z[last_white + i])
        z[last_white + i] = w
        if lsb > 0.0:
            total = value + z[carry + i]
            n_counts = np.floor(total / lsb + 0.5)
            z[carry + i] = total - n_counts * lsb
            z[r + increment + i] = n_counts * lsb
            z[r + counts + i] = n_counts
        else:
            z[r + increment + i] = value
            z[r + counts + i] = 0.0


@njit(cache=True)
def imu_sample(t, x, z, u, p, noise):
    """Discrete update at t: true increments since the last sample, the shift register moved one
    record on, both channels' measurements into the newest record."""
    period = z[Z.sample_period]
    t_prev = t - period
    angle, velocity = Z.last_integrals + LAST.angle, Z.last_integrals + LAST.velocity
    d_angle = (x[X.angle_integral] - z[angle], x[X.angle_integral + 1] - z[angle + 1],
               x[X.angle_integral + 2] - z[angle + 2])
    d_velocity = (x[X.velocity_integral] - z[velocity], x[X.velocity_integral + 1] - z[velocity + 1],
                  x[X.velocity_integral + 2] - z[velocity + 2])
    for i in range(3):
        z[angle + i] = x[X.angle_integral + i]
        z[velocity + i] = x[X.velocity_integral + i]
    r0 = Z.records
    for k in range((z.shape[0] - r0) // RECORD_SIZE - 1, 0, -1):
        for m in range(RECORD_SIZE):
            z[r0 + k * RECORD_SIZE + m] = z[r0 + (k - 1) * RECORD_SIZE + m]
    channel_increment(d_angle, p, GYRO, z, Z.error_states, noise, 0, t_prev, t,
                      r0, R.delta_angle, R.delta_angle_counts)
    channel_increment(d_velocity, p, ACCEL, z, Z.error_states + CHANNEL_STATE_SIZE, noise, CHANNEL_NOISE_SIZE,
                      t_prev, t, r0, R.delta_velocity, R.delta_velocity_counts)
    for i in range(3):
        z[r0 + R.angular_rate + i] = z[r0 + R.delta_angle + i] / period
        z[r0 + R.specific_force + i] = z[r0 + R.delta_velocity + i] / period


@njit(cache=True)
def _held_outputs(t, x, z, u, p, y):
    oldest = z.shape[0] - RECORD_SIZE
    for i in range(3):
        y[Y.angular_rate + i] = z[oldest + R.angular_rate + i]
        y[Y.specific_force + i] = z[oldest + R.specific_force + i]
        y[Y.delta_angle + i] = z[oldest + R.delta_angle + i]
        y[Y.delta_velocity + i] = z[oldest + R.delta_velocity + i]
        y[Y.delta_angle_counts + i] = z[oldest + R.delta_angle_counts + i]
        y[Y.delta_velocity_counts + i] = z[oldest + R.delta_velocity_counts + i]


@njit(cache=True)
def _true_increments(t, x, z, u, p, xdot):
    rotation = U.rotation
    for i in range(3):
        xdot[X.angle_integral + i] = u[U.angular_velocity + i]
        g_node = 0.0
        for j in range(3):
            g_node += u[rotation + 3 * j + i] * p[P.gravity + j]  # R^T g: column i of R
        xdot[X.velocity_integral + i] = (u[U.linear_acceleration + i] - g_node
                                         - u[U.gravitational_acceleration + i])


@register_model
class Imu(Model):
    """Gyro + accelerometer triad at a node with the IEEE 952 error model; see the module docstring."""

    summary = "IMU at a node: ARW, bias instability, RRW, ramp, white angle noise, quantization, SF, misalignment"
    declarations = IMU
    noise_size = 2 * CHANNEL_NOISE_SIZE
    default_period = "0.01 s"
    state_outputs = staticmethod(_held_outputs)
    derivatives = staticmethod(_true_increments)
    update = staticmethod(imu_sample)
    #: imu_sample reads the integrals in x, not the node's rate and acceleration in u: a sample needs no forward
    #: dynamics (tests/models/test_imu.py gives it NaN inputs)
    update_reads_inputs = False

    def __init__(self, name: str, *, period=None, offset=0.0, **parameter_values):
        self._given_period = period
        super().__init__(name, period=period, offset=offset, **parameter_values)

    def configure(self):
        period = parse_period(self._given_period if self._given_period is not None else self.default_period,
                              f"model {self.path}: period")
        for prefix in ("gyro", "accel"):
            m = self.parameter(f"{prefix}_misalignment")
            if np.any(np.diag(m) != 0.0):
                raise ModelError(f"model {self.path}: parameter {prefix}_misalignment: the diagonal must be zero "
                                 f"(scale-factor errors go into {prefix}_scale_factor), given {np.diag(m).tolist()}")
        latency = float(self.parameter("latency"))
        samples = round(latency / float(period))
        if abs(samples * float(period) - latency) > 1e-9 * max(1.0, latency):
            raise ModelError(f"model {self.path}: parameter latency: expected a whole number of sample periods "
                             f"({float(period):g} s), given {latency:g} s")
        self.discrete_states = (tuple(replace(d, initial=float(period)) if d.name == "sample_period" else d
                                      for d in DISCRETE)
                                + (replace(RECORDS, shape=((samples + 1) * RECORD_SIZE,)),))


@njit(cache=True)
def _static_record(z, p, noise, period, rates):
    x = np.zeros(X_SIZE)
    u = np.zeros(U_SIZE)
    oldest = z.shape[0] - RECORD_SIZE
    for k in range(noise.shape[0]):
        imu_sample((k + 1) * period, x, z, u, p, noise[k])
        for i in range(3):
            rates[k, i] = z[oldest + R.angular_rate + i]
            rates[k, 3 + i] = z[oldest + R.specific_force + i]


def static_record(imu: Imu, samples: int, seed=0) -> np.ndarray:
    """Measured (angular rate, specific force) of ``imu`` at rest in zero gravity for ``samples``
    periods, from the same kernel as a simulation (for Allan-deviation studies). Shape (samples, 6)."""
    z = imu.initial_discrete_state()
    noise = np.random.default_rng(seed).standard_normal((samples, imu.noise_size))
    rates = np.empty((samples, 6))
    _static_record(z, imu.p, noise, float(imu.period), rates)
    return rates


def allan_deviation(rate, period: float, cluster_sizes) -> np.ndarray:
    """Overlapping Allan deviation of a rate record (IEEE Std 952 eq. C.2 with all overlapping
    clusters) at tau = m * period for each m in ``cluster_sizes``; ``rate`` shape (n,) or (n, k)."""
    rate = np.asarray(rate, float)
    angle = np.concatenate([np.zeros((1,) + rate.shape[1:]), np.cumsum(rate, axis=0) * period])
    out = []
    for m in cluster_sizes:
        m = int(m)
        second_difference = angle[2 * m:] - 2.0 * angle[m:-m] + angle[:-2 * m]
        out.append(np.sqrt(0.5 * np.mean(second_difference**2, axis=0)) / (m * period))
    return np.array(out)
