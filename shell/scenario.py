"""YAML scenarios: loading with line numbers, schema validation, overrides, and building a Simulation.

A scenario file describes one scene (schema: docs/scenario_schema.md)::

    name, description, seed
    multibody:   gravity, bodies (name, parent, hinge, mass, com, inertia, ..., initial), nodes
    models:      <name>: {type, parameters, config, rate|period, offset, initial, attach}
    connections: ["a.port -> b.port", {from: a.port, to: b.port}, ...]
    integrator:  {method, step, options}
    stop:        {time, events}
    log:         {rate, signals: [name | {signal, rate}], file}

Every refusal names the file, the line, the key path, what was expected and what was given. Values
may carry units ("5 deg/s", "[1, 2, 3] N*m"); they are converted once, when the scene is built.
Command-line overrides ``--set key.path=value`` are applied to the loaded document before
validation: ``seed=7``, ``integrator.step=5 ms``, ``stop.time=30 s``, ``<model>.<parameter>=value``,
``<model>.rate=20 Hz``, ``multibody.<body>.<key>=value``.
"""

from __future__ import annotations

import difflib
from dataclasses import dataclass, field
from pathlib import Path

import networkx as nx
import yaml

from shell.assembly import Assembly
from shell.model import Model, ModelError, parse_period
from shell.registry import RegistryError, lookup
from shell.units import UnitError, to_magnitude


class ScenarioError(ValueError):
    """An invalid scenario; the message starts with ``file:line: key.path:``."""


class LineDict(dict):
    """A mapping that remembers the line of itself and of each key (1-based)."""

    line = 0
    lines: dict


class LineList(list):
    """A sequence that remembers the line of itself and of each item (1-based)."""

    line = 0
    lines: list


class _LineLoader(yaml.SafeLoader):
    """SafeLoader producing LineDict/LineList, refusing duplicate keys."""


def _construct_mapping(loader: _LineLoader, node: yaml.MappingNode) -> LineDict:
    loader.flatten_mapping(node)
    mapping = LineDict()
    mapping.line = node.start_mark.line + 1
    mapping.lines = {}
    for key_node, value_node in node.value:
        key = loader.construct_object(key_node, deep=True)
        line = key_node.start_mark.line + 1
        if key in mapping:
            raise ScenarioError(f"{loader.name}:{line}: duplicate key {key!r} (first on line {mapping.lines[key]})")
        mapping[key] = loader.construct_object(value_node, deep=True)
        mapping.lines[key] = line
    return mapping


def _construct_sequence(loader: _LineLoader, node: yaml.SequenceNode) -> LineList:
    sequence = LineList(loader.construct_object(child, deep=True) for child in node.value)
    sequence.line = node.start_mark.line + 1
    sequence.lines = [child.start_mark.line + 1 for child in node.value]
    return sequence


_LineLoader.add_constructor(yaml.resolver.BaseResolver.DEFAULT_MAPPING_TAG, _construct_mapping)
_LineLoader.add_constructor(yaml.resolver.BaseResolver.DEFAULT_SEQUENCE_TAG, _construct_sequence)


def load_yaml(text: str, filename: str = "<string>"):
    loader = _LineLoader(text)
    loader.name = filename
    try:
        return loader.get_single_data()
    except yaml.MarkedYAMLError as exc:
        mark = exc.problem_mark
        line = mark.line + 1 if mark is not None else 0
        raise ScenarioError(f"{filename}:{line}: not valid YAML: {exc.problem}") from None
    finally:
        loader.dispose()


