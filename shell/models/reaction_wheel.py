"""Reaction wheel at a node: motor torque with limits, friction, imbalance jitter, wheel speed.

Momentum representation (the wheel is a state of this model, the bus a body of the engine): the wheel's
absolute spin momentum ``h = J_w (a . omega + Omega)`` about its unit spin axis ``a`` (node axes) obeys

    dh/dt = tau_m - tau_f(Omega),
    tau_f = [c + s exp(-(Omega / Omega_st)^2)] tanh(Omega / Omega_s) + b Omega

(Coulomb c, viscous b and the Stribeck excess s of the breakaway torque c + s over the Coulomb
level, decaying over the Stribeck speed Omega_st: Armstrong-Helouvry, Dupont and Canudas de Wit,
Automatica 30(7), 1994, eq. 4; the sign function regularized by tanh over Omega_s)

and the wheel acts on the node with the torque ``-(tau_m - tau_f) a - omega x (h a)``: the reaction of
the motor and the gyroscopic coupling of the stored momentum. With the bus inertia in the engine
*excluding the wheel's spin inertia J_w a a^T* (the wheel's mass and transverse inertia stay in the
bus), the pair conserves ``R (J_B omega + h a)`` exactly (Wie, "Space Vehicle Dynamics and Control",
2nd ed., sec. 7.5; SSSIM's reaction-wheel model). Nothing reads the bus's acceleration, so there is
no algebraic loop.

The motor torque is the command clipped to ``max_torque``, and set to zero when the wheel is at
``max_speed`` and the command would spin it faster (a speed limiter).

Body representation (``ReactionWheelMotor``): the wheel is a body of the engine on a revolute hinge
(its full inertia in the engine, the bus's without it), and this model is its motor: attached to the
hinge (``attach: {hinge: <wheel body>}``) it reads the relative speed and applies the same limited
motor torque minus friction as the hinge torque. The engine then carries the gyroscopic coupling, and
imbalance is exact geometry: a wheel COM offset r (U_s = m r) and a product of inertia (U_d).

Imbalance (Masterson, Miller and Grogan, J. Sound Vib. 2002, the standard RWA disturbance model):
a static imbalance ``U_s`` (kg m) gives the radial force ``U_s Omega^2 e(theta)`` and a dynamic
imbalance ``U_d`` (kg m^2) the rocking torque ``U_d Omega^2 e(theta)``, both rotating with the wheel
angle theta (``e(theta) = cos theta e1 + sin theta e2``, e1, e2 perpendicular to a); the force acts
at the node (give each wheel its own node at its mounting point to get the lever arm exactly).

Outputs: ``torque``, ``force`` (node axes), ``wheel_speed`` Omega, ``motor_torque``, and ``spin_momentum``
``h a`` (node axes), the vector a controller's gyroscopic term needs (Basilisk's mrpFeedback forms the
same ``sum_k J_k (a_k . omega + Omega_k) a_k`` from its wheel speeds); sum it over the wheels with a
``Sum`` block into ``MrpFeedback.wheel_momentum``.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from shell.model import Declarations, InputPort, Model, OutputPort, Parameter, State
from shell.ports import node_inputs, node_load_outputs
from shell.registry import register_model

WHEEL_PARAMETERS = (
    Parameter("spin_axis", "", (0.0, 0.0, 1.0), (3,), (-1.0, 1.0), "unit spin axis, node axes"),
    Parameter("spin_inertia", "kg*m^2", None, (), (1e-12, None), "wheel inertia about its spin axis"),
    Parameter("max_torque", "N*m", 0.2, (), (0.0, None), "motor torque limit"),
    Parameter("max_speed", "rad/s", 6000 * np.pi / 30, (), (0.0, None), "speed limit (e.g. 6000 rpm)"),
    Parameter("coulomb_friction", "N*m", 0.0, (), (0.0, None), "Coulomb friction torque"),
    Parameter("coulomb_smoothing_speed", "rad/s", 0.1, (), (1e-9, None),
              "speed over which the Coulomb torque reaches its level (tanh regularization)"),
    Parameter("viscous_friction", "N*m*s/rad", 0.0, (), (0.0, None), "viscous friction coefficient"),
    Parameter("stribeck_friction", "N*m", 0.0, (), (0.0, None),
              "Stribeck excess: breakaway torque minus Coulomb torque (0: no Stribeck effect)"),
    Parameter("stribeck_speed", "rad/s", 1.0, (), (1e-9, None), "speed over which the Stribeck excess decays"),
    Parameter("static_imbalance", "kg*m", 0.0, (), (0.0, None), "static imbalance U_s (datasheet g*cm)"),
    Parameter("dynamic_imbalance", "kg*m^2", 0.0, (), (0.0, None), "dynamic imbalance U_d (g*cm^2)"),
)
WHEEL_INPUTS = (
    InputPort("torque_command", "N*m", (), "commanded motor torque about the spin axis", feedthrough=True),
    *node_inputs("angular_velocity", feedthrough=True,
                 angular_velocity="inertial angular velocity of the node, node axes"),
)
WHEEL_OUTPUTS = (
    *node_load_outputs("torque", "force", torque="torque on the node: reaction, gyroscopic, dynamic imbalance",
                       force="static-imbalance force on the node"),
    OutputPort("wheel_speed", "rad/s", (), "spin speed relative to the node", feedthrough=True),
    OutputPort("motor_torque", "N*m", (), "applied motor torque after limits", feedthrough=True),
    OutputPort("spin_momentum", "N*m*s", (3,), "spin momentum vector h a = J_w (a . omega + Omega) a, node axes "
               "(summed over the wheels: MrpFeedback.wheel_momentum)", feedthrough=True),
)
WHEEL_CONTINUOUS = (
    State("momentum", "N*m*s", (), 0.0, "absolute spin momentum J_w (a . omega + Omega)"),
    State("angle", "rad", (), 0.0, "wheel angle relative to the node (imbalance phase)"),
)
WHEEL = Declarations(parameters=WHEEL_PARAMETERS, inputs=WHEEL_INPUTS, outputs=WHEEL_OUTPUTS,
                     continuous=WHEEL_CONTINUOUS)
P_WHEEL, U_WHEEL, Y_WHEEL, X_WHEEL = WHEEL.P, WHEEL.U, WHEEL.Y, WHEEL.X


@njit(cache=True)
def perpendicular_basis(a0, a1, a2):
    """Two unit vectors e1, e2 (as tuples, no allocation) with (e1, e2, a) right-handed."""
    h0, h1 = (1.0, 0.0) if abs(a0) < 0.9 else (0.0, 1.0)
    # e2 = a x h (h = (h0, h1, 0)), normalized; e1 = e2 x a
    x, y, z = -a2 * h1, a2 * h0, a0 * h1 - a1 * h0
    n = np.sqrt(x * x + y * y + z * z)
    x, y, z = x / n, y / n, z / n
    return (y * a2 - z * a1, z * a0 - x * a2, x * a1 - y * a0), (x, y, z)


@njit(cache=True)
def wheel_speed(x, u, p):
    """Relative spin speed Omega = h / J_w - a . omega."""
    P, U, a, w = P_WHEEL, U_WHEEL, P_WHEEL.spin_axis, U_WHEEL.angular_velocity
    return x[X_WHEEL.momentum] / p[P.spin_inertia] - (p[a] * u[w] + p[a + 1] * u[w + 1] + p[a + 2] * u[w + 2])


@njit(cache=True)
def motor_torque(command, speed, max_torque, max_speed):
    """The command clipped to max_torque, zero when it would spin the wheel beyond max_speed."""
    tau = min(max(command, -max_torque), max_torque)
    if (speed >= max_speed and tau > 0.0) or (speed <= -max_speed and tau < 0.0):
        tau = 0.0
    return tau


@njit(cache=True)
def friction_torque(speed, coulomb, smoothing_speed, viscous, stribeck=0.0, stribeck_speed=1.0):
    """Coulomb + Stribeck + viscous friction torque (module docstring); stribeck = 0: the exact
    Coulomb + viscous value."""
    level = coulomb
    if stribeck > 0.0:
        ratio = speed / stribeck_speed
        level = coulomb + stribeck * np.exp(-ratio * ratio)
    return level * np.tanh(speed / smoothing_speed) + viscous * speed


@njit(cache=True)
def _wheel_motor_torque(x, u, p, speed):
    return motor_torque(u[U_WHEEL.torque_command], speed, p[P_WHEEL.max_torque], p[P_WHEEL.max_speed])


@njit(cache=True)
def _wheel_friction(p, speed):
    return friction_torque(speed, p[P_WHEEL.coulomb_friction], p[P_WHEEL.coulomb_smoothing_speed],
                           p[P_WHEEL.viscous_friction], p[P_WHEEL.stribeck_friction], p[P_WHEEL.stribeck_speed])


@njit(cache=True)
def _wheel_loads(t, x, z, u, p, y):
    P, U, Y = P_WHEEL, U_WHEEL, Y_WHEEL
    speed = wheel_speed(x, u, p)
    tau_m = _wheel_motor_torque(x, u, p, speed)
    net = tau_m - _wheel_friction(p, speed)
    h = x[X_WHEEL.momentum]
    a0, a1, a2 = p[P.spin_axis], p[P.spin_axis + 1], p[P.spin_axis + 2]
    w0, w1, w2 = u[U.angular_velocity], u[U.angular_velocity + 1], u[U.angular_velocity + 2]
    e1, e2 = perpendicular_basis(a0, a1, a2)
    c, s = np.cos(x[X_WHEEL.angle]), np.sin(x[X_WHEEL.angle])
    s2 = speed * speed
    y[Y.torque] = -net * a0 - h * (w1 * a2 - w2 * a1)
    y[Y.torque + 1] = -net * a1 - h * (w2 * a0 - w0 * a2)
    y[Y.torque + 2] = -net * a2 - h * (w0 * a1 - w1 * a0)
    for i, (b1, b2) in enumerate(((e1[0], e2[0]), (e1[1], e2[1]), (e1[2], e2[2]))):
        direction = c * b1 + s * b2
        y[Y.torque + i] += p[P.dynamic_imbalance] * s2 * direction
        y[Y.force + i] = p[P.static_imbalance] * s2 * direction
    y[Y.wheel_speed] = speed
    y[Y.motor_torque] = tau_m
    y[Y.spin_momentum], y[Y.spin_momentum + 1], y[Y.spin_momentum + 2] = h * a0, h * a1, h * a2


@njit(cache=True)
def _wheel_derivatives(t, x, z, u, p, xdot):
    speed = wheel_speed(x, u, p)
    xdot[X_WHEEL.momentum] = _wheel_motor_torque(x, u, p, speed) - _wheel_friction(p, speed)
    xdot[X_WHEEL.angle] = speed


@register_model
class ReactionWheel(Model):
    """One reaction wheel at a node (momentum representation); see the module docstring."""

    summary = "reaction wheel at a node: torque command in; reaction torque, imbalance force, speed out"
    declarations = WHEEL
    feedthrough_outputs = staticmethod(_wheel_loads)
    derivatives = staticmethod(_wheel_derivatives)

    def configure(self):
        self.require_unit_norm("spin_axis")


MOTOR_PARAMETERS = (
    Parameter("max_torque", "N*m", 0.2, (), (0.0, None), "motor torque limit"),
    Parameter("max_speed", "rad/s", 6000 * np.pi / 30, (), (0.0, None), "speed limit"),
    Parameter("coulomb_friction", "N*m", 0.0, (), (0.0, None), "Coulomb friction torque"),
    Parameter("coulomb_smoothing_speed", "rad/s", 0.1, (), (1e-9, None), "tanh regularization speed"),
    Parameter("viscous_friction", "N*m*s/rad", 0.0, (), (0.0, None), "viscous friction coefficient"),
    Parameter("stribeck_friction", "N*m", 0.0, (), (0.0, None), "Stribeck excess over the Coulomb torque"),
    Parameter("stribeck_speed", "rad/s", 1.0, (), (1e-9, None), "speed over which the Stribeck excess decays"),
)
MOTOR_INPUTS = (
    InputPort("torque_command", "N*m", (), "commanded motor torque", feedthrough=True),
    InputPort("u", "rad/s", (1,), "wheel speed relative to the bus (the hinge rate)", feedthrough=True),
)
MOTOR_OUTPUTS = (
    OutputPort("torque", "N*m", (1,), "hinge torque: motor minus friction", feedthrough=True),
    OutputPort("motor_torque", "N*m", (), "applied motor torque after limits", feedthrough=True),
)
MOTOR = Declarations(parameters=MOTOR_PARAMETERS, inputs=MOTOR_INPUTS, outputs=MOTOR_OUTPUTS)
P_MOTOR, U_MOTOR, Y_MOTOR = MOTOR.P, MOTOR.U, MOTOR.Y


@njit(cache=True)
def _motor_torque(t, x, z, u, p, y):
    P = P_MOTOR
    speed = u[U_MOTOR.u]
    tau = motor_torque(u[U_MOTOR.torque_command], speed, p[P.max_torque], p[P.max_speed])
    y[Y_MOTOR.torque] = tau - friction_torque(speed, p[P.coulomb_friction], p[P.coulomb_smoothing_speed],
                                              p[P.viscous_friction], p[P.stribeck_friction], p[P.stribeck_speed])
    y[Y_MOTOR.motor_torque] = tau


@register_model
class ReactionWheelMotor(Model):
    """Motor of a wheel body on a revolute hinge (body representation); see the module docstring."""

    summary = "reaction-wheel motor on a revolute hinge of a wheel body: limits, friction (attach: {hinge: ...})"
    declarations = MOTOR
    feedthrough_outputs = staticmethod(_motor_torque)
