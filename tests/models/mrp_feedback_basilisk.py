"""The same closed loop in Basilisk and in flexshell, in one process: Basilisk's
scenarioAttitudeFeedback (a rigid spacecraft, ``extForceTorque`` applying ``mrpFeedback``'s torque,
``inertial3D`` or ``inertial3DSpin`` reference, ``attTrackingError``, ``simpleNav``) against the YAML
scene ``SCENE`` (``MrpFeedback`` on the node's true attitude and rate).

Same numbers on both sides: inertia, initial MRP and rate, gains, RK4 at ``STEP``, control at
``CONTROL_PERIOD``. Timing: Basilisk's dynamics task runs first at instants shared with the flight
software task (the control law reads the state at t_k), and ``extForceTorque`` reads the command
before the hub integrates, so the torque computed at t_k acts over [t_k, t_k + T], flexshell's
zero-order hold. Basilisk's mrpFeedback takes dt = 0 at its first call and at any call that follows a
call at t = 0 (its ``priorTime`` 0 means "none yet"), so with the integral term the flight software
starts at ``offset`` > 0 on both sides. Used by ``tests/models/test_mrp_feedback.py`` (``-m slow``: needs bsk).

``run_basilisk_rw`` / ``scene_text_rw``: the same with reaction wheels (Basilisk's
scenarioAttitudeFeedbackRW: ``reactionWheelStateEffector`` with three balanced HR16 wheels, ``rwMotorTorque``,
``mrpFeedback`` reading the wheel speeds) against ``ReactionWheel`` x 3, ``PseudoInverseAllocator`` and the
wheels' ``spin_momentum`` summed into ``MrpFeedback.wheel_momentum``.
"""

from __future__ import annotations

import textwrap

import numpy as np

STEP = 0.01
CONTROL_PERIOD = 0.1
INERTIA = np.array([[900.0, 15.0, -10.0], [15.0, 800.0, 20.0], [-10.0, 20.0, 600.0]])
SIGMA_BN = np.array([0.1, 0.2, -0.3])
OMEGA_BN_B = np.array([0.001, -0.01, 0.03])
DISTURBANCE = np.array([0.05, -0.03, 0.02])     # N m, body axes (extForceTorque's extTorquePntB_B)


def mrp_to_quaternion(sigma):
    s2 = float(np.dot(sigma, sigma))
    return np.r_[(1.0 - s2) / (1.0 + s2), 2.0 * np.asarray(sigma) / (1.0 + s2)]


