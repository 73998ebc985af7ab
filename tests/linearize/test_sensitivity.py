"""Parameter sensitivities and trim over named parameters (shell.analysis.sensitivity, shell.analysis.trim), written
by name into the run's Context (shell.names): a model parameter and a rigid body's mass properties.

Plant: a rigid bus at rest (omega = 0, so no gyroscopic term) with a constant torque T and force F at its center of
mass: omega' = J^-1 T, v' = F / m. Closed-form derivatives: d(omega')/dT = J^-1, d(omega')/dJ_ij = -J^-1 E_ij J^-1 T
(E_ij the symmetric unit pair), d(v')/dm = -F / m^2. Tolerances: the 4-point scheme with Richardson extrapolation
at tolerance 1e-10 leaves ~1e-9 relative (its own error estimate says so, and is checked to bound the error).
"""

import numpy as np
import pytest

from shell.analysis.linearize import LinearizationError
from shell.analysis.sensitivity import parameter_sensitivities
from shell.analysis.trim import trim
from shell.scenario import build_simulation, load_scenario

SCENE = """
multibody:
  gravity: "[0, 0, 0] m/s^2"
  bodies:
    - {name: bus, hinge: free, mass: 50 kg, inertia: "[[40, 3, 0], [3, 30, 0], [0, 0, 25]] kg*m^2"}
  nodes:
    - {name: acs, body: bus}
models:
  torque: {type: Constant, config: {unit: N*m, shape: [3]}, parameters: {value: "[1, -2, 3] N*m"}}
  push: {type: Constant, config: {unit: N, shape: [3]}, parameters: {value: "[4, 0, -5] N"}}
connections:
  - torque.y -> multibody.acs.torque
  - push.y -> multibody.acs.force
integrator: {method: rk4, step: 10 ms}
"""
J = np.array([[40.0, 3.0, 0.0], [3.0, 30.0, 0.0], [0.0, 0.0, 25.0]])
T, F, M = np.array([1.0, -2.0, 3.0]), np.array([4.0, 0.0, -5.0]), 50.0


@pytest.fixture
def sim(tmp_path):
    path = tmp_path / "bus.yaml"
    path.write_text(SCENE)
    return build_simulation(load_scenario(path))


def test_sensitivities_to_a_model_parameter_and_to_mass_properties(sim):
    p_before = sim.context.p.copy()
    s = parameter_sensitivities(sim, ["torque.value", "multibody.bus.inertia", "multibody.bus.mass"],
                                outputs=["multibody.acs.angular_acceleration"])
    omega_rows = [s.state_names.index(f"multibody.u[{k}]") for k in range(3)]
    v_rows = [s.state_names.index(f"multibody.u[{k}]") for k in range(3, 6)]
    Jinv = np.linalg.inv(J)
    columns = {name: k for k, name in enumerate(s.parameter_names)}
    expected = {f"torque.value[{k}]": Jinv[:, k] for k in range(3)}
    for i, j in [(0, 0), (0, 1), (1, 1), (2, 2), (0, 2)]:
        E = np.zeros((3, 3))
        E[i, j] = E[j, i] = 1.0
        expected[f"multibody.bus.inertia[{i},{j}]"] = -Jinv @ E @ Jinv @ T
    for name, column in expected.items():
        np.testing.assert_allclose(s.rates[omega_rows, columns[name]], column, rtol=1e-8, atol=1e-11, err_msg=name)
        assert np.all(np.abs(s.rates[omega_rows, columns[name]] - column) <= s.errors["rates"][omega_rows,
                                                                                                columns[name]] + 1e-13)
    np.testing.assert_allclose(s.rates[v_rows, columns["multibody.bus.mass"]], -F / M**2, rtol=1e-8, atol=1e-12)
    np.testing.assert_allclose(s.rates[omega_rows, columns["multibody.bus.mass"]], 0.0, atol=1e-12)
    # the node's angular acceleration output is omega' itself (node axes = bus axes)
    np.testing.assert_allclose(s.outputs[:, columns["torque.value[1]"]], Jinv[:, 1], rtol=1e-8, atol=1e-11)
    # the operating values are back: the parameters, and the engine's mass properties
    assert sim.context.p.tobytes() == p_before.tobytes()
    np.testing.assert_array_equal(sim.context.get("multibody.bus.inertia"), J)
    np.testing.assert_allclose(sim.plan.derivative(0.0, sim.x)[-6:-3], Jinv @ T, rtol=1e-14)


def test_trim_solves_for_named_parameters(sim):
    """Hold the state; find the torque and force giving omega' = (0.1, 0.2, 0.3) rad/s^2 and v' = 0: T = J omega',
    F = 0. The solution stays in the run's Context."""
    target = np.array([0.1, 0.2, 0.3, 0.0, 0.0, 0.0])
    result = trim(sim, hold=["multibody.q", "multibody.u"], derivatives=["multibody.u"],
                  targets={"multibody.u": target}, free_parameters=["torque.value", "push.value"])
    assert result.success and result.max_residual < 1e-10, result
    np.testing.assert_allclose(result.parameter_values["torque.value"], J @ target[:3], rtol=1e-9)
    np.testing.assert_allclose(result.parameter_values["push.value"], 0.0, atol=1e-9)
    np.testing.assert_allclose(sim.context.get("torque.value"), J @ target[:3], rtol=1e-9)
    np.testing.assert_allclose(sim.plan.derivative(0.0, sim.x)[-6:], target, rtol=1e-9, atol=1e-11)


def test_parameters_that_a_run_cannot_take_by_name_are_refused(sim):
    with pytest.raises(LinearizationError, match="not a parameter"):
        parameter_sensitivities(sim, ["multibody.bus.initial.angular_velocity"])
    with pytest.raises(LinearizationError, match="did you mean 'torque.value'"):
        parameter_sensitivities(sim, ["torque.valeu"])
