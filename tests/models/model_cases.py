"""Every built-in model (except the engine), constructed once per configuration that changes its kernels
or layouts, and a harness that calls all of a model's kernels on values placed *by name*.

``kernel_results(model, case, draw)`` fills p, u, x, z declaration by declaration with values that depend
only on (case, draw, array, declaration name), calls every kernel (outputs, derivatives, zero crossings,
three updates with the same standard normals for a model with ``noise_size``), and returns the results
keyed by declaration name. Two models whose kernels read their arrays correctly give bit-identical
results whatever the order of their declarations.
"""

from __future__ import annotations

import hashlib

import numpy as np

#: parameters set to zero in draw 1 so that the branches they switch (no lag, no quantization, no
#: gravity-gradient torque, flat world, no J3/J4, no command limit) run too
SWITCHES = {"rise_time", "fall_time", "gyro_lsb", "accel_lsb", "gravity_gradient", "planet_radius", "j3", "j4",
            "max_command"}
DRAWS = (0, 1)


def hold_inputs(t, signals):
    """A user function for UserFunction cases: outputs from the inputs and the time."""
    return {"b": signals["a"][:2] * t, "c": float(signals["a"].sum())}


def cases(tmp_path):
    """(case name, module, class name, construction keyword arguments) of every built-in model."""
    gain = tmp_path / "gain.npy"
    np.save(gain, np.arange(6.0).reshape(2, 3) + 0.5)
    rng = np.random.default_rng(3)
    thrusters = np.cross(rng.normal(size=(8, 3)), rng.normal(size=(8, 3))).T
    jets = np.c_[thrusters, -thrusters]  # +-pairs: a strictly positive null vector exists
    return [
        ("aero", "aerodynamics", "Aerodynamics", dict(reference_area=2.0, normal_force_slope=3.0)),
        ("aero_msis", "aerodynamics", "Aerodynamics",
         dict(atmosphere="nrlmsis", epoch_julian_date=2460755.0, latitude=28.5, longitude=-80.6, reference_area=2.0,
              normal_force_slope=3.0, log_density=np.linspace(0.2, -35.0, 4001))),
        ("pinv", "allocation", "PseudoInverseAllocator",
         dict(demand=3, actuators=4, effectiveness=rng.normal(size=(3, 4)))),
        ("loads", "allocation", "NodeLoadSum", dict(count=3)),
        ("nonnegative", "allocation", "NonnegativeAllocator",
         dict(demand=3, actuators=16, effectiveness=jets, max_command=0.7)),
        ("constant", "blocks", "Constant", dict(shape=(3,), value=[1.0, 2.0, 3.0])),
        ("gain", "blocks", "Gain", dict(shape=(2, 2))),
        ("sum", "blocks", "Sum", dict(count=3, shape=(2,))),
        ("integrator", "blocks", "Integrator", dict(shape=(3,))),
        ("hold", "blocks", "SampleHold", dict(shape=(3,), period=0.1)),
        ("noisy", "blocks", "NoisySampler", dict(shape=(3,), period=0.1, sigma=0.3)),
        ("profile", "blocks", "Profile", dict(shape=(2,), segments=2, times=[0.0, 0.4, 1.5])),
        ("lqr", "controllers", "LqrStateFeedback", dict(gain_file=str(gain))),
        ("pid", "controllers", "PidAttitudeController", dict(period=0.1)),
        ("gimbal_prescribed", "gimbaled_engine", "GimbalActuator", dict(mode="prescribed")),
        ("gimbal_torque", "gimbaled_engine", "GimbalActuator", dict(mode="torque")),
        ("gravity", "gravity", "CentralBodyGravity", dict(mass=10.0, inertia=np.diag([1.0, 2.0, 3.0]) + 0.1)),
        ("imu", "imu", "Imu", dict(period=0.01, latency=0.02)),
        ("mass", "mass_depletion", "MassDepletion",
         dict(body="b", full_mass=10.0, empty_mass=4.0, full_inertia=np.eye(3), empty_inertia=0.5 * np.eye(3))),
        ("pd", "pd_attitude", "PdAttitudeController", dict(period=0.1)),
        ("mrp", "mrp_feedback", "MrpFeedback", dict(period=0.1, ki=0.01, inertia=np.diag([1.0, 2.0, 3.0]) + 0.1)),
        ("mrp_law1", "mrp_feedback", "MrpFeedback", dict(period=0.1, control_law_type=1)),
        ("inertial", "guidance", "InertialPointing", dict(target={"axis": [0, 0, 1], "angle": "30 deg"})),
        ("nadir", "guidance", "NadirPointing", {}),
        ("sun", "guidance", "SunPointing", {}),
        ("slew", "guidance", "EigenaxisSlew",
         dict(period=0.1, max_rate=0.02, max_acceleration=0.002, target={"euler": [0.3, 0.2, 0.1], "sequence": "ZYX"})),
        ("cmgs", "cmg", "CmgCluster", dict(wheel_momentum=2.0)),
        ("cmg_steering", "cmg", "CmgSteering", dict(period=0.1, wheel_momentum=2.0)),
        ("modes", "mode_manager", "AttitudeModeManager", dict(period=1.0, rate_threshold=0.01, pointing_threshold=0.02)),
        ("mekf", "mekf", "AttitudeMekf",
         dict(period=0.1, gyro_random_walk=1e-5, gyro_bias_random_walk=1e-7, star_tracker_noise=[1e-5, 2e-5, 5e-5])),
        ("wheel", "reaction_wheel", "ReactionWheel", dict(spin_inertia=0.01)),
        ("motor", "reaction_wheel", "ReactionWheelMotor", {}),
        ("slosh", "slosh", "SloshSpringDamper", dict(dofs=2)),
        ("slosh_translational", "slosh", "SloshSpringDamper", dict(dofs=1, kind="translational")),
        ("jet_pwm", "thruster", "Thruster", dict(mode="pwm", max_thrust=2.0, isp=200.0)),
        ("jet_on_off", "thruster", "Thruster", dict(mode="on_off", max_thrust=2.0, isp=200.0)),
        ("jet_proportional", "thruster", "Thruster", dict(mode="proportional", max_thrust=2.0, isp=200.0)),
        ("ephemeris", "ephemeris", "SunMoonEphemeris", dict(epoch="2025-03-20T12:00:00")),
        ("eclipse_conical", "eclipse", "Eclipse", {}),
        ("eclipse_cylindrical", "eclipse", "Eclipse", dict(shadow="cylindrical")),
        ("srp", "srp", "SolarRadiationPressure", dict(plates=3)),
        ("igrf", "magnetic", "MagneticField", dict(epoch="2025-03-20T12:00:00", degree=13)),
        ("magnetometer", "magnetic", "Magnetometer", dict(period=0.1, lsb=1e-8, range=6e-5)),
        ("torquer", "magnetic", "Magnetorquer", dict(lsb=0.01)),
        ("bdot", "magnetic_control", "BDot", dict(period=1.0)),
        ("dumping", "magnetic_control", "MomentumDumping", dict(period=1.0)),
        ("tracker", "star_tracker", "StarTracker", dict(period=0.2, latency=0.4, sun_exclusion=0.5)),
        ("css", "sun_sensors", "CoarseSunSensors", dict(sensors=4, period=0.1, albedo=0.3)),
        ("sun_estimate", "sun_sensors", "SunDirectionEstimate",
         dict(sensors=4, normal=[[1, 0, 0], [0, 1, 0], [0, 0, 1], [0.6, 0.8, 0]])),
        ("sun_safe", "guidance", "SunSafePointing", dict(boresight=[0.0, 0.6, 0.8])),
        ("drag", "atmosphere", "AtmosphericDrag", dict(area=1.0, log_density=np.full((181, 19, 25), -20.0))),
        ("third_body", "third_body", "ThirdBodyGravity", dict(mass=10.0)),
        ("user", "user_hook", "UserFunction",
         dict(function="tests.models.model_cases:hold_inputs", inputs={"a": {"shape": [3]}},
              outputs={"b": {"shape": [2]}, "c": {}}, period=0.1)),
    ]


