"""Flat shell elements for CQUAD4 / CTRIA3 with PSHELL: membrane + Mindlin plate + drilling.

Each element lies in its mean plane (CTRIA3: its plane, local x along G1 -> G2; CQUAD4: through
the centre of its grids, z normal to both diagonals); a warped CQUAD4 (grids off that plane) is
the flat element on the mean plane joined to its grids by rigid links (item "Warping" below).
Local DOFs per grid ``[u, v, w, theta_x, theta_y, theta_z]``; the rotation vector theta moves a
point at height z by ``theta x (0, 0, z)``, i.e. ``u = z theta_y``, ``v = -z theta_x``.

* Materials: MAT1 (``Q = E / (1 - nu^2) [[1, nu, 0], [nu, 1, 0], [0, 0, (1-nu)/2]]``) or MAT2
  (Q = [[G11, G12, G13], [G12, G22, G23], [G13, G23, G33]], transverse shear from the MID3
  MAT2's [[G11, G12], [G12, G22]]), in material axes at THETA from the element x axis or along
  the projection of the MCID x axis, rotated to the element axes (Jones, Mechanics of
  Composite Materials, 1999, eq. 2.84). Element x: G1 -> G2 for CTRIA3, the bisector of the
  diagonals G1 -> G3 and G4 -> G2 for CQUAD4 (NASTRAN's element systems).
* Membrane: plane stress, ``A = t Q``;
  CQUAD4 bilinear with Wilson-Taylor incompatible modes (QM6, Taylor, Beresford & Wilson,
  IJNME 10, 1976; Jacobian at the centre so it passes the patch test) condensed statically;
  CTRIA3 constant strain.
* Bending: curvatures ``k_xx = theta_y,x``, ``k_yy = -theta_x,y``, ``k_xy = theta_y,y -
  theta_x,x``; ``D = (12 I / T^3) t^3 / 12 Q`` (Q of MID2).
* Membrane-bending coupling (PSHELL MID4, unsymmetric PCOMP): ``N = A e + B k``,
  ``M = B e + D k`` with ``B = C t^2`` (C the coupling modulus of the property row, -G4 of
  NASTRAN's MID4: :mod:`dynamics.flex.laminates`), the strain energy
  ``int e' B k dA`` added to both elements with their own membrane and bending strains (for
  CQUAD4 also on the incompatible modes before their condensation, so the patch test still
  holds: the modes' strains integrate to zero over the element).
* Transverse shear ``gamma_xz = w,x + theta_y``, ``gamma_yz = w,y - theta_x`` with
  ``S = (TS/T) t G_s``, by mixed interpolation of tensorial components, which removes shear
  locking: CQUAD4 is MITC4 (Dvorkin & Bathe, Eng. Comput. 1, 1984; Bathe, Finite Element
  Procedures, 2014, sec. 5.4.2: covariant gamma_r tied at (0, +-1), gamma_s at (+-1, 0));
  CTRIA3 is MITC3+ (next item). PSHELL without MID3 (no
  transverse shear flexibility in NASTRAN) gets ``1e3`` times the shear stiffness of MID2:
  the Kirchhoff limit, which the mixed interpolation reaches without locking.
* CTRIA3 bending and shear: MITC3+ (Lee, Lee & Bathe, Comput. Struct. 138, 2014, 12-23). In the
  area coordinates (r, s), w is linear (h = [1 - r - s, r, s]) and the rotations are
  ``theta = sum_i f_i theta_i + f_4 theta_4`` with the cubic bubble ``f_4 = 27 r s (1 - r - s)``
  and ``f_i = h_i - f_4 / 3``; the bubble's two rotations theta_4 are condensed statically, so
  the element keeps 6 DOFs per grid. The curvatures of the enriched rotations are quadratic;
  their energy is integrated exactly by Radon's 7-point rule (degree 5). The covariant
  transverse shear e_rt = w,r + x,r theta_y - y,r theta_x (and e_st) is assumed as
  ``e_rt = 2/3 (e_rt^B - e_st^B / 2) + 1/3 (e_rt^C + e_st^C) + c (3 s - 1) / 3``,
  ``e_st = 2/3 (e_st^A - e_rt^A / 2) + 1/3 (e_rt^C + e_st^C) + c (1 - 3 r) / 3``,
  ``c = e_rt^F - e_rt^D - e_st^F + e_st^E``, tied at A (1/6, 2/3), B (2/3, 1/6), C (1/6, 1/6),
  D (1/3 + d, 1/3 - 2d), E (1/3 - 2d, 1/3 + d), F (1/3 + d, 1/3 + d), d = 1e-4; the bubble
  enters the shear through these interior points. Its mass is that of MITC3 (linear
  interpolation; the bubble carries no inertia).
  Why MITC3+: the previous CTRIA3, MITC3 (Lee & Bathe, Comput. Struct. 82, 2004), locks in the
  thin cantilever plate (16 x 16 mesh against Leissa: modes 2, 4, 5 up to +74 % at t/a = 1e-3,
  up to +130 % at 1e-4). DKT (Batoz 1980) is Kirchhoff and would drop the MID3 shear
  flexibility; DKMT (Katili 1993) and DSG3 (Bletzinger 2000, whose stiffness depends on the node
  numbering) build the shear from edge constraints or shear gaps. MITC3+ keeps Mindlin shear,
  does not depend on the node numbering, passes the patch tests and is the MITC4's triangle.
* Drilling: Hughes-Brezzi penalty ``gamma_d int (theta_z - omega)^2 dA``, ``omega = (v,x - u,y)/2``
  (Hughes & Brezzi, CMAME 72, 1989: stable and convergent for any gamma_d > 0), at the 2 x 2
  (quadrilateral) or 3 edge-midpoint (triangle) points, so no theta_z pattern is free. Where the
  surface twists (its normal turns by k per unit length from one element to the next), theta_z of a
  grid is part of the neighbouring element's bending rotation, so gamma_d is the stiffness of a hinge
  between elements, with a compliance of about ``beta = D k^2 / gamma_d`` relative to the bending.
  ``gamma_d = DRILL D_m / A`` with ``D_m = (D_11 + D_22 + 2 D_33) / 4`` (invariant under a rotation of
  the axes) and A the element's area: the rotation about the normal is as stiff as the element's
  bending rotations, so ``beta ~ k^2 A`` falls with refinement at any thickness, and the penalty never
  exceeds the bending scale of thin shells, which it would lock. DRILL = 1, kept between
  ``DRILL_MIN = 1e-4`` and ``DRILL_MAX = 0.1`` times ``Q_33 t``: the floor is the value the element had,
  MSC Nastran's PARAM K6ROT = 100 (``1e-6 K6ROT G t``), so thin and flat shells keep it; the cap keeps
  the penalty a small part of the in-plane rotation stiffness of very thick or very fine elements
  (Hughes & Brezzi recommend gamma ~ G; 0.1 G t suffices for the thick twisted beam at 48 x 8).
  Chosen by measurement (tests/flex/test_drilling.py, docs/fem2modal.md "Drilling penalty"): a
  penalty ``DRILL G t`` fails either way, DRILL = 1e-4 leaving MacNeal & Harder's thick twisted beam
  3.9 x too flexible at every mesh and DRILL = 1e-2 locking the thin one with CTRIA3 (0.46 x at
  12 x 2) and the pinched hemisphere at 4 x 4 (0.92 x). A membrane (PSHELL without
  MID2, PCOMP LAM = MEM) has no bending, transverse shear or drilling stiffness, as in NASTRAN,
  whose membrane shells leave the grid rotations unconnected.
* ZOFFS: the element's reference plane lies ZOFFS along its normal from the plane of its grids
  (for a warped CQUAD4 their mean plane, next item), joined to them by rigid links
  (``u = u_grid + theta x (0, 0, ZOFFS)``, as NASTRAN's shell offset).
* Warping: the grids of a warped CQUAD4 lie at heights ``h_i = (h, -h, h, -h)`` above its mean
  plane. Its stiffness is the flat element's on the mean plane (on the reference plane ZOFFS above
  it) with every grid joined to its projection by a rigid link along the normal,
  ``u_i = u_grid,i + theta_i x (0, 0, ZOFFS - h_i)`` (MacNeal, Finite Elements: Their Design and
  Performance, 1994, on warped elements; the transformation ZOFFS uses, with one length per grid).
  A rigid motion of the grids, ``u = a + omega x x``, moves every projected point p_i by
  ``a + omega x p_i``: a rigid motion of the flat element, which its strains ignore exactly; without
  the links the in-plane components ``omega x (0, 0, h_i)`` of an out-of-plane rotation strain the
  membrane (energy ~ (h / a)^2 of the element's stiffness). The links also couple the membrane
  forces to the grid rotations by the lever h_i, the membrane-bending coupling of a twisted facet
  (MacNeal & Harder's twisted beam, FEAD 1, 1985, tests it). The mass stays with the grids (only
  ZOFFS moves it): it is the mass of the bilinear surface through them, whose velocity under a
  rigid motion is the rigid velocity field, so the kinetic energy needs no link; the projection
  would move rotary inertia by O(m h^2) and make lumped masses non-diagonal.
* Mass: consistent ``int (rho t + nsm) N' N dA`` on the translations and the Mindlin rotary
  inertia ``rho t^3 / 12`` on theta_x, theta_y (none on theta_z, as NASTRAN); lumped: the
  element's translational mass shared equally by its grids (NASTRAN COUPMASS <= 0).
"""

