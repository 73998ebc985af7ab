"""Geomagnetic field, magnetometer, magnetorquers, B-dot and momentum dumping.

References: the closed-form centered dipole, the maintained ppigrf package evaluating the same IGRF-14
coefficients by its own code (its distribution does not ship the NOAA test points of its test suite,
so its function is the reference), the sensor and actuator equations written out, and a closed-loop
detumble that must remove kinetic energy.
"""

import numpy as np
import pytest
from numpy.testing import assert_allclose

from shell.model import ModelError
from shell.models.ephemeris import TT_MINUS_UTC, earth_fixed_rotation, julian_date
from shell.models.magnetic import (MAX_DEGREE, MagneticField, Magnetometer, Magnetorquer, igrf_coefficients,
                                   spherical_harmonic_field)
from shell.models.magnetic_control import BDot, MomentumDumping
from shell.scenario import build_simulation, parse_scenario

import ppigrf  # noqa: E402  (a runtime dependency of flexshell)
A = 6371.2e3


def _field(points, g, h, degree):
    return np.array([spherical_harmonic_field(x, y, z, g.ravel(), h.ravel(), degree, A) for x, y, z in points])


def _points(n, seed):
    rng = np.random.default_rng(seed)
    d = rng.normal(size=(n, 3))
    return d / np.linalg.norm(d, axis=1)[:, None] * rng.uniform(6.5e6, 4.2e7, n)[:, None]


def test_tilted_dipole_equals_closed_form():
    g, h = igrf_coefficients(julian_date("2025-01-01T00:00:00"), degree=1)
    m = np.array([g[1, 1], h[1, 1], g[1, 0]])
    pts = _points(50, 1)
    r = np.linalg.norm(pts, axis=1)[:, None]
    rhat = pts / r
    closed = (A / r) ** 3 * (3 * (rhat @ m)[:, None] * rhat - m)
    assert_allclose(_field(pts, g, h, 1), closed, rtol=0, atol=1e-12 * np.abs(m).max())
    # the dipole's field at its magnetic equator is |m| (A/r)^3, at its pole twice that
    pole = A * m / np.linalg.norm(m)
    assert_allclose(np.linalg.norm(_field([pole], g, h, 1)), 2 * np.linalg.norm(m), rtol=1e-12)
    assert 2.9e-5 < np.linalg.norm(m) < 3.0e-5  # 2025 dipole moment: 29.7 uT at the reference radius


@pytest.mark.parametrize("date", ["2010-01-01T00:00:00", "2020-01-01T00:00:00", "2022-10-05T00:00:00"])
def test_igrf_equals_ppigrf(date):
    # ppigrf's own test dates; our recursion and sums against ppigrf's igrf_gc (its Legendre functions)
    from datetime import datetime
    g, h = igrf_coefficients(julian_date(date))
    pts = _points(60, 2)
    r = np.linalg.norm(pts, axis=1)
    theta = np.degrees(np.arccos(pts[:, 2] / r))
    phi = np.degrees(np.arctan2(pts[:, 1], pts[:, 0]))
    br, bt, bp = (c.ravel() for c in ppigrf.igrf_gc(r / 1e3, theta, phi, datetime.fromisoformat(date)))
    th, ph = np.radians(theta), np.radians(phi)
    e_r = np.c_[np.sin(th) * np.cos(ph), np.sin(th) * np.sin(ph), np.cos(th)]
    e_t = np.c_[np.cos(th) * np.cos(ph), np.cos(th) * np.sin(ph), -np.sin(th)]
    e_p = np.c_[-np.sin(ph), np.cos(ph), np.zeros_like(ph)]
    ref = (br[:, None] * e_r + bt[:, None] * e_t + bp[:, None] * e_p) * 1e-9
    ours = _field(pts, g, h, MAX_DEGREE)
    # same coefficients, two evaluations of the series: rounding only (1e-15 of |B|); 1e-9 nT-level
    assert_allclose(ours, ref, rtol=0, atol=1e-9 * np.linalg.norm(ref, axis=1).max())
    # over a pole (where ppigrf divides by sin theta = 0) the field is the limit of its neighbours
    pole, near = _field([[0.0, 0.0, -7e6], [1e-3, 2e-3, -7e6]], g, h, MAX_DEGREE)
    assert_allclose(pole, near, rtol=0, atol=1e-9 * np.linalg.norm(near))  # 2 mm of gradient: 4e-10


