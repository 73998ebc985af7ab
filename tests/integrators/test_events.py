"""Event location: analytic roots, close root pairs inside one step, direction, ties, terminal stop."""
import numpy as np
import pytest
from numpy.testing import assert_allclose

from shell.integrators import event, integrate, locate_events
from shell.integrators.base import DenseOutput

from .problems import oscillator


class ExactSolution(DenseOutput):
    """Dense output returning a known function, to test the root finder without interpolation error."""

    def __init__(self, t_min, t_max, fn):
        super().__init__(t_min, t_max)
        self.fn = fn

    def _evaluate(self, t):
        return np.atleast_1d(self.fn(t)) if t.ndim == 0 else np.atleast_2d(self.fn(t))


def _g(fn, terminal=False, direction=0):
    def g(t, y):
        return fn(t, y)

    return event(terminal, direction)(g)


def test_two_roots_in_one_step_both_found_and_ordered():
    sol = ExactSolution(0.0, 1.0, lambda t: t)
    g = _g(lambda t, y: (y[0] - 0.3) * (y[0] - 0.62))
    roots = locate_events([g], sol, 0.0, 1.0, [g(0.0, [0.0])], [g(1.0, [1.0])], xtol=1e-14)
    assert [i for _, i in roots] == [0, 0]
    assert_allclose([t for t, _ in roots], [0.3, 0.62], atol=1e-13)


def test_close_root_pair_inside_one_subinterval_found():
    # roots 0.51 and 0.53 lie in the same eighth [0.5, 0.625] of the step: g has the same sign at
    # every uniform sample; the parabolic-extremum check must find the dip
    sol = ExactSolution(0.0, 1.0, lambda t: t)
    g = _g(lambda t, y: (y[0] - 0.51) * (y[0] - 0.53))
    roots = locate_events([g], sol, 0.0, 1.0, [g(0.0, [0.0])], [g(1.0, [1.0])], xtol=1e-14)
    assert_allclose([t for t, _ in roots], [0.51, 0.53], atol=1e-13)


def test_direction_filter_and_simultaneous_events_ordered_by_index():
    sol = ExactSolution(0.0, 1.0, lambda t: t)
    rising = _g(lambda t, y: y[0] - 0.5, direction=+1)
    falling = _g(lambda t, y: 0.5 - y[0], direction=-1)
    falling_only = _g(lambda t, y: y[0] - 0.25, direction=-1)  # rises through 0.25: not reported
    fns = [falling, rising, falling_only]
    g0 = [f(0.0, [0.0]) for f in fns]
    g1 = [f(1.0, [1.0]) for f in fns]
    roots = locate_events(fns, sol, 0.0, 1.0, g0, g1)
    assert [i for _, i in roots] == [0, 1]
    assert roots[0][0] == roots[1][0] == pytest.approx(0.5, abs=1e-12)


def test_zero_at_step_end_reported_once():
    sol = ExactSolution(0.0, 1.0, lambda t: t)
    g = _g(lambda t, y: y[0] - 1.0)
    assert locate_events([g], sol, 0.0, 1.0, [-1.0], [0.0]) == [(1.0, 0)]
    sol2 = ExactSolution(1.0, 2.0, lambda t: t)
    assert locate_events([g], sol2, 1.0, 2.0, [0.0], [1.0]) == []  # the zero at t_old was already reported


@pytest.mark.parametrize("method, step", [("rk4", 0.002)])
def test_oscillator_zero_crossings_located_to_1e10_seconds(method, step):
    # x = cos(t) crosses zero at pi/2 + k pi; rising at odd k (x goes from - to +). The step makes the
    # solution (phase) error ~1e-12 over 10 s, so the located times measure the event finder itself.
    fun, _ = oscillator(1.0)
    r = integrate(method, fun, 0.0, [1.0, 0.0], 10.0, step=step,
                  events=[_g(lambda t, y: y[0]), _g(lambda t, y: y[0], direction=+1)])
    expected = np.pi / 2 + np.pi * np.arange(3)
    assert_allclose(r.t_events[0], expected, rtol=0, atol=1e-10)
    assert_allclose(r.t_events[1], expected[1::2], rtol=0, atol=1e-10)


