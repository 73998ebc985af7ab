"""The rigid engine against Pinocchio (an independent C++ implementation of the same dynamics).

Tolerance: 1e-10 relative (issue 2). Both codes evaluate the same recursions in float64, so they agree
to roughly N * eps * (condition of the recursion); the worst case seen here (200-body chains) is ~1e-13.
Inverse dynamics and the mass matrix are compared for the *same* input accelerations, so ill-conditioning
of the forward problem does not enter them.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from dynamics import Multibody
from dynamics.samples import random_urdf

from .pinocchio_reference import pinocchio_from_builder, pinocchio_from_urdf, random_state
from .random_models import random_multibody

REL_TOL = 1e-10


def rel_err(a, b):
    return np.linalg.norm(a - b) / max(np.linalg.norm(b), 1e-300)


def compare_dynamics(system, model, cmap, seed, n_states=3, forward_reference="aba"):
    """``forward_reference="dense"`` compares the forward dynamics with Pinocchio's
    ``crba`` / ``nonLinearEffects`` solution instead of its ``aba`` (see the spherical-chain test)."""
    data = model.createData()
    rng = np.random.default_rng(seed)
    for _ in range(n_states):
        q, u, tau = random_state(system, rng)
        qp, vp, taup = cmap.q_to_pin(q), cmap.v_to_pin(u), cmap.v_to_pin(tau)
        udot = system.forward_dynamics(q, u, tau)
        if forward_reference == "aba":
            udot_pin = cmap.v_from_pin(pin.aba(model, data, qp, vp, taup))
        else:
            M_pin = pin.crba(model, data, qp)
            M_pin = np.triu(M_pin) + np.triu(M_pin, 1).T
            udot_pin = cmap.v_from_pin(np.linalg.solve(M_pin, taup - pin.nonLinearEffects(model, data, qp, vp)))
        assert rel_err(udot, udot_pin) < REL_TOL, "forward dynamics"
        a = rng.standard_normal(system.nu)
        tau_id = system.inverse_dynamics(q, u, a)
        tau_pin = cmap.v_from_pin(pin.rnea(model, data, qp, vp, cmap.v_to_pin(a)))
        assert rel_err(tau_id, tau_pin) < REL_TOL, "inverse dynamics"
        M = system.mass_matrix(q)
        M_pin = pin.crba(model, data, qp)
        M_pin = np.triu(M_pin) + np.triu(M_pin, 1).T
        assert rel_err(M, cmap.matrix_from_pin(M_pin)) < REL_TOL, "mass matrix"


@pytest.mark.parametrize("topology", ["chain", "tree"])
@pytest.mark.parametrize("n", [1, 2, 7, 30, 200])
@pytest.mark.parametrize("floating_base", [False, True])
def test_random_urdf_matches_pinocchio(tmp_path, topology, n, floating_base):
    path = tmp_path / "robot.urdf"
    path.write_text(random_urdf(n, topology=topology, seed=1000 * n + len(topology),
                                fixed_fraction=0.2 if topology == "tree" else 0.0))
    system = Multibody.from_urdf(path, floating_base=floating_base).compile()
    model, cmap = pinocchio_from_urdf(system, path, floating_base)
    assert system.nu == model.nv and system.nq == model.nq
    compare_dynamics(system, model, cmap, seed=n)


@pytest.mark.parametrize("seed", range(4))
def test_every_hinge_type_with_frame_offsets_matches_pinocchio(seed):
    """Spherical, U-joint and free hinges anywhere in a branched tree, with outboard frame offsets."""
    mb = random_multibody(12, seed=seed, root_hinge="free")
    system = mb.compile()
    model, cmap = pinocchio_from_builder(mb, system)
    compare_dynamics(system, model, cmap, seed=seed)


def test_long_chain_of_spherical_and_ujoints_matches_pinocchio():
    """A 60-body chain of spherical and U-joints (150 DOFs, mass-matrix condition ~1e6).

    Pinocchio 4.1's ``aba`` drifts from its own ``crba``/``rnea`` solution on long spherical chains
    (relative difference 2e-11 at 20 bodies, 3e-7 at 40, 3e-2 at 60, measured 2026-11-21), while
    flexshell's ABA stays within 3e-12 of it, so here the forward dynamics is checked against
    Pinocchio's dense solution; inverse dynamics and mass matrix are compared directly as everywhere.
    """
    mb = random_multibody(60, seed=7, hinges=("spherical", "ujoint"), branched=False)
    system = mb.compile()
    model, cmap = pinocchio_from_builder(mb, system)
    compare_dynamics(system, model, cmap, seed=7, n_states=2, forward_reference="dense")


def test_node_kinematics_match_pinocchio_frames(tmp_path):
    """Nodes made from welded URDF links against Pinocchio's frames: placement, velocity and classical
    acceleration in the local frame (pin.LOCAL)."""
    path = tmp_path / "robot.urdf"
    path.write_text(random_urdf(25, topology="tree", seed=3, fixed_fraction=0.5))
    system = Multibody.from_urdf(path, floating_base=True).compile()
    assert system.nnodes > 5
    model, cmap = pinocchio_from_urdf(system, path, True)
    data = model.createData()
    rng = np.random.default_rng(0)
    q, u, udot = random_state(system, rng)
    qp, vp, ap = cmap.q_to_pin(q), cmap.v_to_pin(u), cmap.v_to_pin(udot)
    pin.forwardKinematics(model, data, qp, vp, ap)
    pin.updateFramePlacements(model, data)
    kin = system.node_kinematics(q, u, udot)
    for n, name in enumerate(system.node_names):
        fid = model.getFrameId(name, pin.BODY)
        placement = data.oMf[fid]
        np.testing.assert_allclose(kin.rotation[n], placement.rotation, atol=1e-12)
        np.testing.assert_allclose(kin.position[n], placement.translation, atol=1e-12)
        v = pin.getFrameVelocity(model, data, fid, pin.LOCAL)
        np.testing.assert_allclose(kin.angular_velocity[n], v.angular, atol=1e-11)
        np.testing.assert_allclose(kin.linear_velocity[n], v.linear, atol=1e-11)
        a = pin.getFrameClassicalAcceleration(model, data, fid, pin.LOCAL)
        np.testing.assert_allclose(kin.angular_acceleration[n], a.angular, atol=1e-10)
        np.testing.assert_allclose(kin.linear_acceleration[n], a.linear, atol=1e-10)


def test_energy_and_momentum_match_pinocchio(tmp_path):
    mb = random_multibody(15, seed=11, root_hinge="free")
    system = mb.compile()
    model, cmap = pinocchio_from_builder(mb, system)
    data = model.createData()
    rng = np.random.default_rng(5)
    q, u, _ = random_state(system, rng)
    qp, vp = cmap.q_to_pin(q), cmap.v_to_pin(u)
    ke = pin.computeKineticEnergy(model, data, qp, vp)
    pe = pin.computePotentialEnergy(model, data, qp)
    assert abs(system.kinetic_energy(q, u) - ke) < 1e-12 * abs(ke)
    assert abs(system.potential_energy(q) - pe) < 1e-12 * max(abs(pe), 1.0)
    # centroidal momentum (about the COM, world axes) moved to the world origin
    h = pin.computeCentroidalMomentum(model, data, qp, vp)
    com = pin.centerOfMass(model, data, qp)
    P = h.linear
    L = h.angular + np.cross(com, P)
    np.testing.assert_allclose(system.linear_momentum(q, u), P, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(system.angular_momentum(q, u), L, rtol=1e-12, atol=1e-12)
