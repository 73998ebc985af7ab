"""Deck units (``--units``) and the output coordinate system (``--csid``).

A deck written in another unit system is the SI deck with every number divided by its unit's factor
(lengths by 0.0254 for inches, E by lbf/in^2, ...; :func:`convert`); fem2modal with ``--units`` must
give the SI body file. How closely: mass properties, node masses and positions to 1e-12 (measured
3e-15). The eigen-solution to the round-off the matrices themselves carry: the converted deck's K_f,
brought back to SI, differs from the SI deck's by 8e-14 relative in its largest-error entry (sums that
cancel), and the spacecraft's lowest eigenvalues move by 3e-11 under such perturbations (LAPACK on each
deck's own matrices gives the same 3e-11 between the decks; each pipeline run is within 6e-12 of its
deck's LAPACK solution): frequencies measured 3.2e-11, asserted 1e-10; mode shapes and what is made of
them (modal integrals, geometric stiffness) measured 1.0e-10 (the closely spaced pair 6.43 / 6.48 Hz),
asserted 1e-9.
"""

import subprocess
import warnings
import sys

import numpy as np
import pytest
from numpy.testing import assert_allclose

from dynamics.flex import Fem2ModalOptions, fem2modal, read_body_file, write_body_file
from dynamics.flex.units import POUND_MASS, UnitsError, parse_units

SPACECRAFT = "configs/fem/spacecraft.dat"
# NASTRAN field number (the card name is field 1, a continuation line's first data field is 10) -> the
# (length, mass, time) exponents of its unit, for the cards of configs/fem/spacecraft.dat
FIELD_DIMENSIONS = {
    "GRID": {4: (1, 0, 0), 5: (1, 0, 0), 6: (1, 0, 0)},
    "CONM2": {5: (0, 1, 0), 6: (1, 0, 0), 7: (1, 0, 0), 8: (1, 0, 0),
              **{k: (2, 1, 0) for k in range(10, 16)}},
    "MAT1": {3: (-1, 1, -2), 4: (-1, 1, -2), 6: (-3, 1, 0)},
    "PSHELL": {4: (1, 0, 0), 9: (-2, 1, 0)},
    "PBAR": {4: (2, 0, 0), 5: (4, 0, 0), 6: (4, 0, 0), 7: (4, 0, 0), 8: (-1, 1, 0),
             **{k: (1, 0, 0) for k in range(10, 18)}},
    "PBUSH": {4: (0, 1, -2), 5: (0, 1, -2), 6: (0, 1, -2), 7: (2, 1, -2), 8: (2, 1, -2), 9: (2, 1, -2)},
}
OPTIONS = dict(n_modes=8, geometric_stiffness=True, preloads=[("thrust", 187, 1, -200.0)],
               recover_elements=[164, 170], recover_grids=[38])


def convert(text, units, mass_unit=None):
    """The free-field SI deck ``text`` in ``units`` (every dimensioned field divided by its factor);
    ``mass_unit`` (kg per unit): masses and densities in that unit instead, for a PARAM WTMASS deck."""
    mass = units.mass if mass_unit is None else mass_unit
    out, card = [], None
    for line in text.splitlines():
        fields = line.split(",")
        first = bool(fields[0].strip())
        if first:
            card = fields[0].strip()
        for i in range(1, len(fields)):
            dims = FIELD_DIMENSIONS.get(card, {}).get(i + 1 if first else 9 + i)
            if dims and fields[i].strip():
                a, b, c = dims
                # a consistent-unit stiffness (mass exponent from the force) keeps the system's mass unit
                m = units.mass if c else mass
                fields[i] = repr(float(fields[i]) / (units.length ** a * m ** b * units.time ** c))
        out.append(",".join(fields))
    return "\n".join(out) + "\n"


@pytest.fixture(scope="module")
def reference():
    return fem2modal(SPACECRAFT, Fem2ModalOptions(**OPTIONS))


def _same_body(a, b, shapes_rtol=1e-9):
    def close(x, y, rtol):
        x, y = np.asarray(x), np.asarray(y)
        assert_allclose(y, x, rtol=0, atol=rtol * np.abs(x).max())
    close(a.frequencies_hz, b.frequencies_hz, 1e-10)
    assert_allclose(b.mass, a.mass, rtol=1e-13)
    for name in ("cm_offset", "inertia", "grid_positions", "node_mass", "node_cm_offset", "node_inertia"):
        close(getattr(a, name), getattr(b, name), 1e-12)
    close(a.modal_stiffness, b.modal_stiffness, 1e-10)
    close(a.modal_mass, b.modal_mass, 1e-12)
    for name in ("translation_shapes", "rotation_shapes"):
        close(getattr(a, name), getattr(b, name), shapes_rtol)
    ga, gb = a.geometric_stiffness, b.geometric_stiffness
    # a free body under inertia relief carries no stress from a uniform acceleration: the translational
    # cases are round-off (1e-14) and compared against the rotational scale
    scale = np.abs(ga.rotation).max()
    assert_allclose(gb.translation, ga.translation, rtol=0, atol=1e-9 * scale)
    for name in ("rotation", "angular_velocity", "preload"):
        close(getattr(ga, name), getattr(gb, name), shapes_rtol)
    la, lb = a.loads_recovery, b.loads_recovery
    assert la.names == lb.names and la.reaction == lb.reaction == "inertia_relief"
    close(la.mode_displacement, lb.mode_displacement, shapes_rtol)


