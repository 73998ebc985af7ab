"""The compiled loop (shell.compiled_loop) against the interpreted reference (shell.diagram): same states,
same log rows, same counters, bit for bit. The compiled loop calls the same kernels through function
pointers and repeats the interpreted arithmetic operation for operation (Runge-Kutta combinations,
quaternion normalization, instants k/den rounded like float(Fraction)), so anything but bit identity
is a defect."""

from pathlib import Path

import numpy as np
import pytest

from shell.assembly import Assembly
from shell.log_file import read_log
from shell.models.blocks import Constant, Gain, Integrator, NoisySampler, SampleHold
from shell.scenario import build_root, load_scenario
from shell.simulation import Simulation, SimulationError

CONFIGS = Path(__file__).resolve().parents[2] / "configs"


def _build(scenario, mode):
    sim = Simulation(build_root(scenario), integrator=scenario.integrator, step=scenario.step,
                     integrator_options=scenario.integrator_options, seed=scenario.seed,
                     stop_events=scenario.stop_events, event_tol=scenario.event_tolerance,
                     event_detection=scenario.event_detection, mode=mode)
    for name, rate, _ in scenario.log_signals:
        sim.log([name], rate)
    return sim


def _assert_same_run(a, b, log_a, log_b):
    assert a.x.tobytes() == b.x.tobytes()
    assert a.z.tobytes() == b.z.tobytes()
    assert a.t == b.t
    assert a.counters == b.counters
    if log_a is not None:
        la, lb = read_log(log_a), read_log(log_b)
        assert sorted(la) == sorted(lb)
        for key in la:
            assert la[key].tobytes() == lb[key].tobytes(), key


SHIPPED = sorted(p.name for p in CONFIGS.glob("*.yaml") if not p.name.startswith("campaign_"))


@pytest.mark.parametrize("name", SHIPPED)
def test_every_shipped_config_runs_compiled_and_interpreted_identically(name, tmp_path, monkeypatch):
    """Each scenario in configs/, shortened to a few seconds (every rate still fires many times)."""
    monkeypatch.chdir(CONFIGS.parent)  # configs name their files relative to the repository root
    scenario = load_scenario(CONFIGS / name, ["stop.time=3 s"])
    runs = {}
    for mode in ("interpreted", "compiled"):
        sim = _build(scenario, mode)
        log = tmp_path / f"{mode}.h5"
        sim.run(scenario.t_final, log_path=log if scenario.log_signals else None)
        runs[mode] = (sim, log if scenario.log_signals else None)
    (a, log_a), (b, log_b) = runs["interpreted"], runs["compiled"]
    assert a.mode == "interpreted"
    assert b.mode == "compiled", b.interpreted_reason
    _assert_same_run(a, b, log_a, log_b)


def _multirate_scene():
    root = Assembly("root")
    root.add(Constant("one", value=1.0))
    root.add(Integrator("clock", unit="s"))
    root.add(SampleHold("fast", unit="s", period="100 Hz"))
    root.add(SampleHold("medium", unit="s", period="0.1 s", offset="0.025 s"))
    root.add(NoisySampler("sensor", unit="s", period="30 Hz", sigma="0.01 s"))
    root.add(Gain("k", unit="s", output_unit="s", k=-0.5))
    root.add(Integrator("area", unit="s^2"))
    root.connect("one.y", "clock.u")
    root.connect("clock.y", "fast.u")
    root.connect("fast.y", "medium.u")
    root.connect("clock.y", "sensor.u")
    root.connect("sensor.y", "k.u")
    root.connect("k.y", "area.u")
    return root


@pytest.mark.parametrize("method", ["euler", "heun", "rk4", "rk8", "dopri5"])
def test_multirate_noise_and_odd_log_rates_are_bit_identical(method, tmp_path):
    """Rates 100 Hz, 10 Hz with an offset, 30 Hz (not a multiple of the 7 ms step: steps are cut at the
    instants), Gaussian noise from the model's own stream, logs at 7 Hz and 120 Hz. With ``dopri5`` the
    integrator stays in Python and the compiled plan serves its derivatives and the sampled updates
    (``CompiledPlan.update``, noise drawn inside numba from the same generators)."""
    runs = []
    for mode in ("interpreted", "compiled"):
        sim = Simulation(_multirate_scene(), integrator=method, step=0.007, seed=11, mode=mode)
        assert sim.mode == mode
        sim.log(["clock.y", "sensor.y", "area.y"], "7 Hz")
        sim.log(["medium.y", "fast.samples", "k.y"], "120 Hz")
        log = tmp_path / f"{mode}.h5"
        sim.run(2.0, log_path=log)
        sim.run(3.3, log_path=tmp_path / f"{mode}_second.h5")  # a second run continues the first
        runs.append((sim, log))
    (a, log_a), (b, log_b) = runs
    _assert_same_run(a, b, log_a, log_b)
    assert a.counters["updates"] > 300


