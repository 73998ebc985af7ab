"""Eclipse (cylindrical and conical) and solar radiation pressure on flat plates.

References: the analytic entry and exit of a circular orbit into the shadow cylinder and the umbra and
penumbra cones (Vallado sec. 5.3 geometry, written independently of the model's apparent-disc formula),
the overlap of two discs integrated by brute force on a grid, and the closed-form force on a plate.
"""

import textwrap

import numpy as np
import pytest
from numpy.testing import assert_allclose
from scipy.optimize import brentq

from shell.log_file import read_log
from shell.model import ModelError
from shell.models.eclipse import conical_shadow, cylindrical_shadow
from shell.models.ephemeris import ASTRONOMICAL_UNIT, SUN_RADIUS
from shell.models.gravity import EARTH_MU, EARTH_RADIUS
from shell.models.srp import SOLAR_FLUX, SPEED_OF_LIGHT, SolarRadiationPressure
from shell.scenario import build_simulation, parse_scenario

A = 7000e3
SUN = ASTRONOMICAL_UNIT  # the Sun fixed on +x at 1 AU (a Constant block): the geometry is exact
N_MOTION = np.sqrt(EARTH_MU / A**3)

ORBIT = """
multibody:
  bodies:
    - name: sat
      hinge: free
      mass: 100 kg
      inertia: "[10, 10, 10] kg*m^2"
      initial: {position: "[{a}, 0, 0] m", velocity: "[0, {v}, 0] m/s"}
  nodes:
    - {name: cm, body: sat}
models:
  gravity: {type: CentralBodyGravity, attach: {node: cm}, parameters: {mass: 100 kg, j2: 0, gravity_gradient: 0}}
  sun: {type: Constant, config: {unit: m, shape: [3]}, parameters: {value: "[{sun}, 0, 0] m"}}
  cone: {type: Eclipse, attach: {node: cm}}
  cylinder: {type: Eclipse, config: {shadow: cylindrical}, attach: {node: cm}}
connections: [sun.y -> cone.sun_position, sun.y -> cylinder.sun_position]
integrator: {method: rk4, step: 1 s}
log: {rate: 10 Hz, signals: [cone.shadow_factor, cylinder.shadow_factor, multibody.cm.position]}
"""


def _cone_entries(a):
    """Orbit angles (from +x, the Sun direction) of penumbra entry, umbra entry, umbra exit, penumbra
    exit, from the shadow cones: penumbra cone apex between Earth and Sun at x = R D/(R_s + R), half
    angle asin((R_s + R)/D); umbra cone apex behind Earth at x = -R D/(R_s - R), half angle
    asin((R_s - R)/D) (Vallado sec. 5.3)."""
    R, Rs, D = EARTH_RADIUS, SUN_RADIUS, SUN
    xp, ap = R * D / (Rs + R), np.arcsin((Rs + R) / D)
    xu, au = -R * D / (Rs - R), np.arcsin((Rs - R) / D)

    def in_penumbra_cone(th):  # angle of (point - apex) from -x minus the half angle
        px, py = A * np.cos(th) - xp, A * np.sin(th)
        return np.arctan2(abs(py), -px) - ap

    def in_umbra_cone(th):  # angle of (point - apex) from +x minus the half angle
        px, py = A * np.cos(th) - xu, A * np.sin(th)
        return np.arctan2(abs(py), px) - au

    pen_in = brentq(in_penumbra_cone, np.pi / 2, np.pi)
    umb_in = brentq(in_umbra_cone, np.pi / 2, np.pi)
    return pen_in, umb_in, 2 * np.pi - umb_in, 2 * np.pi - pen_in


