"""The compiled multibody system: an immutable :class:`dynamics.model.Model` with a :class:`dynamics.data.Data` of
its own, and the engine's algorithms (:mod:`dynamics.algorithms`) as its methods.

Coordinates (docs/conventions.md): ``q`` and ``u`` concatenate, in body order, each body's hinge coordinates
(see :mod:`dynamics.hinges`) followed by its modal coordinates (none for rigid bodies). Generalized
forces ``tau`` are conjugate to ``u``: a torque for a revolute DOF, a force for a prismatic one, the
hinge's ``[torque; force]`` in the outboard frame for spherical/free hinges.

Node forces are spatial forces ``[torque; force]`` in node axes, applied at the node origin.

Compilation (:meth:`MultibodySystem.from_definitions`) lays the description out (:mod:`dynamics.layout`) for the
kernels of :mod:`dynamics.kernels` (one recursion for rigid and flexible bodies): ``topology`` and ``nodes`` (int
tables), ``joint_rot``/``joint_vec`` (hinge frames), ``params`` (ground acceleration, inertias, modal data, node
frames and mode shapes, and what can be precomputed from them: the inverse modal mass ``G0^-1``, ``M0_re G0^-1``,
``Pi G0^-1`` at the nodes children hang from), and sizes the workspace (``ws_rot``, ``ws_vec``, ``ws_mat``,
``pool``). The description is the immutable model (``system.model``); the workspace, and the rigid bodies' mass
properties once :meth:`MultibodySystem.set_mass_properties` changes them, are the system's data (``system.data``).
A system must not be shared between threads: :meth:`MultibodySystem.copy` gives one with its own data.

It also chooses the forward-dynamics solver (``solver``): the articulated-body recursion, or the dense
``M udot = tau - h`` where that is cheaper (:func:`choose_solver`).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from dynamics import algorithms as A
from dynamics import layout as L
from dynamics.data import Data, frozen
from dynamics.errors import ModelDefinitionError
from dynamics.flexible_body import same_nodes
from dynamics.hinges import HINGE_TYPES, HINGES
from dynamics.kernels.node_inertia import NODE_STATE, node_params
from dynamics.kernels.node_mass import MASS_NODE_STATE, node_mass_params
from dynamics.model import Model
from dynamics.reconfigure import reconfigure
from dynamics.spatial import spatial_inertia as _spatial_inertia


class _Packer:
    """Lays float64 blocks out one after the other in a flat array; returns each block's offset."""

    def __init__(self, start=0):
        self.chunks, self.size = [np.zeros(start)], start

    def push(self, a):
        a = np.ascontiguousarray(a, dtype=np.float64).ravel()
        offset = self.size
        self.chunks.append(a)
        self.size += a.size
        return offset

    def reserve(self, size):
        return self.push(np.zeros(int(size)))

    def array(self):
        return np.concatenate(self.chunks)


def _offdiagonal_ratio(a):
    """The largest off-diagonal entry of the square matrix ``a`` relative to the geometric mean of its two diagonal
    entries, ``max |a_ij| / sqrt(|a_ii a_jj|)`` over i != j (scale-free: the same for any scaling of the modes);
    0 for a diagonal matrix, inf where an entry sits beside a zero diagonal entry."""
    n = a.shape[0]
    if n < 2:
        return 0.0
    off = np.abs(a - np.diag(np.diag(a)))
    if not np.any(off):
        return 0.0
    d = np.sqrt(np.abs(np.diag(a)))
    scale = np.outer(d, d)
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.where(off > 0.0, off / scale, 0.0)
    return float(ratio.max())


def _is_diagonal(a):
    """Diagonal to round-off: every off-diagonal entry below 1e-13 of the geometric mean of its two diagonal
    entries (a mass-normalized modal mass is diagonal with off-diagonal round-off of 1e-15 relative; treating it as
    diagonal changes results by as little)."""
    return _offdiagonal_ratio(a) <= 1e-13


MODAL_DIAGONAL_TOLERANCE = 1e-9
"""A flexible body's modal stiffness or damping is applied as its diagonal when every off-diagonal entry is below
this fraction of the geometric mean of its two diagonal entries (:func:`_offdiagonal_ratio`). ``Phi' K Phi`` of an
eigen-solution is diagonal only to the round-off of the finite-element stiffness it was projected from: off-diagonal
entries of 1.1e-10 of that mean on the 101-grid tube of ``benchmarks/flexible_scaling.py`` (3e-15 of the largest
diagonal entry), which kept a dense n x n product in every evaluation (at 196 modes, a third of the order-0 forward
dynamics, 55 against 36 us). An off-diagonal entry ``r sqrt(k_ii k_jj)`` couples modes i and j by a force r times
their own stiffness forces: it moves frequencies by O(r^2) and beats a degenerate pair at a relative rate r, so
dropping r <= 1e-9 changes the elastic forces by at most 1e-9 of themselves. The diagonal is what the engine holds
(every kernel, the energy and the linearization read the same matrix) and ``summary()`` names the largest ratio
dropped; above the tolerance the matrix is kept whole (a damping matrix with real coupling, a stiffness from
a reduction that is not an eigen-solution)."""


