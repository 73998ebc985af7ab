"""Closed-loop speed race against Basilisk: reaction-wheel attitude control in Earth orbit, same process.

The scene a guidance-and-control engineer would otherwise build in Basilisk (its example
scenarioAttitudeFeedbackRW), written once in flexshell's YAML (``configs/rw_attitude.yaml``, and
``configs/rw_attitude_slosh_panels.yaml`` with two slosh particles and two hinged rigid panels) and
once here from Basilisk's documented modules:

* ``spacecraft.Spacecraft`` hub (750 kg, products of inertia), RK4 (Basilisk's default integrator) at
  the dynamics task rate, 10 ms; Earth point-mass gravity (``gravBodyFactory.createEarth``);
* ``reactionWheelStateEffector`` with three ``Honeywell_HR16`` wheels (50 N m s, balanced wheels, no
  friction, no minimum torque; 0.2 N m and 6000 rpm limits) on the body axes;
* ``imuSensor`` with a constant gyro bias and white rate noise, sampled at 10 Hz, brought to the
  controller by ``imuComm`` + ``rateMsgConverter`` and merged by ``navAggregate`` with the attitude of
  ``simpleNav`` (an ideal star tracker);
* ``inertial3D`` + ``attTrackingError`` + ``mrpFeedback`` (K = 3.5, P = 30, no integral term) +
  ``rwMotorTorque`` at 10 Hz;
* with ``--scenes slosh_panels``: two ``linearSpringMassDamper`` particles and two
  ``hingedRigidBodyStateEffector`` panels.

Same physics on both sides, and where they differ:

* Basilisk's hub inertia includes the balanced wheels' spin inertia (its wheel effector removes
  ``J_s g g^T``); flexshell's bus excludes it (its ``ReactionWheel`` carries it): the YAML bus has
  ``J_s`` less on each wheel axis. flexshell refuses a body without rotational inertia, so each slosh
  particle is a 1e-3 kg m^2 ball whose inertia is taken from the bus (exact: a prismatic hinge never
  rotates the particle relative to the bus).
* Gravity: Earth point mass on both sides (``configs/rw_attitude.yaml``: no gravity-gradient torque,
  as Basilisk's gravity effector). With appendages flexshell applies the field at each body's center
  of mass (one ``CentralBodyGravity`` per body), which gives the spacecraft the gravity-gradient torque
  of their layout: that scene therefore carries the full gravity-gradient torque on both sides
  (Basilisk: ``GravityGradientEffector``, on the whole spacecraft's inertia; flexshell: each body's own
  term in addition). What remains different there is where it acts: tidal forces of 2e-6 m/s^2 on
  the panels in flexshell, a torque on the hub in Basilisk (1e-7 rad of hinge deflection).
* Control law: MRP feedback ``-K sigma - P omega`` (sigma = tan(theta/4) e) against flexshell's
  quaternion PD ``-kp 2 sin(theta/2) e - kd omega`` with ``kp = K/4``, ``kd = P``: equal to O(theta^3),
  so the same linear loop near the target and the same steady state under the gyro bias
  (``theta = 4 P |b| / K``); up to 14 % apart at the initial 82 deg, where the wheels saturate anyway.
* Gyro: Basilisk's ``imuSensor`` reports the instantaneous rate plus bias plus noise, and nothing at its
  first call (t = 0: the controller sees zero rate); flexshell's ``Imu`` reports the mean rate over the
  last sample (delta angle / T, an effective 50 ms lag, 1.5e-3 rad of phase at the loop's 0.03 rad/s)
  plus bias plus angle random walk, and zero true increment at t = 0. Noise is white in both with the
  same per-sample standard deviation ``N / sqrt(T)``; the draws differ (different generators), so the
  noisy closed-loop answers agree statistically, and the noise is kept 100x below the bias effect.

The same-law check (run before the race unless ``--no-verify``) tests the claim "same physics": the
flexshell scene with its gyro and controller replaced by a ``UserFunction`` computing exactly
mrpFeedback's law from the true rate plus bias (and zero rate at t = 0, as Basilisk's first IMU call),
against Basilisk with the gyro noise off; every state both report (attitude, body rate, wheel speeds,
panel angles and rates, hub position) must agree over the whole run. Twice: in orbit, and without
gravity with the center of mass at rest. Without orbit the two agree to round-off (a few 1e-13 over
60,000 RK4 steps of closed loop), and in orbit too since the engine leaves the velocity-product term
``v x (m v)`` out of its bias (zero in exact arithmetic; with the 7 km/s orbital velocity carried in body
axes by the free hinge, its round-off was a torque of order eps m |v|^2 that drifted the wheel speeds by
a few 1e-7 in 600 s; found by this check, fixed in ``dynamics.kernels.body_terms.rigid_bias_add``). Measured
2026-11-23 in orbit, reaction-wheel scene: attitude 1.5e-13, body rate 1.9e-13, wheel speeds 2.4e-13
(relative), hub position 1.8e-6 m on a 1e7 m orbit. The slosh-and-panels scene in orbit stays at
5e-8..1e-6 (relative): where the gravity-gradient acts differs between the two (tidal forces on the
panels in flexshell, a hub torque in Basilisk: see above), so ``TOLERANCES`` in orbit stays 1e-5.

Timing (the race): both simulators run the full scene, each build excluded, alternately in this one
process (flexshell, Basilisk, flexshell, ...) for ``--pairs`` pairs; per-step time = wall time of the
run (flexshell ``Simulation.run``'s own clock, Basilisk ``ExecuteSimulation``) / integration steps
(0.01 s each). Both record attitude, rate, gyro output, torque command and wheel speeds (and the
panel angles) at 10 Hz. The table gives each pair and the median of the
per-pair ratios flexshell / Basilisk. BLAS/OpenMP/numba threads are capped at 1 and the load average is
printed before and after (the machine is shared: only ratios of interleaved runs mean anything).

The flexshell side uses only the user path: ``shell.scenario.load_scenario`` + ``build_simulation`` +
``Simulation.run`` with an HDF5 log read by ``shell.log_file.read_log`` (``parse_scenario`` for the
verification variant).

Install the peers: ``pip install -e ".[bench]"`` (bsk, exudyn, threadpoolctl).
Run: ``python benchmarks/basilisk_race.py [--scenes rw slosh_panels] [--pairs 5] [--duration 600]
[--no-verify | --verify-only]`` from the repository root (about 25 minutes with the defaults on a
loaded 2-core machine).
"""

