"""The linear blocks' math (shell/linear) against analytic step and frequency responses, to 1e-12.

Each filter is built by shell.linear.realization and stepped by the compiled kernels of shell.linear.kernels,
then compared with closed forms written here independently of the realization:

* continuous sections H = N/D of normalized quadratics q(s) = s^2/w^2 + 2 zeta s/w + 1: the step response
  y(t) = H(0) + sum over the poles p of N(p) / (p D'(p)) e^(p t) (residues of H(s)/s; the low-pass also against
  the textbook 1 - e^(-zeta w t) (cos w_d t + zeta / sqrt(1 - zeta^2) sin w_d t)); the frequency response
  N(j w) / D(j w);
* sampled sections (Tustin, prewarped per quadratic): the z-polynomials written in factored form
  q_d(z) = c^2 (z - 1)^2 + 2 zeta c (z^2 - 1) + (z + 1)^2, c = 1 / tan(w T / 2), the step response
  y_k = H(1) + sum over the poles p of N(p) p^k / (D'(p) (p - 1)) (residues of H(z) z^k / (z - 1)), and the
  frequency response N(j c_n tan(W T / 2)) / D(j c_d tan(W T / 2)) of the prewarped map.

Frequency responses of the kernels are measured as periodic steady states: started from x0 = Re[(s I - A)^-1 B]
and driven by cos(w t), a linear system's output is Re[H e^(j w t)] at every instant (every sample), so the
kernels' outputs are compared sample by sample, with nothing to fit and no transient to wait for.
Tolerances: 1e-12 relative to the response's size (measured: a few 1e-15).
"""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest
from scipy.linalg import expm

from shell.linear.kernels import state_space_derivative, state_space_output, state_space_update
from shell.linear.realization import (bending, low_pass, notch, series, transfer_function, zero_order_hold)
from shell.linear.response import frequency_response
from shell.linear.system import LinearSystem, LinearSystemError

TOLERANCE = 1e-12
FILTERS = {  # name -> (filter, numerator quadratic (Hz, zeta) or None, denominator quadratic)
    "low_pass": (low_pass(3.0, 0.4), None, (3.0, 0.4)),
    "notch": (notch(5.0, 0.3, 0.05), (5.0, 0.015), (5.0, 0.3)),
    "bending_gain": (bending(8.0, 0.02, 6.0, 0.5), (8.0, 0.02), (6.0, 0.5)),
    "bending_phase": (bending(4.0, 0.7, 9.0, 0.2), (4.0, 0.7), (9.0, 0.2)),
}
SAMPLE_TIME = 0.01


def _q(frequency_hz, zeta, s):
    w = 2 * math.pi * frequency_hz
    return (s / w) ** 2 + 2 * zeta * s / w + 1


def _dq(frequency_hz, zeta, s):
    w = 2 * math.pi * frequency_hz
    return 2 * s / w ** 2 + 2 * zeta / w


def _continuous_H(numerator, denominator, s):
    return (_q(*numerator, s) if numerator else 1.0) / _q(*denominator, s)


def _continuous_step(numerator, denominator, t):
    """Residues of H(s)/s at the (distinct, complex) poles of the quadratic denominator."""
    f, zeta = denominator
    w = 2 * math.pi * f
    y = np.full_like(t, 1.0, dtype=complex)  # H(0) = 1 for normalized quadratics
    for p in (w * (-zeta + 1j * math.sqrt(1 - zeta ** 2)), w * (-zeta - 1j * math.sqrt(1 - zeta ** 2))):
        N = _q(*numerator, p) if numerator else 1.0
        y += N / (p * _dq(f, zeta, p)) * np.exp(p * t)
    return y.real


def _tustin_poly(frequency_hz, zeta, T, z):
    c = 1.0 / math.tan(math.pi * frequency_hz * T)
    return c * c * (z - 1) ** 2 + 2 * zeta * c * (z * z - 1) + (z + 1) ** 2


def _tustin_dpoly(frequency_hz, zeta, T, z):
    c = 1.0 / math.tan(math.pi * frequency_hz * T)
    return 2 * c * c * (z - 1) + 4 * zeta * c * z + 2 * (z + 1)


