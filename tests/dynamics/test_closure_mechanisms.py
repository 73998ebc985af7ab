"""Closed-chain mechanisms through the compiled constraints against independent solutions.

* a planar four-bar under gravity and a slider-crank (prismatic closure), over several crank revolutions,
  against the absolute-coordinate DAE of tests/dynamics/planar_dae.py (another formulation: centre-of-mass
  coordinates, joints as algebraic equations): crank angle to 1e-6 rad (measured 8.7e-10 and 1.4e-9 rad at
  DOP853 tolerances 1e-10; 3e-11 at 1e-12);
* Andrews' squeezing mechanism (Hairer and Wanner's benchmark): the initial accelerations against the test
  set's consistent initial values, the angles at t = 0.03 s against its published reference solution (measured
  1.6e-9 rad);
* the linearized four-bar: its small-oscillation frequency about the hanging equilibrium on the constraint
  manifold (minimal coordinates) against the one-DOF Lagrange equation built by hand, with no spurious modes.
"""

from __future__ import annotations

import numpy as np
from scipy.integrate import solve_ivp
from scipy.optimize import brentq

from dynamics.constraints import restrict

from .mechanisms import (ANDREWS, ANDREWS_ORDER, ANDREWS_REFERENCE, ANDREWS_Y0, COUPLER, CRANK, FOUR_BAR_MASSES,
                         GROUND, ROCKER, ROD_LENGTH, SLIDER_MASS, andrews, andrews_q, four_bar, four_bar_state,
                         rocker_angle, slider_crank)
from .planar_dae import PlanarMechanism

TIGHT = dict(method="DOP853", rtol=1e-10, atol=1e-10)


def e(theta):
    return np.array([np.cos(theta), np.sin(theta)])


def e_rate(theta):
    return np.array([-np.sin(theta), np.cos(theta)])


def izz(length, mass):
    return mass * length ** 2 / 12 + 1e-3


def four_bar_dae():
    """Crank, coupler, rocker as three free bodies pinned to each other and to the ground."""
    m1, m2, m3 = FOUR_BAR_MASSES
    mech = PlanarMechanism([(m1, izz(CRANK, m1)), (m2, izz(COUPLER, m2)), (m3, izz(ROCKER, m3))], gravity=(0, -9.81))
    mech.revolute(0, (-CRANK / 2, 0.0), None, (0.0, 0.0))
    mech.revolute(0, (CRANK / 2, 0.0), 1, (-COUPLER / 2, 0.0))
    mech.revolute(1, (COUPLER / 2, 0.0), 2, (ROCKER / 2, 0.0))
    mech.revolute(2, (-ROCKER / 2, 0.0), None, (GROUND, 0.0))
    return mech


def four_bar_absolute(q, u):
    """Absolute coordinates (centres of mass, angles) and their rates of the engine's tree coordinates."""
    th1, th2, th3 = q[0], q[0] + q[1], q[2]
    w1, w2, w3 = u[0], u[0] + u[1], u[2]
    r1, v1 = CRANK / 2 * e(th1), CRANK / 2 * w1 * e_rate(th1)
    r2 = CRANK * e(th1) + COUPLER / 2 * e(th2)
    v2 = CRANK * w1 * e_rate(th1) + COUPLER / 2 * w2 * e_rate(th2)
    r3, v3 = np.array([GROUND, 0.0]) + ROCKER / 2 * e(th3), ROCKER / 2 * w3 * e_rate(th3)
    return (np.concatenate([r1, [th1], r2, [th2], r3, [th3]]), np.concatenate([v1, [w1], v2, [w2], v3, [w3]]))


def test_four_bar_under_gravity_equals_the_absolute_coordinate_dae_over_several_revolutions():
    """Crank at 60 deg and 6 rad/s: it turns through 3.7 revolutions in 2 s under gravity. Both formulations
    integrated by DOP853 at 1e-10 (the engine with mild Baumgarte 1/s against drift, the DAE with 10/s):
    crank angle, coupler angle and rocker angle agree to 1e-6 rad (measured 8.7e-10 rad; 3.5e-11 rad over 4 s at
    1e-12); the engine keeps the loop closed to 1e-9 m."""
    cs = four_bar(baumgarte=(1.0, 1.0))
    q0, u0 = cs.project(*four_bar_state(np.radians(60.0), 6.0))
    z0, zd0 = four_bar_absolute(q0, u0)
    times = np.linspace(0.0, 2.0, 41)
    engine = solve_ivp(cs.rates, (0.0, 2.0), np.concatenate([q0, u0]), t_eval=times, **TIGHT)
    dae = solve_ivp(four_bar_dae().rates, (0.0, 2.0), np.concatenate([z0, zd0]), t_eval=times, **TIGHT)
    q = engine.y[:3]
    angles = np.vstack([q[0], q[0] + q[1], q[2]])
    assert np.abs(angles - dae.y[[2, 5, 8]]).max() < 1e-6
    assert q[0, -1] - q[0, 0] > 3 * 2 * np.pi  # a large motion: the crank turned more than three times
    assert max(np.abs(cs.residual(q[:, k])).max() for k in range(len(times))) < 1e-9


