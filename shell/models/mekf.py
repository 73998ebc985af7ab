"""Multiplicative extended Kalman filter for attitude and gyro bias from a star tracker and a gyro.

Markley and Crassidis, "Fundamentals of Spacecraft Attitude Determination and Control" (2014),
sec. 7.2.4 (Table 7.1), with the gyro model of sec. 4.7.1 (Farrenkopf):

    omega_meas = omega + beta + eta_v,    beta' = eta_u,    E[eta_v eta_v^T] = s_v^2 I, E[eta_u eta_u^T] = s_u^2 I

(``s_v`` the angle random walk, ``s_u`` the rate random walk: the IMU's ``gyro_random_walk`` and
``gyro_bias_random_walk``). The estimate is ``q`` (node -> world) and ``beta``; the six error states
are the small rotation ``dtheta`` in node axes (``q_true = q (x) [1, dtheta/2]``) and ``dbeta``.
At each sample (period dt, the gyro's rate ``omega_meas`` the mean over the last period, as the IMU
gives it)::

    propagate   w = omega_meas - beta,  q <- q (x) exp(w dt / 2),  P <- Phi P Phi^T + Q      (eqs. 7.39-7.47)
                Phi = [[Phi11, Phi12], [0, I]],  with |w| = n, W = [w x]:
                Phi11 = I - sin(n dt)/n W + (1 - cos(n dt))/n^2 W^2
                Phi12 = -(I dt - (1 - cos(n dt))/n^2 W + (n dt - sin(n dt))/n^3 W^2)
                Q = [[(s_v^2 dt + s_u^2 dt^3 / 3) I, -s_u^2 dt^2 / 2 I], [-s_u^2 dt^2 / 2 I, s_u^2 dt I]]
    update      (star tracker valid) q_m = q_st (x) q_align^*   (sensor -> world, then node -> world)
                y = 2 sign(w_e) v_e of q_e = q^* (x) q_m,  H = [I 0],  R = C diag(s_st^2) C^T (C: sensor -> node)
                K = P H^T (H P H^T + R)^-1,  dx = K y,  q <- q (x) [1, dx_theta / 2] normalized,
                beta <- beta + dx_beta,  P <- (I - K H) P (I - K H)^T + K R K^T   (Joseph form)

Initialization: at the first sample with a valid star-tracker quaternion, ``q = q_m``, ``beta = 0``,
``P = diag(R, s_b0^2 I)``; before it the outputs are the identity with ``initialized`` 0.
The covariance and a scratch area are discrete states (no allocation in the kernel): ``covariance``
(6 x 6 row-major) and ``scratch`` (two 6 x 6 blocks).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from shell.model import Declarations, InputPort, Model, OutputPort, Parameter, State
from shell.attitude import (axis_angle_quaternion, error_rotation_vector, quaternion_conjugate, quaternion_multiply,
                            quaternion_normalized, rotate)
from shell.registry import register_model

PARAMETERS = (
    Parameter("gyro_random_walk", "rad/s*s**0.5", None, (), (0.0, None), "angle random walk s_v (e.g. deg/hour**0.5)"),
    Parameter("gyro_bias_random_walk", "rad/s/s**0.5", None, (), (0.0, None), "rate random walk s_u"),
    Parameter("star_tracker_noise", "rad", None, (3,), (1e-12, None),
              "1-sigma star-tracker error per sensor axis (e.g. [5, 5, 40] arcsec)"),
    Parameter("star_tracker_alignment", "", (1.0, 0.0, 0.0, 0.0), (4,), (-1.0, 1.0),
              "quaternion star-tracker sensor frame -> node frame"),
    Parameter("initial_bias_sigma", "rad/s", 1e-4, (), (0.0, None), "1-sigma of the initial gyro bias"),
)
INPUTS = (
    InputPort("angular_rate", "rad/s", (3,), "gyro measurement, node axes (the IMU's mean rate over the period)"),
    InputPort("star_tracker_attitude", "", (4,), "star-tracker quaternion, sensor -> world"),
    InputPort("star_tracker_valid", "", (), "1: measurement valid, 0: none (dropout, exclusion)",
              required=False, default=1.0),
)
OUTPUTS = (
    OutputPort("attitude", "", (4,), "estimated quaternion, node -> world"),
    OutputPort("angular_velocity", "rad/s", (3,), "gyro rate minus the estimated bias, node axes"),
    OutputPort("gyro_bias", "rad/s", (3,), "estimated gyro bias"),
    OutputPort("attitude_sigma", "rad", (3,), "1-sigma of the attitude error per node axis (sqrt diag P)"),
    OutputPort("covariance", "", (6, 6), "error covariance of [dtheta (rad); dbeta (rad/s)]"),
    OutputPort("initialized", "", (), "1 once a star-tracker measurement has initialized the filter"),
)
DISCRETE = (
    State("attitude", "", (4,), (1.0, 0.0, 0.0, 0.0), "estimated quaternion"),
    State("gyro_bias", "rad/s", (3,), None, "estimated bias"),
    State("angular_velocity", "rad/s", (3,), None, "bias-corrected rate of the last sample"),
    State("covariance", "", (36,), None, "error covariance, row-major"),
    State("scratch", "", (72,), None, "two 6 x 6 work blocks"),
    State("initialized", "", (), 0.0, "1 after the first valid star-tracker measurement"),
    State("last_time", "s", (), -1.0, "time of the previous sample (-1: none)"),
)
MEKF = Declarations(parameters=PARAMETERS, inputs=INPUTS, outputs=OUTPUTS, discrete=DISCRETE)
P, U, Y, Z = MEKF.P, MEKF.U, MEKF.Y, MEKF.Z


@njit(cache=True)
def _outputs(t, x, z, u, p, y):
    for i in range(4):
        y[Y.attitude + i] = z[Z.attitude + i]
    for i in range(3):
        y[Y.angular_velocity + i] = z[Z.angular_velocity + i]
        y[Y.gyro_bias + i] = z[Z.gyro_bias + i]
        y[Y.attitude_sigma + i] = np.sqrt(max(z[Z.covariance + 7 * i], 0.0))
    for i in range(36):
        y[Y.covariance + i] = z[Z.covariance + i]
    y[Y.initialized] = z[Z.initialized]


@njit(cache=True)
def _propagate(z, p, w, dt):
    """q <- q (x) exp(w dt / 2); P <- Phi P Phi^T + Q (module docstring)."""
    n = np.sqrt(w[0] * w[0] + w[1] * w[1] + w[2] * w[2])
    if n * dt > 1e-300:
        e = (w[0] / n, w[1] / n, w[2] / n)
        q = quaternion_multiply((z[Z.attitude], z[Z.attitude + 1], z[Z.attitude + 2], z[Z.attitude + 3]),
                                axis_angle_quaternion(e, n * dt))
        q = quaternion_normalized(q)
        for i in range(4):
            z[Z.attitude + i] = q[i]
    # W = [w x], W^2 = w w^T - n^2 I
    nt = n * dt
    if nt > 1e-4:
        a = np.sin(nt) / n
        b = (1.0 - np.cos(nt)) / (n * n)
        c = (nt - np.sin(nt)) / (n * n * n)
    else:  # series: the exact coefficients lose digits for small n dt
        a = dt * (1.0 - nt * nt / 6.0)
        b = dt * dt * (0.5 - nt * nt / 24.0)
        c = dt * dt * dt * (1.0 / 6.0 - nt * nt / 120.0)
    s = Z.scratch  # Phi in the first block
    for i in range(36):
        z[s + i] = 0.0
    for i in range(3):
        for j in range(3):
            wij = 0.0
            if i != j:
                k = 3 - i - j
                # [w x]_{ij}: (1,0) = w2, (0,2) = w1, (2,1) = w0 positive; their transposes negative
                sign = 1.0 if (i - j + 3) % 3 == 1 else -1.0
                wij = sign * w[k]
            w2 = w[i] * w[j] - (n * n if i == j else 0.0)
            eye = 1.0 if i == j else 0.0
            z[s + 6 * i + j] = eye - a * wij + b * w2
            z[s + 6 * i + j + 3] = -(eye * dt - b * wij + c * w2)
            z[s + 6 * (i + 3) + j + 3] = eye
    # second block = Phi P; then P = (Phi P) Phi^T + Q
    m = Z.scratch + 36
    cov = Z.covariance
    for i in range(6):
        for j in range(6):
            acc = 0.0
            for k in range(6):
                acc += z[s + 6 * i + k] * z[cov + 6 * k + j]
            z[m + 6 * i + j] = acc
    sv2, su2 = p[P.gyro_random_walk] ** 2, p[P.gyro_bias_random_walk] ** 2
    for i in range(6):
        for j in range(6):
            acc = 0.0
            for k in range(6):
                acc += z[m + 6 * i + k] * z[s + 6 * j + k]
            z[cov + 6 * i + j] = acc
    for i in range(3):
        z[cov + 7 * i] += sv2 * dt + su2 * dt * dt * dt / 3.0
        z[cov + 6 * i + i + 3] -= 0.5 * su2 * dt * dt
        z[cov + 6 * (i + 3) + i] -= 0.5 * su2 * dt * dt
        z[cov + 7 * (i + 3)] += su2 * dt


@njit(cache=True)
def _measurement_covariance(p):
    """R in node axes: C diag(s_st^2) C^T, C the sensor -> node rotation (columns: sensor axes)."""
    al = P.star_tracker_alignment
    q_align = (p[al], p[al + 1], p[al + 2], p[al + 3])
    c0, c1, c2 = rotate(q_align, (1.0, 0.0, 0.0)), rotate(q_align, (0.0, 1.0, 0.0)), rotate(q_align, (0.0, 0.0, 1.0))
    v0, v1, v2 = p[P.star_tracker_noise] ** 2, p[P.star_tracker_noise + 1] ** 2, p[P.star_tracker_noise + 2] ** 2
    return ((c0[0] * v0 * c0[0] + c1[0] * v1 * c1[0] + c2[0] * v2 * c2[0],
             c0[0] * v0 * c0[1] + c1[0] * v1 * c1[1] + c2[0] * v2 * c2[1],
             c0[0] * v0 * c0[2] + c1[0] * v1 * c1[2] + c2[0] * v2 * c2[2]),
            (c0[1] * v0 * c0[0] + c1[1] * v1 * c1[0] + c2[1] * v2 * c2[0],
             c0[1] * v0 * c0[1] + c1[1] * v1 * c1[1] + c2[1] * v2 * c2[1],
             c0[1] * v0 * c0[2] + c1[1] * v1 * c1[2] + c2[1] * v2 * c2[2]),
            (c0[2] * v0 * c0[0] + c1[2] * v1 * c1[0] + c2[2] * v2 * c2[0],
             c0[2] * v0 * c0[1] + c1[2] * v1 * c1[1] + c2[2] * v2 * c2[1],
             c0[2] * v0 * c0[2] + c1[2] * v1 * c1[2] + c2[2] * v2 * c2[2]))


@njit(cache=True)
def _measurement_covariance_into(z, p):
    r = _measurement_covariance(p)
    for i in range(3):
        for j in range(3):
            z[Z.covariance + 6 * i + j] = r[i][j]


@njit(cache=True)
def _update(z, p, q_m):
    """Star-tracker update (module docstring), Joseph form."""
    q = (z[Z.attitude], z[Z.attitude + 1], z[Z.attitude + 2], z[Z.attitude + 3])
    y0, y1, y2 = error_rotation_vector(q, q_m)
    cov = Z.covariance
    r = _measurement_covariance(p)
    # S = P11 + R and its inverse (adjugate)
    s00, s01, s02 = z[cov] + r[0][0], z[cov + 1] + r[0][1], z[cov + 2] + r[0][2]
    s10, s11, s12 = z[cov + 6] + r[1][0], z[cov + 7] + r[1][1], z[cov + 8] + r[1][2]
    s20, s21, s22 = z[cov + 12] + r[2][0], z[cov + 13] + r[2][1], z[cov + 14] + r[2][2]
    c00, c01, c02 = s11 * s22 - s12 * s21, s02 * s21 - s01 * s22, s01 * s12 - s02 * s11
    c10, c11, c12 = s12 * s20 - s10 * s22, s00 * s22 - s02 * s20, s02 * s10 - s00 * s12
    c20, c21, c22 = s10 * s21 - s11 * s20, s01 * s20 - s00 * s21, s00 * s11 - s01 * s10
    det = s00 * c00 + s01 * c10 + s02 * c20
    inv = ((c00 / det, c01 / det, c02 / det), (c10 / det, c11 / det, c12 / det), (c20 / det, c21 / det, c22 / det))
    # K (6 x 3) = P[:, :3] S^-1 in the first scratch block (rows of 3)
    kb = Z.scratch
    for i in range(6):
        for j in range(3):
            z[kb + 3 * i + j] = (z[cov + 6 * i] * inv[0][j] + z[cov + 6 * i + 1] * inv[1][j]
                                 + z[cov + 6 * i + 2] * inv[2][j])
    dth0 = z[kb] * y0 + z[kb + 1] * y1 + z[kb + 2] * y2
    dth1 = z[kb + 3] * y0 + z[kb + 4] * y1 + z[kb + 5] * y2
    dth2 = z[kb + 6] * y0 + z[kb + 7] * y1 + z[kb + 8] * y2
    for i in range(3):
        z[Z.gyro_bias + i] += z[kb + 3 * (i + 3)] * y0 + z[kb + 3 * (i + 3) + 1] * y1 + z[kb + 3 * (i + 3) + 2] * y2
    q = quaternion_normalized(quaternion_multiply(q, (1.0, 0.5 * dth0, 0.5 * dth1, 0.5 * dth2)))
    for i in range(4):
        z[Z.attitude + i] = q[i]
    # Joseph form: A = I - K H (6 x 6, second block), P = A P A^T + K R K^T
    a = Z.scratch + 36
    for i in range(6):
        for j in range(6):
            z[a + 6 * i + j] = (1.0 if i == j else 0.0) - (z[kb + 3 * i + j] if j < 3 else 0.0)
    # A P goes into K's block (A P cannot be formed in place): K is copied out first
    k_copy = (z[kb], z[kb + 1], z[kb + 2], z[kb + 3], z[kb + 4], z[kb + 5], z[kb + 6], z[kb + 7], z[kb + 8],
              z[kb + 9], z[kb + 10], z[kb + 11], z[kb + 12], z[kb + 13], z[kb + 14], z[kb + 15], z[kb + 16],
              z[kb + 17])
    for i in range(6):
        for j in range(6):
            acc = 0.0
            for k in range(6):
                acc += z[a + 6 * i + k] * z[cov + 6 * k + j]
            z[kb + 6 * i + j] = acc
    for i in range(6):
        for j in range(6):
            acc = 0.0
            for k in range(6):
                acc += z[kb + 6 * i + k] * z[a + 6 * j + k]
            for m in range(3):
                for n in range(3):
                    acc += k_copy[3 * i + m] * r[m][n] * k_copy[3 * j + n]
            z[cov + 6 * i + j] = acc


@njit(cache=True)
def _mekf_update(t, x, z, u, p):
    st = U.star_tracker_attitude
    al = P.star_tracker_alignment
    valid = u[U.star_tracker_valid] >= 0.5
    q_m = quaternion_normalized(quaternion_multiply(
        (u[st], u[st + 1], u[st + 2], u[st + 3]),
        quaternion_conjugate((p[al], p[al + 1], p[al + 2], p[al + 3])))) if valid else (1.0, 0.0, 0.0, 0.0)
    g = U.angular_rate
    if z[Z.initialized] < 0.5:
        z[Z.last_time] = t
        if not valid:
            return
        for i in range(4):
            z[Z.attitude + i] = q_m[i]
        for i in range(36):
            z[Z.covariance + i] = 0.0
        # the first measurement's error covariance (node axes) and the bias prior
        _measurement_covariance_into(z, p)
        for i in range(3):
            z[Z.covariance + 7 * (i + 3)] = p[P.initial_bias_sigma] ** 2
            z[Z.gyro_bias + i] = 0.0
            z[Z.angular_velocity + i] = u[g + i]
        z[Z.initialized] = 1.0
        return
    dt = t - z[Z.last_time]
    z[Z.last_time] = t
    w = (u[g] - z[Z.gyro_bias], u[g + 1] - z[Z.gyro_bias + 1], u[g + 2] - z[Z.gyro_bias + 2])
    _propagate(z, p, w, dt)
    if valid:
        _update(z, p, q_m)
    for i in range(3):
        z[Z.angular_velocity + i] = u[g + i] - z[Z.gyro_bias + i]


@register_model
class AttitudeMekf(Model):
    """Multiplicative EKF (attitude + gyro bias) from a star tracker and a gyro; see the module docstring."""

    summary = "attitude MEKF (Markley-Crassidis 7.2.4): star tracker + gyro in; attitude, rate, bias, covariance out"
    declarations = MEKF
    default_period = "0.1 s"
    state_outputs = staticmethod(_outputs)
    update = staticmethod(_mekf_update)

    def configure(self):
        self.require_unit_norm("star_tracker_alignment")
