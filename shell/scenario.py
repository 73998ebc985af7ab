"""Building the scene of a YAML scenario: its models, assemblies and connections, and the Simulation.

A scenario is read and validated by the schema package (:func:`load_scenario`, :func:`parse_scenario`;
:mod:`shell.schema`, written for users in docs/scenario_schema.md); this module instantiates what it
describes: :func:`build_root` makes the root :class:`shell.assembly.Assembly` (the engine model of the
``multibody:`` section, the models and the assembly types of the ``assemblies:`` section, attachments and
connections), :func:`build_simulation` the :class:`shell.simulation.Simulation` with its log. Errors of a
model's constructor are pointed at the parameter line they concern.

The names users and tools import from here (README): ``load_scenario``, ``parse_scenario``,
``build_simulation``, ``build_root``, ``ScenarioError``.
"""

from __future__ import annotations

import numpy as np

from shell.assembly import Assembly
from shell.diagnostics import located
from shell.model import Model, ModelError
from shell.models.multibody import MultibodyModel
from shell.registry import lookup
from shell.schema import Scenario, ScenarioError, Where, connection_ends, find, show
# the schema's names that users and the commands import from here (README: load_scenario)
from shell.schema import (apply_override, apply_value, check_sample_counts, check_time, decode_scenario,  # noqa: F401
                          load_scenario, load_yaml, parse_scenario)
from shell.schema.multibody import read_multibody
from shell.scene_events import add_scene_events, free_detached_bodies
from shell.simulation import Simulation
from shell.units import UnitError, written_numbers


def build_root(scenario: Scenario) -> Assembly:
    """Instantiate the scenario's models and connections into a root assembly."""
    document = scenario.document
    root_where = Where(scenario.file, 1, "")
    root = Assembly("scenario")
    notes = ()
    if "multibody" in document:
        where = root_where.child(document, "multibody")
        try:
            description, notes = free_detached_bodies(document["multibody"], where, scenario.scene_events)
            section = read_multibody(description, where)
            root.add(MultibodyModel(section.name, section.system, initial_q=section.initial_q,
                                    initial_u=section.initial_u, written_q=section.written_q,
                                    constrained=section.constrained, assembly=section.assembly,
                                    outputs=section.outputs))
        except (ModelError, UnitError, ValueError) as exc:
            if isinstance(exc, ScenarioError):
                raise
            raise where.error(str(exc)) from None
    classes = {name: _assembly_class(name, spec, here, scenario) for name, (spec, here) in scenario.templates.items()}
    scenario.template_classes = classes
    _add_members(root, document, root_where, classes)
    add_scene_events(root, scenario, notes)
    return root


def _add_members(container: Assembly, section: dict, where: Where, classes: dict) -> None:
    """Construct the models of ``section['models']`` into ``container`` and add its connections
    (the top-level scene, or an assembly type defined in the assemblies: section)."""
    models = section.get("models", {}) or {}
    models_where = where.child(section, "models")
    for name, entry in models.items():
        here = models_where.child(models, name)
        member = build_member(container, name, entry, here, classes)
        if name in container.children:
            raise here.error(f"the name {name!r} is taken (the multibody engine model is named {name!r})")
        container.add(member)
        if "attach" in entry:
            attach = entry["attach"]
            try:
                attach_where = here.child(entry, "attach")
                container.attach(name, engine=attach.get("engine", "multibody"), node=attach.get("node"),
                                 hinge=attach.get("hinge"), origin=f"{attach_where.file}:{attach_where.line}")
            except ModelError as exc:
                raise here.child(entry, "attach").error(str(exc)) from None
    connections = section.get("connections", []) or []
    where = where.child(section, "connections")
    for k, item in enumerate(connections):
        here = where.child(connections, k)
        source, destination = connection_ends(item, here)
        container.connect(source, destination, origin=f"{here.file}:{here.line}")


def build_member(container: Assembly, name: str, entry: dict, here: Where, classes: dict):
    """One model or assembly of a models: section, constructed from its entry (type, config, parameters,
    rate/period/offset, initial); ``container`` gives parent assembly parameters. Monte Carlo runs call it
    again with an entry carrying a run's dispersed values."""
    cls = classes.get(entry["type"]) or lookup(entry["type"])
    kwargs = dict(entry.get("config", {}) or {})
    kwargs.update(entry.get("parameters", {}) or {})
    kwargs = container.child_parameters(name, **kwargs)
    for key in ("rate", "period"):
        if key in entry:
            kwargs["period"] = entry[key]
    if "offset" in entry:
        kwargs["offset"] = entry["offset"]
    try:
        with located(here):  # a constructor's warnings, with the model's file, line and key
            member = cls(name, **kwargs)
    except ScenarioError as exc:  # inside an assembly type: also say where it is used
        raise ScenarioError(f"{exc}\n  in {entry['type']} {name!r} used at {here.file}:{here.line}") from None
    except (ModelError, UnitError) as exc:
        raise _locate_error(here, entry, exc) from None
    except TypeError as exc:
        raise here.error(f"cannot construct {entry['type']}: {exc}") from None
    except (AttributeError, KeyError, IndexError, ValueError, OverflowError, ZeroDivisionError) as exc:
        # a configuration value of the wrong kind that the model's constructor did not check itself
        raise here.error(f"cannot construct {entry['type']} from these values: {type(exc).__name__}: "
                         f"{show(str(exc))}") from None
    for state, value in (entry.get("initial", {}) or {}).items():
        if not isinstance(member, Model):
            raise here.child(entry, "initial").error("initial values are set on models, not assemblies")
        state_where = here.child(entry, "initial").child(entry["initial"], state)
        try:
            member.set_initial(state, value)
            values = (member.initial_continuous_state(), member.initial_discrete_state())
        except (ModelError, UnitError) as exc:
            raise state_where.error(str(exc)) from None
        if not all(np.all(np.isfinite(np.asarray(v, dtype=float))) for v in values):
            raise state_where.error(f"expected finite initial values, given {show(value)}")
    return member