from __future__ import annotations

import os

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from dataclasses import dataclass, field  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
import yaml  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

# ------------------------------------------------------------------------------------------------
# The Basilisk scene's numbers (SI). configs/rw_attitude*.yaml hold the same values, converted where
# the conventions differ (see the module docstring); verify() checks that the two scenes agree.
STEP = 0.01                                   # s, dynamics task = RK4 step
CONTROL_PERIOD = 0.1                          # s, gyro and flight software
HUB_MASS = 750.0                              # kg
HUB_INERTIA = np.array([[900.0, 15.0, -10.0], [15.0, 800.0, 20.0], [-10.0, 20.0, 600.0]])  # kg m^2, about Bc
WHEEL_AXES = np.eye(3)
WHEEL_MAX_MOMENTUM = 50.0                     # N m s: HR16 size; J_s = 50 / (6000 rpm)
WHEEL_SPEEDS_RPM = (100.0, 200.0, 300.0)      # initial
SIGMA_BN = np.array([0.1, 0.2, -0.3])         # initial MRP
OMEGA_BN_B = np.array([0.001, -0.01, 0.03])   # rad/s, initial
ORBIT = dict(a=10_000e3, e=0.01, i=33.3, raan=48.2, argp=347.8, f=85.3)  # m, deg
K_GAIN, P_GAIN = 3.5, 30.0                    # mrpFeedback
GYRO_BIAS = np.radians([3.0, -2.0, 2.5]) / 3600.0          # rad/s (3, -2, 2.5 deg/h)
GYRO_ARW = np.radians(0.003) / 60.0                         # rad/sqrt(s) (0.003 deg/sqrt(h))
GYRO_SEED = 11
# slosh particles (linearSpringMassDamper) and hinged panels (hingedRigidBodyStateEffector)
PARTICLES = (dict(mass=15.0, k=150.0, c=3.0, r_PB_B=[0.1, 0.0, -0.1], pHat_B=[1.0, 0.0, 0.0], rho=0.05),
             dict(mass=15.0, k=150.0, c=3.0, r_PB_B=[0.0, 0.1, 0.1], pHat_B=[0.0, 1.0, 0.0], rho=0.0))
PANELS = (dict(mass=40.0, inertia=[3.5, 30.0, 33.0], d=1.5, k=1200.0, c=20.0, r_HB_B=[0.5, 0.0, 1.0],
               dcm_HB=[[-1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, 1.0]], theta=np.radians(5.0)),
          dict(mass=40.0, inertia=[3.5, 30.0, 33.0], d=1.5, k=1200.0, c=20.0, r_HB_B=[-0.5, 0.0, 1.0],
               dcm_HB=np.eye(3).tolist(), theta=0.0))

# the UserFunction of verify() imports this module by name: the running one, not a second copy
_MODULE = "basilisk_race"
sys.modules.setdefault(_MODULE, sys.modules[__name__])

