"""The terms G1, F2, G2 summed over the nodes (dynamics.kernels.node_inertia) and the refined modal mass
(dynamics.kernels.articulated_body) against the tables and the brute-force nodal formulation.

References: the same body with every term of M(eta) as tables (the modal integrals of TM-2020-5008164 App. E,
themselves checked against the nodal product E.1.34 in tests/flex/test_modal_integrals.py), and the dense
Lagrange / Euler-Poincare solve of tests/flexible/test_brute_force.py with the node-by-node mass matrix
differentiated by complex steps. Tolerances: 1e-12 relative between the two engine representations (the
same quantities summed in another order: round-off, observed <= 1e-14) and 1e-10 against the brute force (as
in test_brute_force.py, observed <= 1e-14); the refinement stops at 4 eps of the modal accelerations.
"""

from __future__ import annotations

import numpy as np
import pytest

import dynamics.system
from dynamics import Multibody
from dynamics.kernels import articulated_body as AB

from .random_flexible import flexible_body_data, random_node_model
from .test_brute_force import reference_free_free, rel


def _body(model, order, nodal, wheel=False, solver="aba"):
    mb = Multibody()
    mb.add_flexible_body("body", None, modal=flexible_body_data(model, order, nodal=nodal), hinge="free")
    if wheel:  # a child on a deforming node: the Woodbury path of the modal elimination
        mb.add_node("mount", "body", grid=3)
        mb.add_body("wheel", "body", mass=4.0, inertia=[0.08, 0.05, 0.05], com=(0.01, 0.0, 0.02), hinge="revolute",
                    axis=(1.0, 0.0, 0.0), parent_node="mount")
    return mb.compile(solver=solver)


def _state(system, n, rng, size=0.1):
    q = system.neutral_configuration()
    q[:4] = rng.standard_normal(4)
    q[:4] /= np.linalg.norm(q[:4])
    q[4:7] = rng.standard_normal(3)
    q[7:7 + n] = size * rng.standard_normal(n)
    return q, rng.standard_normal(system.nu), rng.standard_normal(system.nu)


@pytest.mark.parametrize("order", [1, 2])
@pytest.mark.parametrize("refine", [False, True])
@pytest.mark.parametrize("offsets", ["all", "none", "some"])
def test_node_terms_equal_the_tables(order, refine, offsets, monkeypatch):
    """Every algorithm on a body with rotary node inertia and CG offsets on all, none or every other node (the node
    sums skip the offset terms of a body without any and carry zero offsets through them where only some nodes have
    one), and a wheel on one of its nodes: the node sums (refined or factored modal mass) against the same body with
    all terms as tables."""
    monkeypatch.setattr(dynamics.system, "refinement_budget", lambda n, count: 60 if refine else 0)
    model = random_node_model(9, 6, seed=50 + order)
    if offsets != "all":
        model.cg[::1 if offsets == "none" else 2] = 0.0
    tables = _body(model, order, nodal=False, wheel=True)
    nodes = _body(model, order, nodal=True, wheel=True)
    fx = nodes.topology[0, dynamics.system.L.FLEX:]
    assert fx[dynamics.system.L.FX_NODES] >= 0 and bool(fx[dynamics.system.L.FX_REFINE]) == refine
    assert nodes.params[fx[dynamics.system.L.FX_NODES]] == (0.0 if offsets == "none" else 1.0)
    rng = np.random.default_rng(order)
    for _ in range(3):
        q, u, tau = _state(nodes, 6, rng)
        udot = tables.forward_dynamics(q, u, tau)
        assert rel(nodes.forward_dynamics(q, u, tau), udot) < 1e-12
        assert rel(nodes.inverse_dynamics(q, u, udot), tables.inverse_dynamics(q, u, udot)) < 1e-12
        assert rel(nodes.mass_matrix(q), tables.mass_matrix(q)) < 1e-12
        assert abs(nodes.kinetic_energy(q, u) - tables.kinetic_energy(q, u)) < 1e-12 * tables.kinetic_energy(q, u)
        assert rel(nodes.angular_momentum(q, u), tables.angular_momentum(q, u)) < 1e-12


