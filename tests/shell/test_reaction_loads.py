"""Reaction loads and the energy as outputs of a scene (``multibody.outputs: [hinge_load, energy]``; issue 29).

A three-body chain under gravity (two hinges about z, the last about y, offset centers of mass), a constant torque
on its middle hinge, run by ``flexshell run`` and logged:
* each ``<body>.hinge_load`` projected on its hinge's axis equals ``inverse_dynamics`` at the logged (q, u, u_dot)
  (the applied torques) to 1e-12; the tip body's full spatial load equals its own Newton-Euler balance (mass times
  the center of mass's acceleration less gravity, ``I alpha + w x I w`` and the moment of that force about the hinge)
  from the engine's node kinematics, to 1e-12;
* the ``energy`` output: its total is conserved (no dissipation: the torque's work is added back) to the RK4 error;
and the four-bar's ``pin.load`` equals the constrained forward dynamics' multipliers at the logged states (1e-12).
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np

from shell.log_file import read_log
from shell.scenario import build_root, load_scenario

ROOT = Path(__file__).resolve().parents[2]

CHAIN = """\
name: chain
multibody:
  gravity: "[0, -9.81, 0] m/s^2"
  outputs: [hinge_load, energy]
  bodies:
    - {name: a, hinge: revolute, axis: [0, 0, 1], mass: 1 kg, com: "[0.5, 0, 0] m", inertia: [0.01, 0.1, 0.1],
       initial: {angle: 0.3 rad}}
    - {name: b, parent: a, hinge: revolute, axis: [0, 0, 1], inboard_position: "[1, 0, 0] m", mass: 2 kg,
       com: "[0.5, 0.1, 0] m", inertia: [0.02, 0.2, 0.2], initial: {angle: -0.5 rad, angle_rate: 1 rad/s}}
    - {name: c, parent: b, hinge: revolute, axis: [0, 1, 0], inboard_position: "[1, 0, 0] m", mass: 0.5 kg,
       com: "[0.3, 0, 0.1] m", inertia: [0.01, 0.02, 0.03], initial: {angle: 0.2 rad}}
  nodes:
    - {name: c_cg, body: c, position: "[0.3, 0, 0.1] m"}
models:
  motor: {type: Constant, config: {unit: N*m, shape: [1]}, parameters: {value: "[0.7] N*m"}}
connections:
  - motor.y -> multibody.b.torque
integrator: {method: rk4, step: 1 ms}
stop: {time: 0.5 s}
log:
  rate: 100 Hz
  signals: [multibody.q, multibody.u, multibody.a.u_dot, multibody.b.u_dot, multibody.c.u_dot, multibody.a.hinge_load,
            multibody.b.hinge_load, multibody.c.hinge_load, multibody.energy]
"""


def _run(scene, tmp_path, *options):
    log = tmp_path / "run.h5"
    result = subprocess.run([sys.executable, "-m", "shell.cli", "run", str(scene), "-o", str(log), *options],
                            cwd=ROOT, capture_output=True, text=True, timeout=900)
    assert result.returncode == 0, result.stderr + result.stdout
    return read_log(log), result.stdout + result.stderr


def _skew(v):
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


def test_hinge_loads_of_a_chain_equal_inverse_dynamics_and_the_tip_body_balance(tmp_path):
    scene = tmp_path / "chain.yaml"
    scene.write_text(CHAIN)
    log, out = _run(scene, tmp_path)
    assert "hinge_load and energy asked for: the constrained path computes them" in out
    system = build_root(load_scenario(scene)).children["multibody"].system
    q, u = log["multibody.q"], log["multibody.u"]
    udot = np.column_stack([log[f"multibody.{b}.u_dot"] for b in "abc"])
    loads = np.stack([log[f"multibody.{b}.hinge_load"] for b in "abc"], axis=1)  # (samples, 3, 6)
    axes = np.array([[0, 0, 1], [0, 0, 1], [0, 1, 0]], dtype=float)
    m, com, inertia = 0.5, np.array([0.3, 0.0, 0.1]), np.diag([0.01, 0.02, 0.03])
    g = np.array([0.0, -9.81, 0.0])
    for k in range(len(log["time"])):
        tau = system.inverse_dynamics(q[k], u[k], udot[k])
        np.testing.assert_allclose(tau, [0.0, 0.7, 0.0], rtol=0, atol=1e-12)
        np.testing.assert_allclose(np.einsum("ij,ij->i", loads[k, :, :3], axes), tau, rtol=0, atol=1e-12)
        # the tip body c alone: its node at the center of mass, axes of the body (= its hinge's outboard frame)
        kin = system.node_kinematics(q[k], u[k], udot[k])
        R, w, alpha, a = kin.rotation[0], kin.angular_velocity[0], kin.angular_acceleration[0], \
            kin.linear_acceleration[0]
        force = m * (a - R.T @ g)  # node axes = body axes, the classical acceleration of the center of mass
        torque = inertia @ alpha + np.cross(w, inertia @ w) + np.cross(com, force)
        np.testing.assert_allclose(loads[k, 2], np.concatenate([torque, force]), rtol=0, atol=1e-12)
    energy = log["multibody.energy"]
    np.testing.assert_allclose(energy[:, 3], energy[:, :3].sum(axis=1), rtol=0, atol=1e-12)
    work = np.concatenate([[0.0], np.cumsum(0.7 * 0.5 * (u[1:, 1] + u[:-1, 1]) * np.diff(log["time"]))])
    assert abs(energy[-1, 3] - energy[0, 3] - work[-1]) < 1e-3  # the torque's work, by the trapezoid at 10 ms


def test_a_constraint_load_equals_the_multipliers(tmp_path):
    """configs/four_bar.yaml run 0.2 s: the logged ``pin.load`` equals the constrained forward dynamics' load at the
    logged state (1e-12 relative to its size) and its selected rows are the multipliers."""
    from shell.scenario import build_simulation

    log, _ = _run(ROOT / "configs" / "four_bar.yaml", tmp_path, "--set", "stop.time=0.2 s")
    constrained = build_simulation(load_scenario(ROOT / "configs" / "four_bar.yaml")).diagram.models[0].constrained
    q = np.column_stack([log[f"multibody.{b}.q"] for b in ("crank", "coupler", "rocker")])
    assert "multibody.pin.load" in log
    for k in range(len(log["time"])):
        u = np.array([log["multibody.crank.u"][k, 0], *_velocities(constrained, q[k], log["multibody.crank.u"][k, 0])])
        acc = constrained.forward_dynamics(q[k], u)
        load = log["multibody.pin.load"][k]
        scale = np.abs(load).max()
        np.testing.assert_allclose(load, acc.loads[0], rtol=0, atol=1e-12 * scale)
        selection = constrained.constraints[0].selection
        np.testing.assert_allclose(selection @ load, acc.multipliers[0], rtol=0, atol=1e-12 * scale)


def _velocities(constrained, q, crank_rate):
    """The coupler's and rocker's rates that close the loop with the crank's (G u = 0)."""
    G = constrained.jacobian(q)
    return np.linalg.lstsq(G[:, 1:], -G[:, 0] * crank_rate, rcond=None)[0]
