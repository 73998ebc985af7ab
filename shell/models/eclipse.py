"""Eclipse: the shadow of the central body on a node, cylindrical or conical (penumbra fraction).

Attach to a node (``attach: {node: ...}``: it reads the node's world position ``r``, central body at the
origin) and wire the Sun (``SunMoonEphemeris.sun_position -> <eclipse>.sun_position``, world axes, central
body -> Sun). Output ``shadow_factor`` (the name flight software and the radiation-pressure and
sun-sensor models wire to, keep it): the fraction of the solar disc visible, 1 lit .. 0 umbra.

``shadow: conical`` (default; Montenbruck & Gill, "Satellite Orbits", sec. 3.4.2, eqs. 3.85-3.87): with
the apparent radii of the Sun ``a = asin(R_sun / |s - r|)`` and of the body ``b = asin(R_b / |r|)`` and
their apparent separation ``c = acos(-r . (s - r) / (|r| |s - r|))``::

    c >= a + b           nu = 1                                   lit
    c <= b - a           nu = 0                                   umbra
    c <= a - b           nu = 1 - b^2 / a^2                       antumbra (annular)
    otherwise            nu = 1 - A / (pi a^2),                   penumbra
                         A = a^2 acos(x/a) + b^2 acos((c - x)/b) - c y,
                         x = (c^2 + a^2 - b^2) / (2 c),  y = sqrt(a^2 - x^2)

(A is the area of the overlap of the two discs: planar approximation of the small circles.)

``shadow: cylindrical`` (Vallado, "Fundamentals of Astrodynamics", 4th ed., sec. 5.3): the Sun at
infinity, ``nu = 0`` when ``r . s_hat < 0`` and ``|r - (r . s_hat) s_hat| < R_b``, else 1.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from shell.model import Declarations, InputPort, Model, ModelError, OutputPort, Parameter
from shell.models.ephemeris import SUN_RADIUS
from shell.models.gravity import EARTH_RADIUS
from shell.ports import node_inputs
from shell.registry import register_model

SHADOWS = {"cylindrical": 0.0, "conical": 1.0}
CYLINDRICAL = 0.0

PARAMETERS = (
    Parameter("body_radius", "m", EARTH_RADIUS, (), (0.0, None), "radius of the shadowing body (default Earth)"),
    Parameter("sun_radius", "m", SUN_RADIUS, (), (0.0, None), "solar radius (conical shadow)"),
    Parameter("shadow_model", "", 1.0, (), (0.0, 1.0), "0 cylindrical, 1 conical (set by config shadow)"),
)
INPUTS = (
    *node_inputs("position", feedthrough=True, position="node position from the body's center, world axes"),
    InputPort("sun_position", "m", (3,), "body center -> Sun, world axes", feedthrough=True),
)
OUTPUTS = (OutputPort("shadow_factor", "", (), "visible fraction of the solar disc: 1 lit .. 0 umbra",
                      feedthrough=True),)
ECLIPSE = Declarations(parameters=PARAMETERS, inputs=INPUTS, outputs=OUTPUTS)
P, U, Y = ECLIPSE.P, ECLIPSE.U, ECLIPSE.Y


@njit(cache=True)
def conical_shadow(r, s, body_radius, sun_radius):
    """Visible fraction of the solar disc at r (M&G eqs. 3.85-3.87); r, s from the body center."""
    d0, d1, d2 = s[0] - r[0], s[1] - r[1], s[2] - r[2]
    dn = np.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
    rn = np.sqrt(r[0] * r[0] + r[1] * r[1] + r[2] * r[2])
    if rn <= body_radius:
        return 0.0
    a = np.arcsin(min(sun_radius / dn, 1.0))
    b = np.arcsin(body_radius / rn)
    cos_c = -(r[0] * d0 + r[1] * d1 + r[2] * d2) / (rn * dn)
    c = np.arccos(max(-1.0, min(1.0, cos_c)))
    if c >= a + b:
        return 1.0
    if c <= b - a:
        return 0.0
    if c <= a - b:
        return 1.0 - (b * b) / (a * a)
    x = (c * c + a * a - b * b) / (2.0 * c)
    y = np.sqrt(max(a * a - x * x, 0.0))
    area = (a * a * np.arccos(max(-1.0, min(1.0, x / a))) + b * b * np.arccos(max(-1.0, min(1.0, (c - x) / b)))
            - c * y)
    return 1.0 - area / (np.pi * a * a)


@njit(cache=True)
def cylindrical_shadow(r, s, body_radius):
    """1 lit, 0 in the cylinder of radius body_radius behind the body (Sun at infinity)."""
    sn = np.sqrt(s[0] * s[0] + s[1] * s[1] + s[2] * s[2])
    along = (r[0] * s[0] + r[1] * s[1] + r[2] * s[2]) / sn
    if along >= 0.0:
        return 1.0
    p0, p1, p2 = r[0] - along * s[0] / sn, r[1] - along * s[1] / sn, r[2] - along * s[2] / sn
    return 0.0 if p0 * p0 + p1 * p1 + p2 * p2 < body_radius * body_radius else 1.0


@njit(cache=True)
def shadow_factor(r, s, body_radius, sun_radius, model):
    if model == CYLINDRICAL:
        return cylindrical_shadow(r, s, body_radius)
    return conical_shadow(r, s, body_radius, sun_radius)


@njit(cache=True)
def _eclipse_outputs(t, x, z, u, p, y):
    y[Y.shadow_factor] = shadow_factor(u[U.position:U.position + 3], u[U.sun_position:U.sun_position + 3],
                                       p[P.body_radius], p[P.sun_radius], p[P.shadow_model])


@register_model
class Eclipse(Model):
    """Shadow of the central body at a node, conical (penumbra) or cylindrical; see the module docstring."""

    summary = "eclipse by the central body at a node: shadow_factor 1 lit .. 0 umbra (conical or cylindrical)"
    declarations = ECLIPSE
    feedthrough_outputs = staticmethod(_eclipse_outputs)

    def __init__(self, name: str, *, shadow: str = "conical", **kwargs):
        if shadow not in SHADOWS:
            raise ModelError(f"model {name}: config shadow: expected one of {sorted(SHADOWS)}, given {shadow!r}")
        if "shadow_model" in kwargs:
            raise ModelError(f"model {name}: parameter shadow_model is set by config shadow "
                             f"({' or '.join(sorted(SHADOWS))})")
        super().__init__(name, shadow_model=SHADOWS[shadow], **kwargs)
