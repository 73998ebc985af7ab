"""Independent reference for the launch-vehicle gimbaled-engine case (TM-2020-5008164 App. F, the
"complex test case": 1695 kg airframe, 50 kg engine with its CG 1 m aft of the gimbal and 10 cm /
20 cm lateral offsets, large products of inertia, 1000 N thrust), rigid airframe.

Derived with SymPy in coordinates chosen independently of the engine's: airframe attitude by 3-2-1
Euler angles (psi, theta, phi), airframe CG position p (world), gimbal angles (d1 about the airframe's
y axis, then d2 about the rotated z axis). Kinetic energy T = 1/2 qdot' M(q) qdot with
M = sum m Jv' Jv + Jw' R I R' Jw (Jv, Jw the symbolic Jacobians of each CG position and of the angular
velocity, [w x] = Rdot R'); generalized forces Q from the virtual work of the thrust (along the
engine's +x axis at the gimbal) and the gimbal torque.

Kane's equations in the generalized speeds u = (airframe angular velocity and velocity in airframe
axes, gimbal rates) -- the engine's speeds, which matter because the thrust cases are linearized
about a state that accelerates, where the Jacobian depends on the choice of speeds (not of
coordinates) -- with qdot = W(q) u read W' M W udot + (velocity-quadratic terms) = W' Q. About a
state at rest the velocity-quadratic terms drop out of the linearization exactly, so

    udot = Mk(q)^-1 Qk(q, tau),   d udot / dq_j = Mk^-1 (dQk/dq_j - dMk/dq_j udot0),   Mk = W'MW, Qk = W'Q

with the derivatives in q taken by complex steps on the lambdified SymPy expressions
(d f / dq_j = Im f(q0 + i h e_j) / h, h = 1e-30: exact to round-off, no differencing). Outputs at
the sensor point r_s of the airframe: angular velocity in airframe axes (the first three speeds) and
classical acceleration in airframe axes (R_b' J_s W udot, no gravity). Prescribed gimbal motion
(TM App. F: load-torque feedback open): the gimbal accelerations are the input, the remaining rows
M_ff udot_f = Q_f - M_fp d'' give the rest.

The geometry of TM Fig. F.6.1 (sensor and gimbal positions, airframe inertia) is not in the text;
the values here are representative, with the TM's stated masses, offsets and thrust.
"""

from __future__ import annotations

import functools

import numpy as np
import sympy as sp

AIRFRAME_MASS = 1695.0
AIRFRAME_INERTIA = np.array([[620.0, 25.0, -18.0], [25.0, 2450.0, 35.0], [-18.0, 35.0, 2480.0]])  # about its CG
GIMBAL = np.array([-3.2, 0.05, -0.04])   # from the airframe CG (the body origin), airframe axes
SENSOR = np.array([1.6, 0.12, 0.07])
ENGINE_MASS = 50.0
ENGINE_CG = np.array([-1.0, 0.10, 0.20])  # from the gimbal, engine axes: 1 m aft, 10 cm / 20 cm offsets
ENGINE_INERTIA = np.array([[4.0, 1.1, -0.8], [1.1, 6.5, 0.9], [-0.8, 0.9, 6.0]])  # about its CG, large products
THRUST = 1000.0


def _rx(a):
    return sp.Matrix([[1, 0, 0], [0, sp.cos(a), -sp.sin(a)], [0, sp.sin(a), sp.cos(a)]])


def _ry(a):
    return sp.Matrix([[sp.cos(a), 0, sp.sin(a)], [0, 1, 0], [-sp.sin(a), 0, sp.cos(a)]])


def _rz(a):
    return sp.Matrix([[sp.cos(a), -sp.sin(a), 0], [sp.sin(a), sp.cos(a), 0], [0, 0, 1]])


def _vee(S):
    return sp.Matrix([S[2, 1], S[0, 2], S[1, 0]])


