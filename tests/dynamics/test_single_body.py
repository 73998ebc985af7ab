"""The single-free-rigid-body fast path (dynamics/single_body.py) against the general recursion.

Reference: the engine's general articulated-body kernels (dynamics/kernels.py), themselves verified against
Pinocchio (test_against_pinocchio.py). Same inputs to both: random mass properties, inboard frame, node
frames, node forces, gravity and state. Tolerance 1e-12 relative to each output's scale: both are a few
hundred floating-point operations apart (different association of the same sums). The exception is the
velocity-product bias at orbital speed: both leave out ``v x (m v)`` (exactly zero; kernels.rigid_bias_add),
checked separately below.
"""

from __future__ import annotations

import numpy as np
import pytest

from dynamics import Multibody
from dynamics import engine as E
from dynamics import kernels as K
from dynamics import single_body as SB
from dynamics.samples import _random_inertia, _random_rotation


def _single_body(seed, inboard=True, gravity=(0.0, 0.0, -9.81), nodes=4):
    rng = np.random.default_rng(seed)
    mb = Multibody(gravity=gravity)
    mass = rng.uniform(0.5, 800.0)
    mb.add_body("bus", None, mass=mass, com=rng.uniform(-0.3, 0.3, 3), inertia=_random_inertia(rng, mass),
                hinge="free", inboard_position=rng.uniform(-0.5, 0.5, 3) if inboard else (0, 0, 0),
                inboard_rotation=_random_rotation(rng) if inboard else None)
    for k in range(nodes):
        mb.add_node(f"n{k}", "bus", position=rng.uniform(-2, 2, 3), rotation=_random_rotation(rng))
    return mb.compile(), rng


def _state(system, rng, speed=1.0):
    q = np.zeros(system.nq)
    quat = rng.standard_normal(4)
    q[:4] = quat / np.linalg.norm(quat)
    q[4:7] = rng.uniform(-5, 5, 3)
    u = np.concatenate([rng.uniform(-1, 1, 3), speed * rng.uniform(-1, 1, 3)])
    return q, u


def _general(system, q, u, tau, node_forces):
    s = system.copy()
    udot, tau_out = np.zeros(system.nu), np.zeros(system.nu)
    status = K.forward_dynamics(s.topology, s.nodes, s.joint_rot, s.joint_vec, s.params, q, u, tau, node_forces,
                                np.zeros((1, 6)), udot, tau_out, s.ws_rot, s.ws_vec, s.ws_mat, s.pool)
    out = [np.zeros((s.nnodes, 3, 3)), np.zeros((s.nnodes, 3)), np.zeros((s.nnodes, 6)), np.zeros((s.nnodes, 6))]
    K.node_kinematics_after_dynamics(s.topology, s.nodes, s.joint_rot, s.joint_vec, s.params, q, u, udot, *out,
                                     s.ws_rot, s.ws_vec, s.ws_mat, s.pool)
    plain = [np.zeros((s.nnodes, 3, 3)), np.zeros((s.nnodes, 3)), np.zeros((s.nnodes, 6)), np.zeros((s.nnodes, 6))]
    K.node_kinematics(s.topology, s.nodes, s.joint_rot, s.joint_vec, s.params, q, u, udot, *plain, s.ws_rot, s.ws_vec,
                      s.ws_mat, s.pool)
    return status, udot, tau_out, out, plain


def _fast(system, q, u, tau, node_forces):
    d = E.engine_data(system.copy())
    udot, tau_out = np.zeros(system.nu), np.zeros(system.nu)
    status = E.forward_dynamics(d, q, u, tau, node_forces, udot, tau_out)
    out = [np.zeros((system.nnodes, 3, 3)), np.zeros((system.nnodes, 3)), np.zeros((system.nnodes, 6)),
           np.zeros((system.nnodes, 6))]
    E.node_kinematics_after_dynamics(d, q, u, udot, *out)
    plain = [np.zeros_like(a) for a in out]
    E.node_kinematics(d, q, u, udot, *plain)
    return status, udot, tau_out, out, plain


