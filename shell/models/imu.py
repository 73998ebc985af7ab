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
"""

from __future__ import annotations

import numpy as np
from numba import njit

from shell.model import InputPort, Model, ModelError, OutputPort, Parameter, State, parse_period
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

# channel parameter block: 7 scalars + 3 turn-on bias + 3 scale factors + 9 misalignment = 22 values
_CHANNEL_SIZE = 22
# per-channel discrete state: random-walk bias, Gauss-Markov bias, previous white-angle noise, carry
_CHANNEL_STATE = 12
_RECORD = 18  # rate, specific force, delta angle, delta velocity, angle counts, velocity counts


@njit(cache=True)
def channel_increment(d_true, p, c, z, s, noise, n0, t_prev, t_now, out):
    """One sample of one sensor channel (gyro or accelerometer), see the module docstring.

    p[c:c+22]: random_walk N, bias_instability B, correlation_time Tc, bias_random_walk K, ramp R,
    white_noise Q, lsb, turn-on bias (3), scale factor (3), misalignment (3x3).
    z[s:s+12]: random-walk bias (3), Gauss-Markov bias (3), previous white noise (3), carry (3).
    noise[n0:n0+12]: standard normals (random walk, bias walk, Gauss-Markov, white).
    out[0:3] measured increment (quantized), out[3:6] integer counts (0 when lsb = 0).
    """
    period = t_now - t_prev
    sq = np.sqrt(period)
    arw, b_inst, tc, rrw, ramp, white, lsb = p[c], p[c + 1], p[c + 2], p[c + 3], p[c + 4], p[c + 5], p[c + 6]
    sigma_gm = FLICKER_FLOOR * b_inst / GAUSS_MARKOV_PEAK
    phi = np.exp(-period / tc)
    gm_drive = sigma_gm * np.sqrt(1.0 - phi * phi)
    t_start = max(t_prev, 0.0)  # the ramp starts at t = 0
    ramp_integral = 0.5 * ramp * (t_now * t_now - t_start * t_start)
    for i in range(3):
        aligned = d_true[i]
        for j in range(3):
            aligned += p[c + 13 + 3 * i + j] * d_true[j]
        z[s + i] += rrw * sq * noise[n0 + 3 + i]
        z[s + 3 + i] = phi * z[s + 3 + i] + gm_drive * noise[n0 + 6 + i]
        w = white * noise[n0 + 9 + i]
        value = ((1.0 + p[c + 10 + i]) * aligned + (p[c + 7 + i] + z[s + i] + z[s + 3 + i]) * period
                 + ramp_integral + arw * sq * noise[n0 + i] + w - z[s + 6 + i])
        z[s + 6 + i] = w
        if lsb > 0.0:
            total = value + z[s + 9 + i]
            counts = np.floor(total / lsb + 0.5)
            z[s + 9 + i] = total - counts * lsb
            out[i] = counts * lsb
            out[3 + i] = counts
        else:
            out[i] = value
            out[3 + i] = 0.0


@njit(cache=True)
def imu_sample(t, x, z, u, p, noise):
    """Discrete update at t. z = [sample period, last angle and velocity integrals (6), channel error
    states (2 x 12), output shift register (records of 18 values, newest first)]."""
    period = z[0]
    t_prev = t - period
    d_angle = np.empty(3)
    d_velocity = np.empty(3)
    for i in range(3):
        d_angle[i] = x[i] - z[1 + i]
        d_velocity[i] = x[3 + i] - z[4 + i]
        z[1 + i] = x[i]
        z[4 + i] = x[3 + i]
    gyro = np.empty(6)
    accel = np.empty(6)
    channel_increment(d_angle, p, 0, z, 7, noise, 0, t_prev, t, gyro)
    channel_increment(d_velocity, p, _CHANNEL_SIZE, z, 7 + _CHANNEL_STATE, noise, 12, t_prev, t, accel)
    r0 = 7 + 2 * _CHANNEL_STATE
    n_records = (z.shape[0] - r0) // _RECORD
    for k in range(n_records - 1, 0, -1):
        for m in range(_RECORD):
            z[r0 + k * _RECORD + m] = z[r0 + (k - 1) * _RECORD + m]
    for i in range(3):
        z[r0 + i] = gyro[i] / period
        z[r0 + 3 + i] = accel[i] / period
        z[r0 + 6 + i] = gyro[i]
        z[r0 + 9 + i] = accel[i]
        z[r0 + 12 + i] = gyro[3 + i]
        z[r0 + 15 + i] = accel[3 + i]


@njit(cache=True)
def _held_outputs(t, x, z, u, p, y):
    start = z.shape[0] - _RECORD
    for m in range(_RECORD):
        y[m] = z[start + m]


@njit(cache=True)
def _true_increments(t, x, z, u, p, xdot):
    # u = [angular_velocity (3), linear_acceleration (3), rotation (9), gravitational_acceleration (3)]
    for i in range(3):
        xdot[i] = u[i]
        g_node = 0.0
        for j in range(3):
            g_node += u[6 + 3 * j + i] * p[2 * _CHANNEL_SIZE + j]  # R^T g: column i of R
        xdot[3 + i] = u[3 + i] - g_node - u[15 + i]


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


@register_model
class Imu(Model):
    """Gyro + accelerometer triad at a node with the IEEE 952 error model; see the module docstring."""

    summary = "IMU at a node: ARW, bias instability, RRW, ramp, white angle noise, quantization, SF, misalignment"
    parameters = (_channel_parameters("gyro", "angle", "rad/s", "rad")
                  + _channel_parameters("accel", "velocity", "m/s^2", "m/s")
                  + (Parameter("gravity", "m/s^2", (0.0, 0.0, 0.0), (3,), None,
                               "uniform gravitational field, world axes (the engine's multibody gravity)"),
                     Parameter("latency", "s", 0.0, (), (0.0, None),
                               "output latency, a whole number of sample periods")))
    inputs = (
        InputPort("angular_velocity", "rad/s", (3,), "inertial angular velocity of the node, node axes"),
        InputPort("linear_acceleration", "m/s^2", (3,), "classical acceleration of the node, node axes"),
        InputPort("rotation", "", (3, 3), "rotation node -> world"),
        InputPort("gravitational_acceleration", "m/s^2", (3,), "gravity not in the engine, node axes",
                  required=False),
    )
    outputs = (
        OutputPort("angular_rate", "rad/s", (3,), "measured angular rate (delta angle / period)"),
        OutputPort("specific_force", "m/s^2", (3,), "measured specific force (delta velocity / period)"),
        OutputPort("delta_angle", "rad", (3,), "quantized delta angle of the last sample"),
        OutputPort("delta_velocity", "m/s", (3,), "quantized delta velocity of the last sample"),
        OutputPort("delta_angle_counts", "", (3,), "integer delta-angle counts (0 without lsb)"),
        OutputPort("delta_velocity_counts", "", (3,), "integer delta-velocity counts (0 without lsb)"),
    )
    continuous_states = (State("angle_integral", "rad", (3,), None, "integral of the true angular velocity"),
                         State("velocity_integral", "m/s", (3,), None, "integral of the true specific force"))
    default_period = "0.01 s"
    state_outputs = staticmethod(_held_outputs)
    derivatives = staticmethod(_true_increments)

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
        self.discrete_states = (
            State("sample_period", "s", (), float(period), "the sample period (from the rate)"),
            State("last_integrals", "", (6,), None, "angle and velocity integrals at the last sample"),
            State("error_states", "", (2 * _CHANNEL_STATE,), None,
                  "per channel: random-walk bias, Gauss-Markov bias, last white noise, quantizer carry"),
            State("records", "", ((samples + 1) * _RECORD,), None, "output shift register (latency)"),
        )
        self._noise = np.zeros(24)

    def update(self, t, x, z, u, p):
        self.rng.standard_normal(out=self._noise)
        imu_sample(t, x, z, u, p, self._noise)


@njit(cache=True)
def _static_record(z, p, noise, period, rates):
    x = np.zeros(6)
    u = np.zeros(18)
    r0 = z.shape[0] - _RECORD
    for k in range(noise.shape[0]):
        imu_sample((k + 1) * period, x, z, u, p, noise[k])
        for i in range(3):
            rates[k, i] = z[r0 + i]
            rates[k, 3 + i] = z[r0 + 3 + i]


def static_record(imu: Imu, samples: int, seed=0) -> np.ndarray:
    """Measured (angular rate, specific force) of ``imu`` at rest in zero gravity for ``samples``
    periods, from the same kernel as a simulation (for Allan-deviation studies). Shape (samples, 6)."""
    z = imu.initial_discrete_state()
    noise = np.random.default_rng(seed).standard_normal((samples, 24))
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
