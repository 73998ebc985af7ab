"""Cards of delivered decks (issue 33): CMASS1/CMASS2/PMASS, RBAR, RBE1, MPC/MPCADD, PBARL/PBEAML shapes.

Each is checked against an equivalent model or a closed form:
* CMASS2 on components 1-3 of a grid = CONM2 of that mass (no inertia); CMASS1/PMASS = CMASS2; between two
  DOFs the kinetic energy is m (u1' - u2')^2 / 2 (QRG CMASS1); in a rotated CD frame = CONM1 with the
  same 6 x 6 in CID = CD.
* RBAR (CNA = 123456, CMB = 123456) = RBE2; the same rigid link with its six independent DOFs split
  between the ends (CNA = 1234, CNB = 23 for a bar along x) or with CMA/CMB blank = the same model;
  RBE1 with one independent grid = RBE2; with three grids it moves its dependent grid rigidly.
* MPC: the six equations of an RBE2 written as MPCs = the RBE2; selection by case control MPC = n
  through an MPCADD.
* PBARL/PBEAML: NASTRAN's own equivalent PBEAM/PBAR entries (f06 USER INFORMATION MESSAGE 4379 of
  pyNastran's models/aero/fmondsp.f06 (MSC Nastran 2005), models/aero/aerobeam.f06 (NX Nastran),
  models/beam_modes/beam_modes.f06 (MSC)) to their printed 5 digits; BAR's torsion constant against
  Timoshenko & Goodier's table; an I section's A, I1, I2 against the polygon integrals of its outline;
  a CBAR with a PBARL = the same CBAR with a PBAR of the derived values.
"""

import numpy as np
import pytest
from numpy.testing import assert_allclose

import decks
from dynamics.flex.assembly import assemble
from dynamics.flex.bulk_data import BulkDataError, read_bulk_data
from dynamics.flex.pipeline import Fem2ModalOptions, fem2modal
from dynamics.flex.sections import rectangle_torsion_constant, section_properties

RTOL = 1e-10   # equivalent decks: the same matrices up to round-off amplified by the eigen-solution


def _frame(extra, coupled=True):
    """A free CBAR beam along x (grids 1..7) plus ``extra`` lines (free-field)."""
    return decks.beam_deck(6, 2.0, coupled=coupled, extra=extra)


def _modes(write_deck, text, name, n=8, **kw):
    return fem2modal(write_deck(text, name), Fem2ModalOptions(n_modes=n, **kw))


# ----------------------------------------------------------------------------------------- CMASS
def test_cmass_equals_conm2_point_mass(write_deck):
    conm2 = _modes(write_deck, _frame("CONM2,900,4,,3.5"), "conm2.dat")
    cmass2 = _modes(write_deck, _frame("\n".join(f"CMASS2,{900 + c},3.5,4,{c}" for c in (1, 2, 3))), "cmass2.dat")
    cmass1 = _modes(write_deck, _frame("PMASS,77,3.5\n" + "\n".join(f"CMASS1,{900 + c},77,4,{c}" for c in (1, 2, 3))),
                    "cmass1.dat")
    for body in (cmass2, cmass1):
        assert_allclose(body.frequencies_hz, conm2.frequencies_hz, rtol=RTOL)
        assert_allclose(body.mass, conm2.mass, rtol=1e-14)
        assert_allclose(body.inertia, conm2.inertia, rtol=1e-13)
        assert_allclose(body.node_mass, conm2.node_mass, rtol=1e-14)


def test_cmass_between_two_dofs_is_a_relative_mass(write_deck):
    """M = m [[1, -1], [-1, 1]] on (grid 3 T2, grid 5 T3): u' M u = m (u_a - u_b)^2 for any u."""
    text = _frame("CMASS2,900,2.5,3,2,5,3")
    plain = assemble(read_bulk_data(write_deck(_frame(""), "plain.dat")))
    sm = assemble(read_bulk_data(write_deck(text, "cmass.dat")))
    added = (sm.mass_g - plain.mass_g).toarray()
    u = np.random.default_rng(3).standard_normal(added.shape[0])
    a, b = 6 * 2 + 1, 6 * 4 + 2
    assert_allclose(u @ added @ u, 2.5 * (u[a] - u[b]) ** 2, rtol=1e-13)
    assert np.count_nonzero(added) == 4


