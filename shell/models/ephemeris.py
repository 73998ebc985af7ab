"""Analytic Sun and Moon ephemerides and the scene's clock: low-precision series, no downloaded kernels.

The scene's world frame is taken as the Earth-centred inertial frame of the mean equator and equinox of
J2000 (EME2000; GCRF to 0.02 arcsec of frame bias), with the central body at the origin, as
:class:`shell.models.gravity.CentralBodyGravity` assumes. Simulation time ``t`` (s) counts from the
scene epoch ``epoch_julian_date`` (UTC Julian date; config ``epoch: "2025-03-20T12:00:00"`` writes it
from an ISO date in UTC); the series run on Terrestrial Time ``TT = UTC + tt_minus_utc`` (69.184 s
since 2017).

Sun (Montenbruck & Gill, "Satellite Orbits", 2000, sec. 3.3.2, eqs. 3.43-3.46), with
``T = (JD_TT - 2451545.0) / 36525`` and ``M = 357.5256 deg + 35999.049 deg T``::

    lambda = 282.9400 deg + 0.32327 deg T + M + 6892" sin M + 72" sin 2M     ecliptic longitude, J2000
    r      = (149.619 - 2.499 cos M - 0.021 cos 2M) 10^9 m
    r_sun  = R_x(-eps) r [cos lambda, sin lambda, 0],            eps = 23.43929111 deg

(the 0.32327 deg T perihelion advance in J2000 axes is added from Standish's JPL table of approximate
planetary elements: M&G hold the perihelion fixed, which drifts 12 arcsec a year from J2000). Moon (same
section, eqs. 3.47-3.49): Brown's lunar theory truncated to its largest terms, with the
mean arguments ``L0, l, l', F, D`` (the 1.3972 deg T precession removed so that longitudes refer to the
equinox of J2000)::

    lambda = L0 + 22640" sin l + 769" sin 2l - 4586" sin(l - 2D) + 2370" sin 2D - 668" sin l' - ...
    beta   = 18520" sin(F + lambda - L0 + 412" sin 2F + 541" sin l') - 526" sin(F - 2D) + ...
    r      = 385000 km - 20905 km cos l - 3699 km cos(2D - l) - 2956 km cos 2D - ...
    r_moon = R_x(-eps) r [cos lambda cos beta, sin lambda cos beta, sin beta]

Accuracy stated by the source: about 0.1-1 arcmin for the Sun, a few arcmin and 500 km for the Moon
(tests/models/test_ephemeris.py measures it against astropy's built-in ephemerides).

Earth rotation (for Earth-fixed fields, :mod:`shell.models.magnetic`): ``r_ecef = R_z(GMST) P r_J2000``
with the IAU 1976 precession ``P = R_z(-z) R_y(theta) R_z(-zeta)`` (Lieske 1977; M&G eq. 5.23) and
the IAU 1982 sidereal time GMST(UT1 ~ UTC) (M&G eq. 5.71, Vallado eq. 3-47); nutation (< 20 arcsec),
polar motion (< 0.5 arcsec) and UT1 - UTC (< 0.9 s) are neglected.

Model :class:`SunMoonEphemeris`, outputs (the names flight software wires to, keep them):
``sun_position`` (m, world axes, central body -> Sun), ``sun_direction`` (unit vector of it),
``moon_position`` (m, world axes, central body -> Moon), ``moon_direction``.
"""

from __future__ import annotations

import datetime as _datetime

import numpy as np
from numba import njit

from shell.model import Declarations, Model, ModelError, OutputPort, Parameter
from shell.registry import register_model

J2000 = 2451545.0                        # Julian date of 2000-01-01 12:00 TT
ARCSEC = np.pi / (180.0 * 3600.0)
DEG = np.pi / 180.0
OBLIQUITY_J2000 = 23.43929111 * DEG      # M&G eq. 3.44 (IAU 1976 obliquity at J2000)
ASTRONOMICAL_UNIT = 149597870700.0       # m, IAU 2012 Resolution B2
SUN_RADIUS = 6.957e8                     # m, IAU 2015 Resolution B3 nominal solar radius
EARTH_MAGNETIC_RADIUS = 6371.2e3         # m, IGRF reference radius
TT_MINUS_UTC = 69.184                    # s, 32.184 s + 37 leap seconds (since 2017-01-01)


