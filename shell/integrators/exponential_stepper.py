"""Krogstad's exponential RK4 (:mod:`shell.integrators.exponential`) stepping in the compiled loop.

The stepper holds the method's state and work arrays and the linear part's matrix functions (built in Python by
:class:`ExponentialRK4`); its step is ExponentialRK4._step_impl with the same njit stage products (stage_real /
stage_eigen), the same remainder N = f - L y, the same order of operations and the same lazy slope, so the compiled
and the Python runs agree bit for bit. Python keeps what must be Python: the callable linear part (a mass matrix and
a Cholesky solve in the models' ``stiff_linear_part``) and the rebuild of the matrix functions. The stepper keeps
the integrator's check counters (``counters``: steps since the last check, the check interval, the step's flags) and
asks (:class:`ExponentialStepping`) for a check of the linear part when one is due (after 2, 4, 8, ... steps up to
max(64 steps, 0.25 s): one request per 250 steps of 1 ms once the part stands still: LINEAR_CHECK), and when a step
finds the remainder stiff (h rho(N) > 1: STIFF_REMAINDER); Python checks (and perhaps rebuilds the stepper) and the
loop continues the step where it stopped (flag RESUME: the stages before are kept in S and N). Until the integrator
exists the stepper is a placeholder (step 0) that asks for it (NEW_INTEGRATOR) where the Python loop makes it, at
the start of the first integration after the updates at that instant, so that its linear part and driven rows are
built at the same state. The dense output (for event location) is ExponentialDenseOutput's, from ``N`` and the
step's start.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit

from . import exponential as EX
from .compiled import (FIRST_REQUEST, I_F_VALID, I_FAILED_STAGE, I_NFEV, R_FAILED_T, START_FAILED, STEP_FAILED,
                       CompiledStepping, derivative, normalize, register_stepper, state)
from .kernels import all_finite, copy_into

LINEAR_CHECK = FIRST_REQUEST          # a check of the callable linear part is due before the step from t
STIFF_REMAINDER = FIRST_REQUEST + 1   # the step from t found h rho(N) > STIFF_REMAINDER_BOUND (rho in values[RHO])
NEW_INTEGRATOR = FIRST_REQUEST + 2    # the stepper is a placeholder: Python makes the integrator at the run's state

# counters: steps since the last check, the check interval, this step's flags
SINCE_CHECK, CHECK_INTERVAL, STEP_FLAGS = range(3)
# values: h of the eigenbasis phi functions in phi_diag, the last h rho(N)
PHI_H, RHO = range(2)
# STEP_FLAGS bits: this step's scheduled check was done, its stiffness was handled (no more checks in this step),
# continue it at stage 4 (the stages before are kept in S and N)
CHECK_DONE, STIFF_DONE, RESUME = 1, 2, 4
# ints[I_F_VALID]: 0 restart from the context's x, 1 F = f(t, Y), 2 Y current, F due
F_DUE = 2


class ExponentialStepper(NamedTuple):
    """Krogstad's exponential RK4 as arrays: the state, the stage and remainder work arrays, the linear part and its
    matrix functions (built in Python by ExponentialRK4)."""

    h: float
    Y: np.ndarray            # (n,) the state at the current time
    F: np.ndarray            # (n,) f(t, Y) when ints[I_F_VALID] == 1
    YN: np.ndarray           # (n,) the new state; after a failure the offending state
    S: np.ndarray            # (4, n) stage states Y2, Y3, Y4 and the propagated state
    N: np.ndarray            # (4, n) remainders N1..N4 (the last step's: its dense output)
    W: np.ndarray            # (MAX_TERMS, n) term vectors
    indices: np.ndarray      # (m,) int64 the linear part's components
    other_components: np.ndarray   # (n_other,) int64 those whose row of L is not a copy (LinearPart)
    copy_components: np.ndarray    # (n_copy,) int64 those whose row copies one component
    copied_components: np.ndarray  # (n_copy,) int64 the components they copy
    nonzero_components: np.ndarray  # (m_nz,) int64 those whose column of L is not zero
    zero_components: np.ndarray     # (m - m_nz,) int64 those whose column of L is zero
    dense_other_components: np.ndarray  # other components whose column is not zero (the stage products' columns)
    dense_copy_components: np.ndarray   # copy components whose column is not zero
    L_other: np.ndarray      # (n_other, m_nz) the other rows of L over its non-zero columns
    L_norm: float
    is_linear: np.ndarray    # (n,) bool
    Phi: tuple               # 4 stage matrices, other columns side by side (ExponentialRK4.Phi_other)
    Phi_copies: np.ndarray   # (7, m, n_copy) their copy columns (ExponentialRK4.Phi_copies)
    stage_base: np.ndarray   # (4,) int64: -1 (the step's start) or the stage state added (exponential.STAGES)
    stage_terms: np.ndarray  # (4,) int64
    stage_functions: np.ndarray     # (4, MAX_TERMS) int64
    stage_coefficients: np.ndarray  # (4, MAX_TERMS, 5)
    phi_at_zero: np.ndarray  # (7,)
    phi_c: np.ndarray        # (7,) c of exponential.FUNCTIONS
    phi_k: np.ndarray        # (7,) int64 k of exponential.FUNCTIONS
    c_nodes: np.ndarray      # (3,)
    y_lin: np.ndarray        # (m,) scratch
    product: np.ndarray      # (m,)
    w_stack: np.ndarray      # (MAX_TERMS n_other,)
    w_copies: np.ndarray     # (n_copy,)
    V: np.ndarray            # (m, m) complex: eigenvectors (shortened steps)
    Vinv: np.ndarray
    lam: np.ndarray          # (m,) complex eigenvalues
    phi_diag: np.ndarray     # (7, m) complex phi_k(c h lambda) at h = values[PHI_H]
    phi_work: np.ndarray     # (4, m) complex
    z_work: np.ndarray       # (m,) complex
    z_acc: np.ndarray
    z_in: np.ndarray
    z_out: np.ndarray
    dense_n: np.ndarray      # (3, n) the last step's dense output: its quadratic in N
    dense_z: np.ndarray      # (4, m) complex: its eigenbasis coordinates
    check_drift: bool        # the linear part is a callable to re-check (the shell's always is)
    counters: np.ndarray     # (3,) int64: SINCE_CHECK, CHECK_INTERVAL, STEP_FLAGS
    values: np.ndarray       # (2,) PHI_H, RHO


def exponential_stepper(integ, Y=None, F=None) -> ExponentialStepper:
    """The stepper of an :class:`shell.integrators.ExponentialRK4` (its current linear part and nominal step, its
    check counters); ``Y``, ``F`` carried over from a previous stepper (a rebuild), else the integrator's."""
    part, n = integ.part, integ.n
    m = part.m
    base = np.array([stage[0] for stage in EX.STAGES], dtype=np.int64)
    terms = np.array([stage[1].shape[0] for stage in EX.STAGES], dtype=np.int64)
    functions = np.zeros((4, EX.MAX_TERMS), dtype=np.int64)
    coefficients = np.zeros((4, EX.MAX_TERMS, 5))
    for j, (_, fn, co) in enumerate(EX.STAGES):
        functions[j, :fn.shape[0]] = fn
        coefficients[j, :fn.shape[0]] = co
    complex_m = (lambda: np.zeros(m, dtype=np.complex128))
    n_other = part.other_rows.size
    return ExponentialStepper(
        float(integ.h), (integ.y if Y is None else Y).copy(), (integ.f if F is None else F).copy(), np.zeros(n),
        np.zeros((4, n)), np.zeros((4, n)), np.zeros((EX.MAX_TERMS, n)), part.indices.astype(np.int64),
        part.other_components.astype(np.int64), part.copy_components.astype(np.int64),
        part.copied_components.astype(np.int64), part.nonzero_components.astype(np.int64),
        part.zero_components.astype(np.int64), part.dense_other_components.astype(np.int64),
        part.dense_copy_components.astype(np.int64),
        np.ascontiguousarray(part.L_other).reshape(n_other, part.nonzero_columns.size),
        float(part.L_norm), part.is_linear.copy(),
        tuple(np.ascontiguousarray(P, dtype=np.float64).reshape(P.shape if m else (0, 0)) for P in integ.Phi_other),
        np.ascontiguousarray(integ.Phi_copies, dtype=np.float64).reshape(len(EX.FUNCTIONS), m,
                                                                          part.dense_copy_rows.size),
        base, terms, functions, coefficients, EX.PHI_AT_ZERO.copy(), np.array([c for c, _ in EX.FUNCTIONS]),
        np.array([k for _, k in EX.FUNCTIONS], dtype=np.int64), np.array(EX.C_NODES), np.zeros(m), np.zeros(m),
        np.zeros(EX.MAX_TERMS * n_other), np.zeros(part.copy_rows.size),
        np.ascontiguousarray(part.V, dtype=np.complex128),
        np.ascontiguousarray(part.Vinv, dtype=np.complex128), np.ascontiguousarray(part.lam, dtype=np.complex128),
        np.zeros((len(EX.FUNCTIONS), m), dtype=np.complex128), np.zeros((4, m), dtype=np.complex128), complex_m(),
        complex_m(), complex_m(), complex_m(), np.zeros((3, n)), np.zeros((4, m), dtype=np.complex128),
        bool(callable(integ.linear_part_option)),
        np.array([integ.steps_since_check, integ.check_interval, 0], dtype=np.int64), np.array([np.nan, 0.0]))


