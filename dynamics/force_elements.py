"""Force elements between nodes and on hinges: springs, bushings, hinge springs, limit stops and friction,
and contact; their definitions, checks and compiled forces and potential energies.

Each element adds node forces (``[torque; force]`` in node axes about the node origin, like every node force
of the engine) or hinge generalized forces, computed from the node kinematics of the evaluation (pose and
velocity of the deformed nodes, :func:`dynamics.kernels.node_kinematics`), and contributes its potential
energy to the energy output. A node on a flexible body moves with the deformation, so an element attached
there loads the deforming structure.

* ``spring_damper``: a line spring between the origins of two nodes (or a node and a world point),
  tension ``F = k (L - L0) + c dL/dt`` along the line; ``acts`` ``"both"``, ``"compression"`` (pushes only
  while shorter than ``L0``: a separation spring) or ``"tension"`` (a cable). ``V = k (L - L0)^2 / 2`` where
  it acts.
* ``bushing``: six-DOF stiffness ``K`` and damping ``C`` (6 x 6, rows ``[rotation; translation]``) in node
  A's axes, deflection ``delta = [theta; rho]`` with ``theta = log(R_A' R_B)`` and ``rho = R_A'(p_B - p_A)``.
  Wrench on B (A axes, at B's origin): ``torque = -J_l(theta)^-T (K delta)_theta - (C v)_theta``,
  ``force = -(K delta)_rho - (C v)_rho`` with ``v = [w_rel; rho_dot]`` (:mod:`dynamics.constraint_kernels`) and
  ``J_l`` the left Jacobian of SO(3) (``w_rel = J_l theta_dot``), so that the stiffness force is exactly
  ``-dV/d(delta)`` of ``V = delta' K delta / 2`` at any rotation (Barfoot, *State Estimation for Robotics*,
  2017, sec. 7.1.5); ``K`` symmetric positive semidefinite, ``C`` positive semidefinite.
* ``hinge_spring``: ``tau = -k (q - q0) - c u`` on one hinge DOF; ``V = k (q - q0)^2 / 2``.
* ``hinge_stop``: limits ``lower <= q <= upper`` on one hinge DOF by a Hunt-Crossley penalty
  ``F = k delta^n (1 + D delta_dot)``, ``F >= 0`` (penetration ``delta`` past the limit);
  ``V = k delta^(n+1) / (n+1)``.
* ``hinge_friction``: Coulomb friction ``tau = -T u / sqrt(u^2 + v_s^2)`` on one hinge DOF (regularized:
  no true sticking; a sustained load creeps at a rate of order ``v_s``).
* ``plane_contact``: a sphere (radius r, centred on node A) against a plane (through node B's origin with
  normal ``n`` in B's axes, or fixed in the world); ``sphere_contact``: two spheres on nodes A and B.
  Normal force Hunt-Crossley ``F_n = k delta^n (1 + D delta_dot)``, ``F_n >= 0`` (Hunt and Crossley, ASME
  J. Appl. Mech. 42, 1975; ``n = 3/2`` for Hertz spheres), along the line through the sphere centre(s), so
  that it is exactly ``-dV/d(delta)``; friction ``F_t = -mu F_n v_t / sqrt(|v_t|^2 + v_s^2)`` from the
  tangential slip velocity at the contact point (mid-overlap). ``V = k delta^(n+1) / (n+1)``.

The Hunt-Crossley damping ``D`` [s/m, s/rad] may be given through a coefficient of restitution ``e`` at an
impact speed ``v``: the law's restitution depends on ``D v`` and the exponent only (:func:`restitution_of`), so
``D`` is the root of ``restitution_of(D v, n) = e``, found once per element by Brent's method on a DOP853
integration (:func:`hunt_crossley_damping`): an impact at ``v`` rebounds with exactly ``e`` (Lankarani and
Nikravesh's closed form ``3 (1 - e^2) / (4 v)``, J. Mech. Des. 112, 1990, is an energy balance for ``e`` near 1:
it rebounds at 0.845 for e = 0.8). The penalty keeps the impact finite: gravity or other loads acting during the
contact change the rebound by about their impulse over the contact time.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from numba import njit

from dynamics.errors import ModelDefinitionError
from dynamics.vector3 import cross, rotate, rotate_back, rotation_log

SPRING_DAMPER = 0
BUSHING = 1
HINGE_SPRING = 2
HINGE_STOP = 3
HINGE_FRICTION = 4
PLANE_CONTACT = 5
SPHERE_CONTACT = 6

ACTS = {"both": 0, "compression": 1, "tension": 2}

# int columns (one row per element)
F_KIND = 0
F_NODE_A = 1
F_NODE_B = 2  # -1: the world (F_WORLD_*)
F_Q = 3  # hinge elements: the DOF's index in q
F_U = 4  # and in u
F_ACTS = 5
F_ACTIVE = 6
F_INT_COLUMNS = 7

# float columns
F_STIFFNESS = 0
F_DAMPING = 1  # c of springs; D of Hunt-Crossley laws
F_LENGTH = 2  # free length / neutral coordinate
F_EXPONENT = 3
F_FRICTION = 4  # mu, or the friction level T of hinge friction
F_SLIP = 5  # the regularization speed v_s
F_RADIUS_A = 6
F_RADIUS_B = 7
F_LOWER = 8
F_UPPER = 9
F_WORLD_R = 10  # 9
F_WORLD_P = 19  # 3
F_NORMAL = 22  # 3: plane normal (in node B's axes, or the world's)
F_K6 = 25  # 36
F_C6 = 61  # 36
F_FLOAT_COLUMNS = 97


@njit(cache=True)
def _point_velocity(rotation, position, velocity, k, x0, x1, x2):
    """World velocity of the point at world position x moving with node k's frame."""
    R = rotation[k]
    w0, w1, w2 = rotate(R, velocity[k, 0], velocity[k, 1], velocity[k, 2])
    v0, v1, v2 = rotate(R, velocity[k, 3], velocity[k, 4], velocity[k, 5])
    c0, c1, c2 = cross(w0, w1, w2, x0 - position[k, 0], x1 - position[k, 1], x2 - position[k, 2])
    return v0 + c0, v1 + c1, v2 + c2


