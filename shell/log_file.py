"""Simulation logs in HDF5: writer (chunked, flushed as the run goes) and reader (dict of arrays).

Layout (a stable contract, docs/architecture.md)::

    /                         attrs: format="flexshell-log", format_version=1, status ("running",
                              "completed", "stopped", "failed", "interrupted"), message, seed,
                              scenario (YAML text)
    /<group>/time             (N,) float64, attrs unit="s"
    /<group>/<signal>         (N, *shape) float64, attrs unit, description, time="<group>/time"

One group per log rate, named after its period (``every_0.01s``). Datasets are resizable along the
first axis and chunked; rows are buffered in memory and written every ``flush_rows`` samples or
``flush_seconds`` of wall time, and the file is flushed, so a run that crashes keeps everything up to
the last flush plus the rows written by :meth:`LogWriter.close` in the error path.

Safety (a log is data a user may not be able to make again):

- A writer holds the log for its whole run (HDF5's exclusive lock); a second writer of the same path is
  refused before it touches the file, and a file that is not a flexshell log (a scenario, a campaign,
  anything else) is never overwritten (:func:`check_log_target`).
- The new log is created under a temporary name in the target's directory and renamed into place once
  its layout is written, so a writer refused or failing at start leaves the previous file as it was.
- ``last_time`` (attribute) is the time of the last sample on disk; :meth:`LogWriter.close` records the
  final status ("completed", "stopped", "failed", "interrupted") with it.
- Before each write the writer checks that the disk (and the process's file-size limit) leaves room for
  it and for closing: short of room it stops with :class:`LogError` while the file can still be closed,
  so a full disk gives a readable log marked "failed" instead of a broken file.
- A log whose status is still "running" while no process holds it was cut (``kill -9``, power loss):
  :func:`log_status` reports it as "interrupted", and :func:`read_log` warns about every log that did
  not complete (:class:`LogIncompleteWarning`).
"""

from __future__ import annotations

import fcntl
import os
import resource
import time as _time
import warnings
from dataclasses import dataclass
from pathlib import Path

import h5py
import numpy as np

FORMAT = "flexshell-log"
FORMAT_VERSION = 1
#: bytes kept free for closing a log (final rows of the buffers, attributes, HDF5 metadata)
CLOSE_RESERVE = 1 << 20
DONE_STATUSES = ("completed", "stopped")


class LogError(ValueError):
    """A log that cannot be written or read safely; the message names the file and what to do."""


class LogIncompleteWarning(UserWarning):
    """A log read from a run that did not complete (failed, interrupted, or cut by a kill)."""


def held_by_another_process(path) -> bool:
    """True when another process holds ``path`` open for writing (HDF5's lock, or a flexshell writer)."""
    fd = os.open(path, os.O_RDONLY)
    try:
        return _locked_by_another(fd)
    finally:
        os.close(fd)


def _locked_by_another(fd: int) -> bool:
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        return True
    fcntl.flock(fd, fcntl.LOCK_UN)
    return False


def _log_format(path: Path):
    """The ``format`` attribute of an HDF5 file, or None for anything else (text, empty, damaged)."""
    try:
        with h5py.File(path, "r", locking=False) as f:
            value = f.attrs.get("format")
    except (OSError, RuntimeError, ValueError):
        return None
    return value.decode() if isinstance(value, bytes) else value


def check_output_place(path) -> Path:
    """Refuse an output path that is a directory or lies in a missing or read-only directory (before a
    run, not after it); returns the path."""
    target = Path(path)
    parent = target.parent if str(target.parent) else Path(".")
    if target.is_dir():
        raise LogError(f"{path}: is a directory; give a file name")
    if not parent.is_dir():
        raise LogError(f"{path}: the directory {str(parent)!r} does not exist; create it or choose another output")
    if not os.access(parent, os.W_OK | os.X_OK):
        raise LogError(f"{path}: the directory {str(parent)!r} is not writable; choose another output")
    return target


def check_log_target(path, kind: str = FORMAT) -> None:
    """Refuse a log destination that would lose data or fail later: a directory, a missing or read-only
    directory, a file being written by another process, or an existing file that is not a log of
    ``kind`` (it is replaced only when it is one, or empty). Raises :class:`LogError`."""
    target = check_output_place(path)
    if not target.exists():
        return
    if not target.is_file():
        raise LogError(f"{path}: is not a regular file; choose another output")
    if target.stat().st_size == 0:  # nothing to lose (e.g. a name reserved by tempfile.mkstemp)
        return
    try:
        fd = os.open(target, os.O_RDONLY)
    except OSError as exc:
        raise LogError(f"{path}: cannot open the existing file ({exc.strerror})") from None
    try:
        if _locked_by_another(fd):
            raise LogError(f"{path}: is being written (or read) by another process; wait for it to finish "
                           "or choose another output")
    finally:
        os.close(fd)
    found = _log_format(target)
    if found != kind:
        what = "not an HDF5 file" if found is None else f"an HDF5 file of format {found!r}"
        raise LogError(f"{path}: exists and is {what}, not a {kind} file; refusing to overwrite it "
                       "(remove it or choose another output)")


