"""Third-body gravity of the Sun and the Moon on a body in orbit about the Earth (point masses).

Attach to a node at the body's center of mass (``attach: {node: ...}``: position from the Earth's
center and rotation node -> world) and wire ``SunMoonEphemeris.sun_position`` and ``moon_position``
(world axes, from the Earth's center; an unconnected input, the zero vector, switches that body off).
The acceleration relative to the Earth (Montenbruck & Gill, "Satellite Orbits", eq. 3.37)::

    a = mu_b [ (s - r) / |s - r|^3 - s / |s|^3 ]        for each body b at s

(the second term is the Earth's own acceleration toward the body: the frame is Earth-centred). The two
terms nearly cancel near the Earth (their difference is ``O(|r|/|s|)`` of each): in double precision that
costs about ``log10(|s|/|r|)`` digits, 4 of 16 for the Sun and 2 for the Moon, so the direct form is kept
(tests/models/test_third_body.py measures it against a 50-digit evaluation). Outputs: ``force = m R^T a``
(node axes) and
``gravitational_acceleration`` (node axes).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from shell.model import Declarations, InputPort, Model, OutputPort, Parameter
from shell.ports import node_inputs, node_load_outputs
from shell.registry import register_model

SUN_MU = 1.32712440018e20   # m^3/s^2, DE405/DE440 (IERS Conventions 2010, Table 1.1)
MOON_MU = 4.9028000661e12   # m^3/s^2, DE440 (GM_Earth / 81.30056907)

PARAMETERS = (
    Parameter("mass", "kg", None, (), (0.0, None), "mass of the body"),
    Parameter("sun_mu", "m^3/s^2", SUN_MU, (), (0.0, None), "gravitational parameter of the Sun"),
    Parameter("moon_mu", "m^3/s^2", MOON_MU, (), (0.0, None), "gravitational parameter of the Moon"),
)
INPUTS = (
    *node_inputs("position", "rotation", feedthrough=True,
                 position="node (center of mass) from the Earth's center, world", rotation="rotation node -> world"),
    InputPort("sun_position", "m", (3,), "Earth -> Sun, world (zero: no Sun)", feedthrough=True, required=False),
    InputPort("moon_position", "m", (3,), "Earth -> Moon, world (zero: no Moon)", feedthrough=True,
              required=False),
)
OUTPUTS = (
    *node_load_outputs("force", force="third-body force, node axes"),
    OutputPort("gravitational_acceleration", "m/s^2", (3,), "third-body acceleration, node axes",
               feedthrough=True),
)
THIRD_BODY = Declarations(parameters=PARAMETERS, inputs=INPUTS, outputs=OUTPUTS)
P, U, Y = THIRD_BODY.P, THIRD_BODY.U, THIRD_BODY.Y


@njit(cache=True)
def third_body_acceleration(r0, r1, r2, s0, s1, s2, mu):
    """``mu [(s - r)/|s - r|^3 - s/|s|^3]`` (M&G eq. 3.37); zero for s = 0."""
    sn2 = s0 * s0 + s1 * s1 + s2 * s2
    if sn2 == 0.0:
        return 0.0, 0.0, 0.0
    d0, d1, d2 = s0 - r0, s1 - r1, s2 - r2
    dn = np.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
    sn = np.sqrt(sn2)
    kd, ks = mu / (dn * dn * dn), mu / (sn2 * sn)
    return kd * d0 - ks * s0, kd * d1 - ks * s1, kd * d2 - ks * s2


@njit(cache=True)
def _third_body_outputs(t, x, z, u, p, y):
    r, s, m, rot = U.position, U.sun_position, U.moon_position, U.rotation
    a0, a1, a2 = third_body_acceleration(u[r], u[r + 1], u[r + 2], u[s], u[s + 1], u[s + 2], p[P.sun_mu])
    b0, b1, b2 = third_body_acceleration(u[r], u[r + 1], u[r + 2], u[m], u[m + 1], u[m + 2], p[P.moon_mu])
    w0, w1, w2 = a0 + b0, a1 + b1, a2 + b2
    for i in range(3):
        acceleration = u[rot + i] * w0 + u[rot + 3 + i] * w1 + u[rot + 6 + i] * w2  # R^T a
        y[Y.gravitational_acceleration + i] = acceleration
        y[Y.force + i] = p[P.mass] * acceleration


@register_model
class ThirdBodyGravity(Model):
    """Sun and Moon point-mass perturbations relative to the Earth at a center-of-mass node."""

    summary = "third-body (Sun, Moon) gravity at a center-of-mass node, Earth-centred (M&G eq. 3.37)"
    declarations = THIRD_BODY
    feedthrough_outputs = staticmethod(_third_body_outputs)
