"""Campaign runs: bit-for-bit reproducibility of a run alone, noise streams from (seed, run), faults,
resume, kill safety, and the command line."""

import hashlib
import os
import signal
import subprocess
import sys
import time

import h5py
import numpy as np
import pytest

from shell.cli import main
from shell.montecarlo.campaign import CampaignError, load_campaign
from shell.montecarlo.executors import run_campaign
from shell.montecarlo.results import ResultsError, open_results, read_journal, read_kept, read_results, tables_equal
from shell.scenario import build_simulation, parse_scenario


def test_one_run_alone_reproduces_bit_for_bit(ramp_campaign, tmp_path):
    campaign = load_campaign(ramp_campaign())
    records = [campaign.run(i) for i in range(4)]
    alone = load_campaign(ramp_campaign()).run(2)  # a fresh process would do the same: nothing is shared
    assert alone.draws.tobytes() == records[2].draws.tobytes()
    assert alone.metrics.tobytes() == records[2].metrics.tobytes()
    assert alone.kept["sensor.y"][1].tobytes() == records[2].kept["sensor.y"][1].tobytes()
    # the run is the scenario with the campaign's overrides: `flexshell run SCENARIO --set ...` gives it
    scenario = parse_scenario((tmp_path / "ramp.yaml").read_text(), str(tmp_path / "ramp.yaml"),
                              campaign.overrides(2))
    simulation = build_simulation(scenario)
    simulation.run(scenario.t_final, log_path=tmp_path / "alone.h5")
    with h5py.File(tmp_path / "alone.h5") as f:
        assert f["every_0.1s/sensor.y"][:].tobytes() == records[2].kept["sensor.y"][1].tobytes()
    assert len({r.metrics[1] for r in records}) == 4


def test_noise_streams_come_from_seed_and_run(ramp_campaign):
    """Run i's sensor noise is the stream SeedSequence(entropy=[master, i], spawn_key=sha256(path))
    (docs/shell.md), rebuilt here independently: reading_k = position(t_k) + sigma * n_k."""
    campaign = load_campaign(ramp_campaign())
    for run in (0, 5):
        record = campaign.run(run)
        rate, sigma = record.draws[0] / 100.0, record.draws[1] / 1000.0  # cm/s -> m/s, mm -> m
        digest = hashlib.sha256(b"sensor").digest()
        key = tuple(int.from_bytes(digest[k:k + 4], "little") for k in range(0, 16, 4))
        rng = np.random.Generator(np.random.PCG64(np.random.SeedSequence(entropy=[7, run], spawn_key=key)))
        t, readings, unit = record.kept["sensor.y"]
        assert unit == "m" and t.size == 21
        expected = rate * t + sigma * rng.standard_normal(t.size)
        # rk4 integrates a constant rate exactly: only round-off of the sums (1e-15 relative) remains
        np.testing.assert_allclose(readings, expected, rtol=0, atol=1e-14)


FAULTY_SCENE = """
models:
  escape: {type: FiniteEscape, initial: {x: 0.01}}
  ball: {type: BouncingBall, parameters: {restitution: 0.8}}
integrator: {method: rk4, step: 10 ms}
stop: {time: 3 s}
log: {rate: 100 Hz, signals: [escape.x]}
"""

FAULTY_CAMPAIGN = """
scenario: faulty.yaml
runs: 12
seed: 3
timeout: 0.5 s
dispersions:
  escape.initial.x: {distribution: choice, choices: [0.01, 1.0], probabilities: [0.6, 0.4]}   # 1.0: x -> inf at t = 1 s
  ball.restitution: {distribution: choice, choices: [0.8, 1.5], probabilities: [0.7, 0.3]}   # 1.5: out of bounds
  integrator.step: {distribution: choice, choices: [10 ms, 1 us], probabilities: [0.7, 0.3]}  # 1 us: times out
metrics:
  final_x: {signal: escape.x, statistic: final}
"""


