"""Geometric (differential) stiffness of a flexible body under the loads of its rigid motion and of a
named preload, projected on its modes (issue 15: geometric stiffening).

Why: a spinning or accelerating structure carries internal forces from its own inertia (the centrifugal
tension of a rotor blade, the compression of a launch vehicle under thrust), and the stress state
changes its bending stiffness. The modal integrals of the mass matrix alone miss this (a modal model of
a spun-up beam then diverges; Kane, Ryan and Banerjee, JGCD 10(2), 1987). The remedy of Banerjee and
Dickens ("Dynamics of an arbitrary flexible body in large rotation and translation", JGCD 13(2), 1990)
and of the SID "standard input data" format (Wallrapp, Mech. Struct. Mach. 22(3), 1994: the
geometric-stiffening terms of the SID) is to compute, once, the geometric stiffness of the structure
under unit inertial load cases and to scale them in the equations of motion by the current rigid-body
motion. Here the load cases are the d'Alembert loads of the body frame's motion on the lumped node
masses ``B_j`` (6 x 6 grid blocks of the lumped mass matrix, the same nodal model as the modal
integrals), with ``l_j`` the grid position from the reference point (body frame)::

    ==========  ======  ===========================================  ==========================================
    name        count   node load (translation part; rotation part)  scaled in the engine by
    ==========  ======  ===========================================  ==========================================
    translation 3 (k)   B_j [e_k; 0]                                 v_k (with eta_dot), (v x omega)_k
    rotation    3 (k)   B_j [e_k x l_j; e_k]                         omega_k (with eta_dot)
    angular_    3 x 3   B_j [omega-product field; 0], field          omega_a omega_b
    velocity    (a, b)  delta_ab l_j - (e_a l_jb + e_b l_ja) / 2
    ==========  ======  ===========================================  ==========================================

(translation = the load of a unit acceleration -e_k, rotation = of a unit angular acceleration -e_k, the
angular-velocity products sum to the centrifugal load ``m_j (|omega|^2 l_j - omega (omega . l_j))``.)
For each case the static displacement ``u = K^-1 f`` gives every element's axial force ``N`` (tension
positive) and the element's geometric stiffness ``K_G,e = N K_G1,e``; the modal matrix of the case is
``Phi' (sum_e K_G,e) Phi`` (n x n, symmetric, with the body file's mode shapes).

How the loads are reacted (the stress state depends on it):

* bodies with an a-set (Craig-Bampton / normalized component modes, mounted at an interface grid): the
  a-set DOFs are held (``reaction = "aset"``): the loads flow to the interface, as in a blade on its hub;
* free-free bodies: inertia relief (``reaction = "inertia_relief"``): the load's rigid-body resultant is
  balanced by the rigid-body inertia ``M Phi_r a_r`` and the self-equilibrated remainder is solved with
  the rigid motions removed (``[K, M Phi_r; Phi_r' M, 0]``);
* bodies held by the deck's own SPCs (no rigid-body motion left, e.g. a cantilever clamped in the deck and
  mounted by its reference frame): the SPCs react the loads (``reaction = "spc"``).

Why these matrices give the stiffening (the engine side, :mod:`dynamics.flexible_body`): the foreshortening
``u2_j(eta)`` of the nodes (second order in eta, e.g. the axial pull-in of a bent beam) does work on any
load ``f``: ``sum_j f_j . u2_j = -1/2 eta' K_G[f] eta`` (the geometric stiffness is the second variation of
the load's potential). The kinetic energy term linear in ``u2``,
``sum_j m_j (v + omega x l_j) . (omega x u2_j + du2_j/dt)``, is therefore a quadratic form in the
velocities written with these matrices alone: it is added to the body mass matrix ``M(eta)`` (first-order
rigid/modal block and second-order rigid/rigid block), which keeps the equations Lagrangian (energy
conserved in free spin) and gives the angular-acceleration and linear-acceleration terms of Banerjee and
Dickens through d/dt of the modal momentum. A named preload (``f`` given by the user, e.g. thrust through
the structure) is a potential ``1/2 s eta' K_G[f] eta`` added to the modal stiffness, ``s`` its scale in
the scene.

Elements: CBAR and CBEAM (cubic Hermite transverse field and the torsion term N I_p / (A L), Przemieniecki,
Theory of Matrix Structural Analysis, 1968, sec. 15.2, eq. 15.53, I_p = I1 + I2 about the section's
centroid (a tapered PBEAM: its end-A section); element offsets through the same rigid links as the
stiffness) and CROD (a string: N / L on the transverse translations). The geometry,
properties and offsets are read through :mod:`dynamics.flex.assembly`'s own beam functions. Shells
(CQUAD4, CTRIA3: membrane resultants on u, v, w) and solids (CHEXA8/20, CTETRA4/10, CPENTA6/15: the full
stress) through :mod:`dynamics.flex.geometric_stiffness_continuum` (initial-stress matrix int G' S G dV from
the elements' own Gauss-point stresses). Springs
(CBUSH, CELAS) and the shells with mid-side grids (CQUAD8, CTRIA6) contribute no geometric stiffness: the
pipeline warns naming them.
Limits: the shear-flexible beam (PBEAM K) uses the Euler-Bernoulli geometric stiffness; the geometric
stiffness of node rotary inertia loads is left out (second order for slender beams).
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from dynamics.flex import geometric_stiffness_continuum as gsc
from dynamics.flex import solids
from dynamics.flex.bulk_data import BulkDataError

# order of the angular-velocity products in the stored (6, n, n) array
OMEGA_PAIRS = ((0, 0), (1, 1), (2, 2), (0, 1), (1, 2), (2, 0))
"""(a, b) of the six angular-velocity product cases: xx, yy, zz, xy, yz, zx."""

CONTINUUM_ELEMENTS = ("CQUAD4", "CTRIA3", "CHEXA", "CTETRA", "CPENTA")
SUPPORTED_ELEMENTS = ("CBAR", "CBEAM", "CROD") + CONTINUUM_ELEMENTS
# numbers per temporary array of the modal projection of the shells and solids (blocks of elements)
_BLOCK_ENTRIES = 4_000_000


@dataclass
class GeometricStiffness:
    """Modal geometric stiffness of a body under its rigid-motion load cases and named preloads.

    ``translation`` (3, n, n): case k = nodes loaded by ``B_j [e_k; 0]`` (kg m/s^2 per unit acceleration:
    the matrices are in 1/s^2 per m/s^2 with mass-normalized modes, i.e. 1/m); ``rotation`` (3, n, n): by
    ``B_j [e_k x l_j; e_k]`` (per rad/s^2: dimensionless); ``angular_velocity`` (6, n, n): the products
    :data:`OMEGA_PAIRS` (per (rad/s)^2: dimensionless), xy, yz, zx each the symmetric half-sum so that
    ``sum_ab omega_a omega_b K_w[ab]`` over all nine (a, b) equals
    ``sum_k omega_k omega_k K[kk] + 2 sum_{a<b} omega_a omega_b K[ab]``; ``preload`` (p, n, n): the named
    preloads (1/s^2 with mass-normalized modes, per unit scale); ``reaction``: "aset" or
    "inertia_relief" or "spc"; ``elements``: element counts that contributed, e.g. "CBAR 40"."""

    reaction: str
    translation: np.ndarray
    rotation: np.ndarray
    angular_velocity: np.ndarray
    preload_names: list = field(default_factory=list)
    preload: np.ndarray | None = None
    elements: str = ""

    @property
    def n_modes(self) -> int:
        return self.translation.shape[1]

    def omega_matrix(self, a: int, b: int) -> np.ndarray:
        """K_w[ab] (n x n) for any a, b in 0..2 (symmetric in a, b)."""
        for k, (p, q) in enumerate(OMEGA_PAIRS):
            if (p, q) in ((a, b), (b, a)):
                return self.angular_velocity[k]
        raise IndexError((a, b))

    def select(self, keep) -> "GeometricStiffness":
        """The same data for the modes ``keep`` (indices)."""
        keep = np.asarray(keep, dtype=np.int64)

        def sub(a):
            return None if a is None else np.ascontiguousarray(a[:, keep][:, :, keep])

        return GeometricStiffness(self.reaction, sub(self.translation), sub(self.rotation),
                                  sub(self.angular_velocity), list(self.preload_names), sub(self.preload),
                                  self.elements)


def parse_preload(text: str) -> tuple[str, int, int, float]:
    """"NAME:GRID:COMPONENT:VALUE" (component 1-3 force [N], 4-6 moment [N m], basic axes) ->
    (name, grid, component, value)."""
    parts = text.split(":")
    try:
        if len(parts) != 4 or not parts[0].strip():
            raise ValueError
        name, grid, comp, value = parts[0].strip(), int(parts[1]), int(parts[2]), float(parts[3])
    except ValueError:
        raise ValueError(f"--preload expects NAME:GRID:COMPONENT:VALUE (e.g. thrust:11:1:-2000 for a "
                         f"2000 N force along -x at grid 11), got {text!r}") from None
    if comp < 1 or comp > 6:
        raise ValueError(f"--preload {text!r}: component must be 1..6 (1-3 force, 4-6 moment, basic axes), "
                         f"got {comp}")
    if not np.isfinite(value):
        raise ValueError(f"--preload {text!r}: value must be finite")
    return name, grid, comp, value


def hermite_geometric_stiffness(L: float) -> np.ndarray:
    """4 x 4 geometric stiffness per unit axial force of cubic Hermite bending (v1, theta1, v2, theta2),
    ``int v'^2 dx`` (Przemieniecki eq. 15.53): 1/(30 L) [[36, 3L, -36, 3L], ...]."""
    return np.array([[36.0, 3.0 * L, -36.0, 3.0 * L],
                     [3.0 * L, 4.0 * L * L, -3.0 * L, -L * L],
                     [-36.0, -3.0 * L, 36.0, -3.0 * L],
                     [3.0 * L, -L * L, -3.0 * L, 4.0 * L * L]]) / (30.0 * L)


