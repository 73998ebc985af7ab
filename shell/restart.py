"""Save and restore a run: the snapshot of a simulation, and the HDF5 restart file that holds one.

A snapshot holds everything a run carries from one instant to the next: time, continuous and discrete states,
the exact sample schedule of every sampled model and log group (Fractions), the state of every model's random
stream. ``restore(snapshot())`` continues bit-identically; the models then re-apply what they keep outside their
states (``Model.restored``: mass properties set in the engine). Restart file layout (``flexshell run
--save-state`` / ``--restore``): attrs ``format="flexshell-restart"``, ``t``, ``schedule`` (JSON of the sample
schedule, log schedule, random-stream states and model paths); datasets ``x`` and ``z``.
"""

from __future__ import annotations

import json
from fractions import Fraction

import h5py

from shell.model import ModelError

FORMAT = "flexshell-restart"


def snapshot(simulation) -> dict:
    """The full state of ``simulation``'s run (see the module docstring)."""
    context = simulation.context
    return {
        "t": simulation.t,
        "x": simulation.x.copy(),
        "z": simulation.z.copy(),
        "next_sample": [None if s is None else (s.numerator, s.denominator) for s in context.next_sample],
        "next_log": {g: None if e["next"] is None else (e["next"].numerator, e["next"].denominator)
                     for g, e in simulation.log_session.groups.items()},
        "rng": {m.path: rng.bit_generator.state for m, rng in zip(simulation.models, context.rngs)},
        "models": [m.path for m in simulation.models],
    }


def restore(simulation, snap: dict) -> None:
    """Put ``simulation`` in the state ``snap`` holds; refuses a snapshot of another scene."""
    models, context = simulation.models, simulation.context
    if list(snap["models"]) != [m.path for m in models]:
        raise ModelError(f"restart state was saved from a scene with models {list(snap['models'])}, "
                         f"this scene has {[m.path for m in models]}")
    if snap["x"].shape != simulation.x.shape or snap["z"].shape != simulation.z.shape:
        raise ModelError("restart state does not match this scene's state sizes "
                         f"(x {snap['x'].shape} vs {simulation.x.shape}, z {snap['z'].shape} vs {simulation.z.shape})")
    simulation.t = float(snap["t"])
    simulation.x[:] = snap["x"]
    simulation.z[:] = snap["z"]
    context.next_sample = [None if s is None else Fraction(*s) for s in snap["next_sample"]]
    groups = simulation.log_session.groups
    for g, value in snap["next_log"].items():
        if g in groups:
            groups[g]["next"] = None if value is None else Fraction(*value)
    for m, rng in zip(models, context.rngs):
        rng.bit_generator.state = snap["rng"][m.path]


def save(simulation, path) -> None:
    """Write :func:`snapshot` to an HDF5 restart file."""
    snap = snapshot(simulation)
    with h5py.File(path, "w") as f:
        f.attrs["format"] = FORMAT
        f.create_dataset("x", data=snap["x"])
        f.create_dataset("z", data=snap["z"])
        f.attrs["t"] = snap["t"]
        f.attrs["schedule"] = json.dumps({k: snap[k] for k in ("next_sample", "next_log", "rng", "models")})


def load(path) -> dict:
    """The snapshot in an HDF5 restart file."""
    with h5py.File(path, "r") as f:
        if f.attrs.get("format") != FORMAT:
            raise ModelError(f"{path}: not a flexshell restart file")
        snap = json.loads(f.attrs["schedule"])
        snap.update(t=float(f.attrs["t"]), x=f["x"][()], z=f["z"][()])
    return snap
