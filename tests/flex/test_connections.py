"""RBE3, CBUSH/PBUSH and spherical coordinate systems (CORD2S) against brute-force or equivalent
models."""

import warnings

import numpy as np
import pytest
from numpy.testing import assert_allclose

import decks
from dynamics.flex.assembly import assemble
from dynamics.flex.bulk_data import read_bulk_data
from dynamics.flex.pipeline import Fem2ModalOptions, fem2modal


def _quiet(fn, *a, **k):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return fn(*a, **k)


PLATE_CORNERS = [(11, 0.3, -0.2, 0.1), (12, 1.1, 0.0, -0.1), (13, 0.9, 0.8, 0.2), (14, -0.1, 0.6, 0.0)]


def _rbe3_deck(ref_comps="123456", comps="123", weights=(1.0, 2.0)):
    lines = ["GRID,10,,0.4,0.3,0.5"]
    lines += [f"GRID,{g},,{x!r},{y!r},{z!r}" for g, x, y, z in PLATE_CORNERS]
    lines.append(f"RBE3,5,,10,{ref_comps},{weights[0]!r},{comps},11,12\n,{weights[1]!r},{comps},13,14")
    lines.append("ENDDATA")
    return "\n".join(lines) + "\n"


@pytest.mark.parametrize("comps", ["123", "123456"])
def test_rbe3_reference_motion_is_the_weighted_least_squares_rigid_fit(write_deck, comps):
    """The reference grid's DOFs in T_gf against numpy's lstsq of the rigid-body fit (the MSC
    QRG RBE3 definition; rotation rows weighted by the mean distance squared)."""
    text = _rbe3_deck(comps=comps).replace("ENDDATA", "CONM2,1,11,,1.0\nCONM2,2,12,,1.0\n"
                                           "CONM2,3,13,,1.0\nCONM2,4,14,,1.0\nENDDATA")
    sm = _quiet(assemble, read_bulk_data(write_deck(text)))
    rng = np.random.default_rng(1)
    u_f = rng.standard_normal(len(sm.f_dofs))
    u_g = sm.T_gf @ u_f
    ref = np.array([0.4, 0.3, 0.5])
    rows, rhs, w = [], [], []
    pos = {g: np.array([x, y, z]) for g, x, y, z in PLATE_CORNERS}
    length = np.mean([np.linalg.norm(p - ref) for p in pos.values()])
    for g, weight in ((11, 1.0), (12, 1.0), (13, 2.0), (14, 2.0)):
        i = sorted([10, 11, 12, 13, 14]).index(g)
        d = pos[g] - ref
        S = np.zeros((6, 6))
        S[:3, :3] = np.eye(3)
        S[:3, 3:] = -np.array([[0, -d[2], d[1]], [d[2], 0, -d[0]], [-d[1], d[0], 0]])
        S[3:, 3:] = np.eye(3)
        for c in [int(ch) for ch in comps]:
            rows.append(S[c - 1])
            rhs.append(u_g[6 * i + c - 1])
            w.append(weight * (length**2 if c > 3 else 1.0))
    sw = np.sqrt(np.array(w))
    fit = np.linalg.lstsq(np.array(rows) * sw[:, None], np.array(rhs) * sw, rcond=None)[0]
    assert_allclose(u_g[:6], fit, rtol=1e-12, atol=1e-12 * np.abs(fit).max())


def test_rbe3_carries_a_mass_with_the_exact_rigid_body_properties(write_deck):
    """A 10 kg CONM2 on an RBE3 reference grid above a free CBAR beam: the rigid-body mass
    properties are those of beam + point mass (the RBE3 reproduces rigid motions exactly)."""
    extra = ("GRID,50,,1.0,0.0,0.3\nCONM2,60,50,,10.0\n"
             "RBE3,70,,50,123456,1.0,123456,1,3\n,5,7,9")
    body = _quiet(fem2modal, write_deck(decks.beam_deck(8, 2.0, extra=extra, grdpnt=None)),
                  Fem2ModalOptions(n_modes=4))
    beam_mass = decks.RHO * decks.A * 2.0
    assert_allclose(body.mass, beam_mass + 10.0, rtol=1e-12)
    assert_allclose(body.cm_offset, [1.0, 0.0, 10.0 * 0.3 / (beam_mass + 10.0)], rtol=1e-12)
    assert body.n_rigid_modes_removed == 6


def _bush_or_springs(kind):
    lines = ["PARAM,COUPMASS,1", "GRID,1,,0.0,0.0,0.0", "GRID,2,,0.0,0.0,0.0",
             "CONM2,1,2,,2.0,,,,,\n,0.3,,0.4,,,0.5", "SPC1,1,123456,1"]
    k = [1000.0, 2000.0, 3000.0, 400.0, 500.0, 600.0]
    if kind == "CBUSH":
        lines += ["PBUSH,5,K," + ",".join(repr(v) for v in k), "CBUSH,7,5,1,2,,,,0"]
    else:
        lines += [f"CELAS2,{20 + c},{k[c - 1]!r},1,{c},2,{c}" for c in range(1, 7)]
    return "\n".join(["SOL 103", "CEND", "SPC = 1", "BEGIN BULK"] + lines + ["ENDDATA"]) + "\n"