def julian_date(value) -> float:
    """UTC Julian date of an ISO 8601 date-time (naive = UTC), a ``datetime``, or a number (returned
    as is). ``julian_date("2000-01-01T12:00:00") == 2451545.0``."""
    if isinstance(value, (int, float, np.floating, np.integer)) and not isinstance(value, bool):
        return float(value)
    if isinstance(value, str):
        try:
            value = _datetime.datetime.fromisoformat(value.strip().replace("Z", "+00:00"))
        except ValueError as error:
            raise ModelError(f"epoch {value!r}: expected an ISO 8601 date-time such as "
                             f"'2025-03-20T12:00:00' (UTC) or a Julian date number") from error
    if isinstance(value, _datetime.date) and not isinstance(value, _datetime.datetime):
        value = _datetime.datetime(value.year, value.month, value.day)
    if not isinstance(value, _datetime.datetime):
        raise ModelError(f"epoch {value!r}: expected an ISO 8601 date-time (UTC) or a Julian date number")
    if value.tzinfo is not None:
        value = value.astimezone(_datetime.timezone.utc).replace(tzinfo=None)
    delta = value - _datetime.datetime(2000, 1, 1, 12, 0, 0)
    return J2000 + delta.days + (delta.seconds + delta.microseconds * 1e-6) / 86400.0


EPOCH_PARAMETERS = (
    Parameter("epoch_julian_date", "", J2000, (), (2.0e6, 3.0e6),
              "UTC Julian date at t = 0 (config epoch: ISO date-time in UTC sets it)"),
    Parameter("tt_minus_utc", "s", TT_MINUS_UTC, (), (0.0, 100.0), "TT - UTC (32.184 s + leap seconds)"),
)


class EpochModel(Model):
    """A model on the scene's clock: accepts ``epoch`` (ISO 8601 UTC or Julian date) as a config option
    and writes it into the parameter ``epoch_julian_date``."""

    def __init__(self, name: str, *, epoch=None, **kwargs):
        if epoch is not None:
            if "epoch_julian_date" in kwargs:
                raise ModelError(f"model {name}: give either config epoch or parameter epoch_julian_date, not both")
            try:
                kwargs["epoch_julian_date"] = julian_date(epoch)
            except ModelError as error:
                raise ModelError(f"model {name}: config {error}") from None
        super().__init__(name, **kwargs)


@njit(cache=True)
def centuries_tt(t, epoch_jd_utc, tt_minus_utc):
    """Julian centuries of TT since J2000 at scene time t (s)."""
    return ((epoch_jd_utc - J2000) + (t + tt_minus_utc) / 86400.0) / 36525.0


@njit(cache=True)
def sun_position(T, out):
    """Geocentric Sun, EME2000 axes (m), at T Julian centuries TT since J2000 (M&G sec. 3.3.2)."""
    m = (357.5256 + 35999.049 * T) * DEG
    # perihelion longitude in J2000 axes advances 0.32327 deg per century (Standish, "Keplerian elements
    # for approximate positions of the major planets", JPL, Table 1, Earth-Moon barycentre); M&G hold it
    # fixed, which drifts 12 arcsec a year from J2000
    lon = (282.9400 + 0.32327 * T) * DEG + m + (6892.0 * np.sin(m) + 72.0 * np.sin(2.0 * m)) * ARCSEC
    r = (149.619 - 2.499 * np.cos(m) - 0.021 * np.cos(2.0 * m)) * 1e9
    x, y = r * np.cos(lon), r * np.sin(lon)
    ce, se = np.cos(OBLIQUITY_J2000), np.sin(OBLIQUITY_J2000)
    out[0] = x
    out[1] = ce * y
    out[2] = se * y


@njit(cache=True)
def moon_position(T, out):
    """Geocentric Moon, EME2000 axes (m), at T Julian centuries TT since J2000 (M&G sec. 3.3.2)."""
    l0 = (218.31617 + 481267.88088 * T - 1.3972 * T) * DEG
    l = (134.96292 + 477198.86753 * T) * DEG
    lp = (357.52543 + 35999.04944 * T) * DEG
    f = (93.27283 + 483202.01873 * T) * DEG
    d = (297.85027 + 445267.11135 * T) * DEG
    lon = l0 + ARCSEC * (22640.0 * np.sin(l) + 769.0 * np.sin(2.0 * l) - 4586.0 * np.sin(l - 2.0 * d)
                         + 2370.0 * np.sin(2.0 * d) - 668.0 * np.sin(lp) - 412.0 * np.sin(2.0 * f)
                         - 212.0 * np.sin(2.0 * l - 2.0 * d) - 206.0 * np.sin(l + lp - 2.0 * d)
                         + 192.0 * np.sin(l + 2.0 * d) - 165.0 * np.sin(lp - 2.0 * d)
                         + 148.0 * np.sin(l - lp) - 125.0 * np.sin(d) - 110.0 * np.sin(l + lp)
                         - 55.0 * np.sin(2.0 * f - 2.0 * d))
    lat = ARCSEC * (18520.0 * np.sin(f + lon - l0 + ARCSEC * (412.0 * np.sin(2.0 * f) + 541.0 * np.sin(lp)))
                    - 526.0 * np.sin(f - 2.0 * d) + 44.0 * np.sin(l + f - 2.0 * d)
                    - 31.0 * np.sin(-l + f - 2.0 * d) - 25.0 * np.sin(-2.0 * l + f)
                    - 23.0 * np.sin(lp + f - 2.0 * d) + 21.0 * np.sin(-l + f) + 11.0 * np.sin(-lp + f - 2.0 * d))
    r = 1e3 * (385000.0 - 20905.0 * np.cos(l) - 3699.0 * np.cos(2.0 * d - l) - 2956.0 * np.cos(2.0 * d)
               - 570.0 * np.cos(2.0 * l) + 246.0 * np.cos(2.0 * l - 2.0 * d) - 205.0 * np.cos(lp - 2.0 * d)
               - 171.0 * np.cos(l + 2.0 * d) - 152.0 * np.cos(l + lp - 2.0 * d))
    x, y, z = r * np.cos(lon) * np.cos(lat), r * np.sin(lon) * np.cos(lat), r * np.sin(lat)
    ce, se = np.cos(OBLIQUITY_J2000), np.sin(OBLIQUITY_J2000)
    out[0] = x
    out[1] = ce * y - se * z
    out[2] = se * y + ce * z


