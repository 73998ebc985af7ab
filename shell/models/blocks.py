"""Signal blocks: constant, gain, sum, integrator, sample-and-hold, noisy sampler and time profile.

Small framework-level models used to wire scenes, to test the framework, and as the "trivial models"
of the orchestration-overhead benchmark. Each block's port unit and shape are chosen at construction
(``unit="deg/s"``, ``shape=(3,)``; in YAML under ``config:``); parameters take the port unit.

Equations: Constant y = c; Gain y = k u (direct feedthrough); Sum y = u_1 + ... + u_n (direct
feedthrough, e.g. the wheels' spin momenta into one controller input); Integrator x' = u, y = x;
SampleHold z(t_k) = u(t_k), y = z (zero-order hold, TM-2020-5008164 App. D.1 multi-rate models), with a
sample counter; NoisySampler z(t_k) = u(t_k) + sigma n_k, n_k ~ N(0, 1) from the model's own stream;
Profile: a piecewise waveform of time, on segment i (``times[i] <= t < times[i+1]``, local time
``s = (t - times[i]) / (times[i+1] - times[i])`` in [0, 1))::

    y = c0 + c1 s + c2 s^2 + c3 s^3 + cosine cos(2 pi cycles s) + sine sin(2 pi cycles s)

(every coefficient in the port unit, one row per segment), 0 before ``times[0]`` and ``after`` from the last
breakpoint on. Ramps, steps, cubic blends and the one-minus-cosine spin-up law of Kane, Ryan and Banerjee
(JGCD 10(2), 1987: ``theta_ddot = (Omega / T) (1 - cos(2 pi t / T))`` for ``t < T``: one segment ``[0, T]``,
``c0 = Omega / T``, ``cosine = -Omega / T``, ``cycles = 1``) are written without expressions.

Array layouts: a block's port shape is a construction option, so its offsets are not compile-time
constants beyond the first declaration of each array: each block's :class:`Declarations` lists its
port-shaped declarations as ``sized`` (their offsets are always 0) and has ``None`` where the kernel derives
the offset from array sizes (SampleHold's sample counter follows the held sample: at ``Z_HOLD.held +
u.shape[0]``; Sum's input k starts at ``(k - 1) y.shape[0]``). The construction check refuses any other
order.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from shell.model import MAX_COUNT, MAX_ELEMENTS, Declarations, InputPort, Model, ModelError, OutputPort, Parameter, State
from shell.registry import register_model


#: each block's declarations at a scalar port without unit; ``declare`` gives them the block's unit and shape
CONSTANT = Declarations(parameters=(Parameter("value", "", 0.0, (), description="the output value"),),
                        outputs=(OutputPort("y", "", (), "the constant"),), sized=("value", "y"))
GAIN = Declarations(parameters=(Parameter("k", "", 1.0, description="gain"),),
                    inputs=(InputPort("u", "", (), "input", feedthrough=True),),
                    outputs=(OutputPort("y", "", (), "k u", feedthrough=True),), sized=("u", "y"))
SUM = Declarations(outputs=(OutputPort("y", "", (), "sum of the inputs", feedthrough=True),), sized=("y",))
INTEGRATOR = Declarations(inputs=(InputPort("u", "", (), "rate"),), outputs=(OutputPort("y", "", (), "integral"),),
                          continuous=(State("x", "", (), None, "integral of u"),), sized=("u", "y", "x"))
SAMPLE_HOLD = Declarations(inputs=(InputPort("u", "", (), "sampled signal"),),
                           outputs=(OutputPort("y", "", (), "held sample"),),
                           discrete=(State("held", "", (), None, "last sample"),
                                     State("samples", "", (), 0.0, "number of samples taken")),
                           sized=("u", "y", "held"))
NOISY_SAMPLER = Declarations(parameters=(Parameter("sigma", "", 0.0, (), (0.0, None), "noise standard deviation"),),
                             inputs=(InputPort("u", "", (), "sampled signal"),),
                             outputs=(OutputPort("y", "", (), "noisy held sample"),),
                             discrete=(State("held", "", (), None, "last noisy sample"),), sized=("u", "y", "held"))
# Profile: the segment count is a construction option, so only the first offset is a constant; the kernel
# derives m from the sizes: len(p) = (m + 1) + 6 m k + m + k with k the output size (docstring order)
PROFILE = Declarations(
    parameters=(Parameter("times", "s", None, (2,), description="segment breakpoints, ascending"),
                *(Parameter(f"c{j}", "", 0.0, (1,), description=f"coefficient of s^{j} per segment "
                            "(s: local time 0..1 in the segment)") for j in range(4)),
                Parameter("cosine", "", 0.0, (1,), description="amplitude of cos(2 pi cycles s) per segment"),
                Parameter("sine", "", 0.0, (1,), description="amplitude of sin(2 pi cycles s) per segment"),
                Parameter("cycles", "", 1.0, (1,), description="harmonic cycles per segment"),
                Parameter("after", "", 0.0, (), description="output from the last breakpoint on")),
    outputs=(OutputPort("y", "", (), "the profile value"),),
    sized=("times", "y"))
P_CONSTANT, Y_CONSTANT = CONSTANT.P, CONSTANT.Y
P_GAIN, U_GAIN, Y_GAIN = GAIN.P, GAIN.U, GAIN.Y
Y_SUM = SUM.Y
U_INTEGRATOR, Y_INTEGRATOR, X_INTEGRATOR = INTEGRATOR.U, INTEGRATOR.Y, INTEGRATOR.X
U_HOLD, Y_HOLD, Z_HOLD = SAMPLE_HOLD.U, SAMPLE_HOLD.Y, SAMPLE_HOLD.Z
P_NOISY, U_NOISY, Y_NOISY, Z_NOISY = NOISY_SAMPLER.P, NOISY_SAMPLER.U, NOISY_SAMPLER.Y, NOISY_SAMPLER.Z
P_PROFILE, Y_PROFILE = PROFILE.P, PROFILE.Y


@njit(cache=True)
def _constant(t, x, z, u, p, y):
    for i in range(y.shape[0]):
        y[Y_CONSTANT.y + i] = p[P_CONSTANT.value + i]


@njit(cache=True)
def _gain(t, x, z, u, p, y):
    for i in range(y.shape[0]):
        y[Y_GAIN.y + i] = p[P_GAIN.k] * u[U_GAIN.u + i]


@njit(cache=True)
def _sum(t, x, z, u, p, y):
    m = y.shape[0]
    for i in range(m):
        y[Y_SUM.y + i] = 0.0
    for k in range(u.shape[0] // m):  # input k + 1 starts at k m
        for i in range(m):
            y[Y_SUM.y + i] += u[k * m + i]


@njit(cache=True)
def _integral(t, x, z, u, p, y):
    for i in range(y.shape[0]):
        y[Y_INTEGRATOR.y + i] = x[X_INTEGRATOR.x + i]


@njit(cache=True)
def _integrand(t, x, z, u, p, xdot):
    for i in range(xdot.shape[0]):
        xdot[X_INTEGRATOR.x + i] = u[U_INTEGRATOR.u + i]


@njit(cache=True)
def _held_sample(t, x, z, u, p, y):
    for i in range(y.shape[0]):
        y[Y_HOLD.y + i] = z[Z_HOLD.held + i]


@njit(cache=True)
def _sample(t, x, z, u, p):
    n = u.shape[0]
    for i in range(n):
        z[Z_HOLD.held + i] = u[U_HOLD.u + i]
    z[Z_HOLD.held + n] += 1.0  # the sample counter follows the n held values


@njit(cache=True)
def _held_noisy_sample(t, x, z, u, p, y):
    for i in range(y.shape[0]):
        y[Y_NOISY.y + i] = z[Z_NOISY.held + i]


@njit(cache=True)
def _noisy_sample(t, x, z, u, p, noise):
    for i in range(u.shape[0]):
        z[Z_NOISY.held + i] = u[U_NOISY.u + i] + p[P_NOISY.sigma] * noise[i]


@njit(cache=True)
def _profile(t, x, z, u, p, y):
    k = y.shape[0]
    m = (p.shape[0] - 1 - k) // (2 + 6 * k)
    times = p[P_PROFILE.times:P_PROFILE.times + m + 1]
    if t < times[0]:
        for j in range(k):
            y[Y_PROFILE.y + j] = 0.0
        return
    base_after = m + 1 + 6 * m * k + m
    if t >= times[m]:
        for j in range(k):
            y[Y_PROFILE.y + j] = p[base_after + j]
        return
    i = 0
    while i < m - 1 and t >= times[i + 1]:
        i += 1
    s = (t - times[i]) / (times[i + 1] - times[i])
    cycles = p[m + 1 + 6 * m * k + i]
    c = np.cos(2.0 * np.pi * cycles * s)
    sn = np.sin(2.0 * np.pi * cycles * s)
    for j in range(k):
        row = m + 1 + i * k + j          # c0 block; the next blocks follow at strides of m k
        mk = m * k
        y[Y_PROFILE.y + j] = (p[row] + s * (p[row + mk] + s * (p[row + 2 * mk] + s * p[row + 3 * mk]))
                              + p[row + 4 * mk] * c + p[row + 5 * mk] * sn)


class SignalBlock(Model):
    """A block whose port unit and shape are construction options."""

    def __init__(self, name: str, *, unit: str = "", shape=(), **kwargs):
        self.unit = unit
        self.shape = (int(shape),) if isinstance(shape, int) else tuple(int(n) for n in shape)
        self.size = int(np.prod(self.shape, dtype=np.int64)) if self.shape else 1
        #: the unit and shape of the block's port-shaped declarations (Declarations.replace)
        self.port = {"unit": unit, "shape": self.shape}
        super().__init__(name, **kwargs)


@register_model
class Constant(SignalBlock):
    """y = value."""

    summary = "constant output (unit and shape under config:)"
    declarations = CONSTANT
    state_outputs = staticmethod(_constant)

    def declare(self):
        self.use_declarations(CONSTANT.replace(value=self.port, y=self.port))


@register_model
class Gain(SignalBlock):
    """y = k u, direct feedthrough; k has the unit output_unit / unit."""

    summary = "static gain y = k u (direct feedthrough; config: unit, output_unit, shape)"
    declarations = GAIN
    feedthrough_outputs = staticmethod(_gain)

    def __init__(self, name: str, *, unit: str = "", output_unit: str | None = None, shape=(), **kwargs):
        self.output_unit = unit if output_unit is None else output_unit
        super().__init__(name, unit=unit, shape=shape, **kwargs)

    def declare(self):
        self.use_declarations(GAIN.replace(k={"unit": f"({self.output_unit or '1'})/({self.unit or '1'})"}, u=self.port,
                                           y={"unit": self.output_unit, "shape": self.shape}))


@register_model
class Sum(SignalBlock):
    """y = u_1 + ... + u_count, direct feedthrough (config: count, unit, shape)."""

    summary = "sum of count inputs u_1 .. u_count of one unit and shape (config: count, unit, shape)"
    declarations = SUM
    feedthrough_outputs = staticmethod(_sum)

    def __init__(self, name: str, *, count: int = 2, unit: str = "", shape=(), **kwargs):
        if isinstance(count, bool) or not isinstance(count, (int, np.integer)) or not 1 <= count <= MAX_COUNT:
            raise ModelError(f"model {name}: config count: expected an integer >= 1 (the number of inputs, at most "
                             f"{MAX_COUNT}), "
                             f"given {count!r}")
        self.count = int(count)
        super().__init__(name, unit=unit, shape=shape, **kwargs)

    def declare(self):
        terms = tuple(InputPort(f"u_{k}", self.unit, self.shape, f"term {k}", feedthrough=True)
                      for k in range(1, self.count + 1))
        declarations = Declarations(inputs=terms, outputs=SUM.replace(y=self.port).outputs, sized=("u_1",))
        self.use_declarations(declarations)
        self.offsets = {"u": declarations.U, "y": Y_SUM}


@register_model
class Integrator(SignalBlock):
    """x' = u, y = x (u in the unit of y per second)."""

    summary = "continuous integrator x' = u, y = x"
    declarations = INTEGRATOR
    state_outputs = staticmethod(_integral)
    derivatives = staticmethod(_integrand)

    def declare(self):
        self.use_declarations(INTEGRATOR.replace(u={"unit": f"({self.unit or '1'})/s", "shape": self.shape},
                                                 y=self.port, x=self.port))


