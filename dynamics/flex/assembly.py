"""Sparse structural matrices from bulk data: g-set assembly, RBE2 elimination, SPCs.

Set names follow NASTRAN: the g-set holds 6 DOFs per grid (``[T1 T2 T3 R1 R2 R3]`` in the
grid's displacement frame CD, grids in ascending ID order); eliminating RBE2 dependent DOFs
gives the n-set; removing single-point constraints (SPC/SPC1, GRID PS, plus AUTOSPC of DOFs that
carry neither stiffness nor mass) gives the f-set on which the eigen-problems are solved. One
sparse matrix ``T_gf`` (g x f) carries all of it: ``u_g = T_gf u_f``, ``K_ff = T_gf' K_gg T_gf``.

Massless mechanisms: a motion of the massless DOFs (zero rows of M_ff) with no strain energy,
such as the spin of a lumped-mass CBAR line about its own axis, has neither mass nor stiffness,
so K - sigma M is singular for every sigma. For a positive semi-definite K such a motion z
satisfies K_oo z = 0 on the massless set o, and then K z = 0 and M z = 0 on the whole f-set. The
null space of K_oo is found and one DOF per null vector (the largest entries, by a pivoted QR)
is held, as NASTRAN's AUTOSPC does for grid-point singularities; any complement of the null
space gives the same strain and kinetic energy, so no frequency or mass property changes. The
held DOFs are reported in :attr:`StructuralModel.mechanisms`.

Rigid-body vectors of the geometry (:meth:`StructuralModel.rigid_body_vectors`): for every
connected part, the six motions ``u = t + theta x (x - x_c)``, ``rotation = theta`` of its
grids, rotated to the CD frames, restricted to the combinations that carry no strain energy
(round-off relative to the absolute-value energy |D|' |K| |D|) and have mass.

Elements are assembled in the basic frame and rotated to the CD frames afterwards
(``K_gg = R' K_basic R`` with R block-diagonal per grid); CELAS springs act on CD components
and are added after that rotation. Every matrix stays scipy.sparse (CSR) here.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp
from numba import njit

from dynamics.flex import elements as el
from dynamics.flex import solids
from dynamics.flex.laminates import mat8_moduli, pcomp_section
from dynamics.flex.sections import section_properties
from dynamics.flex.shells import property_row as shell_props
from dynamics.flex.quadratic_shells import cquad8_batch, tria6_parts
from dynamics.flex.shells import shell_batch
from dynamics.flex.bulk_data import (BulkData, BulkDataError, displacement_frame_rotation,
                                      vector_to_basic)


@dataclass
class LumpedMass:
    """A CONM2 as a rigid body: grid, mass [kg], CG in basic [m], inertia about CG (basic)."""

    element_id: int
    grid_id: int
    mass: float
    cg_basic: np.ndarray
    inertia_cg: np.ndarray


@dataclass
class StructuralModel:
    """Assembled g-set matrices and the constraint transformation to the f-set.

    stiffness_g, mass_g : (6n, 6n) CSR in CD frames [N/m, N, N m/rad; kg, kg m, kg m^2].
    mass_lumped_basic : (6n, 6n) CSR, lumped (block-diagonal per grid) in the basic frame;
        the node masses of the modal integrals come from its 6 x 6 blocks.
    T_gf : (6n, n_f) CSR, u_g = T_gf @ u_f.
    f_dofs : (n_f,) g-set index of each f-set DOF (RBE2 independent, unconstrained).
    """

    bulk: BulkData
    stiffness_g: sp.csr_matrix
    mass_g: sp.csr_matrix
    mass_lumped_basic: sp.csr_matrix
    T_gf: sp.csr_matrix
    f_dofs: np.ndarray
    deck_aset: list = field(default_factory=list)
    lumped_masses: list = field(default_factory=list)
    autospc_count: int = 0
    spc_count: int = 0
    rbe2_dependent_count: int = 0
    spc_dofs: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    mechanisms: list = field(default_factory=list)

    @property
    def grid_ids(self) -> np.ndarray:
        return self.bulk.grid_ids

    @property
    def n_grids(self) -> int:
        return len(self.bulk.grid_ids)

    def stiffness_f(self) -> sp.csr_matrix:
        T = self.T_gf
        return (T.T @ self.stiffness_g @ T).tocsr()

    def mass_f(self) -> sp.csr_matrix:
        T = self.T_gf
        return (T.T @ self.mass_g @ T).tocsr()

    def describe_g(self, g: int) -> str:
        return f"grid {self.grid_ids[g // 6]} component {g % 6 + 1}"

    def rigid_body_vectors(self, stiffness_f=None, mass_f=None,
                           energy_tol: float = 1e-10) -> np.ndarray:
        """(n_f, r) f-set rigid-body motions that the constraints allow and K does not resist.

        Per connected part of the structure (grids joined by K_f or M_f), the six motions
        ``u = t + theta x (x - x_c)``, ``rotation = theta`` (rotations scaled by the part's size
        so the columns are comparable) restricted to the free DOFs; combinations that vanish
        there (all their DOFs held) are dropped, and a combination is rigid when its strain
        energy is below ``energy_tol`` times its absolute-value energy |D|' |K| |D| (round-off
        of K D is ~1e-16 of the latter; an element to a held DOF or a grounded CELAS spring
        gives an O(1) fraction). Parts without mass (mechanisms) give no vector.
        """
        from scipy.sparse.csgraph import connected_components
        K = self.stiffness_f() if stiffness_f is None else sp.csr_matrix(stiffness_f)
        M = self.mass_f() if mass_f is None else sp.csr_matrix(mass_f)
        nf = len(self.f_dofs)
        grid_of = self.f_dofs // 6
        C = (abs(K) + abs(M)).tocoo()
        ng = self.n_grids
        G = sp.csr_matrix((np.ones(C.nnz), (grid_of[C.row], grid_of[C.col])), shape=(ng, ng))
        _, part = connected_components(G, directed=False)
        pos = self.bulk.positions
        Rcd = self.bulk.displacement_rotation
        out = []
        for label in np.unique(part[grid_of]):
            rows = np.nonzero(part[grid_of] == label)[0]
            grids = np.unique(grid_of[rows])
            center = pos[grids].mean(axis=0)
            size = max(float(np.max(np.abs(pos[grids] - center))), 1e-12)
            r = (pos - center) / size
            D = np.zeros((ng, 6, 6))
            D[:, :3, :3] = np.eye(3)
            D[:, 0, 4], D[:, 0, 5] = r[:, 2], -r[:, 1]      # theta x r
            D[:, 1, 3], D[:, 1, 5] = -r[:, 2], r[:, 0]
            D[:, 2, 3], D[:, 2, 4] = r[:, 1], -r[:, 0]
            D[:, 3:, 3:] = np.eye(3) / size
            D[:, :3] = np.einsum("nba,nbk->nak", Rcd, D[:, :3])
            D[:, 3:] = np.einsum("nba,nbk->nak", Rcd, D[:, 3:])
            Dc = np.zeros((nf, 6))
            Dc[rows] = D.reshape(6 * ng, 6)[self.f_dofs[rows]]
            U, sv, _ = np.linalg.svd(Dc[rows], full_matrices=False)
            Dc = np.zeros((nf, int(np.sum(sv > 1e-8 * sv.max(initial=0.0)))))
            if Dc.shape[1] == 0:
                continue
            Dc[rows] = U[:, :Dc.shape[1]]
            absolute = np.abs(Dc).T @ (abs(K) @ np.abs(Dc))
            scale = np.sqrt(np.maximum(np.diag(absolute), 1e-300))
            E = (Dc.T @ (K @ Dc)) / np.outer(scale, scale)
            w, V = np.linalg.eigh(0.5 * (E + E.T))
            Dr = Dc @ V[:, np.abs(w) <= energy_tol]
            if Dr.shape[1] == 0:
                continue
            Mr = Dr.T @ (M @ Dr)
            w, V = np.linalg.eigh(0.5 * (Mr + Mr.T))
            out.append(Dr @ V[:, w > 1e-12 * max(w.max(initial=0.0), 1e-300)])
        return np.hstack(out) if out else np.zeros((nf, 0))

    def dof_index(self, grid_id: int, component: int, context: str) -> int:
        """g-set index of (grid, component 1..6)."""
        if component < 1 or component > 6:
            raise BulkDataError(f"{context}: component {component} of grid {grid_id} "
                                "is not in 1..6")
        return 6 * self.bulk.grid_index(grid_id, context) + component - 1

    def f_index(self, grid_id: int, component: int, context: str) -> int:
        """f-set index of (grid, component); error if the DOF is constrained or dependent."""
        g = self.dof_index(grid_id, component, context)
        pos = np.searchsorted(self.f_dofs, g)
        if pos >= len(self.f_dofs) or self.f_dofs[pos] != g:
            raise BulkDataError(f"{context}: DOF {component} of grid {grid_id} is constrained "
                                "(SPC/AUTOSPC) or an RBE2 dependent DOF, so it is not free")
        return int(pos)


def block_rotation(R: np.ndarray) -> sp.csr_matrix:
    """Block-diagonal (6n x 6n) rotation, u_basic = B @ u_g, from per-grid R (n, 3, 3)."""
    n = R.shape[0]
    blocks = np.zeros((n, 2, 3, 3))
    blocks[:, 0] = R
    blocks[:, 1] = R
    rows = (np.arange(n)[:, None, None, None] * 6 + np.arange(2)[None, :, None, None] * 3
            + np.arange(3)[None, None, :, None]) + np.zeros((1, 1, 1, 3), dtype=int)
    cols = (np.arange(n)[:, None, None, None] * 6 + np.arange(2)[None, :, None, None] * 3
            + np.arange(3)[None, None, None, :]) + np.zeros((1, 1, 3, 1), dtype=int)
    return sp.csr_matrix((blocks.ravel(), (rows.ravel(), cols.ravel())), shape=(6 * n, 6 * n))


def _components(value) -> list[int]:
    s = str(value).strip()
    if s in ("", "0", "None"):
        return []
    return sorted({int(c) for c in s})


class _Triplets:
    """Element blocks of one sparse matrix: each ``add`` / ``add_batch`` stores the DOFs and the
    dense blocks as given; :meth:`matrix` sums them into CSR in one compiled pass
    (:func:`_csr_from_blocks`) without expanding them into (row, column, value) triplets."""

    def __init__(self):
        self.batches = []

    def add(self, dofs: np.ndarray, block: np.ndarray):
        self.add_batch(np.asarray(dofs)[None, :], np.asarray(block)[None])

    def add_batch(self, dofs: np.ndarray, blocks: np.ndarray):
        """dofs (ne, k), blocks (ne, k, k)."""
        self.batches.append((np.ascontiguousarray(dofs, dtype=np.int64),
                             np.ascontiguousarray(blocks, dtype=float)))

    def matrix(self, n: int) -> sp.csr_matrix:
        if not self.batches:
            return sp.csr_matrix((n, n))
        k = np.concatenate([np.full(d.shape[0], d.shape[1], dtype=np.int64)
                            for d, _ in self.batches])
        dof_ptr = np.concatenate([[0], np.cumsum(k)])
        val_ptr = np.concatenate([[0], np.cumsum(k * k)])
        if len(self.batches) == 1:
            dofs, vals = self.batches[0][0].ravel(), self.batches[0][1].ravel()
        else:
            dofs = np.concatenate([d.ravel() for d, _ in self.batches])
            vals = np.concatenate([b.ravel() for _, b in self.batches])
        indptr, indices, data = _csr_from_blocks(n, dof_ptr, dofs, val_ptr, vals)
        return sp.csr_matrix((data, indices, indptr), shape=(n, n))


@njit(cache=True)
def _csr_from_blocks(n, dof_ptr, dofs, val_ptr, vals):
    """CSR (indptr, indices, data) of the sum of element blocks: block e couples the DOFs
    dofs[dof_ptr[e]:dof_ptr[e + 1]] with the row-major values vals[val_ptr[e]:val_ptr[e + 1]].

    Row by row over the elements that hold the row, a marker per column finds the row's entry
    (duplicates summed) and columns are sorted within the row. Zero block entries (the rotary
    inertia of lumped element masses) and entries that sum to exactly zero are left out.
    """
    ne = len(dof_ptr) - 1
    held = np.zeros(n + 1, dtype=np.int64)
    for t in range(dof_ptr[ne]):
        held[dofs[t] + 1] += 1
    for r in range(n):
        held[r + 1] += held[r]
    occurrence = np.empty(held[n], dtype=np.int64)
    fill = held[:n].copy()
    for e in range(ne):
        for t in range(dof_ptr[e], dof_ptr[e + 1]):
            occurrence[fill[dofs[t]]] = t
            fill[dofs[t]] += 1
    element = np.empty(dof_ptr[ne], dtype=np.int64)
    for e in range(ne):
        element[dof_ptr[e]:dof_ptr[e + 1]] = e
    marker = np.full(n, -1, dtype=np.int64)
    indptr = np.zeros(n + 1, dtype=np.int64)
    for r in range(n):
        count = 0
        for h in range(held[r], held[r + 1]):
            e = element[occurrence[h]]
            for t in range(dof_ptr[e], dof_ptr[e + 1]):
                if marker[dofs[t]] != r:
                    marker[dofs[t]] = r
                    count += 1
        indptr[r + 1] = indptr[r] + count
    indices = np.empty(indptr[n], dtype=np.int64)
    data = np.zeros(indptr[n])
    where = np.empty(n, dtype=np.int64)
    marker[:] = -1
    nnz = 0
    for r in range(n):
        start = nnz
        first = indptr[r]
        end = first
        for h in range(held[r], held[r + 1]):
            t_row = occurrence[h]
            e = element[t_row]
            k = dof_ptr[e + 1] - dof_ptr[e]
            base = val_ptr[e] + (t_row - dof_ptr[e]) * k
            for lb in range(k):
                if vals[base + lb] == 0.0:
                    continue
                c = dofs[dof_ptr[e] + lb]
                if marker[c] != r:
                    marker[c] = r
                    where[c] = end
                    indices[end] = c
                    end += 1
                data[where[c]] += vals[base + lb]
        for i in range(first + 1, end):
            c, v = indices[i], data[i]
            j = i - 1
            while j >= first and indices[j] > c:
                indices[j + 1] = indices[j]
                data[j + 1] = data[j]
                j -= 1
            indices[j + 1] = c
            data[j + 1] = v
        for i in range(first, end):
            if data[i] != 0.0:
                indices[nnz] = indices[i]
                data[nnz] = data[i]
                nnz += 1
        indptr[r] = start
    indptr[n] = nnz
    return indptr, indices[:nnz].copy(), data[:nnz].copy()


def material_card(model, mid: int, context: str):
    mat = model.materials.get(mid)
    if mat is None:
        raise BulkDataError(f"{context}: material {mid} is not defined")
    if mat.type != "MAT1":
        raise BulkDataError(f"{context}: material {mid} is a {mat.type}; only MAT1 is supported")
    E = float(mat.e or 0.0)
    G = float(mat.g or 0.0)
    rho = float(mat.rho or 0.0)
    return E, G, rho


def property_card(model, pid: int, kinds: tuple, context: str):
    prop = model.properties.get(pid)
    if prop is None:
        raise BulkDataError(f"{context}: property {pid} is not defined")
    if prop.type not in kinds:
        raise BulkDataError(f"{context}: property {pid} is a {prop.type}, expected "
                            + " or ".join(kinds))
    return prop


def _shape_section(prop, context: str):
    """:class:`~dynamics.flex.sections.Section` of a PBARL, or of a prismatic PBEAML (every station the same)."""
    dims = np.asarray(prop.dim, dtype=float)
    if dims.ndim > 1:                     # PBEAML: one row per station
        if np.ptp(dims, axis=0).max() > 1e-12 * np.abs(dims).max():
            raise BulkDataError(f"{context}: tapered PBEAML is not supported")
        dims = dims[0]
    return section_properties(prop.Type, dims, context)


def _beam_section(prop, context: str):
    if prop.type in ("PBARL", "PBEAML"):
        sec = _shape_section(prop, context)
        nsm = float(np.atleast_1d(np.asarray(prop.nsm, dtype=float))[0] or 0.0)
        return sec.A, sec.I1, sec.I2, sec.J, nsm, sec.k1, sec.k2, None
    if prop.type == "PBAR":
        A, I1, I2, I12, J, nsm = (float(prop.A), float(prop.i1), float(prop.i2),
                                  float(prop.i12), float(prop.j), float(prop.nsm))
        k1, k2 = float(prop.k1 if prop.k1 is not None else 1e8), float(
            prop.k2 if prop.k2 is not None else 1e8)
    else:
        arrays = [np.atleast_1d(np.asarray(getattr(prop, n), dtype=float))
                  for n in ("A", "i1", "i2", "i12", "j", "nsm")]
        k1 = float(prop.k1 if prop.k1 is not None else 1.0)
        k2 = float(prop.k2 if prop.k2 is not None else 1.0)
        if any(np.ptp(a) > 1e-12 * max(np.max(np.abs(a)), 1e-300) for a in arrays):
            return _tapered_section(prop, arrays, k1, k2, context)
        A, I1, I2, I12, J, nsm = (float(a[0]) for a in arrays)
    if I12 != 0.0:
        raise BulkDataError(f"{context}: {prop.type} {prop.pid} has I12 = {I12}; unsymmetric "
                            "sections are not supported")
    if A <= 0.0:
        raise BulkDataError(f"{context}: {prop.type} {prop.pid} has area A = {A} (must be > 0)")
    return A, I1, I2, J, nsm, k1, k2, None


def _tapered_section(prop, arrays, k1, k2, context: str):
    """A PBEAM whose stations differ: values at end A for the prismatic placeholder, and the
    stations (x/XB, (ns, 5) A, I1, I2, J, NSM) for
    :func:`~dynamics.flex.elements.tapered_beam_local_matrices`."""
    A, I1, I2, I12, J, nsm = arrays
    xxb = np.atleast_1d(np.asarray(prop.xxb, dtype=float))
    if len(xxb) != len(A) or abs(xxb[0]) > 1e-12 or abs(xxb[-1] - 1.0) > 1e-12 \
            or np.any(np.diff(xxb) < 0.0):
        raise BulkDataError(f"{context}: PBEAM {prop.pid} stations X/XB {list(xxb)} must rise "
                            "from 0 to 1, one per section")
    if np.any(I12 != 0.0):
        raise BulkDataError(f"{context}: PBEAM {prop.pid} has I12 = {list(I12)}; unsymmetric "
                            "sections are not supported")
    for name, v in (("A", A), ("I1", I1), ("I2", I2)):
        if np.any(v <= 0.0):
            raise BulkDataError(f"{context}: PBEAM {prop.pid} has {name} = {list(v)} at its "
                                "stations (must be > 0 at every station)")
    sections = np.column_stack([A, I1, I2, J, nsm])
    return (float(A[0]), float(I1[0]), float(I2[0]), float(J[0]), float(nsm[0]), k1, k2,
            (xxb, sections))


def assemble(bulk: BulkData, separate_lumped: bool = False, progress=None,
             interface: list = ()) -> StructuralModel:
    """Assemble g-set K and M (and the lumped M in basic), build T_gf.

    ``separate_lumped`` leaves CONM2 masses out of M (FModal's separateLumpedRigidBodies) and
    returns them as :class:`LumpedMass` records. ``interface``: (grid, [components]) that
    should stay free when a massless mechanism needs a DOF held (the a-set).
    """
    model = bulk.model
    n = len(bulk.grid_ids)
    ng = 6 * n
    K_b, M_b, ML_b = _Triplets(), _Triplets(), _Triplets()
    k_cd = _Triplets()
    wt = bulk.wtmass
    pos = bulk.positions
    Rcd = bulk.displacement_rotation

    row_of = {int(g): i for i, g in enumerate(bulk.grid_ids)}

    def idx(gid, ctx):
        i = row_of.get(gid)
        return bulk.grid_index(int(gid), ctx) if i is None else i

    elems = model.elements
    n_elem = len(elems)
    beams: list = []
    shells: list = []
    solid_elems: list = []
    sections: dict = {}
    for count, (eid, elem) in enumerate(sorted(elems.items())):
        if progress is not None and count % 5000 == 0:
            progress(f"assembling elements {count}/{n_elem}")
        ctx = f"{elem.type} {eid}"
        if elem.type in bulk.report.unsupported:
            continue    # reported by read_bulk_data and accepted with allow_unsupported
        if elem.type in ("CBAR", "CBEAM"):
            beams.append(beam_data(bulk, elem, ctx, wt, idx, sections))
        elif elem.type in ("CQUAD4", "CTRIA3", "CQUAD8", "CTRIA6"):
            shells.append(shell_data(bulk, elem, ctx, wt, idx, sections))
        elif elem.type in ("CHEXA", "CTETRA", "CPENTA"):
            solid_elems.append(solid_data(bulk, elem, ctx, wt, idx, sections))
        elif elem.type == "CBUSH":
            _add_bush(bulk, elem, ctx, K_b, M_b, ML_b, idx)
        elif elem.type == "CROD":
            _add_rod(bulk, elem, ctx, K_b, M_b, ML_b, wt, idx)
        elif elem.type in ("CELAS1", "CELAS2"):
            if elem.type == "CELAS1":
                prop = property_card(model, int(elem.pid), ("PELAS",), ctx)
                k = float(prop.k)
            else:
                k = float(elem.k)
            _add_scalar(k_cd, k, elem, ctx, idx)
        else:
            raise BulkDataError(f"{ctx}: element type not supported")

    if beams:
        if progress is not None:
            progress(f"element matrices for {len(beams)} beams")
        dofs, props, frames, wa, wb, torsion = beam_batch(bulk, beams)
        Kg, Mg, MLg = el.beam_element_batch(props, frames, wa, wb, bulk.coupled_mass, torsion)
        for e, beam in enumerate(beams):
            if beam[9] is None:
                continue
            stations, secs, rho = beam[9]
            L, E, G = props[e, 0], props[e, 1], props[e, 2]
            k1, k2 = props[e, 8], props[e, 9]
            T = el.local_to_grids(frames[e], wa[e], wb[e])
            Kl, Ml = el.tapered_beam_local_matrices(L, E, G, stations, secs, rho, k1, k2,
                                                    bulk.coupled_mass, bool(torsion[e]))
            Kg[e], Mg[e] = T.T @ Kl @ T, T.T @ Ml @ T
            if bulk.coupled_mass:
                _, Mlump = el.tapered_beam_local_matrices(L, E, G, stations, secs, rho, k1, k2,
                                                          False, bool(torsion[e]))
                MLg[e] = T.T @ Mlump @ T
            else:
                MLg[e] = Mg[e]
        K_b.add_batch(dofs, Kg)
        M_b.add_batch(dofs, Mg)
        ML_b.add_batch(dofs, MLg)

    for nn in (3, 4, 6, 8):
        group = [sh for sh in shells if len(sh[0]) == nn]
        if not group:
            continue
        if progress is not None:
            progress(f"element matrices for {len(group)} {SHELL_NAMES[nn]}")
        rows = np.array([sh[0] for sh in group], dtype=np.int64)
        xyz = pos[rows]
        props = np.array([sh[1] for sh in group], dtype=float)
        if nn == 8:
            Kg, Mg, MLg = cquad8_batch(xyz, props, bulk.coupled_mass)
        elif nn == 6:
            xyz, props, local = tria6_parts(xyz, props)
            rows = np.take_along_axis(np.repeat(rows, 4, axis=0), local, axis=1)
            Kg, Mg, MLg = shell_batch(xyz, props, bulk.coupled_mass)
        else:
            Kg, Mg, MLg = shell_batch(xyz, props, bulk.coupled_mass)
        dofs = (6 * rows[:, :, None] + np.arange(6)).reshape(len(rows), 6 * rows.shape[1])
        K_b.add_batch(dofs, Kg)
        M_b.add_batch(dofs, Mg)
        ML_b.add_batch(dofs, MLg)

    for kind in sorted({se[0] for se in solid_elems}):
        group = [se for se in solid_elems if se[0] == kind]
        if progress is not None:
            progress(f"element matrices for {len(group)} {solids.NAMES[kind]}")
        rows = np.array([se[1] for se in group], dtype=np.int64)
        props = np.array([se[2] for se in group], dtype=float)
        pts, wts = solids.RULES[kind]
        Kg, Mg, MLg = solids.solid_batch(kind, pos[rows], props, pts, wts, bulk.coupled_mass)
        dofs = (6 * rows[:, :, None] + np.arange(3)).reshape(len(group), 3 * rows.shape[1])
        K_b.add_batch(dofs, Kg)
        M_b.add_batch(dofs, Mg)
        ML_b.add_batch(dofs, MLg)

    lumped: list[LumpedMass] = []
    m_cd = _Triplets()
    for eid, mass in sorted(model.masses.items()):
        ctx = f"{mass.type} {eid}"
        if mass.type in bulk.report.unsupported:
            continue
        if mass.type in ("CMASS1", "CMASS2"):
            if mass.type == "CMASS1":
                prop = model.properties_mass.get(int(mass.pid))
                if prop is None or prop.type != "PMASS":
                    raise BulkDataError(f"{ctx}: PMASS {mass.pid} is not defined")
                m = float(prop.mass)
            else:
                m = float(mass.mass)
            _add_scalar(m_cd, m * wt, mass, ctx, idx)
            continue
        gid = int(mass.nid)
        i = idx(gid, ctx)
        dofs = 6 * i + np.arange(6)
        if mass.type == "CONM2":
            cid = int(mass.cid)
            m = float(mass.mass) * wt
            if cid == -1:
                cg = np.asarray(mass.X, float)
                rot = np.eye(3)
            else:
                cg = pos[i] + vector_to_basic(model, cid, mass.X, pos[i], ctx)
                rot = displacement_frame_rotation(model, cid, pos[i], ctx)
            inertia = rot @ el.conm2_inertia(mass.I) @ rot.T * wt
            if separate_lumped:
                lumped.append(LumpedMass(int(eid), gid, m, cg, inertia))
                continue
            block = el.point_mass_block(m, cg - pos[i], inertia)
        elif mass.type == "CONM1":
            L = np.asarray(mass.mass_matrix, float)
            B = L + L.T - np.diag(np.diag(L))
            rot = displacement_frame_rotation(model, int(mass.cid), pos[i], ctx)
            R6 = np.kron(np.eye(2), rot)
            block = R6 @ B @ R6.T * wt
        else:
            raise BulkDataError(f"{ctx}: mass element type not supported")
        M_b.add(dofs, block)
        ML_b.add(dofs, block)

    K_g = K_b.matrix(ng)
    M_g = M_b.matrix(ng)
    K_dmig, M_dmig = direct_input_matrices(bulk, "K2GG"), direct_input_matrices(bulk, "M2GG")
    if not np.array_equal(Rcd, np.broadcast_to(np.eye(3), Rcd.shape)):
        R = block_rotation(Rcd)
        K_g = (R.T @ K_g @ R).tocsr()
        M_g = (R.T @ M_g @ R).tocsr()
    if k_cd.batches:
        K_g = (K_g + k_cd.matrix(ng)).tocsr()
    ML_basic = ML_b.matrix(ng)
    if K_dmig is not None:
        K_g = (K_g + K_dmig).tocsr()
    if M_dmig is not None:
        M_g = (M_g + M_dmig).tocsr()
        R = block_rotation(Rcd)
        ML_basic = ML_basic + R @ M_dmig @ R.T
    if m_cd.batches:
        M_scalar = m_cd.matrix(ng)
        M_g = (M_g + M_scalar).tocsr()
        R = block_rotation(Rcd)
        ML_basic = ML_basic + R @ M_scalar @ R.T
    if M_g.nnz == 0 or not np.any(M_g.diagonal() > 0.0):
        raise BulkDataError(f"{bulk.path}: zero-mass model (no element density, CONM1/CONM2 "
                            "or non-structural mass); modes and mass properties need mass")

    structural = StructuralModel(bulk=bulk, stiffness_g=K_g, mass_g=M_g,
                                 mass_lumped_basic=ML_basic.tocsr(), T_gf=sp.identity(ng, format="csr"),
                                 f_dofs=np.arange(ng), lumped_masses=lumped)
    apply_constraints(structural, interface)
    structural.deck_aset = deck_aset(bulk)
    return structural


def _dmig_selection(bulk: BulkData, kind: str):
    """[(scale, DMIG name)] that case control's ``kind`` (K2GG, M2GG) selects: ``K2GG = KX``,
    ``K2GG = 1.5*KX``, ``K2GG = KX, KY`` (the first subcase that has it, or the global case control)."""
    cc = getattr(bulk.model, "case_control_deck", None)
    if cc is None:
        return []
    for isub in sorted(cc.subcases):
        try:
            value = cc.subcases[isub].get_parameter(kind)[0]
        except KeyError:
            continue
        out = []
        for term in str(value).replace(" ", "").split(","):
            scale, _, name = term.rpartition("*")
            try:
                out.append((float(scale) if scale else 1.0, name.upper()))
            except ValueError:
                raise BulkDataError(f"{bulk.path}: case control {kind} = {value}: expected NAME or SCALE*NAME "
                                    "terms") from None
        return out
    return []


def direct_input_matrices(bulk: BulkData, kind: str):
    """The g-set matrix (CD frames) of the DMIG entries case control selects with ``kind`` (K2GG or M2GG),
    scaled by PARAM CK2 / CM2, or None (MSC Nastran QRG K2GG, M2GG, DMIG, PARAM CM2: the terms are added to
    the structural matrices before constraints; M2GG is not scaled by WTMASS). The matrices must be real and
    symmetric (IFO = 6); a term given in both triangles is refused, as is a DMIG on a scalar point."""
    model = bulk.model
    selection = _dmig_selection(bulk, kind)
    unused = sorted(set(getattr(model, "dmig", {})) - {name for _, name in
                                                       _dmig_selection(bulk, "K2GG") + _dmig_selection(bulk, "M2GG")})
    if unused and kind == "K2GG":
        warnings.warn(f"{bulk.path}: DMIG {', '.join(unused)} not selected by case control K2GG/M2GG: not used "
                      "(NASTRAN ignores an unselected DMIG too)", stacklevel=4)
    if not selection:
        return None
    ng = 6 * len(bulk.grid_ids)
    factor = float(model.params["C" + kind[0] + "2"].values[0]) if "C" + kind[0] + "2" in model.params else 1.0
    total = sp.csr_matrix((ng, ng))
    for scale, name in selection:
        dmig = getattr(model, "dmig", {}).get(name)
        where = f"{bulk.path}: DMIG {name} ({kind})"
        if dmig is None:
            raise BulkDataError(f"{where}: case control selects it, but no DMIG of that name is in the deck")
        if int(dmig.matrix_form) != 6:
            raise BulkDataError(f"{where}: IFO = {dmig.matrix_form}; {kind} takes symmetric matrices (IFO = 6)")
        if int(dmig.tin) not in (1, 2):
            raise BulkDataError(f"{where}: TIN = {dmig.tin}: complex matrices are not supported")
        entries = {}
        for (gj, cj), (gi, ci), value in zip(dmig.GCj, dmig.GCi, dmig.Real):
            for g, c in ((gj, cj), (gi, ci)):
                if not 1 <= int(c) <= 6:
                    raise BulkDataError(f"{where}: component {c} of point {g}: grids with components 1-6 only")
            j = 6 * bulk.grid_index(int(gj), where) + int(cj) - 1
            i = 6 * bulk.grid_index(int(gi), where) + int(ci) - 1
            key = (min(i, j), max(i, j))
            if key in entries:
                raise BulkDataError(f"{where}: the term ({gi}, {ci}) x ({gj}, {cj}) is given twice (both triangles "
                                    "of a symmetric matrix, or repeated)")
            entries[key] = float(value)
        rows = np.array([k[0] for k in entries] + [k[1] for k in entries if k[0] != k[1]], dtype=np.int64)
        cols = np.array([k[1] for k in entries] + [k[0] for k in entries if k[0] != k[1]], dtype=np.int64)
        vals = np.array(list(entries.values()) + [v for k, v in entries.items() if k[0] != k[1]])
        total = total + scale * sp.csr_matrix((vals, (rows, cols)), shape=(ng, ng))
    return (factor * total).tocsr()


def _add_scalar(triplets, value, elem, ctx, idx):
    """A scalar spring or mass (CELAS1/2, CMASS1/2) of ``value`` between the CD components C1 of G1 and C2
    of G2, or from one of them to ground (QRG CELAS1, CMASS1: ``value (u1 - u2)^2 / 2``)."""
    ends = []
    for gid, comp in zip(elem.nodes, (elem.c1, elem.c2)):
        if gid is None or gid == 0:
            continue
        c = int(comp or 0)
        if c < 1 or c > 6:
            raise BulkDataError(f"{ctx}: component {comp} of grid {gid} is not in 1..6 (scalar points are not "
                                "supported)")
        ends.append(6 * idx(gid, ctx) + c - 1)
    if len(ends) == 2:
        if ends[0] == ends[1]:
            raise BulkDataError(f"{ctx}: both ends are the same DOF")
        triplets.add(np.array(ends), value * np.array([[1.0, -1.0], [-1.0, 1.0]]))
    elif len(ends) == 1:
        triplets.add(np.array(ends), np.array([[value]]))
    else:
        raise BulkDataError(f"{ctx}: no grid connected")


SHELL_NAMES = {3: "CTRIA3", 4: "CQUAD4", 6: "CTRIA6", 8: "CQUAD8"}


def shell_data(bulk, elem, ctx, wt, idx, sections):
    """(grid rows, property row of :func:`shells.shell_batch`) of one CQUAD4/CTRIA3/CQUAD8/CTRIA6 with a
    PSHELL or a PCOMP (its equivalent PSHELL, :mod:`dynamics.flex.laminates`)."""
    model = bulk.model
    if elem.type in ("CQUAD8", "CTRIA6"):
        if any(g is None or int(g) == 0 for g in elem.nodes):
            raise BulkDataError(f"{bulk.path}: {ctx}: a mid-side grid is blank; {elem.type} is modelled with all "
                                f"{len(elem.nodes)} grids (a straight edge: put its mid-side grid at the midpoint)")
        if float(elem.zoffset or 0.0) != 0.0:
            raise BulkDataError(f"{bulk.path}: {ctx}: ZOFFS = {elem.zoffset} is not supported on {elem.type}")
    rows = [idx(int(g), ctx) for g in elem.nodes]
    if len(set(rows)) != len(rows):
        raise BulkDataError(f"{ctx}: repeated grid (degenerate element)")
    key = ("SHELL", int(elem.pid))
    if key not in sections:
        prop = property_card(model, int(elem.pid), ("PSHELL", "PCOMP"), ctx)
        sections[key] = (pcomp_section(model, int(elem.pid), ctx) if prop.type == "PCOMP"
                         else _pshell_moduli(model, int(elem.pid), ctx))
    Gm, Gb, Gs, rho, t, nsm, bend, ts, rigid, Gc = sections[key]
    thick = [float(v) for v in (getattr(elem, "T1", None), getattr(elem, "T2", None),
                                getattr(elem, "T3", None), getattr(elem, "T4", None))
             if v is not None and float(v) > 0.0]
    if thick and model.properties[int(elem.pid)].type == "PCOMP":
        raise BulkDataError(f"{ctx}: corner thicknesses T1-T4 = {thick} with PCOMP "
                            f"{elem.pid}, whose plies define the thickness; leave them blank")
    if thick and getattr(elem, "tflag", 0) == 0:
        t = float(np.mean(thick))
    elif thick:
        t = t * float(np.mean(thick))
    orient = elem.theta_mcid
    theta, direction = 0.0, np.zeros(3)
    if isinstance(orient, (int, np.integer)):
        from dynamics.flex.bulk_data import coordinate_axes
        _, axes, kind = coordinate_axes(model, int(orient), f"{ctx} MCID")
        if kind != "R":
            raise BulkDataError(f"{ctx}: MCID {orient} is not a rectangular system")
        direction = axes[:, 0]
    elif orient is not None:
        theta = np.radians(float(orient))
    return rows, shell_props(Gm, Gb, Gs, rho * wt, t, nsm * wt, bend, ts, rigid, theta,
                             direction, float(elem.zoffset or 0.0), Gc)


def _plane_modulus(model, mid: int, context: str):
    """(3x3 plane-stress modulus, 2x2 transverse shear modulus, rho) of a MAT1, MAT2 or MAT8.

    The transverse shear modulus is the material's as a MID3: MAT1 G, MAT2 [[G11, G12], [G12,
    G22]] (QRG PSHELL), MAT8 diag(G1Z, G2Z) with inf for a blank (no shear flexibility)."""
    mat = model.materials.get(mid)
    if mat is None:
        raise BulkDataError(f"{context}: material {mid} is not defined")
    if mat.type == "MAT1":
        E, G, rho = material_card(model, mid, context)
        nu = _poisson(model, mid)
        c = E / (1.0 - nu * nu)
        Q = np.array([[c, nu * c, 0.0], [nu * c, c, 0.0], [0.0, 0.0, G]])
        return Q, G * np.eye(2), rho
    if mat.type == "MAT2":
        g = [float(v or 0.0) for v in (mat.G11, mat.G12, mat.G13, mat.G22, mat.G23, mat.G33)]
        Q = np.array([[g[0], g[1], g[2]], [g[1], g[3], g[4]], [g[2], g[4], g[5]]])
        return Q, np.array([[g[0], g[1]], [g[1], g[3]]]), float(mat.rho or 0.0)
    if mat.type == "MAT8":
        Q, shear, rho = mat8_moduli(mat, context)
        return Q, np.diag(shear), rho
    raise BulkDataError(f"{context}: material {mid} is a {mat.type}; shells take MAT1, MAT2 or "
                        "MAT8")


def _pshell_moduli(model, pid: int, ctx: str):
    """Membrane, bending and shear moduli, the scalars and the membrane-bending coupling modulus
    (-G4 of MID4, :mod:`dynamics.flex.laminates`) of a PSHELL (NASTRAN QRG PSHELL)."""
    prop = property_card(model, pid, ("PSHELL",), ctx)
    pctx = f"{ctx} -> PSHELL {prop.pid}"
    if not prop.mid1:
        raise BulkDataError(f"{pctx}: MID1 blank (no membrane stiffness) is not supported")
    if prop.mid2 and int(prop.mid2) == -1:
        raise BulkDataError(f"{pctx}: MID2 = -1 (plane strain) is not supported")
    Gm, _, rho = _plane_modulus(model, int(prop.mid1), pctx)
    if prop.mid2:
        Gb, Gs_b, _ = _plane_modulus(model, int(prop.mid2), pctx)
        bend = float(prop.twelveIt3 if prop.twelveIt3 is not None else 1.0)
    else:
        # no MID2: no bending and no transverse shear (QRG PSHELL), a membrane
        Gb, Gs_b, bend = Gm, np.zeros((2, 2)), 0.0
    if not np.all(np.isfinite(Gs_b)):
        # a MAT8 MID2 with blank G1Z/G2Z: the rigid-shear scale below is its in-plane shear
        Gs_b = Gb[2, 2] * np.eye(2)
    if not prop.mid2:
        Gs, rigid = Gs_b, False
    elif prop.mid3:
        _, Gs, _ = _plane_modulus(model, int(prop.mid3), pctx)
        finite = np.isfinite(np.diag(Gs))
        if not finite.any():
            Gs, rigid = Gs_b, True         # MAT8 G1Z and G2Z blank: as a blank MID3
        elif not finite.all():
            raise BulkDataError(f"{pctx}: MID3 = MAT8 {prop.mid3} with one of G1Z, G2Z blank: "
                                "shear flexibility in one direction only is not supported")
        else:
            rigid = False
    else:
        Gs, rigid = Gs_b, True
    Gc = np.zeros((3, 3))
    if getattr(prop, "mid4", None):
        if not prop.mid2:
            raise BulkDataError(f"{pctx}: MID4 = {prop.mid4} (membrane-bending coupling) needs "
                                "MID2 (bending); MID2 is blank")
        if model.materials.get(int(prop.mid4)) is not None and \
                model.materials[int(prop.mid4)].type not in ("MAT1", "MAT2"):
            raise BulkDataError(f"{pctx}: MID4 = {prop.mid4} is a "
                                f"{model.materials[int(prop.mid4)].type}; MID4 takes MAT1 or MAT2")
        G4, _, _ = _plane_modulus(model, int(prop.mid4), pctx)
        # NASTRAN's forces: N = T G1 eps + T^2 G4 (1/rho): its curvature is -kappa here, so
        # B = -T^2 G4 (the sign MSC's own PCOMP equivalents carry: laminates module)
        Gc = -G4
    ts = float(prop.tst if prop.tst is not None else 0.833333)
    return Gm, Gb, Gs, rho, float(prop.t), float(prop.nsm or 0.0), bend, ts, rigid, Gc


_SOLID_KINDS = {("CHEXA", 8): solids.HEXA8, ("CHEXA", 20): solids.HEXA20,
                ("CTETRA", 4): solids.TETRA4, ("CTETRA", 10): solids.TETRA10,
                ("CPENTA", 6): solids.PENTA6, ("CPENTA", 15): solids.PENTA15}


def solid_data(bulk, elem, ctx, wt, idx, sections):
    """(kind, grid rows, (E, nu, rho)) of one CHEXA/CTETRA/CPENTA with PSOLID and MAT1."""
    model = bulk.model
    nodes = list(elem.nodes)
    kind = _SOLID_KINDS.get((elem.type, len(nodes)))
    if kind is None or any(g is None or int(g) == 0 for g in nodes):
        given = sum(1 for g in nodes if g)
        raise BulkDataError(f"{ctx}: {elem.type} with {given} grids is not supported (CHEXA 8 "
                            "or 20, CTETRA 4 or 10, CPENTA 6 or 15, all mid-edge grids present)")
    rows = [idx(int(g), ctx) for g in nodes]
    key = ("PSOLID", int(elem.pid))
    if key not in sections:
        prop = property_card(model, int(elem.pid), ("PSOLID",), ctx)
        pctx = f"{ctx} -> PSOLID {prop.pid}"
        if str(getattr(prop, "fctn", "SMECH") or "SMECH").strip() not in ("SMECH", "PFLUID"):
            raise BulkDataError(f"{pctx}: FCTN = {prop.fctn} is not supported")
        if str(getattr(prop, "fctn", "SMECH") or "SMECH").strip() == "PFLUID":
            raise BulkDataError(f"{pctx}: FCTN = PFLUID (fluid element) is not supported")
        E, G, rho = material_card(model, int(prop.mid), pctx)
        sections[key] = (E, _poisson(model, int(prop.mid)), rho * wt)
    return kind, rows, sections[key]


def _poisson(model, mid: int) -> float:
    mat = model.materials[mid]
    E, G, nu = mat.e, mat.g, mat.nu
    if nu is not None:
        return float(nu)
    return float(E) / (2.0 * float(G)) - 1.0


def beam_data(bulk, elem, ctx, wt, idx, sections):
    """Raw fields of one CBAR/CBEAM: (eid, ia, ib, x, i_g0, wa, wb, section, is_cbeam, taper);
    taper None or (stations, (ns, 5) A I1 I2 J NSM*WTMASS, rho*WTMASS) of a tapered PBEAM."""
    model = bulk.model
    offt = getattr(elem, "offt", "GGG")
    if elem.type == "CBEAM" and getattr(elem, "bit", None) is not None:
        raise BulkDataError(f"{ctx}: BIT field (warping) is not supported")
    if offt not in (None, "GGG"):
        raise BulkDataError(f"{ctx}: OFFT = {offt}; only GGG (offsets and orientation vector "
                            "in the grids' displacement frames) is supported")
    if int(elem.pa or 0) or int(elem.pb or 0):
        raise BulkDataError(f"{ctx}: pin flags PA/PB are not supported")
    ga, gb = elem.nodes
    ia, ib = idx(ga, ctx), idx(gb, ctx)
    if elem.g0 is not None and int(elem.g0) > 0:
        i0, x = idx(int(elem.g0), ctx + " G0"), _ZERO3
    elif elem.x is None:
        raise BulkDataError(f"{ctx}: no orientation vector (X1-X3 or G0)")
    else:
        i0, x = -1, elem.x
    key = (elem.type, int(elem.pid))
    if key not in sections:
        prop = property_card(model, int(elem.pid), ("PBAR", "PBARL") if elem.type == "CBAR"
                         else ("PBEAM", "PBEAML"), ctx)
        A, I1, I2, J, nsm, k1, k2, taper = _beam_section(prop,
                                                         f"{ctx} -> {prop.type} {prop.pid}")
        if prop.type in ("PBARL", "PBEAML"):
            note = _shape_section(prop, f"{prop.type} {prop.pid}").note
            if note:
                bulk.report.notes.append(f"{prop.type} {prop.pid} {note}")
        E, G, rho = material_card(model, int(prop.mid), f"{ctx} -> {prop.type} {prop.pid}")
        if taper is not None:
            # mass per length rho A + NSM, both scaled by WTMASS
            taper = (taper[0], taper[1] * np.array([1.0, 1.0, 1.0, 1.0, wt]), rho * wt)
        sections[key] = (E, G, A, I1, I2, J, (rho * A + nsm) * wt, k1, k2)
        sections[("taper",) + key] = taper
    wa = _ZERO3 if elem.wa is None else elem.wa
    wb = _ZERO3 if elem.wb is None else elem.wb
    return (int(elem.eid), ia, ib, x, i0, wa, wb, sections[key], elem.type == "CBEAM",
            sections[("taper",) + key])


_ZERO3 = np.zeros(3)


def beam_batch(bulk, beams):
    """Vectorized geometry of all beams: dofs, props, frames, offsets (basic), CBEAM flags."""
    eids = np.array([b[0] for b in beams])
    ia = np.array([b[1] for b in beams])
    ib = np.array([b[2] for b in beams])
    x = np.array([b[3] for b in beams], dtype=float)
    i0 = np.array([b[4] for b in beams])
    R = bulk.displacement_rotation
    pos = bulk.positions
    wa = np.einsum("eab,eb->ea", R[ia], np.array([b[5] for b in beams], dtype=float))
    wb = np.einsum("eab,eb->ea", R[ib], np.array([b[6] for b in beams], dtype=float))
    v = np.where((i0 >= 0)[:, None], pos[i0] - pos[ia], np.einsum("eab,eb->ea", R[ia], x))
    axis = pos[ib] + wb - pos[ia] - wa
    L = np.linalg.norm(axis, axis=1)
    bad = np.nonzero(L <= 0.0)[0]
    if len(bad):
        raise BulkDataError(f"{'CBEAM' if beams[bad[0]][8] else 'CBAR'} {eids[bad[0]]}: "
                            "zero element length")
    ex = axis / L[:, None]
    vy = v - np.einsum("ea,ea->e", v, ex)[:, None] * ex
    ny = np.linalg.norm(vy, axis=1)
    bad = np.nonzero(ny <= 1e-9 * np.maximum(np.linalg.norm(v, axis=1), 1e-300))[0]
    if len(bad):
        raise ValueError(f"{'CBEAM' if beams[bad[0]][8] else 'CBAR'} {eids[bad[0]]}: "
                         "orientation vector is parallel to the element axis (or zero)")
    ey = vy / ny[:, None]
    frames = np.stack([ex, ey, np.cross(ex, ey)], axis=1)
    props = np.column_stack([L, np.array([b[7] for b in beams], dtype=float)])
    dofs = np.concatenate([6 * ia[:, None] + np.arange(6), 6 * ib[:, None] + np.arange(6)],
                          axis=1)
    return dofs, props, frames, wa, wb, np.array([b[8] for b in beams])


def _add_bush(bulk, elem, ctx, K_b, M_b, ML_b, idx):
    """CBUSH with PBUSH K1-K6 and M (MSC Nastran 2022.4 QRG, CBUSH and PBUSH): six springs in the
    element frame at the spring point, joined to the grids by rigid links; GB blank is a spring
    to ground.

    Element frame: CID >= 0 its axes (CID 0: basic), else x from GA to GB and y in the plane of x
    and the orientation vector (X in GA's CD frame, or G0).
    Spring point (CBUSH remark 9): OCID = -1 (blank) puts it at the fraction S of GA -> GB; OCID >= 0
    ignores S and puts it at GA + (S1, S2, S3), the offset's components along the axes of the
    rectangular system OCID. The QRG's text does not say where the offset starts (its figure
    9-21 is an image); we measure it from GA as MYSTRAN's CBUSH reader states (BD_CBUSH.f90: the
    offset "is relative to grid A") and as PBUSH remark 13's "vector from grid GA to
    (S1, S2, S3)" reads. A cylindrical or spherical OCID is refused.
    Mass (PBUSH remark 13): M lumped on the translations of the two grids, (1 - S) M on GA and S M
    on GB, no rotary inertia ("if inertia properties are desired CONM2 should be used"). For
    OCID >= 0 the QRG splits M by distances from the grids in formulas it gives only as images, and
    a grounded CBUSH has no GB share: PBUSH M is refused there. Damping (B, GE) is reported and not
    used (the body's damping is modal).
    """
    model = bulk.model
    prop = property_card(model, int(elem.pid), ("PBUSH",), ctx)
    pctx = f"{bulk.path}: {ctx} -> PBUSH {prop.pid}"
    k = np.array([float(v or 0.0) for v in (list(prop.Ki) + [0.0] * 6)[:6]])
    mass = float(getattr(prop, "mass", None) or 0.0)
    if mass < 0.0:
        raise BulkDataError(f"{pctx}: mass M = {mass} must be >= 0")
    if any(v for v in list(prop.Bi) + list(prop.GEi)):
        warnings.warn(f"{ctx} -> PBUSH {prop.pid}: damping B/GE is not used (the body's "
                      "damping is modal: --damping)", stacklevel=4)
    ga, gb = elem.nodes[0], elem.nodes[1] if len(elem.nodes) > 1 else None
    ia = idx(int(ga), ctx)
    ib = idx(int(gb), ctx) if gb else None
    xa = bulk.positions[ia]
    xb = bulk.positions[ib] if ib is not None else xa
    axis = xb - xa
    L = float(np.linalg.norm(axis))
    if elem.cid is not None and int(elem.cid) >= 0:
        from dynamics.flex.bulk_data import coordinate_axes
        _, axes, kind = coordinate_axes(model, int(elem.cid), ctx)
        if kind != "R":
            raise BulkDataError(f"{ctx}: CID {elem.cid} is not rectangular")
        Lam = axes.T
    else:
        if L <= 1e-12:
            raise BulkDataError(f"{ctx}: coincident grids need CID (the element axes)")
        if elem.g0 is not None and int(elem.g0) > 0:
            v = bulk.positions[idx(int(elem.g0), ctx)] - xa
        elif elem.x is not None and elem.x[0] is not None:
            v = bulk.displacement_rotation[ia] @ np.asarray(elem.x, float)
        else:
            raise BulkDataError(f"{ctx}: no orientation (CID, X1-X3 or G0)")
        Lam = el.beam_frame(axis, v, ctx)
    point, s_loc = _bush_point(bulk, elem, ctx, xa, axis)
    # relative motion at the spring point: local (B - A), rigid links from each grid
    ends = [(ia, -1.0)] + ([(ib, 1.0)] if ib is not None else [])
    T = np.zeros((6, 6 * len(ends)))
    for n, (i, sign) in enumerate(ends):
        link = np.eye(6)
        link[:3, 3:] = -el.skew(point - bulk.positions[i])
        T[:, 6 * n:6 * n + 6] = sign * np.kron(np.eye(2), Lam) @ link
    dofs = np.concatenate([6 * i + np.arange(6) for i, _ in ends])
    K_b.add(dofs, T.T @ np.diag(k) @ T)
    if mass == 0.0:
        return
    if ib is None:
        raise BulkDataError(f"{pctx}: mass M = {mass!r} on a CBUSH to ground (GB blank): the QRG "
                            "(PBUSH remark 13) splits M between GA and GB; give the mass as a CONM2")
    if s_loc is None:
        raise BulkDataError(f"{pctx}: mass M = {mass!r} with OCID = {elem.ocid} is not supported: "
                            "the QRG's split of M between GA and GB for an offset spring (PBUSH "
                            "remark 13) is given only as formula images; give the mass as CONM2s")
    for i, share in ((ia, 1.0 - s_loc), (ib, s_loc)):
        block = np.diag(np.r_[np.full(3, share * mass * bulk.wtmass), np.zeros(3)])
        M_b.add(6 * i + np.arange(6), block)
        ML_b.add(6 * i + np.arange(6), block)


def _bush_point(bulk, elem, ctx, xa, axis):
    """(spring point in basic, S or None) of a CBUSH: S along GA -> GB for OCID = -1 (blank), else
    GA plus the offset (S1, S2, S3) along the axes of the rectangular system OCID."""
    ocid = -1 if elem.ocid is None else int(elem.ocid)
    if ocid == -1:
        s_loc = float(elem.s if elem.s is not None else 0.5)
        return xa + s_loc * axis, s_loc
    if ocid < -1:
        raise BulkDataError(f"{bulk.path}: {ctx}: OCID = {ocid}; expected -1 (spring at S along "
                            "GA-GB) or a coordinate system id >= 0 (offset S1-S3)")
    from dynamics.flex.bulk_data import coordinate_axes
    _, axes, kind = coordinate_axes(bulk.model, ocid, f"{bulk.path}: {ctx} OCID")
    if kind != "R":
        name = "cylindrical" if kind == "C" else "spherical"
        raise BulkDataError(f"{bulk.path}: {ctx}: OCID = {ocid} is a {name} system; offsets S1-S3 "
                            "are modelled in rectangular systems (0 = basic)")
    offset = np.array([float(v or 0.0) for v in (list(elem.si) + [None] * 3)[:3]])
    return xa + axes @ offset, None


def _add_rod(bulk, elem, ctx, K_b, M_b, ML_b, wt, idx):
    model = bulk.model
    ga, gb = (int(g) for g in elem.nodes)
    ia, ib = idx(ga, ctx), idx(gb, ctx)
    axis = bulk.positions[ib] - bulk.positions[ia]
    trial = np.eye(3)[np.argmin(np.abs(axis))]
    Lam = el.beam_frame(axis, trial, ctx)
    L = float(np.linalg.norm(axis))
    prop = property_card(model, int(elem.pid), ("PROD",), ctx)
    E, G, rho = material_card(model, int(prop.mid), f"{ctx} -> PROD {prop.pid}")
    A, J, nsm = float(prop.A), float(prop.j or 0.0), float(prop.nsm or 0.0)
    mu = (rho * A + nsm) * wt
    Kl, Ml = el.rod_local_matrices(L, E, G, A, J, mu, bulk.coupled_mass)
    T = el.local_to_grids(Lam, np.zeros(3), np.zeros(3))
    dofs = np.concatenate([6 * ia + np.arange(6), 6 * ib + np.arange(6)])
    K_b.add(dofs, T.T @ Kl @ T)
    M_b.add(dofs, T.T @ Ml @ T)
    _, Mlump = el.rod_local_matrices(L, E, G, A, J, mu, False)
    ML_b.add(dofs, T.T @ Mlump @ T)


def _selected_set(model, kind: str):
    """Set id selected by the first subcase (or the global case control), else None = all."""
    cc = getattr(model, "case_control_deck", None)
    if cc is None:
        return None
    for isub in sorted(cc.subcases):
        try:
            return int(cc.subcases[isub].get_parameter(kind)[0])
        except KeyError:
            continue
    return None


def _constraint_sets(bulk, sid, kind: str = "SPC"):
    """SPC/SPC1 (``kind`` "SPC") or MPC (``kind`` "MPC") set ids that case control's SPC = sid or MPC = sid
    selects: sid itself, or the union an SPCADD / MPCADD sid names (NASTRAN: an SPCADD may not reference
    another SPCADD, nor an MPCADD another MPCADD); None = all sets. A selected id that is neither selects
    nothing, with a warning (it used to, silently: an SPCADD was never applied)."""
    if sid is None:
        return None
    model = bulk.model
    adds = getattr(model, kind.lower() + "adds", {}) or {}
    defined = model.spcs if kind == "SPC" else model.mpcs
    cards = "SPC or SPC1" if kind == "SPC" else "MPC"
    if sid in adds:
        out = set()
        for card in adds[sid]:
            for s in card.sets:
                s = int(s)
                if s in adds:
                    raise BulkDataError(f"{bulk.path}: {kind}ADD {sid} references {kind}ADD {s}; "
                                        f"NASTRAN does not allow nested {kind}ADDs")
                if s not in defined:
                    raise BulkDataError(f"{bulk.path}: {kind}ADD {sid} references {kind} set {s}, "
                                        f"which no {cards} card defines")
                out.add(s)
        return out
    if sid in defined:
        return {sid}
    listing = "SPC/SPC1" if kind == "SPC" else "MPC"
    warnings.warn(f"{bulk.path}: case control selects {kind} = {sid}, but no {cards.replace(' or ', ', ')} or "
                  f"{kind}ADD card has that set id (defined: {listing} sets {sorted(defined)}, {kind}ADD "
                  f"sets {sorted(adds)}); no {kind} set is applied"
                  + (" (GRID PS still is)" if kind == "SPC" else ""), stacklevel=4)
    return set()


def apply_constraints(sm: StructuralModel, interface: list = ()) -> None:
    bulk = sm.bulk
    model = bulk.model
    ng = 6 * sm.n_grids
    pos = bulk.positions
    Rcd = bulk.displacement_rotation

    # RBE2, RBE3, RBAR, RBE1, MPC: dependent rows of S (g x g) expressed on all g DOFs; chains resolved by S @ S.
    dependent: dict[int, str] = {}
    rows, cols, vals = [], [], []

    def depend(g, dofs, coeffs, ctx):
        if g in dependent:
            raise BulkDataError(f"{ctx}: DOF {g % 6 + 1} of grid {bulk.grid_ids[g // 6]} "
                                f"is already dependent in {dependent[g]}")
        dependent[g] = ctx
        rows.extend([g] * len(dofs))
        cols.extend(dofs)
        vals.extend(coeffs)

    for eid, rig in sorted(model.rigid_elements.items()):
        ctx = f"{rig.type} {eid}"
        if rig.type in bulk.report.unsupported:
            continue
        if rig.type == "RBE3":
            for g, dofs, coeffs in rbe3_rows(bulk, rig, ctx):
                depend(g, dofs, coeffs, ctx)
            continue
        if rig.type in ("RBAR", "RBE1"):
            for g, dofs, coeffs in rigid_link_rows(bulk, *_rigid_link_dofs(bulk, rig, ctx), ctx):
                depend(g, dofs, coeffs, ctx)
            continue
        if rig.type != "RBE2":
            raise BulkDataError(f"{ctx}: rigid element type not supported (RBE2, RBE3, RBAR, RBE1)")
        ni = bulk.grid_index(int(rig.gn), ctx)
        comps = _components(rig.cm)
        for gm in rig.Gmi:
            mi = bulk.grid_index(int(gm), ctx)
            d = pos[mi] - pos[ni]
            rigid = np.eye(6)
            rigid[:3, 3:] = -el.skew(d)
            Rm6 = np.kron(np.eye(2), Rcd[mi])
            Rn6 = np.kron(np.eye(2), Rcd[ni])
            C = Rm6.T @ rigid @ Rn6
            for c in comps:
                depend(6 * mi + c - 1, 6 * ni + np.arange(6), C[c - 1], ctx)
    n_mpc = 0
    selected_mpc = _constraint_sets(bulk, _selected_set(model, "MPC"), "MPC")
    for set_id, cards in sorted(model.mpcs.items()):
        if selected_mpc is not None and set_id not in selected_mpc:
            continue
        for card in cards:
            n_mpc += 1
            ctx = f"{card.type} set {set_id}"
            g, dofs, coeffs = mpc_row(bulk, card, ctx)
            depend(g, dofs, coeffs, ctx)
    if selected_mpc is None and len(model.mpcs) > 1:
        warnings.warn(f"{bulk.path}: no MPC selected in case control; applying all MPC sets "
                      f"{sorted(model.mpcs)}", stacklevel=3)
    dep = np.array(sorted(dependent), dtype=np.int64)
    T = sp.identity(ng, format="csr")
    if len(dep):
        keep_rows = np.setdiff1d(np.arange(ng), dep)
        S = sp.csr_matrix((np.ones(len(keep_rows)), (keep_rows, keep_rows)), shape=(ng, ng)) + \
            sp.csr_matrix((vals, (rows, cols)), shape=(ng, ng))
        for _ in range(len(model.rigid_elements) + n_mpc + 1):
            if not np.any(S[:, dep].getnnz(axis=0)):
                break
            S = (S @ S).tocsr()
        else:
            raise BulkDataError(f"{bulk.path}: rigid elements and MPCs form a closed loop of dependencies")
        T = S
    sm.rbe2_dependent_count = len(dep)

    # SPC / SPC1 (zero enforced values only)
    sid = _selected_set(model, "SPC")
    selected = _constraint_sets(bulk, sid, "SPC")
    spc_dofs = set()
    for set_id, cards in sorted(model.spcs.items()):
        if selected is not None and set_id not in selected:
            continue
        for card in cards:
            ctx = f"{card.type} set {set_id}"
            if card.type == "SPC1":
                pairs = [(int(g), card.components) for g in card.nodes]
            elif card.type == "SPC":
                if any(float(v or 0.0) != 0.0 for v in card.enforced):
                    raise BulkDataError(f"{ctx}: enforced displacements are not supported")
                pairs = list(zip(card.nodes, card.components))
            else:
                raise BulkDataError(f"{ctx}: constraint card not supported")
            for g, comps in pairs:
                for c in _components(comps):
                    gi = 6 * bulk.grid_index(int(g), ctx) + c - 1
                    if gi in dependent:
                        raise BulkDataError(f"{ctx}: DOF {c} of grid {g} is an RBE2 dependent "
                                            f"DOF ({dependent[gi]}) and cannot also be an SPC")
                    spc_dofs.add(gi)
    for gid, comps in bulk.permanent_spc:
        for c in comps:
            gi = 6 * bulk.grid_index(gid, "GRID PS") + c - 1
            if gi in dependent:
                raise BulkDataError(f"GRID {gid} PS: DOF {c} is an RBE2 dependent DOF "
                                    f"({dependent[gi]}) and cannot also be held")
            spc_dofs.add(gi)
    if sid is None and len(model.spcs) > 1:
        warnings.warn(f"{bulk.path}: no SPC selected in case control; applying all SPC sets "
                      f"{sorted(model.spcs)}", stacklevel=3)
    sm.spc_count = len(spc_dofs)

    independent = np.setdiff1d(np.arange(ng), np.concatenate([dep, np.array(sorted(spc_dofs),
                                                                             dtype=np.int64)]))
    T_gn = T[:, independent].tocsr()
    # DOFs with neither stiffness nor mass (unconnected grids, rotations of rod-only grids)
    # would make K - sigma M singular; they are removed whatever PARAM AUTOSPC says.
    Kd = np.abs((T_gn.T @ sm.stiffness_g @ T_gn).diagonal())
    Md = np.abs((T_gn.T @ sm.mass_g @ T_gn).diagonal())
    null = (Kd <= 1e-14 * max(Kd.max(initial=0.0), 1e-300)) & \
        (Md <= 1e-14 * max(Md.max(initial=0.0), 1e-300))
    sm.autospc_count = int(null.sum())
    sm.spc_dofs = np.array(sorted(spc_dofs), dtype=np.int64)
    f_dofs = independent[~null]
    T_gf = T_gn[:, ~null].tocsr()
    if len(f_dofs) == 0:
        raise BulkDataError(f"{bulk.path}: every DOF is constrained; nothing can move")
    avoid = np.zeros(len(f_dofs), dtype=bool)
    for gid, comps in list(interface) + deck_aset(bulk):
        i = row_of_grid(bulk, gid)
        if i is not None:
            avoid |= np.isin(f_dofs, 6 * i + np.asarray(comps, dtype=np.int64) - 1)
    held = massless_mechanism_dofs(T_gf.T @ sm.stiffness_g @ T_gf, T_gf.T @ sm.mass_g @ T_gf,
                                   avoid)
    if len(held):
        keep = np.setdiff1d(np.arange(len(f_dofs)), held)
        sm.mechanisms = [sm.describe_g(int(g)) for g in f_dofs[held]]
        sm.spc_dofs = np.union1d(sm.spc_dofs, f_dofs[held])
        f_dofs, T_gf = f_dofs[keep], T_gf[:, keep].tocsr()
        warnings.warn(f"{bulk.path}: {len(held)} massless mechanism(s) (motions with neither "
                      "mass nor stiffness, e.g. a lumped-mass CBAR/CROD line spinning about its "
                      "axis) removed by holding " + ", ".join(sm.mechanisms[:6])
                      + (" ..." if len(held) > 6 else "") + " (as NASTRAN AUTOSPC does); "
                      "frequencies and mass properties are unchanged", stacklevel=3)
    sm.f_dofs, sm.T_gf = f_dofs, T_gf


DENSE_NULL_LIMIT = 3000


def row_of_grid(bulk: BulkData, gid: int):
    i = int(np.searchsorted(bulk.grid_ids, gid))
    return i if i < len(bulk.grid_ids) and bulk.grid_ids[i] == gid else None


def massless_mechanism_dofs(K, M, avoid: np.ndarray | None = None) -> np.ndarray:
    """f-set DOFs to hold so that no motion has both zero mass and zero stiffness.

    The massless set o (zero rows of M) is where such motions live; their span is the null
    space of K_oo (module docstring). Dense eigen-decomposition of K_oo up to
    ``DENSE_NULL_LIMIT`` massless DOFs; above, one sparse LU decides that K_oo is regular (the
    usual case) and a shift-invert Lanczos finds the null vectors otherwise. DOFs flagged in
    ``avoid`` (interface DOFs) are held only when a mechanism lives on them alone.
    """
    import scipy.linalg as sla
    import scipy.sparse.linalg as spla
    M = sp.csr_matrix(M)
    row = np.asarray(abs(M).sum(axis=1)).ravel()
    o = np.nonzero(row <= 1e-14 * max(row.max(initial=0.0), 1e-300))[0]
    if len(o) == 0:
        return np.zeros(0, dtype=np.int64)
    Koo = sp.csr_matrix(K)[o][:, o]
    kmax = max(float(np.abs(Koo.diagonal()).max(initial=0.0)), 1e-300)
    if len(o) <= DENSE_NULL_LIMIT:
        w, V = np.linalg.eigh(Koo.toarray())
        Z = V[:, w <= 1e-10 * kmax]
    else:
        try:
            # K_oo is positive semi-definite: symmetric mode, minimum degree on A' + A, no
            # pivoting (half the time of the default COLAMD + partial pivoting on the
            # 49,413 massless rotations of the 98,826-DOF plate)
            lu = spla.splu(Koo.tocsc(), permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0,
                           options=dict(SymmetricMode=True))
            d = np.abs(lu.U.diagonal())
            if d.min() > 1e-10 * d.max():
                return np.zeros(0, dtype=np.int64)
        except RuntimeError:
            pass
        w, V = spla.eigsh(Koo.tocsc(), k=min(24, len(o) - 1), sigma=-1e-8 * kmax, which="LM")
        Z = V[:, w <= 1e-10 * kmax]
        if Z.shape[1] == V.shape[1]:
            raise BulkDataError("24 or more massless mechanisms (motions with neither mass nor "
                                "stiffness): give the rotations mass (PARAM COUPMASS 1, CBEAM, "
                                "CONM2 inertia) or constrain them")
    if avoid is not None and np.any(avoid[o]) and Z.shape[1]:
        # a mechanism that moves interface DOFs is restrained by them in the Craig-Bampton reduction (K_ee);
        # holding another DOF would add a stiffness the structure does not have (the spin of a lumped CBAR
        # line held at its tip twisting against its interface). Hold only the motions off the interface.
        Z = Z @ sla.null_space(Z[avoid[o]], rcond=1e-10)
    if Z.shape[1] == 0:
        return np.zeros(0, dtype=np.int64)
    _, _, piv = sla.qr(Z.T, pivoting=True, mode="economic")
    return np.sort(o[piv[:Z.shape[1]]])


def _dof_list(bulk, pairs, ctx):
    """[(grid row, component)] of (grid id, component string) pairs, in order."""
    out = []
    for gid, comps in pairs:
        i = bulk.grid_index(int(gid), ctx)
        out.extend((i, c) for c in _components(comps))
    return out


def _rigid_link_dofs(bulk: BulkData, rig, ctx: str):
    """(independent, dependent) [(grid row, component)] of an RBAR (CNA/CNB independent, CMA/CMB
    dependent, all the others when both are blank: QRG RBAR remarks) or an RBE1 (GNi/CNi, GMi/CMi)."""
    if rig.type == "RBAR":
        ga, gb = int(rig.ga), int(rig.gb)
        independent = _dof_list(bulk, [(ga, rig.cna), (gb, rig.cnb)], ctx)
        if not _components(rig.cma) and not _components(rig.cmb):
            rows = {bulk.grid_index(ga, ctx), bulk.grid_index(gb, ctx)}
            dependent = [(i, c) for i in sorted(rows) for c in range(1, 7) if (i, c) not in independent]
        else:
            dependent = _dof_list(bulk, [(ga, rig.cma), (gb, rig.cmb)], ctx)
    else:
        independent = _dof_list(bulk, zip(rig.Gni, rig.Cni), ctx)
        dependent = _dof_list(bulk, zip(rig.Gmi, rig.Cmi), ctx)
    both = set(independent) & set(dependent)
    if both:
        i, c = sorted(both)[0]
        raise BulkDataError(f"{bulk.path}: {ctx}: DOF {c} of grid {bulk.grid_ids[i]} is listed as independent "
                            "and dependent")
    return independent, dependent


def rigid_link_rows(bulk: BulkData, independent, dependent, ctx: str):
    """Dependent rows of a rigid element whose six independent DOFs fix its rigid-body motion (RBAR, RBE1):
    [(dependent g-set DOF, independent g-set DOFs, coefficients)].

    Every listed DOF is a component, in its grid's CD frame, of the rigid motion (t, theta) of the element
    about its first independent grid: S_i = R_i' [[I, -skew(x_i - x_1)], [0, I]] (translation rows,
    rotation rows). The six independent DOFs give S_n (t, theta) = u_n; when S_n is regular (QRG RBAR, RBE1:
    the independent DOFs "must jointly be capable of representing any general rigid body motion") the
    dependent DOFs follow as u_m = S_m S_n^-1 u_n. Checked with the rotation columns scaled by the element's
    size, so the test does not depend on units."""
    pos, Rcd = bulk.positions, bulk.displacement_rotation
    where = f"{bulk.path}: {ctx}"
    if len(independent) != 6:
        raise BulkDataError(f"{where}: {len(independent)} independent DOFs; a rigid element needs exactly six "
                            "that fix its rigid-body motion (QRG RBAR / RBE1)")
    ref = pos[independent[0][0]]

    def rows(pairs):
        S = np.zeros((len(pairs), 6))
        for k, (i, c) in enumerate(pairs):
            rigid = np.eye(6)
            rigid[:3, 3:] = -el.skew(pos[i] - ref)
            S[k] = (np.kron(np.eye(2), Rcd[i]).T @ rigid)[c - 1]
        return S

    Sn, Sm = rows(independent), rows(dependent)
    grids = {i for i, _ in independent + dependent}
    size = max(max(np.linalg.norm(pos[i] - ref) for i in grids), 1e-300)
    scale = np.r_[np.ones(3), np.full(3, 1.0 / size)]
    sv = np.linalg.svd(Sn / scale, compute_uv=False)
    if sv[-1] <= 1e-10 * sv[0]:
        names = ", ".join(f"grid {bulk.grid_ids[i]} DOF {c}" for i, c in independent)
        raise BulkDataError(f"{where}: the independent DOFs ({names}) cannot represent every rigid-body motion "
                            "of the element (e.g. translations along its axis only, or no rotation about it): "
                            "choose six that do (QRG RBAR remark 3)")
    X = Sm @ np.linalg.inv(Sn)
    ind = np.array([6 * i + c - 1 for i, c in independent], dtype=np.int64)
    return [(6 * i + c - 1, ind, X[k]) for k, (i, c) in enumerate(dependent)]


def mpc_row(bulk: BulkData, card, ctx: str):
    """(dependent g-set DOF, independent g-set DOFs, coefficients) of an MPC: A1 u1 + sum_k A_k u_k = 0 with
    the first (grid, component) dependent, u1 = -sum_k (A_k / A1) u_k (QRG MPC; components in CD frames)."""
    where = f"{bulk.path}: {ctx}"
    dofs, coeffs = [], []
    for gid, comp, a in zip(card.nodes, card.components, card.coefficients):
        c = int(comp or 0)
        if c < 1 or c > 6:
            raise BulkDataError(f"{where}: component {comp!r} of point {gid} is not in 1..6 (scalar points are not "
                                "supported)")
        dofs.append(6 * bulk.grid_index(int(gid), ctx) + c - 1)
        coeffs.append(float(a or 0.0))
    if not coeffs or coeffs[0] == 0.0:
        raise BulkDataError(f"{where}: the first coefficient A1 must be non-zero (its DOF is the dependent one)")
    if len(set(dofs)) != len(dofs):
        raise BulkDataError(f"{where}: a DOF appears twice in one MPC equation")
    return dofs[0], np.asarray(dofs[1:], dtype=np.int64), -np.asarray(coeffs[1:]) / coeffs[0]


def rbe3_rows(bulk: BulkData, rig, ctx: str):
    """Dependent rows of an RBE3: [(dependent g-set DOF, independent g-set DOFs, coefficients)].

    The reference grid moves with the rigid-body motion (u, theta) that fits the independent
    grids' motions in the weighted least-squares sense (MSC Nastran QRG, RBE3 remarks;
    MSC "RBE3 theory"): minimize sum_i w_i |S_i (u, theta) - u_i|^2 over the listed components,
    S_i = R_i' [I, -skew(x_i - x_ref)] for translations and R_i' [0, I] for rotations (R_i the
    grid's CD frame), rotation rows weighted by w_i L^2 with L the mean distance of the
    independent grids from the reference (so both kinds of rows have the same units). Then
    (u, theta) = (S' W S)^-1 S' W u_ind, rotated to the reference grid's CD frame: one equation
    ``u_ref,c - G_c u_ind = 0`` per REFC component c.

    UM (alternate dependent DOFs; MSC Nastran 2022.4 QRG, RBE3 field UM and remark 7) changes
    which DOFs these equations are solved for, not the equations: with C their coefficients on
    all their DOFs, the UM DOFs m follow ``u_m = -C_m^-1 C_n u_n`` from the others n (REFC DOFs
    of REFGRID not in UM become independent). As remark 7 requires, the UM set must have as many
    DOFs as REFC, be a subset of the REFC and (Gi,j, Ci) DOFs, and give a nonsingular C_m (tested
    with rotations scaled by L, so the test does not depend on units); anything else is refused
    with a message, as is a DOF listed twice.
    """
    pos, Rcd = bulk.positions, bulk.displacement_rotation
    ref = bulk.grid_index(int(rig.refgrid), ctx)
    refc = _components(rig.refc)
    if not refc:
        raise BulkDataError(f"{ctx}: REFC is blank")
    entries = []     # (g-set dof, weight, S row)
    for weight, comp, grids in zip(rig.weights, rig.comps, rig.Gijs):
        for gid in grids:
            i = bulk.grid_index(int(gid), ctx)
            d = pos[i] - pos[ref]
            rigid = np.zeros((6, 6))
            rigid[:3, :3] = np.eye(3)
            rigid[:3, 3:] = -el.skew(d)
            rigid[3:, 3:] = np.eye(3)
            S6 = np.kron(np.eye(2), Rcd[i]).T @ rigid
            for c in _components(comp):
                entries.append((6 * i + c - 1, float(weight), S6[c - 1], c > 3))
    if not entries:
        raise BulkDataError(f"{ctx}: no independent grids")
    grids = {e[0] // 6 for e in entries}
    length = np.mean([np.linalg.norm(pos[g] - pos[ref]) for g in grids]) or 1.0
    S = np.array([e[2] for e in entries])
    w = np.array([e[1] * (length**2 if e[3] else 1.0) for e in entries])
    A = S.T @ (w[:, None] * S)
    ev = np.linalg.eigvalsh(A)
    if ev[0] <= 1e-10 * ev[-1]:
        raise BulkDataError(f"{ctx}: the independent grids and components do not determine the "
                            "reference grid's rigid motion (e.g. collinear grids with "
                            "translations only); add grids or rotation components")
    G = np.linalg.solve(A, S.T * w)                       # (6, n_ind), basic
    G = np.kron(np.eye(2), Rcd[ref]).T @ G                # reference grid's CD frame
    dofs = np.array([e[0] for e in entries], dtype=np.int64)
    if not rig.Gmi:
        return [(6 * ref + c - 1, dofs, G[c - 1]) for c in refc]
    return _rbe3_alternate_rows(bulk, rig, ctx, [6 * ref + c - 1 for c in refc], dofs,
                                G[np.array(refc) - 1], length)


def _rbe3_alternate_rows(bulk, rig, ctx, ref_dofs, ind_dofs, G, length):
    """The RBE3 equations ``u_ref - G u_ind = 0`` solved for the UM DOFs (:func:`rbe3_rows`)."""
    where = f"{bulk.path}: {ctx}"
    um = []
    for gid, comps in zip(rig.Gmi, rig.Cmi):
        i = bulk.grid_index(int(gid), ctx + " UM")
        for c in _components(comps):
            if 6 * i + c - 1 in um:
                raise BulkDataError(f"{where}: UM lists DOF {c} of grid {gid} twice")
            um.append(6 * i + c - 1)
    if len(um) != len(ref_dofs):
        raise BulkDataError(f"{where}: UM lists {len(um)} dependent DOFs, REFC {len(ref_dofs)}; "
                            "the UM set must have one DOF per REFC component")
    involved = np.unique(np.concatenate([ref_dofs, ind_dofs]))
    col = {int(g): k for k, g in enumerate(involved)}
    for g in um:
        if g not in col:
            raise BulkDataError(f"{where}: UM DOF {g % 6 + 1} of grid {bulk.grid_ids[g // 6]} is "
                                "neither a REFC component of REFGRID nor a listed (Gi,j, Ci) "
                                "component; the UM DOFs must be a subset of those (QRG RBE3 "
                                "remark 7)")
    C = np.zeros((len(ref_dofs), len(involved)))
    for r, g in enumerate(ref_dofs):
        C[r, col[g]] += 1.0
        np.add.at(C[r], [col[int(d)] for d in ind_dofs], -G[r])
    # rotations in units of length (theta L) so that the singularity test does not depend on units
    scale = np.where(involved % 6 >= 3, length, 1.0)
    row_scale = np.where(np.array(ref_dofs) % 6 >= 3, length, 1.0)
    m = np.array([col[g] for g in um])
    n = np.setdiff1d(np.arange(len(involved)), m)
    sv = np.linalg.svd(row_scale[:, None] * C[:, m] / scale[m], compute_uv=False)
    if sv[-1] <= 1e-10 * sv[0]:
        names = ", ".join(f"grid {bulk.grid_ids[g // 6]} DOF {g % 6 + 1}" for g in um)
        raise BulkDataError(f"{where}: the RBE3 equations cannot be solved for the UM DOFs "
                            f"({names}): their coefficient matrix is singular (smallest/largest "
                            f"singular value {sv[-1] / sv[0]:.1e}); choose UM DOFs that the "
                            "equations determine (QRG RBE3 remark 7)")
    X = -np.linalg.solve(C[:, m], C[:, n])
    return [(int(involved[m[k]]), involved[n], X[k]) for k in range(len(m))]


def deck_aset(bulk: BulkData) -> list:
    out = []
    for card in bulk.model.asets:
        if card.type == "ASET1":
            out.extend((int(g), _components(card.components)) for g in card.ids)
        else:
            out.extend((int(g), _components(c)) for g, c in zip(card.ids, card.components))
    return out
