"""The simulation: a diagram, the context of one run, its evaluation plan, and the pieces that run it.

Build time (once): :class:`shell.diagram.Diagram` flattens the assembly, lays out the buffers, wires and orders the
evaluation (see its module docstring); :meth:`Diagram.create_context` makes this run's :class:`shell.diagram.Context`
(states, signals, parameters, per-model data, random streams, schedule); the evaluation plan computes outputs,
derivatives, zero crossings and updates at a context, compiled (:class:`shell.compiled_plan.CompiledPlan`) or
interpreted (:class:`shell.diagram.InterpretedPlan`, the reference): the same methods and the same numbers.

Running (TM-2020-5008164 App. D.1: multi-rate models, zero finding) is split into pieces:

* :mod:`shell.compiled_run` drives the compiled loop (:mod:`shell.compiled_loop`) for an integrator that steps
  compiled (the fixed-step Runge-Kutta methods, the exponential RK4) when the plan is compiled;
* :mod:`shell.python_loop` drives a Python integrator otherwise (adaptive and implicit methods, the interpreted
  reference); both run the same instants, updates, steps and log rows;
* :mod:`shell.log_session` keeps the log groups and their schedule, :mod:`shell.event_location` decides which
  steps are searched for zero crossings and locates them, :mod:`shell.restart` saves and restores a run.

This class holds what those pieces share (the run's time and states, counters, the Python integrator), handles
what a crossing does (the state moved there, the models' handlers, a terminal stop; the actions of the scene's
``events: on:``, :mod:`shell.scene_events`, recorded in the run summary and the log), runs the sampled models'
updates at an instant, and names the model and state of a failure.
"""

from __future__ import annotations

import gc
import time as _time
import warnings
import weakref
from dataclasses import dataclass
from fractions import Fraction

import numpy as np

from shell import restart
from shell.assembly import Assembly
from shell.compiled_plan import evaluation_plan
from shell.compiled_run import CompiledRun
from shell.diagram import AlgebraicLoopError, Diagram, EvaluationError, WiringError  # noqa: F401 (public here too)
from shell.event_location import EventLocation
from shell.integrators import INTEGRATORS
from shell.log_session import LogSession
from shell.model import ModelError
from shell.python_loop import PythonLoop
from shell.scene_events import SceneEvents, changes_json


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
    changes: tuple = ()  # (time, event, what changed) of the scene's events: on: during the run

    @property
    def real_time_factor(self) -> float:
        return (self.t_end - self.t_start) / self.wall_time if self.wall_time > 0 else float("inf")

    def __str__(self) -> str:
        return (f"{self.status} at t = {self.t_end:.6g} s ({self.reason}); wall time {self.wall_time:.3f} s, "
                f"{self.steps} steps, {self.derivative_evaluations} derivative evaluations, "
                f"{self.discrete_updates} discrete updates, {self.events} events, "
                f"real-time factor {self.real_time_factor:.3g}"
                + "".join(f"\n  event {name} at t = {t:.12g} s: {what}" for t, name, what in self.changes)
                + "".join(f"\n  note: {n}" for n in self.notes))


