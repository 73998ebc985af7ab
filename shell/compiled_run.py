"""The Python side of a run in the compiled loop (:mod:`shell.compiled_loop`): its arrays, and the returns to Python.

The compiled loop runs the instants of :mod:`shell.python_loop` (updates, steps, zero-crossing checks, log rows)
inside numba on integer ticks of a common time base ``1 / den`` s (every sample instant, period, log instant and
the end are multiples of it; a run whose ticks would exceed 2**53 runs the Python loop). The integrator steps
there when it says it can (its ``compiled_stepping``: :mod:`shell.integrators.compiled`; nothing here names a
method). The loop returns to Python for what must be Python, and this module answers: a Python-only model due
(its update, and the compiled ones due with it, in order), a full log buffer (its rows to the writer), a spent
budget of instants (progress; the budget adapts to about 0.1 s of wall time per call), a step that may contain a
crossing (located on the method's dense output and handled as in the Python loop), a failure (named as in the
Python loop), and what the integrator asks of its Python side. When the loop ends, or fails, the times, the sample
and log schedules, the counters and the integrator's Python side are brought up to date (``sync``).
"""

from __future__ import annotations

import math
import time as _time
from fractions import Fraction

import numpy as np

from shell import compiled_loop as CL
from shell.integrators import INTEGRATORS
from shell.integrators import compiled as IC


