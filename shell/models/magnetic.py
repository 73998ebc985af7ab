"""Geomagnetic field (IGRF or its tilted dipole), magnetometer and magnetorquers.

``MagneticField`` -- attach to a node (position and rotation node -> world, world = EME2000 with the
Earth at the origin, see :mod:`shell.models.ephemeris`). The node's position is rotated into Earth-fixed
axes (``r_ecef = R_z(GMST) P r``, IAU 1976 precession and IAU 1982 sidereal time from the scene epoch)
and the field is the spherical-harmonic expansion of the International Geomagnetic Reference Field
(IGRF-14, Alken et al. 2025; geocentric form, Langel 1987 eqs. 3-5, reference radius a = 6371.2 km)::

    V   = a sum_{n=1}^{N} (a/r)^{n+1} sum_{m=0}^{n} (g_nm cos m phi + h_nm sin m phi) P_n^m(cos theta)
    B_r = sum (n+1) (a/r)^{n+2} sum (g cos m phi + h sin m phi) P_n^m
    B_t = -sum (a/r)^{n+2} sum (g cos m phi + h sin m phi) dP_n^m/dtheta
    B_p = -1/sin theta sum (a/r)^{n+2} sum m (-g sin m phi + h cos m phi) P_n^m

with the Schmidt semi-normalized Legendre functions from the recursions (Wertz App. H)
``P_n^n = sqrt((2n-1)/2n) sin theta P_{n-1}^{n-1}`` (``P_1^1 = sin theta``) and
``P_n^m = ((2n-1) cos theta P_{n-1}^m - sqrt((n-1)^2 - m^2) P_{n-2}^m) / sqrt(n^2 - m^2)``, run per order m
with two scalars (nothing allocated); ``P_n^m / sin theta`` (in B_p) follows the same recursions from
``P_1^1 / sin theta = 1``, so the poles need no special case. The Gauss coefficients (parameters ``g``,
``h``, T) come from the
maintained ``ppigrf`` package's IGRF-14 file, linearly interpolated to the scene epoch (as ppigrf
does) and held over the run (secular variation ~0.3 nT per day), unless given. Parameter ``degree``: 13
(full IGRF, default) down to 1, the **tilted centered dipole** (the cheap choice), whose closed form is
``B = (a/r)^3 [3 (m . r_hat) r_hat - m]``, ``m = (g_11, h_11, g_10)`` in Earth-fixed axes.
Outputs (keep the names): ``field_inertial`` (T, world axes) and ``field`` (T, node axes).

``Magnetometer`` -- three-axis magnetometer sampled at its rate: wire ``MagneticField.field`` to its
``true_field`` (node axes); ``mounting`` rotates sensor -> node axes. Each sample::

    b = sat( Q( (I + diag(s)) (I + M) C^T b_node + b_0 + sigma w ) )

scale factor s, small-angle misalignment M (off-diagonal), bias b_0, white noise sigma w (per axis, from
the model's own generator), quantization Q to ``lsb`` and saturation at +-``range``. Output ``field`` (T,
sensor axes; keep the name).

``Magnetorquer`` -- three torque rods along the node axes: input ``dipole_command`` (A m^2, node axes;
keep the name) clipped per axis at ``max_dipole`` and quantized to ``lsb``; input ``field`` (T, node
axes, from ``MagneticField.field``); torque ``T = m x B`` on the node (Wertz sec. 19.1).
"""

from __future__ import annotations

import datetime as _datetime
import numpy as np
from numba import njit

from shell.attitude import quaternion_to_matrix
from shell.model import Declarations, InputPort, Model, ModelError, OutputPort, Parameter, State
from shell.models.ephemeris import EARTH_MAGNETIC_RADIUS, EPOCH_PARAMETERS, J2000, EpochModel, earth_fixed_rotation
from shell.ports import node_inputs, node_load_outputs
from shell.registry import register_model

MAX_DEGREE = 13
NT = 1e-9


