"""The diagram's plan in the form :mod:`shell.compiled_loop` runs: op tables and kernel pointers.

:func:`compile_plan` checks that a scene can run compiled and says why not; :class:`CompiledPlan` binds a
:class:`shell.diagram.Diagram` and one :class:`shell.diagram.Context` (its buffers are the context's own
arrays, so the compiled and the interpreted path see and change the same state) and offers the compiled
evaluation to Python callers (``derivative`` for adaptive and implicit integrators, ``evaluate``,
``zero_crossings``, ``update``).

What runs compiled: every model kernel that is a numba function of the uniform signature
``kernel(t, x, z, u, p, out)`` (update: ``update(t, x, z, u, p)``, or ``update(t, x, z, u, p, noise)``
with ``noise_size``), and the engine model (:class:`shell.models.multibody.MultibodyModel`). A model
whose output, derivative or zero-crossing kernel is plain Python makes the whole scene run interpreted
(the message names it). A sampled model whose update is plain Python (``UserFunction``, the thruster
cluster's minimum-fuel allocation, ``MassDepletion``) keeps the loop compiled: it returns to Python at
that model's sample instants.
"""

from __future__ import annotations

import numpy as np
from numba import typeof
from numba.core.registry import CPUDispatcher
from numba.experimental.function_type import _get_jit_address, _get_wrapper_address

from shell import compiled_loop as L
from shell.models.multibody import MultibodyModel, no_engine_kernel


class NotCompilable(Exception):
    """The scene cannot run in the compiled loop; the message says which model and why."""


def _pointer(fn, signature, model=None, what=""):
    """[cfunc wrapper address, numba entry address] of ``fn`` compiled for ``signature``."""
    if not isinstance(fn, CPUDispatcher):
        raise NotCompilable(f"model {model.path} ({type(model).__name__}): its {what} kernel is Python, not a "
                            "numba function")
    try:
        fn.compile(signature)
        return [_get_wrapper_address(fn, signature), _get_jit_address(fn, signature)]
    except Exception as exc:  # a kernel that does not fit the uniform signature
        where = f"model {model.path} ({type(model).__name__}): its {what} kernel" if model else f"kernel {fn}"
        raise NotCompilable(f"{where} does not compile for the uniform signature {signature}: "
                            f"{type(exc).__name__}: {str(exc).splitlines()[0][:200]}") from None


_ENGINE_POINTERS: dict = {}
_PROBE: list = []


def _engine_pointers(engine_model):
    """The engine slot of the kernel table: the engine model's kernel (the one for its system's path, so a
    scene compiles that path only), or for a scene without the engine model a stand-in that is never called
    (so that such a scene does not compile the engine)."""
    kernel = no_engine_kernel if engine_model is None else engine_model.engine_kernel
    if kernel not in _ENGINE_POINTERS:
        _ENGINE_POINTERS[kernel] = _pointer(kernel, L.ENGINE_SIGNATURE)
    return np.asarray(_ENGINE_POINTERS[kernel], dtype=np.int64)


def _probe():
    if not _PROBE:
        from shell.models.multibody import probe_engine_data

        _PROBE.append(probe_engine_data())
        _PROBE.append(np.random.default_rng(0))
    return _PROBE


def _op(kind, fn, gather, x, z, u, p, out, noise=(0, 0), rng=0):
    return [kind, fn, gather[0], gather[1], x.start, x.stop, z.start, z.stop, u.start, u.stop, p.start, p.stop,
            out.start, out.stop, noise[0], noise[1], rng]


def _table(rows):
    return np.asarray(rows, dtype=np.int64).reshape(-1, L.OP_COLUMNS)


