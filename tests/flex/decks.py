"""Bulk-data text generators shared by the fem2modal tests and benchmarks (free-field cards)."""

from __future__ import annotations

import numpy as np

# Steel-like prismatic section used by the generated beams (SI units).
E, NU, RHO = 2.0e11, 0.3, 7800.0
A, I1, I2, J = 4.0e-4, 2.0e-8, 1.0e-8, 2.5e-8


def beam_deck(n_elements: int, length: float = 2.0, card: str = "CBAR", coupled: bool = True,
              clamp_root: bool = False, grdpnt: int | None = 1, extra: str = "",
              rho: float = RHO, wtmass: float | None = None, shear_k: float | None = None,
              with_header: bool = False) -> str:
    """A straight beam along basic x, grids 1..n+1, elements 101.., PBAR/PBEAM 10, MAT1 1."""
    lines = []
    if with_header:
        lines += ["SOL 103", "CEND", "SPC = 1", "BEGIN BULK"]
    if coupled:
        lines.append("PARAM,COUPMASS,1")
    if grdpnt:
        lines.append(f"PARAM,GRDPNT,{grdpnt}")
    if wtmass is not None:
        lines.append(f"PARAM,WTMASS,{wtmass!r}")
    x = np.linspace(0.0, length, n_elements + 1)
    for i, xi in enumerate(x):
        lines.append(f"GRID,{i + 1},,{float(xi)!r},0.0,0.0")
    lines.append(f"MAT1,1,{E!r},,{NU!r},{rho!r}")
    if card == "CBAR":
        lines.append(f"PBAR,10,1,{A!r},{I1!r},{I2!r},{J!r}")
    else:
        k = "" if shear_k is None else repr(shear_k)
        lines.append(f"PBEAM,10,1,{A!r},{I1!r},{I2!r},0.0,{J!r}")
        lines.append(",,,,,,,,")
        lines.append(f",{k if k else '0.0'},{k if k else '0.0'}")
    for i in range(n_elements):
        lines.append(f"{card},{101 + i},10,{i + 1},{i + 2},0.0,1.0,0.0")
    if clamp_root:
        lines.append("SPC1,1,123456,1")
    lines.append(extra)
    lines.append("ENDDATA")
    return "\n".join(lines) + "\n"


def five_particle_deck() -> str:
    """TM-2020-5008164 App. A.3: five 2 kg masses, four 1 N/m springs along x, other DOFs held."""
    lines = ["$ Five-particle spring-mass system, NASA/TM-2020-5008164 Appendix A.3 (Table A1)",
             "$ m = 2 (CONM2 on each grid), k = 1 (CELAS springs on component 1);",
             "$ the five unused DOFs of every grid are held by SPC1.",
             "SOL 103", "CEND", "SPC = 1", "BEGIN BULK"]
    for g in range(1, 6):
        lines.append(f"GRID,{g},,{float(g - 1)!r},0.0,0.0")
        lines.append(f"CONM2,{100 + g},{g},,2.0")
    lines.append("PELAS,7,1.0")
    lines.append("CELAS1,201,7,1,1,2,1")
    lines.append("CELAS1,202,7,2,1,3,1")
    lines.append("CELAS2,203,1.0,3,1,4,1")
    lines.append("CELAS2,204,1.0,4,1,5,1")
    lines.append("SPC1,1,23456,1,THRU,5")
    lines.append("ENDDATA")
    return "\n".join(lines) + "\n"


