"""Linearize and trim on the constraint manifold, through ``flexshell linearize`` (issue 29).

The references are one-DOF Lagrangian derivations in SymPy, independent of the engine: the crank angle ``theta`` is
the coordinate, the other bodies' positions and angles are the closed-form loop closures (circle intersection for the
four-bar, the slider on its axis for the slider-crank), ``T = 1/2 m(theta) theta'^2`` from the bodies' center-of-mass
velocities and spins, ``V(theta)`` from gravity. An equilibrium ``V'(theta*) = 0`` is found with mpmath at 30
digits; small oscillations have ``omega^2 = V''(theta*) / m(theta*)`` and the other hinges follow the crank with
``d angle / d theta``. The scene's minimal model (two states: the crank's angle and rate) must reproduce them.

Tolerance: the linearization's truncation error at ``--tolerance 1e-12`` (four points, Richardson) is estimated by
the model itself (``errors``); a frequency error ``|d omega| / omega = |d A21| / (2 |A21|)`` below 1e-8 is what that
estimate bounds (measured 4e-10 on the four-bar).
"""

from __future__ import annotations

import subprocess
import sys
from functools import lru_cache
from pathlib import Path

import numpy as np
import pytest

from shell.analysis.linear_model_file import read_linear_model
from shell.analysis.system_modes import state_space_modes

ROOT = Path(__file__).resolve().parents[2]
CONFIGS = ROOT / "configs"


@lru_cache(maxsize=None)
def _one_dof(mechanism: str, guess: float):
    """(theta*, omega^2, [d angle / d theta of each further hinge's angle], [those angles], m(theta*)) of a mechanism
    of tests/dynamics/mechanisms.py about the equilibrium near ``guess`` (module docstring)."""
    import mpmath as mp
    import sympy as sp

    th = sp.Symbol("theta")
    R = sp.Rational
    g = R(981, 100)

    def izz(length, mass):  # slender rod about its CG, + 1e-3 (tests/dynamics/mechanisms.rod)
        return mass * length ** 2 / 12 + R(1, 1000)

    A = sp.Matrix([sp.cos(th), sp.sin(th)])  # crank tip (crank 1 m from the origin)
    if mechanism.startswith("four_bar"):  # coupler 3 m, rocker 2.5 m pivoting at (3, 0)
        # the configs' branch: the coupler's end left of the line from the crank's tip to the rocker's pivot
        branch = -1 if mechanism == "four_bar_mirrored" else 1
        D = sp.Matrix([3, 0])
        dv = D - A
        dist = sp.sqrt(dv.dot(dv))
        ev = dv / dist
        along = (9 - R(25, 4) + dist ** 2) / (2 * dist)
        B = A + along * ev + branch * sp.sqrt(9 - along ** 2) * sp.Matrix([-ev[1], ev[0]])
        coupler = sp.atan2(B[1] - A[1], B[0] - A[0])
        rocker = sp.atan2(B[1], B[0] - 3)
        bodies = [(1, A / 2, th, izz(1, 1)), (2, A + R(3, 2) * sp.Matrix([sp.cos(coupler), sp.sin(coupler)]), coupler,
                                              izz(3, 2)),
                  (R(3, 2), D + R(5, 4) * sp.Matrix([sp.cos(rocker), sp.sin(rocker)]), rocker, izz(R(5, 2), R(3, 2)))]
        relative = [coupler - th, rocker]
    else:  # slider-crank: rod 3 m, a 2 kg slider on the x axis that does not turn
        root = sp.sqrt(9 - sp.sin(th) ** 2)
        B = sp.Matrix([sp.cos(th) + root, 0])
        rod = sp.atan2(-sp.sin(th), root)
        bodies = [(1, A / 2, th, izz(1, 1)), (2, (A + B) / 2, rod, izz(3, 2)), (2, B, sp.Integer(0), R(3, 100))]
        relative = [rod - th, -rod]
    V = sum(m * g * r[1] for m, r, _, _ in bodies)
    M = sum(m * sp.diff(r, th).dot(sp.diff(r, th)) + inertia * sp.diff(angle, th) ** 2
            for m, r, angle, inertia in bodies)
    mp.mp.dps = 30
    f = {name: sp.lambdify(th, e, "mpmath") for name, e in
         (("dV", sp.diff(V, th)), ("d2V", sp.diff(V, th, 2)), ("M", M))}
    theta = mp.findroot(f["dV"], guess)
    omega2 = f["d2V"](theta) / f["M"](theta)
    ratios = [float(sp.lambdify(th, sp.diff(a, th), "mpmath")(theta)) for a in relative]
    angles = [float(sp.lambdify(th, a, "mpmath")(theta)) for a in relative]
    return float(theta), float(omega2), ratios, angles, float(f["M"](theta))


