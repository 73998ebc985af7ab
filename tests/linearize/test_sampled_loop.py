"""Issue 30 item 3: the sampled closed-loop linear model (``flexshell linearize --sampled``,
:mod:`shell.analysis.sampled_loop`) against independent references.

* A linear plant and a linear sampled controller (a rigid bus on a revolute hinge, a sampled StateSpace PD by
  backward difference, a two-sample delay line): the model equals the one built by hand from python-control's
  ``c2d`` (zero-order hold) of J theta'' = tau composed with the controller's and the delay line's updates.
  One rate, and the delay line at twice the controller's rate (multi-rate); over two periods the square. The
  period map is linear here and RK4 integrates a constant torque exactly, so central differences are exact up to
  round-off (the bound on it: entries ~3e3, steps ~2e-2, 16 eps 3e3 / 2e-2 ~ 5e-11); tolerance 1e-9 relative to
  the largest entry, measured 1.4e-17 absolute (4.5e-21 relative).
* configs/sampled/pd_axis.yaml (the demo's quaternion PD at 10 Hz behind a one-sample delay): the least-stable
  eigenvalue pair against the decay of the nonlinear loop's logged angle from 1 deg, fitted independently of the
  model (Prony: theta[k+2] = a1 theta[k+1] + a0 theta[k] by least squares over samples 30..280, the roots of
  z^2 - a1 z - a0). Measured: decay rate to 1.1e-6 relative, which scales with the square of the amplitude
  (1.1e-8 at 0.1 deg, 2.7e-5 at 5 deg): the PD's error 2 sin(theta/2) departs from theta by theta^2/24 =
  1.3e-5 at 1 deg; tolerance 1e-5.
* The gain sweep: kp scaled by ``--set``; the critical kp where the spectral radius crosses 1 (bisection on the
  model) within 1 % of the nonlinear loop's stability boundary (bisection on runs from 1 deg: the late envelope
  growing or shrinking); measured 1887.23 against 1887.21..1887.33 (6e-5); and through the command line: at
  0.99 and 1.01 times the critical gain the printed spectral radius is below and above 1 and the logged angle
  decays and grows.
* Refusals: no sampled model, a period that is not a multiple of every rate, a time that is no sample instant,
  options that do not go together.
"""

from __future__ import annotations

import re
import textwrap
from pathlib import Path

import numpy as np
import pytest
import yaml

from shell.analysis.linear_model_file import read_linear_model
from shell.analysis.linearize import LinearizationError
from shell.analysis.sampled_loop import loop_eigenvalues, sampled_linearize, spectral_radius
from shell.cli import main
from shell.log_file import read_log
from shell.scenario import build_simulation, load_scenario

REPO = Path(__file__).resolve().parents[2]
PD_AXIS = REPO / "configs/sampled/pd_axis.yaml"
T, J = 0.1, 250.0
KP, KD = 100.0, 300.0  # the linear scene's PD: tau = -KP theta - KD (theta_k - theta_k-1) / T



def linear_scene(path):
    """configs/sampled/pd_axis.yaml's plant (J = 250 kg m^2 about the hinge) under a linear sampled controller:
    a StateSpace PD by backward difference behind a two-sample delay line."""
    scene = yaml.safe_load(PD_AXIS.read_text())
    scene["models"] = {
        "controller": {"type": "StateSpace", "rate": "10 Hz",
                       "config": {"A": [[0.0]], "B": [[1.0]], "C": [[KD / T]], "D": [[-(KP + KD / T)]],
                                  "input_unit": "rad", "output_unit": "N*m"}},
        "delay": {"type": "Delay", "rate": "10 Hz", "config": {"samples": 2, "unit": "N*m", "shape": [1]}}}
    scene["connections"] = ["multibody.bus.q -> controller.u", "controller.y -> delay.u",
                            "delay.y -> multibody.bus.torque"]
    scene["log"]["signals"] = ["multibody.bus.q"]
    path.write_text(yaml.safe_dump(scene))
    return path


def linearize_cli(capsys, *arguments) -> tuple[int, str, str]:
    capsys.readouterr()
    code = main(["linearize", *map(str, arguments)])
    out = capsys.readouterr()
    return code, out.out, out.err


