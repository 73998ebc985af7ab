"""Rigid-body mass properties about a reference point (NASTRAN's grid point weight generator).

With D (g-set x 6) the rigid-body displacement of every grid for unit translations and
rotations about the reference point (u_j = t + theta x (x_j - x_ref), rotated into each grid's
CD frame), M0 = D' M_gg D is the 6 x 6 rigid-body mass in ``[T; R]`` order:
``[[m I, -m p~], [m p~, J_ref]]`` with p the centre-of-mass offset from the reference point and
J_ref the inertia about it (TM-2020-5008164 eqs. E.2.3-E.2.4 for the undeformed body: m(k),
p_0^k and J_0^k). Exact for any mass matrix, consistent or lumped.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp



@dataclass
class RigidBodyProperties:
    """mass [kg]; cm_offset [m] from the reference point; inertia [kg m^2] about it; basic axes."""

    mass: float
    cm_offset: np.ndarray
    inertia: np.ndarray
    reference_point: np.ndarray
    reference_grid: int


def rigid_body_displacements(positions: np.ndarray, reference: np.ndarray,
                             cd_rotation: np.ndarray) -> sp.csr_matrix:
    """D (6n x 6), g-set rigid-body displacements for [tx, ty, tz, rx, ry, rz] about ``reference``."""
    n = len(positions)
    D = np.zeros((n, 6, 6))
    d = positions - reference
    for a in range(3):
        e = np.zeros(3)
        e[a] = 1.0
        D[:, :3, a] = cd_rotation.transpose(0, 2, 1) @ e
        D[:, :3, 3 + a] = np.einsum("nji,nj->ni", cd_rotation, np.cross(e, d))
        D[:, 3:, 3 + a] = cd_rotation.transpose(0, 2, 1) @ e
    return sp.csr_matrix(D.reshape(6 * n, 6))


def rigid_body_mass_properties(mass_g, positions, cd_rotation, reference_point,
                               reference_grid: int = 0) -> RigidBodyProperties:
    D = rigid_body_displacements(positions, reference_point, cd_rotation)
    M0 = np.asarray((D.T @ (mass_g @ D)).todense())
    M0 = 0.5 * (M0 + M0.T)
    m = float(np.trace(M0[:3, :3]) / 3.0)
    if m <= 0.0:
        raise ValueError("zero-mass model: rigid-body mass is not positive")
    mp = M0[3:, :3]
    p = np.array([mp[2, 1] - mp[1, 2], mp[0, 2] - mp[2, 0], mp[1, 0] - mp[0, 1]]) / (2.0 * m)
    return RigidBodyProperties(mass=m, cm_offset=p, inertia=M0[3:, 3:].copy(),
                               reference_point=np.asarray(reference_point, float),
                               reference_grid=int(reference_grid))
