"""Linearization core against analytic Jacobians (TM-2020-5008164 Sec. 7.1.3 and 7.3)."""

from __future__ import annotations

import numpy as np
import pytest

from shell.analysis.linearize import LinearizationError, _skew, linearize
from tests.linearize.plants import chain_matrices, chain_scene, pendulum_scene, spinning_body_scene

SCHEMES = [(2, False), (2, True), (4, False), (4, True)]
MASS, STIFFNESS, DAMPING = [2.0, 3.0, 0.5], [400.0, 250.0, 90.0], [3.0, 1.5, 0.2]


@pytest.mark.parametrize("points,richardson", SCHEMES)
def test_linear_chain_is_exact(points, richardson):
    """A linear scene: every scheme is exact up to round-off. Tolerance 1e-10 absolute on entries of
    size up to 1e3 (the issue's requirement; measured <= 2.3e-13)."""
    sim = chain_scene(gain=0.5)
    model = linearize(sim, ["amplifier.u"], ["chain.position", "chain.acceleration", "sensor.y"],
                      points=points, richardson=richardson)
    A, B = chain_matrices(MASS, STIFFNESS, DAMPING)
    B = B * 0.5 * 1000.0  # amplifier gain, kN -> N
    n = len(MASS)
    C = np.vstack([np.eye(n, 2 * n), A[n:], 1000.0 * np.eye(n, 2 * n)])  # position; acceleration; mm
    D = np.vstack([np.zeros((n, n)), B[n:], np.zeros((n, n))])
    for name, got, want in (("A", model.A, A), ("B", model.B, B), ("C", model.C, C), ("D", model.D, D)):
        np.testing.assert_allclose(got, want, rtol=0, atol=1e-10, err_msg=name)
    assert model.state_units == ["m"] * n + ["m/s"] * n
    assert model.input_units == ["kN"] * n and model.output_units[-1] == "mm"
    assert model.max_error < 1e-6  # only the round-off term 16 eps max|F| / h (h = 1e-5 for order 2)


def test_linearization_leaves_the_simulation_untouched():
    """The opened connection and the state are restored: the run afterwards is bit-identical."""
    reference = chain_scene()
    reference.run(0.5)
    sim = chain_scene()
    linearize(sim, ["chain.force[1]"], ["sensor.y"])
    sim.run(0.5)
    np.testing.assert_array_equal(sim.x, reference.x)
    np.testing.assert_array_equal(sim.signals, reference.signals)


def test_port_elements_and_operating_input_values():
    """``port[k]`` selects one element; an operating input value moves the operating point (the chain
    is linear, so only u and y shift: y0 = C x0 + D u0)."""
    sim = chain_scene()
    model = linearize(sim, ["chain.force[2]"], ["chain.acceleration[2]"], input_values={"chain.force[2]": 4.0})
    assert model.B.shape == (6, 1) and model.C.shape == (1, 6)
    np.testing.assert_allclose(model.D, [[1.0 / MASS[2]]], rtol=1e-13)
    A, _ = chain_matrices(MASS, STIFFNESS, DAMPING)
    x0 = model.operating_point["x"]
    np.testing.assert_allclose(model.operating_point["y"], A[5] @ x0 + 4.0 / MASS[2], rtol=1e-12)


def test_spinning_rigid_body_in_tangent_coordinates():
    """Free rigid body spinning at w0 (torque-free Euler equations), attitude in rotation-vector tangent
    coordinates q = q0 (x) Exp(phi): phi' = -[w0 x] phi / 2 + dw, J dw' = ([J w0 x] - [w0 x] J) dw + dtau,
    position' = R v. Analytic; the rotational part is nonlinear, FD truncation at tol 1e-10 stays
    below 1e-9 (measured 1.1e-13)."""
    J = np.array([[20.0, 0.5, 0.0], [0.5, 25.0, -0.3], [0.0, -0.3, 30.0]])
    w0 = np.array([0.3, -0.5, 0.8])
    q0 = np.array([0.8, 0.6, 0.0, 0.0])
    sim = spinning_body_scene(J, w0, q0)
    model = linearize(sim, ["multibody.cg.torque", "multibody.cg.force"], ["multibody.cg.angular_velocity"])
    assert model.A.shape == (12, 12)  # 3 rotation-vector + 3 position + 6 velocity states
    assert np.linalg.matrix_rank(model.A[:, 6:]) == 6
    R = np.array([[1.0, 0.0, 0.0], [0.0, 0.28, -0.96], [0.0, 0.96, 0.28]])  # of q0: 73.74 deg about x
    A = np.zeros((12, 12))
    A[0:3, 0:3] = -0.5 * _skew(w0)
    A[0:3, 6:9] = np.eye(3)
    A[3:6, 9:12] = R
    A[6:9, 6:9] = np.linalg.solve(J, _skew(J @ w0) - _skew(w0) @ J)
    A[9:12, 9:12] = -_skew(w0)  # v' = -w x v (body axes) at v = 0: dv' = -w0 x dv
    B = np.zeros((12, 6))
    B[6:9, 0:3] = np.linalg.inv(J)
    B[9:12, 3:6] = np.eye(3) / 50.0
    np.testing.assert_allclose(model.A, A, rtol=0, atol=1e-9)
    np.testing.assert_allclose(model.B, B, rtol=0, atol=1e-9)
    np.testing.assert_allclose(model.C, np.hstack([np.zeros((3, 6)), np.eye(3), np.zeros((3, 3))]), atol=1e-9)
    assert np.all(model.errors["A"] < 1e-8)


