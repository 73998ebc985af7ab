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
spin rates in the columns of the carrier's modal rates (:func:`rotor_gyroscopic_factors`),
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

Cost: one mass matrix (composite-body algorithm, of the copy with averaged rotors, kept between calls), its
Cholesky factor, ``O(nu^3)``, and the columns of ``M_ff^-1`` that the right-hand sides need: ``K_aug`` and
``D_aug`` are the flexible bodies' modal blocks, non-zero in the modal rows only, so ``M_ff^-1 [K_aug | D_aug] =
M_ff^-1 [e_r] [K_aug | D_aug][rows]`` takes one solve per modal row (a diagonal block, as a body file's stiffness
is, then scales those columns: the same numbers as the product), and the gyroscopic coupling of the rotors on one
node has rank 3 (``-J' [h x] J_e``, :func:`rotor_gyroscopic_factors`), three solves per node: 199 right-hand sides
for the 196-mode observatory of benchmarks/flexible_observatory.py instead of the 402 columns of ``[K_aug[f,
modal] | D_aug[f, f] + C]``: the whole evaluation 5.1 -> 3.6 ms, with the kept copy (2026-12-07, interleaved in
one process, medians of 9, load 3.4; of the 3.6 ms the mass matrix is about 1.3, the solve 0.9). The result
equals the solve of those 402 columns to round-off (tests/flexible/test_modal_linear_part.py).
"""

from __future__ import annotations

import weakref

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


#: the spin-averaged copy of each system data seen (:func:`_rotors_averaged`), with the mass properties it was made
#: from; weak, so a run's systems are not kept alive by it
_AVERAGED: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def _rotors_averaged(system):
    """``system`` itself, or a copy whose rotors (rigid bodies without children on revolute hinges) have their
    spin-averaged inertia (:func:`spin_averaged_inertia`). The copy is kept per system data while that data's mass
    properties are the same objects (``set_mass_properties`` replaces the definitions, so a change makes a new copy):
    the exponential integrator's checks evaluate the linear part every few hundred steps, and making the copy was 0.7
    of their 5 ms on the observatory."""
    bodies = system.definitions[0]
    has_children = {p for p in system.parents if p >= 0}
    rotors = [i for i, b in enumerate(bodies)
              if b.flexible is None and b.hinge == "revolute" and i not in has_children]
    if not rotors:
        return system
    data = system.data
    kept = _AVERAGED.get(data)
    if kept is not None and kept[0] is data.definitions and kept[1] is data.params and kept[2] is data.masses:
        return kept[3]
    averaged = system.copy(mass_properties=True)
    for i in rotors:
        b = bodies[i]
        axis = b.outboard_rotation @ b.axes[0]  # hinge axis in the body frame (outboard frame M -> body)
        averaged.set_mass_properties(b.name, *spin_averaged_inertia(b.mass, b.com, b.inertia, b.outboard_position,
                                                                    axis))
    _AVERAGED[data] = (data.definitions, data.params, data.masses, averaged)
    return averaged


def rotor_gyroscopic_factors(system, u):
    """The gyroscopic coupling of the rotors hinged on nodes of flexible bodies, ``d(bias)/d(eta_dot)``, as factors
    ``(rows, columns, J, h)`` per carrier node: the coupling is ``-J' [h x] J_e`` in the carrier's rows (``rows``,
    its u-slice) and modal-rate columns (``columns``), with ``J = [S_rot, lambda]`` (3 x rows) the node's angular
    velocity per unit rate of the carrier's hinge (its motion subspace's rotational rows, body axes: left in the
    workspace by the last kinematics pass of ``system`` at the configuration) and of its modes (``lambda``, the
    node's rotational mode shapes; ``J_e`` its modal columns), and ``h`` the sum over the node's rotors of their
    spin momenta ``J_a s a`` (axial moment about the hinge point, spin rate, axis in the carrier's axes): the
    gyroscopic coupling of the node's elastic rotation rates, of rank 3 per node (the rotors of one node share J).
    (The coupling of the rigid rates, of the carrier and its ancestors, is slow, as the rigid motion, and stays in
    ``N``; in ``L`` it would also couple the rigid velocities' zero eigenvalues into a defective matrix.)"""
    from dynamics.layout import MAT_S

    bodies, nodes, _ = system.definitions
    has_children = {p for p in system.parents if p >= 0}
    node_index = {nd.name: k for k, nd in enumerate(nodes)}
    factors = {}
    for i, b in enumerate(bodies):
        carrier = system.parents[i]
        if (b.flexible is not None or b.hinge != "revolute" or i in has_children or carrier < 0
                or bodies[carrier].flexible is None or b.parent_node is None):
            continue
        node = nodes[node_index[b.parent_node]]
        if (carrier, b.parent_node) not in factors:
            span = system.u_slices[carrier]
            n = system.n_modes[carrier]
            nh = span.stop - span.start - n
            J = np.concatenate([system.ws_mat[carrier, MAT_S, :3, :nh], np.asarray(node.shape, dtype=float)[:3]],
                               axis=1)
            factors[carrier, b.parent_node] = [np.arange(span.start, span.stop), np.arange(span.stop - n, span.stop),
                                               J, np.zeros(3)]
        a_rotor = b.outboard_rotation @ b.axes[0]
        d = b.com - b.outboard_position
        J_point = b.inertia + b.mass * (d @ d * np.eye(3) - np.outer(d, d))
        spin = u[system.u_slices[i].start]
        factors[carrier, b.parent_node][3] += ((a_rotor @ J_point @ a_rotor) * spin
                                               * (node.rotation @ b.inboard_rotation @ b.axes[0]))
    return [tuple(f) for f in factors.values()]


def _skew(h):
    return np.array([[0.0, -h[2], h[1]], [h[2], 0.0, -h[0]], [-h[1], h[0], 0.0]])


def _times(X, B):
    """``X @ B``; a square ``B`` whose off-diagonal entries are all zero (a modal stiffness or damping block: the
    body file's is diagonal) scales the columns of X instead, which gives the same numbers (the product's other
    terms are exact zeros) in O(size of X)."""
    if B.shape[0] == B.shape[1] and np.count_nonzero(B) == np.count_nonzero(np.diagonal(B)):
        return X * np.diagonal(B)
    return X @ B


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
    try:
        factor = scipy.linalg.cho_factor(M_ff)
    except np.linalg.LinAlgError:
        raise ValueError("modal_linear_part: the mass matrix of the free DOFs is not positive definite at this "
                         "configuration (a massless subtree or aligned hinge axes)") from None
    K_e = system.stiffness_matrix()[np.ix_(free, eta_u)]
    D_ff = system.damping_matrix()[np.ix_(free, free)]
    # M^-1 [K_e | D_ff + C] from the columns of M^-1 that their rows need (module docstring, "Cost")
    rows = np.flatnonzero(K_e.any(axis=1) | D_ff.any(axis=1))
    damped = np.flatnonzero(D_ff.any(axis=0))
    gyroscopic = rotor_gyroscopic_factors(averaged, np.asarray(u, dtype=np.float64)) if u is not None else []
    rhs = np.zeros((n_free, rows.size + 3 * len(gyroscopic)))
    rhs[rows, np.arange(rows.size)] = 1.0
    for g, (span, _, J, _) in enumerate(gyroscopic):
        kept = position_in_free[span] >= 0  # a prescribed hinge DOF of the carrier is not a row of L
        rhs[position_in_free[span[kept]], rows.size + 3 * g:rows.size + 3 * g + 3] = J.T[kept]
    solved = scipy.linalg.cho_solve(factor, rhs)
    unit = solved[:, :rows.size]  # the columns of M_ff^-1 at rows
    L = np.zeros((n_eta + n_free, n_eta + n_free))
    L[np.arange(n_eta), n_eta + eta_in_free] = 1.0
    L[n_eta:, :n_eta] = -_times(unit, K_e[rows])
    if damped.size:
        L[n_eta:, n_eta + damped] = -_times(unit, D_ff[np.ix_(rows, damped)])
    for g, (_, columns, J, h) in enumerate(gyroscopic):
        n = columns.size
        L[n_eta:, n_eta + position_in_free[columns]] += solved[:, rows.size + 3 * g:rows.size + 3 * g + 3] @ (
            _skew(h) @ J[:, J.shape[1] - n:])
    indices = np.concatenate([eta_q, system.nq + free]).astype(np.int64)
    return indices, L
