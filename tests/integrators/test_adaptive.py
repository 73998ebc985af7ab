"""Adaptive explicit pairs: agreement with scipy.integrate.solve_ivp at the same tolerances, dense output,
error control that ignores excluded components and the quaternion gauge, events, failure reports."""
import warnings

import numpy as np
import pytest
from numpy.testing import assert_allclose
from scipy.integrate import solve_ivp

from shell.integrators import StiffnessWarning, event, integrate, make_integrator, quaternion_gauge
from shell.integrators.kernels import remove_quaternion_gauge
from shell.integrators.reference_problems import (FreeFreeBeamModes, TipForcedBeam, TorqueFreeRigidBody,
                                                  linear_oscillator, spinning_spacecraft_pd)

PAIRS = [("bs32", "RK23"), ("dopri5", "RK45"), ("dop853", "DOP853")]


def _cases():
    fun, exact = linear_oscillator(1.0)
    body = TorqueFreeRigidBody((100.0, 200.0, 300.0), (0.3, -0.5, 1.0))
    beam = FreeFreeBeamModes(f_max=10.0)
    return {"oscillator": (fun, np.array([1.0, 0.0]), 20.0, exact(20.0)),
            "rigid_body": (body.euler_equations(), np.array([0.3, -0.5, 1.0]), 30.0, body.omega(30.0)),
            "beam": (beam.fun, beam.y0, 2.0, beam.exact(2.0))}


CASES = _cases()


@pytest.mark.parametrize("case", sorted(CASES))
@pytest.mark.parametrize("method, scipy_method", PAIRS)
@pytest.mark.parametrize("tol", [1e-5, 1e-8])
def test_same_accuracy_and_work_as_solve_ivp(method, scipy_method, case, tol):
    fun, y0, t_end, exact = CASES[case]
    ours = integrate(method, fun, 0.0, y0, t_end, rtol=tol, atol=tol * 1e-3)
    ref = solve_ivp(fun, (0.0, t_end), y0, method=scipy_method, rtol=tol, atol=tol * 1e-3)
    err_ours = np.linalg.norm(ours.y[:, -1] - exact)
    err_ref = np.linalg.norm(ref.y[:, -1] - exact)
    # same formulas and controller: same steps (to within the treatment of the last step) and error
    assert abs(ours.nsteps - (ref.t.size - 1)) <= max(2, 0.02 * ref.t.size)
    assert err_ours <= 2.0 * err_ref + 1e-14
    assert err_ref <= 2.0 * err_ours + 1e-14
    # and the error is of the order of the tolerance asked for (global error over many periods)
    assert err_ours < 1e3 * tol


@pytest.mark.parametrize("method, tol, dense_tol", [("dopri5", 1e-10, 1e-8), ("dop853", 1e-12, 1e-11),
                                                   ("bs32", 1e-8, 1e-6)])
def test_dense_output_inside_steps(method, tol, dense_tol):
    fun, exact = linear_oscillator(1.0)
    integ = make_integrator(method, fun, 0.0, [1.0, 0.0], 10.0, rtol=tol, atol=tol)
    worst = 0.0
    while integ.status == "running":
        integ.step()
        sol = integ.dense_output()
        ts = np.linspace(integ.t_old, integ.t, 5)[1:-1]
        worst = max(worst, np.abs(sol(ts) - exact(ts)).max())
        assert_allclose(sol(integ.t), integ.y, atol=1e-13)
    assert worst < dense_tol


