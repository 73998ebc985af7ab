"""Adaptive explicit Runge-Kutta pairs with error control and dense output: Bogacki-Shampine 3(2),
Dormand-Prince 5(4) and DOP853 (8th order with 5th/3rd-order error estimators).

Step control (HNW I Sec. II.4): the embedded estimate ``err = h sum_i e_i k_i`` is measured in the
weighted RMS norm (see :mod:`kernels`); a step is accepted when ``||err|| <= 1`` and the next step is
``h * min(10, max(0.2, 0.9 ||err||^(-1/(q+1))))`` with q the order of the error estimator (no growth right
after a rejection). DOP853 combines its two estimators as HNW I Sec. II.10 eq. (10.17):
``||err|| = h ||e5||^2 / sqrt(n (||e5||^2 + 0.01 ||e3||^2))``. The first step follows HNW I Sec. II.4
("starting step size"). Local extrapolation: every pair propagates its higher-order solution.

Dense output: BS32 uses the cubic Hermite polynomial, DOPRI5 Shampine's 4th-order continuous extension,
DOP853 the 7th-order interpolant of Hairer and Wanner (three extra stages, computed only when dense output
is requested, i.e. when events or output times need it).

Stiffness detection (HNW I Sec. IV.2, as in dopri5.f/dop853.f): the last stage and the FSAL stage are
both taken at t + h, so ``rho = ||k_fsal - k_last|| / ||y_new - y_last||`` estimates the dominant
eigenvalue; if ``h rho`` exceeds 75% of the real-axis stability radius for 15 accepted steps, a power iteration
on the Jacobian confirms it (``h |lambda_max|`` above 75% of the radius for a 1%-damped mode) before a warning
recommends the implicit method; so lightly damped structural modes are caught too, without false alarms
from the non-normal Jacobians of modal models.
"""
import warnings

import numpy as np

from . import kernels, tableaus
from .base import DenseOutput, Integrator, PolynomialDenseOutput, StepSizeControl

SAFETY = 0.9
MIN_FACTOR = 0.2
MAX_FACTOR = 10.0


class StiffnessWarning(UserWarning):
    """The explicit step size is pinned at its stability limit: an implicit method would be cheaper."""