@pytest.mark.parametrize("system", ["in,lbf,s", "mm,N,s", "mm,kg,s"])
def test_deck_in_other_units_gives_the_si_body(reference, write_deck, system):
    units = parse_units(system)
    deck = write_deck(convert(open(SPACECRAFT).read(), units), "units.dat")
    body = fem2modal(deck, Fem2ModalOptions(units=system, **OPTIONS))
    _same_body(reference, body)
    assert_allclose(body.reference_point, reference.reference_point, rtol=0, atol=1e-15)
    assert body.deck_units["spec"] == system
    assert body.deck_units["length"] == units.length and body.deck_units["mass"] == units.mass


def test_wtmass_deck_in_pound_mass(reference, write_deck):
    """Densities in lbm/in^3 and CONM2 masses in lbm with PARAM WTMASS = 1/386.0886 (the QRG's use of
    WTMASS): the same body."""
    units = parse_units("in,lbf,s")
    text = convert(open(SPACECRAFT).read(), units, mass_unit=POUND_MASS)
    text = text.replace("PARAM,COUPMASS,1", f"PARAM,COUPMASS,1\nPARAM,WTMASS,{0.0254 / 9.80665!r}")
    body = fem2modal(write_deck(text, "wtmass.dat"), Fem2ModalOptions(units="in,lbf,s", **OPTIONS))
    _same_body(reference, body)
    assert_allclose(body.deck_units["wtmass"], 1.0 / 386.08858267716535, rtol=1e-15)


def test_a_pound_inch_deck_read_as_si_is_warned_about(write_deck):
    deck = write_deck(convert(open(SPACECRAFT).read(), parse_units("in,lbf,s")), "inch.dat")
    with pytest.warns(UserWarning, match=r"SI \(no --units given\).*MAT1 1 rho = 0.000252.*kg/m\^3.*--units"):
        fem2modal(deck, Fem2ModalOptions(n_modes=2))


@pytest.mark.parametrize("text, match", [
    ("in,lbf", "three units"), ("in,lbf,lbm,s", "three units"), ("furlong,lbf,s", "unknown unit 'furlong'"),
    ("lbf,in,s", "unit 1 .'lbf'. is a force, expected a length"), ("in,lbf,h", "unknown unit 'h'"),
    ("in,s,s", "unit 2 .'s'. is a time, expected a force or mass")])
def test_unknown_or_inconsistent_systems_are_refused(text, match):
    with pytest.raises(UnitsError, match=match):
        parse_units(text)
    with pytest.raises(ValueError, match=match):
        fem2modal(SPACECRAFT, Fem2ModalOptions(n_modes=2, units=text))


def test_loads_recovery_in_other_units(write_deck):
    """The cantilever of configs/fem/cantilever_loads.dat (held at its root: the reference-acceleration columns
    are not zero) in mm,N,s: its recovery matrices (element forces, stresses at the PBAR stress points,
    interface forces) are the SI deck's."""
    deck = "configs/fem/cantilever_loads.dat"
    options = dict(n_modes=6, aset=[(1, [1, 2, 3, 4, 5, 6])], recover_elements=[101, 110], recover_grids=[1])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        a = fem2modal(deck, Fem2ModalOptions(**options))
        b = fem2modal(write_deck(convert(open(deck).read(), parse_units("mm,N,s")), "mm.dat"),
                      Fem2ModalOptions(units="mm,N,s", **options))
    la, lb = a.loads_recovery, b.loads_recovery
    assert la.names == lb.names and la.reaction == lb.reaction == "aset"
    for name in ("mode_displacement", "reference_acceleration"):
        x, y = getattr(la, name), getattr(lb, name)
        assert_allclose(y, x, rtol=0, atol=1e-9 * np.abs(x).max())
    assert np.abs(la.reference_acceleration).max() > 0


def test_derived_units():
    """lbf s^2/in = 175.126835 kg (the 'slinch'); N s^2/mm = 1 tonne; kg mm/s^2 = 1 mN."""
    assert_allclose(parse_units("in,lbf,s").mass, 4.4482216152605 / 0.0254, rtol=1e-15)
    assert_allclose(parse_units("mm,N,s").mass, 1000.0, rtol=1e-15)
    assert_allclose(parse_units("mm,kg,s").force, 1e-3, rtol=1e-15)
    assert_allclose(parse_units("ft,slug,s").force, 4.4482216152605, rtol=1e-15)


