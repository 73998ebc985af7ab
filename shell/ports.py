"""Ports that many models share, declared once: a node's kinematics in, loads on a node out.

The engine model (:mod:`shell.models.multibody`) gives every node the kinematic signals of
:data:`NODE_OUTPUTS` and takes the loads of :data:`NODE_INPUTS` (docs/conventions.md: quaternions scalar
first, node -> world; vectors in node axes unless said). A model attached to a node
(``attach: {node: acs}``) is wired by these names, so its ports must carry the same unit and shape: it
declares them with :func:`node_inputs` and :func:`node_load_outputs` (unit and shape from here, its own
description of what the port means to it, feedthrough as its kernels need), or takes a whole bundle
(Basilisk's message payloads, declared once and read by every module that uses them):

* :data:`MEASURED_ATTITUDE_AND_RATE`: ``attitude`` and ``angular_velocity`` in, as an attitude controller
  samples them;
* :data:`COMMANDED_TORQUE` out and :data:`HELD_TORQUE`, the discrete state a sampled controller holds it in;
* the attitude reference a guidance model gives a controller (Basilisk's attitude reference message):
  :func:`attitude_reference_outputs` and :func:`attitude_reference_inputs`.
"""

from __future__ import annotations

from shell.model import InputPort, OutputPort, State

#: node signal -> (unit, shape, description, feedthrough) of the engine's outputs per node
NODE_OUTPUTS = {
    "attitude": ("", (4,), "quaternion [w, x, y, z] rotating node axes into world axes", False),
    "rotation": ("", (3, 3), "rotation matrix node -> world", False),
    "position": ("m", (3,), "node origin in the world frame", False),
    "angular_velocity": ("rad/s", (3,), "inertial angular velocity, node axes", False),
    "linear_velocity": ("m/s", (3,), "inertial velocity of the node origin, node axes", False),
    "angular_acceleration": ("rad/s^2", (3,), "inertial angular acceleration, node axes", True),
    "linear_acceleration": ("m/s^2", (3,), "classical acceleration of the node origin, node axes", True),
}
#: node load -> (unit, shape, description) of the engine's inputs per node
NODE_INPUTS = {
    "torque": ("N*m", (3,), "external torque about the node origin, node axes"),
    "force": ("N", (3,), "external force at the node origin, node axes"),
}


def node_inputs(*names: str, feedthrough: bool = False, required: bool = True, **descriptions: str):
    """Input ports for the node signals ``names`` (unit and shape of :data:`NODE_OUTPUTS`), each described
    by ``descriptions[name]`` (default: the engine's description)."""
    return tuple(InputPort(name, NODE_OUTPUTS[name][0], NODE_OUTPUTS[name][1],
                           descriptions.get(name, NODE_OUTPUTS[name][2]), feedthrough=feedthrough, required=required)
                 for name in names)


def node_load_outputs(*names: str, feedthrough: bool = True, **descriptions: str):
    """Output ports for the node loads ``names`` (``torque``, ``force``: unit and shape of :data:`NODE_INPUTS`),
    each described by ``descriptions[name]`` (default: the engine's description)."""
    return tuple(OutputPort(name, NODE_INPUTS[name][0], NODE_INPUTS[name][1],
                            descriptions.get(name, NODE_INPUTS[name][2]), feedthrough=feedthrough)
                 for name in names)


def node_load_inputs(*names: str, **descriptions: str):
    """Inputs taking node loads (``torque``, ``force``), as a model summing several loads has: optional, zero
    when unconnected; each described by ``descriptions[name]`` (default: the engine's description)."""
    return tuple(InputPort(name, NODE_INPUTS[name][0], NODE_INPUTS[name][1],
                           descriptions.get(name, NODE_INPUTS[name][2]), feedthrough=True, required=False)
                 for name in names)


#: what a sampled attitude controller reads at each sample
MEASURED_ATTITUDE_AND_RATE = node_inputs("attitude", "angular_velocity",
                                         attitude="measured quaternion [w, x, y, z], node -> world",
                                         angular_velocity="measured angular velocity, node axes")
#: the torque command of a sampled attitude controller, and the discrete state that holds it between samples
COMMANDED_TORQUE = node_load_outputs("torque", feedthrough=False,
                                     torque="commanded torque, node axes (held between samples)")
HELD_TORQUE = State("torque", "N*m", (3,), None, "held torque command")

#: reference signal -> (unit, shape, description) of the attitude a controller tracks, its rate and acceleration
ATTITUDE_REFERENCE = {
    "reference_attitude": ("", (4,), "reference quaternion [w, x, y, z], reference -> world"),
    "reference_angular_velocity": ("rad/s", (3,), "reference angular velocity, world axes"),
    "reference_angular_acceleration": ("rad/s^2", (3,), "reference angular acceleration, world axes"),
}


def attitude_reference_outputs(feedthrough: bool = False):
    """The attitude-reference outputs of a guidance model."""
    return tuple(OutputPort(name, unit, shape, description, feedthrough=feedthrough)
                 for name, (unit, shape, description) in ATTITUDE_REFERENCE.items())


def attitude_reference_inputs(**descriptions: str):
    """The attitude-reference inputs of a controller, optional: unconnected, the reference is the identity
    attitude at rest."""
    return tuple(InputPort(name, unit, shape, descriptions.get(name, description), required=False,
                           default=(1.0, 0.0, 0.0, 0.0) if name == "reference_attitude" else None)
                 for name, (unit, shape, description) in ATTITUDE_REFERENCE.items())
