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


def skew(v: np.ndarray) -> np.ndarray:
    """Cross-product matrix: skew(a) @ b = a x b."""
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


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


def shear_parameter(E: float, I: float, k: float, G: float, A: float, L: float) -> float:
    """phi = 12 E I / (k G A L^2); zero for no shear flexibility (k = 0 or blank/1e8, G = 0)."""
    if k == 0.0 or k >= 1e8 or G == 0.0 or A == 0.0:
        return 0.0
    return 12.0 * E * I / (k * G * A * L * L)


def _bending_stiffness(EI: float, L: float, phi: float) -> np.ndarray:
    c = EI / (L**3 * (1.0 + phi))
    return c * np.array([
        [12.0, 6.0 * L, -12.0, 6.0 * L],
        [6.0 * L, (4.0 + phi) * L * L, -6.0 * L, (2.0 - phi) * L * L],
        [-12.0, -6.0 * L, 12.0, -6.0 * L],
        [6.0 * L, (2.0 - phi) * L * L, -6.0 * L, (4.0 + phi) * L * L]])


def _bending_mass(mu: float, L: float, phi: float) -> np.ndarray:
    d = (1.0 + phi) ** 2
    m11 = (13.0 / 35 + 7.0 / 10 * phi + phi * phi / 3) / d
    m12 = (11.0 / 210 + 11.0 / 120 * phi + phi * phi / 24) * L / d
    m13 = (9.0 / 70 + 3.0 / 10 * phi + phi * phi / 6) / d
    m14 = (13.0 / 420 + 3.0 / 40 * phi + phi * phi / 24) * L / d
    m22 = (1.0 / 105 + phi / 60 + phi * phi / 120) * L * L / d
    m24 = (1.0 / 140 + phi / 60 + phi * phi / 120) * L * L / d
    return mu * L * np.array([
        [m11, m12, m13, -m14],
        [m12, m22, m14, -m24],
        [m13, m14, m11, -m12],
        [-m14, -m24, -m12, m22]])


_PLANE1 = np.array([1, 5, 7, 11])   # v1, theta_z1, v2, theta_z2
_PLANE2 = np.array([2, 4, 8, 10])   # w1, theta_y1, w2, theta_y2
_FLIP2 = np.array([1.0, -1.0, 1.0, -1.0])  # theta_y = -dw/dx


def beam_local_matrices(L, E, G, A, I1, I2, J, mu, k1, k2, coupled: bool,
                        lumped_torsion: bool = False):
    """Local 12 x 12 stiffness and mass of a prismatic beam (mu = mass per length).

    ``lumped_torsion`` puts half the torsional mass moment rho (I1 + I2) L on each end in the
    lumped mass (CBEAM, as NASTRAN does); CBAR's lumped mass has no rotational inertia.
    """
    K = np.zeros((12, 12))
    ax = E * A / L * np.array([[1.0, -1.0], [-1.0, 1.0]])
    K[np.ix_([0, 6], [0, 6])] = ax
    K[np.ix_([3, 9], [3, 9])] = G * J / L * np.array([[1.0, -1.0], [-1.0, 1.0]])
    phi1 = shear_parameter(E, I1, k1, G, A, L)
    phi2 = shear_parameter(E, I2, k2, G, A, L)
    K[np.ix_(_PLANE1, _PLANE1)] = _bending_stiffness(E * I1, L, phi1)
    K[np.ix_(_PLANE2, _PLANE2)] = _FLIP2[:, None] * _bending_stiffness(E * I2, L, phi2) * _FLIP2
    M = np.zeros((12, 12))
    rho_ip = 0.0 if A == 0.0 else mu / A * (I1 + I2)
    if coupled:
        lin = L / 6.0 * np.array([[2.0, 1.0], [1.0, 2.0]])
        M[np.ix_([0, 6], [0, 6])] = mu * lin
        M[np.ix_([3, 9], [3, 9])] = rho_ip * lin
        M[np.ix_(_PLANE1, _PLANE1)] = _bending_mass(mu, L, phi1)
        M[np.ix_(_PLANE2, _PLANE2)] = _FLIP2[:, None] * _bending_mass(mu, L, phi2) * _FLIP2
    else:
        M[[0, 1, 2, 6, 7, 8], [0, 1, 2, 6, 7, 8]] = mu * L / 2.0
        if lumped_torsion:
            M[[3, 9], [3, 9]] = rho_ip * L / 2.0
    return K, M


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
