"""Test plants with analytic solutions, for verifying the framework (events, failures, multi-rate).

They live with the tests, not among the user's models: tests/conftest.py imports this module so that
its ``@register_model`` decorators run and YAML scenes of the tests can name ``BouncingBall`` and
``FiniteEscape``; ``flexshell models`` does not list them.

BouncingBall: h' = v, v' = -g; zero crossing g(h) = h falling; at contact v <- -e v. Contact times
from the free-fall solution: t_1 = (v0 + sqrt(v0^2 + 2 g h0)) / g, then each flight lasts
2 e^k v_1 / g with v_1 = sqrt(v0^2 + 2 g h0) the impact speed.

FiniteEscape: x' = x^2, x(0) = x0 > 0 has x(t) = x0 / (1 - x0 t), which escapes to infinity at
t = 1 / x0 (a model that produces a non-finite state, to test that runs stop and name it).

TableTracker: a first-order lag tracking a table held in the model's per-run data slot, sampled with noise (to
test data slots in the compiled loop; closed form below).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from shell.model import Model, ModelError, OutputPort, Parameter, State, ZeroCrossing, named_offsets
from shell.registry import register_model


BALL_PARAMETERS = (
    Parameter("gravity", "m/s^2", 9.81, (), (0.0, None), "gravitational acceleration"),
    Parameter("restitution", "", 0.8, (), (0.0, 1.0), "coefficient of restitution e"),
)
BALL_OUTPUTS = (OutputPort("height", "m", (), "height above the ground"),
                OutputPort("velocity", "m/s", (), "vertical velocity (up positive)"))
BALL_CONTINUOUS = (State("height", "m", (), 10.0, "height above the ground"),
                   State("velocity", "m/s", (), 0.0, "vertical velocity"))
BALL_DISCRETE = (State("bounces", "", (), 0.0, "number of contacts so far"),)
P_BALL, Y_BALL = named_offsets(BALL_PARAMETERS), named_offsets(BALL_OUTPUTS)
X_BALL, Z_BALL = named_offsets(BALL_CONTINUOUS), named_offsets(BALL_DISCRETE)


@njit(cache=True)
def _ball_outputs(t, x, z, u, p, y):
    y[Y_BALL.height] = x[X_BALL.height]
    y[Y_BALL.velocity] = x[X_BALL.velocity]


@njit(cache=True)
def _ball_derivatives(t, x, z, u, p, xdot):
    xdot[X_BALL.height] = x[X_BALL.velocity]
    xdot[X_BALL.velocity] = -p[P_BALL.gravity]


@njit(cache=True)
def _ball_height(t, x, z, u, p, g):
    g[0] = x[X_BALL.height]  # the one zero crossing, ground_contact


@register_model
class BouncingBall(Model):
    """Point mass in uniform gravity bouncing on the plane h = 0 with restitution e."""

    summary = "falling mass bouncing on h = 0 (event test plant)"
    parameters = BALL_PARAMETERS
    outputs = BALL_OUTPUTS
    continuous_states = BALL_CONTINUOUS
    discrete_states = BALL_DISCRETE
    offsets = {"p": P_BALL, "y": Y_BALL, "x": X_BALL, "z": Z_BALL}
    zero_crossings = (ZeroCrossing("ground_contact", direction=-1, description="height reaches zero falling"),)
    state_outputs = staticmethod(_ball_outputs)
    derivatives = staticmethod(_ball_derivatives)
    zero_crossing_values = staticmethod(_ball_height)

    def on_event(self, index, t, x, z, p):
        x[X_BALL.height] = 0.0
        x[X_BALL.velocity] = -p[P_BALL.restitution] * x[X_BALL.velocity]
        z[Z_BALL.bounces] += 1.0


ESCAPE_OUTPUTS = (OutputPort("x", "", (), "the escaping state"),)
ESCAPE_CONTINUOUS = (State("x", "", (), 1.0, "state"),)
Y_ESCAPE, X_ESCAPE = named_offsets(ESCAPE_OUTPUTS), named_offsets(ESCAPE_CONTINUOUS)


@njit(cache=True)
def _escape_outputs(t, x, z, u, p, y):
    y[Y_ESCAPE.x] = x[X_ESCAPE.x]


@njit(cache=True)
def _escape_derivatives(t, x, z, u, p, xdot):
    xdot[X_ESCAPE.x] = x[X_ESCAPE.x] * x[X_ESCAPE.x]


@register_model
class FiniteEscape(Model):
    """x' = x^2: escapes to infinity at t = 1/x0 (failure-handling test plant)."""

    summary = "x' = x^2, blows up at t = 1/x0 (failure test plant)"
    outputs = ESCAPE_OUTPUTS
    continuous_states = ESCAPE_CONTINUOUS
    offsets = {"y": Y_ESCAPE, "x": X_ESCAPE}
    state_outputs = staticmethod(_escape_outputs)
    derivatives = staticmethod(_escape_derivatives)


