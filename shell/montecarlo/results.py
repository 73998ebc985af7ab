"""Campaign results in HDF5: one table of draws + metrics per run, kept signals, metadata; resume.

Layout (a stable contract, like the log layout of shell/log_file.py)::

    /                    attrs: format="flexshell-campaign", format_version=2, name, fingerprint,
                         campaign (YAML text), campaign_file, scenario (YAML text), scenario_file,
                         seed (master), runs, status ("running" | "completed" | "interrupted")
    /table               (runs,) compound, row i = run i: run, status, message, t_end, one float64
                         column per drawn component (e.g. "controller.kp[0]"), one per metric column;
                         attrs draw_columns, metric_columns, units (JSON column -> unit), choices (JSON)
    /timing              (runs,) compound: wall_time, simulation_time, cpu_time, compiled_kernels, worker
    /signals/<signal>/samples   (runs,) int64: samples kept of run i (-1: none kept)
    /signals/<signal>/time      (runs, n) float64: row i = run i's log times, NaN past samples[i]
    /signals/<signal>/values    (runs, n, *shape) float64, attrs unit: likewise
    /signals/<signal>/other/run_000017/time, /values   a run whose samples have another shape than the
                         signal's first stored run (a dispersion that changes a port's size)

``n`` is the longest run stored so far (the sample axis grows); :func:`read_kept` returns a run's
``samples[i]`` rows. Format 1 (an earlier flexshell) kept one group per run, ``/signals/run_000017/<signal>/
time, /values``: it is still read, not resumed. One dataset per signal for all runs, written in batches,
costs the coordinator 0.3-0.6 ms per run (journal line included) instead of ~5 ms for the nine HDF5 objects
of a run's group, time the coordinator took from the workers on a machine with as many workers as cores.

Only /timing depends on the machine and the executor; /table and /signals are bit-identical for the
same campaign whatever executed it. Rows are "pending" until their run completes.

A results file is written by one process at a time: a second campaign (or ``--resume``) refuses a file
another process holds (HDF5's lock), and ``--overwrite`` only ever replaces a campaign results file.

Kill safety: each completed run is first appended to a journal (``OUT.h5.journal``, one JSON line per
run, flushed; floats written with repr, arrays as base64 bytes, so they round-trip exactly). The HDF5
file takes the journaled runs in batches (:data:`FLUSH_SECONDS` after its last write, or
:data:`FLUSH_RUNS` runs, and when the campaign ends or is interrupted), then is flushed. A campaign killed
at any instant therefore keeps every completed run: in the HDF5 file, or in the journal (a run completed
within the last second, or a file a kill corrupted during a write), from which :func:`open_results` stores
it on ``--resume``. The journal is removed when a campaign completes.
"""

from __future__ import annotations

import base64
import json
import os
import time
from pathlib import Path

import h5py
import numpy as np

from shell.log_file import LogError, check_log_target, held_by_another_process, open_for_reading
from shell.montecarlo.campaign import Campaign, RunRecord

FORMAT = "flexshell-campaign"
FORMAT_VERSION = 2
#: the HDF5 file takes the journaled runs when this long has passed since its last write ...
FLUSH_SECONDS = 1.0
#: ... or when this many runs wait (a slow campaign writes each run as it completes)
FLUSH_RUNS = 256


class ResultsError(ValueError):
    """A results file that cannot be created, resumed or read; the message names the file."""


def _table_dtype(campaign: Campaign) -> np.dtype:
    fields = [("run", "<i8"), ("status", "S9"), ("message", h5py.string_dtype()), ("t_end", "<f8")]
    fields += [(c, "<f8") for c in campaign.draw_columns + campaign.metric_columns]
    return np.dtype(fields)


TIMING_DTYPE = np.dtype([("wall_time", "<f8"), ("simulation_time", "<f8"), ("cpu_time", "<f8"), ("compiled_kernels", "<i8"),
                         ("worker", h5py.string_dtype())])


