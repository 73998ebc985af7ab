"""The linear part of a flexible multibody system's dynamics: what an exponential integrator propagates exactly.

For a :class:`dynamics.MultibodySystem` with state ``x = [q; u]`` the elastic forces are linear in the modal
coordinates: the engine's equations of motion are (:mod:`dynamics.flexible_kernels`, TM-2020-5008164 eqs.
E.2.6-E.2.7)

    d(eta)/dt = eta_dot                                          (coordinate rates, exact)
    M(q) u_dot = tau - K_aug eta - D_aug u - b(q, u)             (b: velocity products, gravity, forces)

with ``K_aug`` and ``D_aug`` the modal stiffness and damping blocks placed at the modal DOFs
(``system.stiffness_matrix()``, ``system.damping_matrix()``), which act on ``eta`` through the modal columns.
Freezing the mass matrix at a configuration ``q0`` and splitting ``u`` into free DOFs ``f`` (prescribed DOFs
take their acceleration from an input and are not part of the dynamics) gives

    d/dt [eta; u_f] = L [eta; u_f] + N(x),

    L = [[ 0,                                 E            ],
         [ -M_ff(q0)^-1 K_aug[f, modal],      -M_ff(q0)^-1 D_aug[f, f] ]]

with ``E`` the selection ``eta_dot = u[modal]`` (a 0/1 matrix) and the remainder

    N(x) = f(x) - L x  =  [0;  (M_ff(q)^-1 - M_ff(q0)^-1)(-K_aug eta - D_aug u) + M_ff(q)^-1 (tau - b - M_fp a_p)].

``L`` is the Jacobian of the dynamics with respect to ``(eta, u_f)`` at rest (``u = 0``, where the velocity
products are quadratic and contribute nothing, and without gravity; with gravity the load-dependent
geometric stiffness of order-1/2 modal integrals is left in ``N``, it is small against ``K``), except for
spinning rotors on deforming nodes: a rotor's spin momentum ``h`` couples the node's rotation rates to its
torque ``(lambda eta_dot) x h``, and through the node's rotational mode shapes ``lambda`` (whose sum of squares
grows with every mode that rotates the node) that coupling is as stiff as the modes themselves (a 5 N m s
wheel on the middle grid of the 196-mode tube of benchmarks/flexible_observatory.py: ``h rho(N) = 136`` at
1 ms, against a stability limit of 2.8). ``L`` therefore takes the gyroscopic term at the rotors' current
spin rates in the columns of the carrier's modal rates (:func:`rotor_gyroscopic_coupling`),
and ``N`` keeps the slow rest (the coupling with the rigid rates, the change of the spin). Its
eigenvalues are the system modes of the assembled structure at ``q0`` (the generalized eigenproblem
``K_aug phi = omega^2 M phi`` of :mod:`dynamics.modal_analysis`, with damping), plus zeros for the rigid DOFs.
All the stiffness of the problem (frequencies up to the top retained mode) is in ``L``; ``N`` carries
rigid-body motion, gyroscopic and centrifugal terms, actuator and environment forces, which vary on the
time scale of the rigid motion. An exponential integrator (Hochbruck & Ostermann, "Exponential
integrators", Acta Numerica 19, 2010, eq. 1.1) integrates ``L`` exactly and ``N`` explicitly, so its step is
limited by ``N`` and not by the top mode.

When the configuration changes (refresh or not): ``L`` depends on ``q`` only through ``M(q)``.

* A free or spherical base hinge does not enter ``M``: velocities are in body axes, so the mass matrix of a
  free-flying structure does not depend on its attitude or position.
* A rotor (a rigid body without children on a revolute hinge: a reaction wheel) enters ``L`` with its inertia
  averaged over its spin angle (:func:`spin_averaged_inertia`: the axial moment kept, the transverse ones made
  equal, the centre of mass put on the axis), so ``L`` does not depend on the rotor's angle: an axisymmetric
  wheel is unchanged by the averaging, and an unbalanced one (a real imbalance: products of inertia, a centre
  of mass off the axis) no longer makes ``L`` drift at every turn (each drift is a rebuild of the matrix
  functions by forward differences, m + 1 derivative evaluations); its imbalance, a small part of ``M``, is
  in ``N``. The observatory scene (free structure, four wheels) therefore has a constant ``L`` up to the
  ``O(eta)`` terms of the order-1/2 modal integrals, which are of the size of the elastic deflection.
* Articulated parts that rotate a lot relative to each other (a solar-array drive turning a flexible
  array, a gimbaled flexible boom) change ``M_ff(q)`` and hence the system modes. The stiff term
  ``(M_ff(q)^-1 - M_ff(q0)^-1) K_aug eta`` then sits in ``N`` and is integrated explicitly: stable and
  accurate only while ``h ||L(q) - L(q0)||`` stays small. The exponential integrator
  (:mod:`shell.integrators.exponential`) therefore takes this function as a callable (the shell passes it
  so), re-evaluates it every few steps (with back-off while it does not move) and recomputes its matrix
  functions when ``L`` has moved by more than 0.1 %; it also watches the stiffness of ``N`` on every step
  (and warns if it was given a fixed ``(indices, L)``). The observatory never triggers a rebuild.

Cost: one mass matrix (composite-body algorithm) and one Cholesky solve with ``n_modes + 1`` right-hand
sides, ``O(nu^3)``: 0.7 ms for the 60-mode observatory (a fifth of one derivative evaluation), negligible
against the matrix functions computed from ``L``.
"""

