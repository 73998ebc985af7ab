"""Linear and signal-shaping blocks of flight software, compiled: state space, transfer function, second-order
filter, delay, saturation, rate limiter, dead zone.

Equations (the math and its sources are in :mod:`shell.linear`; these models step it in the compiled loop)::

    StateSpace, TransferFunction, Filter   continuous:  x' = A x + B u,  y = C x + D u
                                           sampled:     at t_k: x_k = x, u_k = u(t_k), x <- A x_k + B u_k;
                                                        y = C x_k + D u_k held on [t_k, t_k+1)
    Delay        (sampled, N samples)      y_k = u_(k-N), held
    Saturation                             y = min(max(u, lower), upper)                     (feedthrough)
    DeadZone                               y = u - upper above upper, u - lower below lower, 0 between
    RateLimiter  (sampled, period T)       y_k = y_(k-1) + min(max(u_k - y_(k-1), -falling_rate T), rising_rate T)

A sampled linear block is exactly the discrete system ``x[k+1] = A x[k] + B u[k], y[k] = C x[k] + D u[k]``
(python-control's ``dlsim``, MATLAB's ``lsim`` with ``dt``), its output held between samples, so its output
never feeds through within an instant and closes loops without algebraic loops. A continuous block feeds its
input through only when D is not zero.

Where the matrices come from (``config:``): ``StateSpace`` from a file (``file``: HDF5, .mat or .npz through
:func:`shell.linear.matrix_files.read_state_space`, with ``group``) or inline (``A``, ``B``, ``C``, ``D``:
lists of rows), or in Python ``system=`` a :class:`~shell.linear.system.LinearSystem` or a python-control
``StateSpace`` or ``TransferFunction`` (its ``dt``: 0 continuous, a number the sample time); a file with ``sample_time`` makes a sampled block at that period (``rate``/``period`` may
repeat it); inline matrices are sampled when ``rate`` or ``period`` is given. ``TransferFunction``:
``numerator``, ``denominator`` (highest power first; in s, or in z when sampled, as python-control's
``tf(num, den, dt)``), realized minimal and balanced. ``Filter``: ``kind`` low_pass, notch or bending with
its frequencies (Hz) and dampings; sampled, Tustin with prewarping per quadratic. ``TransferFunction`` and
``Filter`` act on every element of a port of ``shape`` (one copy per channel: block-diagonal A).

Array layouts. The matrices are parameters ``A``, ``B``, ``C``, ``D`` (row-major, one after the other, in
the ports' units: A at 0, B at n n, C at n (n + m), D at n (n + m) + p n) whose shapes the configuration
sets, so every offset after the first is derived in the kernels from the array sizes: n from the continuous
state (``x.shape[0]``) or, sampled, from the discrete state ``[x (n), x_k (n), u_k (m)]`` as ``(z.shape[0] -
m) / 2``; m from ``u.shape[0]``; p from ``y.shape[0]``. Kernels view the flat arrays as matrices
(``p[a:b].reshape(n, n)``: no copy) and call :mod:`shell.linear.kernels`. Delay's discrete state is ``[held
output (m), head (1), ring buffer (N m)]``, RateLimiter's ``[output (m), period (1)]``; Saturation's and
DeadZone's parameters ``[lower (m), upper (m)]``.
"""

from __future__ import annotations

import warnings
from dataclasses import replace

import numpy as np
from numba import njit

from shell.linear import kernels as K
from shell.linear.matrix_files import read_state_space
from shell.linear.realization import bending, low_pass, notch, transfer_function
from shell.linear.system import LinearSystem, LinearSystemError
from shell.model import (MAX_ELEMENTS, Declarations, InputPort, Model, ModelError, OutputPort, Parameter, State,
                         parse_period)
from shell.models.blocks import SignalBlock
from shell.registry import register_model
from shell.units import UnitError, to_magnitude

MATRICES = tuple(Parameter(key, "", None, (1, 1), None, f"{key} of the state-space system (the ports' units)")
                 for key in ("A", "B", "C", "D"))
