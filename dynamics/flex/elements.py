"""Element stiffness and mass matrices for the line, spring and mass cards of the pipeline.

Local DOF order per end is NASTRAN's ``[u, v, w, theta_x, theta_y, theta_z]``; the element x axis
runs from end A to end B (grid plus offset), y lies in the plane of x and the orientation vector,
z = x cross y. Plane 1 bending (v, theta_z) uses I1, plane 2 bending (w, theta_y) uses I2.

* CBAR / CBEAM: two-node beam with cubic Hermite bending. Transverse shear flexibility is
  included as in NASTRAN when the property gives a shear factor K (Timoshenko beam with the
  shear parameter phi = 12 E I / (K G A L^2); Przemieniecki, Theory of Matrix Structural
  Analysis, 1968, secs. 5.6 and 11.6). PBAR leaves K blank (pyNastran stores 1e8: no shear
  deformation, the Euler-Bernoulli element); PBEAM defaults to K = 1. The consistent mass of the
  shear-deformable element (Przemieniecki eq. 11.40 without rotary inertia) reduces to the
  classical 156/54/22/13 Hermite mass for phi = 0. Torsion: linear, mass moment rho (I1 + I2).
* CROD: axial and torsion; consistent mass is linear in all three translations (rigid lateral).
* Lumped mass (PARAM COUPMASS <= 0, NASTRAN's default): half of the element mass on the
  translations of each end; CBEAM also lumps half its torsional mass moment rho (I1 + I2) L on
  each end's axial rotation (so a free-free CBEAM model has no massless torsion mechanism),
  CBAR and CROD have no rotational inertia.
* Offsets: rigid links from the grid to the element end, u_end = u_grid + theta_grid x w.
* CONM2: point mass with CG offset and inertia about the CG; CONM1: 6 x 6 nodal mass.
  Nodal 6 x 6 blocks are written in the pipeline's ``[T; R]`` grid order
  ``[[m I, -m p~], [m p~, J_cg - m p~ p~]]`` which is TM-2020-5008164 eq. E.1.2 with the
  rotation and translation blocks swapped.
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True)
def skew(v: np.ndarray) -> np.ndarray:
    """Cross-product matrix: skew(a) @ b = a x b."""
    S = np.zeros((3, 3))
    S[0, 1], S[0, 2] = -v[2], v[1]
    S[1, 0], S[1, 2] = v[2], -v[0]
    S[2, 0], S[2, 1] = -v[1], v[0]
    return S


def beam_frame(axis: np.ndarray, orientation: np.ndarray, context: str) -> np.ndarray:
    """Rows are the element x, y, z axes in basic (local = Lambda @ basic)."""
    length = np.linalg.norm(axis)
    if length <= 0.0:
        raise ValueError(f"{context}: zero element length")
    x = axis / length
    vy = orientation - (orientation @ x) * x
    ny = np.linalg.norm(vy)
    if ny <= 1e-9 * max(np.linalg.norm(orientation), 1e-300):
        raise ValueError(f"{context}: orientation vector is parallel to the element axis "
                         "(or zero)")
    y = vy / ny
    return np.vstack([x, y, np.cross(x, y)])


@njit(cache=True)
def shear_parameter(E: float, I: float, k: float, G: float, A: float, L: float) -> float:
    """phi = 12 E I / (k G A L^2); zero for no shear flexibility (k = 0 or blank/1e8, G = 0)."""
    if k == 0.0 or k >= 1e8 or G == 0.0 or A == 0.0:
        return 0.0
    return 12.0 * E * I / (k * G * A * L * L)


@njit(cache=True)
def _bending_into(K, M, idx, flip, EI, mu, L, phi, coupled):
    """Add plane bending stiffness/consistent mass (v, theta) at local indices ``idx``."""
    c = EI / (L**3 * (1.0 + phi))
    kb = np.empty((4, 4))
    kb[0, 0], kb[0, 1], kb[0, 2], kb[0, 3] = 12.0, 6.0 * L, -12.0, 6.0 * L
    kb[1, 1], kb[1, 2], kb[1, 3] = (4.0 + phi) * L * L, -6.0 * L, (2.0 - phi) * L * L
    kb[2, 2], kb[2, 3] = 12.0, -6.0 * L
    kb[3, 3] = (4.0 + phi) * L * L
    d = (1.0 + phi) ** 2
    m11 = (13.0 / 35 + 7.0 / 10 * phi + phi * phi / 3) / d
    m12 = (11.0 / 210 + 11.0 / 120 * phi + phi * phi / 24) * L / d
    m13 = (9.0 / 70 + 3.0 / 10 * phi + phi * phi / 6) / d
    m14 = (13.0 / 420 + 3.0 / 40 * phi + phi * phi / 24) * L / d
    m22 = (1.0 / 105 + phi / 60 + phi * phi / 120) * L * L / d
    m24 = (1.0 / 140 + phi / 60 + phi * phi / 120) * L * L / d
    mb = np.empty((4, 4))
    mb[0, 0], mb[0, 1], mb[0, 2], mb[0, 3] = m11, m12, m13, -m14
    mb[1, 1], mb[1, 2], mb[1, 3] = m22, m14, -m24
    mb[2, 2], mb[2, 3] = m11, -m12
    mb[3, 3] = m22
    for a in range(4):
        for b in range(a, 4):
            sab = flip[a] * flip[b]
            K[idx[a], idx[b]] += sab * c * kb[a, b]
            if coupled:
                M[idx[a], idx[b]] += sab * mu * L * mb[a, b]
            if b != a:
                K[idx[b], idx[a]] = K[idx[a], idx[b]]
                M[idx[b], idx[a]] = M[idx[a], idx[b]]


@njit(cache=True)
def beam_local_matrices(L, E, G, A, I1, I2, J, mu, k1, k2, coupled, lumped_torsion):
    """Local 12 x 12 stiffness and mass of a prismatic beam (mu = mass per length).

    ``lumped_torsion`` puts half the torsional mass moment rho (I1 + I2) L on each end in the
    lumped mass (used for CBEAM); CBAR's lumped mass has no rotational inertia.
    """
    K = np.zeros((12, 12))
    M = np.zeros((12, 12))
    ea, gj = E * A / L, G * J / L
    K[0, 0] = K[6, 6] = ea
    K[0, 6] = K[6, 0] = -ea
    K[3, 3] = K[9, 9] = gj
    K[3, 9] = K[9, 3] = -gj
    rho_ip = 0.0 if A == 0.0 else mu / A * (I1 + I2)
    phi1 = shear_parameter(E, I1, k1, G, A, L)
    phi2 = shear_parameter(E, I2, k2, G, A, L)
    _bending_into(K, M, np.array([1, 5, 7, 11]), np.array([1.0, 1.0, 1.0, 1.0]),
                  E * I1, mu, L, phi1, coupled)
    _bending_into(K, M, np.array([2, 4, 8, 10]), np.array([1.0, -1.0, 1.0, -1.0]),
                  E * I2, mu, L, phi2, coupled)   # theta_y = -dw/dx
    if coupled:
        for a, b, w in ((0, 6, mu), (3, 9, rho_ip)):
            M[a, a] = M[b, b] = w * L / 3.0
            M[a, b] = M[b, a] = w * L / 6.0
    else:
        for i in (0, 1, 2, 6, 7, 8):
            M[i, i] = mu * L / 2.0
        if lumped_torsion:
            M[3, 3] = M[9, 9] = rho_ip * L / 2.0
    return K, M


@njit(cache=True)
def beam_element_batch(props, frames, offsets_a, offsets_b, coupled, lumped_torsion):
    """Grid-level (basic, [T; R] per grid) K, M and lumped M for many beams at once.

    props (ne, 10): L, E, G, A, I1, I2, J, mu, k1, k2; frames (ne, 3, 3) element axes (rows);
    offsets (ne, 3) in basic; lumped_torsion (ne,) bool. Returns three (ne, 12, 12) arrays.
    """
    ne = props.shape[0]
    Kg = np.empty((ne, 12, 12))
    Mg = np.empty((ne, 12, 12))
    MLg = np.empty((ne, 12, 12))
    for e in range(ne):
        L, E, G, A, I1, I2, J, mu, k1, k2 = props[e]
        Kl, Ml = beam_local_matrices(L, E, G, A, I1, I2, J, mu, k1, k2, coupled,
                                     lumped_torsion[e])
        T = local_to_grids(frames[e], offsets_a[e], offsets_b[e])
        Kg[e] = T.T @ Kl @ T
        Mg[e] = T.T @ Ml @ T
        if coupled:
            _, Mlump = beam_local_matrices(L, E, G, A, I1, I2, J, mu, k1, k2, False,
                                           lumped_torsion[e])
            MLg[e] = T.T @ Mlump @ T
        else:
            MLg[e] = Mg[e]
    return Kg, Mg, MLg


def rod_local_matrices(L, E, G, A, J, mu, coupled: bool):
    """Local 12 x 12 stiffness and mass of a rod (axial + torsion)."""
    K = np.zeros((12, 12))
    K[np.ix_([0, 6], [0, 6])] = E * A / L * np.array([[1.0, -1.0], [-1.0, 1.0]])
    K[np.ix_([3, 9], [3, 9])] = G * J / L * np.array([[1.0, -1.0], [-1.0, 1.0]])
    M = np.zeros((12, 12))
    if coupled:
        lin = mu * L / 6.0 * np.array([[2.0, 1.0], [1.0, 2.0]])
        for d in range(3):
            M[np.ix_([d, 6 + d], [d, 6 + d])] = lin
    else:
        M[[0, 1, 2, 6, 7, 8], [0, 1, 2, 6, 7, 8]] = mu * L / 2.0
    return K, M


@njit(cache=True)
def local_to_grids(Lambda: np.ndarray, offset_a: np.ndarray, offset_b: np.ndarray) -> np.ndarray:
    """T (12 x 12): local end DOFs = T @ grid DOFs (basic, [T; R] per grid), offsets included."""
    T = np.zeros((12, 12))
    for end, w in ((0, offset_a), (6, offset_b)):
        T[end:end + 3, end:end + 3] = Lambda
        T[end:end + 3, end + 3:end + 6] = -Lambda @ skew(w)
        T[end + 3:end + 6, end + 3:end + 6] = Lambda
    return T


def point_mass_block(mass: float, offset: np.ndarray, inertia_cg: np.ndarray) -> np.ndarray:
    """6 x 6 grid mass ([T; R] order) of a rigid mass at ``offset`` with inertia about its CG."""
    P = skew(offset)
    B = np.zeros((6, 6))
    B[:3, :3] = mass * np.eye(3)
    B[:3, 3:] = -mass * P
    B[3:, :3] = mass * P
    B[3:, 3:] = inertia_cg - mass * P @ P
    return B


def conm2_inertia(I6) -> np.ndarray:
    """CONM2 I11, I21, I22, I31, I32, I33 to the inertia matrix (NASTRAN sign convention)."""
    i11, i21, i22, i31, i32, i33 = (float(v) for v in I6)
    return np.array([[i11, -i21, -i31], [-i21, i22, -i32], [-i31, -i32, i33]])


def _station_values(stations: np.ndarray, values: np.ndarray, s: np.ndarray) -> np.ndarray:
    """Piecewise-linear interpolation in s = x / L of the station values (columns of values)."""
    return np.stack([np.interp(s, stations, v) for v in values.T], axis=1)


def tapered_beam_local_matrices(L, E, G, stations, sections, rho, k1, k2, coupled,
                                lumped_torsion, n_gauss: int = 16):
    """Local 12 x 12 stiffness and mass of a tapered beam (NASTRAN PBEAM with stations).

    ``stations`` (ns,) ascending x / L from 0 to 1; ``sections`` (ns, 5) A, I1, I2, J, NSM at
    the stations, each interpolated linearly in x between stations (the documented assumption:
    MSC's QRG gives the station values, not the law between them). ``rho`` the material
    density (mu = rho A + NSM per length).

    Stiffness: exact for the interpolated section under end loads, by the flexibility method
    (Przemieniecki, Theory of Matrix Structural Analysis, 1968, sec. 5.5 - 5.6): end B's
    flexibility relative to a clamped end A, f11 = int (L - x)^2 / EI + int 1 / (k G A),
    f12 = int (L - x) / EI, f22 = int 1 / EI, inverted and carried to both ends by
    equilibrium, K = R' F^-1 R with R the relative (deformation) map; axial 1 / int 1/EA,
    torsion 1 / int 1/GJ. For a prismatic section this is :func:`beam_local_matrices`' stiffness
    exactly. Consistent mass: cubic Hermite (shear-free) bending shapes and linear axial /
    torsion shapes integrated with mu(x) and rho (I1 + I2)(x); lumped mass: the element mass and
    torsional moment split between the ends by the lever rule (int mu (1 - x/L), int mu x/L).
    Integrals by Gauss-Legendre, ``n_gauss`` points per interval between stations: 1 / EI(x)
    with EI linear and end ratios up to 10 is integrated to ~1e-14.
    """
    g, w = np.polynomial.legendre.leggauss(n_gauss)
    s_pts, s_w = [], []
    for a, b in zip(stations[:-1], stations[1:]):
        if b > a:
            s_pts.append(0.5 * (a + b) + 0.5 * (b - a) * g)
            s_w.append(0.5 * (b - a) * w)
    s = np.concatenate(s_pts)
    ws = np.concatenate(s_w) * L                  # weights in x
    x = s * L
    A, I1, I2, J, nsm = _station_values(np.asarray(stations, float), np.asarray(sections, float),
                                        s).T
    if np.any(A <= 0.0) or np.any(I1 <= 0.0) or np.any(I2 <= 0.0):
        raise ValueError("tapered beam: A, I1 and I2 must be > 0 along the element")
    K = np.zeros((12, 12))
    M = np.zeros((12, 12))
    ea = 1.0 / np.sum(ws / (E * A))
    K[np.ix_([0, 6], [0, 6])] = ea * np.array([[1.0, -1.0], [-1.0, 1.0]])
    if G > 0.0 and np.all(J > 0.0):
        gj = 1.0 / np.sum(ws / (G * J))
        K[np.ix_([3, 9], [3, 9])] = gj * np.array([[1.0, -1.0], [-1.0, 1.0]])
    R = np.array([[-1.0, -L, 1.0, 0.0], [0.0, -1.0, 0.0, 1.0]])
    for idx, flip, I, k in (([1, 5, 7, 11], [1.0, 1.0, 1.0, 1.0], I1, k1),
                            ([2, 4, 8, 10], [1.0, -1.0, 1.0, -1.0], I2, k2)):
        EI = E * I
        F = np.empty((2, 2))
        F[0, 0] = np.sum(ws * (L - x) ** 2 / EI)
        F[0, 1] = F[1, 0] = np.sum(ws * (L - x) / EI)
        F[1, 1] = np.sum(ws / EI)
        if not (k == 0.0 or k >= 1e8 or G == 0.0):
            F[0, 0] += np.sum(ws / (k * G * A))
        kb = R.T @ np.linalg.inv(F) @ R
        f = np.asarray(flip)
        K[np.ix_(idx, idx)] += kb * np.outer(f, f)
    mu = rho * A + nsm
    mu_t = rho * (I1 + I2)
    if coupled:
        xi = s
        N = np.stack([1 - 3 * xi**2 + 2 * xi**3, L * (xi - 2 * xi**2 + xi**3),
                      3 * xi**2 - 2 * xi**3, L * (-xi**2 + xi**3)], axis=1)
        mb = np.einsum("q,qa,qb->ab", ws * mu, N, N)
        for idx, flip in (([1, 5, 7, 11], [1.0, 1.0, 1.0, 1.0]),
                          ([2, 4, 8, 10], [1.0, -1.0, 1.0, -1.0])):
            M[np.ix_(idx, idx)] += mb * np.outer(flip, flip)
        Nl = np.stack([1 - xi, xi], axis=1)
        M[np.ix_([0, 6], [0, 6])] += np.einsum("q,qa,qb->ab", ws * mu, Nl, Nl)
        M[np.ix_([3, 9], [3, 9])] += np.einsum("q,qa,qb->ab", ws * mu_t, Nl, Nl)
    else:
        ma, mbb = np.sum(ws * mu * (1 - s)), np.sum(ws * mu * s)
        for i in (0, 1, 2):
            M[i, i] = ma
            M[i + 6, i + 6] = mbb
        if lumped_torsion:
            M[3, 3] = np.sum(ws * mu_t * (1 - s))
            M[9, 9] = np.sum(ws * mu_t * s)
    return 0.5 * (K + K.T), M
