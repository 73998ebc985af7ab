"""Observed order of accuracy (log-log slope of the final-state error against the step) matches each
method's theory on three problems with closed-form solutions: the linear oscillator, the torque-free
asymmetric rigid body (Jacobi elliptic functions) and a free-free beam's modal model.

Adaptive methods are run on a uniform step so that the propagating formula itself is measured: explicit
pairs with max_step = step and tolerances loose enough that no step is rejected, Radau IIA with its step
controller disabled (error norm fixed at 0.5, step factor 1) and Newton converged far below the truncation error.
"""
import numpy as np
import pytest

from shell.integrators import Radau5, integrate
from shell.integrators.reference_problems import FreeFreeBeamModes, TorqueFreeRigidBody, linear_oscillator


class UniformStepRadau5(Radau5):
    """Radau IIA 5 with step control disabled: every step has the size given as ``step``."""

    def _error_norm(self, err, y_new):
        return 0.5

    def _accepted_step_factor(self, h, error_norm, safety, recompute_jac):
        return 1.0


def _problems():
    fun, exact = linear_oscillator(1.0)
    body = TorqueFreeRigidBody((100.0, 200.0, 300.0), (0.3, -0.5, 1.0))
    beam = FreeFreeBeamModes(f_max=10.0)
    return {
        # name: (fun, y0, t_end, exact final state, fastest rate omega_max in rad/s)
        "oscillator": (fun, np.array([1.0, 0.0]), 4.0, exact(4.0), 1.0),
        "rigid_body": (body.euler_equations(), np.array([0.3, -0.5, 1.0]), 8.0, body.omega(8.0), 1.0),
        "beam": (beam.fun, beam.y0, 0.5, beam.exact(0.5), beam.omega[-1]),
    }


PROBLEMS = _problems()
# (method, theoretical order, step * omega_max for the coarse run; the fine run halves it). The steps keep
# the error well above round-off and inside the asymptotic range.
METHODS = [("euler", 1, 0.004), ("heun", 2, 0.02), ("rk4", 4, 0.1), ("rk8", 8, 0.4),
           ("bs32", 3, 0.05), ("dopri5", 5, 0.2), ("dop853", 8, 0.4), ("radau5", 5, 0.1)]


def _final_error(method, problem, h):
    fun, y0, t_end, y_exact, _ = PROBLEMS[problem]
    if method == "radau5":
        # Newton converges to ~1e-13 absolute at this tolerance, far below the truncation errors measured
        r = integrate(UniformStepRadau5, fun, 0.0, y0, t_end, step=h, max_step=h, rtol=1e-9, atol=1e-9)
        assert r.nrejected == 0 and r.nsteps == round(t_end / h)
    elif method in ("bs32", "dopri5", "dop853"):
        r = integrate(method, fun, 0.0, y0, t_end, step=h, max_step=h, rtol=1.0, atol=1.0)
        assert r.nrejected == 0 and r.nsteps == round(t_end / h)
    else:
        r = integrate(method, fun, 0.0, y0, t_end, step=h)
    assert r.status == "finished"
    return np.linalg.norm(r.y[:, -1] - y_exact)


@pytest.mark.parametrize("problem", sorted(PROBLEMS))
@pytest.mark.parametrize("method, order, kappa", METHODS)
def test_observed_order_matches_theory(method, order, kappa, problem):
    omega_max = PROBLEMS[problem][4]
    t_end = PROBLEMS[problem][2]
    n_coarse = int(np.ceil(t_end * omega_max / kappa))
    h = t_end / n_coarse
    e_coarse = _final_error(method, problem, h)
    e_fine = _final_error(method, problem, h / 2)
    slope = np.log2(e_coarse / e_fine)
    # one halving in the asymptotic range reproduces the order to within ~10%
    assert abs(slope - order) < 0.12 * order + 0.1, (method, problem, e_coarse, e_fine, slope)
