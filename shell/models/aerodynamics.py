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

from shell.model import InputPort, Model, ModelError, OutputPort, Parameter, named_offsets
from shell.registry import register_model

PARAMETERS = (
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
INPUTS = (
    InputPort("position", "m", (3,), "node position, world", feedthrough=True),
    InputPort("linear_velocity", "m/s", (3,), "node velocity, node axes", feedthrough=True),
    InputPort("rotation", "", (3, 3), "rotation node -> world", feedthrough=True),
)
OUTPUTS = (
    OutputPort("force", "N", (3,), "aerodynamic force, node axes", feedthrough=True),
    OutputPort("torque", "N*m", (3,), "aerodynamic torque about the node, node axes", feedthrough=True),
    OutputPort("dynamic_pressure", "Pa", (), "q = rho |v_a|^2 / 2", feedthrough=True),
    OutputPort("angle_of_attack", "rad", (), "total angle of attack", feedthrough=True),
)
P, U, Y = named_offsets(PARAMETERS), named_offsets(INPUTS), named_offsets(OUTPUTS)


@njit(cache=True)
def _aero_loads(t, x, z, u, p, y):
    r, v, rotation, wind, axis = U.position, U.linear_velocity, U.rotation, P.wind, P.axis
    if p[P.planet_radius] > 0.0:
        altitude = np.sqrt(u[r] ** 2 + u[r + 1] ** 2 + u[r + 2] ** 2) - p[P.planet_radius]
    else:
        altitude = u[r + 2]
    rho = p[P.sea_level_density] * np.exp(-altitude / p[P.scale_height])
    # v_a = v - R^T w, R row-major: (R^T w)_i = R[0, i] w_0 + R[1, i] w_1 + R[2, i] w_2
    va0 = u[v] - (u[rotation] * p[wind] + u[rotation + 3] * p[wind + 1] + u[rotation + 6] * p[wind + 2])
    va1 = u[v + 1] - (u[rotation + 1] * p[wind] + u[rotation + 4] * p[wind + 1] + u[rotation + 7] * p[wind + 2])
    va2 = u[v + 2] - (u[rotation + 2] * p[wind] + u[rotation + 5] * p[wind + 1] + u[rotation + 8] * p[wind + 2])
    e0, e1, e2 = p[axis], p[axis + 1], p[axis + 2]
    axial = va0 * e0 + va1 * e1 + va2 * e2
    l0, l1, l2 = va0 - axial * e0, va1 - axial * e1, va2 - axial * e2
    lateral = np.sqrt(l0 * l0 + l1 * l1 + l2 * l2)
    q = 0.5 * rho * (va0 * va0 + va1 * va1 + va2 * va2)
    alpha = np.arctan2(lateral, axial)
    normal = q * p[P.reference_area] * p[P.normal_force_slope] * alpha
    drag = q * p[P.reference_area] * p[P.axial_coefficient] * (1.0 if axial >= 0.0 else -1.0)
    f0, f1, f2 = -drag * e0, -drag * e1, -drag * e2
    if lateral > 0.0:
        f0 -= normal * l0 / lateral
        f1 -= normal * l1 / lateral
        f2 -= normal * l2 / lateral
    cp = p[P.center_of_pressure]
    c0, c1, c2 = cp * e0, cp * e1, cp * e2
    y[Y.force], y[Y.force + 1], y[Y.force + 2] = f0, f1, f2
    y[Y.torque] = c1 * f2 - c2 * f1
    y[Y.torque + 1] = c2 * f0 - c0 * f2
    y[Y.torque + 2] = c0 * f1 - c1 * f0
    y[Y.dynamic_pressure] = q
    y[Y.angle_of_attack] = alpha


@register_model
class Aerodynamics(Model):
    """Normal force (C_N_alpha), axial force (C_A) at the center of pressure; exponential atmosphere."""

    summary = "launch-vehicle aerodynamics at a node: exponential atmosphere, C_N_alpha, C_A, center of pressure"
    parameters = PARAMETERS
    inputs = INPUTS
    outputs = OUTPUTS
    offsets = {"p": P, "u": U, "y": Y}
    feedthrough_outputs = staticmethod(_aero_loads)

    def configure(self):
        axis = self.parameter("axis")
        if abs(float(np.sqrt(axis @ axis)) - 1.0) > 1e-9:
            raise ModelError(f"model {self.path}: parameter axis: expected a unit vector, given {axis.tolist()}")
