"""NASTRAN OP2 results through pyNastran's OP2 reader: SOL 103 eigenvalues and eigenvectors, DMAP matrices.

What is read (pyNastran ``read_op2``): the real eigenvalue table LAMA (eigenvalues omega^2, generalized
masses), the eigenvector tables OUGV1 (each grid's displacement frame CD, NASTRAN's default output, also
with PARAM OUGCORD GLOBAL) or BOUGV1 (basic), the grid point weight generator's mass properties (OGPWG,
PARAM GRDPNT), and matrices written by DMAP OUTPUT2 (e.g. KGG, MGG). Eigenvectors of scalar or extra
points are refused: the body file holds grids.

pyNastran 1.3.4 (pinned: 1.4 needs numpy < 2) imports ``numpy.in1d``, which numpy 2.4 removed; the alias
to ``numpy.isin`` is put in place for that import only (the eigenvector and matrix tables do not call it).
"""

from __future__ import annotations

import contextlib
import io
import logging
import os
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp


class Op2Error(ValueError):
    """An OP2 file fem2modal cannot use; the message names the file and what is missing."""


@dataclass
class Op2Results:
    """What fem2modal takes from an OP2 file.

    eigenvalues (n,) omega^2 [1/s^2 in the deck's units]; vectors (n, n_grids, 6) [T1 T2 T3 R1 R2 R3] per
    grid in ``frame`` ("CD": each grid's displacement frame, "basic"); grid_ids (n_grids,);
    generalized_mass (n,) as NASTRAN normalized (1 for NORM = MASS); grid_point_weight: (reference grid,
    MO) with MO the 6 x 6 rigid-body mass matrix about the reference point in basic, [T; R] order, as the
    grid point weight generator wrote it (PARAM GRDPNT), or None; matrices {NAME: csr}.
    """

    path: str
    title: str = ""
    eigenvalues: np.ndarray = field(default_factory=lambda: np.zeros(0))
    vectors: np.ndarray = field(default_factory=lambda: np.zeros((0, 0, 6)))
    grid_ids: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    frame: str = "CD"
    table: str = ""
    generalized_mass: np.ndarray = field(default_factory=lambda: np.zeros(0))
    grid_point_weight: tuple | None = None
    matrices: dict = field(default_factory=dict)

    @property
    def has_modes(self) -> bool:
        return len(self.eigenvalues) > 0


def _op2_reader():
    had = hasattr(np, "in1d")
    if not had:
        np.in1d = np.isin
    try:
        from pyNastran.op2.op2 import read_op2
    finally:
        if not had:
            del np.in1d
    return read_op2