def _modal_diagonal(a):
    """``(matrix, diagonal, dropped)``: ``a`` itself, or its diagonal when :func:`_offdiagonal_ratio` is within
    :data:`MODAL_DIAGONAL_TOLERANCE`, whether it is diagonal, and the ratio dropped (0 when exactly diagonal)."""
    ratio = _offdiagonal_ratio(a)
    if ratio <= MODAL_DIAGONAL_TOLERANCE:
        return np.diag(np.diag(a)), True, ratio
    return a, False, 0.0


def has_quasi_static_modes(data) -> bool:
    """True when a flexible body has quasi-static modes (infinite frequency, no modal mass: the massless
    interface DOFs of normalized component modes, dynamics/flex/component_modes.py)."""
    return bool(np.any(np.isposinf(np.asarray(data.frequencies_hz, dtype=float))))


def _modal_mass_inverse(G0, where):
    """(kind, inverse) of the constant modal mass: its reciprocal diagonal when G0 is exactly diagonal,
    else the symmetric inverse from a Cholesky factorization. Refuses a G0 that is not positive definite."""
    n = G0.shape[0]
    if n and not np.allclose(G0, G0.T, rtol=0.0, atol=1e-12 * np.abs(G0).max()):
        raise ModelDefinitionError(f"{where}: the modal mass matrix M0[6:, 6:] is not symmetric")
    try:
        factor = np.linalg.cholesky(G0) if n else np.zeros((0, 0))
    except np.linalg.LinAlgError:
        raise ModelDefinitionError(f"{where}: the modal mass matrix M0[6:, 6:] is not positive definite "
                                   f"(eigenvalues {np.linalg.eigvalsh(G0)[:3].tolist()} ...)") from None
    if _is_diagonal(G0):
        return L.GINV_DIAGONAL, 1.0 / np.diag(G0)
    Linv = np.linalg.solve(factor, np.eye(n))
    inverse = Linv.T @ Linv
    return L.GINV_DENSE, 0.5 * (inverse + inverse.T)


MIN_REFINEMENT_BUDGET = 5
"""A body whose modal mass varies through node terms is refined when five refinements (what deformations of
1e-4..1e-3 rad take) cost less than forming and factoring ``G(eta)``; :func:`choose_solver` prices a refined body
at that many."""

REFINEMENT_PASS = 40.0
"""Multiply-adds per mode of a refinement's bias and acceleration passes (:mod:`dynamics.kernels.articulated_body`:
the modal elimination's bias part and the modal accelerations), in the units of :func:`modal_mass_formation_cost`:
with it :func:`refinement_budget` puts the crossover between refining and factoring where it was measured (the beam
of benchmarks/flexible_vs_exudyn.py factors at 20 modes and refines at 100)."""


def modal_mass_formation_cost(n, count):
    """Multiply-adds of forming ``G(eta)`` of a body of ``n`` modes over the terms of ``count`` nodes, per
    evaluation: the products ``dJ lambda_s`` (9 n per node) and the lower triangle of ``Lambda' (dJ lambda)``
    (1.5 n^2 per node, formed as a matrix product: ~1.7x the multiply-adds per second of the refinement's
    matrix-vector products, :func:`dynamics.kernels.node_inertia.node_inertia_modal_mass`)."""
    return (1.5 * count * n * n + 9.0 * count * n) / 1.7


def refinement_cost(n, count):
    """Multiply-adds of one refinement of a body of ``n`` modes whose modal mass varies through the terms of
    ``count`` nodes: the product with ``dG`` over the nodes (6 n per node) and the bias and acceleration passes
    (``REFINEMENT_PASS`` n)."""
    return 6.0 * count * n + REFINEMENT_PASS * n


def _node_set_shapes(where, name, node_set, terms, n):
    """The shapes (count, 6, n) of a body's terms summed over nodes (``name``: node_inertia or mass_nodes), refused
    when a term it sums is also given as a table or the shapes do not fit ``n`` modes."""
    twice = sorted(t for t in node_set.terms if getattr(terms, t) is not None)
    if twice:
        raise ModelDefinitionError(f"{where}: terms {twice} are given both as tables and over the nodes")
    shapes = np.asarray(node_set.shapes, dtype=np.float64)
    if shapes.shape != (node_set.count, 6, n):
        raise ModelDefinitionError(f"{where}: {name} shapes must have shape {(node_set.count, 6, n)}, got "
                                   f"{shapes.shape}")
    return shapes


def refinement_budget(n, count):
    """How many refinements of a body of ``n`` modes whose modal mass varies through the terms of ``count`` nodes
    cost as much as forming ``G(eta)`` over the nodes (:func:`modal_mass_formation_cost`) and factoring it (its
    Cholesky factorization n^3 / 6 and solves 14 n^2), per evaluation: the forward dynamics refines against the
    constant ``G0`` while the iterations it predicts stay within this budget, and factors ``G(eta)`` past it
    (:mod:`dynamics.kernels.articulated_body`); a body whose budget is below ``MIN_REFINEMENT_BUDGET`` factors
    ``G(eta)`` from the start. Measured (benchmarks/flexible_vs_exudyn.py's beam, 105 nodes): factoring wins at 20
    modes (4-5 refinements there), refining at 100."""
    return int((modal_mass_formation_cost(n, count) + n ** 3 / 6.0 + 14.0 * n * n) / refinement_cost(n, count))


