"""Decks for the geometric stiffening of shells and solids (issue 15): a plate strip and a slender solid
cantilever equivalent to the rotating beam of :mod:`tests.flex.rotating_beam` (L 1 m, rho A 1 kg/m, EI 1 N m^2
flapwise, so frequencies in rad/s are the dimensionless ones and the spin rate in rad/s is lambda), and a
simply supported square plate under uniform in-plane compression.

Poisson's ratio is 0 in the strip and the solid, so that the plate's bending stiffness D b and the solid's
E I equal the beam's EI exactly (no anticlastic or Poisson coupling to model).
"""

from __future__ import annotations

import numpy as np

import decks

STRIP_WIDTH, STRIP_THICKNESS = 0.05, 0.01
STRIP_E = 12.0 / (STRIP_THICKNESS ** 3 * STRIP_WIDTH)      # D b = E t^3 b / 12 = 1 N m^2
STRIP_RHO = 1.0 / (STRIP_THICKNESS * STRIP_WIDTH)          # rho t b = 1 kg/m
STRIP_EI_CHORD = STRIP_E * STRIP_THICKNESS * STRIP_WIDTH ** 3 / 12.0   # in-plane bending, 25 N m^2
SOLID_WIDTH, SOLID_HEIGHT = 0.06, 0.04                    # along y and z: flapwise bending is along z
SOLID_E = 12.0 / (SOLID_WIDTH * SOLID_HEIGHT ** 3)       # E I_y = 1 N m^2 (flapwise)
SOLID_RHO = 1.0 / (SOLID_WIDTH * SOLID_HEIGHT)           # rho A = 1 kg/m


def strip_grid(i, j, nx):
    return 1 + i + (nx + 1) * j


def plate_strip_deck(nx=40, ny=2, root_grid=True, coupled=True) -> str:
    """CQUAD4 strip along basic x in the x-y plane, L 1 m, width 0.05 m (centred on y = 0), t 0.01 m, nu 0,
    PSHELL with MID2 (bending) and MID3 (transverse shear). ``root_grid``: grid 9001 at the root's centre
    joined to the root edge by an RBE2 (123456), the grid a hub holds (a-set, ``child_grid``); else the root
    edge is clamped by SPCs. Grids ``strip_grid(i, j)``; the tip centre is ``strip_grid(nx, ny // 2)``."""
    lines = ["$ plate strip equivalent to the unit rotating beam (issue 15)"]
    if coupled:
        lines.append("PARAM,COUPMASS,1")
    for j in range(ny + 1):
        for i in range(nx + 1):
            y = -0.5 * STRIP_WIDTH + STRIP_WIDTH * j / ny
            lines.append(f"GRID,{strip_grid(i, j, nx)},,{i / nx!r},{y!r},0.0")
    lines.append(f"MAT1,1,{STRIP_E!r},,0.0,{STRIP_RHO!r}")
    lines.append(f"PSHELL,1,1,{STRIP_THICKNESS!r},1,,1")
    lines += decks.quad_cards(lambda i, j: strip_grid(i, j, nx), nx, ny)
    root = [strip_grid(0, j, nx) for j in range(ny + 1)]
    if root_grid:
        lines.append("GRID,9001,,0.0,0.0,0.0")
        lines.append("RBE2,9001,9001,123456," + ",".join(str(g) for g in root))
    else:
        lines += [f"SPC1,1,123456,{g}" for g in root]
    lines.append("ENDDATA")
    return "\n".join(lines) + "\n"