def _assembly_class(name: str, spec: dict, where: Where, scenario: Scenario) -> type:
    """An Assembly subclass built from an assemblies: entry (members, connections, exposed ports)."""

    def build(self) -> None:
        _add_members(self, spec, where, scenario.template_classes)
        for port, inner in (spec.get("inputs", {}) or {}).items():
            self.expose_input(port, *(inner if isinstance(inner, list) else [inner]))
        for port, inner in (spec.get("outputs", {}) or {}).items():
            self.expose_output(port, inner)

    summary = spec.get("description") or f"assembly defined in {where.file}:{where.line}"
    return type(name, (Assembly,), {"build": build, "summary": summary, "__module__": __name__})


def _locate_error(here: Where, entry: dict, exc: Exception) -> ScenarioError:
    """Point an error from a model constructor at the parameter or config line it concerns, if any."""
    message = str(exc)
    params = entry.get("parameters", {}) or {}
    unknown_part = message.split("known:")[0] if "unknown parameter" in message else ""
    for key in params:
        if f"parameter {key}:" in message or f"'{key}'" in unknown_part:
            return here.child(entry, "parameters").child(params, key).error(message)
    config = entry.get("config", {}) or {}
    for key in config:
        if f"config {key}:" in message:
            return here.child(entry, "config").child(config, key).error(message)
    return here.error(message)


def build_simulation(scenario: Scenario):
    """The :class:`shell.simulation.Simulation` of a validated scenario, with its log configured."""
    root = build_root(scenario)
    try:
        with located(lambda text: _model_location(scenario, text)):  # configure()'s warnings, located
            simulation = Simulation.of_scenario(scenario, root)
    except (ModelError, UnitError) as exc:
        message = str(exc)
        raise ScenarioError(message if message.startswith(scenario.file) else f"{scenario.file}: {message}") from None
    _check_initial_state(simulation, scenario)
    return simulation


def _model_location(scenario: Scenario, message: str) -> str:
    """Where the model a message names (``model controller.kp: ...``) is in the scenario: its entry under
    models:, else the file."""
    path = message[len("model "):].split(":", 1)[0] if message.startswith("model ") else ""
    models = scenario.document.get("models")
    top = path.split(".", 1)[0]
    return scenario.location("models", top) if isinstance(models, dict) and top in models else scenario.file


def _check_initial_state(simulation, scenario: Scenario) -> None:
    """Refuse a scene whose initial state is not finite (a NaN rate, an infinite angle), naming the model."""
    for model in simulation.models:
        for name, (kind, sl, _) in ((n, v) for (m, n), v in simulation.state_slices.items() if m == model.path):
            values = (simulation.x if kind == "x" else simulation.z)[sl]
            if not np.all(np.isfinite(values)):
                keys = ("multibody",) if model.path == "multibody" else ("models", model.path, "initial")
                where = _nonfinite_body_initial(scenario) or find(scenario.document, scenario.file, keys)
                raise where.error(f"initial state {model.path}.{name} is not finite: {show(values.tolist())}")


def _nonfinite_body_initial(scenario: Scenario) -> Where | None:
    """The multibody.bodies[i](name).initial.<key> whose value, as written, is not finite (if one is)."""
    document = scenario.document
    multibody = document.get("multibody")
    bodies = multibody.get("bodies") if isinstance(multibody, dict) else None
    if not isinstance(bodies, list):
        return None
    where = Where(scenario.file, 1, "").child(document, "multibody").child(multibody, "bodies")
    for k, body in enumerate(bodies):
        initial = body.get("initial") if isinstance(body, dict) else None
        if not isinstance(initial, dict):
            continue
        for key, value in initial.items():
            try:
                finite = np.all(np.isfinite(written_numbers(value)))
            except UnitError:
                continue
            if not finite:
                here = where.child(bodies, k, f"[{k}]({body.get('name')})")
                return here.child(body, "initial").child(initial, key)
    return None