def expected_status(draws) -> str:
    escapes, bad_restitution, tiny_step = (int(v) for v in draws)
    if bad_restitution:
        return "failed"
    if tiny_step:
        return "timeout"
    return "nonfinite" if escapes else "completed"


def test_failing_runs_are_recorded_and_the_campaign_continues(write, tmp_path):
    write("faulty.yaml", FAULTY_SCENE)
    campaign = load_campaign(write("faulty_campaign.yaml", FAULTY_CAMPAIGN))
    counts = run_campaign(campaign, tmp_path / "faulty.h5")
    table = read_results(tmp_path / "faulty.h5")["table"]
    statuses = [s.decode() for s in table["status"]]
    assert statuses == [expected_status(table[["escape.initial.x", "ball.restitution", "integrator.step"]][i].tolist())
                        for i in range(12)]
    assert set(statuses) == {"completed", "failed", "nonfinite", "timeout"}, counts
    for row in table:
        status = row["status"].decode()
        if status == "failed":
            assert "restitution" in row["message"] and "does not build" in row["message"]
        if status == "nonfinite":
            assert "non-finite" in row["message"] and 0.9 < row["t_end"] < 1.05  # escape at t = 1 s
        if status == "timeout":
            assert "timeout of 0.5 s" in row["message"]
        if status == "completed":
            np.testing.assert_allclose(row["final_x"], 0.01 / (1 - 0.01 * 3.0), rtol=1e-9)  # x0 / (1 - x0 t)
        else:
            assert np.isnan(row["final_x"])
    assert not os.path.exists(tmp_path / "faulty.h5.journal")  # removed once the campaign completed


# Flight software whose first call compiles a numba function (a new one in every run: the file is imported
# again for each build); ~0.5-1.5 s of compilation on this machine, a few ms of work per run
COMPILING_LAW = """
import numba

SOURCE = "def heavy(x):\\n" + "".join(f"    x = x * 1.0000001 + {k}.0 / (x * x + 1.0)\\n" for k in range(250)) + \\
    "    return x\\n"
namespace = {}
exec(SOURCE, namespace)
heavy = numba.njit(namespace["heavy"])


def law(t, signals):
    return {"y": heavy(float(signals["u"][0]))}
"""


def test_the_timeout_does_not_count_numba_compilation(write, tmp_path):
    """A run that compiles a kernel (the first run to need it after an install: here a user's numba function)
    spends that time on its wall clock; the campaign timeout bounds the run's own work, so such a run completes.
    Before, a fresh install marked the first run of a campaign with events 'timeout' (found on a cold cache:
    test_failing_runs_are_recorded_and_the_campaign_continues failed at run 1, which located the first bounce)."""
    from shell.montecarlo.campaign import _compile_seconds

    write("law.py", COMPILING_LAW)
    write("compiling.yaml", f"""
        models:
          source: {{type: Constant, config: {{shape: [1]}}, parameters: {{value: [1.0]}}}}
          law:
            type: UserFunction
            rate: 10 Hz
            config: {{function: {tmp_path / 'law.py'}:law, inputs: {{u: {{shape: [1]}}}}, outputs: {{y: {{}}}}}}
        connections: [source.y -> law.u]
        integrator: {{method: rk4, step: 0.1 s}}
        stop: {{time: 1 s}}
        log: {{rate: 10 Hz, signals: [law.y]}}
        """)
    campaign = load_campaign(write("compiling_campaign.yaml", """
        scenario: compiling.yaml
        runs: 3
        seed: 1
        timeout: 0.15 s
        dispersions:
          source.value: {distribution: uniform, low: [0.5], high: [1.5]}
        metrics:
          final_y: {signal: law.y, statistic: final}
        """))
    before = _compile_seconds()
    record = campaign.run(0)
    # the run did compile for longer than its timeout (250 lines compile in ~1 s here, 0.5 s on the CI machine,
    # where 60 lines took 0.24 s and this check, then against 0.3 s, failed: the margin is now ~3x on either)
    assert _compile_seconds() - before > 0.15
    assert record.status == "completed", record.message
    run_campaign(campaign, tmp_path / "out.h5")
    assert set(read_results(tmp_path / "out.h5")["table"]["status"]) == {b"completed"}


