"""Flexible-body accelerations against an independent brute-force nodal formulation.

The reference (FModal paper, "Validation Approach"; TM-2020-5008164 eq. E.1.34) evaluates the body mass
matrix node by node, ``M(eta) = sum_j Y_j' M_nd(j) Y_j`` with the first-order node attitude
``delta_r = I + (lambda_j eta)~`` of eq. E.1.17, differentiates it by the complex step (exact to
round-off), and solves the equations of motion as a dense system: Lagrange's equations in the true
generalized coordinates for the pinned and cantilevered bodies, the Euler-Poincare (Kirchhoff) form for
the free-free body. No modal integral, spatial recursion or engine code is involved.

Modal-integral order k is compared with the nodal M truncated at order k in eta (its Taylor
polynomial), which is what the order-k engine models.

Tolerance 1e-10 relative (issue 4): both sides are O(10)-term sums and a dense solve of a
well-conditioned system; the observed agreement is <= 2e-15 (39 states, 2026-11-21).
"""

from __future__ import annotations

import numpy as np
import pytest

from dynamics import Multibody

from .random_flexible import flexible_body_data, random_node_model

H = 1e-30  # complex step


def skew(v):
    return np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]], dtype=v.dtype)


def nodal_mass_matrix(model, eta):
    """[omega, v, eta]-ordered body mass matrix, node by node (works for complex eta)."""
    n = model.shapes.shape[2]
    dtype = np.result_type(eta, float)
    M = np.zeros((6 + n, 6 + n), dtype=dtype)
    for j in range(len(model.mass)):
        lam, gam = model.shapes[j, :3], model.shapes[j, 3:]
        dr = np.eye(3) + skew(lam @ eta)
        J = dr @ model.inertia[j] @ dr.T
        p = dr @ model.cg[j]
        m = model.mass[j]
        Mnd = np.zeros((6, 6), dtype=dtype)
        Mnd[:3, :3] = J
        Mnd[:3, 3:] = m * skew(p)
        Mnd[3:, :3] = -m * skew(p)
        Mnd[3:, 3:] = m * np.eye(3)
        l = model.position[j] + gam @ eta
        # node velocity = [omega + lambda eta_dot; v + omega x l + gamma eta_dot]
        Y = np.zeros((6, 6 + n), dtype=dtype)
        Y[:3, :3] = np.eye(3)
        Y[3:, 3:6] = np.eye(3)
        Y[3:, :3] = -skew(l)
        Y[:3, 6:] = lam
        Y[3:, 6:] = gam
        M += Y.T @ Mnd @ Y
    return M


def truncated(model, order):
    """M(eta) truncated at ``order`` in eta (Taylor polynomial about 0, via complex steps)."""
    n = model.shapes.shape[2]
    M0 = nodal_mass_matrix(model, np.zeros(n)).real
    if order == 2:
        return lambda eta: nodal_mass_matrix(model, eta)
    if order == 0:
        return lambda eta: M0 + 0 * eta[0]
    D = [nodal_mass_matrix(model, 1j * H * np.eye(n)[r]).imag / H for r in range(n)]
    return lambda eta: M0 + sum(D[r] * eta[r] for r in range(n))


def derivatives(Mfun, eta):
    n = len(eta)
    return [Mfun(eta + 1j * H * np.eye(n)[r]).imag / H for r in range(n)]


def reference_free_free(model, order, x, eta, tau):
    """Euler-Poincare for V = [omega; v] and Lagrange for eta, dense solve."""
    Mfun = truncated(model, order)
    M = Mfun(eta).real
    D = derivatives(Mfun, eta)
    n = len(eta)
    etad = x[6:]
    h = M @ x
    Mdot = sum(D[r] * etad[r] for r in range(n))
    w, v = x[:3], x[3:6]
    rhs = tau - Mdot @ x
    rhs[:3] -= np.cross(w, h[:3]) + np.cross(v, h[3:6])
    rhs[3:6] -= np.cross(w, h[3:6])
    rhs[6:] += np.array([0.5 * x @ D[r] @ x for r in range(n)])
    rhs[6:] -= model.stiffness @ eta + model.damping @ etad
    return np.linalg.solve(M, rhs)


