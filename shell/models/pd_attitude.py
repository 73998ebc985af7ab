"""Sampled proportional-derivative attitude controller (flight-software stand-in for closed-loop demos).

At every sample t_k (its own period) it reads the measured attitude quaternion q (body/node -> world,
scalar first) and angular velocity omega (node axes), forms the error quaternion
``q_e = q_c^* (x) q`` (rotation from the commanded to the actual frame), and holds the torque command

    tau = -K_p (2 sign(w_e) v_e) - K_d (omega - omega_c)

until the next sample (zero-order hold). ``2 sign(w_e) v_e`` is the rotation vector of the error for
small angles and picks the short way round (Wie, "Space Vehicle Dynamics and Control", 2nd ed.,
sec. 7.3: quaternion-feedback regulator). Gains are per body axis.
"""

from __future__ import annotations

from numba import njit

from shell.model import InputPort, Model, ModelError, OutputPort, Parameter, State, named_offsets
from shell.registry import register_model

PARAMETERS = (
    Parameter("kp", "N*m/rad", (1.0, 1.0, 1.0), (3,), (0.0, None), "proportional gain per axis"),
    Parameter("kd", "N*m*s/rad", (1.0, 1.0, 1.0), (3,), (0.0, None), "derivative gain per axis"),
    Parameter("attitude_command", "", (1.0, 0.0, 0.0, 0.0), (4,), (-1.0, 1.0),
              "commanded quaternion [w, x, y, z], command frame -> world"),
    Parameter("angular_velocity_command", "rad/s", (0.0, 0.0, 0.0), (3,), None,
              "commanded angular velocity, node axes"),
)
INPUTS = (
    InputPort("attitude", "", (4,), "measured quaternion [w, x, y, z], node -> world"),
    InputPort("angular_velocity", "rad/s", (3,), "measured angular velocity, node axes"),
)
OUTPUTS = (OutputPort("torque", "N*m", (3,), "commanded torque, node axes (held between samples)"),)
DISCRETE = (State("torque", "N*m", (3,), None, "held torque command"),)
P, U, Y, Z = (named_offsets(d) for d in (PARAMETERS, INPUTS, OUTPUTS, DISCRETE))


@njit(cache=True)
def _held_torque(t, x, z, u, p, y):
    for i in range(3):
        y[Y.torque + i] = z[Z.torque + i]


@njit(cache=True)
def _pd_update(t, x, z, u, p):
    q, c = U.attitude, P.attitude_command
    qw, qx, qy, qz = u[q], u[q + 1], u[q + 2], u[q + 3]
    cw, cx, cy, cz = p[c], -p[c + 1], -p[c + 2], -p[c + 3]  # conjugate of the command
    ew = cw * qw - cx * qx - cy * qy - cz * qz
    ex = cw * qx + cx * qw + cy * qz - cz * qy
    ey = cw * qy - cx * qz + cy * qw + cz * qx
    ez = cw * qz + cx * qy - cy * qx + cz * qw
    sign = 1.0 if ew >= 0.0 else -1.0
    error = (2.0 * sign * ex, 2.0 * sign * ey, 2.0 * sign * ez)
    for i in range(3):
        z[Z.torque + i] = (-p[P.kp + i] * error[i]
                           - p[P.kd + i] * (u[U.angular_velocity + i] - p[P.angular_velocity_command + i]))


@register_model
class PdAttitudeController(Model):
    """Sampled quaternion-feedback PD attitude controller; attach it to a node of the engine."""

    summary = "sampled PD attitude controller: attitude, angular_velocity in, torque out (held)"
    parameters = PARAMETERS
    inputs = INPUTS
    outputs = OUTPUTS
    discrete_states = DISCRETE
    offsets = {"p": P, "u": U, "y": Y, "z": Z}
    default_period = "0.1 s"
    state_outputs = staticmethod(_held_torque)
    update = staticmethod(_pd_update)

    def configure(self):
        command = self.parameter("attitude_command")
        norm = float((command ** 2).sum() ** 0.5)
        if abs(norm - 1.0) > 1e-9:
            raise ModelError(f"model {self.path}: parameter attitude_command: expected a unit quaternion "
                             f"[w, x, y, z], given norm {norm:.12g}")