from __future__ import annotations

import numpy as np
import scipy.linalg


def modal_indices(system):
    """(positions of every flexible body's modal coordinates in ``q``, positions of their rates in ``u``)."""
    q_index, u_index = [], []
    for b, n in enumerate(system.n_modes):
        if n:
            q_index.extend(range(system.q_slices[b].stop - n, system.q_slices[b].stop))
            u_index.extend(range(system.u_slices[b].stop - n, system.u_slices[b].stop))
    return np.asarray(q_index, dtype=np.int64), np.asarray(u_index, dtype=np.int64)


def spin_averaged_inertia(mass, com, inertia, point, axis):
    """``(mass, com, inertia about the com)`` of a rigid body averaged over its rotation about the line through
    ``point`` along the unit ``axis`` (body frame): the centre of mass projected on the line, the inertia
    about ``point`` replaced by its mean over the angle, ``(a' J a) a a' + (tr J - a' J a) / 2 (I - a a')``."""
    a = np.asarray(axis, dtype=float)
    d = np.asarray(com, dtype=float) - point
    J_point = np.asarray(inertia, dtype=float) + mass * (d @ d * np.eye(3) - np.outer(d, d))
    axial = a @ J_point @ a
    J_mean = axial * np.outer(a, a) + 0.5 * (np.trace(J_point) - axial) * (np.eye(3) - np.outer(a, a))
    d_mean = (d @ a) * a
    J_com = J_mean - mass * (d_mean @ d_mean * np.eye(3) - np.outer(d_mean, d_mean))
    return mass, point + d_mean, 0.5 * (J_com + J_com.T)


def _rotors_averaged(system):
    """``system`` itself, or a copy whose rotors (rigid bodies without children on revolute hinges) have their
    spin-averaged inertia (:func:`spin_averaged_inertia`)."""
    bodies = system.definitions[0]
    has_children = {p for p in system.parents if p >= 0}
    rotors = [i for i, b in enumerate(bodies)
              if b.flexible is None and b.hinge == "revolute" and i not in has_children]
    if not rotors:
        return system
    averaged = system.copy(mass_properties=True)
    for i in rotors:
        b = bodies[i]
        axis = b.outboard_rotation @ b.axes[0]  # hinge axis in the body frame (outboard frame M -> body)
        averaged.set_mass_properties(b.name, *spin_averaged_inertia(b.mass, b.com, b.inertia, b.outboard_position,
                                                                    axis))
    return averaged


