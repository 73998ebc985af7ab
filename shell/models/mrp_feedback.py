"""Sampled MRP feedback attitude control law (the law of Basilisk's ``mrpFeedback`` module).

At each sample t_k the model reads the measured attitude ``q_BN`` (node -> world) and rate
``omega_BN`` (node axes), the reference ``q_RN`` (reference -> world) with its angular velocity
``omega_RN`` and acceleration ``omega_RN'`` (world axes, as Basilisk's attitude reference message)
and, optionally, the wheels' spin momentum ``h_s`` (node axes), and holds until the next sample::

    sigma      = MRP of q_BR = q_RN^* (x) q_BN           (short rotation, |sigma| <= 1)
    d_omega    = omega_BN - omega_RN                      (node axes)
    s_k        = sat(s_{k-1} + K dt_k sigma, s_max)      (integral, per component; dt_0 = 0)
    z          = s_k + [I] d_omega                        (z = 0 without integral feedback, K_i = 0)
    L_r        = K sigma + P d_omega + P K_i z
                 - (omega_RN + K_i z) x ([I] omega_BN + h_s)      (control_law_type 0)
                 - omega_BN x ([I] omega_BN + h_s)                 (control_law_type 1, instead)
                 + [I] (omega_BN x omega_RN - omega_RN') + L
    torque     = -L_r

(Schaub and Junkins, "Analytical Mechanics of Space Systems", 4th ed., sec. 8.4, eq. 8.95 with the
integral term of sec. 8.4.3; the discrete form, the integral's first sample and clamp, the two
gyroscopic variants and the sign of the output are Basilisk's ``mrpFeedback``). Without the integral
and for a rest reference the law is ``-K sigma - P omega``; ``sigma = tan(theta/4) e``.

Outputs are the held torque and, for logging, sigma, d_omega and the integral s. Discrete states
name the held values; ``last_time`` (time of the previous sample, -1 before the first) gives dt.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from shell.model import Declarations, InputPort, Model, ModelError, OutputPort, Parameter, State
from shell.attitude import cross, quaternion_conjugate, quaternion_multiply, quaternion_to_mrp, rotate_inverse
from shell.ports import MEASURED_ATTITUDE_AND_RATE, attitude_reference_inputs
from shell.registry import register_model

PARAMETERS = (
    Parameter("k", "N*m", 1.0, (), (0.0, None), "attitude gain K (torque per unit MRP)"),
    Parameter("p", "N*m*s/rad", 1.0, (), (0.0, None), "rate gain P"),
    Parameter("ki", "rad/(N*m*s^2)", 0.0, (), (0.0, None), "integral gain K_i (0: no integral feedback)"),
    Parameter("integral_limit", "N*m*s", 1e300, (), (0.0, None),
              "clamp of each component of the integral s = sum K dt sigma"),
    Parameter("inertia", "kg*m^2", np.eye(3), (3, 3), None, "spacecraft inertia about its center of mass, node axes"),
    Parameter("known_torque", "N*m", (0.0, 0.0, 0.0), (3,), None, "known external torque L, node axes"),
    Parameter("control_law_type", "", 0.0, (), (0.0, 1.0),
              "0: gyroscopic term (omega_RN + K_i z) x H; 1: omega_BN x H (Basilisk's controlLawType)"),
)
INPUTS = (
    *MEASURED_ATTITUDE_AND_RATE,
    *attitude_reference_inputs(reference_attitude="reference quaternion, reference -> world (default: identity)"),
    InputPort("wheel_momentum", "N*m*s", (3,), "wheels' spin momentum sum_k J_k (a_k . omega + Omega_k) a_k, "
              "node axes", required=False),
)
OUTPUTS = (
    OutputPort("torque", "N*m", (3,), "commanded torque on the spacecraft, node axes (held)"),
    OutputPort("attitude_error", "", (3,), "MRP sigma_BR of the last sample"),
    OutputPort("rate_error", "rad/s", (3,), "omega_BN - omega_RN of the last sample, node axes"),
    OutputPort("integral", "N*m*s", (3,), "integral s = sum K dt sigma (clamped)"),
)
DISCRETE = (
    State("torque", "N*m", (3,), None, "held torque command"),
    State("attitude_error", "", (3,), None, "held sigma_BR"),
    State("rate_error", "rad/s", (3,), None, "held rate error"),
    State("integral", "N*m*s", (3,), None, "integral of K sigma"),
    State("last_time", "s", (), -1.0, "time of the previous sample (-1: none yet)"),
)
MRP = Declarations(parameters=PARAMETERS, inputs=INPUTS, outputs=OUTPUTS, discrete=DISCRETE)
P, U, Y, Z = MRP.P, MRP.U, MRP.Y, MRP.Z


@njit(cache=True)
def _held(t, x, z, u, p, y):
    for i in range(3):
        y[Y.torque + i] = z[Z.torque + i]
        y[Y.attitude_error + i] = z[Z.attitude_error + i]
        y[Y.rate_error + i] = z[Z.rate_error + i]
        y[Y.integral + i] = z[Z.integral + i]


@njit(cache=True)
def _inertia_times(p, v):
    i = P.inertia
    return (p[i] * v[0] + p[i + 1] * v[1] + p[i + 2] * v[2],
            p[i + 3] * v[0] + p[i + 4] * v[1] + p[i + 5] * v[2],
            p[i + 6] * v[0] + p[i + 7] * v[1] + p[i + 8] * v[2])


@njit(cache=True)
def _mrp_feedback_update(t, x, z, u, p):
    a, r = U.attitude, U.reference_attitude
    q_bn = (u[a], u[a + 1], u[a + 2], u[a + 3])
    q_rn = (u[r], u[r + 1], u[r + 2], u[r + 3])
    sigma = quaternion_to_mrp(quaternion_multiply(quaternion_conjugate(q_rn), q_bn))
    w = U.angular_velocity
    omega = (u[w], u[w + 1], u[w + 2])
    wr, ar = U.reference_angular_velocity, U.reference_angular_acceleration
    omega_r = rotate_inverse(q_bn, (u[wr], u[wr + 1], u[wr + 2]))
    domega_r = rotate_inverse(q_bn, (u[ar], u[ar + 1], u[ar + 2]))
    d_omega = (omega[0] - omega_r[0], omega[1] - omega_r[1], omega[2] - omega_r[2])
    dt = t - z[Z.last_time] if z[Z.last_time] >= 0.0 else 0.0
    z[Z.last_time] = t
    k, gain_p, ki = p[P.k], p[P.p], p[P.ki]
    zi = (0.0, 0.0, 0.0)
    if ki > 0.0:
        limit = p[P.integral_limit]
        for i in range(3):
            s = z[Z.integral + i] + k * dt * sigma[i]
            z[Z.integral + i] = min(max(s, -limit), limit)
        i_dw = _inertia_times(p, d_omega)
        zi = (z[Z.integral] + i_dw[0], z[Z.integral + 1] + i_dw[1], z[Z.integral + 2] + i_dw[2])
    h = _inertia_times(p, omega)
    hw = U.wheel_momentum
    h = (h[0] + u[hw], h[1] + u[hw + 1], h[2] + u[hw + 2])
    if p[P.control_law_type] < 0.5:
        spin = (omega_r[0] + ki * zi[0], omega_r[1] + ki * zi[1], omega_r[2] + ki * zi[2])
    else:
        spin = omega
    gyro = cross(spin, h)
    wxr = cross(omega, omega_r)
    feedforward = _inertia_times(p, (wxr[0] - domega_r[0], wxr[1] - domega_r[1], wxr[2] - domega_r[2]))
    for i in range(3):
        lr = (k * sigma[i] + gain_p * d_omega[i] + gain_p * ki * zi[i] - gyro[i] + feedforward[i]
              + p[P.known_torque + i])
        z[Z.torque + i] = -lr
        z[Z.attitude_error + i] = sigma[i]
        z[Z.rate_error + i] = d_omega[i]


@register_model
class MrpFeedback(Model):
    """Sampled MRP feedback law (Basilisk's mrpFeedback); see the module docstring."""

    summary = "sampled MRP feedback (Basilisk mrpFeedback): -K sigma - P d_omega + integral, feed-forward, wheels"
    declarations = MRP
    default_period = "0.1 s"
    state_outputs = staticmethod(_held)
    update = staticmethod(_mrp_feedback_update)

    def configure(self):
        inertia = self.parameter("inertia")
        if not np.allclose(inertia, inertia.T, rtol=0.0, atol=1e-12 * max(1.0, float(np.abs(inertia).max()))):
            raise ModelError(f"model {self.path}: parameter inertia: expected a symmetric matrix, given "
                             f"{inertia.tolist()}")
        law = float(self.parameter("control_law_type"))
        if law not in (0.0, 1.0):
            raise ModelError(f"model {self.path}: parameter control_law_type: expected 0 or 1, given {law:g}")
