"""The flexible-body HDF5 file: one module that writes and reads it (layout in docs/body_file.md).

The layout follows TM-2020-5008164 Appendix C.3 (FModal): groups RigidBody, ModalSolution
(FREQ, modal matrices, TransModeShape, RotModeShape), ModalIntegral, CraigBampton, Gset, Fset,
GridPosition, ChildBodies and file metadata (version, time stamp). Everything is float64 and
SI. Two deliberate differences from C.3: per-grid mode shapes are stored as one
(n_grids, 3, n_modes) array next to a GridIds dataset instead of one dataset per grid (a 20,000
grid model would otherwise need 40,000 datasets), and the modal integrals carry their TM names
(p1, J1, J2, F0, ...) rather than P0..P6.

``write_body_file(path, body)`` and ``read_body_file(path) -> ModalBody`` round-trip exactly.
"""

from __future__ import annotations

import datetime as _dt
from dataclasses import dataclass, field, fields

import h5py
import numpy as np
import scipy.sparse as sp

from dynamics.flex.geometric_stiffness import GeometricStiffness
from dynamics.flex.modal_integrals import ModalIntegrals

FORMAT_VERSION = "1.2"
"""Layout version. 1.1 (issue 15) adds the optional ``GeometricStiffness`` group; 1.2 (issue 33) the
optional ``Units`` (the deck's unit system and its factors to SI), ``OutputFrame`` (CSID axes) and
``LoadsRecovery`` groups.
Older files read unchanged, without them."""


@dataclass
class SparseModel:
    """Physical-set matrices (NASTRAN G-set or F-set) in CD frames, [T1 T2 T3 R1 R2 R3] order.

    uset : (n_dof, 2) int64 rows (grid id, component 1..6) naming each DOF.
    """

    mass: sp.csr_matrix
    stiffness: sp.csr_matrix
    uset: np.ndarray


@dataclass
class CraigBamptonData:
    """Craig-Bampton model (eq. A.2.8): coordinates [fixed-interface modal; a-set physical].

    frequencies_hz : fixed-interface modal frequencies; uset : (n_b, 2) a-set (grid, component).
    """

    frequencies_hz: np.ndarray
    mass: np.ndarray
    stiffness: np.ndarray
    uset: np.ndarray


@dataclass
class ChildRigidBody:
    """A CONM2 separated from the flexible body (FModal separateLumpedRigidBodies).

    cm_offset : CG from the attachment grid [m] (basic axes); inertia about the CG [kg m^2].
    """

    element_id: int
    grid_id: int
    mass: float
    cm_offset: np.ndarray
    inertia: np.ndarray


