"""Card-level checks: coordinate systems, offsets, RBE2, INCLUDE and large field, WTMASS,
CONM1/CONM2, CROD, Timoshenko CBEAM. Each compares two decks that describe the same
structure differently, or one deck against a closed form."""

import numpy as np
import pytest
import scipy.sparse.linalg as spla
from numpy.testing import assert_allclose

import decks
from dynamics.flex.assembly import assemble
from dynamics.flex.bulk_data import read_bulk_data
from dynamics.flex.elements import point_mass_block
from dynamics.flex.pipeline import Fem2ModalOptions, fem2modal

OPT = Fem2ModalOptions(n_modes=8)
# Two decks of the same structure give the same matrices up to the rotations applied:
# agreement to round-off amplified by the eigen-solution, 1e-10 relative.
RTOL = 1e-10


def _align(a, b):
    """b with each mode (last axis) sign-flipped to match a."""
    s = np.sign(np.sum(a.reshape(-1, a.shape[-1]) * b.reshape(-1, b.shape[-1]), axis=0))
    return b * s


def _beam_lines(n, length, grid_fmt, card="CBAR", v="0.0,1.0,0.0", pre=()):
    lines = ["PARAM,COUPMASS,1", "PARAM,GRDPNT,1", *pre]
    for i, x in enumerate(np.linspace(0.0, length, n + 1)):
        lines.append(grid_fmt(i + 1, float(x)))
    lines.append(f"MAT1,1,{decks.E!r},,{decks.NU!r},{decks.RHO!r}")
    lines.append(f"PBAR,10,1,{decks.A!r},{decks.I1!r},{decks.I2!r},{decks.J!r}")
    for i in range(n):
        lines.append(f"{card},{101 + i},10,{i + 1},{i + 2},{v}")
    return lines


def test_cord2c_location_and_displacement_frames(write_deck):
    ref = fem2modal(write_deck(decks.beam_deck(6, 2.0), "x.dat"), OPT)
    # CORD2C 5: origin (1, 2, 3), axes of basic; grids on the ray theta = 30 deg, CP = CD = 5.
    # Orientation vector (0,1,0) in the cylindrical CD frame of GA is the tangential direction.
    lines = ["CORD2C,5,,1.0,2.0,3.0,1.0,2.0,4.0\n,2.0,2.0,3.0"]
    lines += _beam_lines(6, 2.0, lambda g, x: f"GRID,{g},5,{x + 0.5!r},30.0,0.0,5")
    body = fem2modal(write_deck("\n".join(lines) + "\nENDDATA\n", "c.dat"), OPT)
    assert_allclose(body.frequencies_hz, ref.frequencies_hz, rtol=RTOL)
    c, s = np.cos(np.pi / 6), np.sin(np.pi / 6)
    R = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]])
    assert_allclose(body.mass, ref.mass, rtol=1e-14)
    assert_allclose(body.cm_offset, R @ ref.cm_offset, atol=1e-13)
    assert_allclose(body.inertia, R @ ref.inertia @ R.T, atol=1e-13 * ref.inertia.max())
    assert_allclose(body.reference_point, [1 + 0.5 * c, 2 + 0.5 * s, 3.0], atol=1e-14)
    rotated = np.einsum("ab,nbk->nak", R, ref.translation_shapes)
    assert_allclose(_align(rotated, body.translation_shapes), rotated, atol=1e-9)


def test_cord2r_and_cord1r_frames(write_deck):
    ref = fem2modal(write_deck(decks.beam_deck(6, 2.0), "x.dat"), OPT)
    # CORD2R 7 rotated 90 deg about basic z and shifted: local x = basic y
    pre = ["CORD2R,7,,5.0,0.0,0.0,5.0,0.0,1.0\n,5.0,1.0,0.0",
           # CORD1R 8 from grids 91, 92, 93: a displacement frame tilted about x by 45 deg
           "GRID,91,,0.0,0.0,-10.0", "GRID,92,,0.0,-0.70710678118654757,-9.2928932188134521",
           "GRID,93,,1.0,0.0,-10.0", "CORD1R,8,91,92,93", "SPC1,1,123456,91,92,93"]
    lines = _beam_lines(6, 2.0, lambda g, x: f"GRID,{g},7,{x!r},0.0,0.0,8",
                        v="-1.0,0.0,0.0", pre=pre)   # = R (0,1,0): basic -x, CD 8 x axis
    body = fem2modal(write_deck("\n".join(lines) + "\nENDDATA\n", "r.dat"), OPT)
    # the three auxiliary grids are SPC'd and massless, so the beam is the same structure
    assert_allclose(body.frequencies_hz, ref.frequencies_hz, rtol=RTOL)
    R = np.array([[0, -1.0, 0], [1.0, 0, 0], [0, 0, 1.0]])     # basic x -> basic y
    assert_allclose(body.inertia, R @ ref.inertia @ R.T, atol=1e-13 * ref.inertia.max())
    i = np.searchsorted(body.grid_ids, 4)
    rotated = R @ ref.translation_shapes[3]
    assert_allclose(np.abs(body.translation_shapes[i]), np.abs(rotated), atol=1e-9)


