"""NASTRAN bulk data in: read a deck with pyNastran and keep what the modal pipeline models.

The deck (free, small or large field, INCLUDE files, with or without executive and case control)
is parsed with pyNastran's BDF reader. Every card type is then sorted into one of three bins and
reported by name and count, so nothing is silently dropped:

* supported: modelled by :mod:`dynamics.flex.elements` / :mod:`dynamics.flex.assembly`
  (GRID, GRDSET, CORD2R, CORD2C, CORD2S, CORD1R, CORD1C, CORD1S, RBE3, CBUSH/PBUSH, CBAR/PBAR/PBARL,
  CBEAM/PBEAM/PBEAML, CROD/PROD, CELAS1/PELAS, CELAS2, CQUAD4/CTRIA3/CQUAD8/CTRIA6 with PSHELL/PCOMP,
  CHEXA/CTETRA/CPENTA (6 and 15 grids)/PSOLID, CONM1, CONM2, CMASS1/PMASS, CMASS2, MAT1, MAT2, MAT8, RBE2,
  RBAR, RBE1, MPC, MPCADD, SPC, SPC1, SPCADD, ASET, ASET1, DMIG (K2GG/M2GG), PARAM WTMASS/COUPMASS/GRDPNT/CK2/CM2);
* ignored: cards that carry no mass, stiffness or constraint (solution controls, output and
  load cards, SPOINTs without elements, other PARAMs): reported as a warning;
* unsupported structural cards (other elements, properties, materials, rigid elements, MPCs,
  coordinate systems): an :class:`UnsupportedCardError` naming the cards, because leaving them
  out would change the structure. ``allow_unsupported=True`` downgrades this to a warning.

Grid geometry is resolved here: positions in the basic frame (CP frames) and, per grid, the
rotation from its displacement frame (CD) to basic, including the position-dependent axes of a
cylindrical or spherical CD frame (MSC Nastran Quick Reference Guide, GRID / CORD2C / CORD2S). GRDSET supplies CP, CD
and PS to GRIDs that leave them blank (QRG, GRDSET); pyNastran reads a blank CP/CD as 0, so an
explicit 0 on a GRID cannot be told from a blank one and also takes the GRDSET value (the
report says so). The GRID PS field (permanent single-point constraints, in the CD frame) is
kept per grid and applied by :mod:`dynamics.flex.assembly` like an SPC1.
"""

from __future__ import annotations

import contextlib
import io
import logging
import os
import re
import warnings
from collections import Counter
from dataclasses import dataclass, field

import numpy as np

SUPPORTED_CARDS = frozenset({
    "GRID", "GRDSET", "CORD2R", "CORD2C", "CORD1R",
    "CBAR", "PBAR", "PBARL", "CBEAM", "PBEAM", "PBEAML", "CROD", "PROD",
    "CELAS1", "CELAS2", "PELAS", "CONM1", "CONM2", "CMASS1", "CMASS2", "PMASS", "MAT1", "MAT2", "MAT8",
    "CQUAD4", "CTRIA3", "CQUAD8", "CTRIA6", "PSHELL", "PCOMP", "CHEXA", "CTETRA", "CPENTA", "PSOLID",
    "RBE2", "RBE3", "RBAR", "RBE1", "MPC", "MPCADD", "CBUSH", "PBUSH", "CORD2S", "CORD1C", "CORD1S",
    "SPC", "SPC1", "SPCADD", "ASET", "ASET1", "PARAM", "ENDDATA", "DMIG",
})
# PARAMs that change the structural matrices or the products; all others are reported as ignored.
USED_PARAMS = frozenset({"WTMASS", "COUPMASS", "GRDPNT", "CK2", "CM2"})
# Containers of the pyNastran model whose unsupported members would change M or K.
STRUCTURAL_CONTAINERS = ("elements", "properties", "materials", "masses", "rigid_elements",
                         "coords", "mpcs", "plotels", "properties_mass", "dmig", "dmiji", "dmik")


class BulkDataError(ValueError):
    """A deck the pipeline cannot turn into structural matrices; the message names the card."""


