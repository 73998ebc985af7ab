"""Radau IIA 5: agreement with scipy's Radau, L-stability on stiff problems, steps far beyond the explicit
stability limit, user and finite-difference Jacobians, events on its collocation dense output."""
import numpy as np
import pytest
from numpy.testing import assert_allclose
from scipy.integrate import solve_ivp

from shell.integrators import integrate, make_integrator
from shell.integrators.reference_problems import FreeFreeBeamModes, TorqueFreeRigidBody, linear_oscillator

from .test_order import UniformStepRadau5


def _cases():
    fun, exact = linear_oscillator(1.0)
    body = TorqueFreeRigidBody((100.0, 200.0, 300.0), (0.3, -0.5, 1.0))
    beam = FreeFreeBeamModes(f_max=10.0)
    return {"oscillator": (fun, np.array([1.0, 0.0]), 20.0, exact(20.0)),
            "rigid_body": (body.euler_equations(), np.array([0.3, -0.5, 1.0]), 30.0, body.omega(30.0)),
            "beam": (beam.fun, beam.y0, 2.0, beam.exact(2.0))}


CASES = _cases()


@pytest.mark.parametrize("case", sorted(CASES))
@pytest.mark.parametrize("tol", [1e-5, 1e-8])
def test_same_accuracy_and_work_as_scipy_radau(case, tol):
    fun, y0, t_end, exact = CASES[case]
    ours = integrate("radau5", fun, 0.0, y0, t_end, rtol=tol, atol=tol * 1e-3)
    ref = solve_ivp(fun, (0.0, t_end), y0, method="Radau", rtol=tol, atol=tol * 1e-3)
    err_ours = np.linalg.norm(ours.y[:, -1] - exact)
    err_ref = np.linalg.norm(ref.y[:, -1] - exact)
    # same algorithm (RADAU5 of Hairer & Wanner): no more steps than scipy (+10%), errors within a factor 3;
    # the Jacobians differ slightly (forward-difference increments), which changes Newton convergence
    assert ours.nsteps <= 1.1 * (ref.t.size - 1) + 2
    assert err_ours <= 3.0 * err_ref + 1e-13 and err_ref <= 3.0 * err_ours + 1e-13
    assert err_ours < 1e3 * tol


def test_l_stable_on_very_stiff_scalar_problem():
    # y' = -1e6 (y - cos t) - sin t has the solution y = cos t from y(0) = 1 (Prothero-Robinson)
    def fun(t, y):
        return -1e6 * (y - np.cos(t)) - np.sin(t)

    r = integrate("radau5", fun, 0.0, [1.0], 10.0, rtol=1e-6, atol=1e-9)
    assert r.status == "finished"
    assert r.nsteps < 200  # an explicit method would need h < 2.8e-6 s: > 3.5 million steps
    assert abs(r.y[0, -1] - np.cos(10.0)) < 1e-6


@pytest.mark.filterwarnings("ignore:overflow encountered:RuntimeWarning")  # the RK4 comparison diverges
def test_stiff_flexible_beam_steps_far_beyond_explicit_limit():
    beam = FreeFreeBeamModes(f_max=100.0)
    h = 0.05  # h * omega_max = 29, ten times RK4's limit 2.83
    r = integrate(UniformStepRadau5, beam.fun, 0.0, beam.y0, 5.0, step=h, max_step=h, rtol=1e-9, atol=1e-12,
                  jac=beam.jacobian())
    assert r.status == "finished" and r.nsteps == 100
    exact = beam.exact(5.0)
    n = beam.n_modes
    # rigid-body and first elastic mode (1 Hz, h omega = 0.31) stay accurate; L-stability damps the modes
    # the step cannot resolve instead of amplifying them
    assert_allclose(r.y[[0, 1, 2], -1], exact[[0, 1, 2]], atol=2e-6)
    assert np.all(np.abs(r.y[3:n, -1]) <= np.abs(beam.y0[3:n]) + 1e-12)
    # RK4 with the same step blows up
    rk4 = integrate("rk4", beam.fun, 0.0, beam.y0, 5.0, step=h)
    assert rk4.status == "failed" and "radau5" in rk4.message


