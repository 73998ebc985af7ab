"""Random flexible bodies from explicit node data (test helper).

Nodes carry mass, CG offset and inertia (TM eq. E.1.2), undeformed positions and random mode shapes;
the modal integrals come from ``dynamics.flex.modal_integrals`` and the brute-force references in the
tests use the node data directly."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from dynamics.flex.modal_integrals import modal_integrals
from dynamics.flexible_body import (FlexibleBodyData, mass_matrix_polynomial, mass_terms_from_integrals,
                                    node_inertia_from_nodes, rigid_mass_block)


@dataclass
class NodeModel:
    mass: np.ndarray  # (N,)
    cg: np.ndarray  # (N, 3) CG offset from the node
    inertia: np.ndarray  # (N, 3, 3) about the node
    position: np.ndarray  # (N, 3)
    shapes: np.ndarray  # (N, 6, n) [lambda; gamma]
    stiffness: np.ndarray
    damping: np.ndarray


def random_node_model(n_nodes, n_modes, seed, point_masses=False, scale=0.3):
    rng = np.random.default_rng(seed)
    mass = rng.uniform(0.5, 2.0, n_nodes)
    if point_masses:
        cg = np.zeros((n_nodes, 3))
        inertia = np.zeros((n_nodes, 3, 3))
    else:
        cg = rng.uniform(-0.05, 0.05, (n_nodes, 3))
        inertia = np.zeros((n_nodes, 3, 3))
        for j in range(n_nodes):
            A = rng.standard_normal((3, 3))
            # inertia about the node: about the CG (SPD) plus the parallel-axis term
            Jc = 0.01 * (A @ A.T + 0.5 * np.eye(3))
            c = cg[j]
            inertia[j] = Jc + mass[j] * (c @ c * np.eye(3) - np.outer(c, c))
    # lateral spread keeps the undeformed inertia well conditioned, so that the first-order truncation
    # of M(eta) stays positive definite at the deformations used (it need not for slender bodies)
    position = np.column_stack([np.linspace(0.0, 2.0, n_nodes), rng.uniform(-0.4, 0.4, (n_nodes, 2))])
    shapes = scale * rng.standard_normal((n_nodes, 6, n_modes))
    omega = 2 * np.pi * np.sort(rng.uniform(0.5, 5.0, n_modes))
    K = np.diag(omega**2)
    C = np.diag(2 * 0.01 * omega)
    return NodeModel(mass, cg, inertia, position, shapes, K, C)


def flexible_body_data(model: NodeModel, order, nodal=False):
    """The body as polynomial coefficients M1, M2 (all terms as tables), or with ``nodal`` the terms G1, F2, G2
    summed over the nodes (``FlexibleBodyData.node_inertia``) and the others as tables."""
    n = model.shapes.shape[2]
    common = dict(n_modes=n, order=order, stiffness=model.stiffness, damping=model.damping,
                  grid_ids=np.arange(1, len(model.mass) + 1), grid_positions=model.position,
                  grid_shapes=model.shapes, frequencies_hz=np.sqrt(np.diag(model.stiffness)) / (2 * np.pi))
    if nodal:
        mi = modal_integrals(model.mass, model.cg, model.inertia, model.position, model.shapes[:, :3, :],
                             model.shapes[:, 3:, :], order=order, omit=("G1", "F2", "G2"))
        nodes = node_inertia_from_nodes(model.mass, model.cg, model.inertia, model.shapes, order)
        return FlexibleBodyData(M0=rigid_mass_block(mi), M1=None, M2=None, terms=mass_terms_from_integrals(mi, order),
                                node_inertia=nodes, **common)
    mi = modal_integrals(model.mass, model.cg, model.inertia, model.position, model.shapes[:, :3, :],
                         model.shapes[:, 3:, :])
    M0, M1, M2 = mass_matrix_polynomial(mi, order)
    return FlexibleBodyData(M0=M0, M1=M1, M2=M2, **common)