def beam_local_geometric_stiffness(L: float, polar_radius_sq: float = 0.0) -> np.ndarray:
    """12 x 12 local geometric stiffness per unit axial force (tension positive) of a CBAR/CBEAM, local
    DOFs [u v w tx ty tz] per end: plane 1 (v, theta_z), plane 2 (w, -theta_y), and the torsion term
    ``(I_p / A) / L [[1, -1], [-1, 1]]`` on (tx1, tx2) with ``polar_radius_sq = I_p / A = (I1 + I2) / A``
    (Przemieniecki eq. 15.53: the axial stress acting on the helical tilt r theta' of the fibres; linear twist
    as the element's torsion)."""
    K = np.zeros((12, 12))
    if polar_radius_sq:
        K[np.ix_([3, 9], [3, 9])] = polar_radius_sq / L * np.array([[1.0, -1.0], [-1.0, 1.0]])
    h = hermite_geometric_stiffness(L)
    for idx, flip in (([1, 5, 7, 11], [1.0, 1.0, 1.0, 1.0]), ([2, 4, 8, 10], [1.0, -1.0, 1.0, -1.0])):
        f = np.asarray(flip)
        K[np.ix_(idx, idx)] += h * np.outer(f, f)
    return K


def rod_local_geometric_stiffness(L: float) -> np.ndarray:
    """12 x 12 local geometric stiffness per unit axial force of a CROD (a string on the translations)."""
    K = np.zeros((12, 12))
    for d in (1, 2):
        K[np.ix_([d, 6 + d], [d, 6 + d])] = np.array([[1.0, -1.0], [-1.0, 1.0]]) / L
    return K


