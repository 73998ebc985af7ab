"""fem2modal products on the seed decks: modal-integral identities, residual vectors,
HDF5 and OP4 round trips, damping, lumped-mass separation."""

import os

import numpy as np
import pytest
import scipy.sparse as sp
from numpy.testing import assert_allclose, assert_array_equal

import decks
from dynamics.flex.assembly import assemble
from dynamics.flex.body_file import read_body_file, write_body_file
from dynamics.flex.bulk_data import read_bulk_data
from dynamics.flex.modal_integrals import flexible_body_mass_matrix
from dynamics.flex.op4 import read_op4_matrices, write_op4_matrices
from dynamics.flex.pipeline import Fem2ModalOptions, fem2modal


def test_simple_beam_seed_deck_loads_and_reports_cards(data_dir):
    with pytest.warns(UserWarning, match="EIGRL"):
        body = fem2modal(os.path.join(data_dir, "SimpleBeam.dat"),
                         Fem2ModalOptions(n_modes=4))
    report = " ".join(body.card_report)
    for name in ("CBEAM x9", "GRID x11", "SPOINT", "QSET1", "EIGRL"):
        assert name in report
    assert body.reference_grid == 11                      # PARAM GRDPNT 11
    assert_allclose(body.mass, 8000.0 * 1.5625e-2 * 9.0, rtol=1e-14)
    assert_allclose(body.cm_offset, 0.0, atol=1e-12)      # grid 11 is the beam's centre
    assert body.n_rigid_modes_removed == 6


@pytest.mark.parametrize("deck", ["SimpleBeam.dat", "single_length_beam.dat"])
def test_mass_normalized_free_free_modes_have_zero_p1_E0_F0(data_dir, deck):
    """TM Section 7.2: with Pi' M Pi = I the integrals p1, E0 and F0 vanish (lumped mass)."""
    import warnings
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        body = fem2modal(os.path.join(data_dir, deck),
                         Fem2ModalOptions(n_modes=8, modal_integrals=True))
    mi = body.modal_integrals
    # the node masses are the lumped mass matrix the modes were computed with, so these are
    # M-orthogonality of flexible and rigid modes: zero to round-off relative to O(sqrt(m) L).
    # SimpleBeam (60 DOFs) is solved by LAPACK, the 101-grid beam (606 DOFs) by ARPACK
    # shift-invert Lanczos whose vectors are M-orthogonal to ~1e-11 relative: bound 1e-10.
    scale = np.sqrt(body.mass) * np.abs(body.grid_positions).max()
    assert np.abs(mi.p1).max() * mi.mass < 1e-10 * scale
    assert np.abs(mi.E0).max() < 1e-10 * scale
    assert np.abs(mi.F0).max() < 1e-10 * scale
    assert_allclose(mi.E0, mi.mass * mi.p1, atol=1e-12 * scale)
    assert_allclose(mi.G0, np.eye(8), atol=1e-12)           # G0 = Pi' M_lumped Pi = I
    assert_allclose(mi.J2, mi.J2.transpose(1, 0, 3, 2), atol=1e-12 * np.abs(mi.J2).max())
    assert_allclose(mi.mass, body.mass, rtol=1e-13)
    assert_allclose(mi.J0, body.inertia, rtol=1e-12, atol=1e-12 * np.abs(body.inertia).max())
    assert_allclose(mi.p0, body.cm_offset, atol=1e-12)


def test_fem_modal_integrals_match_brute_force_mass_matrix(data_dir):
    """E.2.6 from the pipeline's integrals = Y' M_nd Y node by node (E.1.34), random eta."""
    from test_modal_integrals import brute_force_mass_matrix
    import warnings
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        body = fem2modal(os.path.join(data_dir, "SimpleBeam.dat"),
                         Fem2ModalOptions(n_modes=5, modal_integrals=True))
    rng = np.random.default_rng(7)
    for _ in range(3):
        eta = rng.normal(scale=1e-2, size=5)
        ref = brute_force_mass_matrix(body.node_mass, body.node_cm_offset, body.node_inertia,
                                      body.grid_positions, body.rotation_shapes,
                                      body.translation_shapes, eta)
        got = flexible_body_mass_matrix(body.modal_integrals, eta)
        assert_allclose(got, ref, rtol=0, atol=1e-12 * np.abs(ref).max())