def _node_mass_cost(fx, n):
    """Multiply-adds of the terms C1 and J2 summed over a body's nodes (:mod:`dynamics.kernels.node_mass`), with
    their forces: ~9 per entry of the 3N x n shapes (6 for the translation shapes, as many again for the rotation
    shapes of nodes with rotary inertia: :func:`dynamics.flexible_body.node_mass_is_cheaper`), 150 per node."""
    if fx[L.FX_MASS_NODES] < 0:
        return 0.0
    count = float(fx[L.FX_MASS_NODE_COUNT])
    return 27.0 * count * n + 150.0 * count


def choose_solver(topology):
    """``("aba" | "dense", reason)``: the forward-dynamics solver with the lower estimated cost
    (:func:`solver_costs`)."""
    aba, dense = solver_costs(topology)
    if dense < aba:
        return "dense", (f"dense M udot = tau - h (estimated {dense:.3g} multiply-adds against {aba:.3g} for "
                         f"the articulated-body recursion)")
    return "aba", (f"articulated-body recursion (estimated {aba:.3g} multiply-adds against {dense:.3g} for the "
                   f"dense M udot = tau - h)")


def solver_costs(topology):
    """``(aba, dense)``: the estimated cost of a forward dynamics by the articulated-body recursion and by the dense
    solve.

    The estimate (in multiply-adds, ~1 ns each here) counts only what differs between the two. The
    articulated-body recursion costs ~600 per rigid body and, per flexible body, ~6000 fixed (the modal
    elimination's small dense steps) plus its applications of ``G^-1`` (7 n or n^2 per row for a constant modal
    mass, and the six rows of ``M_re G^-1`` again per call when ``M_re`` varies: C1 as a table or over the nodes,
    F2; with G1 or G2 tables a Cholesky factorization n^3/3 and 2 n^2 per solved row), the Woodbury rank terms
    3 r^2 n, the terms of the nodes' rotary inertia (G1, F2, G2 over N nodes) with their forces 30 n + 100 per node
    and, for a modal mass that varies through them, ``MIN_REFINEMENT_BUDGET`` refinements (:func:`refinement_cost`)
    or ``G(eta)`` formed over the nodes (:func:`modal_mass_formation_cost`). The dense path costs an inverse
    dynamics and a composite-inertia pass (~1100 per rigid body, ~4000 + 8 n^2 per flexible body, the mass-matrix
    columns carried to the root), each with the body's terms: the modal mass formed a second time (n^3 with G1,
    3 n^3 with F2, n^4 with G2 tables), the node terms once more without their forces (15 n + 100 per node),
    ``G(eta)`` formed over the nodes in both passes where the recursion factors it (once where it refines), C1 and
    J2 over the nodes once more (:func:`_node_mass_cost`); and the Cholesky factorization nu^3/3 + 2 nu^2 of the
    mass matrix. The constants were fitted to ``benchmarks/flexible_scaling.py``, the solver comparison in
    docs/engine.md ("Scaling") and, for the node terms, eight bodies of 5-107 nodes and 6-30 modes
    (``benchmarks/flexible_scaling.py --solvers``; the recursion 1.2-1.7x faster on all of them): dense wins, by
    10-40 %, for small systems of tables or point masses (a flexible body of up to ~10 modes, a few bodies of a
    few modes), the recursion everywhere else; near the crossover the two differ by less than the timing noise."""
    aba = dense = 0.0
    nu_total = 0
    depth = np.zeros(topology.shape[0], dtype=np.int64)
    for i, t in enumerate(topology):
        n = int(t[L.N_MODES])
        ncol = int(t[L.NU_HINGE]) + n
        nu_total += ncol
        depth[i] = 0 if t[L.PARENT] < 0 else depth[t[L.PARENT]] + 1
        dense += 40.0 * ncol * depth[i]
        if not t[L.FLEXIBLE]:
            aba += 600.0
            dense += 1100.0
            continue
        fx = t[L.FLEX:]
        kind = int(fx[L.FX_GINV_KIND])
        r = int(fx[L.FX_RANK])
        varying = (fx[L.FX_C1] >= 0 or fx[L.FX_F2] >= 0 or (fx[L.FX_NODE_TERMS] & L.NODE_F2) != 0
                   or (fx[L.FX_MASS_NODE_TERMS] & L.MASS_C1) != 0)
        count = int(fx[L.FX_NODE_COUNT]) if fx[L.FX_NODES] >= 0 else 0
        node_terms = (30.0 * n + 100.0) * count
        formed = modal_mass_formation_cost(n, count) if fx[L.FX_NODE_TERMS] & (L.NODE_G1 | L.NODE_G2) else 0.0
        aba += 6000.0 + 3.0 * r * r * n + node_terms
        if fx[L.FX_REFINE]:
            aba += MIN_REFINEMENT_BUDGET * refinement_cost(n, count)
        else:
            aba += formed
        if kind == L.GINV_DIAGONAL:
            aba += 7.0 * n * (1 + 6 * varying)
        elif kind == L.GINV_DENSE:
            aba += 1.0 * n * n * (1 + 6 * varying)
        else:
            aba += n ** 3 / 3.0 + 2.0 * n * n * (r + 13)
        dense += 4000.0 + 8.0 * n * n + node_terms + (15.0 * n + 100.0) * count + _node_mass_cost(fx, n)
        dense += (n ** 3 if fx[L.FX_G1] >= 0 else 0) + (3 * n ** 3 if fx[L.FX_F2] >= 0 else 0) + \
            (n ** 4 if fx[L.FX_G2] >= 0 else 0) + (formed if fx[L.FX_REFINE] else 2.0 * formed)
    dense += nu_total ** 3 / 3.0 + 2.0 * nu_total ** 2
    return aba, dense


