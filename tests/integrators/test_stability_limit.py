"""The explicit stability limit on a flexible structure is where linear stability theory puts it: just
below ``r(zeta) / omega_max`` the highest mode decays, just above it grows; Radau IIA stays stable far
beyond it (the full sweep is benchmarks/stability_study.py)."""
import numpy as np
import pytest

from shell.integrators import INTEGRATORS, integrate, stability
from shell.integrators.reference_problems import FreeFreeBeamModes

from .test_order import UniformStepRadau5

ZETA = 0.005
BEAM = FreeFreeBeamModes(f_max=30.0, zeta=ZETA)


def top_mode_energy_ratio(method, h, n_steps, **options):
    n = BEAM.n_modes
    r = integrate(method, BEAM.fun, 0.0, BEAM.y0, n_steps * h, step=h, **options)
    if r.status != "finished":
        return np.inf
    k = n - 1

    def energy(y):
        return 0.5 * (y[n + k] ** 2 + BEAM.stiffness[k] * y[k] ** 2)

    return energy(r.y[:, -1]) / energy(BEAM.y0)


@pytest.mark.filterwarnings("ignore:overflow encountered:RuntimeWarning")  # the unstable runs overflow
@pytest.mark.parametrize("method", ["rk4", "rk8", "heun"])
def test_explicit_methods_fail_just_beyond_the_theoretical_limit(method):
    h_theory = stability.max_stable_step(INTEGRATORS[method].tableau, BEAM.omega[-1], ZETA)
    n_steps = 10000 if method == "heun" else 2000  # Heun's growth just past the limit is slow
    # the exact solution decays (0.5 % damping): any growth of the highest mode is numerical instability
    assert top_mode_energy_ratio(method, 0.98 * h_theory, n_steps) < 1.0
    assert top_mode_energy_ratio(method, 1.02 * h_theory, n_steps) > 1.0


def test_rk4_limit_matches_the_textbook_value():
    # HW II Fig. IV.2.1: RK4 reaches 2 sqrt(2) on the imaginary axis; light damping moves it out slightly
    r = stability.stability_radius(INTEGRATORS["rk4"].tableau, stability.mode_angle(ZETA))
    assert 2 * np.sqrt(2) < r < 2.85


def test_radau5_stable_at_a_thousand_times_the_explicit_limit():
    h = 1000.0 / BEAM.omega[-1]
    n = BEAM.n_modes
    r = integrate(UniformStepRadau5, BEAM.fun, 0.0, BEAM.y0, 50 * h, step=h, max_step=h, rtol=1e-9, atol=1e-12,
                  jac=BEAM.jacobian())
    assert r.status == "finished" and r.nsteps == 50

    def elastic_energy(y):
        return 0.5 * np.sum(y[n + 2:] ** 2 + BEAM.stiffness[2:] * y[2:n] ** 2)

    assert elastic_energy(r.y[:, -1]) < elastic_energy(BEAM.y0)
