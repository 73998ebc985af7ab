"""IMU: Allan deviation of static records against the IEEE Std 952 signatures; sensed motion at a node.

Static records come from the model's own sample kernel (``static_record``) with a fixed seed. The
reference for each record is the exact Allan variance of the discrete process the model generates
(closed forms below), and each point must lie within ``4 sigma`` of it, with the relative standard
deviation of an Allan-deviation estimate from K non-overlapping clusters 1/sqrt(2 (K - 1)) for white
processes (IEEE Std 952 eq. C.3; the overlapping estimator used here is at least as good) and twice
that variance for walk-type processes (fewer equivalent degrees of freedom).
"""

import numpy as np
from numpy.testing import assert_allclose

from shell.models.imu import (FLICKER_FLOOR, GAUSS_MARKOV_PEAK, Imu, allan_deviation,
                              gauss_markov_allan_variance, static_record)

DEG_H = np.pi / 180 / 3600          # deg/hour in rad/s


def _within_confidence(measured, reference, n_samples, m, walk=False, n_sigma=4.0):
    clusters = n_samples // np.asarray(m)
    relative_sigma = 1.0 / np.sqrt(2.0 * (clusters - 1))
    if walk:
        relative_sigma *= np.sqrt(2.0)
    error = np.abs(measured / reference - 1.0)
    assert np.all(error < n_sigma * relative_sigma), (error, n_sigma * relative_sigma)


def test_angle_and_velocity_random_walk_at_tau_one_second():
    n, period = 200_000, 0.01
    imu = Imu("imu", period=period, gyro_random_walk="0.15 deg/hour**0.5", accel_random_walk="0.05 m/s/hour**0.5")
    record = static_record(imu, n, seed=11)
    m = np.array([1, 10, 100, 1000])
    tau = m * period
    ad = allan_deviation(record, period, m)
    arw = 0.15 * np.pi / 180 / 60              # rad/s**0.5
    vrw = 0.05 / 60                           # m/s**1.5
    for axis in range(3):
        _within_confidence(ad[:, axis], arw / np.sqrt(tau), n, m)
        _within_confidence(ad[:, 3 + axis], vrw / np.sqrt(tau), n, m)
    # the datasheet number itself: Allan deviation at tau = 1 s equals N
    _within_confidence(ad[2, :3], np.full(3, arw), n, 100)


def test_bias_instability_floor_is_0p664_b():
    n, period, tc = 200_000, 0.1, 10.0
    b = 0.5 * DEG_H
    imu = Imu("imu", period=period, gyro_bias_instability="0.5 deg/hour", gyro_bias_correlation_time=tc)
    record = static_record(imu, n, seed=12)[:, :3]
    m = np.unique(np.geomspace(1, 2000, 40).astype(int))
    tau = m * period
    ad = allan_deviation(record, period, m)
    # exact Allan variance of the discrete AR(1) rate b_k = phi b_k-1 + ...: cluster sums' variance
    sigma = FLICKER_FLOOR * b / GAUSS_MARKOV_PEAK
    phi = np.exp(-period / tc)
    reference = []
    for mm in m:
        d = np.arange(1, mm)
        var_sum = sigma**2 * (mm + 2.0 * np.sum((mm - d) * phi**d))
        cov_adjacent = sigma**2 * phi * (1.0 - phi**mm) ** 2 / (1.0 - phi) ** 2
        reference.append(np.sqrt((var_sum - cov_adjacent) / mm**2))
    reference = np.array(reference)
    # the discrete (sample-and-hold) reference tends to the continuous Gauss-Markov formula once the
    # clusters span many samples (tau >= 20 T: within 0.5 %)
    long = m >= 20
    assert_allclose(reference[long], np.sqrt(gauss_markov_allan_variance(tau[long], sigma, tc)), rtol=5e-3)
    for axis in range(3):
        _within_confidence(ad[:, axis], reference, n, m, walk=True)
    # the floor: peak of the measured curve = 0.664 B within the confidence at the peak (K ~ 1000)
    peak = ad.max(axis=0)
    k_peak = n // m[np.argmax(reference)]
    assert_allclose(peak / (0.664 * b), 1.0, atol=4 * np.sqrt(2.0 / (2 * (k_peak - 1))) + 2e-3)


