"""Command-line overrides of a scenario: ``--set key.path=value`` applied to the loaded document.

``seed=7``, ``integrator.step=5 ms``, ``stop.time=30 s``, ``<model>.<parameter>=value`` (also
``<model>.parameters.<name>``, ``<model>.config.<key>``, ``<model>.initial.<state>``), ``<model>.rate=20 Hz``
and ``multibody.<body or node>.<key>=value``, ``events.<event>.time`` / ``.crosses`` (an ``events: on:`` entry). The value is read as YAML (a number, a list, a mapping) within
the limits of a scenario file, else kept as text for the unit parser (``[1, 2] N*m/rad``). Overrides are
applied before validation, so an overridden value is checked like a written one; Monte Carlo runs apply
their drawn values the same way (:func:`apply_value`).
"""

from __future__ import annotations

import yaml

from shell.schema.document import LineDict, LineLoader, ScenarioError
from shell.schema.events import set_event_value
from shell.schema.validation import Where


def apply_override(document: dict, assignment: str, filename: str) -> None:
    """Apply ``key.path=value`` (value parsed as YAML) to the loaded document."""
    shown = assignment if len(assignment) <= 80 else assignment[:60] + "..." + assignment[-10:]
    where = Where(filename, 0, f"--set {shown}")
    if "=" not in assignment:
        raise where.error("expected key.path=value")
    key, raw = assignment.split("=", 1)
    _apply_value(document, key, override_value(raw, where), where)


def apply_value(document: dict, key: str, value, filename: str) -> None:
    """Apply ``key.path`` = ``value``, a value already in the form YAML gives (what :func:`apply_override`
    does after parsing the text; Monte Carlo runs pass their drawn numbers this way, not as text)."""
    _apply_value(document, key, value, Where(filename, 0, f"--set {key}=..."))


def _apply_value(document: dict, key: str, value, where: "Where") -> None:
    parts = [p for p in key.strip().split(".") if p]
    if not parts:
        raise where.error("expected key.path=value")
    models = document.get("models") or {}
    if not isinstance(models, dict):
        raise where.error("the scenario's models: section is not a mapping")
    if parts[0] in ("seed", "name", "description") and len(parts) == 1:
        document[parts[0]] = value
    elif parts[0] == "events" and len(parts) == 3 and parts[1] not in ("detection", "tolerance", "on"):
        set_event_value(document.get("events"), parts[1], parts[2], value, where)
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


def override_value(raw: str, where: Where):
    """The value of ``--set key=value``: YAML (a number, a list, a mapping), else the text itself (e.g.
    ``[1, 2] N*m/rad``, read by the unit parser later); nesting and aliases bounded as in a file."""
    if not raw.strip():
        return ""
    try:
        loader = LineLoader(raw)
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


def _set_nested(mapping: dict, parts: list[str], value, where: Where) -> None:
    if not parts:
        raise where.error("expected a key after the section name")
    for part in parts[:-1]:
        mapping = mapping.setdefault(part, LineDict())
        if not isinstance(mapping, dict):
            raise where.error(f"{part!r} is not a mapping (a --set cannot reach into a list or a value)")
    mapping[parts[-1]] = value
