"""One compiled loop that runs any scene: the diagram's plan as arrays, the model kernels as function pointers.

The interpreted evaluation (:mod:`shell.diagram`) calls each model kernel from Python: about a microsecond of
dispatch per kernel, many per derivative. Here the same sequence runs inside numba:

* the plan (evaluation order, gather ranges, each model's slices of ``x``, ``z``, the signal buffer, the packed
  parameters and its data slot) is encoded as integer *op* tables (:class:`shell.compiled_plan.CompiledPlan`);
* every model kernel is passed as a function pointer (the addresses numba gives a compiled function, in an int64
  table) and called through it: an indirect call of ~10 ns, no Python. Kernels of the uniform signature, kernels
  of models with a data slot, and the op kernels of models with typed per-run data (the engine: its data by
  reference, an int64 array, :func:`shell.kernel_protocol.reference`) are called the same way
  (:mod:`shell.kernel_protocol`);
* :func:`advance` runs the instants from one to the next: it integrates with the run's stepper (whatever method:
  :mod:`shell.integrators.compiled`; the loop below owns the instants, the shortened last step, the counters, the
  zero-crossing checks on the method's dense output and the returns to Python), runs the sampled models' updates
  at integer ticks of a common time base (their noise drawn from each model's own ``numpy.random.Generator``,
  bit-identical to the interpreted draws; the generators by reference in ``R``), writes log rows into preallocated buffers, and returns to Python only to
  run Python-only models, flush full log buffers, report progress, locate a crossing, answer the integrator, or
  report a failure (:mod:`shell.compiled_run`).

Because the plan, the kernels and the op kernels' data are data (arrays of offsets, of addresses, of references),
this module is compiled once per installation (numba's on-disk cache) per stepper type, not per scene: a new
scene costs no compilation, and the loop's compiled code does not contain the engine or any model (each is compiled
and cached on its own). The arithmetic is that of the interpreted path operation for operation (same kernels, the
stepper's combinations, the same quaternion normalization, instants ``k / den`` rounded as Python's
``float(Fraction)``), so the two give the same numbers; tests check it.

Op table columns (int64): ``KIND, FN, G0, G1, X0, X1, Z0, Z1, U0, U1, P0, P1, O0, O1, N0, N1, RNG, D0, D1,
OPCODE``: the kind of call, the function index, the feedthrough gather range, the model's slices of ``x``, ``z``,
the signal buffer (inputs), the parameters, its output range (outputs in the signal buffer, derivatives in
``xdot``, zero crossings in ``g``), the noise buffer range of a noisy update and where its generator's reference
starts in ``R``, its data slot range (for an op kernel: the range of its data's reference in ``R``), and an op
kernel's op code.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit, typeof, types
from numba.core import cgutils
from numba.extending import intrinsic
from numba.np.random import generator_core  # noqa: F401 (registers the numba data model of a numpy Generator)

from dynamics.engine import borrowed, strip_references
from shell import kernel_protocol as KP
from shell.integrators import compiled as IC
from shell.integrators.compiled import (I_F_VALID, I_NOW, I_PHASE, I_STEPS, I_UPDATES, R_LAST_EVENT, R_T, R_T_OLD,
                                        START_FAILED, STEP_FAILED, FIRST_REQUEST, N_INTS, N_REALS)
from shell.integrators.kernels import all_finite, copy_into

__all__ = ["N_INTS", "N_REALS", "START_FAILED", "STEP_FAILED", "FIRST_REQUEST"]

#: a numpy Generator's numba type and the int64 words of its reference (:func:`shell.kernel_protocol.reference`)
GENERATOR = typeof(np.random.default_rng(0))
GENERATOR_WORDS = KP.reference_words(GENERATOR)
_generator = KP.reader(GENERATOR)


def _function_struct(function_type, context, builder, args):
    value = cgutils.create_struct_proxy(function_type)(context, builder)
    pointer = context.get_value_type(types.voidptr)
    value.c_addr = builder.inttoptr(args[0], pointer)
    value.py_addr = cgutils.get_null_value(pointer)
    value.jit_addr = builder.inttoptr(args[1], pointer)
    return value._getvalue()


def _pointer_intrinsic(signature):
    """An intrinsic turning (cfunc wrapper address, numba entry address) into a callable first-class function of
    ``signature`` (numba's FunctionType struct; the call goes through the numba entry)."""
    function_type = types.FunctionType(signature)

    @intrinsic
    def as_function(typingctx, c_address, jit_address):
        def codegen(context, builder, sig, args):
            return _function_struct(function_type, context, builder, args)

        return function_type(types.int64, types.int64), codegen

    return as_function


@intrinsic
def _view(typingctx, array, start, stop):
    """``array[start:stop]`` (1-D, contiguous) without reference counting: the loop passes views of the
    context's buffers, which outlive every call, to kernels behind function pointers, where numba's own
    slices cost an atomic increment and decrement each (measured: 55 ns per call with five slices, 7-17
    ns with these views)."""
    if not (isinstance(array, types.Array) and array.ndim == 1):
        return None
    view_type = types.Array(array.dtype, 1, "C")

    def codegen(context, builder, sig, args):
        from numba.np.arrayobj import make_array, populate_array

        source = make_array(sig.args[0])(context, builder, args[0])
        view = make_array(view_type)(context, builder)
        itemsize = source.itemsize
        populate_array(view, data=builder.gep(source.data, [args[1]]),
                       shape=cgutils.pack_array(builder, [builder.sub(args[2], args[1])]),
                       strides=cgutils.pack_array(builder, [itemsize]), itemsize=itemsize, meminfo=None)
        return view._getvalue()

    return view_type(array, types.intp, types.intp), codegen


_kernel = _pointer_intrinsic(KP.KERNEL_SIGNATURE)
_data_kernel = _pointer_intrinsic(KP.DATA_KERNEL_SIGNATURE)
_update_kernel = _pointer_intrinsic(KP.UPDATE_SIGNATURE)
_op_kernel = _pointer_intrinsic(KP.REFERENCE_KERNEL_SIGNATURE)

# op table columns
KIND, FN, G0, G1, X0, X1, Z0, Z1, U0, U1, P0, P1, O0, O1, N0, N1, RNG, D0, D1, OPCODE = range(20)
OP_COLUMNS = 20

# op kinds
PLAIN = 0                # fns[FN](t, x, z, u, p, out)
DATA = 1                 # data_fns[FN](t, x, z, u, p, d, out), d = the model's data slot D[D0:D1]
OP = 2                   # op_fns[FN](OPCODE, t, x, z, u, p, R[D0:D1], out): the model's data by reference
UPDATE = 5               # update_fns[FN](t, x, z, u, p)
UPDATE_NOISE = 6         # noise from the generator at R[RNG:] into noise[N0:N1], then fns[FN](t, x, z, u, p, noise)
UPDATE_PYTHON = 7        # the update runs in Python: advance returns to the caller
UPDATE_DATA = 8          # fns[FN](t, x, z, u, p, d)
UPDATE_DATA_NOISE = 9    # noise as UPDATE_NOISE, then data_fns[FN](t, x, z, u, p, d, noise)
COMPILED_UPDATES = (UPDATE, UPDATE_NOISE, UPDATE_DATA, UPDATE_DATA_NOISE)

# advance status (the stepper's own: shell.integrators.compiled)
DONE = 0
PYTHON_UPDATE = 1        # a Python-only model is due at the current instant (no update done there yet)
LOG_FULL = 2             # a log buffer is full (after logging at the current instant)
BUDGET = 3               # the instant budget of this call is spent (after a whole instant)
UPDATE_FAILED = 6        # a discrete update left a non-finite state
EVENT_CANDIDATE = 7      # a zero-crossing function may cross inside the last step: Python locates it

# zero-crossing detection modes
NO_EVENTS = 0
SIGN_CHANGE = 1          # search a step when a function changes sign between its ends
SUBDIVIDED = 2           # search every step on its dense output (shell.integrators.events)
SUBDIVISIONS = 8         # the subdivisions of shell.integrators.locate_events


class Buffers(NamedTuple):
    """The context's buffers and the plan's op tables (arrays only: a fast argument for numba)."""

    X: np.ndarray
    Z: np.ndarray
    S: np.ndarray
    P: np.ndarray
    D: np.ndarray               # the data slots of the models that have one
    R: np.ndarray               # int64: the op-kernel models' data and the noisy models' generators by reference
    XD: np.ndarray
    G: np.ndarray
    noise: np.ndarray
    src: np.ndarray
    dst: np.ndarray
    fac: np.ndarray
    full_ops: np.ndarray        # every output stage, in order
    derivative_ops: np.ndarray  # output stages the derivatives need, then one op per derivative kernel
    n_derivative_stages: int
    zc_ops: np.ndarray
    update_ops: np.ndarray      # one row per model (KIND -1: not sampled); G0:G1 its rows of input_stage_ops
    normalize_ops: np.ndarray   # one OP row (op code NORMALIZE) per model with quaternions
    input_stage_ops: np.ndarray  # per sampled model, the stages its inputs need (Diagram.input_stages)
    zc_stage_ops: np.ndarray    # the stages the zero-crossing functions need


class Kernels(NamedTuple):
    """Function pointers ([cfunc wrapper address, numba entry address] rows) of the plan's kernels."""

    fns: np.ndarray          # (n, 2) KERNEL_SIGNATURE
    data_fns: np.ndarray     # (m, 2) DATA_KERNEL_SIGNATURE
    update_fns: np.ndarray   # (k, 2) UPDATE_SIGNATURE
    op_fns: np.ndarray       # (e, 2) REFERENCE_KERNEL_SIGNATURE: op kernels by reference


class System(NamedTuple):
    """What a stepper integrates (shell.integrators.compiled): the kernels and the buffers."""

    kernels: Kernels
    buffers: Buffers


class Events(NamedTuple):
    """Zero-crossing detection: the mode, the check's function pointer (:func:`event_check`), each function's
    direction, values at the ends of the last step and at the subdivision samples, the last step's start (for its
    dense output)."""

    mode: int
    check: np.ndarray        # (2,) int64: [cfunc wrapper address, numba entry address] of events_at (0: no events)
    direction: np.ndarray    # (m,) int64: +1 rising only, -1 falling only, 0 both
    g_old: np.ndarray        # (m,)
    g_new: np.ndarray        # (m,)
    samples: np.ndarray      # (SUBDIVISIONS + 1, m)
    y_old: np.ndarray        # state and slope at the start of the last step (the stepper's keep)
    f_old: np.ndarray
    y_mid: np.ndarray        # scratch: the dense output at a sample


class Schedule(NamedTuple):
    """Sample instants as integer ticks of 1/den s: per model (-1: not sampled) and per log group."""

    den: int
    end: int
    next_tick: np.ndarray
    period: np.ndarray
    order: np.ndarray          # sampled models in update order
    log_next: np.ndarray
    log_period: np.ndarray
    log_kind: np.ndarray       # per logged element: 0 signal, 1 x, 2 z
    log_index: np.ndarray
    log_start: np.ndarray      # group g owns log_kind[log_start[g]:log_start[g + 1]]
    log_times: np.ndarray      # (groups, capacity)
    log_rows: np.ndarray       # (groups, capacity, widest group)
    log_count: np.ndarray
    log_stage_ops: np.ndarray  # the output stages the logged signals need


# ----------------------------------------------------------------------------------------------------------
# evaluation. The chain from the derivative to the model kernels is inlined (numba's inline="always") into one
# function, which the steppers call with the system by reference (_derivative_by_reference): a call level that copies
# the scene's arrays by value measured 40 % of an RK4 step of a free rigid body (6.4 against 3.6 us, when the
# engine's ~40 arrays were among them) and 8x the kernel calls of 200 trivial models when each kernel call was a
# helper of its own; inlining the evaluation into every stepper's call site instead cost ~25 s of each loop's
# compilation (issue 31).
@njit(cache=True, inline="always")
def _run_rows(k, b, ops, r0, r1, t, src, fac, out):
    """Rows ``r0:r1`` of an op table: gather each row's feedthrough inputs (its G0:G1 range of the gather arrays
    ``src``/``fac``), then call its kernel with output ``out[O0:O1]`` (the signal buffer for output stages, ``XD`` for
    derivatives, ``G`` for zero crossings)."""
    S = b.S
    dst = b.dst
    for r in range(r0, r1):
        for g in range(ops[r, G0], ops[r, G1]):
            S[dst[g]] = fac[g] * S[src[g]]
        x = _view(b.X, ops[r, X0], ops[r, X1])
        z = _view(b.Z, ops[r, Z0], ops[r, Z1])
        u = _view(S, ops[r, U0], ops[r, U1])
        p = _view(b.P, ops[r, P0], ops[r, P1])
        y = _view(out, ops[r, O0], ops[r, O1])
        kind = ops[r, KIND]
        f = ops[r, FN]
        if kind == PLAIN:
            _kernel(k.fns[f, 0], k.fns[f, 1])(t, x, z, u, p, y)
        elif kind == OP:
            _op_kernel(k.op_fns[f, 0], k.op_fns[f, 1])(ops[r, OPCODE], t, x, z, u, p,
                                                       _view(b.R, ops[r, D0], ops[r, D1]), y)
        else:
            _data_kernel(k.data_fns[f, 0], k.data_fns[f, 1])(t, x, z, u, p, _view(b.D, ops[r, D0], ops[r, D1]), y)


@njit(cache=True)
def run_stages(ops, n_ops, k, b, t, src, fac):
    """Output stages ``ops[:n_ops]``: gather each model's feedthrough inputs, then call its kernel."""
    _run_rows(k, b, ops, 0, n_ops, t, src, fac, b.S)


@njit(cache=True)
def gather_all(b, src, fac):
    S = b.S
    dst = b.dst
    for g in range(dst.shape[0]):
        S[dst[g]] = fac[g] * S[src[g]]


@njit(cache=True)
def evaluate_full(k, t, b, src, fac):
    """Every output, then every input (the interpreted ``Diagram.evaluate``)."""
    run_stages(b.full_ops, b.full_ops.shape[0], k, b, t, src, fac)
    gather_all(b, src, fac)


@njit(cache=True)
def evaluate_stages(ops, k, t, b):
    """The output stages of the op table ``ops``, then every input (a log's evaluation)."""
    run_stages(ops, ops.shape[0], k, b, t, b.src, b.fac)
    gather_all(b, b.src, b.fac)


@njit(cache=True, inline="always")
def derivatives(k, b, t, src, fac):
    """``XD = f(t, X)`` (the interpreted ``Diagram.derivatives``), with the gather arrays ``src``/``fac`` (the
    diagram's, or an opened diagram's)."""
    ops = b.derivative_ops
    n_stages = b.n_derivative_stages
    _run_rows(k, b, ops, 0, n_stages, t, src, fac, b.S)
    gather_all(b, src, fac)
    _run_rows(k, b, ops, n_stages, ops.shape[0], t, src, fac, b.XD)


@intrinsic
def _by_reference(typingctx, value):
    """A pointer to ``value`` (a tuple of arrays, nested) stored on the caller's stack with its arrays borrowed
    (:func:`dynamics.engine.borrowed`): valid in the caller's frame while the owner of the arrays keeps them."""
    def codegen(context, builder, sig, args):
        model = context.data_model_manager[sig.args[0]]
        stripped = strip_references(context, builder, sig.args[0], args[0])
        return cgutils.alloca_once_value(builder, model.as_data(builder, stripped))

    return types.CPointer(value)(value), codegen


@intrinsic
def _dereference(typingctx, pointer):
    """The value :func:`_by_reference` stored (its arrays borrowed)."""
    if not isinstance(pointer, types.CPointer):
        return None

    def codegen(context, builder, sig, args):
        return context.data_model_manager[sig.return_type].from_data(builder, builder.load(args[0]))

    return pointer.dtype(pointer), codegen


@njit(cache=True)
def _derivative_by_reference(system_reference, t, y):
    system = _dereference(system_reference)
    b = system.buffers
    copy_into(b.X, y)
    derivatives(system.kernels, b, t, b.src, b.fac)
    return b.XD


@njit(cache=True, inline="always")
def derivative_at(system, t, y):
    """``f(t, y)`` into ``XD``, returned (``X`` is overwritten with ``y``): the system's derivative for steppers.
    The evaluation is compiled once, in a function of its own that takes the system by reference (one pointer: the
    system's ~170 words by value measured 40 % of an RK4 step of a free body), not into every call site."""
    return _derivative_by_reference(_by_reference(system), t, y)


@njit(cache=True)
def derivative_of(k, t, y, b):
    """:func:`derivative_at` for a Python caller."""
    copy_into(b.X, y)
    derivatives(k, b, t, b.src, b.fac)


@njit(cache=True)
def _zero_crossings(k, b, t):
    """Every zero-crossing function into ``G`` after evaluating the outputs they need."""
    run_stages(b.zc_stage_ops, b.zc_stage_ops.shape[0], k, b, t, b.src, b.fac)
    gather_all(b, b.src, b.fac)
    _run_rows(k, b, b.zc_ops, 0, b.zc_ops.shape[0], t, b.src, b.fac, b.G)


@njit(cache=True)
def zero_crossings(k, t, y, b):
    """:func:`_zero_crossings` at state ``y`` for a Python caller."""
    copy_into(b.X, y)
    _zero_crossings(k, b, t)


@njit(cache=True)
def update_model_alone(i, system, t):
    """Evaluate the outputs model ``i``'s inputs need, then run its compiled update, drawing its noise first from
    its own random stream."""
    b, k = system.buffers, system.kernels
    ops = b.update_ops
    run_stages(b.input_stage_ops[ops[i, G0]:ops[i, G1]], ops[i, G1] - ops[i, G0], k, b, t, b.src, b.fac)
    gather_all(b, b.src, b.fac)
    x = _view(b.X, ops[i, X0], ops[i, X1])
    z = _view(b.Z, ops[i, Z0], ops[i, Z1])
    u = _view(b.S, ops[i, U0], ops[i, U1])
    p = _view(b.P, ops[i, P0], ops[i, P1])
    d = _view(b.D, ops[i, D0], ops[i, D1])
    f = ops[i, FN]
    kind = ops[i, KIND]
    if kind == UPDATE:
        _update_kernel(k.update_fns[f, 0], k.update_fns[f, 1])(t, x, z, u, p)
    elif kind == UPDATE_DATA:
        _kernel(k.fns[f, 0], k.fns[f, 1])(t, x, z, u, p, d)
    else:
        noise = _view(b.noise, ops[i, N0], ops[i, N1])
        rng = _generator(_view(b.R, ops[i, RNG], ops[i, RNG] + GENERATOR_WORDS))
        for n in range(noise.shape[0]):
            noise[n] = rng.standard_normal()
        if kind == UPDATE_NOISE:
            _kernel(k.fns[f, 0], k.fns[f, 1])(t, x, z, u, p, noise)
        else:
            _data_kernel(k.data_fns[f, 0], k.data_fns[f, 1])(t, x, z, u, p, d, noise)


@njit(cache=True)
def update_model(i, k, t, b):
    """:func:`update_model_alone` for a Python caller (a loop whose integrator stays in Python)."""
    update_model_alone(i, System(k, b), t)


@njit(cache=True, inline="always")
def normalize(system, y):
    """Renormalize the hinge quaternions of state ``y`` (the interpreted ``Diagram.normalize``)."""
    b, k = system.buffers, system.kernels
    ops = b.normalize_ops
    for r in range(ops.shape[0]):
        x = _view(y, ops[r, X0], ops[r, X1])
        f = ops[r, FN]
        _op_kernel(k.op_fns[f, 0], k.op_fns[f, 1])(KP.NORMALIZE, 0.0, x, x, x, x, _view(b.R, ops[r, D0], ops[r, D1]),
                                                   x)


@njit(cache=True)
def normalize_state(k, b, y):
    """:func:`normalize` for a Python caller."""
    normalize(System(k, b), y)


@njit(cache=True)
def _state(system):
    return system.buffers.X


IC.register_system(System, derivative=derivative_at, normalize=normalize, state=_state)


# ----------------------------------------------------------------------------------------------------------
# the loop
@njit(cache=True)
def _instant_time(tick, den):
    # float(Fraction(tick, den)): both exact in binary64 (checked by the caller), the quotient correctly rounded
    return float(tick) / float(den)


@njit(cache=True)
def _zero_crossings_at(system, t, y, out):
    b = system.buffers
    copy_into(b.X, y)
    _zero_crossings(system.kernels, b, t)
    copy_into(out, b.G)


@njit(cache=True)
def _candidate_pair(a, c, direction):
    """The check of locate_events on one pair of consecutive samples: a root is reported there."""
    if a == 0.0 or np.isnan(a) or np.isnan(c):
        return False
    if c == 0.0:
        crossing = -1.0 if a > 0.0 else 1.0
    elif (a < 0.0) != (c < 0.0):
        crossing = 1.0 if c > 0.0 else -1.0
    else:
        return False
    return direction == 0 or direction == crossing


@njit(cache=True)
def _parabola_flags(g0, g1, g2, t0, t1, t2):
    """The condition under which locate_events samples a parabola's extremum between three same-sign
    samples (it may hide two roots): Python then decides."""
    same_sign = (g0 > 0 and g1 > 0 and g2 > 0) or (g0 < 0 and g1 < 0 and g2 < 0)
    if not same_sign:
        return False
    d01 = (g1 - g0) / (t1 - t0)
    d12 = (g2 - g1) / (t2 - t1)
    curv = (d12 - d01) / (t2 - t0)
    if curv == 0.0:
        return False
    t_ext = 0.5 * (t0 + t1) - d01 / (2.0 * curv)
    if not (t0 < t_ext < t2 and t_ext != t1):
        return False
    model = g0 + d01 * (t_ext - t0) + curv * (t_ext - t0) * (t_ext - t1)
    return np.sign(model) != np.sign(g1) or abs(model) < 0.1 * min(abs(g0), abs(g1), abs(g2))


@njit(cache=True)
def _samples_flag_candidate(ev, m, n, step, t_old, t_new):
    """True when the zero-crossing samples ``ev.samples[0..n]`` (instants ``t_old + j step``, the last one
    ``t_new``) show a sign change in the wanted direction, or a parabola through three of them that may
    cross in between: the tests of ``shell.integrators.locate_events`` (steps 2 and 3)."""
    for f in range(m):
        for j in range(n):
            if _candidate_pair(ev.samples[j, f], ev.samples[j + 1, f], ev.direction[f]):
                return True
        for j in range(n - 1):
            if _parabola_flags(ev.samples[j, f], ev.samples[j + 1, f], ev.samples[j + 2, f], j * step + t_old,
                               (j + 1) * step + t_old, (t_new if j + 2 == n else (j + 2) * step + t_old)):
                return True
    return False


@njit(cache=True)
def _crossed(ev):
    """Simulation's sign-change test: a sign change between the ends of the step, in a counted direction."""
    for j in range(ev.g_old.shape[0]):
        a, c = ev.g_old[j], ev.g_new[j]
        if a == 0.0:
            continue
        if c == 0.0 or (a < 0.0) != (c < 0.0):
            rising = c > a
            if ev.direction[j] == 0 or (ev.direction[j] > 0) == rising:
                return True
    return False


@njit(cache=True)
def _dense_samples(system, st, ev, t_old, t_new):
    """The zero-crossing functions at the uniform samples of the step's dense output into ev.samples: what
    locate_events' first pass computes (numpy.linspace instants, the same dense output), handed to it with a
    candidate (shell.compiled_run)."""
    n = SUBDIVISIONS
    h = t_new - t_old
    step = (t_new - t_old) / n  # numpy.linspace(t_old, t_new, n + 1)
    IC.prepare_dense(st, ev)
    copy_into(ev.samples[0], ev.g_old)
    copy_into(ev.samples[n], ev.g_new)
    for j in range(1, n):
        t_j = j * step + t_old
        IC.dense(st, ev, (t_j - t_old) / h, h, ev.y_mid)
        _zero_crossings_at(system, t_j, ev.y_mid, ev.samples[j])


@njit(cache=True)
def _event_candidate(system, st, ev, t_old, t_new, search):
    """Would locate_events report a crossing in this step (before the simulation's filter of just-handled
    events)? With ``search`` (subdivided detection, the step after an event) the same samples and tests (the
    parabola test answers yes whenever Python would evaluate the extremum), else the sign change of the ends; a
    candidate carries its samples to Python."""
    m = ev.g_old.shape[0]
    n = SUBDIVISIONS
    if not search:
        if not _crossed(ev):
            return False
        _dense_samples(system, st, ev, t_old, t_new)
        return True
    _dense_samples(system, st, ev, t_old, t_new)
    return _samples_flag_candidate(ev, m, n, (t_new - t_old) / n, t_old, t_new)


# phases of events_at
EVENTS_START = 0         # the functions' values at the start of the steps
EVENTS_STEP = 1          # after a step: a sign change of a function between the step's ends is a candidate
EVENTS_SEARCH = 2        # after a step: the subdivided search of the step's dense output


@njit(cache=True)
def events_at(system_reference, stepper_reference, events_reference, phase, t_old, t):
    """The zero-crossing checks of a run with events (the stepper at ``t``): the functions' values at the start
    (EVENTS_START), or after a step from ``t_old``: their values at its end, and whether a crossing may lie inside it
    (:func:`_event_candidate`; otherwise the end's values become the next step's start's). The loop calls it
    through a function pointer (:func:`event_check`), so a scene without zero crossings does not compile it."""
    system = _dereference(system_reference)
    st = _dereference(stepper_reference)
    ev = _dereference(events_reference)
    if phase == EVENTS_START:
        _zero_crossings_at(system, t, st.Y, ev.g_old)
        return False
    _zero_crossings_at(system, t, st.Y, ev.g_new)
    if _event_candidate(system, st, ev, t_old, t, phase == EVENTS_SEARCH):
        return True
    copy_into(ev.g_old, ev.g_new)
    return False


def _events_signature(system_type, stepper_type, events_type):
    return types.boolean(types.CPointer(system_type), types.CPointer(stepper_type), types.CPointer(events_type),
                         types.int64, types.float64, types.float64)


@intrinsic
def _events_function(typingctx, c_address, jit_address, system_reference, stepper_reference, events_reference):
    """:func:`events_at` at (cfunc wrapper address, numba entry address) for the types of the references."""
    function_type = types.FunctionType(_events_signature(system_reference.dtype, stepper_reference.dtype,
                                                         events_reference.dtype))

    def codegen(context, builder, sig, args):
        return _function_struct(function_type, context, builder, args)

    return function_type(types.int64, types.int64, system_reference, stepper_reference, events_reference), codegen


def event_check(kernels, buffers, stepper, events) -> np.ndarray:
    """``Events.check`` of a run with zero crossings: :func:`events_at` compiled for the types of its system, its
    stepper and ``events`` (compiled or loaded here, once per stepper type)."""
    from numba import typeof
    from numba.experimental.function_type import _get_jit_address, _get_wrapper_address

    signature = _events_signature(typeof(System(kernels, buffers)), typeof(stepper), typeof(events))
    events_at.compile(signature.args)
    return np.array([_get_wrapper_address(events_at, signature), _get_jit_address(events_at, signature)],
                    dtype=np.int64)


@njit(cache=True)
def _integrate(system, st, ev, target, ints, reals, skip_final):
    """Steps of the run's method from reals[R_T] to ``target`` (the Python loop's _advance, the same arithmetic);
    the last step lands on ``target`` (shortened; a remainder within 1e-9 h of a full step is one step). Returns 0
    or a status (a failure, an event candidate, a request of the method)."""
    X = system.buffers.X
    t = reals[R_T]
    status = IC.start(system, st, t, ints, reals)
    if status != 0:  # the context's state is untouched
        return status
    events = ev.mode != NO_EVENTS
    if events:
        system_reference, stepper_reference, events_reference = (_by_reference(system), _by_reference(st),
                                                                  _by_reference(ev))
        check = _events_function(ev.check[0], ev.check[1], system_reference, stepper_reference, events_reference)
        check(system_reference, stepper_reference, events_reference, EVENTS_START, t, t)
    h0 = st.h
    while t < target:
        remaining = target - t
        last = remaining <= h0 * (1.0 + 1e-9)
        h = remaining if last else h0
        t_new = target if last else t + h
        skip = last and skip_final  # an update follows at target, then a restart: no slope at the end
        status = IC.step(system, st, t, h, t_new, skip, ints, reals)
        if status != 0:
            reals[R_T] = t
            if status == STEP_FAILED:
                reals[R_T_OLD] = t
            else:  # the method stopped before its step: the run's state is its state
                copy_into(X, st.Y)
            return status
        if events:
            IC.keep(st, ev)
        IC.accept(st, ints, skip)
        reals[R_T_OLD] = t
        t_old = t
        t = t_new
        ints[I_STEPS] += 1
        if t >= target:
            t = target
        if skip:
            break
        if events:
            search = ev.mode == SUBDIVIDED or t_old == reals[R_LAST_EVENT]
            if check(system_reference, stepper_reference, events_reference, EVENTS_SEARCH if search else EVENTS_STEP,
                     t_old, t):
                reals[R_T] = t
                copy_into(X, st.Y)
                return EVENT_CANDIDATE
    reals[R_T] = t
    copy_into(X, st.Y)
    return 0


@njit(cache=True)
def _log_instant(system, sc, ints, reals, write):
    """Rows of the log groups due at the current instant (one evaluation of the stages they need first)."""
    b = system.buffers
    now = ints[I_NOW]
    t = reals[R_T]
    evaluated = False
    for g in range(sc.log_next.shape[0]):
        if sc.log_next[g] != now:
            continue
        if write:
            if not evaluated:
                run_stages(sc.log_stage_ops, sc.log_stage_ops.shape[0], system.kernels, b, t, b.src, b.fac)
                gather_all(b, b.src, b.fac)
                evaluated = True
            row = sc.log_count[g]
            sc.log_times[g, row] = t
            width = 0
            for e in range(sc.log_start[g], sc.log_start[g + 1]):
                kind = sc.log_kind[e]
                j = sc.log_index[e]
                value = b.S[j] if kind == 0 else (b.X[j] if kind == 1 else b.Z[j])
                sc.log_rows[g, row, width] = value
                width += 1
            sc.log_count[g] = row + 1
        sc.log_next[g] += sc.log_period[g]


@njit(cache=True)
def advance(k, b, st, ev, sc, ints, reals, budget, write_logs, integrate):
    """Run instants until the end tick, a return to Python, or ``budget`` instants (see the module docstring).

    ``ints[I_PHASE]`` 1: the updates at the current instant were done by the caller; continue with its
    logging. ``integrate``: the scene has continuous states.

    The context's arrays are used as borrowed references inside (``dynamics.engine.borrowed``): the
    caller's context owns them for the whole call, and passing the tuples between the loop's functions
    otherwise costs an atomic increment and decrement per array and call."""
    k, b, st, ev, sc = borrowed((k, b, st, ev, sc))
    system = System(k, b)
    instants = 0
    while True:
        if ints[I_PHASE] == 0:
            nxt = sc.end
            for i in sc.order:
                if sc.next_tick[i] < nxt:
                    nxt = sc.next_tick[i]
            for g in range(sc.log_next.shape[0]):
                if sc.log_next[g] < nxt:
                    nxt = sc.log_next[g]
            target = _instant_time(nxt, sc.den)
            if integrate and target > reals[R_T]:
                update_due = False
                for i in sc.order:
                    if sc.next_tick[i] == nxt:
                        update_due = True
                status = _integrate(system, st, ev, target, ints, reals, update_due and ev.mode == NO_EVENTS)
                if status != 0:
                    return status
            reals[R_T] = target
            ints[I_NOW] = nxt
            for i in sc.order:
                if sc.next_tick[i] == nxt and b.update_ops[i, KIND] == UPDATE_PYTHON:
                    ints[I_PHASE] = 1
                    return PYTHON_UPDATE
            updated = False
            for i in sc.order:
                if sc.next_tick[i] == nxt:
                    update_model_alone(i, system, target)
                    sc.next_tick[i] += sc.period[i]
                    ints[I_UPDATES] += 1
                    updated = True
            if updated:
                ints[I_F_VALID] = 0
                if not (all_finite(b.X) and all_finite(b.Z)):
                    return UPDATE_FAILED
        ints[I_PHASE] = 0
        _log_instant(system, sc, ints, reals, write_logs)
        instants += 1
        if ints[I_NOW] >= sc.end:
            return DONE
        for g in range(sc.log_count.shape[0]):
            if sc.log_count[g] == sc.log_times.shape[1]:
                return LOG_FULL
        if instants >= budget:
            return BUDGET
