"""flexshell view: the scene's geometry and poses against analytic values and the engine's own node
kinematics, the page's deformation (computed by the browser) against numpy, and the pages drawn in headless
Chromium (Debian package ``chromium``, installed by .ci/run): non-blank where the bodies are, and different
at two instants of a log in which only the flexible body deforms.

The log of these tests is written directly (LogWriter) with a prescribed motion of configs/lqr_plant.yaml
(a rigid bus on a revolute hinge carrying a cantilevered flexible array, configs/lqr_data/array.h5), so the
expected poses are known in closed form and no simulation runs.
"""

from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from shell.cli import main
from shell.log_file import LoggedSignal, LogWriter
from shell.view.scene import component_labels, element_drawing, from_log, inertia_box, nice_scale

REPO = Path(__file__).resolve().parents[2]
PLANT = REPO / "configs" / "lqr_plant.yaml"
BACKGROUND = np.array([0x1B, 0x1F, 0x27])
WINDOW = (1000, 640)
PANEL = 380  # px of the signal panel on the right
BAR = 44     # px of the control bar at the bottom


def chromium() -> str:
    path = shutil.which("chromium") or shutil.which("chromium-browser")
    assert path, "headless Chromium is needed (Debian: apt-get install chromium; .ci/run installs it)"
    return path


def _browser(html: Path, query: str, *extra: str, timeout: int = 120) -> subprocess.CompletedProcess:
    args = [chromium(), "--headless", "--no-sandbox", "--disable-gpu-sandbox", "--use-angle=swiftshader",
            "--enable-unsafe-swiftshader", "--hide-scrollbars", f"--window-size={WINDOW[0]},{WINDOW[1]}",
            "--virtual-time-budget=5000", *extra, html.resolve().as_uri() + query]
    return subprocess.run(args, capture_output=True, text=True, timeout=timeout,
                          env={**os.environ, "HOME": str(html.parent)})


def screenshot(html: Path, query: str, png: Path) -> np.ndarray:
    """The page as an (h, w, 3) uint8 array."""
    import matplotlib.image

    _browser(html, query, f"--screenshot={png}")
    assert png.is_file(), f"chromium wrote no screenshot of {html}"
    return (matplotlib.image.imread(png)[..., :3] * 255).round().astype(np.uint8)


def probe(html: Path, query: str) -> dict:
    """What the page computed (viewer.js writes it into <pre id=probe> with ?probe=1)."""
    out = _browser(html, query + "&probe=1", "--dump-dom").stdout
    match = re.search(r'<pre id="probe">(.*?)</pre>', out, re.S)
    assert match, f"no probe in the page's DOM ({out[:300]!r})"
    return json.loads(match.group(1).replace("&quot;", '"'))


def view_region(image: np.ndarray) -> np.ndarray:
    h, w, _ = image.shape
    return image[30:h - BAR, :w - PANEL]


def drawn_fraction(image: np.ndarray) -> float:
    region = view_region(image).astype(int)
    return float(np.mean(np.abs(region - BACKGROUND).sum(axis=2) > 30))


# -- geometry --------------------------------------------------------------------------------------------

def test_equivalent_inertia_box_has_the_bodys_inertia():
    """The box's own inertia, m/12 (b^2 + c^2) ... about its axes, rotated back, is the input (1e-12:
    an eigen-decomposition and square roots)."""
    rng = np.random.default_rng(3)
    for _ in range(20):
        m, edges = rng.uniform(1, 1000), rng.uniform(0.1, 5, 3)
        R, _ = np.linalg.qr(rng.normal(size=(3, 3)))
        a2 = edges ** 2
        J = R @ np.diag(m / 12 * np.array([a2[1] + a2[2], a2[0] + a2[2], a2[0] + a2[1]])) @ R.T
        found, axes = inertia_box(m, J)
        f2 = found ** 2
        back = axes @ np.diag(m / 12 * np.array([f2[1] + f2[2], f2[0] + f2[2], f2[0] + f2[1]])) @ axes.T
        assert np.allclose(back, J, rtol=0, atol=1e-12 * np.abs(J).max())
        assert np.allclose(sorted(found), sorted(edges), rtol=1e-10)
        assert np.linalg.det(axes) > 0


