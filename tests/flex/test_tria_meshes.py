"""CTRIA3 (MITC3+, :mod:`dynamics.flex.shells`) on the mesh patterns a mesher produces: both diagonal
directions, union jack (alternating diagonals), crossed (four triangles around a centre grid in every
square) and a distorted mesh (interior grids moved at random by up to 0.2 h in x and y).

References, as in test_shells.py: the exact Mindlin (Navier) solution of the hard simply supported
square plate (Mindlin, J. Appl. Mech. 18, 1951) and Leissa's CFFF square plate (NASA SP-160, Table
4.48: lambda = 3.4917, 8.5246, 21.429, 27.331, 31.111, nu = 0.3).
"""

import warnings
from math import factorial

import numpy as np
import pytest
from numpy.testing import assert_allclose

import decks
from dynamics.flex import shells
from dynamics.flex.pipeline import Fem2ModalOptions, fem2modal
from test_shells import E, NU, RHO, SS_MODES, mindlin_ss_frequency

LEISSA_CFFF = np.array([3.4917, 8.5246, 21.429, 27.331, 31.111])


def _pattern_deck(n, pattern, t, edges="SSSS", distortion=0.0, seed=7):
    """decks.plate_deck's square plate (grids, PSHELL, edge SPCs) with its CQUAD4s split into CTRIA3s:
    "right" (diagonal G1-G3), "left" (G2-G4), "union jack" (alternating) or "crossed" (a centre grid
    per square); ``distortion`` moves the interior grids by up to that fraction of h."""
    lines = decks.plate_deck(n, t=t, edges=edges).splitlines()
    grids = {}
    for ln in lines:
        if ln.startswith("GRID,"):
            f = ln.split(",")
            grids[int(f[1])] = np.array([float(f[3]), float(f[4])])
    rng = np.random.default_rng(seed)
    h = 1.0 / n
    for gid in sorted(grids):
        x, y = grids[gid]
        if distortion and 1e-9 < x < 1.0 - 1e-9 and 1e-9 < y < 1.0 - 1e-9:
            grids[gid] = grids[gid] + distortion * h * rng.uniform(-1.0, 1.0, 2)
    out, tri, next_grid = [], [], max(grids) + 1
    for ln in lines:
        if ln.startswith("GRID,"):
            continue
        if not ln.startswith("CQUAD4,"):
            out.append(ln)
            continue
        g = [int(v) for v in ln.split(",")[3:7]]
        i, j = (g[0] - 1) % (n + 1), (g[0] - 1) // (n + 1)
        kind = pattern if pattern != "union jack" else ("right", "left")[(i + j) % 2]
        if kind == "right":
            tri += [(g[0], g[1], g[2]), (g[0], g[2], g[3])]
        elif kind == "left":
            tri += [(g[0], g[1], g[3]), (g[1], g[2], g[3])]
        else:
            grids[next_grid] = np.mean([grids[k] for k in g], axis=0)
            tri += [(g[k], g[(k + 1) % 4], next_grid) for k in range(4)]
            next_grid += 1
    out = [f"GRID,{gid},,{float(x)!r},{float(y)!r},0.0,,126" for gid, (x, y) in sorted(grids.items())] + out
    body = [f"CTRIA3,{e + 1},1,{a},{b},{c}" for e, (a, b, c) in enumerate(tri)]
    return "\n".join(out[:-1] + body + ["ENDDATA"]) + "\n"


def _frequencies(write_deck, text, count, name):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return fem2modal(write_deck(text, name), Fem2ModalOptions(n_modes=count)).frequencies_hz


def test_both_diagonal_directions_give_the_same_plate(write_deck):
    """The "left" mesh is the mirror image of the "right" one and the simply supported plate is
    symmetric, so the frequencies must agree (to the eigen-solver's refined round-off: 1e-10)."""
    right = _frequencies(write_deck, _pattern_deck(16, "right", 0.01), 4, "r.dat")
    left = _frequencies(write_deck, _pattern_deck(16, "left", 0.01), 4, "l.dat")
    assert_allclose(left, right, rtol=1e-10)