@dataclass
class ModalBody:
    """Everything the multibody engine needs to build one flexible body (SI, basic axes).

    Body frame: origin at the reference point (GRDPNT grid, or the basic origin), axes of the
    basic frame. Mode shapes per grid: ``mode_shape(grid)`` = [rotation (3); translation (3)]
    x n_modes, i.e. Pi(j) = [lambda; gamma] of TM eq. E.1.19 and docs/conventions.md.
    """

    source: str
    mode_set: str                          # "free-free" | "normalized-component"
    reference_grid: int                    # 0 = basic origin
    reference_point: np.ndarray            # (3,) basic [m]
    mass: float                            # [kg]
    cm_offset: np.ndarray                  # (3,) from the reference point [m]
    inertia: np.ndarray                    # (3,3) about the reference point [kg m^2]
    frequencies_hz: np.ndarray             # (n,); inf for the quasi-static modes
    n_rigid_modes_removed: int
    n_residual_vectors: int
    grid_ids: np.ndarray                   # (N,) int64
    grid_positions: np.ndarray             # (N,3) from the reference point [m]
    rotation_shapes: np.ndarray            # (N,3,n) lambda [rad per unit eta]
    translation_shapes: np.ndarray         # (N,3,n) gamma [m per unit eta]
    node_mass: np.ndarray                  # (N,)  [kg]
    node_cm_offset: np.ndarray             # (N,3) [m]
    node_inertia: np.ndarray               # (N,3,3) about the grid [kg m^2]
    modal_mass: np.ndarray                 # (n,n)
    modal_stiffness: np.ndarray            # (n,n) [1/s^2 with mass-normalized modes]
    modal_damping: np.ndarray              # (n,n) [1/s]
    damping_ratios: np.ndarray             # (n,)
    modal_integrals: ModalIntegrals | None = None
    point_mass_integrals: ModalIntegrals | None = None
    craig_bampton: CraigBamptonData | None = None
    gset: SparseModel | None = None
    fset: SparseModel | None = None
    modal_matrix: np.ndarray | None = None  # (6N, n) g-set (CD frames, [T; R] per grid)
    aset: np.ndarray = field(default_factory=lambda: np.zeros((0, 2), dtype=np.int64))
    residual_dofs: np.ndarray = field(default_factory=lambda: np.zeros((0, 2), dtype=np.int64))
    child_bodies: list = field(default_factory=list)
    card_report: list = field(default_factory=list)
    geometric_stiffness: GeometricStiffness | None = None
    # element geometry for drawing (flexshell view): NASTRAN card name and corner grids (0-padded) per
    # element; empty when unknown (files written before it was kept)
    element_types: list = field(default_factory=list)
    element_grids: np.ndarray = field(default_factory=lambda: np.zeros((0, 0), dtype=np.int64))
    # the deck's units and the factors that brought the body to SI (``--units``): keys spec, length, mass,
    # time, force (SI per deck unit), wtmass; None when the deck was taken as SI
    deck_units: dict | None = None
    # output coordinate system (``--csid``): its id and axes in basic (columns); the body frame has these
    # axes. 0 and the identity: basic axes
    output_csid: int = 0
    output_axes: np.ndarray = field(default_factory=lambda: np.eye(3))
    # element forces / stresses and interface forces from the modal coordinates (dynamics.flex.loads_recovery)
    loads_recovery: object = None
    # the last n_quasi_static modes have stiffness and no mass (massless interface DOFs of normalized component
    # modes, dynamics.flex.component_modes): frequency inf, modal mass 0, modal stiffness the largest flexible
    # eigenvalue each
    n_quasi_static: int = 0
    version: str = FORMAT_VERSION
    time_stamp: str = ""

    @property
    def n_modes(self) -> int:
        return len(self.frequencies_hz)

    def interface_grids(self) -> list[int]:
        """Grids of the a-set (the interface of normalized component modes), ascending."""
        return sorted({int(g) for g in self.aset[:, 0]}) if len(self.aset) else []

    def mounting_warnings(self, child_grid: int | None, hinge: str) -> list[str]:
        """What is suspicious about mounting this body with ``child_grid`` on a ``hinge``.

        Normalized component modes (mode_set "normalized-component") contain the constraint
        modes of the a-set, which represent the interface motion relative to the rest of the
        body: (1) without ``child_grid`` the hinge frame sits at the reference point, not at the
        interface, so the constraint modes are not held where the structure is attached; (2) on
        a free (6-DOF) hinge a ``child_grid`` adds six hinge DOFs that the rigid-body part of
        the constraint modes already spans, a singular mass matrix.
        """
        out = []
        if self.mode_set != "normalized-component":
            return out
        grids = self.interface_grids()
        if child_grid is None:
            out.append(f"{self.source}: normalized component modes (interface grids {grids}) "
                       "used without child_grid: the hinge does not hold the interface grid, so "
                       f"the constraint modes are not restrained; set child_grid to one of {grids}")
        elif int(child_grid) not in grids:
            out.append(f"{self.source}: child_grid {child_grid} is not an interface (a-set) grid "
                       f"of these normalized component modes ({grids})")
        if child_grid is not None and hinge in ("free", "6dof", "floating"):
            out.append(f"{self.source}: child_grid {child_grid} on a free hinge duplicates the "
                       "rigid-body motion the constraint modes already contain (singular mass "
                       "matrix, 'articulated inertia is singular'); use free-free modes for a "
                       "free body, or a hinge that holds the interface")
        return out

    def mode_shape(self, grid_id: int) -> np.ndarray:
        """6 x n block Pi(j) = [lambda; gamma] of grid ``grid_id``."""
        i = int(np.searchsorted(self.grid_ids, grid_id))
        if i >= len(self.grid_ids) or self.grid_ids[i] != grid_id:
            raise KeyError(f"grid {grid_id} is not in the body file ({self.source})")
        return np.vstack([self.rotation_shapes[i], self.translation_shapes[i]])