# ------------------------------------------------------------------------------------------------
@dataclass
class _Where:
    """A location in the scenario: file, line and dotted key path."""

    file: str
    line: int
    key: str

    def __str__(self) -> str:
        return f"{self.file}:{self.line}: {self.key}"

    def child(self, container, key, path_part=None) -> "_Where":
        line = self.line
        lines = getattr(container, "lines", None)
        if isinstance(container, LineDict) and key in lines:
            line = lines[key]
        elif isinstance(container, LineList) and isinstance(key, int) and key < len(lines):
            line = lines[key]
        part = path_part if path_part is not None else (f"[{key}]" if isinstance(key, int) else str(key))
        joined = f"{self.key}{part}" if part.startswith("[") or not self.key else f"{self.key}.{part}"
        return type(self)(self.file, line, joined)

    def error(self, message: str) -> ScenarioError:
        return ScenarioError(f"{self}: {message}")


def _type_name(value) -> str:
    return {dict: "mapping", LineDict: "mapping", list: "list", LineList: "list", str: "text", int: "integer",
            float: "number", bool: "boolean", type(None): "nothing"}.get(type(value), type(value).__name__)


def _expect_mapping(value, where: _Where, allowed: dict[str, str], required=()) -> dict:
    """Check a mapping's keys; ``allowed`` maps key -> short description used in messages."""
    if not isinstance(value, dict):
        raise where.error(f"expected a mapping with keys {sorted(allowed)}, given {_type_name(value)} {value!r}")
    for key in value:
        if key not in allowed:
            close = difflib.get_close_matches(str(key), list(allowed), n=1)
            hint = f" (did you mean {close[0]!r}?)" if close else ""
            raise where.child(value, key).error(f"unknown key {key!r}{hint}; expected one of {sorted(allowed)}")
    for key in required:
        if key not in value:
            raise where.error(f"missing required key {key!r} ({allowed[key]})")
    return value


def _expect_list(value, where: _Where, what: str) -> list:
    if not isinstance(value, list):
        raise where.error(f"expected a list of {what}, given {_type_name(value)} {value!r}")
    return value


def _expect_name(value, where: _Where, what: str) -> str:
    if not isinstance(value, str) or not value:
        raise where.error(f"expected {what} (text), given {_type_name(value)} {value!r}")
    return value


# ------------------------------------------------------------------------------------------------
TOP_LEVEL = {
    "name": "scenario name", "description": "free text", "seed": "integer (or list of integers)",
    "multibody": "bodies, hinges and nodes of the multibody engine", "models": "component models by name",
    "assemblies": "reusable assembly types defined in this file",
    "connections": "list of 'source.port -> destination.port'", "integrator": "method and step",
    "stop": "stop time and stop events", "log": "logged signals and rates",
    "events": "zero-crossing search: detection (sign_change | subdivided), tolerance",
}
MODEL_KEYS = {
    "type": "registered model or assembly type", "parameters": "parameter values (with units)",
    "config": "construction options (e.g. unit, shape)", "rate": "sample rate, e.g. 10 Hz",
    "period": "sample period, e.g. 0.1 s", "offset": "first sample time, e.g. 0 s",
    "initial": "initial values of states", "attach": "{node: NAME} or {hinge: BODY} of the engine",
    "description": "free text",
}


@dataclass
class Scenario:
    """A validated scenario, ready to build."""

    file: str
    document: dict
    text: str
    seed: object = 0
    integrator: str = "rk4"
    step: float | None = 0.01
    integrator_options: dict = field(default_factory=dict)
    t_final: float | None = None
    stop_events: list = field(default_factory=list)
    event_detection: str = "subdivided"
    event_tolerance: float = 1e-10
    log_rate: object = None
    log_signals: list = field(default_factory=list)  # (name, rate)
    log_file: str | None = None
    templates: dict = field(default_factory=dict)  # assemblies: section, name -> (spec, where)
    template_classes: dict = field(default_factory=dict)  # the Assembly subclasses built from them

    @property
    def name(self) -> str:
        return str(self.document.get("name", Path(self.file).stem))


