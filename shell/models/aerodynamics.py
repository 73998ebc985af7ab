"""Simple launch-vehicle aerodynamics at a node: exponential atmosphere, normal-force slope, axial
force, center of pressure.

The air-relative velocity of the node in node axes is ``v_a = v - R^T w`` (``w`` a constant wind,
world axes). With the vehicle's longitudinal axis ``e`` (node axes, ``axis``), the total angle of
attack is ``alpha = atan2(|v_lat|, v_a . e)`` with ``v_lat = v_a - (v_a . e) e``, and with the
dynamic pressure ``q = rho(h) |v_a|^2 / 2`` and reference area S (Blakelock / Greensite missile and
launch-vehicle linear aerodynamics; TM-2020-5008164 App. F airframe loads)::

    N = q S C_N_alpha alpha        normal force, opposite to v_lat
    A = q S C_A                    axial force, along -e (for v_a . e > 0)
    F = -N v_lat / |v_lat| - A sign(v_a . e) e,   applied at the center of pressure x_cp e

so the node receives ``F`` and the torque ``(x_cp e) x F``. Atmosphere: exponential
``rho = rho_0 exp(-h / H)`` with altitude ``h = |r| - planet_radius`` (``planet_radius: 0`` for a flat
world with h = the world z coordinate). Outputs include ``dynamic_pressure`` and ``angle_of_attack``.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from shell.model import InputPort, Model, ModelError, OutputPort, Parameter
from shell.registry import register_model

# p = [axis (3), reference_area, normal_force_slope, axial_coefficient, center_of_pressure,
#      sea_level_density, scale_height, planet_radius, wind (3)]


@njit(cache=True)
def _aero_loads(t, x, z, u, p, y):
    # u = [position (3, world), linear_velocity (3, node), rotation (9, node -> world)]
    # y = [force (3), torque (3), dynamic_pressure, angle_of_attack]
    if p[9] > 0.0:
        altitude = np.sqrt(u[0] ** 2 + u[1] ** 2 + u[2] ** 2) - p[9]
    else:
        altitude = u[2]
    rho = p[7] * np.exp(-altitude / p[8])
    va0 = u[3] - (u[6] * p[10] + u[9] * p[11] + u[12] * p[12])
    va1 = u[4] - (u[7] * p[10] + u[10] * p[11] + u[13] * p[12])
    va2 = u[5] - (u[8] * p[10] + u[11] * p[11] + u[14] * p[12])
    e0, e1, e2 = p[0], p[1], p[2]
    axial = va0 * e0 + va1 * e1 + va2 * e2
    l0, l1, l2 = va0 - axial * e0, va1 - axial * e1, va2 - axial * e2
    lateral = np.sqrt(l0 * l0 + l1 * l1 + l2 * l2)
    q = 0.5 * rho * (va0 * va0 + va1 * va1 + va2 * va2)
    alpha = np.arctan2(lateral, axial)
    normal = q * p[3] * p[4] * alpha
    drag = q * p[3] * p[5] * (1.0 if axial >= 0.0 else -1.0)
    f0, f1, f2 = -drag * e0, -drag * e1, -drag * e2
    if lateral > 0.0:
        f0 -= normal * l0 / lateral
        f1 -= normal * l1 / lateral
        f2 -= normal * l2 / lateral
    c0, c1, c2 = p[6] * e0, p[6] * e1, p[6] * e2
    y[0], y[1], y[2] = f0, f1, f2
    y[3] = c1 * f2 - c2 * f1
    y[4] = c2 * f0 - c0 * f2
    y[5] = c0 * f1 - c1 * f0
    y[6] = q
    y[7] = alpha


@register_model
class Aerodynamics(Model):
    """Normal force (C_N_alpha), axial force (C_A) at the center of pressure; exponential atmosphere."""

    summary = "launch-vehicle aerodynamics at a node: exponential atmosphere, C_N_alpha, C_A, center of pressure"
    parameters = (
        Parameter("axis", "", (0.0, 0.0, 1.0), (3,), (-1.0, 1.0), "longitudinal (nose) axis, node axes"),
        Parameter("reference_area", "m^2", None, (), (0.0, None), "reference area S"),
        Parameter("normal_force_slope", "1/rad", None, (), None, "C_N_alpha"),
        Parameter("axial_coefficient", "", 0.0, (), None, "C_A"),
        Parameter("center_of_pressure", "m", 0.0, (), None, "center of pressure along the axis from the node"),
        Parameter("sea_level_density", "kg/m^3", 1.225, (), (0.0, None), "rho_0"),
        Parameter("scale_height", "m", 7200.0, (), (1e-9, None), "exponential-atmosphere scale height H"),
        Parameter("planet_radius", "m", 0.0, (), (0.0, None), "0: flat world, altitude = world z"),
        Parameter("wind", "m/s", (0.0, 0.0, 0.0), (3,), None, "constant wind, world axes"),
    )
    inputs = (
        InputPort("position", "m", (3,), "node position, world", feedthrough=True),
        InputPort("linear_velocity", "m/s", (3,), "node velocity, node axes", feedthrough=True),
        InputPort("rotation", "", (3, 3), "rotation node -> world", feedthrough=True),
    )
    outputs = (
        OutputPort("force", "N", (3,), "aerodynamic force, node axes", feedthrough=True),
        OutputPort("torque", "N*m", (3,), "aerodynamic torque about the node, node axes", feedthrough=True),
        OutputPort("dynamic_pressure", "Pa", (), "q = rho |v_a|^2 / 2", feedthrough=True),
        OutputPort("angle_of_attack", "rad", (), "total angle of attack", feedthrough=True),
    )
    feedthrough_outputs = staticmethod(_aero_loads)

    def configure(self):
        axis = self.parameter("axis")
        if abs(float(np.sqrt(axis @ axis)) - 1.0) > 1e-9:
            raise ModelError(f"model {self.path}: parameter axis: expected a unit vector, given {axis.tolist()}")