ORBIT = """
multibody:
  bodies:
    - name: sat
      hinge: free
      mass: 20 kg
      inertia: "[0.3, 0.4, 0.5] kg*m^2"
      initial:
        position: "[6878137, 0, 0] m"
        velocity: "[0, 0, 7612.6] m/s"      # polar circular orbit at 500 km
        attitude: [0.9, 0.1, -0.3, 0.3]
        angular_velocity: "{w0}"
  nodes:
    - {name: cm, body: sat}
    - {name: mtq, body: sat}                # the rods' frame: a node takes one torque source
models:
  gravity: {type: CentralBodyGravity, attach: {node: cm}, parameters: {mass: 20 kg, gravity_gradient: 0}}
  field:
    type: MagneticField
    config: {epoch: "2025-06-01T00:00:00"}
    parameters: {degree: {degree}}
    attach: {node: cm}
  magnetometer: {type: Magnetometer, rate: 2 Hz}
  bdot: {type: BDot, rate: 2 Hz, parameters: {gain: "{gain}", max_dipole: "[0.2, 0.2, 0.2] A*m^2"}}
  torquers: {type: Magnetorquer, attach: {node: mtq}, parameters: {max_dipole: "[0.2, 0.2, 0.2] A*m^2"}}
connections:
  - field.field -> magnetometer.true_field
  - magnetometer.field -> bdot.field
  - bdot.dipole_command -> torquers.dipole_command
  - field.field -> torquers.field
integrator: {method: rk4, step: 0.1 s}
log:
  rate: 0.1 Hz
  signals: [field.field_inertial, field.field, multibody.cm.position, multibody.cm.rotation,
            multibody.cm.angular_velocity, torquers.torque, torquers.dipole]
"""


def _scene(degree=13, gain="0 A*m^2*s/T", w0="[3, -2, 4] deg/s"):
    text = ORBIT.replace("{degree}", str(degree)).replace("{gain}", gain).replace("{w0}", w0)
    return build_simulation(parse_scenario(text, "mag.yaml", None))


def test_field_through_a_scenario(tmp_path):
    from shell.log_file import read_log
    sim = _scene()
    sim.run(120.0, log_path=tmp_path / "m.h5")
    log = read_log(tmp_path / "m.h5")
    epoch = julian_date("2025-06-01T00:00:00")
    g, h = igrf_coefficients(epoch)
    for k, t in enumerate(log["time"]):
        E = np.reshape(earth_fixed_rotation(t, epoch, TT_MINUS_UTC), (3, 3))
        b_ecef = _field([E @ log["multibody.cm.position"][k]], g, h, MAX_DEGREE)[0]
        assert_allclose(log["field.field_inertial"][k], E.T @ b_ecef, rtol=1e-13, atol=1e-20)
        R = log["multibody.cm.rotation"][k]
        assert_allclose(log["field.field"][k], R.T @ log["field.field_inertial"][k], rtol=0, atol=1e-19)
    assert 1.5e-5 < np.linalg.norm(log["field.field_inertial"][0]) < 6e-5


def test_magnetometer_error_model_and_noise():
    q = np.array([0.8, 0.2, -0.4, 0.4])
    q /= np.linalg.norm(q)
    mis = np.array([[0, 1e-3, -2e-3], [5e-4, 0, 1e-3], [-1e-3, 2e-3, 0]])
    mag = Magnetometer("mag", mounting=q, bias=[1e-7, -2e-7, 3e-7], scale_factor=[1e-3, -2e-3, 5e-4],
                       misalignment=mis)
    z = mag.initial_discrete_state()
    b = np.array([2e-5, -3e-5, 1e-5])
    mag.update(0.0, np.zeros(0), z, b, mag.p, np.zeros(3))
    w, x, y, zq = q
    C = np.array([[1 - 2 * (y * y + zq * zq), 2 * (x * y - w * zq), 2 * (x * zq + w * y)],
                  [2 * (x * y + w * zq), 1 - 2 * (x * x + zq * zq), 2 * (y * zq - w * x)],
                  [2 * (x * zq - w * y), 2 * (y * zq + w * x), 1 - 2 * (x * x + y * y)]])
    expected = np.diag(1 + np.array([1e-3, -2e-3, 5e-4])) @ (np.eye(3) + mis) @ C.T @ b + [1e-7, -2e-7, 3e-7]
    assert_allclose(z, expected, rtol=1e-14)
    quantized = Magnetometer("q", lsb=1e-7, range=2.5e-5)
    zq_ = quantized.initial_discrete_state()
    quantized.update(0.0, np.zeros(0), zq_, b, quantized.p, np.zeros(3))
    assert_allclose(zq_, [2e-5, -2.5e-5, 1e-5], rtol=1e-12)
    noisy = Magnetometer("n", noise=[1e-7, 2e-7, 3e-7])
    normals = np.random.default_rng(4).standard_normal((4000, 3))
    samples = []
    for w_ in normals:
        zn = noisy.initial_discrete_state()
        noisy.update(0.0, np.zeros(0), zn, b, noisy.p, w_)
        samples.append(zn - b)
    # the model scales the framework's standard normals by sigma exactly (same draws)
    assert_allclose(np.array(samples), normals * [1e-7, 2e-7, 3e-7], rtol=1e-7, atol=1e-21)
    with pytest.raises(ModelError, match="diagonal must be zero"):
        Magnetometer("bad", misalignment=np.eye(3) * 1e-3)