#: continuous: x' = A x + B u, y = C x + D u
CONTINUOUS_SYSTEM = Declarations(parameters=MATRICES, inputs=(InputPort("u", "", (1,), "input"),),
                          outputs=(OutputPort("y", "", (1,), "output y = C x + D u"),),
                          continuous=(State("x", "", (1,), None, "state"),),
                          sized=("A", "B", "C", "D", "u", "y", "x"))
#: sampled: the state, and the state and input of the last sample (the held output is C x_k + D u_k)
SAMPLED_SYSTEM = Declarations(parameters=MATRICES, inputs=(InputPort("u", "", (1,), "input, sampled"),),
                       outputs=(OutputPort("y", "", (1,), "output y[k] = C x[k] + D u[k], held"),),
                       discrete=(State("x", "", (1,), None, "state x[k+1] (after the last sample)"),
                                 State("x_sampled", "", (1,), None, "state x[k] of the last sample"),
                                 State("u_sampled", "", (1,), None, "input u[k] of the last sample")),
                       sized=("A", "B", "C", "D", "u", "y", "x", "x_sampled", "u_sampled"))
DELAY = Declarations(inputs=(InputPort("u", "", (), "input, sampled"),),
                     outputs=(OutputPort("y", "", (), "the input of N samples ago, held"),),
                     discrete=(State("y", "", (), None, "held output"),
                               State("head", "", (), 0.0, "ring-buffer row of the oldest sample"),
                               State("buffer", "", (1,), None, "the last N samples, oldest at head")),
                     sized=("u", "y", "buffer"))
LIMITS = (Parameter("lower", "", None, (), description="lower limit"),
          Parameter("upper", "", None, (), description="upper limit"))
SATURATION = Declarations(parameters=LIMITS, inputs=(InputPort("u", "", (), "input", feedthrough=True),),
                          outputs=(OutputPort("y", "", (), "min(max(u, lower), upper)", feedthrough=True),),
                          sized=("lower", "u", "y"))
DEAD_ZONE = Declarations(parameters=LIMITS, inputs=(InputPort("u", "", (), "input", feedthrough=True),),
                         outputs=(OutputPort("y", "", (), "u - upper above upper, u - lower below lower, 0 "
                                                          "between", feedthrough=True),),
                         sized=("lower", "u", "y"))
RATE_LIMITER = Declarations(
    parameters=(Parameter("rising_rate", "", None, (), (0.0, None), "largest rate of increase"),
                Parameter("falling_rate", "", None, (), (0.0, None), "largest rate of decrease (positive)")),
    inputs=(InputPort("u", "", (), "input, sampled"),),
    outputs=(OutputPort("y", "", (), "rate-limited output, held"),),
    discrete=(State("y", "", (), None, "output"), State("period", "s", (), None, "sample period (from the rate)")),
    sized=("rising_rate", "u", "y"))
P_SS, U_SS, Y_SS, Z_SS = CONTINUOUS_SYSTEM.P, CONTINUOUS_SYSTEM.U, CONTINUOUS_SYSTEM.Y, SAMPLED_SYSTEM.Z
U_DELAY, Y_DELAY, Z_DELAY = DELAY.U, DELAY.Y, DELAY.Z
P_LIMITS, U_LIMITS, Y_LIMITS = SATURATION.P, SATURATION.U, SATURATION.Y
P_RATE, U_RATE, Y_RATE, Z_RATE = RATE_LIMITER.P, RATE_LIMITER.U, RATE_LIMITER.Y, RATE_LIMITER.Z


@njit(cache=True)
def _continuous_derivative(t, x, z, u, p, xdot):
    n, m = xdot.shape[0], u.shape[0]
    b = P_SS.A + n * n
    K.state_space_derivative(p[P_SS.A:b].reshape(n, n), p[b:b + n * m].reshape(n, m), x, u[U_SS.u:U_SS.u + m],
                             xdot)


@njit(cache=True)
def _output(p, n, m, x, u, y):
    """y = C x + D u from the flat matrices (n states, m inputs, y.shape[0] outputs)."""
    q = y.shape[0]
    c = P_SS.A + n * (n + m)
    d = c + q * n
    K.state_space_output(p[c:d].reshape(q, n), p[d:d + q * m].reshape(q, m), x, u, y)