def test_rate_random_walk_slope_plus_one_half():
    n, period = 200_000, 1.0
    k_rrw = 0.02 * DEG_H / np.sqrt(3600)       # 0.02 deg/h/sqrt(h) in rad/s**1.5
    imu = Imu("imu", period=period, gyro_bias_random_walk="0.02 deg/hour**1.5")
    record = static_record(imu, n, seed=13)[:, :3]
    m = np.array([10, 30, 100, 300])
    ad = allan_deviation(record, period, m)
    # discrete random walk of the rate: AVAR = K^2 T (2 m^2 + 1) / (6 m) = K^2 tau / 3 + K^2 T / (6 m)
    reference = np.sqrt(k_rrw**2 * period * (2 * m**2 + 1) / (6 * m))
    for axis in range(3):
        _within_confidence(ad[:, axis], reference, n, m, walk=True)
        slope = np.polyfit(np.log(m), np.log(ad[:, axis]), 1)[0]
        # 4 sigma of 6 % at the longest tau over a 1.5 decade lever arm: |error| < 0.1
        assert abs(slope - 0.5) < 0.1, slope


def test_rate_ramp_is_exact():
    period = 0.1
    imu = Imu("imu", period=period, gyro_ramp="36 deg/hour**2")
    record = static_record(imu, 20_000, seed=0)[:, :3]
    m = np.array([1, 10, 100])
    ramp = 36 * DEG_H / 3600
    assert_allclose(allan_deviation(record, period, m), np.outer(ramp * m * period / np.sqrt(2), np.ones(3)),
                    rtol=1e-7)   # round-off of the cumulative sum of a growing rate


def test_angle_white_noise_and_quantization_slope_minus_one():
    n, period = 200_000, 0.01
    lsb = 0.1 / 3600 * np.pi / 180              # 0.1 arcsec counter resolution
    q_awn = 0.05 / 3600 * np.pi / 180
    arw = lsb / np.sqrt(period)                 # increment noise of one lsb: dithers the quantizer
    imu = Imu("imu", period=period, gyro_random_walk=arw, gyro_lsb="0.1 arcsec")
    rates = static_record(imu, n, seed=14)[:, :3]
    counts = np.round(rates * period / lsb)
    assert_allclose(rates * period, counts * lsb, rtol=0, atol=1e-12 * lsb)  # integer counter output
    m = np.array([1, 2, 4])
    tau = m * period
    ad = allan_deviation(rates, period, m)
    quantization = np.sqrt(3) * (lsb / np.sqrt(12)) / tau
    total = np.sqrt(arw**2 / tau + quantization**2)
    for axis in range(3):
        _within_confidence(ad[:, axis], total, n, m)
        # the quantization part alone, after removing the random walk: slope -1
        q_part = np.sqrt(ad[:, axis] ** 2 - arw**2 / tau)
        slope = np.polyfit(np.log(tau), np.log(q_part), 1)[0]
        assert abs(slope + 1.0) < 0.1, slope
    imu = Imu("imu", period=period, gyro_white_noise=q_awn)
    ad = allan_deviation(static_record(imu, n, seed=15)[:, :3], period, m)
    for axis in range(3):   # exact: cluster differences telescope to w_2m - 2 w_m + w_0
        _within_confidence(ad[:, axis], np.sqrt(3) * q_awn / tau, n, m)


SPINNING = """
multibody:
  gravity: "[0, 0, -9.81] m/s^2"
  bodies:
    - name: bus
      hinge: free
      mass: 100 kg
      inertia: "[10, 30, 40] kg*m^2"
      initial: {angular_velocity: "[0, 0, 30] deg/s"}
  nodes:
    - {name: imu_node, body: bus, position: "[2, 0.5, 0] m"}
models:
  imu:
    type: Imu
    rate: 100 Hz
    attach: {node: imu_node}
    parameters:
      gravity: "[0, 0, -9.81] m/s^2"
      latency: 0.02 s
      gyro_scale_factor: "[100, -200, 300] ppm"
      gyro_misalignment: "[[0, 20, 0], [-10, 0, 5], [0, 30, 0]] arcsec"
      gyro_bias: "[1, 2, 3] deg/hour"
      accel_scale_factor: "[50, 0, 0] ppm"
integrator: {method: rk4, step: 0.01 s}
log:
  rate: 100 Hz
  signals: [imu.angular_rate, imu.specific_force, imu.delta_velocity]
"""