def slider_crank_dae():
    mech = PlanarMechanism([(1.0, izz(CRANK, 1.0)), (2.0, izz(ROD_LENGTH, 2.0)), (SLIDER_MASS, 0.03)],
                           gravity=(0, -9.81))
    mech.revolute(0, (-CRANK / 2, 0.0), None, (0.0, 0.0))
    mech.revolute(0, (CRANK / 2, 0.0), 1, (-ROD_LENGTH / 2, 0.0))
    mech.revolute(1, (ROD_LENGTH / 2, 0.0), 2, (0.0, 0.0))
    mech.translational(2, (0.0, 0.0), (0.0, 0.0), (1.0, 0.0), 0.0)
    return mech


def test_slider_crank_with_a_prismatic_closure_equals_the_absolute_coordinate_dae():
    """Crank at 60 deg, 5 rad/s, gravity along -y, 3 s (the crank turns 1.8 times): crank angle and slider
    position against the DAE to 1e-6 (measured 1.4e-9 rad, 7.1e-10 m; 2.6e-11 rad, 1.1e-11 m over 4 s at
    1e-12); the slider keeps its angle and stays on the axis (prismatic residual < 1e-9)."""
    cs, q_start = slider_crank(baumgarte=(1.0, 1.0))
    q0, u0 = cs.project(q_start, np.array([5.0, 0.0, 0.0]))
    th1, th2 = q0[0], q0[0] + q0[1]
    w1, w2 = u0[0], u0[0] + u0[1]
    z0 = np.concatenate([CRANK / 2 * e(th1), [th1], CRANK * e(th1) + ROD_LENGTH / 2 * e(th2), [th2],
                         CRANK * e(th1) + ROD_LENGTH * e(th2), [th2 + q0[2]]])
    zd0 = np.concatenate([CRANK / 2 * w1 * e_rate(th1), [w1],
                          CRANK * w1 * e_rate(th1) + ROD_LENGTH / 2 * w2 * e_rate(th2), [w2],
                          CRANK * w1 * e_rate(th1) + ROD_LENGTH * w2 * e_rate(th2), [w2 + u0[2]]])
    times = np.linspace(0.0, 3.0, 61)
    engine = solve_ivp(cs.rates, (0.0, 3.0), np.concatenate([q0, u0]), t_eval=times, **TIGHT)
    dae = solve_ivp(slider_crank_dae().rates, (0.0, 3.0), np.concatenate([z0, zd0]), t_eval=times, **TIGHT)
    q = engine.y[:3]
    assert np.abs(q[0] - dae.y[2]).max() < 1e-6
    slider_x = CRANK * np.cos(q[0]) + ROD_LENGTH * np.cos(q[0] + q[1])
    assert np.abs(slider_x - dae.y[6]).max() < 1e-6
    assert q[0, -1] - q[0, 0] > 1.5 * 2 * np.pi
    assert max(np.abs(cs.residual(q[:, k])).max() for k in range(len(times))) < 1e-9


def test_andrews_squeezing_mechanism_against_the_published_reference():
    """Hairer and Wanner's seven-body mechanism: the engine's accelerations at the consistent initial state
    equal the test set's initial values (beta'' = 14222.44..., Theta'' = -10666.83..., the others 0) to 1e-9
    relative, the force of the first closure has the test set's magnitude |lambda_1, lambda_2| (the engine
    reports it in K2's axes), and DOP853 at 1e-10 reaches the published angles at t = 0.03 s to 1e-8 rad
    (measured 1.6e-9 rad; beta has turned 2.5 revolutions)."""
    cs = andrews()
    q0 = andrews_q(ANDREWS_Y0)
    tau = np.zeros(7)
    tau[0] = ANDREWS["mom"]
    assert np.abs(cs.residual(q0)).max() < 1e-16
    acc = cs.forward_dynamics(q0, np.zeros(7), tau=tau)
    initial = np.array([14222.4439199541138705911625887, -10666.8329399655854029433719415, 0, 0, 0, 0, 0])
    np.testing.assert_allclose(acc.u_dot[list(ANDREWS_ORDER)], initial, rtol=0, atol=1e-9 * 14222.44)
    np.testing.assert_allclose(np.linalg.norm(acc.loads[0, 3:]),
                               np.hypot(98.5668703962410896057654982170, -6.12268834425566265503114393122),
                               rtol=1e-10)
    sol = solve_ivp(lambda t, y: cs.rates(t, y, tau), (0.0, 0.03), np.concatenate([q0, np.zeros(7)]),
                    method="DOP853", rtol=1e-10, atol=1e-10)
    q = sol.y[:7, -1]
    assert np.abs(q[list(ANDREWS_ORDER)] - np.array(ANDREWS_REFERENCE)).max() < 1e-8


