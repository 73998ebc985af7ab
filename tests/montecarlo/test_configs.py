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
