"""The engine's algorithms as free functions over ``(model, data, ...)``, named for what they compute.

As Pinocchio's ``aba(model, data, q, v, tau)``: ``model`` is the immutable
:class:`dynamics.model.Model`, ``data`` a :class:`dynamics.data.Data` of it (``model.create_data()``) whose workspace
the call overwrites; nothing else is kept between calls. :class:`dynamics.MultibodySystem` (a model with its own
data) has each of them as a method.

Coordinates (docs/conventions.md): ``q`` and ``u`` concatenate, in body order, each body's hinge coordinates
(:mod:`dynamics.hinges`) followed by its modal coordinates (none for rigid bodies). Generalized forces ``tau`` are
conjugate to ``u``: a torque for a revolute DOF, a force for a prismatic one, the hinge's ``[torque; force]`` in the
outboard frame for spherical/free hinges. Node forces are spatial forces ``[torque; force]`` in node axes, applied
at the node origin; body forces ``[torque; force]`` about the body origin, body axes.

The equations are those of the kernels each function calls (:mod:`dynamics.kernels`): the articulated-body
recursion or the dense ``M udot = tau - h`` for :func:`forward_dynamics` (the model's ``solver``), recursive
Newton-Euler for :func:`inverse_dynamics`, composite rigid bodies for :func:`mass_matrix`.

The kernels take the arrays as borrowed references (:func:`dynamics.engine.borrowed`): otherwise numba increments
and decrements an atomic reference count for every view a kernel takes of them (ws_mat[i, MAT_IA], a node's slot,
...), which was 60 % of a rigid forward dynamics (a random tree of 30 bodies 16.2 -> 6.5 us, of 300 bodies
155 -> 67 us, 2026-11-28; benchmarks/rigid_vs_pinocchio.py); on the AMD EPYC machine of 2026-12-07 the
difference is within 5 % (100 bodies: 88 -> 84 us at load 4.5): atomic operations cost little there. The caller
holds ``model`` and ``data`` for the whole call, which keeps the arrays alive.
"""

from __future__ import annotations

import dataclasses
from typing import NamedTuple

import numpy as np
from numba import njit

from dynamics import kernels as K
from dynamics import layout as L
from dynamics.engine import borrowed
from dynamics.errors import SingularConfigurationError
from dynamics.model import checked_mass_properties, rigid_inertia_block

_FLOAT64 = np.dtype(np.float64)


class NodeKinematics(NamedTuple):
    """Kinematics of every node; arrays indexed like ``MultibodySystem.node_names``."""

    rotation: np.ndarray  # (n, 3, 3) node -> world
    position: np.ndarray  # (n, 3) node origin in the world
    angular_velocity: np.ndarray  # (n, 3) node axes
    linear_velocity: np.ndarray  # (n, 3) node axes, velocity of the node origin
    angular_acceleration: np.ndarray  # (n, 3) node axes
    linear_acceleration: np.ndarray  # (n, 3) node axes, classical acceleration of the node origin


@njit(cache=True)
def _borrowing_articulated_forward_dynamics(*arrays):
    return K.forward_dynamics(*borrowed(arrays))


@njit(cache=True)
def _borrowing_dense_forward_dynamics(*arrays):
    return K.forward_dynamics_dense(*borrowed(arrays))


@njit(cache=True)
def _borrowing_inverse_dynamics(*arrays):
    K.inverse_dynamics(*borrowed(arrays))


@njit(cache=True)
def _borrowing_mass_matrix(*arrays):
    K.mass_matrix(*borrowed(arrays))


@njit(cache=True)
def _borrowing_node_kinematics(*arrays):
    K.node_kinematics(*borrowed(arrays))


@njit(cache=True)
def _borrowing_energy_momentum(*arrays):
    K.energy_momentum(*borrowed(arrays))


_FORWARD_KERNELS = {"aba": _borrowing_articulated_forward_dynamics, "dense": _borrowing_dense_forward_dynamics}


def _checked(model, data):
    if data.model is not model:
        raise ValueError(f"{data!r} is not a data of {model!r}: use model.create_data()")


def _vector(x, n, what):
    if type(x) is np.ndarray and x.dtype is _FLOAT64 and x.ndim == 1 and x.shape[0] == n:
        return x  # the common case, without a conversion call
    x = np.asarray(x, dtype=np.float64)
    if x.shape != (n,):
        raise ValueError(f"{what}: expected shape ({n},), got {x.shape}")
    return x


