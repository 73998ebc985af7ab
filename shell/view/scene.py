"""What ``flexshell view`` draws: a scene's geometry and its motion, gathered into plain arrays.

Three sources give a :class:`ViewScene`:

* a log (:func:`from_log`): the scene is rebuilt from the scenario text the log keeps (``scenario``
  attribute; body files are found relative to ``scenario_file``), without running it; the motion is the
  logged engine coordinates ``<engine>.q`` (or the per-body ``<engine>.<body>.q`` / ``.modal_q`` ports;
  a body whose coordinates are not logged stays at its initial pose, said in the notes);
* a scenario (:func:`from_scenario`): its initial configuration, or, with ``t_final``, a short run that
  logs ``<engine>.q``, the wheels' speeds and the thrusters' thrust (and the scenario's own signals) to a
  temporary log, then as above;
* a linear model (:func:`from_linear_model`): one system mode, ``q(phi) = q0 (+) s Re(v e^{i phi})`` over
  one period (:func:`shell.analysis.system_modes.state_space_modes`; ``(+)`` adds plain coordinates and
  composes hinge quaternions with ``Exp`` of the rotation-vector rows, as the linearization's tangent
  coordinates are defined: ``q = q0 (x) Exp(phi)``, shell/analysis/linearize.py); a model of a scene with closure
  constraints, in minimal coordinates, has its dependent coordinates moved onto the constraints in every frame
  (:func:`shell.analysis.linearize.close_loops`).

Poses: body frames from :meth:`dynamics.system.MultibodySystem.body_poses`, node frames (elastic motion
included) from :meth:`~dynamics.system.MultibodySystem.node_kinematics`, evaluated once per frame in
Python. Quaternions are stored scalar-last ``[x, y, z, w]`` (three.js order) of the rotation body -> world.

Geometry (body frame):

* a rigid body is its equivalent-inertia box: the homogeneous box with the body's mass and principal
  moments, ``a_1^2 = 6 (I_2 + I_3 - I_1) / m`` and cyclically (edges ``a_i`` along the principal axes,
  centred at the centre of mass), or a user mesh (``meshes``: any file trimesh reads, metres, body axes);
* a flexible body is its FE grids (``FlexibleBodyData.grid_positions``) and elements (the body file's
  ``Geometry`` group, or the deck named by its ``SOURCE`` when the file predates it): bars as lines, shells
  as triangles, solids as their faces; the browser deforms it as ``l0 + s sum_k eta_k gamma_k`` with the
  translation mode shapes ``gamma`` of the kept modes and the deformation scale ``s``.

Devices found by model class in the flattened scene: a :class:`~shell.models.reaction_wheel.ReactionWheel`
(spin axis, its logged ``wheel_speed`` integrated into a spin angle), a :class:`~shell.models.thruster.Thruster`
(position, direction, its logged ``thrust`` over ``max_thrust``, or the rate of its ``propellant_used``
times ``Isp g0``). The node a device acts on is the engine port its connections reach (through load sums).
"""

from __future__ import annotations

import json
import math
import re
import tempfile
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from dynamics.hinges import HINGE_NQ, HINGE_TYPES
from shell.analysis.linear_model_file import read_linear_model
from shell.analysis.linearize import close_loops, quaternion_exp
from shell.analysis.system_modes import state_space_modes
from shell.assembly import flatten
from shell.attitude import quaternion_products
from shell.charts import component_labels, resolve_signal
from shell.log_file import LogIncompleteWarning, log_info, read_log
from shell.models.multibody import MultibodyModel
from shell.models.reaction_wheel import ReactionWheel
from shell.models.thruster import Thruster
from shell.scenario import build_root, build_simulation, load_scenario, parse_scenario

G0 = 9.80665
#: frames kept by default: 10 Hz over 10 minutes
DEFAULT_MAX_FRAMES = 6000
#: samples of a signal in the panel (each signal decimated to at most this many)
PANEL_POINTS = 4000


class ViewError(ValueError):
    """Input that cannot be viewed; the message names the file and what to do."""


@dataclass
class ViewBody:
    name: str
    kind: str                                  # "box", "mesh", "flexible"
    position: np.ndarray                       # (F, 3) body origin, world [m]
    quaternion: np.ndarray                     # (F, 4) [x, y, z, w] body -> world
    box: np.ndarray | None = None              # (3,) edge lengths along the principal axes [m]
    box_center: np.ndarray | None = None       # (3,) centre of mass, body frame
    box_quaternion: np.ndarray | None = None   # (4,) principal axes -> body
    vertices: np.ndarray | None = None         # (V, 3) mesh or FE grids, body frame
    faces: np.ndarray | None = None            # (T, 3) triangles (int)
    edges: np.ndarray | None = None            # (E, 2) lines (int)
    shapes: np.ndarray | None = None           # (n, V*3) translation mode shapes (flexible)
    eta: np.ndarray | None = None              # (F, n) modal coordinates (flexible)
    mode_frequencies_hz: np.ndarray | None = None
    max_deformation: float = 0.0               # largest |sum eta gamma| over frames and grids [m]


@dataclass
class ViewScene:
    title: str
    source: str
    time: np.ndarray                           # (F,) s
    bodies: list
    nodes: list = field(default_factory=list)      # dicts: name, body, position (F,3), quaternion (F,4)
    wheels: list = field(default_factory=list)     # dicts: name, node, axis (3,), angle (F,), speed (F,) | None
    thrusters: list = field(default_factory=list)  # dicts: name, node, position, direction, level (F,) | None
    signals: list = field(default_factory=list)    # dicts: name, unit, labels, time, values (k, m)
    notes: list = field(default_factory=list)
    length: float = 1.0                        # size of the scene [m]
    deformation_scale: float = 1.0
    loop: bool = False                         # a mode shape: play in a loop
    track_body: int = 0                        # the body whose path is drawn (root of the tree)
    center: np.ndarray = field(default_factory=lambda: np.zeros(3))  # of the first frame, from the track body