SCENES = {
    "rw": ROOT / "configs" / "rw_attitude.yaml",
    "slosh_panels": ROOT / "configs" / "rw_attitude_slosh_panels.yaml",
}
#: the attitude error the settling time is measured to: the appendages add ~400 kg m^2 and their
#: momentum, so that scene reaches 1 deg only after ~700 s (5 deg at ~480 s)
SETTLE_DEG = {"rw": 1.0, "slosh_panels": 5.0}


@dataclass
class Result:
    """One run of one simulator: time histories at 10 Hz (SI) and its timing."""

    t: np.ndarray
    angle_deg: np.ndarray          # attitude error angle
    wheel_rpm: np.ndarray          # (n, 3) wheel speeds relative to the bus
    wall: float = 0.0
    steps: int = 0
    extra: dict = field(default_factory=dict)   # verification signals

    @property
    def per_step_us(self) -> float:
        return 1e6 * self.wall / self.steps


# ------------------------------------------------------------------------------------------------
# Basilisk
def build_basilisk(scene: str, duration: float, gyro_noise: bool = True, verify: bool = False, orbit: bool = True):
    """The Basilisk simulation of ``scene`` ("rw" or "slosh_panels"), initialized; returns (sim, reader)
    where ``reader()`` gives a :class:`Result` after ``sim.ExecuteSimulation()``. ``orbit=False``: no
    gravity and the center of mass at rest at the origin (verify()'s probe of the rotational dynamics)."""
    from Basilisk.architecture import messaging
    from Basilisk.fswAlgorithms import (attTrackingError, imuComm, inertial3D, mrpFeedback, navAggregate,
                                        rateMsgConverter, rwMotorTorque)
    from Basilisk.simulation import (GravityGradientEffector, hingedRigidBodyStateEffector, imuSensor,
                                     linearSpringMassDamper, reactionWheelStateEffector, simpleNav, spacecraft)
    from Basilisk.utilities import SimulationBaseClass, macros, orbitalMotion, simIncludeGravBody, simIncludeRW

    sim = SimulationBaseClass.SimBaseClass()
    process = sim.CreateNewProcess("process")
    # at instants shared by both tasks the dynamics task runs first (higher priority), so the flight
    # software reads the state at t_k and its command holds over [t_k, t_k + T], as in flexshell
    process.addTask(sim.CreateNewTask("dynamics", macros.sec2nano(STEP)), 200)
    process.addTask(sim.CreateNewTask("fsw", macros.sec2nano(CONTROL_PERIOD)), 100)

    sc = spacecraft.Spacecraft()
    sc.ModelTag = "sc"
    sc.hub.mHub = HUB_MASS
    sc.hub.r_BcB_B = [[0.0], [0.0], [0.0]]
    sc.hub.IHubPntBc_B = HUB_INERTIA.tolist()
    gravity = simIncludeGravBody.gravBodyFactory()
    earth = gravity.createEarth()
    earth.isCentralBody = True
    if orbit:
        gravity.addBodiesTo(sc)

    wheels = simIncludeRW.rwFactory()
    for axis, rpm in zip(WHEEL_AXES, WHEEL_SPEEDS_RPM):
        wheels.create("Honeywell_HR16", axis.tolist(), maxMomentum=WHEEL_MAX_MOMENTUM, Omega=rpm,
                      RWModel=messaging.BalancedWheels)
    rw_effector = reactionWheelStateEffector.ReactionWheelStateEffector()
    wheels.addToSpacecraft("wheels", rw_effector, sc)
    # the wheel effector reads its command before the hub integrates (priority 2 > 1): the command
    # written at t_k is applied from the step that starts at t_k
    sim.AddModelToTask("dynamics", rw_effector, None, 2)
    sim.AddModelToTask("dynamics", sc, None, 1)

    effectors = []
    if scene == "slosh_panels" and orbit:
        # flexshell's per-body gravity carries the gravity gradient of the appendages' layout, which a
        # spacecraft-level field cannot omit; Basilisk gets its gravity-gradient effector (torque of the
        # whole spacecraft's inertia about its center of mass) and flexshell each body's own term
        gravity_gradient = GravityGradientEffector.GravityGradientEffector()
        gravity_gradient.ModelTag = "gravity_gradient"
        gravity_gradient.addPlanetName(earth.planetName)
        sc.addDynamicEffector(gravity_gradient)
        sim.AddModelToTask("dynamics", gravity_gradient)
        effectors.append(gravity_gradient)
    if scene == "slosh_panels":
        for k, spec in enumerate(PARTICLES):
            particle = linearSpringMassDamper.LinearSpringMassDamper()
            particle.ModelTag = f"particle{k + 1}"
            particle.massInit = spec["mass"]
            particle.k = spec["k"]
            particle.c = spec["c"]
            particle.r_PB_B = [[v] for v in spec["r_PB_B"]]
            particle.pHat_B = [[v] for v in spec["pHat_B"]]
            particle.rhoInit = spec["rho"]
            particle.rhoDotInit = 0.0
            particle.nameOfRhoState = f"rho{k + 1}"
            particle.nameOfRhoDotState = f"rhoDot{k + 1}"
            particle.nameOfMassState = f"slosh_mass{k + 1}"
            sc.addStateEffector(particle)
            effectors.append(particle)
        for k, spec in enumerate(PANELS):
            panel = hingedRigidBodyStateEffector.HingedRigidBodyStateEffector()
            panel.ModelTag = f"panel{k + 1}"
            panel.mass = spec["mass"]
            panel.IPntS_S = np.diag(spec["inertia"]).tolist()
            panel.d = spec["d"]
            panel.k = spec["k"]
            panel.c = spec["c"]
            panel.r_HB_B = [[v] for v in spec["r_HB_B"]]
            panel.dcm_HB = spec["dcm_HB"]
            panel.thetaInit = spec["theta"]
            panel.thetaDotInit = 0.0
            panel.nameOfThetaState = f"theta{k + 1}"
            panel.nameOfThetaDotState = f"thetaDot{k + 1}"
            sc.addStateEffector(panel)
            sim.AddModelToTask("dynamics", panel)
            effectors.append(panel)

    elements = orbitalMotion.ClassicElements()
    elements.a, elements.e = ORBIT["a"], ORBIT["e"]
    elements.i, elements.Omega = np.radians(ORBIT["i"]), np.radians(ORBIT["raan"])
    elements.omega, elements.f = np.radians(ORBIT["argp"]), np.radians(ORBIT["f"])
    r_N, v_N = orbitalMotion.elem2rv(earth.mu, elements) if orbit else (np.zeros(3), np.zeros(3))
    sc.hub.r_CN_NInit = [[v] for v in r_N]
    sc.hub.v_CN_NInit = [[v] for v in v_N]
    sc.hub.sigma_BNInit = [[v] for v in SIGMA_BN]
    sc.hub.omega_BN_BInit = [[v] for v in OMEGA_BN_B]

    # sensors and flight software at 10 Hz
    nav = simpleNav.SimpleNav()
    nav.scStateInMsg.subscribeTo(sc.scStateOutMsg)
    imu = imuSensor.ImuSensor()
    imu.scStateInMsg.subscribeTo(sc.scStateOutMsg)
    imu.senRotBias = GYRO_BIAS.tolist()
    sigma_rate = GYRO_ARW / np.sqrt(CONTROL_PERIOD) if gyro_noise else 0.0
    imu.setAMatrixGyro(np.zeros((3, 3)))           # no memory: white rate noise of 1-sigma PMatrix
    imu.PMatrixGyro = (sigma_rate * np.eye(3)).tolist()
    imu.RNGSeed = GYRO_SEED
    imu_comm = imuComm.imuComm()
    imu_comm.dcm_BP = np.eye(3).flatten().tolist()
    imu_comm.imuComInMsg.subscribeTo(imu.sensorOutMsg)
    rate = rateMsgConverter.rateMsgConverter()
    rate.imuRateInMsg.subscribeTo(imu_comm.imuSensorOutMsg)
    aggregate = navAggregate.navAggregate()
    aggregate.attMsgs = [navAggregate.AggregateAttInput(), navAggregate.AggregateAttInput()]
    aggregate.attMsgs[0].navAttInMsg.subscribeTo(nav.attOutMsg)              # star tracker: attitude
    aggregate.attMsgs[1].navAttInMsg.subscribeTo(rate.navRateOutMsg)         # gyro: rate
    aggregate.attMsgCount = 2
    aggregate.attIdx, aggregate.attTimeIdx, aggregate.rateIdx, aggregate.sunIdx = 0, 0, 1, 0
    reference = inertial3D.inertial3D()
    reference.sigma_R0N = [0.0, 0.0, 0.0]
    tracking = attTrackingError.attTrackingError()
    tracking.attNavInMsg.subscribeTo(aggregate.navAttOutMsg)
    tracking.attRefInMsg.subscribeTo(reference.attRefOutMsg)
    control = mrpFeedback.mrpFeedback()
    control.K, control.P, control.Ki = K_GAIN, P_GAIN, -1.0      # Ki < 0: no integral term
    control.guidInMsg.subscribeTo(tracking.attGuidOutMsg)
    vehicle = messaging.VehicleConfigMsgPayload()
    vehicle.ISCPntB_B = HUB_INERTIA.flatten().tolist()    # enters only terms that vanish here (omega_R = 0)
    vehicle_msg = messaging.VehicleConfigMsg().write(vehicle)
    control.vehConfigInMsg.subscribeTo(vehicle_msg)
    rw_params_msg = wheels.getConfigMessage()
    motor = rwMotorTorque.rwMotorTorque()
    motor.controlAxes_B = np.eye(3).flatten().tolist()
    motor.rwParamsInMsg.subscribeTo(rw_params_msg)
    motor.vehControlInMsg.subscribeTo(control.cmdTorqueOutMsg)
    rw_effector.rwMotorCmdInMsg.subscribeTo(motor.rwMotorTorqueOutMsg)
    # execution order inside the 10 Hz task: sensors, navigation, guidance, control, allocation
    for priority, module in enumerate((imu, imu_comm, rate, nav, aggregate, reference, tracking, control, motor)):
        sim.AddModelToTask("fsw", module, None, 100 - priority)

    # what flexshell's YAML logs: attitude and rate (guidance), gyro output, torque command, wheel
    # speeds, panel angles; the spacecraft state as well for the check
    sample = macros.sec2nano(CONTROL_PERIOD)
    guidance_log = tracking.attGuidOutMsg.recorder(sample)
    speed_log = rw_effector.rwSpeedOutMsg.recorder(sample)
    gyro_log = imu.sensorOutMsg.recorder(sample)
    command_log = control.cmdTorqueOutMsg.recorder(sample)
    panel_logs = [e.hingedRigidBodyOutMsg.recorder(sample) for e in effectors if hasattr(e, "hingedRigidBodyOutMsg")]
    recorders = [guidance_log, speed_log, gyro_log, command_log, *panel_logs]
    state_log = None
    if verify:
        state_log = sc.scStateOutMsg.recorder(sample)
        recorders.append(state_log)
    for recorder in recorders:
        sim.AddModelToTask("fsw", recorder)

    # Basilisk's C++ side keeps raw pointers to effectors, gravity bodies and stand-alone messages:
    # their Python owners must live as long as the simulation
    sim.keep_alive = [sc, gravity, earth, wheels, rw_effector, effectors, vehicle_msg, rw_params_msg, nav, imu,
                      imu_comm, rate, aggregate, reference, tracking, control, motor, recorders]
    sim.InitializeSimulation()
    sim.ConfigureStopTime(macros.sec2nano(duration))

    def reader() -> Result:
        t = guidance_log.times() * 1e-9
        sigma = np.asarray(guidance_log.sigma_BR)
        result = Result(t=t, angle_deg=np.degrees(4.0 * np.arctan(np.linalg.norm(sigma, axis=1))),
                        wheel_rpm=np.asarray(speed_log.wheelSpeeds)[:, :3] * 30.0 / np.pi)
        if verify:
            result.extra["sigma_BN"] = np.asarray(state_log.sigma_BN)
            result.extra["omega_BN_B"] = np.asarray(state_log.omega_BN_B)
            result.extra["r_BN_N"] = np.asarray(state_log.r_BN_N)
            result.extra["v_BN_N"] = np.asarray(state_log.v_BN_N)
            if panel_logs:
                result.extra["panel_theta"] = np.column_stack([np.asarray(p.theta) for p in panel_logs])
                result.extra["panel_theta_dot"] = np.column_stack([np.asarray(p.thetaDot) for p in panel_logs])
        return result

    return sim, reader


