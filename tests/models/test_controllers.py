"""Controllers: PD steady-state error vs exact value and PID removing it; LQR from a file against the
exact sampled closed loop; the user-function hook reproducing the compiled PD controller."""

import textwrap

import numpy as np
import pytest
import scipy.linalg
from numba import njit
from numpy.testing import assert_allclose

from shell.assembly import Assembly
from shell.log_file import read_log
from shell.model import InputPort, Model, ModelError, OutputPort, State
from shell.models.controllers import LqrStateFeedback
from shell.scenario import build_simulation, parse_scenario
from shell.simulation import Simulation

DISTURBED = """
multibody:
  bodies:
    - {name: bus, hinge: free, mass: 100 kg, inertia: "[10, 20, 30] kg*m^2"}
  nodes:
    - {name: acs, body: bus}
models:
  disturbance: {type: Constant, config: {unit: N*m, shape: [3]}, parameters: {value: "[0, 0, 0.05] N*m"}}
  controller:
    type: PidAttitudeController
    rate: 10 Hz
    parameters: {kp: "[4, 4, 4] N*m/rad", ki: "[KI, KI, KI] N*m/(rad*s)", kd: "[20, 20, 20] N*m*s/rad"}
  total: {type: NodeLoadSum, config: {count: 2}}
connections:
  - multibody.acs.attitude -> controller.attitude
  - multibody.acs.angular_velocity -> controller.angular_velocity
  - controller.torque -> total.torque_0
  - disturbance.y -> total.torque_1
  - total.torque -> multibody.acs.torque
integrator: {method: rk4, step: 0.05 s}
"""


def _yaw_error(ki, t_final):
    sim = build_simulation(parse_scenario(textwrap.dedent(DISTURBED).replace("KI", str(ki)), "pid.yaml", None))
    sim.run(t_final)
    q = sim.signal("multibody.acs.attitude")
    return 2.0 * np.arctan2(q[3], q[0]), sim


def test_pd_steady_state_error_is_exact_and_pid_removes_it():
    # at rest the PD torque balances the disturbance: kp * 2 sin(theta / 2) = d exactly
    theta_pd, _ = _yaw_error(0.0, 150.0)
    assert_allclose(theta_pd, 2 * np.arcsin(0.05 / (2 * 4.0)), rtol=1e-12)  # settled: transient e^{-0.2 t}
    theta_pid, sim = _yaw_error(0.5, 150.0)
    # integral action: the error decays (slowest closed-loop pole ~ e^{-0.15 t}) below 1e-6 of the PD error
    assert abs(theta_pid) < 1e-6 * abs(theta_pd)
    # the integral torque holds the disturbance: -ki I + d = 0
    assert_allclose(0.5 * sim.signal("controller.integral")[2], 0.05, rtol=1e-6)


@njit(cache=True)
def _plant_outputs(t, x, z, u, p, y):
    y[0] = x[0]
    y[1] = x[1]


@njit(cache=True)
def _plant_derivatives(t, x, z, u, p, xdot):
    xdot[0] = x[1]
    xdot[1] = u[0]


class DoubleIntegrator(Model):
    """x'' = u as states [x, v] (test plant, not registered)."""

    inputs = (InputPort("u", "", (1,), "acceleration"),)
    outputs = (OutputPort("x", "", (2,), "position, velocity"),)
    continuous_states = (State("x", "", (2,), (1.0, 0.0), "position, velocity"),)
    state_outputs = staticmethod(_plant_outputs)
    derivatives = staticmethod(_plant_derivatives)


@pytest.mark.parametrize("suffix", [".csv", ".npy", ".h5"])
def test_lqr_from_file_matches_the_exact_sampled_closed_loop(tmp_path, suffix):
    period = 0.2
    ad = np.array([[1.0, period], [0.0, 1.0]])
    bd = np.array([[period**2 / 2], [period]])
    q, r = np.diag([1.0, 0.1]), np.array([[0.5]])
    p = scipy.linalg.solve_discrete_are(ad, bd, q, r)
    gain = np.linalg.solve(r + bd.T @ p @ bd, bd.T @ p @ ad)
    path = tmp_path / f"gain{suffix}"
    if suffix == ".csv":
        np.savetxt(path, gain, delimiter=",", fmt="%.17g")
    elif suffix == ".npy":
        np.save(path, gain)
    else:
        import h5py

        with h5py.File(path, "w") as f:
            f["K"] = gain
    scene = Assembly("scene")
    scene.add(DoubleIntegrator("plant"))
    scene.add(LqrStateFeedback("lqr", gain_file=str(path), period=period))
    scene.connect("plant.x", "lqr.state")
    scene.connect("lqr.command", "plant.u")
    sim = Simulation(scene, integrator="rk4", step=0.05)
    x = np.array([1.0, 0.0])
    closed = ad - bd @ gain
    for k in range(1, 26):
        sim.run(k * period)
        x = closed @ x
        # RK4 is exact for the double integrator under a held input: only round-off
        assert_allclose(sim.signal("plant.x"), x, rtol=0, atol=1e-13)


