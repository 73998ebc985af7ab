"""Monte Carlo runs on one diagram: the campaign's scene is built once per process, and each run is a new
context with its dispersions applied (no YAML parse, no scene build, no engine compilation per run).

Run ``i`` is defined as the scenario with ``--set`` overrides (:meth:`Campaign.overrides`); this module
produces the same run without rebuilding, by applying each dispersed value where the rebuilt scene
would have it, through the same code that builds a scene:

* a parameter, rate, period, offset, config or initial value of a model of the ``models:`` section:
  the model is constructed again from its entry with the run's values (:func:`shell.scenario.build_member`,
  the scenario builder's own function), checked to have the same layout as the diagram's model (same
  class, parameters, ports, states, noise), and the run's context takes its packed parameters, initial
  states, sample period and offset;
* the mass, center of mass or inertia of a rigid body of ``multibody:``: the context's private engine
  system gets them with ``MultibodySystem.set_mass_properties`` (parsed by the same function as at build);
* a body's ``initial:`` state: the engine's initial (q, u) recomputed from the run's entries;
* ``seed``: the context's random streams.

Anything else (integrator, stop, log, a body file, a hinge, wiring, the type of a model, members of
assemblies) changes the scene's structure, and so do models whose update is Python (``python_update``:
user flight software keeps its own state between calls, which must not leak from one run into the next):
such a campaign rebuilds the scene for every run, as before, and says so once. Tests check that both
ways give the same table bit for bit.
"""

from __future__ import annotations

import copy

import numpy as np

from shell.diagram import Diagram
from shell.model import Model
from shell.scenario import ScenarioError, apply_value, build_member, build_root, parse_scenario
from shell.schema import Where
from shell.schema.multibody import body_entries, initial_state, rigid_mass_properties


class Structural(Exception):
    """A dispersion the context of an existing diagram cannot take; the message says why."""


def _layout_key(m: Model):
    def decl(d):
        return (d.name, tuple(d.shape), str(getattr(d, "unit", "")))

    return (type(m), tuple(decl(p) for p in m.parameters), tuple(decl(p) for p in m.inputs),
            tuple(decl(p) for p in m.outputs), tuple(decl(s) for s in m.continuous_states),
            tuple(decl(s) for s in m.discrete_states), tuple(z.name for z in m.zero_crossings), int(m.noise_size),
            m.period is None)


