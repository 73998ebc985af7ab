"""The simulation: flattens an assembly into flat float64 buffers and drives the integrator.

Build time (once): the model tree is flattened (:func:`shell.assembly.flatten`); every output and input
port gets a slice of one signal buffer, every continuous state a slice of the state vector ``x``, every
discrete state a slice of ``z``; each connection becomes element index pairs with the unit conversion
factor of its two ports (``deg/s -> rad/s`` = pi/180), after dimensions and shapes are checked. Outputs
are ordered by a topological sort (networkx) of the direct-feedthrough graph, whose nodes are each
model's *state-output* and *feedthrough-output* stages; a cycle is an algebraic loop and is refused
with the models and ports on it.

Per derivative evaluation f(t, x) (the integrator's ``fun``): copy ``x`` into the state buffer, run the
output plan in order (gather a model's feedthrough inputs, call its output kernel), gather every input,
call every derivative kernel, return ``xdot``. No dict look-up, no pint, no allocation except the
returned copy.

Run loop (TM-2020-5008164 App. D.1: multi-rate models, zero finding): integrate continuously up to the
next instant at which a sampled model updates or a log group samples (exact rational sample instants),
checking the models' zero-crossing functions after each step. Every crossing (the default
``event_detection="subdivided"`` samples each step on the dense output, so two crossings inside one step
are both found; ``"sign_change"`` searches only steps whose ends differ in sign, cheaper but blind to
such pairs) is located to ``event_tol`` on the integrator's dense output (:func:`shell.integrators.locate_events`), the
state is moved to the
crossing, the models' ``on_event`` handlers run (state reset, mode switch) in (time, model order), and
the integrator restarts; a terminal crossing stops the run. At a sample instant the due sampled models
update one after another in dataflow order (upstream first, ties by declaration order), each seeing the
outputs the previous ones just produced; their outputs are then held until their next sample.
"""

from __future__ import annotations

import gc
import json
import time as _time
import weakref
from dataclasses import dataclass
from fractions import Fraction

import h5py
import networkx as nx
import numpy as np
from numba import njit

from shell.assembly import Assembly, Connection, flatten
from shell.integrators import INTEGRATORS, locate_events, make_integrator, quaternion_gauge
from shell.log_file import LoggedSignal, LogWriter
from shell.model import ModelError, parse_period
from shell.units import UnitError, conversion_factor, format_unit, to_magnitude


class WiringError(ModelError):
    """A connection or port configuration refused at build time."""


class AlgebraicLoopError(WiringError):
    """Direct-feedthrough outputs depend on themselves; the message names the models and ports."""


class SimulationError(RuntimeError):
    """A run that could not continue; the message names the model and the time."""


