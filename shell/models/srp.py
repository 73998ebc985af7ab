"""Solar radiation pressure on flat plates: force and torque at a node, with the central body's shadow.

Attach to a node (``attach: {node: ...}``: position and rotation node -> world) and wire the Sun
(``SunMoonEphemeris.sun_position``) and, optionally, the shadow (``Eclipse.shadow_factor``, default 1).
Config ``plates: N`` (default 1); each plate k has an area ``A_k``, an outward unit normal ``n_k`` and a
center of pressure ``c_k`` (node axes), and the fractions of the incident photons reflected specularly
``rho_s`` and diffusely ``rho_d`` (the rest, ``1 - rho_s - rho_d``, is absorbed). With ``s`` the unit
vector from the node to the Sun in node axes and ``cos theta = n . s``, a plate lit on its front face
(``cos theta > 0``) receives (Montenbruck & Gill, "Satellite Orbits", eq. 3.73; Wertz, "Spacecraft
Attitude Determination and Control", eq. 17-12, Lambertian diffuse reflection)::

    F_k = -P nu A_k cos theta [ (1 - rho_s) s + 2 (rho_s cos theta + rho_d / 3) n ]
    P   = (Phi / c) (AU / |r_sun - r|)^2         Phi = 1361 W/m^2 at 1 AU (Kopp & Lean 2011)

and the node ``F = sum F_k``, ``T = sum c_k x F_k``. A plate's back face feels nothing (model a panel lit
on both sides as two plates with opposite normals); plates do not shadow one another.

Array layout: the scalar parameters first (``SCALARS``, fixed offsets ``P``), then the plate arrays in
the order of ``PLATES`` (``area`` (N), ``normal`` (N, 3), ...); the kernel derives N from the parameter
vector's length, ``N = (len(p) - SCALAR_SIZE) / PLATE_SIZE``, and each plate array's start as
``SCALAR_SIZE + N * PLATE.<name>`` (``PLATE``: the offsets of one plate's values).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from shell.model import (Declarations, InputPort, Layout, Model, ModelError, OutputPort, Parameter, count_option,
                         named_offsets)
from shell.models.ephemeris import ASTRONOMICAL_UNIT
from shell.ports import node_inputs, node_load_outputs
from shell.registry import register_model

SOLAR_FLUX = 1361.0          # W/m^2 at 1 AU, total solar irradiance (Kopp & Lean 2011, GRL 38 L01706)
SPEED_OF_LIGHT = 299792458.0  # m/s

SCALARS = (
    Parameter("solar_flux", "W/m^2", SOLAR_FLUX, (), (0.0, None), "solar irradiance at 1 AU"),
)
PLATES = (
    Parameter("area", "m^2", (1.0,), (1,), (0.0, None), "plate areas"),
    Parameter("normal", "", ((0.0, 0.0, 1.0),), (1, 3), (-1.0, 1.0), "outward unit normals, node axes"),
    Parameter("center", "m", ((0.0, 0.0, 0.0),), (1, 3), None, "centers of pressure from the node, node axes"),
    Parameter("specular", "", (0.0,), (1,), (0.0, 1.0), "specular reflection fraction rho_s"),
    Parameter("diffuse", "", (0.0,), (1,), (0.0, 1.0), "diffuse reflection fraction rho_d"),
)
#: offsets of one plate's values within its block; a plate array of N plates starts at
#: ``SCALAR_SIZE + N * PLATE.<name>``
PLATE, PLATE_SIZE = named_offsets(PLATES), Layout.of(PLATES).size
SCALAR_SIZE = Layout.of(SCALARS).size
INPUTS = (
    *node_inputs("position", "rotation", feedthrough=True, position="node position from the central body, world axes",
                 rotation="rotation node -> world"),
    InputPort("sun_position", "m", (3,), "central body -> Sun, world axes", feedthrough=True),
    InputPort("shadow_factor", "", (), "1 lit .. 0 umbra (Eclipse)", feedthrough=True, required=False,
              default=1.0),
)
OUTPUTS = (
    *node_load_outputs("force", "torque", force="radiation-pressure force, node axes",
                       torque="radiation-pressure torque about the node, node axes"),
    OutputPort("pressure", "Pa", (), "solar radiation pressure Phi/c at the node, before the shadow",
               feedthrough=True),
)
#: the plate count is a configuration: each plate array has one row per plate
SRP = Declarations(parameters=SCALARS + PLATES, inputs=INPUTS, outputs=OUTPUTS, sized=[d.name for d in PLATES])
P, U, Y = SRP.P, SRP.U, SRP.Y


@njit(cache=True)
def plate_force(pressure, area, n0, n1, n2, s0, s1, s2, specular, diffuse):
    """Force on one flat plate (front face), M&G eq. 3.73; s the unit vector to the Sun."""
    cos_t = n0 * s0 + n1 * s1 + n2 * s2
    if cos_t <= 0.0:
        return 0.0, 0.0, 0.0
    k = -pressure * area * cos_t
    a = 1.0 - specular
    b = 2.0 * (specular * cos_t + diffuse / 3.0)
    return k * (a * s0 + b * n0), k * (a * s1 + b * n1), k * (a * s2 + b * n2)


@njit(cache=True)
def _srp_loads(t, x, z, u, p, y):
    n = (p.shape[0] - SCALAR_SIZE) // PLATE_SIZE
    area, normal, center = SCALAR_SIZE + n * PLATE.area, SCALAR_SIZE + n * PLATE.normal, SCALAR_SIZE + n * PLATE.center
    specular, diffuse = SCALAR_SIZE + n * PLATE.specular, SCALAR_SIZE + n * PLATE.diffuse
    r, rot, sun = U.position, U.rotation, U.sun_position
    d0, d1, d2 = u[sun] - u[r], u[sun + 1] - u[r + 1], u[sun + 2] - u[r + 2]
    dn = np.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
    # s in node axes: R^T d / |d| (R row-major: column i is rot + i, rot + 3 + i, rot + 6 + i)
    s0 = (u[rot] * d0 + u[rot + 3] * d1 + u[rot + 6] * d2) / dn
    s1 = (u[rot + 1] * d0 + u[rot + 4] * d1 + u[rot + 7] * d2) / dn
    s2 = (u[rot + 2] * d0 + u[rot + 5] * d1 + u[rot + 8] * d2) / dn
    pressure = p[P.solar_flux] / SPEED_OF_LIGHT * (ASTRONOMICAL_UNIT / dn) ** 2
    lit = pressure * u[U.shadow_factor]
    f0 = f1 = f2 = t0 = t1 = t2 = 0.0
    for k in range(n):
        g0, g1, g2 = plate_force(lit, p[area + k], p[normal + 3 * k], p[normal + 3 * k + 1], p[normal + 3 * k + 2],
                                 s0, s1, s2, p[specular + k], p[diffuse + k])
        c0, c1, c2 = p[center + 3 * k], p[center + 3 * k + 1], p[center + 3 * k + 2]
        f0 += g0
        f1 += g1
        f2 += g2
        t0 += c1 * g2 - c2 * g1
        t1 += c2 * g0 - c0 * g2
        t2 += c0 * g1 - c1 * g0
    y[Y.force], y[Y.force + 1], y[Y.force + 2] = f0, f1, f2
    y[Y.torque], y[Y.torque + 1], y[Y.torque + 2] = t0, t1, t2
    y[Y.pressure] = pressure


@register_model
class SolarRadiationPressure(Model):
    """Solar radiation pressure on N flat plates (specular, diffuse, absorbed) at a node, with shadow."""

    summary = "solar radiation pressure on flat plates (area, normal, specular/diffuse) at a node, shadowed"
    declarations = SRP
    feedthrough_outputs = staticmethod(_srp_loads)

    def __init__(self, name: str, *, plates: int = 1, **kwargs):
        self.plate_count = count_option(name, "plates", plates, "plates")
        super().__init__(name, **kwargs)

    def declare(self):
        n = self.plate_count
        rows = {d.name: (n,) + tuple(d.shape[1:]) for d in PLATES}  # one plate's default in each row
        self.use_declarations(SRP.replace(**{d.name: {"shape": rows[d.name], "default": np.broadcast_to(
            np.asarray(d.default, float)[0], rows[d.name]).copy()} for d in PLATES}))

    def configure(self):
        normals = self.parameter("normal")
        norms = np.linalg.norm(normals, axis=1)
        if np.any(np.abs(norms - 1.0) > 1e-9):
            k = int(np.argmax(np.abs(norms - 1.0)))
            raise ModelError(f"model {self.path}: parameter normal: expected unit vectors, plate {k + 1} has "
                             f"norm {norms[k]:.12g}")
        total = self.parameter("specular") + self.parameter("diffuse")
        if np.any(total > 1.0 + 1e-12):
            k = int(np.argmax(total))
            raise ModelError(f"model {self.path}: parameters specular + diffuse: expected at most 1 (the rest is "
                             f"absorbed), plate {k + 1} has {total[k]:.6g}")
