"""The IGRF expansion of shell/models/magnetic.py against NOAA's geomagnetic calculator.

ppigrf's repository keeps, as test data, the field that NOAA's NCEI calculator gives on a 1 deg x 1 deg
grid 5 km above the WGS 84 ellipsoid (``test/data/<date>/b_e.csv``, ``b_n.csv``, ``b_z.csv``: east, north,
down, nT, rounded to 0.1 nT). Clone it and point this script at one date's folder:

    git clone https://github.com/klaundal/ppigrf /tmp/ppigrf
    python benchmarks/igrf_noaa_grid.py /tmp/ppigrf/test/data/2020-01-01 --igrf 13

The geodetic-to-Earth-fixed conversion and the local east/north/down axes are written here (WGS 84),
independently of ppigrf; only the coefficients come from its files (the calculator's "IGRF2020" is the
IGRF-13 model: ``--igrf 13``).
"""

from __future__ import annotations

import argparse
import datetime
from pathlib import Path

import numpy as np

from shell.models.ephemeris import julian_date
from shell.models.magnetic import MAX_DEGREE, igrf_coefficients, spherical_harmonic_field

A, F = 6378137.0, 1.0 / 298.257223563
E2 = F * (2.0 - F)


def read_component(path):
    rows = np.loadtxt(path, delimiter=",", comments="#")
    return rows[:, 0], rows[:, 1], rows[:, 2], rows[:, 3], rows[:, 4]   # year, lat, lon, height km, value nT


def compare(folder: Path, igrf: int = 14, every: int = 1):
    import ppigrf.ppigrf as pp
    year, lat, lon, h, east = read_component(folder / "b_e.csv")
    north = read_component(folder / "b_n.csv")[4]
    down = read_component(folder / "b_z.csv")[4]
    date = datetime.datetime(int(year[0]), 1, 1) + datetime.timedelta(days=(year[0] % 1) * 365.0)
    coefficients = {13: pp.shc_fn_igrf13, 14: pp.shc_fn_igrf14}[igrf]
    g, hh = igrf_coefficients(julian_date(date.isoformat()), coefficient_file=coefficients)
    sel = slice(None, None, every)
    phi, lam, height = np.radians(lat[sel]), np.radians(lon[sel]), h[sel] * 1e3
    n = A / np.sqrt(1.0 - E2 * np.sin(phi) ** 2)
    x = (n + height) * np.cos(phi) * np.cos(lam)
    y = (n + height) * np.cos(phi) * np.sin(lam)
    z = (n * (1.0 - E2) + height) * np.sin(phi)
    b = np.array([spherical_harmonic_field(*p, g.ravel(), hh.ravel(), MAX_DEGREE, 6371.2e3)
                  for p in zip(x, y, z)]) * 1e9
    e_axis = np.c_[-np.sin(lam), np.cos(lam), np.zeros_like(lam)]
    n_axis = np.c_[-np.sin(phi) * np.cos(lam), -np.sin(phi) * np.sin(lam), np.cos(phi)]
    d_axis = -np.c_[np.cos(phi) * np.cos(lam), np.cos(phi) * np.sin(lam), np.sin(phi)]
    ours = np.c_[np.sum(b * e_axis, 1), np.sum(b * n_axis, 1), np.sum(b * d_axis, 1)]
    noaa = np.c_[east[sel], north[sel], down[sel]]
    return np.abs(ours - noaa), len(x)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("folder", type=Path)
    parser.add_argument("--igrf", type=int, default=14, choices=(13, 14))
    parser.add_argument("--every", type=int, default=1, help="use every k-th grid point")
    args = parser.parse_args(argv)
    diff, n = compare(args.folder, args.igrf, args.every)
    print(f"{n} points: max |difference| east {diff[:, 0].max():.3f} nT, north {diff[:, 1].max():.3f} nT, "
          f"down {diff[:, 2].max():.3f} nT; rms {np.sqrt(np.mean(diff**2)):.3f} nT (NOAA rounds to 0.1 nT)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
