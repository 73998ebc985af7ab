"""Thruster cluster: nonnegative torque allocation over N thrusters summed into one node load.

The demanded torque T (node axes) becomes thrust commands ``c >= 0`` with ``A c = T``, A the 3 x N matrix
of the thrusters' torques per newton ``r_k x d_k`` (:class:`NonnegativeAllocator`); each member
``jet<k>`` is a :class:`Thruster` (pwm by default) at ``positions[k]`` from the node along
``directions[k]``, and ``loads`` adds their torques and forces. The default directions are the
16-thruster layout of TM-2020-5008164 eq. G.3.2 (two thrusters on each of eight bus panels); the
positions are the user's (the TM gives none). Torque-only allocation leaves a net force (the price of
push-only jets); give a balanced layout if the translation matters.

Exposed ports: input ``torque_command`` (3,) N m; outputs ``torque``, ``force`` (attach to the node).
"""

from __future__ import annotations

import numpy as np

from shell.assembly import Assembly
from shell.model import ModelError, Parameter
from shell.models.allocation import NodeLoadSum, NonnegativeAllocator
from shell.models.thruster import Thruster
from shell.registry import register_model

#: TM-2020-5008164 eq. G.3.2: force direction of each of the 16 thrusters (rows), body frame
TM_G32_DIRECTIONS = np.array([
    [-0.7071, 0.5, 0.5], [0.7071, -0.5, 0.5], [-0.1464, 0.5, 0.8536], [0.8536, -0.5, -0.1464],
    [0.5, 0.5, 0.7071], [0.5, -0.5, -0.7071], [0.8536, 0.5, 0.1464], [-0.1464, -0.5, -0.8536],
    [0.7071, 0.5, -0.5], [-0.7071, -0.5, -0.5], [0.1464, 0.5, -0.8536], [-0.8536, -0.5, 0.1464],
    [-0.5, 0.5, -0.7071], [-0.5, -0.5, 0.7071], [-0.8536, 0.5, -0.1464], [0.1464, -0.5, 0.8536]])


@register_model
class ThrusterCluster(Assembly):
    """N thrusters with nonnegative torque allocation (config: thrusters = 16, mode = pwm, period)."""

    summary = "thruster cluster: torque command -> nonnegative allocation -> N jets -> one node load"

    def __init__(self, name: str, *, thrusters: int = 16, mode: str = "pwm", period="0.1 s", **parameter_values):
        self.n_thrusters = int(thrusters)
        self.mode, self.cycle = mode, period
        default_directions = TM_G32_DIRECTIONS if self.n_thrusters == 16 else None
        self.parameters = (
            Parameter("directions", "", default_directions, (self.n_thrusters, 3), (-1.0, 1.0),
                      "unit force direction of each thruster, node axes (default TM eq. G.3.2)"),
            Parameter("positions", "m", None, (self.n_thrusters, 3), None, "each thruster's position from the node"),
            Parameter("max_thrust", "N", None, (), (0.0, None), "each thruster's thrust"),
            Parameter("isp", "s", None, (), (1e-9, None), "specific impulse"),
            Parameter("min_on_time", "s", 0.0, (), (0.0, None), "minimum valve opening"),
        )
        super().__init__(name, **parameter_values)

    def build(self):
        directions = np.array(self.parameter("directions"), float)
        norms = np.linalg.norm(directions, axis=1)
        if np.any(np.abs(norms - 1.0) > 1e-3):
            raise ModelError(f"assembly {self.path}: parameter directions: rows must be unit vectors, norms "
                             f"{norms.round(6).tolist()}")
        directions = directions / norms[:, None]
        positions = np.array(self.parameter("positions"), float)
        effectiveness = np.cross(positions, directions).T
        self.add(NonnegativeAllocator("allocator", demand=3, actuators=self.n_thrusters, demand_unit="N*m",
                                      command_unit="N", period=self.cycle,
                                      **self.child_parameters("allocator", effectiveness=effectiveness)))
        self.add(NodeLoadSum("loads", count=self.n_thrusters))
        self.expose_input("torque_command", "allocator.demand")
        self.expose_output("torque", "loads.torque")
        self.expose_output("force", "loads.force")
        shared = {key: float(self.parameter(key)) for key in ("max_thrust", "isp", "min_on_time")}
        for k in range(self.n_thrusters):
            name = f"jet{k + 1}"
            self.add(Thruster(name, mode=self.mode, period=self.cycle,
                              **self.child_parameters(name, direction=directions[k], position=positions[k], **shared)))
            self.connect(f"allocator.command_{k + 1}", f"{name}.command")
            self.connect(f"{name}.torque", f"loads.torque_{k}")
            self.connect(f"{name}.force", f"loads.force_{k}")
