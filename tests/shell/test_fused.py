"""The fused (single compiled function) derivative equals the interpreted plan bit for bit."""

import numpy as np
import pytest

from shell.assembly import Assembly
from shell.model import ModelError
from shell.models.blocks import Constant, Gain, Integrator
from shell.simulation import Simulation


def scene():
    root = Assembly("root")
    root.add(Constant("bias", unit="m/s", shape=(2,), value=[0.5, -0.25]))
    root.add(Integrator("x", unit="m", shape=(2,)))
    root.add(Gain("k", unit="m", output_unit="cm/s", shape=(2,), k="-3 1/s"))  # k in (cm/s)/m = 300; wiring cm/s -> m/s: factor 0.01
    root.add(Integrator("y", unit="m", shape=(2,)))
    root.connect("bias.y", "x.u")
    root.connect("x.y", "k.u")
    root.connect("k.y", "y.u")
    return root


@pytest.mark.slow  # compiling the generated function takes 6-10 s (numba recompiles the inlined kernels)
def test_fused_derivative_is_bit_identical_to_the_interpreted_one():
    interpreted = Simulation(scene(), step=0.01)
    fused = Simulation(scene(), step=0.01, fuse=True)
    state = np.array([1.0, 2.0, 3.0, 4.0])
    assert fused.rhs(0.3, state).tobytes() == interpreted.derivative(0.3, state).tobytes()
    # y' = 0.01 * (-300 x) = -3 x
    np.testing.assert_allclose(interpreted.derivative(0.0, state)[2:], -3 * state[:2], rtol=1e-15)
    interpreted.run(1.0)
    fused.run(1.0)
    assert fused.x.tobytes() == interpreted.x.tobytes()


def test_fusion_refuses_python_kernels():
    from tests.shell.test_failures import _Raises

    root = Assembly("root")
    root.add(_Raises("table"))
    with pytest.raises(ModelError, match=r"cannot fuse the derivative: models \['table'\]"):
        Simulation(root, fuse=True)