def exponential_placeholder(n: int) -> ExponentialStepper:
    """A stepper of the right type with step 0: the loop asks Python for the integrator before using it."""
    empty_c = np.zeros(0, dtype=np.complex128)
    empty_i = np.zeros(0, dtype=np.int64)
    return ExponentialStepper(
        0.0, np.zeros(n), np.zeros(n), np.zeros(n), np.zeros((4, n)), np.zeros((4, n)), np.zeros((EX.MAX_TERMS, n)),
        empty_i, empty_i, empty_i, empty_i, empty_i, empty_i, empty_i, empty_i, np.zeros((0, 0)), 0.0,
        np.zeros(n, dtype=np.bool_),
        (np.zeros((0, 0)),) * 4, np.zeros((len(EX.FUNCTIONS), 0, 0)),
        np.zeros(4, dtype=np.int64), np.zeros(4, dtype=np.int64), np.zeros((4, EX.MAX_TERMS), dtype=np.int64),
        np.zeros((4, EX.MAX_TERMS, 5)), np.zeros(7), np.zeros(7), np.zeros(7, dtype=np.int64), np.zeros(3),
        np.zeros(0), np.zeros(0), np.zeros(0), np.zeros(0), np.zeros((0, 0), dtype=np.complex128),
        np.zeros((0, 0), dtype=np.complex128), empty_c, np.zeros((7, 0), dtype=np.complex128),
        np.zeros((4, 0), dtype=np.complex128), empty_c, empty_c, empty_c, empty_c, np.zeros((3, n)),
        np.zeros((4, 0), dtype=np.complex128), False, np.zeros(3, dtype=np.int64), np.array([np.nan, 0.0]))


