"""Attitude mode manager: detumble -> Sun pointing -> fine pointing, with switching conditions.

Sampled at its own rate, it keeps the mode (0 detumble, 1 pointing, 2 fine pointing / slew) as a
discrete state and advances it, never back::

    0 -> 1  when |omega_meas| < rate_threshold has held for hold_time (and the mode lasted min_time)
    1 -> 2  when the pointing error 4 atan |sigma| < pointing_threshold has held for hold_time
            (sigma the controller's MRP attitude error) and the mode lasted min_time

It routes the actuators by the mode (feedthrough, so a command passes at the instant it is made):
``dipole_command`` = ``dipole_command_in`` in mode 0, zero after (magnetorquers: B-dot); and
``torque_command`` = ``torque_command_in`` from mode 1 on, zero in mode 0 (wheels off while tumbling).
``slew_trigger`` is 1 in mode 2 (``EigenaxisSlew.trigger``); ``mode`` and the time the mode began
are outputs for logging and for other flight software. The conditions are those of a Basilisk
``sunSafe`` -> ``inertial3D`` sequence written as data (Basilisk sequences modes with Python events).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from shell.model import Declarations, InputPort, Model, OutputPort, Parameter, State
from shell.registry import register_model

PARAMETERS = (
    Parameter("rate_threshold", "rad/s", None, (), (0.0, None), "detumble ends below this body rate"),
    Parameter("pointing_threshold", "rad", None, (), (0.0, None), "fine pointing starts below this pointing error"),
    Parameter("hold_time", "s", 10.0, (), (0.0, None), "how long a condition must hold before the switch"),
    Parameter("min_time", "s", 0.0, (), (0.0, None), "shortest time in a mode before it may end"),
)
INPUTS = (
    InputPort("angular_rate", "rad/s", (3,), "measured body rate (gyro), node axes"),
    InputPort("attitude_error", "", (3,), "controller's MRP attitude error (MrpFeedback.attitude_error)"),
    InputPort("dipole_command_in", "A*m^2", (3,), "detumble dipole command (B-dot)", feedthrough=True,
              required=False),
    InputPort("torque_command_in", "N*m", (3,), "pointing torque command (attitude controller)", feedthrough=True,
              required=False),
)
OUTPUTS = (
    OutputPort("dipole_command", "A*m^2", (3,), "dipole command in mode 0, else zero", feedthrough=True),
    OutputPort("torque_command", "N*m", (3,), "torque command from mode 1 on, else zero", feedthrough=True),
    OutputPort("mode", "", (), "0 detumble, 1 pointing, 2 fine pointing", feedthrough=True),
    OutputPort("slew_trigger", "", (), "1 in mode 2", feedthrough=True),
    OutputPort("mode_start", "s", (), "time the current mode began", feedthrough=True),
)
DISCRETE = (
    State("mode", "", (), 0.0, "current mode"),
    State("condition_since", "s", (), -1.0, "time the switching condition became true (-1: false)"),
    State("mode_start", "s", (), 0.0, "time the current mode began"),
)
MODES = Declarations(parameters=PARAMETERS, inputs=INPUTS, outputs=OUTPUTS, discrete=DISCRETE)
P, U, Y, Z = MODES.P, MODES.U, MODES.Y, MODES.Z


@njit(cache=True)
def _route(t, x, z, u, p, y):
    mode = z[Z.mode]
    for i in range(3):
        y[Y.dipole_command + i] = u[U.dipole_command_in + i] if mode < 0.5 else 0.0
        y[Y.torque_command + i] = u[U.torque_command_in + i] if mode > 0.5 else 0.0
    y[Y.mode] = mode
    y[Y.slew_trigger] = 1.0 if mode > 1.5 else 0.0
    y[Y.mode_start] = z[Z.mode_start]


@njit(cache=True)
def _switch(t, x, z, u, p):
    mode = z[Z.mode]
    if mode > 1.5:
        return
    if mode < 0.5:
        w = U.angular_rate
        condition = np.sqrt(u[w] * u[w] + u[w + 1] * u[w + 1] + u[w + 2] * u[w + 2]) < p[P.rate_threshold]
    else:
        s = U.attitude_error
        norm = np.sqrt(u[s] * u[s] + u[s + 1] * u[s + 1] + u[s + 2] * u[s + 2])
        condition = 4.0 * np.arctan(norm) < p[P.pointing_threshold]
    if not condition:
        z[Z.condition_since] = -1.0
        return
    if z[Z.condition_since] < 0.0:
        z[Z.condition_since] = t
    if t - z[Z.condition_since] >= p[P.hold_time] and t - z[Z.mode_start] >= p[P.min_time]:
        z[Z.mode] = mode + 1.0
        z[Z.mode_start] = t
        z[Z.condition_since] = -1.0


@register_model
class AttitudeModeManager(Model):
    """Detumble -> pointing -> fine pointing mode logic and actuator routing; see the module docstring."""

    summary = "mode manager: detumble (B-dot) -> pointing -> fine pointing on rate / pointing-error conditions"
    declarations = MODES
    default_period = "1 s"
    feedthrough_outputs = staticmethod(_route)
    update = staticmethod(_switch)
