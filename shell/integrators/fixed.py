"""Fixed-step explicit Runge-Kutta integrators: Euler (order 1), Heun (2), classical RK4 (4) and the
12-stage 8th-order Dormand-Prince formula used with a fixed step (RK8).

One step (HNW I Sec. II.1 eq. 1.8): ``k_i = f(t + c_i h, y + h sum_j a_ij k_j)``,
``y_new = y + h sum_i b_i k_i``; then ``normalize(y_new)`` and ``f_new = f(t + h, y_new)``, which is
both the end slope of the cubic Hermite dense output and the first stage of the next step (so each step
costs exactly ``s`` derivative evaluations). The last step before ``t_bound`` is shortened to land on it
exactly; a remainder within 1e-9 h of a full step is taken as one step, so a discrete sample period that
is a multiple of the step never produces a sliver step from round-off.

In the compiled loop (:mod:`shell.integrators.compiled`) a method steps with :class:`RungeKuttaStepper`: the same
stage states, combination and slopes from the same kernels, driven by the tableau's arrays (one compiled stepper
for every tableau); with zero crossings, when its dense output is the cubic Hermite one.
"""
import math
from typing import NamedTuple

import numpy as np
from numba import njit

from . import kernels, stability, tableaus
from .base import HermiteDenseOutput, Integrator
from .compiled import (I_F_VALID, I_FAILED_STAGE, I_NFEV, R_FAILED_T, START_FAILED, STEP_FAILED, CompiledStepping,
                       derivative, normalize, register_stepper, state)


# -- stepping in the compiled loop (shell.integrators.compiled) -----------------------------------------------------
class RungeKuttaStepper(NamedTuple):
    """A fixed-step explicit Runge-Kutta method as arrays: its tableau and nominal step, the state and its slope,
    the stage slopes and state, the new state and its slope."""

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
    FN: np.ndarray


@njit(cache=True)
def _start(system, st, t, ints, reals):
    """A restart from the run's state (Integrator.reset: normalized, its slope evaluated)."""
    if ints[I_F_VALID] == 0:
        kernels.copy_into(st.Y, state(system))
        normalize(system, st.Y)
        f = derivative(system, t, st.Y)
        ints[I_NFEV] += 1
        if not kernels.all_finite(f):
            return START_FAILED
        kernels.copy_into(st.F, f)
        ints[I_F_VALID] = 1
    return 0


@njit(cache=True, inline="always")
def _step(system, st, t, h, t_new, skip_slope, ints, reals):
    """FixedStepRungeKutta._step_impl: the same arithmetic. One call site of the system's derivative serves the
    stages and the end slope (i == s): the evaluation is inlined here, and a second site compiled it twice."""
    Y, K, YS, YN = st.Y, st.K, st.YS, st.YN
    s = st.n_stages
    kernels.copy_into(K[0], st.F)
    for i in range(1, s + 1):
        if i < s:
            kernels.stage_state(Y, K, st.A[i], i, h, YS)
            at, ys = t + st.c[i] * h, YS
        else:
            if not kernels.propagate(Y, K, st.b, s, h, YN):
                reals[R_FAILED_T] = t_new
                ints[I_FAILED_STAGE] = 0
                return STEP_FAILED
            normalize(system, YN)
            if skip_slope:
                return 0
            at, ys = t_new, YN
        f = derivative(system, at, ys)
        ints[I_NFEV] += 1
        if i < s:
            kernels.copy_into(K[i], f)
        elif not kernels.all_finite(f):
            reals[R_FAILED_T] = t_new
            ints[I_FAILED_STAGE] = 1
            return STEP_FAILED
        else:
            kernels.copy_into(st.FN, f)
    return 0


@njit(cache=True)
def _keep(st, ev):
    kernels.copy_into(ev.y_old, st.Y)
    kernels.copy_into(ev.f_old, st.F)


@njit(cache=True)
def _accept(st, ints, skipped):
    kernels.copy_into(st.Y, st.YN)
    if skipped:
        ints[I_F_VALID] = 0
    else:
        kernels.copy_into(st.F, st.FN)


@njit(cache=True)
def _prepare_dense(st, ev):
    return


@njit(cache=True)
def _dense(st, ev, theta, h, out):
    kernels.hermite_cubic(theta, h, ev.y_old, ev.f_old, st.Y, st.F, out)


register_stepper(RungeKuttaStepper, start=_start, step=_step, keep=_keep, accept=_accept, prepare_dense=_prepare_dense,
                 dense=_dense)


class RungeKuttaStepping(CompiledStepping):
    """The Python side of a fixed-step Runge-Kutta method in the compiled loop: its stepper (one per step size),
    and the cubic Hermite dense output of its steps for event location (as ``FixedStepRungeKutta.dense_output``)."""

    @classmethod
    def applies(cls, method, options, has_events) -> bool:
        # events are located on the dense output: the compiled loop evaluates the cubic Hermite one
        return options.get("step") is not None and (not has_events or method.hermite_dense_output)

    def stepper(self, stale: bool):
        options = self.run.options
        step = float(options["step"])
        if not (step > 0.0 and math.isfinite(step)):
            raise ValueError(f"integrator step must be a positive number of seconds, got {options['step']!r}")
        h = min(step, float(options.get("max_step", np.inf)))
        tb = self.method.tableau
        if not isinstance(self.st, RungeKuttaStepper) or self.st.h != h or self.st.A is not tb.A:
            n = self.run.x.size
            self.st = RungeKuttaStepper(tb.A, tb.b, tb.c, tb.n_stages, h, self.run.x.copy(), np.zeros(n),
                                        np.zeros((tb.n_stages, n)), np.zeros(n), np.zeros(n), np.zeros(n))
            stale = True
        return self.st, 0 if stale else 1

    def dense_output(self, st, t_old, t_new, y_old, f_old):
        return HermiteDenseOutput(t_old, t_new, y_old, f_old, st.Y, st.F)


