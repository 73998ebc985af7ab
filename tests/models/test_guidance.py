"""Guidance: attitude targets in every YAML form against independent constructions (scipy, elementary
rotations), refusals with file, line and key; the eigenaxis slew's bang-coast-bang profile against its
closed form and its rate outputs against the derivative of its attitude; nadir and Sun pointing frames
(boresight on the target direction, reference rate = derivative of the reference attitude); a slew
flown by MrpFeedback through the command line."""

import textwrap

import numpy as np
import pytest
from numpy.testing import assert_allclose
from scipy.spatial.transform import Rotation

from shell.attitude_target import parse_attitude_target
from shell.cli import main
from shell.log_file import read_log
from shell.model import ModelError
from shell.models.guidance import slew_duration
from shell.scenario import ScenarioError, build_simulation, parse_scenario


def _qmul(a, b):
    return np.r_[a[0] * b[0] - a[1:] @ b[1:], a[0] * b[1:] + b[0] * a[1:] + np.cross(a[1:], b[1:])]


def _elementary(axis, angle):
    return np.r_[np.cos(angle / 2), np.sin(angle / 2) * np.eye(3)[axis]]


def _dcm(q):
    w, x, y, z = q
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                     [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                     [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])


def _same_rotation(a, b, atol):
    assert min(np.abs(a - b).max(), np.abs(a + b).max()) <= atol, (a, b)


def test_targets_in_every_form_equal_independent_constructions():
    where = "model m: parameter target"
    axis = np.array([1.0, -2.0, 0.5]) / np.linalg.norm([1.0, -2.0, 0.5])
    q = parse_attitude_target({"axis": [1.0, -2.0, 0.5], "angle": "40 deg"}, where)
    x, y, z, w = Rotation.from_rotvec(np.radians(40.0) * axis).as_quat()
    _same_rotation(q, np.array([w, x, y, z]), 1e-15)
    # intrinsic ZYX (yaw, pitch, roll) = z(a) then y'(b) then x''(c): q = qz (x) qy (x) qx
    q = parse_attitude_target({"euler": ["30 deg", "-20 deg", "10 deg"], "sequence": "ZYX"}, where)
    expected = _qmul(_qmul(_elementary(2, np.radians(30)), _elementary(1, np.radians(-20))), _elementary(0, np.radians(10)))
    _same_rotation(q, expected, 1e-15)
    # extrinsic xyz: x first about the fixed axes, so q = qz (x) qy (x) qx as well
    q = parse_attitude_target({"euler": [0.1, 0.2, 0.3], "sequence": "xyz"}, where)
    _same_rotation(q, _qmul(_qmul(_elementary(2, 0.3), _elementary(1, 0.2)), _elementary(0, 0.1)), 1e-15)
    for at in ([0.3, -0.4, 0.5], [0.0, 0.0, -1.0], [0.0, 0.0, 1.0]):
        q = parse_attitude_target({"point": [0, 0, 1], "at": at}, where)
        assert_allclose(_dcm(q) @ [0, 0, 1], np.array(at) / np.linalg.norm(at), atol=1e-15)
    _same_rotation(parse_attitude_target([0.0, 0.6, 0.0, -0.8], where), np.array([0.0, 0.6, 0.0, -0.8]), 0)


@pytest.mark.parametrize("target, message", [
    ("{axis: [0, 0, 0], angle: 10 deg}", r"parameter target: axis: expected a nonzero"),
    ("{axis: [0, 0, 1], angel: 10 deg}", r"parameter target: unknown key\(s\) \['angel'\]; missing key\(s\) \['angle'\]"),
    ("{euler: [1, 2, 3], sequence: ZZX}", r"parameter target: sequence: expected three axis letters"),
    ("{euler: [1 deg, 2 m, 3 deg], sequence: ZYX}", r"parameter target: euler\[1\]: expected an angle"),
    ("[1, 0, 0, 0.1]", r"parameter target: expected a unit quaternion"),
    ("{point: [0, 0, 1]}", r"parameter target: missing key\(s\) \['at'\]"),
])
def test_a_bad_target_is_refused_with_file_line_and_key(target, message):
    text = textwrap.dedent(f"""
        models:
          slew:
            type: EigenaxisSlew
            parameters:
              max_rate: 1 deg/s
              max_acceleration: 0.1 deg/s^2
              target: {target}
        """)
    with pytest.raises(ScenarioError, match=r"slew\.yaml:8: .*" + message):
        build_simulation(parse_scenario(text, "slew.yaml", None))


