"""Third-body gravity: the double-precision form against a 50-digit evaluation of the same expression
(mpmath, installed with sympy in the test extra), the tidal limit, and a scenario with the ephemeris."""

import mpmath
import numpy as np
from numpy.testing import assert_allclose

from shell.models.ephemeris import TT_MINUS_UTC, centuries_tt, julian_date, moon_position, sun_position
from shell.models.third_body import MOON_MU, SUN_MU, third_body_acceleration
from shell.scenario import build_simulation, parse_scenario


def _exact(r, s, mu):
    mpmath.mp.dps = 50
    r, s = [mpmath.mpf(float(c)) for c in r], [mpmath.mpf(float(c)) for c in s]
    d = [si - ri for si, ri in zip(s, r)]
    dn = mpmath.sqrt(sum(c * c for c in d))
    sn = mpmath.sqrt(sum(c * c for c in s))
    return np.array([float(mu * (di / dn**3 - si / sn**3)) for di, si in zip(d, s)])


def test_double_precision_against_fifty_digits_and_tidal_limit():
    rng = np.random.default_rng(3)
    for body, mu, distance in (("sun", SUN_MU, 1.496e11), ("moon", MOON_MU, 3.84e8)):
        for _ in range(20):
            r = rng.normal(size=3) * 4e6
            s = rng.normal(size=3)
            s *= distance / np.linalg.norm(s)
            ours = np.array(third_body_acceleration(*r, *s, mu))
            exact = _exact(r, s, mu)
            # cancellation of two terms |s|/|r| ~ 2e4 (Sun) and 50 (Moon) times larger than the result
            assert_allclose(ours, exact, rtol=0, atol=1e-11 * np.linalg.norm(exact))
        # tidal limit mu/|s|^3 (3 (s_hat . r) s_hat - r): the relative difference is O(|r|/|s|)
        r = np.array([7e6, 0.0, 0.0])
        errors = []
        for scale in (1.0, 10.0):
            s = np.array([1.0, 1.0, 0.5]) / 1.5 * distance * scale
            sh = s / np.linalg.norm(s)
            tidal = mu / np.linalg.norm(s) ** 3 * (3 * (sh @ r) * sh - r)
            ours = np.array(third_body_acceleration(*r, *s, mu))
            errors.append(np.linalg.norm(ours - tidal) / np.linalg.norm(tidal))
        assert_allclose(errors[1] / errors[0], 0.1, rtol=0.05)  # first order in |r|/|s|


SCENE = """
multibody:
  bodies:
    - name: sat
      hinge: free
      mass: 500 kg
      inertia: "[100, 100, 100] kg*m^2"
      initial: {position: "[42164, 0, 0] km", velocity: "[0, 3074.7, 0] m/s", attitude: [0.8, 0.6, 0, 0]}
  nodes:
    - {name: cm, body: sat}
models:
  ephemeris: {type: SunMoonEphemeris, config: {epoch: "2025-01-01T00:00:00"}}
  third_body: {type: ThirdBodyGravity, attach: {node: cm}, parameters: {mass: 500 kg}}
connections:
  - ephemeris.sun_position -> third_body.sun_position
  - ephemeris.moon_position -> third_body.moon_position
integrator: {method: rk4, step: 10 s}
log: {rate: 0.01 Hz, signals: [third_body.force, multibody.cm.position, multibody.cm.rotation]}
"""


def test_geostationary_perturbation_through_a_scenario():
    sim = build_simulation(parse_scenario(SCENE, "tb.yaml", None))
    sim.run(600.0)
    t = 600.0
    T = centuries_tt(t, julian_date("2025-01-01T00:00:00"), TT_MINUS_UTC)  # the same rounding of the time
    s, m = np.zeros(3), np.zeros(3)
    sun_position(T, s)
    moon_position(T, m)
    r = sim.signal("multibody.cm.position")
    R = sim.signal("multibody.cm.rotation")
    expected = 500.0 * R.T @ (np.array(third_body_acceleration(*r, *s, SUN_MU))
                              + np.array(third_body_acceleration(*r, *m, MOON_MU)))
    assert_allclose(sim.signal("third_body.force"), expected, rtol=0, atol=1e-12 * np.linalg.norm(expected))
    # at GEO the lunisolar acceleration is ~1e-5 m/s^2 (Moon ~7e-6, Sun ~3.5e-6 at most)
    assert 1e-6 < np.linalg.norm(expected) / 500.0 < 2e-5
