"""CQUAD8 and CTRIA6 (dynamics/flex/quadratic_shells.py): patch tests, zero-energy modes, the simply supported
plate against the exact Mindlin (Navier) solution, Leissa's cantilever plate at thin limits, and a curved
ring against the inextensional ring modes (references: tests/flex/test_shells.py's docstring).
"""

import warnings

import numpy as np
import pytest
from numpy.testing import assert_allclose

import decks
from dynamics.flex import quadratic_shells as qs
from dynamics.flex.pipeline import Fem2ModalOptions, fem2modal
from dynamics.flex.shells import isotropic_props
from test_shells import PATCH, PATCH_QUADS, mindlin_ss_frequency

E, NU, RHO = decks.E, decks.NU, decks.RHO
EDGES = {8: [(0, 1), (1, 2), (2, 3), (3, 0)], 6: [(0, 1), (1, 2), (2, 0)]}


def _with_midsides(points, elements, n):
    """Grids and connectivity with mid-side grids at the edge midpoints (shared between elements)."""
    pts = [tuple(p) for p in points]
    index = {}
    out = []
    for conn in elements:
        extra = []
        for a, b in EDGES[n]:
            key = tuple(sorted((conn[a], conn[b])))
            if key not in index:
                index[key] = len(pts)
                pts.append(tuple((np.asarray(pts[conn[a]]) + pts[conn[b]]) / 2))
            extra.append(index[key])
        out.append(list(conn) + extra)
    return np.array(pts), out


def _patch_mesh(n):
    elements = PATCH_QUADS if n == 8 else [(q[0], q[1], q[2]) for q in PATCH_QUADS] + \
        [(q[0], q[2], q[3]) for q in PATCH_QUADS]
    pts2, conn = _with_midsides(PATCH, elements, n)
    return np.column_stack([pts2, np.zeros(len(pts2))]), conn


def _assemble(pts, conn, t, n):
    """Dense K, M of the elements ``conn`` (CQUAD8 for n = 8; CTRIA6, as its four CTRIA3, for n = 6)."""
    from dynamics.flex.shells import shell_batch
    conn = np.array(conn)
    xyz = pts[conn]
    props = np.tile(isotropic_props(E, NU, RHO, t), (len(conn), 1))
    if n == 8:
        Ke, Me, _ = qs.cquad8_batch(xyz, props, True)
    else:
        xyz, props, local = qs.tria6_parts(xyz, props)
        conn = np.take_along_axis(np.repeat(conn, 4, axis=0), local, axis=1)
        Ke, Me, _ = shell_batch(xyz, props, True)
    nd = 6 * len(pts)
    K, M = np.zeros((nd, nd)), np.zeros((nd, nd))
    for e, c in enumerate(conn):
        d = (6 * np.asarray(c)[:, None] + np.arange(6)).ravel()
        K[np.ix_(d, d)] += Ke[e]
        M[np.ix_(d, d)] += Me[e]
    return K, M


def _field(pts, kind):
    x, y = pts[:, 0], pts[:, 1]
    u = np.zeros((len(pts), 6))
    if kind == "membrane":
        u[:, 0] = 1e-3 * (x + 0.5 * y)
        u[:, 1] = 1e-3 * (y + 0.5 * x)
    else:                                         # constant curvature, no transverse shear
        u[:, 2] = 1e-3 * 0.5 * (x ** 2 + x * y + y ** 2)
        u[:, 3] = 1e-3 * (0.5 * x + y)            # theta_x = w,y
        u[:, 4] = -1e-3 * (x + 0.5 * y)           # theta_y = -w,x
    return u.ravel()


@pytest.mark.parametrize("n", [8, 6], ids=["CQUAD8", "CTRIA6"])
@pytest.mark.parametrize("kind", ["membrane", "bending"])
@pytest.mark.parametrize("t", [1e-3, 1e-1])
def test_patch_test(n, kind, t):
    """MacNeal-Harder patch with mid-side grids: the boundary grids take the exact constant-strain (or
    constant-curvature) field, the interior ones must come out exact: to round-off, 3e-8 of the field (the
    drilling rotation is held only by its penalty, whose round-off the thin element amplifies: 1.6e-8 at
    t = 1e-3, as the flat shells' patch test explains)."""
    pts, conn = _patch_mesh(n)
    K, _ = _assemble(pts, conn, t, n)
    x, y = pts[:, 0], pts[:, 1]
    boundary = np.isclose(x, 0) | np.isclose(x, 0.24) | np.isclose(y, 0) | np.isclose(y, 0.12)
    b = np.nonzero(np.repeat(boundary, 6))[0]
    i = np.nonzero(~np.repeat(boundary, 6))[0]
    exact = _field(pts, kind)
    ui = np.linalg.solve(K[np.ix_(i, i)], -K[np.ix_(i, b)] @ exact[b])
    assert_allclose(ui, exact[i], rtol=0, atol=3e-8 * np.abs(exact).max())


