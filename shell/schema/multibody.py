"""The ``multibody:`` section of a scenario: bodies, hinges, nodes and initial state, read into an engine system.

The section (docs/scenario_schema.md, section multibody) lists bodies in order, each with its parent, hinge (locked,
revolute, prismatic, ujoint, spherical, free, translation: dynamics.hinges.HINGES; docs/conventions.md for their
coordinates), rigid mass properties or a
flexible body file (``flexshell fem2modal``), the placement of its inboard and outboard frames, and an optional
``initial:`` hinge state; then nodes fixed on bodies; then closure ``constraints:`` between nodes (weld, ball,
revolute, prismatic, distance: :mod:`dynamics.constraints`), which close loops or hold a node to the world.
:func:`read_multibody` checks it key by key (every refusal names file, line and key path), builds the
:class:`dynamics.Multibody` and compiles it; a scene with constraints gets a
:class:`dynamics.constraints.ConstrainedSystem` and its initial state assembled onto the constraints (moved by at
most ``assembly_tolerance``, refused beyond it, naming the constraint). The runtime side, the engine as a shell model
with its ports, is :mod:`shell.models.multibody`; Monte Carlo runs read a body's dispersed mass properties again with
:func:`rigid_mass_properties` and :func:`initial_state`.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from dynamics import ModelDefinitionError, Multibody, MultibodySystem
from dynamics.constraints import (CONSTRAINT_KINDS, DEFAULT_ASSEMBLY_TOLERANCE, AssemblyReport, ClosureConstraint,
                                  ConstrainedSystem)
from dynamics.definitions import suggest
from dynamics.force_elements import (ACTS, Bushing, HingeFriction, HingeSpring, HingeStop, PlaneContact, SphereContact,
                                      SpringDamper, element_tables)
from dynamics.hinges import HINGE_TYPES, HINGES
from dynamics.layout import N_MODES
from dynamics.modal_order import resolve_modal_orders
from dynamics.mode_selection import select_modes
from dynamics.spatial import quaternion_to_rotation
from shell.diagnostics import located
from shell.schema.validation import Where, expect_list, expect_mapping, expect_name
from shell.units import UnitError, to_magnitude, ureg

CONSTRAINT_KEYS = {"name": "constraint name (its load port: <name>.load)", "kind": "weld, ball, revolute, prismatic "
                   "or distance", "node_a": "node frame A (axes of the axis and the load)",
                   "node_b": "node frame B (omitted: the world, at A's initial pose)",
                   "axis": "revolute or prismatic axis, unit vector in A's axes",
                   "length": "distance constraint's length (m; default: the initial distance)",
                   "active": "false: declared off until an event switches it on (a latch; events: on:); default true"}
_LAW_KEYS = {"stiffness": "Hunt-Crossley k: N/m^n (contacts), N*m/rad^n or N/m^n (stops), n the exponent",
             "exponent": "Hunt-Crossley n (default 1.5 for contacts, 1 for stops)",
             "damping": "Hunt-Crossley D (s/m, s/rad): F = k delta^n (1 + D delta_dot)",
             "restitution": "coefficient of restitution e in (0, 1] at impact_speed (instead of damping)",
             "impact_speed": "the impact speed e holds at (m/s, rad/s)"}
_HINGE_KEYS = {"body": "body whose inboard hinge it acts on", "dof": "the hinge's DOF (default 0; 1: a U-joint's "
               "second angle)"}
FORCE_KEYS = {
    "spring_damper": {"node_a": "node at one end", "node_b": "node at the other end (or world_point)",
                      "world_point": "fixed end, world (m; default origin)", "stiffness": "N/m", "damping": "N*s/m",
                      "free_length": "m (default: the initial length)",
                      "acts": "both, compression or tension (default both)"},
    "bushing": {"node_a": "node frame A (the axes of K and C)", "node_b": "node frame B (omitted: the world)",
                "world_position": "B's world position when node_b is omitted (m; default A's initial)",
                "world_rotation": "B's world rotation, 3x3 or [w, x, y, z] (default A's initial)",
                "stiffness": "6 diagonal entries or 6x6, rows [rotation; translation], SI (N*m/rad, N/m), or "
                             "{rotation: N*m/rad, translation: N/m} (3 or 3x3 each)",
                "damping": "as stiffness, SI (N*m*s/rad, N*s/m) or {rotation: N*m*s/rad, translation: N*s/m}"},
    "hinge_spring": {**_HINGE_KEYS, "stiffness": "N*m/rad or N/m", "damping": "N*m*s/rad or N*s/m",
                     "neutral": "coordinate where it is relaxed (rad or m, default 0)"},
    "hinge_stop": {**_HINGE_KEYS, "lower": "lower limit (rad or m)", "upper": "upper limit (rad or m)",
                   **_LAW_KEYS},
    "hinge_friction": {**_HINGE_KEYS, "level": "Coulomb friction torque or force (N*m or N)",
                       "slip_speed": "regularization speed (rad/s or m/s, default 1e-3)"},
    "plane_contact": {"node": "node at the sphere's centre", "radius": "sphere radius (m, default 0: a point)",
                      "plane_node": "node the plane goes through (omitted: a world plane)",
                      "normal": "unit normal, plane_node's axes or the world's (default [0, 0, 1])",
                      "world_point": "a point of a world plane (m, default origin)", **_LAW_KEYS,
                      "friction": "Coulomb coefficient mu (default 0)",
                      "slip_speed": "friction regularization speed (m/s, default 1e-3)"},
    "sphere_contact": {"node_a": "node at sphere A's centre", "node_b": "node at sphere B's centre",
                       "radius_a": "m", "radius_b": "m", **_LAW_KEYS,
                       "friction": "Coulomb coefficient mu (default 0)",
                       "slip_speed": "friction regularization speed (m/s, default 1e-3)"},
}
"""Keys of each force element kind (:mod:`dynamics.force_elements`), besides name and kind."""
FORCE_KINDS = tuple(FORCE_KEYS)
_FORCE_REQUIRED = {"spring_damper": ("node_a", "stiffness"), "bushing": ("node_a",),
                   "hinge_spring": ("body", "stiffness"), "hinge_stop": ("body", "stiffness"),
                   "hinge_friction": ("body", "level"), "plane_contact": ("node", "stiffness"),
                   "sphere_contact": ("node_a", "node_b", "stiffness")}
SECTION_KEYS = {"name": "engine model name (default multibody)", "gravity": "uniform gravity, world axes (m/s^2)",
                "bodies": "list of bodies", "nodes": "list of nodes",
                "constraints": "closure constraints between nodes (weld, ball, revolute, prismatic, distance)",
                "forces": "force elements: " + ", ".join(FORCE_KINDS),
                "outputs": "optional outputs, computed only when asked for: hinge_load (<body>.hinge_load of every "
                           "body) and energy",
                "assembly_tolerance": "largest constraint residual of the initial state that is projected away "
                                      "(m or rad, default 1e-6); beyond it the scene is refused"}
NODE_KEYS = {"name": "node name", "body": "body it is fixed on", "position": "in the body frame (m)",
             "rotation": "node -> body", "grid": "FE grid id (nodes on flexible bodies)"}
BODY_KEYS = {
    "name": "body name", "parent": "parent body name or world", "hinge": ", ".join(HINGE_TYPES),
    "mass": "mass (kg)", "com": "center of mass in the body frame (m)",
    "inertia": "inertia about the center of mass, 3x3 or 3 principal moments (kg m^2)",
    "axis": "hinge axis (unit vector)", "axes": "two U-joint axes", "inboard_position": "m",
    "inboard_rotation": "3x3 or quaternion", "outboard_position": "m", "outboard_rotation": "3x3 or quaternion",
    "prescribed": "bool or one bool per hinge DOF", "initial": "initial hinge state",
    "parent_node": "node of a flexible parent the hinge attaches at",
    "body_file": "flexible body file (HDF5, from flexshell fem2modal), relative to the scenario",
    "modes": "indices of the body file's modes to keep (default all)",
    "max_frequency": "keep the body file's modes at or below this frequency, e.g. 100 Hz (with modes: the listed "
                     "modes below it)",
    "modal_integrals_order": "0, 1, 2 or auto: order of the deformation-dependent modal integrals (default auto: "
                             "the order the scene needs at its initial state, dynamics.modal_order)",
    "omit_terms": "terms of the nodes' rotary inertia to leave out: a list of G1, F2, G2 (auto chooses otherwise)",
    "damping_ratio": "modal damping ratio overriding the body file's",
    "integrals": "general or point_mass modal integrals (default general)",
    "child_grid": "grid of this flexible body that the hinge holds (its deforming interface grid)",
    "geometric_stiffening": "true/false: stiffening by the rigid-motion stresses (default: on when the body "
                            "file has them, fem2modal --geometric-stiffness)",
    "preload": "mapping preload name -> scale of the body file's named preloads (fem2modal --preload)",
}
FLEXIBLE_ONLY = ("modes", "max_frequency", "modal_integrals_order", "omit_terms", "damping_ratio", "integrals",
                 "child_grid", "geometric_stiffening", "preload")
OPTIONAL_OUTPUTS = {"hinge_load": "<body>.hinge_load of every body", "energy": "energy (kinetic, potential, force "
                    "elements', total)"}
"""Outputs a scene asks for (``multibody.outputs:``): computed on the constrained path only (its kernel has them)."""


def _initial_keys():
    """key -> (unit, what it applies to) of a body's ``initial:`` entry: q and u, the hinge types' own keys (their
    records, dynamics.hinges.HINGES), a flexible body's modal coordinates."""
    keys = {"q": ("", "all"), "u": ("", "all")}
    for record in HINGES:
        for key, _, _, _, unit in record.initial:
            keys[key] = (unit, f"{keys[key][1]} {record.name}" if key in keys else record.name)
    return keys | {"modal": ("", "flexible"), "modal_rate": ("1/s", "flexible")}