@njit(cache=True)
def _continuous_output(t, x, z, u, p, y):
    _output(p, x.shape[0], u.shape[0], x, u[U_SS.u:], y[Y_SS.y:])


@njit(cache=True)
def _continuous_state_output(t, x, z, u, p, y):
    """y = C x when D = 0 (reads no input)."""
    n, m, q = x.shape[0], u.shape[0], y.shape[0]
    c = P_SS.A + n * (n + m)
    for i in range(q):
        acc = 0.0
        for j in range(n):
            acc += p[c + i * n + j] * x[j]
        y[Y_SS.y + i] = acc


@njit(cache=True)
def _sampled_update(t, x, z, u, p):
    m = u.shape[0]
    n = (z.shape[0] - m) // 2
    b = P_SS.A + n * n
    for j in range(n):
        z[Z_SS.x + n + j] = z[Z_SS.x + j]
    for j in range(m):
        z[Z_SS.x + 2 * n + j] = u[U_SS.u + j]
    K.state_space_derivative(p[P_SS.A:b].reshape(n, n), p[b:b + n * m].reshape(n, m), z[n:2 * n], z[2 * n:],
                             z[Z_SS.x:n])


@njit(cache=True)
def _sampled_output(t, x, z, u, p, y):
    m = u.shape[0]
    n = (z.shape[0] - m) // 2
    _output(p, n, m, z[n:2 * n], z[2 * n:], y[Y_SS.y:])


@njit(cache=True)
def _delay_update(t, x, z, u, p):
    m = u.shape[0]
    buffer = z[m + 1:]
    depth = buffer.shape[0] // m if m else 0
    head = K.delay_line_update(buffer.reshape(depth, m), int(z[m]), u[U_DELAY.u:U_DELAY.u + m],
                               z[Z_DELAY.y:Z_DELAY.y + m])
    z[m] = head


@njit(cache=True)
def _held(t, x, z, u, p, y):
    for i in range(y.shape[0]):
        y[Y_DELAY.y + i] = z[Z_DELAY.y + i]


@njit(cache=True)
def _saturation(t, x, z, u, p, y):
    m = y.shape[0]
    K.saturation(u[U_LIMITS.u:U_LIMITS.u + m], p[P_LIMITS.lower:m], p[m:2 * m], y[Y_LIMITS.y:Y_LIMITS.y + m])


@njit(cache=True)
def _dead_zone(t, x, z, u, p, y):
    m = y.shape[0]
    K.dead_zone(u[U_LIMITS.u:U_LIMITS.u + m], p[P_LIMITS.lower:m], p[m:2 * m], y[Y_LIMITS.y:Y_LIMITS.y + m])


@njit(cache=True)
def _rate_limiter_update(t, x, z, u, p):
    m = u.shape[0]
    period = z[m]
    for j in range(m):
        z[Z_RATE.y + j] = K.rate_limited(z[Z_RATE.y + j], u[U_RATE.u + j], p[m + j] * period,
                                         p[P_RATE.rising_rate + j] * period)


def _port_shape(name: str, shape) -> tuple:
    try:
        dims = (int(shape),) if isinstance(shape, (int, np.integer)) else tuple(int(n) for n in shape)
    except (TypeError, ValueError):
        raise ModelError(f"model {name}: config shape: expected a list of whole numbers, given {shape!r}") from None
    if any(n < 1 for n in dims) or np.prod(dims, dtype=float) > MAX_ELEMENTS:
        raise ModelError(f"model {name}: config shape: expected whole numbers >= 1, given {list(dims)}")
    return dims


def _per_channel(system: LinearSystem, channels: int) -> LinearSystem:
    """``channels`` copies of a single-input single-output system side by side (block-diagonal)."""
    if channels == 1:
        return system
    eye = np.eye(channels)
    return LinearSystem(np.kron(eye, system.A), np.kron(eye, system.B), np.kron(eye, system.C),
                        np.kron(eye, system.D), system.sample_time, where=system.where)


