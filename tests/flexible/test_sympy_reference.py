"""A small flexible system against a SymPy derivation (TM-2020-5008164 Section 7.2 compared DARTS with
computer algebra to 1e-8).

System: a flexible beam of point masses pinned to the ground about z, two in-plane modes, modal
stiffness, a rigid link hinged (about z) at the beam's deforming tip node, gravity along -y. SymPy builds
the kinetic energy from the world-frame positions of every mass (no spatial algebra, no modal
integrals), forms Lagrange's equations symbolically and solves for the accelerations, which must equal
the engine's to 1e-10 relative: the planar kinematics are exact in both models (point-mass nodes make
the modal mass matrix exactly quadratic in eta; the tip rotation is a plane rotation).
"""

from __future__ import annotations

import numpy as np
import sympy as sp

from dynamics import Multibody

from .random_flexible import flexible_body_data, random_node_model

G = 9.81


def planar_model():
    model = random_node_model(5, 2, seed=77, point_masses=True)
    model.position[:, 2] = 0.0
    model.shapes[:, 0:2, :] = 0.0  # rotations about z only
    model.shapes[:, 5, :] = 0.0  # translations in the plane only
    model.damping[:] = 0.0
    return model


def sympy_accelerations(model, link):
    theta, e1, e2, psi = sp.symbols("theta e1 e2 psi")
    dtheta, de1, de2, dpsi = sp.symbols("dtheta de1 de2 dpsi")
    q = [theta, e1, e2, psi]
    qd = [dtheta, de1, de2, dpsi]
    eta = sp.Matrix([e1, e2])
    Rz = lambda a: sp.Matrix([[sp.cos(a), -sp.sin(a)], [sp.sin(a), sp.cos(a)]])  # noqa: E731
    positions = []
    masses = []
    for j in range(len(model.mass)):
        l0 = sp.Matrix([float(x) for x in model.position[j, :2]])
        gam = sp.Matrix(model.shapes[j, 3:5, :].tolist())
        positions.append(Rz(theta) * (l0 + gam * eta))
        masses.append(float(model.mass[j]))
    tip = len(model.mass) - 1
    tip_angle = (sp.Matrix([model.shapes[tip, 2, :].tolist()]) * eta)[0]
    link_angle = theta + tip_angle + psi
    link_origin = positions[tip]
    link_com = link_origin + Rz(link_angle) * sp.Matrix([link["com_x"], 0.0])
    dt = lambda expr: sum(sp.diff(expr, qi) * qdi for qi, qdi in zip(q, qd))  # noqa: E731
    T = 0
    V = 0
    for m, r in zip(masses, positions):
        v = r.applyfunc(dt)
        T += sp.Rational(1, 2) * m * (v.T * v)[0]
        V += m * G * r[1]
    vc = link_com.applyfunc(dt)
    T += sp.Rational(1, 2) * link["mass"] * (vc.T * vc)[0] + sp.Rational(1, 2) * link["izz"] * dt(link_angle) ** 2
    V += link["mass"] * G * link_com[1]
    K = model.stiffness
    V += sp.Rational(1, 2) * (K[0, 0] * e1**2 + 2 * K[0, 1] * e1 * e2 + K[1, 1] * e2**2)
    L = T - V
    Mmat = sp.Matrix(4, 4, lambda i, k: sp.diff(L, qd[i], qd[k]))
    # Lagrange: M qdd + sum_k d(dL/dqd_i)/dq_k qd_k - dL/dq_i = tau_i
    rhs = sp.Matrix([sum(sp.diff(sp.diff(L, qd[i]), q[k]) * qd[k] for k in range(4)) - sp.diff(L, q[i])
                     for i in range(4)])
    return sp.lambdify([q, qd], Mmat, "numpy"), sp.lambdify([q, qd], rhs, "numpy")


def test_engine_matches_sympy_lagrange_equations():
    model = planar_model()
    link = {"mass": 0.7, "com_x": 0.35, "izz": 0.02}
    mb = Multibody(gravity=(0.0, -G, 0.0))
    mb.add_flexible_body("beam", None, modal=flexible_body_data(model, 2), hinge="revolute", axis=(0, 0, 1))
    mb.add_node("tip", "beam", grid=len(model.mass))
    mb.add_body("link", "beam", mass=link["mass"], com=(link["com_x"], 0.0, 0.0),
                inertia=[0.01, link["izz"], link["izz"]], hinge="revolute", axis=(0, 0, 1), parent_node="tip")
    system = mb.compile()
    mass_fn, rhs_fn = sympy_accelerations(model, link)
    rng = np.random.default_rng(12)
    for _ in range(4):
        q = np.array([rng.uniform(-3, 3), 0.1 * rng.standard_normal(), 0.1 * rng.standard_normal(),
                      rng.uniform(-3, 3)])
        u = rng.standard_normal(4)
        tau = rng.standard_normal(4)
        ref = np.linalg.solve(np.array(mass_fn(q, u), dtype=float),
                              tau - np.array(rhs_fn(q, u), dtype=float).ravel())
        got = system.forward_dynamics(q, u, tau)
        assert np.linalg.norm(got - ref) / np.linalg.norm(ref) < 1e-10