def _write_sparse(group: h5py.Group, name: str, M) -> None:
    M = sp.csr_matrix(M)
    g = group.create_group(name)
    g.attrs["format"] = "csr"
    g.create_dataset("data", data=M.data.astype(np.float64))
    g.create_dataset("indices", data=M.indices.astype(np.int64))
    g.create_dataset("indptr", data=M.indptr.astype(np.int64))
    g.create_dataset("shape", data=np.asarray(M.shape, dtype=np.int64))


def _read_sparse(g: h5py.Group) -> sp.csr_matrix:
    return sp.csr_matrix((g["data"][()], g["indices"][()], g["indptr"][()]),
                         shape=tuple(g["shape"][()]))


def _write_integrals(group: h5py.Group, mi: ModalIntegrals) -> None:
    for name, arr in mi.arrays().items():
        group.create_dataset(name, data=np.asarray(arr, dtype=np.float64))


def _read_integrals(g: h5py.Group) -> ModalIntegrals:
    kw = {}
    for f in fields(ModalIntegrals):
        if f.name not in g:             # G2 absent: identically zero or not computed
            kw[f.name] = None
            continue
        v = g[f.name][()]
        kw[f.name] = float(v) if f.name == "mass" else v
    return ModalIntegrals(**kw)


def _write_set(h5: h5py.File, name: str, s: SparseModel) -> None:
    g = h5.create_group(name)
    _write_sparse(g, "MassMatrix", s.mass)
    _write_sparse(g, "StiffnessMatrix", s.stiffness)
    g.create_dataset("USET", data=np.asarray(s.uset, dtype=np.int64))


def _read_set(g: h5py.Group) -> SparseModel:
    return SparseModel(mass=_read_sparse(g["MassMatrix"]),
                       stiffness=_read_sparse(g["StiffnessMatrix"]), uset=g["USET"][()])


