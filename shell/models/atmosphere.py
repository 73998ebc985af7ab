"""Orbital drag with the NRLMSIS 2.1 thermosphere (through the maintained pymsis package).

``AtmosphericDrag`` -- attach to a node (position from the Earth's center and rotation node -> world,
velocity in node axes) and wire the Sun (``SunMoonEphemeris.sun_position``): the density depends on the
local solar time. At build time the model asks pymsis (NRLMSIS 2.1, Emmert et al. 2021) for the total
mass density on a grid of altitude (100 to 1000 km every 5 km), geodetic latitude (every 10 deg) and
local solar time (every hour) at the scene epoch, with the given solar and geomagnetic indices
(``f107``, ``f107_average``, ``ap``: no space-weather file is downloaded), and stores its logarithm
(parameter ``log_density``; all zero: computed at the epoch). Each evaluation interpolates ``ln rho``
trilinearly at the node's altitude above the WGS 84 ellipsoid (``|r| - R(phi)``, geocentric latitude
phi; within 0.2 deg of the geodetic one), latitude, and local solar time
``12 h + (alpha_node - alpha_sun) 12 h / pi`` (right ascensions, world axes), extrapolating ``ln rho``
linearly outside 100-1000 km. Held at the epoch over a run: the day of year, the indices, and the small
longitude (universal-time) terms of the model at a fixed local time.

Drag on the node (Vallado sec. 8.6.2; a cannonball: the attitude enters through ``center`` only)::

    v_rel = R v - omega_E x r               air co-rotating with the Earth, world axes
    F     = -1/2 rho C_D A |v_rel| v_rel     node axes after R^T;  torque = c x F

Outputs: ``force``, ``torque`` (node axes), ``density`` (kg/m^3), ``altitude`` (m).

Layout: the scalar parameters first (``PARAMETERS``), then ``log_density`` (altitude, latitude, local
time) row-major at the fixed offset ``P.log_density``; the grid is the module's ``ALTITUDES``,
``LATITUDES``, ``LOCAL_TIMES``.
"""

from __future__ import annotations

import datetime as _datetime

import numpy as np
from numba import njit

from shell.model import Declarations, InputPort, OutputPort, Parameter
from shell.models.ephemeris import J2000, EpochModel, EPOCH_PARAMETERS
from shell.models.gravity import EARTH_RADIUS
from shell.ports import node_inputs, node_load_outputs
from shell.registry import register_model

ALTITUDES = np.arange(100.0, 1000.0 + 1e-9, 5.0) * 1e3      # m
LATITUDES = np.arange(-90.0, 90.0 + 1e-9, 10.0)             # deg, geodetic
LOCAL_TIMES = np.arange(0.0, 24.0 + 1e-9, 1.0)              # h (24 repeats 0)
N_ALT, N_LAT, N_LST = len(ALTITUDES), len(LATITUDES), len(LOCAL_TIMES)
WGS84_POLAR_RADIUS = 6356752.314245
EARTH_ROTATION_RATE = 7.292115e-5   # rad/s, IERS

