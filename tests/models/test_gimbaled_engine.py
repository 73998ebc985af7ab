"""Gimbaled engine: prescribed gimbal motion followed exactly with the airframe reacting (momentum of
the free vehicle conserved); torque mode with the load-torque loop closed is a frictionless bearing
(TM-2020-5008164 App. F.4): the airframe then feels only the engine's mass at the gimbal, not its
rotational inertia, while the prescribed (rigid) gimbal couples that inertia in."""

import textwrap

import numpy as np
from numpy.testing import assert_allclose

from shell.log_file import read_log
from shell.scenario import build_simulation, parse_scenario

FREE = """
multibody:
  bodies:
    - {name: stage, hinge: free, mass: 2000 kg, inertia: "[7000, 7000, 500] kg*m^2",
       initial: {angular_velocity: "[0.01, -0.02, 0.03] rad/s", velocity: "[0, 0, 50] m/s"}}
    - {name: engine, parent: stage, hinge: ujoint, axes: [[1, 0, 0], [0, 1, 0]], prescribed: true,
       mass: 150 kg, com: "[0, 0, -0.8] m", inertia: "[40, 40, 25] kg*m^2", inboard_position: "[0, 0, -4] m"}
models:
  command: {type: Constant, config: {unit: rad, shape: [2]}, parameters: {value: "[0.05, -0.03] rad"}}
  gimbal: {type: GimbalActuator, attach: {hinge: engine}}
connections: [command.y -> gimbal.angle_command]
integrator: {method: rk4, step: 0.001 s}
log: {rate: 100 Hz, signals: [multibody.q, multibody.u, multibody.engine.q, multibody.engine.u, gimbal.reference]}
"""


def test_prescribed_gimbal_follows_the_servo_and_the_vehicle_reacts(tmp_path):
    sim = build_simulation(parse_scenario(textwrap.dedent(FREE), "free.yaml", None))
    sim.run(1.0, log_path=tmp_path / "free.h5")
    log = read_log(tmp_path / "free.h5")
    # the hinge integrates the prescribed acceleration: it equals the servo reference to round-off
    assert_allclose(log["multibody.engine.q"], log["gimbal.reference"][:, :2], rtol=0, atol=1e-13)
    assert_allclose(log["multibody.engine.u"], log["gimbal.reference"][:, 2:], rtol=0, atol=1e-12)
    # rate limit: the acceleration switches off inside an RK4 step, so the rate may pass the limit by
    # at most one step of the largest acceleration, w^2 * 0.05 rad * 1 ms = 0.045 rad/s
    assert np.max(np.abs(log["multibody.engine.u"])) <= np.radians(20.0) + 0.045
    assert np.max(np.abs(log["multibody.engine.u"])) > np.radians(19.0)             # ... and reached
    assert_allclose(log["multibody.engine.q"][-1], [0.05, -0.03], atol=2e-4)         # settled (w = 30 rad/s)
    # the airframe reacts: internal motion leaves the free vehicle's momenta constant (RK4, 1 ms)
    system = sim.models[sim.model_index["multibody"]].system
    h = np.array([system.angular_momentum(q, u) for q, u in zip(log["multibody.q"], log["multibody.u"])])
    p = np.array([system.linear_momentum(q, u) for q, u in zip(log["multibody.q"], log["multibody.u"])])
    assert_allclose(h, np.tile(h[0], (len(h), 1)), rtol=0, atol=1e-10 * np.linalg.norm(h[0]))
    assert_allclose(p, np.tile(p[0], (len(p), 1)), rtol=0, atol=1e-10 * np.linalg.norm(p[0]))
    assert np.ptp(log["multibody.u"][:, 0]) > 1e-3                                   # the stage did react


PINNED = """
multibody:
  bodies:
    - {name: stage, hinge: revolute, axis: [1, 0, 0], mass: 2000 kg, inertia: "[7000, 7000, 500] kg*m^2"}
    - {name: engine, parent: stage, hinge: ujoint, axes: [[1, 0, 0], [0, 1, 0]], prescribed: PRESCRIBED,
       mass: 150 kg, com: "[0, 0, 0] m", inertia: "[40, 40, 25] kg*m^2", inboard_position: "[0, 0, -4] m"}
models:
  drive: {type: Constant, config: {unit: N*m, shape: [1]}, parameters: {value: "[1000] N*m"}}
  command: {type: Constant, config: {unit: rad, shape: [2]}, parameters: {value: "[0, 0] rad"}}
  gimbal: {type: GimbalActuator, config: {mode: MODE}, attach: {hinge: engine}}
connections: [drive.y -> multibody.stage.torque, command.y -> gimbal.angle_command]
integrator: {method: rk4, step: 0.001 s}
log: {rate: 100 Hz, signals: [multibody.stage.q, multibody.engine.q]}
"""


def test_load_torque_feedback_closed_is_a_frictionless_bearing(tmp_path):
    t_final = 0.5
    results = {}
    for mode, prescribed in (("torque", "false"), ("prescribed", "true")):
        text = textwrap.dedent(PINNED).replace("MODE", mode).replace("PRESCRIBED", prescribed)
        sim = build_simulation(parse_scenario(text, "pinned.yaml", None))
        sim.run(t_final, log_path=tmp_path / f"{mode}.h5")
        results[mode] = read_log(tmp_path / f"{mode}.h5")
    t = results["torque"]["time"]
    # torque mode, zero gains: the engine (COM at the gimbal) keeps its inertial attitude, the stage
    # feels its mass at 4 m only: J = 7000 + 150 * 4^2; the gimbal angle is minus the stage angle.
    # Constant angular acceleration: RK4 exact to round-off.
    theta = 0.5 * 1000.0 / (7000 + 150 * 16) * t**2
    assert_allclose(results["torque"]["multibody.stage.q"][:, 0], theta, rtol=0, atol=1e-13)
    assert_allclose(results["torque"]["multibody.engine.q"][:, 0], -theta, rtol=0, atol=1e-13)
    # prescribed (rigid gimbal, load-torque loop open): the engine's own inertia is coupled in
    theta_rigid = 0.5 * 1000.0 / (7000 + 150 * 16 + 40) * t**2
    assert_allclose(results["prescribed"]["multibody.stage.q"][:, 0], theta_rigid, rtol=0, atol=1e-13)
    assert_allclose(results["prescribed"]["multibody.engine.q"], 0.0, atol=0)