def _sampled_H(numerator, denominator, T, theta):
    """The prewarped map at z = e^(j theta): s = k (z - 1)/(z + 1) = j k tan(theta / 2), k = w / tan(w T / 2), so
    each quadratic sees s / w = j tan(theta / 2) / tan(w T / 2)."""
    def factor(frequency_hz, zeta):
        x = 1j * math.tan(theta / 2) / math.tan(math.pi * frequency_hz * T)
        return x * x + 2 * zeta * x + 1
    return (factor(*numerator) if numerator else 1.0) / factor(*denominator)


def _sampled_step(numerator, denominator, T, k):
    f, zeta = denominator
    c = 1.0 / math.tan(math.pi * f * T)
    a2, a1, a0 = c * c + 2 * zeta * c + 1, 2 - 2 * c * c, c * c - 2 * zeta * c + 1
    disc = np.sqrt(complex(a1 * a1 - 4 * a2 * a0))
    y = np.ones(k.shape, dtype=complex)  # H(1) = 1
    for p in ((-a1 + disc) / (2 * a2), (-a1 - disc) / (2 * a2)):
        N = _tustin_poly(*numerator, T, p) if numerator else (p + 1) ** 2
        y += N * p ** k / (_tustin_dpoly(f, zeta, T, p) * (p - 1))
    return y.real


@pytest.mark.parametrize("name", FILTERS)
def test_continuous_filter_step_response(name):
    """Along the exact step trajectory x(t) of the realization (the zero-order-hold integral: the top-right block
    of expm([[A, B], [0, 0]] t), exact for a constant input), the output kernel gives the analytic step response
    y(t) and C times the derivative kernel gives its analytic rate y'(t) = sum N(p) / D'(p) e^(p t)."""
    filt, numerator, denominator = FILTERS[name]
    system = filt.continuous()
    assert system.A.shape == (2, 2)
    f, zeta = denominator
    w = 2 * math.pi * f
    poles = (w * (-zeta + 1j * math.sqrt(1 - zeta ** 2)), w * (-zeta - 1j * math.sqrt(1 - zeta ** 2)))
    u, y, xdot = np.ones(1), np.zeros(1), np.zeros(2)
    for t in np.linspace(0.0, 1.5, 61):
        x = zero_order_hold(system, t).B[:, 0] if t > 0 else np.zeros(2)
        state_space_output(system.C, system.D, x, u, y)
        exact = _continuous_step(numerator, denominator, np.array([t]))[0]
        assert abs(y[0] - exact) <= TOLERANCE
        state_space_derivative(system.A, system.B, x, u, xdot)
        rate = sum(((_q(*numerator, p) if numerator else 1.0) / _dq(f, zeta, p) * np.exp(p * t)) for p in poles).real
        assert abs((system.C @ xdot)[0] - rate) <= TOLERANCE * w
    if name == "low_pass":
        times = np.linspace(0.0, 1.5, 61)
        wd = w * math.sqrt(1 - zeta ** 2)
        textbook = 1 - np.exp(-zeta * w * times) * (np.cos(wd * times) + zeta / math.sqrt(1 - zeta ** 2)
                                                    * np.sin(wd * times))
        np.testing.assert_allclose(_continuous_step(numerator, denominator, times), textbook, rtol=0, atol=1e-14)


@pytest.mark.parametrize("name", FILTERS)
@pytest.mark.parametrize("frequency_hz", [0.3, 3.0, 5.0, 8.0, 30.0])
def test_continuous_filter_frequency_response(name, frequency_hz):
    """The kernels on the periodic solution x(t) = Re[X e^(j w t)], X = (j w I - A)^-1 B: the output kernel gives
    Re[H(j w) e^(j w t)] and the derivative kernel d/dt x(t) = Re[j w X e^(j w t)], H analytic."""
    filt, numerator, denominator = FILTERS[name]
    system = filt.continuous()
    w = 2 * math.pi * frequency_hz
    H = _continuous_H(numerator, denominator, 1j * w)
    X = np.linalg.solve(1j * w * np.eye(2) - system.A, system.B[:, 0])
    y, xdot = np.zeros(1), np.zeros(2)
    for t in np.linspace(0.0, 2 / frequency_hz, 17):
        phasor = np.exp(1j * w * t)
        x, u = (X * phasor).real.copy(), np.array([phasor.real])
        state_space_output(system.C, system.D, x, u, y)
        assert abs(y[0] - (H * phasor).real) <= TOLERANCE * max(abs(H), 1.0)
        state_space_derivative(system.A, system.B, x, u, xdot)
        np.testing.assert_allclose(xdot, (1j * w * X * phasor).real, rtol=0,
                                   atol=TOLERANCE * w * np.max(np.abs(X)))
    assert abs(frequency_response(system, [w])[0, 0, 0] - H) <= TOLERANCE * max(abs(H), 1.0)


