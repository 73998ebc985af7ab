"""``flexshell run SCENARIO.yaml``: build a scenario, run it with a progress bar, log to HDF5, summarize.

Everything that can be refused without building the scene (the scenario, the stop time, the log and
restart paths) is refused first. Ctrl-C and SIGTERM end a run as "interrupted" (exit 130 and 143): the
log is closed with the time of its last sample (shell.log_file).
"""

from __future__ import annotations

import signal
import sys
import threading
import time
from pathlib import Path


def register(subparsers) -> None:
    parser = subparsers.add_parser("run", help="run a YAML scenario and log it to HDF5",
                                   description="Run a YAML scenario; logs the scenario's log: signals.")
    parser.add_argument("scenario", help="scenario file (YAML)")
    parser.add_argument("-o", "--output", help="log file (HDF5); default: the scenario's log.file, "
                                               "else <scenario name>.h5")
    parser.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                        help="override a scenario value, e.g. --set controller.kp='[5, 5, 5] N*m/rad' "
                             "or --set integrator.step='5 ms' (repeatable)")
    parser.add_argument("--t-final", help="stop time (overrides stop.time), e.g. 30 or '30 s'")
    parser.add_argument("--restore", metavar="RESTART.h5", help="continue from a saved state")
    parser.add_argument("--save-state", metavar="RESTART.h5", help="save the final state for a restart")
    parser.add_argument("--quiet", action="store_true", help="no progress bar")
    parser.set_defaults(func=run)


class ProgressBar:
    """Simulated time against the stop time on stderr (tqdm): fraction, wall time spent, ETA, speed in
    simulated seconds per wall second; redrawn at most every 0.2 s."""

    def __init__(self, t_start: float, t_final: float, enabled: bool):
        from tqdm import tqdm

        self.t_start, self.t_final = t_start, t_final
        self.enabled = enabled
        self.done = 0.0
        self.bar = tqdm(total=max(t_final - t_start, 0.0), unit="s", unit_scale=False, disable=not enabled,
                        file=sys.stderr, mininterval=0.2, leave=True, dynamic_ncols=True,
                        bar_format="{l_bar}{bar}| t = {n:.4g} / {total:.4g} s [{elapsed} < {remaining}, "
                                   "{rate_fmt}]") if enabled else None

    def __call__(self, t: float) -> None:
        if self.bar is None:
            return
        done = min(max(t - self.t_start, 0.0), self.bar.total)
        if done > self.done:
            self.bar.update(done - self.done)
            self.done = done

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()
            self.bar = None


def compiling_line(label: str, work, enabled: bool):
    """Run ``work()`` while a tqdm line shows ``label`` and the seconds spent (refreshed by a thread:
    numba compiles without reporting progress, so an ETA would be invented); returns work's result."""
    if not enabled:
        return work()
    from tqdm import tqdm

    line = tqdm(total=None, desc=label, file=sys.stderr, bar_format="{desc}: {elapsed} elapsed", leave=True)
    finished = threading.Event()

    def tick():
        while not finished.wait(0.5):
            line.refresh()

    ticker = threading.Thread(target=tick, daemon=True)
    ticker.start()
    try:
        return work()
    finally:
        finished.set()
        ticker.join()
        line.close()


def announce_compilation(quiet: bool) -> None:
    """The first run after installing flexshell compiles its loop (numba); say so, with the time spent
    ticking, instead of a silent minute."""
    from shell.compiled_plan import loop_is_cached, prepare

    if loop_is_cached():
        return
    if not quiet:
        print("flexshell: compiling the simulation loop (first run after installing or updating flexshell; "
              "cached for every later run and scene)...", file=sys.stderr, flush=True)
    seconds = compiling_line("flexshell: compiling (numba)", prepare, not quiet and sys.stderr.isatty())
    if not quiet:
        print(f"flexshell: compiled in {seconds:.0f} s", file=sys.stderr, flush=True)


class Terminated(KeyboardInterrupt):
    """SIGTERM received: handled as an interruption, so the log is closed with status "interrupted"."""


#: SIGTERMs received during the current run. The handler raises Terminated where Python happens to be, and an
#: exception raised inside a weakref callback or a __del__ (the garbage collector runs them at any time) is
#: printed and dropped by Python: the run then checks this at every progress call, so a SIGTERM is never lost.
_SIGTERMS: list = []