def _line_elements(sm):
    """(grid rows a, b (ne,), T (ne, 12, 12) local <- grid basic [T; R], EA/L (ne,), axis (ne, 3), unit
    local K_G (ne, 12, 12), counts {type: count}, the other element types {type: count})."""
    from dynamics.flex import assembly as asm
    from dynamics.flex import elements as el

    bulk = sm.bulk
    model = bulk.model
    row_of = {int(g): i for i, g in enumerate(bulk.grid_ids)}

    def idx(gid, ctx):
        i = row_of.get(gid)
        return bulk.grid_index(int(gid), ctx) if i is None else i

    beams, rods, other, sections = [], [], {}, {}
    for eid, elem in sorted(model.elements.items()):
        if elem.type in bulk.report.unsupported:
            continue
        if elem.type in ("CBAR", "CBEAM"):
            beams.append(asm.beam_data(bulk, elem, f"{elem.type} {eid}", bulk.wtmass, idx, sections))
        elif elem.type == "CROD":
            rods.append((eid, elem))
        elif elem.type in CONTINUUM_ELEMENTS:
            continue
        else:
            other[elem.type] = other.get(elem.type, 0) + 1
    ia, ib, T, ea_l, axes, KG = [], [], [], [], [], []
    counts = {}
    if beams:
        dofs, props, frames, wa, wb, is_cbeam = asm.beam_batch(bulk, beams)
        for e in range(len(beams)):
            L, E, A = props[e, 0], props[e, 1], props[e, 3]  # props: L, E, G, A, I1, I2, J, mu, k1, k2
            I1, I2 = props[e, 4], props[e, 5]
            ia.append(int(dofs[e, 0]) // 6)
            ib.append(int(dofs[e, 6]) // 6)
            T.append(el.local_to_grids(frames[e], wa[e], wb[e]))
            ea_l.append(E * A / L)
            KG.append(beam_local_geometric_stiffness(L, (I1 + I2) / A))
        counts["CBEAM"] = int(np.sum(is_cbeam))
        counts["CBAR"] = len(beams) - counts["CBEAM"]
    for eid, elem in rods:
        ctx = f"CROD {eid}"
        a, b = (idx(int(g), ctx) for g in elem.nodes)
        axis = bulk.positions[b] - bulk.positions[a]
        Lam = el.beam_frame(axis, np.eye(3)[np.argmin(np.abs(axis))], ctx)
        L = float(np.linalg.norm(axis))
        prop = asm.property_card(model, int(elem.pid), ("PROD",), ctx)
        E, _, _ = asm.material_card(model, int(prop.mid), f"{ctx} -> PROD {prop.pid}")
        ia.append(a)
        ib.append(b)
        T.append(el.local_to_grids(Lam, np.zeros(3), np.zeros(3)))
        ea_l.append(E * float(prop.A) / L)
        KG.append(rod_local_geometric_stiffness(L))
    if rods:
        counts["CROD"] = len(rods)
    counts = {k: v for k, v in counts.items() if v}
    ne = len(ia)
    return (np.asarray(ia, dtype=np.int64), np.asarray(ib, dtype=np.int64),
            np.asarray(T).reshape(ne, 12, 12), np.asarray(ea_l, dtype=float), np.asarray(KG).reshape(ne, 12, 12),
            counts, other)


def _continuum_elements(sm, counts):
    """Shells grouped by grid count [(rows (ne, nn), shell property rows (ne, 42))] and solids by kind
    [(kind, rows (ne, n), (ne, 3) E nu rho)], read through :mod:`dynamics.flex.assembly`'s own functions;
    ``counts`` gets their numbers by card name."""
    from dynamics.flex import assembly as asm

    bulk = sm.bulk
    row_of = {int(g): i for i, g in enumerate(bulk.grid_ids)}

    def idx(gid, ctx):
        i = row_of.get(gid)
        return bulk.grid_index(int(gid), ctx) if i is None else i

    shells, solid_elems, sections = [], [], {}
    for eid, elem in sorted(bulk.model.elements.items()):
        if elem.type in bulk.report.unsupported:
            continue
        ctx = f"{elem.type} {eid}"
        if elem.type in ("CQUAD4", "CTRIA3"):
            shells.append(asm.shell_data(bulk, elem, ctx, bulk.wtmass, idx, sections))
            if np.any(shells[-1][1][33:42]):
                # the membrane resultants of gsc leave out B kappa
                raise BulkDataError(f"{ctx}: the geometric stiffness of a shell with membrane-"
                                    f"bending coupling (property {elem.pid}: PSHELL MID4 or an "
                                    "unsymmetric PCOMP) is not modelled")
        elif elem.type in ("CHEXA", "CTETRA", "CPENTA"):
            solid_elems.append(asm.solid_data(bulk, elem, ctx, bulk.wtmass, idx, sections))
        else:
            continue
        counts[elem.type] = counts.get(elem.type, 0) + 1
    shell_groups = []
    for nn in (3, 4):
        group = [sh for sh in shells if len(sh[0]) == nn]
        if group:
            shell_groups.append((np.array([sh[0] for sh in group], dtype=np.int64),
                                 np.array([sh[1] for sh in group], dtype=float)))
    solid_groups = []
    for kind in sorted({se[0] for se in solid_elems}):
        group = [se for se in solid_elems if se[0] == kind]
        solid_groups.append((kind, np.array([se[1] for se in group], dtype=np.int64),
                             np.array([se[2] for se in group], dtype=float)))
    return shell_groups, solid_groups


def _contract(H, phi):
    """sum_e sum_ij H[e, c, i, j] phi[e, i, :, k] . phi[e, j, :, l] -> (c, n, n): the initial-stress matrix
    ``H (x) I_3`` of each element on its grids' translations ``phi`` (ne, nn, 3, n), by batched matrix
    products in blocks of elements (temporaries of about _BLOCK_ENTRIES numbers)."""
    ne, c, nn = H.shape[0], H.shape[1], H.shape[2]
    n = phi.shape[3]
    out = np.zeros((c, n, n))
    chunk = max(1, min(ne, _BLOCK_ENTRIES // max(1, c * max(n * n, 3 * nn * n))))
    for start in range(0, ne, chunk):
        h = H[start:start + chunk]                                   # (e, c, i, j)
        p = phi[start:start + chunk].reshape(-1, nn, 3 * n)           # (e, j, d l)
        Y = np.matmul(h, p[:, None])                                  # (e, c, i, d l)
        Y = Y.reshape(Y.shape[0], c, 3 * nn, n)                       # (e, c, (i d), l)
        P = p.reshape(-1, 3 * nn, n).transpose(0, 2, 1)[:, None]      # (e, 1, k, (i d))
        out += np.matmul(P, Y).sum(axis=0)
    return out


def rigid_motion_loads(blocks: np.ndarray, l0: np.ndarray) -> np.ndarray:
    """(N, 6, 12) node loads ([force; moment], basic) of the 12 rigid-motion cases (3 translation, 3
    rotation, 6 angular-velocity products in :data:`OMEGA_PAIRS` order) from the lumped 6 x 6 grid
    blocks ``blocks`` (N, 6, 6, [T; R]) and grid positions ``l0`` (N, 3) from the reference point."""
    N = l0.shape[0]
    field_ = np.zeros((N, 6, 12))
    for k in range(3):
        e = np.eye(3)[k]
        field_[:, k, k] = 1.0
        field_[:, :3, 3 + k] = np.cross(e, l0)
        field_[:, 3 + k, 3 + k] = 1.0
    for c, (a, b) in enumerate(OMEGA_PAIRS):
        f = np.zeros((N, 3))
        if a == b:
            f += l0
        f[:, a] -= 0.5 * l0[:, b]
        f[:, b] -= 0.5 * l0[:, a]
        field_[:, :3, 6 + c] = f
    return np.einsum("nij,njc->nic", blocks, field_)


def static_displacements(sm, K, M, loads_f, held, rigid_vectors):
    """f-set displacements for the f-set loads (n_f, c): ``held`` DOFs fixed (a-set) or, without them,
    inertia relief with the rigid-body vectors."""
    from dynamics.flex.modes import factorize  # supernodal Cholesky (SPD: held or SPC'd), else SuperLU

    nf = K.shape[0]
    if held is not None and len(held):
        free = np.setdiff1d(np.arange(nf), held)
        Kii = sp.csc_matrix(K[free][:, free])
        u = np.zeros_like(loads_f)
        u[free] = np.asarray(factorize(Kii).solve(np.ascontiguousarray(loads_f[free]))).reshape(len(free), -1)
        return u
    R = np.asarray(rigid_vectors)
    if R.size == 0:
        return np.asarray(factorize(sp.csc_matrix(K)).solve(np.ascontiguousarray(loads_f))).reshape(nf, -1)
    MR = np.asarray(M @ R)
    relieved = loads_f - MR @ np.linalg.solve(R.T @ MR, R.T @ loads_f)
    scale = max(abs(K).max(), 1e-300) / max(np.abs(MR).max(), 1e-300)
    A = sp.bmat([[K, sp.csr_matrix(MR * scale)], [sp.csr_matrix(MR.T * scale), None]], format="csc")
    rhs = np.vstack([relieved, np.zeros((R.shape[1], loads_f.shape[1]))])
    return spla.splu(A).solve(np.ascontiguousarray(rhs))[:nf]


def geometric_stiffness(sm, K, M, blocks, l0, rot, trans, held=None, rigid_vectors=None, preloads=(),
                        context="", interface_row=None) -> GeometricStiffness:
    """The :class:`GeometricStiffness` of a structural model (module docstring).

    ``sm``: the :class:`dynamics.flex.assembly.StructuralModel`; ``K``, ``M``: f-set matrices; ``blocks``
    (N, 6, 6): lumped grid mass blocks (basic, [T; R]); ``l0`` (N, 3): grid positions from the reference
    point; ``rot``, ``trans`` (N, 3, n): the body's mode shapes (basic); ``held``: f-set indices of the
    a-set (reaction there), else inertia relief with ``rigid_vectors`` (n_f, r); ``preloads``: list of
    (name, grid, component 1..6, value) in basic axes, several entries per name add up; ``interface_row``:
    row of the interface grid (an a-set grid with all six components) whose frame holds the preloads.

    The rigid-motion cases use the mode shapes as they are (the second-order kinematics of the body frame,
    :mod:`dynamics.flexible_body`). A preload is a load fixed in the frame that holds the structure: for
    normalized component modes, mounted by the interface grid while the body frame floats, its matrix uses
    the shapes relative to the interface grid's rigid motion (else the rigid rotation the constraint modes
    contain would turn the structure against its own preload)."""
    bulk = sm.bulk
    N = len(bulk.grid_ids)
    Rcd = bulk.displacement_rotation
    ia, ib, T, ea_l, KG1, counts, other = _line_elements(sm)
    shell_groups, solid_groups = _continuum_elements(sm, counts)
    if other:
        warnings.warn(f"{context}: geometric stiffness from {', '.join(SUPPORTED_ELEMENTS)} only; the "
                      f"stress in {', '.join(f'{k} ({v})' for k, v in sorted(other.items()))} does not "
                      "stiffen the modes (their geometric stiffness is not implemented)", stacklevel=3)
    if not counts:
        raise ValueError(f"{context}: --geometric-stiffness needs elements that carry stress "
                         f"({', '.join(SUPPORTED_ELEMENTS)}); the deck has none")
    names = []
    for name, _, _, _ in preloads:
        if name not in names:
            names.append(name)
    loads_basic = np.zeros((N, 6, 12 + len(names)))
    loads_basic[:, :, :12] = rigid_motion_loads(blocks, l0)
    for name, grid, comp, value in preloads:
        loads_basic[bulk.grid_index(int(grid), f"--preload {name}"), comp - 1, 12 + names.index(name)] += value
    # basic -> CD frames (g-set) -> f-set
    g = np.empty_like(loads_basic)
    g[:, :3] = np.einsum("nba,nbc->nac", Rcd, loads_basic[:, :3])
    g[:, 3:] = np.einsum("nba,nbc->nac", Rcd, loads_basic[:, 3:])
    loads_f = np.asarray(sm.T_gf.T @ g.reshape(6 * N, -1))
    u_f = static_displacements(sm, K, M, loads_f, held, rigid_vectors)
    ug = np.asarray(sm.T_gf @ u_f).reshape(N, 6, -1)
    ub = np.empty_like(ug)
    ub[:, :3] = np.einsum("nab,nbc->nac", Rcd, ug[:, :3])
    ub[:, 3:] = np.einsum("nab,nbc->nac", Rcd, ug[:, 3:])
    axial = None
    if len(ia):
        ue = np.concatenate([ub[ia], ub[ib]], axis=1)  # (ne, 12, cases)
        local = np.einsum("eij,ejc->eic", T, ue)
        axial = ea_l[:, None] * (local[:, 6] - local[:, 0])  # (ne, cases), tension positive
    shell_H = [(rows, *gsc.shell_stress_batch(bulk.positions[rows], props,
                                              np.ascontiguousarray(ub[rows].reshape(len(rows), -1, ub.shape[2]))))
               for rows, props in shell_groups]
    solid_H = [(rows, gsc.solid_stress_batch(kind, bulk.positions[rows], props, *solids.RULES[kind],
                                             np.ascontiguousarray(ub[rows][:, :, :3].reshape(len(rows), -1,
                                                                                             ub.shape[2]))))
               for kind, rows, props in solid_groups]

    def project(trans_, rot_, cases_):
        """sum over the elements of Phi' K_G,e Phi for the load cases ``cases_`` (slice)."""
        n = trans_.shape[2]
        out = np.zeros((len(range(*cases_.indices(loads_basic.shape[2]))), n, n))
        if axial is not None:
            phi = np.concatenate([trans_[ia], rot_[ia], trans_[ib], rot_[ib]], axis=1)  # (ne, 12, n)
            local_phi = np.einsum("eij,ejk->eik", T, phi)
            Y = np.einsum("eij,ejk->eik", KG1, local_phi)
            out += np.einsum("ec,eik,eil->ckl", axial[:, cases_], local_phi, Y)
        for rows, H, Ts in shell_H:
            nn = rows.shape[1]
            phi = np.concatenate([trans_[rows], rot_[rows]], axis=2).reshape(len(rows), 6 * nn, n)
            local_phi = np.matmul(Ts, phi).reshape(len(rows), nn, 6, n)[:, :, :3]
            out += _contract(H[:, cases_], local_phi)
        for rows, H in solid_H:
            out += _contract(H[:, cases_], trans_[rows])
        return out

    cases = project(trans, rot, slice(None))
    if names and interface_row is not None:
        r = int(interface_row)
        arm = l0 - l0[r]
        rel_rot = rot - rot[r][None]
        rel_trans = trans - trans[r][None] - np.cross(rot[r][None].transpose(0, 2, 1),
                                                      arm[:, None, :]).transpose(0, 2, 1)
        cases[12:] = project(rel_trans, rel_rot, slice(12, None))
    cases = 0.5 * (cases + cases.transpose(0, 2, 1))
    return GeometricStiffness(
        reaction="aset" if held is not None and len(held) else "inertia_relief" if rigid_vectors is not None
        and np.asarray(rigid_vectors).size else "spc",
        translation=cases[:3].copy(), rotation=cases[3:6].copy(), angular_velocity=cases[6:12].copy(),
        preload_names=names, preload=cases[12:].copy() if names else None,
        elements=", ".join(f"{k} {v}" for k, v in sorted(counts.items())))
