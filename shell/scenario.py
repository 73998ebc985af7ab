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
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import yaml

from shell.assembly import Assembly
from shell.graphs import Digraph, find_cycle
from shell.model import Model, ModelError, parse_period
from shell.registry import RegistryError, lookup
from shell.units import UnitError, short_repr, to_magnitude, written_numbers


class ScenarioError(ValueError):
    """An invalid scenario; the message starts with ``file:line: key.path:``."""


#: deepest nesting of lists and mappings a scenario may have (deeper: refused, not a RecursionError)
MAX_DEPTH = 48
#: most YAML nodes a scenario may expand to once aliases are followed (an alias bomb is refused)
MAX_NODES = 200_000
#: most samples of one rate (model updates or log rows) and integrator steps in one run
MAX_SAMPLES = 10**8
MAX_STEPS = 10**10
#: largest scenario file read (a scenario is a short text; a larger file is refused, not parsed for minutes)
MAX_BYTES = 16 * 2**20


def show(value) -> str:
    """``repr(value)`` cut to a line (:func:`shell.units.short_repr`)."""
    return short_repr(value)


class LineDict(dict):
    """A mapping that remembers the line of itself and of each key (1-based)."""

    line = 0
    lines: dict


class LineList(list):
    """A sequence that remembers the line of itself and of each item (1-based)."""

    line = 0
    lines: list


class _LineLoader(yaml.SafeLoader):
    """SafeLoader producing LineDict/LineList, refusing duplicate keys, keys that are not text or
    numbers, nesting deeper than MAX_DEPTH and documents expanding to more than MAX_NODES nodes."""

    depth = 0

    def compose_node(self, parent, index):
        self.depth += 1
        try:
            if self.depth > MAX_DEPTH:
                mark = self.peek_event().start_mark
                raise ScenarioError(f"{self.name}:{mark.line + 1}: nested more than {MAX_DEPTH} levels deep")
            return super().compose_node(parent, index)
        finally:
            self.depth -= 1

    def get_single_data(self):
        node = self.get_single_node()
        if node is None:
            return None
        _check_expansion(node, self.name)
        return self.construct_document(node)


def _check_expansion(root: yaml.Node, filename: str) -> None:
    """Refuse a document whose aliases expand it past MAX_NODES nodes (a "billion laughs" file) or nest it
    deeper than MAX_DEPTH (an alias inside an alias inside ...), before anything is built from it."""
    measured: dict[int, tuple[int, int]] = {}  # node id -> (expanded size, depth below it)

    def measure(node) -> tuple[int, int]:
        key = id(node)
        if key in measured:
            return measured[key]
        measured[key] = (MAX_NODES + 1, MAX_DEPTH + 1)  # reached again while being measured: a cycle
        if isinstance(node, yaml.MappingNode):
            children = [measure(n) for pair in node.value for n in pair]
        elif isinstance(node, yaml.SequenceNode):
            children = [measure(n) for n in node.value]
        else:
            children = []
        total = min(1 + sum(c[0] for c in children), MAX_NODES + 1)
        depth = 1 + max((c[1] for c in children), default=0)
        line = node.start_mark.line + 1
        if total > MAX_NODES:
            raise ScenarioError(f"{filename}:{line}: the document expands to more than {MAX_NODES} values "
                                "through its aliases (*name); write the values out")
        if depth > MAX_DEPTH:
            raise ScenarioError(f"{filename}:{line}: nested more than {MAX_DEPTH} levels deep (through aliases)")
        measured[key] = (total, depth)
        return total, depth

    measure(root)


def _construct_mapping(loader: _LineLoader, node: yaml.MappingNode) -> LineDict:
    loader.flatten_mapping(node)
    mapping = LineDict()
    mapping.line = node.start_mark.line + 1
    mapping.lines = {}
    for key_node, value_node in node.value:
        key = loader.construct_object(key_node, deep=True)
        line = key_node.start_mark.line + 1
        if not isinstance(key, (str, int, float, bool)) and key is not None:
            raise ScenarioError(f"{loader.name}:{line}: a key must be a name, given {_type_name(key)} {show(key)}")
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
    try:
        loader = _LineLoader(text)
    except yaml.reader.ReaderError as exc:  # the reader checks every character first
        raise _reader_error(exc, text, filename) from None
    loader.name = filename
    try:
        return loader.get_single_data()
    except yaml.MarkedYAMLError as exc:
        mark = exc.problem_mark
        line = mark.line + 1 if mark is not None else 0
        raise ScenarioError(f"{filename}:{line}: not valid YAML: {exc.problem}") from None
    except yaml.reader.ReaderError as exc:
        raise _reader_error(exc, text, filename) from None
    except yaml.YAMLError as exc:
        raise ScenarioError(f"{filename}:1: not valid YAML: {show(str(exc))}") from None
    except RecursionError:
        raise ScenarioError(f"{filename}:1: nested too deeply to read") from None
    finally:
        loader.dispose()


