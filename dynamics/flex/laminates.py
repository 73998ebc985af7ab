"""Orthotropic and laminated shell sections: MAT8 plies, PCOMP laminates, PSHELL MID4 coupling.

NASTRAN turns a PCOMP into an equivalent PSHELL with four MAT2 entries (MSC Nastran Quick
Reference Guide, PCOMP remarks; MSC writes them to the OP2 as MAT2 1e8 + PID ... 4e8 + PID).
This module forms the same section, in the terms of the PSHELL (QRG PSHELL remarks: membrane
T G1, bending I G2, transverse shear T_s G3, membrane-bending coupling T^2 G4)::

    [N]   [ T G1      -T^2 G4 ] [eps  ]      Q_s = T_s G3 [gamma_xz, gamma_yz]
    [M] = [ -T^2 G4   I G2    ] [kappa]

with ``eps(z) = eps + z kappa`` the strain at height z along the element normal (the curvature of
:mod:`dynamics.flex.shells`) and ``M = int sigma z dz``. In these terms, and with the plies stacked
from ``z_0 = Z0`` upwards (ply 1 at the bottom):

* ply stiffness in its axes (plane stress, Jones, Mechanics of Composite Materials, 2nd ed., 1999,
  eq. 2.61): ``Q11 = E1 / (1 - nu12 nu21)``, ``Q12 = nu12 E2 / (1 - nu12 nu21)``,
  ``Q22 = E2 / (1 - nu12 nu21)``, ``Q66 = G12``, ``nu21 = nu12 E2 / E1`` (MAT8); a MAT1 ply is the
  isotropic case with ``G12 = E / (2 (1 + nu))`` and a MAT2 ply gives its matrix directly;
* in the laminate axes, the ply at angle theta: ``Qbar = T' Q T`` (Jones eq. 2.84,
  :func:`dynamics.flex.shells.rotate_plane`);
* ``A = sum Qbar_k (z_k - z_k-1)``, ``B = 1/2 sum Qbar_k (z_k^2 - z_k-1^2)``,
  ``D = 1/3 sum Qbar_k (z_k^3 - z_k-1^3)`` (Jones eqs. 4.22-4.24), so that
  ``G1 = A / T``, ``G2 = 12 D / T^3`` (12I/T^3 = 1) and ``G4 = -B / T^2`` (the minus: NASTRAN's
  plate curvature is -kappa; it is the sign MSC's own equivalents carry, and with it a PCOMP and
  MSC's equivalent PSHELL give the same modes, tests);
* transverse shear, each direction on its own (cylindrical bending; Whitney, "Shear correction
  factors for orthotropic laminates under static load", J. Appl. Mech. 40, 1973): under a shear
  force Q_x the bending stress ``Qbar11 (z - z_n) M_x / D_n`` of a plate bent about y (``z_n`` the
  neutral plane of Qbar11, ``D_n = int Qbar11 (z - z_n)^2 dz``) is in equilibrium with
  ``tau_xz(z) = -Q_x g(z) / D_n``, ``g(z) = int_zb^z Qbar11 (zeta - z_n) dzeta``; equal
  complementary energy gives ``H_x = D_n^2 / int g^2 / G_xz dz`` (5/6 G T for one homogeneous
  ply), ``G_xz = c^2 G1Z + s^2 G2Z`` of each ply; H_y the same with Qbar22 and
  ``G_yz = s^2 G1Z + c^2 G2Z``. ``G3 = diag(H_x, H_y) / T`` with TS/T = 1.
* mass: ``rho = sum rho_k t_k / T`` (the equivalent MID1's density) plus the PCOMP NSM per area;
  the consistent mass's rotary inertia is then the equivalent PSHELL's ``rho T^3 / 12``.

Checked against MSC Nastran's own equivalent MAT2s (tests/flex/test_nastran_laminates.py): A, B, D
to the OP2's single precision for MAT1, MAT8 and MAT2 plies and offset (Z0) laminates (LAM =
SYM is checked against the same laminate listed in full);
the transverse shear to single precision for laminates of 0 and 90 degree plies and for balanced
ones, while for some laminates with +-45 degree plies MSC's MID3 differs from this rule by up to
10 % (MSC's rule for those is not documented; docs/fem2modal.md, "NASTRAN agreement").

PCOMP fields: LAM blank, SYM (the listed plies then their mirror image) and MEM (membrane only, as
a PSHELL with MID1 alone) are modelled; BEND, SMEAR and SMCORE are refused. FT, SB, TREF and the
plies' SOUT (failure and stress output) do not enter K or M; GE (structural damping) is not used
for real modes and is reported. A MAT8's G1Z, G2Z blank means no transverse shear flexibility
(QRG MAT8); pyNastran stores a blank as 1e8, so an explicit 1e8 cannot be told from a blank.
"""

