"""Events that change the scene (``events: on:``): located as zero crossings, applied to the run in place.

Design: the state layout stays the same for the whole run, so the log keeps its columns, the compiled loop its data
type and a restart its state vector. A body that can be released is written on a free hinge held by a weld
constraint; a body that can be latched has the latch declared as a constraint with ``active: false``. An action then
switches constraints of the engine's per-run data on or off (the ``C_ACTIVE`` column of
:class:`dynamics.constraint_kernels.ConstraintData`, which the compiled kernels read): nothing is compiled again and
the loop continues. (The engine's :meth:`dynamics.constraints.ConstrainedSystem.reconfigure` changes the tree
itself, and with it the state's size and the kernels' data: a scene that needs it is a new scene.)

* ``detach: BODY`` (BODY on a free hinge): every active constraint with a node on BODY switched off; the body goes
  on with its state (the free hinge carries it). A BODY written on a locked hinge is built that way for the user
  (:func:`free_detached_bodies`: a free hinge at its initial pose and velocity, a weld to its parent), as the
  engine's :func:`dynamics.reconfigure.reconfigure` detaches a body: on a free hinge from the world;
* ``unlock: BODY``: the active constraints between BODY's nodes and its parent's (or the world) switched off;
* ``lock: BODY`` / ``attach: {body: A, to: B}`` / ``constraint: {add: NAME}``: constraints switched on, then the
  gap closed by the position projection (refused beyond the scene's ``assembly_tolerance``) and the perfectly
  plastic impact ``u+ = u - M^-1 G' (G M^-1 G')^+ G u`` (:func:`dynamics.constraint_kernels.project_velocities`;
  the impulse is internal, so momentum is conserved; the kinetic energy lost is ``1/2 (G u)' (G M^-1 G')^+ (G u)``,
  reported);
* ``constraint: {remove: NAME}``: switched off;
* ``set: {NAME: VALUE}``: parameters written by name into the run's context (:meth:`shell.names.NameIndex.assign`,
  converted and checked as the scenario's values are).

When: a time event is the zero crossing ``g = t - T`` (rising); a signal event ``g = s - c`` of the signal's element
``s`` and the value ``c`` crossed, in the direction written. Both are zero-crossing functions of one model,
:class:`SceneEvents` (named ``events``), so they are located exactly by the run's event location
(:mod:`shell.event_location`; the compiled loop returns to Python at a crossing, the action is applied, the loop
goes on). ``T`` and ``c`` are that model's parameters ``events.<event>.time`` and ``events.<event>.crosses``: a Monte
Carlo campaign disperses them by name. Each event happens once: its discrete state ``fired`` records the order in
which the events happened (0: not yet), and afterwards its function is held at 1. A restart restores ``fired`` and
with it the switches and parameters of the events that happened (:meth:`SceneEvents.establish`).
"""

from __future__ import annotations

import json
import warnings

import numpy as np
from numba import njit

from dynamics import constraint_kernels as CK
from dynamics.constraints import DEFAULT_ASSEMBLY_TOLERANCE
from dynamics.definitions import suggest
from shell.model import InputPort, Model, ModelError, Parameter, State, ZeroCrossing, convert_parameters
from shell.models.multibody import PROJECTION_ITERATIONS, PROJECTION_TOLERANCE, MultibodyModel
from shell.schema.document import show
from shell.schema.validation import find, is_bare_number
from shell.units import UnitError, to_magnitude

#: the model's name in the scene (its values: events.<event>.time, events.<event>.crosses, events.fired)
MODEL_NAME = "events"
TIME_EVENT, SIGNAL_EVENT = 0.0, 1.0
#: the actions that switch constraints on (the others switch them off; ``add``/``remove``: constraint:)
SWITCHES_ON = ("lock", "attach", "add")


@njit(cache=True)
def event_functions(t, x, z, u, p, g):
    """g_k = t - T_k (time event) or s_k - c_k (signal event), 1 once event k happened. ``p``: the n values
    T_k or c_k, then (kind, input element) per event."""
    n = g.shape[0]
    for k in range(n):
        if z[k] > 0.0:
            g[k] = 1.0
        elif p[n + 2 * k] == 0.0:
            g[k] = t - p[k]
        else:
            g[k] = u[int(p[n + 2 * k + 1])] - p[k]