class _LinearBlock(Model):
    """A linear block: ``self.system`` (continuous, or sampled at the block's period) stepped by the kernels of
    the module. Subclasses make the system, then call this constructor."""

    def __init__(self, name: str, system: LinearSystem, *, input_unit: str = "", output_unit: str = "",
                 input_shape=None, output_shape=None, require_stable: bool = False, state_unit: str = "",
                 period=None, **kwargs):
        if system.discrete:
            given = None if period is None else float(parse_period(period, f"model {name}: period"))
            if given is not None and abs(given - system.sample_time) > 1e-12 * system.sample_time:
                raise ModelError(f"model {name}: period: {given:g} s differs from the sample time "
                                 f"{system.sample_time:g} s of {system.where}")
            period = system.sample_time if period is None else period
        if not isinstance(require_stable, bool):
            raise ModelError(f"model {name}: config require_stable: expected true or false, given {require_stable!r}")
        if require_stable:
            try:
                system.require_stable(f"block {name} (config require_stable: true)")
            except LinearSystemError as exc:
                raise ModelError(f"model {name}: config require_stable: {exc}") from None
        elif not system.is_stable():
            poles = system.poles()
            worst = poles[np.argmax(np.abs(poles) if system.discrete else poles.real)]
            warnings.warn(f"model {name}: {system.where} is not asymptotically stable (pole {worst:.6g}); allowed "
                          "(config require_stable: true refuses it)", stacklevel=3)
        self.system = system
        n, m, q = system.shape
        self._ports = {"u": {"unit": input_unit, "shape": (m,) if input_shape is None else input_shape},
                       "y": {"unit": output_unit, "shape": (q,) if output_shape is None else output_shape}}
        self._state = {"unit": state_unit, "shape": (n,)}
        if system.discrete:
            self.update, self.state_outputs = _sampled_update, _sampled_output
        else:
            self.derivatives = _continuous_derivative if n else None
            if np.any(system.D):
                self.feedthrough_outputs = _continuous_output
            else:
                self.state_outputs = _continuous_state_output
        super().__init__(name, period=period, **kwargs)

    def declare(self):
        system, ports = self.system, self._ports
        matrices = {key: {"default": getattr(system, key), "shape": getattr(system, key).shape}
                    for key in ("A", "B", "C", "D")}
        if system.discrete:
            template = SAMPLED_SYSTEM
            states = {"x": self._state, "x_sampled": self._state, "u_sampled": ports["u"]}
        else:
            feedthrough = {"feedthrough": bool(np.any(system.D))}
            template = CONTINUOUS_SYSTEM
            states = {"x": self._state}
            ports = {"u": ports["u"] | feedthrough, "y": ports["y"] | feedthrough}
        self.use_declarations(template.replace(**matrices, **ports, **states))
        self.offsets = template.offsets

    def configure(self):
        for key in ("A", "B", "C", "D"):  # the kernels and the feedthrough were chosen for these matrices
            if not np.array_equal(self.parameter(key), getattr(self.system, key)):
                raise ModelError(f"model {self.path}: parameter {key}: set by the block's configuration "
                                 f"({type(self).__name__}: its file, inline matrices or design), not a parameter to "
                                 "give")


def _located(name: str, key: str, exc: LinearSystemError, where: str | None = None) -> ModelError:
    """A refusal of the matrices as a ModelError naming the config key (``where``: the prefix of the message
    to drop when the key is in it)."""
    text = str(exc)
    if where and text.startswith(where + ": "):
        text = text[len(where) + 2:]
        key = text.split(":", 1)[0]
        text = text.split(": ", 1)[1] if ": " in text else text
    return ModelError(f"model {name}: config {key}: {text}")