def test_magnetorquer_limits_quantization_and_torque():
    mtq = Magnetorquer("mtq", max_dipole=[1.0, 2.0, 0.5], lsb=0.1)
    b = np.array([1e-5, -2e-5, 3e-5])
    y = np.zeros(6)
    mtq.feedthrough_outputs(0.0, np.zeros(0), np.zeros(0), np.r_[[3.0, -0.34, 0.47], b], mtq.p, y)
    dipole = np.array([1.0, -0.3, 0.5])
    assert_allclose(y[3:], dipole, rtol=1e-15)  # clipped at 1.0; -0.34 -> -3 lsb; 0.47 -> 0.5 (its limit)
    assert_allclose(y[:3], np.cross(dipole, b), rtol=1e-14)  # -3 * 0.1 = -0.30000000000000004


def test_bdot_command_and_momentum_dumping_torque():
    bdot = BDot("bdot", gain=2e4, max_dipole=[1.0, 1.0, 1.0])
    z = bdot.initial_discrete_state()
    b1, b2 = np.array([1e-5, 2e-5, -3e-5]), np.array([1.2e-5, 1.9e-5, -3.1e-5])
    bdot.update(0.0, np.zeros(0), z, b1, bdot.p)
    y = np.zeros(3)
    bdot.state_outputs(0.0, np.zeros(0), z, b1, bdot.p, y)
    assert np.all(y == 0.0)  # no difference at the first sample
    bdot.update(0.5, np.zeros(0), z, b2, bdot.p)
    bdot.state_outputs(0.5, np.zeros(0), z, b2, bdot.p, y)
    assert_allclose(y, -2e4 * (b2 - b1) / 0.5, rtol=1e-12)
    strong = BDot("strong", gain=2e6, max_dipole=[1.0, 1.0, 1.0])
    z = strong.initial_discrete_state()
    strong.update(0.0, np.zeros(0), z, b1, strong.p)
    strong.update(0.5, np.zeros(0), z, b2, strong.p)
    raw = -2e6 * (b2 - b1) / 0.5
    strong.state_outputs(0.5, np.zeros(0), z, b2, strong.p, y)
    assert_allclose(y, raw / np.abs(raw).max(), rtol=1e-12)  # scaled as a whole, direction kept

    dump = MomentumDumping("dump", gain=0.02, max_dipole=[500.0, 500.0, 500.0])  # unsaturated: 86 A m^2
    hw = np.array([0.1, -0.05, 0.2])
    z = dump.initial_discrete_state()
    dump.update(0.0, np.zeros(0), z, np.r_[b1, hw], dump.p)
    dump.state_outputs(0.0, np.zeros(0), z, np.r_[b1, hw], dump.p, y)
    bhat = b1 / np.linalg.norm(b1)
    assert_allclose(np.cross(y, b1), -0.02 * (hw - (hw @ bhat) * bhat), rtol=1e-12)


def test_bdot_detumbles_through_a_scenario(tmp_path):
    from shell.log_file import read_log
    sim = _scene(degree=1, gain="1e5 A*m^2*s/T")
    sim.run(4500.0, log_path=tmp_path / "d.h5")
    log = read_log(tmp_path / "d.h5")
    w = log["multibody.cm.angular_velocity"]
    J = np.diag([0.3, 0.4, 0.5])
    energy = 0.5 * np.einsum("ki,ij,kj->k", w, J, w)
    # B-dot takes energy out: -k |omega x B|^2 in the continuous limit, while the body rate is well
    # above the field's own rotation in body axes (~2 orbit rates, 2.2e-3 rad/s: there B-dot settles);
    # sampled at 2 Hz the energy falls at every logged point (10 s apart) while |omega| > 30 orbit
    # rates (at 18 it rose by 1e-7 of itself over 10 s with omega nearly along B)
    orbit_rate = np.sqrt(3.986004418e14 / 6878137.0**3)
    fast = np.linalg.norm(w, axis=1)[1:] > 30 * orbit_rate
    assert fast.sum() > 100 and np.all(np.diff(energy)[fast] < 0)
    assert energy[-1] < 0.07 * energy[0]  # measured 0.050 after 4500 s (5.4 deg/s -> 1.1 deg/s)
    assert np.abs(log["torquers.dipole"]).max() <= 0.2 + 1e-15
    with pytest.raises(ModelError, match="whole number"):
        MagneticField("f", degree=2.5)


def test_an_epoch_outside_igrf_is_refused_with_the_file_line():
    from shell.scenario import ScenarioError
    text = 'models:\n  field: {type: MagneticField, config: {epoch: "1850-01-01T00:00:00"}}\n'
    with pytest.raises(ScenarioError, match=r"old.yaml:2: models.field: .*outside the IGRF coefficient file"):
        build_simulation(parse_scenario(text, "old.yaml", None))
