"""The ``events: on:`` list of a scenario: events that change the scene, read and checked key by key.

Each entry names an event, when it happens and what it does (docs/scenario_schema.md, section events)::

    events:
      on:
        - name: separation
          when: {time: 2 s}            # or {signal: multibody.array.q[0], crosses: 90 deg, direction: rising}
          do: [{detach: upper}]

``when:`` is a time (with its unit) or a signal (an output port of a model of the scene, with an optional element
index) crossing a value (with the port's unit) in a direction (rising, falling or either; default either). ``do:``
lists actions, each a mapping with one key: ``lock: BODY``, ``unlock: BODY``, ``detach: BODY``, ``attach: {body: A,
to: B}`` (B a body or ``world``), ``constraint: {add: NAME}`` / ``constraint: {remove: NAME}`` and ``set: {NAME:
VALUE, ...}`` (parameters by name, :mod:`shell.names`). What the actions do to the engine is
:mod:`shell.scene_events`; the names of bodies, constraints, signals and parameters are checked there, when the
scene exists, with the place of the action. Here: the keys, units, directions and the uniqueness of the names.

YAML 1.1 reads the key ``on`` as the boolean true: the section's reader takes that key as ``on``. Inside a flow
mapping ``{...}`` a signal with an index, ``{signal: multibody.array.q[0], ...}``, is read as one text by the
scenario loader (:class:`shell.schema.document.LineLoader`; plain YAML refuses it).
"""

from __future__ import annotations

import re
from dataclasses import dataclass

from shell.schema.document import show, type_name
from shell.schema.validation import Where, expect_list, expect_mapping, expect_name, is_bare_number
from shell.units import UnitError, to_magnitude

EVENT_KEYS = {"name": "event name (its time and threshold are the values events.<name>.time / .crosses)",
              "when": "{time: 2 s} or {signal: model.port[index], crosses: VALUE, direction: rising|falling|either}",
              "do": "list of actions: lock, unlock, detach, attach, constraint, set"}
WHEN_KEYS = {"time": "time of the event, with its unit (e.g. 2 s)",
             "signal": "output port, e.g. multibody.array.q[0]", "crosses": "value crossed, in the port's unit "
             "(e.g. 90 deg)", "direction": "rising, falling or either (default either)"}
ACTIONS = {"lock": "BODY: switch on the constraints declared between BODY and its parent (plastic impact)",
           "unlock": "BODY: switch off the constraints between BODY and its parent",
           "detach": "BODY (on a free hinge): switch off every constraint that holds BODY",
           "attach": "{body: A, to: B or world}: switch on the constraints declared between A and B (plastic impact)",
           "constraint": "{add: NAME} or {remove: NAME}: switch constraint NAME on (plastic impact) or off",
           "set": "{NAME: VALUE, ...}: parameters by name (e.g. controller.kp: 5 N*m/rad)"}
DIRECTIONS = {"rising": 1, "falling": -1, "either": 0}
_SIGNAL = re.compile(r"^([A-Za-z_][\w.]*)(?:\[(\d+)\])?$")


@dataclass(frozen=True)
class Action:
    """One action of an event: ``verb`` (a key of :data:`ACTIONS`), its ``target`` as written, where it is."""

    verb: str
    target: object
    where: Where


@dataclass(frozen=True)
class SceneEvent:
    """One entry of ``events: on:``: a time event (``time`` in s) or a signal crossing (``signal`` the port,
    ``element`` its flat index, ``crosses`` the value as written: converted with the port's unit at build)."""

    name: str
    where: Where
    actions: tuple
    time: float | None = None
    signal: str | None = None
    element: int = 0
    crosses: object = None
    direction: int = 0
    signal_where: Where | None = None
    crosses_where: Where | None = None


def normalize_on_key(spec) -> None:
    """The ``on`` key of the events mapping, read by YAML 1.1 as the boolean true, renamed ``on`` (its line kept)."""
    if isinstance(spec, dict) and True in spec and "on" not in spec:
        lines = getattr(spec, "lines", None)
        spec["on"] = spec.pop(True)
        if isinstance(lines, dict) and True in lines:
            lines["on"] = lines.pop(True)


def read_events_on(entries, where: Where) -> list[SceneEvent]:
    """The checked events of the ``on:`` list (``where`` its place)."""
    entries = expect_list(entries, where, "events ({name, when, do} mappings)")
    events, places = [], {}
    for k, entry in enumerate(entries):
        here = where.child(entries, k)
        expect_mapping(entry, here, EVENT_KEYS, required=("name", "when", "do"))
        name = expect_name(entry["name"], here.child(entry, "name"), "an event name")
        if not re.fullmatch(r"[A-Za-z_]\w*", name):
            raise here.child(entry, "name").error(f"event names use letters, digits and underscores, given {name!r}")
        if name in places:
            raise here.child(entry, "name").error(f"duplicate event name {name!r} (first at {places[name]})")
        places[name] = here.child(entry, "name")
        here = here.named(name)
        events.append(_event(entry, name, here))
    return events


