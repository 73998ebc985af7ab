"""Geometric stiffness in the fem2modal pipeline (issue 15): element matrix, axially preloaded beam,
load-case symmetry, body-file layout and version.

* The Hermite element matrix per unit axial force is ``int v'^2 dx`` of the cubic through its end values
  (checked by Gauss quadrature of random cubics: exact to round-off).
* Pinned-pinned uniform beam under an axial preload P (``--preload``, reacted by the SPCs): the exact
  continuous result is ``omega_k^2 = omega0_k^2 (1 - P / (k^2 P_cr))``, ``P_cr = pi^2 EI / L^2``, for
  compression and tension alike (the sine modes diagonalize both operators). The FE model (40 CBAR,
  coupled mass) projected on its own unloaded modes reproduces it to 1e-5 of omega0^2 (measured 2026-11-23:
  7e-7 at |P| = P_cr / 2, 4e-6 at P = 3 P_cr in tension; the
  FE discretization of the ratio is O(h^2) smaller than its terms).
* The rigid-motion cases of a spinning cantilever: every matrix symmetric; tension positive (the centrifugal
  case zz of a beam along x is positive semi-definite).
"""

from __future__ import annotations

import h5py
import numpy as np
import pytest

from dynamics.flex.body_file import read_body_file, write_body_file
from dynamics.flex.geometric_stiffness import (beam_local_geometric_stiffness, hermite_geometric_stiffness,
                                               parse_preload)
from dynamics.flex.pipeline import Fem2ModalOptions, fem2modal

from tests.flex.rotating_beam import rotating_beam_deck

N_ELEMENTS = 40
EI = 1.0  # rotating_beam_deck: E 1e6, I 1e-6


def test_hermite_matrix_is_the_integral_of_the_squared_slope():
    rng = np.random.default_rng(3)
    L = 0.37
    G = hermite_geometric_stiffness(L)
    xg, wg = np.polynomial.legendre.leggauss(4)
    x = 0.5 * L * (xg + 1.0)
    for _ in range(5):
        d = rng.normal(size=4)  # v1, theta1, v2, theta2
        s = x / L
        dv = (d[0] * (-6 * s + 6 * s * s) / L + d[1] * (1 - 4 * s + 3 * s * s)
              + d[2] * (6 * s - 6 * s * s) / L + d[3] * (-2 * s + 3 * s * s))
        assert d @ G @ d == pytest.approx(0.5 * L * np.sum(wg * dv * dv), rel=1e-13)
    K = beam_local_geometric_stiffness(L)
    np.testing.assert_allclose(K, K.T)
    assert np.all(K[[0, 3, 6, 9]] == 0.0)  # no axial terms; no torsion term without a section
    Kt = beam_local_geometric_stiffness(L, 2.5e-3)
    np.testing.assert_array_equal(np.delete(np.delete(Kt - K, [3, 9], 0), [3, 9], 1), 0.0)
    np.testing.assert_allclose(Kt[np.ix_([3, 9], [3, 9])], 2.5e-3 / L * np.array([[1, -1], [-1, 1]]), rtol=1e-15)


def pinned_beam(tmp_path, load):
    extra = ["SPC1,1,1234,1", f"SPC1,1,23,{N_ELEMENTS + 1}"]
    deck = rotating_beam_deck(N_ELEMENTS).replace("ENDDATA", "\n".join(extra) + "\nENDDATA")
    path = tmp_path / "pinned.dat"
    path.write_text(deck)
    return fem2modal(str(path), Fem2ModalOptions(n_modes=10, preloads=[("axial", N_ELEMENTS + 1, 1, load)]))