from __future__ import annotations

import numpy as np
from numba import njit

DRILL = 1.0
DRILL_MIN = 1e-4
DRILL_MAX = 0.1
NO_SHEAR_FLEXIBILITY = 1e3
GAUSS2_POINT = 1.0 / np.sqrt(3.0)
_QUAD_NODES = np.array([[-1.0, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, 1.0]])
_TRI_DN = np.array([[-1.0, 1.0, 0.0], [-1.0, 0.0, 1.0]])     # d/dr, d/ds of [1 - r - s, r, s]
# MITC3+ tying points (r, s): A, B, C on the lines from the centroid to the corners 3, 2, 1; D, E, F at
# distance ~d from the centroid towards the edge midpoints (Lee, Lee & Bathe 2014; d = 1e-4)
_MITC3P_D = 1e-4
_MITC3P_TIE = np.array([[1.0 / 6.0, 2.0 / 3.0], [2.0 / 3.0, 1.0 / 6.0], [1.0 / 6.0, 1.0 / 6.0],
                        [1.0 / 3.0 + _MITC3P_D, 1.0 / 3.0 - 2.0 * _MITC3P_D],
                        [1.0 / 3.0 - 2.0 * _MITC3P_D, 1.0 / 3.0 + _MITC3P_D],
                        [1.0 / 3.0 + _MITC3P_D, 1.0 / 3.0 + _MITC3P_D]])


