"""Loads recovery: element forces and stresses at named elements and interface forces at named grids of a
flexible body, from its modal coordinates, by mode displacement and by mode acceleration.

Output operator. Every recovered quantity is linear in the body's displacement u (g-set, CD frames):
y = L u. CBAR/CBEAM: the element's end forces f = K_local T u_e (local axes, offsets through the rigid links
of :func:`dynamics.flex.elements.local_to_grids`) give NASTRAN's element forces (QRG CBAR: bending moments in
planes 1 and 2 at ends A and B, shears in planes 1 and 2, axial force, torque):
BM1A = -f[5], BM2A = f[4], BM1B = f[11], BM2B = -f[10], TS1 = f[7], TS2 = f[8], AF = f[6], TRQ = f[9]
(the internal forces of the section at each end: the force on the element at B, minus the one at A), and the
bending stresses at the stress recovery points (y, z) = C, D, E, F of the section (PBAR C1-F2, or the
PBARL/PBEAML shape's points, :mod:`dynamics.flex.sections`): S = -M1 y / I1 - M2 z / I2 (NASTRAN's SA1-SA4,
SB1-SB4), and the axial stress AF / A. These signs are those of MSC Nastran's own output: the element forces
and stresses MSC wrote for the modes of pyNastran's beam_modes model are reproduced from its eigenvectors
(tests/flex/test_loads_recovery.py). CROD: axial force and torque. Interface forces at a grid: the force and
moment the structure needs there to hold its displacement, (K u) of the grid's six DOFs, in the body axes.

Methods (Craig and Kurdila, Fundamentals of Structural Dynamics, 2006, sec. 14.6; the mode-acceleration
method of Williams 1945):

* mode displacement: u = Phi eta, y_MD = L Phi eta;
* mode acceleration: u = K^-1 (F - M u_ddot - C u_dot) with the reduced model's accelerations. For eigenvector
  bases the modal equations turn this into u = Phi eta + G_r F, G_r = K^-1 - Phi K_m^-1 Phi' (the residual
  flexibility of the modes kept, K_m = Phi' K Phi), which is how it is computed here: y_MA = y_MD + R F with
  R = L G_r on the loads F. In that form it holds for any basis (normalized component modes and residual
  vectors are not eigenvectors of the held structure: K^-1 M Phi_k is not Phi_k / omega_k^2 for them) and any
  damping the reduced model carries (modal damping of component modes is not a damping of the held
  structure's modes, so the acceleration form's damping term would need the physical damping matrix, which
  the body does not have). The loads are the inertia load of the reference grid's angular and linear
  acceleration a, F = -M D a (D its rigid motions), and unit loads at chosen DOFs (the residual-vector DOFs):
  y_MA = y_MD + S a + F_l f. K^-1 is the static solution of the body as it is held: at its interface grid
  (the a-set, one grid with all six components: the modes are taken relative to that grid's rigid motion,
  which the hinge holding the grid carries), by the deck's SPCs, or, for a free body, by inertia relief (the
  rigid acceleration's load is then balanced by the rigid-body inertia: S = 0). The correction is the
  quasi-static response of the truncated modes: mode acceleration converges much faster in the number of
  modes than mode displacement; loads at residual-vector DOFs need none (their static response is in the
  basis).

Gravity is an acceleration -g of the reference (give the specific force as the linear acceleration); the
centrifugal load of the reference's angular velocity is not included (a first-order method).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp

from dynamics.flex import elements as el
from dynamics.flex.bulk_data import BulkDataError

BEAM_FORCES = ("BM1A", "BM2A", "BM1B", "BM2B", "TS1", "TS2", "AF", "TRQ")
BEAM_STRESSES = ("SA1", "SA2", "SA3", "SA4", "SB1", "SB2", "SB3", "SB4", "AXIAL")
# row of NASTRAN's force in the local end forces f (12: [Fx Fy Fz Mx My Mz] at A, then at B) and its sign
_BEAM_FORCE_ROWS = ((5, -1.0), (4, 1.0), (11, 1.0), (10, -1.0), (7, 1.0), (8, 1.0), (6, 1.0), (9, 1.0))
INTERFACE = ("FX", "FY", "FZ", "MX", "MY", "MZ")
# dimension of each output (length, mass, time exponents), for the unit conversion of the body file
DIMENSIONS = {"force": (1, 1, -2), "moment": (2, 1, -2), "stress": (-1, 1, -2)}


@dataclass
class LoadsRecovery:
    """Recovery matrices of a body (module docstring); n outputs, m modes.

    names (n,) e.g. "CBAR 1 BM1A", "GRID 1 FX"; kinds (n,) "force" | "moment" | "stress" (SI units N, N m,
    Pa); mode_displacement (n, m) L Phi; reference_acceleration (n, 6) S, the residual-flexibility response
    to the inertia load of a unit [angular (rad/s^2); linear (m/s^2)] acceleration of the reference grid,
    body axes; load_dofs (l, 2) (grid, component 1-6 in the grid's CD frame, as residual-vector DOFs) and
    loads (n, l) the residual-flexibility response per unit load; reaction "aset" | "spc" |
    "inertia_relief"; reference_grid (0: the body frame's origin)."""

    names: list
    kinds: list
    mode_displacement: np.ndarray
    reference_acceleration: np.ndarray
    reaction: str
    reference_grid: int = 0
    load_dofs: np.ndarray = field(default_factory=lambda: np.zeros((0, 2), dtype=np.int64))
    loads: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))

    @property
    def n_outputs(self) -> int:
        return len(self.names)

    def recover(self, eta, acceleration=None, loads=None):
        """(y_MD, y_MA) for one instant (a reference implementation of the LoadsRecovery model's kernel)."""
        y_md = self.mode_displacement @ eta
        y_ma = y_md.copy()
        if acceleration is not None:
            y_ma = y_ma + self.reference_acceleration @ acceleration
        if loads is not None and len(loads):
            y_ma = y_ma + self.loads @ loads
        return y_md, y_ma


