"""A flexible scene's engine computes the kinematics of the nodes something reads, and only those (issue 28,
must-show 3: the observatory's sixteen nodes that only its linearization drives were ~40 % of each derivative).

Scene: a free-free beam (the KRB deck, 6 modes) on a revolute hinge, spinning and deforming; node ``a`` carries an IMU
(continuous states integrating a's velocity and acceleration: read by every derivative), node ``b`` is logged,
node ``c`` is read by nothing, node ``d`` receives a force. Checked:

* which nodes are read (connection, log) and that the run summary says which are not computed; a node nothing
  reads has NaN outputs (never a stale value);
* against the engine's own all-node kinematics (:meth:`dynamics.MultibodySystem.node_kinematics`, the unmasked
  kernel, an independent call at the logged state): the read nodes' outputs are equal to the last bit (the same
  arithmetic on the same state);
* a scene with every node read gives the same trajectory and node outputs, bit for bit, as the scene with
  ``c`` unread (the mask selects what is computed, never how);
* an unread node read later by name (``Simulation.signal``) or by a linearization, or connected in another scene,
  gets its correct value;
* per evaluation kind: a derivative evaluation (the integrator's right-hand side) computes only ``a``, which the IMU's
  derivatives read (its outputs equal the engine's own kinematics at that state: the pose and velocity to the last
  bit, the acceleration to round-off), and leaves ``b`` and a sampled reader's ``c`` NaN, interpreted and compiled
  alike; the logs are bit-identical with every read node computed in every derivative; a sample-and-hold of ``c``
  holds, at each of its samples, the engine's ``c`` at that state to the last bit; a node only logged, read by name
  after the run, is the engine's at the final state.
"""

from __future__ import annotations

import numpy as np
import pytest

from shell.cli import main
from shell.log_file import MemoryLog
from shell.scenario import build_simulation, load_scenario
from tests.flexible.test_spinup_beam import N_ELEMENTS, krb_deck