class SceneEvents(Model):
    """The ``events: on:`` of a scenario as one model: its zero crossings, and the actions of each (module
    docstring). Built by :func:`add_scene_events`; the simulation calls :meth:`establish` when a run's context is
    set up or restored and :meth:`happen` when an event's crossing is located."""

    summary = "events that change the scene (events: on:): time events and signal crossings, and their actions"
    zero_crossing_values = staticmethod(event_functions)
    #: what the scene's builder chose for the events (said in the run summary)
    notes: tuple = ()

    def __init__(self, events, sources: dict, engine: str | None, operations: list, tolerance: float):
        #: the scenario's events (shell.schema.events.SceneEvent), in order
        self.events = list(events)
        #: event name -> (source port unit, shape) of its signal
        self.sources = sources
        #: the engine model's name (actions on constraints), or None
        self.engine = engine
        #: per event: [(verb, constraint indices or (name, value) pairs, the action's Where)]
        self.operations = operations
        #: largest gap (m or rad) a switched-on constraint may close (the scene's assembly_tolerance)
        self.tolerance = tolerance
        values = {}
        for e in self.events:
            if e.time is not None:
                values[f"{e.name}.time"] = {"value": e.time, "unit": "s"}
            else:
                values[f"{e.name}.crosses"] = e.crosses
        super().__init__(MODEL_NAME, **values)

    def declare(self):
        parameters, inputs, crossings = [], [], []
        for e in self.events:
            if e.time is not None:
                parameters.append(Parameter(f"{e.name}.time", "s", None, (), (0.0, None), f"time of event {e.name}"))
                crossings.append(ZeroCrossing(e.name, 1, False, f"t reaches events.{e.name}.time"))
            else:
                unit, shape = self.sources[e.name]
                parameters.append(Parameter(f"{e.name}.crosses", unit, None, (), None,
                                            f"value of {e.signal}[{e.element}] that makes event {e.name} happen"))
                inputs.append(InputPort(e.name, unit, shape, f"{e.signal} (event {e.name} watches element "
                                        f"{e.element})"))
                crossings.append(ZeroCrossing(e.name, e.direction, False, f"{e.signal}[{e.element}] crosses "
                                              f"events.{e.name}.crosses"))
        self.inputs = tuple(inputs)
        self.zero_crossings = tuple(crossings)
        self.discrete_states = (State("fired", "", (len(self.events),), np.zeros(len(self.events)),
                                      "order in which the events happened (0: not yet)"),)
        # where each function reads its signal: kind and element of the input vector, after the values
        offsets, start = {}, 0
        for port in inputs:
            offsets[port.name] = start
            start += int(np.prod(port.shape, dtype=int))
        layout = []
        for e in self.events:
            layout += [TIME_EVENT, 0.0] if e.time is not None else [SIGNAL_EVENT, offsets[e.name] + e.element]
        self.parameters = tuple(parameters) + (
            Parameter("layout", "", np.array(layout), (len(layout),), None,
                      "per event: kind (0 time, 1 signal) and the element of the inputs it watches (from the "
                      "events: on: section; the scene's structure, not a value a run changes)"),)

    def configure(self):
        self.parameter("layout")  # read here: a structural value (shell.names refuses to change it in a run)

    # -- a run --------------------------------------------------------------------------------------------
    def _engine(self, simulation):
        """(engine index, x slice of the engine, its per-run data, its system) of ``simulation``'s context."""
        i = simulation.model_index[self.engine]
        context = simulation.context
        return i, simulation.diagram.x_block[i], context.data[i], context.hosts[i]

    def establish(self, simulation) -> None:
        """The run's constraint switches as declared, then those of the events that already happened (``fired``,
        in their order) applied again with their parameters, without impacts (their state is the run's): a fresh
        run starts from the scene as written, a restored one from the scene as it was changed."""
        views = simulation.context.views[simulation.model_index[self.path]]
        if self.engine is not None:
            _, _, data, _ = self._engine(simulation)
            model = simulation.models[simulation.model_index[self.engine]]
            for j, c in enumerate(model.constrained.constraints):
                data[3].data.c_int[j, CK.C_ACTIVE] = int(c.active)
        fired = views.z
        for k in np.argsort(fired, kind="stable"):
            if fired[k] > 0.0:
                self._switch(simulation, k)
                self._set(simulation, k)

    def check(self, simulation) -> None:
        """Refuse (at the action's place) a ``set:`` of a name that is not a parameter the run can change, or a
        value it cannot take."""
        names = simulation.diagram.names
        for ops in self.operations:
            for verb, items, where in ops:
                if verb != "set":
                    continue
                for name, value in items:
                    entry = names.find(name)
                    here = where.child(dict(items), name)
                    if entry is None or entry.kind != "parameter" or entry.configured:
                        what = ("not a parameter of the scene" if entry is None or entry.kind != "parameter" else
                                "a parameter that shapes its model (read when it is built), which a run cannot change")
                        raise here.error(f"{name!r} is {what}; an event sets model parameters by name (e.g. "
                                         f"controller.kp)")
                    model = simulation.models[entry.model]
                    try:  # converted as NameIndex.assign will at the event
                        convert_parameters((entry.declaration,), {entry.leaf: value}, f"model {model.path}",
                                           type(model).__name__)
                    except (ModelError, UnitError) as exc:
                        raise here.error(str(exc)) from None

    def happen(self, simulation, k: int, t: float) -> str:
        """Event ``k`` at time ``t``: its actions applied to the run; returns what changed (for the log and the
        run summary)."""
        views = simulation.context.views[simulation.model_index[self.path]]
        views.z[k] = views.z.max() + 1.0
        changes = self._switch(simulation, k, impact=True)
        changes += self._set(simulation, k)
        return "; ".join(changes)

    def _switch(self, simulation, k: int, impact: bool = False) -> list[str]:
        """The constraint switches of event ``k``: off, then on (with the gap closed and the plastic impact of all
        active constraints when ``impact``). Returns what changed."""
        ops = [op for op in self.operations[k] if op[0] != "set"]
        if not ops:
            return []
        _, xs, data, system = self._engine(simulation)
        model = simulation.models[simulation.model_index[self.engine]]
        labels = [c.label for c in model.constrained.constraints]
        c = data[3].data
        active = c.c_int[:, CK.C_ACTIVE]
        switched_on, switched_off = [], []
        for on in (False, True):
            for verb, indices, where in ops:
                if (verb in SWITCHES_ON) != on:
                    continue
                change = [j for j in indices if bool(active[j]) != on]
                if not change and impact:
                    state = "on" if on else "off"
                    raise ModelError(f"{where}: event {self.events[k].name}: {verb} has nothing to switch {state} "
                                     f"(its constraints {[labels[j] for j in indices]} are {state} already)")
                for j in change:
                    active[j] = int(on)
                (switched_on if on else switched_off).extend(labels[j] for j in change)
        changes = [f"{', '.join(switched_off)} off"] if switched_off else []
        if switched_on and impact:
            x = simulation.x[xs]
            nq = system.nq
            q, u = x[:nq], x[nq:]
            engine = data[0]
            gap = CK.residual(engine, c, q)
            if gap > self.tolerance:
                for j in switched_on:
                    active[labels.index(j)] = 0
                raise ModelError(f"event {self.events[k].name}: switching on {', '.join(switched_on)} would close a "
                                 f"gap of {gap:.6g} (m or rad), more than the scene's assembly_tolerance "
                                 f"{self.tolerance:g}: the frames are not together when the event happens")
            energy = system.kinetic_energy(q, u)
            u_before = u.copy()
            # as ConstrainedSystem.switch_on: the plastic impact where the state is, then the gap closed and the
            # velocity defect the move leaves removed
            if (CK.project_velocities(engine, c, q, u) < 0
                    or CK.project_positions(engine, c, q, PROJECTION_TOLERANCE, PROJECTION_ITERATIONS) < 0
                    or CK.project_velocities(engine, c, q, u) < 0):
                raise ModelError(f"event {self.events[k].name}: the constraints {switched_on} cannot be met here")
            lost = energy - system.kinetic_energy(q, u)
            changes.append(f"{', '.join(switched_on)} on (gap {gap:.3g}, plastic impact: velocities changed by "
                           f"{np.abs(u - u_before).max(initial=0.0):.6g}, kinetic energy lost {lost:.9g} J)")
        elif switched_on:
            changes.append(f"{', '.join(switched_on)} on")
        return changes

    def _set(self, simulation, k: int) -> list[str]:
        items = [item for verb, pairs, _ in self.operations[k] if verb == "set" for item in pairs]
        if not items:
            return []
        simulation.context.assign(items)
        return [f"{name} = {show(value)}" for name, value in items]