def _radon_rule():
    """Radon's 7-point rule on the unit triangle, exact to degree 5 (Dunavant, IJNME 21, 1985, degree-5 rule):
    rows (r, s, weight as a fraction of the area)."""
    a, b = (6.0 - np.sqrt(15.0)) / 21.0, (6.0 + np.sqrt(15.0)) / 21.0
    wa, wb = (155.0 - np.sqrt(15.0)) / 1200.0, (155.0 + np.sqrt(15.0)) / 1200.0
    return np.array([[1.0 / 3.0, 1.0 / 3.0, 9.0 / 40.0],
                     [a, a, wa], [1.0 - 2.0 * a, a, wa], [a, 1.0 - 2.0 * a, wa],
                     [b, b, wb], [1.0 - 2.0 * b, b, wb], [b, 1.0 - 2.0 * b, wb]])


_TRI7 = _radon_rule()


@njit(cache=True)
def element_frame(xyz: np.ndarray):
    """(Lambda rows = local x, y, z in basic; local 2-D coordinates of the grids' projections on the mean
    plane (n, 2); heights h (n,) of the grids above that plane).

    The mean plane passes through the centre of the grids with the normal z. For a CQUAD4, z is normal to
    both diagonals, so the heights alternate, h = (h, -h, h, -h) (all zero for a flat quadrilateral); a
    CTRIA3 lies in its plane (h = 0).
    """
    n = xyz.shape[0]
    c = np.zeros(3)
    for i in range(n):
        c += xyz[i] / n
    if n == 4:
        d13 = xyz[2] - xyz[0]
        d24 = xyz[3] - xyz[1]
        z = np.cross(d13, d24)
        # NASTRAN's QUAD4 x axis: bisector of the diagonals G1->G3 and G4->G2
        x = d13 / np.linalg.norm(d13) - d24 / np.linalg.norm(d24)
    else:
        z = np.cross(xyz[1] - xyz[0], xyz[2] - xyz[0])
        x = xyz[1] - xyz[0]
    z = z / np.linalg.norm(z)
    x = x - (x @ z) * z
    x = x / np.linalg.norm(x)
    y = np.cross(z, x)
    Lam = np.empty((3, 3))
    Lam[0], Lam[1], Lam[2] = x, y, z
    loc = np.empty((n, 2))
    h = np.zeros(n)
    for i in range(n):
        d = xyz[i] - c
        loc[i, 0] = d @ x
        loc[i, 1] = d @ y
        if n == 4:
            h[i] = d @ z
    return Lam, loc, h


