"""Bad input is refused with messages that name the card, grid or file."""

import os

import numpy as np
import pytest

import decks
from dynamics.flex.bulk_data import BulkDataError, UnsupportedCardError
from dynamics.flex.component_modes import CraigBamptonError
from dynamics.flex.op4 import write_op4_matrices
from dynamics.flex.pipeline import Fem2ModalOptions, fem2modal, parse_grid_dofs
from shell.cli import main

OPT = Fem2ModalOptions(n_modes=3)


def test_unsupported_structural_cards_are_named_and_counted(write_deck):
    extra = ("GRID,90,,0.0,1.0,0.0\nGRID,91,,1.0,1.0,0.0\nPSHEAR,20,1,0.01\n"
             "CSHEAR,500,20,1,2,91,90\nCSHEAR,501,20,2,3,91,90")
    deck = write_deck(decks.beam_deck(4, 2.0, extra=extra))
    with pytest.raises(UnsupportedCardError, match=r"CSHEAR x2.*PSHEAR x1"):
        fem2modal(deck, OPT)
    with pytest.warns(UserWarning, match="CSHEAR x2"):
        body = fem2modal(deck, Fem2ModalOptions(n_modes=3, allow_unsupported=True))
    assert any("UNSUPPORTED" in line and "CSHEAR x2" in line for line in body.card_report)


def test_missing_property_material_and_grid(write_deck):
    text = decks.beam_deck(4, 2.0).replace("CBAR,102,10,", "CBAR,102,99,")
    with pytest.raises(BulkDataError, match=r"CBAR 102: property 99 is not defined"):
        fem2modal(write_deck(text, "p.dat"), OPT)
    text = decks.beam_deck(4, 2.0).replace("PBAR,10,1,", "PBAR,10,7,")
    with pytest.raises(BulkDataError, match=r"CBAR 101 -> PBAR 10: material 7 is not defined"):
        fem2modal(write_deck(text, "m.dat"), OPT)
    text = decks.beam_deck(4, 2.0).replace("CBAR,104,10,4,5", "CBAR,104,10,4,55")
    with pytest.raises(BulkDataError, match=r"CBAR 104: grid 55 does not exist"):
        fem2modal(write_deck(text, "g.dat"), OPT)


def test_inconsistent_cards(write_deck):
    text = decks.beam_deck(4, 2.0).replace("CBAR,101,10,1,2,0.0,1.0,0.0",
                                           "CBAR,101,10,1,2,1.0,0.0,0.0")
    with pytest.raises(ValueError, match=r"CBAR 101: orientation vector is parallel"):
        fem2modal(write_deck(text, "v.dat"), OPT)
    text = decks.beam_deck(4, 2.0, extra="RBE2,7,1,123,2\nRBE2,8,3,1,2")
    with pytest.raises(BulkDataError, match=r"RBE2 8: DOF 1 of grid 2 is already dependent"):
        fem2modal(write_deck(text, "r.dat"), OPT)
    text = decks.beam_deck(4, 2.0, extra="SPC,1,2,3,0.01")
    with pytest.raises(BulkDataError, match=r"enforced displacements"):
        fem2modal(write_deck(text, "s.dat"), OPT)


def test_zero_mass_model(write_deck):
    with pytest.raises(BulkDataError, match="zero-mass model"):
        fem2modal(write_deck(decks.beam_deck(4, 2.0, rho=0.0)), OPT)


def test_singular_interior_stiffness_in_craig_bampton(write_deck):
    deck = write_deck(decks.beam_deck(4, 2.0))
    # translations of one grid do not stop the beam rotating about it
    with pytest.raises(CraigBamptonError, match=r"K_ee is .*singular.*a-set"):
        fem2modal(deck, Fem2ModalOptions(n_modes=2, aset=[(1, [1, 2, 3])]))


def test_aset_and_residual_grids_must_exist_and_be_free(write_deck):
    deck = write_deck(decks.beam_deck(4, 2.0, clamp_root=True, with_header=True))
    with pytest.raises(BulkDataError, match=r"a-set grid 999:1: grid 999 does not exist"):
        fem2modal(deck, Fem2ModalOptions(n_modes=2, aset=[(999, [1])]))
    with pytest.raises(BulkDataError, match=r"DOF 3 of grid 1 is constrained"):
        fem2modal(deck, Fem2ModalOptions(n_modes=2, residual=[(1, [3])]))
    with pytest.raises(ValueError, match="GRID:DOFS"):
        parse_grid_dofs("12-123")
    with pytest.raises(ValueError, match="digits 1..6"):
        parse_grid_dofs("12:789")


def test_files_and_deck_sections(write_deck, tmp_path):
    with pytest.raises(BulkDataError, match="not found"):
        fem2modal(str(tmp_path / "nope.dat"), OPT)
    with pytest.raises(BulkDataError, match="BEGIN BULK without executive"):
        fem2modal(write_deck("BEGIN BULK\n" + decks.beam_deck(4, 2.0)), OPT)
    deck = write_deck(decks.beam_deck(4, 2.0), "b.dat")
    op4 = tmp_path / "small.op4"
    write_op4_matrices(op4, {"KGG": np.eye(12), "MGG": np.eye(12)})
    with pytest.raises(BulkDataError, match=r"12 x 12, expected 30 x 30"):
        fem2modal(deck, Fem2ModalOptions(n_modes=2, op4=str(op4)))
    with pytest.raises(ValueError, match="exactly one of"):
        fem2modal(deck, Fem2ModalOptions())