def test_restore_continues_bit_identically_in_the_compiled_loop():
    straight = Simulation(_multirate_scene(), step=0.005, seed=3)
    straight.run(2.0)
    resumed = Simulation(_multirate_scene(), step=0.005, seed=3)
    resumed.run(0.73)
    snap = resumed.snapshot()
    other = Simulation(_multirate_scene(), step=0.005, seed=3)
    other.restore(snap)
    other.run(2.0)
    assert other.mode == "compiled"
    assert other.x.tobytes() == straight.x.tobytes()
    assert other.z.tobytes() == straight.z.tobytes()


def test_non_finite_state_is_named_and_located_like_the_interpreted_loop():
    from tests.plants import FiniteEscape

    messages = []
    for mode in ("interpreted", "compiled"):
        root = Assembly("root")
        root.add(FiniteEscape("runaway"))  # x = 1 / (1 - t)
        sim = Simulation(root, step=0.01, mode=mode)
        with pytest.raises(SimulationError, match=r"non-finite model runaway (state|derivative of) x") as info:
            sim.run(2.0)
        messages.append(str(info.value))
    # the same failing step and the same last good state
    assert [m.split("; the run stopped")[0] for m in messages][0] == messages[1].split("; the run stopped")[0]
    assert messages[0].split("last good state at t = ")[1][:12] == messages[1].split("last good state at t = ")[1][:12]


def test_python_output_kernels_run_interpreted_and_say_why():
    from shell.simulation import SimulationWarning
    from tests.shell.test_failures import _Raises

    root = Assembly("root")
    root.add(_Raises("table"))
    with pytest.warns(SimulationWarning, match=r"runs interpreted .*model table \(_Raises\): its derivatives "
                                               r"kernel is Python"):
        sim = Simulation(root)
    assert sim.mode == "interpreted" and "table" in sim.interpreted_reason


@pytest.mark.parametrize("detection", ["subdivided", "sign_change"])
@pytest.mark.parametrize("stop", [(), ("ball.ground_contact",)])
def test_zero_crossings_are_found_and_handled_like_the_interpreted_loop(detection, stop, tmp_path):
    """A bouncing ball (12 contacts in 12 s, located to 1e-12 s, state reset by the handler), logged at a
    rate that is not a multiple of the step; with a terminal event the run stops at the first contact."""
    from tests.plants import BouncingBall

    runs = []
    for mode in ("interpreted", "compiled"):
        root = Assembly("root")
        ball = root.add(BouncingBall("ball", gravity=9.81, restitution=0.8))
        ball.set_initial("height", 10.0)
        sim = Simulation(root, step=0.037, stop_events=stop, event_tol=1e-12, event_detection=detection, mode=mode)
        sim.log(["ball.height"], "30 Hz")
        log = tmp_path / f"{mode}.h5"
        summary = sim.run(12.0, log_path=log)
        runs.append((sim, log, summary))
    (a, log_a, sa), (b, log_b, sb) = runs
    assert b.mode == "compiled" and b._compiled_loop_applies()
    assert a.events == b.events and len(a.events) == (1 if stop else 12)
    assert (sa.status, sa.reason) == (sb.status, sb.reason)
    _assert_same_run(a, b, log_a, log_b)


# --- the exponential RK4 (etdrk4) in the compiled loop -------------------------------------------------------------
QUIET_IMU = ["imu.gyro_lsb=0 rad", "imu.accel_lsb=0 m/s", "imu.gyro_random_walk=0 rad/s**0.5",
             "imu.gyro_bias_instability=0 rad/s", "imu.accel_random_walk=0 m/s**1.5"]


def _run_both(scenario, tmp_path, t_final):
    runs = []
    for mode in ("interpreted", "compiled"):
        sim = _build(scenario, mode)
        log = tmp_path / f"{mode}.h5"
        summary = sim.run(t_final, log_path=log if scenario.log_signals else None)
        runs.append((sim, log if scenario.log_signals else None, summary))
    return runs


