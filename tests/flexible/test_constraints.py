"""Closure constraints (dynamics.constraints) against analytic kinematics, conservation laws and the
equivalent prescribed motion of tree models (FModal paper, "Closure Constraints": cantilever by a
locked hinge vs by a closure on a free body, ball joint vs ball closure).

* a planar four-bar linkage (crank-rocker, gravity) cut at the coupler-rocker pin: its accelerations
  equal the hand-built one-DOF Lagrange equation; the rocker angle follows the analytic loop-closure
  solution for the simulated crank angle, the energy is conserved, and the drift figures with and
  without stabilization and projection are as documented in docs/closure_constraints.md;
* constraint forces: the tree's inverse dynamics with the reactions applied as node forces returns the
  applied generalized forces; a weld to the world equals a free hinge whose six DOFs are prescribed at
  zero acceleration (accelerations and the hinge wrench), for a rigid chain and for a flexible body
  whose modes vanish at the welded node; a ball closure equals a spherical hinge.
"""

from __future__ import annotations

import numpy as np
import pytest

from dynamics import Multibody
from dynamics.constraints import ClosureConstraint, ConstrainedSystem, ConstraintError

from tests.dynamics.mechanisms import COUPLER, CRANK, ROCKER, four_bar, four_bar_state, rk4_step, rocker_angle

from .random_flexible import flexible_body_data, random_node_model

assembled_state = four_bar_state  # tree coordinates on the loop (upper branch) with the crank rate given


def simulate(cs, t_final, h, project):
    q, u = assembled_state(np.radians(60.0), 2.0)
    q, u = cs.project(q, u)
    y = np.concatenate([q, u])
    e0 = cs.energy(q, u)
    worst_phi = worst_energy = worst_angle = 0.0
    for _ in range(int(round(t_final / h))):
        y = rk4_step(cs.rates, y, h)
        if project:
            q, u = cs.project(y[:3], y[3:])
            y = np.concatenate([q, u])
        q, u = y[:3], y[3:]
        worst_phi = max(worst_phi, np.abs(cs.residual(q)).max())
        worst_energy = max(worst_energy, abs(cs.energy(q, u) - e0) / abs(e0))
        worst_angle = max(worst_angle, abs(np.angle(np.exp(1j * (q[2] - rocker_angle(q[0])[0])))))
    return worst_phi, worst_energy, worst_angle


def test_four_bar_assembly_is_consistent_and_redundancy_handled():
    cs = four_bar()
    q, u = assembled_state(np.radians(60.0), 2.0)
    assert np.abs(cs.residual(q)).max() < 1e-14
    G = cs.jacobian(q)
    assert G.shape == (5, 3) and np.linalg.matrix_rank(G, tol=1e-10) == 2  # planar loop: 3 rows redundant
    q2, u2 = cs.project(q, u)
    assert np.abs(cs.velocity_residual(q2, u2)).max() < 1e-13
    assert len(cs.null_space(q2).T) == 1  # one degree of freedom
    acc = cs.forward_dynamics(q2, u2)
    # acceleration-level constraint G u_dot + k = 0 holds exactly (no stabilization)
    h = 1e-6
    vel = [cs.velocity_residual(q2 + s * h * cs.system.q_dot(q2, u2), u2 + s * h * acc.u_dot) for s in (-1, 1)]
    assert np.abs((vel[1] - vel[0]) / (2 * h)).max() < 1e-7  # central difference, truncation ~1e-9


def test_four_bar_follows_analytic_loop_closure_and_conserves_energy():
    """RK4, h = 2 ms, 1 s, projection after every step (tolerance 1e-12): rocker angle = analytic
    closure for the simulated crank angle (measured 4.3e-13 rad), |phi| <= 1.0e-12 (the projection
    tolerance), relative energy drift 1.3e-9 (RK4 truncation; the projections remove only the
    constraint-violating part of each step's error)."""
    worst_phi, worst_energy, worst_angle = simulate(four_bar(), 1.0, 2e-3, project=True)
    assert worst_angle < 1e-11
    assert worst_phi <= 1e-12
    assert worst_energy < 1e-8