def write_body_file(path, body: ModalBody) -> None:
    """Write ``body`` to ``path`` (overwrites). Sets ``body.time_stamp`` if empty."""
    if not body.time_stamp:
        body.time_stamp = _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds")
    with h5py.File(path, "w") as h5:
        h5.attrs["FLEXSHELL_BODY_FILE_VERSION"] = body.version
        h5.create_dataset("FLEXSHELL_BODY_FILE_VERSION", data=body.version)
        h5.create_dataset("TIME_STAMP", data=body.time_stamp)
        h5.create_dataset("SOURCE", data=body.source)
        h5.create_dataset("N_GRIDS", data=len(body.grid_ids))
        h5.create_dataset("GRDPNT", data=int(body.reference_grid))
        h5.create_dataset("CARD_REPORT", data=np.array(body.card_report, dtype=object),
                          dtype=h5py.string_dtype())
        rb = h5.create_group("RigidBody")
        rb.create_dataset("mass", data=float(body.mass))
        rb.create_dataset("cmoffset", data=body.cm_offset)
        rb.create_dataset("inertia", data=body.inertia)
        rb.create_dataset("reference_point", data=body.reference_point)
        gp = h5.create_group("GridPosition")
        gp.create_dataset("GridIds", data=np.asarray(body.grid_ids, dtype=np.int64))
        gp.create_dataset("position", data=body.grid_positions)
        nm = h5.create_group("NodeMass")
        nm.create_dataset("mass", data=body.node_mass)
        nm.create_dataset("cmoffset", data=body.node_cm_offset)
        nm.create_dataset("inertia", data=body.node_inertia)
        ms = h5.create_group("ModalSolution")
        ms.attrs["mode_set"] = body.mode_set
        ms.create_dataset("MODE_SET", data=body.mode_set)
        ms.create_dataset("FREQ", data=body.frequencies_hz)
        ms.create_dataset("N_FLEX_MODES", data=body.n_modes)
        ms.create_dataset("N_RIGID_MODES", data=int(body.n_rigid_modes_removed))
        ms.create_dataset("N_RESIDUAL_VECTORS", data=int(body.n_residual_vectors))
        if body.n_quasi_static:
            ms.create_dataset("N_QUASI_STATIC_MODES", data=int(body.n_quasi_static))
        ms.create_dataset("ModalMassMatrix", data=body.modal_mass)
        ms.create_dataset("ModalStiffnessMatrix", data=body.modal_stiffness)
        ms.create_dataset("ModalDampingMatrix", data=body.modal_damping)
        ms.create_dataset("DampingRatio", data=body.damping_ratios)
        ms.create_dataset("GridIds", data=np.asarray(body.grid_ids, dtype=np.int64))
        ms.create_dataset("TransModeShape", data=body.translation_shapes)
        ms.create_dataset("RotModeShape", data=body.rotation_shapes)
        ms.create_dataset("ASET", data=np.asarray(body.aset, dtype=np.int64).reshape(-1, 2))
        ms.create_dataset("RESIDUAL_DOFS",
                          data=np.asarray(body.residual_dofs, dtype=np.int64).reshape(-1, 2))
        if body.modal_matrix is not None:
            ms.create_dataset("ModalMatrix", data=body.modal_matrix)
        if body.modal_integrals is not None or body.point_mass_integrals is not None:
            mi = h5.create_group("ModalIntegral")
            if body.modal_integrals is not None:
                _write_integrals(mi.create_group("General"), body.modal_integrals)
            if body.point_mass_integrals is not None:
                _write_integrals(mi.create_group("PointMass"), body.point_mass_integrals)
        if body.craig_bampton is not None:
            cb = h5.create_group("CraigBampton")
            cb.create_dataset("FREQ", data=body.craig_bampton.frequencies_hz)
            cb.create_dataset("MassMatrix", data=body.craig_bampton.mass)
            cb.create_dataset("StiffnessMatrix", data=body.craig_bampton.stiffness)
            cb.create_dataset("USET", data=np.asarray(body.craig_bampton.uset, dtype=np.int64))
        if body.gset is not None:
            _write_set(h5, "Gset", body.gset)
        if body.fset is not None:
            _write_set(h5, "Fset", body.fset)
        gs = body.geometric_stiffness
        if gs is not None:
            g = h5.create_group("GeometricStiffness")
            g.attrs["reaction"] = gs.reaction
            g.create_dataset("REACTION", data=gs.reaction)
            g.create_dataset("ELEMENTS", data=gs.elements)
            g.create_dataset("Translation", data=gs.translation)
            g.create_dataset("Rotation", data=gs.rotation)
            g.create_dataset("AngularVelocity", data=gs.angular_velocity)
            if gs.preload_names:
                g.create_dataset("PreloadNames", data=np.array(gs.preload_names, dtype=object),
                                 dtype=h5py.string_dtype())
                g.create_dataset("Preload", data=gs.preload)
        if len(body.element_types):
            geometry = h5.create_group("Geometry")
            geometry.create_dataset("ElementType", data=np.array(body.element_types, dtype=object),
                                    dtype=h5py.string_dtype())
            geometry.create_dataset("ElementGrids", data=np.asarray(body.element_grids, dtype=np.int64))
        if body.deck_units is not None:
            units = h5.create_group("Units")
            units.attrs["spec"] = body.deck_units["spec"]
            units.create_dataset("DECK_UNITS", data=body.deck_units["spec"])
            for key in UNIT_FACTORS:
                units.create_dataset(key.upper(), data=float(body.deck_units[key]))
        if body.loads_recovery is not None:
            _write_loads_recovery(h5.create_group("LoadsRecovery"), body.loads_recovery)
        if body.output_csid:
            frame = h5.create_group("OutputFrame")
            frame.create_dataset("CSID", data=int(body.output_csid))
            frame.create_dataset("Axes", data=np.asarray(body.output_axes, dtype=np.float64))
        cbs = h5.create_group("ChildBodies")
        for k, child in enumerate(body.child_bodies):
            g = cbs.create_group(f"{k:04d}")
            g.create_dataset("element_id", data=int(child.element_id))
            g.create_dataset("grid_id", data=int(child.grid_id))
            g.create_dataset("mass", data=float(child.mass))
            g.create_dataset("cmoffset", data=child.cm_offset)
            g.create_dataset("inertia", data=child.inertia)


