"""The translation hinge (three DOFs: M's origin moves in F, M parallel to F), added to flexshell from its record in
``dynamics.hinges.HINGES`` and its branches in the hinge kernels alone: the proof that a hinge type is one record.

Checked against Pinocchio 4.1's ``JointModelTranslation`` (an independent implementation, same process) in random
branched trees that mix it with revolute, U-joint, spherical and free hinges, outboard frame offsets included:
forward dynamics, inverse dynamics and mass matrix to 1e-10 relative (the tolerance of every Pinocchio comparison,
tests/dynamics/test_against_pinocchio.py; they agree to ~1e-14). Through the user's path: a YAML scene of a point
mass (no rotary inertia: a translation never turns it) thrown on a translation hinge with ``initial: {position,
velocity}``, run by ``flexshell run`` with RK4: the exact parabola to round-off (RK4 integrates a quadratic exactly),
its ports in metres; a spring on one of its coordinates in Python, the analytic oscillation.
"""

from __future__ import annotations

import numpy as np
import pytest

from dynamics import Multibody
from dynamics.constraints import ConstrainedSystem
from dynamics.errors import ModelDefinitionError
from dynamics.force_elements import HingeSpring
from shell.cli import main
from shell.log_file import log_info, read_log

from .pinocchio_reference import pinocchio_from_builder
from .random_models import random_multibody
from .test_against_pinocchio import compare_dynamics


@pytest.mark.parametrize("seed", range(3))
def test_translation_hinges_in_random_trees_match_pinocchio(seed):
    mb = random_multibody(12, seed=seed, hinges=("translation", "revolute", "ujoint", "spherical", "free"),
                          root_hinge="translation")
    assert sum(b.hinge == "translation" for b in mb.bodies) >= 2
    system = mb.compile(solver="aba")
    model, cmap = pinocchio_from_builder(mb, system)
    compare_dynamics(system, model, cmap, seed=seed)
    dense = mb.compile(solver="dense")
    compare_dynamics(dense, model, cmap, seed=seed + 10, n_states=1)


def test_translation_hinge_record_and_checks():
    mb = Multibody(gravity=(0.0, 0.0, -9.81))
    mb.add_body("puck", None, mass=2.0, inertia=[0.0, 0.0, 0.0], hinge="translation")
    system = mb.compile()
    assert (system.nq, system.nu) == (3, 3) and np.array_equal(system.neutral_configuration(), np.zeros(3))
    u = np.array([1.0, -2.0, 3.0])
    np.testing.assert_array_equal(system.q_dot(np.array([0.3, 0.1, -0.2]), u), u)
    np.testing.assert_allclose(system.forward_dynamics(np.zeros(3), u), [0.0, 0.0, -9.81], rtol=1e-15, atol=0)
    with pytest.raises(ModelDefinitionError, match="a translation hinge takes no axis"):
        Multibody().add_body("b", None, mass=1.0, inertia=[1, 1, 1], hinge="translation", axis=(0, 0, 1))
    # a hinge spring on its z coordinate: the oscillation sqrt(k / m) about the sagged position
    k, m = 50.0, 2.0
    spring = HingeSpring("z_spring", "puck", stiffness=k, dof=2)
    with pytest.raises(ModelDefinitionError, match="dof 0 to 2"):
        ConstrainedSystem(system, [], [HingeSpring("bad", "puck", stiffness=k, dof=3)])
    constrained = ConstrainedSystem(system, [], [spring])
    q = np.array([0.0, 0.0, 0.1])
    udot = constrained.forward_dynamics(q, np.zeros(3)).u_dot
    np.testing.assert_allclose(udot, [0.0, 0.0, -9.81 - k / m * 0.1], rtol=1e-14)


SCENE = """name: throw
description: a point mass thrown on a translation hinge (three displacements, no rotation)
multibody:
  gravity: "[0, 0, -9.81] m/s^2"
  bodies:
    - name: puck
      parent: world
      hinge: translation
      mass: 0.5 kg
      inertia: "[0, 0, 0] kg*m^2"
      initial: {position: "[1, 2, 3] m", velocity: "[4, -5, 60] cm/s"}
integrator:
  method: rk4
  step: 10 ms
stop:
  time: 1 s
log:
  rate: 10 Hz
  signals:
    - multibody.puck.q
    - multibody.puck.u
"""


def test_translation_hinge_through_yaml_and_the_command_line(tmp_path):
    path = tmp_path / "throw.yaml"
    path.write_text(SCENE)
    assert main(["run", str(path), "-o", str(tmp_path / "throw.h5"), "--quiet"]) == 0
    data = read_log(tmp_path / "throw.h5")
    t = data["time"]
    v0, g = np.array([0.04, -0.05, 0.6]), np.array([0.0, 0.0, -9.81])
    expected = np.array([1.0, 2.0, 3.0]) + np.outer(t, v0) + 0.5 * np.outer(t * t, g)
    np.testing.assert_allclose(data["multibody.puck.q"], expected, rtol=0, atol=1e-13)
    np.testing.assert_allclose(data["multibody.puck.u"], v0 + np.outer(t, g), rtol=0, atol=1e-13)
    signals = log_info(tmp_path / "throw.h5")["signals"]
    assert (signals["multibody.puck.q"]["unit"], signals["multibody.puck.u"]["unit"]) == ("m", "m/s")
