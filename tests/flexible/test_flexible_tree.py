"""Trees with flexible bodies and hinges on flexible nodes: consistency, kinematics and conservation.

* ABA against the dense ``M^-1 (tau - bias)``, forward/inverse round trip, mass matrix against inverse
  dynamics columns, kinetic energy against ``1/2 u' M u``: 1e-10 relative (issue 4).
* Node forces act through the transpose of the node velocity Jacobian (power consistency).
* Node velocities and accelerations equal central differences of node poses and velocities along the
  motion (1e-7: O(h^2) truncation with h = 1e-5 and O(eps/h) round-off).
* RK4 conserves energy and angular momentum of a torque-free tree with flexible bodies to 4th order:
  the attachment kinematics (exponential map, left Jacobian) are exactly those of the coordinates.
"""

from __future__ import annotations

import numpy as np
import pytest

from dynamics import Multibody

from .conftest import rk4_march
from .random_flexible import flexible_body_data, random_node_model


def flexible_tree(gravity=(0.0, 0.0, -9.81), order=2, damping=True, point_masses=False):
    def data(seed, nodes, modes, o=order):
        model = random_node_model(nodes, modes, seed=seed, point_masses=point_masses, scale=0.2)
        if not damping:
            model.damping[:] = 0.0
        return flexible_body_data(model, o)

    mb = Multibody(gravity=gravity)
    mb.add_flexible_body("bus", None, modal=data(1, 6, 3), hinge="free")
    mb.add_node("bus_tip", "bus", grid=6, rotation=[np.cos(0.3), np.sin(0.3), 0.0, 0.0])
    mb.add_node("bus_mid", "bus", grid=3)
    mb.add_body("arm", "bus", mass=1.0, com=(0.2, 0.0, 0.0), inertia=[0.01, 0.02, 0.025], hinge="revolute",
                axis=(0.0, 0.0, 1.0), parent_node="bus_tip", inboard_position=(0.05, 0.0, 0.0))
    mb.add_flexible_body("panel", "arm", modal=data(2, 5, 2, o=min(order, 1)), hinge="spherical",
                         inboard_position=(0.4, 0.0, 0.0), outboard_position=(0.1, 0.0, 0.0))
    mb.add_node("panel_tip", "panel", grid=5)
    mb.add_body("tip_mass", "panel", mass=0.5, com=(0.0, 0.1, 0.0), inertia=[0.01, 0.012, 0.013],
                hinge="ujoint", axes=[(1.0, 0.0, 0.0), (0.0, 1.0, 0.0)], parent_node="panel_tip")
    mb.add_flexible_body("boom", "bus", modal=data(3, 4, 2), hinge="prismatic", axis=(0.0, 1.0, 0.0),
                         parent_node="bus_mid")
    mb.add_node("boom_sensor", "boom", grid=2)
    mb.add_node("arm_sensor", "arm", position=(0.3, 0.0, 0.0))
    return mb.compile()


def random_state(system, rng, eta_scale=0.05):
    q = system.neutral_configuration()
    for b, qs in enumerate(system.q_slices):
        nq = qs.stop - qs.start - system.n_modes[b]
        q[qs.start:qs.start + nq] += 0.5 * rng.standard_normal(nq)
        q[qs.start + nq:qs.stop] = eta_scale * rng.standard_normal(system.n_modes[b])
    system.normalize_quaternions(q)
    return q, rng.standard_normal(system.nu), rng.standard_normal(system.nu)


def rel(a, b):
    return np.linalg.norm(a - b) / np.linalg.norm(b)


@pytest.mark.parametrize("order", [0, 1, 2])
def test_aba_dense_round_trip_and_mass_matrix(order):
    system = flexible_tree(order=order)
    assert system.is_flexible and system.n_modes == (3, 0, 2, 0, 2)
    rng = np.random.default_rng(order)
    for _ in range(2):
        q, u, tau = random_state(system, rng)
        f = rng.standard_normal((system.nnodes, 6))
        udot = system.forward_dynamics(q, u, tau, node_forces=f)
        M = system.mass_matrix(q)
        assert np.array_equal(M, M.T)
        bias = system.bias_forces(q, u, node_forces=f)
        assert rel(udot, np.linalg.solve(M, tau - bias)) < 1e-10
        assert rel(system.inverse_dynamics(q, u, udot, node_forces=f), tau) < 1e-10
        zero = np.zeros(system.nu)
        base = system.inverse_dynamics(q, zero, zero)
        columns = np.array([system.inverse_dynamics(q, zero, e) - base for e in np.eye(system.nu)]).T
        assert np.abs(columns - M).max() < 1e-10 * np.abs(M).max()
        assert abs(system.kinetic_energy(q, u) - 0.5 * u @ M @ u) < 1e-12 * (u @ M @ u)


