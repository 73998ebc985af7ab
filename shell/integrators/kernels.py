"""Compiled per-step arithmetic shared by the Runge-Kutta integrators.

Stage states ``y + h * sum_j a_ij k_j``, the propagated solution ``y + h * sum_i b_i k_i`` and the
weighted RMS error norm of HNW I Sec. II.4 eq. (4.11),
``||e|| = sqrt(mean((e_i / (atol_i + rtol * max(|y_i|, |y_new_i|)))**2))`` over the components that
take part in error control. All kernels write into caller-owned arrays and do not allocate.
"""
import numpy as np
from numba import njit


@njit(cache=True)
def stage_state(y, K, a_row, n_used, h, out):
    """out = y + h * sum_{j < n_used} a_row[j] * K[j]."""
    n = y.shape[0]
    for i in range(n):
        acc = 0.0
        for j in range(n_used):
            acc += a_row[j] * K[j, i]
        out[i] = y[i] + h * acc


@njit(cache=True)
def propagate(y, K, b, n_used, h, out):
    """out = y + h * sum_j b[j] K[j]; returns True when every component of out is finite."""
    n = y.shape[0]
    finite = True
    for i in range(n):
        acc = 0.0
        for j in range(n_used):
            acc += b[j] * K[j, i]
        v = y[i] + h * acc
        out[i] = v
        if not np.isfinite(v):
            finite = False
    return finite


@njit(cache=True)
def all_finite(x):
    for i in range(x.shape[0]):
        if not np.isfinite(x[i]):
            return False
    return True


@njit(cache=True)
def weighted_combination(K, w, n_used, h, out):
    """out = h * sum_j w[j] K[j] (an embedded error estimate)."""
    n = K.shape[1]
    for i in range(n):
        acc = 0.0
        for j in range(n_used):
            acc += w[j] * K[j, i]
        out[i] = h * acc


@njit(cache=True)
def remove_quaternion_gauge(err, y, w_indices):
    """Remove from err the component along each unit quaternion y[w:w+4] (its norm direction).

    A quaternion's norm is restored by renormalization after every step, so error along q itself (the
    gauge) says nothing about accuracy and must not shrink the step.
    """
    for w in w_indices:
        qq = 0.0
        eq = 0.0
        for k in range(4):
            qq += y[w + k] * y[w + k]
            eq += err[w + k] * y[w + k]
        if qq > 0.0:
            s = eq / qq
            for k in range(4):
                err[w + k] -= s * y[w + k]


@njit(cache=True)
def rms_error_norm(err, y, y_new, atol, rtol, weight, n_weighted):
    """Weighted RMS norm of err; weight[i] is 1.0 for controlled components and 0.0 for excluded ones."""
    acc = 0.0
    for i in range(err.shape[0]):
        if weight[i] != 0.0:
            scale = atol[i] + rtol * max(abs(y[i]), abs(y_new[i]))
            r = err[i] / scale
            acc += r * r
    if n_weighted == 0:
        return 0.0
    return np.sqrt(acc / n_weighted)


@njit(cache=True)
def scaled_sq_sum(err, y, y_new, atol, rtol, weight):
    """sum((err_i / scale_i)**2) over controlled components (DOP853's two-estimator norm)."""
    acc = 0.0
    for i in range(err.shape[0]):
        if weight[i] != 0.0:
            scale = atol[i] + rtol * max(abs(y[i]), abs(y_new[i]))
            r = err[i] / scale
            acc += r * r
    return acc


@njit(cache=True)
def hermite_cubic(x, h, y0, f0, y1, f1, out):
    """Cubic Hermite interpolant at theta = x in [0, 1] through (y0, f0) and (y1, f1) over a step h."""
    h00 = (1 + 2 * x) * (1 - x) * (1 - x)
    h10 = x * (1 - x) * (1 - x)
    h01 = x * x * (3 - 2 * x)
    h11 = x * x * (x - 1)
    for i in range(y0.shape[0]):
        out[i] = h00 * y0[i] + h * h10 * f0[i] + h01 * y1[i] + h * h11 * f1[i]
