"""Flexible-body data for the engine: the deformation-dependent mass matrix as a polynomial in eta.

A flexible body's generalized velocity is ``x = [V; eta_dot]`` (its reference frame's spatial velocity
``V = [omega; v]`` in body axes, then the modal rates). Its kinetic energy is ``T = 1/2 x' M(eta) x`` with

    M(eta) = M0 + sum_r M1[r] eta_r + sum_rs M2[r, s] eta_r eta_s            (N x N, N = 6 + n)

the body mass matrix of TM-2020-5008164 eqs. E.1.34 and E.2.6 (blocks from the modal integrals
E.2.2-E.2.5), re-ordered here as [omega, v, eta]. ``M2[r, s]`` is symmetric in (r, s) and as a matrix.
The modal-integral ``order`` selects the fidelity (issue 4): 0 keeps ``M0`` only (constant mass
matrix, rigid/elastic coupling through the participation factors F0, E0 only: the "linear
superposition" level of TM Section 7.2), 1 adds the first-order terms, 2 is the full expansion.

The engine never stores ``M1`` and ``M2`` whole (``n N^2`` and ``n^2 N^2`` numbers, mostly zeros): it
keeps their non-zero blocks, :class:`ModalMassTerms`, and each block has its own cost per evaluation
(n modes):

=====  ==============================  =====================  ===================================
term   block of M(eta)                 integrals              cost per evaluation
=====  ==============================  =====================  ===================================
R1     rigid/rigid, first order        J1, p1                 O(n)
C1     rigid/modal, first order        F1, E1                 O(n^2) as a table, O(N n) summed over
                                                              every node
G1     modal/modal, first order        G1                     O(n^3) as a table, O(N_r n) summed over
                                                              the nodes; makes the modal mass eta-
                                                              dependent (dynamics.kernels.articulated_body
                                                              refines against the constant G0, or
                                                              factors G(eta): O(n^3))
J2     rotational, second order        J2                     O(n^2) as a table, O(N n) over every
                                                              node (with C1)
F2     rotational/modal, second order  F2                     O(n^3) as a table, O(N_r n) over nodes
G2     modal/modal, second order       G2                     O(n^4) as a table, O(N_r n) over nodes
P2     rotational/translational,       geometric stiffness    O(n^2)
       second order                    (translation cases)
=====  ==============================  =====================  ===================================

Geometric stiffening (:func:`add_geometric_stiffening`, issue 15) adds to C1 and J2 and brings P2.

C1 and J2 are sums over every node with mass of products of its shapes, mass, position, offset and inertia
(the integrals F1, E1, J2 of TM eqs. E.2.4-E.2.5): :class:`NodeMass` holds those per-node invariants and
:mod:`dynamics.kernels.node_mass` evaluates the two terms from them in O(N n) per evaluation (N nodes), where
that is cheaper than reading the tables (:func:`node_mass_is_cheaper`: from about 1.7 N modes at order 2, 3.4 N
at order 1). Geometric stiffening's parts of C1 and J2 are not node sums: a body with it keeps both as tables.

G1, F2 and G2 come only from nodes with rotational inertia or centre-of-mass offsets (zero for point
masses, TM eq. E.3.1): they are the turning of each such node's own inertia with its elastic rotation
``theta_j = lambda_j eta`` (first-order attitude ``I + theta_j~``, E.1.17). Summed over those nodes
(:class:`NodeInertia`, the per-node invariants m_j, p_j, J_j, lambda_j, gamma_j, as Exudyn's floating-frame
formulation evaluates its inertia terms) they cost O(N_r n) per evaluation instead of the O(n^3) and O(n^4)
tables (N_r: the nodes with rotary inertia or offsets), exactly: with ``dJ = theta~ J - J theta~`` (first
order), ``-theta~ J theta~`` (second order) and ``dP = (theta x p)~``,

    G(eta)  = G0 + sum_j lambda_j' dJ_j lambda_j + m_j (lambda_j' dP_j gamma_j + gamma_j' dP_j' lambda_j),
    F2 eta eta (rows omega of M_re) = sum_j (-theta_j~ J_j theta_j~ - m_j u_j~ dP_j) lambda_j,  u_j = gamma_j eta,

the blocks of ``sum_j Y_j' M_nd,j Y_j`` (E.1.34) that the tables hold. :func:`flexible_body_from_modal_body`
chooses the nodal form where it is cheaper (:func:`nodal_is_cheaper`). A user may also leave the three
terms out (``omit_terms``, :data:`OMITTABLE_TERMS`). The kinetic energy stays a positive quadratic form of the
velocities with any subset of the terms (they are small corrections at small deformation), so the
equations of motion remain Lagrangian and conserve energy; what is lost is the change of the modal mass
(G1, G2) and of the rotational/modal coupling (F2) with the rotation ``lambda eta`` of the nodes' own
inertia, effects of relative size ``|lambda eta|`` (the node rotation angles) on those blocks.

The equations of motion follow from Lagrange's equations for ``eta`` and the Euler-Poincare (Kirchhoff)
equations for the quasi-velocity ``V`` (see :mod:`dynamics.kernels`).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from dynamics.errors import ModelDefinitionError
from dynamics.spatial import skew

OMITTABLE_TERMS = ("G1", "F2", "G2")
"""Terms of M(eta) a user may leave out: the O(n^3) and O(n^4) ones (module docstring)."""


@dataclass
class ModalMassTerms:
    """The eta-dependent blocks of a body mass matrix, stored compactly ([omega, v, eta] order).

    ``R1`` (n, 6, 6) = M1[r, :6, :6]; ``C1`` (n, 6, n) = M1[r, :6, 6:]; ``G1`` (n, n, n) = M1[r, 6:, 6:];
    ``J2`` (n, n, 3, 3) = M2[r, s, :3, :3]; ``F2`` (n, n, 3, n) = M2[r, s, :3, 6:];
    ``G2`` (n, n, n, n) = M2[r, s, 6:, 6:]; ``P2`` (n, n, 3) the geometric-stiffening shift of the mass
    centre, M2[r, s, :3, 3:6] = skew(P2[r, s]) = -M2[r, s, 3:6, :3] (:func:`add_geometric_stiffening`).
    A term is None when it is absent: above the body's order,
    identically zero, or omitted. The other blocks of M1, M2 follow by symmetry (or are zero)."""

    R1: np.ndarray | None = None
    C1: np.ndarray | None = None
    G1: np.ndarray | None = None
    J2: np.ndarray | None = None
    F2: np.ndarray | None = None
    G2: np.ndarray | None = None
    P2: np.ndarray | None = None  # (n, n, 3): second-order mass-centre shift m p2 (geometric stiffening)

    def present(self):
        """Names of the terms that are present."""
        return tuple(f.name for f in dataclasses.fields(self) if getattr(self, f.name) is not None)


@dataclass
class NodeInertia:
    """The nodes of a flexible body whose own inertia turns with their elastic rotation (rotary inertia
    ``inertia`` J_j about the node, or a centre-of-mass offset ``cg`` p_j), with their mass ``mass`` m_j and
    mode shapes ``shapes`` (N_r, 6, n) = [lambda_j; gamma_j]: the engine evaluates the ``terms`` (a subset of
    :data:`OMITTABLE_TERMS`) of M(eta) as sums over them (module docstring) instead of tables."""

    mass: np.ndarray  # (N_r,)
    cg: np.ndarray  # (N_r, 3)
    inertia: np.ndarray  # (N_r, 3, 3) about the node
    shapes: np.ndarray  # (N_r, 6, n)
    terms: tuple = ()

    @property
    def count(self):
        return int(self.mass.shape[0])


@dataclass
class NodeMass:
    """Every node of a flexible body with mass or inertia (mass ``mass`` m_j, CG offset ``cg`` p_j, inertia
    ``inertia`` J_j about the node, undeformed position ``positions`` l0_j and mode shapes ``shapes`` (N, 6, n) =
    [lambda_j; gamma_j]): the engine evaluates the ``terms`` (of "C1", "J2") of M(eta) as sums over them
    (:mod:`dynamics.kernels.node_mass`) instead of tables."""

    mass: np.ndarray  # (N,)
    cg: np.ndarray  # (N, 3)
    inertia: np.ndarray  # (N, 3, 3) about the node
    positions: np.ndarray  # (N, 3)
    shapes: np.ndarray  # (N, 6, n)
    terms: tuple = ()

    @property
    def count(self):
        return int(self.mass.shape[0])

    @property
    def rotary(self):
        """Whether any node has rotary inertia or a CG offset (else the rotation shapes are not read)."""
        return bool(np.any(self.inertia) or np.any(self.cg))


@dataclass
class FlexibleBodyData:
    """Modal data of one flexible body, ready for the engine (SI units, body frame).

    The eta-dependent part of M(eta) is given either as the polynomial coefficients ``M1`` (n, N, N)
    and ``M2`` (n, n, N, N) (convenient for small bodies and tests), or compactly as ``terms`` (what
    :func:`flexible_body_from_modal_body` builds, without the O(n^3) arrays). ``node_inertia`` (a
    :class:`NodeInertia`) holds the terms G1, F2, G2 as per-node invariants instead of tables (then absent
    from ``terms``). ``note`` records a choice made for the user (an order chosen by default), reported by the
    compiled system. ``mass_nodes`` (a :class:`NodeMass`) holds the terms C1 and J2 as sums over every node
    instead of tables (then absent from ``terms``)."""

    n_modes: int
    order: int
    M0: np.ndarray  # (N, N)
    M1: np.ndarray | None  # (n, N, N) at order >= 1, or None with ``terms``
    M2: np.ndarray | None  # (n, n, N, N) at order 2, or None with ``terms``
    stiffness: np.ndarray  # (n, n) modal stiffness
    damping: np.ndarray  # (n, n) modal damping
    grid_ids: np.ndarray  # (G,) grids whose shapes are available for nodes
    grid_positions: np.ndarray  # (G, 3) undeformed positions l0 in the body frame
    grid_shapes: np.ndarray  # (G, 6, n) Pi(j) = [lambda; gamma]
    frequencies_hz: np.ndarray  # (n,)
    source: str = "arrays"
    terms: ModalMassTerms | None = None
    note: str = ""
    node_inertia: NodeInertia | None = None
    geometric_stiffening: bool = False  # the terms of add_geometric_stiffening are in
    stiffness_available: bool = False  # the body file holds geometric stiffness (used or not)
    first_frequency_hz: float | None = None  # the body's lowest elastic frequency mounted (None: its lowest mode's)
    mass_nodes: NodeMass | None = None

    @property
    def lowest_frequency_hz(self):
        """The lowest elastic frequency to compare the scene's rates with: ``first_frequency_hz`` (a component
        mode set's fixed-interface frequency: the body held at its interface), else the lowest of its modes."""
        return float(self.first_frequency_hz if self.first_frequency_hz is not None else np.min(self.frequencies_hz))

    @property
    def mass(self):
        return float(self.M0[3, 3])

    def grid_index(self, grid_id):
        hits = np.flatnonzero(self.grid_ids == grid_id)
        if hits.size == 0:
            raise ModelDefinitionError(f"grid {grid_id} is not in the flexible body's modal data "
                                       f"({self.source}); grids run from {self.grid_ids.min()} to "
                                       f"{self.grid_ids.max()}")
        return int(hits[0])

    def mass_terms(self):
        """The :class:`ModalMassTerms` of M(eta) (from ``terms``, or extracted from ``M1``, ``M2``)."""
        if self.terms is not None:
            return self.terms
        return mass_terms_from_polynomial(self.M1, self.M2, self.order, self.n_modes, self.source)

    def without(self, omit_terms):
        """A copy without the terms named in ``omit_terms`` (a subset of :data:`OMITTABLE_TERMS`)."""
        omit = tuple(omit_terms)
        unknown = sorted(set(omit) - set(OMITTABLE_TERMS))
        if unknown:
            raise ModelDefinitionError(f"{self.source}: omit_terms: only {list(OMITTABLE_TERMS)} can be "
                                       f"left out (the O(n^3) and O(n^4) terms), got {unknown}")
        if not omit:
            return self
        terms = dataclasses.replace(self.mass_terms(), **{name: None for name in omit})
        nodes = self.node_inertia
        if nodes is not None:
            kept = tuple(t for t in nodes.terms if t not in omit)
            nodes = dataclasses.replace(nodes, terms=kept) if kept else None
        return dataclasses.replace(self, M1=None, M2=None, terms=terms, node_inertia=nodes)