def _units(campaign: Campaign) -> dict:
    units = {}
    for d in campaign.dispersions:
        for c in d.columns():
            units[c] = "index" if d.distribution == "choice" else d.unit
    for m in campaign.metrics:
        for c in m.columns():
            units[c] = "s" if m.statistic == "settling_time" else (m.unit or "")
    return units


def _encode(array: np.ndarray) -> dict:
    array = np.ascontiguousarray(array, dtype="<f8")
    return {"shape": list(array.shape), "data": base64.b64encode(array.tobytes()).decode()}


def _decode(item: dict) -> np.ndarray:
    return np.frombuffer(base64.b64decode(item["data"]), dtype="<f8").reshape(item["shape"]).copy()


def record_to_json(record: RunRecord) -> str:
    return json.dumps({
        "run": record.run, "status": record.status, "message": record.message, "t_end": record.t_end,
        "draws": _encode(record.draws), "metrics": _encode(record.metrics), "wall_time": record.wall_time,
        "simulation_time": record.simulation_time, "cpu_time": record.cpu_time, "worker": record.worker,
        "compiled_kernels": record.compiled_kernels,
        "kept": {s: [_encode(t), _encode(v), u] for s, (t, v, u) in record.kept.items()}})


def record_from_json(line: str) -> RunRecord:
    item = json.loads(line)
    return RunRecord(item["run"], item["status"], item["message"], item["t_end"], _decode(item["draws"]),
                     _decode(item["metrics"]), item["wall_time"], item["simulation_time"], item["cpu_time"],
                     item["worker"], item["compiled_kernels"],
                     {s: (_decode(t), _decode(v), u) for s, (t, v, u) in item["kept"].items()})


def read_journal(path) -> list[RunRecord]:
    """Complete lines of a journal (a line cut short by a kill is ignored: its run is not done)."""
    records = []
    try:
        data = Path(path).read_text()
    except FileNotFoundError:
        return records
    for line in data.split("\n"):
        if not line.strip():
            continue
        try:
            records.append(record_from_json(line))
        except (ValueError, KeyError):
            continue
    return records


