"""The closed-form reference solutions are checked independently of any integrator: they satisfy their
differential equations (central differences) and conserve what the physics conserves."""
import numpy as np
import pytest
from numpy.testing import assert_allclose

from shell.integrators.reference_problems import (FreeFreeBeamModes, TipForcedBeam, TorqueFreeRigidBody,
                                                  free_free_beam_roots, linear_oscillator)

RIGID_CASES = [  # (principal moments, initial body rates): both solution families, unsorted axes, odd permutations
    ((100.0, 200.0, 300.0), (0.3, -0.5, 1.0)),
    ((100.0, 200.0, 300.0), (-1.0, 0.4, 0.1)),
    ((250.0, 200.0, 300.0), (0.1, -0.4, 0.03)),
    ((300.0, 100.0, 200.0), (1.0, 0.2, -0.1)),
]


def _central_difference(fn, t, h=1e-5):
    return (fn(t + h) - fn(t - h)) / (2 * h)


@pytest.mark.parametrize("inertia, w0", RIGID_CASES)
def test_jacobi_elliptic_solution_satisfies_euler_equations(inertia, w0):
    body = TorqueFreeRigidBody(inertia, w0)
    fun = body.euler_equations()
    assert_allclose(body.omega(0.0), w0, atol=1e-14)
    I = np.array(inertia)
    for t in (0.7, 13.1, 101.3):
        w = body.omega(t)
        # central-difference truncation ~ h^2 |w'''| / 6 ~ 1e-11 for these rates
        assert_allclose(_central_difference(body.omega, t), fun(t, w), atol=1e-9)
        assert np.sum(I * w * w) == pytest.approx(body.two_T, rel=1e-13)  # kinetic energy
        assert np.sum((I * w) ** 2) == pytest.approx(body.H2, rel=1e-13)  # |angular momentum|


def test_separatrix_and_symmetric_body_refused():
    with pytest.raises(ValueError, match="distinct"):
        TorqueFreeRigidBody((100.0, 100.0, 300.0), (0.1, 0.2, 0.3))
    with pytest.raises(ValueError, match="separatrix"):
        TorqueFreeRigidBody((100.0, 200.0, 300.0), (0.0, 1.0, 0.0))


def test_free_free_beam_roots_match_published_values():
    # Blevins (1979) Table 8-1, free-free beam: lambda_i = 4.73004074, 7.85320462, 10.9956078, 14.1371655
    assert_allclose(free_free_beam_roots(4), [4.730040744862704, 7.853204624095838, 10.995607838001671,
                                              14.137165491257464], rtol=1e-12)


def test_beam_modal_model_exact_solution_and_frequency_range():
    beam = FreeFreeBeamModes(f_max=100.0)
    f = beam.omega / (2 * np.pi)
    assert f[0] == f[1] == 0.0 and f[2] == pytest.approx(1.0) and 90.0 < f[-1] <= 100.0
    assert_allclose(beam.exact(0.0), beam.y0, atol=1e-18)
    for t in (0.013, 0.5):
        assert_allclose(_central_difference(beam.exact, t, h=1e-6), beam.fun(t, beam.exact(t)),
                        rtol=1e-6, atol=1e-9)


def test_damped_oscillator_exact_solution():
    fun, exact = linear_oscillator(3.0, 0.1)
    for t in (0.0, 0.4, 2.0):
        assert_allclose(_central_difference(exact, t, h=1e-6), fun(t, exact(t)), atol=1e-8)


def test_tip_forced_beam_exact_response():
    problem = TipForcedBeam(f_max=30.0)
    assert_allclose(problem.exact(0.0), 0.0, atol=1e-18)  # starts at rest
    for t in (0.05, 3.0):
        y = problem.exact(t)
        assert_allclose(_central_difference(problem.exact, t, h=1e-6), problem.fun(t, y), rtol=1e-6,
                        atol=1e-9 * np.abs(problem.fun(t, y)).max())
