"""MrpFeedback: exact steady states under a constant disturbance (default suite, through YAML), and
Basilisk's mrpFeedback in the same process (``-m slow``, needs bsk): the law at random inputs with
feed-forward, wheels and the integral, and the closed loop of scenarioAttitudeFeedback."""

import numpy as np
import pytest
from numpy.testing import assert_allclose

from tests.models import mrp_feedback_basilisk as bsk_case
from shell.models.mrp_feedback import INPUTS, U, Z, MrpFeedback, _mrp_feedback_update
from shell.log_file import read_log
from shell.scenario import build_simulation, parse_scenario


def _run(text, t_final):
    sim = build_simulation(parse_scenario(text, "mrp_feedback.yaml", None))
    sim.run(t_final)
    return sim


def _fast(text):
    # the analytic cases need no 10 ms steps: the loop's poles are below 0.1 rad/s
    return text.replace("step: 0.01 s", "step: 0.1 s")


def test_pd_steady_state_is_the_exact_mrp_balance():
    # at rest the torque balances the disturbance d: K sigma = d exactly (sigma the MRP of the attitude)
    sim = _run(_fast(bsk_case.scene_text(900.0, 3.5, 30.0)), 900.0)
    q = sim.signal("multibody.bus.attitude")
    sigma = q[1:] / (1.0 + q[0]) * np.sign(q[0])
    # transient: slowest closed-loop pole ~ e^{-0.019 t}, 4e-8 of the initial error at 900 s
    assert_allclose(sigma, bsk_case.DISTURBANCE / 3.5, rtol=1e-6)
    assert_allclose(sim.signal("controller.attitude_error"), sigma, atol=1e-9)


def test_integral_feedback_removes_the_error_and_holds_the_disturbance():
    # Basilisk scenario's K_i; linearized, the slowest closed-loop pole is -0.0081 /s: e^{-24} at 3000 s
    ki = 0.0002
    sim = _run(_fast(bsk_case.scene_text(3000.0, 3.5, 30.0, ki=ki)), 3000.0)
    q = sim.signal("multibody.bus.attitude")
    assert np.linalg.norm(q[1:]) < 1e-6 * np.linalg.norm(bsk_case.DISTURBANCE / 3.5)
    # at rest P K_i s = d: the integral carries the disturbance
    assert_allclose(30.0 * ki * sim.signal("controller.integral"), bsk_case.DISTURBANCE, rtol=1e-5)


def test_the_integral_is_clamped_per_component():
    limit = 0.5  # N m s, below d / (P K_i) (>= 3.3 N m s) on every axis: the error cannot vanish
    sim = _run(_fast(bsk_case.scene_text(600.0, 3.5, 30.0, ki=0.0002, integral_limit=limit)), 600.0)
    s = sim.signal("controller.integral")
    assert_allclose(np.abs(s), limit, rtol=1e-12)


def test_refuses_a_non_symmetric_inertia():
    text = bsk_case.scene_text(1.0, 3.5, 30.0).replace("N*m*s, inertia: \"[[900.0, 15.0", "N*m*s, inertia: \"[[900.0, 16.0")
    with pytest.raises(Exception, match=r"mrp_feedback.yaml:\d+.*parameter inertia: expected a symmetric"):
        build_simulation(parse_scenario(text, "mrp_feedback.yaml", None))


# ------------------------------------------------------------------------------------------------
def _random_quaternion(rng):
    q = rng.standard_normal(4)
    return q / np.linalg.norm(q)


def _dcm(q):
    """rotation matrix child -> parent of [w, x, y, z] (independent of the kernels' helpers)."""
    w, x, y, z = q
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                     [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                     [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])


