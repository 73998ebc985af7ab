"""The multibody builder: collect bodies, hinges and nodes, validate them, compile to arrays.

``Multibody`` is the only mutable description; ``compile()`` checks everything a user can get wrong
(names, parents, masses, inertias, axes, frames, prescribed flags) and returns an immutable
:class:`dynamics.system.MultibodySystem` of numpy arrays (model/data separation as in Pinocchio's
``Model``/``Data``). Bodies are numbered in the order they are added, which must put every parent before
its children; that is also the coordinate order of ``q`` and ``u`` (docs/conventions.md).
"""

from __future__ import annotations

import difflib
import warnings
from dataclasses import dataclass

import numpy as np

from dynamics.hinges import (FREE, HINGE_NAMES, HINGE_NAXES, HINGE_NQ, HINGE_NU, HINGE_TYPES, LOCKED, PRISMATIC,
                             REVOLUTE, SPHERICAL, UJOINT)
from dynamics.spatial import quaternion_to_rotation

GROUND = None
"""Parent name meaning the inertial ground (world) frame."""

_UNIT_TOLERANCE = 1e-9
_ROTATION_TOLERANCE = 1e-9


class ModelDefinitionError(ValueError):
    """A body, hinge or node definition that cannot describe a physical system."""


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


@dataclass
class NodeDefinition:
    name: str
    body: str
    position: np.ndarray
    rotation: np.ndarray
    shape: np.ndarray | None = None  # (6, n) mode shapes Pi = [lambda; gamma] on a flexible body
    grid: int | None = None


def _suggest(name, candidates):
    close = difflib.get_close_matches(str(name), [str(c) for c in candidates], n=1)
    return f" Did you mean '{close[0]}'?" if close else ""


def _vector3(value, what):
    try:
        v = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ModelDefinitionError(f"{what}: expected 3 numbers, got {value!r}") from exc
    if v.shape != (3,) or not np.all(np.isfinite(v)):
        raise ModelDefinitionError(f"{what}: expected 3 finite numbers, got {value!r}")
    return v


def _rotation(value, what):
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


