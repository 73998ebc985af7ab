"""Modal integrals of a flexible body (TM-2020-5008164 Appendix E).

Inputs per node j (all in the body frame, basic axes, origin at the reference point): mass
m_j, centre-of-mass offset p_j and inertia J_j about the node (eq. E.1.2), undeformed position
l0_j, and the mode-shape blocks Pi_j = [lambda_j; gamma_j] (rotation rows first, eq. E.1.19).

The node inertia in the body frame is deformation dependent (eq. E.1.3) with the first-order
attitude delta_r = I + theta~ (eq. E.1.17), theta = lambda eta, and l = l0 + gamma eta
(eq. E.1.1). Expanding M_fl = Y' M_nd Y (eq. E.1.34) in powers of eta gives the integrals
below, which reproduce that product exactly (see tests/flex/test_modal_integrals.py):

  m, p0, J0, p1(r), J1(r), J2(r,s)           eqs. E.2.3-E.2.4   rigid/rigid block
  F0(r), F1(r,s), F2(r,s,l), E0(r), E1(r,s)   eq. E.2.5          rigid/modal block
  G0(r,s), G1(r,s,l), G2(r,s,l,m)             eq. E.2.2          modal/modal block

Notes on the printed equations. F1 is written here as
  sum_j [lambda_s~ J - J lambda_s~] lambda_r + m { gamma_s~ gamma_r - gamma_s~ p~ lambda_r
        + [lambda_s~ p]x gamma_r - l0~ [lambda_s~ p]x lambda_r },
algebraically identical to the TM's form (a x b = -b x a). G2 uses lambda~ where the TM prints
gamma~ (only the rotation of the node changes its inertia, eq. E.1.3). J2 is stored in its
symmetrized form (J2(r,s) + J2(s,r))/2: the sum sum_rs J2(r,s) eta_r eta_s is unchanged and the
stored array satisfies J2(r,s) = J2(s,r)' (the symmetry the TM states), which the unsymmetrized
expression does not when nodes have CG offsets. G1 keeps the TM's (r, s, l) definition, used
as G1(r,s,l) + G1(s,r,l) in eq. E.2.2.

The point-mass specialisation (eq. E.3.1: J_j = 0, p_j = 0) is :func:`point_mass_integrals`.
The FEM pipeline takes m_j, p_j, J_j from the 6 x 6 grid blocks of the lumped mass matrix.
"""

from __future__ import annotations

from dataclasses import dataclass, fields

import numpy as np


def skew_batch(v: np.ndarray) -> np.ndarray:
    """(..., 3) -> (..., 3, 3) cross-product matrices."""
    S = np.zeros(v.shape + (3,))
    S[..., 0, 1], S[..., 0, 2] = -v[..., 2], v[..., 1]
    S[..., 1, 0], S[..., 1, 2] = v[..., 2], -v[..., 0]
    S[..., 2, 0], S[..., 2, 1] = -v[..., 1], v[..., 0]
    return S


@dataclass
class ModalIntegrals:
    """Modal integrals (SI: kg, m; mode shapes carry the units of mass-normalized modes).

    Shapes with n = number of modes: mass (), p0 (3,), J0 (3,3), p1 (n,3), J1 (n,3,3),
    J2 (n,n,3,3), F0 (n,3), F1 (n,n,3) [index (r,s)], F2 (n,n,n,3) [(r,s,l)], E0 (n,3),
    E1 (n,n,3) [(r,s)], G0 (n,n), G1 (n,n,n) [(r,s,l)], G2 (n,n,n,n) [(r,s,l,m)]. An integral
    is None when it was not computed (above the order :func:`modal_integrals` was asked for, or
    omitted there) or, for G2, when it is identically zero (no node has rotational inertia). For
    point-mass nodes (TM eq. E.3.1) G1 and F2 are arrays of zeros, as the body-file layout has them
    (docs/body_file.md); leave them out with ``omit`` for large studies.
    """

    mass: float
    p0: np.ndarray
    J0: np.ndarray
    p1: np.ndarray | None
    J1: np.ndarray | None
    J2: np.ndarray | None
    F0: np.ndarray
    F1: np.ndarray | None
    F2: np.ndarray | None
    E0: np.ndarray
    E1: np.ndarray | None
    G0: np.ndarray
    G1: np.ndarray | None
    G2: np.ndarray | None

    def arrays(self) -> dict:
        """Name -> array of every integral that is present."""
        return {f.name: np.asarray(getattr(self, f.name)) for f in fields(self)
                if getattr(self, f.name) is not None}


