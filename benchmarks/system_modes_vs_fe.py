"""System modes of multibody beam assemblies versus the direct FE solution of the whole structure.

The study behind docs/flexible_validation.md (FModal paper "System Modes with Multiple Bodies",
"Configuration Changes", "Closure Constraints"; TM-2020-5008164 Appendix C.4). For each number of
fixed-interface modes per body it builds the single-length-beam body files with the pipeline,
assembles every case of ``tests/flexible/test_system_modes.py``, linearizes at rest and compares the
first ten system modes with the pipeline's eigen-solution of the whole-structure deck:

    python3 benchmarks/system_modes_vs_fe.py [N ...]        (default N = 20 40 60 100 200)

Printed: per case and N, the largest |f_multibody - f_FE| over the first 6 and the first 10 modes
[Hz], and the Frobenius norm of the differences of the unit-norm, sign-aligned grid-motion matrices
(first 6 / first 10 modes), as a markdown table.
"""

from __future__ import annotations

import pathlib
import sys
import tempfile
import time
import warnings

import numpy as np

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1]))

from tests.flexible.test_system_modes import (case_cantilever, case_double_beam, case_fixed_fixed,  # noqa: E402
                                              case_lumped_mass, case_pinned, case_solar_array, compare,
                                              component_bodies)

CASES = {
    "(1) double-length beam, welded (closure)": lambda b, t: case_double_beam(b, t, 0.0),
    "(2) two beams at 45 deg, welded (closure)": lambda b, t: case_double_beam(b, t, 45.0),
    "(2) same, tree: locked hinge, modes referred to grid 1": lambda b, t: case_double_beam(b, t, 45.0, "tree"),
    "(2) same, tree: locked hinge, body-file modes as they are": lambda b, t: case_double_beam(b, t, 45.0,
                                                                                              "tree_as_is"),
    "(3) two beams pinned (revolute closure / RBE2 12345)": case_pinned,
    "(4) double-length cantilever": case_cantilever,
    "(5) free-free beam + lumped mass (rigid child)": lambda b, t: case_lumped_mass(b, t, True),
    "(5) same after detaching the mass": lambda b, t: case_lumped_mass(b, t, False),
    "(6) fixed-fixed beam (two weld closures)": case_fixed_fixed,
    "C.4 array on rigid bus, normalized component modes": lambda b, t: case_solar_array(b, t, "a1"),
    "C.4 array on rigid bus, free-free modes": lambda b, t: case_solar_array(b, t, "free"),
}


def main(mode_counts):
    warnings.simplefilter("ignore")
    rows = {name: [] for name in CASES}
    with tempfile.TemporaryDirectory() as tmpdir:
        tmp = pathlib.Path(tmpdir)
        for n in mode_counts:
            t0 = time.perf_counter()
            bodies = component_bodies(tmp, n)
            print(f"N = {n}: body files in {time.perf_counter() - t0:.1f} s", flush=True)
            for name, build in CASES.items():
                result, modes = compare(build(bodies, tmp))
                df = np.abs(result.frequency_difference_hz)
                sd = result.shape_difference
                row = (n, result.frequencies_fe_hz[0], df[:6].max(), df.max(), np.sqrt(np.sum(sd[:6] ** 2)),
                       np.sqrt(np.sum(sd ** 2)))
                rows[name].append(row)
                print("   ", name, "N = %d  f1 = %.6f Hz  df = %.1e / %.1e Hz  shapes %.1e / %.1e" % row, flush=True)
    print("\n| case | N | first FE mode [Hz] | max abs df, modes 1-6 [Hz] | modes 1-10 [Hz] "
          "| shape diff. 1-6 | shape diff. 1-10 |")
    print("| --- | ---: | ---: | ---: | ---: | ---: | ---: |")
    for name, results in rows.items():
        for n, f1, d6, d10, s6, s10 in results:
            print(f"| {name} | {n} | {f1:.6f} | {d6:.1e} | {d10:.1e} | {s6:.1e} | {s10:.1e} |")


if __name__ == "__main__":
    main([int(a) for a in sys.argv[1:]] or [20, 40, 60, 100, 200])