@functools.lru_cache(maxsize=1)
def _symbolic_model():
    """Lambdified M(q), Q(q, thrust), Euler-rate map, R_b(q) and R_b' J_sensor(q) (built once)."""
    q = sp.symbols("psi theta phi x y z d1 d2")
    psi, theta, phi, x, y, z, d1, d2 = q
    Rb = _rz(psi) * _ry(theta) * _rx(phi)
    Re = Rb * _ry(d1) * _rz(d2)
    p = sp.Matrix([x, y, z])
    gimbal = p + Rb * sp.Matrix(GIMBAL)
    engine_cg = gimbal + Re * sp.Matrix(ENGINE_CG)
    sensor = p + Rb * sp.Matrix(SENSOR)

    def jw(R):
        return sp.Matrix.hstack(*[_vee(R.diff(qj) * R.T) for qj in q])

    bodies = ((AIRFRAME_MASS, AIRFRAME_INERTIA, p, Rb), (ENGINE_MASS, ENGINE_INERTIA, engine_cg, Re))
    M = sp.zeros(8, 8)
    for mass, inertia, cg, R in bodies:
        Jv = cg.jacobian(q)
        Jw = jw(R)
        M += mass * Jv.T * Jv + Jw.T * (R * sp.Matrix(inertia) * R.T) * Jw
    thrust_symbol = sp.Symbol("thrust")
    Q = gimbal.jacobian(q).T * (Re * sp.Matrix([thrust_symbol, 0, 0]))
    euler_rates_to_body_rate = (Rb.T * jw(Rb))[:, 0:3]
    f_M = sp.lambdify([q], M, "numpy")
    f_Q = sp.lambdify([q, thrust_symbol], Q, "numpy")
    f_E = sp.lambdify([q], euler_rates_to_body_rate, "numpy")
    f_R = sp.lambdify([q], Rb, "numpy")
    f_S = sp.lambdify([q], Rb.T * sensor.jacobian(q), "numpy")

    return f_M, f_Q, f_E, f_R, f_S


def reference_state_space(thrust: float, prescribed: bool):
    """(A, B, C, D) in (q, u) for the pitch-gimbal input (torque, or prescribed acceleration) and
    outputs [sensor angular velocity (3); sensor acceleration (3)], about the relaxed state at rest."""
    f_M, f_Q, f_E, f_R, f_S = _symbolic_model()

    def W(qv):
        """qdot = W(q) u for the generalized speeds u = (w_body, v_body, d1', d2') of the engine."""
        out = np.zeros((8, 8), dtype=qv.dtype)
        out[0:3, 0:3] = np.linalg.inv(np.array(f_E(qv), dtype=qv.dtype))
        out[3:6, 3:6] = np.array(f_R(qv), dtype=qv.dtype)
        out[6, 6] = out[7, 7] = 1.0
        return out

    def mass_matrix(qv):    # Kane: W' M W
        Wq = W(qv)
        return Wq.T @ np.array(f_M(qv), dtype=qv.dtype) @ Wq

    def forces(qv):         # W' Q
        return W(qv).T @ np.array(f_Q(qv, thrust), dtype=qv.dtype).reshape(-1)

    def sensor_accel_map(qv):  # a_body = R_b' J_s W udot (+ velocity-quadratic terms)
        return np.array(f_S(qv), dtype=qv.dtype) @ W(qv)

    h = 1e-30

    def value_and_derivatives(f):
        value = np.real(f(np.zeros(8, dtype=complex)))
        derivatives = []
        for j in range(8):
            step = np.zeros(8, dtype=complex)
            step[j] = 1j * h
            derivatives.append(np.imag(f(step)) / h)
        return value, derivatives

    M0, dM = value_and_derivatives(mass_matrix)
    Q0, dQ = value_and_derivatives(forces)
    G0, dG = value_and_derivatives(sensor_accel_map)
    free = [0, 1, 2, 3, 4, 5] + ([] if prescribed else [6, 7])
    pinned = [] if not prescribed else [6, 7]
    Mff = M0[np.ix_(free, free)]
    udot0 = np.zeros(8)  # prescribed gimbal accelerations are zero at the operating point
    udot0[free] = np.linalg.solve(Mff, Q0[free])
    dudot = np.zeros((8, 8))
    for j in range(8):
        dudot[free, j] = np.linalg.solve(Mff, (dQ[j] - dM[j] @ udot0)[free])
    dudot_du = np.zeros(8)
    if prescribed:  # input d1'': M_ff udot_f = Q_f - M_fp d''
        dudot_du[6] = 1.0
        dudot_du[free] = np.linalg.solve(Mff, -M0[np.ix_(free, pinned)] @ np.array([1.0, 0.0]))
    else:  # input: gimbal torque, the generalized force of d1
        torque = np.zeros(8)
        torque[6] = 1.0
        dudot_du[free] = np.linalg.solve(Mff, torque[free])
    A = np.block([[np.zeros((8, 8)), W(np.zeros(8))], [dudot, np.zeros((8, 8))]])
    B = np.concatenate([np.zeros(8), dudot_du]).reshape(16, 1)
    C = np.zeros((6, 16))
    C[0:3, 8:11] = np.eye(3)  # sensor angular velocity = airframe body rate
    for j in range(8):
        C[3:6, j] = dG[j] @ udot0 + G0 @ dudot[:, j]
    D = np.zeros((6, 1))
    D[3:6, 0] = G0 @ dudot_du
    return A, B, C, D


