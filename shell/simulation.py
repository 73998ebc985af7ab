"""The simulation: a diagram, the context of one run, and the loop that drives the integrator.

Build time (once): :class:`shell.diagram.Diagram` flattens the assembly, lays out the buffers, wires and
orders the evaluation (see its module docstring); :meth:`Diagram.create_context` makes this run's
:class:`shell.diagram.Context` (states, signals, parameters, per-model data, random streams, schedule).

Run loop (TM-2020-5008164 App. D.1: multi-rate models, zero finding): integrate continuously up to the
next instant at which a sampled model updates or a log group samples (exact rational sample instants),
checking the models' zero-crossing functions after each step. Every crossing (the default
``event_detection="subdivided"`` samples each step on the dense output, so two crossings inside one step
are both found; ``"sign_change"`` searches only steps whose ends differ in sign, cheaper but blind to
such pairs) is located to ``event_tol`` on the integrator's dense output
(:func:`shell.integrators.locate_events`), the state is moved to the crossing, the models' ``on_event``
handlers run (state reset, mode switch) in (time, model order), and the integrator restarts; a terminal
crossing stops the run. At a sample instant the due sampled models update one after another in dataflow
order (upstream first, ties by declaration order), each seeing the outputs the previous ones just
produced; their outputs are then held until their next sample.
"""

from __future__ import annotations

import gc
import json
import math
import warnings
import time as _time
import weakref
from dataclasses import dataclass
from fractions import Fraction

import h5py
import numpy as np

from shell import compiled_loop as CL
from shell.assembly import Assembly
from shell.compiled_plan import compile_plan
from shell.diagram import AlgebraicLoopError, Diagram, EvaluationError, WiringError, gather_inputs
from shell.integrators import INTEGRATORS, locate_events, make_integrator, quaternion_gauge
from shell.log_file import LoggedSignal, LogWriter, MemoryLog
from shell.model import ModelError, parse_period
from shell.units import format_unit


class SimulationWarning(UserWarning):
    """Allowed but worth knowing: a scene that runs interpreted, a Python model in the compiled loop."""


_WARNED_PYTHON_UPDATES: set = set()


def _warn_python_updates(models) -> None:
    """Once per model type and rate: the compiled loop returns to Python at these models' samples."""
    new = [m for m in models if (type(m).__name__, m.period) not in _WARNED_PYTHON_UPDATES]
    if not new:
        return
    _WARNED_PYTHON_UPDATES.update((type(m).__name__, m.period) for m in new)
    listed = ", ".join(f"{m.path} ({type(m).__name__}, every {float(m.period):g} s)" for m in new)
    warnings.warn(f"the compiled loop returns to Python at the samples of {listed}: their updates are Python "
                  "(python_update); everything else stays compiled", SimulationWarning, stacklevel=3)


#: per diagram, the logged signals already described: {name: (LoggedSignal, kind, slice)}
_LOGGED: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


class SimulationError(RuntimeError):
    """A run that could not continue; the message names the model and the time."""


@dataclass
class RunSummary:
    status: str          # "completed" | "stopped" (terminal event)
    reason: str
    t_start: float
    t_end: float
    wall_time: float
    steps: int
    derivative_evaluations: int
    events: int
    discrete_updates: int
    notes: tuple = ()    # choices made for the user (models' ``notes``: engine solver, modal-integral order)

    @property
    def real_time_factor(self) -> float:
        return (self.t_end - self.t_start) / self.wall_time if self.wall_time > 0 else float("inf")

    def __str__(self) -> str:
        return (f"{self.status} at t = {self.t_end:.6g} s ({self.reason}); wall time {self.wall_time:.3f} s, "
                f"{self.steps} steps, {self.derivative_evaluations} derivative evaluations, "
                f"{self.discrete_updates} discrete updates, {self.events} events, "
                f"real-time factor {self.real_time_factor:.3g}" + "".join(f"\n  note: {n}" for n in self.notes))


class _EventFunction:
    """g_i(t, y) for locate_events: evaluates the whole system at (t, y) and returns component i."""

    def __init__(self, simulation: "Simulation", index: int, direction: int, terminal: bool):
        self.simulation = simulation
        self.index = index
        self.direction = direction
        self.terminal = terminal

    def __call__(self, t, y):
        return float(self.simulation._zero_crossing_vector(float(t), y)[self.index])


