"""Hypothesis fuzzing of scenarios and --set (issue 17): whatever the input, loading and building a scene
raises nothing but flexshell's own errors (no TypeError, RecursionError, OverflowError, ...), and every
refusal of the loader names the file.

The default run tries a few hundred inputs of each kind; ``-m slow`` tries thousands.
"""

import copy
import math

import pytest
import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from shell.model import ModelError
from shell.scenario import ScenarioError, build_simulation, parse_scenario
from shell.units import UnitError
from tests.safety.conftest import RAMP

#: the project's own errors (ScenarioError and UnitError and ModelError are ValueErrors, but a bare
#: ValueError, TypeError or KeyError escaping is a bug)
PROJECT_ERRORS = (ScenarioError, ModelError, UnitError)
BASE = yaml.safe_load(RAMP)

numbers = st.one_of(st.integers(min_value=-10**30, max_value=10**30), st.floats(allow_nan=True, allow_infinity=True),
                    st.sampled_from([0, -1, 1e-300, 1e300, 10**20]))
units = st.sampled_from(["", "s", "ms", "Hz", "kHz", "m", "m/s", "kg", "deg", "N*m", "rad/s", "1/s", "degC", "%",
                         "furlong", "s^-1", "**", "(", "Hz Hz", "/"])
quantities = st.builds(lambda n, u: f"{n} {u}".strip(), numbers, units)
junk_text = st.text(st.characters(codec="utf-8", exclude_categories=("Cs",)), max_size=20)
scalars = st.one_of(numbers, quantities, junk_text, st.booleans(), st.none(),
                    st.sampled_from(["rk4", "[1, 2, 3] m", "[[[", "]]", ".inf", ".nan", "1e999 s", "-0 s", "{a: 1}",
                                     "sensor.y", "a -> b", "rate.y -> position.u", "10", "1e12 Hz", "nan s"]))
values = st.recursive(scalars, lambda inner: st.one_of(st.lists(inner, max_size=4),
                                                       st.dictionaries(st.one_of(junk_text, st.sampled_from(
                                                           ["type", "rate", "period", "time", "step", "method",
                                                            "signals", "file", "initial", "x", "value"])), inner,
                                                           max_size=3)), max_leaves=8)


def paths(document, prefix=()):
    """Every key path of a nested document (mappings and lists)."""
    yield prefix
    if isinstance(document, dict):
        for key, value in document.items():
            yield from paths(value, prefix + (key,))
    elif isinstance(document, list):
        for k, value in enumerate(document):
            yield from paths(value, prefix + (k,))


ALL_PATHS = [p for p in paths(BASE) if p]


@st.composite
def mutated_scenarios(draw):
    """The ramp scene with a few values replaced, keys removed or added (then written as YAML)."""
    document = copy.deepcopy(BASE)
    for _ in range(draw(st.integers(1, 3))):
        path = draw(st.sampled_from(ALL_PATHS))
        container = document
        try:
            for key in path[:-1]:
                container = container[key]
            action = draw(st.sampled_from(["replace", "replace", "delete", "add"]))
            if action == "replace":
                container[path[-1]] = draw(values)
            elif action == "delete":
                del container[path[-1]]
            elif isinstance(container, dict):
                container[draw(st.one_of(junk_text, st.sampled_from(["rate", "period", "offset", "events"])))] = \
                    draw(values)
        except (KeyError, IndexError, TypeError):  # an earlier mutation changed this path's containers
            continue
    return yaml.safe_dump(document, allow_unicode=True, sort_keys=False)


@st.composite
def edited_texts(draw):
    """The ramp scene's text with a few characters or lines inserted, removed or replaced."""
    text = RAMP
    for _ in range(draw(st.integers(1, 4))):
        at = draw(st.integers(0, len(text)))
        kind = draw(st.sampled_from(["insert", "delete", "line"]))
        if kind == "insert":
            piece = draw(st.one_of(junk_text, st.sampled_from(["[", "{", "&a ", "*a", ": ", "\t", "- ", "\n  ", "'",
                                                               '"', "!!python/object ", "<<: *a\n"])))
            text = text[:at] + piece + text[at:]
        elif kind == "delete":
            text = text[:at] + text[at + draw(st.integers(1, 10)):]
        else:
            lines = text.splitlines()
            if not lines:
                continue
            line = draw(st.integers(0, len(lines) - 1))
            key = lines[line].split(":")[0]
            lines[line] = f"{key}: {yaml.safe_dump(draw(values), default_flow_style=True).strip()}"
            text = "\n".join(lines) + "\n"
    return text


SECTIONS = ["seed", "name", "integrator.method", "integrator.step", "integrator.options.rtol", "stop.time",
            "stop.events", "log.rate", "log.signals", "log.file", "events.detection", "events.tolerance",
            "sensor.rate", "sensor.period", "sensor.offset", "sensor.sigma", "sensor.parameters.sigma",
            "rate.value", "rate.type", "position.initial.x", "position.config.unit", "multibody.bus.mass",
            "nothere.x", "log.signals.x", "integrator.method.x", "stop", "", "."]
