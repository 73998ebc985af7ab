"""Reaction wheel at a node: motor torque with limits, friction, imbalance jitter, wheel speed.

Momentum representation (the wheel is a state of this model, the bus a body of the engine): the wheel's
absolute spin momentum ``h = J_w (a . omega + Omega)`` about its unit spin axis ``a`` (node axes) obeys

    dh/dt = tau_m - tau_f(Omega),        tau_f = c tanh(Omega / Omega_s) + b Omega     (Coulomb + viscous)

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
"""

from __future__ import annotations

import numpy as np
from numba import njit

from shell.model import InputPort, Model, ModelError, OutputPort, Parameter, State
from shell.registry import register_model

# p = [axis (3), spin_inertia, max_torque, max_speed, coulomb, smoothing speed, viscous, U_s, U_d]


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
    """Relative spin speed Omega = h / J_w - a . omega (u[1:4] the node angular velocity)."""
    return x[0] / p[3] - (p[0] * u[1] + p[1] * u[2] + p[2] * u[3])


@njit(cache=True)
def motor_torque(command, speed, p):
    tau = min(max(command, -p[4]), p[4])
    if (speed >= p[5] and tau > 0.0) or (speed <= -p[5] and tau < 0.0):
        tau = 0.0
    return tau


@njit(cache=True)
def friction_torque(speed, p):
    return p[6] * np.tanh(speed / p[7]) + p[8] * speed


@njit(cache=True)
def _wheel_loads(t, x, z, u, p, y):
    # u = [torque_command, angular_velocity (3)]; y = [torque (3), force (3), speed, motor torque]
    speed = wheel_speed(x, u, p)
    tau_m = motor_torque(u[0], speed, p)
    net = tau_m - friction_torque(speed, p)
    h = x[0]
    a0, a1, a2 = p[0], p[1], p[2]
    w0, w1, w2 = u[1], u[2], u[3]
    e1, e2 = perpendicular_basis(a0, a1, a2)
    c, s = np.cos(x[1]), np.sin(x[1])
    s2 = speed * speed
    y[0] = -net * a0 - h * (w1 * a2 - w2 * a1)
    y[1] = -net * a1 - h * (w2 * a0 - w0 * a2)
    y[2] = -net * a2 - h * (w0 * a1 - w1 * a0)
    for i, (b1, b2) in enumerate(((e1[0], e2[0]), (e1[1], e2[1]), (e1[2], e2[2]))):
        direction = c * b1 + s * b2
        y[i] += p[10] * s2 * direction
        y[3 + i] = p[9] * s2 * direction
    y[6] = speed
    y[7] = tau_m


@njit(cache=True)
def _wheel_derivatives(t, x, z, u, p, xdot):
    speed = wheel_speed(x, u, p)
    xdot[0] = motor_torque(u[0], speed, p) - friction_torque(speed, p)
    xdot[1] = speed


@register_model
class ReactionWheel(Model):
    """One reaction wheel at a node (momentum representation); see the module docstring."""

    summary = "reaction wheel at a node: torque command in; reaction torque, imbalance force, speed out"
    parameters = (
        Parameter("spin_axis", "", (0.0, 0.0, 1.0), (3,), (-1.0, 1.0), "unit spin axis, node axes"),
        Parameter("spin_inertia", "kg*m^2", None, (), (1e-12, None), "wheel inertia about its spin axis"),
        Parameter("max_torque", "N*m", 0.2, (), (0.0, None), "motor torque limit"),
        Parameter("max_speed", "rad/s", 6000 * np.pi / 30, (), (0.0, None), "speed limit (e.g. 6000 rpm)"),
        Parameter("coulomb_friction", "N*m", 0.0, (), (0.0, None), "Coulomb friction torque"),
        Parameter("coulomb_smoothing_speed", "rad/s", 0.1, (), (1e-9, None),
                  "speed over which the Coulomb torque reaches its level (tanh regularization)"),
        Parameter("viscous_friction", "N*m*s/rad", 0.0, (), (0.0, None), "viscous friction coefficient"),
        Parameter("static_imbalance", "kg*m", 0.0, (), (0.0, None), "static imbalance U_s (datasheet g*cm)"),
        Parameter("dynamic_imbalance", "kg*m^2", 0.0, (), (0.0, None), "dynamic imbalance U_d (g*cm^2)"),
    )
    inputs = (
        InputPort("torque_command", "N*m", (), "commanded motor torque about the spin axis", feedthrough=True),
        InputPort("angular_velocity", "rad/s", (3,), "inertial angular velocity of the node, node axes",
                  feedthrough=True),
    )
    outputs = (
        OutputPort("torque", "N*m", (3,), "torque on the node: reaction, gyroscopic, dynamic imbalance",
                   feedthrough=True),
        OutputPort("force", "N", (3,), "static-imbalance force on the node", feedthrough=True),
        OutputPort("wheel_speed", "rad/s", (), "spin speed relative to the node", feedthrough=True),
        OutputPort("motor_torque", "N*m", (), "applied motor torque after limits", feedthrough=True),
    )
    continuous_states = (
        State("momentum", "N*m*s", (), 0.0, "absolute spin momentum J_w (a . omega + Omega)"),
        State("angle", "rad", (), 0.0, "wheel angle relative to the node (imbalance phase)"),
    )
    feedthrough_outputs = staticmethod(_wheel_loads)
    derivatives = staticmethod(_wheel_derivatives)

    def configure(self):
        axis = self.parameter("spin_axis")
        norm = float(np.sqrt(axis @ axis))
        if abs(norm - 1.0) > 1e-9:
            raise ModelError(f"model {self.path}: parameter spin_axis: expected a unit vector, given norm {norm:.12g}")


@njit(cache=True)
def _motor_torque(t, x, z, u, p, y):
    # u = [torque_command, hinge rate (1)]; p = [max_torque, max_speed, coulomb, smoothing, viscous]
    speed = u[1]
    tau = min(max(u[0], -p[0]), p[0])
    if (speed >= p[1] and tau > 0.0) or (speed <= -p[1] and tau < 0.0):
        tau = 0.0
    y[0] = tau - (p[2] * np.tanh(speed / p[3]) + p[4] * speed)
    y[1] = tau


@register_model
class ReactionWheelMotor(Model):
    """Motor of a wheel body on a revolute hinge (body representation); see the module docstring."""

    summary = "reaction-wheel motor on a revolute hinge of a wheel body: limits, friction (attach: {hinge: ...})"
    parameters = (
        Parameter("max_torque", "N*m", 0.2, (), (0.0, None), "motor torque limit"),
        Parameter("max_speed", "rad/s", 6000 * np.pi / 30, (), (0.0, None), "speed limit"),
        Parameter("coulomb_friction", "N*m", 0.0, (), (0.0, None), "Coulomb friction torque"),
        Parameter("coulomb_smoothing_speed", "rad/s", 0.1, (), (1e-9, None), "tanh regularization speed"),
        Parameter("viscous_friction", "N*m*s/rad", 0.0, (), (0.0, None), "viscous friction coefficient"),
    )
    inputs = (
        InputPort("torque_command", "N*m", (), "commanded motor torque", feedthrough=True),
        InputPort("u", "rad/s", (1,), "wheel speed relative to the bus (the hinge rate)", feedthrough=True),
    )
    outputs = (
        OutputPort("torque", "N*m", (1,), "hinge torque: motor minus friction", feedthrough=True),
        OutputPort("motor_torque", "N*m", (), "applied motor torque after limits", feedthrough=True),
    )
    feedthrough_outputs = staticmethod(_motor_torque)