@njit(cache=True)
def _phi_diagonal(st, h):
    """phi_k(c h lambda) of exponential.FUNCTIONS into st.phi_diag (LinearPart.diagonal_functions)."""
    m = st.lam.shape[0]
    for f in range(st.phi_c.shape[0]):
        c = st.phi_c[f]
        kf = st.phi_k[f]
        for i in range(m):
            st.z_work[i] = c * h * st.lam[i]
        EX.phi_into(st.z_work, kf, st.phi_work)
        for i in range(m):
            st.phi_diag[f, i] = st.phi_work[kf, i]


@njit(cache=True)
def _stage(st, j, h, nominal, out):
    """Stage ``j`` of exponential.STAGES into ``out`` (ExponentialRK4._stage); True if out is finite."""
    base_index = st.stage_base[j]
    base = st.Y if base_index < 0 else st.S[base_index]
    n_terms = st.stage_terms[j]
    functions = st.stage_functions[j, :n_terms]
    coefficients = st.stage_coefficients[j, :n_terms]
    W = st.W[:n_terms]
    if nominal:
        return EX.stage_real(st.Phi[j], st.Phi_copies, st.phi_at_zero, functions, coefficients, st.F, st.N, h, base,
                             st.indices, st.dense_other_components, st.dense_copy_components, st.zero_components,
                             st.is_linear, out, W, st.w_stack, st.w_copies, st.product)
    return EX.stage_eigen(st.V, st.Vinv, st.phi_diag, st.phi_at_zero, functions, coefficients, st.F, st.N, h, base,
                          st.indices, st.is_linear, out, W, st.z_acc, st.z_in, st.z_out)