@njit(cache=True)
def add_node_wrench(F, k, R, t0, t1, t2, f0, f1, f2):
    """``F[k] += [R' t; R' f]``: a torque and force given in the axes R maps into the world, at node k's origin."""
    a0, a1, a2 = rotate_back(R, t0, t1, t2)
    b0, b1, b2 = rotate_back(R, f0, f1, f2)
    F[k, 0] += a0
    F[k, 1] += a1
    F[k, 2] += a2
    F[k, 3] += b0
    F[k, 4] += b1
    F[k, 5] += b2


@njit(cache=True)
def _add_world_force(rotation, position, k, x0, x1, x2, p0, p1, p2, F):
    """Node k receives the world force P applied at world point x: node axes, about the node origin."""
    m0, m1, m2 = cross(x0 - position[k, 0], x1 - position[k, 1], x2 - position[k, 2], p0, p1, p2)
    add_node_wrench(F, k, rotation[k], m0, m1, m2, p0, p1, p2)


@njit(cache=True)
def add_wrench_pair(F, a, b, rotation, rho0, rho1, rho2, t0, t1, t2, f0, f1, f2):
    """The wrench ``[t; f]`` that node A exerts on node B (A's axes, at B's origin, ``rho`` = B's origin from A's in
    A's axes) as node forces: B receives it (unless ``b < 0``: the world), A the opposite moved to its origin."""
    m0, m1, m2 = cross(rho0, rho1, rho2, f0, f1, f2)
    F[a, 0] -= t0 + m0
    F[a, 1] -= t1 + m1
    F[a, 2] -= t2 + m2
    F[a, 3] -= f0
    F[a, 4] -= f1
    F[a, 5] -= f2
    if b >= 0:
        RA = rotation[a]
        x0, x1, x2 = rotate(RA, t0, t1, t2)
        y0, y1, y2 = rotate(RA, f0, f1, f2)
        add_node_wrench(F, b, rotation[b], x0, x1, x2, y0, y1, y2)


@njit(cache=True)
def frame_b(rotation, position, b, row, r_col, p_col, R):
    """Pose of an element's or constraint's frame B: node b's (rotation into ``R``, origin returned), or, for
    ``b < 0``, the world pose stored in ``row`` (rotation row major from ``r_col``, origin from ``p_col``)."""
    if b >= 0:
        for r in range(3):
            for s in range(3):
                R[r, s] = rotation[b, r, s]
        return position[b, 0], position[b, 1], position[b, 2]
    for r in range(3):
        for s in range(3):
            R[r, s] = row[r_col + 3 * r + s]
    return row[p_col], row[p_col + 1], row[p_col + 2]


@njit(cache=True)
def hunt_crossley(k, n, D, delta, delta_dot):
    """Normal force ``k delta^n (1 + D delta_dot)`` of a penetration ``delta > 0``, never pulling."""
    f = k * delta ** n * (1.0 + D * delta_dot)
    return f if f > 0.0 else 0.0


@njit(cache=True)
def _contact(f_int, f_float, e, rotation, position, velocity, F, c0, c1, c2, n0, n1, n2, delta, b):
    """Normal and friction force of contact e at the world point c with unit normal n (from B towards the
    sphere on A), penetration delta: A receives ``F_n n + F_t`` at c, B (node index b, or the world) the
    opposite. The normal force acts on the line through the sphere centre(s)."""
    a = f_int[e, F_NODE_A]
    va0, va1, va2 = _point_velocity(rotation, position, velocity, a, c0, c1, c2)
    vb0 = vb1 = vb2 = 0.0
    if b >= 0:
        vb0, vb1, vb2 = _point_velocity(rotation, position, velocity, b, c0, c1, c2)
    s0, s1, s2 = va0 - vb0, va1 - vb1, va2 - vb2
    approach = -(s0 * n0 + s1 * n1 + s2 * n2)  # delta_dot
    fn = hunt_crossley(f_float[e, F_STIFFNESS], f_float[e, F_EXPONENT], f_float[e, F_DAMPING], delta, approach)
    p0, p1, p2 = fn * n0, fn * n1, fn * n2
    mu = f_float[e, F_FRICTION]
    if mu > 0.0 and fn > 0.0:
        sn = s0 * n0 + s1 * n1 + s2 * n2
        t0, t1, t2 = s0 - sn * n0, s1 - sn * n1, s2 - sn * n2
        vs = f_float[e, F_SLIP]
        scale = -mu * fn / np.sqrt(t0 * t0 + t1 * t1 + t2 * t2 + vs * vs)
        p0 += scale * t0
        p1 += scale * t1
        p2 += scale * t2
    _add_world_force(rotation, position, a, c0, c1, c2, p0, p1, p2, F)
    if b >= 0:
        _add_world_force(rotation, position, b, c0, c1, c2, -p0, -p1, -p2, F)


