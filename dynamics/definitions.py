"""Body and node definitions and their checks: what :class:`dynamics.Multibody` collects and compiles.

Everything a user can get wrong about one body, hinge or node (masses, inertias, axes, frames, prescribed
flags) is checked here, once, and refused with a :class:`dynamics.errors.ModelDefinitionError` that names
it; the builder, run-time reconfiguration (:mod:`dynamics.reconfigure`) and in-place mass changes
(:meth:`dynamics.MultibodySystem.set_mass_properties`) all use these checks.
"""

from __future__ import annotations

import difflib
from dataclasses import dataclass

import numpy as np

from dynamics.errors import ModelDefinitionError
from dynamics.hinges import FREE, HINGE_TYPES, HINGES, LOCKED
from dynamics.spatial import quaternion_to_rotation

_UNIT_TOLERANCE = 1e-9
_ROTATION_TOLERANCE = 1e-9


@dataclass
class BodyDefinition:
    name: str
    parent: str | None
    mass: float
    com: np.ndarray
    inertia: np.ndarray
    hinge: str
    axes: np.ndarray
    inboard_position: np.ndarray
    inboard_rotation: np.ndarray
    outboard_position: np.ndarray
    outboard_rotation: np.ndarray
    prescribed: np.ndarray
    joint_name: str
    parent_node: str | None = None
    flexible: object | None = None  # dynamics.flexible_body.FlexibleBodyData
    locked_from: tuple | None = None  # the hinge a run-time lock replaced (dynamics.reconfigure)
    outboard_node: str | None = None  # node of this (flexible) body carrying the hinge's outboard frame
    auto_order: object | None = None  # order="auto": (order, omit) -> FlexibleBodyData (dynamics.modal_order)


@dataclass
class NodeDefinition:
    name: str
    body: str
    position: np.ndarray
    rotation: np.ndarray
    shape: np.ndarray | None = None  # (6, n) mode shapes Pi = [lambda; gamma] on a flexible body
    grid: int | None = None



def suggest(name, candidates):
    """" Did you mean 'x'?" for the closest of ``candidates``, or an empty string."""
    close = difflib.get_close_matches(str(name), [str(c) for c in candidates], n=1)
    return f" Did you mean '{close[0]}'?" if close else ""


def vector3(value, what):
    try:
        v = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ModelDefinitionError(f"{what}: expected 3 numbers, got {value!r}") from exc
    if v.shape != (3,) or not np.all(np.isfinite(v)):
        raise ModelDefinitionError(f"{what}: expected 3 finite numbers, got {value!r}")
    return v


def rotation_matrix(value, what):
    """A 3x3 proper rotation matrix, or a unit quaternion [w, x, y, z]; None means identity."""
    if value is None:
        return np.eye(3)
    try:
        a = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ModelDefinitionError(f"{what}: expected a 3x3 rotation matrix or a quaternion [w, x, y, z], "
                                   f"got {value!r}") from exc
    if a.shape == (4,):
        norm = np.linalg.norm(a)
        if not np.isfinite(norm) or abs(norm - 1.0) > _UNIT_TOLERANCE:
            raise ModelDefinitionError(f"{what}: quaternion {a.tolist()} has norm {norm:.12g}, expected 1")
        R = np.empty((3, 3))
        quaternion_to_rotation(a[0], a[1], a[2], a[3], R)
        return R
    if a.shape != (3, 3) or not np.all(np.isfinite(a)):
        raise ModelDefinitionError(f"{what}: expected a 3x3 rotation matrix or a quaternion [w, x, y, z], "
                                   f"got shape {a.shape}")
    orth = np.abs(a @ a.T - np.eye(3)).max()
    if orth > _ROTATION_TOLERANCE or np.linalg.det(a) < 0.0:
        raise ModelDefinitionError(f"{what}: not a proper rotation matrix (|R R^T - I| = {orth:.3g}, "
                                   f"det = {np.linalg.det(a):.6g})")
    return a