def solid_cantilever_deck(nx=40, nyz=2, root_grid=True, coupled=True) -> str:
    """CHEXA8 cantilever along basic x, L 1 m, 0.06 m (y) x 0.04 m (z) section centred on the x axis, nu 0; the root
    face joined by an RBE2 to grid 9001 (as :func:`plate_strip_deck`) or clamped (SPC 123). Grid of node
    (i, j, k): 1 + i + (nx + 1) (j + (nyz + 1) k); the tip centre is (nx, nyz / 2, nyz / 2) for even nyz."""
    def g(i, j, k):
        return 1 + i + (nx + 1) * (j + (nyz + 1) * k)

    lines = ["$ slender solid cantilever equivalent to the unit rotating beam (issue 15)"]
    if coupled:
        lines.append("PARAM,COUPMASS,1")
    for k in range(nyz + 1):
        for j in range(nyz + 1):
            for i in range(nx + 1):
                y = SOLID_WIDTH * (j / nyz - 0.5)
                z = SOLID_HEIGHT * (k / nyz - 0.5)
                lines.append(f"GRID,{g(i, j, k)},,{i / nx!r},{y!r},{z!r},,456")
    lines.append(f"MAT1,1,{SOLID_E!r},,0.0,{SOLID_RHO!r}")
    lines.append("PSOLID,1,1")
    e = 1
    for k in range(nyz):
        for j in range(nyz):
            for i in range(nx):
                c = [g(i, j, k), g(i + 1, j, k), g(i + 1, j + 1, k), g(i, j + 1, k),
                     g(i, j, k + 1), g(i + 1, j, k + 1), g(i + 1, j + 1, k + 1), g(i, j + 1, k + 1)]
                lines.append(f"CHEXA,{e},1," + ",".join(str(x) for x in c[:6]))
                lines.append("," + ",".join(str(x) for x in c[6:]))
                e += 1
    root = [g(0, j, k) for j in range(nyz + 1) for k in range(nyz + 1)]
    if root_grid:
        lines.append("GRID,9001,,0.0,0.0,0.0")
        lines.append("RBE2,9001,9001,123," + ",".join(str(x) for x in root))
    else:
        lines += [f"SPC1,1,123,{x}" for x in root]
    lines.append("ENDDATA")
    return "\n".join(lines) + "\n"


def solid_tip_grid(nx=40, nyz=2):
    return 1 + nx + (nx + 1) * (nyz // 2 + (nyz + 1) * (nyz // 2))


PLATE_E, PLATE_NU, PLATE_T, PLATE_RHO = 1.0e7, 0.3, 0.01, 100.0
PLATE_D = PLATE_E * PLATE_T ** 3 / (12.0 * (1.0 - PLATE_NU ** 2))


def plate_grid(i, j, n):
    return 1 + i + (n + 1) * j


def simply_supported_plate(n, triangles=False):
    """(deck, preload entries) of a unit square plate (t 0.01 m, E 1e7 Pa, nu 0.3, rho 100 kg/m^3) meshed
    n x n (CQUAD4, or two CTRIA3 per square), simply supported (w = 0 on the four edges), u held on the edge
    x = 0 and v at the corner (0, 0), compressed by a uniform edge load of 1 N/m along -x on the edge x = 1
    (consistent nodal forces: h per grid, h / 2 at the corners), as the entries of a preload named ``comp``."""
    h = 1.0 / n
    lines = ["PARAM,COUPMASS,1"]
    for j in range(n + 1):
        for i in range(n + 1):
            lines.append(f"GRID,{plate_grid(i, j, n)},,{i * h!r},{j * h!r},0.0")
    lines.append(f"MAT1,1,{PLATE_E!r},,{PLATE_NU!r},{PLATE_RHO!r}")
    lines.append(f"PSHELL,1,1,{PLATE_T!r},1,,1")
    e = 1
    for j in range(n):
        for i in range(n):
            c = [plate_grid(i, j, n), plate_grid(i + 1, j, n), plate_grid(i + 1, j + 1, n), plate_grid(i, j + 1, n)]
            if triangles:
                lines.append(f"CTRIA3,{e},1,{c[0]},{c[1]},{c[2]}")
                lines.append(f"CTRIA3,{e + 1},1,{c[0]},{c[2]},{c[3]}")
                e += 2
            else:
                lines.append(f"CQUAD4,{e},1,{c[0]},{c[1]},{c[2]},{c[3]}")
                e += 1
    edge = sorted({plate_grid(i, j, n) for i in range(n + 1) for j in range(n + 1) if i in (0, n) or j in (0, n)})
    lines += [f"SPC1,1,3,{g}" for g in edge]
    lines += [f"SPC1,1,1,{plate_grid(0, j, n)}" for j in range(n + 1)]
    lines.append(f"SPC1,1,2,{plate_grid(0, 0, n)}")
    lines.append("ENDDATA")
    preload = [("comp", plate_grid(n, j, n), 1, -(h / 2 if j in (0, n) else h)) for j in range(n + 1)]
    return "\n".join(lines) + "\n", preload


def plate_buckling_ratio(m, n_):
    """P / P_cr,mn per unit compression (1 N/m) of mode (m, n) of the unit square plate: the exact ratio in
    omega_mn^2 = omega0_mn^2 (1 - P / P_cr,mn), P_cr,mn = pi^2 D (m^2 + n^2)^2 / m^2 (Timoshenko & Gere,
    Theory of Elastic Stability, 1961, sec. 9.2; k = 4 for m = n = 1)."""
    return m * m / (np.pi ** 2 * PLATE_D * (m * m + n_ * n_) ** 2)