def run_basilisk(duration, k, p, ki=-1.0, integral_limit=0.0, disturbance=True, offset=0.0):
    """Basilisk's scenarioAttitudeFeedback, the flight software's first call at ``offset``.
    Returns (t, sigma_BN, omega_BN_B, torque command) at the control period."""
    from Basilisk.architecture import messaging
    from Basilisk.fswAlgorithms import attTrackingError, inertial3D, mrpFeedback
    from Basilisk.simulation import extForceTorque, simpleNav, spacecraft
    from Basilisk.utilities import SimulationBaseClass, macros

    sim = SimulationBaseClass.SimBaseClass()
    process = sim.CreateNewProcess("process")
    process.addTask(sim.CreateNewTask("dynamics", macros.sec2nano(STEP)), 200)
    process.addTask(sim.CreateNewTask("fsw", macros.sec2nano(CONTROL_PERIOD), FirstStart=macros.sec2nano(offset)),
                    100)
    sc = spacecraft.Spacecraft()
    sc.ModelTag = "sc"
    sc.hub.mHub = 750.0
    sc.hub.r_BcB_B = [[0.0], [0.0], [0.0]]
    sc.hub.IHubPntBc_B = INERTIA.tolist()
    sc.hub.sigma_BNInit = [[v] for v in SIGMA_BN]
    sc.hub.omega_BN_BInit = [[v] for v in OMEGA_BN_B]
    ext = extForceTorque.ExtForceTorque()
    ext.ModelTag = "ext"
    if disturbance:
        ext.extTorquePntB_B = [[v] for v in DISTURBANCE]
    sc.addDynamicEffector(ext)
    sim.AddModelToTask("dynamics", ext, None, 2)     # reads the command before the hub integrates
    sim.AddModelToTask("dynamics", sc, None, 1)
    nav = simpleNav.SimpleNav()
    nav.scStateInMsg.subscribeTo(sc.scStateOutMsg)
    reference = inertial3D.inertial3D()
    reference.sigma_R0N = [0.0, 0.0, 0.0]
    tracking = attTrackingError.attTrackingError()
    tracking.attNavInMsg.subscribeTo(nav.attOutMsg)
    tracking.attRefInMsg.subscribeTo(reference.attRefOutMsg)
    control = mrpFeedback.mrpFeedback()
    control.K, control.P, control.Ki, control.integralLimit = k, p, ki, integral_limit
    control.guidInMsg.subscribeTo(tracking.attGuidOutMsg)
    vehicle = messaging.VehicleConfigMsgPayload()
    vehicle.ISCPntB_B = INERTIA.flatten().tolist()
    vehicle_msg = messaging.VehicleConfigMsg().write(vehicle)
    control.vehConfigInMsg.subscribeTo(vehicle_msg)
    ext.cmdTorqueInMsg.subscribeTo(control.cmdTorqueOutMsg)
    for priority, module in enumerate((nav, reference, tracking, control)):
        sim.AddModelToTask("fsw", module, None, 100 - priority)
    state_log = sc.scStateOutMsg.recorder(macros.sec2nano(CONTROL_PERIOD))
    torque_log = control.cmdTorqueOutMsg.recorder(macros.sec2nano(CONTROL_PERIOD))
    sim.AddModelToTask("dynamics", state_log, None, 0)      # the state at t_k, every control period
    sim.AddModelToTask("fsw", torque_log)
    sim.keep_alive = [sc, ext, nav, reference, tracking, control, vehicle_msg, state_log, torque_log]
    sim.InitializeSimulation()
    sim.ConfigureStopTime(macros.sec2nano(duration))
    sim.ExecuteSimulation()
    return (state_log.times() * 1e-9, np.asarray(state_log.sigma_BN), np.asarray(state_log.omega_BN_B),
            np.asarray(torque_log.torqueRequestBody))


def scene_text(duration, k, p, ki=0.0, integral_limit=1e300, disturbance=True, offset=0.0):
    """The flexshell scene of the same loop (YAML, as a user writes it)."""
    q0 = mrp_to_quaternion(SIGMA_BN)
    inertia = INERTIA.tolist()
    torque_sum = ""
    if disturbance:
        torque_sum = f"""
          disturbance: {{type: Constant, config: {{unit: N*m, shape: [3]}}, parameters: {{value: "{DISTURBANCE.tolist()} N*m"}}}}
          total: {{type: NodeLoadSum, config: {{count: 2}}}}"""
        sink = "total.torque_0\n          - disturbance.y -> total.torque_1\n          - total.torque -> multibody.bus.torque"
    else:
        sink = "multibody.bus.torque"
    return textwrap.dedent(f"""
        name: mrp_feedback_vs_basilisk
        multibody:
          gravity: "[0, 0, 0] m/s^2"
          bodies:
            - name: hub
              hinge: free
              mass: 750 kg
              inertia: "{inertia} kg*m^2"
              initial:
                attitude: {q0.tolist()}
                angular_velocity: "{OMEGA_BN_B.tolist()} rad/s"
          nodes:
            - {{name: bus, body: hub}}
        models:
          controller:
            type: MrpFeedback
            rate: {1.0 / CONTROL_PERIOD:g} Hz
            offset: {offset} s
            parameters: {{k: {k} N*m, p: {p} N*m*s/rad, ki: {max(ki, 0.0)} rad/(N*m*s^2),
                         integral_limit: {integral_limit} N*m*s, inertia: "{inertia} kg*m^2"}}{torque_sum}
        connections:
          - multibody.bus.attitude -> controller.attitude
          - multibody.bus.angular_velocity -> controller.angular_velocity
          - controller.torque -> {sink}
        integrator: {{method: rk4, step: {STEP} s}}
        stop: {{time: {duration} s}}
        log:
          rate: {1.0 / CONTROL_PERIOD:g} Hz
          signals: [multibody.bus.attitude, multibody.bus.angular_velocity, controller.torque]
        """)