def hand_model(delay_period=T):
    """The period map of the linear scene by hand, in the model's coordinates (theta, omega, controller x,
    x_sampled, u_sampled, delay y, buffer oldest, buffer newest), from just after the updates at t_k: products of
    the plant's flow over each stretch between samples (python-control's ``c2d``, zero-order hold of
    J theta'' = tau under the delay's held output) and the updates at its end, the controller first (dataflow
    order: x_sampled = x, u_sampled = theta, x = a x + b theta; its output c x_sampled + d u_sampled, held) then
    the delay line (y = oldest, oldest = newest, newest = the controller's output)."""
    control = pytest.importorskip("control")
    a, b, c, d = 0.0, 1.0, KD / T, -(KP + KD / T)

    def flow(h):
        plant = control.c2d(control.ss([[0.0, 1.0], [0.0, 0.0]], [[0.0], [1.0 / J]], np.eye(2), np.zeros((2, 1))),
                            h, method="zoh")
        F = np.eye(8)
        F[0:2, 0:2], F[0:2, 5] = np.asarray(plant.A), np.asarray(plant.B)[:, 0]
        return F

    controller = np.eye(8)
    controller[2:5] = 0.0
    controller[3, 2], controller[4, 0], controller[2, 2], controller[2, 0] = 1.0, 1.0, a, b
    delay = np.eye(8)
    delay[5:8] = 0.0
    delay[5, 6], delay[6, 7], delay[7, 3], delay[7, 4] = 1.0, 1.0, c, d
    M = np.eye(8)
    for k in range(round(T / delay_period)):  # the delay's samples in (t_k, t_k + T]; the controller's at the end
        M = delay @ (controller if k == round(T / delay_period) - 1 else np.eye(8)) @ flow(delay_period) @ M
    return M


@pytest.mark.parametrize("delay_rate", ["10 Hz", "20 Hz"])
def test_linear_loop_equals_the_zero_order_hold_model_built_by_hand(tmp_path, capsys, delay_rate):
    """One rate, and the delay line at twice the controller's rate (multi-rate: two stretches per period)."""
    scene = linear_scene(tmp_path / "linear.yaml")
    code, out, err = linearize_cli(capsys, scene, "--sampled", "-o", tmp_path / "m.h5", "--mat", tmp_path / "m.mat",
                                   "--set", f"delay.rate={delay_rate}")
    assert code == 0, err
    model = read_linear_model(tmp_path / "m.h5")
    assert model.metadata["sample_time"] == pytest.approx(T, abs=1e-15)
    assert model.state_names == ["multibody.q", "multibody.u", "controller.x", "controller.x_sampled",
                                 "controller.u_sampled", "delay.y", "delay.buffer[0]", "delay.buffer[1]"]
    M = hand_model(1.0 / float(delay_rate.split()[0]))
    assert np.max(np.abs(model.A - M)) < 1e-9 * np.max(np.abs(M))
    radius = np.max(np.abs(np.linalg.eigvals(M)))
    assert float(re.search(r"spectral radius (\S+) \(stable\)", out).group(1)) == pytest.approx(radius, abs=1e-11)
    from scipy.io import loadmat

    assert float(loadmat(tmp_path / "m.mat")["sample_time"].squeeze()) == pytest.approx(T, abs=1e-15)
    # later in the run (the delay line's ring buffer turned): the same map (time-invariant coordinates)
    sim = build_simulation(load_scenario(scene, ["multibody.bus.initial.angle=1 deg", f"delay.rate={delay_rate}"]))
    sim.run(0.3)
    with pytest.warns(UserWarning, match="not at a fixed point of its sampled loop: .* moves by"):
        later = sampled_linearize(sim)
    assert sim.t == pytest.approx(0.3, abs=1e-15)  # left where it was found
    assert np.max(np.abs(later.A - M)) < 1e-9 * np.max(np.abs(M))
    # over two periods: the square of the map
    with pytest.warns(UserWarning, match="not at a fixed point"):
        twice = sampled_linearize(sim, period=2 * T)
    assert twice.metadata["sample_time"] == pytest.approx(2 * T, abs=1e-15)
    assert np.max(np.abs(twice.A - M @ M)) < 1e-9 * np.max(np.abs(M @ M))


def fitted_decay(theta, first=30, last=280):
    """The dominant pair of the logged samples by Prony's method (module docstring)."""
    k = np.arange(first, last)
    a1, a0 = np.linalg.lstsq(np.column_stack((theta[k + 1], theta[k])), theta[k + 2], rcond=None)[0]
    return np.roots([1.0, -a1, -a0])


