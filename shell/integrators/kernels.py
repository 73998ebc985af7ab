"""Compiled per-step arithmetic shared by the Runge-Kutta integrators.

Stage states ``y + h * sum_j a_ij k_j``, the propagated solution ``y + h * sum_i b_i k_i`` and the
weighted RMS error norm of HNW I Sec. II.4 eq. (4.11),
``||e|| = sqrt(mean((e_i / (atol_i + rtol * max(|y_i|, |y_new_i|)))**2))`` over the components that
take part in error control. All kernels write into caller-owned arrays and do not allocate.
"""
import numpy as np
from numba import njit


@njit(cache=True)
def copy_into(dst, src):
    """``dst[:] = src`` for 1-D arrays of equal length (the loop's own buffers): numba's slice assignment
    compiles a shape check whose error message (string formatting) cost ~4 s of every cold compile of the
    compiled loop."""
    for i in range(dst.shape[0]):
        dst[i] = src[i]


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


@njit(cache=True)
def stiffness_ratio(k_a, k_b, y_a, y_b):
    """``||k_b - k_a|| / ||y_b - y_a||``: a Rayleigh-quotient estimate of the dominant ``abs(eigenvalue)`` from two
    stages taken at the same time (HNW I Sec. IV.2); 0 when the two states coincide."""
    num = 0.0
    den = 0.0
    for i in range(k_a.shape[0]):
        dk = k_b[i] - k_a[i]
        dy = y_b[i] - y_a[i]
        num += dk * dk
        den += dy * dy
    if den == 0.0:
        return 0.0
    return np.sqrt(num / den)


@njit(cache=True)
def lu_factor_inplace(A, piv):
    """LU factorization with partial pivoting, in place (Doolittle; Golub & Van Loan Alg. 3.4.1).

    Works for float64 and complex128 matrices; ``piv[k]`` is the row swapped with row k. Returns False if
    a pivot is exactly zero (singular Newton matrix).
    """
    n = A.shape[0]
    for k in range(n):
        p = k
        best = abs(A[k, k])
        for i in range(k + 1, n):
            v = abs(A[i, k])
            if v > best:
                best = v
                p = i
        piv[k] = p
        if best == 0.0:
            return False
        if p != k:
            for j in range(n):
                tmp = A[k, j]
                A[k, j] = A[p, j]
                A[p, j] = tmp
        inv = 1.0 / A[k, k]
        for i in range(k + 1, n):
            A[i, k] *= inv
            lik = A[i, k]
            if lik != 0.0:
                for j in range(k + 1, n):
                    A[i, j] -= lik * A[k, j]
    return True


@njit(cache=True)
def lu_solve_inplace(LU, piv, b):
    """Solve LU x = P b in place in b (factors from :func:`lu_factor_inplace`)."""
    n = LU.shape[0]
    for k in range(n):
        p = piv[k]
        if p != k:
            tmp = b[k]
            b[k] = b[p]
            b[p] = tmp
    for i in range(n):
        acc = b[i]
        for j in range(i):
            acc -= LU[i, j] * b[j]
        b[i] = acc
    for i in range(n - 1, -1, -1):
        acc = b[i]
        for j in range(i + 1, n):
            acc -= LU[i, j] * b[j]
        b[i] = acc / LU[i, i]


@njit(cache=True)
def radau_newton_update(F, W, Z, LU_real, piv_real, LU_complex, piv_complex, TI, T, M_real, M_complex,
                        scale, rhs_real, rhs_complex):
    """One simplified-Newton update of the transformed Radau IIA stages (HW II eq. IV.8.16).

    rhs_real = (T^-1 F)_0 - M_real W_0, rhs_complex = (T^-1 F)_1 + i (T^-1 F)_2 - M_complex (W_1 + i W_2);
    solves with the real and complex LU factors, adds dW to W, sets Z = T W and returns the RMS norm of
    dW / scale.
    """
    n = F.shape[1]
    for i in range(n):
        g0 = TI[0, 0] * F[0, i] + TI[0, 1] * F[1, i] + TI[0, 2] * F[2, i]
        g1 = TI[1, 0] * F[0, i] + TI[1, 1] * F[1, i] + TI[1, 2] * F[2, i]
        g2 = TI[2, 0] * F[0, i] + TI[2, 1] * F[1, i] + TI[2, 2] * F[2, i]
        rhs_real[i] = g0 - M_real * W[0, i]
        rhs_complex[i] = (g1 + 1j * g2) - M_complex * (W[1, i] + 1j * W[2, i])
    lu_solve_inplace(LU_real, piv_real, rhs_real)
    lu_solve_inplace(LU_complex, piv_complex, rhs_complex)
    acc = 0.0
    for i in range(n):
        d0 = rhs_real[i]
        d1 = rhs_complex[i].real
        d2 = rhs_complex[i].imag
        s = scale[i]
        acc += (d0 / s) ** 2 + (d1 / s) ** 2 + (d2 / s) ** 2
        W[0, i] += d0
        W[1, i] += d1
        W[2, i] += d2
        Z[0, i] = T[0, 0] * W[0, i] + T[0, 1] * W[1, i] + T[0, 2] * W[2, i]
        Z[1, i] = T[1, 0] * W[0, i] + T[1, 1] * W[1, i] + T[1, 2] * W[2, i]
        Z[2, i] = T[2, 0] * W[0, i] + T[2, 1] * W[1, i] + T[2, 2] * W[2, i]
    return np.sqrt(acc / (3 * n))
