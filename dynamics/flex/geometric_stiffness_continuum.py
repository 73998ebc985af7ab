"""Initial-stress (geometric) stiffness of the shell and solid elements: stress recovery from a static
displacement and the stress-weighted gradient products that :mod:`dynamics.flex.geometric_stiffness`
projects on the modes (issue 15: geometric stiffening of shells and solids).

Equations. With a stress state sigma held fixed, the nonlinear (quadratic) part of the Green-Lagrange strain
``E_ij = 1/2 (u_i,j + u_j,i + u_k,i u_k,j)`` does the work ``W(v) = 1/2 int sigma_ij v_k,i v_k,j dV`` on an
added displacement v; its Hessian is the initial-stress matrix (Cook, Malkus, Plesha & Witt, Concepts and
Applications of Finite Element Analysis, 4th ed., 2002, sec. 18.2-18.4; Zienkiewicz & Taylor, The Finite
Element Method, vol. 2, 6th ed., 2005, sec. 6.2 and 10.6 for plates)::

    K_sigma = int G' S G dV = H (x) I_3,     H_ij = int dN_i/dx_a  sigma_ab  dN_j/dx_b  dV

(G the gradient of the shape functions, S the 3 x 3 stress, ``(x) I_3`` the same n x n block on each of the
three displacement components). These kernels return H per element and load case; the caller applies it to
the element's translations.

* Solids (CHEXA8/20, CTETRA4/10, CPENTA6/15, :mod:`dynamics.flex.solids`): sigma = C (B u + B_a alpha) at every
  Gauss point of the element's own rule; for CHEXA8 the nine incompatible-mode amplitudes are recovered from
  the static condensation, ``alpha = -K_aa^-1 K_ua' u`` (the same B_a as the element: centre Jacobian scaled
  by det J0 / det J), so the stress is the element's own (its nodal forces int B' sigma dV equal K u, tested).
* Shells (CQUAD4, CTRIA3, :mod:`dynamics.flex.shells`): the membrane stress resultants
  ``[N_x, N_y, N_xy] = A (B_m u + B_a alpha)`` (QM6 incompatible modes of CQUAD4 recovered as for CHEXA8;
  CTRIA3 constant strain) at the 2 x 2 Gauss points (one point for CTRIA3), in the element axes, and the plate
  initial-stress matrix ``int [N_x N_xy; N_xy N_y]`` contracted with the in-plane shape gradients (Cook et al.
  eq. 18.4-5), on w (bending under membrane stress: buckling, the flapwise stiffening of a spinning strip) and
  on u and v (the in-plane terms: the chordwise stiffening of a strip, "in-plane bending"). Left out: the
  rotation terms ``t^2 / 12 (N theta,x^2 ...)`` of the Mindlin plate (order (t / L)^2) and the bending moments'
  own geometric stiffness (order curvature x thickness), as in Cook et al.'s plate matrix. The strains, the
  stresses and the translations the matrix acts on are those of the flat element on the reference plane,
  joined to the grids by the stiffness's own rigid links (ZOFFS, and a warped CQUAD4's heights above its mean
  plane: :func:`dynamics.flex.shells.shell_frame_transform`), so a rigid motion carries no stress.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from dynamics.flex import solids
from dynamics.flex.shells import GAUSS2_POINT, membrane_bending_B, quad_shape, shell_frame_transform, shell_materials


@njit(cache=True)
def _shell_points(loc):
    """Gauss points of the membrane: (dNx (np, 2, nn), weights det (np,), Ba (np, 3, 4)) with the QM6
    incompatible-mode strain rows of a CQUAD4 (zero for CTRIA3)."""
    nn = loc.shape[0]
    x, y = loc[:, 0].copy(), loc[:, 1].copy()
    if nn == 3:
        dN = np.array([[-1.0, 1.0, 0.0], [-1.0, 0.0, 1.0]])
        J = np.array([[dN[0] @ x, dN[0] @ y], [dN[1] @ x, dN[1] @ y]])
        det = np.linalg.det(J)
        if det <= 0.0:
            raise ValueError("CTRIA3: degenerate triangle (zero area)")
        dNx = np.empty((1, 2, 3))
        dNx[0] = np.linalg.inv(J) @ dN
        return dNx, np.array([0.5 * det]), np.zeros((1, 3, 4))
    _, dN0 = quad_shape(0.0, 0.0)
    J0 = np.array([[dN0[0] @ x, dN0[0] @ y], [dN0[1] @ x, dN0[1] @ y]])
    J0i = np.linalg.inv(J0)
    det0 = np.linalg.det(J0)
    dNx = np.empty((4, 2, 4))
    wts = np.empty(4)
    Ba = np.zeros((4, 3, 4))
    q = 0
    for r in (-GAUSS2_POINT, GAUSS2_POINT):
        for s_ in (-GAUSS2_POINT, GAUSS2_POINT):
            _, dN = quad_shape(r, s_)
            J = np.array([[dN[0] @ x, dN[0] @ y], [dN[1] @ x, dN[1] @ y]])
            det = np.linalg.det(J)
            if det <= 0.0:
                raise ValueError("CQUAD4: non-convex or badly ordered corners (Jacobian <= 0)")
            dNx[q] = np.linalg.inv(J) @ dN
            wts[q] = det
            g1 = J0i @ np.array([-2.0 * r, 0.0]) * (det0 / det)
            g2 = J0i @ np.array([0.0, -2.0 * s_]) * (det0 / det)
            Ba[q, 0, 0], Ba[q, 2, 0], Ba[q, 1, 1], Ba[q, 2, 1] = g1[0], g1[1], g1[1], g1[0]
            Ba[q, 0, 2], Ba[q, 2, 2], Ba[q, 1, 3], Ba[q, 2, 3] = g2[0], g2[1], g2[1], g2[0]
            q += 1
    return dNx, wts, Ba


@njit(cache=True)
def shell_membrane_resultants(xyz, props, u):
    """Membrane stress resultants [N_x, N_y, N_xy] (element axes, N/m) at the membrane Gauss points of one
    CQUAD4 (4 points) or CTRIA3 (1 point) for the grid displacements ``u`` (6 nn, c) in basic [T; R]:
    (np, 3, c), with the shape gradients (np, 2, nn) and weights (np,) of the points."""
    T, loc, Lam = shell_frame_transform(xyz, props[32])
    A = shell_materials(props, Lam)[0]
    ul = T @ u
    dNx, wts, Ba = _shell_points(loc)
    npt, nn = wts.shape[0], xyz.shape[0]
    strains = np.empty((npt, 3, u.shape[1]))
    Kua = np.zeros((6 * nn, 4))
    Kaa = np.zeros((4, 4))
    for q in range(npt):
        Bm, _ = membrane_bending_B(dNx[q], nn)
        strains[q] = Bm @ ul
        Kua += Bm.T @ A @ Ba[q] * wts[q]
        Kaa += Ba[q].T @ A @ Ba[q] * wts[q]
    if nn == 4:
        alpha = -np.linalg.solve(Kaa, Kua.T @ ul)
        for q in range(npt):
            strains[q] += Ba[q] @ alpha
    out = np.empty_like(strains)
    for q in range(npt):
        out[q] = A @ strains[q]
    return out, dNx, wts


@njit(cache=True)
def shell_stress_batch(xyz, props, u):
    """H (ne, c, nn, nn) = int dN_i/dx_a N_ab dN_j/dx_b dA of many shells with the same grid count under the
    load cases u (ne, 6 nn, c) (grid displacements, basic [T; R]), and the local transforms T (ne, 6 nn, 6 nn)
    (module docstring)."""
    ne, nn, c = xyz.shape[0], xyz.shape[1], u.shape[2]
    H = np.zeros((ne, c, nn, nn))
    Ts = np.empty((ne, 6 * nn, 6 * nn))
    for e in range(ne):
        Ts[e] = shell_frame_transform(xyz[e], props[e, 32])[0]
        res, dNx, wts = shell_membrane_resultants(xyz[e], props[e], np.ascontiguousarray(u[e]))
        for q in range(wts.shape[0]):
            for k in range(c):
                S = np.array([[res[q, 0, k], res[q, 2, k]], [res[q, 2, k], res[q, 1, k]]])
                H[e, k] += dNx[q].T @ S @ dNx[q] * wts[q]
    return H, Ts


@njit(cache=True)
def solid_stresses(kind, xyz, E, nu, pts, wts, u):
    """Stresses (nq, 6, c) in Voigt order [xx, yy, zz, xy, yz, zx] at the Gauss points of one solid for the
    grid displacements u (3 n, c) (basic), with the shape gradients (nq, 3, n) and weights w det J (nq,)."""
    n = xyz.shape[0]
    nq = wts.shape[0]
    c = u.shape[1]
    C = solids.elasticity(E, nu)
    incompatible = kind == solids.HEXA8
    J0i = np.eye(3)
    det0 = 1.0
    if incompatible:
        _, dN0 = solids.shape(kind, np.zeros(3))
        J0 = dN0 @ xyz
        J0i = np.linalg.inv(J0)
        det0 = np.linalg.det(J0)
    grads = np.empty((nq, 3, n))
    w = np.empty(nq)
    strain = np.empty((nq, 6, c))
    Bas = np.zeros((nq, 6, 9))
    Kua = np.zeros((3 * n, 9))
    Kaa = np.zeros((9, 9))
    for q in range(nq):
        _, dN = solids.shape(kind, pts[q])
        J = dN @ xyz
        det = np.linalg.det(J)
        if det <= 0.0:
            raise ValueError("solid element: inverted or badly ordered grids (det J <= 0)")
        grads[q] = np.linalg.solve(J, dN)
        w[q] = wts[q] * det
        B = solids.strain_matrix(grads[q], n)
        strain[q] = B @ u
        if incompatible:
            Bas[q] = solids.incompatible_rows(pts[q], J0i, det0, det)
            Kua += B.T @ C @ Bas[q] * w[q]
            Kaa += Bas[q].T @ C @ Bas[q] * w[q]
    if incompatible:
        alpha = -np.linalg.solve(Kaa, Kua.T @ u)
        for q in range(nq):
            strain[q] += Bas[q] @ alpha
    stress = np.empty_like(strain)
    for q in range(nq):
        stress[q] = C @ strain[q]
    return stress, grads, w


@njit(cache=True)
def solid_stress_batch(kind, xyz, props, pts, wts, u):
    """H (ne, c, n, n) = int dN_i/dx_a sigma_ab dN_j/dx_b dV of many solids of one kind under the load cases
    u (ne, 3 n, c) (grid translations, basic); props (ne, 3): E, nu, rho (module docstring)."""
    ne, n, c = xyz.shape[0], xyz.shape[1], u.shape[2]
    H = np.zeros((ne, c, n, n))
    for e in range(ne):
        stress, grads, w = solid_stresses(kind, xyz[e], props[e, 0], props[e, 1], pts, wts,
                                          np.ascontiguousarray(u[e]))
        for q in range(w.shape[0]):
            for k in range(c):
                s = stress[q, :, k]
                S = np.array([[s[0], s[3], s[5]], [s[3], s[1], s[4]], [s[5], s[4], s[2]]])
                H[e, k] += grads[q].T @ S @ grads[q] * w[q]
    return H
