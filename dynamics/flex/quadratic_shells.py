"""Curved shell elements CQUAD8 and CTRIA6 (PSHELL or PCOMP): quadratic isoparametric Mindlin shells.

Geometry and displacements share the quadratic shape functions of the grids: CQUAD8 the 8-node serendipity
quadrilateral (corners G1-G4, then G5-G8 on the edges 1-2, 2-3, 3-4, 4-1), CTRIA6 the 6-node triangle
(corners G1-G3, then G4-G6 on the edges 1-2, 2-3, 3-1; MSC Nastran QRG CQUAD8, CTRIA6). Every grid has its
three translations and three rotations in basic.

At each integration point the shell is taken as flat in its tangent plane (the "degenerated shell in
resultant form" of Hughes, The Finite Element Method, 1987, sec. 6.4, with the thickness integrated
analytically and the curvature of the lamina within one element neglected, a shallow-shell assumption per
element): the normal e3 = g1 x g2 / |g1 x g2| of the tangents g_a = dx/dxi_a, e1 the element x axis projected
on the tangent plane, e2 = e3 x e1. With u_a = e_a . u, theta_a = e_a . theta the local components:

* membrane e = [u1,1, u2,2, u1,2 + u2,1], N = A e (+ B kappa);
* bending (the sign convention of :mod:`dynamics.flex.shells`: a point at height z moves by theta x z e3)
  kappa = [theta2,1, -theta1,2, theta2,2 - theta1,1], M = D kappa (+ B e);
* transverse shear gamma = [w,1 + theta2, w,2 - theta1], Q = S gamma, w = e3 . u;
* drilling: the Hughes-Brezzi penalty gamma_d (theta3 - omega)^2, omega = (u2,1 - u1,2) / 2, gamma_d from
  :func:`dynamics.flex.shells.drilling_modulus` (the element's mean bending modulus over its area).

A, D, S, B are those of the flat shells (:func:`dynamics.flex.shells._materials`: MAT1, MAT2, MAT8, PCOMP,
material axes by THETA or MCID from the element x axis, which is that of the corner grids as for CQUAD4 /
CTRIA3). Integration: CQUAD8 3 x 3 Gauss points for membrane, bending and mass, 2 x 2 for transverse shear
and drilling (selective reduced integration: Hughes sec. 5.6; the reduced shear rule relieves the shear
locking of the quadratic element, and the full bending rule leaves no zero-energy mode besides the six rigid
motions, tests/flex/test_quadratic_shells.py); CTRIA6 Dunavant's 6-point degree-4 rule for membrane,
bending and mass, the 3 edge-midpoint rule (degree 2) for shear and drilling. Mass: consistent
(rho t + NSM) int N_i N_j dA on the translations and the Mindlin rotary inertia rho t^3 / 12 on the two
bending rotations; lumped: the translational mass by HRZ diagonal scaling (Hinton, Rock & Zienkiewicz 1976),
which keeps the corner masses of the quadratic elements positive. ZOFFS is not supported (refused by the
assembly).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from dynamics.flex.shells import _materials, drilling_modulus, element_frame

_Q8_NODES = np.array([[-1.0, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, 1.0],
                      [0.0, -1.0], [1.0, 0.0], [0.0, 1.0], [-1.0, 0.0]])


def _gauss_square(n):
    x, w = np.polynomial.legendre.leggauss(n)
    return np.array([[a, b, wa * wb] for a, wa in zip(x, w) for b, wb in zip(x, w)])


def _dunavant6():
    """Dunavant's degree-4 rule on the unit triangle (IJNME 21, 1985): rows (r, s, weight / area)."""
    a1, w1 = 0.445948490915965, 0.223381589678011
    a2, w2 = 0.091576213509771, 0.109951743655322
    rows = []
    for a, w in ((a1, w1), (a2, w2)):
        b = 1.0 - 2.0 * a
        rows += [[a, a, w], [b, a, w], [a, b, w]]
    return np.array(rows)


Q8_FULL, Q8_REDUCED = _gauss_square(3), _gauss_square(2)
T6_FULL = _dunavant6()
T6_REDUCED = np.array([[0.5, 0.0, 1.0 / 3.0], [0.5, 0.5, 1.0 / 3.0], [0.0, 0.5, 1.0 / 3.0]])


