"""Serial, process-pool and Dask (LocalCluster, 2 worker processes) runs of one campaign give identical
tables and kept signals; workers load the kernels from numba's on-disk cache instead of compiling."""

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