class UnsupportedCardError(BulkDataError):
    """The deck holds structural cards the pipeline does not model."""


@dataclass
class CardReport:
    """What happened to every card type of a deck (name -> count)."""

    supported: dict[str, int] = field(default_factory=dict)
    ignored: dict[str, int] = field(default_factory=dict)
    unsupported: dict[str, int] = field(default_factory=dict)
    parse_errors: dict[str, list[str]] = field(default_factory=dict)
    ignored_params: list[str] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)

    def lines(self) -> list[str]:
        out = ["supported cards: " + _fmt(self.supported)] + list(self.notes)
        if self.ignored:
            out.append("ignored cards (no mass, stiffness or constraint): " + _fmt(self.ignored))
        if self.ignored_params:
            out.append("ignored PARAMs: " + ", ".join(sorted(self.ignored_params)))
        if self.unsupported:
            out.append("UNSUPPORTED structural cards: " + _fmt(self.unsupported))
        for name, errs in sorted(self.parse_errors.items()):
            out.append(f"unreadable {name} card(s) ({len(errs)}): {errs[0].splitlines()[0]}")
        return out


def _fmt(counts: dict[str, int]) -> str:
    return ", ".join(f"{k} x{v}" for k, v in sorted(counts.items())) or "none"


@dataclass
class BulkData:
    """A parsed deck: pyNastran model plus resolved grid geometry and the card report.

    Parameters
    ----------
    grid_ids : (n,) int64, sorted ascending; the g-set order is 6 DOFs per grid in this order.
    positions : (n, 3) grid locations in the basic frame [m].
    displacement_rotation : (n, 3, 3) R with v_basic = R @ v_cd for each grid's CD frame.
    wtmass : PARAM WTMASS (mass-unit scale applied to every mass term).
    coupled_mass : True when PARAM COUPMASS > 0 (consistent element mass matrices).
    grdpnt : PARAM GRDPNT grid (0 / None = basic origin).
    permanent_spc : (grid id, [components]) from the GRID PS fields (after GRDSET).
    """

    path: str
    model: object
    grid_ids: np.ndarray
    positions: np.ndarray
    displacement_rotation: np.ndarray
    wtmass: float
    coupled_mass: bool
    grdpnt: int | None
    report: CardReport
    permanent_spc: list = field(default_factory=list)

    def grid_index(self, grid_id: int, context: str) -> int:
        """Row of ``grid_id`` in :attr:`grid_ids`; a :class:`BulkDataError` naming ``context``."""
        i = int(np.searchsorted(self.grid_ids, grid_id))
        if i >= len(self.grid_ids) or self.grid_ids[i] != grid_id:
            raise BulkDataError(f"{context}: grid {grid_id} does not exist in {self.path}")
        return i


def _param_value(model, name: str, default):
    p = model.params.get(name)
    if p is None:
        return default
    return p.values[0]


def _has_case_control(path: str) -> bool:
    """True if the main file has an executive/case control section (a CEND line)."""
    begin_bulk = False
    with open(path, errors="replace") as fh:
        for line in fh:
            text = line.split("$")[0].strip().upper()
            if text == "CEND":
                return True
            begin_bulk |= text.replace(" ", "") == "BEGINBULK"
    if begin_bulk:
        raise BulkDataError(f"{path}: BEGIN BULK without executive and case control (no CEND "
                            "line); delete the BEGIN BULK line for a bulk-only deck, or put "
                            "'SOL 103' and 'CEND' above it")
    return False


def _no_dump(*args, **kwargs) -> None:
    """Stands in for pyNastran's crash dump (see read_bulk_data)."""