@register_model
class StateSpace(_LinearBlock):
    """x' = A x + B u (or x[k+1] = A x[k] + B u[k], sampled), y = C x + D u; matrices from a file or inline."""

    summary = ("state-space system, continuous or sampled (config: file [group] or A, B, C, D; input_unit, "
               "output_unit, require_stable)")
    example_config = {"A": [[-1.0]], "B": [[1.0]], "C": [[1.0]], "D": [[0.0]]}

    def __init__(self, name: str, *, file: str | None = None, group: str | None = None, A=None, B=None, C=None,
                 D=None, system=None, period=None, **kwargs):
        inline = {key: value for key, value in zip("ABCD", (A, B, C, D)) if value is not None}
        sources = [what for what, given in (("file", file is not None), ("A, B, C, D", inline),
                                            ("system", system is not None)) if given]
        if len(sources) > 1:
            raise ModelError(f"model {name}: config: give the matrices one way: a file (file: ...), inline (A, B, C, "
                             f"D) or, in Python, system=; given {' and '.join(sources)}")
        if system is not None:
            system = _python_system(name, system, period)
        elif file is not None:
            try:
                system = read_state_space(file, group)
            except LinearSystemError as exc:
                raise _located(name, "file", exc) from None
            if period is not None and not system.discrete:
                raise ModelError(f"model {name}: period: {file} holds a continuous system (no sample_time); "
                                 "remove rate:/period: or give a sampled system")
        else:
            missing = [key for key in "ABCD" if key not in inline]
            if missing:
                raise ModelError(f"model {name}: config: no {', '.join(missing)}; expected file: (HDF5, .mat, "
                                 ".npz) or the matrices A, B, C, D inline (lists of rows)")
            where = f"model {name}"
            try:
                sample_time = None if period is None else float(parse_period(period, f"model {name}: period"))
                system = LinearSystem(*(_matrix(name, key, inline[key]) for key in "ABCD"), sample_time,
                                      where=where)
            except LinearSystemError as exc:
                raise _located(name, "A", exc, where) from None
        super().__init__(name, system, period=period, **kwargs)


def _python_system(name: str, system, period) -> LinearSystem:
    """A :class:`LinearSystem`, or python-control's ``StateSpace`` or ``TransferFunction`` (``dt`` 0: continuous;
    a number: its sample time; True, a sampled system of unspecified period: the block's ``period``)."""
    if isinstance(system, LinearSystem):
        return system
    if not hasattr(system, "A") and hasattr(system, "num"):  # a python-control TransferFunction
        import control

        system = control.ss(system)
    if not all(hasattr(system, key) for key in "ABCD"):
        raise ModelError(f"model {name}: system: expected a LinearSystem or a python-control StateSpace or "
                         f"TransferFunction, given {type(system).__name__}")
    dt = getattr(system, "dt", 0)
    if dt is True:
        if period is None:
            raise ModelError(f"model {name}: system: sampled with an unspecified period (dt=True); give period=")
        sample_time = float(parse_period(period, f"model {name}: period"))
    else:
        sample_time = float(dt) if dt else None
    where = f"model {name}"
    try:
        return LinearSystem(*(np.asarray(getattr(system, key), dtype=float) for key in "ABCD"), sample_time,
                            where=where)
    except LinearSystemError as exc:
        raise _located(name, "A", exc, where) from None


def _matrix(name: str, key: str, value) -> np.ndarray:
    """An inline matrix: a list of rows (a number or a flat list is refused: which shape was meant?)."""
    try:
        matrix = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise ModelError(f"model {name}: config {key}: expected a matrix as a list of rows of numbers, "
                         f"given {value!r}") from None
    if matrix.ndim != 2:
        raise ModelError(f"model {name}: config {key}: expected a matrix as a list of rows (e.g. [[1, 0]]), given "
                         f"{value!r}")
    return matrix


