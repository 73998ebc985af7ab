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