def read_bulk_data(path: str | os.PathLike, allow_unsupported: bool = False) -> BulkData:
    """Parse ``path`` and resolve grid geometry. Raises :class:`BulkDataError` on bad decks."""
    from unittest import mock

    from pyNastran.bdf.bdf import BDF
    from pyNastran.bdf.bdf_interface.pybdf import BDFInputPy

    path = os.fspath(path)
    if not os.path.isfile(path):
        raise BulkDataError(f"bulk data file not found: {path}")
    log = logging.getLogger("pyNastran.flexshell")
    log.setLevel(logging.ERROR)
    if not log.handlers:  # pyNastran's errors reach the user in BulkDataError, not also as raw log lines
        log.addHandler(logging.NullHandler())
        log.propagate = False
    model = BDF(debug=None, log=log)
    model.set_error_storage(nparse_errors=100000, stop_on_parsing_error=False,
                            nxref_errors=0, stop_on_xref_error=True)
    punch = not _has_case_control(path)
    stdout = io.StringIO()
    try:
        # pyNastran dumps the lines read so far to pyNastran_crash.bdf in the working directory when an INCLUDE
        # is missing, replacing a user's file of that name: not here
        with contextlib.redirect_stdout(stdout), mock.patch.object(BDFInputPy, "_dump_file", _no_dump):
            model.read_bdf(path, xref=False, punch=punch, validate=False)
    except Exception as exc:  # pyNastran raises a variety of types; name the file and pass it on
        raise BulkDataError(f"{path}: pyNastran could not read the deck: {exc}") from exc
    for filename in dict.fromkeys(getattr(model, "active_filenames", None) or [path]):
        check_line_fields(filename, bulk_only=not punch and os.path.abspath(filename) == os.path.abspath(path))

    report = _classify_cards(model)
    structural_parse_errors = {k: v for k, v in report.parse_errors.items()
                               if k in SUPPORTED_CARDS or _is_structural_name(k)}
    if structural_parse_errors:
        name, errs = next(iter(sorted(structural_parse_errors.items())))
        raise BulkDataError(f"{path}: {name} card could not be read: {errs[0].strip()}")
    if report.unsupported:
        msg = (f"{path}: structural cards not modelled by fem2modal: {_fmt(report.unsupported)}; "
               "leaving them out would change the structure")
        if not allow_unsupported:
            raise UnsupportedCardError(msg + " (pass allow_unsupported to proceed without them)")
        warnings.warn(msg, stacklevel=2)
    if report.ignored or report.ignored_params or report.parse_errors:
        warnings.warn(f"{path}: " + "; ".join(report.lines()[1:]), stacklevel=2)

    grdset_note = _apply_grdset(model, path)
    try:
        model.cross_reference(xref=True, xref_nodes=True, xref_elements=False,
                              xref_nodes_with_elements=False, xref_properties=False,
                              xref_masses=False, xref_materials=False, xref_loads=False,
                              xref_constraints=False, xref_aero=False, xref_sets=False,
                              xref_optimization=False)
    except Exception as exc:
        raise BulkDataError(f"{path}: inconsistent grid/coordinate-system cards: {exc}") from exc

    if not model.nodes:
        raise BulkDataError(f"{path}: the deck defines no GRID cards")
    grid_ids = np.array(sorted(model.nodes), dtype=np.int64)
    positions = np.empty((len(grid_ids), 3))
    rotations = np.empty((len(grid_ids), 3, 3))
    for i, nid in enumerate(grid_ids):
        node = model.nodes[int(nid)]
        positions[i] = node.get_position()
        rotations[i] = displacement_frame_rotation(model, int(node.cd), positions[i],
                                                   f"GRID {nid}")
    permanent_spc = []
    for nid in grid_ids:
        ps = str(model.nodes[int(nid)].ps or "").strip()
        if ps not in ("", "0", "None"):
            comps = sorted({int(c) for c in ps})
            if any(c < 1 or c > 6 for c in comps):
                raise BulkDataError(f"{path}: GRID {nid}: PS = {ps} must hold digits 1..6")
            permanent_spc.append((int(nid), comps))
    if grdset_note:
        report.notes.append(grdset_note)
    coupmass = _param_value(model, "COUPMASS", -1)
    grdpnt = _param_value(model, "GRDPNT", -1)
    return BulkData(path=path, model=model, grid_ids=grid_ids, positions=positions,
                    displacement_rotation=rotations,
                    wtmass=float(_param_value(model, "WTMASS", 1.0)),
                    coupled_mass=int(coupmass) > 0,
                    grdpnt=int(grdpnt) if int(grdpnt) > 0 else None, report=report,
                    permanent_spc=permanent_spc)