@njit(cache=True)
def greenwich_mean_sidereal_time(jd_ut1):
    """GMST (rad, in [0, 2 pi)), IAU 1982 (M&G eq. 5.71)."""
    days = jd_ut1 - J2000
    T = days / 36525.0
    # seconds of sidereal time; the 86400 s per day term is split off to keep the digits
    seconds = 67310.54841 + 8640184.812866 * T + 0.093104 * T * T - 6.2e-6 * T * T * T
    fraction = days - np.floor(days)
    angle = (seconds / 86400.0 + fraction) * 2.0 * np.pi
    angle = angle % (2.0 * np.pi)
    return angle


@njit(cache=True)
def earth_fixed_rotation(t, epoch_jd_utc, tt_minus_utc):
    """Rotation EME2000 -> Earth-fixed, R_z(GMST) P(T) with the IAU 1976 precession, as a row-major
    9-tuple (r_ecef_i = sum_j E[3 i + j] r_j)."""
    T = centuries_tt(t, epoch_jd_utc, tt_minus_utc)
    zeta = (2306.2181 * T + 0.30188 * T * T + 0.017998 * T * T * T) * ARCSEC
    z = (2306.2181 * T + 1.09468 * T * T + 0.018203 * T * T * T) * ARCSEC
    theta = (2004.3109 * T - 0.42665 * T * T - 0.041833 * T * T * T) * ARCSEC
    g = greenwich_mean_sidereal_time(epoch_jd_utc + t / 86400.0)
    # elementary frame rotations R_z(a) = [[c, s, 0], [-s, c, 0], [0, 0, 1]], R_y(a) = [[c, 0, -s], ...]
    cz, sz = np.cos(-zeta), np.sin(-zeta)
    ct, st = np.cos(theta), np.sin(theta)
    cg, sg = np.cos(g - z), np.sin(g - z)  # R_z(GMST) R_z(-z) = R_z(GMST - z)
    # A = R_y(theta) R_z(-zeta)
    a00, a01, a02 = ct * cz, ct * sz, -st
    a10, a11, a12 = -sz, cz, 0.0
    a20, a21, a22 = st * cz, st * sz, ct
    return (cg * a00 + sg * a10, cg * a01 + sg * a11, cg * a02 + sg * a12,
            -sg * a00 + cg * a10, -sg * a01 + cg * a11, -sg * a02 + cg * a12,
            a20, a21, a22)


PARAMETERS = EPOCH_PARAMETERS
OUTPUTS = (
    OutputPort("sun_position", "m", (3,), "central body -> Sun, world (EME2000) axes"),
    OutputPort("sun_direction", "", (3,), "unit vector central body -> Sun, world axes"),
    OutputPort("moon_position", "m", (3,), "central body -> Moon, world axes"),
    OutputPort("moon_direction", "", (3,), "unit vector central body -> Moon, world axes"),
)
EPHEMERIS = Declarations(parameters=PARAMETERS, outputs=OUTPUTS)
P, Y = EPHEMERIS.P, EPHEMERIS.Y


@njit(cache=True)
def _ephemeris_outputs(t, x, z, u, p, y):
    T = centuries_tt(t, p[P.epoch_julian_date], p[P.tt_minus_utc])
    sun_position(T, y[Y.sun_position:Y.sun_position + 3])
    moon_position(T, y[Y.moon_position:Y.moon_position + 3])
    for body, direction in ((Y.sun_position, Y.sun_direction), (Y.moon_position, Y.moon_direction)):
        norm = np.sqrt(y[body] ** 2 + y[body + 1] ** 2 + y[body + 2] ** 2)
        for i in range(3):
            y[direction + i] = y[body + i] / norm


@register_model
class SunMoonEphemeris(EpochModel):
    """Analytic geocentric Sun and Moon positions (Montenbruck & Gill 3.3.2); see the module docstring."""

    summary = "analytic Sun and Moon positions (M&G 3.3.2) in the world (EME2000) frame from the scene epoch"
    declarations = EPHEMERIS
    state_outputs = staticmethod(_ephemeris_outputs)
