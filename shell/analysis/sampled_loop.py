"""Sampled closed-loop linear model of a scene: the map of one period of its sampled models, linearized.

A scene with sampled models (flight software at its rates) is, between two instants ``T`` apart at which the
sample schedule repeats, a map of its continuous state x and its discrete states z just after the updates at a
sample instant t_k to the same at t_k + T:

    (x, z)(t_k + T) = Phi(x(t_k), z(t_k))

Phi is the run itself (:meth:`shell.simulation.Simulation.run` from a restored snapshot): the continuous
dynamics integrated by the scene's integrator with the sampled models' outputs held (zero-order hold), the
updates of every sampled model at its samples in (t_k, t_k + T] (multi-rate, delay lines), log instants and all,
so the linear model is the nonlinear loop's own discretization. ``T`` is a common multiple of every sampled
model's period (default the least, the hyperperiod), so Phi is the same map at t_k + j T and, about a fixed
point, its Jacobian ``M = dPhi/d(xi, zeta)`` is the monodromy matrix of the sampled loop (Floquet); for one
rate it is the zero-order-hold discretization of the plant composed with the controller's update (Franklin,
Powell & Workman, Digital Control of Dynamic Systems, 3rd ed., sec. 4.3, 6.2). The loop is asymptotically
stable when the spectral radius ``rho(M) < 1``; an eigenvalue lambda decays at ``ln|lambda| / T`` (1/s) and
turns at ``arg(lambda) / (2 pi T)`` (Hz).

Coordinates: the continuous states in linearize's tangent coordinates (:class:`TangentStates`: a quaternion
``q = q_ref (x) Exp(phi)``, q_ref the reference run's quaternion at the start, resp. at the end of the period,
and ``phi = Log(q_ref^* (x) q)`` back), the discrete states element by element, except where a model gives
time-invariant coordinates of its discrete state (``sampled_coordinates(z)``: a delay line's ring buffer oldest
sample first, its row pointer left out). Columns by linearize's central differences with Richardson
extrapolation (:func:`shell.analysis.linearize.difference_column`); the random streams are restored with the
snapshot, so every perturbed run sees the same noise. A fixed-step integrator makes Phi smooth; an adaptive
one chooses its steps from the state, and the differences then carry its tolerance (warned).
"""

from __future__ import annotations

import math
import re
import warnings
from fractions import Fraction

import numpy as np

from shell.analysis.linearize import SCHEMES, LinearizationError, LinearModel, TangentStates, difference_column
from shell.integrators import INTEGRATORS
from shell.units import format_unit

#: largest drift of the reference run over one period (relative to the states' scales) taken as a fixed point
FIXED_POINT_TOLERANCE = 1e-6


def loop_period(sim, period=None) -> Fraction:
    """The period of the sampled loop: ``period`` (s), checked to be a multiple of every sampled model's period,
    or the least common multiple of those periods."""
    sampled = [(m, p) for m, p in zip(sim.models, sim.context.periods) if p is not None]
    if not sampled:
        raise LinearizationError("the scene has no sampled model (none has a rate or a period): there is no "
                                 "sampled loop to linearize; linearize without --sampled for the continuous model")
    least = Fraction(0)
    for _, p in sampled:
        least = p if least == 0 else Fraction(math.lcm(least.numerator * p.denominator, p.numerator *
                                                       least.denominator), least.denominator * p.denominator)
    if period is None:
        return least
    if not (isinstance(period, (int, float, Fraction)) and math.isfinite(period) and period > 0):
        raise LinearizationError(f"period (--period) {period!r}: expected a time > 0 (s)")
    T = Fraction(period).limit_denominator(10**9)
    for m, p in sampled:
        if (T / p).denominator != 1:
            raise LinearizationError(f"period (--period) {float(T):g} s is not a multiple of the period "
                                     f"{float(p):g} s of {m.path}: the sample schedule would not repeat; "
                                     f"use a multiple of {float(least):g} s (every sampled model's period)")
    return T


def _at_sample_instant(sim) -> None:
    """Bring the scene to just after the updates at its current instant; refuse a time that is no sample."""
    context, t = sim.context, Fraction(sim.t).limit_denominator(10**9)
    pending = [i for i, s in enumerate(context.next_sample) if s is not None and s == t]
    done = [i for i, s in enumerate(context.next_sample) if s is not None and s - context.periods[i] == t]
    if not pending and not done:
        listed = ", ".join(f"{m.path} every {float(p):g} s from {float(o):g} s" for m, p, o in
                           zip(sim.models, context.periods, context.offsets) if p is not None)
        raise LinearizationError(f"the scene is at t = {sim.t:.9g} s, not a sample instant of any sampled model "
                                 f"({listed}): the sampled loop's map starts at a sample (--at a sample time)")
    if pending:
        sim.run(sim.t)  # the updates due now: the map starts just after them