def test_circular_orbit_eclipse_entry_and_exit_times(tmp_path):
    text = ORBIT.replace("{a}", repr(A)).replace("{v}", repr(float(np.sqrt(EARTH_MU / A)))).replace("{sun}", repr(SUN))
    sim = build_simulation(parse_scenario(text, "eclipse.yaml", None))
    period = 2 * np.pi / N_MOTION
    sim.run(period, log_path=tmp_path / "e.h5")
    log = read_log(tmp_path / "e.h5")
    t = log["time"]
    # cylindrical: shadow for |theta - pi| < asin(R / a) (the orbit in the plane of the Sun)
    half = np.arcsin(EARTH_RADIUS / A)
    dark = t[log["cylinder.shadow_factor"] == 0.0]
    # logged at 0.1 s and the orbit's phase error under RK4 at 1 s is ~1e-7 rad: 0.1 s + 1e-3 s
    assert_allclose([dark[0], dark[-1]], [(np.pi - half) / N_MOTION, (np.pi + half) / N_MOTION], atol=0.11)
    assert set(np.unique(log["cylinder.shadow_factor"])) == {0.0, 1.0}
    nu = log["cone.shadow_factor"]
    expected = np.array(_cone_entries(A)) / N_MOTION
    measured = [t[nu < 1.0][0], t[nu == 0.0][0], t[nu == 0.0][-1], t[nu < 1.0][-1]]
    assert_allclose(measured, expected, atol=0.11)
    # penumbra lasts ~8.6 s each side at 7000 km (the cone angles differ by the Sun's 0.27 deg radius)
    assert 8.0 < expected[1] - expected[0] < 9.5
    inside = (t > expected[0] + 0.5) & (t < expected[1] - 0.5)
    assert np.all((nu[inside] > 0.0) & (nu[inside] < 1.0)) and np.all(np.diff(nu[inside]) < 0.0)


def _disc_overlap_brute_force(a, b, c, n=2001):
    """Visible fraction of a disc of radius a whose center is c from a disc of radius b, on a grid."""
    x = np.linspace(-a, a, n)
    X, Y = np.meshgrid(x, x)
    sun = X**2 + Y**2 <= a * a
    hidden = (X - c) ** 2 + Y**2 <= b * b
    return 1.0 - np.count_nonzero(sun & hidden) / np.count_nonzero(sun)


@pytest.mark.parametrize("fraction", [0.1, 0.5, 0.9])
def test_penumbra_fraction_equals_disc_overlap(fraction):
    # a point behind the Earth, rotated in the penumbra so that the separation c runs from a+b to b-a
    r = A
    sun = np.array([SUN, 0.0, 0.0])
    b = np.arcsin(EARTH_RADIUS / r)
    a_approx = np.arcsin(SUN_RADIUS / (SUN + r))
    theta = np.pi - b - a_approx + 2 * a_approx * (1 - fraction)  # rough spread over the penumbra
    pos = r * np.array([np.cos(theta), np.sin(theta), 0.0])
    nu = conical_shadow(pos, sun, EARTH_RADIUS, SUN_RADIUS)
    d = sun - pos
    a = np.arcsin(SUN_RADIUS / np.linalg.norm(d))
    c = np.arccos(-pos @ d / (np.linalg.norm(pos) * np.linalg.norm(d)))
    assert 0.0 < nu < 1.0
    # the grid's area error ~ perimeter * cell / area ~ 4 / 2000: 3e-3
    assert_allclose(nu, _disc_overlap_brute_force(a, b, c), atol=3e-3)


def test_annular_and_lit_limits():
    # far behind a small body: the Sun's disc larger than the body's: annular 1 - b^2/a^2
    sun = np.array([SUN, 0.0, 0.0])
    pos = np.array([-2e9, 0.0, 0.0])
    a = np.arcsin(SUN_RADIUS / (SUN + 2e9))
    b = np.arcsin(1e6 / 2e9)
    assert_allclose(conical_shadow(pos, sun, 1e6, SUN_RADIUS), 1 - b**2 / a**2, rtol=1e-12)
    assert conical_shadow(np.array([A, 0, 0.0]), sun, EARTH_RADIUS, SUN_RADIUS) == 1.0
    assert cylindrical_shadow(np.array([-A, 0, 0.0]), sun, EARTH_RADIUS) == 0.0
    assert cylindrical_shadow(np.array([-A, 0, EARTH_RADIUS * 1.001]), sun, EARTH_RADIUS) == 1.0