def test_lqr_refuses_a_missing_or_bad_gain_file(tmp_path):
    with pytest.raises(ModelError, match="not found"):
        LqrStateFeedback("lqr", gain_file=str(tmp_path / "none.csv"))
    (tmp_path / "bad.csv").write_text("1, 2\n3, x\n")
    with pytest.raises(ModelError, match="bad.csv"):
        LqrStateFeedback("lqr", gain_file=str(tmp_path / "bad.csv"))


HOOK = '''
import numpy as np


def pd_law(t, signals):
    q, w = signals["attitude"], signals["angular_velocity"]
    # error quaternion q_c^* (x) q with q_c = identity is q itself
    error = 2.0 * np.sign(q[0]) * q[1:] if q[0] != 0 else 2.0 * q[1:]
    return {"torque": -np.array([10, 7.5, 6.25]) * error - np.array([90, 67.5, 56]) * w}
'''


def test_user_function_hook_reproduces_the_compiled_pd_controller(tmp_path):
    (tmp_path / "fsw.py").write_text(HOOK)
    base = open("configs/demo_attitude_hold.yaml").read()
    hooked = base.replace("""    type: PdAttitudeController
    rate: 10 Hz
    attach: {node: acs}           # attitude, angular_velocity in; torque out
    parameters:
      # natural frequency ~0.1 rad/s... 0.16 rad/s, damping ~0.7 for J = 250..400 kg m^2
      kp: "[10, 7.5, 6.25] N*m/rad"
      kd: "[90, 67.5, 56] N*m*s/rad"
      attitude_command: [1, 0, 0, 0]""", f"""    type: UserFunction
    rate: 10 Hz
    attach: {{node: acs}}
    config:
      function: {tmp_path / 'fsw.py'}:pd_law
      inputs: {{attitude: {{shape: [4]}}, angular_velocity: {{unit: rad/s, shape: [3]}}}}
      outputs: {{torque: {{unit: N*m, shape: [3]}}}}""")
    assert hooked != base
    logs = []
    for k, text in enumerate((base, hooked)):
        sim = build_simulation(parse_scenario(text, "demo.yaml", ["stop.time=30 s"]))
        sim.run(30.0, log_path=tmp_path / f"run{k}.h5")
        logs.append(read_log(tmp_path / f"run{k}.h5"))
    # same law in numpy instead of numba: identical up to floating-point reassociation
    assert_allclose(logs[1]["multibody.acs.attitude"], logs[0]["multibody.acs.attitude"], rtol=0, atol=1e-13)
    assert_allclose(logs[1]["controller.torque"], logs[0]["controller.torque"], rtol=0, atol=1e-12)


def test_user_function_errors_name_the_model_and_time(tmp_path):
    (tmp_path / "bad.py").write_text("def law(t, s):\n    return {'torque': [1.0, 2.0]}\n")
    from shell.models.user_hook import UserFunction

    hook = UserFunction("fsw", function=f"{tmp_path / 'bad.py'}:law", period=0.1,
                        inputs={"rate": {"unit": "rad/s", "shape": [3]}}, outputs={"torque": {"unit": "N*m", "shape": [3]}})
    with pytest.raises(ModelError, match=r"model fsw: user function output 'torque' at t = 0 s: expected shape \(3,\)"):
        hook.update(0.0, np.zeros(0), np.zeros(3), np.zeros(3), np.zeros(0))
    with pytest.raises(ModelError, match="has no 'nope'"):
        UserFunction("fsw", function=f"{tmp_path / 'bad.py'}:nope", period=0.1, inputs={"a": {}}, outputs={"b": {}})
