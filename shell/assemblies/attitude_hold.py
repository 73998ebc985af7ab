"""Sampled attitude-hold loop: rate-gyro sampler with noise feeding a PD attitude controller.

A reusable assembly (TM-2020-5008164 App. D.1 hierarchical assemblies) that a scenario attaches to an
engine node: it exposes the node-signal names ``attitude`` and ``angular_velocity`` as inputs and
``torque`` as output, so ``attach: {node: acs}`` wires it. Inside, ``gyro`` (a NoisySampler at the
loop period, white noise ``gyro_noise`` 1-sigma per sample) measures the angular velocity and
``controller`` (PdAttitudeController at the same period) holds the torque command; at each sample the
gyro updates before the controller (dataflow order), so the command uses the fresh measurement.
Controller gains and commands are set as ``controller.kp`` etc. on the assembly.
"""

from __future__ import annotations

from shell.assembly import Assembly
from shell.model import Parameter
from shell.models.blocks import NoisySampler
from shell.models.pd_attitude import PdAttitudeController
from shell.registry import register_model


@register_model
class AttitudeHoldLoop(Assembly):
    """Gyro sampler + sampled PD controller; inputs attitude, angular_velocity; output torque."""

    summary = "noisy rate gyro + sampled PD attitude controller (attach to a node)"
    parameters = (
        Parameter("period", "s", 0.1, (), (0.0, None), "sample period of gyro and controller"),
        Parameter("gyro_noise", "rad/s", 0.0, (), (0.0, None), "gyro white noise, 1 sigma per sample"),
    )

    def build(self):
        period = float(self.parameter("period"))
        self.add(NoisySampler("gyro", unit="rad/s", shape=(3,), period=period,
                              **self.child_parameters("gyro", sigma=float(self.parameter("gyro_noise")))))
        self.add(PdAttitudeController("controller", period=period, **self.child_parameters("controller")))
        self.connect("gyro.y", "controller.angular_velocity")
        self.expose_input("attitude", "controller.attitude")
        self.expose_input("angular_velocity", "gyro.u")
        self.expose_output("torque", "controller.torque")