def test_spinning_node_senses_rate_and_lever_arm_specific_force(tmp_path):
    import textwrap

    from shell.log_file import read_log
    from shell.scenario import build_simulation, parse_scenario

    sim = build_simulation(parse_scenario(textwrap.dedent(SPINNING), "scene.yaml", None))
    sim.run(2.0, log_path=tmp_path / "imu.h5")
    log = read_log(tmp_path / "imu.h5")
    omega = np.radians(30.0)
    arcsec = np.pi / 180 / 3600
    misalignment = np.array([[0, 20, 0], [-10, 0, 5], [0, 30, 0]]) * arcsec
    sf = np.array([100, -200, 300]) * 1e-6
    rate_true = np.array([0, 0, omega])
    expected_rate = (1 + sf) * ((np.eye(3) + misalignment) @ rate_true) + np.array([1, 2, 3]) * DEG_H
    after_latency = log["time"] >= 0.03           # the first two samples are the latency's empty slots
    # torque-free spin about a principal axis: constant rate; RK4 integral error < 1e-12 rad/s
    assert_allclose(log["imu.angular_rate"][after_latency], np.tile(expected_rate, (after_latency.sum(), 1)),
                    rtol=0, atol=1e-12)
    # specific force: centripetal -omega^2 r in node (= body) axes; the body falls freely, so gravity
    # cancels (a - g = 0 along z): the accelerometer feels only the lever-arm term
    r = np.array([2.0, 0.5, 0.0])
    expected_force = -omega**2 * r
    expected_force[0] *= 1 + 50e-6
    assert_allclose(log["imu.specific_force"][after_latency], np.tile(expected_force, (after_latency.sum(), 1)),
                    rtol=0, atol=1e-10)
    # the output register starts empty: nothing during the first two periods, then the t = 0 sample
    # (an increment over [-T, 0] before the motion was integrated: the bias alone)
    assert_allclose(log["imu.angular_rate"][:2], 0.0, atol=0)
    assert_allclose(log["imu.angular_rate"][2], np.array([1, 2, 3]) * DEG_H, rtol=1e-12)


VIBRATING = """
multibody:
  bodies:
    - {name: base, hinge: locked, mass: 10 kg, inertia: "[1, 1, 1] kg*m^2"}
    - {name: shaker, parent: base, hinge: prismatic, axis: [0, 1, 0], mass: 2 kg, inertia: "[0.1, 0.1, 0.1] kg*m^2",
       initial: {displacement: 0.003 m}}
  nodes:
    - {name: imu_node, body: shaker, position: "[0.1, 0, 0] m"}
models:
  spring: {type: SloshSpringDamper, config: {dofs: 1, kind: translational}, attach: {hinge: shaker},
           parameters: {stiffness: [20000]}}
  imu: {type: Imu, rate: 1000 Hz, attach: {node: imu_node}}
integrator: {method: rk4, step: 0.0002 s}
log:
  rate: 1000 Hz
  signals: [imu.delta_velocity, imu.delta_angle]
"""


def test_vibrating_node_senses_the_oscillating_specific_force(tmp_path):
    import textwrap

    from shell.log_file import read_log
    from shell.scenario import build_simulation, parse_scenario

    sim = build_simulation(parse_scenario(textwrap.dedent(VIBRATING), "shaker.yaml", None))
    sim.run(0.5, log_path=tmp_path / "shaker.h5")
    log = read_log(tmp_path / "shaker.h5")
    omega, amplitude = np.sqrt(20000 / 2.0), 0.003          # 100 rad/s, 3 mm
    t = log["time"][1:]
    # delta velocity of each 1 ms sample = v(t_k) - v(t_k - T) of x = A cos(omega t), along the axis
    expected = -amplitude * omega * (np.sin(omega * t) - np.sin(omega * (t - 1e-3)))
    # RK4 at h = 0.2 ms (omega h = 0.02): the accumulated truncation error of the oscillator reaches
    # ~1e-9 of A omega after 2500 steps (measured); tolerance 1e-8
    assert_allclose(log["imu.delta_velocity"][1:, 1], expected, rtol=0, atol=1e-8 * amplitude * omega)
    assert_allclose(log["imu.delta_velocity"][1:, [0, 2]], 0.0, atol=1e-15)
    assert_allclose(log["imu.delta_angle"], 0.0, atol=0)     # pure translation


def test_the_sample_reads_no_input():
    """Imu.update_reads_inputs is False (a sample evaluates no output stage for it: no forward dynamics per
    sample): its update must give the same record with non-finite inputs as with real ones."""
    import textwrap

    from shell.models.imu import imu_sample
    from shell.scenario import build_simulation, parse_scenario

    imu = Imu("imu", period=0.01, gyro_random_walk="0.15 deg/hour**0.5", accel_bias_instability="0.1 m/s**2")
    assert imu.update_reads_inputs is False
    rng = np.random.default_rng(5)
    x = rng.normal(size=imu.x_layout.size)
    noise = rng.normal(size=imu.noise_size)
    records = []
    for u in (rng.normal(size=imu.u_layout.size), np.full(imu.u_layout.size, np.nan)):
        z = imu.initial_discrete_state()
        imu_sample(0.01, x, z, u, imu.p, noise.copy())
        records.append(z)
    assert np.all(np.isfinite(records[1]))
    np.testing.assert_array_equal(records[0], records[1])
    # so the scene's diagram gives its samples no output stage to evaluate (the engine's forward dynamics)
    sim = build_simulation(parse_scenario(textwrap.dedent(SPINNING), "scene.yaml", None))
    d = sim.diagram
    assert d.input_stages[d.model_index["imu"]] == ()