def add_scene_events(root, scenario, notes=()) -> None:
    """The :class:`SceneEvents` of ``scenario``'s ``events: on:`` into the scene ``root`` (built by
    :func:`shell.scenario.build_root`): each action's bodies and constraints, each event's signal checked against
    the scene (refused at the action's or the signal's place), the signals connected; ``notes``: what the scene's
    builder chose for the events (:func:`free_detached_bodies`), said in the run summary."""
    events = scenario.scene_events
    if not events:
        return
    children = root.children
    if MODEL_NAME in children:
        here = find(scenario.document, scenario.file, ("models", MODEL_NAME))
        raise here.error(f"the name {MODEL_NAME!r} is taken by the model of the events: on: section (its values: "
                         "events.<event>.time, events.<event>.crosses)")
    engine = next((m for m in children.values() if isinstance(m, MultibodyModel)), None)
    operations = [[_operation(action, engine, e) for action in e.actions] for e in events]
    sources = {}
    for e in events:
        if e.signal is not None:
            sources[e.name] = _source(children, e)
        elif scenario.t_final is not None and e.time > scenario.t_final:
            warnings.warn(f"{e.where}: event {e.name} at t = {e.time:g} s is after the stop time "
                          f"{scenario.t_final:g} s: it will not happen in this run", UserWarning, stacklevel=2)
    tolerance = DEFAULT_ASSEMBLY_TOLERANCE
    section = scenario.document.get("multibody")
    if isinstance(section, dict) and "assembly_tolerance" in section:
        tolerance = float(to_magnitude(section["assembly_tolerance"], "", (), "assembly_tolerance"))
    monitor = SceneEvents(events, {name: (unit, shape) for name, (unit, shape, _) in sources.items()},
                          None if engine is None else engine.name, operations, tolerance)
    monitor.notes = tuple(f"{MODEL_NAME}: {note}" for note in notes)
    root.add(monitor)
    for name, (_, _, signal_where) in sources.items():
        event = next(e for e in events if e.name == name)
        root.connect(event.signal, f"{MODEL_NAME}.{name}", origin=f"{signal_where.file}:{signal_where.line}")