@pytest.mark.parametrize("order", [1, 2])
@pytest.mark.parametrize("refine", [False, True])
def test_node_terms_match_the_nodal_reference(order, refine, monkeypatch):
    """A free-free body through the refined (and the factored) modal mass against the brute-force nodal
    formulation, at modal deformations from 1e-3 (two or three refinements) to 4 at order 2 (node rotations of
    several radians, far past any modal model's validity: the refinement stops contracting and the forward
    dynamics factors G(eta); order 1's truncated mass matrix is no longer positive definite there)."""
    monkeypatch.setattr(dynamics.system, "refinement_budget", lambda n, count: 60 if refine else 0)
    model = random_node_model(8, 4, seed=60 + order)
    system = _body(model, order, nodal=True)
    rng = np.random.default_rng(7 + order)
    fell_back = []
    for size in (1e-3, 1e-1, 0.5) + ((4.0, 8.0, 16.0) if order == 2 else ()):
        q, u, tau = _state(system, 4, rng, size)
        ref = reference_free_free(model, order, u, q[7:], tau)
        assert rel(system.forward_dynamics(q, u, tau), ref) < 1e-10
        if refine:
            udot, out = np.zeros(system.nu), np.zeros(system.nu)
            status = AB._forward_dynamics(system.topology, system.nodes, system.joint_rot, system.joint_vec,
                                          system.params, q, u, tau, np.zeros((system.nnodes, 6)),
                                          np.zeros((system.nbodies, 6)), udot, out, system.ws_rot, system.ws_vec,
                                          system.ws_mat, system.pool, False)
            assert status in (0, AB.NOT_CONVERGED) and (status == 0 or size > 1.0)
            fell_back.append(status == AB.NOT_CONVERGED)
    assert not refine or order == 1 or any(fell_back)  # the factored fall-back was exercised


def test_dense_solver_with_node_terms():
    """The dense solve (composite-inertia mass matrix with G(eta) formed over the nodes) equals the ABA."""
    model = random_node_model(9, 5, seed=71)
    aba = _body(model, 2, nodal=True, wheel=True)
    dense = _body(model, 2, nodal=True, wheel=True, solver="dense")
    rng = np.random.default_rng(3)
    for _ in range(3):
        q, u, tau = _state(aba, 5, rng)
        assert rel(dense.forward_dynamics(q, u, tau), aba.forward_dynamics(q, u, tau)) < 1e-11


def _skew(v):
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


@pytest.mark.parametrize("terms", ["G1", "G2", "G1 G2 F2"])
@pytest.mark.parametrize("offsets", [False, True])
@pytest.mark.parametrize("count, n", [(7, 1), (7, 3), (7, 4), (7, 5), (7, 8), (7, 11), (11, 160), (12, 161)])
def test_formed_modal_mass_equals_the_node_sum(terms, offsets, count, n):
    """``node_inertia_modal_mass`` (formed by blocks of TILE modes, two rows at a time, lower triangle mirrored)
    against the node sum of its docstring written out here with NumPy, node by node: ``lambda_j' dJ_j lambda_j``
    with ``dJ = theta~ J - J theta~`` [G1] ``- theta~ J theta~`` [G2] and, with G1, the offsets'
    ``m (lambda_j' dP gamma_j + gamma_j' dP' lambda_j)``, ``dP = (theta x p)~``; mode counts below, at and past
    the tile's four (every remainder of the blocks and of the row pairs). Also ``node_inertia_times`` against the
    formed matrix: over the mode-major shapes (few modes) and over the node-major copy (from NODE_MAJOR_MODES = 96
    modes, two nodes at a time: 11 nodes leave one over, 12 none). Tolerance 1e-13 of the sum of the summands' sizes (``|lambda|' |dJ| |lambda|``; the sum itself
    cancels to zero at one mode, plus the 2 that ``G`` holds on entry): the same ~30 N products summed in another
    order."""
    from dynamics.kernels.node_inertia import (
        NODE_STATE, node_inertia_modal_mass, node_inertia_terms, node_inertia_times, node_params)
    from dynamics.layout import NODE_F2, NODE_G1, NODE_G2

    bits = sum({"G1": NODE_G1, "G2": NODE_G2, "F2": NODE_F2}[t] for t in terms.split())
    model = random_node_model(count, n, seed=90 + n)
    if not offsets:
        model.cg[:] = 0.0
    rng = np.random.default_rng(n)
    eta, e, V = 0.3 * rng.standard_normal(n), rng.standard_normal(n), rng.standard_normal(6)
    params = np.concatenate([[7.0, 8.0], node_params(model.mass, model.cg, model.inertia, model.shapes)])
    state = np.zeros(NODE_STATE * count)
    node_inertia_terms(params, 2, count, n, bits, eta, V, e, True, np.zeros((6, n)), np.zeros(6), np.zeros(n), state)
    G = np.full((n, n), 2.0)
    node_inertia_modal_mass(params, 2, count, n, bits, state, G)
    ref = np.full((n, n), 2.0)
    size = np.zeros((n, n))
    for j in range(count):
        lam, gam = model.shapes[j, :3], model.shapes[j, 3:]
        theta = lam @ eta
        t, J = _skew(theta), model.inertia[j]
        dJ = (t @ J - J @ t if "G1" in terms else 0.0) - (t @ J @ t if "G2" in terms else 0.0)
        ref += lam.T @ dJ @ lam
        size += np.abs(lam).T @ np.abs(dJ) @ np.abs(lam)
        if "G1" in terms:
            dP = _skew(np.cross(theta, model.cg[j]))
            ref += model.mass[j] * (lam.T @ dP @ gam + gam.T @ dP.T @ lam)
            part = np.abs(lam).T @ np.abs(dP) @ np.abs(gam)
            size += model.mass[j] * (part + part.T)
    assert np.abs(G - ref).max() <= 1e-13 * (size.max() + 2.0)  # G held 2 on entry: it is added to
    x, out = rng.standard_normal(n), np.zeros(n)
    node_inertia_times(params, 2, count, n, bits, state, x, out)
    assert np.abs(out - (ref - 2.0) @ x).max() <= 1e-13 * size.max() * np.abs(x).sum()