def rotor_gyroscopic_coupling(system, u):
    """``C`` (nu x nu): ``d(bias)/d(eta_dot)`` of the spin momentum of every rotor hinged on a node of a flexible
    body, ``-J' [h x] lambda`` in the carrier's rows and its modal-rate columns, with ``J = [S_rot, lambda]`` the
    node's angular velocity per unit rate of the carrier's hinge (its motion subspace's rotational rows, body axes:
    left in the workspace by the last kinematics pass of ``system`` at the configuration) and of its modes
    (``lambda``, the node's rotational mode shapes), and ``h = J_a s a`` the rotor's spin momentum (axial moment
    about its hinge point, spin rate, axis in the carrier's axes): the gyroscopic coupling of the node's elastic
    rotation rates.
    (The coupling of the rigid rates, of the carrier and its ancestors, is slow, as the rigid motion, and stays in
    ``N``; in ``L`` it would also couple the rigid velocities' zero eigenvalues into a defective matrix.)"""
    from dynamics.layout import MAT_S

    bodies, nodes, _ = system.definitions
    has_children = {p for p in system.parents if p >= 0}
    node_index = {nd.name: k for k, nd in enumerate(nodes)}
    C = np.zeros((system.nu, system.nu))
    for i, b in enumerate(bodies):
        carrier = system.parents[i]
        if (b.flexible is not None or b.hinge != "revolute" or i in has_children or carrier < 0
                or bodies[carrier].flexible is None or b.parent_node is None):
            continue
        node = nodes[node_index[b.parent_node]]
        span = system.u_slices[carrier]
        n = system.n_modes[carrier]
        nh = span.stop - span.start - n
        J = np.concatenate([system.ws_mat[carrier, MAT_S, :3, :nh], np.asarray(node.shape, dtype=float)[:3]], axis=1)
        a_rotor = b.outboard_rotation @ b.axes[0]
        d = b.com - b.outboard_position
        J_point = b.inertia + b.mass * (d @ d * np.eye(3) - np.outer(d, d))
        spin = u[system.u_slices[i].start]
        h = (a_rotor @ J_point @ a_rotor) * spin * (node.rotation @ b.inboard_rotation @ b.axes[0])
        skew = np.array([[0.0, -h[2], h[1]], [h[2], 0.0, -h[0]], [-h[1], h[0], 0.0]])
        modal = slice(span.stop - n, span.stop)
        C[span, modal] -= J.T @ skew @ J[:, nh:]
    return C


def modal_linear_part(system, q, u=None):
    """``(indices, L)``: the linear part of ``d/dt [q; u]`` over ``indices`` into ``[q; u]`` (module docstring);
    ``u`` gives the rotors' spin rates (none when omitted).

    ``indices`` lists the modal coordinates (positions in ``q``) followed by every free velocity
    (positions ``system.nq + k`` in ``[q; u]``); ``L`` is square over them. A system without flexible bodies
    has no linear part: both are empty.
    """
    q = np.asarray(q, dtype=np.float64)
    if q.shape != (system.nq,):
        raise ValueError(f"modal_linear_part: q must have shape ({system.nq},), got {q.shape}")
    if not np.all(np.isfinite(q)):
        raise ValueError("modal_linear_part: q has non-finite components "
                         f"{np.flatnonzero(~np.isfinite(q))[:10].tolist()}")
    eta_q, eta_u = modal_indices(system)
    if eta_q.size == 0:
        return np.zeros(0, dtype=np.int64), np.zeros((0, 0))
    free = np.flatnonzero(~np.asarray(system.prescribed_dofs))
    n_eta, n_free = eta_q.size, free.size
    # modal DOFs are always free (they are not hinge DOFs): their positions among the free velocities
    position_in_free = np.full(system.nu, -1, dtype=np.int64)
    position_in_free[free] = np.arange(n_free)
    eta_in_free = position_in_free[eta_u]
    averaged = _rotors_averaged(system)
    M_ff = averaged.mass_matrix(q)[np.ix_(free, free)]
    K_aug = system.stiffness_matrix()
    D_aug = system.damping_matrix()
    try:
        factor = scipy.linalg.cho_factor(M_ff)
    except np.linalg.LinAlgError:
        raise ValueError("modal_linear_part: the mass matrix of the free DOFs is not positive definite at this "
                         "configuration (a massless subtree or aligned hinge axes)") from None
    if u is not None:
        D_aug = D_aug + rotor_gyroscopic_coupling(averaged, np.asarray(u, dtype=np.float64))
    rhs = np.concatenate([K_aug[np.ix_(free, eta_u)], D_aug[np.ix_(free, free)]], axis=1)
    solved = scipy.linalg.cho_solve(factor, rhs)
    L = np.zeros((n_eta + n_free, n_eta + n_free))
    L[np.arange(n_eta), n_eta + eta_in_free] = 1.0
    L[n_eta:, :n_eta] = -solved[:, :n_eta]
    L[n_eta:, n_eta:] = -solved[:, n_eta:]
    indices = np.concatenate([eta_q, system.nq + free]).astype(np.int64)
    return indices, L