def reference_lagrange(model, order, Hmat, q_eta, u, tau, potential=None, q=None):
    """Plain Lagrange with x = Hmat u and generalized coordinates whose last n entries are eta:
    G(eta) u_dot = tau - Gdot u + 1/2 u' dG/dq u - K eta - C eta_dot - dPE/dq."""
    Mfun = truncated(model, order)
    n = len(q_eta)
    G = Hmat.T @ Mfun(q_eta).real @ Hmat
    D = [Hmat.T @ Dr @ Hmat for Dr in derivatives(Mfun, q_eta)]
    nh = len(u) - n
    etad = u[nh:]
    Gdot = sum(D[r] * etad[r] for r in range(n))
    rhs = tau - Gdot @ u
    rhs[nh:] += np.array([0.5 * u @ D[r] @ u for r in range(n)])
    rhs[nh:] -= model.stiffness @ q_eta + model.damping @ etad
    if potential is not None:
        grad = np.array([potential(q + 1j * H * e).imag / H for e in np.eye(len(q))])
        rhs -= grad
    return np.linalg.solve(G, rhs)


def rel(a, b):
    return np.linalg.norm(a - b) / np.linalg.norm(b)


@pytest.mark.parametrize("order", [0, 1, 2])
@pytest.mark.parametrize("point_masses, nodal", [(False, False), (True, False), (False, True)])
def test_free_free_body_matches_nodal_reference(order, point_masses, nodal):
    """``nodal``: G1, F2, G2 summed over the nodes (dynamics.kernels.node_inertia) instead of tables."""
    model = random_node_model(8, 4, seed=10 + order, point_masses=point_masses)
    mb = Multibody()
    mb.add_flexible_body("beam", None, modal=flexible_body_data(model, order, nodal=nodal), hinge="free")
    system = mb.compile()
    rng = np.random.default_rng(order)
    for _ in range(3):
        q = system.neutral_configuration()
        q[:4] = rng.standard_normal(4)
        q[:4] /= np.linalg.norm(q[:4])
        q[4:7] = rng.standard_normal(3)
        q[7:] = 0.1 * rng.standard_normal(4)
        u = rng.standard_normal(system.nu)
        tau = rng.standard_normal(system.nu)
        udot = system.forward_dynamics(q, u, tau)
        ref = reference_free_free(model, order, u, q[7:], tau)
        assert rel(udot, ref) < 1e-10


@pytest.mark.parametrize("order", [0, 1, 2])
@pytest.mark.parametrize("nodal", [False, True])
def test_pinned_free_body_matches_lagrange(order, nodal):
    model = random_node_model(7, 3, seed=20 + order)
    axis = np.array([0.3, -0.5, 0.8])
    axis /= np.linalg.norm(axis)
    mb = Multibody()
    mb.add_flexible_body("beam", None, modal=flexible_body_data(model, order, nodal=nodal), hinge="revolute", axis=axis,
                         inboard_rotation=[np.cos(0.4), 0.0, np.sin(0.4), 0.0])
    system = mb.compile()
    n = 3
    Hmat = np.zeros((6 + n, 1 + n))
    Hmat[:3, 0] = axis
    Hmat[6:, 1:] = np.eye(n)
    rng = np.random.default_rng(order)
    for _ in range(3):
        q = np.concatenate([[rng.uniform(-3, 3)], 0.1 * rng.standard_normal(n)])
        u = rng.standard_normal(1 + n)
        tau = rng.standard_normal(1 + n)
        ref = reference_lagrange(model, order, Hmat, q[1:], u, tau)
        assert rel(system.forward_dynamics(q, u, tau), ref) < 1e-10


@pytest.mark.parametrize("order", [0, 1, 2])
def test_cantilevered_body_under_gravity_matches_lagrange(order):
    """Locked to the ground at a tilted clamp; point-mass nodes so that the gravity potential
    -sum m_j g . r_j (r_j = R (l0_j + gamma_j eta)) is exact at every order."""
    model = random_node_model(9, 4, seed=30 + order, point_masses=True)
    g = np.array([0.0, 0.0, -9.81])
    R = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]) @ \
        np.array([[np.cos(0.3), 0, np.sin(0.3)], [0, 1, 0], [-np.sin(0.3), 0, np.cos(0.3)]])
    mb = Multibody(gravity=g)
    mb.add_flexible_body("beam", None, modal=flexible_body_data(model, order), hinge="locked",
                         inboard_rotation=R, inboard_position=(1.0, 2.0, 3.0))
    system = mb.compile()
    n = 4
    Hmat = np.zeros((6 + n, n))
    Hmat[6:, :] = np.eye(n)

    def potential(q):
        r = model.position + np.einsum("jan,n->ja", model.shapes[:, 3:, :], q)
        return -np.sum(model.mass * ((r @ R.T) @ g))

    rng = np.random.default_rng(order)
    for _ in range(3):
        q = 0.1 * rng.standard_normal(n)
        u = rng.standard_normal(n)
        tau = rng.standard_normal(n)
        ref = reference_lagrange(model, order, Hmat, q, u, tau, potential=potential, q=q)
        assert rel(system.forward_dynamics(q, u, tau), ref) < 1e-10