INITIAL_KEYS = _initial_keys()


@dataclass(frozen=True)
class MultibodySection:
    """What the ``multibody:`` section describes: the engine model's name, its compiled system and initial
    state (hinge quaternions normalized; ``written_q`` the coordinates as written, from which a run that changes
    a body's initial value normalizes, as the scene built with that value does). With ``constraints:``,
    ``constrained`` holds the system with its closures and ``assembly`` how far the initial state was moved onto
    them (``initial_q``, ``initial_u`` are the assembled state)."""

    name: str
    system: MultibodySystem
    initial_q: np.ndarray
    initial_u: np.ndarray
    written_q: np.ndarray
    constrained: ConstrainedSystem | None = None
    assembly: AssemblyReport | None = None
    outputs: tuple = ()  # the optional outputs asked for (shell.models.multibody.OPTIONAL_OUTPUTS)


def read_multibody(description, where: Where) -> MultibodySection:
    """Read the scenario's ``multibody:`` mapping; ``where`` locates errors (file, line, key)."""
    expect_mapping(description, where, SECTION_KEYS, required=("bodies",))
    name = description.get("name", "multibody")
    gravity = _vector(description, "gravity", "m/s^2", (3,), where, (0.0, 0.0, 0.0))
    builder = Multibody(gravity=tuple(gravity))
    bodies = expect_list(description["bodies"], where.child(description, "bodies"), "bodies")
    # nodes are added right after their body, so that a later body's hinge can attach to them
    pending_nodes = _node_adders(builder, description, where)
    initial = []
    for k, body in enumerate(bodies):
        here = where.child(description, "bodies").child(bodies, k)
        here = _add_body(builder, body, here)
        for add in pending_nodes.pop(body["name"], []):
            add()
        initial.append((body.get("initial"), here, body))
    for node_body in list(pending_nodes):  # nodes of bodies that do not exist: named by add_node
        for add in pending_nodes.pop(node_body):
            add()
    try:
        system = builder.compile()
    except ModelDefinitionError as exc:
        raise where.error(str(exc)) from None
    written, u0 = initial_state(system, initial)
    q0 = system.normalize_quaternions(written.copy())
    places = {body.get("name"): here for _, here, body in initial}  # the stiffening warning names its body
    with located(lambda text: next((h for b, h in places.items() if f"body '{b}'" in text), where)):
        system, _ = resolve_modal_orders(system, q0, u0)  # modal_integrals_order: auto
    outputs = _optional_outputs(description, where)
    if not description.get("constraints") and not description.get("forces"):
        for key in ("constraints", "forces"):
            if key in description:
                expect_list(description[key], where.child(description, key), key)
        if "assembly_tolerance" in description:
            raise where.child(description, "assembly_tolerance").error("applies to a scene with constraints:")
        if outputs:  # the constrained path computes them: a ConstrainedSystem without constraints or elements
            return MultibodySection(name, system, q0, u0, written, ConstrainedSystem(system), None, outputs)
        return MultibodySection(name, system, q0, u0, written)
    constrained, q0, u0, report = _constrained(system, description, where, q0, u0)
    return MultibodySection(name, system, q0, u0, written, constrained, report, outputs)


