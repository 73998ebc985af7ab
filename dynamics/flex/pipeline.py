"""fem2modal: NASTRAN bulk data (or OP4 matrices plus a geometry deck) to a :class:`ModalBody`.

Steps (FModal workflow, TM-2020-5008164 Appendix C; FModal paper Sections 2-4):
1. read the deck and report every card (:mod:`dynamics.flex.bulk_data`);
2. assemble sparse K, M and the g -> f constraint transformation (:mod:`dynamics.flex.assembly`),
   or take K_gg, M_gg from an OP4 file (:mod:`dynamics.flex.op4`);
3. mode set: free-free normal modes (no a-set), or Craig-Bampton plus normalized component modes
   for the a-set (the default when an a-set is given, as in FModal)
   (:mod:`dynamics.flex.modes`, :mod:`dynamics.flex.component_modes`);
4. residual vectors for chosen load DOFs (:mod:`dynamics.flex.residual_vectors`);
5. rigid-body mass properties about GRDPNT (:mod:`dynamics.flex.mass_properties`);
6. per-grid mode shapes in the basic frame, node masses from the lumped mass matrix, modal
   integrals (:mod:`dynamics.flex.modal_integrals`), modal damping;
7. the result is a :class:`~dynamics.flex.body_file.ModalBody` for
   :func:`~dynamics.flex.body_file.write_body_file`.
"""

from __future__ import annotations

import time
import warnings
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp

from dynamics.flex.assembly import (StructuralModel, apply_constraints, assemble,
                                     block_rotation, deck_aset)
from dynamics.flex.body_file import (ChildRigidBody, CraigBamptonData, ModalBody, SparseModel, elements_of_deck)
from dynamics.flex.bulk_data import BulkData, BulkDataError, coordinate_axes, read_bulk_data
from dynamics.flex.component_modes import craig_bampton, normalized_component_modes
from dynamics.flex.mass_properties import rigid_body_mass_properties
from dynamics.flex.modal_integrals import modal_integrals, point_mass_integrals
from dynamics.flex.modes import (EigenSolution, RigidSplit, free_free_modes, largest_entry_signs,
                                 massless_dofs)
from dynamics.flex.residual_vectors import append_residual_vectors, residual_vectors
from dynamics.flex.transform import express_body
from dynamics.flex.units import SI, DeckUnits, parse_units


@dataclass
class Fem2ModalOptions:
    """What to compute. Exactly one of ``n_modes`` / ``cutoff_hz``.

    n_modes / cutoff_hz: flexible free-free modes, or fixed-interface modes when an a-set is
        given (the normalized component set then has n_modes + n_b - n_rigid modes).
    aset / residual: lists of (grid id, [components 1..6]); the deck's ASET/ASET1 are added.
    grdpnt: reference grid for mass properties and the body frame (None: deck PARAM GRDPNT,
        else the basic origin).
    damping: modal damping ratio, one value for all modes or one per mode.
    rigid_threshold_hz: rigid-body modes come from the geometry (see
        :func:`dynamics.flex.modes.free_free_modes`); a flexible mode below this frequency is
        reported as suspicious (a mechanism, or a near-rigid structure).
    geometric_stiffness: also compute the modal geometric stiffness of the rigid-motion load cases
        (:mod:`dynamics.flex.geometric_stiffness`; reacted at the a-set, or by inertia relief).
    preloads: (name, grid, component 1..6, value) named static loads (basic axes) whose modal
        geometric stiffness is stored too (implies geometric_stiffness).
    units: the deck's unit system, ``LENGTH,FORCE,TIME`` or ``LENGTH,MASS,TIME`` (``"in,lbf,s"``,
        :mod:`dynamics.flex.units`); the body is expressed in SI and the conversion recorded. None: the
        deck is taken as SI (its densities are checked for plausibility). ``--preload`` values are SI.
    csid: output coordinate system (rectangular): the body frame takes its axes (origin still at the
        reference point); mass properties, grid positions, mode shapes and modal integrals are in them.
    recover_elements, recover_grids: loads recovery (:mod:`dynamics.flex.loads_recovery`): element forces
        and stresses of these CBAR/CBEAM/CROD elements and interface forces at these grids, by mode
        displacement and mode acceleration, stored for the LoadsRecovery model; the residual-vector DOFs
        are its load DOFs.
    op2: a NASTRAN OP2 file: its SOL 103 eigenvalues and eigenvectors replace our eigen-solution (the deck
        supplies geometry and the mass for normalization, mass properties and modal integrals; our own
        modes are computed too and compared), or, without eigenvectors, its KGG and MGG replace the
        assembled matrices (as ``op4``) (:mod:`dynamics.flex.op2`).
    blas_threads: BLAS threads while the pipeline runs (threadpoolctl; None = unchanged). Its
        dense products are small or memory-bound: more threads than cores thrash on a shared
        machine (a 606-DOF Craig-Bampton reduction took 20 s instead of 0.1 s).
    """

    n_modes: int | None = None
    cutoff_hz: float | None = None
    aset: list = field(default_factory=list)
    residual: list = field(default_factory=list)
    grdpnt: int | None = None
    modal_integrals: bool = False
    separate_lumped: bool = False
    damping: float | list = 0.0
    rigid_threshold_hz: float | None = None
    write_gset: bool = False
    write_fset: bool = False
    write_modal_matrix: bool = False
    allow_unsupported: bool = False
    op4: str | None = None
    blas_threads: int | None = 1
    geometric_stiffness: bool = False
    preloads: list = field(default_factory=list)
    units: str | None = None
    csid: int | None = None
    op2: str | None = None
    recover_elements: list = field(default_factory=list)
    recover_grids: list = field(default_factory=list)