def four_bar_one_dof(theta1, g=9.81):
    """(m_eff, dV/dtheta1) of the four-bar reduced to its crank angle by hand: analytic loop closure, velocity
    coefficients from the differentiated loop equation, rod kinetic energies, V = sum m g y_cg."""
    lengths = (CRANK, COUPLER, ROCKER)
    inertia = [izz(L, m) for m, L in zip(FOUR_BAR_MASSES, lengths)]
    th3, Q, P = rocker_angle(theta1)
    phi2 = np.arctan2(Q[1] - P[1], Q[0] - P[0])
    A = np.column_stack([COUPLER * e_rate(phi2), -ROCKER * e_rate(th3)])
    k2, k3 = np.linalg.solve(A, -CRANK * e_rate(theta1))
    v_cg = [CRANK / 2 * e_rate(theta1), CRANK * e_rate(theta1) + COUPLER / 2 * k2 * e_rate(phi2),
            ROCKER / 2 * k3 * e_rate(th3)]
    rates = (1.0, k2, k3)
    m_eff = sum(m * v @ v + J * w ** 2 for m, v, J, w in zip(FOUR_BAR_MASSES, v_cg, inertia, rates))
    dV = sum(m * g * v[1] for m, v in zip(FOUR_BAR_MASSES, v_cg))
    return m_eff, dV


def test_linearized_four_bar_frequency_on_the_constraint_manifold():
    """About its hanging equilibrium the four-bar oscillates at omega^2 = V''/m_eff (one-DOF Lagrange equation,
    V'' by a central difference of the hand-built dV). The engine's state (3 angles + 3 rates) linearized by
    central differences has, besides the pendulum pair, four eigenvalues at zero (the constraint directions
    of positions and of velocities: a planar loop removes two DOFs of three); restricted to the manifold's tangent
    space (2 states) it keeps only the pair, at the frequency of the one-DOF equation to 1e-6 relative (finite
    differences)."""
    thetas = np.linspace(0.0, 2 * np.pi, 73)
    dv = [four_bar_one_dof(t)[1] for t in thetas]
    roots = [brentq(lambda t: four_bar_one_dof(t)[1], a, b) for a, b, fa, fb in
             zip(thetas[:-1], thetas[1:], dv[:-1], dv[1:]) if fa < 0 < fb]
    assert len(roots) == 1
    theta = roots[0]
    h = 1e-5
    m_eff = four_bar_one_dof(theta)[0]
    stiffness = (four_bar_one_dof(theta + h)[1] - four_bar_one_dof(theta - h)[1]) / (2 * h)
    omega_ref = np.sqrt(stiffness / m_eff)

    cs = four_bar()
    q0, u0 = cs.project(*four_bar_state(theta, 0.0))
    x0 = np.concatenate([q0, u0])
    assert np.abs(cs.rates(0.0, x0)).max() < 1e-9  # an equilibrium
    step = 1e-6
    A = np.empty((6, 6))
    for k in range(6):
        dx = np.zeros(6)
        dx[k] = step
        A[:, k] = (cs.rates(0.0, x0 + dx) - cs.rates(0.0, x0 - dx)) / (2 * step)
    full = np.linalg.eigvals(A)
    # the four spurious eigenvalues form nilpotent Jordan blocks: finite-difference noise of 1e-20 splits them
    # by its fourth root
    assert np.sum(np.abs(full) < 1e-3 * omega_ref) == 4
    V = cs.tangent_basis(q0, u0)
    assert V.shape == (6, 2)
    Ar, Br, Cr, defect = restrict(A, np.zeros((6, 1)), np.eye(6), V)
    assert defect < 1e-8
    reduced = np.linalg.eigvals(Ar)
    np.testing.assert_allclose(np.abs(reduced.imag), omega_ref, rtol=1e-6)
    assert np.abs(reduced.real).max() < 1e-6 * omega_ref