def igrf_coefficients(epoch_julian_date: float, degree: int = MAX_DEGREE, coefficient_file=None):
    """IGRF Gauss coefficients g, h (T, arrays (14, 14) indexed [n, m]) at a UTC Julian date, read from
    the ppigrf package's IGRF file (default its newest, IGRF-14; ``coefficient_file`` another .shc file
    such as ``ppigrf.ppigrf.shc_fn_igrf13``) and linearly interpolated in time (ppigrf's own rule)."""
    import pandas as pd
    from ppigrf.ppigrf import read_shc

    date = _datetime.datetime(2000, 1, 1, 12) + _datetime.timedelta(days=float(epoch_julian_date) - J2000)
    g_table, h_table = read_shc() if coefficient_file is None else read_shc(coefficient_file)
    first, last = g_table.index[0], g_table.index[-1]
    if not first <= pd.Timestamp(date) <= last:
        raise ModelError(f"epoch {date.isoformat()}: outside the IGRF coefficient file ({first.date()} to "
                         f"{last.date()})")
    out = []
    for table in (g_table, h_table):
        index = table.index.union([pd.Timestamp(date)])
        values = table.reindex(index).groupby(index).first().interpolate(method="time").loc[pd.Timestamp(date)]
        c = np.zeros((MAX_DEGREE + 1, MAX_DEGREE + 1))
        for (n, m), v in values.items():
            if n <= degree:
                c[n, m] = float(v) * NT
        out.append(c)
    return out[0], out[1]


@njit(cache=True)
def spherical_harmonic_field(x, y, z, g, h, degree, a):
    """Field (Earth-fixed Cartesian, units of g) of the expansion at Earth-fixed (x, y, z) (m); g, h
    flattened (14, 14) arrays [n, m]; see the module docstring."""
    r = np.sqrt(x * x + y * y + z * z)
    rho = np.sqrt(x * x + y * y)
    ct, st = z / r, rho / r
    phi = np.arctan2(y, x)
    ratio = a / r
    br = bt = bp = 0.0
    pmm, dpmm = 1.0, 0.0  # P_m^m, dP_m^m / dtheta
    qmm = 1.0             # P_m^m / sin theta (m >= 1): the same recursions, finite at the poles
    for m in range(degree + 1):
        if m == 1:
            pmm, dpmm, qmm = st, ct, 1.0
        elif m > 1:
            k = np.sqrt((2.0 * m - 1.0) / (2.0 * m))
            pmm, dpmm, qmm = k * st * pmm, k * (ct * pmm + st * dpmm), k * st * qmm
        cm, sm = np.cos(m * phi), np.sin(m * phi)
        p1, dp1, q1 = pmm, dpmm, qmm     # at n = m
        p2, dp2, q2 = 0.0, 0.0, 0.0      # at n - 1
        for n in range(max(m, 1), degree + 1):
            if n > m:
                k1 = 2.0 * n - 1.0
                k2 = np.sqrt((n - 1.0) ** 2 - m * m)
                k3 = np.sqrt(n * n - m * m)
                pn = (k1 * ct * p1 - k2 * p2) / k3
                dpn = (k1 * (ct * dp1 - st * p1) - k2 * dp2) / k3
                qn = (k1 * ct * q1 - k2 * q2) / k3
                p2, dp2, q2, p1, dp1, q1 = p1, dp1, q1, pn, dpn, qn
            gnm, hnm = g[n * (MAX_DEGREE + 1) + m], h[n * (MAX_DEGREE + 1) + m]
            scale = ratio ** (n + 2)
            term = gnm * cm + hnm * sm
            br += (n + 1.0) * scale * term * p1
            bt -= scale * term * dp1
            if m > 0:
                bp -= scale * m * (-gnm * sm + hnm * cm) * q1
    cp, sp = np.cos(phi), np.sin(phi)
    bx = st * cp * br + ct * cp * bt - sp * bp
    by = st * sp * br + ct * sp * bt + cp * bp
    bz = ct * br - st * bt
    return bx, by, bz


FIELD_PARAMETERS = EPOCH_PARAMETERS + (
    Parameter("reference_radius", "m", EARTH_MAGNETIC_RADIUS, (), (0.0, None), "IGRF reference radius a"),
    Parameter("degree", "", float(MAX_DEGREE), (), (1.0, float(MAX_DEGREE)),
              "expansion degree: 13 full IGRF .. 1 tilted dipole"),
    Parameter("g", "T", np.zeros((MAX_DEGREE + 1, MAX_DEGREE + 1)), (MAX_DEGREE + 1, MAX_DEGREE + 1), None,
              "Gauss coefficients g[n, m] (all zero: IGRF at the epoch)"),
    Parameter("h", "T", np.zeros((MAX_DEGREE + 1, MAX_DEGREE + 1)), (MAX_DEGREE + 1, MAX_DEGREE + 1), None,
              "Gauss coefficients h[n, m] (all zero: IGRF at the epoch)"),
)
FIELD_INPUTS = (
    *node_inputs("position", "rotation", feedthrough=True,
                 position="node position from the Earth's center, world axes", rotation="rotation node -> world"),
)
FIELD_OUTPUTS = (
    OutputPort("field_inertial", "T", (3,), "geomagnetic field, world axes", feedthrough=True),
    OutputPort("field", "T", (3,), "geomagnetic field, node axes", feedthrough=True),
)
FIELD = Declarations(parameters=FIELD_PARAMETERS, inputs=FIELD_INPUTS, outputs=FIELD_OUTPUTS)
PF, UF, YF = FIELD.P, FIELD.U, FIELD.Y


