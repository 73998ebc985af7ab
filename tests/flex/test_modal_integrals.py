"""Modal integrals against a brute-force node-by-node evaluation (TM-2020-5008164 App. E)."""

import numpy as np
import pytest
from numpy.testing import assert_allclose

from dynamics.flex.modal_integrals import (flexible_body_mass_matrix, modal_integrals,
                                           point_mass_integrals, skew_batch)


def _random_body(rng, N=7, n=4, point_mass=False):
    m = rng.uniform(0.5, 2.0, N)
    p = np.zeros((N, 3)) if point_mass else rng.normal(scale=0.2, size=(N, 3))
    J = np.zeros((N, 3, 3))
    if not point_mass:
        A = rng.normal(size=(N, 3, 3))
        J = A @ A.transpose(0, 2, 1) * 0.1 - m[:, None, None] * skew_batch(p) @ skew_batch(p)
    l0 = rng.normal(size=(N, 3))
    lam = np.zeros((N, 3, n)) if point_mass else rng.normal(scale=0.3, size=(N, 3, n))
    gam = rng.normal(scale=0.3, size=(N, 3, n))
    return m, p, J, l0, lam, gam


def brute_force_mass_matrix(m, p, J, l0, lam, gam, eta):
    """M_fl = Y' M_nd Y (eq. E.1.34) node by node, with eqs. E.1.1, E.1.3, E.1.17, E.1.29."""
    N, _, n = lam.shape
    Mfl = np.zeros((n + 6, n + 6))
    for j in range(N):
        theta = lam[j] @ eta
        dr = np.eye(3) + skew_batch(theta)            # first-order attitude, eq. E.1.17
        Ju = dr @ J[j] @ dr.T
        pu = dr @ p[j]
        Mnd = np.zeros((6, 6))
        Mnd[:3, :3] = Ju
        Mnd[:3, 3:] = m[j] * skew_batch(pu)
        Mnd[3:, :3] = -m[j] * skew_batch(pu)
        Mnd[3:, 3:] = m[j] * np.eye(3)
        l = l0[j] + gam[j] @ eta                      # deformed position, eq. E.1.1
        phi = np.eye(6)
        phi[:3, 3:] = skew_batch(l)
        Y = np.hstack([np.vstack([lam[j], gam[j]]), phi.T])   # eq. E.1.29
        Mfl += Y.T @ Mnd @ Y
    return Mfl


@pytest.mark.parametrize("point_mass", [False, True])
def test_mass_matrix_matches_brute_force(point_mass):
    rng = np.random.default_rng(3)
    m, p, J, l0, lam, gam = _random_body(rng, point_mass=point_mass)
    mi = modal_integrals(m, p, J, l0, lam, gam)
    for trial in range(5):
        eta = rng.normal(scale=0.5, size=lam.shape[2])
        ref = brute_force_mass_matrix(m, p, J, l0, lam, gam, eta)
        got = flexible_body_mass_matrix(mi, eta)
        # both are sums of O(10) terms of O(1): agreement to round-off, 1e-12 relative
        assert_allclose(got, ref, rtol=0, atol=1e-12 * np.abs(ref).max())


def test_point_mass_specialisation_matches_general_form():
    rng = np.random.default_rng(5)
    m, p, J, l0, lam, gam = _random_body(rng, point_mass=True)
    a = point_mass_integrals(m, l0, gam)
    b = modal_integrals(m, p, J, l0, lam, gam)
    assert a.arrays().keys() == b.arrays().keys()
    for name, arr in a.arrays().items():
        assert_allclose(arr, b.arrays()[name], atol=1e-13, err_msg=name)
    # E.3.1 closed forms
    assert_allclose(a.F1, -np.einsum("j,jrab,jbs->rsa", m,
                                     skew_batch(np.moveaxis(gam, 2, 1)), gam), atol=1e-13)
    assert_allclose(a.J1, -np.einsum("j,jrab,jbc->rac", m, skew_batch(np.moveaxis(gam, 2, 1)),
                                     skew_batch(l0)), atol=1e-13)
    for z in (a.F2, a.E1, a.G1):
        assert not np.any(z)
    assert a.G2 is None                      # identically zero for point masses


def test_symmetries_and_E0_equals_m_p1():
    rng = np.random.default_rng(11)
    mi = modal_integrals(*_random_body(rng))
    assert_allclose(mi.J2, mi.J2.transpose(1, 0, 3, 2), atol=1e-14)   # J2(r,s) = J2(s,r)'
    assert_allclose(mi.G0, mi.G0.T, atol=1e-14)
    Gsum = mi.G1 + mi.G1.transpose(1, 0, 2)
    assert_allclose(Gsum, Gsum.transpose(1, 0, 2), atol=1e-14)
    G2s = mi.G2 + mi.G2.transpose(0, 1, 3, 2)
    assert_allclose(G2s, G2s.transpose(1, 0, 2, 3), atol=1e-13)
    assert_allclose(mi.E0, mi.mass * mi.p1, atol=1e-13)   # eq. E.2.5: E0 = m p1
    assert_allclose(mi.J0, mi.J0.T, atol=1e-14)