def run_basilisk(scene: str, duration: float, gyro_noise: bool = True, verify: bool = False,
                 orbit: bool = True) -> Result:
    sim, reader = build_basilisk(scene, duration, gyro_noise, verify, orbit)
    start = time.perf_counter()
    sim.ExecuteSimulation()
    wall = time.perf_counter() - start
    result = reader()
    result.wall, result.steps = wall, int(round(duration / STEP))
    return result


# ------------------------------------------------------------------------------------------------
# flexshell
def _flexshell_result(simulation, duration: float, workdir: Path, extra_signals=()) -> Result:
    from shell.log_file import read_log

    log_path = workdir / "run.h5"
    summary = simulation.run(duration, log_path=log_path)
    if summary.status != "completed":
        raise RuntimeError(f"flexshell run {summary.status}: {summary.reason}")
    log = read_log(log_path)
    w = np.abs(log["multibody.acs.attitude"][:, 0])     # command = identity: error angle 2 acos|w|
    result = Result(t=log["time"], angle_deg=np.degrees(2.0 * np.arccos(np.minimum(w, 1.0))),
                    wheel_rpm=np.column_stack([log[f"rw{k}.wheel_speed"] for k in (1, 2, 3)]) * 30.0 / np.pi,
                    wall=summary.wall_time, steps=summary.steps)
    for name in extra_signals:
        result.extra[name] = log[name]
    return result