def _kept(last_time: float) -> str:
    if last_time != last_time:
        return "the log holds no sample"
    return f"the log keeps the samples up to t = {last_time:.9g} s"


def _room_left(path: str) -> int:
    """Bytes that can still be added to the file at ``path``: the free space of its file system, and
    the process's file-size limit (RLIMIT_FSIZE) if it has one."""
    stats = os.statvfs(path)
    room = stats.f_bavail * stats.f_frsize
    limit = resource.getrlimit(resource.RLIMIT_FSIZE)[0]
    if limit != resource.RLIM_INFINITY:
        room = min(room, limit - os.path.getsize(path))
    return room


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
    """Append samples of groups of signals to an HDF5 log (see the module docstring for the safety rules)."""

    def __init__(self, path, groups: dict[str, list[LoggedSignal]], attributes: dict | None = None,
                 flush_rows: int = 512, flush_seconds: float = 2.0):
        self.path = str(path)
        self.last_time = float("nan")
        self._broken = None
        target = Path(self.path)
        check_log_target(target)
        temporary = target.parent / f".{target.name}.{os.getpid()}.part"
        try:
            self.file = h5py.File(temporary, "w", track_order=True)
        except (OSError, RuntimeError) as exc:
            raise LogError(f"{path}: cannot create the log ({exc})") from None
        try:
            self._write_layout(groups, attributes, flush_rows)
            self.file.flush()
            self._replace(target)
        except BaseException:
            self.file.close()
            temporary.unlink(missing_ok=True)
            raise
        self.flush_seconds = flush_seconds
        self._last_flush = _time.perf_counter()

    def _write_layout(self, groups, attributes, flush_rows) -> None:
        self.file.attrs["format"] = FORMAT
        self.file.attrs["format_version"] = FORMAT_VERSION
        self.file.attrs["status"] = "running"
        self.file.attrs["message"] = ""
        self.file.attrs["last_time"] = self.last_time
        for key, value in (attributes or {}).items():
            self.file.attrs[key] = value
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

    def _replace(self, target: Path) -> None:
        """Rename the new log (held by this process's HDF5 lock) over ``target``, unless another writer
        took ``target`` since :func:`check_log_target` looked at it."""
        temporary = Path(self.file.filename)
        if target.exists():
            fd = os.open(target, os.O_RDONLY)
            try:
                try:  # held until the rename: no other writer starts in between
                    fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
                except BlockingIOError:
                    raise LogError(f"{self.path}: another process opened it meanwhile (to write or read it); try again "
                                   "or choose another output") from None
                if os.fstat(fd).st_ino != os.stat(target).st_ino:
                    raise LogError(f"{self.path}: another process replaced it meanwhile; choose another output")
                os.replace(temporary, target)
            finally:
                os.close(fd)
        else:
            os.replace(temporary, target)

    def _guard(self, rows: int, width: int) -> None:
        """Stop before a write that the disk or the file-size limit cannot take (see the module docstring)."""
        if self._broken is not None:
            raise LogError(self._broken)
        needed = 8 * rows * (width + 1) * 2 + CLOSE_RESERVE
        try:
            room = _room_left(self.path)
        except OSError:
            return
        if room < needed:
            self._broken = (f"{self.path}: not enough room left to write the log (disk full or file-size limit: "
                            f"{max(room, 0)} bytes left); {_kept(self.last_time)}")
            raise LogError(self._broken)

    def _guarded(self, operation, *args) -> None:
        try:
            operation(*args)
        except (OSError, RuntimeError) as exc:
            self._broken = f"{self.path}: cannot write the log ({exc}); {_kept(self.last_time)}"
            raise LogError(self._broken) from None

    def append(self, group_name: str, t: float, values: list[np.ndarray]) -> None:
        buffer = self.buffers[group_name]
        row = buffer.count
        buffer.time[row] = t
        for store, value in zip(buffer.values, values):
            store[row] = value
        buffer.count += 1
        if buffer.count == buffer.rows:
            self._write(buffer)
            self._guarded(self._flush_file)
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
        self._guard(k, rows.shape[1] if rows.ndim == 2 else 1)
        self._guarded(self._write_rows, buffer, times, rows)
        if _time.perf_counter() - self._last_flush > self.flush_seconds:
            self._guarded(self._flush_file)

    def _write_rows(self, buffer: _GroupBuffer, times: np.ndarray, rows: np.ndarray) -> None:
        k = len(times)
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
        self._reached(float(times[-1]))

    def _reached(self, t: float) -> None:
        if not self.last_time >= t:  # also when last_time is still NaN
            self.last_time = t

    def _write(self, buffer: _GroupBuffer) -> None:
        n = buffer.count
        if n == 0:
            return
        self._guard(n, sum(v[0].size for v in buffer.values))
        self._guarded(self._write_buffer, buffer)

    def _write_buffer(self, buffer: _GroupBuffer) -> None:
        n = buffer.count
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
        self._reached(float(buffer.time[n - 1]))

    def _flush_file(self) -> None:
        self.file.flush()
        self._last_flush = _time.perf_counter()

    def flush(self) -> None:
        """Write every buffered row and flush the file to disk."""
        for buffer in self.buffers.values():
            self._write(buffer)
        self._guarded(self._flush_file)

    def close(self, status: str = "completed", message: str = "") -> None:
        """Write what is buffered (unless the disk refused an earlier write), record ``status``,
        ``message`` and ``last_time``, and release the file. A failure to write here is reported as
        :class:`LogError` after the file is closed."""
        if not self.file.id.valid:
            return
        problem = self._broken
        try:
            if problem is None:
                try:
                    self.flush()
                except LogError as exc:
                    problem = str(exc)
            if problem is not None and status in DONE_STATUSES:
                status, message = "failed", problem
            elif problem is not None and problem not in message:
                message = f"{message}; {problem}" if message else problem
            try:
                self.file.attrs["status"] = status
                self.file.attrs["message"] = message
                self.file.attrs["last_time"] = self.last_time
            except (OSError, RuntimeError) as exc:
                problem = problem or f"{self.path}: cannot record the final status ({exc})"
        finally:
            try:
                self.file.close()
            except (OSError, RuntimeError) as exc:
                problem = problem or f"{self.path}: cannot close the log ({exc})"
        if problem is not None and status in DONE_STATUSES:
            raise LogError(problem)


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


