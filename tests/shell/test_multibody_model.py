"""The engine inside the shell: node/hinge ports, attachment, feedthrough accelerations, closed loop."""

import numpy as np
import pytest
from numpy.testing import assert_allclose

from shell.log_file import read_log
from shell.scenario import ScenarioError

SPINUP = """
multibody:
  bodies:
    - name: bus
      hinge: free
      mass: 100 kg
      inertia: "[10, 30, 40] kg*m^2"
  nodes:
    - {name: center, body: bus}
    - {name: tip, body: bus, position: "[2, 0, 0] m"}
models:
  thruster_pair: {type: Constant, config: {unit: N*m, shape: [3]}, parameters: {value: "[0, 0, 4] N*m"}}
connections:
  - thruster_pair.y -> multibody.center.torque
log:
  rate: 10 Hz
  signals: [multibody.center.attitude, multibody.center.angular_velocity, multibody.tip.linear_acceleration,
            multibody.tip.position, multibody.bus.u]
"""


def test_constant_torque_spin_up_matches_the_analytic_rotation(scene, tmp_path):
    sim = scene(SPINUP, overrides=["integrator.step=0.01 s"])
    sim.run(3.0, log_path=tmp_path / "spin.h5")
    log = read_log(tmp_path / "spin.h5")
    t = log["time"]
    alpha = 4.0 / 40.0                       # T / J_zz about a principal axis: no gyroscopic coupling
    theta = 0.5 * alpha * t**2
    expected_q = np.stack([np.cos(theta / 2), 0 * t, 0 * t, np.sin(theta / 2)], axis=1)
    # RK4 on the quaternion kinematics with h = 0.01 s: local error ~ (omega h)^5, global < 1e-10
    assert_allclose(log["multibody.center.attitude"], expected_q, atol=1e-10)
    assert_allclose(log["multibody.center.angular_velocity"][:, 2], alpha * t, atol=1e-12)
    # node 2 m out on x: world position rotates with the body
    assert_allclose(log["multibody.tip.position"], np.stack([2 * np.cos(theta), 2 * np.sin(theta), 0 * t], 1),
                    atol=1e-9)
    # classical acceleration of the tip, node (= body) axes: alpha x r + omega x (omega x r)
    omega = alpha * t
    expected_a = np.stack([-2 * omega**2, 2 * alpha + 0 * t, 0 * t], axis=1)
    assert_allclose(log["multibody.tip.linear_acceleration"], expected_a, atol=1e-10)


def test_derivative_plan_skips_engine_outputs_nobody_reads_continuously(scene):
    sim = scene(SPINUP)
    d = sim.diagram
    assert [d.models[s.model].path for s in d.derivative_stages] == ["thruster_pair"]
    assert {d.models[s.model].path for s in d.output_order} == {"multibody", "thruster_pair"}


def test_attaching_an_assembly_binds_node_signals(scene, tmp_path):
    sim = scene("""
    seed: 3
    multibody:
      bodies:
        - name: bus
          hinge: free
          mass: 500 kg
          inertia: "[400, 300, 250] kg*m^2"
          initial: {angular_velocity: "[1, -2, 1] deg/s"}
      nodes:
        - {name: acs, body: bus}
    models:
      loop:
        type: AttitudeHoldLoop
        attach: {node: acs}
        parameters:
          period: 0.1 s
          gyro_noise: 0.001 deg/s
          controller.kp: "[40, 30, 25] N*m/rad"
          controller.kd: "[200, 150, 125] N*m*s/rad"
    stop: {time: 60 s}
    log: {rate: 1 Hz, signals: [multibody.acs.angular_velocity, loop.controller.torque, loop.gyro.y]}
    """)
    bound = sorted((c.source_model.path + "." + c.source_port, c.destination_model.path + "." + c.destination_port)
                   for c in sim.connections)
    assert bound == [("loop.controller.torque", "multibody.acs.torque"),
                     ("loop.gyro.y", "loop.controller.angular_velocity"),
                     ("multibody.acs.angular_velocity", "loop.gyro.u"),
                     ("multibody.acs.attitude", "loop.controller.attitude")]
    sim.run(60.0, log_path=tmp_path / "loop.h5")
    log = read_log(tmp_path / "loop.h5")
    rate = log["multibody.acs.angular_velocity"]
    assert np.linalg.norm(rate[0]) == pytest.approx(np.radians(np.sqrt(6)), rel=1e-12)
    assert np.linalg.norm(rate[-1]) < 1e-3 * np.linalg.norm(rate[0])  # damped to the gyro noise level
    assert np.any(log["loop.gyro.y"] != log["multibody.acs.angular_velocity"])  # noise present


def test_attach_to_unknown_node_is_refused(scene):
    with pytest.raises(ScenarioError, match=r"scene.yaml:10: attach pd to node imu: .*no node 'imu'; nodes: \['acs'\]"):
        scene("""
        multibody:
          bodies:
            - {name: bus, hinge: free, mass: 1 kg, inertia: "[1, 1, 1] kg*m^2"}
          nodes:
            - {name: acs, body: bus}
        models:
          pd:
            type: PdAttitudeController
            attach: {node: imu}
        """)


def test_multibody_errors_name_the_line_and_key(scene):
    with pytest.raises(ScenarioError, match=r"scene.yaml:7: multibody.bodies\[0\]\(bus\).inertia: .*kg\*m\*\*2"):
        scene("""
        multibody:
          bodies:
            - name: bus
              hinge: free
              mass: 1 kg
              inertia: "[1, 1, 1] kg*m"
        """)
    with pytest.raises(ScenarioError, match=r"scene.yaml:6: multibody.bodies\[0\]\(bus\).initial.angle: 'angle' "
                                            r"does not apply to a free hinge"):
        scene("""
        multibody:
          bodies:
            - name: bus
              hinge: free
              initial: {angle: 1 deg}
              mass: 1 kg
              inertia: "[1, 1, 1] kg*m^2"
        """)


def test_revolute_hinge_ports_carry_units(scene):
    sim = scene("""
    multibody:
      gravity: "[0, 0, -9.81] m/s^2"
      bodies:
        - name: arm
          hinge: revolute
          axis: [0, 1, 0]
          mass: 2 kg
          com: "[0.5, 0, 0] m"
          inertia: "[0.001, 0.01, 0.01] kg*m^2"
          initial: {angle: 0 deg}
    models:
      hold: {type: Constant, config: {unit: N*m, shape: [1]}, parameters: {value: "[-9.81] N*m"}}
    connections:
      - hold.y -> multibody.arm.torque
    """)
    sim.run(1.0)
    # gravity torque about +y of the horizontal arm is r x F = (0.5 x) x (-19.62 z) = +9.81 N m;
    # the motor's -9.81 N m balances it: no motion
    assert_allclose(sim.signal("multibody.arm.q"), [0.0], atol=1e-13)
    port = sim.port_info[("multibody", "arm.torque")]
    assert port.unit == "N*m" and port.shape == (1,)