class ResultsFile:
    """An open campaign results file; :meth:`write` journals one run at once and stores it in the HDF5 file
    with the next batch (:meth:`flush`)."""

    def __init__(self, path, campaign: Campaign, h5: h5py.File):
        self.path = str(path)
        self.campaign = campaign
        self.file = h5
        self.table = h5["table"]
        self.timing = h5["timing"]
        self.journal_path = self.path + ".journal"
        self._journal = open(self.journal_path, "a")
        self._pending: dict[int, RunRecord] = {}
        self._flushed_at = time.monotonic()

    def done(self) -> set[int]:
        """Runs completed: stored in the file or waiting for the next batch."""
        status = self.table["status"]
        return {i for i, s in enumerate(status) if s != b"pending"} | set(self._pending)

    def write(self, record: RunRecord) -> None:
        self._journal.write(record_to_json(record) + "\n")
        self._journal.flush()
        self._pending[record.run] = record
        if len(self._pending) >= FLUSH_RUNS or time.monotonic() - self._flushed_at >= FLUSH_SECONDS:
            self.flush()

    def flush(self) -> None:
        """Store the runs waiting since the last batch (rows in run order, one write per dataset) and flush
        the file."""
        if self._pending:
            records = [self._pending[run] for run in sorted(self._pending)]
            self._store(records)
            self._pending.clear()
        self.file.flush()
        self._flushed_at = time.monotonic()

    def _store(self, records: list[RunRecord]) -> None:
        runs = [r.run for r in records]
        rows = np.zeros(len(records), dtype=self.table.dtype)
        timing = np.zeros(len(records), dtype=TIMING_DTYPE)
        for k, record in enumerate(records):
            row = rows[k]
            row["run"], row["status"], row["message"], row["t_end"] = (record.run, record.status.encode(),
                                                                       record.message, record.t_end)
            for column, value in zip(self.campaign.draw_columns, record.draws):
                row[column] = value
            for column, value in zip(self.campaign.metric_columns, record.metrics):
                row[column] = value
            timing[k] = (record.wall_time, record.simulation_time, record.cpu_time, record.compiled_kernels,
                         record.worker)
        _write_rows(self.table, runs, rows)
        _write_rows(self.timing, runs, timing)
        signals = {}
        for record in records:
            for signal, item in record.kept.items():
                signals.setdefault(signal, []).append((record.run, item))
        for signal, items in signals.items():
            self._store_signal(signal, items)

    def _store_signal(self, signal: str, items: list) -> None:
        """Rows ``items`` = [(run, (time, values, unit)), ...] (in run order) of a kept signal."""
        group = self.file.require_group("signals").get(signal)
        if group is None:
            group = self._create_signal(signal, items[0][1])
        time_set, values_set, samples_set = group["time"], group["values"], group["samples"]
        shape, unit = values_set.shape[2:], values_set.attrs["unit"]
        fits = []
        for run, item in items:
            if item[1].shape[1:] == shape and item[2] == unit:
                fits.append((run, item))
                continue
            apart = group.require_group("other")  # a port of another size in this run
            if f"run_{run:06d}" in apart:  # written before a kill that left the run pending: written again
                del apart[f"run_{run:06d}"]
            _write_record(apart.create_group(f"run_{run:06d}"), item)
        if not fits:
            return
        longest = max(len(t) for _, (t, _, _) in fits)
        if longest > time_set.shape[1]:
            time_set.resize(longest, axis=1)
            values_set.resize(longest, axis=1)
        width = time_set.shape[1]
        times = np.full((len(fits), width), np.nan)
        block = np.full((len(fits), width) + tuple(shape), np.nan)
        samples = np.zeros(len(fits), dtype=np.int64)
        for k, (_, (t, values, _)) in enumerate(fits):
            samples[k] = len(t)
            times[k, :len(t)] = t
            block[k, :len(t)] = values
        runs = [run for run, _ in fits]
        _write_rows(time_set, runs, times)
        _write_rows(values_set, runs, block)
        _write_rows(samples_set, runs, samples)

    def _create_signal(self, signal: str, item) -> h5py.Group:
        t, values, unit = item
        runs, n, shape = self.campaign.runs, max(len(t), 1), values.shape[1:]
        # one chunk per run's row (at most ~1 MB: a long record spans several)
        per_sample = 8 * max(int(np.prod(shape, dtype=np.int64)), 1)
        chunk = max(1, min(n, (1 << 20) // per_sample))
        group = self.file["signals"].create_group(signal)
        group.create_dataset("samples", shape=(runs,), dtype=np.int64, fillvalue=-1, track_times=False)
        group.create_dataset("time", shape=(runs, n), maxshape=(runs, None), chunks=(1, chunk), dtype=np.float64,
                             fillvalue=np.nan, track_times=False).attrs["unit"] = "s"
        group.create_dataset("values", shape=(runs, n) + shape, maxshape=(runs, None) + shape,
                             chunks=(1, chunk) + shape, dtype=np.float64, fillvalue=np.nan,
                             track_times=False).attrs["unit"] = unit
        return group

    def close(self, status: str) -> None:
        try:
            self.flush()
            self.file.attrs["status"] = status
        finally:
            self.file.close()
            self._journal.close()
        if status == "completed":
            Path(self.journal_path).unlink(missing_ok=True)


def _write_record(group: h5py.Group, item) -> None:
    """One run's ``(time, values, unit)`` as ``group/time`` and ``group/values`` (attrs unit): a kept signal kept
    apart, as every run's were in format 1 (:func:`_read_record` reads both)."""
    t, values, unit = item
    group.create_dataset("time", data=t, track_times=False).attrs["unit"] = "s"
    group.create_dataset("values", data=values, track_times=False).attrs["unit"] = unit


def _read_record(group: h5py.Group) -> tuple:
    return group["time"][:], group["values"][:], str(group["values"].attrs["unit"])


def _write_rows(dataset: h5py.Dataset, rows: list, data: np.ndarray) -> None:
    """``dataset[rows] = data`` for increasing row indices: one slice when they are consecutive (the serial
    executor's batches), else one point selection."""
    if rows[-1] - rows[0] == len(rows) - 1:
        dataset[rows[0]:rows[-1] + 1] = data
    else:
        dataset[rows] = data


def _create(path: str, campaign: Campaign) -> h5py.File:
    h5 = h5py.File(path, "w", track_order=True)
    attrs = {"format": FORMAT, "format_version": FORMAT_VERSION, "name": campaign.name,
             "fingerprint": campaign.fingerprint, "campaign": campaign.text, "campaign_file": campaign.file,
             "scenario": campaign.scenario_text, "scenario_file": campaign.scenario_file, "seed": campaign.seed,
             "runs": campaign.runs, "status": "running"}
    for key, value in attrs.items():
        h5.attrs[key] = value
    dtype = _table_dtype(campaign)
    pending = np.zeros(campaign.runs, dtype=dtype)
    pending["run"] = np.arange(campaign.runs)
    pending["status"] = b"pending"
    pending["message"] = ""
    for column in campaign.draw_columns + campaign.metric_columns + ["t_end"]:
        pending[column] = np.nan
    table = h5.create_dataset("table", data=pending, track_times=False)
    table.attrs["draw_columns"] = json.dumps(campaign.draw_columns)
    table.attrs["metric_columns"] = json.dumps(campaign.metric_columns)
    table.attrs["units"] = json.dumps(_units(campaign))
    table.attrs["choices"] = json.dumps({d.path: d.choices for d in campaign.dispersions if d.distribution == "choice"})
    timing = np.zeros(campaign.runs, dtype=TIMING_DTYPE)
    timing["wall_time"] = timing["simulation_time"] = timing["cpu_time"] = np.nan
    timing["worker"] = ""
    h5.create_dataset("timing", data=timing, track_times=False)
    h5.create_group("signals")
    h5.flush()
    return h5


def _discard_journal(journal: str, overwrite: bool) -> None:
    """Remove the journal a new campaign would append to; one that holds anything (completed runs of a campaign
    that was killed before its results file took them, or a file that is not a journal) only with --overwrite."""
    try:
        size = os.path.getsize(journal)
    except FileNotFoundError:
        return
    if size and not overwrite:
        runs = len(read_journal(journal))
        held = (f"holds {runs} completed run(s) of a campaign that did not finish" if runs
                else "is not empty and holds no run of a campaign")
        raise ResultsError(f"{journal} {held}: --resume to finish that campaign, --overwrite to discard the file, "
                           "or choose another output")
    Path(journal).unlink()


def open_results(path, campaign: Campaign, resume: bool = False, overwrite: bool = False) -> ResultsFile:
    """Create ``path`` for ``campaign``, or (``resume``) reopen it, replaying the journal.

    Refuses to overwrite an existing file unless ``overwrite``, and to resume a file written by a
    different campaign (the fingerprint covers the campaign and scenario texts).
    """
    path = str(path)
    journal = path + ".journal"
    exists = os.path.exists(path)
    if exists and not (resume or overwrite):
        raise ResultsError(f"{path} exists; pass --resume to finish that campaign or choose another output")
    if exists and os.path.isfile(path) and held_by_another_process(path):
        raise ResultsError(f"{path}: another process is writing this campaign (it holds the file); wait for it "
                           "to finish, or stop it and then --resume")
    if not (resume and exists):
        try:  # a new file, or --overwrite: only ever replaces a campaign results file
            check_log_target(path, FORMAT)
        except LogError as exc:
            raise ResultsError(str(exc)) from None
    if not resume or not exists and not os.path.exists(journal):
        if resume:
            raise ResultsError(f"{path}: nothing to resume (no results file and no journal {journal})")
        _discard_journal(journal, overwrite)
        results = ResultsFile(path, campaign, _create(path, campaign))
        return results
    h5 = None
    if exists:
        try:
            h5 = h5py.File(path, "a")
            fingerprint = h5.attrs.get("fingerprint")
            h5["table"], h5["timing"]
        except (OSError, KeyError):  # cut by a kill during a write (no one holds it: checked above): rebuilt
            # from the journal below
            if h5 is not None:
                h5.close()
            h5, fingerprint = None, None
            os.replace(path, path + ".damaged")
        if h5 is not None and fingerprint != campaign.fingerprint:
            h5.close()
            raise ResultsError(f"{path} was written by another campaign (or the campaign or scenario file changed "
                               f"since); resume needs the same files")
        version = h5.attrs.get("format_version") if h5 is not None else FORMAT_VERSION
        if version != FORMAT_VERSION:
            h5.close()
            raise ResultsError(f"{path} has the results layout of format_version {version} (an earlier flexshell); "
                               f"--resume continues files of format_version {FORMAT_VERSION}: finish it with the "
                               "flexshell that started it, or run the campaign again with --overwrite")
    if h5 is None:
        h5 = _create(path, campaign)
    results = ResultsFile(path, campaign, h5)
    done = results.done()
    for record in read_journal(journal):
        if record.run not in done and 0 <= record.run < campaign.runs \
                and record.draws.shape == (len(campaign.draw_columns),):
            results._pending[record.run] = record
    results.flush()
    return results


def read_results(path) -> dict:
    """{"table": structured array (runs,), "timing": ..., "attrs": file attributes, "units": {...},
    "draw_columns": [...], "metric_columns": [...], "choices": {...}}. A file still marked "running"
    that no process holds was cut by a kill: its status reads "interrupted"."""
    try:
        with open_for_reading(path) as f:
            if f.attrs.get("format") != FORMAT:
                raise ResultsError(f"{path}: not a flexshell campaign results file (format "
                                   f"{f.attrs.get('format')!r})")
            table = f["table"]
            rows = table[:]
            rows["message"] = [m.decode() if isinstance(m, bytes) else m for m in rows["message"]]
            attrs = dict(f.attrs)
            if attrs.get("status") == "running" and not held_by_another_process(path):
                attrs["status"] = "interrupted"  # cut by a kill: no process is writing it (finish with --resume)
            return {"table": rows, "timing": f["timing"][:], "attrs": attrs,
                    "units": json.loads(table.attrs["units"]),
                    "draw_columns": json.loads(table.attrs["draw_columns"]),
                    "metric_columns": json.loads(table.attrs["metric_columns"]),
                    "choices": json.loads(table.attrs["choices"])}
    except OSError as exc:
        raise ResultsError(f"{path}: cannot read the campaign results ({exc})") from None


def read_kept(path, run: int) -> dict:
    """{signal: (time, values, unit)} kept for run ``run`` (format 2, and format 1 of earlier files)."""
    with open_for_reading(path) as f:
        signals = f.get("signals")
        if signals is None:
            return {}
        if f.attrs.get("format_version", 1) == 1:
            group = signals.get(f"run_{run:06d}")
            return {} if group is None else {s: _read_record(g) for s, g in group.items()}
        kept = {}
        for signal, group in signals.items():
            other = group.get(f"other/run_{run:06d}")
            if other is not None:
                kept[signal] = _read_record(other)
                continue
            n = int(group["samples"][run])
            if n >= 0:
                kept[signal] = (group["time"][run, :n], group["values"][run, :n], str(group["values"].attrs["unit"]))
        return kept


def tables_equal(a, b) -> bool:
    """Two campaign tables equal field by field, bit for bit (the message column holds variable-length
    strings: compared as text)."""
    return a.dtype == b.dtype and all(
        list(a[n]) == list(b[n]) if a.dtype[n].kind == "O" else a[n].tobytes() == b[n].tobytes() for n in a.dtype.names)