def _write_loads_recovery(g: h5py.Group, lr) -> None:
    g.attrs["reaction"] = lr.reaction
    g.create_dataset("REACTION", data=lr.reaction)
    g.create_dataset("REFERENCE_GRID", data=int(lr.reference_grid))
    g.create_dataset("Names", data=np.array(lr.names, dtype=object), dtype=h5py.string_dtype())
    g.create_dataset("Kinds", data=np.array(lr.kinds, dtype=object), dtype=h5py.string_dtype())
    for name, value in (("ModeDisplacement", lr.mode_displacement),
                        ("ReferenceAcceleration", lr.reference_acceleration), ("Loads", lr.loads)):
        g.create_dataset(name, data=np.asarray(value, dtype=np.float64))
    g.create_dataset("LoadDofs", data=np.asarray(lr.load_dofs, dtype=np.int64).reshape(-1, 2))


def _read_loads_recovery(g: h5py.Group):
    from dynamics.flex.loads_recovery import LoadsRecovery

    def strings(ds):
        return [s.decode() if isinstance(s, bytes) else str(s) for s in ds[()]]
    return LoadsRecovery(names=strings(g["Names"]), kinds=strings(g["Kinds"]),
                         mode_displacement=g["ModeDisplacement"][()],
                         reference_acceleration=g["ReferenceAcceleration"][()], reaction=_str(g["REACTION"]),
                         reference_grid=int(g["REFERENCE_GRID"][()]),
                         load_dofs=g["LoadDofs"][()], loads=g["Loads"][()])


# datasets of the ``Units`` group: SI per deck unit of length, mass, time and force, and PARAM WTMASS
UNIT_FACTORS = ("length", "mass", "time", "force", "wtmass")


def _str(ds) -> str:
    v = ds[()]
    return v.decode() if isinstance(v, bytes) else str(v)


def _read_geometric_stiffness(g) -> GeometricStiffness:
    names = [s.decode() if isinstance(s, bytes) else str(s) for s in g["PreloadNames"][()]] \
        if "PreloadNames" in g else []
    return GeometricStiffness(reaction=_str(g["REACTION"]), translation=g["Translation"][()],
                              rotation=g["Rotation"][()], angular_velocity=g["AngularVelocity"][()],
                              preload_names=names, preload=g["Preload"][()] if names else None,
                              elements=_str(g["ELEMENTS"]))


