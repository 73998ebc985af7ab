"""Component models: declarations of parameters, ports, states, rate and zero crossings.

A :class:`Model` is the Dshell/Drake "leaf system" of flexshell (TM-2020-5008164 App. D.1;
Drake ``LeafSystem``): it *declares* what it has, once, and holds its parameter values (converted to
the declared units at construction). It never holds state: continuous states, discrete states and
signals live in the :class:`shell.simulation.Simulation`'s flat float64 buffers, and the model's
math is written as kernels with one uniform signature over views into those buffers::

    kernel(t, x, z, u, p, out)

``x`` continuous states, ``z`` discrete states, ``u`` all input ports (concatenated in declaration
order, each flattened), ``p`` all parameters (concatenated, flattened, in declared units), ``out`` the
array the kernel fills. The kernels a model may provide:

``state_outputs(t, x, z, u, p, y)``         outputs not marked ``feedthrough`` (must not read ``u``)
``feedthrough_outputs(t, x, z, u, p, y)``   outputs marked ``feedthrough`` (may read feedthrough inputs)
``derivatives(t, x, z, u, p, xdot)``        continuous-state derivatives
``update(t, x, z, u, p)``                   periodic discrete update, in place on ``z``
``update(t, x, z, u, p, noise)``            the same for a model with ``noise_size > 0``: ``noise`` holds
                                            ``noise_size`` fresh standard normals from the model's
                                            random stream (drawn by the framework before each call)
``zero_crossing_values(t, x, z, u, p, g)``  zero-crossing functions (one per declared ZeroCrossing)

Kernels are normally ``numba.njit(cache=True)`` functions set as ``staticmethod`` class attributes,
so the simulation can call them without Python-level indirection and fuse them into one compiled
loop. Output kernels write the whole output block; the ones not written by ``state_outputs`` are
written by ``feedthrough_outputs``.

Kernels read their arrays by name, never by hand-counted position. A model's declarations are written
once, at module level, as one :class:`Declarations`; it yields the named tuples of start offsets the kernels
read (``P``, ``U``, ``Y``, ``X``, ``Z`` for parameters, inputs, outputs, continuous and discrete states: ``p[P.kp
+ i]`` in a kernel, folded to a constant by numba) and, set as the class attribute ``declarations``, the
model's ``parameters``, ``inputs``, ``outputs``, ``continuous_states``, ``discrete_states``, ``zero_crossings``
and ``offsets``::

    PD = Declarations(parameters=(Parameter("kp", "N*m/rad", 1.0, (3,)), ...), inputs=MEASURED_ATTITUDE_AND_RATE,
                      outputs=(OutputPort("torque", "N*m", (3,)),), discrete=(State("torque", "N*m", (3,)),))
    P, U, Y, Z = PD.P, PD.U, PD.Y, PD.Z

    class PdAttitudeController(Model):
        declarations = PD

Define it in the same module as the kernels that use its offsets: numba's on-disk cache is invalidated when
that file changes, so reordering a declaration recompiles the kernels with the new offsets. Ports that many
models share (a node's attitude and rate in, a torque out) are declared once in :mod:`shell.ports`, and every
quaternion, rotation-vector and MRP formula is in :mod:`shell.attitude`.

Writing a model's kernels (the conventions every built-in model follows):

* Construction checks the kernels' offsets (the class attribute ``offsets``) against the instance's actual
  declarations (:func:`check_named_offsets`): a subclass, or a ``configure``, that reorders, renames, adds or
  resizes a declaration without new kernels is refused with the model, the declaration and both offsets. A
  declaration's initial value that depends on configuration is set with ``dataclasses.replace`` on the
  module-level declaration, which keeps the layout.
* Declarations whose shapes depend on configuration (n wheels, a gain file's K, a block's port shape) cannot
  have compile-time offsets: list them in ``Declarations(..., sized=(...))``. Their own offsets stay constants
  while the ones after them in the same array are ``None``, derived by the kernel from array sizes
  (``y.shape[0]``, ``u.shape[0]``; the module says how); the check still refuses any change of the names or
  their order. The instance's declarations of one configuration are ``declare()``'s
  ``self.use_declarations(TEMPLATE.replace(name={"shape": ..., "unit": ...}))``.
* ``configure`` reads parameters with ``self.parameter(name)``: the parameters it reads are recorded
  (``configured_parameters``), and a run that changes one builds the model again from its constructor's
  arguments; every other parameter may change in a run's Context alone (:mod:`shell.names`).
* Kernels allocate nothing: scratch goes in the model's discrete states or in scalars.
* A sampled model that needs Gaussian noise sets ``noise_size``; the framework fills the update
  kernel's ``noise`` argument from the model's random stream before each call.
* ``python_update = True`` marks a model whose ``update`` must stay Python (user code, a scipy linear
  program, a call into the engine's Python API); its docstring says why. A compiled simulation loop
  returns to Python at each of that model's sample instants, which costs one interpreter round trip
  (microseconds) per sample; every other kernel must be ``numba.njit(cache=True)``.
* ``update_reads_inputs = False`` marks a sampled model whose ``update`` reads none of its inputs (only its own
  states and parameters): its samples then evaluate no output stage for it (the IMU's, whose inputs need the
  engine's forward dynamics: one solve per sample saved). A test gives such an update non-finite inputs.
* ``state_outputs_for_derivatives`` / ``feedthrough_outputs_for_derivatives`` (optional, same signatures): the
  output kernels a *derivative evaluation* (the integrator's right-hand side, where only the derivatives are read)
  calls instead of ``state_outputs`` / ``feedthrough_outputs``. They may leave out, as NaN, the outputs that no
  derivative reads (:meth:`Model.output_read` says which are: ``in_derivatives``), which samples, logs and names
  then get from the ordinary kernels (the engine's nodes that only a sampled controller or a log reads).
"""

