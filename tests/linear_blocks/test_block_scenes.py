"""The linear-block models in YAML scenes run by ``flexshell run``, against analytic responses.

Every scene runs through the command line (``shell.cli.main(["run", ...])``) and must run compiled (the
simulation warns on stderr when a scene falls back to interpreted; the test fails on that warning). The
references are written here, independent of the realizations the blocks use:

* sampled state space (matrices from .npz, .mat and HDF5 files, with the file's sample time): the step
  response in closed form ``y_k = C (I - A)^-1 (I - A^k) B u + D u`` and the periodic steady state
  ``y_k = Re[G(e^(j w T)) e^(j w k T)]``, ``G(z) = C (z I - A)^-1 B + D``; exact discretization, so 1e-12;
* continuous state space and transfer function (RK4, 1 ms): the step response from the matrix exponential /
  from the residues of H(s)/s; RK4's global error (h |lambda|)^4 / 120 ~ 1e-13 here, tolerance 1e-10;
* transfer function in z: python-control's ``forced_response`` of ``tf(num, den, dt)`` (a peer), 1e-12;
* sampled notch and low-pass filters (Tustin, prewarped per quadratic): the steady state against the
  prewarped map ``H_d(e^(j W T)) = N(j r_n) / D(j r_d)``, ``r = tan(W T / 2) / tan(w T / 2)`` per quadratic of
  normalized form ``q(j r) = 1 - r^2 + 2 zeta j r``: the notch passes ``g`` at its frequency exactly; 1e-12;
* delay, saturation, dead zone, rate limiter: their definitions evaluated on the logged input, exact (1e-15).
"""

from __future__ import annotations

import math
import textwrap
from fractions import Fraction

import h5py
import numpy as np
import pytest
from scipy.io import savemat
from scipy.linalg import expm

from shell.cli import main
from shell.log_file import read_log
from shell.model import ModelError
from shell.scenario import ScenarioError, build_root, build_simulation, parse_scenario
from shell.simulation import Simulation

A = np.array([[0.5, 0.2, 0.0], [-0.1, 0.7, 0.3], [0.0, -0.2, 0.4]])
B = np.array([[1.0, 0.0], [0.5, -1.0], [0.0, 2.0]])
C = np.array([[1.0, -1.0, 0.5], [0.0, 2.0, 1.0]])
D = np.array([[0.25, 0.0], [0.0, -0.5]])
T = 0.1


def run(tmp_path, capsys, scene: str, stop: float) -> dict:
    """Run ``scene`` (YAML) with ``flexshell run``; the log as a dict. Fails when the scene ran interpreted."""
    path = tmp_path / "scene.yaml"
    path.write_text(textwrap.dedent(scene) + f"\nstop: {{time: {stop} s}}\n")
    capsys.readouterr()
    code = main(["run", str(path), "-o", str(tmp_path / "log.h5"), "--overwrite"])
    err = capsys.readouterr().err
    assert code == 0, err
    assert "interpreted" not in err, err
    return read_log(tmp_path / "log.h5")


def write_system(path, sample_time):
    if path.suffix == ".npz":
        np.savez(path, A=A, B=B, C=C, D=D, sample_time=sample_time)
    elif path.suffix == ".mat":
        savemat(path, {"A": A, "B": B, "C": C, "D": D, "sample_time": sample_time})
    else:
        with h5py.File(path, "w") as f:
            group = f.create_group("attitude_filter")
            for key, value in zip("ABCD", (A, B, C, D)):
                group.create_dataset(key, data=value)
            group.attrs["sample_time"] = sample_time