def _optional_outputs(description, where: Where) -> tuple:
    """The section's ``outputs:`` list, each one of :data:`OPTIONAL_OUTPUTS`, none twice."""
    here = where.child(description, "outputs")
    entries = expect_list(description.get("outputs") or [], here, "optional outputs")
    for k, entry in enumerate(entries):
        if entry not in OPTIONAL_OUTPUTS or entry in entries[:k]:
            raise here.child(entries, k).error(f"expected one of {list(OPTIONAL_OUTPUTS)}, each once, given "
                                               f"{entry!r}" + (suggest(entry, OPTIONAL_OUTPUTS) if isinstance(
                                                   entry, str) else ""))
    return tuple(entries)


def _constrained(system, description, where: Where, q0, u0):
    """(ConstrainedSystem, assembled q0, u0, AssemblyReport) of the section's ``constraints:``; the initial
    configuration supplies the world pose of a constraint without node_b and a distance's default length."""
    here_list = where.child(description, "constraints")
    entries = expect_list(description.get("constraints") or [], here_list, "constraints")
    tolerance = float(_vector(description, "assembly_tolerance", "", (), where, DEFAULT_ASSEMBLY_TOLERANCE))
    if not tolerance > 0.0:
        raise where.child(description, "assembly_tolerance").error(f"expected a positive residual (m or rad), "
                                                                   f"given {tolerance!r}")
    constraints, places = [], {}
    for k, entry in enumerate(entries):
        here = here_list.child(entries, k)
        constraint = _constraint(system, entry, here)
        here = here.named(constraint.label)
        if constraint.label in places:
            raise here.child(entry, "name").error(f"duplicate constraint name {constraint.label!r} (first at "
                                                  f"{places[constraint.label]})")
        places[constraint.label] = here
        constraints.append(constraint)
    forces = _forces(system, description, where, q0)
    try:
        constrained = ConstrainedSystem(system, constraints, forces, q_reference=q0)
    except ModelDefinitionError as exc:
        raise (here_list if constraints else where.child(description, "forces")).error(str(exc)) from None
    if not constraints:
        return constrained, q0, u0, None
    worst, label = constrained.worst_residual(q0)
    if worst > tolerance:
        raise places[label].error(f"the initial state violates this constraint by {worst:.3e} (m or rad), more than "
                                  f"assembly_tolerance {tolerance:g}: give an initial state that closes it (or "
                                  f"raise assembly_tolerance to have it projected)")
    try:
        q0, u0, report = constrained.assemble(q0, u0, tolerance)
    except ModelDefinitionError as exc:
        raise here_list.error(str(exc)) from None
    return constrained, q0, u0, report


