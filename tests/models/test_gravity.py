"""Central-body gravity: two-body period and energy, J2 nodal regression, gravity-gradient torque."""

import textwrap

import numpy as np
from numpy.testing import assert_allclose

from shell.log_file import read_log
from shell.models.gravity import EARTH_J2, EARTH_MU, EARTH_RADIUS, central_body_acceleration, gravity_gradient_torque
from shell.scenario import build_simulation, parse_scenario

ORBIT = """
multibody:
  bodies:
    - name: sat
      hinge: free
      mass: 1000 kg
      inertia: "[100, 200, 300] kg*m^2"
      initial: {position: "{r0}", velocity: "{v0}"}
  nodes:
    - {name: cm, body: sat}
models:
  gravity:
    type: CentralBodyGravity
    attach: {node: cm}
    parameters: {mass: 1000 kg, j2: {j2}, gravity_gradient: 0}
integrator: {method: rk4, step: {step} s}
log:
  rate: {rate} Hz
  signals: [multibody.cm.position, multibody.sat.u]
"""


def _orbit(tmp_path, r0, v0, j2, t_final, step, rate):
    text = (textwrap.dedent(ORBIT).replace("{r0}", str([float(c) for c in r0]) + " m").replace("{v0}", str([float(c) for c in v0]) + " m/s")
            .replace("{j2}", repr(j2)).replace("{step}", repr(step)).replace("{rate}", repr(rate)))
    sim = build_simulation(parse_scenario(text, "orbit.yaml", None))
    sim.run(t_final, log_path=tmp_path / "orbit.h5")
    return read_log(tmp_path / "orbit.h5"), sim.signal("multibody.cm.position")


def test_two_body_orbit_period_and_energy(tmp_path):
    # ellipse a = 7000 km, e = 0.1 from perigee; attitude stays identity (no torque), so body axes = world
    a, e = 7.0e6, 0.1
    rp = a * (1 - e)
    vp = np.sqrt(EARTH_MU * (1 + e) / rp)
    period = 2 * np.pi * np.sqrt(a**3 / EARTH_MU)
    log, final_position = _orbit(tmp_path, (rp, 0.0, 0.0), (0.0, vp * np.cos(0.3), vp * np.sin(0.3)), 0.0, period, 1.0, 1.0)
    r = log["multibody.cm.position"]
    v = log["multibody.sat.u"][:, 3:6]
    energy = 0.5 * np.sum(v**2, axis=1) - EARTH_MU / np.linalg.norm(r, axis=1)
    # vis-viva: -mu / 2a; RK4 with 1 s steps (perigee rate 1.4e-3 rad/s): relative error ~1e-11
    assert_allclose(energy, -EARTH_MU / (2 * a), rtol=1e-10)
    # after the Kepler period the orbit closes: RK4 phase error over one orbit ~1e-10 of 44,000 km
    assert_allclose(final_position, [rp, 0.0, 0.0], rtol=0, atol=1e-3)


def test_j2_nodal_regression_matches_secular_theory(tmp_path):
    a, inclination = 6778.137e3, np.radians(51.6)
    v = np.sqrt(EARTH_MU / a)
    n_orbits = 6
    period = 2 * np.pi * np.sqrt(a**3 / EARTH_MU)
    log, _ = _orbit(tmp_path, (a, 0.0, 0.0), (0.0, v * np.cos(inclination), v * np.sin(inclination)), EARTH_J2,
                 n_orbits * period, 2.0, 0.5)
    r = log["multibody.cm.position"]
    vel = log["multibody.sat.u"][:, 3:6]
    h = np.cross(r, vel)
    node = np.unwrap(np.arctan2(h[:, 0], -h[:, 1]))
    # sample the osculating node at each ascending-node crossing (z from - to +): same phase each orbit,
    # so the short-period terms repeat and the slope is the secular rate
    crossings = np.nonzero((r[:-1, 2] < 0) & (r[1:, 2] >= 0))[0]
    t = log["time"]
    slope = np.polyfit(t[crossings], node[crossings], 1)[0]
    n = np.sqrt(EARTH_MU / a**3)
    secular = -1.5 * n * EARTH_J2 * (EARTH_RADIUS / a) ** 2 * np.cos(inclination)
    # first-order secular theory; osculating vs mean elements differ by O(J2) ~ 1e-3: tolerance 1 %
    assert_allclose(slope, secular, rtol=1e-2)


