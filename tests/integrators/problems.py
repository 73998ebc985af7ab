"""Shared reference problems for the integrator tests (each with a closed-form solution)."""
import numpy as np


def oscillator(omega):
    """x'' = -omega^2 x as y = [x, v]; exact solution from x(0) = 1, v(0) = 0 is x = cos(omega t)."""

    def fun(t, y):
        return np.array([y[1], -omega * omega * y[0]])

    def exact(t):
        return np.array([np.cos(omega * t), -omega * np.sin(omega * t)])

    return fun, exact
