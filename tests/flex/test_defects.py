"""Regression tests for the defects of issue 16 that plain beam decks hit (each failed before).

References are independent of the code under test: closed forms, brute-force dense LAPACK on
the same matrices, a 40-digit inverse iteration on the same matrices, or an equivalent deck.
"""

import os
import warnings

import mpmath
import numpy as np
import pytest
import scipy.linalg as sla
from numpy.testing import assert_allclose

import decks
from dynamics.flex.assembly import assemble
from dynamics.flex.bulk_data import read_bulk_data
from dynamics.flex.modes import lowest_modes
from dynamics.flex.pipeline import Fem2ModalOptions, fem2modal
from shell.cli import main

CONFIGS = os.path.join(os.path.dirname(__file__), "..", "..", "configs", "fem")


def _conm2_with_inertia(grids):
    return "\n".join(f"CONM2,{900 + g},{g},,1.0\n,1.0,,1.0,,,1.0" for g in grids)


def _quiet(fn, *a, **k):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return fn(*a, **k)


@pytest.mark.parametrize("aset", [None, [(1, [1, 2, 3, 4, 5, 6])]], ids=["free-free", "component"])
def test_near_rigid_round_off_modes_are_not_kept_as_flexible(write_deck, aset):
    """200 stiff, short CBARs (1206 DOFs: the sparse path) with CONM2 rotary inertias: round-off
    put the computed rigid-body modes at +-1e-4 Hz; the free-free run stopped with 'negative
    eigenvalue -1.4e-06', the component run kept a 1.2e-4 Hz mode as flexible (5 rigid)."""
    deck = write_deck(decks.beam_deck(200, 2.0, coupled=False,
                                      extra=_conm2_with_inertia(range(1, 202))))
    body = _quiet(fem2modal, deck, Fem2ModalOptions(n_modes=6, aset=aset or []))
    assert body.n_rigid_modes_removed == 6
    sm = _quiet(assemble, read_bulk_data(deck))
    K, M = sm.stiffness_f().toarray(), sm.mass_f().toarray()
    lam, vec = sla.eigh(K, M, subset_by_index=[0, 40])
    # brute force: dense LAPACK, the 35 flexible modes above the six near-zero ones, their
    # eigenvalues as Rayleigh quotients of LAPACK's vectors (LAPACK's own eigenvalues are 1e-7
    # off on this stiffness-to-mass range, 1e11)
    rq = np.einsum("ij,ij->j", vec, K @ vec) / np.einsum("ij,ij->j", vec, M @ vec)
    reference = np.sqrt(rq[6:]) / (2 * np.pi)
    assert reference[0] > 1e3 * np.sqrt(np.abs(lam[:6]).max()) / (2 * np.pi)
    if aset is None:
        # 1.2e-10 measured: the float64 floor of the quotients on this range
        assert_allclose(body.frequencies_hz, reference[:6], rtol=1e-9)
    else:
        # Ritz (component modes) bound the eigenvalues from above; all well clear of zero
        assert np.all(body.frequencies_hz >= reference[:6] * (1 - 1e-9))
        assert body.frequencies_hz[0] > 0.5
    assert_allclose(body.modal_mass, np.eye(6), atol=1e-10)