@njit(cache=True)
def rigid_links(Lam, offsets):
    """(6 nn x 6 nn) T from the grid DOFs (basic, [T; R] per grid) to the local DOFs ``[u, v, w, theta_x,
    theta_y, theta_z]`` of the points at ``offsets`` (nn,) along the element normal from the grids, joined
    to them by rigid links: ``u_point = u_grid + theta x (0, 0, offset)`` in the element axes."""
    nn = offsets.shape[0]
    T = np.zeros((6 * nn, 6 * nn))
    for i in range(2 * nn):
        T[3 * i:3 * i + 3, 3 * i:3 * i + 3] = Lam
    for i in range(nn):
        if offsets[i] != 0.0:
            T[6 * i, :] += offsets[i] * T[6 * i + 4, :]
            T[6 * i + 1, :] -= offsets[i] * T[6 * i + 3, :]
    return T


@njit(cache=True)
def shell_frame_transform(xyz, zoff):
    """(T, local 2-D coordinates (nn, 2), Lambda) of the element's stiffness: T (6 nn x 6 nn) takes the grid
    DOFs (basic, [T; R]) to the local DOFs of the flat element on the reference plane, which lies ZOFFS
    above the mean plane; grid i is joined to its point of that plane by a rigid link of length
    ``ZOFFS - h_i`` along the normal (h_i its height above the mean plane, :func:`element_frame`), so a
    rigid motion of the grids is a rigid motion of the flat element (module docstring, "Warping")."""
    Lam, loc, h = element_frame(xyz)
    return rigid_links(Lam, zoff - h), loc, Lam


@njit(cache=True)
def quad_shape(r, s):
    N = np.empty(4)
    dN = np.empty((2, 4))
    for i in range(4):
        ri, si = _QUAD_NODES[i, 0], _QUAD_NODES[i, 1]
        N[i] = 0.25 * (1 + ri * r) * (1 + si * s)
        dN[0, i] = 0.25 * ri * (1 + si * s)
        dN[1, i] = 0.25 * si * (1 + ri * r)
    return N, dN


@njit(cache=True)
def rotate_plane(C, c, s):
    """C (3x3, Voigt with engineering shear) of axes at angle theta (c, s) in the element axes."""
    T = np.array([[c * c, s * s, c * s], [s * s, c * c, -c * s],
                  [-2 * c * s, 2 * c * s, c * c - s * s]])
    return T.T @ C @ T


@njit(cache=True)
def shell_materials(p, Lam):
    """A (membrane), D (bending), S (2x2 transverse shear), drilling modulus, B (membrane-bending
    coupling), in element axes.

    p: the property row of :func:`shell_batch`. The material axes are at angle THETA from the
    element x axis, or along the projection of the MCID x axis when one is given.
    """
    Gm = p[0:9].copy().reshape(3, 3)
    Gb = p[9:18].copy().reshape(3, 3)
    Gs = p[18:22].copy().reshape(2, 2)
    t, bend_ratio, ts_t, shear_rigid, theta = p[23], p[25], p[26], p[27], p[28]
    direction = p[29:32]
    if direction @ direction > 0.0:
        theta = np.arctan2(direction @ Lam[1], direction @ Lam[0])
    c, s = np.cos(theta), np.sin(theta)
    A = rotate_plane(Gm, c, s) * t
    D = rotate_plane(Gb, c, s) * (bend_ratio * t ** 3 / 12.0)
    R = np.array([[c, s], [-s, c]])
    S = R.T @ Gs @ R * (ts_t * t)
    if shear_rigid > 0.5:
        S = R.T @ Gs @ R * (NO_SHEAR_FLEXIBILITY * (5.0 / 6.0) * t)
    Bc = rotate_plane(p[33:42].copy().reshape(3, 3), c, s) * t ** 2
    # a membrane (no MID2) has no rotational stiffness in NASTRAN: no drilling penalty either
    gt = Gm[2, 2] * t if bend_ratio > 0.0 else 0.0
    return A, D, S, gt, Bc


@njit(cache=True)
def drilling_modulus(gt, A, D, B, area):
    """gamma_d of the drilling penalty (module docstring, "Drilling"): DRILL times the element's mean bending
    modulus ``(D_11 + D_22 + 2 D_33) / 4`` (invariant under a rotation of the axes) over its area, kept between
    DRILL_MIN and DRILL_MAX times ``gt = Q_33 t``; zero for a membrane (gt = 0). With membrane-bending coupling
    B the bending modulus is ``D - B A^-1 B``, the bending stiffness about the section's neutral surface, which
    does not depend on the reference plane (moved by e: B - e A, D - 2 e B + e^2 A), so neither does gamma_d."""
    if np.any(B != 0.0):
        D = D - B @ np.linalg.solve(A, B)
    bending = DRILL * 0.25 * (D[0, 0] + D[1, 1] + 2.0 * D[2, 2]) / area
    return min(DRILL_MAX * gt, max(DRILL_MIN * gt, bending))


