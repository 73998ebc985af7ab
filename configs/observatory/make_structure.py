"""Generate the observatory scene's flexible structure: the NASTRAN deck and the body file next to this script.

The structure is a notional observatory frame: a 4.5 m optical bench along x (101 grids) crossed at its middle
grid 51 by a 3 m instrument boom along y (grids 102-161), modelled as Euler-Bernoulli beams (the FModal
single-length beam's section in aluminium, dynamics.modal_analysis.BeamDeck) whose mass is lumped as point
masses (CONM2 without inertia or offset) at the grids: 720 kg on the bench, 480 kg on the boom. Point-mass
nodes make the second-order modal integrals that involve node inertia vanish (TM-2020-5008164 eq. E.3.1), so
the body file holds its 60 free-free modes (2.6 Hz to about 1.4 kHz) with modal integrals in about a megabyte.

    python3 configs/observatory/make_structure.py        # rewrites observatory_structure.dat and structure.h5

Steps: BeamDeck -> dynamics.flex.fem2modal (free-free modes, modal integrals, 1 % modal damping) ->
dynamics.flex.body_file.write_body_file, then a copy of that file whose floating-point datasets are stored
with HDF5's gzip filter (the layout and every value are unchanged; the zero arrays of the point-mass
integrals take no room). A regenerated file has the same frequencies (to 2e-13) and mode shapes up to the
sign of each mode, which the eigen-solver's start vector decides, and the modal integrals that follow.
"""

from __future__ import annotations

import tempfile
from pathlib import Path

import h5py
import numpy as np

from dynamics.flex import Fem2ModalOptions, fem2modal
from dynamics.flex.body_file import write_body_file
from dynamics.modal_analysis import BeamDeck

HERE = Path(__file__).resolve().parent
DECK = HERE.parent / "fem" / "observatory_structure.dat"
BODY = HERE / "structure.h5"
N_MODES = 60
DAMPING = 0.01
BENCH = (4.5, 100, 720.0)  # length (m), elements, mass (kg) of the optical bench along x
BOOM = (3.0, 60, 480.0)  # of the instrument boom along y


def structure_deck() -> BeamDeck:
    deck = BeamDeck()
    deck.E, deck.G = 70.0e9, 70.0e9 / 2.6  # aluminium (Poisson ratio 0.3)
    deck.rho = 0.0  # the mass is in the point masses below
    length, n, mass = BENCH
    bench = deck.add_line(1, (-length / 2, 0.0, 0.0), (1.0, 0.0, 0.0), length, n, (0.0, 1.0, 0.0), 1)
    masses = {g: mass / n * (0.5 if k in (0, n) else 1.0) for k, g in enumerate(bench)}
    length, n, mass = BOOM
    half = n // 2
    centre = bench[len(bench) // 2]
    plus = deck.add_line(101, (0.0, 0.0, 0.0), (0.0, 1.0, 0.0), length / 2, half, (1.0, 0.0, 0.0), 101,
                         start_grid=centre)
    minus = deck.add_line(101 + half, (0.0, 0.0, 0.0), (0.0, -1.0, 0.0), length / 2, half, (1.0, 0.0, 0.0),
                          101 + half, start_grid=centre)
    for line in (plus, minus):
        for k, g in enumerate(line):
            masses[g] = masses.get(g, 0.0) + mass / n * (0.5 if k in (0, half) else 1.0)
    for k, (g, m) in enumerate(sorted(masses.items())):
        deck.conm2.append((1001 + k, g, m, np.zeros(3), np.zeros((3, 3))))
    return deck


def gzip_copy(source: Path, target: Path) -> None:
    """Copy an HDF5 file, storing its floating-point arrays with the gzip filter (values unchanged)."""
    with h5py.File(source, "r") as src, h5py.File(target, "w") as dst:
        dst.attrs.update(src.attrs)

        def copy(name, obj):
            if isinstance(obj, h5py.Group):
                dst.require_group(name).attrs.update(obj.attrs)
                return
            compress = obj.dtype.kind == "f" and obj.size > 64
            options = {"compression": "gzip", "compression_opts": 9, "shuffle": True} if compress else {}
            dst.create_dataset(name, data=obj[()], **options).attrs.update(obj.attrs)

        src.visititems(copy)


def main() -> None:
    structure_deck().write(DECK, title="observatory structure: 4.5 m bench (x) crossed by a 3 m boom (y), point "
                                        "masses; written by configs/observatory/make_structure.py")
    # the massless grid rotations put the six rigid-body eigenvalues at +-3e-6 (rad/s)^2 of round-off: classify
    # below 0.01 Hz as rigid (the first flexible mode is three orders of magnitude above)
    body = fem2modal(str(DECK), Fem2ModalOptions(n_modes=N_MODES, modal_integrals=True, damping=DAMPING,
                                                 rigid_threshold_hz=0.01))
    with tempfile.TemporaryDirectory() as tmp:
        plain = Path(tmp) / "structure.h5"
        write_body_file(plain, body)
        gzip_copy(plain, BODY)
    f = body.frequencies_hz
    print(f"{DECK.name}: {len(body.grid_ids)} grids, {body.mass:.1f} kg; {BODY.name}: {body.n_modes} modes "
          f"{f[0]:.3f} .. {f[-1]:.1f} Hz, {BODY.stat().st_size / 1e6:.2f} MB")


if __name__ == "__main__":
    main()
