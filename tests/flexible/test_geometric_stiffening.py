"""Geometric stiffening in the engine (issue 15): energy and momentum conserved in free tumbling with the
stiffening terms, which do change the motion; the scene key switches them off; old data is unchanged.

The stiffening terms are an addition to the body mass matrix M(eta) (dynamics.flexible_body.
add_geometric_stiffening: first-order rigid/modal block C1, second-order rotational block J2 and the new
mass-centre shift P2), so the equations stay Lagrange's: with no forces and no damping, the total energy
and the angular momentum of a free body are invariants. A free-free uniform beam (body frame at one end,
not at the centre of mass, so the body's linear velocity is not zero and every block of the stiffening
terms is exercised) tumbles with rates [0.3, 0.5, 2] rad/s from a bent state; RK4 at 1 ms (highest mode
61.7 rad/s, omega h = 0.06) for 1 s bounds the relative drifts well below 1e-8 (measured in the
assertion messages); a sign error in any bias term of P2 gives a drift of order 1e-3.
"""

from __future__ import annotations

import numpy as np
import pytest

from dynamics import Multibody
from dynamics.flex.pipeline import Fem2ModalOptions, fem2modal
from tests.flex.rotating_beam import rotating_beam_deck
from tests.flexible.conftest import rk4_march


@pytest.fixture(scope="module")
def free_beam(tmp_path_factory):
    deck = tmp_path_factory.mktemp("gs") / "beam.dat"
    # a tip mass with rotary inertia: a free hinge needs inertia about the beam axis too
    deck.write_text(rotating_beam_deck(20).replace("ENDDATA", "CONM2,900,21,,0.1\n,0.01,,0.01,,,0.01\nENDDATA"))
    return fem2modal(str(deck), Fem2ModalOptions(n_modes=4, modal_integrals=True, geometric_stiffness=True))


def tumble(body, stiffening, t_final=1.0, h=1e-3):
    mb = Multibody()
    mb.add_flexible_body("beam", None, modal=body, hinge="free", damping_ratio=0.0,
                         geometric_stiffening=stiffening)
    system = mb.compile()
    q = system.neutral_configuration()
    u = np.zeros(system.nu)
    u[:3] = [0.3, 0.5, 2.0]
    q[7:] = [0.02, -0.01, 0.005, 0.003]
    e0 = system.kinetic_energy(q, u) + system.potential_energy(q)
    L0 = system.angular_momentum(q, u)
    q, u, _ = rk4_march(system, q, u, h, int(round(t_final / h)))
    energy_drift = abs(system.kinetic_energy(q, u) + system.potential_energy(q) - e0) / e0
    momentum_drift = np.linalg.norm(system.angular_momentum(q, u) - L0) / np.linalg.norm(L0)
    return system, q, energy_drift, momentum_drift


def test_free_tumbling_with_stiffening_conserves_energy_and_momentum(free_beam):
    system, q, energy_drift, momentum_drift = tumble(free_beam, None)
    assert "P2" in system.summary()  # on by default when the body file has the geometric stiffness
    assert energy_drift < 1e-8, energy_drift
    assert momentum_drift < 1e-8, momentum_drift
    off, q_off, energy_off, momentum_off = tumble(free_beam, False)
    assert "P2" not in off.summary()
    assert energy_off < 1e-8 and momentum_off < 1e-8, (energy_off, momentum_off)
    # the stiffening changes the modal motion (2 rad/s on a 3.6 Hz beam: the phase of the modes drifts)
    change = np.linalg.norm(q[7:] - q_off[7:]) / np.linalg.norm(q_off[7:])
    assert change > 1e-2, change
    print(f"drifts with stiffening: energy {energy_drift:.2e}, momentum {momentum_drift:.2e}; without: "
          f"{energy_off:.2e}, {momentum_off:.2e}; modal change {change:.3f}")


def test_stiffening_requested_without_data_is_refused(tmp_path):
    deck = tmp_path / "beam.dat"
    deck.write_text(rotating_beam_deck(10))
    body = fem2modal(str(deck), Fem2ModalOptions(n_modes=2, modal_integrals=True))
    mb = Multibody()
    with pytest.raises(Exception, match="no geometric stiffness"):
        mb.add_flexible_body("beam", None, modal=body, hinge="free", geometric_stiffening=True)
    with pytest.raises(Exception, match="preload"):
        mb.add_flexible_body("beam2", None, modal=body, hinge="free", preload={"thrust": 1.0})


PRELOAD_SCENE = """name: preloaded_beam
multibody:
  bodies:
    - name: beam
      parent: world
      hinge: locked
      body_file: beam.h5
      child_grid: 1
      {extra}
  nodes:
    - {{name: tip, body: beam, grid: 41}}
integrator: {{method: rk4, step: 1 ms}}
stop: {{time: 0.01 s}}
"""


@pytest.fixture(scope="module")
def preloaded_body_file(tmp_path_factory):
    from shell.cli import main

    tmp = tmp_path_factory.mktemp("preload")
    (tmp / "beam.dat").write_text(rotating_beam_deck(40))
    assert main(["fem2modal", str(tmp / "beam.dat"), "--modes", "12", "--aset", "1:123456", "--modal-integrals",
                 "--preload", "tip:41:1:-1.0", "-q", "-o", str(tmp / "beam.h5")]) == 0
    return tmp / "beam.h5"


def scene_bending_frequencies(body_file, extra):
    import warnings

    from shell.analysis.linearize import linearize
    from shell.scenario import build_simulation, load_scenario

    path = body_file.parent / "scene.yaml"
    path.write_text(PRELOAD_SCENE.format(extra=extra))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sim = build_simulation(load_scenario(str(path), []))
    model = linearize(sim, ["multibody.beam.modal_force"], ["multibody.tip.position"], points=2, richardson=False,
                      tolerance=1e-12)
    ev = np.linalg.eigvals(model.A)
    return np.sort(np.abs(ev.imag[ev.imag > 1e-6]))


@pytest.mark.parametrize("scale", [0.0, 1.0, -2.0])
def test_scene_preload_scales_the_named_load(preloaded_body_file, scale):
    """A cantilever (40 CBAR, EI 1, L 1, root held by the hinge) with the named tip load -1 N (compression)
    of ``fem2modal --preload tip:41:1:-1.0``, scaled by the scene: the first bending frequencies (each a
    (y, z) pair) against the power series of w'''' - tau w'' = omega^2 w, tau = -scale N (1e-3: the lumped
    node masses' O(h^2) error, 2.9e-4 at 40 elements)."""
    from tests.flex.rotating_beam import axially_loaded_cantilever_frequencies

    got = scene_bending_frequencies(preloaded_body_file, f"preload: {{tip: {scale}}}")
    ref = axially_loaded_cantilever_frequencies(-scale, count=2)
    np.testing.assert_allclose(got[[0, 1, 2, 3]], np.repeat(ref, 2), rtol=1e-3)


def test_scene_keys_are_checked(preloaded_body_file):
    from shell.scenario import ScenarioError, build_simulation, load_scenario

    for extra, match in (("geometric_stiffening: yes please", "geometric_stiffening"),
                         ("preload: [1.0]", "preload"),
                         ("preload: {tip: big}", "preload"),
                         ("preload: {thrust: 1.0}", "thrust")):
        path = preloaded_body_file.parent / "bad.yaml"
        path.write_text(PRELOAD_SCENE.format(extra=extra))
        with pytest.raises((ScenarioError, Exception), match=match):
            build_simulation(load_scenario(str(path), []))
