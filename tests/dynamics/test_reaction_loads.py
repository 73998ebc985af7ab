"""Reaction loads: the spatial force each hinge transmits and each constraint's load.

Independent references:

* a body-by-body Newton-Euler balance in the world (numpy): each body's ``m (a_c - g) - F_ext`` and
  ``I_c alpha + omega x I_c omega - T_ext`` from the node kinematics at its centre of mass, summed over the
  subtree a hinge carries and moved to the hinge's outboard frame; the hinge loads of a three-body chain
  (revolute, U-joint, prismatic, with frames off the body origins, gravity, node forces) agree to 1e-12 of the
  load scale, and their projections on the hinge axes are the generalized forces of ``inverse_dynamics``;
* a closure that replaces a hinge: the load of a ball closure between a free body and the world, and of a
  revolute closure, equals minus the hinge load of the same body on a spherical / revolute hinge, the
  accelerations equal, and the multipliers are the load's selected rows;
* a distance constraint: a point mass on a rod (spherical pendulum) has the analytic tension
  ``m (|v|^2 / L + g . r_hat)`` toward the pivot and acceleration.
"""

from __future__ import annotations

import numpy as np

from dynamics import Multibody
from dynamics.constraints import ClosureConstraint, ConstrainedSystem
from dynamics.spatial import skew

GRAVITY = np.array([0.0, -3.0, -9.81])


def unit(v):
    v = np.asarray(v, dtype=float)
    return v / np.linalg.norm(v)


def rotation(axis, angle):
    a = unit(axis)
    K = skew(a)
    return np.eye(3) + np.sin(angle) * K + (1 - np.cos(angle)) * K @ K


BODIES = {  # name: (parent, hinge kwargs, mass, com, inertia about com)
    "b1": (None, dict(hinge="revolute", axis=unit([0.2, 0.3, 1.0]), inboard_position=(0.1, -0.2, 0.3),
                      outboard_position=(0.05, 0.02, -0.1), outboard_rotation=rotation([1, 2, 3], 0.4)),
           2.0, (0.4, 0.1, 0.0), [[0.3, 0.01, 0.0], [0.01, 0.25, 0.02], [0.0, 0.02, 0.2]]),
    "b2": ("b1", dict(hinge="ujoint", axes=[unit([1, 0, 0.1]), unit([0, 1, 0])], inboard_position=(0.8, 0.1, 0.0),
                      inboard_rotation=rotation([0, 1, 1], 0.3), outboard_position=(-0.1, 0.0, 0.05)),
           1.5, (0.3, -0.05, 0.1), [[0.1, 0.0, 0.01], [0.0, 0.12, 0.0], [0.01, 0.0, 0.08]]),
    "b3": ("b2", dict(hinge="prismatic", axis=unit([1, 0.2, -0.1]), inboard_position=(0.6, 0.0, 0.1),
                      outboard_rotation=rotation([3, -1, 2], 0.7), outboard_position=(0.02, 0.03, 0.04)),
           0.8, (0.1, 0.2, -0.1), [[0.02, 0.0, 0.0], [0.0, 0.03, 0.001], [0.0, 0.001, 0.025]]),
}


def chain():
    mb = Multibody(gravity=GRAVITY)
    for name, (parent, hinge, mass, com, inertia) in BODIES.items():
        mb.add_body(name, parent, mass=mass, com=com, inertia=inertia, **hinge)
        mb.add_node(f"{name}.cg", name, position=com)
        mb.add_node(f"{name}.hinge", name, position=hinge.get("outboard_position", (0, 0, 0)),
                    rotation=hinge.get("outboard_rotation"))
        mb.add_node(f"{name}.tip", name, position=(0.3, -0.2, 0.25))
    return mb.compile()