@pytest.mark.parametrize("suffix", [".npz", ".mat", ".h5"])
def test_sampled_state_space_from_a_file_step_and_sinusoid(tmp_path, capsys, suffix):
    """2 inputs, 3 states, 2 outputs, the sample time from the file: the step (input 1: 1, input 2: -2) in
    closed form and a sinusoid's periodic steady state, both to 1e-12."""
    path = tmp_path / f"system{suffix}"
    write_system(path, T)
    group = ", group: attitude_filter" if suffix == ".h5" else ""
    omega, stop = 2 * math.pi * 0.7, 60.0  # the run stops 1 s before the profile ends
    log = run(tmp_path, capsys, f"""
        models:
          step: {{type: Constant, config: {{shape: [2]}}, parameters: {{value: [1.0, -2.0]}}}}
          wave:
            type: Profile
            config: {{shape: [2]}}
            parameters: {{times: "[0, {stop}] s", cosine: [[1.0, 0.0]], sine: [[0.0, 1.0]], cycles: [{0.7 * stop}]}}
          by_step: {{type: StateSpace, config: {{file: {path}{group}}}}}
          by_wave: {{type: StateSpace, rate: 10 Hz, config: {{file: {path}{group}}}}}
        connections: [step.y -> by_step.u, wave.y -> by_wave.u]
        integrator: {{method: rk4, step: 0.05 s}}
        log: {{rate: 10 Hz, signals: [by_step.y, by_wave.y]}}
        """, stop - 1.0)
    k = np.arange(log["time"].size)
    assert np.allclose(log["time"], k * T, rtol=0, atol=1e-12)
    u = np.array([1.0, -2.0])
    inverse = np.linalg.inv(np.eye(3) - A)
    expected = np.array([C @ inverse @ (np.eye(3) - np.linalg.matrix_power(A, j)) @ B @ u + D @ u for j in k])
    np.testing.assert_allclose(log["by_step.y"], expected, rtol=0, atol=1e-12 * np.abs(expected).max())
    G = C @ np.linalg.solve(np.exp(1j * omega * T) * np.eye(3) - A, B) + D
    steady = np.real(np.exp(1j * omega * T * k)[:, None] * (G @ np.array([1.0, -1j]))[None, :])
    late = k > 300  # the transient: spectral radius 0.62, 0.62^300 ~ 1e-62
    np.testing.assert_allclose(log["by_wave.y"][late], steady[late], rtol=0, atol=1e-12)


def test_continuous_state_space_and_transfer_function_step(tmp_path, capsys):
    """Continuous blocks under RK4 (1 ms): a 2-state inline system against expm, (s + 3) / (s^2 + 2 s + 5)
    against its residues; a feedthrough TransferFunction (D = 2) too. Tolerance 1e-10 (RK4, above)."""
    log = run(tmp_path, capsys, """
        models:
          step: {type: Constant, config: {shape: [1]}, parameters: {value: [1.0]}}
          one: {type: Constant, parameters: {value: 1.0}}
          plant:
            type: StateSpace
            config: {A: [[0, 1], [-4, -0.8]], B: [[0], [1]], C: [[1, 0], [0, 1]], D: [[0], [0]], output_unit: m}
          tf: {type: TransferFunction, config: {numerator: [1, 3], denominator: [1, 2, 5]}}
          lead: {type: TransferFunction, config: {numerator: [2, 3], denominator: [1, 1]}}
        connections: [step.y -> plant.u, one.y -> tf.u, one.y -> lead.u]
        integrator: {method: rk4, step: 1 ms}
        log: {rate: 100 Hz, signals: [plant.y, tf.y, lead.y]}
        """, 3.0)
    t = log["time"]
    Ac = np.array([[0.0, 1.0], [-4.0, -0.8]])
    expected = np.array([np.linalg.solve(Ac, expm(Ac * s) - np.eye(2)) @ np.array([0.0, 1.0]) for s in t])
    np.testing.assert_allclose(log["plant.y"], expected, rtol=0, atol=1e-10)
    poles = np.roots([1.0, 2.0, 5.0])
    tf = 3.0 / 5.0 + sum((p + 3.0) / (p * (2 * p + 2.0)) * np.exp(p * t) for p in poles).real
    np.testing.assert_allclose(log["tf.y"], tf, rtol=0, atol=1e-10)
    np.testing.assert_allclose(log["lead.y"], 3.0 - np.exp(-t), rtol=0, atol=1e-10)


