"""A flexible body's node: :func:`dynamics.flexible_kernels.node_deformation` (pose, ``Psi``, ``w``, ``w'``: the slots
children hang from) and :func:`~dynamics.flexible_kernels.node_motion` (the same without ``Psi``, with ``Psi
eta_ddot`` from sums over the shape: node outputs), against an independent reference.

Reference (numpy, no shared code): ``phi = lambda eta``, ``R = exp(phi~) R0`` and the left Jacobian ``J_l(phi) =
sum_k phi~^k / (k + 1)!`` by their power series (40 terms: below 1e-17 for |phi| <= 2), ``Psi = [J_l lambda; gamma +
l~ J_l lambda]`` (CONVENTIONS.md, flexible bodies; the node's velocity per unit modal rate at the body origin), and
``w' = (d/dt Psi) eta_dot`` along ``eta(t) = eta + t eta_dot`` by central differences with Richardson extrapolation.
Tolerances: 1e-13 of the largest entry for the closed forms (round-off of sums over 37 modes, the reference's
included), 1e-8 for the differences (truncation ~h^4 and round-off ~eps / h at h = 1e-3 of the motion). Three sizes of
the node's rotation: below the series branch of the SO(3) coefficients (|phi| = 1e-3 < 0.05), above it (0.3) and large
(2 rad).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from dynamics import flexible_kernels as FK


def skew(v):
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


def series(phi, shift):
    """sum_k phi~^k / (k + shift)!: exp (shift 0) and the left Jacobian (shift 1)."""
    total, power = np.zeros((3, 3)), np.eye(3)
    for k in range(40):
        total += power / math.factorial(k + shift)
        power = power @ skew(phi)
    return total


def reference(shape, l0, R0, eta):
    lam, gam = shape[:3], shape[3:]
    phi = lam @ eta
    pos = l0 + gam @ eta
    A = series(phi, 1) @ lam
    return series(phi, 0) @ R0, pos, np.vstack([A, gam + skew(pos) @ A]), phi


def random_node(size, n=37, seed=3):
    rng = np.random.default_rng(seed)
    shape = rng.standard_normal((6, n))
    eta, eta_dot, eta_ddot = rng.standard_normal(n), rng.standard_normal(n), rng.standard_normal(n)
    shape[:3] *= size / np.linalg.norm(shape[:3] @ eta)  # |lambda eta| = size
    R0 = series(rng.standard_normal(3), 0)
    return shape, rng.standard_normal(3), R0, eta, eta_dot, eta_ddot


def deformation(shape, l0, R0, eta, eta_dot):
    n = eta.size
    R, pos, Psi, tmp = np.zeros((3, 3)), np.zeros(3), np.zeros((6, n)), np.zeros((8, 3))
    w, wd = np.zeros(6), np.zeros(6)
    FK.node_deformation(shape, l0, R0, eta, n, eta_dot, R, pos, Psi, w, wd, tmp)
    return R, pos, Psi, w, wd, tmp[0].copy()


@pytest.mark.parametrize("size", [1e-3, 0.3, 2.0])
def test_node_deformation_and_node_motion_against_the_series_reference(size):
    shape, l0, R0, eta, eta_dot, eta_ddot = random_node(size)
    n = eta.size
    R_ref, pos_ref, Psi_ref, phi_ref = reference(shape, l0, R0, eta)
    R, pos, Psi, w, wd, phi = deformation(shape, l0, R0, eta, eta_dot)
    scale = np.abs(Psi_ref).max()
    np.testing.assert_allclose(R, R_ref, rtol=0, atol=1e-13)
    np.testing.assert_allclose(pos, pos_ref, rtol=0, atol=1e-13 * np.abs(pos_ref).max())
    np.testing.assert_allclose(Psi, Psi_ref, rtol=0, atol=1e-13 * scale)
    np.testing.assert_allclose(phi, phi_ref, rtol=0, atol=1e-13 * size)
    np.testing.assert_allclose(w, Psi_ref @ eta_dot, rtol=0, atol=1e-13 * scale * np.abs(eta_dot).sum())

    # w' = (d/dt Psi(eta + t eta_dot)) eta_dot: central differences at h and 2h, Richardson
    def psi_at(t):
        return reference(shape, l0, R0, eta + t * eta_dot)[2] @ eta_dot

    h = 1e-3
    d1 = (psi_at(h) - psi_at(-h)) / (2 * h)
    d2 = (psi_at(2 * h) - psi_at(-2 * h)) / (4 * h)
    wd_ref = (4 * d1 - d2) / 3
    np.testing.assert_allclose(wd, wd_ref, rtol=0, atol=1e-8 * np.abs(wd_ref).max())

    # node_motion: the same pose, w and w' to the last bit (the same sums), Psi eta_ddot without Psi
    R2, pos2, tmp = np.zeros((3, 3)), np.zeros(3), np.zeros((8, 3))
    w2, wd2, psi_acc = np.zeros(6), np.zeros(6), np.zeros(6)
    FK.node_motion(shape, l0, R0, eta, n, eta_dot, eta_ddot, R2, pos2, w2, wd2, psi_acc, tmp)
    for mine, theirs in ((R2, R), (pos2, pos), (w2, w), (wd2, wd), (tmp[0], phi)):
        np.testing.assert_array_equal(mine, theirs)
    np.testing.assert_allclose(psi_acc, Psi_ref @ eta_ddot, rtol=0, atol=1e-13 * scale * np.abs(eta_ddot).sum())
    psi_acc[:] = 7.0  # without eta_ddot: left as it is
    FK.node_motion(shape, l0, R0, eta, n, eta_dot, eta_ddot[:0], R2, pos2, w2, wd2, psi_acc, tmp)
    assert (psi_acc == 7.0).all()
    np.testing.assert_array_equal(w2, w)


def tree_with_children_on_a_node():
    """A free flexible beam with two children on its node ``joint``: a flexible beam whose hinge holds its own grid
    (``child_grid``: a slot of its own) and a rigid wheel; nodes on all three bodies."""
    from dynamics import Multibody

    from .random_flexible import flexible_body_data, random_node_model

    mb = Multibody(gravity=(0.0, -9.81, 0.0))
    mb.add_flexible_body("beam1", None, modal=flexible_body_data(random_node_model(6, 3, seed=1, scale=0.2), 2),
                         hinge="free")
    mb.add_node("joint", "beam1", grid=6)
    mb.add_node("mid", "beam1", grid=3)
    mb.add_flexible_body("beam2", "beam1", modal=flexible_body_data(random_node_model(5, 2, seed=2, scale=0.2), 2),
                         hinge="revolute", axis=(0.0, 0.0, 1.0), parent_node="joint", child_grid=1)
    mb.add_node("beam2_tip", "beam2", grid=5)
    mb.add_body("wheel", "beam1", mass=2.0, inertia=np.diag([0.1, 0.06, 0.06]), hinge="revolute", axis=(1.0, 0.0, 0.0),
                parent_node="joint")
    mb.add_node("rim", "wheel", position=(0.0, 0.1, 0.0))
    return mb.compile()


@pytest.mark.parametrize("selected", [("rim",), ("beam2_tip",), ("beam2_tip", "rim"), ("mid",), ()])
def test_node_velocities_of_the_selected_nodes_equal_the_full_kinematics(selected):
    """:func:`dynamics.kernels.node_frames.node_velocities_selected` computes the bodies the selected nodes need (the
    slot of ``joint`` from the first selected child on it, without Psi) on a workspace left stale by a full pass at
    another state: the selected nodes' poses and velocities equal those of the full kinematics (the Python API's
    :meth:`node_kinematics`) to the last bit (the same arithmetic), the other rows are left untouched."""
    from dynamics.engine import engine_data
    from dynamics.kernels.node_frames import node_velocities_selected

    from .test_flexible_tree import random_state

    system = tree_with_children_on_a_node()
    rng = np.random.default_rng(11)
    q_stale, u_stale, _ = random_state(system, rng)
    q, u, _ = random_state(system, rng)
    kin = system.node_kinematics(q, u)
    system.node_kinematics(q_stale, u_stale)  # the shared workspace now holds another state
    d = engine_data(system)
    nn = len(system.node_names)
    active = np.array([1 if name in selected else 0 for name in system.node_names], dtype=np.int64)
    if not selected:
        active = active[:0]  # empty: every node
    rotation, position, velocity = np.full((nn, 3, 3), 7.0), np.full((nn, 3), 7.0), np.full((nn, 6), 7.0)
    bodies = np.zeros(system.nbodies, dtype=np.int64)
    node_velocities_selected(d.topology, d.nodes, d.joint_rot, d.joint_vec, d.params, q, u, rotation, position,
                             velocity, d.ws_rot, d.ws_vec, d.ws_mat, d.pool, active, bodies)
    needed = {"rim": {"beam1", "wheel"}, "beam2_tip": {"beam1", "beam2"}, "mid": {"beam1"}}
    expected = set().union(*(needed[s] for s in selected)) if selected else set(system.body_names)
    assert {b for b, flag in zip(system.body_names, bodies) if flag} == expected
    for k, name in enumerate(system.node_names):
        if selected and name not in selected:
            assert (position[k] == 7.0).all() and (velocity[k] == 7.0).all() and (rotation[k] == 7.0).all()
            continue
        np.testing.assert_array_equal(position[k], kin.position[k])
        np.testing.assert_array_equal(rotation[k], kin.rotation[k])
        np.testing.assert_array_equal(velocity[k, :3], kin.angular_velocity[k])
        np.testing.assert_array_equal(velocity[k, 3:], kin.linear_velocity[k])
