"""The O(n^2) flexible-body step and what comes with it: modal condensation against dense solves, terms
left out of M(eta) against the brute-force nodal formulation, the default modal-integral order, the
order-limited modal integrals, the dense solver and node kinematics after the forward dynamics.

References and tolerances:

* forward dynamics against ``solve(mass_matrix(q), tau - bias_forces(q, u))`` (composite inertia and
  Newton-Euler, no articulated-body elimination): 1e-10 relative, the issue-4 figure; observed <= 1e-12;
* a 500 kg mass on the tip of the FE beam (a child much heavier than the body's modal mass, where a
  non-symmetric Woodbury form lost 5 digits): the same comparison to 1e-12, observed 3e-13 (the dense
  solve itself is good to about eps cond(M) = 2e-11 of the largest component, so the test compares the
  two accelerations in the norm, where both are far better);
* terms omitted from M(eta) (``omit_terms``): the nodal formulation of ``tests/flexible/test_brute_force``
  with the same blocks removed from its Taylor polynomial of M(eta), 1e-10 relative (observed ~1e-15);
* the order-limited modal integrals equal the corresponding integrals of the full computation to
  round-off (1e-13 relative: the same sums, in a different grouping only where noted in the code).
"""

from __future__ import annotations

import dataclasses
import warnings

import numpy as np
import pytest

from dynamics import ModelDefinitionError, Multibody, engine
from dynamics import layout as L
from dynamics.flex.modal_integrals import modal_integrals
from dynamics.flexible_body import FlexibleBodyData, flexible_body_from_modal_body, mass_matrix_polynomial
from dynamics.system import choose_solver  # the real one: tests/flexible/conftest.py forces "aba" in compile()

from .random_flexible import flexible_body_data, random_node_model
from .test_brute_force import H, derivatives, nodal_mass_matrix
from .test_flexible_tree import flexible_tree, random_state


def rel(a, b):
    return np.linalg.norm(np.asarray(a) - np.asarray(b)) / np.linalg.norm(b)


def dense_accelerations(system, q, u, tau, **forces):
    return np.linalg.solve(system.mass_matrix(q), tau - system.bias_forces(q, u, **forces))


def tree_with_heavy_children(order, child_grid, diagonal_modal_mass):
    """A flexible bus carrying three children on two of its nodes (one node shared: a rank-12 update),
    one of them heavy, and a flexible panel hinged at its own grid (``child_grid``: the rank-12 term of
    the hinge on a deforming node of the body)."""
    model = random_node_model(8, 5, seed=7, scale=0.2)
    data = flexible_body_data(model, order)
    if diagonal_modal_mass:  # a mass-normalized body: G0 = I exactly, so G^-1 is its diagonal
        data = dataclasses.replace(data, M0=data.M0.copy())
        data.M0[6:, 6:] = np.eye(data.n_modes)
    mb = Multibody(gravity=(0.0, 0.0, -9.81))
    mb.add_flexible_body("bus", None, modal=data, hinge="free")
    mb.add_node("bus_a", "bus", grid=8)
    mb.add_node("bus_b", "bus", grid=3, rotation=[np.cos(0.2), 0.0, np.sin(0.2), 0.0])
    mb.add_body("wheel", "bus", mass=50.0, inertia=[2.0, 1.0, 1.0], hinge="revolute", axis=(1.0, 0.0, 0.0),
                parent_node="bus_a")
    mb.add_body("tank", "bus", mass=400.0, com=(0.1, 0.0, 0.0), inertia=[30.0, 40.0, 50.0], hinge="locked",
                parent_node="bus_a", inboard_position=(0.3, 0.0, 0.0))
    panel = flexible_body_data(random_node_model(5, 3, seed=8, scale=0.2), min(order, 1))
    kwargs = {"child_grid": 1} if child_grid else {}
    mb.add_flexible_body("panel", "bus", modal=panel, hinge="revolute", axis=(0.0, 0.0, 1.0), parent_node="bus_b",
                         **kwargs)
    mb.add_node("panel_tip", "panel", grid=5)
    return mb


@pytest.mark.parametrize("order", [0, 1, 2])
@pytest.mark.parametrize("child_grid", [False, True])
@pytest.mark.parametrize("diagonal", [False, True])
def test_condensation_equals_dense_solve(order, child_grid, diagonal):
    mb = tree_with_heavy_children(order, child_grid, diagonal)
    aba, dense = mb.compile(solver="aba"), mb.compile(solver="dense")
    kind = aba.topology[0, L.FLEX + L.FX_GINV_KIND]  # the three ways G^-1 is applied
    assert kind == (L.GINV_FACTORED if order >= 1 else (L.GINV_DIAGONAL if diagonal else L.GINV_DENSE))
    rng = np.random.default_rng(order + 2 * child_grid + 4 * diagonal)
    for _ in range(2):
        q, u, tau = random_state(aba, rng)
        f = rng.standard_normal((aba.nnodes, 6))
        ref = dense_accelerations(aba, q, u, tau, node_forces=f)
        assert rel(aba.forward_dynamics(q, u, tau, node_forces=f), ref) < 1e-10
        assert rel(dense.forward_dynamics(q, u, tau, node_forces=f), ref) < 1e-10


