"""Time the FEM-to-modal pipeline on the 101-grid beam (FModal paper App. C) and on a generated
20,000-grid beam lattice with 100 modes, against scipy peers measured in the same run.

Peer in both cases: one bare scipy.sparse.linalg.eigsh shift-invert call for the same number
of modes (plus 6 rigid-body modes) on the same f-set K and M, i.e. the eigen-solution any
sparse pipeline must at least spend. Ratio = whole pipeline (read, assemble, solve, mass
properties, mode shapes, modal integrals) / bare eigsh.

Run:  python3 benchmarks/fem2modal_speed.py [--nx 100 --ny 200 --modes 100]
      python3 benchmarks/fem2modal_speed.py --plate [--repeat 2]

``--plate``: the 98,826-DOF free plate of tests/flex/test_speed.py (180 x 90 CQUAD4, lumped
mass), 100 flexible modes: the whole pipeline and one bare scipy eigsh (shift-invert, SuperLU,
k = 106) on the same f-set matrices, each in its own process (peak RSS per process), interleaved
``--repeat`` times, with the load average before each run; wall and CPU time of the measured
call (CPU time is the less load-sensitive of the two on a shared machine). The pipeline's line
adds its CPU time by step, its Lanczos and Sturm-check lines and the body-file write.

OpenBLAS is limited to one thread (unless OPENBLAS_NUM_THREADS is set): ARPACK's level-2 BLAS
on long vectors gains nothing from threads and loses badly when the cores are shared (30k-DOF
lattice, 106 modes: 36 s with default threads on the loaded 2-core machine, 7.6 s with one), and
the pipeline's BLAS work is timed as the CPU time of one core. The repository's own packages
are imported (its root goes first on sys.path), whatever flexshell is installed.
"""

from __future__ import annotations

import os

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")   # before numpy loads OpenBLAS

import argparse  # noqa: E402
import resource  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
import warnings  # noqa: E402

import numpy as np  # noqa: E402
import scipy.sparse.linalg as spla  # noqa: E402

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "tests", "flex"))
sys.path.insert(0, os.path.join(HERE, ".."))

import decks  # noqa: E402
from dynamics.flex.assembly import assemble  # noqa: E402
from dynamics.flex.body_file import write_body_file  # noqa: E402
from dynamics.flex.bulk_data import read_bulk_data  # noqa: E402
from dynamics.flex.modes import default_shift  # noqa: E402
from dynamics.flex.pipeline import Fem2ModalOptions, fem2modal  # noqa: E402


def lattice_deck(nx: int, ny: int, spacing: float = 0.1) -> str:
    """Planar CBAR lattice (a grillage) of nx * ny grids in the basic xy plane."""
    lines = ["PARAM,COUPMASS,1", "PARAM,GRDPNT,1",
             f"MAT1,1,{decks.E!r},,{decks.NU!r},{decks.RHO!r}",
             f"PBAR,10,1,{decks.A!r},{decks.I1!r},{decks.I2!r},{decks.J!r}"]
    gid = lambda i, j: 1 + i + nx * j  # noqa: E731
    for j in range(ny):
        for i in range(nx):
            lines.append(f"GRID,{gid(i, j)},,{i * spacing!r},{j * spacing!r},0.0")
    eid = 1
    for j in range(ny):
        for i in range(nx):
            if i + 1 < nx:
                lines.append(f"CBAR,{eid},10,{gid(i, j)},{gid(i + 1, j)},0.0,0.0,1.0")
                eid += 1
            if j + 1 < ny:
                lines.append(f"CBAR,{eid},10,{gid(i, j)},{gid(i, j + 1)},0.0,0.0,1.0")
                eid += 1
    lines.append("ENDDATA")
    return "\n".join(lines) + "\n"


def timed(fn, *a, **k):
    t = time.perf_counter()
    out = fn(*a, **k)
    return out, time.perf_counter() - t


def bench_beam(tmp: str) -> None:
    deck = os.path.join(HERE, "..", "configs", "fem", "single_length_beam.dat")
    sm = assemble(read_bulk_data(deck))
    K, M = sm.stiffness_f(), sm.mass_f()
    _, t_peer = timed(spla.eigsh, K, k=36, M=M, sigma=default_shift(K, M), which="LM")
    for integrals in (False, True):
        opts = Fem2ModalOptions(n_modes=30, modal_integrals=integrals)
        fem2modal(deck, opts)                       # warm imports and caches
        body, t_pipe = timed(fem2modal, deck, opts)
        _, t_write = timed(write_body_file, os.path.join(tmp, "beam.h5"), body)
        print(f"101-grid beam ({K.shape[0]} f-set DOFs, 30 modes"
              f"{' + modal integrals' if integrals else ''}): pipeline {t_pipe:.3f} s, "
              f"body-file write {t_write:.3f} s; peer bare scipy eigsh {t_peer:.3f} s; "
              f"ratio {t_pipe / t_peer:.1f}")