def test_element_drawing_of_bars_shells_solids_and_rigid_elements():
    ids = np.arange(1, 13)
    types = ["CBAR", "CQUAD4", "CTRIA3", "CHEXA", "RBE2", "CWELD"]
    grids = np.array([[1, 2, 0, 0, 0, 0, 0, 0], [1, 2, 3, 4, 0, 0, 0, 0], [1, 3, 5, 0, 0, 0, 0, 0],
                      [1, 2, 3, 4, 5, 6, 7, 8], [9, 10, 11, 12, 0, 0, 0, 0], [1, 2, 0, 0, 0, 0, 0, 0]])
    edges, triangles, skipped = element_drawing(types, grids, ids)
    assert skipped == ["CWELD"]
    assert len(triangles) == 2 + 1 + 12
    edge_set = {tuple(e) for e in edges.tolist()}
    assert (0, 1) in edge_set and (8, 9) in edge_set and (8, 11) in edge_set  # bar, RBE2 star
    hexa = {tuple(sorted((a - 1, b - 1))) for a, b in [(1, 2), (2, 3), (3, 4), (4, 1), (5, 6), (6, 7), (7, 8),
                                                         (8, 5), (1, 5), (2, 6), (3, 7), (4, 8)]}
    assert hexa <= edge_set
    assert edges.max() < len(ids) and triangles.max() < len(ids)


def test_body_file_keeps_element_geometry_and_reads_old_files(tmp_path):
    from dynamics.flex.body_file import read_body_file, read_body_geometry, write_body_file

    old = REPO / "configs" / "lqr_data" / "array.h5"
    types, grids, source = read_body_geometry(old)  # written before the Geometry group existed
    assert types is None and source.endswith("cantilever_array.dat")
    body = read_body_file(old)
    assert body.element_types == [] and body.element_grids.size == 0
    body.element_types, body.element_grids = ["CBAR", "CQUAD4"], np.array([[1, 2, 0, 0], [1, 2, 3, 4]])
    write_body_file(tmp_path / "new.h5", body)
    again = read_body_file(tmp_path / "new.h5")
    assert again.element_types == ["CBAR", "CQUAD4"]
    assert np.array_equal(again.element_grids, body.element_grids)
    assert np.array_equal(again.translation_shapes, body.translation_shapes)


def test_labels_and_scale():
    assert component_labels("multibody.acs.attitude", (4,)) == ["w", "x", "y", "z"]
    assert component_labels("imu.angular_rate", (3,)) == ["x", "y", "z"]
    assert component_labels("wheels.rw1.wheel_speed", ()) == ["wheel_speed"]
    assert [nice_scale(v) for v in (0.3, 1.0, 7.3, 49.0, 2.0e4)] == [1.0, 1.0, 5.0, 20.0, 2.0e4]


# -- a log with a prescribed motion ------------------------------------------------------------------------

MODE_FREQUENCY = 0.5  # Hz, of the prescribed modal motion
AMPLITUDE = 0.05      # of eta_0 and eta_1


def write_plant_log(path: Path, turning: bool) -> tuple[np.ndarray, np.ndarray]:
    """A log of configs/lqr_plant.yaml: bus angle 0.2 t (if ``turning``, else 5 deg held), eta_0, eta_1
    oscillating. Returns (time, q)."""
    t = np.arange(0.0, 4.0 + 1e-9, 0.1)
    q = np.zeros((len(t), 7))
    q[:, 0] = 0.2 * t if turning else np.radians(5.0)
    q[:, 1] = AMPLITUDE * np.sin(2 * np.pi * MODE_FREQUENCY * t)
    q[:, 2] = -0.5 * AMPLITUDE * np.cos(2 * np.pi * MODE_FREQUENCY * t)
    writer = LogWriter(path, {"every_0.1s": [LoggedSignal("multibody.q", (7,), "", "generalized coordinates"),
                                             LoggedSignal("multibody.bus.q", (1,), "rad", "hinge angle")]},
                       {"scenario": PLANT.read_text(), "scenario_file": str(PLANT)})
    writer.append_rows("every_0.1s", t, np.hstack([q, q[:, :1]]))
    writer.close()
    return t, q


