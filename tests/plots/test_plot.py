"""`flexshell plot`: legends, units, derived attitude panels, the engine's q split per body, figure sizes
and pages. The logs are written directly with the log writer (no simulation), so the expected values
are known exactly; Euler angles and attitude errors are checked against scipy's Rotation (an
independent implementation) to 1e-12 rad (round-off of a few trigonometric operations)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from shell.cli import main
from shell.commands.plot import (PANEL_HEIGHT, attitude_error, build_panels, component_labels, draw_pages,
                                 euler_321, pretty_unit)
from shell.log_file import LoggedSignal, LogWriter, log_info, read_log

SCENE = """
multibody:
  bodies:
    - {name: bus, hinge: free, mass: 500 kg, inertia: "[400, 300, 250] kg*m^2"}
    - {name: array, parent: bus, parent_node: root, hinge: locked, body_file: array.h5}
  nodes:
    - {name: acs, body: bus}
models:
  controller:
    type: PdAttitudeController
    attach: {node: acs}
    parameters: {attitude_command: [0.9659258262890683, 0, 0, 0.25881904510252074]}
"""
COMMAND = np.array([0.9659258262890683, 0, 0, 0.25881904510252074])  # 30 deg about z


def random_quaternions(n, seed=0):
    q = np.random.default_rng(seed).normal(size=(n, 4))
    return q / np.linalg.norm(q, axis=1, keepdims=True)


def write_log(path, signals, t, values, scenario=SCENE):
    writer = LogWriter(path, {"every_0.1s": signals}, {"scenario": scenario})
    for k, time in enumerate(t):
        writer.append("every_0.1s", float(time), [v[k] for v in values])
    writer.close()
    return path


@pytest.fixture
def log(tmp_path):
    t = np.arange(50) * 0.1
    n = t.size
    signals = [LoggedSignal("multibody.acs.attitude", (4,), "", "quaternion [w, x, y, z] rotating node axes"),
               LoggedSignal("controller.torque", (3,), "m*N", "commanded torque"),
               LoggedSignal("wheels.rw1.wheel_speed", (), "rad/s", ""),
               LoggedSignal("wheels.rw2.wheel_speed", (), "rad/s", ""),
               LoggedSignal("wheels.rw3.wheel_speed", (), "rad/s", ""),
               LoggedSignal("multibody.q", (10,), "", "generalized coordinates (SI)"),
               LoggedSignal("multibody.array.modal_q", (3,), "1", "modal coordinates eta of array")]
    q = random_quaternions(n)
    values = [q, np.sin(t)[:, None] * [1.0, 2.0, 3.0], t, 2 * t, 3 * t,
              np.column_stack([q, np.zeros((n, 3)), 1e-6 * np.cos(t)[:, None] * [1.0, 2.0, 3.0]]),
              1e-6 * np.cos(t)[:, None] * [1.0, 2.0, 3.0]]
    return write_log(tmp_path / "log.h5", signals, t, values), q


@pytest.mark.parametrize("unit, expected", [
    ("m*N", "N m"), ("N*m", "N m"), ("kg*m^2", "kg m²"), ("N*m*s/rad", "N m s/rad"), ("rad/s^2", "rad/s²"),
    ("1", ""), ("", ""), ("1/s", "1/s"), ("N*m/(rad*s)", "N m/(rad s)"), ("deg/s", "deg/s"), ("Pa", "Pa"),
    ("rad*s", "rad s"), ("m^3/s^2", "m³/s²")])
def test_units_print_as_an_engineer_writes_them(unit, expected):
    assert pretty_unit(unit) == expected


def test_component_labels():
    assert component_labels("multibody.acs.attitude", (4,), "quaternion") == ["w", "x", "y", "z"]
    assert component_labels("controller.torque", (3,)) == ["x", "y", "z"]
    assert component_labels("multibody.array.modal_q", (3,)) == ["η1", "η2", "η3"]
    assert component_labels("multibody.array.modal_u", (2,)) == ["η1'", "η2'"]
    assert component_labels("multibody.acs.rotation", (3, 3))[:2] == ["R11", "R12"]
    assert component_labels("lqr.command", (2,)) == ["command[0]", "command[1]"]


def test_euler_angles_and_attitude_error_against_scipy():
    q = random_quaternions(200, seed=4)
    rotations = Rotation.from_quat(q[:, [1, 2, 3, 0]])  # scipy: scalar last
    # intrinsic z-y'-x'' of the node -> world rotation = yaw, pitch, roll of the 3-2-1 sequence
    np.testing.assert_allclose(euler_321(q), rotations.as_euler("ZYX"), rtol=0, atol=1e-12)
    expected = (Rotation.from_quat(COMMAND[[1, 2, 3, 0]]).inv() * rotations).magnitude()
    np.testing.assert_allclose(attitude_error(q, COMMAND), expected, rtol=0, atol=1e-12)
    assert attitude_error(-q, COMMAND) == pytest.approx(expected, abs=1e-12)  # q and -q: one attitude


def test_panels_name_components_split_the_engine_q_and_derive_attitude(log):
    path, q = log
    panels = build_panels(log_info(path), read_log(path), list(log_info(path)["signals"]))
    by_title = {p.title: p for p in panels}
    labels = {p.title: [c[2] for c in p.curves] for p in panels}
    assert labels["multibody.acs.attitude"] == ["w", "x", "y", "z"]
    assert labels["controller.torque"] == ["x", "y", "z"] and pretty_unit(by_title["controller.torque"].unit) == "N m"
    assert labels["wheels.*.wheel_speed"] == ["rw1", "rw2", "rw3"]   # one panel, wheel names as legend
    # the engine's q: the bus's free-hinge coordinates and the array's modal coordinates apart
    assert labels["multibody.q: bus free hinge"] == ["qw", "qx", "qy", "qz", "x", "y", "z"]
    modal = by_title["multibody.q: array modal coordinates"]
    assert [c[2] for c in modal.curves] == ["η1", "η2", "η3"]
    assert np.max(np.abs(modal.curves[2][1])) == pytest.approx(3e-6)  # its own axis: not flattened by q_w ~ 1
    # the error is measured from the controller's attitude_command found in the scenario of the log
    error = next(p for p in panels if "attitude error" in p.title)
    np.testing.assert_allclose(error.curves[0][1], np.degrees(attitude_error(q, COMMAND)), rtol=1e-14)
    euler = next(p for p in panels if "Euler" in p.title)
    assert [c[2] for c in euler.curves] == ["yaw", "pitch", "roll"] and euler.unit == "deg"
    # derived panels follow their quaternion; panel order follows the signals' order
    titles = [p.title for p in panels]
    assert titles.index(error.title) == titles.index("multibody.acs.attitude") + 1


def test_figures_keep_their_size_and_page(log, tmp_path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.image as mpimg
    import matplotlib.pyplot as plt

    path, _ = log
    info, data = log_info(path), read_log(path)
    panels = build_panels(info, data, list(info["signals"]))
    assert len(panels) == 8   # attitude + 2 derived, torque, wheels, 2 blocks of q, modal_q
    figures = draw_pages(panels, "log", per_page=6)
    assert [len(f.axes) for f in figures] == [6, 2]
    heights = [f.get_size_inches()[1] for f in figures]
    assert heights == [pytest.approx(PANEL_HEIGHT * 6 + 0.9), pytest.approx(PANEL_HEIGHT * 2 + 0.9)]
    axes = {ax.get_title(loc="left"): ax for f in figures for ax in f.axes}
    assert [t.get_text() for t in axes["multibody.acs.attitude"].get_legend().get_texts()] == ["w", "x", "y", "z"]
    assert [t.get_text() for t in axes["wheels.*.wheel_speed"].get_legend().get_texts()] == ["rw1", "rw2", "rw3"]
    assert axes["controller.torque"].get_ylabel() == "N m" and axes["wheels.*.wheel_speed"].get_ylabel() == "rad/s"
    assert all("1" != ax.get_ylabel() for f in figures for ax in f.axes)
    for f in figures:
        plt.close(f)
    # through the command line: two PNG pages of the expected pixel height, or one PDF
    out = tmp_path / "fig.png"
    assert main(["plot", str(path), "-o", str(out)]) == 0
    first, second = mpimg.imread(tmp_path / "fig-1.png"), mpimg.imread(tmp_path / "fig-2.png")
    assert abs(first.shape[0] - (PANEL_HEIGHT * 6 + 0.9) * 110) <= 1 and second.shape[0] < first.shape[0]
    assert not out.exists()
    assert main(["plot", str(path), "-o", str(tmp_path / "fig.pdf")]) == 0
    assert (tmp_path / "fig.pdf").read_bytes().count(b"/Type /Page\n") + \
        (tmp_path / "fig.pdf").read_bytes().count(b"/Type /Page ") >= 2


def test_bad_options_are_refused(log, tmp_path, capsys):
    path, _ = log
    assert main(["plot", str(path), "--attitude-reference", "[1, 1, 0, 0]", "-o", str(tmp_path / "a.png")]) == 1
    assert "unit quaternion" in capsys.readouterr().err
    assert main(["plot", str(path), "--per-page", "0", "-o", str(tmp_path / "a.png")]) == 1
    assert "--per-page" in capsys.readouterr().err
    assert main(["plot", str(path), "nothing_here", "-o", str(tmp_path / "a.png")]) == 1
    assert "no signal 'nothing_here'" in capsys.readouterr().err


def test_plot_reads_a_stored_scenario_with_an_indexed_signal_in_a_flow_mapping():
    """The array-latch scene writes issue 29's `when: {signal: multibody.array.q[0], ...}` unquoted; plot reads the
    scenario stored in the log with the scenario loader, so q still splits per hinge (plain YAML refused the text and
    the split was silently dropped)."""
    from pathlib import Path

    from shell.commands.plot import coordinate_blocks

    text = (Path(__file__).resolve().parents[2] / "configs" / "gallery" / "16_array_latch.yaml").read_text()
    assert "q[0], crosses" in text
    blocks = coordinate_blocks(text, "multibody.q", 8)
    assert [(title, first, count) for title, first, count, _, _ in blocks] == [
        ("bus free hinge", 0, 7), ("array revolute hinge", 7, 1)]