def single_length_beam_deck() -> str:
    """FModal paper App. C: 101 grids from 0 to 9 m on x, CBEAM 11.., PBEAM 50002, MAT1 1."""
    lines = ["$ Single-length beam, FModal paper (IEEE Aerospace 2023) Appendix C:",
             "$ 101 equally spaced grids on x from 0 to 9 m, identical CBEAMs, PBEAM 50002."]
    for i, xi in enumerate(np.linspace(0.0, 9.0, 101)):
        lines.append(f"GRID, {i + 1}, 0, {xi:.8e}, 0.0000000e+00, 0.0000000e+00, 0")
    for i in range(100):
        lines.append(f"CBEAM, {11 + i}, 50002, {i + 1}, {i + 2}, 0.0000E+00, 1.0000E+00, "
                     "0.0000E+00")
        lines.append(", , , 0.0000E+00, 0.0000E+00, 0.0000E+00, 0.0000E+00")
    lines += ["$*", "$*  MATERIAL CARD", "$*",
              "MAT1, 1, 2.000+9, 775193798.449612, , 8000.0, 12.000-6, 21.85000, 0.0",
              "$*", "$*  PROPERTY CARD", "$*",
              "PBEAM, 50002, 1, 2.000E-02, 6.66666667E-05, 1.66666667E-05, 0.0000E+00, "
              "8.33333333E-05, 0.0000E+00",
              ", 0.0000E+00, 0.0000E+00, 0.0000E+00, 0.0000E+00, 0.0000E+00, 0.0000E+00, "
              "0.0000E+00, 0.0000E+00",
              ", 0.0000E+00, 0.0000E+00, 0.0000E+00, 0.0000E+00, 0.0000E+00, 0.0000E+00, "
              "0.0000E+00, 0.0000E+00",
              ", 0.0000E+00, 0.0000E+00, 0.0000E+00, 0.0000E+00, 0.0000E+00, 0.0000E+00, "
              "0.0000E+00, 0.0000E+00",
              "ENDDATA"]
    return "\n".join(lines) + "\n"


def quad_cards(gid, nx: int, ny: int, pid: int = 1) -> list[str]:
    """CQUAD4 cards 1, 2, ... of an nx x ny grid of quadrilaterals (rows j, then columns i), corners
    gid(i, j), gid(i + 1, j), gid(i + 1, j + 1), gid(i, j + 1)."""
    return [f"CQUAD4,{1 + i + nx * j},{pid},{gid(i, j)},{gid(i + 1, j)},{gid(i + 1, j + 1)},{gid(i, j + 1)}"
            for j in range(ny) for i in range(nx)]


def plate_deck(n: int, a: float = 1.0, b: float = 1.0, t: float = 0.01, edges: str = "SSSS",
               coupled: bool = True, triangles: bool = False, in_plane_held: bool = True,
               mid3: bool = True, ny: int | None = None) -> str:
    """Flat rectangular plate in the basic x-y plane, n x ny CQUAD4 (or 2 n ny CTRIA3), PSHELL 1.

    ``edges``: boundary of the edges x = 0, y = 0, x = a, y = b, each S (hard simply supported:
    w and the rotation about the edge normal held), C (clamped) or F (free).
    ``in_plane_held``: GRID PS 126 on every grid, so only plate (w, theta_x, theta_y) modes remain.
    """
    lines = []
    if coupled:
        lines.append("PARAM,COUPMASS,1")
    ps = "126" if in_plane_held else ""
    m = n if ny is None else ny
    nid = lambda i, j: 1 + i + (n + 1) * j      # noqa: E731
    for j in range(m + 1):
        for i in range(n + 1):
            lines.append(f"GRID,{nid(i, j)},,{a * i / n!r},{b * j / m!r},0.0,,{ps}")
    lines.append(f"MAT1,1,{E!r},,{NU!r},{RHO!r}")
    lines.append(f"PSHELL,1,1,{t!r},1,,{'1' if mid3 else ''}")
    eid = 1
    for j in range(m):
        for i in range(n):
            g = (nid(i, j), nid(i + 1, j), nid(i + 1, j + 1), nid(i, j + 1))
            if triangles:
                lines.append(f"CTRIA3,{eid},1,{g[0]},{g[1]},{g[2]}")
                lines.append(f"CTRIA3,{eid + 1},1,{g[0]},{g[2]},{g[3]}")
                eid += 2
            else:
                lines.append(f"CQUAD4,{eid},1,{g[0]},{g[1]},{g[2]},{g[3]}")
                eid += 1
    held = {"S": {0: "34", 1: "35"}, "C": {0: "345", 1: "345"}, "F": {0: "", 1: ""}}
    for edge, kind in enumerate(edges):
        comps = held[kind][edge % 2]    # x = const edges: theta_x along the edge is held (S)
        if not comps:
            continue
        if edge == 0:
            grids = [nid(0, j) for j in range(m + 1)]
        elif edge == 2:
            grids = [nid(n, j) for j in range(m + 1)]
        elif edge == 1:
            grids = [nid(i, 0) for i in range(n + 1)]
        else:
            grids = [nid(i, m) for i in range(n + 1)]
        lines += [f"SPC1,1,{comps},{g}" for g in grids]
    lines.append("ENDDATA")
    return "\n".join(lines) + "\n"


