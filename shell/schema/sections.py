"""The scenario schema's sections: which keys a scenario has, what each holds, and the validated
:class:`Scenario` (the schema itself is written for users in docs/scenario_schema.md).

A scenario file describes one scene::

    name, description, seed
    multibody:   gravity, bodies (name, parent, hinge, mass, com, inertia, ..., initial), nodes
    models:      <name>: {type, parameters, config, rate|period, offset, initial, attach}
    assemblies:  <type>: {description, models, connections, inputs, outputs}
    connections: ["a.port -> b.port", {from: a.port, to: b.port}, ...]
    integrator:  {method, step, options}
    stop:        {time, events}
    events:      {detection, tolerance, on: [{name, when, do}]}   (shell.schema.events)
    log:         {rate, signals: [name | {signal, rate}], file}

:func:`parse_scenario` reads the text (:mod:`shell.schema.document`), applies the command-line overrides
(:mod:`shell.schema.overrides`) and checks every section here; the ``multibody:`` section is read when the
scene is built (:mod:`shell.schema.multibody`, it needs the body files). Every refusal names the file, the
line, the key path, what was expected and what was given. Values may carry units ("5 deg/s",
"[1, 2, 3] N*m"); they are converted once, when the scene is built.
"""

from __future__ import annotations

import difflib
import math
from dataclasses import dataclass, field
from pathlib import Path

from shell.graphs import Digraph, find_cycle
from shell.integrators import INTEGRATORS
from shell.registry import RegistryError, lookup
from shell.schema.document import MAX_BYTES, LineDict, ScenarioError, decode_scenario, load_yaml, show, type_name
from shell.schema.events import normalize_on_key, read_events_on
from shell.schema.overrides import apply_override
from shell.schema.validation import (Where, check_rate, check_time, expect_list, expect_mapping, expect_name, find,
                                     period_seconds, refuse_nan, seconds)
from shell.units import UnitError, to_magnitude


TOP_LEVEL = {
    "name": "scenario name", "description": "free text", "seed": "integer (or list of integers)",
    "multibody": "bodies, hinges and nodes of the multibody engine", "models": "component models by name",
    "assemblies": "reusable assembly types defined in this file",
    "connections": "list of 'source.port -> destination.port'", "integrator": "method and step",
    "stop": "stop time and stop events", "log": "logged signals and rates",
    "events": "zero-crossing search: detection (sign_change | subdivided), tolerance; on: events that change "
              "the scene",
}
MODEL_KEYS = {
    "type": "registered model or assembly type", "parameters": "parameter values (with units)",
    "config": "construction options (e.g. unit, shape)", "rate": "sample rate, e.g. 10 Hz",
    "period": "sample period, e.g. 0.1 s", "offset": "first sample time, e.g. 0 s",
    "initial": "initial values of states", "attach": "{node: NAME} or {hinge: BODY} of the engine",
    "description": "free text",
}
ASSEMBLY_KEYS = {
    "description": "free text", "models": "member models and assemblies (as under models:)",
    "connections": "connections between members", "inputs": "exposed input -> member input(s)",
    "outputs": "exposed output -> member output",
}


#: most samples of one rate (model updates or log rows) and integrator steps in one run
MAX_SAMPLES = 10**8
MAX_STEPS = 10**10


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
    scene_events: list = field(default_factory=list)  # events: on: (shell.schema.events.SceneEvent)

    @property
    def name(self) -> str:
        return str(self.document.get("name", Path(self.file).stem))

    def location(self, *keys) -> str:
        """``file:line: key.path`` of ``document[keys[0]][keys[1]]...`` (for messages about a value)."""
        return str(find(self.document, self.file, keys))


def load_scenario(path, overrides: list[str] | None = None) -> Scenario:
    """Read, override and validate a scenario file (the scene is built by :func:`shell.scenario.build_simulation`)."""
    path = str(path)
    try:
        if Path(path).is_dir():
            raise ScenarioError(f"{path}: is a directory, not a scenario file")
        with open(path, "rb") as f:
            data = f.read(MAX_BYTES + 1)
    except OSError as exc:
        raise ScenarioError(f"{path}: cannot read the scenario ({exc.strerror})") from None
    return parse_scenario(decode_scenario(data, path), path, overrides)