def test_four_bar_drift_without_projection():
    """Drift figures of docs/closure_constraints.md (RK4, h = 5 ms, 5 s, no projection): without
    stabilization the loop opens steadily (measured 2.7e-6 m); Baumgarte with alpha = beta = 5/s keeps
    it at 8.8e-8 m. (Over 2 s, the horizon before the compiled constraints, the free drift is now 2.9e-7 m:
    the translation rows' rate is exactly d(rho)/dt off the manifold too, so the loop opens 3x slower than
    with the former rows, and 2 s no longer separates the two.)"""
    free_drift, _, _ = simulate(four_bar(), 5.0, 5e-3, project=False)
    stabilized, _, _ = simulate(four_bar(baumgarte=(5.0, 5.0)), 5.0, 5e-3, project=False)
    assert 1e-8 < free_drift < 1e-4
    assert stabilized < 0.2 * free_drift


def reduced_four_bar_acceleration(crank_angle, crank_rate, crank_torque, g=9.81):
    """Crank acceleration from the one-DOF Lagrange equation of the four-bar built by hand:
    m(th) th'' + 1/2 m'(th) th'^2 + V'(th) = tau, with the analytic loop closure, velocity coefficients
    from the differentiated loop equation a e^(i th1) + b e^(i phi2) - c e^(i th3) - d = 0, rod kinetic
    energies (mass at the middle, I_zz about the CG), V = sum m g y_cg; m' by a central difference."""
    masses, lengths = (1.0, 2.0, 1.5), (CRANK, COUPLER, ROCKER)
    izz = [m * L ** 2 / 12 + 1e-3 for m, L in zip(masses, lengths)]

    def coefficients(th1):
        th3, Q, P = rocker_angle(th1)
        phi2 = np.arctan2(Q[1] - P[1], Q[0] - P[0])
        e = lambda x: np.array([-np.sin(x), np.cos(x)])  # d/dx of (cos x, sin x)
        A = np.column_stack([COUPLER * e(phi2), -ROCKER * e(th3)])
        k2, k3 = np.linalg.solve(A, -CRANK * e(th1))
        v_cg = [CRANK / 2 * e(th1), CRANK * e(th1) + COUPLER / 2 * k2 * e(phi2), ROCKER / 2 * k3 * e(th3)]
        rates = (1.0, k2, k3)
        m_eff = sum(m * v @ v + J * w ** 2 for m, v, J, w in zip(masses, v_cg, izz, rates))
        dV = sum(m * g * v[1] for m, v in zip(masses, v_cg))
        return m_eff, dV

    h = 1e-5
    m_eff, dV = coefficients(crank_angle)
    dm = (coefficients(crank_angle + h)[0] - coefficients(crank_angle - h)[0]) / (2 * h)
    return (crank_torque - 0.5 * dm * crank_rate ** 2 - dV) / m_eff


def test_four_bar_dynamics_equals_hand_derived_reduced_equation():
    """Constrained accelerations of the cut tree vs the hand-built one-DOF Lagrange equation (analytic
    kinematics, no engine quantities): crank acceleration agrees to 1e-8 relative (central-difference
    m'; measured <= 1.4e-10)."""
    cs = four_bar()
    rng = np.random.default_rng(12)
    for _ in range(6):
        th1, rate, torque = rng.uniform(0, 2 * np.pi), rng.uniform(-3, 3), rng.uniform(-20, 20)
        q, u = cs.project(*assembled_state(th1, rate))
        acc = cs.forward_dynamics(q, u, tau=np.array([torque, 0.0, 0.0]))
        ref = reduced_four_bar_acceleration(q[0], u[0], torque)  # projection set the other rates
        assert abs(acc.u_dot[0] - ref) < 1e-8 * max(1.0, abs(ref))