@njit(cache=True, inline="always")
def _remainder(st, f, y, out):
    EX.remainder(f, y, st.nonzero_components, st.L_other, st.other_components, st.copy_components,
                 st.copied_components, st.y_lin, st.product, out)


@njit(cache=True)
def _failed(st, reals, ints, t_failed, stage_state, stage):
    copy_into(st.YN, stage_state)
    reals[R_FAILED_T] = t_failed
    ints[I_FAILED_STAGE] = stage
    st.counters[STEP_FLAGS] = 0
    return STEP_FAILED


@njit(cache=True)
def _start(system, st, t, ints, reals):
    """A restart from the run's state (Integrator.reset: normalized; the slope is computed when a step needs it)."""
    if st.h == 0.0:
        return NEW_INTEGRATOR
    if ints[I_F_VALID] == 0:
        copy_into(st.Y, state(system))
        normalize(system, st.Y)
        ints[I_F_VALID] = F_DUE
    return 0


@njit(cache=True, inline="always")
def _step(system, st, t, h, t_new, skip_slope, ints, reals):
    """ExponentialRK4._step_impl from (t, Y) into YN (module docstring); a request returns before the step."""
    Y, F, S, N, counters = st.Y, st.F, st.S, st.N, st.counters
    if ints[I_F_VALID] != 1:  # the slope at the step's start (lazy: a restart follows most steps)
        f = derivative(system, t, Y)
        ints[I_NFEV] += 1
        if not all_finite(f):
            return START_FAILED
        copy_into(F, f)
        ints[I_F_VALID] = 1
    nominal = abs(h - st.h) <= 1e-12 * st.h
    flags = counters[STEP_FLAGS]
    if st.check_drift and not (flags & CHECK_DONE):
        counters[SINCE_CHECK] += 1
        counters[STEP_FLAGS] = flags | CHECK_DONE
        if counters[SINCE_CHECK] >= counters[CHECK_INTERVAL]:
            return LINEAR_CHECK
        flags = counters[STEP_FLAGS]
    if not nominal and st.values[PHI_H] != h:
        _phi_diagonal(st, h)
        st.values[PHI_H] = h
    first = 0
    if flags & RESUME:
        first = 2
    else:
        _remainder(st, F, Y, N[0])
    for j in range(first, 3):
        t_stage = t + st.c_nodes[j] * h
        if not _stage(st, j, h, nominal, S[j]):
            return _failed(st, reals, ints, t_stage, S[j], 0)
        f = derivative(system, t_stage, S[j])
        ints[I_NFEV] += 1
        if not all_finite(f):
            return _failed(st, reals, ints, t_stage, S[j], 1)
        _remainder(st, f, S[j], N[j + 1])
        if j == 1 and not (flags & STIFF_DONE):
            rho, noise = EX.remainder_stiffness(N[1], N[2], S[0], S[1], st.indices, st.L_norm)
            if not (h * noise > 0.1 * EX.STIFF_REMAINDER_BOUND):  # ExponentialRK4._remainder_is_stiff
                st.values[RHO] = h * rho
                if h * rho > EX.STIFF_REMAINDER_BOUND:
                    counters[STEP_FLAGS] = flags | STIFF_DONE | RESUME
                    return STIFF_REMAINDER
    if not _stage(st, 3, h, nominal, S[3]):
        return _failed(st, reals, ints, t_new, S[3], 0)
    copy_into(st.YN, S[3])
    normalize(system, st.YN)
    counters[STEP_FLAGS] = 0
    return 0


@njit(cache=True)
def _keep(st, ev):
    copy_into(ev.y_old, st.Y)


@njit(cache=True)
def _accept(st, ints, skipped):
    copy_into(st.Y, st.YN)
    ints[I_F_VALID] = F_DUE


@njit(cache=True)
def _prepare_dense(st, ev):
    EX.dense_coefficients(ev.y_old, st.N, st.Vinv, st.indices, st.dense_n, st.dense_z, st.z_in)