@register_model
class TransferFunction(_LinearBlock):
    """y = num / den u per channel (in s, or in z when sampled), minimal realization."""

    summary = ("transfer function num/den per element (config: numerator, denominator: in s, or in z with "
               "rate:; shape, input_unit, output_unit)")
    example_config = {"numerator": [1.0], "denominator": [1.0, 1.0]}

    def __init__(self, name: str, *, numerator=None, denominator=None, shape=(), period=None, **kwargs):
        if numerator is None or denominator is None:
            raise ModelError(f"model {name}: config: expected numerator and denominator (coefficients, highest "
                             "power first)")
        where = f"model {name}"
        try:
            sample_time = None if period is None else float(parse_period(period, f"model {name}: period"))
            siso = transfer_function(numerator, denominator, sample_time, where=where)
        except LinearSystemError as exc:
            raise _located(name, "numerator", exc, where) from None
        dims = _port_shape(name, shape)
        system = _per_channel(siso, int(np.prod(dims)))
        super().__init__(name, system, input_shape=dims, output_shape=dims, period=period, **kwargs)


@register_model
class Filter(_LinearBlock):
    """Second-order low-pass, notch or bending filter per channel; sampled: Tustin with prewarping."""

    summary = ("second-order filter per element (config: kind low_pass|notch|bending, frequency, damping, "
               "notch_gain | numerator_/denominator_frequency, _damping; shape, unit); sampled with rate: (Tustin, "
               "prewarped)")
    example_config = {"kind": "notch", "frequency": "2 Hz", "damping": 0.5, "notch_gain": 0.1}

    def __init__(self, name: str, *, kind: str | None = None, frequency=None, damping=None, notch_gain=None,
                 numerator_frequency=None, numerator_damping=None, denominator_frequency=None,
                 denominator_damping=None, shape=(), unit: str = "", period=None, **kwargs):
        given = {"frequency": frequency, "damping": damping, "notch_gain": notch_gain,
                 "numerator_frequency": numerator_frequency, "numerator_damping": numerator_damping,
                 "denominator_frequency": denominator_frequency, "denominator_damping": denominator_damping}
        needs = {"low_pass": ("frequency", "damping"), "notch": ("frequency", "damping", "notch_gain"),
                 "bending": ("numerator_frequency", "numerator_damping", "denominator_frequency",
                             "denominator_damping")}
        if kind not in needs:
            raise ModelError(f"model {name}: config kind: expected one of {', '.join(needs)}, given {kind!r}")
        missing = [key for key in needs[kind] if given[key] is None]
        extra = [key for key, value in given.items() if value is not None and key not in needs[kind]]
        if missing or extra:
            raise ModelError(f"model {name}: config: a {kind} filter takes {', '.join(needs[kind])}"
                             + (f"; missing {', '.join(missing)}" if missing else "")
                             + (f"; not used: {', '.join(extra)}" if extra else ""))
        values = {}
        for key in needs[kind]:
            try:
                values[key] = float(to_magnitude(given[key], "Hz" if key.endswith("frequency") else "", (),
                                                 f"model {name}: config {key}"))
            except UnitError as exc:
                raise ModelError(str(exc)) from None
        where = f"model {name}"
        try:
            design = {"low_pass": low_pass, "notch": notch, "bending": bending}[kind](*values.values(), where=where)
            sample_time = None if period is None else float(parse_period(period, f"model {name}: period"))
            siso = design.continuous() if sample_time is None else design.tustin(sample_time)
        except LinearSystemError as exc:
            text = str(exc)[len(where) + 2:]
            named = [key for key in needs[kind] if key.replace("_", " ") in text]
            raise ModelError(f"model {name}: config {named[-1] if named else 'kind'}: {text}") from None
        self.design = design
        dims = _port_shape(name, shape)
        system = _per_channel(siso, int(np.prod(dims)))
        super().__init__(name, system, input_unit=unit, output_unit=unit, input_shape=dims, output_shape=dims,
                         state_unit=unit, period=period, **kwargs)