def _beam_operator(sm, eid, elem, ctx):
    """(rows (k, 6N) of L for a CBAR/CBEAM, names, kinds): NASTRAN's forces, and the stresses when the
    section has stress recovery points."""
    from dynamics.flex import assembly as asm

    bulk = sm.bulk
    rows_of = {}

    def idx(gid, c):
        return bulk.grid_index(int(gid), c)

    beam = asm.beam_data(bulk, elem, ctx, bulk.wtmass, idx, rows_of)
    if beam[9] is not None:
        raise BulkDataError(f"{bulk.path}: {ctx}: loads recovery of a tapered PBEAM is not supported")
    _, props, frames, wa, wb, torsion = asm.beam_batch(bulk, [beam])
    L, E, G, A, I1, I2, J, mu, k1, k2 = props[0]
    Kl, _ = el.beam_local_matrices(L, E, G, A, I1, I2, J, mu, k1, k2, False, bool(torsion[0]))
    T = el.local_to_grids(frames[0], wa[0], wb[0])
    ia, ib = beam[1], beam[2]
    Rcd = bulk.displacement_rotation
    C = np.zeros((12, 12))                       # grid DOFs (CD) -> basic
    for k, i in enumerate((ia, ib)):
        C[6 * k:6 * k + 3, 6 * k:6 * k + 3] = Rcd[i]
        C[6 * k + 3:6 * k + 6, 6 * k + 3:6 * k + 6] = Rcd[i]
    F = Kl @ T @ C                               # local end forces per grid DOF
    rows = [sign * F[r] for r, sign in _BEAM_FORCE_ROWS]
    names = [f"{elem.type} {eid} {q}" for q in BEAM_FORCES]
    kinds = ["moment"] * 4 + ["force"] * 3 + ["moment"]
    points = _stress_points(bulk.model.properties[int(elem.pid)], ctx)
    if points is not None:
        m1a, m2a, m1b, m2b = rows[0], rows[1], rows[2], rows[3]
        for end, (m1, m2) in (("A", (m1a, m2a)), ("B", (m1b, m2b))):
            for p, (y, z) in enumerate(points):
                rows.append(-m1 * y / I1 - m2 * z / I2)
                names.append(f"{elem.type} {eid} S{end}{p + 1}")
                kinds.append("stress")
        rows.append(rows[6] / A)
        names.append(f"{elem.type} {eid} AXIAL")
        kinds.append("stress")
    dofs = np.concatenate([6 * ia + np.arange(6), 6 * ib + np.arange(6)])
    return np.array(rows), dofs, names, kinds


