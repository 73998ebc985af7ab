"""Parameters, states and sample schedules addressed by dotted name: the Diagram's index and a Context's writes.

Drake keeps a system's numeric parameters in its Context and MuJoCo its model's fields in named arrays
(docs/architecture.md); here :class:`NameIndex` maps each name of a scene to where its value lives in a run's
:class:`shell.diagram.Context`, with the unit, shape and bounds the value is checked against:

====================================  =====================================================================
name                                  where the value goes
====================================  =====================================================================
``controller.kp``                     a parameter: its slice of ``context.p`` (declared unit)
``controller.integral``               a continuous or discrete state: its slice of ``context.x`` / ``z``
``controller.rate`` / ``.period``     a sampled model's schedule: ``context.periods``, ``offsets`` and
``controller.offset``                 ``next_sample``
``multibody.bus.inertia``             what a model keeps itself (:meth:`named_values` of the model): the
``multibody.bus.initial.attitude``    engine's mass properties in the run's own engine system, its
                                      per-body initial values
====================================  =====================================================================

The forms a scenario's ``--set`` path takes are accepted too: ``controller.parameters.kp`` and
``controller.initial.integral``. Monte Carlo runs (:mod:`shell.montecarlo.reuse`), trim and parameter
sensitivities write a run's values through :meth:`NameIndex.assign`; nothing is parsed from YAML, no scene is
built. A value is converted exactly as the model's constructor converts it (:func:`shell.model.convert_parameters`,
:func:`shell.units.to_magnitude`: same arithmetic, so the run equals the scene built with that value, bit for
bit) and refused with the same messages (unit, shape, finiteness, bounds).

A parameter that the model's ``configure`` reads (``Model.configured_parameters``: it shapes declarations,
derived data or initial states), and a sample rate, period or offset (a model may derive states from it), are
values the Context cannot take alone: the model is constructed again from its constructor's arguments
(``Model.construction``) with the new values, checked to keep its layout (same ports, states, parameters, noise),
and the run takes the new model's parameters, initial states and schedule. Results are remembered per value:
a choice between a few rates costs one construction per choice and process. A change of layout raises
:class:`StructuralChange` (a campaign then builds each run's scene from its overrides).
"""

from __future__ import annotations

import difflib
from dataclasses import dataclass

import numpy as np

from shell.model import ModelError, convert_parameters
from shell.units import UnitError, to_magnitude

#: a model's sample schedule, by the scenario's keys
SCHEDULE = ("rate", "period", "offset")


class StructuralChange(ModelError):
    """A value a run's Context cannot take: it changes the model's layout or the scene's structure."""


@dataclass(frozen=True)
class NamedValue:
    """One addressable value of a scene."""

    name: str                 # dotted name, e.g. "controller.kp"
    kind: str                 # "parameter", "x", "z" (states), "schedule", "model" (kept by the model itself)
    model: int                # index of the model in the diagram
    leaf: str                 # the model's own name for it ("kp", "integral", "rate", "bus.inertia")
    unit: str = ""
    shape: tuple | None = None
    bounds: tuple | None = None
    where: slice | None = None   # parameters: slice of context.p; states: slice of context.x or z
    configured: bool = False     # a change builds the model again (module docstring)
    declaration: object = None   # the Parameter or State; a model's own value: its description
    initial: bool = False        # an initial value: taken only before the run starts