def _source(children, event):
    """(unit, shape, where) of the output port an event watches; refused at its ``signal:`` line when the scene has
    no such port or element, or when a bare number is given for a value with a unit."""
    where = event.signal_where
    model_name, _, port = event.signal.partition(".")
    model = children.get(model_name)
    if model is None or not isinstance(model, Model):
        known = sorted(name for name, m in children.items() if isinstance(m, Model) and name != MODEL_NAME)
        raise where.error(f"no model {model_name!r} at the scene's top level for signal {event.signal!r}; an event "
                          f"watches an output port of one of {known}")
    ports = {p.name: p for p in model.outputs}
    if port not in ports:
        raise where.error(f"model {model_name} has no output port {port!r}" + suggest(port, list(ports)))
    declared = ports[port]
    size = int(np.prod(declared.shape, dtype=int))
    if not 0 <= event.element < size:
        raise where.error(f"{event.signal} has {size} element(s); element {event.element} does not exist")
    crosses_where = event.crosses_where
    if declared.unit and is_bare_number(event.crosses):
        raise crosses_where.error(f"expected a value with its unit ({declared.unit}, or one convertible to it), given "
                                  f"the bare number {show(event.crosses)}")
    try:
        to_magnitude(event.crosses, declared.unit, (), "crosses")
    except UnitError as exc:
        raise crosses_where.error(str(exc)) from None
    return declared.unit, declared.shape, where


