"""The campaign results file, format 2: one dataset per kept signal for all runs (rows padded with NaN past a
run's own samples), written in batches behind the per-run journal; format 1 files are read, not resumed."""

import h5py
import numpy as np
import pytest

from shell.cli import main
from shell.montecarlo import results as results_module
from shell.montecarlo.campaign import load_campaign
from shell.montecarlo.executors import run_campaign
from shell.montecarlo.results import ResultsError, open_results, read_journal, read_kept, read_results, tables_equal


def test_runs_of_different_lengths_keep_exactly_their_samples(ramp_campaign, tmp_path):
    """stop.time dispersed between 1 s and 2 s: runs keep 11 or 21 samples at 10 Hz; every run reads back its own
    samples bit for bit, whichever executor stored them and in whichever order the sample axis grew."""
    path = ramp_campaign(runs=8)
    text = path.read_text().replace("dispersions:\n", "dispersions:\n  stop.time: {distribution: choice, "
                                                      "choices: [1 s, 2 s]}\n")
    path.write_text(text)
    campaign = load_campaign(path)
    run_campaign(campaign, tmp_path / "serial.h5", executor="serial")
    run_campaign(campaign, tmp_path / "pool.h5", executor="pool", workers=2)
    lengths = []
    for run in range(8):
        record = campaign.run(run)
        t, values, unit = record.kept["sensor.y"]
        lengths.append(len(t))
        for name in ("serial", "pool"):
            kept_t, kept_values, kept_unit = read_kept(tmp_path / f"{name}.h5", run)["sensor.y"]
            assert kept_t.tobytes() == t.tobytes() and kept_values.tobytes() == values.tobytes() and kept_unit == unit
    assert set(lengths) == {11, 21}, lengths  # both lengths occur with this seed
    assert tables_equal(read_results(tmp_path / "serial.h5")["table"], read_results(tmp_path / "pool.h5")["table"])
    with h5py.File(tmp_path / "serial.h5") as f:
        assert f.attrs["format_version"] == 2
        group = f["signals/sensor.y"]
        assert group["samples"][:].tolist() == lengths
        assert group["time"].shape == (8, 21) and group["values"].shape == (8, 21)
        assert group["values"].attrs["unit"] == "m" and group["time"].attrs["unit"] == "s"
        short = lengths.index(11)
        assert np.isnan(group["values"][short, 11:]).all() and np.isnan(group["time"][short, 11:]).all()


def test_a_port_of_another_size_is_kept_apart(write, tmp_path):
    """A dispersion that changes a kept port's size (a Constant's configured shape): runs whose samples do not
    fit the signal's dataset are kept in their own group, none is dropped."""
    write("shape.yaml", """
        models:
          c: {type: Constant, config: {unit: m, shape: [2]}}
        integrator: {method: rk4, step: 0.1 s}
        stop: {time: 0.5 s}
        log: {rate: 10 Hz, signals: [c.y]}
        """)
    path = write("shape_campaign.yaml", """
        scenario: shape.yaml
        runs: 6
        seed: 1
        dispersions:
          c.config.shape: {distribution: choice, choices: [[2], [3]]}
        keep: [c.y]
        """)
    campaign = load_campaign(path)
    run_campaign(campaign, tmp_path / "out.h5")
    shapes = []
    for run in range(6):
        t, values, unit = read_kept(tmp_path / "out.h5", run)["c.y"]
        assert t.shape == (6,) and unit == "m" and not np.isnan(values).any()
        shapes.append(values.shape[1])
        assert values.tobytes() == campaign.run(run).kept["c.y"][1].tobytes()
    assert set(shapes) == {2, 3}, shapes
    with h5py.File(tmp_path / "out.h5") as f:
        first = f["signals/c.y/values"].shape[2]
        apart = sorted(int(name[4:]) for name in f["signals/c.y/other"])
        assert apart == [run for run in range(6) if shapes[run] != first]
        assert [int(n) for n in f["signals/c.y/samples"][:]] == [6 if s == first else -1 for s in shapes]


def test_runs_not_yet_in_the_file_are_in_the_journal(ramp_campaign, tmp_path, monkeypatch):
    """Runs completed within the batch interval are in the journal before they are in the HDF5 file; a process
    that dies then (the file closed as a kill leaves it, the batch never written) loses none: --resume stores
    them, equal to an uninterrupted campaign."""
    campaign = load_campaign(ramp_campaign(runs=5))
    monkeypatch.setattr(results_module, "FLUSH_SECONDS", 3600.0)
    output = tmp_path / "cut.h5"
    results = open_results(output, campaign)
    for run in (0, 3, 1):
        results.write(campaign.run(run))
    assert results.done() == {0, 1, 3}
    results.file.close()   # as a kill leaves it: the batch was never written
    results._journal.close()
    assert {r.run for r in read_journal(str(output) + ".journal")} == {0, 1, 3}
    assert set(read_results(output)["table"]["status"]) == {b"pending"}
    executed = []
    run_campaign(campaign, output, resume=True, progress=lambda record, done, total: executed.append(record.run))
    assert sorted(executed) == [2, 4]
    run_campaign(campaign, tmp_path / "fresh.h5")
    assert tables_equal(read_results(output)["table"], read_results(tmp_path / "fresh.h5")["table"])
    for run in range(5):
        assert read_kept(output, run)["sensor.y"][1].tobytes() == \
            read_kept(tmp_path / "fresh.h5", run)["sensor.y"][1].tobytes()


def test_a_slow_campaign_writes_each_run_at_once(ramp_campaign, tmp_path, monkeypatch):
    """Once FLUSH_SECONDS have passed since the file's last write (runs slower than that), each run is in the
    HDF5 file when write returns."""
    campaign = load_campaign(ramp_campaign(runs=3))
    monkeypatch.setattr(results_module, "FLUSH_SECONDS", 0.0)
    results = open_results(tmp_path / "slow.h5", campaign)
    try:
        results.write(campaign.run(1))
        assert results.table["status"].tolist() == [b"pending", b"completed", b"pending"]
        assert results.file["signals/sensor.y/samples"][:].tolist() == [-1, 21, -1]
    finally:
        results.close("partial")


def _format_1_file(campaign, path):
    """A results file in the format-1 layout (one group per run), written here with h5py as an earlier
    flexshell wrote it."""
    results = open_results(path, campaign)
    results.close("partial")
    (path.parent / (path.name + ".journal")).write_text("")
    record = campaign.run(2)
    with h5py.File(path, "a") as f:
        f.attrs["format_version"] = 1
        del f["signals"]
        group = f.create_group("signals/run_000002/sensor.y")
        t, values, unit = record.kept["sensor.y"]
        group.create_dataset("time", data=t).attrs["unit"] = "s"
        group.create_dataset("values", data=values).attrs["unit"] = unit
    return record


def test_format_1_files_are_read_and_not_resumed(ramp_campaign, tmp_path, capsys):
    path = ramp_campaign(runs=4)
    campaign = load_campaign(path)
    output = tmp_path / "old.h5"
    record = _format_1_file(campaign, output)
    t, values, unit = read_kept(output, 2)["sensor.y"]
    assert values.tobytes() == record.kept["sensor.y"][1].tobytes() and unit == "m"
    assert read_kept(output, 1) == {}
    with pytest.raises(ResultsError, match="format_version 1 .* --resume continues files of format_version 2"):
        open_results(output, campaign, resume=True)
    assert main(["montecarlo", str(path), "-o", str(output), "--resume", "--quiet"]) == 1
    error = capsys.readouterr().err
    assert "old.h5 has the results layout of format_version 1" in error and "--overwrite" in error
    assert "Traceback" not in error