class _DiscreteCoordinates:
    """The discrete states as coordinates: positions in z, read from a given z (a model's ``sampled_coordinates``
    follow its ring buffers), with names and units."""

    def __init__(self, sim):
        self.sim = sim
        self.names, self.units, self.index, self.parts = [], [], {}, []
        entries = sim.diagram.state_entries("z")
        for i, block in enumerate(sim.diagram.z_block):
            if block.stop == block.start:
                continue
            self.parts.append(i)
            rows = {}
            for position in block.start + self._local(i, sim.z):  # in the coordinates' order
                key, sl, decl = next(entry for entry in entries if entry[1].start <= position < entry[1].stop)
                label = f"{key[0]}.{key[1]}"
                members = rows.setdefault(label, [])
                # the coordinate's place in its state (a delay line's buffer: 0 the oldest sample)
                self.names.append(f"{label}[{len(members)}]" if sl.stop - sl.start > 1 else label)
                self.units.append(format_unit(decl.unit))
                members.append(len(self.names) - 1)
            self.index.update({label: np.asarray(members, dtype=np.int64) for label, members in rows.items()})
        self.n = len(self.names)

    def _local(self, i, z):
        model, block = self.sim.models[i], self.sim.diagram.z_block[i]
        coordinates = getattr(model, "sampled_coordinates", None)
        if coordinates is None:
            return np.arange(block.stop - block.start)
        return np.asarray(coordinates(z[block]), dtype=np.int64)

    def positions(self, z):
        """Positions in z of the coordinates (in :attr:`names` order) for the discrete state z."""
        parts = [self.sim.diagram.z_block[i].start + self._local(i, z) for i in self.parts]
        return np.concatenate(parts) if parts else np.zeros(0, dtype=np.int64)


def sampled_linearize(sim, *, period=None, tolerance: float = 1e-10, points: int = 4, richardson: bool = True,
                      scales=None, metadata=None) -> LinearModel:
    """The sampled closed-loop linear model of ``sim`` at its current sample instant (module docstring):
    ``A`` the Jacobian of the period map in the coordinates ``state_names`` (the continuous states' tangent
    coordinates, then the discrete states), no inputs or outputs, ``metadata["sample_time"]`` the period.
    ``period`` (s): a multiple of every sampled model's period (default the least). ``scales``: {state name:
    typical size} as for :func:`shell.analysis.linearize.linearize`. The scene is left as it was found (at its
    sample instant, just after the updates there)."""
    if (points, bool(richardson)) not in SCHEMES:
        raise LinearizationError(f"points = {points}: expected 2 or 4 (central differences)")
    if not 0.0 < tolerance < 1.0:
        raise LinearizationError(f"tolerance = {tolerance}: expected a relative error in (0, 1)")
    T = loop_period(sim, period)
    method = INTEGRATORS.get(str(sim.integrator_name).lower(), sim.integrator_name)
    if getattr(method, "adaptive", False):
        warnings.warn(f"integrator {sim.integrator_name} chooses its steps from the state: the sampled model's "
                      "differences carry its tolerance (a fixed-step method makes the period map smooth)",
                      stacklevel=2)
    _at_sample_instant(sim)
    start = sim.snapshot()
    t0, t_end = sim.t, float(Fraction(sim.t).limit_denominator(10**9) + T)
    x0, z0 = start["x"].copy(), start["z"].copy()
    states = TangentStates(sim, x0, dict(scales or {}))
    discrete = _DiscreteCoordinates(sim)
    z_start = discrete.positions(z0)
    n_x, n = states.n, states.n + discrete.n
    z_scale = np.maximum(np.abs(z0[z_start]), 1.0)
    for name, given in (scales or {}).items():
        if name in discrete.index:
            z_scale[discrete.index[name]] = np.maximum(z_scale[discrete.index[name]], given)
        elif name not in states.index:
            raise LinearizationError(f"scale given for {name!r}, which is not a state; states: "
                                     f"{sorted(states.index) + sorted(discrete.index)}")

    def period_map(xi, zeta):
        sim.restore(start)
        z = z0.copy()
        z[z_start] += zeta
        sim.set_state(states.retract(xi), z)
        summary = sim.run(t_end)
        if summary.status != "completed":
            raise LinearizationError(f"the run over the period [{t0:.9g}, {t_end:.9g}] s stopped: {summary.reason}")
        return sim.x.copy(), sim.z.copy()

    try:
        x_ref, z_ref = period_map(np.zeros(n_x), np.zeros(discrete.n))
        z_end = discrete.positions(z_ref)

        def coordinates(x, z):
            return np.concatenate((states.between(x, x_ref), z[z_end] - z_ref[z_end]))

        drift = np.concatenate((states.between(x_ref, x0), z_ref[z_end] - z0[z_start]))
        scale = np.concatenate((states.scale, z_scale))
        M, err, steps = np.empty((n, n)), np.empty((n, n)), np.empty(n)
        for j in range(n):
            def at(delta, j=j):
                xi, zeta = np.zeros(n_x), np.zeros(discrete.n)
                if j < n_x:
                    xi[j] = delta
                else:
                    zeta[j - n_x] = delta
                return coordinates(*period_map(xi, zeta))

            M[:, j], err[:, j], steps[j] = difference_column(at, scale[j], np.zeros(n), tolerance, points,
                                                             richardson, (states.names + discrete.names)[j])
    finally:
        sim.restore(start)
    names = states.names + discrete.names
    worst = int(np.argmax(np.abs(drift) / scale)) if n else 0
    if n and abs(drift[worst]) > FIXED_POINT_TOLERANCE * scale[worst]:
        warnings.warn(f"the scene is not at a fixed point of its sampled loop: {names[worst]} moves by "
                      f"{drift[worst]:.3g} over one period ({float(T):g} s); the eigenvalues are those of the "
                      "period map along this motion, not of an equilibrium", stacklevel=2)
    index = dict(states.index)
    index.update({name: rows + n_x for name, rows in discrete.index.items()})
    empty = np.zeros((0, 0))
    return LinearModel(M, np.zeros((n, 0)), np.zeros((0, n)), empty, names, states.units + discrete.units,
                       [], [], [], [], {"A": err, "B": np.zeros((n, 0)), "C": np.zeros((0, n)), "D": empty},
                       {"t": t0, "x": x0, "z": z0, "u": np.zeros(0), "y": np.zeros(0), "drift": drift,
                        "tangent": np.concatenate((states.value, z0[z_start]))},
                       index, {}, {},
                       method={"points": points, "richardson": bool(richardson), "tolerance": tolerance,
                               "order": SCHEMES[(points, bool(richardson))], "state_steps": steps,
                               "input_steps": np.zeros(0)},
                       metadata={**dict(metadata or {}), "sample_time": float(T), "model": "sampled closed loop"})