from __future__ import annotations

import hashlib
from collections import namedtuple
from dataclasses import dataclass, field, fields, replace
from fractions import Fraction

import numpy as np

from shell.units import UnitError, format_unit, parse_unit, to_magnitude, ureg


def named_offsets(declarations, name: str = "Offsets", sized=()):
    """Start offset of each declaration in the flat array that packs them in declaration order, as a
    named tuple (``named_offsets((Parameter("kp", shape=(3,)), Parameter("kd", shape=(3,)))).kd == 3``).

    Works for parameters, ports and states alike; the names must be Python identifiers. After a declaration
    named in ``sized`` (its size a configuration), the offsets are ``None``: the kernel derives them."""
    names, offsets, offset = [], [], 0
    for d in declarations:
        names.append(d.name)
        offsets.append(offset)
        if offset is not None:
            offset = None if d.name in sized else offset + _size(_shape(d.shape))
    return namedtuple(name, names)(*offsets)


class ModelError(ValueError):
    """A model declaration or configuration a user must fix; the message names the model path."""


_DECLARATION_KINDS = {"p": "parameters", "u": "inputs", "y": "outputs", "x": "continuous_states",
                      "z": "discrete_states"}


def check_named_offsets(model) -> None:
    """Refuse a model whose kernels' named offsets (class attribute ``offsets``: array letter ->
    named tuple from :func:`named_offsets`, ``None`` for an offset the kernel derives from array
    sizes) disagree with its actual declarations: other names, another order or other offsets."""
    where = f"model {model.path}: {type(model).__name__}"
    advice = ("a subclass or configure that changes a declaration tuple needs kernels written for the new "
              "layout (their own named_offsets)")
    for key, expected in model.offsets.items():
        if key not in _DECLARATION_KINDS:
            raise ModelError(f"{where}: offsets key {key!r}: expected one of {sorted(_DECLARATION_KINDS)}")
        kind = _DECLARATION_KINDS[key]
        actual = Layout.of(getattr(model, kind))
        compiled = list(getattr(expected, "_fields", ()))
        missing, extra = sorted(set(compiled) - set(actual.names)), sorted(set(actual.names) - set(compiled))
        if missing or extra:
            raise ModelError(f"{where}: {kind} {actual.names} differ from the {compiled} its kernels read "
                             f"(not declared: {missing}, not read: {extra}); {advice}")
        for name, offset in zip(compiled, expected):
            if offset is not None and offset != actual.offsets[name]:
                raise ModelError(f"{where}: {kind[:-1].replace('_', ' ')} {name!r} is at offset "
                                 f"{actual.offsets[name]} of the declarations but its kernels read it at offset "
                                 f"{offset}; {advice}")
        if compiled != actual.names:
            raise ModelError(f"{where}: {kind} are declared in the order {actual.names} but its kernels derive "
                             f"their offsets from the order {compiled}; {advice}")