def _values(case, draw, kind, name, size):
    seed = int.from_bytes(hashlib.sha256(f"{case}/{draw}/{kind}/{name}".encode()).digest()[:8], "little")
    return np.random.default_rng(seed).uniform(0.5, 1.5, size)


def _fill(layout, case, draw, kind):
    array = np.empty(layout.size)
    for name in layout.names:
        sl = layout.slice(name)
        array[sl] = _values(case, draw, kind, name, sl.stop - sl.start)
    return array


def _by_name(layout, array):
    return {name: array[layout.slice(name)].copy() for name in layout.names}


def kernel_results(model, case, draw):
    """Results of every kernel of ``model`` on values placed by name, keyed by declaration name."""
    m = model
    if m.python_update:  # a Python update reads its parameters by name: keep the real values
        p = m.p.copy()
    else:
        p = _fill(m.p_layout, case, draw, "p")
        if draw == 1:
            for name in SWITCHES & set(m.p_layout.names):
                p[m.p_layout.slice(name)] = 0.0
    u = _fill(m.u_layout, case, draw, "u")
    x = _fill(m.x_layout, case, draw, "x")
    z = _fill(m.z_layout, case, draw, "z")
    if "cycle" in m.z_layout.names:  # a thruster's mode code and cycle period are configuration
        z[m.z_layout.slice("cycle")] = m.initial_discrete_state()[m.z_layout.slice("cycle")]
    t = 0.73
    out = {}
    for kernel in ("state_outputs", "feedthrough_outputs"):
        fn = getattr(m, kernel)
        if fn is not None:
            y = np.full(m.y_layout.size, np.nan)
            fn(t, x, z, u, p, y)
            written = [o.name for o in m.outputs if o.feedthrough == (kernel == "feedthrough_outputs")]
            unwritten = [name for name in written if np.isnan(y[m.y_layout.slice(name)]).any()]
            assert not unwritten, f"{case}: {kernel} left outputs {unwritten} unwritten"
            out[kernel] = {name: y[m.y_layout.slice(name)] for name in written}
    if m.derivatives is not None:
        xdot = np.full(m.x_layout.size, np.nan)
        m.derivatives(t, x, z, u, p, xdot)
        assert not np.isnan(xdot).any(), f"{case}: derivatives left {xdot} unwritten"
        out["derivatives"] = _by_name(m.x_layout, xdot)
    if m.zero_crossing_values is not None:
        g = np.full(len(m.zero_crossings), np.nan)
        m.zero_crossing_values(t, x, z, u, p, g)
        out["zero_crossings"] = {c.name: g[k] for k, c in enumerate(m.zero_crossings)}
    if m.update is not None and type(m).__name__ != "MassDepletion":  # that one needs an engine
        normals = np.random.default_rng(7)
        for k in range(3):
            if m.noise_size:
                noise = np.empty(m.noise_size)
                normals.standard_normal(out=noise)
                m.update(t + k, x, z, u, p, noise)
            else:
                m.update(t + k, x, z, u, p)
            out[f"update_{k}"] = _by_name(m.z_layout, z)
    out["initial_discrete_state"] = _by_name(m.z_layout, m.initial_discrete_state())
    out["initial_continuous_state"] = _by_name(m.x_layout, m.initial_continuous_state())
    return out


def assert_identical(first, second, where):
    """Bit-for-bit equality of two kernel_results."""
    assert first.keys() == second.keys(), where
    for kernel, values in first.items():
        assert values.keys() == second[kernel].keys(), f"{where} {kernel}"
        for name, value in values.items():
            a, b = np.asarray(value), np.asarray(second[kernel][name])
            assert a.shape == b.shape and a.tobytes() == b.tobytes(), f"{where} {kernel} {name}: {a} != {b}"