def test_cbush_between_coincident_grids_equals_six_celas(write_deck):
    a = _quiet(fem2modal, write_deck(_bush_or_springs("CBUSH"), "b.dat"), Fem2ModalOptions(n_modes=6))
    b = _quiet(fem2modal, write_deck(_bush_or_springs("CELAS"), "c.dat"), Fem2ModalOptions(n_modes=6))
    # closed form: sqrt(k / m) for the translations, sqrt(k / J) for the rotations
    exact = np.sort(np.sqrt([1000 / 2, 2000 / 2, 3000 / 2, 400 / 0.3, 500 / 0.4, 600 / 0.5])) \
        / (2 * np.pi)
    assert_allclose(a.frequencies_hz, exact, rtol=1e-12)
    assert_allclose(a.frequencies_hz, b.frequencies_hz, rtol=1e-12)


def test_cbush_on_a_line_equals_rigid_links_to_a_coincident_bush(write_deck):
    """GA-GB 1 m apart along x with S = 0.5 and an orientation vector: the same as RBE2 links
    from each grid to a coincident pair at the midpoint with a CBUSH in CID 0."""
    common = ["GRID,1,,0.0,0.0,0.0", "GRID,2,,1.0,0.0,0.0", "CONM2,1,2,,2.0,,,,,\n,0.3,,0.4,,,0.5",
              "SPC1,1,123456,1", "PBUSH,5,K,1000.0,2000.0,3000.0,400.0,500.0,600.0"]
    line = common + ["CBUSH,7,5,1,2,0.0,1.0,0.0"]
    linked = common + ["GRID,3,,0.5,0.0,0.0", "GRID,4,,0.5,0.0,0.0", "RBE2,8,1,123456,3",
                       "RBE2,9,2,123456,4", "CBUSH,7,5,3,4,,,,0"]
    head = ["SOL 103", "CEND", "SPC = 1", "BEGIN BULK"]
    a = _quiet(fem2modal, write_deck("\n".join(head + line + ["ENDDATA"]) + "\n", "l.dat"),
               Fem2ModalOptions(n_modes=6))
    b = _quiet(fem2modal, write_deck("\n".join(head + linked + ["ENDDATA"]) + "\n", "k.dat"),
               Fem2ModalOptions(n_modes=6))
    assert_allclose(a.frequencies_hz, b.frequencies_hz, rtol=1e-12)


def test_spherical_displacement_frames(write_deck):
    """The beam with every grid's CD in a CORD2S (and one grid located by CP spherical) has the
    frequencies and basic-frame mode shapes of the plain beam. The CBAR orientation is a G0
    grid, since an X vector would be read in GA's (now spherical) CD frame."""
    plain = decks.beam_deck(6, 2.0).replace(",0.0,1.0,0.0", ",99").replace(
        "ENDDATA", "GRID,99,,0.7,5.0,0.0\nSPC1,1,123456,99\nENDDATA")
    ref = _quiet(fem2modal, write_deck(plain, "x.dat"), Fem2ModalOptions(n_modes=5))
    text = plain
    lines = []
    for ln in text.splitlines():
        if ln.startswith("GRID,") and not ln.startswith("GRID,99,"):
            f = ln.split(",")
            ln = ",".join(f[:6]) + ",9"             # CD = 9
        lines.append(ln)
    text = "\n".join(lines).replace("PARAM,COUPMASS,1", "PARAM,COUPMASS,1\n"
                                    "CORD2S,9,,0.3,-1.0,0.5,0.3,-1.0,1.5\n,1.3,-1.0,0.5")
    # grid 7 (x = 2) located in the spherical system: R, theta (deg from z), phi (deg from x)
    p = np.array([2.0, 0.0, 0.0]) - np.array([0.3, -1.0, 0.5])
    r = float(np.linalg.norm(p))
    theta = float(np.degrees(np.arccos(p[2] / r)))
    phi = float(np.degrees(np.arctan2(p[1], p[0])))
    text = text.replace("GRID,7,,2.0,0.0,0.0,9", f"GRID,7,9,{r!r},{theta!r},{phi!r},9")
    body = _quiet(fem2modal, write_deck(text, "s.dat"), Fem2ModalOptions(n_modes=5))
    assert_allclose(body.grid_positions, ref.grid_positions, atol=1e-12)
    assert_allclose(body.frequencies_hz, ref.frequencies_hz, rtol=1e-10)
    assert_allclose(np.abs(body.translation_shapes), np.abs(ref.translation_shapes), atol=1e-8)
