"""Delay line, saturation, dead zone and rate limiter kernels (shell/linear/kernels.py) against analytic responses.

A static nonlinearity's frequency response is its describing function: the first harmonic of its response to
A sin(theta), divided by A. For a saturation at +-a (A > a; Gelb and Vander Velde, Multiple-Input Describing
Functions and Nonlinear System Design, 1968, Ch. 2)::

    N_sat(A) = (2 / pi) (asin(a / A) + (a / A) sqrt(1 - (a / A)^2))

and a dead zone of half-width d is u - sat_d(u), so N_dz(A) = 1 - N_sat(A) with a = d. The first harmonic is
integrated by Gauss-Legendre quadrature on each piece between the breakpoints |A sin(theta)| = a, where the
kernel's output is smooth (a multiple of sin(theta) or a constant), so the quadrature is exact to round-off and
the comparison holds to 1e-12 (measured 1e-16).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from shell.linear.kernels import dead_zone, delay_line_update, rate_limiter_update, saturation

TOLERANCE = 1e-12


def _first_harmonic(kernel, amplitude, breakpoint):
    """(1 / (pi A)) * integral over one period of kernel(A sin(theta)) sin(theta), piecewise Gauss-Legendre."""
    t1 = math.asin(breakpoint / amplitude)
    edges = [0.0, t1, math.pi - t1, math.pi + t1, 2 * math.pi - t1, 2 * math.pi]
    nodes, weights = np.polynomial.legendre.leggauss(24)
    total = 0.0
    y = np.zeros(1)
    for a, b in zip(edges[:-1], edges[1:]):
        for x, wt in zip(0.5 * (b - a) * nodes + 0.5 * (a + b), 0.5 * (b - a) * weights):
            kernel(np.array([amplitude * math.sin(x)]), y)
            total += wt * y[0] * math.sin(x)
    return total / (math.pi * amplitude)


def _sat_df(a, A):
    r = a / A
    return 2 / math.pi * (math.asin(r) + r * math.sqrt(1 - r * r))


@pytest.mark.parametrize("amplitude", [1.2, 2.0, 7.5, 100.0])
def test_saturation_describing_function(amplitude):
    a = 0.8
    lower, upper = np.array([-a]), np.array([a])
    found = _first_harmonic(lambda u, y: saturation(u, lower, upper, y), amplitude, a)
    assert abs(found - _sat_df(a, amplitude)) < TOLERANCE


@pytest.mark.parametrize("amplitude", [0.31, 1.0, 4.0])
def test_dead_zone_describing_function(amplitude):
    d = 0.3
    lower, upper = np.array([-d]), np.array([d])
    found = _first_harmonic(lambda u, y: dead_zone(u, lower, upper, y), amplitude, d)
    assert abs(found - (1.0 - _sat_df(d, amplitude))) < TOLERANCE


def test_saturation_and_dead_zone_step_responses_with_asymmetric_limits():
    """Steps of every size through limits [-1, 2] (per element): y = clip(u) and the dead zone's u - clip(u)."""
    steps = np.array([-5.0, -1.0, -0.5, 0.0, 0.7, 2.0, 3.5])
    lower, upper = np.full(steps.size, -1.0), np.full(steps.size, 2.0)
    y = np.zeros(steps.size)
    saturation(steps, lower, upper, y)
    np.testing.assert_array_equal(y, np.clip(steps, -1.0, 2.0))
    dead_zone(steps, lower, upper, y)
    np.testing.assert_array_equal(y, [-4.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.5])


@pytest.mark.parametrize("depth", [0, 1, 3, 10])
def test_delay_line_step_and_frequency_response(depth):
    """y[k] = u[k - N]: a step appears N samples late; on a sine that has run forever (the buffer pre-filled with
    its past) the response is Re[e^(-j theta N) e^(j theta k)] at every sample: the frequency response e^(-j w N T)."""
    m = 2
    buffer = np.zeros((depth, m))
    head, y, out = 0, np.zeros(m), []
    for k in range(20):
        head = delay_line_update(buffer, head, np.array([1.0, -2.0]), y)
        out.append(y.copy())
    out = np.array(out)
    np.testing.assert_array_equal(out[:depth], 0.0)
    np.testing.assert_array_equal(out[depth:], np.tile([1.0, -2.0], (20 - depth, 1)))
    theta = 2 * math.pi * 0.137
    buffer = np.array([[math.cos(theta * k), math.sin(theta * k)] for k in range(-depth, 0)]).reshape(depth, m)
    head = 0
    for k in range(50):
        head = delay_line_update(buffer, head, np.array([math.cos(theta * k), math.sin(theta * k)]), y)
        response = np.exp(-1j * theta * depth) * np.exp(1j * theta * k)
        assert abs(y[0] - response.real) < TOLERANCE and abs(y[1] - response.imag) < TOLERANCE


def test_rate_limiter_step_ramp_and_triangle():
    """A unit step rises by exactly rate * T per sample (falls by the falling rate); a sine whose slope stays
    below the limit passes unchanged (to round-off); one far above it moves by exactly +-rate * T per sample, or
    lands on the input."""
    T, rising, falling = 0.01, 5.0, 2.0
    up, down = np.array([rising * T]), np.array([falling * T])
    y = np.zeros(1)
    out = []
    for k in range(30):
        rate_limiter_update(y, np.array([1.0]), down, up)
        out.append(y[0])
    expected = np.minimum(rising * T * np.arange(1, 31), 1.0)
    np.testing.assert_allclose(out, expected, rtol=0, atol=1e-15)
    out = []
    for k in range(60):
        rate_limiter_update(y, np.array([0.0]), down, up)
        out.append(y[0])
    np.testing.assert_allclose(out, np.maximum(1.0 - falling * T * np.arange(1, 61), 0.0), rtol=0, atol=1e-14)
    # a slow sine: |du| <= 2 pi f A T = 0.0126 < 0.02 per sample
    theta = 2 * math.pi * 0.4 * T
    y[0] = 0.0
    for k in range(1, 300):
        u = 0.5 * math.sin(theta * k)
        rate_limiter_update(y, np.array([u]), down, up)
        assert abs(y[0] - u) <= 1e-16
    # a fast, large sine (slope 63 per second, limit 5 and 2): the output only slews
    y[0], previous = 0.0, 0.0
    theta = 2 * math.pi * 2.0 * T
    for k in range(1, 400):
        u = 5.0 * math.sin(theta * k)
        rate_limiter_update(y, np.array([u]), down, up)
        step = y[0] - previous
        assert math.isclose(step, rising * T, rel_tol=1e-12) or math.isclose(step, -falling * T, rel_tol=1e-12) \
            or abs(y[0] - u) <= 1e-15
        previous = y[0]