def test_resume_finishes_without_redoing(ramp_campaign, tmp_path):
    campaign = load_campaign(ramp_campaign(runs=8))
    output = tmp_path / "ramp.h5"
    run_campaign(campaign, output, runs=range(0, 8, 2))
    first = read_results(output)
    assert first["attrs"]["status"] == "partial"
    assert [s.decode() for s in first["table"]["status"]] == ["completed", "pending"] * 4
    with pytest.raises(ResultsError, match="exists; pass --resume"):
        run_campaign(campaign, output)
    executed = []
    run_campaign(campaign, output, resume=True, progress=lambda record, done, total: executed.append(record.run))
    assert sorted(executed) == [1, 3, 5, 7]
    resumed = read_results(output)
    assert resumed["attrs"]["status"] == "completed"
    assert tables_equal(resumed["timing"][::2], first["timing"][::2])  # the first session's runs kept as they were
    run_campaign(campaign, tmp_path / "fresh.h5")
    assert tables_equal(resumed["table"], read_results(tmp_path / "fresh.h5")["table"])


def test_resume_refuses_another_campaign(ramp_campaign, tmp_path):
    output = tmp_path / "ramp.h5"
    run_campaign(load_campaign(ramp_campaign(runs=3)), output, runs=[0])
    with pytest.raises(ResultsError, match="written by another campaign"):
        run_campaign(load_campaign(ramp_campaign(runs=4)), output, resume=True)