def test_cmass_acts_in_the_cd_frame(write_deck):
    """CMASS2 on component 1 of a grid whose CD frame is turned = CONM1 with that one entry in CID = CD."""
    cord = "CORD2R,5,,0.0,0.0,0.0,0.3,0.4,0.8660254037844386\n,1.0,0.2,0.1"
    base = _frame(cord).replace("GRID,4,,", "GRID,4,,").splitlines()
    base = [ln + ",,,5" if ln.startswith("GRID,4,") else ln for ln in base]
    cmass = "\n".join(base + ["CMASS2,900,4.0,4,1"])
    conm1 = "\n".join(base + ["CONM1,900,4,5,4.0"])
    a = _modes(write_deck, cmass, "a.dat")
    b = _modes(write_deck, conm1, "b.dat")
    assert_allclose(a.frequencies_hz, b.frequencies_hz, rtol=RTOL)
    assert_allclose(a.inertia, b.inertia, rtol=1e-13)


# ------------------------------------------------------------------------------------ RBAR, RBE1
def _rigid_link_deck(link):
    """Two CBAR beams (grids 1..7 along x, 11..17 along x from (2.1, 0, 0)) joined by ``link`` between
    grid 7 and grid 11 (0.1 m apart along x)."""
    lines = decks.beam_deck(6, 2.0, coupled=True).replace("ENDDATA\n", "").splitlines()
    for i, x in enumerate(np.linspace(2.1, 4.1, 7)):
        lines.append(f"GRID,{11 + i},,{float(x)!r},0.0,0.0")
    lines += [f"CBAR,{201 + i},10,{11 + i},{12 + i},0.0,1.0,0.0" for i in range(6)]
    lines += [link, "ENDDATA"]
    return "\n".join(lines) + "\n"


@pytest.mark.parametrize("link", [
    "RBAR,900,7,11,123456,,,123456",          # GA independent, GB dependent
    "RBAR,900,7,11,1234,23,56,1456",          # the six independent DOFs split between the ends
    "RBAR,900,7,11,1234,23",                  # CMA, CMB blank: every other DOF dependent
    "RBE1,900,7,123456\n,UM,11,123456",       # one independent grid
    "MPC,1,11,1,1.0,7,1,-1.0\nMPC,1,11,2,1.0,7,2,-1.0\n,,7,6,-0.1\nMPC,1,11,3,1.0,7,3,-1.0\n,,7,5,0.1\n"
    "MPC,1,11,4,1.0,7,4,-1.0\nMPC,1,11,5,1.0,7,5,-1.0\nMPC,1,11,6,1.0,7,6,-1.0",   # the RBE2 as MPCs
], ids=["rbar", "rbar-split", "rbar-blank-cm", "rbe1", "mpc"])
def test_rigid_link_cards_equal_rbe2(write_deck, link):
    """Every form of the rigid link between grids 7 and 11 is the same model as RBE2 7 -> 11 (123456):
    u11 = u7 + theta7 x (0.1, 0, 0), theta11 = theta7 (so u11_2 = u7_2 + 0.1 theta7_3, u11_3 = u7_3 -
    0.1 theta7_2 in the MPCs)."""
    reference = _modes(write_deck, _rigid_link_deck("RBE2,900,7,123456,11"), "rbe2.dat")
    body = _modes(write_deck, _rigid_link_deck(link), "link.dat")
    assert_allclose(body.frequencies_hz, reference.frequencies_hz, rtol=RTOL)
    assert_allclose(body.inertia, reference.inertia, rtol=1e-12)
    assert body.n_rigid_modes_removed == reference.n_rigid_modes_removed == 6


def test_rbe1_on_three_grids_moves_its_dependent_grid_rigidly(write_deck):
    """RBE1: translations of grid 1 (123), grid 2 (23) and grid 3 (3) fix the rigid motion of the plane they
    span; grid 4 (dependent, all six) follows it. For every rigid motion of all four grids, the
    constraint maps the independent values to grid 4's rigid values exactly (the translations of grids 1-3
    stay in the f-set, their rotations, with neither mass nor stiffness, go to AUTOSPC)."""
    text = ("GRID,1,,0.0,0.0,0.0\nGRID,2,,1.0,0.0,0.0\nGRID,3,,0.0,1.0,0.0\nGRID,4,,0.7,0.4,0.9\n"
            "CONM2,1,1,,1.0\nCONM2,2,2,,1.0\nCONM2,3,3,,1.0\nCONM2,4,4,,1.0,,,,\n,1.,,1.,,,1.\n"
            "RBE1,10,1,123,2,23,3,3\n,UM,4,123456\nENDDATA\n")
    sm = assemble(read_bulk_data(write_deck(text, "rbe1.dat")))
    assert list(sm.f_dofs) == [0, 1, 2, 6, 7, 8, 12, 13, 14]
    rng = np.random.default_rng(5)
    t, th = rng.standard_normal(3), rng.standard_normal(3)
    pos = sm.bulk.positions
    rigid = np.concatenate([np.r_[t + np.cross(th, x), th] for x in pos])
    u = sm.T_gf @ rigid[sm.f_dofs]
    assert_allclose(u[18:24], rigid[18:24], rtol=0, atol=1e-14)