def test_eigenvalues_predict_the_nonlinear_decay(tmp_path, capsys):
    code, out, err = linearize_cli(capsys, PD_AXIS, "--sampled", "-o", tmp_path / "m.h5")
    assert code == 0, err
    (lam, magnitude, rate, frequency, _), *rest = loop_eigenvalues(read_linear_model(tmp_path / "m.h5"))
    assert abs(lam.imag) > 0.1 and all(r[1] < 0.2 for r in rest[1:])  # one oscillatory pair dominates
    assert f"{magnitude:.9f}" in out
    assert main(["run", str(PD_AXIS), "-o", str(tmp_path / "log.h5"), "--set", "multibody.bus.initial.angle=1 deg",
                 "--set", "stop.time=30 s"]) == 0
    theta = read_log(tmp_path / "log.h5")["multibody.bus.q"][:, 0]
    fitted = fitted_decay(theta)
    fitted_rate = np.log(np.abs(fitted[0])) / T
    assert abs(fitted_rate / rate - 1.0) < 1e-5
    assert abs(np.abs(np.angle(fitted[0])) / (2 * np.pi * T) - frequency) < 1e-5 * frequency


def growth(sim, start, kp, t_final=80.0, log=None):
    """ln of the ratio of the angle's envelope over the last 20 s to that over [20, 40] s of a run from ``start``."""
    sim.restore(start)
    sim.context.set("controller.kp", [0.0, 0.0, kp])
    sim.run(t_final, log_path=log)
    data = read_log(log)
    t, theta = data["time"], np.abs(data["multibody.bus.q"][:, 0])
    return float(np.log(np.max(theta[t > t_final - 20.0]) / np.max(theta[(t > 20.0) & (t <= 40.0)])))


def bisect(stable, low, high, relative):
    while high - low > relative * high:
        middle = 0.5 * (low + high)
        low, high = (middle, high) if stable(middle) else (low, middle)
    return low, high


def test_gain_sweep_critical_gain_matches_the_nonlinear_boundary(tmp_path, capsys):
    plant = build_simulation(load_scenario(PD_AXIS, []))

    def radius(kp):
        plant.context.set("controller.kp", [0.0, 0.0, kp])
        return spectral_radius(sampled_linearize(plant))

    predicted = bisect(lambda kp: radius(kp) < 1.0, 1000.0, 3000.0, 1e-5)
    loop = build_simulation(load_scenario(PD_AXIS, ["multibody.bus.initial.angle=1 deg"]))
    start = loop.snapshot()
    boundary = bisect(lambda kp: growth(loop, start, kp, log=tmp_path / "g.h5") < 0.0, 1000.0, 3000.0, 1e-4)
    critical = 0.5 * sum(predicted)
    assert abs(critical / (0.5 * sum(boundary)) - 1.0) < 0.01
    assert boundary[0] - 1e-3 * critical <= critical <= boundary[1] + 1e-3 * critical  # measured: inside
    # the command line at 0.99 and 1.01 times the critical gain: the printed radius and the logged angle
    for factor, verdict in ((0.99, "(stable)"), (1.01, "(NOT asymptotically stable)")):
        gain = f"controller.parameters.kp=[0, 0, {factor * critical}] N*m/rad"
        code, out, err = linearize_cli(capsys, PD_AXIS, "--sampled", "--set", gain, "-o", tmp_path / "m.h5",
                                       "--overwrite")
        assert code == 0, err
        assert verdict in out
        radius_printed = float(re.search(r"spectral radius (\S+)", out).group(1))
        assert (radius_printed < 1.0) == (factor < 1.0)
        assert main(["run", str(PD_AXIS), "-o", str(tmp_path / "run.h5"), "--overwrite", "--set", gain,
                     "--set", "multibody.bus.initial.angle=1 deg", "--set", "stop.time=80 s"]) == 0
        theta = np.abs(read_log(tmp_path / "run.h5")["multibody.bus.q"][:, 0])
        assert (np.max(theta[-200:]) < np.max(theta[200:400])) == (factor < 1.0)


STATIC = """
name: no_sampled_model
multibody:
  gravity: "[0, 0, 0] m/s^2"
  bodies:
    - {name: bus, parent: world, hinge: revolute, axis: [0, 0, 1], mass: 1 kg, com: "[0, 0, 0] m",
       inertia: "[1, 1, 1] kg*m^2"}
stop: {time: 1 s}
"""


