"""AttitudeMekf: consistency over a 50-run Monte Carlo (NEES within its chi-square bounds), converged
attitude error against the sensors' noise, a star-tracker dropout, and the filter in a YAML scene with
the Imu and a noisy attitude through the command line.

The Monte Carlo calls the model's own update kernel on measurements simulated here, independently of the
filter: a body turning at a constant rate (exact attitude ``q_0 (x) exp(omega t)``), a gyro whose mean
rate over each period carries the discrete Farrenkopf model (Markley and Crassidis 2014 sec. 6.4,
eq. 6.94: bias random walk and ``sqrt(s_v^2 / dt + s_u^2 dt / 12)`` white noise around the mean
bias), and a star tracker with independent noise per sensor axis, misaligned from the node.
"""

import numpy as np
import pytest
from numpy.testing import assert_allclose
from scipy.stats import chi2

from shell.cli import main
from shell.log_file import read_log
from shell.models.mekf import INPUTS, U, Z, AttitudeMekf, _mekf_update

DT = 0.1
SIGMA_V = 1e-5            # rad/s^0.5 (ARW 0.034 deg/h^0.5)
SIGMA_U = 1e-7            # rad/s^1.5
SIGMA_ST = np.radians(np.array([10.0, 10.0, 50.0]) / 3600.0)   # rad, per sensor axis (boresight noisier)
SIGMA_B0 = 1e-4           # rad/s (20 deg/h)
ALIGNMENT = np.array([np.cos(0.4), 0.0, np.sin(0.4), 0.0])      # sensor -> node: 46 deg about y
DROPOUT = (150.0, 180.0)  # s: no star tracker


def _qmul(a, b):
    return np.r_[a[0] * b[0] - a[1:] @ b[1:], a[0] * b[1:] + b[0] * a[1:] + np.cross(a[1:], b[1:])]


def _conj(q):
    return np.r_[q[0], -q[1:]]


def _exp(v):
    n = np.linalg.norm(v)
    return np.r_[np.cos(n / 2), np.sin(n / 2) * v / n] if n > 0 else np.array([1.0, 0, 0, 0])


def _qmul_rows(a, b):
    return np.column_stack([a[:, 0] * b[:, 0] - np.einsum("ki,ki->k", a[:, 1:], b[:, 1:]),
                            a[:, :1] * b[:, 1:] + b[:, :1] * a[:, 1:] + np.cross(a[:, 1:], b[:, 1:])])


def _run(seed, steps):
    """(errors (steps, 6), covariances (steps, 6, 6)) of one run."""
    rng = np.random.default_rng(seed)
    model = AttitudeMekf("mekf", gyro_random_walk=SIGMA_V, gyro_bias_random_walk=SIGMA_U,
                         star_tracker_noise=SIGMA_ST.tolist(), star_tracker_alignment=ALIGNMENT.tolist(),
                         initial_bias_sigma=SIGMA_B0)
    z = model.initial_discrete_state()
    u = np.zeros(sum(d.size for d in INPUTS))
    omega = rng.normal(0.0, 0.01, 3)                 # rad/s
    q0 = rng.standard_normal(4)
    q0 /= np.linalg.norm(q0)
    bias = rng.normal(0.0, SIGMA_B0, 3)
    white = np.sqrt(SIGMA_V**2 / DT + SIGMA_U**2 * DT / 12.0)
    t = np.arange(steps) * DT
    # truth and measurements for the whole run first (numpy), then the filter sample by sample
    angle = np.linalg.norm(omega) * t
    axis = omega / np.linalg.norm(omega)
    increments = np.column_stack([np.cos(angle / 2), np.sin(angle / 2)[:, None] * axis])
    q_true = _qmul_rows(np.broadcast_to(q0, (steps, 4)), increments)
    bias = bias + np.vstack([np.zeros(3), np.cumsum(SIGMA_U * np.sqrt(DT) * rng.standard_normal((steps, 3)), axis=0)])
    rates = omega + 0.5 * (bias[:-1] + bias[1:]) + white * rng.standard_normal((steps, 3))
    rotation = SIGMA_ST * rng.standard_normal((steps, 3))
    norm = np.linalg.norm(rotation, axis=1)
    noise = np.column_stack([np.cos(norm / 2), np.sin(norm / 2)[:, None] * rotation / norm[:, None]])
    tracker = _qmul_rows(_qmul_rows(q_true, np.broadcast_to(ALIGNMENT, (steps, 4))), noise)   # noise in sensor axes
    valid = ~((DROPOUT[0] <= t) & (t < DROPOUT[1]))
    estimates = np.empty((steps, 4))
    covariances = np.empty((steps, 6, 6))
    bias_estimates = np.empty((steps, 3))
    for k in range(steps):
        u[U.angular_rate:U.angular_rate + 3] = rates[k]
        u[U.star_tracker_attitude:U.star_tracker_attitude + 4] = tracker[k]
        u[U.star_tracker_valid] = float(valid[k])
        _mekf_update(t[k], np.zeros(0), z, u, model.p)
        estimates[k] = z[Z.attitude:Z.attitude + 4]
        bias_estimates[k] = z[Z.gyro_bias:Z.gyro_bias + 3]
        covariances[k] = z[Z.covariance:Z.covariance + 36].reshape(6, 6)
    e = _qmul_rows(estimates * [1.0, -1.0, -1.0, -1.0], q_true)
    errors = np.empty((steps, 6))
    errors[:, :3] = 2.0 * np.sign(e[:, :1]) * e[:, 1:]
    # the filter's bias is that of the last period's mean rate: compare with the truth at its end
    errors[:, 3:] = bias[1:] - bias_estimates
    return errors, covariances


