"""Run-time configuration changes: lock or unlock hinges, detach subtrees, change mass properties.

A compiled system never changes shape; a configuration change builds the next system from the
previous one's definitions and maps the state across (Dshell's run-time reconfiguration):

* **lock** a hinge: the hinge becomes ``locked`` with its current pose folded into its inboard frame;
  the locked DOFs' rates are removed by an *impulsive* (perfectly plastic) constraint,
  ``u+ = u- + M^-1 E' lambda`` with ``E u+ = 0`` (E selects the locked DOFs), which conserves the
  momentum of the rest of the system (the lock impulse is internal: total linear and angular momentum
  are unchanged) and never adds energy.
* **unlock** a hinge locked earlier: the original hinge comes back at the pose it was locked in, with
  zero relative rate (continuous velocities, no impulse). A hinge defined as locked from the start is
  unlocked by giving its new hinge, ``unlock={"name": {"hinge": "revolute", "axis": (0, 0, 1)}}``; its
  coordinates start at zero (the inboard frame is kept).
* **detach** a body: the subtree it roots separates from its parent (a separation event). The body is
  re-attached to the ground by a free hinge placed at its current world pose and moving with its
  current spatial velocity; every node keeps its pose and velocity, so nothing jumps.
* **attach** (a latch, a docking) a body floating free (a root on a free hinge) to a node of another body: the
  body becomes the node's child through a locked hinge whose outboard frame is its mating node, at the relative
  pose where the latch caught it (nothing moves, so nothing jumps). The two mating frames must already move
  together: the latch's perfectly plastic impact (the velocity projection of a weld between them, momentum
  conserved, misalignment checked) is :meth:`dynamics.constraints.ConstrainedSystem.reconfigure`'s; here a
  relative velocity left between them is refused. Bodies are renumbered so that parents come first.
* **mass properties** of rigid bodies, via a new system or in place with
  :meth:`dynamics.MultibodySystem.set_mass_properties` (cheap enough for per-step mass depletion).

With closure constraints and force elements, :meth:`dynamics.constraints.ConstrainedSystem.reconfigure`
applies these changes with the constraints' impacts included and carries the constraints and elements over.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from dynamics.definitions import hinge_definition, rigid_mass_properties, suggest
from dynamics.errors import ModelDefinitionError
from dynamics.hinges import HINGE_TYPES, hinge_transform, neutral_hinge_coordinates
from dynamics.spatial import rotation_to_quaternion


def _hinge_pose(system, body, q):
    """(R_FM, p_FM) of a body's hinge at configuration q."""
    i = system.body_index(body)
    R = np.empty((3, 3))
    p = np.empty(3)
    hinge_transform(int(system.topology[i, 1]), np.asarray(q, dtype=float), int(system.topology[i, 2]),
                    system.joint_vec[i, 2:4], R, p, np.empty((3, 3)), np.empty((3, 3)))
    return R, p