def _forces(system, description, where: Where, q0) -> list:
    """The section's ``forces:`` entries as force elements (:mod:`dynamics.force_elements`), checked key by key; each
    is compiled against the system at the initial configuration ``q0`` here, so that what only the engine can judge
    (a non-symmetric stiffness, a hinge elements cannot act on) is refused at its entry."""
    here_list = where.child(description, "forces")
    entries = expect_list(description.get("forces") or [], here_list, "forces")
    every_key = {"name": "force element name", "kind": ", ".join(FORCE_KINDS)}
    for keys in FORCE_KEYS.values():
        every_key.update(keys)
    reference = system.node_kinematics(q0, np.zeros(system.nu))
    out, names = [], set()
    for k, entry in enumerate(entries):
        here = here_list.child(entries, k)
        expect_mapping(entry, here, every_key, required=("name", "kind"))
        name = expect_name(entry["name"], here.child(entry, "name"), "a force element name")
        here = here.named(name)
        if name in names:
            raise here.child(entry, "name").error(f"duplicate force element name {name!r}")
        names.add(name)
        kind = expect_name(entry["kind"], here.child(entry, "kind"), "a force element kind")
        if kind not in FORCE_KINDS:
            raise here.child(entry, "kind").error(f"unknown force element kind {kind!r}; expected one of "
                                                  f"{list(FORCE_KINDS)}" + suggest(kind, FORCE_KINDS))
        allowed = {"name": every_key["name"], "kind": every_key["kind"], **FORCE_KEYS[kind]}
        for key in entry:
            if key not in allowed:
                raise here.child(entry, key).error(f"not a key of a {kind}; expected one of {sorted(allowed)}")
        expect_mapping(entry, here, allowed, required=_FORCE_REQUIRED[kind])
        element = _FORCE_READERS[kind](_ForceEntry(system, entry, here), name)
        try:
            element_tables([element], system, reference)
        except ModelDefinitionError as exc:
            message = str(exc).split(": ", 1)[-1]
            key = next((key for key in entry if key not in ("name", "kind") and key in message.split()), None)
            raise (here if key is None else here.child(entry, key)).error(message) from None
        out.append(element)
    return out


class _ForceEntry:
    """One ``forces:`` entry's values, converted and checked with file, line and key."""

    def __init__(self, system, entry, here: Where):
        self.system, self.entry, self.here = system, entry, here
        self.coordinate, self.load = "", ""  # a hinge element's coordinate and generalized force units

    def error(self, key, message):
        return self.here.child(self.entry, key).error(message)

    def node(self, key):
        if key not in self.entry:
            return None
        node = expect_name(self.entry[key], self.here.child(self.entry, key), "a node name")
        if node not in self.system.node_names:
            raise self.error(key, f"unknown node {node!r}; nodes: {list(self.system.node_names)}"
                             + suggest(node, self.system.node_names))
        return node

    def number(self, key, unit, *, low=None, positive=False, high=None):
        """The value of ``key`` in ``unit`` (None when absent), checked against its bounds."""
        if key not in self.entry:
            return None
        value = float(_vector(self.entry, key, unit, (), self.here))
        if not np.isfinite(value) or (low is not None and not value >= low) or (positive and not value > 0.0) or \
                (high is not None and not value <= high):
            bound = (f"in (0, {high:g}]" if high is not None else "> 0") if positive else \
                (f"in [{low:g}, {high:g}]" if high is not None else f">= {low:g}")
            raise self.error(key, f"expected a value {bound if low is not None or positive else 'finite'}, given "
                                  f"{self.entry[key]!r}")
        return value

    def vector(self, key, unit):
        return None if key not in self.entry else tuple(_vector(self.entry, key, unit, (3,), self.here))

    def apart(self, key_a, key_b):
        """Refuse the nodes of ``key_a`` and ``key_b`` on one body (a contact of a body with itself)."""
        a, b = self.node(key_a), self.node(key_b)
        if a is not None and b is not None and self.system.node_bodies[self.system.node_index(a)] == \
                self.system.node_bodies[self.system.node_index(b)]:
            raise self.error(key_b, f"nodes {a!r} and {b!r} are on the same body "
                                    f"{self.system.node_bodies[self.system.node_index(a)]!r}")
        return a, b

    def hinge(self):
        """The hinge element's body, checked, and the units of its coordinate and generalized force."""
        body = expect_name(self.entry["body"], self.here.child(self.entry, "body"), "a body name")
        names = list(self.system.body_names)
        if body not in names:
            raise self.error("body", f"unknown body {body!r}; bodies: {names}" + suggest(body, names))
        hinge = self.system.hinge_names[names.index(body)]
        units = {"revolute": ("rad", "N*m"), "ujoint": ("rad", "N*m"), "prismatic": ("m", "N")}
        if hinge not in units:
            raise self.error("body", f"body {body!r} has a {hinge} hinge; hinge elements act on revolute, prismatic "
                                     f"or U-joint coordinates")
        self.coordinate, self.load = units[hinge]
        dof = self.entry.get("dof", 0)
        if isinstance(dof, bool) or not isinstance(dof, int) or not 0 <= dof < (2 if hinge == "ujoint" else 1):
            raise self.error("dof", f"expected {'0 or 1' if hinge == 'ujoint' else '0'} (the {hinge} hinge's DOF), "
                                    f"given {dof!r}")
        return body, dof

    def law(self, length, exponent_default):
        """The Hunt-Crossley law's keys in the units of ``length`` (m or rad): stiffness per length^n."""
        exponent = self.number("exponent", "", low=1.0)
        n = exponent_default if exponent is None else exponent
        force = self.load or "N"
        if "damping" in self.entry and "restitution" in self.entry:
            raise self.error("restitution", "give damping or restitution (with impact_speed), not both")
        if "restitution" in self.entry and "impact_speed" not in self.entry:
            raise self.error("restitution", "restitution needs the impact_speed it holds at (the Hunt-Crossley "
                                            "damping depends on it)")
        if "impact_speed" in self.entry and "restitution" not in self.entry:
            raise self.error("impact_speed", "impact_speed goes with restitution")
        return dict(stiffness=self.number("stiffness", f"{force}/{length}**{n!r}", low=0.0), exponent=exponent,
                    damping=self.number("damping", f"s/{length}", low=0.0),
                    restitution=self.number("restitution", "", positive=True, high=1.0),
                    impact_speed=self.number("impact_speed", f"{length}/s", positive=True))

    def six_by_six(self, key, rotation_unit, translation_unit):
        """A bushing's stiffness or damping: 6 or 6 x 6 SI numbers, or ``{rotation: .., translation: ..}`` blocks
        (3 or 3 x 3 each, with units)."""
        if key not in self.entry:
            return None
        value = self.entry[key]
        if isinstance(value, dict) and "unit" not in value:
            expect_mapping(value, self.here.child(self.entry, key), {"rotation": rotation_unit,
                                                                     "translation": translation_unit})
            matrix = np.zeros((6, 6))
            for block, unit, rows in (("rotation", rotation_unit, slice(0, 3)),
                                      ("translation", translation_unit, slice(3, 6))):
                if block in value:
                    where = self.here.child(self.entry, key)
                    part = _vector(value, block, unit, None, where)
                    if part.shape not in ((3,), (3, 3)):
                        raise where.child(value, block).error(f"expected 3 entries or a 3x3 matrix, given shape "
                                                              f"{part.shape}")
                    matrix[rows, rows] = np.diag(part) if part.shape == (3,) else part
            return matrix
        part = _vector(self.entry, key, "", None, self.here)
        if part.shape not in ((6,), (6, 6)):
            raise self.error(key, f"expected 6 entries or a 6x6 matrix (SI: {rotation_unit} rows 0-2, "
                                  f"{translation_unit} rows 3-5), given shape {part.shape}")
        return part


