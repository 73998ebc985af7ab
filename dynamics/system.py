"""The compiled multibody system: immutable arrays, a private workspace, and the user-facing algorithms.

Coordinates (CONVENTIONS.md): ``q`` and ``u`` concatenate, in body order, each body's hinge coordinates
(see :mod:`dynamics.hinges`) followed by its modal coordinates (none for rigid bodies). Generalized
forces ``tau`` are conjugate to ``u``: a torque for a revolute DOF, a force for a prismatic one, the
hinge's ``[torque; force]`` in the outboard frame for spherical/free hinges.

Node forces are spatial forces ``[torque; force]`` in node axes, applied at the node origin.

The arrays (``topology``, ``hinge_dofs``, ``joint_rot``, ``joint_vec``, ``spatial_inertia``, node tables)
never change after :meth:`dynamics.Multibody.compile`; the workspace is scratch owned by this object,
so a system must not be shared between threads (use :meth:`MultibodySystem.copy`).
"""

from __future__ import annotations

import dataclasses
from typing import NamedTuple

import numpy as np

from dynamics import flexible_kernels as FK
from dynamics import kernels as K
from dynamics.hinges import FREE, HINGE_NQ, HINGE_NU, HINGE_TYPES, SPHERICAL
from dynamics.spatial import spatial_inertia as _spatial_inertia


class SingularConfigurationError(RuntimeError):
    """The articulated inertia of a hinge vanished: the forward dynamics has no unique solution."""


class NodeKinematics(NamedTuple):
    """Kinematics of every node; arrays indexed like ``MultibodySystem.node_names``."""

    rotation: np.ndarray  # (n, 3, 3) node -> world
    position: np.ndarray  # (n, 3) node origin in the world
    angular_velocity: np.ndarray  # (n, 3) node axes
    linear_velocity: np.ndarray  # (n, 3) node axes, velocity of the node origin
    angular_acceleration: np.ndarray  # (n, 3) node axes
    linear_acceleration: np.ndarray  # (n, 3) node axes, classical acceleration of the node origin


def _frozen(a, dtype=np.float64):
    a = np.ascontiguousarray(a, dtype=dtype)
    a.setflags(write=False)
    return a