def reconfigure(system, q, u, *, lock=(), unlock=(), detach=(), attach=None, mass_properties=None):
    """Return ``(new_system, q_new, u_new)`` after the requested changes (applied in the order
    mass properties, detach, unlock, attach, lock).

    ``attach``: ``{body: (body_node, target_node)}``: body (a root on a free hinge) latched with its node
    ``body_node`` onto ``target_node`` of another body, the two frames moving together already."""
    bodies, nodes, gravity = system.definitions
    bodies = [dataclasses.replace(b) for b in bodies]
    by_name = {b.name: b for b in bodies}
    joint_to_body = {b.joint_name: b for b in bodies}

    def find(name, what):
        body = by_name.get(name) or joint_to_body.get(name)
        if body is None:
            raise ModelDefinitionError(f"{what}: unknown body or hinge '{name}' (hinges: "
                                       f"{[b.joint_name for b in bodies]})")
        return body

    q = np.asarray(q, dtype=float)
    u = np.asarray(u, dtype=float)
    # new coordinates per body: start from the old ones
    q_parts = {b.name: q[system.q_slices[k]].copy() for k, b in enumerate(bodies)}
    u_parts = {b.name: u[system.u_slices[k]].copy() for k, b in enumerate(bodies)}

    for name, props in (mass_properties or {}).items():
        body = find(name, "mass_properties")
        if body.flexible is not None:
            raise ModelDefinitionError(f"mass_properties: '{name}' is flexible; its mass properties come "
                                       f"from its modal data")
        body.mass, body.com, body.inertia = rigid_mass_properties(
            props.get("mass", body.mass), props.get("com", body.com), props.get("inertia", body.inertia),
            f"mass_properties: body '{name}'")

    if detach:
        rotations, origins = system.body_poses(q)
        velocities = system.body_velocities(q, u)
    for name in detach:
        body = find(name, "detach")
        if body.parent is None:
            raise ModelDefinitionError(f"detach: '{body.name}' is already attached to the ground")
        k = system.body_index(body.name)
        n = 0 if body.flexible is None else body.flexible.n_modes
        body.parent, body.parent_node, body.hinge = None, None, "free"
        body.axes = np.zeros((2, 3))
        body.prescribed = np.zeros(6, dtype=bool)
        body.inboard_rotation, body.inboard_position = np.eye(3), np.zeros(3)
        body.outboard_rotation, body.outboard_position = np.eye(3), np.zeros(3)
        body.outboard_node = None
        body.locked_from = None
        eta = q_parts[body.name][len(q_parts[body.name]) - n:]
        eta_dot = u_parts[body.name][len(u_parts[body.name]) - n:]
        q_parts[body.name] = np.concatenate([rotation_to_quaternion(rotations[k]), origins[k], eta])
        u_parts[body.name] = np.concatenate([velocities[k], eta_dot])

    for entry in (unlock.items() if isinstance(unlock, dict) else [(name, None) for name in unlock]):
        name, spec = entry
        body = find(name, "unlock")
        if body.hinge != "locked":
            raise ModelDefinitionError(f"unlock: hinge '{body.joint_name}' is not locked (it is {body.hinge})")
        modal_q, modal_u = q_parts[body.name], u_parts[body.name]  # a locked hinge has no coordinates
        if spec is None:
            if body.locked_from is None:
                raise ModelDefinitionError(
                    f"unlock: hinge '{body.joint_name}' was defined locked; give its new hinge, e.g. "
                    f"unlock={{'{body.joint_name}': {{'hinge': 'revolute', 'axis': (0, 0, 1)}}}}")
            hinge, axes, prescribed, R_in, p_in, q_hinge = body.locked_from
            body.hinge, body.axes, body.prescribed = hinge, axes, prescribed
            body.inboard_rotation, body.inboard_position = R_in, p_in
        else:
            spec = dict(spec)
            unknown = sorted(set(spec) - {"hinge", "axis", "axes", "prescribed"})
            if unknown or "hinge" not in spec:
                raise ModelDefinitionError(f"unlock: hinge '{body.joint_name}': give 'hinge' and its 'axis' / 'axes' / "
                                           f"'prescribed', got {sorted(spec)}")
            body.hinge, body.axes, body.prescribed = hinge_definition(spec.pop("hinge"), f"unlock: hinge "
                                                                      f"'{body.joint_name}'", **spec)
            q_hinge = neutral_hinge_coordinates(HINGE_TYPES[body.hinge])
        body.locked_from = None
        nu = int(len(body.prescribed))
        q_parts[body.name] = np.concatenate([q_hinge, modal_q])
        u_parts[body.name] = np.concatenate([np.zeros(nu), modal_u])

    if attach:
        q_parts, u_parts = _attach(type(system), bodies, nodes, gravity, q_parts, u_parts, attach, find)
        bodies = _parents_first(bodies)
        by_name = {b.name: b for b in bodies}

    locked_names = [find(name, "lock").name for name in lock]
    for name in locked_names:
        body = by_name[name]
        if body.hinge == "locked":
            raise ModelDefinitionError(f"lock: hinge '{body.joint_name}' is already locked")

    # impulsive lock: project the velocities of the current (possibly detached/unlocked) system
    if locked_names:
        mid = _compile(type(system), bodies, nodes, gravity)
        q_mid = np.concatenate([q_parts[b.name] for b in bodies])
        u_mid = np.concatenate([u_parts[b.name] for b in bodies])
        locked_dofs = []
        for name in locked_names:
            k = mid.body_index(name)
            start = mid.u_slices[k].start
            locked_dofs.extend(range(start, start + len(by_name[name].prescribed)))
        E = np.zeros((len(locked_dofs), mid.nu))
        E[np.arange(len(locked_dofs)), locked_dofs] = 1.0
        M = mid.mass_matrix(q_mid)
        Minv_Et = np.linalg.solve(M, E.T)
        lam = np.linalg.solve(E @ Minv_Et, -E @ u_mid)
        u_mid = u_mid + Minv_Et @ lam
        for k, b in enumerate(bodies):
            u_parts[b.name] = u_mid[mid.u_slices[k]]
        for name in locked_names:
            body = by_name[name]
            k = mid.body_index(name)
            nh = mid.q_slices[k].stop - mid.q_slices[k].start - mid.n_modes[k]
            q_hinge = q_parts[name][:nh]
            R_FM, p_FM = _hinge_pose(mid, name, q_mid)
            body.locked_from = (body.hinge, body.axes, body.prescribed, body.inboard_rotation,
                                body.inboard_position, q_hinge.copy())
            body.inboard_position = body.inboard_position + body.inboard_rotation @ p_FM
            body.inboard_rotation = body.inboard_rotation @ R_FM
            body.hinge, body.axes, body.prescribed = "locked", np.zeros((2, 3)), np.zeros(0, dtype=bool)
            nu = len(body.locked_from[2])
            q_parts[name] = q_parts[name][nh:]
            u_parts[name] = u_parts[name][nu:]

    new = _compile(type(system), bodies, nodes, gravity)
    q_new = np.concatenate([q_parts[b.name] for b in bodies])
    u_new = np.concatenate([u_parts[b.name] for b in bodies])
    return new, q_new, u_new