def test_sampled_transfer_function_equals_python_control(tmp_path, capsys):
    control = pytest.importorskip("control")
    num, den = [0.2, -0.1], [1.0, -1.3, 0.6]
    log = run(tmp_path, capsys, f"""
        models:
          wave:
            type: Profile
            parameters: {{times: "[0, 10] s", c0: [0.5], sine: [1.0], cycles: [3]}}
          tf: {{type: TransferFunction, rate: 20 Hz, config: {{numerator: {num}, denominator: {den}}}}}
        connections: [wave.y -> tf.u]
        integrator: {{method: rk4, step: 0.05 s}}
        log: {{rate: 20 Hz, signals: [tf.y, wave.y]}}
        """, 9.0)
    k = np.arange(log["time"].size)
    u = 0.5 + np.sin(2 * math.pi * 3 * k * 0.05 / 10.0)
    np.testing.assert_allclose(log["wave.y"], u, rtol=0, atol=1e-14)
    peer = control.forced_response(control.tf(num, den, 0.05), T=k * 0.05, U=u).outputs
    np.testing.assert_allclose(log["tf.y"], peer, rtol=0, atol=1e-12)


def _prewarped(quadratics, W, T):
    """H_d(e^(j W T)) of a product of normalized quadratics (frequency Hz, damping, exponent +1 / -1)."""
    value = 1.0 + 0j
    for frequency, damping, power in quadratics:
        r = math.tan(W * T / 2) / math.tan(2 * math.pi * frequency * T / 2)
        value *= (1.0 - r * r + 2j * damping * r) ** power
    return value


@pytest.mark.parametrize("drive_hz", [2.0, 0.6, 7.0])
def test_sampled_notch_and_low_pass_filters_steady_state(tmp_path, capsys, drive_hz):
    """A 2 Hz notch (damping 0.5, gain 0.1 at the notch) and a 5 Hz low-pass (damping 0.7), sampled at
    100 Hz on two channels: the periodic steady state equals the prewarped map to 1e-12; at 2 Hz the notch
    passes exactly 0.1 of the input."""
    T, stop = 0.01, 12.0
    log = run(tmp_path, capsys, f"""
        models:
          wave:
            type: Profile
            config: {{shape: [2]}}
            parameters: {{times: "[0, {stop}] s", cosine: [[1.0, 0.0]], sine: [[0.0, 1.0]],
                          cycles: [{drive_hz * stop}]}}
          notch:
            type: Filter
            rate: 100 Hz
            config: {{kind: notch, frequency: 2 Hz, damping: 0.5, notch_gain: 0.1, shape: [2], unit: rad}}
          smooth: {{type: Filter, rate: 100 Hz, config: {{kind: low_pass, frequency: 5 Hz, damping: 0.7, shape: [2]}}}}
        connections: [wave.y -> notch.u, wave.y -> smooth.u]
        integrator: {{method: rk4, step: 0.01 s}}
        log: {{rate: 100 Hz, signals: [notch.y, smooth.y]}}
        """, stop - 1.0)
    k = np.arange(log["time"].size)
    W = 2 * math.pi * drive_hz
    phase = np.exp(1j * W * T * k)[:, None] * np.array([1.0, -1j])[None, :]
    late = k > 600  # slowest pole radius exp(-0.5 * 2 pi 2 Hz * 0.01 s) = 0.94: 0.94^600 ~ 1e-16
    for name, quadratics in (("notch", [(2.0, 0.05, 1), (2.0, 0.5, -1)]), ("smooth", [(5.0, 0.7, -1)])):
        H = _prewarped(quadratics, W, T)
        np.testing.assert_allclose(log[f"{name}.y"][late], np.real(H * phase)[late], rtol=0, atol=1e-12)
    if drive_hz == 2.0:
        assert abs(abs(_prewarped([(2.0, 0.05, 1), (2.0, 0.5, -1)], W, T)) - 0.1) < 1e-15


