"""Reaction-wheel cluster: pseudo-inverse torque allocation, N wheels, one summed load at a node.

The demanded body torque T (node axes) is split into wheel motor torques ``tau = -pinv(A) T`` with A the
3 x N matrix of spin axes (TM-2020-5008164 eq. G.3.1 for the default four-wheel pyramid: x, y, z and
(1, 1, 1)/sqrt(3)); the minus sign because a wheel's motor torque acts on the bus as ``-tau a``. Each
member ``rw<k>`` is a :class:`ReactionWheel` (parameters as ``rw<k>.<name>`` or for all wheels at once
through the cluster parameters below), and ``loads`` adds their torques and forces.

Exposed ports: inputs ``torque_command`` (3,) N m, ``angular_velocity`` (node, fans out to every
wheel); outputs ``torque``, ``force`` (attach the cluster to the node), ``wheel_speed_<k>``.
"""

from __future__ import annotations

import numpy as np

from shell.assembly import Assembly
from shell.model import ModelError, Parameter
from shell.models.allocation import NodeLoadSum, PseudoInverseAllocator
from shell.models.reaction_wheel import ReactionWheel
from shell.registry import register_model

#: TM-2020-5008164 eq. G.3.1: wheel momentum directions (columns) in the body frame
PYRAMID_AXES = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [1.0, 1.0, 1.0] / np.sqrt(3.0)])


@register_model
class WheelCluster(Assembly):
    """N reaction wheels with pseudo-inverse allocation (config: wheels, default 4 = TM eq. G.3.1)."""

    summary = "reaction-wheel cluster: torque command -> pinv allocation -> N wheels -> one node load"

    def __init__(self, name: str, *, wheels: int = 4, **parameter_values):
        self.n_wheels = int(wheels)
        default_axes = PYRAMID_AXES if self.n_wheels == 4 else None
        self.parameters = (
            Parameter("spin_axes", "", default_axes, (self.n_wheels, 3), (-1.0, 1.0),
                      "unit spin axis of each wheel, node axes (default TM eq. G.3.1)"),
            Parameter("spin_inertia", "kg*m^2", None, (), (1e-12, None), "each wheel's spin inertia"),
            Parameter("max_torque", "N*m", 0.2, (), (0.0, None), "each wheel's motor torque limit"),
            Parameter("max_speed", "rad/s", 6000 * np.pi / 30, (), (0.0, None), "each wheel's speed limit"),
        )
        super().__init__(name, **parameter_values)

    def build(self):
        axes = np.array(self.parameter("spin_axes"), float)
        norms = np.linalg.norm(axes, axis=1)
        if np.any(np.abs(norms - 1.0) > 1e-3):
            raise ModelError(f"assembly {self.path}: parameter spin_axes: rows must be unit vectors, norms "
                             f"{norms.round(6).tolist()}")
        axes = axes / norms[:, None]
        self.add(PseudoInverseAllocator("allocator", demand=3, actuators=self.n_wheels,
                                        **self.child_parameters("allocator", effectiveness=-axes.T)))
        self.add(NodeLoadSum("loads", count=self.n_wheels))
        self.expose_input("torque_command", "allocator.demand")
        self.expose_output("torque", "loads.torque")
        self.expose_output("force", "loads.force")
        angular_velocity = []
        for k in range(self.n_wheels):
            name = f"rw{k + 1}"
            shared = {key: float(self.parameter(key)) for key in ("spin_inertia", "max_torque", "max_speed")}
            self.add(ReactionWheel(name, **self.child_parameters(name, spin_axis=axes[k], **shared)))
            self.connect(f"allocator.command_{k + 1}", f"{name}.torque_command")
            self.connect(f"{name}.torque", f"loads.torque_{k}")
            self.connect(f"{name}.force", f"loads.force_{k}")
            self.expose_output(f"wheel_speed_{k + 1}", f"{name}.wheel_speed")
            angular_velocity.append(f"{name}.angular_velocity")
        self.expose_input("angular_velocity", *angular_velocity)