class Multibody:
    """Builder of a tree of bodies connected by hinges, with nodes (frames fixed on bodies).

    Example::

        mb = Multibody(gravity=(0, 0, -9.81))
        mb.add_body("link1", parent=None, mass=1.0, com=(0.5, 0, 0), inertia=np.diag([1e-3, 0.1, 0.1]),
                    hinge="revolute", axis=(0, 0, 1))
        mb.add_node("tip", body="link1", position=(1, 0, 0))
        system = mb.compile()
    """

    def __init__(self, gravity=(0.0, 0.0, 0.0)):
        self.gravity = _vector3(gravity, "gravity")
        self.bodies: list[BodyDefinition] = []
        self.nodes: list[NodeDefinition] = []
        self._body_index: dict[str, int] = {}
        self._node_names: set[str] = set()
        self.notes: list[str] = []  # choices made for the user (default modal-integral orders)

    def add_body(self, name, parent=GROUND, *, mass, inertia, com=(0.0, 0.0, 0.0), hinge, axis=None,
                 axes=None, inboard_position=(0.0, 0.0, 0.0), inboard_rotation=None,
                 outboard_position=(0.0, 0.0, 0.0), outboard_rotation=None, prescribed=None,
                 joint_name=None, parent_node=None):
        """Add a rigid body connected to ``parent`` (a body name, or None for the ground) by a hinge.

        ``inertia`` is about the center of mass ``com``, in the body frame. The hinge's inboard frame F
        is placed on the parent by ``inboard_position``/``inboard_rotation``; its outboard frame M on
        this body by ``outboard_position``/``outboard_rotation`` (pose of M in the body frame).
        ``axis`` (revolute, prismatic) or ``axes`` (two, U-joint) are unit vectors in the hinge frames.
        ``prescribed`` is a bool or one bool per hinge DOF. ``parent_node`` attaches the hinge to a node
        of the parent (required on a flexible parent, whose nodes move with its deformation): the
        inboard pose is then relative to that node's frame. Returns the body name.
        """
        where = f"body '{name}'"
        if not isinstance(name, str) or not name:
            raise ModelDefinitionError(f"body name must be a non-empty string, got {name!r}")
        if name in self._body_index:
            raise ModelDefinitionError(f"{where}: duplicate body name (already defined as body "
                                       f"#{self._body_index[name]})")
        if parent is not GROUND and parent not in self._body_index:
            known = list(self._body_index)
            raise ModelDefinitionError(
                f"{where}: unknown parent '{parent}'; parents must be added before their children "
                f"(bodies defined so far: {known or 'none'}; use parent=None for the ground)."
                + _suggest(parent, known))
        if hinge not in HINGE_TYPES:
            raise ModelDefinitionError(f"{where}: unknown hinge type {hinge!r}; expected one of "
                                       f"{sorted(HINGE_TYPES)}" + _suggest(hinge, HINGE_TYPES))
        try:
            mass = float(mass)
        except (TypeError, ValueError) as exc:
            raise ModelDefinitionError(f"{where}: mass must be a number, got {mass!r}") from exc
        if not np.isfinite(mass) or mass <= 0.0:
            raise ModelDefinitionError(f"{where}: mass must be positive and finite, got {mass!r} kg")
        com = _vector3(com, f"{where}: center of mass")
        code = HINGE_TYPES[hinge]
        hinge_axes = self._check_axes(code, axis, axes, where)
        prescribed_flags = self._check_prescribed(code, prescribed, where)
        inertia = self._check_inertia(inertia, where, code, hinge_axes, prescribed_flags, mass, com,
                                      _vector3(outboard_position, f"{where}: outboard_position"),
                                      _rotation(outboard_rotation, f"{where}: outboard_rotation"))
        if parent_node is not None:
            node = next((nd for nd in self.nodes if nd.name == parent_node), None)
            if node is None or node.body != parent:
                raise ModelDefinitionError(
                    f"{where}: parent_node '{parent_node}' is not a node of parent '{parent}' (its nodes: "
                    f"{[nd.name for nd in self.nodes if nd.body == parent]})")
        elif parent is not GROUND and self.bodies[self._body_index[parent]].flexible is not None:
            raise ModelDefinitionError(
                f"{where}: parent '{parent}' is flexible; attach the hinge to one of its nodes with "
                f"parent_node=... (a node at a grid of the body file)")
        self.bodies.append(BodyDefinition(
            name=name, parent=parent, mass=mass, com=com, inertia=inertia, hinge=hinge, axes=hinge_axes,
            inboard_position=_vector3(inboard_position, f"{where}: inboard_position"),
            inboard_rotation=_rotation(inboard_rotation, f"{where}: inboard_rotation"),
            outboard_position=_vector3(outboard_position, f"{where}: outboard_position"),
            outboard_rotation=_rotation(outboard_rotation, f"{where}: outboard_rotation"),
            prescribed=prescribed_flags, joint_name=joint_name or name, parent_node=parent_node))
        self._body_index[name] = len(self.bodies) - 1
        return name

    def add_flexible_body(self, name, parent=GROUND, *, modal, hinge, modes=None, max_frequency=None, order=None,
                          damping_ratio=None, integrals="general", child_grid=None, omit_terms=(), geometric_stiffening=None,
                          preload=None, **hinge_kwargs):
        """Add a flexible body whose reference frame is connected to ``parent`` by a hinge.

        ``modal``: a body file path (``flexshell fem2modal ... --modal-integrals``), a
        ``dynamics.flex.body_file.ModalBody`` or a :class:`dynamics.flexible_body.FlexibleBodyData`.
        The body frame is the FE model's reference frame (basic axes at the reference grid). ``modes``
        selects mode indices, ``max_frequency`` (Hz) keeps only the body file's modes at or below it (of the
        listed ones when ``modes`` is given; :func:`dynamics.mode_selection.select_modes`), ``order`` the modal-integral order (0, 1, 2; default: the highest the body
        file supports, 2 unless the file omits G2 for its nodes' rotational inertia, then 1, which is
        recorded in :attr:`notes` and warned about), ``damping_ratio`` overrides the file's modal
        damping, ``integrals`` picks ``"general"`` or ``"point_mass"`` integrals, ``omit_terms`` leaves
        out terms of M(eta) that cost O(n^3) or O(n^4) per evaluation (a subset of ("G1", "F2", "G2"),
        see :mod:`dynamics.flexible_body`). ``geometric_stiffening`` (None: on when the body file has the
        geometric stiffness of ``fem2modal --geometric-stiffness``; False: off; True: required) and ``preload``
        ({name: scale} of the file's named preloads) add the stiffening of the rigid-motion and preload
        stresses (:func:`dynamics.flexible_body.add_geometric_stiffening`). ``child_grid`` puts the hinge's outboard frame on that grid
        of this body, so the hinge holds the deforming interface grid (as DARTS does) rather than the
        body frame; ``outboard_position`` and ``outboard_rotation`` are then relative to the grid's node
        frame. Other keywords are those of :meth:`add_body` (hinge axes, frames, prescribed,
        parent_node, joint_name). Modal coordinates are appended to the hinge coordinates in ``q`` and
        ``u``.
        """
        from dynamics.flexible_body import FlexibleBodyData, flexible_body_from_modal_body

        if isinstance(modal, FlexibleBodyData):
            data = modal.without(omit_terms)
            if (modes is not None or max_frequency is not None or damping_ratio is not None or preload
                    or geometric_stiffening or (order is not None and order != data.order)):
                raise ModelDefinitionError(f"body '{name}': modes/max_frequency/damping_ratio/order/geometric_stiffening/"
                                           f"preload apply to body files; "
                                           f"FlexibleBodyData is used as given (its order is {data.order})")
        else:
            if not hasattr(modal, "modal_integrals"):
                from dynamics.flex.body_file import read_body_file

                modal = read_body_file(modal)
            if max_frequency is not None:
                from dynamics.mode_selection import select_modes

                try:
                    modes = select_modes(modal.frequencies_hz, modes, max_frequency)
                except ValueError as exc:
                    raise ModelDefinitionError(f"body '{name}': {exc}") from None
            try:
                data = flexible_body_from_modal_body(modal, modes=modes, order=order, damping_ratio=damping_ratio,
                                                     integrals=integrals, omit_terms=omit_terms,
                                                     geometric_stiffening=geometric_stiffening, preload=preload)
            except ModelDefinitionError as exc:
                raise ModelDefinitionError(f"body '{name}': {exc}") from None
            # normalized component modes mounted where their interface is not held, or held twice (a free
            # body without child_grid needs no holding: its modes span the interface motion)
            if hasattr(modal, "mounting_warnings") and not (child_grid is None and hinge == "free"):
                for message in modal.mounting_warnings(child_grid, hinge):
                    warnings.warn(f"body '{name}': {message}", UserWarning, stacklevel=2)
        M0 = data.M0
        mass = M0[3, 3]
        com = np.array([M0[2, 4], M0[0, 5], M0[1, 3]]) / mass
        J0 = M0[:3, :3]
        J_com = J0 - mass * (com @ com * np.eye(3) - np.outer(com, com))
        self.add_body(name, parent, mass=mass, com=com, inertia=J_com, hinge=hinge, **hinge_kwargs)
        self.bodies[-1].flexible = data
        if data.note:
            self.notes.append(f"body '{name}': {data.note}")
            warnings.warn(self.notes[-1], UserWarning, stacklevel=2)
        if child_grid is not None:
            self.bodies[-1].outboard_node = self.add_node(f"{name}.hinge", name, grid=child_grid)
        return name

    def add_node(self, name, body, position=None, rotation=None, grid=None):
        """Add a node: a frame fixed on ``body`` at ``position`` with ``rotation`` (node -> body).

        On a flexible body the node sits at FE grid ``grid`` (its position comes from the body file) and
        moves with the deformation ``Pi(grid) eta``."""
        if not isinstance(name, str) or not name:
            raise ModelDefinitionError(f"node name must be a non-empty string, got {name!r}")
        if name in self._node_names:
            raise ModelDefinitionError(f"node '{name}': duplicate node name")
        if body not in self._body_index:
            raise ModelDefinitionError(f"node '{name}': unknown body '{body}' (bodies: "
                                       f"{list(self._body_index) or 'none'})" + _suggest(body, self._body_index))
        flexible = self.bodies[self._body_index[body]].flexible
        shape = None
        if flexible is not None:
            if grid is None or position is not None:
                raise ModelDefinitionError(f"node '{name}': a node on flexible body '{body}' is placed by "
                                           f"grid=<FE grid id>, not by position")
            j = flexible.grid_index(grid)
            position = flexible.grid_positions[j]
            shape = flexible.grid_shapes[j]
        elif grid is not None:
            raise ModelDefinitionError(f"node '{name}': grid= applies to flexible bodies; '{body}' is rigid")
        position = (0.0, 0.0, 0.0) if position is None else position
        self.nodes.append(NodeDefinition(name, body, _vector3(position, f"node '{name}': position"),
                                         _rotation(rotation, f"node '{name}': rotation"), shape, grid))
        self._node_names.add(name)
        return name

    @staticmethod
    def _check_inertia(inertia, where, code=FREE, hinge_axes=None, prescribed=None, mass=1.0, com=None,
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
            if code in (LOCKED, PRISMATIC) or fully_prescribed:
                ok = True
            elif code in (REVOLUTE, UJOINT):
                R = np.eye(3) if R_BM is None else R_BM
                n_axes = 1 if code == REVOLUTE else 2
                ok = all((R @ a) @ about_hinge @ (R @ a) > tol for a in hinge_axes[:n_axes])
            elif code == SPHERICAL:
                ok = np.linalg.eigvalsh(about_hinge)[0] > tol
            else:
                ok = False
            if not ok:
                need = ("a free hinge turns the body about its center of mass: it needs rotary inertia about "
                        "every axis" if code == FREE else f"its {HINGE_NAMES[code]} hinge turns it about an "
                        "axis without inertia about the hinge point")
                raise ModelDefinitionError(
                    f"{where}: {need}; principal moments about the center of mass are {eig.tolist()} kg m^2, "
                    f"none about {null} (body axes). Give the body rotary inertia there (in an FE deck: "
                    f"CONM2 I11-I33, PARAM COUPMASS 1 or CBEAM elements), or use a hinge that does not turn "
                    f"about that axis")
            return J
        if eig[0] + eig[1] < eig[2] * (1.0 - 1e-9):
            warnings.warn(f"{where}: principal moments {eig.tolist()} violate the triangle inequality "
                          f"(I1 + I2 >= I3) that every physical mass distribution satisfies", stacklevel=3)
        return J

    @staticmethod
    def _check_axes(code, axis, axes, where):
        naxes = HINGE_NAXES[code]
        result = np.zeros((2, 3))
        if naxes == 0:
            if axis is not None or axes is not None:
                raise ModelDefinitionError(f"{where}: a {HINGE_NAMES[code]} hinge takes no axis")
            return result
        if naxes == 1:
            if axes is not None:
                raise ModelDefinitionError(f"{where}: a {HINGE_NAMES[code]} hinge takes one 'axis', not 'axes'")
            if axis is None:
                raise ModelDefinitionError(f"{where}: a {HINGE_NAMES[code]} hinge needs an 'axis'")
            given = [axis]
        else:
            if axes is None or len(axes) != 2:
                raise ModelDefinitionError(f"{where}: a U-joint needs 'axes' = [axis1, axis2], got {axes!r}")
            given = list(axes)
        for k, a in enumerate(given):
            v = _vector3(a, f"{where}: hinge axis {k + 1}")
            norm = np.linalg.norm(v)
            if abs(norm - 1.0) > _UNIT_TOLERANCE:
                raise ModelDefinitionError(f"{where}: hinge axis {k + 1} {v.tolist()} is not a unit vector "
                                           f"(norm {norm:.12g}); normalize it explicitly")
            result[k] = v
        if naxes == 2 and np.linalg.norm(np.cross(result[0], result[1])) < 1e-6:
            raise ModelDefinitionError(f"{where}: U-joint axes {result.tolist()} are parallel")
        return result

    @staticmethod
    def _check_prescribed(code, prescribed, where):
        nu = int(HINGE_NU[code])
        if prescribed is None or prescribed is False:
            return np.zeros(nu, dtype=bool)
        if prescribed is True:
            return np.ones(nu, dtype=bool)
        flags = np.asarray(prescribed, dtype=bool).reshape(-1)
        if flags.shape != (nu,):
            raise ModelDefinitionError(f"{where}: 'prescribed' needs one flag per hinge DOF ({nu} for a "
                                       f"{HINGE_NAMES[code]} hinge), got {prescribed!r}")
        return flags

    def compile(self, solver=None):
        """Freeze the description into a :class:`~dynamics.system.MultibodySystem`.

        ``solver``: "aba" or "dense" forces the forward-dynamics method; by default the cheaper one is
        chosen (:func:`dynamics.system.choose_solver`) and reported by ``system.summary()``."""
        from dynamics.system import MultibodySystem

        if not self.bodies:
            raise ModelDefinitionError("the multibody has no bodies")
        return MultibodySystem.from_definitions(self.bodies, self.nodes, self.gravity, solver=solver)

    # ------------------------------------------------------------------ URDF
    @classmethod
    def from_urdf(cls, path, floating_base=False, gravity=(0.0, 0.0, -9.81)):
        """Build from a URDF file; see :mod:`dynamics.urdf` for the mapping of links and joints."""
        from dynamics.urdf import multibody_from_urdf

        return multibody_from_urdf(path, floating_base=floating_base, gravity=gravity)


def hinge_sizes(hinge):
    """(nq, nu) of a hinge type name."""
    code = HINGE_TYPES[hinge]
    return int(HINGE_NQ[code]), int(HINGE_NU[code])

