"""Scenes whose tree changes during the run: stage separation, a deployment ending in a latch, docking, and
constraints switched on and off, through the engine's operations (:meth:`ConstrainedSystem.reconfigure`,
``switch_on``/``switch_off``) with the events located by scipy's event finder.

Independent references: conservation of total linear and angular momentum (no external force: 1e-9 relative
over the runs, integration error; 1e-12 through each change, which is an algebraic map), the straight line of
a free body's centre of mass, the separation speed of a spring's energy shared by the reduced mass, and the
energy a plastic impact loses computed without the engine's mass matrix (the merged bodies as one rigid body:
the composite inertia assembled by hand from the bodies' mass properties and poses; two bodies joined by a
ball: the classical impulse ``K^-1 v_rel`` with ``K = (1/m1 + 1/m2) I - r1~ I1^-1 r1~ - r2~ I2^-1 r2~``).
"""

from __future__ import annotations

import numpy as np
from scipy.integrate import solve_ivp

from dynamics import Multibody
from dynamics.constraints import ClosureConstraint, ConstrainedSystem
from dynamics.force_elements import HingeSpring, PlaneContact, SpringDamper, hunt_crossley_damping
from dynamics.spatial import skew

TIGHT = dict(method="DOP853", rtol=1e-12, atol=1e-12)


def momentum(cs, y):
    system = cs.system
    q, u = y[:system.nq], y[system.nq:]
    return np.concatenate([system.linear_momentum(q, u), system.angular_momentum(q, u)])


def run(cs, y0, t0, t1, event=None, **options):
    """Integrate cs from (t0, y0) to t1, or to the event (terminal); returns (t, y, solution)."""
    if event is not None:
        event.terminal = True
    sol = solve_ivp(cs.rates, (t0, t1), y0, events=event, dense_output=True, **dict(TIGHT, **options))
    return sol.t[-1], sol.y[:, -1], sol


def node_position(cs, y, node):
    system = cs.system
    return system.node_kinematics(y[:system.nq], y[system.nq:]).position[system.node_index(node)]


def composite_kinetic_energy(cs, y, bodies):
    """Kinetic energy of the bodies moving as one rigid body with their total momentum: the composite mass,
    centre of mass and inertia assembled from each body's mass properties at its pose (no engine mass
    matrix)."""
    system = cs.system
    q, u = y[:system.nq], y[system.nq:]
    R, origins = system.body_poses(q)
    definitions = {b.name: b for b in system.definitions[0]}
    masses, centres, inertias = [], [], []
    for name in bodies:
        k = system.body_index(name)
        b = definitions[name]
        masses.append(b.mass)
        centres.append(origins[k] + R[k] @ b.com)
        inertias.append(R[k] @ b.inertia @ R[k].T)
    M = sum(masses)
    c = sum(m * x for m, x in zip(masses, centres)) / M
    I = sum(J + m * (np.dot(x - c, x - c) * np.eye(3) - np.outer(x - c, x - c))
            for m, x, J in zip(masses, centres, inertias))
    P = system.linear_momentum(q, u)
    H = system.angular_momentum(q, u) - np.cross(c, P)  # about the composite centre of mass
    return P @ P / (2 * M) + 0.5 * H @ np.linalg.solve(I, H)