# -- the scene's models ------------------------------------------------------------------------------

def _engine_of(models):

    engines = [m for m in models if isinstance(m, MultibodyModel)]
    if not engines:
        raise ViewError("the scene has no multibody: section, nothing to draw")
    return engines[0]


def _build(scenario):
    """(engine model, models, connections) of a validated scenario, without a simulation."""
    root = build_root(scenario)
    models, connections = flatten(root)
    return _engine_of(models), models, connections


def _device_nodes(engine, models, connections) -> dict:
    """model path -> the engine node it acts on or reads (through load sums, at most 4 hops)."""
    node_names = set(engine.system.node_names)

    def node_of(port):
        head = port.rsplit(".", 1)[0]
        return head if head in node_names else None

    out = {}
    downstream = {}
    for c in connections:
        if c.source_model is engine and c.destination_model is not engine:
            node = node_of(c.source_port)
            if node:
                out.setdefault(c.destination_model.path, node)
        downstream.setdefault(c.source_model.path, []).append(c)
    for m in models:
        if m.path in out:
            continue
        frontier, seen = [m.path], set()
        for _ in range(4):
            nxt = []
            for path in frontier:
                for c in downstream.get(path, []):
                    if c.destination_model is engine:
                        node = node_of(c.destination_port)
                        if node:
                            out[m.path] = node
                            break
                    elif c.destination_model.path not in seen:
                        seen.add(c.destination_model.path)
                        nxt.append(c.destination_model.path)
                if m.path in out:
                    break
            if m.path in out or not nxt:
                break
            frontier = nxt
    return out


# -- geometry ------------------------------------------------------------------------------------------

def inertia_box(mass: float, inertia) -> tuple[np.ndarray, np.ndarray]:
    """(edge lengths (3,), principal axes R (3, 3), columns) of the homogeneous box with ``mass`` and the
    principal moments of ``inertia`` (about the centre of mass): ``a_i^2 = 6 (I_j + I_k - I_i) / m``."""
    J = 0.5 * (np.asarray(inertia, float) + np.asarray(inertia, float).T)
    moments, axes = np.linalg.eigh(J)
    if np.linalg.det(axes) < 0:
        axes[:, 2] = -axes[:, 2]
    if mass <= 0 or not np.all(np.isfinite(moments)):
        return np.zeros(3), axes
    squares = 6.0 * (moments.sum() - 2.0 * moments) / mass
    return np.sqrt(np.clip(squares, 0.0, None)), axes


def _quat_xyzw(R) -> np.ndarray:

    return Rotation.from_matrix(R).as_quat()


# element kinds: how to draw each (lines between consecutive corner grids, or faces)
_LINES = {"CBAR", "CBEAM", "CROD", "CONROD", "CTUBE", "CBUSH", "CELAS1", "CELAS2", "CDAMP1", "CDAMP2", "CGAP",
          "CVISC", "CBUSH1D"}
_SHELLS = {"CQUAD4": 4, "CQUAD8": 4, "CQUADR": 4, "CTRIA3": 3, "CTRIA6": 3, "CTRIAR": 3, "CSHEAR": 4}
_SOLID_FACES = {
    "CTETRA": [(0, 1, 2), (0, 1, 3), (1, 2, 3), (0, 2, 3)],
    "CPENTA": [(0, 1, 2), (3, 4, 5), (0, 1, 4, 3), (1, 2, 5, 4), (0, 2, 5, 3)],
    "CHEXA": [(0, 1, 2, 3), (4, 5, 6, 7), (0, 1, 5, 4), (1, 2, 6, 5), (2, 3, 7, 6), (0, 3, 7, 4)],
}
_RIGID = {"RBE2", "RBE3", "RBAR", "RROD"}


def element_drawing(types, grids, grid_ids) -> tuple[np.ndarray, np.ndarray, list[str]]:
    """(edges (E, 2), triangles (T, 3)) as rows into ``grid_ids`` for elements of ``types`` (NASTRAN card
    names) with corner grids ``grids`` (rows padded with 0), and the element types not drawn."""
    row = {int(g): i for i, g in enumerate(grid_ids)}
    edges, triangles, skipped = set(), [], set()
    for kind, corners in zip(types, grids):
        ids = [row.get(int(g)) for g in corners if int(g) > 0]
        if any(i is None for i in ids) or len(ids) < 2:
            skipped.add(kind)
            continue
        if kind in _LINES:
            edges.add(tuple(sorted(ids[:2])))
        elif kind in _RIGID:  # a star from the first (independent or reference) grid
            for i in ids[1:]:
                edges.add(tuple(sorted((ids[0], i))))
        elif kind in _SHELLS:
            polygon = ids[:_SHELLS[kind]]
            faces = [polygon]
        elif kind in _SOLID_FACES:
            faces = [[ids[k] for k in face] for face in _SOLID_FACES[kind] if max(face) < len(ids)]
        else:
            skipped.add(kind)
            continue
        if kind in _SHELLS or kind in _SOLID_FACES:
            for polygon in faces:
                for a in range(len(polygon)):
                    edges.add(tuple(sorted((polygon[a], polygon[(a + 1) % len(polygon)]))))
                for a in range(1, len(polygon) - 1):
                    triangles.append((polygon[0], polygon[a], polygon[a + 1]))
    return (np.array(sorted(edges), dtype=np.int32).reshape(-1, 2),
            np.array(triangles, dtype=np.int32).reshape(-1, 3), sorted(skipped))