def test_element_does_not_depend_on_the_node_numbering():
    """A triangle given as (1, 2, 3), (2, 3, 1) and (3, 1, 2): the same basic-frame stiffness and mass
    after the DOFs are put back in one order (MITC3+ is spatially isotropic; DSG3, for one, is not).
    1e-12 of the largest entry: the element frames differ, so the products round differently."""
    rng = np.random.default_rng(3)
    props = shells.isotropic_props(E, NU, RHO, 0.02)[None]
    xyz = np.array([[0.1, 0.0, 0.0], [1.0, 0.2, 0.1], [0.3, 0.9, -0.2]]) + 0.1 * rng.standard_normal((3, 3))
    ref_K, ref_M, _ = shells.shell_batch(xyz[None], props, True)
    for shift in (1, 2):
        order = np.roll(np.arange(3), -shift)
        K, M, _ = shells.shell_batch(xyz[order][None], props, True)
        dofs = (6 * order[:, None] + np.arange(6)).ravel()
        back = np.argsort(dofs)
        assert_allclose(K[0][np.ix_(back, back)], ref_K[0], rtol=0, atol=1e-12 * np.abs(ref_K).max())
        assert_allclose(M[0][np.ix_(back, back)], ref_M[0], rtol=0, atol=1e-12 * np.abs(ref_M).max())


def test_bending_rule_is_exact_to_degree_five():
    """Radon's 7-point rule integrates r^a s^b over the unit triangle to a! b! / (a + b + 2)! for
    a + b <= 5 (the MITC3+ bending energy is quartic); round-off only."""
    r, s, w = shells._TRI7.T
    for a in range(6):
        for b in range(6 - a):
            exact = factorial(a) * factorial(b) / factorial(a + b + 2)
            assert abs(0.5 * np.sum(w * r**a * s**b) - exact) < 1e-15


@pytest.mark.parametrize("pattern,distortion,bound", [("union jack", 0.0, 1.04e-2), ("crossed", 0.0, 4.5e-3),
                                                       ("right", 0.2, 1.06e-2)],
                         ids=["union jack", "crossed", "distorted"])
def test_simply_supported_plate_on_other_patterns(write_deck, pattern, distortion, bound):
    """Modes (1,1) (1,2) (2,1) (2,2), t/a = 0.01, 16 x 16 and 32 x 32 squares. Measured at 32
    (largest of the four, rate of the last halving): union jack 9.4e-3, 2.05-2.06; crossed 4.1e-3,
    2.04-2.05; distorted 9.6e-3, 2.01-2.06 (the regular "right" mesh: 8.8e-3, test_shells.py).
    Bounds: those values + 10 %, and O(h^2)."""
    t = 0.01
    exact = np.sort([mindlin_ss_frequency(m, k, 1.0, 1.0, t) for m, k in SS_MODES])
    errs = np.array([np.abs(_frequencies(write_deck, _pattern_deck(n, pattern, t, distortion=distortion), 4,
                                         f"p{n}.dat") / exact - 1) for n in (16, 32)])
    print(pattern, distortion, "errors", errs, "rates", np.log2(errs[0] / errs[1]))
    assert np.all(errs[1] < bound)
    assert np.all(np.log2(errs[0] / errs[1]) > 1.95)


@pytest.mark.parametrize("pattern,distortion", [("union jack", 0.0), ("crossed", 0.0), ("right", 0.2)],
                         ids=["union jack", "crossed", "distorted"])
def test_thin_cantilever_plate_on_other_patterns_does_not_lock(write_deck, pattern, distortion):
    """Leissa's CFFF plate at t/a = 1e-4 on a 16 x 16 mesh of each pattern; measured within
    -4.9e-3 .. +6.2e-3 (union jack), -5.3e-3 .. +0.1e-3 (crossed), -4.8e-3 .. +6.0e-3 (distorted);
    held to the 1 % of the regular mesh (test_shells.py). Locking would stiffen them by orders of
    magnitude (the MITC3 it replaced: +130 % on the regular mesh)."""
    t = 1e-4
    D = E * t**3 / (12 * (1 - NU**2))
    leissa = LEISSA_CFFF * np.sqrt(D / (RHO * t)) / (2 * np.pi)
    f = _frequencies(write_deck, _pattern_deck(16, pattern, t, edges="CFFF", distortion=distortion), 5,
                     "c.dat")
    print(pattern, distortion, "cantilever errors", f / leissa - 1)
    assert_allclose(f, leissa, rtol=1e-2)
