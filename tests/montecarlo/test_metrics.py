"""Metrics against hand-computed values on short synthetic signals (exact to round-off: 1e-15)."""

import numpy as np
import pytest

from shell.montecarlo.metrics import Metric, evaluate, mapped_samples

TIME = np.arange(6) * 0.5
SIGNAL = np.array([[3.0, -4.0], [1.0, 0.0], [-2.0, 2.0], [0.5, 0.1], [0.2, -0.1], [0.1, 0.05]])


@pytest.mark.parametrize("statistic, expected", [
    ("final", [0.1, 0.05]),
    ("max", [3.0, 2.0]),
    ("min", [-2.0, -4.0]),
    ("max_abs", [3.0, 4.0]),
    ("mean", [(3 + 1 - 2 + 0.5 + 0.2 + 0.1) / 6, (-4 + 0 + 2 + 0.1 - 0.1 + 0.05) / 6]),
    ("rms", [np.sqrt((9 + 1 + 4 + 0.25 + 0.04 + 0.01) / 6), np.sqrt((16 + 0 + 4 + 0.01 + 0.01 + 0.0025) / 6)]),
])
def test_statistics_per_component(statistic, expected):
    metric = Metric("m", "s", statistic)
    np.testing.assert_allclose(evaluate(metric, TIME, mapped_samples(metric, SIGNAL)), expected, rtol=1e-15)


def test_norm_and_component():
    metric = Metric("m", "s", "max", of="norm")
    np.testing.assert_allclose(evaluate(metric, TIME, mapped_samples(metric, SIGNAL)), [5.0], rtol=1e-15)
    metric = Metric("m", "s", "final", component=1)
    assert evaluate(metric, TIME, mapped_samples(metric, SIGNAL)).tolist() == [0.05]


def test_settling_time():
    # |y0| <= 0.6 from t = 1.5 s on (samples 3..5); y1 from t = 1.5 s (|0.1|, |-0.1|, |0.05|)
    metric = Metric("m", "s", "settling_time", tolerance=0.6)
    assert evaluate(metric, TIME, mapped_samples(metric, SIGNAL)).tolist() == [1.5, 1.5]
    metric = Metric("m", "s", "settling_time", tolerance=0.15)
    assert evaluate(metric, TIME, mapped_samples(metric, SIGNAL)).tolist() == [2.5, 1.5]
    metric = Metric("m", "s", "settling_time", tolerance=0.05)   # last sample of y0 outside: not settled
    assert evaluate(metric, TIME, mapped_samples(metric, SIGNAL)).tolist() == [np.inf, 2.5]
    metric = Metric("m", "s", "settling_time", tolerance=10.0)   # inside from the first sample
    assert evaluate(metric, TIME, mapped_samples(metric, SIGNAL)).tolist() == [0.0, 0.0]
    metric = Metric("m", "s", "settling_time", tolerance=0.5, target=0.6)
    assert evaluate(metric, TIME, mapped_samples(metric, SIGNAL[:, :1])).tolist() == [1.5]


def test_quaternion_angle_short_way_round():
    angles = np.array([0.0, 0.3, 2.0, 3.0])
    axis = np.array([1.0, 2.0, 2.0]) / 3.0
    q = np.column_stack([np.cos(angles / 2), np.sin(angles / 2)[:, None] * axis])
    metric = Metric("m", "s", "max", of="quaternion_angle")
    np.testing.assert_allclose(mapped_samples(metric, q)[:, 0], angles, rtol=1e-15, atol=1e-15)
    np.testing.assert_allclose(mapped_samples(metric, -q)[:, 0], angles, rtol=1e-15, atol=1e-15)  # same rotation
    # beyond pi the short way round is 2 pi - angle
    big = np.array([[np.cos(2.0), *(np.sin(2.0) * axis)]])  # rotation by 4 rad
    np.testing.assert_allclose(mapped_samples(metric, big)[0, 0], 2 * np.pi - 4.0, rtol=1e-14)


def test_quaternion_angle_from_a_reference():
    """Angle between q = rot(a, n) and r = rot(b, n) about one axis is |a - b|; about different axes,
    compare with the angle of the rotation matrices' relative rotation (independent formula)."""
    def quaternion(angle, axis):
        axis = np.asarray(axis, dtype=float) / np.linalg.norm(axis)
        return np.array([np.cos(angle / 2), *(np.sin(angle / 2) * axis)])

    def matrix(q):
        w, x, y, z = q
        return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                         [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                         [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])

    r = quaternion(0.7, [1, 1, 1])
    metric = Metric("m", "s", "final", of="quaternion_angle", reference=tuple(r))
    q = np.array([quaternion(0.2, [1, 1, 1]), quaternion(0.5, [1, -2, 0.5]), quaternion(2.9, [0, 0, 1])])
    relative = [matrix(r).T @ matrix(qk) for qk in q]
    expected = [np.arccos(np.clip((np.trace(m) - 1) / 2, -1, 1)) for m in relative]
    np.testing.assert_allclose(mapped_samples(metric, q)[:, 0], expected, rtol=1e-12)
    assert abs(mapped_samples(metric, q)[0, 0] - 0.5) < 1e-14
