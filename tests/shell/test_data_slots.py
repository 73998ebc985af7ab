"""Per-model data slots, any number of noisy models and several op-kernel models in the compiled loop
(shell.kernel_protocol, shell.compiled_plan): the compiled run equals the interpreted reference bit for bit, and
every run (context) has data of its own.

The plant (tests.plants.TableTracker) keeps a table and a scratch entry in its data slot, reads it in its derivative
kernel and in its noisy update; ten of them draw noise (each generator by reference in the loop). Two engine
models (two multibody systems, the engine's op kernel and typed data) share one scene.
"""

import numpy as np

from shell.assembly import Assembly
from shell.log_file import read_log
from shell.scenario import build_root, build_simulation, load_scenario
from shell.simulation import Simulation

TRACKERS = 10
SCENE = "seed: 3\nmodels:\n" + "".join(
    f"  track{k}: {{type: TableTracker, rate: 20 Hz, config: {{times: [0, 0.5, 1, 2], values: [2, 2, {k}, {-k}]}}, "
    f"parameters: {{tau: {0.2 + 0.1 * k} s, sigma: {0.01 * k}}}}}\n" for k in range(TRACKERS)) + """
integrator: {method: rk4, step: 5 ms}
stop: {time: 2 s}
log:
  rate: 20 Hz
  signals: [""" + ", ".join(f"track{k}.x, track{k}.measured" for k in range(TRACKERS)) + "]\n"


def test_data_slots_and_ten_noisy_models_run_compiled_as_interpreted(tmp_path):
    from shell.cli import main

    path = tmp_path / "trackers.yaml"
    path.write_text(SCENE)
    assert main(["run", str(path), "-o", str(tmp_path / "compiled.h5"), "--quiet"]) == 0
    scenario = load_scenario(path)
    assert build_simulation(scenario).mode == "compiled"
    sim = Simulation(build_root(scenario), integrator="rk4", step=scenario.step, seed=scenario.seed, mode="interpreted")
    for name, rate, _ in scenario.log_signals:
        sim.log([name], rate)
    sim.run(scenario.t_final, log_path=tmp_path / "interpreted.h5")
    compiled, interpreted = read_log(tmp_path / "compiled.h5"), read_log(tmp_path / "interpreted.h5")
    assert sorted(compiled) == sorted(interpreted)
    for key in compiled:
        assert compiled[key].tobytes() == interpreted[key].tobytes(), key
    # the table read from the data slot: r = 2 until 0.5 s, so x = 2 (1 - exp(-t / tau)) there (RK4 at 5 ms: 1e-9)
    t = compiled["time"]
    early = t <= 0.5
    for k in (0, 3, 9):
        tau = 0.2 + 0.1 * k
        np.testing.assert_allclose(compiled[f"track{k}.x"][early], 2.0 * (1.0 - np.exp(-t[early] / tau)),
                                   rtol=0, atol=1e-8)
    # a sample is the state plus sigma (1 + w) N(0, 1), w in [0, 1] from the slot's scratch: sigma 0 is exact
    assert compiled["track0.measured"].tobytes() == compiled["track0.x"].tobytes()
    noise = compiled["track9.measured"] - compiled["track9.x"]
    assert 0.07 < np.std(noise) < 0.2  # sigma 0.09 times 1 to 2, 41 samples


def test_each_run_has_data_of_its_own(tmp_path):
    path = tmp_path / "trackers.yaml"
    path.write_text(SCENE)
    simulation = build_simulation(load_scenario(path))
    diagram = simulation.diagram
    other = diagram.create_context(seed=[1, 2], own_data=True)
    i = diagram.model_index["track4"]
    assert other.data[i].base is other.flat_data and simulation.context.data[i].base is simulation.context.flat_data
    other.data[i][1 + 4] = 99.0  # the run's own table (its first value)
    assert simulation.context.data[i][1 + 4] == 2.0
    np.testing.assert_array_equal(diagram.models[i].table[:-1], simulation.context.data[i][:-1])


def _two_engines():
    from dynamics import Multibody
    from shell.models.multibody import MultibodyModel

    root = Assembly("root")
    for name, rate in (("left", [0.1, 2.0, 0.0]), ("right", [1.0, 0.0, 0.3])):
        builder = Multibody()
        builder.add_body("bus", None, mass=10.0, inertia=[3.0, 2.0, 1.0], hinge="free")
        builder.add_node("tip", "bus", position=(1.0, 0.0, 0.0))
        system = builder.compile()
        q0, u0 = system.neutral_configuration(), np.zeros(system.nu)
        u0[:3] = rate
        root.add(MultibodyModel(name, system, initial_q=q0, initial_u=u0))
    return root


def test_two_engine_models_in_one_scene_run_compiled_as_interpreted():
    """Two torque-free tumbling bodies, each its own engine model: the compiled loop takes both engines' data
    (each by reference) and equals the interpreted run; each body's angular momentum in world axes is conserved."""
    runs = []
    for mode in ("interpreted", "compiled"):
        sim = Simulation(_two_engines(), step=0.01, mode=mode)
        sim.run(2.0)
        runs.append(sim)
    interpreted, compiled = runs
    assert compiled.mode == "compiled" and compiled._compiled_loop_applies()
    assert len(compiled.plan.op_data) == 2 and compiled.plan.references.size > 0
    assert compiled.x.tobytes() == interpreted.x.tobytes()
    for name in ("left", "right"):
        rotation = compiled.signal(f"{name}.tip.rotation")
        omega = compiled.signal(f"{name}.tip.angular_velocity")
        u0 = np.array([0.1, 2.0, 0.0]) if name == "left" else np.array([1.0, 0.0, 0.3])
        np.testing.assert_allclose(rotation @ (np.diag([3.0, 2.0, 1.0]) @ omega), np.diag([3.0, 2.0, 1.0]) @ u0,
                                   rtol=0, atol=1e-7)  # RK4 at 10 ms over 2 s: 1e-8 of |L| ~ 4
