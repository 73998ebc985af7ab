"""Aerodynamics: weathercock oscillation of a pinned body in a steady wind at sqrt(q S C_N_alpha l / J);
axial force and the exponential atmosphere against their formulas; the NRLMSIS atmosphere against pymsis
itself (its profile interpolation error stated), through the kernel, a YAML scene and the command line;
refusals of misplaced atmosphere options."""

import textwrap
from pathlib import Path

import numpy as np
import pytest
from numpy.testing import assert_allclose

from shell.cli import main
from shell.log_file import read_log
from shell.model import ModelError
from shell.models.aerodynamics import PROFILE_ALTITUDES, Aerodynamics
from shell.models.atmosphere import msis_log_density_profile
from shell.models.ephemeris import julian_date
from shell.scenario import ScenarioError, build_simulation, parse_scenario

ROOT = Path(__file__).resolve().parents[2]

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
    y = np.empty(9)
    altitude, speed = 5000.0, 300.0
    u = np.concatenate([[0.0, 0.0, altitude], [0.0, 0.0, speed], np.eye(3).reshape(-1)])
    model.feedthrough_outputs(0.0, None, None, u, model.p, y)
    q = 0.5 * 1.225 * np.exp(-altitude / 7200.0) * speed**2
    assert_allclose(y[6], q, rtol=1e-14)
    assert_allclose(y[8], 1.225 * np.exp(-altitude / 7200.0), rtol=1e-15)
    assert_allclose(y[0:3], [0.0, 0.0, -q * 2.0 * 0.4], rtol=1e-14)        # pure drag at zero alpha
    assert_allclose(y[3:6], 0.0, atol=0)
    assert y[7] == 0.0


def _density(model, altitudes):
    """The model's density output at flat-world altitudes (world z), nose up, 300 m/s along the nose."""
    y, out = np.empty(9), []
    for h in altitudes:
        u = np.concatenate([[0.0, 0.0, h], [0.0, 0.0, 300.0], np.eye(3).reshape(-1)])
        model.feedthrough_outputs(0.0, None, None, u, model.p, y)
        out.append(y[8])
        assert_allclose(y[6], 0.5 * y[8] * 300.0**2, rtol=1e-14)   # q uses that density
    return np.array(out)


# (site, epoch): Cape Canaveral in the late morning near the equinox; Andoya (69.3 N) at local midnight in
# midwinter, quiet Sun; a high-activity day over Kourou
SITES = [(28.5, -80.6, "2025-03-20T14:00:00", 150.0, 150.0, 4.0),
         (69.3, 16.0, "2024-12-21T23:00:00", 70.0, 75.0, 2.0),
         (5.2, -52.8, "2024-10-10T18:30:00", 260.0, 210.0, 80.0)]


@pytest.mark.parametrize("latitude, longitude, epoch, f107, f107_average, ap", SITES)
def test_nrlmsis_density_against_pymsis(latitude, longitude, epoch, f107, f107_average, ap):
    model = Aerodynamics("aero", atmosphere="nrlmsis", epoch=epoch, latitude=f"{latitude} deg",
                         longitude=f"{longitude} deg", f107=f107, f107_average=f107_average, ap=ap,
                         reference_area=2.0, normal_force_slope=3.0)
    jd = julian_date(epoch)
    # at the profile's altitudes: pymsis's own values, to its single-precision output (two calls on other
    # point sets differ by up to 1.4e-7: NRLMSIS 2.1 computes in float32)
    nodes = PROFILE_ALTITUDES[::7]
    reference = np.exp(msis_log_density_profile(jd, latitude, longitude, nodes, f107, f107_average, ap))
    assert_allclose(_density(model, nodes), reference, rtol=5e-7)
    # between them: ln rho is interpolated linearly every 0.25 km; its error h^2/8 |d2 ln rho/dh2| is largest
    # at the tropopause kink (10-15 km): at most 5.9e-5, 7.6e-5 and 1.3e-4 for these sites (measured every
    # 5 m over 0-1000 km and every 0.5 m over 5-25 km); 1.5e-4 bounds it
    rng = np.random.default_rng(7)
    between = np.concatenate([rng.uniform(0.0, 1000e3, 300), np.arange(8e3, 20e3, 37.0)])
    reference = np.exp(msis_log_density_profile(jd, latitude, longitude, between, f107, f107_average, ap))
    error = np.abs(_density(model, between) / reference - 1.0)
    assert error.max() < 1.5e-4
    assert error.max() > 1e-6            # the points do fall between the profile's altitudes
    # below the ground and above 1000 km: ln rho continued linearly from the end segments
    for h, (a, b) in ((-300.0, (0, 1)), (1100e3, (-2, -1))):
        ln = model.parameter("log_density")
        slope = (ln[b] - ln[a]) / (PROFILE_ALTITUDES[b] - PROFILE_ALTITUDES[a])
        assert_allclose(np.log(_density(model, [h])[0]), ln[a] + slope * (h - PROFILE_ALTITUDES[a]), rtol=1e-12)