PARAMETERS = EPOCH_PARAMETERS + (
    Parameter("f107", "", 150.0, (), (0.0, 400.0), "F10.7 solar flux of the previous day (sfu)"),
    Parameter("f107_average", "", 150.0, (), (0.0, 400.0), "81-day mean F10.7 (sfu)"),
    Parameter("ap", "", 4.0, (), (0.0, 400.0), "daily geomagnetic Ap index"),
    Parameter("drag_coefficient", "", 2.2, (), (0.0, None), "C_D"),
    Parameter("area", "m^2", None, (), (0.0, None), "reference area A"),
    Parameter("center", "m", (0.0, 0.0, 0.0), (3,), None, "center of pressure from the node, node axes"),
    Parameter("earth_rotation_rate", "rad/s", EARTH_ROTATION_RATE, (), None, "co-rotation of the atmosphere"),
    Parameter("log_density", "", np.zeros((N_ALT, N_LAT, N_LST)), (N_ALT, N_LAT, N_LST), None,
              "ln(rho / (kg/m^3)) on the grid (all zero: NRLMSIS 2.1 at the epoch)"),
)
INPUTS = (
    *node_inputs("position", "rotation", "linear_velocity", feedthrough=True,
                 position="node position from the Earth's center, world", rotation="rotation node -> world",
                 linear_velocity="node velocity, node axes"),
    InputPort("sun_position", "m", (3,), "Earth -> Sun, world axes", feedthrough=True),
)
OUTPUTS = (
    *node_load_outputs("force", "torque", force="drag force, node axes",
                       torque="drag torque about the node, node axes"),
    OutputPort("density", "kg/m^3", (), "NRLMSIS total mass density", feedthrough=True),
    OutputPort("altitude", "m", (), "altitude above the ellipsoid", feedthrough=True),
)
DRAG = Declarations(parameters=PARAMETERS, inputs=INPUTS, outputs=OUTPUTS)
P, U, Y = DRAG.P, DRAG.U, DRAG.Y
ALT0, DALT = float(ALTITUDES[0]), float(ALTITUDES[1] - ALTITUDES[0])
LAT0, DLAT = float(LATITUDES[0]), float(LATITUDES[1] - LATITUDES[0])
DLST = float(LOCAL_TIMES[1] - LOCAL_TIMES[0])


def _epoch_datetime(epoch_julian_date):
    """The UTC date-time of a Julian date, to the microsecond."""
    return _datetime.datetime(2000, 1, 1, 12) + _datetime.timedelta(days=float(epoch_julian_date) - J2000)


def msis_log_density_profile(epoch_julian_date, latitude_deg, longitude_deg, altitudes_m, f107, f107_average, ap):
    """ln(total mass density, kg/m^3) from pymsis (NRLMSIS 2.1) at one site (geodetic latitude and
    longitude, deg) and one instant (the epoch, to the second) at the given altitudes (m), with the given
    daily F10.7, its 81-day mean and a constant Ap (no space-weather file downloaded)."""
    import pymsis

    epoch = np.datetime64(_epoch_datetime(epoch_julian_date).replace(microsecond=0))
    out = pymsis.calculate(epoch, float(longitude_deg), float(latitude_deg), np.asarray(altitudes_m) / 1e3,
                           f107s=f107, f107as=f107_average, aps=[[ap] * 7], version=2.1)
    return np.log(out[..., pymsis.Variable.MASS_DENSITY]).reshape(np.shape(altitudes_m))


def msis_log_density_table(epoch_julian_date, f107, f107_average, ap):
    """ln(total mass density, kg/m^3) from pymsis (NRLMSIS 2.1) on the module's grid at the epoch."""
    import pymsis

    epoch = _epoch_datetime(epoch_julian_date)
    ut_hours = epoch.hour + epoch.minute / 60.0 + epoch.second / 3600.0
    table = np.empty((N_ALT, N_LAT, N_LST))
    for k, lst in enumerate(LOCAL_TIMES):
        lon = ((lst - ut_hours) * 15.0) % 360.0
        out = pymsis.calculate(np.datetime64(epoch.replace(microsecond=0)), lon, LATITUDES, ALTITUDES / 1e3,
                               f107s=f107, f107as=f107_average, aps=[[ap] * 7], version=2.1)
        table[:, :, k] = np.log(np.squeeze(out[..., pymsis.Variable.MASS_DENSITY])).T  # (lat, alt) -> (alt, lat)
    return table


