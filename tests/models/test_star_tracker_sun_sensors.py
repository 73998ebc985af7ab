"""Star tracker and coarse sun sensors: the measurement equations written out, exclusion geometry,
dropout statistics, latency through a scenario, cosine response, and the Earth-albedo term against a
brute-force integral over a Lambertian sphere."""

import numpy as np
import pytest
from numpy.testing import assert_allclose

from shell.log_file import read_log
from shell.model import ModelError
from shell.models.ephemeris import ASTRONOMICAL_UNIT
from shell.attitude import quaternion_multiply, rotation_vector_quaternion
from shell.models.star_tracker import StarTracker
from shell.models.sun_sensors import CoarseSunSensors, lambert_sphere_albedo
from shell.scenario import build_simulation, parse_scenario


def _unit(q):
    q = np.asarray(q, float)
    return q / np.linalg.norm(q)


def _rotation(q):
    w, x, y, z = q
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                     [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                     [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])


def _sample(tracker, attitude, position=(7e6, 0, 0), sun=(0, 0, 0), moon=(0, 0, 0), noise=(0, 0, 0, 0)):
    z = tracker.initial_discrete_state()
    u = np.r_[_rotation(attitude).ravel(), position, sun, moon].astype(float)
    tracker.update(0.0, np.zeros(0), z, u, tracker.p, np.asarray(noise, float))
    y = np.zeros(5)
    tracker.state_outputs(0.0, np.zeros(0), z, u, tracker.p, y)
    return y[:4], y[4]


def test_star_tracker_measurement_equation():
    mount = _unit([0.9, 0.1, 0.2, -0.3])
    delta = np.array([1e-4, -2e-4, 5e-4])
    sigma = np.array([1e-5, 2e-5, 1e-4])
    st = StarTracker("st", mounting=mount, misalignment=delta, noise=sigma)
    q = _unit([0.3, -0.5, 0.7, 0.1])
    w = np.array([0.3, -1.2, 2.0])
    true = quaternion_multiply(tuple(q), tuple(mount))
    boresight = _rotation(true)[:, 2]
    measured, valid = _sample(st, q, position=7e6 * boresight, noise=np.r_[w, 0.0])  # Earth behind it
    expected = np.array(quaternion_multiply(true, rotation_vector_quaternion(*(delta + sigma * w))))
    expected *= np.sign(expected[0])
    assert valid == 1.0
    assert_allclose(measured, expected, rtol=0, atol=1e-15)
    # the error rotation (true^-1 (x) measured) is the drawn one: 2 vec for small angles, exactly
    # 2 asin |vec| along vec
    conj = np.r_[true[0], -np.asarray(true[1:])]
    err = np.array(quaternion_multiply(tuple(conj), tuple(measured)))
    err *= np.sign(err[0])
    angle = 2 * np.arcsin(np.linalg.norm(err[1:]))
    assert_allclose(angle * err[1:] / np.linalg.norm(err[1:]), delta + sigma * w, rtol=1e-9)


def test_star_tracker_exclusions_and_dropouts():
    r = np.array([7e6, 0.0, 0.0])
    # boresight = sensor z; mount the sensor so that its z axis is node +x: rotation of +90 deg about y
    mount = np.array([np.cos(np.pi / 4), 0.0, np.sin(np.pi / 4), 0.0])
    identity = np.array([1.0, 0, 0, 0])
    st = StarTracker("st", mounting=mount, sun_exclusion=np.radians(30), moon_exclusion=np.radians(10),
                     earth_exclusion=np.radians(15))

    def about_z(deg):  # node attitude: turn the boresight (+x) by deg about world z
        return np.array([np.cos(np.radians(deg) / 2), 0, 0, np.sin(np.radians(deg) / 2)])

    sun = r + 1.5e11 * np.array([1.0, 0, 0])
    assert _sample(st, about_z(29.5), sun=sun)[1] == 0.0
    assert _sample(st, about_z(30.5), sun=sun)[1] == 1.0
    moon = r + 3.8e8 * np.array([0, 1.0, 0])
    assert _sample(st, about_z(90 - 9.5), moon=moon)[1] == 0.0
    assert _sample(st, about_z(90 - 10.5), moon=moon)[1] == 1.0
    limb = np.degrees(np.arcsin(6378137.0 / 7e6))  # 65.7 deg: Earth center at 180 deg from the boresight
    assert _sample(st, about_z(180 - limb - 15 + 0.5))[1] == 0.0
    assert _sample(st, about_z(180 - limb - 15 - 0.5))[1] == 1.0
    assert _sample(StarTracker("free", mounting=mount), about_z(0), sun=sun)[1] == 1.0  # no cone: no exclusion
    # an invalid sample holds the previous valid attitude
    z = st.initial_discrete_state()
    st.update(0.0, np.zeros(0), z, np.r_[_rotation(about_z(90)).ravel(), r, sun, np.zeros(3)], st.p, np.zeros(4))
    st.update(0.2, np.zeros(0), z, np.r_[_rotation(about_z(0)).ravel(), r, sun, np.zeros(3)], st.p, np.zeros(4))
    y = np.zeros(5)
    st.state_outputs(0.2, np.zeros(0), z, np.zeros(18), st.p, y)
    assert y[4] == 0.0 and _same_quaternion(y[:4], quaternion_multiply(tuple(about_z(90)), tuple(mount)))
    # dropouts: a uniform draw from the standard normal (its CDF) below the probability
    drops = StarTracker("drop", dropout_probability=0.3)
    normals = np.random.default_rng(9).standard_normal((4000, 4))
    lost = sum(_sample(drops, identity, position=(0, 0, 7e6), noise=n)[1] == 0.0 for n in normals)
    assert abs(lost / 4000 - 0.3) < 4 * np.sqrt(0.3 * 0.7 / 4000)  # binomial, 4 sigma
    with pytest.raises(ModelError, match="whole number of sample periods"):
        StarTracker("late", period=0.2, latency=0.3)


