"""Loads recovery of a flexible body: element forces and stresses and interface forces from its modal
coordinates, by mode displacement and by mode acceleration (:mod:`dynamics.flex.loads_recovery` has the
equations; the matrices come from the body file, ``flexshell fem2modal --recover-elements ... --recover-grids
...``).

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

Parameter layout (the sizes are the body file's, so the kernel derives the offsets): ``sizes`` = [m, l] first,
then Y (n x m), S (n x 6), F (n x l), row-major; n = half the output size. Input layout: eta (m), the
angular and linear accelerations (3 + 3), the loads (l).
"""

from __future__ import annotations

from collections import namedtuple

import numpy as np
from numba import njit

from shell.model import InputPort, Model, ModelError, OutputPort, Parameter
from shell.registry import register_model

P = namedtuple("LoadsRecoveryParameters", "sizes mode_displacement reference_acceleration loads")(0, 2, None, None)
U = namedtuple("LoadsRecoveryInputs", "modal_q angular_acceleration linear_acceleration loads")(0, None, None, None)
Y = namedtuple("LoadsRecoveryOutputs", "mode_displacement mode_acceleration")(0, None)


@njit(cache=True)
def _recover(t, x, z, u, p, y):
    n = y.shape[0] // 2
    m = int(p[P.sizes])
    nl = int(p[P.sizes + 1])
    acc, loads = U.modal_q + m, U.modal_q + m + 6
    ps = P.mode_displacement + n * m
    pf = ps + 6 * n
    for i in range(n):
        md = 0.0
        for k in range(m):
            md += p[P.mode_displacement + i * m + k] * u[U.modal_q + k]
        ma = md
        for j in range(6):
            ma += p[ps + 6 * i + j] * u[acc + j]
        for j in range(nl):
            ma += p[pf + nl * i + j] * u[loads + j]
        y[Y.mode_displacement + i] = md
        y[n + i] = ma


@register_model
class LoadsRecovery(Model):
    """Element forces / stresses and interface forces of a flexible body by mode displacement and mode
    acceleration (config: ``body_file``, the body's file with a LoadsRecovery group, relative to the working
    directory or absolute, as a controller's ``gain_file``); connect its modal coordinates and the reference
    grid's accelerations."""

    summary = ("loads recovery: element forces, stresses, interface forces of a flexible body by mode displacement "
               "and mode acceleration (config: body_file)")
    feedthrough_outputs = staticmethod(_recover)
    offsets = {"p": P, "u": U, "y": Y}

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
        self.parameters = (
            Parameter("sizes", "", np.array([m, nl], dtype=float), (2,), description="modes m, loads l"),
            Parameter("mode_displacement", "", lr.mode_displacement, (n, m), description="Y: outputs per unit eta"),
            Parameter("reference_acceleration", "", lr.reference_acceleration, (n, 6),
                      description="S: residual-flexibility outputs per unit [angular; linear] reference acceleration"),
            Parameter("loads", "", lr.loads, (n, nl),
                      description="F: residual-flexibility outputs per unit load at the load DOFs"),
        )
        self.inputs = (
            InputPort("modal_q", "", (m,), "modal coordinates eta of the body", feedthrough=True),
            InputPort("angular_acceleration", "rad/s^2", (3,), f"angular acceleration of the reference grid "
                      f"{lr.reference_grid}, body axes", feedthrough=True, required=False),
            InputPort("linear_acceleration", "m/s^2", (3,), "linear acceleration of the reference grid (minus "
                      "gravity), body axes", feedthrough=True, required=False),
            InputPort("loads", "", (nl,), "loads at the body file's load DOFs (N, N m)", feedthrough=True,
                      required=False),
        )
        self.outputs = (
            OutputPort("mode_displacement", "", (n,), f"outputs by mode displacement (SI: N, N m, Pa): {listing}",
                       feedthrough=True),
            OutputPort("mode_acceleration", "", (n,), f"outputs by mode acceleration (SI): {listing}",
                       feedthrough=True),
        )

    def configure(self):
        lr = self.recovery
        if lr.reaction == "inertia_relief" and lr.loads.shape[1] == 0:
            import warnings

            warnings.warn(f"model {self.path}: {self.body_file} is a free body without load DOFs: its mode "
                          "acceleration recovery has no external loads to add (make the body with --residual at the "
                          "loaded grids)", stacklevel=2)

    def output_names(self) -> list[str]:
        """The body file's names of the recovered quantities, in output order."""
        return list(self.recovery.names)