@pytest.mark.parametrize("arguments, message", [
    (["--period", "0.15"], "period (--period) 0.15 s is not a multiple of the period 0.1 s of controller"),
    (["--period", "-1"], "--period -1.0: expected a time > 0"),
    (["--at", "0.05"], "t = 0.05 s, not a sample instant of any sampled model (controller every 0.1 s from 0 s"),
    (["--inputs", "multibody.bus.torque"], "--inputs: not taken with --sampled"),
    (["--trim"], "--trim: not taken with --sampled"),
])
def test_refusals_name_the_option(tmp_path, capsys, arguments, message):
    code, out, err = linearize_cli(capsys, PD_AXIS, "--sampled", "-o", tmp_path / "m.h5", *arguments)
    assert code == 1 and message in err, err
    assert not (tmp_path / "m.h5").exists()


def test_refusals_without_a_sampled_model_or_without_sampled(tmp_path, capsys):
    scene = tmp_path / "static.yaml"
    scene.write_text(textwrap.dedent(STATIC))
    code, _, err = linearize_cli(capsys, scene, "--sampled", "-o", tmp_path / "m.h5")
    assert code == 1 and "the scene has no sampled model" in err, err
    code, _, err = linearize_cli(capsys, PD_AXIS, "--period", "0.1", "-o", tmp_path / "m.h5")
    assert code == 1 and "--period is taken with --sampled only" in err, err
    code, _, err = linearize_cli(capsys, PD_AXIS, "-o", tmp_path / "m.h5")
    assert code == 1 and "--inputs and --outputs required (or --sampled" in err, err
    with pytest.raises(LinearizationError, match="period .* is not a multiple"):
        sampled_linearize(build_simulation(load_scenario(PD_AXIS, [])), period=0.25)


FREE_TRANSLATION = "multibody.q[4:7],multibody.u[3:6]"


@pytest.mark.parametrize("step, bound", [("10 ms", 1e-4), pytest.param("2.5 ms", 1e-6, marks=pytest.mark.slow)])
def test_3axis_lqr_scene_against_its_linear_design(monkeypatch, tmp_path, capsys, step, bound):
    """Gallery 13 (the 3-axis flexible spacecraft under LinearizedState + LqrStateFeedback at 10 Hz) at rest: the
    sampled model's eigenvalues, the free translation left out, against the design's closed loop Ad - Bd K
    (python-control c2d of the shipped continuous linearization, configs/lqr_data/design_lqr_3axis.py; its unit
    poles are the translation). The sampled model is the scene's own RK4 discretization: measured 4.3e-5 at the
    scene's 10 ms step and 1.7e-7 at 2.5 ms (RK4's h^4: 256 times smaller)."""
    from tests.linearize.test_lqr_3axis import load_design

    monkeypatch.chdir(REPO)
    design = load_design()
    K, Ad, Bd = design.design(read_linear_model(REPO / "configs/lqr_data/lqr_3axis_plant.h5"))
    poles = np.linalg.eigvals(Ad - Bd @ K)
    poles = np.sort_complex(poles[np.abs(poles - 1.0) > 1e-6])
    code, out, err = linearize_cli(capsys, "configs/gallery/13_lqr_3axis.yaml", "--sampled", "-o", tmp_path / "m.h5",
                                   "--set", "multibody.bus.initial.attitude=[1, 0, 0, 0]", "--set",
                                   f"integrator.step={step}", "--leave-out", FREE_TRANSLATION)
    assert code == 0, err
    assert "(stable)" in out and f"left out of the verdict: {FREE_TRANSLATION.replace(',', ', ')}" in out
    model = read_linear_model(tmp_path / "m.h5")
    eigenvalues = np.array([row[0] for row in loop_eigenvalues(model, FREE_TRANSLATION.split(","))])
    eigenvalues = np.sort_complex(eigenvalues[np.abs(eigenvalues) > 1e-6])  # the held commands' zeros aside
    assert eigenvalues.size == poles.size == 18
    assert np.max(np.abs(eigenvalues - poles)) < bound
    # the rotation is what the loop acts on: leaving it out is refused (the commands depend on it)
    code, _, err = linearize_cli(capsys, "configs/gallery/13_lqr_3axis.yaml", "--sampled", "-o",
                                 tmp_path / "m.h5", "--overwrite", "--leave-out", "multibody.u[0:3]")
    assert code == 1 and "depends on multibody.u[" in err and "the model is written" in err, err