def test_heavy_tip_mass_on_the_fe_beam_keeps_round_off_accuracy(tmp_path):
    from dynamics.flex import Fem2ModalOptions, fem2modal

    from .test_system_modes import ALL, case_lumped_mass, single_beam

    deck = str(single_beam().write(tmp_path / "single_beam.dat"))
    bodies = {"a101": fem2modal(deck, Fem2ModalOptions(n_modes=20, aset=[(101, ALL)]))}
    _, _, system, q0, _, _ = case_lumped_mass(bodies, tmp_path, True)
    rng = np.random.default_rng(1)
    q = q0.copy()
    q[7:] += 1e-3 * rng.standard_normal(system.nq - 7)
    system.normalize_quaternions(q)
    u, tau = 0.1 * rng.standard_normal(system.nu), rng.standard_normal(system.nu)
    assert rel(system.forward_dynamics(q, u, tau), dense_accelerations(system, q, u, tau)) < 1e-12


def reference_without(model, order, omitted, x, eta, tau):
    """Free-free Euler-Poincare/Lagrange equations (as ``reference_free_free``) of the nodal M(eta)
    truncated at ``order`` with the ``omitted`` blocks removed from its Taylor polynomial."""
    n = len(eta)
    N = 6 + n
    M0 = nodal_mass_matrix(model, np.zeros(n)).real
    D1 = np.array([nodal_mass_matrix(model, 1j * H * np.eye(n)[r]).imag / H for r in range(n)])
    # second derivatives by complex steps of the first: D2[r, s] = d2M / deta_r deta_s
    D2 = np.zeros((n, n, N, N))
    if order == 2:
        eps = 1e-4  # central differences of the complex-step derivative; exact for a quadratic in eta
        for s in range(n):
            e = eps * np.eye(n)[s]
            plus = [nodal_mass_matrix(model, e + 1j * H * np.eye(n)[r]).imag / H for r in range(n)]
            minus = [nodal_mass_matrix(model, -e + 1j * H * np.eye(n)[r]).imag / H for r in range(n)]
            D2[:, s] = (np.array(plus) - np.array(minus)) / (2 * eps)
    blocks = {"G1": (1, slice(6, None), slice(6, None)), "G2": (2, slice(6, None), slice(6, None)),
              "F2": (2, slice(0, 3), slice(6, None))}
    for name in omitted:
        k, rows, cols = blocks[name]
        D = D1 if k == 1 else D2
        D[..., rows, cols] = 0.0
        D[..., cols, rows] = 0.0

    def Mfun(e):
        M = M0 + np.einsum("rab,r->ab", D1, e) if order >= 1 else M0 + 0 * e[0]
        if order == 2:
            M = M + 0.5 * np.einsum("rsab,r,s->ab", D2, e, e)
        return M

    M = Mfun(eta).real
    D = derivatives(Mfun, eta)
    etad = x[6:]
    h = M @ x
    rhs = tau - sum(D[r] * etad[r] for r in range(n)) @ x
    rhs[:3] -= np.cross(x[:3], h[:3]) + np.cross(x[3:6], h[3:6])
    rhs[3:6] -= np.cross(x[:3], h[3:6])
    rhs[6:] += np.array([0.5 * x @ D[r] @ x for r in range(n)])
    rhs[6:] -= model.stiffness @ eta + model.damping @ etad
    return np.linalg.solve(M, rhs)


@pytest.mark.parametrize("order, omitted", [(1, ("G1",)), (2, ("G1", "F2", "G2")), (2, ("G2",)), (2, ("F2",))])
def test_omitted_terms_match_the_nodal_formulation_without_them(order, omitted):
    model = random_node_model(8, 4, seed=50 + order, scale=0.3)
    mb = Multibody()
    mb.add_flexible_body("beam", None, modal=flexible_body_data(model, order), hinge="free", omit_terms=omitted)
    system = mb.compile()
    column = {"G1": L.FX_G1, "F2": L.FX_F2, "G2": L.FX_G2}
    for name in ("G1", "F2", "G2"):
        stored = system.topology[0, L.FLEX + column[name]] >= 0
        assert stored == (name not in omitted and (order == 2 or name == "G1")), name
    rng = np.random.default_rng(order)
    for _ in range(2):
        q = system.neutral_configuration()
        q[:4] = rng.standard_normal(4)
        q[:4] /= np.linalg.norm(q[:4])
        q[4:7] = rng.standard_normal(3)
        q[7:] = 0.1 * rng.standard_normal(4)
        u, tau = rng.standard_normal(system.nu), rng.standard_normal(system.nu)
        ref = reference_without(model, order, omitted, u, q[7:], tau)
        assert rel(system.forward_dynamics(q, u, tau), ref) < 1e-10
    with pytest.raises(ModelDefinitionError, match="omit_terms: only"):
        Multibody().add_flexible_body("beam", None, modal=flexible_body_data(model, order), hinge="free",
                                      omit_terms=("J1",))


