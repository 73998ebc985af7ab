"""Shell elements with mid-side grids: CQUAD8 and CTRIA6 (PSHELL or PCOMP).

CQUAD8 (corners G1-G4, then G5-G8 on the edges 1-2, 2-3, 3-4, 4-1; MSC Nastran QRG CQUAD8): the MITC9 shell of
Bucalem and Bathe ("Higher-order MITC general shell elements", IJNME 36, 1993) on the element's eight grids.
The geometry is the 8-node serendipity surface; the displacements and rotations add to the serendipity field a
bubble (1 - r^2)(1 - s^2) (the biquadratic Lagrange field), whose six amplitudes are condensed statically, so
the element keeps six DOFs per grid. At each integration point the shell is taken as flat in its tangent plane
(the degenerated shell in resultant form, Hughes, The Finite Element Method, 1987, sec. 6.4, thickness
integrated analytically, the lamina's own curvature within an element neglected):
``e3 = g1 x g2 / norm(g1 x g2)`` with g_a = dx/dxi_a, e1 the element x axis projected on the tangent plane,
e2 = e3 x e1; with u_a = e_a . u, theta_a = e_a . theta (a point at height z moves by theta x z e3, as in
:mod:`dynamics.flex.shells`):

* membrane e = [u1,1, u2,2, u1,2 + u2,1], N = A e (+ B kappa);
* bending kappa = [theta2,1, -theta1,2, theta2,2 - theta1,1], M = D kappa (+ B e);
* transverse shear gamma = [w,1 + theta2, w,2 - theta1], Q = S gamma, w = e3 . u;
* drilling: the Hughes-Brezzi penalty gamma_d (theta3 - omega)^2, omega = (u2,1 - u1,2) / 2, gamma_d from
  :func:`dynamics.flex.shells.drilling_modulus`.

Mixed interpolation of the strains (the MITC9 scheme's tying): the transverse shear e_rt (covariant) and the
in-plane e_11 are tied at r = +-1/sqrt(3), s = 0, +-sqrt(3/5) and interpolated linearly in r, quadratically in
s; e_st and e_22 the other way round; g_12 at (+-1/sqrt(3), +-1/sqrt(3)), bilinearly. The in-plane strains are
tied by their local Cartesian components (MITC9 ties covariant ones; on a distorted element those do not
reproduce a constant strain, and the membrane patch test failed by 6 %). This removes shear locking of thin
plates and membrane locking of curved shells and leaves no zero-energy mode but the six rigid motions
(tests/flex/test_quadratic_shells.py). Bending and drilling use the 3 x 3 Gauss rule. A, D, S, B are those of
the flat shells (:func:`dynamics.flex.shells.shell_materials`: MAT1, MAT2, MAT8, PCOMP; material axes by THETA or
MCID from the element x axis of the corner grids, as for CQUAD4). Mass: consistent (rho t + NSM) int N_i N_j
dA on the translations of the serendipity field and the Mindlin rotary inertia rho t^3 / 12 on the two
bending rotations (the bubble carries no inertia, as the MITC3+ bubble of CTRIA3); lumped: the translational
mass by HRZ diagonal scaling (Hinton, Rock & Zienkiewicz 1976), which keeps the corner masses positive.

CTRIA6 (corners G1-G3, then G4-G6 on the edges 1-2, 2-3, 3-1; QRG CTRIA6): four CTRIA3 (MITC3+,
:mod:`dynamics.flex.shells`) on the triangles its mid-side grids cut it into, (G1, G4, G6), (G4, G2, G5),
(G6, G5, G3), (G4, G5, G6); material axes fixed by the parent's element x axis (G1 -> G2) and THETA, passed to
each part as a direction. A quadratic triangle with a locking-free shear interpolation (the MITC6 elements of
Lee and Bathe) was not built: the split keeps MITC3+'s verified behaviour (no shear locking, no spurious
modes) at the cost of its linear convergence, and a curved CTRIA6 is faceted.

ZOFFS is not supported on either (refused by the assembly).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from dynamics.flex.shells import drilling_modulus, element_frame, shell_materials

_Q8_NODES = np.array([[-1.0, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, 1.0],
                      [0.0, -1.0], [1.0, 0.0], [0.0, 1.0], [-1.0, 0.0]])
_X, _W = np.polynomial.legendre.leggauss(3)
Q8_RULE = np.array([[a, b, wa * wb] for a, wa in zip(_X, _W) for b, wb in zip(_X, _W)])
TIE_A, TIE_B = 1.0 / np.sqrt(3.0), np.sqrt(0.6)
# CTRIA6 -> four CTRIA3: rows into (G1, G2, G3, G4, G5, G6)
TRIA6_PARTS = np.array([[0, 3, 5], [3, 1, 4], [5, 4, 2], [3, 4, 5]], dtype=np.int64)


@njit(cache=True)
def shape8(r, s):
    """N (8,) and dN/d(r, s) (2, 8) of the serendipity quadrilateral."""
    N = np.zeros(8)
    dN = np.zeros((2, 8))
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
def _lagrange(x, nodes, k):
    """Value at x of the Lagrange polynomial through ``nodes`` that is 1 at nodes[k]."""
    v = 1.0
    for m in range(nodes.shape[0]):
        if m != k:
            v *= (x - nodes[m]) / (nodes[k] - nodes[m])
    return v


@njit(cache=True)
def _point9(xyz, x_axis, r, s):
    """As :func:`_point` for the CQUAD8 with its bubble: N and dN/d(x1, x2) of the eight serendipity functions
    and of (1 - r^2)(1 - s^2) (the Lagrange biquadratic field), the frame, dA / d(r, s) and J = [g_a . e_b]."""
    N8, dN8 = shape8(r, s)
    g1 = dN8[0] @ xyz
    g2 = dN8[1] @ xyz
    nrm = np.cross(g1, g2)
    jac = np.linalg.norm(nrm)
    if jac <= 0.0:
        raise ValueError("CQUAD8: degenerate element (zero area element at an integration point)")
    e3 = nrm / jac
    e1 = x_axis - (x_axis @ e3) * e3
    e1 = e1 / np.linalg.norm(e1)
    e2 = np.cross(e3, e1)
    E = np.empty((3, 3))
    E[0], E[1], E[2] = e1, e2, e3
    J = np.array([[g1 @ e1, g1 @ e2], [g2 @ e1, g2 @ e2]])
    N = np.empty(9)
    dN = np.empty((2, 9))
    N[:8] = N8
    dN[:, :8] = dN8
    N[8] = (1.0 - r * r) * (1.0 - s * s)
    dN[0, 8] = -2.0 * r * (1.0 - s * s)
    dN[1, 8] = -2.0 * s * (1.0 - r * r)
    return N, np.linalg.solve(J, dN), E, jac, J


@njit(cache=True)
def _shear_covariant(J, Bs):
    """Covariant transverse shears (e_rt, e_st) = J gamma from the local Cartesian rows."""
    return J @ Bs


@njit(cache=True)
def cquad8(xyz, p, coupled):
    """Basic-frame K, M and lumped M (48 x 48) of one CQUAD8: the MITC9 shell of Bucalem and Bathe (module
    docstring) on the eight grids plus a bubble condensed statically."""
    nd = 54
    Lam, _, _ = element_frame(np.ascontiguousarray(xyz[:4]))
    A, D, S, gt, Bc = shell_materials(p, Lam)
    x_axis = np.ascontiguousarray(Lam[0])
    a, b = TIE_A, TIE_B
    lin = np.array([-a, a])
    quad = np.array([-b, 0.0, b])
    # at the tying points: e_11 and the covariant e_rt at (lin, quad), e_22 and e_st at (quad, lin), g_12 at
    # (lin, lin); the in-plane strains by their local Cartesian components (a constant strain is then
    # reproduced on any element: the membrane patch test)
    t_r = np.zeros((2, 3, 2, nd))
    t_s = np.zeros((2, 3, 2, nd))
    t_rs = np.zeros((2, 2, nd))
    for i in range(2):
        for j in range(3):
            N, dNx, E, _, J = _point9(xyz, x_axis, lin[i], quad[j])
            Bm, _, Bs, _ = _rows(N, dNx, E)
            t_r[i, j, 0], t_r[i, j, 1] = Bm[0], _shear_covariant(J, Bs)[0]
            N, dNx, E, _, J = _point9(xyz, x_axis, quad[j], lin[i])
            Bm, _, Bs, _ = _rows(N, dNx, E)
            t_s[i, j, 0], t_s[i, j, 1] = Bm[1], _shear_covariant(J, Bs)[1]
        for j in range(2):
            N, dNx, E, _, J = _point9(xyz, x_axis, lin[i], lin[j])
            Bm, _, _, _ = _rows(N, dNx, E)
            t_rs[i, j] = Bm[2]
    K = np.zeros((nd, nd))
    area = 0.0
    for q in range(Q8_RULE.shape[0]):
        r, s, wq = Q8_RULE[q, 0], Q8_RULE[q, 1], Q8_RULE[q, 2]
        N, dNx, E, jac, J = _point9(xyz, x_axis, r, s)
        _, Bb, _, _ = _rows(N, dNx, E)
        Bm = np.zeros((3, nd))
        cov = np.zeros((2, nd))
        for i in range(2):
            for j in range(3):
                f_r = _lagrange(r, lin, i) * _lagrange(s, quad, j)
                f_s = _lagrange(s, lin, i) * _lagrange(r, quad, j)
                Bm[0] += f_r * t_r[i, j, 0]
                cov[0] += f_r * t_r[i, j, 1]
                Bm[1] += f_s * t_s[i, j, 0]
                cov[1] += f_s * t_s[i, j, 1]
            for j in range(2):
                Bm[2] += _lagrange(r, lin, i) * _lagrange(s, lin, j) * t_rs[i, j]
        Bs = np.linalg.solve(J, cov)
        w = wq * jac
        area += w
        K += (Bm.T @ A @ Bm + Bb.T @ D @ Bb + Bm.T @ Bc @ Bb + Bb.T @ Bc @ Bm + Bs.T @ S @ Bs) * w
    gamma_d = drilling_modulus(gt, A, D, Bc, area)
    for q in range(Q8_RULE.shape[0]):
        N, dNx, E, jac, _ = _point9(xyz, x_axis, Q8_RULE[q, 0], Q8_RULE[q, 1])
        _, _, _, Bd = _rows(N, dNx, E)
        K += gamma_d * (Bd.T @ Bd) * (Q8_RULE[q, 2] * jac)
    K = 0.5 * (K + K.T)
    Kab = np.ascontiguousarray(K[:48, 48:])
    Kc = K[:48, :48] - Kab @ np.linalg.pinv(np.ascontiguousarray(K[48:, 48:])) @ Kab.T
    M, ML = _cquad8_mass(xyz, x_axis, p, coupled)
    return 0.5 * (Kc + Kc.T), M, ML


@njit(cache=True)
def _cquad8_mass(xyz, x_axis, p, coupled):
    """Consistent and lumped (HRZ) mass of the CQUAD8's serendipity field (module docstring)."""
    rho, t, nsm = p[22], p[23], p[24]
    mu = rho * t + nsm
    rotary = rho * t ** 3 / 12.0
    M = np.zeros((48, 48))
    diag = np.zeros(8)
    area = 0.0
    for q in range(Q8_RULE.shape[0]):
        N9, _, E, jac, _ = _point9(xyz, x_axis, Q8_RULE[q, 0], Q8_RULE[q, 1])
        N = N9[:8]
        w = Q8_RULE[q, 2] * jac
        area += w
        bend = np.outer(E[0], E[0]) + np.outer(E[1], E[1])
        for i in range(8):
            diag[i] += mu * N[i] * N[i] * w
            if coupled:
                for j in range(8):
                    m = N[i] * N[j] * w
                    for d in range(3):
                        M[6 * i + d, 6 * j + d] += mu * m
                    M[6 * i + 3:6 * i + 6, 6 * j + 3:6 * j + 6] += rotary * m * bend
    ML = np.zeros((48, 48))
    share = diag * (mu * area / diag.sum())
    for i in range(8):
        for d in range(3):
            ML[6 * i + d, 6 * i + d] = share[i]
    if not coupled:
        M[:, :] = ML
    return M, ML