@pytest.fixture(scope="module")
def plant_log(tmp_path_factory):
    path = tmp_path_factory.mktemp("view") / "plant.h5"
    return (path, *write_plant_log(path, turning=True))


def test_log_poses_against_closed_form_and_engine_node_kinematics(plant_log):
    """Bus: rotation by the logged angle about z; array: at the array_root node (1, 0, 0) of the bus.
    The page's deformation formula, body pose (l0 + sum eta gamma), reproduces the engine's own node
    kinematics at the array tip (grid 21) to round-off: the view draws what the engine computes."""
    path, t, q = plant_log
    view = from_log(path)
    assert len(view.time) == len(t)
    bus, array = view.bodies
    assert (bus.kind, array.kind) == ("box", "flexible")
    angle = q[:, 0]
    expected = np.stack([np.zeros_like(angle), np.zeros_like(angle), np.sin(angle / 2), np.cos(angle / 2)], 1)
    assert np.allclose(bus.quaternion, expected, atol=2e-7)  # stored as float32
    assert np.allclose(array.position, np.stack([np.cos(angle), np.sin(angle), 0 * angle], 1), atol=1e-12)
    assert np.array_equal(array.eta, q[:, 1:])
    assert len(array.edges) >= 20  # the 20 CBARs of the deck (array.h5 predates element geometry)
    from scipy.spatial.transform import Rotation

    tip = view.nodes[[n["name"] for n in view.nodes].index("array_tip")]
    grid = array.vertices[-1]  # grid 21, the last
    shapes = array.shapes.reshape(array.shapes.shape[0], -1, 3)[:, -1, :]
    for f in range(0, len(t), 7):
        local = grid + array.eta[f] @ shapes
        world = array.position[f] + Rotation.from_quat(array.quaternion[f].astype(float)).apply(local)
        assert np.allclose(world, tip["position"][f], atol=2e-6)  # float32 quaternion of the body
    assert array.max_deformation > 0
    assert any("largest elastic displacement" in note for note in view.notes)


def test_cli_refuses_bad_input(plant_log, tmp_path, capsys):
    path = plant_log[0]
    text = tmp_path / "notes.txt"
    text.write_text("keep me")
    assert main(["view", str(path), "-o", str(text)]) == 1
    assert "not an HTML page" in capsys.readouterr().err and text.read_text() == "keep me"
    assert main(["view", str(path), "--mode", "1", "-o", str(tmp_path / "a.html")]) == 1
    assert "--mode" in capsys.readouterr().err
    assert main(["view", str(path), "--scale", "big", "-o", str(tmp_path / "a.html")]) == 1
    assert "--scale" in capsys.readouterr().err
    assert main(["view", str(path), "--signals", "nothing", "-o", str(tmp_path / "a.html")]) == 1
    assert "no signal 'nothing'" in capsys.readouterr().err
    assert main(["view", str(tmp_path / "missing.h5")]) == 1
    assert "no such file" in capsys.readouterr().err


def test_browser_deforms_the_array_as_numpy_does(plant_log, tmp_path):
    """The grids the page computed at t = 1.33 s with scale 40 equal l0 + 40 sum eta gamma (float32), eta
    interpolated linearly between the samples at 1.3 and 1.4 s; the body's pose likewise (slerp)."""
    from scipy.spatial.transform import Rotation, Slerp

    path, t, q = plant_log
    html = tmp_path / "plant.html"
    assert main(["view", str(path), "-o", str(html), "--signals", "multibody.bus.q"]) == 0
    view = from_log(path)
    array = view.bodies[1]
    found = probe(html, "?t=1.33&scale=40")
    frame = int(np.searchsorted(t, 1.33, side="right") - 1)
    a = (1.33 - t[frame]) / (t[frame + 1] - t[frame])
    assert found["frame"] == frame and found["alpha"] == pytest.approx(a, abs=1e-12)
    eta = (1 - a) * array.eta[frame] + a * array.eta[frame + 1]
    expected = array.vertices.ravel() + 40 * (eta @ array.shapes)
    assert np.allclose(found["flexible"][0], expected, atol=1e-5 * np.abs(expected).max())
    assert not np.allclose(found["flexible"][0], array.vertices.ravel(), atol=1e-3)
    bus = view.bodies[0].quaternion[frame:frame + 2].astype(float)
    slerp = Slerp([0.0, 1.0], Rotation.from_quat(bus))([a]).as_quat()[0]
    assert np.allclose(np.abs(np.dot(found["bodies"][0][1], slerp)), 1.0, atol=1e-6)


