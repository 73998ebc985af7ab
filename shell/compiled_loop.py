"""One compiled loop that runs any scene: the diagram's plan as arrays, the model kernels as function pointers.

The interpreted loop (:mod:`shell.diagram`, :mod:`shell.simulation`) calls each model kernel from Python:
about a microsecond of dispatch per kernel, many per derivative. Here the same sequence runs inside numba:

* the plan (evaluation order, gather ranges, each model's slices of ``x``, ``z``, the signal buffer and
  the packed parameters) is encoded as integer *op* tables (:class:`shell.compiled_plan.CompiledPlan`);
* every model kernel of the uniform signature is passed as a function pointer (the addresses numba
  gives a compiled function, in an int64 table) and called through it: an indirect call of ~10 ns,
  no Python; the engine model's kernels, which also take the engine's arrays (:mod:`dynamics.engine`,
  one data tuple of a fixed type), are called the same way;
* :func:`advance` integrates with a fixed-step explicit Runge-Kutta method (or the exponential RK4,
  ``etdrk4``: see "Exponential RK4 in the loop" below) from one sample instant to the next, runs the sampled models' updates at integer ticks of a common time base (their noise drawn from
  each model's own ``numpy.random.Generator``, bit-identical to the interpreted draws), writes log rows
  into preallocated buffers, and returns to Python only to run Python-only models, flush full log
  buffers, report progress, or report a failure.

Because the plan and the kernels are data (arrays of offsets and of addresses), this module is compiled
once per installation (numba's on-disk cache) and serves every scene: a new scene costs no compilation,
and the loop's compiled code does not contain the engine or any model (each is compiled and cached on
its own). The arithmetic is that of the interpreted path
operation for operation (same kernels, same Runge-Kutta combinations from
:mod:`shell.integrators.kernels`, same quaternion normalization, instants ``k / den`` rounded as Python's
``float(Fraction)``), so the two give the same numbers; tests check it.

Op table columns (int64): ``KIND, FN, G0, G1, X0, X1, Z0, Z1, U0, U1, P0, P1, O0, O1, N0, N1, RNG``:
the kind of call, the function or engine index, the feedthrough gather range, the model's slices of
``x``, ``z``, the signal buffer (inputs), the parameters, its output range (outputs in the signal buffer,
derivatives in ``xdot``, zero crossings in ``g``), the noise buffer range and random stream of a noisy
update.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit

from numba import typeof, types
from numba.core import cgutils
from numba.extending import intrinsic, overload
from numba.np.arrayobj import make_array, populate_array

from dynamics.engine import borrowed
from shell.integrators import exponential as EX
from shell.integrators.kernels import all_finite, copy_into, hermite_cubic, propagate, stage_state
from shell.models.multibody import DERIVATIVES as E_DERIVATIVES
from shell.models.multibody import DERIVATIVES_AFTER_FEEDTHROUGH as E_DERIVATIVES_REUSE
from shell.models.multibody import FEEDTHROUGH_OUTPUTS as E_FEEDTHROUGH
from shell.models.multibody import NORMALIZE as E_NORMALIZE
from shell.models.multibody import STATE_OUTPUTS as E_STATE
from shell.models.multibody import probe_engine_data

_ARRAY = types.float64[::1]
#: output, derivative and zero-crossing kernels, and updates with noise: kernel(t, x, z, u, p, out)
KERNEL_SIGNATURE = types.void(types.float64, _ARRAY, _ARRAY, _ARRAY, _ARRAY, _ARRAY)
#: updates without noise: update(t, x, z, u, p)
UPDATE_SIGNATURE = types.void(types.float64, _ARRAY, _ARRAY, _ARRAY, _ARRAY)
#: the engine model's data (dynamics.engine.EngineData, ports, work) as numba types it
ENGINE_DATA = typeof(probe_engine_data())
#: the engine model's kernel: engine_kernel(op, t, x, z, u, p, d, out) (shell.models.multibody)
ENGINE_SIGNATURE = types.void(types.int64, types.float64, _ARRAY, _ARRAY, _ARRAY, _ARRAY, ENGINE_DATA, _ARRAY)
#: slots of the random-stream tuple (models with noise_size in one scene)
MAX_NOISY_MODELS = 8


def _pointer_intrinsic(signature):
    """An intrinsic turning (cfunc wrapper address, numba entry address) into a callable first-class
    function of ``signature`` (numba's FunctionType struct; the call goes through the numba entry)."""
    function_type = types.FunctionType(signature)

    @intrinsic
    def as_function(typingctx, c_address, jit_address):
        def codegen(context, builder, sig, args):
            value = cgutils.create_struct_proxy(function_type)(context, builder)
            pointer = context.get_value_type(types.voidptr)
            value.c_addr = builder.inttoptr(args[0], pointer)
            value.py_addr = cgutils.get_null_value(pointer)
            value.jit_addr = builder.inttoptr(args[1], pointer)
            return value._getvalue()

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
        source = make_array(sig.args[0])(context, builder, args[0])
        view = make_array(view_type)(context, builder)
        itemsize = source.itemsize
        populate_array(view, data=builder.gep(source.data, [args[1]]),
                       shape=cgutils.pack_array(builder, [builder.sub(args[2], args[1])]),
                       strides=cgutils.pack_array(builder, [itemsize]), itemsize=itemsize, meminfo=None)
        return view._getvalue()

    return view_type(array, types.intp, types.intp), codegen


_kernel = _pointer_intrinsic(KERNEL_SIGNATURE)
_update_kernel = _pointer_intrinsic(UPDATE_SIGNATURE)
_engine_kernel = _pointer_intrinsic(ENGINE_SIGNATURE)

# op table columns
KIND, FN, G0, G1, X0, X1, Z0, Z1, U0, U1, P0, P1, O0, O1, N0, N1, RNG = range(17)
OP_COLUMNS = 17

# op kinds
PLAIN = 0                # fns[FN](t, x, z, u, p, out)
ENGINE_STATE = 1         # engine state outputs
ENGINE_FEEDTHROUGH = 2   # engine feedthrough outputs (forward dynamics, node accelerations)
ENGINE_DERIVATIVES = 3
ENGINE_DERIVATIVES_REUSE = 4  # after the engine's feedthrough stage in the same evaluation
UPDATE = 5               # update_fns[FN](t, x, z, u, p)
UPDATE_NOISE = 6         # noise from rngs[RNG] into noise[N0:N1], then fns[FN](t, x, z, u, p, noise)
UPDATE_PYTHON = 7        # the update runs in Python: advance returns to the caller

# advance status
DONE = 0
PYTHON_UPDATE = 1        # a Python-only model is due at the current instant (no update done there yet)
LOG_FULL = 2             # a log buffer is full (after logging at the current instant)
BUDGET = 3               # the instant budget of this call is spent (after a whole instant)
STEP_FAILED = 4          # a step produced a non-finite state or derivative
START_FAILED = 5         # the derivative at the start of an interval is not finite
UPDATE_FAILED = 6        # a discrete update left a non-finite state
EVENT_CANDIDATE = 7      # a zero-crossing function may cross inside the last step: Python locates it

# zero-crossing detection modes
NO_EVENTS = 0
SIGN_CHANGE = 1          # search a step when a function changes sign between its ends
SUBDIVIDED = 2           # search every step on its dense output (shell.integrators.events)
SUBDIVISIONS = 8         # the subdivisions of shell.integrators.locate_events

# integer registers of advance (ints array)
I_NOW, I_F_VALID, I_STEPS, I_NFEV, I_UPDATES, I_PHASE, I_FAILED_STAGE = range(7)
# the exponential stepper's (see "Exponential RK4 in the loop" below)
I_SINCE_CHECK, I_CHECK_INTERVAL, I_STEP_FLAGS = range(7, 10)
N_INTS = 10
# float registers (reals array)
R_T, R_FAILED_T, R_T_OLD, R_LAST_EVENT = range(4)
R_PHI_H, R_RHO = range(4, 6)  # the exponential stepper's: h of its eigenbasis phi functions, last h rho(N)
N_REALS = 6


class Buffers(NamedTuple):
    """The context's buffers and the plan's op tables (arrays only: a fast argument for numba)."""

    X: np.ndarray
    Z: np.ndarray
    S: np.ndarray
    P: np.ndarray
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
    normalize_ops: np.ndarray   # engine index, x0 of each engine model with quaternions
    input_stage_ops: np.ndarray  # per sampled model, the stages its inputs need (Diagram.input_stages)
    zc_stage_ops: np.ndarray    # the stages the zero-crossing functions need


class Stepper(NamedTuple):
    """A fixed-step explicit Runge-Kutta method and its work arrays."""

    A: np.ndarray
    b: np.ndarray
    c: np.ndarray
    n_stages: int
    h: float
    Y: np.ndarray
    F: np.ndarray
    K: np.ndarray
    YS: np.ndarray
    YN: np.ndarray


class Events(NamedTuple):
    """Zero-crossing detection: the mode, each function's direction, values at the ends of the last step
    and at the subdivision samples, the last step's start (for its dense output)."""

    mode: int
    direction: np.ndarray    # (m,) int64: +1 rising only, -1 falling only, 0 both
    g_old: np.ndarray        # (m,)
    g_new: np.ndarray        # (m,)
    samples: np.ndarray      # (SUBDIVISIONS + 1, m)
    y_old: np.ndarray        # state and slope at the start of the last step
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


class Kernels(NamedTuple):
    """Function pointers ([cfunc wrapper address, numba entry address] rows) of the plan's kernels."""

    fns: np.ndarray          # (n, 2) KERNEL_SIGNATURE
    update_fns: np.ndarray   # (m, 2) UPDATE_SIGNATURE
    engine_fn: np.ndarray    # (2,) the engine model's kernel


@njit(cache=True)
def run_stages(ops, n_ops, k, engine, t, b, src, fac):
    """Output stages ``ops[:n_ops]``: gather each model's feedthrough inputs, then call its kernel."""
    S = b.S
    dst = b.dst
    for r in range(n_ops):
        for g in range(ops[r, G0], ops[r, G1]):
            S[dst[g]] = fac[g] * S[src[g]]
        kind = ops[r, KIND]
        x = _view(b.X, ops[r, X0], ops[r, X1])
        z = _view(b.Z, ops[r, Z0], ops[r, Z1])
        u = _view(S, ops[r, U0], ops[r, U1])
        p = _view(b.P, ops[r, P0], ops[r, P1])
        y = _view(S, ops[r, O0], ops[r, O1])
        if kind == PLAIN:
            f = ops[r, FN]
            _kernel(k.fns[f, 0], k.fns[f, 1])(t, x, z, u, p, y)
        else:
            _engine_kernel(k.engine_fn[0], k.engine_fn[1])(E_STATE if kind == ENGINE_STATE else E_FEEDTHROUGH, t, x,
                                                           z, u, p, engine, y)


@njit(cache=True)
def gather_all(b, src, fac):
    S = b.S
    dst = b.dst
    for g in range(dst.shape[0]):
        S[dst[g]] = fac[g] * S[src[g]]


@njit(cache=True)
def evaluate_full(k, engine, t, b, src, fac):
    """Every output, then every input (the interpreted ``Diagram.evaluate``)."""
    run_stages(b.full_ops, b.full_ops.shape[0], k, engine, t, b, src, fac)
    gather_all(b, src, fac)


@njit(cache=True)
def derivatives(k, engine, t, b, src, fac):
    """``b.XD = f(t, b.X)`` (the interpreted ``Diagram.derivatives``)."""
    ops = b.derivative_ops
    n_stages = b.n_derivative_stages
    run_stages(ops, n_stages, k, engine, t, b, src, fac)
    gather_all(b, src, fac)
    S = b.S
    for r in range(n_stages, ops.shape[0]):
        kind = ops[r, KIND]
        x = _view(b.X, ops[r, X0], ops[r, X1])
        z = _view(b.Z, ops[r, Z0], ops[r, Z1])
        u = _view(S, ops[r, U0], ops[r, U1])
        p = _view(b.P, ops[r, P0], ops[r, P1])
        xdot = _view(b.XD, ops[r, O0], ops[r, O1])
        if kind == PLAIN:
            f = ops[r, FN]
            _kernel(k.fns[f, 0], k.fns[f, 1])(t, x, z, u, p, xdot)
        else:
            _engine_kernel(k.engine_fn[0], k.engine_fn[1])(E_DERIVATIVES if kind == ENGINE_DERIVATIVES else
                                                           E_DERIVATIVES_REUSE, t, x, z, u, p, engine, xdot)


@njit(cache=True)
def derivative_at(k, engine, t, y, b, src, fac):
    """``f(t, y)`` into ``b.XD`` (``b.X`` is overwritten with ``y``)."""
    copy_into(b.X, y)
    derivatives(k, engine, t, b, src, fac)


@njit(cache=True)
def zero_crossings(k, engine, t, b, src, fac):
    """Every zero-crossing function into ``b.G`` after evaluating the outputs they need."""
    run_stages(b.zc_stage_ops, b.zc_stage_ops.shape[0], k, engine, t, b, src, fac)
    gather_all(b, src, fac)
    ops = b.zc_ops
    S = b.S
    for r in range(ops.shape[0]):
        f = ops[r, FN]
        _kernel(k.fns[f, 0], k.fns[f, 1])(t, _view(b.X, ops[r, X0], ops[r, X1]), _view(b.Z, ops[r, Z0], ops[r, Z1]),
                                          _view(S, ops[r, U0], ops[r, U1]), _view(b.P, ops[r, P0], ops[r, P1]),
                                          _view(b.G, ops[r, O0], ops[r, O1]))


@njit(cache=True)
def update_model(i, k, engine, rngs, t, b):
    """Evaluate the outputs model ``i``'s inputs need, then run its compiled update (drawing its noise
    first, from its slot of ``rngs``)."""
    update_model_alone(i, k, engine, rngs[b.update_ops[i, RNG]], t, b)


@njit(cache=True)
def update_model_alone(i, k, engine, rng, t, b):
    """Model ``i``'s update given only its own random stream (any generator when it draws no noise): what
    :func:`update_model` runs, and what a Python caller (a loop whose integrator stays in Python) calls
    directly, since unboxing the tuple of every model's stream costs more than most updates."""
    ops = b.update_ops
    run_stages(b.input_stage_ops[ops[i, G0]:ops[i, G1]], ops[i, G1] - ops[i, G0], k, engine, t, b, b.src, b.fac)
    gather_all(b, b.src, b.fac)
    x = _view(b.X, ops[i, X0], ops[i, X1])
    z = _view(b.Z, ops[i, Z0], ops[i, Z1])
    u = _view(b.S, ops[i, U0], ops[i, U1])
    p = _view(b.P, ops[i, P0], ops[i, P1])
    f = ops[i, FN]
    if ops[i, KIND] == UPDATE:
        _update_kernel(k.update_fns[f, 0], k.update_fns[f, 1])(t, x, z, u, p)
    else:
        noise = _view(b.noise, ops[i, N0], ops[i, N1])
        for n in range(noise.shape[0]):
            noise[n] = rng.standard_normal()
        _kernel(k.fns[f, 0], k.fns[f, 1])(t, x, z, u, p, noise)


@njit(cache=True)
def normalize(k, engine, b, y):
    """Renormalize the hinge quaternions of state ``y`` (the interpreted ``Diagram.normalize``)."""
    ops = b.normalize_ops
    for r in range(ops.shape[0]):
        x = _view(y, ops[r, 1], ops[r, 2])
        _engine_kernel(k.engine_fn[0], k.engine_fn[1])(E_NORMALIZE, 0.0, x, x, x, x, engine, x)


@njit(cache=True)
def _instant_time(tick, den):
    # float(Fraction(tick, den)): both exact in binary64 (checked by the caller), the quotient correctly rounded
    return float(tick) / float(den)


@njit(cache=True)
def _zero_crossings_at(k, engine, t, y, b, out):
    copy_into(b.X, y)
    zero_crossings(k, engine, t, b, b.src, b.fac)
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
def _event_candidate(k, engine, b, ev, t_old, t_new, y_new, f_new, subdivided):
    """Would shell.integrators.locate_events report a crossing in this step (before the simulation's
    filter of just-handled events)? The same samples, the same tests; the parabola test answers yes
    whenever Python would evaluate the extremum."""
    m = ev.g_old.shape[0]
    if not subdivided:  # Simulation._crossed: a sign change between the ends, in a counted direction
        for j in range(m):
            a, c = ev.g_old[j], ev.g_new[j]
            if a == 0.0:
                continue
            if c == 0.0 or (a < 0.0) != (c < 0.0):
                rising = c > a
                if ev.direction[j] == 0 or (ev.direction[j] > 0) == rising:
                    return True
        return False
    n = SUBDIVISIONS
    h = t_new - t_old
    step = (t_new - t_old) / n  # numpy.linspace(t_old, t_new, n + 1)
    copy_into(ev.samples[0], ev.g_old)
    copy_into(ev.samples[n], ev.g_new)
    for j in range(1, n):
        t_j = j * step + t_old
        hermite_cubic((t_j - t_old) / h, h, ev.y_old, ev.f_old, y_new, f_new, ev.y_mid)
        _zero_crossings_at(k, engine, t_j, ev.y_mid, b, ev.samples[j])
    return _samples_flag_candidate(ev, m, n, step, t_old, t_new)


@njit(cache=True)
def _integrate(k, engine, b, st, ev, target, ints, reals, skip_final):
    """Fixed-step Runge-Kutta from reals[R_T] to ``target`` (FixedStepRungeKutta._step_impl, the same
    arithmetic), with the zero-crossing checks of Simulation._advance; returns 0 or a status."""
    Y, F, K, YS, YN = st.Y, st.F, st.K, st.YS, st.YN
    t = reals[R_T]
    if ints[I_F_VALID] == 0:  # a restart from the context's state: Integrator.reset (normalize, derivative)
        copy_into(Y, b.X)
        normalize(k, engine, b, Y)
        derivative_at(k, engine, t, Y, b, b.src, b.fac)
        ints[I_NFEV] += 1
        if not all_finite(b.XD):
            return START_FAILED
        copy_into(F, b.XD)
        ints[I_F_VALID] = 1
    if ev.mode != NO_EVENTS:
        _zero_crossings_at(k, engine, t, Y, b, ev.g_old)
    h = st.h
    s = st.n_stages
    while t < target:
        remaining = target - t
        hh = h
        last = remaining <= h * (1.0 + 1e-9)
        if last:
            hh = remaining
        copy_into(K[0], F)
        for i in range(1, s):
            stage_state(Y, K, st.A[i], i, hh, YS)
            derivative_at(k, engine, t + st.c[i] * hh, YS, b, b.src, b.fac)
            copy_into(K[i], b.XD)
        ints[I_NFEV] += s - 1
        t_new = target if last else t + hh
        if not propagate(Y, K, st.b, s, hh, YN):
            reals[R_FAILED_T] = t_new
            reals[R_T_OLD] = t
            reals[R_T] = t
            ints[I_FAILED_STAGE] = 0
            return STEP_FAILED
        normalize(k, engine, b, YN)
        if last and skip_final:  # an update follows at target, then a restart: no slope at the end
            copy_into(Y, YN)
            reals[R_T_OLD] = t
            t = target
            ints[I_STEPS] += 1
            ints[I_F_VALID] = 0
            break
        derivative_at(k, engine, t_new, YN, b, b.src, b.fac)
        ints[I_NFEV] += 1
        if not all_finite(b.XD):
            reals[R_FAILED_T] = t_new
            reals[R_T_OLD] = t
            reals[R_T] = t
            ints[I_FAILED_STAGE] = 1
            return STEP_FAILED
        if ev.mode != NO_EVENTS:
            copy_into(ev.y_old, Y)
            copy_into(ev.f_old, F)
        copy_into(Y, YN)
        copy_into(F, b.XD)
        reals[R_T_OLD] = t
        t_old = t
        t = t_new
        ints[I_STEPS] += 1
        if t >= target:
            t = target
        if ev.mode != NO_EVENTS:
            _zero_crossings_at(k, engine, t, Y, b, ev.g_new)
            search = ev.mode == SUBDIVIDED or t_old == reals[R_LAST_EVENT]
            if _event_candidate(k, engine, b, ev, t_old, t, Y, F, search):
                reals[R_T] = t
                copy_into(b.X, Y)
                return EVENT_CANDIDATE
            copy_into(ev.g_old, ev.g_new)
    reals[R_T] = t
    copy_into(b.X, Y)
    return 0


@njit(cache=True)
def _log_instant(k, engine, b, sc, ints, reals, write):
    """Rows of the log groups due at the current instant (one full evaluation first)."""
    now = ints[I_NOW]
    t = reals[R_T]
    evaluated = False
    for g in range(sc.log_next.shape[0]):
        if sc.log_next[g] != now:
            continue
        if write:
            if not evaluated:
                run_stages(sc.log_stage_ops, sc.log_stage_ops.shape[0], k, engine, t, b, b.src, b.fac)
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
def advance(k, engine, rngs, b, st, ev, sc, ints, reals, budget, write_logs, integrate):
    """Run instants until the end tick, a return to Python, or ``budget`` instants (see the module docstring).

    ``ints[I_PHASE]`` 1: the updates at the current instant were done by the caller; continue with its
    logging. ``integrate``: the scene has continuous states.

    The context's arrays are used as borrowed references inside (``dynamics.engine.borrowed``): the
    caller's context owns them for the whole call, and passing the tuples between the loop's functions
    otherwise costs an atomic increment and decrement per array and call."""
    k, engine, b, st, ev, sc = borrowed((k, engine, b, st, ev, sc))
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
                status = _step_to(k, engine, b, st, ev, target, ints, reals, update_due and ev.mode == NO_EVENTS)
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
                    update_model(i, k, engine, rngs, target, b)
                    sc.next_tick[i] += sc.period[i]
                    ints[I_UPDATES] += 1
                    updated = True
            if updated:
                ints[I_F_VALID] = 0
                if not (all_finite(b.X) and all_finite(b.Z)):
                    return UPDATE_FAILED
        ints[I_PHASE] = 0
        _log_instant(k, engine, b, sc, ints, reals, write_logs)
        instants += 1
        if ints[I_NOW] >= sc.end:
            return DONE
        for g in range(sc.log_count.shape[0]):
            if sc.log_count[g] == sc.log_times.shape[1]:
                return LOG_FULL
        if instants >= budget:
            return BUDGET


# ----------------------------------------------------------------------------------------------------------
# Exponential RK4 in the loop: Krogstad's scheme (shell.integrators.exponential.ExponentialRK4) stepped here,
# with the same njit stage products (stage_real / stage_eigen), the same remainder N = f - L y, the same order of
# operations and the same lazy slope, so that the compiled and the interpreted runs agree bit for bit. Python
# keeps what must be Python: the callable linear part (a mass matrix and a Cholesky solve in the models'
# ``stiff_linear_part``) and the rebuild of the matrix functions. The loop keeps the integrator's check counters
# (ints[I_SINCE_CHECK], ints[I_CHECK_INTERVAL]) and returns LINEAR_CHECK when a check of the linear part is due
# (after 1, 2, 4, ... 64 steps: one return per 64 steps once the part stands still) and STIFF_REMAINDER when a
# step finds the remainder stiff (h rho(N) > 1); Python checks (and perhaps rebuilds the stepper) and calls
# advance again, which continues the step where it stopped (ints[I_STEP_FLAGS]). Events: as for the Runge-Kutta
# methods, the loop decides whether locate_events would find a crossing in the step (the ends with sign_change
# detection; samples of the dense output with subdivided detection and on the step right after an event),
# and Python locates it on the method's own dense output (ExponentialDenseOutput from ``N`` and the step's
# start, kept in ``Events.y_old``; both evaluate the compiled exponential.dense_state).
# ----------------------------------------------------------------------------------------------------------

LINEAR_CHECK = 8         # a check of the callable linear part is due before the step from reals[R_T]
STIFF_REMAINDER = 9      # the step from reals[R_T] found h rho(N) > STIFF_REMAINDER_BOUND (rho in R_RHO)
NEW_INTEGRATOR = 10      # the stepper is a placeholder: Python makes the integrator at (reals[R_T], b.X)

# ints[I_STEP_FLAGS] bits: this step's scheduled check was done, its stiffness was handled (no more checks in
# this step), continue it at stage 4 (the stages before are kept in S and N)
CHECK_DONE, STIFF_DONE, RESUME = 1, 2, 4
# ints[I_F_VALID] of the exponential stepper: 0 restart from the context's x, 1 F = f(t, Y), 2 Y current, F due
F_DUE = 2


class ExponentialStepper(NamedTuple):
    """Krogstad's exponential RK4 (shell.integrators.exponential) as arrays: the state, the stage and remainder
    work arrays, the linear part and its matrix functions (built in Python by ExponentialRK4)."""

    h: float
    Y: np.ndarray            # (n,) the state at reals[R_T]
    F: np.ndarray            # (n,) f(t, Y) when ints[I_F_VALID] == 1
    YN: np.ndarray           # (n,) the new state; after a failure the offending state
    S: np.ndarray            # (4, n) stage states Y2, Y3, Y4 and the propagated state
    N: np.ndarray            # (4, n) remainders N1..N4 (the last step's: its dense output)
    W: np.ndarray            # (3, n) term vectors
    no_base: np.ndarray      # (0,)
    indices: np.ndarray      # (m,) int64 the linear part's components
    L: np.ndarray            # (m, m)
    L_norm: float
    is_linear: np.ndarray    # (n,) bool
    Phi: tuple               # 4 stage matrices phi_k(c h L) side by side (ExponentialRK4.Phi_stages)
    stage_base: np.ndarray   # (4,) int64: -1 or the stage state added (exponential.STAGES)
    stage_terms: np.ndarray  # (4,) int64
    stage_functions: np.ndarray     # (4, 3) int64
    stage_coefficients: np.ndarray  # (4, 3, 5)
    phi_at_zero: np.ndarray  # (7,)
    phi_c: np.ndarray        # (7,) c of exponential.FUNCTIONS
    phi_k: np.ndarray        # (7,) int64 k of exponential.FUNCTIONS
    c_nodes: np.ndarray      # (3,)
    y_lin: np.ndarray        # (m,) scratch
    product: np.ndarray      # (m,)
    w_stack: np.ndarray      # (3 m,)
    V: np.ndarray            # (m, m) complex: eigenvectors (shortened steps)
    Vinv: np.ndarray
    lam: np.ndarray          # (m,) complex eigenvalues
    phi_diag: np.ndarray     # (7, m) complex phi_k(c h lambda) at h = reals[R_PHI_H]
    phi_work: np.ndarray     # (4, m) complex
    z_work: np.ndarray       # (m,) complex
    z_acc: np.ndarray
    z_in: np.ndarray
    z_out: np.ndarray
    dense_n: np.ndarray      # (3, n) the last step's dense output: its quadratic in N
    dense_z: np.ndarray      # (4, m) complex: its eigenbasis coordinates
    check_drift: bool        # the linear part is a callable to re-check (the shell's always is)


def exponential_stepper(integ, Y=None, F=None):
    """The :class:`ExponentialStepper` of an :class:`shell.integrators.ExponentialRK4` (its current linear part
    and nominal step); ``Y``, ``F`` carried over from a previous stepper (a rebuild), else the integrator's."""
    part, n = integ.part, integ.n
    m = part.m
    base = np.array([stage[0] for stage in EX.STAGES], dtype=np.int64)
    terms = np.array([stage[1].shape[0] for stage in EX.STAGES], dtype=np.int64)
    functions = np.zeros((4, 3), dtype=np.int64)
    coefficients = np.zeros((4, 3, 5))
    for j, (_, fn, co) in enumerate(EX.STAGES):
        functions[j, :fn.shape[0]] = fn
        coefficients[j, :fn.shape[0]] = co
    complex_m = (lambda: np.zeros(m, dtype=np.complex128))
    V = np.ascontiguousarray(part.V, dtype=np.complex128)
    Vinv = np.ascontiguousarray(part.Vinv, dtype=np.complex128)
    lam = np.ascontiguousarray(part.lam, dtype=np.complex128)
    return ExponentialStepper(
        float(integ.h), (integ.y if Y is None else Y).copy(), (integ.f if F is None else F).copy(), np.zeros(n),
        np.zeros((4, n)), np.zeros((4, n)), np.zeros((3, n)), np.zeros(0), part.indices.astype(np.int64),
        np.ascontiguousarray(part.L), float(part.L_norm), part.is_linear.copy(),
        tuple(np.ascontiguousarray(P, dtype=np.float64).reshape(P.shape if m else (0, 0)) for P in integ.Phi_stages),
        base, terms, functions, coefficients, EX.PHI_AT_ZERO.copy(), np.array([c for c, _ in EX.FUNCTIONS]),
        np.array([k for _, k in EX.FUNCTIONS], dtype=np.int64), np.array(EX.C_NODES), np.zeros(m), np.zeros(m),
        np.zeros(3 * m), V, Vinv, lam, np.zeros((len(EX.FUNCTIONS), m), dtype=np.complex128),
        np.zeros((4, m), dtype=np.complex128), complex_m(), complex_m(), complex_m(), complex_m(), np.zeros((3, n)),
        np.zeros((4, m), dtype=np.complex128), bool(callable(integ.linear_part_option)))


def exponential_placeholder(n):
    """A stepper of the right type with step 0: the loop asks Python for the integrator before using it."""
    empty_c = np.zeros(0, dtype=np.complex128)
    return ExponentialStepper(
        0.0, np.zeros(n), np.zeros(n), np.zeros(n), np.zeros((4, n)), np.zeros((4, n)), np.zeros((3, n)), np.zeros(0),
        np.zeros(0, dtype=np.int64), np.zeros((0, 0)), 0.0, np.zeros(n, dtype=np.bool_), (np.zeros((0, 0)),) * 4,
        np.zeros(4, dtype=np.int64), np.zeros(4, dtype=np.int64), np.zeros((4, 3), dtype=np.int64),
        np.zeros((4, 3, 5)), np.zeros(7), np.zeros(7), np.zeros(7, dtype=np.int64), np.zeros(3), np.zeros(0),
        np.zeros(0), np.zeros(0), np.zeros((0, 0), dtype=np.complex128), np.zeros((0, 0), dtype=np.complex128),
        empty_c, np.zeros((7, 0), dtype=np.complex128), np.zeros((4, 0), dtype=np.complex128), empty_c, empty_c,
        empty_c, empty_c, np.zeros((3, n)), np.zeros((4, 0), dtype=np.complex128), False)


@njit(cache=True)
def _exponential_phi_diagonal(st, h):
    """phi_k(c h lambda) of exponential.FUNCTIONS into st.phi_diag (LinearPart.diagonal_functions)."""
    m = st.lam.shape[0]
    for f in range(st.phi_c.shape[0]):
        c = st.phi_c[f]
        kf = st.phi_k[f]
        for i in range(m):
            st.z_work[i] = c * h * st.lam[i]
        EX._phi_into(st.z_work, kf, st.phi_work)
        for i in range(m):
            st.phi_diag[f, i] = st.phi_work[kf, i]


@njit(cache=True)
def _exponential_stage(st, j, h, nominal, out):
    """Stage ``j`` of exponential.STAGES into ``out`` (ExponentialRK4._stage); True if out is finite."""
    base_index = st.stage_base[j]
    base = st.no_base if base_index < 0 else st.S[base_index]
    n_terms = st.stage_terms[j]
    functions = st.stage_functions[j, :n_terms]
    coefficients = st.stage_coefficients[j, :n_terms]
    W = st.W[:n_terms]
    if nominal:
        return EX.stage_real(st.Phi[j], st.phi_at_zero, functions, coefficients, st.Y, st.N, h, base, st.indices,
                             st.is_linear, out, W, st.w_stack, st.product)
    return EX.stage_eigen(st.V, st.Vinv, st.phi_diag, st.phi_at_zero, functions, coefficients, st.Y, st.N, h, base,
                          st.indices, st.is_linear, out, W, st.z_acc, st.z_in, st.z_out)


@njit(cache=True)
def _exponential_failed(st, reals, ints, t, t_failed, state, stage):
    copy_into(st.YN, state)
    reals[R_FAILED_T] = t_failed
    reals[R_T_OLD] = t
    reals[R_T] = t
    ints[I_FAILED_STAGE] = stage
    ints[I_STEP_FLAGS] = 0
    return STEP_FAILED


@njit(cache=True)
def _exponential_event_samples(k, engine, b, st, ev, t_old, t_new):
    """The zero-crossing functions at the uniform samples of the step's dense output into ev.samples (the same
    compiled exponential.dense_state that ExponentialDenseOutput evaluates in Python, at the same sample times):
    what locate_events' first pass computes, handed to it with the candidate (Simulation._compiled_event)."""
    n = SUBDIVISIONS
    h = t_new - t_old
    step = (t_new - t_old) / n  # numpy.linspace(t_old, t_new, n + 1)
    EX.dense_coefficients(ev.y_old, st.N, st.Vinv, st.indices, st.dense_n, st.dense_z, st.z_in)
    copy_into(ev.samples[0], ev.g_old)
    copy_into(ev.samples[n], ev.g_new)
    for j in range(1, n):
        t_j = j * step + t_old
        EX.dense_state((t_j - t_old) / h, h, ev.y_old, st.dense_n, st.dense_z, st.lam, st.V, st.indices, st.z_work,
                       st.phi_work, st.z_acc, st.z_out, ev.y_mid)
        _zero_crossings_at(k, engine, t_j, ev.y_mid, b, ev.samples[j])


@njit(cache=True)
def _exponential_event_candidate(k, engine, b, st, ev, t_old, t_new):
    """_event_candidate's subdivided search on the exponential dense output's samples, so that the loop returns
    to Python exactly when locate_events would find a crossing."""
    m = ev.g_old.shape[0]
    n = SUBDIVISIONS
    step = (t_new - t_old) / n
    _exponential_event_samples(k, engine, b, st, ev, t_old, t_new)
    return _samples_flag_candidate(ev, m, n, step, t_old, t_new)


@njit(cache=True)
def _integrate_exponential(k, engine, b, st, ev, target, ints, reals):
    """Exponential RK4 steps from reals[R_T] to ``target`` (ExponentialRK4._step_impl and Simulation._advance,
    the same arithmetic; see the section comment); returns 0 or a status."""
    Y, F, S, N = st.Y, st.F, st.S, st.N
    t = reals[R_T]
    if st.h == 0.0:
        return NEW_INTEGRATOR
    if ints[I_F_VALID] == 0:  # a restart from the context's state: Integrator.reset (normalize, derivative)
        copy_into(Y, b.X)
        normalize(k, engine, b, Y)
        ints[I_F_VALID] = F_DUE
    if ev.mode != NO_EVENTS:
        _zero_crossings_at(k, engine, t, Y, b, ev.g_old)
    h0 = st.h
    while t < target:
        if ints[I_F_VALID] != 1:  # the slope at the step's start (lazy: a restart follows most steps)
            derivative_at(k, engine, t, Y, b, b.src, b.fac)
            ints[I_NFEV] += 1
            if not all_finite(b.XD):
                reals[R_T] = t
                copy_into(b.X, Y)
                return START_FAILED
            copy_into(F, b.XD)
            ints[I_F_VALID] = 1
        remaining = target - t
        last = remaining <= h0 * (1.0 + 1e-9)
        h = remaining if last else h0
        nominal = abs(h - h0) <= 1e-12 * h0
        t_new = target if last else t + h
        flags = ints[I_STEP_FLAGS]
        if st.check_drift and not (flags & CHECK_DONE):
            ints[I_SINCE_CHECK] += 1
            ints[I_STEP_FLAGS] = flags | CHECK_DONE
            if ints[I_SINCE_CHECK] >= ints[I_CHECK_INTERVAL]:
                reals[R_T] = t
                copy_into(b.X, Y)
                return LINEAR_CHECK
            flags = ints[I_STEP_FLAGS]
        if not nominal and reals[R_PHI_H] != h:
            _exponential_phi_diagonal(st, h)
            reals[R_PHI_H] = h
        first = 0
        if flags & RESUME:
            first = 2
        else:
            EX.remainder(F, Y, st.indices, st.L, st.y_lin, st.product, N[0])
        for j in range(first, 3):
            t_stage = t + st.c_nodes[j] * h
            if not _exponential_stage(st, j, h, nominal, S[j]):
                return _exponential_failed(st, reals, ints, t, t_stage, S[j], 0)
            derivative_at(k, engine, t_stage, S[j], b, b.src, b.fac)
            ints[I_NFEV] += 1
            if not all_finite(b.XD):
                return _exponential_failed(st, reals, ints, t, t_stage, S[j], 1)
            EX.remainder(b.XD, S[j], st.indices, st.L, st.y_lin, st.product, N[j + 1])
            if j == 1 and not (flags & STIFF_DONE):
                rho, noise = EX.remainder_stiffness(N[1], N[2], S[0], S[1], st.indices, st.L_norm)
                if not (h * noise > 0.1 * EX.STIFF_REMAINDER_BOUND):  # ExponentialRK4._remainder_is_stiff
                    reals[R_RHO] = h * rho
                    if h * rho > EX.STIFF_REMAINDER_BOUND:
                        ints[I_STEP_FLAGS] = flags | STIFF_DONE | RESUME
                        reals[R_T] = t
                        copy_into(b.X, Y)
                        return STIFF_REMAINDER
        if not _exponential_stage(st, 3, h, nominal, S[3]):
            return _exponential_failed(st, reals, ints, t, t_new, S[3], 0)
        copy_into(st.YN, S[3])
        normalize(k, engine, b, st.YN)
        ints[I_STEP_FLAGS] = 0
        if ev.mode != NO_EVENTS:
            copy_into(ev.y_old, Y)
        copy_into(Y, st.YN)
        ints[I_F_VALID] = F_DUE
        reals[R_T_OLD] = t
        t_old = t
        t = t_new
        ints[I_STEPS] += 1
        if t >= target:
            t = target
        if ev.mode != NO_EVENTS:
            _zero_crossings_at(k, engine, t, Y, b, ev.g_new)
            # subdivided detection, and the step right after an event, search the dense output (Simulation._advance)
            if ev.mode == SUBDIVIDED or t_old == reals[R_LAST_EVENT]:
                candidate = _exponential_event_candidate(k, engine, b, st, ev, t_old, t)
            else:
                candidate = _event_candidate(k, engine, b, ev, t_old, t, Y, F, False)
                if candidate:  # Python's search starts from these samples
                    _exponential_event_samples(k, engine, b, st, ev, t_old, t)
            if candidate:
                reals[R_T] = t
                copy_into(b.X, Y)
                return EVENT_CANDIDATE
            copy_into(ev.g_old, ev.g_new)
    reals[R_T] = t
    copy_into(b.X, Y)
    return 0


def _step_to(k, engine, b, st, ev, target, ints, reals, skip_final):
    """Integrate from reals[R_T] to ``target`` with the stepper ``st``: the explicit Runge-Kutta loop or the
    exponential one, chosen by the stepper's type at compile time."""


@overload(_step_to)
def _step_to_overload(k, engine, b, st, ev, target, ints, reals, skip_final):
    if isinstance(st, types.BaseNamedTuple) and st.instance_class is ExponentialStepper:
        def exponential(k, engine, b, st, ev, target, ints, reals, skip_final):
            return _integrate_exponential(k, engine, b, st, ev, target, ints, reals)
        return exponential

    def runge_kutta(k, engine, b, st, ev, target, ints, reals, skip_final):
        return _integrate(k, engine, b, st, ev, target, ints, reals, skip_final)
    return runge_kutta
