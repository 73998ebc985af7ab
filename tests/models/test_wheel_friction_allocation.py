"""Reaction-wheel Stribeck friction against the Armstrong-Helouvry curve and an independent spin-down
solution; saturation-aware allocation keeping the demanded torque's direction (through YAML and the CLI)."""

import textwrap

import numpy as np
from numpy.testing import assert_allclose
from scipy.integrate import solve_ivp

from shell.cli import main
from shell.log_file import read_log
from shell.scenario import build_simulation, parse_scenario

J, COULOMB, STRIBECK, STRIBECK_SPEED, VISCOUS, SMOOTHING = 0.01, 0.02, 0.03, 20.0, 2e-4, 0.1

SPIN_DOWN = f"""
multibody:
  gravity: "[0, 0, 0] m/s^2"
  bodies:
    - {{name: base, hinge: locked, mass: 10 kg, inertia: "[1, 1, 1] kg*m^2"}}
  nodes:
    - {{name: mount, body: base}}
models:
  wheel:
    type: ReactionWheel
    attach: {{node: mount}}
    parameters: {{spin_axis: [0, 0.6, 0.8], spin_inertia: {J} kg*m^2, coulomb_friction: {COULOMB} N*m,
                 stribeck_friction: {STRIBECK} N*m, stribeck_speed: {STRIBECK_SPEED} rad/s,
                 viscous_friction: {VISCOUS} N*m*s/rad, coulomb_smoothing_speed: {SMOOTHING} rad/s}}
    initial: {{momentum: {J * 120.0} N*m*s}}
  command: {{type: Constant, config: {{unit: N*m, shape: []}}, parameters: {{value: 0 N*m}}}}
connections:
  - command.y -> wheel.torque_command
integrator: {{method: rk4, step: 0.005 s}}
stop: {{time: 40 s}}
log:
  rate: 10 Hz
  signals: [wheel.wheel_speed, wheel.torque]
"""


def stribeck_curve(speed):
    """Armstrong-Helouvry, Dupont, Canudas de Wit (1994) eq. 4 with the regularized sign of the model."""
    return ((COULOMB + STRIBECK * np.exp(-(speed / STRIBECK_SPEED) ** 2)) * np.tanh(speed / SMOOTHING)
            + VISCOUS * speed)


def test_stribeck_spin_down_follows_the_curve_and_the_independent_solution(tmp_path):
    path = tmp_path / "spin_down.yaml"
    path.write_text(SPIN_DOWN)
    assert main(["run", str(path), "-o", str(tmp_path / "spin.h5"), "--quiet"]) == 0
    log = read_log(tmp_path / "spin.h5")
    t, speed = log["time"], log["wheel.wheel_speed"]
    # the torque on the (fixed) mount is the friction torque along the spin axis: the curve, pointwise
    assert_allclose(log["wheel.torque"], np.outer(stribeck_curve(speed), [0.0, 0.6, 0.8]), rtol=1e-13, atol=1e-16)
    # the speed history against scipy's DOP853 solution of J Omega' = -tau_f(Omega)
    moving = speed > 1.0          # below ~1 rad/s the tanh regularization is stiff; the wheel stops there
    reference = solve_ivp(lambda _, w: -stribeck_curve(w) / J, (0.0, 40.0), [120.0], method="DOP853",
                          t_eval=t[moving], rtol=1e-12, atol=1e-12)
    assert_allclose(speed[moving], reference.y[0], rtol=0, atol=1e-7)   # RK4 at 5 ms: ~1e-9 rad/s local
    # the Stribeck rise is crossed: deceleration near 20 rad/s exceeds the Coulomb + viscous level
    assert moving.sum() > 100 and speed[moving].min() < 5.0


def test_zero_stribeck_is_the_former_coulomb_viscous_law():
    from shell.models.reaction_wheel import friction_torque

    for w in (-50.0, -0.03, 0.0, 0.02, 7.0, 300.0):
        assert friction_torque(w, 0.01, 0.1, 1e-4) == 0.01 * np.tanh(w / 0.1) + 1e-4 * w
        assert friction_torque(w, 0.01, 0.1, 1e-4, 0.0, 5.0) == 0.01 * np.tanh(w / 0.1) + 1e-4 * w


BETA = np.radians(54.7356103172)
AXES = np.array([[np.sin(BETA) * np.cos(k * np.pi / 2), np.sin(BETA) * np.sin(k * np.pi / 2), np.cos(BETA)]
                 for k in range(4)])