def _reader_error(exc: yaml.reader.ReaderError, text: str, filename: str) -> ScenarioError:
    line = text.count("\n", 0, exc.position) + 1
    return ScenarioError(f"{filename}:{line}: not a text file: character {exc.character!r} ({exc.reason})")


# ------------------------------------------------------------------------------------------------
@dataclass
class _Where:
    """A location in the scenario: file, line and dotted key path."""

    file: str
    line: int
    key: str

    def __str__(self) -> str:
        if self.key.startswith("--set"):  # a command-line override: no line in the file
            return f"{self.file}: {self.key}"
        return f"{self.file}:{self.line}: {self.key}"

    def child(self, container, key, path_part=None) -> "_Where":
        line = self.line
        lines = getattr(container, "lines", None) or {}
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
        raise where.error(f"expected a mapping with keys {sorted(allowed)}, given {_type_name(value)} {show(value)}")
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
        raise where.error(f"expected a list of {what}, given {_type_name(value)} {show(value)}")
    return value


def _expect_name(value, where: _Where, what: str) -> str:
    if not isinstance(value, str) or not value:
        raise where.error(f"expected {what} (text), given {_type_name(value)} {show(value)}")
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

    def location(self, *keys) -> str:
        """``file:line: key.path`` of ``document[keys[0]][keys[1]]...`` (for messages about a value)."""
        return str(_find(self.document, self.file, keys))


def load_scenario(path, overrides: list[str] | None = None) -> Scenario:
    """Read, override and validate a scenario file (the scene is built by :func:`build_simulation`)."""
    path = str(path)
    try:
        if Path(path).is_dir():
            raise ScenarioError(f"{path}: is a directory, not a scenario file")
        with open(path, "rb") as f:
            data = f.read(MAX_BYTES + 1)
    except OSError as exc:
        raise ScenarioError(f"{path}: cannot read the scenario ({exc.strerror})") from None
    return parse_scenario(decode_scenario(data, path), path, overrides)


def decode_scenario(data: bytes, path: str) -> str:
    """The text of a scenario file: UTF-8 (a UTF-8 byte-order mark is dropped); anything else refused."""
    if len(data) > MAX_BYTES:
        raise ScenarioError(f"{path}:1: larger than {MAX_BYTES // 2**20} MiB; a scenario is a short text file")
    if data[:2] in (b"\xff\xfe", b"\xfe\xff"):
        raise ScenarioError(f"{path}:1: encoded in UTF-16; save the scenario as UTF-8")
    if b"\x00" in data:
        line = data.count(b"\n", 0, data.index(b"\x00")) + 1
        raise ScenarioError(f"{path}:{line}: not a text file (it holds NUL bytes); a scenario is YAML text in UTF-8")
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        line = data.count(b"\n", 0, exc.start) + 1
        raise ScenarioError(f"{path}:{line}: not UTF-8 text (byte {data[exc.start]:#04x}); save the scenario "
                            "as UTF-8") from None


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
    _refuse_nan(document, root)
    check_sample_counts(scenario, scenario.t_final)
    return scenario


def check_time(seconds: float, where: str, given) -> float:
    """``seconds`` if it is a finite positive time; else ScenarioError naming ``where``."""
    if not math.isfinite(seconds) or seconds <= 0:
        raise ScenarioError(f"{where}: expected a positive time (a finite number of seconds), given {show(given)}")
    return seconds


def _refuse_nan(value, where: _Where) -> None:
    """NaN is never a meaningful input (a value, a limit, a state): refused wherever it appears."""
    if isinstance(value, float) and value != value:
        raise where.error("expected a number, given NaN (.nan)")
    if isinstance(value, dict):
        for key, item in value.items():
            _refuse_nan(item, where.child(value, key))
    elif isinstance(value, list):
        for k, item in enumerate(value):
            _refuse_nan(item, where.child(value, k))


def _period_seconds(value) -> float | None:
    try:
        return float(parse_period(value, "rate"))
    except (ModelError, UnitError, ZeroDivisionError, OverflowError, ValueError):
        return None


