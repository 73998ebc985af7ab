"""The diagram's plan in the form :mod:`shell.compiled_loop` runs: op tables and kernel pointers.

:func:`compile_plan` checks that a scene can run compiled and says why not; :class:`CompiledPlan` binds a
:class:`shell.diagram.Diagram` and one :class:`shell.diagram.Context` (its buffers are the context's own
arrays, so the compiled and the interpreted path see and change the same state) and offers the compiled
evaluation to Python callers with the methods of :class:`shell.diagram.InterpretedPlan` (``derivative`` for
adaptive and implicit integrators, ``evaluate``, ``zero_crossings``, ``update``, ``normalize``,
``derivatives_into``).

What runs compiled (:mod:`shell.kernel_protocol`): every model kernel that is a numba function of the uniform
signature ``kernel(t, x, z, u, p, out)`` (update: ``update(t, x, z, u, p)``, or ``update(t, x, z, u, p, noise)``
with ``noise_size``), with the model's data slot after ``p`` when its per-run data is one float64 array, and the
op kernel of a model whose per-run data is a typed tuple (``compiled_kernel``: the multibody engine; its data by
reference). Any number of noisy models (their random streams by reference too), of models with data slots, and of
op-kernel models (with data of any types: the loop does not see them). A model whose output, derivative or zero-crossing kernel is plain Python makes the
whole scene run interpreted (the message names it). A sampled model whose update is plain Python
(``UserFunction``, the thruster cluster's minimum-fuel allocation, ``MassDepletion``) keeps the loop compiled: it
returns to Python at that model's sample instants.
"""

from __future__ import annotations

import numpy as np
from numba import typeof
from numba.core.registry import CPUDispatcher
from numba.experimental.function_type import _get_jit_address, _get_wrapper_address

from shell import compiled_loop as L
from shell import kernel_protocol as KP
from shell.diagram import stage_kernel


class NotCompilable(Exception):
    """The scene cannot run in the compiled loop; the message says which model and why."""


def _pointer(fn, signature, model, what):
    """[cfunc wrapper address, numba entry address] of ``fn`` compiled for ``signature``."""
    if not isinstance(fn, CPUDispatcher):
        raise NotCompilable(f"model {model.path} ({type(model).__name__}): its {what} kernel is Python, not a "
                            "numba function")
    try:
        fn.compile(signature)
        return [_get_wrapper_address(fn, signature), _get_jit_address(fn, signature)]
    except Exception as exc:  # a kernel that does not fit the uniform signature
        raise NotCompilable(f"model {model.path} ({type(model).__name__}): its {what} kernel does not compile for "
                            f"the signature {signature}: {type(exc).__name__}: {str(exc).splitlines()[0][:200]}") from None


_OP_CODES = {("state", False): KP.STATE_OUTPUTS, ("feedthrough", False): KP.FEEDTHROUGH_OUTPUTS,
             ("state", True): KP.STATE_OUTPUTS_FOR_DERIVATIVES,
             ("feedthrough", True): KP.FEEDTHROUGH_OUTPUTS_FOR_DERIVATIVES}


def _op(kind, fn, gather, x, z, u, p, out, noise=(0, 0), rng=0, data=(0, 0), opcode=0):
    return [kind, fn, gather[0], gather[1], x.start, x.stop, z.start, z.stop, u.start, u.stop, p.start, p.stop,
            out.start, out.stop, noise[0], noise[1], rng, data[0], data[1], opcode]


def _table(rows):
    return np.asarray(rows, dtype=np.int64).reshape(-1, L.OP_COLUMNS)