class FixedStepRungeKutta(Integrator):
    """Explicit Runge-Kutta method with a constant step ``step`` (the last step may be shorter).

    ``skip_final_slope``: set by a caller that will ``reset`` the integrator at ``t_bound`` (a discrete
    update changes the right-hand side there): the last step before ``t_bound`` then does not evaluate
    the slope at its end, which the reset recomputes anyway (a step of a model sampled at the step rate
    costs s evaluations, not s + 1). That step has no dense output.
    """

    fixed_step = True
    tableau = None
    skip_final_slope = False
    options = {"max_step": ("s", "largest step: the step taken is min(step, max_step)")}
    #: the dense output is the cubic Hermite one (the compiled loop then locates zero crossings on it too)
    hermite_dense_output = True
    compiled_stepping = RungeKuttaStepping

    def _setup(self):
        tb = self.tableau
        self.h = min(self.step_option, self.max_step)
        self.K = np.empty((tb.n_stages, self.n))
        self.y_stage = np.empty(self.n)

    def _step_impl(self):
        tb = self.tableau
        t = self.t
        y = self.y
        remaining = self.t_bound - t
        h = self.h
        last = remaining <= h * (1.0 + 1e-9)
        if last:
            h = remaining
        K = self.K
        K[0] = self.f
        fun = self.fun
        for i in range(1, tb.n_stages):
            kernels.stage_state(y, K, tb.A[i], i, h, self.y_stage)
            K[i] = fun(t + tb.c[i] * h, self.y_stage)
        self.nfev += tb.n_stages - 1
        y_new = np.empty(self.n)
        t_new = self.t_bound if last else t + h
        if not kernels.propagate(y, K, tb.b, tb.n_stages, h, y_new):
            return self._fail(self._nonfinite_reason("the new state", t_new, y_new), t_new, y_new,
                              self._stability_suggestion(h))
        if self.normalize is not None:
            self.normalize(y_new)
        if last and self.skip_final_slope:
            self.t_old, self.y_old, self.f_old = t, y, self.f
            self.t, self.y, self.f = t_new, y_new, None
            return True
        f_new = np.array(fun(t_new, y_new), dtype=np.float64)
        self.nfev += 1
        if not kernels.all_finite(f_new):
            return self._fail(self._nonfinite_reason("the derivative fun(t, y)", t_new, f_new), t_new, y_new,
                              "Check the model for a division by zero or an invalid state at that time; "
                              + self._stability_suggestion(h))
        self.t_old = t
        self.y_old = y
        self.f_old = self.f
        self.t = t_new
        self.y = y_new
        self.f = f_new
        return True

    def _dense_output_impl(self):
        if self.f is None:
            raise RuntimeError(f"{self.name}: no dense output for a step taken with skip_final_slope")
        return HermiteDenseOutput(self.t_old, self.t, self.y_old, self.f_old, self.y, self.f)

    def _stability_suggestion(self, h):
        # the last good state of a diverging run is huge; the eigenvalues of a structural model hardly
        # depend on the state, so linearize at the start of the run instead
        rho = self.estimate_spectral_radius(self.t_start, self.y_start)
        if not np.isfinite(rho) or rho == 0.0:
            return ("If the state grew without bound, the step may exceed the explicit stability limit: "
                    "reduce step or use method 'radau5'.")
        r_osc = stability.stability_radius(self.tableau, np.pi / 2)
        r_real = stability.stability_radius(self.tableau, np.pi)
        return (f"The fastest eigenvalue of the model at the start of the run has |lambda| ~ {rho:.3g} rad/s "
                f"({rho / (2 * np.pi):.3g} Hz); {self.name} with step {h:.3g} s gives h|lambda| = {h * rho:.3g}, "
                f"while it is stable only up to h|lambda| = {r_osc:.3g} for an undamped oscillation and "
                f"{r_real:.3g} for a decaying mode (step < {r_osc / rho:.3g} s resp. {r_real / rho:.3g} s). "
                f"Reduce the step, remove the mode if it is not needed, or use the implicit method 'radau5'.")


class ExplicitEuler(FixedStepRungeKutta):
    """Forward Euler, order 1."""

    name = "euler"
    order = 1
    tableau = tableaus.EULER


class Heun(FixedStepRungeKutta):
    """Heun's method (explicit trapezoidal rule), order 2."""

    name = "heun"
    order = 2
    tableau = tableaus.HEUN


class RK4(FixedStepRungeKutta):
    """Classical 4-stage Runge-Kutta, order 4."""

    name = "rk4"
    order = 4
    tableau = tableaus.RK4


class RK8(FixedStepRungeKutta):
    """Dormand-Prince 12-stage 8th-order formula (the propagator of DOP853) with a fixed step.

    Dense output is DOP853's 7th-order interpolant (three extra stages per step, evaluated only when
    dense output is requested), so events are located with the accuracy of the step itself.
    """

    name = "rk8"
    order = 8
    tableau = tableaus.RK8
    hermite_dense_output = False

    def _setup(self):
        super()._setup()
        self.K_extended = np.empty((16, self.n))
        self.K = self.K_extended[:12]

    def _dense_output_impl(self):
        from .adaptive import dop853_dense_output

        self.K_extended[12] = self.f
        return dop853_dense_output(self, self.K_extended, self.t - self.t_old)

