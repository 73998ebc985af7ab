"""The engine's immutable model: what a compiled multibody system *is*, apart from any run of it.

Pinocchio's ``Model`` / MuJoCo's ``mjModel``: a :class:`Model` holds the description
that :meth:`dynamics.Multibody.compile` lays out (:mod:`dynamics.layout`) and nothing that an evaluation writes:

* the tables the kernels read: ``topology`` and ``nodes`` (int64), ``joint_rot`` / ``joint_vec`` (hinge frames),
  ``params`` (ground acceleration, the bodies' spatial inertias, modal data, node frames and mode shapes, and what is
  precomputed from them), every one of them read-only (``flags.writeable`` False: a kernel or a user writing into
  one fails loudly; numba refuses to compile a store into a read-only array);
* sizes and index maps (``nq``, ``nu``, ``q_slices``, ``quaternion_q_indices`` ...), names, the body and node
  definitions it was compiled from (``definitions``), the forward-dynamics solver chosen for it (``solver``,
  ``solver_reason``) and ``notes``.

A model never changes: its attributes cannot be rebound and its arrays cannot be written. What a run writes lives
in a :class:`dynamics.data.Data` (``model.create_data()``): the kernels' workspace, and the run's own copy of the
rigid bodies' mass properties once the run changes them (mass depletion, a Monte Carlo run's dispersed masses).
Changing the model's own mass properties gives a new model (:meth:`Model.with_mass_properties`): the arrays that do
not change are shared, ``params`` is copied with the changed 6x6 blocks.

The algorithms are free functions over ``(model, data, ...)`` (:mod:`dynamics.algorithms`);
:class:`dynamics.MultibodySystem` is a model with a data of its own and the same algorithms as methods.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from dynamics import layout as L
from dynamics.data import Data, frozen
from dynamics.definitions import rigid_mass_properties
from dynamics.errors import ModelDefinitionError
from dynamics.hinges import HINGES
from dynamics.spatial import spatial_inertia


def rigid_inertia_block(model, body):
    """(index, offset in ``params`` of its 6x6 spatial inertia) of rigid body ``body`` (a name); refuses a flexible
    one, whose rigid block comes from its modal data."""
    i = model.body_index(body)
    if model.topology[i, L.FLEXIBLE]:
        raise ModelDefinitionError(f"set_mass_properties: '{body}' is flexible; its mass properties come "
                                   f"from its modal data")
    return i, int(model.topology[i, L.INERTIA])


def checked_mass_properties(body, mass, com, inertia):
    """``(mass, com, inertia, M)`` validated like :meth:`dynamics.Multibody.add_body`'s
    (:func:`dynamics.definitions.rigid_mass_properties`), with ``M`` the spatial inertia about the body origin."""
    mass, com, inertia = rigid_mass_properties(mass, com, inertia, f"body '{body}'")
    return mass, com, inertia, spatial_inertia(mass, com, inertia)


class Model:
    """A compiled tree of bodies, immutable (module docstring). Built by :meth:`dynamics.Multibody.compile` (as
    ``system.model``) or :meth:`dynamics.MultibodySystem.from_definitions`; one model serves any number of
    :class:`dynamics.data.Data` (:meth:`create_data`), e.g. one per thread or per Monte Carlo run."""

    def __init__(self, *, body_names, joint_names, hinge_names, node_names, node_bodies, topology, nodes,
                 joint_rot, joint_vec, params, pool_size, gravity, node_rot, node_pos, masses, notes, solver,
                 solver_reason, requested_solver, definitions):
        set_ = object.__setattr__
        topology = frozen(topology, np.int64)
        nodes = frozen(np.asarray(nodes).reshape(-1, L.NODE_COLUMNS), np.int64)
        params = frozen(params)
        nb = topology.shape[0]
        last = topology[-1]
        nu = int(last[L.U_START] + last[L.NU_HINGE] + last[L.N_MODES])
        prescribed = np.zeros(nu, dtype=bool)
        for t in topology:
            for kk in range(t[L.N_PRESCRIBED]):
                prescribed[t[L.U_START] + t[L.PRESCRIBED_DOFS + kk]] = True
        bodies, node_definitions, definition_gravity = definitions
        fields = dict(
            body_names=tuple(body_names), joint_names=tuple(joint_names), hinge_names=tuple(hinge_names),
            node_names=tuple(node_names), node_bodies=tuple(node_bodies), topology=topology, nodes=nodes,
            joint_rot=frozen(joint_rot), joint_vec=frozen(joint_vec), params=params, pool_size=int(pool_size),
            hinge_dofs=frozen(np.stack([topology[:, L.FREE_DOFS:L.FREE_DOFS + 6],
                                        topology[:, L.PRESCRIBED_DOFS:L.PRESCRIBED_DOFS + 6]], axis=1), np.int64),
            spatial_inertia=params[6:6 + 36 * nb].reshape(nb, 6, 6), gravity=frozen(gravity),
            ground_accel=params[L.GROUND_ACCEL:L.GROUND_ACCEL + 6], node_body=frozen(nodes[:, L.NODE_BODY], np.int64),
            node_rot=frozen(np.asarray(node_rot).reshape(-1, 3, 3)),
            node_pos=frozen(np.asarray(node_pos).reshape(-1, 3)),
            masses=frozen(masses), n_modes=tuple(int(t[L.N_MODES]) for t in topology),
            is_flexible=bool(np.any(topology[:, L.FLEXIBLE])), nbodies=nb, nnodes=len(node_names),
            nq=int(last[L.Q_START] + last[L.NQ_HINGE] + last[L.N_MODES]), nu=nu,
            parents=tuple(int(p) for p in topology[:, L.PARENT]),
            q_slices=tuple(slice(int(t[L.Q_START]), int(t[L.Q_START] + t[L.NQ_HINGE] + t[L.N_MODES]))
                           for t in topology),
            u_slices=tuple(slice(int(t[L.U_START]), int(t[L.U_START] + t[L.NU_HINGE] + t[L.N_MODES]))
                           for t in topology),
            quaternion_q_indices=frozen([t[L.Q_START] for t in topology if HINGES[t[L.HINGE_TYPE]].quaternion],
                                        np.int64),
            prescribed_dofs=frozen(prescribed, bool), solver=solver, solver_reason=solver_reason,
            notes=tuple(notes), requested_solver=requested_solver,
            definitions=(tuple(bodies), tuple(node_definitions), frozen(definition_gravity)))
        for name, value in fields.items():
            set_(self, name, value)

    def __setattr__(self, name, value):
        raise AttributeError(f"a dynamics.Model is immutable ('{name}'): build another one (with_mass_properties, "
                             f"with_notes, or dynamics.Multibody.compile)")

    def __delattr__(self, name):
        self.__setattr__(name, None)

    def __setstate__(self, state):
        # an unpickled or deep-copied model: numpy restores arrays writable, so freeze them again (as numba types
        # them read-only, also the kernels' compiled specialization stays the one of a compiled model)
        for name, value in state.items():
            if isinstance(value, np.ndarray):
                value.setflags(write=False)
            object.__setattr__(self, name, value)

    def _replaced(self, **changes):
        """A model with ``changes`` (already frozen) and every other attribute shared with this one."""
        other = object.__new__(Model)
        other.__dict__.update(self.__dict__)
        other.__dict__.update(changes)
        return other

    # ------------------------------------------------------------------ runs of this model
    def create_data(self, mass_properties: bool = False):
        """A new :class:`dynamics.data.Data` of this model: the workspace of its algorithms, with the model's mass
        properties (``mass_properties``: a private copy of them at once, else at its first change)."""
        return Data(self, own_mass_properties=mass_properties)

    # ------------------------------------------------------------------ new models from this one
    def with_mass_properties(self, changes):
        """A new model with the rigid bodies' mass properties ``changes`` ({body: (mass, com, inertia about the
        COM)} or {body: {"mass": ..., "com": ..., "inertia": ...}}), validated like
        :meth:`dynamics.Multibody.add_body`'s; every array but ``params`` and ``masses`` is shared with this model.
        O(size of params)."""
        params = np.array(self.params)
        masses = np.array(self.masses)
        bodies = list(self.definitions[0])
        for body, value in changes.items():
            mass, com, inertia = (value["mass"], value["com"], value["inertia"]) if isinstance(value, dict) else value
            i, o = rigid_inertia_block(self, body)
            mass, com, inertia, M = checked_mass_properties(body, mass, com, inertia)
            params[o:o + 36] = M.ravel()
            masses[i] = mass
            bodies[i] = dataclasses.replace(bodies[i], mass=mass, com=com, inertia=inertia)
        params, nb = frozen(params), self.nbodies
        return self._replaced(params=params, masses=frozen(masses),
                              spatial_inertia=params[6:6 + 36 * nb].reshape(nb, 6, 6),
                              ground_accel=params[L.GROUND_ACCEL:L.GROUND_ACCEL + 6],
                              definitions=(tuple(bodies),) + self.definitions[1:])

    def with_notes(self, notes):
        """A new model with ``notes`` (strings) after this one's; every array shared."""
        return self._replaced(notes=self.notes + tuple(notes))

    # ------------------------------------------------------------------ names
    def body_index(self, name):
        try:
            return self.body_names.index(name)
        except ValueError:
            raise KeyError(f"unknown body '{name}'; bodies: {list(self.body_names)}") from None

    def node_index(self, name):
        try:
            return self.node_names.index(name)
        except ValueError:
            raise KeyError(f"unknown node '{name}'; nodes: {list(self.node_names)}") from None

    def neutral_configuration(self):
        """Zero hinge angles/displacements, identity quaternions, zero modal coordinates."""
        q = np.zeros(self.nq)
        q[self.quaternion_q_indices] = 1.0
        return q

    def __repr__(self):
        return (f"Model({self.nbodies} bodies, nq={self.nq}, nu={self.nu}, {self.nnodes} nodes, "
                f"solver={self.solver})")