def attach_moves(bodies, nodes, attach, find):
    """Check the ``attach`` entries against the body and node definitions; returns ``(body, body_node,
    target_node)`` per entry."""
    node_by_name = {nd.name: nd for nd in nodes}
    children = {}
    for b in bodies:
        children.setdefault(b.parent, []).append(b.name)
    moves = []
    for name, spec in attach.items():
        body = find(name, "attach")
        where = f"attach: body '{body.name}'"
        try:
            body_node, target = spec
        except (TypeError, ValueError):
            raise ModelDefinitionError(f"{where}: give (body_node, target_node), got {spec!r}") from None
        if body.parent is not None or body.hinge != "free" or np.any(body.prescribed):
            raise ModelDefinitionError(f"{where}: only a body floating free (a root on a free hinge, nothing "
                                       f"prescribed) can be attached; it has a {body.hinge} hinge to "
                                       f"{body.parent or 'the ground'}")
        if body.outboard_node is not None:
            raise ModelDefinitionError(f"{where}: its free hinge sits on its node '{body.outboard_node}'; attach "
                                       f"needs the hinge on the body frame")
        for role, nd in (("its node", body_node), ("the target node", target)):
            if nd not in node_by_name:
                raise ModelDefinitionError(f"{where}: unknown node '{nd}' ({role}); nodes: {list(node_by_name)}"
                                           + suggest(nd, node_by_name))
        if node_by_name[body_node].body != body.name:
            raise ModelDefinitionError(f"{where}: node '{body_node}' is on body '{node_by_name[body_node].body}', "
                                       f"not on '{body.name}'")
        subtree, stack = set(), [body.name]
        while stack:
            b = stack.pop()
            subtree.add(b)
            stack.extend(children.get(b, []))
        if node_by_name[target].body in subtree:
            raise ModelDefinitionError(f"{where}: target node '{target}' is on body '{node_by_name[target].body}', "
                                       f"which moves with '{body.name}' (a loop: use a closure constraint)")
        moves.append((body, body_node, target))
    return moves


