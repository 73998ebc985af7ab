"""Linear-model export: HDF5 (TM-2020-5008164 App. G.4 layout) round trip, MATLAB .mat, python-control,
and the ``flexshell linearize`` command."""

from __future__ import annotations

from pathlib import Path

import h5py
import numpy as np
import pytest
from scipy.io import loadmat

from shell.analysis.linear_model_file import read_linear_model, to_statespace, write_linear_model, write_mat
from shell.analysis.linearize import _skew, linearize
from shell.cli import main
from tests.linearize.plants import chain_scene

REPO = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def model():
    return linearize(chain_scene(), ["amplifier.u", "chain.force[1]"], ["chain.position", "sensor.y[2]"],
                     metadata={"scenario": "chain", "delivery": {"damping": 0.0025}})


def test_hdf5_round_trip(model, tmp_path):
    path = tmp_path / "lin.h5"
    write_linear_model(path, model)
    back = read_linear_model(path)
    for key in "ABCD":
        np.testing.assert_array_equal(getattr(back, key), getattr(model, key))
        np.testing.assert_array_equal(back.errors[key], model.errors[key])
    assert back.state_names == model.state_names and back.input_units == model.input_units
    assert list(back.input_index) == ["amplifier.u", "chain.force[1]"]
    np.testing.assert_array_equal(back.input_index["chain.force[1]"], [3])
    np.testing.assert_array_equal(back.output_index["sensor.y[2]"], [3])
    np.testing.assert_array_equal(back.operating_point["x"], model.operating_point["x"])
    assert back.metadata["scenario"] == "chain" and back.method["order"] == 6
    with h5py.File(path) as f:  # the G.4 delivery layout: matrices at the root, index maps as groups
        assert set(f) >= {"A", "B", "C", "D", "state_index", "input_index", "output_index", "operating_point"}
        assert f["input_index/amplifier.u"].attrs["unit"] == "kN"


def test_mat_file(model, tmp_path):
    path = tmp_path / "lin.mat"
    write_mat(path, model)
    m = loadmat(path)
    for key in "ABCD":
        np.testing.assert_array_equal(m[key], getattr(model, key))
    assert [str(c[0][0]) for c in m["input_names"]] == model.input_names


def test_python_control_statespace_with_names(model):
    """The StateSpace's frequency response equals C (jw I - A)^-1 B + D evaluated directly."""
    system = to_statespace(model)
    assert system.input_labels[3] == "chain/force[1]" and system.output_labels[3] == "sensor/y[2]"
    for w in (0.3, 7.0, 40.0):
        direct = model.C @ np.linalg.solve(1j * w * np.eye(6) - model.A, model.B) + model.D
        np.testing.assert_allclose(system(1j * w), direct, rtol=1e-12, atol=1e-15)


def test_command_line_on_the_demo_scene(tmp_path):
    """``flexshell linearize`` on configs/demo_attitude_hold.yaml: the bus tumbles at w0 = [2, -1, 3] deg/s
    with inertia J; the rotational block equals the linearized Euler equations
    J dw' = ([J w0 x] - [w0 x] J) dw + dtau and phi' = -[w0 x] phi / 2 + dw (tolerance 1e-9: FD truncation
    at tol 1e-10 on O(1) entries)."""
    out, mat = tmp_path / "demo_lin.h5", tmp_path / "demo_lin.mat"
    rc = main(["linearize", str(REPO / "configs/demo_attitude_hold.yaml"), "--inputs", "multibody.acs.torque",
               "--outputs", "multibody.acs.angular_velocity", "--outputs", "controller.torque", "-o", str(out),
               "--mat", str(mat)])
    assert rc == 0 and mat.exists()
    model = read_linear_model(out)
    J = np.array([[400.0, 5.0, 0.0], [5.0, 300.0, 0.0], [0.0, 0.0, 250.0]])
    w0 = np.deg2rad([2.0, -1.0, 3.0])
    np.testing.assert_allclose(model.A[0:3, 0:3], -0.5 * _skew(w0), atol=1e-9)
    np.testing.assert_allclose(model.A[0:3, 6:9], np.eye(3), atol=1e-9)
    np.testing.assert_allclose(model.A[6:9, 6:9], np.linalg.solve(J, _skew(J @ w0) - _skew(w0) @ J), atol=1e-9)
    np.testing.assert_allclose(model.B[6:9], np.linalg.inv(J), atol=1e-12)
    np.testing.assert_allclose(model.C[3:6], 0.0, atol=0)  # the sampled controller's output is held
    assert model.metadata["scenario_name"] == "demo_attitude_hold"


def test_command_line_refuses_unknown_port(tmp_path, capsys):
    rc = main(["linearize", str(REPO / "configs/demo_attitude_hold.yaml"), "--inputs", "multibody.acs.torq",
               "--outputs", "multibody.acs.angular_velocity", "-o", str(tmp_path / "x.h5")])
    assert rc == 1
    assert "no port or state 'acs.torq'" in capsys.readouterr().err
    assert not (tmp_path / "x.h5").exists()


PENDULUM_YAML = """
name: pendulum
multibody:
  gravity: "[0, -9.81, 0] m/s^2"
  bodies:
    - name: rod
      parent: world
      hinge: revolute
      axis: [0, 0, 1]
      mass: 2 kg
      com: "[0, -1.5, 0] m"
      inertia: "[0.001, 0.001, 0.001] kg*m^2"
      initial: {angle: 0.3 rad}
  nodes:
    - {name: tip, body: rod, position: "[0, -1.5, 0] m"}
"""


def test_command_line_trims_before_linearizing(tmp_path):
    """``--trim --hold multibody.u``: the pendulum released at 0.3 rad is trimmed to hang at 0
    (A21 = -m g l / I); ``--trim --free`` with everything held solves the holding torque m g l sin(0.3)."""
    scene = tmp_path / "pendulum.yaml"
    scene.write_text(PENDULUM_YAML)
    inertia = 2.0 * 1.5 ** 2 + 1e-3
    out = tmp_path / "hanging.h5"
    assert main(["linearize", str(scene), "--inputs", "multibody.rod.torque", "--outputs", "multibody.tip.position",
                 "--trim", "--hold", "multibody.u", "-o", str(out)]) == 0
    model = read_linear_model(out)
    np.testing.assert_allclose(model.operating_point["x"], [0.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(model.A[1, 0], -2.0 * 9.81 * 1.5 / inertia, rtol=1e-9)
    assert model.metadata["trim_residual"] < 1e-12
    out = tmp_path / "held.h5"
    assert main(["linearize", str(scene), "--inputs", "multibody.rod.torque", "--outputs", "multibody.tip.position",
                 "--trim", "--hold", "multibody.q,multibody.u", "--free", "multibody.rod.torque", "-o", str(out)]) == 0
    model = read_linear_model(out)
    np.testing.assert_allclose(model.operating_point["u"], [2.0 * 9.81 * 1.5 * np.sin(0.3)], rtol=1e-10)
    np.testing.assert_allclose(model.operating_point["xdot"], 0.0, atol=1e-10)
    assert main(["linearize", str(scene), "--inputs", "multibody.rod.torque", "--outputs", "multibody.tip.position",
                 "--hold", "multibody.u", "-o", str(tmp_path / "x.h5")]) == 1