def checked_inertia(inertia, where, code=FREE, hinge_axes=None, prescribed=None, mass=1.0, com=None,
                   hinge_point=None, R_BM=None):
    """The inertia about the center of mass as a symmetric 3x3 matrix. Positive definite is always
    accepted. Positive semi-definite (a point mass, a line of point masses: no rotary inertia about some
    axis) is accepted where the hinge never needs it: a locked, prismatic or fully prescribed hinge, a
    revolute or U-joint whose axes see a positive moment of inertia about the hinge point
    (``a' (J + m (|d|^2 I - d d')) a``, d = com - hinge point), a spherical hinge whose inertia about the
    hinge point is positive definite; refused with the axes it lacks otherwise (always on a free hinge)."""
    try:
        J = np.asarray(inertia, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ModelDefinitionError(f"{where}: inertia must be a 3x3 matrix, got {inertia!r}") from exc
    if J.shape == (3,):
        J = np.diag(J)
    if J.shape != (3, 3) or not np.all(np.isfinite(J)):
        raise ModelDefinitionError(f"{where}: inertia must be a finite 3x3 matrix (or 3 principal "
                                   f"moments), got shape {J.shape}")
    scale = max(np.abs(J).max(), 1e-300)
    if np.abs(J - J.T).max() > 1e-12 * scale:
        raise ModelDefinitionError(f"{where}: inertia matrix is not symmetric: {J.tolist()}")
    J = 0.5 * (J + J.T)
    eig, vectors = np.linalg.eigh(J)
    if eig[0] <= 0.0:
        d = (np.zeros(3) if com is None else com) - (np.zeros(3) if hinge_point is None else hinge_point)
        about_hinge = J + mass * (d @ d * np.eye(3) - np.outer(d, d))
        tol = 1e-12 * max(np.abs(about_hinge).max(), mass * (d @ d), 1e-300)
        if eig[0] < -1e-12 * scale:
            raise ModelDefinitionError(
                f"{where}: inertia about the center of mass must be positive semi-definite; principal "
                f"moments are {eig.tolist()} kg m^2")
        null = [np.round(vectors[:, k], 12).tolist() for k in range(3) if eig[k] <= 1e-12 * scale]
        fully_prescribed = prescribed is not None and len(prescribed) > 0 and all(prescribed)
        rotation = HINGES[code].rotation
        if rotation == "none" or fully_prescribed:
            ok = True
        elif rotation == "axes":
            R = np.eye(3) if R_BM is None else R_BM
            ok = all((R @ a) @ about_hinge @ (R @ a) > tol for a in hinge_axes[:HINGES[code].n_axes])
        elif rotation == "point":
            ok = np.linalg.eigvalsh(about_hinge)[0] > tol
        else:
            ok = False
        if not ok:
            need = (f"a {HINGES[code].name} hinge turns the body about its center of mass: it needs rotary inertia "
                    "about every axis" if rotation == "free" else f"its {HINGES[code].name} hinge turns it about an "
                    "axis without inertia about the hinge point")
            raise ModelDefinitionError(
                f"{where}: {need}; principal moments about the center of mass are {eig.tolist()} kg m^2, "
                f"none about {null} (body axes). Give the body rotary inertia there (in an FE deck: "
                f"CONM2 I11-I33, PARAM COUPMASS 1 or CBEAM elements), or use a hinge that does not turn "
                f"about that axis")
        return J
    if eig[0] + eig[1] < eig[2] * (1.0 - 1e-9):  # refused, not warned: shell/diagnostics.py says why
        raise ModelDefinitionError(
            f"{where}: principal moments {eig.tolist()} kg m^2 violate the triangle inequality I1 + I2 >= I3 "
            "that every mass distribution satisfies (I1 + I2 - I3 is twice the integral of z^2 dm): no body "
            "has this inertia. Check the values and their axes (a wheel or disk of spin inertia Is has "
            "transverse inertia of at least Is/2)")
    return J

def checked_axes(code, axis, axes, where):
    naxes = HINGES[code].n_axes
    name = HINGES[code].name
    result = np.zeros((2, 3))
    if naxes == 0:
        if axis is not None or axes is not None:
            raise ModelDefinitionError(f"{where}: a {name} hinge takes no axis")
        return result
    if naxes == 1:
        if axes is not None:
            raise ModelDefinitionError(f"{where}: a {name} hinge takes one 'axis', not 'axes'")
        if axis is None:
            raise ModelDefinitionError(f"{where}: a {name} hinge needs an 'axis'")
        given = [axis]
    else:
        if axes is None or len(axes) != 2:
            raise ModelDefinitionError(f"{where}: a {name} hinge needs 'axes' = [axis1, axis2], got {axes!r}")
        given = list(axes)
    for k, a in enumerate(given):
        v = vector3(a, f"{where}: hinge axis {k + 1}")
        norm = np.linalg.norm(v)
        if abs(norm - 1.0) > _UNIT_TOLERANCE:
            raise ModelDefinitionError(f"{where}: hinge axis {k + 1} {v.tolist()} is not a unit vector "
                                       f"(norm {norm:.12g}); normalize it explicitly")
        result[k] = v
    if naxes == 2 and np.linalg.norm(np.cross(result[0], result[1])) < 1e-6:
        raise ModelDefinitionError(f"{where}: {name} hinge axes {result.tolist()} are parallel")
    return result

def checked_prescribed(code, prescribed, where):
    nu = HINGES[code].nu
    if prescribed is None or prescribed is False:
        return np.zeros(nu, dtype=bool)
    if prescribed is True:
        return np.ones(nu, dtype=bool)
    flags = np.asarray(prescribed, dtype=bool).reshape(-1)
    if flags.shape != (nu,):
        raise ModelDefinitionError(f"{where}: 'prescribed' needs one flag per hinge DOF ({nu} for a "
                                   f"{HINGES[code].name} hinge), got {prescribed!r}")
    return flags


def checked_mass(mass, where):
    """The mass as a positive finite float."""
    try:
        mass = float(mass)
    except (TypeError, ValueError) as exc:
        raise ModelDefinitionError(f"{where}: mass must be a number, got {mass!r}") from exc
    if not np.isfinite(mass) or mass <= 0.0:
        raise ModelDefinitionError(f"{where}: mass must be positive and finite, got {mass!r} kg")
    return mass


def rigid_mass_properties(mass, com, inertia, where):
    """``(mass, com, inertia)`` checked as :meth:`dynamics.Multibody.add_body` checks a body's on a locked hinge
    (the inertia about the center of mass symmetric and positive semi-definite)."""
    mass = checked_mass(mass, where)
    com = vector3(com, f"{where}: center of mass")
    return mass, com, checked_inertia(inertia, where, LOCKED, mass=mass, com=com)


def hinge_definition(hinge, where, axis=None, axes=None, prescribed=None):
    """``(hinge, axes (2, 3), prescribed flags)`` of a hinge given by name, axis or axes and prescribed flags,
    checked as :meth:`dynamics.Multibody.add_body` checks them."""
    if hinge not in HINGE_TYPES:
        raise ModelDefinitionError(f"{where}: unknown hinge type {hinge!r}; expected one of "
                                   f"{sorted(HINGE_TYPES)}" + suggest(hinge, HINGE_TYPES))
    code = HINGE_TYPES[hinge]
    return hinge, checked_axes(code, axis, axes, where), checked_prescribed(code, prescribed, where)