def log_status(path) -> dict:
    """``{"status", "message", "last_time"}`` of a log. A log whose recorded status is still "running"
    while no process holds it was cut (killed, or the machine stopped): reported as "interrupted"."""
    with _open_log(path) as f:
        status = _plain(f.attrs.get("status", ""))
        message = _plain(f.attrs.get("message", ""))
        last_time = float(f.attrs.get("last_time", float("nan")))
        if last_time != last_time:  # a cut log never recorded it: the last sample on disk
            times = [g["time"] for g in f.values() if isinstance(g, h5py.Group) and "time" in g]
            ends = [float(t[-1]) for t in times if t.shape[0]]
            last_time = max(ends) if ends else float("nan")
    if status == "running" and not held_by_another_process(path):
        status = "interrupted"
        message = ("the run was cut (killed or the machine stopped) before it closed the log; it holds the "
                   "samples written before that")
    return {"status": status, "message": message, "last_time": last_time}


def open_for_reading(path) -> h5py.File:
    """An HDF5 file opened for reading without taking HDF5's lock (a file another process is writing can
    be read); a file this process already has open is opened with that open's locking."""
    try:
        return h5py.File(path, "r", locking=False)
    except OSError as exc:
        if "locking flag values don't match" not in str(exc):
            raise
        return h5py.File(path, "r")


def _open_log(path):
    """The log opened for reading (:func:`open_for_reading`)."""
    try:
        f = open_for_reading(path)
    except FileNotFoundError:
        raise LogError(f"{path}: no such log") from None
    except (OSError, RuntimeError) as exc:
        raise LogError(f"{path}: cannot read the log; it is not an HDF5 file or it is damaged ({exc})") from None
    try:
        _check_format(f, path)
    except BaseException:
        f.close()
        raise
    return f


def read_log(path) -> dict[str, np.ndarray]:
    """Every dataset of a log as numpy arrays, keyed by signal name.

    Signal values are under their names ("controller.torque"); each rate group's time vector is under
    ``"time"`` when the log has one rate group, and under ``"<group>/time"`` always (the group of a
    signal is in :func:`log_info`). A log of a run that did not complete (failed, interrupted, cut by
    a kill) is read as far as it goes, with a :class:`LogIncompleteWarning` saying so.
    """
    out: dict[str, np.ndarray] = {}
    state = log_status(path)
    if state["status"] not in DONE_STATUSES and state["status"] != "running":
        warnings.warn(f"{path}: the run did not complete (status {state['status']}: {state['message']}); "
                      f"{_kept(state['last_time'])}", LogIncompleteWarning,
                      stacklevel=2)
    with _open_log(path) as f:
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
    """File attributes plus, per signal, its unit, description and time dataset. ``attributes["status"]``
    is as :func:`log_status` reports it (a cut log says "interrupted")."""
    state = log_status(path)
    with _open_log(path) as f:
        info = {"attributes": {k: _plain(v) for k, v in f.attrs.items()}, "signals": {}}
        for g in f.values():
            for name, ds in g.items():
                if name != "time":
                    info["signals"][name] = {k: _plain(v) for k, v in ds.attrs.items()} | {"shape": ds.shape}
    info["attributes"].update(state)
    return info


def _plain(value):
    if isinstance(value, bytes):
        return value.decode(errors="replace")
    return value.item() if isinstance(value, np.generic) else value


def _check_format(f: h5py.File, path) -> None:
    if _plain(f.attrs.get("format")) != FORMAT:
        raise LogError(f"{path}: not a flexshell log (attribute format={f.attrs.get('format')!r}, "
                       f"expected {FORMAT!r})")