def read_body_file(path) -> ModalBody:
    """Read a body file written by :func:`write_body_file`."""
    with h5py.File(path, "r") as h5:
        if "FLEXSHELL_BODY_FILE_VERSION" not in h5:
            raise ValueError(f"{path}: not a flexshell body file (no FLEXSHELL_BODY_FILE_VERSION)")
        version = _str(h5["FLEXSHELL_BODY_FILE_VERSION"])
        if version.split(".")[0] != FORMAT_VERSION.split(".")[0]:
            raise ValueError(f"{path}: body file version {version}, this reader handles "
                             f"{FORMAT_VERSION}")
        rb, ms, gp, nm = h5["RigidBody"], h5["ModalSolution"], h5["GridPosition"], h5["NodeMass"]
        mi = h5.get("ModalIntegral")
        cb = h5.get("CraigBampton")
        body = ModalBody(
            source=_str(h5["SOURCE"]),
            mode_set=_str(ms["MODE_SET"]),
            reference_grid=int(h5["GRDPNT"][()]),
            reference_point=rb["reference_point"][()],
            mass=float(rb["mass"][()]),
            cm_offset=rb["cmoffset"][()],
            inertia=rb["inertia"][()],
            frequencies_hz=ms["FREQ"][()],
            n_rigid_modes_removed=int(ms["N_RIGID_MODES"][()]),
            n_residual_vectors=int(ms["N_RESIDUAL_VECTORS"][()]),
            grid_ids=gp["GridIds"][()],
            grid_positions=gp["position"][()],
            rotation_shapes=ms["RotModeShape"][()],
            translation_shapes=ms["TransModeShape"][()],
            node_mass=nm["mass"][()],
            node_cm_offset=nm["cmoffset"][()],
            node_inertia=nm["inertia"][()],
            modal_mass=ms["ModalMassMatrix"][()],
            modal_stiffness=ms["ModalStiffnessMatrix"][()],
            modal_damping=ms["ModalDampingMatrix"][()],
            damping_ratios=ms["DampingRatio"][()],
            modal_integrals=_read_integrals(mi["General"]) if mi is not None
            and "General" in mi else None,
            point_mass_integrals=_read_integrals(mi["PointMass"]) if mi is not None
            and "PointMass" in mi else None,
            craig_bampton=CraigBamptonData(cb["FREQ"][()], cb["MassMatrix"][()],
                                           cb["StiffnessMatrix"][()], cb["USET"][()])
            if cb is not None else None,
            gset=_read_set(h5["Gset"]) if "Gset" in h5 else None,
            fset=_read_set(h5["Fset"]) if "Fset" in h5 else None,
            modal_matrix=ms["ModalMatrix"][()] if "ModalMatrix" in ms else None,
            aset=ms["ASET"][()],
            residual_dofs=ms["RESIDUAL_DOFS"][()],
            child_bodies=[ChildRigidBody(int(g["element_id"][()]), int(g["grid_id"][()]),
                                         float(g["mass"][()]), g["cmoffset"][()],
                                         g["inertia"][()])
                          for _, g in sorted(h5["ChildBodies"].items())],
            card_report=[s.decode() if isinstance(s, bytes) else str(s)
                         for s in h5["CARD_REPORT"][()]],
            geometric_stiffness=_read_geometric_stiffness(h5["GeometricStiffness"])
            if "GeometricStiffness" in h5 else None,
            version=version,
            time_stamp=_str(h5["TIME_STAMP"]),
        )
        body.element_types, body.element_grids = _read_geometry(h5)
        if "Units" in h5:
            units = h5["Units"]
            body.deck_units = {"spec": _str(units["DECK_UNITS"]),
                               **{key: float(units[key.upper()][()]) for key in UNIT_FACTORS}}
        if "N_QUASI_STATIC_MODES" in ms:
            body.n_quasi_static = int(ms["N_QUASI_STATIC_MODES"][()])
        if "LoadsRecovery" in h5:
            body.loads_recovery = _read_loads_recovery(h5["LoadsRecovery"])
        if "OutputFrame" in h5:
            body.output_csid = int(h5["OutputFrame/CSID"][()])
            body.output_axes = h5["OutputFrame/Axes"][()]
    return body


def _read_geometry(h5: h5py.File):
    if "Geometry" not in h5:
        return [], np.zeros((0, 0), dtype=np.int64)
    g = h5["Geometry"]
    types = [s.decode() if isinstance(s, bytes) else str(s) for s in g["ElementType"][()]]
    return types, g["ElementGrids"][()]


def read_body_geometry(path):
    """(element types or None when the file keeps none, element grids, SOURCE) of a body file, without
    reading its matrices (the 3D view's need)."""
    with h5py.File(path, "r") as h5:
        types, grids = _read_geometry(h5)
        return (types if types else None), grids, _str(h5["SOURCE"])


def elements_of_deck(model) -> tuple[list, np.ndarray]:
    """(card names, corner grids padded with 0) of a pyNastran model's elements and rigid elements, in
    element-id order: the body file's ``Geometry`` group. RBE2: independent grid then dependent grids;
    RBE3: reference grid then the weighted grids."""
    types, rows = [], []
    for _, elem in sorted(model.elements.items()):
        types.append(elem.type)
        rows.append([int(g) if g else 0 for g in elem.node_ids])
    for _, elem in sorted(model.rigid_elements.items()):
        if elem.type == "RBE2":
            grids = [elem.gn] + list(elem.Gmi_node_ids)
        elif elem.type == "RBE3":
            grids = [elem.refgrid] + [int(g) for group in elem.Gijs for g in group]
        else:
            grids = list(elem.independent_nodes) + list(elem.dependent_nodes)
        types.append(elem.type)
        rows.append([int(g) for g in grids])
    width = max((len(r) for r in rows), default=0)
    grids = np.zeros((len(rows), width), dtype=np.int64)
    for k, r in enumerate(rows):
        grids[k, :len(r)] = r
    return types, grids