def _operation(action, engine, event):
    """(verb, constraint indices or (name, value) pairs, where) of one action, checked against the engine."""
    verb, target, where = action.verb, action.target, action.where
    if verb == "set":
        return "set", [(str(name), value) for name, value in target.items()], where
    if engine is None or engine.constrained is None:
        raise where.error(f"{verb} switches constraints of the multibody engine; the scene has "
                          f"{'no multibody: section' if engine is None else 'no constraints: in multibody:'}")
    system = engine.system
    constraints = engine.constrained.constraints
    labels = [c.label for c in constraints]

    def body(name, here):
        if name not in system.body_names:
            raise here.error(f"unknown body {name!r}; bodies: {list(system.body_names)}"
                             + suggest(name, list(system.body_names)))
        return system.body_index(name)

    def between(b, others):
        """Constraints with one node on body b and the other on a body of ``others`` (-1: the world)."""
        found = []
        for j, c in enumerate(constraints):
            a = system.body_index(system.node_bodies[system.node_index(c.node_a)])
            other = -1 if c.node_b is None else system.body_index(system.node_bodies[system.node_index(c.node_b)])
            if (a == b and other in others) or (other == b and a in others):
                found.append(j)
        return found

    if verb == "constraint":
        key, name = next(iter(target.items()))
        if name not in labels:
            raise where.child(target, key).error(f"unknown constraint {name!r}; constraints: {labels}"
                                                 + suggest(name, labels))
        return key, [labels.index(name)], where
    if verb == "attach":
        b = body(target["body"], where.child(target, "body"))
        to = -1 if target["to"] == "world" else body(target["to"], where.child(target, "to"))
        found = between(b, (to,))
        if not found:
            raise where.error(f"no constraint is declared between {target['body']!r} and {target['to']!r}: declare "
                              f"the latch under multibody: constraints: (e.g. kind: weld, active: false)")
        return verb, found, where
    b = body(target, where)
    if verb == "detach":
        if system.hinge_names[b] != "free":
            raise where.error(f"body {target!r} is on a {system.hinge_names[b]} hinge; a detached body goes on on a "
                              f"free hinge: give it hinge: free and hold it by a weld constraint (which detach "
                              f"switches off), or use unlock: to free its own hinge")
        found = [j for j in range(len(constraints)) if b in _bodies(system, constraints[j])]
        if not found:
            raise where.error(f"no constraint holds body {target!r}; detach switches off the constraints with a node "
                              f"on it (a weld to the body that carries it)")
        return verb, found, where
    parent = system.parents[b]
    found = between(b, (parent,))
    if not found:
        parent_name = "the world" if parent < 0 else repr(system.body_names[parent])
        raise where.error(f"no constraint is declared between body {target!r} and its parent {parent_name}: a {verb} "
                          f"switches those {'on' if verb == 'lock' else 'off'} (declare it under multibody: "
                          f"constraints:{', active: false' if verb == 'lock' else ''})")
    return verb, found, where


def _bodies(system, constraint) -> tuple:
    a = system.body_index(system.node_bodies[system.node_index(constraint.node_a)])
    if constraint.node_b is None:
        return (a,)
    return a, system.body_index(system.node_bodies[system.node_index(constraint.node_b)])


def changes_json(changes) -> str:
    """The scene changes of a run ((time, event, what changed) triples) as the log's ``scene_events`` attribute."""
    return json.dumps([{"time": t, "event": name, "changes": what} for t, name, what in changes])


#: the keys of a body entry that place it on its parent (replaced when it is built on a free hinge)
_MOUNT_KEYS = ("parent", "hinge", "inboard_position", "inboard_rotation", "outboard_position", "outboard_rotation",
               "parent_node", "axis", "axes", "prescribed", "initial")


