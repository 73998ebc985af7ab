"""Every Butcher table satisfies the Runge-Kutta order conditions of its order (and fails the next one);
Radau IIA is L-stable; the stability radii used in the stability study are the textbook values."""

import numpy as np
import pytest
from numpy.testing import assert_allclose

from shell.integrators import stability, tableaus


def rooted_trees(max_order):
    """Rooted trees up to max_order as nested sorted tuples (a tree is the tuple of its children)."""
    by_order = {1: [()]}
    for n in range(2, max_order + 1):
        smaller = [t for k in range(1, n) for t in by_order[k]]
        order_of = {t: k for k in range(1, n) for t in by_order[k]}
        found = set()

        def extend(children, remaining, start):
            if remaining == 0:
                found.add(tuple(sorted(children)))
                return
            for idx in range(start, len(smaller)):
                t = smaller[idx]
                if order_of[t] <= remaining:
                    extend(children + [t], remaining - order_of[t], idx)

        extend([], n - 1, 0)
        by_order[n] = sorted(found)
    return by_order


TREES = rooted_trees(8)
# known counts of rooted trees (OEIS A000081): a check on the generator itself
assert [len(TREES[n]) for n in range(1, 9)] == [1, 1, 2, 4, 9, 20, 48, 115]


def _order(t):
    return 1 + sum(_order(c) for c in t)


def _density(t):
    return _order(t) * np.prod([_density(c) for c in t]) if t else 1.0


def _stage_weights(A, t):
    g = np.ones(A.shape[0])
    for c in t:
        g = g * (A @ _stage_weights(A, c))
    return g


def max_satisfied_order(A, b, tol=1e-12, up_to=8):
    """Largest p such that b . Phi(t) = 1 / gamma(t) for every tree of order <= p."""
    for n in range(1, up_to + 1):
        for t in TREES[n]:
            if abs(b @ _stage_weights(A, t) - 1.0 / _density(t)) > tol:
                return n - 1
    return up_to


@pytest.mark.parametrize("tb", [tableaus.EULER, tableaus.HEUN, tableaus.RK4, tableaus.BS32, tableaus.DOPRI5,
                                tableaus.RK8], ids=lambda tb: tb.name)
def test_propagating_formula_has_its_order(tb):
    assert max_satisfied_order(tb.A, tb.b, up_to=min(tb.order + 1, 8)) == tb.order


@pytest.mark.parametrize("tb, embedded_order", [(tableaus.BS32, 2), (tableaus.DOPRI5, 4)], ids=["bs32", "dopri5"])
def test_embedded_formula_has_the_error_estimator_order(tb, embedded_order):
    # b_hat = b - e over the s stages plus the FSAL stage (c = 1, a row = b)
    s = tb.n_stages
    A = np.zeros((s + 1, s + 1))
    A[:s, :s] = tb.A
    A[s, :s] = tb.b
    b_hat = np.append(tb.b, 0.0) - tb.error_weights
    assert max_satisfied_order(A, b_hat, up_to=embedded_order + 1) == embedded_order


def test_dop853_error_estimators_are_5th_and_3rd_order():
    A = tableaus.DOP853_A_EXTENDED[:13, :13]
    b = np.append(tableaus.DOP853.b, 0.0)
    # the 5th-order estimator's weights are b - b_hat5 scaled; the 3rd-order one is b - b_hat3
    assert max_satisfied_order(A, b - tableaus.DOP853_ERR3, up_to=4) == 3
    err5 = tableaus.DOP853_ERR5
    # err5 annihilates every condition up to order 5 (it is a difference of two 5th-order formulas)
    for n in range(1, 6):
        for t in TREES[n]:
            assert abs(err5 @ _stage_weights(A, t)) < 1e-12


