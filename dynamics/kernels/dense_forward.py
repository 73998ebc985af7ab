"""Forward dynamics by the dense solve ``M(q) udot = tau - h`` (composite-rigid-body mass matrix, Newton-Euler
bias and a dense Cholesky factorization): the contract of :func:`dynamics.kernels.articulated_body.forward_dynamics`,
chosen at compile time where it is cheaper (``MultibodySystem.solver``, :func:`dynamics.system.choose_solver`).
"""

from __future__ import annotations

from numba import njit

from dynamics import flexible_kernels as FK
from dynamics.kernels.composite_body import mass_matrix
from dynamics.kernels.kinematics import accelerations
from dynamics.kernels.newton_euler import inverse_dynamics
from dynamics.layout import GROUND_ACCEL, NU_HINGE, N_MODES, N_PRESCRIBED, PRESCRIBED_DOFS, U_START, view


@njit(cache=True)
def forward_dynamics_dense(topology, nodes, joint_rot, joint_vec, params, q, u, tau, node_forces, body_forces, udot,
                           tau_out, ws_rot, ws_vec, ws_mat, pool):
    """The contract of :func:`forward_dynamics` solved densely: ``h`` from :func:`inverse_dynamics` at the
    prescribed accelerations, ``M`` from :func:`mass_matrix`, then ``M_ff udot_f = tau_f - h_f`` by a
    Cholesky factorization of M with its prescribed rows and columns replaced by the identity; the
    prescribed DOFs' forces from a second inverse dynamics when there are any. O(nu^3); uses the last
    ``nu^2 + 2 nu`` numbers of ``pool``. Returns 0, or 1 + the index of the body owning a DOF at which
    the mass matrix is singular."""
    nb = topology.shape[0]
    last = nb - 1
    nu = topology[last, U_START] + topology[last, NU_HINGE] + topology[last, N_MODES]
    base = pool.shape[0] - nu * nu - 2 * nu
    M = view(pool, base, nu, nu)
    h = pool[base + nu * nu:base + nu * nu + nu]
    a0 = pool[base + nu * nu + nu:base + nu * nu + 2 * nu]
    for k in range(nu):
        a0[k] = 0.0
    npres = 0
    for i in range(nb):
        u0 = topology[i, U_START]
        for kk in range(topology[i, N_PRESCRIBED]):
            k = u0 + topology[i, PRESCRIBED_DOFS + kk]
            a0[k] = udot[k]
            npres += 1
    inverse_dynamics(topology, nodes, joint_rot, joint_vec, params, q, u, a0, node_forces, body_forces, h, ws_rot,
                     ws_vec, ws_mat, pool)
    mass_matrix(topology, nodes, joint_rot, joint_vec, params, q, u, M, ws_rot, ws_vec, ws_mat, pool)
    for k in range(nu):
        h[k] = tau[k] - h[k]
    for i in range(nb):
        u0 = topology[i, U_START]
        for kk in range(topology[i, N_PRESCRIBED]):
            k = u0 + topology[i, PRESCRIBED_DOFS + kk]
            for j in range(nu):
                M[k, j] = 0.0
                M[j, k] = 0.0
            M[k, k] = 1.0
            h[k] = 0.0
    bad = FK.cholesky_in_place(M, nu)
    if bad >= 0:
        for i in range(nb):
            if bad < topology[i, U_START] + topology[i, NU_HINGE] + topology[i, N_MODES]:
                return 1 + i
    FK.cholesky_solve(M, nu, h)
    for k in range(nu):
        udot[k] = h[k]
        tau_out[k] = tau[k]
    for i in range(nb):
        u0 = topology[i, U_START]
        for kk in range(topology[i, N_PRESCRIBED]):
            k = u0 + topology[i, PRESCRIBED_DOFS + kk]
            udot[k] = a0[k]
    if npres > 0:
        inverse_dynamics(topology, nodes, joint_rot, joint_vec, params, q, u, udot, node_forces, body_forces, a0,
                         ws_rot, ws_vec, ws_mat, pool)
        for i in range(nb):
            u0 = topology[i, U_START]
            for kk in range(topology[i, N_PRESCRIBED]):
                k = u0 + topology[i, PRESCRIBED_DOFS + kk]
                tau_out[k] = a0[k]
    else:
        accelerations(topology, nodes, params[GROUND_ACCEL:GROUND_ACCEL + 6], udot, ws_rot, ws_vec, ws_mat, pool)
    return 0
