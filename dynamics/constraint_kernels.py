"""Compiled closure constraints and force elements on a tree: the constrained forward dynamics, drift
projection and reaction loads (numba; arrays in, arrays out, nothing allocated per call).

A closed-chain scene is a spanning tree (:class:`dynamics.MultibodySystem`) plus closure constraints that
tie node frame B (``node_b``, or a fixed world pose) to node frame A (``node_a``), plus force elements
between nodes and on hinges (:mod:`dynamics.force_elements`). FModal paper (IEEE Aerospace 2023),
"Closure Constraints"; Jain, *Robot and Multibody Dynamics*, 2011, ch. 11.

Constraint kinematics, every quantity in A's axes (``R_A`` node A -> world, ``rho = R_A'(p_B - p_A)``,
``w`` the angular velocity of A in A axes, node velocities and classical accelerations from
:func:`dynamics.kernels.node_kinematics`, elastic motion included)::

    relative angular velocity    w_rel = R_A'(w_B - w_A)
    relative linear velocity     v_rel = rho_dot = R_A'(v_B - v_A) - w x rho   (B's origin relative to the
                                 point of A that coincides with it)
    their rates                  dw_rel = R_A'(dw_B - dw_A) - w x w_rel
                                 rho_ddot = R_A'(a_B - a_A) - 2 w x rho_dot - w x (w x rho) - dw_A x rho

A constraint constrains the rows ``S [w_rel; v_rel]`` (S in A axes): all six (``weld``), the translations
(``ball``), the translations and the rotations perpendicular to an axis ``n`` (``revolute``), the rotations
and the translations perpendicular to ``n`` (``prismatic``), or the distance ``|rho|`` (``distance``, the row
``[0, rho/|rho|]``, with the extra rate term ``(|rho_dot|^2 - (rho_hat . rho_dot)^2) / |rho|``). Position
residuals: ``log(R_A' R_B)`` (weld, prismatic), ``n x (R_A' R_B n)`` (revolute, zero exactly when the axes
align; its rate is the perpendicular ``w_rel`` on the manifold), ``rho`` (selected rows), ``|rho| - L``.

``G u`` are those velocity rows and ``k = G_dot u`` the rate rows at ``u_dot = 0`` (node accelerations are
affine in ``u_dot``). The transpose of ``G`` is the generalized force of the constraint wrench: row r's
unit multiplier is the wrench ``S_r'`` that A exerts on B (A axes, at B's origin), and ``-S_r'`` moved to A's
origin on A; :func:`node_forces_generalized` (the Newton-Euler backward pass, ``J' f``) turns the pair into
column r of ``G'``, so ``G`` is exactly the velocity map whatever the bodies (rigid or flexible).

Dynamics (index-1 form, Baumgarte 1972 stabilization with gains alpha, beta [1/s])::

    M u_dot = tau - h + G' lambda,      G u_dot = -k - 2 alpha G u - beta^2 phi

solved as ``u_dot = u_dot_free + M^-1 G' lambda`` with ``u_dot_free`` from the engine's forward dynamics
(O(N) articulated-body algorithm or its dense solve), ``M`` from the composite-body algorithm and one
Cholesky factorization, and ``(G M^-1 G') lambda = -k - 2 alpha G u - beta^2 phi - G u_dot_free``.
Redundant rows (a planar loop closed by a spatial revolute) make ``G M^-1 G'`` singular: the minimum-norm
multipliers (pivoted Cholesky stopped at the numerical rank, relative tolerance 1e-10, then the
basic solution projected onto the range) keep the motion unique. Prescribed hinge
DOFs keep their accelerations (``M^-1`` acts on the free DOFs only) and report the force realizing them
with the constraint forces included.

Drift: :func:`project_positions` (Newton on ``phi(q) = 0`` along ``dq = -M^-1 G' (G M^-1 G')^+ phi``, the
least kinetic-energy correction, applied through the coordinate rates with quaternion renormalization)
and :func:`project_velocities` (``u <- u - M^-1 G' (G M^-1 G')^+ G u``, the M-orthogonal projection onto
``G u = 0``, which is also the perfectly plastic impact of a constraint switched on).

Reaction loads: :func:`hinge_loads` (the spatial force each hinge transmits, from the Newton-Euler pass
with every applied, element and constraint force) and the constraint loads ``S' lambda`` per constraint.

The entry points take the engine's :class:`dynamics.engine.EngineData` and a :class:`ConstraintData` and use
their arrays as borrowed references (:func:`dynamics.engine.borrowed`; their owner, the
:class:`dynamics.constraints.ConstrainedSystem` or the simulation's context, keeps them alive): reference
counting of the ~40 arrays passed down the calls was 2/3 of a four-bar's constrained evaluation (54 -> 19 us;
the tree's forward dynamics alone: 5-6 us).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit

from dynamics import engine as E
from dynamics import flexible_kernels as FK
from dynamics import kernels as K
from dynamics.force_elements import add_wrench_pair, apply_force_elements, force_element_energy, frame_b
from dynamics.kernels.body_terms import apply_node_forces
from dynamics.kernels.kinematics import body_kinematics
from dynamics.kernels.newton_euler import transmit_forces
from dynamics.layout import (
    FLEX, FX_P_VEC, N_MODES, N_PRESCRIBED, OUTBOARD, OUTBOARD_NODE, PRESCRIBED_DOFS, PV_FORCE, ROT_BM, U_START, VEC_P,
    VEC_PBM)
from dynamics.vector3 import cross, rotate, rotate_back, rotation_log

# constraint kinds
WELD = 0
BALL = 1
REVOLUTE = 2
PRISMATIC = 3
DISTANCE = 4
KINDS = {"weld": WELD, "ball": BALL, "revolute": REVOLUTE, "prismatic": PRISMATIC, "distance": DISTANCE}
ROWS = {WELD: 6, BALL: 3, REVOLUTE: 5, PRISMATIC: 5, DISTANCE: 1}

# constraint table columns (int64, one row per constraint)
C_KIND = 0
C_NODE_A = 1
C_NODE_B = 2  # -1: the world pose in C_WORLD_R / C_WORLD_P
C_ROWS = 3
C_ACTIVE = 4  # 0: switched off (its rows are skipped; an event may switch it on)
C_INT_COLUMNS = 5

# constraint float columns (one row per constraint)
C_WORLD_R = 0  # 9: rotation of the world frame B (B -> world), row major
C_WORLD_P = 9  # 3: its origin
C_AXIS = 12  # 3: the revolute / prismatic axis n in A's axes
C_SELECT = 15  # 36: the selection S (rows x 6) in A's axes, row major
C_LENGTH = 51  # the distance constraint's length
C_FLOAT_COLUMNS = 52

RANK_TOLERANCE = 1e-10


class ConstraintData(NamedTuple):
    """Constraints, force elements and the scratch of :func:`forward_dynamics` (built by
    :class:`dynamics.constraints.ConstrainedSystem`; one per simulation, like the engine's data)."""

    c_int: np.ndarray         # (nc, C_INT_COLUMNS) int64
    c_float: np.ndarray       # (nc, C_FLOAT_COLUMNS)
    gains: np.ndarray         # [alpha, beta] Baumgarte gains [1/s]
    f_int: np.ndarray         # (ne, force element int columns), dynamics.force_elements
    f_float: np.ndarray       # (ne, force element float columns)
    rotation: np.ndarray      # (nn, 3, 3) node kinematics scratch
    position: np.ndarray      # (nn, 3)
    velocity: np.ndarray      # (nn, 6)
    acceleration: np.ndarray  # (nn, 6)
    forces: np.ndarray        # (nn, 6) applied + element + constraint node forces of the last evaluation
    unit: np.ndarray          # (nn, 6) one constraint row's wrench as node forces
    tau: np.ndarray           # (nu,) applied + element generalized forces of the last evaluation
    zero_u: np.ndarray        # (nu,) zeros
    work: np.ndarray          # (nu,) scratch
    G: np.ndarray             # (m, nu) constraint Jacobian of the active rows
    Yt: np.ndarray            # (m, nu) rows of (M^-1 G')'
    M: np.ndarray             # (nu, nu) mass matrix, then its Cholesky factor
    M_full: np.ndarray        # (nu, nu) the mass matrix kept when there are prescribed DOFs
    A: np.ndarray             # (m, m) G M^-1 G'
    V: np.ndarray             # (m, m) a basis of its null space (redundant rows)
    phi: np.ndarray           # (m,) position residual
    gu: np.ndarray            # (m,) G u
    k: np.ndarray             # (m,) G_dot u
    rhs: np.ndarray           # (m,)
    lam: np.ndarray           # (m,) multipliers of the active rows
    scratch: np.ndarray       # (32,)
    frames: np.ndarray        # (2, 3, 3)
    qdot: np.ndarray          # (nq,)


@njit(cache=True)
def relative_motion(c_int, c_float, i, rotation, position, velocity, acceleration, RB, Rrel, out):
    """Frame B relative to frame A (module docstring), A axes: ``Rrel = R_A' R_B`` (``RB`` scratch) and into
    ``out`` (24): ``[0:3] rho``, ``[3:6] w_rel``, ``[6:9] rho_dot``, ``[9:12] dw_rel``, ``[12:15] rho_ddot`` (the
    last two from the node accelerations given: the rate rows at ``u_dot = 0`` when those are)."""
    a = c_int[i, C_NODE_A]
    b = c_int[i, C_NODE_B]
    RA = rotation[a]
    pb0, pb1, pb2 = frame_b(rotation, position, b, c_float[i], C_WORLD_R, C_WORLD_P, RB)
    for r in range(3):
        for s in range(3):
            Rrel[r, s] = RA[0, r] * RB[0, s] + RA[1, r] * RB[1, s] + RA[2, r] * RB[2, s]
    rho0, rho1, rho2 = rotate_back(RA, pb0 - position[a, 0], pb1 - position[a, 1], pb2 - position[a, 2])
    w0, w1, w2 = velocity[a, 0], velocity[a, 1], velocity[a, 2]
    dw0, dw1, dw2 = acceleration[a, 0], acceleration[a, 1], acceleration[a, 2]
    wb0 = wb1 = wb2 = vb0 = vb1 = vb2 = dwb0 = dwb1 = dwb2 = ab0 = ab1 = ab2 = 0.0
    if b >= 0:  # B's velocities and accelerations in A's axes
        wb0, wb1, wb2 = rotate(Rrel, velocity[b, 0], velocity[b, 1], velocity[b, 2])
        vb0, vb1, vb2 = rotate(Rrel, velocity[b, 3], velocity[b, 4], velocity[b, 5])
        dwb0, dwb1, dwb2 = rotate(Rrel, acceleration[b, 0], acceleration[b, 1], acceleration[b, 2])
        ab0, ab1, ab2 = rotate(Rrel, acceleration[b, 3], acceleration[b, 4], acceleration[b, 5])
    wr0, wr1, wr2 = wb0 - w0, wb1 - w1, wb2 - w2
    c0, c1, c2 = cross(w0, w1, w2, rho0, rho1, rho2)
    rd0 = vb0 - velocity[a, 3] - c0
    rd1 = vb1 - velocity[a, 4] - c1
    rd2 = vb2 - velocity[a, 5] - c2
    e0, e1, e2 = cross(w0, w1, w2, wr0, wr1, wr2)
    f0, f1, f2 = cross(w0, w1, w2, rd0, rd1, rd2)
    g0, g1, g2 = cross(w0, w1, w2, c0, c1, c2)
    h0, h1, h2 = cross(dw0, dw1, dw2, rho0, rho1, rho2)
    out[0], out[1], out[2] = rho0, rho1, rho2
    out[3], out[4], out[5] = wr0, wr1, wr2
    out[6], out[7], out[8] = rd0, rd1, rd2
    out[9], out[10], out[11] = dwb0 - dw0 - e0, dwb1 - dw1 - e1, dwb2 - dw2 - e2
    out[12] = ab0 - acceleration[a, 3] - 2.0 * f0 - g0 - h0
    out[13] = ab1 - acceleration[a, 4] - 2.0 * f1 - g1 - h1
    out[14] = ab2 - acceleration[a, 5] - 2.0 * f2 - g2 - h2


@njit(cache=True)
def constraint_rows(c_int, c_float, rotation, position, velocity, acceleration, phi, gu, k, scratch, R2):
    """Residual ``phi``, velocity rows ``G u`` and rate rows ``k`` of every active constraint (module
    docstring) from node kinematics; returns the number of active rows m. Scratch: ``scratch`` (24),
    ``R2`` (2, 3, 3)."""
    m = 0
    Rrel = R2[1]
    for i in range(c_int.shape[0]):
        if not c_int[i, C_ACTIVE]:
            continue
        kind = c_int[i, C_KIND]
        relative_motion(c_int, c_float, i, rotation, position, velocity, acceleration, R2[0], Rrel, scratch)
        if kind == DISTANCE:
            length = np.sqrt(scratch[0] ** 2 + scratch[1] ** 2 + scratch[2] ** 2)
            rate = (scratch[0] * scratch[6] + scratch[1] * scratch[7] + scratch[2] * scratch[8]) / length
            speed2 = scratch[6] ** 2 + scratch[7] ** 2 + scratch[8] ** 2
            phi[m] = length - c_float[i, C_LENGTH]
            gu[m] = rate
            k[m] = (scratch[0] * scratch[12] + scratch[1] * scratch[13] + scratch[2] * scratch[14]) / length \
                + (speed2 - rate * rate) / length
            m += 1
            continue
        # the full residual [rotation; rho] into scratch[18:24]
        if kind == REVOLUTE:
            n0, n1, n2 = c_float[i, C_AXIS], c_float[i, C_AXIS + 1], c_float[i, C_AXIS + 2]
            rn0, rn1, rn2 = rotate(Rrel, n0, n1, n2)
            scratch[18], scratch[19], scratch[20] = cross(n0, n1, n2, rn0, rn1, rn2)
        elif kind == BALL:
            scratch[18] = scratch[19] = scratch[20] = 0.0
        else:
            scratch[18], scratch[19], scratch[20] = rotation_log(Rrel)
        scratch[21], scratch[22], scratch[23] = scratch[0], scratch[1], scratch[2]
        for r in range(c_int[i, C_ROWS]):
            p_ = 0.0
            v_ = 0.0
            a_ = 0.0
            for s in range(6):
                sel = c_float[i, C_SELECT + 6 * r + s]
                p_ += sel * scratch[18 + s]
                v_ += sel * scratch[3 + s]
                a_ += sel * scratch[9 + s]
            phi[m] = p_
            gu[m] = v_
            k[m] = a_
            m += 1
    return m


@njit(cache=True)
def _rho(c_int, c_float, i, rotation, position):
    """B's origin relative to A's, in A's axes."""
    a = c_int[i, C_NODE_A]
    b = c_int[i, C_NODE_B]
    if b >= 0:
        pb0, pb1, pb2 = position[b, 0], position[b, 1], position[b, 2]
    else:
        pb0, pb1, pb2 = c_float[i, C_WORLD_P], c_float[i, C_WORLD_P + 1], c_float[i, C_WORLD_P + 2]
    return rotate_back(rotation[a], pb0 - position[a, 0], pb1 - position[a, 1], pb2 - position[a, 2])


@njit(cache=True)
def add_constraint_wrench(c_int, c_float, i, rotation, position, wrench, F):
    """Node forces (node axes, about the node origins) into ``F`` equivalent to the wrench ``[torque; force]``
    that A exerts on B (A axes, at B's origin): B receives it, A the opposite moved to A's origin."""
    rho0, rho1, rho2 = _rho(c_int, c_float, i, rotation, position)
    add_wrench_pair(F, c_int[i, C_NODE_A], c_int[i, C_NODE_B], rotation, rho0, rho1, rho2, wrench[0], wrench[1],
                    wrench[2], wrench[3], wrench[4], wrench[5])


@njit(cache=True)
def row_wrench(c_int, c_float, i, r, rotation, position, wrench):
    """The unit wrench of row r of constraint i: ``S_r'`` (``[0; rho_hat]`` for a distance), A's axes."""
    if c_int[i, C_KIND] == DISTANCE:
        rho0, rho1, rho2 = _rho(c_int, c_float, i, rotation, position)
        length = np.sqrt(rho0 * rho0 + rho1 * rho1 + rho2 * rho2)
        wrench[0] = wrench[1] = wrench[2] = 0.0
        wrench[3], wrench[4], wrench[5] = rho0 / length, rho1 / length, rho2 / length
        return
    for s in range(6):
        wrench[s] = c_float[i, C_SELECT + 6 * r + s]


@njit(cache=True)
def node_forces_generalized(topology, nodes, joint_rot, joint_vec, params, q, u, node_forces, tau, ws_rot, ws_vec,
                            ws_mat, pool, positions):
    """``tau = J' F``: the generalized forces of node forces ``F`` (node axes, about the deformed node origins)
    with nothing else (no inertia, gravity or elastic force): the Newton-Euler backward pass
    (:func:`dynamics.kernels.newton_euler.transmit_forces`) over the node forces alone. With ``positions``
    the body poses are computed first; without, the workspace must hold those of ``q``."""
    nb = topology.shape[0]
    for i in range(nb):
        if positions:
            body_kinematics(i, topology, nodes, joint_rot, joint_vec, params, q, u, ws_rot, ws_vec, ws_mat, pool, False)
        for a in range(6):
            ws_vec[i, VEC_P, a] = 0.0
        n = topology[i, N_MODES]
        if n > 0:
            pv = topology[i, FLEX + FX_P_VEC] + PV_FORCE * n
            for s in range(n):
                pool[pv + s] = 0.0
    apply_node_forces(topology, nodes, params, q, node_forces, ws_vec, pool, 1.0)
    transmit_forces(topology, nodes, tau, ws_rot, ws_vec, ws_mat, pool)


@njit(cache=True)
def constraint_jacobian(d, c, q, m):
    """Rows of ``G`` (``c.G[:m]``) for the active constraints at ``q``: column r of ``G'`` is the generalized
    force of row r's unit wrench (module docstring). Node poses must be in ``c.rotation``/``c.position``."""
    wrench = c.scratch[24:30]
    for i in range(d.topology.shape[0]):
        body_kinematics(i, d.topology, d.nodes, d.joint_rot, d.joint_vec, d.params, q, c.zero_u, d.ws_rot, d.ws_vec,
                        d.ws_mat, d.pool, False)
    row = 0
    for i in range(c.c_int.shape[0]):
        if not c.c_int[i, C_ACTIVE]:
            continue
        a = c.c_int[i, C_NODE_A]
        b = c.c_int[i, C_NODE_B]
        for r in range(c.c_int[i, C_ROWS]):
            row_wrench(c.c_int, c.c_float, i, r, c.rotation, c.position, wrench)
            add_constraint_wrench(c.c_int, c.c_float, i, c.rotation, c.position, wrench, c.unit)
            node_forces_generalized(d.topology, d.nodes, d.joint_rot, d.joint_vec, d.params, q, c.zero_u, c.unit,
                                    c.G[row], d.ws_rot, d.ws_vec, d.ws_mat, d.pool, False)
            for s in range(6):
                c.unit[a, s] = 0.0
                if b >= 0:
                    c.unit[b, s] = 0.0
            row += 1


@njit(cache=True)
def _factor_and_solve_rows(d, c, q, m):
    """Mass matrix (prescribed rows and columns replaced by the identity; the original kept in ``M_full``
    when there are prescribed DOFs), its Cholesky factor, ``Yt = (M^-1 G')'`` (zero at prescribed DOFs) and
    ``A = G M^-1 G'``. Returns the number of prescribed DOFs, or -1 when M is not positive definite."""
    topology = d.topology
    nu = c.zero_u.shape[0]
    M = c.M
    K.mass_matrix(topology, d.nodes, d.joint_rot, d.joint_vec, d.params, q, c.zero_u, M, d.ws_rot, d.ws_vec, d.ws_mat,
                  d.pool)
    npres = 0
    for i in range(topology.shape[0]):
        npres += topology[i, N_PRESCRIBED]
    if npres > 0:
        for r in range(nu):
            for s in range(nu):
                c.M_full[r, s] = M[r, s]
        for i in range(topology.shape[0]):
            for kk in range(topology[i, N_PRESCRIBED]):
                p = topology[i, U_START] + topology[i, PRESCRIBED_DOFS + kk]
                for s in range(nu):
                    M[p, s] = 0.0
                    M[s, p] = 0.0
                M[p, p] = 1.0
    if FK.cholesky_in_place(M, nu) >= 0:
        return -1
    for r in range(m):
        y = c.Yt[r]
        for s in range(nu):
            y[s] = c.G[r, s]
        for i in range(topology.shape[0]):
            for kk in range(topology[i, N_PRESCRIBED]):
                y[topology[i, U_START] + topology[i, PRESCRIBED_DOFS + kk]] = 0.0
        FK.cholesky_solve(M, nu, y)
    for r in range(m):
        for s in range(r + 1):
            t = 0.0
            for j in range(nu):
                t += c.G[r, j] * c.Yt[s, j]
            c.A[r, s] = t
            c.A[s, r] = t
    return npres


@njit(cache=True)
def _minimum_norm_solve(c, m):
    """``lam = A^+ rhs`` for the symmetric positive semidefinite ``A`` (m x m; destroyed) by a pivoted Cholesky
    factorization ``P' A P = L L'`` that stops at the numerical rank r (pivots below ``RANK_TOLERANCE`` times the
    largest diagonal entry: redundant rows), the basic solution of the r leading pivots, and its projection onto
    the range of A (the minimum-norm solution: the basic one less its part in the null space, spanned by the
    columns of ``P [-L11'^-1 L21'; I]``; Golub and Van Loan, *Matrix Computations*, 4th ed., sec. 4.2.8 and
    5.5). O(m^3 / 6 + m^2 (m - r)); ``c.V`` holds the null-space basis, ``c.k`` (the permutation) and ``c.gu``
    serve as scratch (both consumed by then)."""
    A = c.A
    top = 0.0
    for r in range(m):
        top = max(top, A[r, r])
    order = c.k  # the permutation
    for r in range(m):
        order[r] = r
    rank = 0
    for j in range(m):
        # the largest remaining diagonal entry
        best = j
        for r in range(j + 1, m):
            if A[r, r] > A[best, best]:
                best = r
        if not A[best, best] > RANK_TOLERANCE * top:
            break
        if best != j:
            for r in range(m):
                t = A[j, r]
                A[j, r] = A[best, r]
                A[best, r] = t
            for r in range(m):
                t = A[r, j]
                A[r, j] = A[r, best]
                A[r, best] = t
            t = order[j]
            order[j] = order[best]
            order[best] = t
        d = np.sqrt(A[j, j])
        A[j, j] = d
        for r in range(j + 1, m):
            A[r, j] /= d
        for r in range(j + 1, m):
            for s in range(j + 1, r + 1):
                A[r, s] -= A[r, j] * A[s, j]
                A[s, r] = A[r, s]
        rank += 1
    # basic solution: L11 L11' y = (P' rhs)[:rank], the other entries zero
    y = c.gu
    for j in range(m):
        y[j] = c.rhs[int(order[j])] if j < rank else 0.0
    FK.cholesky_solve(A, rank, y)
    nullity = m - rank
    if nullity > 0:
        # null-space basis in permuted order: N = [X; I] with L11' X = -L21' (rank x nullity), into c.V
        N = c.V
        for col in range(nullity):
            for j in range(rank):
                N[j, col] = -A[rank + col, j]
            for j in range(rank - 1, -1, -1):
                t = N[j, col]
                for s in range(j + 1, rank):
                    t -= A[s, j] * N[s, col]
                N[j, col] = t / A[j, j]
            for j in range(nullity):
                N[rank + j, col] = 1.0 if j == col else 0.0
        # y <- y - N (N'N)^-1 N' y: the small SPD system N'N z = N'y, in the trailing block of A (free now)
        G = A[rank:, rank:]
        z = c.lam
        for a in range(nullity):
            t = 0.0
            for j in range(m):
                t += N[j, a] * y[j]
            z[a] = t
            for b in range(a + 1):
                t = 0.0
                for j in range(m):
                    t += N[j, a] * N[j, b]
                G[a, b] = t
        FK.cholesky_in_place(G, nullity)  # N'N = I + X'X: well conditioned
        FK.cholesky_solve(G, nullity, z)
        for j in range(m):
            t = 0.0
            for a in range(nullity):
                t += N[j, a] * z[a]
            y[j] -= t
    for j in range(m):
        c.lam[int(order[j])] = y[j]


@njit(cache=True)
def _correction(c, m):
    """``c.work = M^-1 G' lambda`` (from the rows ``Yt`` and the multipliers)."""
    for s in range(c.work.shape[0]):
        t = 0.0
        for r in range(m):
            t += c.lam[r] * c.Yt[r, s]
        c.work[s] = t


@njit(cache=True)
def active_rows(c_int):
    m = 0
    for i in range(c_int.shape[0]):
        if c_int[i, C_ACTIVE]:
            m += c_int[i, C_ROWS]
    return m


@njit(cache=True)
def _loads(c, m, loads):
    """Each constraint's wrench ``S' lambda`` (A on B, A axes, at B's origin) into ``loads`` (nc, 6)."""
    wrench = c.scratch[24:30]
    row = 0
    for i in range(c.c_int.shape[0]):
        for s in range(6):
            loads[i, s] = 0.0
        if not c.c_int[i, C_ACTIVE]:
            continue
        for r in range(c.c_int[i, C_ROWS]):
            row_wrench(c.c_int, c.c_float, i, r, c.rotation, c.position, wrench)
            for s in range(6):
                loads[i, s] += wrench[s] * c.lam[row]
            row += 1


@njit(cache=True)
def forward_dynamics(d, c, q, u, tau, node_forces, udot, tau_out, loads):
    """Accelerations of the constrained tree with its force elements into ``udot`` (holding the prescribed
    accelerations on entry), the generalized forces into ``tau_out`` (``tau`` plus the hinge elements' at
    free DOFs; the force realizing the prescribed motion, constraint forces included, at prescribed DOFs)
    and each constraint's wrench into ``loads`` (nc, 6). On exit ``c.forces`` holds every node force (applied,
    element and constraint) and ``c.tau`` the applied plus element generalized forces, for
    :func:`hinge_loads`. Returns 0, 1 + the index of a body whose articulated inertia is singular, or -1 when
    the mass matrix is not positive definite."""
    d = E.borrowed(d)
    c = E.borrowed(c)
    nu = c.zero_u.shape[0]
    K.node_kinematics(d.topology, d.nodes, d.joint_rot, d.joint_vec, d.params, q, u, c.zero_u, c.rotation, c.position,
                      c.velocity, c.acceleration, d.ws_rot, d.ws_vec, d.ws_mat, d.pool)
    for r in range(c.forces.shape[0]):
        for s in range(6):
            c.forces[r, s] = node_forces[r, s]
    for s in range(nu):
        c.tau[s] = tau[s]
    apply_force_elements(c.f_int, c.f_float, q, u, c.rotation, c.position, c.velocity, c.forces, c.tau, c.frames)
    status = E.forward_dynamics(d, q, u, c.tau, c.forces, udot, tau_out)
    m = active_rows(c.c_int)
    if status != 0 or m == 0:
        for i in range(loads.shape[0]):
            for s in range(6):
                loads[i, s] = 0.0
        return status
    constraint_rows(c.c_int, c.c_float, c.rotation, c.position, c.velocity, c.acceleration, c.phi, c.gu, c.k,
                    c.scratch, c.frames)
    constraint_jacobian(d, c, q, m)
    alpha = c.gains[0]
    beta = c.gains[1]
    for r in range(m):
        t = -c.k[r] - 2.0 * alpha * c.gu[r] - beta * beta * c.phi[r]
        for s in range(nu):
            t -= c.G[r, s] * udot[s]
        c.rhs[r] = t
    npres = _factor_and_solve_rows(d, c, q, m)
    if npres < 0:
        return -1
    _minimum_norm_solve(c, m)
    _correction(c, m)
    for s in range(nu):
        udot[s] += c.work[s]
    if npres > 0:
        topology = d.topology
        for i in range(topology.shape[0]):
            for kk in range(topology[i, N_PRESCRIBED]):
                p = topology[i, U_START] + topology[i, PRESCRIBED_DOFS + kk]
                t = 0.0
                for s in range(nu):
                    t += c.M_full[p, s] * c.work[s]
                for r in range(m):
                    t -= c.G[r, p] * c.lam[r]
                tau_out[p] += t
    _loads(c, m, loads)
    for i in range(c.c_int.shape[0]):
        if c.c_int[i, C_ACTIVE]:
            add_constraint_wrench(c.c_int, c.c_float, i, c.rotation, c.position, loads[i], c.forces)
    return 0


@njit(cache=True)
def hinge_loads(d, c, q, u, udot, out):
    """The spatial force ``[torque; force]`` each hinge transmits from its parent (or the ground) to its body,
    at the hinge's outboard frame M, in M's axes (nb, 6), for the accelerations ``udot`` that
    :func:`forward_dynamics` returned with the node forces it left in ``c.forces`` (applied, element and
    constraint forces): the Newton-Euler pass (:func:`dynamics.kernels.inverse_dynamics`), whose hinge
    projections are the generalized forces. Uses ``c.work`` and the engine's workspace."""
    d = E.borrowed(d)
    c = E.borrowed(c)
    topology = d.topology
    K.inverse_dynamics(topology, d.nodes, d.joint_rot, d.joint_vec, d.params, q, u, udot, c.forces,
                       d.zero_body_forces, c.work, d.ws_rot, d.ws_vec, d.ws_mat, d.pool)
    for i in range(topology.shape[0]):
        f = d.ws_vec[i, VEC_P]
        if topology[i, OUTBOARD_NODE] >= 0:
            R = d.ws_rot[i, ROT_BM]
            p = d.ws_vec[i, VEC_PBM]
        else:
            R = d.joint_rot[i, OUTBOARD]
            p = d.joint_vec[i, OUTBOARD]
        # about M's origin: n_M = n_B - p_BM x f (body axes), then both into M's axes
        m0, m1, m2 = cross(p[0], p[1], p[2], f[3], f[4], f[5])
        n0, n1, n2 = f[0] - m0, f[1] - m1, f[2] - m2
        for r in range(3):
            out[i, r] = R[0, r] * n0 + R[1, r] * n1 + R[2, r] * n2
            out[i, 3 + r] = R[0, r] * f[3] + R[1, r] * f[4] + R[2, r] * f[5]


@njit(cache=True)
def _positions(d, c, q):
    K.node_kinematics(d.topology, d.nodes, d.joint_rot, d.joint_vec, d.params, q, c.zero_u, c.zero_u, c.rotation,
                      c.position, c.velocity, c.acceleration, d.ws_rot, d.ws_vec, d.ws_mat, d.pool)


@njit(cache=True)
def residual(d, c, q):
    """The position residual of the active rows into ``c.phi``; returns its largest absolute value."""
    d = E.borrowed(d)
    c = E.borrowed(c)
    _positions(d, c, q)
    m = constraint_rows(c.c_int, c.c_float, c.rotation, c.position, c.velocity, c.acceleration, c.phi, c.gu, c.k,
                        c.scratch, c.frames)
    worst = 0.0
    for r in range(m):
        worst = max(worst, abs(c.phi[r]))
    return worst


@njit(cache=True)
def project_positions(d, c, q, tolerance, max_iterations):
    """``q`` moved onto ``phi(q) = 0`` in place (module docstring); returns the Newton iterations taken, or -1
    when ``|phi| <= tolerance`` is not reached in ``max_iterations`` or the mass matrix is singular."""
    d = E.borrowed(d)
    c = E.borrowed(c)
    m = active_rows(c.c_int)
    qdot = c.qdot
    for it in range(max_iterations + 1):
        if residual(d, c, q) <= tolerance:
            return it
        if it == max_iterations:
            break
        constraint_jacobian(d, c, q, m)
        if _factor_and_solve_rows(d, c, q, m) < 0:
            return -1
        for r in range(m):
            c.rhs[r] = -c.phi[r]
        _minimum_norm_solve(c, m)
        _correction(c, m)
        K.coordinate_rates(d.topology, q, c.work, qdot)
        for s in range(q.shape[0]):
            q[s] += qdot[s]
        E.normalize_quaternions(d, q)
    return -1


@njit(cache=True)
def project_velocities(d, c, q, u):
    """``u <- u - M^-1 G' (G M^-1 G')^+ G u`` in place: the M-orthogonal projection onto ``G u = 0`` (the
    perfectly plastic impact of the active constraints). Returns 0, or -1 when M is singular."""
    d = E.borrowed(d)
    c = E.borrowed(c)
    nu = c.zero_u.shape[0]
    m = active_rows(c.c_int)
    if m == 0:
        return 0
    _positions(d, c, q)
    constraint_jacobian(d, c, q, m)
    if _factor_and_solve_rows(d, c, q, m) < 0:
        return -1
    for r in range(m):
        t = 0.0
        for s in range(nu):
            t += c.G[r, s] * u[s]
        c.rhs[r] = -t
    _minimum_norm_solve(c, m)
    _correction(c, m)
    for s in range(nu):
        u[s] += c.work[s]
    return 0


@njit(cache=True)
def element_forces(d, c, q, u, out):
    """The generalized forces of the force elements alone, ``J' F_e + tau_e`` (nu,), into ``out``; their node
    forces are left in ``c.forces`` and hinge forces in ``c.tau``."""
    d = E.borrowed(d)
    c = E.borrowed(c)
    K.node_kinematics(d.topology, d.nodes, d.joint_rot, d.joint_vec, d.params, q, u, c.zero_u, c.rotation, c.position,
                      c.velocity, c.acceleration, d.ws_rot, d.ws_vec, d.ws_mat, d.pool)
    for r in range(c.forces.shape[0]):
        for s in range(6):
            c.forces[r, s] = 0.0
    for s in range(c.tau.shape[0]):
        c.tau[s] = 0.0
    apply_force_elements(c.f_int, c.f_float, q, u, c.rotation, c.position, c.velocity, c.forces, c.tau, c.frames)
    node_forces_generalized(d.topology, d.nodes, d.joint_rot, d.joint_vec, d.params, q, u, c.forces, out, d.ws_rot,
                            d.ws_vec, d.ws_mat, d.pool, True)
    for s in range(out.shape[0]):
        out[s] += c.tau[s]


@njit(cache=True)
def potential_energy(d, c, q):
    """The force elements' potential energy at ``q`` (springs, bushings, hinge springs and stops, contacts)."""
    d = E.borrowed(d)
    c = E.borrowed(c)
    _positions(d, c, q)
    return force_element_energy(c.f_int, c.f_float, q, c.rotation, c.position, c.velocity, c.frames)