def _linearize(tmp_path, config, *options):
    out = tmp_path / "lin.h5"
    result = subprocess.run([sys.executable, "-m", "shell.cli", "linearize", str(config), "-o", str(out), *options],
                            cwd=ROOT, capture_output=True, text=True, timeout=900)
    assert result.returncode == 0, result.stderr + result.stdout
    return read_linear_model(out), result.stdout


def _at_rest(body, angle):
    return ["--set", f"multibody.{body}.initial={{angle: {angle!r} rad, angle_rate: 0 rad/s}}"]


@pytest.mark.parametrize("config, bodies, guess", [
    ("four_bar", ("crank", "coupler", "rocker"), -1.8),
    ("slider_crank", ("crank", "rod", "slider"), -1.5),
])
def test_a_closed_loop_linearizes_to_its_one_dof_small_oscillation(tmp_path, config, bodies, guess):
    """The four-bar and the slider-crank configs started at rest at their hanging equilibrium (``--set``, the
    derivation's angles: the slider's guide is horizontal because it takes the slider's initial pose), trimmed (``--trim``) and linearized from the crank's torque to the other hinges'
    angles: two states (the crank's angle and rate, no spurious zero or constraint modes), ``omega`` equal to the
    SymPy derivation to 1e-8 relative (module docstring; measured 4e-10), the other hinges' output rows the loop
    closure's ``d angle / d theta`` and the torque's input column ``1 / m(theta*)`` (1e-8 relative). The 3D view of
    the four-bar's mode moves the dependent hinges with the crank: the loop is closed in every frame (1e-12 m)."""
    theta, omega2, ratios, angles, mass = _one_dof(config, guess)
    start = [option for body, angle in zip(bodies, [theta] + angles) for option in _at_rest(body, angle)]
    model, out = _linearize(tmp_path, CONFIGS / f"{config}.yaml", *start, "--trim", "--tolerance", "1e-12",
                            "--inputs", f"multibody.{bodies[0]}.torque",
                            "--outputs", ",".join(f"multibody.{b}.q" for b in bodies))
    assert "trim converged" in out
    assert model.state_names == ["multibody.q[0]", "multibody.u[0]"]
    A, B, C = model.A, model.B, model.C
    assert abs(model.operating_point["x"][0] - theta) < 1e-12
    assert abs(np.sqrt(-A[1, 0]) / np.sqrt(omega2) - 1.0) < 1e-8
    assert abs(A[1, 0] + omega2) < 20 * model.errors["A"][1, 0]  # the model's own estimate bounds its error
    assert np.abs(A - [[0.0, 1.0], [A[1, 0], 0.0]]).max() < 1e-9
    modes = state_space_modes(A)
    assert modes.n_rigid == 0 and modes.real_eigenvalues.size == 0 and modes.frequencies_hz.size == 1
    assert np.abs(C[:, 0] - ([1.0] + ratios)).max() < 1e-8 and np.abs(C[:, 1]).max() < 1e-9
    assert abs(B[0, 0]) < 1e-9 and abs(B[1, 0] * mass - 1.0) < 1e-8
    if config == "four_bar":  # flexshell view LIN.h5 --mode 1: the loop stays closed in every frame
        from shell.view.scene import from_linear_model

        view = from_linear_model(tmp_path / "lin.h5", 1)
        ends = {node["name"]: node["position"] for node in view.nodes}
        assert np.abs(ends["coupler_end"] - ends["rocker_end"]).max() < 1e-12
        assert np.ptp(ends["rocker_end"], axis=0).max() > 1e-2
        assert view.time[1] * len(view.time) == pytest.approx(2 * np.pi / np.sqrt(omega2), rel=1e-8)


def test_trim_of_a_moving_four_bar_finds_the_mirror_equilibrium(tmp_path):
    """configs/four_bar.yaml as written (the crank at 60 deg turning at 6 rad/s) trimmed: the rates vanish at the
    inverted equilibrium, the mirror image of the lower branch's hanging one (theta = +1.4554 rad), whose linear
    model is the saddle ``A21 = +omega^2`` of that SymPy equilibrium; the loop is closed at the trim state. Holding a
    dependent coordinate is refused, naming the minimal ones."""
    from shell.scenario import build_simulation, load_scenario

    model, out = _linearize(tmp_path, CONFIGS / "four_bar.yaml", "--trim", "--tolerance", "1e-12",
                            "--inputs", "multibody.crank.torque", "--outputs", "multibody.crank.q")
    theta, omega2, _, _, _ = _one_dof("four_bar_mirrored", -1.45)  # the other branch hanging, mirrored
    assert "trim converged" in out
    x = model.operating_point["x"]
    assert abs(x[0] + theta) < 1e-9
    assert abs(model.A[1, 0] / omega2 - 1.0) < 1e-8
    sim = build_simulation(load_scenario(CONFIGS / "four_bar.yaml"))
    constrained = sim.diagram.models[0].constrained
    assert np.abs(constrained.residual(x[:3])).max() < 1e-13 and np.abs(constrained.velocity_residual(
        x[:3], x[3:])).max() < 1e-13
    from shell.analysis.linearize import LinearizationError
    from shell.analysis.trim import trim

    with pytest.raises(LinearizationError, match=r"'multibody.q\[2\]' is a dependent coordinate of a closed loop"):
        trim(sim, hold=["multibody.q[2]"])


