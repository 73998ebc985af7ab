"""configs/rw_attitude*.yaml, the scenes benchmarks/basilisk_race.py races against Basilisk, stay valid.

They run through ``flexshell run``, and they start from the state the race's Basilisk side starts
from (its scenarioAttitudeFeedbackRW initial conditions), checked against independent formulas here,
without Basilisk: wheel speeds 100, 200, 300 rpm from the YAML's wheel momenta, the attitude of the
MRP [0.1, 0.2, -0.3], and the center of mass on the orbit of the classical elements
a = 10,000 km, e = 0.01, i = 33.3 deg, RAAN 48.2 deg, argument of perigee 347.8 deg, true anomaly
85.3 deg (mu = 3.98600436e14 m^3/s^2, Basilisk 2.12's Earth).
"""

from pathlib import Path

import numpy as np
import pytest

from shell.cli import main
from shell.log_file import read_log
from shell.scenario import build_simulation, load_scenario

ROOT = Path(__file__).resolve().parents[2]
CONFIGS = ["rw_attitude.yaml", "rw_attitude_slosh_panels.yaml"]
MU = 3.98600436e14
SIGMA_BN = np.array([0.1, 0.2, -0.3])
OMEGA_BN_B = np.array([0.001, -0.01, 0.03])
# (node at a body's center of mass, the body's mass in kg), per scene
MASS_POINTS = {
    "rw_attitude.yaml": [("acs", 750.0)],
    "rw_attitude_slosh_panels.yaml": [("acs", 750.0), ("particle1_cm", 15.0), ("particle2_cm", 15.0),
                                      ("panel1_cm", 40.0), ("panel2_cm", 40.0)],
}


def orbit_state(a, e, i, raan, argp, f, mu=MU):
    """Inertial position and velocity from classical elements (Vallado, Fundamentals of Astrodynamics,
    4th ed., algorithm 10: perifocal state rotated by RAAN, inclination, argument of perigee)."""
    p = a * (1.0 - e * e)
    r_pqw = p / (1.0 + e * np.cos(f)) * np.array([np.cos(f), np.sin(f), 0.0])
    v_pqw = np.sqrt(mu / p) * np.array([-np.sin(f), e + np.cos(f), 0.0])

    def rot3(angle):
        c, s = np.cos(angle), np.sin(angle)
        return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])

    rot1 = np.array([[1.0, 0.0, 0.0], [0.0, np.cos(i), -np.sin(i)], [0.0, np.sin(i), np.cos(i)]])
    rotation = rot3(raan) @ rot1 @ rot3(argp)
    return rotation @ r_pqw, rotation @ v_pqw


def mrp_dcm_bn(sigma):
    """[BN] of an MRP: I + (8 [s]^2 - 4 (1 - s.s) [s]) / (1 + s.s)^2 (Schaub and Junkins, Analytical
    Mechanics of Space Systems, eq. 3.153)."""
    s = np.array([[0.0, -sigma[2], sigma[1]], [sigma[2], 0.0, -sigma[0]], [-sigma[1], sigma[0], 0.0]])
    s2 = sigma @ sigma
    return np.eye(3) + (8.0 * s @ s - 4.0 * (1.0 - s2) * s) / (1.0 + s2) ** 2


def quaternion_dcm(q):
    w, x, y, z = q
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                     [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                     [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])


@pytest.mark.parametrize("name", CONFIGS)
def test_runs_through_flexshell_run(name, tmp_path, capsys):
    log_path = tmp_path / "run.h5"
    code = main(["run", str(ROOT / "configs" / name), "--t-final", "0.2", "-o", str(log_path), "--quiet"])
    out = capsys.readouterr().out
    assert code == 0, out
    assert "completed at t = 0.2 s" in out and "20 steps" in out      # RK4 at 10 ms
    log = read_log(log_path)
    np.testing.assert_allclose(log["time"], [0.0, 0.1, 0.2], atol=1e-12)
    for signal in ("multibody.acs.attitude", "multibody.acs.angular_velocity", "imu.angular_rate",
                   "controller.torque", "rw1.wheel_speed", "rw2.wheel_speed", "rw3.wheel_speed"):
        assert np.all(np.isfinite(log[signal])), signal
    # the YAML's wheel momenta J_s (a . omega_0 + Omega_0) give back the classic 100, 200, 300 rpm
    speeds = [log[f"rw{k}.wheel_speed"][0] * 30.0 / np.pi for k in (1, 2, 3)]
    np.testing.assert_allclose(speeds, [100.0, 200.0, 300.0], rtol=1e-13)
    # the quaternion is the MRP's attitude (body -> inertial = [BN]^T), to rounding of its 16 digits
    np.testing.assert_allclose(quaternion_dcm(log["multibody.acs.attitude"][0]), mrp_dcm_bn(SIGMA_BN).T,
                               atol=2e-16)
    np.testing.assert_allclose(log["multibody.acs.angular_velocity"][0], OMEGA_BN_B, rtol=1e-15)
    # the 82 deg error saturates every wheel over the first sample (|command| > 0.2 N m): each wheel's
    # absolute momentum gains exactly 0.1 s x 0.2 N m (no friction), i.e. Omega = h / J_s - a . omega
    torque = log["controller.torque"][0]
    assert np.all(np.abs(torque) > 0.2), torque
    omega = log["multibody.acs.angular_velocity"]
    gained = [(log[f"rw{k + 1}.wheel_speed"][1] + omega[1, k] - log[f"rw{k + 1}.wheel_speed"][0] - omega[0, k])
              * 0.07957747154594767 for k in range(3)]
    np.testing.assert_allclose(gained, -0.1 * 0.2 * np.sign(torque), rtol=1e-12)


@pytest.mark.parametrize("name", CONFIGS)
def test_center_of_mass_starts_on_the_races_orbit(name):
    sim = build_simulation(load_scenario(ROOT / "configs" / name))
    sim.evaluate()
    total = sum(m for _, m in MASS_POINTS[name])
    r_c = sum(m * sim.signal(f"multibody.{node}.position") for node, m in MASS_POINTS[name]) / total
    v_c = sum(m * sim.signal(f"multibody.{node}.rotation") @ sim.signal(f"multibody.{node}.linear_velocity")
              for node, m in MASS_POINTS[name]) / total
    r, v = orbit_state(10_000e3, 0.01, *np.radians([33.3, 48.2, 347.8, 85.3]))
    # 17-digit YAML values and sums of five 1e7 m positions: rounding of 1e-9 m, 1e-12 m/s
    np.testing.assert_allclose(r_c, r, rtol=0.0, atol=1e-7)
    np.testing.assert_allclose(v_c, v, rtol=0.0, atol=1e-9)