def newton_euler_loads(system, q, u, udot, node_forces):
    """Hinge loads by a world-frame Newton-Euler balance of every body, summed over each hinge's subtree."""
    kin = system.node_kinematics(q, u, udot)
    names = list(BODIES)
    own = {}
    for name in names:
        _, _, mass, com, inertia = BODIES[name]
        k = system.node_index(f"{name}.cg")
        R = kin.rotation[k]
        w, alpha = R @ kin.angular_velocity[k], R @ kin.angular_acceleration[k]
        a = R @ kin.linear_acceleration[k]
        Ic = R @ np.asarray(inertia) @ R.T
        force = mass * (a - GRAVITY)
        torque = Ic @ alpha + np.cross(w, Ic @ w)  # about the centre of mass
        for j, node in enumerate(system.node_names):
            if system.node_bodies[j] != name:
                continue
            Rn = kin.rotation[j]
            F, T = Rn @ node_forces[j, 3:], Rn @ node_forces[j, :3]
            force -= F
            torque -= T + np.cross(kin.position[j] - kin.position[k], F)
        own[name] = (force, torque, kin.position[k])
    loads = np.empty((len(names), 6))
    for i, name in enumerate(names):
        subtree = names[i:]  # a chain: every later body hangs from this hinge
        m = system.node_index(f"{name}.hinge")
        P, R = kin.position[m], kin.rotation[m]
        F = sum(own[b][0] for b in subtree)
        T = sum(own[b][1] + np.cross(own[b][2] - P, own[b][0]) for b in subtree)
        loads[i] = np.concatenate([R.T @ T, R.T @ F])
    return loads


def random_state(system, rng):
    return (rng.uniform(-1, 1, system.nq), rng.uniform(-2, 2, system.nu), rng.uniform(-5, 5, system.nu),
            rng.uniform(-3, 3, (system.nnodes, 6)))


def test_hinge_loads_of_a_three_body_chain_equal_the_world_newton_euler_balance_and_inverse_dynamics():
    system = chain()
    cs = ConstrainedSystem(system)
    rng = np.random.default_rng(7)
    for _ in range(4):
        q, u, tau, F = random_state(system, rng)
        loads = cs.hinge_loads(q, u, tau=tau, node_forces=F)
        udot = system.forward_dynamics(q, u, tau=tau, node_forces=F)
        reference = newton_euler_loads(system, q, u, udot, F)
        scale = np.abs(reference).max()
        np.testing.assert_allclose(loads, reference, rtol=0, atol=1e-12 * scale)
        # projections on the hinge axes (motion subspace in the outboard frame M) are inverse dynamics' tau
        tau_id = system.inverse_dynamics(q, u, udot, node_forces=F)
        np.testing.assert_allclose(tau_id, tau, rtol=0, atol=1e-12 * scale)
        b1_axis, b3_axis = BODIES["b1"][1]["axis"], BODIES["b3"][1]["axis"]
        np.testing.assert_allclose(loads[0, :3] @ b1_axis, tau_id[0], rtol=0, atol=1e-12 * scale)
        np.testing.assert_allclose(loads[2, 3:] @ b3_axis, tau_id[3], rtol=0, atol=1e-12 * scale)
        a2 = BODIES["b2"][1]["axes"][1]  # the U-joint's second axis is fixed in M
        np.testing.assert_allclose(loads[1, :3] @ a2, tau_id[2], rtol=0, atol=1e-12 * scale)


def _pendulum(hinge, axis=None):
    mb = Multibody(gravity=GRAVITY)
    mb.add_body("p", None, mass=2.0, com=(0.2, 0.1, -0.5), inertia=[[0.3, 0.01, 0.0], [0.01, 0.2, 0.0], [0, 0, 0.15]],
                hinge=hinge, axis=axis, inboard_position=(0.1, 0.2, 0.3))
    mb.add_node("pivot", "p")
    return mb.compile()