def node_jacobian(system, q, node):
    J = np.empty((6, system.nu))
    for k in range(system.nu):
        kin = system.node_kinematics(q, np.eye(system.nu)[k])
        J[:3, k] = kin.angular_velocity[node]
        J[3:, k] = kin.linear_velocity[node]
    return J


def test_node_forces_act_through_the_node_velocity_jacobian():
    system = flexible_tree()
    rng = np.random.default_rng(7)
    q, _, _ = random_state(system, rng)
    zero = np.zeros(system.nu)
    for node in range(system.nnodes):
        f = np.zeros((system.nnodes, 6))
        f[node] = rng.standard_normal(6)
        generalized = system.bias_forces(q, zero) - system.bias_forces(q, zero, node_forces=f)
        J = node_jacobian(system, q, node)
        np.testing.assert_allclose(generalized, J.T @ f[node], rtol=0, atol=1e-12 * np.abs(J).max() * 10)


def test_node_kinematics_equal_differences_along_the_motion():
    system = flexible_tree()
    rng = np.random.default_rng(8)
    q, u, tau = random_state(system, rng)
    udot = system.forward_dynamics(q, u, tau)
    h = 1e-5

    def world(qq, uu, uudot=None):
        kin = system.node_kinematics(qq, uu, uudot)
        w = np.einsum("nab,nb->na", kin.rotation, kin.angular_velocity)
        v = np.einsum("nab,nb->na", kin.rotation, kin.linear_velocity)
        return kin, w, v

    kin, w, v = world(q, u, udot)
    qdot = system.q_dot(q, u)
    plus, w_p, v_p = world(q + h * qdot, u + h * udot)
    minus, w_m, v_m = world(q - h * qdot, u - h * udot)
    pos_rate = (plus.position - minus.position) / (2 * h)
    np.testing.assert_allclose(pos_rate, v, atol=1e-7)
    Rdot = (plus.rotation - minus.rotation) / (2 * h)
    W = np.einsum("nba,nbc->nac", kin.rotation, Rdot)  # R' Rdot = skew(omega_node)
    omega = np.stack([W[:, 2, 1], W[:, 0, 2], W[:, 1, 0]], axis=1)
    np.testing.assert_allclose(omega, kin.angular_velocity, atol=1e-7)
    alpha = np.einsum("nba,nb->na", kin.rotation, (w_p - w_m) / (2 * h))
    accel = np.einsum("nba,nb->na", kin.rotation, (v_p - v_m) / (2 * h))
    np.testing.assert_allclose(alpha, kin.angular_acceleration, atol=1e-6)
    np.testing.assert_allclose(accel, kin.linear_acceleration, atol=1e-6)


def rk4(system, q, u, h, steps):
    q, u, _ = rk4_march(system, q, u, h, steps, normalize=False)
    return q, u


def test_torque_free_flexible_tree_conserves_energy_and_momentum_at_rk4_order():
    system = flexible_tree(gravity=(0.0, 0.0, 0.0), damping=False)
    rng = np.random.default_rng(9)
    q0, u0, _ = random_state(system, rng)
    u0 *= 0.5

    def total_energy(q, u):
        return system.kinetic_energy(q, u) + system.potential_energy(q)

    e0 = total_energy(q0, u0)
    L0 = system.angular_momentum(q0, u0)
    steps = np.array([4e-3, 2e-3, 1e-3])
    drift = []
    for h in steps:
        q, u = rk4(system, q0, u0, h, int(round(0.2 / h)))
        drift.append((abs(total_energy(q, u) - e0) / e0,
                      np.linalg.norm(system.angular_momentum(q, u) - L0) / np.linalg.norm(L0)))
    drift = np.array(drift)
    # An inconsistency between coordinates and kinematics would leave a drift floor that does not shrink
    # with h; RK4 must shrink it at (at least) 4th order. Over this short span the energy error even
    # falls faster (measured slopes 4.5 energy, 4.0 momentum), so only the lower bound is meaningful.
    for k, what in enumerate(("energy", "angular momentum")):
        slope = np.polyfit(np.log(steps), np.log(drift[:, k]), 1)[0]
        assert slope > 3.6, f"{what}: drift {drift[:, k]} has slope {slope:.2f}, expected >= 4"
        assert drift[-1, k] < 1e-9