@pytest.mark.parametrize("link, match", [
    ("RBAR,900,7,11,123,123", "cannot represent every rigid-body motion"),
    ("RBAR,900,7,11,12345,,,123456", "5 independent DOFs"),
    ("RBAR,900,7,11,123456,1,1", "listed as independent and dependent"),
])
def test_rigid_links_that_do_not_fix_a_rigid_motion_are_refused(write_deck, link, match):
    with pytest.raises(BulkDataError, match=match):
        _modes(write_deck, _rigid_link_deck(link), "bad.dat")


def test_mpcadd_selected_by_case_control(write_deck):
    """Case control MPC = 20 selects the MPCADD of sets 1 and 2 (two of the three RBE2 equations each) and
    leaves set 3 (a contradicting tie) out."""
    rows = {1: "MPC,1,11,1,1.0,7,1,-1.0\nMPC,1,11,2,1.0,7,2,-1.0\n,,7,6,-0.1\nMPC,1,11,3,1.0,7,3,-1.0\n,,7,5,0.1",
            2: "MPC,2,11,4,1.0,7,4,-1.0\nMPC,2,11,5,1.0,7,5,-1.0\nMPC,2,11,6,1.0,7,6,-1.0",
            3: "MPC,3,12,1,1.0,6,1,-1.0"}
    body_text = _rigid_link_deck("\n".join(rows.values()) + "\nMPCADD,20,1,2")
    text = "SOL 103\nCEND\nMPC = 20\nBEGIN BULK\n" + body_text
    reference = _modes(write_deck, _rigid_link_deck("RBE2,900,7,123456,11"), "rbe2.dat")
    body = _modes(write_deck, text, "mpcadd.dat")
    assert_allclose(body.frequencies_hz, reference.frequencies_hz, rtol=RTOL)


# --------------------------------------------------------------------------------- PBARL / PBEAML
# NASTRAN's equivalent entries: (shape, dims, A, I1, I2, J, K1, K2), printed to 5 digits
NASTRAN_EQUIVALENTS = [
    ("TUBE", (0.2, 0.195), 6.2047e-03, 1.2103e-04, 1.2103e-04, 2.4206e-04, 0.5, 0.5),          # fmondsp PBEAML 1
    ("TUBE", (0.6, 0.598), 7.5274e-03, 1.3504e-03, 1.3504e-03, 2.7008e-03, 0.5, 0.5),          # fmondsp PBEAML 8
    ("BOX", (0.6, 0.2, 0.0025, 0.0025), 3.9750e-03, 3.2346e-05, 1.7702e-04, 8.7582e-05, 2.4528e-01, 7.4843e-01),
    ("BOX", (0.05, 0.5, 0.001, 0.001), 1.0960e-03, 2.6809e-05, 6.1877e-07, 2.1819e-06, 9.0876e-01, 8.7591e-02),
    ("BOX", (6.0, 1.0, 0.1, 0.1), 1.3600e+00, 2.5253e-01, 4.9925e+00, 8.2930e-01, 1.1765e-01, 8.5294e-01),  # NX
    ("ROD", (1.0,), 3.1416e+00, 7.8540e-01, 7.8540e-01, 1.5708e+00, 0.9, 0.9),                 # beam_modes
]


@pytest.mark.parametrize("shape, dims, A, I1, I2, J, K1, K2", NASTRAN_EQUIVALENTS)
def test_section_equals_nastrans_equivalent_entry(shape, dims, A, I1, I2, J, K1, K2):
    sec = section_properties(shape, dims, "test")
    # five printed digits: half a unit in the last place is at most 5e-5 relative
    assert_allclose([sec.A, sec.I1, sec.I2, sec.J, sec.k1, sec.k2], [A, I1, I2, J, K1, K2], rtol=5e-5)
    assert sec.note == ""


def test_box_and_tube_stress_points_are_nastrans():
    """fmondsp PBEAML 5 (BOX 0.6 x 0.2): C, D, E, F = (0.1, 0.3), (-0.1, 0.3), (-0.1, -0.3), (0.1, -0.3);
    PBEAML 1 (TUBE r = 0.2): (0.2, 0), (0, 0.2), (-0.2, 0), (0, -0.2)."""
    assert_allclose(section_properties("BOX", (0.6, 0.2, 0.0025, 0.0025), "").stress_points,
                    [[0.1, 0.3], [-0.1, 0.3], [-0.1, -0.3], [0.1, -0.3]])
    assert_allclose(section_properties("TUBE", (0.2, 0.195), "").stress_points,
                    [[0.2, 0.0], [0.0, 0.2], [-0.2, 0.0], [0.0, -0.2]], atol=1e-17)