class MultibodySystem:
    """A compiled tree of bodies. Build with :class:`dynamics.Multibody`."""

    def __init__(self, *, body_names, joint_names, hinge_names, node_names, node_bodies, topology,
                 hinge_dofs, joint_rot, joint_vec, spatial_inertia, gravity, node_body, node_rot,
                 node_pos, masses, flex_index=None, flex_data=None, node_shape=None):
        self.body_names = tuple(body_names)
        self.joint_names = tuple(joint_names)
        self.hinge_names = tuple(hinge_names)
        self.node_names = tuple(node_names)
        self.node_bodies = tuple(node_bodies)
        self.topology = _frozen(topology, np.int64)
        self.hinge_dofs = _frozen(hinge_dofs, np.int64)
        self.joint_rot = _frozen(joint_rot)
        self.joint_vec = _frozen(joint_vec)
        self.spatial_inertia = _frozen(spatial_inertia)
        self.gravity = _frozen(gravity)
        self.ground_accel = _frozen(np.concatenate([np.zeros(3), -np.asarray(gravity, dtype=np.float64)]))
        self.node_body = _frozen(node_body, np.int64)
        self.node_rot = _frozen(node_rot)
        self.node_pos = _frozen(node_pos)
        self.masses = _frozen(masses)
        nb = self.topology.shape[0]
        self.n_modes = tuple(int(t[K.N_MODES]) for t in self.topology)
        self.is_flexible = any(self.n_modes)
        if self.is_flexible:
            self.flex_index = _frozen(flex_index, np.int64)
            self.flex_data = _frozen(flex_data)
            self.node_shape = _frozen(node_shape)
        last = self.topology[-1]
        self.nbodies = nb
        self.nnodes = len(self.node_names)
        self.nq = int(last[K.Q_START] + last[K.NQ_HINGE] + last[K.N_MODES])
        self.nu = int(last[K.U_START] + last[K.NU_HINGE] + last[K.N_MODES])
        self.parents = tuple(int(p) for p in self.topology[:, K.PARENT])
        self.q_slices = tuple(slice(int(t[K.Q_START]), int(t[K.Q_START] + t[K.NQ_HINGE] + t[K.N_MODES]))
                              for t in self.topology)
        self.u_slices = tuple(slice(int(t[K.U_START]), int(t[K.U_START] + t[K.NU_HINGE] + t[K.N_MODES]))
                              for t in self.topology)
        self.quaternion_q_indices = np.array(
            [t[K.Q_START] for t in self.topology if t[K.HINGE_TYPE] in (SPHERICAL, FREE)], dtype=np.int64)
        prescribed = np.zeros(self.nu, dtype=bool)
        for i, t in enumerate(self.topology):
            for kk in range(t[K.N_PRESCRIBED]):
                prescribed[t[K.U_START] + self.hinge_dofs[i, 1, kk]] = True
        self.prescribed_dofs = _frozen(prescribed, bool)
        self._allocate_workspace()

    @classmethod
    def from_definitions(cls, bodies, nodes, gravity):
        index = {b.name: i for i, b in enumerate(bodies)}
        node_index = {n.name: k for k, n in enumerate(nodes)}
        nb = len(bodies)
        topology = np.zeros((nb, K.TOPOLOGY_COLUMNS), dtype=np.int64)
        hinge_dofs = np.zeros((nb, 2, 6), dtype=np.int64)
        joint_rot = np.zeros((nb, 2, 3, 3))
        joint_vec = np.zeros((nb, 4, 3))
        inertia = np.zeros((nb, 6, 6))
        q0 = u0 = 0
        for i, b in enumerate(bodies):
            code = HINGE_TYPES[b.hinge]
            nq, nu = int(HINGE_NQ[code]), int(HINGE_NU[code])
            free = np.flatnonzero(~b.prescribed)
            pres = np.flatnonzero(b.prescribed)
            outboard_identity = (np.array_equal(b.outboard_rotation, np.eye(3))
                                 and not np.any(b.outboard_position) and b.outboard_node is None)
            n_modes = 0 if b.flexible is None else b.flexible.n_modes
            parent_flexible = b.parent is not None and bodies[index[b.parent]].flexible is not None
            parent_node = node_index[b.parent_node] if (b.parent_node and parent_flexible) else -1
            outboard_node = node_index[b.outboard_node] if b.outboard_node else -1
            topology[i] = [-1 if b.parent is None else index[b.parent], code, q0, nq, u0, nu, n_modes,
                           len(free), len(pres), outboard_identity, parent_node, outboard_node]
            hinge_dofs[i, 0, :len(free)] = free
            hinge_dofs[i, 1, :len(pres)] = pres
            R_in, p_in = b.inboard_rotation, b.inboard_position
            if b.parent_node and not parent_flexible:  # a node of a rigid parent: fold its fixed pose in
                node = nodes[node_index[b.parent_node]]
                R_in, p_in = node.rotation @ R_in, node.position + node.rotation @ p_in
            joint_rot[i, K.INBOARD] = R_in
            joint_rot[i, K.OUTBOARD] = b.outboard_rotation
            joint_vec[i, K.INBOARD] = p_in
            joint_vec[i, K.OUTBOARD] = b.outboard_position
            joint_vec[i, K.AXIS1:K.AXIS2 + 1] = b.axes
            inertia[i] = _spatial_inertia(b.mass, b.com, b.inertia)
            q0 += nq + n_modes
            u0 += nu + n_modes
        nn = len(nodes)
        node_body = np.array([index[n.body] for n in nodes], dtype=np.int64)
        node_rot = np.array([n.rotation for n in nodes]).reshape(nn, 3, 3)
        node_pos = np.array([n.position for n in nodes]).reshape(nn, 3)
        flex = {}
        if any(b.flexible is not None for b in bodies):
            flex = cls._flexible_arrays(bodies, nodes, inertia)
        system = cls(body_names=[b.name for b in bodies], joint_names=[b.joint_name for b in bodies],
                     hinge_names=[b.hinge for b in bodies], node_names=[n.name for n in nodes],
                     node_bodies=[n.body for n in nodes], topology=topology, hinge_dofs=hinge_dofs,
                     joint_rot=joint_rot, joint_vec=joint_vec, spatial_inertia=inertia, gravity=gravity,
                     node_body=node_body, node_rot=node_rot, node_pos=node_pos,
                     masses=[b.mass for b in bodies], **flex)
        # the description this system was compiled from, for run-time reconfiguration
        system.definitions = (tuple(dataclasses.replace(b) for b in bodies),
                              tuple(dataclasses.replace(n) for n in nodes), np.array(gravity, dtype=float))
        return system

    @staticmethod
    def _flexible_arrays(bodies, nodes, inertia):
        """flex_index, flex_data (M0, M1, M2, K, C per body, flattened) and padded node mode shapes."""
        nb = len(bodies)
        flex_index = np.zeros((nb, FK.N_FX), dtype=np.int64)
        chunks, offset = [], 0

        def push(a):
            nonlocal offset
            a = np.ascontiguousarray(a, dtype=np.float64).ravel()
            chunks.append(a)
            start = offset
            offset += a.size
            return start

        for i, b in enumerate(bodies):
            data = b.flexible
            if data is None:
                flex_index[i] = [0, push(inertia[i]), 0, 0, 0, 0, 0]
                continue
            n = data.n_modes
            flex_index[i, FK.FX_N] = n
            flex_index[i, FK.FX_M0] = push(data.M0)
            flex_index[i, FK.FX_M1] = push(data.M1 if data.order >= 1 else np.zeros(0))
            if data.order == 2:
                # store M2 on the smallest leading block holding its non-zeros (only J2 for point masses)
                nonzero = np.flatnonzero(np.any(data.M2 != 0.0, axis=(0, 1, 2)) | np.any(data.M2 != 0.0, axis=(0, 1, 3)))
                extent = int(nonzero.max()) + 1 if nonzero.size else 0
                flex_index[i, FK.FX_M2_EXTENT] = extent
                flex_index[i, FK.FX_M2] = push(data.M2[:, :, :extent, :extent])
            else:
                flex_index[i, FK.FX_M2] = push(np.zeros(0))
            flex_index[i, FK.FX_K] = push(data.stiffness)
            push(data.damping)
            flex_index[i, FK.FX_ORDER] = data.order
        nmax = max(1, max((b.flexible.n_modes for b in bodies if b.flexible is not None), default=1))
        node_shape = np.zeros((len(nodes), 6, nmax))
        for k, nd in enumerate(nodes):
            if nd.shape is not None:
                node_shape[k, :, :nd.shape.shape[1]] = nd.shape
        return {"flex_index": flex_index, "flex_data": np.concatenate(chunks), "node_shape": node_shape}

    def _allocate_workspace(self):
        nb = self.nbodies
        self.ws_rot = np.zeros((nb, K.N_ROT, 3, 3))
        self.ws_vec = np.zeros((nb, K.N_VEC, 6))
        self.ws_mat = np.zeros((nb, K.N_MAT, 6, 6))
        K.initialize_workspace(self.topology, self.joint_rot, self.joint_vec, self.ws_rot, self.ws_mat)
        self._zero_body_forces = np.zeros((nb, 6))
        self._zero_body_forces.setflags(write=False)
        self._zero_node_forces = np.zeros((self.nnodes, 6))
        self._zero_node_forces.setflags(write=False)
        self._body_forces = np.zeros((nb, 6))
        self._zero_u = np.zeros(self.nu)
        self._zero_u.setflags(write=False)
        if self.is_flexible:
            nmax = self.node_shape.shape[2]
            nm = max(6 + max(self.n_modes), 12)
            self.fw_psi = np.zeros((nb + 1, 12, nmax))  # Psi of the parent node, then of the own hinge node
            self.fw_vec = np.zeros((nb, FK.N_FV, nm))
            self.fw_mat = np.zeros((nb, FK.N_FM, nm, nm))
            self.fw_tmp = np.zeros((8, 3))
            self.fw_scratch = np.zeros((4, 6, 6))

    def copy(self):
        """A system sharing the immutable arrays with its own workspace (one per thread)."""
        other = object.__new__(MultibodySystem)
        other.__dict__.update(self.__dict__)
        other._allocate_workspace()
        return other

    # ------------------------------------------------------------------ helpers
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

    def reconfigure(self, q, u, *, lock=(), unlock=(), detach=(), mass_properties=None):
        """A new system after locking/unlocking hinges, detaching subtrees or changing mass properties,
        with the state mapped across: returns ``(system, q, u)``. See :mod:`dynamics.reconfigure`."""
        from dynamics.reconfigure import reconfigure

        return reconfigure(self, q, u, lock=lock, unlock=unlock, detach=detach, mass_properties=mass_properties)

    def set_mass_properties(self, body, mass, com, inertia):
        """Change a rigid body's mass, center of mass and inertia (about the COM) in place, O(1): for
        mass depletion during a run. The values are validated like :meth:`Multibody.add_body`'s."""
        from dynamics.builder import ModelDefinitionError, Multibody

        i = self.body_index(body)
        if self.n_modes[i]:
            raise ModelDefinitionError(f"set_mass_properties: '{body}' is flexible; its mass properties come "
                                       f"from its modal data")
        probe = Multibody()
        probe.add_body(body, None, mass=mass, com=com, inertia=inertia, hinge="locked")
        b = probe.bodies[0]
        M = _spatial_inertia(b.mass, b.com, b.inertia)
        self.spatial_inertia.setflags(write=True)
        self.spatial_inertia[i] = M
        self.spatial_inertia.setflags(write=False)
        self.masses.setflags(write=True)
        self.masses[i] = b.mass
        self.masses.setflags(write=False)
        if self.is_flexible:
            start = int(self.flex_index[i, FK.FX_M0])
            self.flex_data.setflags(write=True)
            self.flex_data[start:start + 36] = M.ravel()
            self.flex_data.setflags(write=False)
        definitions = list(self.definitions[0])
        definitions[i] = dataclasses.replace(definitions[i], mass=b.mass, com=b.com, inertia=b.inertia)
        self.definitions = (tuple(definitions),) + self.definitions[1:]

    def neutral_configuration(self):
        """Zero hinge angles/displacements, identity quaternions, zero modal coordinates."""
        q = np.zeros(self.nq)
        q[self.quaternion_q_indices] = 1.0
        return q

    def normalize_quaternions(self, q):
        """Renormalize every hinge quaternion of ``q`` in place; returns ``q``."""
        for k in self.quaternion_q_indices:
            q[k:k + 4] /= np.linalg.norm(q[k:k + 4])
        return q

    def _vector(self, x, n, what):
        x = np.asarray(x, dtype=np.float64)
        if x.shape != (n,):
            raise ValueError(f"{what}: expected shape ({n},), got {x.shape}")
        return x

    def _body_forces_from(self, node_forces, body_forces):
        if node_forces is None and body_forces is None:
            return self._zero_body_forces
        out = self._body_forces
        if node_forces is not None:
            node_forces = np.asarray(node_forces, dtype=np.float64)
            if node_forces.shape != (self.nnodes, 6):
                raise ValueError(f"node_forces: expected shape ({self.nnodes}, 6) (one [torque; force] per "
                                 f"node, node axes), got {node_forces.shape}")
            K.node_forces_to_bodies(self.node_body, self.node_rot, self.node_pos, node_forces, out)
        else:
            out[:] = 0.0
        if body_forces is not None:
            body_forces = np.asarray(body_forces, dtype=np.float64)
            if body_forces.shape != (self.nbodies, 6):
                raise ValueError(f"body_forces: expected shape ({self.nbodies}, 6), got {body_forces.shape}")
            out += body_forces
        return out

    def _flex_forces(self, node_forces, body_forces):
        nf = self._zero_node_forces if node_forces is None else np.asarray(node_forces, dtype=np.float64)
        if nf.shape != (self.nnodes, 6):
            raise ValueError(f"node_forces: expected shape ({self.nnodes}, 6) (one [torque; force] per "
                             f"node, node axes), got {nf.shape}")
        bf = self._zero_body_forces if body_forces is None else np.asarray(body_forces, dtype=np.float64)
        if bf.shape != (self.nbodies, 6):
            raise ValueError(f"body_forces: expected shape ({self.nbodies}, 6), got {bf.shape}")
        return nf, bf

    def _flex_workspace(self):
        return self.ws_rot, self.ws_vec, self.ws_mat, self.fw_psi, self.fw_vec, self.fw_mat, self.fw_tmp

    # ------------------------------------------------------------------ algorithms
    def q_dot(self, q, u):
        """Coordinate rates ``q_dot = f(q, u)``."""
        qdot = np.empty(self.nq)
        K.coordinate_rates(self.topology, self._vector(q, self.nq, "q"), self._vector(u, self.nu, "u"), qdot)
        return qdot

    def forward_dynamics(self, q, u, tau=None, node_forces=None, prescribed_accel=None, body_forces=None,
                         return_forces=False):
        """Accelerations ``u_dot`` by the O(N) articulated-body algorithm.

        ``tau`` (nu,) generalized forces at the free DOFs; ``node_forces`` (nnodes, 6) and
        ``body_forces`` (nbodies, 6: about the body origin, body axes) external spatial forces;
        ``prescribed_accel`` (nu,) the accelerations of prescribed DOFs (zero if omitted). With
        ``return_forces`` also returns the generalized forces of all DOFs (the input ``tau`` at free
        DOFs, the force realizing the prescribed motion at prescribed DOFs).
        """
        q = self._vector(q, self.nq, "q")
        u = self._vector(u, self.nu, "u")
        tau = self._zero_u if tau is None else self._vector(tau, self.nu, "tau")
        udot = np.zeros(self.nu) if prescribed_accel is None else \
            np.array(self._vector(prescribed_accel, self.nu, "prescribed_accel"))
        tau_out = np.empty(self.nu)
        if self.is_flexible:
            nf, bf = self._flex_forces(node_forces, body_forces)
            status = FK.flex_forward_dynamics(
                self.topology, self.hinge_dofs, self.joint_rot, self.joint_vec, self.flex_index, self.flex_data,
                self.node_body, self.node_shape, self.node_rot, self.node_pos, self.ground_accel, q, u, tau, nf,
                bf, udot, tau_out, *self._flex_workspace(), self.fw_scratch)
        else:
            status = K.forward_dynamics(self.topology, self.hinge_dofs, self.joint_rot, self.joint_vec,
                                        self.spatial_inertia, self.ground_accel, q, u, tau,
                                        self._body_forces_from(node_forces, body_forces), udot, tau_out,
                                        self.ws_rot, self.ws_vec, self.ws_mat)
        if status:
            name = self.body_names[status - 1]
            raise SingularConfigurationError(
                f"articulated inertia of hinge '{self.joint_names[status - 1]}' (body '{name}') is singular: "
                f"the subtree it moves has no inertia along a free DOF (massless subtree, or a configuration "
                f"where the hinge axes align)")
        return (udot, tau_out) if return_forces else udot

    def inverse_dynamics(self, q, u, u_dot, node_forces=None, body_forces=None):
        """Generalized forces realizing ``u_dot`` (recursive Newton-Euler), external forces included."""
        tau = np.empty(self.nu)
        q = self._vector(q, self.nq, "q")
        u = self._vector(u, self.nu, "u")
        u_dot = self._vector(u_dot, self.nu, "u_dot")
        if self.is_flexible:
            nf, bf = self._flex_forces(node_forces, body_forces)
            FK.flex_inverse_dynamics(self.topology, self.joint_rot, self.joint_vec, self.flex_index,
                                     self.flex_data, self.node_body, self.node_shape, self.node_rot, self.node_pos,
                                     self.ground_accel, q, u, u_dot, nf, bf, tau, *self._flex_workspace(),
                                     self.fw_scratch)
        else:
            K.inverse_dynamics(self.topology, self.joint_rot, self.joint_vec, self.spatial_inertia,
                               self.ground_accel, q, u, u_dot, self._body_forces_from(node_forces, body_forces),
                               tau, self.ws_rot, self.ws_vec, self.ws_mat)
        return tau

    def mass_matrix(self, q):
        """Joint-space mass matrix (composite-rigid-body algorithm), symmetric (nu, nu)."""
        M = np.empty((self.nu, self.nu))
        q = self._vector(q, self.nq, "q")
        if self.is_flexible:
            FK.flex_mass_matrix(self.topology, self.joint_rot, self.joint_vec, self.flex_index, self.flex_data,
                                self.node_shape, self.node_rot, self.node_pos, q, self._zero_u, M,
                                *self._flex_workspace())
        else:
            K.mass_matrix(self.topology, self.joint_rot, self.joint_vec, self.spatial_inertia, q, M,
                          self.ws_rot, self.ws_vec, self.ws_mat)
        return M

    def bias_forces(self, q, u, node_forces=None, body_forces=None):
        """Coriolis, gyroscopic, gravity and external-force terms: ``M u_dot + bias = tau``."""
        return self.inverse_dynamics(q, u, self._zero_u, node_forces=node_forces, body_forces=body_forces)

    def _modal_matrix(self, which):
        out = np.zeros((self.nu, self.nu))
        if not self.is_flexible:
            return out
        for i, n in enumerate(self.n_modes):
            if n == 0:
                continue
            start = int(self.flex_index[i, FK.FX_K]) + (n * n if which == "damping" else 0)
            k = self.u_slices[i].stop - n
            out[k:k + n, k:k + n] = self.flex_data[start:start + n * n].reshape(n, n)
        return out

    def stiffness_matrix(self):
        """Generalized stiffness (nu, nu): the modal stiffness blocks of flexible bodies, zero elsewhere.

        At rest without gravity this is the exact linearization of the generalized forces, so
        ``K phi = omega^2 M(q0) phi`` gives the system modes."""
        return self._modal_matrix("stiffness")

    def damping_matrix(self):
        """Generalized damping (nu, nu): the modal damping blocks of flexible bodies, zero elsewhere."""
        return self._modal_matrix("damping")

    def node_kinematics(self, q, u, u_dot=None):
        """Pose, velocity and (classical) acceleration of every node; see :class:`NodeKinematics`."""
        n = self.nnodes
        rotation = np.empty((n, 3, 3))
        position = np.empty((n, 3))
        velocity = np.empty((n, 6))
        acceleration = np.empty((n, 6))
        u_dot = self._zero_u if u_dot is None else self._vector(u_dot, self.nu, "u_dot")
        q = self._vector(q, self.nq, "q")
        u = self._vector(u, self.nu, "u")
        if self.is_flexible:
            FK.flex_node_kinematics(self.topology, self.joint_rot, self.joint_vec, self.flex_index,
                                    self.flex_data, self.node_body, self.node_shape, self.node_rot, self.node_pos,
                                    q, u, u_dot, rotation, position, velocity, acceleration,
                                    *self._flex_workspace(), self.fw_scratch)
        else:
            K.node_kinematics(self.topology, self.joint_rot, self.joint_vec, self.node_body, self.node_rot,
                              self.node_pos, q, u, u_dot, rotation, position, velocity, acceleration,
                              self.ws_rot, self.ws_vec, self.ws_mat)
        return NodeKinematics(rotation, position, velocity[:, :3], velocity[:, 3:], acceleration[:, :3],
                              acceleration[:, 3:])

    def body_poses(self, q):
        """(rotations (nb, 3, 3) body -> world, origins (nb, 3) in the world)."""
        self._energy_momentum(q, self._zero_u)
        return self.ws_rot[:, K.ROT_WB].copy(), self.ws_vec[:, K.VEC_WPOS, :3].copy()

    def body_velocities(self, q, u):
        """Spatial velocities ``[omega; v]`` of every body reference frame, body axes, at its origin."""
        self._energy_momentum(q, u)
        if self.is_flexible:
            return self.fw_vec[:, FK.FV_X, :6].copy()
        return self.ws_vec[:, K.VEC_V].copy()

    def _energy_momentum(self, q, u):
        out = np.empty(8)
        q = self._vector(q, self.nq, "q")
        u = self._vector(u, self.nu, "u")
        if self.is_flexible:
            FK.flex_energy_momentum(self.topology, self.joint_rot, self.joint_vec, self.flex_index,
                                    self.flex_data, self.node_shape, self.node_rot, self.node_pos,
                                    self.ground_accel, q, u, out, *self._flex_workspace())
        else:
            K.energy_momentum(self.topology, self.joint_rot, self.joint_vec, self.spatial_inertia,
                              self.ground_accel, q, u, out, self.ws_rot, self.ws_vec, self.ws_mat)
        return out

    def kinetic_energy(self, q, u):
        return float(self._energy_momentum(q, u)[0])

    def potential_energy(self, q):
        """Potential energy: uniform gravity ``-sum m g . r_com`` (zero at the world origin) plus the
        elastic energy ``1/2 eta' K eta`` of flexible bodies."""
        return float(self._energy_momentum(q, self._zero_u)[1])

    def linear_momentum(self, q, u):
        """Total linear momentum, world axes."""
        return self._energy_momentum(q, u)[2:5]

    def angular_momentum(self, q, u):
        """Total angular momentum about the world origin, world axes."""
        return self._energy_momentum(q, u)[5:8]

    def __repr__(self):
        return (f"MultibodySystem({self.nbodies} bodies, nq={self.nq}, nu={self.nu}, "
                f"{self.nnodes} nodes)")