def test_continuous_low_pass_and_bending_filter_step(tmp_path, capsys):
    """Continuous filters under RK4 (0.5 ms): the low-pass step against the textbook
    1 - e^(-zeta w t) (cos w_d t + zeta / sqrt(1 - zeta^2) sin w_d t); the bending filter's step tends to 1
    (unit gain at zero frequency). Tolerance 1e-10 (RK4)."""
    log = run(tmp_path, capsys, """
        models:
          one: {type: Constant, parameters: {value: 1.0}}
          smooth: {type: Filter, config: {kind: low_pass, frequency: 1 Hz, damping: 0.3}}
          bend:
            type: Filter
            config: {kind: bending, numerator_frequency: 3 Hz, numerator_damping: 0.05,
                     denominator_frequency: 2 Hz, denominator_damping: 0.7}
        connections: [one.y -> smooth.u, one.y -> bend.u]
        integrator: {method: rk4, step: 0.5 ms}
        log: {rate: 100 Hz, signals: [smooth.y, bend.y]}
        """, 6.0)
    t, w, zeta = log["time"], 2 * math.pi, 0.3
    wd = w * math.sqrt(1 - zeta ** 2)
    expected = 1 - np.exp(-zeta * w * t) * (np.cos(wd * t) + zeta / math.sqrt(1 - zeta ** 2) * np.sin(wd * t))
    np.testing.assert_allclose(log["smooth.y"], expected, rtol=0, atol=1e-10)
    assert abs(log["bend.y"][-1] - 1.0) < 1e-8  # poles at -8.8 /s: e^(-8.8 * 6) ~ 1e-23


def test_delay_saturation_dead_zone_and_rate_limiter(tmp_path, capsys):
    """A ramp-and-sine input through Delay (3 samples, 10 Hz), Saturation, DeadZone (continuous, feedthrough)
    and RateLimiter (10 Hz, rising 0.5/s, falling 2/s): each equals its definition on the logged input."""
    log = run(tmp_path, capsys, """
        models:
          drive:
            type: Profile
            config: {unit: N*m, shape: [2]}
            parameters: {times: "[0, 4] s", c1: "[[2, -3]] N*m", sine: "[[0.5, 0.5]] N*m", cycles: [3]}
          late: {type: Delay, rate: 10 Hz, config: {samples: 3, unit: N*m, shape: [2]}}
          limit:
            type: Saturation
            config: {unit: N*m, shape: [2]}
            parameters: {lower: "[-0.4, -1] N*m", upper: "[0.3, 1] N*m"}
          ignore:
            type: DeadZone
            config: {unit: N*m, shape: [2]}
            parameters: {lower: "[-0.2, -0.5] N*m", upper: "[0.1, 0.5] N*m"}
          slew:
            type: RateLimiter
            rate: 10 Hz
            config: {unit: N*m, shape: [2]}
            parameters: {rising_rate: "[0.5, 0.5] N*m/s", falling_rate: "[2, 2] N*m/s"}
        connections: [drive.y -> late.u, drive.y -> limit.u, drive.y -> ignore.u, drive.y -> slew.u]
        integrator: {method: rk4, step: 0.05 s}
        log: {rate: 10 Hz, signals: [drive.y, late.y, limit.y, ignore.y, slew.y]}
        """, 3.9)
    u = log["drive.y"]
    delayed = np.vstack([np.zeros((3, 2)), u[:-3]])
    np.testing.assert_array_equal(log["late.y"], delayed)
    np.testing.assert_array_equal(log["limit.y"], np.clip(u, [-0.4, -1.0], [0.3, 1.0]))
    lower, upper = np.array([-0.2, -0.5]), np.array([0.1, 0.5])
    np.testing.assert_allclose(log["ignore.y"], np.where(u > upper, u - upper, np.where(u < lower, u - lower, 0.0)),
                               rtol=0, atol=1e-15)
    y, limited = np.zeros(2), []
    for row in u:
        y = y + np.clip(row - y, -2.0 * 0.1, 0.5 * 0.1)
        limited.append(y)
    np.testing.assert_allclose(log["slew.y"], limited, rtol=0, atol=1e-15)
    assert np.any(np.abs(np.diff(log["slew.y"], axis=0)) > 0.05 - 1e-12)  # the limit is reached


