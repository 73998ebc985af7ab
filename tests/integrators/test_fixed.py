"""Fixed-step methods: observed order on the linear oscillator, step bookkeeping, counters, refusals."""
import numpy as np
import pytest
from numpy.testing import assert_allclose

from shell.integrators import INTEGRATORS, integrate, make_integrator

from .problems import oscillator

# (method, theoretical order, steps used for the log-log slope): steps are chosen so the error stays far
# above round-off (1e-13) yet in the asymptotic regime.
ORDER_CASES = [("euler", 1, (0.01, 0.005)), ("heun", 2, (0.02, 0.01)), ("rk4", 4, (0.1, 0.05)),
               ("rk8", 8, (0.5, 0.25))]


@pytest.mark.parametrize("method, order, steps", ORDER_CASES)
def test_observed_order_matches_theory_on_linear_oscillator(method, order, steps):
    fun, exact = oscillator(1.0)
    errors = []
    for h in steps:
        r = integrate(method, fun, 0.0, [1.0, 0.0], 4.0, step=h)
        errors.append(np.linalg.norm(r.y[:, -1] - exact(4.0)))
    slope = np.log(errors[0] / errors[1]) / np.log(steps[0] / steps[1])
    # a step halving in the asymptotic regime gives the order to within a few percent
    assert abs(slope - order) < 0.1 * order, (method, errors, slope)


def test_counters_and_exact_landing_on_t_bound():
    fun, _ = oscillator(1.0)
    integ = make_integrator("rk4", fun, 0.0, [1.0, 0.0], 1.0, step=0.1)
    while integ.status == "running":
        integ.step()
    assert integ.status == "finished"
    assert integ.t == 1.0  # bit-exact, the scheduler compares sample times with ==
    assert integ.nsteps == 10  # 0.1 accumulated 10 times is 0.9999999999999999: no sliver step
    assert integ.nfev == 1 + 4 * 10  # initial derivative + 4 stages per step (last stage of each step reused)
    assert integ.nrejected == 0 and integ.njev == 0


def test_last_step_shortened_not_past_t_bound():
    fun, exact = oscillator(1.0)
    integ = make_integrator("rk4", fun, 0.0, [1.0, 0.0], 0.25, step=0.1)
    times = []
    while integ.status == "running":
        integ.step()
        times.append(integ.t)
    assert_allclose(times, [0.1, 0.2, 0.25], rtol=0, atol=1e-15)
    assert_allclose(integ.y, exact(0.25), atol=1e-6)


def test_extend_and_reset_for_multirate_scheduling():
    fun, exact = oscillator(2.0)
    integ = make_integrator("rk4", fun, 0.0, [1.0, 0.0], 0.1, step=0.01)
    for k in range(1, 11):  # ten discrete samples of period 0.1 s
        while integ.status == "running":
            integ.step()
        assert integ.t == pytest.approx(0.1 * k, abs=1e-15)
        integ.extend(0.1 * (k + 1))
    assert_allclose(integ.y, exact(1.0), atol=1e-7)  # RK4 global error at h = 0.01, omega = 2
    # a state jump: restart from a new state; dense output from before the jump is no longer offered
    integ.reset(1.0, [0.0, 1.0], 1.5)
    with pytest.raises(RuntimeError, match="dense output needs at least one step"):
        integ.dense_output()
    integ.step()
    assert integ.t == pytest.approx(1.01)


def test_hermite_dense_output_matches_solution_inside_step():
    fun, exact = oscillator(1.0)
    integ = make_integrator("rk4", fun, 0.0, [1.0, 0.0], 1.0, step=0.05)
    integ.step()
    integ.step()
    sol = integ.dense_output()
    ts = np.linspace(integ.t_old, integ.t, 7)
    # cubic Hermite interpolation error bound h^4/384 max|y''''| = 0.05^4/384 ~ 1.6e-8
    assert_allclose(sol(ts), exact(ts), atol=2e-8)
    assert_allclose(sol(integ.t), integ.y, atol=1e-15)


@pytest.mark.parametrize("bad", [0.0, -0.01, np.nan, np.inf])
def test_non_positive_or_non_finite_step_refused(bad):
    fun, _ = oscillator(1.0)
    with pytest.raises(ValueError, match="step must be a positive"):
        make_integrator("rk4", fun, 0.0, [1.0, 0.0], 1.0, step=bad)


def test_fixed_step_method_requires_step_and_unknown_method_named():
    fun, _ = oscillator(1.0)
    with pytest.raises(ValueError, match="fixed-step method: pass step="):
        make_integrator("rk4", fun, 0.0, [1.0, 0.0], 1.0)
    with pytest.raises(ValueError, match="unknown integrator 'rk5'; choose one of"):
        make_integrator("rk5", fun, 0.0, [1.0, 0.0], 1.0, step=0.1)


def test_nan_derivative_fails_with_time_and_last_good_state():
    def fun(t, y):
        return np.array([np.nan if t > 0.35 else 1.0])

    integ = make_integrator("rk4", fun, 0.0, [0.0], 1.0, step=0.1)
    while integ.status == "running":
        integ.step()
    assert integ.status == "failed"
    assert "not finite" in integ.message and "t=0.3 s" in integ.message
    assert integ.t == pytest.approx(0.3)  # last good state kept
    assert_allclose(integ.y, [0.3], atol=1e-15)
    with pytest.raises(RuntimeError, match="status is 'failed'"):
        integ.step()


@pytest.mark.filterwarnings("ignore:overflow encountered:RuntimeWarning")  # the model overflows on purpose
def test_explicit_instability_reported_with_stability_limit_and_radau_suggestion():
    # a stiff decaying mode lambda = -1000 1/s with RK4 at h = 0.01 (h|lambda| = 10 > 2.785)
    def fun(t, y):
        return np.array([-1000.0 * y[0]])

    integ = make_integrator("rk4", fun, 0.0, [1.0], 100.0, step=0.01)
    while integ.status == "running":
        integ.step()
    assert integ.status == "failed"
    assert "radau5" in integ.message
    assert "|lambda| ~ 1e+03 rad/s" in integ.message  # the power iteration finds the mode


def test_normalize_callback_applied_after_each_step():
    calls = []

    def normalize(y):
        calls.append(1)
        y /= np.linalg.norm(y)

    def fun(t, y):  # rotation in the plane: norm is invariant, Euler inflates it
        return np.array([-y[1], y[0]])

    integ = make_integrator("euler", fun, 0.0, [1.0, 0.0], 1.0, step=0.1, normalize=normalize)
    while integ.status == "running":
        integ.step()
    assert len(calls) == 1 + 10  # y0 and every accepted step
    assert np.linalg.norm(integ.y) == pytest.approx(1.0, abs=1e-15)


def test_registry_lists_fixed_methods():
    for name in ("euler", "heun", "rk4", "rk8"):
        assert INTEGRATORS[name].fixed_step and INTEGRATORS[name].name == name
