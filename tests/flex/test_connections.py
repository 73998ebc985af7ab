"""RBE3, CBUSH/PBUSH and spherical coordinate systems (CORD2S) against brute-force or equivalent
models."""

import warnings

import numpy as np
import pytest
from numpy.testing import assert_allclose

import decks
from dynamics.flex.assembly import assemble
from dynamics.flex.bulk_data import BulkDataError, read_bulk_data
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


# CBUSH offsets (MSC Nastran 2022.4 QRG, CBUSH remark 9): S along GA-GB (OCID = -1), or the offset
# (S1, S2, S3) from GA along the axes of the rectangular system OCID. Each case is checked against the
# same spring between two coincident grids at the spring point, joined to GA and GB by RBE2s.
GA_XYZ, GB_XYZ = np.array([0.1, -0.2, 0.3]), np.array([1.1, 0.3, 0.1])
BUSH_K = "PBUSH,5,K,1000.0,2000.0,3000.0,400.0,500.0,600.0"
ROTATED = "CORD2R,9,,0.5,0.5,0.5,0.8,0.9,1.3\n,1.7,0.2,0.4"      # an arbitrary rectangular system


def _bush_decks(case):
    """(deck with the offset CBUSH, deck with RBE2-linked coincident grids at the spring point)."""
    common = ["GRID,1,,{!r},{!r},{!r}".format(*map(float, GA_XYZ)),
              "GRID,2,,{!r},{!r},{!r},7".format(*map(float, GB_XYZ)),
              "CORD2R,7,,0.0,0.0,0.0,0.3,-0.4,0.9\n,1.0,1.0,0.0",     # GB's displacement frame, rotated
              "CONM2,1,2,,2.0,,,,,\n,0.3,0.01,0.4,0.02,0.03,0.5", "SPC1,1,123456,1", BUSH_K, ROTATED]
    axis = GB_XYZ - GA_XYZ
    if case == "OCID -1, S 0.2":
        bush = ["CBUSH,7,5,1,2,0.0,1.0,0.0\n,0.2"]
        point = GA_XYZ + 0.2 * axis
    elif case == "OCID 0":
        bush = ["CBUSH,7,5,1,2,,,,0\n,,0,0.3,0.4,-0.2"]
        point = GA_XYZ + np.array([0.3, 0.4, -0.2])
    else:           # OCID 9, element axes from GA -> GB and an orientation vector X (CID blank)
        bush = ["CBUSH,7,5,1,2,0.0,1.0,1.0\n,,9,0.3,0.4,-0.2"]
        from pyNastran.bdf.bdf import BDF
        cord = BDF(debug=None)
        cord.add_cord2r(9, [0.5, 0.5, 0.5], [0.8, 0.9, 1.3], [1.7, 0.2, 0.4])
        point = GA_XYZ + cord.coords[9].beta().T @ np.array([0.3, 0.4, -0.2])
    ex = axis / np.linalg.norm(axis)
    v = np.array([0.0, 1.0, 1.0 if case.startswith("OCID 9") else 0.0])
    ez = np.cross(ex, v) / np.linalg.norm(np.cross(ex, v))
    frame = ["CORD2R,8,,0.0,0.0,0.0,{!r},{!r},{!r}\n,{!r},{!r},{!r}".format(*map(float, np.r_[ez, ex]))]
    cid = 0 if case == "OCID 0" else 8
    linked = ["GRID,3,,{!r},{!r},{!r}".format(*map(float, point)),
              "GRID,4,,{!r},{!r},{!r}".format(*map(float, point)),
              "RBE2,11,1,123456,3", "RBE2,12,2,123456,4", f"CBUSH,7,5,3,4,,,,{cid}"]
    head, tail = ["SOL 103", "CEND", "SPC = 1", "BEGIN BULK"], ["ENDDATA"]
    return ("\n".join(head + common + bush + tail) + "\n",
            "\n".join(head + common + frame + linked + tail) + "\n")