class SceneReuse:
    """The nominal scene of a campaign and the way each run's dispersions enter a fresh context."""

    def __init__(self, campaign):
        self.campaign = campaign
        self.scenario = parse_scenario(campaign.scenario_text, campaign.scenario_file, campaign.base_overrides)
        document = self.scenario.document
        models = document.get("models", {}) or {}
        self.targets = {}
        for d in campaign.dispersions:
            self.targets[d.path] = self._classify(d.path, document, models)
        root = build_root(self.scenario)
        self.diagram = Diagram(root, stop_events=self.scenario.stop_events)
        python = [m.path for m in self.diagram.models if getattr(m, "python_update", False)]
        if python:
            raise Structural(f"models {python} run Python updates (their own state must not carry from one run "
                             "to the next)")
        self.engine_index = next((i for i, m in enumerate(self.diagram.models) if hasattr(m, "system")
                                  and m.path == document.get("multibody", {}).get("name", "multibody")), None)

    def _classify(self, path: str, document: dict, models: dict) -> tuple:
        parts = path.split(".")
        if parts[0] == "multibody" and len(parts) >= 3 and "multibody" in document:
            bodies = {b.get("name"): b for b in document["multibody"].get("bodies", []) or [] if isinstance(b, dict)}
            body = bodies.get(parts[1])
            if body is None:
                raise Structural(f"{path}: not a body of multibody (a node, or unknown)")
            if parts[2] in ("mass", "com", "inertia") and len(parts) == 3 and "body_file" not in body:
                return ("engine", "mass", parts[1])
            if parts[2] == "initial":
                return ("engine", "initial", parts[1])
            raise Structural(f"{path}: changes the engine's structure")
        if parts[0] in models and len(parts) >= 2:
            if parts[1] == "type":
                raise Structural(f"{path}: changes a model's type")
            return ("model", parts[0])
        raise Structural(f"{path}: not a model parameter, rate or initial value, nor a rigid body's mass "
                         "properties or initial state")

    def simulation(self, run: int, draws: dict):
        """The Simulation of run ``run`` (a new context of the shared diagram), logging the campaign's
        signals."""
        from shell.simulation import Simulation

        campaign, diagram, scenario = self.campaign, self.diagram, self.scenario
        context = diagram.create_context(seed=[campaign.seed, int(run)], own_data=True)
        assignments = {}
        for key, value in campaign.dispersed_values(run, draws):
            if key in self.targets:
                assignments.setdefault(self.targets[key][:2] if self.targets[key][0] == "engine"
                                       else self.targets[key], []).append((key, value))
        engine_items = [item for key, items in assignments.items() if key[0] == "engine" for item in items]
        if engine_items:
            self._apply_engine(context, engine_items)
        for key, items in assignments.items():
            if key[0] == "model":
                self._apply_model(context, key[1], items)
        simulation = Simulation(None, integrator=scenario.integrator, step=scenario.step,
                                integrator_options=scenario.integrator_options, seed=context.seed,
                                event_tol=scenario.event_tolerance, event_detection=scenario.event_detection,
                                diagram=diagram, context=context)
        for name, rate, _ in scenario.log_signals:
            simulation.log([name], rate)
        rate = campaign.log_rate or scenario.log_rate or "10 Hz"
        logged = {name for name, _, _ in scenario.log_signals}
        for signal in campaign.signals:
            if signal not in logged:
                simulation.log([signal], rate)
        return scenario, simulation

    def _apply_model(self, context, name: str, items: list[tuple[str, object]]) -> None:
        document = self.scenario.document
        entry = copy.deepcopy(document["models"][name])
        mini = {"models": {name: entry}}
        for key, value in items:
            apply_value(mini, key, value, self.scenario.file)
        where = Where(self.scenario.file, 1, "").child(document, "models").child(document["models"], name)
        fresh = build_member(self.diagram.root, name, mini["models"][name], where, self.scenario.template_classes)
        i = self.diagram.model_index.get(name)
        if i is None or not isinstance(fresh, Model):
            raise Structural(f"{name}: not a model of the diagram")
        model = self.diagram.models[i]
        if _layout_key(fresh) != _layout_key(model):
            raise Structural(f"{name}: the run's values change the model's layout (ports, states or parameters)")
        d = self.diagram
        context.p[d.p_block[i]] = fresh.p
        context.x[d.x_block[i]] = fresh.initial_continuous_state()
        context.z[d.z_block[i]] = fresh.initial_discrete_state()
        context.periods[i], context.offsets[i] = fresh.period, fresh.offset
        context.next_sample[i] = d.first_sample(fresh.period, fresh.offset, context.t)

    def _apply_engine(self, context, items: list[tuple[str, object]]) -> None:
        if self.engine_index is None:
            raise Structural("no engine model to disperse")
        document = self.scenario.document
        mini = {"multibody": copy.deepcopy(document["multibody"])}
        for key, value in items:
            apply_value(mini, key, value, self.scenario.file)
        description = mini["multibody"]
        where = Where(self.scenario.file, 1, "").child(document, "multibody")
        system = context.hosts[self.engine_index]
        entries = body_entries(description, where)
        nominal = {b.get("name"): b for b, _ in body_entries(document["multibody"], where)}
        for body, here in entries:
            old = nominal[body.get("name")]
            if "body_file" not in body and any(old.get(k) != body.get(k) for k in ("mass", "com", "inertia")):
                mass, com, inertia = rigid_mass_properties(body, here)
                system.set_mass_properties(body["name"], mass, com, inertia)
        q0, u0 = initial_state(system, [(body.get("initial"), here, body) for body, here in entries])
        block = self.diagram.x_block[self.engine_index]
        context.x[block] = np.concatenate([q0, u0])


_CACHE: dict = {}


def scene_for(campaign):
    """The process's :class:`SceneReuse` of ``campaign`` (built on first use), or the reason the
    campaign's runs must rebuild the scene (a string)."""
    key = campaign.fingerprint
    if key not in _CACHE:
        try:
            _CACHE.clear()  # one campaign per process at a time
            _CACHE[key] = SceneReuse(campaign)
        except (Structural, ScenarioError) as exc:
            _CACHE[key] = str(exc)
    return _CACHE[key]