def _stress_points(prop, ctx):
    """(4, 2) stress recovery points C, D, E, F (y, z) of a PBAR, PBEAM (end A) or PBARL/PBEAML, or None when
    a PBAR/PBEAM gives none (all zero)."""
    from dynamics.flex.sections import section_properties

    if prop.type in ("PBARL", "PBEAML"):
        dims = np.asarray(prop.dim, dtype=float)
        return section_properties(prop.Type, dims[0] if dims.ndim > 1 else dims, ctx).stress_points
    if prop.type == "PBAR":
        pts = np.array([[prop.c1, prop.c2], [prop.d1, prop.d2], [prop.e1, prop.e2], [prop.f1, prop.f2]], float)
    else:
        pts = np.array([[np.atleast_1d(getattr(prop, name + "1"))[0], np.atleast_1d(getattr(prop, name + "2"))[0]]
                        for name in ("c", "d", "e", "f")], dtype=float)
    pts = np.nan_to_num(pts)
    return pts if np.any(pts) else None


def output_operator(sm, element_ids, grid_ids):
    """(L (n, 6N) sparse over the g-set, names, kinds) of the recovered quantities."""
    bulk = sm.bulk
    model = bulk.model
    N6 = 6 * len(bulk.grid_ids)
    blocks, names, kinds = [], [], []
    for eid in element_ids:
        elem = model.elements.get(int(eid))
        if elem is None:
            raise BulkDataError(f"{bulk.path}: loads recovery: element {eid} is not in the deck")
        ctx = f"{elem.type} {eid}"
        if elem.type in ("CBAR", "CBEAM"):
            rows, dofs, n, k = _beam_operator(sm, eid, elem, ctx)
        elif elem.type == "CROD":
            rows, dofs, n, k = _rod_operator(sm, eid, elem, ctx)
        else:
            raise BulkDataError(f"{bulk.path}: loads recovery of {ctx}: element forces are recovered for CBAR, "
                                "CBEAM and CROD; shells and solids are not supported yet")
        blocks.append((rows, dofs))
        names += n
        kinds += k
    K = sm.stiffness_g.tocsr()
    Rcd = bulk.displacement_rotation
    for gid in grid_ids:
        i = bulk.grid_index(int(gid), "loads recovery interface grid")
        R6 = np.kron(np.eye(2), Rcd[i])
        rows = R6 @ K[6 * i:6 * i + 6].toarray()
        blocks.append((rows, np.arange(N6)))
        names += [f"GRID {gid} {q}" for q in INTERFACE]
        kinds += ["force"] * 3 + ["moment"] * 3
    data, rr, cc = [], [], []
    start = 0
    for rows, dofs in blocks:
        r, c = np.nonzero(rows)
        data.append(rows[r, c])
        rr.append(start + r)
        cc.append(np.asarray(dofs)[c])
        start += rows.shape[0]
    if not data:
        raise BulkDataError(f"{bulk.path}: loads recovery: no element or grid to recover")
    L = sp.csr_matrix((np.concatenate(data), (np.concatenate(rr), np.concatenate(cc))), shape=(start, N6))
    return L, names, kinds


def _rod_operator(sm, eid, elem, ctx):
    from dynamics.flex import assembly as asm

    bulk = sm.bulk
    ia, ib = (bulk.grid_index(int(g), ctx) for g in elem.nodes)
    axis = bulk.positions[ib] - bulk.positions[ia]
    length = float(np.linalg.norm(axis))
    prop = asm.property_card(bulk.model, int(elem.pid), ("PROD",), ctx)
    E, G, _ = asm.material_card(bulk.model, int(prop.mid), f"{ctx} -> PROD {prop.pid}")
    e = axis / length
    Rcd = bulk.displacement_rotation
    rows = np.zeros((2, 12))
    ea, gj = E * float(prop.A) / length, G * float(prop.j or 0.0) / length
    rows[0, 0:3], rows[0, 6:9] = -ea * (e @ Rcd[ia]), ea * (e @ Rcd[ib])
    rows[1, 3:6], rows[1, 9:12] = -gj * (e @ Rcd[ia]), gj * (e @ Rcd[ib])
    dofs = np.concatenate([6 * ia + np.arange(6), 6 * ib + np.arange(6)])
    return rows, dofs, [f"CROD {eid} AF", f"CROD {eid} TRQ"], ["force", "moment"]


