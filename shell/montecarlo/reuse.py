"""Monte Carlo runs on one diagram: the campaign's scene is built once per process, and each run is a new
context with its dispersed values written by name (:mod:`shell.names`): no YAML, no scene build, no model
construction, no engine compilation per run.

Run ``i`` is defined as the scenario with ``--set`` overrides (:meth:`Campaign.overrides`); this module
produces the same run without building it: every dispersion names a value of the scene's
:class:`shell.names.NameIndex` (a model parameter, state or sample rate, a rigid body's mass properties or a
body's initial value), and the run's Context takes the drawn value converted as the scene's builder converts
it (same functions, same arithmetic). A parameter that a model's ``configure`` reads, and a sample rate, build
that one model again from its constructor's arguments (remembered per value: a choice of rates costs one
construction per choice and process).

Anything else (integrator, stop, log, a body file, a hinge, wiring, the type or configuration of a model,
parameters of assemblies, states and rates of assembly members, which ``--set`` cannot reach) changes the
scene's structure, and so do models whose update is Python (``python_update``: user flight software keeps its
own state between calls, which must not leak from one run into the next): such a campaign builds the scene
from its overrides for every run, as before, and says so once. Tests check that both ways give the same
table bit for bit.
"""

from __future__ import annotations

from shell.diagram import Diagram
from shell.names import StructuralChange
from shell.scenario import ScenarioError, build_root, parse_scenario


class SceneReuse:
    """The nominal scene of a campaign and the way each run's dispersions enter a fresh context."""

    def __init__(self, campaign):
        self.campaign = campaign
        self.scenario = parse_scenario(campaign.scenario_text, campaign.scenario_file, campaign.base_overrides)
        self.diagram = Diagram(build_root(self.scenario), stop_events=self.scenario.stop_events)
        python = [m.path for m in self.diagram.models if getattr(m, "python_update", False)]
        if python:
            raise StructuralChange(f"models {python} run Python updates (their own state must not carry from one run "
                                   "to the next)")
        for d in campaign.dispersions:
            self._check_path(d.path)

    def _check_path(self, path: str) -> None:
        """Refuse (StructuralChange) a dispersion whose ``--set`` path is not a value of the scene by name, or means
        another one: ``--set`` reaches the parameters of models and of assembly members, the rate, period, offset
        and ``initial.<state>`` of the scenario's own models, and the bodies of its ``multibody:`` section."""
        entry = self.diagram.names.find(path)
        if entry is None:
            raise StructuralChange(f"{path}: not a model parameter, state or sample rate, nor a rigid body's mass "
                                   "properties or a body's initial value")
        model = self.diagram.models[entry.model]
        own = model.path in (self.scenario.document.get("models") or {})
        if entry.kind == "model" and not path.startswith("multibody."):
            raise StructuralChange(f"{path}: --set reaches the engine's bodies as multibody.<body>")
        if (entry.kind in ("schedule", "x", "z") or ".parameters." in path) and not own:
            raise StructuralChange(f"{path}: a state or rate of a model that is not an entry of models:")
        if entry.kind in ("x", "z") and ".initial." not in path:
            raise StructuralChange(f"{path}: --set reads a model's states as <model>.initial.<state>")

    def simulation(self, run: int, draws: dict):
        """The Simulation of run ``run`` (a new context of the shared diagram), logging the campaign's signals."""
        from shell.simulation import Simulation

        campaign = self.campaign
        context = self.diagram.create_context(seed=[campaign.seed, int(run)], own_data=True)
        context.assign(campaign.dispersed_values(run, draws))
        simulation = Simulation.of_scenario(self.scenario, diagram=self.diagram, context=context)
        campaign.log_signals(simulation, self.scenario)
        return self.scenario, simulation


_CACHE: dict = {}


def scene_for(campaign):
    """The process's :class:`SceneReuse` of ``campaign`` (built on first use), or the reason the
    campaign's runs must rebuild the scene (a string)."""
    key = campaign.fingerprint
    if key not in _CACHE:
        try:
            _CACHE.clear()  # one campaign per process at a time
            _CACHE[key] = SceneReuse(campaign)
        except (StructuralChange, ScenarioError) as exc:
            _CACHE[key] = str(exc)
    return _CACHE[key]
