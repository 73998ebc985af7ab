"""Solid elements for CHEXA (8 and 20 grids), CTETRA (4 and 10), CPENTA (6 and 15) with PSOLID and MAT1.

Isoparametric displacement elements (Zienkiewicz, Taylor & Zhu, The Finite Element Method,
7th ed., 2013, ch. 6), three translations per grid, grids in NASTRAN's order (QRG: CHEXA,
CTETRA, CPENTA: corners first, then the mid-edge grids). Isotropic elasticity in Voigt order
``[e_xx, e_yy, e_zz, g_xy, g_yz, g_zx]``.

* CHEXA8: trilinear plus Wilson's nine incompatible modes ``(1 - xi^2), (1 - eta^2),
  (1 - zeta^2)`` per direction, their derivatives taken with the centre Jacobian and scaled by
  det J0 / det J (Taylor, Beresford & Wilson, IJNME 10, 1976) so that the element passes the
  patch test, condensed statically: without them the 2 x 2 x 2 element locks in bending.
  NASTRAN's default CHEXA uses bubble functions to the same end, so frequencies agree to
  discretization error, not round-off.
* CHEXA20 (serendipity), CTETRA10, CTETRA4, CPENTA6, CPENTA15: plain displacement elements. CPENTA15 is the
  quadratic serendipity wedge (triangle area coordinates L_i times zeta in [-1, 1]): corners
  L_i (2 L_i - 1)(1 +- zeta)/2 - L_i (1 - zeta^2)/2, mid-edge grids of the triangles 2 L_a L_b (1 +- zeta),
  of the vertical edges L_i (1 - zeta^2); grids G7-G9 on the edges 1-2, 2-3, 3-1, G10-G12 on 1-4, 2-5,
  3-6, G13-G15 on 4-5, 5-6, 6-4 (QRG CPENTA remark 2: G1, G10 and G4 on one edge).
* Quadrature: Gauss 2^3 (CHEXA8), 3^3 (CHEXA20); tetrahedra by the collapsed (Duffy) product of
  4^3 Gauss points, exact for the degree-4 integrand of the CTETRA10 mass; CPENTA6 a collapsed
  3^2 triangle rule times 2 Gauss points in zeta; CPENTA15 4^2 times 3 (exact for its degree-4 mass
  integrand on an undistorted wedge).
* Mass: consistent ``rho int N' N dV`` or lumped: the element mass shared equally by the corner
  grids (CHEXA8, CTETRA4, CPENTA6); for the mid-edge elements by HRZ diagonal scaling (Hinton,
  Rock & Zienkiewicz, Earthquake Eng. Struct. Dyn. 4, 1976), which keeps every grid's mass
  positive.
"""

from __future__ import annotations

import numpy as np
from numba import njit

HEXA8, HEXA20, TETRA4, TETRA10, PENTA6, PENTA15 = 0, 1, 2, 3, 4, 5
GRIDS = {HEXA8: 8, HEXA20: 20, TETRA4: 4, TETRA10: 10, PENTA6: 6, PENTA15: 15}
NAMES = {HEXA8: "CHEXA8", HEXA20: "CHEXA20", TETRA4: "CTETRA4", TETRA10: "CTETRA10",
         PENTA6: "CPENTA6", PENTA15: "CPENTA15"}

_HEX_CORNERS = np.array([[-1, -1, -1], [1, -1, -1], [1, 1, -1], [-1, 1, -1],
                         [-1, -1, 1], [1, -1, 1], [1, 1, 1], [-1, 1, 1]], dtype=np.float64)
# CHEXA20 mid-edge grids 9-20: edges 1-2, 2-3, 3-4, 4-1, 1-5, 2-6, 3-7, 4-8, 5-6, 6-7, 7-8, 8-5
_HEX_EDGES = np.array([[0, 1], [1, 2], [2, 3], [3, 0], [0, 4], [1, 5], [2, 6], [3, 7],
                       [4, 5], [5, 6], [6, 7], [7, 4]], dtype=np.int64)