def load_scenario(path, overrides: list[str] | None = None) -> Scenario:
    """Read, override and validate a scenario file (the scene is built by :func:`build_simulation`)."""
    path = str(path)
    try:
        text = Path(path).read_text()
    except OSError as exc:
        raise ScenarioError(f"{path}: cannot read the scenario ({exc.strerror})") from None
    return parse_scenario(text, path, overrides)


def parse_scenario(text: str, filename: str = "<string>", overrides: list[str] | None = None) -> Scenario:
    document = load_yaml(text, filename)
    if document is None:
        document = LineDict()
        document.lines = {}
    root = _Where(filename, 1, "")
    if not isinstance(document, dict):
        raise root.error(f"expected a mapping at the top level (keys {sorted(TOP_LEVEL)}), given {_type_name(document)}")
    for override in overrides or []:
        apply_override(document, override, filename)
    _expect_mapping(document, _Where(filename, document.line or 1, ""), TOP_LEVEL)
    scenario = Scenario(file=filename, document=document, text=text)
    _validate_seed(document, root, scenario)
    scenario.templates = _validate_assemblies(document, root)
    _validate_models(document, root, scenario.templates)
    _validate_connections(document, root)
    _validate_integrator(document, root, scenario)
    _validate_stop(document, root, scenario)
    _validate_events(document, root, scenario)
    _validate_log(document, root, scenario)
    return scenario


def _validate_seed(document, root: _Where, scenario: Scenario) -> None:
    if "seed" not in document:
        return
    seed = document["seed"]
    ok = (isinstance(seed, int) and not isinstance(seed, bool) and seed >= 0) or (
        isinstance(seed, list) and seed and all(isinstance(s, int) and not isinstance(s, bool) and s >= 0 for s in seed))
    if not ok:
        raise root.child(document, "seed").error(f"expected a non-negative integer or list of them, given {seed!r}")
    scenario.seed = list(seed) if isinstance(seed, list) else seed


ASSEMBLY_KEYS = {
    "description": "free text", "models": "member models and assemblies (as under models:)",
    "connections": "connections between members", "inputs": "exposed input -> member input(s)",
    "outputs": "exposed output -> member output",
}


def _validate_assemblies(document, root: _Where) -> dict:
    """Check the assemblies: section; returns {type name: (spec, where)}."""
    if "assemblies" not in document:
        return {}
    where = root.child(document, "assemblies")
    section = document["assemblies"]
    if not isinstance(section, dict):
        raise where.error(f"expected a mapping of assembly type -> definition, given {_type_name(section)}")
    templates = {}
    for name, spec in section.items():
        here = where.child(section, name)
        if not isinstance(name, str) or not name.replace("_", "a").isalnum():
            raise here.error(f"assembly type names use letters, digits and underscores, given {name!r}")
        try:
            lookup(name)
        except RegistryError:
            pass
        else:
            raise here.error(f"{name!r} is already a registered model type; choose another name")
        _expect_mapping(spec, here, ASSEMBLY_KEYS, required=("models",))
        templates[name] = (spec, here)
    graph = nx.DiGraph()
    for name, (spec, here) in templates.items():
        _validate_models(spec, here, templates, inside=name)
        if "connections" in spec:
            _validate_connections(spec, here)
        for key in ("inputs", "outputs"):
            exposed = spec.get(key, {}) or {}
            if not isinstance(exposed, dict):
                raise here.child(spec, key).error(f"expected a mapping of exposed name -> member port, given {exposed!r}")
            for port, inner in exposed.items():
                targets = inner if key == "inputs" and isinstance(inner, list) else [inner]
                for target in targets:
                    if not isinstance(target, str) or "." not in target:
                        raise here.child(spec, key).child(exposed, port).error(
                            f"expected member.port{' or a list of them' if key == 'inputs' else ''}, given {inner!r}")
        for member in (spec.get("models") or {}).values():
            if member["type"] in templates:
                graph.add_edge(name, member["type"])
    try:
        cycle = nx.find_cycle(graph)
    except nx.NetworkXNoCycle:
        return templates
    raise where.error(f"assemblies contain themselves: {' -> '.join(a for a, _ in cycle)} -> {cycle[0][0]}")