@njit(cache=True)
def _covariant_shear_row(dN_r, N, xr, yr, nn):
    """Row (6 nn) of gamma_r = w,r + x,r theta_y - y,r theta_x at a point."""
    row = np.zeros(6 * nn)
    for i in range(nn):
        row[6 * i + 2] = dN_r[i]
        row[6 * i + 3] = -yr * N[i]
        row[6 * i + 4] = xr * N[i]
    return row


@njit(cache=True)
def membrane_bending_B(dNx, n):
    """Membrane and bending strain-displacement rows (3 x 6n each) of an n-node plate element from the shape
    function derivatives ``dNx`` (rows d/dx, d/dy): e = [u_x, v_y, u_y + v_x], kappa = [theta_y,x, -theta_x,y,
    theta_y,y - theta_x,x] with the DOFs (u, v, w, theta_x, theta_y, theta_z) per node."""
    Bm = np.zeros((3, 6 * n))
    Bb = np.zeros((3, 6 * n))
    for i in range(n):
        Bm[0, 6 * i] = dNx[0, i]
        Bm[1, 6 * i + 1] = dNx[1, i]
        Bm[2, 6 * i] = dNx[1, i]
        Bm[2, 6 * i + 1] = dNx[0, i]
        Bb[0, 6 * i + 4] = dNx[0, i]
        Bb[1, 6 * i + 3] = -dNx[1, i]
        Bb[2, 6 * i + 4] = dNx[1, i]
        Bb[2, 6 * i + 3] = -dNx[0, i]
    return Bm, Bb


@njit(cache=True)
def quad4_local(loc, A, D, S, gt, rho, t, nsm, coupled, Bc):
    """Local 24 x 24 K and M of a MITC4 / QM6 shell quadrilateral (module docstring); Bc the
    membrane-bending coupling (3 x 3, element axes, zero for a homogeneous section)."""
    M = np.zeros((24, 24))
    x, y = np.ascontiguousarray(loc[:, 0]), np.ascontiguousarray(loc[:, 1])  # contiguous for '@'
    # tying points: gamma_r at (0, -1) [B] and (0, 1) [D]; gamma_s at (-1, 0) [A] and (1, 0) [C]
    tie_r = np.zeros((2, 24))
    tie_s = np.zeros((2, 24))
    for k in range(2):
        N, dN = quad_shape(0.0, 2.0 * k - 1.0)
        tie_r[k] = _covariant_shear_row(dN[0], N, dN[0] @ x, dN[0] @ y, 4)
        N, dN = quad_shape(2.0 * k - 1.0, 0.0)
        tie_s[k] = _covariant_shear_row(dN[1], N, dN[1] @ x, dN[1] @ y, 4)
    # incompatible membrane modes (1 - r^2), (1 - s^2) in u and v, with J at the centre
    N0, dN0 = quad_shape(0.0, 0.0)
    J0 = np.array([[dN0[0] @ x, dN0[0] @ y], [dN0[1] @ x, dN0[1] @ y]])
    J0i = np.linalg.inv(J0)
    det0 = np.linalg.det(J0)
    gd = drilling_modulus(gt, A, D, Bc, 0.5 * np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y))
    Kuu = np.zeros((24, 24))
    Kua = np.zeros((24, 4))
    Kaa = np.zeros((4, 4))
    area = 0.0
    mu = rho * t + nsm
    I_rot = rho * t ** 3 / 12.0
    for r in (-GAUSS2_POINT, GAUSS2_POINT):
        for s_ in (-GAUSS2_POINT, GAUSS2_POINT):
            N, dN = quad_shape(r, s_)
            J = np.array([[dN[0] @ x, dN[0] @ y], [dN[1] @ x, dN[1] @ y]])
            det = np.linalg.det(J)
            if det <= 0.0:
                raise ValueError("CQUAD4: non-convex or badly ordered corners (Jacobian <= 0)")
            Ji = np.linalg.inv(J)
            dNx = Ji @ dN                      # rows: d/dx, d/dy
            area += det
            Bm, Bb = membrane_bending_B(dNx, 4)
            # incompatible modes: d(1-r^2)/d(x,y) = J0^-1 (-2r, 0) * det0/det (Taylor's correction)
            g1 = J0i @ np.array([-2.0 * r, 0.0]) * (det0 / det)
            g2 = J0i @ np.array([0.0, -2.0 * s_]) * (det0 / det)
            Ba = np.zeros((3, 4))
            Ba[0, 0], Ba[2, 0], Ba[1, 1], Ba[2, 1] = g1[0], g1[1], g1[1], g1[0]
            Ba[0, 2], Ba[2, 2], Ba[1, 3], Ba[2, 3] = g2[0], g2[1], g2[1], g2[0]
            # MITC4 covariant shear, then Cartesian: [g_xz, g_yz] = J^-1 [g_r, g_s]
            gr = 0.5 * (1 - s_) * tie_r[0] + 0.5 * (1 + s_) * tie_r[1]
            gs = 0.5 * (1 - r) * tie_s[0] + 0.5 * (1 + r) * tie_s[1]
            Bs = np.zeros((2, 24))
            Bs[0] = Ji[0, 0] * gr + Ji[0, 1] * gs
            Bs[1] = Ji[1, 0] * gr + Ji[1, 1] * gs
            Kuu += (Bm.T @ A @ Bm + Bb.T @ D @ Bb + Bs.T @ S @ Bs
                    + Bm.T @ Bc @ Bb + Bb.T @ Bc @ Bm) * det
            Kua += (Bm.T @ A @ Ba + Bb.T @ Bc @ Ba) * det
            Kaa += Ba.T @ A @ Ba * det
            # drilling: the grids' theta_z against the in-plane rotation, at every point
            bd = np.zeros(24)
            for i in range(4):
                bd[6 * i + 5] = N[i]
                bd[6 * i] += 0.5 * dNx[1, i]
                bd[6 * i + 1] -= 0.5 * dNx[0, i]
            Kuu += gd * np.outer(bd, bd) * det
            if coupled:
                for i in range(4):
                    for j in range(4):
                        m = N[i] * N[j] * det
                        for d in range(3):
                            M[6 * i + d, 6 * j + d] += mu * m
                        M[6 * i + 3, 6 * j + 3] += I_rot * m
                        M[6 * i + 4, 6 * j + 4] += I_rot * m
    Kuu -= Kua @ np.linalg.solve(Kaa, Kua.T)
    if not coupled:
        for i in range(4):
            for d in range(3):
                M[6 * i + d, 6 * i + d] = mu * area / 4.0
    return 0.5 * (Kuu + Kuu.T), M