_SLICE = re.compile(r"^(.*)\[(\d+):(\d+)\]$")


def kept_states(model: LinearModel, leave_out=()) -> np.ndarray:
    """Indices of the states that stay in the stability verdict when the states ``leave_out`` (state names,
    ``name[a:b]`` ranges of them, or index keys such as ``multibody.bus.hinge_q``) are left out: a free body's
    translation, say, which no feedback reaches. The eigenvalues of the kept block are eigenvalues of the whole
    model only when the kept states do not depend on the ones left out (the matrix is block triangular), so a
    coupling entry beyond ten times its error estimate (and 1e-12 of the largest entry) is refused."""
    position = {name: i for i, name in enumerate(model.state_names)}
    out = set()
    for name in leave_out:
        match = _SLICE.match(name.strip())
        if match:
            rows = [position.get(f"{match.group(1)}[{k}]") for k in range(int(match.group(2)), int(match.group(3)))]
        elif name in position:
            rows = [position[name]]
        else:
            rows = list(model.state_index.get(name, [None]))
        if not rows or None in rows:
            raise LinearizationError(f"states left out (--leave-out) {name!r}: not a state of the model; states: "
                                     f"{', '.join(model.state_names)}")
        out.update(int(r) for r in rows)
    kept = np.array([i for i in range(model.A.shape[0]) if i not in out], dtype=np.int64)
    out = np.array(sorted(out), dtype=np.int64)
    if out.size and kept.size:
        coupling = np.abs(model.A[np.ix_(kept, out)])
        bound = 10.0 * model.errors["A"][np.ix_(kept, out)] + 1e-12 * np.max(np.abs(model.A))
        if np.any(coupling > bound):
            i, j = np.unravel_index(np.argmax(coupling - bound), coupling.shape)
            raise LinearizationError(
                f"states left out (--leave-out): {model.state_names[kept[i]]} depends on "
                f"{model.state_names[out[j]]} (entry {model.A[kept[i], out[j]]:.3g}, estimated error "
                f"{model.errors['A'][kept[i], out[j]]:.3g}): leaving it out would change the other eigenvalues")
    return kept


def loop_eigenvalues(model: LinearModel, leave_out=()):
    """[(eigenvalue, ``abs(eigenvalue)``, decay rate ``ln(abs(lambda)) / T`` (1/s), frequency (Hz), the state with
    the largest eigenvector component)] of a sampled closed-loop model, least stable first; ``leave_out``: states
    left out (:func:`kept_states`)."""
    T = float(model.metadata["sample_time"])
    kept = kept_states(model, leave_out)
    values, vectors = np.linalg.eig(model.A[np.ix_(kept, kept)])
    order = np.argsort(-np.abs(values), kind="stable")
    rows = []
    for k in order:
        lam = values[k]
        magnitude = abs(lam)
        rate = math.log(magnitude) / T if magnitude > 0 else -math.inf
        rows.append((lam, magnitude, rate, abs(np.angle(lam)) / (2.0 * math.pi * T),
                     model.state_names[kept[int(np.argmax(np.abs(vectors[:, k])))]]))
    return rows


def spectral_radius(model: LinearModel, leave_out=()) -> float:
    """Largest eigenvalue magnitude of the sampled closed-loop model (the states ``leave_out`` left out)."""
    kept = kept_states(model, leave_out)
    return float(np.max(np.abs(np.linalg.eigvals(model.A[np.ix_(kept, kept)])), initial=0.0))
