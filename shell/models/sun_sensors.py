"""Coarse sun sensors: N cosine-response photocells at a node, field of view, eclipse, Earth albedo.

Attach to a node (``attach: {node: ...}``: position and rotation node -> world) and wire the Sun
(``SunMoonEphemeris.sun_position``) and, optionally, the shadow (``Eclipse.shadow_factor``, default 1).
Config ``sensors: N`` (default 1); parameter ``normal`` (N, 3) gives each cell's unit normal in node axes.
Each sample, with ``s`` the unit vector from the node to the Sun and ``e = -r / |r|`` the direction to the
Earth's center (node axes), ``d`` the node-Sun distance (Wertz, "Spacecraft Attitude Determination and
Control", sec. 6.1, cosine detectors; the Basilisk CoarseSunSensor module's response)::

    y_k = scale ( nu (AU/d)^2 f(n_k . s) + albedo E_a f(n_k . e) ) + sigma w_k,   clipped at 0
    f(c) = c if c >= cos(field_of_view) and c > 0, else 0

``field_of_view`` is the half-angle of the cell's cone. With ``albedo`` > 0 (0 switches it off), the Earth
is a Lambertian sphere of Bond albedo ``albedo`` whose reflected irradiance, relative to the direct Sun,
is (Lambert sphere phase law; Russell 1916; Wertz sec. 5.3)::

    E_a = (AU/d)^2 (R / |r|)^2 (2 / (3 pi)) [sin alpha + (pi - alpha) cos alpha],   cos alpha = r_hat . s_hat

with the phase angle ``alpha`` between the Sun and the node seen from the Earth's center, arriving from
the Earth's center (a far-field approximation: in low orbit the Earth fills a large cone and the true
response integrates over the visible lit cap; this term gives its order of magnitude, the disc's mean).
Output ``signals`` (N, scale units, held between samples).

Layout: the scalar parameters first (``PARAMETERS``), then ``normal`` (N, 3); the kernel derives N from
the parameter vector's length, ``N = (len(p) - SCALAR_SIZE) / 3``.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from shell.model import InputPort, Layout, Model, ModelError, OutputPort, Parameter, State, named_offsets
from shell.models.ephemeris import ASTRONOMICAL_UNIT
from shell.models.gravity import EARTH_RADIUS
from shell.registry import register_model

PARAMETERS = (
    Parameter("scale", "", 1.0, (), (0.0, None), "output of a cell facing the Sun at 1 AU"),
    Parameter("field_of_view", "rad", np.pi / 2, (), (0.0, np.pi / 2), "half-angle of each cell's cone"),
    Parameter("noise", "", 0.0, (), (0.0, None), "white-noise standard deviation of each output"),
    Parameter("albedo", "", 0.0, (), (0.0, 1.0), "Earth's Bond albedo (0: albedo off; 0.3 typical)"),
    Parameter("body_radius", "m", EARTH_RADIUS, (), (0.0, None), "radius of the albedo body"),
)
NORMAL = Parameter("normal", "", ((0.0, 0.0, 1.0),), (1, 3), (-1.0, 1.0), "cell normals, node axes")
INPUTS = (
    InputPort("position", "m", (3,), "node position from the central body, world axes"),
    InputPort("rotation", "", (3, 3), "rotation node -> world"),
    InputPort("sun_position", "m", (3,), "central body -> Sun, world axes"),
    InputPort("shadow_factor", "", (), "1 lit .. 0 umbra (Eclipse)", required=False, default=1.0),
)
OUTPUTS = (OutputPort("signals", "", (1,), "cell outputs (held)"),)
DISCRETE = (State("signals", "", (1,), None, "held outputs"),)
SCALAR_SIZE = Layout.of(PARAMETERS).size
P = named_offsets(PARAMETERS + (NORMAL,))._replace(normal=None)
U = named_offsets(INPUTS)
Y, Z = named_offsets(OUTPUTS), named_offsets(DISCRETE)


@njit(cache=True)
def lambert_sphere_albedo(cos_alpha):
    """(2 / 3 pi) [sin alpha + (pi - alpha) cos alpha]: a Lambert sphere's phase law (1 at full phase)
    times the 2/3 of its disc-averaged reflectance."""
    alpha = np.arccos(max(-1.0, min(1.0, cos_alpha)))
    return 2.0 / (3.0 * np.pi) * (np.sin(alpha) + (np.pi - alpha) * np.cos(alpha))


@njit(cache=True)
def _css_outputs(t, x, z, u, p, y):
    for k in range(y.shape[0]):
        y[Y.signals + k] = z[Z.signals + k]


@njit(cache=True)
def _css_sample(t, x, z, u, p, noise):
    n = (p.shape[0] - SCALAR_SIZE) // 3
    normal = SCALAR_SIZE
    r, rot, sun = U.position, U.rotation, U.sun_position
    d0, d1, d2 = u[sun] - u[r], u[sun + 1] - u[r + 1], u[sun + 2] - u[r + 2]
    dn = np.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
    rn = np.sqrt(u[r] ** 2 + u[r + 1] ** 2 + u[r + 2] ** 2)
    # node axes: R^T v
    s0 = (u[rot] * d0 + u[rot + 3] * d1 + u[rot + 6] * d2) / dn
    s1 = (u[rot + 1] * d0 + u[rot + 4] * d1 + u[rot + 7] * d2) / dn
    s2 = (u[rot + 2] * d0 + u[rot + 5] * d1 + u[rot + 8] * d2) / dn
    e0 = -(u[rot] * u[r] + u[rot + 3] * u[r + 1] + u[rot + 6] * u[r + 2]) / rn
    e1 = -(u[rot + 1] * u[r] + u[rot + 4] * u[r + 1] + u[rot + 7] * u[r + 2]) / rn
    e2 = -(u[rot + 2] * u[r] + u[rot + 5] * u[r + 1] + u[rot + 8] * u[r + 2]) / rn
    distance = (ASTRONOMICAL_UNIT / dn) ** 2
    direct = distance * u[U.shadow_factor]
    reflected = 0.0
    if p[P.albedo] > 0.0 and rn > p[P.body_radius]:
        sn = np.sqrt(u[sun] ** 2 + u[sun + 1] ** 2 + u[sun + 2] ** 2)
        cos_alpha = (u[r] * u[sun] + u[r + 1] * u[sun + 1] + u[r + 2] * u[sun + 2]) / (rn * sn)
        reflected = distance * p[P.albedo] * (p[P.body_radius] / rn) ** 2 * lambert_sphere_albedo(cos_alpha)
    cos_fov = np.cos(p[P.field_of_view])
    for k in range(n):
        n0, n1, n2 = p[normal + 3 * k], p[normal + 3 * k + 1], p[normal + 3 * k + 2]
        cs = n0 * s0 + n1 * s1 + n2 * s2
        ce = n0 * e0 + n1 * e1 + n2 * e2
        value = 0.0
        if cs > 0.0 and cs >= cos_fov:
            value += direct * cs
        if reflected > 0.0 and ce > 0.0 and ce >= cos_fov:
            value += reflected * ce
        z[Z.signals + k] = max(0.0, p[P.scale] * value + p[P.noise] * noise[k])


@register_model
class CoarseSunSensors(Model):
    """N cosine-response sun cells with field of view, eclipse and optional Earth albedo."""

    summary = "coarse sun sensors at a node: N cosine cells, field of view, shadow, Earth albedo on/off, noise"
    inputs = INPUTS
    offsets = {"p": P, "u": U, "y": Y, "z": Z}
    default_period = "0.1 s"
    state_outputs = staticmethod(_css_outputs)
    update = staticmethod(_css_sample)

    def __init__(self, name: str, *, sensors: int = 1, **kwargs):
        if isinstance(sensors, bool) or not isinstance(sensors, (int, np.integer)) or sensors < 1:
            raise ModelError(f"model {name}: config sensors: expected a positive whole number of cells, "
                             f"given {sensors!r}")
        self.sensor_count = int(sensors)
        super().__init__(name, **kwargs)

    def declare(self):
        n = self.sensor_count
        default = np.tile([0.0, 0.0, 1.0], (n, 1))
        self.parameters = PARAMETERS + (Parameter(NORMAL.name, NORMAL.unit, default, (n, 3), NORMAL.bounds,
                                                  NORMAL.description),)
        self.outputs = (OutputPort("signals", "", (n,), "cell outputs (held)"),)
        self.discrete_states = (State("signals", "", (n,), None, "held outputs"),)
        self.noise_size = n

    def configure(self):
        normals = self.parameter("normal")
        norms = np.linalg.norm(normals, axis=1)
        if np.any(np.abs(norms - 1.0) > 1e-9):
            k = int(np.argmax(np.abs(norms - 1.0)))
            raise ModelError(f"model {self.path}: parameter normal: expected unit vectors, cell {k + 1} has "
                             f"norm {norms[k]:.12g}")
