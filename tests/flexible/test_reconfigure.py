"""Run-time configuration changes: lock/unlock hinges, detach subtrees, change mass properties.

Independent checks: an internal impulsive lock conserves total linear and angular momentum and does not
add energy; after the lock the system moves like the original one with that hinge held by a zero
prescribed acceleration; unlocking and detaching change no node pose or velocity (no jump) and conserve
momentum; a detached free subtree's momentum then stays constant on its own; a mass change equals a
fresh build. Tolerances 1e-12 relative: the mappings are exact up to one dense solve.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from dynamics import ModelDefinitionError, Multibody
from dynamics.system import MultibodySystem

from .test_flexible_tree import flexible_tree, random_state


def momentum(system, q, u):
    return np.concatenate([system.linear_momentum(q, u), system.angular_momentum(q, u)])


def node_state(system, q, u):
    kin = system.node_kinematics(q, u)
    w = np.einsum("nab,nb->na", kin.rotation, kin.angular_velocity)
    v = np.einsum("nab,nb->na", kin.rotation, kin.linear_velocity)
    return kin.rotation, kin.position, w, v


def test_lock_is_an_internal_plastic_impulse_and_unlock_restores_the_hinge():
    system = flexible_tree(gravity=(0.0, 0.0, 0.0))
    rng = np.random.default_rng(1)
    q, u, _ = random_state(system, rng)
    locked, q1, u1 = system.reconfigure(q, u, lock=["arm", "tip_mass"])
    assert locked.nu == system.nu - 3 and locked.hinge_names[1] == "locked"
    np.testing.assert_allclose(momentum(locked, q1, u1), momentum(system, q, u), rtol=1e-12, atol=1e-12)
    assert locked.kinetic_energy(q1, u1) <= system.kinetic_energy(q, u)
    # poses do not jump
    before, after = node_state(system, q, u), node_state(locked, q1, u1)
    np.testing.assert_allclose(after[0], before[0], atol=1e-14)
    np.testing.assert_allclose(after[1], before[1], atol=1e-14)
    # the locked system moves like the original with the hinges held (zero rate, zero acceleration):
    # build that original with the two hinges prescribed and compare the remaining accelerations
    held_bodies = [dataclasses.replace(b, prescribed=np.ones_like(b.prescribed))
                   if b.name in ("arm", "tip_mass") else b for b in system.definitions[0]]
    held = MultibodySystem.from_definitions(held_bodies, list(system.definitions[1]), np.zeros(3))
    keep = np.concatenate([
        np.arange(s.start + (s.stop - s.start - held.n_modes[i] if name in ("arm", "tip_mass") else 0), s.stop)
        for i, (name, s) in enumerate(zip(held.body_names, held.u_slices))])
    u_held = np.zeros(held.nu)
    u_held[keep] = u1
    tau_l = rng.standard_normal(locked.nu)
    tau_h = np.zeros(held.nu)
    tau_h[keep] = tau_l
    a_locked = locked.forward_dynamics(q1, u1, tau_l)
    a_held = held.forward_dynamics(q, u_held, tau_h)
    np.testing.assert_allclose(a_locked, a_held[keep], rtol=1e-10, atol=1e-10)
    # unlock: same hinges back at the locked pose, zero relative rates, no jump
    unlocked, q2, u2 = locked.reconfigure(q1, u1, unlock=["arm", "tip_mass"])
    assert unlocked.nu == system.nu and unlocked.hinge_names == system.hinge_names
    np.testing.assert_allclose(q2, q, atol=1e-14)
    again = node_state(unlocked, q2, u2)
    for a, b in zip(again, node_state(locked, q1, u1)):
        np.testing.assert_allclose(a, b, atol=1e-12)


def test_detach_separates_a_subtree_without_jumps_and_it_then_drifts_alone():
    system = flexible_tree(gravity=(0.0, 0.0, 0.0), damping=False)
    rng = np.random.default_rng(2)
    q, u, _ = random_state(system, rng)
    free, q1, u1 = system.reconfigure(q, u, detach=["panel"])
    assert free.hinge_names[free.body_index("panel")] == "free" and free.parents[free.body_index("panel")] == -1
    for a, b in zip(node_state(free, q1, u1), node_state(system, q, u)):
        np.testing.assert_allclose(a, b, atol=1e-12)
    np.testing.assert_allclose(momentum(free, q1, u1), momentum(system, q, u), rtol=1e-12, atol=1e-12)
    # the panel and the tip mass it carries now form an isolated system: their momentum is constant
    zero = np.zeros(free.nu)
    h = 1e-3
    P0 = None
    for _ in range(50):
        k1 = (free.q_dot(q1, u1), free.forward_dynamics(q1, u1, zero))
        k2 = (free.q_dot(q1 + h / 2 * k1[0], u1 + h / 2 * k1[1]),
              free.forward_dynamics(q1 + h / 2 * k1[0], u1 + h / 2 * k1[1], zero))
        k3 = (free.q_dot(q1 + h / 2 * k2[0], u1 + h / 2 * k2[1]),
              free.forward_dynamics(q1 + h / 2 * k2[0], u1 + h / 2 * k2[1], zero))
        k4 = (free.q_dot(q1 + h * k3[0], u1 + h * k3[1]),
              free.forward_dynamics(q1 + h * k3[0], u1 + h * k3[1], zero))
        q1 = q1 + h / 6 * (k1[0] + 2 * k2[0] + 2 * k3[0] + k4[0])
        u1 = u1 + h / 6 * (k1[1] + 2 * k2[1] + 2 * k3[1] + k4[1])
        # separated: the panel subtree alone, rebuilt as its own system, has constant momentum
        alone, qa, ua = _subtree_system(free, q1, u1, "panel")
        P = momentum(alone, qa, ua)
        P0 = P if P0 is None else P0
        np.testing.assert_allclose(P, P0, rtol=1e-9, atol=1e-9)


def _subtree_system(system, q, u, root):
    """The subtree rooted at ``root`` (already free) as a standalone system with its state."""
    bodies, nodes, gravity = system.definitions
    keep = set()
    for b in bodies:
        if b.name == root or b.parent in keep:
            keep.add(b.name)
    sub_bodies = [b for b in bodies if b.name in keep]
    sub_nodes = [n for n in nodes if n.body in keep]
    sub = MultibodySystem.from_definitions(sub_bodies, sub_nodes, gravity)
    idx = [system.body_index(b.name) for b in sub_bodies]
    qs = np.concatenate([q[system.q_slices[i]] for i in idx])
    us = np.concatenate([u[system.u_slices[i]] for i in idx])
    return sub, qs, us


def test_mass_properties_change_equals_a_fresh_build_in_place_and_by_reconfigure():
    system = flexible_tree()
    rng = np.random.default_rng(3)
    q, u, tau = random_state(system, rng)
    new_props = dict(mass=2.5, com=(0.1, 0.05, 0.0), inertia=[0.03, 0.04, 0.05])
    rebuilt, q1, u1 = system.reconfigure(q, u, mass_properties={"arm": new_props})
    copy = system.copy()
    before = system.forward_dynamics(q, u, tau)
    system.set_mass_properties("arm", **new_props)
    np.testing.assert_array_equal(q1, q)
    a1 = rebuilt.forward_dynamics(q, u, tau)
    a2 = system.forward_dynamics(q, u, tau)
    np.testing.assert_allclose(a1, a2, rtol=1e-13, atol=1e-13)
    # a copy shares the model, not the data: the change stays in the system it was made in (dynamics.data)
    np.testing.assert_array_equal(copy.forward_dynamics(q, u, tau), before)
    assert not np.allclose(before, a2)
    assert rebuilt.masses[rebuilt.body_index("arm")] == 2.5
    with pytest.raises(ModelDefinitionError, match="mass must be positive"):
        system.set_mass_properties("arm", mass=0.0, com=(0, 0, 0), inertia=[1, 1, 1])
    with pytest.raises(ModelDefinitionError, match="'bus' is flexible"):
        system.set_mass_properties("bus", mass=1.0, com=(0, 0, 0), inertia=[1, 1, 1])


def test_bad_reconfiguration_requests_are_refused():
    system = flexible_tree()
    q = system.neutral_configuration()
    u = np.zeros(system.nu)
    with pytest.raises(ModelDefinitionError, match="unknown body or hinge 'arn'"):
        system.reconfigure(q, u, lock=["arn"])
    with pytest.raises(ModelDefinitionError, match="already attached to the ground"):
        system.reconfigure(q, u, detach=["bus"])
    with pytest.raises(ModelDefinitionError, match="is not locked"):
        system.reconfigure(q, u, unlock=["arm"])
    mb = Multibody()
    mb.add_body("base", None, mass=1.0, inertia=[1, 1, 1], hinge="free")
    mb.add_body("stub", "base", mass=1.0, inertia=[1, 1, 1], hinge="locked", inboard_position=(1, 0, 0))
    rigid = mb.compile()
    q, u = rigid.neutral_configuration(), np.zeros(rigid.nu)
    with pytest.raises(ModelDefinitionError, match="was defined locked"):
        rigid.reconfigure(q, u, unlock=["stub"])
    opened, q1, u1 = rigid.reconfigure(q, u, unlock={"stub": {"hinge": "revolute", "axis": (0, 0, 1)}})
    assert opened.nu == 7 and q1[-1] == 0.0