# TableTracker: x' = (r(t) - x) / tau with r(t) the piecewise-linear table of breakpoints and values held in the
# model's data slot (per-run data, shell.kernel_protocol), the interpolation weight written to a scratch entry of the
# slot at every call; sampled every ``period``, it reports x plus white noise of standard deviation sigma (noise from
# its own stream) scaled by the last weight. Closed form for a constant table value r from x(0) = 0:
# x(t) = r (1 - exp(-t / tau)).
TRACKER_PARAMETERS = (Parameter("tau", "s", 1.0, (), (1e-9, None), "time constant"),
                      Parameter("sigma", "", 0.0, (), (0.0, None), "measurement noise standard deviation"))
TRACKER_OUTPUTS = (OutputPort("x", "", (), "the tracking state"), OutputPort("measured", "", (), "the last sample"))
TRACKER_CONTINUOUS = (State("x", "", (), 0.0, "tracking state"),)
TRACKER_DISCRETE = (State("measured", "", (), 0.0, "last noisy sample"),)
P_TRACK, Y_TRACK = named_offsets(TRACKER_PARAMETERS), named_offsets(TRACKER_OUTPUTS)
X_TRACK, Z_TRACK = named_offsets(TRACKER_CONTINUOUS), named_offsets(TRACKER_DISCRETE)


@njit(cache=True)
def _table_value(t, d):
    """r(t) from the slot d = [n, times (n), values (n), scratch]; the weight of the upper point into the scratch."""
    n = int(d[0])
    k = 0
    while k < n - 2 and t >= d[1 + k + 1]:
        k += 1
    w = min(max((t - d[1 + k]) / (d[1 + k + 1] - d[1 + k]), 0.0), 1.0)
    d[1 + 2 * n] = w
    return (1.0 - w) * d[1 + n + k] + w * d[1 + n + k + 1]


@njit(cache=True)
def _tracker_outputs(t, x, z, u, p, d, y):
    y[Y_TRACK.x] = x[X_TRACK.x]
    y[Y_TRACK.measured] = z[Z_TRACK.measured]


@njit(cache=True)
def _tracker_derivatives(t, x, z, u, p, d, xdot):
    xdot[X_TRACK.x] = (_table_value(t, d) - x[X_TRACK.x]) / p[P_TRACK.tau]


@njit(cache=True)
def _tracker_sample(t, x, z, u, p, d, noise):
    _table_value(t, d)
    z[Z_TRACK.measured] = x[X_TRACK.x] + p[P_TRACK.sigma] * (1.0 + d[1 + 2 * int(d[0])]) * noise[0]


@register_model
class TableTracker(Model):
    """First-order lag tracking a table held in the model's data slot, sampled with noise (data-slot test plant)."""

    summary = "x' = (table(t) - x) / tau, table in a per-run data slot; noisy samples (data-slot test plant)"
    parameters = TRACKER_PARAMETERS
    outputs = TRACKER_OUTPUTS
    continuous_states = TRACKER_CONTINUOUS
    discrete_states = TRACKER_DISCRETE
    offsets = {"p": P_TRACK, "y": Y_TRACK, "x": X_TRACK, "z": Z_TRACK}
    default_period = "0.1 s"
    noise_size = 1
    uses_data = True
    state_outputs = staticmethod(_tracker_outputs)
    derivatives = staticmethod(_tracker_derivatives)
    update = staticmethod(_tracker_sample)

    def __init__(self, name, *, times=(0.0, 1.0), values=(0.0, 1.0), **kwargs):
        times, values = np.asarray(times, dtype=float), np.asarray(values, dtype=float)
        if times.shape != values.shape or times.size < 2 or np.any(np.diff(times) <= 0):
            raise ModelError(f"model {name}: config times and values: two lists of equal length >= 2, times "
                             f"increasing; given {times.tolist()} and {values.tolist()}")
        self.table = np.concatenate(([times.size], times, values, [0.0]))
        super().__init__(name, **kwargs)

    def create_data(self, own=False):
        return None, self.table.copy()