def test_events_on_adaptive_steps_located_to_1e10_and_two_per_step_found():
    fun, _ = linear_oscillator(1.0)
    zero = event()(lambda t, y: y[0])
    near_peak = event(direction=0)(lambda t, y: y[0] - 0.999)  # crossings at 2 pi k +- acos(0.999)
    r = integrate("dop853", fun, 0.0, [1.0, 0.0], 13.0, rtol=1e-13, atol=1e-13, events=[zero])
    assert_allclose(r.t_events[0], np.pi / 2 + np.pi * np.arange(4), rtol=0, atol=1e-10)
    # loose tolerance: steps of ~1 s straddle both crossings around each peak (0.089 s apart)
    r = integrate("dop853", fun, 0.0, [1.0, 0.0], 13.0, rtol=1e-6, atol=1e-6, events=[near_peak])
    expected = np.sort(np.concatenate([[np.arccos(0.999)], 2 * np.pi + np.array([-1, 1]) * np.arccos(0.999),
                                       4 * np.pi + np.array([-1, 1]) * np.arccos(0.999)]))
    assert np.max(np.diff(r.t)) > 0.5  # the steps really are much longer than the pair spacing
    # a grazing crossing amplifies the solution error (1e-6) by 1/|x'| = 1/sin(acos 0.999) = 22
    assert_allclose(r.t_events[0], expected, atol=1e-4)


def test_excluded_components_do_not_drive_the_step():
    # component 2 grows like exp(30 t) and is not of interest; excluded, the step follows the oscillator
    fun0, _ = linear_oscillator(1.0)

    def fun(t, y):
        return np.array([y[1], -y[0], 30.0 * y[2]])

    y0 = [1.0, 0.0, 1e-6]
    base = integrate("dopri5", fun0, 0.0, [1.0, 0.0], 1.0, rtol=1e-8, atol=1e-10)
    excl = integrate("dopri5", fun, 0.0, y0, 1.0, rtol=1e-8, atol=1e-10, error_exclude=[2])
    full = integrate("dopri5", fun, 0.0, y0, 1.0, rtol=1e-8, atol=1e-10)
    assert excl.nsteps <= base.nsteps + 1
    assert full.nsteps > 2 * excl.nsteps


def test_quaternion_gauge_removed_from_error():
    q = np.array([0.5, 0.5, -0.5, 0.5])
    perp = np.array([0.5, -0.5, 0.5, 0.5])  # orthogonal to q
    y = np.concatenate([[7.0], q, [1.0]])
    err = np.concatenate([[0.1], 0.3 * q + 0.2 * perp, [0.4]])
    remove_quaternion_gauge(err, y, np.array([1]))
    assert_allclose(err, np.concatenate([[0.1], 0.2 * perp, [0.4]]), atol=1e-15)


def test_closed_loop_spacecraft_with_normalization_and_gauge_matches_tight_reference():
    fun, y0, normalize, w_idx = spinning_spacecraft_pd()
    ref = solve_ivp(fun, (0.0, 60.0), y0, method="DOP853", rtol=1e-13, atol=1e-13)
    r = integrate("dopri5", fun, 0.0, y0, 60.0, rtol=1e-8, atol=1e-10, normalize=normalize,
                  error_exclude=quaternion_gauge(w_idx))
    assert np.linalg.norm(r.y[:4, -1]) == pytest.approx(1.0, abs=1e-15)
    assert_allclose(r.y[:, -1], ref.y[:, -1], atol=1e-7)


def test_non_positive_tolerances_refused():
    fun, _ = linear_oscillator(1.0)
    with pytest.raises(ValueError, match="rtol must be positive"):
        make_integrator("dopri5", fun, 0.0, [1.0, 0.0], 1.0, rtol=0.0)
    with pytest.raises(ValueError, match="atol must be positive"):
        make_integrator("dopri5", fun, 0.0, [1.0, 0.0], 1.0, atol=-1e-9)
    with pytest.raises(ValueError, match="atol must be a scalar or have the state's shape"):
        make_integrator("dopri5", fun, 0.0, [1.0, 0.0], 1.0, atol=[1e-9, 1e-9, 1e-9])
    with pytest.raises(ValueError, match="max_step must be a positive"):
        make_integrator("dopri5", fun, 0.0, [1.0, 0.0], 1.0, max_step=0.0)
    with pytest.warns(UserWarning, match="below what float64"):
        make_integrator("dopri5", fun, 0.0, [1.0, 0.0], 1.0, rtol=1e-20)


