"""The refinement of a modal mass that varies through node terms (dynamics.kernels.articulated_body: G(eta) = G0 +
dG refined against the constant G0) in trees where the refined body is neither the root nor the last body, and the
solver choice's prices (dynamics.system.choose_solver, refinement_budget).

Reference: the same system with G(eta) formed and factored on every evaluation (refinement budget 0: no iteration),
itself checked against the tables and the brute-force nodal formulation in tests/flexible/test_node_inertia.py, and
the dense solve. Tolerance 1e-12 relative: the refinement stops when its next correction would be below 1e-14 of the
largest modal acceleration, and the two eliminations sum the same terms in another order (observed <= 3e-16).
"""

from __future__ import annotations

import numpy as np
import pytest

import dynamics.system
from dynamics import Multibody
from dynamics.layout import FLEX, FX_REFINE, P_REFINEMENTS, VEC_A

from .random_flexible import flexible_body_data, random_node_model
from .test_brute_force import rel


def _tree(budget, solver="aba", monkeypatch=None, nodes=9, modes=6):
    """A rigid bus (free) with, in body order: a rigid arm, the flexible panel (revolute on the bus, its modal mass
    refined or factored per ``budget``), a wheel on a node of the panel, a rigid boom on the bus with a prescribed
    hinge, and a tip mass on the wheel: bodies before the panel, after it and hanging from it."""
    monkeypatch.setattr(dynamics.system, "refinement_budget", lambda n, count: budget)
    model = random_node_model(nodes, modes, seed=81)
    mb = Multibody()
    mb.add_body("bus", None, mass=50.0, inertia=[4.0, 5.0, 6.0], com=(0.02, 0.01, 0.0), hinge="free")
    mb.add_body("arm", "bus", mass=3.0, inertia=[0.1, 0.2, 0.2], com=(0.3, 0.0, 0.0), hinge="revolute",
                axis=(0.0, 0.0, 1.0), inboard_position=(0.5, 0.0, 0.0))
    mb.add_flexible_body("panel", "bus", modal=flexible_body_data(model, 1, nodal=True), hinge="revolute",
                         axis=(0.0, 1.0, 0.0), inboard_position=(0.0, 0.6, 0.0))
    mb.add_node("mount", "panel", grid=4)
    mb.add_body("wheel", "panel", mass=4.0, inertia=[0.08, 0.05, 0.05], com=(0.01, 0.0, 0.02), hinge="revolute",
                axis=(1.0, 0.0, 0.0), parent_node="mount")
    mb.add_body("boom", "bus", mass=2.0, inertia=[0.05, 0.3, 0.3], com=(0.0, 0.0, 0.4), hinge="revolute",
                axis=(1.0, 0.0, 0.0), inboard_position=(0.0, 0.0, -0.5), prescribed=True)
    mb.add_body("tip", "wheel", mass=0.5, inertia=[0.01, 0.01, 0.01], hinge="revolute", axis=(0.0, 1.0, 0.0),
                inboard_position=(0.0, 0.1, 0.0))
    return mb.compile(solver=solver)


def test_bodies_before_and_after_the_refined_body(monkeypatch):
    """Accelerations, the prescribed hinge's force and every body's spatial acceleration in the workspace equal the
    factored modal mass's: the bodies after the last refined one (boom, tip, here also the wheel) get theirs once,
    from the accepted iterate, the others on every refinement."""
    refined = _tree(60, monkeypatch=monkeypatch)
    factored = _tree(0, monkeypatch=monkeypatch)
    dense = _tree(0, solver="dense", monkeypatch=monkeypatch)
    panel = refined.body_index("panel")
    assert refined.topology[panel, FLEX + FX_REFINE] and not factored.topology[panel, FLEX + FX_REFINE]
    rng = np.random.default_rng(5)
    n = refined.n_modes[panel]
    for size in (1e-3, 3e-2):
        # q: bus (quaternion, position), arm, the panel's hinge angle and its n modal coordinates, wheel, boom, tip
        q = refined.neutral_configuration()
        q[:4] = rng.standard_normal(4)
        q[:4] /= np.linalg.norm(q[:4])
        q[4:] = 0.1 * rng.standard_normal(refined.nq - 4)
        q[9:9 + n] = size * rng.standard_normal(n)
        u, tau = rng.standard_normal(refined.nu), rng.standard_normal(refined.nu)
        accel = np.zeros(refined.nu)
        accel[-2] = 0.7  # the boom's prescribed acceleration
        udot, forces = refined.forward_dynamics(q, u, tau, prescribed_accel=accel, return_forces=True)
        assert refined.pool[P_REFINEMENTS] > 0
        workspace = refined.ws_vec[:, VEC_A].copy()
        ref, ref_forces = factored.forward_dynamics(q, u, tau, prescribed_accel=accel, return_forces=True)
        assert rel(udot, ref) < 1e-12 and rel(forces, ref_forces) < 1e-12
        assert rel(workspace, factored.ws_vec[:, VEC_A]) < 1e-12
        assert rel(udot, dense.forward_dynamics(q, u, tau, prescribed_accel=accel)) < 1e-11


