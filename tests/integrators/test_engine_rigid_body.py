"""The torque-free body through the multibody engine (dynamics.Multibody, one body on a free hinge):
body rates against the Jacobi-elliptic closed form, attitude through conservation of the world-frame
angular momentum, with quaternion renormalization and the quaternion gauge excluded from error control."""
import numpy as np
import pytest
from numpy.testing import assert_allclose

import dynamics
from shell.integrators import integrate, quaternion_gauge
from shell.integrators.reference_problems import TorqueFreeRigidBody

INERTIA = (100.0, 200.0, 300.0)
OMEGA0 = (0.3, -0.5, 1.0)


@pytest.fixture(scope="module")
def free_body():
    mb = dynamics.Multibody()
    mb.add_body("bus", None, mass=100.0, inertia=np.diag(INERTIA), hinge="free")
    system = mb.compile()
    nq = system.nq

    def fun(t, y):
        out = np.empty(nq + system.nu)
        out[:nq] = system.q_dot(y[:nq], y[nq:])
        out[nq:] = system.forward_dynamics(y[:nq], y[nq:])
        return out

    def normalize(y):
        system.normalize_quaternions(y[:nq])

    u0 = np.zeros(system.nu)
    u0[:3] = OMEGA0
    y0 = np.concatenate([system.neutral_configuration(), u0])
    return system, fun, normalize, y0


@pytest.mark.parametrize("method, options, tol", [
    ("dop853", dict(rtol=1e-12, atol=1e-12), 1e-10),
    ("dopri5", dict(rtol=1e-10, atol=1e-12), 1e-8),
    ("radau5", dict(rtol=1e-9, atol=1e-11), 1e-7),
    ("rk4", dict(step=0.01), 1e-8),
])
def test_engine_free_body_matches_closed_form(free_body, method, options, tol):
    system, fun, normalize, y0 = free_body
    nq = system.nq
    t_end = 20.0
    r = integrate(method, fun, 0.0, y0, t_end, normalize=normalize,
                  error_exclude=quaternion_gauge(system.quaternion_q_indices), **options)
    assert r.status == "finished"
    closed = TorqueFreeRigidBody(INERTIA, OMEGA0)
    # body-frame rates: the tolerance is the global error the method/tolerance pair delivers over 20 s
    assert_allclose(r.y[nq:nq + 3, -1], closed.omega(t_end), atol=tol)
    assert_allclose(r.y[nq + 3:, -1], 0.0, atol=1e-14)  # no force: the origin keeps zero velocity
    q_end = r.y[:nq, -1]
    assert np.linalg.norm(q_end[:4]) == pytest.approx(1.0, abs=1e-15)
    h0 = system.angular_momentum(y0[:nq], y0[nq:])
    h_end = system.angular_momentum(q_end, r.y[nq:, -1])
    assert_allclose(h_end, h0, atol=tol * 300.0)  # |I| ~ 300 kg m^2 times the rate tolerance