def _spring_damper(f: _ForceEntry, name):
    acts = f.entry.get("acts", "both")
    if acts not in ACTS:
        raise f.error("acts", f"expected one of {sorted(ACTS)}, given {acts!r}")
    if "node_b" in f.entry and "world_point" in f.entry:
        raise f.error("world_point", "give node_b or world_point, not both")
    values = {key: f.number(key, unit, low=0.0) for key, unit in (("stiffness", "N/m"), ("damping", "N*s/m"),
                                                                  ("free_length", "m")) if key in f.entry}
    return SpringDamper(name, f.node("node_a"), f.node("node_b"), acts=acts, world_point=f.vector("world_point", "m"),
                        **values)


def _bushing(f: _ForceEntry, name):
    if "node_b" in f.entry:
        for key in ("world_position", "world_rotation"):
            if key in f.entry:
                raise f.error(key, "give node_b or a world pose, not both")
    return Bushing(name, f.node("node_a"), f.node("node_b"),
                   stiffness=f.six_by_six("stiffness", "N*m/rad", "N/m"),
                   damping=f.six_by_six("damping", "N*m*s/rad", "N*s/m"),
                   world_rotation=_rotation(f.entry, "world_rotation", f.here),
                   world_position=f.vector("world_position", "m"))


def _hinge_spring(f: _ForceEntry, name):
    body, dof = f.hinge()
    c, load = f.coordinate, f.load
    return HingeSpring(name, body, f.number("stiffness", f"{load}/{c}", low=0.0),
                       f.number("damping", f"{load}*s/{c}", low=0.0) or 0.0, f.number("neutral", c) or 0.0, dof)


def _hinge_stop(f: _ForceEntry, name):
    body, dof = f.hinge()
    if "lower" not in f.entry and "upper" not in f.entry:
        raise f.here.error("give lower and/or upper")
    lower, upper = f.number("lower", f.coordinate), f.number("upper", f.coordinate)
    if lower is not None and upper is not None and not lower < upper:
        raise f.error("upper", f"lower ({lower:g} {f.coordinate}) must be below upper ({upper:g} {f.coordinate})")
    return HingeStop(name, body, lower, upper, dof=dof, **f.law(f.coordinate, 1.0))


def _hinge_friction(f: _ForceEntry, name):
    body, dof = f.hinge()
    slip = f.number("slip_speed", f"{f.coordinate}/s", positive=True)
    return HingeFriction(name, body, f.number("level", f.load, low=0.0), 1e-3 if slip is None else slip, dof)


def _contact_keys(f: _ForceEntry):
    slip = f.number("slip_speed", "m/s", positive=True)
    return dict(friction=f.number("friction", "", low=0.0) or 0.0, slip_speed=1e-3 if slip is None else slip,
                **f.law("m", 1.5))


def _plane_contact(f: _ForceEntry, name):
    if "plane_node" in f.entry and "world_point" in f.entry:
        raise f.error("world_point", "give plane_node or world_point, not both")
    normal = f.vector("normal", "")
    node, plane_node = f.apart("node", "plane_node")
    return PlaneContact(name, node, f.number("radius", "m", low=0.0) or 0.0, plane_node,
                        (0.0, 0.0, 1.0) if normal is None else normal, f.vector("world_point", "m") or (0.0, 0.0, 0.0),
                        **_contact_keys(f))


def _sphere_contact(f: _ForceEntry, name):
    return SphereContact(name, *f.apart("node_a", "node_b"), f.number("radius_a", "m", low=0.0) or 0.0,
                         f.number("radius_b", "m", low=0.0) or 0.0, **_contact_keys(f))


_FORCE_READERS = {"spring_damper": _spring_damper, "bushing": _bushing, "hinge_spring": _hinge_spring,
                  "hinge_stop": _hinge_stop, "hinge_friction": _hinge_friction, "plane_contact": _plane_contact,
                  "sphere_contact": _sphere_contact}


