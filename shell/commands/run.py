"""``flexshell run SCENARIO.yaml``: build a scenario, run it with a progress bar, log to HDF5, summarize.

Everything that can be refused without building the scene (the scenario, the stop time, the log and
restart paths) is refused first. Ctrl-C and SIGTERM end a run as "interrupted" (exit 130 and 143): the
log is closed with the time of its last sample (shell.log_file).
"""

from __future__ import annotations

import signal
import sys
import threading
from pathlib import Path

from shell.outputs import OVERWRITE_HELP


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
    parser.add_argument("--overwrite", action="store_true", help=OVERWRITE_HELP)
    parser.add_argument("--quiet", action="store_true", help="no progress bar")
    parser.set_defaults(func=run)


class ProgressBar:
    """Simulated time against the stop time on stderr (tqdm): fraction, wall time spent, ETA, speed in
    simulated seconds per wall second; redrawn at most every 0.2 s."""

    def __init__(self, t_start: float, t_final: float, enabled: bool):
        self.t_start, self.t_final = t_start, t_final
        self.enabled = enabled
        self.done = 0.0
        self.bar = None  # drawn at the first report, after any compilation line (CompileNotice)

    def __call__(self, t: float) -> None:
        if not self.enabled:
            return
        if self.bar is None:
            from tqdm import tqdm

            self.bar = tqdm(total=max(self.t_final - self.t_start, 0.0), unit="s", unit_scale=False, file=sys.stderr,
                            mininterval=0.2, leave=True, dynamic_ncols=True,
                            bar_format="{l_bar}{bar}| t = {n:.4g} / {total:.4g} s [{elapsed} < {remaining}, "
                                       "{rate_fmt}]")
        done = min(max(t - self.t_start, 0.0), self.bar.total)
        if done > self.done:
            self.bar.update(done - self.done)
            self.done = done

    def close(self) -> None:
        self.enabled = False
        if self.bar is not None:
            self.bar.close()
            self.bar = None


class CompileNotice:
    """Says when numba compiles (the first run after installing or updating flexshell, or the first scene that
    needs a kernel not compiled before) and for how long, instead of a silent wait.

    Listens to numba's ``numba:compile`` event, raised when a kernel is compiled and not when it is loaded from
    the on-disk cache: the first compilation prints a line, a TTY shows the seconds ticking, and :meth:`stop`
    (at the run's first progress report, or at the end) prints the compile time. Only what the scene needs is
    compiled: a scene without the multibody engine does not compile it. Use as a context manager."""

    def __init__(self, quiet: bool):
        from dynamics.compile_cache import CompileClock

        self.quiet, self.announced, self._line = quiet, False, None
        self.parts: list[str] = []  # what was compiled: the engine, the loop, model kernels (in that order of start)
        self._clock = CompileClock(on_start=self._compiling)

    @property
    def seconds(self) -> float:
        """Seconds spent compiling while the notice listened."""
        return self._clock.seconds

    def __enter__(self) -> "CompileNotice":
        self._clock.start()
        return self

    def _compiling(self, dispatcher) -> None:
        """An outer compilation starts: the first says that the run compiles, each new part what and how long."""
        if not self._clock.running or self._clock.depth != 1:
            return
        from shell.commands.compile import describe

        part, seconds = describe(dispatcher)
        if part in self.parts:
            return
        self.parts.append(part)
        first = not self.announced
        self.announced = True
        if self.quiet:
            return
        if first:
            print("flexshell: compiling the scene's kernels (numba; first run after installing or updating flexshell, "
                  "or a kernel no earlier scene needed; cached for every later run; `flexshell compile` compiles the "
                  "common set ahead)...", file=sys.stderr, flush=True)
        label = f"flexshell: compiling {part} (up to ~{seconds:.0f} s)"
        if not sys.stderr.isatty():
            print(label, file=sys.stderr, flush=True)
        elif self._line is None:
            self._line = TickingLine(label)
        else:
            self._line.relabel(label)

    def stop(self) -> None:
        """Stop listening; print the compile time if anything was compiled. Idempotent."""
        if not self._clock.running:
            return
        self._clock.stop()
        if self._line is not None:
            self._line.close()
            self._line = None
        if self.announced and not self.quiet:
            print(f"flexshell: compiled in {self.seconds:.0f} s", file=sys.stderr, flush=True)

    def __exit__(self, *exc) -> None:
        self.stop()


class TickingLine:
    """A tqdm line showing ``label`` and the seconds spent, refreshed by a thread (numba compiles without
    reporting progress, so an ETA would be invented) until :meth:`close`."""

    def __init__(self, label: str):
        from tqdm import tqdm

        self._line = tqdm(total=None, desc=label, file=sys.stderr, bar_format="{desc}: {elapsed} elapsed", leave=True)
        self._finished = threading.Event()
        self._ticker = threading.Thread(target=self._tick, daemon=True)
        self._ticker.start()

    def relabel(self, label: str) -> None:
        self._line.set_description_str(label, refresh=True)

    def _tick(self) -> None:
        while not self._finished.wait(0.5):
            self._line.refresh()

    def close(self) -> None:
        self._finished.set()
        self._ticker.join()
        self._line.close()


class Terminated(KeyboardInterrupt):
    """SIGTERM received: handled as an interruption, so the log is closed with status "interrupted"."""


#: SIGTERMs received during the current run. The first is only recorded: the run's next progress call (about
#: every 0.1 s of wall time in the compiled loop, every sample instant in the Python loop) raises Terminated
#: there, at a point where the run's own code is in control. A second SIGTERM, sent because the first seemed
#: ignored, raises at once unless numba is compiling (see _raise_terminated).
_SIGTERMS: list = []


