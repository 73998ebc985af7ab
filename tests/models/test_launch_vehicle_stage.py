"""configs/launch_vehicle_stage.yaml runs end to end: TVC stabilizes the stage, the gimbal stays within
its limits, the tanks empty at F / (Isp g0), the IMU feels the thrust acceleration."""

from pathlib import Path

import numpy as np
from numpy.testing import assert_allclose

from shell.log_file import read_log
from shell.scenario import build_simulation, load_scenario

ROOT = Path(__file__).resolve().parents[2]


def test_launch_vehicle_stage_scenario(tmp_path, monkeypatch):
    monkeypatch.chdir(ROOT)                       # the flight-software path is relative to the repository
    sim = build_simulation(load_scenario(ROOT / "configs" / "launch_vehicle_stage.yaml"))
    sim.run(10.0, log_path=tmp_path / "stage.h5")  # the file runs 40 s
    log = read_log(tmp_path / "stage.h5")
    t = log["time"]
    q = log["multibody.nav.attitude"]
    error = 2 * np.degrees(np.arccos(np.clip(np.abs(q[:, 0]), 0, 1)))
    assert np.max(error[t > 5.0]) < 0.02          # the 2 deg/s lift-off disturbance is absorbed
    assert np.max(np.abs(log["multibody.engine.q"])) <= np.radians(6.0) + 1e-6
    mdot = 3e5 / (300 * 9.80665)
    sample_times = np.floor(t * 10 + 1e-9) / 10  # tanks sample at 10 Hz: mass held since the last sample
    assert_allclose(log["tanks.mass"], 20000 - mdot * sample_times, rtol=1e-9)
    # specific force along the stage axis ~ thrust / total mass (stage + engine + slosh), within the
    # IMU noise and lever-arm terms
    total = log["tanks.mass"][-1] + 1000 + 1500
    assert_allclose(log["imu.specific_force"][-1, 2], 3e5 / total, rtol=2e-3)
    assert log["multibody.nav.position"][-1, 2] > 50.0