def _same_quaternion(a, b):
    b = np.asarray(b) * np.sign(b[0])
    return np.allclose(a, b, rtol=0, atol=1e-15)


SCENE = """
multibody:
  bodies:
    - name: sat
      hinge: free
      mass: 100 kg
      inertia: "[10, 12, 15] kg*m^2"
      initial:
        position: "[7000, 0, 0] km"
        attitude: [1, 0, 0, 0]
        angular_velocity: "[0.5, -1, 2] deg/s"
  nodes:
    - {name: acs, body: sat}
models:
  eph: {type: SunMoonEphemeris, config: {epoch: "2025-03-20T09:00:00"}}
  eclipse: {type: Eclipse, attach: {node: acs}}
  tracker: {type: StarTracker, rate: 5 Hz, attach: {node: acs}, parameters: {latency: 0.4 s}}
  css:
    type: CoarseSunSensors
    rate: 5 Hz
    config: {sensors: 6}
    attach: {node: acs}
    parameters:
      normal: [[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]]
connections:
  - eph.sun_position -> eclipse.sun_position
  - eph.sun_position -> tracker.sun_position
  - eph.sun_position -> css.sun_position
  - eclipse.shadow_factor -> css.shadow_factor
integrator: {method: rk4, step: 0.05 s}
log:
  rate: 5 Hz
  signals: [multibody.acs.attitude, multibody.acs.rotation, multibody.acs.position, tracker.attitude,
            tracker.valid, css.signals, eph.sun_position, eclipse.shadow_factor]
"""


def test_latency_and_cosine_sun_vector_through_a_scenario(tmp_path):
    sim = build_simulation(parse_scenario(SCENE, "sensors.yaml", None))
    sim.run(20.0, log_path=tmp_path / "s.h5")
    log = read_log(tmp_path / "s.h5")
    q, meas = log["multibody.acs.attitude"], log["tracker.attitude"]
    q = q * np.sign(q[:, :1])
    # 0.4 s latency at 5 Hz: the output at sample k is the attitude sampled at k - 2
    assert_allclose(meas[3:], q[1:-2], rtol=0, atol=1e-14)
    assert np.all(log["tracker.valid"][3:] == 1.0)
    # six cells on +-x, +-y, +-z with a 90 deg field of view: opposite pairs give the Sun vector in node
    # axes times (AU/d)^2 (no albedo, in sunlight)
    y = log["css.signals"]
    measured = np.c_[y[:, 0] - y[:, 1], y[:, 2] - y[:, 3], y[:, 4] - y[:, 5]]
    d = log["eph.sun_position"] - log["multibody.acs.position"]
    R = log["multibody.acs.rotation"]
    expected = np.einsum("kji,kj->ki", R, d / np.linalg.norm(d, axis=1)[:, None]) \
        * ((ASTRONOMICAL_UNIT / np.linalg.norm(d, axis=1)) ** 2)[:, None]
    assert np.all(log["eclipse.shadow_factor"] == 1.0)
    assert_allclose(measured[1:], expected[1:], rtol=0, atol=1e-14)


def _css(**parameters):
    return CoarseSunSensors("css", sensors=3, **parameters)