def _step_sampled(system, inputs, x0=None):
    x = np.zeros(system.A.shape[0]) if x0 is None else x0.copy()
    work, y, out = np.zeros_like(x), np.zeros(system.C.shape[0]), []
    for u in inputs:
        u = np.atleast_1d(np.asarray(u, dtype=float))
        state_space_output(system.C, system.D, x, u, y)
        out.append(y.copy())
        state_space_update(system.A, system.B, x, u, work)
    return np.array(out)


@pytest.mark.parametrize("name", FILTERS)
def test_sampled_filter_step_response(name):
    filt, numerator, denominator = FILTERS[name]
    system = filt.tustin(SAMPLE_TIME)
    k = np.arange(300)
    exact = _sampled_step(numerator, denominator, SAMPLE_TIME, k)
    stepped = _step_sampled(system, np.ones(k.size))[:, 0]
    np.testing.assert_allclose(stepped, exact, rtol=0, atol=TOLERANCE * np.max(np.abs(exact)))


@pytest.mark.parametrize("name", FILTERS)
@pytest.mark.parametrize("frequency_hz", [0.3, 3.0, 5.0, 8.0, 30.0, 49.0])
def test_sampled_filter_frequency_response(name, frequency_hz):
    """Periodic steady state of the sampled kernels against the prewarped analytic response, sample by sample."""
    filt, numerator, denominator = FILTERS[name]
    system = filt.tustin(SAMPLE_TIME)
    theta = 2 * math.pi * frequency_hz * SAMPLE_TIME
    H = _sampled_H(numerator, denominator, SAMPLE_TIME, theta)
    z = np.exp(1j * theta)
    x0 = np.linalg.solve(z * np.eye(2) - system.A, system.B[:, 0]).real
    k = np.arange(200)
    stepped = _step_sampled(system, np.cos(theta * k), x0)[:, 0]
    np.testing.assert_allclose(stepped, (H * z ** k).real, rtol=0, atol=TOLERANCE * max(abs(H), 1.0))
    ours = frequency_response(system, [2 * math.pi * frequency_hz])[0, 0, 0]
    assert abs(ours - H) <= TOLERANCE * max(abs(H), 1.0)


def test_prewarping_keeps_the_notch_on_its_frequency():
    """At the notch frequency the sampled notch's gain is exactly the designed gain (0.05), whatever the rate;
    the unwarped bilinear map would move the null to (2/T) atan(w T/2) (here 4.8 % low at 40 Hz, 100 Hz)."""
    for T in (0.01, 0.002, 0.0125):
        for f0 in (5.0, 20.0, 39.0):
            if f0 >= 0.5 / T:
                continue
            system = notch(f0, 0.3, 0.05).tustin(T)
            assert abs(abs(frequency_response(system, [2 * math.pi * f0])[0, 0, 0]) - 0.05) < 1e-13


def test_sampled_filter_refuses_frequencies_above_nyquist():
    with pytest.raises(LinearSystemError, match="Nyquist frequency 50 Hz"):
        notch(60.0, 0.3, 0.1, where="configs/x.yaml:12: models.notch").tustin(SAMPLE_TIME)


@pytest.mark.parametrize("make, message", [
    (lambda: low_pass(0.0, 0.5), "frequency: expected a finite frequency > 0 Hz"),
    (lambda: low_pass(2.0, 0.0), r"denominator damping: expected a finite damping ratio > 0 \(a stable filter\)"),
    (lambda: notch(2.0, 0.3, 1.2), "notch gain: expected 0 <= gain < 1"),
    (lambda: bending(2.0, -0.1, 3.0, 0.3), "numerator damping: expected a finite damping ratio >= 0"),
    (lambda: bending(2.0, 0.1, float("nan"), 0.3), "denominator frequency"),
])
def test_filter_parameters_are_checked(make, message):
    with pytest.raises(LinearSystemError, match=message):
        make()


