"""Multi-rate sampling: 1, 10 and 100 Hz zero-order holds around a continuous plant, checked against
the sample-and-hold sequence computed by hand with integer sample indices."""

import numpy as np
import pytest
from numpy.testing import assert_allclose, assert_array_equal

from shell.assembly import Assembly
from shell.log_file import read_log
from shell.models.blocks import Constant, Integrator, SampleHold
from shell.simulation import Simulation


@pytest.fixture(scope="module")
def multirate_log(tmp_path_factory):
    root = Assembly("root")
    root.add(Constant("one", value=1.0))
    root.add(Integrator("clock", unit="s"))                   # clock = t
    root.add(SampleHold("fast", unit="s", period="100 Hz"))   # samples the clock
    root.add(SampleHold("medium", unit="s", period="10 Hz"))  # samples the fast hold (chained)
    root.add(SampleHold("slow", unit="s", period="1 Hz"))     # samples the clock
    root.add(Integrator("area", unit="s^2"))                  # integral of the medium hold
    root.connect("one.y", "clock.u")
    root.connect("clock.y", "fast.u")
    root.connect("fast.y", "medium.u")
    root.connect("clock.y", "slow.u")
    root.connect("medium.y", "area.u")
    sim = Simulation(root, step=0.005)
    sim.log(["clock.y", "fast.y", "medium.y", "slow.y", "fast.samples", "medium.samples", "slow.samples",
             "area.y"], "200 Hz")
    path = tmp_path_factory.mktemp("multirate") / "log.h5"
    summary = sim.run(2.5, log_path=path)
    return read_log(path), summary


def test_log_times_are_the_exact_grid(multirate_log):
    log, _ = multirate_log
    j = np.arange(501)
    assert_array_equal(log["time"], j / 200)  # sample instants from exact fractions: k * (1/200)


def test_sample_and_hold_sequences_match_hand_computation(multirate_log):
    log, summary = multirate_log
    j = np.arange(501)  # log instant t_j = j / 200 s; logs are taken after the updates due at t_j
    # sample counts: a hold of period P has sampled at 0, P, 2P, ... <= t_j
    assert_array_equal(log["fast.samples"], j // 2 + 1)
    assert_array_equal(log["medium.samples"], j // 20 + 1)
    assert_array_equal(log["slow.samples"], j // 200 + 1)
    # held values: the clock at the last sample instant. The clock integrates 1 with RK4 steps of
    # 5 ms, so it equals t up to round-off of the step sum (< 1e-13 s over 2.5 s).
    assert_allclose(log["clock.y"], j / 200, atol=1e-13)
    assert_allclose(log["fast.y"], (j // 2) / 100, atol=1e-13)
    # at coincident instants the medium hold updates after the fast one (dataflow order), so it sees
    # the fast hold's new sample, not the previous one
    assert_allclose(log["medium.y"], (j // 20) / 10, atol=1e-13)
    assert_allclose(log["slow.y"], (j // 200) * 1.0, atol=1e-13)
    assert summary.discrete_updates == 251 + 26 + 3


def test_continuous_plant_integrates_the_held_signal(multirate_log):
    log, _ = multirate_log
    t = log["time"]
    k = np.floor(t * 10 + 1e-9)          # index of the medium sample held at t
    held = k / 10
    # area(t) = sum_{i<k} 0.1 * (i / 10) + (t - k/10) * held = 0.01 * k (k - 1) / 2 + (t - k/10) * held
    expected = 0.01 * k * (k - 1) / 2 + (t - k / 10) * held
    # piecewise-constant input with steps aligned to the samples: RK4 is exact up to round-off
    assert_allclose(log["area.y"], expected, atol=1e-12)


def test_offset_delays_the_first_sample():
    root = Assembly("root")
    root.add(Constant("one", value=1.0))
    root.add(Integrator("clock", unit="s"))
    root.add(SampleHold("late", unit="s", period="0.5 s", offset="0.2 s"))
    root.connect("one.y", "clock.u")
    root.connect("clock.y", "late.u")
    sim = Simulation(root, step=0.1)
    sim.run(1.3)
    # samples at 0.2, 0.7, 1.2
    assert sim.signal("late.samples") == 3.0
    assert sim.signal("late.y") == pytest.approx(1.2, abs=1e-13)