@njit(cache=True)
def _field_outputs(t, x, z, u, p, y):
    e = earth_fixed_rotation(t, p[PF.epoch_julian_date], p[PF.tt_minus_utc])
    r = UF.position
    r0, r1, r2 = u[r], u[r + 1], u[r + 2]
    xe = e[0] * r0 + e[1] * r1 + e[2] * r2
    ye = e[3] * r0 + e[4] * r1 + e[5] * r2
    ze = e[6] * r0 + e[7] * r1 + e[8] * r2
    bx, by, bz = spherical_harmonic_field(xe, ye, ze, p[PF.g:PF.g + (MAX_DEGREE + 1) ** 2],
                                          p[PF.h:PF.h + (MAX_DEGREE + 1) ** 2], int(p[PF.degree]),
                                          p[PF.reference_radius])
    w0 = e[0] * bx + e[3] * by + e[6] * bz  # E^T b
    w1 = e[1] * bx + e[4] * by + e[7] * bz
    w2 = e[2] * bx + e[5] * by + e[8] * bz
    y[YF.field_inertial], y[YF.field_inertial + 1], y[YF.field_inertial + 2] = w0, w1, w2
    rot = UF.rotation
    for i in range(3):
        y[YF.field + i] = u[rot + i] * w0 + u[rot + 3 + i] * w1 + u[rot + 6 + i] * w2  # R^T b


@register_model
class MagneticField(EpochModel):
    """IGRF (degree 1..13, 1 = tilted dipole) at a node, world and node axes; see the module docstring."""

    summary = "geomagnetic field at a node: IGRF-14 (ppigrf coefficients) or tilted dipole (degree: 1)"
    declarations = FIELD
    feedthrough_outputs = staticmethod(_field_outputs)

    def configure(self):
        g, h = self.parameter("g"), self.parameter("h")
        degree = int(self.parameter("degree"))
        if degree != float(self.parameter("degree")):
            raise ModelError(f"model {self.path}: parameter degree: expected a whole number 1 (tilted dipole) to "
                             f"{MAX_DEGREE} (full IGRF), given {float(self.parameter('degree')):g}")
        if not g.any() and not h.any():
            try:
                g_igrf, h_igrf = igrf_coefficients(float(self.parameter("epoch_julian_date")), degree)
            except ModelError as error:
                raise ModelError(f"model {self.path}: {error}") from None
            g[...] = g_igrf
            h[...] = h_igrf
        elif np.any(g[degree + 1:]) or np.any(h[degree + 1:]):
            raise ModelError(f"model {self.path}: parameters g, h: coefficients above degree {degree} are given "
                             f"but parameter degree is {degree}")


# -- magnetometer ------------------------------------------------------------------------------------

MAGNETOMETER_PARAMETERS = (
    Parameter("mounting", "", (1.0, 0.0, 0.0, 0.0), (4,), (-1.0, 1.0), "quaternion sensor -> node [w, x, y, z]"),
    Parameter("noise", "T", (0.0, 0.0, 0.0), (3,), (0.0, None), "white-noise standard deviation per axis"),
    Parameter("bias", "T", (0.0, 0.0, 0.0), (3,), None, "constant bias per axis"),
    Parameter("scale_factor", "", (0.0, 0.0, 0.0), (3,), (-0.5, 0.5), "scale-factor error per axis"),
    Parameter("misalignment", "rad", np.zeros((3, 3)), (3, 3), (-0.1, 0.1),
              "small-angle misalignment: sensed_i += M_ij true_j (diagonal zero)"),
    Parameter("lsb", "T", 0.0, (), (0.0, None), "quantization step (0: none)"),
    Parameter("range", "T", 0.0, (), (0.0, None), "saturation +-range per axis (0: none)"),
)
MAGNETOMETER_INPUTS = (InputPort("true_field", "T", (3,), "geomagnetic field, node axes"),)
MAGNETOMETER_OUTPUTS = (OutputPort("field", "T", (3,), "measured field, sensor axes (held)"),)
MAGNETOMETER_DISCRETE = (State("field", "T", (3,), None, "held measurement"),)
MAGNETOMETER = Declarations(parameters=MAGNETOMETER_PARAMETERS, inputs=MAGNETOMETER_INPUTS,
                            outputs=MAGNETOMETER_OUTPUTS, discrete=MAGNETOMETER_DISCRETE)
