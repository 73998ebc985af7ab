"""Propellant slosh equivalents: spring and damper on the hinge of a slosh mass in the engine.

The mechanical-equivalent slosh models (Abramson, "The Dynamic Behavior of Liquids in Moving
Containers", NASA SP-106, ch. 6; Dodge, "The New Dynamic Behavior of Liquids in Moving Containers",
2000) represent the sloshing part of the liquid by a mass on a pendulum or on a spring, attached at a
tank node. In flexshell the mass is a body of the engine, so its coupling with the vehicle, its
flexible structure and the vehicle's acceleration is exact:

* pendulum: a body of mass m_s with its center of mass at distance L below a U-joint (two swing axes)
  at the tank node; under the axial acceleration a it swings at ``omega = sqrt(a / L)``;
* spring-mass: a body on a prismatic hinge (one per lateral direction) with stiffness k:
  ``omega = sqrt(k / m_s)``.

``SloshSpringDamper`` closes the hinge with the generalized
force ``tau = -k (q - q_0) - c q_dot`` per degree of freedom (config ``dofs``: 1 for a prismatic or
revolute hinge, 2 for a U-joint; ``kind``: ``rotational`` gains in N m/rad, ``translational`` in N/m).
A pendulum needs only damping (k = 0); the damping ``c = 2 zeta m_s L^2 omega`` (pendulum) or
``2 zeta sqrt(k m_s)`` (spring) gives the liquid's damping ratio zeta. Attach it to the slosh body's
hinge: ``attach: {hinge: <slosh body>}``.

Parameters from a tank's fill level (upright cylinder): :func:`dynamics.slosh_tank.cylindrical_tank_slosh`
or ``flexshell slosh``, which prints the pendulum bodies and these dampers as scenario YAML.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from shell.model import InputPort, Model, ModelError, OutputPort, Parameter
from shell.registry import register_model

UNITS = {"rotational": ("rad", "rad/s", "N*m", "N*m/rad", "N*m*s/rad"),
         "translational": ("m", "m/s", "N", "N/m", "N*s/m")}


@njit(cache=True)
def _spring_damper(t, x, z, u, p, y):
    # u = [q (n), u (n)]; p = [k (n), c (n), q0 (n)]
    n = y.shape[0]
    for i in range(n):
        y[i] = -p[i] * (u[i] - p[2 * n + i]) - p[n + i] * u[n + i]


@register_model
class SloshSpringDamper(Model):
    """tau = -k (q - q0) - c q_dot on a slosh body's hinge (config: dofs, kind)."""

    summary = "slosh pendulum / spring-mass hinge spring and damper (config: dofs, kind; attach: {hinge: ...})"
    feedthrough_outputs = staticmethod(_spring_damper)

    def __init__(self, name: str, *, dofs: int = 2, kind: str = "rotational", **kwargs):
        if kind not in UNITS:
            raise ModelError(f"model {name}: config kind: expected one of {sorted(UNITS)}, given {kind!r}")
        self.dofs, self.kind = int(dofs), kind
        super().__init__(name, **kwargs)

    def declare(self):
        n = self.dofs
        uq, uu, uf, uk, uc = UNITS[self.kind]
        self.parameters = (
            Parameter("stiffness", uk, np.zeros(n), (n,), (0.0, None), "spring per DOF (0 for a pendulum)"),
            Parameter("damping", uc, np.zeros(n), (n,), (0.0, None), "damper per DOF"),
            Parameter("neutral", uq, np.zeros(n), (n,), None, "unstretched position q_0"),
        )
        self.inputs = (InputPort("q", uq, (n,), "hinge coordinates", feedthrough=True),
                       InputPort("u", uu, (n,), "hinge rates", feedthrough=True))
        self.outputs = (OutputPort("torque", uf, (n,), "generalized force on the hinge", feedthrough=True),)
