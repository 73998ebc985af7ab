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

``SunDirectionEstimate`` -- the Sun direction in node axes from the cells' outputs (wire
``CoarseSunSensors.signals`` to ``signals``; give the same ``normal`` and ``scale``). The cells whose output
exceeds ``threshold`` (lit, above the noise) form ``H`` (their normals as rows) and ``y`` (outputs over
``scale``); with three or more whose normals span space, the least-squares solution (Basilisk's
``cssWlsEst`` with unit weights; Wertz sec. 7.1)::

    s = (H^T H)^-1 H^T y,    sun_direction = s / |s|,    valid = 1

and with one or two lit cells the minimum-norm solution ``s = H^T (H H^T)^-1 y`` (the direction is then
only known in their span), ``valid = 0``; no lit cell (eclipse): a zero vector, ``valid = 0``. For cosine
cells without albedo or noise, ``y = H s_true |s|`` and the estimate is exact; the albedo term biases it
towards the Earth. Outputs ``sun_direction`` (unit, node axes), ``valid`` and ``lit_cells``, for a
Sun-safe controller that needs no attitude estimate (``SunSafePointing`` in :mod:`shell.models.guidance`).
Layout as ``CoarseSunSensors``: the scalars first, then ``normal`` (N, 3).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from shell.model import Declarations, InputPort, Layout, Model, ModelError, OutputPort, Parameter, State, count_option
from shell.models.ephemeris import ASTRONOMICAL_UNIT
from shell.models.gravity import EARTH_RADIUS
from shell.ports import node_inputs
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
    *node_inputs("position", "rotation", position="node position from the central body, world axes",
                 rotation="rotation node -> world"),
    InputPort("sun_position", "m", (3,), "central body -> Sun, world axes"),
    InputPort("shadow_factor", "", (), "1 lit .. 0 umbra (Eclipse)", required=False, default=1.0),
)
OUTPUTS = (OutputPort("signals", "", (1,), "cell outputs (held)"),)
DISCRETE = (State("signals", "", (1,), None, "held outputs"),)
SCALAR_SIZE = Layout.of(PARAMETERS).size
#: the cell count is a configuration: ``normal`` (N, 3), the outputs and the held states are sized by it
CSS = Declarations(parameters=PARAMETERS + (NORMAL,), inputs=INPUTS, outputs=OUTPUTS, discrete=DISCRETE,
                   sized=("normal", "signals"))
P, U, Y, Z = CSS.P, CSS.U, CSS.Y, CSS.Z


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
    declarations = CSS
    default_period = "0.1 s"
    state_outputs = staticmethod(_css_outputs)
    update = staticmethod(_css_sample)

    def __init__(self, name: str, *, sensors: int = 1, **kwargs):
        self.sensor_count = count_option(name, "sensors", sensors, "cells")
        super().__init__(name, **kwargs)

    def declare(self):
        n = self.sensor_count
        self.use_declarations(CSS.replace(normal={"default": np.tile([0.0, 0.0, 1.0], (n, 1)), "shape": (n, 3)},
                                          signals={"shape": (n,)}))
        self.noise_size = n

    def configure(self):
        normals = self.parameter("normal")
        norms = np.linalg.norm(normals, axis=1)
        if np.any(np.abs(norms - 1.0) > 1e-9):
            k = int(np.argmax(np.abs(norms - 1.0)))
            raise ModelError(f"model {self.path}: parameter normal: expected unit vectors, cell {k + 1} has "
                             f"norm {norms[k]:.12g}")


ESTIMATE_PARAMETERS = (
    Parameter("scale", "", 1.0, (), (1e-300, None), "output of a cell facing the Sun at 1 AU (as the sensors')"),
    Parameter("threshold", "", 0.05, (), (0.0, None), "outputs at or below it are ignored (unlit or noise)"),
)
ESTIMATE_INPUTS = (InputPort("signals", "", (1,), "cell outputs (CoarseSunSensors.signals)", feedthrough=True),)
ESTIMATE_OUTPUTS = (
    OutputPort("sun_direction", "", (3,), "estimated unit Sun direction, node axes (zero: no lit cell)",
               feedthrough=True),
    OutputPort("valid", "", (), "1: three or more lit cells spanning space, else 0", feedthrough=True),
    OutputPort("lit_cells", "", (), "number of cells above the threshold", feedthrough=True),
)
ESTIMATE_SCALAR_SIZE = Layout.of(ESTIMATE_PARAMETERS).size
ESTIMATE = Declarations(parameters=ESTIMATE_PARAMETERS + (NORMAL,), inputs=ESTIMATE_INPUTS, outputs=ESTIMATE_OUTPUTS,
                        sized=("normal", "signals"))
P_EST, U_EST, Y_EST = ESTIMATE.P, ESTIMATE.U, ESTIMATE.Y


