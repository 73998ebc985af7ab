"""Campaign report charts: percentile envelopes (against numpy's percentiles computed directly, to 1e-12),
requirement lines and counts, runs that did not complete marked, component names and units."""

from __future__ import annotations

import textwrap

import numpy as np
import pytest

from shell.montecarlo.campaign import CampaignError, parse_campaign
from shell.montecarlo.metrics import meets, parse_requirement
from shell.montecarlo.report import ENVELOPE_PERCENTILES, _signal_chart, percentile_envelope
from tests.montecarlo.conftest import NOISY_RAMP, RAMP_CAMPAIGN


def test_envelope_equals_numpy_percentiles_on_a_common_grid():
    rng = np.random.default_rng(1)
    t = np.linspace(0.0, 10.0, 101)
    runs = [(t, rng.normal(size=(t.size, 3)) + k) for k in range(40)]
    grid, envelope = percentile_envelope(runs)
    stack = np.stack([v for _, v in runs])
    assert np.array_equal(grid, t)
    np.testing.assert_allclose(envelope, np.percentile(stack, ENVELOPE_PERCENTILES, axis=0), rtol=0, atol=1e-12)


def test_a_run_that_stopped_early_leaves_the_envelope_after_its_end_and_other_grids_are_interpolated():
    t = np.linspace(0.0, 10.0, 11)
    full = [(t, np.full((t.size, 1), float(k))) for k in range(5)]           # constant 0, 1, 2, 3, 4
    short = (t[:6], np.full((6, 1), 100.0))                                    # stops at 5 s
    shifted = (t[:-1] + 0.5, (t[:-1] + 0.5)[:, None])                          # y = t, sampled at 0.5 .. 9.5 s
    grid, envelope = percentile_envelope(full + [short, shifted])
    assert np.array_equal(grid, t)                                             # the runs that reach furthest
    median = envelope[ENVELOPE_PERCENTILES.index(50.0), :, 0]
    expected = []
    for k, time in enumerate(t):
        present = list(range(5)) + ([100.0] if time <= 5.0 else []) + ([time] if 0.5 <= time <= 9.5 else [])
        expected.append(np.median(present))
    np.testing.assert_allclose(median, expected, rtol=0, atol=1e-12)


@pytest.mark.parametrize("text, unit, expected", [
    ("<= 0.5 deg", "rad", ("<=", np.deg2rad(0.5))), (">= 10 s", "s", (">=", 10.0)), ("< 2", "m", ("<", 2.0)),
    ("> 3 cm", "m", (">", 0.03))])
def test_requirements_are_read_in_the_metric_unit(text, unit, expected):
    operator, bound = parse_requirement(text, unit)
    assert operator == expected[0] and bound == pytest.approx(expected[1], rel=1e-15)


def test_requirement_counts():
    values = np.array([0.1, 0.5, 0.6, np.inf, np.nan])
    assert meets(values, ("<=", 0.5)).tolist() == [True, True, False, False, False]
    assert meets(values, (">", 0.5)).tolist() == [False, False, True, True, False]


def test_a_bad_requirement_is_refused_with_its_line(tmp_path):
    (tmp_path / "ramp.yaml").write_text(textwrap.dedent(NOISY_RAMP))
    campaign = textwrap.dedent(RAMP_CAMPAIGN.format(runs=3)).replace(
        "final_position: {signal: position.y, statistic: final, unit: m}",
        "final_position: {signal: position.y, statistic: final, unit: m, requirement: about 2 m}")
    with pytest.raises(CampaignError, match=r"requirement.*expected a requirement starting with"):
        parse_campaign(campaign, str(tmp_path / "c.yaml"), validate=False)
    campaign = campaign.replace("about 2 m", "<= 2 kg")
    with pytest.raises(CampaignError, match=r"c\.yaml:\d+: metrics\.final_position\.requirement: .*kg"):
        parse_campaign(campaign, str(tmp_path / "c.yaml"), validate=False)


def test_signal_chart_names_components_marks_failed_runs_and_draws_envelopes(tmp_path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    t = np.linspace(0.0, 1.0, 11)
    items = [(k, (t, np.outer(t, [1.0, 2.0, 3.0]) * (1 + 0.1 * k), "m*N")) for k in range(6)]
    status = {k: b"completed" for k in range(5)} | {5: b"failed"}
    captured = {}
    original = plt.subplots

    def keep(*args, **kwargs):
        captured["figure"], captured["axes"] = original(*args, **kwargs)
        return captured["figure"], captured["axes"]

    plt.subplots = keep
    try:
        path = _signal_chart(plt, tmp_path, "controller.torque", items, status)
    finally:
        plt.subplots = original
    assert path.exists()
    axes = captured["axes"][:, 0]
    assert [ax.get_ylabel() for ax in axes] == ["x [N m]", "y [N m]", "z [N m]"]
    legend = [t.get_text() for t in axes[0].get_legend().get_texts()]
    assert legend == ["median", "did not complete", "0.135-99.865 %", "5-95 %"] or set(legend) == {
        "median", "did not complete", "0.135-99.865 %", "5-95 %"}
    red = [line for line in axes[0].get_lines() if line.get_color() == "C3" and len(line.get_xdata())]
    assert len(red) == 1   # the failed run, drawn apart from the completed ones
    median = next(line for line in axes[2].get_lines() if line.get_label() == "median")
    np.testing.assert_allclose(median.get_ydata(), 3.0 * t * (1 + 0.1 * 2), rtol=1e-12)  # completed runs 0..4
    assert "5 completed, 1 did not complete" in axes[0].get_title(loc="left")