#: most elements of one declaration (parameter, port, state): 80 MB of float64; a larger one is a slip (a size
#: of 3e9 for 3), refused before any allocation
MAX_ELEMENTS = 10**7
#: most members of a count that makes ports or objects (actuators, sensors, inputs, plates): far above any
#: scene's, far below what takes minutes to build (3,000,000 actuators did)
MAX_COUNT = 10_000


def count_option(model: str, key: str, value, what: str, maximum: int = MAX_COUNT) -> int:
    """A config count: a whole number from 1 to ``maximum`` (not 2.5 read as 2, not 3e6)."""
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or not 1 <= value <= maximum:
        raise ModelError(f"model {model}: config {key}: expected a whole number of {what} from 1 to {maximum}, "
                         f"given {value!r}")
    return int(value)


def _shape(shape) -> tuple[int, ...]:
    dims = (shape,) if isinstance(shape, (int, np.integer)) else tuple(shape)
    if not all(isinstance(n, (int, np.integer)) and not isinstance(n, bool) and n >= 0 for n in dims):
        raise ModelError(f"a shape is a list of whole numbers >= 0, given {list(dims)!r}")
    if np.prod([float(n) for n in dims]) > MAX_ELEMENTS:
        raise ModelError(f"shape {list(dims)}: more than {MAX_ELEMENTS:.0e} elements")
    return tuple(int(n) for n in dims)


def _size(shape: tuple[int, ...]) -> int:
    return int(np.prod(shape, dtype=np.int64)) if shape else 1


class _Shaped:
    """Shape normalization (an int or any sequence -> a tuple of ints) and element count of the
    declarations below (parameters, ports, states)."""

    def __post_init__(self):
        object.__setattr__(self, "shape", _shape(self.shape))

    @property
    def size(self) -> int:
        return _size(self.shape)


@dataclass(frozen=True)
class Parameter(_Shaped):
    """A model parameter: value converted to ``unit`` at construction, checked against ``bounds``."""

    name: str
    unit: str = ""
    default: object = None
    shape: tuple = ()
    bounds: tuple | None = None  # (low, high) in ``unit``, either may be None
    description: str = ""


@dataclass(frozen=True)
class InputPort(_Shaped):
    """An input signal. ``feedthrough``: the model's feedthrough outputs read it at the same instant.

    An input that is not ``required`` takes ``default`` (in ``unit``; zeros if None) when unconnected.
    """

    name: str
    unit: str = ""
    shape: tuple = ()
    description: str = ""
    feedthrough: bool = False
    required: bool = True
    default: object = None


@dataclass(frozen=True)
class OutputPort(_Shaped):
    """An output signal; ``feedthrough`` outputs are computed by ``feedthrough_outputs``."""

    name: str
    unit: str = ""
    shape: tuple = ()
    description: str = ""
    feedthrough: bool = False


@dataclass(frozen=True)
class State(_Shaped):
    """A continuous or discrete state with its initial value (in ``unit``)."""

    name: str
    unit: str = ""
    shape: tuple = ()
    initial: object = None
    description: str = ""


@dataclass(frozen=True)
class ZeroCrossing:
    """A zero-crossing function g(t, x, z, u) of a model.

    ``direction``: +1 only rising crossings count, -1 only falling, 0 both. ``terminal``: the run
    stops at the crossing (after the model's ``on_event`` handler ran). A scenario may make any
    crossing terminal (``stop: events:``).
    """

    name: str
    direction: int = 0
    terminal: bool = False
    description: str = ""