@njit(cache=True)
def shape(n, r, s):
    """N (n,) and dN/d(r, s) (2, n) of the 8-node serendipity quadrilateral or the 6-node triangle."""
    N = np.zeros(n)
    dN = np.zeros((2, n))
    if n == 8:
        for i in range(4):
            a, b = _Q8_NODES[i, 0], _Q8_NODES[i, 1]
            N[i] = 0.25 * (1 + a * r) * (1 + b * s) * (a * r + b * s - 1)
            dN[0, i] = 0.25 * a * (1 + b * s) * (2 * a * r + b * s)
            dN[1, i] = 0.25 * b * (1 + a * r) * (a * r + 2 * b * s)
        for i in range(4, 8):
            a, b = _Q8_NODES[i, 0], _Q8_NODES[i, 1]
            if a == 0.0:
                N[i] = 0.5 * (1 - r * r) * (1 + b * s)
                dN[0, i] = -r * (1 + b * s)
                dN[1, i] = 0.5 * b * (1 - r * r)
            else:
                N[i] = 0.5 * (1 + a * r) * (1 - s * s)
                dN[0, i] = 0.5 * a * (1 - s * s)
                dN[1, i] = -s * (1 + a * r)
        return N, dN
    L = np.array([1.0 - r - s, r, s])
    dL = np.array([[-1.0, 1.0, 0.0], [-1.0, 0.0, 1.0]])
    for i in range(3):
        N[i] = L[i] * (2.0 * L[i] - 1.0)
        for d in range(2):
            dN[d, i] = dL[d, i] * (4.0 * L[i] - 1.0)
    for k in range(3):
        a, b = k, (k + 1) % 3
        N[3 + k] = 4.0 * L[a] * L[b]
        for d in range(2):
            dN[d, 3 + k] = 4.0 * (dL[d, a] * L[b] + L[a] * dL[d, b])
    return N, dN


@njit(cache=True)
def _point(xyz, x_axis, r, s):
    """(N, local derivatives dN/d(x1, x2) (2, n), frame rows e1, e2, e3, area element dA / d(r, s))."""
    n = xyz.shape[0]
    N, dN = shape(n, r, s)
    g1 = dN[0] @ xyz
    g2 = dN[1] @ xyz
    nrm = np.cross(g1, g2)
    jac = np.linalg.norm(nrm)
    if jac <= 0.0:
        raise ValueError("CQUAD8/CTRIA6: degenerate element (zero area element at an integration point)")
    e3 = nrm / jac
    e1 = x_axis - (x_axis @ e3) * e3
    e1 = e1 / np.linalg.norm(e1)
    e2 = np.cross(e3, e1)
    E = np.empty((3, 3))
    E[0], E[1], E[2] = e1, e2, e3
    J = np.array([[g1 @ e1, g1 @ e2], [g2 @ e1, g2 @ e2]])
    dNx = np.linalg.solve(J, dN)
    return N, dNx, E, jac


@njit(cache=True)
def _rows(N, dNx, E):
    """Strain rows (6 n columns: [u; theta] in basic per grid): membrane (3), bending (3), shear (2),
    drilling theta3 - omega (1)."""
    n = N.shape[0]
    Bm = np.zeros((3, 6 * n))
    Bb = np.zeros((3, 6 * n))
    Bs = np.zeros((2, 6 * n))
    Bd = np.zeros((1, 6 * n))
    for i in range(n):
        x1, x2 = dNx[0, i], dNx[1, i]
        for k in range(3):
            cu, ct = 6 * i + k, 6 * i + 3 + k
            e1, e2, e3 = E[0, k], E[1, k], E[2, k]
            Bm[0, cu] = x1 * e1
            Bm[1, cu] = x2 * e2
            Bm[2, cu] = x2 * e1 + x1 * e2
            Bb[0, ct] = x1 * e2
            Bb[1, ct] = -x2 * e1
            Bb[2, ct] = x2 * e2 - x1 * e1
            Bs[0, cu] = x1 * e3
            Bs[1, cu] = x2 * e3
            Bs[0, ct] = N[i] * e2
            Bs[1, ct] = -N[i] * e1
            Bd[0, ct] = N[i] * e3
            Bd[0, cu] = -0.5 * (x1 * e2 - x2 * e1)
    return Bm, Bb, Bs, Bd