def loads_recovery(sm, K, M, modes_f: np.ndarray, element_ids, grid_ids, held=None, rigid_vectors=None,
                   reference_row=None, reference_point=None, load_dofs=()) -> LoadsRecovery:
    """:class:`LoadsRecovery` of the body whose f-set modes are ``modes_f`` (module docstring).

    ``held``: f-set indices of the a-set (one grid, all six components, at row ``reference_row``), else
    inertia relief with ``rigid_vectors``, else the SPCs hold the body (``reference_point``: the body frame's
    origin, basic); ``load_dofs``: (grid, component) f-set DOFs of the unit loads (CD frames)."""
    from dynamics.flex.geometric_stiffness import static_displacements

    bulk = sm.bulk
    L, names, kinds = output_operator(sm, element_ids, grid_ids)
    T = sm.T_gf
    LT = (L @ T).tocsr()
    Y = np.asarray(LT @ modes_f)
    N = len(bulk.grid_ids)
    Rcd = bulk.displacement_rotation
    pos = bulk.positions
    nf = K.shape[0]
    if held is not None and len(held):
        reaction = "aset"
        origin = pos[reference_row]
        # the modes relative to the interface grid's rigid motion (zero at the held DOFs)
        ref = np.asarray(T @ modes_f).reshape(N, 6, -1)[reference_row]
        ref_b = np.concatenate([Rcd[reference_row] @ ref[:3], Rcd[reference_row] @ ref[3:]])
        rigid = _rigid_motions(pos - origin, Rcd)                       # (6N, 6) [rotation; translation] cols
        basis = modes_f - _to_f(sm, rigid @ np.vstack([ref_b[3:], ref_b[:3]]))
    else:
        reaction = "inertia_relief" if rigid_vectors is not None and np.asarray(rigid_vectors).size else "spc"
        origin = np.zeros(3) if reference_point is None else np.asarray(reference_point, float)
        rigid = _rigid_motions(pos - origin, Rcd)
        basis = modes_f
    D = _to_f(sm, rigid)                                                 # f-set rigid motions
    loads = np.zeros((nf, len(load_dofs)))
    for k, (gid, comp) in enumerate(load_dofs):
        loads[sm.f_index(int(gid), int(comp), "loads recovery load DOF"), k] = 1.0
    F = np.hstack([-(M @ D), loads])
    if reaction == "aset":
        F[held] = 0.0                                                    # the holding reacts these
    u = static_displacements(sm, K, M, F, held, rigid_vectors if reaction == "inertia_relief" else np.zeros((nf, 0)))
    Km = basis.T @ (K @ basis)
    modal = basis @ np.linalg.solve(0.5 * (Km + Km.T), basis.T @ F)
    correction = np.asarray(LT @ (u - modal))
    if reaction == "inertia_relief":
        correction[:, :6] = 0.0          # the rigid inertia balances a rigid acceleration's load exactly
    return LoadsRecovery(names=names, kinds=kinds, mode_displacement=Y, reference_acceleration=correction[:, :6],
                         reaction=reaction,
                         reference_grid=int(bulk.grid_ids[reference_row]) if reaction == "aset" else 0,
                         load_dofs=np.asarray(load_dofs, dtype=np.int64).reshape(-1, 2), loads=correction[:, 6:])


def _rigid_motions(arm, Rcd):
    """(6N, 6) g-set (CD frames) displacements of unit rigid rotations (columns 0-2, about the point the arms
    ``arm`` (N, 3) are measured from) and translations (3-5)."""
    N = arm.shape[0]
    D = np.zeros((N, 6, 6))
    for k in range(3):
        e = np.eye(3)[k]
        D[:, :3, k] = np.cross(e, arm)
        D[:, 3 + k, k] = 1.0
        D[:, k, 3 + k] = 1.0
    D[:, :3] = np.einsum("nba,nbk->nak", Rcd, D[:, :3])
    D[:, 3:] = np.einsum("nba,nbk->nak", Rcd, D[:, 3:])
    return D.reshape(6 * N, 6)


def _to_f(sm, g_vectors):
    """f-set part of g-set vectors (the independent DOFs)."""
    return np.asarray(g_vectors)[sm.f_dofs]
