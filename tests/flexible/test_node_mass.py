"""The terms C1 and J2 summed over every node (dynamics.kernels.node_mass) against their tables.

Reference: the same body with C1 and J2 as tables (the modal integrals F1, E1, J2 of TM-2020-5008164 App. E,
themselves checked against the nodal product E.1.34 in tests/flex/test_modal_integrals.py), every other term
the same in both. Tolerance 1e-12 relative: the two representations sum the same products in another order
(round-off; observed below 1e-14), while a wrong sign or a missing factor of any single term of the node sums
moves the result by far more than that at the deformations and rates used (1e-1 modal coordinates, unit rates).
Also every term over the nodes against the brute-force nodal reference of test_brute_force.py (1e-10; leaving
C1 or J2 out moves the result by 1e-1 and 3e-2 of it there).
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import dynamics.flexible_body as FB
from dynamics import Multibody
from dynamics import layout as L
from dynamics.errors import ModelDefinitionError
from dynamics.flexible_body import node_inertia_from_nodes, node_mass_from_nodes, node_mass_is_cheaper, same_nodes

from .random_flexible import flexible_body_data, random_node_model
from .test_brute_force import rel
from .test_node_inertia import _state


def _with_node_mass(data, model, order):
    """``data`` with its tables C1 and J2 replaced by the sums over the nodes of ``model``."""
    nodes = node_mass_from_nodes(model.mass, model.cg, model.inertia, model.position, model.shapes, order)
    terms = dataclasses.replace(data.mass_terms(), C1=None, J2=None)
    return dataclasses.replace(data, M1=None, M2=None, terms=terms, mass_nodes=nodes)


def _system(data, wheel):
    mb = Multibody()
    mb.add_flexible_body("body", None, modal=data, hinge="free")
    if wheel:  # a child on a deforming node: the Woodbury path of the modal elimination
        mb.add_node("mount", "body", grid=3)
        mb.add_body("wheel", "body", mass=4.0, inertia=[0.08, 0.05, 0.05], com=(0.01, 0.0, 0.02), hinge="revolute",
                    axis=(1.0, 0.0, 0.0), parent_node="mount")
    return mb.compile(solver="aba")


def _hinged_state(system, rng):
    q = system.neutral_configuration()
    q[:] = 0.02 * rng.standard_normal(system.nq)
    return q, rng.standard_normal(system.nu), rng.standard_normal(system.nu)


@pytest.mark.parametrize("order", [1, 2])
@pytest.mark.parametrize("nodes", ["all", "none", "some", "point masses", "one point mass"])
@pytest.mark.parametrize("rotary_terms", ["tables", "nodes"])
def test_node_sums_equal_the_tables(order, nodes, rotary_terms):
    """Every algorithm, on a body with rotary node inertia and CG offsets on all, none or every other node, or of
    point masses (no rotation shapes read), or with one point mass among nodes with rotary inertia, with G1, F2, G2
    as tables or summed over the nodes too, and a wheel on one of its nodes: C1 and J2 over the nodes against the
    same body with them as tables. Where G1, F2, G2 are summed over the same nodes, C1 and J2 share their shapes and
    passes (one sweep back over each shape array for both kernels); with a point mass the node sets differ and
    each kernel keeps its own."""
    n = 6
    model = random_node_model(9, n, seed=70 + order, point_masses=nodes == "point masses")
    if nodes in ("none", "some"):
        model.cg[::1 if nodes == "none" else 2] = 0.0
    if nodes == "one point mass":
        model.cg[4] = 0.0
        model.inertia[4] = 0.0
    base = flexible_body_data(model, order, nodal=rotary_terms == "nodes")
    tables = _system(base, wheel=True)
    summed = _system(_with_node_mass(base, model, order), wheel=True)
    fx = summed.topology[0, L.FLEX:]
    assert fx[L.FX_C1] < 0 and fx[L.FX_J2] < 0 and fx[L.FX_MASS_NODES] >= 0
    assert fx[L.FX_MASS_NODE_TERMS] == (L.MASS_C1 if order == 1 else L.MASS_C1 | L.MASS_J2)
    summed_terms = "C1 over 9 nodes" if order == 1 else "C1+J2 over 9 nodes"
    assert summed_terms in summed.summary() and summed_terms not in tables.summary()  # what was compiled is said
    rotary, offset, shared = summed.params[fx[L.FX_MASS_NODES]:fx[L.FX_MASS_NODES] + 3]
    assert (rotary, offset) == (float(nodes != "point masses"), float(nodes in ("all", "some", "one point mass")))
    sharing = rotary_terms == "nodes" and nodes in ("all", "none", "some")
    assert shared == float(sharing)
    assert ("shapes shared" in summed.summary()) == sharing
    rng = np.random.default_rng(order)
    for _ in range(3):
        q, u, tau = _state(summed, n, rng)
        udot = tables.forward_dynamics(q, u, tau)
        assert rel(summed.forward_dynamics(q, u, tau), udot) < 1e-12
        assert rel(summed.inverse_dynamics(q, u, udot), tables.inverse_dynamics(q, u, udot)) < 1e-12
        assert rel(summed.bias_forces(q, u), tables.bias_forces(q, u)) < 1e-12
        assert rel(summed.mass_matrix(q), tables.mass_matrix(q)) < 1e-12
        assert abs(summed.kinetic_energy(q, u) - tables.kinetic_energy(q, u)) < 1e-12 * tables.kinetic_energy(q, u)
        assert rel(summed.angular_momentum(q, u), tables.angular_momentum(q, u)) < 1e-12


def test_terms_given_twice_are_refused():
    model = random_node_model(5, 3, seed=3)
    data = flexible_body_data(model, 2)
    both = dataclasses.replace(data, mass_nodes=node_mass_from_nodes(model.mass, model.cg, model.inertia,
                                                                     model.position, model.shapes, 2))
    with pytest.raises(ModelDefinitionError, match=r"\['C1', 'J2'\] are given both as tables and over the nodes"):
        _system(both, wheel=False)


def test_the_cheaper_form_is_chosen():
    """Over the nodes where the tables (3 n^2 and 9 n^2 numbers) outgrow the shapes (6 N n): many modes on few
    nodes; tables for few modes on many nodes."""
    model = random_node_model(100, 2, seed=4)
    nodes = node_mass_from_nodes(model.mass, model.cg, model.inertia, model.position,
                                 np.zeros((100, 6, 200)), 2)
    assert node_mass_is_cheaper(200, nodes)
    few = node_mass_from_nodes(model.mass, model.cg, model.inertia, model.position, np.zeros((100, 6, 5)), 2)
    assert not node_mass_is_cheaper(5, few)
    # where the nodes are those of G1, F2, G2 too, their rotation-shape passes serve both: node sums from fewer modes
    at = node_mass_from_nodes(model.mass, model.cg, model.inertia, model.position, np.zeros((100, 6, 120)), 2)
    same = node_inertia_from_nodes(model.mass, model.cg, model.inertia, at.shapes, 2)
    other = node_inertia_from_nodes(model.mass, model.cg, model.inertia, at.shapes + 1.0, 2)
    assert same_nodes(at, same) and not same_nodes(at, other) and not same_nodes(at, None)
    assert node_mass_is_cheaper(120, at, same) and not node_mass_is_cheaper(120, at, other)
    assert not node_mass_is_cheaper(120, at)


@pytest.fixture(scope="module")
def fe_beam_body():
    from dynamics.flex.pipeline import Fem2ModalOptions, fem2modal

    return fem2modal("configs/fem/single_length_beam.dat", Fem2ModalOptions(n_modes=6, modal_integrals=True))


@pytest.mark.parametrize("integrals", ["general", "point_mass"])
@pytest.mark.parametrize("order", [1, 2])
def test_body_file_node_sums_equal_its_tables(fe_beam_body, integrals, order, monkeypatch):
    """A body file's grids (masses, offsets, inertias, positions and shapes of the kept modes, as
    ``flexible_body_from_modal_body`` selects them) against the tables built from the file's own modal integrals
    (computed by the FEM pipeline): the same dynamics to 1e-12."""
    systems = []
    for nodal in (False, True):
        monkeypatch.setattr(FB, "node_mass_is_cheaper", lambda n, nodes, node_inertia, nodal=nodal: nodal)
        mb = Multibody()
        # point masses on a line have no inertia about it: a revolute hinge across the beam for those
        hinge = {"hinge": "free"} if integrals == "general" else {"hinge": "revolute", "axis": (0.0, 0.0, 1.0)}
        mb.add_flexible_body("beam", None, modal=fe_beam_body, order=order, integrals=integrals,
                             modes=[0, 2, 3, 5], **hinge)
        systems.append(mb.compile(solver="aba"))
    fx = [s.topology[0, L.FLEX:] for s in systems]
    assert fx[0][L.FX_C1] >= 0 and fx[0][L.FX_MASS_NODES] < 0
    assert fx[1][L.FX_C1] < 0 and fx[1][L.FX_J2] < 0 and fx[1][L.FX_MASS_NODES] >= 0
    assert fx[1][L.FX_MASS_NODE_COUNT] == np.count_nonzero(fe_beam_body.node_mass)
    rng = np.random.default_rng(5)
    for _ in range(3):
        q, u, tau = _state(systems[0], 4, rng, size=0.02) if integrals == "general" else _hinged_state(systems[0], rng)
        assert rel(systems[1].forward_dynamics(q, u, tau), systems[0].forward_dynamics(q, u, tau)) < 1e-12
        assert rel(systems[1].bias_forces(q, u), systems[0].bias_forces(q, u)) < 1e-12
        assert rel(systems[1].mass_matrix(q), systems[0].mass_matrix(q)) < 1e-12


def test_geometric_stiffening_keeps_the_tables(monkeypatch, tmp_path):
    """Geometric stiffening adds stiffness-derived parts to C1 and J2 that are not sums over the nodes: the body
    keeps both as tables however the costs compare."""
    from dynamics.flex.pipeline import Fem2ModalOptions, fem2modal
    from tests.flex.rotating_beam import rotating_beam_deck

    deck = tmp_path / "beam.dat"
    deck.write_text(rotating_beam_deck(10))
    body = fem2modal(str(deck), Fem2ModalOptions(n_modes=4, modal_integrals=True, geometric_stiffness=True))
    monkeypatch.setattr(FB, "node_mass_is_cheaper", lambda n, nodes, node_inertia: True)
    stiffened = FB.flexible_body_from_modal_body(body, order=2)
    assert stiffened.geometric_stiffening and stiffened.mass_nodes is None
    assert stiffened.terms.C1 is not None and stiffened.terms.J2 is not None and stiffened.terms.P2 is not None
    plain = FB.flexible_body_from_modal_body(body, order=2, geometric_stiffening=False)
    assert plain.mass_nodes is not None and plain.mass_nodes.terms == ("C1", "J2") and plain.terms.C1 is None


@pytest.mark.parametrize("order", [1, 2])
def test_all_node_sums_match_the_nodal_reference(order):
    """Every eta-dependent term but R1 over the nodes (C1, J2 here, G1, F2, G2 by node_inertia) against the
    brute-force nodal formulation of test_brute_force.py (the node-by-node mass matrix truncated at the order,
    differentiated by complex steps; independent of the modal-integral tables): 1e-10, as there."""
    from .test_brute_force import reference_free_free

    model = random_node_model(8, 4, seed=80 + order)
    system = _system(_with_node_mass(flexible_body_data(model, order, nodal=True), model, order), wheel=False)
    fx = system.topology[0, L.FLEX:]
    assert fx[L.FX_MASS_NODES] >= 0 and fx[L.FX_NODES] >= 0 and fx[L.FX_C1] < 0 and fx[L.FX_G1] < 0
    rng = np.random.default_rng(9 + order)
    for size in (1e-3, 1e-1, 0.5):
        q, u, tau = _state(system, 4, rng, size)
        assert rel(system.forward_dynamics(q, u, tau), reference_free_free(model, order, u, q[7:], tau)) < 1e-10