@pytest.fixture(scope="module")
def fe_beam_body():
    from dynamics.flex.pipeline import Fem2ModalOptions, fem2modal

    return fem2modal("configs/fem/single_length_beam.dat", Fem2ModalOptions(n_modes=6, modal_integrals=True))


def test_order_2_without_the_g2_table_sums_over_the_nodes(fe_beam_body):
    """A file written without G2 (what fem2modal does above 40 modes for nodes with rotational inertia) gives
    order 2 by default, with G1, F2, G2 summed over its grids (issue 28: order 2 at any mode count; until
    then the default fell back to order 1 with a warning and order 2 was refused): silently, and the same
    dynamics as the file with the table (1e-12: the same sums in another order)."""
    without_g2 = dataclasses.replace(
        fe_beam_body, modal_integrals=dataclasses.replace(fe_beam_body.modal_integrals, G2=None))
    assert np.any(fe_beam_body.node_inertia)
    systems = []
    for body in (without_g2, fe_beam_body):
        mb = Multibody()
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            mb.add_flexible_body("beam", None, modal=body, hinge="free")
        assert mb.bodies[0].flexible.order == 2
        systems.append(mb.compile())
    # no note but the round-off of the file's modal stiffness (dynamics.system.MODAL_DIAGONAL_TOLERANCE)
    assert [n for n in systems[0].notes if "modal stiffness applied as its diagonal" not in n] == []
    assert mb_terms(systems[0]) == ("G1", "F2", "G2")
    rng = np.random.default_rng(11)
    for _ in range(3):
        q, u, tau = random_state(systems[0], rng)
        a, b = systems[0].forward_dynamics(q, u, tau), systems[1].forward_dynamics(q, u, tau)
        assert np.linalg.norm(a - b) <= 1e-12 * np.linalg.norm(b)
    # the point-mass integrals need no G2: order 2 by default
    assert flexible_body_from_modal_body(without_g2, integrals="point_mass").order == 2


def mb_terms(system):
    """The terms of M(eta) body 0 sums over its nodes."""
    fx = system.topology[0, L.FLEX:]
    return tuple(t for t, bit in (("G1", L.NODE_G1), ("F2", L.NODE_F2), ("G2", L.NODE_G2))
                 if fx[L.FX_NODES] >= 0 and fx[L.FX_NODE_TERMS] & bit)


def test_body_file_terms_equal_the_polynomial_form(fe_beam_body):
    """The compact terms built from the integrals (no n N^2 arrays) give the same dynamics as the full
    M1, M2 polynomial of ``mass_matrix_polynomial``."""
    compact = Multibody()
    compact.add_flexible_body("beam", None, modal=fe_beam_body, hinge="free", order=2)
    M0, M1, M2 = mass_matrix_polynomial(fe_beam_body.modal_integrals, 2)
    data = compact.bodies[0].flexible
    poly = Multibody()
    poly.add_flexible_body("beam", None, hinge="free", modal=FlexibleBodyData(
        n_modes=data.n_modes, order=2, M0=M0, M1=M1, M2=M2, stiffness=data.stiffness, damping=data.damping,
        grid_ids=data.grid_ids, grid_positions=data.grid_positions, grid_shapes=data.grid_shapes,
        frequencies_hz=data.frequencies_hz))
    a, b = compact.compile(), poly.compile()
    rng = np.random.default_rng(5)
    q, u, tau = random_state(a, rng)
    assert rel(a.forward_dynamics(q, u, tau), b.forward_dynamics(q, u, tau)) < 1e-13