def validate_options(options: Fem2ModalOptions) -> None:
    """ValueError naming the option (and its command-line flag) for values that cannot work."""
    if (options.n_modes is None) == (options.cutoff_hz is None):
        raise ValueError("give exactly one of n_modes (--modes) or cutoff_hz (--cutoff)")
    has_aset = bool(options.aset)
    if options.n_modes is not None:
        if int(options.n_modes) != options.n_modes or options.n_modes < 0:
            raise ValueError(f"--modes (n_modes) must be a whole number >= 0, got "
                             f"{options.n_modes}")
    if options.cutoff_hz is not None:
        c = float(options.cutoff_hz)
        if not np.isfinite(c) or c <= 0.0:
            raise ValueError(f"--cutoff (cutoff_hz) must be a finite frequency > 0 Hz, got "
                             f"{options.cutoff_hz}")
    d = np.asarray(options.damping, dtype=float)
    if d.ndim > 1 or not np.all(np.isfinite(d)) or np.any(d < 0.0):
        raise ValueError(f"--damping (damping) must be a finite ratio >= 0 (0.01 = 1 % of "
                         f"critical), got {options.damping}")
    if np.any(d >= 1.0):
        warnings.warn(f"--damping {options.damping}: ratios >= 1 are critically or over-damped "
                      "modes", stacklevel=3)
    t = options.rigid_threshold_hz
    if t is not None and (not np.isfinite(t) or t <= 0.0):
        raise ValueError(f"--rigid-threshold (rigid_threshold_hz) must be a finite frequency "
                         f"> 0 Hz, got {t}")
    if options.units is not None:
        parse_units(options.units)
    if options.op2 is not None and options.op4 is not None:
        raise ValueError("give one of --op2 and --op4, not both")
    if (options.recover_elements or options.recover_grids) and options.op4 is not None:
        raise ValueError("loads recovery (--recover-elements, --recover-grids) needs the deck's elements; "
                         "--op4 matrices carry none")
    if options.csid is not None and (int(options.csid) != options.csid or options.csid < 0):
        raise ValueError(f"--csid (csid) must be a coordinate system id >= 0, got {options.csid}")
    if options.n_modes == 0 and not has_aset:
        raise ValueError("--modes 0 (n_modes = 0) without an a-set leaves a free-free body with "
                         "no flexible mode: ask for at least one mode, or use a rigid body "
                         "(with --aset, --modes 0 gives the constraint modes alone)")

def parse_grid_dofs(text: str) -> tuple[int, list[int]]:
    """"GRID:DOFS" (e.g. "101:123456") -> (101, [1, 2, 3, 4, 5, 6])."""
    try:
        grid, dofs = text.split(":")
        comps = sorted({int(c) for c in dofs.strip()})
        gid = int(grid)
    except ValueError as exc:
        raise ValueError(f"expected GRID:DOFS such as 101:123456, got {text!r}") from exc
    if not comps or any(c < 1 or c > 6 for c in comps):
        raise ValueError(f"{text!r}: components must be digits 1..6")
    return gid, comps


def energy_signs(vectors: np.ndarray, stiffness_diagonal: np.ndarray) -> np.ndarray:
    """+-1 per column, so that every mode's sign is the same in any unit system.

    The eigen-solvers make the largest entry of each vector positive, which compares metres with radians,
    so the sign changed with the deck's length unit. Here the sign is that of sum_i w_i sqrt(K_ii) phi_i:
    sqrt(K_ii) phi_i has the units of sqrt(energy) on every DOF, and the fixed weights w_i = 1 + frac(0.618 i)
    (golden-ratio sequence) keep the sum from vanishing for the symmetric and antisymmetric modes of
    symmetric structures, where the largest entries tie (a plain sum would cancel, the largest entry would
    be chosen by round-off). A sum that still cancels (below 1e-8 of sum_i w_i sqrt(K_ii) |phi_i|) falls
    back to the largest weighted entry."""
    scaled = np.sqrt(np.abs(np.asarray(stiffness_diagonal, dtype=float)))[:, None] * vectors
    weights = 1.0 + np.modf(0.6180339887498949 * np.arange(len(scaled)))[0]
    total = weights @ scaled
    signs = np.where(total < 0.0, -1.0, 1.0)
    tied = np.abs(total) <= 1e-8 * (weights @ np.abs(scaled))
    if np.any(tied):
        signs[tied] = largest_entry_signs(np.ascontiguousarray(scaled[:, tied]))
    return signs


