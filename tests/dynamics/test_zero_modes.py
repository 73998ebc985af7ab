"""One engine: a flexible body with zero modes is a rigid body, to round-off.

The engine runs bodies without modal data whose hinges sit on fixed frames through its rigid fast path
(6 x 6 articulated-body, Newton-Euler and composite-inertia steps), and every other body through the
augmented path (modal condensation, hinges on deforming nodes, node slots, the outboard node of a
``child_grid`` hinge). Here the same random trees (every hinge type, prescribed DOFs, frame offsets,
nodes, children on nodes, gravity, node and body forces) are built twice: all rigid, and with some
bodies declared flexible with zero modes (so their nodes are "deforming" nodes with empty mode shapes
and children hang from them through the augmented path). The two must agree in forward dynamics (ABA
and the dense solver), generalized forces of prescribed DOFs, inverse dynamics, mass matrix, node
kinematics, energies and momenta.

Tolerances: the two paths add the same terms in different orders (the augmented path sums a parent's
children per node before adding them to the parent), so they differ by round-off: 1e-12 relative for
the quantities computed without a solve (~1e-15 per operation over 9-body trees; observed below 1e-14),
and ``1e-15 cond(M_ff)`` for the accelerations, which amplify their inputs' round-off by the condition
number of the free-DOF mass matrix (observed 1e-13 .. 1.4e-12 at condition numbers up to 5e3).
"""

from __future__ import annotations

import numpy as np
import pytest

from dynamics import Multibody
from dynamics import layout as L
from dynamics.flexible_body import FlexibleBodyData
from dynamics.samples import _random_inertia, _random_rotation
from dynamics.spatial import spatial_inertia
from .random_models import random_hinge_axes

HINGES = ("locked", "revolute", "prismatic", "ujoint", "spherical", "free")
NODES_PER_BODY = 3


def _hinge_kwargs(rng, hinge, allow_prescribed=True):
    kwargs = random_hinge_axes(rng, hinge)
    nu = {"locked": 0, "revolute": 1, "prismatic": 1, "ujoint": 2, "spherical": 3, "free": 6}[hinge]
    if nu and allow_prescribed:
        kwargs["prescribed"] = rng.uniform(size=nu) < 0.3
    return kwargs


def twin_trees(n_bodies, seed):
    """(rigid system, system with some zero-mode flexible bodies), the same physics."""
    rng = np.random.default_rng(seed)
    specs = []
    for i in range(n_bodies):
        hinge = "free" if i == 0 else str(rng.choice(HINGES))
        mass = rng.uniform(0.5, 3.0)
        specs.append(dict(
            parent=None if i == 0 else int(rng.integers(i)), hinge=hinge, mass=mass, com=rng.uniform(-0.3, 0.3, 3),
            inertia=_random_inertia(rng, mass), kwargs=_hinge_kwargs(rng, hinge, allow_prescribed=i > 0),
            inboard_position=rng.uniform(-0.5, 0.5, 3), inboard_rotation=_random_rotation(rng),
            outboard_position=rng.uniform(-0.3, 0.3, 3), outboard_rotation=_random_rotation(rng),
            node_positions=rng.uniform(-0.5, 0.5, (NODES_PER_BODY, 3)),
            node_rotations=[_random_rotation(rng) for _ in range(NODES_PER_BODY)],
            flexible=bool(rng.uniform() < 0.5), child_grid=bool(rng.uniform() < 0.5),
            on_node=int(rng.integers(-1, NODES_PER_BODY))))
        if i and specs[specs[-1]["parent"]]["flexible"]:
            specs[-1]["on_node"] = max(specs[-1]["on_node"], 0)  # hinges on flexible parents sit on nodes
    return _build(specs, rng, zero_modes=False), _build(specs, np.random.default_rng(seed), zero_modes=True)


def _zero_mode_data(spec, order):
    grids = NODES_PER_BODY
    return FlexibleBodyData(n_modes=0, order=order, M0=spatial_inertia(spec["mass"], spec["com"], spec["inertia"]),
                            M1=np.zeros((0, 6, 6)), M2=np.zeros((0, 0, 6, 6)), stiffness=np.zeros((0, 0)),
                            damping=np.zeros((0, 0)), grid_ids=np.arange(1, grids + 1),
                            grid_positions=spec["node_positions"], grid_shapes=np.zeros((grids, 6, 0)),
                            frequencies_hz=np.zeros(0))


