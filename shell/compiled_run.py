"""The Python side of a run in the compiled loop (:mod:`shell.compiled_loop`): its arrays, and the returns to Python.

The compiled loop runs the instants of :mod:`shell.python_loop` (updates, steps, zero-crossing checks, log rows)
inside numba on integer ticks of a common time base ``1 / den`` s (every sample instant, period, log instant and
the end are multiples of it; a run whose ticks would exceed 2**53 runs the Python loop). It returns to Python
for what must be Python, and this module answers: a Python-only model due (its update, and the compiled ones due
with it, in order), a full log buffer (its rows to the writer), a spent budget of instants (progress; the budget
adapts to about 0.1 s of wall time per call), a step that may contain a crossing (located on the step's dense
output and handled as in the Python loop), a failure (named as in the Python loop), and what the integrator asks
of its Python side (:mod:`shell.integrators.exponential`: a check of its linear part, its creation). When the loop
ends, or fails, the times, the sample and log schedules and the counters go back to the simulation (``sync``).
"""

from __future__ import annotations

import math
import time as _time
from fractions import Fraction

import numpy as np

from shell import compiled_loop as CL
from shell.integrators import INTEGRATORS
from shell.model import ModelError


class CompiledRun:
    """Runs ``simulation`` in the compiled loop (see the module docstring)."""

    def __init__(self, simulation):
        self.sim = simulation
        self.stepper = None
        # the exponential stepper's linear part, the time its state is current at, its slope's state (CL.F_DUE)
        self.part, self.stepper_t, self.f_state = None, None, 0

    def applies(self) -> bool:
        """Fixed-step explicit Runge-Kutta and the exponential RK4 run in the compiled loop; adaptive and
        implicit methods run the Python loop on the compiled derivative."""
        from shell.integrators.exponential import ExponentialRK4
        from shell.integrators.fixed import FixedStepRungeKutta

        sim = self.sim
        cls = INTEGRATORS.get(str(sim.integrator_name).lower())
        if sim.mode != "compiled" or cls is None or sim.integrator_options.get("step") is None:
            return False
        if cls is ExponentialRK4:
            return True
        if not issubclass(cls, FixedStepRungeKutta):
            return False
        # events are located on the dense output: the compiled loop evaluates the cubic Hermite one
        return sim.diagram.n_zero_crossings == 0 or cls.name in ("euler", "heun", "rk4")

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

    # -- steppers --------------------------------------------------------------------------------------------
    def _exponential_stepper(self):
        """The exponential RK4's stepper (:class:`shell.compiled_loop.ExponentialStepper`), or a placeholder
        (step 0) until the integrator exists: the loop then returns NEW_INTEGRATOR where the Python loop would
        make it (at the start of the first integration, after the updates at that instant), so that its linear
        part and driven rows are built at the same state. The :class:`ExponentialRK4` object stays the home
        of the linear part, its matrix functions and check counters (the compiled loop reads and writes them
        back), and of the events' dense output."""
        from shell.integrators.exponential import ExponentialRK4

        sim = self.sim
        integ = sim._integrator
        if not isinstance(integ, ExponentialRK4):
            self.stepper, self.part = CL.exponential_placeholder(sim.x.size), None
        elif not isinstance(self.stepper, CL.ExponentialStepper) or self.part is not integ.part:
            # the Python loop's integrator moved on: the loop restarts from the context (no slope needed here)
            self.stepper = CL.exponential_stepper(integ, integ.y, np.zeros_like(integ.y))
            self.part = integ.part
            sim._integrator_stale = True
        return self.stepper

    def _new_exponential_integrator(self, ints, reals, end):
        """NEW_INTEGRATOR: make the integrator at the loop's time and state (as the Python loop does at its first
        integration) and return its stepper, with its slope."""
        sim = self.sim
        sim.t = float(reals[CL.R_T])
        sim._integrator = None
        integ = sim.python_loop.restart_integrator(float(end))
        self.stepper, self.part = CL.exponential_stepper(integ), integ.part
        ints[CL.I_F_VALID] = 1
        ints[CL.I_SINCE_CHECK] = integ.steps_since_check
        ints[CL.I_CHECK_INTERVAL] = integ.check_interval
        reals[CL.R_PHI_H] = np.nan
        return self.stepper

    def _runge_kutta_stepper(self):
        sim = self.sim
        cls = INTEGRATORS[str(sim.integrator_name).lower()]
        options = sim.integrator_options
        step = float(options["step"])
        if not (step > 0.0 and math.isfinite(step)):
            raise ModelError(f"integrator step must be a positive number of seconds, got {options['step']!r}")
        h = min(step, float(options.get("max_step", np.inf)))
        if not isinstance(self.stepper, CL.Stepper) or self.stepper.h != h or self.stepper.A is not cls.tableau.A:
            tb, n = cls.tableau, sim.x.size
            self.stepper = CL.Stepper(tb.A, tb.b, tb.c, tb.n_stages, h, sim.x.copy(), np.zeros(n),
                                      np.zeros((tb.n_stages, n)), np.zeros(n), np.zeros(n))
            sim._integrator_stale = True
        return self.stepper

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
        exponential = getattr(INTEGRATORS.get(str(sim.integrator_name).lower()), "uses_linear_part", False)
        stepper = self._exponential_stepper() if exponential else self._runge_kutta_stepper()
        schedule, next_tick, period, groups, widths = self._schedule(den, end)
        ints = np.zeros(CL.N_INTS, dtype=np.int64)
        reals = np.zeros(CL.N_REALS)
        reals[CL.R_T] = sim.t
        ints[CL.I_F_VALID] = 0 if sim._integrator_stale else 1
        ints[CL.I_NOW] = int(Fraction(sim.t).limit_denominator(10**9) * den)
        if exponential and self.part is not None:
            ints[CL.I_SINCE_CHECK] = sim._integrator.steps_since_check
            ints[CL.I_CHECK_INTERVAL] = sim._integrator.check_interval
            reals[CL.R_PHI_H] = np.nan
            if sim._integrator_stale or self.stepper_t != sim.t:
                ints[CL.I_F_VALID] = 0
            else:
                ints[CL.I_F_VALID] = self.f_state
        names = list(sim.log_session.groups)

        def flush():
            for g in range(len(groups)):
                count = int(schedule.log_count[g])
                if count and writer is not None:
                    writer.append_rows(names[g], schedule.log_times[g, :count], schedule.log_rows[g, :count, :widths[g]])
                schedule.log_count[g] = 0

        def sync():
            sim.t = float(reals[CL.R_T])
            for i in sim.diagram.update_order:
                sim.context.next_sample[i] = Fraction(int(next_tick[i]), den)
            for g, group in enumerate(groups):
                group["next"] = Fraction(int(schedule.log_next[g]), den)
            done = ints[[CL.I_STEPS, CL.I_NFEV, CL.I_UPDATES]]
            sim.counters["steps"] += int(done[0])
            sim.counters["nfev"] += int(done[1])
            sim.counters["updates"] += int(done[2])
            ints[[CL.I_STEPS, CL.I_NFEV, CL.I_UPDATES]] = 0
            sim._integrator_stale = ints[CL.I_F_VALID] == 0
            if exponential and self.part is not None:
                sim._integrator.steps_since_check = int(ints[CL.I_SINCE_CHECK])
                sim._integrator.check_interval = int(ints[CL.I_CHECK_INTERVAL])
                self.stepper_t = sim.t
                self.f_state = int(ints[CL.I_F_VALID])

        try:
            stop_reason = self._loop(stepper, schedule, ints, reals, next_tick, period, end, writer, progress, flush,
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

    def _loop(self, stepper, schedule, ints, reals, next_tick, period, end, writer, progress, flush, sync):
        """Call the compiled loop until it is done; answer each return (module docstring). The stop reason of a
        terminal event, or None."""
        sim = self.sim
        plan = sim.plan
        n_g, n_x = sim.diagram.n_zero_crossings, sim.x.size
        mode = CL.NO_EVENTS if n_g == 0 else (CL.SUBDIVIDED if sim.event_location.detection == "subdivided" else
                                             CL.SIGN_CHANGE)
        events = CL.Events(mode, sim.event_location.directions(), np.zeros(n_g), np.zeros(n_g),
                           np.zeros((CL.SUBDIVISIONS + 1, n_g)), np.zeros(n_x), np.zeros(n_x), np.zeros(n_x))
        reals[CL.R_LAST_EVENT] = sim.event_location.last[0]
        budget, integrate, b = 64, n_x > 0, plan.buffers
        while True:
            started = _time.perf_counter()
            status = CL.advance(plan.kernels, plan.engine, plan.rngs, b, stepper, events, schedule, ints, reals,
                                budget, writer is not None, integrate)
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
                stop_reason = self._event(events, stepper, ints, reals)
                if stop_reason is not None:
                    return stop_reason
            elif status in (CL.LINEAR_CHECK, CL.STIFF_REMAINDER):
                stepper = self._check_linear_part(sim._integrator, stepper, ints, reals, status == CL.STIFF_REMAINDER)
            elif status == CL.NEW_INTEGRATOR:
                stepper = self._new_exponential_integrator(ints, reals, end)
            else:
                sync()
                self._raise_failure(status, stepper, reals)
            if progress is not None and status != CL.PYTHON_UPDATE:
                sim.t = float(reals[CL.R_T])
                progress(sim.t)

    def _event(self, events, stepper, ints, reals) -> str | None:
        """A step of the compiled loop that may contain a crossing: locate it on the step's dense output (the
        integrator's: cubic Hermite for the Runge-Kutta methods) and handle it; the loop restarts at the event
        (or, with no crossing after all, goes on from the step's end)."""
        from shell.integrators.base import HermiteDenseOutput

        sim = self.sim
        t_old, t_new = float(reals[CL.R_T_OLD]), float(reals[CL.R_T])
        samples = None
        if isinstance(stepper, CL.ExponentialStepper):
            from shell.integrators.exponential import ExponentialDenseOutput

            sol = ExponentialDenseOutput(t_old, t_new, events.y_old, stepper.N, self.part)
            samples = events.samples[1:-1].copy()  # the loop sampled the dense output already (same numbers)
        else:
            sol = HermiteDenseOutput(t_old, t_new, events.y_old, events.f_old, stepper.Y, stepper.F)
        handled, stop = sim.handle_crossings(sol, t_old, t_new, events.g_old.copy(), events.g_new.copy(),
                                             sim.plan.normalize, samples)
        if handled:
            reals[CL.R_T] = sim.t
            reals[CL.R_LAST_EVENT] = sim.t
            ints[CL.I_F_VALID] = 0
        else:
            sim.x[:] = stepper.Y
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
        self.stepper = CL.exponential_stepper(integ, stepper.Y, stepper.F)
        self.part = integ.part
        reals[CL.R_PHI_H] = np.nan
        return self.stepper

    def _python_updates(self, ints, reals, next_tick, period) -> None:
        """The updates at the current instant when a Python-only model is due (all due models, in order)."""
        sim = self.sim
        t = float(reals[CL.R_T])
        sim.t = t
        now = int(ints[CL.I_NOW])
        due = [i for i in sim.diagram.update_order if next_tick[i] == now]
        for i in due:
            next_tick[i] += period[i]
        ints[CL.I_UPDATES] += sim.update_models(t, due, schedule=False)
        ints[CL.I_F_VALID] = 0

    def _raise_failure(self, status, stepper, reals) -> None:
        sim = self.sim
        t = float(reals[CL.R_T])
        if status == CL.UPDATE_FAILED:
            sim.check_finite(f"the discrete updates at t = {t:.9g} s")
        if status == CL.START_FAILED:
            culprit = sim.nonfinite_derivative(t, sim.x.copy())
            raise sim.failure(f"{culprit or 'a non-finite derivative'} at t = {t:.9g} s")
        failed_t = float(reals[CL.R_FAILED_T])
        bad_y = stepper.YN.copy()
        sim.x[:] = stepper.Y
        culprit = sim.nonfinite_state(bad_y)
        if culprit is None:
            culprit = sim.nonfinite_derivative(failed_t, bad_y)
            sim.x[:] = stepper.Y
        advice = ("if the state grew without bound the step may exceed the explicit stability limit: reduce "
                  "the step, remove fast modes, or use an implicit method")
        if isinstance(stepper, CL.ExponentialStepper):
            sim._integrator.last_rho = float(reals[CL.R_RHO]) / stepper.h
            advice = sim._integrator._suggestion(stepper.h)
        raise sim.failure(f"{culprit or 'a non-finite value'} at t = {failed_t:.9g} s; the run stopped there (last "
                          f"good state at t = {t:.9g} s). Integrator: {sim.integrator_name} with step "
                          f"{stepper.h:.6g} s; " + advice)