def test_order_limited_integrals_equal_the_full_computation():
    rng = np.random.default_rng(9)
    N, n = 9, 5
    args = (rng.uniform(0.5, 2, N), rng.normal(scale=0.05, size=(N, 3)),
            np.array([0.01 * (A @ A.T) for A in rng.normal(size=(N, 3, 3))]), rng.normal(size=(N, 3)),
            rng.normal(scale=0.3, size=(N, 3, n)), rng.normal(scale=0.3, size=(N, 3, n)))
    full = modal_integrals(*args)
    for order, omit in ((0, ()), (1, ()), (1, ("G1",)), (2, ("F2", "G2"))):
        part = modal_integrals(*args, order=order, omit=omit)
        for name, value in full.arrays().items():
            got = getattr(part, name)
            expected_present = {"p1": 1, "J1": 1, "F1": 1, "E1": 1, "G1": 1, "J2": 2, "F2": 2, "G2": 2}.get(name, 0)
            if order < expected_present or name in omit:
                assert got is None, (order, omit, name)
            else:
                np.testing.assert_allclose(got, value, rtol=1e-13, atol=1e-13 * np.abs(value).max(),
                                           err_msg=f"{name} at order {order}")
    with pytest.raises(ValueError, match="omit: only G1, F2 and G2"):
        modal_integrals(*args, omit=("J2",))


@pytest.mark.parametrize("solver", ["aba", "dense"])
def test_node_kinematics_after_dynamics_equals_node_kinematics(solver):
    """The engine's shortcut reuses the forward-dynamics workspace; it must equal the full node
    kinematics (flexible tree, gravity, node forces), to round-off (1e-12 relative)."""
    system = flexible_tree(order=2)
    if solver == "dense":
        system = type(system).from_definitions(*system.definitions, solver="dense")
    d = engine.engine_data(system)
    rng = np.random.default_rng(11)
    q, u, tau = random_state(system, rng)
    f = rng.standard_normal((system.nnodes, 6))
    udot, tau_out = np.zeros(system.nu), np.empty(system.nu)
    assert engine.forward_dynamics(d, q, u, tau, f, udot, tau_out) == 0
    assert rel(udot, system.forward_dynamics(q, u, tau, node_forces=f)) < 1e-12
    out = [np.empty((system.nnodes, 3, 3)), np.empty((system.nnodes, 3)), np.empty((system.nnodes, 6)),
           np.empty((system.nnodes, 6))]
    assert engine.forward_dynamics(d, q, u, tau, f, udot, tau_out) == 0
    engine.node_kinematics_after_dynamics(d, q, u, udot, *out)
    ref = [np.empty_like(a) for a in out]
    engine.node_kinematics(d, q, u, udot, *ref)
    for got, expected in zip(out, ref):
        assert rel(got, expected) < 1e-12


@pytest.mark.parametrize("order", [0, 1, 2])
def test_dense_solver_matches_the_nodal_reference(order):
    """The dense solve (composite inertia, Newton-Euler, Cholesky) against the brute-force nodal
    formulation, as the recursion is in test_brute_force.py (1e-10 relative)."""
    from .test_brute_force import reference_free_free

    model = random_node_model(8, 4, seed=10 + order)
    mb = Multibody()
    mb.add_flexible_body("beam", None, modal=flexible_body_data(model, order), hinge="free")
    system = mb.compile(solver="dense")
    assert system.solver == "dense" and "requested" in system.solver_reason
    rng = np.random.default_rng(order)
    q = system.neutral_configuration()
    q[:4] = rng.standard_normal(4)
    q[:4] /= np.linalg.norm(q[:4])
    q[4:7] = rng.standard_normal(3)
    q[7:] = 0.1 * rng.standard_normal(4)
    u, tau = rng.standard_normal(system.nu), rng.standard_normal(system.nu)
    assert rel(system.forward_dynamics(q, u, tau), reference_free_free(model, order, u, q[7:], tau)) < 1e-10


def test_compile_chooses_and_reports_the_cheaper_solver():
    """Dense for small systems (one flexible body of a few modes, the 5-body tree of test_flexible_tree:
    measured 10-40 % faster, docs/engine.md), the recursion for large bodies and long chains; the choice
    is in the repr and the summary."""
    def one_body(n_modes):
        mb = Multibody()
        mb.add_flexible_body("beam", None, modal=flexible_body_data(random_node_model(3 * n_modes, n_modes, seed=1,
                                                                                      point_masses=True), 1),
                             hinge="free")
        return choose_solver(mb.compile("aba").topology)

    assert one_body(5)[0] == "dense" and one_body(60)[0] == "aba"
    assert "dense M udot = tau - h (estimated" in one_body(5)[1]
    assert choose_solver(flexible_tree(order=1).topology)[0] == "dense"
    mb = Multibody()
    for i in range(12):
        mb.add_flexible_body(f"b{i}", None if i == 0 else f"b{i - 1}", hinge="free" if i == 0 else "spherical",
                             modal=flexible_body_data(random_node_model(5, 3, seed=i), 1),
                             **({} if i == 0 else {"parent_node": f"tip{i - 1}"}))
        mb.add_node(f"tip{i}", f"b{i}", grid=5)
    chain = mb.compile()
    assert choose_solver(chain.topology)[0] == "aba"
    assert "solver=aba" in repr(chain) and "solver: articulated-body recursion" in chain.summary()