def _event(entry, name: str, here: Where) -> SceneEvent:
    when_where = here.child(entry, "when")
    when = expect_mapping(entry["when"], when_where, WHEN_KEYS)
    actions = _actions(entry["do"], here.child(entry, "do"))
    if ("time" in when) == ("signal" in when):
        raise when_where.error(f"expected either time: (e.g. {{time: 2 s}}) or signal: with crosses: (e.g. {{signal: "
                               f"multibody.array.q[0], crosses: 90 deg}}), given "
                               f"{show(dict(when))}")
    if "time" in when:
        for key in ("crosses", "direction"):
            if key in when:
                raise when_where.child(when, key).error("belongs to a signal event; a time event has time: only")
        t_where = when_where.child(when, "time")
        return SceneEvent(name, here, actions, time=event_time(when["time"], t_where))
    s_where = when_where.child(when, "signal")
    signal = expect_name(when["signal"], s_where, "an output port, e.g. multibody.array.q[0]")
    match = _SIGNAL.fullmatch(signal)
    if match is None or "." not in match.group(1):
        raise s_where.error(f"expected model.port or model.port[index] (e.g. multibody.array.q[0]), given {signal!r}")
    if "crosses" not in when:
        raise when_where.error("missing required key 'crosses' (the value the signal crosses, in its unit)")
    direction = when.get("direction", "either")
    if direction not in DIRECTIONS:
        raise when_where.child(when, "direction").error(f"expected one of {list(DIRECTIONS)}, given {show(direction)}")
    return SceneEvent(name, here, actions, signal=match.group(1), element=int(match.group(2) or 0),
                      crosses=when["crosses"], direction=DIRECTIONS[direction], signal_where=s_where,
                      crosses_where=when_where.child(when, "crosses"))


def event_time(value, where: Where) -> float:
    """An event time in seconds: a value with a unit of time (a bare number is refused: its unit is not known)."""
    if is_bare_number(value):
        raise where.error(f"expected a time with its unit (e.g. 2 s), given the bare number {show(value)}")
    try:
        seconds = float(to_magnitude(value, "s", (), "time"))
    except UnitError as exc:
        raise where.error(f"expected a time, given {show(value)} ({exc})") from None
    if not seconds == seconds or abs(seconds) == float("inf") or seconds <= 0.0:
        raise where.error(f"expected a finite time after the start (> 0 s), given {show(value)}: a change at the start "
                          f"is the scene as written")
    return seconds


def _actions(items, where: Where) -> tuple:
    items = expect_list(items, where, "actions (mappings with one key each)")
    if not items:
        raise where.error(f"expected at least one action; actions: {', '.join(ACTIONS)}")
    actions = []
    for k, item in enumerate(items):
        here = where.child(items, k)
        if not isinstance(item, dict) or len(item) != 1:
            raise here.error(f"expected a mapping with one action key ({', '.join(ACTIONS)}), given "
                             f"{type_name(item)} {show(item)}")
        expect_mapping(item, here, ACTIONS)
        verb, target = next(iter(item.items()))
        there = here.child(item, verb)
        if verb in ("lock", "unlock", "detach"):
            expect_name(target, there, "a body name")
        elif verb == "attach":
            expect_mapping(target, there, {"body": "the body that is latched", "to": "a body, or world"},
                           required=("body", "to"))
            for key in ("body", "to"):
                expect_name(target[key], there.child(target, key), "a body name")
        elif verb == "constraint":
            if isinstance(target, dict) and (True in target or False in target):
                raise there.error("expected add: NAME or remove: NAME (YAML reads the keys on and off as true and "
                                  "false)")
            expect_mapping(target, there, {"add": "constraint switched on (plastic impact)",
                                           "remove": "constraint switched off"})
            if len(target) != 1:
                raise there.error(f"expected one of add: NAME or remove: NAME, given {show(dict(target))}")
            key = next(iter(target))
            expect_name(target[key], there.child(target, key), "a constraint name")
        elif verb == "set":
            if not isinstance(target, dict) or not target:
                raise there.error(f"expected a mapping of parameter name -> value, given {type_name(target)} "
                                  f"{show(target)}")
        actions.append(Action(verb, target, there))
    return tuple(actions)


def set_event_value(section, event: str, key: str, value, where: Where) -> None:
    """``--set events.<event>.time=...`` or ``.crosses=...``: the value into that event's ``when:`` (a Monte Carlo
    dispersion of an event time or threshold takes this path)."""
    normalize_on_key(section)
    entries = section.get("on") if isinstance(section, dict) else None
    names = [e.get("name") for e in entries if isinstance(e, dict)] if isinstance(entries, list) else []
    if event not in names:
        raise where.error(f"no event named {event!r} in events: on: (events: {names})")
    if key not in ("time", "crosses"):
        raise where.error(f"an event's value is events.{event}.time or events.{event}.crosses, given {key!r}")
    entry = entries[names.index(event)]
    when = entry.get("when")
    if not isinstance(when, dict) or key not in when:
        other = "crosses" if key == "time" else "time"
        raise where.error(f"event {event!r} has no {key}: (it is a {'signal' if other == 'crosses' else 'time'} "
                          f"event: give events.{event}.{other})")
    when[key] = value
