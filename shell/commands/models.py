"""``flexshell models [NAME]``: list registered models and assemblies with parameters, ports and units."""

from __future__ import annotations

import sys


def register(subparsers) -> None:
    parser = subparsers.add_parser("models", help="list model and assembly types usable in scenarios",
                                   description="List registered models and assemblies; with NAME, show its "
                                               "parameters, ports, states and units.")
    parser.add_argument("name", nargs="?", help="one model type to describe in full")
    parser.set_defaults(func=list_models)


def _example(cls):
    """An instance of the class's ``example_config`` (a model whose ports its configuration sets), else of the
    default configuration (to show ports that depend on construction options)."""
    example = getattr(cls, "example_config", None)
    for options in ([example] if example else []) + [{}, {"period": 1.0}]:
        try:
            return cls("example", **options)
        except Exception:  # types needing construction data (the engine) show their class declarations
            continue
    return None


def _default(value) -> str:
    """A parameter's default on one line (a matrix from a configuration too)."""
    import numpy as np

    if isinstance(value, np.ndarray):
        return " ".join(np.array2string(value, separator=", ", max_line_width=10**6, threshold=12).split())
    return repr(value)


def _unit(unit: str) -> str:
    from shell.units import format_unit

    return format_unit(unit) if unit else "1"


def describe(name: str, cls) -> str:
    from shell.model import Model

    lines = [f"{name}: {cls.summary or (cls.__doc__ or '').strip().splitlines()[0]}"]
    example = _example(cls)
    source = example if example is not None else cls
    # a class's declarations whose shapes its configuration sets (Declarations(sized=...)) show no shape
    sized = getattr(source.declarations, "sized", ()) if example is None and hasattr(source, "declarations") else ()

    def shape(declaration) -> str:
        return "set by the configuration" if declaration.name in sized else str(declaration.shape)
    depends = sorted(getattr(getattr(cls, "declarations", None), "sized", ()))
    config = getattr(cls, "example_config", None)
    if example is not None and (depends or config):
        shown = f"the example config: {config}" if config else "the default config"
        lines.append(f"  shapes{' of ' + ', '.join(depends) if depends else ''} depend on config; shown for {shown}")
    if getattr(cls, "config_note", ""):
        lines.append(f"  {cls.config_note}")
    period = getattr(example, "period", None)
    if period is not None:
        lines.append("  sampled: set rate: or period:"
                     + (f" (default period {float(period):g} s)" if cls.default_period is not None else ""))
    for title, items in (("parameters", source.parameters),):
        if items:
            lines.append(f"  {title}:")
            for p in items:
                lines.append(f"    {p.name:28s} [{_unit(p.unit)}] shape {shape(p)} default {_default(p.default)}"
                             f"{' bounds ' + str(p.bounds) if p.bounds else ''}  {p.description}")
    if isinstance(source, Model) or (isinstance(source, type) and issubclass(source, Model)):
        for title, items in (("inputs", source.inputs), ("outputs", source.outputs)):
            if items:
                lines.append(f"  {title}:")
                for port in items:
                    flags = " feedthrough" if port.feedthrough else ""
                    flags += " optional" if title == "inputs" and not port.required else ""
                    lines.append(f"    {port.name:28s} [{_unit(port.unit)}] shape {shape(port)}{flags}  "
                                 f"{port.description}")
        for title, items in (("continuous states", source.continuous_states),
                             ("discrete states", source.discrete_states)):
            if items:
                lines.append(f"  {title}: " + ", ".join(f"{s.name} [{_unit(s.unit)}] {shape(s)}" for s in items))
        if source.zero_crossings:
            lines.append("  zero crossings: " + ", ".join(z.name for z in source.zero_crossings))
    else:
        lines.append(f"  exposed inputs: {source.input_names() if example else '(built from parameters)'}")
        lines.append(f"  exposed outputs: {source.output_names() if example else '(built from parameters)'}")
    if example is None and getattr(cls, "scenario_section", None):
        lines.append(f"  declared in the scenario's {cls.scenario_section}: section; ports per body and node:")
        lines.extend(f"    {line}" for line in getattr(cls, "port_summary", ()))
    return "\n".join(lines)


def list_models(args) -> int:
    from shell.registry import RegistryError, lookup, registered

    if args.name:
        try:
            cls = lookup(args.name)
        except RegistryError as exc:
            print(f"flexshell models: {exc}", file=sys.stderr)
            return 1
        print(describe(args.name, cls))
        return 0
    for name, cls in registered().items():
        print(describe(name, cls))
        print()
    return 0
