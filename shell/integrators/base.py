"""The interface every flexshell integrator implements, and the pieces they share.

Modelled on scipy.integrate's ``OdeSolver``: an integrator advances ``y' = fun(t, y)`` from ``t0`` towards
``t_bound`` one accepted step per :meth:`Integrator.step`, never past ``t_bound``; :meth:`dense_output`
gives a continuous solution on the last step for event location and output at arbitrary times;
:meth:`reset` restarts after a state jump (event, discrete update) and :meth:`extend` moves ``t_bound``
(the shell's multi-rate scheduler integrates from one discrete sample time to the next).

Additions for multibody states:
- ``normalize(y)`` is applied in place to every accepted state (quaternion renormalization).
- ``error_exclude`` removes components from error control: an index array (those components are not
  controlled) or a callable ``exclude(y, err)`` editing ``err`` in place, e.g.
  :func:`quaternion_gauge` which removes the error along each quaternion (its norm, fixed by
  ``normalize``).
- counters ``nfev`` (derivative evaluations), ``njev`` (Jacobian evaluations), ``nlu`` (LU
  factorizations), ``nsteps`` (accepted steps), ``nrejected`` (rejected steps).
- on failure ``status == "failed"`` and ``message`` says when, why, and what to try; ``t``/``y`` keep the
  last good state and ``failed_t``/``failed_y`` the state that could not be advanced.
"""
import warnings

import numpy as np

from . import kernels

EPS = np.finfo(np.float64).eps


def quaternion_gauge(w_indices):
    """An ``error_exclude`` callable removing the error along each quaternion whose w is at ``w_indices``.

    ``w_indices`` are the positions of each scalar-first quaternion's w in the state vector (for a
    ``MultibodySystem`` state ``y = [q; u]`` these are ``system.quaternion_q_indices``).
    """
    w_indices = np.ascontiguousarray(w_indices, dtype=np.int64)

    def exclude(y, err):
        kernels.remove_quaternion_gauge(err, y, w_indices)

    exclude.quaternion_w_indices = w_indices
    return exclude


class DenseOutput:
    """Continuous solution on one step ``[t_min, t_max]``; ``sol(t)`` takes a scalar or a 1-D array."""

    def __init__(self, t_min, t_max):
        self.t_min = t_min
        self.t_max = t_max

    def __call__(self, t):
        t = np.asarray(t, dtype=np.float64)
        if t.ndim > 1:
            raise ValueError(f"dense output takes a scalar or a 1-D array of times, got shape {t.shape}")
        return self._evaluate(t)


class HermiteDenseOutput(DenseOutput):
    """Cubic Hermite interpolation through (y, f) at both ends of the step (3rd-order accurate)."""

    def __init__(self, t_old, t, y_old, f_old, y, f):
        super().__init__(t_old, t)
        self.h = t - t_old
        self.y_old = y_old.copy()
        self.f_old = f_old.copy()
        self.y = y.copy()
        self.f = f.copy()

    def _evaluate(self, t):
        x = (t - self.t_min) / self.h
        if t.ndim == 0:
            out = np.empty_like(self.y_old)
            kernels.hermite_cubic(float(x), self.h, self.y_old, self.f_old, self.y, self.f, out)
            return out
        out = np.empty((self.y_old.shape[0], t.shape[0]))
        col = np.empty_like(self.y_old)
        for j in range(t.shape[0]):
            kernels.hermite_cubic(float(x[j]), self.h, self.y_old, self.f_old, self.y, self.f, col)
            out[:, j] = col
        return out


class PolynomialDenseOutput(DenseOutput):
    """``y(t_old + x h) = y_old + h * Q @ [x, x**2, ..., x**p]`` (Runge-Kutta continuous extensions)."""

    def __init__(self, t_old, t, y_old, Q):
        super().__init__(t_old, t)
        self.h = t - t_old
        self.y_old = y_old.copy()
        self.Q = Q
        self.power = Q.shape[1]

    def _evaluate(self, t):
        x = (t - self.t_min) / self.h
        if t.ndim == 0:
            p = np.cumprod(np.full(self.power, x))
            return self.y_old + self.h * (self.Q @ p)
        p = np.cumprod(np.tile(x, (self.power, 1)), axis=0)
        return self.y_old[:, None] + self.h * (self.Q @ p)


