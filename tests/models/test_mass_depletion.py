"""Mass depletion: a throttled jet emptying a body follows the exact sampled-mass sum and converges to
the rocket equation; the engine's mass properties follow the fill fraction."""

import textwrap

import numpy as np
from numpy.testing import assert_allclose

from shell.scenario import build_simulation, parse_scenario

ROCKET = """
multibody:
  bodies:
    - {name: stage, hinge: free, mass: 100 kg, inertia: "[40, 50, 60] kg*m^2"}
  nodes:
    - {name: cm, body: stage}
models:
  throttle: {type: Constant, config: {unit: N}, parameters: {value: 1000 N}}
  engine:
    type: Thruster
    rate: 1 Hz
    config: {mode: proportional}
    attach: {node: cm}
    parameters: {direction: [1, 0, 0], max_thrust: 1000 N, isp: 100 s}
  tanks:
    type: MassDepletion
    rate: RATE
    config: {body: stage}
    parameters:
      full_mass: 100 kg
      empty_mass: 50 kg
      full_inertia: "[[40, 0, 0], [0, 50, 0], [0, 0, 60]] kg*m^2"
      empty_inertia: "[[20, 0, 0], [0, 25, 0], [0, 0, 30]] kg*m^2"
      empty_com: "[0.2, 0, 0] m"
connections:
  - throttle.y -> engine.command
  - engine.propellant_used -> tanks.propellant_used
integrator: {method: rk4, step: 0.1 s}
"""


def test_constant_thrust_follows_the_sampled_mass_sum_and_the_rocket_equation():
    g0, isp, thrust, t_final = 9.80665, 100.0, 1000.0, 40.0      # 41 of 50 kg of propellant
    mdot = thrust / (isp * g0)
    velocities = []
    for rate, period in (("1 Hz", 1.0), ("10 Hz", 0.1)):
        sim = build_simulation(parse_scenario(textwrap.dedent(ROCKET).replace("RATE", rate), "rocket.yaml", None))
        sim.run(t_final - 1e-9)
        v = sim.signal("multibody.stage.u")[3]
        # exact for mass held over each sample: sum_k F T / m(t_k) (constant acceleration per interval,
        # integrated exactly by RK4); the last partial interval is 1e-9 s short
        t_k = np.arange(0.0, t_final, period)
        assert_allclose(v, np.sum(thrust * period / (100.0 - mdot * t_k)), rtol=1e-9)
        velocities.append(v)
        system = sim.models[sim.model_index["multibody"]].system
        used = float(sim.signal("engine.propellant_used"))
        f = (mdot * t_k[-1]) / 50.0
        assert_allclose(system.masses[0], 100.0 - mdot * t_k[-1], rtol=1e-12)
        assert_allclose(used, mdot * t_final, rtol=1e-9)
        assert_allclose(system.definitions[0][0].com, [0.2 * f, 0, 0], rtol=1e-12)
        # the run's data holds the depleted mass (the compiled loop read it: the velocity above); the engine's
        # model keeps the scene's (dynamics.model / dynamics.data)
        assert system.model.masses[0] == 100.0 and system.model.definitions[0][0].mass == 100.0
        assert system.params is system.data.params is not system.model.params
    rocket = isp * g0 * np.log(100.0 / (100.0 - mdot * t_final))
    # sampled mass lags the true mass by T/2 on average: error ~ (mdot T / 2 m) * dv, shrinking with T
    errors = [abs(v - rocket) / rocket for v in velocities]
    # (1 kg/s * T / 2 / ~75 kg: 7e-3 at T = 1 s, 7e-4 at 0.1 s): first order in T
    assert errors[0] < 1e-2 and errors[1] < 1e-3 and errors[1] < errors[0] / 9


def test_restart_between_samples_continues_bit_identically(tmp_path):
    """Save a depleting run between two mass samples, restore it into a freshly built scene (whose engine
    starts with the full-tank mass properties) and continue: the restored model re-applies its mass
    properties at once (Model.restored), so the result equals the straight run bit for bit. Without the
    hook the resumed engine flies 100 kg until the next sample: the velocity at 20 s is 2.6e-3 low."""
    text = textwrap.dedent(ROCKET).replace("RATE", "1 Hz")
    straight = build_simulation(parse_scenario(text, "rocket.yaml", None))
    straight.run(20.0)
    first = build_simulation(parse_scenario(text, "rocket.yaml", None))
    first.run(10.5)                      # between the 10 s and 11 s mass samples
    first.save_state(tmp_path / "restart.h5")
    resumed = build_simulation(parse_scenario(text, "rocket.yaml", None))
    system = resumed.models[resumed.model_index["multibody"]].system
    assert system.masses[0] == 100.0     # fresh scene: full tanks
    resumed.load_state(tmp_path / "restart.h5")
    assert system.masses[0] == first.models[first.model_index["multibody"]].system.masses[0] < 90.0
    resumed.run(20.0)
    assert resumed.x.tobytes() == straight.x.tobytes()
    assert resumed.z.tobytes() == straight.z.tobytes()
    assert system.definitions[0][0].com.tobytes() == \
        straight.models[straight.model_index["multibody"]].system.definitions[0][0].com.tobytes()