def test_minimal_linearization_at_a_moving_state_is_that_of_the_graph_chart():
    """Away from equilibrium the tangent space of the state manifold {phi = 0, G u = 0} includes the velocity
    rows' dependence on q. In the chart that writes the manifold as a graph over its tangent space,
    ``x(z) = x0 + V z + N w(z)`` (N the normal space), the reduced dynamics are ``z' = V' f(x(z))`` exactly,
    and their linearization at z = 0 is V' A V: the restricted model. Checked against central differences of
    ``V' f(x(z))`` with the manifold points found by least squares (1e-6 relative)."""
    from scipy.linalg import null_space
    from scipy.optimize import least_squares

    cs = four_bar()
    q0, u0 = cs.project(*four_bar_state(np.radians(40.0), 2.0))
    x0 = np.concatenate([q0, u0])
    V = cs.tangent_basis(q0, u0)
    N = null_space(V.T)
    assert V.shape == (6, 2) and np.linalg.norm(cs.rates(0.0, x0)) > 1.0

    def on_manifold(z):
        def residual(w):
            x = x0 + V @ z + N @ w
            return np.concatenate([cs.residual(x[:3]), cs.velocity_residual(x[:3], x[3:])])
        return x0 + V @ z + N @ least_squares(residual, np.zeros(4), xtol=1e-15, ftol=1e-15, gtol=1e-15).x

    step = 1e-5
    Az = np.column_stack([(V.T @ cs.rates(0.0, on_manifold(step * dz)) - V.T @ cs.rates(0.0, on_manifold(-step * dz)))
                          / (2 * step) for dz in np.eye(2)])
    A = np.empty((6, 6))
    for k in range(6):
        dx = np.zeros(6)
        dx[k] = 1e-6
        A[:, k] = (cs.rates(0.0, x0 + dx) - cs.rates(0.0, x0 - dx)) / 2e-6
    Ar = restrict(A, np.zeros((6, 1)), np.eye(6), V)[0]
    np.testing.assert_allclose(Ar, Az, rtol=0, atol=1e-6 * np.abs(Az).max())


def test_multipliers_of_redundant_rows_are_the_minimum_norm_solution():
    """The compiled solve of (G M^-1 G') lambda = rhs for a positive semidefinite matrix of rank 6 in 15 rows
    (as Andrews' three spatial revolutes closing a planar mechanism give) equals numpy's pseudo-inverse
    solution to 1e-11 of the largest multiplier, for random matrices of full rank, rank 6 and rank 1."""
    from dynamics import constraint_kernels as CK

    cs = andrews()
    c = cs.data
    rng = np.random.default_rng(2)
    for rank in (15, 6, 1):
        B = rng.standard_normal((15, rank)) * np.logspace(0, 1, rank)
        A = B @ B.T
        rhs = A @ rng.standard_normal(15)
        c.A[:] = A
        c.rhs[:] = rhs
        CK._minimum_norm_solve(c, 15)
        expected = np.linalg.pinv(A, rcond=1e-12) @ rhs
        np.testing.assert_allclose(c.lam, expected, rtol=0, atol=1e-12 * np.abs(expected).max() * 10)


def test_a_prescribed_crank_in_a_closed_loop_reports_the_torque_that_drives_it():
    """The four-bar with its crank's acceleration prescribed: the loop's other accelerations follow, and the
    generalized force reported at the crank, applied as a torque to the same four-bar with a free crank,
    produces exactly that motion (1e-10)."""
    from dynamics import Multibody
    from dynamics.constraints import ClosureConstraint, ConstrainedSystem

    from .mechanisms import Z, rod

    mb = Multibody(gravity=(0.0, -9.81, 0.0))
    mb.add_body("crank", None, hinge="revolute", axis=Z, prescribed=True, **rod(CRANK, FOUR_BAR_MASSES[0]))
    mb.add_body("coupler", "crank", hinge="revolute", axis=Z, inboard_position=(CRANK, 0, 0),
                **rod(COUPLER, FOUR_BAR_MASSES[1]))
    mb.add_body("rocker", None, hinge="revolute", axis=Z, inboard_position=(GROUND, 0, 0),
                **rod(ROCKER, FOUR_BAR_MASSES[2]))
    mb.add_node("coupler_tip", "coupler", position=(COUPLER, 0, 0))
    mb.add_node("rocker_tip", "rocker", position=(ROCKER, 0, 0))
    driven = ConstrainedSystem(mb.compile(), [ClosureConstraint("coupler_tip", "rocker_tip", "revolute", axis=Z)])
    free = four_bar()
    q, u = free.project(*four_bar_state(np.radians(70.0), 1.5))
    acc = driven.forward_dynamics(q, u, prescribed_accel=np.array([2.5, 0.0, 0.0]))
    assert acc.u_dot[0] == 2.5
    check = free.forward_dynamics(q, u, tau=np.array([acc.tau[0], 0.0, 0.0]))
    np.testing.assert_allclose(check.u_dot, acc.u_dot, rtol=0, atol=1e-10)
    assert np.abs(driven.velocity_residual(q, u)).max() < 1e-12