def _nonzero(a):
    return a if a is not None and np.any(a) else None


def mass_terms_from_polynomial(M1, M2, order, n, source="arrays"):
    """:class:`ModalMassTerms` of ``M(eta) = M0 + M1 eta + M2 eta eta`` (blocks that are zero: None).

    Refuses coefficients the engine does not model: a first-order block that is not symmetric, or
    second-order terms outside the rotational rows (the modal integrals of TM Appendix E have none)."""
    N = 6 + n
    terms = ModalMassTerms()
    if order >= 1 and n:
        M1 = np.asarray(M1, dtype=np.float64)
        if M1.shape != (n, N, N):
            raise ModelDefinitionError(f"{source}: M1 must have shape {(n, N, N)} at order {order}, "
                                       f"got {M1.shape}")
        if np.abs(M1 - M1.transpose(0, 2, 1)).max() > 1e-12 * max(np.abs(M1).max(), 1e-300):
            raise ModelDefinitionError(f"{source}: every M1[r] must be symmetric")
        terms.R1 = _nonzero(np.ascontiguousarray(M1[:, :6, :6]))
        terms.C1 = _nonzero(np.ascontiguousarray(M1[:, :6, 6:]))
        terms.G1 = _nonzero(np.ascontiguousarray(M1[:, 6:, 6:]))
    if order >= 2 and n:
        M2 = np.asarray(M2, dtype=np.float64)
        if M2.shape != (n, n, N, N):
            raise ModelDefinitionError(f"{source}: M2 must have shape {(n, n, N, N)} at order 2, got {M2.shape}")
        scale = max(np.abs(M2).max(), 1e-300)
        if (np.abs(M2 - M2.transpose(1, 0, 2, 3)).max() > 1e-12 * scale
                or np.abs(M2 - M2.transpose(0, 1, 3, 2)).max() > 1e-12 * scale):
            raise ModelDefinitionError(f"{source}: M2[r, s] must be symmetric in (r, s) and as a matrix")
        if np.any(M2[:, :, 3:6, :6]) or np.any(M2[:, :, :3, 3:6]) or np.any(M2[:, :, 3:6, 6:]):
            raise ModelDefinitionError(f"{source}: M2 has second-order terms in the linear-momentum rows, "
                                       f"which the modal integrals (TM App. E) do not produce and the engine "
                                       f"does not model; only M2[r, s, :3, :3], [:3, 6:] and [6:, 6:] may be "
                                       f"non-zero")
        terms.J2 = _nonzero(np.ascontiguousarray(M2[:, :, :3, :3]))
        terms.F2 = _nonzero(np.ascontiguousarray(M2[:, :, :3, 6:]))
        terms.G2 = _nonzero(np.ascontiguousarray(M2[:, :, 6:, 6:]))
    return terms