def _validate_models(document, root: _Where, templates: dict, inside: str | None = None) -> None:
    models = document.get("models", {})
    where = root.child(document, "models")
    if not isinstance(models, dict):
        raise where.error(f"expected a mapping of model name -> model entry, given {_type_name(models)}")
    for name, entry in models.items():
        here = where.child(models, name)
        if not isinstance(name, str) or not name.replace("_", "a").isalnum():
            raise here.error(f"model names use letters, digits and underscores, given {name!r}")
        _expect_mapping(entry, here, MODEL_KEYS, required=("type",))
        type_name = _expect_name(entry["type"], here.child(entry, "type"), "a model type")
        if inside is not None and "attach" in entry:
            raise here.child(entry, "attach").error(f"attach the assembly {inside!r} where it is used (under the "
                                                    "top-level models:), not its members")
        if type_name in templates:
            cls = Assembly
        else:
            try:
                cls = lookup(type_name)
            except RegistryError as exc:
                raise here.child(entry, "type").error(str(exc)) from None
        section = getattr(cls, "scenario_section", None)
        if section:
            raise here.child(entry, "type").error(f"{type_name} is declared in the {section}: section, "
                                                  "not under models:")
        for key in ("parameters", "config", "initial"):
            if key in entry and not isinstance(entry[key], dict):
                raise here.child(entry, key).error(f"expected a mapping, given {_type_name(entry[key])} {entry[key]!r}")
        if "rate" in entry and "period" in entry:
            raise here.child(entry, "period").error("give either rate or period, not both")
        for key in ("rate", "period"):
            if key in entry:
                try:
                    parse_period(entry[key], key)
                except (ModelError, UnitError) as exc:
                    raise here.child(entry, key).error(f"expected a {'frequency (e.g. 10 Hz)' if key == 'rate' else 'time (e.g. 0.1 s)'}, "
                                                       f"given {entry[key]!r} ({exc})") from None
        if "attach" in entry:
            attach = _expect_mapping(entry["attach"], here.child(entry, "attach"),
                                     {"node": "node name", "hinge": "body whose hinge", "engine": "engine model name"})
            if ("node" in attach) == ("hinge" in attach):
                raise here.child(entry, "attach").error(f"expected exactly one of node: or hinge:, given {dict(attach)}")


def _connection_ends(item, where: _Where) -> tuple[str, str]:
    if isinstance(item, str):
        parts = [p.strip() for p in item.split("->")]
        if len(parts) != 2 or not all(parts):
            raise where.error(f"expected 'source.port -> destination.port', given {item!r}")
        return parts[0], parts[1]
    if isinstance(item, dict):
        _expect_mapping(item, where, {"from": "source model.port", "to": "destination model.port"}, required=("from", "to"))
        return (_expect_name(item["from"], where.child(item, "from"), "a source model.port"),
                _expect_name(item["to"], where.child(item, "to"), "a destination model.port"))
    raise where.error(f"expected 'source.port -> destination.port' or {{from:, to:}}, given {_type_name(item)} {item!r}")


def _validate_connections(document, root: _Where) -> None:
    if "connections" not in document:
        return
    where = root.child(document, "connections")
    connections = _expect_list(document["connections"], where, "connections")
    for k, item in enumerate(connections):
        here = where.child(connections, k)
        for end in _connection_ends(item, here):
            if "." not in end:
                raise here.error(f"expected model.port, given {end!r}")


