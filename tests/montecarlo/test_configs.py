"""The shipped campaigns load (median scene built and stepped) and their runs complete."""

from pathlib import Path

import numpy as np

from shell.montecarlo.campaign import load_campaign
from shell.montecarlo.executors import run_campaign
from shell.montecarlo.results import read_results

CONFIGS = Path(__file__).resolve().parents[2] / "configs"


def test_attitude_hold_campaign_runs(tmp_path):
    campaign = load_campaign(CONFIGS / "campaign_attitude_hold.yaml")
    assert campaign.runs == 100 and len(campaign.draw_columns) == 13
    output = tmp_path / "attitude.h5"
    run_campaign(campaign, output, runs=[0, 1])
    results = read_results(output)
    table = results["table"][:2]
    assert set(table["status"]) == {b"completed"}
    assert results["units"]["final_attitude_error"] == "deg" and results["units"]["multibody.bus.inertia[0]"] == "kg*m^2"
    # the PD loop holds attitude: after 60 s the error is a small fraction of the initial 20 deg
    assert np.all(table["final_attitude_error"] < 0.5) and np.all(table["settling_time"] < 60)
    # the values drawn for run 0 are the values its scene was built with (units converted at build)
    _, simulation = campaign.build(0)
    simulation.evaluate()
    models = {m.path: m for m in simulation.models}
    kp = [table[f"controller.kp[{k}]"][0] for k in range(3)]
    assert models["controller"].parameter("kp").tolist() == kp                      # N*m/rad both
    rates = np.array([table[f"multibody.bus.initial.angular_velocity[{k}]"][0] for k in range(3)])
    np.testing.assert_allclose(simulation.signal("multibody.acs.angular_velocity"), np.radians(rates),
                               rtol=1e-15)                                            # deg/s drawn, rad/s built


def test_spacecraft_slew_campaign_builds_each_run_with_its_draws(monkeypatch):
    """Wheel friction (assembly member paths), IMU noise and bias, inertia and rates reach the scene in
    the declared units. (One slew run takes ~10 s: the campaign's runs are in docs/montecarlo.md.)"""
    monkeypatch.chdir(CONFIGS.parent)   # the scenario's flight-software path is relative to the repository
    campaign = load_campaign(CONFIGS / "campaign_spacecraft_slew.yaml")
    assert campaign.runs == 30 and campaign.timeout == 300.0
    draws = campaign.draws(4)
    _, simulation = campaign.build(4)
    models = {m.path: m for m in simulation.models}
    for k in range(1, 5):   # drawn in mN*m, built in N*m
        np.testing.assert_allclose(models[f"wheels.rw{k}"].parameter("coulomb_friction"),
                                   draws[f"wheels.rw{k}.coulomb_friction"][0] * 1e-3, rtol=1e-15)
    hour = 3600.0
    np.testing.assert_allclose(models["imu"].parameter("gyro_bias"), np.radians(draws["imu.gyro_bias"]) / hour,
                               rtol=1e-15)
    np.testing.assert_allclose(models["imu"].parameter("gyro_random_walk"),
                               np.radians(draws["imu.gyro_random_walk"][0]) / np.sqrt(hour), rtol=1e-15)
    assert np.all(np.abs(draws["imu.gyro_bias"]) <= 10.0)