def _constraint(system, entry, here: Where) -> ClosureConstraint:
    """One ``constraints:`` entry, checked key by key against the system's nodes."""
    expect_mapping(entry, here, CONSTRAINT_KEYS, required=("kind", "node_a"))
    kind = expect_name(entry["kind"], here.child(entry, "kind"), "a constraint kind")
    if kind not in CONSTRAINT_KINDS:
        raise here.child(entry, "kind").error(f"unknown constraint kind {kind!r}; expected one of "
                                              f"{sorted(CONSTRAINT_KINDS)}" + suggest(kind, list(CONSTRAINT_KINDS)))
    nodes = {}
    for role in ("node_a", "node_b"):
        if role not in entry:
            continue
        node = expect_name(entry[role], here.child(entry, role), "a node name")
        if node not in system.node_names:
            raise here.child(entry, role).error(f"unknown node {node!r}; nodes: {list(system.node_names)}"
                                                + suggest(node, system.node_names))
        nodes[role] = node
    if "node_b" in nodes:
        body = system.node_bodies[system.node_index(nodes["node_a"])]
        if body == system.node_bodies[system.node_index(nodes["node_b"])] and not system.topology[
                system.body_index(body), N_MODES]:
            raise here.child(entry, "node_b").error(f"nodes {nodes['node_a']!r} and {nodes['node_b']!r} are both on "
                                                    f"the rigid body {body!r}: a constraint between two frames of one "
                                                    f"rigid body holds nothing")
    axis = None
    if kind in ("revolute", "prismatic"):
        if "axis" not in entry:
            raise here.error(f"missing required key 'axis': a {kind} constraint turns or slides about an axis (unit "
                             f"vector in node_a's axes), e.g. axis: [0, 0, 1]")
        axis = _vector(entry, "axis", "", (3,), here)
        if abs(np.linalg.norm(axis) - 1.0) > 1e-9:
            raise here.child(entry, "axis").error(f"expected a unit vector, given norm {np.linalg.norm(axis):.12g}")
    elif "axis" in entry:
        raise here.child(entry, "axis").error(f"a {kind} constraint takes no axis (only revolute and prismatic do)")
    length = None
    if "length" in entry:
        if kind != "distance":
            raise here.child(entry, "length").error(f"a {kind} constraint takes no length (only distance does)")
        length = float(_vector(entry, "length", "m", (), here))
        if not length > 0.0:
            raise here.child(entry, "length").error(f"expected a positive length, given {entry['length']!r}")
    name = expect_name(entry["name"], here.child(entry, "name"), "a constraint name") if "name" in entry else ""
    active = entry.get("active", True)
    if not isinstance(active, bool):
        raise here.child(entry, "active").error(f"expected true or false, given {active!r}")
    try:
        return ClosureConstraint(nodes["node_a"], nodes.get("node_b"), kind, axis=None if axis is None else
                                 tuple(axis), name=name, length=length, active=active)
    except ModelDefinitionError as exc:
        raise here.error(str(exc)) from None


def _node_adders(builder: Multibody, description, where: Where) -> dict:
    """{body name: [function adding one of its nodes to ``builder``]} of the section's nodes, each checked."""
    pending = {}
    nodes = expect_list(description.get("nodes", []), where.child(description, "nodes"), "nodes")
    for k, node in enumerate(nodes):
        here = where.child(description, "nodes").child(nodes, k)
        expect_mapping(node, here, NODE_KEYS, required=("name", "body"))
        grid = node.get("grid")
        if grid is not None and (isinstance(grid, bool) or not isinstance(grid, int)):
            raise here.child(node, "grid").error(f"expected an FE grid id (integer), given {grid!r}")
        node_name = expect_name(node["name"], here.child(node, "name"), "a node name")
        node_body = expect_name(node["body"], here.child(node, "body"), "a body name")
        position = _vector(node, "position", "m", (3,), here) if "position" in node else None
        rotation = _rotation(node, "rotation", here)

        def add(node_name=node_name, node_body=node_body, position=position, rotation=rotation, grid=grid,
                here=here):
            try:
                builder.add_node(node_name, node_body, position=position, rotation=rotation, grid=grid)
            except ModelDefinitionError as exc:
                raise here.error(str(exc)) from None

        pending.setdefault(node_body, []).append(add)
    return pending


def _add_body(builder: Multibody, body, here: Where) -> Where:
    """Check one body entry and add it to ``builder``; returns its location named by the body."""
    flexible = isinstance(body, dict) and "body_file" in body
    expect_mapping(body, here, BODY_KEYS,
                   required=("name", "hinge") if flexible else ("name", "hinge", "mass", "inertia"))
    body_name = expect_name(body["name"], here.child(body, "name"), "a body name")
    here = here.named(body_name)
    for key in (("mass", "inertia", "com") if flexible else FLEXIBLE_ONLY):
        if key in body:
            raise here.child(body, key).error(
                "the body file gives the mass properties of a flexible body" if flexible else
                f"{key!r} applies to flexible bodies (with body_file:)")
    parent = body.get("parent", "world")
    if parent is not None:
        parent = expect_name(parent, here.child(body, "parent"), "a body name or world")
    kwargs = dict(
        hinge=expect_name(body["hinge"], here.child(body, "hinge"), "a hinge type"),
        inboard_position=_vector(body, "inboard_position", "m", (3,), here, (0, 0, 0)),
        outboard_position=_vector(body, "outboard_position", "m", (3,), here, (0, 0, 0)),
        inboard_rotation=_rotation(body, "inboard_rotation", here),
        outboard_rotation=_rotation(body, "outboard_rotation", here),
    )
    if "axis" in body:
        kwargs["axis"] = _vector(body, "axis", "", (3,), here)
    if "axes" in body:
        kwargs["axes"] = _vector(body, "axes", "", (2, 3), here)
    if "prescribed" in body:
        kwargs["prescribed"] = body["prescribed"]
    if "parent_node" in body:
        kwargs["parent_node"] = expect_name(body["parent_node"], here.child(body, "parent_node"), "a node")
    parent = None if parent in (None, "world") else parent
    try:
        with located(here):  # the engine's warnings about this body, with its file, line and key
            if flexible:
                builder.add_flexible_body(body_name, parent, **_flexible_options(body, here), **kwargs)
            else:
                mass, com, inertia = rigid_mass_properties(body, here)
                builder.add_body(body_name, parent, mass=mass, inertia=inertia, com=com, **kwargs)
    except (ModelDefinitionError, OSError, KeyError) as exc:
        raise here.error(str(exc.args[0] if isinstance(exc, KeyError) else exc)) from None
    return here