@pytest.fixture(scope="module")
def monte_carlo():
    runs, steps = 50, 3000
    results = [_run(seed, steps) for seed in range(runs)]
    errors = np.array([r[0] for r in results])
    covariances = np.array([r[1] for r in results])
    return errors, covariances


def test_nees_is_within_its_chi_square_bounds_over_50_runs(monte_carlo):
    errors, covariances = monte_carlo
    runs = errors.shape[0]
    nees = np.einsum("rki,rki->rk", errors, np.linalg.solve(covariances, errors[..., None])[..., 0])
    average = nees.mean(axis=0)[10:]           # after the first second (the bias prior is still being learnt)
    low, high = chi2.ppf([0.005, 0.995], 6 * runs) / runs
    inside = np.mean((average >= low) & (average <= high))
    # 99 % two-sided bounds; consecutive samples are correlated, so allow 5 % outside
    assert inside > 0.95, (inside, low, high, average.mean())
    # the time average is 6 (the dimension) to within its own sampling error
    assert abs(average.mean() - 6.0) < 0.3, average.mean()


def test_converged_attitude_error_matches_the_filter_sigma_and_beats_the_star_tracker(monte_carlo):
    errors, covariances = monte_carlo
    steady = np.r_[1000:1500, 2100:3000]        # converged: 100-150 s, and 210-300 s after the dropout
    rms = np.sqrt(np.mean(errors[:, steady, :3] ** 2, axis=(0, 1)))
    diagonal = np.diagonal(covariances[:, steady], axis1=2, axis2=3)
    sigma = np.sqrt(np.mean(diagonal[..., :3], axis=(0, 1)))
    assert_allclose(rms, sigma, rtol=0.1)        # 70,000 samples correlated over ~10 s: ~3 % sampling error
    # fusion with the gyro: every node axis better than the best star-tracker axis alone
    assert rms.max() < SIGMA_ST.min()
    # the bias is learnt (1e-4 rad/s prior, about 1e-6 after 100 s) and its error matches its sigma
    bias_rms = np.sqrt(np.mean(errors[:, steady, 3:] ** 2, axis=(0, 1)))
    bias_sigma = np.sqrt(np.mean(diagonal[..., 3:], axis=(0, 1)))
    assert_allclose(bias_rms, bias_sigma, rtol=0.2)     # 50 runs of a slowly varying error: ~10 % sampling error
    assert bias_rms.max() < 0.02 * SIGMA_B0