def mass_terms_from_integrals(mi, order):
    """:class:`ModalMassTerms` straight from a ``ModalIntegrals`` (no n N^2 polynomial arrays): the same
    blocks :func:`mass_matrix_polynomial` places in M1, M2. Integrals that are None are left out."""
    n = mi.G0.shape[0]
    m = float(mi.mass)
    terms = ModalMassTerms()
    if order >= 1:
        R1 = np.zeros((n, 6, 6))
        R1[:, :3, :3] = mi.J1 + mi.J1.transpose(0, 2, 1)
        skew_p1 = np.zeros((n, 3, 3))
        skew_p1[:, 0, 1], skew_p1[:, 0, 2], skew_p1[:, 1, 2] = -mi.p1[:, 2], mi.p1[:, 1], -mi.p1[:, 0]
        skew_p1 -= skew_p1.transpose(0, 2, 1)
        R1[:, :3, 3:6] = m * skew_p1
        R1[:, 3:6, :3] = -m * skew_p1
        terms.R1 = _nonzero(R1)
        C1 = np.zeros((n, 6, n))
        C1[:, :3, :] = mi.F1.transpose(1, 2, 0)  # F(s) gains F1[s, r] eta_r
        C1[:, 3:6, :] = mi.E1.transpose(1, 2, 0)
        terms.C1 = _nonzero(C1)
        if mi.G1 is not None and np.any(mi.G1):  # point-mass nodes: zeros, left out before any n^3 copy
            G1 = mi.G1.transpose(2, 0, 1)
            terms.G1 = _nonzero(np.ascontiguousarray(G1 + G1.transpose(0, 2, 1)))
    if order >= 2:
        J2 = 0.5 * (mi.J2 + mi.J2.transpose(1, 0, 3, 2))  # symmetric in (r, s) as matrices
        terms.J2 = _nonzero(np.ascontiguousarray(0.5 * (J2 + J2.transpose(0, 1, 3, 2))))
        if mi.F2 is not None and np.any(mi.F2):
            F2 = 0.5 * (mi.F2 + mi.F2.transpose(0, 2, 1, 3))  # (l, r, s, a) symmetric in (r, s)
            terms.F2 = _nonzero(np.ascontiguousarray(F2.transpose(1, 2, 3, 0)))
        if mi.G2 is not None:
            G2 = 0.25 * (mi.G2 + mi.G2.transpose(1, 0, 2, 3) + mi.G2.transpose(0, 1, 3, 2)
                         + mi.G2.transpose(1, 0, 3, 2))
            terms.G2 = _nonzero(np.ascontiguousarray(G2.transpose(2, 3, 0, 1)))
    return terms