class EmbeddedRungeKutta(StepSizeControl, Integrator):
    adaptive = True
    options = {"rtol": ("", "relative tolerance of the error control"),
               "atol": ("", "absolute tolerance of the error control (state units)"),
               "max_step": ("s", "largest step")}
    tableau = None
    stiffness_boundary = None  # h*rho at which the stiffness counter increments (None: no detection)
    oscillatory_stability_radius = None  # stability radius along the ray of a 1%-damped mode

    def _setup(self):
        tb = self.tableau
        self.error_exponent = -1.0 / (tb.error_order + 1)
        self.K = np.empty((tb.n_stages + 1, self.n))
        self.y_stage = np.empty(self.n)
        self.y_last_stage = np.empty(self.n)
        self.err = np.empty(self.n)
        self.stiff_count = 0
        self.nonstiff_count = 0
        self.stiffness_detected = False
        self.next_confirmation = 0
        self._dense_cache = None
        self.h_previous = None
        self.h_abs = self._initial_step() if self.step_option is None else min(self.step_option, self.max_step)

    def _on_reset(self):
        self.stiff_count = 0
        self.nonstiff_count = 0

    def _initial_step(self):
        return self._hairer_initial_step(self.tableau.order + 1, self.error_weight, self.n_weighted)

    def _stages(self, t, y, h, K):
        """Stages 1..s-1 (stage 0 is the FSAL derivative already in K[0])."""
        tb = self.tableau
        fun = self.fun
        for i in range(1, tb.n_stages):
            kernels.stage_state(y, K, tb.A[i], i, h, self.y_stage)
            K[i] = fun(t + tb.c[i] * h, self.y_stage)
        self.y_last_stage[:] = self.y_stage
        self.nfev += tb.n_stages - 1

    def _estimate_error_norm(self, K, h, y_new):
        kernels.weighted_combination(K, self.tableau.error_weights, self.tableau.n_stages + 1, h, self.err)
        return self._error_norm(self.err, y_new)

    def _step_impl(self):
        tb = self.tableau
        t = self.t
        y = self.y
        K = self.K
        min_step = 10.0 * abs(np.nextafter(t, np.inf) - t)
        h_abs = min(max(self.h_abs, min_step), self.max_step)
        rejected = False
        nonfinite = None
        while True:
            if h_abs < min_step:
                return self._fail_underflow(h_abs, nonfinite)
            remaining = self.t_bound - t
            clipped = remaining <= h_abs * (1.0 + 1e-9)  # no round-off sliver before t_bound
            h = remaining if clipped else h_abs
            t_new = self.t_bound if clipped else t + h
            K[0] = self.f
            self._stages(t, y, h, K)
            y_new = np.empty(self.n)
            finite = kernels.propagate(y, K, tb.b, tb.n_stages, h, y_new)
            if finite:
                K[tb.n_stages] = self.fun(t_new, y_new)
                self.nfev += 1
                finite = kernels.all_finite(K[tb.n_stages])
            if not finite:
                # a too-large step can push the model into an invalid region: treat as a large error
                nonfinite = (t_new, y_new.copy())
                h_abs = h * MIN_FACTOR
                rejected = True
                self.nrejected += 1
                continue
            error_norm = self._estimate_error_norm(K, h, y_new)
            if error_norm < 1.0:
                if error_norm == 0.0:
                    factor = MAX_FACTOR
                else:
                    factor = min(MAX_FACTOR, SAFETY * error_norm ** self.error_exponent)
                if rejected:
                    factor = min(1.0, factor)
                h_next = h * factor
                self.h_abs = max(h_next, h_abs) if (clipped and not rejected) else h_next
                break
            h_abs = h * max(MIN_FACTOR, SAFETY * error_norm ** self.error_exponent)
            rejected = True
            self.nrejected += 1
        if self.stiffness_boundary is not None:
            self._detect_stiffness(h, y_new, K)
        if self.normalize is not None:
            self.normalize(y_new)
        self.t_old = t
        self.y_old = y
        self.f_old = self.f
        self.h_previous = h
        self.t = t_new
        self.y = y_new
        self.f = K[tb.n_stages].copy()
        self._dense_cache = None
        return True

    def _detect_stiffness(self, h, y_new, K):
        s = self.tableau.n_stages
        h_rho = h * kernels.stiffness_ratio(K[s - 1], K[s], self.y_last_stage, y_new)
        if h_rho > self.stiffness_boundary:
            self.nonstiff_count = 0
            self.stiff_count += 1
            if self.stiff_count >= 15 and not self.stiffness_detected and self.nsteps >= self.next_confirmation:
                self._confirm_stiffness(h)
        else:
            self.nonstiff_count += 1
            if self.nonstiff_count == 6:
                self.stiff_count = 0

    def _confirm_stiffness(self, h):
        """The stage-difference ratio overestimates |lambda| when the Jacobian is far from normal (a modal
        model in [eta, eta_dot] reaches omega^2, not omega), so confirm with a power iteration (13
        evaluations, at most once per 100 steps) against 75% of the stability radius of a 1%-damped mode."""
        rho = self.estimate_spectral_radius(self.t_old + h, self.y_last_stage)
        self.next_confirmation = self.nsteps + 100
        self.stiff_count = 0
        if np.isfinite(rho) and h * rho > 0.75 * self.oscillatory_stability_radius:
            self.stiffness_detected = True
            warnings.warn(f"{self.name}: the problem looks stiff near t={self.t_old + h:.6g} s (the step is pinned "
                          f"at the explicit stability limit, h|lambda| ~ {h * rho:.3g}); the implicit method "
                          f"'radau5' will take far fewer steps", StiffnessWarning, stacklevel=5)

    def _fail_underflow(self, h_abs, nonfinite):
        if nonfinite is not None:
            t_bad, y_bad = nonfinite
            f_bad = np.asarray(self.fun(t_bad, y_bad), dtype=np.float64) if kernels.all_finite(y_bad) else y_bad
            reason = ("the step size fell below the time resolution while the model kept returning "
                      "non-finite values: " + self._nonfinite_reason("the derivative", t_bad, f_bad))
            return self._fail(reason, t_bad, y_bad, "Check the model for a singularity or invalid state "
                              "(division by zero, sqrt of a negative number) near that time.")
        # which component drives the error at the smallest step tried
        err = np.abs(self.err) / (self.atol + self.rtol * np.abs(self.y)) * self.error_weight
        worst = int(np.argmax(err))
        rho = self.estimate_spectral_radius()
        stiff = self.stiffness_detected or (np.isfinite(rho) and h_abs * rho > 1.0)
        if stiff:
            suggestion = (f"The model has a fast eigenvalue |lambda| ~ {rho:.3g} rad/s; an explicit method "
                          f"cannot take steps larger than ~{1.0 / rho:.3g} s there: use 'radau5'.")
        else:
            suggestion = ("The solution or the model changes abruptly there (a discontinuity, an unresolved "
                          "switch or a finite-time blow-up): add an event function for the switch so the "
                          "integrator restarts at it, or check the model; if a stiff mode is involved use "
                          "'radau5'.")
        reason = (f"step size underflow (h = {h_abs:.3g} s after {self.nrejected} rejected steps in total); "
                  f"the error is dominated by state component {worst}")
        return self._fail(reason, self.t + h_abs, None, suggestion)

    def _dense_output_impl(self):
        Q = self.K.T @ self.tableau.dense_weights
        return PolynomialDenseOutput(self.t_old, self.t, self.y_old, Q)