AXES = np.eye(3)
SPEEDS_RPM = np.array([100.0, 200.0, 300.0])

def run_basilisk_rw(duration, k, p, law_type=1):
    """Basilisk's scenarioAttitudeFeedbackRW: three Honeywell HR16 wheels (balanced, on the body axes, at
    100, 200, 300 rpm) driven through rwMotorTorque by mrpFeedback, which reads the wheel speeds. Returns
    (t, sigma_BN, omega_BN_B, wheel speeds, Js, u_max) at the control period."""
    from Basilisk.architecture import messaging
    from Basilisk.fswAlgorithms import attTrackingError, inertial3D, mrpFeedback, rwMotorTorque
    from Basilisk.simulation import reactionWheelStateEffector, simpleNav, spacecraft
    from Basilisk.utilities import SimulationBaseClass, macros, simIncludeRW
    sim = SimulationBaseClass.SimBaseClass()
    proc = sim.CreateNewProcess("process")
    proc.addTask(sim.CreateNewTask("dynamics", macros.sec2nano(STEP)), 200)
    proc.addTask(sim.CreateNewTask("fsw", macros.sec2nano(CONTROL_PERIOD)), 100)
    sc = spacecraft.Spacecraft()
    sc.ModelTag = "sc"
    sc.hub.mHub = 750.0
    sc.hub.IHubPntBc_B = INERTIA.tolist()
    sc.hub.sigma_BNInit = [[v] for v in SIGMA_BN]
    sc.hub.omega_BN_BInit = [[v] for v in OMEGA_BN_B]
    factory = simIncludeRW.rwFactory()
    wheels = [factory.create("Honeywell_HR16", AXES[i].tolist(), maxMomentum=50.0, Omega=float(SPEEDS_RPM[i]))
              for i in range(3)]
    rw = reactionWheelStateEffector.ReactionWheelStateEffector()
    rw.ModelTag = "rw"
    factory.addToSpacecraft("rw", rw, sc)
    sim.AddModelToTask("dynamics", rw, None, 2)
    sim.AddModelToTask("dynamics", sc, None, 1)
    nav = simpleNav.SimpleNav()
    nav.scStateInMsg.subscribeTo(sc.scStateOutMsg)
    ref = inertial3D.inertial3D()
    ref.sigma_R0N = [0.0, 0.0, 0.0]
    track = attTrackingError.attTrackingError()
    track.attNavInMsg.subscribeTo(nav.attOutMsg)
    track.attRefInMsg.subscribeTo(ref.attRefOutMsg)
    rw_params = factory.getConfigMessage()
    ctrl = mrpFeedback.mrpFeedback()
    ctrl.K, ctrl.P, ctrl.Ki, ctrl.integralLimit = k, p, -1.0, 0.0
    ctrl.controlLawType = law_type     # 1: omega_BN x (I omega + h_s), which reads the wheels at a rest reference
    ctrl.guidInMsg.subscribeTo(track.attGuidOutMsg)
    veh = messaging.VehicleConfigMsgPayload()
    veh.ISCPntB_B = INERTIA.flatten().tolist()
    veh_msg = messaging.VehicleConfigMsg().write(veh)
    ctrl.vehConfigInMsg.subscribeTo(veh_msg)
    ctrl.rwParamsInMsg.subscribeTo(rw_params)
    ctrl.rwSpeedsInMsg.subscribeTo(rw.rwSpeedOutMsg)
    motor = rwMotorTorque.rwMotorTorque()
    motor.controlAxes_B = [1, 0, 0, 0, 1, 0, 0, 0, 1]
    motor.vehControlInMsg.subscribeTo(ctrl.cmdTorqueOutMsg)
    motor.rwParamsInMsg.subscribeTo(rw_params)
    rw.rwMotorCmdInMsg.subscribeTo(motor.rwMotorTorqueOutMsg)
    for pr, m in enumerate((nav, ref, track, ctrl, motor)):
        sim.AddModelToTask("fsw", m, None, 100 - pr)
    st = sc.scStateOutMsg.recorder(macros.sec2nano(CONTROL_PERIOD))
    sp = rw.rwSpeedOutMsg.recorder(macros.sec2nano(CONTROL_PERIOD))
    sim.AddModelToTask("dynamics", st, None, 0)
    sim.AddModelToTask("dynamics", sp, None, 0)
    sim.keep = [sc, rw, nav, ref, track, ctrl, motor, veh_msg, rw_params, st, sp, wheels, factory]
    sim.InitializeSimulation()
    sim.ConfigureStopTime(macros.sec2nano(duration))
    sim.ExecuteSimulation()
    return (st.times() * 1e-9, np.asarray(st.sigma_BN), np.asarray(st.omega_BN_B), np.asarray(sp.wheelSpeeds)[:, :3],
            np.array([w.Js for w in wheels]), np.array([w.u_max for w in wheels]))