class CompiledRun:
    """Runs ``simulation`` in the compiled loop (see the module docstring); also the run's side that the
    integrator's :class:`shell.integrators.compiled.CompiledStepping` sees."""

    def __init__(self, simulation):
        self.sim = simulation
        self.stepping = None

    # -- what the integrator's compiled stepping sees --------------------------------------------------------
    @property
    def t(self) -> float:
        return self.sim.t

    @property
    def x(self) -> np.ndarray:
        return self.sim.x

    @property
    def options(self) -> dict:
        return self.sim.integrator_options

    @property
    def integrator(self):
        return self.sim._integrator

    def make_integrator(self, t_end: float):
        """The method's Python integrator at the run's state, as the Python loop makes it at its first
        integration (heading for ``t_end``)."""
        self.sim._integrator = None
        return self.sim.python_loop.restart_integrator(float(t_end))

    # -- whether, and what ----------------------------------------------------------------------------------
    def _method(self):
        return INTEGRATORS.get(str(self.sim.integrator_name).lower())

    def applies(self) -> bool:
        """The plan is compiled and the integrator steps in the compiled loop for this run (its options, its
        dense output for the scene's zero crossings)."""
        sim, method = self.sim, self._method()
        stepping = getattr(method, "compiled_stepping", None)
        return (sim.mode == "compiled" and stepping is not None
                and stepping.applies(method, sim.integrator_options, sim.diagram.n_zero_crossings > 0))

    @property
    def stepper(self):
        """The current stepper (None before a compiled run)."""
        return None if self.stepping is None else self.stepping.st

    def time_base(self, end: Fraction):
        """Common denominator of every instant of this run, or None when ticks would exceed 2**53."""
        sim = self.sim
        fractions = [end, Fraction(sim.t).limit_denominator(10**9)]
        fractions += [f for f in sim.context.next_sample if f is not None]
        fractions += [p for p in sim.context.periods if p is not None]
        for group in sim.log_session.groups.values():
            fractions += [group["period"], sim.log_session.next_time(group, sim.t)]
        den = 1
        for f in fractions:
            den = den * f.denominator // math.gcd(den, f.denominator)
        limit = 2 ** 53
        if den >= limit or max(abs(f) for f in fractions) * den >= limit:
            return None
        return den

    # -- the run ---------------------------------------------------------------------------------------------
    def _schedule(self, den: int, end: Fraction) -> tuple:
        """(Schedule, next_tick, period, groups, widths) of the run on the time base ``den``."""
        sim = self.sim
        d, context, session = sim.diagram, sim.context, sim.log_session
        n_models = len(d.models)
        next_tick = np.full(n_models, -1, dtype=np.int64)
        period = np.zeros(n_models, dtype=np.int64)
        for i in d.update_order:
            next_tick[i] = int(context.next_sample[i] * den)
            period[i] = int(context.periods[i] * den)
        groups = list(session.groups.values())
        kinds, indices, starts = [], [], [0]
        for group in groups:
            for signal, kind, sl in group["signals"]:
                kinds += [{"signal": 0, "x": 1, "z": 2}[kind]] * (sl.stop - sl.start)
                indices += list(range(sl.start, sl.stop))
            starts.append(len(kinds))
        widths = [starts[g + 1] - starts[g] for g in range(len(groups))]
        capacity = 512
        schedule = CL.Schedule(
            den, int(end * den), next_tick, period, np.asarray(d.update_order, dtype=np.int64),
            np.asarray([int(session.next_time(g, sim.t) * den) for g in groups], dtype=np.int64),
            np.asarray([int(g["period"] * den) for g in groups], dtype=np.int64),
            np.asarray(kinds, dtype=np.int64), np.asarray(indices, dtype=np.int64), np.asarray(starts, dtype=np.int64),
            np.zeros((len(groups), capacity)), np.zeros((len(groups), capacity, max(widths, default=0))),
            np.zeros(len(groups), dtype=np.int64), sim.plan.stage_table(session.stages()))
        return schedule, next_tick, period, groups, widths

    def run(self, end: Fraction, writer, progress):
        """Run to ``end`` in the compiled loop: (status, reason), or None when its time base does not fit (the
        caller then runs the Python loop)."""
        den = self.time_base(end)
        if den is None:
            return None
        sim = self.sim
        if self.stepping is None:
            method = self._method()
            self.stepping = method.compiled_stepping(self, method)
        st, f_valid = self.stepping.stepper(sim._integrator_stale)
        schedule, next_tick, period, groups, widths = self._schedule(den, end)
        ints = np.zeros(IC.N_INTS, dtype=np.int64)
        reals = np.zeros(IC.N_REALS)
        reals[IC.R_T] = sim.t
        ints[IC.I_F_VALID] = f_valid
        ints[IC.I_NOW] = int(Fraction(sim.t).limit_denominator(10**9) * den)
        names = list(sim.log_session.groups)
        current = [st]

        def flush():
            for g in range(len(groups)):
                count = int(schedule.log_count[g])
                if count and writer is not None:
                    writer.append_rows(names[g], schedule.log_times[g, :count], schedule.log_rows[g, :count, :widths[g]])
                schedule.log_count[g] = 0

        def sync():
            sim.t = float(reals[IC.R_T])
            for i in sim.diagram.update_order:
                sim.context.next_sample[i] = Fraction(int(next_tick[i]), den)
            for g, group in enumerate(groups):
                group["next"] = Fraction(int(schedule.log_next[g]), den)
            done = ints[[IC.I_STEPS, IC.I_NFEV, IC.I_UPDATES]]
            sim.counters["steps"] += int(done[0])
            sim.counters["nfev"] += int(done[1])
            sim.counters["updates"] += int(done[2])
            ints[[IC.I_STEPS, IC.I_NFEV, IC.I_UPDATES]] = 0
            sim._integrator_stale = ints[IC.I_F_VALID] == 0
            self.stepping.sync(current[0], ints)

        try:
            stop_reason = self._loop(current, schedule, ints, reals, next_tick, period, end, writer, progress, flush,
                                     sync)
        finally:
            flush()
            sync()
        if stop_reason is not None:
            sim.log_session.sample(writer, sim.t, {"signal": sim.signals, "x": sim.x, "z": sim.z},
                                   sim.plan.evaluate, force=True)
            return "stopped", stop_reason
        if progress is not None:
            progress(sim.t)
        return "completed", "reached t_final"

    def _loop(self, current, schedule, ints, reals, next_tick, period, end, writer, progress, flush, sync):
        """Call the compiled loop until it is done; answer each return (module docstring). The stop reason of a
        terminal event, or None. ``current[0]``: the stepper (a request may replace it)."""
        sim = self.sim
        plan = sim.plan
        n_g, n_x = sim.diagram.n_zero_crossings, sim.x.size
        mode = CL.NO_EVENTS if n_g == 0 else (CL.SUBDIVIDED if sim.event_location.detection == "subdivided" else
                                             CL.SIGN_CHANGE)
        events = CL.Events(mode, np.zeros(2, dtype=np.int64), sim.event_location.directions(), np.zeros(n_g),
                           np.zeros(n_g), np.zeros((CL.SUBDIVISIONS + 1, n_g)), np.zeros(n_x), np.zeros(n_x),
                           np.zeros(n_x))
        reals[IC.R_LAST_EVENT] = sim.event_location.last[0]
        budget, integrate = 64, n_x > 0
        checked = None  # the stepper the events' check was compiled for
        while True:
            if mode != CL.NO_EVENTS and current[0] is not checked:
                checked = current[0]
                events = events._replace(check=CL.event_check(plan.kernels, plan.buffers, checked, events))
            started = _time.perf_counter()
            status = CL.advance(plan.kernels, plan.buffers, current[0], events, schedule, ints,
                                reals, budget, writer is not None, integrate)
            elapsed = _time.perf_counter() - started
            if status == CL.DONE:
                return None
            if status == CL.PYTHON_UPDATE:
                self._python_updates(ints, reals, next_tick, period)
            elif status == CL.LOG_FULL:
                flush()
            elif status == CL.BUDGET:
                budget = int(min(max(budget * 0.1 / max(elapsed, 1e-6), 16), 1 << 20))
            elif status == CL.EVENT_CANDIDATE:
                stop_reason = self._event(events, current[0], ints, reals)
                if stop_reason is not None:
                    return stop_reason
            elif status >= IC.FIRST_REQUEST:
                sim.t = float(reals[IC.R_T])
                current[0] = self.stepping.request(status, current[0], ints, reals, float(end))
            else:
                sync()
                self._raise_failure(status, current[0], reals)
            if progress is not None and status != CL.PYTHON_UPDATE:
                sim.t = float(reals[IC.R_T])
                progress(sim.t)

    def _event(self, events, st, ints, reals) -> str | None:
        """A step of the compiled loop that may contain a crossing: locate it on the step's dense output (the
        method's, from the samples the loop took of it) and handle it; the loop restarts at the event (or, with no
        crossing after all, goes on from the step's end)."""
        sim = self.sim
        t_old, t_new = float(reals[IC.R_T_OLD]), float(reals[IC.R_T])
        sol = self.stepping.dense_output(st, t_old, t_new, events.y_old, events.f_old)
        samples = events.samples[1:-1].copy()  # the loop sampled the dense output already (the same numbers)
        handled, stop = sim.handle_crossings(sol, t_old, t_new, events.g_old.copy(), events.g_new.copy(),
                                             sim.plan.normalize, samples)
        if handled:
            reals[IC.R_T] = sim.t
            reals[IC.R_LAST_EVENT] = sim.t
            ints[IC.I_F_VALID] = 0
        else:
            sim.x[:] = st.Y
        return stop

    def _python_updates(self, ints, reals, next_tick, period) -> None:
        """The updates at the current instant when a Python-only model is due (all due models, in order)."""
        sim = self.sim
        t = float(reals[IC.R_T])
        sim.t = t
        now = int(ints[IC.I_NOW])
        due = [i for i in sim.diagram.update_order if next_tick[i] == now]
        for i in due:
            next_tick[i] += period[i]
        ints[IC.I_UPDATES] += sim.update_models(t, due, schedule=False)
        ints[IC.I_F_VALID] = 0

    def _raise_failure(self, status, st, reals) -> None:
        sim = self.sim
        t = float(reals[IC.R_T])
        if status == CL.UPDATE_FAILED:
            sim.check_finite(f"the discrete updates at t = {t:.9g} s")
        if status == IC.START_FAILED:
            culprit = sim.nonfinite_derivative(t, sim.x.copy())
            raise sim.failure(f"{culprit or 'a non-finite derivative'} at t = {t:.9g} s")
        failed_t = float(reals[IC.R_FAILED_T])
        bad_y = st.YN.copy()
        sim.x[:] = st.Y
        culprit = sim.nonfinite_state(bad_y)
        if culprit is None:
            culprit = sim.nonfinite_derivative(failed_t, bad_y)
            sim.x[:] = st.Y
        raise sim.failure(f"{culprit or 'a non-finite value'} at t = {failed_t:.9g} s; the run stopped there (last "
                          f"good state at t = {t:.9g} s). Integrator: {sim.integrator_name} with step {st.h:.6g} s; "
                          + self.stepping.advice(st))