def test_terminal_event_stops_at_root_with_state_from_dense_output():
    fun, exact = oscillator(1.0)
    stop = _g(lambda t, y: y[0] + 0.5, terminal=True, direction=-1)  # cos t = -1/2 at t = 2 pi / 3
    r = integrate("rk4", fun, 0.0, [1.0, 0.0], 10.0, step=0.002, events=[stop])
    assert r.status == "terminated"
    assert r.t[-1] == pytest.approx(2 * np.pi / 3, abs=1e-10)
    assert_allclose(r.y[:, -1], exact(2 * np.pi / 3), atol=1e-10)
    assert_allclose(r.y_events[0][0], exact(2 * np.pi / 3), atol=1e-10)


def test_bad_arguments_refused():
    sol = ExactSolution(0.0, 1.0, lambda t: t)
    g = _g(lambda t, y: y[0])
    with pytest.raises(ValueError, match="one per event function"):
        locate_events([g], sol, 0.0, 1.0, [0.0, 1.0], [1.0])
    with pytest.raises(ValueError, match="direction must be"):
        event(direction=2)


def test_vectorized_sampling_gives_the_same_roots_with_fewer_calls():
    calls = {"single": 0, "all": 0}
    sol = ExactSolution(0.0, 1.0, lambda t: t)

    def make(center):
        def g(t, y):
            calls["single"] += 1
            return (y[0] - center) * (y[0] - center - 0.1)
        return g

    fns = [make(0.2), make(0.6)]

    def all_values(t, y):
        calls["all"] += 1
        return [(y[0] - 0.2) * (y[0] - 0.3), (y[0] - 0.6) * (y[0] - 0.7)]

    g0 = [f(0.0, [0.0]) for f in fns]
    g1 = [f(1.0, [1.0]) for f in fns]
    calls["single"] = 0
    expected = locate_events(fns, sol, 0.0, 1.0, g0, g1, xtol=1e-14)
    single_calls = calls["single"]
    calls["single"] = 0
    roots = locate_events(fns, sol, 0.0, 1.0, g0, g1, xtol=1e-14, all_values=all_values)
    assert roots == expected
    assert_allclose([t for t, _ in roots], [0.2, 0.3, 0.6, 0.7], atol=1e-13)
    assert calls["all"] == 7  # one call per interior sample instead of one per function and sample
    assert calls["single"] == single_calls - 2 * 7


def test_integrate_output_times_on_dense_output_up_to_terminal_event():
    fun, exact = oscillator(1.0)
    stop = _g(lambda t, y: y[0] + 0.5, terminal=True, direction=-1)  # t = 2 pi / 3
    t_eval = np.linspace(0.0, 5.0, 51)
    r = integrate("dop853", fun, 0.0, [1.0, 0.0], 5.0, rtol=1e-12, atol=1e-12, t_eval=t_eval, events=[stop])
    kept = t_eval[t_eval <= 2 * np.pi / 3]
    assert_allclose(r.t, kept, rtol=0, atol=0)  # exactly the requested times, none after the stop
    assert_allclose(r.y, exact(kept), atol=1e-10)
    with pytest.raises(ValueError, match="increasing 1-D array within"):
        integrate("rk4", fun, 0.0, [1.0, 0.0], 1.0, step=0.1, t_eval=[0.5, 0.2])


def test_precomputed_samples_give_the_same_roots_and_are_checked():
    """locate_events(samples=...): the caller's values at the inner uniform samples (the compiled loop's) replace
    the first pass; the roots are those found by sampling itself (a close pair found by the extremum check
    included; a function that cannot cross is skipped). A wrongly shaped array is refused."""
    sol = ExactSolution(0.0, 1.0, lambda t: t)
    fns = [_g(lambda t, y: np.sin(40.0 * y[0]) - 0.3), _g(lambda t, y: y[0] - 0.55),
           _g(lambda t, y: (y[0] - 0.51) * (y[0] - 0.53)), _g(lambda t, y: 1.0 + 0.0 * y[0])]
    g0 = [f(0.0, [0.0]) for f in fns]
    g1 = [f(1.0, [1.0]) for f in fns]
    inner = np.array([[f(t, [t]) for f in fns] for t in np.linspace(0.0, 1.0, 9)[1:-1]])
    expected = locate_events(fns, sol, 0.0, 1.0, g0, g1, xtol=1e-14)
    assert {i for _, i in expected} == {0, 1, 2} and len(expected) == 6
    assert locate_events(fns, sol, 0.0, 1.0, g0, g1, xtol=1e-14, samples=inner) == expected
    with pytest.raises(ValueError, match=r"samples must hold \(7, 4\) values"):
        locate_events(fns, sol, 0.0, 1.0, g0, g1, samples=inner[:, :2])
