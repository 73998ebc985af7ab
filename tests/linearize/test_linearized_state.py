"""LinearizedState: the engine's q and u in the coordinates of a model written by ``flexshell linearize``.

A free-flying bus with a revolute arm (q: quaternion, position, arm angle) is linearized with the command line,
then run in a scene with ``LinearizedState`` wired from ``multibody.q`` and ``multibody.u``:

* at the operating point the output is 0 (exactly: the map subtracts the operating point it was given);
* from a perturbed state (a tumbling bus, another arm angle) every logged sample equals the deviation computed
  independently here: scipy's rotation vector of ``R0^-1 R`` for the quaternion (``Rotation.as_rotvec``, its
  own Log) and plain differences for the rest, to 1e-14 (round-off of a few operations on numbers ~1).

The compiled Log map itself is checked against scipy on random rotations (both quaternion signs, angles from
1e-9 rad to pi) and as the exact inverse of linearize's Exp (:func:`shell.analysis.linearize.quaternion_exp`).
"""

from __future__ import annotations

import textwrap

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from shell.analysis.linearize import quaternion_exp
from shell.attitude import quaternion_rotation_vector
from shell.cli import main
from shell.log_file import read_log
from shell.scenario import ScenarioError, build_simulation, parse_scenario

Q0 = [0.9238795325112867, 0.0, 0.3826834323650898, 0.0]  # 45 deg about y
PLANT = f"""
name: bus_and_arm
multibody:
  gravity: "[0, 0, 0] m/s^2"
  bodies:
    - name: bus
      parent: world
      hinge: free
      mass: 100 kg
      com: "[0, 0, 0] m"
      inertia: "[[40, 1, 0], [1, 30, 0], [0, 0, 25]] kg*m^2"
      initial: {{attitude: {Q0}, angular_velocity: "[0, 0, 0] deg/s"}}
    - name: arm
      parent: bus
      hinge: revolute
      axis: [0, 0, 1]
      mass: 5 kg
      com: "[0.5, 0, 0] m"
      inertia: "[1, 1, 1] kg*m^2"
      initial: {{angle: 10 deg}}
  nodes:
    - {{name: acs, body: bus}}
integrator: {{method: rk4, step: 0.01 s}}
stop: {{time: 1 s}}
"""


@pytest.fixture(scope="module")
def plant(tmp_path_factory):
    """(directory, linear-model file) of the plant, linearized by the command line."""
    directory = tmp_path_factory.mktemp("linearized_state")
    (directory / "plant.yaml").write_text(PLANT)
    assert main(["linearize", str(directory / "plant.yaml"), "--inputs", "multibody.acs.torque", "--outputs",
                 "multibody.acs.angular_velocity", "-o", str(directory / "plant.h5")]) == 0
    return directory, directory / "plant.h5"


def _estimate_scene(model_file) -> str:
    return PLANT.replace("integrator:", textwrap.dedent(f"""\
        models:
          x_hat: {{type: LinearizedState, config: {{linear_model: {model_file}}}}}
        connections: [multibody.q -> x_hat.q, multibody.u -> x_hat.u]
        log: {{rate: 100 Hz, signals: [x_hat.x, multibody.q, multibody.u]}}
        integrator:"""))


def test_zero_at_the_operating_point_and_the_deviation_elsewhere(plant, capsys):
    directory, model_file = plant
    scene = directory / "estimate.yaml"
    scene.write_text(_estimate_scene(model_file))
    assert main(["run", str(scene), "-o", str(directory / "at_rest.h5")]) == 0
    assert "interpreted" not in capsys.readouterr().err
    log = read_log(directory / "at_rest.h5")
    assert log["x_hat.x"].shape == (101, 14) and np.all(log["x_hat.x"] == 0.0)

    assert main(["run", str(scene), "-o", str(directory / "moving.h5"),
                 "--set", "multibody.bus.initial.angular_velocity=[10, 20, -30] deg/s",
                 "--set", "multibody.bus.initial.velocity=[0.1, 0, -0.2] m/s",
                 "--set", "multibody.arm.initial.angle=20 deg"]) == 0
    log = read_log(directory / "moving.h5")
    q, u, x = log["multibody.q"], log["multibody.u"], log["x_hat.x"]
    rotation = (Rotation.from_quat([Q0[1], Q0[2], Q0[3], Q0[0]]).inv()
                * Rotation.from_quat(np.c_[q[:, 1:4], q[:, 0]])).as_rotvec()
    expected = np.c_[rotation, q[:, 4:7], q[:, 7] - np.radians(10.0), u]
    assert np.max(np.abs(rotation)) > 0.5  # the bus turned by more than 30 deg: the Log's nonlinear range
    np.testing.assert_allclose(x, expected, rtol=0, atol=1e-14)


def test_refusals_name_the_file_and_key(plant, tmp_path):
    directory, model_file = plant
    with_integrator = PLANT.replace("integrator:", textwrap.dedent("""\
        models:
          angle: {type: Integrator, config: {unit: rad, shape: [3]}}
        connections: [multibody.acs.angular_velocity -> angle.u]
        integrator:"""))
    (tmp_path / "with_integrator.yaml").write_text(with_integrator)
    assert main(["linearize", str(tmp_path / "with_integrator.yaml"), "--inputs", "multibody.acs.torque",
                 "--outputs", "multibody.acs.angular_velocity", "-o", str(tmp_path / "other.h5")]) == 0
    for file, message in ((tmp_path / "other.h5", r"names/states: state 'angle.x\[0\]' is not a coordinate of the "
                                                   r"engine's q or u"),
                          (tmp_path / "plant.mat", "expected the HDF5 linear-model file"),
                          (directory / "plant.yaml", "expected the HDF5 linear-model file")):
        text = _estimate_scene(file)
        with pytest.raises(ScenarioError, match=rf"scene.yaml:\d+: models.x_hat.config.linear_model: .*{message}"):
            build_simulation(parse_scenario(text, "scene.yaml", None))
    locked = _estimate_scene(model_file).replace("hinge: revolute\n      axis: [0, 0, 1]", "hinge: locked").replace(
        "      initial: {angle: 10 deg}\n", "")  # q has 7 entries, not 8
    with pytest.raises(ScenarioError, match=r"x_hat.q"):
        build_simulation(parse_scenario(locked, "scene.yaml", None))


def test_log_map_is_scipy_rotvec_and_inverts_linearize_exp():
    rng = np.random.default_rng(30)
    axes = rng.normal(size=(200, 3))
    axes /= np.linalg.norm(axes, axis=1, keepdims=True)
    angles = np.concatenate([np.logspace(-9, 0, 100), rng.uniform(1.0, np.pi - 1e-6, 100)])
    for axis, angle in zip(axes, angles):
        phi = axis * angle
        q = quaternion_exp(phi)
        np.testing.assert_allclose(quaternion_rotation_vector(tuple(q)), phi, rtol=0, atol=4e-16 * max(1, angle))
        flipped = tuple(-q)  # the same rotation
        np.testing.assert_allclose(quaternion_rotation_vector(flipped), phi, rtol=0, atol=4e-16 * max(1, angle))
        scipy = Rotation.from_quat([q[1], q[2], q[3], q[0]]).as_rotvec()
        np.testing.assert_allclose(quaternion_rotation_vector(tuple(q)), scipy, rtol=0, atol=1e-15)