@njit(cache=True)
def _left_jacobian_inverse_transpose_times(t0, t1, t2, g0, g1, g2):
    """``J_l(theta)^-T g = g + theta x g / 2 + gamma theta x (theta x g)``,
    ``gamma = (1 - (theta/2) cot(theta/2)) / theta^2`` (series below 1e-2 rad)."""
    th2 = t0 * t0 + t1 * t1 + t2 * t2
    if th2 < 1e-4:
        gamma = 1.0 / 12.0 + th2 / 720.0 + th2 * th2 / 30240.0
    else:
        th = np.sqrt(th2)
        gamma = (1.0 - 0.5 * th / np.tan(0.5 * th)) / th2
    c0, c1, c2 = cross(t0, t1, t2, g0, g1, g2)
    d0, d1, d2 = cross(t0, t1, t2, c0, c1, c2)
    return g0 + 0.5 * c0 + gamma * d0, g1 + 0.5 * c1 + gamma * d1, g2 + 0.5 * c2 + gamma * d2


@njit(cache=True)
def _bushing_rows(f_float, e, offset, first, x):
    """Rows first..first+2 of the 6 x 6 matrix at ``offset`` times the 6-tuple x."""
    out0 = out1 = out2 = 0.0
    for s in range(6):
        out0 += f_float[e, offset + 6 * first + s] * x[s]
        out1 += f_float[e, offset + 6 * (first + 1) + s] * x[s]
        out2 += f_float[e, offset + 6 * (first + 2) + s] * x[s]
    return out0, out1, out2


@njit(cache=True)
def _bushing_deflection(f_int, f_float, e, rotation, position, RB, Rrel):
    """The deflection ``[theta; rho]`` of node B (or the world pose) from node A, A's axes; ``Rrel = R_A' R_B``."""
    a = f_int[e, F_NODE_A]
    RA = rotation[a]
    pb0, pb1, pb2 = frame_b(rotation, position, f_int[e, F_NODE_B], f_float[e], F_WORLD_R, F_WORLD_P, RB)
    for r in range(3):
        for s in range(3):
            Rrel[r, s] = RA[0, r] * RB[0, s] + RA[1, r] * RB[1, s] + RA[2, r] * RB[2, s]
    t0, t1, t2 = rotation_log(Rrel)
    r0, r1, r2 = rotate_back(RA, pb0 - position[a, 0], pb1 - position[a, 1], pb2 - position[a, 2])
    return t0, t1, t2, r0, r1, r2


@njit(cache=True)
def _bushing_energy(f_int, f_float, e, rotation, position, RB, Rrel):
    delta = _bushing_deflection(f_int, f_float, e, rotation, position, RB, Rrel)
    energy = 0.0
    for r in range(6):
        for s in range(6):
            energy += 0.5 * delta[r] * f_float[e, F_K6 + 6 * r + s] * delta[s]
    return energy


@njit(cache=True)
def _bushing(f_int, f_float, e, rotation, position, velocity, F, RB, Rrel):
    """The bushing's wrench on B (A's axes, at B's origin) and its reaction on A, into F."""
    a = f_int[e, F_NODE_A]
    b = f_int[e, F_NODE_B]
    delta = _bushing_deflection(f_int, f_float, e, rotation, position, RB, Rrel)
    t0, t1, t2, r0, r1, r2 = delta
    w0, w1, w2 = velocity[a, 0], velocity[a, 1], velocity[a, 2]
    wb0 = wb1 = wb2 = vb0 = vb1 = vb2 = 0.0
    if b >= 0:
        wb0, wb1, wb2 = rotate(Rrel, velocity[b, 0], velocity[b, 1], velocity[b, 2])
        vb0, vb1, vb2 = rotate(Rrel, velocity[b, 3], velocity[b, 4], velocity[b, 5])
    c0, c1, c2 = cross(w0, w1, w2, r0, r1, r2)
    rate = (wb0 - w0, wb1 - w1, wb2 - w2, vb0 - velocity[a, 3] - c0, vb1 - velocity[a, 4] - c1,
            vb2 - velocity[a, 5] - c2)
    # stiffness rows K delta (the rotation rows go through J_l^-T), damping rows C v (on w_rel directly)
    k0, k1, k2 = _bushing_rows(f_float, e, F_K6, 0, delta)
    k3, k4, k5 = _bushing_rows(f_float, e, F_K6, 3, delta)
    h0, h1, h2 = _bushing_rows(f_float, e, F_C6, 0, rate)
    h3, h4, h5 = _bushing_rows(f_float, e, F_C6, 3, rate)
    j0, j1, j2 = _left_jacobian_inverse_transpose_times(t0, t1, t2, k0, k1, k2)
    wrench0, wrench1, wrench2 = -j0 - h0, -j1 - h1, -j2 - h2
    wrench3, wrench4, wrench5 = -k3 - h3, -k4 - h4, -k5 - h5
    add_wrench_pair(F, a, b, rotation, r0, r1, r2, wrench0, wrench1, wrench2, wrench3, wrench4, wrench5)


