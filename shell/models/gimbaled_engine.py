"""Gimbal actuator for an engine body on a two-axis gimbal (U-joint) of the engine.

The engine is a body of the multibody engine (its own mass, inertia and center-of-mass offset) on a
``ujoint`` hinge at the airframe's gimbal point; its thrust is a :class:`shell.models.thruster.Thruster`
(``proportional``) at a node on the nozzle axis. This model drives the two gimbal angles, with the
two cases of TM-2020-5008164 App. F.4 (config ``mode``):

* ``prescribed`` -- ideal actuator, load-torque feedback open (K_LT = 0): declare the hinge
  ``prescribed: true``; the model integrates a second-order servo reference
  ``delta_dd = w^2 (sat(delta_c) - delta) - 2 zeta w delta_d`` with the rate held within
  ``max_rate`` (no acceleration beyond it) and the command clipped to ``max_angle``, and outputs that
  acceleration as the hinge's ``prescribed_accel``. The engine follows it whatever the load, and the
  airframe reacts with the inverse-dynamics hinge force the engine computes.
* ``torque`` -- actuator torque with the load-torque feedback closed (K_LT = 1): the hinge is free
  and the model outputs the servo torque ``tau = K_p (sat(delta_c) - delta) - K_d delta_d``; the
  engine's equations of motion then contain the load torque exactly (I_gim delta_dd = tau_act +
  tau_load, TM eq. of Fig. F.4.1), so with zero gains the gimbal is a frictionless bearing.

Attach to the engine body's hinge: ``attach: {hinge: engine}`` (binds q, u and the output).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from shell.model import InputPort, Model, ModelError, OutputPort, Parameter, State
from shell.registry import register_model

# p = [natural_frequency, damping_ratio, max_angle, max_rate, kp, kd]


@njit(cache=True)
def _reference_acceleration(x, u, p, out):
    w, zeta, max_angle, max_rate = p[0], p[1], p[2], p[3]
    for i in range(2):
        command = min(max(u[i], -max_angle), max_angle)
        acc = w * w * (command - x[i]) - 2.0 * zeta * w * x[2 + i]
        if (x[2 + i] >= max_rate and acc > 0.0) or (x[2 + i] <= -max_rate and acc < 0.0):
            acc = 0.0
        out[i] = acc


@njit(cache=True)
def _prescribed_outputs(t, x, z, u, p, y):
    # u = [angle_command (2), q (2), u (2)]; y = [prescribed_accel (2)]
    _reference_acceleration(x, u, p, y)


@njit(cache=True)
def _reference_derivatives(t, x, z, u, p, xdot):
    xdot[0] = x[2]
    xdot[1] = x[3]
    _reference_acceleration(x, u, p, xdot[2:4])


@njit(cache=True)
def _servo_torque(t, x, z, u, p, y):
    # u = [angle_command (2), q (2), u (2)]
    for i in range(2):
        command = min(max(u[i], -p[2]), p[2])
        y[i] = p[4] * (command - u[2 + i]) - p[5] * u[4 + i]


@register_model
class GimbalActuator(Model):
    """Two-axis engine gimbal: prescribed servo reference or servo torque (config: mode)."""

    summary = "engine gimbal actuator on a ujoint hinge: prescribed (K_LT = 0) or torque (K_LT = 1) mode"
    parameters = (
        Parameter("natural_frequency", "rad/s", 30.0, (), (0.0, None), "prescribed mode: servo bandwidth"),
        Parameter("damping_ratio", "", 0.7, (), (0.0, None), "prescribed mode: servo damping"),
        Parameter("max_angle", "rad", np.radians(6.0), (), (0.0, None), "gimbal angle limit"),
        Parameter("max_rate", "rad/s", np.radians(20.0), (), (0.0, None), "prescribed mode: gimbal rate limit"),
        Parameter("kp", "N*m/rad", 0.0, (), (0.0, None), "torque mode: servo stiffness"),
        Parameter("kd", "N*m*s/rad", 0.0, (), (0.0, None), "torque mode: servo damping"),
    )

    def __init__(self, name: str, *, mode: str = "prescribed", **kwargs):
        if mode not in ("prescribed", "torque"):
            raise ModelError(f"model {name}: config mode: expected 'prescribed' or 'torque', given {mode!r}")
        self.mode = mode
        super().__init__(name, **kwargs)

    def declare(self):
        self.inputs = (
            InputPort("angle_command", "rad", (2,), "commanded gimbal angles", feedthrough=True),
            InputPort("q", "rad", (2,), "gimbal angles (the hinge)", feedthrough=True),
            InputPort("u", "rad/s", (2,), "gimbal rates (the hinge)", feedthrough=True),
        )
        if self.mode == "prescribed":
            self.outputs = (OutputPort("prescribed_accel", "rad/s^2", (2,), "gimbal accelerations", feedthrough=True),)
            self.continuous_states = (State("reference", "", (4,), None, "servo reference: angles, rates"),)
            self.feedthrough_outputs = staticmethod(_prescribed_outputs)
            self.derivatives = staticmethod(_reference_derivatives)
        else:
            self.outputs = (OutputPort("torque", "N*m", (2,), "actuator torque about the gimbal axes",
                                       feedthrough=True),)
            self.feedthrough_outputs = staticmethod(_servo_torque)