def _rotated_deck(text, R, csid_line):
    """The free-field deck with every GRID moved by the rotation R about the basic origin (CBAR
    orientation vectors turned too), plus ``csid_line``."""
    out = []
    for line in text.splitlines():
        f = line.split(",")
        if f[0] == "GRID":
            x = R @ np.array([float(v) for v in f[3:6]])
            f[3:6] = [repr(float(v)) for v in x]
        elif f[0] == "CBAR":
            v = R @ np.array([float(v) for v in f[5:8]])
            f[5:8] = [repr(float(c)) for c in v]
        out.append(",".join(f))
        if line.startswith("PARAM,GRDPNT"):
            out.append(csid_line)
    return "\n".join(out) + "\n"


def test_csid_output_frame_equals_the_unrotated_body(reference, write_deck, tmp_path):
    """The spacecraft turned by R in the deck, with a CORD2R whose axes are R's columns as --csid: in
    the CSID axes the body is the unturned one (mass properties, shapes, geometric-stiffness cases)."""
    c, s = np.cos(0.3), np.sin(0.3)
    R = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]) @ np.array([[1.0, 0, 0], [0, np.cos(0.7), -np.sin(0.7)],
                                                                       [0, np.sin(0.7), np.cos(0.7)]])
    z, x = R[:, 2].tolist(), (R[:, 0] + R[:, 2]).tolist()
    cord = f"CORD2R,9,,0.0,0.0,0.0,{z[0]!r},{z[1]!r},{z[2]!r}\n,{x[0]!r},{x[1]!r},{x[2]!r}"
    text = _rotated_deck(open(SPACECRAFT).read(), R, cord)
    # the CBUSH axes and the CONM2 inertias are given in basic (CID 0 / blank): turn them with the deck
    text = text.replace("CBUSH,162,5,176,177,,,,0", "CBUSH,162,5,176,177,,,,9")
    text = text.replace("CONM2,174,187,,", "CONM2,174,187,9,").replace("CONM2,175,188,,", "CONM2,175,188,9,")
    # the preload (basic axes) turned too: one entry per basic component, which add up
    load = -200.0 * R[:, 0]
    options = dict(OPTIONS, preloads=[("thrust", 187, k + 1, float(load[k])) for k in range(3)])
    body = fem2modal(write_deck(text, "turned.dat"), Fem2ModalOptions(csid=9, **options))
    assert_allclose(body.reference_point, R @ reference.reference_point, rtol=0, atol=1e-14)
    # a mode's sign is fixed in the deck's CD frames (pipeline.energy_signs), which the turn changes
    signs = np.sign(np.einsum("nak,nak->k", reference.translation_shapes, body.translation_shapes))
    body.translation_shapes *= signs
    body.rotation_shapes *= signs
    for name in ("translation", "rotation", "angular_velocity", "preload"):
        setattr(body.geometric_stiffness, name, getattr(body.geometric_stiffness, name) * np.outer(signs, signs))
    assert body.output_csid == 9
    assert_allclose(body.output_axes, R, atol=1e-15)
    _same_body(reference, body)
    path = tmp_path / "turned.h5"
    write_body_file(path, body)
    again = read_body_file(path)
    assert again.output_csid == 9 and np.array_equal(again.output_axes, body.output_axes)


def test_csid_must_be_rectangular(write_deck):
    text = open(SPACECRAFT).read().replace("PARAM,GRDPNT,1000",
                                           "PARAM,GRDPNT,1000\nCORD2C,4,,0.,0.,0.,0.,0.,1.\n,1.,0.,0.")
    with pytest.raises(ValueError, match="--csid 4 is a cylindrical system"):
        fem2modal(write_deck(text, "c.dat"), Fem2ModalOptions(n_modes=2, csid=4))


def test_command_line_prints_the_mass_in_both_systems_and_records_the_units(write_deck, tmp_path):
    deck = write_deck(convert(open(SPACECRAFT).read(), parse_units("in,lbf,s")), "inch.dat")
    out = tmp_path / "inch.h5"
    run = subprocess.run([sys.executable, "-m", "shell.cli", "fem2modal", deck, "--modes", "4", "--units",
                          "in,lbf,s", "-o", str(out)], capture_output=True, text=True)
    assert run.returncode == 0, run.stderr
    body = read_body_file(out)
    slinch = body.mass / parse_units("in,lbf,s").mass
    assert f"mass {body.mass:.6g} kg ({slinch:.6g} lbf*s^2/in in the deck's units in,lbf,s)" in run.stderr
    assert body.deck_units == {"spec": "in,lbf,s", "length": 0.0254, "mass": parse_units("in,lbf,s").mass,
                               "time": 1.0, "force": 4.4482216152605, "wtmass": 1.0}
    bad = subprocess.run([sys.executable, "-m", "shell.cli", "fem2modal", deck, "--modes", "4", "--units",
                          "in,lbf", "-o", str(out)], capture_output=True, text=True)
    assert bad.returncode == 1 and "three units" in bad.stderr