def check_sample_counts(scenario: "Scenario", t_final: float | None) -> None:
    """Refuse a run that would take more than MAX_SAMPLES samples at one rate (models, log) or
    MAX_STEPS integrator steps before ``t_final``, and a step longer than the run."""
    document = scenario.document
    file = scenario.file
    if t_final is None:
        return
    step_where = _find(document, file, ("integrator", "step"))
    if scenario.step and scenario.step > t_final:
        raise step_where.error(f"the step ({scenario.step:g} s) is longer than the run ({t_final:g} s); "
                               "give a step shorter than the stop time")
    if scenario.step and t_final / scenario.step > MAX_STEPS:
        raise step_where.error(f"{t_final / scenario.step:.3g} steps of {scenario.step:g} s to reach "
                               f"{t_final:g} s (more than {MAX_STEPS:.0e}); give a longer step or a shorter run")
    rated = [(_find(document, file, ("models", name, key)), entry[key])
             for name, entry in (document.get("models") or {}).items() if isinstance(entry, dict)
             for key in ("rate", "period") if key in entry]
    if "log" in document and isinstance(document["log"], dict) and "rate" in document["log"]:
        rated.append((_find(document, file, ("log", "rate")), document["log"]["rate"]))
    rated += [(here, rate) for _, rate, here in scenario.log_signals if rate is not scenario.log_rate]
    for here, rate in rated:
        period = _period_seconds(rate)
        if period and t_final / period > MAX_SAMPLES:
            raise here.error(f"{show(rate)} for {t_final:g} s is {t_final / period:.3g} samples (more than "
                             f"{MAX_SAMPLES:.0e}); give a lower rate or a shorter run")


def _find(document, file: str, keys: tuple) -> _Where:
    """The location of ``document[keys[0]][keys[1]]...`` (as deep as it exists)."""
    where = _Where(file, 1, "")
    container = document
    for key in keys:
        if not isinstance(container, dict) or key not in container:
            break
        where = where.child(container, key)
        container = container[key]
    return where


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
    graph = Digraph()
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
    cycle = find_cycle(graph.successors)
    if cycle is None:
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
                raise here.child(entry, key).error(f"expected a mapping, given {_type_name(entry[key])} {show(entry[key])}")
        if "rate" in entry and "period" in entry:
            raise here.child(entry, "period").error("give either rate or period, not both")
        for key in ("rate", "period"):
            if key in entry:
                check_rate(entry[key], here.child(entry, key), key,
                           "a frequency (e.g. 10 Hz)" if key == "rate" else "a time (e.g. 0.1 s)")
        if "attach" in entry:
            attach = _expect_mapping(entry["attach"], here.child(entry, "attach"),
                                     {"node": "node name", "hinge": "body whose hinge", "engine": "engine model name"})
            if ("node" in attach) == ("hinge" in attach):
                raise here.child(entry, "attach").error(f"expected exactly one of node: or hinge:, given {dict(attach)}")


def check_rate(value, where: _Where, key: str = "rate", expected: str = "a rate such as 10 Hz") -> None:
    """A sample rate (``rate:``, "10 Hz") or period (``period:``, "0.1 s"): with a unit under ``rate:``
    (a bare number there was once read as a period in seconds), finite, positive."""
    if key == "rate" and _is_bare_number(value) and not math.isfinite(float(value)):
        raise where.error(f"expected a finite rate such as 10 Hz, given {show(value)}")
    if key == "rate" and _is_bare_number(value):
        raise where.error(f"a rate needs a unit: write `{show(value)} Hz` (or a period such as `0.1 s`), "
                          f"given the bare number {show(value)}")
    try:
        period = parse_period(value, key)
    except (ModelError, UnitError) as exc:
        raise where.error(f"expected {expected}, given {show(value)} ({exc})") from None
    except (ZeroDivisionError, OverflowError, ValueError):
        raise where.error(f"expected {expected}, given {show(value)}") from None
    if not math.isfinite(float(period)) or float(period) < 1e-9:
        raise where.error(f"expected {expected} with a period of at least 1 ns, given {show(value)}")