# ---------------------------------------------------------------------------------------------- separation
def two_stage(spring, misaligned=False):
    """A lower stage (1000 kg) carrying an upper stage (300 kg) through a locked interface, flying free (no
    gravity); with ``spring`` a compression-only separation spring (2e4 N/m) between them, 0.1 m compressed,
    on the line through both centres of mass."""
    mb = Multibody()
    mb.add_body("lower", None, mass=1000.0, inertia=[500.0, 2000.0, 2100.0], hinge="free")
    mb.add_body("upper", "lower", mass=300.0, com=(1.0, 0.0, 0.0), inertia=[100.0, 250.0, 260.0], hinge="locked",
                inboard_position=(3.0, 0.0, 0.0))
    mb.add_node("lower_seat", "lower", position=(2.8, 0.0, 0.0))
    mb.add_node("upper_seat", "upper", position=(0.2, 0.0, 0.0))
    mb.add_node("upper_cg", "upper", position=(1.0, 0.0, 0.0))
    forces = [SpringDamper("separation_spring", "lower_seat", "upper_seat", stiffness=2e4, free_length=0.5,
                           acts="compression")] if spring else []
    cs = ConstrainedSystem(mb.compile(), forces=forces)
    q = cs.system.neutral_configuration()
    q[4:7] = [10.0, -5.0, 2.0]
    u = np.zeros(6)
    u[:3] = [0.5, 0.0, 0.03 if misaligned else 0.0]  # roll (and a small yaw rate) in body axes
    u[3:] = [20.0, 1.0, -0.5]
    return cs, np.concatenate([q, u])


def separate(spring, misaligned=False):
    """Fly 1 s together, detach the upper stage, fly 3 s more; returns what the checks need."""
    cs, y = two_stage(spring, misaligned)
    p0 = momentum(cs, y)
    e0 = cs.energy(y[:7], y[7:])
    t, y, _ = run(cs, y, 0.0, 1.0)
    before = momentum(cs, y)
    cs, q, u, _ = cs.reconfigure(y[:cs.system.nq], y[cs.system.nq:], detach=["upper"])
    y = np.concatenate([q, u])
    after = momentum(cs, y)
    t, y, sol = run(cs, y, 1.0, 4.0)
    return cs, p0, e0, before, after, y, sol


def test_stage_separation_without_a_spring_conserves_momentum_and_the_stage_flies_straight():
    cs, p0, e0, before, after, y, sol = separate(spring=False, misaligned=True)
    scale = np.abs(p0).max()
    np.testing.assert_allclose(after, before, rtol=0, atol=1e-12 * scale)  # detach is an exact map
    np.testing.assert_allclose(momentum(cs, y), p0, rtol=0, atol=1e-9 * scale)
    times = np.linspace(1.0, 4.0, 13)
    path = np.array([node_position(cs, sol.sol(t), "upper_cg") for t in times])
    line = path[0] + np.outer(times - 1.0, (path[-1] - path[0]) / 3.0)
    assert np.abs(path - line).max() < 1e-8


def test_stage_separation_with_a_spring_pushes_the_stages_apart_at_the_spring_energy_speed():
    """The compression-only spring (0.1 m precompressed, 100 J) acts inside the locked stack, then pushes the
    detached stage away until it reaches its free length; the stages then part at ``sqrt(2 E / mu)``
    (mu = 1000 * 300 / 1300 kg) to 1e-8 relative, momentum and energy conserved to 1e-9, and the upper
    stage flies straight once the spring is slack."""
    cs, p0, e0, before, after, y, sol = separate(spring=True)
    scale = np.abs(p0).max()
    np.testing.assert_allclose(after, before, rtol=0, atol=1e-12 * scale)
    np.testing.assert_allclose(momentum(cs, y), p0, rtol=0, atol=1e-9 * scale)
    nq = cs.system.nq
    np.testing.assert_allclose(cs.energy(y[:nq], y[nq:]), e0, rtol=1e-9)
    assert cs.force_element_energy(y[:nq]) == 0.0  # slack
    mu = 1000.0 * 300.0 / 1300.0
    v_lower = cs.system.linear_momentum(y[:nq], y[nq:])  # total; the relative speed from the CG velocities
    kin = cs.system.node_kinematics(y[:nq], y[nq:])
    R_upper = kin.rotation[cs.system.node_index("upper_cg")]
    v_upper = R_upper @ kin.linear_velocity[cs.system.node_index("upper_cg")]
    v_cm = v_lower / 1300.0
    relative = (v_upper - v_cm) * 1300.0 / 1000.0  # upper minus lower centre-of-mass velocity
    np.testing.assert_allclose(np.linalg.norm(relative), np.sqrt(2 * 100.0 / mu), rtol=1e-8)
    times = np.linspace(2.5, 4.0, 7)  # the spring is slack after 0.17 s
    path = np.array([node_position(cs, sol.sol(t), "upper_cg") for t in times])
    line = path[0] + np.outer(times - 2.5, (path[-1] - path[0]) / 1.5)
    assert np.abs(path - line).max() < 1e-8