def run_flexshell(scene: str, duration: float, workdir: Path) -> Result:
    """The scene's YAML through the user path: load_scenario + build_simulation + Simulation.run."""
    from shell.scenario import build_simulation, load_scenario

    simulation = build_simulation(load_scenario(SCENES[scene]))
    return _flexshell_result(simulation, duration, workdir)


def mrp_feedback_check_law(t, signals):
    """mrpFeedback's law (K, P, no integral, inertial reference) on the true rate plus the gyro bias,
    with zero rate at t = 0 as Basilisk's imuSensor (no output at its first call). Used by verify()."""
    q = signals["attitude"]
    q = q if q[0] >= 0.0 else -q                      # |sigma| <= 1, the short rotation
    sigma = q[1:] / (1.0 + q[0])
    rate = signals["angular_velocity"] + GYRO_BIAS if t > 0.0 else np.zeros(3)
    return {"torque": -K_GAIN * sigma - P_GAIN * rate}


def verification_scene_text(scene: str, initial_translation=None) -> str:
    """The scene's YAML with its gyro and PD controller replaced by :func:`mrp_feedback_check_law`.
    ``initial_translation = (position (world), velocity (body axes))``: the orbit-free probe, without
    gravity models and with the bus's translational state replaced."""
    document = yaml.safe_load(SCENES[scene].read_text())
    models = document["models"]
    removed = {"imu", "controller"}
    if initial_translation is not None:
        removed |= {name for name, entry in models.items() if entry["type"] == "CentralBodyGravity"}
        position, velocity = initial_translation
        initial = document["multibody"]["bodies"][0]["initial"]
        initial["position"] = f"{np.asarray(position).tolist()} m"
        initial["velocity"] = f"{np.asarray(velocity).tolist()} m/s"
    for name in removed:
        del models[name]
    models["law"] = {"type": "UserFunction", "rate": "10 Hz", "config": {
        "function": f"{_MODULE}:mrp_feedback_check_law",
        "inputs": {"attitude": {"shape": [4]}, "angular_velocity": {"unit": "rad/s", "shape": [3]}},
        "outputs": {"torque": {"unit": "N*m", "shape": [3]}}}}
    document["connections"] = [c for c in document["connections"]
                                if not any(f"{name}." in c for name in removed)]
    document["connections"] += ["multibody.acs.attitude -> law.attitude",
                                "multibody.acs.angular_velocity -> law.angular_velocity",
                                "law.torque -> allocator.demand"]
    signals = ["multibody.acs.attitude", "multibody.acs.angular_velocity", "multibody.acs.position",
               "rw1.wheel_speed", "rw2.wheel_speed", "rw3.wheel_speed"]
    if scene == "slosh_panels":
        signals += ["multibody.panel1.q", "multibody.panel2.q", "multibody.panel1.u", "multibody.panel2.u"]
    document["log"] = {"rate": "10 Hz", "signals": signals}
    return yaml.safe_dump(document, sort_keys=False)