def test_the_blocks_run_compiled_and_as_interpreted():
    scene = parse_scenario(textwrap.dedent("""
        models:
          one: {type: Constant, config: {shape: [1]}, parameters: {value: [1.0]}}
          ss: {type: StateSpace, config: {A: [[-1]], B: [[1]], C: [[1]], D: [[1]]}}
          dss: {type: StateSpace, rate: 10 Hz, config: {A: [[0.5]], B: [[1]], C: [[1]], D: [[0]]}}
          tf: {type: TransferFunction, config: {numerator: [1], denominator: [1, 1], shape: [1]}}
          f:
            type: Filter
            rate: 50 Hz
            config: {kind: notch, frequency: 3 Hz, damping: 0.4, notch_gain: 0, shape: [1]}
          d: {type: Delay, rate: 10 Hz, config: {samples: 0, shape: [1]}}
          s: {type: Saturation, config: {shape: [1]}, parameters: {lower: [-1], upper: [1]}}
          z: {type: DeadZone, config: {shape: [1]}, parameters: {lower: [-1], upper: [1]}}
          r: {type: RateLimiter, rate: 10 Hz, config: {shape: [1]}, parameters: {rising_rate: [1], falling_rate: [1]}}
        connections: [one.y -> ss.u, ss.y -> dss.u, dss.y -> tf.u, tf.y -> f.u, f.y -> d.u, d.y -> s.u, s.y -> z.u,
                      z.y -> r.u]
        integrator: {method: rk4, step: 0.01 s}
        """), "blocks.yaml", None)
    simulation = build_simulation(scene)
    assert simulation.mode == "compiled", simulation.interpreted_reason
    simulation.run(0.5)
    assert np.all(np.isfinite(simulation.x)) and np.any(simulation.z != 0.0)
    # the interpreted loop (each kernel called from Python) is the reference: the same numbers, bit for bit
    reference = Simulation(build_root(scene), integrator="rk4", step=0.01, mode="interpreted")
    reference.run(0.5)
    assert reference.x.tobytes() == simulation.x.tobytes() and reference.z.tobytes() == simulation.z.tobytes()


def _refusal(tmp_path, model: str) -> str:
    """The refusal of a scene whose model ``block`` is ``model`` (YAML lines under ``block:``, from line 4)."""
    body = textwrap.indent(textwrap.dedent(model).strip(), "    ")
    text = ("models:\n  one: {type: Constant, config: {shape: [1]}, parameters: {value: [1.0]}}\n  block:\n"
            f"{body}\nconnections: [one.y -> block.u]\nintegrator: {{method: rk4, step: 0.01 s}}\n")
    with pytest.raises(ScenarioError) as info:
        build_simulation(parse_scenario(text, str(tmp_path / "scene.yaml"), None))
    return str(info.value)