def rigid_mass_block(mi):
    """M0 (N x N, [omega, v, eta]) from a ``ModalIntegrals``."""
    n = mi.G0.shape[0]
    M0 = np.zeros((6 + n, 6 + n))
    m = float(mi.mass)
    M0[:3, :3] = mi.J0
    M0[:3, 3:6] = m * skew(mi.p0)
    M0[3:6, :3] = -m * skew(mi.p0)
    M0[3:6, 3:6] = m * np.eye(3)
    M0[:3, 6:] = mi.F0.T
    M0[3:6, 6:] = mi.E0.T
    M0[6:, 6:] = mi.G0
    M0[6:, :6] = M0[:6, 6:].T
    return M0


def mass_matrix_polynomial(mi, order):
    """(M0, M1, M2) in [omega, v, eta] order from a ``dynamics.flex.modal_integrals.ModalIntegrals``.

    Only the terms of the requested order are allocated (M2 alone is n^2 (6 + n)^2 numbers); for large
    bodies use :func:`mass_terms_from_integrals`, which the engine stores."""
    n = mi.G0.shape[0]
    N = 6 + n
    M0 = rigid_mass_block(mi)
    M1 = np.zeros((n, N, N) if order >= 1 else (0, N, N))
    M2 = np.zeros((n, n, N, N) if order >= 2 else (0, 0, N, N))
    terms = mass_terms_from_integrals(mi, order)
    if terms.R1 is not None:
        M1[:, :6, :6] = terms.R1
    if terms.C1 is not None:
        M1[:, :6, 6:] = terms.C1
        M1[:, 6:, :6] = terms.C1.transpose(0, 2, 1)
    if terms.G1 is not None:
        M1[:, 6:, 6:] = terms.G1
    if terms.J2 is not None:
        M2[:, :, :3, :3] = terms.J2
    if terms.F2 is not None:
        M2[:, :, :3, 6:] = terms.F2
        M2[:, :, 6:, :3] = terms.F2.transpose(0, 1, 3, 2)
    if terms.G2 is not None:
        M2[:, :, 6:, 6:] = terms.G2
    return M0, M1, M2