def test_beam_offsets_equal_moved_grids(write_deck):
    off = _beam_lines(6, 2.0, lambda g, x: f"GRID,{g},,{x!r},0.0,0.0")
    off = [ln + "\n,,,0.0,0.0,0.05,0.0,0.0,0.05" if ln.startswith("CBAR") else ln for ln in off]
    moved = _beam_lines(6, 2.0, lambda g, x: f"GRID,{g},,{x!r},0.0,0.05")
    a = fem2modal(write_deck("\n".join(off) + "\nENDDATA\n", "o.dat"), OPT)
    b = fem2modal(write_deck("\n".join(moved) + "\nENDDATA\n", "m.dat"), OPT)
    assert_allclose(a.frequencies_hz, b.frequencies_hz, rtol=RTOL)
    assert_allclose(a.cm_offset, [1.0, 0.0, 0.05], atol=1e-14)   # mass lies on the offset axis
    assert_allclose(b.cm_offset, [1.0, 0.0, 0.0], atol=1e-14)


def test_rbe2_joins_two_beams_and_carries_a_mass(write_deck):
    cont = write_deck(decks.beam_deck(8, 2.0, extra="CONM2,900,4,,3.0,0.0,0.3,0.0"), "c.dat")
    lines = _beam_lines(8, 2.0, lambda g, x: f"GRID,{g},,{x!r},0.0,0.0")
    lines = [ln for ln in lines if not ln.startswith("CBAR,105")]
    lines += ["GRID,50,,1.0,0.0,0.0", "CBAR,105,10,50,6,0.0,1.0,0.0",
              "RBE2,700,5,123456,50",                 # coincident grids joined rigidly
              "GRID,60,,0.75,0.3,0.0", "CONM2,900,60,,3.0",
              "RBE2,701,4,123456,60"]                 # mass carried on a rigid arm
    split = write_deck("\n".join(lines) + "\nENDDATA\n", "s.dat")
    a = fem2modal(cont, OPT)
    b = fem2modal(split, OPT)
    assert_allclose(b.frequencies_hz, a.frequencies_hz, rtol=RTOL)
    assert_allclose(b.mass, a.mass, rtol=1e-14)
    assert_allclose(b.inertia, a.inertia, rtol=1e-12)
    i = np.searchsorted(b.grid_ids, 60)
    j = np.searchsorted(b.grid_ids, 4)
    # dependent grid 60 moves as a rigid arm of grid 4: u60 = u4 + theta4 x (x60 - x4)
    arm = np.array([0.0, 0.3, 0.0])
    expect = b.translation_shapes[j] + np.cross(b.rotation_shapes[j].T, arm).T
    assert_allclose(b.translation_shapes[i], expect, atol=1e-12)


def test_include_and_large_field_cards(write_deck, tmp_path):
    ref = fem2modal(write_deck(decks.beam_deck(6, 2.0), "x.dat"), OPT)
    text = decks.beam_deck(6, 2.0)
    grids = [ln for ln in text.splitlines() if ln.startswith("GRID")]
    rest = [ln for ln in text.splitlines() if not ln.startswith("GRID")]
    large = []
    for ln in grids:
        _, gid, _, x, y, z = ln.split(",")
        large.append(f"{'GRID*':<8}{gid:>16}{'':>16}{float(x):>16.9e}{float(y):>16.9e}*G{gid}")
        large.append(f"{'*G' + gid:<8}{float(z):>16.9e}")
    (tmp_path / "grids.inc").write_text("\n".join(large) + "\n")
    main = write_deck("\n".join(["INCLUDE 'grids.inc'"] + rest) + "\n", "main.dat")
    body = fem2modal(main, OPT)
    assert_allclose(body.frequencies_hz, ref.frequencies_hz, rtol=RTOL)
    assert len(body.grid_ids) == 7


def test_wtmass_scales_every_mass(write_deck):
    ref = fem2modal(write_deck(decks.beam_deck(6, 2.0, extra="CONM2,900,3,,2.0"), "a.dat"),
                    OPT)
    scaled = decks.beam_deck(6, 2.0, rho=2 * decks.RHO, wtmass=0.5,
                             extra="CONM2,900,3,,4.0")
    body = fem2modal(write_deck(scaled, "b.dat"), OPT)
    assert_allclose(body.frequencies_hz, ref.frequencies_hz, rtol=RTOL)
    assert_allclose(body.mass, ref.mass, rtol=1e-14)