@njit(cache=True)
def _dense(st, ev, theta, h, out):
    EX.dense_state(theta, h, ev.y_old, st.dense_n, st.dense_z, st.lam, st.V, st.indices, st.z_work, st.phi_work,
                   st.z_acc, st.z_out, out)


register_stepper(ExponentialStepper, start=_start, step=_step, keep=_keep, accept=_accept,
                 prepare_dense=_prepare_dense, dense=_dense)


class ExponentialStepping(CompiledStepping):
    """The Python side of the compiled exponential RK4 (module docstring): the :class:`ExponentialRK4` object (the
    run's Python integrator) stays the home of the linear part, its matrix functions and check counters (the
    stepper carries them while the loop runs and gives them back), and of the events' dense output."""

    def __init__(self, run, method):
        super().__init__(run, method)
        self.part = None        # the linear part the stepper was built from
        self.t_current = None   # the time the stepper's state is current at
        self.f_state = 0        # its slope's state (ints[I_F_VALID]) then

    @classmethod
    def applies(cls, method, options, has_events) -> bool:
        return options.get("step") is not None

    def stepper(self, stale: bool):
        run = self.run
        integ = run.integrator
        if not isinstance(integ, EX.ExponentialRK4):
            self.st, self.part = exponential_placeholder(run.x.size), None
            return self.st, 0
        if not isinstance(self.st, ExponentialStepper) or self.part is not integ.part:
            # the Python loop's integrator moved on: the loop restarts from the context (no slope needed here)
            self.st = exponential_stepper(integ, integ.y, np.zeros_like(integ.y))
            self.part = integ.part
            stale = True
        self.st.counters[:] = (integ.steps_since_check, integ.check_interval, 0)
        self.st.values[:] = (np.nan, 0.0)
        return self.st, 0 if stale or self.t_current != run.t else self.f_state

    def request(self, status, st, ints, reals, t_end):
        if status == NEW_INTEGRATOR:
            integ = self.run.make_integrator(t_end)
            self.st, self.part = exponential_stepper(integ), integ.part
            ints[I_F_VALID] = 1
            return self.st
        return self._check_linear_part(self.run.integrator, st, ints, status == STIFF_REMAINDER)

    def _check_linear_part(self, integ, st, ints, stiff: bool):
        """A check of the linear part (due by the check counters, or forced by a stiff remainder):
        ExponentialRK4._check_drift's work; a rebuilt linear part gives a new stepper (the state and slope carried
        over, the step taken again from its start after a stiff remainder)."""
        t, h = self.run.t, st.h
        if stiff:
            integ.last_rho = float(st.values[RHO]) / h
            if not st.check_drift:  # a fixed (indices, L): the Python integrator warns and goes on
                saved, integ.t = integ.t, t
                integ._warn_stiff(h)
                integ.t = saved
                return st
        before = integ.nfev
        integ.steps_since_check = 0
        integ.check_interval = int(st.counters[CHECK_INTERVAL])
        rebuilt = integ.check_linear_part(t, st.Y.copy())
        st.counters[SINCE_CHECK] = 0
        st.counters[CHECK_INTERVAL] = integ.check_interval
        ints[I_NFEV] += integ.nfev - before
        if not rebuilt:
            return st
        flags = int(st.counters[STEP_FLAGS])
        if stiff:
            flags &= ~RESUME
            integ.nrejected += 1
        self.st = exponential_stepper(integ, st.Y, st.F)
        self.st.counters[STEP_FLAGS] = flags
        self.st.values[RHO] = st.values[RHO]
        self.part = integ.part
        return self.st

    def dense_output(self, st, t_old, t_new, y_old, f_old):
        return EX.ExponentialDenseOutput(t_old, t_new, y_old, st.N, self.part)

    def advice(self, st) -> str:
        integ = self.run.integrator
        integ.last_rho = float(st.values[RHO]) / st.h
        return integ._suggestion(st.h)

    def sync(self, st, ints) -> None:
        integ = self.run.integrator
        if self.part is not None and isinstance(integ, EX.ExponentialRK4):
            integ.steps_since_check = int(st.counters[SINCE_CHECK])
            integ.check_interval = int(st.counters[CHECK_INTERVAL])
            self.t_current = self.run.t
            self.f_state = int(ints[I_F_VALID])
