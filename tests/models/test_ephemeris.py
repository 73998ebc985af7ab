"""Analytic Sun and Moon ephemerides and Earth rotation against astropy (its built-in ERFA ephemerides
and IAU transformations, no downloaded kernels), and the epoch through a scenario."""

import warnings

import numpy as np
import pytest
from numpy.testing import assert_allclose

from shell.model import ModelError
from shell.models.ephemeris import (J2000, TT_MINUS_UTC, SunMoonEphemeris, earth_fixed_rotation,
                                    greenwich_mean_sidereal_time, julian_date, moon_position, sun_position)
from shell.scenario import build_simulation, parse_scenario

from astropy import units as u  # noqa: E402  (astropy: the test extra)
from astropy.coordinates import GCRS, ITRS, CartesianRepresentation, get_body, solar_system_ephemeris  # noqa: E402
from astropy.time import Time  # noqa: E402
from astropy.utils import iers  # noqa: E402

iers.conf.auto_download = False
#: 40 dates 2000-2024 (inside the IERS-B table astropy ships, so UT1 and polar motion are known)
DATES = J2000 + np.random.default_rng(5).uniform(0.0, 24.5 * 365.25, 40)


def _angle(a, b):
    return np.arccos(np.clip(np.sum(a * b, axis=-1) / (np.linalg.norm(a, axis=-1) * np.linalg.norm(b, axis=-1)),
                             -1, 1))


def test_sun_and_moon_against_astropy_builtin_ephemeris():
    tt = Time(DATES + TT_MINUS_UTC / 86400.0, format="jd", scale="tt")
    with solar_system_ephemeris.set("builtin"), warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sun_ref = get_body("sun", tt).cartesian.xyz.to(u.m).value.T
        moon_ref = get_body("moon", tt).cartesian.xyz.to(u.m).value.T
    sun, moon = np.zeros((len(DATES), 3)), np.zeros((len(DATES), 3))
    for k, jd in enumerate(DATES):
        T = (jd + TT_MINUS_UTC / 86400.0 - J2000) / 36525.0
        sun_position(T, sun[k])
        moon_position(T, moon[k])
    arcmin = np.radians(1 / 60)
    # M&G state 0.1'-1' for the Sun; astropy's GCRS Sun is apparent (aberration 20"): measured 0.75'
    assert np.max(_angle(sun, sun_ref)) < 1.0 * arcmin
    assert_allclose(np.linalg.norm(sun, axis=1), np.linalg.norm(sun_ref, axis=1), rtol=1e-4)
    # the Moon's truncated series: "a few arcmin, 500 km" (M&G); measured 3.2' and 480 km
    assert np.max(_angle(moon, moon_ref)) < 5.0 * arcmin
    assert_allclose(np.linalg.norm(moon, axis=1), np.linalg.norm(moon_ref, axis=1), atol=600e3)


def test_earth_rotation_against_astropy_itrs():
    t = Time(DATES, format="jd", scale="utc")
    vectors = np.random.default_rng(1).normal(size=(len(DATES), 3)) * 7e6
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        gcrs = GCRS(CartesianRepresentation(vectors.T * u.m), obstime=t)
        itrs = gcrs.transform_to(ITRS(obstime=t)).cartesian.xyz.to(u.m).value.T
        gmst_ref = t.sidereal_time("mean", "greenwich", model="IAU1982").to(u.rad).value
    ours = np.array([np.reshape(earth_fixed_rotation(0.0, jd, TT_MINUS_UTC), (3, 3)) @ v
                     for jd, v in zip(DATES, vectors)])
    # neglected: nutation (< 20"), polar motion (< 0.5"), UT1 - UTC (< 0.9 s = 13.5"): 40" bound
    assert np.max(_angle(ours, itrs)) < np.radians(40 / 3600)
    gmst = np.array([greenwich_mean_sidereal_time(jd) for jd in DATES])
    diff = np.angle(np.exp(1j * (gmst - gmst_ref)))
    assert np.max(np.abs(diff)) < np.radians(15 / 3600)  # UT1 - UTC < 0.9 s of time
    for R in (np.reshape(earth_fixed_rotation(10.0, jd, TT_MINUS_UTC), (3, 3)) for jd in DATES[:5]):
        assert_allclose(R @ R.T, np.eye(3), atol=1e-14)


def test_julian_date_and_bad_epochs():
    assert julian_date("2000-01-01T12:00:00") == J2000
    assert julian_date("2000-01-01T12:00:00Z") == J2000
    assert julian_date("2025-03-20T00:00:00") == 2460754.5  # Astronomical Almanac JD table
    with pytest.raises(ModelError, match="ISO 8601"):
        SunMoonEphemeris("eph", epoch="20 March 2025")
    with pytest.raises(ModelError, match="either config epoch or parameter"):
        SunMoonEphemeris("eph", epoch="2025-03-20T00:00:00", epoch_julian_date=2460754.5)


SCENE = """
models:
  eph: {type: SunMoonEphemeris, config: {epoch: "2024-06-20T20:51:00"}}
integrator: {method: rk4, step: 1 s}
log: {rate: 1 Hz, signals: [eph.sun_position, eph.sun_direction, eph.moon_position]}
"""


def test_ephemeris_through_a_scenario_at_the_june_solstice():
    sim = build_simulation(parse_scenario(SCENE, "eph.yaml", None))
    sim.run(3600.0)
    jd = julian_date("2024-06-20T20:51:00") + 3600.0 / 86400.0
    T = (jd + TT_MINUS_UTC / 86400.0 - J2000) / 36525.0
    expected = np.zeros(3)
    sun_position(T, expected)
    assert_allclose(sim.signal("eph.sun_position"), expected, rtol=0, atol=1e-12 * np.linalg.norm(expected))
    s = sim.signal("eph.sun_direction")
    # solstice 2024-06-20 20:51 UTC (US Naval Observatory): ecliptic longitude of date 90 deg, i.e.
    # 90 - 0.3418 deg in J2000 axes (general precession 5029.1"/century x 0.2447 century), one hour
    # later +0.0413 deg; right ascension there moves 1/cos(eps) = 1.0904 times faster than longitude:
    # RA = 90 - 1.0904 x 0.3005 = 89.672 deg, declination the obliquity 23.4393 deg (to 1e-5 deg)
    assert_allclose(np.degrees(np.arcsin(s[2])), 23.4393, atol=0.01)
    assert_allclose(np.degrees(np.arctan2(s[1], s[0])), 89.672, atol=0.03)


def test_a_bad_epoch_in_yaml_names_the_file_line_and_key(tmp_path):
    from shell.scenario import ScenarioError, load_scenario
    path = tmp_path / "bad.yaml"
    path.write_text('models:\n  eph: {type: SunMoonEphemeris, config: {epoch: "yesterday"}}\n')
    with pytest.raises(ScenarioError, match=r"bad.yaml:2: models.eph: .*ISO 8601"):
        build_simulation(load_scenario(path))