def _is_bare_number(value) -> bool:
    if isinstance(value, bool):
        return False
    if isinstance(value, (int, float)):
        return True
    if isinstance(value, str):
        try:
            float(value)
        except ValueError:
            return False
        return True
    return False


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
    raise where.error(f"expected 'source.port -> destination.port' or {{from:, to:}}, given {_type_name(item)} {show(item)}")


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
        if not isinstance(method, str) or method not in INTEGRATORS:
            close = difflib.get_close_matches(str(method), list(INTEGRATORS), n=1) if isinstance(method, str) else []
            hint = f" (did you mean {close[0]!r}?)" if close else ""
            given = show(method) if isinstance(method, str) else f"{_type_name(method)} {show(method)}"
            raise where.child(spec, "method").error(f"expected one of {sorted(INTEGRATORS)}, given {given}{hint}")
        scenario.integrator = method
    if "step" in spec:
        here = where.child(spec, "step")
        scenario.step = check_time(_seconds(spec["step"], here), str(here), spec["step"])
    options = spec.get("options", {})
    if not isinstance(options, dict):
        raise where.child(spec, "options").error(f"expected a mapping, given {options!r}")
    for key, value in options.items():
        if key not in ("rtol", "atol", "max_step"):
            raise where.child(spec, "options").child(options, key).error(
                f"unknown integrator option; expected rtol, atol or max_step")
        unit = "s" if key == "max_step" else ""
        here = where.child(spec, "options").child(options, key)
        try:
            number = float(to_magnitude(value, unit, (), key))
        except UnitError as exc:
            raise here.error(str(exc)) from None
        if not math.isfinite(number) or number <= 0:
            raise here.error(f"expected a finite positive number, given {show(value)}")
        scenario.integrator_options[key] = number


def _seconds(value, where: _Where) -> float:
    """A time value in seconds (any unit of time; a bare number is in seconds)."""
    try:
        return float(to_magnitude(value, "s", (), "time"))
    except UnitError as exc:
        raise where.error(f"expected a time, given {show(value)} ({exc})") from None


def _validate_stop(document, root: _Where, scenario: Scenario) -> None:
    if "stop" not in document:
        return
    where = root.child(document, "stop")
    spec = _expect_mapping(document["stop"], where, {"time": "stop time, e.g. 20 s",
                                                     "events": "list of model.zero_crossing names"})
    if "time" in spec:
        here = where.child(spec, "time")
        scenario.t_final = check_time(_seconds(spec["time"], here), str(here), spec["time"])
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
        if not isinstance(spec["detection"], str) or spec["detection"] not in ("sign_change", "subdivided"):
            raise where.child(spec, "detection").error(f"expected sign_change or subdivided, given {show(spec['detection'])}")
        scenario.event_detection = spec["detection"]
    if "tolerance" in spec:
        here = where.child(spec, "tolerance")
        scenario.event_tolerance = check_time(_seconds(spec["tolerance"], here), str(here), spec["tolerance"])


def _validate_log(document, root: _Where, scenario: Scenario) -> None:
    if "log" not in document:
        return
    where = root.child(document, "log")
    spec = _expect_mapping(document["log"], where, {"rate": "default log rate, e.g. 10 Hz",
                                                    "signals": "list of model.port names",
                                                    "file": "default log file (HDF5)"})
    scenario.log_rate = spec.get("rate", "100 Hz")
    check_rate(scenario.log_rate, where.child(spec, "rate"))
    signals = _expect_list(spec.get("signals", []), where.child(spec, "signals"), "signal names")
    for k, item in enumerate(signals):
        here = where.child(spec, "signals").child(signals, k)
        if isinstance(item, str):
            scenario.log_signals.append((item, scenario.log_rate, here))
        else:
            _expect_mapping(item, here, {"signal": "model.port", "rate": "log rate"}, required=("signal",))
            rate = item.get("rate", scenario.log_rate)
            check_rate(rate, here.child(item, "rate"))
            scenario.log_signals.append((_expect_name(item["signal"], here.child(item, "signal"), "model.port"),
                                         rate, here))
    if "file" in spec:
        scenario.log_file = _expect_name(spec["file"], where.child(spec, "file"), "a file name")


# ------------------------------------------------------------------------------------------------
def apply_override(document: dict, assignment: str, filename: str) -> None:
    """Apply ``key.path=value`` (value parsed as YAML) to the loaded document."""
    shown = assignment if len(assignment) <= 80 else assignment[:60] + "..." + assignment[-10:]
    where = _Where(filename, 0, f"--set {shown}")
    if "=" not in assignment:
        raise where.error("expected key.path=value")
    key, raw = assignment.split("=", 1)
    _apply_value(document, key, _override_value(raw, where), where)


def apply_value(document: dict, key: str, value, filename: str) -> None:
    """Apply ``key.path`` = ``value``, a value already in the form YAML gives (what :func:`apply_override`
    does after parsing the text; Monte Carlo runs pass their drawn numbers this way, not as text)."""
    _apply_value(document, key, value, _Where(filename, 0, f"--set {key}=..."))