def test_dropout_grows_the_covariance_as_the_gyro_model_says_and_recovers(monte_carlo):
    errors, covariances = monte_carlo
    k0, k1 = int(DROPOUT[0] / DT), int(DROPOUT[1] / DT)
    var = covariances[0, :, 0, 0] + covariances[0, :, 1, 1] + covariances[0, :, 2, 2]
    growth = var[k1 - 1] - var[k0 - 1]
    # without updates: trace P11 grows by at least 3 s_v^2 T (angle random walk) plus the bias term
    assert growth > 3 * SIGMA_V**2 * (DROPOUT[1] - DROPOUT[0])
    assert var[k1 + 300] < 1.2 * var[k0 - 1]     # back to the converged level 30 s after
    nees = np.einsum("rki,rki->rk", errors, np.linalg.solve(covariances, errors[..., None])[..., 0]).mean(axis=0)
    assert abs(nees[k0:k1].mean() - 6.0) < 0.6   # consistent during the dropout too


SCENE = """
multibody:
  gravity: "[0, 0, 0] m/s^2"
  bodies:
    - name: sat
      hinge: free
      mass: 100 kg
      inertia: "[10, 12, 14] kg*m^2"
      initial: {angular_velocity: "[0.01, -0.02, 0.015] rad/s"}
  nodes:
    - {name: bus, body: sat}
models:
  imu:
    type: Imu
    rate: 10 Hz
    attach: {node: bus}
    parameters: {gyro_random_walk: 0.034 deg/hour**0.5, gyro_bias: "[20, -15, 10] deg/hour"}
  star_tracker:
    type: NoisySampler
    rate: 10 Hz
    config: {shape: [4]}
    parameters: {sigma: 2.4e-5}        # on each component: about 2 sigma = 10 arcsec per axis
  mekf:
    type: AttitudeMekf
    rate: 10 Hz
    parameters:
      gyro_random_walk: 0.034 deg/hour**0.5
      gyro_bias_random_walk: 1e-7 rad/s**1.5
      star_tracker_noise: "[10, 10, 10] arcsec"
      initial_bias_sigma: 30 deg/hour
connections:
  - multibody.bus.attitude -> star_tracker.u
  - star_tracker.y -> mekf.star_tracker_attitude
  - imu.angular_rate -> mekf.angular_rate
integrator: {method: rk4, step: 0.05 s}
stop: {time: 120 s}
log:
  rate: 10 Hz
  signals: [multibody.bus.attitude, mekf.attitude, mekf.gyro_bias, mekf.attitude_sigma, mekf.initialized,
            mekf.covariance]
"""


def test_mekf_in_a_scene_estimates_attitude_and_the_imu_bias(tmp_path):
    path = tmp_path / "mekf.yaml"
    path.write_text(SCENE)
    assert main(["check", str(path)]) == 0
    assert main(["run", str(path), "-o", str(tmp_path / "mekf.h5"), "--quiet"]) == 0
    log = read_log(tmp_path / "mekf.h5")
    truth, estimate = log["multibody.bus.attitude"], log["mekf.attitude"]
    assert log["mekf.initialized"][0] == 1.0
    later = log["time"] > 60.0
    # the IMU's rate at t_k is the mean over [t_k - T, t_k] and the filter propagates with it: compare at t_k
    e = np.array([_qmul(_conj(a), b) for a, b in zip(estimate[later], truth[later])])
    angle = 2.0 * np.arcsin(np.linalg.norm(e[:, 1:], axis=1))
    sigma = np.linalg.norm(log["mekf.attitude_sigma"][later], axis=1)
    assert np.sqrt(np.mean(angle**2)) < 2.0 * sigma.mean()
    assert np.sqrt(np.mean(angle**2)) < np.radians(10.0 / 3600.0)
    # the turn-on bias is found within 4 of the filter's own sigmas (about 1 % of the bias)
    bias_sigma = np.sqrt(np.diagonal(log["mekf.covariance"][-1].reshape(6, 6))[3:])
    bias_error = log["mekf.gyro_bias"][-1] - np.radians([20.0, -15.0, 10.0]) / 3600.0
    assert np.all(np.abs(bias_error) < 4.0 * bias_sigma), (bias_error, bias_sigma)
    assert np.all(bias_sigma < 0.03 * np.radians(10.0) / 3600.0)


def test_refuses_a_non_unit_alignment():
    with pytest.raises(Exception, match="parameter star_tracker_alignment: expected a unit quaternion"):
        AttitudeMekf("m", gyro_random_walk=1e-5, gyro_bias_random_walk=1e-7, star_tracker_noise=[1e-5] * 3,
                     star_tracker_alignment=[1.0, 0.1, 0.0, 0.0])
