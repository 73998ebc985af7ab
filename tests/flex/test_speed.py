"""A 100,000-DOF shell model through fem2modal against one bare scipy eigsh on the same
matrices (issue 16: "a 100,000-DOF model reduces in seconds"). Slow: run with -m slow."""

import resource
import time
import warnings

import numpy as np
import pytest
import scipy.sparse.linalg as spla
from numpy.testing import assert_allclose

import decks
from dynamics.flex.assembly import assemble
from dynamics.flex.bulk_data import read_bulk_data
from dynamics.flex.modes import rayleigh_quotients
from dynamics.flex.pipeline import Fem2ModalOptions, fem2modal


@pytest.mark.slow
def test_100k_dof_free_plate_100_modes(write_deck):
    """Free 2 m x 1 m x 5 mm steel plate, 180 x 90 CQUAD4 (16,471 grids, 98,826 DOFs), lumped
    mass (NASTRAN's default: the rotations are massless). 100 flexible modes."""
    n_modes = 100
    text = decks.plate_deck(180, a=2.0, b=1.0, t=0.005, edges="FFFF", coupled=False,
                            in_plane_held=False, ny=90)
    deck = write_deck(text, "plate100k.dat")
    t0 = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        body = fem2modal(deck, Fem2ModalOptions(n_modes=n_modes, write_modal_matrix=True))
    t_pipeline = time.perf_counter() - t0
    peak_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sm = assemble(read_bulk_data(deck))
    K, M = sm.stiffness_f(), sm.mass_f()
    assert K.shape[0] > 95_000
    sigma = -1.0
    t0 = time.perf_counter()
    lam, vec = spla.eigsh(K.tocsc(), k=n_modes + 6, M=M.tocsc(), sigma=sigma, which="LM")
    t_eigsh = time.perf_counter() - t0
    order = np.argsort(lam)
    bare = np.sqrt(lam[order][6:]) / (2 * np.pi)
    bare_rq = np.sqrt(rayleigh_quotients(K, M, vec[:, order[6:]])) / (2 * np.pi)
    print(f"\n{K.shape[0]} DOFs, {n_modes} modes: pipeline {t_pipeline:.1f} s (read, assemble, "
          f"solve, refine, shapes), bare eigsh {t_eigsh:.1f} s, peak RSS {peak_mb:.0f} MB; "
          f"f1 {body.frequencies_hz[0]:.6g} Hz, f100 {body.frequencies_hz[-1]:.6g} Hz")
    # same matrices: ARPACK's eigenvalues and the Rayleigh quotients of its vectors differ
    # from the pipeline's refined ones by up to 1.5e-7 and 3e-7 (measured); the relative
    # residuals ||K x - lambda M x|| / ||K x|| say which is closer
    assert_allclose(body.frequencies_hz, bare, rtol=1e-6)
    assert_allclose(body.frequencies_hz, bare_rq, rtol=1e-6)
    X = body.modal_matrix[sm.f_dofs]
    lam_p = (2 * np.pi * body.frequencies_hz) ** 2

    def residual(V, lam_v):
        KV = K @ V
        return np.linalg.norm(KV - (M @ V) * lam_v, axis=0) / np.linalg.norm(KV, axis=0)
    r_pipeline = residual(X, lam_p)
    r_bare = residual(vec[:, order[6:]], lam[order][6:])
    print(f"relative residuals: pipeline max {r_pipeline.max():.2e}, bare eigsh max "
          f"{r_bare.max():.2e}")
    assert r_pipeline.max() < r_bare.max()
    assert body.n_rigid_modes_removed == 6
    assert t_pipeline < 4 * t_eigsh + 30.0