def parse_scenario(text: str, filename: str = "<string>", overrides: list[str] | None = None) -> Scenario:
    """Validate a scenario's text (``filename`` names it in messages) after applying ``overrides``."""
    document = load_yaml(text, filename)
    if document is None:
        document = LineDict()
        document.lines = {}
    root = Where(filename, 1, "")
    if not isinstance(document, dict):
        raise root.error(f"expected a mapping at the top level (keys {sorted(TOP_LEVEL)}), given {type_name(document)}")
    for override in overrides or []:
        apply_override(document, override, filename)
    expect_mapping(document, Where(filename, document.line or 1, ""), TOP_LEVEL)
    scenario = Scenario(file=filename, document=document, text=text)
    _validate_seed(document, root, scenario)
    scenario.templates = _validate_assemblies(document, root)
    _validate_models(document, root, scenario.templates)
    _validate_connections(document, root)
    _validate_integrator(document, root, scenario)
    _validate_stop(document, root, scenario)
    _validate_events(document, root, scenario)
    _validate_log(document, root, scenario)
    refuse_nan(document, root)
    check_sample_counts(scenario, scenario.t_final)
    return scenario


def check_sample_counts(scenario: "Scenario", t_final: float | None) -> None:
    """Refuse a run that would take more than MAX_SAMPLES samples at one rate (models, log) or
    MAX_STEPS integrator steps before ``t_final``, and a step longer than the run."""
    document = scenario.document
    file = scenario.file
    if t_final is None:
        return
    step_where = find(document, file, ("integrator", "step"))
    if scenario.step and scenario.step > t_final:
        raise step_where.error(f"the step ({scenario.step:g} s) is longer than the run ({t_final:g} s); "
                               "give a step shorter than the stop time")
    if scenario.step and t_final / scenario.step > MAX_STEPS:
        raise step_where.error(f"{t_final / scenario.step:.3g} steps of {scenario.step:g} s to reach "
                               f"{t_final:g} s (more than {MAX_STEPS:.0e}); give a longer step or a shorter run")
    rated = [(find(document, file, ("models", name, key)), entry[key])
             for name, entry in (document.get("models") or {}).items() if isinstance(entry, dict)
             for key in ("rate", "period") if key in entry]
    if "log" in document and isinstance(document["log"], dict) and "rate" in document["log"]:
        rated.append((find(document, file, ("log", "rate")), document["log"]["rate"]))
    rated += [(here, rate) for _, rate, here in scenario.log_signals if rate is not scenario.log_rate]
    for here, rate in rated:
        period = period_seconds(rate)
        if period and t_final / period > MAX_SAMPLES:
            raise here.error(f"{show(rate)} for {t_final:g} s is {t_final / period:.3g} samples (more than "
                             f"{MAX_SAMPLES:.0e}); give a lower rate or a shorter run")


def _validate_seed(document, root: Where, scenario: Scenario) -> None:
    if "seed" not in document:
        return
    seed = document["seed"]
    ok = (isinstance(seed, int) and not isinstance(seed, bool) and seed >= 0) or (
        isinstance(seed, list) and seed and all(isinstance(s, int) and not isinstance(s, bool) and s >= 0 for s in seed))
    if not ok:
        raise root.child(document, "seed").error(f"expected a non-negative integer or list of them, given {seed!r}")
    scenario.seed = list(seed) if isinstance(seed, list) else seed


def _validate_assemblies(document, root: Where) -> dict:
    """Check the assemblies: section; returns {type name: (spec, where)}."""
    if "assemblies" not in document:
        return {}
    where = root.child(document, "assemblies")
    section = document["assemblies"]
    if not isinstance(section, dict):
        raise where.error(f"expected a mapping of assembly type -> definition, given {type_name(section)}")
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
        expect_mapping(spec, here, ASSEMBLY_KEYS, required=("models",))
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