def _grid_blocks(M: sp.csr_matrix, n: int) -> tuple[np.ndarray, float]:
    """6 x 6 diagonal blocks (n,6,6) of M and the largest |entry| outside them."""
    i = np.arange(n)[:, None, None] * 6
    rows = (i + np.arange(6)[None, :, None]) + np.zeros((1, 1, 6), dtype=int)
    cols = (i + np.arange(6)[None, None, :]) + np.zeros((1, 6, 1), dtype=int)
    blocks = np.asarray(M[rows.ravel(), cols.ravel()]).reshape(n, 6, 6)
    C = M.tocoo()
    off = (C.row // 6) != (C.col // 6)
    return blocks, float(np.abs(C.data[off]).max(initial=0.0))


def node_masses(mass_lumped_basic: sp.csr_matrix, n_grids: int, context: str):
    """(m, p, J) per grid from the lumped mass matrix (basic frame, [T; R] order)."""
    B, off = _grid_blocks(mass_lumped_basic, n_grids)
    if off > 1e-12 * max(np.abs(B).max(initial=0.0), 1e-300):
        warnings.warn(f"{context}: mass matrix couples grids (largest off-block entry {off:.3e});"
                      " node masses for the modal integrals use its grid-diagonal blocks",
                      stacklevel=3)
    m = np.trace(B[:, :3, :3], axis1=1, axis2=2) / 3.0
    mp = B[:, 3:, :3]
    vee = np.stack([mp[:, 2, 1] - mp[:, 1, 2], mp[:, 0, 2] - mp[:, 2, 0],
                    mp[:, 1, 0] - mp[:, 0, 1]], axis=1) / 2.0
    p = np.divide(vee, m[:, None], out=np.zeros_like(vee), where=m[:, None] > 0)
    J = 0.5 * (B[:, 3:, 3:] + B[:, 3:, 3:].transpose(0, 2, 1))
    return m, p, J


def structural_model_from_matrices(bulk: BulkData, stiffness_g, mass_g,
                                   interface: list = ()) -> StructuralModel:
    """A :class:`StructuralModel` from given g-set K and M (e.g. OP4 KGG, MGG)."""
    ng = 6 * len(bulk.grid_ids)
    for name, M in (("stiffness", stiffness_g), ("mass", mass_g)):
        if M.shape != (ng, ng):
            raise BulkDataError(f"{bulk.path}: OP4 {name} matrix is {M.shape[0]} x {M.shape[1]}"
                                f", expected {ng} x {ng} (6 DOFs for each of the "
                                f"{len(bulk.grid_ids)} grids)")
    K = sp.csr_matrix(stiffness_g)
    M = sp.csr_matrix(mass_g)
    if not np.any(M.diagonal() > 0):
        raise BulkDataError(f"{bulk.path}: zero-mass model (OP4 mass matrix has no positive "
                            "diagonal)")
    R = block_rotation(bulk.displacement_rotation)
    sm = StructuralModel(bulk=bulk, stiffness_g=K, mass_g=M, mass_lumped_basic=(R @ M @ R.T)
                         .tocsr(), T_gf=sp.identity(ng, format="csr"), f_dofs=np.arange(ng))
    apply_constraints(sm, interface)
    sm.deck_aset = deck_aset(bulk)
    return sm


def _f_indices(sm: StructuralModel, pairs, what: str) -> tuple[np.ndarray, np.ndarray]:
    idx, uset = [], []
    for gid, comps in pairs:
        for c in comps:
            idx.append(sm.f_index(gid, c, f"{what} {gid}:{c}"))
            uset.append((gid, c))
    order = np.argsort(idx, kind="stable")
    idx = np.asarray(idx, dtype=np.int64)[order]
    uset = np.asarray(uset, dtype=np.int64).reshape(-1, 2)[order]
    if len(np.unique(idx)) != len(idx):
        idx, first = np.unique(idx, return_index=True)
        uset = uset[first]
    return idx, uset


def _uset(sm: StructuralModel, g_dofs: np.ndarray) -> np.ndarray:
    return np.stack([sm.grid_ids[g_dofs // 6], g_dofs % 6 + 1], axis=1).astype(np.int64)


def _check_central_inertia(deck, mass: float, cm: np.ndarray, inertia_ref: np.ndarray) -> None:
    """Warn when the inertia about the center of mass is singular (a straight lumped-mass line,
    a point mass): the scene accepts such a body only where no hinge needs that inertia."""
    c = np.asarray(cm, dtype=float)
    J = inertia_ref - mass * (c @ c * np.eye(3) - np.outer(c, c))
    w, V = np.linalg.eigh(0.5 * (J + J.T))
    if w[-1] > 0.0 and w[0] > 1e-9 * w[-1]:
        return
    axes = [np.round(V[:, i], 6).tolist() for i in range(3) if w[i] <= 1e-9 * max(w[-1], 0.0)]
    warnings.warn(f"{deck}: principal moments of inertia about the center of mass are "
                  f"{np.round(w, 12).tolist()} kg m^2: no rotary inertia about axis(es) {axes} "
                  "(basic frame). A free, spherical or revolute hinge about such an axis has no "
                  "inertia to act on; give the deck rotary inertia there (CONM2 I11-I33, PARAM "
                  "COUPMASS 1, or CBEAM, whose lumped mass carries the torsional moment), or "
                  "mount the body with a locked hinge", stacklevel=3)


def _check_split(deck, split: RigidSplit, flex, threshold_hz) -> None:
    """Warnings for a rigid/flexible split that the spectrum does not confirm."""
    if split.n_rigid and split.alignment < 0.999:
        # (the lowest n_rigid + n_mechanisms computed modes should contain the rigid space)
        warnings.warn(f"{deck}: the {split.n_rigid} lowest computed modes are not the "
                      f"rigid-body motions of the geometry (smallest cosine "
                      f"{split.alignment:.3g}): the structure has a zero-energy mechanism or a "
                      "flexible mode near zero frequency; the flexible set is what remains "
                      "M-orthogonal to the rigid-body motions", stacklevel=3)
    elif (split.n_rigid or split.n_mechanisms) and split.gap < 1e3:
        warnings.warn(f"{deck}: the zero-energy modes (largest "
                      f"{max(split.computed_rigid_hz, split.mechanism_hz):.3g} Hz) are within a "
                      f"factor {split.gap:.3g} of the first flexible mode "
                      f"({split.first_flexible_hz:.3g} Hz): the split is not clear-cut and the "
                      "lowest flexible frequency may be inaccurate", stacklevel=3)
    if split.n_mechanisms:
        warnings.warn(f"{deck}: {split.n_mechanisms} mechanism mode(s) (zero-energy motion that "
                      "is not a rigid-body motion, e.g. a pin or free hinge in the FE model) "
                      "removed with the rigid-body modes; a scene needs a hinge for each",
                      stacklevel=3)
    if threshold_hz is not None and len(flex.eigenvalues) and \
            flex.frequencies_hz[0] < threshold_hz:
        warnings.warn(f"{deck}: flexible mode 1 at {flex.frequencies_hz[0]:.3g} Hz is below "
                      f"--rigid-threshold {threshold_hz:g} Hz but is not a rigid-body motion of "
                      "the geometry: a mechanism (free hinge, unconnected part) or a very soft "
                      "spring", stacklevel=3)


def _interface_row(bulk, aset_pairs):
    """Row of the first a-set grid held in all six components (the frame of a preload), or None."""
    comps = {}
    for gid, cs in aset_pairs:
        comps.setdefault(int(gid), set()).update(int(c) for c in cs)
    for gid, cs in comps.items():
        if cs == {1, 2, 3, 4, 5, 6}:
            return bulk.grid_index(gid, "a-set grid")
    return None


class _Progress:
    """Progress messages stamped with the wall and CPU time since the start, and the CPU time
    of the pipeline's steps (a step lasts until the next one starts), summed up at the end."""

    def __init__(self, sink):
        self.sink = sink
        self.wall0, self.cpu0 = time.perf_counter(), time.process_time()
        self.steps = []

    def __call__(self, message: str) -> None:
        if self.sink is not None:
            self.sink(f"[{time.perf_counter() - self.wall0:7.2f} s, CPU "
                      f"{time.process_time() - self.cpu0:7.2f} s] {message}")

    def step(self, name: str, message: str) -> None:
        self.steps.append((name, time.process_time()))
        self(message)

    def summary(self) -> str:
        end = time.process_time()
        marks = self.steps + [("", end)]
        parts = [f"{name} {b - a:.2f} s" for (name, a), (_, b) in zip(marks, marks[1:])]
        return (f"CPU time by step: {', '.join(parts)}; total {end - self.cpu0:.2f} s")


def fem2modal(deck: str, options: Fem2ModalOptions, progress=None) -> ModalBody:
    """Run the pipeline on ``deck``; ``progress(message)`` receives step messages, each
    stamped with the wall and CPU time since the start, and a last one with the CPU time of
    every step."""
    say = _Progress(progress)
    validate_options(options)
    if options.blas_threads is None:
        return _fem2modal(deck, options, say)
    from threadpoolctl import threadpool_limits
    with threadpool_limits(limits=options.blas_threads, user_api="blas"):
        return _fem2modal(deck, options, say)


def _fem2modal(deck: str, options: Fem2ModalOptions, say: _Progress) -> ModalBody:
    say.step("read", f"reading {deck}")
    bulk = read_bulk_data(deck, allow_unsupported=options.allow_unsupported)
    say(f"{len(bulk.grid_ids)} grids; " + "; ".join(bulk.report.lines()))
    units = parse_units(options.units) if options.units is not None else SI
    _check_densities(bulk, units, options.units is not None)
    op2 = None
    if options.op2:
        from dynamics.flex.op2 import read_op2_results
        op2 = read_op2_results(options.op2)
        if op2.has_modes:
            for flag, given in (("--aset (and the deck's ASET)", options.aset or deck_aset(bulk)),
                                ("--residual", options.residual), ("--separate-lumped", options.separate_lumped)):
                if given:
                    raise ValueError(f"{options.op2}: NASTRAN's modes (--op2 with eigenvectors) are the deck's normal "
                                     f"modes; {flag} needs our own eigen-solution: leave out --op2 or {flag}")
    if options.op4 or (op2 is not None and not op2.has_modes):
        source = options.op4 or options.op2
        if options.op4:
            from dynamics.flex.op4 import read_op4_matrices
            mats = read_op4_matrices(options.op4)
        else:
            mats = op2.matrices
        missing = [n for n in ("KGG", "MGG") if n not in mats]
        if missing:
            raise BulkDataError(f"{source}: matrices {missing} not found (has "
                                f"{sorted(mats)})")
        if options.separate_lumped:
            raise ValueError("separate_lumped needs the deck's CONM2 cards, not OP2/OP4 matrices")
        sm = structural_model_from_matrices(bulk, mats["KGG"], mats["MGG"], options.aset)
        say(f"matrices KGG, MGG from {source}")
    else:
        say.step("assembly", "assembling the structural matrices")
        sm = assemble(bulk, separate_lumped=options.separate_lumped, progress=say,
                      interface=options.aset)
    say(f"g-set {sm.stiffness_g.shape[0]} DOFs, f-set {len(sm.f_dofs)} DOFs "
        f"(RBE2/RBE3 dependent {sm.rbe2_dependent_count}, SPC + PS {sm.spc_count}, "
        f"AUTOSPC {sm.autospc_count})")
    K = sm.stiffness_f()
    M = sm.mass_f()
    n_massless = int(np.sum(massless_dofs(M)))
    if n_massless:
        say(f"{n_massless} f-set DOFs carry no mass (e.g. lumped-mass rotations): dense solves "
            "condense them statically, the shift-invert Lanczos never returns their infinite "
            "eigenvalues")
    if sm.mechanisms:
        say(f"massless mechanisms held (AUTOSPC): {', '.join(sm.mechanisms)}")
    rigid_geometry = sm.rigid_body_vectors(K, M)

    aset_pairs = list(sm.deck_aset) + list(options.aset)
    cb_data = None
    quasi_static = EigenSolution(np.zeros(0), np.zeros((K.shape[0], 0)))
    n_rigid = 0
    rigid_vectors = None
    if aset_pairs:
        b_idx, b_uset = _f_indices(sm, aset_pairs, "a-set grid")

        def describe(f):
            g = sm.f_dofs[f]
            return f"grid {sm.grid_ids[g // 6]} component {g % 6 + 1}"
        say.step("eigen-solution", f"Craig-Bampton reduction, a-set {len(b_idx)} DOFs")
        cb = craig_bampton(K, M, b_idx, n_modes=options.n_modes, cutoff_hz=options.cutoff_hz,
                           describe=describe, groups=sm.f_dofs // 6)
        signs = np.ones(cb.mass.shape[0])
        signs[:cb.n_modes] = energy_signs(cb.fixed_interface.vectors, K.diagonal()[cb.interior])
        cb_data = CraigBamptonData(frequencies_hz=cb.fixed_interface.frequencies_hz,
                                   mass=signs[:, None] * cb.mass * signs,
                                   stiffness=signs[:, None] * cb.stiffness * signs,
                                   uset=b_uset)
        component = normalized_component_modes(cb, rigid_geometry)
        rigid, flex, split = component.rigid, component.flexible, component.split
        quasi_static = component.quasi_static
        if component.n_massless_rigid:
            say(f"{component.n_massless_rigid} massless rigid motion(s) of the Craig-Bampton basis removed (no mass "
                "and no stiffness: e.g. a lumped-mass CBAR line spinning about its axis, which the interface carries)")
        if len(quasi_static.eigenvalues):
            say(f"{len(quasi_static.eigenvalues)} quasi-static mode(s) kept: directions of the Craig-Bampton basis "
                "with stiffness and no mass (the constraint mode of a massless interface DOF, e.g. a beam-end "
                "rotation with lumped mass); the bodies attached at the interface give them inertia. They are the "
                "last modes of the body (infinite frequency, zero modal mass) and need the engine's dense solver")
        mode_set = "normalized-component"
        grids = sorted({int(g) for g in b_uset[:, 0]})
        say("normalized component modes: their frequencies below are those of the free, "
            "unmounted component, not of the body once a hinge holds it; the fixed-interface "
            "frequencies (a-set held) are " + ", ".join(
                f"{f:.6g}" for f in cb.fixed_interface.frequencies_hz[:6]) + " Hz. Mount the "
            f"body with child_grid = one of the interface grids {grids} on a hinge that holds "
            "it (not a free hinge)")
    elif op2 is not None and op2.has_modes:
        from dynamics.flex.op2 import modes_on_fset
        say.step("eigen-solution", f"NASTRAN's modes from {options.op2}")
        b_uset = np.zeros((0, 2), dtype=np.int64)
        nastran = modes_on_fset(op2, sm, K, M, rigid_geometry, options.n_modes, options.cutoff_hz)
        for line in nastran.report:
            say(line)
            bulk.report.notes.append(line)
        rigid = EigenSolution(np.zeros(nastran.n_rigid), np.zeros((K.shape[0], nastran.n_rigid)))
        flex = EigenSolution(nastran.eigenvalues, nastran.vectors)
        mode_set = "free-free"
        say.step("our own modes", "our own modes of the deck, for comparison")
        # four more of ours than NASTRAN's: a degenerate pair split at the end of NASTRAN's set stays in our span
        _, own, _ = free_free_modes(K, M, n_modes=len(flex.eigenvalues) + 4, rigid_vectors=rigid_geometry,
                                    groups=sm.f_dofs // 6)
        line = _compare_with_own_modes(flex, own, M)
        say(line)
        bulk.report.notes.append(line)
        if "WARNING" in line:
            warnings.warn(f"{deck}: {line}", stacklevel=3)
    else:
        say.step("eigen-solution", "free-free normal modes (block shift-invert Lanczos)")
        b_uset = np.zeros((0, 2), dtype=np.int64)
        rigid, flex, split = free_free_modes(K, M, n_modes=options.n_modes,
                                             cutoff_hz=options.cutoff_hz,
                                             rigid_vectors=rigid_geometry,
                                             groups=sm.f_dofs // 6, progress=say)
        mode_set = "free-free"
    n_rigid = len(rigid.eigenvalues)
    rigid_vectors = rigid.vectors if n_rigid else None
    if op2 is None or not op2.has_modes:
        say(f"{len(flex.eigenvalues)} flexible modes, {n_rigid} rigid-body and mechanism modes "
            "removed: " + split.line())
        _check_split(deck, split, flex, options.rigid_threshold_hz)

    n_residual = 0
    res_uset = np.zeros((0, 2), dtype=np.int64)
    if options.residual and len(quasi_static.eigenvalues):
        raise ValueError(f"{deck}: residual vectors with quasi-static modes (massless interface DOFs) are not "
                         "supported: give the interface DOFs mass (PARAM COUPMASS 1, CONM2 inertia) or leave out "
                         "--residual")
    if options.residual:
        r_idx, res_uset = _f_indices(sm, options.residual, "residual-vector grid")
        say.step("residual vectors", f"residual vectors for {len(r_idx)} load DOFs")
        res = residual_vectors(K, M, flex.vectors, r_idx, rigid_vectors)
        n_residual = len(res.eigenvalues)
        flex = append_residual_vectors(K, M, flex, res)

    if len(quasi_static.eigenvalues):
        flex = EigenSolution(np.concatenate([flex.eigenvalues, quasi_static.eigenvalues]),
                             np.hstack([flex.vectors, quasi_static.vectors]))
    if op2 is None or not op2.has_modes:       # NASTRAN's modes keep NASTRAN's signs
        flex.vectors *= energy_signs(flex.vectors, K.diagonal())
    n = len(flex.eigenvalues)
    damping = np.broadcast_to(np.asarray(options.damping, dtype=float), (n,)).copy() \
        if np.ndim(options.damping) == 0 else np.asarray(options.damping, dtype=float)
    if damping.shape != (n,):
        raise ValueError(f"damping: {len(damping)} ratios given for {n} modes")
    omega = np.sqrt(np.maximum(flex.eigenvalues, 0.0))
    omega[np.isinf(omega)] = 0.0           # quasi-static modes: no mass, no modal damping

    # physical shapes: f -> g (CD frames) -> basic, rows [rotation; translation] per grid
    say.step("mode shapes", "mode shapes per grid")
    phi_g = sm.T_gf @ flex.vectors
    N = sm.n_grids
    Rcd = bulk.displacement_rotation
    blocks = phi_g.reshape(N, 6, n)
    trans = np.einsum("nab,nbk->nak", Rcd, blocks[:, :3])
    rot = np.einsum("nab,nbk->nak", Rcd, blocks[:, 3:])

    grdpnt = options.grdpnt if options.grdpnt is not None else bulk.grdpnt
    if grdpnt:
        ref_point = bulk.positions[bulk.grid_index(int(grdpnt), "GRDPNT")]
    else:
        grdpnt, ref_point = 0, np.zeros(3)
    say.step("mass properties", "rigid-body mass properties")
    rbp = rigid_body_mass_properties(sm.mass_g, bulk.positions, Rcd, ref_point, grdpnt)
    nm, npos, nJ = node_masses(sm.mass_lumped_basic, N, bulk.path)
    l0 = bulk.positions - ref_point

    gs = None
    if options.geometric_stiffness or options.preloads:
        from dynamics.flex.geometric_stiffness import geometric_stiffness
        say.step("geometric stiffness", "geometric stiffness of the rigid-motion load cases"
            + (f" and preloads {sorted({p[0] for p in options.preloads})}" if options.preloads else ""))
        gs = geometric_stiffness(sm, K, M, _grid_blocks(sm.mass_lumped_basic, N)[0], l0, rot, trans,
                                 held=b_idx if aset_pairs else None, rigid_vectors=rigid_geometry,
                                 preloads=_preloads_in_deck_units(options.preloads, units), context=str(deck),
                                 interface_row=_interface_row(bulk, aset_pairs))
        say(f"geometric stiffness: {gs.elements}, reaction {gs.reaction}")

    say.step("modal matrices", "modal mass and stiffness, body record")
    Mr = flex.vectors.T @ (M @ flex.vectors)
    Kr = flex.vectors.T @ (K @ flex.vectors)
    body = ModalBody(
        source=str(deck), mode_set=mode_set, reference_grid=int(grdpnt),
        reference_point=ref_point, mass=rbp.mass, cm_offset=rbp.cm_offset,
        inertia=rbp.inertia, frequencies_hz=flex.frequencies_hz, n_rigid_modes_removed=n_rigid,
        n_residual_vectors=n_residual, grid_ids=bulk.grid_ids.copy(), grid_positions=l0,
        rotation_shapes=rot, translation_shapes=trans, node_mass=nm, node_cm_offset=npos,
        node_inertia=nJ, modal_mass=0.5 * (Mr + Mr.T), modal_stiffness=0.5 * (Kr + Kr.T),
        modal_damping=np.diag(2.0 * damping * omega), damping_ratios=damping,
        craig_bampton=cb_data, geometric_stiffness=gs, n_quasi_static=len(quasi_static.eigenvalues),
        gset=SparseModel(sm.mass_g, sm.stiffness_g, _uset(sm, np.arange(6 * N)))
        if options.write_gset else None,
        fset=SparseModel(M, K, _uset(sm, sm.f_dofs)) if options.write_fset else None,
        modal_matrix=phi_g if options.write_modal_matrix else None,
        aset=b_uset, residual_dofs=res_uset,
        child_bodies=[ChildRigidBody(lm.element_id, lm.grid_id, lm.mass,
                                     lm.cg_basic - bulk.positions[bulk.grid_index(lm.grid_id,
                                                                                  "CONM2")],
                                     lm.inertia_cg) for lm in sm.lumped_masses],
        card_report=bulk.report.lines())
    body.element_types, body.element_grids = elements_of_deck(bulk.model)
    if options.recover_elements or options.recover_grids:
        from dynamics.flex.loads_recovery import loads_recovery
        say.step("loads recovery", f"loads recovery of elements {list(options.recover_elements)} and grids "
                 f"{list(options.recover_grids)}")
        reference_row = None
        if aset_pairs:
            reference_row = _interface_row(bulk, aset_pairs)
            if reference_row is None or len({int(g) for g, _ in aset_pairs}) != 1:
                raise ValueError(f"{deck}: loads recovery by mode acceleration needs the body held at one interface "
                                 f"grid in all six components (the a-set is {sorted({int(g) for g, _ in aset_pairs})})")
        body.loads_recovery = loads_recovery(
            sm, K, M, flex.vectors, options.recover_elements, options.recover_grids,
            held=b_idx if aset_pairs else None, rigid_vectors=rigid_geometry, reference_row=reference_row,
            reference_point=ref_point, load_dofs=[tuple(int(v) for v in row) for row in res_uset])
        say(f"loads recovery: {body.loads_recovery.n_outputs} outputs, reaction {body.loads_recovery.reaction}")
    if options.units is not None or options.csid:
        axes = _output_axes(bulk, options.csid)
        say.step("units and axes", f"body expressed in SI from {units.describe()}"
                 + (f", in the axes of CSID {options.csid}" if options.csid else ""))
        body = express_body(body, units, axes)
        body.output_csid, body.output_axes = int(options.csid or 0), axes
        if options.units is not None:
            body.deck_units = {"spec": units.spec, "length": units.length, "mass": units.mass,
                               "time": units.time, "force": units.force, "wtmass": bulk.wtmass}
    _check_central_inertia(deck, body.mass, body.cm_offset, body.inertia)
    if options.modal_integrals:
        say.step("modal integrals", "modal integrals (TM App. E)")
        body.modal_integrals = modal_integrals(body.node_mass, body.node_cm_offset, body.node_inertia,
                                               body.grid_positions, body.rotation_shapes, body.translation_shapes)
        body.point_mass_integrals = point_mass_integrals(body.node_mass, body.grid_positions,
                                                         body.translation_shapes)
    say("done; " + say.summary())
    return body


# NASTRAN's modes against ours: frequencies within this relative difference and MAC above this value, else a
# warning (single-precision OP2 vectors and NASTRAN's own elements, e.g. a different drilling stiffness, move
# frequencies by far less on the decks whose elements we share with NASTRAN: tests/flex/test_op2.py)
OWN_MODES_RTOL, OWN_MODES_MAC = 1e-2, 0.99


def _compare_with_own_modes(nastran: EigenSolution, own: EigenSolution, M) -> str:
    """One line comparing NASTRAN's modes with ours: frequency differences, and the part of each NASTRAN mode in
    the span of our modes (the sum of its M-weighted modal assurance criteria with each of ours: 1 when our
    modes contain it; a sum rather than the largest single MAC, since degenerate pairs come out in any basis)."""
    n = min(len(nastran.eigenvalues), len(own.eigenvalues))
    fn, fo = nastran.frequencies_hz[:n], own.frequencies_hz[:n]
    C = nastran.vectors[:, :n].T @ (M @ own.vectors)
    mac = np.sum(C ** 2, axis=1)
    worst = float(np.max(np.abs(fn / fo - 1.0)))
    line = (f"check against our own FE of the deck: {n} frequencies within {worst:.2e} (relative), every NASTRAN "
            f"mode in the span of our modes to {mac.min():.6f} (sum of modal assurance criteria)")
    if worst > OWN_MODES_RTOL or mac.min() < OWN_MODES_MAC:
        line = "WARNING: " + line + (f"; outside {OWN_MODES_RTOL:g} / {OWN_MODES_MAC:g}: NASTRAN's model and ours "
                                     "differ (elements, constraints, mass)")
    return line


def _output_axes(bulk: BulkData, csid) -> np.ndarray:
    """Axes (columns, basic) of the output coordinate system ``csid`` (0 / None: basic); a cylindrical or
    spherical system, whose axes depend on the point, is refused."""
    if not csid:
        return np.eye(3)
    _, axes, kind = coordinate_axes(bulk.model, int(csid), f"{bulk.path}: --csid {csid}")
    if kind != "R":
        raise BulkDataError(f"{bulk.path}: --csid {csid} is a {'cylindrical' if kind == 'C' else 'spherical'} "
                            "system; the body frame needs fixed axes: give a rectangular system (CORD1R/CORD2R)")
    return np.asarray(axes, dtype=float)


def _preloads_in_deck_units(preloads, units: DeckUnits) -> list:
    """``--preload`` entries (SI: N for components 1-3, N m for 4-6) in the deck's force and moment units."""
    return [(name, grid, comp, value / (units.force if comp <= 3 else units.force * units.length))
            for name, grid, comp, value in preloads]


# A MAT density (times WTMASS) outside this range in kg/m^3 is no engineering material (osmium, the densest
# element, is 22,590 kg/m^3; rigid foams start near 10): the deck's units are probably not the ones assumed.
PLAUSIBLE_DENSITY = (1.0, 3.0e4)


def _check_densities(bulk: BulkData, units: DeckUnits, declared: bool) -> None:
    """Warn about material densities that are implausible in SI once WTMASS and the deck's units are
    applied: an inch-pound deck read as SI (0.283, 7.3e-4), a mm-tonne deck (7.8e-9), WTMASS missing."""
    odd = []
    for mid, mat in sorted(bulk.model.materials.items()):
        rho = float(getattr(mat, "rho", 0.0) or 0.0)
        if rho > 0.0:
            si = units.density(rho * bulk.wtmass)
            if not PLAUSIBLE_DENSITY[0] <= si <= PLAUSIBLE_DENSITY[1]:
                odd.append(f"{mat.type} {mid} rho = {rho:g} -> {si:.4g} kg/m^3")
    if not odd:
        return
    system = (f"the deck's units {units.spec} (--units)" if declared else "SI (no --units given)")
    warnings.warn(f"{bulk.path}: material densities taken with PARAM WTMASS = {bulk.wtmass:g} in {system} are "
                  f"not those of an engineering material ({', '.join(odd[:4])}{' ...' if len(odd) > 4 else ''}; "
                  f"plausible {PLAUSIBLE_DENSITY[0]:g} - {PLAUSIBLE_DENSITY[1]:g} kg/m^3): check --units (e.g. "
                  "in,lbf,s; mm,N,s) and PARAM WTMASS (1/386.0886 for densities in lbm/in^3)", stacklevel=3)
