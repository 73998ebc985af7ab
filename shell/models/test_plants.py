"""Test plants with analytic solutions, for verifying the framework (events, failures, multi-rate).

BouncingBall: h' = v, v' = -g; zero crossing g(h) = h falling; at contact v <- -e v. Contact times
from the free-fall solution: t_1 = (v0 + sqrt(v0^2 + 2 g h0)) / g, then each flight lasts
2 e^k v_1 / g with v_1 = sqrt(v0^2 + 2 g h0) the impact speed.

FiniteEscape: x' = x^2, x(0) = x0 > 0 has x(t) = x0 / (1 - x0 t), which escapes to infinity at
t = 1 / x0 (a model that produces a non-finite state, to test that runs stop and name it).
"""

from __future__ import annotations

from numba import njit

from shell.model import Model, OutputPort, Parameter, State, ZeroCrossing
from shell.registry import register_model


@njit(cache=True)
def _ball_outputs(t, x, z, u, p, y):
    y[0] = x[0]
    y[1] = x[1]


@njit(cache=True)
def _ball_derivatives(t, x, z, u, p, xdot):
    xdot[0] = x[1]
    xdot[1] = -p[0]


@njit(cache=True)
def _ball_height(t, x, z, u, p, g):
    g[0] = x[0]


@register_model
class BouncingBall(Model):
    """Point mass in uniform gravity bouncing on the plane h = 0 with restitution e."""

    summary = "falling mass bouncing on h = 0 (event test plant)"
    parameters = (
        Parameter("gravity", "m/s^2", 9.81, (), (0.0, None), "gravitational acceleration"),
        Parameter("restitution", "", 0.8, (), (0.0, 1.0), "coefficient of restitution e"),
    )
    outputs = (OutputPort("height", "m", (), "height above the ground"),
               OutputPort("velocity", "m/s", (), "vertical velocity (up positive)"))
    continuous_states = (State("height", "m", (), 10.0, "height above the ground"),
                         State("velocity", "m/s", (), 0.0, "vertical velocity"))
    discrete_states = (State("bounces", "", (), 0.0, "number of contacts so far"),)
    zero_crossings = (ZeroCrossing("ground_contact", direction=-1, description="height reaches zero falling"),)
    state_outputs = staticmethod(_ball_outputs)
    derivatives = staticmethod(_ball_derivatives)
    zero_crossing_values = staticmethod(_ball_height)

    def on_event(self, index, t, x, z, p):
        x[0] = 0.0
        x[1] = -p[1] * x[1]
        z[0] += 1.0


@njit(cache=True)
def _escape_outputs(t, x, z, u, p, y):
    y[0] = x[0]


@njit(cache=True)
def _escape_derivatives(t, x, z, u, p, xdot):
    xdot[0] = x[0] * x[0]


@register_model
class FiniteEscape(Model):
    """x' = x^2: escapes to infinity at t = 1/x0 (failure-handling test plant)."""

    summary = "x' = x^2, blows up at t = 1/x0 (failure test plant)"
    outputs = (OutputPort("x", "", (), "the escaping state"),)
    continuous_states = (State("x", "", (), 1.0, "state"),)
    state_outputs = staticmethod(_escape_outputs)
    derivatives = staticmethod(_escape_derivatives)
