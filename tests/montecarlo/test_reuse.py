"""Monte Carlo runs as new contexts of one diagram (shell.montecarlo.reuse) against the reference: every
run's scene rebuilt from its --set overrides. Same metrics, same kept signals, same status, bit for bit."""

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from shell.montecarlo.campaign import load_campaign

CONFIGS = Path(__file__).resolve().parents[2] / "configs"

# dispersed: engine inertia (matrix form), initial attitude and rate, controller gains, controller rate
# (a choice between 10 and 5 Hz: a different sample schedule per run), and a node position is NOT
# dispersed (structural) in the second campaign below
SCENE = """
name: reuse_scene
seed: 1
multibody:
  gravity: "[0, 0, 0] m/s^2"
  bodies:
    - name: bus
      hinge: free
      mass: 500 kg
      inertia: "[[400, 5, 0], [5, 300, 0], [0, 0, 250]] kg*m^2"
      initial:
        attitude: [0.984807753012208, 0.10025582212029019, 0.10025582212029019, 0.10025582212029019]
        angular_velocity: "[2, -1, 3] deg/s"
    - name: wheel
      parent: bus
      hinge: revolute
      axis: [0, 0, 1]
      mass: 5 kg
      inertia: "[0.1, 0.1, 0.2] kg*m^2"
  nodes:
    - {name: acs, body: bus, position: "[0.1, 0, 0] m"}
models:
  controller:
    type: PidAttitudeController
    rate: 10 Hz
    attach: {node: acs}
    parameters: {kp: "[10, 7.5, 6.25] N*m/rad", kd: "[90, 67.5, 56] N*m*s/rad"}
  gyro:
    type: Imu
    rate: 50 Hz
    attach: {node: acs}
    parameters: {gyro_random_walk: "0.1 deg/hour**0.5", gyro_bias: "[1, -1, 0.5] deg/hour"}
integrator: {method: rk4, step: 0.05 s}
stop: {time: 4 s}
log: {rate: 5 Hz, signals: [multibody.acs.attitude, controller.torque, gyro.angular_rate]}
"""

CAMPAIGN = """
name: reuse_campaign
scenario: reuse_scene.yaml
runs: 8
seed: 99
dispersions:
  multibody.bus.inertia: {distribution: normal, mean: "[400, 300, 250] kg*m^2", sigma: "[20, 15, 12] kg*m^2"}
  multibody.wheel.mass: {distribution: uniform, low: 4 kg, high: 6 kg}
  multibody.bus.initial.angular_velocity: {distribution: uniform, low: "-3 deg/s", high: "3 deg/s", shape: [3]}
  controller.kp: {distribution: lognormal, median: "[10, 7.5, 6.25] N*m/rad", log_sigma: 0.1}
  controller.rate: {distribution: choice, choices: [10 Hz, 5 Hz], probabilities: [0.5, 0.5]}
  gyro.gyro_bias_instability: {distribution: uniform, low: 0.1 deg/hour, high: 1 deg/hour}
metrics:
  final_error: {signal: multibody.acs.attitude, of: quaternion_angle, statistic: final, unit: deg}
  peak_torque: {signal: controller.torque, statistic: max_abs, unit: N*m}
  rms_rate: {signal: gyro.angular_rate, statistic: rms}
keep: [multibody.acs.attitude, gyro.angular_rate]
"""


def _runs(campaign, reuse):
    campaign = dataclasses.replace(campaign, reuse_scene=reuse)
    records = [campaign.run(i) for i in range(campaign.runs)]
    return campaign, records


def _assert_same(a, b):
    assert (a.status, a.message, a.t_end) == (b.status, b.message, b.t_end)
    assert a.metrics.tobytes() == b.metrics.tobytes()
    assert a.draws.tobytes() == b.draws.tobytes()
    assert sorted(a.kept) == sorted(b.kept)
    for name in a.kept:
        for x, y in zip(a.kept[name][:2], b.kept[name][:2]):
            assert np.asarray(x).tobytes() == np.asarray(y).tobytes(), name


def test_reused_diagram_runs_equal_rebuilt_runs_bit_for_bit(write):
    write("reuse_scene.yaml", SCENE)
    campaign = load_campaign(write("reuse_campaign.yaml", CAMPAIGN))
    rebuilt, reference = _runs(campaign, reuse=False)
    reused, records = _runs(campaign, reuse=True)
    assert reused.rebuild_reason is None  # every run was a new context of the same diagram
    rates = {float(r.draws[campaign.draw_columns.index("controller.rate")]) for r in records}
    assert rates == {0.0, 1.0}  # both sample schedules occur
    for a, b in zip(reference, records):
        assert a.status == "completed"
        _assert_same(a, b)


def test_structural_dispersion_rebuilds_each_run_and_says_why(write):
    write("reuse_scene.yaml", SCENE)
    campaign = load_campaign(write("reuse_campaign.yaml", CAMPAIGN.replace(
        "dispersions:\n", "dispersions:\n  integrator.step: {distribution: choice, choices: [50 ms, 25 ms]}\n")))
    rebuilt, reference = _runs(campaign, reuse=False)
    reused, records = _runs(campaign, reuse=True)
    assert "integrator.step" in reused.rebuild_reason
    for a, b in zip(reference, records):
        _assert_same(a, b)


@pytest.mark.parametrize("name", ["campaign_attitude_hold.yaml"])
def test_shipped_campaign_reuses_its_scene(name):
    campaign = dataclasses.replace(load_campaign(CONFIGS / name), runs=3)
    rebuilt, reference = _runs(campaign, reuse=False)
    reused, records = _runs(campaign, reuse=True)
    assert reused.rebuild_reason is None
    for a, b in zip(reference, records):
        _assert_same(a, b)