def test_a_spring_damper_linearizes_to_its_frequency_and_damping_ratio(tmp_path):
    """The cart of tests/shell/test_closure_scenes.py (2 kg on a prismatic hinge, a 50 N/m, 1.2 N s/m spring-damper to
    the world origin) through ``flexshell linearize``: one mode with ``omega_n = sqrt(k / m)`` and ``zeta = c / (2
    sqrt(k m))`` to 1e-10 (the force is linear in the displacement and rate along the line: the central differences
    are exact to round-off); the force element adds no state and removes none."""
    from tests.shell.test_closure_scenes import SPRING_SCENE

    scene = tmp_path / "spring.yaml"
    scene.write_text(SPRING_SCENE)
    model, _ = _linearize(tmp_path, scene, "--inputs", "multibody.cart.torque", "--outputs", "multibody.cart.q")
    assert model.state_names == ["multibody.q", "multibody.u"]
    modes = state_space_modes(model.A)
    m, k, c = 2.0, 50.0, 1.2
    assert abs(modes.frequencies_hz[0] * 2 * np.pi - np.sqrt(k / m)) < 1e-10
    assert abs(modes.damping_ratios[0] - c / (2 * np.sqrt(k * m))) < 1e-10
    assert abs(model.B[1, 0] - 1 / m) < 1e-12


SAMPLED = """\
name: four_bar_sampled
multibody:
  gravity: "[0, -9.81, 0] m/s^2"
  bodies:
    - {{name: crank, hinge: revolute, axis: [0, 0, 1], mass: 1 kg, com: "[0.5, 0, 0] m",
       inertia: "[0.001, 0.08333333333333333, 0.08433333333333333] kg*m^2", initial: {{angle: {0!r} rad}}}}
    - {{name: coupler, parent: crank, hinge: revolute, axis: [0, 0, 1], inboard_position: "[1, 0, 0] m", mass: 2 kg,
       com: "[1.5, 0, 0] m", inertia: "[0.001, 1.5, 1.501] kg*m^2", initial: {{angle: {1!r} rad}}}}
    - {{name: rocker, parent: world, hinge: revolute, axis: [0, 0, 1], inboard_position: "[3, 0, 0] m", mass: 1.5 kg,
       com: "[1.25, 0, 0] m", inertia: "[0.001, 0.78125, 0.78225] kg*m^2", initial: {{angle: {2!r} rad}}}}
  nodes:
    - {{name: coupler_end, body: coupler, position: "[3, 0, 0] m"}}
    - {{name: rocker_end, body: rocker, position: "[2.5, 0, 0] m"}}
  constraints:
    - {{name: pin, kind: revolute, node_a: coupler_end, node_b: rocker_end, axis: [0, 0, 1]}}
models:
  hold: {{type: SampleHold, rate: 10 Hz, config: {{unit: rad, shape: [1]}}}}
  gain: {{type: Gain, config: {{unit: rad, output_unit: N*m, shape: [1]}}, parameters: {{k: 0 N*m/rad}}}}
connections:
  - multibody.crank.q -> hold.u
  - hold.y -> gain.u
  - gain.y -> multibody.crank.torque
integrator: {{method: rk4, step: 1 ms}}
stop: {{time: 1 s}}
"""


def test_the_sampled_map_of_a_closed_loop_has_its_minimal_coordinates_only(tmp_path):
    """The four-bar at rest at its hanging equilibrium with a 10 Hz sample-and-hold of the crank angle (the loop's
    gain zero): ``flexshell linearize --sampled`` gives the period map in the crank's angle and rate and the hold's
    states, the mechanism's pair of eigenvalues ``exp(+-i omega T)`` with the SymPy omega (1e-8; RK4 at 1 ms over
    0.1 s) and no eigenvalue of the constraint directions."""
    theta, omega2, _, angles, _ = _one_dof("four_bar", -1.8)
    scene = tmp_path / "sampled.yaml"
    scene.write_text(SAMPLED.format(theta, *angles))
    model, _ = _linearize(tmp_path, scene, "--sampled")
    assert model.state_names == ["multibody.q[0]", "multibody.u[0]", "hold.held", "hold.samples"]
    mechanism = np.linalg.eigvals(model.A[:2, :2])
    expected = np.exp(1j * np.sqrt(omega2) * 0.1)
    assert np.abs(np.sort_complex(mechanism) - np.sort_complex([expected.conjugate(), expected])).max() < 1e-8
    assert np.abs(model.A[:2, 2:]).max() == 0.0  # the held angle reaches the crank through a zero gain
