"""Signal blocks: constant, gain, sum, integrator, sample-and-hold and noisy sampler.

Small framework-level models used to wire scenes, to test the framework, and as the "trivial models"
of the orchestration-overhead benchmark. Each block's port unit and shape are chosen at construction
(``unit="deg/s"``, ``shape=(3,)``; in YAML under ``config:``); parameters take the port unit.

Equations: Constant y = c; Gain y = k u (direct feedthrough); Sum y = u_1 + ... + u_n (direct
feedthrough, e.g. the wheels' spin momenta into one controller input); Integrator x' = u, y = x;
SampleHold z(t_k) = u(t_k), y = z (zero-order hold, TM-2020-5008164 App. D.1 multi-rate models), with a
sample counter; NoisySampler z(t_k) = u(t_k) + sigma n_k, n_k ~ N(0, 1) from the model's own stream.

Array layouts: a block's port shape is a construction option, so its offsets are not compile-time
constants beyond the first declaration of each array: the named tuples below hold those (always 0)
and ``None`` where the kernel derives the offset from array sizes (SampleHold's sample counter follows
the held sample: at ``Z_HOLD.held + u.shape[0]``; Sum's input k starts at ``(k - 1) y.shape[0]``). The
construction check refuses any other order.
"""

from __future__ import annotations

from collections import namedtuple

import numpy as np
from numba import njit

from shell.model import InputPort, Model, ModelError, OutputPort, Parameter, State
from shell.registry import register_model


def _offsets(typename, **offsets):
    return namedtuple(typename, list(offsets))(*offsets.values())


P_CONSTANT, Y_CONSTANT = _offsets("ConstantParameters", value=0), _offsets("ConstantOutputs", y=0)
P_GAIN, U_GAIN, Y_GAIN = _offsets("GainParameters", k=0), _offsets("GainInputs", u=0), _offsets("GainOutputs", y=0)
Y_SUM = _offsets("SumOutputs", y=0)
U_INTEGRATOR, Y_INTEGRATOR = _offsets("IntegratorInputs", u=0), _offsets("IntegratorOutputs", y=0)
X_INTEGRATOR = _offsets("IntegratorStates", x=0)
U_HOLD, Y_HOLD = _offsets("SampleHoldInputs", u=0), _offsets("SampleHoldOutputs", y=0)
Z_HOLD = _offsets("SampleHoldDiscrete", held=0, samples=None)
P_NOISY, U_NOISY, Y_NOISY = (_offsets("NoisySamplerParameters", sigma=0), _offsets("NoisySamplerInputs", u=0),
                             _offsets("NoisySamplerOutputs", y=0))
Z_NOISY = _offsets("NoisySamplerDiscrete", held=0)


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


class _Block(Model):
    """A block whose port unit and shape are construction options."""

    def __init__(self, name: str, *, unit: str = "", shape=(), **kwargs):
        self.unit = unit
        self.shape = (int(shape),) if isinstance(shape, int) else tuple(int(n) for n in shape)
        self.size = int(np.prod(self.shape, dtype=np.int64)) if self.shape else 1
        super().__init__(name, **kwargs)


@register_model
class Constant(_Block):
    """y = value."""

    summary = "constant output (unit and shape under config:)"
    state_outputs = staticmethod(_constant)
    offsets = {"p": P_CONSTANT, "y": Y_CONSTANT}

    def declare(self):
        self.parameters = (Parameter("value", self.unit, 0.0, self.shape, description="the output value"),)
        self.outputs = (OutputPort("y", self.unit, self.shape, "the constant"),)