def test_lumped_cbar_component_split_condenses_the_massless_spin(write_deck):
    """Lumped-mass CBAR: the spin of the line about its axis moves only massless rotations and
    has no strain energy. With interface grids in the a-set this stopped with 'K - sigma M is
    not positive definite'; then one DOF was held, which gave the interface's constraint mode a torsional
    spring the beam does not have. Now (issue 33) the interface restrains the spin, nothing is held: the
    spin's constraint mode is a massless rigid motion (removed), the twist between the two interface grids
    a quasi-static mode (kept), and the flexible frequencies are those of the deck where the user holds the
    spin with an SPC, within the truncation of 8 fixed-interface modes."""
    deck = write_deck(decks.beam_deck(10, 2.0, coupled=False), "lumped.dat")
    aset = [(1, [1, 2, 3, 4, 5, 6]), (11, [1, 2, 3, 4, 5, 6])]
    with warnings.catch_warnings():
        warnings.simplefilter("error", UserWarning)
        warnings.filterwarnings("ignore", message=".*principal moments of inertia")
        body = fem2modal(deck, Fem2ModalOptions(n_modes=8, aset=aset))
    assert body.n_rigid_modes_removed == 5          # no rotation about the beam axis
    assert body.n_quasi_static == 1
    twist = body.rotation_shapes[:, 0, -1]          # the quasi-static mode: rotation about x only
    assert np.abs(body.translation_shapes[:, :, -1]).max() < 1e-9 * np.abs(twist).max()
    assert_allclose(twist, twist[0] * np.linspace(1.0, -1.0, 11) if twist[0] != 0 else twist,
                    atol=1e-9 * abs(twist).max())
    held = write_deck(decks.beam_deck(10, 2.0, coupled=False, extra="SPC1,1,4,6",
                                      with_header=True), "held.dat")
    free = _quiet(fem2modal, deck, Fem2ModalOptions(n_modes=8))
    user = _quiet(fem2modal, held, Fem2ModalOptions(n_modes=8))
    assert_allclose(free.frequencies_hz, user.frequencies_hz, rtol=1e-11)
    # the component modes span the whole model here (interior modes + both ends): Ritz values
    # above the full-model ones, the lowest within the truncation of 8 fixed-interface modes
    assert np.all(body.frequencies_hz[:4] >= free.frequencies_hz[:4] * (1 - 1e-10))
    assert_allclose(body.frequencies_hz[:2], free.frequencies_hz[:2], rtol=1e-2)


def test_lumped_cbar_reports_the_missing_rotary_inertia(write_deck):
    deck = write_deck(decks.beam_deck(10, 2.0, coupled=False))
    with pytest.warns(UserWarning, match=r"principal moments.*\[0\.0, .*axis\(es\) \[\[1\.0, 0\.0, 0\.0\]\]"
                      r".*CONM2 I11-I33"):
        fem2modal(deck, Fem2ModalOptions(n_modes=3))


def _chain_deck(spc_style: str) -> str:
    """TM App. A.3 five-particle chain with the unused DOFs held by SPC1, GRID PS or GRDSET."""
    lines = ["SOL 103", "CEND", "SPC = 1", "BEGIN BULK"]
    if spc_style == "GRDSET":
        lines.append("GRDSET,,,,,,,23456")
    for g in range(1, 6):
        ps = "23456" if spc_style == "PS" else ""
        lines.append(f"GRID,{g},,{float(g - 1)!r},0.0,0.0,,{ps}")
        lines.append(f"CONM2,{100 + g},{g},,2.0")
    lines += [f"CELAS2,{200 + g},1.0,{g},1,{g + 1},1" for g in range(1, 5)]
    if spc_style == "SPC1":
        lines.append("SPC1,1,23456,1,THRU,5")
    return "\n".join(lines + ["ENDDATA"]) + "\n"


@pytest.mark.parametrize("style", ["SPC1", "PS", "GRDSET"])
def test_grid_ps_and_grdset_hold_the_dofs(write_deck, style):
    """Chain of five 2 kg masses and 1 N/m springs: omega_j^2 = (2 k / m)(1 - cos(j pi / 5)),
    j = 1..4 (free-free spring-mass chain, e.g. Meirovitch, Fundamentals of Vibrations, 2001,
    sec. 7.x; TM-2020-5008164 Table A1). The PS field used to be ignored (the run failed)."""
    body = _quiet(fem2modal, write_deck(_chain_deck(style)), Fem2ModalOptions(n_modes=4))
    exact = np.sqrt(1.0 - np.cos(np.arange(1, 5) * np.pi / 5)) / (2 * np.pi)
    assert_allclose(body.frequencies_hz, exact, rtol=1e-13)
    assert body.n_rigid_modes_removed == 1
    if style == "GRDSET":
        assert any("GRDSET" in line and "PS to 5 grid(s)" in line for line in body.card_report)


def test_shipped_simple_beam_has_no_unreadable_card():
    bulk = _quiet(read_bulk_data, os.path.join(CONFIGS, "SimpleBeam.dat"))
    assert not bulk.report.parse_errors
    assert not any("unreadable" in line for line in bulk.report.lines())