def test_exponential_rk4_on_the_observatory_is_bit_identical(tmp_path, monkeypatch):
    """configs/observatory.yaml as shipped (60 modes to 2.29 kHz, IMU with noise, 1 kHz controller, 16 pulsing
    jets whose valve closings are located as events): etdrk4 at 1 ms stepped in the compiled loop against the
    interpreted ExponentialRK4 on the interpreted diagram, 60 ms (three jet periods), logged at 1 kHz."""
    monkeypatch.chdir(CONFIGS.parent)
    scenario = load_scenario(CONFIGS / "observatory.yaml", ["stop.time=60 ms", "log.rate=1 kHz"])
    (a, log_a, sa), (b, log_b, sb) = _run_both(scenario, tmp_path, scenario.t_final)
    assert a.mode == "interpreted" and not a._compiled_loop_applies()
    assert b.mode == "compiled" and b._compiled_loop_applies()
    assert type(b._stepper).__name__ == "ExponentialStepper"
    assert len(a.events) >= 4 and a.events == b.events
    assert a.counters["updates"] >= 120 and a.counters["steps"] >= 60
    _assert_same_run(a, b, log_a, log_b)
    # the check counters of the linear part moved the same way (2, 8, 32 steps between checks: L stands still)
    assert (a._integrator.check_interval, a._integrator.steps_since_check, a._integrator.njev) == \
        (b._integrator.check_interval, b._integrator.steps_since_check, b._integrator.njev)
    assert a._integrator.njev >= 4


MOVING_ARRAY = """
name: moving_array
multibody:
  gravity: "[0, 0, 0] m/s^2"
  bodies:
    - name: bus
      parent: world
      hinge: free
      mass: 200 kg
      inertia: "[300, 300, 300] kg*m^2"
    - name: array
      parent: bus
      parent_node: array_root
      hinge: revolute
      axis: [0, 0, 1]
      body_file: {array}
      damping_ratio: 0.005
      initial: {{angle: 0 deg, angle_rate: 60 deg/s}}
  nodes:
    - {{name: array_root, body: bus, position: "[1, 0, 0] m"}}
    - {{name: array_tip, body: array, grid: 21}}
models:
  drive:
    type: Constant
    config: {{unit: N*m, shape: [1]}}
    parameters: {{value: "[40] N*m"}}
connections:
  - drive.y -> multibody.array.torque
integrator:
  method: etdrk4
  step: 10 ms
stop:
  time: 1 s
log:
  rate: 30 Hz
  signals: [multibody.array_tip.position, multibody.q]
"""


@pytest.mark.parametrize("rate, step, torque, retakes", [("60 deg/s", "10 ms", "[40] N*m", 0),
                                                         ("600 deg/s", "50 ms", "[400] N*m", 1)])
def test_exponential_rk4_with_a_moving_linear_part_and_shortened_steps_is_bit_identical(rate, step, torque, retakes,
                                                                                        tmp_path):
    """A flexible array driven round its hinge on a free bus: the mass matrix, hence the linear part, changes
    with the hinge angle, so the loop returns to Python for the checks and the matrix functions are rebuilt
    many times; the 30 Hz log is not a multiple of the step, so shortened steps take the eigenbasis path (phi
    functions of c h lambda computed in the loop). Turning 10x faster with 50 ms steps, the remainder becomes
    stiff inside steps: a forced check, a rebuild and the step taken again (and a forced check that keeps L,
    after which the step goes on from its third stage)."""
    scene = tmp_path / "moving_array.yaml"
    scene.write_text(MOVING_ARRAY.format(array=CONFIGS / "lqr_data" / "array.h5").replace("60 deg/s", rate)
                     .replace("10 ms", step).replace("[40] N*m", torque))
    scenario = load_scenario(scene)
    (a, log_a, _), (b, log_b, _) = _run_both(scenario, tmp_path, scenario.t_final)
    assert b._compiled_loop_applies() and type(b._stepper).__name__ == "ExponentialStepper"
    assert a._integrator.nlu >= 40, a._integrator.nlu  # rebuilt (two decompositions each: modes, driven rows)
    assert a._integrator.nrejected >= retakes
    assert (a._integrator.nlu, a._integrator.njev, a._integrator.nrejected) == \
        (b._integrator.nlu, b._integrator.njev, b._integrator.nrejected)
    _assert_same_run(a, b, log_a, log_b)