class _Tables:
    """What the compiled form of a diagram needs that does not depend on the run: op tables, kernel
    pointers, which model is the engine, which models draw noise (built once per diagram)."""

    def __init__(self, diagram):
        models = diagram.models
        fns, update_fns = [], []
        self.python_updates, self.noisy = [], []
        fn_index: dict = {}
        engine_models: list = []

        def plain(fn, model, what):
            key = id(fn)
            if key not in fn_index:
                fns.append(_pointer(fn, L.KERNEL_SIGNATURE, model, what))
                fn_index[key] = len(fns) - 1
            return fn_index[key]

        def engine(i):
            if i not in engine_models:
                if engine_models:
                    raise NotCompilable(f"models {models[engine_models[0]].path} and {models[i].path}: the compiled "
                                        "loop runs one engine model per scene")
                engine_models.append(i)
            return 0

        def is_engine(m):
            if isinstance(m, MultibodyModel):
                return True
            if m.uses_data:
                raise NotCompilable(f"model {m.path} ({type(m).__name__}) keeps per-run data the compiled loop "
                                    "does not know (only the engine model's)")
            return False

        def stage_op(stage):
            i, m = stage.model, models[stage.model]
            block = (diagram.x_block[i], diagram.z_block[i], diagram.u_block[i], diagram.p_block[i],
                     diagram.y_block[i])
            if is_engine(m):
                kind = L.ENGINE_STATE if stage.kind == "state" else L.ENGINE_FEEDTHROUGH
                return _op(kind, engine(i), stage.gather, *block)
            fn = m.state_outputs if stage.kind == "state" else m.feedthrough_outputs
            return _op(L.PLAIN, plain(fn, m, f"{stage.kind}-outputs"), stage.gather, *block)

        def derivative_rows(stages):
            rows = [stage_op(s) for s in stages]
            reuse = diagram.feedthrough_precedes_derivatives(stages)
            for i in diagram.derivative_models:
                m = models[i]
                block = (diagram.x_block[i], diagram.z_block[i], diagram.u_block[i], diagram.p_block[i],
                         diagram.x_block[i])
                if is_engine(m):
                    kind = L.ENGINE_DERIVATIVES_REUSE if reuse[i] else L.ENGINE_DERIVATIVES
                    rows.append(_op(kind, engine(i), (0, 0), *block))
                else:
                    rows.append(_op(L.PLAIN, plain(m.derivatives, m, "derivatives"), (0, 0), *block))
            return rows

        #: op table of a derivative evaluation that runs ``stages`` first (linearization's subsets)
        self.derivative_table = lambda stages: _table(derivative_rows(stages))
        full = [stage_op(s) for s in diagram.output_order]
        derivative = derivative_rows(diagram.derivative_stages)
        zc = []
        for i, sl in diagram.zero_crossing_models:
            m = models[i]
            if is_engine(m):
                raise NotCompilable(f"model {m.path}: engine zero crossings are not compiled")
            zc.append(_op(L.PLAIN, plain(m.zero_crossing_values, m, "zero-crossing"), (0, 0), diagram.x_block[i],
                          diagram.z_block[i], diagram.u_block[i], diagram.p_block[i], sl))
        updates, noise_offset, input_stage_rows = [], 0, []
        for i, m in enumerate(models):
            block = (diagram.x_block[i], diagram.z_block[i], diagram.u_block[i], diagram.p_block[i], slice(0, 0))
            if m.period is None:
                updates.append(_op(-1, 0, (0, 0), *block))
                continue
            start = len(input_stage_rows)
            input_stage_rows += [stage_op(s) for s in diagram.input_stages[i]]
            stages = (start, len(input_stage_rows))
            fn = m.update
            if not isinstance(fn, CPUDispatcher):
                self.python_updates.append(i)
                updates.append(_op(L.UPDATE_PYTHON, 0, stages, *block))
            elif m.noise_size:
                if len(self.noisy) == L.MAX_NOISY_MODELS:
                    raise NotCompilable(f"model {m.path}: more than {L.MAX_NOISY_MODELS} models with noise")
                self.noisy.append(i)
                noise = (noise_offset, noise_offset + int(m.noise_size))
                noise_offset += int(m.noise_size)
                updates.append(_op(L.UPDATE_NOISE, plain(fn, m, "update"), stages, *block, noise=noise,
                                   rng=len(self.noisy) - 1))
            else:
                update_fns.append(_pointer(fn, L.UPDATE_SIGNATURE, m, "update"))
                updates.append(_op(L.UPDATE, len(update_fns) - 1, stages, *block))
        normalizers = []
        for i in diagram.normalizers:
            if not is_engine(models[i]):
                raise NotCompilable(f"model {models[i].path}: only the engine's quaternions are normalized compiled")
            normalizers.append([engine(i), diagram.x_block[i].start, diagram.x_block[i].stop])
        self.engine_model = engine_models[0] if engine_models else None
        self.engine_type_checked = False
        self.noise_size = max(noise_offset, 1)
        self.kernels = L.Kernels(np.asarray(fns, dtype=np.int64).reshape(-1, 2),
                                 np.asarray(update_fns, dtype=np.int64).reshape(-1, 2),
                                 _engine_pointers(models[engine_models[0]] if engine_models else None))
        self.tables = (_table(full), _table(derivative), len(diagram.derivative_stages), _table(zc), _table(updates),
                       np.asarray(normalizers, dtype=np.int64).reshape(-1, 3), _table(input_stage_rows),
                       _table([stage_op(s) for s in diagram.zero_crossing_stages]))
        #: op table of a set of output stages (a log's)
        self.stage_table = lambda stages: _table([stage_op(s) for s in stages])


def _tables(diagram) -> _Tables:
    tables = getattr(diagram, "_compiled_tables", None)
    if tables is None:
        tables = diagram._compiled_tables = _Tables(diagram)
    return tables