def _deck_elements(deck: Path):
    """(types, grids) of the structural and rigid elements of a NASTRAN deck (pyNastran)."""
    from dynamics.flex.body_file import elements_of_deck
    from dynamics.flex.bulk_data import read_bulk_data

    return elements_of_deck(read_bulk_data(str(deck), allow_unsupported=True).model)


def _find_deck(source: str, body_file: Path) -> Path | None:
    """The deck a body file was made from: its ``SOURCE`` as written, else the longest tail of that path
    found from the current directory or from a directory above the body file."""
    path = Path(source)
    if path.is_file():
        return path
    parts = path.parts
    bases = [Path.cwd()] + list(body_file.resolve().parents)
    for k in range(1, len(parts)):
        tail = Path(*parts[k:])
        for base in bases:
            if (base / tail).is_file():
                return base / tail
    return None


def _flexible_geometry(body_file: Path, flexible, notes: list):
    """(grid positions, edges, triangles) of a flexible body: the grids its FlexibleBodyData keeps, the
    elements of its body file (or of its deck)."""
    from dynamics.flex.body_file import read_body_geometry

    grid_ids = np.asarray(flexible.grid_ids)
    types, grids, source = read_body_geometry(body_file)
    where = f"{body_file}"
    if types is None:
        deck = _find_deck(source, body_file)
        if deck is None:
            notes.append(f"{where}: no element geometry in the body file (made before it kept one) and its deck "
                         f"{source!r} not found: the body is drawn as its grids only (re-run flexshell fem2modal)")
            return np.zeros((0, 2), np.int32), np.zeros((0, 3), np.int32)
        types, grids = _deck_elements(deck)
        notes.append(f"{where}: elements read from its deck {deck} (the body file predates element geometry)")
    edges, triangles, skipped = element_drawing(types, grids, grid_ids)
    if skipped:
        notes.append(f"{where}: element types not drawn: {', '.join(skipped)}")
    return edges, triangles


def _mesh(path: str, name: str):
    try:
        import trimesh
    except ImportError:
        raise ViewError(f"--mesh {name}={path}: drawing a user mesh needs trimesh (pip install trimesh)") from None
    try:
        mesh = trimesh.load(path, force="mesh")
    except Exception as exc:  # trimesh raises many kinds for unreadable files
        raise ViewError(f"--mesh {name}={path}: cannot read the mesh ({exc})") from None
    if len(mesh.faces) == 0:
        raise ViewError(f"--mesh {name}={path}: the mesh has no faces")
    return np.asarray(mesh.vertices, float), np.asarray(mesh.faces, np.int32)


def _bodies_geometry(engine, scenario_file: str, meshes: dict, notes: list) -> list[dict]:
    """Per body: what to draw, in its body frame (see the module docstring)."""
    system = engine.system
    definitions = system.definitions[0]
    unknown = sorted(set(meshes) - set(system.body_names))
    if unknown:
        raise ViewError(f"--mesh: no body {', '.join(unknown)}; bodies: {list(system.body_names)}")
    files = _body_files(engine, scenario_file)
    out = []
    for b, definition in enumerate(definitions):
        name = definition.name
        item = {"name": name}
        if definition.flexible is not None:
            flexible = definition.flexible
            item["kind"] = "flexible"
            item["vertices"] = np.asarray(flexible.grid_positions, float)
            translation = np.asarray(flexible.grid_shapes, float)[:, 3:6, :]  # (G, 3, n) gamma
            item["shapes"] = np.ascontiguousarray(np.transpose(translation, (2, 0, 1)).reshape(flexible.n_modes, -1))
            item["frequencies"] = np.asarray(flexible.frequencies_hz, float)
            if name in files:
                item["edges"], item["faces"] = _flexible_geometry(files[name], flexible, notes)
            else:
                item["edges"], item["faces"] = np.zeros((0, 2), np.int32), np.zeros((0, 3), np.int32)
        elif name in meshes:
            item["kind"] = "mesh"
            item["vertices"], item["faces"] = _mesh(meshes[name], name)
        else:
            item["kind"] = "box"
            edges, axes = inertia_box(float(definition.mass), definition.inertia)
            item["box"] = edges
            item["box_center"] = np.asarray(definition.com, float)
            item["box_quaternion"] = _quat_xyzw(axes)
        out.append(item)
    return out


def _body_files(engine, scenario_file: str) -> dict:
    """body name -> its body file (the scenario's ``body_file:``, relative to the scenario)."""
    description = getattr(engine, "description", None)
    out = {}
    if description is None:
        return out
    for body in description.get("bodies", []) or []:
        if isinstance(body, dict) and "body_file" in body:
            path = Path(str(body["body_file"]))
            if not path.is_absolute():
                path = Path(scenario_file).parent / path
            out[str(body.get("name"))] = path
    return out


# -- motion ------------------------------------------------------------------------------------------

def _poses(system, q_frames: np.ndarray):
    """(body positions (F, nb, 3), body quaternions (F, nb, 4), node positions (F, nn, 3), node
    quaternions (F, nn, 4)) for each row of ``q_frames``."""

    F = len(q_frames)
    nb, nn = system.nbodies, system.nnodes
    body_pos, body_rot = np.empty((F, nb, 3)), np.empty((F, nb, 3, 3))
    node_pos, node_rot = np.empty((F, nn, 3)), np.empty((F, nn, 3, 3))
    zero_u = np.zeros(system.nu)
    for f, q in enumerate(q_frames):
        body_rot[f], body_pos[f] = system.body_poses(q)
        if nn:
            kin = system.node_kinematics(q, zero_u)
            node_rot[f], node_pos[f] = kin.rotation, kin.position
    body_quat = Rotation.from_matrix(body_rot.reshape(-1, 3, 3)).as_quat().reshape(F, nb, 4)
    node_quat = Rotation.from_matrix(node_rot.reshape(-1, 3, 3)).as_quat().reshape(F, nn, 4) if nn else \
        np.zeros((F, 0, 4))
    return body_pos, body_quat, node_pos, node_quat