def test_gravity_gradient_torque_equals_point_mass_sum():
    """Brute force: a rigid cloud of point masses with inverse-square forces; its torque about the
    center of mass tends to 3 mu / r^3 r_hat x J r_hat with relative error O((size / r)^2)."""
    rng = np.random.default_rng(7)
    points = rng.normal(size=(40, 3)) * np.array([3.0, 2.0, 1.0])
    masses = rng.uniform(1.0, 5.0, size=40)
    points -= masses @ points / masses.sum()
    inertia = sum(m * (p @ p * np.eye(3) - np.outer(p, p)) for m, p in zip(masses, points))
    for distance in (1e5, 1e6):
        for _ in range(5):
            direction = rng.normal(size=3)
            r = distance * direction / np.linalg.norm(direction)
            brute = np.zeros(3)
            for m, p in zip(masses, points):
                g = np.empty(3)
                central_body_acceleration(r + p, EARTH_MU, EARTH_RADIUS, 0.0, g)
                brute += np.cross(p, m * g)
            formula = np.empty(3)
            gravity_gradient_torque(r, inertia.reshape(-1), EARTH_MU, formula)
            scale = 3 * EARTH_MU / distance**3 * np.abs(np.linalg.eigvalsh(inertia)).max()
            # next term of the expansion ~ (size / r) relative; size ~ 10 m
            assert_allclose(brute, formula, rtol=0, atol=scale * 50.0 / distance)


def test_model_outputs_rotate_into_node_axes():
    from scipy.spatial.transform import Rotation

    from shell.models.gravity import CentralBodyGravity

    inertia = np.array([[100.0, 3.0, -2.0], [3.0, 200.0, 5.0], [-2.0, 5.0, 300.0]])
    model = CentralBodyGravity("g", mass=500.0, inertia=inertia)
    rotation = Rotation.from_rotvec([0.3, -1.1, 0.7]).as_matrix()     # node -> world
    r = np.array([3.0e6, -5.5e6, 2.0e6])
    y = np.empty(9)
    model.feedthrough_outputs(0.0, None, None, np.concatenate([r, rotation.reshape(-1)]), model.p, y)
    g = np.empty(3)
    central_body_acceleration(r, EARTH_MU, EARTH_RADIUS, EARTH_J2, g)
    assert_allclose(y[6:9], rotation.T @ g, rtol=1e-14)
    assert_allclose(y[0:3], 500.0 * rotation.T @ g, rtol=1e-14)
    r_node = rotation.T @ r
    r_hat = r_node / np.linalg.norm(r_node)
    expected = 3 * EARTH_MU / np.linalg.norm(r) ** 3 * np.cross(r_hat, inertia @ r_hat)
    assert_allclose(y[3:6], expected, rtol=1e-12, atol=1e-12 * np.abs(expected).max())



def test_zonal_accelerations_are_the_gradient_of_the_zonal_potential():
    """U = -mu/r [1 - sum_n J_n (R/r)^n P_n(z/r)] (Legendre P2, P3, P4), differentiated numerically;
    each harmonic alone and all together, at points of all latitudes."""
    legendre = {2: lambda s: (3 * s**2 - 1) / 2, 3: lambda s: (5 * s**3 - 3 * s) / 2,
                4: lambda s: (35 * s**4 - 30 * s**2 + 3) / 8}
    rng = np.random.default_rng(5)
    for coefficients in ({2: 1e-3}, {3: -2.5e-6 * 100}, {4: -1.6e-6 * 100}, {2: 1e-3, 3: -2.5e-4, 4: -1.6e-4}):
        def zonal_potential(p):       # U minus its point-mass part -mu/r (differenced alone: less round-off)
            rn = np.linalg.norm(p)
            return EARTH_MU / rn * sum(j * (EARTH_RADIUS / rn) ** n * legendre[n](p[2] / rn)
                                       for n, j in coefficients.items())

        for _ in range(6):
            r = rng.normal(size=3)
            r *= 7.0e6 / np.linalg.norm(r)
            g = np.empty(3)
            central_body_acceleration(r, EARTH_MU, EARTH_RADIUS, coefficients.get(2, 0.0), g,
                                      coefficients.get(3, 0.0), coefficients.get(4, 0.0))
            g_zonal = g + EARTH_MU * r / np.linalg.norm(r) ** 3
            step = 10.0
            numeric = -np.array([(zonal_potential(r + step * e) - zonal_potential(r - step * e)) / (2 * step)
                                 for e in np.eye(3)])
            # central differences with a 10 m step: truncation (h/r)^2 ~ 2e-12 relative, round-off
            # 1e-16 * U_zonal / h ~ 1e-12 of the zonal acceleration
            assert_allclose(g_zonal, numeric, rtol=0, atol=1e-9 * np.abs(numeric).max())