def _close(a, b, what):
    scale = max(1.0, float(np.max(np.abs(b))))
    assert np.max(np.abs(a - b)) <= 1e-12 * scale, (what, np.max(np.abs(a - b)) / scale)


@pytest.mark.parametrize("seed", range(12))
def test_fast_path_equals_the_general_recursion(seed):
    system, rng = _single_body(seed, inboard=seed % 2 == 0, gravity=(0.0, 0.0, -9.81) if seed % 3 else (0, 0, 0))
    assert SB.applies(system.topology)
    q, u = _state(system, rng)
    tau = rng.standard_normal(6) * 10.0
    node_forces = rng.standard_normal((system.nnodes, 6)) * 5.0
    node_forces[1] = 0.0                       # a node without force (skipped by both)
    g_status, g_udot, g_tau, g_after, g_plain = _general(system, q, u, tau, node_forces)
    f_status, f_udot, f_tau, f_after, f_plain = _fast(system, q, u, tau, node_forces)
    assert g_status == f_status == 0
    _close(f_udot, g_udot, "udot")
    np.testing.assert_array_equal(f_tau, g_tau)
    for name, a, b in zip(("rotation", "position", "velocity", "acceleration"), f_after, g_after):
        _close(a, b, "after dynamics: " + name)
    for name, a, b in zip(("rotation", "position", "velocity", "acceleration"), f_plain, g_plain):
        _close(a, b, "node kinematics: " + name)


def test_general_systems_do_not_take_the_fast_path():
    from tests.dynamics.random_models import random_multibody

    for hinge in ("revolute", "spherical", "free"):
        system = random_multibody(2, 3, root_hinge=hinge).compile()
        assert not SB.applies(system.topology)
    system = random_multibody(1, 3, root_hinge="spherical").compile()
    assert not SB.applies(system.topology)
    system = random_multibody(1, 3, root_hinge="free", offsets=True).compile()
    assert not SB.applies(system.topology)      # an outboard frame off the body frame: general path
    system = random_multibody(1, 3, root_hinge="free", offsets=False).compile()
    assert SB.applies(system.topology)


def test_orbital_speed_leaves_no_round_off_torque():
    """A torque-free body translating at 7 km/s without rotation: the angular acceleration is zero
    exactly (no ``v x (m v)`` round-off), on the fast path and on the general one (which, before the bias
was split, gave up to 1e-8 rad/s^2 here)."""
    for seed in range(5):
        system, rng = _single_body(seed, inboard=False, gravity=(0.0, 0.0, 0.0))
        q, u = _state(system, rng)
        u[:3] = 0.0
        u[3:] = np.array([523.5002958381789, -6199.411244131906, 1107.5161649914692]) * (1 + seed)
        status, udot, _, _, _ = _fast(system, q, u, np.zeros(6), np.zeros((system.nnodes, 6)))
        assert status == 0
        assert np.all(udot == 0.0), udot
        g_status, g_udot, *_ = _general(system, q, u, np.zeros(6), np.zeros((system.nnodes, 6)))
        assert np.all(g_udot == 0.0), g_udot


def test_singular_inertia_is_reported_as_body_zero():
    system, rng = _single_body(1, inboard=False)
    system = system.copy(mass_properties=True)    # its own mass properties, unfrozen as set_mass_properties does
    system.params.setflags(write=True)
    o = system.topology[0, K.INERTIA]
    system.params[o:o + 36] = 0.0
    q, u = _state(system, rng)
    d = E.engine_data(system)
    udot = np.zeros(6)
    assert E.forward_dynamics(d, q, u, np.zeros(6), np.zeros((system.nnodes, 6)), udot, np.zeros(6)) == 1
    assert np.all(np.isnan(udot))
