"""CHEXA8 (incompatible modes), CHEXA20, CTETRA4, CTETRA10, CPENTA6, CPENTA15 with PSOLID/MAT1: patch tests,
axial bar modes against the closed form with convergence rates, slender cantilever bending
against Euler-Bernoulli, a thick block across element families.

References:
* Solid patch: MacNeal & Harder, Finite Elements in Analysis and Design 1 (1985) 3-20, fig. 3:
  unit cube, interior grids (0.249, 0.342, 0.192), (0.826, 0.288, 0.288), (0.850, 0.649, 0.263),
  (0.273, 0.750, 0.230), (0.320, 0.186, 0.643), (0.677, 0.305, 0.683), (0.788, 0.693, 0.644),
  (0.165, 0.745, 0.702); seven hexahedra (tetrahedra: Delaunay of the same 16 points).
* Clamped-free bar with nu = 0: plane sections stay plane, so the 3-D axial modes are the 1-D
  ones, f_k = (2k - 1) c / (4 L), c = sqrt(E / rho) (e.g. Blevins, Formulas for Natural
  Frequency and Mode Shape, Table 8-16). Linear elements converge as h^2, quadratic as h^4
  (Strang & Fix, sec. 6.3).
* Slender cantilever: Euler-Bernoulli beta_1 L = 1.8751040687 (Blevins Table 8-1); shear and
  rotary inertia at b / L = 0.05 raise the 3-D value's difference to ~1e-3.
"""

import warnings

import numpy as np
import pytest
from numpy.testing import assert_allclose
from scipy.spatial import Delaunay

import decks
from dynamics.flex import solids
from dynamics.flex.pipeline import Fem2ModalOptions, fem2modal

E, RHO = decks.E, decks.RHO
INNER = np.array([[0.249, 0.342, 0.192], [0.826, 0.288, 0.288], [0.850, 0.649, 0.263],
                  [0.273, 0.750, 0.230], [0.320, 0.186, 0.643], [0.677, 0.305, 0.683],
                  [0.788, 0.693, 0.644], [0.165, 0.745, 0.702]])
CUBE = solids._HEX_CORNERS * 0.5 + 0.5
FACES = [(0, 1, 2, 3), (4, 5, 6, 7), (0, 1, 5, 4), (3, 2, 6, 7), (0, 3, 7, 4), (1, 2, 6, 5)]


def _hex_patch():
    pts = np.vstack([CUBE, INNER])
    elems = [list(range(8, 16))]
    for face in FACES:
        conn = list(face) + [8 + v for v in face]
        xyz = pts[conn]
        _, dN = solids.shape(solids.HEXA8, np.zeros(3))
        if np.linalg.det(dN @ xyz) < 0:
            conn = [8 + v for v in face] + list(face)
        elems.append(conn)
    return pts, elems


def _with_mid_edges(pts, elems, edges):
    pts = [tuple(p) for p in pts]
    index = {p: i for i, p in enumerate(pts)}
    out = []
    for conn in elems:
        extra = []
        for a, b in edges:
            key = tuple(np.round((np.asarray(pts[conn[a]]) + pts[conn[b]]) / 2, 14))
            if key not in index:
                index[key] = len(pts)
                pts.append(key)
            extra.append(index[key])
        out.append(list(conn) + extra)
    return np.array(pts), out


def _patch(kind):
    if kind in (solids.HEXA8, solids.HEXA20):
        pts, elems = _hex_patch()
        if kind == solids.HEXA20:
            pts, elems = _with_mid_edges(pts, elems, solids._HEX_EDGES)
    elif kind in (solids.TETRA4, solids.TETRA10):
        pts = np.vstack([CUBE, INNER])
        elems = []
        for simplex in Delaunay(pts).simplices:
            conn = list(simplex)
            L = pts[conn[1:]] - pts[conn[0]]
            if np.linalg.det(L) < 0:
                conn[1], conn[2] = conn[2], conn[1]
            elems.append(conn)
        if kind == solids.TETRA10:
            pts, elems = _with_mid_edges(pts, elems, solids._TET_EDGES)
    else:     # wedges: the MacNeal-Harder 2-D patch triangulated, two layers, wavy middle
        p2 = np.array([[0.0, 0.0], [0.24, 0.0], [0.24, 0.12], [0.0, 0.12], [0.04, 0.02],
                       [0.18, 0.03], [0.16, 0.08], [0.08, 0.08]])
        tri = Delaunay(p2).simplices
        z = [np.zeros(8), 0.05 + 0.01 * np.sin(7 * np.arange(8)), np.full(8, 0.1)]
        pts = np.vstack([np.column_stack([p2, zz]) for zz in z])
        elems = []
        for layer in range(2):
            for t in tri:
                t = list(t)
                a = p2[t[1]] - p2[t[0]]
                b = p2[t[2]] - p2[t[0]]
                if a[0] * b[1] - a[1] * b[0] < 0:
                    t[1], t[2] = t[2], t[1]
                elems.append([8 * layer + v for v in t] + [8 * (layer + 1) + v for v in t])
        if kind == solids.PENTA15:
            pts, elems = _with_mid_edges(pts, elems, [(0, 1), (1, 2), (2, 0), (0, 3), (1, 4), (2, 5), (3, 4),
                                                      (4, 5), (5, 3)])
    return np.asarray(pts, float), elems


def _on_boundary(pts, kind):
    if kind in (solids.PENTA6, solids.PENTA15):
        x, y, z = pts.T
        return (np.isclose(x, 0) | np.isclose(x, 0.24) | np.isclose(y, 0) | np.isclose(y, 0.12)
                | np.isclose(z, 0) | np.isclose(z, 0.1))
    return np.any(np.isclose(pts, 0.0) | np.isclose(pts, 1.0), axis=1)


