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

from shell.model import InputPort, Model, OutputPort, Parameter, State
from shell.registry import register_model


@njit(cache=True)
def _held_torque(t, x, z, u, p, y):
    y[0] = z[0]
    y[1] = z[1]
    y[2] = z[2]


@njit(cache=True)
def _pd_update(t, x, z, u, p):
    # u = [q (4), omega (3)]; p = [kp (3), kd (3), q_c (4), omega_c (3)]
    qw, qx, qy, qz = u[0], u[1], u[2], u[3]
    cw, cx, cy, cz = p[6], -p[7], -p[8], -p[9]  # conjugate of the command
    ew = cw * qw - cx * qx - cy * qy - cz * qz
    ex = cw * qx + cx * qw + cy * qz - cz * qy
    ey = cw * qy - cx * qz + cy * qw + cz * qx
    ez = cw * qz + cx * qy - cy * qx + cz * qw
    sign = 1.0 if ew >= 0.0 else -1.0
    error = (2.0 * sign * ex, 2.0 * sign * ey, 2.0 * sign * ez)
    for i in range(3):
        z[i] = -p[i] * error[i] - p[3 + i] * (u[4 + i] - p[10 + i])


@register_model
class PdAttitudeController(Model):
    """Sampled quaternion-feedback PD attitude controller; attach it to a node of the engine."""

    summary = "sampled PD attitude controller: attitude, angular_velocity in, torque out (held)"
    parameters = (
        Parameter("kp", "N*m/rad", (1.0, 1.0, 1.0), (3,), (0.0, None), "proportional gain per axis"),
        Parameter("kd", "N*m*s/rad", (1.0, 1.0, 1.0), (3,), (0.0, None), "derivative gain per axis"),
        Parameter("attitude_command", "", (1.0, 0.0, 0.0, 0.0), (4,), (-1.0, 1.0),
                  "commanded quaternion [w, x, y, z], command frame -> world"),
        Parameter("angular_velocity_command", "rad/s", (0.0, 0.0, 0.0), (3,), None,
                  "commanded angular velocity, node axes"),
    )
    inputs = (
        InputPort("attitude", "", (4,), "measured quaternion [w, x, y, z], node -> world"),
        InputPort("angular_velocity", "rad/s", (3,), "measured angular velocity, node axes"),
    )
    outputs = (OutputPort("torque", "N*m", (3,), "commanded torque, node axes (held between samples)"),)
    discrete_states = (State("torque", "N*m", (3,), None, "held torque command"),)
    default_period = "0.1 s"
    state_outputs = staticmethod(_held_torque)
    update = staticmethod(_pd_update)

    def configure(self):
        command = self.parameter("attitude_command")
        norm = float((command ** 2).sum() ** 0.5)
        if abs(norm - 1.0) > 1e-9:
            from shell.model import ModelError

            raise ModelError(f"model {self.path}: parameter attitude_command: expected a unit quaternion "
                             f"[w, x, y, z], given norm {norm:.12g}")
