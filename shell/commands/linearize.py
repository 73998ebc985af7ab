"""``flexshell linearize SCENARIO.yaml --inputs ... --outputs ... -o LIN.h5``: linear model of a scene.

Builds the scenario, optionally runs it to ``--at`` seconds, optionally trims it (``--trim``:
:func:`shell.analysis.trim.trim` with ``--hold``, ``--free``, ``--zero-rates``; the linearization inputs
are held open at their values), linearizes between the named input ports
and outputs (:func:`shell.analysis.linearize.linearize`) and writes the HDF5 linear-model file
(:mod:`shell.analysis.linear_model_file`, TM-2020-5008164 App. G.4 layout) and, with ``--mat``, a
MATLAB file.
"""

from __future__ import annotations

import math
import sys

from shell.outputs import OVERWRITE_HELP


def _names(values):
    return [name for value in values for name in value.split(",") if name.strip()]


def register(subparsers) -> None:
    parser = subparsers.add_parser(
        "linearize", help="linearize a scenario between named inputs and outputs (A, B, C, D to HDF5)",
        description="Linearize a scenario about its initial state (or its state at --at) between input ports "
                    "and outputs named by dotted path (an element as port[k]); central differences with "
                    "Richardson extrapolation; writes A, B, C, D, index maps, units, operating point and "
                    "error estimates to an HDF5 linear-model file.")
    parser.add_argument("scenario", help="scenario file (YAML)")
    parser.add_argument("--inputs", action="append", required=True, metavar="PORT[,PORT...]",
                        help="input ports or elements, e.g. multibody.bus.torque or multibody.acs.torque[2]")
    parser.add_argument("--outputs", action="append", required=True, metavar="SIGNAL[,SIGNAL...]",
                        help="output ports, input ports or states, e.g. multibody.acs.angular_velocity")
    parser.add_argument("-o", "--output", required=True, help="linear-model file to write (HDF5)")
    parser.add_argument("--mat", help="also write a MATLAB .mat file")
    parser.add_argument("--at", type=float, default=None, metavar="SECONDS",
                        help="run the scenario to this time first and linearize there")
    parser.add_argument("--trim", action="store_true",
                        help="trim before linearizing: solve the states not held (and the --free inputs) so the "
                             "--zero-rates state rates vanish (default: all rates, an equilibrium)")
    parser.add_argument("--hold", action="append", default=[], metavar="STATE[,STATE...]",
                        help="with --trim: states or state elements kept at their values, e.g. multibody.u")
    parser.add_argument("--free", action="append", default=[], metavar="INPUT[,INPUT...]",
                        help="with --trim: input ports/elements solved for (then linearized about the result)")
    parser.add_argument("--zero-rates", action="append", default=[], metavar="STATE[,STATE...]",
                        help="with --trim: the states whose rates must vanish (default: every state)")
    parser.add_argument("--tolerance", type=float, default=1e-10,
                        help="relative truncation error aimed at; sets the steps (default 1e-10)")
    parser.add_argument("--points", type=int, choices=(2, 4), default=4, help="central-difference points")
    parser.add_argument("--no-richardson", action="store_true", help="no Richardson extrapolation")
    parser.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                        help="override a scenario value (as for run)")
    parser.add_argument("--overwrite", action="store_true", help=OVERWRITE_HELP)
    parser.set_defaults(func=linearize_command)


def linearize_command(args) -> int:
    from datetime import datetime, timezone

    from shell.analysis.linear_model_file import write_linear_model, write_mat
    from shell.outputs import LINEAR_MODEL, MAT, guard_output
    from shell.analysis.linearize import linearize
    from shell.analysis.trim import trim
    from shell.model import ModelError
    from shell.scenario import ScenarioError, build_simulation, load_scenario
    from shell.units import UnitError

    try:  # outputs first: a refused output costs nothing, a linearization may take minutes
        for output, kind, other in ((args.output, LINEAR_MODEL, args.mat), (args.mat, MAT, args.output)):
            if output is not None:
                guard_output(output, kind, inputs=((args.scenario, "the scenario itself"),),
                             overwrite=args.overwrite, others=(other,))
        if args.at is not None and not (math.isfinite(args.at) and args.at >= 0):
            raise ValueError(f"--at {args.at}: expected a finite time >= 0 (s)")
        scenario = load_scenario(args.scenario, args.overrides)
        simulation = build_simulation(scenario)
        if args.at is not None:
            simulation.run(args.at)
        inputs, input_values, trimmed = _names(args.inputs), None, None
        if args.trim:
            loose = [name for name in _names(args.free) if name not in inputs]
            if loose:
                raise ValueError(f"--free {', '.join(loose)}: a solved input must also be a linearization input "
                                 "(--inputs), so that the linear model holds it at its trimmed value")
            trimmed = trim(simulation, hold=_names(args.hold), free_inputs=_names(args.free), inputs=inputs,
                           derivatives=_names(args.zero_rates) or None)
            input_values = {name: value for name, value in trimmed.input_values.items() if name in inputs}
        elif args.hold or args.free or args.zero_rates:
            raise ValueError("--hold, --free and --zero-rates need --trim")
        model = linearize(simulation, inputs, _names(args.outputs), tolerance=args.tolerance,
                          input_values=input_values,
                          points=args.points, richardson=not args.no_richardson,
                          metadata={"scenario": str(args.scenario), "scenario_name": scenario.name,
                                    "overrides": list(args.overrides),
                                    "created": datetime.now(timezone.utc).isoformat(timespec="seconds")})
    except (ScenarioError, UnitError, ModelError, ValueError, OSError) as exc:
        print(f"flexshell linearize: {exc}", file=sys.stderr)
        return 1
    if trimmed is not None:
        print(f"{args.scenario}: {trimmed}")
        if not trimmed.success or trimmed.max_residual > 1e-6:
            worst = max(trimmed.residuals, key=lambda name: abs(trimmed.residuals[name]))
            print(f"flexshell linearize: warning: trim residual {trimmed.max_residual:.3g} (largest at {worst}); "
                  "the model is linearized about a point that is not an equilibrium", file=sys.stderr)
        model.metadata["trim_residual"] = trimmed.max_residual
    write_linear_model(args.output, model)
    if args.mat:
        write_mat(args.mat, model)
    print(f"{args.scenario}: {model}")
    print(f"  written {args.output}{' and ' + args.mat if args.mat else ''}")
    return 0
