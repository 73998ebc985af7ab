"""Steady-state Kalman filter design (shell/analysis/kalman.py) against python-control's dlqe and lqe, the Riccati
equations' residuals, the covariance recursion run to convergence, and the estimator stepped by the compiled
state-space kernels against the textbook predict/update recursion with the same gains."""

from __future__ import annotations

import control
import numpy as np
import pytest

from shell.analysis.kalman import estimator, kalman_design
from shell.linear.kernels import state_space_output, state_space_update
from shell.linear.system import LinearSystemError


def _plant():
    """A sampled 4-state plant (a lightly damped mode and a drifting bias), 2 measurements, 3 noise inputs."""
    A = np.array([[0.98, 0.1, 0.0, 0.0], [-0.3, 0.97, 0.0, 0.1], [0.0, 0.0, 1.0, 0.05], [0.0, 0.0, 0.0, 0.99]])
    B = np.array([[0.0], [0.1], [0.0], [0.05]])
    G = np.array([[0.1, 0.0, 0.0], [1.0, 0.2, 0.0], [0.0, 0.0, 0.01], [0.0, 0.5, 1.0]])
    C = np.array([[1.0, 0.0, 1.0, 0.0], [0.0, 1.0, 0.0, 0.0]])
    D = np.array([[0.0], [0.02]])
    Q = np.diag([0.04, 0.01, 0.002])
    R = np.array([[0.01, 0.002], [0.002, 0.02]])
    return A, B, G, C, D, Q, R


def test_sampled_design_equals_dlqe():
    """Gains, covariance and error poles equal python-control's dlqe (which solves the same DARE with scipy) to
    1e-12; the a-priori covariance solves the DARE to round-off and equals the covariance recursion
    P <- A (P - P C^T (C P C^T + R)^-1 C P) A^T + G Q G^T iterated from G Q G^T to convergence (1e-10)."""
    A, B, G, C, D, Q, R = _plant()
    design = kalman_design(A, G, C, Q, R, sample_time=0.1)
    L, P, E = control.dlqe(A, G, C, Q, R)
    np.testing.assert_allclose(design.predictor_gain, L, rtol=1e-12, atol=1e-14)
    np.testing.assert_allclose(design.covariance, P, rtol=1e-12, atol=1e-14)
    np.testing.assert_allclose(np.sort_complex(design.error_poles), np.sort_complex(E), rtol=1e-12, atol=1e-14)
    GQG = G @ Q @ G.T
    P = design.covariance
    residual = A @ P @ A.T - A @ P @ C.T @ np.linalg.solve(C @ P @ C.T + R, C @ P @ A.T) + GQG - P
    assert np.max(np.abs(residual)) <= 1e-13 * np.max(np.abs(P))
    recursion = GQG.copy()
    for _ in range(5000):
        recursion = A @ (recursion - recursion @ C.T @ np.linalg.solve(C @ recursion @ C.T + R, C @ recursion)) @ A.T \
            + GQG
    np.testing.assert_allclose(P, recursion, rtol=1e-10, atol=1e-14)
    np.testing.assert_allclose(design.predictor_gain, A @ design.filter_gain, rtol=1e-14, atol=1e-16)
    np.testing.assert_allclose(design.posterior_covariance,
                               P - P @ C.T @ np.linalg.solve(C @ P @ C.T + R, C @ P), rtol=1e-12, atol=1e-15)


def test_continuous_design_equals_lqe():
    """A continuous plant (the sampled one's matrix logarithm / T would do; here a mode, a drift and a bias)."""
    A = np.array([[0.0, 1.0, 0.0], [-4.0, -0.4, 1.0], [0.0, 0.0, -0.01]])
    G = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]])
    C = np.array([[1.0, 0.0, 0.0]])
    Q, R = np.diag([0.5, 0.01]), np.array([[0.001]])
    design = kalman_design(A, G, C, Q, R)
    L, P, E = control.lqe(A, G, C, Q, R)
    np.testing.assert_allclose(design.predictor_gain, L, rtol=1e-12)
    np.testing.assert_allclose(design.covariance, P, rtol=1e-12)
    residual = A @ P + P @ A.T - P @ C.T @ np.linalg.solve(R, C @ P) + G @ Q @ G.T
    assert np.max(np.abs(residual)) <= 1e-12 * np.max(np.abs(P)) * np.max(np.abs(A))
    assert design.filter_gain is None and np.all(design.error_poles.real < 0)


def test_estimator_stepped_by_the_kernels_is_the_kalman_recursion():
    """The estimator system (inputs [u; y], output x[k|k]) stepped by state_space_output/update equals the
    predict/update recursion x[k|k] = x- + M (y - C x- - D u), x-[k+1] = A x[k|k] + B u to 1e-12, on a noisy
    run of the plant; and its estimation error stays within 4 sigma of the design's a-posteriori covariance."""
    A, B, G, C, D, Q, R = _plant()
    design = kalman_design(A, G, C, Q, R, sample_time=0.1)
    system = estimator(A, B, C, D, design)
    assert system.shape == (4, 3, 4) and system.sample_time == 0.1
    rng = np.random.default_rng(11)
    x, prior = np.array([0.5, -0.2, 0.3, 0.1]), np.zeros(4)
    state, work, estimate = np.zeros(4), np.zeros(4), np.zeros(4)
    M = design.filter_gain
    errors = []
    for k in range(400):
        u = np.array([np.sin(0.05 * k)])
        y = C @ x + D @ u + rng.multivariate_normal(np.zeros(2), R)
        posterior = prior + M @ (y - C @ prior - D @ u)
        stacked = np.concatenate([u, y])
        state_space_output(system.C, system.D, state, stacked, estimate)
        state_space_update(system.A, system.B, state, stacked, work)
        np.testing.assert_allclose(estimate, posterior, rtol=0, atol=1e-12 * max(1.0, np.max(np.abs(posterior))))
        prior = A @ posterior + B @ u
        errors.append(x - posterior)
        x = A @ x + B @ u + G @ rng.multivariate_normal(np.zeros(3), Q)
    sigma = np.sqrt(np.diag(design.posterior_covariance))
    assert np.all(np.abs(np.array(errors[50:])) < 4.5 * sigma)


@pytest.mark.parametrize("change, message", [
    (dict(R=np.array([[0.01, 0.0], [0.0, 0.0]])), r"R \(measurement noise covariance\): a covariance must be positive "
                                                   "definite"),
    (dict(Q=np.diag([0.04, -0.01, 0.002])), r"Q \(process noise covariance\): a covariance must be positive semi-definite"),
    (dict(Q=np.ones((2, 2))), r"Q \(process noise covariance\): expected shape \(3, 3\)"),
    (dict(R=np.array([[0.01, 0.002], [0.0, 0.02]])), "must be symmetric"),
    (dict(C=np.array([[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0]]), A=np.diag([0.9, 0.9, 1.2, 0.9])),
     "no stabilizing solution|must be stable"),
])
def test_refusals(change, message):
    A, B, G, C, D, Q, R = _plant()
    values = dict(A=A, G=G, C=C, Q=Q, R=R)
    values.update(change)
    with pytest.raises(LinearSystemError, match=message):
        kalman_design(values["A"], values["G"], values["C"], values["Q"], values["R"], 0.1, where="scene.yaml:7: kf")
