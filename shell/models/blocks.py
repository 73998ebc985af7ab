"""Signal blocks: constant, gain, integrator, sample-and-hold and noisy sampler.

Small framework-level models used to wire scenes, to test the framework, and as the "trivial models"
of the orchestration-overhead benchmark. Each block's port unit and shape are chosen at construction
(``unit="deg/s"``, ``shape=(3,)``; in YAML under ``config:``); parameters take the port unit.

Equations: Constant y = c; Gain y = k u (direct feedthrough); Integrator x' = u, y = x;
SampleHold z(t_k) = u(t_k), y = z (zero-order hold, TM-2020-5008164 App. D.1 multi-rate models), with a
sample counter; NoisySampler z(t_k) = u(t_k) + sigma n_k, n_k ~ N(0, 1) from the model's own stream.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from shell.model import InputPort, Model, OutputPort, Parameter, State
from shell.registry import register_model


@njit(cache=True)
def _copy_parameters(t, x, z, u, p, y):
    y[:] = p


@njit(cache=True)
def _gain(t, x, z, u, p, y):
    for i in range(y.shape[0]):
        y[i] = p[0] * u[i]


@njit(cache=True)
def _copy_state(t, x, z, u, p, y):
    y[:] = x


@njit(cache=True)
def _state_rate_is_input(t, x, z, u, p, xdot):
    xdot[:] = u


@njit(cache=True)
def _hold_output(t, x, z, u, p, y):
    y[:] = z[:y.shape[0]]


@njit(cache=True)
def _sample(t, x, z, u, p):
    n = u.shape[0]
    z[:n] = u
    z[n] += 1.0


@njit(cache=True)
def _add_noise(z, u, sigma, noise):
    for i in range(u.shape[0]):
        z[i] = u[i] + sigma * noise[i]


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
    state_outputs = staticmethod(_copy_parameters)

    def declare(self):
        self.parameters = (Parameter("value", self.unit, 0.0, self.shape, description="the output value"),)
        self.outputs = (OutputPort("y", self.unit, self.shape, "the constant"),)


@register_model
class Gain(_Block):
    """y = k u, direct feedthrough; k has the unit output_unit / unit."""

    summary = "static gain y = k u (direct feedthrough; config: unit, output_unit, shape)"
    feedthrough_outputs = staticmethod(_gain)

    def __init__(self, name: str, *, unit: str = "", output_unit: str | None = None, shape=(), **kwargs):
        self.output_unit = unit if output_unit is None else output_unit
        super().__init__(name, unit=unit, shape=shape, **kwargs)

    def declare(self):
        gain_unit = f"({self.output_unit or '1'})/({self.unit or '1'})"
        self.parameters = (Parameter("k", gain_unit, 1.0, description="gain"),)
        self.inputs = (InputPort("u", self.unit, self.shape, "input", feedthrough=True),)
        self.outputs = (OutputPort("y", self.output_unit, self.shape, "k u", feedthrough=True),)


@register_model
class Integrator(_Block):
    """x' = u, y = x (u in the unit of y per second)."""

    summary = "continuous integrator x' = u, y = x"
    state_outputs = staticmethod(_copy_state)
    derivatives = staticmethod(_state_rate_is_input)

    def declare(self):
        self.inputs = (InputPort("u", f"({self.unit or '1'})/s", self.shape, "rate"),)
        self.outputs = (OutputPort("y", self.unit, self.shape, "integral"),)
        self.continuous_states = (State("x", self.unit, self.shape, None, "integral of u"),)


@register_model
class SampleHold(_Block):
    """Zero-order hold: samples u every period, holds it; counts its samples."""

    summary = "zero-order hold at its own period, with a sample counter"
    state_outputs = staticmethod(_hold_output)
    update = staticmethod(_sample)

    def declare(self):
        self.inputs = (InputPort("u", self.unit, self.shape, "sampled signal"),)
        self.outputs = (OutputPort("y", self.unit, self.shape, "held sample"),)
        self.discrete_states = (State("held", self.unit, self.shape, None, "last sample"),
                                State("samples", "", (), 0.0, "number of samples taken"))


@register_model
class NoisySampler(_Block):
    """Samples u every period and adds white noise of standard deviation sigma (held between samples)."""

    summary = "sampled signal plus Gaussian white noise from the model's random stream"
    state_outputs = staticmethod(_hold_output)

    def declare(self):
        self.parameters = (Parameter("sigma", self.unit, 0.0, (), (0.0, None), "noise standard deviation"),)
        self.inputs = (InputPort("u", self.unit, self.shape, "sampled signal"),)
        self.outputs = (OutputPort("y", self.unit, self.shape, "noisy held sample"),)
        self.discrete_states = (State("held", self.unit, self.shape, None, "last noisy sample"),)
        self._noise = np.zeros(self.size)

    def update(self, t, x, z, u, p):
        self.rng.standard_normal(out=self._noise)
        _add_noise(z, u, p[0], self._noise)
