"""Agreement with MSC Nastran where public results exist.

pyNastran's repository ships MSC Nastran 2005r2 output for models/beam_modes/beam_modes.dat
(+ cbar_cbeam.blk): a 10 m cantilever of nine CBARs (PBARL ROD, r = 1) and one CBEAM (PBEAML
ROD), a 2.59e-3 CONM2 with inertia at the tip, MAT1 E = 3e7, G = 1.1628e7, nu = 0.29,
rho = 7.4851e-4, lumped mass, grid 1 clamped, grid 12 unconnected. The deck below transcribes
that model; the reference eigenvalues are the f06's REAL EIGENVALUES table
(models/beam_modes/beam_modes.f06, page 13).
"""

import warnings

import numpy as np
from numpy.testing import assert_allclose

from dynamics.flex.pipeline import Fem2ModalOptions, fem2modal

NASTRAN_EIGENVALUES = np.array([8.232776e+06, 8.232776e+06, 2.824056e+08, 2.824056e+08,
                                4.989076e+08, 8.021004e+08, 1.733310e+09, 1.733310e+09,
                                4.874295e+09, 4.874295e+09])


def _beam_modes_deck():
    lines = ["SOL 103", "CEND", "SPC = 1", "BEGIN BULK", "PARAM,GRDPNT,0"]
    lines += [f"GRID,{g},0,{float(g - 1)!r},0.0,0.0,0" for g in range(1, 12)]
    lines.append("GRID,12,0,5.49607,0.0,0.0,0")
    lines += [f"CBAR,{e},1,{e},{e + 1},0.0,1.0,0.0" for e in range(1, 10)]
    lines.append("CBEAM,10,3,10,11,0.0,1.0,0.0")
    lines.append("CONM2,21,11,0,2.59e-3,0.0,0.0,0.0\n,2.59e-3,0.0,2.59e-3,0.0,0.0,2.59e-3")
    lines.append("MAT1,2,3.0e7,1.1628e7,0.29,7.4851e-4,0.0,,0.0")
    lines.append("PBARL,1,2,MSCBML0,ROD\n,1.0,0.0")
    lines.append("PBEAML,3,2,MSCBML0,ROD\n,1.0,0.0")
    lines.append("SPC,1,1,123456,0.0")
    return "\n".join(lines + ["ENDDATA"]) + "\n"


def test_cantilever_of_cbar_and_cbeam_matches_msc_nastran(write_deck):
    """All ten eigenvalues (bending in both planes with shear flexibility, torsion, axial) to
    the f06's printed precision: 7 significant digits, half a unit in the last place is at most
    5e-7 relative; observed 1.5e-7."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        body = fem2modal(write_deck(_beam_modes_deck()), Fem2ModalOptions(n_modes=10))
    eigenvalues = (2 * np.pi * body.frequencies_hz) ** 2
    assert_allclose(eigenvalues, NASTRAN_EIGENVALUES, rtol=5e-7)