def test_bad_matrices_are_refused_with_file_line_and_key(tmp_path):
    non_square = tmp_path / "non_square.npz"
    np.savez(non_square, A=np.ones((2, 3)), B=np.ones((2, 1)), C=np.ones((1, 2)), D=np.zeros((1, 1)))
    message = _refusal(tmp_path, f"""
        type: StateSpace
        config:
          file: {non_square}""")
    assert "scene.yaml:6: models.block.config.file" in message and f"{non_square}: A: expected a square" in message
    nan = tmp_path / "nan.mat"
    savemat(nan, {"A": [[-1.0]], "B": [[np.nan]], "C": [[1.0]], "D": [[0.0]]})
    message = _refusal(tmp_path, f"""
        type: StateSpace
        config: {{file: {nan}}}""")
    assert "scene.yaml:5: models.block.config.file" in message and "B: entry [0, 0] is nan" in message
    unstable = tmp_path / "unstable.h5"
    with h5py.File(unstable, "w") as f:
        for key, value in zip("ABCD", ([[1.2, 0.0], [0.0, 0.5]], [[1.0], [0.0]], [[1.0, 1.0]], [[0.0]])):
            f[key] = value
        f.attrs["sample_time"] = 0.1
    message = _refusal(tmp_path, f"""
        type: StateSpace
        config:
          file: {unstable}
          require_stable: true""")
    assert ("scene.yaml:7: models.block.config.require_stable" in message and f"{unstable}: A:" in message
            and "1 eigenvalue(s) on or outside the unit circle: 1.2" in message)
    with pytest.warns(UserWarning, match=r"scene.yaml:\d+: .*not asymptotically stable \(pole 1.2"):
        build_simulation(parse_scenario(textwrap.dedent(f"""
            models:
              one: {{type: Constant, config: {{shape: [1]}}, parameters: {{value: [1.0]}}}}
              block: {{type: StateSpace, config: {{file: {unstable}}}}}
            connections: [one.y -> block.u]
            integrator: {{method: rk4, step: 0.01 s}}
            """), str(tmp_path / "scene.yaml"), None))
    message = _refusal(tmp_path, """
        type: StateSpace
        config:
          A: [[-1, 0], [0, -2]]
          B: [[1], [1]]
          C: [[1, 1, 1]]
          D: [[0]]""")
    assert "scene.yaml:8: models.block.config.C: model block: config C: expected 2 columns" in message
    message = _refusal(tmp_path, """
        type: StateSpace
        rate: 10 Hz
        config: {file: %s}""" % (tmp_path / "nan.mat"))
    assert "config.file" in message
    message = _refusal(tmp_path, """
        type: TransferFunction
        config: {numerator: [1, 0, 0], denominator: [1, 1]}""")
    assert "models.block.config.numerator" in message and "improper" in message


def test_sample_time_and_filter_refusals(tmp_path):
    sampled = tmp_path / "sampled.npz"
    np.savez(sampled, A=[[0.5]], B=[[1.0]], C=[[1.0]], D=[[0.0]], sample_time=0.1)
    message = _refusal(tmp_path, f"""
        type: StateSpace
        rate: 20 Hz
        config: {{file: {sampled}}}""")
    assert "0.05 s differs from the sample time 0.1 s" in message
    continuous = tmp_path / "continuous.npz"
    np.savez(continuous, A=[[-1.0]], B=[[1.0]], C=[[1.0]], D=[[0.0]])
    message = _refusal(tmp_path, f"""
        type: StateSpace
        rate: 20 Hz
        config: {{file: {continuous}}}""")
    assert "holds a continuous system" in message
    message = _refusal(tmp_path, """
        type: Filter
        rate: 10 Hz
        config: {kind: notch, frequency: 6 Hz, damping: 0.5, notch_gain: 0.1, shape: [1]}""")
    assert "models.block.config.frequency" in message and "Nyquist" in message
    message = _refusal(tmp_path, """
        type: Filter
        config: {kind: notch, frequency: 6 Hz, damping: 0.5, shape: [1]}""")
    assert "a notch filter takes frequency, damping, notch_gain; missing notch_gain" in message
    message = _refusal(tmp_path, """
        type: Filter
        config: {kind: low_pass, frequency: 6 Hz, damping: 0.5, shape: [1], unit: N*m}""")
    assert "connection one.y -> block.u: unit dimensions differ" in message  # the filter's ports take its unit
    message = _refusal(tmp_path, """
        type: Filter
        config: {kind: low_pass, frequency: 6 Hz, damping: 0.5, shape: [1]}
        parameters: {D: [[1.0]]}""")
    assert "models.block.parameters.D" in message and "set by the block's configuration" in message
    message = _refusal(tmp_path, """
        type: Saturation
        config: {shape: [1]}
        parameters: {lower: [1], upper: [-1]}""")
    assert "models.block.parameters.lower" in message and "lower <= upper" in message