def _numba_is_compiling() -> bool:
    """This thread holds numba's compiler lock: a compilation (or a load from the on-disk cache) is under way."""
    try:
        from numba.core.compiler_lock import global_compiler_lock

        return bool(global_compiler_lock.is_locked())
    except (ImportError, AttributeError):  # numba's internals moved: defer, the safe side (see _raise_terminated)
        return True


def _raise_terminated(signum, frame) -> None:
    """SIGTERM: recorded; the run's next progress call raises Terminated. Only a repeated SIGTERM raises here, and
    not while numba compiles.

    Why not raise at once: a handler's exception appears wherever the main thread runs Python, including inside
    the finalizers and bookkeeping of extension libraries (llvmlite's ``__del__`` between disposing of an LLVM
    object and marking it disposed, numba's compiler between a call into LLVM and what it records of it); such a
    cut can free memory twice. tests/safety/test_logs.py's SIGTERM test ended in SIGSEGV instead of exit 143 in
    CI (2026-11-27, a cold cache) and again in a helper's run under load (2026-11-28) after compilations were
    already deferred; raising only at the run's progress calls removes the hazard at the cost of up to about
    0.1 s of latency."""
    _SIGTERMS.append(signum)
    if len(_SIGTERMS) > 1 and not _numba_is_compiling():
        raise Terminated("terminated (SIGTERM)")


def _dropped_sigterm_unprinted(hook):
    """``sys.unraisablehook`` that leaves out a Terminated that Python dropped (raised by the handler inside a weakref
    callback or a __del__): it is recorded in _SIGTERMS and raised at the next progress call, so the printed
    "Exception ignored ... Traceback" would only alarm (a user, and tests/safety/test_logs.py, which failed on it
    once under two pytest workers); every other unraisable exception goes to ``hook``."""
    def unraisable(record) -> None:
        if not isinstance(record.exc_value, Terminated):
            hook(record)
    return unraisable


def _watching_sigterm(progress):
    """``progress`` that first raises Terminated if a SIGTERM arrived (the handler records the first one only, and a
    repeated one's exception may have been dropped by Python or deferred by a compilation: _raise_terminated)."""
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
    from shell.outputs import LOG, RESTART, OutputError, guard_output
    from shell.scenario import ScenarioError, check_sample_counts, load_scenario
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
        inputs = ((args.scenario, "the scenario itself"), (args.restore, "the restart file of --restore"))
        if output is not None:
            try:
                guard_output(output, LOG, inputs=inputs, overwrite=args.overwrite, others=(args.save_state,))
            except OutputError as exc:
                if args.output:
                    raise
                raise OutputError(f"{scenario.location('log', 'file')}: {exc}") from None
        if args.save_state:
            guard_output(args.save_state, RESTART, inputs=inputs, overwrite=args.overwrite)
    except (ScenarioError, UnitError, ValueError, OSError) as exc:
        print(f"flexshell run: {exc}", file=sys.stderr)
        return 1
    with CompileNotice(args.quiet) as notice:
        return _build_and_run(args, scenario, t_final, output, notice)


def _build_and_run(args, scenario, t_final, output, notice: CompileNotice) -> int:
    from shell.log_file import LogError
    from shell.outputs import LOG, clear_for_writing
    from shell.scenario import ScenarioError, build_simulation
    from shell.simulation import SimulationError
    from shell.units import UnitError

    try:
        simulation = build_simulation(scenario)
        if args.restore:
            simulation.load_state(args.restore)
    except (ScenarioError, UnitError, ValueError, OSError) as exc:
        notice.stop()
        print(f"flexshell run: {exc}", file=sys.stderr)
        return 1
    bar = ProgressBar(simulation.t, t_final, enabled=not args.quiet and sys.stderr.isatty())

    def progress(t: float) -> None:  # the first report comes after the loop is compiled (or loaded)
        notice.stop()
        bar(t)

    def close() -> None:
        notice.stop()
        bar.close()

    if output and args.overwrite:  # the log writer replaces only a log: the foreign file approved goes now
        clear_for_writing(output, LOG)
    in_main_thread = threading.current_thread() is threading.main_thread()  # signal handlers live there
    _SIGTERMS.clear()
    previous_handler = signal.signal(signal.SIGTERM, _raise_terminated) if in_main_thread else None
    previous_hook, sys.unraisablehook = sys.unraisablehook, _dropped_sigterm_unprinted(sys.unraisablehook)
    try:
        summary = simulation.run(t_final, log_path=output, progress=_watching_sigterm(progress),
                                 log_attributes={"scenario": scenario.text, "scenario_file": str(args.scenario)})
    except (SimulationError, LogError) as exc:
        close()
        print(f"flexshell run: {exc}", file=sys.stderr)
        if output and isinstance(exc, SimulationError):
            print(f"flexshell run: the log {output} keeps every sample up to the failure", file=sys.stderr)
        return 1
    except KeyboardInterrupt as exc:
        close()
        cause = str(exc) or "interrupted"
        print(f"flexshell run: {cause} at t = {simulation.t:.6g} s"
              + (f"; the log {output} keeps every sample up to there" if output else ""), file=sys.stderr)
        return 143 if isinstance(exc, Terminated) else 130
    finally:
        sys.unraisablehook = previous_hook
        if in_main_thread:
            signal.signal(signal.SIGTERM, previous_handler)
    close()
    if _SIGTERMS:  # after the last progress call, its exception dropped or deferred: the run had reached its end
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