_PER_RUN = ("params", "masses", "definitions", "spatial_inertia", "ground_accel")


class MultibodySystem:
    """A compiled tree of bodies: an immutable :class:`dynamics.model.Model` (:attr:`model`) with a
    :class:`dynamics.data.Data` of its own (:attr:`data`), and the algorithms of :mod:`dynamics.algorithms` as
    methods. Build with :class:`dynamics.Multibody`.

    The model's attributes (names, sizes, ``topology``, ``joint_rot`` ...) read as the system's. ``params``,
    ``masses``, ``definitions`` and ``spatial_inertia`` are this system's (its data's: the model's until
    :meth:`set_mass_properties` changes them). ``solver`` is the forward-dynamics method chosen at compile time
    ("aba" or "dense", ``solver_reason`` says why); ``notes`` lists choices made for the user (default
    modal-integral orders, O(n^3) terms kept); :meth:`summary` prints both."""

    def __init__(self, model, data=None):
        if data is not None and data.model is not model:
            raise ValueError(f"{data!r} is not a data of {model!r}")
        # the model's attributes as plain attributes of the system (as fast to read as before the split), but for
        # those a run may change, which the properties below read from the data
        self.__dict__.update((k, v) for k, v in model.__dict__.items() if k not in _PER_RUN)
        self.model = model
        self.data = model.create_data() if data is None else data

    # what a run may change, and the workspace: the data's
    params = property(lambda self: self.data.params, doc="the parameters the kernels read (the data's)")
    masses = property(lambda self: self.data.masses, doc="(nb,) body masses (the data's)")
    definitions = property(lambda self: self.data.definitions,
                           doc="(bodies, nodes, gravity) this system was compiled from, with its mass changes")
    spatial_inertia = property(lambda self: self.data.params[6:6 + 36 * self.nbodies].reshape(self.nbodies, 6, 6),
                               doc="(nb, 6, 6) spatial inertias about the body origins (the data's)")
    ground_accel = property(lambda self: self.data.params[L.GROUND_ACCEL:L.GROUND_ACCEL + 6],
                            doc="(6,) the ground's spatial acceleration (minus gravity)")
    ws_rot = property(lambda self: self.data.ws_rot, doc="the data's workspace")
    ws_vec = property(lambda self: self.data.ws_vec, doc="the data's workspace")
    ws_mat = property(lambda self: self.data.ws_mat, doc="the data's workspace")
    pool = property(lambda self: self.data.pool, doc="the data's workspace")


    @classmethod
    def from_definitions(cls, bodies, nodes, gravity, solver=None):
        """Compile body and node definitions (:class:`dynamics.builder.BodyDefinition`, ``NodeDefinition``)
        into a system; ``solver`` forces "aba" or "dense" (default: :func:`choose_solver`)."""
        index = {b.name: i for i, b in enumerate(bodies)}
        node_index = {n.name: k for k, n in enumerate(nodes)}
        nb, nn = len(bodies), len(nodes)
        topology = np.zeros((nb, L.TOPOLOGY_COLUMNS), dtype=np.int64)
        table = np.full((nn, L.NODE_COLUMNS), -1, dtype=np.int64)
        joint_rot = np.zeros((nb, 2, 3, 3))
        joint_vec = np.zeros((nb, 4, 3))
        params = _Packer()
        params.push(np.concatenate([np.zeros(3), -np.asarray(gravity, dtype=np.float64)]))
        params.reserve(36 * nb)  # the bodies' rigid blocks, written below
        inertia = np.zeros((nb, 6, 6))
        n_modes = [0 if b.flexible is None else int(b.flexible.n_modes) for b in bodies]
        nmax = max(n_modes)
        pool = _Packer(L.POOL_HEADER + 6 * nmax)
        q0 = u0 = 0
        child_nodes = [[] for _ in bodies]  # nodes of each flexible body that children hang from
        for i, b in enumerate(bodies):
            code = HINGE_TYPES[b.hinge]
            nq, nu = HINGES[code].nq, HINGES[code].nu
            free = np.flatnonzero(~b.prescribed)
            pres = np.flatnonzero(b.prescribed)
            outboard_identity = (np.array_equal(b.outboard_rotation, np.eye(3))
                                 and not np.any(b.outboard_position) and b.outboard_node is None)
            parent_flexible = b.parent is not None and bodies[index[b.parent]].flexible is not None
            parent_node = node_index[b.parent_node] if (b.parent_node and parent_flexible) else -1
            outboard_node = node_index[b.outboard_node] if b.outboard_node else -1
            flexible = b.flexible is not None
            t = topology[i]
            for col, value in ((L.PARENT, -1 if b.parent is None else index[b.parent]), (L.HINGE_TYPE, code),
                               (L.Q_START, q0), (L.NQ_HINGE, nq), (L.U_START, u0), (L.NU_HINGE, nu),
                               (L.N_MODES, n_modes[i]), (L.N_FREE, len(free)), (L.N_PRESCRIBED, len(pres)),
                               (L.OUTBOARD_IDENTITY, outboard_identity), (L.PARENT_NODE, parent_node),
                               (L.OUTBOARD_NODE, outboard_node)):
                t[col] = value
            t[L.FLEXIBLE] = flexible
            t[L.GENERAL] = flexible or parent_node >= 0 or outboard_node >= 0
            t[L.FREE_DOFS:L.FREE_DOFS + len(free)] = free
            t[L.PRESCRIBED_DOFS:L.PRESCRIBED_DOFS + len(pres)] = pres
            t[L.INERTIA] = 6 + 36 * i
            t[L.FIRST_SLOT] = -1
            if parent_node >= 0 and parent_node not in child_nodes[index[b.parent]]:
                child_nodes[index[b.parent]].append(parent_node)
            R_in, p_in = b.inboard_rotation, b.inboard_position
            if b.parent_node and not parent_flexible:  # a node of a rigid parent: fold its fixed pose in
                node = nodes[node_index[b.parent_node]]
                R_in, p_in = node.rotation @ R_in, node.position + node.rotation @ p_in
            joint_rot[i, L.INBOARD] = R_in
            joint_rot[i, L.OUTBOARD] = b.outboard_rotation
            joint_vec[i, L.INBOARD] = p_in
            joint_vec[i, L.OUTBOARD] = b.outboard_position
            joint_vec[i, L.AXIS1:L.AXIS2 + 1] = b.axes
            inertia[i] = b.flexible.M0[:6, :6] if flexible else _spatial_inertia(b.mass, b.com, b.inertia)
            q0 += nq + n_modes[i]
            u0 += nu + n_modes[i]
        ginv = {}
        dropped = []  # (body, "stiffness" | "damping", ratio) applied as their diagonal (MODAL_DIAGONAL_TOLERANCE)
        for i, b in enumerate(bodies):
            if b.flexible is not None:
                ginv[i] = cls._flexible_layout(i, b, topology[i], params, pool, len(child_nodes[i]), dropped)
        for k, nd in enumerate(nodes):
            i = index[nd.body]
            table[k, L.NODE_BODY] = i
            table[k, L.NODE_FRAME] = params.push(np.concatenate([nd.rotation.ravel(), nd.position]))
            if bodies[i].flexible is not None:
                table[k, L.NODE_SHAPE] = params.push(nd.shape)
        for i, b in enumerate(bodies):
            slots = child_nodes[i] + ([topology[i, L.OUTBOARD_NODE]] if topology[i, L.OUTBOARD_NODE] >= 0 else [])
            for k in dict.fromkeys(slots):
                table[k, L.NODE_SLOT] = pool.reserve(L.SL_PSI + 12 * n_modes[i])
                kind, inverse = ginv[i]
                if kind != L.GINV_FACTORED:
                    shape = np.asarray(nodes[k].shape, dtype=np.float64).reshape(6, n_modes[i])
                    table[k, L.NODE_SHAPE_GINV] = params.push(shape * inverse if kind == L.GINV_DIAGONAL
                                                              else shape @ inverse)
            for a, k in enumerate(child_nodes[i]):
                if a == 0:
                    topology[i, L.FIRST_SLOT] = k
                table[k, L.NODE_NEXT_SLOT] = child_nodes[i][a + 1] if a + 1 < len(child_nodes[i]) else -1
        flat = params.array()
        flat[6:6 + 36 * nb] = inertia.ravel()
        notes = [f"body '{b.name}': {b.flexible.note}" for b in bodies if b.flexible is not None and b.flexible.note]
        notes.extend(f"body '{b.name}': modal {name} applied as its diagonal (largest off-diagonal entry {ratio:.1e} of "
                     f"the geometric mean of its diagonal entries: round-off, within {MODAL_DIAGONAL_TOLERANCE:.0e})"
                     for b, name, ratio in dropped)
        for i, b in enumerate(bodies):
            t = topology[i]
            if t[L.FLEXIBLE] and t[L.N_MODES] > 40:
                fx = t[L.FLEX:]
                cubic = [name for name, col in (("G1", L.FX_G1), ("F2", L.FX_F2), ("G2", L.FX_G2)) if fx[col] >= 0]
                if cubic:
                    notes.append(f"body '{b.name}': terms {', '.join(cubic)} of M(eta) from tables cost O(n^3) or "
                                 f"more per evaluation at {t[L.N_MODES]} modes (no per-node data to sum them over); "
                                 f"omit_terms={tuple(cubic)!r} leaves them out (see dynamics/flexible_body.py)")
        requested = solver
        quasi = [b.name for b in bodies if b.flexible is not None and has_quasi_static_modes(b.flexible)]
        if quasi and solver == "aba":
            raise ModelDefinitionError(f"bodies {quasi} have quasi-static modes (no modal mass): the articulated-body "
                                       "recursion needs the inverse modal mass; use the dense solver")
        if solver is None and quasi:
            solver, reason = "dense", (f"dense M udot = tau - h (bodies {quasi} have quasi-static modes without "
                                       "modal mass: the articulated-body recursion cannot invert their modal mass)")
        elif solver is None:
            solver, reason = choose_solver(topology)
        elif solver in ("aba", "dense"):
            reason = f"{solver} (requested)"
        else:
            raise ModelDefinitionError(f"solver must be 'aba' or 'dense', got {solver!r}")
        if solver == "dense":  # the mass matrix and two vectors at the end of the pool
            pool.reserve(u0 * u0 + 2 * u0)
        model = Model(body_names=[b.name for b in bodies], joint_names=[b.joint_name for b in bodies],
                      hinge_names=[b.hinge for b in bodies], node_names=[n.name for n in nodes],
                      node_bodies=[n.body for n in nodes], topology=topology, nodes=table, joint_rot=joint_rot,
                      joint_vec=joint_vec, params=flat, pool_size=pool.size, gravity=gravity,
                      node_rot=[n.rotation for n in nodes], node_pos=[n.position for n in nodes],
                      masses=[b.mass for b in bodies], notes=notes, solver=solver, solver_reason=reason,
                      # what compile(solver=...) asked for, kept by a recompilation
                      requested_solver=requested,
                      # the description this system was compiled from, for run-time reconfiguration
                      definitions=(tuple(dataclasses.replace(b) for b in bodies),
                                   tuple(dataclasses.replace(n) for n in nodes), np.array(gravity, dtype=float)))
        return cls(model)

    @staticmethod
    def _flexible_layout(i, body, t, params, pool, n_child_nodes, dropped):
        """Modal data of flexible body ``i`` into ``params``, its workspace into ``pool``, their offsets into
        its topology row ``t``; returns how G^-1 is applied and the precomputed inverse. A modal stiffness or damping
        applied as its diagonal is added to ``dropped`` as ``(body, name, ratio)``."""
        data = body.flexible
        where = f"body '{body.name}' ({data.source})"
        n = int(data.n_modes)
        N = 6 + n
        M0 = np.asarray(data.M0, dtype=np.float64)
        if M0.shape != (N, N) or not np.all(np.isfinite(M0)):
            raise ModelDefinitionError(f"{where}: M0 must be a finite {N} x {N} matrix, got shape {M0.shape}")
        if data.order not in (0, 1, 2):
            raise ModelDefinitionError(f"{where}: modal-integral order must be 0, 1 or 2, got {data.order!r}")
        terms = data.mass_terms()
        fx = t[L.FLEX:]
        fx[:] = -1
        fx[L.FX_ORDER] = data.order
        fx[L.FX_M0RE] = params.push(M0[:6, 6:])
        fx[L.FX_G0] = params.push(M0[6:, 6:])
        if terms.R1 is not None:
            fx[L.FX_R1] = params.push(terms.R1)
        fx[L.FX_C1_ROWS] = 6
        if terms.C1 is not None:
            rows = 3 if not np.any(terms.C1[:, 3:6, :]) else 6  # no CG offsets: E1 = 0
            fx[L.FX_C1_ROWS] = rows
            fx[L.FX_C1] = params.push(terms.C1[:, :rows, :])
        for col, term in ((L.FX_G1, terms.G1), (L.FX_J2, terms.J2), (L.FX_F2, terms.F2), (L.FX_G2, terms.G2),
                          (L.FX_P2, terms.P2)):
            if term is not None:
                fx[col] = params.push(term)
        for col, diag_col, name in ((L.FX_K, L.FX_K_DIAGONAL, "stiffness"), (L.FX_C, L.FX_C_DIAGONAL, "damping")):
            a = np.asarray(getattr(data, name), dtype=np.float64)
            if a.shape != (n, n) or not np.all(np.isfinite(a)):
                raise ModelDefinitionError(f"{where}: the modal {name} must be a finite {n} x {n} matrix, got "
                                           f"shape {a.shape}")
            a, fx[diag_col], ratio = _modal_diagonal(a)
            if ratio > 0.0:
                dropped.append((body, name, ratio))
            fx[col] = params.push(a)
        nodes = data.node_inertia
        node_terms = 0
        fx[L.FX_NODE_COUNT] = 0
        fx[L.FX_NODE_TERMS] = 0
        if nodes is not None:
            shapes = _node_set_shapes(where, "node_inertia", nodes, terms, n)
            bits = {"G1": L.NODE_G1, "G2": L.NODE_G2, "F2": L.NODE_F2}
            node_terms = sum(bits[t] for t in nodes.terms)
            fx[L.FX_NODE_COUNT] = nodes.count
            fx[L.FX_NODE_TERMS] = node_terms
            fx[L.FX_NODES] = params.push(node_params(nodes.mass, nodes.cg, nodes.inertia, shapes))
            fx[L.FX_P_NODES] = pool.reserve(NODE_STATE * nodes.count)
        mass_nodes = data.mass_nodes
        fx[L.FX_MASS_NODE_COUNT] = 0
        fx[L.FX_MASS_NODE_TERMS] = 0
        if mass_nodes is not None:
            shapes = _node_set_shapes(where, "mass_nodes", mass_nodes, terms, n)
            bits = {"C1": L.MASS_C1, "J2": L.MASS_J2}
            fx[L.FX_MASS_NODE_COUNT] = mass_nodes.count
            fx[L.FX_MASS_NODE_TERMS] = sum(bits[t] for t in mass_nodes.terms)
            # the node-inertia nodes again (every node with mass has rotary inertia): their shapes and passes shared
            shared = same_nodes(mass_nodes, nodes)
            fx[L.FX_MASS_NODES] = params.push(node_mass_params(mass_nodes.mass, mass_nodes.cg, mass_nodes.inertia,
                                                               mass_nodes.positions, shapes, shared))
            fx[L.FX_P_MASS_NODES] = pool.reserve(MASS_NODE_STATE * mass_nodes.count)
        varying = terms.G1 is not None or terms.G2 is not None
        quasi_static = has_quasi_static_modes(data)
        budget = refinement_budget(n, nodes.count) if node_terms & (L.NODE_G1 | L.NODE_G2) else 0
        refine = not varying and not quasi_static and budget >= MIN_REFINEMENT_BUDGET
        if varying or quasi_static or (node_terms & (L.NODE_G1 | L.NODE_G2) and not refine):
            # quasi-static modes make G singular: no inverse (the dense solver factors the whole mass matrix)
            kind, inverse = L.GINV_FACTORED, None
        else:
            kind, inverse = _modal_mass_inverse(M0[6:, 6:], where)
            fx[L.FX_GINV] = params.push(inverse)
            fx[L.FX_ZM0] = params.push(M0[:6, 6:] * inverse if kind == L.GINV_DIAGONAL else M0[:6, 6:] @ inverse)
        fx[L.FX_GINV_KIND] = kind
        fx[L.FX_REFINE] = budget if refine else 0
        r = 6 * n_child_nodes + (12 if t[L.OUTBOARD_NODE] >= 0 else 0)
        fx[L.FX_RANK] = r if n else 0
        for col in (L.FX_P_MRE, L.FX_P_MDRE, L.FX_P_BP, L.FX_P_ZM, L.FX_P_W):
            fx[col] = pool.reserve(6 * n)
        fx[L.FX_P_VEC] = pool.reserve(L.N_PV * n)
        fx[L.FX_P_G] = pool.reserve(n * n)
        fx[L.FX_P_F] = pool.reserve(6 * (6 + n))
        fx[L.FX_P_MRR] = pool.reserve(36)
        fx[L.FX_P_SMALL] = pool.reserve(3 * r * r + 14 * r + 2 * r * n)
        return kind, inverse

    def copy(self, mass_properties: bool = False):
        """A system of the same model with a data of its own (one per thread or per run): its own workspace, and
        the same mass properties as this system, which a change in either does not carry to the other (with
        ``mass_properties`` its own copy of them at once, else at its first change)."""
        return MultibodySystem(self.model, self.data.copy(mass_properties))

    def with_notes(self, notes):
        """A system of this model with ``notes`` (strings) added (:meth:`dynamics.model.Model.with_notes`) and a
        data of its own with this system's mass properties."""
        model, d = self.model.with_notes(notes), self.data
        if not d.owns_mass_properties:
            return MultibodySystem(model)
        return MultibodySystem(model, Data(model, params=frozen(np.array(d.params)), masses=frozen(np.array(d.masses)),
                                           definitions=d.definitions))

    # ------------------------------------------------------------------ helpers
    def reconfigure(self, q, u, *, lock=(), unlock=(), detach=(), attach=None, mass_properties=None):
        """A new system after locking/unlocking hinges, detaching subtrees, attaching free bodies or changing
        mass properties, with the state mapped across: returns ``(system, q, u)``. See :mod:`dynamics.reconfigure`."""
        return reconfigure(self, q, u, lock=lock, unlock=unlock, detach=detach, attach=attach,
                           mass_properties=mass_properties)

    def set_mass_properties(self, body, mass, com, inertia):
        """Change a rigid body's mass, center of mass and inertia (about the COM) in this system's data, O(1): for
        mass depletion during a run (:func:`dynamics.algorithms.set_mass_properties`; the model and the systems
        that share it keep theirs). The values are validated like :meth:`Multibody.add_body`'s
        (:func:`dynamics.definitions.rigid_mass_properties`)."""
        A.set_mass_properties(self.model, self.data, body, mass, com, inertia)

    def body_index(self, name):
        return self.model.body_index(name)

    def node_index(self, name):
        return self.model.node_index(name)

    def neutral_configuration(self):
        """Zero hinge angles/displacements, identity quaternions, zero modal coordinates."""
        return self.model.neutral_configuration()

    def normalize_quaternions(self, q):
        """Renormalize every hinge quaternion of ``q`` in place; returns ``q``."""
        for k in self.quaternion_q_indices:
            q[k:k + 4] /= np.linalg.norm(q[k:k + 4])
        return q

    # ------------------------------------------------------------------ algorithms (dynamics.algorithms)
    def q_dot(self, q, u):
        """Coordinate rates ``q_dot = f(q, u)``."""
        return A.coordinate_rates(self.model, q, u)

    def forward_dynamics(self, q, u, tau=None, node_forces=None, prescribed_accel=None, body_forces=None,
                         return_forces=False):
        """Accelerations ``u_dot``: :func:`dynamics.algorithms.forward_dynamics` on this system's model and data."""
        return A.forward_dynamics(self.model, self.data, q, u, tau, node_forces, prescribed_accel, body_forces,
                                  return_forces)

    def inverse_dynamics(self, q, u, u_dot, node_forces=None, body_forces=None):
        """Generalized forces realizing ``u_dot`` (recursive Newton-Euler), external forces included."""
        return A.inverse_dynamics(self.model, self.data, q, u, u_dot, node_forces, body_forces)

    def mass_matrix(self, q):
        """Joint-space mass matrix (composite-rigid-body algorithm), symmetric (nu, nu)."""
        return A.mass_matrix(self.model, self.data, q)

    def bias_forces(self, q, u, node_forces=None, body_forces=None):
        """Coriolis, gyroscopic, gravity and external-force terms: ``M u_dot + bias = tau``."""
        return A.bias_forces(self.model, self.data, q, u, node_forces, body_forces)

    def stiffness_matrix(self):
        """Generalized stiffness (nu, nu): :func:`dynamics.algorithms.stiffness_matrix`."""
        return A.stiffness_matrix(self.model)

    def damping_matrix(self):
        """Generalized damping (nu, nu): :func:`dynamics.algorithms.damping_matrix`."""
        return A.damping_matrix(self.model)

    def node_kinematics(self, q, u, u_dot=None):
        """Pose, velocity and (classical) acceleration of every node; see :class:`NodeKinematics`."""
        return A.node_kinematics(self.model, self.data, q, u, u_dot)

    def body_poses(self, q):
        """(rotations (nb, 3, 3) body -> world, origins (nb, 3) in the world)."""
        return A.body_poses(self.model, self.data, q)

    def body_velocities(self, q, u):
        """Spatial velocities ``[omega; v]`` of every body reference frame, body axes, at its origin."""
        return A.body_velocities(self.model, self.data, q, u)

    def kinetic_energy(self, q, u):
        return A.kinetic_energy(self.model, self.data, q, u)

    def potential_energy(self, q):
        """Potential energy: uniform gravity ``-sum m g . r_com`` (zero at the world origin) plus the
        elastic energy ``1/2 eta' K eta`` of flexible bodies."""
        return A.potential_energy(self.model, self.data, q)

    def linear_momentum(self, q, u):
        """Total linear momentum, world axes."""
        return A.linear_momentum(self.model, self.data, q, u)

    def angular_momentum(self, q, u):
        """Total angular momentum about the world origin, world axes."""
        return A.angular_momentum(self.model, self.data, q, u)

    def summary(self):
        """A few lines describing the compiled system: sizes, flexible bodies, solver and notes."""
        lines = [repr(self)]
        for i, name in enumerate(self.body_names):
            if self.topology[i, L.FLEXIBLE]:
                fx = self.topology[i, L.FLEX:]
                terms = [term for term, col in (("R1", L.FX_R1), ("C1", L.FX_C1), ("G1", L.FX_G1),
                                                ("J2", L.FX_J2), ("F2", L.FX_F2), ("G2", L.FX_G2),
                                                ("P2", L.FX_P2)) if fx[col] >= 0]
                if fx[L.FX_NODES] >= 0:
                    nodal = [t for t, bit in (("G1", L.NODE_G1), ("F2", L.NODE_F2), ("G2", L.NODE_G2))
                             if fx[L.FX_NODE_TERMS] & bit]
                    terms.append(f"{'+'.join(nodal)} over {fx[L.FX_NODE_COUNT]} nodes")
                if fx[L.FX_MASS_NODES] >= 0:
                    summed = [t for t, bit in (("C1", L.MASS_C1), ("J2", L.MASS_J2)) if fx[L.FX_MASS_NODE_TERMS] & bit]
                    shared = " (the same nodes, shapes shared)" if self.params[fx[L.FX_MASS_NODES] + 2] else ""
                    terms.append(f"{'+'.join(summed)} over {fx[L.FX_MASS_NODE_COUNT]} nodes{shared}")
                kind = {L.GINV_DIAGONAL: "diagonal G0", L.GINV_DENSE: "G0^-1 precomputed",
                        L.GINV_FACTORED: "G(eta) factored per call"}[int(fx[L.FX_GINV_KIND])]
                if fx[L.FX_REFINE]:
                    kind += ", G(eta) - G0 refined"
                lines.append(f"  flexible body '{name}': {self.n_modes[i]} modes, modal-integral order "
                             f"{fx[L.FX_ORDER]}, terms {'+'.join(['M0'] + terms)}, {kind}")
        lines.append(f"  solver: {self.solver_reason}")
        lines.extend(f"  note: {note}" for note in self.notes)
        return "\n".join(lines)

    def __repr__(self):
        return (f"MultibodySystem({self.nbodies} bodies, nq={self.nq}, nu={self.nu}, "
                f"{self.nnodes} nodes, solver={self.solver})")