def test_browser_draws_the_log_and_its_deformation(tmp_path):
    """The bus held, only the array deforming: the pictures at two instants differ, and both are drawn."""
    path = tmp_path / "held.h5"
    write_plant_log(path, turning=False)
    html = tmp_path / "held.html"
    assert main(["view", str(path), "-o", str(html), "--scale", "60"]) == 0
    a = screenshot(html, "?t=0.5", tmp_path / "a.png")   # eta_0 at its peak
    b = screenshot(html, "?t=1.5", tmp_path / "b.png")   # eta_0 at its trough
    assert drawn_fraction(a) > 0.01 and drawn_fraction(b) > 0.01
    changed = np.abs(view_region(a).astype(int) - view_region(b).astype(int)).sum(axis=2) > 30
    assert changed.mean() > 0.002, f"only {changed.mean():.4%} of the view changed"
    same = screenshot(html, "?t=0.5", tmp_path / "c.png")
    assert np.array_equal(view_region(a), view_region(same))  # a deterministic picture: the change is motion


def test_browser_draws_a_scenario_with_wheels_and_thrusters(tmp_path):
    """configs/spacecraft_slew.yaml, initial configuration: a box, 4 wheels and 16 thrusters found on
    their nodes, drawn."""
    html = tmp_path / "slew.html"
    cwd = os.getcwd()
    os.chdir(REPO)  # the scenario's flight-software file is relative to the repository root
    try:
        assert main(["view", "configs/spacecraft_slew.yaml", "-o", str(html)]) == 0
    finally:
        os.chdir(cwd)
    found = probe(html, "?t=0")
    assert len(found["wheels"]) == 4 and len(found["plumes"]) == 16
    image = screenshot(html, "?t=0", tmp_path / "slew.png")
    h, w, _ = image.shape
    centre = image[h // 2 - 40:h // 2 + 40, (w - PANEL) // 2 - 40:(w - PANEL) // 2 + 40].astype(int)
    assert np.mean(np.abs(centre - BACKGROUND).sum(axis=2) > 30) > 0.9  # the bus is in the middle
    assert drawn_fraction(image) > 0.05


def test_user_mesh_replaces_the_inertia_box(tmp_path):
    """--mesh BODY=FILE: the body is drawn with the mesh trimesh reads (an STL box 1 x 2 x 3 m here)."""
    import trimesh

    from shell.view.scene import ViewError, from_scenario

    stl = tmp_path / "bus.stl"
    trimesh.creation.box(extents=[1.0, 2.0, 3.0]).export(stl)
    view = from_scenario(PLANT, meshes={"bus": str(stl)})
    bus = view.bodies[0]
    assert bus.kind == "mesh" and len(bus.faces) == 12
    assert np.allclose(np.ptp(bus.vertices, axis=0), [1.0, 2.0, 3.0])
    with pytest.raises(ViewError, match="no body wing"):
        from_scenario(PLANT, meshes={"wing": str(stl)})


def write_plant_linear_model(path: Path) -> np.ndarray:
    """The linear model of configs/lqr_plant.yaml at rest, x = [q; u], A = [[0, I], [-M^-1 K, -M^-1 D]] from
    the engine's mass, stiffness and damping matrices (exact at rest without gravity), written as
    flexshell linearize writes it. Returns the undamped frequencies [Hz] of K phi = w^2 M phi."""
    from scipy.linalg import eigh

    from shell.analysis.linear_model_file import write_linear_model
    from shell.analysis.linearize import LinearModel
    from shell.scenario import build_root, load_scenario
    from shell.view.scene import _engine_of

    from shell.assembly import flatten

    engine = _engine_of(flatten(build_root(load_scenario(PLANT)))[0])
    s = engine.system
    q0 = np.asarray(engine._initial_q, float)
    M, K, D = s.mass_matrix(q0), s.stiffness_matrix(), s.damping_matrix()
    n = s.nu
    A = np.block([[np.zeros((n, n)), np.eye(n)], [-np.linalg.solve(M, K), -np.linalg.solve(M, D)]])
    names = [f"multibody.q[{k}]" for k in range(n)] + [f"multibody.u[{k}]" for k in range(n)]
    x0 = np.concatenate([q0, np.zeros(n)])
    model = LinearModel(A, np.zeros((2 * n, 1)), np.eye(2 * n), np.zeros((2 * n, 1)), names, [""] * 2 * n,
                        ["multibody.bus.torque"], ["N*m"], names, [""] * 2 * n,
                        {k: np.zeros(m.shape) for k, m in (("A", A), ("B", np.zeros((2 * n, 1))),
                                                          ("C", np.eye(2 * n)), ("D", np.zeros((2 * n, 1))))},
                        {"t": 0.0, "x": x0, "z": np.zeros(0), "u": np.zeros(1), "y": x0, "xdot": np.zeros(2 * n),
                         "tangent": x0},
                        {"multibody.q": np.arange(n), "multibody.u": np.arange(n, 2 * n)},
                        {"multibody.bus.torque": np.array([0])}, {"multibody.q": np.arange(2 * n)},
                        {"points": 4, "richardson": True, "tolerance": 1e-8, "order": 6,
                         "state_steps": np.ones(2 * n), "input_steps": np.ones(1)},
                        {"scenario": str(PLANT), "overrides": "[]"})
    write_linear_model(path, model)
    w2 = eigh(K, M, eigvals_only=True)
    return np.sqrt(np.clip(w2[w2 > 1e-9], 0, None)) / (2 * np.pi)


def test_linear_model_mode_is_animated_over_one_period(tmp_path, capsys):
    """flexshell view LIN.h5 --mode 1: the frames span one period of the lowest flexible system mode (the
    generalized eigenproblem K phi = w^2 M phi, scipy.linalg.eigh; 1e-6 relative: the 0.5 % damping shifts
    |lambda| by less), the modal coordinates move along the mode's shape, the page is drawn."""
    lin = tmp_path / "lin.h5"
    frequencies = write_plant_linear_model(lin)
    html = tmp_path / "mode.html"
    assert main(["view", str(lin), "--mode", "1", "-o", str(html)]) == 0
    assert "system mode 1 of 6" in capsys.readouterr().out
    from shell.view.scene import from_linear_model

    view = from_linear_model(lin, 1)
    period = view.time[1] * len(view.time)
    assert period == pytest.approx(1.0 / frequencies[0], rel=1e-6)
    array = view.bodies[1]
    # undamped: every frame's modal coordinates are a multiple of one real shape (the mode's)
    shape = array.eta[np.argmax(np.abs(array.eta).sum(axis=1))]
    residual = array.eta - np.outer(array.eta @ shape / (shape @ shape), shape)
    assert np.abs(residual).max() < 1e-2 * np.abs(shape).max()
    assert view.loop and array.max_deformation > 0.05 * view.length  # shown at about 10 % of the scene
    assert main(["view", str(lin), "--mode", "9", "-o", str(html)]) == 1
    assert "6 oscillatory modes" in capsys.readouterr().err
    image = screenshot(html, "?t=0", tmp_path / "mode.png")
    assert drawn_fraction(image) > 0.01


@pytest.mark.slow
def test_view_a_scenario_run_from_the_command_line(tmp_path, capsys):
    """flexshell view SCENE.yaml --t-final: the scenario runs (logging multibody.q) and its run is drawn;
    the bus starts at the scenario's 5 deg and the frames are the requested rate's."""
    html = tmp_path / "run.html"
    assert main(["view", str(PLANT), "--t-final", "2 s", "--rate", "10 Hz", "--set",
                 "multibody.bus.initial.angle_rate=2 deg/s", "-o", str(html)]) == 0
    out = capsys.readouterr().out
    assert "running 2 s" in out and "21 frames" in out
    from shell.view.scene import from_scenario

    view = from_scenario(PLANT, t_final=2.0, rate="10 Hz", overrides=["multibody.bus.initial.angle_rate=2 deg/s"])
    angle = 2 * np.arctan2(view.bodies[0].quaternion[:, 2], view.bodies[0].quaternion[:, 3])
    assert angle[0] == pytest.approx(np.radians(5.0), abs=1e-6)
    assert angle[-1] - angle[0] == pytest.approx(np.radians(4.0), rel=0.05)  # ~2 deg/s for 2 s, torque-free
    assert drawn_fraction(screenshot(html, "?t=1", tmp_path / "run.png")) > 0.01


def test_fem2modal_keeps_the_decks_elements(tmp_path):
    """The body file of a deck holds its elements: configs/fem/spacecraft.dat's 160 CQUAD4, 11 CBAR, 1 CBUSH,
    RBE2 and RBE3 (card counts of its own report), drawn as the view draws them."""
    from dynamics.flex.body_file import read_body_geometry, write_body_file
    from dynamics.flex.pipeline import Fem2ModalOptions, fem2modal

    body = fem2modal(str(REPO / "configs" / "fem" / "spacecraft.dat"), Fem2ModalOptions(n_modes=2))
    write_body_file(tmp_path / "sc.h5", body)
    types, grids, _ = read_body_geometry(tmp_path / "sc.h5")
    counts = {kind: types.count(kind) for kind in set(types)}
    assert counts == {"CQUAD4": 160, "CBAR": 11, "CBUSH": 1, "RBE2": 1, "RBE3": 1}
    assert set(grids[grids > 0].ravel()) <= set(body.grid_ids.tolist())
    edges, triangles, skipped = element_drawing(types, grids, body.grid_ids)
    assert skipped == [] and len(triangles) == 2 * 160


FREE_BUS = """
name: free_bus
multibody:
  gravity: "[0, 0, 0] m/s^2"
  bodies:
    - name: bus
      parent: world
      hinge: free
      mass: 500 kg
      inertia: "[300, 200, 100] kg*m^2"
  nodes:
    - {name: star, body: bus, position: "[0.4, -0.2, 0.6] m", rotation: [0.9659258262890683, 0, 0.25881904510252074, 0]}
log:
  rate: 10 Hz
  signals: [multibody.star.attitude, multibody.star.position]
"""


def test_a_free_body_is_posed_from_a_logged_node_attitude_and_position(tmp_path):
    """A log with only a node's attitude and position (as the demo logs): the body's pose is derived by
    inverting the node frame; against the engine's forward node kinematics of known body poses (1e-9)."""
    from scipy.spatial.transform import Rotation

    from shell.assembly import flatten
    from shell.scenario import build_root, parse_scenario
    from shell.view.scene import _engine_of

    scenario = tmp_path / "free_bus.yaml"
    scenario.write_text(FREE_BUS)
    engine = _engine_of(flatten(build_root(parse_scenario(FREE_BUS, str(scenario))))[0])
    t = np.arange(0.0, 3.0, 0.1)
    rotation = Rotation.from_rotvec(np.outer(t, [0.3, -0.2, 0.5]))
    q = np.zeros((len(t), 7))
    q[:, :4] = rotation.as_quat()[:, [3, 0, 1, 2]]
    q[:, 4:] = np.outer(t, [1.0, 2.0, -0.5])
    attitude, position = np.zeros((len(t), 4)), np.zeros((len(t), 3))
    for f in range(len(t)):
        kin = engine.system.node_kinematics(q[f], np.zeros(6))
        attitude[f] = Rotation.from_matrix(kin.rotation[0]).as_quat()[[3, 0, 1, 2]]
        position[f] = kin.position[0]
    log = tmp_path / "free.h5"
    writer = LogWriter(log, {"every_0.1s": [LoggedSignal("multibody.star.attitude", (4,), "", ""),
                                            LoggedSignal("multibody.star.position", (3,), "m", "")]},
                       {"scenario": FREE_BUS, "scenario_file": str(scenario)})
    writer.append_rows("every_0.1s", t, np.hstack([attitude, position]))
    writer.close()
    view = from_log(log)
    bus = view.bodies[0]
    assert np.allclose(bus.position, q[:, 4:], atol=1e-9)
    assert np.allclose(np.abs(np.sum(bus.quaternion * rotation.as_quat(), axis=1)), 1.0, atol=1e-6)
    assert any("derived from the logged multibody.star.attitude" in note for note in view.notes)