@njit(cache=True)
def cquad8_batch(xyz, props, coupled):
    """K, M, lumped M (ne, 48, 48) of many CQUAD8 (:func:`cquad8`)."""
    ne = xyz.shape[0]
    Kg = np.empty((ne, 48, 48))
    Mg = np.empty((ne, 48, 48))
    MLg = np.empty((ne, 48, 48))
    for e in range(ne):
        Kg[e], Mg[e], MLg[e] = cquad8(np.ascontiguousarray(xyz[e]), props[e], coupled)
    return Kg, Mg, MLg


def tria6_parts(xyz: np.ndarray, props: np.ndarray):
    """(grid positions (4 ne, 3, 3), property rows (4 ne, 42), parent-row index (4 ne, 3)) of the CTRIA3 that the
    CTRIA6 (xyz (ne, 6, 3), props (ne, 42)) are split into; the material axes of each part follow the parent's
    element x axis (G1 -> G2) turned by THETA, unless an MCID already gives them."""
    ne = xyz.shape[0]
    parts = xyz[:, TRIA6_PARTS].reshape(4 * ne, 3, 3)
    rows = np.repeat(props, 4, axis=0).copy()
    for e in range(ne):
        p = props[e]
        if p[29:32] @ p[29:32] > 0.0:
            continue
        Lam, _, _ = element_frame(np.ascontiguousarray(xyz[e, :3]))
        c, s = np.cos(p[28]), np.sin(p[28])
        rows[4 * e:4 * e + 4, 29:32] = c * Lam[0] + s * Lam[1]
        rows[4 * e:4 * e + 4, 28] = 0.0
    return parts, rows, np.tile(TRIA6_PARTS, (ne, 1))



