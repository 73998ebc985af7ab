"""A Monte Carlo campaign that disperses the time of a scene event (``events.<event>.time``, shell/scene_events.py):
each run separates the stages at its drawn time (the upper stage's final position is the analytic tangent line from
that release, to 1e-9 m), and the runs made as new contexts of one diagram equal the runs rebuilt from their --set
overrides bit for bit."""

from pathlib import Path

import numpy as np

from shell.montecarlo.campaign import load_campaign
from tests.montecarlo.test_reuse import _assert_same, _runs

SCENE = (Path(__file__).resolve().parents[2] / "configs" / "stage_separation_coast.yaml").read_text()

CAMPAIGN = """
name: separation_time
scenario: separation.yaml
runs: 3
seed: 5
set: {stop.time: 3 s}
dispersions:
  events.separation.time: {distribution: uniform, low: 1.5 s, high: 2.5 s}
metrics:
  upper_x: {signal: multibody.upper_cm.position, component: 0, statistic: final, unit: m}
  upper_y: {signal: multibody.upper_cm.position, component: 1, statistic: final, unit: m}
"""


def test_a_dispersed_event_time_moves_the_release_in_each_run(write):
    write("separation.yaml", SCENE)
    campaign = load_campaign(write("campaign.yaml", CAMPAIGN))
    rebuilt, reference = _runs(campaign, reuse=False)
    reused, records = _runs(campaign, reuse=True)
    assert reused.rebuild_reason is None
    times = []
    for a, b in zip(reference, records):
        assert a.status == "completed"
        _assert_same(a, b)
        release = float(b.draws[campaign.draw_columns.index("events.separation.time")])
        times.append(release)
        w, t_end, c = 0.2, 3.0, 300.0 * 4.5 / 1300.0
        rho = (4.5 - c) * np.array([np.cos(w * release), np.sin(w * release)])
        expected = np.array([c, 0.0]) + rho + (t_end - release) * w * np.array([-rho[1], rho[0]])
        assert np.abs(b.metrics - expected).max() < 1e-9
    assert np.ptp(times) > 0.1 and all(1.5 <= t <= 2.5 for t in times)
