"""Build-time refusals (issue 5 'Must show'): each names the offending model/port and what was expected."""

import numpy as np
import pytest

from shell.assembly import Assembly
from shell.model import ModelError
from shell.models.blocks import Constant, Gain, Integrator
from shell.scenario import ScenarioError
from shell.simulation import AlgebraicLoopError, Simulation, WiringError


def test_unknown_model_type(scene):
    with pytest.raises(ScenarioError, match=r"scene.yaml:3: models.c.type: unknown model type 'Constnt'; "
                                            r"did you mean Constant\?"):
        scene("""
        models:
          c: {type: Constnt}
        """)


def test_unknown_model_in_a_connection_or_log(scene):
    with pytest.raises(ScenarioError, match=r"scene.yaml:5: connection a.y -> integ.u: input 'integ.u': the scene "
                                            r"has no member 'integ'; members: \['a', 'i'\]"):
        scene("""
        models:
          a: {type: Constant, config: {unit: 1/s}}
          i: {type: Integrator}
        connections: [a.y -> integ.u]
        """)
    with pytest.raises(ScenarioError, match=r"scene.yaml:7: log.signals\[0\]: signal 'b.y': no model path is a "
                                            r"prefix of it; models: \['a', 'i'\]"):
        scene("""
        models:
          a: {type: Constant, config: {unit: 1/s}}
          i: {type: Integrator}
        connections: [a.y -> i.u]
        log:
          signals: [b.y]
        """)


def test_unknown_parameter(scene):
    with pytest.raises(ScenarioError) as info:
        scene("""
        models:
          c:
            type: Constant
            parameters:
              value: 1.0
              gian: 2.0
        """)
    message = str(info.value)
    assert message.startswith("scene.yaml:7: models.c.parameters.gian:")
    assert "unknown parameter(s) ['gian'] for Constant; known: ['value']" in message


def test_wrong_unit_dimension_of_a_parameter(scene):
    with pytest.raises(ScenarioError, match=r"scene.yaml:6: models.c.parameters.value: .*kg .*cannot become deg/s"):
        scene("""
        models:
          c:
            type: Constant
            config: {unit: deg/s}
            parameters: {value: 5 kg}
        """)


def test_wrong_unit_dimension_of_a_connection_names_both_ends(scene):
    with pytest.raises(ScenarioError) as info:
        scene("""
        models:
          rate: {type: Constant, config: {unit: deg/s}, parameters: {value: 1 deg/s}}
          pos: {type: Integrator, config: {unit: m}}
        connections:
          - rate.y -> pos.u
        """)
    message = str(info.value)
    assert "scene.yaml:6: connection rate.y -> pos.u" in message
    assert "output unit deg/s, input unit m/s" in message


def test_unit_conversion_factor_is_applied_at_build_time():
    root = Assembly("root")
    root.add(Constant("rate", unit="deg/s", value="90 deg/s"))
    root.add(Integrator("angle", unit="rad"))
    root.connect("rate.y", "angle.u")
    sim = Simulation(root, step=0.1)
    sim.run(1.0)
    # x' = pi/2 rad/s exactly after the deg/s -> rad/s factor; RK4 integrates a constant exactly
    assert sim.signal("angle.x") == pytest.approx(np.pi / 2, rel=1e-14)


def test_wrong_shape(scene):
    with pytest.raises(ScenarioError, match=r"connection v3.y -> s2.u: shape mismatch: output has shape "
                                            r"\(3,\), input expects \(2,\)"):
        scene("""
        models:
          v3: {type: Constant, config: {shape: [3]}, parameters: {value: [1, 2, 3]}}
          s2: {type: Integrator, config: {shape: [2]}}
        connections:
          - v3.y -> s2.u
        """)


def test_wrong_shape_of_a_parameter(scene):
    with pytest.raises(ScenarioError, match=r"scene.yaml:3: models.v3.parameters.value: .*expected shape \(3,\), "
                                            r"given shape \(2,\)"):
        scene("""
        models:
          v3: {type: Constant, config: {shape: [3]}, parameters: {value: [1, 2]}}
        """)


