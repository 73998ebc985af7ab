"""Loads recovery of a flexible body: element forces and stresses and interface forces from its modal
coordinates, by mode displacement and by mode acceleration (:mod:`dynamics.flex.loads_recovery` has the
equations; the matrices come from the body file, ``flexshell fem2modal`` with ``--recover-elements`` and
``--recover-grids``).

    mode_displacement = Y eta
    mode_acceleration = Y eta + S [alpha; a] + F loads

Y (n x m) the outputs per unit modal coordinate, S (n x 6) the residual-flexibility response to the inertia
load of a unit angular / linear acceleration of the reference grid (alpha, a in the body's axes, e.g. the
interface node's ``angular_acceleration`` and ``linear_acceleration``; for a scene with gravity g give a - g),
F (n x l) to unit loads at the body file's load DOFs: the mode-acceleration method written as mode
displacement plus the static response the kept modes miss. Outputs in SI (N, N m, Pa), in the order of the
body file's
``LoadsRecovery/Names`` (``flexshell fem2modal`` prints them; e.g. ``CBAR 1 BM1A``: the bending moment in plane
1 at end A of element 1, NASTRAN's sign).

Layout (the sizes are the body file's: ``per_mode`` and everything after it are ``sized``, so the kernel derives
the offsets): parameters ``sizes`` = [m, l], then Y (``per_mode``, n x m), S (``per_acceleration``, n x 6), F
(``per_load``, n x l), row-major; n = half the output size. Inputs: eta (m), the angular and linear accelerations
(3 + 3), the loads (l). Outputs: the n by mode displacement, then the n by mode acceleration.
"""

from __future__ import annotations

import warnings

import numpy as np
from numba import njit

from shell.model import Declarations, InputPort, Model, ModelError, OutputPort, Parameter
from shell.registry import register_model

#: the model's declarations; their shapes (n outputs, m modes, l loads) come from the body file, set per
#: instance in ``declare``
RECOVERY = Declarations(
    parameters=(Parameter("sizes", "", None, (2,), None, "modes m and load DOFs l (from the body file)"),
                Parameter("per_mode", "", None, (1, 1), None, "Y: outputs per unit modal coordinate"),
                Parameter("per_acceleration", "", None, (1, 6), None,
                          "S: residual-flexibility outputs per unit [angular; linear] reference acceleration"),
                Parameter("per_load", "", None, (1, 1), None,
                          "F: residual-flexibility outputs per unit load at the load DOFs")),
    inputs=(InputPort("modal_q", "", (1,), "modal coordinates eta of the body", feedthrough=True),
            InputPort("angular_acceleration", "rad/s^2", (3,), "angular acceleration of the reference grid, body "
                      "axes", feedthrough=True, required=False),
            InputPort("linear_acceleration", "m/s^2", (3,), "linear acceleration of the reference grid (minus "
                      "gravity), body axes", feedthrough=True, required=False),
            InputPort("loads", "", (1,), "loads at the body file's load DOFs (N, N m)", feedthrough=True,
                      required=False)),
    outputs=(OutputPort("mode_displacement", "", (1,), "outputs by mode displacement (SI: N, N m, Pa)",
                        feedthrough=True),
             OutputPort("mode_acceleration", "", (1,), "outputs by mode acceleration (SI)", feedthrough=True)),
    sized=("per_mode", "per_acceleration", "per_load", "modal_q", "loads", "mode_displacement",
           "mode_acceleration"),
)
P, U, Y = RECOVERY.P, RECOVERY.U, RECOVERY.Y


@njit(cache=True)
def _recover(t, x, z, u, p, y):
    n = y.shape[0] // 2
    m = int(p[P.sizes])
    nl = int(p[P.sizes + 1])
    acc, loads = U.modal_q + m, U.modal_q + m + 6          # after eta: the accelerations, then the loads
    ps = P.per_mode + n * m                                  # S after the n x m Y, F after the n x 6 S
    pf = ps + 6 * n
    for i in range(n):
        md = 0.0
        for k in range(m):
            md += p[P.per_mode + i * m + k] * u[U.modal_q + k]
        ma = md
        for j in range(6):
            ma += p[ps + 6 * i + j] * u[acc + j]
        for j in range(nl):
            ma += p[pf + nl * i + j] * u[loads + j]
        y[Y.mode_displacement + i] = md
        y[n + i] = ma                                        # mode_acceleration follows the n by mode displacement


@register_model
class LoadsRecovery(Model):
    """Element forces / stresses and interface forces of a flexible body by mode displacement and mode
    acceleration (config: ``body_file``, the body's file with a LoadsRecovery group, relative to the working
    directory or absolute, as a controller's ``gain_file``); connect its modal coordinates and the reference
    grid's accelerations."""

    summary = ("loads recovery: element forces, stresses, interface forces of a flexible body by mode displacement "
               "and mode acceleration (config: body_file)")
    declarations = RECOVERY
    feedthrough_outputs = staticmethod(_recover)

    def __init__(self, name: str, *, body_file: str, **kwargs):
        from dynamics.flex.body_file import read_body_file

        try:
            body = read_body_file(body_file)
        except (OSError, ValueError) as exc:
            raise ModelError(f"model {name}: config body_file {body_file!r}: {exc}") from None
        if body.loads_recovery is None:
            raise ModelError(f"model {name}: body file {body_file!r} has no LoadsRecovery group: make it with "
                             "flexshell fem2modal ... --recover-elements EID,... and/or --recover-grids GRID,...")
        self.body_file = str(body_file)
        self.recovery = body.loads_recovery
        self.source = body.source
        super().__init__(name, **kwargs)

    def declare(self):
        lr = self.recovery
        n, m = lr.mode_displacement.shape
        nl = lr.loads.shape[1]
        listing = ", ".join(lr.names[:6]) + (" ..." if n > 6 else "")
        self.use_declarations(RECOVERY.replace(
            sizes={"default": np.array([m, nl], dtype=float)},
            per_mode={"default": lr.mode_displacement, "shape": (n, m)},
            per_acceleration={"default": lr.reference_acceleration, "shape": (n, 6)},
            per_load={"default": lr.loads, "shape": (n, nl)},
            modal_q={"shape": (m,)}, loads={"shape": (nl,)},
            angular_acceleration={"description": f"angular acceleration of the reference grid {lr.reference_grid}, "
                                                 "body axes"},
            mode_displacement={"shape": (n,), "description": f"outputs by mode displacement (SI): {listing}"},
            mode_acceleration={"shape": (n,), "description": f"outputs by mode acceleration (SI): {listing}"}))

    def configure(self):
        lr = self.recovery
        if lr.reaction == "inertia_relief" and lr.loads.shape[1] == 0:
            warnings.warn(f"model {self.path}: {self.body_file} is a free body without load DOFs: its mode "
                          "acceleration recovery has no external loads to add (make the body with --residual at the "
                          "loaded grids)", stacklevel=2)

    def output_names(self) -> list[str]:
        """The body file's names of the recovered quantities, in output order."""
        return list(self.recovery.names)