def free_detached_bodies(description, where, events):
    """The ``multibody:`` section with each body that a ``detach:`` releases and that is written on a ``locked`` hinge
    (a stage stacked on another) built instead on a free hinge from the world, at its initial pose and velocity,
    held to its parent by a weld ``<body>_mount`` between the nodes ``<body>_seat`` (on the parent, at the body's
    frame) and ``<body>_mount`` (the body's frame), which the event switches off: the state keeps its layout through
    the release. Returns (section, notes saying so); the section as written when no such body is released."""
    chosen = {}
    for e in events:
        for a in e.actions:
            if a.verb == "detach" and isinstance(a.target, str):
                chosen.setdefault(a.target, (e.name, a.where))
    bodies = description.get("bodies") if isinstance(description, dict) else None
    if not isinstance(bodies, list):
        return description, ()
    locked = {b["name"]: k for k, b in enumerate(bodies)  # a malformed entry is refused by the section's reader
              if isinstance(b, dict) and isinstance(b.get("name"), str) and b.get("hinge") == "locked"}
    chosen = {name: place for name, place in chosen.items() if name in locked}
    if not chosen:
        return description, ()
    from dynamics.spatial import rotation_to_quaternion
    from shell.schema.document import LineDict, LineList
    from shell.schema.multibody import read_multibody

    written = read_multibody(description, where)
    system = written.system
    rotations, origins = system.body_poses(written.initial_q)
    velocities = system.body_velocities(written.initial_q, written.initial_u)
    section = _like(description, LineDict(description))
    section["bodies"] = _like(bodies, LineList(bodies))
    for key in ("nodes", "constraints"):
        section[key] = _like(description.get(key), LineList(description.get(key) or []))
    taken = {n.get("name") for n in section["nodes"] if isinstance(n, dict)}
    taken |= {c.get("name") for c in section["constraints"] if isinstance(c, dict)}
    notes = []
    for name, (event, here) in chosen.items():
        body = bodies[locked[name]]
        if "body_file" in body or "parent_node" in body:
            raise here.error(f"body {name!r} is {'flexible' if 'body_file' in body else 'on a node of its parent'}: "
                             f"write it on a free hinge held by a weld constraint, which detach switches off")
        mount, seat = f"{name}_mount", f"{name}_seat"
        for label in (mount, seat):
            if label in taken:
                raise here.error(f"detach {name!r} builds the body on a free hinge held by the weld {mount!r} between "
                                 f"nodes {seat!r} and {mount!r}; the scene already has the name {label!r}")
        b = system.body_index(name)
        entry = _like(body, LineDict((k, v) for k, v in body.items() if k not in _MOUNT_KEYS))
        entry.update(parent="world", hinge="free", initial={
            "attitude": rotation_to_quaternion(rotations[b]).tolist(), "position": origins[b].tolist(),
            "angular_velocity": velocities[b, :3].tolist(), "velocity": velocities[b, 3:].tolist()})
        section["bodies"][locked[name]] = entry
        section["nodes"].append({"name": mount, "body": name})
        parent = system.parents[b]
        weld = {"name": mount, "kind": "weld", "node_a": mount}
        if parent >= 0:
            R = rotations[parent].T
            section["nodes"].append({"name": seat, "body": system.body_names[parent],
                                     "position": (R @ (origins[b] - origins[parent])).tolist(),
                                     "rotation": rotation_to_quaternion(R @ rotations[b]).tolist()})
            weld.update(node_a=seat, node_b=mount)
        section["constraints"].append(weld)
        held_by = system.body_names[parent] if parent >= 0 else "the world"
        notes.append(f"body {name} (written on a locked hinge to {held_by}) is built on a free hinge held by the weld "
                     f"{mount}, which event {event} switches off")
    return section, tuple(notes)


def _like(original, copy):
    """``copy`` with the line numbers of ``original`` (a LineDict or LineList of the scenario)."""
    copy.line = getattr(original, "line", 0)
    copy.lines = type(getattr(original, "lines", None) or ({} if isinstance(copy, dict) else []))(
        getattr(original, "lines", None) or ({} if isinstance(copy, dict) else []))
    return copy
