"""The loop of a run whose integrator steps in Python: adaptive and implicit methods, the interpreted reference.

TM-2020-5008164 App. D.1 (multi-rate models, zero finding): the loop integrates the continuous states from one
instant to the next, an instant being the next sample of a sampled model or of a log group (exact rational
times), and the end. After each step the zero crossings are checked (:mod:`shell.event_location`); a crossing is
located on the step's dense output, the state moves there, the models' handlers run and the integrator
restarts; a terminal crossing stops the run. At an instant the due sampled models update one after another in
dataflow order (upstream first), each seeing what the previous ones just produced; the due log groups sample.
The integrator is an :class:`shell.integrators.Integrator` on the run's evaluation plan (compiled or interpreted:
the same numbers); it is reset only after the state jumped (an update, an event) and otherwise extended to the
next instant. :mod:`shell.compiled_run` runs the same instants, updates, steps and log rows inside numba.
"""

from __future__ import annotations

from fractions import Fraction

import numpy as np

from shell.integrators import INTEGRATORS, make_integrator, quaternion_gauge


class PythonLoop:
    """Runs ``simulation`` from instant to instant with a Python integrator (see the module docstring)."""

    def __init__(self, simulation):
        self.sim = simulation

    def run(self, end: Fraction, writer, progress) -> tuple[str, str]:
        """Run to ``end``; returns (status, reason)."""
        sim = self.sim
        sources = {"signal": sim.signals, "x": sim.x, "z": sim.z}
        while True:
            instant = self._next_instant(end)
            target = float(instant)
            if target > sim.t:
                update_due = any(s == instant for s in sim.context.next_sample if s is not None)
                stopped = self._advance(target, update_due)
                if stopped is not None:
                    sim.log_session.sample(writer, sim.t, sources, sim.plan.evaluate, force=True)
                    return "stopped", stopped
            sim.t = target
            schedule = sim.context.next_sample
            sim.update_models(target, [i for i in sim.diagram.update_order if schedule[i] == instant])
            sim.log_session.sample(writer, sim.t, sources, sim.plan.evaluate, instant)
            if progress is not None:
                progress(sim.t)
            if instant >= end:
                return "completed", "reached t_final"

    def _next_instant(self, end: Fraction) -> Fraction:
        sim = self.sim
        candidates = [s for s in sim.context.next_sample if s is not None]
        candidates += [sim.log_session.next_time(g, sim.t) for g in sim.log_session.groups.values()]
        return min(candidates + [end])

    def make_integrator(self, t_bound: float):
        """The run's integrator at (t, x) heading for ``t_bound``: quaternions renormalized after every step and
        left out of error control along themselves (gauge), and an exponential method given the stiff linear part
        of every model that has one (block-diagonal, offset to the full state)."""
        sim = self.sim
        diagram, context = sim.diagram, sim.context
        normalize = None
        if diagram.normalizers:
            def normalize(y):
                diagram.normalize(context, y)
        options = dict(sim.integrator_options)
        w_indices = diagram.quaternion_w_indices()
        if w_indices.size and "error_exclude" not in options:
            options["error_exclude"] = quaternion_gauge(w_indices)
        method = INTEGRATORS.get(str(sim.integrator_name).lower(), sim.integrator_name)
        if getattr(method, "uses_linear_part", False) and "linear_part" not in options:
            options["linear_part"] = self._linear_part()
        return make_integrator(sim.integrator_name, sim.plan.derivative, sim.t, sim.x.copy(), t_bound,
                               normalize=normalize, **options)

    def _linear_part(self):
        sim = self.sim
        parts = [(sim.diagram.x_block[i], m, sim.context.hosts[i]) for i, m in enumerate(sim.models)
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
        return linear_part

    def restart_integrator(self, target: float):
        """The integrator positioned at the run's (t, x) heading for ``target``; reset only after a jump."""
        sim = self.sim
        integ = sim._integrator
        try:
            if integ is None:
                integ = sim._integrator = self.make_integrator(target)
                sim.counters["nfev"] += integ.nfev
            elif sim._integrator_stale or integ.t != sim.t:
                before = integ.nfev
                integ.reset(sim.t, sim.x.copy(), target)
                sim.counters["nfev"] += integ.nfev - before
            else:
                integ.extend(target)
        except ValueError as exc:  # non-finite derivative at the restart point
            culprit = sim.nonfinite_derivative(sim.t, sim.x.copy())
            raise sim.failure(f"{culprit or 'integrator restart failed'} at t = {sim.t:.9g} s ({exc})") from exc
        sim._integrator_stale = False
        return integ

    def _advance(self, target: float, update_due: bool = False) -> str | None:
        """Integrate the continuous states from the run's time to ``target``; returns a stop reason or None.

        ``update_due``: a sampled model updates at ``target``, after which the integrator restarts; a fixed-step
        method then skips the slope at the end of its last step (it would be recomputed with the new discrete
        states anyway), unless zero crossings need that step's dense output."""
        sim = self.sim
        if sim.x.size == 0:
            return None
        integ = self.restart_integrator(target)
        events = sim.event_location
        values = sim.plan.zero_crossings
        if hasattr(integ, "skip_final_slope"):
            integ.skip_final_slope = update_due and not events
        g_old = values(sim.t, integ.y) if events else None
        while integ.status == "running":
            nfev_before = integ.nfev
            integ.step()
            sim.counters["nfev"] += integ.nfev - nfev_before
            if integ.status == "failed":
                self._raise_failure(integ)
            sim.counters["steps"] += 1
            if events:
                g_new = values(integ.t, integ.y)
                if events.search(integ.t_old, g_old, g_new):
                    handled, stop = sim.handle_crossings(integ.dense_output(), integ.t_old, integ.t, g_old, g_new,
                                                         integ.normalize)
                    if handled:
                        sim._integrator_stale = True
                        if stop is not None:
                            return stop
                        self.restart_integrator(target)
                    integ = sim._integrator
                    g_old = values(integ.t, integ.y)  # at the restart, or again at the step's end
                    continue
                g_old = g_new
        sim.x[:] = integ.y
        sim.check_finite(f"t = {integ.t:.9g} s")
        return None

    def _raise_failure(self, integ) -> None:
        sim = self.sim
        bad_y = integ.failed_y if integ.failed_y is not None else integ.y
        culprit = sim.nonfinite_state(bad_y) or sim.nonfinite_derivative(integ.failed_t, bad_y)
        sim.x[:] = integ.y
        raise sim.failure(f"{culprit or 'a non-finite value'} at t = {integ.failed_t:.9g} s; the run stopped there "
                          f"(last good state at t = {integ.t:.9g} s). Integrator: {integ.message}")
