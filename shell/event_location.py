"""Zero crossings of a run: which steps are searched, and where in a step the first crossings lie.

The models' zero-crossing functions g_i(t, x) (TM-2020-5008164 App. D.1, zero finding) are evaluated after every
step. With ``detection="subdivided"`` (the default) every step is searched on the integrator's dense output, so two
crossings inside one step are both found; ``"sign_change"`` searches only steps whose ends differ in sign in a
counted direction (cheaper, blind to such pairs). The step right after an event is always searched: a function
left at zero by the event can leave and come back inside one (long, adaptive) step without a sign change at its
ends. Crossings are located to ``tolerance`` in time (:func:`shell.integrators.locate_events`: samples of the dense
output, parabolic extrema, Brent's method); a crossing of a function just handled, within four tolerances of the
event, is its own round-off and not a new event. What happens at a crossing (the state moved there, the models'
``on_event`` handlers, a terminal stop) is the simulation's (:meth:`shell.simulation.Simulation`).
"""

from __future__ import annotations

import numpy as np

from shell.integrators import locate_events
from shell.model import ModelError

DETECTIONS = ("sign_change", "subdivided")


class EventFunction:
    """g_i(t, y) for locate_events: evaluates every zero-crossing function at (t, y) and returns component i."""

    def __init__(self, values, index: int, direction: int, terminal: bool):
        self.values = values
        self.index = index
        self.direction = direction
        self.terminal = terminal

    def __call__(self, t, y):
        return float(self.values(float(t), y)[self.index])


class EventLocation:
    """The zero crossings of a diagram's models for one run; ``values(t, y)`` evaluates all of them (the plan's)."""

    def __init__(self, diagram, values, tolerance: float, detection: str):
        if detection not in DETECTIONS:
            raise ModelError(f"event detection {detection!r}: expected 'sign_change' (search a step when a "
                             "zero-crossing function changes sign between its ends) or 'subdivided' (search every "
                             "step on its dense output: also finds two crossings inside one step)")
        self.values = values
        self.tolerance = float(tolerance)
        self.detection = detection
        self.functions = [EventFunction(values, j, zc.direction, diagram.zero_crossing_terminal[j])
                          for j, (_, _, zc) in enumerate(diagram.zero_crossing_owner)]
        #: (time, indices) of the crossings handled last
        self.last: tuple[float, set] = (-np.inf, set())

    def __bool__(self) -> bool:
        return bool(self.functions)

    def directions(self) -> np.ndarray:
        return np.asarray([f.direction for f in self.functions], dtype=np.int64)

    def search(self, t_old: float, g_old, g_new) -> bool:
        """Whether the step from ``t_old`` with functions ``g_old`` -> ``g_new`` is searched (module docstring)."""
        return self.detection == "subdivided" or t_old == self.last[0] or self.crossed(g_old, g_new)

    def crossed(self, g_old, g_new) -> bool:
        """A sign change between the ends of a step, in a counted direction."""
        for f, a, b in zip(self.functions, g_old, g_new):
            if a == 0.0:
                continue
            if b == 0.0 or (a < 0.0) != (b < 0.0):
                rising = b > a
                if f.direction == 0 or (f.direction > 0) == rising:
                    return True
        return False

    def first(self, sol, t_old: float, t_new: float, g_old, g_new, samples=None) -> tuple[float, list] | None:
        """(time, [function index, ...]) of the first crossings of the step [t_old, t_new] on its dense output
        ``sol`` (``samples``: the functions at its inner uniform samples when already computed), or None; they
        become the last handled crossings."""
        hits = locate_events(self.functions, sol, t_old, t_new, g_old, g_new, xtol=self.tolerance,
                             all_values=self.values, samples=samples)
        t_last, handled = self.last
        hits = [(t, j) for t, j in hits if not (j in handled and t - t_last <= 4 * self.tolerance)]
        if not hits:
            return None
        t_event = hits[0][0]
        crossing = [j for t, j in hits if t == t_event]
        self.last = (t_event, set(crossing))
        return t_event, crossing