def rigid_mass_properties(body, where):
    """(mass, com, inertia about the COM) of a rigid body's scenario entry, SI."""
    return (float(_vector(body, "mass", "kg", (), where)), _vector(body, "com", "m", (3,), where, (0, 0, 0)),
            _matrix_or_diagonal(body, where))


def initial_state(system, entries):
    """(q0, u0) from each body's ``initial:`` entry (``entries``: (spec or None, where, body entry) in body
    order), as written: the engine model normalizes the quaternions (MultibodySection's ``written_q``)."""
    q0, u0 = system.neutral_configuration(), np.zeros(system.nu)
    for b, (spec, here, body) in enumerate(entries):
        if spec is not None:
            _apply_initial(system, b, spec, here.child(body, "initial"), q0, u0)
    return q0, u0


def initial_targets(system, b) -> dict:
    """{key: ("q" or "u", slice of q or u, shape, unit)} of the initial keys (INITIAL_KEYS) body ``b``'s hinge
    takes: the hinge's own coordinates first, then a flexible body's modal coordinates (docs/conventions.md)."""
    cached = _INITIAL_TARGETS.get((id(system.topology), b))
    if cached is not None and cached[0] is system.topology:
        return cached[1]
    hinge = system.hinge_names[b]
    qs, us = system.q_slices[b], system.u_slices[b]
    nq, nu = qs.stop - qs.start, us.stop - us.start
    record = HINGES[HINGE_TYPES[hinge]]
    local = [("q", "q", 0, nq, ""), ("u", "u", 0, nu, "")] + list(record.initial)
    if nq > record.nq:
        local += [("modal", "q", record.nq, nq, INITIAL_KEYS["modal"][0]),
                  ("modal_rate", "u", record.nu, nu, INITIAL_KEYS["modal_rate"][0])]
    targets = {}
    for key, target, start, stop, unit in local:
        base = qs.start if target == "q" else us.start
        targets[key] = (target, slice(base + start, base + stop), (stop - start,), unit)
    if len(_INITIAL_TARGETS) > 1024:
        _INITIAL_TARGETS.clear()
    _INITIAL_TARGETS[(id(system.topology), b)] = (system.topology, targets)
    return targets


#: initial_targets per (engine topology, body): the same for every run of a scene (its systems share the topology)
_INITIAL_TARGETS: dict = {}


def body_entries(description, where):
    """[(body entry, where)] of the multibody: section, in order, ``where`` naming each body."""
    bodies = expect_list(description["bodies"], where.child(description, "bodies"), "bodies")
    out = []
    for k, body in enumerate(bodies):
        here = where.child(description, "bodies").child(bodies, k)
        out.append((body, here.named(body.get("name")) if isinstance(body, dict) else here))
    return out


def _flexible_options(body, where) -> dict:
    """The :meth:`dynamics.Multibody.add_flexible_body` options of a flexible body's entry."""
    path = Path(str(body["body_file"]))
    if not path.is_absolute():
        path = Path(where.file).parent / path
    if not path.exists():
        raise where.child(body, "body_file").error(f"no body file {str(path)!r} (paths are relative to the scenario)")
    options = {"modal": str(path)}
    if "modes" in body:
        modes = body["modes"]
        if not isinstance(modes, list) or not all(isinstance(m, int) and not isinstance(m, bool) for m in modes):
            raise where.child(body, "modes").error(f"expected a list of mode indices, given {modes!r}")
        options["modes"] = list(modes)
    if "max_frequency" in body:
        options.update(_max_frequency_options(body, where, path, options.get("modes")))
    order = body.get("modal_integrals_order", "auto")
    if isinstance(order, bool) or order not in (0, 1, 2, "auto"):
        raise where.child(body, "modal_integrals_order").error(f"expected 0, 1, 2 or auto, given {order!r}")
    options["order"] = order
    if "omit_terms" in body:
        omit = body["omit_terms"]
        if not isinstance(omit, list) or not set(omit) <= {"G1", "F2", "G2"}:
            raise where.child(body, "omit_terms").error(f"expected a list of G1, F2, G2, given {omit!r}")
        options["omit_terms"] = tuple(omit)
    if "damping_ratio" in body:
        options["damping_ratio"] = float(_vector(body, "damping_ratio", "", (), where))
    if "integrals" in body:
        if body["integrals"] not in ("general", "point_mass"):
            raise where.child(body, "integrals").error(f"expected general or point_mass, given {body['integrals']!r}")
        options["integrals"] = body["integrals"]
    if "child_grid" in body:
        grid = body["child_grid"]
        if not isinstance(grid, int) or isinstance(grid, bool):
            raise where.child(body, "child_grid").error(f"expected an FE grid id (integer), given {grid!r}")
        options["child_grid"] = grid
    if "geometric_stiffening" in body:
        flag = body["geometric_stiffening"]
        if not isinstance(flag, bool):
            raise where.child(body, "geometric_stiffening").error(f"expected true or false, given {flag!r}")
        options["geometric_stiffening"] = flag
    if "preload" in body:
        pre = body["preload"]
        if (not isinstance(pre, dict) or not all(isinstance(k, str) for k in pre)
                or not all(isinstance(v, (int, float)) and not isinstance(v, bool) and np.isfinite(v)
                           for v in pre.values())):
            raise where.child(body, "preload").error(f"expected a mapping preload name -> scale (number), "
                                                     f"e.g. {{thrust: 1.0}}, given {pre!r}")
        options["preload"] = {k: float(v) for k, v in pre.items()}
    return options


