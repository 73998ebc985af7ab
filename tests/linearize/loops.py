"""Loops with known structure for the margin and ``flexshell bode`` tests."""

from __future__ import annotations

import numpy as np


def attitude_loop():
    """Two coupled attitude axes broken at the commanded torque: actuator lags (0.1 s), inertia with a product
    term, PD control on the attitude and on the rate filtered at 0.2 s; input the commanded torque, output the
    controller's command, which closes the loop by positive feedback (u = +y)."""
    J = np.array([[10.0, 1.5], [1.5, 6.0]])
    Kp, Kd, rate_filter, actuator = np.diag([4.0, 3.6]), np.diag([12.0, 6.0]), 0.2, 0.1
    Z, I = np.zeros((2, 2)), np.eye(2)
    # states: actuator torque, attitude, rate, filtered rate (2 each)
    A = np.block([[-I / actuator, Z, Z, Z], [Z, Z, I, Z], [np.linalg.inv(J), Z, Z, Z],
                  [Z, Z, I / rate_filter, -I / rate_filter]])
    B = np.vstack([I / actuator, Z, Z, Z])
    C = np.hstack([Z, -Kp, Z, -Kd])
    return A, B, C, np.zeros((2, 2))
