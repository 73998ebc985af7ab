"""When geometric stiffening matters: frequency error of a spinning cantilever versus the spin rate, with and
without the stiffening (issue 15; the chart of docs/geometric_stiffening.md).

The user's workflow of tests/flexible/test_rotating_cantilever.py (80 CBAR, 24 fixed-interface modes,
``flexshell fem2modal --geometric-stiffness``, a scene with a hub spinning at lambda rad/s, linearization)
for lambda = 0..12, hub radius 0 and 1 (in beam lengths), with ``geometric_stiffening`` on and off, against
the power-series reference of tests/flex/rotating_beam.py. Modes are told apart by the tip motion of their
eigenvector (C of the linear model: out of the plane of rotation = flapwise). Writes
docs/geometric_stiffening.png and prints the table.

    PYTHONPATH=. python3 benchmarks/geometric_stiffening_chart.py [--out docs/geometric_stiffening.png]
"""

from __future__ import annotations

import argparse
import tempfile
import warnings
from pathlib import Path

import numpy as np

from shell.analysis.linearize import linearize
from shell.cli import main
from shell.scenario import build_simulation, load_scenario
from tests.flex.rotating_beam import rotating_beam_deck, rotating_beam_frequencies, spinning_scene

TIP = 81


def families(model):
    """(flapwise, chordwise) frequencies (rad/s) of the modal block, classified by the tip motion; an
    unstable mode (positive real eigenvalue) is reported as NaN in its family's first place."""
    A, C = model.A, model.C
    n = A.shape[0] // 2
    keep = [i for i in range(2 * n) if i % n >= 1]
    ev, vec = np.linalg.eig(A[np.ix_(keep, keep)])
    tip = C[:, keep] @ vec
    flap, chord = [], []
    for k in np.flatnonzero(ev.imag > 1e-6):
        (flap if abs(tip[2, k]) > abs(tip[1, k]) else chord).append(abs(ev.imag[k]))
    unstable = bool(np.any(ev.real > 1e-6))
    flap, chord = np.sort(flap), np.sort(chord)
    if unstable:
        chord = np.concatenate([[np.nan], chord])
    return flap, chord


def run(out_png):
    tmp = Path(tempfile.mkdtemp())
    (tmp / "beam.dat").write_text(rotating_beam_deck(80))
    assert main(["fem2modal", str(tmp / "beam.dat"), "--modes", "24", "--aset", "1:123456", "--modal-integrals",
                 "--geometric-stiffness", "-q", "-o", str(tmp / "beam.h5")]) == 0
    lams = np.arange(13)
    rows = {}
    for hub in (0.0, 1.0):
        for on in (True, False):
            err = np.full((lams.size, 2), np.nan)
            for i, lam in enumerate(lams):
                scene = tmp / "scene.yaml"
                scene.write_text(spinning_scene("beam.h5", float(lam), hub_radius=hub, stiffening=on, tip_grid=TIP))
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore")
                    sim = build_simulation(load_scenario(str(scene), []))
                model = linearize(sim, ["multibody.beam.modal_force"], ["multibody.tip.position"], points=2,
                                  richardson=False, tolerance=1e-12)
                flap, chord = families(model)
                f_ref = rotating_beam_frequencies(lam, hub=hub, count=1)[0]
                c_ref = rotating_beam_frequencies(lam, hub=hub, chordwise=True, count=1)[0]
                err[i] = [flap[0] / f_ref - 1.0, chord[0] / c_ref - 1.0]
                print(f"hub {hub:.0f} stiffening {'on ' if on else 'off'} lambda {lam:2d}: flapwise {flap[0]:8.4f} "
                      f"(ref {f_ref:8.4f}), chordwise {chord[0]:8.4f} (ref {c_ref:8.4f})", flush=True)
            rows[(hub, on)] = err
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, axes = plt.subplots(1, 2, figsize=(10, 4), sharey=True)
    for ax, j, title in ((axes[0], 0, "first flapwise frequency"), (axes[1], 1, "first chordwise frequency")):
        for (hub, on), err in rows.items():
            ax.semilogy(lams, np.maximum(np.abs(err[:, j]), 1e-6), "o-" if on else "s--",
                        label=f"{'with' if on else 'without'} stiffening, hub radius {hub:.0f} L")
        ax.axhline(1e-3, color="gray", lw=0.8)
        ax.set_title(title)
        ax.set_xlabel("dimensionless spin rate lambda = Omega sqrt(rho A L^4 / EI)")
        ax.grid(True, which="both", alpha=0.3)
    axes[0].set_ylabel("|relative error| vs rotating-beam theory")
    axes[1].legend(fontsize=7)
    fig.suptitle("Spinning uniform cantilever (80 CBAR, 24 modes): fem2modal -> scene -> linearize")
    fig.tight_layout()
    fig.savefig(out_png, dpi=110)
    print(f"wrote {out_png}")


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default="docs/geometric_stiffening.png")
    run(parser.parse_args().out)
