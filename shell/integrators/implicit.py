"""Radau IIA of order 5: the L-stable implicit integrator for stiff flexible modes.

Method (HW II Sec. IV.5 and IV.8, the algorithm of the authors' RADAU5 code):
- 3-stage collocation at the Radau points c = ((4 - sqrt 6)/10, (4 + sqrt 6)/10, 1); with z_i = Y_i - y the
  stage equations are ``Z = h (A x I) F(y + Z)``; ``y_new = y + z_3`` (stiffly accurate, L-stable, order 5).
- Simplified Newton with one Jacobian J per step: transforming W = (T^-1 x I) Z with
  T^-1 A^-1 T = diag(gamma, [[alpha, beta], [-beta, alpha]]) splits the 3n x 3n Newton matrix into the real
  system ``(gamma/h I - J)`` and the complex system ``((alpha - i beta)/h I - J)`` (HW II eq. IV.8.16).
  Iteration stops when the convergence-rate estimate ``theta/(1 - theta) ||dW|| < kappa * min(0.03, sqrt(rtol))``
  and is abandoned when it diverges (theta >= 1) or will not converge in 6 iterations.
- Error estimate (HW II eq. IV.8.19-8.20): ``err = (gamma/h I - J)^-1 (f(t, y) + (e . Z)/h)``, filtered once
  more through f after a rejection to stay bounded for very stiff components.
- Step-size control: Gustafsson's predictive controller (HW II eq. IV.8.25), safety factor reduced when
  Newton needed many iterations; the LU factorizations are reused while the step changes by < 20%.
- Jacobian: the user's ``jac(t, y)`` (array or callable), else forward differences column by column
  (n derivative evaluations, counted in ``nfev``; ``njev`` counts Jacobian evaluations).
- Dense output: the collocation polynomial through (t, y) and the three stages (3rd order, continuous).
"""
import numpy as np

from . import kernels, tableaus
from .base import EPS, DenseOutput, Integrator, StepSizeControl

NEWTON_MAXITER = 6
MIN_FACTOR = 0.2
MAX_FACTOR = 10.0

C = tableaus.RADAU_C
E = tableaus.RADAU_ERROR_WEIGHTS
GAMMA = tableaus.RADAU_GAMMA
MU_COMPLEX = tableaus.RADAU_ALPHA - 1j * tableaus.RADAU_BETA
T = tableaus.RADAU_T
TI = tableaus.RADAU_T_INV
TI_REAL = TI[0]
TI_COMPLEX = TI[1] + 1j * TI[2]
# collocation polynomial u(x) = sum_k q_k x^k (k = 1..3) with u(c_i) = z_i:  Q = Z^T P, P = V^-T
COLLOCATION_P = np.linalg.inv(np.column_stack([C, C ** 2, C ** 3])).T


class RadauDenseOutput(DenseOutput):
    def __init__(self, t_old, t, y_old, Q):
        super().__init__(t_old, t)
        self.h = t - t_old
        self.y_old = y_old
        self.Q = Q

    def _evaluate(self, t):
        x = (t - self.t_min) / self.h
        if t.ndim == 0:
            return self.y_old + self.Q @ np.array([x, x * x, x * x * x])
        p = np.vstack([x, x * x, x * x * x])
        return self.y_old[:, None] + self.Q @ p