@register_model
class Gain(_Block):
    """y = k u, direct feedthrough; k has the unit output_unit / unit."""

    summary = "static gain y = k u (direct feedthrough; config: unit, output_unit, shape)"
    feedthrough_outputs = staticmethod(_gain)
    offsets = {"p": P_GAIN, "u": U_GAIN, "y": Y_GAIN}

    def __init__(self, name: str, *, unit: str = "", output_unit: str | None = None, shape=(), **kwargs):
        self.output_unit = unit if output_unit is None else output_unit
        super().__init__(name, unit=unit, shape=shape, **kwargs)

    def declare(self):
        gain_unit = f"({self.output_unit or '1'})/({self.unit or '1'})"
        self.parameters = (Parameter("k", gain_unit, 1.0, description="gain"),)
        self.inputs = (InputPort("u", self.unit, self.shape, "input", feedthrough=True),)
        self.outputs = (OutputPort("y", self.output_unit, self.shape, "k u", feedthrough=True),)


@register_model
class Sum(_Block):
    """y = u_1 + ... + u_count, direct feedthrough (config: count, unit, shape)."""

    summary = "sum of count inputs u_1 .. u_count of one unit and shape (config: count, unit, shape)"
    feedthrough_outputs = staticmethod(_sum)

    def __init__(self, name: str, *, count: int = 2, unit: str = "", shape=(), **kwargs):
        if isinstance(count, bool) or not isinstance(count, (int, np.integer)) or count < 1:
            raise ModelError(f"model {name}: config count: expected an integer >= 1 (the number of inputs), "
                             f"given {count!r}")
        self.count = int(count)
        super().__init__(name, unit=unit, shape=shape, **kwargs)

    def declare(self):
        self.inputs = tuple(InputPort(f"u_{k}", self.unit, self.shape, f"term {k}", feedthrough=True)
                            for k in range(1, self.count + 1))
        self.outputs = (OutputPort("y", self.unit, self.shape, "sum of the inputs", feedthrough=True),)
        self.offsets = {"u": _offsets("SumInputs", **{f"u_{k}": 0 if k == 1 else None
                                                    for k in range(1, self.count + 1)}), "y": Y_SUM}


@register_model
class Integrator(_Block):
    """x' = u, y = x (u in the unit of y per second)."""

    summary = "continuous integrator x' = u, y = x"
    state_outputs = staticmethod(_integral)
    derivatives = staticmethod(_integrand)
    offsets = {"u": U_INTEGRATOR, "y": Y_INTEGRATOR, "x": X_INTEGRATOR}

    def declare(self):
        self.inputs = (InputPort("u", f"({self.unit or '1'})/s", self.shape, "rate"),)
        self.outputs = (OutputPort("y", self.unit, self.shape, "integral"),)
        self.continuous_states = (State("x", self.unit, self.shape, None, "integral of u"),)


@register_model
class SampleHold(_Block):
    """Zero-order hold: samples u every period, holds it; counts its samples."""

    summary = "zero-order hold at its own period, with a sample counter"
    state_outputs = staticmethod(_held_sample)
    update = staticmethod(_sample)
    offsets = {"u": U_HOLD, "y": Y_HOLD, "z": Z_HOLD}

    def declare(self):
        self.inputs = (InputPort("u", self.unit, self.shape, "sampled signal"),)
        self.outputs = (OutputPort("y", self.unit, self.shape, "held sample"),)
        self.discrete_states = (State("held", self.unit, self.shape, None, "last sample"),
                                State("samples", "", (), 0.0, "number of samples taken"))


@register_model
class NoisySampler(_Block):
    """Samples u every period and adds white noise of standard deviation sigma (held between samples)."""

    summary = "sampled signal plus Gaussian white noise from the model's random stream"
    state_outputs = staticmethod(_held_noisy_sample)
    update = staticmethod(_noisy_sample)
    offsets = {"p": P_NOISY, "u": U_NOISY, "y": Y_NOISY, "z": Z_NOISY}

    def declare(self):
        self.parameters = (Parameter("sigma", self.unit, 0.0, (), (0.0, None), "noise standard deviation"),)
        self.inputs = (InputPort("u", self.unit, self.shape, "sampled signal"),)
        self.outputs = (OutputPort("y", self.unit, self.shape, "noisy held sample"),)
        self.discrete_states = (State("held", self.unit, self.shape, None, "last noisy sample"),)
        self.noise_size = self.size
