"""A scene's immutable evaluation plan (:class:`Diagram`) and the state of one run of it (:class:`Context`).

Drake's ``Diagram`` / ``Context`` split (docs/architecture.md) applied to flexshell's flat buffers:

* The **diagram** is built once from an assembly: the model tree is flattened
  (:func:`shell.assembly.flatten`); every output and input port gets a slice of one signal buffer, every
  continuous state a slice of ``x``, every discrete state a slice of ``z``, every parameter a slice of one
  packed parameter vector; each connection becomes element index pairs with the unit conversion factor of
  its two ports (``deg/s -> rad/s`` = pi/180), after dimensions and shapes are checked. Outputs are
  ordered by a topological sort (shell.graphs) of the direct-feedthrough graph, whose nodes are each model's
  *state-output* and *feedthrough-output* stages; a cycle is an algebraic loop and is refused with the
  models and ports on it. Sampled models are ordered upstream first. Nothing in a diagram changes after
  it is built.
* A **context** holds everything one run changes: time, ``x``, ``z``, the signal buffer, the packed
  parameters, each model's own data (the engine's arrays and workspace), each model's random stream, and
  the sample schedule. One diagram serves many contexts: Monte Carlo runs, linearization columns,
  saved and restored states.

The diagram's public methods evaluate a context: :meth:`Diagram.evaluate` (every output and input),
:meth:`Diagram.derivatives` (the integrator's right-hand side: only the output stages the derivatives
need, then every derivative kernel), :meth:`Diagram.zero_crossings`, :meth:`Diagram.update` (one sampled
model), and :meth:`Diagram.opened` (the same plan with some inputs cut from their drivers, for
linearization). This interpreted path calls each model kernel from Python (:class:`InterpretedPlan` offers it with
the methods of the compiled plan); :mod:`shell.compiled_loop` runs the same sequence compiled and must give the
same numbers.

Kernel signatures (:mod:`shell.model`, :mod:`shell.kernel_protocol`): ``kernel(t, x, z, u, p, out)``; a model with
per-run data (``Model.uses_data``) receives it after ``p``: ``kernel(t, x, z, u, p, d, out)`` (its data slot, one
float64 array of the context's ``flat_data``, or its typed data).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from fractions import Fraction

import numpy as np
from numba import njit

from shell.assembly import Assembly, Connection, flatten
from shell.graphs import CycleError, Digraph, condensation_order, find_cycle, topological_order
from shell.model import ModelError
from shell.names import NameIndex
from shell.units import UnitError, conversion_factor, format_unit, to_magnitude


class WiringError(ModelError):
    """A connection or port configuration refused at build time."""


class AlgebraicLoopError(WiringError):
    """Direct-feedthrough outputs depend on themselves; the message names the models and ports."""


class EvaluationError(RuntimeError):
    """A model kernel failed; the message names the model, the stage and the time."""


@njit(cache=True)
def gather_inputs(signals, source, destination, factor, start, stop):
    """signals[destination[k]] = factor[k] * signals[source[k]] for k in [start, stop)."""
    for k in range(start, stop):
        signals[destination[k]] = factor[k] * signals[source[k]]


def stage_kernel(model, kind: str, for_derivatives: bool = False):
    """The kernel of ``model``'s output stage ``kind`` ("state" or "feedthrough"); ``for_derivatives``: in a
    derivative evaluation (its ``*_outputs_for_derivatives`` kernel when it has one, :mod:`shell.model`)."""
    if for_derivatives:
        fn = model.state_outputs_for_derivatives if kind == "state" else model.feedthrough_outputs_for_derivatives
        if fn is not None:
            return fn
    return model.state_outputs if kind == "state" else model.feedthrough_outputs


@dataclass(frozen=True)
class Stage:
    """One output stage of the evaluation order: model ``model`` computes its ``kind`` outputs
    ("state" or "feedthrough") after gathering its feedthrough inputs ``gather`` (a range of the
    diagram's gather arrays; empty for state stages)."""

    model: int
    kind: str
    gather: tuple[int, int]


class Diagram:
    """The immutable plan of a scene; see the module docstring."""

    def __init__(self, root: Assembly, *, stop_events=()):
        self.root = root
        self.models, self.connections = flatten(root)
        if not self.models:
            raise WiringError("the scene has no models")
        self.model_index = {m.path: i for i, m in enumerate(self.models)}
        self._layout()
        self._wire()
        self._order_outputs()
        for c, in_derivatives in zip(self.connections, self.read_in_derivatives()):
            # a model computing only what is read learns what its connections read, and which derivatives read
            c.source_model.output_read(c.source_port, in_derivatives=in_derivatives)
        self._order_updates()
        self._collect_zero_crossings(stop_events)
        self.normalizers = tuple(i for i, m in enumerate(self.models) if hasattr(m, "normalize_state"))
        self.sampled = tuple(i for i, m in enumerate(self.models) if m.period is not None)
        self.periods = tuple(m.period for m in self.models)
        self.offsets = tuple(m.offset for m in self.models)
        #: initial continuous and discrete states of the models (their declared or overridden values)
        self.initial_x = _frozen(np.concatenate([m.initial_continuous_state() for m in self.models]))
        self.initial_z = _frozen(np.concatenate([m.initial_discrete_state() for m in self.models]))
        #: every parameter, state, sample schedule and model value by dotted name (:mod:`shell.names`)
        self.names = NameIndex(self)

    # ------------------------------------------------------------------------------------------------
    # build
    def _layout(self) -> None:
        n_signals = n_x = n_z = n_p = 0
        self.port_slices: dict[tuple[str, str], slice] = {}
        self.port_info: dict[tuple[str, str], object] = {}
        y_block, u_block, x_block, z_block, p_block = [], [], [], [], []
        for m in self.models:
            y_block.append(slice(n_signals, n_signals + m.y_layout.size))
            for port in m.outputs:
                self.port_slices[(m.path, port.name)] = slice(n_signals, n_signals + port.size)
                self.port_info[(m.path, port.name)] = port
                n_signals += port.size
            u_block.append(slice(n_signals, n_signals + m.u_layout.size))
            for port in m.inputs:
                self.port_slices[(m.path, port.name)] = slice(n_signals, n_signals + port.size)
                self.port_info[(m.path, port.name)] = port
                n_signals += port.size
            x_block.append(slice(n_x, n_x + m.x_layout.size))
            n_x += m.x_layout.size
            z_block.append(slice(n_z, n_z + m.z_layout.size))
            n_z += m.z_layout.size
            p_block.append(slice(n_p, n_p + m.p.size))
            n_p += m.p.size
        self.y_block, self.u_block = tuple(y_block), tuple(u_block)
        self.x_block, self.z_block, self.p_block = tuple(x_block), tuple(z_block), tuple(p_block)
        self.n_signals, self.n_x, self.n_z, self.n_p = n_signals, n_x, n_z, n_p
        self.state_slices: dict[tuple[str, str], tuple[str, slice, object]] = {}
        for i, m in enumerate(self.models):
            for kind, decls, block in (("x", m.continuous_states, x_block[i]), ("z", m.discrete_states, z_block[i])):
                layout = m.x_layout if kind == "x" else m.z_layout
                for s in decls:
                    sl = layout.slice(s.name)
                    self.state_slices[(m.path, s.name)] = (kind, slice(block.start + sl.start, block.start + sl.stop), s)

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
        missing, defaults = [], []
        for m in self.models:
            for port in m.inputs:
                if (m.path, port.name) in driver:
                    continue
                if port.required:
                    missing.append(f"{m.path}.{port.name} ({format_unit(port.unit)}, shape {port.shape}"
                                   f"{': ' + port.description if port.description else ''})")
                else:
                    default = port.default if port.default is not None else np.zeros(port.shape)
                    value = to_magnitude(default, port.unit, port.shape, f"input {m.path}.{port.name} default")
                    defaults.append((self.port_slices[(m.path, port.name)], value.reshape(-1)))
        if missing:
            raise WiringError("unconnected required input(s): " + "; ".join(missing))
        self.driver = driver
        self.input_defaults = tuple(defaults)
        # sorted by destination model, feedthrough inputs first: each model's feedthrough inputs are one
        # contiguous range gathered just before its feedthrough outputs are computed
        as_int = lambda values: np.asarray(values, dtype=np.int64)  # noqa: E731
        order = np.lexsort((as_int(dst_ft), as_int(dst_model))) if sources else np.zeros(0, dtype=np.int64)
        self.gather_source = _frozen(as_int(sources)[order])
        self.gather_destination = _frozen(as_int(destinations)[order])
        self.gather_factor = _frozen(np.asarray(factors, dtype=np.float64)[order])
        dst_model_sorted, dst_ft_sorted = as_int(dst_model)[order], as_int(dst_ft)[order]
        ft_range = []
        for i in range(len(self.models)):
            ks = np.flatnonzero((dst_model_sorted == i) & (dst_ft_sorted == 0))
            ft_range.append((int(ks[0]), int(ks[-1]) + 1) if ks.size else (0, 0))
        self.feedthrough_gather = tuple(ft_range)
        self.n_gather = int(self.gather_source.size)

    def _order_outputs(self) -> None:
        graph = Digraph()
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
            order = topological_order(graph.successors, key=lambda n: stage_rank[n])
        except CycleError:
            cycle = find_cycle(graph.successors)
            models = []
            for a, _ in cycle:
                if a[0] not in models:
                    models.append(a[0])
            ports = "; ".join(port_labels[(a, b)] for a, b in cycle)
            raise AlgebraicLoopError(
                f"algebraic loop through models {' -> '.join(models)} -> {models[0]}: each output feeds "
                f"through to the next without a state in between ({ports}). Break it with a state "
                f"(a filter, a sampled model) or remove a direct feedthrough.") from None
        self.output_order = tuple(self._stage(self.model_index[path], kind) for path, kind in order)
        self.derivative_models = []
        for i, m in enumerate(self.models):
            if m.x_layout.size:
                if m.derivatives is None:
                    raise ModelError(f"model {m.path}: has continuous states but no derivatives kernel")
                self.derivative_models.append(i)
        self.derivative_models = tuple(self.derivative_models)
        self.derivative_stages = self.stages_for(self.stages_needed_by_derivatives())
        feeding = self.feeding_stages()
        #: per model: the output stages its inputs need (an update evaluates only these; other outputs
        #: may be stale in the buffer until the next evaluation that needs them); none for an update that reads
        #: no input (Model.update_reads_inputs)
        self.input_stages = tuple(self.stages_for(self.stages_closure(
            [stage for stage, _ in feeding.get(m.path, [])] if m.update_reads_inputs else [], feeding))
            for m in self.models)
        zc_paths = [m.path for m in self.models if m.zero_crossings]
        #: the output stages the zero-crossing functions need
        self.zero_crossing_stages = self.stages_for(self.stages_closure(
            [stage for path in zc_paths for stage, _ in feeding.get(path, [])], feeding))

    def _stage(self, i: int, kind: str) -> Stage:
        return Stage(i, kind, self.feedthrough_gather[i] if kind == "feedthrough" else (0, 0))

    def _order_updates(self) -> None:
        graph = Digraph()
        for i in range(len(self.models)):
            graph.add_node(i)
        for c in self.connections:
            graph.add_edge(self.model_index[c.source_model.path], self.model_index[c.destination_model.path])
        rank = {}
        for position, members in enumerate(condensation_order(graph.successors, min)):
            for member in members:
                rank[member] = (position, member)
        #: sampled models in the order they update at a shared instant (upstream first, ties by declaration)
        self.update_order = tuple(sorted((i for i, m in enumerate(self.models) if m.period is not None),
                                         key=lambda i: rank[i]))

    def _collect_zero_crossings(self, stop_events) -> None:
        zc_models, owner, declared, n = [], [], {}, 0
        for i, m in enumerate(self.models):
            if not m.zero_crossings:
                continue
            zc_models.append((i, slice(n, n + len(m.zero_crossings))))
            for k, zc in enumerate(m.zero_crossings):
                owner.append((i, k, zc))
                declared[f"{m.path}.{zc.name}"] = n + k
            n += len(m.zero_crossings)
        terminal = [zc.terminal for _, _, zc in owner]
        for name in stop_events:
            if name not in declared:
                raise ModelError(f"stop event {name!r}: no such zero crossing; declared: {sorted(declared) or 'none'}")
            terminal[declared[name]] = True
        if n and self.n_x == 0:
            raise ModelError(f"zero crossings {sorted(declared)} need continuous states to be located on; "
                             "the scene has none")
        #: (model index, slice of the zero-crossing vector) per model with zero crossings
        self.zero_crossing_models = tuple(zc_models)
        #: (model index, index within the model, ZeroCrossing) per zero-crossing function
        self.zero_crossing_owner = tuple(owner)
        self.zero_crossing_terminal = tuple(terminal)
        self.zero_crossing_names = tuple(f"{self.models[i].path}.{zc.name}" for i, _, zc in owner)
        self.n_zero_crossings = n

    # ------------------------------------------------------------------------------------------------
    # dependency queries
    def feeding_stages(self) -> dict[str, list]:
        """{model path: [((source path, "feedthrough" | "state"), input is feedthrough), ...]}."""
        feeding: dict[str, list] = {}
        for c in self.connections:
            out_port = self.port_info[(c.source_model.path, c.source_port)]
            in_port = self.port_info[(c.destination_model.path, c.destination_port)]
            stage = (c.source_model.path, "feedthrough" if out_port.feedthrough else "state")
            feeding.setdefault(c.destination_model.path, []).append((stage, in_port.feedthrough))
        return feeding

    def stages_closure(self, stages, feeding: dict[str, list] | None = None) -> set:
        """``stages`` ((model path, kind) pairs) and every output stage they need: a feedthrough stage
        needs the stages feeding its feedthrough inputs, recursively."""
        feeding = self.feeding_stages() if feeding is None else feeding
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

    def stages_needed_by_derivatives(self) -> set:
        """Output stages a derivative evaluation must run: those feeding, directly or through
        feedthrough stages, an input of a model with continuous states or zero crossings. Inputs of
        purely sampled models are read only at their sample instants (full evaluation there)."""
        feeding = self.feeding_stages()
        return self.stages_closure([stage for m in self.models if m.x_layout.size or m.zero_crossings
                                    for stage, _ in feeding.get(m.path, [])], feeding)

    def read_in_derivatives(self) -> tuple[bool, ...]:
        """Per connection: a derivative evaluation reads its destination input: the destination has continuous
        states or zero crossings (its derivatives read every input), or the input is a feedthrough input of a model
        whose feedthrough stage the derivatives need (:meth:`stages_needed_by_derivatives`)."""
        needed = self.stages_needed_by_derivatives()
        read = []
        for c in self.connections:
            m = c.destination_model
            port = self.port_info[(m.path, c.destination_port)]
            read.append(bool(m.x_layout.size or m.zero_crossings
                             or (port.feedthrough and (m.path, "feedthrough") in needed)))
        return tuple(read)

    def stages_for(self, needed: set) -> tuple[Stage, ...]:
        """The stages of ``needed`` ((model path, kind) pairs) in evaluation order."""
        return tuple(s for s in self.output_order if (self.models[s.model].path, s.kind) in needed)

    def feedthrough_precedes_derivatives(self, stages) -> tuple[bool, ...]:
        """Per model: its feedthrough stage is among ``stages``, so its derivative may reuse what that
        stage computed at the same state and inputs (``Model.derivatives_after_feedthrough``)."""
        ran = {s.model for s in stages if s.kind == "feedthrough"}
        return tuple(i in ran and self.models[i].derivatives_after_feedthrough is not None
                     for i in range(len(self.models)))

    # ------------------------------------------------------------------------------------------------
    # names
    def locate(self, name: str):
        """(kind, slice, declaration) of a port ("signal") or state ("x", "z") by dotted name."""
        model_path, _, leaf = self.split_name(name)
        key = (model_path, leaf)
        if key in self.port_slices:
            self.note_read(name)
            return "signal", self.port_slices[key], self.port_info[key]
        if key in self.state_slices:
            return self.state_slices[key]
        model = self.models[self.model_index[model_path]]
        names = [p.name for p in model.outputs + model.inputs] + [s.name for s in model.continuous_states
                                                                  + model.discrete_states]
        raise ModelError(f"signal {name!r}: model {model_path} has no port or state {leaf!r}"
                         f"{model.missing_port_hint(leaf)}; it has {names}")

    def note_read(self, name: str) -> bool:
        """Tell the model of output port ``name`` that it is read (:meth:`shell.model.Model.output_read`): True when
        the model did not compute it until now (its buffer value is stale until the next evaluation)."""
        model_path, _, leaf = self.split_name(name)
        if not any(p.name == leaf for p in self.models[self.model_index[model_path]].outputs):
            return False
        return bool(self.models[self.model_index[model_path]].output_read(leaf))

    def split_name(self, name: str):
        """(model path, ".", leaf) of a dotted port or state name; the longest model path wins."""
        parts = name.split(".")
        for cut in range(len(parts) - 1, 0, -1):
            path = ".".join(parts[:cut])
            if path in self.model_index:
                return path, ".", ".".join(parts[cut:])
        raise ModelError(f"signal {name!r}: no model path is a prefix of it; models: {sorted(self.model_index)}")

    def state_entries(self, kind: str = "x"):
        """[((model path, state name), slice, declaration)] of every continuous ("x") or discrete ("z") state."""
        return [(key, sl, decl) for key, (k, sl, decl) in self.state_slices.items() if k == kind]

    # ------------------------------------------------------------------------------------------------
    # contexts
    def create_context(self, seed=0, t_start: float = 0.0, *, own_data: bool = False) -> "Context":
        """A fresh run: initial states and parameters of the models, their random streams seeded from
        ``seed``, the sample schedule from ``t_start``. ``own_data``: give each model with per-run data
        a private copy (Monte Carlo contexts); otherwise the first context shares the models' own data."""
        return Context(self, seed, t_start, own_data)

    def opened(self, destination_elements) -> "OpenedDiagram":
        """This plan with the signal elements ``destination_elements`` (indices into the signal buffer, of
        connected inputs) cut from their drivers: each keeps whatever value the caller writes there. The
        plan used to linearize from a connected input (the plant seen from that input)."""
        return OpenedDiagram(self, destination_elements)

    # ------------------------------------------------------------------------------------------------
    # interpreted evaluation (the reference for shell.compiled_loop)
    def evaluate(self, context: "Context", t: float | None = None, stages=None) -> None:
        """Compute every output (or those of ``stages``) and then every input at ``context``'s state."""
        t = context.t if t is None else t
        self._run_stages(context, t, self.output_order if stages is None else stages)
        gather_inputs(context.signals, self.gather_source, self.gather_destination, self.gather_factor, 0,
                      self.n_gather)

    def derivatives(self, context: "Context", t: float, x: np.ndarray) -> np.ndarray:
        """f(t, x): the integrator's right-hand side (continuous states of every model), a new array. Its output
        stages are a derivative evaluation's (models' ``*_outputs_for_derivatives`` kernels: outputs that only samples,
        logs and names read may be NaN after it)."""
        context.x[:] = x
        self._derivatives(context, t, self.derivative_stages, self.gather_source, self.gather_factor,
                          for_derivatives=True)
        return context.xdot.copy()

    def _derivatives(self, context, t, stages, source, factor, for_derivatives=False) -> None:
        self._run_stages(context, t, stages, source, factor, for_derivatives)
        gather_inputs(context.signals, source, self.gather_destination, factor, 0, self.n_gather)
        reuse = context.reuse_for(stages)
        i = -1
        try:
            for i in self.derivative_models:
                v = context.views[i]
                fn = v.model.derivatives_after_feedthrough if reuse[i] else v.model.derivatives
                if v.data is None:
                    fn(t, v.x, v.z, v.u, v.p, v.xdot)
                else:
                    fn(t, v.x, v.z, v.u, v.p, v.data, v.xdot)
        except Exception as exc:
            raise EvaluationError(f"model {self.models[i].path} failed computing derivatives at t = {t:.9g} s: "
                                  f"{type(exc).__name__}: {exc}") from exc

    def _run_stages(self, context, t, stages, source=None, factor=None, for_derivatives=False) -> None:
        source = self.gather_source if source is None else source
        factor = self.gather_factor if factor is None else factor
        signals, destination = context.signals, self.gather_destination
        stage = None
        try:
            for stage in stages:
                k0, k1 = stage.gather
                if k1 > k0:
                    gather_inputs(signals, source, destination, factor, k0, k1)
                v = context.views[stage.model]
                fn = stage_kernel(v.model, stage.kind, for_derivatives)
                if v.data is None:
                    fn(t, v.x, v.z, v.u, v.p, v.y)
                else:
                    fn(t, v.x, v.z, v.u, v.p, v.data, v.y)
        except Exception as exc:
            raise EvaluationError(f"model {self.models[stage.model].path} failed computing outputs at t = "
                                  f"{t:.9g} s: {type(exc).__name__}: {exc}") from exc

    def zero_crossings(self, context: "Context", t: float, x: np.ndarray) -> np.ndarray:
        """Every zero-crossing function at (t, x) after a full evaluation, a new array."""
        context.x[:] = x
        self.evaluate(context, t, self.zero_crossing_stages)
        g = context.g
        for i, sl in self.zero_crossing_models:
            v = context.views[i]
            if v.data is None:
                v.model.zero_crossing_values(t, v.x, v.z, v.u, v.p, g[sl])
            else:
                v.model.zero_crossing_values(t, v.x, v.z, v.u, v.p, v.data, g[sl])
        return g.copy()

    def stages_of_signals(self, names) -> tuple:
        """The output stages that the ports and states ``names`` need, in evaluation order (a log's)."""
        feeding, pending = self.feeding_stages(), []
        for name in names:
            kind, sl, decl = self.locate(name)
            if kind != "signal":
                continue
            path, _, leaf = self.split_name(name)
            key = (path, leaf)
            if key in self.driver:  # an input: its driver's stage
                c = self.driver[key]
                port = self.port_info[(c.source_model.path, c.source_port)]
                pending.append((c.source_model.path, "feedthrough" if port.feedthrough else "state"))
            elif any(p.name == leaf for p in self.models[self.model_index[path]].outputs):
                pending.append((path, "feedthrough" if decl.feedthrough else "state"))
        return self.stages_for(self.stages_closure(pending, feeding))

    def update(self, context: "Context", i: int, t: float) -> None:
        """Evaluate the outputs model ``i``'s inputs need at ``t``, then run its discrete update (drawing its
        noise first)."""
        self.evaluate(context, t, self.input_stages[i])
        v = context.views[i]
        m = v.model
        try:
            args = (t, v.x, v.z, v.u, v.p) + (() if v.data is None else (v.data,))
            if m.noise_size:
                noise = context.noise[i]
                context.rngs[i].standard_normal(out=noise)
                m.update(*args, noise)
            else:
                m.update(*args)
        except Exception as exc:
            raise EvaluationError(f"model {m.path} failed in its discrete update at t = {t:.9g} s: "
                                  f"{type(exc).__name__}: {exc}") from exc

    def normalize(self, context: "Context", y: np.ndarray) -> None:
        """Renormalize the hinge quaternions of state vector ``y`` in place (the integrator's hook)."""
        for i in self.normalizers:
            v = context.views[i]
            v.model.normalize_state(y[self.x_block[i]], v.data)

    def quaternion_w_indices(self) -> np.ndarray:
        """Positions in the state vector of each hinge quaternion's w (for the integrators' error norm)."""
        return np.asarray([self.x_block[i].start + k for i in self.normalizers
                           for k in self.models[i].quaternion_w_indices()], dtype=np.int64)

    @staticmethod
    def first_sample(period: Fraction | None, offset: Fraction, t_start: float) -> Fraction | None:
        """The first sample instant ``offset + k period`` at or after ``t_start`` (exact), None if continuous."""
        if period is None:
            return None
        first = offset
        start = Fraction(t_start).limit_denominator(10**9)
        if first < start:
            first += math.ceil((start - first) / period) * period
        return first

    def describe(self) -> str:
        n_models = len(self.models)
        return (f"diagram: {n_models} models, {self.n_x} continuous and {self.n_z} discrete states, "
                f"{self.n_signals} signal elements, {len(self.output_order)} output stages "
                f"({len(self.derivative_stages)} per derivative), {len(self.update_order)} sampled models, "
                f"{self.n_zero_crossings} zero crossings")


class OpenedDiagram:
    """A diagram whose gather skips some destination elements (see :meth:`Diagram.opened`): same
    evaluation API for the methods linearization needs."""

    def __init__(self, diagram: Diagram, destination_elements):
        self.diagram = diagram
        positions = np.asarray(list(destination_elements), dtype=np.int64)
        hits = np.flatnonzero(np.isin(diagram.gather_destination, positions))
        source = diagram.gather_source.copy()
        factor = diagram.gather_factor.copy()
        source[hits] = diagram.gather_destination[hits]  # the element copies itself: its value is kept
        factor[hits] = 1.0
        self.gather_source, self.gather_factor = _frozen(source), _frozen(factor)

    def evaluate(self, context: "Context", t: float, stages=None) -> None:
        d = self.diagram
        d._run_stages(context, t, d.output_order if stages is None else stages, self.gather_source,
                      self.gather_factor)
        gather_inputs(context.signals, self.gather_source, d.gather_destination, self.gather_factor, 0, d.n_gather)


class InterpretedPlan:
    """The evaluation of ``diagram`` at ``context`` with every kernel called from Python: the reference that the
    compiled plan (:class:`shell.compiled_plan.CompiledPlan`, the same methods) must equal, and what runs a scene
    whose kernels are not all numba functions. A failing kernel raises :class:`EvaluationError` naming the model,
    the stage and the time."""

    mode = "interpreted"
    #: the sampled models whose update is Python (here: every one; the compiled plan lists its Python-only ones)
    python_updates = ()

    def __init__(self, diagram: Diagram, context: "Context"):
        self.diagram, self.context = diagram, context

    def derivative(self, t: float, y: np.ndarray) -> np.ndarray:
        """f(t, y), a new array (the integrators' right-hand side)."""
        return self.diagram.derivatives(self.context, t, y)

    def evaluate(self, t: float, stages=None) -> None:
        """Every output (or those of ``stages``), then every input, at the context's state."""
        self.diagram.evaluate(self.context, t, stages)

    def zero_crossings(self, t: float, y: np.ndarray) -> np.ndarray:
        return self.diagram.zero_crossings(self.context, t, y)

    def update(self, t: float, i: int) -> None:
        """Sampled model ``i``'s update (its inputs' stages first, its noise drawn)."""
        self.diagram.update(self.context, i, t)

    def normalize(self, y: np.ndarray) -> None:
        self.diagram.normalize(self.context, y)

    def derivatives_into(self, t: float, stages, source=None, factor=None) -> None:
        """Derivatives at the context's ``x`` into its ``xdot``, running only the output ``stages`` first, with the
        gather arrays ``source``/``factor`` (an opened diagram's, for linearization and trim)."""
        d = self.diagram
        d._derivatives(self.context, t, stages, d.gather_source if source is None else source,
                       d.gather_factor if factor is None else factor)


@dataclass
class ModelViews:
    """A model's views into a context's buffers, and its per-run data (None for most models)."""

    model: object
    x: np.ndarray
    z: np.ndarray
    u: np.ndarray
    p: np.ndarray
    y: np.ndarray
    xdot: np.ndarray
    data: object


class Context:
    """The state of one run of a diagram; see the module docstring. Build with
    :meth:`Diagram.create_context`."""

    def __init__(self, diagram: Diagram, seed, t_start: float, own_data: bool):
        self.diagram = diagram
        self.seed = seed
        self.t = float(t_start)
        self.signals = np.zeros(diagram.n_signals)
        self.x = np.zeros(diagram.n_x)
        self.xdot = np.zeros(diagram.n_x)
        self.z = np.zeros(diagram.n_z)
        self.g = np.zeros(diagram.n_zero_crossings)
        self.p = np.concatenate([m.p for m in diagram.models]) if diagram.n_p else np.zeros(0)
        for sl, value in diagram.input_defaults:
            self.signals[sl] = value
        models = diagram.models
        self.x[:] = diagram.initial_x
        self.z[:] = diagram.initial_z
        #: per model: (host, data) of models with per-run data: ``data`` what its kernels receive after ``p`` (one
        #: float64 array, the model's *data slot*, or a typed tuple served by its op kernel), ``host`` the Python
        #: object owning those arrays (the engine's MultibodySystem), else None
        self.hosts, self.data = [], []
        #: the data slots of every model that has one, side by side (``data[i]`` is a view), and each one's slice
        self.flat_slices: list = []
        slots, n_flat = [], 0
        for m in models:
            host, data = m.create_data(own=own_data) if m.uses_data else (None, None)
            self.hosts.append(host)
            self.data.append(data)
            if isinstance(data, np.ndarray) and data.ndim == 1 and data.dtype == np.float64:
                self.flat_slices.append(slice(n_flat, n_flat + data.size))
                slots.append(data)
                n_flat += data.size
            else:
                self.flat_slices.append(None)
        self.flat_data = np.concatenate(slots) if slots else np.zeros(0)
        for i, sl in enumerate(self.flat_slices):
            if sl is not None:
                self.data[i] = self.flat_data[sl]
        self.rngs = [m.random_stream(seed) for m in models]
        self.noise = {i: np.zeros(int(m.noise_size)) for i, m in enumerate(models) if m.noise_size}
        self.views = [ModelViews(m, self.x[diagram.x_block[i]], self.z[diagram.z_block[i]],
                                 self.signals[diagram.u_block[i]], self.p[diagram.p_block[i]],
                                 self.signals[diagram.y_block[i]], self.xdot[diagram.x_block[i]], self.data[i])
                      for i, m in enumerate(models)]
        #: sample period and offset of each model in this run (a Monte Carlo run may disperse a rate)
        self.periods = list(diagram.periods)
        self.offsets = list(diagram.offsets)
        self.next_sample = [diagram.first_sample(self.periods[i], self.offsets[i], self.t) for i in range(len(models))]
        #: no run has advanced this context yet: initial values and changes that build a model again may be given
        self.unstarted = True
        self._reuse_cache: dict = {}

    def set(self, name: str, value) -> None:
        """Give parameter, state, sample rate or model value ``name`` the value ``value`` (a number or array in the
        declared unit, a string with a unit, ``{value, unit}``): :meth:`shell.names.NameIndex.assign`."""
        self.diagram.names.assign(self, [(name, value)])

    def assign(self, items) -> None:
        """Several (name, value) pairs at once (one construction per model whose configuration they change)."""
        self.diagram.names.assign(self, items)

    def get(self, name: str):
        """The current value of ``name`` in its declared unit (a copy)."""
        return self.diagram.names.value(self, name)

    def reuse_for(self, stages) -> tuple[bool, ...]:
        key = id(stages)
        hit = self._reuse_cache.get(key)
        if hit is None or hit[0] is not stages:
            hit = self._reuse_cache[key] = (stages, self.diagram.feedthrough_precedes_derivatives(stages))
        return hit[1]

    def model_views(self, path: str) -> ModelViews:
        return self.views[self.diagram.model_index[path]]


def _frozen(a: np.ndarray) -> np.ndarray:
    a = np.ascontiguousarray(a)
    a.setflags(write=False)
    return a