def add_geometric_stiffening(terms, stiffness, gs, preload=None, source=""):
    """``terms`` (:class:`ModalMassTerms`) and modal ``stiffness`` with the geometric stiffening of ``gs``
    (a :class:`dynamics.flex.geometric_stiffness.GeometricStiffness` for the same modes) added.

    The foreshortening ``u2_j(eta)`` of the nodes (second order in eta) does the work
    ``sum_j f_j . u2_j = -1/2 eta' K_G[f] eta`` on a load ``f``. The kinetic energy term linear in it,
    ``sum_j m_j (v + omega x l_j) . (omega x u2_j + du2_j/dt)``, is then, with ``K_t[k]``, ``K_a[k]``,
    ``K_w[ab]`` the translation, rotation and angular-velocity cases,

        T_G = -eta' (sum_k v_k K_t[k] + omega_k K_a[k]) eta_dot
              - 1/2 eta' (sum_ab omega_a omega_b K_w[ab] + sum_k (v x omega)_k K_t[k]) eta,

    a quadratic form in the velocities with eta-dependent coefficients, i.e. an addition to M(eta):
    ``C1[r, k, s] -= K_a[k][r, s]`` (k = 0..2), ``C1[r, 3 + k, s] -= K_t[k][r, s]``,
    ``J2[r, s, a, b] -= K_w[ab][r, s]`` and ``P2[r, s, k] = -1/2 K_t[k][r, s]`` (``m p2 = P2 eta eta``: the
    mass centre moves by the foreshortening). The equations of motion stay Lagrange's (energy conserved in
    free spin); in steady spin the modal stiffness becomes ``K + sum omega_a omega_b K_w[ab] + ...`` (the
    centrifugal stiffening), and ``d/dt`` of the modal momentum gives the acceleration terms
    ``K_t[k] a_k + K_a[k] alpha_k`` of Banerjee and Dickens (JGCD 1990). ``preload``: {name: scale} of
    the named preloads, added as ``scale * K_pre`` to the stiffness (a potential)."""
    n = stiffness.shape[0]
    if gs.n_modes != n:
        raise ModelDefinitionError(f"{source}: geometric stiffness for {gs.n_modes} modes, body has {n}")
    C1 = np.zeros((n, 6, n)) if terms.C1 is None else terms.C1.copy()
    for k in range(3):
        C1[:, k, :] -= gs.rotation[k]
        C1[:, 3 + k, :] -= gs.translation[k]
    J2 = np.zeros((n, n, 3, 3)) if terms.J2 is None else terms.J2.copy()
    for a in range(3):
        for b in range(3):
            J2[:, :, a, b] -= gs.omega_matrix(a, b)
    P2 = np.ascontiguousarray(-0.5 * gs.translation.transpose(1, 2, 0))
    K = np.array(stiffness, dtype=np.float64)
    for name, scale in (preload or {}).items():
        if name not in gs.preload_names:
            raise ModelDefinitionError(f"{source}: preload {name!r} is not in the body file (it has "
                                       f"{gs.preload_names or 'none'}; fem2modal --preload NAME:GRID:COMP:VALUE)")
        K = K + float(scale) * gs.preload[gs.preload_names.index(name)]
    return dataclasses.replace(terms, C1=_nonzero(C1), J2=_nonzero(J2), P2=_nonzero(P2)), K


