"""A flexible body's node: :func:`dynamics.flexible_kernels.node_deformation` (pose, ``Psi``, ``w``, ``w'``: the slots
children hang from) and :func:`~dynamics.flexible_kernels.node_motion` (the same without ``Psi``, with ``Psi
eta_ddot`` from sums over the shape: node outputs), against an independent reference.

Reference (numpy, no shared code): ``phi = lambda eta``, ``R = exp(phi~) R0`` and the left Jacobian ``J_l(phi) =
sum_k phi~^k / (k + 1)!`` by their power series (40 terms: below 1e-17 for |phi| <= 2), ``Psi = [J_l lambda; gamma +
l~ J_l lambda]`` (CONVENTIONS.md, flexible bodies; the node's velocity per unit modal rate at the body origin), and
``w' = (d/dt Psi) eta_dot`` along ``eta(t) = eta + t eta_dot`` by central differences with Richardson extrapolation.
Tolerances: 1e-13 of the largest entry for the closed forms (round-off of sums over 37 modes, the reference's
included), 1e-8 for the differences (truncation ~h^4 and round-off ~eps / h at h = 1e-3 of the motion). Three sizes of
the node's rotation: below the series branch of the SO(3) coefficients (|phi| = 1e-3 < 0.05), above it (0.3) and large
(2 rad).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from dynamics import flexible_kernels as FK


def skew(v):
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


def series(phi, shift):
    """sum_k phi~^k / (k + shift)!: exp (shift 0) and the left Jacobian (shift 1)."""
    total, power = np.zeros((3, 3)), np.eye(3)
    for k in range(40):
        total += power / math.factorial(k + shift)
        power = power @ skew(phi)
    return total


def reference(shape, l0, R0, eta):
    lam, gam = shape[:3], shape[3:]
    phi = lam @ eta
    pos = l0 + gam @ eta
    A = series(phi, 1) @ lam
    return series(phi, 0) @ R0, pos, np.vstack([A, gam + skew(pos) @ A]), phi


def random_node(size, n=37, seed=3):
    rng = np.random.default_rng(seed)
    shape = rng.standard_normal((6, n))
    eta, eta_dot, eta_ddot = rng.standard_normal(n), rng.standard_normal(n), rng.standard_normal(n)
    shape[:3] *= size / np.linalg.norm(shape[:3] @ eta)  # |lambda eta| = size
    R0 = series(rng.standard_normal(3), 0)
    return shape, rng.standard_normal(3), R0, eta, eta_dot, eta_ddot


def deformation(shape, l0, R0, eta, eta_dot):
    n = eta.size
    R, pos, Psi, w, wd, tmp = np.zeros((3, 3)), np.zeros(3), np.zeros((6, n)), np.zeros(6), np.zeros(6), np.zeros((8, 3))
    FK.node_deformation(shape, l0, R0, eta, n, eta_dot, R, pos, Psi, w, wd, tmp)
    return R, pos, Psi, w, wd, tmp[0].copy()


@pytest.mark.parametrize("size", [1e-3, 0.3, 2.0])
def test_node_deformation_and_node_motion_against_the_series_reference(size):
    shape, l0, R0, eta, eta_dot, eta_ddot = random_node(size)
    n = eta.size
    R_ref, pos_ref, Psi_ref, phi_ref = reference(shape, l0, R0, eta)
    R, pos, Psi, w, wd, phi = deformation(shape, l0, R0, eta, eta_dot)
    scale = np.abs(Psi_ref).max()
    np.testing.assert_allclose(R, R_ref, rtol=0, atol=1e-13)
    np.testing.assert_allclose(pos, pos_ref, rtol=0, atol=1e-13 * np.abs(pos_ref).max())
    np.testing.assert_allclose(Psi, Psi_ref, rtol=0, atol=1e-13 * scale)
    np.testing.assert_allclose(phi, phi_ref, rtol=0, atol=1e-13 * size)
    np.testing.assert_allclose(w, Psi_ref @ eta_dot, rtol=0, atol=1e-13 * scale * np.abs(eta_dot).sum())

    # w' = (d/dt Psi(eta + t eta_dot)) eta_dot: central differences at h and 2h, Richardson
    def psi_at(t):
        return reference(shape, l0, R0, eta + t * eta_dot)[2] @ eta_dot

    h = 1e-3
    d1 = (psi_at(h) - psi_at(-h)) / (2 * h)
    d2 = (psi_at(2 * h) - psi_at(-2 * h)) / (4 * h)
    wd_ref = (4 * d1 - d2) / 3
    np.testing.assert_allclose(wd, wd_ref, rtol=0, atol=1e-8 * np.abs(wd_ref).max())

    # node_motion: the same pose, w and w' to the last bit (the same sums), Psi eta_ddot without Psi
    R2, pos2, w2, wd2, psi_acc, tmp = np.zeros((3, 3)), np.zeros(3), np.zeros(6), np.zeros(6), np.zeros(6), np.zeros((8, 3))
    FK.node_motion(shape, l0, R0, eta, n, eta_dot, eta_ddot, R2, pos2, w2, wd2, psi_acc, tmp)
    for mine, theirs in ((R2, R), (pos2, pos), (w2, w), (wd2, wd), (tmp[0], phi)):
        np.testing.assert_array_equal(mine, theirs)
    np.testing.assert_allclose(psi_acc, Psi_ref @ eta_ddot, rtol=0, atol=1e-13 * scale * np.abs(eta_ddot).sum())
    psi_acc[:] = 7.0  # without eta_ddot: left as it is
    FK.node_motion(shape, l0, R0, eta, n, eta_dot, eta_ddot[:0], R2, pos2, w2, wd2, psi_acc, tmp)
    assert (psi_acc == 7.0).all()
    np.testing.assert_array_equal(w2, w)
