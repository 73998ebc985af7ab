"""CMG pyramid: the cluster conserves the system's angular momentum with the bus (through YAML); the
steering law equals numpy's pseudo-inverse away from singularities and the singularity-robust inverse
near one, with bounded gimbal rates where the pseudo-inverse diverges."""

import numpy as np
from numpy.testing import assert_allclose
from scipy.optimize import minimize

from shell.cli import main
from shell.log_file import read_log
from shell.models.cmg import STEERING_INPUTS, CmgSteering, U_STEER, Z_STEER, _steering_update

BETA = np.radians(54.73)
H0 = 2.0


def _jacobian(d):
    """A(d) of the standard pyramid, written out (Wie sec. 7.8: H = h0 [-cb s1 - c2 + cb s3 + c4,
    c1 - cb s2 - c3 + cb s4, sb (s1 + s2 + s3 + s4)])."""
    cb, sb = np.cos(BETA), np.sin(BETA)
    c, s = np.cos(d), np.sin(d)
    return np.array([[-cb * c[0], s[1], cb * c[2], -s[3]],
                     [-s[0], -cb * c[1], s[2], cb * c[3]],
                     [sb * c[0], sb * c[1], sb * c[2], sb * c[3]]])


def _momentum(d):
    cb, sb = np.cos(BETA), np.sin(BETA)
    c, s = np.cos(d), np.sin(d)
    return H0 * np.array([-cb * s[0] - c[1] + cb * s[2] + c[3], c[0] - cb * s[1] - c[2] + cb * s[3],
                          sb * s.sum()])


def _steer(d, torque, lambda_0, mu=10.0):
    model = CmgSteering("s", wheel_momentum=H0, skew_angle=BETA, max_gimbal_rate=100.0, lambda_0=lambda_0, mu=mu)
    z = model.initial_discrete_state()
    u = np.zeros(sum(x.size for x in STEERING_INPUTS))
    u[U_STEER.torque_command:U_STEER.torque_command + 3] = torque
    u[U_STEER.gimbal_angles:U_STEER.gimbal_angles + 4] = d
    _steering_update(0.0, np.zeros(0), z, u, model.p)
    return z[Z_STEER.gimbal_rate_command:Z_STEER.gimbal_rate_command + 4], z[Z_STEER.singularity_measure]


def test_steering_is_the_pseudo_inverse_away_from_singularities():
    rng = np.random.default_rng(4)
    for _ in range(20):
        d, torque = rng.uniform(-np.pi, np.pi, 4), rng.normal(0.0, 0.5, 3)
        a = _jacobian(d)
        if np.linalg.det(a @ a.T) < 0.5:
            continue
        rates, measure = _steer(d, torque, lambda_0=0.0)
        assert_allclose(rates, -np.linalg.pinv(a) @ torque / H0, rtol=1e-10, atol=1e-14)
        assert_allclose(-H0 * a @ rates, torque, rtol=1e-10, atol=1e-14)      # the torque delivered
        assert_allclose(measure, np.linalg.det(a @ a.T), rtol=1e-12)


def test_singularity_robust_inverse_bounds_the_rates_near_a_singularity():
    # a singular configuration of the pyramid, found by minimizing det(A A^T)
    best = min((minimize(lambda d: np.linalg.det(_jacobian(d) @ _jacobian(d).T), x0, method="Nelder-Mead",
                         options={"xatol": 1e-12, "fatol": 1e-16, "maxiter": 20000})
                for x0 in np.random.default_rng(1).uniform(-np.pi, np.pi, (8, 4))), key=lambda r: r.fun)
    d = best.x
    a = _jacobian(d)
    assert np.linalg.det(a @ a.T) < 1e-10
    # the torque along the singular direction (the direction A cannot produce)
    singular = np.linalg.svd(a)[0][:, -1]
    torque = 0.1 * singular + 0.05 * np.linalg.svd(a)[0][:, 0]
    rates, measure = _steer(d, torque, lambda_0=0.01)
    lam = 0.01 * np.exp(-10.0 * measure)
    expected = -a.T @ np.linalg.solve(a @ a.T + lam * np.eye(3), torque) / H0
    assert_allclose(rates, expected, rtol=1e-8)
    assert np.abs(rates).max() < 10.0                      # bounded, while
    near = d + 1e-4                                        # the pseudo-inverse just off the singularity
    assert np.abs(np.linalg.pinv(_jacobian(near)) @ torque / H0).max() > 10 * np.abs(rates).max()
    # the torque error is the SR residual lambda (A A^T + lambda I)^-1 tau
    assert_allclose(-H0 * a @ rates - torque, -lam * np.linalg.solve(a @ a.T + lam * np.eye(3), torque), atol=1e-12)