def test_models_command_shows_ports_that_depend_on_config(capsys):
    """``flexshell models TYPE`` shows the ports of an example configuration, and says so; a model whose
    ports follow a file says what sets them, with an example."""
    for name, expected in (("StateSpace", ["shapes depend on config; shown for the example config: {'A': [[-1.0]]",
                                           "u                            [1] shape (1,)", "continuous states: x"]),
                           ("Filter", ["shown for the example config: {'kind': 'notch'", "feedthrough"]),
                           ("Delay", ["shapes of buffer, u, y depend on config", "buffer [1] (2,)"]),
                           ("RateLimiter", ["rising_rate", "[1/s] shape ()", "sampled: set rate: or period:"]),
                           ("LinearizedState", ["port sizes follow the linear model",
                                                "config: {linear_model: plant.h5}",
                                                "q                            [1] shape set by the configuration"]),
                           ("LqrStateFeedback", ["port sizes follow K (m x n)"])):
        assert main(["models", name]) == 0
        out = capsys.readouterr().out
        for text in expected:
            assert text in out, (name, text, out)


def test_python_control_objects_in_python(tmp_path):
    """In Python, ``StateSpace(system=...)`` takes python-control's StateSpace (sampled: its dt is the period)
    and TransferFunction (continuous): the same step responses as above, to 1e-12 (sampled) and 1e-10 (RK4)."""
    control = pytest.importorskip("control")
    from shell.assembly import Assembly
    from shell.models.blocks import Constant
    from shell.models.linear_blocks import StateSpace

    root = Assembly("scene")
    root.add(Constant("step", shape=(2,), value=[1.0, -2.0]))
    root.add(Constant("one", shape=(1,), value=[1.0]))
    root.add(StateSpace("sampled", system=control.ss(A, B, C, D, T)))
    root.add(StateSpace("tf", system=control.tf([1.0, 3.0], [1.0, 2.0, 5.0])))
    root.connect("step.y", "sampled.u")
    root.connect("one.y", "tf.u")
    simulation = Simulation(root, integrator="rk4", step=1e-3)
    assert simulation.mode == "compiled" and simulation.models[2].period == Fraction(1, 10)
    simulation.log(["sampled.y", "tf.y"], 10.0)
    simulation.run(3.0, log_path=tmp_path / "log.h5")
    log = read_log(tmp_path / "log.h5")
    k = np.arange(log["time"].size)
    u = np.array([1.0, -2.0])
    inverse = np.linalg.inv(np.eye(3) - A)
    expected = np.array([C @ inverse @ (np.eye(3) - np.linalg.matrix_power(A, j)) @ B @ u + D @ u for j in k])
    np.testing.assert_allclose(log["sampled.y"], expected, rtol=0, atol=1e-12 * np.abs(expected).max())
    t, poles = log["time"], np.roots([1.0, 2.0, 5.0])
    tf = 3.0 / 5.0 + sum((p + 3.0) / (p * (2 * p + 2.0)) * np.exp(p * t) for p in poles).real
    np.testing.assert_allclose(log["tf.y"][:, 0], tf, rtol=0, atol=1e-10)
    with pytest.raises(ModelError, match="sampled with an unspecified period"):
        StateSpace("b", system=control.ss(A, B, C, D, True))
    with pytest.raises(ModelError, match="give the matrices one way"):
        StateSpace("b", system=control.ss(A, B, C, D), A=[[1.0]])