@pytest.mark.parametrize("case", ["OCID -1, S 0.2", "OCID 0", "OCID 9, CID blank"])
def test_cbush_offset_equals_rigid_links_to_a_spring_at_the_offset_point(write_deck, case):
    """GA clamped, GB (rotated displacement frame) carrying a mass: the f-set stiffness (GB's six DOFs)
    of the offset CBUSH equals the RBE2-linked model's to 1e-12 of its largest entry (round-off of
    the two link products), and so do the six frequencies."""
    offset, linked = _bush_decks(case)
    a = _quiet(assemble, read_bulk_data(write_deck(offset, "o.dat")))
    b = _quiet(assemble, read_bulk_data(write_deck(linked, "l.dat")))
    assert_allclose(a.f_dofs, b.f_dofs)
    Ka, Kb = a.stiffness_f().toarray(), b.stiffness_f().toarray()
    assert_allclose(Ka, Kb, rtol=0, atol=1e-12 * np.abs(Kb).max())
    fa = _quiet(fem2modal, write_deck(offset, "o.dat"), Fem2ModalOptions(n_modes=6)).frequencies_hz
    fb = _quiet(fem2modal, write_deck(linked, "l.dat"), Fem2ModalOptions(n_modes=6)).frequencies_hz
    assert_allclose(fa, fb, rtol=1e-12)


def _bush_mass_deck(mass_on_pbush):
    """Two grids with small CONM2s (so every DOF has mass), a CBUSH at S = 0.25 and PARAM WTMASS 0.5;
    the PBUSH's M = 3.0, or the same mass as CONM2s split as the QRG's PBUSH remark 13 says:
    (1 - S) M on GA, S M on GB."""
    lines = ["SOL 103", "CEND", "BEGIN BULK", "PARAM,WTMASS,0.5",
             "GRID,1,,0.0,0.0,0.0", "GRID,2,,1.0,0.2,0.0",
             "CONM2,1,1,,0.5,,,,,\n,0.1,,0.1,,,0.1", "CONM2,2,2,,0.5,,,,,\n,0.1,,0.1,,,0.1",
             "CBUSH,7,5,1,2,0.0,0.0,1.0\n,0.25"]
    if mass_on_pbush:
        lines.append(BUSH_K + "\n,,M,3.0")
    else:
        lines += [BUSH_K, "CONM2,3,1,,2.25", "CONM2,4,2,,0.75"]
    return "\n".join(lines + ["ENDDATA"]) + "\n"


def test_pbush_mass_is_lumped_on_the_grids_as_the_qrg_says(write_deck):
    """PBUSH M equals CONM2s of (1 - S) M on GA and S M on GB (translations only; both scaled by WTMASS):
    the same mass matrix (round-off) and the same modes. Before, PBUSH M was refused."""
    a = _quiet(assemble, read_bulk_data(write_deck(_bush_mass_deck(True), "m.dat")))
    b = _quiet(assemble, read_bulk_data(write_deck(_bush_mass_deck(False), "c.dat")))
    assert_allclose(a.mass_g.toarray(), b.mass_g.toarray(), rtol=0, atol=1e-15)
    assert_allclose(a.mass_lumped_basic.toarray(), b.mass_lumped_basic.toarray(), rtol=0, atol=1e-15)
    assert_allclose(a.mass_g.diagonal()[[0, 6]], 0.5 * np.array([0.5 + 2.25, 0.5 + 0.75]), rtol=1e-15)
    fa = _quiet(fem2modal, write_deck(_bush_mass_deck(True), "m.dat"), Fem2ModalOptions(n_modes=6))
    fb = _quiet(fem2modal, write_deck(_bush_mass_deck(False), "c.dat"), Fem2ModalOptions(n_modes=6))
    assert_allclose(fa.frequencies_hz, fb.frequencies_hz, rtol=1e-12)
    assert_allclose(fa.mass, 0.5 * (1.0 + 3.0), rtol=1e-15)