@pytest.mark.parametrize("ratio", [-0.5, -0.9, 0.5, 3.0])  # P / P_cr: negative = compression
def test_axially_loaded_pinned_beam_follows_the_euler_relation(tmp_path, ratio):
    P_cr = np.pi ** 2 * EI
    body = pinned_beam(tmp_path, ratio * P_cr)  # +x force at the roller end: tension
    gs = body.geometric_stiffness
    assert gs.preload_names == ["axial"] and gs.reaction == "spc"
    K = body.modal_stiffness
    Kp = gs.preload[0]
    # bending modes: those the preload changes (axial and torsion modes carry no transverse slope)
    w0 = np.sqrt(np.diag(K))
    w2 = np.linalg.eigvalsh(K + Kp)
    bending = np.abs(np.diag(Kp)) > 1e-6 * np.abs(np.diag(Kp)).max()
    w0b = np.sort(w0[bending])
    # modes come in (y, z) pairs: k-th pair has k half-waves
    k = np.repeat(np.arange(1, w0b.size // 2 + 1), 2)
    expected = w0b[:k.size] ** 2 * (1.0 + ratio / k ** 2)
    got = np.sort(np.linalg.eigvalsh((K + Kp)[np.ix_(bending, bending)]))[:k.size]
    err = np.abs(got - expected) / (w0b[:k.size] ** 2)
    assert err.max() < 1e-5, err
    assert w2.size == K.shape[0]


def test_spin_cases_are_symmetric_and_centrifugal_tension_stiffens(tmp_path):
    path = tmp_path / "cantilever.dat"
    path.write_text(rotating_beam_deck(20))
    body = fem2modal(str(path), Fem2ModalOptions(n_modes=6, aset=[(1, [1, 2, 3, 4, 5, 6])],
                                                 geometric_stiffness=True))
    gs = body.geometric_stiffness
    assert gs.reaction == "aset" and gs.elements == "CBAR 20"
    for block in (gs.translation, gs.rotation, gs.angular_velocity):
        np.testing.assert_allclose(block, block.transpose(0, 2, 1), atol=1e-12 * np.abs(block).max())
    assert np.linalg.eigvalsh(gs.omega_matrix(2, 2)).min() > -1e-10 * np.abs(gs.omega_matrix(2, 2)).max()
    # a beam along x: spin about x (the case xx) loads nothing along the beam
    assert np.abs(gs.omega_matrix(0, 0)).max() < 1e-9 * np.abs(gs.omega_matrix(2, 2)).max()
    # the centrifugal load of spin about z equals that of spin about y (both pull along x)
    np.testing.assert_allclose(gs.omega_matrix(1, 1), gs.omega_matrix(2, 2), atol=1e-9)


def test_body_file_round_trip_and_version_1_0_still_reads(tmp_path):
    path = tmp_path / "cantilever.dat"
    path.write_text(rotating_beam_deck(10))
    body = fem2modal(str(path), Fem2ModalOptions(n_modes=4, aset=[(1, [1, 2, 3, 4, 5, 6])],
                                                 preloads=[("thrust", 11, 1, -3.0), ("thrust", 6, 3, 0.5)]))
    out = tmp_path / "b.h5"
    write_body_file(out, body)
    back = read_body_file(out)
    assert back.version == "1.2"  # 1.2 (issue 33): Units and OutputFrame groups
    for name in ("translation", "rotation", "angular_velocity", "preload"):
        np.testing.assert_array_equal(getattr(back.geometric_stiffness, name), getattr(body.geometric_stiffness, name))
    assert back.geometric_stiffness.preload_names == ["thrust"]
    assert back.geometric_stiffness.reaction == "aset"
    # a version 1.0 file (no GeometricStiffness group) reads with geometric_stiffness None
    with h5py.File(out, "a") as h5:
        del h5["GeometricStiffness"]
        del h5["FLEXSHELL_BODY_FILE_VERSION"]
        h5.create_dataset("FLEXSHELL_BODY_FILE_VERSION", data="1.0")
    old = read_body_file(out)
    assert old.version == "1.0" and old.geometric_stiffness is None


@pytest.mark.parametrize("text,match", [("thrust:11:7:1", "component"), ("thrust:11:1", "NAME:GRID"),
                                        (":11:1:2", "NAME:GRID"), ("t:x:1:2", "NAME:GRID")])
def test_bad_preload_text_is_refused(text, match):
    with pytest.raises(ValueError, match=match):
        parse_preload(text)


def test_unknown_preload_grid_is_refused(tmp_path):
    path = tmp_path / "cantilever.dat"
    path.write_text(rotating_beam_deck(4))
    with pytest.raises(Exception, match="999"):
        fem2modal(str(path), Fem2ModalOptions(n_modes=2, aset=[(1, [1, 2, 3, 4, 5, 6])],
                                              preloads=[("p", 999, 1, 1.0)]))


def test_axial_tension_stiffens_torsion_by_n_ip_over_a(tmp_path):
    """Torsion term N I_p / (A L) (Przemieniecki eq. 15.53): a bar with both ends held in twist under an axial
    load N has torsional frequencies omega_k^2 = (k pi / L)^2 (GJ + N I_p / A) / (rho I_p) (the axial stress
    on the helical tilt r theta' of the fibres, e.g. Timoshenko & Gere 1961, sec. 5.3), so every torsion mode's
    omega^2 changes by the factor 1 + N I_p / (A G J). Linear-twist elements have discrete-sine torsion modes
    and a geometric matrix proportional to their torsional stiffness: the modal model reproduces the factor to
    round-off (1e-9), and the preload does not couple torsion and bending modes."""
    n = 20
    lines = ["PARAM,COUPMASS,1"] + [f"GRID,{i + 1},,{i / n!r},0.0,0.0" for i in range(n + 1)]
    lines += ["MAT1,1,2.6e6,1.0e6,,1.0", "PBAR,10,1,1.0e-2,2.0e-5,3.0e-5,1.5e-5"]
    lines += [f"CBAR,{101 + i},10,{i + 1},{i + 2},0.0,1.0,0.0" for i in range(n)]
    lines += ["SPC1,1,123456,1", f"SPC1,1,2346,{n + 1}", "ENDDATA"]
    path = tmp_path / "torsion.dat"
    path.write_text("\n".join(lines) + "\n")
    N = 40.0  # tension at the free-axial end
    body = fem2modal(str(path), Fem2ModalOptions(n_modes=12, preloads=[("pull", n + 1, 1, N)]))
    rot = body.rotation_shapes
    torsion = [k for k in range(rot.shape[2]) if np.abs(rot[:, 0, k]).max() > 10 * np.abs(rot[:, 1:, k]).max()]
    assert len(torsion) >= 2
    lam = np.diag(body.modal_stiffness)
    Kp = body.geometric_stiffness.preload[0]
    factor = N * (2.0e-5 + 3.0e-5) / (1.0e-2 * 1.0e6 * 1.5e-5)
    np.testing.assert_allclose(np.diag(Kp)[torsion] / lam[torsion], factor, rtol=1e-9)
    others = [k for k in range(len(lam)) if k not in torsion]
    assert np.abs(Kp[np.ix_(torsion, others)]).max() < 1e-9 * np.abs(Kp[np.ix_(torsion, torsion)]).max()