overrides = st.builds(lambda key, extra, value: f"{key}{extra}={value}",
                      st.sampled_from(SECTIONS), st.sampled_from(["", ".x", ".0", "..", ".rate"]),
                      st.one_of(junk_text, quantities, st.builds(lambda v: yaml.safe_dump(
                          v, default_flow_style=True).strip(), values)))
equals_free = st.text(max_size=30).filter(lambda s: "=" not in s)


def load_and_build(text, overrides=()):
    """Load and build; refusals must be the project's errors, and the loader's name the file."""
    try:
        scenario = parse_scenario(text, "fuzz.yaml", list(overrides))
    except ScenarioError as exc:
        assert str(exc).startswith("fuzz.yaml"), str(exc)
        assert len(str(exc)) < 3000, "values in messages are cut short"
        return
    try:
        build_simulation(scenario)
    except PROJECT_ERRORS:
        pass


FAST = settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow,
                                                                         HealthCheck.data_too_large])
SLOW = settings(max_examples=3000, deadline=None, suppress_health_check=[HealthCheck.too_slow,
                                                                          HealthCheck.data_too_large])


@FAST
@given(mutated_scenarios())
def test_mutated_scenarios(text):
    load_and_build(text)


@FAST
@given(edited_texts())
def test_edited_scenario_texts(text):
    load_and_build(text)


@FAST
@given(st.lists(st.one_of(overrides, equals_free), min_size=1, max_size=3))
def test_overrides(items):
    load_and_build(RAMP, items)


@pytest.mark.slow
@SLOW
@given(mutated_scenarios())
def test_mutated_scenarios_slow(text):
    load_and_build(text)


@pytest.mark.slow
@SLOW
@given(edited_texts())
def test_edited_scenario_texts_slow(text):
    load_and_build(text)


@pytest.mark.slow
@SLOW
@given(st.lists(st.one_of(overrides, equals_free), min_size=1, max_size=3))
def test_overrides_slow(items):
    load_and_build(RAMP, items)


def test_the_unmutated_scene_builds():
    """The fuzzers start from a scene that loads and builds (else they would test only refusals)."""
    scenario = parse_scenario(RAMP, "fuzz.yaml")
    assert math.isclose(scenario.t_final, 2.0)
    build_simulation(scenario)


# ------------------------------------------------------------------------------------------------
# campaign files (read and validated against the scenario's text; not built: validate=False)
CAMPAIGN = {"name": "ramp_campaign", "scenario": "scene.yaml", "runs": 4, "seed": 7, "timeout": "10 s",
            "set": {"stop.time": "3 s"},
            "dispersions": {"rate.value": {"distribution": "normal", "mean": "100 cm/s", "sigma": "10 cm/s"},
                            "sensor.sigma": {"distribution": "uniform", "low": "1 mm", "high": "5 mm"},
                            "sensor.rate": {"distribution": "choice", "choices": ["10 Hz", "20 Hz"],
                                            "probabilities": [0.5, 0.5]}},
            "correlations": [{"between": ["rate.value", "sensor.sigma"], "coefficient": 0.3}],
            "metrics": {"final_position": {"signal": "sensor.y", "statistic": "final", "unit": "m"},
                        "settle": {"signal": "sensor.y", "statistic": "settling_time", "tolerance": "1 cm",
                                   "target": "2 m"}},
            "keep": ["sensor.y"]}
CAMPAIGN_PATHS = [p for p in paths(CAMPAIGN) if p]


@st.composite
def mutated_campaigns(draw):
    document = copy.deepcopy(CAMPAIGN)
    for _ in range(draw(st.integers(1, 3))):
        path = draw(st.sampled_from(CAMPAIGN_PATHS))
        container = document
        try:
            for key in path[:-1]:
                container = container[key]
            if draw(st.booleans()):
                container[path[-1]] = draw(values)
            else:
                del container[path[-1]]
        except (KeyError, IndexError, TypeError):
            continue
    return yaml.safe_dump(document, allow_unicode=True, sort_keys=False)


@pytest.fixture(scope="module")
def campaign_dir(tmp_path_factory):
    directory = tmp_path_factory.mktemp("campaign")
    (directory / "scene.yaml").write_text(RAMP)
    return directory


def check_campaign(text, directory):
    from shell.montecarlo.campaign import parse_campaign

    filename = str(directory / "campaign.yaml")
    try:
        parse_campaign(text, filename, validate=False)
    except ScenarioError as exc:  # CampaignError is a ScenarioError
        assert str(exc).startswith(filename), str(exc)


@FAST
@given(text=mutated_campaigns())
def test_mutated_campaigns(text, campaign_dir):
    check_campaign(text, campaign_dir)


@pytest.mark.slow
@SLOW
@given(text=mutated_campaigns())
def test_mutated_campaigns_slow(text, campaign_dir):
    check_campaign(text, campaign_dir)


def test_the_unmutated_campaign_parses(campaign_dir):
    from shell.montecarlo.campaign import parse_campaign

    campaign = parse_campaign(yaml.safe_dump(CAMPAIGN), str(campaign_dir / "campaign.yaml"), validate=False)
    assert campaign.runs == 4 and len(campaign.groups) == 1 and len(campaign.metrics) == 2