def test_cli_writes_a_body_file_and_reports_errors(write_deck, tmp_path, capsys, data_dir):
    out = tmp_path / "beam.h5"
    rc = main(["fem2modal", os.path.join(data_dir, "SimpleBeam.dat"), "--modes", "4",
               "--aset", "1:123456", "--residual", "10:3", "--grdpnt", "11",
               "--modal-integrals", "--damping", "0.01", "-o", str(out)])
    err = capsys.readouterr().err
    assert rc == 0 and out.exists()
    assert "Craig-Bampton reduction" in err and "wrote" in err and "EIGRL" in err
    from dynamics.flex.body_file import read_body_file
    body = read_body_file(out)
    assert body.mode_set == "normalized-component" and body.n_residual_vectors == 1
    rc = main(["fem2modal", os.path.join(data_dir, "SimpleBeam.dat"), "--modes", "4",
               "--aset", "77:123456", "-o", str(tmp_path / "x.h5")])
    err = capsys.readouterr().err
    assert rc == 1 and "grid 77 does not exist" in err
    assert not (tmp_path / "x.h5").exists()


_CHAIN = ("SOL 103\nCEND\nDISPLACEMENT(PLOT,PRINT) = ALL\nBEGIN BULK\n"
          + "".join(f"GRID,{g},,{float(g)!r},0.,0.\n" for g in range(1, 9))
          + "{spc}\nCONM2,10,8,,1.0\nENDDATA\n")


@pytest.mark.parametrize("spc, message", [
    ("SPC1,1,123456,1,2,3,4,5,6,7,8", r"model\.dat:13: SPC1: 11 free-field fields on one line; a line holds 10"),
    ("SPC1,1,123456,1,2,3,4,5,6,7", r"model\.dat:13: SPC1: field 10 of a free-field line is the continuation label,"
                                    r" and '7' there would be read as one and dropped"),
])
def test_free_field_line_longer_than_nastran_reads_is_refused(write_deck, spc, message):
    """pyNastran kept the first ten fields of a free-field line and read a number in the tenth as a continuation
    label, dropping grids 7 and 8 of this SPC1 without a word (found with a twisted-beam deck that lost half its
    root clamp). Case control's commas (DISPLACEMENT(PLOT,PRINT)) are not fields."""
    from dynamics.flex.bulk_data import read_bulk_data

    with pytest.raises(BulkDataError, match=message):
        read_bulk_data(write_deck(_CHAIN.format(spc=spc)), allow_unsupported=True)


@pytest.mark.parametrize("spc", ["SPC1,1,123456,1,2,3,4,5,6,+A\n+A,7,8", "SPC1,1,123456,1,2,3,4,5,6\n,7,8",
                                 "SPC1,1,123456,1,2,3,4,5,6,,\n,7,8"])
def test_free_field_continuations_keep_every_field(write_deck, spc):
    from dynamics.flex.bulk_data import read_bulk_data

    bulk = read_bulk_data(write_deck(_CHAIN.format(spc=spc)), allow_unsupported=True)
    assert bulk.model.spcs[1][0].node_ids == list(range(1, 9))


def test_free_field_lines_of_an_included_file_are_checked(write_deck):
    from dynamics.flex.bulk_data import read_bulk_data

    write_deck("SPC1,1,123456,1,2,3,4,5,6,7,8\n", "constraints.inc")
    main_deck = _CHAIN.format(spc="INCLUDE 'constraints.inc'")
    with pytest.raises(BulkDataError, match=r"constraints\.inc:1: SPC1: 11 free-field fields"):
        read_bulk_data(write_deck(main_deck), allow_unsupported=True)


def test_text_after_column_80_of_a_fixed_format_line_is_warned(write_deck):
    """NASTRAN reads 80 columns of a fixed-format line, and so does pyNastran: a grid written in columns 81-88
    is lost; the deck is accepted (that is NASTRAN's rule) with a warning naming the line."""
    from dynamics.flex.bulk_data import read_bulk_data

    fixed = "".join(f"{x:<8s}" for x in ["SPC1", "1", "123456", "1", "2", "3", "4", "5", "6", "+A"]) + "7"
    with pytest.warns(UserWarning, match=r"model\.dat:13: text after column 80 of a fixed-format line is ignored"):
        bulk = read_bulk_data(write_deck(_CHAIN.format(spc=fixed)), allow_unsupported=True)
    assert bulk.model.spcs[1][0].node_ids == list(range(1, 7))


def test_flexshell_fem2modal_refuses_a_long_free_field_line(write_deck, tmp_path, capsys):
    """The user's path: `flexshell fem2modal` on such a deck exits 1 naming file and line, and writes no body."""
    deck = write_deck(_CHAIN.format(spc="SPC1,1,123456,1,2,3,4,5,6,7,8"))
    out = tmp_path / "chain.h5"
    assert main(["fem2modal", deck, "--modes", "2", "-o", str(out)]) == 1
    assert "model.dat:13: SPC1: 11 free-field fields on one line" in capsys.readouterr().err
    assert not out.exists()
