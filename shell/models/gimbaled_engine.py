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

from shell.model import Declarations, InputPort, Layout, Model, ModelError, OutputPort, Parameter, State, named_offsets
from shell.registry import register_model

PARAMETERS = (
    Parameter("natural_frequency", "rad/s", 30.0, (), (0.0, None), "prescribed mode: servo bandwidth"),
    Parameter("damping_ratio", "", 0.7, (), (0.0, None), "prescribed mode: servo damping"),
    Parameter("max_angle", "rad", np.radians(6.0), (), (0.0, None), "gimbal angle limit"),
    Parameter("max_rate", "rad/s", np.radians(20.0), (), (0.0, None), "prescribed mode: gimbal rate limit"),
    Parameter("kp", "N*m/rad", 0.0, (), (0.0, None), "torque mode: servo stiffness"),
    Parameter("kd", "N*m*s/rad", 0.0, (), (0.0, None), "torque mode: servo damping"),
)
INPUTS = (
    InputPort("angle_command", "rad", (2,), "commanded gimbal angles", feedthrough=True),
    InputPort("q", "rad", (2,), "gimbal angles (the hinge)", feedthrough=True),
    InputPort("u", "rad/s", (2,), "gimbal rates (the hinge)", feedthrough=True),
)
PRESCRIBED_OUTPUTS = (OutputPort("prescribed_accel", "rad/s^2", (2,), "gimbal accelerations", feedthrough=True),)
TORQUE_OUTPUTS = (OutputPort("torque", "N*m", (2,), "actuator torque about the gimbal axes", feedthrough=True),)
#: the parts of the servo-reference state (one state ``reference``, its name kept for logs and restarts)
REFERENCE_PARTS = (State("angle", "rad", (2,), None, "servo reference angles"),
                   State("rate", "rad/s", (2,), None, "servo reference rates"))
PRESCRIBED_CONTINUOUS = (State("reference", "", (Layout.of(REFERENCE_PARTS).size,), None,
                               "servo reference: angles, rates"),)
#: the two modes (config: mode): a servo reference the hinge follows, or a servo torque on the hinge
PRESCRIBED = Declarations(parameters=PARAMETERS, inputs=INPUTS, outputs=PRESCRIBED_OUTPUTS,
                          continuous=PRESCRIBED_CONTINUOUS)
TORQUE = Declarations(parameters=PARAMETERS, inputs=INPUTS, outputs=TORQUE_OUTPUTS)
P, U, Y_PRESCRIBED, X, Y_TORQUE = PRESCRIBED.P, PRESCRIBED.U, PRESCRIBED.Y, PRESCRIBED.X, TORQUE.Y
REFERENCE = named_offsets(REFERENCE_PARTS)
ANGLE, RATE = X.reference + REFERENCE.angle, X.reference + REFERENCE.rate


@njit(cache=True)
def _reference_acceleration(t, x, z, u, p, out, start):
    """Servo reference acceleration of both axes into out[start:start + 2]."""
    w, zeta, max_angle, max_rate = p[P.natural_frequency], p[P.damping_ratio], p[P.max_angle], p[P.max_rate]
    for i in range(2):
        command = min(max(u[U.angle_command + i], -max_angle), max_angle)
        rate = x[RATE + i]
        acc = w * w * (command - x[ANGLE + i]) - 2.0 * zeta * w * rate
        if (rate >= max_rate and acc > 0.0) or (rate <= -max_rate and acc < 0.0):
            acc = 0.0
        out[start + i] = acc


@njit(cache=True)
def _prescribed_outputs(t, x, z, u, p, y):
    _reference_acceleration(t, x, z, u, p, y, Y_PRESCRIBED.prescribed_accel)


@njit(cache=True)
def _reference_derivatives(t, x, z, u, p, xdot):
    for i in range(2):
        xdot[ANGLE + i] = x[RATE + i]
    _reference_acceleration(t, x, z, u, p, xdot, RATE)


@njit(cache=True)
def _servo_torque(t, x, z, u, p, y):
    for i in range(2):
        command = min(max(u[U.angle_command + i], -p[P.max_angle]), p[P.max_angle])
        y[Y_TORQUE.torque + i] = p[P.kp] * (command - u[U.q + i]) - p[P.kd] * u[U.u + i]


@register_model
class GimbalActuator(Model):
    """Two-axis engine gimbal: prescribed servo reference or servo torque (config: mode)."""

    summary = "engine gimbal actuator on a ujoint hinge: prescribed (K_LT = 0) or torque (K_LT = 1) mode"
    declarations = PRESCRIBED

    def __init__(self, name: str, *, mode: str = "prescribed", **kwargs):
        if mode not in ("prescribed", "torque"):
            raise ModelError(f"model {name}: config mode: expected 'prescribed' or 'torque', given {mode!r}")
        self.mode = mode
        super().__init__(name, **kwargs)

    def declare(self):
        if self.mode == "prescribed":
            self.feedthrough_outputs = _prescribed_outputs
            self.derivatives = _reference_derivatives
        else:
            self.use_declarations(TORQUE)
            self.feedthrough_outputs = _servo_torque
            self.offsets = TORQUE.offsets