# CTETRA10 mid-edge grids 5-10: edges 1-2, 2-3, 3-1, 1-4, 2-4, 3-4
_TET_EDGES = np.array([[0, 1], [1, 2], [2, 0], [0, 3], [1, 3], [2, 3]], dtype=np.int64)
# CPENTA15 mid-edge grids 7-9 and 13-15: the triangle edges 1-2, 2-3, 3-1 at zeta = -1 and +1
_TRI_EDGES = np.array([[0, 1], [1, 2], [2, 0]], dtype=np.int64)


def _gauss(n):
    x, w = np.polynomial.legendre.leggauss(n)
    return x, w


def _hex_rule(n):
    x, w = _gauss(n)
    pts = np.array([[a, b, c] for a in x for b in x for c in x])
    wts = np.array([wa * wb * wc for wa in w for wb in w for wc in w])
    return pts, wts


def _tet_rule(n):
    """Collapsed Gauss product on the unit tetrahedron (volume coordinates r, s, t)."""
    x, w = _gauss(n)
    x, w = 0.5 * (x + 1.0), 0.5 * w
    pts, wts = [], []
    for a, wa in zip(x, w):
        for b, wb in zip(x, w):
            for c, wc in zip(x, w):
                pts.append([a, b * (1 - a), c * (1 - a) * (1 - b)])
                wts.append(wa * wb * wc * (1 - a) ** 2 * (1 - b))
    return np.array(pts), np.array(wts)


def _penta_rule(n_tri, n_z):
    x, w = _gauss(n_tri)
    x, w = 0.5 * (x + 1.0), 0.5 * w
    z, wz = _gauss(n_z)
    pts, wts = [], []
    for a, wa in zip(x, w):
        for b, wb in zip(x, w):
            for c, wc in zip(z, wz):
                pts.append([a, b * (1 - a), c])
                wts.append(wa * wb * wc * (1 - a))
    return np.array(pts), np.array(wts)


RULES = {HEXA8: _hex_rule(2), HEXA20: _hex_rule(3), TETRA4: _tet_rule(4),
         TETRA10: _tet_rule(4), PENTA6: _penta_rule(3, 2), PENTA15: _penta_rule(4, 3)}