def test_ball_and_revolute_closures_carry_the_hinge_load_of_the_hinge_they_replace():
    """A body on a free hinge held by a closure at its origin equals the body on the replaced hinge:
    accelerations to 1e-12, the constraint load (A = the body's node on B = the world, at B's origin, A's axes)
    = minus the hinge load (ground on body, at the hinge frame = the body frame here), and the multipliers
    are the load's selected rows."""
    rng = np.random.default_rng(4)
    quat = unit(rng.standard_normal(4))
    R = np.empty((3, 3))
    from dynamics.spatial import quaternion_to_rotation

    quaternion_to_rotation(*quat, R)
    free = _pendulum("free")
    q_free = np.concatenate([quat, np.zeros(3)])  # the free hinge's inboard frame is at the pivot
    for kind, hinge, q_tree, w in (("ball", "spherical", quat, rng.uniform(-1, 1, 3)),
                                   ("revolute", "revolute", np.array([0.0]), np.array([0.0, 0.0, 1.3]))):
        if kind == "revolute":  # the revolute about the body z axis, at the same pose
            q_tree = np.array([0.7])
            R = rotation([0, 0, 1], 0.7)
            q_free = np.concatenate([[np.cos(0.35), 0, 0, np.sin(0.35)], np.zeros(3)])
        tree = _pendulum(hinge, axis=(0, 0, 1) if kind == "revolute" else None)
        closure = ClosureConstraint("pivot", None, kind, axis=(0, 0, 1) if kind == "revolute" else None,
                                    world_rotation=np.eye(3), world_position=[0.1, 0.2, 0.3])
        cs = ConstrainedSystem(free, [closure])
        tree_cs = ConstrainedSystem(tree)
        u_tree = w if kind == "ball" else np.array([1.3])
        u_free = np.concatenate([w, np.zeros(3)])
        acc = cs.forward_dynamics(q_free, u_free)
        ref = tree.forward_dynamics(q_tree, u_tree)
        np.testing.assert_allclose(acc.u_dot[:3], ref if kind == "ball" else [0, 0, ref[0]], rtol=0, atol=1e-12)
        np.testing.assert_allclose(acc.u_dot[3:], 0.0, atol=1e-12)
        hinge_load = tree_cs.hinge_loads(q_tree, u_tree)[0]
        # the load is in A's axes (the body's) at B's origin (the pivot): the hinge frame
        np.testing.assert_allclose(acc.loads[0], -hinge_load, rtol=0, atol=1e-12 * np.abs(hinge_load).max())
        np.testing.assert_allclose(acc.multipliers[0], closure.selection @ acc.loads[0], rtol=0, atol=1e-12 * 50)
        np.testing.assert_allclose(acc.loads[0], closure.selection.T @ acc.multipliers[0], rtol=0, atol=1e-12 * 50)


def test_distance_constraint_is_a_spherical_pendulum_with_the_analytic_tension():
    """A body on a free hinge with its centre of mass held at distance L from a world point: its centre of mass
    accelerates as ``g - (|v|^2 / L + g . r_hat) r_hat`` (r_hat from the pivot) and the rod pulls with
    ``m (|v|^2 / L + g . r_hat)``; its rotation is untouched (the rod acts at the centre of mass)."""
    mb = Multibody(gravity=GRAVITY)
    mb.add_body("bob", None, mass=3.0, inertia=[0.2, 0.3, 0.4], hinge="free")
    mb.add_node("cg", "bob")
    system = mb.compile()
    pivot = np.array([0.5, -0.2, 1.0])
    rng = np.random.default_rng(9)
    quat = unit(rng.standard_normal(4))
    r_hat = unit([0.3, -0.4, -1.0])
    L = 1.7
    q = np.concatenate([quat, pivot + L * r_hat])
    R = np.empty((3, 3))
    from dynamics.spatial import quaternion_to_rotation

    quaternion_to_rotation(*quat, R)
    v_world = np.cross(rng.standard_normal(3), r_hat)  # perpendicular to the rod
    w = rng.uniform(-1, 1, 3)
    u = np.concatenate([w, R.T @ v_world])
    rod = ClosureConstraint("cg", None, "distance", world_rotation=np.eye(3), world_position=pivot, length=L,
                            name="rod")
    cs = ConstrainedSystem(system, [rod])
    assert abs(cs.residual(q)[0]) < 1e-15 and abs(cs.velocity_residual(q, u)[0]) < 1e-14
    acc = cs.forward_dynamics(q, u)
    pull = 3.0 * (v_world @ v_world / L + GRAVITY @ r_hat)
    a_world = GRAVITY - pull / 3.0 * r_hat
    kin = system.node_kinematics(q, u, acc.u_dot)
    np.testing.assert_allclose(R @ kin.linear_acceleration[0], a_world, rtol=0, atol=1e-12)
    free = system.forward_dynamics(q, u)
    np.testing.assert_allclose(acc.u_dot[:3], free[:3], rtol=0, atol=1e-12)
    # the load: the bob (A) pulls the world (B) towards itself, +pull r_hat (A's axes in the load)
    np.testing.assert_allclose(R @ acc.loads[0, 3:], pull * r_hat, rtol=0, atol=1e-12 * abs(pull))
    np.testing.assert_allclose(abs(acc.multipliers[0][0]), abs(pull), rtol=1e-12)