def read_op2_results(path) -> Op2Results:
    """Read ``path``; :class:`Op2Error` for a file without eigenvectors or matrices, or with more than one
    eigenvector subcase."""
    path = os.fspath(path)
    if not os.path.isfile(path):
        raise FileNotFoundError(f"OP2 file not found: {path}")
    read_op2 = _op2_reader()
    log = logging.getLogger("pyNastran.flexshell.op2")
    log.setLevel(logging.ERROR)
    try:
        with contextlib.redirect_stdout(io.StringIO()):
            model = read_op2(path, debug=False, build_dataframe=False, log=log)
    except Exception as exc:  # pyNastran raises many types for unreadable files; name the file
        raise Op2Error(f"{path}: pyNastran could not read the OP2 file: {exc}") from exc
    out = Op2Results(path=path)
    for name, matrix in getattr(model, "matrices", {}).items():
        data = getattr(matrix, "data", matrix)
        out.matrices[str(name).strip().upper()] = sp.csr_matrix(data, dtype=np.float64)
    if model.eigenvectors:
        if len(model.eigenvectors) > 1:
            raise Op2Error(f"{path}: eigenvectors of {len(model.eigenvectors)} subcases "
                           f"({sorted(model.eigenvectors)}); give an OP2 of one SOL 103 subcase")
        vec = next(iter(model.eigenvectors.values()))
        table = str(getattr(vec, "table_name", "") or "").strip()
        if table not in ("OUGV1", "BOUGV1"):
            raise Op2Error(f"{path}: eigenvector table {table!r}; OUGV1 (CD frames) or BOUGV1 (basic) expected")
        kinds = np.asarray(vec.node_gridtype)[:, 1]
        if np.any(kinds != 1):
            raise Op2Error(f"{path}: eigenvectors of scalar or extra points (grid types {sorted(set(kinds))}); "
                           "the body file holds grids (type 1) only")
        out.table, out.frame = table, ("basic" if table == "BOUGV1" else "CD")
        out.vectors = np.asarray(vec.data, dtype=np.float64)
        out.grid_ids = np.asarray(vec.node_gridtype)[:, 0].astype(np.int64)
        eigns = np.asarray(getattr(vec, "eigns", []), dtype=np.float64)
        if model.eigenvalues:
            lama = next(iter(model.eigenvalues.values()))
            out.title = str(next(iter(model.eigenvalues)))
            modes = np.asarray(lama.mode, dtype=np.int64)
            order = np.asarray(vec.modes, dtype=np.int64)
            lookup = {int(m): k for k, m in enumerate(modes)}
            if any(int(m) not in lookup for m in order):
                raise Op2Error(f"{path}: eigenvectors of modes {sorted(set(order.tolist()) - set(lookup))} have no "
                               "eigenvalue in the LAMA table")
            pick = np.array([lookup[int(m)] for m in order])
            out.eigenvalues = np.asarray(lama.eigenvalues, dtype=np.float64)[pick]
            out.generalized_mass = np.asarray(lama.generalized_mass, dtype=np.float64)[pick]
        elif len(eigns) == out.vectors.shape[0]:
            out.eigenvalues = eigns
            out.generalized_mass = np.full(len(eigns), np.nan)
        else:
            raise Op2Error(f"{path}: eigenvectors without eigenvalues (no LAMA table)")
    weights = getattr(model, "grid_point_weight", {}) or {}
    if weights:
        gpw = next(iter(weights.values()))
        out.grid_point_weight = (int(gpw.reference_point), np.asarray(gpw.MO, dtype=np.float64))
    if not out.has_modes and not out.matrices:
        raise Op2Error(f"{path}: neither eigenvectors (OUGV1/BOUGV1 with LAMA) nor matrices were found")
    return out


@dataclass
class Op2Modes:
    """NASTRAN's modes on the deck's f-set (:func:`modes_on_fset`).

    eigenvalues (n,) and vectors (n_f, n) of the flexible modes kept, M-orthonormal with the deck's mass
    matrix; n_rigid: rigid-body (and zero-energy) modes of the OP2 left out; report: lines for the run and the
    card report (what was read, how far NASTRAN's vectors were from M-orthonormal with this mass matrix,
    how well the dependent DOFs match the deck's constraints)."""

    eigenvalues: np.ndarray
    vectors: np.ndarray
    n_rigid: int
    report: list


