"""Zero-crossing (event) location on the dense output of one integration step.

An event function ``g(t, y) -> float`` fires where it changes sign; optional attributes (as in
scipy.integrate.solve_ivp): ``terminal`` (bool, the caller stops there) and ``direction`` (+1: only
rising crossings g from - to +; -1: only falling; 0: both).

Algorithm for a step [t_old, t_new] with continuous solution ``sol``:
1. Sample g on ``subdivisions`` equal sub-intervals of the dense output, so that two roots inside one
   step are separated into different sub-intervals unless they are closer than h / subdivisions.
2. For each run of three samples of equal sign, fit the parabola through them; if its extremum lies
   inside and has the opposite sign, sample g there too. This catches a close pair of roots (a grazing
   crossing) that the uniform samples straddle.
3. Every sign change between consecutive samples is bracketed and solved with Brent's method
   (scipy.optimize.brentq; R. P. Brent, "Algorithms for Minimization without Derivatives", 1973, ch. 4)
   to ``xtol`` in time. A sample where g is exactly zero is a root at that time; a zero at t_old is the
   event handled at the end of the previous step and is not reported again.
"""
import numpy as np
from numba import njit


def event(terminal=False, direction=0):
    """Decorator setting ``terminal`` and ``direction`` on an event function."""
    if direction not in (-1, 0, 1):
        raise ValueError(f"event direction must be -1, 0 or +1, got {direction!r}")

    def mark(g):
        g.terminal = bool(terminal)
        g.direction = direction
        return g

    return mark


def _event_direction(g):
    d = getattr(g, "direction", 0)
    d = 0 if d is None else d
    if d not in (-1, 0, 1):
        raise ValueError(f"event {getattr(g, '__name__', g)!r}: direction must be -1, 0 or +1, got {d!r}")
    return d


def _insert_extremum_samples(g, sol, ts, gs):
    """Step 2 of the module docstring: add samples at parabolic extrema that may hide two roots."""
    k = 0
    while k + 2 < len(ts):
        g0, g1, g2 = gs[k], gs[k + 1], gs[k + 2]
        same_sign = (g0 > 0 and g1 > 0 and g2 > 0) or (g0 < 0 and g1 < 0 and g2 < 0)
        if same_sign:
            t0, t1, t2 = ts[k], ts[k + 1], ts[k + 2]
            # parabola through three points (Newton form); extremum where its derivative vanishes
            d01 = (g1 - g0) / (t1 - t0)
            d12 = (g2 - g1) / (t2 - t1)
            curv = (d12 - d01) / (t2 - t0)
            if curv != 0.0:
                t_ext = 0.5 * (t0 + t1) - d01 / (2.0 * curv)
                if t0 < t_ext < t2 and t_ext != t1:
                    g_ext_model = g0 + d01 * (t_ext - t0) + curv * (t_ext - t0) * (t_ext - t1)
                    if np.sign(g_ext_model) != np.sign(g1) or abs(g_ext_model) < 0.1 * min(abs(g0), abs(g1), abs(g2)):
                        g_ext = float(g(t_ext, sol(t_ext)))
                        if np.sign(g_ext) != np.sign(g1):
                            pos = k + 1 if t_ext < t1 else k + 2
                            ts.insert(pos, t_ext)
                            gs.insert(pos, g_ext)
                            k += 1
                            continue
        k += 1


@njit(cache=True)
def _may_report(gs, ts, direction):
    """False when the samples ``gs`` of one function at ``ts`` can give neither a root (no sign change or zero
    between consecutive samples in a counted direction) nor an extremum sample (no run of three equal-sign
    samples whose parabola has an extremum inside, of the other sign or near zero): the tests of steps 2 and
    3, so that locate_events skips such a function (most of them, most of the time) without changing its
    answer."""
    n = gs.shape[0]
    for j in range(n - 1):
        a, b = gs[j], gs[j + 1]
        if a == 0.0 or np.isnan(a) or np.isnan(b):
            continue
        if b == 0.0:
            crossing = -1.0 if a > 0.0 else 1.0
        elif (a < 0.0) != (b < 0.0):
            crossing = 1.0 if b > 0.0 else -1.0
        else:
            continue
        if direction == 0 or direction == crossing:
            return True
    for k in range(n - 2):
        g0, g1, g2 = gs[k], gs[k + 1], gs[k + 2]
        if not ((g0 > 0 and g1 > 0 and g2 > 0) or (g0 < 0 and g1 < 0 and g2 < 0)):
            continue
        t0, t1, t2 = ts[k], ts[k + 1], ts[k + 2]
        d01 = (g1 - g0) / (t1 - t0)
        d12 = (g2 - g1) / (t2 - t1)
        curv = (d12 - d01) / (t2 - t0)
        if curv == 0.0:
            continue
        t_ext = 0.5 * (t0 + t1) - d01 / (2.0 * curv)
        if not (t0 < t_ext < t2 and t_ext != t1):
            continue
        model = g0 + d01 * (t_ext - t0) + curv * (t_ext - t0) * (t_ext - t1)
        if np.sign(model) != np.sign(g1) or abs(model) < 0.1 * min(abs(g0), abs(g1), abs(g2)):
            return True
    return False