def scene_text_rw(duration, k, p, js, umax, wheel_momentum=True, law_type=1):
    """The same loop in flexshell: ReactionWheel (momentum representation: the bus inertia is Basilisk's hub
    inertia without the wheels' spin inertia Js a a^T, which Basilisk's balanced wheels take out of it),
    a pseudo-inverse allocation of -torque, and the wheels' spin momenta summed into MrpFeedback."""
    q0 = mrp_to_quaternion(SIGMA_BN)
    bus = (INERTIA - sum(j * np.outer(a, a) for j, a in zip(js, AXES))).tolist()
    wheels = "\n".join(
        f"  rw{i + 1}: {{type: ReactionWheel, attach: {{node: rw{i + 1}}}, "
        f"parameters: {{spin_axis: {AXES[i].tolist()}, "
        f"spin_inertia: {float(js[i])!r} kg*m^2, max_torque: {float(umax[i])!r} N*m, max_speed: 1e9 rad/s}}, "
        f"initial: {{momentum: {float(js[i] * (AXES[i] @ OMEGA_BN_B + SPEEDS_RPM[i] * np.pi / 30))!r} N*m*s}}}}"
        for i in range(3))
    momentum_line = "  - wheel_momentum.y -> controller.wheel_momentum\n" if wheel_momentum else ""
    return f"""
name: mrp_feedback_rw_vs_basilisk
multibody:
  gravity: "[0, 0, 0] m/s^2"
  bodies:
    - name: hub
      hinge: free
      mass: 750 kg
      inertia: "{bus} kg*m^2"
      initial: {{attitude: {q0.tolist()}, angular_velocity: "{OMEGA_BN_B.tolist()} rad/s"}}
  nodes:
    - {{name: bus, body: hub}}
    - {{name: rw1, body: hub}}
    - {{name: rw2, body: hub}}
    - {{name: rw3, body: hub}}
models:
  controller:
    type: MrpFeedback
    rate: {1 / CONTROL_PERIOD:g} Hz
    parameters: {{k: {k} N*m, p: {p} N*m*s/rad, inertia: "{INERTIA.tolist()} kg*m^2", control_law_type: {law_type}}}
  allocator:
    type: PseudoInverseAllocator
    config: {{demand: 3, actuators: 3}}
    parameters: {{effectiveness: "[[-1, 0, 0], [0, -1, 0], [0, 0, -1]]"}}
{wheels}
  wheel_momentum: {{type: Sum, config: {{count: 3, unit: N*m*s, shape: [3]}}}}
connections:
  - multibody.bus.attitude -> controller.attitude
  - multibody.bus.angular_velocity -> controller.angular_velocity
  - controller.torque -> allocator.demand
  - allocator.command_1 -> rw1.torque_command
  - allocator.command_2 -> rw2.torque_command
  - allocator.command_3 -> rw3.torque_command
  - rw1.spin_momentum -> wheel_momentum.u_1
  - rw2.spin_momentum -> wheel_momentum.u_2
  - rw3.spin_momentum -> wheel_momentum.u_3
{momentum_line}integrator: {{method: rk4, step: {STEP} s}}
stop: {{time: {duration} s}}
log:
  rate: {1 / CONTROL_PERIOD:g} Hz
  signals: [multibody.bus.attitude, multibody.bus.angular_velocity, rw1.wheel_speed, rw2.wheel_speed,
            rw3.wheel_speed, controller.torque]
"""