#: the class attribute of each declaration tuple, by the argument name of :class:`Declarations`
_DECLARED = {"parameters": "parameters", "inputs": "inputs", "outputs": "outputs", "continuous": "continuous_states",
             "discrete": "discrete_states", "zero_crossings": "zero_crossings"}


class Declarations:
    """A model's declarations, written once: parameters, input and output ports, continuous and discrete
    states, zero crossings; and the named offsets its kernels read (``P``, ``U``, ``Y``, ``X``, ``Z``).

    ``sized``: names of declarations whose shape is set per instance (the module docstring); offsets after
    them in the same array are ``None``. A model class sets ``declarations = <this>``; a model whose shapes
    depend on its configuration builds its instance's declarations with :meth:`replace` in ``declare()``.
    """

    def __init__(self, *, parameters=(), inputs=(), outputs=(), continuous=(), discrete=(), zero_crossings=(),
                 sized=()):
        self.parameters, self.inputs, self.outputs = tuple(parameters), tuple(inputs), tuple(outputs)
        self.continuous, self.discrete = tuple(continuous), tuple(discrete)
        self.zero_crossings = tuple(zero_crossings)
        self.sized = frozenset(sized)
        arrays = {"p": self.parameters, "u": self.inputs, "y": self.outputs, "x": self.continuous, "z": self.discrete}
        unknown = sorted(self.sized - {d.name for array in arrays.values() for d in array})
        if unknown:
            raise ModelError(f"Declarations: sized names {unknown} are not declared")
        kinds = {"p": "Parameters", "u": "Inputs", "y": "Outputs", "x": "ContinuousStates", "z": "DiscreteStates"}
        #: array letter -> named offsets of its declarations (the class attribute ``offsets`` of a model)
        self.offsets = {key: named_offsets(array, kinds[key], self.sized) for key, array in arrays.items()}
        self.P, self.U, self.Y, self.X, self.Z = (self.offsets[key] for key in "puyxz")

    def class_attributes(self) -> dict:
        """The model class attributes these declarations stand for."""
        return {attribute: getattr(self, name) for name, attribute in _DECLARED.items()} | {"offsets": self.offsets}

    def replace(self, **changes) -> "Declarations":
        """The same declarations (names and order) with fields changed per declaration name, e.g.
        ``replace(u={"unit": "rad/s", "shape": (3,)})``; a name declared in several arrays (an output and the
        state that holds it) changes in each, with the fields its kind has (``default`` of a parameter,
        ``initial`` of a state)."""
        unknown = sorted(set(changes) - {d.name for name in _DECLARED for d in getattr(self, name)})
        if unknown:
            raise ModelError(f"Declarations.replace: no declarations named {unknown}")

        def changed(declaration):
            wanted = changes.get(declaration.name)
            if not wanted:
                return declaration
            own = {f.name for f in fields(declaration)}
            return replace(declaration, **{k: v for k, v in wanted.items() if k in own})

        for name, wanted in changes.items():
            kinds = [d for array in _DECLARED for d in getattr(self, array) if d.name == name]
            ignored = set(wanted) - {f.name for d in kinds for f in fields(d)}
            if ignored:
                raise ModelError(f"Declarations.replace: {name} has no field(s) {sorted(ignored)}")
        return Declarations(**{name: tuple(changed(d) for d in getattr(self, name)) for name in _DECLARED},
                            sized=self.sized)


@dataclass
class Layout:
    """Offsets of named blocks inside one flat array (parameters, ports or states of a model)."""

    names: list[str] = field(default_factory=list)
    offsets: dict[str, int] = field(default_factory=dict)
    shapes: dict[str, tuple] = field(default_factory=dict)
    size: int = 0

    @classmethod
    def of(cls, declarations) -> "Layout":
        layout = cls()
        for d in declarations:
            layout.names.append(d.name)
            layout.offsets[d.name] = layout.size
            layout.shapes[d.name] = d.shape
            layout.size += d.size
        return layout

    def slice(self, name: str) -> slice:
        start = self.offsets[name]
        return slice(start, start + _size(self.shapes[name]))


