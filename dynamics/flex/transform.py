"""A :class:`~dynamics.flex.body_file.ModalBody` computed in the deck's units and basic axes, expressed
in SI (``--units``) and in the axes of an output coordinate system (``--csid``).

Units (:mod:`dynamics.flex.units`: SI = deck x factor; l, mu, tau, f the length, mass, time and
force factors, f = mu l / tau^2). A physical displacement vector scales by D = diag(l on
translations, 1 on rotations); energies by f l. Hence the physical matrices (G-set, F-set, in CD
frames) K_SI = f l D^-1 K D^-1 and M_SI = mu l^2 D^-1 M D^-1. A modal coordinate of a
mass-normalized mode scales by c = l sqrt(mu) (phi' M phi = 1 in both systems), so translation
shapes scale by l / c = 1/sqrt(mu), rotation shapes by 1/c, the modal stiffness by
f l / c^2 = 1/tau^2, the modal damping by 1/tau and frequencies by 1/tau. Craig-Bampton coordinates
are [fixed-interface modal (c); a-set physical (D)] and scale the same way. The modal geometric
stiffness (per unit load scale, TM-free: :mod:`dynamics.flex.geometric_stiffness`) of the
translational cases scales by mu l / c^2 = 1/l, of the rotational and angular-velocity cases by
mu l^2 / c^2 = 1, of the named preloads like the modal stiffness. Modal integrals are not converted
here: the pipeline computes them from the expressed body.

Axes: R (3 x 3) holds the output system's axes in basic as columns, v_out = R' v_basic. Every
body-frame vector (CG, grid positions, mode shapes, node CG offsets, child CG offsets) is rotated,
every inertia becomes R' J R; the load cases of the geometric stiffness are re-taken along the
output axes (translation and rotation case k' = sum_j R[j, k'] case j; the angular-velocity
products as the symmetric tensor R' W R). NASTRAN-set quantities (G-set, F-set, modal matrix,
Craig-Bampton interface DOFs) stay in the grids' CD frames, as in NASTRAN. The reference point
stays in basic coordinates (it says where the body frame's origin is in the deck).
"""

from __future__ import annotations

import dataclasses

import numpy as np
import scipy.sparse as sp

from dynamics.flex.body_file import ChildRigidBody, CraigBamptonData, ModalBody, SparseModel
from dynamics.flex.geometric_stiffness import OMEGA_PAIRS, GeometricStiffness
from dynamics.flex.units import SI, DeckUnits


def _component_scale(uset: np.ndarray, length: float) -> np.ndarray:
    """D for DOFs named by (grid, component): the length factor on components 1-3, 1 on 4-6."""
    comps = np.asarray(uset, dtype=np.int64).reshape(-1, 2)[:, 1]
    return np.where(comps <= 3, length, 1.0)


def _scale_physical(s: SparseModel | None, u: DeckUnits) -> SparseModel | None:
    if s is None:
        return None
    Dinv = sp.diags(1.0 / _component_scale(s.uset, u.length))
    return SparseModel(mass=(u.mass * u.length ** 2 * (Dinv @ s.mass @ Dinv)).tocsr(),
                       stiffness=(u.force * u.length * (Dinv @ s.stiffness @ Dinv)).tocsr(), uset=s.uset)


def _rotate_cases(cases: np.ndarray, R: np.ndarray) -> np.ndarray:
    return np.einsum("jk,jrs->krs", R, cases)


def _rotate_omega_products(products: np.ndarray, R: np.ndarray) -> np.ndarray:
    W = np.zeros((3, 3) + products.shape[1:])
    for p, (a, b) in enumerate(OMEGA_PAIRS):
        W[a, b] = W[b, a] = products[p]
    W = np.einsum("ac,bd,abrs->cdrs", R, R, W)
    return np.stack([W[a, b] for a, b in OMEGA_PAIRS])


def _loads_recovery(lr, u: DeckUnits, R: np.ndarray, c: np.ndarray):
    """The recovery matrices in SI and the output axes: each row scales by its quantity's factor (force f,
    moment f l, stress f / l^2), the modal columns by 1 / c, the reference-acceleration columns per SI unit
    of angular (1/tau^2) and linear (l/tau^2) acceleration, the load columns per SI force or moment of their
    CD component; interface forces (basic rows) and the reference acceleration (basic columns) turn with R."""
    from dynamics.flex.loads_recovery import DIMENSIONS, LoadsRecovery

    L, mu, tau = u.length, u.mass, u.time
    row = np.array([L ** a * mu ** b * tau ** t for a, b, t in (DIMENSIONS[k] for k in lr.kinds)])
    S = lr.reference_acceleration * row[:, None] * np.r_[np.full(3, tau ** 2), np.full(3, tau ** 2 / L)]
    S = np.hstack([S[:, :3] @ R, S[:, 3:] @ R])
    load_unit = np.where(np.asarray(lr.load_dofs, dtype=np.int64).reshape(-1, 2)[:, 1] <= 3, u.force,
                         u.force * L)
    rows = {name: k for k, name in enumerate(lr.names)}
    out = LoadsRecovery(names=list(lr.names), kinds=list(lr.kinds),
                        mode_displacement=lr.mode_displacement * row[:, None] / c, reference_acceleration=S,
                        reaction=lr.reaction, reference_grid=lr.reference_grid, load_dofs=lr.load_dofs,
                        loads=lr.loads * row[:, None] / load_unit)
    for name, k in rows.items():           # interface forces: [F; M] triples in basic rows -> output axes
        if name.startswith("GRID ") and name.endswith(" FX"):
            for arrays in (out.mode_displacement, out.reference_acceleration, out.loads):
                arrays[k:k + 3] = R.T @ arrays[k:k + 3]
                arrays[k + 3:k + 6] = R.T @ arrays[k + 3:k + 6]
    return out