@njit(cache=True)
def _sphere_plane(f_int, f_float, e, rotation, position):
    """(contact point, unit normal towards the sphere, penetration) of a sphere-plane pair."""
    a = f_int[e, F_NODE_A]
    b = f_int[e, F_NODE_B]
    nx, ny, nz = f_float[e, F_NORMAL], f_float[e, F_NORMAL + 1], f_float[e, F_NORMAL + 2]
    if b >= 0:
        n0, n1, n2 = rotate(rotation[b], nx, ny, nz)
        o0, o1, o2 = position[b, 0], position[b, 1], position[b, 2]
    else:
        n0, n1, n2 = nx, ny, nz
        o0, o1, o2 = f_float[e, F_WORLD_P], f_float[e, F_WORLD_P + 1], f_float[e, F_WORLD_P + 2]
    s0, s1, s2 = position[a, 0], position[a, 1], position[a, 2]
    height = (s0 - o0) * n0 + (s1 - o1) * n1 + (s2 - o2) * n2
    radius = f_float[e, F_RADIUS_A]
    delta = radius - height
    back = radius - 0.5 * delta
    return s0 - back * n0, s1 - back * n1, s2 - back * n2, n0, n1, n2, delta


@njit(cache=True)
def _sphere_sphere(f_int, f_float, e, position):
    """(contact point, unit normal from B's centre towards A's, penetration) of two spheres."""
    a = f_int[e, F_NODE_A]
    b = f_int[e, F_NODE_B]
    d0, d1, d2 = position[a, 0] - position[b, 0], position[a, 1] - position[b, 1], position[a, 2] - position[b, 2]
    dist = np.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
    ra = f_float[e, F_RADIUS_A]
    delta = ra + f_float[e, F_RADIUS_B] - dist
    if dist == 0.0:
        return position[a, 0], position[a, 1], position[a, 2], 0.0, 0.0, 1.0, delta
    n0, n1, n2 = d0 / dist, d1 / dist, d2 / dist
    back = ra - 0.5 * delta
    return position[a, 0] - back * n0, position[a, 1] - back * n1, position[a, 2] - back * n2, n0, n1, n2, delta


@njit(cache=True)
def _spring_geometry(f_int, f_float, e, rotation, position, velocity):
    """(unit vector from A to B, length, its rate) of a spring-damper."""
    a = f_int[e, F_NODE_A]
    b = f_int[e, F_NODE_B]
    if b >= 0:
        pb0, pb1, pb2 = position[b, 0], position[b, 1], position[b, 2]
        vb0, vb1, vb2 = _point_velocity(rotation, position, velocity, b, pb0, pb1, pb2)
    else:
        pb0, pb1, pb2 = f_float[e, F_WORLD_P], f_float[e, F_WORLD_P + 1], f_float[e, F_WORLD_P + 2]
        vb0 = vb1 = vb2 = 0.0
    va0, va1, va2 = _point_velocity(rotation, position, velocity, a, position[a, 0], position[a, 1], position[a, 2])
    d0, d1, d2 = pb0 - position[a, 0], pb1 - position[a, 1], pb2 - position[a, 2]
    length = np.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
    e0, e1, e2 = d0 / length, d1 / length, d2 / length
    rate = e0 * (vb0 - va0) + e1 * (vb1 - va1) + e2 * (vb2 - va2)
    return e0, e1, e2, length, rate


@njit(cache=True)
def _spring_acts(acts, stretch):
    return acts == 0 or (acts == 1 and stretch < 0.0) or (acts == 2 and stretch > 0.0)


@njit(cache=True)
def apply_force_elements(f_int, f_float, q, u, rotation, position, velocity, F, tau, frames):
    """Add every active element's node forces to ``F`` (nn, 6) and hinge forces to ``tau`` (nu,), from the
    node kinematics of the evaluation (module docstring); ``frames`` (2, 3, 3) is scratch."""
    RB = frames[0]
    Rrel = frames[1]
    for e in range(f_int.shape[0]):
        if not f_int[e, F_ACTIVE]:
            continue
        kind = f_int[e, F_KIND]
        if kind == SPRING_DAMPER:
            e0, e1, e2, length, rate = _spring_geometry(f_int, f_float, e, rotation, position, velocity)
            stretch = length - f_float[e, F_LENGTH]
            acts = f_int[e, F_ACTS]
            if not _spring_acts(acts, stretch):
                continue
            tension = f_float[e, F_STIFFNESS] * stretch + f_float[e, F_DAMPING] * rate
            if (acts == 1 and tension > 0.0) or (acts == 2 and tension < 0.0):
                continue
            a = f_int[e, F_NODE_A]
            b = f_int[e, F_NODE_B]
            _add_world_force(rotation, position, a, position[a, 0], position[a, 1], position[a, 2],
                             tension * e0, tension * e1, tension * e2, F)
            if b >= 0:
                _add_world_force(rotation, position, b, position[b, 0], position[b, 1], position[b, 2],
                                 -tension * e0, -tension * e1, -tension * e2, F)
        elif kind == BUSHING:
            _bushing(f_int, f_float, e, rotation, position, velocity, F, RB, Rrel)
        elif kind == PLANE_CONTACT or kind == SPHERE_CONTACT:
            if kind == PLANE_CONTACT:
                c0, c1, c2, n0, n1, n2, delta = _sphere_plane(f_int, f_float, e, rotation, position)
            else:
                c0, c1, c2, n0, n1, n2, delta = _sphere_sphere(f_int, f_float, e, position)
            if delta > 0.0:
                _contact(f_int, f_float, e, rotation, position, velocity, F, c0, c1, c2, n0, n1, n2, delta,
                         f_int[e, F_NODE_B])
        else:
            x = q[f_int[e, F_Q]]
            v = u[f_int[e, F_U]]
            k = f_float[e, F_STIFFNESS]
            if kind == HINGE_SPRING:
                t = -k * (x - f_float[e, F_LENGTH]) - f_float[e, F_DAMPING] * v
            elif kind == HINGE_STOP:
                n = f_float[e, F_EXPONENT]
                D = f_float[e, F_DAMPING]
                t = 0.0
                if x < f_float[e, F_LOWER]:
                    t = hunt_crossley(k, n, D, f_float[e, F_LOWER] - x, -v)
                elif x > f_float[e, F_UPPER]:
                    t = -hunt_crossley(k, n, D, x - f_float[e, F_UPPER], v)
            else:
                vs = f_float[e, F_SLIP]
                t = -f_float[e, F_FRICTION] * v / np.sqrt(v * v + vs * vs)
            tau[f_int[e, F_U]] += t