def _node_deck(n_nodes, n_modes, order, node_mass, wheel):
    import dataclasses

    from dynamics.flexible_body import node_mass_from_nodes

    model = random_node_model(n_nodes, n_modes, seed=3)
    data = flexible_body_data(model, order, nodal=True)
    if node_mass:
        nodes = node_mass_from_nodes(model.mass, model.cg, model.inertia, model.position, model.shapes, order)
        data = dataclasses.replace(data, terms=dataclasses.replace(data.terms, C1=None, J2=None), mass_nodes=nodes)
    mb = Multibody()
    mb.add_flexible_body("body", None, modal=data, hinge="free")
    if wheel:
        mb.add_node("mount", "body", grid=3)
        mb.add_body("wheel", "body", mass=4.0, inertia=[0.08, 0.05, 0.05], hinge="revolute", axis=(1.0, 0.0, 0.0),
                    parent_node="mount")
    return mb.compile(solver="aba")


@pytest.mark.parametrize("deck", [(9, 6, 1, False, False), (9, 6, 2, True, False), (5, 12, 2, True, False),
                                  (30, 12, 1, False, True), (107, 20, 2, False, False)])
def test_solver_choice_follows_the_cost_of_node_terms(deck):
    """Bodies whose nodes have rotary inertia (G1, F2, G2 summed over the nodes, C1 and J2 too on some): the dense
    solve evaluates the node terms twice (inverse dynamics and mass matrix) and forms G(eta) in both where the
    recursion factors it once; measured (benchmarks/flexible_scaling.py --solvers, 2026-12-07, interleaved) the
    recursion is 1.1-1.8x faster on every one of these, and main's estimate, which priced neither the second pass
    nor C1 over the nodes nor the formation of G(eta), chose the dense solve on the first three."""
    system = _node_deck(*deck)
    chosen, reason = dynamics.system.choose_solver(system.topology)
    assert chosen == "aba", reason


def test_choice_prices_what_the_body_does():
    """The estimate's parts: C1 over the nodes makes M_re vary (its six rows solved again per call) and costs the
    dense path a second evaluation; a body whose G(eta) is factored pays its formation once in the recursion and
    twice in the dense path, a refined one a refinement budget's products instead."""
    from dynamics import layout as L

    def estimates(system):
        return dynamics.system.solver_costs(system.topology)

    import dataclasses

    from dynamics.flexible_body import node_mass_from_nodes

    model = random_node_model(8, 12, seed=4, point_masses=True)
    tables = flexible_body_data(model, 1)
    nodes = node_mass_from_nodes(model.mass, model.cg, model.inertia, model.position, model.shapes, 1)
    summed = dataclasses.replace(tables, M1=None, M2=None, terms=dataclasses.replace(tables.mass_terms(), C1=None),
                                 mass_nodes=nodes)
    costs = []
    for data in (tables, summed):
        mb = Multibody()
        mb.add_flexible_body("body", None, modal=data, hinge="free")
        system = mb.compile(solver="aba")
        costs.append(estimates(system))
    assert system.topology[0, L.FLEX + L.FX_MASS_NODE_TERMS] & L.MASS_C1 and system.topology[0, L.FLEX + L.FX_C1] < 0
    assert costs[1][0] == costs[0][0]  # M_re varies either way: its rows solved again per call
    assert costs[1][1] > costs[0][1]  # C1 over the nodes evaluated a second time by the dense path
    n, count = 20, 107
    formed = dynamics.system.modal_mass_formation_cost(n, count)
    assert dynamics.system.refinement_budget(n, count) < dynamics.system.MIN_REFINEMENT_BUDGET  # factored (measured)
    assert dynamics.system.refinement_budget(100, count) >= dynamics.system.MIN_REFINEMENT_BUDGET  # refined
    factored = _node_deck(count, n, 2, False, False)
    assert not factored.topology[0, L.FLEX + L.FX_REFINE]
    aba, dense = estimates(factored)
    assert dense - aba > formed  # the second formation (and node pass) of the dense path


