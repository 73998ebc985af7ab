"""Reaction wheels: momentum conservation with the bus, limits, imbalance jitter, cluster allocation."""

import textwrap

import numpy as np
import pytest
from numpy.testing import assert_allclose

from shell.log_file import read_log
from shell.scenario import build_simulation, parse_scenario


def _run(text, t_final, tmp_path, overrides=None):
    sim = build_simulation(parse_scenario(textwrap.dedent(text), "scene.yaml", overrides))
    sim.run(t_final, log_path=tmp_path / "run.h5")
    return read_log(tmp_path / "run.h5")


CLUSTER = """
multibody:
  bodies:
    - name: bus
      hinge: free
      mass: 500 kg
      inertia: "[[400, 5, 0], [5, 300, 0], [0, 0, 250]] kg*m^2"
      initial: {angular_velocity: "[2, -1, 3] deg/s"}
  nodes:
    - {name: acs, body: bus, position: "[0.3, 0.1, -0.2] m"}
models:
  demand: {type: Constant, config: {unit: N*m, shape: [3]}, parameters: {value: "[0.3, -0.2, 0.25] N*m"}}
  wheels:
    type: WheelCluster
    attach: {node: acs}
    parameters:
      spin_inertia: 0.05 kg*m^2
      max_torque: 0.2 N*m
      max_speed: 6000 rpm
      rw1.coulomb_friction: 0.002 N*m
      rw2.viscous_friction: 1e-5 N*m*s/rad
      rw3.coulomb_friction: 0.001 N*m
connections: [demand.y -> wheels.torque_command]
integrator: {method: rk4, step: 0.01 s}
log:
  rate: 10 Hz
  signals: [multibody.acs.rotation, multibody.acs.angular_velocity, wheels.rw1.momentum, wheels.rw2.momentum,
            wheels.rw3.momentum, wheels.rw4.momentum, wheels.rw1.motor_torque, wheels.rw4.motor_torque,
            wheels.loads.torque]
"""


def test_cluster_conserves_system_angular_momentum(tmp_path):
    log = _run(CLUSTER, 20.0, tmp_path)
    inertia = np.array([[400, 5, 0], [5, 300, 0], [0, 0, 250.0]])
    axes = np.array([[1, 0, 0], [0, 1, 0], [0, 0, 1], np.ones(3) / np.sqrt(3)])
    h = np.stack([log[f"wheels.rw{k}.momentum"] for k in (1, 2, 3, 4)], axis=1)
    body = np.einsum("ij,nj->ni", inertia, log["multibody.acs.angular_velocity"]) + h @ axes
    world = np.einsum("nij,nj->ni", log["multibody.acs.rotation"], body)
    # the node is off the center of mass but the bus does not translate (no net force): the
    # momentum about the origin is R (J omega + sum h a). RK4 at 10 ms over 20 s: drift ~1e-12 N m s.
    assert np.ptp(np.linalg.norm(h, axis=1)) > 1.0            # the wheels did exchange momentum
    assert_allclose(world, np.tile(world[0], (len(world), 1)), rtol=0, atol=1e-10)
    # the allocator splits the demand with pinv(-A): motor torque of wheel 4 = -(d . 1/sqrt3) * 0.75 ...
    demand = np.array([0.3, -0.2, 0.25])
    expected_motor = np.linalg.pinv(-axes.T) @ demand
    assert_allclose(log["wheels.rw4.motor_torque"][0], expected_motor[3], rtol=1e-14)


