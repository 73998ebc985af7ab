"""Thrusters: impulse per pulse and propellant use against Isp and the pulse train; minimum impulse bit;
rise/fall lags (analytic pulse area); momentum delivered to a free body."""

import textwrap

import numpy as np
from scipy.optimize import linprog
from numpy.testing import assert_allclose

from shell.scenario import build_simulation, parse_scenario

G0 = 9.80665

SCENE = """
multibody:
  bodies:
    - {name: bus, hinge: free, mass: 200 kg, inertia: "[50, 60, 70] kg*m^2"}
  nodes:
    - {name: cm, body: bus}
models:
  command: {type: Constant, config: {unit: UNIT}, parameters: {value: COMMAND}}
  jet:
    type: Thruster
    rate: RATE
    config: {mode: MODE}
    attach: {node: cm}
    parameters: {direction: [1, 0, 0], max_thrust: 10 N, isp: 220 s, min_on_time: 20 ms,
                 rise_time: RISE, fall_time: FALL}
connections: [command.y -> jet.command]
integrator: {method: rk4, step: STEP}
log: {rate: 10 Hz, signals: [multibody.bus.u]}
"""


def _run(tmp_path, t_final, command, mode="pwm", rate="10 Hz", rise="0 s", fall="0 s", step="0.01 s"):
    text = (textwrap.dedent(SCENE).replace("COMMAND", str(command)).replace("MODE", mode).replace("RATE", rate)
            .replace("RISE", rise).replace("FALL", fall).replace("STEP", step).replace("UNIT", "''" if mode == "on_off" else "N"))
    sim = build_simulation(parse_scenario(text, "jets.yaml", None))
    sim.run(t_final, log_path=tmp_path / "jets.h5")
    return sim


def test_pwm_pulse_train_impulse_and_propellant(tmp_path):
    # 4 N demanded of a 10 N jet at 10 Hz: 40 ms pulses; 10 cycles starting at t = 0, 0.1, ..., 0.9 s
    sim = _run(tmp_path, 0.95, 4.0)
    impulse = 10 * 10.0 * 0.04
    # the valve closes at an exactly located event (tolerance 1e-10 s), so the velocity is exact to
    # ~1e-10 s * 10 N / 200 kg
    assert_allclose(sim.signal("multibody.bus.u")[3], impulse / 200.0, rtol=0, atol=1e-11)
    assert_allclose(sim.signal("jet.propellant_used"), impulse / (220 * G0), rtol=1e-12)
    assert sim.signal("jet.valve")[3] == 10
    assert len([e for e in sim.events if e[1] == "jet.valve_closes"]) == 10


def test_minimum_impulse_bit(tmp_path):
    # 1.9 N -> 19 ms < 20 ms minimum on-time: no pulse at all; 2.0 N -> exactly the 0.2 N s bit
    sim = _run(tmp_path, 0.95, 1.9)
    assert sim.signal("multibody.bus.u")[3] == 0.0
    assert sim.signal("jet.propellant_used") == 0.0
    sim = _run(tmp_path, 0.05, 2.0)
    assert_allclose(sim.signal("multibody.bus.u")[3] * 200.0, 10.0 * 0.02, rtol=1e-9)


def test_rise_and_fall_lags_deliver_the_analytic_pulse_area(tmp_path):
    # one 1 s pulse (5 N of 10 N over a 2 s cycle), lags 50 ms up and 80 ms down; run until the tail has
    # decayed (exp(-0.99 / 0.08) = 4e-6 relative: the area formula includes the full tail, so compare
    # with the tail integrated to the stop time)
    t_on, tau_r, tau_f, f_max, t_end = 1.0, 0.05, 0.08, 10.0, 1.99
    sim = _run(tmp_path, t_end, 5.0, rate="0.5 Hz", rise="50 ms", fall="80 ms", step="1 ms")
    f1 = f_max * (1 - np.exp(-t_on / tau_r))
    area = f_max * (t_on - tau_r * (1 - np.exp(-t_on / tau_r))) + f1 * tau_f * (1 - np.exp(-(t_end - t_on) / tau_f))
    # RK4 with h / tau = 0.02 on a linear lag: relative error ~1e-9; the closing event puts the kink exactly
    assert_allclose(sim.signal("multibody.bus.u")[3] * 200.0, area, rtol=1e-8)
    assert_allclose(sim.signal("jet.propellant_used"), area / (220 * G0), rtol=1e-8)


def test_on_off_and_proportional_modes(tmp_path):
    sim = _run(tmp_path, 0.55, 1.0, mode="on_off")       # valve open every whole cycle: 0.55 s of thrust
    assert_allclose(sim.signal("multibody.bus.u")[3] * 200.0, 10.0 * 0.55, rtol=1e-12)
    sim = _run(tmp_path, 0.55, 3.5, mode="proportional")
    assert_allclose(sim.signal("multibody.bus.u")[3] * 200.0, 3.5 * 0.55, rtol=1e-12)
    sim = _run(tmp_path, 0.55, 30.0, mode="proportional")   # clipped at the maximum thrust
    assert_allclose(sim.signal("multibody.bus.u")[3] * 200.0, 10.0 * 0.55, rtol=1e-12)