def test_user_jacobian_equals_finite_differences():
    beam = FreeFreeBeamModes(f_max=30.0)
    fd = integrate("radau5", beam.fun, 0.0, beam.y0, 1.0, rtol=1e-8, atol=1e-11)
    user = integrate("radau5", beam.fun, 0.0, beam.y0, 1.0, rtol=1e-8, atol=1e-11, jac=beam.jacobian())
    call = integrate("radau5", beam.fun, 0.0, beam.y0, 1.0, rtol=1e-8, atol=1e-11,
                     jac=lambda t, y: beam.jacobian())
    assert_allclose(user.y[:, -1], fd.y[:, -1], atol=1e-9)
    assert_allclose(call.y[:, -1], user.y[:, -1], atol=1e-15)
    assert user.njev >= 1 and fd.nlu >= 1
    # finite differences cost one derivative evaluation per state: f(t0, y0), the trial Euler step of the
    # starting-step heuristic, then n columns
    n = beam.y0.size
    integ = make_integrator("radau5", beam.fun, 0.0, beam.y0, 1.0)
    assert (integ.nfev, integ.njev) == (2 + n, 1)
    integ = make_integrator("radau5", beam.fun, 0.0, beam.y0, 1.0, jac=beam.jacobian())
    assert (integ.nfev, integ.njev) == (2, 1)


def test_jacobian_arguments_checked():
    fun, _ = linear_oscillator(1.0)
    with pytest.raises(ValueError, match=r"constant jac must have shape \(2, 2\)"):
        make_integrator("radau5", fun, 0.0, [1.0, 0.0], 1.0, jac=np.eye(3))
    with pytest.raises(ValueError, match="explicit and does not use a Jacobian"):
        make_integrator("dopri5", fun, 0.0, [1.0, 0.0], 1.0, jac=np.eye(2))


def test_events_on_collocation_dense_output():
    fun, _ = linear_oscillator(1.0)
    zero = lambda t, y: y[0]  # noqa: E731 - plain function as event without attributes
    r = integrate("radau5", fun, 0.0, [1.0, 0.0], 10.0, rtol=1e-12, atol=1e-12, events=[zero])
    assert_allclose(r.t_events[0], np.pi / 2 + np.pi * np.arange(3), rtol=0, atol=1e-10)


def test_discontinuity_makes_radau_fail_with_actionable_message():
    # a derivative that is undefined past t = 0.5 (the model asks for sqrt of a negative number)
    def fun(t, y):
        with np.errstate(invalid="ignore"):
            return np.array([np.sqrt(0.5 - t) * 1.0])

    integ = make_integrator("radau5", fun, 0.0, [0.0], 1.0, rtol=1e-6, atol=1e-9)
    while integ.status == "running":
        integ.step()
    assert integ.status == "failed"
    assert "step size underflow" in integ.message and "event function" in integ.message
    assert integ.t <= 0.5


@pytest.mark.parametrize("fun, y0, exact", [
    (lambda t, y: np.zeros_like(y), np.zeros(2), lambda t: np.zeros(2)),                 # a state at rest
    (lambda t, y: np.array([1.0, 2.0 * t]), np.zeros(2), lambda t: np.array([t, t * t])),  # collocation is exact
])
def test_an_exact_step_grows_the_next_one(fun, y0, exact):
    """An error estimate of exactly 0 (no motion, or a polynomial the collocation reproduces) takes the
    largest step growth; before, the step-size controller raised ZeroDivisionError (0.0 ** -0.25)."""
    r = integrate("radau5", fun, 0.0, y0, 10.0, rtol=1e-8, atol=1e-10)
    assert r.status == "finished"
    assert r.nsteps < 12            # growth by MAX_FACTOR = 10 per step from the initial step
    assert_allclose(r.y[:, -1], exact(10.0), rtol=1e-12, atol=1e-12)


def test_a_scene_at_rest_runs_with_radau5_from_the_command_line(tmp_path):
    from shell.cli import main
    from shell.log_file import read_log

    scene = tmp_path / "rest.yaml"
    scene.write_text("models:\n"
                     "  zero: {type: Constant, config: {unit: m/s}, parameters: {value: 0 m/s}}\n"
                     "  position: {type: Integrator, config: {unit: m}}\n"
                     "connections: [zero.y -> position.u]\n"
                     "integrator: {method: radau5, step: 0.1 s, options: {rtol: 1e-8, atol: 1e-10}}\n"
                     "stop: {time: 5 s}\n"
                     "log: {rate: 1 Hz, signals: [position.y]}\n")
    assert main(["run", str(scene), "-o", str(tmp_path / "rest.h5")]) == 0
    log = read_log(tmp_path / "rest.h5")
    assert log["time"][-1] == pytest.approx(5.0) and not np.any(log["position.y"])