# ---------------------------------------------------------------------------------------------- deployment
def deploying_array():
    """A bus (500 kg, free, turning slowly) with an array (30 kg, 3 m) on a revolute hinge, driven open by a
    hinge spring (5 N m/rad towards 143 deg) from folded at rest."""
    mb = Multibody()
    mb.add_body("bus", None, mass=500.0, com=(0.1, 0.0, 0.05), inertia=[400.0, 300.0, 350.0], hinge="free")
    mb.add_body("array", "bus", mass=30.0, com=(1.5, 0.0, 0.0), inertia=[1.0, 23.0, 24.0], hinge="revolute",
                axis=(0.0, 0.0, 1.0), inboard_position=(1.0, 0.5, 0.0))
    cs = ConstrainedSystem(mb.compile(), forces=[HingeSpring("deploy", "array", stiffness=5.0, neutral=2.5)])
    q = cs.system.neutral_configuration()
    u = np.zeros(cs.system.nu)
    u[:3] = [0.01, -0.02, 0.005]
    u[3:6] = [0.1, 0.0, 0.0]
    return cs, np.concatenate([q, u])


def test_array_deployment_ending_in_a_latch_conserves_angular_momentum_and_loses_the_plastic_energy():
    """The hinge angle crossing 90 deg (located by the event finder) latches the array: a lock, the plastic
    impact. Momentum is unchanged through the latch (1e-12) and over the whole run (1e-9); the kinetic energy
    after the latch is that of bus and array as one rigid body with the same momentum (composite inertia by
    hand, 1e-10 relative), the loss equals 1/2 w^2 / (M^-1)_ww (the impact formula), and the hinge spring is
    switched off with the hinge."""
    cs, y = deploying_array()
    p0 = momentum(cs, y)

    def open_90(t, y):
        return y[7] - np.pi / 2
    open_90.direction = 1
    t, y, sol = run(cs, y, 0.0, 60.0, event=open_90)
    assert sol.status == 1 and 1.0 < t < 60.0  # latched during the run
    nq = cs.system.nq
    q, u = y[:nq], y[nq:]
    kinetic_before = cs.system.kinetic_energy(q, u)
    rate = u[6]
    w_mobility = np.linalg.inv(cs.system.mass_matrix(q))[6, 6]
    latched, q1, u1, _ = cs.reconfigure(q, u, lock=["array"])
    y1 = np.concatenate([q1, u1])
    scale = np.abs(p0).max()
    np.testing.assert_allclose(momentum(latched, y1), momentum(cs, y), rtol=0, atol=1e-12 * scale)
    kinetic_after = latched.system.kinetic_energy(q1, u1)
    np.testing.assert_allclose(kinetic_after, composite_kinetic_energy(latched, y1, ["bus", "array"]), rtol=1e-10)
    np.testing.assert_allclose(kinetic_before - kinetic_after, 0.5 * rate ** 2 / w_mobility, rtol=1e-10)
    assert kinetic_before - kinetic_after > 0.1 * kinetic_before
    assert latched.force_element_energy(q1) == 0.0 and latched.system.hinge_names[1] == "locked"
    t, y2, _ = run(latched, y1, t, t + 10.0)
    np.testing.assert_allclose(momentum(latched, y2), p0, rtol=0, atol=1e-9 * scale)