# ------------------------------------------------------------------------------------------------
# closed-loop answers
def settling_time(t, angle_deg, threshold=1.0) -> float:
    """Last time the attitude error is above ``threshold``, interpolated between samples."""
    above = np.nonzero(angle_deg > threshold)[0]
    if above.size == 0:
        return 0.0
    k = above[-1]
    if k + 1 >= t.size:
        return float("inf")
    a, b = angle_deg[k], angle_deg[k + 1]
    return float(t[k] + (t[k + 1] - t[k]) * (a - threshold) / (a - b))


def answers(result: Result, settle_deg: float, window: float = 10.0) -> dict:
    """Final attitude error (mean over the last ``window`` s, which averages the gyro noise), settling
    time to ``settle_deg``, peak and final wheel speeds."""
    tail = result.t >= result.t[-1] - window
    return {
        f"final attitude error (deg, mean of last {window:g} s)": float(result.angle_deg[tail].mean()),
        f"settling time to {settle_deg:g} deg (s)": settling_time(result.t, result.angle_deg, settle_deg),
        **{f"peak |wheel {k + 1}| (rpm)": float(np.abs(result.wheel_rpm[:, k]).max()) for k in range(3)},
        **{f"final wheel {k + 1} (rpm)": float(result.wheel_rpm[-1, k]) for k in range(3)},
    }


# ------------------------------------------------------------------------------------------------
def _quaternion_to_dcm(q):
    """Rotation matrices (n, 3, 3) body -> inertial of [w, x, y, z] quaternions (n, 4)."""
    w, x, y, z = q.T
    return np.stack([
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
        np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
        np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1)], 1)


def _mrp_to_dcm(sigma):
    """Rotation matrices (n, 3, 3) body -> inertial, [NB], of MRPs sigma_BN (n, 3)."""
    s2 = np.einsum("ij,ij->i", sigma, sigma)
    q = np.column_stack([(1.0 - s2), 2.0 * sigma]) / (1.0 + s2)[:, None]
    return _quaternion_to_dcm(q)