def _forces(model, data, node_forces, body_forces):
    if node_forces is None:
        nf = data.zero_node_forces
    else:
        nf = np.asarray(node_forces, dtype=np.float64)
        if nf.shape != (model.nnodes, 6):
            raise ValueError(f"node_forces: expected shape ({model.nnodes}, 6) (one [torque; force] per "
                             f"node, node axes), got {nf.shape}")
    if body_forces is None:
        return nf, data.zero_body_forces
    bf = np.asarray(body_forces, dtype=np.float64)
    if bf.shape != (model.nbodies, 6):
        raise ValueError(f"body_forces: expected shape ({model.nbodies}, 6), got {bf.shape}")
    return nf, bf


def coordinate_rates(model, q, u):
    """Coordinate rates ``q_dot = f(q, u)`` (quaternion kinematics for spherical and free hinges, identity
    elsewhere); needs no workspace."""
    qdot = np.empty(model.nq)
    K.coordinate_rates(model.topology, _vector(q, model.nq, "q"), _vector(u, model.nu, "u"), qdot)
    return qdot


def forward_dynamics(model, data, q, u, tau=None, node_forces=None, prescribed_accel=None, body_forces=None,
                     return_forces=False):
    """Accelerations ``u_dot`` (O(N) articulated-body algorithm, or the dense solve: ``model.solver``).

    ``tau`` (nu,) generalized forces at the free DOFs; ``node_forces`` (nnodes, 6) and ``body_forces`` (nbodies, 6)
    external spatial forces; ``prescribed_accel`` (nu,) the accelerations of prescribed DOFs (zero if omitted). With
    ``return_forces`` also returns the generalized forces of all DOFs (the input ``tau`` at free DOFs, the force
    realizing the prescribed motion at prescribed DOFs). Raises :class:`dynamics.SingularConfigurationError` when a
    hinge's articulated inertia is singular."""
    if data.model is not model:
        _checked(model, data)
    nu = model.nu
    q = _vector(q, model.nq, "q")
    u = _vector(u, nu, "u")
    tau = data.zero_u if tau is None else _vector(tau, nu, "tau")
    udot = np.zeros(nu) if prescribed_accel is None else np.array(_vector(prescribed_accel, nu, "prescribed_accel"))
    tau_out = np.empty(nu)
    if node_forces is None and body_forces is None:
        nf, bf = data.zero_node_forces, data.zero_body_forces
    else:
        nf, bf = _forces(model, data, node_forces, body_forces)
    status = _FORWARD_KERNELS[model.solver](model.topology, model.nodes, model.joint_rot, model.joint_vec, data.params,
                                            q, u, tau, nf, bf, udot, tau_out, data.ws_rot, data.ws_vec, data.ws_mat,
                                            data.pool)
    if status:
        raise SingularConfigurationError(
            f"articulated inertia of hinge '{model.joint_names[status - 1]}' (body '{model.body_names[status - 1]}') "
            f"is singular: the subtree it moves has no inertia along a free DOF (massless subtree, or a configuration "
            f"where the hinge axes align)")
    return (udot, tau_out) if return_forces else udot


def inverse_dynamics(model, data, q, u, u_dot, node_forces=None, body_forces=None):
    """Generalized forces realizing ``u_dot`` (recursive Newton-Euler), external forces included."""
    _checked(model, data)
    tau = np.empty(model.nu)
    q = _vector(q, model.nq, "q")
    u = _vector(u, model.nu, "u")
    u_dot = _vector(u_dot, model.nu, "u_dot")
    nf, bf = _forces(model, data, node_forces, body_forces)
    _borrowing_inverse_dynamics(model.topology, model.nodes, model.joint_rot, model.joint_vec, data.params, q, u,
                                u_dot, nf, bf, tau, data.ws_rot, data.ws_vec, data.ws_mat, data.pool)
    return tau


def mass_matrix(model, data, q):
    """Joint-space mass matrix (composite-rigid-body algorithm), symmetric (nu, nu)."""
    _checked(model, data)
    M = np.empty((model.nu, model.nu))
    _borrowing_mass_matrix(model.topology, model.nodes, model.joint_rot, model.joint_vec, data.params,
                           _vector(q, model.nq, "q"), data.zero_u, M, data.ws_rot, data.ws_vec, data.ws_mat, data.pool)
    return M


def bias_forces(model, data, q, u, node_forces=None, body_forces=None):
    """Coriolis, gyroscopic, gravity and external-force terms: ``M u_dot + bias = tau``."""
    return inverse_dynamics(model, data, q, u, data.zero_u, node_forces=node_forces, body_forces=body_forces)