from __future__ import annotations

import warnings

import numpy as np

from dynamics.flex.bulk_data import BulkDataError
from dynamics.flex.shells import rotate_plane

# pyNastran's value for a blank MAT8 G1Z / G2Z (QRG: blank = infinite transverse shear modulus)
_BLANK_G1Z = 1e8
_GAUSS3 = np.polynomial.legendre.leggauss(3)


def orthotropic_q(E1: float, E2: float, nu12: float, G12: float) -> np.ndarray:
    """Plane-stress reduced stiffness (3 x 3, engineering shear) of an orthotropic lamina in its
    axes (Jones eq. 2.61)."""
    nu21 = nu12 * E2 / E1
    d = 1.0 - nu12 * nu21
    return np.array([[E1 / d, nu12 * E2 / d, 0.0], [nu12 * E2 / d, E2 / d, 0.0],
                     [0.0, 0.0, G12]])


def mat8_moduli(mat, context: str):
    """(Q 3 x 3, transverse shear moduli (G1Z, G2Z) with inf for blank, rho) of a MAT8."""
    E1, E2 = float(mat.e11 or 0.0), float(mat.e22 or 0.0)
    nu12, G12 = float(mat.nu12 or 0.0), float(mat.g12 or 0.0)
    if E1 <= 0.0 or E2 <= 0.0:
        raise BulkDataError(f"{context}: MAT8 {mat.mid} has E1 = {E1}, E2 = {E2}; both must be "
                            "> 0")
    if nu12 * nu12 * E2 / E1 >= 1.0:
        raise BulkDataError(f"{context}: MAT8 {mat.mid} has NU12 = {nu12} with E1 = {E1}, "
                            f"E2 = {E2}: nu12^2 E2 / E1 must be < 1 (positive definite)")
    if G12 <= 0.0:
        raise BulkDataError(f"{context}: MAT8 {mat.mid} has G12 = {G12}; the in-plane shear "
                            "modulus must be > 0")
    shear = []
    for name, g in (("G1Z", mat.g1z), ("G2Z", mat.g2z)):
        g = float(g or 0.0)
        if g == _BLANK_G1Z or g == 0.0:
            shear.append(np.inf)
        elif g < 0.0:
            raise BulkDataError(f"{context}: MAT8 {mat.mid} has {name} = {g} (must be > 0 or "
                                "blank)")
        else:
            shear.append(g)
    return orthotropic_q(E1, E2, nu12, G12), np.array(shear), float(mat.rho or 0.0)