def _validate_models(document, root: Where, templates: dict, inside: str | None = None) -> None:
    models = document.get("models", {})
    where = root.child(document, "models")
    if not isinstance(models, dict):
        raise where.error(f"expected a mapping of model name -> model entry, given {type_name(models)}")
    for name, entry in models.items():
        here = where.child(models, name)
        if not isinstance(name, str) or not name.replace("_", "a").isalnum():
            raise here.error(f"model names use letters, digits and underscores, given {name!r}")
        expect_mapping(entry, here, MODEL_KEYS, required=("type",))
        model_type = expect_name(entry["type"], here.child(entry, "type"), "a model type")
        if inside is not None and "attach" in entry:
            raise here.child(entry, "attach").error(f"attach the assembly {inside!r} where it is used (under the "
                                                    "top-level models:), not its members")
        if model_type not in templates:  # an assembly type of this file is not in the registry
            try:
                cls = lookup(model_type)
            except RegistryError as exc:
                raise here.child(entry, "type").error(str(exc)) from None
            section = getattr(cls, "scenario_section", None)
            if section:
                raise here.child(entry, "type").error(f"{model_type} is declared in the {section}: section, "
                                                      "not under models:")
        for key in ("parameters", "config", "initial"):
            if key in entry and not isinstance(entry[key], dict):
                raise here.child(entry, key).error(f"expected a mapping, given {type_name(entry[key])} {show(entry[key])}")
        if "rate" in entry and "period" in entry:
            raise here.child(entry, "period").error("give either rate or period, not both")
        for key in ("rate", "period"):
            if key in entry:
                check_rate(entry[key], here.child(entry, key), key,
                           "a frequency (e.g. 10 Hz)" if key == "rate" else "a time (e.g. 0.1 s)")
        if "attach" in entry:
            attach = expect_mapping(entry["attach"], here.child(entry, "attach"),
                                    {"node": "node name", "hinge": "body whose hinge", "engine": "engine model name"})
            if ("node" in attach) == ("hinge" in attach):
                raise here.child(entry, "attach").error(f"expected exactly one of node: or hinge:, given {dict(attach)}")


def connection_ends(item, where: Where) -> tuple[str, str]:
    if isinstance(item, str):
        parts = [p.strip() for p in item.split("->")]
        if len(parts) != 2 or not all(parts):
            raise where.error(f"expected 'source.port -> destination.port', given {item!r}")
        return parts[0], parts[1]
    if isinstance(item, dict):
        expect_mapping(item, where, {"from": "source model.port", "to": "destination model.port"}, required=("from", "to"))
        return (expect_name(item["from"], where.child(item, "from"), "a source model.port"),
                expect_name(item["to"], where.child(item, "to"), "a destination model.port"))
    raise where.error(f"expected 'source.port -> destination.port' or {{from:, to:}}, given {type_name(item)} {show(item)}")


def _validate_connections(document, root: Where) -> None:
    if "connections" not in document:
        return
    where = root.child(document, "connections")
    connections = expect_list(document["connections"], where, "connections")
    for k, item in enumerate(connections):
        here = where.child(connections, k)
        for end in connection_ends(item, here):
            if "." not in end:
                raise here.error(f"expected model.port, given {end!r}")