def _validate_integrator(document, root: _Where, scenario: Scenario) -> None:
    from shell.integrators import INTEGRATORS

    if "integrator" not in document:
        return
    where = root.child(document, "integrator")
    spec = _expect_mapping(document["integrator"], where, {"method": f"one of {sorted(INTEGRATORS)}",
                                                           "step": "time step, e.g. 10 ms",
                                                           "options": "rtol, atol, max_step"})
    if "method" in spec:
        method = spec["method"]
        if method not in INTEGRATORS:
            raise where.child(spec, "method").error(f"expected one of {sorted(INTEGRATORS)}, given {method!r}")
        scenario.integrator = method
    if "step" in spec:
        try:
            step = float(to_magnitude(spec["step"], "s", (), "step"))
        except UnitError as exc:
            raise where.child(spec, "step").error(f"expected a time, given {spec['step']!r} ({exc})") from None
        if not step > 0:
            raise where.child(spec, "step").error(f"expected a positive time, given {spec['step']!r}")
        scenario.step = step
    options = spec.get("options", {})
    if not isinstance(options, dict):
        raise where.child(spec, "options").error(f"expected a mapping, given {options!r}")
    for key, value in options.items():
        if key not in ("rtol", "atol", "max_step"):
            raise where.child(spec, "options").child(options, key).error(
                f"unknown integrator option; expected rtol, atol or max_step")
        unit = "s" if key == "max_step" else ""
        try:
            scenario.integrator_options[key] = float(to_magnitude(value, unit, (), key))
        except UnitError as exc:
            raise where.child(spec, "options").child(options, key).error(str(exc)) from None


def _validate_stop(document, root: _Where, scenario: Scenario) -> None:
    if "stop" not in document:
        return
    where = root.child(document, "stop")
    spec = _expect_mapping(document["stop"], where, {"time": "stop time, e.g. 20 s",
                                                     "events": "list of model.zero_crossing names"})
    if "time" in spec:
        try:
            scenario.t_final = float(to_magnitude(spec["time"], "s", (), "time"))
        except UnitError as exc:
            raise where.child(spec, "time").error(f"expected a time, given {spec['time']!r} ({exc})") from None
        if scenario.t_final <= 0:
            raise where.child(spec, "time").error(f"expected a positive time, given {spec['time']!r}")
    if "events" in spec:
        events = _expect_list(spec["events"], where.child(spec, "events"), "model.zero_crossing names")
        for k, name in enumerate(events):
            _expect_name(name, where.child(spec, "events").child(events, k), "model.zero_crossing")
        scenario.stop_events = list(events)


def _validate_events(document, root: _Where, scenario: Scenario) -> None:
    if "events" not in document:
        return
    where = root.child(document, "events")
    spec = _expect_mapping(document["events"], where, {
        "detection": "subdivided (default: search every step, also two crossings inside one step) or "
                     "sign_change (search a step only when a function changes sign between its ends; cheaper)",
        "tolerance": "time tolerance of located crossings, e.g. 1e-10 s"})
    if "detection" in spec:
        if spec["detection"] not in ("sign_change", "subdivided"):
            raise where.child(spec, "detection").error(f"expected sign_change or subdivided, given {spec['detection']!r}")
        scenario.event_detection = spec["detection"]
    if "tolerance" in spec:
        try:
            scenario.event_tolerance = float(to_magnitude(spec["tolerance"], "s", (), "tolerance"))
        except UnitError as exc:
            raise where.child(spec, "tolerance").error(f"expected a time, given {spec['tolerance']!r} ({exc})") from None
        if not scenario.event_tolerance > 0:
            raise where.child(spec, "tolerance").error(f"expected a positive time, given {spec['tolerance']!r}")