@pytest.mark.parametrize("n", [8, 6], ids=["CQUAD8", "CTRIA6"])
@pytest.mark.parametrize("curved", [False, True])
def test_one_free_element_has_six_rigid_modes_and_no_other_zero_energy_mode(n, curved):
    """A single free element (flat, or on a cylinder of radius 0.5 across it): exactly six zero eigenvalues of
    K, the next 2e-9 of the largest or more (thin-shell bending against membrane), no spurious mode (a CQUAD8
    with the 2 x 2 rule on membrane and shear had one at 2e-15)."""
    corners = np.array([[0.0, 0.0], [0.3, 0.02], [0.28, 0.25], [0.02, 0.22]])[:4 if n == 8 else 3]
    pts2, conn = _with_midsides(corners, [list(range(len(corners)))], n)
    z = 0.5 - np.sqrt(0.25 - (pts2[:, 0] - 0.15) ** 2) if curved else np.zeros(len(pts2))
    K, _ = _assemble(np.column_stack([pts2, z]), conn, 0.01, n)
    # eigenvalues of K with the rotations scaled by the element size (0.3 m), so all DOFs are commensurate
    d = np.tile(np.r_[np.ones(3), np.full(3, 0.3)], len(pts2))
    lam = np.linalg.eigvalsh(d[:, None] * K * d)
    assert np.all(np.abs(lam[:6]) < 1e-12 * lam[-1])
    assert lam[6] > 1e-10 * lam[-1]                  # measured >= 1e-8.7
    # the rigid motions carry no strain energy
    rng = np.random.default_rng(1)
    t, th = rng.standard_normal(3), rng.standard_normal(3)
    pts = np.column_stack([pts2, z])
    rigid = np.concatenate([np.r_[t + np.cross(th, p), th] for p in pts])
    assert abs(rigid @ K @ rigid) < 1e-12 * np.abs(K).max() * rigid @ rigid