@pytest.fixture(scope="module")
def body_file(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("nodes_read")
    (tmp / "krb.dat").write_text(krb_deck())
    assert main(["fem2modal", str(tmp / "krb.dat"), "--modes", "6", "--modal-integrals", "-q",
                 "-o", str(tmp / "krb.h5")]) == 0
    return tmp / "krb.h5"


def build(body_file, logged=("b",), attach_c=False, hold_c=False):
    signals = [f"multibody.{n}.position" for n in logged] + [f"multibody.{n}.linear_velocity" for n in logged] \
        + ["multibody.q", "multibody.u", "imu.angular_rate"]
    extra = """
  gyro2:
    type: Imu
    rate: 100 Hz
    attach: {node: c}""" if attach_c else ""
    text = f"""name: nodes_read
multibody:
  bodies:
    - name: beam
      hinge: revolute
      axis: [0, 0, 1]
      body_file: {body_file.name}
      modal_integrals_order: 1
      initial: {{angle_rate: 0.5 rad/s}}
  nodes:
    - {{name: a, body: beam, grid: 5}}
    - {{name: b, body: beam, grid: {N_ELEMENTS + 1}}}
    - {{name: c, body: beam, grid: 12}}
    - {{name: d, body: beam, grid: 16}}
models:
  imu:
    type: Imu
    rate: 100 Hz
    attach: {{node: a}}{extra}
  push:
    type: Constant
    config: {{unit: N, shape: [3]}}
    parameters: {{value: "[0, 0.5, 2] N"}}
connections:
  - push.y -> multibody.d.force
integrator: {{method: rk4, step: 1 ms}}
stop: {{time: 0.05 s}}
log:
  rate: 100 Hz
  signals: {signals}
"""
    if hold_c:  # a sampled reader of c: a zero-order hold at half the log's rate, logged
        signals = signals + ["hold.y"]
        hold = "  hold: {type: SampleHold, rate: 50 Hz, config: {unit: m, shape: [3]}}\n"
        text = text.replace("models:\n", "models:\n" + hold)
        text = text.replace("connections:\n", "connections:\n  - multibody.c.position -> hold.u\n")
        text = text.replace(f"signals: {signals[:-1]}", f"signals: {signals}")
    path = body_file.parent / f"scene_{'_'.join(logged)}_{attach_c}_{hold_c}.yaml"
    path.write_text(text)
    return build_simulation(load_scenario(str(path)))


def engine(sim):
    return next(m for m in sim.models if m.path == "multibody")


def run_log(sim, duration=0.05):
    log = MemoryLog(sim.log_groups())
    sim.run(duration, log_path=log)
    return {k: np.asarray(v[1]) for k, v in log.signals().items()}


def test_only_the_read_nodes_are_computed_and_the_summary_says_so(body_file):
    sim = build(body_file)
    model = engine(sim)
    assert model.nodes_read == ("a", "b")  # a: the IMU's connections; b: logged; c: nothing; d: only a force in
    assert any("node kinematics of 2 of 4 nodes" in n and "c, d" in n for n in model.notes), model.notes
    sim.run(0.01)
    sim.evaluate()
    y = sim.signals[sim.diagram.port_slices[("multibody", "c.position")]]
    assert np.isnan(y).all()  # not computed: NaN, never a stale value
    assert np.isnan(sim.signals[sim.diagram.port_slices[("multibody", "d.linear_acceleration")]]).all()


def test_read_nodes_equal_the_all_node_kinematics_to_the_last_bit(body_file):
    sim = build(body_file)
    data = run_log(sim)
    system = engine(sim).system
    nq = system.nq
    assert data["multibody.b.position"].shape[0] == 6
    for k in range(data["multibody.q"].shape[0]):
        kin = system.node_kinematics(data["multibody.q"][k], data["multibody.u"][k])
        b = system.node_names.index("b")
        np.testing.assert_array_equal(data["multibody.b.position"][k], kin.position[b])
        np.testing.assert_array_equal(data["multibody.b.linear_velocity"][k], kin.linear_velocity[b])
    assert np.ptp(data["multibody.q"][:, 1:nq], axis=0).max() > 1e-9  # the beam deforms (modal coordinates move)


def test_every_node_read_gives_the_same_run_bit_for_bit(body_file):
    some = run_log(build(body_file))
    every = run_log(build(body_file, logged=("a", "b", "c", "d")))
    assert engine(build(body_file, logged=("a", "b", "c", "d"))).nodes_read == ("a", "b", "c", "d")
    for key in ("multibody.q", "multibody.u", "imu.angular_rate", "multibody.b.position"):
        np.testing.assert_array_equal(some[key], every[key])


def test_a_node_read_later_by_name_by_linearization_or_connected_is_right(body_file):
    sim = build(body_file)
    sim.run(0.02)
    system = engine(sim).system
    c = system.node_names.index("c")
    value = sim.signal("multibody.c.position")  # read by name: computed from now on, evaluated first
    assert engine(sim).nodes_read == ("a", "b", "c")
    x = sim.x[sim.diagram.x_block[sim.diagram.model_index["multibody"]]]
    kin = system.node_kinematics(x[:system.nq], x[system.nq:])
    np.testing.assert_array_equal(value, kin.position[c])

    from shell.analysis.linearize import linearize

    plain, logged = build(body_file), build(body_file, logged=("b", "c"))
    lin = [linearize(s, ["multibody.d.force[2]"], ["multibody.c.position", "multibody.c.angular_velocity"])
           for s in (plain, logged)]
    assert np.isfinite(lin[0].C).all() and np.abs(lin[0].C).max() > 0
    np.testing.assert_array_equal(lin[0].C, lin[1].C)
    np.testing.assert_array_equal(lin[0].D, lin[1].D)

    connected = build(body_file, attach_c=True)
    assert engine(connected).nodes_read == ("a", "b", "c")
    data, reference = run_log(connected), run_log(build(body_file, logged=("b", "c")))
    np.testing.assert_array_equal(data["multibody.q"], reference["multibody.q"])


def node_outputs(sim, node):
    """{signal: value} of a node's outputs in the signal buffer."""
    slices = sim.diagram.port_slices
    return {k: sim.signals[slices[("multibody", f"{node}.{k}")]].copy()
            for k in ("position", "rotation", "angular_velocity", "linear_velocity", "linear_acceleration")}


@pytest.mark.parametrize("mode", ["compiled", "interpreted"])
def test_a_derivative_evaluation_computes_the_nodes_derivatives_read(body_file, mode):
    sim = build(body_file, hold_c=True)
    model = engine(sim)
    assert model.nodes_read == ("a", "b", "c")  # a: the IMU; b: logged; c: the hold (sampled)
    assert model.nodes_read_in_derivatives == ("a",)  # the IMU integrates a's motion: read by every derivative
    assert any("between samples" in n and "node kinematics of a only" in n and "b, c" in n for n in model.notes)
    sim.run(0.013)  # between samples of the hold, off the log's instants
    y = sim.x.copy()
    if mode == "compiled":
        xdot = sim.plan.derivative(sim.t, y)
    else:
        xdot = sim.diagram.derivatives(sim.context, sim.t, y)
    system = model.system
    block = sim.diagram.x_block[sim.diagram.model_index["multibody"]]
    q, u, udot = y[block][:system.nq], y[block][system.nq:], xdot[block][system.nq:]
    kin = system.node_kinematics(q, u, udot)
    a = node_outputs(sim, "a")
    index = system.node_names.index("a")
    np.testing.assert_array_equal(a["position"], kin.position[index])  # the same arithmetic: to the last bit
    np.testing.assert_array_equal(a["rotation"].reshape(3, 3), kin.rotation[index])
    np.testing.assert_array_equal(a["angular_velocity"], kin.angular_velocity[index])
    np.testing.assert_array_equal(a["linear_velocity"], kin.linear_velocity[index])
    # the forward dynamics' body accelerations against a kinematics pass with its udot: equal to round-off (1e-12 of
    # the largest term, the centripetal acceleration of the 0.5 rad/s spin)
    scale = np.abs(kin.linear_acceleration[index]).max()
    np.testing.assert_allclose(a["linear_acceleration"], kin.linear_acceleration[index], rtol=0, atol=1e-12 * scale)
    imu_in = sim.signals[sim.diagram.port_slices[("imu", "linear_acceleration")]]
    np.testing.assert_array_equal(imu_in, a["linear_acceleration"])  # what the IMU's derivatives integrated
    for node in ("b", "c"):  # read only at samples and logs: not computed between them, NaN (never stale)
        for key, value in node_outputs(sim, node).items():
            assert np.isnan(value).all(), (node, key)
    sim.evaluate()  # an evaluation that reads every output computes them at the current state
    kin = system.node_kinematics(q, u)
    for node in ("b", "c"):
        np.testing.assert_array_equal(node_outputs(sim, node)["position"], kin.position[system.node_names.index(node)])


def test_logs_are_bit_identical_with_every_read_node_computed_in_every_derivative(body_file):
    selected = build(body_file, hold_c=True)
    every = build(body_file, hold_c=True)
    ports = engine(every).ports
    ports.node_read_in_derivatives[:] = ports.node_read  # what the model computed before the selection per kind
    assert engine(every).nodes_read_in_derivatives == ("a", "b", "c")
    logs = run_log(selected), run_log(every)
    assert set(logs[0]) == set(logs[1]) and "hold.y" in logs[0]
    for key in logs[0]:
        np.testing.assert_array_equal(logs[0][key], logs[1][key])
    np.testing.assert_array_equal(selected.x, every.x)
    assert np.isfinite(logs[0]["multibody.b.position"]).all() and np.isfinite(logs[0]["hold.y"]).all()


def test_a_sampled_reader_holds_the_node_at_its_samples_and_a_logged_node_read_by_name_after_the_run(body_file):
    sim = build(body_file, hold_c=True)
    data = run_log(sim)  # log at 100 Hz, the hold at 50 Hz: rows 0, 2, 4 are its samples
    system = engine(sim).system
    c = system.node_names.index("c")
    held = data["hold.y"]
    assert held.shape[0] == 6
    for k in range(held.shape[0]):
        sample = k - k % 2
        kin = system.node_kinematics(data["multibody.q"][sample], data["multibody.u"][sample])
        np.testing.assert_array_equal(held[k], kin.position[c])
    assert np.abs(held[2] - held[0]).max() > 1e-9  # the node moves between samples: the check can fail
    x = sim.x[sim.diagram.x_block[sim.diagram.model_index["multibody"]]]
    kin = system.node_kinematics(x[:system.nq], x[system.nq:])
    b = system.node_names.index("b")
    np.testing.assert_array_equal(sim.signal("multibody.b.position"), kin.position[b])
    np.testing.assert_array_equal(sim.signal("multibody.b.linear_velocity"), kin.linear_velocity[b])