def _mp_lowest_eigenvalue(K, M, dps=40, iterations=40):
    """Lowest eigenvalue of (K, M) (banded, SPD) by inverse iteration in ``dps`` digits."""
    mpmath.mp.dps = dps
    n = K.shape[0]
    rows, cols = np.nonzero(K)
    bw = int(np.max(np.abs(rows - cols)))
    band = lambda i: range(max(0, i - bw), min(n, i + bw + 1))   # noqa: E731
    Kb = {(i, j): mpmath.mpf(float(K[i, j])) for i in range(n) for j in band(i)}
    Mb = {(i, j): mpmath.mpf(float(M[i, j])) for i in range(n) for j in band(i)}
    A = dict(Kb)
    for k in range(n):                     # banded Gaussian elimination (SPD: no pivoting)
        for i in range(k + 1, min(n, k + bw + 1)):
            f = A[i, k] / A[k, k]
            for j in range(k, min(n, k + bw + 1)):
                A[i, j] -= f * A[k, j]
            A[i, k] = f

    def solve(b):
        y = list(b)
        for i in range(n):
            for k in range(max(0, i - bw), i):
                y[i] -= A[i, k] * y[k]
        x = [mpmath.mpf(0)] * n
        for i in reversed(range(n)):
            x[i] = (y[i] - sum(A[i, j] * x[j] for j in range(i + 1, min(n, i + bw + 1)))) / A[i, i]
        return x

    def mul(B, x):
        return [sum(B[i, j] * x[j] for j in band(i)) for i in range(n)]

    x = [mpmath.mpf(1)] * n
    for _ in range(iterations):             # lambda_1 / lambda_2 = 1/39: 1e-60 after 40
        x = solve(mul(Mb, x))
        top = max(abs(v) for v in x)
        x = [v / top for v in x]
    return float(sum(a * b for a, b in zip(x, mul(Kb, x))) / sum(a * b for a, b in zip(x, mul(Mb, x))))