@njit(cache=True)
def force_element_energy(f_int, f_float, q, rotation, position, velocity, frames):
    """The potential energy of every active element (node kinematics of the evaluation; ``frames`` scratch)."""
    RB = frames[0]
    Rrel = frames[1]
    total = 0.0
    for e in range(f_int.shape[0]):
        if not f_int[e, F_ACTIVE]:
            continue
        kind = f_int[e, F_KIND]
        k = f_float[e, F_STIFFNESS]
        n = f_float[e, F_EXPONENT]
        if kind == SPRING_DAMPER:
            _, _, _, length, _ = _spring_geometry(f_int, f_float, e, rotation, position, velocity)
            stretch = length - f_float[e, F_LENGTH]
            if _spring_acts(f_int[e, F_ACTS], stretch):
                total += 0.5 * k * stretch * stretch
        elif kind == BUSHING:
            total += _bushing_energy(f_int, f_float, e, rotation, position, RB, Rrel)
        elif kind == PLANE_CONTACT or kind == SPHERE_CONTACT:
            if kind == PLANE_CONTACT:
                delta = _sphere_plane(f_int, f_float, e, rotation, position)[6]
            else:
                delta = _sphere_sphere(f_int, f_float, e, position)[6]
            if delta > 0.0:
                total += k * delta ** (n + 1.0) / (n + 1.0)
        elif kind == HINGE_SPRING:
            x = q[f_int[e, F_Q]] - f_float[e, F_LENGTH]
            total += 0.5 * k * x * x
        elif kind == HINGE_STOP:
            x = q[f_int[e, F_Q]]
            if x < f_float[e, F_LOWER]:
                total += k * (f_float[e, F_LOWER] - x) ** (n + 1.0) / (n + 1.0)
            elif x > f_float[e, F_UPPER]:
                total += k * (x - f_float[e, F_UPPER]) ** (n + 1.0) / (n + 1.0)
    return total


# ---------------------------------------------------------------------------------------------- definitions
def _number(value, where, what, low=None, positive=False):
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise ModelDefinitionError(f"{where}: {what} must be a number, got {value!r}") from None
    if not np.isfinite(x) or (positive and not x > 0.0) or (low is not None and x < low):
        need = "a positive number" if positive else f"a number >= {low}" if low is not None else "finite"
        raise ModelDefinitionError(f"{where}: {what} must be {need}, got {value!r}")
    return x


def hunt_crossley_damping(restitution, impact_speed, where, exponent=1.5):
    """The Hunt-Crossley damping ``D`` [s per unit penetration] whose impact at ``impact_speed`` rebounds with exactly
    the coefficient of restitution ``e`` (module docstring): ``D = beta / v`` with ``beta`` the root of
    ``restitution_of(beta, n) = e`` (:func:`restitution_of`; the restitution of the law depends on ``D v`` and the
    exponent only, not on the stiffness or the mass)."""
    e = _number(restitution, where, "restitution", positive=True)
    if e > 1.0:
        raise ModelDefinitionError(f"{where}: restitution must be in (0, 1], got {restitution!r}")
    v = _number(impact_speed, where, "impact_speed", positive=True)
    n = _number(exponent, where, "exponent", low=1.0)
    return _damping_number(e, n) / v


def restitution_of(beta, exponent):
    """Coefficient of restitution of the Hunt-Crossley impact ``X'' = -X^n max(1 + beta X', 0)`` entered at ``X' =
    1`` (the law in units where the impact speed is 1 and ``m = k = 1``: ``x = a X``, ``t = tau s`` with ``a / tau =
    v`` and ``m a / tau^2 = k a^n`` turn ``m x'' = -k x^n (1 + D x')`` into it with ``beta = D v``): the exit speed,
    by DOP853 to 1e-12."""
    from scipy.integrate import solve_ivp

    def rates(t, y):
        return [y[1], -max(y[0], 0.0) ** exponent * max(1.0 + beta * y[1], 0.0)]

    def leaves(t, y):
        return y[0] if y[1] < 0.0 else 1.0
    leaves.terminal, leaves.direction = True, -1
    sol = solve_ivp(rates, (0.0, 1e6), [0.0, 1.0], events=leaves, method="DOP853", rtol=1e-12, atol=1e-14)
    if not sol.t_events[0].size:  # the damping held it: it never comes back out
        return 0.0
    return -float(sol.y_events[0][0][1])


@lru_cache(maxsize=256)
def _damping_number(e, n):
    """``beta`` with :func:`restitution_of` ``(beta, n) = e`` (it falls from 1 at beta = 0): Brent's method."""
    from scipy.optimize import brentq

    if e == 1.0:
        return 0.0
    high = 1.0
    while restitution_of(high, n) > e:
        high *= 4.0
        if high > 1e9:
            raise ModelDefinitionError(f"restitution {e!r} is below what Hunt-Crossley damping reaches; give damping")
    return brentq(lambda beta: restitution_of(beta, n) - e, 0.0, high, xtol=1e-14, rtol=1e-13)