SLEW = """
multibody:
  gravity: "[0, 0, 0] m/s^2"
  bodies:
    - name: bus
      hinge: free
      mass: 800 kg
      inertia: "[[900, 15, -10], [15, 800, 20], [-10, 20, 600]] kg*m^2"
      initial: {attitude: [0.7543859649122807, 0.17543859649122806, 0.3508771929824561, -0.5263157894736842]}
  nodes:
    - {name: acs, body: bus}
models:
  controller:
    type: MrpFeedback
    rate: 10 Hz
    parameters: {k: 3.5 N*m, p: 30 N*m*s/rad, inertia: "[[900, 15, -10], [15, 800, 20], [-10, 20, 600]] kg*m^2"}
  allocator:
    type: PseudoInverseAllocator
    config: {demand: 3, actuators: 4}
    parameters: {effectiveness: EFFECTIVENESS, max_command: LIMIT}
WHEELS
  total: {type: NodeLoadSum, config: {count: 4}}
connections:
  - multibody.acs.attitude -> controller.attitude
  - multibody.acs.angular_velocity -> controller.angular_velocity
  - controller.torque -> allocator.demand
CONNECTIONS
  - total.torque -> multibody.acs.torque
integrator: {method: rk4, step: 0.02 s}
stop: {time: 30 s}
log:
  rate: 10 Hz
  signals: [controller.torque, allocator.command_1, allocator.command_2, allocator.command_3, allocator.command_4,
            rw1.motor_torque, rw2.motor_torque, rw3.motor_torque, rw4.motor_torque]
"""


def _slew_scene(limit):
    wheels = "\n".join(
        f"  rw{k + 1}: {{type: ReactionWheel, parameters: {{spin_axis: {a.tolist()}, spin_inertia: 0.08 kg*m^2, "
        f"max_torque: 0.2 N*m}}}}" for k, a in enumerate(AXES))
    links = "\n".join(f"  - allocator.command_{k + 1} -> rw{k + 1}.torque_command\n"
                      f"  - multibody.acs.angular_velocity -> rw{k + 1}.angular_velocity\n"
                      f"  - rw{k + 1}.torque -> total.torque_{k}" for k in range(4))
    effectiveness = (-AXES.T).tolist()
    return (SLEW.replace("EFFECTIVENESS", str(effectiveness)).replace("LIMIT", limit).replace("WHEELS", wheels)
            .replace("CONNECTIONS", links))


def _delivered(log):
    motor = np.column_stack([log[f"rw{k}.motor_torque"] for k in (1, 2, 3, 4)])
    return motor @ (-AXES)     # torque on the bus from the motors


def test_saturation_aware_allocation_keeps_the_demanded_direction(tmp_path):
    path = tmp_path / "limited.yaml"
    path.write_text(_slew_scene("0.2 N*m"))
    assert main(["check", str(path)]) == 0
    assert main(["run", str(path), "-o", str(tmp_path / "limited.h5"), "--quiet"]) == 0
    log = read_log(tmp_path / "limited.h5")
    demand = log["controller.torque"]
    commands = np.column_stack([log[f"allocator.command_{k}"] for k in (1, 2, 3, 4)])
    # the 82 deg error asks up to 0.88 N m of one of the four 0.2 N m wheels
    unlimited = demand @ np.linalg.pinv(-AXES.T).T
    assert np.abs(unlimited).max() > 0.8
    assert np.abs(commands).max() <= 0.2 * (1 + 1e-12)
    delivered = _delivered(log)
    sin_angle = np.linalg.norm(np.cross(delivered, demand), axis=1) / (
        np.linalg.norm(delivered, axis=1) * np.linalg.norm(demand, axis=1) + 1e-300)
    assert sin_angle.max() < 1e-12         # direction kept exactly (round-off)
    scale = np.linalg.norm(delivered, axis=1) / np.linalg.norm(demand, axis=1)
    assert_allclose(scale, np.minimum(1.0, 0.2 / np.abs(unlimited).max(axis=1)), rtol=1e-12)

    # clipping by the wheels alone (no max_command) turns the produced torque away from the demand
    text = _slew_scene("0 N*m")
    sim = build_simulation(parse_scenario(text, "clipped.yaml", None))
    path = tmp_path / "clipped.h5"
    sim.run(30.0, log_path=path)
    clipped = read_log(path)
    delivered = _delivered(clipped)
    demand = clipped["controller.torque"]
    sin_angle = np.linalg.norm(np.cross(delivered, demand), axis=1) / (
        np.linalg.norm(delivered, axis=1) * np.linalg.norm(demand, axis=1))
    assert sin_angle.max() > 0.05


def test_max_command_refuses_a_negative_limit():
    text = textwrap.dedent(_slew_scene("-1 N*m"))
    try:
        build_simulation(parse_scenario(text, "neg.yaml", None))
    except Exception as exc:  # the bounds check of the parameter, located at its line
        assert "neg.yaml:" in str(exc) and "max_command" in str(exc)
    else:
        raise AssertionError("a negative max_command was accepted")
