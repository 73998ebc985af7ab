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

from dataclasses import replace

import numpy as np
from numba import njit

from shell.model import (Declarations, InputPort, Layout, Model, ModelError, OutputPort, Parameter, State, ZeroCrossing, named_offsets, parse_period)
from shell.ports import node_load_outputs
from shell.registry import register_model

G0 = 9.80665
MODES = {"pwm": 0, "on_off": 1, "proportional": 2}
ON_OFF, PROPORTIONAL = float(MODES["on_off"]), float(MODES["proportional"])  # mode codes for the kernels

PARAMETERS = (
    Parameter("direction", "", (0.0, 0.0, 1.0), (3,), (-1.0, 1.0), "unit force direction, node axes"),
    Parameter("position", "m", (0.0, 0.0, 0.0), (3,), None, "point of application from the node, node axes"),
    Parameter("max_thrust", "N", None, (), (0.0, None), "thrust with the valve open"),
    Parameter("isp", "s", None, (), (1e-9, None), "specific impulse"),
    Parameter("min_on_time", "s", 0.0, (), (0.0, None), "shortest valve opening (minimum impulse bit / F)"),
    Parameter("rise_time", "s", 0.0, (), (0.0, None), "time constant of the thrust rise (0: instant)"),
    Parameter("fall_time", "s", 0.0, (), (0.0, None), "time constant of the thrust decay (0: instant)"),
)
OUTPUTS = (
    *node_load_outputs("torque", "force", feedthrough=False, torque="torque about the node, node axes",
                       force="force, node axes"),
    OutputPort("thrust", "N", (), "thrust magnitude"),
    OutputPort("propellant_used", "kg", (), "propellant consumed since t = 0"),
)
CONTINUOUS = (State("thrust", "N", (), 0.0, "lagged thrust"),
              State("propellant_used", "kg", (), 0.0, "integral of F / (Isp g0)"))
ZERO_CROSSINGS = (ZeroCrossing("valve_closes", -1, False, "end of a pulse shorter than the cycle"),)
#: the command's unit depends on the mode (set in ``declare``), its place does not
INPUTS = (InputPort("command", "N", (), "demanded (pwm: mean over the cycle) thrust"),)
#: parts of the two discrete states (each one state, names kept for logs and restarts)
VALVE_PARTS = (State("level", "N", (), None, "valve level: thrust the valve lets through"),
               State("closing_time", "s", (), None, "time at which the open valve closes"),
               State("closing_scheduled", "", (), None, "1: the valve closes at closing_time in this cycle"),
               State("pulses", "", (), None, "pulses fired"))
CYCLE_PARTS = (State("mode", "", (), None, "mode code (MODES)"),
               State("period", "s", (), None, "cycle period (from config)"))
DISCRETE = (State("valve", "", (Layout.of(VALVE_PARTS).size,), None,
                  "valve level N, closing time, closing scheduled, pulses fired"),
            State("cycle", "", (Layout.of(CYCLE_PARTS).size,), None, "mode code and cycle period (from config)"))
THRUSTER = Declarations(parameters=PARAMETERS, inputs=INPUTS, outputs=OUTPUTS, continuous=CONTINUOUS,
                        discrete=DISCRETE, zero_crossings=ZERO_CROSSINGS)
P, U, Y, X, Z = THRUSTER.P, THRUSTER.U, THRUSTER.Y, THRUSTER.X, THRUSTER.Z
_VALVE, _CYCLE = named_offsets(VALVE_PARTS), named_offsets(CYCLE_PARTS)
LEVEL, CLOSING_TIME = Z.valve + _VALVE.level, Z.valve + _VALVE.closing_time
CLOSING_SCHEDULED, PULSES = Z.valve + _VALVE.closing_scheduled, Z.valve + _VALVE.pulses
MODE, PERIOD = Z.cycle + _CYCLE.mode, Z.cycle + _CYCLE.period


@njit(cache=True)
def _lagged(p):
    return p[P.rise_time] > 0.0 or p[P.fall_time] > 0.0


@njit(cache=True)
def _thrust(x, z, p):
    if _lagged(p):
        return x[X.thrust]
    return z[LEVEL]  # no lag: the valve level itself (the thrust state stays unused)


@njit(cache=True)
def _thruster_outputs(t, x, z, u, p, y):
    f = _thrust(x, z, p)
    d, r, force, torque = P.direction, P.position, Y.force, Y.torque
    for i in range(3):
        y[force + i] = f * p[d + i]
    y[torque] = p[r + 1] * y[force + 2] - p[r + 2] * y[force + 1]      # position x force
    y[torque + 1] = p[r + 2] * y[force] - p[r] * y[force + 2]
    y[torque + 2] = p[r] * y[force + 1] - p[r + 1] * y[force]
    y[Y.thrust] = f
    y[Y.propellant_used] = x[X.propellant_used]


@njit(cache=True)
def _thruster_derivatives(t, x, z, u, p, xdot):
    if _lagged(p):
        tau = p[P.rise_time] if z[LEVEL] > x[X.thrust] else p[P.fall_time]
        xdot[X.thrust] = (z[LEVEL] - x[X.thrust]) / tau if tau > 0.0 else 0.0
    else:
        xdot[X.thrust] = 0.0
    xdot[X.propellant_used] = _thrust(x, z, p) / (p[P.isp] * G0)


@njit(cache=True)
def _valve_update(t, x, z, u, p):
    f_max, period, mode = p[P.max_thrust], z[PERIOD], z[MODE]
    command = u[U.command]
    z[CLOSING_SCHEDULED] = 0.0
    if mode == PROPORTIONAL:
        z[LEVEL] = min(max(command, 0.0), f_max)
        return
    if mode == ON_OFF:
        on_time = period if command >= 0.5 else 0.0
    else:
        on_time = period * min(max(command, 0.0) / f_max, 1.0)
        if on_time < p[P.min_on_time]:
            on_time = 0.0
    if on_time > 0.0:
        z[LEVEL] = f_max
        z[PULSES] += 1.0
        if on_time < period:
            z[CLOSING_TIME] = t + on_time
            z[CLOSING_SCHEDULED] = 1.0
    else:
        z[LEVEL] = 0.0


@njit(cache=True)
def _valve_closing(t, x, z, u, p, g):
    # the one zero crossing, valve_closes
    g[0] = z[CLOSING_TIME] - t if z[CLOSING_SCHEDULED] != 0.0 else 1.0


@register_model
class Thruster(Model):
    """One thruster (config: mode = pwm | on_off | proportional); see the module docstring."""

    summary = "thruster at a node: pwm / on_off / proportional, min impulse, rise/fall lag, Isp propellant flow"
    declarations = THRUSTER
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
            self.use_declarations(THRUSTER.replace(
                command={"unit": "", "description": "valve flag: >= 0.5 open for the cycle"}))

    def configure(self):
        self.require_unit_norm("direction")
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
        cycle = np.zeros(Layout.of(CYCLE_PARTS).size)
        cycle[_CYCLE.mode], cycle[_CYCLE.period] = MODES[self.mode], period
        self.discrete_states = tuple(replace(d, initial=cycle) if d.name == "cycle" else d for d in DISCRETE)

    def on_event(self, index, t, x, z, p):
        z[LEVEL] = 0.0
        z[CLOSING_SCHEDULED] = 0.0
