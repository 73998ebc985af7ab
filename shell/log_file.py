"""Simulation logs in HDF5: writer (chunked, flushed as the run goes) and reader (dict of arrays).

Layout (a stable contract, ARCHITECTURE.md)::

    /                         attrs: format="flexshell-log", format_version=1, status ("running",
                              "completed", "stopped", "failed", "interrupted"), message, seed,
                              scenario (YAML text)
    /<group>/time             (N,) float64, attrs unit="s"
    /<group>/<signal>         (N, *shape) float64, attrs unit, description, time="<group>/time"

One group per log rate, named after its period (``every_0.01s``). Datasets are resizable along the
first axis and chunked; rows are buffered in memory and written every ``flush_rows`` samples or
``flush_seconds`` of wall time, and the file is flushed, so a run that crashes keeps everything up to
the last flush plus the rows written by :meth:`LogWriter.close` in the error path.
"""

from __future__ import annotations

import time as _time
from dataclasses import dataclass

import h5py
import numpy as np

FORMAT = "flexshell-log"
FORMAT_VERSION = 1


@dataclass(frozen=True)
class LoggedSignal:
    name: str          # "model.port" or "model.state"
    shape: tuple
    unit: str
    description: str


class _GroupBuffer:
    def __init__(self, h5group: h5py.Group, signals: list[LoggedSignal], rows: int):
        self.group = h5group
        self.signals = signals
        self.rows = rows
        self.time = np.empty(rows)
        self.values = [np.empty((rows, *s.shape)) for s in signals]
        self.count = 0
        self.written = 0


class LogWriter:
    """Append samples of groups of signals to an HDF5 log."""

    def __init__(self, path, groups: dict[str, list[LoggedSignal]], attributes: dict | None = None,
                 flush_rows: int = 512, flush_seconds: float = 2.0):
        self.path = str(path)
        self.file = h5py.File(self.path, "w", track_order=True)
        self.file.attrs["format"] = FORMAT
        self.file.attrs["format_version"] = FORMAT_VERSION
        self.file.attrs["status"] = "running"
        self.file.attrs["message"] = ""
        for key, value in (attributes or {}).items():
            self.file.attrs[key] = value
        self.flush_seconds = flush_seconds
        self._last_flush = _time.perf_counter()
        self.buffers: dict[str, _GroupBuffer] = {}
        for group_name, signals in groups.items():
            g = self.file.create_group(group_name)
            chunk = min(flush_rows, 4096)
            ds = g.create_dataset("time", shape=(0,), maxshape=(None,), dtype="f8", chunks=(chunk,),
                                  track_times=False)
            ds.attrs["unit"] = "s"
            for s in signals:
                d = g.create_dataset(s.name, shape=(0, *s.shape), maxshape=(None, *s.shape), dtype="f8",
                                     chunks=(chunk, *s.shape), track_times=False)
                d.attrs["unit"] = s.unit
                d.attrs["description"] = s.description
                d.attrs["time"] = f"{group_name}/time"
            self.buffers[group_name] = _GroupBuffer(g, signals, flush_rows)
        self.file.flush()

    def append(self, group_name: str, t: float, values: list[np.ndarray]) -> None:
        buffer = self.buffers[group_name]
        row = buffer.count
        buffer.time[row] = t
        for store, value in zip(buffer.values, values):
            store[row] = value
        buffer.count += 1
        if buffer.count == buffer.rows:
            self._write(buffer)
            self._flush_file()
        elif _time.perf_counter() - self._last_flush > self.flush_seconds:
            self.flush()

    def append_rows(self, group_name: str, times: np.ndarray, rows: np.ndarray) -> None:
        """Append ``len(times)`` samples at once; ``rows`` (k, width) holds each sample's signals flattened
        and concatenated in the group's signal order (the compiled loop's log buffers)."""
        buffer = self.buffers[group_name]
        self._write(buffer)
        k = len(times)
        if k == 0:
            return
        start, stop = buffer.written, buffer.written + k
        ds = buffer.group["time"]
        ds.resize((stop,))
        ds[start:stop] = times
        column = 0
        for s in buffer.signals:
            size = int(np.prod(s.shape, dtype=np.int64))
            d = buffer.group[s.name]
            d.resize((stop, *s.shape))
            d[start:stop] = rows[:, column:column + size].reshape(k, *s.shape)
            column += size
        buffer.written = stop
        if _time.perf_counter() - self._last_flush > self.flush_seconds:
            self._flush_file()

    def _write(self, buffer: _GroupBuffer) -> None:
        n = buffer.count
        if n == 0:
            return
        start, stop = buffer.written, buffer.written + n
        ds = buffer.group["time"]
        ds.resize((stop,))
        ds[start:stop] = buffer.time[:n]
        for s, store in zip(buffer.signals, buffer.values):
            d = buffer.group[s.name]
            d.resize((stop, *s.shape))
            d[start:stop] = store[:n]
        buffer.written = stop
        buffer.count = 0

    def _flush_file(self) -> None:
        self.file.flush()
        self._last_flush = _time.perf_counter()

    def flush(self) -> None:
        """Write every buffered row and flush the file to disk."""
        for buffer in self.buffers.values():
            self._write(buffer)
        self._flush_file()

    def close(self, status: str = "completed", message: str = "") -> None:
        if not self.file.id.valid:
            return
        try:
            self.flush()
            self.file.attrs["status"] = status
            self.file.attrs["message"] = message
        finally:
            self.file.close()


