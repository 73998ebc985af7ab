"""The small solves of the articulated-body recursion against numpy's LAPACK: the factored modal mass applied to
rows (:func:`dynamics.flexible_kernels.modal_mass_solve_rows`, six rows per sweep since 2026-12-07) and the hinge's
``D^-1`` (:func:`dynamics.kernels.small_linalg.spd_inverse`, with the pivots' reciprocals) and the solve with a Cholesky
factor of the dense solver (:func:`dynamics.flexible_kernels.cholesky_solve`).

References and tolerances: ``numpy.linalg.solve`` and ``numpy.linalg.inv`` of the same matrices, which are well
conditioned here (condition numbers below 1e3): both sides are then good to a few eps times the condition number,
so 1e-12 relative to the largest entry leaves a margin of 5 or more over what either side can lose; a wrong index,
a row skipped or solved twice with the wrong right-hand side, or a reciprocal applied twice gives an error of order
one. The forward dynamics through these solves (children on nodes: Woodbury ranks 12 and 24, taken six rows per
sweep) is checked against the dense solve in ``tests/flexible/test_modal_condensation.py``.
"""

from __future__ import annotations

import numpy as np
import pytest

from dynamics import flexible_kernels as FK
from dynamics import layout as L
from dynamics.kernels.small_linalg import spd_inverse


def spd(n, seed, condition=100.0):
    """A symmetric positive definite n x n matrix with eigenvalues from 1 to ``condition``."""
    rng = np.random.default_rng(seed)
    Q, _ = np.linalg.qr(rng.standard_normal((n, n)))
    return (Q * np.geomspace(1.0, condition, n)) @ Q.T


@pytest.mark.parametrize("n", [1, 2, 7, 20, 45])
@pytest.mark.parametrize("rows", [1, 2, 5, 6, 7, 12, 13])
def test_factored_modal_mass_solve_equals_lapack(n, rows):
    G = spd(n, seed=n + 100 * rows)
    X = np.random.default_rng(rows).standard_normal((rows, n))
    factor = G.copy()
    assert FK.cholesky_in_place(factor, n) < 0
    out = np.full((rows, n), np.nan)
    fx = np.full(L.N_FX, -1, dtype=np.int64)
    FK.modal_mass_solve_rows(fx, L.GINV_FACTORED, np.zeros(1), n, factor, X, rows, out)
    reference = np.linalg.solve(G, X.T).T  # G symmetric: X G^-1 = (G^-1 X')'
    assert np.abs(out - reference).max() <= 1e-12 * np.abs(reference).max()


@pytest.mark.parametrize("n", [1, 2, 3, 4, 5, 6])
def test_spd_inverse_equals_lapack(n):
    D = np.zeros((6, 6))
    D[:n, :n] = spd(n, seed=n, condition=1e3)
    scratch = np.full((6, 6), np.nan)
    out = np.full((6, 6), np.nan)
    assert spd_inverse(D, n, 1e-14 * np.trace(D), scratch, out)
    reference = np.linalg.inv(D[:n, :n])
    assert np.abs(out[:n, :n] - reference).max() <= 1e-12 * np.abs(reference).max()


def test_spd_inverse_refuses_a_singular_block():
    D = spd(6, seed=3)
    D[:, 5] = D[:, 0]
    D[5, :] = D[0, :]  # row and column 5 repeat row and column 0: positive semidefinite, singular
    assert not spd_inverse(D, 6, 1e-14 * np.trace(D), np.zeros((6, 6)), np.zeros((6, 6)))


@pytest.mark.parametrize("n", [1, 3, 50, 200])
def test_cholesky_solve_equals_lapack(n):
    # the dense solver's and the constraints' solve (dynamics.kernels.dense_forward, dynamics.constraint_kernels)
    G = spd(n, seed=7 * n)
    factor = G.copy()
    assert FK.cholesky_in_place(factor, n) < 0
    y = np.random.default_rng(n).standard_normal(n)
    reference = np.linalg.solve(G, y)
    FK.cholesky_solve(factor, n, y)
    assert np.abs(y - reference).max() <= 1e-12 * np.abs(reference).max()
