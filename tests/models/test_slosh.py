"""Slosh equivalents: pendulum frequency sqrt(a / L) and spring-mass sqrt(k / m) under acceleration;
momentum conserved by a damped pendulum in a free vehicle."""

import textwrap

import numpy as np
from numpy.testing import assert_allclose

from shell.log_file import read_log
from shell.scenario import build_simulation, parse_scenario


def _frequency(t, signal):
    """Angular frequency from the mean interval between upward zero crossings (linear interpolation)."""
    s = signal - signal.mean()
    i = np.nonzero((s[:-1] < 0) & (s[1:] >= 0))[0]
    crossings = t[i] - s[i] * (t[i + 1] - t[i]) / (s[i + 1] - s[i])
    return 2 * np.pi / np.mean(np.diff(crossings))


TANK = """
multibody:
  gravity: "[0, 0, -12] m/s^2"        # the stage's axial acceleration, 12 m/s^2 (equivalence principle)
  bodies:
    - {name: tank, hinge: locked, mass: 1000 kg, inertia: "[500, 500, 300] kg*m^2"}
    - name: slosh
      parent: tank
      hinge: HINGE
      AXES
      mass: 50 kg
      com: "COM m"
      inertia: "[0.001, 0.001, 0.001] kg*m^2"
      inboard_position: "[0, 0, 1.5] m"
      initial: INITIAL
models:
  liquid:
    type: SloshSpringDamper
    config: CONFIG
    attach: {hinge: slosh}
    parameters: PARAMETERS
integrator: {method: rk4, step: 0.002 s}
log: {rate: 500 Hz, signals: [multibody.slosh.q]}
"""


def _tank(tmp_path, **fields):
    text = textwrap.dedent(TANK)
    for key, value in fields.items():
        text = text.replace(key, value)
    sim = build_simulation(parse_scenario(text, "tank.yaml", None))
    sim.run(12.0, log_path=tmp_path / "tank.h5")
    return read_log(tmp_path / "tank.h5")


def test_pendulum_slosh_frequency_is_sqrt_a_over_l(tmp_path):
    length = 0.8
    log = _tank(tmp_path, HINGE="ujoint", AXES="axes: [[1, 0, 0], [0, 1, 0]]", COM=f"[0, 0, -{length}]",
                INITIAL="{angle: [0.01, 0.0]}", CONFIG="{dofs: 2}", PARAMETERS="{damping: [0, 0]}")
    # point mass (inertia 1e-3 about its COM) on a massless rod: omega^2 = a m L / (m L^2 + I_c);
    # amplitude 0.01 rad shifts the period by theta^2/16 = 6e-6
    expected = np.sqrt(12.0 * 50 * length / (50 * length**2 + 0.001))
    assert_allclose(_frequency(log["time"], log["multibody.slosh.q"][:, 0]), expected, rtol=2e-5)


def test_spring_mass_slosh_frequency_is_sqrt_k_over_m(tmp_path):
    log = _tank(tmp_path, HINGE="prismatic", AXES="axis: [1, 0, 0]", COM="[0, 0, 0]",
                INITIAL="{displacement: 0.01 m}", CONFIG="{dofs: 1, kind: translational}",
                PARAMETERS="{stiffness: [2000], damping: [0]}")
    # lateral spring: the axial acceleration does not enter; sampling error of the crossing < 1e-6
    assert_allclose(_frequency(log["time"], log["multibody.slosh.q"][:, 0]), np.sqrt(2000 / 50.0), rtol=1e-5)


def test_damped_pendulum_in_a_free_vehicle_conserves_momentum(tmp_path):
    text = textwrap.dedent("""
    multibody:
      bodies:
        - name: stage
          hinge: free
          mass: 1000 kg
          inertia: "[500, 500, 300] kg*m^2"
          initial: {angular_velocity: "[0.5, -0.3, 0.2] rad/s", velocity: "[1, 2, 3] m/s"}
        - {name: slosh, parent: stage, hinge: ujoint, axes: [[1, 0, 0], [0, 1, 0]], mass: 50 kg,
           com: "[0, 0, -0.8] m", inertia: "[0.1, 0.1, 0.1] kg*m^2", inboard_position: "[0, 0, 1.5] m",
           initial: {angle: [0.3, -0.2], angle_rate: [0.1, 0.0]}}
    models:
      liquid: {type: SloshSpringDamper, attach: {hinge: slosh}, parameters: {damping: "[20, 20] N*m*s/rad"}}
    integrator: {method: rk4, step: 0.002 s}
    log: {rate: 10 Hz, signals: [multibody.q, multibody.u]}
    """)
    sim = build_simulation(parse_scenario(text, "free.yaml", None))
    sim.run(5.0, log_path=tmp_path / "free.h5")
    log = read_log(tmp_path / "free.h5")
    system = sim.models[sim.model_index["multibody"]].system
    h = np.array([system.angular_momentum(q, u) for q, u in zip(log["multibody.q"], log["multibody.u"])])
    p = np.array([system.linear_momentum(q, u) for q, u in zip(log["multibody.q"], log["multibody.u"])])
    energy = np.array([system.kinetic_energy(q, u) for q, u in zip(log["multibody.q"], log["multibody.u"])])
    # the damper is internal: momenta constant to RK4 truncation (h = 2 ms), while energy is dissipated
    assert_allclose(h, np.tile(h[0], (len(h), 1)), rtol=0, atol=1e-9 * np.linalg.norm(h[0]))
    assert_allclose(p, np.tile(p[0], (len(p), 1)), rtol=0, atol=1e-9 * np.linalg.norm(p[0]))
    assert energy[-1] < energy[0] - 1.0