@pytest.mark.parametrize("size, nodes, modes", [(1e-3, 9, 6), (1e-2, 9, 6), (3e-2, 9, 6), (1e-4, 40, 160)])
def test_single_precision_corrections(size, nodes, modes, monkeypatch):
    """The late refinements take their product with ``dG`` as the correction ``dG (x_k - x_(k-1))`` in single
    precision (dynamics.kernels.articulated_body.SINGLE_BELOW); the result still equals the factored modal mass's to
    1e-12 (module docstring). That they were taken so: the product the refinement kept (``PV_DG``) differs from the
    double-precision product of the iterate it is of (``PV_PREV``) by float32's rounding of the corrections, where
    double-precision products alone would equal it exactly (the same kernel on the same numbers); and by no more
    than 1e-10 of it (the corrections are below SINGLE_BELOW = 1e-7 of the accelerations and their float32
    products within a few 1e-7 of themselves: a few 1e-14 of ``|dG| |x|``; observed <= 4.5e-16 of the product, with
    3, 4 and 5 refinements at the three sizes of the 6-mode panel). At 160 modes on 40 nodes the single-precision
    shapes are node-major (``dynamics.kernels.node_inertia.node_major``: one sweep per product)."""
    from dynamics.kernels.node_inertia import NODE_STATE, node_inertia_times, node_major
    from dynamics.layout import (FX_NODE_COUNT, FX_NODE_TERMS, FX_NODES, FX_P_NODES, FX_P_VEC, N_FX, PV_DG,
                                 PV_PREV)

    refined = _tree(60, monkeypatch=monkeypatch, nodes=nodes, modes=modes)
    factored = _tree(0, monkeypatch=monkeypatch, nodes=nodes, modes=modes)
    panel = refined.body_index("panel")
    n = refined.n_modes[panel]
    assert node_major(nodes, n) == (modes == 160)
    rng = np.random.default_rng(11)
    q = refined.neutral_configuration()
    q[9:9 + n] = size * rng.standard_normal(n)
    u, tau = rng.standard_normal(refined.nu), rng.standard_normal(refined.nu)
    udot = refined.forward_dynamics(q, u, tau)
    assert rel(udot, factored.forward_dynamics(q, u, tau)) < 1e-12
    assert refined.pool[P_REFINEMENTS] >= 3  # the third pass on takes the single-precision corrections
    fx = refined.topology[panel, FLEX:FLEX + N_FX]
    pool, count = refined.pool, fx[FX_NODE_COUNT]
    kept = pool[fx[FX_P_VEC] + PV_DG * n:fx[FX_P_VEC] + (PV_DG + 1) * n]
    double = np.zeros(n)
    node_inertia_times(refined.data.params, fx[FX_NODES], count, n, fx[FX_NODE_TERMS],
                       pool[fx[FX_P_NODES]:fx[FX_P_NODES] + NODE_STATE * count].copy(),
                       pool[fx[FX_P_VEC] + PV_PREV * n:fx[FX_P_VEC] + (PV_PREV + 1) * n].copy(), double)
    assert 0.0 < np.abs(kept - double).max() <= 1e-10 * np.abs(double).max()