@register_model
class Delay(SignalBlock):
    """y[k] = u[k - N]: a delay of N samples at the block's period, held (N = 0: a sample and hold)."""

    summary = "delay of N samples (config: samples, unit, shape; rate: or period:)"
    declarations = DELAY
    state_outputs = staticmethod(_held)
    update = staticmethod(_delay_update)
    example_config = {"samples": 2, "period": "0.1 s"}

    def __init__(self, name: str, *, samples=None, **kwargs):
        if isinstance(samples, bool) or not isinstance(samples, (int, np.integer)) or not 0 <= samples <= 10**6:
            raise ModelError(f"model {name}: config samples: expected a whole number of samples from 0 to 1e6, "
                             f"given {samples!r}")
        self.samples = int(samples)
        super().__init__(name, **kwargs)

    def declare(self):
        rows = (self.samples,) + self.shape
        self.use_declarations(DELAY.replace(u=self.port, y=self.port,
                                            buffer={"unit": self.unit, "shape": rows}))

    def sampled_coordinates(self, z):
        """Positions in the discrete state ``z`` of its time-invariant coordinates (the sampled closed-loop model,
        :mod:`shell.analysis.sampled_loop`): the held output, then the buffer's samples oldest first; the head
        (the ring buffer's row pointer, not a signal) left out."""
        m = self.size
        head = int(z[m])
        rows = [(head + r) % self.samples for r in range(self.samples)]
        return np.concatenate([np.arange(m)] + [m + 1 + row * m + np.arange(m) for row in rows]).astype(np.int64)


class _Limits(SignalBlock):
    """Lower and upper limits in the port unit, per element; lower <= upper."""

    example_config = {"lower": -1.0, "upper": 1.0}

    def declare(self):
        self.use_declarations(self.declarations.replace(lower=self.port, upper=self.port, u=self.port, y=self.port))

    def configure(self):
        lower, upper = self.parameter("lower"), self.parameter("upper")
        if np.any(lower > upper):
            raise ModelError(f"model {self.path}: parameter lower: expected lower <= upper, given lower "
                             f"{lower.tolist()} and upper {upper.tolist()} {self.unit}")


@register_model
class Saturation(_Limits):
    """y = min(max(u, lower), upper), element by element."""

    summary = "saturation y = min(max(u, lower), upper) (direct feedthrough; config: unit, shape)"
    declarations = SATURATION
    feedthrough_outputs = staticmethod(_saturation)


@register_model
class DeadZone(_Limits):
    """y = u - upper above upper, u - lower below lower, 0 between."""

    summary = "dead zone: 0 between lower and upper, u - limit outside (direct feedthrough; config: unit, shape)"
    declarations = DEAD_ZONE
    feedthrough_outputs = staticmethod(_dead_zone)


@register_model
class RateLimiter(SignalBlock):
    """Sampled: the output moves toward the input by at most rising_rate T up, falling_rate T down, per sample."""

    summary = "sampled rate limiter (parameters rising_rate, falling_rate in unit/s; config: unit, shape)"
    declarations = RATE_LIMITER
    state_outputs = staticmethod(_held)
    update = staticmethod(_rate_limiter_update)
    example_config = {"rising_rate": 1.0, "falling_rate": 1.0, "period": "0.1 s"}

    def __init__(self, name: str, *, period=None, **kwargs):
        self._given_period = period
        super().__init__(name, period=period, **kwargs)

    def declare(self):
        rate = {"unit": f"({self.unit or '1'})/s", "shape": self.shape}
        self.use_declarations(RATE_LIMITER.replace(rising_rate=rate, falling_rate=rate, u=self.port, y=self.port))

    def configure(self):
        for key in ("rising_rate", "falling_rate"):
            if np.any(self.parameter(key) <= 0.0):
                raise ModelError(f"model {self.path}: parameter {key}: expected a rate > 0, given "
                                 f"{self.parameter(key).tolist()} ({self.unit or '1'})/s")
        if self._given_period is None:
            raise ModelError(f"model {self.path}: RateLimiter is sampled; give its period (e.g. period: 0.1 s or "
                             "rate: 10 Hz)")
        period = float(parse_period(self._given_period, f"model {self.path}: period"))
        self.discrete_states = tuple(replace(s, initial=period) if s.name == "period" else s
                                     for s in self.discrete_states)

    def sampled_coordinates(self, z):
        """Positions in ``z`` of its coordinates in the sampled closed-loop model (:mod:`shell.analysis.sampled_loop`):
        the output; the stored period (a constant, not a signal: it would be a unit eigenvalue) left out."""
        return np.arange(self.size, dtype=np.int64)
