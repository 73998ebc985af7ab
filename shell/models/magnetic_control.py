"""Magnetic flight-software laws: B-dot detumbling and momentum dumping (sampled, dipole commands).

Both read the measured field in node axes (a ``Magnetometer`` whose mounting is the identity, or any
field source in node axes) and hold a ``dipole_command`` (A m^2, node axes) for a ``Magnetorquer``. A
command over a rod's ``max_dipole`` is scaled down as a whole (its direction kept), so that the largest
axis sits at its limit.

``BDot`` (Stickler & Alfriend 1976; Wertz sec. 19.1; Markley & Crassidis sec. 7.5.1): the body-frame
field derivative by the backward difference of two samples, ``m = -k (B_k - B_{k-1}) / T``. In the
continuous limit ``dB/dt = -omega x B`` (field fixed in space over the sample), so the torque
``m x B = -k (B x omega) x B`` removes kinetic energy ``-k |omega x B|^2`` (never adds it). The first
sample has no difference and commands zero.

``MomentumDumping`` (cross-product law; Markley & Crassidis sec. 7.5.2; Camillo & Markley 1980)::

    m = k (h x B) / |B|^2,        so that  T = m x B = -k (h - (h . B_hat) B_hat)

the external torque that removes the stored wheel momentum ``h`` (node axes, input ``wheel_momentum``)
across the field at the rate k (1/s); the component along B cannot be removed at this instant.
"""

from __future__ import annotations

from numba import njit

from shell.model import Declarations, InputPort, Model, OutputPort, Parameter, State
from shell.registry import register_model


@njit(cache=True)
def _store_limited(z, at, m0, m1, m2, p, limit):
    """Write (m0, m1, m2) at z[at:], scaled so that no axis exceeds p[limit + i]."""
    scale = 1.0
    for i, m in enumerate((m0, m1, m2)):
        if abs(m) * scale > p[limit + i]:
            scale = p[limit + i] / abs(m)
    z[at], z[at + 1], z[at + 2] = scale * m0, scale * m1, scale * m2


BDOT_PARAMETERS = (
    Parameter("gain", "A*m^2*s/T", 1.0e5, (), (0.0, None), "k: dipole per rate of change of the field"),
    Parameter("max_dipole", "A*m^2", (10.0, 10.0, 10.0), (3,), (0.0, None), "dipole limit per axis"),
)
FIELD_INPUT = (InputPort("field", "T", (3,), "measured field, node axes"),)
COMMAND_OUTPUT = (OutputPort("dipole_command", "A*m^2", (3,), "dipole command, node axes (held)"),)
BDOT_DISCRETE = (
    State("dipole_command", "A*m^2", (3,), None, "held command"),
    State("previous_field", "T", (3,), None, "field at the previous sample"),
    State("previous_time", "s", (), -1.0, "time of the previous sample (< 0: none yet)"),
)
BDOT = Declarations(parameters=BDOT_PARAMETERS, inputs=FIELD_INPUT, outputs=COMMAND_OUTPUT, discrete=BDOT_DISCRETE)
PB, UB, YB, ZB = BDOT.P, BDOT.U, BDOT.Y, BDOT.Z


@njit(cache=True)
def _bdot_command(t, x, z, u, p, y):
    for i in range(3):
        y[YB.dipole_command + i] = z[ZB.dipole_command + i]


@njit(cache=True)
def _bdot_update(t, x, z, u, p):
    b, prev = UB.field, ZB.previous_field
    if z[ZB.previous_time] >= 0.0 and t > z[ZB.previous_time]:
        k = -p[PB.gain] / (t - z[ZB.previous_time])
        _store_limited(z, ZB.dipole_command, k * (u[b] - z[prev]), k * (u[b + 1] - z[prev + 1]),
                       k * (u[b + 2] - z[prev + 2]), p, PB.max_dipole)
    else:
        _store_limited(z, ZB.dipole_command, 0.0, 0.0, 0.0, p, PB.max_dipole)
    for i in range(3):
        z[prev + i] = u[b + i]
    z[ZB.previous_time] = t


@register_model
class BDot(Model):
    """B-dot detumbling law ``m = -k dB/dt`` (backward difference of the sampled field), direction-preserving
    dipole limits; see the module docstring."""

    summary = "B-dot detumbling: field (node axes) in, dipole_command = -k dB/dt out (held, limited)"
    declarations = BDOT
    default_period = "1 s"
    state_outputs = staticmethod(_bdot_command)
    update = staticmethod(_bdot_update)


DUMP_PARAMETERS = (
    Parameter("gain", "1/s", 0.01, (), (0.0, None), "k: momentum removal rate"),
    Parameter("max_dipole", "A*m^2", (10.0, 10.0, 10.0), (3,), (0.0, None), "dipole limit per axis"),
)
DUMP_INPUTS = FIELD_INPUT + (InputPort("wheel_momentum", "N*m*s", (3,), "stored wheel momentum, node axes"),)
DUMP_DISCRETE = (State("dipole_command", "A*m^2", (3,), None, "held command"),)
DUMPING = Declarations(parameters=DUMP_PARAMETERS, inputs=DUMP_INPUTS, outputs=COMMAND_OUTPUT, discrete=DUMP_DISCRETE)
PD, UD, YD, ZD = DUMPING.P, DUMPING.U, DUMPING.Y, DUMPING.Z


@njit(cache=True)
def _dump_command(t, x, z, u, p, y):
    for i in range(3):
        y[YD.dipole_command + i] = z[ZD.dipole_command + i]


@njit(cache=True)
def _dump_update(t, x, z, u, p):
    b, h = UD.field, UD.wheel_momentum
    b0, b1, b2 = u[b], u[b + 1], u[b + 2]
    h0, h1, h2 = u[h], u[h + 1], u[h + 2]
    b2n = b0 * b0 + b1 * b1 + b2 * b2
    if b2n <= 0.0:
        _store_limited(z, ZD.dipole_command, 0.0, 0.0, 0.0, p, PD.max_dipole)
        return
    k = p[PD.gain] / b2n
    _store_limited(z, ZD.dipole_command, k * (h1 * b2 - h2 * b1), k * (h2 * b0 - h0 * b2), k * (h0 * b1 - h1 * b0),
                   p, PD.max_dipole)


@register_model
class MomentumDumping(Model):
    """Magnetic momentum dumping ``m = k (h x B) / |B|^2``, direction-preserving dipole limits."""

    summary = "magnetic momentum dumping: field and wheel_momentum in, dipole_command = k h x B / |B|^2 out"
    declarations = DUMPING
    default_period = "1 s"
    state_outputs = staticmethod(_dump_command)
    update = staticmethod(_dump_update)