def test_reactions_reproduce_applied_forces_through_inverse_dynamics():
    """Tree inverse dynamics with the closure reactions as node forces returns the applied torques."""
    cs = four_bar()
    rng = np.random.default_rng(3)
    for _ in range(5):
        q, u = assembled_state(rng.uniform(0, 2 * np.pi), rng.uniform(-3, 3))
        q, u = cs.project(q, u)
        tau = rng.uniform(-5, 5, 3)
        acc = cs.forward_dynamics(q, u, tau=tau)
        F = cs.constraint_node_forces(q, acc.multipliers)
        np.testing.assert_allclose(cs.system.inverse_dynamics(q, u, acc.u_dot, node_forces=F), tau,
                                   rtol=0, atol=1e-11)


def _chain(base_prescribed, flexible_base=None):
    mb = Multibody(gravity=(0.0, 0.0, -9.81))
    if flexible_base is None:
        mb.add_body("base", None, mass=3.0, com=(0.1, 0.05, 0.0), inertia=[0.2, 0.3, 0.4], hinge="free",
                    prescribed=base_prescribed)
        mb.add_node("base_origin", "base")
    else:
        mb.add_flexible_body("base", None, modal=flexible_base, hinge="free", prescribed=base_prescribed)
        mb.add_node("base_origin", "base", grid=1)
        mb.add_node("base_tip", "base", grid=len(flexible_base.grid_ids))
    mb.add_body("arm", "base", mass=1.0, com=(0.4, 0, 0), inertia=[0.01, 0.05, 0.05], hinge="revolute",
                axis=(0.0, 1.0, 0.0), inboard_position=(0.3, 0.1, 0.2), parent_node=None
                if flexible_base is None else "base_tip")
    return mb.compile()


def _clamped_modes():
    """A random flexible body whose node 1 sits at the body origin and does not deform."""
    model = random_node_model(6, 3, seed=11, scale=0.2)
    model.position[0] = 0.0
    model.shapes[0] = 0.0
    return flexible_body_data(model, 2)


@pytest.mark.parametrize("flexible", [False, True])
def test_weld_to_world_equals_prescribed_free_hinge(flexible):
    """Welding the base's (non-deforming) node to the world gives the accelerations and, as multipliers,
    the hinge wrench of the same base held by a free hinge prescribed at zero acceleration
    (-lambda: lambda is the base's wrench on the world). Measured agreement, relative to the largest
    hinge force: 7e-16 / 2e-15 (rigid), 5e-16 / 2.6e-15 (flexible base with order-2 modal integrals,
    arm on its deforming tip)."""
    base = _clamped_modes() if flexible else None
    held = _chain(True, base)
    free = _chain(False, base)
    rng = np.random.default_rng(5)
    quat = rng.standard_normal(4)
    q = held.neutral_configuration()
    q[:4] = quat / np.linalg.norm(quat)
    q[4:7] = [0.3, -0.2, 1.0]
    q[7:] = rng.uniform(-0.3, 0.3, held.nq - 7)
    u = np.zeros(held.nu)
    u[6:] = rng.uniform(-1, 1, held.nu - 6)
    cs = ConstrainedSystem(free, [ClosureConstraint("base_origin", None, "weld")], q_reference=q)
    u_dot_ref, forces = held.forward_dynamics(q, u, return_forces=True)
    acc = cs.forward_dynamics(q, u)
    scale = max(1.0, np.abs(forces).max())
    np.testing.assert_allclose(acc.u_dot, u_dot_ref, rtol=0, atol=1e-12 * scale)
    np.testing.assert_allclose(-acc.multipliers[0], forces[:6], rtol=0, atol=1e-12 * scale)


