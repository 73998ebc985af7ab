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
  signals: [sensor.gyro.y, multibody.tip.angular_velocity, multibody.root.angular_velocity, multibody.beam.u]
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
    modal_rates = log["multibody.beam.u"][:, 6:]
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
    from dynamics.flexible_kernels import OUTBOARD_NODE

    assert system.topology[1, OUTBOARD_NODE] == system.node_index("beam2.hinge")
    with pytest.raises(ScenarioError, match=r"child_grid: expected an FE grid id"):
        scene(f"""
        multibody:
          bodies:
            - {{name: beam, hinge: free, body_file: {beam_file}, child_grid: first}}
        """)