class BogackiShampine32(EmbeddedRungeKutta):
    """Bogacki-Shampine 3(2) pair, FSAL, cubic Hermite dense output."""

    name = "bs32"
    order = 3
    tableau = tableaus.BS32


class DormandPrince54(EmbeddedRungeKutta):
    """Dormand-Prince 5(4) pair (the method of MATLAB ode45 and scipy RK45), 4th-order dense output."""

    name = "dopri5"
    order = 5
    tableau = tableaus.DOPRI5
    # 75% of the real-axis stability radius 3.31: without a PI controller the step of a stiff problem settles
    # at h|lambda| ~ 2.8, just below dopri5.f's 3.25 (checked in tests/integrators/test_adaptive.py)
    stiffness_boundary = 0.75 * 3.3066
    oscillatory_stability_radius = 1.8721


class Dop853DenseOutput(DenseOutput):
    """7th-order interpolant ``y_old + x (F0 + (1-x)(F1 + x (F2 + (1-x)(F3 + x (F4 + (1-x)(F5 + x F6))))))``."""

    def __init__(self, t_old, t, y_old, F):
        super().__init__(t_old, t)
        self.h = t - t_old
        self.y_old = y_old.copy()
        self.F = F

    def _evaluate(self, t):
        x = (t - self.t_min) / self.h
        if t.ndim == 1:
            x = x[None, :]
            F = self.F[:, :, None]
            y = np.zeros((self.y_old.shape[0], x.shape[1]))
            y_old = self.y_old[:, None]
        else:
            F = self.F
            y = np.zeros_like(self.y_old)
            y_old = self.y_old
        for i in range(F.shape[0] - 1, -1, -1):
            y = y + F[i]
            y = y * (x if i % 2 == 0 else 1.0 - x)
        return y + y_old


def dop853_dense_output(integ, K_extended, h):
    """Dense output of one DOP853 step whose stages 0..12 are in K_extended (computes stages 13..15)."""
    A = tableaus.DOP853_A_EXTENDED
    c = tableaus.DOP853_C_EXTENDED
    y_stage = np.empty(integ.n)
    for s in range(13, 16):
        kernels.stage_state(integ.y_old, K_extended, A[s], s, h, y_stage)
        K_extended[s] = integ.fun(integ.t_old + c[s] * h, y_stage)
    integ.nfev += 3
    F = np.empty((7, integ.n))
    f_old = K_extended[0]
    delta_y = integ.y - integ.y_old
    F[0] = delta_y
    F[1] = h * f_old - delta_y
    F[2] = 2 * delta_y - h * (integ.f + f_old)
    F[3:] = h * (tableaus.DOP853_DENSE @ K_extended)
    return Dop853DenseOutput(integ.t_old, integ.t, integ.y_old, F)


class DOP853(EmbeddedRungeKutta):
    """Dormand-Prince 8(5,3): 12 stages + FSAL, for tight tolerances; 7th-order dense output."""

    name = "dop853"
    order = 8
    tableau = tableaus.DOP853
    stiffness_boundary = 0.75 * 6.3937  # 75% of the real-axis stability radius, as for dopri5
    oscillatory_stability_radius = 6.0317

    def _setup(self):
        super()._setup()
        self.K_extended = np.empty((16, self.n))
        self.K = self.K_extended[:13]
        self.err3 = np.empty(self.n)

    def _estimate_error_norm(self, K, h, y_new):
        kernels.weighted_combination(K, tableaus.DOP853_ERR5, 13, 1.0, self.err)
        kernels.weighted_combination(K, tableaus.DOP853_ERR3, 13, 1.0, self.err3)
        if self.error_exclude_fn is not None:
            self.error_exclude_fn(y_new, self.err)
            self.error_exclude_fn(y_new, self.err3)
        e5 = kernels.scaled_sq_sum(self.err, self.y, y_new, self.atol, self.rtol, self.error_weight)
        e3 = kernels.scaled_sq_sum(self.err3, self.y, y_new, self.atol, self.rtol, self.error_weight)
        if e5 == 0.0 and e3 == 0.0:
            return 0.0
        self.err *= h  # keep the error estimate in state units for failure diagnostics
        return h * e5 / np.sqrt((e5 + 0.01 * e3) * max(self.n_weighted, 1))

    def _dense_output_impl(self):
        if self._dense_cache is None:
            self._dense_cache = dop853_dense_output(self, self.K_extended, self.h_previous)
        return self._dense_cache