def node_inertia_from_nodes(mass, cg, inertia, shapes, order, omit=()):
    """The :class:`NodeInertia` of the nodes with rotary inertia or a CG offset among ``mass`` (N,),
    ``cg`` (N, 3), ``inertia`` (N, 3, 3) about the node and ``shapes`` (N, 6, n), for the terms of
    modal-integral ``order`` (G1 at 1, G1, F2, G2 at 2) not in ``omit``; None when no node has either or no
    term is left."""
    terms = tuple(t for t in (("G1",) if order >= 1 else ()) + (("F2", "G2") if order >= 2 else ()) if t not in omit)
    inertia = np.asarray(inertia, dtype=np.float64)
    cg = np.asarray(cg, dtype=np.float64)
    sel = (np.abs(inertia).reshape(len(inertia), -1).max(axis=1, initial=0.0) > 0.0) | (np.abs(cg).max(axis=1) > 0.0)
    if not terms or not np.any(sel):
        return None
    return NodeInertia(mass=np.asarray(mass, dtype=np.float64)[sel], cg=cg[sel], inertia=inertia[sel],
                       shapes=np.ascontiguousarray(np.asarray(shapes, dtype=np.float64)[sel]), terms=terms)


def nodal_is_cheaper(n, count, terms, tables_available=True):
    """Whether the terms ``terms`` (of G1, F2, G2) cost less per evaluation as sums over ``count`` nodes than
    as tables of a body of ``n`` modes (multiply-adds: G1 2 n^3 to form and differentiate, F2 9 n^3, G2 2 n^4,
    and a factorization of the modal mass n^3 / 3; over the nodes about 30 n per node for the forces and
    four refinements of 6 n per node against the constant modal mass, see :mod:`dynamics.kernels.articulated_body`).
    Tables that the body file does not hold (G2 above 40 modes) are never cheaper."""
    if not tables_available:
        return True
    table = (2.0 * n ** 3 if "G1" in terms else 0.0) + (9.0 * n ** 3 if "F2" in terms else 0.0) \
        + (2.0 * n ** 4 if "G2" in terms else 0.0) + (n ** 3 / 3.0 if {"G1", "G2"} & set(terms) else 0.0)
    nodal = count * n * (30.0 + (24.0 if {"G1", "G2"} & set(terms) else 0.0))
    return nodal < table


def node_mass_from_nodes(mass, cg, inertia, positions, shapes, order):
    """The :class:`NodeMass` of the nodes with mass or inertia among ``mass`` (N,), ``cg`` (N, 3), ``inertia``
    (N, 3, 3), ``positions`` (N, 3) and ``shapes`` (N, 6, n), for the terms of modal-integral ``order`` (C1 at 1,
    C1 and J2 at 2); None at order 0 or when no node has mass."""
    terms = ("C1",) if order == 1 else ("C1", "J2") if order == 2 else ()
    mass = np.asarray(mass, dtype=np.float64)
    cg = np.asarray(cg, dtype=np.float64)
    inertia = np.asarray(inertia, dtype=np.float64)
    sel = (mass != 0.0) | (np.abs(inertia).reshape(len(mass), -1).max(axis=1, initial=0.0) > 0.0)
    if not terms or not np.any(sel):
        return None
    return NodeMass(mass=mass[sel], cg=cg[sel], inertia=inertia[sel],
                    positions=np.asarray(positions, dtype=np.float64)[sel],
                    shapes=np.ascontiguousarray(np.asarray(shapes, dtype=np.float64)[sel]), terms=terms)


def same_nodes(mass_nodes, node_inertia):
    """Whether the C1/J2 nodes ``mass_nodes`` (a :class:`NodeMass`) are the G1/F2/G2 nodes ``node_inertia`` (a
    :class:`NodeInertia`, or None) of the same body: same order, masses, offsets, inertias and shapes (every node
    with mass has rotary inertia, as on the beams and shells of real decks). The engine then sums C1 and J2 with
    the passes of the G1/F2/G2 terms over the same shapes (:mod:`dynamics.kernels.node_mass`)."""
    if node_inertia is None or node_inertia.count != mass_nodes.count:
        return False
    return all(np.array_equal(np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64))
               for a, b in ((mass_nodes.mass, node_inertia.mass), (mass_nodes.cg, node_inertia.cg),
                            (mass_nodes.inertia, node_inertia.inertia), (mass_nodes.shapes, node_inertia.shapes)))