def _as_positive_float(value, what, allow_inf=False):
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{what} must be a positive number of seconds, got {value!r}") from None
    if not (v > 0.0) or (np.isinf(v) and not allow_inf) or np.isnan(v):
        raise ValueError(f"{what} must be a positive{'' if allow_inf else ', finite'} number, got {value!r}")
    return v


class StepSizeControl:
    """First-step choice shared by the error-controlled methods (Hairer, Norsett & Wanner I, Sec. II.4)."""

    def _on_extend(self):
        if self.h_abs == 0.0:  # created or reset with t_bound == t: no first step chosen yet
            self.h_abs = self._initial_step()

    def _hairer_initial_step(self, error_order, weight=None, n_weighted=None):
        """h0 from |y0| and |f0|, refined with one explicit Euler step, for an error estimate of order
        ``error_order``; the norm is the RMS, or with ``weight`` the weighted RMS over ``n_weighted``."""
        interval = self.t_bound - self.t
        if interval == 0.0:
            return 0.0
        scale = self.atol + np.abs(self.y) * self.rtol
        if weight is None:
            def norm(z):
                return np.sqrt(np.mean(z ** 2))
        else:
            n_w = max(n_weighted, 1)

            def norm(z):
                return np.sqrt(np.sum(weight * z ** 2) / n_w)
        d0 = norm(self.y / scale)
        d1 = norm(self.f / scale)
        h0 = 1e-6 if (d0 < 1e-5 or d1 < 1e-5) else 0.01 * d0 / d1
        h0 = min(h0, interval)
        f1 = np.asarray(self.fun(self.t + h0, self.y + h0 * self.f), dtype=np.float64)
        self.nfev += 1
        d2 = norm((f1 - self.f) / scale) / h0
        if d1 <= 1e-15 and d2 <= 1e-15:
            h1 = max(1e-6, h0 * 1e-3)
        else:
            h1 = (0.01 / max(d1, d2)) ** (1.0 / error_order)
        return min(100 * h0, h1, interval, self.max_step)