def _skew(v):
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


def _grid_jacobian(body, row, nu):
    """[omega; v] of grid ``row`` of a free flexible body per speed u = (w, v, eta', ...), at rest."""
    n = body.n_modes
    J = np.zeros((6, nu))
    J[0:3, 0:3] = np.eye(3)
    J[0:3, 6:6 + n] = body.rotation_shapes[row]
    J[3:6, 0:3] = -_skew(body.grid_positions[row])
    J[3:6, 3:6] = np.eye(3)
    J[3:6, 6:6 + n] = body.translation_shapes[row]
    return J


def flexible_airframe_at_rest(body, gimbal_grid, sensor_grid, damping_ratio):
    """(A, B, C, D) of the flexible airframe (free-free modal body) with the gimbaled engine at the
    gimbal grid, at rest, no thrust (Table F1 case 7, flexible): input pitch gimbal torque, outputs
    sensor-grid angular velocity and acceleration (grid axes = body axes at rest).

    Brute force from the FE data, not from modal integrals: the kinetic energy is summed over every
    lumped grid mass (mass, CG offset and inertia of the body file's NodeMass, moving with the grid's
    rigid-body plus modal translation and rotation) plus the engine (its gimbal on the grid's deformed
    frame, pitch about y then yaw about z), M = sum J' M_spatial J in the speeds
    u = (w, v, eta', d1', d2'); stiffness diag(w_k^2) and damping diag(2 zeta w_k) on the modes."""
    n = body.n_modes
    nu = 6 + n + 2
    M = np.zeros((nu, nu))
    for i in range(len(body.grid_ids)):
        J = _grid_jacobian(body, i, nu)
        m, c = body.node_mass[i], body.node_cm_offset[i]
        spatial = np.block([[body.node_inertia[i], m * _skew(c)], [-m * _skew(c), m * np.eye(3)]])
        M += J.T @ spatial @ J
    row = {int(g): k for k, g in enumerate(body.grid_ids)}
    engine = _grid_jacobian(body, row[gimbal_grid], nu)
    engine[0:3, 6 + n] = (0.0, 1.0, 0.0)
    engine[0:3, 7 + n] = (0.0, 0.0, 1.0)
    c = ENGINE_CG
    about_gimbal = ENGINE_INERTIA - ENGINE_MASS * _skew(c) @ _skew(c)
    spatial = np.block([[about_gimbal, ENGINE_MASS * _skew(c)], [-ENGINE_MASS * _skew(c), ENGINE_MASS * np.eye(3)]])
    M += engine.T @ spatial @ engine
    w = 2.0 * np.pi * body.frequencies_hz
    K = np.zeros((nu, nu))
    K[6:6 + n, 6:6 + n] = np.diag(w ** 2)
    damping = np.zeros((nu, nu))
    damping[6:6 + n, 6:6 + n] = np.diag(2.0 * damping_ratio * w)
    M_inv = np.linalg.inv(M)
    A = np.block([[np.zeros((nu, nu)), np.eye(nu)], [-M_inv @ K, -M_inv @ damping]])
    torque = np.zeros(nu)
    torque[6 + n] = 1.0
    B = np.concatenate([np.zeros(nu), M_inv @ torque]).reshape(-1, 1)
    sensor = _grid_jacobian(body, row[sensor_grid], nu)
    C = np.vstack([np.hstack([np.zeros((3, nu)), sensor[0:3]]), sensor[3:6] @ A[nu:]])
    D = np.vstack([np.zeros((3, 1)), sensor[3:6] @ B[nu:]])
    return A, B, C, D