class _Element:
    """What every element shares: a name, and the table rows it compiles to."""

    kind = -1

    @property
    def where(self):
        return f"force element '{self.name}'"

    def _rows(self):
        ints = np.zeros(F_INT_COLUMNS, dtype=np.int64)
        ints[F_KIND] = self.kind
        ints[F_NODE_A] = ints[F_NODE_B] = ints[F_Q] = ints[F_U] = -1
        ints[F_ACTIVE] = 1
        floats = np.zeros(F_FLOAT_COLUMNS)
        floats[F_WORLD_R:F_WORLD_R + 9] = np.eye(3).ravel()
        return ints, floats

    def _node(self, system, name, what):
        if name not in system.node_names:
            from dynamics.definitions import suggest

            raise ModelDefinitionError(f"{self.where}: unknown node '{name}' for {what}; nodes: "
                                       f"{list(system.node_names)}" + suggest(name, system.node_names))
        return system.node_index(name)

    def _contact_law(self, floats, exponent_default):
        floats[F_STIFFNESS] = _number(self.stiffness, self.where, "stiffness", positive=True)
        floats[F_EXPONENT] = _number(exponent_default if self.exponent is None else self.exponent, self.where,
                                     "exponent", low=1.0)
        if self.restitution is not None:
            if self.damping is not None:
                raise ModelDefinitionError(f"{self.where}: give damping or restitution (with impact_speed), not both")
            if self.impact_speed is None:
                raise ModelDefinitionError(f"{self.where}: restitution needs the impact_speed it holds at "
                                           f"(the Hunt-Crossley damping depends on it)")
            floats[F_DAMPING] = hunt_crossley_damping(self.restitution, self.impact_speed, self.where,
                                                      floats[F_EXPONENT])
        else:
            floats[F_DAMPING] = _number(self.damping or 0.0, self.where, "damping", low=0.0)


@dataclass
class SpringDamper(_Element):
    """Line spring-damper between the origins of ``node_a`` and ``node_b`` (or ``world_point``); ``free_length``
    None: the length at the reference configuration."""

    name: str
    node_a: str
    node_b: str | None = None
    stiffness: float = 0.0
    damping: float = 0.0
    free_length: float | None = None
    acts: str = "both"
    world_point: tuple | None = None
    kind = SPRING_DAMPER

    def compile(self, system, reference, allow_locked=False):
        ints, floats = self._rows()
        ints[F_NODE_A] = self._node(system, self.node_a, "node_a")
        if self.node_b is not None:
            if self.world_point is not None:
                raise ModelDefinitionError(f"{self.where}: give node_b or world_point, not both")
            ints[F_NODE_B] = self._node(system, self.node_b, "node_b")
            end = None
        else:
            end = np.zeros(3) if self.world_point is None else np.asarray(self.world_point, dtype=float)
            if end.shape != (3,) or not np.all(np.isfinite(end)):
                raise ModelDefinitionError(f"{self.where}: world_point must be 3 numbers, got {self.world_point!r}")
            floats[F_WORLD_P:F_WORLD_P + 3] = end
        if self.acts not in ACTS:
            raise ModelDefinitionError(f"{self.where}: acts must be one of {sorted(ACTS)}, got {self.acts!r}")
        ints[F_ACTS] = ACTS[self.acts]
        floats[F_STIFFNESS] = _number(self.stiffness, self.where, "stiffness", low=0.0)
        floats[F_DAMPING] = _number(self.damping, self.where, "damping", low=0.0)
        if self.free_length is None:
            if reference is None:
                raise ModelDefinitionError(f"{self.where}: give free_length (or a reference configuration)")
            pa = reference.position[ints[F_NODE_A]]
            pb = reference.position[ints[F_NODE_B]] if end is None else end
            floats[F_LENGTH] = float(np.linalg.norm(pb - pa))
        else:
            floats[F_LENGTH] = _number(self.free_length, self.where, "free_length", low=0.0)
        return ints, floats


