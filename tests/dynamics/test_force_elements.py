"""Force elements (dynamics/force_elements.py) against independent references.

* every conservative element (spring, bushing at a large rotation, hinge spring, hinge stops, sphere-sphere and
  sphere-plane contact, on rigid bodies of a tree and free bodies) exerts exactly the generalized force
  ``-dV/dq`` of the potential energy it reports: central differences of the energy in tangent coordinates
  (1e-7 relative, the differences' truncation);
* a spring-damper on a prismatic hinge: the analytic damped oscillator (1e-9);
* a hinge stop and a sphere-sphere impact: an independent scalar integration of the same Hunt-Crossley law
  (rebound speed to 1e-8), the coefficient of restitution the one requested at its impact speed (1e-8: the damping
  is calibrated on the law), momentum conserved through the impact (1e-12);
* friction: a sphere launched sliding on a plane decelerates at ``mu g`` and spins up at ``mu m g r / I`` until
  it rolls (the classical result), a hinge with Coulomb friction stops at ``I w0 / T``.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from dynamics import ModelDefinitionError, Multibody
from dynamics.constraints import ConstrainedSystem
from dynamics.force_elements import (Bushing, HingeFriction, HingeSpring, HingeStop, PlaneContact, SphereContact,
                                     SpringDamper, hunt_crossley_damping)

TIGHT = dict(method="DOP853", rtol=1e-11, atol=1e-12)


def unit(v):
    v = np.asarray(v, dtype=float)
    return v / np.linalg.norm(v)


def scene():
    mb = Multibody(gravity=(0.0, 0.0, -9.81))
    mb.add_body("base", None, mass=5.0, com=(0.05, 0.0, 0.02), inertia=[0.5, 0.6, 0.7], hinge="free")
    mb.add_body("arm", "base", mass=1.0, com=(0.3, 0.0, 0.0), inertia=[0.01, 0.05, 0.05], hinge="revolute",
                axis=(0, 0, 1), inboard_position=(0.4, 0.0, 0.0))
    mb.add_body("slide", "arm", mass=0.5, com=(0.05, 0.0, 0.0), inertia=[0.01, 0.01, 0.01], hinge="prismatic",
                axis=(1, 0, 0), inboard_position=(0.2, 0.0, 0.0))
    mb.add_body("ball", None, mass=2.0, inertia=[0.03, 0.03, 0.03], hinge="free")
    mb.add_node("b_spring", "base", position=(0.3, 0.1, 0.0))
    mb.add_node("b_bush", "base", position=(-0.2, 0.1, 0.05), rotation=[[0, -1, 0], [1, 0, 0], [0, 0, 1]])
    mb.add_node("b_plate", "base", position=(0.5, 0.0, -0.3), rotation=[[1, 0, 0], [0, 0, -1], [0, 1, 0]])
    mb.add_node("a_spring", "arm", position=(0.4, 0.05, 0.0))
    mb.add_node("a_tip", "arm", position=(0.8, 0.0, 0.0))
    mb.add_node("s_tip", "slide", position=(0.1, 0.0, 0.0))
    mb.add_node("ball_c", "ball")
    return mb.compile()


def elements(floor_z=-0.5, damping=0.0, friction=0.0):
    rng = np.random.default_rng(3)
    X = rng.standard_normal((6, 6))
    K = X @ X.T + 6 * np.eye(6)
    return [SpringDamper("spring", "b_spring", "a_spring", stiffness=50.0, damping=damping, free_length=0.2),
            Bushing("bush", "b_bush", stiffness=K, damping=damping * np.eye(6), world_rotation=np.eye(3),
                    world_position=(-0.3, 0.2, 0.0)),
            HingeSpring("torsion", "arm", stiffness=3.0, damping=damping, neutral=0.2),
            HingeStop("arm_stop", "arm", upper=0.1, stiffness=100.0, exponent=1.5, damping=damping),
            HingeStop("slide_stop", "slide", lower=0.05, upper=0.5, stiffness=200.0, damping=damping),
            SphereContact("touch", "a_tip", "ball_c", radius_a=0.1, radius_b=0.2, stiffness=1e3, damping=damping,
                          friction=friction),
            PlaneContact("floor", "ball_c", radius=0.2, world_point=(0.0, 0.0, floor_z), stiffness=2e3, damping=damping,
                         friction=friction),
            PlaneContact("plate", "s_tip", radius=0.4, plane_node="b_plate", stiffness=500.0, exponent=1.0,
                         damping=damping, friction=friction)]


def engaged_state(system):
    """A configuration with every element loaded: the base turned by ~1 rad (the bushing far from linear), the
    arm past its stop, the slide below its stop, the ball overlapping the arm tip; returns q and the height of
    a floor the ball sinks into by 0.1 m."""
    q = system.neutral_configuration()
    q[0:4] = unit([0.8, 0.3, -0.2, 0.4])
    q[4:7] = [0.05, -0.1, -0.35]
    q[7] = 0.3  # arm angle, past the upper stop at 0.1
    q[8] = 0.01  # slide, below the lower stop at 0.05
    tip = system.node_kinematics(q, np.zeros(system.nu)).position[system.node_index("a_tip")]
    q[9:13] = unit([0.9, -0.1, 0.3, 0.2])
    q[13:16] = tip + 0.25 * unit([1.0, 0.2, 0.1])
    return q, q[15] - 0.1


def test_every_conservative_element_exerts_minus_the_gradient_of_its_energy():
    system = scene()
    q, floor_z = engaged_state(system)
    cs = ConstrainedSystem(system, forces=elements(floor_z))
    _, generalized = cs.element_forces(q, np.zeros(system.nu))
    N = cs.tangent_map(q)
    h = 1e-6
    gradient = np.empty(system.nu)
    for k in range(system.nu):
        dq = np.zeros(system.nu)
        dq[k] = h
        energies = [cs.force_element_energy(cs.retract(q, sign * dq)) for sign in (1, -1)]
        gradient[k] = (energies[0] - energies[1]) / (2 * h)
    # power: tau . u = -dV/dt = -dV/d(dq) . N u
    np.testing.assert_allclose(generalized, -N.T @ gradient, rtol=0, atol=1e-7 * np.abs(generalized).max())
    assert cs.force_element_energy(q) > 1.0
    # each element separately contributes (none is silently zero at this state)
    for element in elements(floor_z):
        single = ConstrainedSystem(system, forces=[element])
        assert np.abs(single.element_forces(q, np.zeros(system.nu))[1]).max() > 1e-3, element.name


def test_spring_damper_on_a_prismatic_hinge_is_the_analytic_damped_oscillator():
    m, k, c, L0 = 2.0, 80.0, 3.0, 1.5
    mb = Multibody()
    mb.add_body("cart", None, mass=m, inertia=[0.1, 0.1, 0.1], hinge="prismatic", axis=(1, 0, 0))
    mb.add_node("hook", "cart")
    system = mb.compile()
    cs = ConstrainedSystem(system, forces=[SpringDamper("s", "hook", world_point=(-2.0, 0.0, 0.0), stiffness=k,
                                                        damping=c, free_length=L0)])
    x0, v0 = 0.4, -1.0
    sol = solve_ivp(cs.rates, (0.0, 2.0), [x0, v0], t_eval=[0.5, 1.0, 2.0], **TIGHT)
    x_eq = L0 - 2.0
    wn = np.sqrt(k / m)
    zeta = c / (2 * np.sqrt(k * m))
    wd = wn * np.sqrt(1 - zeta ** 2)
    A, B = x0 - x_eq, (v0 + zeta * wn * (x0 - x_eq)) / wd
    t = sol.t
    exact = x_eq + np.exp(-zeta * wn * t) * (A * np.cos(wd * t) + B * np.sin(wd * t))
    np.testing.assert_allclose(sol.y[0], exact, rtol=0, atol=1e-9)


def rebound(mass, stiffness, exponent, damping, speed):
    """Exit speed of ``mass delta'' = -k delta^n (1 + D delta')`` (never pulling) entered at ``speed``: an
    independent scalar integration, stopped where the force vanishes."""
    def rhs(t, y):
        f = stiffness * max(y[0], 0.0) ** exponent * (1 + damping * y[1])
        return [y[1], -max(f, 0.0) / mass]

    def leaves(t, y):
        return y[0] if y[1] < 0 else 1.0
    leaves.terminal, leaves.direction = True, -1
    sol = solve_ivp(rhs, (0.0, 10.0), [0.0, speed], events=leaves, method="DOP853", rtol=1e-12, atol=1e-14)
    return -sol.y_events[0][0][1]


def test_hinge_stop_rebound_equals_the_scalar_hunt_crossley_law():
    """A wheel (no gravity) turning at 2 rad/s into a stop at 0.5 rad: it leaves the stop at the rebound speed of
    the scalar law with its inertia (1e-8 relative), and with restitution 0.9 requested at 2 rad/s the measured
    coefficient is 0.9 to 1e-8 (the damping is calibrated on the law itself: force_elements.restitution_of)."""
    inertia = 0.4
    mb = Multibody()
    mb.add_body("wheel", None, mass=1.0, inertia=[0.3, 0.3, inertia], hinge="revolute", axis=(0, 0, 1))
    system = mb.compile()
    stop = HingeStop("stop", "wheel", upper=0.5, stiffness=500.0, exponent=1.0, restitution=0.9, impact_speed=2.0)
    cs = ConstrainedSystem(system, forces=[stop])

    def out(t, y):
        return y[0] - 0.5 if y[1] < 0 else 1.0
    out.terminal, out.direction = True, -1
    sol = solve_ivp(cs.rates, (0.0, 5.0), [0.3, 2.0], events=out, **TIGHT)
    exit_rate = -sol.y_events[0][0][1]
    D = hunt_crossley_damping(0.9, 2.0, "test", exponent=1.0)
    np.testing.assert_allclose(exit_rate, rebound(inertia, 500.0, 1.0, D, 2.0), rtol=1e-8)
    assert abs(exit_rate / 2.0 - 0.9) < 1e-8


def test_sphere_impact_conserves_momentum_and_rebounds_as_the_scalar_law():
    """Two free spheres head on (Hertz exponent 3/2, damping from e = 0.8 at 1 m/s): total momentum conserved to
    1e-12, their separation speed equals the scalar law with the reduced mass (1e-8), 0.8 of the approach speed."""
    mb = Multibody()
    for name, mass in (("a", 2.0), ("b", 3.0)):
        mb.add_body(name, None, mass=mass, inertia=[0.05, 0.05, 0.05], hinge="free")
        mb.add_node(f"{name}_c", name)
    system = mb.compile()
    contact = SphereContact("hit", "a_c", "b_c", radius_a=0.1, radius_b=0.15, stiffness=1e5, restitution=0.8,
                            impact_speed=1.0)
    cs = ConstrainedSystem(system, forces=[contact])
    q = system.neutral_configuration()
    q[4:7] = [0.0, 0.0, 0.0]
    q[11:14] = [0.3, 0.0, 0.0]
    u = np.zeros(12)
    u[3] = 0.6
    u[9] = -0.4
    p0 = system.linear_momentum(q, u)
    sol = solve_ivp(cs.rates, (0.0, 0.4), np.concatenate([q, u]), **TIGHT)
    qe, ue = sol.y[:14, -1], sol.y[14:, -1]
    np.testing.assert_allclose(system.linear_momentum(qe, ue), p0, rtol=0, atol=1e-12)
    separation = ue[9] - ue[3]
    assert qe[11] - qe[4] > 0.25  # apart again
    D = hunt_crossley_damping(0.8, 1.0, "test")
    np.testing.assert_allclose(separation, rebound(2.0 * 3.0 / 5.0, 1e5, 1.5, D, 1.0), rtol=1e-8)
    assert abs(separation - 0.8) < 1e-8  # the restitution asked at the impact speed


def test_friction_slows_a_sliding_sphere_until_it_rolls():
    """A solid sphere (radius 0.1 m, 1 kg) set on a plane at 2 m/s without spin, friction 0.3: while it slides,
    its speed falls at mu g and its spin grows at mu m g r / I (I = 2/5 m r^2); it rolls from
    t = 2 v0 / (7 mu g) on at 5/7 v0 (the classical result; the contact's vertical settling and the
    regularization speed 1e-3 m/s leave 1e-4 relative; the arm of the friction force is the radius less half
    the resting penetration)."""
    g, mu, r, m = 9.81, 0.3, 0.1, 1.0
    inertia = 0.4 * m * r * r
    mb = Multibody(gravity=(0.0, 0.0, -g))
    mb.add_body("ball", None, mass=m, inertia=[inertia] * 3, hinge="free")
    mb.add_node("centre", "ball")
    system = mb.compile()
    k = 1e7
    floor = PlaneContact("floor", "centre", radius=r, stiffness=k, damping=hunt_crossley_damping(0.1, 0.1, "t"),
                         friction=mu, slip_speed=1e-3)
    cs = ConstrainedSystem(system, forces=[floor])
    q = system.neutral_configuration()
    q[6] = r - (m * g / k) ** (1 / 1.5)  # resting penetration
    u = np.zeros(6)
    u[3] = 2.0
    t_roll = 2 * 2.0 / (7 * mu * g)
    arm = r - 0.5 * (m * g / k) ** (1 / 1.5)  # friction acts mid-overlap
    times = [0.5 * t_roll, 1.5 * t_roll]
    sol = solve_ivp(cs.rates, (0.0, times[-1]), np.concatenate([q, u]), t_eval=times, method="LSODA",
                    rtol=1e-10, atol=1e-12)
    speed = [system.linear_momentum(sol.y[:7, k], sol.y[7:, k])[0] / m for k in range(2)]
    spin = sol.y[7 + 1, 0]  # about the body y axis, which stays the world's
    np.testing.assert_allclose(speed[0], 2.0 - mu * g * times[0], rtol=1e-4)
    np.testing.assert_allclose(spin, mu * m * g * arm / inertia * times[0], rtol=1e-4)
    # rolling: the angular momentum about the contact point is kept, v (1 + I / (m arm^2)) = v0 (5/7 v0 when arm = r)
    np.testing.assert_allclose(speed[1], 2.0 / (1 + inertia / (m * arm * arm)), rtol=1e-4)


def test_hinge_friction_stops_a_wheel_in_the_coulomb_time():
    inertia, level, w0 = 0.5, 0.2, 3.0
    mb = Multibody()
    mb.add_body("wheel", None, mass=1.0, inertia=[0.3, 0.3, inertia], hinge="revolute", axis=(0, 0, 1))
    cs = ConstrainedSystem(mb.compile(), forces=[HingeFriction("bearing", "wheel", level=level, slip_speed=1e-6)])
    t_stop = inertia * w0 / level
    sol = solve_ivp(cs.rates, (0.0, 0.5 * t_stop), [0.0, w0], t_eval=[0.5 * t_stop], **TIGHT)
    np.testing.assert_allclose(sol.y[1, -1], w0 / 2, rtol=1e-9)


@pytest.mark.parametrize("element, fragment", [
    (SpringDamper("s", "nope", stiffness=1.0, free_length=1.0), "force element 's': unknown node 'nope'"),
    (SpringDamper("s", "ball_c", "a_tip", stiffness=-1.0, free_length=1.0), "stiffness must be a number >= 0"),
    (SpringDamper("s", "ball_c", "a_tip", stiffness=1.0, free_length=1.0, acts="push"), "acts must be one of"),
    (Bushing("b", "b_bush", stiffness=[[1, 2, 0, 0, 0, 0]] + [[0] * 6] * 5), "positive semidefinite"),
    (HingeSpring("h", "bass", stiffness=1.0), "unknown body or hinge 'bass'"),
    (HingeSpring("h", "base", stiffness=1.0), "free hinge; hinge elements act on"),
    (HingeStop("h", "arm", stiffness=1.0), "give lower and/or upper"),
    (HingeStop("h", "arm", lower=1.0, upper=0.0, stiffness=1.0), "lower (1.0) must be below upper"),
    (HingeStop("h", "arm", upper=0.0, stiffness=1.0, restitution=0.5), "restitution needs the impact_speed"),
    (PlaneContact("p", "ball_c", radius=0.1, normal=(0, 0, 2), stiffness=1.0), "normal must be a unit 3-vector"),
    (SphereContact("c", "a_tip", "a_spring", radius_a=0.1, stiffness=1.0), "on the same body 'arm'"),
])
def test_bad_force_elements_are_refused_with_the_element_named(element, fragment):
    with pytest.raises(ModelDefinitionError) as info:
        ConstrainedSystem(scene(), forces=[element])
    assert fragment in str(info.value), str(info.value)


def test_elements_on_deforming_nodes_of_a_flexible_body_load_its_modes_by_the_gradient_of_their_energy():
    """A flexible body (order-2 modal integrals, free) with a spring from one deforming node to the world, a
    bushing from another to a rigid arm on a third node, and that arm against a floor: the generalized forces,
    modal rows included, are minus the gradient of the elements' energy (1e-7, finite differences)."""
    from tests.flexible.random_flexible import flexible_body_data, random_node_model

    mb = Multibody(gravity=(0.0, 0.0, -9.81))
    mb.add_flexible_body("panel", None, modal=flexible_body_data(random_node_model(6, 3, seed=4), 2), hinge="free")
    mb.add_node("p2", "panel", grid=2)
    mb.add_node("p4", "panel", grid=4)
    mb.add_node("p6", "panel", grid=6)
    mb.add_body("arm", "panel", parent_node="p6", mass=1.0, com=(0.2, 0, 0), inertia=[0.01, 0.02, 0.02],
                hinge="revolute", axis=(0, 1, 0))
    mb.add_node("arm_tip", "arm", position=(0.4, 0.0, 0.0))
    system = mb.compile()
    q = system.neutral_configuration()
    q[:4] = unit([0.9, 0.1, -0.3, 0.2])
    q[7:10] = [0.3, -0.2, 0.25]
    q[10] = 0.4
    tip = system.node_kinematics(q, np.zeros(system.nu)).position[system.node_index("arm_tip")]
    forces = [SpringDamper("tether", "p2", world_point=(1.0, 2.0, -1.0), stiffness=40.0, free_length=0.5),
              Bushing("mount", "p4", "arm_tip", stiffness=np.diag([5.0, 6.0, 7.0, 300.0, 200.0, 100.0])),
              PlaneContact("floor", "arm_tip", radius=0.1, world_point=(0.0, 0.0, tip[2] - 0.05), stiffness=1e3)]
    cs = ConstrainedSystem(system, forces=forces)
    _, generalized = cs.element_forces(q, np.zeros(system.nu))
    h = 1e-6
    energy = cs.force_element_energy
    gradient = np.array([(energy(cs.retract(q, h * e)) - energy(cs.retract(q, -h * e))) / (2 * h)
                         for e in np.eye(system.nu)])
    np.testing.assert_allclose(generalized, -cs.tangent_map(q).T @ gradient, rtol=0,
                               atol=1e-7 * np.abs(generalized).max())
    assert np.abs(generalized[6:9]).min() > 1e-3  # the modes are loaded
