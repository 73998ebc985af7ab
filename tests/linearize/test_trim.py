"""Trim against analytic equilibria."""

from __future__ import annotations

import numpy as np
import pytest

from shell.analysis.linearize import LinearizationError, _skew, linearize
from shell.analysis.trim import trim
from tests.linearize.plants import chain_matrices, chain_scene, pendulum_scene, spinning_body_scene


def test_pendulum_held_by_a_torque():
    """Hinge torque tau holds the pendulum where m g l sin(theta) = tau; the linearization there has
    A21 = -m g l cos(theta) / I. Residual and angle to 1e-12 (Newton-type convergence to round-off)."""
    sim, _ = pendulum_scene(0.1)
    result = trim(sim, hold=["multibody.u"], inputs=["multibody.rod.torque"],
                  input_values={"multibody.rod.torque": [10.0]})
    theta = np.arcsin(10.0 / (2.0 * 9.81 * 1.5))
    assert result.success and result.max_residual < 1e-12
    np.testing.assert_allclose(sim.x, [theta, 0.0], atol=1e-12)
    model = linearize(sim, ["multibody.rod.torque"], ["multibody.rod.q"], input_values=result.input_values)
    np.testing.assert_allclose(model.operating_point["xdot"], 0.0, atol=1e-12)
    np.testing.assert_allclose(model.A[1, 0], -2.0 * 9.81 * 1.5 * np.cos(theta) / (2.0 * 1.5 ** 2 + 1e-3),
                               rtol=1e-9)


def test_chain_forces_for_a_static_deflection():
    """Positions held at the chain's initial values, velocities at zero: the forces that make every
    acceleration vanish are f = K x (analytic, round-off tolerance 1e-10 N)."""
    sim = chain_scene()
    sim.x[3:] = 0.0
    result = trim(sim, hold=["chain.position", "chain.velocity"], free_inputs=["chain.force"])
    A, B = chain_matrices([2.0, 3.0, 0.5], [400.0, 250.0, 90.0], [3.0, 1.5, 0.2])
    expected = -np.linalg.solve(B[3:], A[3:] @ sim.x)
    np.testing.assert_allclose(result.input_values["chain.force"], expected, rtol=0, atol=1e-10)
    assert result.max_residual < 1e-10


def test_spinning_body_torque_for_steady_spin():
    """A body spinning at w0 about a non-principal axis needs tau = w0 x J w0 to keep w0 (Euler)."""
    J = np.array([[20.0, 0.5, 0.0], [0.5, 25.0, -0.3], [0.0, -0.3, 30.0]])
    w0 = np.array([0.3, -0.5, 0.8])
    sim = spinning_body_scene(J, w0, (0.8, 0.6, 0.0, 0.0))
    result = trim(sim, hold=["multibody.q", "multibody.u"], free_inputs=["multibody.cg.torque"],
                  derivatives=["multibody.u"])
    np.testing.assert_allclose(result.input_values["multibody.cg.torque"], _skew(w0) @ J @ w0, atol=1e-10)
    assert result.max_residual < 1e-12


def test_trim_refuses_unknown_states():
    sim = chain_scene()
    with pytest.raises(LinearizationError, match="neither a continuous state nor a state element"):
        trim(sim, hold=["chain.positions"])


def free_free_airframe_with_thrust(tmp_path):
    """A free-free flexible airframe (the FModal beam, 20 elements over 9 m, 4 flexible modes, 1 %
    damping) pushed by a canted 1000 N thrust at grid 1 (TM App. F's vehicle, flexible, as a beam)."""
    from dynamics import Multibody
    from dynamics.flex import Fem2ModalOptions, fem2modal
    from dynamics.modal_analysis import BeamDeck
    from shell.assembly import Assembly
    from shell.models.blocks import Constant
    from shell.models.multibody import MultibodyModel
    from shell.simulation import Simulation

    deck = BeamDeck()
    deck.add_line(1, (0.0, 0.0, 0.0), (1.0, 0.0, 0.0), 9.0, 20, (0.0, 1.0, 0.0), 1)
    body = fem2modal(str(deck.write(tmp_path / "airframe.dat")), Fem2ModalOptions(n_modes=4, modal_integrals=True))

    def scene():
        mb = Multibody(gravity=(0.0, 0.0, 0.0))
        mb.add_flexible_body("airframe", None, modal=body, hinge="free", damping_ratio=0.01)
        mb.add_node("gimbal", "airframe", grid=1)
        assembly = Assembly("launch_vehicle")
        assembly.add(MultibodyModel("multibody", mb.compile()))
        assembly.add(Constant("thrust", unit="N", shape=(3,), value=[1000.0, 0.0, 30.0]))
        assembly.connect("thrust.y", "multibody.gimbal.force")
        return Simulation(assembly, integrator="rk4", step=0.002)
    return scene


def test_flexible_vehicle_preloaded_by_thrust(tmp_path):
    """TM finding F-2 / recommendation R-2: trim the modal coordinates of a thrusting flexible vehicle so
    its modal accelerations vanish (rigid-body states held). Independent check: the nonlinear simulation
    started at the trim keeps the modal coordinates at the trim values (largest drift over 1 s measured
    7e-7 while the vehicle spins up), while the untrimmed vehicle oscillates about them with the full
    pre-load amplitude (0.0895): the drift must stay below 1e-4 of that amplitude."""
    scene = free_free_airframe_with_thrust(tmp_path)
    sim = scene()
    n_modes = 4
    rigid = [f"multibody.q[0:4].rotation_vector[{k}]" for k in range(3)] + [f"multibody.q[{k}]" for k in (4, 5, 6)]
    result = trim(sim, hold=rigid + ["multibody.u"], derivatives=[f"multibody.u[{6 + k}]" for k in range(n_modes)])
    assert result.success and result.max_residual < 1e-12
    eta_trim = sim.x[7:7 + n_modes].copy()

    def largest_modal_excursion(simulation):
        excursion = 0.0
        for k in range(1, 51):
            simulation.run(0.02 * k)
            excursion = max(excursion, float(np.max(np.abs(simulation.x[7:7 + n_modes] - eta_trim))))
        return excursion

    untrimmed = largest_modal_excursion(scene())
    trimmed = largest_modal_excursion(sim)
    assert untrimmed > 0.5 * np.max(np.abs(eta_trim))
    assert trimmed < 1e-4 * untrimmed