@pytest.mark.parametrize("tb, dense_order", [(tableaus.BS32, 3), (tableaus.DOPRI5, 4)], ids=["bs32", "dopri5"])
def test_continuous_extension_order(tb, dense_order):
    # b_i(theta) = sum_k P_ik theta^(k+1) must satisfy b(theta) . Phi(t) = theta^|t| / gamma(t)
    s = tb.n_stages
    A = np.zeros((s + 1, s + 1))
    A[:s, :s] = tb.A
    A[s, :s] = tb.b
    for theta in (0.3, 0.7, 1.0):
        b_theta = tb.dense_weights @ theta ** np.arange(1, tb.dense_weights.shape[1] + 1)
        for n in range(1, dense_order + 1):
            for t in TREES[n]:
                assert abs(b_theta @ _stage_weights(A, t) - theta ** n / _density(t)) < 1e-12


def test_radau_iia_is_order_5_collocation_and_l_stable():
    A, c = tableaus.RADAU_A, tableaus.RADAU_C
    b = A[-1]
    for k in range(1, 6):
        assert abs(b @ c ** (k - 1) - 1.0 / k) < 1e-14  # B(5)
    for k in range(1, 4):
        assert_allclose(A @ c ** (k - 1), c ** k / k, atol=1e-14)  # C(3)
    assert max_satisfied_order(A, b, up_to=6) == 5

    def R(z):
        return 1 + z * b @ np.linalg.solve(np.eye(3) - z * A, np.ones(3))

    assert abs(R(-1e8)) < 1e-7  # L-stable: R(-inf) = 0
    for y in np.logspace(-2, 4, 50):  # A-stable: |R| <= 1 on the imaginary axis
        assert abs(R(1j * y)) <= 1 + 1e-12
    # the transformation used by the Newton iteration
    lam = tableaus.RADAU_T_INV @ np.linalg.inv(A) @ tableaus.RADAU_T
    expected = np.array([[tableaus.RADAU_GAMMA, 0, 0], [0, tableaus.RADAU_ALPHA, tableaus.RADAU_BETA],
                         [0, -tableaus.RADAU_BETA, tableaus.RADAU_ALPHA]])
    assert_allclose(lam, expected, atol=1e-12)


def test_stability_radii_match_textbook_values():
    # HW II Sec. IV.2, Fig. 2.1: RK4 real-axis limit 2.785, imaginary-axis limit 2 sqrt(2);
    # Euler real-axis limit 2 and no stable undamped oscillation; Heun real-axis limit 2
    assert stability.stability_radius(tableaus.RK4, np.pi) == pytest.approx(2.785293563, abs=1e-8)
    assert stability.stability_radius(tableaus.RK4, np.pi / 2) == pytest.approx(2 * np.sqrt(2), abs=1e-8)
    assert stability.stability_radius(tableaus.EULER, np.pi) == pytest.approx(2.0, abs=1e-9)
    assert stability.stability_radius(tableaus.EULER, np.pi / 2) < 1e-6  # |1 + iy| > 1 for every y > 0
    assert stability.stability_radius(tableaus.HEUN, np.pi) == pytest.approx(2.0, abs=1e-9)
    # the stiffness thresholds of the adaptive pairs are 75% of these real-axis radii
    assert stability.stability_radius(tableaus.DOPRI5, np.pi) == pytest.approx(3.3066, abs=1e-4)
    assert stability.stability_radius(tableaus.DOP853, np.pi) == pytest.approx(6.3937, abs=1e-4)
    # radii along a 1%-damped ray used to confirm stiffness warnings
    one_percent = stability.mode_angle(0.01)
    assert stability.stability_radius(tableaus.DOPRI5, one_percent) == pytest.approx(1.8721, abs=1e-4)
    assert stability.stability_radius(tableaus.DOP853, one_percent) == pytest.approx(6.0317, abs=1e-4)
    # Euler on a damped mode: |1 + h lambda| <= 1  <=>  h omega <= 2 zeta
    zeta = 0.02
    assert stability.max_stable_step(tableaus.EULER, 1.0, zeta) == pytest.approx(2 * zeta, rel=1e-8)