def _apply_grdset(model, path: str) -> str:
    """Give GRIDs with blank (0) CP, CD and blank PS the GRDSET values; return a report line.

    pyNastran keeps GRDSET apart and its own cross-reference does not apply it consistently,
    so it is applied here and removed from the model before cross-referencing.
    """
    grdset = getattr(model, "grdset", None)
    if grdset is None:
        return ""
    cp, cd = int(grdset.cp or 0), int(grdset.cd or 0)
    ps = str(grdset.ps or "").strip()
    seid = int(grdset.seid or 0)
    if seid:
        raise UnsupportedCardError(f"{path}: GRDSET SEID = {seid}: superelements are not "
                                   "supported")
    changed = Counter()
    for node in model.nodes.values():
        if cp and not node.cp:
            node.cp = cp
            changed["CP"] += 1
        if cd and not node.cd:
            node.cd = cd
            changed["CD"] += 1
        if ps not in ("", "0", "None") and str(node.ps or "").strip() in ("", "0", "None"):
            node.ps = ps
            changed["PS"] += 1
    model.grdset = None
    fields = ", ".join(f"{k} to {v} grid(s)" for k, v in changed.items()) or "no grid"
    return (f"GRDSET (CP {cp}, CD {cd}, PS {ps or 'blank'}) applied: {fields} "
            "(a GRID CP/CD of 0 counts as blank)")


def _is_structural_name(name: str) -> bool:
    return name.startswith(("C", "P", "MAT", "RB", "MPC", "CORD", "CONM", "DMI")) and \
        name not in ("PARAM",)


def _classify_cards(model) -> CardReport:
    report = CardReport()
    counts = Counter({k: v for k, v in model.card_count.items()})
    structural_types: set[str] = set()
    for container in STRUCTURAL_CONTAINERS:
        obj = getattr(model, container, None)
        if not obj:
            continue
        values = obj.values()
        for item in values:
            items = item if isinstance(item, list) else [item]
            for card in items:
                structural_types.add(getattr(card, "type", ""))
    rejected = Counter()
    for card in getattr(model, "reject_cards", []):
        rejected[str(card[0]).upper().rstrip("*")] += 1
    counts.update(rejected)
    for name, count in counts.items():
        if name in SUPPORTED_CARDS:
            report.supported[name] = count
        elif name in structural_types or (name in rejected and _is_structural_name(name)):
            report.unsupported[name] = count
        else:
            report.ignored[name] = count
    for name, errs in getattr(model, "_stored_parse_errors", []):
        report.parse_errors.setdefault(name, []).extend(errs)
    report.ignored_params = sorted(k for k in model.params if k not in USED_PARAMS)
    return report


def coordinate_axes(model, cid: int, context: str):
    """Origin (3,) and axes matrix B (3x3, columns = local x, y, z in basic) of system ``cid``."""
    if cid == 0:
        return np.zeros(3), np.eye(3), "R"
    coord = model.coords.get(cid)
    if coord is None:
        raise BulkDataError(f"{context}: coordinate system {cid} is not defined")
    if coord.type not in ("CORD2R", "CORD2C", "CORD2S", "CORD1R", "CORD1C", "CORD1S"):
        raise UnsupportedCardError(f"{context}: coordinate system {cid} is a {coord.type}; "
                                   "supported are CORD1R/C/S and CORD2R/C/S")
    axes = np.asarray(coord.beta(), dtype=float).T
    kind = coord.type[-1]
    return np.asarray(coord.origin, dtype=float), axes, kind