def _validate_log(document, root: _Where, scenario: Scenario) -> None:
    if "log" not in document:
        return
    where = root.child(document, "log")
    spec = _expect_mapping(document["log"], where, {"rate": "default log rate, e.g. 10 Hz",
                                                    "signals": "list of model.port names",
                                                    "file": "default log file (HDF5)"})
    scenario.log_rate = spec.get("rate", "100 Hz")
    try:
        parse_period(scenario.log_rate, "rate")
    except (ModelError, UnitError) as exc:
        raise where.child(spec, "rate").error(f"expected a rate such as 10 Hz, given {scenario.log_rate!r} ({exc})") from None
    signals = _expect_list(spec.get("signals", []), where.child(spec, "signals"), "signal names")
    for k, item in enumerate(signals):
        here = where.child(spec, "signals").child(signals, k)
        if isinstance(item, str):
            scenario.log_signals.append((item, scenario.log_rate, here))
        else:
            _expect_mapping(item, here, {"signal": "model.port", "rate": "log rate"}, required=("signal",))
            rate = item.get("rate", scenario.log_rate)
            try:
                parse_period(rate, "rate")
            except (ModelError, UnitError) as exc:
                raise here.child(item, "rate").error(f"expected a rate, given {rate!r} ({exc})") from None
            scenario.log_signals.append((_expect_name(item["signal"], here.child(item, "signal"), "model.port"),
                                         rate, here))
    if "file" in spec:
        scenario.log_file = _expect_name(spec["file"], where.child(spec, "file"), "a file name")


# ------------------------------------------------------------------------------------------------
def apply_override(document: dict, assignment: str, filename: str) -> None:
    """Apply ``key.path=value`` (value parsed as YAML) to the loaded document."""
    where = _Where(filename, 0, f"--set {assignment}")
    if "=" not in assignment:
        raise where.error("expected key.path=value")
    key, raw = assignment.split("=", 1)
    parts = [p for p in key.strip().split(".") if p]
    if not parts:
        raise where.error("expected key.path=value")
    try:
        value = yaml.safe_load(raw) if raw.strip() else ""
    except yaml.YAMLError:  # "[1, 2] N*m/rad": a list with a unit, read by the unit parser later
        value = raw.strip()
    models = document.get("models") or {}
    if parts[0] in ("seed", "name", "description") and len(parts) == 1:
        document[parts[0]] = value
    elif parts[0] in ("integrator", "stop", "log", "events"):
        section = document.setdefault(parts[0], LineDict())
        if not isinstance(section, dict):
            raise where.error(f"section {parts[0]} is not a mapping")
        _set_nested(section, parts[1:], value, where)
    elif parts[0] == "multibody" and "multibody" in document and len(parts) >= 3:
        bodies = document["multibody"].get("bodies", []) or []
        nodes = document["multibody"].get("nodes", []) or []
        for item in list(bodies) + list(nodes):
            if isinstance(item, dict) and item.get("name") == parts[1]:
                _set_nested(item, parts[2:], value, where)
                return
        raise where.error(f"no body or node named {parts[1]!r} in multibody")
    elif parts[0] in models and len(parts) >= 2:
        entry = models[parts[0]]
        if parts[1] in ("rate", "period", "offset", "type") and len(parts) == 2:
            entry[parts[1]] = value
            if parts[1] == "rate":
                entry.pop("period", None)
            if parts[1] == "period":
                entry.pop("rate", None)
        elif parts[1] in ("parameters", "config", "initial"):
            _set_nested(entry.setdefault(parts[1], LineDict()), parts[2:], value, where)
        else:
            params = entry.setdefault("parameters", LineDict())
            params[".".join(parts[1:])] = value
    else:
        known = sorted(set(models) | {"seed", "integrator", "stop", "log", "events", "multibody"})
        raise where.error(f"{parts[0]!r} is neither a model nor a scenario section; known: {known}")


def _set_nested(mapping: dict, parts: list[str], value, where: _Where) -> None:
    if not parts:
        raise where.error("expected a key after the section name")
    for part in parts[:-1]:
        mapping = mapping.setdefault(part, LineDict())
        if not isinstance(mapping, dict):
            raise where.error(f"{part!r} is not a mapping")
    mapping[parts[-1]] = value