def bench_lattice(tmp: str, nx: int, ny: int, n_modes: int) -> None:
    path = os.path.join(tmp, "lattice.dat")
    with open(path, "w") as fh:
        fh.write(lattice_deck(nx, ny))
    steps = []
    t0 = time.perf_counter()
    body = fem2modal(path, Fem2ModalOptions(n_modes=n_modes, modal_integrals=True),
                     progress=lambda m: steps.append((time.perf_counter() - t0, m)))
    t_pipe = time.perf_counter() - t0
    _, t_write = timed(write_body_file, os.path.join(tmp, "lattice.h5"), body)
    for t, m in steps:
        print(f"    {m[:110]}")
    bulk, t_read = timed(read_bulk_data, path)
    sm, t_asm = timed(assemble, bulk)
    K, M = sm.stiffness_f(), sm.mass_f()
    sigma = default_shift(K, M)
    _, t_peer = timed(spla.eigsh, K, k=n_modes + 6, M=M, sigma=sigma, which="LM")
    print(f"{nx * ny}-grid lattice ({K.shape[0]} f-set DOFs, nnz(K) {K.nnz}, {n_modes} modes "
          f"+ modal integrals): pipeline {t_pipe:.2f} s (pyNastran read {t_read:.2f} s, "
          f"assembly {t_asm:.2f} s), body-file write {t_write:.2f} s; "
          f"peer bare scipy eigsh {t_peer:.2f} s; ratio pipeline/eigsh "
          f"{t_pipe / t_peer:.2f}; first flexible frequencies "
          f"{np.round(body.frequencies_hz[:3], 4)} Hz")


def plate_run(which: str, tmp: str) -> None:
    """One measurement in this process: 'pipeline' or 'eigsh'; prints one line."""
    path = os.path.join(tmp, "plate100k.dat")
    if not os.path.exists(path):
        with open(path, "w") as fh:
            fh.write(decks.plate_deck(180, a=2.0, b=1.0, t=0.005, edges="FFFF", coupled=False,
                                      in_plane_held=False, ny=90))
    if which == "pipeline":
        steps = []
        t0, c0 = time.perf_counter(), time.process_time()
        body = fem2modal(path, Fem2ModalOptions(n_modes=100, write_modal_matrix=True),
                         progress=steps.append)
        dt, cpu = time.perf_counter() - t0, time.process_time() - c0
        c1 = time.process_time()
        write_body_file(os.path.join(tmp, "plate100k.h5"), body)
        write = time.process_time() - c1
        f = body.frequencies_hz
        said = [m.split("] ", 1)[1] for m in steps]
        detail = "; ".join([m for m in said if m.startswith(("block Lanczos", "Sturm"))]
                           + [said[-1].split("done; ", 1)[1],
                              f"body-file write {write:.2f} s CPU"])
    else:
        sm = assemble(read_bulk_data(path))
        K, M = sm.stiffness_f().tocsc(), sm.mass_f().tocsc()
        t0, c0 = time.perf_counter(), time.process_time()
        lam, _ = spla.eigsh(K, k=106, M=M, sigma=-1.0, which="LM")
        dt, cpu = time.perf_counter() - t0, time.process_time() - c0
        f = np.sqrt(np.sort(lam)[6:]) / (2 * np.pi)
        detail = f"{K.shape[0]} DOFs"
    ru = resource.getrusage(resource.RUSAGE_SELF)
    peak = ru.ru_maxrss / 1024
    print(f"  {which:8s} {dt:7.1f} s wall, {cpu:7.1f} s CPU  peak RSS {peak:6.0f} MB  "
          f"f1 {f[0]:.7g} Hz  "
          f"f100 {f[99]:.7g} Hz  [{detail}]", flush=True)


def bench_plate(tmp: str, repeat: int) -> None:
    print("98,826-DOF free plate, 100 flexible modes: whole pipeline vs one bare eigsh, "
          "each in its own process, interleaved")
    for _ in range(repeat):
        for which in ("pipeline", "eigsh"):
            print(f"  load average {os.getloadavg()[0]:.1f}", flush=True)
            subprocess.run([sys.executable, __file__, "--plate-run", which, "--tmp", tmp],
                           check=True)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--nx", type=int, default=100)
    ap.add_argument("--ny", type=int, default=200)
    ap.add_argument("--modes", type=int, default=100)
    ap.add_argument("--plate", action="store_true", help="the 98,826-DOF plate study only")
    ap.add_argument("--repeat", type=int, default=2)
    ap.add_argument("--plate-run", choices=("pipeline", "eigsh"), help=argparse.SUPPRESS)
    ap.add_argument("--tmp", help=argparse.SUPPRESS)
    args = ap.parse_args()
    warnings.simplefilter("ignore")
    if args.plate_run:
        plate_run(args.plate_run, args.tmp)
        return
    print(f"OPENBLAS_NUM_THREADS={os.environ['OPENBLAS_NUM_THREADS']}")
    with tempfile.TemporaryDirectory() as tmp:
        if args.plate:
            bench_plate(tmp, args.repeat)
            return
        bench_beam(tmp)
        bench_lattice(tmp, args.nx, args.ny, args.modes)


if __name__ == "__main__":
    main()