def _build(specs, rng, zero_modes):
    mb = Multibody(gravity=(0.3, -0.5, -9.81))
    for i, spec in enumerate(specs):
        name = f"b{i}"
        parent = None if spec["parent"] is None else f"b{spec['parent']}"
        common = dict(hinge=spec["hinge"], inboard_position=spec["inboard_position"],
                      inboard_rotation=spec["inboard_rotation"], **spec["kwargs"])
        if parent is not None and spec["on_node"] >= 0:
            common["parent_node"] = f"{parent}_n{spec['on_node']}"
        flexible = zero_modes and spec["flexible"]
        if flexible and spec["child_grid"]:
            # the hinge's outboard frame on the body's grid 1 (node 'b<i>.hinge' at node 0's position,
            # identity rotation): outboard pose relative to that node
            common.update(child_grid=1, outboard_position=spec["outboard_position"] - spec["node_positions"][0],
                          outboard_rotation=spec["outboard_rotation"])
        else:
            common.update(outboard_position=spec["outboard_position"], outboard_rotation=spec["outboard_rotation"])
        if flexible:
            mb.add_flexible_body(name, parent, modal=_zero_mode_data(spec, order=i % 3), **common)
            for k in range(NODES_PER_BODY):
                mb.add_node(f"{name}_n{k}", name, grid=k + 1, rotation=spec["node_rotations"][k])
        else:
            mb.add_body(name, parent, mass=spec["mass"], com=spec["com"], inertia=spec["inertia"], **common)
            if spec["flexible"] and spec["child_grid"]:  # the twin of the flexible body's hinge node
                mb.add_node(f"{name}.hinge", name, position=spec["node_positions"][0])
            for k in range(NODES_PER_BODY):
                mb.add_node(f"{name}_n{k}", name, position=spec["node_positions"][k],
                            rotation=spec["node_rotations"][k])
    return mb


def state(system, rng):
    q = system.neutral_configuration() + 0.5 * rng.standard_normal(system.nq)
    system.normalize_quaternions(q)
    return q, rng.standard_normal(system.nu), rng.standard_normal(system.nu)


def rel(a, b):
    return np.linalg.norm(np.asarray(a) - np.asarray(b)) / max(np.linalg.norm(b), 1e-300)


@pytest.mark.parametrize("seed", range(6))
def test_zero_mode_flexible_bodies_reproduce_the_rigid_kernels(seed):
    rigid_mb, flexible_mb = twin_trees(9, seed)
    rigid, flexible = rigid_mb.compile(), flexible_mb.compile()
    dense = flexible_mb.compile(solver="dense")
    assert rigid.node_names == flexible.node_names and rigid.nu == flexible.nu
    assert not any(rigid.topology[:, L.GENERAL]) and any(flexible.topology[:, L.GENERAL])  # both paths are used
    assert flexible.is_flexible and not rigid.is_flexible and flexible.n_modes == (0,) * 9
    rng = np.random.default_rng(100 + seed)
    for _ in range(2):
        q, u, tau = state(rigid, rng)
        f_nodes = rng.standard_normal((rigid.nnodes, 6))
        f_bodies = rng.standard_normal((rigid.nbodies, 6))
        accel = rng.standard_normal(rigid.nu)
        M = rigid.mass_matrix(q)
        free = ~rigid.prescribed_dofs
        tol = max(1e-12, 1e-15 * np.linalg.cond(M[np.ix_(free, free)]))
        ref, ref_tau = rigid.forward_dynamics(q, u, tau, node_forces=f_nodes, body_forces=f_bodies,
                                              prescribed_accel=accel, return_forces=True)
        for system in (flexible, dense):
            got, got_tau = system.forward_dynamics(q, u, tau, node_forces=f_nodes, body_forces=f_bodies,
                                                   prescribed_accel=accel, return_forces=True)
            assert rel(got, ref) < tol
            assert rel(got_tau, ref_tau) < tol
        np.testing.assert_array_equal(ref[rigid.prescribed_dofs], accel[rigid.prescribed_dofs])
        assert rel(flexible.inverse_dynamics(q, u, ref, node_forces=f_nodes, body_forces=f_bodies),
                   rigid.inverse_dynamics(q, u, ref, node_forces=f_nodes, body_forces=f_bodies)) < 1e-12
        assert np.abs(flexible.mass_matrix(q) - M).max() < 1e-12 * np.abs(M).max()
        a, b = rigid.node_kinematics(q, u, ref), flexible.node_kinematics(q, u, ref)
        for field in a._fields:
            assert rel(getattr(b, field), getattr(a, field)) < 1e-12, field
        for name in ("kinetic_energy", "linear_momentum", "angular_momentum"):
            assert rel(getattr(flexible, name)(q, u), getattr(rigid, name)(q, u)) < 1e-12, name
        assert rel(flexible.potential_energy(q), rigid.potential_energy(q)) < 1e-12
        for x, y in zip(flexible.body_poses(q), rigid.body_poses(q)):
            assert rel(x, y) < 1e-12
