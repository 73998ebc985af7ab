"""Sum block: y = u_1 + ... + u_n against numpy for several counts and shapes, unit conversion and refusals
through a YAML scene."""

import textwrap

import numpy as np
import pytest
from numpy.testing import assert_allclose

from shell.log_file import read_log
from shell.model import ModelError
from shell.models.blocks import Sum
from shell.scenario import ScenarioError, build_simulation, parse_scenario


@pytest.mark.parametrize("count, shape", [(1, ()), (2, (3,)), (4, (3,)), (3, (2, 2))])
def test_sum_equals_numpy(count, shape):
    block = Sum("s", count=count, shape=shape)
    assert [p.name for p in block.inputs] == [f"u_{k}" for k in range(1, count + 1)]
    terms = np.random.default_rng(count).normal(size=(count,) + shape)
    y = np.zeros(int(np.prod(shape)))
    block.feedthrough_outputs(0.0, None, None, terms.reshape(-1), block.p, y)
    assert_allclose(y, terms.sum(axis=0).reshape(-1), rtol=1e-15, atol=1e-15)


SCENE = """
models:
  a: {type: Constant, config: {unit: N*m*s, shape: [3]}, parameters: {value: "[1, 2, 3] N*m*s"}}
  b: {type: Constant, config: {unit: g*m^2/s, shape: [3]}, parameters: {value: "[1000, 0, -500] g*m^2/s"}}
  total: {type: Sum, config: {count: 2, unit: N*m*s, shape: [3]}}
connections: [a.y -> total.u_1, b.y -> total.u_2]
integrator: {method: rk4, step: 0.1 s}
log: {rate: 10 Hz, signals: [total.y]}
"""


def test_sum_in_a_scene_converts_units_and_refuses_a_wrong_one(tmp_path):
    sim = build_simulation(parse_scenario(textwrap.dedent(SCENE), "sum.yaml", None))
    sim.run(0.2, log_path=tmp_path / "sum.h5")
    assert_allclose(read_log(tmp_path / "sum.h5")["total.y"][-1], [2.0, 2.0, 2.5], rtol=1e-14)
    wrong = SCENE.replace("{unit: g*m^2/s, shape: [3]}, parameters: {value: \"[1000, 0, -500] g*m^2/s\"}",
                          "{unit: N*m, shape: [3]}, parameters: {value: \"[1, 0, 0] N*m\"}")
    with pytest.raises(ScenarioError, match="total.u_2"):
        build_simulation(parse_scenario(textwrap.dedent(wrong), "sum.yaml", None))
    for count in (0, True, 2.5):
        with pytest.raises(ModelError, match="config count: expected an integer >= 1"):
            Sum("s", count=count)
