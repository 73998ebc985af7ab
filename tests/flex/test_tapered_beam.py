"""Tapered PBEAM (stations with different A, I1, I2, J): the element of
:func:`dynamics.flex.elements.tapered_beam_local_matrices` against an independent reference.

Reference: the same continuous beam (A, I1, I2, J linear in x between the stations) meshed
with many short *prismatic* CBEAMs whose sections are the values at their midpoints (the
prismatic element of beam_local_matrices, a different code path); the stepped model converges
to the continuous one at O(h^2), so two meshes (N, 2N) extrapolated by Richardson give the
continuous eigenvalues to O(h^4).
"""

import warnings

import numpy as np
import pytest
from numpy.testing import assert_allclose
from pyNastran.bdf.bdf import BDF

from dynamics.flex import elements as el
from dynamics.flex.bulk_data import BulkDataError
from dynamics.flex.pipeline import Fem2ModalOptions, fem2modal

L = 2.0
E, NU, RHO = 7.0e10, 0.33, 2700.0
# root (x = 0) and tip (x = L) sections of a tapered aluminium cantilever
ROOT = dict(A=8e-4, I1=2.7e-8, I2=1.1e-7, J=5e-8)
TIP = dict(A=4e-4, I1=1.3e-8, I2=0.5e-7, J=2e-8)


def _pbeam(pid, root, tip):
    m = BDF(debug=None)
    p = m.add_pbeam(pid, 1, [0.0, 1.0], ["YES", "YES"], [root["A"], tip["A"]],
                    [root["I1"], tip["I1"]], [root["I2"], tip["I2"]], [0.0, 0.0],
                    [root["J"], tip["J"]], [0.0, 0.0])
    return p.write_card()


def _deck(n, tapered, coupled=True):
    lines = ["SOL 103", "CEND", "SPC = 1", "BEGIN BULK"]
    if coupled:
        lines.append("PARAM,COUPMASS,1")
    lines.append(f"MAT1,1,{E!r},,{NU!r},{RHO!r}")
    for i in range(n + 1):
        lines.append(f"GRID,{i + 1},,{L * i / n!r},0.0,0.0")
    for i in range(n):
        if tapered:
            s0, s1 = i / n, (i + 1) / n
            root = {k: ROOT[k] + (TIP[k] - ROOT[k]) * s0 for k in ROOT}
            tip = {k: ROOT[k] + (TIP[k] - ROOT[k]) * s1 for k in ROOT}
            lines.append(_pbeam(100 + i, root, tip).rstrip())
        else:
            s = (i + 0.5) / n
            sec = {k: ROOT[k] + (TIP[k] - ROOT[k]) * s for k in ROOT}
            lines.append(_pbeam(100 + i, sec, sec).rstrip())
        lines.append(f"CBEAM,{i + 1},{100 + i},{i + 1},{i + 2},0.0,1.0,0.0")
    lines.append("SPC1,1,123456,1")
    lines.append("ENDDATA")
    return "\n".join(lines) + "\n"


def _frequencies(write_deck, n, tapered, modes=8, coupled=True):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        body = fem2modal(write_deck(_deck(n, tapered, coupled), f"b{n}{tapered}.dat"),
                         Fem2ModalOptions(n_modes=modes))
    return body.frequencies_hz


def test_prismatic_stations_reproduce_the_prismatic_element():
    """Equal stations: the flexibility-based stiffness equals the closed-form element to
    round-off (with shear flexibility); consistent mass equal without shear (phi = 0)."""
    sec = np.array([[ROOT["A"], ROOT["I1"], ROOT["I2"], ROOT["J"], 0.0]] * 3)
    G = E / (2 * (1 + NU))
    for k in (0.0, 1.0):
        Kp, Mp = el.beam_local_matrices(0.3, E, G, ROOT["A"], ROOT["I1"], ROOT["I2"],
                                        ROOT["J"], RHO * ROOT["A"], k, k, True, True)
        Kt, Mt = el.tapered_beam_local_matrices(0.3, E, G, np.array([0.0, 0.3, 1.0]), sec, RHO,
                                                k, k, True, True)
        assert_allclose(Kt, Kp, rtol=0, atol=1e-12 * np.abs(Kp).max())
        if k == 0.0:
            assert_allclose(Mt, Mp, rtol=0, atol=1e-14 * np.abs(Mp).max())


