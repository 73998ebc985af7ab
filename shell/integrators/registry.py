"""The integrators by name: the registry a scenario's ``integrator.method`` and :func:`make_integrator` read.

A new method registers here (:func:`register_integrator`) from its own file; one that steps in the compiled loop
brings its :class:`shell.integrators.compiled.CompiledStepping` (docs/integrators.md, "Adding a method").
"""

from .adaptive import DOP853, BogackiShampine32, DormandPrince54
from .base import Integrator
from .exponential import ExponentialRK4
from .exponential_stepper import ExponentialStepping
from .fixed import RK4, RK8, ExplicitEuler, Heun
from .implicit import Radau5

#: the integrators by name (a scenario's integrator.method, make_integrator)
INTEGRATORS: dict = {}


def register_integrator(cls, compiled_stepping=None):
    """Make the :class:`Integrator` subclass ``cls`` available by its ``name``; ``compiled_stepping``: the
    :class:`shell.integrators.compiled.CompiledStepping` of a method that steps in the compiled loop, when it lives
    in another file than the class (one that lives with it is the class's ``compiled_stepping``). Returns ``cls``."""
    if compiled_stepping is not None:
        cls.compiled_stepping = compiled_stepping
    INTEGRATORS[cls.name] = cls
    return cls


for _method in (ExplicitEuler, Heun, RK4, RK8, BogackiShampine32, DormandPrince54, DOP853, Radau5):
    register_integrator(_method)
register_integrator(ExponentialRK4, compiled_stepping=ExponentialStepping)


def make_integrator(method, fun, t0, y0, t_bound, **options):
    """Construct the integrator named ``method`` (a key of ``INTEGRATORS``) or given as a class.

    Options: ``step`` (fixed-step methods: the step; adaptive: initial step guess), ``rtol``, ``atol``,
    ``max_step``, ``normalize``, ``error_exclude``, ``jac`` for implicit methods, and ``linear_part`` for the
    exponential method (classes with ``uses_linear_part``).
    """
    if isinstance(method, type) and issubclass(method, Integrator):
        cls = method
    else:
        try:
            cls = INTEGRATORS[str(method).lower()]
        except KeyError:
            raise ValueError(f"unknown integrator {method!r}; choose one of {sorted(INTEGRATORS)}") from None
    if options.get("jac") is not None and not cls.implicit:
        raise ValueError(f"integrator {cls.name!r} is explicit and does not use a Jacobian; pass jac only "
                         f"to an implicit method ({sorted(k for k, c in INTEGRATORS.items() if c.implicit)})")
    if "jac" in options and not cls.implicit:
        options = {k: v for k, v in options.items() if k != "jac"}
    return cls(fun, t0, y0, t_bound, **options)