@njit(cache=True)
def _mitc3p_rotation_shapes(r, s):
    """MITC3+ rotation interpolation at (r, s): f (4,) = [h_1 - f_4/3, h_2 - f_4/3, h_3 - f_4/3, f_4] with
    h = [1 - r - s, r, s] and the cubic bubble f_4 = 27 r s (1 - r - s); df (2, 4) = d/dr, d/ds."""
    b = 27.0 * r * s * (1.0 - r - s)
    db_r = 27.0 * s * (1.0 - 2.0 * r - s)
    db_s = 27.0 * r * (1.0 - r - 2.0 * s)
    f = np.array([1.0 - r - s - b / 3.0, r - b / 3.0, s - b / 3.0, b])
    df = np.array([[-1.0 - db_r / 3.0, 1.0 - db_r / 3.0, -db_r / 3.0, db_r],
                   [-1.0 - db_s / 3.0, -db_s / 3.0, 1.0 - db_s / 3.0, db_s]])
    return f, df


@njit(cache=True)
def _mitc3p_covariant_shear(r, s, J):
    """Rows (2, 20) of the covariant transverse shear strains e_rt, e_st of MITC3+ at (r, s) on the
    18 grid DOFs and the bubble rotations (theta_x, theta_y at 18, 19): w linear, rotations by
    :func:`_mitc3p_rotation_shapes`."""
    f, _ = _mitc3p_rotation_shapes(r, s)
    rows = np.zeros((2, 20))
    for a in range(2):
        xa, ya = J[a, 0], J[a, 1]
        rows[a, :18] = _covariant_shear_row(_TRI_DN[a], f[:3], xa, ya, 3)
        rows[a, 18] = -ya * f[3]
        rows[a, 19] = xa * f[3]
    return rows


