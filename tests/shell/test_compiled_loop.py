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