def modes_on_fset(op2: Op2Results, sm, K, M, rigid_vectors: np.ndarray, n_modes: int | None,
                  cutoff_hz: float | None) -> Op2Modes:
    """NASTRAN's eigenvectors as f-set vectors of the deck's structural model ``sm``.

    Each grid's six components (CD frames, or basic for BOUGV1, turned to CD) fill the g-set; the f-set
    vector is its independent DOFs, and T_gf of it must give NASTRAN's dependent and constrained values back
    (reported; a large difference means the deck's constraints are not NASTRAN's). The rigid-body modes are
    the geometry's (``rigid_vectors``, as in :func:`dynamics.flex.modes.free_free_modes`): the OP2's modes
    with the lowest ``abs(eigenvalue)``, as many as the geometry has rigid motions, are left out (their alignment
    with the rigid space is reported), and the rest are projected M-orthogonal to it. NASTRAN's vectors
    (single precision, NASTRAN's mass matrix, any normalization) are made M-orthonormal with the deck's mass
    matrix by the symmetric (Loewdin) transformation V (V' M V)^-1/2, the one that changes them least; the
    eigenvalues stay NASTRAN's."""
    from dynamics.flex.modes import TWO_PI

    where = op2.path
    ids = np.asarray(sm.grid_ids)
    missing = np.setdiff1d(ids, op2.grid_ids)
    if len(missing):
        raise Op2Error(f"{where}: eigenvectors lack grids {missing[:8].tolist()} of the deck (DISP = ALL needed)")
    extra = np.setdiff1d(op2.grid_ids, ids)
    if len(extra):
        raise Op2Error(f"{where}: eigenvectors hold grids {extra[:8].tolist()} the deck does not define: another "
                       "deck's results?")
    rows = np.searchsorted(op2.grid_ids, ids) if np.all(np.diff(op2.grid_ids) > 0) else \
        np.array([int(np.nonzero(op2.grid_ids == g)[0][0]) for g in ids])
    data = op2.vectors[:, rows, :]                          # (modes, grids, 6)
    if op2.frame == "basic":
        Rcd = sm.bulk.displacement_rotation
        data = np.concatenate([np.einsum("gba,mgb->mga", Rcd, data[:, :, :3]),
                               np.einsum("gba,mgb->mga", Rcd, data[:, :, 3:])], axis=2)
    order = np.argsort(op2.eigenvalues, kind="stable")
    lam = op2.eigenvalues[order]
    ug = data[order].reshape(len(order), -1).T                 # (6 N, modes) in CD frames
    uf = ug[sm.f_dofs]
    back = sm.T_gf @ uf
    mismatch = np.linalg.norm(back - ug, axis=0) / np.maximum(np.linalg.norm(ug, axis=0), 1e-300)
    report = [f"modes from {where} ({op2.table}, {op2.title or 'untitled'}): {len(lam)} NASTRAN eigenpairs"]
    if mismatch.max() > 1e-4:
        report.append(f"WARNING: NASTRAN's vectors differ from the deck's constraints at dependent or constrained "
                      f"DOFs by up to {mismatch.max():.2e} (relative): the OP2 may not come from this deck")
    r = rigid_vectors.shape[1]
    if len(lam) <= r:
        raise Op2Error(f"{where}: {len(lam)} modes, of which the geometry makes {r} rigid-body modes: no flexible "
                       "mode left")
    if r:
        G = rigid_vectors.T @ (M @ rigid_vectors)
        s, U = np.linalg.eigh(0.5 * (G + G.T))
        Phi_r = rigid_vectors @ (U / np.sqrt(s))
        low = uf[:, :r]
        low = low / np.sqrt(np.maximum(np.einsum("ij,ij->j", low, M @ low), 1e-300))
        cosines = np.linalg.svd(Phi_r.T @ (M @ low), compute_uv=False)
        report.append(f"{r} rigid-body modes of the geometry left out: NASTRAN's {r} lowest "
                      f"(|f| <= {np.sqrt(np.abs(lam[:r]).max()) / TWO_PI:.3g} Hz), smallest cosine with the rigid "
                      f"space {cosines.min():.6f}")
        if cosines.min() < 0.999:
            report.append("WARNING: NASTRAN's lowest modes are not the geometry's rigid-body motions (a mechanism "
                          "or a soft mode near zero?)")
        flex = uf[:, r:] - Phi_r @ (Phi_r.T @ (M @ uf[:, r:]))
    else:
        flex = uf
    lam = lam[r:]
    if n_modes is not None:
        if n_modes > len(lam):
            raise Op2Error(f"{where}: {len(lam)} flexible modes in the OP2, {n_modes} asked for (--modes)")
        keep = n_modes
    else:
        keep = int(np.sum(np.sqrt(np.maximum(lam, 0.0)) / TWO_PI <= cutoff_hz))
        if keep == len(lam):
            report.append(f"WARNING: every flexible mode of the OP2 is below --cutoff {cutoff_hz:g} Hz: NASTRAN may "
                          "have found more below it than it wrote (EIGRL ND / V2)")
    lam, flex = lam[:keep], flex[:, :keep]
    G = flex.T @ (M @ flex)
    w, V = np.linalg.eigh(0.5 * (G + G.T))
    if w.min() <= 1e-12 * w.max():
        raise Op2Error(f"{where}: NASTRAN's modes are linearly dependent with the deck's mass matrix")
    flex = flex @ (V @ np.diag(w ** -0.5) @ V.T)
    scale = np.sqrt(np.diag(G))
    off = (G / np.outer(scale, scale)) - np.eye(keep)
    quotients = np.einsum("ij,ij->j", flex, K @ flex)
    report.append(f"{keep} flexible modes kept; NASTRAN's vectors with this deck's mass matrix: largest "
                  f"normalized off-diagonal of V'MV {np.abs(off).max():.2e}; Rayleigh quotients with this deck's "
                  f"stiffness within {np.abs(quotients / lam - 1).max():.2e} of NASTRAN's eigenvalues")
    return Op2Modes(lam, flex, r, report)