def _validate_integrator(document, root: Where, scenario: Scenario) -> None:
    if "integrator" not in document:
        return
    where = root.child(document, "integrator")
    spec = expect_mapping(document["integrator"], where, {"method": f"one of {sorted(INTEGRATORS)}",
                                                          "step": "time step, e.g. 10 ms",
                                                          "options": "the method's options (its class's options)"})
    if "method" in spec:
        method = spec["method"]
        if not isinstance(method, str) or method not in INTEGRATORS:
            close = difflib.get_close_matches(str(method), list(INTEGRATORS), n=1) if isinstance(method, str) else []
            hint = f" (did you mean {close[0]!r}?)" if close else ""
            given = show(method) if isinstance(method, str) else f"{type_name(method)} {show(method)}"
            raise where.child(spec, "method").error(f"expected one of {sorted(INTEGRATORS)}, given {given}{hint}")
        scenario.integrator = method
    if "step" in spec:
        here = where.child(spec, "step")
        scenario.step = check_time(seconds(spec["step"], here), str(here), spec["step"])
    options = spec.get("options", {})
    if not isinstance(options, dict):
        raise where.child(spec, "options").error(f"expected a mapping, given {options!r}")
    declared = INTEGRATORS[scenario.integrator].options
    for key, value in options.items():
        if key not in declared:
            raise where.child(spec, "options").child(options, key).error(
                f"not an option of {scenario.integrator}; its options: "
                + (", ".join(f"{k} ({d})" for k, (_, d) in declared.items()) or "none"))
        unit = declared[key][0]
        here = where.child(spec, "options").child(options, key)
        try:
            number = float(to_magnitude(value, unit, (), key))
        except UnitError as exc:
            raise here.error(str(exc)) from None
        if not math.isfinite(number) or number <= 0:
            raise here.error(f"expected a finite positive number, given {show(value)}")
        scenario.integrator_options[key] = number


def _validate_stop(document, root: Where, scenario: Scenario) -> None:
    if "stop" not in document:
        return
    where = root.child(document, "stop")
    spec = expect_mapping(document["stop"], where, {"time": "stop time, e.g. 20 s",
                                                    "events": "list of model.zero_crossing names"})
    if "time" in spec:
        here = where.child(spec, "time")
        scenario.t_final = check_time(seconds(spec["time"], here), str(here), spec["time"])
    if "events" in spec:
        events = expect_list(spec["events"], where.child(spec, "events"), "model.zero_crossing names")
        for k, name in enumerate(events):
            expect_name(name, where.child(spec, "events").child(events, k), "model.zero_crossing")
        scenario.stop_events = list(events)


def _validate_events(document, root: Where, scenario: Scenario) -> None:
    if "events" not in document:
        return
    where = root.child(document, "events")
    normalize_on_key(document["events"])
    spec = expect_mapping(document["events"], where, {
        "detection": "subdivided (default: search every step, also two crossings inside one step) or "
                     "sign_change (search a step only when a function changes sign between its ends; cheaper)",
        "tolerance": "time tolerance of located crossings, e.g. 1e-10 s",
        "on": "events that change the scene: [{name, when, do}] (docs/scenario_schema.md)"})
    if "on" in spec:
        scenario.scene_events = read_events_on(spec["on"], where.child(spec, "on"))
    if "detection" in spec:
        if not isinstance(spec["detection"], str) or spec["detection"] not in ("sign_change", "subdivided"):
            raise where.child(spec, "detection").error(f"expected sign_change or subdivided, given {show(spec['detection'])}")
        scenario.event_detection = spec["detection"]
    if "tolerance" in spec:
        here = where.child(spec, "tolerance")
        scenario.event_tolerance = check_time(seconds(spec["tolerance"], here), str(here), spec["tolerance"])


def _validate_log(document, root: Where, scenario: Scenario) -> None:
    if "log" not in document:
        return
    where = root.child(document, "log")
    spec = expect_mapping(document["log"], where, {"rate": "default log rate, e.g. 10 Hz",
                                                   "signals": "list of model.port names",
                                                   "file": "default log file (HDF5)"})
    scenario.log_rate = spec.get("rate", "100 Hz")
    check_rate(scenario.log_rate, where.child(spec, "rate"))
    signals = expect_list(spec.get("signals", []), where.child(spec, "signals"), "signal names")
    for k, item in enumerate(signals):
        here = where.child(spec, "signals").child(signals, k)
        if isinstance(item, str):
            scenario.log_signals.append((item, scenario.log_rate, here))
        else:
            expect_mapping(item, here, {"signal": "model.port", "rate": "log rate"}, required=("signal",))
            rate = item.get("rate", scenario.log_rate)
            check_rate(rate, here.child(item, "rate"))
            scenario.log_signals.append((expect_name(item["signal"], here.child(item, "signal"), "model.port"),
                                         rate, here))
    if "file" in spec:
        scenario.log_file = expect_name(spec["file"], where.child(spec, "file"), "a file name")