SCENE = f"""
multibody:
  gravity: "[0, 0, 0] m/s^2"
  bodies:
    - name: bus
      hinge: free
      mass: 500 kg
      inertia: "[[300, 5, -3], [5, 250, 4], [-3, 4, 200]] kg*m^2"
      initial: {{angular_velocity: "[0.02, -0.01, 0.03] rad/s"}}
  nodes:
    - {{name: acs, body: bus}}
models:
  cmgs:
    type: CmgCluster
    attach: {{node: acs}}
    parameters: {{wheel_momentum: {H0} N*m*s, max_gimbal_rate: 0.15 rad/s}}
    initial: {{gimbal_angles: "[0.3, -0.2, 0.5, 0.1] rad"}}
  rates: {{type: Constant, config: {{unit: rad/s, shape: [4]}}, parameters: {{value: "[0.1, -0.2, 0.05, 0.15] rad/s"}}}}
connections:
  - rates.y -> cmgs.gimbal_rate_command
integrator: {{method: rk4, step: 0.01 s}}
stop: {{time: 30 s}}
log:
  rate: 1 Hz
  signals: [multibody.acs.rotation, multibody.acs.angular_velocity, cmgs.momentum, cmgs.gimbal_angles, cmgs.gimbal_rates]
"""


def test_cluster_conserves_angular_momentum_and_limits_gimbal_rates(tmp_path):
    path = tmp_path / "cmg.yaml"
    path.write_text(SCENE)
    assert main(["run", str(path), "-o", str(tmp_path / "cmg.h5"), "--quiet"]) == 0
    log = read_log(tmp_path / "cmg.h5")
    inertia = np.array([[300, 5, -3], [5, 250, 4], [-3, 4, 200]], float)
    rotation = log["multibody.acs.rotation"].reshape(-1, 3, 3)
    total = np.einsum("kij,kj->ki", rotation, log["multibody.acs.angular_velocity"] @ inertia + log["cmgs.momentum"])
    assert np.abs(total - total[0]).max() < 1e-10 * np.linalg.norm(total[0])
    # the momentum output is the pyramid's H at the logged angles; the 0.2 rad/s command is clipped at 0.15
    assert_allclose(log["cmgs.momentum"], [_momentum(d) for d in log["cmgs.gimbal_angles"]], atol=1e-13)
    assert_allclose(log["cmgs.gimbal_rates"][-1], [0.1, -0.15, 0.05, 0.15], rtol=1e-15)
    assert_allclose(log["cmgs.gimbal_angles"][-1], np.array([0.3, -0.2, 0.5, 0.1]) + 30 * np.array([0.1, -0.15, 0.05, 0.15]),
                    rtol=1e-12)


LOOP = f"""
multibody:
  gravity: "[0, 0, 0] m/s^2"
  bodies:
    - name: bus
      hinge: free
      mass: 500 kg
      inertia: "[[300, 5, -3], [5, 250, 4], [-3, 4, 200]] kg*m^2"
  nodes:
    - {{name: acs, body: bus}}
models:
  target: {{type: InertialPointing, parameters: {{target: {{axis: [1, 2, 3], angle: 40 deg}}}}}}
  controller:
    type: MrpFeedback
    rate: 10 Hz
    parameters: {{k: 30 N*m, p: 120 N*m*s/rad, inertia: "[[300, 5, -3], [5, 250, 4], [-3, 4, 200]] kg*m^2"}}
  steering:
    type: CmgSteering
    rate: 10 Hz
    parameters: {{wheel_momentum: {H0} N*m*s, max_gimbal_rate: 1 rad/s}}
  cmgs:
    type: CmgCluster
    attach: {{node: acs}}
    parameters: {{wheel_momentum: {H0} N*m*s, max_gimbal_rate: 1 rad/s}}
connections:
  - multibody.acs.attitude -> controller.attitude
  - multibody.acs.angular_velocity -> controller.angular_velocity
  - target.reference_attitude -> controller.reference_attitude
  - controller.torque -> steering.torque_command
  - cmgs.gimbal_angles -> steering.gimbal_angles
  - multibody.acs.angular_velocity -> steering.angular_velocity
  - steering.gimbal_rate_command -> cmgs.gimbal_rate_command
integrator: {{method: rk4, step: 0.02 s}}
stop: {{time: 200 s}}
log:
  rate: 10 Hz
  signals: [multibody.acs.attitude, controller.torque, cmgs.torque, steering.singularity_measure]
"""


def test_mrp_feedback_slews_with_the_cmg_pyramid(tmp_path):
    path = tmp_path / "loop.yaml"
    path.write_text(LOOP)
    assert main(["check", str(path)]) == 0
    assert main(["run", str(path), "-o", str(tmp_path / "loop.h5"), "--quiet"]) == 0
    log = read_log(tmp_path / "loop.h5")
    axis = np.array([1.0, 2.0, 3.0]) / np.sqrt(14.0)
    target = np.r_[np.cos(np.radians(20.0)), np.sin(np.radians(20.0)) * axis]
    q = log["multibody.acs.attitude"][-1]
    error = target[0] * q[1:] - q[0] * target[1:] - np.cross(target[1:], q[1:])
    assert 2 * np.arcsin(np.linalg.norm(error)) < 1e-4      # 40 deg slew settled
    # the gimbal path passes close to a singular configuration (det(A A^T) from 1.2 down to ~4e-7); the
    # singularity-robust weight carries the loop through it to the target
    measure = log["steering.singularity_measure"]
    assert measure[1:].min() < 1e-3 and measure[1] > 1.0