# ---------------------------------------------------------------------------------------------- docking
def docking_scene():
    """A target (2000 kg) at rest and a chaser (500 kg) approaching at 5 cm/s, 2 mm off the axis and turned
    by 0.01 rad: a probe sphere (radius 5 cm) on the chaser meets the target's plate (Hunt-Crossley, e = 0.5 at
    5 cm/s, friction 0.2); the docking ports coincide when the probe has sunk 5 mm into the plate."""
    mb = Multibody()
    mb.add_body("target", None, mass=2000.0, inertia=[1500.0, 1800.0, 2000.0], hinge="free")
    mb.add_body("chaser", None, mass=500.0, inertia=[300.0, 400.0, 450.0], hinge="free")
    mb.add_node("plate", "target", position=(1.0, 0.0, 0.0), rotation=[[0, 0, 1], [0, 1, 0], [-1, 0, 0]])
    mb.add_node("target_port", "target", position=(1.0, 0.0, 0.0))
    mb.add_node("probe", "chaser", position=(-1.0, 0.0, 0.0))
    mb.add_node("chaser_port", "chaser", position=(-1.045, 0.0, 0.0))
    probe = PlaneContact("probe_contact", "probe", radius=0.05, plane_node="plate", stiffness=1e4, exponent=1.0,
                         damping=hunt_crossley_damping(0.5, 0.05, "docking"), friction=0.2)
    cs = ConstrainedSystem(mb.compile(), forces=[probe])
    q = cs.system.neutral_configuration()
    q[7:11] = [np.cos(0.005), 0.0, 0.0, np.sin(0.005)]
    q[11:14] = [2.15, 0.002, 0.0]
    u = np.zeros(12)
    u[9] = -0.05 * np.cos(0.01)  # chaser velocity -0.05 m/s along world x, in its (turned) axes
    u[10] = 0.05 * np.sin(0.01)
    return cs, np.concatenate([q, u])


def test_two_free_bodies_dock_through_contact_and_a_latch():
    """Contact first (the probe pushes the target; internal forces: momentum conserved to 1e-9), then the latch
    when the ports meet along the axis (located by the event finder): the ports are caught where they are (the
    2 mm offset and 0.01 rad misalignment reported, nothing moves), the plastic impact conserves momentum
    (1e-12) and leaves one rigid body whose kinetic energy is that of the composite with the same momentum
    (1e-10); the merged vehicle then flies on as one body (momentum 1e-9, the ports' relative pose fixed)."""
    cs, y = docking_scene()
    p0 = momentum(cs, y)

    def ports_meet(t, y):
        return node_position(cs, y, "chaser_port")[0] - node_position(cs, y, "target_port")[0]
    ports_meet.direction = -1
    t, y, sol = run(cs, y, 0.0, 10.0, event=ports_meet, max_step=0.05)
    assert sol.status == 1
    scale = np.abs(p0).max()
    np.testing.assert_allclose(momentum(cs, y), p0, rtol=0, atol=1e-9 * scale)
    nq = cs.system.nq
    kinetic_before = cs.system.kinetic_energy(y[:nq], y[nq:])
    before = momentum(cs, y)
    docked, q1, u1, report = cs.reconfigure(y[:nq], y[nq:], attach={"chaser": ("chaser_port", "target_port")},
                                            tolerance=0.02)
    assert 0.009 < report.residual < 0.011 and report.worst == "attach chaser"  # the misalignment caught
    assert docked.system.parents[docked.system.body_index("chaser")] == docked.system.body_index("target")
    y1 = np.concatenate([q1, u1])
    np.testing.assert_allclose(momentum(docked, y1), before, rtol=0, atol=1e-12 * scale)
    kinetic_after = docked.system.kinetic_energy(q1, u1)
    np.testing.assert_allclose(kinetic_after, composite_kinetic_energy(docked, y1, ["target", "chaser"]), rtol=1e-10)
    np.testing.assert_allclose(report.energy_lost, kinetic_before - kinetic_after, rtol=1e-10)
    assert 0 < kinetic_after < kinetic_before
    for node in ("chaser_port", "target_port", "probe"):  # nothing moved
        np.testing.assert_allclose(node_position(docked, y1, node), node_position(cs, y, node), rtol=0, atol=1e-14)

    def relative(cs, y):
        kin = cs.system.node_kinematics(y[:cs.system.nq], np.zeros(cs.system.nu))
        a, b = (cs.system.node_index(n) for n in ("chaser_port", "target_port"))
        return np.concatenate([(kin.rotation[b].T @ kin.rotation[a]).ravel(),
                               kin.rotation[b].T @ (kin.position[a] - kin.position[b])])
    t, y2, _ = run(docked, y1, t, t + 5.0)
    np.testing.assert_allclose(momentum(docked, y2), p0, rtol=0, atol=1e-9 * scale)
    np.testing.assert_allclose(relative(docked, y2), relative(cs, y), rtol=0, atol=1e-14)


