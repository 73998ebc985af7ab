"""``flexshell check SCENARIO.yaml``: validate and build a scenario without running it."""

from __future__ import annotations

import sys


def register(subparsers) -> None:
    parser = subparsers.add_parser("check", help="validate a YAML scenario without running it",
                                   description="Load, validate and build a scenario (units, shapes, wiring, "
                                               "algebraic loops); print what it contains.")
    parser.add_argument("scenario", help="scenario file (YAML)")
    parser.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                        help="override a scenario value (as for run)")
    parser.add_argument("--trust", action="store_true",
                        help="import the scenario's user code (UserFunction files) while building; without it "
                             "check reads that code (file, syntax, name) but does not run it")
    parser.set_defaults(func=check)


def check(args) -> int:
    from shell.models.user_hook import user_code
    from shell.scenario import ScenarioError, build_simulation, load_scenario
    from shell.units import UnitError

    try:
        scenario = load_scenario(args.scenario, args.overrides)
        with user_code(runs=args.trust):
            simulation = build_simulation(scenario)
    except (ScenarioError, UnitError, ValueError, OSError) as exc:
        print(f"flexshell check: {exc}", file=sys.stderr)
        return 1
    sampled = sorted({f"{float(m.period):g} s" for m in simulation.models if m.period is not None})
    print(f"{args.scenario}: OK ({scenario.name})")
    print(f"  models: {len(simulation.models)} ({', '.join(m.path for m in simulation.models)})")
    print(f"  continuous states: {simulation.x.size}, discrete states: {simulation.z.size}, "
          f"signals: {simulation.signals.size}, connections: {len(simulation.connections)}")
    print(f"  sample periods: {', '.join(sampled) or 'none'}; integrator {scenario.integrator}"
          f"{f', step {scenario.step:g} s' if scenario.step else ''}")
    print(f"  stop: {f'{scenario.t_final:g} s' if scenario.t_final else 'no stop time'}"
          f"{', events ' + ', '.join(scenario.stop_events) if scenario.stop_events else ''}")
    print(f"  logged signals: {len(scenario.log_signals)}")
    for note in (note for m in simulation.models for note in getattr(m, "notes", ())):
        print(f"  note: {note}")  # choices made for the user (engine solver, modal-integral orders), as `run` says
    return 0