class _Kinds:
    """How each model's kernels are called, and the function-pointer tables (built once per diagram)."""

    def __init__(self, diagram, context):
        self.diagram = diagram
        self.tables = {"fns": [], "data_fns": [], "update_fns": [], "op_fns": []}
        self._index: dict = {}
        #: per model: "plain", "data" (a float64 data slot) or "op" (op kernel, typed data by reference)
        self.kind = []
        #: per model with an op kernel: the numba type of its data, and the range of its reference in the loop's
        #: references (Buffers.R)
        self.data_type, self.reference_range = {}, {}
        n_words = 0
        for i, m in enumerate(diagram.models):
            if not m.uses_data:
                self.kind.append("plain")
            elif getattr(m, "compiled_kernel", None) is not None:
                data_type = self.data_type[i] = typeof(context.data[i])
                words = KP.reference_words(data_type)
                self.reference_range[i] = (n_words, n_words + words)
                n_words += words
                self.kind.append("op")
            elif context.flat_slices[i] is not None:
                self.kind.append("data")
            else:
                raise NotCompilable(f"model {m.path} ({type(m).__name__}) keeps per-run data that is neither one "
                                    "float64 array (a data slot) nor served by an op kernel (compiled_kernel)")
        #: int64 words of the op-kernel models' references: the noisy models' generators' follow in Buffers.R
        self.n_words = n_words

    def pointer(self, table, fn, signature, model, what) -> int:
        key = (table, id(fn), str(signature))
        if key not in self._index:
            self.tables[table].append(_pointer(fn, signature, model, what))
            self._index[key] = len(self.tables[table]) - 1
        return self._index[key]

    def kernels(self) -> L.Kernels:
        return L.Kernels(*(np.asarray(self.tables[name], dtype=np.int64).reshape(-1, 2)
                           for name in ("fns", "data_fns", "update_fns", "op_fns")))


class _Tables:
    """What the compiled form of a diagram needs that does not depend on the run: op tables, kernel
    pointers, which models keep data, which draw noise (built once per diagram, from its first context)."""

    def __init__(self, diagram, context):
        models = diagram.models
        kinds = self.kinds = _Kinds(diagram, context)
        self.python_updates, self.noisy = [], []
        self.flat_slices = tuple(context.flat_slices)

        def call(i, fn, what, gather, out, opcode):
            """The op row calling model ``i``'s ``fn`` (or its op kernel with ``opcode``) into ``out``."""
            m = models[i]
            block = (diagram.x_block[i], diagram.z_block[i], diagram.u_block[i], diagram.p_block[i], out)
            kind = kinds.kind[i]
            if kind == "op":
                f = kinds.pointer("op_fns", KP.by_reference(m.compiled_kernel, kinds.data_type[i]),
                                  KP.REFERENCE_KERNEL_SIGNATURE, m, "op")
                return _op(L.OP, f, gather, *block, data=kinds.reference_range[i], opcode=opcode)
            if kind == "data":
                f = kinds.pointer("data_fns", fn, KP.DATA_KERNEL_SIGNATURE, m, what)
                return _op(L.DATA, f, gather, *block, data=_range(self.flat_slices[i]))
            return _op(L.PLAIN, kinds.pointer("fns", fn, KP.KERNEL_SIGNATURE, m, what), gather, *block)

        def stage_op(stage, for_derivatives=False):
            """The row of an output stage; ``for_derivatives``: within the integrator's derivative evaluation (the
            model's kernel for it, :func:`shell.diagram.stage_kernel`; an op kernel's op code for it)."""
            m = models[stage.model]
            fn = stage_kernel(m, stage.kind, for_derivatives)
            own = for_derivatives and getattr(m, f"{stage.kind}_outputs_for_derivatives") is not None
            return call(stage.model, fn, f"{stage.kind}-outputs{' (derivatives)' if own else ''}", stage.gather,
                        diagram.y_block[stage.model], _OP_CODES[(stage.kind, own)])

        def derivative_rows(stages, for_derivatives=False):
            rows = [stage_op(s, for_derivatives) for s in stages]
            reuse = diagram.feedthrough_precedes_derivatives(stages)
            for i in diagram.derivative_models:
                m = models[i]
                opcode = KP.DERIVATIVES_AFTER_FEEDTHROUGH if reuse[i] else KP.DERIVATIVES
                rows.append(call(i, m.derivatives, "derivatives", (0, 0), diagram.x_block[i], opcode))
            return rows

        #: op table of a derivative evaluation that runs ``stages`` first (linearization's subsets)
        self.derivative_table = lambda stages: _table(derivative_rows(stages))
        #: op table of a set of output stages (a log's)
        self.stage_table = lambda stages: _table([stage_op(s) for s in stages])
        zc = []
        for i, sl in diagram.zero_crossing_models:
            if kinds.kind[i] == "op":
                raise NotCompilable(f"model {models[i].path}: zero crossings of an op-kernel model are not compiled")
            zc.append(call(i, models[i].zero_crossing_values, "zero-crossing", (0, 0), sl, 0))
        updates, input_stage_rows = self._updates(diagram, kinds, stage_op)
        normalizers = []
        for i in diagram.normalizers:
            if kinds.kind[i] != "op":
                raise NotCompilable(f"model {models[i].path}: only op-kernel models' quaternions are normalized "
                                    "compiled")
            normalizers.append(call(i, None, "normalize", (0, 0), slice(0, 0), KP.NORMALIZE))
        self.tables = (_table([stage_op(s) for s in diagram.output_order]),
                       _table(derivative_rows(diagram.derivative_stages, True)), len(diagram.derivative_stages),
                       _table(zc),
                       _table(updates), _table(normalizers), _table(input_stage_rows),
                       _table([stage_op(s) for s in diagram.zero_crossing_stages]))
        # every kernel is in a table now (every output stage is in the full order): later stage tables reuse them
        self.kernels = kinds.kernels()

    def _updates(self, diagram, kinds, stage_op):
        """One update row per model (kind -1: not sampled), and the rows of the stages their inputs need."""
        updates, input_stage_rows, noise_offset = [], [], 0
        for i, m in enumerate(diagram.models):
            block = (diagram.x_block[i], diagram.z_block[i], diagram.u_block[i], diagram.p_block[i], slice(0, 0))
            if m.period is None:
                updates.append(_op(-1, 0, (0, 0), *block))
                continue
            start = len(input_stage_rows)
            input_stage_rows += [stage_op(s) for s in diagram.input_stages[i]]
            stages = (start, len(input_stage_rows))
            data = _range(self.flat_slices[i]) if kinds.kind[i] == "data" else (0, 0)
            if not isinstance(m.update, CPUDispatcher):
                self.python_updates.append(i)
                updates.append(_op(L.UPDATE_PYTHON, 0, stages, *block))
            elif kinds.kind[i] == "op":
                raise NotCompilable(f"model {m.path}: updates of an op-kernel model are not compiled")
            elif m.noise_size:
                self.noisy.append(i)
                noise = (noise_offset, noise_offset + int(m.noise_size))
                noise_offset += int(m.noise_size)
                if kinds.kind[i] == "data":
                    kind, f = L.UPDATE_DATA_NOISE, kinds.pointer("data_fns", m.update, KP.DATA_KERNEL_SIGNATURE, m,
                                                                 "update")
                else:
                    kind, f = L.UPDATE_NOISE, kinds.pointer("fns", m.update, KP.KERNEL_SIGNATURE, m, "update")
                rng = kinds.n_words + L.GENERATOR_WORDS * (len(self.noisy) - 1)
                updates.append(_op(kind, f, stages, *block, noise=noise, rng=rng, data=data))
            elif kinds.kind[i] == "data":
                f = kinds.pointer("fns", m.update, KP.KERNEL_SIGNATURE, m, "update")
                updates.append(_op(L.UPDATE_DATA, f, stages, *block, data=data))
            else:
                f = kinds.pointer("update_fns", m.update, KP.UPDATE_SIGNATURE, m, "update")
                updates.append(_op(L.UPDATE, f, stages, *block))
        self.noise_size = max(noise_offset, 1)
        return updates, input_stage_rows