@dataclass
class Bushing(_Element):
    """Six-DOF bushing: ``stiffness`` and ``damping`` (6 x 6, rows [rotation; translation], node A's axes)
    between node A and node B (or the world pose ``world_rotation``/``world_position``; None: node A's pose
    at the reference configuration, so the bushing starts relaxed)."""

    name: str
    node_a: str
    node_b: str | None = None
    stiffness: object = None
    damping: object = None
    world_rotation: object = None
    world_position: object = None
    kind = BUSHING

    def _matrix(self, value, what):
        a = np.asarray(value, dtype=float)
        if a.shape == (6,):
            a = np.diag(a)
        if a.shape != (6, 6) or not np.all(np.isfinite(a)):
            raise ModelDefinitionError(f"{self.where}: {what} must be 6 x 6 (or its 6 diagonal entries), got "
                                       f"shape {a.shape}")
        scale = max(np.abs(a).max(), 1e-300)
        sym = 0.5 * (a + a.T)
        if np.linalg.eigvalsh(sym).min() < -1e-12 * scale:
            raise ModelDefinitionError(f"{self.where}: {what} must be positive semidefinite (eigenvalues "
                                       f"{np.linalg.eigvalsh(sym).round(6).tolist()})")
        return a, scale

    def compile(self, system, reference, allow_locked=False):
        ints, floats = self._rows()
        ints[F_NODE_A] = self._node(system, self.node_a, "node_a")
        K, scale = self._matrix(self.stiffness, "stiffness") if self.stiffness is not None else (np.zeros((6, 6)), 1.0)
        if np.abs(K - K.T).max(initial=0.0) > 1e-12 * scale:
            raise ModelDefinitionError(f"{self.where}: stiffness must be symmetric (a non-symmetric stiffness is "
                                       f"not conservative and has no potential energy)")
        C = self._matrix(self.damping, "damping")[0] if self.damping is not None else np.zeros((6, 6))
        floats[F_K6:F_K6 + 36] = K.ravel()
        floats[F_C6:F_C6 + 36] = C.ravel()
        if self.node_b is not None:
            ints[F_NODE_B] = self._node(system, self.node_b, "node_b")
            return ints, floats
        R, p = self.world_rotation, self.world_position
        if R is None or p is None:
            if reference is None:
                raise ModelDefinitionError(f"{self.where}: give world_rotation and world_position (or a "
                                           f"reference configuration)")
            R = reference.rotation[ints[F_NODE_A]] if R is None else R
            p = reference.position[ints[F_NODE_A]] if p is None else p
        floats[F_WORLD_R:F_WORLD_R + 9] = np.asarray(R, dtype=float).ravel()
        floats[F_WORLD_P:F_WORLD_P + 3] = np.asarray(p, dtype=float)
        return ints, floats


@dataclass
class _HingeElement(_Element):
    def _dof(self, system, ints, allow_locked):
        """q and u indices of the element's DOF into ``ints``; on a hinge locked by a run-time change
        (``allow_locked``) the element is switched off."""
        from dynamics.definitions import suggest
        from dynamics.hinges import HINGES, hinge as hinge_record

        names = list(system.body_names)
        if self.body not in names:
            joints = list(system.joint_names)
            if self.body not in joints:
                raise ModelDefinitionError(f"{self.where}: unknown body or hinge '{self.body}'; bodies: {names}"
                                           + suggest(self.body, names + joints))
            k = joints.index(self.body)
        else:
            k = names.index(self.body)
        hinge = system.hinge_names[k]
        if hinge == "locked" and allow_locked:
            ints[F_ACTIVE] = 0
            return
        n = hinge_record(hinge).element_dofs
        dof = int(self.dof)
        if not 0 <= dof < n:
            kinds = ", ".join(h.name for h in HINGES if h.element_dofs)
            raise ModelDefinitionError(f"{self.where}: body '{system.body_names[k]}' has a {hinge} hinge; hinge "
                                       f"elements act on {kinds} coordinates (dof 0"
                                       f"{f' to {n - 1}' if n > 1 else ''}), got dof {self.dof!r}" if n else
                                       f"{self.where}: body '{system.body_names[k]}' has a {hinge} hinge; hinge "
                                       f"elements act on {kinds} coordinates")
        ints[F_Q] = system.q_slices[k].start + dof
        ints[F_U] = system.u_slices[k].start + dof


@dataclass
class HingeSpring(_HingeElement):
    """``tau = -stiffness (q - neutral) - damping u`` on DOF ``dof`` of ``body``'s hinge."""

    name: str
    body: str
    stiffness: float = 0.0
    damping: float = 0.0
    neutral: float = 0.0
    dof: int = 0
    kind = HINGE_SPRING

    def compile(self, system, reference, allow_locked=False):
        ints, floats = self._rows()
        self._dof(system, ints, allow_locked)
        floats[F_STIFFNESS] = _number(self.stiffness, self.where, "stiffness", low=0.0)
        floats[F_DAMPING] = _number(self.damping, self.where, "damping", low=0.0)
        floats[F_LENGTH] = _number(self.neutral, self.where, "neutral")
        return ints, floats


@dataclass
class HingeStop(_HingeElement):
    """Limit stops ``lower <= q <= upper`` (either may be None) on DOF ``dof`` of ``body``'s hinge: Hunt-Crossley
    penalty ``k delta^n (1 + D delta_dot)`` with ``D`` = ``damping`` or from ``restitution`` at ``impact_speed``."""

    name: str
    body: str
    lower: float | None = None
    upper: float | None = None
    stiffness: float = 0.0
    exponent: float | None = None
    damping: float | None = None
    restitution: float | None = None
    impact_speed: float | None = None
    dof: int = 0
    kind = HINGE_STOP

    def compile(self, system, reference, allow_locked=False):
        ints, floats = self._rows()
        self._dof(system, ints, allow_locked)
        if self.lower is None and self.upper is None:
            raise ModelDefinitionError(f"{self.where}: give lower and/or upper")
        lower = -np.inf if self.lower is None else _number(self.lower, self.where, "lower")
        upper = np.inf if self.upper is None else _number(self.upper, self.where, "upper")
        if not lower < upper:
            raise ModelDefinitionError(f"{self.where}: lower ({lower}) must be below upper ({upper})")
        floats[F_LOWER], floats[F_UPPER] = lower, upper
        self._contact_law(floats, 1.0)
        return ints, floats


@dataclass
class HingeFriction(_HingeElement):
    """Coulomb friction of level ``level`` (N m or N) on DOF ``dof`` of ``body``'s hinge, regularized below
    ``slip_speed``."""

    name: str
    body: str
    level: float = 0.0
    slip_speed: float = 1e-3
    dof: int = 0
    kind = HINGE_FRICTION

    def compile(self, system, reference, allow_locked=False):
        ints, floats = self._rows()
        self._dof(system, ints, allow_locked)
        floats[F_FRICTION] = _number(self.level, self.where, "level", low=0.0)
        floats[F_SLIP] = _number(self.slip_speed, self.where, "slip_speed", positive=True)
        return ints, floats