class Simulation:
    """A runnable scene: a :class:`shell.diagram.Diagram`, the :class:`shell.diagram.Context` of this run,
    the integrator, the sample schedule and the log."""

    def __init__(self, root: Assembly, *, integrator: str = "rk4", step: float | None = 0.01,
                 integrator_options: dict | None = None, seed=0, stop_events=(), event_tol: float = 1e-10,
                 event_detection: str = "subdivided", t_start: float = 0.0, diagram: Diagram | None = None,
                 mode: str = "compiled", context=None):
        self.seed = seed
        self.event_tol = float(event_tol)
        if event_detection not in ("sign_change", "subdivided"):
            raise ModelError(f"event detection {event_detection!r}: expected 'sign_change' (search a step when a "
                             "zero-crossing function changes sign between its ends) or 'subdivided' (search every "
                             "step on its dense output: also finds two crossings inside one step)")
        self.event_detection = event_detection
        #: the scene's immutable plan (shared by every run of the scene)
        self.diagram = diagram if diagram is not None else Diagram(root, stop_events=stop_events)
        self.root = self.diagram.root
        d = self.diagram
        self.models, self.connections, self.model_index = d.models, d.connections, d.model_index
        self.port_slices, self.port_info, self.state_slices, self.driver = (d.port_slices, d.port_info,
                                                                            d.state_slices, d.driver)
        if context is None:
            for m in self.models:  # the first context shares the models' own data (the engine's workspace)
                owner = getattr(m, "_simulation", None)
                if owner is not None and owner() is not None:
                    gc.collect()  # a discarded simulation may still be waiting in a reference cycle
                if owner is not None and owner() is not None:
                    raise ModelError(f"model {m.path} already belongs to another Simulation (its random stream and "
                                     "workspace would be shared); build the scene again for a second simulation, "
                                     "or run another context of the same diagram (Diagram.create_context(own_data="
                                     "True), Simulation(diagram=..., context=...))")
        elif context.diagram is not d:
            raise ModelError("Simulation: the context belongs to another diagram")
        #: the state of this run (time, states, signals, parameters, per-model data, random streams)
        self.context = d.create_context(seed, t_start) if context is None else context
        for i, m in enumerate(self.models):
            m.rng = self.context.rngs[i]
            m._simulation = weakref.ref(self)
        self.integrator_name = integrator
        self.integrator_options = dict(integrator_options or {})
        if step is not None:
            self.integrator_options["step"] = step
        if mode not in ("compiled", "interpreted"):
            raise ModelError(f"simulation mode {mode!r}: expected 'compiled' (the default: the scene runs in "
                             "flexshell's compiled loop) or 'interpreted' (every kernel called from Python: the "
                             "reference, and the fallback for scenes with Python kernels)")
        self._plan, self.interpreted_reason = None, None
        if mode == "compiled":
            self._plan, self.interpreted_reason = compile_plan(d, self.context)
            if self._plan is None:
                warnings.warn(f"the scene runs interpreted (every kernel called from Python, slower): "
                              f"{self.interpreted_reason}", SimulationWarning, stacklevel=2)
        #: "compiled" or "interpreted" (see ``interpreted_reason``)
        self.mode = "compiled" if self._plan is not None else "interpreted"
        if self._plan is not None and self._plan.python_updates:
            _warn_python_updates([self.models[i] for i in self._plan.python_updates])
        #: the integrator's right-hand side f(t, x): compiled, or the interpreted reference ``derivative``
        self.rhs = self._plan.derivative if self._plan is not None else self.derivative
        self._integrator = None
        self._integrator_stale = True
        self._stepper = None
        # the exponential stepper's linear part, the time its state is current at, its slope's state (CL.F_DUE)
        self._stepper_part, self._stepper_t, self._stepper_f_state = None, None, 0
        self._event_functions = [_EventFunction(self, j, zc.direction, d.zero_crossing_terminal[j])
                                 for j, (_, _, zc) in enumerate(d.zero_crossing_owner)]
        self._last_events: tuple[float, set] = (-np.inf, set())
        self._log_groups: dict[str, dict] = {}
        self._log_stages_key, self._log_stages_value = None, ()
        self._initialized = False
        self.counters = {"steps": 0, "nfev": 0, "events": 0, "updates": 0}
        #: (time, "model.zero_crossing") of every handled event, in order
        self.events: list[tuple[float, str]] = []

    @classmethod
    def of_scenario(cls, scenario, root: Assembly | None = None, *, diagram: Diagram | None = None,
                    context=None) -> "Simulation":
        """The Simulation of a validated scenario (:class:`shell.scenario.Scenario`): its integrator and options,
        seed, stop events and event settings, and its log: the scene ``root``, or a new ``context`` of a
        ``diagram`` built before (a Monte Carlo run). A log signal the scene does not have is refused at the
        scenario's line for it."""
        seed = scenario.seed if context is None else context.seed
        simulation = cls(root, integrator=scenario.integrator, step=scenario.step,
                         integrator_options=scenario.integrator_options, seed=seed, stop_events=scenario.stop_events,
                         event_tol=scenario.event_tolerance, event_detection=scenario.event_detection, diagram=diagram,
                         context=context)
        for name, rate, here in scenario.log_signals:
            try:
                simulation.log([name], rate)
            except ModelError as exc:
                raise here.error(str(exc)) from None
        return simulation

    @property
    def plan(self):
        """The compiled form of this run (:class:`shell.compiled_plan.CompiledPlan`), None when interpreted."""
        return self._plan

    # the current run's buffers (views of the context)
    @property
    def t(self) -> float:
        return self.context.t

    @t.setter
    def t(self, value: float) -> None:
        self.context.t = float(value)

    @property
    def x(self) -> np.ndarray:
        return self.context.x

    @property
    def z(self) -> np.ndarray:
        return self.context.z

    @property
    def signals(self) -> np.ndarray:
        return self.context.signals

    @property
    def xdot(self) -> np.ndarray:
        return self.context.xdot

    def set_state(self, x=None, z=None) -> None:
        """Replace the continuous and/or discrete state of the run (trim, user edits); the integrator
        restarts from it at the next step."""
        if x is not None:
            x = np.asarray(x, dtype=float)
            if x.shape != self.x.shape:
                raise ModelError(f"set_state: x has shape {x.shape}, the scene's continuous state has {self.x.shape}")
            self.x[:] = x
        if z is not None:
            z = np.asarray(z, dtype=float)
            if z.shape != self.z.shape:
                raise ModelError(f"set_state: z has shape {z.shape}, the scene's discrete state has {self.z.shape}")
            self.z[:] = z
        self._integrator_stale = True

    # ------------------------------------------------------------------------------------------------
    # evaluation
    def derivative(self, t: float, y: np.ndarray) -> np.ndarray:
        """f(t, x): the integrator's right-hand side (continuous states of every model)."""
        try:
            return self.diagram.derivatives(self.context, t, y)
        except EvaluationError as exc:
            raise SimulationError(str(exc)) from exc.__cause__

    def evaluate(self, t: float | None = None) -> None:
        """Compute every output and input at the current state (used at sample and log instants)."""
        if self._plan is not None:
            self._plan.evaluate(self.t if t is None else t)
            return
        try:
            self.diagram.evaluate(self.context, t)
        except EvaluationError as exc:
            raise SimulationError(str(exc)) from exc.__cause__

    def _evaluate_stages(self, t: float, stages) -> None:
        """The outputs of ``stages``, then every input (a log's evaluation)."""
        if self._plan is not None:
            self._plan.evaluate(t, stages)
            return
        try:
            self.diagram.evaluate(self.context, t, stages)
        except EvaluationError as exc:
            raise SimulationError(str(exc)) from exc.__cause__

    def _log_stages(self) -> tuple:
        """The output stages the logged signals need (computed once per set of logged signals)."""
        names = tuple(s.name for group in self._log_groups.values() for s, _, _ in group["signals"])
        if self._log_stages_key != names:
            self._log_stages_key = names
            self._log_stages_value = self.diagram.stages_of_signals(names)
        return self._log_stages_value

    def _zero_crossing_vector(self, t: float, y: np.ndarray) -> np.ndarray:
        if self._plan is not None:
            return self._plan.zero_crossings(t, y)
        try:
            return self.diagram.zero_crossings(self.context, t, y)
        except EvaluationError as exc:
            raise SimulationError(str(exc)) from exc.__cause__

    # ------------------------------------------------------------------------------------------------
    # signals by name
    def signal(self, name: str) -> np.ndarray:
        """Current value of a port or state by dotted name (a copy, in the port's/state's unit)."""
        kind, sl, decl = self.diagram.locate(name)
        source = {"signal": self.signals, "x": self.x, "z": self.z}[kind]
        return source[sl].reshape(decl.shape).copy()

    # ------------------------------------------------------------------------------------------------
    # logging
    def log(self, signals, rate) -> None:
        """Log ``signals`` (dotted port/state names) every ``rate`` ("10 Hz", "0.1 s", seconds)."""
        period = parse_period(rate, "log rate")
        group = f"every_{float(period):g}s"
        entries = self._log_groups.setdefault(group, {"period": period, "signals": [], "next": None})
        known = _LOGGED.setdefault(self.diagram, {})
        for name in signals:
            if name not in known:  # the same for every run of the diagram (formatting a unit costs ~0.1 ms)
                kind, sl, decl = self.diagram.locate(name)
                known[name] = (LoggedSignal(name, tuple(decl.shape), format_unit(decl.unit), decl.description), kind,
                               sl)
            if any(s.name == name for s, _, _ in entries["signals"]):
                continue
            entries["signals"].append(known[name])

    def log_groups(self) -> dict:
        """{group name: [LoggedSignal, ...]} of what :meth:`log` requested (a writer's layout)."""
        return {g: [s for s, _, _ in e["signals"]] for g, e in self._log_groups.items()}

    def _next_log_time(self, group: dict) -> Fraction:
        if group["next"] is None:
            start = Fraction(self.t).limit_denominator(10**9)
            group["next"] = -(-start // group["period"]) * group["period"]
        return group["next"]

    def _log_row(self, group: dict) -> list[np.ndarray]:
        sources = {"signal": self.signals, "x": self.x, "z": self.z}
        return [sources[kind][sl].reshape(s.shape) for s, kind, sl in group["signals"]]

    # ------------------------------------------------------------------------------------------------
    # running
    def _make_integrator(self, t_bound: float):
        normalize = None
        if self.diagram.normalizers:
            diagram, context = self.diagram, self.context

            def normalize(y):
                diagram.normalize(context, y)
        options = dict(self.integrator_options)
        w_indices = self.diagram.quaternion_w_indices()
        if w_indices.size and "error_exclude" not in options:
            # quaternion norms are fixed by normalize; their error along the quaternion is gauge, not error
            options["error_exclude"] = quaternion_gauge(w_indices)
        # exponential integrators get the stiff linear part of every model that has one
        method = INTEGRATORS.get(str(self.integrator_name).lower(), self.integrator_name)
        if getattr(method, "uses_linear_part", False) and "linear_part" not in options:
            parts = [(self.diagram.x_block[i], m, self.context.hosts[i]) for i, m in enumerate(self.models)
                     if hasattr(m, "stiff_linear_part")]

            def linear_part(t, y):
                """Block-diagonal union of the models' (local indices, L), offset to the full state."""
                pieces = [(block.start, *model.stiff_linear_part(y[block], host)) for block, model, host in parts]
                indices = [start + np.asarray(local, dtype=np.int64) for start, local, _ in pieces]
                m = sum(index.size for index in indices)
                L = np.zeros((m, m))
                k = 0
                for (_, _, block_L), index in zip(pieces, indices):
                    L[k:k + index.size, k:k + index.size] = block_L
                    k += index.size
                return (np.concatenate(indices) if indices else np.zeros(0, dtype=np.int64)), L
            options["linear_part"] = linear_part
        return make_integrator(self.integrator_name, self.rhs, self.t, self.x.copy(), t_bound,
                               normalize=normalize, **options)

    def _initialize(self) -> None:
        if self._initialized:
            return
        self._check_finite_state("initial state")
        self._initialized = True

    def run(self, t_final: float, log_path=None, progress=None, log_attributes: dict | None = None) -> RunSummary:
        """Run from the current time to ``t_final`` (s); log to ``log_path`` (HDF5) if given.

        ``progress(t)`` is called after every sample instant. A failure raises
        :class:`SimulationError` naming the model and time; the log keeps every sample taken before it
        and records ``status="failed"`` and the message.
        """
        t_final = float(t_final)
        if t_final < self.t:
            raise ValueError(f"t_final = {t_final} s is before the current time {self.t} s")
        writer = None
        if log_path is not None:
            if not self._log_groups:
                raise ModelError("nothing to log: call Simulation.log(signals, rate) (or list log: signals "
                                 "in the scenario) before running with a log file")
            if isinstance(log_path, MemoryLog):
                writer = log_path
            else:
                attrs = {"seed": json.dumps(self.seed)} | dict(log_attributes or {})
                writer = LogWriter(log_path, self.log_groups(), attrs)
        start_counters = dict(self.counters)
        t_start = self.t
        wall_start = _time.perf_counter()
        status, reason = "completed", "reached t_final"
        blas = self._single_threaded_blas()
        try:
            self._initialize()
            self.context.unstarted = False
            end = Fraction(t_final).limit_denominator(10**9)
            compiled = self._compiled_run(end, writer, progress) if self._compiled_loop_applies() else None
            if compiled is not None:
                status, reason = compiled
            while compiled is None:
                instant = self._next_instant(end)
                target = float(instant)
                if target > self.t:
                    update_due = any(s == instant for s in self.context.next_sample if s is not None)
                    stopped = self._advance(target, update_due)
                    if stopped is not None:
                        status, reason = "stopped", stopped
                        self._sample_logs(writer, force=True)
                        break
                self.t = target
                self._discrete_updates(instant)
                self._sample_logs(writer, instant)
                if progress is not None:
                    progress(self.t)
                if instant >= end:
                    break
        except KeyboardInterrupt as exc:  # Ctrl-C, or a signal turned into one (flexshell run: SIGTERM)
            if writer is not None:
                writer.close("interrupted", f"{exc or 'interrupted by the user'} at t = {self.t:.9g} s")
            raise
        except Exception as exc:
            message = str(exc) if isinstance(exc, SimulationError) else \
                f"{type(exc).__name__} at t = {self.t:.9g} s: {exc}"
            if writer is not None:
                writer.close("failed", message)
            if isinstance(exc, SimulationError):
                raise
            raise SimulationError(message) from exc
        finally:
            if blas is not None:
                blas.restore_original_limits()
        if writer is not None:
            writer.close(status, reason)
        self.evaluate()  # outputs consistent with the final state for signal() queries
        wall = _time.perf_counter() - wall_start
        return RunSummary(status, reason, t_start, self.t, wall, self.counters["steps"] - start_counters["steps"],
                          self.counters["nfev"] - start_counters["nfev"],
                          self.counters["events"] - start_counters["events"],
                          self.counters["updates"] - start_counters["updates"],
                          tuple(note for m in self.diagram.models for note in getattr(m, "notes", ())))

    # ------------------------------------------------------------------------------------------------
    # the compiled loop (shell.compiled_loop): the same instants, updates, steps and log rows as below
    def _compiled_loop_applies(self) -> bool:
        """Fixed-step explicit Runge-Kutta and the exponential RK4 run in the compiled loop; adaptive and
        implicit methods run the Python loop on the compiled derivative."""
        from shell.integrators import INTEGRATORS
        from shell.integrators.exponential import ExponentialRK4
        from shell.integrators.fixed import FixedStepRungeKutta

        cls = INTEGRATORS.get(str(self.integrator_name).lower())
        if self._plan is not None and cls is ExponentialRK4:
            return self.integrator_options.get("step") is not None
        if self._plan is None or cls is None or not issubclass(cls, FixedStepRungeKutta):
            return False
        # events are located on the dense output: the compiled loop evaluates the cubic Hermite one
        hermite = cls.name in ("euler", "heun", "rk4")
        return self.integrator_options.get("step") is not None and (self.diagram.n_zero_crossings == 0 or hermite)

    def _time_base(self, end: Fraction):
        """Common denominator of every instant of this run, or None when ticks would exceed 2**53."""
        fractions = [end, Fraction(self.t).limit_denominator(10**9)]
        fractions += [f for f in self.context.next_sample if f is not None]
        fractions += [p for p in self.context.periods if p is not None]
        for group in self._log_groups.values():
            fractions += [group["period"], self._next_log_time(group)]
        den = 1
        for f in fractions:
            den = den * f.denominator // math.gcd(den, f.denominator)
        limit = 2 ** 53
        if den >= limit or max(abs(f) for f in fractions) * den >= limit:
            return None
        return den

    def _compiled_exponential_stepper(self):
        """The exponential RK4's stepper (:class:`shell.compiled_loop.ExponentialStepper`), or a placeholder
        (step 0) until the integrator exists: the loop then returns NEW_INTEGRATOR where the Python loop would
        make it (at the start of the first integration, after the updates at that instant), so that its linear
        part and driven rows are built at the same state. The :class:`ExponentialRK4` object stays the home
        of the linear part, its matrix functions and check counters (the compiled loop reads and writes them
        back), and of the events' dense output."""
        from shell.integrators.exponential import ExponentialRK4

        integ = self._integrator
        if not isinstance(integ, ExponentialRK4):
            self._stepper, self._stepper_part = CL.exponential_placeholder(self.x.size), None
        elif not isinstance(self._stepper, CL.ExponentialStepper) or self._stepper_part is not integ.part:
            # the Python loop's integrator moved on: the loop restarts from the context (no slope needed here)
            self._stepper = CL.exponential_stepper(integ, integ.y, np.zeros_like(integ.y))
            self._stepper_part = integ.part
            self._integrator_stale = True
        return self._stepper

    def _new_exponential_integrator(self, ints, reals, end):
        """NEW_INTEGRATOR: make the integrator at the loop's time and state (Simulation._restart_integrator,
        as the Python loop does at its first integration) and return its stepper, with its slope."""
        self.t = float(reals[CL.R_T])
        self._integrator = None
        integ = self._restart_integrator(float(end))
        self._stepper, self._stepper_part = CL.exponential_stepper(integ), integ.part
        ints[CL.I_F_VALID] = 1
        ints[CL.I_SINCE_CHECK] = integ.steps_since_check
        ints[CL.I_CHECK_INTERVAL] = integ.check_interval
        reals[CL.R_PHI_H] = np.nan
        return self._stepper

    def _compiled_stepper(self):
        from shell.integrators import INTEGRATORS

        cls = INTEGRATORS[str(self.integrator_name).lower()]
        options = self.integrator_options
        step = float(options["step"])
        if not (step > 0.0 and math.isfinite(step)):
            raise ModelError(f"integrator step must be a positive number of seconds, got {options['step']!r}")
        h = min(step, float(options.get("max_step", np.inf)))
        if not isinstance(self._stepper, CL.Stepper) or self._stepper.h != h or self._stepper.A is not cls.tableau.A:
            tb, n = cls.tableau, self.x.size
            self._stepper = CL.Stepper(tb.A, tb.b, tb.c, tb.n_stages, h, self.x.copy(), np.zeros(n),
                                       np.zeros((tb.n_stages, n)), np.zeros(n), np.zeros(n))
            self._integrator_stale = True
        return self._stepper

    def _compiled_run(self, end: Fraction, writer, progress):
        """Run to ``end`` in the compiled loop; None when its time base does not fit (the caller then runs
        the Python loop)."""
        den = self._time_base(end)
        if den is None:
            return None
        d, context, plan = self.diagram, self.context, self._plan
        exponential = getattr(INTEGRATORS.get(str(self.integrator_name).lower()), "uses_linear_part", False)
        if exponential:
            stepper = self._compiled_exponential_stepper()
        else:
            stepper = self._compiled_stepper()
        n_models = len(self.models)
        next_tick = np.full(n_models, -1, dtype=np.int64)
        period = np.zeros(n_models, dtype=np.int64)
        for i in d.update_order:
            next_tick[i] = int(context.next_sample[i] * den)
            period[i] = int(context.periods[i] * den)
        groups = list(self._log_groups.values())
        kinds, indices, starts = [], [], [0]
        for group in groups:
            for signal, kind, sl in group["signals"]:
                kinds += [{"signal": 0, "x": 1, "z": 2}[kind]] * (sl.stop - sl.start)
                indices += list(range(sl.start, sl.stop))
            starts.append(len(kinds))
        widths = [starts[g + 1] - starts[g] for g in range(len(groups))]
        capacity = 512
        log_table = plan.stage_table(self._log_stages())
        schedule = CL.Schedule(
            den, int(end * den), next_tick, period, np.asarray(d.update_order, dtype=np.int64),
            np.asarray([int(self._next_log_time(g) * den) for g in groups], dtype=np.int64),
            np.asarray([int(g["period"] * den) for g in groups], dtype=np.int64),
            np.asarray(kinds, dtype=np.int64), np.asarray(indices, dtype=np.int64), np.asarray(starts, dtype=np.int64),
            np.zeros((len(groups), capacity)), np.zeros((len(groups), capacity, max(widths, default=0))),
            np.zeros(len(groups), dtype=np.int64), log_table)
        ints = np.zeros(CL.N_INTS, dtype=np.int64)
        reals = np.zeros(CL.N_REALS)
        reals[CL.R_T] = self.t
        ints[CL.I_F_VALID] = 0 if self._integrator_stale else 1
        ints[CL.I_NOW] = int(Fraction(self.t).limit_denominator(10**9) * den)
        if exponential and self._stepper_part is not None:
            ints[CL.I_SINCE_CHECK] = self._integrator.steps_since_check
            ints[CL.I_CHECK_INTERVAL] = self._integrator.check_interval
            reals[CL.R_PHI_H] = np.nan
            if self._integrator_stale or self._stepper_t != self.t:
                ints[CL.I_F_VALID] = 0
            else:
                ints[CL.I_F_VALID] = self._stepper_f_state
        names = list(self._log_groups)

        def flush():
            for g, group in enumerate(groups):
                count = int(schedule.log_count[g])
                if count and writer is not None:
                    writer.append_rows(names[g], schedule.log_times[g, :count],
                                       schedule.log_rows[g, :count, :widths[g]])
                schedule.log_count[g] = 0

        def sync():
            self.t = float(reals[CL.R_T])
            for i in d.update_order:
                context.next_sample[i] = Fraction(int(next_tick[i]), den)
            for g, group in enumerate(groups):
                group["next"] = Fraction(int(schedule.log_next[g]), den)
            done = ints[[CL.I_STEPS, CL.I_NFEV, CL.I_UPDATES]]
            self.counters["steps"] += int(done[0])
            self.counters["nfev"] += int(done[1])
            self.counters["updates"] += int(done[2])
            ints[[CL.I_STEPS, CL.I_NFEV, CL.I_UPDATES]] = 0
            self._integrator_stale = ints[CL.I_F_VALID] == 0
            if exponential and self._stepper_part is not None:
                self._integrator.steps_since_check = int(ints[CL.I_SINCE_CHECK])
                self._integrator.check_interval = int(ints[CL.I_CHECK_INTERVAL])
                self._stepper_t = self.t
                self._stepper_f_state = int(ints[CL.I_F_VALID])

        budget = 64
        integrate = self.x.size > 0
        b = plan.buffers
        n_g, n_x = self.diagram.n_zero_crossings, self.x.size
        mode = CL.NO_EVENTS if n_g == 0 else (CL.SUBDIVIDED if self.event_detection == "subdivided" else
                                             CL.SIGN_CHANGE)
        events = CL.Events(mode, np.asarray([f.direction for f in self._event_functions], dtype=np.int64), np.zeros(n_g),
                           np.zeros(n_g), np.zeros((CL.SUBDIVISIONS + 1, n_g)), np.zeros(n_x), np.zeros(n_x),
                           np.zeros(n_x))
        reals[CL.R_LAST_EVENT] = self._last_events[0]
        stop_reason = None
        try:
            while True:
                started = _time.perf_counter()
                status = CL.advance(plan.kernels, plan.engine, plan.rngs, b, stepper, events, schedule, ints, reals,
                                    budget, writer is not None, integrate)
                elapsed = _time.perf_counter() - started
                if status == CL.DONE:
                    break
                if status == CL.PYTHON_UPDATE:
                    self._python_updates(ints, reals, next_tick, period)
                elif status == CL.LOG_FULL:
                    flush()
                elif status == CL.BUDGET:
                    budget = int(min(max(budget * 0.1 / max(elapsed, 1e-6), 16), 1 << 20))
                elif status == CL.EVENT_CANDIDATE:
                    stop_reason = self._compiled_event(events, stepper, ints, reals)
                    if stop_reason is not None:
                        break
                elif status in (CL.LINEAR_CHECK, CL.STIFF_REMAINDER):
                    stepper = self._check_linear_part(self._integrator, stepper, ints, reals,
                                                      status == CL.STIFF_REMAINDER)
                elif status == CL.NEW_INTEGRATOR:
                    stepper = self._new_exponential_integrator(ints, reals, end)
                else:
                    sync()
                    self._raise_compiled_failure(status, stepper, reals)
                if progress is not None and status != CL.PYTHON_UPDATE:
                    self.t = float(reals[CL.R_T])
                    progress(self.t)
        finally:
            flush()
            sync()
        if stop_reason is not None:
            self._sample_logs(writer, force=True)
            return "stopped", stop_reason
        if progress is not None:
            progress(self.t)
        return "completed", "reached t_final"

    def _compiled_event(self, events, stepper, ints, reals) -> str | None:
        """A step of the compiled loop that may contain a crossing: locate it on the step's cubic Hermite
        dense output (as the fixed-step integrators' ``dense_output``) and handle it; the loop restarts at
        the event (or, with no crossing after all, goes on from the step's end)."""
        from shell.integrators.base import HermiteDenseOutput

        t_old, t_new = float(reals[CL.R_T_OLD]), float(reals[CL.R_T])
        samples = None
        if isinstance(stepper, CL.ExponentialStepper):
            from shell.integrators.exponential import ExponentialDenseOutput

            sol = ExponentialDenseOutput(t_old, t_new, events.y_old, stepper.N, self._stepper_part)
            samples = events.samples[1:-1].copy()  # the loop sampled the dense output already (same numbers)
        else:
            sol = HermiteDenseOutput(t_old, t_new, events.y_old, events.f_old, stepper.Y, stepper.F)
        handled, stop = self._locate_and_handle(sol, t_old, t_new, events.g_old.copy(), events.g_new.copy(),
                                                self._plan.normalize, samples)
        if handled:
            reals[CL.R_T] = self.t
            reals[CL.R_LAST_EVENT] = self.t
            ints[CL.I_F_VALID] = 0
        else:
            self.x[:] = stepper.Y
        return stop

    def _check_linear_part(self, integ, stepper, ints, reals, stiff: bool):
        """The compiled exponential RK4 asks for a check of its linear part (due by the check counters, or
        forced by a stiff remainder): ExponentialRK4._check_drift's work, in Python; a rebuilt linear part gives
        a new stepper (the state and slope carried over). Returns the stepper to continue with."""
        t, h = float(reals[CL.R_T]), stepper.h
        if stiff:
            integ.last_rho = float(reals[CL.R_RHO]) / h
            if not stepper.check_drift:  # a fixed (indices, L): the interpreted integrator warns and goes on
                saved, integ.t = integ.t, t
                integ._warn_stiff(h)
                integ.t = saved
                return stepper
        before = integ.nfev
        integ.steps_since_check = 0
        integ.check_interval = int(ints[CL.I_CHECK_INTERVAL])
        rebuilt = integ.check_linear_part(t, stepper.Y.copy())
        ints[CL.I_SINCE_CHECK] = 0
        ints[CL.I_CHECK_INTERVAL] = integ.check_interval
        ints[CL.I_NFEV] += integ.nfev - before
        if not rebuilt:
            return stepper
        if stiff:  # the step is taken again from its start with the new linear part
            ints[CL.I_STEP_FLAGS] &= ~CL.RESUME
            integ.nrejected += 1
        self._stepper = CL.exponential_stepper(integ, stepper.Y, stepper.F)
        self._stepper_part = integ.part
        reals[CL.R_PHI_H] = np.nan
        return self._stepper

    def _python_updates(self, ints, reals, next_tick, period) -> None:
        """The updates at the current instant when a Python-only model is due (all due models, in order)."""
        t = float(reals[CL.R_T])
        self.t = t
        now = int(ints[CL.I_NOW])
        plan = self._plan
        for i in self.diagram.update_order:
            if next_tick[i] != now:
                continue
            if plan.update_is_compiled(i):
                plan.update(t, i)  # the same numbers as Diagram.update, without a Python dispatch per stage
            else:
                try:
                    self.diagram.update(self.context, i, t)
                except EvaluationError as exc:
                    raise SimulationError(str(exc)) from exc.__cause__
            next_tick[i] += period[i]
            ints[CL.I_UPDATES] += 1
        self._check_finite_state(f"the discrete updates at t = {t:.9g} s")
        ints[CL.I_F_VALID] = 0

    def _raise_compiled_failure(self, status, stepper, reals) -> None:
        t = float(reals[CL.R_T])
        if status == CL.UPDATE_FAILED:
            self._check_finite_state(f"the discrete updates at t = {t:.9g} s")
        if status == CL.START_FAILED:
            self.derivative(t, self.x.copy())
            culprit = self._name_nonfinite(self.xdot, self.x_states(), what="derivative of")
            raise SimulationError(f"{culprit or 'a non-finite derivative'} at t = {t:.9g} s")
        failed_t = float(reals[CL.R_FAILED_T])
        bad_y = stepper.YN.copy()
        self.x[:] = stepper.Y
        culprit = self._name_nonfinite(bad_y, self.x_states())
        if culprit is None:
            self.derivative(failed_t, bad_y)
            culprit = self._name_nonfinite(self.xdot, self.x_states(), what="derivative of")
            self.x[:] = stepper.Y
        advice = ("if the state grew without bound the step may exceed the explicit stability limit: reduce "
                  "the step, remove fast modes, or use an implicit method")
        if isinstance(stepper, CL.ExponentialStepper):
            self._integrator.last_rho = float(reals[CL.R_RHO]) / stepper.h
            advice = self._integrator._suggestion(stepper.h)
        message = (f"{culprit or 'a non-finite value'} at t = {failed_t:.9g} s; the run stopped there (last good "
                   f"state at t = {t:.9g} s). Integrator: {self.integrator_name} with step {stepper.h:.6g} s; "
                   + advice)
        raise SimulationError(message)

    def _next_instant(self, end: Fraction) -> Fraction:
        candidates = [s for s in self.context.next_sample if s is not None]
        candidates += [self._next_log_time(g) for g in self._log_groups.values()]
        return min(candidates + [end])

    def _advance(self, target: float, update_due: bool = False) -> str | None:
        """Integrate the continuous states from self.t to target; returns a stop reason or None.

        ``update_due``: a sampled model updates at ``target``, after which the integrator restarts; a
        fixed-step method then skips the slope at the end of its last step (it would be recomputed
        with the new discrete states anyway), unless zero crossings need that step's dense output."""
        if self.x.size == 0:
            return None
        integ = self._restart_integrator(target)
        have_events = bool(self._event_functions)
        if hasattr(integ, "skip_final_slope"):
            integ.skip_final_slope = update_due and not have_events
        g_old = self._zero_crossing_vector(self.t, integ.y) if have_events else None
        while integ.status == "running":
            nfev_before = integ.nfev
            integ.step()
            self.counters["nfev"] += integ.nfev - nfev_before
            if integ.status == "failed":
                self._raise_integration_failure(integ)
            self.counters["steps"] += 1
            if have_events:
                g_new = self._zero_crossing_vector(integ.t, integ.y)
                # the step right after an event is always searched: a function left at zero by the event
                # can leave and come back inside one (long, adaptive) step without a sign change at its ends
                if self.event_detection == "subdivided" or integ.t_old == self._last_events[0] \
                        or self._crossed(g_old, g_new):
                    stop = self._handle_events(integ, g_old, g_new, target)
                    if stop is not None:
                        return stop
                    integ = self._integrator
                    g_old = self._zero_crossing_vector(integ.t, integ.y)
                    continue
                g_old = g_new
        self.x[:] = integ.y
        self._check_finite_state(f"t = {integ.t:.9g} s")
        return None

    def _crossed(self, g_old, g_new) -> bool:
        for f, a, b in zip(self._event_functions, g_old, g_new):
            if a == 0.0:
                continue
            if b == 0.0 or (a < 0.0) != (b < 0.0):
                rising = b > a
                if f.direction == 0 or (f.direction > 0) == rising:
                    return True
        return False

    def _handle_events(self, integ, g_old, g_new, target) -> str | None:
        handled, stop = self._locate_and_handle(integ.dense_output(), integ.t_old, integ.t, g_old, g_new,
                                                integ.normalize)
        if not handled:
            return None
        self._integrator_stale = True
        if stop is not None:
            return stop
        self._restart_integrator(target)
        return None

    def _locate_and_handle(self, sol, t_old, t_new, g_old, g_new, normalize, samples=None) -> tuple[bool, str | None]:
        """Locate the crossings of one step on its dense output ``sol`` (``samples``: the functions at its inner
        uniform samples when already computed) and run the handlers of the first; returns (an event was
        handled, the stop reason of a terminal one or None)."""
        hits = locate_events(self._event_functions, sol, t_old, t_new, g_old, g_new, xtol=self.event_tol,
                             all_values=self._zero_crossing_vector, samples=samples)
        # a crossing just handled leaves its function at zero up to round-off, which may read as a new
        # sign change right after the restart: the same function within the tolerance is not a new event
        t_last, handled = self._last_events
        hits = [(t, j) for t, j in hits if not (j in handled and t - t_last <= 4 * self.event_tol)]
        if not hits:
            return False, None
        t_event = hits[0][0]
        y_event = np.array(sol(t_event), dtype=np.float64)
        if normalize is not None:
            normalize(y_event)
        self.t = t_event
        self.x[:] = y_event
        self.evaluate(t_event)
        stop = None
        self._last_events = (t_event, {j for t_hit, j in hits if t_hit == t_event})
        for t_hit, j in hits:
            if t_hit != t_event:
                break
            i, k, zc = self.diagram.zero_crossing_owner[j]
            model, views = self.models[i], self.context.views[i]
            try:
                model.on_event(k, t_event, views.x, views.z, views.p)
            except Exception as exc:
                raise SimulationError(f"model {model.path} failed handling event {zc.name} at t = {t_event:.12g} s: "
                                      f"{type(exc).__name__}: {exc}") from exc
            self.counters["events"] += 1
            self.events.append((t_event, f"{model.path}.{zc.name}"))
            if self._event_functions[j].terminal:
                stop = f"event {model.path}.{zc.name} at t = {t_event:.12g} s"
        self._check_finite_state(f"after the event at t = {t_event:.12g} s")
        self.evaluate(t_event)  # outputs reflect the state after the handlers
        return True, stop

    def _single_threaded_blas(self):
        """BLAS limited to one thread for a run whose integrator multiplies small dense matrices at every step
        (the exponential and implicit methods: a few hundred rows at most, where more BLAS threads only add
        synchronization, and spin against other work on a shared machine: the observatory scene's etdrk4
        run measured 6x slower with two BLAS threads on a loaded 2-core machine). None otherwise."""
        cls = INTEGRATORS.get(str(self.integrator_name).lower(), self.integrator_name)
        if not (getattr(cls, "uses_linear_part", False) or getattr(cls, "implicit", False)):
            return None
        from threadpoolctl import threadpool_limits

        return threadpool_limits(limits=1, user_api="blas")

    def _restart_integrator(self, target: float):
        """The integrator positioned at (self.t, self.x) heading for target; reset only after a jump."""
        integ = self._integrator
        try:
            if integ is None:
                integ = self._integrator = self._make_integrator(target)
                self.counters["nfev"] += integ.nfev
            elif self._integrator_stale or integ.t != self.t:
                before = integ.nfev
                integ.reset(self.t, self.x.copy(), target)
                self.counters["nfev"] += integ.nfev - before
            else:
                integ.extend(target)
        except ValueError as exc:  # non-finite derivative at the restart point
            self.derivative(self.t, self.x.copy())
            culprit = self._name_nonfinite(self.xdot, self.x_states(), what="derivative of")
            raise SimulationError(f"{culprit or 'integrator restart failed'} at t = {self.t:.9g} s ({exc})") from exc
        self._integrator_stale = False
        return integ

    def _raise_integration_failure(self, integ) -> None:
        bad_y = integ.failed_y if integ.failed_y is not None else integ.y
        culprit = self._name_nonfinite(bad_y, self.x_states())
        if culprit is None:
            # the derivative of a finite state was not finite: find the model producing it
            self.derivative(integ.failed_t, bad_y)
            culprit = self._name_nonfinite(self.xdot, self.x_states(), what="derivative of")
        self.x[:] = integ.y
        raise SimulationError(f"{culprit or 'a non-finite value'} at t = {integ.failed_t:.9g} s; the run stopped "
                              f"there (last good state at t = {integ.t:.9g} s). Integrator: {integ.message}")

    def x_states(self):
        return self.diagram.state_entries("x")

    def _name_nonfinite(self, values, states, what="state") -> str | None:
        bad = []
        for (path, name), sl, _ in states:
            if not np.all(np.isfinite(values[sl])):
                entry = f"model {path} {what} {name} = {np.array2string(values[sl], precision=4)}"
                i = self.model_index[path]
                explain = getattr(self.models[i], "failure_message", None)
                reason = explain(self.context.data[i]) if explain is not None else None
                bad.append(entry + (f" ({reason})" if reason else ""))
        return "non-finite " + "; ".join(bad) if bad else None

    def _check_finite_state(self, when: str) -> None:
        for kind, values in (("x", self.x), ("z", self.z)):
            if not np.all(np.isfinite(values)):
                states = self.diagram.state_entries(kind)
                raise SimulationError(f"{self._name_nonfinite(values, states)} at {when}")

    def _discrete_updates(self, instant) -> None:
        schedule = self.context.next_sample
        due = [i for i in self.diagram.update_order if schedule[i] == instant]
        if not due:
            return
        t = float(instant)
        plan = self._plan
        for i in due:
            if plan is not None and plan.update_is_compiled(i):
                plan.update(t, i)  # the same numbers, without a Python dispatch per output stage
            else:
                try:
                    self.diagram.update(self.context, i, t)
                except EvaluationError as exc:
                    raise SimulationError(str(exc)) from exc.__cause__
            schedule[i] += self.context.periods[i]
            self.counters["updates"] += 1
        self._check_finite_state(f"the discrete updates at t = {t:.9g} s")
        self._integrator_stale = True  # derivatives may depend on the new discrete states

    def _sample_logs(self, writer, instant: Fraction | None = None, force: bool = False) -> None:
        """Log the groups due at ``instant`` (all groups, off-schedule, with ``force``: a stop event)."""
        if writer is None:
            for group in self._log_groups.values():  # keep the schedule moving without a file
                if not force and self._next_log_time(group) == instant:
                    group["next"] += group["period"]
            return
        evaluated = False
        for name, group in self._log_groups.items():
            due = force or self._next_log_time(group) == instant
            if not due:
                continue
            if not evaluated:
                self._evaluate_stages(self.t, self._log_stages())
                evaluated = True
            writer.append(name, self.t, self._log_row(group))
            if not force:
                group["next"] += group["period"]

    # ------------------------------------------------------------------------------------------------
    # restart
    def snapshot(self) -> dict:
        """The full simulation state: time, continuous and discrete states, sample schedule, random
        streams. ``restore(snapshot())`` continues bit-identically."""
        return {
            "t": self.t,
            "x": self.x.copy(),
            "z": self.z.copy(),
            "next_sample": [None if s is None else (s.numerator, s.denominator) for s in self.context.next_sample],
            "next_log": {g: None if e["next"] is None else (e["next"].numerator, e["next"].denominator)
                         for g, e in self._log_groups.items()},
            "rng": {m.path: rng.bit_generator.state for m, rng in zip(self.models, self.context.rngs)},
            "models": [m.path for m in self.models],
        }

    def restore(self, snapshot: dict) -> None:
        if list(snapshot["models"]) != [m.path for m in self.models]:
            raise ModelError(f"restart state was saved from a scene with models {list(snapshot['models'])}, "
                             f"this scene has {[m.path for m in self.models]}")
        if snapshot["x"].shape != self.x.shape or snapshot["z"].shape != self.z.shape:
            raise ModelError("restart state does not match this scene's state sizes "
                             f"(x {snapshot['x'].shape} vs {self.x.shape}, z {snapshot['z'].shape} vs {self.z.shape})")
        self.t = float(snapshot["t"])
        self.x[:] = snapshot["x"]
        self.z[:] = snapshot["z"]
        self.context.next_sample = [None if s is None else Fraction(*s) for s in snapshot["next_sample"]]
        for g, value in snapshot["next_log"].items():
            if g in self._log_groups:
                self._log_groups[g]["next"] = None if value is None else Fraction(*value)
        for m, rng in zip(self.models, self.context.rngs):
            rng.bit_generator.state = snapshot["rng"][m.path]
        for i, m in enumerate(self.models):
            views = self.context.views[i]
            try:
                m.restored(self.t, views.x, views.z, views.p)
            except Exception as exc:
                raise SimulationError(f"model {m.path} failed re-applying its restored state at t = "
                                      f"{self.t:.9g} s: {type(exc).__name__}: {exc}") from exc
        self._integrator_stale = True
        self._initialized = True
        self.context.unstarted = False

    def save_state(self, path) -> None:
        """Write :meth:`snapshot` to an HDF5 restart file."""
        snap = self.snapshot()
        with h5py.File(path, "w") as f:
            f.attrs["format"] = "flexshell-restart"
            f.create_dataset("x", data=snap["x"])
            f.create_dataset("z", data=snap["z"])
            f.attrs["t"] = snap["t"]
            f.attrs["schedule"] = json.dumps({k: snap[k] for k in ("next_sample", "next_log", "rng", "models")})

    def load_state(self, path) -> None:
        with h5py.File(path, "r") as f:
            if f.attrs.get("format") != "flexshell-restart":
                raise ModelError(f"{path}: not a flexshell restart file")
            snap = json.loads(f.attrs["schedule"])
            snap.update(t=float(f.attrs["t"]), x=f["x"][()], z=f["z"][()])
        self.restore(snap)
