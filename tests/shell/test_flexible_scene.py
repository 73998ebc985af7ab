"""A flexible body from a body file in a YAML scene: a sensor attached to a grid node sees elastic motion."""

import warnings

import numpy as np
import pytest

from shell.log_file import read_log
from shell.scenario import ScenarioError


@pytest.fixture(scope="module")
def beam_file(tmp_path_factory):
    from dynamics.flex.body_file import write_body_file
    from dynamics.flex.pipeline import Fem2ModalOptions, fem2modal

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the deck's unsupported EIGRL/QSET cards are reported, not needed
        body = fem2modal("configs/fem/SimpleBeam.dat", Fem2ModalOptions(n_modes=4, modal_integrals=True))
    path = tmp_path_factory.mktemp("beam") / "beam.h5"
    write_body_file(path, body)
    return path


SCENE = """
seed: 2
multibody:
  bodies:
    - name: beam
      hinge: free
      body_file: {file}
      damping_ratio: 0.0
      initial: {{modal: [0, 0, 0, 0]}}
  nodes:
    - {{name: root, body: beam, grid: 11}}        # reference point at the middle
    - {{name: tip, body: beam, grid: 10}}         # end of the 9 m beam, x = 4.5 m
models:
  push: {{type: Constant, config: {{unit: N, shape: [3]}}, parameters: {{value: "[0, 0, 50] N"}}}}
  sensor:
    type: AttitudeHoldLoop          # its gyro samples the tip's angular velocity; zero gains: no torque
    attach: {{node: tip}}
    parameters: {{period: 0.01 s, controller.kp: [0, 0, 0], controller.kd: [0, 0, 0]}}
connections:
  - push.y -> multibody.tip.force
integrator: {{step: 1 ms}}
log:
  rate: 100 Hz
  signals: [sensor.gyro.y, multibody.tip.angular_velocity, multibody.root.angular_velocity, multibody.beam.modal_u]
"""


def test_sensor_on_a_flexible_node_measures_elastic_motion(scene, tmp_path, beam_file):
    sim = scene(SCENE.format(file=beam_file))
    engine = sim.models[0]
    assert engine.system.nq == 7 + 4 and engine.system.nu == 6 + 4
    summary = sim.run(0.5, log_path=tmp_path / "beam.h5")
    # the run summary says which forward-dynamics solver the engine chose for the flexible body, and why
    assert summary.notes[0].startswith(f"multibody: forward dynamics by {engine.system.solver_reason}")
    assert "note: multibody: forward dynamics by " in str(summary)
    log = read_log(tmp_path / "beam.h5")
    # the gyro holds the tip node's angular velocity sampled at the same instants (zero noise)
    np.testing.assert_array_equal(log["sensor.gyro.y"], log["multibody.tip.angular_velocity"])
    # engine check of the port values at the final state: the port is the engine's node kinematics
    q, u = sim.x[:11], sim.x[11:]
    kinematics = engine.system.node_kinematics(q, u)
    np.testing.assert_allclose(sim.signal("multibody.tip.angular_velocity"), kinematics.angular_velocity[1],
                               rtol=0, atol=1e-15)
    # the tip turns relative to the root (the reference grid, rigid with the body frame): the difference
    # is the elastic slope rate Pi_rot(tip) eta_dot, to first order in the elastic rotation (measured
    # agreement 2e-16 relative here; tolerance 1e-3 relative allows the second-order terms)
    from dynamics.flex.body_file import read_body_file

    difference = log["multibody.tip.angular_velocity"] - log["multibody.root.angular_velocity"]
    modal_rates = log["multibody.beam.modal_u"]
    slope_rate = modal_rates @ read_body_file(beam_file).mode_shape(10)[:3].T
    assert np.max(np.abs(difference)) > 1e-2  # 0.022 rad/s: elastic motion the sensor measures
    np.testing.assert_allclose(difference, slope_rate, atol=1e-3 * np.max(np.abs(difference)))


def test_flexible_body_keys_are_checked(scene, beam_file):
    with pytest.raises(ScenarioError, match=r"scene.yaml:7: multibody.bodies\[0\]\(beam\).mass: the body file "
                                            r"gives the mass properties"):
        scene(f"""
        multibody:
          bodies:
            - name: beam
              hinge: free
              body_file: {beam_file}
              mass: 3 kg
        """)
    with pytest.raises(ScenarioError, match=r"scene.yaml:6: multibody.bodies\[0\]\(beam\).body_file: no body file"):
        scene("""
        multibody:
          bodies:
            - name: beam
              hinge: free
              body_file: missing.h5
        """)