def test_nrlmsis_differs_from_the_exponential_default():
    """The option matters: against the exponential default (1.225 kg/m^3, 7.2 km scale height) NRLMSIS at
    Cape Canaveral is 2 % lower at sea level, 36 % higher at 10 km and 235 times higher at 200 km."""
    msis = Aerodynamics("aero", atmosphere="nrlmsis", epoch="2025-03-20T14:00:00", latitude=28.5, longitude=-80.6,
                        reference_area=2.0, normal_force_slope=3.0)
    exponential = Aerodynamics("aero", reference_area=2.0, normal_force_slope=3.0)
    ratio = _density(msis, [0.0, 10e3, 200e3]) / _density(exponential, [0.0, 10e3, 200e3])
    assert 0.97 < ratio[0] < 0.99
    assert 1.3 < ratio[1] < 1.4
    assert 200.0 < ratio[2] < 270.0


ROCKET = ROOT / "configs" / "sounding_rocket_nrlmsis.yaml"


def test_sounding_rocket_example_through_the_command_line(tmp_path):
    """configs/sounding_rocket_nrlmsis.yaml as a user runs it: the logged density is NRLMSIS (pymsis called
    here, at the logged altitudes) within the profile's interpolation error, all the way up."""
    assert main(["check", str(ROCKET)]) == 0
    out = tmp_path / "rocket.h5"
    assert main(["run", str(ROCKET), "-o", str(out), "--quiet"]) == 0
    log = read_log(out)
    altitude = log["multibody.cg.position"][:, 2]
    assert altitude.min() >= 0.0 and altitude.max() > 60e3         # troposphere to mesosphere
    reference = np.exp(msis_log_density_profile(julian_date("2025-03-20T14:00:00"), 28.5, -80.6, altitude,
                                                150.0, 150.0, 4.0))
    assert np.abs(log["aero.density"] / reference - 1.0).max() < 1.5e-4
    speed2 = np.einsum("ki,ki->k", log["multibody.cg.linear_velocity"], log["multibody.cg.linear_velocity"])
    assert_allclose(log["aero.dynamic_pressure"], 0.5 * log["aero.density"] * speed2, rtol=1e-12)
    assert np.degrees(log["aero.angle_of_attack"][10:]).max() < 3.0  # it weathercocks onto its flight path


MISPLACED = """
multibody:
  bodies: [{name: rocket, hinge: free, mass: 100 kg, inertia: "[50, 50, 5] kg*m^2"}]
  nodes: [{name: cg, body: rocket}]
models:
  aero:
    type: Aerodynamics
    attach: {node: cg}
    config: {atmosphere: nrlmsis, epoch: "2025-03-20T14:00:00"}
    parameters: {reference_area: 0.5 m^2, normal_force_slope: 2 /rad, latitude: 28.5 deg, longitude: -80.6 deg,
                 scale_height: 7000 m}
"""


def test_misplaced_atmosphere_options_are_refused():
    with pytest.raises(ScenarioError, match=r"rocket\.yaml:\d+.*\['scale_height'\] belong to atmosphere: exponential"):
        build_simulation(parse_scenario(textwrap.dedent(MISPLACED), "rocket.yaml", None))
    with pytest.raises(ModelError, match="config epoch: required with atmosphere: nrlmsis"):
        Aerodynamics("aero", atmosphere="nrlmsis", latitude=0.0, longitude=0.0, reference_area=1.0,
                     normal_force_slope=1.0)
    with pytest.raises(ModelError, match="config epoch: only read with config atmosphere: nrlmsis"):
        Aerodynamics("aero", epoch="2025-03-20T14:00:00", reference_area=1.0, normal_force_slope=1.0)
    with pytest.raises(ModelError, match=r"\['latitude'\] belong to atmosphere: nrlmsis"):
        Aerodynamics("aero", latitude=10.0, reference_area=1.0, normal_force_slope=1.0)
    with pytest.raises(ModelError, match="config atmosphere: expected one of"):
        Aerodynamics("aero", atmosphere="msis", reference_area=1.0, normal_force_slope=1.0)