def test_pinned_body_under_gravity_with_point_masses_matches_lagrange():
    model = random_node_model(6, 3, seed=41, point_masses=True)
    g = np.array([0.0, -9.81, 0.0])
    mb = Multibody(gravity=g)
    mb.add_flexible_body("beam", None, modal=flexible_body_data(model, 2), hinge="revolute", axis=(0, 0, 1))
    system = mb.compile()
    n = 3
    Hmat = np.zeros((6 + n, 1 + n))
    Hmat[2, 0] = 1.0
    Hmat[6:, 1:] = np.eye(n)

    def potential(q):
        c, s = np.cos(q[0]), np.sin(q[0])
        Rz = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]], dtype=q.dtype)
        r = model.position + np.einsum("jan,n->ja", model.shapes[:, 3:, :], q[1:])
        return -np.sum(model.mass * ((r @ Rz.T) @ g))

    rng = np.random.default_rng(4)
    for _ in range(3):
        q = np.concatenate([[rng.uniform(-3, 3)], 0.1 * rng.standard_normal(n)])
        u = rng.standard_normal(1 + n)
        tau = rng.standard_normal(1 + n)
        ref = reference_lagrange(model, 2, Hmat, q[1:], u, tau, potential=potential, q=q)
        assert rel(system.forward_dynamics(q, u, tau), ref) < 1e-10


@pytest.fixture(scope="module")
def fe_beam():
    """The FModal paper's 101-grid, 9 m beam through the pipeline: free-free modes, and normalized
    component modes with grid 1 in the a-set (the body used for clamped and pinned attachments)."""
    from dynamics.flex.pipeline import Fem2ModalOptions, fem2modal

    deck = "configs/fem/single_length_beam.dat"
    return {"free": fem2modal(deck, Fem2ModalOptions(n_modes=6, modal_integrals=True)),
            "component": fem2modal(deck, Fem2ModalOptions(n_modes=4, aset=[(1, [1, 2, 3, 4, 5, 6])],
                                                          modal_integrals=True))}


def node_model_of(body):
    from .random_flexible import NodeModel

    shapes = np.concatenate([body.rotation_shapes, body.translation_shapes], axis=1)
    return NodeModel(body.node_mass, body.node_cm_offset, body.node_inertia, body.grid_positions, shapes,
                     np.asarray(body.modal_stiffness), np.asarray(body.modal_damping))


@pytest.mark.parametrize("attachment", ["free", "clamped", "pinned"])
@pytest.mark.parametrize("order", [0, 2])
def test_fe_beam_matches_nodal_reference(fe_beam, attachment, order):
    """The same comparison on the FE beam of the FModal paper, its data straight from the body file
    (node masses and inertias of the lumped mass matrix, grid positions, mode shapes)."""
    body = fe_beam["free" if attachment == "free" else "component"]
    model = node_model_of(body)
    n = body.n_modes
    mb = Multibody()
    hinge = {"free": dict(hinge="free"), "clamped": dict(hinge="locked"),
             "pinned": dict(hinge="revolute", axis=(0.0, 0.0, 1.0))}[attachment]
    mb.add_flexible_body("beam", None, modal=body, order=order, damping_ratio=0.02, **hinge)
    system = mb.compile()
    model.damping = system.damping_matrix()[-n:, -n:]
    rng = np.random.default_rng(order)
    q = system.neutral_configuration()
    u = rng.standard_normal(system.nu)
    tau = rng.standard_normal(system.nu)
    q[-n:] = 0.05 * rng.standard_normal(n)
    if attachment == "free":
        ref = reference_free_free(model, order, u, q[-n:], tau)
    else:
        nh = 1 if attachment == "pinned" else 0
        Hmat = np.zeros((6 + n, nh + n))
        if nh:
            Hmat[2, 0] = 1.0
        Hmat[6:, nh:] = np.eye(n)
        ref = reference_lagrange(model, order, Hmat, q[-n:], u, tau)
    assert rel(system.forward_dynamics(q, u, tau), ref) < 1e-10