@pytest.mark.parametrize("flexible", [False, True])
def test_ball_closure_equals_spherical_hinge(flexible):
    """A pendulum on a spherical hinge vs the same body on a free hinge with a ball closure at the
    hinge point (FModal paper: cantilever with a ball joint vs free-free beam with a ball closure);
    rigid, and flexible with modes that vanish at the pivot node (accelerations agree to 1e-13)."""
    props = dict(mass=2.0, com=(0.2, 0.1, -0.5), inertia=[0.3, 0.2, 0.1])

    def build(hinge):
        mb = Multibody(gravity=(0.0, 0.0, -9.81))
        if flexible:
            mb.add_flexible_body("pendulum", None, modal=_clamped_modes(), hinge=hinge)
            mb.add_node("pivot", "pendulum", grid=1)
        else:
            mb.add_body("pendulum", None, hinge=hinge, **props)
            mb.add_node("pivot", "pendulum")
        return mb.compile()

    spherical, free = build("spherical"), build("free")
    quat = np.array([0.9, 0.2, -0.3, 0.1])
    quat /= np.linalg.norm(quat)
    n = spherical.nu - 3
    rng = np.random.default_rng(8)
    eta, eta_dot = rng.uniform(-0.2, 0.2, n), rng.uniform(-1, 1, n)
    w = np.array([0.5, -1.0, 2.0])
    cs = ConstrainedSystem(free, [ClosureConstraint("pivot", None, "ball", world_rotation=np.eye(3),
                                                    world_position=np.zeros(3))])
    acc = cs.forward_dynamics(np.concatenate([quat, np.zeros(3), eta]), np.concatenate([w, np.zeros(3), eta_dot]))
    ref = spherical.forward_dynamics(np.concatenate([quat, eta]), np.concatenate([w, eta_dot]))
    np.testing.assert_allclose(acc.u_dot[:3], ref[:3], rtol=0, atol=1e-13)
    np.testing.assert_allclose(acc.u_dot[3:6], 0.0, atol=1e-13)
    np.testing.assert_allclose(acc.u_dot[6:], ref[3:], rtol=0, atol=1e-12)


def test_flexible_body_hung_at_two_deforming_nodes_conserves_energy():
    """A flexible body (order-2 modal integrals, undamped) on a free hinge held in the world by ball
    closures at two nodes that deform, under gravity, started swinging with modal velocity: RK4
    (h = 1 ms, 0.5 s) with projection keeps |phi| <= 1e-12 and the energy to 2e-9 relative (measured 5.0e-11).

    Point-mass nodes: with CG offsets or rotational inertia at the nodes the engine's gravity forces on
    a flexible body are not the gradient of its potential energy (about 1e-4 J in 0.1 s for this model
    free in space; reported to the engine's owner), which would mask the closure's own behaviour."""
    model = random_node_model(6, 3, seed=21, scale=0.2, point_masses=True)
    model.damping[:] = 0.0
    mb = Multibody(gravity=(0.0, 0.0, -9.81))
    mb.add_flexible_body("panel", None, modal=flexible_body_data(model, 2), hinge="free")
    mb.add_node("left", "panel", grid=1)
    mb.add_node("right", "panel", grid=6)
    system = mb.compile()
    q0 = system.neutral_configuration()
    cs = ConstrainedSystem(system, [ClosureConstraint("left", None, "ball"), ClosureConstraint("right", None, "ball")],
                           q_reference=q0)
    u0 = np.zeros(system.nu)
    u0[:3] = 0.3 * (model.position[5] - model.position[0])  # swing about the line through the two holds
    u0[6:] = [0.5, -0.4, 0.3]
    q, u = cs.project(q0, u0)
    assert np.linalg.matrix_rank(cs.jacobian(q)) == 6 and np.abs(u).max() > 0.1
    y = np.concatenate([q, u])
    e0 = cs.energy(q, u)
    worst_phi = worst_energy = 0.0
    for _ in range(500):
        y = rk4_step(cs.rates, y, 1e-3)
        q, u = cs.project(y[:system.nq], y[system.nq:])
        y = np.concatenate([q, u])
        worst_phi = max(worst_phi, np.abs(cs.residual(q)).max())
        worst_energy = max(worst_energy, abs(cs.energy(q, u) - e0) / abs(e0))
    assert worst_phi <= 1e-12
    assert worst_energy < 2e-9