@pytest.mark.parametrize("n", [1, 2, 3, 4, 5, 6, 7, 9])
def test_shape_passes_equal_numpy(n):
    """The passes over the stacked shapes (four rows at a time in ``shapes_times`` and ``_shapes_dot``, two in
    ``columns_times``'s register tile; every remainder of both) against NumPy's products, with and without their
    optional halves. Tolerance 1e-14 of the sum of the products' sizes: the same sums in another order."""
    from dynamics.kernels.node_inertia import columns_times, shapes_times

    rng = np.random.default_rng(n)
    width = 3 * 5
    S = rng.standard_normal((n, width))
    params = np.concatenate([[9.0, 9.0, 9.0], S.ravel(), [9.0]])
    x, y = rng.standard_normal(n), rng.standard_normal(n)
    W, z = rng.standard_normal(3 * width), rng.standard_normal(width)
    size = np.abs(S).sum()
    for with_y in (False, True):
        out_x, out_y = np.full(width, 7.0), np.full(width, 7.0)
        shapes_times(params, 3, n, width, x, y, out_x, out_y, with_y)
        assert np.abs(out_x - S.T @ x).max() <= 1e-14 * size * np.abs(x).max()
        assert np.abs(out_y - (S.T @ y if with_y else 0.0)).max() <= 1e-14 * size * np.abs(y).max()
    for with_c, with_dot in ((True, True), (True, False), (False, True)):
        Mre, bm = np.full((6, n), 2.0), np.full(n, 3.0)
        columns_times(params, 3, n, width, W, z, 3, with_c, with_dot, Mre, bm)
        rows = W.reshape(3, width) @ S.T
        assert np.abs(Mre[:3] - 2.0).max() == 0.0
        assert np.abs(Mre[3:] - (2.0 + rows if with_c else 2.0)).max() <= 1e-14 * size * np.abs(W).max()
        assert np.abs(bm - (3.0 + S @ z if with_dot else 3.0)).max() <= 1e-14 * size * np.abs(z).max()


@pytest.mark.parametrize("terms", ["G1 G2 F2", "G2"])
@pytest.mark.parametrize("offsets", [False, True])
@pytest.mark.parametrize("count, n", [(11, 1), (11, 4), (11, 5), (11, 9), (11, 20), (11, 165), (12, 161), (3, 160),
                                      (1, 170)])