class Radau5(StepSizeControl, Integrator):
    """Radau IIA order 5, adaptive step, simplified Newton, L-stable (recommended for stiff flexible modes)."""

    name = "radau5"
    order = 5
    adaptive = True
    implicit = True
    options = {"rtol": ("", "relative tolerance of the error control"),
               "atol": ("", "absolute tolerance of the error control (state units)"),
               "max_step": ("s", "largest step")}

    def __init__(self, fun, t0, y0, t_bound, *, jac=None, **options):
        if jac is not None and not callable(jac):
            jac_arr = np.asarray(jac, dtype=np.float64)
            n = np.asarray(y0).size
            if jac_arr.shape != (n, n):
                raise ValueError(f"radau5: a constant jac must have shape ({n}, {n}), got {jac_arr.shape}")
        self.user_jac = jac
        super().__init__(fun, t0, y0, t_bound, **options)

    def _setup(self):
        self.newton_tol = max(10 * EPS / self.rtol, min(0.03, self.rtol ** 0.5))
        self.F = np.empty((3, self.n))
        self.LU_real = np.empty((self.n, self.n))
        self.LU_complex = np.empty((self.n, self.n), dtype=np.complex128)
        self.piv_real = np.empty(self.n, dtype=np.int64)
        self.piv_complex = np.empty(self.n, dtype=np.int64)
        self.rhs_real = np.empty(self.n)
        self.rhs_complex = np.empty(self.n, dtype=np.complex128)
        self.J = None
        self.h_abs = self._initial_step() if self.step_option is None else min(self.step_option, self.max_step)
        self._on_reset()

    def _on_reset(self):
        self.h_abs_old = None
        self.error_norm_old = None
        self.sol = None
        self.Z = None
        if getattr(self, "J", None) is None:
            self.J = self._jacobian(self.t, self.y, self.f)
            self.current_jac = True
            self.LU_h = None
        else:
            # a discrete update (held control input, mode switch) rarely changes df/dy much: keep J and its
            # LU, marked stale, so that a Newton failure refreshes it instead of paying n evaluations per sample
            self.current_jac = False

    def _initial_step(self):
        """With the order of the error estimator (3): exponent 1/4."""
        return self._hairer_initial_step(4)

    def _jacobian(self, t, y, f):
        self.njev += 1
        if self.user_jac is not None:
            J = self.user_jac(t, y) if callable(self.user_jac) else self.user_jac
            return np.array(J, dtype=np.float64)
        # forward differences; the increment balances truncation and round-off (HW II Sec. IV.8)
        J = np.empty((self.n, self.n))
        y_pert = y.copy()
        for j in range(self.n):
            delta = np.sqrt(EPS) * max(1e-5, abs(y[j]))
            y_pert[j] = y[j] + delta
            J[:, j] = (np.asarray(self.fun(t, y_pert), dtype=np.float64) - f) / delta
            y_pert[j] = y[j]
        self.nfev += self.n
        return J

    def _solve_collocation(self, t, y, h, Z0, scale):
        """Simplified Newton on the transformed stage equations; returns (converged, iterations, Z, rate)."""
        M_real = GAMMA / h
        M_complex = MU_COMPLEX / h
        W = TI @ Z0
        Z = Z0.copy()
        F = self.F
        ch = t + h * C
        dW_norm_old = None
        rate = None
        converged = False
        fun = self.fun
        k = 0
        for k in range(NEWTON_MAXITER):
            for i in range(3):
                F[i] = fun(ch[i], y + Z[i])
            self.nfev += 3
            if not kernels.all_finite(F.ravel()):
                break
            dW_norm = kernels.radau_newton_update(F, W, Z, self.LU_real, self.piv_real, self.LU_complex,
                                                  self.piv_complex, TI, T, M_real, M_complex, scale,
                                                  self.rhs_real, self.rhs_complex)
            if dW_norm_old is not None:
                rate = dW_norm / dW_norm_old
            if rate is not None and (rate >= 1 or rate ** (NEWTON_MAXITER - k) / (1 - rate) * dW_norm
                                     > self.newton_tol):
                break
            if dW_norm == 0 or (rate is not None and rate / (1 - rate) * dW_norm < self.newton_tol):
                converged = True
                break
            dW_norm_old = dW_norm
        return converged, k + 1, Z, rate

    def _factorize(self, h):
        """LU factors of the real and complex Newton matrices (gamma/h I - J) and ((alpha - i beta)/h I - J)."""
        np.multiply(self.J, -1.0, out=self.LU_real)
        self.LU_real[np.diag_indices(self.n)] += GAMMA / h
        self.LU_complex[:] = -self.J
        self.LU_complex[np.diag_indices(self.n)] += MU_COMPLEX / h
        ok = kernels.lu_factor_inplace(self.LU_real, self.piv_real)
        ok &= kernels.lu_factor_inplace(self.LU_complex, self.piv_complex)
        self.LU_h = h if ok else None
        self.nlu += 1
        return ok

    def _lu_solve_real(self, b):
        x = np.array(b, dtype=np.float64)
        kernels.lu_solve_inplace(self.LU_real, self.piv_real, x)
        return x

    def _predict_factor(self, h_abs, error_norm):
        """Gustafsson's predictive controller (HW II eq. IV.8.25); an exact step (error 0: a state at rest, a
        polynomial solution) allows the largest growth, which the caller caps at MAX_FACTOR."""
        if error_norm == 0:
            return np.inf
        if self.error_norm_old is None or self.h_abs_old is None:
            multiplier = 1.0
        else:
            multiplier = h_abs / self.h_abs_old * (self.error_norm_old / error_norm) ** 0.25
        return min(1.0, multiplier) * error_norm ** -0.25

    def _accepted_step_factor(self, h, error_norm, safety, recompute_jac):
        """Next step / this step after an accepted step; kept at 1 (reusing the LU) unless it would grow by
        20% or the Jacobian is being refreshed anyway (HW II Sec. IV.8)."""
        factor = min(MAX_FACTOR, safety * self._predict_factor(h, error_norm))
        if not recompute_jac and factor < 1.2:
            return 1.0
        return factor

    def _step_impl(self):
        t = self.t
        y = self.y
        f = self.f
        min_step = 10.0 * abs(np.nextafter(t, np.inf) - t)
        h_abs = min(max(self.h_abs, min_step), self.max_step)
        rejected = False
        newton_failures = 0
        while True:
            if h_abs < min_step:
                return self._fail_underflow(h_abs, newton_failures)
            remaining = self.t_bound - t
            clipped = remaining <= h_abs * (1.0 + 1e-9)  # no round-off sliver before t_bound
            h = remaining if clipped else h_abs
            t_new = self.t_bound if clipped else t + h
            if self.sol is None:
                Z0 = np.zeros((3, self.n))
            else:
                Z0 = self.sol(t + h * C).T - y
            scale = self.atol + np.abs(y) * self.rtol
            converged = False
            while not converged:
                if self.LU_h != h:
                    if not self._factorize(h):
                        break
                converged, n_iter, Z, rate = self._solve_collocation(t, y, h, Z0, scale)
                if not converged:
                    if self.current_jac:
                        break
                    self.J = self._jacobian(t, y, f)
                    self.current_jac = True
                    self.LU_h = None
            if not converged:
                newton_failures += 1
                h_abs *= 0.5
                self.LU_h = None
                rejected = True
                self.nrejected += 1
                continue
            y_new = y + Z[-1]
            ZE = Z.T @ E / h
            error = self._lu_solve_real(f + ZE)
            error_norm = self._error_norm(error.copy(), y_new)
            safety = 0.9 * (2 * NEWTON_MAXITER + 1) / (2 * NEWTON_MAXITER + n_iter)
            if rejected and error_norm > 1:
                f_err = np.asarray(self.fun(t, y + error), dtype=np.float64)
                self.nfev += 1
                error = self._lu_solve_real(f_err + ZE)
                error_norm = self._error_norm(error.copy(), y_new)
            if not np.isfinite(error_norm):
                error_norm = np.inf
            if error_norm > 1:
                self.last_error = error
                h_abs *= max(MIN_FACTOR, safety * error_norm ** -0.25) if np.isfinite(error_norm) else MIN_FACTOR
                self.LU_h = None
                rejected = True
                self.nrejected += 1
                continue
            break

        recompute_jac = n_iter > 2 and rate is not None and rate > 1e-3
        factor = self._accepted_step_factor(h, error_norm, safety, recompute_jac)
        if self.normalize is not None:
            self.normalize(y_new)
        f_new = np.array(self.fun(t_new, y_new), dtype=np.float64)
        self.nfev += 1
        if not np.all(np.isfinite(f_new)):
            return self._fail(self._nonfinite_reason("the derivative fun(t, y)", t_new, f_new), t_new, y_new,
                              "Check the model for a singularity or invalid state near that time.")
        if recompute_jac:
            self.J = self._jacobian(t_new, y_new, f_new)
            self.current_jac = True
        else:
            self.current_jac = False
        self.h_abs_old = h
        self.error_norm_old = error_norm
        h_next = h * factor
        self.h_abs = max(h_next, h_abs) if (clipped and not rejected) else h_next
        self.t_old = t
        self.y_old = y
        self.f_old = f
        self.t = t_new
        self.y = y_new
        self.f = f_new
        self.Z = Z
        self.sol = RadauDenseOutput(t, t_new, y, Z.T @ COLLOCATION_P)
        return True

    def _fail_underflow(self, h_abs, newton_failures):
        rho = self.estimate_spectral_radius()
        reason = (f"step size underflow (h = {h_abs:.3g} s; {newton_failures} Newton failures at this step, "
                  f"{self.nrejected} rejected steps in total)")
        suggestion = ("The model is probably discontinuous or singular there (fastest eigenvalue |lambda| ~ "
                      f"{rho:.3g} rad/s): add an event function for the switch so the integrator restarts at "
                      "it, supply an exact jac, or check the model at that state.")
        return self._fail(reason, self.t + h_abs, None, suggestion)

    def _dense_output_impl(self):
        return self.sol
