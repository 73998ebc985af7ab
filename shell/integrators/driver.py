"""``integrate``: run one integrator over an interval with events and output times (solve_ivp-like).

The shell's ``Simulation`` drives integrators itself (discrete rates, logging); this driver is for
plain ODEs: tests, benchmarks, sub-problems and users who want a one-call solution. Event handling is
the protocol the shell follows too: after each accepted step evaluate the event functions, locate every
crossing on the step's dense output (:func:`locate_events`), record them in time order and stop at
the first terminal one (the state there is taken from the dense output).
"""
import numpy as np

from .events import locate_events
from .registry import make_integrator


class IntegrationResult:
    """Output of :func:`integrate`.

    ``t`` (m,) and ``y`` (n, m): accepted step times or the requested ``t_eval``; ``t_events[i]`` /
    ``y_events[i]``: crossings of event function i; ``status``: "finished", "terminated" (terminal
    event) or "failed"; ``message``; counters ``nfev``, ``njev``, ``nlu``, ``nsteps``, ``nrejected``.
    """

    def __init__(self, t, y, t_events, y_events, status, message, integrator):
        self.t = t
        self.y = y
        self.t_events = t_events
        self.y_events = y_events
        self.status = status
        self.message = message
        self.success = status != "failed"
        self.integrator = integrator
        self.nfev = integrator.nfev
        self.njev = integrator.njev
        self.nlu = integrator.nlu
        self.nsteps = integrator.nsteps
        self.nrejected = integrator.nrejected


def integrate(method, fun, t0, y0, t_end, *, events=(), t_eval=None, event_xtol=1e-12,
              event_subdivisions=8, **options):
    """Integrate ``y' = fun(t, y)`` from t0 to t_end with the named method (see ``INTEGRATORS``).

    ``options`` go to the integrator (``step``, ``rtol``, ``atol``, ``max_step``, ``normalize``,
    ``error_exclude``, ``jac`` for implicit methods). ``t_eval``: increasing output times within
    [t0, t_end], interpolated on dense output; by default every accepted step is returned.
    """
    integ = make_integrator(method, fun, t0, y0, t_end, **options)
    events = list(events) if events else []
    if t_eval is not None:
        t_eval = np.asarray(t_eval, dtype=np.float64)
        if t_eval.ndim != 1 or np.any(np.diff(t_eval) < 0) or (t_eval.size and (
                t_eval[0] < t0 or t_eval[-1] > t_end)):
            raise ValueError(f"t_eval must be an increasing 1-D array within [t0, t_end] = [{t0}, {t_end}]")
    ts = []
    ys = []
    if t_eval is None:
        ts.append(integ.t)
        ys.append(integ.y.copy())
        next_eval = 0
    else:
        next_eval = int(np.searchsorted(t_eval, t0, side="right"))
        if t_eval.size and t_eval[0] == t0:
            ts.append(t0)
            ys.append(integ.y.copy())
    t_events = [[] for _ in events]
    y_events = [[] for _ in events]
    g_old = np.array([g(integ.t, integ.y) for g in events], dtype=np.float64)
    status = integ.status
    message = None
    while integ.status == "running":
        integ.step()
        if integ.status == "failed":
            status = "failed"
            message = integ.message
            break
        t_stop = integ.t
        sol = None
        if events:
            g_new = np.array([g(integ.t, integ.y) for g in events], dtype=np.float64)
            sol = integ.dense_output()
            roots = locate_events(events, sol, integ.t_old, integ.t, g_old, g_new, xtol=event_xtol,
                                  subdivisions=event_subdivisions)
            terminal_hit = False
            for t_root, i in roots:
                if terminal_hit and t_root > t_stop:
                    break
                y_root = sol(t_root)
                t_events[i].append(t_root)
                y_events[i].append(y_root)
                if getattr(events[i], "terminal", False) and not terminal_hit:
                    terminal_hit = True
                    t_stop = t_root
            g_old = g_new
        if t_eval is None:
            if t_stop == integ.t:
                ts.append(integ.t)
                ys.append(integ.y.copy())
            else:
                ts.append(t_stop)
                ys.append(sol(t_stop))
        else:
            stop = int(np.searchsorted(t_eval, t_stop, side="right"))
            if stop > next_eval:
                if sol is None:
                    sol = integ.dense_output()
                chunk = t_eval[next_eval:stop]
                ts.extend(chunk.tolist())
                vals = sol(chunk)
                ys.extend(vals[:, k] for k in range(chunk.size))
                next_eval = stop
        if t_stop < integ.t:
            status = "terminated"
            message = f"terminal event at t={t_stop:.12g} s"
            break
        status = integ.status
    if status == "finished":
        message = "reached t_end"
    y_out = np.array(ys).T if ys else np.empty((integ.n, 0))
    return IntegrationResult(np.array(ts), y_out, [np.array(v) for v in t_events],
                             [np.array(v) for v in y_events], status, message, integ)