@pytest.mark.parametrize("kind", [solids.HEXA8, solids.HEXA20, solids.TETRA4, solids.TETRA10,
                                  solids.PENTA6, solids.PENTA15], ids=lambda k: solids.NAMES[k])
def test_patch_test(kind):
    """Exact linear displacement on the boundary grids: the interior grids take the exact values
    (every element reproduces constant strain, including the incompatible-mode CHEXA8)."""
    pts, elems = _patch(kind)
    n = len(pts)
    pw, ww = solids.RULES[kind]
    xyz = pts[np.array(elems)]
    Ke, _, _ = solids.solid_batch(kind, xyz, np.tile([E, 0.3, RHO], (len(elems), 1)), pw, ww,
                                  True)
    K = np.zeros((3 * n, 3 * n))
    for e, conn in enumerate(elems):
        d = (3 * np.asarray(conn)[:, None] + np.arange(3)).ravel()
        K[np.ix_(d, d)] += Ke[e]
    A = 1e-3 * np.array([[1.0, 0.2, -0.4], [0.5, -0.7, 0.3], [0.1, 0.6, 0.9]])
    exact = (pts @ A.T).ravel()
    bnd = _on_boundary(pts, kind)
    assert (~bnd).sum() >= 4
    b = np.nonzero(np.repeat(bnd, 3))[0]
    i = np.nonzero(~np.repeat(bnd, 3))[0]
    ui = np.linalg.solve(K[np.ix_(i, i)], -K[np.ix_(i, b)] @ exact[b])
    # round-off: a few 1e-16 times the condition of K_ii (~1e3 here)
    assert_allclose(ui, exact[i], rtol=0, atol=1e-11 * np.abs(exact).max())


def _modes(write_deck, text, count, name):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return fem2modal(write_deck(text, name), Fem2ModalOptions(n_modes=count))


def _axial_frequency(body):
    tx = np.sum(body.translation_shapes[:, 0, :] ** 2 * body.node_mass[:, None], axis=0)
    tot = np.sum(np.sum(body.translation_shapes ** 2, axis=1) * body.node_mass[:, None], axis=0)
    return body.frequencies_hz[tx / tot > 0.99][0]


# measured errors of the first axial mode at 4 / 8 / 16 elements along the bar:
#   CHEXA8 6.4e-3 1.6e-3 4.0e-4 | CHEXA20 1.6e-5 1.0e-6 | CTETRA4 4.8e-3 1.9e-3 |
#   CTETRA10 1.2e-5 5.9e-7 | CPENTA6 5.6e-3 1.7e-3 | CPENTA15 (2 / 4 / 8) 2.4e-4 1.4e-5 7.6e-7, rate 4.18
@pytest.mark.parametrize("element,meshes,order", [
    ("CHEXA8", (4, 8, 16), 2), ("CHEXA20", (2, 4, 8), 4), ("CTETRA4", (4, 8, 16), 2),
    ("CTETRA10", (2, 4, 8), 4), ("CPENTA6", (4, 8, 16), 2), ("CPENTA15", (2, 4, 8), 4)])
def test_axial_bar_modes_converge_at_the_element_order(write_deck, element, meshes, order):
    L = 1.0
    exact = np.sqrt(E / RHO) / (4 * L)
    errs = []
    for n in meshes:
        body = _modes(write_deck, decks.solid_bar_deck(n, 1, 1, L, 0.1, 0.1, element), 12,
                      f"{element}{n}.dat")
        errs.append(abs(_axial_frequency(body) / exact - 1))
    rates = np.log2(np.array(errs[:-1]) / np.array(errs[1:]))
    print(element, "axial errors", errs, "rates", rates)
    assert errs[-1] < 1e-2
    assert rates[-1] > order - 0.15


@pytest.mark.parametrize("element,n,bound", [("CHEXA8", 20, 1e-2), ("CHEXA20", 10, 5e-3),
                                             ("CTETRA10", 10, 5e-3)])
def test_slender_cantilever_bending(write_deck, element, n, bound):
    """20:1 square bar (b/L = 0.05), one element (CHEXA8: the incompatible modes carry the
    bending) across the section; Euler-Bernoulli within the bound (3-D effects ~1e-3)."""
    L, b = 1.0, 0.05
    body = _modes(write_deck, decks.solid_bar_deck(n, 1, 1, L, b, b, element), 2,
                  f"cant{element}.dat")
    I, A = b**4 / 12, b * b
    exact = 1.8751040687**2 * np.sqrt(E * I / (RHO * A * L**4)) / (2 * np.pi)
    assert_allclose(body.frequencies_hz, [exact, exact], rtol=bound)


def test_thick_block_agrees_across_element_families(write_deck):
    """Clamped cube (nu = 0.3), lowest frequency: CHEXA20 and CTETRA10 at 4^3, CHEXA8 at 8^3
    converge to one value; no closed form exists, so the families check each other."""
    f = {}
    for element, n in (("CHEXA20", 4), ("CTETRA10", 4), ("CHEXA8", 8)):
        body = _modes(write_deck, decks.solid_bar_deck(n, n, n, 1.0, 1.0, 1.0, element, nu=0.3),
                      3, f"block{element}.dat")
        f[element] = body.frequencies_hz[0]
    print("thick block", f)
    assert abs(f["CTETRA10"] / f["CHEXA20"] - 1) < 5e-3
    assert abs(f["CHEXA8"] / f["CHEXA20"] - 1) < 1e-2