@njit(cache=True)
def tria3_local(loc, A, D, S, gt, rho, t, nsm, coupled, Bc):
    """Local 18 x 18 K and M of a MITC3+ / CST shell triangle (module docstring); Bc the membrane-bending
    coupling. Its stiffness ``area (Bm' Bc Bb + Bb' Bc Bm)`` uses the constant membrane strain and the mean
    curvature of the linear rotations, which is exact for MITC3+ too: against a constant membrane strain only
    the mean curvature counts, and the cubic rotation bubble, zero on the edges, adds nothing to it
    (divergence theorem), so the coupling neither involves the bubble nor changes its condensation."""
    x, y = np.ascontiguousarray(loc[:, 0]), np.ascontiguousarray(loc[:, 1])  # contiguous for '@'
    J = np.array([[_TRI_DN[0] @ x, _TRI_DN[0] @ y], [_TRI_DN[1] @ x, _TRI_DN[1] @ y]])
    det = np.linalg.det(J)
    if det <= 0.0:
        raise ValueError("CTRIA3: degenerate triangle (zero area)")
    Ji = np.linalg.inv(J)
    dNx = Ji @ _TRI_DN
    area = 0.5 * det
    gd = drilling_modulus(gt, A, D, Bc, area)
    # 18 grid DOFs, then the bubble's theta_x, theta_y (condensed statically below)
    Ke = np.zeros((20, 20))
    Bm = np.zeros((3, 20))
    Bm_grid, Bb_linear = membrane_bending_B(dNx, 3)
    Bm[:, :18] = Bm_grid
    Ke += Bm.T @ A @ Bm * area
    Ke[:18, :18] += (Bm_grid.T @ Bc @ Bb_linear + Bb_linear.T @ Bc @ Bm_grid) * area
    # bending of the enriched rotations: curvatures quadratic, energy quartic; the 7-point rule is exact
    for q in range(_TRI7.shape[0]):
        _, df = _mitc3p_rotation_shapes(_TRI7[q, 0], _TRI7[q, 1])
        dfx = Ji @ df
        Bb = np.zeros((3, 20))
        Bb[:, :18] = membrane_bending_B(dfx[:, :3].copy(), 3)[1]
        Bb[0, 19] = dfx[0, 3]
        Bb[1, 18] = -dfx[1, 3]
        Bb[2, 19] = dfx[1, 3]
        Bb[2, 18] = -dfx[0, 3]
        Ke += Bb.T @ D @ Bb * (area * _TRI7[q, 2])
    # MITC3+ assumed covariant shear (module docstring): a constant part from A, B, C and
    # a linear part c (3 s - 1) / 3, c (1 - 3 r) / 3 with c from D, E, F
    e = np.zeros((6, 2, 20))
    for k in range(6):
        e[k] = _mitc3p_covariant_shear(_MITC3P_TIE[k, 0], _MITC3P_TIE[k, 1], J)
    er_const = (2.0 / 3.0) * (e[1, 0] - 0.5 * e[1, 1]) + (1.0 / 3.0) * (e[2, 0] + e[2, 1])
    es_const = (2.0 / 3.0) * (e[0, 1] - 0.5 * e[0, 0]) + (1.0 / 3.0) * (e[2, 0] + e[2, 1])
    c = (e[5, 0] - e[3, 0]) - (e[5, 1] - e[4, 1])
    M = np.zeros((18, 18))
    mu = rho * t + nsm
    I_rot = rho * t ** 3 / 12.0
    # the assumed shear is linear: the 3 edge-midpoint rule integrates its energy (and the linear mass and
    # drilling products) exactly
    for r, s_ in ((0.5, 0.0), (0.5, 0.5), (0.0, 0.5)):
        gr = er_const + c * ((3.0 * s_ - 1.0) / 3.0)
        gs = es_const + c * ((1.0 - 3.0 * r) / 3.0)
        Bs = np.zeros((2, 20))
        Bs[0] = Ji[0, 0] * gr + Ji[0, 1] * gs
        Bs[1] = Ji[1, 0] * gr + Ji[1, 1] * gs
        Ke += (Bs.T @ S @ Bs) * (area / 3.0)
        N = np.array([1.0 - r - s_, r, s_])
        bd = np.zeros(20)
        for i in range(3):
            bd[6 * i + 5] = N[i]
            bd[6 * i] += 0.5 * dNx[1, i]
            bd[6 * i + 1] -= 0.5 * dNx[0, i]
        Ke += gd * np.outer(bd, bd) * (area / 3.0)
        if coupled:
            for i in range(3):
                for j in range(3):
                    m = N[i] * N[j] * area / 3.0
                    for d in range(3):
                        M[6 * i + d, 6 * j + d] += mu * m
                    M[6 * i + 3, 6 * j + 3] += I_rot * m
                    M[6 * i + 4, 6 * j + 4] += I_rot * m
    if not coupled:
        for i in range(3):
            for d in range(3):
                M[6 * i + d, 6 * i + d] = mu * area / 3.0
    # static condensation of the bubble; a property with neither bending nor shear stiffness leaves the
    # bubble without energy (K_bb = 0), which the pseudo-inverse drops
    Kcb = np.ascontiguousarray(Ke[:18, 18:])                 # contiguous for '@'
    K = Ke[:18, :18] - Kcb @ np.linalg.pinv(np.ascontiguousarray(Ke[18:, 18:])) @ Kcb.T
    return 0.5 * (K + K.T), M