def _octagon_positions():
    """Two thrusters per panel of an octagonal bus, 2 m across the flats, 1 m above and below."""
    return [[float(2 * np.cos(np.pi / 4 * (k // 2))), float(2 * np.sin(np.pi / 4 * (k // 2))),
             1.0 if k % 2 == 0 else -1.0] for k in range(16)]


def test_nonnegative_allocation_is_exact_and_push_only():
    from shell.assemblies.thruster_cluster import TM_G32_DIRECTIONS
    from shell.models.allocation import NonnegativeAllocator

    directions = TM_G32_DIRECTIONS / np.linalg.norm(TM_G32_DIRECTIONS, axis=1)[:, None]
    a = np.cross(np.array(_octagon_positions()), directions).T
    allocator = NonnegativeAllocator("alloc", demand=3, actuators=16, demand_unit="N*m", command_unit="N",
                                     effectiveness=a)
    rng = np.random.default_rng(3)
    y = np.empty(16)
    for demand in rng.normal(size=(50, 3)) * 5.0:
        allocator.update(0.0, None, y, demand, allocator.p)
        assert np.all(y >= 0.0)
        # minimum fuel: no combination of fewer newtons exists (checked from the LP dual: a
        # cheaper push-only solution would lower the objective; compare with an interior-point solve)
        other = linprog(np.ones(16), A_eq=a, b_eq=demand, bounds=[(0, None)] * 16, method="highs-ipm").fun
        assert_allclose(y.sum(), other, rtol=1e-7)
        assert_allclose(a @ y, demand, rtol=0, atol=1e-9 * np.abs(y).max())    # LP feasibility tolerance


def test_a_repeated_program_is_not_solved_again_and_gives_the_same_commands(monkeypatch):
    """A held demand asks the same linear program at every sample: the allocator answers it from the last
    solution (bit-identical: HiGHS is deterministic); a new demand or a new effectiveness is solved again."""
    import scipy.optimize

    from shell.assemblies.thruster_cluster import TM_G32_DIRECTIONS
    from shell.models.allocation import NonnegativeAllocator

    directions = TM_G32_DIRECTIONS / np.linalg.norm(TM_G32_DIRECTIONS, axis=1)[:, None]
    a = np.cross(np.array(_octagon_positions()), directions).T
    allocator = NonnegativeAllocator("alloc", demand=3, actuators=16, demand_unit="N*m", command_unit="N",
                                     effectiveness=a)
    fresh = NonnegativeAllocator("fresh", demand=3, actuators=16, demand_unit="N*m", command_unit="N",
                                 effectiveness=a)
    calls = []
    real = scipy.optimize.linprog
    monkeypatch.setattr(scipy.optimize, "linprog", lambda *args, **kw: calls.append(1) or real(*args, **kw))
    first, again, expected = np.empty(16), np.full(16, np.nan), np.empty(16)
    demand = np.array([0.05, -0.03, 0.04])
    allocator.update(0.0, None, first, demand, allocator.p)
    allocator.update(0.05, None, again, demand.copy(), allocator.p)
    assert len(calls) == 1 and again.tobytes() == first.tobytes()
    other = np.array([0.05, -0.03, 0.0400000001])
    allocator.update(0.1, None, again, other, allocator.p)
    fresh.update(0.1, None, expected, other, fresh.p)
    assert len(calls) == 3 and again.tobytes() == expected.tobytes()
    allocator.p[:] = 2.0 * allocator.p                   # effectiveness doubled (e.g. another context's values)
    allocator.update(0.15, None, again, other, allocator.p)
    assert len(calls) == 4
    assert_allclose(again, expected / 2.0, rtol=1e-9)


def test_sixteen_thruster_cluster_delivers_the_demanded_angular_impulse(tmp_path):
    positions = _octagon_positions()
    text = textwrap.dedent(f"""
    multibody:
      bodies:
        - {{name: bus, hinge: free, mass: 5000 kg, inertia: "[1000000, 1000000, 1000000] kg*m^2"}}
      nodes:
        - {{name: cm, body: bus}}
    models:
      demand: {{type: Constant, config: {{unit: N*m, shape: [3]}}, parameters: {{value: "[2, -1, 3] N*m"}}}}
      jets:
        type: ThrusterCluster
        config: {{period: 0.1 s}}
        attach: {{node: cm}}
        parameters: {{positions: "{positions} m", max_thrust: 20 N, isp: 70 s}}
    connections: [demand.y -> jets.torque_command]
    integrator: {{method: rk4, step: 0.01 s}}
    """)
    sim = build_simulation(parse_scenario(text, "jets.yaml", None))
    sim.run(0.999)                                          # 10 whole pwm cycles of 0.1 s
    omega = sim.signal("multibody.bus.u")[:3]
    # J omega = demand * 1 s (duty cycles reproduce the mean command exactly; the body turns by
    # ~1e-6 rad, so body and world axes agree to 1e-6 relative)
    assert_allclose(omega * 1e6, np.array([2.0, -1.0, 3.0]) * 1.0, rtol=1e-5)
    used = sum(sim.signal(f"jets.jet{k}.propellant_used") for k in range(1, 17))
    assert used > 0