def _apply_value(document: dict, key: str, value, where: "_Where") -> None:
    parts = [p for p in key.strip().split(".") if p]
    if not parts:
        raise where.error("expected key.path=value")
    models = document.get("models") or {}
    if not isinstance(models, dict):
        raise where.error("the scenario's models: section is not a mapping")
    if parts[0] in ("seed", "name", "description") and len(parts) == 1:
        document[parts[0]] = value
    elif parts[0] in ("integrator", "stop", "log", "events"):
        section = document.setdefault(parts[0], LineDict())
        if not isinstance(section, dict):
            raise where.error(f"section {parts[0]} is not a mapping")
        _set_nested(section, parts[1:], value, where)
    elif parts[0] == "multibody" and "multibody" in document and len(parts) >= 3:
        multibody = document["multibody"]
        if not isinstance(multibody, dict):
            raise where.error("the scenario's multibody: section is not a mapping")
        items = [item for key in ("bodies", "nodes") for item in _as_list(multibody.get(key))]
        for item in items:
            if isinstance(item, dict) and item.get("name") == parts[1]:
                _set_nested(item, parts[2:], value, where)
                return
        raise where.error(f"no body or node named {parts[1]!r} in multibody")
    elif parts[0] in models and len(parts) >= 2:
        entry = models[parts[0]]
        if not isinstance(entry, dict):
            raise where.error(f"the model entry {parts[0]!r} is not a mapping")
        if parts[1] in ("rate", "period", "offset", "type") and len(parts) == 2:
            entry[parts[1]] = value
            if parts[1] == "rate":
                entry.pop("period", None)
            if parts[1] == "period":
                entry.pop("rate", None)
        elif parts[1] in ("parameters", "config", "initial"):
            section = entry.setdefault(parts[1], LineDict())
            if not isinstance(section, dict):
                raise where.error(f"{parts[0]}.{parts[1]} is not a mapping")
            _set_nested(section, parts[2:], value, where)
        else:
            params = entry.setdefault("parameters", LineDict())
            if not isinstance(params, dict):
                raise where.error(f"{parts[0]}.parameters is not a mapping")
            params[".".join(parts[1:])] = value
    else:
        known = sorted({str(m) for m in models} | {"seed", "integrator", "stop", "log", "events", "multibody"})
        raise where.error(f"{parts[0]!r} is neither a model nor a scenario section; known: {known}")


def _as_list(value) -> list:
    return list(value) if isinstance(value, list) else []


def _override_value(raw: str, where: _Where):
    """The value of ``--set key=value``: YAML (a number, a list, a mapping), else the text itself (e.g.
    ``[1, 2] N*m/rad``, read by the unit parser later); nesting and aliases bounded as in a file."""
    if not raw.strip():
        return ""
    try:
        loader = _LineLoader(raw)
    except yaml.reader.ReaderError:
        raise where.error("the value holds control characters") from None
    loader.name = "--set"
    try:
        return loader.get_single_data()
    except ScenarioError as exc:
        raise where.error(str(exc).split(": ", 1)[-1]) from None
    except (yaml.YAMLError, RecursionError):  # "[1, 2] N*m/rad": a list with a unit, read by the unit parser
        return raw.strip()
    finally:
        loader.dispose()


def _set_nested(mapping: dict, parts: list[str], value, where: _Where) -> None:
    if not parts:
        raise where.error("expected a key after the section name")
    for part in parts[:-1]:
        mapping = mapping.setdefault(part, LineDict())
        if not isinstance(mapping, dict):
            raise where.error(f"{part!r} is not a mapping (a --set cannot reach into a list or a value)")
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
    from shell.diagnostics import located

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

    from shell.diagnostics import located

    root = build_root(scenario)
    where = _Where(scenario.file, 1, "")
    try:
        with located(lambda text: _model_location(scenario, text)):  # configure()'s warnings, located
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
                where = _nonfinite_body_initial(scenario) or _find(scenario.document, scenario.file, keys)
                raise where.error(f"initial state {model.path}.{name} is not finite: {show(values.tolist())}")


def _nonfinite_body_initial(scenario: Scenario) -> _Where | None:
    """The multibody.bodies[i](name).initial.<key> whose value, as written, is not finite (if one is)."""
    document = scenario.document
    multibody = document.get("multibody")
    bodies = multibody.get("bodies") if isinstance(multibody, dict) else None
    if not isinstance(bodies, list):
        return None
    where = _Where(scenario.file, 1, "").child(document, "multibody").child(multibody, "bodies")
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