def isotropic_props(E, nu, rho, t, nsm=0.0, bend_ratio=1.0, ts_t=5.0 / 6.0, shear_rigid=False,
                    theta=0.0, direction=(0.0, 0.0, 0.0), zoffset=0.0) -> np.ndarray:
    """A :func:`shell_batch` property row for one isotropic material (MAT1)."""
    G = E / (2.0 * (1.0 + nu))
    c = E / (1.0 - nu * nu)
    Q = np.array([[c, nu * c, 0.0], [nu * c, c, 0.0], [0.0, 0.0, G]])
    return property_row(Q, Q, G * np.eye(2), rho, t, nsm, bend_ratio, ts_t, shear_rigid,
                        theta, direction, zoffset)


def property_row(Gm, Gb, Gs, rho, t, nsm, bend_ratio, ts_t, shear_rigid, theta, direction,
                 zoffset=0.0, coupling=None):
    """A :func:`shell_batch` property row (its docstring lists the entries); ``coupling`` the
    3 x 3 membrane-bending coupling modulus C (B = C t^2; None: no coupling)."""
    C = np.zeros((3, 3)) if coupling is None else np.asarray(coupling, dtype=float)
    return np.concatenate([np.ravel(Gm), np.ravel(Gb), np.ravel(Gs),
                           [rho, t, nsm, bend_ratio, ts_t, 1.0 if shear_rigid else 0.0, theta],
                           np.asarray(direction, dtype=float), [zoffset], np.ravel(C)])


@njit(cache=True)
def shell_batch(xyz, props, coupled):
    """Basic-frame K, M, lumped M of many shells with the same grid count.

    xyz (ne, nn, 3) grid positions; props (ne, 42): [0:9] membrane modulus (3x3, plane
    stress, per unit thickness), [9:18] bending modulus (3x3), [18:22] transverse shear modulus
    (2x2), [22] rho, [23] t, [24] nsm, [25] 12I/T^3, [26] TS/T, [27] shear_rigid (0/1), [28]
    THETA [rad], [29:32] MCID x axis in basic (zero: use THETA), [32] ZOFFS (the reference
    plane's offset from the grids along the element normal), [33:42] membrane-bending
    coupling modulus C (3x3, material axes; B = C t^2 with B = int Q z dz, i.e. -G4 of a
    PSHELL MID4).
    Returns three (ne, 6 nn, 6 nn) arrays in [T; R] order per grid.
    """
    ne, nn = xyz.shape[0], xyz.shape[1]
    nd = 6 * nn
    Kg = np.empty((ne, nd, nd))
    Mg = np.empty((ne, nd, nd))
    MLg = np.empty((ne, nd, nd))
    for e in range(ne):
        p = props[e]
        rho, t, nsm = p[22], p[23], p[24]
        T, loc, Lam = shell_frame_transform(xyz[e], p[32])
        A, D, S, gt, Bc = shell_materials(p, Lam)
        if nn == 4:
            K, M = quad4_local(loc, A, D, S, gt, rho, t, nsm, coupled, Bc)
        else:
            K, M = tria3_local(loc, A, D, S, gt, rho, t, nsm, coupled, Bc)
        area = 0.0
        for i in range(nn):
            j = (i + 1) % nn
            area += 0.5 * (loc[i, 0] * loc[j, 1] - loc[j, 0] * loc[i, 1])
        ML = np.zeros((nd, nd))
        for i in range(nd):
            if i % 6 < 3:
                ML[i, i] = (rho * t + nsm) * area / nn
        # the mass stays with the grids (only ZOFFS moves it): the bilinear surface through the grids carries
        # it, whose kinetic energy is exact for rigid motion without links (module docstring, "Warping")
        Tm = rigid_links(Lam, np.full(nn, p[32]))
        Kg[e] = T.T @ K @ T
        Mg[e] = Tm.T @ M @ Tm
        MLg[e] = Tm.T @ ML @ Tm
    return Kg, Mg, MLg