def test_conm1_equals_conm2(write_deck):
    m, off, Jc = 3.0, np.array([0.1, 0.3, -0.2]), np.diag([0.5, 0.7, 0.9])
    B = point_mass_block(m, off, Jc)
    lower = [B[i, j] for i in range(6) for j in range(i + 1)]
    vals = [repr(float(v)) for v in lower]
    conm1 = ("CONM1,900,4,0," + ",".join(vals[:5]) + "\n," + ",".join(vals[5:13])
             + "\n," + ",".join(vals[13:21]))
    conm2 = "CONM2,900,4,,3.0,0.1,0.3,-0.2\n,0.5,0.0,0.7,0.0,0.0,0.9"
    a = fem2modal(write_deck(decks.beam_deck(6, 2.0, extra=conm1), "a.dat"), OPT)
    b = fem2modal(write_deck(decks.beam_deck(6, 2.0, extra=conm2), "b.dat"), OPT)
    assert_allclose(a.frequencies_hz, b.frequencies_hz, rtol=RTOL)
    assert_allclose(a.inertia, b.inertia, rtol=1e-14)


@pytest.mark.parametrize("coupled,factor", [(False, 2.0), (True, 3.0)])
def test_crod_axial_frequency_closed_form(write_deck, coupled, factor):
    """One CROD, root held: omega^2 = 2 EA/(mu L^2) lumped, 3 EA/(mu L^2) consistent."""
    L, Ar = 1.5, 2e-4
    text = "\n".join(["PARAM,COUPMASS,1" if coupled else "",
                      "GRID,1,,0.0,0.0,0.0", f"GRID,2,,{L!r},0.0,0.0",
                      f"MAT1,1,{decks.E!r},,0.3,{decks.RHO!r}", f"PROD,3,1,{Ar!r},1e-9",
                      "CROD,11,3,1,2", "SPC1,1,123456,1", "SPC1,1,23456,2", "ENDDATA"]) + "\n"
    body = fem2modal(write_deck(text), Fem2ModalOptions(n_modes=1))
    w2 = factor * decks.E * Ar / (decks.RHO * Ar * L**2)
    assert_allclose((2 * np.pi * body.frequencies_hz[0]) ** 2, w2, rtol=1e-12)


def test_timoshenko_cbeam_static_tip_deflection(write_deck):
    """Shear-flexible CBEAM: tip deflection P L^3/(3 E I) + P L/(k G A) for any mesh."""
    k = 0.8
    L = 0.5                                     # short beam: shear matters
    G = decks.E / (2 * (1 + decks.NU))
    for ne in (1, 3):
        text = decks.beam_deck(ne, L, card="CBEAM", clamp_root=True, with_header=True,
                               shear_k=k)
        sm = assemble(read_bulk_data(write_deck(text, f"t{ne}.dat")))
        K = sm.stiffness_f().tocsc()
        f = np.zeros(K.shape[0])
        tip = sm.f_index(ne + 1, 2, "tip")      # plane 1: y deflection, I1
        f[tip] = 1.0
        u = spla.spsolve(K, f)[tip]
        exact = L**3 / (3 * decks.E * decks.I1) + L / (k * G * decks.A)
        assert_allclose(u, exact, rtol=1e-10)


def test_orientation_by_g0_grid_equals_vector(write_deck):
    ref = fem2modal(write_deck(decks.beam_deck(6, 2.0), "x.dat"), OPT)
    text = decks.beam_deck(6, 2.0, extra="GRID,99,,0.3,5.0,0.0\nSPC1,1,123456,99")
    lines = []
    for ln in text.splitlines():
        if ln.startswith("CBAR"):
            f = ln.split(",")
            ln = ",".join(f[:5] + ["99"])        # G0 = 99: v = x(99) - x(GA), in the xy plane
        lines.append(ln)
    body = fem2modal(write_deck("\n".join(lines) + "\n", "g0.dat"), OPT)
    assert_allclose(body.frequencies_hz, ref.frequencies_hz, rtol=RTOL)


def test_deck_aset_and_spc_cards(write_deck):
    """ASET1/ASET in the deck act like --aset; SPC with zero values like SPC1."""
    opt_cli = Fem2ModalOptions(n_modes=3, aset=[(1, [1, 2, 3, 4, 5, 6])])
    a = fem2modal(write_deck(decks.beam_deck(6, 2.0), "a.dat"), opt_cli)
    b = fem2modal(write_deck(decks.beam_deck(6, 2.0, extra="ASET1,123,1\nASET,1,456"),
                             "b.dat"), Fem2ModalOptions(n_modes=3))
    assert_allclose(b.frequencies_hz, a.frequencies_hz, rtol=RTOL)
    assert b.aset.tolist() == a.aset.tolist()
    c1 = fem2modal(write_deck(decks.beam_deck(6, 2.0, clamp_root=True, with_header=True),
                              "c1.dat"), OPT)
    spc = decks.beam_deck(6, 2.0, with_header=True, extra="SPC,1,1,123456,0.0")
    c2 = fem2modal(write_deck(spc, "c2.dat"), OPT)
    assert_allclose(c2.frequencies_hz, c1.frequencies_hz, rtol=RTOL)
    assert c1.n_rigid_modes_removed == 0
