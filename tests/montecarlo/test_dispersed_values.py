"""A run of a reused scene takes its dispersed values by name (shell.names: Context.assign), not as --set text
parsed into a rebuilt scene: the context must hold exactly what the scene built from that text holds (same bits),
for every kind of value a dispersion produces, including the awkward ones (exponents without a '.', -0.0,
subnormal numbers, another unit, choices written as text, rates), and refuse what the text's scene refuses."""

import numpy as np
import pytest

from shell.diagram import Diagram
from shell.model import ModelError, parse_period
from shell.montecarlo.campaign import yaml_text
from shell.scenario import ScenarioError, build_root, parse_scenario

SCENE = """
models:
  c: {type: Constant, config: {unit: N*m/rad, shape: [3]}, parameters: {value: "[10, 7.5, 6.25] N*m/rad"}}
  hold: {type: SampleHold, rate: 10 Hz, config: {unit: N*m/rad, shape: [3]}, initial: {samples: 2}}
connections:
  - c.y -> hold.u
"""

VALUES = [  # (name, value as a dispersion gives it)
    ("c.value", {"value": np.array([400.00000000000006, 1e-05, -0.0]), "unit": "N*m/rad"}),
    ("c.value", {"value": np.array([2.5e-300, 5e-324, 1.0e22]), "unit": "N*m/rad"}),
    ("c.value", {"value": np.array([1.0, 2.5, -3.75]), "unit": "mN*m/deg"}),
    ("c.value", "[1, 2, 3] N*m/deg"),
    ("c.value", [4.0, 5.0, 6.0]),
    ("c.parameters.value", {"value": np.array([0.1, 0.2, 0.3]), "unit": "N*m/rad"}),
    ("hold.rate", "5 Hz"),
    ("hold.period", "0.3 s"),
    ("hold.initial.samples", {"value": 7.0, "unit": ""}),
    ("hold.initial.held", {"value": np.array([1e-5, -0.0, 3.0]), "unit": "N*m/mrad"}),
]


def _text_scene(name, value):
    """The context of the scene built from the --set text of ``name=value``."""
    scenario = parse_scenario(SCENE, "scene.yaml", [f"{name}={yaml_text(value)}"])
    return Diagram(build_root(scenario)).create_context()


def test_values_by_name_equal_the_scene_built_from_their_text():
    nominal = Diagram(build_root(parse_scenario(SCENE, "scene.yaml")))
    for name, value in VALUES:
        expected = _text_scene(name, value)
        context = nominal.create_context()
        context.set(name, value)
        for array in ("p", "x", "z"):
            assert getattr(context, array).tobytes() == getattr(expected, array).tobytes(), (name, value, array)
        assert (context.periods, context.offsets, context.next_sample) == \
            (expected.periods, expected.offsets, expected.next_sample), (name, value)


def test_values_the_text_scene_refuses_are_refused_by_name():
    nominal = Diagram(build_root(parse_scenario(SCENE, "scene.yaml")))
    for name, value in [("c.value", {"value": np.array([np.nan, 1.0, 2.0]), "unit": "N*m/rad"}),
                        ("c.value", {"value": np.array([1.0, 2.0]), "unit": "N*m/rad"}),
                        ("c.value", {"value": np.array([1.0, 2.0, 3.0]), "unit": "m"}),
                        ("hold.rate", "0 Hz")]:
        with pytest.raises((ScenarioError, ModelError)):
            _text_scene(name, value)
        with pytest.raises(ModelError, match=name.split(".")[0]):
            nominal.create_context().set(name, value)


def test_a_started_run_refuses_initial_values_and_unknown_names_get_a_suggestion():
    nominal = Diagram(build_root(parse_scenario(SCENE, "scene.yaml")))
    context = nominal.create_context()
    context.unstarted = False
    with pytest.raises(ModelError, match="before its run starts"):
        context.set("hold.rate", "5 Hz")
    with pytest.raises(ModelError, match="did you mean 'c.value'"):
        context.set("c.valeu", 1.0)


def test_period_text_remembered_gives_the_same_fraction_and_still_refuses_bad_text():
    for text in ("10 Hz", "0.1 s", "1 kHz", "3 ms"):
        assert parse_period(text, "x") == parse_period(text, "y")
    import pytest

    from shell.model import ModelError
    with pytest.raises(ModelError, match="rate.x: a sample period must be positive"):
        parse_period("-1 s", "rate.x")
    with pytest.raises(ModelError, match="rate.y: a sample period must be positive"):
        parse_period("-1 s", "rate.y")  # remembered text still refused, naming the new place