def test_torque_and_speed_limits(tmp_path):
    text = CLUSTER.replace('value: "[0.3, -0.2, 0.25] N*m"', 'value: "[0.0, 0.0, 0.5] N*m"').replace(
        "max_speed: 6000 rpm", "max_speed: 300 rpm").replace("rw1.coulomb_friction: 0.002 N*m", "")
    sim = build_simulation(parse_scenario(textwrap.dedent(text), "scene.yaml", None))
    sim.log(["wheels.rw3.wheel_speed", "wheels.rw3.motor_torque", "wheels.rw4.motor_torque"], "100 Hz")
    sim.run(30.0, log_path=tmp_path / "limits.h5")
    log = read_log(tmp_path / "limits.h5")
    speed = log["wheels.rw3.wheel_speed"]
    limit = 300 * np.pi / 30
    # pinv(-A) asks -0.375 N m of wheel 3 for 0.5 N m about z: clipped to the 0.2 N m limit
    assert np.all(np.abs(log["wheels.rw4.motor_torque"]) <= 0.2)
    assert abs(log["wheels.rw3.motor_torque"][0]) == pytest.approx(0.2, rel=1e-14)
    # once at the limit the motor stops driving: the speed stays within one step of torque (0.2 N m *
    # 10 ms / 0.05 kg m^2 = 0.04 rad/s) of the limit, friction then pulls it back
    assert np.max(np.abs(speed)) <= limit + 0.04 + 1e-9
    assert np.max(np.abs(speed)) > limit - 0.05


IMBALANCE = """
multibody:
  bodies:
    - {name: bus, hinge: locked, mass: 100 kg, inertia: "[10, 10, 10] kg*m^2"}
  nodes:
    - {name: rw, body: bus}
models:
  wheel:
    type: ReactionWheel
    attach: {node: rw}
    parameters: {spin_axis: [0, 0, 1], spin_inertia: 0.05 kg*m^2, static_imbalance: 2 g*cm,
                 dynamic_imbalance: 20 g*cm^2}
    initial: {momentum: 10.471975511965978 N*m*s}      # 0.05 kg m^2 * 2000 rpm
  command: {type: Constant, config: {unit: N*m}}
connections: [command.y -> wheel.torque_command]
integrator: {method: rk4, step: 0.001 s}
log: {rate: 1000 Hz, signals: [wheel.force, wheel.torque, wheel.wheel_speed]}
"""


def test_imbalance_forces_at_wheel_frequency_with_analytic_amplitude(tmp_path):
    log = _run(IMBALANCE, 0.5, tmp_path)
    omega = 2000 * np.pi / 30
    t = log["time"]
    assert_allclose(log["wheel.wheel_speed"], omega, rtol=1e-14)
    force = log["wheel.force"]
    u_s, u_d = 2e-3 * 1e-2, 20e-3 * 1e-4         # 2 g cm, 20 g cm^2 in SI
    # radial force U_s Omega^2 rotating at Omega in the plane normal to the axis (e1 = x for axis z)
    assert_allclose(np.hypot(force[:, 0], force[:, 1]), u_s * omega**2, rtol=1e-12)
    assert_allclose(force[:, 2], 0.0, atol=0)
    phase = np.unwrap(np.arctan2(force[:, 1], force[:, 0]))
    assert_allclose(phase - phase[0], omega * t, atol=1e-9)          # RK4 angle error < 1e-9 rad
    torque = log["wheel.torque"]
    assert_allclose(np.hypot(torque[:, 0], torque[:, 1]), u_d * omega**2, rtol=1e-12)
    # spectrum: one line at the wheel frequency
    spectrum = np.abs(np.fft.rfft(force[:-1, 0]))
    frequencies = np.fft.rfftfreq(len(t) - 1, 1e-3)
    assert frequencies[np.argmax(spectrum)] == pytest.approx(omega / (2 * np.pi), abs=2.0)


BODY_WHEEL = """
multibody:
  bodies:
    - {name: bus, hinge: free, mass: 500 kg, inertia: "[[400, 5, 0], [5, 300, 0], [0, 0, 250]] kg*m^2",
       initial: {angular_velocity: "[2, -1, 3] deg/s"}}
    - {name: wheel, parent: bus, hinge: revolute, axis: [0, 0, 1], mass: 5 kg, inertia: "[0.03, 0.03, 0.05] kg*m^2"}
  nodes:
    - {name: acs, body: bus}
models:
  command: {type: Constant, config: {unit: N*m}, parameters: {value: 0.1 N*m}}
  motor: {type: ReactionWheelMotor, attach: {hinge: wheel}, parameters: {viscous_friction: 1e-4 N*m*s/rad}}
connections: [command.y -> motor.torque_command]
integrator: {method: rk4, step: 0.01 s}
log: {rate: 10 Hz, signals: [multibody.q, multibody.u, multibody.acs.angular_velocity]}
"""