def node_mass_is_cheaper(n, nodes, node_inertia=None):
    """Whether the terms of ``nodes`` (a :class:`NodeMass`) cost less per evaluation summed over the nodes than as
    tables of a body of ``n`` modes, counted in multiply-adds. Tables: C1 three per entry (``3 n^2`` entries,
    ``6 n^2`` with CG offsets), J2 one (``9 n^2``); over the nodes: 6 per entry of the ``3N x n`` translation
    shapes (two passes: the shapes times eta and the rates, then C(eta) and the modal forces), as many of the
    rotation shapes when nodes have rotary inertia (none where they are the nodes of the terms G1, F2, G2,
    ``node_inertia``: their passes serve both, :func:`same_nodes`), 3 more with CG offsets, and some 150 per node.
    Both are bound by reading their data at a few hundred modes (the tables ``12 n^2`` numbers once, the shapes
    ``4 x 3N n`` numbers in two passes each): ``TABLE_WEIGHT`` is the measured ratio. On the 101-grid tube of
    ``benchmarks/flexible_scaling.py --deck-only`` (rotary inertia on every grid, the passes shared) the node sums
    are cheaper from about 75 modes at order 2 (C1 and J2) and 190 at order 1 (C1 only); this rule puts the switch
    at 92 and 177 (2026-12-07, ``node_mass_is_cheaper`` forced either way, interleaved: order 2 at 50, 100, 150,
    196 modes 1.11x, 0.91x, 0.80x, 0.72x the tables' forward dynamics, order 1 1.22x, 1.15x, 1.09x, 0.98x)."""
    rows = 6 if np.any(nodes.cg) else 3
    table = 3.0 * rows * n * n * ("C1" in nodes.terms) + 9.0 * n * n * ("J2" in nodes.terms)
    rotary = nodes.rotary and not same_nodes(nodes, node_inertia)
    per_entry = 6.0 + (6.0 if rotary else 0.0) + (3.0 if np.any(nodes.cg) else 0.0)
    nodal = 3.0 * nodes.count * n * per_entry + 150.0 * nodes.count
    return nodal < TABLE_WEIGHT * table


TABLE_WEIGHT = 1.2
"""Cost of a multiply-add of the C1 and J2 tables relative to one of the node sums (:func:`node_mass_is_cheaper`;
measured 2026-12-07 on the tube of ``benchmarks/flexible_scaling.py --deck-only``: 0.9 to 1.4)."""