def modal_integrals(node_mass: np.ndarray, node_cm: np.ndarray, node_inertia: np.ndarray,
                    positions: np.ndarray, rotation_shapes: np.ndarray,
                    translation_shapes: np.ndarray, max_g2_modes: int = 40, order: int = 2,
                    omit: tuple = (), max_cubic_modes: int = 40) -> ModalIntegrals:
    """The integrals of eqs. E.2.2-E.2.5 that modal-integral ``order`` 0, 1 or 2 uses.

    ``order`` 0 computes m, p0, J0, F0, E0, G0; 1 adds p1, J1, F1, E1, G1; 2 (default) adds J2,
    F2, G2. The integrals above the order are ``None``, as are those named in ``omit`` (a subset of
    "G1", "F2", "G2", the tables of n^3, n^3 and n^4 numbers). Memory and time: O(N n^2) at order 0
    and at order 1 without G1, O(N n^3) with G1 or F2, O(N n^4) with G2 (N nodes, n modes).

    G2 is also ``None`` when it is identically zero (no node has rotational inertia) or when
    n > ``max_g2_modes`` (n^4 numbers), and G1 and F2 when n > ``max_cubic_modes`` (n^3 numbers each, 3 n^3 for
    F2): the engine evaluates these three terms as sums over the nodes (their masses, offsets, inertias and
    shapes, which a body file always holds: :mod:`dynamics.kernels.node_inertia`) at O(N n) per evaluation, so
    the tables are worth their size only for small mode counts, where they are the cheaper form.

    node_mass (N,), node_cm (N,3) = p_j, node_inertia (N,3,3) = J_j about the node,
    positions (N,3) = l0_j from the body-frame origin, rotation_shapes (N,3,n) = lambda_j,
    translation_shapes (N,3,n) = gamma_j.
    """
    if order not in (0, 1, 2):
        raise ValueError(f"modal-integral order must be 0, 1 or 2, got {order!r}")
    unknown = set(omit) - {"G1", "F2", "G2"}
    if unknown:
        raise ValueError(f"omit: only G1, F2 and G2 can be left out, got {sorted(unknown)}")
    n_modes = np.shape(rotation_shapes)[2]
    want_g1 = order >= 1 and "G1" not in omit and n_modes <= max_cubic_modes
    want_f2 = order >= 2 and "F2" not in omit and n_modes <= max_cubic_modes
    want_g2 = order >= 2 and "G2" not in omit
    m = np.asarray(node_mass, float)
    p = np.asarray(node_cm, float)
    J = np.asarray(node_inertia, float)
    l0 = np.asarray(positions, float)
    lam = np.asarray(rotation_shapes, float)
    gam = np.asarray(translation_shapes, float)
    n = lam.shape[2]
    mass = float(m.sum())
    if mass <= 0.0:
        raise ValueError("modal integrals of a zero-mass body")
    es = dict(optimize=True)
    # point-mass part (every node): terms in m, l0 and gamma only, as two GEMMs with
    # C[(a,s),(c,r)] = sum_j m gamma_as gamma_cr and D[a,(c,r)] = sum_j m l0_a gamma_cr, using
    # a~ b~ = b a' - (a.b) I and a~ b = a x b.
    L0 = skew_batch(l0)
    N = len(m)
    Z = gam.reshape(N, 3 * n)
    C = (Z.T @ (m[:, None] * Z)).reshape(3, n, 3, n)             # [a, s, c, r]
    D = ((m[:, None] * l0).T @ Z).reshape(3, 3, n)                # [a, c, r]
    eps = np.zeros((3, 3, 3))
    eps[0, 1, 2] = eps[1, 2, 0] = eps[2, 0, 1] = 1.0
    eps[0, 2, 1] = eps[2, 1, 0] = eps[1, 0, 2] = -1.0
    I3 = np.eye(3)
    p0 = (m[:, None] * (p + l0)).sum(0) / mass
    J0 = (J - m[:, None, None] * (L0 @ L0 + skew_batch(p) @ L0 + L0 @ skew_batch(p))).sum(0)
    E0 = np.einsum("j,jar->ra", m, gam)
    G0 = np.einsum("asar->rs", C)
    F0 = np.einsum("abc,bcr->ra", eps, D)
    p1 = J1 = F1 = E1 = G1 = J2 = F2 = G2 = None
    if order >= 1:
        p1 = E0 / mass
        J1 = -D.transpose(2, 0, 1) + np.einsum("bbr,ac->rac", D, I3)
        F1 = np.einsum("abc,bscr->rsa", eps, C)
        E1 = np.zeros((n, n, 3))
        G1 = np.zeros((n, n, n)) if want_g1 else None
    if order >= 2:
        J2 = -C.transpose(3, 1, 0, 2) + G0[:, :, None, None] * I3
        F2 = np.zeros((n, n, n, 3)) if want_f2 else None
    # terms in the node inertia J and CG offset p: only nodes that have them
    sel = (np.abs(J).reshape(len(m), -1).max(axis=1) > 0.0) | (np.abs(p).max(axis=1) > 0.0)
    if np.any(sel):
        m, p, J, L0 = m[sel], p[sel], J[sel], L0[sel]
        lam, gam = lam[sel], gam[sel]
        Gr = skew_batch(np.moveaxis(gam, 2, 1))         # (N,n,3,3) gamma_r~
        P = skew_batch(p)
        Lr = skew_batch(np.moveaxis(lam, 2, 1))         # (N,n,3,3) lambda_r~
        lxp = np.cross(np.moveaxis(lam, 2, 1), p[:, None, :])   # (N,n,3) lambda_r~ p
        LXP = skew_batch(lxp)                           # [lambda_r~ p]x
        E0 = E0 - np.einsum("j,jab,jbr->ra", m, P, lam, **es)     # eq. E.2.5
        F0 = F0 + (np.einsum("jab,jbr->ra", J - m[:, None, None] * (L0 @ P), lam, **es)
                   + np.einsum("j,jab,jbr->ra", m, P, gam, **es))
        G0 = G0 + (np.einsum("jar,jab,jbs->rs", lam, J, lam, **es)
                   + np.einsum("j,jar,jab,jbs->rs", m, lam, P, gam, **es)
                   + np.einsum("j,jas,jab,jbr->rs", m, lam, P, gam, **es))
        if order >= 1:
            p1 = p1 + np.einsum("j,jri->ri", m, lxp, **es) / mass     # eq. E.2.4
            J1 = J1 + (np.einsum("jrab,jbc->rac", Lr, J, **es)
                       - np.einsum("j,jrab,jbc->rac", m, Gr, P, **es)
                       - np.einsum("j,jab,jrbc->rac", m, L0, LXP, **es))
            LJ = np.einsum("jsab,jbc->jsac", Lr, J, **es)
            JL = np.einsum("jab,jsbc->jsac", J, Lr, **es)
            F1 = F1 + (np.einsum("jsab,jbr->rsa", LJ - JL, lam, **es)
                       - np.einsum("j,jsab,jbc,jcr->rsa", m, Gr, P, lam, **es)
                       + np.einsum("j,jsab,jbr->rsa", m, LXP, gam, **es)
                       - np.einsum("j,jab,jsbc,jcr->rsa", m, L0, LXP, lam, **es))
            E1 = -np.einsum("j,jsab,jbr->rsa", m, LXP, lam, **es)
        if order >= 2:
            J2 = J2 - (np.einsum("jrab,jbc,jscd->rsad", Lr, J, Lr, **es)
                       + np.einsum("j,jrab,jsbc->rsac", m, Gr, LXP, **es)
                       + np.einsum("j,jsab,jrbc->rsac", m, LXP, Gr, **es))
        lam_t = np.moveaxis(lam, 2, 1)                                   # (N,n,3)
        Nj = len(m)
        if want_g1 or want_f2 or want_g2:
            cross_rl = np.cross(lam_t[:, :, None, :], lam_t[:, None, :, :])  # (N,r,l,3)
        if want_f2:
            # F2(r,s,l) = -sum_j [lambda_s x (J (lambda_l x lambda_r))
            #                     + m gamma_s x ((lambda_l x p) x lambda_r)], GEMMs over (node, axis)
            w = np.einsum("jab,jlrb->jalr", J, cross_rl)                         # J (l x r)
            u = np.cross(lxp[:, :, None, :], lam_t[:, None, :, :])              # (l x p) x r
            u = (m[:, None, None, None] * u).transpose(0, 3, 1, 2)               # (N,3,l,r)
            F2 = -((Lr.transpose(1, 2, 0, 3).reshape(3 * n, 3 * Nj)
                    @ w.reshape(3 * Nj, n * n))
                   + (Gr.transpose(1, 2, 0, 3).reshape(3 * n, 3 * Nj)
                      @ u.reshape(3 * Nj, n * n)))
            F2 = F2.reshape(n, 3, n, n).transpose(3, 0, 2, 1)                    # [r,s,l,a]
        if want_g1:
            # lambda_r' lambda_l~ = (lambda_r x lambda_l)' and lambda_r' [w]x = (lambda_r x w)':
            # G1 as one GEMM over (node, axis)
            Jlam = np.einsum("jab,jbs->jas", J, lam)                         # (N,3,n)
            q = m[:, None, None, None] * np.cross(lam_t[:, :, None, :], lxp[:, None, :, :])
            G1 = ((cross_rl.transpose(0, 3, 1, 2).reshape(3 * Nj, n * n).T
                   @ Jlam.reshape(3 * Nj, n))
                  + (q.transpose(0, 3, 1, 2).reshape(3 * Nj, n * n).T
                     @ gam.reshape(3 * Nj, n))).reshape(n, n, n).transpose(0, 2, 1)
        hasJ = np.abs(J).reshape(len(m), -1).max(axis=1) > 0.0
        if want_g2 and np.any(hasJ) and n <= max_g2_modes:
            # G2(r,s,l,m) = -(lambda_r x lambda_l)' J (lambda_m x lambda_s): one GEMM
            C = cross_rl[hasJ].transpose(0, 3, 1, 2).reshape(-1, n * n)      # rows (j,a)
            JC = np.einsum("jab,jbX->jaX", J[hasJ],
                           cross_rl[hasJ].transpose(0, 3, 1, 2).reshape(-1, 3, n * n))
            X = (C.T @ JC.reshape(-1, n * n)).reshape(n, n, n, n)         # [r,l,m,s]
            G2 = -X.transpose(0, 3, 1, 2)
    if J2 is not None:
        J2 = 0.5 * (J2 + J2.transpose(1, 0, 2, 3))
    return ModalIntegrals(mass=mass, p0=p0, J0=J0, p1=p1, J1=J1, J2=J2, F0=F0, F1=F1, F2=F2,
                          E0=E0, E1=E1, G0=G0, G1=G1, G2=G2)