# ---------------------------------------------------------------------------------------------- switching
def two_bodies():
    mb = Multibody()
    mb.add_body("a", None, mass=3.0, com=(0.1, 0.0, 0.0), inertia=[[0.5, 0.02, 0], [0.02, 0.4, 0], [0, 0, 0.3]],
                hinge="free")
    mb.add_body("b", None, mass=2.0, inertia=[0.2, 0.25, 0.3], hinge="free")
    mb.add_node("a_hook", "a", position=(0.5, 0.1, 0.0))
    mb.add_node("b_hook", "b", position=(-0.3, 0.0, 0.1))
    return mb.compile()


def test_switching_a_ball_constraint_on_is_the_classical_impulse_and_off_releases():
    system = two_bodies()
    cs = ConstrainedSystem(system, [ClosureConstraint("a_hook", "b_hook", "ball", name="hook", active=False)])
    rng = np.random.default_rng(5)
    q = system.neutral_configuration()
    q[0:4] = [np.cos(0.2), np.sin(0.2), 0.0, 0.0]
    kin = system.node_kinematics(q, np.zeros(12))
    q[11:14] = kin.position[system.node_index("a_hook")] - np.array([-0.3, 0.0, 0.1])  # hooks meet
    u = rng.uniform(-1, 1, 12)
    y = np.concatenate([q, u])
    p0 = momentum(cs, y)
    q1, u1, report = cs.switch_on("hook", q, u)
    assert report.residual < 1e-14 and report.moved < 1e-14
    np.testing.assert_allclose(momentum(cs, np.concatenate([q1, u1])), p0, rtol=0, atol=1e-12 * np.abs(p0).max())
    # the classical impulse between two free rigid bodies at the contact point, in the world
    R, origins = system.body_poses(q)
    kin = system.node_kinematics(q, u)
    x = kin.position[system.node_index("a_hook")]
    K = np.zeros((3, 3))
    v_rel = np.zeros(3)
    for k, (body, hook, sign) in enumerate((("a", "a_hook", -1), ("b", "b_hook", 1))):
        definition = system.definitions[0][k]
        centre = origins[k] + R[k] @ definition.com
        inverse = np.linalg.inv(R[k] @ definition.inertia @ R[k].T)
        r = skew(x - centre)
        K += np.eye(3) / definition.mass - r @ inverse @ r
        n = system.node_index(hook)
        v_rel += sign * kin.rotation[n] @ kin.linear_velocity[n]
    lost = 0.5 * v_rel @ np.linalg.solve(K, v_rel)
    np.testing.assert_allclose(report.energy_lost, lost, rtol=1e-12)
    assert np.abs(cs.velocity_residual(q1, u1)).max() < 1e-13
    cs.switch_off("hook")
    np.testing.assert_allclose(cs.forward_dynamics(q1, u1).u_dot, system.forward_dynamics(q1, u1), atol=1e-14)
    assert not cs.is_active("hook")