def _static_tip(body, K_full_solution_dof):
    """Static response of the modal model to a unit load at the residual DOF (grid, comp)."""
    gid, comp = K_full_solution_dof
    Pi = body.mode_shape(gid)
    row = {1: 3, 2: 4, 3: 5, 4: 0, 5: 1, 6: 2}[comp]      # [T; R] component -> [R; T] row
    f_modal = Pi[row]                                     # Pi' P for a unit load
    q = f_modal / (2 * np.pi * body.frequencies_hz) ** 2
    return Pi[row] @ q


def test_residual_vectors_recover_the_static_tip_deflection(write_deck):
    """FModal paper Fig. 10: k modes + residual vectors vs k + r modes vs the full FE solution."""
    ne = 40
    text = decks.beam_deck(ne, 2.0, coupled=True, clamp_root=True, with_header=True)
    deck = write_deck(text)
    tip = ne + 1
    sm = assemble(read_bulk_data(deck))
    K = sm.stiffness_f().tocsc()
    f = np.zeros(K.shape[0])
    f[sm.f_index(tip, 3, "tip")] = 1.0
    exact = sp.linalg.spsolve(K, f)[sm.f_index(tip, 3, "tip")]
    k = 4
    with_rv = fem2modal(deck, Fem2ModalOptions(n_modes=k, residual=[(tip, [3])]))
    plain = fem2modal(deck, Fem2ModalOptions(n_modes=k + with_rv.n_residual_vectors))
    assert with_rv.n_residual_vectors == 1 and with_rv.n_modes == k + 1
    e_rv = abs(_static_tip(with_rv, (tip, 3)) - exact) / abs(exact)
    e_plain = abs(_static_tip(plain, (tip, 3)) - exact) / abs(exact)
    print(f"tip deflection: exact {exact:.9e}; relative error k+rv {e_rv:.2e}, "
          f"k+r modes {e_plain:.2e}")
    # exact for loads in span(P) up to round-off: the clamped 40-element steel beam has
    # cond(K) ~ 1e8, so ~1e-8 relative is the attainable accuracy of any static solution here
    assert e_rv < 1e-8
    assert e_plain > 1e-4          # truncated modes miss the static residual
    assert e_plain > 1e4 * e_rv
    assert_allclose(with_rv.modal_mass, np.eye(k + 1), atol=1e-12)
    assert_allclose(with_rv.modal_stiffness, np.diag((2 * np.pi * with_rv.frequencies_hz) ** 2),
                    rtol=0, atol=1e-10 * with_rv.modal_stiffness.max())


def test_residual_vectors_for_a_free_body_use_inertia_relief(data_dir):
    import warnings
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        body = fem2modal(os.path.join(data_dir, "single_length_beam.dat"),
                         Fem2ModalOptions(n_modes=4, residual=[(101, [3]), (51, [2])]))
    assert body.n_residual_vectors == 2
    assert_allclose(body.modal_mass, np.eye(6), atol=1e-12)
    # residual vectors carry no rigid-body motion: momentum sum m gamma = 0 (lumped mass)
    mom = np.einsum("j,jak->ak", body.node_mass, body.translation_shapes)
    assert np.abs(mom).max() < 1e-10 * np.sqrt(body.mass)


def _assert_bodies_equal(a, b):
    from dataclasses import fields
    for f in fields(a):
        va, vb = getattr(a, f.name), getattr(b, f.name)
        if f.name in ("modal_integrals", "point_mass_integrals"):
            assert va.arrays().keys() == vb.arrays().keys()
            for k, arr in va.arrays().items():
                assert_array_equal(arr, vb.arrays()[k], err_msg=k)
        elif f.name == "craig_bampton":
            for g in ("frequencies_hz", "mass", "stiffness", "uset"):
                assert_array_equal(getattr(va, g), getattr(vb, g))
        elif f.name in ("gset", "fset"):
            for g in ("mass", "stiffness"):
                assert (getattr(va, g) != getattr(vb, g)).nnz == 0
            assert_array_equal(va.uset, vb.uset)
        elif f.name == "child_bodies":
            assert len(va) == len(vb)
            for ca, cb in zip(va, vb):
                assert (ca.element_id, ca.grid_id, ca.mass) == (cb.element_id, cb.grid_id, cb.mass)
                assert_array_equal(ca.cm_offset, cb.cm_offset)
                assert_array_equal(ca.inertia, cb.inertia)
        elif isinstance(va, np.ndarray):
            assert va.dtype == vb.dtype or va.dtype.kind == vb.dtype.kind, f.name
            assert_array_equal(va, vb, err_msg=f.name)
        else:
            assert va == vb, f.name