def _raise_terminated(signum, frame) -> None:
    _SIGTERMS.append(signum)
    raise Terminated("terminated (SIGTERM)")


def _watching_sigterm(progress):
    """``progress`` that first raises Terminated if a SIGTERM arrived (its handler's exception may have been
    dropped, see _SIGTERMS)."""
    def call(t: float) -> None:
        if _SIGTERMS:
            raise Terminated("terminated (SIGTERM)")
        progress(t)
    return call


def stop_time(value: str, scenario_file: str) -> float:
    """The ``--t-final`` value in seconds: finite and positive."""
    from shell.scenario import ScenarioError, check_time
    from shell.units import UnitError, to_magnitude

    try:
        seconds = to_magnitude(value, "s", (), "--t-final")
    except UnitError as exc:
        raise ScenarioError(f"{scenario_file}: --t-final: expected a time such as 30 s, given {value!r} ({exc})") from None
    return check_time(float(seconds), f"{scenario_file}: --t-final", value)


def run(args) -> int:
    from shell.log_file import LogError, check_log_target
    from shell.scenario import ScenarioError, build_simulation, check_sample_counts, load_scenario
    from shell.simulation import SimulationError
    from shell.units import UnitError

    try:
        scenario = load_scenario(args.scenario, args.overrides)
        t_final = scenario.t_final
        if args.t_final is not None:
            t_final = stop_time(args.t_final, args.scenario)
            check_sample_counts(scenario, t_final)
        if t_final is None:
            raise ScenarioError(f"{args.scenario}: no stop time; add stop: {{time: ...}} or pass --t-final")
        output = args.output or scenario.log_file or f"{Path(args.scenario).stem}.h5"
        if not scenario.log_signals:
            output = None
        if output is not None:
            try:
                if Path(output).resolve() == Path(args.scenario).resolve():
                    raise LogError(f"{output}: is the scenario itself; choose another log file")
                check_log_target(output)
            except LogError as exc:
                if args.output:
                    raise
                raise LogError(f"{scenario.location('log', 'file')}: {exc}") from None
        if args.save_state:
            check_log_target(args.save_state, "flexshell-restart")
    except (ScenarioError, UnitError, ValueError, OSError) as exc:
        print(f"flexshell run: {exc}", file=sys.stderr)
        return 1
    announce_compilation(args.quiet)
    try:
        simulation = build_simulation(scenario)
        if args.restore:
            simulation.load_state(args.restore)
    except (ScenarioError, UnitError, ValueError, OSError) as exc:
        print(f"flexshell run: {exc}", file=sys.stderr)
        return 1
    progress = ProgressBar(simulation.t, t_final, enabled=not args.quiet and sys.stderr.isatty())
    in_main_thread = threading.current_thread() is threading.main_thread()  # signal handlers live there
    _SIGTERMS.clear()
    previous_handler = signal.signal(signal.SIGTERM, _raise_terminated) if in_main_thread else None
    try:
        summary = simulation.run(t_final, log_path=output, progress=_watching_sigterm(progress),
                                 log_attributes={"scenario": scenario.text, "scenario_file": str(args.scenario)})
    except (SimulationError, LogError) as exc:
        progress.close()
        print(f"flexshell run: {exc}", file=sys.stderr)
        if output and isinstance(exc, SimulationError):
            print(f"flexshell run: the log {output} keeps every sample up to the failure", file=sys.stderr)
        return 1
    except KeyboardInterrupt as exc:
        progress.close()
        cause = str(exc) or "interrupted"
        print(f"flexshell run: {cause} at t = {simulation.t:.6g} s"
              + (f"; the log {output} keeps every sample up to there" if output else ""), file=sys.stderr)
        return 143 if isinstance(exc, Terminated) else 130
    finally:
        if in_main_thread:
            signal.signal(signal.SIGTERM, previous_handler)
    progress.close()
    if _SIGTERMS:  # after the last progress call, its exception dropped: the run had reached its end
        print(f"flexshell run: terminated (SIGTERM) as the run reached t = {simulation.t:.6g} s"
              + (f"; the log {output} is complete" if output else ""), file=sys.stderr)
        return 143
    if args.save_state:
        simulation.save_state(args.save_state)
    print(f"{scenario.name}: {summary}")
    if output:
        print(f"log: {output}")
    if args.save_state:
        print(f"restart state: {args.save_state}")
    return 0
