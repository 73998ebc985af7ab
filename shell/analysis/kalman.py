"""Steady-state Kalman filter design: the gains, the error covariance and the estimator as a linear system.

Plant, process noise w (covariance Q) entering through G, measurement noise v (covariance R), uncorrelated::

    sampled:     x[k+1] = A x[k] + B u[k] + G w[k],   y[k] = C x[k] + D u[k] + v[k]
    continuous:  x' = A x + B u + G w,                y = C x + D u + v

Sampled (the discrete algebraic Riccati equation of the a-priori covariance P = E[e e^T], e = x[k] - x[k|k-1];
Anderson and Moore, Optimal Filtering, 1979, Sec. 4.4)::

    P = A P A^T - A P C^T (C P C^T + R)^-1 C P A^T + G Q G^T
    M = P C^T (C P C^T + R)^-1            filter (measurement-update) gain: x[k|k] = x[k|k-1] + M (y - C x[k|k-1] - D u)
    L = A M                               predictor gain (python-control's and MATLAB's dlqe)
    P+ = (I - M C) P                      a-posteriori covariance

Continuous (Kalman-Bucy; the continuous algebraic Riccati equation)::

    A P + P A^T - P C^T R^-1 C P + G Q G^T = 0,   L = P C^T R^-1   (python-control's and MATLAB's lqe)

:func:`estimator` writes the steady-state filter as a :class:`~shell.linear.system.LinearSystem` with inputs
``[u; y]`` and output the estimate, ready for a StateSpace block: sampled, the current estimate ``x[k|k]``
(state ``x[k|k-1]``)::

    x[k+1|k] = (A - L C) x[k|k-1] + [B - L D, L] [u; y],    x[k|k] = (I - M C) x[k|k-1] + [-M D, M] [u; y]

continuous, ``x_hat' = (A - L C) x_hat + [B - L D, L] [u; y]``, output ``x_hat``.

Refused: shapes that disagree, Q not symmetric positive semi-definite, R not symmetric positive definite, a pair
(A, C) that is not detectable or noise that leaves an unstable mode unexcited (the Riccati equation then has no
stabilizing solution: scipy's solver raises, or the error dynamics A - L C are not stable).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.linalg import solve_continuous_are, solve_discrete_are

from shell.linear.system import LinearSystem, LinearSystemError, check_sample_time


@dataclass(frozen=True)
class KalmanDesign:
    """The steady-state filter of :func:`kalman_design` (module docstring for the symbols)."""

    predictor_gain: np.ndarray          # L
    filter_gain: np.ndarray | None      # M (sampled only)
    covariance: np.ndarray              # P (a priori when sampled)
    posterior_covariance: np.ndarray | None  # (I - M C) P (sampled only)
    error_poles: np.ndarray             # eigenvalues of A - L C
    sample_time: float | None


def _symmetric(where: str, key: str, value, size: int, definite: bool) -> np.ndarray:
    matrix = np.atleast_2d(np.asarray(value, dtype=float))
    if matrix.shape != (size, size):
        raise LinearSystemError(f"{where}: {key}: expected shape ({size}, {size}), given {matrix.shape}")
    if not np.all(np.isfinite(matrix)):
        raise LinearSystemError(f"{where}: {key}: expected finite entries")
    if not np.allclose(matrix, matrix.T, rtol=1e-12, atol=0.0):
        raise LinearSystemError(f"{where}: {key}: a covariance must be symmetric")
    smallest = float(np.min(np.linalg.eigvalsh(matrix), initial=np.inf))
    scale = max(float(np.max(np.abs(matrix), initial=0.0)), np.finfo(float).tiny)
    refused = smallest <= 0.0 if definite else smallest < -1e-12 * scale
    if refused:
        raise LinearSystemError(f"{where}: {key}: a covariance must be positive {'' if definite else 'semi-'}"
                                f"definite; its smallest eigenvalue is {smallest:.6g}")
    return matrix


def kalman_design(A, G, C, Q, R, sample_time=None, where: str = "Kalman filter") -> KalmanDesign:
    """The steady-state Kalman filter of the plant ``(A, G, C)`` with process and measurement noise
    covariances Q and R (module docstring); ``sample_time`` None for the continuous (Kalman-Bucy) filter."""
    sample_time = check_sample_time(sample_time, where)
    try:
        A, G, C = (np.atleast_2d(np.asarray(v, dtype=float)) for v in (A, G, C))
    except (TypeError, ValueError) as exc:
        raise LinearSystemError(f"{where}: A, G, C: expected matrices of numbers ({exc})") from None
    system = LinearSystem(A, G, C, np.zeros((C.shape[0], G.shape[1])), sample_time, where=where)
    Q = _symmetric(where, "Q (process noise covariance)", Q, G.shape[1], definite=False)
    R = _symmetric(where, "R (measurement noise covariance)", R, C.shape[0], definite=True)
    GQG = system.B @ Q @ system.B.T
    try:
        if sample_time is None:
            P = solve_continuous_are(A.T, C.T, GQG, R)
        else:
            P = solve_discrete_are(A.T, C.T, GQG, R)
    except (np.linalg.LinAlgError, ValueError) as exc:
        raise LinearSystemError(f"{where}: the Riccati equation has no stabilizing solution ({exc}): is every "
                                "unstable mode seen by C and driven by the noise G w?") from None
    P = 0.5 * (P + P.T)
    if sample_time is None:
        L, M, posterior = np.linalg.solve(R, C @ P).T, None, None
    else:
        M = np.linalg.solve(C @ P @ C.T + R, C @ P).T
        L = A @ M
        posterior = (np.eye(A.shape[0]) - M @ C) @ P
        posterior = 0.5 * (posterior + posterior.T)
    poles = np.linalg.eigvals(A - L @ C)
    error = LinearSystem(A - L @ C, np.zeros((A.shape[0], 0)), np.zeros((0, A.shape[0])), np.zeros((0, 0)),
                         sample_time, where=where)
    error.require_stable("the estimation error dynamics A - L C")
    return KalmanDesign(L, M, P, posterior, poles, sample_time)


def estimator(A, B, C, D, design: KalmanDesign, where: str = "Kalman filter") -> LinearSystem:
    """The steady-state filter as a system from ``[u; y]`` to the state estimate (module docstring)."""
    plant = LinearSystem(A, B, C, D, design.sample_time, where=where)
    A, B, C, D = plant.A, plant.B, plant.C, plant.D
    L = design.predictor_gain
    if L.shape != (A.shape[0], C.shape[0]):
        raise LinearSystemError(f"{where}: the design's gain is {L.shape}, the plant needs "
                                f"{(A.shape[0], C.shape[0])}")
    n = A.shape[0]
    inputs = np.hstack([B - L @ D, L])
    if design.sample_time is None:
        return LinearSystem(A - L @ C, inputs, np.eye(n), np.zeros((n, inputs.shape[1])), None, where=where)
    M = design.filter_gain
    return LinearSystem(A - L @ C, inputs, np.eye(n) - M @ C, np.hstack([-M @ D, M]), design.sample_time,
                        where=where)
