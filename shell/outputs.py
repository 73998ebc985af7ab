"""One guard for every file a ``flexshell`` verb writes: an output never replaces one of the verb's own inputs,
nor an existing file of another kind, unless the user passes ``--overwrite`` (issue 34).

Every verb that writes (run's log and ``--save-state``, montecarlo's results and ``--rerun`` log, linearize's
model and ``--mat``, fem2modal's body file, view's page, plot's figures, report's directory) calls
:func:`guard_output` with what it will write, the :class:`Kind` of file it writes and the files it reads,
before doing any work (a refused output costs nothing; a run may take hours). The guard refuses:

* a directory, a missing or read-only directory, a file another process is writing (always: no flag makes
  these writable, :func:`shell.log_file.check_output_place`);
* an output that is one of the verb's inputs, compared as files (``os.path.samefile``: device and inode, so a
  symbolic or hard link, ``./x`` or ``../d/x`` are caught as well as the same string), unless ``--overwrite``;
* an existing, non-empty file that is not of the verb's own kind (a NASTRAN deck as a body file, a scenario as
  a log, a text file as a figure), unless ``--overwrite``.

A file of the verb's own kind is replaced, as before (a log by the next run's log). What a kind is, is read
from the file, never from its name: an HDF5 ``format`` attribute, a body file's version attribute, a MAT-file
header, an HTML page's first tag, an image's signature (and, for the formats that record their creator, that
matplotlib drew it, so that a paper saved as ``notes.pdf`` is not taken for a figure).

The lower layers keep their own checks (:class:`shell.log_file.LogWriter` and the campaign results file refuse
any file that is not theirs, whatever the command line said): a verb told ``--overwrite`` removes an approved
foreign file with :func:`clear_for_writing` at the moment it starts writing, so that a refusal found later
(a scene that does not build) still leaves the file as it was.
"""

from __future__ import annotations

import fnmatch
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

OVERWRITE = "--overwrite"
OVERWRITE_HELP = ("replace an existing output even when it is not a file this command writes, or is one of "
                  "its inputs (without it such an output is refused)")
#: bytes read from each end of a file to recognise its kind
PEEK = 16384


class OutputError(ValueError):
    """An output that would lose data or cannot be written; the message names the file and what to do."""


@dataclass(frozen=True)
class Kind:
    """A kind of file a verb writes: ``name`` for messages, ``recognises(path)`` for an existing file."""

    name: str
    recognises: Callable[[Path], bool]
    hdf5: bool = False


def _ends(path: Path) -> tuple[bytes, bytes]:
    """The first and the last :data:`PEEK` bytes of a file."""
    with open(path, "rb") as f:
        head = f.read(PEEK)
        f.seek(0, os.SEEK_END)
        size = f.tell()
        f.seek(max(size - PEEK, 0))
        return head, f.read(PEEK)


def _hdf5_attribute(path: Path, name: str):
    import h5py

    try:
        with h5py.File(path, "r", locking=False) as f:
            value = f.attrs.get(name)
    except (OSError, RuntimeError, ValueError):  # not HDF5, damaged
        return None
    return value.decode() if isinstance(value, bytes) else value


def hdf5_kind(format_name: str) -> Kind:
    """HDF5 files whose ``format`` attribute is ``format_name`` (flexshell-log, flexshell-campaign, ...)."""
    return Kind(f"{format_name} file", lambda path: _hdf5_attribute(path, "format") == format_name, hdf5=True)


LOG = hdf5_kind("flexshell-log")
RESTART = hdf5_kind("flexshell-restart")
CAMPAIGN = hdf5_kind("flexshell-campaign")
LINEAR_MODEL = hdf5_kind("flexshell-linear-model")
BODY_FILE = Kind("flexshell body file (fem2modal)",
                 lambda path: _hdf5_attribute(path, "FLEXSHELL_BODY_FILE_VERSION") is not None, hdf5=True)
MAT = Kind("MATLAB MAT-file", lambda path: _ends(path)[0].startswith(b"MATLAB"))
HTML = Kind("HTML page", lambda path: _ends(path)[0].lstrip().lower().startswith((b"<!doctype html", b"<html")))

#: figure formats plot and report write: (signature test of the first bytes, whether the format records its
#: creator, so that the figure must also say matplotlib drew it)
IMAGE_FORMATS = {
    "png": (lambda head: head.startswith(b"\x89PNG\r\n\x1a\n"), True),
    "pdf": (lambda head: head.startswith(b"%PDF-"), True),
    "svg": (lambda head: b"<svg" in head, True),
    "eps": (lambda head: head.startswith(b"%!PS"), True),
    "ps": (lambda head: head.startswith(b"%!PS"), True),
    "jpg": (lambda head: head.startswith(b"\xff\xd8\xff"), False),
    "jpeg": (lambda head: head.startswith(b"\xff\xd8\xff"), False),
    "tif": (lambda head: head.startswith((b"II*\x00", b"MM\x00*")), False),
    "tiff": (lambda head: head.startswith((b"II*\x00", b"MM\x00*")), False),
    "webp": (lambda head: head[:4] == b"RIFF" and head[8:12] == b"WEBP", False),
}


