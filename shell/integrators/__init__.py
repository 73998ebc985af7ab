"""flexshell's ODE integrators: fixed-step, adaptive embedded and implicit Runge-Kutta methods with dense
output, zero-crossing location and the hooks the multi-rate simulation loop needs.

>>> from shell.integrators import make_integrator, INTEGRATORS
>>> integ = make_integrator("rk4", fun, t0, y0, t_bound, step=0.01)
>>> integ.step(); sol = integ.dense_output()

See :mod:`shell.integrators.base` for the interface, :mod:`shell.integrators.events` for event
location and :func:`shell.integrators.driver.integrate` for a one-call driver; docs/integrators.md says
which method to pick for which scene.
"""
from .adaptive import DOP853, BogackiShampine32, DormandPrince54, EmbeddedRungeKutta, StiffnessWarning
from .base import DenseOutput, Integrator, quaternion_gauge
from .driver import IntegrationResult, integrate
from .events import event, locate_events
from .exponential import ExponentialRK4, StiffRemainderWarning
from .implicit import Radau5
from .fixed import RK4, RK8, ExplicitEuler, FixedStepRungeKutta, Heun
from .registry import INTEGRATORS, make_integrator, register_integrator

__all__ = ["INTEGRATORS", "register_integrator", "make_integrator", "Integrator", "DenseOutput", "quaternion_gauge",
           "locate_events", "event", "integrate", "IntegrationResult",
           "FixedStepRungeKutta", "ExplicitEuler", "Heun", "RK4", "RK8",
           "EmbeddedRungeKutta", "BogackiShampine32", "DormandPrince54", "DOP853", "StiffnessWarning", "Radau5",
           "ExponentialRK4", "StiffRemainderWarning"]
