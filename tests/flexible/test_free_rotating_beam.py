"""Freely rotating free-free beam, initial rate [5, 5, 5] deg/s (TM-2020-5008164 Section 7.2).

The 101-grid, 9 m, 1440 kg single-length beam of the FModal paper (Appendix C) goes through the FEM
pipeline (8 free-free modes, modal integrals) into the engine on a free hinge. With mass-normalized
free-free modes p1 = E0 = F0 = 0 (to round-off), so without the deformation-dependent modal integrals
(order 0) nothing couples the rotation into the modes and the sensor node stays rigid (measured tip
deflection 1.4e-13 m, the round-off of F0, E0); with them (order 2) the beam deforms (5.0e-7 m). The
deformation is small because the translational centrifugal and Euler loads on a straight beam are
linear along it, i.e. mass-orthogonal to every free-free flexible mode; what deforms the beam is the
nodes' rotary inertia (gyroscopic torques on the bending slopes), which the order-2 integrals carry. Energy and angular momentum are conserved over 10 s:
RK4 at 2 ms with the highest mode at 8.5 Hz (omega h = 0.11) bounds the relative drift well below
1e-9; measured values are in the assertions' messages.
"""

from __future__ import annotations

import numpy as np
import pytest

from dynamics import Multibody
from dynamics.flex.pipeline import Fem2ModalOptions, fem2modal
from tests.flexible.conftest import rk4_march


@pytest.fixture(scope="module")
def beam_body():
    return fem2modal("configs/fem/single_length_beam.dat", Fem2ModalOptions(n_modes=8, modal_integrals=True))


def spin(beam_body, order, t_final=10.0, h=2e-3):
    mb = Multibody()
    mb.add_flexible_body("beam", None, modal=beam_body, hinge="free", order=order, damping_ratio=0.0)
    mb.add_node("sensor", "beam", grid=101)
    system = mb.compile()
    q = system.neutral_configuration()
    u = np.zeros(system.nu)
    u[:3] = np.deg2rad([5.0, 5.0, 5.0])
    com = np.asarray(beam_body.cm_offset)
    u[3:6] = -np.cross(u[:3], com)  # centre of mass at rest
    e0 = system.kinetic_energy(q, u) + system.potential_energy(q)
    L0 = system.angular_momentum(q, u)
    gamma_tip = beam_body.mode_shape(101)[3:]
    max_deflection = [0.0]

    def track(t, q, u):
        max_deflection[0] = max(max_deflection[0], np.linalg.norm(gamma_tip @ q[7:]))

    q, u, _ = rk4_march(system, q, u, h, int(round(t_final / h)), after_step=track)
    max_deflection = max_deflection[0]
    energy_drift = abs(system.kinetic_energy(q, u) + system.potential_energy(q) - e0) / e0
    momentum_drift = np.linalg.norm(system.angular_momentum(q, u) - L0) / np.linalg.norm(L0)
    return q, max_deflection, energy_drift, momentum_drift


def test_without_modal_integrals_the_spinning_beam_stays_rigid(beam_body):
    q, deflection, energy_drift, momentum_drift = spin(beam_body, order=0)
    assert deflection < 1e-11, deflection
    assert energy_drift < 1e-9, energy_drift
    assert momentum_drift < 1e-9, momentum_drift


def test_with_modal_integrals_the_spinning_beam_deforms_and_conserves(beam_body):
    q, deflection, energy_drift, momentum_drift = spin(beam_body, order=2)
    assert 1e-7 < deflection < 1e-5, deflection
    assert energy_drift < 1e-9, energy_drift
    assert momentum_drift < 1e-9, momentum_drift
