"""The multibody builder: collect bodies, hinges and nodes, validate them, compile to arrays.

``Multibody`` is the only mutable description; ``compile()`` checks everything a user can get wrong
(names, parents, masses, inertias, axes, frames, prescribed flags) and returns a
:class:`dynamics.system.MultibodySystem`: an immutable :class:`dynamics.model.Model` of numpy arrays with a
:class:`dynamics.data.Data` of its own (model/data separation as in Pinocchio's ``Model``/``Data``). Bodies are numbered in the order they are added, which must put every parent before
its children; that is also the coordinate order of ``q`` and ``u`` (docs/conventions.md).
"""

from __future__ import annotations

import dataclasses
import warnings

import numpy as np

from dynamics.definitions import (BodyDefinition, NodeDefinition, checked_axes, checked_inertia, checked_mass,
                                  checked_prescribed, rotation_matrix, suggest, vector3)
from dynamics.errors import ModelDefinitionError
from dynamics.flexible_body import FlexibleBodyData, flexible_body_from_modal_body
from dynamics.hinges import HINGE_TYPES
from dynamics.system import MultibodySystem
from dynamics.urdf import multibody_from_urdf

GROUND = None
"""Parent name meaning the inertial ground (world) frame."""

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
        self.gravity = vector3(gravity, "gravity")
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
        if parent is not GROUND and not isinstance(parent, str):
            raise ModelDefinitionError(f"{where}: parent must be a body name (text) or None, got {parent!r}")
        if parent is not GROUND and parent not in self._body_index:
            known = list(self._body_index)
            raise ModelDefinitionError(
                f"{where}: unknown parent '{parent}'; parents must be added before their children "
                f"(bodies defined so far: {known or 'none'}; use parent=None for the ground)."
                + suggest(parent, known))
        if not isinstance(hinge, str) or hinge not in HINGE_TYPES:
            raise ModelDefinitionError(f"{where}: unknown hinge type {hinge!r}; expected one of "
                                       f"{sorted(HINGE_TYPES)}" + suggest(hinge, HINGE_TYPES))
        mass = checked_mass(mass, where)
        com = vector3(com, f"{where}: center of mass")
        code = HINGE_TYPES[hinge]
        hinge_axes = checked_axes(code, axis, axes, where)
        prescribed_flags = checked_prescribed(code, prescribed, where)
        inertia = checked_inertia(inertia, where, code, hinge_axes, prescribed_flags, mass, com,
                                      vector3(outboard_position, f"{where}: outboard_position"),
                                      rotation_matrix(outboard_rotation, f"{where}: outboard_rotation"))
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
            inboard_position=vector3(inboard_position, f"{where}: inboard_position"),
            inboard_rotation=rotation_matrix(inboard_rotation, f"{where}: inboard_rotation"),
            outboard_position=vector3(outboard_position, f"{where}: outboard_position"),
            outboard_rotation=rotation_matrix(outboard_rotation, f"{where}: outboard_rotation"),
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
        listed ones when ``modes`` is given; :func:`dynamics.mode_selection.select_modes`), ``order`` the
        modal-integral order: 0, 1, 2 (the default; the terms G1, F2, G2 of nodes with rotary inertia are summed
        over the file's grids where its tables are missing or dearer), or ``"auto"``: the order the scene needs,
        chosen from its initial state by :func:`dynamics.modal_order.resolve_modal_orders` (the YAML default;
        until then the body is compiled at order 2). ``damping_ratio`` overrides the file's modal
        damping, ``integrals`` picks ``"general"`` or ``"point_mass"`` integrals, ``omit_terms`` leaves
        out the terms of nodes with rotary inertia (a subset of ("G1", "F2", "G2"), see
        :mod:`dynamics.flexible_body`). ``geometric_stiffening`` (None: on when the body file has the
        geometric stiffness of ``fem2modal --geometric-stiffness``; False: off; True: required) and ``preload``
        ({name: scale} of the file's named preloads) add the stiffening of the rigid-motion and preload
        stresses (:func:`dynamics.flexible_body.add_geometric_stiffening`). ``child_grid`` puts the hinge's
        outboard frame on that grid of this body, so the hinge holds the deforming interface grid (as DARTS
        does) rather than the
        body frame; ``outboard_position`` and ``outboard_rotation`` are then relative to the grid's node
        frame. Other keywords are those of :meth:`add_body` (hinge axes, frames, prescribed,
        parent_node, joint_name). Modal coordinates are appended to the hinge coordinates in ``q`` and
        ``u``.
        """
        auto = order == "auto"
        if order not in (None, 0, 1, 2, "auto"):
            raise ModelDefinitionError(f"body '{name}': modal-integral order must be 0, 1, 2 or 'auto', got {order!r}")
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

            def build(order_, omit_=()):
                try:
                    return flexible_body_from_modal_body(
                        modal, modes=modes, order=order_, damping_ratio=damping_ratio, integrals=integrals,
                        omit_terms=tuple(omit_terms) + tuple(t for t in omit_ if t not in omit_terms),
                        geometric_stiffening=geometric_stiffening, preload=preload)
                except ModelDefinitionError as exc:
                    raise ModelDefinitionError(f"body '{name}': {exc}") from None

            data = build(2 if auto else order)
            if auto:
                data = dataclasses.replace(data, note="modal integrals order auto, compiled at order 2 until "
                                                      "dynamics.modal_order.resolve_modal_orders chooses")
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
        self.bodies[-1].auto_order = build if auto else None
        if data.note and not auto:
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
        if not isinstance(body, str) or body not in self._body_index:
            raise ModelDefinitionError(f"node '{name}': unknown body '{body}' (bodies: "
                                       f"{list(self._body_index) or 'none'})" + suggest(body, self._body_index))
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
        self.nodes.append(NodeDefinition(name, body, vector3(position, f"node '{name}': position"),
                                         rotation_matrix(rotation, f"node '{name}': rotation"), shape, grid))
        self._node_names.add(name)
        return name

    def compile(self, solver=None):
        """Freeze the description into a :class:`~dynamics.system.MultibodySystem`.

        ``solver``: "aba" or "dense" forces the forward-dynamics method; by default the cheaper one is
        chosen (:func:`dynamics.system.choose_solver`) and reported by ``system.summary()``."""
        if not self.bodies:
            raise ModelDefinitionError("the multibody has no bodies")
        return MultibodySystem.from_definitions(self.bodies, self.nodes, self.gravity, solver=solver)

    # ------------------------------------------------------------------ URDF
    @classmethod
    def from_urdf(cls, path, floating_base=False, gravity=(0.0, 0.0, -9.81)):
        """Build from a URDF file; see :mod:`dynamics.urdf` for the mapping of links and joints."""
        return multibody_from_urdf(path, cls(gravity=gravity), floating_base=floating_base)

