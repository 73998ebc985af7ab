"""AttitudeModeManager: the switching conditions (rate, pointing error, hold time, minimum time), the
modes never going back, and the routing of the B-dot and wheel commands by mode."""

import numpy as np
from numpy.testing import assert_array_equal

from shell.models.mode_manager import INPUTS, OUTPUTS, U, Y, AttitudeModeManager, _route, _switch


def _step(model, z, t, rate, sigma):
    u = np.zeros(sum(d.size for d in INPUTS))
    u[U.angular_rate:U.angular_rate + 3] = rate
    u[U.attitude_error:U.attitude_error + 3] = sigma
    u[U.dipole_command_in:U.dipole_command_in + 3] = [0.1, -0.2, 0.3]
    u[U.torque_command_in:U.torque_command_in + 3] = [0.01, 0.02, -0.03]
    _switch(t, np.zeros(0), z, u, model.p)
    y = np.zeros(sum(d.size for d in OUTPUTS))
    _route(t, np.zeros(0), z, u, model.p, y)
    return y


def test_modes_switch_after_their_conditions_hold_and_route_the_commands():
    model = AttitudeModeManager("modes", rate_threshold="1 deg/s", pointing_threshold="2 deg", hold_time="5 s",
                                min_time="20 s")
    z = model.initial_discrete_state()
    fast, slow = np.radians([1.0, 0.5, 0.3]), np.radians([0.5, 0.5, 0.5])   # |slow| = 0.87 deg/s < 1 deg/s
    far, near = np.full(3, np.tan(np.radians(3.0) / 4) / np.sqrt(3)), np.full(3, np.tan(np.radians(1.9) / 4) / np.sqrt(3))
    history = []
    for t in np.arange(0.0, 80.0, 1.0):
        rate = fast if t < 10 or 14 <= t < 16 else slow   # slow at 10-13 s (too short), again from 16 s
        sigma = far if t < 40 else near
        y = _step(model, z, t, rate, sigma)
        history.append((t, y[Y.mode], y[Y.slew_trigger], y[Y.mode_start]))
        if y[Y.mode] == 0:
            assert_array_equal(y[Y.dipole_command:Y.dipole_command + 3], [0.1, -0.2, 0.3])
            assert_array_equal(y[Y.torque_command:Y.torque_command + 3], 0.0)
        else:
            assert_array_equal(y[Y.dipole_command:Y.dipole_command + 3], 0.0)
            assert_array_equal(y[Y.torque_command:Y.torque_command + 3], [0.01, 0.02, -0.03])
    history = np.array(history)
    # slow from 16 s: held 5 s at 21 s, and min_time 20 s is past -> mode 1 at 21 s
    first = history[history[:, 1] >= 1][0]
    assert first[0] == 21.0 and first[3] == 21.0
    # near from 40 s: held 5 s at 45 s, but mode 1 began at 21 s: 45 - 21 >= 20 -> mode 2 at 45 s
    second = history[history[:, 1] >= 2][0]
    assert second[0] == 45.0 and second[2] == 1.0
    assert np.all(np.diff(history[:, 1]) >= 0)          # never back
    # a rate rising again in mode 1 does not return to detumble
    y = _step(model, z, 90.0, fast * 10, far)
    assert y[Y.mode] == 2
