"""Bad input is refused with a message naming the offending body, node, joint or link."""

from __future__ import annotations

import numpy as np
import pytest

from dynamics import ModelDefinitionError, Multibody, SingularConfigurationError
from dynamics.urdf import UrdfError

GOOD = dict(mass=1.0, inertia=[0.1, 0.2, 0.25], hinge="revolute", axis=(0, 0, 1))


def builder():
    mb = Multibody()
    mb.add_body("base", None, **GOOD)
    return mb


@pytest.mark.parametrize("kwargs, fragments", [
    (dict(parent="bsae"), ["arm", "unknown parent 'bsae'", "Did you mean 'base'"]),
    (dict(mass=0.0), ["arm", "mass must be positive", "0.0"]),
    (dict(mass=-2.0), ["arm", "mass must be positive"]),
    (dict(mass=float("nan")), ["arm", "mass"]),
    (dict(inertia=[[1, 0, 0], [0, -1, 0], [0, 0, 1]]), ["arm", "positive semi-definite", "principal moments"]),
    (dict(inertia=[[1, 0.5, 0], [0, 1, 0], [0, 0, 1]]), ["arm", "not symmetric"]),
    (dict(inertia=[1, 2]), ["arm", "inertia", "3x3"]),
    (dict(axis=(0, 0, 2)), ["arm", "not a unit vector", "norm 2"]),
    (dict(hinge="hinge"), ["arm", "unknown hinge type 'hinge'"]),
    (dict(hinge="ujoint", axis=None, axes=[(1, 0, 0), (1, 0, 0)]), ["arm", "parallel"]),
    (dict(hinge="spherical"), ["arm", "takes no axis"]),
    (dict(prescribed=[True, False]), ["arm", "one flag per hinge DOF"]),
    (dict(inboard_rotation=np.diag([1.0, 1.0, -1.0])), ["arm", "inboard_rotation", "proper rotation"]),
    (dict(outboard_rotation=[1.0, 0.0, 0.0, 0.1]), ["arm", "outboard_rotation", "quaternion", "norm"]),
    (dict(com=(0, 0)), ["arm", "center of mass", "3"]),
])
def test_bad_body_definitions_are_refused_with_the_body_named(kwargs, fragments):
    mb = builder()
    args = dict(GOOD, parent="base")
    args.update(kwargs)
    parent = args.pop("parent")
    with pytest.raises(ModelDefinitionError) as info:
        mb.add_body("arm", parent, **args)
    for fragment in fragments:
        assert fragment in str(info.value), str(info.value)


def test_duplicate_names_are_refused():
    mb = builder()
    with pytest.raises(ModelDefinitionError, match="body 'base': duplicate body name"):
        mb.add_body("base", None, **GOOD)
    mb.add_node("sensor", "base")
    with pytest.raises(ModelDefinitionError, match="node 'sensor': duplicate node name"):
        mb.add_node("sensor", "base")
    with pytest.raises(ModelDefinitionError, match="node 'imu': unknown body 'bsae'"):
        mb.add_node("imu", "bsae")


def test_triangle_inequality_violation_is_refused():
    """Warned until issue 34, refused since: no mass distribution has such moments (shell/diagnostics.py)."""
    mb = Multibody()
    with pytest.raises(ModelDefinitionError, match="body 'rod'.*triangle inequality"):
        mb.add_body("rod", None, mass=1.0, inertia=[0.1, 0.1, 1.0], hinge="revolute", axis=(1, 0, 0))
    mb.add_body("disk", None, mass=1.0, inertia=[0.5, 0.5, 1.0], hinge="revolute", axis=(1, 0, 0))  # equality
    with pytest.raises(ModelDefinitionError, match="parent must be a body name"):
        mb.add_body("wheel", ["disk"], mass=1.0, inertia=[1, 1, 1], hinge="locked")
    with pytest.raises(ModelDefinitionError, match="unknown hinge type"):
        mb.add_body("wheel", None, mass=1.0, inertia=[1, 1, 1], hinge={"type": "locked"})
    with pytest.raises(ModelDefinitionError, match="unknown body"):
        mb.add_node("n", {"body": "disk"})


def test_wrong_state_shapes_are_refused():
    system = builder().compile()
    with pytest.raises(ValueError, match=r"q: expected shape \(1,\)"):
        system.forward_dynamics(np.zeros(3), np.zeros(1))
    with pytest.raises(ValueError, match="node_forces"):
        system.forward_dynamics(np.zeros(1), np.zeros(1), node_forces=np.zeros((2, 6)))


def test_singular_articulated_inertia_is_reported_with_the_hinge_named():
    """Validated bodies always give a positive definite articulated inertia; a body whose inertia about
    the hinge axis is negligible against its mass (1e-300 kg m^2 with 1 kg on the axis) is numerically
    singular and must be reported, not answered with 1e300 rad/s^2."""
    mb = Multibody()
    mb.add_body("tiny", None, mass=1.0, inertia=np.diag([1e-300, 1e-300, 1e-300]), hinge="revolute",
                axis=(0, 0, 1))
    system = mb.compile()
    with pytest.raises(SingularConfigurationError, match="hinge 'tiny'"):
        system.forward_dynamics(np.zeros(1), np.zeros(1), np.ones(1))