def figure_kind(path) -> Kind:
    """A figure in the format of ``path``'s suffix; refuses a suffix that is not a figure format."""
    suffix = Path(path).suffix.lower().lstrip(".")
    if suffix not in IMAGE_FORMATS:
        raise OutputError(f"{path}: {'.' + suffix if suffix else 'no suffix'} is not a figure format; give one of "
                          f"{', '.join('.' + s for s in IMAGE_FORMATS)}")
    signature, records_creator = IMAGE_FORMATS[suffix]

    def recognises(file: Path) -> bool:
        head, tail = _ends(file)
        return signature(head) and (not records_creator or b"matplotlib" in (head + tail).lower())

    drawn = " drawn by matplotlib" if records_creator else ""
    return Kind(f"{suffix.upper()} figure{drawn}", recognises)


def text_kind(name: str, first_line: str) -> Kind:
    """Text files that start with ``first_line`` (a file this project writes with a fixed header)."""
    return Kind(name, lambda path: _ends(path)[0].startswith(first_line.encode()))


def describe(path: Path, kind: Kind) -> str:
    """What an existing file is, as far as its kind goes (for a refusal's message)."""
    head, _ = _ends(path)
    if head.startswith(b"\x89HDF\r\n\x1a\n"):
        found = _hdf5_attribute(path, "format")
        if found is not None:
            return f"an HDF5 file of format {found!r}"
        if _hdf5_attribute(path, "FLEXSHELL_BODY_FILE_VERSION") is not None:
            return "a flexshell body file (fem2modal)"
        return "an HDF5 file without a format attribute"
    if kind.hdf5:
        return "not an HDF5 file"
    for suffix, (signature, _) in IMAGE_FORMATS.items():
        if signature(head):
            return f"a {suffix.upper()} image"
    try:
        head.decode("utf-8")
    except UnicodeDecodeError:
        return "a binary file"
    return "a text file"


def _a(name: str) -> str:
    return f"{'an' if name.startswith(('HTML', 'a', 'e', 'i', 'o', 'u')) else 'a'} {name}"


def _same_file(a: Path, b) -> bool:
    try:
        return os.path.samefile(a, b)
    except (OSError, ValueError):  # either does not exist (or a name the OS refuses)
        return False


def _refusal(path, what: str) -> OutputError:
    return OutputError(f"{path}: {what}; refusing to overwrite it (choose another output, or pass {OVERWRITE} "
                       "to replace it)")


def guard_output(path, kind: Kind, *, inputs=(), overwrite: bool = False, others=()) -> Path:
    """Refuse ``path`` as an output of ``kind`` when writing it would lose data (the module docstring says
    what); ``inputs`` are the files the verb reads (paths, or (path, what it is) pairs for the message),
    ``others`` the other outputs of the same command (two outputs on one file are refused whatever the flag).
    Returns the path."""
    from shell.log_file import LogError, check_output_place, held_by_another_process

    try:
        target = check_output_place(path)
    except LogError as exc:
        raise OutputError(str(exc)) from None
    for other in others:
        if other is not None and (_same_file(target, other) or target.resolve() == Path(other).resolve()):
            raise OutputError(f"{path}: is also the command's output {other}; give each output its own file")
    if not target.exists():
        return target
    if not target.is_file():
        raise OutputError(f"{path}: is not a regular file; choose another output")
    try:
        if held_by_another_process(target):
            raise OutputError(f"{path}: is being written (or read) by another process; wait for it to finish or "
                              "choose another output")
    except OSError as exc:
        raise OutputError(f"{path}: cannot open the existing file ({exc.strerror})") from None
    for source in inputs:
        source, role = source if isinstance(source, tuple) else (source, "one of this command's inputs")
        if source is not None and _same_file(target, source):
            if overwrite:
                return target
            same = "" if str(source) == str(path) else f" ({source})"
            raise _refusal(path, f"is {role}{same}")
    if overwrite or target.stat().st_size == 0:  # an empty file holds nothing to lose
        return target
    try:
        if not kind.recognises(target):
            found = describe(target, kind)
            raise _refusal(path, f"exists and is {found}, so not {_a(kind.name)}" if found.startswith("not ")
                           else f"exists and is {found}, not {_a(kind.name)}")
    except OSError as exc:
        raise OutputError(f"{path}: cannot read the existing file ({exc.strerror})") from None
    return target


def clear_for_writing(path, kind: Kind) -> None:
    """Remove ``path`` if it exists and is not of ``kind``: called by a verb told ``--overwrite``, at the moment
    it starts writing, for the lower layers that refuse any file not theirs (see the module docstring)."""
    target = Path(path)
    if target.is_file() and target.stat().st_size and not kind.recognises(target):
        target.unlink()


#: what flexshell report writes into its directory: file name patterns and their kinds
REPORT_FILES = (("percentiles.csv", text_kind("percentile table (CSV) of flexshell report", "column,unit,kind,")),
                ("percentiles.md", text_kind("campaign report (Markdown) of flexshell report", "# Campaign ")),
                *((pattern, figure_kind("chart.png")) for pattern in ("hist_*.png", "scatter_*.png", "signal_*.png")))


def guard_report_directory(directory, *, inputs=(), overwrite: bool = False) -> Path:
    """Refuse a report directory that is a file, or whose files of the names the report writes
    (:data:`REPORT_FILES`) are not of the report's kinds or are among the ``inputs``."""
    out = Path(directory)
    if out.exists() and not out.is_dir():
        raise OutputError(f"{directory}: exists and is not a directory; give a directory for the report")
    if not out.exists():  # made with its missing parents
        return out
    for entry in sorted(out.iterdir()):
        for pattern, kind in REPORT_FILES:
            if fnmatch.fnmatch(entry.name, pattern):
                guard_output(entry, kind, inputs=inputs, overwrite=overwrite)
                break
    return out