def _eta(system, q_frames: np.ndarray, b: int) -> np.ndarray:
    """Modal coordinates of body ``b`` per frame (its q slice after the hinge coordinates)."""
    sl = system.q_slices[b]
    start = sl.start + int(HINGE_NQ[HINGE_TYPES[system.hinge_names[b]]])
    return q_frames[:, start:sl.stop]


def _max_deformation(shapes: np.ndarray, eta: np.ndarray) -> float:
    """max over frames and grids of |sum_k eta_k gamma_k| (frames in blocks: no F x 3G array)."""
    worst = 0.0
    for start in range(0, len(eta), 256):
        d = (eta[start:start + 256] @ shapes).reshape(-1, shapes.shape[1] // 3, 3)
        if d.size:
            worst = max(worst, float(np.sqrt((d * d).sum(axis=2)).max()))
    return worst


def nice_scale(value: float) -> float:
    """The largest of 1, 2, 5 x 10^k not above ``value`` (at least 1)."""
    if not value > 1.0 or not math.isfinite(value):
        return 1.0
    k = math.floor(math.log10(value))
    for m in (5.0, 2.0, 1.0):
        if m * 10 ** k <= value:
            return m * 10 ** k
    return 10.0 ** k


def _assemble(engine, scenario_file, meshes, time, q_frames, notes, title, source, scale,
              loop=False) -> ViewScene:
    """The ViewScene of the engine's bodies at ``q_frames`` (F, nq)."""
    system = engine.system
    geometry = _bodies_geometry(engine, scenario_file, meshes, notes)
    body_pos, body_quat, node_pos, node_quat = _poses(system, q_frames)
    bodies = []
    extent = [np.ptp(node_pos[0], axis=0).max() if system.nnodes else 0.0]
    for b, item in enumerate(geometry):
        body = ViewBody(item["name"], item["kind"], body_pos[:, b], body_quat[:, b].astype(np.float32),
                        box=item.get("box"), box_center=item.get("box_center"),
                        box_quaternion=item.get("box_quaternion"), vertices=item.get("vertices"),
                        faces=item.get("faces"), edges=item.get("edges"), shapes=item.get("shapes"),
                        mode_frequencies_hz=item.get("frequencies"))
        if body.kind == "flexible":
            body.eta = _eta(system, q_frames, b)
            body.max_deformation = _max_deformation(body.shapes, body.eta)
        if body.vertices is not None and len(body.vertices):
            extent.append(float(np.ptp(body.vertices, axis=0).max()))
        if body.box is not None:
            extent.append(float(body.box.max()))
        bodies.append(body)
    length = max([e for e in extent if np.isfinite(e)] + [0.0]) or 1.0
    for body in bodies:  # bodies too small to see (a massless frame, a point mass) get a marker size
        if body.kind == "box" and body.box.max() < 0.02 * length:
            body.box = np.maximum(body.box, 0.02 * length)
    nodes = [{"name": name, "body": system.node_bodies[k], "position": node_pos[:, k],
              "quaternion": node_quat[:, k].astype(np.float32), "hinge": False}
             for k, name in enumerate(system.node_names)]

    for b, definition in enumerate(system.definitions[0]):  # hinge frames: the outboard frame M of each hinge
        if system.parents[b] < 0:
            continue
        R = Rotation.from_quat(body_quat[:, b])
        M = R * Rotation.from_matrix(definition.outboard_rotation)
        nodes.append({"name": f"hinge of {definition.name}", "body": definition.name,
                      "position": body_pos[:, b] + R.apply(definition.outboard_position),
                      "quaternion": M.as_quat().astype(np.float32), "hinge": True})
    roots = [b for b, p in enumerate(system.parents) if p < 0]
    points = [body_pos[0]] + ([node_pos[0]] if system.nnodes else [])
    corners = np.array([[x, y, z] for x in (-0.5, 0.5) for y in (-0.5, 0.5) for z in (-0.5, 0.5)])
    for b, body in enumerate(bodies):
        local = body.vertices
        if body.kind == "box":
            local = body.box_center + Rotation.from_quat(body.box_quaternion).apply(corners * body.box)
        if local is not None and len(local):
            points.append(body_pos[0, b] + Rotation.from_quat(body_quat[0, b]).apply(local))
    points = np.vstack(points)
    length = max(length, float(np.ptp(points, axis=0).max()))
    deformation = max((b.max_deformation for b in bodies), default=0.0)
    if scale == "auto":
        factor = nice_scale(0.08 * length / deformation) if deformation > 0 else 1.0
    else:
        factor = float(scale)
    if deformation > 0:
        notes.append(f"largest elastic displacement {deformation:.3g} m, drawn x{factor:g} "
                     f"({factor * deformation:.3g} m on a scene of {length:.3g} m)")
    track = roots[0] if roots else 0
    center = 0.5 * (points.min(axis=0) + points.max(axis=0)) - body_pos[0, track]
    return ViewScene(title=title, source=source, time=np.asarray(time, float), bodies=bodies, nodes=nodes,
                     notes=notes, length=float(length), deformation_scale=factor, loop=loop,
                     track_body=track, center=center)


# -- from a log -----------------------------------------------------------------------------------------

def _frames(n: int, max_frames: int) -> np.ndarray:
    stride = max(1, math.ceil(n / max_frames))
    return np.arange(0, n, stride)


def _coordinate_frames(engine, data: dict, info: dict, notes: list, max_frames: int):
    """(time (F,), q (F, nq)) from the log: ``<engine>.q``, else the per-body ports, else the initial q."""
    system = engine.system
    signals = info["signals"]
    q_name = f"{engine.path}.q"
    if q_name in data:
        time = data[signals[q_name]["time"]]
        keep = _frames(len(time), max_frames)
        if len(keep) < len(time):
            notes.append(f"{len(time)} logged samples of {q_name}, {len(keep)} frames drawn (every "
                         f"{keep[1] - keep[0]}th; --max-frames)")
        q = data[q_name].reshape(len(time), -1)[keep]
        return time[keep], q
    pieces = [(f"{engine.path}.{port}", start, count) for port, start, count in engine._coordinate_ports["q"]]
    logged = [p for p in pieces if p[0] in data]
    initial = np.asarray(engine._initial_q, float)
    from_nodes = _root_bodies_from_nodes(engine, data, {p[0] for p in logged})
    timed = [signals[p[0]]["time"] for p in logged] + [signals[f"{engine.path}.{n}.attitude"]["time"]
                                                      for _, n in from_nodes]
    if not timed:
        notes.append(f"the log has no coordinates of the multibody engine ({q_name}, {engine.path}.<body>.q, or "
                     "a node attitude of a free body): the scene is drawn at its initial configuration; add "
                     f"{q_name} to the log's signals to see it move")
        groups = sorted({meta["time"] for meta in signals.values()})
        time = data[groups[0]] if groups else np.zeros(1)
        keep = _frames(len(time), max_frames)
        return time[keep], np.tile(initial, (len(keep), 1))
    time_full = data[max(timed, key=lambda name: len(data[name]))]
    keep = _frames(len(time_full), max_frames)
    time = time_full[keep]
    q = np.tile(initial, (len(time), 1))
    for name, start, count in logged:
        t = data[signals[name]["time"]]
        values = data[name].reshape(len(t), -1)
        for k in range(count):
            q[:, start + k] = np.interp(time, t, values[:, k])
    derived = set()
    for b, node in from_nodes:
        _hinge_from_node(engine, b, node, data, signals, time, q)
        derived.add(f"{engine.path}.{system.body_names[b]}.q")
        notes.append(f"the pose of {system.body_names[b]} is derived from the logged {engine.path}.{node}.attitude"
                     + (f" and .position" if f"{engine.path}.{node}.position" in data else
                        " (its position is held: log the node's position or the body's coordinates)"))
    for k in system.quaternion_q_indices:
        q[:, k:k + 4] /= np.linalg.norm(q[:, k:k + 4], axis=1, keepdims=True)
    missing = [p[0] for p in pieces if p[0] not in data and p[0] not in derived]
    if missing:
        notes.append(f"not logged: {', '.join(missing)}: held at their initial values (log {q_name} to see "
                     "every body move)")
    return time, q


def _root_bodies_from_nodes(engine, data: dict, logged: set) -> list[tuple[int, str]]:
    """(body, node) for each rigid body on a free or spherical hinge to the world whose hinge coordinates
    are not logged but a node's attitude on it is (a node with a logged position preferred)."""
    system = engine.system
    out = []
    for b, body in enumerate(system.body_names):
        if (system.parents[b] >= 0 or system.hinge_names[b] not in ("free", "spherical") or system.n_modes[b]
                or f"{engine.path}.{body}.q" in logged):
            continue
        candidates = [n for k, n in enumerate(system.node_names) if system.node_bodies[k] == body
                      and f"{engine.path}.{n}.attitude" in data]
        candidates.sort(key=lambda n: f"{engine.path}.{n}.position" not in data)
        if candidates:
            out.append((b, candidates[0]))
    return out


def _hinge_from_node(engine, b: int, node: str, data: dict, signals: dict, time, q) -> None:
    """Fill the hinge coordinates of root body ``b`` from its node's logged attitude (and position):
    ``R_body = R_node R_n^T``, ``p_body = p_node - R_body p_n`` (node frame (R_n, p_n) in the body), then
    the hinge's ``R_FM = R_in^T R_body R_out``, ``p_FM = R_in^T (p_body + R_body p_out - p_in)`` (inboard
    frame F on the world, outboard frame M on the body: docs/conventions.md, free hinge = quaternion of M in F,
    then the position of M's origin in F)."""

    system = engine.system
    definition = system.definitions[0][b]
    k = system.node_names.index(node)
    R_n, p_n = system.node_rot[k], system.node_pos[k]
    name = f"{engine.path}.{node}.attitude"
    t = data[signals[name]["time"]]
    wxyz = data[name].reshape(len(t), 4)
    wxyz = np.stack([np.interp(time, t, wxyz[:, a]) for a in range(4)], axis=1)
    R_node = Rotation.from_quat(wxyz[:, [1, 2, 3, 0]]).as_matrix()
    R_body = R_node @ R_n.T
    R_in, p_in = definition.inboard_rotation, definition.inboard_position
    R_out, p_out = definition.outboard_rotation, definition.outboard_position
    R_fm = R_in.T @ R_body @ R_out
    xyzw = Rotation.from_matrix(R_fm).as_quat()
    start = system.q_slices[b].start
    q[:, start:start + 4] = xyzw[:, [3, 0, 1, 2]]
    position = f"{engine.path}.{node}.position"
    if system.hinge_names[b] == "free" and position in data:
        tp = data[signals[position]["time"]]
        p_node = np.stack([np.interp(time, tp, data[position].reshape(len(tp), 3)[:, a]) for a in range(3)], 1)
        p_body = p_node - R_body @ p_n
        q[:, start + 4:start + 7] = (R_in.T @ (p_body + R_body @ p_out - p_in)[..., None])[..., 0]


def _resample(t_from, values, t_to, hold=False):
    if len(t_from) == 0:
        return np.zeros(len(t_to))
    if hold:
        index = np.clip(np.searchsorted(t_from, t_to, side="right") - 1, 0, len(t_from) - 1)
        return values[index]
    return np.interp(t_to, t_from, values)


def _devices(engine, models, connections, data, info, time, notes) -> tuple[list, list]:

    signals = info["signals"]
    nodes = _device_nodes(engine, models, connections)
    node_index = {n: k for k, n in enumerate(engine.system.node_names)}
    wheels, thrusters = [], []
    for m in models:
        if isinstance(m, ReactionWheel) and m.path in nodes:
            speed_name = f"{m.path}.wheel_speed"
            angle = speed = None
            if speed_name in data:
                t = data[signals[speed_name]["time"]]
                w = data[speed_name].reshape(len(t))
                full = np.concatenate(([0.0], np.cumsum(0.5 * (w[1:] + w[:-1]) * np.diff(t))))
                angle, speed = _resample(t, full, time), _resample(t, w, time)
            else:
                notes.append(f"{speed_name} not logged: the wheel {m.path} is drawn without its spin")
            wheels.append({"name": m.path, "node": node_index[nodes[m.path]],
                           "axis": np.asarray(m.parameter("spin_axis"), float), "angle": angle, "speed": speed})
        elif isinstance(m, Thruster) and m.path in nodes:
            level = None
            max_thrust = float(m.parameter("max_thrust"))
            thrust_name, used_name = f"{m.path}.thrust", f"{m.path}.propellant_used"
            if thrust_name in data:
                t = data[signals[thrust_name]["time"]]
                level = _resample(t, data[thrust_name].reshape(len(t)), time, hold=True) / max_thrust
            elif used_name in data:
                t = data[signals[used_name]["time"]]
                used = data[used_name].reshape(len(t))
                if len(t) > 1:
                    rate = np.diff(used) / np.diff(t) * float(m.parameter("isp")) * G0 / max_thrust
                    # the mean thrust over each log interval, held over it
                    level = _resample(t[:-1], rate, time, hold=True)
            thrusters.append({"name": m.path, "node": node_index[nodes[m.path]],
                              "position": np.asarray(m.parameter("position"), float),
                              "direction": np.asarray(m.parameter("direction"), float),
                              "level": None if level is None else np.clip(level, 0.0, 1.0)})
    silent = [t["name"] for t in thrusters if t["level"] is None]
    if silent:
        notes.append(f"{len(silent)} thrusters without a logged thrust or propellant_used ({silent[0]}, ...): drawn "
                     "without their plume")
    return wheels, thrusters


def _extend_length(view: ViewScene) -> None:
    """Grow the scene size to the node frames and the thrusters around them (first frame)."""
    points = [n["position"][0] for n in view.nodes]
    for t in view.thrusters:
        points.append(view.nodes[t["node"]]["position"][0] + t["position"])
    if len(points) > 1:
        view.length = max(view.length, float(np.ptp(np.array(points), axis=0).max()))


def _panel(data, info, requested, engine_path) -> list[dict]:
    signals = info["signals"]
    available = list(signals)
    if requested is None:  # small signals first, the engine's coordinate vectors last
        small = [n for n in available if int(np.prod(signals[n]["shape"][1:])) <= 4]
        requested = [n for n in small if not n.startswith(engine_path + ".")][:2] + \
                    [n for n in small if n.startswith(engine_path + ".")][:1]
        requested = requested or available[:1]
    out = []
    for request in requested:
        name = resolve_signal(request, available, ViewError)
        meta = signals[name]
        t = data[meta["time"]]
        values = data[name].reshape(len(t), -1)
        keep = _frames(len(t), PANEL_POINTS)
        out.append({"name": name, "unit": meta.get("unit", ""), "labels": component_labels(name, meta["shape"][1:]),
                    "time": t[keep], "values": values[keep].T.astype(np.float32)})
    return out


def _scenario_of_log(path: str, info: dict, scenario_path: str | None, overrides):

    attributes = info["attributes"]
    text = attributes.get("scenario")
    file = scenario_path or attributes.get("scenario_file") or "<log>"
    if scenario_path:
        return load_scenario(scenario_path, overrides)
    if not text:
        raise ViewError(f"{path}: the log keeps no scenario (written from Python, not flexshell run); give it "
                        "with --scenario SCENE.yaml")
    if not Path(file).exists():
        warnings.warn(f"{path}: its scenario file {file!r} is not found from here: body files are looked up "
                      "relative to it; pass --scenario to say where it is", stacklevel=2)
    return parse_scenario(text, file, list(overrides or []))


def from_log(path, *, signals=None, scenario=None, overrides=(), meshes=None, scale="auto",
             max_frames: int = DEFAULT_MAX_FRAMES) -> ViewScene:
    """The scene of a log (see the module docstring)."""
    notes: list[str] = []
    info = log_info(path)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", LogIncompleteWarning)
        data = read_log(path)
    notes.extend(str(w.message) for w in caught)
    notes.extend(f"event {e['event']} at t = {e['time']:.9g} s: {e['changes']}"  # events: on: (shell.scene_events)
                 for e in json.loads(info["attributes"].get("scene_events", "[]")))
    spec = _scenario_of_log(str(path), info, scenario, overrides)
    engine, models, connections = _build(spec)
    engine.description = spec.document.get("multibody")
    time, q = _coordinate_frames(engine, data, info, notes, max_frames)
    finite = np.all(np.isfinite(q), axis=1)
    if not finite.all():  # a failed run's last samples
        if not finite.any():
            raise ViewError(f"{path}: every logged sample of the engine's coordinates is NaN or infinite")
        notes.append(f"{int((~finite).sum())} frames with non-finite coordinates left out (from t = "
                     f"{time[~finite][0]:.6g} s)")
        time, q = time[finite], q[finite]
    view = _assemble(engine, spec.file, meshes or {}, time, q, notes, f"{spec.name}: {Path(path).name}",
                     str(path), scale)
    view.wheels, view.thrusters = _devices(engine, models, connections, data, info, time, notes)
    _extend_length(view)
    view.signals = _panel(data, info, signals, engine.path)
    return view


# -- from a scenario ------------------------------------------------------------------------------------

def from_scenario(path, *, overrides=(), meshes=None, scale="auto", t_final=None, rate=None, signals=None,
                  max_frames: int = DEFAULT_MAX_FRAMES, say=None) -> ViewScene:
    """A scenario's initial configuration, or (``t_final`` seconds) a short run of it viewed as its log;
    ``say(text)`` announces the run (its first time compiles the loop for minutes)."""

    spec = load_scenario(path, list(overrides or []))
    if t_final is None:
        engine, models, connections = _build(spec)
        engine.description = spec.document.get("multibody")
        q = np.asarray(engine._initial_q, float)[None, :]
        notes = ["initial configuration (view a run with --t-final, or view its log)"]
        view = _assemble(engine, spec.file, meshes or {}, np.zeros(1), q, notes, f"{spec.name}: initial",
                         str(path), scale)
        view.wheels, view.thrusters = _devices(engine, models, connections, {}, {"signals": {}}, view.time, [])
        _extend_length(view)
        return view
    simulation = build_simulation(spec)
    engine = _engine_of(simulation.models)
    view_rate = rate or spec.log_rate or "10 Hz"

    # what the view draws: the engine's coordinates, the wheels' speeds, the thrusters' thrust
    simulation.log([f"{engine.path}.q"] + [f"{m.path}.wheel_speed" for m in simulation.models
                                           if isinstance(m, ReactionWheel)]
                   + [f"{m.path}.thrust" for m in simulation.models if isinstance(m, Thruster)], view_rate)
    if say is not None:
        say(f"{spec.name}: running {t_final:g} s to view it (logging {engine.path}.q, wheel speeds and thrusts at "
            f"{view_rate}; a first run "
            "compiles the simulation loop, which takes minutes)")
    with tempfile.TemporaryDirectory(prefix="flexshell-view-") as tmp:
        log_path = Path(tmp) / "view.h5"
        simulation.run(float(t_final), log_path=str(log_path),
                       log_attributes={"scenario": spec.text, "scenario_file": str(path)})
        view = from_log(log_path, signals=signals, scenario=str(path), overrides=overrides, meshes=meshes,
                        scale=scale, max_frames=max_frames)
    view.title, view.source = f"{spec.name}: run of {t_final:g} s", str(path)
    return view


# -- from a linear model --------------------------------------------------------------------------------

_PLAIN = re.compile(r"^(?P<label>.+)\[(?P<k>\d+)\]$")
_ROTATION = re.compile(r"^(?P<label>.+)\[(?P<k>\d+):\d+\]\.rotation_vector\[(?P<axis>\d)\]$")


def _tangent_map(state_names: list[str], label: str):
    """Rows of the engine's coordinates among the linear model's tangent states: (row, q index) of plain
    coordinates and (first row, q index of w) of each hinge quaternion's rotation vector."""
    plain, quaternions = [], []
    for row, name in enumerate(state_names):
        rotation = _ROTATION.match(name)
        if rotation:
            if int(rotation["axis"]) == 0 and rotation["label"] == label:
                quaternions.append((row, int(rotation["k"])))
            continue
        plain_match = _PLAIN.match(name)
        if (plain_match and plain_match["label"] == label) or name == label:
            plain.append((row, int(plain_match["k"]) if plain_match else 0))
    return plain, quaternions


def _mode_frames(q0, v, plain, quaternions, amplitude, phases, closure=None):
    """Engine coordinates of the mode's frames; ``closure`` (:func:`_loop_closure`): the dependent coordinates of a
    linear model in minimal coordinates moved onto the closure constraints in every frame."""
    frames = np.tile(q0, (len(phases), 1))
    for f, phi in enumerate(phases):
        xi = amplitude * np.real(v * np.exp(1j * phi))
        for row, k in plain:
            frames[f, k] += xi[row]
        for row, k in quaternions:
            frames[f, k:k + 4] = quaternion_products(q0[k:k + 4], quaternion_exp(xi[row:row + 3]))
        if closure is not None:
            frames[f] = close_loops(closure[0], frames[f], closure[1])
    return frames


def _loop_closure(engine, plain, quaternions):
    """(ConstrainedSystem, dependent tangent coordinates in u's order) when the engine has closure constraints and the
    linear model's states are its minimal coordinates (some coordinates absent), else None."""
    constrained = getattr(engine, "constrained", None)
    if constrained is None or not len(constrained.jacobian(engine._initial_q)):
        return None
    system = constrained.system
    tangent = {}  # q index -> its tangent coordinates (u's order)
    for b, hinge in enumerate(system.hinge_names):
        qs, us = system.q_slices[b], system.u_slices[b]
        quaternion = hinge in ("spherical", "free")
        if quaternion:
            tangent[qs.start] = [us.start, us.start + 1, us.start + 2]
        for j in range(4 if quaternion else 0, qs.stop - qs.start):
            tangent[qs.start + j] = [us.start + j - (1 if quaternion else 0)]
    independent = {i for _, k in plain + quaternions for i in tangent[k]}
    dependent = np.array(sorted(set(range(system.nu)) - independent), dtype=np.int64)
    return (constrained, dependent) if dependent.size else None


def from_linear_model(path, mode: int, *, scenario=None, overrides=None, meshes=None, scale="auto",
                      frames: int = 48) -> ViewScene:
    """System mode ``mode`` (1 = the lowest-frequency oscillatory mode) of a linear model, animated over
    one period (see the module docstring)."""

    try:
        model = read_linear_model(path)
    except (OSError, KeyError) as exc:
        raise ViewError(f"{path}: not a readable linear-model file ({exc})") from None
    modes = state_space_modes(model.A)
    n = len(modes.frequencies_hz)
    if not 1 <= mode <= n:
        listing = ", ".join(f"{k + 1}: {f:.4g} Hz" for k, f in enumerate(modes.frequencies_hz[:12]))
        raise ViewError(f"{path}: --mode {mode}: the model has {n} oscillatory modes (K from 1 to {n}; {listing}"
                        f"{', ...' if n > 12 else ''})")
    scenario_file = scenario or model.metadata.get("scenario")
    if not scenario_file or not Path(str(scenario_file)).is_file():
        raise ViewError(f"{path}: its scenario {scenario_file!r} is not found from here; pass --scenario SCENE.yaml")
    if overrides is None:
        raw = model.metadata.get("overrides", "[]")
        overrides = json.loads(raw) if isinstance(raw, str) else list(raw)
    spec = load_scenario(str(scenario_file), list(overrides))
    engine, models, connections = _build(spec)
    engine.description = spec.document.get("multibody")
    plain, quaternions = _tangent_map(list(model.state_names), f"{engine.path}.q")
    if not plain and not quaternions:
        raise ViewError(f"{path}: none of its states are coordinates of {engine.path} (states "
                        f"{model.state_names[:6]}...): nothing to animate")
    x0 = np.asarray(model.operating_point["x"], float)
    q0 = np.asarray(engine._initial_q, float).copy()
    # the operating point's engine coordinates, by the x index of each tangent row (written by linearize; older
    # files: from the names, which then list every state)
    x_rows = model.operating_point.get("x_rows")
    x_index = [int(r) for r in x_rows] if x_rows is not None else _x_indices(list(model.state_names))
    for row, k in plain:
        q0[k] = x0[x_index[row]]
    for row, k in quaternions:
        q0[k:k + 4] = x0[x_index[row]:x_index[row] + 4]
    closure = _loop_closure(engine, plain, quaternions)
    if closure is not None:  # minimal coordinates: the dependent ones at the operating point, then each frame's
        row, k = (plain or quaternions)[0]
        start = x_index[row] - k
        q0 = x0[start:start + len(q0)].copy()
    v = modes.shapes[:, mode - 1]
    v = v * np.exp(-1j * np.angle(v[np.argmax(np.abs(v))]))  # the largest entry real: phase 0 is a peak
    frequency = float(modes.frequencies_hz[mode - 1])
    phases = np.linspace(0.0, 2.0 * np.pi, frames, endpoint=False)
    notes = [f"system mode {mode} of {n}: {frequency:.6g} Hz, damping ratio {modes.damping_ratios[mode - 1]:.3g} "
             f"(linear model {Path(path).name}, eigenvalue {modes.eigenvalues[mode - 1]:.6g})"]
    # amplitude: the probe's largest displacement (grids, nodes, body origins), scaled to 10 % of the scene
    probe = 1e-4 / max(float(np.abs(v).max()), 1e-300)
    trial = _assemble(engine, spec.file, meshes or {}, np.zeros(4), _mode_frames(
        q0, v, plain, quaternions, probe, phases[::max(1, frames // 4)][:4], closure), [], "", "", 1.0)
    reference = _assemble(engine, spec.file, meshes or {}, np.zeros(1), q0[None, :], [], "", "", 1.0)
    moved = _displacement(trial, reference)
    amplitude = probe * (0.1 * reference.length / moved) if scale == "auto" and moved > 0 else \
        probe * (float(scale) if scale != "auto" else 1.0) / 1e-4
    q_frames = _mode_frames(q0, v, plain, quaternions, amplitude, phases, closure)
    time = phases / (2.0 * np.pi * frequency) if frequency > 0 else phases
    view = _assemble(engine, spec.file, meshes or {}, time, q_frames, notes,
                     f"{spec.name}: system mode {mode}, {frequency:.4g} Hz", str(path), 1.0, loop=True)
    view.deformation_scale = 1.0
    view.notes = [n for n in view.notes if not n.startswith("largest elastic")] + \
        [f"mode amplitude chosen for display (eigenvector x {amplitude:.3g}); shapes are defined up to a factor"]
    return view


def _x_indices(state_names: list[str]) -> list[int]:
    """Index in the full state x of each tangent row (a quaternion's 3 rows: the index of its w; the
    tangent names follow x in order, 3 rows standing for a quaternion's 4 entries)."""
    out, cursor, start = [], 0, 0
    for name in state_names:
        rotation = _ROTATION.match(name)
        if rotation:
            if int(rotation["axis"]) == 0:
                start = cursor
                cursor += 4
            out.append(start)
            continue
        out.append(cursor)
        cursor += 1
    return out


def _displacement(trial: ViewScene, reference: ViewScene) -> float:
    """Largest displacement of node origins, body origins and flexible grids of ``trial`` from ``reference``."""
    worst = 0.0
    for a, b in zip(trial.bodies, reference.bodies):
        worst = max(worst, float(np.abs(a.position - b.position[0]).max()), a.max_deformation)
        if a.kind == "box":  # a rotation shows at the box's corners

            relative = Rotation.from_quat(a.quaternion) * Rotation.from_quat(b.quaternion[0]).inv()
            worst = max(worst, float(relative.magnitude().max()) * 0.5 * float(np.linalg.norm(a.box)))
    for a, b in zip(trial.nodes, reference.nodes):
        worst = max(worst, float(np.abs(a["position"] - b["position"][0]).max()))
    return worst