def _max_frequency_options(body, where, path, modes) -> dict:
    """``modal`` (the body file, read once) and ``modes`` kept by the ``max_frequency:`` cutoff
    (:func:`dynamics.mode_selection.select_modes`); the value must carry a cyclic-frequency unit."""
    here = where.child(body, "max_frequency")
    value = body["max_frequency"]
    f_max = float(_vector(body, "max_frequency", "Hz", (), where))  # refuses what is not a frequency
    if isinstance(value, dict):
        quantity = ureg.Quantity(1.0, value["unit"])
    else:
        quantity = ureg.Quantity(value) if isinstance(value, str) else None
    if quantity is None or quantity.unitless:
        raise here.error(f"expected a frequency with its unit, e.g. '100 Hz', given {value!r}")
    if "radian" in str(quantity.to_root_units().units):  # pint takes rad as 1: 628 rad/s would pass as 628 Hz
        raise here.error(f"max_frequency is a cyclic frequency: give it in Hz, not in an angular unit (given "
                         f"{value!r}, i.e. {f_max / (2 * np.pi):.6g} Hz)")
    # imported here: dynamics.flex loads the FEM pipeline (pyNastran, ~1 s), which only this option needs
    from dynamics.flex.body_file import read_body_file

    modal = read_body_file(path)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            keep = select_modes(modal.frequencies_hz, modes, f_max)
        except ValueError as exc:
            raise here.error(str(exc).replace("select_modes: ", "")) from None
    for warning in caught:
        warnings.warn(f"{here}: {str(warning.message).replace('select_modes: ', '')}", stacklevel=2)
    return {"modal": modal, "modes": keep.tolist()}


def _vector(mapping, key, unit, shape, where, default=None):
    if key not in mapping:
        if default is None:
            raise where.error(f"missing required key {key!r}")
        return np.asarray(default, dtype=float).reshape(shape)
    try:
        return to_magnitude(mapping[key], unit, shape, key)
    except UnitError as exc:
        raise where.child(mapping, key).error(str(exc)) from None


def _matrix_or_diagonal(body, where):
    try:
        inertia = to_magnitude(body["inertia"], "kg*m^2", None, "inertia")
    except UnitError as exc:
        raise where.child(body, "inertia").error(str(exc)) from None
    if inertia.shape == (3,):
        inertia = np.diag(inertia)
    if inertia.shape != (3, 3):
        raise where.child(body, "inertia").error(f"expected a 3x3 matrix or 3 principal moments, given shape "
                                                 f"{inertia.shape}")
    return inertia


def _rotation(mapping, key, where):
    if key not in mapping:
        return None
    value = to_magnitude(mapping[key], "", None, key)
    if value.shape == (4,):
        norm = np.linalg.norm(value)
        if abs(norm - 1.0) > 1e-9:
            raise where.child(mapping, key).error(f"expected a unit quaternion [w, x, y, z], given norm {norm:.12g}")
        rotation = np.empty((3, 3))
        quaternion_to_rotation(value[0], value[1], value[2], value[3], rotation)
        return rotation
    if value.shape != (3, 3):
        raise where.child(mapping, key).error(f"expected a 3x3 rotation matrix or a quaternion [w, x, y, z], "
                                              f"given shape {value.shape}")
    return value


def _apply_initial(system, b, spec, where, q0, u0) -> None:
    """Write a body's ``initial:`` entry into its slices of ``q0`` and ``u0`` (SI)."""
    hinge = system.hinge_names[b]
    expect_mapping(spec, where, {k: f"{unit or 'SI'} ({applies})" for k, (unit, applies) in INITIAL_KEYS.items()})
    targets = initial_targets(system, b)
    for key, value in spec.items():
        if key not in targets:
            raise where.child(spec, key).error(f"{key!r} does not apply to a {hinge} hinge; use "
                                               f"{[k for k, (_, a) in INITIAL_KEYS.items() if a == 'all' or hinge in a.split()]}")
        target, sl, shape, unit = targets[key]
        value_si = _vector(spec, key, unit, None, where)
        if value_si.shape == () and shape == (1,):
            value_si = value_si.reshape(1)
        if value_si.shape != shape:
            raise where.child(spec, key).error(f"expected shape {shape} for a {hinge} hinge, given {value_si.shape}")
        if key == "attitude" and abs(np.linalg.norm(value_si) - 1.0) > 1e-9:
            raise where.child(spec, key).error(f"expected a unit quaternion [w, x, y, z], given norm "
                                               f"{np.linalg.norm(value_si):.12g}")
        (q0 if target == "q" else u0)[sl] = value_si