def express_body(body: ModalBody, units: DeckUnits = SI, axes: np.ndarray | None = None,
                 coordinate_scale: np.ndarray | None = None) -> ModalBody:
    """``body`` (deck units, basic axes) in SI and in the output ``axes`` (columns in basic; None =
    basic). ``coordinate_scale``: SI per deck unit of each modal coordinate (default l sqrt(mu), the
    mass-normalized modes'). The body must not carry modal integrals yet (they are computed from the
    result)."""
    if body.modal_integrals is not None or body.point_mass_integrals is not None:
        raise ValueError("express_body: compute the modal integrals after expressing the body")
    L, mu, tau, f = units.length, units.mass, units.time, units.force
    R = np.eye(3) if axes is None else np.asarray(axes, dtype=float)
    n = body.n_modes
    c = np.full(n, L * np.sqrt(mu)) if coordinate_scale is None else np.asarray(coordinate_scale, float)

    def vec(v):                 # (..., 3) body-frame vectors
        return np.asarray(v) @ R

    def inertia(J):             # (..., 3, 3)
        return np.einsum("ab,...bc,cd->...ad", R.T, np.asarray(J), R)

    def shapes(s, factor):      # (N, 3, n)
        return np.einsum("ba,nbk->nak", R, np.asarray(s)) * (factor / c)

    pair = np.outer(c, c)
    cb = body.craig_bampton
    if cb is not None:
        m = len(cb.frequencies_hz)
        S = np.concatenate([np.full(m, L * np.sqrt(mu)), _component_scale(cb.uset, L)])
        cb = CraigBamptonData(frequencies_hz=cb.frequencies_hz / tau,
                              mass=mu * L ** 2 * cb.mass / np.outer(S, S),
                              stiffness=f * L * cb.stiffness / np.outer(S, S), uset=cb.uset)
    gs = body.geometric_stiffness
    if gs is not None:
        gs = GeometricStiffness(
            reaction=gs.reaction, translation=_rotate_cases(gs.translation, R) * (mu * L / pair),
            rotation=_rotate_cases(gs.rotation, R) * (mu * L ** 2 / pair),
            angular_velocity=_rotate_omega_products(gs.angular_velocity, R) * (mu * L ** 2 / pair),
            preload_names=list(gs.preload_names),
            preload=None if gs.preload is None else gs.preload * (f * L / pair), elements=gs.elements)
    lr = body.loads_recovery
    if lr is not None:
        lr = _loads_recovery(lr, units, R, c)
    modal_matrix = body.modal_matrix
    if modal_matrix is not None:
        rows = np.tile(np.r_[np.full(3, L), np.ones(3)], len(body.grid_ids))
        modal_matrix = modal_matrix * rows[:, None] / c[None, :]
    return dataclasses.replace(
        body,
        reference_point=np.asarray(body.reference_point) * L,
        mass=body.mass * mu, cm_offset=vec(body.cm_offset) * L, inertia=inertia(body.inertia) * mu * L ** 2,
        frequencies_hz=np.asarray(body.frequencies_hz) / tau,
        grid_positions=vec(body.grid_positions) * L,
        rotation_shapes=shapes(body.rotation_shapes, 1.0), translation_shapes=shapes(body.translation_shapes, L),
        node_mass=np.asarray(body.node_mass) * mu, node_cm_offset=vec(body.node_cm_offset) * L,
        node_inertia=inertia(body.node_inertia) * mu * L ** 2,
        modal_mass=np.asarray(body.modal_mass) * (mu * L ** 2 / pair),
        modal_stiffness=np.asarray(body.modal_stiffness) * (f * L / pair),
        modal_damping=np.asarray(body.modal_damping) * (f * L * tau / pair),
        craig_bampton=cb, geometric_stiffness=gs,
        gset=_scale_physical(body.gset, units), fset=_scale_physical(body.fset, units), modal_matrix=modal_matrix,
        loads_recovery=lr,
        child_bodies=[ChildRigidBody(ch.element_id, ch.grid_id, ch.mass * mu, vec(ch.cm_offset) * L,
                                     inertia(ch.inertia) * mu * L ** 2) for ch in body.child_bodies])