#: verify()'s tolerances. In orbit, flexshell's free hinge carries the 7 km/s orbital velocity in body
#: axes, and its velocity-product bias v x (m v), zero in exact arithmetic, leaves a roundoff torque of
#: order eps m |v|^2 (measured: the body rate of a torque-free body drifts 1e-10 rad/s in 10 s at
#: 7 km/s, 1.5e-14 at 70 m/s); over 600 s of closed loop that is a few 1e-7 of the wheel speeds. With
#: appendages, flexshell applies gravity at each body (tidal forces on the panels, 2e-6 m/s^2: 1e-7 rad
#: of hinge deflection) where Basilisk applies the whole spacecraft's gravity-gradient torque to the
#: hub. Without orbit both effects vanish and the two agree to roundoff over 60,000 RK4 steps.
TOLERANCES = {True: {"attitude": 1e-5, "rate": 1e-5, "wheels": 1e-5, "position": 1e-4, "panels": 1e-5},
              False: {"attitude": 1e-10, "rate": 1e-10, "wheels": 1e-10, "position": 1e-9, "panels": 1e-10}}


def verify(scene: str, duration: float, workdir: Path, orbit: bool = True):
    """Run both scenes with mrpFeedback's law and no gyro noise; returns rows (quantity, max difference,
    tolerance) and the two runs' closed-loop answers. ``orbit=False`` removes gravity and orbital
    motion from both (the probe of the rotational dynamics)."""
    from shell.scenario import build_simulation, parse_scenario

    theirs = run_basilisk(scene, duration, gyro_noise=False, verify=True, orbit=orbit)
    translation = None
    if not orbit:   # the bus origin's state that Basilisk derived from its center of mass at rest
        dcm_NB = _mrp_to_dcm(theirs.extra["sigma_BN"][:1])[0]
        translation = (theirs.extra["r_BN_N"][0], dcm_NB.T @ theirs.extra["v_BN_N"][0])
    text = verification_scene_text(scene, translation)
    simulation = build_simulation(parse_scenario(text, str(SCENES[scene])))
    extra = ["multibody.acs.attitude", "multibody.acs.angular_velocity", "multibody.acs.position"]
    if scene == "slosh_panels":
        extra += ["multibody.panel1.q", "multibody.panel2.q", "multibody.panel1.u", "multibody.panel2.u"]
    ours = _flexshell_result(simulation, duration, workdir, extra)
    if ours.t.shape != theirs.t.shape or np.abs(ours.t - theirs.t).max() > 1e-9:
        raise AssertionError(f"sample times differ: {ours.t[:3]}... against {theirs.t[:3]}...")
    tolerance = TOLERANCES[orbit]
    rows = []
    attitude = np.abs(_quaternion_to_dcm(ours.extra["multibody.acs.attitude"])
                      - _mrp_to_dcm(theirs.extra["sigma_BN"])).max()
    rows.append(("attitude, max |R_flexshell - R_Basilisk|", attitude, tolerance["attitude"]))
    omega_scale = np.abs(theirs.extra["omega_BN_B"]).max()
    rows.append(("body rate / max |omega|",
                 np.abs(ours.extra["multibody.acs.angular_velocity"] - theirs.extra["omega_BN_B"]).max()
                 / omega_scale, tolerance["rate"]))
    rows.append(("wheel speeds / max |Omega|", np.abs(ours.wheel_rpm - theirs.wheel_rpm).max()
                 / np.abs(theirs.wheel_rpm).max(), tolerance["wheels"]))
    position = np.abs(ours.extra["multibody.acs.position"] - theirs.extra["r_BN_N"]).max()
    rows.append(("hub position (m)", position, tolerance["position"]))
    if scene == "slosh_panels":
        theta = np.column_stack([ours.extra[f"multibody.panel{k}.q"][:, 0] for k in (1, 2)])
        theta_dot = np.column_stack([ours.extra[f"multibody.panel{k}.u"][:, 0] for k in (1, 2)])
        rows.append(("panel angles / max |theta|", np.abs(theta - theirs.extra["panel_theta"]).max()
                     / np.abs(theirs.extra["panel_theta"]).max(), tolerance["panels"]))
        rows.append(("panel rates / max |theta_dot|", np.abs(theta_dot - theirs.extra["panel_theta_dot"]).max()
                     / np.abs(theirs.extra["panel_theta_dot"]).max(), tolerance["panels"]))
    return rows, answers(ours, SETTLE_DEG[scene]), answers(theirs, SETTLE_DEG[scene])


# ------------------------------------------------------------------------------------------------
def load_average() -> str:
    return subprocess.run(["uptime"], capture_output=True, text=True).stdout.strip()