def test_unconnected_required_input(scene):
    with pytest.raises(ScenarioError, match=r"unconnected required input\(s\): i.u \(1/s, shape \(\)"):
        scene("""
        models:
          i: {type: Integrator}
        """)


def test_port_driven_twice(scene):
    with pytest.raises(ScenarioError, match=r"input i.u is driven twice: by a.y \(scene.yaml:7\) and by b.y "
                                            r"\(scene.yaml:8\)"):
        scene("""
        models:
          a: {type: Constant, config: {unit: 1/s}}
          b: {type: Constant, config: {unit: 1/s}}
          i: {type: Integrator}
        connections:
          - a.y -> i.u
          - b.y -> i.u
        """)


def test_algebraic_loop_names_the_models():
    root = Assembly("root")
    for name in ("first", "second", "third"):
        root.add(Gain(name))
    root.connect("first.y", "second.u")
    root.connect("second.y", "third.u")
    root.connect("third.y", "first.u")
    with pytest.raises(AlgebraicLoopError) as info:
        Simulation(root)
    message = str(info.value)
    assert "algebraic loop through models" in message
    for name in ("first", "second", "third"):
        assert f"{name}.y ->" in message


def test_loop_broken_by_a_state_is_accepted():
    root = Assembly("root")
    root.add(Gain("feedback", output_unit="1/s", k="-2 1/s"))
    root.add(Integrator("x"))
    root.connect("x.y", "feedback.u")
    root.connect("feedback.y", "x.u")
    root.children["x"].set_initial("x", 1.0)
    sim = Simulation(root, step=0.001)
    sim.run(1.0)
    # x' = -2 x: x(1) = exp(-2); RK4 with h = 1e-3 has global error ~ h^4 = 1e-12
    assert sim.signal("x.x") == pytest.approx(np.exp(-2.0), rel=1e-11)


def test_unknown_port_and_output_used_as_input(scene):
    with pytest.raises(ScenarioError, match=r"scene.yaml:6: connection a.y -> i.y: input i.y: an output of "
                                            r"Integrator; inputs: \['u'\]"):
        scene("""
        models:
          a: {type: Constant, config: {unit: 1/s}}
          i: {type: Integrator}
        connections:
          - a.y -> i.y
        """)


def test_parameter_out_of_bounds():
    from tests.plants import BouncingBall

    with pytest.raises(ModelError, match=r"parameter restitution: expected within \[0.0, 1.0\]"):
        BouncingBall("ball", restitution=1.5)


def test_a_scene_serves_one_simulation():
    root = Assembly("root")
    root.add(Constant("a", unit="1/s"))
    root.add(Integrator("i"))
    root.connect("a.y", "i.u")
    first = Simulation(root)
    with pytest.raises(ModelError, match="model a already belongs to another Simulation"):
        Simulation(root)
    del first  # once the first simulation is gone its models may be reused
    Simulation(root)


def test_driven_twice_in_python_names_the_assembly():
    root = Assembly("root")
    root.add(Constant("a", unit="1/s"))
    root.add(Integrator("i"))
    root.connect("a.y", "i.u")
    root.connect("a.y", "i.u")
    with pytest.raises(WiringError, match="driven twice"):
        Simulation(root)


def test_a_name_used_for_an_input_and_an_output_is_refused():
    """`model.name` addresses one port in connections and logs; a model declaring an input and an output
    of the same name had one of them silently shadowed (found with the star tracker's `attitude`)."""
    from shell.model import InputPort, Model, OutputPort

    class Echo(Model):
        inputs = (InputPort("attitude", "", (4,), "in"),)
        outputs = (OutputPort("attitude", "", (4,), "out"),)

    with pytest.raises(ModelError, match=r"\['attitude'\] declared both as input and as output"):
        Echo("echo")
