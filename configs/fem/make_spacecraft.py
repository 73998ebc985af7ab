"""Write configs/fem/spacecraft.dat: a worked example deck for fem2modal (issue 16).

A 1.0 x 1.0 x 1.2 m aluminium bus of CQUAD4 panels (10 mm equivalent skins), a 1 x 2 m solar
array panel (CQUAD4, honeycomb-equivalent MAT1) on a CBAR yoke from the +y face joined by a
CBUSH hinge spring and an RBE2 fitting along the panel's root edge, a 2 m CBAR antenna boom on the top face with a 5 kg CONM2 tip, and a 50 kg
payload CONM2 inside the bus carried by an RBE3 to four side-panel grids. SI units.

    python3 configs/fem/make_spacecraft.py                      (writes configs/fem/spacecraft.dat)
    flexshell fem2modal configs/fem/spacecraft.dat --modes 20 --modal-integrals \\
        --damping 0.005 -o configs/fem/spacecraft.h5
    flexshell run configs/fem/spacecraft_scene.yaml -o spacecraft_log.h5

``MASS_BUDGET`` lists the mass of each part for checks; ``spacecraft_deck()`` returns the deck
text and the grid ids of the places a scene puts nodes on (bus top centre, boom tip, array tip).
"""

from __future__ import annotations

from pathlib import Path

# bus: aluminium, grid spacing 0.25 m (x, y) and 0.2 m (z)
BUS = dict(size=(1.0, 1.0, 1.2), divisions=(4, 4, 6), t=0.01, E=70e9, nu=0.33, rho=2700.0)
ARRAY = dict(x=(0.0, 1.0), y=(1.5, 3.5), z=0.6, divisions=(4, 8), t=0.02, E=10e9, nu=0.3,
             rho=500.0)
YOKE = dict(A=1e-3, I=2e-6, J=4e-6, E=70e9, rho=2700.0)          # root (0.5, 1.0, 0.6) -> array
BOOM = dict(root=(0.5, 0.5, 1.2), length=2.0, elements=10, A=3e-4, I=5e-7, J=1e-6, E=70e9,
            rho=2700.0, tip_mass=5.0, tip_inertia=0.05)
PAYLOAD = dict(position=(0.5, 0.5, 0.4), mass=50.0, inertia=(4.0, 4.0, 3.0))
HINGE_STIFFNESS = (1e7, 1e7, 1e7, 2e4, 2e4, 2e4)               # CBUSH K1-K6 (N/m, N m/rad)


def _surface_area(size):
    a, b, c = size
    return 2 * (a * b + a * c + b * c)


MASS_BUDGET = {
    "bus panels": _surface_area(BUS["size"]) * BUS["t"] * BUS["rho"],
    "array panel": 1.0 * 2.0 * ARRAY["t"] * ARRAY["rho"],
    "yoke": 0.5 * YOKE["A"] * YOKE["rho"],
    "boom": BOOM["length"] * BOOM["A"] * BOOM["rho"],
    "boom tip": BOOM["tip_mass"],
    "payload": PAYLOAD["mass"],
}