def parse_period(value, where: str) -> Fraction:
    """Sample period as an exact fraction of a second, from "10 Hz", "0.1 s", 0.1 or a Fraction.

    Sample instants are ``offset + k * period`` computed from these fractions, so rates like 1, 10
    and 100 Hz coincide exactly at shared instants (0.3 s from 3 x 0.1 s and from 30 x 0.01 s).
    """
    if isinstance(value, Fraction):
        period = value
    elif isinstance(value, str) and value in _PERIODS:  # the text's period, found before (a pure function of it)
        period = _PERIODS[value]
    else:
        try:
            if _is_frequency(value):
                frequency = float(to_magnitude(value, "Hz", (), where))
                period = 1 / Fraction(frequency).limit_denominator(10**9) if frequency > 0 else Fraction(0)
            else:
                period = Fraction(float(to_magnitude(value, "s", (), where))).limit_denominator(10**9)
        except UnitError as exc:
            raise ModelError(f"{exc} (a period in s or a rate in Hz)") from None
        if isinstance(value, str) and len(_PERIODS) < 4096:
            _PERIODS[value] = period
    if period <= 0:
        raise ModelError(f"{where}: a sample period must be positive, given {value!r}")
    return period


_PERIODS: dict = {}  # period text -> its Fraction (parsing "10 Hz" with pint costs ~1 ms; Monte Carlo runs repeat it)


def _is_frequency(value) -> bool:
    if not isinstance(value, str):
        return False
    try:
        return ureg.Quantity(value).dimensionality == ureg.Hz.dimensionality
    except Exception:  # not parseable as a quantity: to_magnitude reports it with context
        return False


def parse_offset(value, where: str) -> Fraction:
    seconds = float(to_magnitude(value, "s", (), where))
    if seconds < 0:
        raise ModelError(f"{where}: a sample offset must be >= 0 s, given {value!r}")
    return Fraction(seconds).limit_denominator(10**9)


def convert_parameters(declarations, given: dict, where: str, type_name: str) -> dict[str, np.ndarray]:
    """Check ``given`` against parameter declarations; values converted to the declared units."""
    known = {p.name: p for p in declarations}
    unknown = sorted(set(given) - set(known))
    if unknown:
        raise ModelError(f"{where}: unknown parameter(s) {unknown} for {type_name}; "
                         f"known: {sorted(known) or 'none'}")
    values = {}
    for p in declarations:
        raw = given.get(p.name, p.default)
        here = f"{where}: parameter {p.name}"
        if raw is None:
            raise ModelError(f"{here}: required ({p.description or 'no default'}; unit "
                             f"{format_unit(p.unit)}, shape {p.shape})")
        try:
            if p.name in given or not p.shape:
                value = to_magnitude(raw, p.unit, p.shape, here)
            else:  # the model's own default: a single number stands for every component of the declared shape
                value = to_magnitude(raw, p.unit, None, here)
                value = np.full(p.shape, value) if value.ndim == 0 else to_magnitude(raw, p.unit, p.shape, here)
        except UnitError as exc:
            raise ModelError(str(exc)) from None
        if not np.all(np.isfinite(value)):
            raise ModelError(f"{here}: must be finite, given {raw!r}")
        if p.bounds is not None:
            low, high = p.bounds
            if (low is not None and np.any(value < low)) or (high is not None and np.any(value > high)):
                raise ModelError(f"{here}: expected within [{low}, {high}] {format_unit(p.unit)}, given {raw!r}")
        values[p.name] = value
    return values


