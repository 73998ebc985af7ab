"""``flexshell linearize SCENARIO.yaml --inputs ... --outputs ... -o LIN.h5``: linear model of a scene.

Builds the scenario, optionally runs it to ``--at`` seconds, optionally trims it (``--trim``:
:func:`shell.analysis.trim.trim` with ``--hold``, ``--free``, ``--zero-rates``; the linearization inputs
are held open at their values), linearizes between the named input ports
and outputs (:func:`shell.analysis.linearize.linearize`) and writes the HDF5 linear-model file
(:mod:`shell.analysis.linear_model_file`, TM-2020-5008164 App. G.4 layout) and, with ``--mat``, a
MATLAB file. With ``--sampled`` it writes the sampled closed-loop model instead
(:func:`shell.analysis.sampled_loop.sampled_linearize`: the period map of the scene's sampled models, ``--period``
a multiple of their periods, default the least) with its ``sample_time``, and prints its spectral radius and
least-stable eigenvalues.
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
    parser.add_argument("--inputs", action="append", default=[], metavar="PORT[,PORT...]",
                        help="input ports or elements, e.g. multibody.bus.torque or multibody.acs.torque[2] "
                             "(required, except with --sampled)")
    parser.add_argument("--outputs", action="append", default=[], metavar="SIGNAL[,SIGNAL...]",
                        help="output ports, input ports or states, e.g. multibody.acs.angular_velocity "
                             "(required, except with --sampled)")
    parser.add_argument("--sampled", action="store_true",
                        help="the sampled closed-loop model instead: the map of the whole scene over one period of "
                             "its sampled models (ZOH, their updates, delays), from a sample instant; its "
                             "eigenvalues say the loop's stability (spectral radius < 1)")
    parser.add_argument("--period", type=float, default=None, metavar="SECONDS",
                        help="with --sampled: the period of the map, a multiple of every sampled model's period "
                             "(default the least such)")
    parser.add_argument("--leave-out", action="append", default=[], metavar="STATE[,STATE...]",
                        help="with --sampled: states left out of the stability verdict (a free body's translation, "
                             "which no feedback reaches: e.g. multibody.q[4:7],multibody.u[3:6]); refused when the "
                             "other states depend on them")
    parser.add_argument("--eigenvalues", type=int, default=6, metavar="N",
                        help="with --sampled: print the N least-stable eigenvalues (default 6)")
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
    from shell.analysis.sampled_loop import sampled_linearize
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
        _check_options(args)
        scenario = load_scenario(args.scenario, args.overrides)
        simulation = build_simulation(scenario)
        if args.at is not None:
            simulation.run(args.at)
        metadata = {"scenario": str(args.scenario), "scenario_name": scenario.name, "overrides": list(args.overrides),
                    "created": datetime.now(timezone.utc).isoformat(timespec="seconds")}
        if args.sampled:
            model = sampled_linearize(simulation, period=args.period, tolerance=args.tolerance, points=args.points,
                                      richardson=not args.no_richardson, metadata=metadata)
            return _write_sampled(args, model)
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
                          points=args.points, richardson=not args.no_richardson, metadata=metadata)
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


def _check_options(args) -> None:
    """The options that go together: --inputs/--outputs or --sampled (with --period, --eigenvalues)."""
    if args.sampled:
        given = [option for option, value in (("--inputs", args.inputs), ("--outputs", args.outputs),
                                              ("--trim", args.trim)) if value]
        if given:
            raise ValueError(f"{', '.join(given)}: not taken with --sampled (the sampled closed-loop model is the "
                             "whole scene's period map: no inputs, outputs or trim)")
        if args.period is not None and not (math.isfinite(args.period) and args.period > 0):
            raise ValueError(f"--period {args.period}: expected a time > 0 (s)")
        if args.eigenvalues < 0:
            raise ValueError(f"--eigenvalues {args.eigenvalues}: expected a count >= 0")
        return
    if args.period is not None or args.leave_out:
        raise ValueError(f"{'--period' if args.period is not None else '--leave-out'} is taken with --sampled only")
    missing = [option for option, value in (("--inputs", args.inputs), ("--outputs", args.outputs)) if not value]
    if missing:
        raise ValueError(f"{' and '.join(missing)} required (or --sampled for the sampled closed-loop model)")


def _write_sampled(args, model) -> int:
    """Write the sampled closed-loop model and print its spectral radius and least-stable eigenvalues."""
    from shell.analysis.linear_model_file import write_linear_model, write_mat
    from shell.analysis.sampled_loop import loop_eigenvalues

    write_linear_model(args.output, model)
    if args.mat:
        write_mat(args.mat, model)
    try:
        rows = loop_eigenvalues(model, _names(args.leave_out))
    except ValueError as exc:  # a state not in the model, or one the others depend on
        print(f"flexshell linearize: {exc} (the model is written to {args.output})", file=sys.stderr)
        return 1
    radius = rows[0][1] if rows else 0.0
    verdict = "stable" if radius < 1.0 else "NOT asymptotically stable"
    print(f"{args.scenario}: sampled closed-loop model at t = {model.operating_point['t']:.9g} s over "
          f"T = {model.metadata['sample_time']:.9g} s: {model.A.shape[0]} states; largest estimated entry error "
          f"{model.max_error:.3g}")
    print(f"  spectral radius {radius:.12g} ({verdict})")
    if rows[:args.eigenvalues]:
        print(f"  least-stable eigenvalues:{'':10}|z|    decay rate ln|z|/T (1/s)  frequency (Hz)  largest in")
        for lam, magnitude, rate, frequency, state in rows[:args.eigenvalues]:
            print(f"    {lam.real:+.9f}{lam.imag:+.9f}j  {magnitude:.9f}  {rate:+.6g}  {frequency:.6g}  {state}")
    if args.leave_out:
        print(f"  left out of the verdict: {', '.join(_names(args.leave_out))}")
    print(f"  written {args.output}{' and ' + args.mat if args.mat else ''}")
    return 0