def test_single_precision_product_equals_the_double_one(terms, offsets, count, n):
    """``node_inertia_times_single`` (the refinement's late corrections, over the float32 copy of the shapes that
    ``node_params`` appends) against ``node_inertia_times`` of ``x - prev`` in double precision, and the copy against
    the shapes rounded to float32: mode-major (``Lambda`` and, with offsets, ``Gamma``: fewer than
    ``NODE_MAJOR_MODES`` modes, or more than 15 per node: 3 nodes and 160 modes, 1 and 170) and node-major (per node
    its rows ``lambda_j`` and with offsets ``gamma_j``, one sweep: 11 nodes and 165 modes, exactly 15 per node; 12
    and 161); with G1 (the offsets' terms) and without (G2 alone: the copy still holds ``Gamma`` with offsets).
    Tolerance 5e-7 of the summands' size (``|Lambda|' |dJ| |Lambda| |x - prev|`` plus the offsets' terms): float32's
    6e-8 relative rounding, accumulated over the 3 N entries of the back products and the n of the forward ones
    (observed <= 2.2e-8 of that size, <= 2.1e-7 of the result's largest entry); and at least 1e-10 of that size away
    from the double result past one mode (observed >= 2.2e-9): it is computed in single precision."""
    from dynamics.kernels.node_inertia import (
        NODE_MAJOR_MODES, NODE_STATE, node_inertia_terms, node_inertia_times, node_inertia_times_single, node_params,
        node_major)
    from dynamics.layout import NODE_F2, NODE_G1, NODE_G2

    bits = sum({"G1": NODE_G1, "G2": NODE_G2, "F2": NODE_F2}[t] for t in terms.split())
    model = random_node_model(count, n, seed=40 + n)
    if not offsets:
        model.cg[:] = 0.0
    rng = np.random.default_rng(n)
    eta, e, V = 0.3 * rng.standard_normal(n), rng.standard_normal(n), rng.standard_normal(6)
    packed = node_params(model.mass, model.cg, model.inertia, model.shapes)
    params = np.concatenate([[7.0, 8.0], packed, [9.0]])
    rows = 6 if offsets else 3
    size = count * rows * n
    major = node_major(count, n)
    assert major == (n >= NODE_MAJOR_MODES and n <= 15 * count)
    start = 1 + 13 * count + 6 * count * n
    if major:  # the node-major double copy, then the float32 one
        copy = model.shapes[:, :rows, :].ravel()
        assert np.array_equal(packed[start:start + size], copy)
        start += size
    else:
        copy = np.concatenate([np.transpose(model.shapes[:, :3, :], (2, 1, 0)).ravel(),
                               np.transpose(model.shapes[:, 3:, :], (2, 1, 0)).ravel() if offsets else []])
    single = packed[start:].view(np.float32)
    assert single.size == size + size % 2
    assert np.array_equal(single[:size], copy.astype(np.float32))
    state = np.full(NODE_STATE * count, np.nan)
    node_inertia_terms(params, 2, count, n, bits, eta, V, e, True, np.zeros((6, n)), np.zeros(6), np.zeros(n), state)
    x, prev = rng.standard_normal(n), rng.standard_normal(n)
    ref = np.full(n, 3.0)
    node_inertia_times(params, 2, count, n, bits, state, x - prev, ref)
    out = np.full(n, 3.0)
    node_inertia_times_single(params, 2, count, n, bits, state, x, prev, out)
    size, d = np.zeros(n), np.abs(x - prev)
    for j in range(count):
        lam, gam = np.abs(model.shapes[j, :3]), np.abs(model.shapes[j, 3:])
        theta = model.shapes[j, :3] @ eta
        t, J = _skew(theta), model.inertia[j]
        dJ = (t @ J - J @ t if "G1" in terms else 0.0) - t @ J @ t
        size += lam.T @ np.abs(dJ) @ lam @ d
        if "G1" in terms:
            dP = np.abs(_skew(np.cross(theta, model.cg[j])))
            size += model.mass[j] * (lam.T @ dP @ gam + gam.T @ dP @ lam) @ d
    assert np.abs(out - ref).max() <= 5e-7 * size.max()
    if n > 1:  # one mode: a few float32 roundings that may all be exact
        assert np.abs(out - ref).max() >= 1e-10 * size.max()