@njit(cache=True)
def shape(kind, p):
    """N (n,) and dN/d(natural) (3, n) at natural point p."""
    if kind == HEXA8 or kind == HEXA20:
        n = 8 if kind == HEXA8 else 20
        N = np.zeros(n)
        dN = np.zeros((3, n))
        for i in range(8):
            a, b, c = _HEX_CORNERS[i]
            fa, fb, fc = 1 + a * p[0], 1 + b * p[1], 1 + c * p[2]
            if kind == HEXA8:
                N[i] = 0.125 * fa * fb * fc
                dN[0, i] = 0.125 * a * fb * fc
                dN[1, i] = 0.125 * b * fa * fc
                dN[2, i] = 0.125 * c * fa * fb
            else:
                g = a * p[0] + b * p[1] + c * p[2] - 2.0
                N[i] = 0.125 * fa * fb * fc * g
                dN[0, i] = 0.125 * a * fb * fc * (g + fa)
                dN[1, i] = 0.125 * b * fa * fc * (g + fb)
                dN[2, i] = 0.125 * c * fa * fb * (g + fc)
        if kind == HEXA20:
            for k in range(12):
                m = 0.5 * (_HEX_CORNERS[_HEX_EDGES[k, 0]] + _HEX_CORNERS[_HEX_EDGES[k, 1]])
                # the coordinate along the edge is the one where m is zero
                f = np.ones(3)
                d = np.zeros(3)
                for j in range(3):
                    if m[j] == 0.0:
                        f[j] = 1 - p[j] * p[j]
                        d[j] = -2 * p[j]
                    else:
                        f[j] = 1 + m[j] * p[j]
                        d[j] = m[j]
                N[8 + k] = 0.25 * f[0] * f[1] * f[2]
                dN[0, 8 + k] = 0.25 * d[0] * f[1] * f[2]
                dN[1, 8 + k] = 0.25 * f[0] * d[1] * f[2]
                dN[2, 8 + k] = 0.25 * f[0] * f[1] * d[2]
        return N, dN
    if kind == TETRA4 or kind == TETRA10:
        L = np.array([1 - p[0] - p[1] - p[2], p[0], p[1], p[2]])
        dL = np.array([[-1.0, 1.0, 0.0, 0.0], [-1.0, 0.0, 1.0, 0.0], [-1.0, 0.0, 0.0, 1.0]])
        if kind == TETRA4:
            return L, dL
        N = np.zeros(10)
        dN = np.zeros((3, 10))
        for i in range(4):
            N[i] = L[i] * (2 * L[i] - 1)
            dN[:, i] = dL[:, i] * (4 * L[i] - 1)
        for k in range(6):
            a, b = _TET_EDGES[k]
            N[4 + k] = 4 * L[a] * L[b]
            dN[:, 4 + k] = 4 * (dL[:, a] * L[b] + L[a] * dL[:, b])
        return N, dN
    L = np.array([1 - p[0] - p[1], p[0], p[1]])
    dL = np.array([[-1.0, 1.0, 0.0], [-1.0, 0.0, 1.0]])
    if kind == PENTA15:
        z = p[2]
        N = np.zeros(15)
        dN = np.zeros((3, 15))
        bubble, dbubble = 1.0 - z * z, -2.0 * z
        for i in range(3):
            quad = L[i] * (2.0 * L[i] - 1.0)
            dquad = 4.0 * L[i] - 1.0
            for k, sgn in enumerate((-1.0, 1.0)):
                fz = 0.5 * (1.0 + sgn * z)
                c = 3 * k + i
                N[c] = quad * fz - 0.5 * L[i] * bubble
                dN[0, c] = dL[0, i] * (dquad * fz - 0.5 * bubble)
                dN[1, c] = dL[1, i] * (dquad * fz - 0.5 * bubble)
                dN[2, c] = quad * 0.5 * sgn - 0.5 * L[i] * dbubble
            N[9 + i] = L[i] * bubble
            dN[0, 9 + i] = dL[0, i] * bubble
            dN[1, 9 + i] = dL[1, i] * bubble
            dN[2, 9 + i] = L[i] * dbubble
        for e in range(3):
            a, b = _TRI_EDGES[e]
            for k, sgn in enumerate((-1.0, 1.0)):
                fz = 1.0 + sgn * z
                c = 6 + e if k == 0 else 12 + e
                N[c] = 2.0 * L[a] * L[b] * fz
                dN[0, c] = 2.0 * (dL[0, a] * L[b] + L[a] * dL[0, b]) * fz
                dN[1, c] = 2.0 * (dL[1, a] * L[b] + L[a] * dL[1, b]) * fz
                dN[2, c] = 2.0 * L[a] * L[b] * sgn
        return N, dN
    # PENTA6: triangle (r, s) x linear zeta
    N = np.zeros(6)
    dN = np.zeros((3, 6))
    for i in range(3):
        for k, z in enumerate((-1.0, 1.0)):
            fz = 0.5 * (1 + z * p[2])
            N[3 * k + i] = L[i] * fz
            dN[0, 3 * k + i] = dL[0, i] * fz
            dN[1, 3 * k + i] = dL[1, i] * fz
            dN[2, 3 * k + i] = L[i] * 0.5 * z
    return N, dN


@njit(cache=True)
def elasticity(E, nu):
    lam = E * nu / ((1 + nu) * (1 - 2 * nu))
    mu = E / (2 * (1 + nu))
    C = np.zeros((6, 6))
    for i in range(3):
        for j in range(3):
            C[i, j] = lam
        C[i, i] = lam + 2 * mu
        C[3 + i, 3 + i] = mu
    return C


@njit(cache=True)
def strain_matrix(dNx, n):
    B = np.zeros((6, 3 * n))
    for i in range(n):
        x, y, z = dNx[0, i], dNx[1, i], dNx[2, i]
        B[0, 3 * i] = x
        B[1, 3 * i + 1] = y
        B[2, 3 * i + 2] = z
        B[3, 3 * i], B[3, 3 * i + 1] = y, x
        B[4, 3 * i + 1], B[4, 3 * i + 2] = z, y
        B[5, 3 * i], B[5, 3 * i + 2] = z, x
    return B