@pytest.mark.slow
@pytest.mark.parametrize("law_type", [0, 1])
def test_law_equals_basilisk_mrp_feedback_at_random_inputs(law_type):
    from Basilisk.architecture import messaging
    from Basilisk.fswAlgorithms import mrpFeedback
    from Basilisk.utilities import SimulationBaseClass, macros

    rng = np.random.default_rng(7)
    for trial in range(5):
        q_bn, q_rn = _random_quaternion(rng), _random_quaternion(rng)
        omega_bn = 0.05 * rng.standard_normal(3)
        omega_rn_n, domega_rn_n = 0.03 * rng.standard_normal(3), 1e-3 * rng.standard_normal(3)
        inertia = np.diag([900.0, 800.0, 600.0]) + 10.0 * (lambda a: a + a.T)(rng.standard_normal((3, 3)))
        axes = np.eye(3)
        js, speeds = np.array([0.08, 0.09, 0.1]), rng.uniform(-300.0, 300.0, 3)
        k, p, ki, limit = 3.5, 30.0, 0.01, 0.05
        known = 0.01 * rng.standard_normal(3)
        # Basilisk's guidance message: errors in body axes (attTrackingError's definitions)
        dcm_bn = _dcm(q_bn).T
        q_br = np.r_[q_rn[0], -q_rn[1:]]
        w1, v1, w2, v2 = q_br[0], q_br[1:], q_bn[0], q_bn[1:]
        q_br = np.r_[w1 * w2 - v1 @ v2, w1 * v2 + w2 * v1 + np.cross(v1, v2)]
        q_br = q_br if q_br[0] >= 0 else -q_br
        sigma_br = q_br[1:] / (1 + q_br[0])
        omega_rn_b, domega_rn_b = dcm_bn @ omega_rn_n, dcm_bn @ domega_rn_n

        sim = SimulationBaseClass.SimBaseClass()
        process = sim.CreateNewProcess("p")
        # first call at 0.5 s: Basilisk's dt is 0 at a call that follows one at t = 0 (priorTime 0 = none)
        process.addTask(sim.CreateNewTask("fsw", macros.sec2nano(0.5), FirstStart=macros.sec2nano(0.5)))
        control = mrpFeedback.mrpFeedback()
        control.K, control.P, control.Ki, control.integralLimit = k, p, ki, limit
        control.knownTorquePntB_B = known.tolist()
        control.controlLawType = law_type
        guid = messaging.AttGuidMsgPayload()
        guid.sigma_BR, guid.omega_BR_B = sigma_br.tolist(), (omega_bn - omega_rn_b).tolist()
        guid.omega_RN_B, guid.domega_RN_B = omega_rn_b.tolist(), domega_rn_b.tolist()
        guid_msg = messaging.AttGuidMsg().write(guid)
        vehicle = messaging.VehicleConfigMsgPayload()
        vehicle.ISCPntB_B = inertia.flatten().tolist()
        vehicle_msg = messaging.VehicleConfigMsg().write(vehicle)
        rw = messaging.RWArrayConfigMsgPayload()
        rw.GsMatrix_B, rw.JsList, rw.numRW = axes.flatten().tolist(), js.tolist(), 3
        rw.uMax = [0.2, 0.2, 0.2]
        rw_msg = messaging.RWArrayConfigMsg().write(rw)
        speed = messaging.RWSpeedMsgPayload()
        speed.wheelSpeeds = speeds.tolist()
        speed_msg = messaging.RWSpeedMsg().write(speed)
        control.guidInMsg.subscribeTo(guid_msg)
        control.vehConfigInMsg.subscribeTo(vehicle_msg)
        control.rwParamsInMsg.subscribeTo(rw_msg)
        control.rwSpeedsInMsg.subscribeTo(speed_msg)
        log = control.cmdTorqueOutMsg.recorder()
        sim.AddModelToTask("fsw", control)
        sim.AddModelToTask("fsw", log)
        sim.InitializeSimulation()
        sim.ConfigureStopTime(macros.sec2nano(1.5))    # calls at 0.5, 1.0, 1.5 s: the integral grows twice
        sim.ExecuteSimulation()
        # the recorder repeats its first time before the task's first call: the last row of each call time
        times, rows = log.times() * 1e-9, np.asarray(log.torqueRequestBody)
        expected = [rows[np.flatnonzero(np.isclose(times, t))[-1]] for t in (0.5, 1.0, 1.5)]

        model = MrpFeedback("c", k=k, p=p, ki=ki, integral_limit=limit, inertia=inertia.tolist(),
                            known_torque=known.tolist(), control_law_type=law_type)
        u = np.zeros(sum(d.size for d in INPUTS))
        u[U.attitude:U.attitude + 4] = q_bn
        u[U.angular_velocity:U.angular_velocity + 3] = omega_bn
        u[U.reference_attitude:U.reference_attitude + 4] = q_rn
        u[U.reference_angular_velocity:U.reference_angular_velocity + 3] = omega_rn_n
        u[U.reference_angular_acceleration:U.reference_angular_acceleration + 3] = domega_rn_n
        h = (js * (axes @ omega_bn + speeds)) @ axes
        u[U.wheel_momentum:U.wheel_momentum + 3] = h
        z = model.initial_discrete_state()
        for row, t in enumerate((0.5, 1.0, 1.5)):
            _mrp_feedback_update(t, np.zeros(0), z, u, model.p)
            # round-off of the frame changes: 1e-12 of the torque's size
            assert_allclose(z[Z.torque:Z.torque + 3], expected[row], rtol=0, atol=1e-12 * np.abs(expected[row]).max(),
                            err_msg=f"trial {trial}, call {row}")


