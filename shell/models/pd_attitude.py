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

from shell.attitude import error_rotation_vector
from shell.model import Declarations, Model, Parameter
from shell.ports import COMMANDED_TORQUE, HELD_TORQUE, MEASURED_ATTITUDE_AND_RATE
from shell.registry import register_model

PARAMETERS = (
    Parameter("kp", "N*m/rad", (1.0, 1.0, 1.0), (3,), (0.0, None), "proportional gain per axis"),
    Parameter("kd", "N*m*s/rad", (1.0, 1.0, 1.0), (3,), (0.0, None), "derivative gain per axis"),
    Parameter("attitude_command", "", (1.0, 0.0, 0.0, 0.0), (4,), (-1.0, 1.0),
              "commanded quaternion [w, x, y, z], command frame -> world"),
    Parameter("angular_velocity_command", "rad/s", (0.0, 0.0, 0.0), (3,), None,
              "commanded angular velocity, node axes"),
)
INPUTS = MEASURED_ATTITUDE_AND_RATE
OUTPUTS = COMMANDED_TORQUE
DISCRETE = (HELD_TORQUE,)
PD = Declarations(parameters=PARAMETERS, inputs=INPUTS, outputs=OUTPUTS, discrete=DISCRETE)
P, U, Y, Z = PD.P, PD.U, PD.Y, PD.Z


@njit(cache=True)
def _held_torque(t, x, z, u, p, y):
    for i in range(3):
        y[Y.torque + i] = z[Z.torque + i]


@njit(cache=True)
def _pd_update(t, x, z, u, p):
    q, c = U.attitude, P.attitude_command
    error = error_rotation_vector((p[c], p[c + 1], p[c + 2], p[c + 3]), (u[q], u[q + 1], u[q + 2], u[q + 3]))
    for i in range(3):
        z[Z.torque + i] = (-p[P.kp + i] * error[i]
                           - p[P.kd + i] * (u[U.angular_velocity + i] - p[P.angular_velocity_command + i]))


@register_model
class PdAttitudeController(Model):
    """Sampled quaternion-feedback PD attitude controller; attach it to a node of the engine."""

    summary = "sampled PD attitude controller: attitude, angular_velocity in, torque out (held)"
    declarations = PD
    default_period = "0.1 s"
    state_outputs = staticmethod(_held_torque)
    update = staticmethod(_pd_update)

    def configure(self):
        self.require_unit_norm("attitude_command")