def solid_bar_deck(nx: int, ny: int, nz: int, length: float, width: float, height: float,
                   element: str = "CHEXA8", nu: float = 0.0, clamp_root: bool = True,
                   coupled: bool = True) -> str:
    """Prismatic bar along x from solids: CHEXA8/CHEXA20 bricks, or each brick split into six
    CTETRA4/CTETRA10 (Kuhn split along the brick diagonal, conforming in a structured mesh), or
    two CPENTA6/CPENTA15 wedges. Grid ids 1 + i + (nx+1)(j + (ny+1) k) on the corner lattice; mid-edge
    grids of the quadratic elements follow. ``clamp_root``: SPC1 123 on the x = 0 face."""
    lines = ["SOL 103", "CEND", "SPC = 1", "BEGIN BULK"]
    if coupled:
        lines.append("PARAM,COUPMASS,1")
    quadratic = element in ("CHEXA20", "CTETRA10", "CPENTA15")
    # lattice with spacing h/2 for quadratic elements so mid-edge grids are lattice points
    f = 2 if quadratic else 1
    mx, my, mz = f * nx, f * ny, f * nz
    gid = lambda i, j, k: 1 + i + (mx + 1) * (j + (my + 1) * k)      # noqa: E731
    used = set()
    elements = []
    corner = [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0), (0, 0, 1), (1, 0, 1), (1, 1, 1),
              (0, 1, 1)]
    kuhn = [(0, 1, 2, 6), (0, 2, 3, 6), (0, 3, 7, 6), (0, 7, 4, 6), (0, 4, 5, 6), (0, 5, 1, 6)]
    hex_edges = [(0, 1), (1, 2), (2, 3), (3, 0), (0, 4), (1, 5), (2, 6), (3, 7), (4, 5), (5, 6),
                 (6, 7), (7, 4)]
    tet_edges = [(0, 1), (1, 2), (2, 0), (0, 3), (1, 3), (2, 3)]
    penta_edges = [(0, 1), (1, 2), (2, 0), (0, 3), (1, 4), (2, 5), (3, 4), (4, 5), (5, 3)]
    for k in range(nz):
        for j in range(ny):
            for i in range(nx):
                c = [(f * (i + a), f * (j + b), f * (k + d)) for a, b, d in corner]

                def mid(p, q):
                    return tuple((p[t] + q[t]) // 2 for t in range(3))
                if element == "CHEXA8":
                    elements.append(("CHEXA", c))
                elif element == "CHEXA20":
                    elements.append(("CHEXA", c + [mid(c[a], c[b]) for a, b in hex_edges]))
                elif element in ("CTETRA4", "CTETRA10"):
                    for tet in kuhn:
                        v = [c[t] for t in tet]
                        if element == "CTETRA10":
                            v += [mid(v[a], v[b]) for a, b in tet_edges]
                        elements.append(("CTETRA", v))
                elif element in ("CPENTA6", "CPENTA15"):
                    for v in ([c[0], c[1], c[2], c[4], c[5], c[6]], [c[0], c[2], c[3], c[4], c[6], c[7]]):
                        if element == "CPENTA15":
                            v = v + [mid(v[a], v[b]) for a, b in penta_edges]
                        elements.append(("CPENTA", v))
                else:
                    raise ValueError(element)
    for _, v in elements:
        used.update(v)
    for (i, j, k) in sorted(used, key=lambda p: gid(*p)):
        lines.append(f"GRID,{gid(i, j, k)},,{length * i / mx!r},{width * j / my!r},"
                     f"{height * k / mz!r}")
    lines.append(f"MAT1,1,{E!r},,{nu!r},{RHO!r}")
    lines.append("PSOLID,1,1")
    for e, (card, v) in enumerate(elements):
        ids = [str(gid(*p)) for p in v]
        fields = [card, str(e + 1), "1"] + ids
        # free-field continuation every 8 data fields
        text = ",".join(fields[:9])
        rest = fields[9:]
        while rest:
            text += "\n," + ",".join(rest[:8])
            rest = rest[8:]
        lines.append(text)
    if clamp_root:
        lines += [f"SPC1,1,123,{gid(0, j, k)}" for (i, j, k) in sorted(used) if i == 0]
    lines.append("ENDDATA")
    return "\n".join(lines) + "\n"