def test_a_lock_in_a_closed_chain_is_the_projection_onto_both_the_lock_and_the_loop():
    """Locking the crank of a four-bar's cousin with two DOFs (a five-bar: two cranks, two couplers, one pin)
    removes the crank rate and what the loop then forbids: the velocities equal the M-orthogonal projection onto
    {crank rate = 0, G u = 0} computed with numpy from the engine's M and G (1e-12)."""
    Z = (0.0, 0.0, 1.0)
    mb = Multibody(gravity=(0.0, -9.81, 0.0))
    rod = dict(mass=1.0, com=(0.5, 0, 0), inertia=[1e-3, 0.1, 0.1])
    mb.add_body("crank1", None, hinge="revolute", axis=Z, **rod)
    mb.add_body("coupler1", "crank1", hinge="revolute", axis=Z, inboard_position=(1, 0, 0), **rod)
    mb.add_body("crank2", None, hinge="revolute", axis=Z, inboard_position=(1.5, 0, 0), **rod)
    mb.add_body("coupler2", "crank2", hinge="revolute", axis=Z, inboard_position=(1, 0, 0), **rod)
    mb.add_node("tip1", "coupler1", position=(1, 0, 0))
    mb.add_node("tip2", "coupler2", position=(1, 0, 0))
    system = mb.compile()
    cs = ConstrainedSystem(system, [ClosureConstraint("tip1", "tip2", "revolute", axis=Z, name="pin")])
    a, b = 1.2, 1.9  # the two crank angles; the couplers meet where two circles of radius 1 intersect
    P1, P2 = np.array([np.cos(a), np.sin(a)]), np.array([1.5 + np.cos(b), np.sin(b)])
    mid, half = (P1 + P2) / 2, np.linalg.norm(P2 - P1) / 2
    n = np.array([-(P2 - P1)[1], (P2 - P1)[0]]) / (2 * half)
    X = mid + np.sqrt(1 - half ** 2) * n
    q = np.array([a, np.arctan2(*(X - P1)[::-1]) - a, b, np.arctan2(*(X - P2)[::-1]) - b])
    q, u = cs.project(q, np.array([0.7, -0.3, 0.4, 0.2]))
    assert np.abs(cs.residual(q)).max() < 1e-12 and np.abs(u).max() > 0.1
    M, G = system.mass_matrix(q), cs.jacobian(q)
    C = np.vstack([np.eye(4)[:1], G])
    Minv_Ct = np.linalg.solve(M, C.T)
    expected = u - Minv_Ct @ np.linalg.lstsq(C @ Minv_Ct, C @ u, rcond=1e-12)[0]
    locked, q1, u1, _ = cs.reconfigure(q, u, lock=["crank1"])
    np.testing.assert_allclose(u1, expected[1:], rtol=0, atol=1e-12)
    assert np.abs(locked.velocity_residual(q1, u1)).max() < 1e-12


def test_bad_attach_requests_are_refused_with_the_body_named():
    from dynamics import ModelDefinitionError
    import pytest

    cs, y = docking_scene()
    q, u = y[:14], y[14:]
    with pytest.raises(ModelDefinitionError, match="unknown node 'dock' \\(the target node\\)"):
        cs.reconfigure(q, u, attach={"chaser": ("chaser_port", "dock")}, tolerance=1.0)
    with pytest.raises(ModelDefinitionError, match="node 'target_port' is on body 'target', not on 'chaser'"):
        cs.reconfigure(q, u, attach={"chaser": ("target_port", "plate")}, tolerance=1.0)
    with pytest.raises(ModelDefinitionError, match="frames of 'attach chaser' are 0.1.* apart, more than the latch"):
        cs.reconfigure(q, u, attach={"chaser": ("chaser_port", "target_port")})
    stack, y = two_stage(spring=False)
    with pytest.raises(ModelDefinitionError, match="only a body floating free .* it has a locked hinge to lower"):
        stack.reconfigure(y[:7], y[7:], attach={"upper": ("upper_seat", "lower_seat")})
    with pytest.raises(ModelDefinitionError, match="unknown body or hinge 'uper'"):
        stack.reconfigure(y[:7], y[7:], detach=["uper"])
    cs, y = docking_scene()
    with pytest.raises(ModelDefinitionError, match="moves at 0.05.* relative to 'target_port'; a latch is a plastic"):
        cs.system.reconfigure(y[:14], y[14:], attach={"chaser": ("chaser_port", "target_port")})