class NameIndex:
    """Every named value of a diagram's scene (see the module docstring); built once per diagram."""

    def __init__(self, diagram):
        self.diagram = diagram
        self.entries: dict[str, NamedValue] = {}
        self._constructed: dict = {}  # (model, changes, current parameters) -> the new model's values
        for i, m in enumerate(diagram.models):
            block = diagram.p_block[i]
            for p in m.parameters:
                sl = m.p_layout.slice(p.name)
                self._add(NamedValue(f"{m.path}.{p.name}", "parameter", i, p.name, p.unit, tuple(p.shape),
                                     p.bounds, slice(block.start + sl.start, block.start + sl.stop),
                                     p.name in m.configured_parameters, p))
            for s in m.continuous_states + m.discrete_states:
                kind, sl, decl = diagram.state_slices[(m.path, s.name)]
                self._add(NamedValue(f"{m.path}.{s.name}", kind, i, s.name, s.unit, tuple(s.shape), None, sl,
                                     False, decl))
            if m.period is not None:
                for key in SCHEDULE:
                    self._add(NamedValue(f"{m.path}.{key}", "schedule", i, key, "Hz" if key == "rate" else "s", (),
                                         None, None, True))
            for leaf, (unit, shape, description, initial) in (getattr(m, "named_values", dict)() or {}).items():
                self._add(NamedValue(f"{m.path}.{leaf}", "model", i, leaf, unit, shape, None, None, False,
                                     description, initial))

    def _add(self, entry: NamedValue) -> None:
        # a port or state name is never also a parameter name of one model (Model's declarations): first wins
        self.entries.setdefault(entry.name, entry)

    # -- lookup --------------------------------------------------------------------------------------
    def __contains__(self, name: str) -> bool:
        return self.find(name) is not None

    def find(self, name: str) -> NamedValue | None:
        """The entry of ``name`` (also in its ``model.parameters.p`` / ``model.initial.s`` forms), or None."""
        entry = self.entries.get(name)
        if entry is not None:
            return entry
        for section, kinds in (("parameters", ("parameter",)), ("initial", ("x", "z"))):
            marker = f".{section}."
            if marker in name:
                head, _, tail = name.partition(marker)
                entry = self.entries.get(f"{head}.{tail}")
                if entry is not None and entry.kind in kinds:
                    return entry
        return None

    def __getitem__(self, name: str) -> NamedValue:
        entry = self.find(name)
        if entry is None:
            close = difflib.get_close_matches(name, list(self.entries), n=3)
            hint = f"; did you mean {' or '.join(repr(c) for c in close)}?" if close else ""
            raise ModelError(f"{name!r} is not a parameter, state, sample rate or model value of the scene{hint}")
        return entry

    def names(self, kind: str | None = None) -> list[str]:
        return [name for name, e in self.entries.items() if kind is None or e.kind == kind]

    # -- values ----------------------------------------------------------------------------------------
    def value(self, context, name: str):
        """The current value of ``name`` in ``context`` (declared unit; a copy)."""
        entry = self[name]
        if entry.kind == "parameter":
            return context.p[entry.where].reshape(entry.shape).copy()
        if entry.kind in ("x", "z"):
            source = context.x if entry.kind == "x" else context.z
            return source[entry.where].reshape(entry.shape).copy()
        if entry.kind == "schedule":
            period, offset = context.periods[entry.model], context.offsets[entry.model]
            return {"rate": 1 / period, "period": period, "offset": offset}[entry.leaf]
        model = self.diagram.models[entry.model]
        return model.named_value(entry.leaf, context.hosts[entry.model])

    def assign(self, context, items) -> None:
        """Write ``items`` ((name, value) pairs) into ``context``. A value is what the scenario would hold: a number
        or array in the declared unit, a string with a unit (``"[10, 7] N*m/rad"``, ``"5 Hz"``), a mapping
        ``{value, unit}`` or a pint Quantity. Per model, in this order: changes that build the model again
        (module docstring), parameters, states, the model's own values. Raises ModelError (or UnitError) naming
        the value, :class:`StructuralChange` for a change the Context cannot take."""
        per_model: dict[int, list] = {}
        for name, value in items:
            entry = self[name]
            per_model.setdefault(entry.model, []).append((entry, value))
        for i, changes in per_model.items():
            configured = [(e, v) for e, v in changes if e.configured]
            if configured:
                self._construct_again(context, i, configured)
            for entry, value in changes:
                if entry.kind == "parameter" and not entry.configured:
                    context.p[entry.where] = self._parameter(entry, value).reshape(-1)
            for entry, value in changes:
                if entry.kind in ("x", "z"):
                    self._state(context, entry, value)
            own = [(e.leaf, v) for e, v in changes if e.kind == "model"]
            late = [e.name for e, _ in changes if e.initial and not context.unstarted]
            if late:
                raise ModelError(f"{', '.join(late)}: initial values are given before the run starts")
            if own:
                model = self.diagram.models[i]
                model.assign_named(own, context.hosts[i], context.x[self.diagram.x_block[i]])

    def _parameter(self, entry: NamedValue, value) -> np.ndarray:
        """``value`` converted and checked as the model's constructor would (same function, same messages)."""
        model = self.diagram.models[entry.model]
        return convert_parameters((entry.declaration,), {entry.leaf: value}, f"model {model.path}",
                                  type(model).__name__)[entry.leaf]

    def _state(self, context, entry: NamedValue, value) -> None:
        model = self.diagram.models[entry.model]
        try:
            magnitude = to_magnitude(value, entry.unit, entry.shape, f"model {model.path}: initial {entry.leaf}")
        except UnitError as exc:
            raise ModelError(str(exc)) from None
        if not np.all(np.isfinite(magnitude)):
            raise ModelError(f"model {model.path}: initial {entry.leaf}: expected finite values, given {value!r}")
        (context.x if entry.kind == "x" else context.z)[entry.where] = magnitude.reshape(-1)

    def _construct_again(self, context, i: int, changes) -> None:
        """Model ``i`` built again from its constructor's arguments with ``changes`` (configured parameters and the
        schedule) and the context's values of the other parameters its ``configure`` reads; the context takes its
        configured parameters, initial states and schedule, and keeps its values of every other parameter."""
        d = self.diagram
        model = d.models[i]
        if not context.unstarted:
            raise ModelError(f"{', '.join(e.name for e, _ in changes)}: a change that builds model {model.path} "
                             "again is given before its run starts")
        block = context.p[d.p_block[i]]
        configured = model.configured_parameters
        given = {p.name: block[model.p_layout.slice(p.name)].reshape(p.shape).copy()  # the run's values so far
                 for p in model.parameters if p.name in configured}
        for entry, value in changes:
            given[entry.leaf if entry.kind == "parameter" else "offset" if entry.leaf == "offset" else "period"] = value
        key = (i, _key(given))
        built = self._constructed.get(key)
        if built is None:
            args, kwargs = model.construction
            fresh = type(model)(*args, **{**kwargs, **given})
            fresh.path = model.path
            for state, initial in model.initial_overrides.items():
                fresh.set_initial(state, initial)
            if _layout(fresh) != _layout(model):
                raise StructuralChange(f"{', '.join(e.name for e, _ in changes)}: the values change the layout of "
                                       f"model {model.path} (its ports, states or parameters)")
            built = (fresh.p.copy(), fresh.initial_continuous_state(), fresh.initial_discrete_state(), fresh.period,
                     fresh.offset)
            if len(self._constructed) > 256:
                self._constructed.clear()
            self._constructed[key] = built
        p, x0, z0, period, offset = built
        for decl in model.parameters:
            if decl.name in configured:
                sl = model.p_layout.slice(decl.name)
                block[sl] = p[sl]
        context.x[d.x_block[i]] = x0
        context.z[d.z_block[i]] = z0
        context.periods[i], context.offsets[i] = period, offset
        context.next_sample[i] = d.first_sample(period, offset, context.t)


def _layout(m) -> tuple:
    def decl(d):
        return (d.name, tuple(d.shape), str(getattr(d, "unit", "")))

    return (type(m), tuple(decl(p) for p in m.parameters), tuple(decl(p) for p in m.inputs),
            tuple(decl(p) for p in m.outputs), tuple(decl(s) for s in m.continuous_states),
            tuple(decl(s) for s in m.discrete_states), tuple(z.name for z in m.zero_crossings), int(m.noise_size),
            m.period is None)


def _key(value):
    """A hashable, exact key of constructor arguments (arrays by their bytes)."""
    if isinstance(value, np.ndarray):
        return ("array", value.dtype.str, value.shape, value.tobytes())
    if isinstance(value, dict):
        return ("dict", tuple((k, _key(v)) for k, v in value.items()))
    if isinstance(value, (list, tuple)):
        return (type(value).__name__, tuple(_key(v) for v in value))
    if isinstance(value, float):
        return ("float", value.hex()) if value == value else ("nan",)
    try:
        hash(value)
    except TypeError:
        return ("repr", repr(value))
    return (type(value).__name__, value)