def test_tapered_cantilever_converges_to_the_stepped_reference(write_deck):
    """Eight lowest modes (bending in both planes, torsion, axial). Reference: stepped prismatic
    meshes of 80 and 160 elements, Richardson-extrapolated (their errors are -4e-5 and -1e-5
    and fall exactly 4x per halving, so the extrapolated reference is good to well below the
    1e-5 level compared here). Tapered elements, N = 4, 8, 16: errors above 1e-5 fall at least
    5x per halving (measured 5.7 - 24: bending at O(h^4), axial and torsion faster than
    O(h^2)), 8 elements are within 0.6 % (the issue's 1 %), 16 within 5e-4 (measured 4.8e-4
    for mode 8, 5e-8 for mode 1)."""
    f80 = _frequencies(write_deck, 80, False)
    f160 = _frequencies(write_deck, 160, False)
    ref = f160 + (f160 - f80) / 3.0
    assert np.max(np.abs(f160 / ref - 1)) < 2e-5
    errs = [np.abs(_frequencies(write_deck, n, True) / ref - 1) for n in (4, 8, 16)]
    assert np.all(errs[1] < 6e-3)
    assert np.all(errs[2] < 5e-4)
    for coarse, fine in zip(errs[:-1], errs[1:]):
        big = coarse > 1e-5
        assert np.all(coarse[big] / fine[big] > 5.0)


def test_lumped_mass_of_a_tapered_beam_keeps_its_total_and_first_moment():
    """Lever rule: end masses sum to int mu and their moment about end A equals int mu x."""
    G = E / (2 * (1 + NU))
    sec = np.array([[ROOT[k] for k in ("A", "I1", "I2", "J")] + [0.1],
                    [TIP[k] for k in ("A", "I1", "I2", "J")] + [0.05]])
    _, M = el.tapered_beam_local_matrices(L, E, G, np.array([0.0, 1.0]), sec, RHO, 1.0, 1.0,
                                          False, True)
    mu0, mu1 = RHO * ROOT["A"] + 0.1, RHO * TIP["A"] + 0.05
    total = 0.5 * (mu0 + mu1) * L
    first = L * L * (mu0 / 6 + mu1 / 3)
    assert M[0, 0] + M[6, 6] == pytest.approx(total, rel=1e-14)
    assert M[6, 6] * L == pytest.approx(first, rel=1e-14)


def test_tapered_pbeam_with_bad_stations_is_refused(write_deck):
    text = _deck(2, True)
    mid = {k: 0.5 * (ROOT[k] + TIP[k]) for k in ROOT}
    good = _pbeam(100, ROOT, mid).rstrip()
    assert good in text
    bad = text.replace(good, _pbeam(100, ROOT, dict(mid, A=-1e-4)).rstrip())
    with pytest.raises(BulkDataError, match="PBEAM 100 has A"):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            fem2modal(write_deck(bad), Fem2ModalOptions(n_modes=2))


def test_cli_reads_a_tapered_pbeam_deck(write_deck, tmp_path, capsys):
    """The user's path: `flexshell fem2modal deck.dat` on a tapered cantilever writes a body
    file whose frequencies are the pipeline's."""
    from shell.cli import main
    from dynamics.flex.body_file import read_body_file
    deck = write_deck(_deck(8, True), "tapered.dat")
    out = tmp_path / "tapered.h5"
    rc = main(["fem2modal", deck, "--modes", "4", "-o", str(out)])
    err = capsys.readouterr().err
    assert rc == 0 and out.exists(), err
    body = read_body_file(out)
    assert_allclose(body.frequencies_hz, _frequencies(write_deck, 8, True, modes=4), rtol=1e-12)
