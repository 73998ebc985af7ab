"""Closed loops declared in a scenario (``multibody.constraints:``) and run through ``flexshell run``.

The shipped configs configs/four_bar.yaml and configs/slider_crank.yaml, run by the command line (RK4, 1 ms,
projection after each step), against the independent absolute-coordinate DAE solutions of
tests/dynamics/test_closure_mechanisms.py (three free planar bodies pinned together, their own constraint
equations and Baumgarte-stabilized index-1 solve, DOP853 at 1e-10); the constraint load port against the
rocker's own Newton-Euler balance; the refusals of bad constraints with file, line and key; the assembly of an
initial state near the loop and the refusal of one far from it.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from shell.log_file import read_log
from shell.scenario import build_root, load_scenario
from shell.schema.document import ScenarioError
from tests.dynamics.mechanisms import (ANDREWS_ORDER, ANDREWS_REFERENCE, COUPLER, CRANK, FOUR_BAR_MASSES, ROCKER,
                                       ROD_LENGTH)
from tests.dynamics.test_closure_mechanisms import (TIGHT, e, e_rate, four_bar_absolute, four_bar_dae, izz,
                                                    slider_crank_dae)

ROOT = Path(__file__).resolve().parents[2]
CONFIGS = ROOT / "configs"


def _run(config, tmp_path):
    log = tmp_path / f"{config}.h5"
    result = subprocess.run([sys.executable, "-m", "shell.cli", "run", str(CONFIGS / f"{config}.yaml"), "-o", str(log)],
                            cwd=ROOT, capture_output=True, text=True, timeout=900)
    assert result.returncode == 0, result.stderr + result.stdout
    return read_log(log), result.stdout + result.stderr


def test_four_bar_config_equals_the_absolute_coordinate_dae(tmp_path):
    """configs/four_bar.yaml through ``flexshell run``: crank, coupler and rocker angles equal the DAE's to 1e-6 rad
    over 2 s while the crank turns 2.1 times; the loop stays closed to 1e-9 m; the pin's load port satisfies the
    rocker's moment balance about its ground pivot (with the DAE's acceleration) to 1e-5 N m (measured 8e-7 N m
    for moments up to ~300 N m: the two solutions' states differ by ~2e-9 rad; angles measured 1.8e-9 rad)."""
    log, out = _run("four_bar", tmp_path)
    assert "closure constraints pin (revolute)" in out
    t = log["time"]
    q = np.column_stack([log["multibody.crank.q"], log["multibody.coupler.q"], log["multibody.rocker.q"]])
    u0 = np.array([6.0, -7.184064806160739, 1.3046192611922818])
    z0, zd0 = four_bar_absolute(q[0], u0)
    mech = four_bar_dae()
    dae = solve_ivp(mech.rates, (0.0, t[-1]), np.concatenate([z0, zd0]), t_eval=t, **TIGHT)
    angles = np.column_stack([q[:, 0], q[:, 0] + q[:, 1], q[:, 2]])
    assert np.abs(angles - dae.y[[2, 5, 8]].T).max() < 1e-6
    assert q[-1, 0] - q[0, 0] > 2 * 2 * np.pi
    coupler_end = CRANK * e(angles[:, 0].T).T + COUPLER * e(angles[:, 1].T).T
    rocker_end = np.array([3.0, 0.0]) + ROCKER * e(angles[:, 2].T).T
    assert np.abs(coupler_end - rocker_end).max() < 1e-9
    # the load of the coupler's end on the rocker's (coupler axes, at the rocker's end): rocker about its pivot
    m3, g = FOUR_BAR_MASSES[2], 9.81
    load = log["multibody.pin.load"]
    for k in range(len(t)):
        th2, th3 = dae.y[5, k], dae.y[8, k]
        force = np.array([[np.cos(th2), -np.sin(th2)], [np.sin(th2), np.cos(th2)]]) @ load[k, 3:5]
        alpha3 = mech.rates(t[k], dae.y[:, k])[17]
        moment = ROCKER * (np.cos(th3) * force[1] - np.sin(th3) * force[0]) - m3 * g * ROCKER / 2 * np.cos(th3)
        assert abs((izz(ROCKER, m3) + m3 * ROCKER ** 2 / 4) * alpha3 - moment) < 1e-5


def test_slider_crank_config_equals_the_absolute_coordinate_dae(tmp_path):
    """configs/slider_crank.yaml through ``flexshell run``: crank angle and slider position equal the DAE's to
    1e-6 (rad, m) over 3 s while the crank turns 3.4 times (measured 1.5e-8 rad, 5.5e-9 m); the slider stays on
    its axis without turning (1e-9; measured 7.9e-11 m)."""
    log, _ = _run("slider_crank", tmp_path)
    t = log["time"]
    q = np.column_stack([log["multibody.crank.q"], log["multibody.rod.q"], log["multibody.slider.q"]])
    u = np.array([5.0, -5.870388279778487, 0.8703882797784883])
    th1, th2 = q[0, 0], q[0, 0] + q[0, 1]
    w1, w2 = u[0], u[0] + u[1]
    z0 = np.concatenate([CRANK / 2 * e(th1), [th1], CRANK * e(th1) + ROD_LENGTH / 2 * e(th2), [th2],
                         CRANK * e(th1) + ROD_LENGTH * e(th2), [th2 + q[0, 2]]])
    zd0 = np.concatenate([CRANK / 2 * w1 * e_rate(th1), [w1],
                          CRANK * w1 * e_rate(th1) + ROD_LENGTH / 2 * w2 * e_rate(th2), [w2],
                          CRANK * w1 * e_rate(th1) + ROD_LENGTH * w2 * e_rate(th2), [w2 + u[2]]])
    dae = solve_ivp(slider_crank_dae().rates, (0.0, t[-1]), np.concatenate([z0, zd0]), t_eval=t, **TIGHT)
    assert np.abs(q[:, 0] - dae.y[2]).max() < 1e-6
    pin = log["multibody.slider_pin.position"]
    assert np.abs(pin[:, 0] - dae.y[6]).max() < 1e-6
    assert np.abs(pin[:, 1:]).max() < 1e-9 and np.abs(q.sum(axis=1)).max() < 1e-9
    assert q[-1, 0] - q[0, 0] > 1.5 * 2 * np.pi


FOUR_BAR = (CONFIGS / "four_bar.yaml").read_text()
PIN = "    - {name: pin, kind: revolute, node_a: coupler_end, node_b: rocker_end, axis: [0, 0, 1]}\n"


def _scene(tmp_path, text):
    path = tmp_path / "scene.yaml"
    path.write_text(text)
    return build_root(load_scenario(path))


def _line_of(text, fragment):
    return text.splitlines().index(fragment.rstrip("\n")) + 1


@pytest.mark.parametrize("entry, key, message", [
    ("{name: pin, kind: revolute, node_a: coupler_tip, node_b: rocker_end, axis: [0, 0, 1]}", "node_a",
     "unknown node 'coupler_tip'"),
    ("{name: pin, kind: revolute, node_a: coupler_end, node_b: rocker_end, axis: [0, 0, 1]}", "node_b",
     "both on the rigid body 'coupler'"),
    ("{name: pin, kind: hinge, node_a: coupler_end, node_b: rocker_end}", "kind", "unknown constraint kind"),
    ("{name: pin, kind: revolute, node_a: coupler_end, node_b: rocker_end}", "", "missing required key 'axis'"),
    ("{name: pin, kind: prismatic, node_a: coupler_end, node_b: rocker_end}", "", "missing required key 'axis'"),
    ("{name: pin, kind: revolute, node_a: coupler_end, node_b: rocker_end, axis: [0, 0, 2]}", "axis", "unit"),
    ("{name: pin, kind: distance, node_a: coupler_end, node_b: rocker_end, length: 0 m}", "length",
     "positive length"),
    ("{name: pin, kind: distance, node_a: coupler_end, node_b: rocker_end, length: -1 m}", "length",
     "positive length"),
    ("{name: pin, kind: ball, node_a: coupler_end, node_b: rocker_end, length: 1 m}", "length", "takes no length"),
    ("{name: pin, kind: weld, node_a: coupler_end, axis: [0, 0, 1]}", "axis", "takes no axis"),
    ("{name: pin, kind: ball, node_a: coupler_end, node_b: rocker_end, stiffness: 1}", "", "stiffness"),
])
def test_bad_constraints_are_refused_with_file_line_and_key(tmp_path, entry, key, message):
    text = FOUR_BAR.replace(PIN, f"    - {entry}\n")
    if "both on the rigid body" in message:
        text = text.replace("- {name: rocker_end, body: rocker,", "- {name: rocker_end, body: coupler,")
    with pytest.raises(ScenarioError) as caught:
        _scene(tmp_path, text)
    where = f"scene.yaml:{_line_of(text, f'    - {entry}')}: multibody.constraints[0]"
    assert where in str(caught.value) and f"{key}:" in str(caught.value).split(where)[1][:20 + len(key)]
    assert message in str(caught.value)


def test_an_initial_state_near_the_loop_is_assembled_and_one_far_from_it_refused(tmp_path):
    """The rocker written 1e-7 rad off the loop: projected onto it (the run's notes say by how much);
    1e-3 rad off: refused at the constraint that is violated, naming the residual; with assembly_tolerance
    raised, projected."""
    near = FOUR_BAR.replace("angle: 1.564393222865947 rad", "angle: 1.564393322865947 rad")
    model = _scene(tmp_path, near).children["multibody"]
    assert 5e-8 < model.assembly.residual < 5e-7 and model.assembly.worst == "pin"
    assert abs(model.constrained.worst_residual(model.initial_continuous_state()[:3])[0]) < 1e-12
    assert any("initial state assembled" in note for note in model.notes)
    far = FOUR_BAR.replace("angle: 1.564393222865947 rad", "angle: 1.565393222865947 rad")
    with pytest.raises(ScenarioError) as caught:
        _scene(tmp_path, far)
    assert f"scene.yaml:{_line_of(far, PIN)}: multibody.constraints[0](pin): the initial state violates" in str(
        caught.value)
    lifted = far.replace("  constraints:\n", "  assembly_tolerance: 0.01\n  constraints:\n")
    assert _scene(tmp_path, lifted).children["multibody"].assembly.residual > 1e-3


def test_a_projection_that_cannot_close_the_loop_stops_the_run_with_the_reason(tmp_path):
    """A distance constraint whose length no configuration reaches (set in the run's data after assembly): the
    projection after a step fails, the velocities become NaN and the model says why (the simulation reports it)."""
    from dynamics import constraint_kernels as CK

    text = FOUR_BAR.replace(PIN, "    - {name: rod, kind: distance, node_a: coupler_end, node_b: rocker_end, "
                                 "length: 0.5 m}\n").replace("  constraints:\n", "  assembly_tolerance: 10\n"
                                                                                   "  constraints:\n")
    model = _scene(tmp_path, text).children["multibody"]
    model.configure()
    _, data = model.create_data(own=True)
    assert model.failure_message(data) is None
    data[3].data.c_float[0, CK.C_LENGTH] = 100.0  # farther than the two ends can be apart
    x = model.initial_continuous_state().copy()
    model.normalize_state(x, data)
    assert np.isnan(x[3:]).all() and "projection onto the closure constraints did not converge" in \
        model.failure_message(data)


SPRING_SCENE = """\
name: spring_mass
multibody:
  bodies:
    - {name: cart, hinge: prismatic, axis: [1, 0, 0], mass: 2 kg, inertia: [1, 1, 1],
       initial: {displacement: 1.5 m, displacement_rate: 0.3 m/s}}
  nodes:
    - {name: hook, body: cart}
  forces:
    - {name: spring, kind: spring_damper, node_a: hook, world_point: [0, 0, 0], stiffness: 50 N/m,
       damping: 1.2 N*s/m, free_length: 1 m}
integrator: {method: rk4, step: 1 ms}
stop: {time: 3 s}
log: {rate: 20 Hz, signals: [multibody.cart.q, multibody.cart.u]}
"""


def test_a_spring_damper_in_a_scenario_is_the_damped_oscillator(tmp_path):
    """A 2 kg cart on a prismatic hinge tied to the world origin by a spring-damper (50 N/m, 1.2 N s/m, free
    length 1 m), run by ``flexshell run``: its displacement is the analytic damped oscillation about 1 m to 1e-9 m."""
    scene = tmp_path / "spring.yaml"
    scene.write_text(SPRING_SCENE)
    result = subprocess.run([sys.executable, "-m", "shell.cli", "run", str(scene), "-o", str(tmp_path / "s.h5")],
                            cwd=ROOT, capture_output=True, text=True, timeout=900)
    assert result.returncode == 0, result.stderr + result.stdout
    assert "force elements spring" in result.stdout + result.stderr
    log = read_log(tmp_path / "s.h5")
    t, x = log["time"], log["multibody.cart.q"][:, 0]
    m, k, c, x0, v0 = 2.0, 50.0, 1.2, 0.5, 0.3
    zeta_w, wd = c / (2 * m), np.sqrt(k / m - (c / (2 * m)) ** 2)
    exact = 1.0 + np.exp(-zeta_w * t) * (x0 * np.cos(wd * t) + (v0 + zeta_w * x0) / wd * np.sin(wd * t))
    assert np.abs(x - exact).max() < 1e-9


@pytest.mark.parametrize("change, key, message", [
    ("kind: spring_damper", "kind", "unknown force element kind 'spring'"),
    ("node_a: hook", "node_a", "unknown node 'hock'"),
    ("damping: 1.2 N*s/m", "damping", "expected a value >= 0"),
])
def test_bad_force_elements_are_refused_with_file_line_and_key(tmp_path, change, key, message):
    wrong = {"kind": "kind: spring", "node_a": "node_a: hock", "damping": "damping: -1 N*s/m"}[key]
    text = SPRING_SCENE.replace(change, wrong)
    with pytest.raises(ScenarioError) as caught:
        _scene(tmp_path, text)
    assert f"multibody.forces[0](spring).{key}: {message}" in str(caught.value)
    line = next(n for n, row in enumerate(text.splitlines(), 1) if wrong in row)
    assert f"scene.yaml:{line}:" in str(caught.value)


def test_andrews_squeezing_mechanism_config_reaches_the_published_reference(tmp_path):
    """configs/mechanisms/andrews_squeezer.yaml (three loops closed at one point, the spring and the motor torque
    from a Constant model) through ``flexshell run``, RK4 at 2 us: the seven angles at t = 0.03 s equal the test
    set's reference (PSIDE at 1e-14) to 1e-8 rad (measured 1.4e-9 rad; beta has turned 2.5 revolutions)."""
    log = tmp_path / "andrews.h5"
    result = subprocess.run([sys.executable, "-m", "shell.cli", "run",
                             str(CONFIGS / "mechanisms" / "andrews_squeezer.yaml"), "-o", str(log)],
                            cwd=ROOT, capture_output=True, text=True, timeout=900)
    assert result.returncode == 0, result.stderr + result.stdout
    data = read_log(log)
    assert data["time"][-1] == pytest.approx(0.03, abs=1e-12)
    q = data["multibody.q"][-1]
    assert np.abs(q[list(ANDREWS_ORDER)] - np.array(ANDREWS_REFERENCE)).max() < 1e-8


def test_andrews_squeezing_mechanism_runs_compiled_and_interpreted_identically(tmp_path):
    """The configs/mechanisms scene is not in test_compiled_loop.py's set (it would run 3 s at 2 us): its two loops
    over 2 ms (1000 steps) end in the same state bit for bit, logs included."""
    from tests.shell.test_compiled_loop import _assert_same_run, _build

    scenario = load_scenario(CONFIGS / "mechanisms" / "andrews_squeezer.yaml", ["stop.time=2 ms"])
    runs = {}
    for mode in ("interpreted", "compiled"):
        sim = _build(scenario, mode)
        sim.run(scenario.t_final, log_path=tmp_path / f"{mode}.h5")
        runs[mode] = sim
    assert runs["compiled"].mode == "compiled", runs["compiled"].interpreted_reason
    _assert_same_run(runs["interpreted"], runs["compiled"], tmp_path / "interpreted.h5", tmp_path / "compiled.h5")
