"""Central-body gravity with zonal harmonics (J2, J3, J4) and the gravity-gradient torque at a node.

Attach to a node at the body's center of mass (``attach: {node: ...}``): the model reads the node's
world position and rotation and applies, in node axes,

* the point-mass + J2 acceleration (Vallado, "Fundamentals of Astrodynamics", 4th ed., eq. 8-30; pole
  along world z, body-fixed rotation of the planet ignored since zonal terms are axisymmetric), with
  optional J3 and J4 terms (same source; parameters ``j3``, ``j4``, default 0)::

      g = -mu r / |r|^3 - 3/2 J2 mu R^2 / |r|^5 [ (1 - 5 z^2/|r|^2) x, (1 - 5 z^2/|r|^2) y,
                                                   (3 - 5 z^2/|r|^2) z ]

  as the force ``m g`` (``mass`` parameter: the body's mass);
* the gravity-gradient torque about the center of mass (Wie sec. 6.2; Hughes, "Spacecraft Attitude
  Dynamics", ch. 8), with ``J`` the body's inertia about its center of mass in node axes::

      T = 3 mu / |r|^3  r_hat x (J r_hat),     r_hat the unit position vector in node axes

  (``gravity_gradient: 0`` switches the torque off: the fidelity switch for a scene that needs only the
  orbit);
* ``gravitational_acceleration`` (node axes) for an :class:`shell.models.imu.Imu` on the same body,
  which must not sense gravity.

A uniform field needs no model: the engine applies ``multibody: gravity:`` to every body exactly.
One model per body whose orbit or gravity-gradient torque matters.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from shell.model import Declarations, Model, OutputPort, Parameter
from shell.ports import node_inputs, node_load_outputs
from shell.registry import register_model

EARTH_MU = 3.986004418e14        # m^3/s^2, WGS 84 / EGM 2008
EARTH_RADIUS = 6378137.0         # m, WGS 84 equatorial
EARTH_J2 = 1.08262668e-3         # EGM 2008 (unnormalized)
EARTH_J3 = -2.53265649e-6        # EGM 2008 (unnormalized)
EARTH_J4 = -1.61962159e-6        # EGM 2008 (unnormalized)


@njit(cache=True)
def central_body_acceleration(r, mu, radius, j2, out, j3=0.0, j4=0.0):
    """Point-mass + zonal (J2, J3, J4) gravitational acceleration at world position r (world axes)."""
    r2 = r[0] * r[0] + r[1] * r[1] + r[2] * r[2]
    rn = np.sqrt(r2)
    k = -mu / (r2 * rn)
    zz = r[2] * r[2] / r2
    c = -1.5 * j2 * mu * radius * radius / (r2 * r2 * rn)
    ax = k * r[0] + c * (1.0 - 5.0 * zz) * r[0]
    ay = k * r[1] + c * (1.0 - 5.0 * zz) * r[1]
    az = k * r[2] + c * (3.0 - 5.0 * zz) * r[2]
    if j3 != 0.0:
        r7 = r2 * r2 * r2 * rn
        c3 = -2.5 * j3 * mu * radius ** 3 / r7
        horizontal = c3 * (3.0 * r[2] - 7.0 * r[2] * zz)
        ax += horizontal * r[0]
        ay += horizontal * r[1]
        az += c3 * (6.0 * r[2] * r[2] - 7.0 * r[2] * r[2] * zz - 0.6 * r2)
    if j4 != 0.0:
        r7 = r2 * r2 * r2 * rn
        c4 = 1.875 * j4 * mu * radius ** 4 / r7
        horizontal = c4 * (1.0 - 14.0 * zz + 21.0 * zz * zz)
        ax += horizontal * r[0]
        ay += horizontal * r[1]
        az += c4 * (5.0 - 70.0 / 3.0 * zz + 21.0 * zz * zz) * r[2]
    out[0] = ax
    out[1] = ay
    out[2] = az


@njit(cache=True)
def gravity_gradient_torque(r_node, inertia, mu, out):
    """3 mu / |r|^3 r_hat x (J r_hat); r_node from the planet center, node axes; inertia (9,) row-major.
    Reads r_node completely before writing out (they may be the same array)."""
    rn = np.sqrt(r_node[0] ** 2 + r_node[1] ** 2 + r_node[2] ** 2)
    x, y, z = r_node[0] / rn, r_node[1] / rn, r_node[2] / rn
    j0 = inertia[0] * x + inertia[1] * y + inertia[2] * z
    j1 = inertia[3] * x + inertia[4] * y + inertia[5] * z
    j2 = inertia[6] * x + inertia[7] * y + inertia[8] * z
    k = 3.0 * mu / (rn * rn * rn)
    out[0] = k * (y * j2 - z * j1)
    out[1] = k * (z * j0 - x * j2)
    out[2] = k * (x * j1 - y * j0)


PARAMETERS = (
    Parameter("mu", "m^3/s^2", EARTH_MU, (), (0.0, None), "gravitational parameter (default Earth)"),
    Parameter("radius", "m", EARTH_RADIUS, (), (0.0, None), "reference radius of J2"),
    Parameter("j2", "", EARTH_J2, (), None, "second zonal harmonic (0: point mass)"),
    Parameter("mass", "kg", None, (), (0.0, None), "mass of the body"),
    Parameter("inertia", "kg*m^2", np.zeros((3, 3)), (3, 3), None,
              "inertia about the center of mass in node axes (gravity-gradient torque)"),
    Parameter("gravity_gradient", "", 1.0, (), (0.0, 1.0), "1: apply the gravity-gradient torque, 0: not"),
    Parameter("j3", "", 0.0, (), None, f"third zonal harmonic (Earth {EARTH_J3:g})"),
    Parameter("j4", "", 0.0, (), None, f"fourth zonal harmonic (Earth {EARTH_J4:g})"),
)
INPUTS = node_inputs("position", "rotation", feedthrough=True,
                     position="node origin (the center of mass) from the planet center, world",
                     rotation="rotation node -> world")
OUTPUTS = (
    *node_load_outputs("force", "torque", force="gravitational force, node axes",
                       torque="gravity-gradient torque about the node, node axes"),
    OutputPort("gravitational_acceleration", "m/s^2", (3,), "gravitational acceleration, node axes",
               feedthrough=True),
)
GRAVITY = Declarations(parameters=PARAMETERS, inputs=INPUTS, outputs=OUTPUTS)
P, U, Y = GRAVITY.P, GRAVITY.U, GRAVITY.Y


@njit(cache=True)
def _gravity_outputs(t, x, z, u, p, y):
    # the force block holds g in world axes and the torque block the position in node axes until
    # they are overwritten (no scratch arrays)
    r, rotation = U.position, U.rotation
    g, torque, acceleration = Y.force, Y.torque, Y.gravitational_acceleration
    central_body_acceleration(u[r:r + 3], p[P.mu], p[P.radius], p[P.j2], y[g:g + 3], p[P.j3], p[P.j4])
    for i in range(3):
        c0, c1, c2 = rotation + i, rotation + 3 + i, rotation + 6 + i  # column i of R (row-major)
        y[acceleration + i] = u[c0] * y[g] + u[c1] * y[g + 1] + u[c2] * y[g + 2]       # R^T g
        y[torque + i] = u[c0] * u[r] + u[c1] * u[r + 1] + u[c2] * u[r + 2]             # R^T r
    for i in range(3):
        y[Y.force + i] = p[P.mass] * y[acceleration + i]
    if p[P.gravity_gradient] != 0.0:
        gravity_gradient_torque(y[torque:torque + 3], p[P.inertia:P.inertia + 9], p[P.mu], y[torque:torque + 3])
    else:
        for i in range(3):
            y[torque + i] = 0.0


@register_model
class CentralBodyGravity(Model):
    """Point-mass + J2 gravity force and gravity-gradient torque at a body's center-of-mass node."""

    summary = "central-body gravity (mu, J2) force and gravity-gradient torque at a center-of-mass node"
    declarations = GRAVITY
    feedthrough_outputs = staticmethod(_gravity_outputs)