def flexible_body_from_modal_body(body, modes=None, order=None, damping_ratio=None, integrals="general",
                                  omit_terms=(), geometric_stiffening=None, preload=None):
    """Build :class:`FlexibleBodyData` from a ``dynamics.flex.body_file.ModalBody`` (a body file).

    ``modes``: indices of the modes to keep (default all); ``order``: modal-integral order 0, 1, 2, or
    None for 2 (the terms G1, F2, G2 of nodes with rotary inertia come from the file's per-grid masses and
    shapes, :class:`NodeInertia`, where that is cheaper than the file's tables or the file omits them);
    ``damping_ratio``: overrides the file's damping (scalar or per kept mode); ``integrals``: ``"general"``
    (nodes with their own inertia and offsets, E.2.2-E.2.5) or ``"point_mass"`` (E.3.1); ``omit_terms``: terms
    of M(eta) to leave out (subset of :data:`OMITTABLE_TERMS`, see the module docstring);
    ``geometric_stiffening``: add the body file's geometric stiffness (:func:`add_geometric_stiffening`); None
    (default) adds it when the file has it, True requires it, False leaves it out; ``preload``: {name:
    scale} of the file's named preloads.
    """
    if order not in (None, 0, 1, 2):
        raise ModelDefinitionError(f"modal-integral order must be 0, 1 or 2, got {order!r}")
    if integrals not in ("general", "point_mass"):
        raise ModelDefinitionError(f"integrals must be 'general' or 'point_mass', got {integrals!r}")
    mi = body.modal_integrals if integrals == "general" else body.point_mass_integrals
    if mi is None:
        raise ModelDefinitionError(
            f"{body.source}: the body file has no {integrals} modal integrals; regenerate it with "
            f"`flexshell fem2modal ... --modal-integrals`")
    n_all = body.n_modes
    keep = np.arange(n_all) if modes is None else np.asarray(modes, dtype=np.int64)
    if keep.size == 0 or keep.min() < 0 or keep.max() >= n_all:
        raise ModelDefinitionError(f"{body.source}: modes {keep.tolist()} out of range 0..{n_all - 1}")
    if order is None:
        order = 2
    shapes = np.concatenate([body.rotation_shapes[:, :, keep], body.translation_shapes[:, :, keep]], axis=1)
    nodes = None
    if integrals == "general":
        nodes = node_inertia_from_nodes(body.node_mass, body.node_cm_offset, body.node_inertia, shapes, order,
                                        omit_terms)
    if nodes is not None:
        tables = all(getattr(mi, t) is not None for t in nodes.terms)
        if not nodal_is_cheaper(int(keep.size), nodes.count, nodes.terms, tables):
            nodes = None
    if nodes is None and order == 2 and integrals == "general" and mi.G2 is None \
            and bool(np.any(body.node_inertia)) and "G2" not in omit_terms:
        raise ModelDefinitionError(f"{body.source}: order-2 modal integrals need G2, which the body file omits and "
                                   f"its per-grid inertias cannot give")
    sub = _select_modes(mi, keep, skip=() if nodes is None else nodes.terms)
    terms = mass_terms_from_integrals(sub, order)
    K = np.asarray(body.modal_stiffness)[np.ix_(keep, keep)]
    gs = getattr(body, "geometric_stiffness", None)
    if geometric_stiffening and gs is None:
        raise ModelDefinitionError(f"{body.source}: geometric_stiffening requested but the body file has no "
                                   f"geometric stiffness; regenerate it with `flexshell fem2modal ... "
                                   f"--geometric-stiffness`")
    if preload and (gs is None or geometric_stiffening is False):
        raise ModelDefinitionError(f"{body.source}: preload {sorted(preload)} needs the body file's geometric "
                                   "stiffness (fem2modal --preload) with geometric stiffening on")
    stiffening = gs is not None and geometric_stiffening is not False
    if stiffening:
        terms, K = add_geometric_stiffening(terms, K, gs.select(keep), preload, body.source)
    mass_nodes = None
    if not stiffening:  # geometric stiffening adds parts to C1 and J2 that are not node sums: tables then
        if integrals == "general":
            mass_nodes = node_mass_from_nodes(body.node_mass, body.node_cm_offset, body.node_inertia,
                                              body.grid_positions, shapes, order)
        else:
            count = len(body.node_mass)
            mass_nodes = node_mass_from_nodes(body.node_mass, np.zeros((count, 3)), np.zeros((count, 3, 3)),
                                              body.grid_positions, shapes, order)
        if mass_nodes is not None and node_mass_is_cheaper(int(keep.size), mass_nodes, nodes):
            terms = dataclasses.replace(terms, C1=None, J2=None)
        else:
            mass_nodes = None
    if damping_ratio is None:
        C = np.asarray(body.modal_damping)[np.ix_(keep, keep)]
    else:
        zeta = np.broadcast_to(np.asarray(damping_ratio, dtype=float), keep.shape)
        omega = 2.0 * np.pi * np.asarray(body.frequencies_hz)[keep]
        omega[np.isinf(omega)] = 0.0          # quasi-static modes: no mass, nothing to damp
        C = np.diag(2.0 * zeta * omega)
    data = FlexibleBodyData(n_modes=int(keep.size), order=order, M0=rigid_mass_block(sub), M1=None, M2=None,
                            stiffness=K, damping=C, grid_ids=np.asarray(body.grid_ids),
                            grid_positions=body.grid_positions, grid_shapes=shapes,
                            frequencies_hz=np.asarray(body.frequencies_hz)[keep], source=body.source,
                            terms=terms, node_inertia=nodes,
                            geometric_stiffening=stiffening, stiffness_available=gs is not None,
                            first_frequency_hz=_first_frequency(body, keep), mass_nodes=mass_nodes)
    return data.without(omit_terms)


def _first_frequency(body, keep):
    """The lowest elastic frequency of the body file's kept modes, or of its fixed-interface modes when it has
    them (normalized component modes list the frequencies of the free body: 6.4 times the first of a cantilever
    held at its interface)."""
    f = float(np.min(np.asarray(body.frequencies_hz)[keep]))
    cb = getattr(body, "craig_bampton", None)
    if cb is not None and len(cb.frequencies_hz):
        f = min(f, float(np.min(cb.frequencies_hz)))
    return f


def _select_modes(mi, keep, skip=()):
    """The integrals of the kept modes; those named in ``skip`` (evaluated over the nodes instead) are None."""
    from dynamics.flex.modal_integrals import ModalIntegrals

    ix = np.ix_

    def take(a, *axes):
        return None if a is None else a[ix(*[keep] * len(axes))] if len(axes) > 1 else a[keep]

    return ModalIntegrals(
        mass=mi.mass, p0=mi.p0, J0=mi.J0, p1=take(mi.p1, 0), J1=take(mi.J1, 0), J2=take(mi.J2, 0, 1),
        F0=mi.F0[keep], F1=take(mi.F1, 0, 1), F2=None if "F2" in skip else take(mi.F2, 0, 1, 2), E0=mi.E0[keep],
        E1=take(mi.E1, 0, 1), G0=mi.G0[ix(keep, keep)], G1=None if "G1" in skip else take(mi.G1, 0, 1, 2),
        G2=None if "G2" in skip else take(mi.G2, 0, 1, 2, 3))