@pytest.mark.parametrize("ratio, beta", [(1.0, 0.141), (1.5, 0.196), (2.0, 0.229), (3.0, 0.263), (4.0, 0.281),
                                         (5.0, 0.291), (10.0, 0.312), (1e4, 0.333)])
def test_bar_torsion_constant_against_timoshenko_goodier(ratio, beta):
    """J = beta a b^3, Timoshenko & Goodier, Theory of Elasticity (1951), sec. 109 table (3 digits)."""
    b = 0.02
    J = section_properties("BAR", (ratio * b, b), "").J
    assert_allclose(J / (ratio * b * b ** 3), beta, atol=6e-4)
    assert_allclose(rectangle_torsion_constant(b, ratio * b), J, rtol=1e-15)


def _polygon_moments(outline):
    """Area and second moments int y^2, int z^2 of a simple polygon (y, z) by Green's theorem."""
    y, z = np.asarray(outline, float).T
    y1, z1 = np.roll(y, -1), np.roll(z, -1)
    cross = y * z1 - y1 * z
    area = cross.sum() / 2
    Iz = np.sum(cross * (y * y + y * y1 + y1 * y1)) / 12      # int y^2 dA
    Iy = np.sum(cross * (z * z + z * z1 + z1 * z1)) / 12      # int z^2 dA
    return area, Iz, Iy


def test_i_section_against_the_integrals_of_its_outline():
    """A W8x31's nominal plates (AISC: d 8.00, bf 7.995, tf 0.435, tw 0.285 in) as a 12-corner outline."""
    h, b, tf, tw = 8.0, 7.995, 0.435, 0.285
    sec = section_properties("I", (h, b, b, tw, tf, tf), "")
    y0, z0 = h / 2, b / 2
    outline = [(-y0, -z0), (-y0, z0), (-y0 + tf, z0), (-y0 + tf, tw / 2), (y0 - tf, tw / 2), (y0 - tf, z0),
               (y0, z0), (y0, -z0), (y0 - tf, -z0), (y0 - tf, -tw / 2), (-y0 + tf, -tw / 2), (-y0 + tf, -z0)]
    A, I1, I2 = _polygon_moments(outline)
    assert_allclose([sec.A, sec.I1, sec.I2], [abs(A), abs(I1), abs(I2)], rtol=1e-14)
    # the AISC table's A 9.12, Ix 110, Iy 37.1 in include the web-flange fillets the idealized plates leave out
    assert_allclose([sec.A, sec.I1, sec.I2], [9.12, 110.0, 37.1], rtol=0.03)
    assert "not available to check" in sec.note


@pytest.mark.parametrize("shape, dims", [("BOX", "0.06,0.04,0.004,0.003"), ("TUBE", "0.05,0.045"),
                                         ("BAR", "0.03,0.05"), ("I", "0.1,0.06,0.06,0.005,0.008,0.008")])
def test_cbar_with_pbarl_equals_cbar_with_the_derived_pbar(write_deck, shape, dims):
    sec = section_properties(shape, [float(v) for v in dims.split(",")], "")
    e = decks.E
    base = decks.beam_deck(8, 2.0, coupled=True).replace(f"PBAR,10,1,{decks.A!r},{decks.I1!r},{decks.I2!r},"
                                                         f"{decks.J!r}", "{PROPERTY}")
    assert "{PROPERTY}" in base and e > 0
    pbarl = base.replace("{PROPERTY}", f"PBARL,10,1,,{shape}\n,{dims}")
    pbar = base.replace("{PROPERTY}", f"PBAR,10,1,{sec.A!r},{sec.I1!r},{sec.I2!r},{sec.J!r}\n,,,,,,,,\n"
                                      f",{sec.k1!r},{sec.k2!r}")
    a = _modes(write_deck, pbarl, "pbarl.dat")
    b = _modes(write_deck, pbar, "pbar.dat")
    assert_allclose(a.frequencies_hz, b.frequencies_hz, rtol=RTOL)
    assert any(shape in line for line in a.card_report if "not available to check" in line) == bool(sec.note)


@pytest.mark.parametrize("shape, dims, match", [
    ("CHAN", (0.1, 0.05, 0.005, 0.008), "section CHAN is not supported"),
    ("I", (0.1, 0.06, 0.05, 0.005, 0.008, 0.008), "unequal flanges"),
    ("BOX", (0.06, 0.04, 0.03, 0.003), "walls fill the section"),
    ("TUBE", (0.04, 0.05), "inner radius"),
])
def test_unsupported_or_impossible_sections_are_refused(shape, dims, match):
    with pytest.raises(BulkDataError, match=match):
        section_properties(shape, dims, "PBARL 10")
