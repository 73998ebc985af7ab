"""Single-gimbal control-moment-gyro pyramid cluster and its singularity-robust steering law.

``CmgCluster`` (attach to the bus node): four CMGs of constant rotor momentum ``h0`` on the faces of
a pyramid of skew angle ``beta`` (Wie, "Space Vehicle Dynamics and Control", 2nd ed., sec. 7.8, the
standard pyramid: rotor momenta at zero gimbal angles +y, -x, -y, +x), CMG i at gimbal angle d_i:

    h_i(d_i) = cos d_i h_i0 + sin d_i t_i0,      H = h0 sum_i h_i(d_i)                  (node axes)
    h_10 = (0, 1, 0)  t_10 = (-cb, 0, sb);  h_20 = (-1, 0, 0)  t_20 = (0, -cb, sb)
    h_30 = (0, -1, 0) t_30 = (cb, 0, sb);   h_40 = (1, 0, 0)   t_40 = (0, cb, sb)
    A(d) = [dh_1/dd_1 ... dh_4/dd_4],  dh_i/dd_i = -sin d_i h_i0 + cos d_i t_i0

The gimbal angles are the model's states, driven by the rate command clipped at ``max_gimbal_rate``
(ideal gimbal servo; the rotor and gimbal inertias other than the spin momentum are in the bus). The
cluster acts on the node with ``tau = -h0 A d' - omega x H``, so ``R (J omega + H)`` is conserved, as
for the reaction wheels.

``CmgSteering`` (sampled): for a commanded torque ``tau_c`` on the spacecraft and the measured gimbal
angles (and body rate, optional: its gyroscopic term is compensated), the singularity-robust inverse
(Bedrossian, Paradiso and Bergmann, J. Guid. Control Dyn. 13(6), 1990; Wie sec. 7.8.3)

    d'_c = -(1 / h0) A^T (A A^T + lambda I)^-1 (tau_c + omega x H),   lambda = lambda_0 exp(-mu det(A A^T))

scaled as a whole to ``max_gimbal_rate`` (the torque direction kept). Away from singularities
(``det(A A^T)`` well above ``1/mu``) it is the pseudo-inverse and the cluster delivers ``tau_c``;
near one, lambda trades a torque error ``lambda (A A^T + lambda I)^-1 tau`` for bounded gimbal rates.
Outputs the command (held) and the singularity measure ``det(A A^T)``.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from shell.model import Declarations, InputPort, Model, OutputPort, Parameter, State
from shell.attitude import cross
from shell.ports import node_inputs
from shell.registry import register_model

GEOMETRY = (
    Parameter("wheel_momentum", "N*m*s", None, (), (1e-12, None), "rotor spin momentum h0 of each CMG"),
    Parameter("skew_angle", "rad", np.radians(54.73), (), (0.0, np.pi / 2), "pyramid skew angle beta"),
    Parameter("max_gimbal_rate", "rad/s", 1.0, (), (1e-12, None), "gimbal rate limit"),
)
CLUSTER_INPUTS = (
    InputPort("gimbal_rate_command", "rad/s", (4,), "commanded gimbal rates", feedthrough=True),
    *node_inputs("angular_velocity", feedthrough=True,
                 angular_velocity="inertial angular velocity of the node, node axes"),
)
CLUSTER_OUTPUTS = (
    OutputPort("torque", "N*m", (3,), "torque on the node: -h0 A d' - omega x H", feedthrough=True),
    OutputPort("momentum", "N*m*s", (3,), "cluster angular momentum H, node axes", feedthrough=True),
    OutputPort("gimbal_angles", "rad", (4,), "gimbal angles", feedthrough=True),
    OutputPort("gimbal_rates", "rad/s", (4,), "gimbal rates after the limit", feedthrough=True),
)
CLUSTER_CONTINUOUS = (State("gimbal_angles", "rad", (4,), None, "gimbal angles d_i"),)
CLUSTER = Declarations(parameters=GEOMETRY, inputs=CLUSTER_INPUTS, outputs=CLUSTER_OUTPUTS,
                       continuous=CLUSTER_CONTINUOUS)
P_CMG, U_CMG, Y_CMG, X_CMG = CLUSTER.P, CLUSTER.U, CLUSTER.Y, CLUSTER.X


@njit(cache=True)
def pyramid_vectors(beta, i):
    """(h_i0, t_i0) of CMG i (0-based) of the standard pyramid (module docstring)."""
    cb, sb = np.cos(beta), np.sin(beta)
    if i == 0:
        return (0.0, 1.0, 0.0), (-cb, 0.0, sb)
    if i == 1:
        return (-1.0, 0.0, 0.0), (0.0, -cb, sb)
    if i == 2:
        return (0.0, -1.0, 0.0), (cb, 0.0, sb)
    return (1.0, 0.0, 0.0), (0.0, cb, sb)


@njit(cache=True)
def rotor_direction(beta, i, angle):
    h, t = pyramid_vectors(beta, i)
    c, s = np.cos(angle), np.sin(angle)
    return (c * h[0] + s * t[0], c * h[1] + s * t[1], c * h[2] + s * t[2])


@njit(cache=True)
def rotor_direction_derivative(beta, i, angle):
    h, t = pyramid_vectors(beta, i)
    c, s = np.cos(angle), np.sin(angle)
    return (-s * h[0] + c * t[0], -s * h[1] + c * t[1], -s * h[2] + c * t[2])


@njit(cache=True)
def _clipped(rate, limit):
    return min(max(rate, -limit), limit)


@njit(cache=True)
def _cluster_outputs(t, x, z, u, p, y):
    h0, beta, limit = p[P_CMG.wheel_momentum], p[P_CMG.skew_angle], p[P_CMG.max_gimbal_rate]
    H = (0.0, 0.0, 0.0)
    hdot = (0.0, 0.0, 0.0)
    for i in range(4):
        d = x[X_CMG.gimbal_angles + i]
        rate = _clipped(u[U_CMG.gimbal_rate_command + i], limit)
        r = rotor_direction(beta, i, d)
        a = rotor_direction_derivative(beta, i, d)
        H = (H[0] + h0 * r[0], H[1] + h0 * r[1], H[2] + h0 * r[2])
        hdot = (hdot[0] + h0 * a[0] * rate, hdot[1] + h0 * a[1] * rate, hdot[2] + h0 * a[2] * rate)
        y[Y_CMG.gimbal_angles + i] = d
        y[Y_CMG.gimbal_rates + i] = rate
    w = U_CMG.angular_velocity
    gyro = cross((u[w], u[w + 1], u[w + 2]), H)
    for k in range(3):
        y[Y_CMG.torque + k] = -hdot[k] - gyro[k]
        y[Y_CMG.momentum + k] = H[k]


@njit(cache=True)
def _cluster_derivatives(t, x, z, u, p, xdot):
    for i in range(4):
        xdot[X_CMG.gimbal_angles + i] = _clipped(u[U_CMG.gimbal_rate_command + i], p[P_CMG.max_gimbal_rate])


@register_model
class CmgCluster(Model):
    """Four single-gimbal CMGs in the standard pyramid at a node; see the module docstring."""

    summary = "single-gimbal CMG pyramid (4) at a node: gimbal-rate commands in; torque, momentum, angles out"
    declarations = CLUSTER
    feedthrough_outputs = staticmethod(_cluster_outputs)
    derivatives = staticmethod(_cluster_derivatives)


STEERING_PARAMETERS = GEOMETRY + (
    Parameter("lambda_0", "", 0.01, (), (0.0, None), "singularity-robust weight at a singularity"),
    Parameter("mu", "", 10.0, (), (0.0, None), "decay of the weight with det(A A^T)"),
)
STEERING_INPUTS = (
    InputPort("torque_command", "N*m", (3,), "torque demanded on the spacecraft, node axes"),
    InputPort("gimbal_angles", "rad", (4,), "measured gimbal angles"),
    *node_inputs("angular_velocity", required=False,
                 angular_velocity="body rate, node axes (omega x H compensated)"),
)
STEERING_OUTPUTS = (
    OutputPort("gimbal_rate_command", "rad/s", (4,), "gimbal rate command (held)"),
    OutputPort("singularity_measure", "", (), "det(A A^T) at the last sample"),
)
STEERING_DISCRETE = (
    State("gimbal_rate_command", "rad/s", (4,), None, "held command"),
    State("singularity_measure", "", (), None, "det(A A^T)"),
)
STEERING = Declarations(parameters=STEERING_PARAMETERS, inputs=STEERING_INPUTS, outputs=STEERING_OUTPUTS,
                        discrete=STEERING_DISCRETE)
P_STEER, U_STEER, Y_STEER, Z_STEER = STEERING.P, STEERING.U, STEERING.Y, STEERING.Z


@njit(cache=True)
def _steering_held(t, x, z, u, p, y):
    for i in range(4):
        y[Y_STEER.gimbal_rate_command + i] = z[Z_STEER.gimbal_rate_command + i]
    y[Y_STEER.singularity_measure] = z[Z_STEER.singularity_measure]


@njit(cache=True)
def _steering_update(t, x, z, u, p):
    h0, beta = p[P_STEER.wheel_momentum], p[P_STEER.skew_angle]
    g = U_STEER.gimbal_angles
    a0 = rotor_direction_derivative(beta, 0, u[g])
    a1 = rotor_direction_derivative(beta, 1, u[g + 1])
    a2 = rotor_direction_derivative(beta, 2, u[g + 2])
    a3 = rotor_direction_derivative(beta, 3, u[g + 3])
    H = (0.0, 0.0, 0.0)
    for i in range(4):
        r = rotor_direction(beta, i, u[g + i])
        H = (H[0] + h0 * r[0], H[1] + h0 * r[1], H[2] + h0 * r[2])
    w = U_STEER.angular_velocity
    gyro = cross((u[w], u[w + 1], u[w + 2]), H)
    c = U_STEER.torque_command
    b = (u[c] + gyro[0], u[c + 1] + gyro[1], u[c + 2] + gyro[2])
    # M = A A^T (3 x 3, symmetric)
    m00 = a0[0] * a0[0] + a1[0] * a1[0] + a2[0] * a2[0] + a3[0] * a3[0]
    m01 = a0[0] * a0[1] + a1[0] * a1[1] + a2[0] * a2[1] + a3[0] * a3[1]
    m02 = a0[0] * a0[2] + a1[0] * a1[2] + a2[0] * a2[2] + a3[0] * a3[2]
    m11 = a0[1] * a0[1] + a1[1] * a1[1] + a2[1] * a2[1] + a3[1] * a3[1]
    m12 = a0[1] * a0[2] + a1[1] * a1[2] + a2[1] * a2[2] + a3[1] * a3[2]
    m22 = a0[2] * a0[2] + a1[2] * a1[2] + a2[2] * a2[2] + a3[2] * a3[2]
    det = m00 * (m11 * m22 - m12 * m12) - m01 * (m01 * m22 - m12 * m02) + m02 * (m01 * m12 - m11 * m02)
    lam = p[P_STEER.lambda_0] * np.exp(-p[P_STEER.mu] * det)
    s00, s11, s22 = m00 + lam, m11 + lam, m22 + lam
    c00, c01, c02 = s11 * s22 - m12 * m12, m02 * m12 - m01 * s22, m01 * m12 - m02 * s11
    c11, c12, c22 = s00 * s22 - m02 * m02, m01 * m02 - s00 * m12, s00 * s11 - m01 * m01
    dets = s00 * c00 + m01 * c01 + m02 * c02
    v = ((c00 * b[0] + c01 * b[1] + c02 * b[2]) / dets, (c01 * b[0] + c11 * b[1] + c12 * b[2]) / dets,
         (c02 * b[0] + c12 * b[1] + c22 * b[2]) / dets)
    rates = (-(a0[0] * v[0] + a0[1] * v[1] + a0[2] * v[2]) / h0, -(a1[0] * v[0] + a1[1] * v[1] + a1[2] * v[2]) / h0,
             -(a2[0] * v[0] + a2[1] * v[1] + a2[2] * v[2]) / h0, -(a3[0] * v[0] + a3[1] * v[1] + a3[2] * v[2]) / h0)
    largest = max(abs(rates[0]), abs(rates[1]), abs(rates[2]), abs(rates[3]))
    limit = p[P_STEER.max_gimbal_rate]
    scale = limit / largest if largest > limit else 1.0
    for i in range(4):
        z[Z_STEER.gimbal_rate_command + i] = scale * rates[i]
    z[Z_STEER.singularity_measure] = det


@register_model
class CmgSteering(Model):
    """Singularity-robust steering of the CMG pyramid; see the module docstring."""

    summary = "singularity-robust CMG steering (Bedrossian): torque command in, gimbal-rate command out (held)"
    declarations = STEERING
    default_period = "0.1 s"
    state_outputs = staticmethod(_steering_held)
    update = staticmethod(_steering_update)