LATCH_VELOCITY_TOLERANCE = 1e-9
"""Largest relative speed (rad/s, m/s, relative to the fastest node) two frames may have to be attached."""


def _attach(system_class, bodies, nodes, gravity, q_parts, u_parts, attach, find):
    """Each ``attach`` entry (module docstring): the body's hinge made a locked hinge on the target node at the
    relative pose of the latch. Returns the new coordinates."""
    node_by_name = {nd.name: nd for nd in nodes}
    moves = attach_moves(bodies, nodes, attach, find)
    mid = _compile(system_class, bodies, nodes, gravity)
    q_mid = np.concatenate([q_parts[b.name] for b in bodies])
    u_mid = np.concatenate([u_parts[b.name] for b in bodies])
    kin = mid.node_kinematics(q_mid, u_mid)
    w = np.einsum("nab,nb->na", kin.rotation, kin.angular_velocity)
    v = np.einsum("nab,nb->na", kin.rotation, kin.linear_velocity)
    scale = max(1.0, float(np.abs(w).max(initial=0.0)), float(np.abs(v).max(initial=0.0)))
    for body, body_node, target in moves:
        a, b = mid.node_index(body_node), mid.node_index(target)
        arm = kin.position[a] - kin.position[b]
        slip = max(np.abs(w[a] - w[b]).max(), np.abs(v[a] - v[b] - np.cross(w[b], arm)).max())
        if slip > LATCH_VELOCITY_TOLERANCE * scale:
            raise ModelDefinitionError(
                f"attach: body '{body.name}': its node '{body_node}' moves at {slip:.3g} (rad/s or m/s) relative to "
                f"'{target}'; a latch is a plastic impact first: use ConstrainedSystem.reconfigure(attach=...) "
                f"(dynamics.constraints)")
    for body, body_node, target in moves:
        node = node_by_name[body_node]
        n = 0 if body.flexible is None else body.flexible.n_modes
        if body.flexible is None:
            body.outboard_rotation, body.outboard_position = node.rotation.copy(), node.position.copy()
        else:
            body.outboard_node = body_node
            body.outboard_rotation, body.outboard_position = np.eye(3), np.zeros(3)
        # the locked hinge holds the body's node where the latch found it relative to the (deformed) target node
        R_N, p_N = kin.rotation[mid.node_index(target)], kin.position[mid.node_index(target)]
        R_C, p_C = kin.rotation[mid.node_index(body_node)], kin.position[mid.node_index(body_node)]
        body.parent, body.parent_node, body.hinge = node_by_name[target].body, target, "locked"
        body.axes = np.zeros((2, 3))
        body.prescribed = np.zeros(0, dtype=bool)
        body.inboard_rotation, body.inboard_position = R_N.T @ R_C, R_N.T @ (p_C - p_N)
        body.locked_from = None
        q_parts[body.name] = q_parts[body.name][len(q_parts[body.name]) - n:]
        u_parts[body.name] = u_parts[body.name][len(u_parts[body.name]) - n:]
    return q_parts, u_parts


def _parents_first(bodies):
    """The bodies reordered so that every parent precedes its children, keeping the given order otherwise."""
    placed, order = set(), []
    pending = list(bodies)
    while pending:
        for k, b in enumerate(pending):
            if b.parent is None or b.parent in placed:
                order.append(pending.pop(k))
                placed.add(b.name)
                break
    return order


def _compile(system_class, bodies, nodes, gravity):
    """The changed definitions compiled by the class of the system they came from
    (:meth:`dynamics.MultibodySystem.from_definitions`)."""
    return system_class.from_definitions(bodies, nodes, gravity)