def point_mass_integrals(node_mass, positions, translation_shapes) -> ModalIntegrals:
    """Eq. E.3.1: nodes as point masses (J_j = 0, p_j = 0); F2 = E1 = G1 = G2 = 0."""
    N, _, n = np.shape(translation_shapes)
    return modal_integrals(node_mass, np.zeros((N, 3)), np.zeros((N, 3, 3)), positions,
                           np.zeros((N, 3, n)), translation_shapes)


def flexible_body_mass_matrix(mi: ModalIntegrals, eta: np.ndarray) -> np.ndarray:
    """M_fl(eta) of eq. E.2.6, ordered [eta_dot; omega; v] (n + 6 square)."""
    eta = np.asarray(eta, float)
    n = len(eta)
    G = mi.G0.copy()
    if mi.G1 is not None:  # None: not computed (order-limited integrals)
        G = G + np.einsum("rsl,l->rs", mi.G1 + mi.G1.transpose(1, 0, 2), eta)
    if mi.G2 is not None:
        G = G + np.einsum("rslm,l,m->rs", mi.G2, eta, eta)
    F = mi.F0 + np.einsum("rsa,s->ra", mi.F1, eta)          # (n,3)
    if mi.F2 is not None:
        F = F + np.einsum("rsla,s,l->ra", mi.F2, eta, eta)
    E = mi.E0 + np.einsum("rsa,s->ra", mi.E1, eta)               # (n,3)
    p = mi.p0 + mi.p1.T @ eta
    Jk = (mi.J0 + np.einsum("rab,r->ab", mi.J1 + mi.J1.transpose(0, 2, 1), eta)
          + np.einsum("rsab,r,s->ab", mi.J2, eta, eta))
    P = skew_batch(p)
    M = np.zeros((n + 6, n + 6))
    M[:n, :n] = G
    M[n:n + 3, :n] = F.T
    M[:n, n:n + 3] = F
    M[n + 3:, :n] = E.T
    M[:n, n + 3:] = E
    M[n:n + 3, n:n + 3] = Jk
    M[n:n + 3, n + 3:] = mi.mass * P
    M[n + 3:, n:n + 3] = -mi.mass * P
    M[n + 3:, n + 3:] = mi.mass * np.eye(3)
    return M