@register_model
class SampleHold(SignalBlock):
    """Zero-order hold: samples u every period, holds it; counts its samples."""

    summary = "zero-order hold at its own period, with a sample counter"
    declarations = SAMPLE_HOLD
    state_outputs = staticmethod(_held_sample)
    update = staticmethod(_sample)

    def declare(self):
        self.use_declarations(SAMPLE_HOLD.replace(u=self.port, y=self.port, held=self.port))


@register_model
class NoisySampler(SignalBlock):
    """Samples u every period and adds white noise of standard deviation sigma (held between samples)."""

    summary = "sampled signal plus Gaussian white noise from the model's random stream"
    declarations = NOISY_SAMPLER
    state_outputs = staticmethod(_held_noisy_sample)
    update = staticmethod(_noisy_sample)

    def declare(self):
        self.use_declarations(NOISY_SAMPLER.replace(sigma={"unit": self.unit}, u=self.port, y=self.port,
                                                    held=self.port))
        self.noise_size = self.size


@register_model
class Profile(SignalBlock):
    """A piecewise waveform of time (module docstring): ``segments`` under config (default 1); parameters
    ``times`` (segments + 1 ascending breakpoints, s), per segment ``c0`` .. ``c3``, ``cosine``, ``sine`` (port
    unit, shape (segments,) + port shape), ``cycles`` (per segment, default 1) and ``after`` (the value from
    the last breakpoint on, default 0). E.g. the Kane-Ryan-Banerjee spin-up of a hub to 6 rad/s in 15 s::

        spin_up:
          type: Profile
          config: {unit: rad/s^2, shape: [1]}
          parameters: {times: "[0, 15] s", c0: "[[0.4]] rad/s^2", cosine: "[[-0.4]] rad/s^2"}
        connections: [spin_up.y -> multibody.hub.prescribed_accel]
    """

    summary = "time profile: piecewise cubic plus harmonic segments (ramps, steps, 1 - cos spin-up)"
    declarations = PROFILE
    state_outputs = staticmethod(_profile)

    def __init__(self, name: str, *, unit: str = "", shape=(), segments: int = 1, **kwargs):
        if (isinstance(segments, bool) or not isinstance(segments, (int, np.integer))
                or not 1 <= segments <= MAX_ELEMENTS):
            raise ModelError(f"model {name}: Profile config segments must be a whole number >= 1 (at most "
                             f"{MAX_ELEMENTS:.0e}), got {segments!r}")
        self.segments = int(segments)
        super().__init__(name, unit=unit, shape=shape, **kwargs)

    def declare(self):
        m = self.segments
        rows = (m,) + self.shape
        per_segment = {"unit": self.unit, "default": np.zeros(rows), "shape": rows}
        self.use_declarations(PROFILE.replace(
            times={"default": np.arange(m + 1, dtype=float), "shape": (m + 1,)},
            **{name: per_segment for name in ("c0", "c1", "c2", "c3", "cosine", "sine")},
            cycles={"default": np.ones(m), "shape": (m,)},
            after={"unit": self.unit, "default": np.zeros(self.shape), "shape": self.shape}, y=self.port))

    def configure(self):
        times = self.parameter("times")
        if not np.all(np.isfinite(times)) or np.any(np.diff(times) <= 0.0):
            raise ModelError(f"model {self.path}: Profile parameter times must be finite and strictly ascending "
                             f"(one breakpoint more than the {self.segments} segment(s)), got {times.tolist()} s")
        for name in ("c0", "c1", "c2", "c3", "cosine", "sine", "cycles", "after"):
            if not np.all(np.isfinite(self.parameter(name))):
                raise ModelError(f"model {self.path}: Profile parameter {name} must be finite")
        end = self._value_at_end()
        after = np.broadcast_to(self.parameter("after"), end.shape)
        jump = np.abs(end - after)
        if np.any(jump > 1e-9 * max(1.0, float(np.max(np.abs(end))))):
            import warnings

            warnings.warn(f"model {self.path}: Profile jumps at its last breakpoint t = {times[-1]:g} s from "
                          f"{end.tolist()} to after = {after.tolist()} {self.unit} (allowed; a discontinuity the "
                          "integrator steps across)", stacklevel=2)

    def _value_at_end(self):
        """The last segment's value at its end (s = 1)."""
        c = [np.asarray(self.parameter(f"c{j}"))[-1] for j in range(4)]
        n = float(self.parameter("cycles")[-1])
        return (c[0] + c[1] + c[2] + c[3] + np.asarray(self.parameter("cosine"))[-1] * np.cos(2 * np.pi * n)
                + np.asarray(self.parameter("sine"))[-1] * np.sin(2 * np.pi * n))