class CompiledPlan:
    """The compiled form of ``diagram`` bound to ``context``; see the module docstring."""

    def __init__(self, diagram, context):
        self.diagram, self.context = diagram, context
        tables = _tables(diagram)
        self.kernels = tables.kernels
        self.python_updates = tables.python_updates
        probe_engine, probe_rng = _probe()
        if tables.engine_model is not None and not tables.engine_type_checked:
            data = context.data[tables.engine_model]
            tables.engine_type_checked = True  # every context of a diagram has data of the same type
            if typeof(data) != L.ENGINE_DATA:
                raise NotCompilable(f"model {diagram.models[tables.engine_model].path}: its engine data has numba "
                                    f"type {typeof(data)}, the compiled loop expects {L.ENGINE_DATA}")
        #: the engine model's data (a stand-in when the scene has none) and the random streams of noisy models
        self.engine = context.data[tables.engine_model] if tables.engine_model is not None else probe_engine
        rngs = [context.rngs[i] for i in tables.noisy]
        self.rngs = tuple(rngs) + (probe_rng,) * (L.MAX_NOISY_MODELS - len(rngs))
        self.noise = np.zeros(tables.noise_size)
        self.buffers = L.Buffers(context.x, context.z, context.signals, context.p, context.xdot, context.g, self.noise,
                                 diagram.gather_source, diagram.gather_destination, diagram.gather_factor,
                                 *tables.tables)
        self._variants: dict = {}

    # -- compiled evaluation for Python callers -------------------------------------------------------
    def derivative(self, t: float, y: np.ndarray) -> np.ndarray:
        """f(t, y), a new array (the right-hand side for adaptive and implicit integrators)."""
        b = self.buffers
        L.derivative_at(self.kernels, self.engine, float(t), np.asarray(y, dtype=np.float64), b, b.src, b.fac)
        return b.XD.copy()

    def evaluate(self, t: float, stages=None) -> None:
        """Every output (or those of ``stages``), then every input, at the context's state."""
        b = self.buffers
        if stages is None:
            L.evaluate_full(self.kernels, self.engine, float(t), b, b.src, b.fac)
            return
        table = self.stage_table(stages)
        L.run_stages(table, table.shape[0], self.kernels, self.engine, float(t), b, b.src, b.fac)
        L.gather_all(b, b.src, b.fac)

    def update_is_compiled(self, i: int) -> bool:
        """Whether sampled model ``i`` has a compiled update (not a Python one)."""
        return int(self.buffers.update_ops[i, L.KIND]) in (L.UPDATE, L.UPDATE_NOISE)

    def update(self, t: float, i: int) -> None:
        """Model ``i``'s discrete update at the context's state, compiled: the outputs its inputs need, its
        noise drawn from its own generator, its kernel (the same numbers as ``Diagram.update``; for loops
        that stay in Python, e.g. with an adaptive or exponential integrator)."""
        rng = self.rngs[int(self.buffers.update_ops[i, L.RNG])]  # its own stream (slot 0, unused, without noise)
        L.update_model_alone(i, self.kernels, self.engine, rng, float(t), self.buffers)

    def stage_table(self, stages):
        """The op table of ``stages`` (cached per stage tuple)."""
        cached = self._variants.get(("stages", stages))
        if cached is None:
            cached = self._variants[("stages", stages)] = _tables(self.diagram).stage_table(stages)
        return cached

    def zero_crossings(self, t: float, y: np.ndarray) -> np.ndarray:
        b = self.buffers
        b.X[:] = y
        L.zero_crossings(self.kernels, self.engine, float(t), b, b.src, b.fac)
        return b.G.copy()

    def normalize(self, y: np.ndarray) -> None:
        L.normalize(self.kernels, self.engine, self.buffers, y)

    def derivatives_into(self, t: float, stages, source=None, factor=None) -> None:
        """Derivatives at the context's ``x`` into its ``xdot``, running only the output ``stages`` first,
        with the gather arrays ``source``/``factor`` (an opened diagram's): the compiled form of
        ``OpenedDiagram.derivatives_into``, for linearization and trim."""
        key = (id(stages), id(source))
        cached = self._variants.get(key)
        if cached is None or cached[0] is not stages:
            table = _tables(self.diagram).derivative_table(stages)
            buffers = self.buffers._replace(derivative_ops=table, n_derivative_stages=len(stages))
            cached = self._variants[key] = (stages, buffers)
        b = cached[1]
        L.derivatives(self.kernels, self.engine, float(t), b, b.src if source is None else source,
                      b.fac if factor is None else factor)


def compile_plan(diagram, context):
    """``(CompiledPlan, None)``, or ``(None, reason)`` when the scene must run interpreted."""
    try:
        return CompiledPlan(diagram, context), None
    except NotCompilable as exc:
        return None, str(exc)