LINK = '<link name="{0}"><inertial><mass value="1"/><inertia ixx="0.1" ixy="0" ixz="0" iyy="0.1" iyz="0" izz="0.1"/></inertial></link>'


@pytest.mark.parametrize("body, fragments", [
    ("<robot name='r'><link name='a'>", ["malformed XML", "line"]),
    ("<model/>", ["<model>", "expected <robot>"]),
    (LINK.format("a") + LINK.format("b") + "<joint name='j' type='planar'><parent link='a'/><child link='b'/></joint>",
     ["joint 'j'", "'planar' is not supported"]),
    (LINK.format("a") + "<joint name='j' type='revolute'><parent link='a'/><child link='ghost'/></joint>",
     ["joint 'j'", "child link 'ghost' is not defined"]),
    (LINK.format("a") + LINK.format("b") + "<joint name='j' type='revolute'><parent link='a'/><child link='b'/>"
     "<axis xyz='0 0 3'/></joint>", ["joint 'j'", "not a unit vector"]),
    (LINK.format("a") + "<link name='b'/><joint name='j' type='revolute'><parent link='a'/><child link='b'/>"
     "</joint>", ["link 'b'", "joint 'j'", "no mass"]),
    (LINK.format("a") + "<link name='b'><inertial><mass value='1'/></inertial></link>"
     "<joint name='j' type='revolute'><parent link='a'/><child link='b'/></joint>", ["link 'b'", "no <inertia>"]),
    (LINK.format("a") + "<link name='b'><inertial><mass value='abc'/><inertia ixx='1' ixy='0' ixz='0' iyy='1' "
     "iyz='0' izz='1'/></inertial></link><joint name='j' type='revolute'><parent link='a'/><child link='b'/>"
     "</joint>", ["link 'b'", "<mass value>", "abc"]),
    (LINK.format("a") + LINK.format("b"), ["exactly one root link"]),
    (LINK.format("a") + LINK.format("b") + "<joint name='j' type='fixed'><parent link='a'/><child link='b'/></joint>",
     ["no movable joint"]),
])
def test_malformed_urdf_is_refused_with_the_item_named(tmp_path, body, fragments):
    path = tmp_path / "bad.urdf"
    text = body if body.startswith("<robot") or body.startswith("<model") else f"<robot name='r'>{body}</robot>"
    path.write_text(text)
    with pytest.raises(UrdfError) as info:
        Multibody.from_urdf(path)
    for fragment in fragments:
        assert fragment in str(info.value), str(info.value)


def test_urdf_missing_file_is_reported(tmp_path):
    with pytest.raises(UrdfError, match="cannot read"):
        Multibody.from_urdf(tmp_path / "nope.urdf")


def test_missing_rotary_inertia_is_accepted_where_the_hinge_never_needs_it():
    """A point mass or a line of point masses (a lumped-mass FE deck) has no rotary inertia about some axis:
    accepted on hinges that do not turn the body about it, with the right dynamics; refused, naming the axis
    and the fix, where they do (always on a free hinge)."""
    from dynamics import Multibody

    line = np.diag([0.0, 1.0, 1.0])  # no inertia about body x
    for hinge, kwargs in (("prismatic", dict(axis=(1, 0, 0))), ("locked", {}),
                          ("revolute", dict(axis=(0, 0, 1), prescribed=True))):
        mb = builder()
        mb.add_body("arm", "base", mass=2.0, inertia=np.zeros(3), hinge=hinge, **kwargs)  # point mass
        mb.compile()
    # turning about z through the hinge point at 0.5 m from the center of mass: J_z + m d^2
    mb = Multibody()
    mb.add_body("arm", None, mass=2.0, inertia=line, com=(0.5, 0.0, 0.0), hinge="revolute", axis=(0, 0, 1))
    system = mb.compile()
    udot = system.forward_dynamics(system.neutral_configuration(), np.zeros(1), tau=np.array([3.0]))
    np.testing.assert_allclose(udot, [3.0 / (1.0 + 2.0 * 0.25)], rtol=1e-15)
    for hinge, kwargs, fragment in (
            ("revolute", dict(axis=(1, 0, 0), com=(0.5, 0.0, 0.0)), "revolute hinge turns it about an axis"),
            ("free", {}, "free hinge turns the body about its center of mass")):
        mb = Multibody()
        with pytest.raises(ModelDefinitionError) as info:
            mb.add_body("arm", None, mass=2.0, inertia=line, hinge=hinge, **kwargs)
        for expected in (fragment, "none about [[1.0, 0.0, 0.0]]", "CONM2"):
            assert expected in str(info.value), str(info.value)