def test_projection_removes_position_and_velocity_drift():
    cs = four_bar()
    q, u = assembled_state(np.radians(60.0), 2.0)
    q_bad = q + np.array([0.0, 0.02, -0.03])
    q2, u2 = cs.project(q_bad, u + 0.1)
    assert np.abs(cs.residual(q2)).max() < 1e-12
    assert np.abs(cs.velocity_residual(q2, u2)).max() < 1e-12
    assert abs(q2[2] - rocker_angle(q2[0])[0]) < 1e-11


def test_bad_constraints_refused():
    cs = four_bar()
    with pytest.raises(ConstraintError, match="unknown node 'nope'"):
        ConstrainedSystem(cs.system, [ClosureConstraint("nope", "rocker_tip", "ball")])
    with pytest.raises(ConstraintError, match="unknown kind"):
        ClosureConstraint("coupler_tip", "rocker_tip", "glue")
    with pytest.raises(ConstraintError, match="needs an axis"):
        ClosureConstraint("coupler_tip", "rocker_tip", "revolute")
    with pytest.raises(ConstraintError, match="q_reference"):
        ConstrainedSystem(cs.system, [ClosureConstraint("coupler_tip", None, "weld")])
    with pytest.raises(ConstraintError, match="a prismatic closure needs an axis"):
        ClosureConstraint("coupler_tip", "rocker_tip", "prismatic")
    with pytest.raises(ConstraintError, match="only distance constraints take a length"):
        ClosureConstraint("coupler_tip", "rocker_tip", "ball", length=1.0)
    with pytest.raises(ConstraintError, match="length must be positive"):
        ClosureConstraint("coupler_tip", "rocker_tip", "distance", length=0.0)
    mb = Multibody()
    mb.add_body("plate", None, mass=1.0, inertia=[0.1, 0.1, 0.1], hinge="free")
    mb.add_node("corner1", "plate", position=(1, 0, 0))
    mb.add_node("corner2", "plate", position=(0, 1, 0))
    with pytest.raises(ConstraintError, match="both on the rigid body 'plate'"):
        ConstrainedSystem(mb.compile(), [ClosureConstraint("corner1", "corner2", "ball")])
    pin = ClosureConstraint("coupler_tip", "rocker_tip", "ball", name="pin")
    with pytest.raises(ConstraintError, match="'pin': duplicate name"):
        ConstrainedSystem(cs.system, [pin, pin])
    with pytest.raises(ConstraintError, match="unknown constraint 'pn'.*Did you mean 'pin'"):
        ConstrainedSystem(cs.system, [pin]).switch_on("pn", *assembled_state(1.0, 0.0))


def test_assembly_projects_a_near_state_says_how_far_and_refuses_a_far_one():
    """A state 1e-7 off the loop is projected (the report gives the residual, the constraint, how far q moved);
    one 0.03 rad off is refused, naming the constraint and the tolerance."""
    cs = four_bar()
    q, u = assembled_state(np.radians(60.0), 2.0)
    q_near = q + np.array([0.0, 1e-7, 0.0])
    q1, u1, report = cs.assemble(q_near, u)
    assert report.worst == "pin" and 5e-8 < report.residual < 5e-7 and 1e-8 < report.moved < 1e-6
    assert np.abs(cs.residual(q1)).max() < 1e-12 and np.abs(cs.velocity_residual(q1, u1)).max() < 1e-12
    assert report.energy_lost > 0.0  # the crank's rate alone violates the loop: the projection removes energy
    with pytest.raises(ConstraintError, match=r"constraint 'pin' is violated by 0.0[0-9]* .*tolerance 1e-06"):
        cs.assemble(q + np.array([0.0, 0.03, 0.0]), u)
    q2, _, report = cs.assemble(q + np.array([0.0, 0.03, 0.0]), u, tolerance=0.1)
    assert abs(q2[2] - rocker_angle(q2[0])[0]) < 1e-11 and report.moved > 0.01