def test_damaged_results_file_is_rebuilt_from_the_journal(ramp_campaign, tmp_path):
    campaign = load_campaign(ramp_campaign(runs=6))
    output = tmp_path / "ramp.h5"
    run_campaign(campaign, output, runs=[0, 1, 4])
    journaled = {r.run for r in read_journal(str(output) + ".journal")}
    assert journaled == {0, 1, 4}
    size = output.stat().st_size
    with open(output, "r+b") as f:   # as if killed in the middle of a write
        f.truncate(size // 3)
    with open(str(output) + ".journal", "a") as f:
        f.write('{"run": 5, "status": "comp')   # a journal line cut short: that run is not done
    results = open_results(output, campaign, resume=True)
    assert results.done() == {0, 1, 4}
    results.close("partial")
    executed = []
    run_campaign(campaign, output, resume=True, progress=lambda record, done, total: executed.append(record.run))
    assert sorted(executed) == [2, 3, 5]
    run_campaign(campaign, tmp_path / "fresh.h5")
    assert tables_equal(read_results(output)["table"], read_results(tmp_path / "fresh.h5")["table"])
    kept = read_kept(output, 4)["sensor.y"][1]
    assert kept.tobytes() == read_kept(tmp_path / "fresh.h5", 4)["sensor.y"][1].tobytes()


def test_killed_campaign_loses_no_completed_run(ramp_campaign, tmp_path):
    """SIGKILL a `flexshell montecarlo` process after some runs completed; every run in the journal at
    that moment survives, and --resume completes the campaign to the same table as an uninterrupted one."""
    path = ramp_campaign(runs=12, extra="set: {stop.time: 40 s}\n")
    output = tmp_path / "killed.h5"
    journal = tmp_path / "killed.h5.journal"
    process = subprocess.Popen([sys.executable, "-m", "shell.cli", "montecarlo", str(path), "-o", str(output),
                                "--quiet"], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    try:
        deadline = time.monotonic() + 120
        while time.monotonic() < deadline and process.poll() is None:
            if journal.exists() and journal.read_text().count("\n") >= 3:
                break
            time.sleep(0.02)
        assert process.poll() is None, process.stderr.read().decode()
        process.send_signal(signal.SIGKILL)
        process.wait(timeout=30)
    finally:
        if process.poll() is None:
            process.kill()
    survived = {r.run for r in read_journal(journal)}
    assert len(survived) >= 3
    campaign = load_campaign(path)
    executed = []
    run_campaign(campaign, output, resume=True, progress=lambda record, done, total: executed.append(record.run))
    assert survived.isdisjoint(executed) and len(survived) + len(executed) == 12
    fresh = tmp_path / "fresh.h5"
    run_campaign(campaign, fresh)
    assert tables_equal(read_results(output)["table"], read_results(fresh)["table"])


def test_command_line_campaign_report_and_overrides(ramp_campaign, tmp_path, capsys):
    path = ramp_campaign(runs=5)
    output = tmp_path / "out.h5"
    assert main(["montecarlo", str(path), "-o", str(output), "--quiet"]) == 0
    printed = capsys.readouterr().out
    assert "ramp_campaign: 5 runs (5 completed)" in printed and "final_position" in printed
    assert main(["montecarlo", str(path), "-o", str(output), "--quiet"]) == 1   # exists: refused
    assert "pass --resume" in capsys.readouterr().err
    assert main(["report", str(output), "-o", str(tmp_path / "report")]) == 0
    capsys.readouterr()
    report = (tmp_path / "report" / "percentiles.md").read_text()
    assert "| final_position | m | metric | 5 | 0 |" in report
    for name in ("hist_final_position.png", "scatter_peak_reading.png", "signal_sensor.y.png", "percentiles.csv"):
        assert (tmp_path / "report" / name).stat().st_size > 0
    assert main(["montecarlo", str(path), "--print-overrides", "3"]) == 0
    lines = capsys.readouterr().out.split("\n")
    assert lines[0].startswith('--set "rate.value={value: ') and not lines[0].startswith('--set "rate.value={value: [')
    assert lines[2] == '--set "seed=[7, 3]"'
    rerun_log = tmp_path / "run3.h5"
    assert main(["montecarlo", str(path), "--rerun", "3", "-o", str(rerun_log)]) == 0
    with h5py.File(rerun_log) as f:
        assert f["every_0.1s/sensor.y"][:].tobytes() == read_kept(output, 3)["sensor.y"][1].tobytes()


def test_campaign_errors_name_the_line(write):
    write("ramp.yaml", "models: {c: {type: Constant, config: {unit: m}}}\nstop: {time: 1 s}\n")
    with pytest.raises(CampaignError, match=r"c.yaml:4: dispersions.nothing.value: .*'nothing' is neither a model"):
        load_campaign(write("c.yaml", "scenario: ramp.yaml\nruns: 2\ndispersions:\n"
                                      "  nothing.value: {distribution: normal, mean: 1, sigma: 1}\n"))
    with pytest.raises(CampaignError, match=r"c.yaml:1: the scenario with the median draws does not run: .*c.valu"):
        load_campaign(write("c.yaml", "scenario: ramp.yaml\nruns: 2\nmetrics:\n"
                                      "  m: {signal: c.valu, statistic: final}\n"))
    with pytest.raises(CampaignError, match=r"c.yaml:4: metrics.m.unit: .*cannot become"):
        load_campaign(write("c.yaml", "scenario: ramp.yaml\nruns: 2\nmetrics:\n"
                                      "  m: {signal: c.y, statistic: final, unit: s}\n"))
    with pytest.raises(CampaignError, match=r"c.yaml:2: runs: expected a positive integer"):
        load_campaign(write("c.yaml", "scenario: ramp.yaml\nruns: 0\n"))
    with pytest.raises(CampaignError, match=r"c.yaml:3: dispersion: unknown key 'dispersion' \(did you mean 'dispersions'"):
        load_campaign(write("c.yaml", "scenario: ramp.yaml\nruns: 2\ndispersion: {}\n"))