def test_transfer_function_is_a_minimal_realization():
    """(s + 1)(s + 2) / ((s + 1)(s + 3)(s + 4)): the common root is cancelled with a warning, the 2-state
    realization has the response and the step response of (s + 2) / ((s + 3)(s + 4))."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        system = transfer_function(np.poly([-1, -2]), np.poly([-1, -3, -4]), where="scene.yaml:4: models.tf")
    assert system.A.shape == (2, 2)
    assert any("share 1 root(s) (-1)" in str(w.message) and "scene.yaml:4" in str(w.message) for w in caught)
    w = np.array([0.0, 0.1, 1.0, 3.0, 100.0])
    expected = (1j * w + 2) / ((1j * w + 3) * (1j * w + 4))
    np.testing.assert_allclose(frequency_response(system, w)[0, 0], expected, rtol=TOLERANCE)
    # partial fractions of (s + 2) / (s (s + 3) (s + 4)): 1/6 + e^(-3t) / 3 - e^(-4t) / 2
    for t in (0.1, 0.7, 2.0):
        exact = 1 / 6 + np.exp(-3 * t) / 3 - np.exp(-4 * t) / 2
        realized = (system.C @ zero_order_hold(system, t).B)[0, 0]
        assert abs(realized - exact) < TOLERANCE


def test_transfer_function_with_feedthrough_and_sampled():
    """(2 z^2 - 0.5) / (z^2 - 1.2 z + 0.52): D = 2; the sampled step response from the recursion
    y_k = 1.2 y_(k-1) - 0.52 y_(k-2) + 2 u_k - 0.5 u_(k-2), exact in a few roundings."""
    system = transfer_function([2.0, 0.0, -0.5], [1.0, -1.2, 0.52], sample_time=0.1)
    assert system.discrete and system.D[0, 0] == 2.0
    k = 60
    y = np.zeros(k)
    for i in range(k):
        y[i] = (1.2 * y[i - 1] if i >= 1 else 0) - (0.52 * y[i - 2] if i >= 2 else 0) + 2.0 - (0.5 if i >= 2 else 0)
    np.testing.assert_allclose(_step_sampled(system, np.ones(k))[:, 0], y, rtol=0, atol=TOLERANCE * np.max(abs(y)))


@pytest.mark.parametrize("numerator, denominator, message", [
    ([1, 0, 0], [1, 1], "improper transfer function"),
    ([1], [0, 0], "every coefficient is zero"),
    ([1, float("inf")], [1, 1], "finite numbers"),
    ([[1, 2]], [1, 1], "non-empty list"),
])
def test_transfer_function_refusals(numerator, denominator, message):
    with pytest.raises(LinearSystemError, match=message):
        transfer_function(numerator, denominator, where="scene.yaml:9: models.tf")


def test_sampled_mimo_state_space_step_response():
    """A 3-state, 2-input, 2-output sampled system: y_k = C (I - A)^-1 (I - A^k) B 1 + D 1 (geometric series)."""
    rng = np.random.default_rng(7)
    A = 0.6 * rng.standard_normal((3, 3)) / 3
    B, C, D = rng.standard_normal((3, 2)), rng.standard_normal((2, 3)), rng.standard_normal((2, 2))
    system = LinearSystem(A, B, C, D, 0.05)
    ones = np.ones(2)
    k = 40
    stepped = _step_sampled(system, [ones] * k)
    for i in range(k):
        exact = C @ np.linalg.solve(np.eye(3) - A, (np.eye(3) - np.linalg.matrix_power(A, i)) @ B @ ones) + D @ ones
        np.testing.assert_allclose(stepped[i], exact, rtol=0, atol=TOLERANCE * np.max(np.abs(exact)))


def test_series_and_zero_order_hold():
    """Two first-order lags in series equal 1 / ((s + 1)(s + 2)); the zero-order hold of a scalar system is
    (e^(a T), (e^(a T) - 1) b / a)."""
    first = transfer_function([1.0], [1.0, 1.0])
    second = transfer_function([1.0], [1.0, 2.0])
    w = np.array([0.3, 2.0, 11.0])
    np.testing.assert_allclose(frequency_response(series(first, second), w)[0, 0],
                               1 / ((1j * w + 1) * (1j * w + 2)), rtol=TOLERANCE)
    a, b, T = -0.7, 2.5, 0.2
    held = zero_order_hold(LinearSystem([[a]], [[b]], [[1.0]], [[0.0]]), T)
    assert abs(held.A[0, 0] - math.exp(a * T)) < 1e-15
    assert abs(held.B[0, 0] - (math.exp(a * T) - 1) * b / a) < 1e-15
    assert np.allclose(expm(np.array([[a * T]])), held.A, rtol=1e-15)
    with pytest.raises(LinearSystemError, match="sample times"):
        series(first, zero_order_hold(second, 0.1))