SLEW = """
multibody:
  gravity: "[0, 0, 0] m/s^2"
  bodies:
    - name: hub
      hinge: free
      mass: 500 kg
      inertia: "[[300, 5, -3], [5, 250, 4], [-3, 4, 200]] kg*m^2"
      initial: {attitude: [0.9238795325112867, 0.0, 0.3826834323650898, 0.0]}
  nodes:
    - {name: bus, body: hub}
models:
  slew:
    type: EigenaxisSlew
    rate: 10 Hz
    parameters:
      target: {euler: [120 deg, 10 deg, -30 deg], sequence: ZYX}
      start_time: 5 s
      max_rate: RATE
      max_acceleration: 0.05 deg/s^2
  controller:
    type: MrpFeedback
    rate: 10 Hz
    parameters: {k: 20 N*m, p: 60 N*m*s/rad, inertia: "[[300, 5, -3], [5, 250, 4], [-3, 4, 200]] kg*m^2"}
connections:
  - multibody.bus.attitude -> slew.attitude
  - multibody.bus.attitude -> controller.attitude
  - multibody.bus.angular_velocity -> controller.angular_velocity
  - slew.reference_attitude -> controller.reference_attitude
  - slew.reference_angular_velocity -> controller.reference_angular_velocity
  - slew.reference_angular_acceleration -> controller.reference_angular_acceleration
  - controller.torque -> multibody.bus.torque
integrator: {method: rk4, step: 0.05 s}
stop: {time: STOP s}
log:
  rate: 10 Hz
  signals: [multibody.bus.attitude, slew.reference_attitude, slew.reference_angular_velocity,
            slew.reference_angular_acceleration, slew.slew_angle, slew.complete, controller.attitude_error]
"""


def _profile(tau, angle, w, a):
    """theta, theta', theta'' of the bang-coast-bang profile, written from its definition."""
    if angle >= w * w / a:
        ta, tc = w / a, angle / w - w / a
    else:
        ta, tc = np.sqrt(angle / a), 0.0
    peak = a * ta
    total = 2 * ta + tc
    theta = np.where(tau < ta, a * tau**2 / 2, np.where(tau < ta + tc, a * ta**2 / 2 + peak * (tau - ta),
                                                            angle - a * (total - tau) ** 2 / 2))
    theta = np.where(tau >= total, angle, np.where(tau <= 0, 0.0, theta))
    rate = np.where(tau < ta, a * tau, np.where(tau < ta + tc, peak, a * (total - tau)))
    rate = np.where((tau <= 0) | (tau >= total), 0.0, rate)
    return theta, rate


@pytest.mark.parametrize("rate", ["1 deg/s", "5 deg/s"], ids=["bang-coast-bang", "bang-bang"])
def test_slew_profile_is_the_closed_form_and_the_loop_reaches_the_target(rate, tmp_path):
    w, a = np.radians(float(rate.split()[0])), np.radians(0.05)
    q0 = np.array([0.9238795325112867, 0.0, 0.3826834323650898, 0.0])
    target = parse_attitude_target({"euler": ["120 deg", "10 deg", "-30 deg"], "sequence": "ZYX"}, "t")
    relative = _qmul(np.r_[q0[0], -q0[1:]], target)
    relative = relative if relative[0] >= 0 else -relative
    angle = 2 * np.arctan2(np.linalg.norm(relative[1:]), relative[0])
    axis = relative[1:] / np.linalg.norm(relative[1:])
    duration = slew_duration(angle, w, a)
    assert (angle >= w * w / a) == (rate == "1 deg/s")       # each case is the profile it claims
    stop = 5.0 + duration + 60.0
    path = tmp_path / "slew.yaml"
    path.write_text(SLEW.replace("RATE", rate).replace("STOP", f"{stop:.1f}"))
    assert main(["check", str(path)]) == 0
    assert main(["run", str(path), "-o", str(tmp_path / "slew.h5"), "--quiet"]) == 0
    log = read_log(tmp_path / "slew.h5")
    t = log["time"]
    # the body is at rest until the start, so the captured start attitude is the initial one
    tau = t - 5.0
    theta, theta_dot = _profile(tau, angle, w, a)
    assert_allclose(log["slew.slew_angle"], theta, atol=1e-12)
    expected_q = np.array([_qmul(q0, np.r_[np.cos(th / 2), np.sin(th / 2) * axis]) for th in theta])
    assert_allclose(log["slew.reference_attitude"], expected_q, atol=1e-12)
    assert_allclose(log["slew.reference_angular_velocity"], np.outer(theta_dot, _dcm(q0) @ axis), atol=1e-12)
    # the rate output is the derivative of the attitude output: omega_world = 2 vec(q' q^*)
    q = log["slew.reference_attitude"]
    dq = np.gradient(q, t, axis=0)
    omega_fd = np.array([2 * _qmul(d, np.r_[x[0], -x[1:]])[1:] for d, x in zip(dq, q)])
    inside = (np.abs(tau - 0.0) > 0.2) & (np.abs(tau - duration) > 0.2) & (np.abs(tau - w / a) > 0.2) & (
        np.abs(tau - (duration - w / a)) > 0.2)
    assert_allclose(omega_fd[inside], log["slew.reference_angular_velocity"][inside], atol=a * 0.1)
    # peak rate and duration as commanded; complete flag after the end
    assert np.linalg.norm(log["slew.reference_angular_velocity"], axis=1).max() <= min(w, np.sqrt(angle * a)) * (1 + 1e-12)
    assert_allclose(t[log["slew.complete"] > 0.5][0], 5.0 + np.ceil(duration * 10 - 1e-9) / 10, atol=1e-9)
    # the tracking loop ends on the target (60 s after the profile's end)
    final = log["multibody.bus.attitude"][-1]
    error = _qmul(np.r_[target[0], -target[1:]], final)
    assert 2 * np.arcsin(min(1.0, np.linalg.norm(error[1:]))) < np.radians(0.01)
    assert np.abs(log["controller.attitude_error"]).max() < np.tan(np.radians(2.0) / 4)   # tracked throughout