@pytest.mark.parametrize("points,richardson", SCHEMES)
@pytest.mark.parametrize("tolerance", [1e-3, 1e-5, 1e-7])
def test_error_estimate_bounds_true_error_on_a_pendulum(points, richardson, tolerance):
    """Pendulum at 0.7 rad under gravity (nonlinear): A21 = -m g l cos(theta)/I, the tip position
    (l sin, -l cos, 0) has dC/dtheta = l (cos, sin, 0). Every entry's reported error bounds its true
    error, and the true error is within the requested relative tolerance."""
    angle, length, mass, g = 0.7, 1.5, 2.0, 9.81
    sim, _ = pendulum_scene(angle, length, mass, g)
    model = linearize(sim, ["multibody.rod.torque"], ["multibody.tip.position"], points=points,
                      richardson=richardson, tolerance=tolerance)
    inertia = mass * length ** 2 + 1e-3
    A = np.array([[0.0, 1.0], [-mass * g * length * np.cos(angle) / inertia, 0.0]])
    C = np.array([[length * np.cos(angle), 0.0], [length * np.sin(angle), 0.0], [0.0, 0.0]])
    true_A, true_C = np.abs(model.A - A), np.abs(model.C - C)
    assert np.all(true_A <= model.errors["A"]), (true_A, model.errors["A"])
    assert np.all(true_C <= model.errors["C"]), (true_C, model.errors["C"])
    assert true_A[1, 0] <= tolerance * abs(A[1, 0])
    assert np.max(true_C) <= tolerance * length
    np.testing.assert_allclose(model.B, [[0.0], [1.0 / inertia]], rtol=1e-9)


def test_requests_are_checked():
    sim = chain_scene()
    with pytest.raises(LinearizationError, match="not an input port"):
        linearize(sim, ["chain.position"], ["sensor.y"])
    with pytest.raises(LinearizationError, match="has no port or state 'forse'"):
        linearize(sim, ["chain.forse"], ["sensor.y"])
    with pytest.raises(LinearizationError, match="element 3 does not exist"):
        linearize(sim, ["chain.force[3]"], ["sensor.y"])
    with pytest.raises(LinearizationError, match="expected 2 or 4"):
        linearize(sim, ["chain.force"], ["sensor.y"], points=3)
    with pytest.raises(LinearizationError, match="not a listed input"):
        linearize(sim, ["chain.force"], ["sensor.y"], input_values={"amplifier.u": [1, 2, 3]})


def test_steps_follow_tolerance_order_and_scales():
    """h_j = max(|x0_j|, scale_j) tol^(1/order): order 6 for 4-point Richardson; a per-body entry
    (``multibody.rod.hinge_q``) or a model state may set the typical size."""
    sim, _ = pendulum_scene(0.0)
    model = linearize(sim, ["multibody.rod.torque"], ["multibody.rod.q"], tolerance=1e-12,
                      scales={"multibody.rod.hinge_q": 0.1, "multibody.rod.torque": 50.0})
    np.testing.assert_allclose(model.method["state_steps"], [0.1 * 1e-2, 1e-2], rtol=1e-12)
    np.testing.assert_allclose(model.method["input_steps"], [50.0 * 1e-2], rtol=1e-12)
    with pytest.raises(LinearizationError, match="neither a state nor a listed input"):
        linearize(sim, ["multibody.rod.torque"], ["multibody.rod.q"], scales={"multibody.rod.angle": 1.0})
