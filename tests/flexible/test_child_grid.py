"""A flexible child whose hinge holds its deforming interface grid (``child_grid``) against the same
structure assembled by a closure constraint between the two deformed grids.

The closure model (each flexible body on its own free hinge, tied by a cut joint of the hinge's kind
between the parent's node and the child's grid node; ``dynamics.constraints``) is an independent route:
it uses only node kinematics and a dense constrained solve. Both must give the same modal accelerations
and the same node accelerations, for locked, revolute and spherical joints, with gravity and velocities:
1e-9 relative (the constrained solve goes through the mass matrix and node Jacobians; observed ~1e-12).
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from dynamics import Multibody
from dynamics.constraints import ClosureConstraint, ConstrainedSystem
from dynamics.system import MultibodySystem

from .random_flexible import flexible_body_data, random_node_model
from .test_flexible_tree import random_state


def two_beams(hinge, closure_kind):
    mb = Multibody(gravity=(0.0, -9.81, 0.0))
    mb.add_flexible_body("beam1", None, modal=flexible_body_data(random_node_model(6, 3, seed=1, scale=0.2), 2),
                         hinge="free")
    mb.add_node("joint", "beam1", grid=6)
    kwargs = {"axis": (0.0, 0.0, 1.0)} if hinge == "revolute" else {}
    mb.add_flexible_body("beam2", "beam1", modal=flexible_body_data(random_node_model(5, 2, seed=2, scale=0.2), 2),
                         hinge=hinge, parent_node="joint", child_grid=1, **kwargs)
    mb.add_node("beam2_tip", "beam2", grid=5)
    return mb.compile()


@pytest.mark.parametrize("hinge, kind", [("locked", "weld"), ("revolute", "revolute"), ("spherical", "ball")])
def test_child_grid_hinge_equals_the_closure_model(hinge, kind):
    tree = two_beams(hinge, kind)
    rng = np.random.default_rng(3)
    q, u, _ = random_state(tree, rng)
    tau = np.zeros(tree.nu)
    udot = tree.forward_dynamics(q, u, tau)
    # same instant, beam2 cut loose and re-tied by a closure between the two deformed frames
    free, qf, uf = tree.reconfigure(q, u, detach=["beam2"])
    kwargs = {"axis": (0.0, 0.0, 1.0)} if kind == "revolute" else {}
    closed = ConstrainedSystem(free, [ClosureConstraint("joint", "beam2.hinge", kind, **kwargs)])
    assert np.abs(closed.residual(qf)).max() < 1e-12
    assert np.abs(closed.velocity_residual(qf, uf)).max() < 1e-12
    udot_f = closed.forward_dynamics(qf, uf, np.zeros(free.nu)).u_dot
    # modal accelerations are the same coordinates in both models
    for name in ("beam1", "beam2"):
        s_t, s_f = tree.u_slices[tree.body_index(name)], free.u_slices[free.body_index(name)]
        n = tree.n_modes[tree.body_index(name)]
        np.testing.assert_allclose(udot[s_t][-n:], udot_f[s_f][-n:], rtol=1e-9,
                                   atol=1e-9 * np.abs(udot).max())
    # every node accelerates alike (world axes)
    def world_accelerations(system, qq, uu, aa):
        kin = system.node_kinematics(qq, uu, aa)
        return (np.einsum("nab,nb->na", kin.rotation, kin.angular_acceleration),
                np.einsum("nab,nb->na", kin.rotation, kin.linear_acceleration))

    for a, b in zip(world_accelerations(tree, q, u, udot), world_accelerations(free, qf, uf, udot_f)):
        np.testing.assert_allclose(a, b, rtol=1e-9, atol=1e-9 * np.abs(a).max())


def test_child_grid_tree_is_consistent_and_conserves_energy():
    tree = two_beams("revolute", "revolute")
    rng = np.random.default_rng(4)
    q, u, tau = random_state(tree, rng)
    udot = tree.forward_dynamics(q, u, tau)
    M = tree.mass_matrix(q)
    assert np.linalg.norm(udot - np.linalg.solve(M, tau - tree.bias_forces(q, u))) < 1e-10 * np.linalg.norm(udot)
    assert np.linalg.norm(tree.inverse_dynamics(q, u, udot) - tau) < 1e-10 * np.linalg.norm(tau)
    # torque-free and undamped: RK4's energy drift must shrink at 4th order (no inconsistency floor)
    mb_defs = tree.definitions
    bodies = [dataclasses.replace(b) for b in mb_defs[0]]
    for b in bodies:
        b.flexible = dataclasses.replace(b.flexible, damping=np.zeros_like(b.flexible.damping))
    free_fall = MultibodySystem.from_definitions(bodies, list(mb_defs[1]), np.zeros(3))
    zero = np.zeros(free_fall.nu)

    def energy(q, u):
        return free_fall.kinetic_energy(q, u) + free_fall.potential_energy(q)

    drifts = []
    for h in (2e-3, 1e-3):
        qq, uu = q.copy(), 0.5 * u
        e0 = energy(qq, uu)
        for _ in range(int(round(0.1 / h))):
            k1 = (free_fall.q_dot(qq, uu), free_fall.forward_dynamics(qq, uu, zero))
            k2 = (free_fall.q_dot(qq + h / 2 * k1[0], uu + h / 2 * k1[1]),
                  free_fall.forward_dynamics(qq + h / 2 * k1[0], uu + h / 2 * k1[1], zero))
            k3 = (free_fall.q_dot(qq + h / 2 * k2[0], uu + h / 2 * k2[1]),
                  free_fall.forward_dynamics(qq + h / 2 * k2[0], uu + h / 2 * k2[1], zero))
            k4 = (free_fall.q_dot(qq + h * k3[0], uu + h * k3[1]),
                  free_fall.forward_dynamics(qq + h * k3[0], uu + h * k3[1], zero))
            qq = qq + h / 6 * (k1[0] + 2 * k2[0] + 2 * k3[0] + k4[0])
            uu = uu + h / 6 * (k1[1] + 2 * k2[1] + 2 * k3[1] + k4[1])
        drifts.append(abs(energy(qq, uu) - e0) / e0)
    assert drifts[0] / drifts[1] > 12.0, drifts
