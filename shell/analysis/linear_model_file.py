"""Linear-model files: the HDF5 delivery layout (TM-2020-5008164 App. G.4), MATLAB .mat, python-control.

HDF5 layout (one file, read and written here):

```
/                      attrs: format="flexshell-linear-model", format_version=1, method, tolerance, points,
                              richardson, max_error, and the caller's metadata (scenario, created, ...)
/A /B /C /D            the state-space matrices (deviations from the operating point)
/state_index/<name>    int64 indices into the state vector of a model state (attrs unit)
/input_index/<name>    int64 indices into the input vector of an input port/element (attrs unit)
/output_index/<name>   int64 indices into the output vector of an output port/element/state (attrs unit)
/names/states, /names/inputs, /names/outputs              one name per row (UTF-8)
/units/states, /units/inputs, /units/outputs              one unit per row
/errors/A ... /errors/D                                   estimated absolute error of every entry
/operating_point/t, x, z, u, y, xdot                      where the model was linearized
/operating_point/tangent, x_rows                          the states' values, and each one's index in x
/steps/states, /steps/inputs                              the finite-difference steps used
```

A sampled closed-loop model (:mod:`shell.analysis.sampled_loop`) has the root attribute ``sample_time`` (s), no
inputs or outputs, and ``operating_point/drift`` (how far the reference run moved over one period).

As in the G.4 delivery file, the index maps say which rows/columns belong to which named signal
(``input_index/.thruster_force`` there, ``input_index/multibody.bus.torque`` here).

``write_mat`` writes the same content for MATLAB (``scipy.io.savemat``: A, B, C, D, state/input/output
names and units as cell arrays, the operating point, ``sample_time`` of a sampled model). ``to_statespace``
returns a python-control ``StateSpace`` carrying the state, input and output names (needs the ``control`` package; python-control
reserves '.', so dots become '/': ``multibody/bus/torque[2]``).
"""

from __future__ import annotations

import json

import h5py
import numpy as np

from shell.analysis.linearize import LinearModel

FORMAT = "flexshell-linear-model"
FORMAT_VERSION = 1
_STRINGS = h5py.string_dtype("utf-8")


def write_linear_model(path, model: LinearModel) -> None:
    """Write ``model`` to an HDF5 linear-model file (layout in the module docstring)."""
    with h5py.File(path, "w") as f:
        f.attrs["format"] = FORMAT
        f.attrs["format_version"] = FORMAT_VERSION
        for key in ("points", "richardson", "tolerance", "order"):
            f.attrs[key] = model.method[key]
        f.attrs["max_error"] = model.max_error
        for key, value in model.metadata.items():
            f.attrs[key] = value if isinstance(value, (int, float, str, bool)) else json.dumps(value)
        for key in ("A", "B", "C", "D"):
            f.create_dataset(key, data=getattr(model, key))
            f.create_dataset(f"errors/{key}", data=model.errors[key])
        for group, index, units in (("state_index", model.state_index, model.state_units),
                                    ("input_index", model.input_index, model.input_units),
                                    ("output_index", model.output_index, model.output_units)):
            g = f.create_group(group)
            for order, (name, rows) in enumerate(index.items()):
                ds = g.create_dataset(name.replace("/", "|"), data=np.asarray(rows, dtype=np.int64))
                ds.attrs["name"] = name
                ds.attrs["order"] = order
                ds.attrs["unit"] = units[int(rows[0])] if len(rows) else ""
        for kind, names, units in (("states", model.state_names, model.state_units),
                                   ("inputs", model.input_names, model.input_units),
                                   ("outputs", model.output_names, model.output_units)):
            f.create_dataset(f"names/{kind}", data=np.array(names, dtype=object), dtype=_STRINGS)
            f.create_dataset(f"units/{kind}", data=np.array(units, dtype=object), dtype=_STRINGS)
        for key, value in model.operating_point.items():
            f.create_dataset(f"operating_point/{key}", data=np.asarray(value, dtype=float))
        f.create_dataset("steps/states", data=model.method["state_steps"])
        f.create_dataset("steps/inputs", data=model.method["input_steps"])