@pytest.mark.parametrize("bush,cord,message", [
    ("CBUSH,7,5,1,2,0.0,0.0,1.0\n,,3,0.1,0.0,0.0", "CORD2C,3,,0.0,0.0,0.0,0.0,0.0,1.0\n,1.0,0.0,0.0",
     "CBUSH 7: OCID = 3 is a cylindrical system"),
    ("CBUSH,7,5,1,2,0.0,0.0,1.0\n,,0,0.1,0.0,0.0", "", "PBUSH 5: mass M = 3.0 with OCID = 0"),
    ("CBUSH,7,5,1,,,,,0", "", "PBUSH 5: mass M = 3.0 on a CBUSH to ground"),
], ids=["cylindrical OCID", "mass with OCID", "mass to ground"])
def test_unmodelled_cbush_offsets_and_masses_are_refused(write_deck, bush, cord, message):
    text = _bush_mass_deck(True).replace("CBUSH,7,5,1,2,0.0,0.0,1.0\n,0.25", bush)
    if "CORD2C" in cord:
        text = text.replace("ENDDATA", cord + "\nENDDATA").replace(BUSH_K + "\n,,M,3.0", BUSH_K)
    with pytest.raises(BulkDataError, match=message):
        _quiet(assemble, read_bulk_data(write_deck(text)))


# RBE3 UM (MSC Nastran 2022.4 QRG, RBE3 remark 7): the same equations solved for other DOFs.
RBE3_ON_BEAM = ("GRID,50,,1.0,0.0,0.3\nCONM2,60,50,,10.0\n"
                "RBE3,70,,50,123456,1.0,123456,1,3\n,5,7,9")


@pytest.mark.parametrize("um", ["UM,5,123456", "UM,50,123,3,456"], ids=["independent grid", "mixed"])
def test_rbe3_um_keeps_the_constraint_and_the_modes(write_deck, um):
    """The RBE3 above a free beam with the dependent DOFs moved to an independent grid (or split between
    REFGRID and one): the same constrained subspace {u_g = T_gf u_f} (every column of one T_gf is a
    combination of the other's to 1e-12; the columns are O(1)) and the same modes (frequencies to 1e-10,
    the refined eigen-solution's tolerance on equivalent decks; mass properties to 1e-12)."""
    plain = decks.beam_deck(8, 2.0, extra=RBE3_ON_BEAM, grdpnt=None)
    moved = decks.beam_deck(8, 2.0, extra=RBE3_ON_BEAM + f"\n,{um}", grdpnt=None)
    a = _quiet(assemble, read_bulk_data(write_deck(plain, "a.dat")))
    b = _quiet(assemble, read_bulk_data(write_deck(moved, "b.dat")))
    assert len(a.f_dofs) == len(b.f_dofs) and not np.array_equal(a.f_dofs, b.f_dofs)
    Ta, Tb = a.T_gf.toarray(), b.T_gf.toarray()
    fit = np.linalg.lstsq(Ta, Tb, rcond=None)[0]
    assert np.abs(Ta @ fit - Tb).max() < 1e-12
    ra = _quiet(fem2modal, write_deck(plain, "a.dat"), Fem2ModalOptions(n_modes=6))
    rb = _quiet(fem2modal, write_deck(moved, "b.dat"), Fem2ModalOptions(n_modes=6))
    assert_allclose(rb.frequencies_hz, ra.frequencies_hz, rtol=1e-10)
    assert_allclose(rb.mass, ra.mass, rtol=1e-12)
    assert_allclose(rb.cm_offset, ra.cm_offset, rtol=1e-12)


@pytest.mark.parametrize("um,message", [
    ("UM,5,123", "UM lists 3 dependent DOFs, REFC 6"),
    ("UM,2,123456", "UM DOF 1 of grid 2 is neither a REFC component"),
    ("UM,1,12,3,1,5,1,\n,,7,1,9,1", "cannot be solved for the UM DOFs"),
], ids=["count", "not in the element", "singular"])
def test_rbe3_um_that_cannot_hold_the_constraint_is_refused(write_deck, um, message):
    """QRG RBE3 remark 7: one UM DOF per REFC component, all among the element's DOFs, and a
    nonsingular partition (the x translations of grids on the beam's axis and one y translation do not
    determine the six REFC equations)."""
    deck = decks.beam_deck(8, 2.0, extra=RBE3_ON_BEAM + f"\n,{um}", grdpnt=None)
    with pytest.raises(BulkDataError, match=message):
        _quiet(assemble, read_bulk_data(write_deck(deck)))