@dataclass(kw_only=True)
class _Contact(_Element):
    """The contact law every contact shares (keywords): Hunt-Crossley ``stiffness``, ``exponent`` (3/2),
    ``damping`` or ``restitution`` at ``impact_speed``, Coulomb ``friction`` regularized below ``slip_speed``."""

    stiffness: float = 0.0
    exponent: float | None = None
    damping: float | None = None
    restitution: float | None = None
    impact_speed: float | None = None
    friction: float = 0.0
    slip_speed: float = 1e-3

    def _contact_rows(self, floats):
        self._contact_law(floats, 1.5)
        floats[F_FRICTION] = _number(self.friction, self.where, "friction", low=0.0)
        floats[F_SLIP] = _number(self.slip_speed, self.where, "slip_speed", positive=True)


@dataclass
class PlaneContact(_Contact):
    """A sphere of ``radius`` centred on ``node`` against a plane through ``plane_node``'s origin with unit
    ``normal`` in its axes (default +z), or fixed in the world (``plane_node`` None: ``world_point`` and a
    world ``normal``)."""

    name: str
    node: str
    radius: float = 0.0
    plane_node: str | None = None
    normal: tuple = (0.0, 0.0, 1.0)
    world_point: tuple = (0.0, 0.0, 0.0)
    kind = PLANE_CONTACT

    def compile(self, system, reference, allow_locked=False):
        ints, floats = self._rows()
        ints[F_NODE_A] = self._node(system, self.node, "node")
        if self.plane_node is not None:
            ints[F_NODE_B] = self._node(system, self.plane_node, "plane_node")
            if system.node_bodies[ints[F_NODE_A]] == system.node_bodies[ints[F_NODE_B]]:
                raise ModelDefinitionError(f"{self.where}: node '{self.node}' and plane_node '{self.plane_node}' are "
                                           f"on the same body '{system.node_bodies[ints[F_NODE_A]]}'")
        n = np.asarray(self.normal, dtype=float)
        if n.shape != (3,) or not abs(np.linalg.norm(n) - 1.0) < 1e-9:
            raise ModelDefinitionError(f"{self.where}: normal must be a unit 3-vector, got {self.normal!r}")
        p = np.asarray(self.world_point, dtype=float)
        if p.shape != (3,) or not np.all(np.isfinite(p)):
            raise ModelDefinitionError(f"{self.where}: world_point must be 3 numbers, got {self.world_point!r}")
        floats[F_NORMAL:F_NORMAL + 3] = n
        floats[F_WORLD_P:F_WORLD_P + 3] = p
        floats[F_RADIUS_A] = _number(self.radius, self.where, "radius", low=0.0)
        self._contact_rows(floats)
        return ints, floats


@dataclass
class SphereContact(_Contact):
    """Two spheres, radius ``radius_a`` on ``node_a`` and ``radius_b`` on ``node_b``."""

    name: str
    node_a: str
    node_b: str
    radius_a: float = 0.0
    radius_b: float = 0.0
    kind = SPHERE_CONTACT

    def compile(self, system, reference, allow_locked=False):
        ints, floats = self._rows()
        ints[F_NODE_A] = self._node(system, self.node_a, "node_a")
        ints[F_NODE_B] = self._node(system, self.node_b, "node_b")
        if system.node_bodies[ints[F_NODE_A]] == system.node_bodies[ints[F_NODE_B]]:
            raise ModelDefinitionError(f"{self.where}: nodes '{self.node_a}' and '{self.node_b}' are on the same "
                                       f"body '{system.node_bodies[ints[F_NODE_A]]}'")
        floats[F_RADIUS_A] = _number(self.radius_a, self.where, "radius_a", low=0.0)
        floats[F_RADIUS_B] = _number(self.radius_b, self.where, "radius_b", low=0.0)
        if not floats[F_RADIUS_A] + floats[F_RADIUS_B] > 0.0:
            raise ModelDefinitionError(f"{self.where}: the radii must not both be zero")
        self._contact_rows(floats)
        return ints, floats


ELEMENT_TYPES = {"spring_damper": SpringDamper, "bushing": Bushing, "hinge_spring": HingeSpring,
                 "hinge_stop": HingeStop, "hinge_friction": HingeFriction, "plane_contact": PlaneContact,
                 "sphere_contact": SphereContact}
"""Force element classes by the ``kind`` a scene gives."""


def element_tables(elements, system, reference, allow_locked=False):
    """``(f_int, f_float)`` of the elements (names unique), validated against ``system``; ``reference`` is
    the node kinematics at the reference configuration (or None). ``allow_locked``: hinge elements on locked
    hinges are switched off instead of refused (a run-time lock; see :mod:`dynamics.reconfigure`)."""
    ints = np.zeros((len(elements), F_INT_COLUMNS), dtype=np.int64)
    floats = np.zeros((len(elements), F_FLOAT_COLUMNS))
    seen = set()
    for k, element in enumerate(elements):
        if element.name in seen:
            raise ModelDefinitionError(f"force element '{element.name}': duplicate name")
        seen.add(element.name)
        ints[k], floats[k] = element.compile(system, reference, allow_locked)
    return ints, floats