def spacecraft_deck() -> tuple[str, dict]:
    lines = ["$ Worked example for fem2modal: bus of plates, solar array, antenna boom",
             "$ (written by configs/fem/make_spacecraft.py; SI units)",
             "SOL 103", "CEND", "BEGIN BULK", "PARAM,COUPMASS,1", "PARAM,GRDPNT,1000"]
    (a, b, c), (nx, ny, nz) = BUS["size"], BUS["divisions"]
    ids = {}

    def grid(key, xyz):
        if key not in ids:
            ids[key] = len(ids) + 1
            lines.append(f"GRID,{ids[key]},,{float(xyz[0])!r},{float(xyz[1])!r},{float(xyz[2])!r}")
        return ids[key]

    def bus_grid(i, j, k):
        return grid(("bus", i, j, k), (a * i / nx, b * j / ny, c * k / nz))

    eid = [0]

    def quad(pid, g):
        eid[0] += 1
        lines.append(f"CQUAD4,{eid[0]},{pid},{g[0]},{g[1]},{g[2]},{g[3]}")

    # six faces, corners ordered so that every normal points outwards
    for k in (0, nz):
        for i in range(nx):
            for j in range(ny):
                g = [bus_grid(i, j, k), bus_grid(i + 1, j, k), bus_grid(i + 1, j + 1, k),
                     bus_grid(i, j + 1, k)]
                quad(1, g if k == nz else g[::-1])
    for j in (0, ny):
        for i in range(nx):
            for k in range(nz):
                g = [bus_grid(i, j, k), bus_grid(i + 1, j, k), bus_grid(i + 1, j, k + 1),
                     bus_grid(i, j, k + 1)]
                quad(1, g if j == 0 else g[::-1])
    for i in (0, nx):
        for j in range(ny):
            for k in range(nz):
                g = [bus_grid(i, j, k), bus_grid(i, j + 1, k), bus_grid(i, j + 1, k + 1),
                     bus_grid(i, j, k + 1)]
                quad(1, g if i == nx else g[::-1])

    # solar array panel in the plane z = 0.6, root edge at y = 1.5
    (x0, x1), (y0, y1), z = ARRAY["x"], ARRAY["y"], ARRAY["z"]
    mx, my = ARRAY["divisions"]

    def array_grid(i, j):
        return grid(("array", i, j), (x0 + (x1 - x0) * i / mx, y0 + (y1 - y0) * j / my, z))
    for i in range(mx):
        for j in range(my):
            quad(2, [array_grid(i, j), array_grid(i + 1, j), array_grid(i + 1, j + 1),
                     array_grid(i, j + 1)])

    # yoke: bus +y face centre line at z = 0.6 to a hinge grid coincident with the array root
    yoke_root = bus_grid(nx // 2, ny, 3)
    yoke_end = grid("yoke end", (0.5, 1.5, z))
    eid[0] += 1
    lines.append(f"CBAR,{eid[0]},3,{yoke_root},{yoke_end},0.0,0.0,1.0")
    hinge = grid("hinge", (0.5, 1.5, z))
    eid[0] += 1
    lines.append(f"CBUSH,{eid[0]},5,{yoke_end},{hinge},,,,0")
    # the hinge fitting spreads into the whole root edge of the panel (a shell grid alone
    # carries in-plane moment only through its drilling penalty)
    root = [array_grid(i, 0) for i in range(mx + 1)]
    eid[0] += 1
    lines.append(f"RBE2,{eid[0]},{hinge},123456," + ",".join(str(g) for g in root[:5])
                 + ("\n," + ",".join(str(g) for g in root[5:]) if root[5:] else ""))

    # antenna boom along +z from the top face centre, tip mass
    boom = [bus_grid(nx // 2, ny // 2, nz)]
    for n in range(1, BOOM["elements"] + 1):
        r = BOOM["root"]
        boom.append(grid(("boom", n), (r[0], r[1], r[2] + BOOM["length"] * n / BOOM["elements"])))
    for ga, gb in zip(boom[:-1], boom[1:]):
        eid[0] += 1
        lines.append(f"CBAR,{eid[0]},4,{ga},{gb},1.0,0.0,0.0")
    it = BOOM["tip_inertia"]
    lines.append(f"CONM2,{eid[0] + 1},{boom[-1]},,{BOOM['tip_mass']!r}\n,{it!r},,{it!r},,,{it!r}")

    # payload on an RBE3 to the four side-panel grids at z = 0.4
    payload = grid("payload", PAYLOAD["position"])
    ixx, iyy, izz = PAYLOAD["inertia"]
    lines.append(f"CONM2,{eid[0] + 2},{payload},,{PAYLOAD['mass']!r}\n,{ixx!r},,{iyy!r},,,{izz!r}")
    k = 2
    legs = [bus_grid(0, ny // 2, k), bus_grid(nx, ny // 2, k), bus_grid(nx // 2, 0, k),
            bus_grid(nx // 2, ny, k)]
    lines.append(f"RBE3,{eid[0] + 3},,{payload},123456,1.0,123,{legs[0]},{legs[1]}\n"
                 f",{legs[2]},{legs[3]}")
    lines.append("GRID,1000,,0.5,0.5,0.6")       # reference point: bus centre (unconnected)

    lines += [f"MAT1,1,{BUS['E']!r},,{BUS['nu']!r},{BUS['rho']!r}",
              f"MAT1,2,{ARRAY['E']!r},,{ARRAY['nu']!r},{ARRAY['rho']!r}",
              f"MAT1,3,{YOKE['E']!r},,0.3,{YOKE['rho']!r}",
              f"PSHELL,1,1,{BUS['t']!r},1,,1",
              f"PSHELL,2,2,{ARRAY['t']!r},2,,2",
              f"PBAR,3,3,{YOKE['A']!r},{YOKE['I']!r},{YOKE['I']!r},{YOKE['J']!r}",
              f"PBAR,4,3,{BOOM['A']!r},{BOOM['I']!r},{BOOM['I']!r},{BOOM['J']!r}",
              "PBUSH,5,K," + ",".join(repr(v) for v in HINGE_STIFFNESS),
              "ENDDATA"]
    named = {"bus_top": bus_grid(nx // 2, ny // 2, nz), "boom_tip": boom[-1],
             "array_tip": ids[("array", mx // 2, my)], "payload": payload}
    return "\n".join(lines) + "\n", named


if __name__ == "__main__":
    out = Path(__file__).with_name("spacecraft.dat")
    text, named = spacecraft_deck()
    out.write_text(text)
    print(f"wrote {out}: {sum(MASS_BUDGET.values()):.3f} kg; grids {named}")