@pytest.mark.slow
@pytest.mark.parametrize("case", [dict(k=3.5, p=30.0), dict(k=3.5, p=30.0, ki=0.0002, integral_limit=1000.0,
                                                                offset=0.1)],
                         ids=["pd", "pid"])
def test_closed_loop_equals_basilisk_scenario_attitude_feedback(case, tmp_path):
    duration = 300.0
    t, sigma_b, omega_b, _ = bsk_case.run_basilisk(duration, case["k"], case["p"], case.get("ki", -1.0),
                                                    case.get("integral_limit", 0.0), offset=case.get("offset", 0.0))
    sim = build_simulation(parse_scenario(bsk_case.scene_text(duration, **case), "mrp.yaml", None))
    path = tmp_path / "run.h5"
    sim.run(duration, log_path=path)
    log = read_log(path)
    q = log["multibody.bus.attitude"]
    omega = log["multibody.bus.angular_velocity"]
    n = min(len(t), len(q))
    assert_allclose(log["time"][:n], t[:n], atol=1e-9)
    q_b = np.array([bsk_case.mrp_to_quaternion(s) for s in sigma_b[:n]])
    angle = 2.0 * np.arcsin(np.minimum(1.0, np.linalg.norm(
        q[:n, 0:1] * q_b[:, 1:] - q_b[:, 0:1] * q[:n, 1:] - np.cross(q[:n, 1:], q_b[:, 1:]), axis=1)))
    # same RK4 at 10 ms, same zero-order hold: agreement to round-off over 30,000 steps (measured 6e-14 rad,
    # 1.6e-15 rad/s from an 82 deg initial error)
    assert angle.max() < 1e-12, angle.max()
    assert np.abs(omega[:n] - omega_b[:n]).max() < 1e-13


@pytest.mark.slow
def test_closed_loop_with_wheels_equals_basilisk_scenario_attitude_feedback_rw(tmp_path):
    """Basilisk's scenarioAttitudeFeedbackRW (three balanced HR16 wheels at 100/200/300 rpm, rwMotorTorque,
    mrpFeedback on the wheel speeds) against ReactionWheel x 3 whose spin_momentum outputs, summed, feed
    MrpFeedback.wheel_momentum. Control law type 1 (omega_BN x (I omega + h_s)): at the scenario's rest
    reference law 0's gyroscopic term (omega_RN + K_i z) x H vanishes and would not read the wheels. The
    commands saturate at the wheels' 0.2 N m for most of the run."""
    duration = 300.0
    t, sigma_b, omega_b, speeds_b, js, umax = bsk_case.run_basilisk_rw(duration, 3.5, 30.0)
    logs = {}
    for fed in (True, False):
        sim = build_simulation(parse_scenario(bsk_case.scene_text_rw(duration, 3.5, 30.0, js, umax, fed),
                                              "mrp_rw.yaml", None))
        sim.run(duration, log_path=tmp_path / f"rw_{fed}.h5")
        logs[fed] = read_log(tmp_path / f"rw_{fed}.h5")
    q_b = np.array([bsk_case.mrp_to_quaternion(s) for s in sigma_b])

    def angle(log):
        q = log["multibody.bus.attitude"][:len(q_b)]
        return 2.0 * np.arcsin(np.minimum(1.0, np.linalg.norm(
            q[:, 0:1] * q_b[:, 1:] - q_b[:, 0:1] * q[:, 1:] - np.cross(q[:, 1:], q_b[:, 1:]), axis=1)))

    log = logs[True]
    assert_allclose(log["time"][:len(t)], t, atol=1e-9)
    assert np.abs(log["controller.torque"]).max() > 0.2          # saturated: the wheels' limit is in play
    # same RK4 at 10 ms, same hold: round-off over 30,000 steps (measured 1.5e-13 rad, 6.5e-15 rad/s, wheel
    # speeds 7.1e-11 rad/s of 291 rad/s)
    assert angle(log).max() < 1e-11
    assert np.abs(log["multibody.bus.angular_velocity"][:len(t)] - omega_b).max() < 1e-12
    speeds = np.column_stack([log[f"rw{k}.wheel_speed"] for k in (1, 2, 3)])[:len(t)]
    assert np.abs(speeds - speeds_b).max() < 1e-9
    # without the wheels' momentum the same loop departs from Basilisk's (measured 0.17 rad): the input matters
    assert angle(logs[False]).max() > 1e-2