def test_long_cantilever_lowest_eigenvalue_is_refined(write_deck):
    """300 m CBEAM cantilever, 120 elements (720 DOFs: shift-invert Lanczos). Its stiffness-to-
    mass ratios span ~1e9 x the lowest eigenvalue; ARPACK's Ritz value was 2e-8 off (plain
    LAPACK on the same plane-2 matrices: 4e-6). Reference: the same plane-2 (w, theta_y)
    matrices, which decouple from the rest for a straight beam, solved in 40 digits. Refined,
    with the quotients summed in extended precision, the error is 7e-13 - 9e-12 over five ARPACK
    start vectors (float64 sums: 1e-11 - 4e-9); bound 3e-11."""
    deck = write_deck(decks.beam_deck(120, 300.0, clamp_root=True, card="CBEAM"))
    sm = _quiet(assemble, read_bulk_data(deck))
    K, M = sm.stiffness_f(), sm.mass_f()
    sol = lowest_modes(K, M, n_modes=4, groups=sm.f_dofs // 6)
    plane2 = np.nonzero(np.isin(sm.f_dofs % 6, [2, 4]))[0]
    ref = _mp_lowest_eigenvalue(K[plane2][:, plane2].toarray(), M[plane2][:, plane2].toarray())
    assert abs(sol.eigenvalues[0] - ref) / ref < 3e-11


@pytest.mark.parametrize("args,option", [
    (["--modes", "0"], "--modes"), (["--cutoff", "-1"], "--cutoff"),
    (["--cutoff", "nan"], "--cutoff"), (["--modes", "3", "--damping", "-2"], "--damping"),
    (["--modes", "3", "--rigid-threshold", "inf"], "--rigid-threshold")])
def test_cli_refuses_bad_counts_and_ratios(tmp_path, capsys, args, option):
    out = tmp_path / "b.h5"
    rc = main(["fem2modal", os.path.join(CONFIGS, "SimpleBeam.dat"), *args, "-q", "-o", str(out)])
    err = capsys.readouterr().err
    assert rc == 1 and f"error: {option}" in err and not out.exists()


def test_cli_says_which_frequencies_component_modes_have(tmp_path, capsys):
    out = tmp_path / "c.h5"
    rc = main(["fem2modal", os.path.join(CONFIGS, "SimpleBeam.dat"), "--modes", "4",
               "--aset", "1:123456", "-o", str(out)])
    err = capsys.readouterr().err
    assert rc == 0
    assert "fixed-interface frequencies (interface grids [1] held)" in err
    assert "free-free frequencies of the unmounted component" in err
    assert "child_grid" in err


def test_mounting_warnings_for_component_modes(write_deck):
    deck = write_deck(decks.beam_deck(10, 2.0))
    body = _quiet(fem2modal, deck, Fem2ModalOptions(n_modes=4, aset=[(1, [1, 2, 3, 4, 5, 6])]))
    assert any("without child_grid" in w for w in body.mounting_warnings(None, "locked"))
    assert body.mounting_warnings(1, "locked") == []
    assert any("not an interface" in w for w in body.mounting_warnings(5, "revolute"))
    assert any("duplicates" in w for w in body.mounting_warnings(1, "free"))
    free = _quiet(fem2modal, deck, Fem2ModalOptions(n_modes=4))
    assert free.mounting_warnings(None, "free") == []


def test_a_pin_inside_the_model_is_a_mechanism_mode_not_a_flexible_one(write_deck):
    """Two CBEAM beams joined by an RBE2 on components 12345 (a pin about z): six rigid-body modes
    from the geometry plus one zero-energy mechanism, removed together and reported (the run
    stopped on 'negative eigenvalue' before). Flexible modes against dense LAPACK on the same
    matrices (Rayleigh quotients; its seven lowest are the zero-energy ones)."""
    second = "\n".join(f"GRID,{1001 + i},,{2.0 + 0.25 * i!r},0.0,0.0" for i in range(9))
    second += "\n" + "\n".join(f"CBEAM,{2001 + i},10,{1001 + i},{1002 + i},0.0,1.0,0.0"
                               for i in range(8))
    pin = second + "\nRBE2,5001,9,12345,1001"
    deck = decks.beam_deck(8, 2.0, card="CBEAM", extra=pin)
    with pytest.warns(UserWarning, match="1 mechanism mode"):
        body = fem2modal(write_deck(deck, "pin.dat"), Fem2ModalOptions(n_modes=4))
    assert body.n_rigid_modes_removed == 7
    sm = _quiet(assemble, read_bulk_data(write_deck(deck, "pin2.dat")))
    K, M = sm.stiffness_f().toarray(), sm.mass_f().toarray()
    lam, vec = sla.eigh(K, M, subset_by_index=[0, 10])
    rq = np.einsum("ij,ij->j", vec, K @ vec) / np.einsum("ij,ij->j", vec, M @ vec)
    assert np.abs(rq[:7]).max() < 1e-9 * rq[7]
    assert_allclose(body.frequencies_hz, np.sqrt(rq[7:11]) / (2 * np.pi), rtol=1e-9)
    assert_allclose(body.modal_mass, np.eye(4), atol=1e-10)


def test_the_scene_builder_warns_about_mounting_component_modes(write_deck):
    """``Multibody.add_flexible_body`` passes the body file's mounting checks on as warnings naming the body:
    normalized component modes on a hinge without child_grid, child_grid on a free hinge; none for the
    correct mounting, nor for a free body without child_grid (nothing to hold)."""
    import warnings

    from dynamics import Multibody

    deck = write_deck(decks.beam_deck(10, 2.0))
    body = _quiet(fem2modal, deck, Fem2ModalOptions(n_modes=4, aset=[(1, [1, 2, 3, 4, 5, 6])], modal_integrals=True))

    def messages(**kwargs):
        mb = Multibody()
        mb.add_body("bus", None, mass=10.0, inertia=[1.0, 1.0, 1.0], hinge="free")
        mb.add_node("port", "bus")
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            mb.add_flexible_body("beam", "bus", modal=body, parent_node="port", **kwargs)
        return [str(w.message) for w in caught if "body 'beam'" in str(w.message)]

    assert any("without child_grid" in m for m in messages(hinge="locked"))
    assert messages(hinge="locked", child_grid=1) == []
    # on a free hinge this lumped-mass beam (no rotary inertia about its axis) is then refused, naming the axis
    from dynamics import ModelDefinitionError

    for child_grid, expect_duplicate in ((1, True), (None, False)):
        mb = Multibody()
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            with pytest.raises(ModelDefinitionError, match=r"free hinge .* none about \[\[1\.0, 0\.0, 0\.0\]\]"):
                mb.add_flexible_body("beam", None, modal=body, hinge="free", child_grid=child_grid)
        found = [str(w.message) for w in caught if "body 'beam'" in str(w.message) and "child_grid" in str(w.message)]
        assert bool(found) == expect_duplicate and all("duplicates" in m for m in found)