def test_blow_up_stops_with_step_underflow_time_and_suggestion():
    # y' = exp(y), y(0) = 0 has the solution -ln(1 - t), singular at t = 1; past it exp overflows
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        integ = make_integrator("dopri5", lambda t, y: np.exp(y), 0.0, [0.0], 2.0, rtol=1e-8, atol=1e-8)
        while integ.status == "running":
            integ.step()
    assert integ.status == "failed"
    assert "step size underflow" in integ.message and "check the model" in integ.message
    # near the pole the time resolution, not the solution, limits how close the run gets to t = 1
    assert 0.999 < integ.t < 1.00001 and np.isfinite(integ.y).all()  # last good state kept
    assert integ.failed_t == pytest.approx(integ.t, abs=1e-6)


def test_model_returning_nan_is_reported():
    def fun(t, y):
        return np.array([np.sqrt(0.5 - t)])  # NaN after t = 0.5

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        integ = make_integrator("dop853", fun, 0.0, [0.0], 1.0, rtol=1e-8, atol=1e-8)
        while integ.status == "running":
            integ.step()
    assert integ.status == "failed"
    assert "non-finite" in integ.message and "not finite" in integ.message
    assert integ.t <= 0.5


@pytest.mark.parametrize("method", ["dopri5", "dop853"])
def test_stiffness_detected_and_radau_recommended(method):
    # y' = -1000 (y - cos t): after the transient the step is limited by stability, not accuracy
    # (HNW I Sec. IV.2 detection, as in dopri5.f / dop853.f; it targets real, decaying stiff modes)
    with pytest.warns(StiffnessWarning, match="radau5"):
        integrate(method, lambda t, y: -1000.0 * (y - np.cos(t)), 0.0, [0.0], 2.0, rtol=1e-6, atol=1e-9)


def test_multirate_extend_lands_on_every_sample_time():
    fun, exact = linear_oscillator(2.0)
    integ = make_integrator("dopri5", fun, 0.0, [1.0, 0.0], 0.01, rtol=1e-10, atol=1e-12)
    for k in range(1, 101):
        while integ.status == "running":
            integ.step()
        assert integ.t == pytest.approx(0.01 * k, abs=1e-15)
        integ.extend(0.01 * (k + 1))
    assert_allclose(integ.y, exact(1.0), atol=1e-9)


@pytest.mark.parametrize("method", ["dopri5", "radau5"])
def test_created_at_t_bound_then_extended_chooses_a_proper_first_step(method):
    # the shell creates the integrator at a sample instant that may equal t_bound, then extends it
    fun, exact = linear_oscillator(1.0)
    integ = make_integrator(method, fun, 0.0, [1.0, 0.0], 0.0, rtol=1e-8, atol=1e-10)
    assert integ.status == "finished"
    integ.extend(1.0)
    while integ.status == "running":
        integ.step()
    assert integ.nsteps < 60  # not a ramp from a 1e-15 s first step
    assert_allclose(integ.y, exact(1.0), atol=1e-7)


@pytest.mark.parametrize("method", ["dopri5", "dop853"])
def test_stiffness_warning_for_lightly_damped_high_modes_and_not_otherwise(method):
    # beam modes to 92.7 Hz driven slowly: the step sits at the oscillatory stability limit -> warning;
    # modes to 8.9 Hz: accuracy, not stability, limits the step -> no warning (the stage-difference ratio
    # alone would raise a false alarm here: it reaches omega^2 on the modal Jacobian)
    stiff = TipForcedBeam(f_max=100.0)
    with pytest.warns(StiffnessWarning, match="radau5"):
        integrate(method, stiff.fun, 0.0, stiff.y0, 10.0, rtol=1e-6, atol=1e-7)
    mild = TipForcedBeam(f_max=10.0)
    with warnings.catch_warnings():
        warnings.simplefilter("error", StiffnessWarning)
        integrate(method, mild.fun, 0.0, mild.y0, 10.0, rtol=1e-6, atol=1e-7)