PM, UM, YM, ZM = MAGNETOMETER.P, MAGNETOMETER.U, MAGNETOMETER.Y, MAGNETOMETER.Z


@njit(cache=True)
def _magnetometer_outputs(t, x, z, u, p, y):
    for i in range(3):
        y[YM.field + i] = z[ZM.field + i]


@njit(cache=True)
def _magnetometer_sample(t, x, z, u, p, noise):
    m = PM.mounting
    c = quaternion_to_matrix(p[m], p[m + 1], p[m + 2], p[m + 3])
    b = UM.true_field
    s0 = c[0] * u[b] + c[3] * u[b + 1] + c[6] * u[b + 2]  # C^T b: node -> sensor axes
    s1 = c[1] * u[b] + c[4] * u[b + 1] + c[7] * u[b + 2]
    s2 = c[2] * u[b] + c[5] * u[b + 1] + c[8] * u[b + 2]
    sensed = (s0, s1, s2)
    lsb, limit = p[PM.lsb], p[PM.range]
    for i in range(3):
        aligned = sensed[i]
        for j in range(3):
            aligned += p[PM.misalignment + 3 * i + j] * sensed[j]
        value = (1.0 + p[PM.scale_factor + i]) * aligned + p[PM.bias + i] + p[PM.noise + i] * noise[i]
        if lsb > 0.0:
            value = np.floor(value / lsb + 0.5) * lsb
        if limit > 0.0:
            value = min(max(value, -limit), limit)
        z[ZM.field + i] = value


def _check_misalignment(model, name="misalignment"):
    m = model.parameter(name)
    if np.any(np.diag(m) != 0.0):
        raise ModelError(f"model {model.path}: parameter {name}: the diagonal must be zero (scale-factor "
                         f"errors go into scale_factor), given {np.diag(m).tolist()}")


@register_model
class Magnetometer(Model):
    """Three-axis magnetometer: mounting, misalignment, scale factor, bias, noise, quantization, range."""

    summary = "three-axis magnetometer: true_field (node axes) in, field (sensor axes) out; noise, bias, lsb"
    declarations = MAGNETOMETER
    noise_size = 3
    default_period = "0.1 s"
    state_outputs = staticmethod(_magnetometer_outputs)
    update = staticmethod(_magnetometer_sample)

    def configure(self):
        self.require_unit_norm("mounting")
        _check_misalignment(self)


# -- magnetorquers -----------------------------------------------------------------------------------

TORQUER_PARAMETERS = (
    Parameter("max_dipole", "A*m^2", (10.0, 10.0, 10.0), (3,), (0.0, None), "dipole limit per rod"),
    Parameter("lsb", "A*m^2", 0.0, (), (0.0, None), "dipole quantization step (0: none)"),
)
TORQUER_INPUTS = (
    InputPort("dipole_command", "A*m^2", (3,), "commanded dipole, node axes", feedthrough=True),
    InputPort("field", "T", (3,), "geomagnetic field, node axes (MagneticField.field)", feedthrough=True),
)
TORQUER_OUTPUTS = (
    *node_load_outputs("torque", torque="magnetic torque m x B on the node, node axes"),
    OutputPort("dipole", "A*m^2", (3,), "dipole produced (clipped, quantized)", feedthrough=True),
)
TORQUER = Declarations(parameters=TORQUER_PARAMETERS, inputs=TORQUER_INPUTS, outputs=TORQUER_OUTPUTS)
PT, UT, YT = TORQUER.P, TORQUER.U, TORQUER.Y


@njit(cache=True)
def _torquer_outputs(t, x, z, u, p, y):
    lsb = p[PT.lsb]
    for i in range(3):
        limit = p[PT.max_dipole + i]
        m = min(max(u[UT.dipole_command + i], -limit), limit)
        if lsb > 0.0:
            m = np.floor(m / lsb + 0.5) * lsb
            if abs(m) > limit:  # rounding may step past the limit
                m -= lsb * np.sign(m)
        y[YT.dipole + i] = m
    m0, m1, m2 = y[YT.dipole], y[YT.dipole + 1], y[YT.dipole + 2]
    b = UT.field
    y[YT.torque] = m1 * u[b + 2] - m2 * u[b + 1]
    y[YT.torque + 1] = m2 * u[b] - m0 * u[b + 2]
    y[YT.torque + 2] = m0 * u[b + 1] - m1 * u[b]


@register_model
class Magnetorquer(Model):
    """Three magnetic torque rods along the node axes: dipole limits, quantization, torque m x B."""

    summary = "three torque rods: dipole_command (A m^2) and field in, torque m x B on the node (clipped, quantized)"
    declarations = TORQUER
    feedthrough_outputs = staticmethod(_torquer_outputs)