SRP_SCENE = """
multibody:
  bodies:
    - name: sat
      hinge: free
      mass: 100 kg
      inertia: "[10, 10, 10] kg*m^2"
      initial: {position: "[7000, 0, 0] km", attitude: {q0}}
  nodes:
    - {name: cm, body: sat}
models:
  sun: {type: Constant, config: {unit: m, shape: [3]}, parameters: {value: "[1, 0, 0] au"}}
  shadow: {type: Constant, parameters: {value: {nu}}}
  srp:
    type: SolarRadiationPressure
    config: {plates: 2}
    attach: {node: cm}
    parameters:
      area: "[2, 3] m^2"
      normal: [[0.6, 0, 0.8], [0, -1, 0]]
      center: "[[0, 0, 1], [0.5, 0, 0]] m"
      specular: [0.3, 0.1]
      diffuse: [0.2, 0.5]
connections: [sun.y -> srp.sun_position, shadow.y -> srp.shadow_factor]
integrator: {method: rk4, step: 1 s}
log: {rate: 1 Hz, signals: [srp.force, srp.torque, srp.pressure]}
"""


def _closed_form_plate(P, area, n, s, rs, rd):
    c = n @ s
    return -P * area * c * ((1 - rs) * s + 2 * (rs * c + rd / 3) * n) if c > 0 else np.zeros(3)


@pytest.mark.parametrize("nu", [1.0, 0.4])
def test_srp_plate_force_and_torque_closed_form(nu):
    # the bus rotated 40 deg about z: the Sun (+x world) seen in node axes off every axis
    angle = np.radians(40.0)
    q0 = [float(np.cos(angle / 2)), 0.0, 0.0, float(np.sin(angle / 2))]
    text = SRP_SCENE.replace("{q0}", str(q0)).replace("{nu}", repr(nu))
    sim = build_simulation(parse_scenario(textwrap.dedent(text), "srp.yaml", None))
    sim.run(1.0)
    d = np.array([ASTRONOMICAL_UNIT - 7.0e6, 0.0, 0.0])
    Rz = np.array([[np.cos(angle), -np.sin(angle), 0], [np.sin(angle), np.cos(angle), 0], [0, 0, 1]])
    s = Rz.T @ d / np.linalg.norm(d)
    P = SOLAR_FLUX / SPEED_OF_LIGHT * (ASTRONOMICAL_UNIT / np.linalg.norm(d)) ** 2
    f1 = _closed_form_plate(P * nu, 2.0, np.array([0.6, 0, 0.8]), s, 0.3, 0.2)
    f2 = _closed_form_plate(P * nu, 3.0, np.array([0, -1.0, 0]), s, 0.1, 0.5)
    assert np.linalg.norm(f2) > 0 and np.linalg.norm(f1) > 0   # both lit at this attitude
    # the plate's attitude moves during the 1 s run only by the SRP torque (1e-5 N m on 10 kg m^2:
    # 5e-7 rad), so the closed form at the initial attitude holds to ~1e-6 relative
    force, torque = f1 + f2, np.cross([0, 0, 1.0], f1) + np.cross([0.5, 0, 0], f2)
    assert_allclose(sim.signal("srp.force"), force, rtol=0, atol=2e-6 * np.linalg.norm(force))
    assert_allclose(sim.signal("srp.torque"), torque, rtol=0, atol=2e-6 * np.linalg.norm(torque))
    assert_allclose(sim.signal("srp.pressure"), P, rtol=1e-9)
    # absorbed-only plate facing the Sun: F = -P A s, 4.55e-6 N/m^2 at 1 AU (the textbook value)
    assert_allclose(SOLAR_FLUX / SPEED_OF_LIGHT, 4.54e-6, rtol=2e-3)


def test_srp_refuses_bad_plates():
    with pytest.raises(ModelError, match="plate 2 has norm"):
        SolarRadiationPressure("srp", plates=2, normal=[[0, 0, 1], [0, 1, 1]])
    with pytest.raises(ModelError, match="at most 1"):
        SolarRadiationPressure("srp", specular=[0.7], diffuse=[0.5])
    with pytest.raises(ModelError, match="config plates"):
        SolarRadiationPressure("srp", plates=0)
