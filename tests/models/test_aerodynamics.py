"""Aerodynamics: weathercock oscillation of a pinned body in a steady wind at sqrt(q S C_N_alpha l / J);
axial force and the exponential atmosphere against their formulas."""

import textwrap

import numpy as np
from numpy.testing import assert_allclose

from shell.log_file import read_log
from shell.models.aerodynamics import Aerodynamics
from shell.scenario import build_simulation, parse_scenario

PINNED = """
multibody:
  bodies:
    - {name: rocket, hinge: revolute, axis: [0, 1, 0], mass: 100 kg, inertia: "[50, 50, 5] kg*m^2",
       initial: {angle: 0.01 rad}}
  nodes:
    - {name: body_axis, body: rocket}
models:
  aero:
    type: Aerodynamics
    attach: {node: body_axis}
    # the nose (node z) points into a 30 m/s wind blowing along -z: air flows nose to tail
    parameters: {reference_area: 0.5 m^2, normal_force_slope: 2.0 /rad, center_of_pressure: -1.5 m,
                 wind: "[0, 0, -30] m/s", scale_height: 7200 m}
integrator: {method: rk4, step: 0.002 s}
log: {rate: 500 Hz, signals: [multibody.rocket.q, aero.angle_of_attack]}
"""


def test_weathercock_frequency(tmp_path):
    sim = build_simulation(parse_scenario(textwrap.dedent(PINNED), "pinned.yaml", None))
    sim.run(10.0, log_path=tmp_path / "aero.h5")
    log = read_log(tmp_path / "aero.h5")
    t, angle = log["time"], log["multibody.rocket.q"][:, 0]
    assert_allclose(log["aero.angle_of_attack"][0], 0.01, rtol=1e-12)
    q = 0.5 * 1.225 * 30.0**2                      # the node sits at the pin (altitude 0)
    # pinned at the node, center of pressure 1.5 m behind it: restoring torque q S C_N_a alpha l
    # (small angles: alpha = theta, normal force ~ the lateral force to O(theta^2))
    inertia = 50.0                                  # about the pin, which is the center of mass
    omega = np.sqrt(q * 0.5 * 2.0 * 1.5 / inertia)
    s = angle - angle.mean()
    i = np.nonzero((s[:-1] < 0) & (s[1:] >= 0))[0]
    crossings = t[i] - s[i] * (t[i + 1] - t[i]) / (s[i + 1] - s[i])
    measured = 2 * np.pi / np.mean(np.diff(crossings))
    # amplitude 0.01 rad: nonlinear terms (alpha vs sin, normal vs lateral) shift omega by O(theta^2)
    assert_allclose(measured, omega, rtol=1e-4)


def test_axial_force_and_atmosphere():
    model = Aerodynamics("aero", reference_area=2.0, normal_force_slope=3.0, axial_coefficient=0.4,
                         center_of_pressure=-2.0)
    y = np.empty(8)
    altitude, speed = 5000.0, 300.0
    u = np.concatenate([[0.0, 0.0, altitude], [0.0, 0.0, speed], np.eye(3).reshape(-1)])
    model.feedthrough_outputs(0.0, None, None, u, model.p, y)
    q = 0.5 * 1.225 * np.exp(-altitude / 7200.0) * speed**2
    assert_allclose(y[6], q, rtol=1e-14)
    assert_allclose(y[0:3], [0.0, 0.0, -q * 2.0 * 0.4], rtol=1e-14)        # pure drag at zero alpha
    assert_allclose(y[3:6], 0.0, atol=0)
    assert y[7] == 0.0
