"""Thruster at a node: on/off, pulse-width-modulated or proportional, with rise/fall lag and Isp flow.

A sampled valve driver (its own rate, the flight-software thruster cycle T) and a continuous thrust:

* ``mode: pwm`` (config) -- the command is the demanded mean thrust over the next cycle; the valve opens
  for ``t_on = T min(command / F_max, 1)``, rounded to zero below ``min_on_time`` (the minimum impulse
  bit ``F_max min_on_time``). The closing instant is a zero crossing, located exactly (the impulse of a
  pulse does not depend on the integrator step).
* ``mode: on_off`` -- the command is a valve flag: >= 0.5 opens the valve for the whole cycle (at least
  ``min_on_time``: a shorter cycle is refused).
* ``mode: proportional`` -- throttled thrust ``clip(command, 0, F_max)`` held over the cycle.

Thrust follows the valve level L with first-order rise/fall lags (SSSIM thruster model; Wertz,
"Spacecraft Attitude Determination and Control" sec. 19.2 thruster response)::

    dF/dt = (L - F) / tau,    tau = rise_time if L > F else fall_time     (0: F = L instantly)

so a pulse of length t_on delivers ``F_max (t_on - tau_r (1 - exp(-t_on/tau_r)) + F_1 tau_f / F_max)``
with ``F_1 = F_max (1 - exp(-t_on/tau_r))``, which is ``F_max t_on`` for equal lags. Propellant flows at
``dm/dt = F / (Isp g0)`` (g0 = 9.80665 m/s^2). The force ``F d`` acts along the unit ``direction``
(node axes; the direction of the force on the vehicle, opposite to the exhaust) at ``position`` from the
node, so the torque about the node is ``position x F d`` (several thrusters can share one node).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from shell.model import (InputPort, Model, ModelError, OutputPort, Parameter, State, ZeroCrossing,
                         parse_period)
from shell.registry import register_model

G0 = 9.80665
MODES = {"pwm": 0, "on_off": 1, "proportional": 2}

# p = [direction (3), position (3), max_thrust, isp, min_on_time, rise_time, fall_time]
# z = [valve level (N), closing time, closing scheduled (0/1), pulses fired, mode code, cycle period]


@njit(cache=True)
def _thrust(x, z, p):
    if p[9] > 0.0 or p[10] > 0.0:
        return x[0]
    return z[0]  # no lag: the valve level itself (x[0] stays unused)


@njit(cache=True)
def _thruster_outputs(t, x, z, u, p, y):
    f = _thrust(x, z, p)
    for i in range(3):
        y[3 + i] = f * p[i]
    y[0] = p[4] * y[5] - p[5] * y[4]
    y[1] = p[5] * y[3] - p[3] * y[5]
    y[2] = p[3] * y[4] - p[4] * y[3]
    y[6] = f
    y[7] = x[1]


@njit(cache=True)
def _thruster_derivatives(t, x, z, u, p, xdot):
    if p[9] > 0.0 or p[10] > 0.0:
        tau = p[9] if z[0] > x[0] else p[10]
        xdot[0] = (z[0] - x[0]) / tau if tau > 0.0 else 0.0
    else:
        xdot[0] = 0.0
    xdot[1] = _thrust(x, z, p) / (p[7] * G0)


@njit(cache=True)
def _valve_update(t, x, z, u, p):
    f_max, period, mode = p[6], z[5], z[4]
    command = u[0]
    z[2] = 0.0
    if mode == 2.0:
        z[0] = min(max(command, 0.0), f_max)
        return
    if mode == 1.0:
        on_time = period if command >= 0.5 else 0.0
    else:
        on_time = period * min(max(command, 0.0) / f_max, 1.0)
        if on_time < p[8]:
            on_time = 0.0
    if on_time > 0.0:
        z[0] = f_max
        z[3] += 1.0
        if on_time < period:
            z[1] = t + on_time
            z[2] = 1.0
    else:
        z[0] = 0.0


@njit(cache=True)
def _valve_closing(t, x, z, u, p, g):
    g[0] = z[1] - t if z[2] != 0.0 else 1.0


@register_model
class Thruster(Model):
    """One thruster (config: mode = pwm | on_off | proportional); see the module docstring."""

    summary = "thruster at a node: pwm / on_off / proportional, min impulse, rise/fall lag, Isp propellant flow"
    parameters = (
        Parameter("direction", "", (0.0, 0.0, 1.0), (3,), (-1.0, 1.0), "unit force direction, node axes"),
        Parameter("position", "m", (0.0, 0.0, 0.0), (3,), None, "point of application from the node, node axes"),
        Parameter("max_thrust", "N", None, (), (0.0, None), "thrust with the valve open"),
        Parameter("isp", "s", None, (), (1e-9, None), "specific impulse"),
        Parameter("min_on_time", "s", 0.0, (), (0.0, None), "shortest valve opening (minimum impulse bit / F)"),
        Parameter("rise_time", "s", 0.0, (), (0.0, None), "time constant of the thrust rise (0: instant)"),
        Parameter("fall_time", "s", 0.0, (), (0.0, None), "time constant of the thrust decay (0: instant)"),
    )
    outputs = (
        OutputPort("torque", "N*m", (3,), "torque about the node, node axes"),
        OutputPort("force", "N", (3,), "force, node axes"),
        OutputPort("thrust", "N", (), "thrust magnitude"),
        OutputPort("propellant_used", "kg", (), "propellant consumed since t = 0"),
    )
    continuous_states = (State("thrust", "N", (), 0.0, "lagged thrust"),
                         State("propellant_used", "kg", (), 0.0, "integral of F / (Isp g0)"))
    zero_crossings = (ZeroCrossing("valve_closes", -1, False, "end of a pulse shorter than the cycle"),)
    default_period = "0.1 s"
    state_outputs = staticmethod(_thruster_outputs)
    derivatives = staticmethod(_thruster_derivatives)
    zero_crossing_values = staticmethod(_valve_closing)
    update = staticmethod(_valve_update)

    def __init__(self, name: str, *, mode: str = "pwm", period=None, **kwargs):
        if mode not in MODES:
            raise ModelError(f"model {name}: config mode: expected one of {sorted(MODES)}, given {mode!r}")
        self.mode = mode
        self._given_period = period
        super().__init__(name, period=period, **kwargs)

    def declare(self):
        if self.mode == "on_off":
            self.inputs = (InputPort("command", "", (), "valve flag: >= 0.5 open for the cycle"),)
        else:
            self.inputs = (InputPort("command", "N", (), "demanded (pwm: mean over the cycle) thrust"),)

    def configure(self):
        direction = self.parameter("direction")
        if abs(float(np.sqrt(direction @ direction)) - 1.0) > 1e-9:
            raise ModelError(f"model {self.path}: parameter direction: expected a unit vector, given {direction}")
        period = float(parse_period(self._given_period if self._given_period is not None else self.default_period,
                                    f"model {self.path}: period"))
        if self.mode == "on_off" and period < float(self.parameter("min_on_time")):
            raise ModelError(f"model {self.path}: on_off cycle {period:g} s is shorter than min_on_time "
                             f"{float(self.parameter('min_on_time')):g} s")
        lags = (float(self.parameter("rise_time")) > 0.0, float(self.parameter("fall_time")) > 0.0)
        if lags[0] != lags[1]:
            raise ModelError(f"model {self.path}: parameters rise_time and fall_time: give both (lagged thrust) or "
                             f"neither (instant), given {float(self.parameter('rise_time')):g} s and "
                             f"{float(self.parameter('fall_time')):g} s")
        self.discrete_states = (
            State("valve", "", (4,), None, "valve level N, closing time, closing scheduled, pulses fired"),
            State("cycle", "", (2,), (float(MODES[self.mode]), period), "mode code and cycle period (from config)"),
        )

    def on_event(self, index, t, x, z, p):
        z[0] = 0.0
        z[2] = 0.0