def _range(sl) -> tuple[int, int]:
    return (sl.start, sl.stop)


def _tables(diagram, context) -> _Tables:
    tables = getattr(diagram, "_compiled_tables", None)
    if tables is None:
        tables = diagram._compiled_tables = _Tables(diagram, context)
    return tables


class CompiledPlan:
    """The compiled form of ``diagram`` bound to ``context``; see the module docstring."""

    mode = "compiled"

    def __init__(self, diagram, context):
        self.diagram, self.context = diagram, context
        tables = _tables(diagram, context)
        if tuple(context.flat_slices) != tables.flat_slices:
            raise NotCompilable("the models' data slots differ in size from those of the diagram's first context")
        self.kernels = tables.kernels
        self.python_updates = tables.python_updates
        kinds = tables.kinds
        op_models = sorted(kinds.reference_range)
        if any(typeof(context.data[i]) != kinds.data_type[i] for i in op_models):
            raise NotCompilable("the op-kernel models' data differ in numba type from those of the diagram's first "
                                "context")
        #: the op-kernel models' per-run data and the noisy models' generators (kept alive here: the loop reads
        #: them by reference), and their references side by side (Buffers.R)
        self.op_data = tuple(context.data[i] for i in op_models)
        self.rngs = tuple(context.rngs[i] for i in tables.noisy)
        self.references = np.concatenate([np.zeros(0, dtype=np.int64)] + [KP.reference(d) for d in self.op_data]
                                         + [KP.reference(rng) for rng in self.rngs])
        self.noise = np.zeros(tables.noise_size)
        self.buffers = L.Buffers(context.x, context.z, context.signals, context.p, context.flat_data,
                                 self.references, context.xdot, context.g, self.noise, diagram.gather_source, diagram.gather_destination,
                                 diagram.gather_factor, *tables.tables)
        self._variants: dict = {}

    # -- compiled evaluation for Python callers (the methods of shell.diagram.InterpretedPlan) -------------------
    def derivative(self, t: float, y: np.ndarray) -> np.ndarray:
        """f(t, y), a new array (the right-hand side for adaptive and implicit integrators)."""
        b = self.buffers
        L.derivative_of(self.kernels, float(t), np.asarray(y, dtype=np.float64), b)
        return b.XD.copy()

    def evaluate(self, t: float, stages=None) -> None:
        """Every output (or those of ``stages``), then every input, at the context's state."""
        b = self.buffers
        if stages is None:
            L.evaluate_full(self.kernels, float(t), b, b.src, b.fac)
            return
        L.evaluate_stages(self.stage_table(stages), self.kernels, float(t), b)

    def update_is_compiled(self, i: int) -> bool:
        """Whether sampled model ``i`` has a compiled update (not a Python one)."""
        return int(self.buffers.update_ops[i, L.KIND]) in L.COMPILED_UPDATES

    def update(self, t: float, i: int) -> None:
        """Model ``i``'s discrete update at the context's state: compiled (the outputs its inputs need, its noise
        drawn from its own generator, its kernel: the same numbers as ``Diagram.update``), or a Python-only update
        through the diagram."""
        if not self.update_is_compiled(i):
            self.diagram.update(self.context, i, t)
            return
        L.update_model(i, self.kernels, float(t), self.buffers)

    def stage_table(self, stages):
        """The op table of ``stages`` (cached per stage tuple)."""
        cached = self._variants.get(("stages", stages))
        if cached is None:
            cached = self._variants[("stages", stages)] = _tables(self.diagram, self.context).stage_table(stages)
        return cached

    def zero_crossings(self, t: float, y: np.ndarray) -> np.ndarray:
        b = self.buffers
        L.zero_crossings(self.kernels, float(t), np.asarray(y, dtype=np.float64), b)
        return b.G.copy()

    def normalize(self, y: np.ndarray) -> None:
        L.normalize_state(self.kernels, self.buffers, y)

    def derivatives_into(self, t: float, stages, source=None, factor=None) -> None:
        """Derivatives at the context's ``x`` into its ``xdot``, running only the output ``stages`` first,
        with the gather arrays ``source``/``factor`` (an opened diagram's: linearization and trim), as
        ``InterpretedPlan.derivatives_into``."""
        key = (id(stages), id(source))
        cached = self._variants.get(key)
        if cached is None or cached[0] is not stages:
            table = _tables(self.diagram, self.context).derivative_table(stages)
            buffers = self.buffers._replace(derivative_ops=table, n_derivative_stages=len(stages))
            cached = self._variants[key] = (stages, buffers)
        b = cached[1]
        L.derivatives(self.kernels, b, float(t), b.src if source is None else source,
                      b.fac if factor is None else factor)


def compile_plan(diagram, context):
    """``(CompiledPlan, None)``, or ``(None, reason)`` when the scene must run interpreted."""
    try:
        return CompiledPlan(diagram, context), None
    except NotCompilable as exc:
        return None, str(exc)


def evaluation_plan(diagram, context, mode: str = "compiled"):
    """``(plan, reason)``: the compiled plan of ``context``, or the interpreted one (``mode="interpreted"``, or a scene
    that cannot run compiled: ``reason`` says why, None otherwise). Both have the same methods and numbers."""
    from shell.diagram import InterpretedPlan

    if mode == "compiled":
        plan, reason = compile_plan(diagram, context)
        if plan is not None:
            return plan, None
        return InterpretedPlan(diagram, context), reason
    return InterpretedPlan(diagram, context), None