def read_linear_model(path) -> LinearModel:
    """Read a file written by :func:`write_linear_model`."""
    with h5py.File(path, "r") as f:
        if f.attrs.get("format") != FORMAT:
            raise ValueError(f"{path}: not a flexshell linear-model file (attribute format = "
                             f"{f.attrs.get('format')!r}, expected {FORMAT!r})")
        names = {k: [s.decode() if isinstance(s, bytes) else s for s in f[f"names/{k}"][()]]
                 for k in ("states", "inputs", "outputs")}
        units = {k: [s.decode() if isinstance(s, bytes) else s for s in f[f"units/{k}"][()]]
                 for k in ("states", "inputs", "outputs")}

        def index(group):
            items = sorted(f[group].values(), key=lambda ds: int(ds.attrs["order"]))
            return {str(ds.attrs["name"]): ds[()] for ds in items}

        method = {key: f.attrs[key].item() if hasattr(f.attrs[key], "item") else f.attrs[key]
                  for key in ("points", "richardson", "tolerance", "order")}
        method["richardson"] = bool(method["richardson"])
        method["state_steps"] = f["steps/states"][()]
        method["input_steps"] = f["steps/inputs"][()]
        reserved = {"format", "format_version", "points", "richardson", "tolerance", "order", "max_error"}
        metadata = {k: v for k, v in f.attrs.items() if k not in reserved}
        op = {k: (f[f"operating_point/{k}"][()]) for k in f["operating_point"]}
        op["t"] = float(op["t"])
        return LinearModel(f["A"][()], f["B"][()], f["C"][()], f["D"][()], names["states"], units["states"],
                           names["inputs"], units["inputs"], names["outputs"], units["outputs"],
                           {k: f[f"errors/{k}"][()] for k in ("A", "B", "C", "D")}, op,
                           index("state_index"), index("input_index"), index("output_index"), method, metadata)


def write_mat(path, model: LinearModel) -> None:
    """MATLAB .mat (v5) with A, B, C, D, names and units (cell arrays), operating point and errors."""
    from scipy.io import savemat

    def cells(strings):
        out = np.empty((len(strings), 1), dtype=object)
        out[:, 0] = strings
        return out

    sampled = {"sample_time": float(model.metadata["sample_time"])} if "sample_time" in model.metadata else {}
    savemat(path, {
        **sampled,
        "A": model.A, "B": model.B, "C": model.C, "D": model.D,
        "state_names": cells(model.state_names), "state_units": cells(model.state_units),
        "input_names": cells(model.input_names), "input_units": cells(model.input_units),
        "output_names": cells(model.output_names), "output_units": cells(model.output_units),
        "A_error": model.errors["A"], "B_error": model.errors["B"],
        "C_error": model.errors["C"], "D_error": model.errors["D"],
        "operating_point": {k: np.asarray(v, dtype=float) for k, v in model.operating_point.items()},
    }, do_compression=True)


def control_signal_name(name: str) -> str:
    """A flexshell signal name as python-control accepts it ('.' is reserved there): dots become '/'s,
    e.g. ``multibody.bus.torque[2]`` -> ``multibody/bus/torque[2]``."""
    return name.replace(".", "/")


def to_statespace(model: LinearModel):
    """python-control ``StateSpace`` with the model's state, input and output names
    (:func:`control_signal_name`: ``multibody/bus/torque[2]``)."""
    try:
        import control
    except ImportError:
        raise ImportError("to_statespace needs the python-control package: python3 -m pip install control") \
            from None
    return control.ss(model.A, model.B, model.C, model.D,
                      states=[control_signal_name(n) for n in model.state_names],
                      inputs=[control_signal_name(n) for n in model.input_names],
                      outputs=[control_signal_name(n) for n in model.output_names])
