"""URDF import into the multibody builder.

Mapping (documented contract, ``Multibody.from_urdf(path, floating_base=False|True)``):

* The root link (the one link that is no joint's child) is the ground for a fixed base. With
  ``floating_base=True`` it becomes a body attached to the ground by a free hinge named ``root_joint``
  (q = [qw, qx, qy, qz, x, y, z], u = [omega; v] in the root link frame).
* Every ``revolute``/``continuous`` joint becomes a revolute hinge, ``prismatic`` a prismatic hinge,
  ``floating`` a free hinge; the child link's frame is the joint frame (URDF semantics): inboard frame =
  the joint ``<origin>`` in the parent link frame, outboard frame = identity, axis = the joint ``<axis>``
  (default x), normalized when within 1e-6 of unit length and refused otherwise.
* ``fixed`` joints are merged: the child link's inertia is added to the body it is welded to, and the
  child link frame becomes a node of that body named after the link, so sensors and children keep their
  frames. (This is also what Pinocchio's URDF parser does, so joint lists match.)
* Bodies are ordered depth-first from the root, children in file order; ``joint_names`` are the URDF
  joint names. Joint limits, dynamics tags, visual and collision elements are ignored.
* ``planar`` joints and closed loops are refused; mimic joints are refused.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np

from dynamics.errors import ModelDefinitionError
from dynamics.spatial import rotation_from_rpy


class UrdfError(ModelDefinitionError):
    """A URDF file that cannot be turned into a multibody tree."""


def _floats(text, n, where, default=None):
    if text is None:
        if default is None:
            raise UrdfError(f"{where}: missing attribute")
        return np.array(default, dtype=np.float64)
    try:
        values = np.array([float(x) for x in text.split()], dtype=np.float64)
    except ValueError as exc:
        raise UrdfError(f"{where}: expected {n} numbers, got '{text}'") from exc
    if values.shape != (n,) or not np.all(np.isfinite(values)):
        raise UrdfError(f"{where}: expected {n} finite numbers, got '{text}'")
    return values


def _origin(element, where):
    """(rotation, position) of an ``<origin xyz rpy>`` child (identity when absent)."""
    origin = element.find("origin")
    if origin is None:
        return np.eye(3), np.zeros(3)
    xyz = _floats(origin.get("xyz"), 3, f"{where} <origin xyz>", default=(0.0, 0.0, 0.0))
    rpy = _floats(origin.get("rpy"), 3, f"{where} <origin rpy>", default=(0.0, 0.0, 0.0))
    return rotation_from_rpy(*rpy), xyz


class _LinkInertia:
    """Mass, COM and inertia about the COM of a link, in some frame; can absorb welded links."""

    def __init__(self, mass=0.0, com=None, inertia=None):
        self.mass = mass
        self.com = np.zeros(3) if com is None else com
        self.inertia = np.zeros((3, 3)) if inertia is None else inertia

    def add(self, other, R, p):
        """Absorb ``other`` (given in a frame with rotation R and origin p in this frame)."""
        if other.mass == 0.0:
            return
        com_o = p + R @ other.com
        J_o = R @ other.inertia @ R.T
        m = self.mass + other.mass
        com = (self.mass * self.com + other.mass * com_o) / m

        def shift(J, mass, c):  # inertia about the combined COM
            d = c - com
            return J + mass * (d @ d * np.eye(3) - np.outer(d, d))

        self.inertia = shift(self.inertia, self.mass, self.com) + shift(J_o, other.mass, com_o)
        self.mass = m
        self.com = com


def _read_link_inertia(link):
    where = f"link '{link.get('name')}'"
    inertial = link.find("inertial")
    if inertial is None:
        return _LinkInertia()
    R, p = _origin(inertial, f"{where} <inertial>")
    mass_el = inertial.find("mass")
    if mass_el is None:
        raise UrdfError(f"{where}: <inertial> has no <mass>")
    mass = _floats(mass_el.get("value"), 1, f"{where} <mass value>")[0]
    inertia_el = inertial.find("inertia")
    if inertia_el is None:
        raise UrdfError(f"{where}: <inertial> has no <inertia>")
    vals = {}
    for key in ("ixx", "ixy", "ixz", "iyy", "iyz", "izz"):
        vals[key] = _floats(inertia_el.get(key), 1, f"{where} <inertia {key}>")[0]
    J = np.array([[vals["ixx"], vals["ixy"], vals["ixz"]],
                  [vals["ixy"], vals["iyy"], vals["iyz"]],
                  [vals["ixz"], vals["iyz"], vals["izz"]]])
    return _LinkInertia(mass, p, R @ J @ R.T)


def multibody_from_urdf(path, mb, floating_base=False):
    """Parse ``path`` and add its links and joints to the empty :class:`~dynamics.Multibody` builder ``mb``;
    returns ``mb`` (call ``compile()`` on it). ``Multibody.from_urdf`` is the user's entry point."""
    path = Path(path)
    try:
        root = ET.parse(path).getroot()
    except ET.ParseError as exc:
        raise UrdfError(f"{path}: malformed XML: {exc}") from exc
    except OSError as exc:
        raise UrdfError(f"{path}: cannot read: {exc}") from exc
    if root.tag != "robot":
        raise UrdfError(f"{path}: root element is <{root.tag}>, expected <robot>")

    links = {}
    for link in root.findall("link"):
        name = link.get("name")
        if not name:
            raise UrdfError(f"{path}: a <link> has no name")
        if name in links:
            raise UrdfError(f"{path}: duplicate link '{name}'")
        links[name] = link
    joints = []
    child_of = {}
    names = set()
    for joint in root.findall("joint"):
        jname = joint.get("name")
        where = f"{path}: joint '{jname}'"
        if not jname:
            raise UrdfError(f"{path}: a <joint> has no name")
        if jname in names:
            raise UrdfError(f"{where}: duplicate joint name")
        names.add(jname)
        jtype = joint.get("type")
        parent_el, child_el = joint.find("parent"), joint.find("child")
        if parent_el is None or child_el is None:
            raise UrdfError(f"{where}: needs <parent link=...> and <child link=...>")
        parent, child = parent_el.get("link"), child_el.get("link")
        for role, link in (("parent", parent), ("child", child)):
            if link not in links:
                raise UrdfError(f"{where}: {role} link '{link}' is not defined")
        if child in child_of:
            raise UrdfError(f"{where}: link '{child}' is already the child of joint '{child_of[child]}' "
                            f"(closed loops are not supported by URDF import)")
        if jtype not in ("revolute", "continuous", "prismatic", "fixed", "floating"):
            raise UrdfError(f"{where}: joint type '{jtype}' is not supported (revolute, continuous, "
                            f"prismatic, fixed, floating)")
        if joint.find("mimic") is not None:
            raise UrdfError(f"{where}: mimic joints are not supported")
        child_of[child] = jname
        joints.append((jname, jtype, parent, child, joint))

    roots = [name for name in links if name not in child_of]
    if len(roots) != 1:
        raise UrdfError(f"{path}: expected exactly one root link (a link that is no joint's child), found "
                        f"{roots}")
    children = {name: [] for name in links}
    for entry in joints:
        children[entry[2]].append(entry)

    inertia = {name: _read_link_inertia(link) for name, link in links.items()}
    # Depth-first traversal. Each link maps to (body it is welded into, or None for the ground;
    # rotation and origin of the link frame in that body's frame).
    placement = {}
    order = []  # (joint or None, link) in body order

    def weld(start, body, R, p):
        # iterative pre-order depth-first traversal (deep chains exceed Python's recursion limit)
        stack = [(start, body, R, p)]
        while stack:
            link, body, R, p = stack.pop()
            placement[link] = (body, R, p)
            pending = []
            for jname, jtype, _, child, joint in children[link]:
                Rj, pj = _origin(joint, f"{path}: joint '{jname}'")
                R_child, p_child = R @ Rj, p + R @ pj
                if jtype == "fixed":
                    pending.append((child, body, R_child, p_child))
                else:
                    pending.append((child, child, np.eye(3), np.zeros(3), (jname, jtype, joint, body,
                                                                            R_child, p_child)))
            for entry in reversed(pending):
                stack.append(entry[:4])
                if len(entry) == 5:
                    # record the joint when its child is visited, so bodies come out depth-first
                    joint_of_child[entry[0]] = entry[4]
            if link in joint_of_child:
                jname, jtype, joint, parent_body, R_in, p_in = joint_of_child.pop(link)
                order.append((jname, jtype, joint, link, parent_body, R_in, p_in))

    joint_of_child = {}
    root = roots[0]
    if floating_base:
        joint_of_child[root] = ("root_joint", "floating", None, None, np.eye(3), np.zeros(3))
        weld(root, root, np.eye(3), np.zeros(3))
    else:
        weld(root, None, np.eye(3), np.zeros(3))

    # accumulate welded inertia into the body that carries it
    body_inertia = {}
    for link, (body, R, p) in placement.items():
        if body is None:
            continue
        acc = body_inertia.setdefault(body, _LinkInertia())
        acc.add(inertia[link], R, p)

    for jname, jtype, joint, child, parent_body, R_in, p_in in order:
        where = f"{path}: link '{child}' (joint '{jname}')"
        mass_props = body_inertia.get(child, _LinkInertia())
        if mass_props.mass <= 0.0:
            raise UrdfError(f"{where}: the body moved by this joint has no mass (give the link, or a link "
                            f"welded to it, an <inertial> with positive mass)")
        kwargs = {}
        if jtype in ("revolute", "continuous", "prismatic"):
            axis_el = joint.find("axis")
            axis = _floats(axis_el.get("xyz") if axis_el is not None else None, 3, f"{where} <axis xyz>",
                           default=(1.0, 0.0, 0.0))
            norm = np.linalg.norm(axis)
            if abs(norm - 1.0) > 1e-6:
                raise UrdfError(f"{where}: axis {axis.tolist()} is not a unit vector (norm {norm:.9g})")
            kwargs["axis"] = axis / norm
        hinge = {"revolute": "revolute", "continuous": "revolute", "prismatic": "prismatic",
                 "floating": "free"}[jtype]
        try:
            mb.add_body(child, parent=parent_body, mass=mass_props.mass, com=mass_props.com,
                        inertia=mass_props.inertia, hinge=hinge, inboard_position=p_in,
                        inboard_rotation=R_in, joint_name=jname, **kwargs)
        except ModelDefinitionError as exc:
            raise UrdfError(f"{path}: {exc}") from exc
    if not mb.bodies:
        raise UrdfError(f"{path}: no movable joint: the model has no degrees of freedom")
    for link, (body, R, p) in placement.items():
        if body is not None and body != link:
            mb.add_node(link, body, position=p, rotation=R)
    return mb