def test_hdf5_round_trip_is_exact(data_dir, tmp_path, write_deck):
    extra = "CONM2,900,9,,25.0,0.1,0.2,0.0\n,1.0,0.1,2.0,0.0,0.0,3.0"
    deck = write_deck(decks.beam_deck(8, 2.0, card="CBEAM", extra=extra))
    body = fem2modal(deck, Fem2ModalOptions(
        n_modes=3, aset=[(1, [1, 2, 3, 4, 5, 6])], residual=[(5, [3])], modal_integrals=True,
        separate_lumped=True, damping=0.02, write_gset=True, write_fset=True,
        write_modal_matrix=True))
    path = tmp_path / "body.h5"
    write_body_file(path, body)
    back = read_body_file(path)
    _assert_bodies_equal(body, back)
    assert back.translation_shapes.dtype == np.float64
    assert back.craig_bampton is not None and len(back.child_bodies) == 1


def test_op4_round_trip_through_pynastran(data_dir, tmp_path):
    import warnings
    deck = os.path.join(data_dir, "SimpleBeam.dat")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sm = assemble(read_bulk_data(deck))
        op4 = tmp_path / "simplebeam.op4"
        write_op4_matrices(op4, {"KGG": sm.stiffness_g, "MGG": sm.mass_g})
        mats = read_op4_matrices(op4)
        assert (mats["KGG"] != sm.stiffness_g).nnz == 0     # bit-exact
        assert (mats["MGG"] != sm.mass_g).nnz == 0
        a = fem2modal(deck, Fem2ModalOptions(n_modes=6, modal_integrals=True))
        b = fem2modal(deck, Fem2ModalOptions(n_modes=6, modal_integrals=True, op4=str(op4)))
    assert_allclose(b.frequencies_hz, a.frequencies_hz, rtol=1e-12)
    assert_allclose(b.mass, a.mass, rtol=1e-14)
    assert_allclose(np.abs(b.translation_shapes), np.abs(a.translation_shapes), atol=1e-9)


def test_modal_damping_uniform_ratio(write_deck):
    deck = write_deck(decks.beam_deck(6, 2.0))
    body = fem2modal(deck, Fem2ModalOptions(n_modes=4, damping=0.01))
    omega = 2 * np.pi * body.frequencies_hz
    assert_allclose(body.modal_damping, np.diag(2 * 0.01 * omega), rtol=1e-15)
    per_mode = fem2modal(deck, Fem2ModalOptions(n_modes=4, damping=[0.01, 0.02, 0.03, 0.04]))
    assert_allclose(np.diag(per_mode.modal_damping), 2 * np.array([1, 2, 3, 4]) * 0.01 * omega)


def test_separate_lumped_masses_become_child_bodies(write_deck):
    conm = "CONM2,900,4,,25.0,0.0,0.3,0.0\n,1.0,0.0,2.0,0.0,0.0,3.0"
    with_mass = write_deck(decks.beam_deck(6, 2.0, extra=conm), "a.dat")
    without = write_deck(decks.beam_deck(6, 2.0), "b.dat")
    sep = fem2modal(with_mass, Fem2ModalOptions(n_modes=4, separate_lumped=True))
    bare = fem2modal(without, Fem2ModalOptions(n_modes=4))
    full = fem2modal(with_mass, Fem2ModalOptions(n_modes=4))
    assert_allclose(sep.frequencies_hz, bare.frequencies_hz, rtol=1e-12)
    assert_allclose(sep.mass, bare.mass, rtol=1e-14)
    assert_allclose(full.mass, bare.mass + 25.0, rtol=1e-14)
    (child,) = sep.child_bodies
    assert (child.element_id, child.grid_id, child.mass) == (900, 4, 25.0)
    assert_allclose(child.cm_offset, [0.0, 0.3, 0.0])
    assert_allclose(child.inertia, np.diag([1.0, 2.0, 3.0]))
