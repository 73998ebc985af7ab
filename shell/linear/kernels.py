"""The per-step kernels of the linear and signal-shaping blocks: compiled, allocation-free, over float64 arrays.

    state space, continuous   x' = A x + B u                      (state_space_derivative)
    state space, sampled      x[k+1] = A x[k] + B u[k]            (state_space_update)
    either                    y = C x + D u                       (state_space_output)
    delay line                y[k] = u[k - N]                     (delay_line_update; N = 0: y[k] = u[k])
    saturation                y = min(max(u, lower), upper)
    dead zone                 y = u - upper (u > upper), u - lower (u < lower), 0 between
    rate limiter, sampled     y[k] = y[k-1] + min(max(u[k] - y[k-1], -falling T), rising T)

Transfer functions and second-order filters are state-space systems here (:mod:`shell.linear.realization` makes
their matrices), so one pair of kernels serves every linear block. The matrices are 2-D arrays: a model whose
parameters are one flat vector passes row-major views of it (``p[a:b].reshape(n, n)`` allocates nothing).
Every kernel writes into arrays it is given; the sampled update needs a work vector of n entries because
``x[k+1]`` is formed from all of ``x[k]``.
"""

from __future__ import annotations

from numba import njit


@njit(cache=True)
def _matrix_sum(M, x, N, u, out):
    """``out = M x + N u``."""
    for i in range(out.shape[0]):
        acc = 0.0
        for j in range(x.shape[0]):
            acc += M[i, j] * x[j]
        for j in range(u.shape[0]):
            acc += N[i, j] * u[j]
        out[i] = acc


@njit(cache=True)
def state_space_derivative(A, B, x, u, xdot):
    """``xdot = A x + B u``."""
    _matrix_sum(A, x, B, u, xdot)


@njit(cache=True)
def state_space_output(C, D, x, u, y):
    """``y = C x + D u``."""
    _matrix_sum(C, x, D, u, y)


@njit(cache=True)
def state_space_update(A, B, x, u, work):
    """``x <- A x + B u`` in place, through ``work`` (n entries)."""
    state_space_derivative(A, B, x, u, work)
    for i in range(x.shape[0]):
        x[i] = work[i]


@njit(cache=True)
def delay_line_update(buffer, head, u, y):
    """One sample of an N-sample delay: ``y = u`` of N samples ago, then ``u`` stored. ``buffer`` is (N, m), its
    row ``head`` the oldest sample; returns the next head. N = 0 passes ``u`` through."""
    depth = buffer.shape[0]
    if depth == 0:
        for j in range(u.shape[0]):
            y[j] = u[j]
        return head
    for j in range(u.shape[0]):
        y[j] = buffer[head, j]
        buffer[head, j] = u[j]
    return (head + 1) % depth


@njit(cache=True)
def saturation(u, lower, upper, y):
    """``y = min(max(u, lower), upper)`` element by element."""
    for j in range(u.shape[0]):
        y[j] = min(max(u[j], lower[j]), upper[j])


@njit(cache=True)
def dead_zone(u, lower, upper, y):
    """``y = u - upper`` above ``upper``, ``u - lower`` below ``lower``, 0 between (element by element)."""
    for j in range(u.shape[0]):
        if u[j] > upper[j]:
            y[j] = u[j] - upper[j]
        elif u[j] < lower[j]:
            y[j] = u[j] - lower[j]
        else:
            y[j] = 0.0


@njit(cache=True)
def rate_limited(y, u, falling_step, rising_step):
    """``y + min(max(u - y, -falling_step), rising_step)``: one sample of a rate limiter, one channel."""
    return y + min(max(u - y, -falling_step), rising_step)


@njit(cache=True)
def rate_limiter_update(y, u, falling_step, rising_step):
    """``y <- y + min(max(u - y, -falling_step), rising_step)`` in place: the output moves toward ``u`` by at
    most ``rising_step`` up or ``falling_step`` down per sample (rate limit times the period)."""
    for j in range(u.shape[0]):
        y[j] = rate_limited(y[j], u[j], falling_step[j], rising_step[j])