def test_gallery_14_notch_sampled_model_against_the_zero_order_hold_of_its_linearization(tmp_path, capsys):
    """Gallery 14 (61 states: the deck's modes to 100 Hz, a continuous notch, ETDRK4 at 2 ms): the spectral
    radius, translation left out, equals the zero-order hold of the continuous linearization computed in
    tests/linearize/test_notch_spillover.py (0.98941 with the notch, 1.0261 with a notch gain of 0.1);
    measured 0.989400956 vs 0.989400956 and 1.025955 vs 1.026062 (the notch's 26 Hz states in ETDRK4's explicit
    part at 2 ms: RK4 at 0.5 ms gives 1.0260608)."""
    body = tmp_path / "spacecraft.h5"
    assert main(["fem2modal", str(REPO / "configs/fem/spacecraft.dat"), "--modes", "20", "--modal-integrals",
                 "--damping", "0.005", "-o", str(body)]) == 0
    for gain, expected, bound in (("0.02", 0.98941, 1e-5), ("0.1", 1.02606, 2e-4)):
        code, out, err = linearize_cli(
            capsys, REPO / "configs/gallery/14_spacecraft_notch.yaml", "--sampled", "-o", tmp_path / "m.h5",
            "--overwrite", "--points", "2", "--tolerance", "1e-8", "--leave-out", FREE_TRANSLATION,
            *[item for value in (f"multibody.spacecraft.body_file={body}",
                                 "controller.parameters.attitude_command=[1, 0, 0, 0]",
                                 f"notch.config.notch_gain={gain}") for item in ("--set", value)])
        assert code == 0, err
        radius = float(re.search(r"spectral radius (\S+)", out).group(1))
        assert abs(radius - expected) < bound and (radius < 1.0) == (gain == "0.02")


def test_constant_discrete_states_are_not_coordinates(tmp_path):
    """A PID's and a rate limiter's stored period (constants, not signals) are left out of the coordinates: kept,
    each would be an eigenvalue of exactly 1. pd_axis with a PID (its integral a coordinate) and a rate limiter
    (not limiting at rest: the sampled PID's output passes) in place of the delay line: every eigenvalue of the
    loop inside the unit circle but the integral's about the axes the hinge does not turn, the same nonzero ones as
    with a zero-sample delay line (the same map)."""
    scene = yaml.safe_load(PD_AXIS.read_text())
    controller = scene["models"]["controller"]
    controller["type"] = "PidAttitudeController"
    controller["parameters"]["ki"] = "[0, 0, 50] N*m/(rad*s)"
    scene["models"]["delay"] = {"type": "RateLimiter", "rate": "10 Hz", "config": {"unit": "N*m", "shape": [3]},
                                "parameters": {"rising_rate": "[1e3, 1e3, 1e3] N*m/s",
                                               "falling_rate": "[1e3, 1e3, 1e3] N*m/s"}}
    (tmp_path / "limited.yaml").write_text(yaml.safe_dump(scene))
    scene["models"]["delay"] = {"type": "Delay", "rate": "10 Hz", "config": {"samples": 0, "unit": "N*m",
                                                                               "shape": [3]}}
    (tmp_path / "passed.yaml").write_text(yaml.safe_dump(scene))
    limited = sampled_linearize(build_simulation(load_scenario(tmp_path / "limited.yaml", [])))
    passed = sampled_linearize(build_simulation(load_scenario(tmp_path / "passed.yaml", [])))
    assert not any("period" in name for name in limited.state_names)
    assert "controller.integral[2]" in limited.state_names and "delay.y[2]" in limited.state_names
    # the integral about x and y integrates an error the revolute hinge keeps at zero: neutral, left out
    assert spectral_radius(limited) == pytest.approx(1.0, abs=1e-12)
    assert spectral_radius(limited, ["controller.integral[0:2]"]) < 1.0
    ours, reference = (np.sort_complex(v[np.abs(v) > 1e-9]) for v in (np.linalg.eigvals(limited.A),
                                                                          np.linalg.eigvals(passed.A)))
    assert ours.size == reference.size >= 3 and np.max(np.abs(ours - reference)) < 1e-9