def race(scene: str, duration: float, pairs: int, workdir: Path):
    """Interleaved runs; returns (per-pair rows, flexshell answers, Basilisk answers)."""
    rows = []
    ours = theirs = None
    for pair in range(pairs):
        # alternate which simulator goes first so a drift in load favours neither
        order = ("flexshell", "basilisk") if pair % 2 == 0 else ("basilisk", "flexshell")
        for who in order:
            if who == "flexshell":
                ours = run_flexshell(scene, duration, workdir)
            else:
                theirs = run_basilisk(scene, duration)
        rows.append((ours.per_step_us, theirs.per_step_us, ours.steps, theirs.steps))
    return rows, answers(ours, SETTLE_DEG[scene]), answers(theirs, SETTLE_DEG[scene])


def print_answers(title: str, ours: dict, theirs: dict) -> None:
    print(f"\n{title}")
    print("| quantity | flexshell | Basilisk | difference / Basilisk |")
    print("| --- | ---: | ---: | ---: |")
    for key in ours:
        a, b = ours[key], theirs[key]
        if not (np.isfinite(a) and np.isfinite(b)):
            print(f"| {key} | {a:.4f} | {b:.4f} | (not reached within the run) |")
        else:
            print(f"| {key} | {a:.4f} | {b:.4f} | {(a - b) / abs(b):+.2e} |")


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenes", nargs="+", choices=sorted(SCENES), default=sorted(SCENES))
    parser.add_argument("--pairs", type=int, default=5, help="interleaved flexshell/Basilisk pairs per scene")
    parser.add_argument("--duration", type=float, default=600.0, help="simulated time per run (s)")
    parser.add_argument("--verify-duration", type=float, default=600.0, help="simulated time of the check (s)")
    mode = parser.add_mutually_exclusive_group()
    mode.add_argument("--no-verify", action="store_true", help="skip the same-law physics check")
    mode.add_argument("--verify-only", action="store_true", help="only the same-law physics check")
    args = parser.parse_args(argv)
    if args.pairs < 1 or args.duration <= 0.0:
        parser.error(f"expected --pairs >= 1 and --duration > 0, given {args.pairs} and {args.duration}")

    from threadpoolctl import threadpool_limits

    import Basilisk
    from Basilisk.utilities import simIncludeGravBody

    earth_mu = simIncludeGravBody.gravBodyFactory().createEarth().mu
    if earth_mu != 3.98600436e14:
        raise SystemExit(f"Basilisk's Earth mu is {earth_mu!r} m^3/s^2; configs/rw_attitude*.yaml use "
                         "3.98600436e14 (Basilisk 2.12): update the configs' gravity mu and initial states")
    failed = False
    with threadpool_limits(1), tempfile.TemporaryDirectory() as tmp:
        workdir = Path(tmp)
        print(f"Basilisk {Basilisk.__version__ if hasattr(Basilisk, '__version__') else ''}; "
              f"load before: {load_average()}")
        for scene in args.scenes:
            print(f"\n== {scene}: {SCENES[scene].relative_to(ROOT)}, RK4 {STEP * 1e3:g} ms, {args.duration:g} s")
            if not args.no_verify:
                for orbit in (True, False):
                    rows, ours, theirs = verify(scene, args.verify_duration, workdir, orbit)
                    print(f"same-law check (mrpFeedback's law in both, no gyro noise, {args.verify_duration:g} s, "
                          f"{'in orbit' if orbit else 'no gravity, center of mass at rest'}):")
                    for name, value, tolerance in rows:
                        ok = value <= tolerance
                        failed |= not ok
                        print(f"  {name:42s} {value:10.2e}  (tolerance {tolerance:.0e}) {'ok' if ok else 'FAILED'}")
                    if orbit:
                        print_answers("closed-loop answers of the same-law check (in orbit):", ours, theirs)
            if args.verify_only:
                continue
            run_flexshell(scene, 1.0, workdir)        # load the numba cache before timing
            run_basilisk(scene, 1.0)
            rows, ours, theirs = race(scene, args.duration, args.pairs, workdir)
            print(f"\nrace ({args.pairs} interleaved pairs, the scenes as written: PD on quaternions against "
                  "mrpFeedback, gyro noise on):")
            print("| pair | flexshell (us/step) | Basilisk (us/step) | flexshell / Basilisk |")
            print("| ---: | ---: | ---: | ---: |")
            for k, (a, b, na, nb) in enumerate(rows):
                if na != nb:
                    raise AssertionError(f"step counts differ: flexshell {na}, Basilisk {nb}")
                print(f"| {k + 1} | {a:.1f} | {b:.1f} | {a / b:.1f} |")
            ratios = [a / b for a, b, _, _ in rows]
            print(f"| median | {np.median([r[0] for r in rows]):.1f} | {np.median([r[1] for r in rows]):.1f} | "
                  f"{np.median(ratios):.1f} |")
            print_answers("closed-loop answers of the race (last pair):", ours, theirs)
        print(f"\nload after: {load_average()}")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
