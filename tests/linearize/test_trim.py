"""Trim against analytic equilibria."""

from __future__ import annotations

import numpy as np
import pytest

from shell.analysis.linearize import LinearizationError, _skew, linearize
from shell.analysis.trim import trim
from tests.linearize.plants import chain_matrices, chain_scene, pendulum_scene, spinning_body_scene


def test_pendulum_held_by_a_torque():
    """Hinge torque tau holds the pendulum where m g l sin(theta) = tau; the linearization there has
    A21 = -m g l cos(theta) / I. Residual and angle to 1e-12 (Newton-type convergence to round-off)."""
    sim, _ = pendulum_scene(0.1)
    result = trim(sim, hold=["multibody.u"], inputs=["multibody.rod.torque"],
                  input_values={"multibody.rod.torque": [10.0]})
    theta = np.arcsin(10.0 / (2.0 * 9.81 * 1.5))
    assert result.success and result.max_residual < 1e-12
    np.testing.assert_allclose(sim.x, [theta, 0.0], atol=1e-12)
    model = linearize(sim, ["multibody.rod.torque"], ["multibody.rod.q"], input_values=result.input_values)
    np.testing.assert_allclose(model.operating_point["xdot"], 0.0, atol=1e-12)
    np.testing.assert_allclose(model.A[1, 0], -2.0 * 9.81 * 1.5 * np.cos(theta) / (2.0 * 1.5 ** 2 + 1e-3),
                               rtol=1e-9)


def test_chain_forces_for_a_static_deflection():
    """Positions held at the chain's initial values, velocities at zero: the forces that make every
    acceleration vanish are f = K x (analytic, round-off tolerance 1e-10 N)."""
    sim = chain_scene()
    sim.x[3:] = 0.0
    result = trim(sim, hold=["chain.position", "chain.velocity"], free_inputs=["chain.force"])
    A, B = chain_matrices([2.0, 3.0, 0.5], [400.0, 250.0, 90.0], [3.0, 1.5, 0.2])
    expected = -np.linalg.solve(B[3:], A[3:] @ sim.x)
    np.testing.assert_allclose(result.input_values["chain.force"], expected, rtol=0, atol=1e-10)
    assert result.max_residual < 1e-10


def test_spinning_body_torque_for_steady_spin():
    """A body spinning at w0 about a non-principal axis needs tau = w0 x J w0 to keep w0 (Euler)."""
    J = np.array([[20.0, 0.5, 0.0], [0.5, 25.0, -0.3], [0.0, -0.3, 30.0]])
    w0 = np.array([0.3, -0.5, 0.8])
    sim = spinning_body_scene(J, w0, (0.8, 0.6, 0.0, 0.0))
    result = trim(sim, hold=["multibody.q", "multibody.u"], free_inputs=["multibody.cg.torque"],
                  derivatives=["multibody.u"])
    np.testing.assert_allclose(result.input_values["multibody.cg.torque"], _skew(w0) @ J @ w0, atol=1e-10)
    assert result.max_residual < 1e-12


def test_trim_refuses_unknown_states():
    sim = chain_scene()
    with pytest.raises(LinearizationError, match="not a continuous state"):
        trim(sim, hold=["chain.positions"])