def test_flexible_child_hinged_at_its_grid_from_yaml(scene, beam_file):
    sim = scene(f"""
    multibody:
      bodies:
        - {{name: beam1, hinge: free, body_file: {beam_file}}}
        - {{name: beam2, parent: beam1, parent_node: joint, hinge: revolute, axis: [0, 0, 1],
           body_file: {beam_file}, child_grid: 1, modes: [0, 1]}}
      nodes:
        - {{name: joint, body: beam1, grid: 10}}
    """)
    system = sim.models[0].system
    assert "beam2.hinge" in system.node_names and system.n_modes == (4, 2)
    from dynamics.layout import OUTBOARD_NODE

    assert system.topology[1, OUTBOARD_NODE] == system.node_index("beam2.hinge")
    with pytest.raises(ScenarioError, match=r"child_grid: expected an FE grid id"):
        scene(f"""
        multibody:
          bodies:
            - {{name: beam, hinge: free, body_file: {beam_file}, child_grid: first}}
        """)


def test_hinge_and_modal_ports_are_separate_with_their_units(scene, beam_file):
    """A flexible body on a revolute hinge: ``beam.q/u/u_dot/torque`` are the hinge's (rad, rad/s, rad/s^2,
    N m; one DOF: a drive torque needs no padding for the modes), ``beam.modal_q/modal_u/modal_u_dot`` and
    ``beam.modal_force`` the modal coordinates' (dimensionless, 1/s, 1/s^2, N m). Each port holds its own
    slice of the engine's coordinates; a modal force enters the modal equations (the same accelerations as
    the engine given that generalized force)."""
    sim = scene(f"""
    multibody:
      bodies:
        - {{name: beam, hinge: revolute, axis: [0, 0, 1], body_file: {beam_file}, damping_ratio: 0.0,
           initial: {{angle: 0.3 rad, angle_rate: 0.2 rad/s, modal: [1e-3, -2e-3, 0, 5e-4],
                     modal_rate: [0.1, 0, -0.05, 0]}}}}
    models:
      drive: {{type: Constant, config: {{unit: N*m, shape: [1]}}, parameters: {{value: "[40] N*m"}}}}
      shake: {{type: Constant, config: {{unit: N*m, shape: [4]}}, parameters: {{value: "[0, 3, 0, -1] N*m"}}}}
    connections:
      - drive.y -> multibody.beam.torque
      - shake.y -> multibody.beam.modal_force
    """)
    engine = sim.models[0]
    ports = {p.name: p for p in engine.outputs + engine.inputs}
    for name, unit, shape in (("beam.q", "rad", (1,)), ("beam.u", "rad/s", (1,)), ("beam.u_dot", "rad/s^2", (1,)),
                              ("beam.torque", "N*m", (1,)), ("beam.modal_q", "", (4,)), ("beam.modal_u", "1/s", (4,)),
                              ("beam.modal_u_dot", "1/s^2", (4,)), ("beam.modal_force", "N*m", (4,))):
        assert (ports[name].unit, ports[name].shape) == (unit, shape), name
    sim.run(0.01)
    system = engine.system
    q, u = sim.x[:system.nq], sim.x[system.nq:system.nq + system.nu]
    np.testing.assert_array_equal(sim.signal("multibody.beam.q"), q[:1])
    np.testing.assert_array_equal(sim.signal("multibody.beam.modal_q"), q[1:])
    np.testing.assert_array_equal(sim.signal("multibody.beam.u"), u[:1])
    np.testing.assert_array_equal(sim.signal("multibody.beam.modal_u"), u[1:])
    expected = system.forward_dynamics(q, u, tau=np.array([40.0, 0.0, 3.0, 0.0, -1.0]))
    np.testing.assert_allclose(np.concatenate([sim.signal("multibody.beam.u_dot"),
                                               sim.signal("multibody.beam.modal_u_dot")]), expected,
                               rtol=1e-13, atol=1e-13 * np.max(np.abs(expected)))
