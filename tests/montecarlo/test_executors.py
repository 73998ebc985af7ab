"""Serial, process-pool and Dask (LocalCluster, and a scheduler address) runs of one campaign give
identical tables and kept signals; workers load the kernels from numba's on-disk cache instead of
compiling. Dask runs go through child processes with hard time limits, so a cluster problem fails the
test instead of hanging it."""

import subprocess
import sys

from shell.montecarlo.campaign import load_campaign
from shell.montecarlo.executors import run_campaign
from shell.montecarlo.results import read_kept, read_results
from tests.montecarlo.test_campaign_runs import tables_equal


def test_serial_pool_and_dask_give_identical_tables(ramp_campaign, tmp_path):
    path = ramp_campaign(runs=6)
    campaign = load_campaign(path)   # validation runs the median scene: kernels are in the disk cache now
    run_campaign(campaign, tmp_path / "serial.h5", executor="serial")
    run_campaign(campaign, tmp_path / "pool.h5", executor="pool", workers=2)
    # Dask in a child process with a hard time limit, so that a cluster problem fails instead of hanging
    result = subprocess.run([sys.executable, "-m", "shell.cli", "montecarlo", str(path), "-o", str(tmp_path / "dask.h5"),
                             "--executor", "dask", "--workers", "2", "--quiet"], timeout=240, capture_output=True,
                            text=True)
    assert result.returncode == 0, result.stderr[-3000:]
    serial = read_results(tmp_path / "serial.h5")
    for name in ("pool", "dask"):
        other = read_results(tmp_path / f"{name}.h5")
        assert tables_equal(serial["table"], other["table"]), name
        for run in range(6):
            assert read_kept(tmp_path / f"{name}.h5", run)["sensor.y"][1].tobytes() == \
                read_kept(tmp_path / "serial.h5", run)["sensor.y"][1].tobytes()
        # fresh Dask worker processes loaded every kernel from the cache: nothing compiled
        assert other["timing"]["compiled_kernels"].tolist() == [0] * 6, name
    assert set(serial["table"]["status"]) == {b"completed"}


def test_dask_scheduler_address(ramp_campaign, tmp_path):
    """--scheduler ADDRESS: a `dask scheduler` and a `dask worker` (2 processes; the modules behind those
    commands) started as a user would on a cluster; the table equals the serial one. Every process
    started here is stopped by its process group."""
    import json
    import os
    import signal
    import time

    path = ramp_campaign(runs=4)
    run_campaign(load_campaign(path), tmp_path / "serial.h5")
    scheduler_file = tmp_path / "scheduler.json"
    started = []
    quiet = dict(cwd=tmp_path, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)
    try:
        started.append(subprocess.Popen([sys.executable, "-m", "distributed.cli.dask_scheduler", "--scheduler-file",
                                         str(scheduler_file), "--port", "0", "--no-dashboard"], **quiet))
        deadline = time.monotonic() + 60
        while not scheduler_file.exists() and time.monotonic() < deadline:
            time.sleep(0.1)
        address = json.loads(scheduler_file.read_text())["address"]
        started.append(subprocess.Popen([sys.executable, "-m", "distributed.cli.dask_worker", "--scheduler-file",
                                         str(scheduler_file), "--nworkers", "2", "--nthreads", "1", "--no-dashboard"],
                                        **quiet))
        result = subprocess.run([sys.executable, "-m", "shell.cli", "montecarlo", str(path), "-o",
                                 str(tmp_path / "cluster.h5"), "--executor", "dask", "--scheduler", address, "--quiet"],
                                timeout=180, capture_output=True, text=True)
        assert result.returncode == 0, result.stderr[-3000:]
    finally:
        for process in reversed(started):
            os.killpg(process.pid, signal.SIGTERM)
            try:
                process.wait(timeout=20)
            except subprocess.TimeoutExpired:
                os.killpg(process.pid, signal.SIGKILL)
                process.wait(timeout=20)
    cluster = read_results(tmp_path / "cluster.h5")
    assert tables_equal(read_results(tmp_path / "serial.h5")["table"], cluster["table"])
    assert cluster["timing"]["compiled_kernels"].tolist() == [0] * 4


def test_guided_chunks_cover_every_run_once_and_shrink_to_single_runs():
    """Dask tasks: every run once, in order; at most 8 runs per task and never more than a quarter of the
    remaining runs per worker, so the tasks end in single runs and the workers finish together."""
    from shell.montecarlo.executors import guided_chunks

    for n, workers in ((100, 2), (7, 2), (1000, 8), (1, 4), (0, 2)):
        runs = list(range(n))
        chunks = guided_chunks(runs, workers)
        assert [i for chunk in chunks for i in chunk] == runs
        sizes = [len(c) for c in chunks]
        assert all(1 <= s <= 8 for s in sizes) and sizes == sorted(sizes, reverse=True)
        if n >= 4 * workers:
            assert sizes[-4 * workers:] == [1] * (4 * workers)  # the tail: single runs
    assert guided_chunks(list(range(100)), 2)[0] == list(range(8))


_WARM_UP = """
import sys
from shell.models.multibody import ENGINE_KERNELS
from shell.compiled_loop import advance
from shell.montecarlo.campaign import load_campaign
from shell.montecarlo.executors import start_worker

campaign = load_campaign(sys.argv[1], validate=False)   # as a Dask worker gets it: nothing run in this process
start_worker(campaign)
print("rebuilt", campaign.rebuild_reason is not None, "loops", len(advance.overloads), "engine",
      sum(len(kernel.overloads) for kernel in ENGINE_KERNELS.values()))
"""


def test_a_worker_warms_up_with_its_campaigns_scene_only(ramp_campaign, tmp_path):
    """A campaign that rebuilds its scene for every run (its integrator step is dispersed) warms a fresh worker
    up with run 0's scene: the compiled loop for its stepper only, and no engine in a scene without one (the
    generic warm-up that preceded this loaded the Runge-Kutta and exponential loops and the multibody engine
    whatever the campaign: 2 loops and 1 engine here)."""
    import os

    path = ramp_campaign(runs=3)
    path.write_text(path.read_text().replace(
        "dispersions:\n", "dispersions:\n  integrator.step: {distribution: choice, choices: [10 ms, 20 ms]}\n"))
    load_campaign(path)   # the coordinator's validation: kernels in numba's disk cache
    env = dict(os.environ, PYTHONPATH=os.getcwd())
    done = subprocess.run([sys.executable, "-c", _WARM_UP, str(path)], capture_output=True, text=True, env=env,
                          timeout=600)
    assert done.returncode == 0, done.stderr[-3000:]
    assert "rebuilt True loops 1 engine 0" in done.stdout, done.stdout