def _modal_matrix(model, column):
    out = np.zeros((model.nu, model.nu))
    for i, s in enumerate(model.u_slices):
        n = model.n_modes[i]
        if n:
            start = int(model.topology[i, L.FLEX + column])
            out[s.stop - n:s.stop, s.stop - n:s.stop] = model.params[start:start + n * n].reshape(n, n)
    return out


def stiffness_matrix(model):
    """Generalized stiffness (nu, nu): the modal stiffness blocks of flexible bodies, zero elsewhere.

    At rest without gravity this is the exact linearization of the generalized forces, so
    ``K phi = omega^2 M(q0) phi`` gives the system modes."""
    return _modal_matrix(model, L.FX_K)


def damping_matrix(model):
    """Generalized damping (nu, nu): the modal damping blocks of flexible bodies, zero elsewhere."""
    return _modal_matrix(model, L.FX_C)


def node_kinematics(model, data, q, u, u_dot=None):
    """Pose, velocity and (classical) acceleration of every node; see :class:`NodeKinematics`."""
    _checked(model, data)
    n = model.nnodes
    rotation = np.empty((n, 3, 3))
    position = np.empty((n, 3))
    velocity = np.empty((n, 6))
    acceleration = np.empty((n, 6))
    u_dot = data.zero_u if u_dot is None else _vector(u_dot, model.nu, "u_dot")
    _borrowing_node_kinematics(model.topology, model.nodes, model.joint_rot, model.joint_vec, data.params,
                               _vector(q, model.nq, "q"), _vector(u, model.nu, "u"), u_dot, rotation, position,
                               velocity, acceleration, data.ws_rot, data.ws_vec, data.ws_mat, data.pool)
    return NodeKinematics(rotation, position, velocity[:, :3], velocity[:, 3:], acceleration[:, :3],
                          acceleration[:, 3:])


def energy_momentum(model, data, q, u):
    """``[kinetic energy, potential energy, linear momentum (3), angular momentum about the world origin (3)]``,
    world axes (one pass; the functions below return its parts)."""
    _checked(model, data)
    out = np.empty(8)
    _borrowing_energy_momentum(model.topology, model.nodes, model.joint_rot, model.joint_vec, data.params,
                               _vector(q, model.nq, "q"), _vector(u, model.nu, "u"), out, data.ws_rot, data.ws_vec,
                               data.ws_mat, data.pool)
    return out


def body_poses(model, data, q):
    """(rotations (nb, 3, 3) body -> world, origins (nb, 3) in the world)."""
    energy_momentum(model, data, q, data.zero_u)
    return data.ws_rot[:, L.ROT_WB].copy(), data.ws_vec[:, L.VEC_WPOS, :3].copy()


def body_velocities(model, data, q, u):
    """Spatial velocities ``[omega; v]`` of every body reference frame, body axes, at its origin."""
    energy_momentum(model, data, q, u)
    return data.ws_vec[:, L.VEC_V].copy()


def kinetic_energy(model, data, q, u):
    return float(energy_momentum(model, data, q, u)[0])


def potential_energy(model, data, q):
    """Potential energy: uniform gravity ``-sum m g'r_com`` (zero at the world origin) plus the elastic energy
    ``1/2 eta' K eta`` of flexible bodies."""
    return float(energy_momentum(model, data, q, data.zero_u)[1])


def linear_momentum(model, data, q, u):
    """Total linear momentum, world axes."""
    return energy_momentum(model, data, q, u)[2:5]


def angular_momentum(model, data, q, u):
    """Total angular momentum about the world origin, world axes."""
    return energy_momentum(model, data, q, u)[5:8]


def set_mass_properties(model, data, body, mass, com, inertia):
    """Change rigid body ``body``'s mass, center of mass and inertia (about the COM) for the run of ``data``, O(1)
    once the data has its own mass properties (it takes a copy of the model's at the first change: the model and
    every other data keep theirs). For mass depletion and per-run dispersions; a new model with other mass
    properties is :meth:`dynamics.model.Model.with_mass_properties`. Validated like
    :meth:`dynamics.Multibody.add_body`'s (:func:`dynamics.definitions.rigid_mass_properties`)."""
    _checked(model, data)
    i, o = rigid_inertia_block(model, body)
    mass, com, inertia, M = checked_mass_properties(body, mass, com, inertia)
    data.own_mass_properties()
    data.params.setflags(write=True)
    data.params[o:o + 36] = M.ravel()
    data.params.setflags(write=False)
    data.masses.setflags(write=True)
    data.masses[i] = mass
    data.masses.setflags(write=False)
    bodies = list(data.definitions[0])
    bodies[i] = dataclasses.replace(bodies[i], mass=mass, com=com, inertia=inertia)
    data.definitions = (tuple(bodies),) + data.definitions[1:]