def locate_events(event_functions, sol, t_old, t_new, g_old, g_new, xtol=1e-12, subdivisions=8, all_values=None,
                  samples=None):
    """All zero crossings of the event functions inside (t_old, t_new].

    Parameters
    ----------
    event_functions : list of callables g(t, y) (with optional ``terminal``, ``direction``).
    sol : dense output valid on [t_old, t_new] (``sol(t)`` scalar or 1-D array of times).
    g_old, g_new : event values at t_old and t_new (length ``len(event_functions)``).
    xtol : absolute time tolerance of each located root (s).
    subdivisions : number of equal sub-intervals sampled before bracketing (>= 1).
    all_values : optional callable ``(t, y) -> array`` returning every event function's value at once; used
        for the uniform sampling pass when one evaluation of all functions costs about as much as one of
        them (a simulation that evaluates the whole scene per call). The individual functions are still
        used for the extremum check and the root refinement.
    samples : optional (subdivisions - 1, m) array: every function's values at the inner uniform samples, already
        computed by the caller on the same dense output (the compiled loop's event search); replaces the
        uniform sampling pass.

    Returns
    -------
    list of (t_event, index) sorted by time, ties by index; only crossings matching each function's
    direction are reported.
    """
    m = len(event_functions)
    if m == 0 or t_new <= t_old:
        return []
    subdivisions = int(subdivisions)
    if subdivisions < 1:
        raise ValueError(f"subdivisions must be >= 1, got {subdivisions}")
    if not xtol > 0:
        raise ValueError(f"xtol must be positive, got {xtol!r}")
    g_old = np.asarray(g_old, dtype=np.float64).reshape(-1)
    g_new = np.asarray(g_new, dtype=np.float64).reshape(-1)
    if g_old.shape != (m,) or g_new.shape != (m,):
        raise ValueError(f"g_old and g_new must each hold {m} values (one per event function), "
                         f"got shapes {g_old.shape} and {g_new.shape}")
    t_samples = np.linspace(t_old, t_new, subdivisions + 1)
    y_inner = None
    inner_values = None
    if samples is not None and subdivisions > 1:
        inner_values = np.asarray(samples, dtype=np.float64).T
        if inner_values.shape != (m, subdivisions - 1):
            raise ValueError(f"samples must hold ({subdivisions - 1}, {m}) values (inner samples x event functions), "
                             f"got shape {inner_values.T.shape}")
    elif subdivisions > 1:
        y_inner = sol(t_samples[1:-1])
    if inner_values is None and all_values is not None and subdivisions > 1:
        inner_values = np.empty((m, subdivisions - 1))
        for j in range(subdivisions - 1):
            values = np.asarray(all_values(t_samples[j + 1], y_inner[:, j]), dtype=np.float64).reshape(-1)
            if values.shape != (m,):
                raise ValueError(f"all_values must return {m} values (one per event function), got shape "
                                 f"{values.shape}")
            inner_values[:, j] = values

    found = []
    for i, g in enumerate(event_functions):
        direction = _event_direction(g)
        ts = [float(t) for t in t_samples]
        gs = [float(g_old[i])]
        for j in range(1, subdivisions):
            if inner_values is not None:
                gs.append(float(inner_values[i, j - 1]))
            else:
                gs.append(float(g(ts[j], y_inner[:, j - 1])))
        gs.append(float(g_new[i]))
        if not _may_report(np.array(gs), t_samples, float(direction)):
            continue
        if subdivisions > 1:
            _insert_extremum_samples(g, sol, ts, gs)

        def g_on_step(t, g=g):
            return g(t, sol(t))

        for j in range(len(ts) - 1):
            a, b = gs[j], gs[j + 1]
            if a == 0.0 or np.isnan(a) or np.isnan(b):
                continue
            if b == 0.0:
                root = ts[j + 1]
                crossing = -np.sign(a)
            elif (a < 0.0) != (b < 0.0):
                from scipy.optimize import brentq  # imported here: scipy.optimize adds ~0.5 s to every start

                root = brentq(g_on_step, ts[j], ts[j + 1], xtol=xtol)
                crossing = np.sign(b)
            else:
                continue
            if direction == 0 or direction == crossing:
                found.append((float(root), i))
    found.sort()
    return found
