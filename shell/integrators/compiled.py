"""What an integrator supplies to step in flexshell's compiled loop, and what the loop supplies to it.

scipy's ``OdeSolver`` shape (docs/architecture.md: a step, a dense output) as numba functions over a *stepper*: a NamedTuple
of the method's numbers and arrays (its coefficients, its nominal step ``h``, the state ``Y`` at the current time,
the state ``YN`` the last step produced, work arrays). An integrator that steps compiled registers its stepper
class with :func:`register_stepper` and these njit functions (its own file; :mod:`shell.compiled_loop` never
names a method):

``start(system, st, t, ints, reals) -> status``
    take the run's state (``state(system)``, the context's x) as ``Y`` when ``ints[I_F_VALID] == 0`` (a restart:
    after an update, an event, or at the start), normalized, with whatever slope the method needs;
``step(system, st, t, h, t_new, skip_slope, ints, reals) -> status``
    one step of size ``h`` from ``(t, Y)`` to ``t_new`` into ``YN`` (normalized); ``skip_slope``: the run restarts
    at ``t_new`` (an update is due there), so no slope is needed at its end. On a non-finite value: ``YN`` holds
    it, ``reals[R_FAILED_T]`` its time, ``ints[I_FAILED_STAGE]`` 0 for a state and 1 for a derivative, and the
    status is STEP_FAILED (START_FAILED for a non-finite slope at ``t``); a status >= FIRST_REQUEST asks the
    integrator's Python side (below) for something before the step is taken or resumed;
``keep(st, ev)``
    before the step is accepted: what its dense output needs from its start, into the loop's event arrays
    (``ev.y_old``, ``ev.f_old``);
``accept(st, ints, skipped)``
    ``Y`` becomes ``YN`` (``skipped``: the step had no end slope);
``prepare_dense(st, ev)`` and ``dense(st, ev, theta, h, out)``
    the state at ``t_old + theta h`` on the accepted step's continuous extension (prepared once per step).

The *system* is what the loop integrates: :func:`derivative`, :func:`normalize` and :func:`state` dispatch on its
type (registered by the loop with :func:`register_system`), so a stepper is written once for any system. The
dispatch is inlined (numba's ``inline="always"``), and a stepper's ``step`` should be too: the system's evaluation is
then inlined into it, instead of copying the scene's arrays by value at every call (shell.compiled_loop).

The Python side of a compiled integrator is a :class:`CompiledStepping` subclass (the integrator class's
``compiled_stepping``; None: the method steps in Python): it says whether a run of the method steps compiled, makes
the run's stepper, answers the stepper's requests, gives the step's dense output to event location and advice to a
failure message.
"""

from __future__ import annotations

from numba.extending import overload

# integer registers of the loop (ints array) that steppers read or write
I_NOW, I_F_VALID, I_STEPS, I_NFEV, I_UPDATES, I_PHASE, I_FAILED_STAGE = range(7)
N_INTS = 7
# float registers (reals array)
R_T, R_FAILED_T, R_T_OLD, R_LAST_EVENT = range(4)
N_REALS = 4

# statuses a stepper returns (0: go on)
STEP_FAILED = 4          # a step produced a non-finite state or derivative
START_FAILED = 5         # the slope at the start of a step is not finite
#: statuses from here on are the integrator's own requests, answered by its CompiledStepping.request
FIRST_REQUEST = 16

_STEPPERS: dict = {}
_SYSTEMS: dict = {}


def register_stepper(stepper_class, *, start, step, keep, accept, prepare_dense, dense) -> None:
    """Make ``stepper_class`` (a NamedTuple with at least ``h``, ``Y`` and ``YN``) steppable by the compiled loop
    with these njit functions (module docstring)."""
    _STEPPERS[stepper_class] = {"start": start, "step": step, "keep": keep, "accept": accept,
                                "prepare_dense": prepare_dense, "dense": dense}


def register_system(system_class, *, derivative, normalize, state) -> None:
    """Make ``system_class`` a system steppers can integrate: ``derivative(system, t, y) -> f`` (the system's own
    array, valid until its next evaluation), ``normalize(system, y)`` in place, ``state(system) -> x``."""
    _SYSTEMS[system_class] = {"derivative": derivative, "normalize": normalize, "state": state}


def _registered(table, what, numba_type, name):
    impl = table.get(getattr(numba_type, "instance_class", None))
    if impl is None:
        raise TypeError(f"{numba_type} is not a registered {what} (register_{what} of shell.integrators.compiled)")
    return impl[name]


# the protocol's functions, dispatched at compile time on the stepper's or the system's type ---------------------
def start(system, st, t, ints, reals):
    """The stepper's ``start`` (module docstring)."""


