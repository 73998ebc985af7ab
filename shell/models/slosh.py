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

Array layout: every declaration has the shape (n,) of the hinge's degrees of freedom (config), so the
offsets are multiples of n: with ``P`` and ``U`` the named offsets of the declarations at shape ()
(module level), declaration ``k`` starts at ``n * k`` and the kernel reads ``p[n * P.damping + i]``.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from shell.model import Declarations, InputPort, Model, ModelError, OutputPort, Parameter, count_option
from shell.registry import register_model

#: unit of each declaration by kind of hinge
UNITS = {"rotational": {"q": "rad", "u": "rad/s", "torque": "N*m", "stiffness": "N*m/rad", "damping": "N*m*s/rad",
                        "neutral": "rad"},
         "translational": {"q": "m", "u": "m/s", "torque": "N", "stiffness": "N/m", "damping": "N*s/m",
                           "neutral": "m"}}

#: declarations per degree of freedom (units and shapes are set per instance from config: kind, dofs)
PARAMETERS = (
    Parameter("stiffness", "", 0.0, (), (0.0, None), "spring per DOF (0 for a pendulum)"),
    Parameter("damping", "", 0.0, (), (0.0, None), "damper per DOF"),
    Parameter("neutral", "", 0.0, (), None, "unstretched position q_0"),
)
INPUTS = (InputPort("q", "", (), "hinge coordinates", feedthrough=True),
          InputPort("u", "", (), "hinge rates", feedthrough=True))
OUTPUTS = (OutputPort("torque", "", (), "generalized force on the hinge", feedthrough=True),)
SLOSH = Declarations(parameters=PARAMETERS, inputs=INPUTS, outputs=OUTPUTS)
P, U, Y = SLOSH.P, SLOSH.U, SLOSH.Y


def _scaled(offsets, n: int):
    """Offsets of declarations of shape (n,) each: n times those of the scalar declarations."""
    return type(offsets)(*(n * k for k in offsets))


@njit(cache=True)
def _spring_damper(t, x, z, u, p, y):
    n = y.shape[0]
    for i in range(n):
        y[n * Y.torque + i] = (-p[n * P.stiffness + i] * (u[n * U.q + i] - p[n * P.neutral + i])
                               - p[n * P.damping + i] * u[n * U.u + i])


@register_model
class SloshSpringDamper(Model):
    """tau = -k (q - q0) - c q_dot on a slosh body's hinge (config: dofs, kind)."""

    summary = "slosh pendulum / spring-mass hinge spring and damper (config: dofs, kind; attach: {hinge: ...})"
    declarations = SLOSH
    feedthrough_outputs = staticmethod(_spring_damper)

    def __init__(self, name: str, *, dofs: int = 2, kind: str = "rotational", **kwargs):
        if kind not in UNITS:
            raise ModelError(f"model {name}: config kind: expected one of {sorted(UNITS)}, given {kind!r}")
        self.dofs, self.kind = count_option(name, "dofs", dofs, "hinge degrees of freedom", 3), kind
        super().__init__(name, **kwargs)

    def declare(self):
        n, units = self.dofs, UNITS[self.kind]
        parameters = {d.name for d in PARAMETERS}
        self.use_declarations(SLOSH.replace(**{name: {"unit": unit, "shape": (n,)} | (
            {"default": np.zeros(n)} if name in parameters else {}) for name, unit in units.items()}))
        self.offsets = {key: _scaled(offsets, n) for key, offsets in SLOSH.offsets.items()}