@njit(cache=True)
def incompatible_rows(pts_q, J0i, det0, det):
    """Strain rows (6 x 9) of CHEXA8's incompatible modes (1 - xi_k^2) at a point, their gradients taken with the
    centre Jacobian J0 and scaled by det J0 / det J (the patch-test-passing form); shared by the stiffness here
    and the stresses of the geometric stiffness (geometric_stiffness_continuum)."""
    g = np.zeros((3, 3))
    for k in range(3):
        dp = np.zeros(3)
        dp[k] = -2.0 * pts_q[k]
        g[:, k] = J0i @ dp * (det0 / det)
    Ba = np.zeros((6, 9))
    for k in range(3):
        x, y, z = g[0, k], g[1, k], g[2, k]
        c = 3 * k
        Ba[0, c] = x
        Ba[1, c + 1] = y
        Ba[2, c + 2] = z
        Ba[3, c], Ba[3, c + 1] = y, x
        Ba[4, c + 1], Ba[4, c + 2] = z, y
        Ba[5, c], Ba[5, c + 2] = z, x
    return Ba


@njit(cache=True)
def solid_matrices(kind, xyz, E, nu, rho, pts, wts, coupled):
    """(K, M) of one solid, 3 n x 3 n in basic, DOFs [u, v, w] per grid."""
    n = xyz.shape[0]
    C = elasticity(E, nu)
    K = np.zeros((3 * n, 3 * n))
    M = np.zeros((3 * n, 3 * n))
    incompatible = kind == HEXA8
    if incompatible:
        _, dN0 = shape(kind, np.zeros(3))
        J0 = dN0 @ xyz
        J0i = np.linalg.inv(J0)
        det0 = np.linalg.det(J0)
        Kua = np.zeros((3 * n, 9))
        Kaa = np.zeros((9, 9))
    volume = 0.0
    diag = np.zeros(n)
    for q in range(len(wts)):
        N, dN = shape(kind, pts[q])
        J = dN @ xyz                      # J[i, j] = d x_j / d xi_i
        det = np.linalg.det(J)
        if det <= 0.0:
            raise ValueError("solid element: inverted or badly ordered grids (det J <= 0)")
        dNx = np.linalg.solve(J, dN)
        B = strain_matrix(dNx, n)
        w = wts[q] * det
        K += B.T @ C @ B * w
        volume += w
        if incompatible:
            Ba = incompatible_rows(pts[q], J0i, det0, det)
            Kua += B.T @ C @ Ba * w
            Kaa += Ba.T @ C @ Ba * w
        for i in range(n):
            diag[i] += rho * N[i] * N[i] * w
            if coupled:
                for j in range(n):
                    m = rho * N[i] * N[j] * w
                    for d in range(3):
                        M[3 * i + d, 3 * j + d] += m
    if incompatible:
        K -= Kua @ np.linalg.solve(Kaa, Kua.T)
    if not coupled:
        mass = rho * volume
        if kind == HEXA8 or kind == TETRA4 or kind == PENTA6:
            share = np.full(n, mass / n)
        else:
            share = diag * (mass / diag.sum())
        for i in range(n):
            for d in range(3):
                M[3 * i + d, 3 * i + d] = share[i]
    return 0.5 * (K + K.T), M


@njit(cache=True)
def solid_batch(kind, xyz, props, pts, wts, coupled):
    """K, M, lumped M (ne, 3n, 3n) of many solids of one kind; props (ne, 3): E, nu, rho."""
    ne, n = xyz.shape[0], xyz.shape[1]
    Kg = np.empty((ne, 3 * n, 3 * n))
    Mg = np.empty((ne, 3 * n, 3 * n))
    MLg = np.empty((ne, 3 * n, 3 * n))
    for e in range(ne):
        E, nu, rho = props[e]
        Kg[e], Mg[e] = solid_matrices(kind, xyz[e], E, nu, rho, pts, wts, coupled)
        if coupled:
            _, MLg[e] = solid_matrices(kind, xyz[e], E, nu, rho, pts, wts, False)
        else:
            MLg[e] = Mg[e]
    return Kg, Mg, MLg