def displacement_frame_rotation(model, cid: int, position_basic: np.ndarray,
                                context: str) -> np.ndarray:
    """R (3x3) with v_basic = R v_cd for a grid at ``position_basic`` whose CD is ``cid``."""
    origin, axes, kind = coordinate_axes(model, cid, context)
    if kind == "R":
        return axes
    local = axes.T @ (position_basic - origin)
    phi = np.arctan2(local[1], local[0])
    c, s = np.cos(phi), np.sin(phi)
    if kind == "C":        # (R, theta, Z): e_R, e_theta, e_z
        return axes @ np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    # spherical (R, theta, phi), theta from the local z axis, phi about it from x (QRG CORD2S):
    # columns e_R, e_theta, e_phi
    th = np.arctan2(np.hypot(local[0], local[1]), local[2])
    ct, st = np.cos(th), np.sin(th)
    if np.hypot(local[0], local[1]) <= 1e-12 * max(np.linalg.norm(local), 1e-300):
        raise BulkDataError(f"{context}: grid on the polar axis of spherical system {cid}: "
                            "its displacement directions are undefined")
    return axes @ np.array([[st * c, ct * c, -s], [st * s, ct * s, c], [ct, -st, 0.0]])


def vector_to_basic(model, cid: int, vector: np.ndarray, at_basic: np.ndarray,
                    context: str) -> np.ndarray:
    """Components ``vector`` given in system ``cid`` (at point ``at_basic``) rotated to basic."""
    return displacement_frame_rotation(model, cid, at_basic, context) @ np.asarray(vector, float)


#: a NASTRAN number in a continuation field: integer, real with exponent (E or D) or NASTRAN's short form 1.-3;
#: a leading '+' is left out, since '+1', '+A' are the usual continuation labels
_NUMBER = re.compile(r"^-?(\d+\.?\d*|\.\d+)([EeDd]?[+-]?\d+)?$")


def check_line_fields(path: str, bulk_only: bool = False) -> None:
    """Refuse a free-field line with more fields than a NASTRAN line holds: ten (the card name or continuation
    field, eight data fields, the continuation field), six for large-field free format (a ``*`` after the card
    name or at the start of a continuation). pyNastran keeps the first ten and drops the rest without a word (an
    SPC1 listing eight grids on one line held six), and NASTRAN versions differ on such lines, so the deck must
    say it with a continuation line. ``bulk_only``: check only between BEGIN BULK and ENDDATA (the file has
    executive and case control, whose commas are not fields). A fixed-format line with text after column 80,
    which NASTRAN ignores and pyNastran too, is warned about."""
    in_bulk = not bulk_only
    beyond: list = []
    try:
        with open(path, errors="replace") as handle:
            lines = handle.readlines()
    except OSError:
        return  # pyNastran read it; an unreadable include was reported there
    for number, raw in enumerate(lines, start=1):
        line = raw.split("$", 1)[0].rstrip()
        word = line.strip().upper()
        if not in_bulk:
            in_bulk = word.startswith("BEGIN") and "BULK" in word
            continue
        if word.startswith("ENDDATA"):
            break
        if "," not in line[:10]:
            if len(line) > 80 and line[80:].strip() and not word.startswith("INCLUDE"):
                beyond.append(number)
            continue
        fields = line.split(",")
        while fields and not fields[-1].strip():
            fields.pop()
        if not fields:
            continue
        large = fields[0].strip().endswith("*") or line.lstrip().startswith("*")
        limit = 6 if large else 10
        card = fields[0].strip() or "continuation"
        if len(fields) > limit:
            raise BulkDataError(
                f"{path}:{number}: {card}: {len(fields)} free-field fields on one line; a line holds {limit} "
                f"(the name, {limit - 2} data fields, the continuation label), and the fields after the "
                f"{limit}th would be dropped: put them on a continuation line (a line starting with ',')")
        if len(fields) == limit and _NUMBER.match(fields[-1].strip()):
            raise BulkDataError(
                f"{path}:{number}: {card}: field {limit} of a free-field line is the continuation label, and "
                f"{fields[-1].strip()!r} there would be read as one and dropped; a line holds {limit - 2} data "
                "fields: put the rest on a continuation line (a line starting with ',')")
    if beyond:
        warnings.warn(f"{path}:{beyond[0]}: text after column 80 of a fixed-format line is ignored (NASTRAN reads "
                      f"80 columns; {len(beyond)} line(s), the first here): use a continuation line or free-field "
                      "format if it was meant as data", stacklevel=3)
