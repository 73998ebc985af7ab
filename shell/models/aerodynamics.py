"""Simple launch-vehicle aerodynamics at a node: exponential or NRLMSIS atmosphere, normal-force slope,
axial force, center of pressure.

The air-relative velocity of the node in node axes is ``v_a = v - R^T w`` (``w`` a constant wind,
world axes). With the vehicle's longitudinal axis ``e`` (node axes, ``axis``), the total angle of
attack is ``alpha = atan2(|v_lat|, v_a . e)`` with ``v_lat = v_a - (v_a . e) e``, and with the
dynamic pressure ``q = rho(h) |v_a|^2 / 2`` and reference area S (Blakelock / Greensite missile and
launch-vehicle linear aerodynamics; TM-2020-5008164 App. F airframe loads)::

    N = q S C_N_alpha alpha        normal force, opposite to v_lat
    A = q S C_A                    axial force, along -e (for v_a . e > 0)
    F = -N v_lat / |v_lat| - A sign(v_a . e) e,   applied at the center of pressure x_cp e

so the node receives ``F`` and the torque ``(x_cp e) x F``. Altitude ``h = |r| - planet_radius``
(``planet_radius: 0`` for a flat world with h = the world z coordinate). The density ``rho(h)``
(config ``atmosphere``):

* ``exponential`` (default): ``rho = rho_0 exp(-h / H)`` (parameters ``sea_level_density``,
  ``scale_height``).
* ``nrlmsis``: NRLMSIS 2.1 (Emmert et al. 2021, through the maintained pymsis package, as the orbital
  :class:`shell.models.atmosphere.AtmosphericDrag`) at the launch site (``latitude``, ``longitude``,
  geodetic) and the scene epoch (config ``epoch``, required), with the given solar and geomagnetic
  indices (``f107``, ``f107_average``, ``ap``; no space-weather file is downloaded). At build time pymsis
  gives ``ln rho`` every 0.25 km from 0 to 1000 km (parameter ``log_density``; all zero: computed), and
  each evaluation interpolates it linearly in h (extrapolating linearly below 0 and above 1000 km):
  within 1.3e-4 of pymsis itself at any altitude (four sites and seasons, checked every 5 m, every
  0.5 m at 5-25 km), the largest error at the tropopause kink (10-15 km).
  The profile is the site's at the epoch: held over the run (an ascent lasts minutes; the day-night
  change of the thermosphere is hours) and over the downrange distance (hundreds of km through the
  dense atmosphere, where the density's horizontal gradients are a few per cent).

Outputs: ``force``, ``torque`` (node axes), ``dynamic_pressure``, ``angle_of_attack`` and ``density``.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from shell.model import Declarations, Model, ModelError, OutputPort, Parameter
from shell.models.atmosphere import msis_log_density_profile
from shell.models.ephemeris import EPOCH_PARAMETERS, julian_date
from shell.ports import node_inputs, node_load_outputs
from shell.registry import register_model

ATMOSPHERES = ("exponential", "nrlmsis")
PROFILE_ALTITUDES = np.arange(0.0, 1000.0 + 1e-9, 0.25) * 1e3      # m, the NRLMSIS profile's grid
N_PROFILE = len(PROFILE_ALTITUDES)
PROFILE_BOTTOM, PROFILE_STEP = float(PROFILE_ALTITUDES[0]), float(PROFILE_ALTITUDES[1] - PROFILE_ALTITUDES[0])

AIRFRAME_PARAMETERS = (
    Parameter("axis", "", (0.0, 0.0, 1.0), (3,), (-1.0, 1.0), "longitudinal (nose) axis, node axes"),
    Parameter("reference_area", "m^2", None, (), (0.0, None), "reference area S"),
    Parameter("normal_force_slope", "1/rad", None, (), None, "C_N_alpha"),
    Parameter("axial_coefficient", "", 0.0, (), None, "C_A"),
    Parameter("center_of_pressure", "m", 0.0, (), None, "center of pressure along the axis from the node"),
)
EXPONENTIAL_PARAMETERS = (
    Parameter("sea_level_density", "kg/m^3", 1.225, (), (0.0, None), "rho_0"),
    Parameter("scale_height", "m", 7200.0, (), (1e-9, None), "exponential-atmosphere scale height H"),
)
WORLD_PARAMETERS = (
    Parameter("planet_radius", "m", 0.0, (), (0.0, None), "0: flat world, altitude = world z"),
    Parameter("wind", "m/s", (0.0, 0.0, 0.0), (3,), None, "constant wind, world axes"),
)
NRLMSIS_PARAMETERS = (
    EPOCH_PARAMETERS[0],
    Parameter("latitude", "deg", None, (), (-90.0, 90.0), "geodetic latitude of the site (NRLMSIS profile)"),
    Parameter("longitude", "deg", None, (), (-360.0, 360.0), "east longitude of the site (NRLMSIS profile)"),
    Parameter("f107", "", 150.0, (), (0.0, 400.0), "F10.7 solar flux of the previous day (sfu)"),
    Parameter("f107_average", "", 150.0, (), (0.0, 400.0), "81-day mean F10.7 (sfu)"),
    Parameter("ap", "", 4.0, (), (0.0, 400.0), "daily geomagnetic Ap index"),
    Parameter("log_density", "", np.zeros(N_PROFILE), (N_PROFILE,), None,
              "ln(rho / (kg/m^3)) every 0.25 km from 0 to 1000 km (all zero: NRLMSIS 2.1 at the site and epoch)"),
)
PARAMETERS = AIRFRAME_PARAMETERS + EXPONENTIAL_PARAMETERS + WORLD_PARAMETERS
MSIS_PARAMETERS = AIRFRAME_PARAMETERS + WORLD_PARAMETERS + NRLMSIS_PARAMETERS
INPUTS = node_inputs("position", "linear_velocity", "rotation", feedthrough=True, position="node position, world",
                     linear_velocity="node velocity, node axes", rotation="rotation node -> world")
OUTPUTS = (
    *node_load_outputs("force", "torque", force="aerodynamic force, node axes",
                       torque="aerodynamic torque about the node, node axes"),
    OutputPort("dynamic_pressure", "Pa", (), "q = rho |v_a|^2 / 2", feedthrough=True),
    OutputPort("angle_of_attack", "rad", (), "total angle of attack", feedthrough=True),
    OutputPort("density", "kg/m^3", (), "air density rho(h)", feedthrough=True),
)
AERO = Declarations(parameters=PARAMETERS, inputs=INPUTS, outputs=OUTPUTS)
AERO_MSIS = Declarations(parameters=MSIS_PARAMETERS, inputs=INPUTS, outputs=OUTPUTS)
P, U, Y, P_MSIS = AERO.P, AERO.U, AERO.Y, AERO_MSIS.P


@njit(cache=True)
def _altitude(u, planet_radius):
    r = U.position
    if planet_radius > 0.0:
        return np.sqrt(u[r] ** 2 + u[r + 1] ** 2 + u[r + 2] ** 2) - planet_radius
    return u[r + 2]


@njit(cache=True)
def profile_log_density(p, altitude):
    """ln rho linearly interpolated in the profile at p[P_MSIS.log_density:], extrapolated linearly
    below its first and above its last altitude."""
    f = (altitude - PROFILE_BOTTOM) / PROFILE_STEP
    i = min(max(int(np.floor(f)), 0), N_PROFILE - 2)
    w = f - i
    return (1.0 - w) * p[P_MSIS.log_density + i] + w * p[P_MSIS.log_density + i + 1]


@njit(cache=True)
def _loads(u, y, rho, e0, e1, e2, area, normal_slope, axial_coefficient, cp, w0, w1, w2):
    """The loads of the module docstring for density rho (axis e, wind w in world axes)."""
    v, rotation = U.linear_velocity, U.rotation
    # v_a = v - R^T w, R row-major: (R^T w)_i = R[0, i] w_0 + R[1, i] w_1 + R[2, i] w_2
    va0 = u[v] - (u[rotation] * w0 + u[rotation + 3] * w1 + u[rotation + 6] * w2)
    va1 = u[v + 1] - (u[rotation + 1] * w0 + u[rotation + 4] * w1 + u[rotation + 7] * w2)
    va2 = u[v + 2] - (u[rotation + 2] * w0 + u[rotation + 5] * w1 + u[rotation + 8] * w2)
    axial = va0 * e0 + va1 * e1 + va2 * e2
    l0, l1, l2 = va0 - axial * e0, va1 - axial * e1, va2 - axial * e2
    lateral = np.sqrt(l0 * l0 + l1 * l1 + l2 * l2)
    q = 0.5 * rho * (va0 * va0 + va1 * va1 + va2 * va2)
    alpha = np.arctan2(lateral, axial)
    normal = q * area * normal_slope * alpha
    drag = q * area * axial_coefficient * (1.0 if axial >= 0.0 else -1.0)
    f0, f1, f2 = -drag * e0, -drag * e1, -drag * e2
    if lateral > 0.0:
        f0 -= normal * l0 / lateral
        f1 -= normal * l1 / lateral
        f2 -= normal * l2 / lateral
    c0, c1, c2 = cp * e0, cp * e1, cp * e2
    y[Y.force], y[Y.force + 1], y[Y.force + 2] = f0, f1, f2
    y[Y.torque] = c1 * f2 - c2 * f1
    y[Y.torque + 1] = c2 * f0 - c0 * f2
    y[Y.torque + 2] = c0 * f1 - c1 * f0
    y[Y.dynamic_pressure] = q
    y[Y.angle_of_attack] = alpha
    y[Y.density] = rho


@njit(cache=True)
def _aero_loads(t, x, z, u, p, y):
    altitude = _altitude(u, p[P.planet_radius])
    rho = p[P.sea_level_density] * np.exp(-altitude / p[P.scale_height])
    _loads(u, y, rho, p[P.axis], p[P.axis + 1], p[P.axis + 2], p[P.reference_area], p[P.normal_force_slope],
           p[P.axial_coefficient], p[P.center_of_pressure], p[P.wind], p[P.wind + 1], p[P.wind + 2])


@njit(cache=True)
def _aero_loads_msis(t, x, z, u, p, y):
    Q = P_MSIS
    rho = np.exp(profile_log_density(p, _altitude(u, p[Q.planet_radius])))
    _loads(u, y, rho, p[Q.axis], p[Q.axis + 1], p[Q.axis + 2], p[Q.reference_area], p[Q.normal_force_slope],
           p[Q.axial_coefficient], p[Q.center_of_pressure], p[Q.wind], p[Q.wind + 1], p[Q.wind + 2])


@register_model
class Aerodynamics(Model):
    """Normal force (C_N_alpha), axial force (C_A) at the center of pressure; exponential or NRLMSIS
    atmosphere (config: atmosphere, epoch)."""

    summary = ("launch-vehicle aerodynamics at a node: C_N_alpha, C_A, center of pressure; exponential or "
               "NRLMSIS 2.1 atmosphere (config: atmosphere: nrlmsis, epoch; then parameters latitude, longitude, "
               "f107, f107_average, ap instead of sea_level_density, scale_height)")
    declarations = AERO
    feedthrough_outputs = staticmethod(_aero_loads)

    def __init__(self, name: str, *, atmosphere: str = "exponential", epoch=None, **kwargs):
        if atmosphere not in ATMOSPHERES:
            raise ModelError(f"model {name}: config atmosphere: expected one of {list(ATMOSPHERES)}, given "
                             f"{atmosphere!r}")
        self.atmosphere = atmosphere
        other = EXPONENTIAL_PARAMETERS if atmosphere == "nrlmsis" else NRLMSIS_PARAMETERS
        misplaced = sorted(d.name for d in other if d.name in kwargs)
        if misplaced:
            belongs = "exponential" if atmosphere == "nrlmsis" else "nrlmsis"
            raise ModelError(f"model {name}: parameter(s) {misplaced} belong to atmosphere: {belongs}, but the "
                             f"model's config atmosphere is {atmosphere!r}")
        if atmosphere == "exponential" and epoch is not None:
            raise ModelError(f"model {name}: config epoch: only read with config atmosphere: nrlmsis (the "
                             f"exponential atmosphere does not depend on the date), given {epoch!r}")
        if atmosphere == "nrlmsis":
            if epoch is None and "epoch_julian_date" not in kwargs:
                raise ModelError(f"model {name}: config epoch: required with atmosphere: nrlmsis (the date-time "
                                 f"of t = 0, UTC, e.g. epoch: '2025-03-20T14:00:00')")
            if epoch is not None:
                if "epoch_julian_date" in kwargs:
                    raise ModelError(f"model {name}: give either config epoch or parameter epoch_julian_date, "
                                     f"not both")
                try:
                    kwargs["epoch_julian_date"] = julian_date(epoch)
                except ModelError as error:
                    raise ModelError(f"model {name}: config {error}") from None
        super().__init__(name, **kwargs)

    def declare(self):
        if self.atmosphere == "nrlmsis":
            self.use_declarations(AERO_MSIS)
            self.feedthrough_outputs = _aero_loads_msis
            self.offsets = AERO_MSIS.offsets

    def configure(self):
        self.require_unit_norm("axis")
        if self.atmosphere == "nrlmsis":
            table = self.parameter("log_density")
            if not table.any():
                table[...] = msis_log_density_profile(
                    float(self.parameter("epoch_julian_date")), float(self.parameter("latitude")),
                    float(self.parameter("longitude")), PROFILE_ALTITUDES, float(self.parameter("f107")),
                    float(self.parameter("f107_average")), float(self.parameter("ap")))
