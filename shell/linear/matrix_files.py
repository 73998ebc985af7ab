"""State-space matrices from files: HDF5, MATLAB .mat and numpy .npz, each checked and refused with file and key.

What is read (``group`` selects an HDF5 group or a prefix ``group/`` of the keys of a .mat or .npz file)::

    A, B, C, D      the matrices (2-D; D of shape outputs x inputs even when zero)
    sample_time     optional scalar, seconds: a sampled system (absent: continuous)

A flexshell linear-model file (``flexshell linearize``, :mod:`shell.analysis.linear_model_file`) is read
through that module, with its signal names and units; its .mat export (``--mat``) through the same names here
(``input_names``, ``output_names``, ``state_names``, ``input_units``, ``output_units``: cell arrays); an .npz file
may hold the same keys as string arrays. Every refusal names the file, the key, what was expected and what
was given (:class:`~shell.linear.system.LinearSystemError`); a missing key lists the keys the file holds.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from shell.linear.system import KEYS, LinearSystem, LinearSystemError

SUFFIXES = (".h5", ".hdf5", ".mat", ".npz")
NAME_KEYS = ("input_names", "output_names", "state_names", "input_units", "output_units")
LINEAR_MODEL_FORMAT = "flexshell-linear-model"


def _strings(value) -> tuple:
    """Names from a cell array (.mat), a string array (.npz) or a list."""
    flat = np.asarray(value, dtype=object).reshape(-1)
    out = []
    for item in flat:
        while isinstance(item, np.ndarray):  # loadmat wraps each cell's string in arrays
            item = item.reshape(-1)[0] if item.size else ""
        out.append(item.decode() if isinstance(item, bytes) else str(item))
    return tuple(out)


def _read_hdf5(path: Path, group: str | None) -> tuple[dict, str]:
    import h5py

    try:
        with h5py.File(path, "r") as f:
            if f.attrs.get("format") == LINEAR_MODEL_FORMAT and group is None:
                return {"linear_model": True}, str(path)
            node = f if group is None else f.get(group)
            where = str(path) if group is None else f"{path}:{group}"
            if not isinstance(node, h5py.Group):
                raise LinearSystemError(f"{path}: no group {group!r}; groups: {sorted(k for k in f)}")
            entries = {key: node[key][()] for key in node if isinstance(node[key], h5py.Dataset)}
            if "sample_time" in node.attrs:
                entries.setdefault("sample_time", node.attrs["sample_time"])
            return entries, where
    except OSError as exc:
        raise LinearSystemError(f"{path}: cannot read as HDF5 ({exc})") from None


def _read_keyed(path: Path, group: str | None) -> tuple[dict, str]:
    try:
        if path.suffix.lower() == ".mat":
            from scipy.io import loadmat

            raw = {k: v for k, v in loadmat(path).items() if not k.startswith("__")}
        else:
            with np.load(path, allow_pickle=False) as data:
                raw = {k: data[k] for k in data.files}
    except (OSError, ValueError) as exc:
        kind = "a MATLAB .mat file" if path.suffix.lower() == ".mat" else "a numpy .npz file"
        raise LinearSystemError(f"{path}: cannot read as {kind} ({exc})") from None
    if group is None:
        return raw, str(path)
    prefix = group.rstrip("/") + "/"
    entries = {k[len(prefix):]: v for k, v in raw.items() if k.startswith(prefix)}
    if not entries:
        groups = sorted({k.split("/")[0] for k in raw if "/" in k})
        raise LinearSystemError(f"{path}: no group {group!r}; groups: {groups}")
    return entries, f"{path}:{group}"


def _scalar(where: str, key: str, value) -> float:
    array = np.asarray(value)
    if array.size != 1:
        raise LinearSystemError(f"{where}: {key}: expected one number (seconds), given shape {array.shape}")
    try:
        return float(array.reshape(-1)[0])
    except (TypeError, ValueError):
        raise LinearSystemError(f"{where}: {key}: expected a number (seconds), given {value!r}") from None


def read_state_space(path, group: str | None = None, require_stable: str | None = None) -> LinearSystem:
    """The system stored in ``path`` (module docstring). ``require_stable``: what the system is for, when it
    must be stable (then an unstable A is refused with its eigenvalues)."""
    path = Path(path)
    if not path.is_file():
        raise LinearSystemError(f"{path}: no such file")
    suffix = path.suffix.lower()
    if suffix not in SUFFIXES:
        raise LinearSystemError(f"{path}: expected an HDF5 (.h5, .hdf5), MATLAB (.mat) or numpy (.npz) file, "
                                f"given {suffix or 'no suffix'}")
    entries, where = _read_hdf5(path, group) if suffix in (".h5", ".hdf5") else _read_keyed(path, group)
    if entries.get("linear_model"):
        from shell.analysis.linear_model_file import read_linear_model

        model = read_linear_model(path)
        system = LinearSystem(model.A, model.B, model.C, model.D, None, model.input_names, model.output_names,
                              model.state_names, model.input_units, model.output_units, str(path))
    else:
        missing = [key for key in KEYS if key not in entries]
        if missing:
            raise LinearSystemError(f"{where}: no {', '.join(missing)}; expected the matrices A, B, C, D; the file "
                                    f"holds: {', '.join(sorted(entries)) or 'nothing'}")
        sample_time = _scalar(where, "sample_time", entries["sample_time"]) if "sample_time" in entries else None
        names = {key: _strings(entries[key]) for key in NAME_KEYS if key in entries}
        system = LinearSystem(*(entries[key] for key in KEYS), sample_time=sample_time, where=where, **names)
    if require_stable:
        system.require_stable(require_stable)
    return system