ORBIT = """
multibody:
  gravity: "[0, 0, 0] m/s^2"
  bodies:
    - name: sat
      hinge: free
      mass: 100 kg
      inertia: "[10, 12, 14] kg*m^2"
      initial:
        position: "[7000000, 0, 0] m"
        velocity: "[0, 6500, 2500] m/s"
  nodes:
    - {name: bus, body: sat}
models:
  gravity: {type: CentralBodyGravity, attach: {node: bus}, parameters: {mass: 100 kg, j2: 0, gravity_gradient: 0}}
  nadir: {type: NadirPointing, attach: {node: bus}, parameters: {boresight: [0, 0, 1], secondary: [1, 0, 0]}}
  sun_line: {type: Constant, config: {shape: [3]}, parameters: {value: [0.6, 0.0, 0.8]}}
  sun: {type: SunPointing, parameters: {boresight: [1, 0, 0], secondary: [0, 1, 0], secondary_direction: [0, 1, 0]}}
connections:
  - sun_line.y -> sun.sun_direction
integrator: {method: rk4, step: 1 s}
stop: {time: 600 s}
log:
  rate: 1 Hz
  signals: [multibody.bus.position, multibody.bus.linear_velocity, multibody.bus.rotation, nadir.reference_attitude,
            nadir.reference_angular_velocity, nadir.reference_angular_acceleration, sun.reference_attitude]
"""


def test_nadir_and_sun_frames_point_their_axes_and_rates_are_the_derivative(tmp_path):
    path = tmp_path / "orbit.yaml"
    path.write_text(ORBIT)
    assert main(["run", str(path), "-o", str(tmp_path / "orbit.h5"), "--quiet"]) == 0
    log = read_log(tmp_path / "orbit.h5")
    t, r = log["time"], log["multibody.bus.position"]
    rotation = log["multibody.bus.rotation"].reshape(-1, 3, 3)
    v = np.einsum("kij,kj->ki", rotation, log["multibody.bus.linear_velocity"])
    q = log["nadir.reference_attitude"]
    # boresight on -r, secondary in the (r, v) plane on the velocity side
    boresight = np.array([_dcm(x) @ [0, 0, 1] for x in q])
    secondary = np.array([_dcm(x) @ [1, 0, 0] for x in q])
    assert_allclose(boresight, -r / np.linalg.norm(r, axis=1)[:, None], atol=1e-14)
    normal = np.cross(r, v)
    assert np.abs(np.einsum("ki,ki->k", secondary, normal)).max() < 1e-14 * np.linalg.norm(normal, axis=1).max()
    assert np.einsum("ki,ki->k", secondary, v).min() > 0
    # angular velocity and acceleration outputs against central differences of the logged frame
    omega = log["nadir.reference_angular_velocity"]
    dq = (q[2:] - q[:-2]) / (t[2:] - t[:-2])[:, None]
    omega_fd = np.array([2 * _qmul(d, np.r_[x[0], -x[1:]])[1:] for d, x in zip(dq, q[1:-1])])
    # central difference of a rotation at n = 1.1e-3 rad/s over 1 s: relative error (n h)^2 / 6 ~ 2e-7
    assert_allclose(omega_fd, omega[1:-1], rtol=0, atol=1e-6 * np.abs(omega).max())
    alpha_fd = (omega[2:] - omega[:-2]) / 2.0
    alpha = log["nadir.reference_angular_acceleration"][1:-1]
    assert np.abs(alpha).max() > 1e-10         # e = 0.15 orbit: a real angular acceleration
    assert_allclose(alpha_fd, alpha, rtol=0, atol=1e-5 * np.abs(alpha).max())
    # Sun pointing: boresight on the Sun line, secondary towards the world y axis (in their plane)
    sun_q = log["sun.reference_attitude"][-1]
    assert_allclose(_dcm(sun_q) @ [1, 0, 0], [0.6, 0.0, 0.8], atol=1e-15)
    assert_allclose(_dcm(sun_q) @ [0, 1, 0], [0.0, 1.0, 0.0], atol=1e-15)


def test_parallel_pointing_axes_are_refused():
    from shell.models.guidance import NadirPointing

    with pytest.raises(ModelError, match="parameter secondary: must not be parallel to boresight"):
        NadirPointing("n", boresight=[0, 0, 1], secondary=[0, 0, -2])
