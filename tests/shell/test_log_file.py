"""HDF5 log layout: chunked datasets written while the run goes, attributes, reader."""

import h5py
import numpy as np
import pytest

from shell.log_file import LoggedSignal, LogWriter, log_info, read_log


def test_rows_reach_the_file_before_close(tmp_path):
    path = tmp_path / "log.h5"
    signals = [LoggedSignal("plant.q", (4,), "1", "quaternion"), LoggedSignal("ctrl.torque", (3,), "N*m", "cmd")]
    writer = LogWriter(path, {"every_0.01s": signals}, {"seed": "1"}, flush_rows=512)
    for k in range(1200):
        writer.append("every_0.01s", 0.01 * k, [np.full(4, k), np.arange(3) + k])
    # two full buffers (1024 rows) are already on disk, chunked and resizable
    dataset = writer.file["every_0.01s/plant.q"]
    assert dataset.shape == (1024, 4)
    assert dataset.chunks == (512, 4) and dataset.maxshape == (None, 4)
    writer.close("completed", "reached t_final")
    log = read_log(path)
    assert log["time"].shape == (1200,) and log["every_0.01s/time"] is not None
    np.testing.assert_array_equal(log["ctrl.torque"][:, 0], np.arange(1200))
    info = log_info(path)
    assert info["signals"]["ctrl.torque"]["unit"] == "N*m"
    assert info["signals"]["ctrl.torque"]["time"] == "every_0.01s/time"
    assert info["attributes"]["status"] == "completed"


def test_reader_refuses_other_files(tmp_path):
    path = tmp_path / "other.h5"
    with h5py.File(path, "w") as f:
        f["x"] = [1.0]
    with pytest.raises(ValueError, match="not a flexshell log"):
        read_log(path)
