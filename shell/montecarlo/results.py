"""Campaign results in HDF5: one table of draws + metrics per run, kept signals, metadata; resume.

Layout (a stable contract, like the log layout of shell/log_file.py)::

    /                    attrs: format="flexshell-campaign", format_version=1, name, fingerprint,
                         campaign (YAML text), campaign_file, scenario (YAML text), scenario_file,
                         seed (master), runs, status ("running" | "completed" | "interrupted")
    /table               (runs,) compound, row i = run i: run, status, message, t_end, one float64
                         column per drawn component (e.g. "controller.kp[0]"), one per metric column;
                         attrs draw_columns, metric_columns, units (JSON column -> unit), choices (JSON)
    /timing              (runs,) compound: wall_time, simulation_time, cpu_time, compiled_kernels, worker
    /signals/run_000017/<signal>/time, /values   kept signals of run 17 (attrs unit)

Only /timing depends on the machine and the executor; /table and /signals are bit-identical for the
same campaign whatever executed it. Rows are "pending" until their run completes.

A results file is written by one process at a time: a second campaign (or ``--resume``) refuses a file
another process holds (HDF5's lock), and ``--overwrite`` only ever replaces a campaign results file.

Kill safety: each completed run is first appended to a journal (``OUT.h5.journal``, one JSON line per
run; floats written with repr, arrays as base64 bytes, so they round-trip exactly) and only then
written to the HDF5 file, which is flushed. A campaign killed at any instant therefore keeps every
completed run: in the HDF5 file, or, if the kill corrupted the HDF5 file during a write, in the
journal, from which :func:`open_results` rebuilds the file on ``--resume``. The journal is removed
when a campaign completes.
"""

from __future__ import annotations

import base64
import json
import os
from pathlib import Path

import h5py
import numpy as np

from shell.log_file import LogError, check_log_target, held_by_another_process, open_for_reading
from shell.montecarlo.campaign import Campaign, RunRecord

FORMAT = "flexshell-campaign"
FORMAT_VERSION = 1


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
    """An open campaign results file; :meth:`write` stores one run (journal first, then HDF5)."""

    def __init__(self, path, campaign: Campaign, h5: h5py.File):
        self.path = str(path)
        self.campaign = campaign
        self.file = h5
        self.table = h5["table"]
        self.timing = h5["timing"]
        self.journal_path = self.path + ".journal"
        self._journal = open(self.journal_path, "a")

    def done(self) -> set[int]:
        status = self.table["status"]
        return {i for i, s in enumerate(status) if s != b"pending"}

    def write(self, record: RunRecord) -> None:
        self._journal.write(record_to_json(record) + "\n")
        self._journal.flush()
        self._store(record)
        self.file.flush()

    def _store(self, record: RunRecord) -> None:
        row = np.zeros((), dtype=self.table.dtype)
        row["run"], row["status"], row["message"], row["t_end"] = (record.run, record.status.encode(),
                                                                   record.message, record.t_end)
        for column, value in zip(self.campaign.draw_columns, record.draws):
            row[column] = value
        for column, value in zip(self.campaign.metric_columns, record.metrics):
            row[column] = value
        self.table[record.run] = row
        timing = np.zeros((), dtype=TIMING_DTYPE)
        timing["wall_time"], timing["simulation_time"] = record.wall_time, record.simulation_time
        timing["cpu_time"] = record.cpu_time
        timing["compiled_kernels"], timing["worker"] = record.compiled_kernels, record.worker
        self.timing[record.run] = timing
        group_name = f"signals/run_{record.run:06d}"
        if group_name in self.file:
            del self.file[group_name]
        group = self.file.create_group(group_name)
        for signal, (t, values, unit) in record.kept.items():
            g = group.create_group(signal)
            g.create_dataset("time", data=t, track_times=False).attrs["unit"] = "s"
            g.create_dataset("values", data=values, track_times=False).attrs["unit"] = unit

    def close(self, status: str) -> None:
        self.file.attrs["status"] = status
        self.file.close()
        self._journal.close()
        if status == "completed":
            Path(self.journal_path).unlink(missing_ok=True)


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
        Path(journal).unlink(missing_ok=True)
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
    if h5 is None:
        h5 = _create(path, campaign)
    results = ResultsFile(path, campaign, h5)
    done = results.done()
    for record in read_journal(journal):
        if record.run not in done and 0 <= record.run < campaign.runs \
                and record.draws.shape == (len(campaign.draw_columns),):
            results._store(record)
            done.add(record.run)
    h5.flush()
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
    """{signal: (time, values, unit)} kept for run ``run``."""
    with h5py.File(path, "r") as f:
        group = f.get(f"signals/run_{run:06d}")
        if group is None:
            return {}
        return {s: (g["time"][:], g["values"][:], str(g["values"].attrs["unit"])) for s, g in group.items()}


def tables_equal(a, b) -> bool:
    """Two campaign tables equal field by field, bit for bit (the message column holds variable-length
    strings: compared as text)."""
    return a.dtype == b.dtype and all(
        list(a[n]) == list(b[n]) if a.dtype[n].kind == "O" else a[n].tobytes() == b[n].tobytes() for n in a.dtype.names)
