"""Slender beams against Euler-Bernoulli closed forms, and rigid-body mass properties.

Closed forms (e.g. Blevins, Formulas for Natural Frequency and Mode Shape, Table 8-1):
omega_n = (beta_n L)^2 sqrt(E I / (mu L^4)) with beta_n L = 4.7300407448, 7.8532046241, ...
(free-free) and 1.8751040687, 4.6940911330, ... (clamped-free).
The cubic Hermite element with consistent mass converges as h^4 in frequency, with lumped
mass as h^2 (Strang & Fix, An Analysis of the Finite Element Method, sec. 6.3).
"""

import numpy as np
import pytest
from numpy.testing import assert_allclose

import decks
from dynamics.flex.pipeline import Fem2ModalOptions, fem2modal

FREE_FREE = np.array([4.7300407448627, 7.8532046240958, 10.995607838002])
CLAMPED = np.array([1.8751040687120, 4.6940911329742, 7.8547574382376])
L = 2.0
MU = decks.RHO * decks.A


def _plane1_frequencies(body, n):
    """Frequencies [rad/s] of the modes whose translation is in y (plane 1, I1)."""
    ty = np.abs(body.translation_shapes[:, 1, :]).max(axis=0)
    tz = np.abs(body.translation_shapes[:, 2, :]).max(axis=0)
    tx = np.abs(body.translation_shapes[:, 0, :]).max(axis=0)
    sel = (ty > 10 * tz) & (ty > 10 * tx)
    return 2 * np.pi * body.frequencies_hz[sel][:n]


def _errors(write_deck, betas, clamp, coupled, meshes):
    exact = betas**2 * np.sqrt(decks.E * decks.I1 / (MU * L**4))
    errs = []
    for ne in meshes:
        deck = write_deck(decks.beam_deck(ne, L, coupled=coupled, clamp_root=clamp,
                                          with_header=clamp), f"beam{ne}.dat")
        body = fem2modal(deck, Fem2ModalOptions(n_modes=18))
        errs.append(np.abs(_plane1_frequencies(body, len(betas)) - exact) / exact)
    return np.array(errs)


@pytest.mark.parametrize("clamp,betas", [(False, FREE_FREE), (True, CLAMPED)],
                         ids=["free-free", "clamped-free"])
def test_consistent_mass_converges_at_fourth_order(write_deck, clamp, betas):
    meshes = [4, 8, 16, 32]
    errs = _errors(write_deck, betas, clamp, True, meshes)
    rates = np.log2(errs[:-1] / errs[1:])
    print("consistent mass relative errors", errs[:, 0], "rates (mode 1)", rates[:, 0])
    # Hermite beam with consistent mass: eigenvalue error O(h^4); over 16 -> 32 elements the
    # observed rate must be within 0.15 of 4 for the first two modes
    assert np.all(np.abs(rates[-1, :2] - 4.0) < 0.15)
    assert errs[-1, 0] < 1e-6
    assert np.all(errs[-1] > 0)   # consistent mass is an upper bound (Rayleigh-Ritz)


def test_lumped_mass_converges_at_second_order(write_deck):
    meshes = [8, 16, 32, 64]
    errs = _errors(write_deck, CLAMPED, True, False, meshes)
    rates = np.log2(errs[:-1] / errs[1:])
    print("lumped mass relative errors", errs[:, 0], "rates", rates[:, 0])
    assert np.all(np.abs(rates[-1, :2] - 2.0) < 0.15)


@pytest.mark.parametrize("coupled", [True, False], ids=["coupled", "lumped"])
def test_mass_properties_exact_and_inertia_to_lumping_error(write_deck, coupled):
    ne = 10
    h = L / ne
    deck = write_deck(decks.beam_deck(ne, L, card="CBEAM", coupled=coupled, grdpnt=1))
    body = fem2modal(deck, Fem2ModalOptions(n_modes=4))
    m = MU * L
    assert_allclose(body.mass, m, rtol=1e-14)
    assert_allclose(body.cm_offset, [L / 2, 0, 0], rtol=1e-14, atol=1e-15)
    # torsional inertia rho (I1 + I2) L is exact for both mass formulations
    assert_allclose(body.inertia[0, 0], decks.RHO * (decks.I1 + decks.I2) * L, rtol=1e-12)
    exact = m * L**2 / 3.0                              # slender rod about its end
    if coupled:
        # consistent Hermite mass integrates x^2 exactly; it has no rotary inertia
        assert_allclose(body.inertia[1, 1], exact, rtol=1e-12)
    else:
        # lumped: trapezoidal rule of int mu x^2 dx, error mu L h^2 / 6
        assert_allclose(body.inertia[1, 1], exact + MU * L * h**2 / 6.0, rtol=1e-12)
    assert_allclose(body.inertia[1, 1], body.inertia[2, 2], rtol=1e-14)
    off = body.inertia - np.diag(np.diag(body.inertia))
    assert np.abs(off).max() < 1e-14 * body.inertia[1, 1]