@njit(cache=True)
def _sun_direction_estimate(t, x, z, u, p, y):
    n = (p.shape[0] - ESTIMATE_SCALAR_SIZE) // 3
    normal = ESTIMATE_SCALAR_SIZE
    # normal matrix H^T H (symmetric: a00 a01 a02 a11 a12 a22) and H^T y over the lit cells
    a00 = a01 = a02 = a11 = a12 = a22 = 0.0
    b0 = b1 = b2 = 0.0
    lit = 0
    first, second = -1, -1
    for k in range(n):
        value = u[U_EST.signals + k] / p[P_EST.scale]
        if u[U_EST.signals + k] <= p[P_EST.threshold]:
            continue
        n0, n1, n2 = p[normal + 3 * k], p[normal + 3 * k + 1], p[normal + 3 * k + 2]
        a00 += n0 * n0
        a01 += n0 * n1
        a02 += n0 * n2
        a11 += n1 * n1
        a12 += n1 * n2
        a22 += n2 * n2
        b0 += n0 * value
        b1 += n1 * value
        b2 += n2 * value
        if lit == 0:
            first = k
        elif lit == 1:
            second = k
        lit += 1
    # adjugate of H^T H: its determinant tells whether the lit normals span space
    c00, c01, c02 = a11 * a22 - a12 * a12, a02 * a12 - a01 * a22, a01 * a12 - a02 * a11
    c11, c12, c22 = a00 * a22 - a02 * a02, a01 * a02 - a00 * a12, a00 * a11 - a01 * a01
    det = a00 * c00 + a01 * c01 + a02 * c02
    valid = 0.0
    s0 = s1 = s2 = 0.0
    if lit >= 3 and det > 1e-9:
        s0 = (c00 * b0 + c01 * b1 + c02 * b2) / det
        s1 = (c01 * b0 + c11 * b1 + c12 * b2) / det
        s2 = (c02 * b0 + c12 * b1 + c22 * b2) / det
        valid = 1.0
    elif lit >= 1:
        # minimum norm over the first (one or two) lit cells: s = H^T (H H^T)^-1 y
        i = normal + 3 * first
        y1 = u[U_EST.signals + first] / p[P_EST.scale]
        if second < 0:
            s0, s1, s2 = y1 * p[i], y1 * p[i + 1], y1 * p[i + 2]
        else:
            j = normal + 3 * second
            y2 = u[U_EST.signals + second] / p[P_EST.scale]
            g = p[i] * p[j] + p[i + 1] * p[j + 1] + p[i + 2] * p[j + 2]
            d = 1.0 - g * g
            if d > 1e-12:
                w1, w2 = (y1 - g * y2) / d, (y2 - g * y1) / d
            else:  # parallel cells: one direction
                w1, w2 = 0.5 * (y1 + y2), 0.0
            s0, s1, s2 = w1 * p[i] + w2 * p[j], w1 * p[i + 1] + w2 * p[j + 1], w1 * p[i + 2] + w2 * p[j + 2]
    norm = np.sqrt(s0 * s0 + s1 * s1 + s2 * s2)
    if norm > 0.0:
        s0, s1, s2 = s0 / norm, s1 / norm, s2 / norm
    y[Y_EST.sun_direction], y[Y_EST.sun_direction + 1], y[Y_EST.sun_direction + 2] = s0, s1, s2
    y[Y_EST.valid] = valid
    y[Y_EST.lit_cells] = lit


@register_model
class SunDirectionEstimate(Model):
    """Least-squares Sun direction from N cosine cells (config: sensors); see the module docstring."""

    summary = "Sun direction in node axes from coarse-sun-sensor outputs: least squares over the lit cells"
    declarations = ESTIMATE
    feedthrough_outputs = staticmethod(_sun_direction_estimate)

    def __init__(self, name: str, *, sensors: int = 3, **kwargs):
        self.sensor_count = count_option(name, "sensors", sensors, "cells")
        super().__init__(name, **kwargs)

    def declare(self):
        n = self.sensor_count
        self.use_declarations(ESTIMATE.replace(
            normal={"default": None, "shape": (n, 3), "description": "cell normals, node axes (as the sensors')"},
            signals={"shape": (n,)}))

    def configure(self):
        normals = self.parameter("normal")
        norms = np.linalg.norm(normals, axis=1)
        if np.any(np.abs(norms - 1.0) > 1e-9):
            k = int(np.argmax(np.abs(norms - 1.0)))
            raise ModelError(f"model {self.path}: parameter normal: expected unit vectors, cell {k + 1} has "
                             f"norm {norms[k]:.12g}")
        if np.linalg.matrix_rank(normals) < 3:
            raise ModelError(f"model {self.path}: parameter normal: the {len(normals)} normals do not span space "
                             f"(rank {np.linalg.matrix_rank(normals)}); no cell set can give a 3-D direction")