def quadratic_plate_deck(n, a=1.0, t=0.01, edges="SSSS", triangles=False):
    """decks.plate_deck's square plate with CQUAD8 (or CTRIA6) on the same n x n corner lattice, mid-side grids
    at the edge midpoints: the lattice of half the spacing."""
    m = 2 * n
    nid = lambda i, j: 1 + i + (m + 1) * j      # noqa: E731
    lines = ["PARAM,COUPMASS,1"]
    used = set()
    elements = []
    for j in range(0, m, 2):
        for i in range(0, m, 2):
            c = [(i, j), (i + 2, j), (i + 2, j + 2), (i, j + 2)]
            mid = lambda p, q: ((p[0] + q[0]) // 2, (p[1] + q[1]) // 2)      # noqa: E731
            if triangles:
                for tri in ((c[0], c[1], c[2]), (c[0], c[2], c[3])):
                    elements.append(("CTRIA6", list(tri) + [mid(tri[0], tri[1]), mid(tri[1], tri[2]),
                                                            mid(tri[2], tri[0])]))
            else:
                elements.append(("CQUAD8", c + [mid(c[k], c[(k + 1) % 4]) for k in range(4)]))
    for _, v in elements:
        used.update(v)
    for (i, j) in sorted(used, key=lambda p: nid(*p)):
        lines.append(f"GRID,{nid(i, j)},,{a * i / m!r},{a * j / m!r},0.0,,126")
    lines.append(f"MAT1,1,{E!r},,{NU!r},{RHO!r}")
    lines.append(f"PSHELL,1,1,{t!r},1,,1")
    for e, (card, v) in enumerate(elements):
        ids = [str(nid(*p)) for p in v]
        lines.append(f"{card},{e + 1},1," + ",".join(ids[:6]) + ("\n," + ",".join(ids[6:]) if ids[6:] else ""))
    held = {"S": {0: "34", 1: "35"}, "C": {0: "345", 1: "345"}, "F": {0: "", 1: ""}}
    for edge, kind in enumerate(edges):
        comps = held[kind][edge % 2]
        if not comps:
            continue
        on = [p for p in used if (edge == 0 and p[0] == 0) or (edge == 2 and p[0] == m)
              or (edge == 1 and p[1] == 0) or (edge == 3 and p[1] == m)]
        lines += [f"SPC1,1,{comps},{nid(*p)}" for p in sorted(on)]
    return "\n".join(lines + ["ENDDATA"]) + "\n"


def _frequencies(write_deck, text, count, name):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return fem2modal(write_deck(text, name), Fem2ModalOptions(n_modes=count)).frequencies_hz


# measured errors, modes (1,1) (1,2) (2,1) (2,2): CQUAD8 at 4 / 8 per side 2.8e-3 1.6e-2 1.6e-2 3.4e-2 /
# 1.8e-4 1.1e-3 1.1e-3 2.6e-3 (rate 3.9); the same at t/a = 1e-3 (no shear locking); CTRIA6 (four MITC3+ each) at
# 8 / 16 as CTRIA3 at 16 / 32 (test_shells.py): 9.0e-3 .. 3.6e-2 / 2.2e-3 .. 8.8e-3, rate 2
@pytest.mark.parametrize("triangles, meshes, bound, rate", [(False, (4, 8), 3e-3, 3.5), (True, (8, 16), 1e-2, 1.9)],
                         ids=["CQUAD8", "CTRIA6"])
@pytest.mark.parametrize("t", [1e-2, 1e-3])
def test_simply_supported_plate_against_the_navier_solution(write_deck, triangles, meshes, bound, rate, t):
    a = 1.0
    exact = np.sort([mindlin_ss_frequency(m, k, a, a, t) for m, k in [(1, 1), (1, 2), (2, 1), (2, 2)]])
    errs = []
    for n in meshes:
        f = _frequencies(write_deck, quadratic_plate_deck(n, a, t, triangles=triangles), 4, f"q{n}.dat")
        errs.append(np.abs(f - exact) / exact)
    errs = np.array(errs)
    print("SS plate", "CTRIA6" if triangles else "CQUAD8", t, errs)
    assert np.all(errs[-1] < bound)
    assert np.all(np.log2(errs[0] / errs[1]) > rate)


@pytest.mark.parametrize("triangles", [False, True], ids=["CQUAD8", "CTRIA6"])
@pytest.mark.parametrize("t", [1e-2, 1e-3])
def test_cantilever_plate_against_leissa(write_deck, t, triangles):
    """Leissa's CFFF square plate, 8 x 8 elements: shear locking would stiffen the thin plate."""
    a = 1.0
    D = E * t ** 3 / (12 * (1 - NU ** 2))
    lam = np.array([3.4917, 8.5246, 21.429, 27.331, 31.111])
    leissa = lam / a ** 2 * np.sqrt(D / (RHO * t)) / (2 * np.pi)
    f = _frequencies(write_deck, quadratic_plate_deck(8, a, t, edges="CFFF", triangles=triangles), 5, "cfff.dat")
    print("cantilever", "CTRIA6" if triangles else "CQUAD8", t, f / leissa - 1)
    assert_allclose(f, leissa, rtol=1e-2)


def _ring8_deck(n, radius=1.0, length=0.05, t=0.01):
    """Cylinder slice of n CQUAD8 around (mid-side grids on the circle: curved elements), axial translation
    held: the in-plane modes of a thin ring, nu = 0."""
    lines = ["PARAM,COUPMASS,1"]
    for k in range(2 * n):
        phi = np.pi * k / n
        x, y = float(radius * np.cos(phi)), float(radius * np.sin(phi))
        lines.append(f"GRID,{k + 1},,{x!r},{y!r},0.0,,3")
        lines.append(f"GRID,{2 * n + k + 1},,{x!r},{y!r},{length!r},,3")
        if k % 2 == 0:
            lines.append(f"GRID,{4 * n + k + 1},,{x!r},{y!r},{length / 2!r},,3")
    lines.append(f"MAT1,1,{E!r},,0.0,{RHO!r}")
    lines.append(f"PSHELL,1,1,{t!r},1,,1")
    for k in range(n):
        a, mid, b = 2 * k, 2 * k + 1, (2 * k + 2) % (2 * n)
        g = (a + 1, b + 1, 2 * n + b + 1, 2 * n + a + 1, mid + 1, 4 * n + b + 1, 2 * n + mid + 1, 4 * n + a + 1)
        lines.append(f"CQUAD8,{k + 1},1," + ",".join(map(str, g[:6])) + "\n," + ",".join(map(str, g[6:])))
    return "\n".join(lines + ["ENDDATA"]) + "\n"


def test_curved_cquad8_ring_modes(write_deck):
    """Inextensional ring modes n = 2, 3, 4 (Soedel eq. 5.3.12), curved CQUAD8 with 16 and 32 around."""
    R, Lz, t = 1.0, 0.05, 0.01
    I, A = Lz * t ** 3 / 12, Lz * t
    k = np.array([2.0, 3.0, 4.0])
    exact = np.sqrt(E * I * k ** 2 * (k ** 2 - 1) ** 2 / (RHO * A * R ** 4 * (k ** 2 + 1))) / (2 * np.pi)
    errs = []
    for n in (16, 32):
        f = _frequencies(write_deck, _ring8_deck(n, R, Lz, t), 6, f"ring{n}.dat")
        assert_allclose(f[0::2], f[1::2], rtol=1e-8)
        errs.append(np.abs(f[0::2] / exact - 1))
    print("curved ring", errs)
    assert np.all(errs[-1] < 1e-2)