def _ply_moduli(model, mid: int, context: str, warned: set):
    """(Q, (G1Z, G2Z), rho) of a PCOMP ply's MAT1, MAT2 or MAT8; ``warned``: the MAT1 ids of
    this PCOMP already warned about."""
    mat = model.materials.get(mid)
    if mat is None:
        raise BulkDataError(f"{context}: material {mid} is not defined")
    if mat.type == "MAT8":
        return mat8_moduli(mat, context)
    if mat.type == "MAT1":
        E, G, nu = mat.e, mat.g, mat.nu
        if E is None or nu is None:
            raise BulkDataError(f"{context}: MAT1 {mid} needs E and NU for a PCOMP ply (given "
                                f"E = {E}, G = {G}, NU = {nu})")
        E, nu = float(E), float(nu)
        G_plane = E / (2.0 * (1.0 + nu))
        G = float(G) if G else G_plane
        if abs(G - G_plane) > 1e-6 * G_plane and mid not in warned:
            warned.add(mid)
            # MSC Nastran's equivalent MID1/MID2 carry E / (2 (1 + nu)), its MID3 5/6 G
            # (pyNastran models/sol_101_elements/mode_solid_shell_bar.op2)
            warnings.warn(f"{context}: MAT1 {mid} has G = {G:.6g} but E / (2 (1 + nu)) = "
                          f"{G_plane:.6g}; as MSC Nastran, the ply's in-plane shear modulus is "
                          "E / (2 (1 + nu)) and G is its transverse shear modulus", stacklevel=5)
        return orthotropic_q(E, E, nu, G_plane), np.array([G, G]), float(mat.rho or 0.0)
    if mat.type == "MAT2":
        g = [float(v or 0.0) for v in (mat.G11, mat.G12, mat.G13, mat.G22, mat.G23, mat.G33)]
        Q = np.array([[g[0], g[1], g[2]], [g[1], g[3], g[4]], [g[2], g[4], g[5]]])
        # a MAT2 defines no transverse shear moduli: no shear flexibility (MSC writes no MID3)
        return Q, np.array([np.inf, np.inf]), float(mat.rho or 0.0)
    raise BulkDataError(f"{context}: material {mid} is a {mat.type}; PCOMP plies take MAT1, MAT2 "
                        "or MAT8")


def laminate_abd(plies, z0: float):
    """A, B, D (3 x 3 each, laminate axes) of plies ``[(Qbar, t), ...]`` stacked upwards from z0
    (Jones eqs. 4.22-4.24)."""
    A, B, D = np.zeros((3, 3)), np.zeros((3, 3)), np.zeros((3, 3))
    z = z0
    for Qbar, t in plies:
        z1 = z + t
        A += Qbar * (z1 - z)
        B += Qbar * (z1 ** 2 - z ** 2) / 2.0
        D += Qbar * (z1 ** 3 - z ** 3) / 3.0
        z = z1
    return A, B, D


def transverse_shear(plies, z0: float) -> np.ndarray:
    """diag(H_x, H_y): the cylindrical-bending shear stiffness of each direction (module
    docstring; Whitney 1973) of plies ``[(Qbar, t, (G_xz, G_yz)), ...]`` stacked upwards from z0;
    inf in a direction whose plies all have infinite transverse shear moduli."""
    H = np.empty(2)
    x, w = _GAUSS3
    for d in range(2):
        q = np.array([p[0][d, d] for p in plies])
        t = np.array([p[1] for p in plies])
        G = np.array([p[2][d] for p in plies])
        zb = z0 + np.concatenate([[0.0], np.cumsum(t)])
        zn = np.sum(q * (zb[1:] ** 2 - zb[:-1] ** 2) / 2.0) / np.sum(q * t)
        Dn = np.sum(q * ((zb[1:] - zn) ** 3 - (zb[:-1] - zn) ** 3) / 3.0)
        flexibility, g0 = 0.0, 0.0
        for k in range(len(plies)):
            a, b = zb[k], zb[k + 1]
            if np.isfinite(G[k]):
                z = 0.5 * (a + b) + 0.5 * (b - a) * x        # g is quadratic: 3 points exact
                g = g0 + q[k] * ((z - zn) ** 2 - (a - zn) ** 2) / 2.0
                flexibility += np.sum(w * g * g) * 0.5 * (b - a) / G[k]
            g0 += q[k] * ((b - zn) ** 2 - (a - zn) ** 2) / 2.0
        H[d] = np.inf if flexibility == 0.0 else Dn * Dn / flexibility
    return np.diag(H)


