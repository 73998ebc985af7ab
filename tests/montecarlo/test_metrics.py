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
