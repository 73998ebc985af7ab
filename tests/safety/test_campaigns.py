"""Fault tests of Monte Carlo campaigns (issue 17): a killed coordinator leaves no worker behind, and
--resume refuses a results file another process is writing."""

import signal
import subprocess
import sys
import time

import psutil
import pytest

from shell.montecarlo.campaign import load_campaign
from shell.montecarlo.results import ResultsError, open_results
from tests.safety.conftest import RAMP, subprocess_env

CAMPAIGN = """\
name: ramp_campaign
scenario: scene.yaml
runs: {runs}
seed: 7
set: {{stop.time: {stop}}}
dispersions:
  rate.value: {{distribution: normal, mean: 100 cm/s, sigma: 10 cm/s}}
metrics:
  final_position: {{signal: sensor.y, statistic: final, unit: m}}
"""


def write_campaign(tmp_path, runs=4, stop="2 s"):
    (tmp_path / "scene.yaml").write_text(RAMP)
    path = tmp_path / "campaign.yaml"
    path.write_text(CAMPAIGN.format(runs=runs, stop=stop))
    return path


def test_kill_9_of_a_pool_campaign_leaves_no_worker(tmp_path):
    campaign = write_campaign(tmp_path, runs=8, stop="100000 s")  # runs far longer than the test
    coordinator = subprocess.Popen([sys.executable, "-m", "shell.cli", "montecarlo", str(campaign), "-o",
                                    str(tmp_path / "out.h5"), "--executor", "pool", "--workers", "2", "--quiet"],
                                   cwd=tmp_path, env=subprocess_env(), stdout=subprocess.DEVNULL,
                                   stderr=subprocess.PIPE, text=True, start_new_session=True)
    workers = []
    try:
        parent = psutil.Process(coordinator.pid)
        deadline = time.monotonic() + 300
        while time.monotonic() < deadline and len(workers) < 2:
            assert coordinator.poll() is None, coordinator.communicate()
            workers = [p for p in parent.children() if "resource_tracker" not in " ".join(p.cmdline())]
            time.sleep(0.5)
        assert len(workers) == 2, "the pool's workers did not start"
        time.sleep(2.0)  # the workers are running their first runs
        coordinator.send_signal(signal.SIGKILL)
        coordinator.wait(timeout=30)
        gone, alive = psutil.wait_procs(workers, timeout=20)
        assert not alive, f"workers {[p.pid for p in alive]} outlived their coordinator"
    finally:  # whatever the outcome, nothing this test started keeps running
        if coordinator.poll() is None:
            coordinator.kill()
            coordinator.wait()
        for process in workers:
            if process.is_running():
                process.kill()


def test_resume_refuses_a_campaign_another_process_is_writing(tmp_path, capsys):
    """The holder is this test (HDF5's lock is per open file, so it stands for another process); the
    second session is the command line. Before: the file was renamed *.damaged and both ran the runs."""
    from shell.cli import main

    campaign = write_campaign(tmp_path)
    output = tmp_path / "out.h5"
    running = open_results(output, load_campaign(campaign, validate=False))
    try:
        assert main(["montecarlo", str(campaign), "-o", str(output), "--resume", "--quiet"]) == 1
        err = capsys.readouterr().err
        assert "another process is writing" in err and "Traceback" not in err
        with pytest.raises(ResultsError, match="another process is writing"):
            open_results(output, load_campaign(campaign, validate=False), overwrite=True)
    finally:
        running.close("interrupted")
    assert sorted(p.name for p in tmp_path.iterdir() if p.name.startswith("out")) == ["out.h5", "out.h5.journal"]


def test_a_campaign_cut_by_a_kill_reads_as_interrupted(tmp_path):
    from shell.montecarlo.results import read_results

    campaign = write_campaign(tmp_path)
    output = tmp_path / "out.h5"
    running = open_results(output, load_campaign(campaign, validate=False))
    assert read_results(output)["attrs"]["status"] == "running", "held by a writer: it is running"
    running.file.close()  # what a kill leaves: the file closed by the system, its status still "running"
    running._journal.close()
    assert read_results(output)["attrs"]["status"] == "interrupted"


def test_a_new_campaign_keeps_the_journal_of_one_that_did_not_finish(tmp_path, capsys):
    """Completed runs that only the journal holds (their campaign was killed, its results file then removed)
    are not deleted by a new campaign on that output: refused, --resume finishes from them, --overwrite
    discards them. Before, ``open_results`` unlinked ``OUT.h5.journal`` unread (a user's runs lost)."""
    from shell.cli import main
    from shell.montecarlo.results import read_journal, read_results, record_to_json

    path = write_campaign(tmp_path, runs=4)
    output, journal = tmp_path / "out.h5", tmp_path / "out.h5.journal"
    campaign = load_campaign(path, validate=False)
    running = open_results(output, campaign)
    for run in (0, 2):
        running._journal.write(record_to_json(campaign.run(run)) + "\n")
    running._journal.close()
    running.file.close()
    output.unlink()
    kept = journal.read_bytes()

    assert main(["montecarlo", str(path), "-o", str(output), "--quiet"]) == 1
    err = capsys.readouterr().err
    assert "holds 2 completed run(s)" in err and "--resume" in err and "Traceback" not in err
    assert journal.read_bytes() == kept and not output.exists()

    assert main(["montecarlo", str(path), "-o", str(output), "--resume", "--quiet"]) == 0
    table = read_results(output)["table"]
    assert set(table["status"]) == {b"completed"} and not journal.exists()

    journal.write_text("my notes\n")                       # not a journal: kept unless --overwrite
    output.unlink()
    assert main(["montecarlo", str(path), "-o", str(output), "--quiet"]) == 1
    assert "holds no run" in capsys.readouterr().err and journal.read_text() == "my notes\n"
    assert main(["montecarlo", str(path), "-o", str(output), "--quiet", "--overwrite"]) == 0
    assert not journal.exists() and read_journal(journal) == []