STATE_WHEEL = """
multibody:
  bodies:
    - {name: bus, hinge: free, mass: 505 kg, inertia: "[[400.03, 5, 0], [5, 300.03, 0], [0, 0, 250]] kg*m^2",
       initial: {angular_velocity: "[2, -1, 3] deg/s"}}
  nodes:
    - {name: acs, body: bus}
models:
  command: {type: Constant, config: {unit: N*m}, parameters: {value: 0.1 N*m}}
  wheel: {type: ReactionWheel, attach: {node: acs},
          parameters: {spin_inertia: 0.05 kg*m^2, viscous_friction: 1e-4 N*m*s/rad},
          initial: {momentum: 0.0026179938779914945 N*m*s}}    # J_w a.omega: at rest relative to the bus
connections: [command.y -> wheel.torque_command]
integrator: {method: rk4, step: 0.01 s}
log: {rate: 10 Hz, signals: [multibody.acs.angular_velocity]}
"""


def test_wheel_body_and_momentum_representations_agree(tmp_path):
    sim = build_simulation(parse_scenario(textwrap.dedent(BODY_WHEEL), "body.yaml", None))
    sim.run(10.0, log_path=tmp_path / "body.h5")
    body = read_log(tmp_path / "body.h5")
    system = sim.models[sim.model_index["multibody"]].system
    h = np.array([system.angular_momentum(q, u) for q, u in zip(body["multibody.q"], body["multibody.u"])])
    # the wheel body spins up (hinge torque internal): angular momentum conserved to RK4 truncation
    assert_allclose(h, np.tile(h[0], (len(h), 1)), rtol=0, atol=1e-12 * np.linalg.norm(h[0]))
    state = _run(STATE_WHEEL, 10.0, tmp_path)
    # same wheel as a state of the ReactionWheel model (spin inertia out of the bus, transverse in):
    # the same bus motion: both are exact for the same physics (measured 3.5e-18 rad/s); round-off bound
    assert np.ptp(body["multibody.acs.angular_velocity"][:, 2]) > 1e-3
    assert_allclose(state["multibody.acs.angular_velocity"], body["multibody.acs.angular_velocity"],
                    rtol=0, atol=1e-14)


def test_spin_momentum_output_is_the_momentum_state_along_the_axis(tmp_path):
    """ReactionWheel.spin_momentum = h a (what MrpFeedback.wheel_momentum sums): equal to the logged state
    times the spin axis, to J_w (a . omega + Omega) a from the logged speed, and the system momentum
    R (J omega + sum of the outputs) is conserved as with the states (see the test above)."""
    scene = CLUSTER.replace("wheels.loads.torque]", "wheels.loads.torque, wheels.rw1.spin_momentum, "
                            "wheels.rw2.spin_momentum, wheels.rw3.spin_momentum, wheels.rw4.spin_momentum, "
                            "wheels.rw4.wheel_speed]")
    log = _run(scene, 5.0, tmp_path)
    inertia = np.array([[400, 5, 0], [5, 300, 0], [0, 0, 250.0]])
    axes = np.array([[1, 0, 0], [0, 1, 0], [0, 0, 1], np.ones(3) / np.sqrt(3)])
    outputs = [log[f"wheels.rw{k}.spin_momentum"] for k in (1, 2, 3, 4)]
    for k, a in enumerate(axes):
        assert_allclose(outputs[k], log[f"wheels.rw{k + 1}.momentum"][:, None] * a, rtol=0, atol=1e-15)
    omega = log["multibody.acs.angular_velocity"]
    assert_allclose(outputs[3], (0.05 * (omega @ axes[3] + log["wheels.rw4.wheel_speed"]))[:, None] * axes[3],
                    rtol=1e-12, atol=1e-15)
    body = np.einsum("ij,nj->ni", inertia, omega) + sum(outputs)
    world = np.einsum("nij,nj->ni", log["multibody.acs.rotation"], body)
    assert np.ptp(np.linalg.norm(sum(outputs), axis=1)) > 0.5
    assert_allclose(world, np.tile(world[0], (len(world), 1)), rtol=0, atol=1e-10)