class Model:
    """Base class of component models (see the module docstring for the kernel contract).

    Subclasses declare ``parameters``, ``inputs``, ``outputs``, ``continuous_states``,
    ``discrete_states`` and ``zero_crossings`` as class attributes (or build them per instance in
    :meth:`configure`, e.g. when port shapes depend on parameters), and set the kernels they need.
    A model with an ``update`` kernel is *sampled*: it runs at ``period`` (+ ``offset``) seconds,
    given at construction or by ``default_period``; its outputs are held between samples.
    """

    parameters: tuple[Parameter, ...] = ()
    inputs: tuple[InputPort, ...] = ()
    outputs: tuple[OutputPort, ...] = ()
    continuous_states: tuple[State, ...] = ()
    discrete_states: tuple[State, ...] = ()
    zero_crossings: tuple[ZeroCrossing, ...] = ()
    #: the model's :class:`Declarations`: a class that sets it gets the six declaration tuples and ``offsets``
    declarations: Declarations | None = None
    default_period: object = None
    #: standard normals the framework draws from the model's stream before each ``update`` call (the
    #: kernel's sixth argument); 0: the update kernel takes the five-argument form
    noise_size: int = 0
    #: True: ``update`` is Python (user code, a scipy solver, the engine's Python API), so a compiled
    #: loop returns to Python at this model's sample instants; every other kernel is numba-compiled
    python_update: bool = False
    #: False: the ``update`` kernel reads no input (``u``), only the model's own states and parameters, so a
    #: sample of this model evaluates no output stage for it (an IMU, whose increments are the integrals of its
    #: inputs in its continuous states: its inputs are the node's acceleration, one forward dynamics per sample)
    update_reads_inputs: bool = True
    #: named offsets the kernels read, checked at construction (see :func:`check_named_offsets`)
    offsets: dict = {}
    #: one line shown by ``flexshell models``
    summary: str = ""

    state_outputs = None
    feedthrough_outputs = None
    derivatives = None
    update = None
    zero_crossing_values = None
    #: optional: the derivatives kernel to call when this model's feedthrough stage ran earlier in the same
    #: evaluation (same state and inputs), so it can reuse what that stage computed (the engine's
    #: accelerations: one forward-dynamics solve per evaluation)
    derivatives_after_feedthrough = None
    #: optional: the output kernels of a derivative evaluation (module docstring), None: the ordinary ones
    state_outputs_for_derivatives = None
    feedthrough_outputs_for_derivatives = None
    #: the model keeps per-run data (arrays its kernels read and write besides x, z, u, p): its kernels
    #: take it as an extra argument after ``p``, and :meth:`create_data` makes it for each run's context
    uses_data = False

    def __new__(cls, *args, **kwargs):
        model = super().__new__(cls)
        #: the constructor's arguments: a change of a value that :meth:`configure` reads (or of the sample rate)
        #: builds the model again from them (:mod:`shell.names`), not from the scenario's text
        model.construction = (args, dict(kwargs))
        return model

    def __init_subclass__(cls, **kwargs):
        super().__init_subclass__(**kwargs)
        declarations = cls.__dict__.get("declarations")
        if declarations is not None:
            for attribute, value in declarations.class_attributes().items():
                setattr(cls, attribute, value)

    def __init__(self, name: str, *, period=None, offset=0.0, **parameter_values):
        if not name or "." in name or not name.replace("_", "a").isalnum():
            raise ModelError(f"model name {name!r}: use letters, digits and underscores (no dots)")
        self.name = name
        self.path = name
        self.rng: np.random.Generator | None = None
        self.initial_overrides: dict[str, object] = {}
        self.declare()
        self._set_parameters(parameter_values)
        self._read_by_configure = set()
        self.configure()
        #: the parameters :meth:`configure` read (through :meth:`parameter`): their values shape declarations,
        #: derived data or initial states; every other parameter is read by the kernels from ``p`` alone, so a
        #: run may change it in its Context without building the model again (:mod:`shell.names`)
        self.configured_parameters = frozenset(self._read_by_configure)
        self._read_by_configure = None
        self._check_declarations()
        check_named_offsets(self)
        self.period: Fraction | None = None
        self.offset = Fraction(0)
        if self.update is not None:
            given = period if period is not None else self.default_period
            if given is None:
                raise ModelError(f"model {self.path}: {type(self).__name__} is sampled; give its period "
                                 "(e.g. period: 0.1 s or rate: 10 Hz)")
            self.period = parse_period(given, f"model {self.path}: period")
            self.offset = parse_offset(offset, f"model {self.path}: offset")
        elif period is not None:
            raise ModelError(f"model {self.path}: {type(self).__name__} is continuous-time and takes no period "
                             f"(given {period!r})")
        self.p_layout = Layout.of(self.parameters)
        self.u_layout = Layout.of(self.inputs)
        self.y_layout = Layout.of(self.outputs)
        self.x_layout = Layout.of(self.continuous_states)
        self.z_layout = Layout.of(self.discrete_states)

    # -- parameters -------------------------------------------------------------------------------
    def _set_parameters(self, given: dict) -> None:
        self.parameter_values = convert_parameters(self.parameters, given, f"model {self.path}",
                                                   type(self).__name__)
        parts = [self.parameter_values[p.name].reshape(-1) for p in self.parameters]
        self.p = np.concatenate(parts) if parts else np.zeros(0)
        offset = 0
        for p in self.parameters:  # views into the flat vector the kernels receive
            self.parameter_values[p.name] = self.p[offset:offset + p.size].reshape(p.shape)
            offset += p.size

    def parameter(self, name: str) -> np.ndarray:
        """The value of parameter ``name`` in its declared unit (a view into ``self.p``)."""
        reading = getattr(self, "_read_by_configure", None)
        if reading is not None:
            reading.add(name)
        return self.parameter_values[name]

    def require_unit_norm(self, name: str, tolerance: float = 1e-9) -> float:
        """Refuse parameter ``name`` (a quaternion [w, x, y, z] or a direction) unless its norm is 1 within
        ``tolerance``; returns the norm."""
        value = np.asarray(self.parameter(name), float).reshape(-1)
        norm = float(np.sqrt(value @ value))
        if abs(norm - 1.0) > tolerance:
            kind = "quaternion [w, x, y, z]" if value.size == 4 else "vector"
            raise ModelError(f"model {self.path}: parameter {name}: expected a unit {kind}, given norm {norm:.12g}")
        return norm

    def declare(self) -> None:
        """Hook run first: instance-level declarations that depend on construction options."""

    def use_declarations(self, declarations: Declarations) -> None:
        """This instance's declarations (from ``declare`` or ``configure``: shapes and units of its configuration);
        the kernels' offsets stay the class's, checked against them."""
        for name, attribute in _DECLARED.items():
            setattr(self, attribute, getattr(declarations, name))

    def configure(self) -> None:
        """Hook run after parameters are set: declarations or data that depend on parameter values."""

    def _check_declarations(self) -> None:
        for kind, decls in (("input", self.inputs), ("output", self.outputs)):
            names = [d.name for d in decls]
            if len(set(names)) != len(names):
                raise ModelError(f"model {self.path}: duplicate {kind} port names in {names}")
            for d in decls:
                parse_unit(d.unit, f"model {self.path}: {kind} {d.name}")
        shared = sorted({d.name for d in self.inputs} & {d.name for d in self.outputs})
        if shared:
            # a port is addressed as `model.name` in connections and logs: one name cannot mean two ports
            raise ModelError(f"model {self.path}: {shared} declared both as input and as output port; "
                             f"give the input and the output different names")
        if any(o.feedthrough for o in self.outputs) and self.feedthrough_outputs is None:
            raise ModelError(f"{type(self).__name__}: feedthrough outputs declared without a feedthrough_outputs kernel")
        if self.zero_crossings and self.zero_crossing_values is None:
            raise ModelError(f"{type(self).__name__}: zero crossings declared without zero_crossing_values")

    # -- events -----------------------------------------------------------------------------------
    def on_event(self, index: int, t: float, x: np.ndarray, z: np.ndarray, p: np.ndarray) -> None:
        """Handle zero crossing ``index`` at time ``t``: reset ``x`` and/or switch modes in ``z``
        (both writable views). Called outside the integration loop; may be plain Python."""

    # -- restart -----------------------------------------------------------------------------------
    def restored(self, t: float, x: np.ndarray, z: np.ndarray, p: np.ndarray) -> None:
        """Called by ``Simulation.restore`` once every state is back: re-establish from ``x`` and ``z``
        whatever the model keeps outside its states (e.g. mass properties it set in the engine), so
        the run continues exactly as if it had never stopped. Plain Python; default: nothing."""

    # -- initial values ----------------------------------------------------------------------------
    def initial_continuous_state(self) -> np.ndarray:
        return self._initial(self.continuous_states)

    def initial_discrete_state(self) -> np.ndarray:
        return self._initial(self.discrete_states)

    def set_initial(self, state_name: str, value) -> None:
        """Override the declared initial value of a continuous or discrete state (checked at build)."""
        names = [s.name for s in self.continuous_states + self.discrete_states]
        if state_name not in names:
            raise ModelError(f"model {self.path}: no state {state_name!r} to initialize; states: {names}")
        self.initial_overrides[state_name] = value

    def _initial(self, states) -> np.ndarray:
        parts = []
        for s in states:
            raw = self.initial_overrides.get(s.name, s.initial)
            raw = raw if raw is not None else np.zeros(s.shape)
            parts.append(to_magnitude(raw, s.unit, s.shape, f"model {self.path}: initial {s.name}").reshape(-1))
        return np.concatenate(parts) if parts else np.zeros(0)

    # -- per-run data -------------------------------------------------------------------------------
    def create_data(self, own: bool = False):
        """``(host, data)`` of a model with ``uses_data``: ``data`` a tuple of numpy arrays (numba-friendly)
        its kernels receive after ``p``, ``host`` the Python object owning them (or None). ``own``: a
        private copy for an additional context (a Monte Carlo run); otherwise the model's own arrays may
        be shared (the first context)."""
        raise NotImplementedError(f"{type(self).__name__} declares uses_data but no create_data")

    # -- random stream -----------------------------------------------------------------------------
    def random_stream(self, scenario_seed) -> np.random.Generator:
        """This model's generator for scenario seed ``scenario_seed`` (see :meth:`seed_random_stream`)."""
        digest = hashlib.sha256(self.path.encode()).digest()
        spawn_key = tuple(int.from_bytes(digest[i:i + 4], "little") for i in range(0, 16, 4))
        sequence = np.random.SeedSequence(entropy=scenario_seed, spawn_key=spawn_key)
        return np.random.Generator(np.random.PCG64(sequence))

    def seed_random_stream(self, scenario_seed) -> None:
        """Give the model its own generator, derived from (scenario seed, model path) only.

        ``numpy.random.SeedSequence(entropy=scenario_seed, spawn_key=words(path))``: the stream does
        not depend on which other models exist or in which order they draw; Monte Carlo run i uses
        ``scenario_seed = [master_seed, i]``.
        """
        self.rng = self.random_stream(scenario_seed)

    # -- attachment to multibody nodes/hinges ----------------------------------------------------------
    def attachment_ports(self, kind: str, target: str) -> tuple[dict[str, str], dict[str, str]]:
        """For engine-like models: (outputs, inputs) maps from generic signal names ("attitude",
        "force", ...) to this model's port names for node/hinge ``target``. Others refuse."""
        raise ModelError(f"model {self.path}: {type(self).__name__} has no nodes or hinges to attach to")

    def output_read(self, name: str, in_derivatives: bool = False) -> bool:
        """Output port ``name`` is read: connected to an input, logged, linearized or read by name (the diagram calls
        this when it is built and whenever a name is resolved); ``in_derivatives``: connected to an input that a
        derivative evaluation reads (of a model with continuous states, or through feedthrough stages to one). A
        model that computes only the outputs something reads (the multibody engine's node kinematics) starts
        computing ``name`` here and returns True when it did not compute it until now (its value in the signal buffer
        is then stale until the next evaluation); the default computes every output and returns False."""
        return False

    def missing_port_hint(self, name: str) -> str:
        """What a refusal of the port or state ``name``, which this model does not have, should add (a port
        the model can have when the scene asks for it); empty when there is nothing to say."""
        return ""

    def __repr__(self) -> str:
        return f"{type(self).__name__}({self.path!r})"
