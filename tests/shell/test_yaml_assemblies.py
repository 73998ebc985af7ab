"""Assembly types defined in a scenario's assemblies: section: reuse, exposure, overrides, refusals."""

import numpy as np
import pytest

from shell.scenario import ScenarioError

SCENE = """
assemblies:
  Axis:                               # one integrator chain: rate in, angle and its sample out
    description: rate integrator with a sampled readout
    models:
      angle: {type: Integrator, config: {unit: rad}}
      readout: {type: SampleHold, rate: 10 Hz, config: {unit: rad}}
    connections:
      - angle.y -> readout.u
    inputs: {rate: angle.u}
    outputs: {angle: angle.y, sample: readout.y}
  TwoAxes:                            # an assembly of assemblies, one input fanned out to both
    models:
      fast: {type: Axis}
      slow: {type: Axis, parameters: {readout.rate_unused: 1}}
    inputs: {rate: [fast.rate, slow.rate]}
    outputs: {fast_sample: fast.sample}
models:
  spin: {type: Constant, config: {unit: deg/s}, parameters: {value: 90 deg/s}}
  gimbal: {type: TwoAxes}
connections:
  - spin.y -> gimbal.rate
"""


def test_yaml_assembly_types_nest_expose_and_run(scene):
    sim = scene(SCENE.replace("      slow: {type: Axis, parameters: {readout.rate_unused: 1}}\n",
                              "      slow: {type: Axis}\n"))
    assert [m.path for m in sim.models] == ["spin", "gimbal.fast.angle", "gimbal.fast.readout",
                                            "gimbal.slow.angle", "gimbal.slow.readout"]
    sim.run(1.05)
    assert sim.signal("gimbal.slow.angle.y") == pytest.approx(np.pi / 2 * 1.05, rel=1e-14)
    assert sim.signal("gimbal.fast.readout.y") == pytest.approx(np.pi / 2, rel=1e-14)  # sampled at 1.0 s


def test_member_parameter_overrides_are_checked(scene):
    with pytest.raises(ScenarioError) as info:
        scene(SCENE)
    # the member's definition line and the line where the override was given
    assert str(info.value).splitlines() == [
        "scene.yaml:7: assemblies.Axis.models.readout: model readout: unknown parameter(s) ['rate_unused'] for "
        "SampleHold; known: none",
        "  in Axis 'slow' used at scene.yaml:15",
        "  in TwoAxes 'gimbal' used at scene.yaml:20"]


def test_yaml_assembly_refusals(scene):
    with pytest.raises(ScenarioError, match=r"scene.yaml:2: assemblies: assemblies contain themselves: Loop -> Loop"):
        scene("""
        assemblies:
          Loop:
            models:
              inner: {type: Loop}
        """)
    with pytest.raises(ScenarioError, match=r"scene.yaml:3: assemblies.Gain: 'Gain' is already a registered model type"):
        scene("""
        assemblies:
          Gain:
            models: {}
        """)
    with pytest.raises(ScenarioError, match=r"scene.yaml:6: assemblies.A.models.c.attach: attach the assembly 'A' "
                                            r"where it is used"):
        scene("""
        assemblies:
          A:
            models:
              c: {type: Constant,
                  attach: {node: acs}}
        """)
