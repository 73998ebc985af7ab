"""Momentum unloading for configs/spacecraft_slew.yaml (called by a UserFunction model at 2 Hz).

The stored wheel momentum (node axes) is estimated from the wheel speeds, ``H = J_w sum Omega_k a_k``
(TM-2020-5008164 eq. G.3.1 spin axes), and the thrusters are asked for the torque ``-k H`` while |H|
is above a dead band, from ``START`` on (after the slew: the momentum a slew parks in the wheels comes
back by itself; only the bus's initial momentum has to go). The attitude loop keeps pointing, so the
wheels give up the momentum the jets remove.
"""

import numpy as np

SPIN_AXES = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [1.0, 1.0, 1.0] / np.sqrt(3.0)])
WHEEL_INERTIA = 0.1          # kg m^2, as in the scenario
GAIN = 0.1                   # 1/s: unloading time constant 10 s
DEAD_BAND = 0.05             # N m s
START = 80.0                 # s


def unload(t, signals):
    speeds = np.array([signals[f"wheel_speed_{k}"] for k in (1, 2, 3, 4)], dtype=float).reshape(4)
    momentum = WHEEL_INERTIA * SPIN_AXES.T @ speeds
    if t < START or np.linalg.norm(momentum) < DEAD_BAND:
        return {"torque_command": np.zeros(3)}
    return {"torque_command": -GAIN * momentum}