def step(system, st, t, h, t_new, skip_slope, ints, reals):
    """The stepper's ``step`` (module docstring)."""


def keep(st, ev):
    """The stepper's ``keep`` (module docstring)."""


def accept(st, ints, skipped):
    """The stepper's ``accept`` (module docstring)."""


def prepare_dense(st, ev):
    """The stepper's ``prepare_dense`` (module docstring)."""


def dense(st, ev, theta, h, out):
    """The stepper's ``dense`` (module docstring)."""


def derivative(system, t, y):
    """f(t, y) of the system (its own array, valid until its next evaluation)."""


def normalize(system, y):
    """Renormalize the quaternions of the system's state vector ``y`` in place."""


def state(system):
    """The system's current state x (the run's context)."""


@overload(start, inline="always")
def _start(system, st, t, ints, reals):
    impl = _registered(_STEPPERS, "stepper", st, "start")
    return lambda system, st, t, ints, reals: impl(system, st, t, ints, reals)


@overload(step, inline="always")
def _step(system, st, t, h, t_new, skip_slope, ints, reals):
    impl = _registered(_STEPPERS, "stepper", st, "step")
    return lambda system, st, t, h, t_new, skip_slope, ints, reals: impl(system, st, t, h, t_new, skip_slope, ints,
                                                                         reals)


@overload(keep, inline="always")
def _keep(st, ev):
    impl = _registered(_STEPPERS, "stepper", st, "keep")
    return lambda st, ev: impl(st, ev)


@overload(accept, inline="always")
def _accept(st, ints, skipped):
    impl = _registered(_STEPPERS, "stepper", st, "accept")
    return lambda st, ints, skipped: impl(st, ints, skipped)


@overload(prepare_dense, inline="always")
def _prepare_dense(st, ev):
    impl = _registered(_STEPPERS, "stepper", st, "prepare_dense")
    return lambda st, ev: impl(st, ev)


@overload(dense, inline="always")
def _dense(st, ev, theta, h, out):
    impl = _registered(_STEPPERS, "stepper", st, "dense")
    return lambda st, ev, theta, h, out: impl(st, ev, theta, h, out)


@overload(derivative, inline="always")
def _derivative(system, t, y):
    impl = _registered(_SYSTEMS, "system", system, "derivative")
    return lambda system, t, y: impl(system, t, y)


@overload(normalize, inline="always")
def _normalize(system, y):
    impl = _registered(_SYSTEMS, "system", system, "normalize")
    return lambda system, y: impl(system, y)


@overload(state, inline="always")
def _state(system):
    impl = _registered(_SYSTEMS, "system", system, "state")
    return lambda system: impl(system)


class CompiledStepping:
    """The Python side of an integrator stepping in the compiled loop, for one run (module docstring); an integrator
    class names its subclass in ``compiled_stepping``.

    ``run`` is the run's side (:class:`shell.compiled_run.CompiledRun`): ``t``, ``x``, ``options`` (the integrator's
    options and ``step``), ``integrator`` (the run's Python integrator object, or None) and ``make_integrator(
    t_bound)`` (the method's Python integrator at the run's state, as the Python loop makes it); ``method`` the
    integrator class; ``st`` the current stepper."""

    def __init__(self, run, method):
        self.run, self.method = run, method
        self.st = None

    @classmethod
    def applies(cls, method, options: dict, has_events: bool) -> bool:
        """Whether ``method`` with ``options`` steps compiled in a run (``has_events``: the scene has zero
        crossings, located on the method's dense output)."""
        raise NotImplementedError

    def stepper(self, stale: bool):
        """The stepper to start (or continue) the run with; ``stale``: the run's state changed since the last
        compiled call (an update, an event, a restore), so the stepper restarts from it. Returns (stepper,
        value of ints[I_F_VALID])."""
        raise NotImplementedError

    def request(self, status: int, st, ints, reals, t_end: float):
        """Answer a status >= FIRST_REQUEST at the run's time; returns the stepper to go on with."""
        raise NotImplementedError(f"{type(self).__name__}: status {status}")

    def dense_output(self, st, t_old: float, t_new: float, y_old, f_old):
        """The accepted step's dense output as a :class:`shell.integrators.DenseOutput` (for event location)."""
        raise NotImplementedError

    def advice(self, st) -> str:
        """What to try after a non-finite step (the end of the failure message)."""
        return ("if the state grew without bound the step may exceed the explicit stability limit: reduce the step, "
                "remove fast modes, or use an implicit method")

    def sync(self, st, ints) -> None:
        """The loop returned (done, failed or stopped): bring the Python side up to date."""
