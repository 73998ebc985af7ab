"""A :class:`~shell.view.scene.ViewScene` as one self-contained HTML file (no server, no network).

The page (``assets/viewer.html``) inlines three.js r111 (``assets/three.min.js``, MIT, from Debian's
libjs-three) and its OrbitControls, the viewer (``assets/viewer.js``) and the scene as JSON in a
``<script type="application/json">`` block. Arrays travel as base64 of little-endian float32 (poses'
quaternions, mode shapes, modal coordinates, signals), float64 (times and positions: an orbit radius in
float32 keeps only half a metre) or int32 (element connectivity): 4 bytes per value become 5.33 characters,
against 10-20 for decimal JSON. Size of a flexible body: ``5.33 (3 G n + F n)`` bytes for G grids, n modes
and F frames (docs/view.md).
"""

from __future__ import annotations

import base64
import json
from importlib import resources
from pathlib import Path

import numpy as np

from shell.view.scene import ViewScene


def _array(values, dtype: str):
    if values is None:
        return None
    a = np.ascontiguousarray(np.asarray(values), dtype={"f4": "<f4", "f8": "<f8", "i4": "<i4"}[dtype])
    return {"dtype": dtype, "shape": list(a.shape), "b64": base64.b64encode(a.tobytes()).decode("ascii")}


def scene_payload(view: ViewScene) -> dict:
    """The JSON the viewer reads (see the module docstring for the encoding)."""
    bodies = []
    for b in view.bodies:
        bodies.append({
            "name": b.name, "kind": b.kind, "position": _array(b.position, "f8"),
            "quaternion": _array(b.quaternion, "f4"), "box": _array(b.box, "f4"),
            "box_center": _array(b.box_center, "f4"), "box_quaternion": _array(b.box_quaternion, "f4"),
            "vertices": _array(b.vertices, "f4"), "faces": _array(b.faces, "i4"), "edges": _array(b.edges, "i4"),
            "shapes": _array(b.shapes, "f4"), "eta": _array(b.eta, "f4"),
            "n_modes": 0 if b.eta is None else int(b.eta.shape[1]),
        })
    return {
        "title": view.title, "source": view.source, "time": _array(view.time, "f8"), "length": view.length,
        "deformation_scale": view.deformation_scale, "loop": view.loop, "track_body": view.track_body,
        "center": [float(c) for c in view.center],
        "bodies": bodies,
        "nodes": [{"name": n["name"], "body": n["body"], "position": _array(n["position"], "f8"),
                   "quaternion": _array(n["quaternion"], "f4"), "hinge": bool(n.get("hinge"))} for n in view.nodes],
        "wheels": [{"name": w["name"], "node": w["node"], "axis": _array(w["axis"], "f4"),
                    "angle": _array(w["angle"], "f4")} for w in view.wheels],
        "thrusters": [{"name": t["name"], "node": t["node"], "position": _array(t["position"], "f4"),
                       "direction": _array(t["direction"], "f4"), "level": _array(t["level"], "f4")}
                      for t in view.thrusters],
        "signals": [{"name": s["name"], "unit": s["unit"], "labels": s["labels"], "time": _array(s["time"], "f8"),
                     "values": _array(s["values"], "f4")} for s in view.signals],
        "notes": list(view.notes),
    }


def _asset(name: str) -> str:
    return resources.files("shell.view").joinpath("assets", name).read_text(encoding="utf-8")


def render_html(view: ViewScene) -> str:
    """The page's text."""
    data = json.dumps(scene_payload(view), separators=(",", ":"), allow_nan=False)
    data = data.replace("</", "<\\/")  # no </script> inside the JSON block
    title = (view.title.replace("&", "&amp;").replace("<", "&lt;").replace(">", "&gt;"))
    page = _asset("viewer.html")
    for key, value in (("/*TITLE*/", title), ("/*THREE*/", _asset("three.min.js")),
                       ("/*CONTROLS*/", _asset("OrbitControls.js")), ("/*VIEWER*/", _asset("viewer.js")),
                       ("/*DATA*/", data)):
        head, sep, tail = page.partition(key)
        page = head + value + tail
    return page


def write_html(view: ViewScene, path) -> int:
    """Write the page to ``path``; returns its size in bytes."""
    text = render_html(view)
    Path(path).write_text(text, encoding="utf-8")
    return len(text.encode("utf-8"))