class Integrator:
    """Base class. Subclasses set the class attributes and implement ``_step_impl`` and ``_dense_output_impl``.

    Class attributes: ``name``, ``order`` (global order of accuracy), ``adaptive`` (error-controlled
    step), ``implicit``, ``fixed_step`` (bool), ``options`` (what a scenario may set), ``compiled_stepping``.
    """

    name = ""
    order = 0
    adaptive = False
    implicit = False
    fixed_step = False
    #: the options a scenario may give the method (``integrator.options``): name -> (unit, description)
    options: dict = {}
    #: its :class:`shell.integrators.compiled.CompiledStepping` when it steps in the compiled loop, else None
    compiled_stepping = None

    def __init__(self, fun, t0, y0, t_bound, *, step=None, rtol=1e-6, atol=1e-9, max_step=np.inf,
                 normalize=None, error_exclude=None):
        if not callable(fun):
            raise TypeError(f"{self.name}: fun must be a callable fun(t, y) -> ydot, got {type(fun).__name__}")
        self.fun = fun
        t0 = float(t0)
        t_bound = float(t_bound)
        if not (np.isfinite(t0) and np.isfinite(t_bound)):
            raise ValueError(f"{self.name}: t0 and t_bound must be finite, got t0={t0}, t_bound={t_bound}")
        if t_bound < t0:
            raise ValueError(f"{self.name}: integration runs forward in time; t_bound={t_bound} is before "
                             f"t0={t0}")
        y0 = np.array(y0, dtype=np.float64)
        if y0.ndim != 1 or y0.size == 0:
            raise ValueError(f"{self.name}: y0 must be a non-empty 1-D state vector, got shape {y0.shape}")
        bad = np.flatnonzero(~np.isfinite(y0))
        if bad.size:
            raise ValueError(f"{self.name}: y0 has non-finite components at indices {bad[:10].tolist()}")
        self.n = y0.shape[0]
        self.max_step = _as_positive_float(max_step, f"{self.name}: max_step", allow_inf=True)
        self.step_option = None if step is None else _as_positive_float(step, f"{self.name}: step")
        if self.fixed_step and step is None:
            raise ValueError(f"{self.name} is a fixed-step method: pass step=<seconds> (e.g. step=0.01)")
        rtol = float(rtol)
        if not (rtol > 0.0) or not np.isfinite(rtol):
            raise ValueError(f"{self.name}: rtol must be positive and finite, got {rtol!r}")
        if rtol < 100 * EPS:
            warnings.warn(f"{self.name}: rtol={rtol:g} is below what float64 arithmetic can deliver; "
                          f"using {100 * EPS:.3g}", stacklevel=3)
            rtol = 100 * EPS
        self.rtol = rtol
        atol_arr = np.array(atol, dtype=np.float64)
        if atol_arr.ndim == 0:
            atol_arr = np.full(self.n, float(atol_arr))
        if atol_arr.shape != (self.n,):
            raise ValueError(f"{self.name}: atol must be a scalar or have the state's shape ({self.n},), "
                             f"got shape {atol_arr.shape}")
        if not np.all(atol_arr > 0.0) or not np.all(np.isfinite(atol_arr)):
            raise ValueError(f"{self.name}: atol must be positive and finite (a zero atol makes the error "
                             f"of a component passing through zero unbounded), got {atol!r}")
        self.atol = atol_arr
        self.normalize = normalize
        self.error_weight = np.ones(self.n)
        self.error_exclude_fn = None
        if error_exclude is not None:
            if callable(error_exclude):
                self.error_exclude_fn = error_exclude
            else:
                idx = np.asarray(error_exclude, dtype=np.int64).ravel()
                if idx.size and (idx.min() < -self.n or idx.max() >= self.n):
                    raise ValueError(f"{self.name}: error_exclude indices must lie in [0, {self.n}), "
                                     f"got {idx.tolist()}")
                self.error_weight[idx] = 0.0
        self.n_weighted = int(np.count_nonzero(self.error_weight))

        self.nfev = 0
        self.njev = 0
        self.nlu = 0
        self.nsteps = 0
        self.nrejected = 0
        self.t = t0
        self.t_old = None
        self.t_bound = t_bound
        self.y = y0
        self.y_old = None
        self.f_old = None
        self.failed_t = None
        self.failed_y = None
        self.message = None
        self.status = "running"
        if normalize is not None:
            normalize(self.y)
        self.f = self._initial_derivative(t0, self.y)
        self.t_start = t0
        self.y_start = self.y.copy()
        self._setup()
        if self.t >= self.t_bound:
            self.status = "finished"

    # --- hooks for subclasses -----------------------------------------------------------------------
    def _setup(self):
        """Allocate work arrays and choose the first step (called once after the first derivative)."""

    def _on_reset(self):
        """Forget step history that a state jump invalidates."""

    def _on_extend(self):
        """React to a new t_bound (adaptive methods choose a first step if they never had room for one)."""

    def _step_impl(self):
        raise NotImplementedError

    def _dense_output_impl(self):
        raise NotImplementedError

    # --- public interface ---------------------------------------------------------------------------
    @property
    def step_size(self):
        """Size of the last accepted step (None before the first one)."""
        return None if self.t_old is None else self.t - self.t_old

    def step(self):
        """Advance one accepted step towards t_bound; sets t_old, t, y, f, status (and message on failure)."""
        if self.status != "running":
            raise RuntimeError(f"{self.name}: cannot step, status is '{self.status}'"
                               + (f" ({self.message})" if self.message else "")
                               + "; call reset(t, y, t_bound) or extend(t_bound) first")
        if self._step_impl():
            self.nsteps += 1
            if self.t >= self.t_bound:
                self.t = self.t_bound
                self.status = "finished"
        return self.status

    def dense_output(self):
        """Continuous solution on the last accepted step [t_old, t]."""
        if self.t_old is None:
            raise RuntimeError(f"{self.name}: dense output needs at least one step since the last reset")
        return self._dense_output_impl()

    def reset(self, t, y, t_bound):
        """Restart at (t, y) towards t_bound after the state jumped (event, discrete update)."""
        t = float(t)
        t_bound = float(t_bound)
        if t_bound < t:
            raise ValueError(f"{self.name}: reset to t={t} with t_bound={t_bound} before it")
        y = np.array(y, dtype=np.float64)
        if y.shape != (self.n,):
            raise ValueError(f"{self.name}: reset state must have shape ({self.n},), got {y.shape}")
        if self.normalize is not None:
            self.normalize(y)
        self.t = t
        self.y = y
        self.t_bound = t_bound
        self.t_old = None
        self.y_old = None
        self.f_old = None
        self.failed_t = None
        self.failed_y = None
        self.message = None
        self.status = "running"
        self.f = self._initial_derivative(t, y)
        self.t_start = t
        self.y_start = y.copy()
        self._on_reset()
        if self.t >= self.t_bound:
            self.status = "finished"

    def extend(self, t_bound):
        """Move t_bound forward without touching the state (next sample time of a discrete rate)."""
        t_bound = float(t_bound)
        if t_bound < self.t:
            raise ValueError(f"{self.name}: extend to t_bound={t_bound} before the current time {self.t}")
        if self.status == "failed":
            raise RuntimeError(f"{self.name}: cannot extend a failed run ({self.message}); reset it first")
        self.t_bound = t_bound
        self.status = "finished" if self.t >= t_bound else "running"
        if self.status == "running":
            self._on_extend()

    # --- shared helpers -----------------------------------------------------------------------------
    def _initial_derivative(self, t, y):
        f = np.array(self.fun(t, y), dtype=np.float64)
        self.nfev += 1
        if f.shape != (self.n,):
            raise ValueError(f"{self.name}: fun(t, y) must return an array of shape ({self.n},) like y, "
                             f"got shape {f.shape}")
        bad = np.flatnonzero(~np.isfinite(f))
        if bad.size:
            raise ValueError(f"{self.name}: fun({t:.9g}, y) returned non-finite derivatives at state "
                             f"indices {bad[:10].tolist()}; check the model at this state")
        return f

    def _error_norm(self, err, y_new):
        if self.error_exclude_fn is not None:
            self.error_exclude_fn(y_new, err)
        return kernels.rms_error_norm(err, self.y, y_new, self.atol, self.rtol, self.error_weight,
                                      self.n_weighted)

    def _fail(self, reason, t_failed, y_failed, suggestion):
        self.status = "failed"
        self.failed_t = float(t_failed)
        self.failed_y = None if y_failed is None else np.array(y_failed, dtype=np.float64)
        self.message = (f"{self.name} failed at t={self.t:.12g} s: {reason}. The last good state is "
                        f"integrator.t / integrator.y; the state that failed is integrator.failed_y "
                        f"(t={self.failed_t:.12g} s). {suggestion}")
        return False

    def _nonfinite_reason(self, what, t_eval, values):
        bad = np.flatnonzero(~np.isfinite(values))
        return f"{what} at t={t_eval:.12g} s is not finite in state components {bad[:10].tolist()}"

    def estimate_spectral_radius(self, t=None, y=None, iterations=12):
        """Estimate the largest |eigenvalue| of df/dy at (t, y) by power iteration on finite-difference
        Jacobian-vector products (used to explain stability failures; costs ``iterations + 1`` calls)."""
        t = self.t if t is None else t
        y = self.y if y is None else y
        f0 = np.asarray(self.fun(t, y), dtype=np.float64)
        self.nfev += 1
        rng = np.random.default_rng(12345)
        v = rng.standard_normal(self.n)
        v /= np.linalg.norm(v)
        ynorm = max(np.linalg.norm(y), 1.0)
        log_growth = 0.0
        for _ in range(iterations):
            delta = np.sqrt(EPS) * ynorm
            jv = (np.asarray(self.fun(t, y + delta * v), dtype=np.float64) - f0) / delta
            self.nfev += 1
            norm = np.linalg.norm(jv)
            if not np.isfinite(norm) or norm == 0.0:
                return float(norm) if np.isfinite(norm) else float("nan")
            log_growth += np.log(norm)
            v = jv / norm
        return float(np.exp(log_growth / iterations))
