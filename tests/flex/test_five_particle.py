"""TM-2020-5008164 Appendix A.3 five-particle example: the four comparisons of Table A1.

The deck (data/five_particle.dat) holds five CONM2 masses m = 2, four CELAS springs k = 1 on
component 1 and SPC1 on the unused DOFs. Table A1 gives the order of magnitude of the
differences between the original system and the normalized component mode (NCM) system:
comparisons 1, 2 and 4 at the 1e-16 level (round-off), comparison 3 (truncated, highest
fixed-base mode removed) 1e-3 - 1e-4 in frequency and 1e-2 - 1e-3 in mode-shape elements.
"""

import os

import numpy as np
import pytest
import scipy.linalg as sla
from numpy.testing import assert_allclose

from dynamics.flex.assembly import assemble
from dynamics.flex.bulk_data import read_bulk_data
from dynamics.flex.component_modes import (constrained_modes, craig_bampton,
                                           normalized_component_modes)
from dynamics.flex.modes import EigenSolution

ROUND_OFF = 1e-14   # "1e-16 level": a few ulps of O(1) numbers after several factorizations


@pytest.fixture(scope="module")
def system(request):
    deck = os.path.join(os.path.dirname(__file__), "data", "five_particle.dat")
    sm = assemble(read_bulk_data(deck))
    K = sm.stiffness_f().toarray()
    M = sm.mass_f().toarray()
    return K, M, sm


def _align(a, b):
    """Flip the signs of the columns of b to match a (mode shapes are defined up to sign)."""
    s = np.sign(np.einsum("ij,ij->j", a, b))
    s[s == 0] = 1.0
    return b * s


def _ncm_system(K, M, n_fixed):
    cb = craig_bampton(K, M, np.array([0]), n_modes=n_fixed)
    # the one rigid-body motion along the springs: every particle moves by the same amount
    modes = normalized_component_modes(cb, np.ones((5, 1)))
    rigid, flex, split = modes.rigid, modes.flexible, modes.split
    assert split.n_rigid == 1 and len(modes.quasi_static.eigenvalues) == 0
    return rigid, flex


def test_deck_reproduces_the_matrices_of_eq_A31(system):
    K, M, sm = system
    k_ref = np.diag([1.0, 2, 2, 2, 1]) - np.diag(np.ones(4), 1) - np.diag(np.ones(4), -1)
    assert_allclose(K, k_ref, atol=0)
    assert_allclose(M, 2.0 * np.eye(5), atol=0)
    assert list(sm.f_dofs) == [0, 6, 12, 18, 24]      # component 1 of grids 1..5


def _original_free_free(K, M):
    lam, vec = sla.eigh(K, M)
    return lam[1:], vec[:, 1:]                          # rigid mode removed


def _original_fixed_base(K, M):
    lam, vec = sla.eigh(K[1:, 1:], M[1:, 1:])
    return lam, np.vstack([np.zeros((1, 4)), vec])


def test_comparison_1_free_free_without_reduction(system):
    K, M, _ = system
    lam, vec = _original_free_free(K, M)
    rigid, flex = _ncm_system(K, M, n_fixed=4)
    assert len(rigid.eigenvalues) == 1
    df = np.abs(np.sqrt(flex.eigenvalues) - np.sqrt(lam)).max()
    dv = np.abs(_align(vec, flex.vectors) - vec).max()
    print(f"comparison 1: max |d omega| = {df:.2e} rad/s, max |d Pi| = {dv:.2e}")
    assert df < ROUND_OFF and dv < ROUND_OFF


def test_comparison_2_fixed_base_without_reduction(system):
    K, M, _ = system
    lam, vec = _original_fixed_base(K, M)
    rigid, flex = _ncm_system(K, M, n_fixed=4)
    allm = np.hstack([rigid.vectors, flex.vectors])
    lam_n = np.concatenate([rigid.eigenvalues, flex.eigenvalues])
    con = constrained_modes(allm, np.diag(lam_n), np.eye(len(lam_n)), np.array([0]))
    df = np.abs(np.sqrt(con.eigenvalues) - np.sqrt(lam)).max()
    dv = np.abs(_align(vec, con.vectors) - vec).max()
    print(f"comparison 2: max |d omega| = {df:.2e} rad/s, max |d Pi| = {dv:.2e}")
    assert df < ROUND_OFF and dv < ROUND_OFF


def test_comparison_3_free_free_truncated_differs_as_in_table_A1(system):
    K, M, _ = system
    lam, vec = _original_free_free(K, M)
    rigid, flex = _ncm_system(K, M, n_fixed=3)       # highest fixed-base mode removed
    assert len(flex.eigenvalues) == 3
    df = np.abs(np.sqrt(flex.eigenvalues) - np.sqrt(lam[:3]))
    dv = np.abs(_align(vec[:, :3], flex.vectors) - vec[:, :3]).max()
    print(f"comparison 3: |d omega| = {df} rad/s, max |d Pi| = {dv:.2e}")
    # Table A1: 1e-3 - 1e-4 (frequency), 1e-2 - 1e-3 (mode-shape elements)
    assert 1e-5 <= df.max() < 1e-2
    assert 1e-4 <= dv < 1e-1
    assert np.all(np.sqrt(flex.eigenvalues) >= np.sqrt(lam[:3]) - ROUND_OFF)  # Rayleigh-Ritz


def test_comparison_4_fixed_base_truncated_is_exact(system):
    K, M, _ = system
    lam, vec = _original_fixed_base(K, M)
    rigid, flex = _ncm_system(K, M, n_fixed=3)
    allm = np.hstack([rigid.vectors, flex.vectors])
    lam_n = np.concatenate([rigid.eigenvalues, flex.eigenvalues])
    con = constrained_modes(allm, np.diag(lam_n), np.eye(len(lam_n)), np.array([0]))
    assert len(con.eigenvalues) == 3
    df = np.abs(np.sqrt(con.eigenvalues) - np.sqrt(lam[:3])).max()
    dv = np.abs(_align(vec[:, :3], con.vectors) - vec[:, :3]).max()
    print(f"comparison 4: max |d omega| = {df:.2e} rad/s, max |d Pi| = {dv:.2e}")
    assert df < ROUND_OFF and dv < ROUND_OFF


def test_ncm_modes_are_mass_normalized_and_diagonalize_K(system):
    K, M, _ = system
    rigid, flex = _ncm_system(K, M, n_fixed=3)
    P = flex.vectors
    assert_allclose(P.T @ M @ P, np.eye(3), atol=ROUND_OFF)                 # eq. A.2.14
    assert_allclose(P.T @ K @ P, np.diag(flex.eigenvalues), atol=ROUND_OFF)  # eq. A.2.15
    assert isinstance(flex, EigenSolution)