class Simulation:
    """A runnable scene: a :class:`shell.diagram.Diagram`, the :class:`shell.diagram.Context` of this run, its
    evaluation plan, the integrator, the sample schedule and the log (see the module docstring)."""

    def __init__(self, root: Assembly, *, integrator: str = "rk4", step: float | None = 0.01,
                 integrator_options: dict | None = None, seed=0, stop_events=(), event_tol: float = 1e-10,
                 event_detection: str = "subdivided", t_start: float = 0.0, diagram: Diagram | None = None,
                 mode: str = "compiled", context=None):
        self.seed = seed
        #: the scene's immutable plan (shared by every run of the scene)
        self.diagram = diagram if diagram is not None else Diagram(root, stop_events=stop_events)
        self.root = self.diagram.root
        d = self.diagram
        self.models, self.connections, self.model_index = d.models, d.connections, d.model_index
        self.port_slices, self.port_info, self.state_slices, self.driver = (d.port_slices, d.port_info,
                                                                            d.state_slices, d.driver)
        if context is None:
            self._claim_models()
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
        #: the evaluation plan of this run: compiled, or interpreted (see ``interpreted_reason``)
        self.plan, self.interpreted_reason = evaluation_plan(d, self.context, mode)
        if self.interpreted_reason is not None:
            warnings.warn(f"the scene runs interpreted (every kernel called from Python, slower): "
                          f"{self.interpreted_reason}", SimulationWarning, stacklevel=2)
        #: "compiled" or "interpreted"
        self.mode = self.plan.mode
        if self.plan.python_updates:
            _warn_python_updates([self.models[i] for i in self.plan.python_updates])
        #: the integrator's right-hand side f(t, x) (the plan's)
        self.rhs = self.plan.derivative
        self.event_location = EventLocation(d, self.plan.zero_crossings, event_tol, event_detection)
        self.log_session = LogSession(d)
        self.python_loop = PythonLoop(self)
        self.compiled_run = CompiledRun(self)
        #: the integrator object of the Python loop (and the exponential method's Python side in the compiled one)
        self._integrator = None
        self._integrator_stale = True
        self._initialized = False
        self.counters = {"steps": 0, "nfev": 0, "events": 0, "updates": 0}
        #: (time, "model.zero_crossing") of every handled event, in order
        self.events: list[tuple[float, str]] = []
        #: what every event of events: on: changed (shell.scene_events), in order: (t, event name, description)
        self.scene_changes: list[tuple[float, str, str]] = []
        #: the model of the scene's events: on: (shell.scene_events.SceneEvents), or None
        self.scene_events = next((m for m in self.models if isinstance(m, SceneEvents)), None)
        if self.scene_events is not None:
            self.scene_events.check(self)
            self.scene_events.establish(self)

    def _claim_models(self) -> None:
        """The first context shares the models' own data (the engine's workspace): one Simulation per scene."""
        for m in self.models:
            owner = getattr(m, "_simulation", None)
            if owner is not None and owner() is not None:
                gc.collect()  # a discarded simulation may still be waiting in a reference cycle
            if owner is not None and owner() is not None:
                raise ModelError(f"model {m.path} already belongs to another Simulation (its random stream and "
                                 "workspace would be shared); build the scene again for a second simulation, "
                                 "or run another context of the same diagram (Diagram.create_context(own_data="
                                 "True), Simulation(diagram=..., context=...))")

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

    # the current run's buffers (views of the context) and settings
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

    @property
    def event_tol(self) -> float:
        return self.event_location.tolerance

    @property
    def event_detection(self) -> str:
        return self.event_location.detection

    @property
    def _log_groups(self) -> dict:
        return self.log_session.groups

    @property
    def _stepper(self):
        """The compiled loop's stepper of this run (None before a compiled run)."""
        return self.compiled_run.stepper

    def _compiled_loop_applies(self) -> bool:
        return self.compiled_run.applies()

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
        """f(t, x): the interpreted reference of the integrator's right-hand side (continuous states of every model)."""
        try:
            return self.diagram.derivatives(self.context, t, y)
        except EvaluationError as exc:
            raise SimulationError(str(exc)) from exc.__cause__

    def evaluate(self, t: float | None = None) -> None:
        """Compute every output and input at the current state (used at sample and log instants)."""
        try:
            self.plan.evaluate(self.t if t is None else t)
        except EvaluationError as exc:
            raise SimulationError(str(exc)) from exc.__cause__

    def _zero_crossing_vector(self, t: float, y: np.ndarray) -> np.ndarray:
        return self.plan.zero_crossings(t, y)

    def signal(self, name: str) -> np.ndarray:
        """Current value of a port or state by dotted name (a copy, in the port's/state's unit); an output its model
        did not compute until now (a node nothing else reads: :meth:`shell.model.Model.output_read`) is computed
        first."""
        if self.diagram.note_read(name):
            self.evaluate()
        kind, sl, decl = self.diagram.locate(name)
        source = {"signal": self.signals, "x": self.x, "z": self.z}[kind]
        return source[sl].reshape(decl.shape).copy()

    # ------------------------------------------------------------------------------------------------
    # logging
    def log(self, signals, rate) -> None:
        """Log ``signals`` (dotted port/state names) every ``rate`` ("10 Hz", "0.1 s", seconds)."""
        self.log_session.add(signals, rate)

    def log_groups(self) -> dict:
        """{group name: [LoggedSignal, ...]} of what :meth:`log` requested (a writer's layout)."""
        return self.log_session.layout()

    # ------------------------------------------------------------------------------------------------
    # running
    def run(self, t_final: float, log_path=None, progress=None, log_attributes: dict | None = None) -> RunSummary:
        """Run from the current time to ``t_final`` (s); log to ``log_path`` (HDF5) if given.

        ``progress(t)`` is called after every sample instant. A failure raises
        :class:`SimulationError` naming the model and time; the log keeps every sample taken before it
        and records ``status="failed"`` and the message.
        """
        t_final = float(t_final)
        if t_final < self.t:
            raise ValueError(f"t_final = {t_final} s is before the current time {self.t} s")
        writer = self.log_session.open(log_path, self.seed, log_attributes)
        start_counters = dict(self.counters)
        len_before = len(self.scene_changes)
        t_start = self.t
        wall_start = _time.perf_counter()
        blas = self._single_threaded_blas()
        try:
            if not self._initialized:
                self.check_finite("initial state")
                self._initialized = True
            self.context.unstarted = False
            end = Fraction(t_final).limit_denominator(10**9)
            outcome = self.compiled_run.run(end, writer, progress) if self.compiled_run.applies() else None
            status, reason = outcome if outcome is not None else self.python_loop.run(end, writer, progress)
        except KeyboardInterrupt as exc:  # Ctrl-C, or a signal turned into one (flexshell run: SIGTERM)
            if writer is not None:
                writer.close("interrupted", f"{exc or 'interrupted by the user'} at t = {self.t:.9g} s")
            raise
        except Exception as exc:
            known = isinstance(exc, (SimulationError, EvaluationError))
            message = str(exc) if known else f"{type(exc).__name__} at t = {self.t:.9g} s: {exc}"
            if writer is not None:
                self._record_changes(writer, len_before)
                writer.close("failed", message)
            if isinstance(exc, SimulationError):
                raise
            raise SimulationError(message) from (exc.__cause__ if known else exc)
        finally:
            if blas is not None:
                blas.restore_original_limits()
        if writer is not None:
            self._record_changes(writer, len_before)
            writer.close(status, reason)
        self.evaluate()  # outputs consistent with the final state for signal() queries
        wall = _time.perf_counter() - wall_start
        return RunSummary(status, reason, t_start, self.t, wall, self.counters["steps"] - start_counters["steps"],
                          self.counters["nfev"] - start_counters["nfev"],
                          self.counters["events"] - start_counters["events"],
                          self.counters["updates"] - start_counters["updates"],
                          tuple(note for m in self.diagram.models for note in getattr(m, "notes", ())),
                          tuple(self.scene_changes[len_before:]))

    def _record_changes(self, writer, start: int) -> None:
        """The scene changes of this run into an HDF5 log: its ``scene_events`` attribute (JSON: time, event, what
        changed). A Monte Carlo run's in-memory log keeps its signals only."""
        file = getattr(writer, "file", None)
        if self.scene_events is not None and file is not None and file.id.valid:
            file.attrs["scene_events"] = changes_json(self.scene_changes[start:])

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

    def update_models(self, t: float, due, schedule: bool = True) -> int:
        """The discrete updates of the sampled models ``due`` at ``t``, in that order (each sees what the previous
        ones produced); ``schedule``: their next samples move on and the update counter counts them (the compiled
        loop keeps its own). Returns their number."""
        if not due:
            return 0
        for i in due:
            self.plan.update(t, i)
            if schedule:
                self.context.next_sample[i] += self.context.periods[i]
        if schedule:
            self.counters["updates"] += len(due)
        self.check_finite(f"the discrete updates at t = {t:.9g} s")
        self._integrator_stale = True  # derivatives may depend on the new discrete states
        return len(due)

    def handle_crossings(self, sol, t_old, t_new, g_old, g_new, normalize, samples=None) -> tuple[bool, str | None]:
        """Locate the crossings of one step on its dense output ``sol`` (:class:`shell.event_location.EventLocation`)
        and handle the first: the state moved there (quaternions renormalized), the models' ``on_event`` handlers in
        model order, the outputs evaluated again. Returns (an event was handled, the stop reason of a terminal one
        or None)."""
        found = self.event_location.first(sol, t_old, t_new, g_old, g_new, samples)
        if found is None:
            return False, None
        t_event, crossing = found
        y_event = np.array(sol(t_event), dtype=np.float64)
        if normalize is not None:
            normalize(y_event)
        self.t = t_event
        self.x[:] = y_event
        self.evaluate(t_event)
        stop = None
        for j in crossing:
            i, k, zc = self.diagram.zero_crossing_owner[j]
            model, views = self.models[i], self.context.views[i]
            try:
                if model is self.scene_events:
                    self.scene_changes.append((t_event, zc.name, model.happen(self, k, t_event)))
                else:
                    model.on_event(k, t_event, views.x, views.z, views.p)
            except Exception as exc:
                raise SimulationError(f"model {model.path} failed handling event {zc.name} at t = {t_event:.12g} s: "
                                      f"{type(exc).__name__}: {exc}") from exc
            self.counters["events"] += 1
            self.events.append((t_event, f"{model.path}.{zc.name}"))
            if self.event_location.functions[j].terminal:
                stop = f"event {model.path}.{zc.name} at t = {t_event:.12g} s"
        self.check_finite(f"after the event at t = {t_event:.12g} s")
        self.evaluate(t_event)  # outputs reflect the state after the handlers
        return True, stop

    # ------------------------------------------------------------------------------------------------
    # failures: which model, which state
    def x_states(self):
        return self.diagram.state_entries("x")

    def failure(self, message: str) -> SimulationError:
        return SimulationError(message)

    def nonfinite_state(self, values) -> str | None:
        """Names the continuous states of ``values`` that are not finite, or None."""
        return self._name_nonfinite(values, self.x_states())

    def nonfinite_derivative(self, t: float, y) -> str | None:
        """Names the states whose derivative at (t, y) is not finite (the interpreted reference evaluates it:
        the model that produced it, or the one whose kernel failed), or None. Leaves ``y`` in the context."""
        self.derivative(t, y)
        return self._name_nonfinite(self.xdot, self.x_states(), what="derivative of")

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

    def check_finite(self, when: str) -> None:
        """Refuse a non-finite continuous or discrete state at ``when``, naming the models and states."""
        for kind, values in (("x", self.x), ("z", self.z)):
            if not np.all(np.isfinite(values)):
                states = self.diagram.state_entries(kind)
                raise SimulationError(f"{self._name_nonfinite(values, states)} at {when}")

    # ------------------------------------------------------------------------------------------------
    # restart (shell.restart)
    def snapshot(self) -> dict:
        """The full simulation state: time, continuous and discrete states, sample schedule, random
        streams. ``restore(snapshot())`` continues bit-identically."""
        return restart.snapshot(self)

    def restore(self, snapshot: dict) -> None:
        restart.restore(self, snapshot)
        for i, m in enumerate(self.models):
            views = self.context.views[i]
            try:
                m.restored(self.t, views.x, views.z, views.p)
            except Exception as exc:
                raise SimulationError(f"model {m.path} failed re-applying its restored state at t = "
                                      f"{self.t:.9g} s: {type(exc).__name__}: {exc}") from exc
        if self.scene_events is not None:
            self.scene_events.establish(self)  # the constraint switches of the events that happened before
        self._integrator_stale = True
        self._initialized = True
        self.context.unstarted = False

    def save_state(self, path) -> None:
        """Write :meth:`snapshot` to an HDF5 restart file."""
        restart.save(self, path)

    def load_state(self, path) -> None:
        self.restore(restart.load(path))
