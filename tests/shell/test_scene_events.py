"""Events that change the scene (``events: on:``, shell/scene_events.py), through the shipped configs and the command
line, against conservation laws and analytic solutions computed here from the logged node motion (masses and
inertias from the configs, not from the engine):

* stage separation with a spring (configs/gallery/15_stage_separation.yaml): total momentum and angular momentum
  conserved to 1e-9 relative; after the spring's stroke both stages on straight lines; their relative velocity
  sqrt(2 E / mu) with E the spring's energy 1/2 k s^2;
* stage separation without a spring, of a tumbling stack (configs/stage_separation_coast.yaml): after the release
  the upper stage on the tangent line of its circle, to 1e-9 m (compiled and interpreted runs of this config agree
  bit for bit: tests/shell/test_compiled_loop.py runs every config in configs/);
* array deployment latched at 90 deg (configs/gallery/16_array_latch.yaml): momentum and angular momentum conserved
  through the latch; the kinetic energy after it equals that of the rigid composite with the same momenta
  (``P^2 / 2M + 1/2 H' I^-1 H`` about the composite's center of mass), to 1e-9 relative, and the loss the run
  reports equals the loss the log shows;
* docking through a spring-damper probe and a latch (configs/gallery/17_docking.yaml): momentum conserved, the pair
  at the common velocity afterwards;
* a restart after the change (``--save-state``/``--restore``) continues bit for bit; the log and the run summary say
  what changed when; bad inputs refused with file, line and key.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import h5py
import numpy as np
import pytest

from shell.cli import main
from shell.log_file import read_log
from shell.scenario import build_simulation, load_scenario, parse_scenario
from shell.schema.document import ScenarioError
from tests.shell.test_closure_scenes import SPRING_SCENE

ROOT = Path(__file__).resolve().parents[2]
CONFIGS = ROOT / "configs"


def _run(config: Path, tmp_path, *extra):
    log = tmp_path / f"{config.stem}.h5"
    result = subprocess.run([sys.executable, "-m", "shell.cli", "run", str(config), "-o", str(log), *extra], cwd=ROOT,
                            capture_output=True, text=True, timeout=900)
    assert result.returncode == 0, result.stderr + result.stdout
    with h5py.File(log) as f:
        changes = json.loads(f.attrs["scene_events"])
    return read_log(log), changes, result.stdout


def _momenta(log, bodies):
    """World-axes linear momentum P, angular momentum H about the composite center of mass c, kinetic energy T, c,
    and the composite inertia about c, per sample, from each body's center-of-mass node (rotation, position,
    velocities in node axes) and its mass and inertia ({body: (mass, inertia about its center of mass)})."""
    kin = {}
    for b, (m, inertia) in bodies.items():
        R = log[f"multibody.{b}_cm.rotation"]
        kin[b] = (R, log[f"multibody.{b}_cm.position"],
                  np.einsum("nij,nj->ni", R, log[f"multibody.{b}_cm.linear_velocity"]),
                  np.einsum("nij,nj->ni", R, log[f"multibody.{b}_cm.angular_velocity"]),
                  np.einsum("nij,jk,nlk->nil", R, inertia, R))
    mass = sum(m for m, _ in bodies.values())
    P = sum(bodies[b][0] * kin[b][2] for b in bodies)
    c = sum(bodies[b][0] * kin[b][1] for b in bodies) / mass
    H, T, I_c = 0.0, 0.0, 0.0
    for b, (m, _) in bodies.items():
        R, r, v, w, I_world = kin[b]
        rho = r - c
        H = H + m * np.cross(rho, v - P / mass) + np.einsum("nij,nj->ni", I_world, w)
        T = T + 0.5 * m * np.sum(v * v, axis=1) + 0.5 * np.einsum("ni,nij,nj->n", w, I_world, w)
        I_c = I_c + I_world + m * (np.sum(rho * rho, axis=1)[:, None, None] * np.eye(3)
                                   - np.einsum("ni,nj->nij", rho, rho))
    return P, H, T, c, I_c, mass


STAGES = {"lower": (1000.0, np.diag([450.0, 3225.0, 3225.0])), "upper": (300.0, np.diag([60.0, 255.0, 255.0]))}


def test_stage_separation_with_a_spring_conserves_momentum_and_ends_on_straight_lines(tmp_path):
    """Released at 2 s, the compression-only spring (5 kN/m, compressed 0.2 m) pushes the stages apart: momentum
    conserved to 1e-9 relative (measured 2e-15), the stages on straight lines after the stroke (fit residual measured
    6e-14 m), their relative velocity sqrt(2 * 100 J / mu) to 1e-6 relative (measured 6.4e-7: the spring's force has
    a kink where it reaches its free length, which the fixed RK4 step crosses without locating it, so the step that
    contains it is first order in the jump of the force's derivative)."""
    log, changes, out = _run(CONFIGS / "gallery" / "15_stage_separation.yaml", tmp_path)
    assert changes == [{"time": 2.0, "event": "separation", "changes": "interface off"}]
    assert "event separation at t = 2 s: interface off" in out
    t = log["time"]
    P, H, _, _, _, _ = _momenta(log, STAGES)
    assert np.abs(P - P[0]).max() <= 1e-9 * np.linalg.norm(P[0])
    assert np.abs(H - H[0]).max() <= 1e-9 * np.linalg.norm(H[0])
    gap = log["multibody.upper_cm.position"][:, 0] - log["multibody.lower_cm.position"][:, 0]
    assert np.abs(gap[t <= 2.0] - 4.5).max() < 1e-9                 # welded until the event
    coasting = t >= 2.6                                              # the stroke ends at 2.3 s
    speeds = {}
    for stage in STAGES:
        r = log[f"multibody.{stage}_cm.position"][coasting]
        fit = np.polynomial.polynomial.polyfit(t[coasting], r, 1)
        assert np.abs(np.polynomial.polynomial.polyval(t[coasting], fit).T - r).max() < 1e-9
        speeds[stage] = fit[1]
    mu = 1000.0 * 300.0 / 1300.0
    assert speeds["upper"][0] - speeds["lower"][0] == pytest.approx(np.sqrt(2 * 0.5 * 5000.0 * 0.2**2 / mu), rel=1e-6)


def test_a_tumbling_stack_released_without_a_spring_flies_off_on_the_tangent(tmp_path):
    """The stack turns at 0.2 rad/s about z through its center of mass c (at rest); released at T = 2 s, the upper
    stage's center of mass follows r(t) = c + R(w T) rho + (t - T) w x R(w T) rho, rho = its offset from c, to 1e-9 m
    (measured 5e-14 m, RK4 5 ms); the lower stage likewise; the total momentum stays zero (1e-9 of m v)."""
    log, changes, _ = _run(CONFIGS / "stage_separation_coast.yaml", tmp_path)
    assert [c["time"] for c in changes] == [2.0]
    _assert_on_tangents(log)
    P, H, _, _, _, _ = _momenta(log, STAGES)
    assert np.abs(P).max() < 1e-9 * 300.0 * 0.7
    assert np.abs(H - H[0]).max() <= 1e-9 * np.linalg.norm(H[0])


def _assert_on_tangents(log, release=2.0):
    """Both stages of the tumbling stack (0.2 rad/s about z through c) on their circles until ``release``, on the
    tangents after it, to 1e-9 m."""
    t, w = log["time"], 0.2
    c = np.array([300.0 * 4.5 / 1300.0, 0.0, 0.0])
    for stage, x in (("upper", 4.5), ("lower", 0.0)):
        angle = w * np.minimum(t, release)
        rho = (x - c[0]) * np.column_stack([np.cos(angle), np.sin(angle), 0 * t])
        tangent = w * (x - c[0]) * np.column_stack([-np.sin(angle), np.cos(angle), 0 * t])
        expected = c + rho + np.maximum(t - release, 0.0)[:, None] * tangent
        assert np.abs(log[f"multibody.{stage}_cm.position"] - expected).max() < 1e-9


STACK = """\
name: stack
multibody:
  bodies:
    - name: lower
      parent: world
      hinge: free
      mass: 1000 kg
      inertia: "[450, 3225, 3225] kg*m^2"
      initial: {velocity: "[0, -0.20769230769230773, 0] m/s", angular_velocity: "[0, 0, 0.2] rad/s"}
    - name: upper
      parent: lower
      hinge: locked
      inboard_position: "[4.5, 0, 0] m"
      mass: 300 kg
      inertia: "[60, 255, 255] kg*m^2"
  nodes:
    - {name: lower_cm, body: lower}
    - {name: upper_cm, body: upper}
events:
  on:
    - name: separation
      when: {time: 2 s}
      do: [{detach: upper}]
integrator: {method: rk4, step: 5 ms}
stop: {time: 4 s}
log: {rate: 50 Hz, signals: [multibody.upper_cm.position, multibody.lower_cm.position]}
"""


def test_a_stage_written_on_a_locked_hinge_is_detached_as_the_engine_detaches_it(tmp_path):
    """The stack of the coast scene written as a user writes a stack (the upper stage a child of the lower on a
    locked hinge): ``detach: upper`` builds it on a free hinge from the world at its initial pose and velocity, held
    by the weld upper_mount that the event switches off, and says so; both stages on their tangents after the
    release (1e-9 m; equal to the explicitly written scene to 9e-16 m)."""
    path = tmp_path / "stack.yaml"
    path.write_text(STACK)
    sim = build_simulation(load_scenario(path))
    summary = sim.run(4.0, log_path=tmp_path / "stack.h5")
    assert summary.changes == ((2.0, "separation", "upper_mount off"),)
    assert ("events: body upper (written on a locked hinge to lower) is built on a free hinge held by the weld "
            "upper_mount, which event separation switches off") in summary.notes
    _assert_on_tangents(read_log(tmp_path / "stack.h5"))
    path.write_text(STACK.replace("nodes:\n", "nodes:\n    - {name: upper_seat, body: lower}\n"))
    with pytest.raises(ScenarioError, match="the scene already has the name 'upper_seat'"):
        build_simulation(load_scenario(path))


def test_array_latch_conserves_momenta_and_loses_the_plastic_impact_energy(tmp_path):
    """The latch at 90 deg (a located crossing of multibody.array.q[0]): P and H unchanged (1e-9 relative; measured
    8e-14 absolute on 22 kg m/s and 2e-15 relative), the array's rate relative to the bus zero afterwards, the
    energy after equal to the rigid composite's P^2 / 2M + 1/2 H' I_c^-1 H (1e-9 relative; measured 3e-16), and the
    loss the run reports equal to the loss the logged motion shows (measured 5.9117608 J both)."""
    log, changes, out = _run(CONFIGS / "gallery" / "16_array_latch.yaml", tmp_path)
    (change,) = changes
    assert change["event"] == "latch" and change["changes"].startswith("latch on (gap ")
    reported = float(change["changes"].split("kinetic energy lost ")[1].split(" J")[0])
    t = log["time"]
    before, after = t < change["time"], t > change["time"]
    bodies = {"bus": (500.0, np.diag([200.0, 250.0, 300.0])), "array": (30.0, np.diag([2.5, 22.5, 25.0]))}
    P, H, T, _, I_c, mass = _momenta(log, bodies)
    assert np.abs(P - P[0]).max() <= 1e-9 * np.linalg.norm(P[0])
    assert np.abs(H - H[0]).max() <= 1e-9 * np.linalg.norm(H[0])
    assert np.abs(log["multibody.array.q"][after] - np.pi / 2).max() < 1e-9
    assert np.abs(log["multibody.array.u"][after]).max() < 1e-12
    predicted = 0.5 * P[after] @ P[0] / mass + 0.5 * np.einsum("ni,ni->n", H[after],
                                                               np.linalg.solve(I_c[after], H[after][..., None])[..., 0])
    assert np.abs(T[after] - predicted).max() <= 1e-9 * T[after].max()
    lost = T[before].mean() - T[after].mean()
    assert reported == pytest.approx(lost, rel=1e-7)                   # printed to 8 digits
    assert lost > 0.5                                                  # a real impact: 5.9 J of 11.6 J


def test_docking_through_a_probe_and_a_latch_conserves_momentum(tmp_path):
    """The probe slows the closing, the latch captures when the gap crosses 0 falling: momentum conserved to 1e-9
    relative throughout (measured 1.4e-15), both bodies at 800 * 0.1 / 2000 = 0.04 m/s afterwards."""
    log, changes, _ = _run(CONFIGS / "gallery" / "17_docking.yaml", tmp_path)
    (change,) = changes
    assert change["event"] == "capture" and 5.0 < change["time"] < 20.0
    t = log["time"]
    bodies = {"chaser": (800.0, np.diag([300.0, 400.0, 400.0])), "target": (1200.0, np.diag([600.0, 800.0, 800.0]))}
    P, _, _, _, _, _ = _momenta(log, bodies)
    assert np.abs(P - P[0]).max() <= 1e-9 * np.linalg.norm(P[0])
    after = t > change["time"]
    for body in bodies:
        v = np.einsum("nij,nj->ni", log[f"multibody.{body}_cm.rotation"][after],
                      log[f"multibody.{body}_cm.linear_velocity"][after])
        assert np.abs(v - [0.04, 0.0, 0.0]).max() < 1e-12
    assert np.abs(log["gap.y"][after, 0]).max() < 1e-9


def test_a_restart_after_the_latch_restores_the_changed_scene(tmp_path):
    """--save-state after the latch, --restore to the end: the same final log rows bit for bit as the straight run
    (the restored run has the latch on again: its array stays latched)."""
    scene = str(CONFIGS / "gallery" / "16_array_latch.yaml")
    straight, first, second, state = (tmp_path / n for n in ("straight.h5", "first.h5", "second.h5", "state.h5"))
    assert main(["run", scene, "-o", str(straight), "--t-final", "5", "--quiet"]) == 0
    assert main(["run", scene, "-o", str(first), "--t-final", "4", "--quiet", "--save-state", str(state)]) == 0
    assert main(["run", scene, "-o", str(second), "--t-final", "5", "--quiet", "--restore", str(state)]) == 0
    a, b = read_log(straight), read_log(second)
    k = np.searchsorted(a["time"], b["time"][0])
    for name in ("multibody.q", "multibody.array.u", "multibody.latch.load"):
        assert a[name][k:].tobytes() == b[name].tobytes(), name
    with h5py.File(second) as f:
        assert json.loads(f.attrs["scene_events"]) == []               # nothing changed in the second part


def test_an_event_sets_a_parameter_by_name_and_the_summary_says_so(tmp_path):
    """``set:`` writes a model parameter by name at the event (a Constant's value from 1 to 3 m/s at 0.5 s: the
    integral is 0.5 * 1 + 0.5 * 3 at 1 s, RK4 exact for a piecewise constant rate with the event on a step)."""
    text = """\
models:
  rate: {type: Constant, config: {unit: m/s}, parameters: {value: 1 m/s}}
  position: {type: Integrator, config: {unit: m}}
connections: [rate.y -> position.u]
events:
  on:
    - name: boost
      when: {time: 500 ms}
      do: [{set: {rate.value: 3 m/s}}]
integrator: {method: rk4, step: 0.1 s}
stop: {time: 1 s}
"""
    sim = build_simulation(parse_scenario(text, "boost.yaml"))
    summary = sim.run(1.0)
    assert sim.signal("position.y") == pytest.approx(2.0, abs=1e-12)
    assert summary.changes == ((0.5, "boost", "rate.value = '3 m/s'"),)
    assert "event boost at t = 0.5 s: rate.value = '3 m/s'" in str(summary)


LATCH = (CONFIGS / "gallery" / "16_array_latch.yaml").read_text()
SEPARATION = (CONFIGS / "gallery" / "15_stage_separation.yaml").read_text()
ON = "      do: [{detach: upper}]"
WHEN = "      when: {time: 2 s}"


@pytest.mark.parametrize("old, new, where, message", [
    (ON, "      do: [{detach: middle}]", "events.on[0](separation).do[0].detach", "unknown body 'middle'"),
    (ON, "      do: [{explode: upper}]", "events.on[0](separation).do[0].explode", "unknown key 'explode'"),
    (ON, "      do: [{constraint: {add: latchh}}]", "events.on[0](separation).do[0].constraint.add",
     "unknown constraint 'latchh'"),
    (ON, "      do: [{set: {upper.gain: 2}}]", "events.on[0](separation).do[0].set.upper.gain",
     "'upper.gain' is not a parameter of the scene"),
    (WHEN, "      when: {time: 2}", "events.on[0](separation).when.time", "bare number 2"),
    (WHEN, "      when: {time: 0 s}", "events.on[0](separation).when.time", "after the start (> 0 s)"),
    (WHEN, "      when: {crosses: 2 s}", "events.on[0](separation).when", "either time: "),
    (WHEN, "      when: {signal: multibody.upper.w, crosses: 1 m}", "events.on[0](separation).when.signal",
     "no output port 'upper.w'"),
    (WHEN, "      when: {signal: nothing.y, crosses: 1 m}", "events.on[0](separation).when.signal",
     "no model 'nothing'"),
    (WHEN, "      when: {signal: multibody.upper_cm.position, crosses: 1}", "events.on[0](separation).when.crosses",
     "bare number 1"),
    (WHEN, "      when: {signal: multibody.upper_cm.position, crosses: 1 s}", "events.on[0](separation).when.crosses",
     "s [[time]] cannot become m [[length]]"),
    (WHEN, "      when: {signal: \"multibody.upper_cm.position[3]\", crosses: 1 m}",
     "events.on[0](separation).when.signal", "element 3 does not exist"),
    (ON, ON + "\n    - name: separation\n      when: {time: 3 s}\n" + ON, "events.on[1].name",
     "duplicate event name 'separation'"),
])
def test_bad_events_are_refused_with_file_line_and_key(tmp_path, old, new, where, message):
    path = tmp_path / "scene.yaml"
    text = SEPARATION.replace(old, new)
    assert text != SEPARATION
    path.write_text(text)
    with pytest.raises(ScenarioError) as caught:
        build_simulation(load_scenario(path))
    text_lines = text.splitlines()
    error = str(caught.value)
    assert f"{path}:" in error and where in error and message in error, error
    line = int(error.split(f"{path}:")[1].split(":")[0])
    assert where.split(".")[-1].split("[")[0].split("(")[0] in text_lines[line - 1] or "name" in where


def test_lock_and_detach_need_the_constraints_they_switch(tmp_path):
    """lock: a body without a constraint to its parent, detach: a body not on a free hinge, are refused at the
    action's line with what to declare."""
    path = tmp_path / "latch.yaml"
    path.write_text(LATCH.replace("do: [{lock: array}]", "do: [{detach: array}]"))
    with pytest.raises(ScenarioError, match=r"latch.yaml:\d+: events.on\[0\]\(latch\).do\[0\].detach: body 'array' "
                                            r"is on a revolute hinge"):
        build_simulation(load_scenario(path))
    path.write_text(LATCH.replace("do: [{lock: array}]", "do: [{lock: bus}]"))
    with pytest.raises(ScenarioError, match="no constraint is declared between body 'bus' and its parent the world"):
        build_simulation(load_scenario(path))


def test_a_latch_whose_frames_are_apart_stops_the_run_naming_the_event(tmp_path):
    """The latch switched on by time at 1 s, where the array is 30 deg short of its seat: the run stops with the
    gap, the event and the tolerance, and the log says so."""
    path = tmp_path / "latch.yaml"
    path.write_text(LATCH.replace("when: {signal: multibody.array.q[0], crosses: 90 deg, direction: rising}",
                                  "when: {time: 1 s}"))
    assert main(["run", str(path), "-o", str(tmp_path / "l.h5"), "--quiet"]) == 1
    with h5py.File(tmp_path / "l.h5") as f:
        assert f.attrs["status"] == "failed"
        assert "event latch: switching on latch would close a gap of" in f.attrs["message"]


def test_event_values_are_dispersable_by_name_and_by_override(tmp_path):
    """events.<event>.time and .crosses: --set reaches them in the scenario, and the scene's named values hold them
    (what a Monte Carlo run writes in its context): the separation happens at the time written there."""
    scenario = load_scenario(CONFIGS / "gallery" / "15_stage_separation.yaml", ["events.separation.time=1.5 s"])
    sim = build_simulation(scenario)
    assert sim.diagram.names.value(sim.context, "events.separation.time") == 1.5
    sim.context.assign([("events.separation.time", "2500 ms")])
    assert sim.run(3.0).changes == ((2.5, "separation", "interface off"),)
    latch = build_simulation(load_scenario(CONFIGS / "gallery" / "16_array_latch.yaml",
                                           ["events.latch.crosses=80 deg"]))
    assert latch.diagram.names.value(latch.context, "events.latch.crosses") == pytest.approx(np.radians(80.0))
    with pytest.raises(ScenarioError, match="event 'latch' has no time:"):
        load_scenario(CONFIGS / "gallery" / "16_array_latch.yaml", ["events.latch.time=1 s"])


def test_a_crossing_in_the_other_direction_is_not_the_event():
    """direction: falling on the array's rising crossing of 90 deg: no event, the array swings on unlatched."""
    text = LATCH.replace("direction: rising", "direction: falling")
    sim = build_simulation(parse_scenario(text, "latch.yaml", ["stop.time=4 s"]))
    summary = sim.run(4.0)
    assert summary.changes == () and summary.events == 0
    assert sim.signal("multibody.array.q")[0] > np.radians(95.0)


def test_the_view_of_a_separation_shows_the_released_stage_flying_away(tmp_path):
    """flexshell view reads the log: the upper stage's frames follow its logged free-hinge coordinates away from the
    lower stage after the release, and the view's notes say what changed when."""
    from shell.view.scene import from_log

    log = tmp_path / "sep.h5"
    assert main(["run", str(CONFIGS / "gallery" / "15_stage_separation.yaml"), "-o", str(log), "--quiet"]) == 0
    view = from_log(log)
    assert "event separation at t = 2 s: interface off" in view.notes
    bodies = {b.name: b for b in view.bodies}
    distance = np.linalg.norm(bodies["upper"].position - bodies["lower"].position, axis=1)
    assert np.abs(distance[view.time <= 2.0] - 4.5).max() < 1e-9 and distance[-1] > 5.5


def test_a_latch_runs_compiled_and_interpreted_identically(tmp_path):
    """The array latch from 80 deg: the loop returns to Python once, at the step with the crossing, which is located
    on the dense output; the impact is applied between two calls of the compiled loop; the interpreted reference ends
    in the same state, log and counters bit for bit."""
    from tests.shell.test_compiled_loop import _assert_same_run, _build

    scenario = parse_scenario(LATCH, str(CONFIGS / "gallery" / "16_array_latch.yaml"),
                              ["multibody.array.initial.angle=80 deg", "stop.time=0.5 s"])
    runs, returns = {}, []
    for mode in ("interpreted", "compiled"):
        sim = _build(scenario, mode)
        located = sim.compiled_run._event
        sim.compiled_run._event = lambda *args: returns.append(args) or located(*args)
        sim.run(scenario.t_final, log_path=tmp_path / f"{mode}.h5")
        runs[mode] = sim
    assert runs["compiled"].mode == "compiled", runs["compiled"].interpreted_reason
    assert len(runs["compiled"].scene_changes) == 1
    assert len(returns) == 1            # 500 steps in the compiled loop, one return to Python: the latch
    assert runs["compiled"].scene_changes == runs["interpreted"].scene_changes
    _assert_same_run(runs["interpreted"], runs["compiled"], tmp_path / "interpreted.h5", tmp_path / "compiled.h5")


PENDULUM = """\
name: held_pendulum
multibody:
  gravity: "[0, -9.81, 0] m/s^2"
  bodies:
    - {name: base, parent: world, hinge: locked, mass: 10 kg, inertia: [1, 1, 1]}
    - name: pendulum
      parent: base
      hinge: revolute
      axis: [0, 0, 1]
      mass: 2 kg
      com: "[1, 0, 0] m"
      inertia: "[0.01, 0.5, 0.5] kg*m^2"
      initial: {angle: -30 deg}
  nodes:
    - {name: root, body: pendulum}
    - {name: start_seat, body: base, rotation: [0.9659258262890683, 0, 0, -0.25881904510252074]}
    - {name: catch_seat, body: base, rotation: [0.5, 0, 0, -0.8660254037844386]}
  constraints:
    - {name: hold, kind: weld, node_a: start_seat, node_b: root}
    - {name: catch, kind: weld, node_a: catch_seat, node_b: root, active: false}
events:
  on:
    - name: release
      when: {time: 200 ms}
      do: [{unlock: pendulum}]
    - name: caught
      when: {signal: multibody.pendulum.q[0], crosses: -120 deg, direction: falling}
      do: [{constraint: {add: catch}}]
    - name: let_go
      when: {time: 1.5 s}
      do: [{constraint: {remove: catch}}]
integrator: {method: rk4, step: 1 ms}
stop: {time: 2.5 s}
log: {rate: 100 Hz, signals: [multibody.pendulum.q, multibody.pendulum.u]}
"""


def test_unlock_and_a_catch_follow_the_pendulum_equation_and_lose_its_kinetic_energy(tmp_path):
    """Held at -30 deg by the weld `hold` until ``unlock`` at 0.2 s, the pendulum swings down; ``constraint: {add:
    catch}`` when it crosses -120 deg falling stops it there; ``constraint: {remove: catch}`` at 1.5 s lets it swing
    back from rest. Against the pendulum's own equation solved here,
    I_p theta'' = -m g d cos(theta) (DOP853, 1e-12): the catch time to 1e-8 s (measured 3e-13 s), the angle before
    it to 1e-8 rad (measured 8e-12 rad); the energy the catch reports equal to m g d (sin(-30 deg) - sin(-120 deg))
    to 1e-7 relative (the summary prints 9 digits; measured 3e-10) (the base is fixed to the world: the whole kinetic
    energy is lost); afterwards the pendulum at rest at -120 deg until 1.5 s, then on the equation's swing from
    there (1e-8 rad)."""
    from scipy.integrate import solve_ivp

    path = tmp_path / "pendulum.yaml"
    path.write_text(PENDULUM)
    sim = build_simulation(load_scenario(path))
    summary = sim.run(2.5, log_path=tmp_path / "p.h5")
    (t_release, first, what_first), (t_catch, second, what_second), let_go = summary.changes
    assert let_go == (1.5, "let_go", "catch off")
    assert (t_release, first, what_first) == (0.2, "release", "hold off")
    assert second == "caught" and what_second.startswith("catch on (gap ")
    m, d, g, inertia = 2.0, 1.0, 9.81, 0.5 + 2.0
    theta0, theta1 = np.radians(-30.0), np.radians(-120.0)

    def crossed(t, y):
        return y[0] - theta1
    crossed.terminal, crossed.direction = True, -1
    ode = solve_ivp(lambda t, y: [y[1], -m * g * d * np.cos(y[0]) / inertia], (0.2, 2.0), [theta0, 0.0],
                    method="DOP853", rtol=1e-12, atol=1e-12, events=crossed, dense_output=True)
    assert t_catch == pytest.approx(ode.t_events[0][0], abs=1e-8)
    log = read_log(tmp_path / "p.h5")
    t, q, u = log["time"], log["multibody.pendulum.q"][:, 0], log["multibody.pendulum.u"][:, 0]
    swinging = (t > 0.2) & (t < t_catch)
    assert np.abs(q[t <= 0.2] - theta0).max() < 1e-12
    assert np.abs(q[swinging] - ode.sol(t[swinging])[0]).max() < 1e-8
    caught = (t > t_catch) & (t <= 1.5)
    assert np.abs(q[caught] - theta1).max() < 1e-9 and np.abs(u[caught]).max() < 1e-12
    again = solve_ivp(lambda t, y: [y[1], -m * g * d * np.cos(y[0]) / inertia], (1.5, 2.5), [q[t == 1.5][0], 0.0],
                      method="DOP853", rtol=1e-12, atol=1e-12, dense_output=True)
    assert np.abs(q[t > 1.5] - again.sol(t[t > 1.5])[0]).max() < 1e-8 and q[-1] > theta1 + 0.5
    lost = float(what_second.split("kinetic energy lost ")[1].split(" J")[0])
    assert lost == pytest.approx(m * g * d * (np.sin(theta0) - np.sin(theta1)), rel=1e-7)   # printed to 8 digits


# the spring-mass cart of tests/shell/test_closure_scenes.py, undamped, leaving x = 0, with a latch to the world
CART = (SPRING_SCENE.replace("displacement: 1.5 m", "displacement: 0 m").replace("damping: 1.2 N*s/m, ", "")
        .replace("world_point: [0, 0, 0]", "world_point: [-1, 0, 0]").replace("stop: {time: 3 s}", "stop: {time: 1 s}")
        .replace("  forces:", "  constraints:\n    - {name: dock, kind: weld, node_a: hook, active: false}\n  forces:")
        + """events:
  on:
    - name: back
      when: {signal: "multibody.cart.q[0]", crosses: 0 m, direction: falling}
      do: [{attach: {body: cart, to: world}}]
""")


def test_attach_to_the_world_catches_a_cart_where_it_started():
    """A cart on a spring leaves x = 0 at 0.3 m/s and comes back after half a period, pi sqrt(m / k) = 0.628 s
    (1e-9 s; measured 3e-12 s): ``attach: {body: cart, to: world}`` switches on the weld to the world at the hook's
    initial pose, which stops it there; the energy lost is its kinetic energy 1/2 m v0^2 = 0.09 J (1e-7 relative)."""
    sim = build_simulation(parse_scenario(CART, "cart.yaml"))
    summary = sim.run(1.0)
    ((t, name, what),) = summary.changes
    assert name == "back" and t == pytest.approx(np.pi * np.sqrt(2.0 / 50.0), abs=1e-9)
    assert float(what.split("kinetic energy lost ")[1].split(" J")[0]) == pytest.approx(0.5 * 2.0 * 0.3**2, rel=1e-7)
    assert abs(sim.signal("multibody.cart.q")[0]) < 1e-12 and abs(sim.signal("multibody.cart.u")[0]) < 1e-12