# ------------------------------------------------------------------------------------------------
def build_root(scenario: Scenario) -> Assembly:
    """Instantiate the scenario's models and connections into a root assembly."""
    document = scenario.document
    root_where = _Where(scenario.file, 1, "")
    root = Assembly("scenario")
    if "multibody" in document:
        from shell.models.multibody import MultibodyModel

        where = root_where.child(document, "multibody")
        try:
            root.add(MultibodyModel.from_description(document["multibody"], where))
        except (ModelError, UnitError, ValueError) as exc:
            if isinstance(exc, ScenarioError):
                raise
            raise where.error(str(exc)) from None
    classes = {name: _assembly_class(name, spec, here, scenario) for name, (spec, here) in scenario.templates.items()}
    scenario.template_classes = classes
    _add_members(root, document, root_where, classes)
    return root


def _add_members(container: Assembly, section: dict, where: _Where, classes: dict) -> None:
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
        source, destination = _connection_ends(item, here)
        container.connect(source, destination, origin=f"{here.file}:{here.line}")


def build_member(container: Assembly, name: str, entry: dict, here: _Where, classes: dict):
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
        member = cls(name, **kwargs)
    except ScenarioError as exc:  # inside an assembly type: also say where it is used
        raise ScenarioError(f"{exc}\n  in {entry['type']} {name!r} used at {here.file}:{here.line}") from None
    except (ModelError, UnitError) as exc:
        raise _locate_error(here, entry, exc) from None
    except TypeError as exc:
        raise here.error(f"cannot construct {entry['type']}: {exc}") from None
    for state, value in (entry.get("initial", {}) or {}).items():
        if not isinstance(member, Model):
            raise here.child(entry, "initial").error("initial values are set on models, not assemblies")
        try:
            member.set_initial(state, value)
            member.initial_continuous_state()
            member.initial_discrete_state()
        except (ModelError, UnitError) as exc:
            raise here.child(entry, "initial").child(entry["initial"], state).error(str(exc)) from None
    return member


def _assembly_class(name: str, spec: dict, where: _Where, scenario: Scenario) -> type:
    """An Assembly subclass built from an assemblies: entry (members, connections, exposed ports)."""

    def build(self) -> None:
        _add_members(self, spec, where, scenario.template_classes)
        for port, inner in (spec.get("inputs", {}) or {}).items():
            self.expose_input(port, *(inner if isinstance(inner, list) else [inner]))
        for port, inner in (spec.get("outputs", {}) or {}).items():
            self.expose_output(port, inner)

    summary = spec.get("description") or f"assembly defined in {where.file}:{where.line}"
    return type(name, (Assembly,), {"build": build, "summary": summary, "__module__": __name__})


def _locate_error(here: _Where, entry: dict, exc: Exception) -> ScenarioError:
    """Point an error from a model constructor at the parameter line it concerns, if any."""
    message = str(exc)
    params = entry.get("parameters", {}) or {}
    unknown_part = message.split("known:")[0] if "unknown parameter" in message else ""
    for key in params:
        if f"parameter {key}:" in message or f"'{key}'" in unknown_part:
            return here.child(entry, "parameters").child(params, key).error(message)
    return here.error(message)


def build_simulation(scenario: Scenario):
    """The :class:`shell.simulation.Simulation` of a validated scenario, with its log configured."""
    from shell.simulation import Simulation

    root = build_root(scenario)
    where = _Where(scenario.file, 1, "")
    try:
        simulation = Simulation(root, integrator=scenario.integrator, step=scenario.step,
                                integrator_options=scenario.integrator_options, seed=scenario.seed,
                                stop_events=scenario.stop_events, event_tol=scenario.event_tolerance,
                                event_detection=scenario.event_detection)
    except (ModelError, UnitError) as exc:
        message = str(exc)
        raise ScenarioError(message if message.startswith(scenario.file) else f"{scenario.file}: {message}") from None
    for name, rate, here in scenario.log_signals:
        try:
            simulation.log([name], rate)
        except ModelError as exc:
            raise here.error(str(exc)) from None
    return simulation