@njit(cache=True)
def gather_inputs(signals, source, destination, factor, start, stop):
    """signals[destination[k]] = factor[k] * signals[source[k]] for k in [start, stop)."""
    for k in range(start, stop):
        signals[destination[k]] = factor[k] * signals[source[k]]


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

    @property
    def real_time_factor(self) -> float:
        return (self.t_end - self.t_start) / self.wall_time if self.wall_time > 0 else float("inf")

    def __str__(self) -> str:
        return (f"{self.status} at t = {self.t_end:.6g} s ({self.reason}); wall time {self.wall_time:.3f} s, "
                f"{self.steps} steps, {self.derivative_evaluations} derivative evaluations, "
                f"{self.discrete_updates} discrete updates, {self.events} events, "
                f"real-time factor {self.real_time_factor:.3g}")


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
    """A built, runnable scene: buffers, evaluation plans, integrator, sampling schedule, log."""

    def __init__(self, root: Assembly, *, integrator: str = "rk4", step: float | None = 0.01,
                 integrator_options: dict | None = None, seed=0, stop_events=(), event_tol: float = 1e-10,
                 event_detection: str = "subdivided", t_start: float = 0.0, fuse: bool = False):
        self.root = root
        self.seed = seed
        self.event_tol = float(event_tol)
        if event_detection not in ("sign_change", "subdivided"):
            raise ModelError(f"event detection {event_detection!r}: expected 'sign_change' (search a step when a "
                             "zero-crossing function changes sign between its ends) or 'subdivided' (search every "
                             "step on its dense output: also finds two crossings inside one step)")
        self.event_detection = event_detection
        self.models, self.connections = flatten(root)
        if not self.models:
            raise WiringError("the scene has no models")
        self.model_index = {m.path: i for i, m in enumerate(self.models)}
        self._allocate()
        self._wire()
        self._order_outputs()
        self._order_updates()
        self._noise = {i: np.zeros(int(m.noise_size)) for i, m in enumerate(self.models) if m.noise_size}
        self._collect_zero_crossings(stop_events)
        for m in self.models:
            m.seed_random_stream(seed)
        self.t = float(t_start)
        self._next_sample = [m.offset if m.period is not None else None for m in self.models]
        start = Fraction(self.t).limit_denominator(10**9)
        for i, m in enumerate(self.models):  # first sample at or after t_start
            if m.period is not None and self._next_sample[i] < start:
                k = -(-(start - m.offset) // m.period)
                self._next_sample[i] = m.offset + k * m.period
        self.integrator_name = integrator
        self.integrator_options = dict(integrator_options or {})
        if step is not None:
            self.integrator_options["step"] = step
        #: the integrator's right-hand side: the interpreted plan, or one compiled function (fuse=True;
        #: ~10x cheaper per call for trivial models, seconds of compilation per scene: shell.fused)
        self.rhs = self.derivative
        if fuse:
            from shell.fused import fuse_derivative

            self.rhs = fuse_derivative(self)
        self._integrator = None
        self._integrator_stale = True
        self._normalizers = [m for m in self.models if hasattr(m, "normalize_state")]
        self._log_groups: dict[str, dict] = {}
        self._initialized = False
        self.counters = {"steps": 0, "nfev": 0, "events": 0, "updates": 0}
        #: (time, "model.zero_crossing") of every handled event, in order
        self.events: list[tuple[float, str]] = []
        for m in self.models:  # a model's random stream and engine workspace serve one simulation
            owner = getattr(m, "_simulation", None)
            if owner is not None and owner() is not None:
                gc.collect()  # a discarded simulation may still be waiting in a reference cycle
            if owner is not None and owner() is not None:
                raise ModelError(f"model {m.path} already belongs to another Simulation (its random stream and "
                                 "workspace would be shared); build the scene again for a second simulation")
        for m in self.models:
            m._simulation = weakref.ref(self)

    # ------------------------------------------------------------------------------------------------
    # build
    def _allocate(self) -> None:
        n_signals = n_x = n_z = 0
        self.port_slices: dict[tuple[str, str], slice] = {}
        self.port_info: dict[tuple[str, str], object] = {}
        self._y_block, self._u_block, self._x_block, self._z_block = [], [], [], []
        for m in self.models:
            self._y_block.append(slice(n_signals, n_signals + m.y_layout.size))
            for port in m.outputs:
                self.port_slices[(m.path, port.name)] = slice(n_signals, n_signals + port.size)
                self.port_info[(m.path, port.name)] = port
                n_signals += port.size
            self._u_block.append(slice(n_signals, n_signals + m.u_layout.size))
            for port in m.inputs:
                self.port_slices[(m.path, port.name)] = slice(n_signals, n_signals + port.size)
                self.port_info[(m.path, port.name)] = port
                n_signals += port.size
            self._x_block.append(slice(n_x, n_x + m.x_layout.size))
            n_x += m.x_layout.size
            self._z_block.append(slice(n_z, n_z + m.z_layout.size))
            n_z += m.z_layout.size
        self.signals = np.zeros(n_signals)
        self.x = np.zeros(n_x)
        self.xdot = np.zeros(n_x)
        self.z = np.zeros(n_z)
        for i, m in enumerate(self.models):
            self.x[self._x_block[i]] = m.initial_continuous_state()
            self.z[self._z_block[i]] = m.initial_discrete_state()
        self.state_slices: dict[tuple[str, str], tuple[str, slice, object]] = {}
        for i, m in enumerate(self.models):
            for kind, decls, block in (("x", m.continuous_states, self._x_block[i]),
                                       ("z", m.discrete_states, self._z_block[i])):
                layout = m.x_layout if kind == "x" else m.z_layout
                for s in decls:
                    sl = layout.slice(s.name)
                    self.state_slices[(m.path, s.name)] = (kind, slice(block.start + sl.start,
                                                                       block.start + sl.stop), s)

    def _wire(self) -> None:
        driver: dict[tuple[str, str], Connection] = {}
        sources, destinations, factors, dst_model, dst_ft = [], [], [], [], []
        for c in self.connections:
            src_key = (c.source_model.path, c.source_port)
            dst_key = (c.destination_model.path, c.destination_port)
            out_port = self.port_info[src_key]
            in_port = self.port_info[dst_key]
            ends = f"{c.origin}: connection {src_key[0]}.{src_key[1]} -> {dst_key[0]}.{dst_key[1]}"
            if dst_key in driver:
                first = driver[dst_key]
                raise WiringError(f"input {dst_key[0]}.{dst_key[1]} is driven twice: by "
                                  f"{first.source_model.path}.{first.source_port} ({first.origin}) and by "
                                  f"{src_key[0]}.{src_key[1]} ({c.origin})")
            driver[dst_key] = c
            if tuple(out_port.shape) != tuple(in_port.shape):
                raise WiringError(f"{ends}: shape mismatch: output has shape {out_port.shape}, input expects "
                                  f"{in_port.shape}")
            try:
                factor = conversion_factor(out_port.unit, in_port.unit, ends)
            except UnitError as exc:
                raise WiringError(f"{exc}; output unit {format_unit(out_port.unit)}, input unit "
                                  f"{format_unit(in_port.unit)}") from None
            src_sl, dst_sl = self.port_slices[src_key], self.port_slices[dst_key]
            sources.extend(range(src_sl.start, src_sl.stop))
            destinations.extend(range(dst_sl.start, dst_sl.stop))
            factors.extend([factor] * out_port.size)
            dst_model.extend([self.model_index[dst_key[0]]] * out_port.size)
            dst_ft.extend([0 if in_port.feedthrough else 1] * out_port.size)
        missing = []
        for m in self.models:
            for port in m.inputs:
                if (m.path, port.name) in driver:
                    continue
                if port.required:
                    missing.append(f"{m.path}.{port.name} ({format_unit(port.unit)}, shape {port.shape}"
                                   f"{': ' + port.description if port.description else ''})")
                else:
                    default = port.default if port.default is not None else np.zeros(port.shape)
                    self.signals[self.port_slices[(m.path, port.name)]] = to_magnitude(
                        default, port.unit, port.shape, f"input {m.path}.{port.name} default").reshape(-1)
        if missing:
            raise WiringError("unconnected required input(s): " + "; ".join(missing))
        self.driver = driver
        # sorted by destination model, feedthrough inputs first: each model's feedthrough inputs are one
        # contiguous range gathered just before its feedthrough outputs are computed
        order = np.lexsort((np.asarray(dst_ft, dtype=np.int64), np.asarray(dst_model, dtype=np.int64))) \
            if sources else np.zeros(0, dtype=np.int64)
        self._src = np.asarray(sources, dtype=np.int64)[order] if sources else np.zeros(0, dtype=np.int64)
        self._dst = np.asarray(destinations, dtype=np.int64)[order] if sources else np.zeros(0, dtype=np.int64)
        self._factor = np.asarray(factors, dtype=np.float64)[order] if sources else np.zeros(0)
        dst_model_sorted = np.asarray(dst_model, dtype=np.int64)[order] if sources else np.zeros(0, dtype=np.int64)
        dst_ft_sorted = np.asarray(dst_ft, dtype=np.int64)[order] if sources else np.zeros(0, dtype=np.int64)
        self._ft_range = []
        for i in range(len(self.models)):
            ks = np.flatnonzero((dst_model_sorted == i) & (dst_ft_sorted == 0))
            self._ft_range.append((int(ks[0]), int(ks[-1]) + 1) if ks.size else (0, 0))
        self._n_gather = int(self._src.size)

    def _order_outputs(self) -> None:
        graph = nx.DiGraph()
        stage_rank = {}
        for i, m in enumerate(self.models):
            if m.state_outputs is not None:
                graph.add_node((m.path, "state"))
                stage_rank[(m.path, "state")] = (i, 0)
            if m.feedthrough_outputs is not None:
                graph.add_node((m.path, "feedthrough"))
                stage_rank[(m.path, "feedthrough")] = (i, 1)
        port_labels = {}
        for c in self.connections:
            in_port = self.port_info[(c.destination_model.path, c.destination_port)]
            if not in_port.feedthrough:
                continue
            out_port = self.port_info[(c.source_model.path, c.source_port)]
            stage = "feedthrough" if out_port.feedthrough else "state"
            edge = ((c.source_model.path, stage), (c.destination_model.path, "feedthrough"))
            graph.add_edge(*edge)
            port_labels[edge] = f"{c.source_model.path}.{c.source_port} -> {c.destination_model.path}." \
                                f"{c.destination_port}"
        try:
            order = list(nx.lexicographical_topological_sort(graph, key=lambda n: stage_rank[n]))
        except nx.NetworkXUnfeasible:
            cycle = nx.find_cycle(graph)
            models = []
            for a, _ in cycle:
                if a[0] not in models:
                    models.append(a[0])
            ports = "; ".join(port_labels[(a, b)] for a, b in cycle)
            raise AlgebraicLoopError(
                f"algebraic loop through models {' -> '.join(models)} -> {models[0]}: each output feeds "
                f"through to the next without a state in between ({ports}). Break it with a state "
                f"(a filter, a sampled model) or remove a direct feedthrough.") from None
        needed = self._stages_needed_by_derivatives()
        self._output_plan_full, self._output_plan = [], []
        for path, stage in order:
            i = self.model_index[path]
            m = self.models[i]
            fn = m.state_outputs if stage == "state" else m.feedthrough_outputs
            k0, k1 = self._ft_range[i] if stage == "feedthrough" else (0, 0)
            entry = (m, fn, self.x[self._x_block[i]], self.z[self._z_block[i]],
                     self.signals[self._u_block[i]], m.p, self.signals[self._y_block[i]], k0, k1)
            self._output_plan_full.append(entry)
            if (path, stage) in needed:
                self._output_plan.append(entry)
        self._derivative_plan = []
        for i, m in enumerate(self.models):
            if m.x_layout.size:
                if m.derivatives is None:
                    raise ModelError(f"model {m.path}: has continuous states but no derivatives kernel")
                self._derivative_plan.append((m, m.derivatives, self.x[self._x_block[i]], self.z[self._z_block[i]],
                                              self.signals[self._u_block[i]], m.p, self.xdot[self._x_block[i]]))

    def _stages_needed_by_derivatives(self) -> set:
        """Output stages a derivative evaluation must run: those feeding, directly or through
        feedthrough stages, an input of a model with continuous states or zero crossings. Inputs of
        purely sampled models are read only at their sample instants (full evaluation there)."""
        feeding = self._feeding_stages()
        return self._stages_closure([stage for m in self.models if m.x_layout.size or m.zero_crossings
                                     for stage, _ in feeding.get(m.path, [])], feeding)

    def _feeding_stages(self) -> dict[str, list]:
        """{model path: [((source path, "feedthrough" | "state"), input is feedthrough), ...]}."""
        feeding: dict[str, list] = {}
        for c in self.connections:
            out_port = self.port_info[(c.source_model.path, c.source_port)]
            in_port = self.port_info[(c.destination_model.path, c.destination_port)]
            stage = (c.source_model.path, "feedthrough" if out_port.feedthrough else "state")
            feeding.setdefault(c.destination_model.path, []).append((stage, in_port.feedthrough))
        return feeding

    def _stages_closure(self, stages, feeding: dict[str, list] | None = None) -> set:
        """``stages`` and every output stage they need: a feedthrough stage needs the stages feeding
        its feedthrough inputs, recursively."""
        feeding = self._feeding_stages() if feeding is None else feeding
        needed: set = set()
        pending = list(stages)
        while pending:
            stage = pending.pop()
            if stage in needed:
                continue
            needed.add(stage)
            if stage[1] == "feedthrough":
                pending.extend(s for s, through in feeding.get(stage[0], []) if through)
        return needed

    def _order_updates(self) -> None:
        graph = nx.DiGraph()
        graph.add_nodes_from(range(len(self.models)))
        for c in self.connections:
            graph.add_edge(self.model_index[c.source_model.path], self.model_index[c.destination_model.path])
        condensed = nx.condensation(graph)
        rank = {}
        for position, component in enumerate(nx.lexicographical_topological_sort(
                condensed, key=lambda n: min(condensed.nodes[n]["members"]))):
            for member in condensed.nodes[component]["members"]:
                rank[member] = (position, member)
        self._update_order = sorted((i for i, m in enumerate(self.models) if m.period is not None),
                                    key=lambda i: rank[i])

    def _collect_zero_crossings(self, stop_events) -> None:
        self._zc_plan, self._zc_owner = [], []
        declared = {}
        n = 0
        for i, m in enumerate(self.models):
            if not m.zero_crossings:
                continue
            self._zc_plan.append((m, m.zero_crossing_values, self.x[self._x_block[i]], self.z[self._z_block[i]],
                                  self.signals[self._u_block[i]], m.p, slice(n, n + len(m.zero_crossings))))
            for k, zc in enumerate(m.zero_crossings):
                self._zc_owner.append((i, k, zc))
                declared[f"{m.path}.{zc.name}"] = n + k
            n += len(m.zero_crossings)
        terminal = [zc.terminal for _, _, zc in self._zc_owner]
        for name in stop_events:
            if name not in declared:
                raise ModelError(f"stop event {name!r}: no such zero crossing; declared: {sorted(declared) or 'none'}")
            terminal[declared[name]] = True
        if n and self.x.size == 0:
            raise ModelError(f"zero crossings {sorted(declared)} need continuous states to be located on; "
                             "the scene has none")
        self._g = np.zeros(n)
        self._last_events: tuple[float, set] = (-np.inf, set())
        self._event_functions = [_EventFunction(self, j, zc.direction, terminal[j])
                                 for j, (_, _, zc) in enumerate(self._zc_owner)]

    # ------------------------------------------------------------------------------------------------
    # evaluation
    def _evaluate_outputs(self, t: float, plan) -> None:
        signals, src, dst, factor = self.signals, self._src, self._dst, self._factor
        entry = None
        try:
            for entry in plan:
                m, fn, x, z, u, p, y, k0, k1 = entry
                if k1 > k0:
                    gather_inputs(signals, src, dst, factor, k0, k1)
                fn(t, x, z, u, p, y)
        except Exception as exc:
            raise SimulationError(f"model {entry[0].path} failed computing outputs at t = {t:.9g} s: "
                                  f"{type(exc).__name__}: {exc}") from exc

    def derivative(self, t: float, y: np.ndarray) -> np.ndarray:
        """f(t, x): the integrator's right-hand side (continuous states of every model)."""
        self.x[:] = y
        self._evaluate_outputs(t, self._output_plan)
        gather_inputs(self.signals, self._src, self._dst, self._factor, 0, self._n_gather)
        entry = None
        try:
            for entry in self._derivative_plan:
                m, fn, x, z, u, p, xdot = entry
                fn(t, x, z, u, p, xdot)
        except Exception as exc:
            raise SimulationError(f"model {entry[0].path} failed computing derivatives at t = {t:.9g} s: "
                                  f"{type(exc).__name__}: {exc}") from exc
        return self.xdot.copy()

    def evaluate(self, t: float | None = None) -> None:
        """Compute every output and input at the current state (used at sample and log instants)."""
        self._evaluate_outputs(self.t if t is None else t, self._output_plan_full)
        gather_inputs(self.signals, self._src, self._dst, self._factor, 0, self._n_gather)

    def _zero_crossing_vector(self, t: float, y: np.ndarray) -> np.ndarray:
        self.x[:] = y
        self.evaluate(t)
        for m, fn, x, z, u, p, sl in self._zc_plan:
            fn(t, x, z, u, p, self._g[sl])
        return self._g.copy()

    # ------------------------------------------------------------------------------------------------
    # signals by name
    def signal(self, name: str) -> np.ndarray:
        """Current value of a port or state by dotted name (a copy, in the port's/state's unit)."""
        kind, sl, decl = self._locate(name)
        source = {"signal": self.signals, "x": self.x, "z": self.z}[kind]
        return source[sl].reshape(decl.shape).copy()

    def _locate(self, name: str):
        model_path, sep, leaf = self._split_name(name)
        key = (model_path, leaf)
        if key in self.port_slices:
            return "signal", self.port_slices[key], self.port_info[key]
        if key in self.state_slices:
            kind, sl, decl = self.state_slices[key]
            return kind, sl, decl
        model = self.models[self.model_index[model_path]]
        names = [p.name for p in model.outputs + model.inputs] + [s.name for s in model.continuous_states
                                                                  + model.discrete_states]
        raise ModelError(f"signal {name!r}: model {model_path} has no port or state {leaf!r}; it has {names}")

    def _split_name(self, name: str):
        parts = name.split(".")
        for cut in range(len(parts) - 1, 0, -1):
            path = ".".join(parts[:cut])
            if path in self.model_index:
                return path, ".", ".".join(parts[cut:])
        raise ModelError(f"signal {name!r}: no model path is a prefix of it; models: {sorted(self.model_index)}")

    # ------------------------------------------------------------------------------------------------
    # logging
    def log(self, signals, rate) -> None:
        """Log ``signals`` (dotted port/state names) every ``rate`` ("10 Hz", "0.1 s", seconds)."""
        period = parse_period(rate, "log rate")
        group = f"every_{float(period):g}s"
        entries = self._log_groups.setdefault(group, {"period": period, "signals": [], "next": None})
        for name in signals:
            kind, sl, decl = self._locate(name)
            if any(s.name == name for s, _, _ in entries["signals"]):
                continue
            entries["signals"].append((LoggedSignal(name, tuple(decl.shape), format_unit(decl.unit),
                                                    decl.description), kind, sl))

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
        if self._normalizers:
            views = [(m, self._x_block[self.model_index[m.path]]) for m in self._normalizers]

            def normalize(y):
                for model, block in views:
                    model.normalize_state(y[block])
        options = dict(self.integrator_options)
        w_indices = [self._x_block[self.model_index[m.path]].start + k
                     for m in self._normalizers for k in getattr(m, "quaternion_w_indices", list)()]
        if w_indices and "error_exclude" not in options:
            # quaternion norms are fixed by normalize; their error along the quaternion is gauge, not error
            options["error_exclude"] = quaternion_gauge(np.asarray(w_indices, dtype=np.int64))
        # --- begin helper/stiff: exponential integrators get the stiff linear part of every model that has one
        method = INTEGRATORS.get(str(self.integrator_name).lower(), self.integrator_name)
        if getattr(method, "uses_linear_part", False) and "linear_part" not in options:
            parts = [(self._x_block[i], m) for i, m in enumerate(self.models) if hasattr(m, "stiff_linear_part")]

            def linear_part(t, y):
                """Block-diagonal union of the models' (local indices, L), offset to the full state."""
                pieces = [(block.start, *model.stiff_linear_part(y[block])) for block, model in parts]
                indices = [start + np.asarray(local, dtype=np.int64) for start, local, _ in pieces]
                m = sum(index.size for index in indices)
                L = np.zeros((m, m))
                k = 0
                for (_, _, block_L), index in zip(pieces, indices):
                    L[k:k + index.size, k:k + index.size] = block_L
                    k += index.size
                return (np.concatenate(indices) if indices else np.zeros(0, dtype=np.int64)), L
            options["linear_part"] = linear_part
        # --- end helper/stiff
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
            attrs = {"seed": json.dumps(self.seed)} | dict(log_attributes or {})
            writer = LogWriter(log_path, {g: [s for s, _, _ in e["signals"]] for g, e in self._log_groups.items()},
                               attrs)
        start_counters = dict(self.counters)
        t_start = self.t
        wall_start = _time.perf_counter()
        status, reason = "completed", "reached t_final"
        try:
            self._initialize()
            end = Fraction(t_final).limit_denominator(10**9)
            while True:
                instant = self._next_instant(end)
                target = float(instant)
                if target > self.t:
                    stopped = self._advance(target)
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
        except KeyboardInterrupt:
            if writer is not None:
                writer.close("interrupted", f"interrupted by the user at t = {self.t:.9g} s")
            raise
        except Exception as exc:
            message = str(exc) if isinstance(exc, SimulationError) else \
                f"{type(exc).__name__} at t = {self.t:.9g} s: {exc}"
            if writer is not None:
                writer.close("failed", message)
            if isinstance(exc, SimulationError):
                raise
            raise SimulationError(message) from exc
        if writer is not None:
            writer.close(status, reason)
        self.evaluate()  # outputs consistent with the final state for signal() queries
        wall = _time.perf_counter() - wall_start
        return RunSummary(status, reason, t_start, self.t, wall, self.counters["steps"] - start_counters["steps"],
                          self.counters["nfev"] - start_counters["nfev"],
                          self.counters["events"] - start_counters["events"],
                          self.counters["updates"] - start_counters["updates"])

    def _next_instant(self, end: Fraction) -> Fraction:
        candidates = [s for s in self._next_sample if s is not None]
        candidates += [self._next_log_time(g) for g in self._log_groups.values()]
        return min(candidates + [end])

    def _advance(self, target: float) -> str | None:
        """Integrate the continuous states from self.t to target; returns a stop reason or None."""
        if self.x.size == 0:
            return None
        integ = self._restart_integrator(target)
        have_events = bool(self._event_functions)
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
        sol = integ.dense_output()
        hits = locate_events(self._event_functions, sol, integ.t_old, integ.t, g_old, g_new, xtol=self.event_tol,
                             all_values=self._zero_crossing_vector)
        # a crossing just handled leaves its function at zero up to round-off, which may read as a new
        # sign change right after the restart: the same function within the tolerance is not a new event
        t_last, handled = self._last_events
        hits = [(t, j) for t, j in hits if not (j in handled and t - t_last <= 4 * self.event_tol)]
        if not hits:
            return None
        t_event = hits[0][0]
        y_event = np.array(sol(t_event), dtype=np.float64)
        if integ.normalize is not None:
            integ.normalize(y_event)
        self.t = t_event
        self.x[:] = y_event
        self.evaluate(t_event)
        stop = None
        self._last_events = (t_event, {j for t_hit, j in hits if t_hit == t_event})
        for t_hit, j in hits:
            if t_hit != t_event:
                break
            i, k, zc = self._zc_owner[j]
            model = self.models[i]
            try:
                model.on_event(k, t_event, self.x[self._x_block[i]], self.z[self._z_block[i]], model.p)
            except Exception as exc:
                raise SimulationError(f"model {model.path} failed handling event {zc.name} at t = {t_event:.12g} s: "
                                      f"{type(exc).__name__}: {exc}") from exc
            self.counters["events"] += 1
            self.events.append((t_event, f"{model.path}.{zc.name}"))
            if self._event_functions[j].terminal:
                stop = f"event {model.path}.{zc.name} at t = {t_event:.12g} s"
        self._check_finite_state(f"after the event at t = {t_event:.12g} s")
        self.evaluate(t_event)  # outputs reflect the state after the handlers
        if stop is not None:
            self._integrator_stale = True
            return stop
        self._integrator_stale = True
        self._restart_integrator(target)
        return None

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
        return [(key, sl, decl) for key, (kind, sl, decl) in self.state_slices.items() if kind == "x"]

    def _name_nonfinite(self, values, states, what="state") -> str | None:
        bad = []
        for (path, name), sl, _ in states:
            if not np.all(np.isfinite(values[sl])):
                bad.append(f"model {path} {what} {name} = {np.array2string(values[sl], precision=4)}")
        return "non-finite " + "; ".join(bad) if bad else None

    def _check_finite_state(self, when: str) -> None:
        for kind, values in (("x", self.x), ("z", self.z)):
            if not np.all(np.isfinite(values)):
                states = [(key, sl, decl) for key, (k, sl, decl) in self.state_slices.items() if k == kind]
                raise SimulationError(f"{self._name_nonfinite(values, states)} at {when}")

    def _discrete_updates(self, instant) -> None:
        due = [i for i in self._update_order if self._next_sample[i] == instant]
        if not due:
            return
        t = float(instant)
        for i in due:
            m = self.models[i]
            self.evaluate(t)
            try:
                if m.noise_size:
                    noise = self._noise[i]
                    m.rng.standard_normal(out=noise)
                    m.update(t, self.x[self._x_block[i]], self.z[self._z_block[i]], self.signals[self._u_block[i]],
                             m.p, noise)
                else:
                    m.update(t, self.x[self._x_block[i]], self.z[self._z_block[i]], self.signals[self._u_block[i]],
                             m.p)
            except Exception as exc:
                raise SimulationError(f"model {m.path} failed in its discrete update at t = {t:.9g} s: "
                                      f"{type(exc).__name__}: {exc}") from exc
            self._next_sample[i] += m.period
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
                self.evaluate(self.t)
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
            "next_sample": [None if s is None else (s.numerator, s.denominator) for s in self._next_sample],
            "next_log": {g: None if e["next"] is None else (e["next"].numerator, e["next"].denominator)
                         for g, e in self._log_groups.items()},
            "rng": {m.path: m.rng.bit_generator.state for m in self.models},
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
        self._next_sample = [None if s is None else Fraction(*s) for s in snapshot["next_sample"]]
        for g, value in snapshot["next_log"].items():
            if g in self._log_groups:
                self._log_groups[g]["next"] = None if value is None else Fraction(*value)
        for m in self.models:
            m.rng.bit_generator.state = snapshot["rng"][m.path]
        for i, m in enumerate(self.models):
            try:
                m.restored(self.t, self.x[self._x_block[i]], self.z[self._z_block[i]], m.p)
            except Exception as exc:
                raise SimulationError(f"model {m.path} failed re-applying its restored state at t = "
                                      f"{self.t:.9g} s: {type(exc).__name__}: {exc}") from exc
        self._integrator_stale = True
        self._initialized = True

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