def _css_sample(css, sun_dir, position=(7e6, 0, 0), shadow=1.0, noise=None, sun=None):
    position = np.asarray(position, float)
    sun = position + ASTRONOMICAL_UNIT * np.asarray(sun_dir, float) if sun is None else np.asarray(sun, float)
    u = np.r_[position, np.eye(3).ravel(), sun, shadow]
    z = css.initial_discrete_state()
    css.update(0.0, np.zeros(0), z, u, css.p, np.zeros(css.noise_size) if noise is None else noise)
    return z


def test_cosine_response_field_of_view_and_shadow():
    normals = [[1, 0, 0], [np.cos(0.8), np.sin(0.8), 0], [-1, 0, 0]]
    css = _css(normal=normals, field_of_view=np.radians(40), scale=2.0)
    z = _css_sample(css, [1.0, 0, 0])
    assert_allclose(z, [2.0, 0.0, 0.0], rtol=1e-12)  # the second cell at 45.8 deg: outside 40 deg
    css60 = _css(normal=normals, field_of_view=np.radians(60), scale=2.0)
    assert_allclose(_css_sample(css60, [1.0, 0, 0], shadow=0.25), [0.5, 0.5 * np.cos(0.8), 0.0], rtol=1e-12)
    noisy = _css(normal=normals, noise=0.01)
    assert_allclose(_css_sample(noisy, [1.0, 0, 0], noise=np.array([1.0, 2.0, -3.0])),
                    [1.01, np.cos(0.8) + 0.02, 0.0], rtol=1e-12)  # negative outputs clip at zero
    with pytest.raises(ModelError, match="cell 2 has norm"):
        _css(normal=[[1, 0, 0], [1, 1, 0], [0, 0, 1]])


def _brute_force_albedo(alpha, distance_in_radii, n=1200):
    """Irradiance from a Lambertian sphere (radius 1, albedo 1, unit solar irradiance) at an observer
    `distance_in_radii` away at phase angle alpha, facing the sphere's center: sum over the surface of
    (cos i / pi) cos e cos(sensor) dA / d^2 on a (theta, phi) grid."""
    th = (np.arange(n) + 0.5) * np.pi / n
    ph = (np.arange(2 * n) + 0.5) * np.pi / n
    T, F = np.meshgrid(th, ph, indexing="ij")
    p = np.stack([np.sin(T) * np.cos(F), np.sin(T) * np.sin(F), np.cos(T)], -1)
    dA = np.sin(T) * (np.pi / n) ** 2
    sun = np.array([1.0, 0, 0])
    obs = distance_in_radii * np.array([np.cos(alpha), np.sin(alpha), 0.0])
    v = obs - p
    d = np.linalg.norm(v, axis=-1)
    cos_i = p @ sun
    cos_e = np.sum(p * v, -1) / d
    cos_s = np.sum(v * obs, -1) / (d * distance_in_radii)  # sensor normal toward the center
    lit = (cos_i > 0) & (cos_e > 0)
    return np.sum(np.where(lit, cos_i / np.pi * cos_e * cos_s / d**2, 0.0) * dA)


@pytest.mark.parametrize("alpha_deg", [0.0, 60.0, 120.0])
def test_albedo_term_equals_lambert_sphere_integral(alpha_deg):
    alpha = np.radians(alpha_deg)
    # far field (r = 10^4 R): the sphere's phase law; the near-field terms are O(R/r) (measured at
    # 120 deg: 2.2e-3 at 10^3 R, 2.1e-4 at 10^4 R), the grid's error < 1e-6
    reference = _brute_force_albedo(alpha, 1e4)
    assert_allclose(lambert_sphere_albedo(np.cos(alpha)) / 1e8, reference, rtol=5e-4)
    # the model: a cell facing the Earth at 50 radii sees albedo E_a (sun behind it, out of its view)
    css = CoarseSunSensors("c", sensors=1, normal=[[-np.cos(alpha), -np.sin(alpha), 0]], albedo=0.3,
                           body_radius=6.4e6)
    pos = 1e4 * 6.4e6 * np.array([np.cos(alpha), np.sin(alpha), 0.0])
    sun = np.array([ASTRONOMICAL_UNIT, 0.0, 0.0])  # phase angle alpha exactly, seen from the Earth
    z = _css_sample(css, None, position=pos, shadow=0.0, sun=sun)
    d = np.linalg.norm(sun - pos)
    assert_allclose(z[0], 0.3 * reference * (ASTRONOMICAL_UNIT / d) ** 2, rtol=5e-4)