@njit(cache=True)
def curved_shell(xyz, p, coupled, full, reduced):
    """Basic-frame K, M and lumped M (6 n x 6 n) of one CQUAD8 (n = 8) or CTRIA6 (n = 6); ``p`` the property
    row of :func:`dynamics.flex.shells.shell_batch`; ``full``, ``reduced`` the rules (r, s, weight)."""
    n = xyz.shape[0]
    nd = 6 * n
    Lam, _, _ = element_frame(np.ascontiguousarray(xyz[:4] if n == 8 else xyz[:3]))
    A, D, S, gt, Bc = _materials(p, Lam)
    rho, t, nsm = p[22], p[23], p[24]
    mu = rho * t + nsm
    rotary = rho * t ** 3 / 12.0
    x_axis = np.ascontiguousarray(Lam[0])
    K = np.zeros((nd, nd))
    M = np.zeros((nd, nd))
    diag = np.zeros(n)
    area = 0.0
    for q in range(full.shape[0]):
        N, dNx, E, jac = _point(xyz, x_axis, full[q, 0], full[q, 1])
        w = full[q, 2] * jac
        area += w
        _, Bb, _, _ = _rows(N, dNx, E)
        K += (Bb.T @ D @ Bb) * w
        bend = np.outer(E[0], E[0]) + np.outer(E[1], E[1])
        for i in range(n):
            diag[i] += mu * N[i] * N[i] * w
            if coupled:
                for j in range(n):
                    m = N[i] * N[j] * w
                    for d in range(3):
                        M[6 * i + d, 6 * j + d] += mu * m
                    M[6 * i + 3:6 * i + 6, 6 * j + 3:6 * j + 6] += rotary * m * bend
    gamma_d = drilling_modulus(gt, A, D, Bc, area)
    for q in range(full.shape[0]):
        N, dNx, E, jac = _point(xyz, x_axis, full[q, 0], full[q, 1])
        _, _, _, Bd = _rows(N, dNx, E)
        K += gamma_d * (Bd.T @ Bd) * (full[q, 2] * jac)
    for q in range(reduced.shape[0]):
        N, dNx, E, jac = _point(xyz, x_axis, reduced[q, 0], reduced[q, 1])
        w = reduced[q, 2] * jac
        Bm, Bb, Bs, _ = _rows(N, dNx, E)
        K += (Bm.T @ A @ Bm + Bm.T @ Bc @ Bb + Bb.T @ Bc @ Bm + Bs.T @ S @ Bs) * w
    ML = np.zeros((nd, nd))
    share = diag * (mu * area / diag.sum())
    for i in range(n):
        for d in range(3):
            ML[6 * i + d, 6 * i + d] = share[i]
    if not coupled:
        M[:, :] = ML
    return 0.5 * (K + K.T), M, ML


@njit(cache=True)
def curved_shell_batch(xyz, props, coupled, full, reduced):
    """K, M, lumped M (ne, 6 n, 6 n) of many elements of one kind (:func:`curved_shell`)."""
    ne, n = xyz.shape[0], xyz.shape[1]
    Kg = np.empty((ne, 6 * n, 6 * n))
    Mg = np.empty((ne, 6 * n, 6 * n))
    MLg = np.empty((ne, 6 * n, 6 * n))
    for e in range(ne):
        Kg[e], Mg[e], MLg[e] = curved_shell(np.ascontiguousarray(xyz[e]), props[e], coupled, full, reduced)
    return Kg, Mg, MLg


def rules(n_grids: int):
    """(full, reduced) integration rules of the element with ``n_grids`` grids (module docstring)."""
    return (Q8_FULL, Q8_REDUCED) if n_grids == 8 else (T6_FULL * [1.0, 1.0, 0.5], T6_REDUCED * [1.0, 1.0, 0.5])