@njit(cache=True)
def log_density(p, altitude, latitude_deg, local_time_h):
    """Trilinear interpolation of ln rho in the table at p[P.log_density:] (linear extrapolation in
    altitude, clamped latitude, periodic local time)."""
    fa = (altitude - ALT0) / DALT
    ia = min(max(int(np.floor(fa)), 0), N_ALT - 2)
    wa = fa - ia
    fl = min(max((latitude_deg - LAT0) / DLAT, 0.0), N_LAT - 1.0)
    il = min(int(np.floor(fl)), N_LAT - 2)
    wl = fl - il
    ft = (local_time_h % 24.0) / DLST
    it = min(int(np.floor(ft)), N_LST - 2)
    wt = ft - it
    value = 0.0
    for da in range(2):
        ca = wa if da == 1 else 1.0 - wa
        for dl in range(2):
            cl = wl if dl == 1 else 1.0 - wl
            for dt in range(2):
                ct = wt if dt == 1 else 1.0 - wt
                value += ca * cl * ct * p[P.log_density + ((ia + da) * N_LAT + il + dl) * N_LST + it + dt]
    return value


@njit(cache=True)
def _drag_loads(t, x, z, u, p, y):
    r, rot, v, s = U.position, U.rotation, U.linear_velocity, U.sun_position
    r0, r1, r2 = u[r], u[r + 1], u[r + 2]
    rn = np.sqrt(r0 * r0 + r1 * r1 + r2 * r2)
    rho_xy = np.sqrt(r0 * r0 + r1 * r1)
    latitude = np.arctan2(r2, rho_xy)
    a, b = EARTH_RADIUS, WGS84_POLAR_RADIUS
    cl, sl = np.cos(latitude), np.sin(latitude)
    surface = a * b / np.sqrt(b * b * cl * cl + a * a * sl * sl)
    altitude = rn - surface
    local_time = 12.0 + (np.arctan2(r1, r0) - np.arctan2(u[s + 1], u[s])) * 12.0 / np.pi
    rho = np.exp(log_density(p, altitude, latitude * 180.0 / np.pi, local_time % 24.0))
    # world velocity R v, minus the co-rotating air omega_E z x r = omega_E (-y, x, 0)
    w = p[P.earth_rotation_rate]
    vw0 = u[rot] * u[v] + u[rot + 1] * u[v + 1] + u[rot + 2] * u[v + 2] + w * r1
    vw1 = u[rot + 3] * u[v] + u[rot + 4] * u[v + 1] + u[rot + 5] * u[v + 2] - w * r0
    vw2 = u[rot + 6] * u[v] + u[rot + 7] * u[v + 1] + u[rot + 8] * u[v + 2]
    speed = np.sqrt(vw0 * vw0 + vw1 * vw1 + vw2 * vw2)
    k = -0.5 * rho * p[P.drag_coefficient] * p[P.area] * speed
    f0 = k * (u[rot] * vw0 + u[rot + 3] * vw1 + u[rot + 6] * vw2)  # R^T (k v_rel)
    f1 = k * (u[rot + 1] * vw0 + u[rot + 4] * vw1 + u[rot + 7] * vw2)
    f2 = k * (u[rot + 2] * vw0 + u[rot + 5] * vw1 + u[rot + 8] * vw2)
    c0, c1, c2 = p[P.center], p[P.center + 1], p[P.center + 2]
    y[Y.force], y[Y.force + 1], y[Y.force + 2] = f0, f1, f2
    y[Y.torque] = c1 * f2 - c2 * f1
    y[Y.torque + 1] = c2 * f0 - c0 * f2
    y[Y.torque + 2] = c0 * f1 - c1 * f0
    y[Y.density] = rho
    y[Y.altitude] = altitude


@register_model
class AtmosphericDrag(EpochModel):
    """Cannonball drag with NRLMSIS 2.1 density (pymsis table at the epoch); see the module docstring."""

    summary = "orbital drag at a node with NRLMSIS 2.1 density (pymsis, at the epoch; F10.7, Ap given)"
    declarations = DRAG
    feedthrough_outputs = staticmethod(_drag_loads)

    def configure(self):
        table = self.parameter("log_density")
        if not table.any():
            table[...] = msis_log_density_table(float(self.parameter("epoch_julian_date")),
                                                float(self.parameter("f107")), float(self.parameter("f107_average")),
                                                float(self.parameter("ap")))