def pcomp_section(model, pid: int, context: str):
    """Equivalent PSHELL of PCOMP ``pid``: (Gm, Gb, Gs, rho, T, nsm, 12I/T^3, TS/T, shear_rigid,
    Gc) in the terms of :func:`dynamics.flex.shells.property_row` (module docstring): membrane
    ``A / T``, bending ``12 D / T^3``, transverse shear ``diag(H_x, H_y) / T`` (TS/T = 1) and the
    coupling modulus ``B / T^2`` (= -G4), all in the element's material axes."""
    prop = model.properties[pid]
    ctx = f"{context} -> PCOMP {pid}"
    lam = str(prop.lam or "").strip().upper()
    if lam in ("BEND", "SMEAR", "SMCORE"):
        raise BulkDataError(f"{ctx}: LAM = {lam} is not supported (blank, SYM and MEM are)")
    if lam not in ("", "SYM", "MEM"):
        raise BulkDataError(f"{ctx}: LAM = {lam} is not a PCOMP laminate option")
    if float(prop.ge or 0.0) != 0.0:
        warnings.warn(f"{ctx}: GE = {prop.ge} (structural damping) is not used (the body's "
                      "damping is modal: --damping)", stacklevel=4)
    listed = list(zip(prop.mids, prop.thicknesses, prop.thetas))
    if not listed:
        raise BulkDataError(f"{ctx}: no plies")
    stack = listed + listed[::-1] if lam == "SYM" else listed
    plies, mass, warned = [], 0.0, set()
    for k, (mid, t, theta) in enumerate(stack):
        pctx = f"{ctx} ply {k % len(listed) + 1}"
        if mid is None or t is None or not float(t) > 0.0:
            raise BulkDataError(f"{pctx}: MID = {mid}, T = {t}; a ply needs a material and a "
                                "thickness > 0")
        Q, G12z, rho = _ply_moduli(model, int(mid), pctx, warned)
        c, s = np.cos(np.radians(float(theta or 0.0))), np.sin(np.radians(float(theta or 0.0)))
        # the ply's shear moduli in the laminate axes (an infinite one only where it acts)
        Gxz = sum(w * g for w, g in ((c * c, G12z[0]), (s * s, G12z[1])) if w > 1e-12)
        Gyz = sum(w * g for w, g in ((s * s, G12z[0]), (c * c, G12z[1])) if w > 1e-12)
        plies.append((rotate_plane(Q, c, s), float(t), (Gxz, Gyz)))
        mass += rho * float(t)
    T = sum(p[1] for p in plies)
    z0 = float(prop.z0) if prop.z0 is not None else -0.5 * T
    A, B, D = laminate_abd([(p[0], p[1]) for p in plies], z0)
    rho = mass / T
    nsm = float(prop.nsm or 0.0)
    Gm = A / T
    if lam == "MEM":
        # a PSHELL with MID1 alone (QRG PCOMP: only the membrane terms are computed)
        return Gm, Gm, np.zeros((2, 2)), rho, T, nsm, 0.0, 1.0, False, np.zeros((3, 3))
    H = transverse_shear(plies, z0)
    h = np.diag(H)
    Gb = 12.0 * D / T ** 3
    if np.isinf(h).all():
        # no transverse shear flexibility: the equivalent PSHELL's blank MID3 (its shear penalty
        # scaled, as for any PSHELL whose MID2 is a MAT2, by MID2's G11, G12, G22)
        Gs, rigid = Gb[:2, :2].copy(), True
    elif np.isinf(h).any():
        raise BulkDataError(f"{ctx}: the plies' transverse shear moduli (MAT8 G1Z, G2Z) leave "
                            "one direction without shear flexibility and the other with it; "
                            "give both or neither")
    else:
        Gs, rigid = H / T, False
    return Gm, Gb, Gs, rho, T, nsm, 1.0, 1.0, rigid, B / T ** 2