class MemoryLog:
    """The :class:`LogWriter` interface kept in memory (Monte Carlo runs keep only what their metrics and
    kept signals need, without a temporary file): ``signals()`` gives ``{name: (time, values, unit)}``."""

    def __init__(self, groups: dict[str, list[LoggedSignal]]):
        self.groups = groups
        self.times: dict[str, list] = {g: [] for g in groups}
        self.rows: dict[str, list] = {g: [] for g in groups}
        self.status, self.message = "running", ""

    def append(self, group_name: str, t: float, values: list[np.ndarray]) -> None:
        self.times[group_name].append(np.array([t]))
        self.rows[group_name].append(np.concatenate([np.asarray(v, dtype=float).reshape(-1) for v in values])[None])

    def append_rows(self, group_name: str, times: np.ndarray, rows: np.ndarray) -> None:
        self.times[group_name].append(np.array(times, dtype=float))
        self.rows[group_name].append(np.array(rows, dtype=float))

    def flush(self) -> None:
        """Nothing to write: the samples are in memory."""

    def close(self, status: str = "completed", message: str = "") -> None:
        self.status, self.message = status, message

    def signals(self) -> dict:
        out = {}
        for g, signals in self.groups.items():
            time = np.concatenate(self.times[g]) if self.times[g] else np.zeros(0)
            width = sum(int(np.prod(s.shape, dtype=np.int64)) for s in signals)
            rows = np.concatenate(self.rows[g]) if self.rows[g] else np.zeros((0, width))
            column = 0
            for s in signals:
                size = int(np.prod(s.shape, dtype=np.int64))
                if s.name not in out:
                    out[s.name] = (time, rows[:, column:column + size].reshape(len(time), *s.shape), s.unit)
                column += size
        return out


def read_log(path) -> dict[str, np.ndarray]:
    """Every dataset of a log as numpy arrays, keyed by signal name.

    Signal values are under their names ("controller.torque"); each rate group's time vector is under
    ``"time"`` when the log has one rate group, and under ``"<group>/time"`` always (the group of a
    signal is in :func:`log_info`).
    """
    out: dict[str, np.ndarray] = {}
    with h5py.File(path, "r") as f:
        _check_format(f, path)
        groups = [g for g in f.values() if isinstance(g, h5py.Group)]
        for g in groups:
            group_name = g.name.strip("/")
            for name, ds in g.items():
                if name == "time":
                    out[f"{group_name}/time"] = ds[()]
                else:
                    out[name] = ds[()]
        if len(groups) == 1:
            out["time"] = out[f"{groups[0].name.strip('/')}/time"]
    return out


def log_info(path) -> dict:
    """File attributes plus, per signal, its unit, description and time dataset."""
    with h5py.File(path, "r") as f:
        _check_format(f, path)
        info = {"attributes": {k: _plain(v) for k, v in f.attrs.items()}, "signals": {}}
        for g in f.values():
            for name, ds in g.items():
                if name != "time":
                    info["signals"][name] = {k: _plain(v) for k, v in ds.attrs.items()} | {"shape": ds.shape}
    return info


def _plain(value):
    return value.item() if isinstance(value, np.generic) else value


def _check_format(f: h5py.File, path) -> None:
    if f.attrs.get("format") != FORMAT:
        raise ValueError(f"{path}: not a flexshell log (attribute format={f.attrs.get('format')!r}, "
                         f"expected {FORMAT!r})")
