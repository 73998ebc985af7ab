"""Kane-Ryan-Banerjee spin-up beam (JGCD 1987) through fem2modal and the engine, with and without geometric
stiffening, against the independent finite-segment reference of :mod:`tests.flexible.spinup_reference`
(issue 15).

Model: 20 CBAR (L = 10 m, E 7e10 Pa, A 4e-4 m^2, I 2e-7 m^4: EI 14,000 N m^2; rho 3000 kg/m^3: 1.2 kg/m),
Craig-Bampton modes with the root grid in the a-set, mounted by a locked hinge holding the root on a hub
whose revolute hinge is prescribed (the spin-up rate of the reference, its acceleration the prescribed
input); RK4. The chordwise tip deflection (across the hub x axis, in the hub frame) of the engine follows
the reference: with stiffening it stays bounded (peak -0.57 m near t = 7 s, back to mm after the spin-up);
without it the linear modal model diverges (the centrifugal softening of the in-plane bending exceeds the
elastic stiffness once Omega passes the first frequency, 3.5 rad/s: the tip runs away by tens of metres).
"""

from __future__ import annotations

import numpy as np
import pytest

from dynamics import Multibody
from dynamics.flex.pipeline import Fem2ModalOptions, fem2modal
from tests.flexible.spinup_reference import chain_reference, hub_motion

N_ELEMENTS = 20


def krb_deck(n_elements=N_ELEMENTS):
    lines = ["$ Kane-Ryan-Banerjee beam: L 10 m, EI 14000 N m^2, rho A 1.2 kg/m", "PARAM,COUPMASS,1"]
    for i, x in enumerate(np.linspace(0.0, 10.0, n_elements + 1)):
        lines.append(f"GRID,{i + 1},,{float(x)!r},0.0,0.0")
    lines += ["MAT1,1,7.0e10,,0.3,3000.0", "PBAR,10,1,4.0e-4,2.0e-7,2.0e-7,4.0e-7"]
    lines += [f"CBAR,{101 + i},10,{i + 1},{i + 2},0.0,1.0,0.0" for i in range(n_elements)]
    return "\n".join(lines + ["ENDDATA"]) + "\n"


@pytest.fixture(scope="module")
def krb_body(tmp_path_factory):
    path = tmp_path_factory.mktemp("krb") / "krb.dat"
    path.write_text(krb_deck())
    return fem2modal(str(path), Fem2ModalOptions(n_modes=6, aset=[(1, [1, 2, 3, 4, 5, 6])], modal_integrals=True,
                                                 geometric_stiffness=True))


def engine_tip_deflection(body, stiffening, t_eval, h=2e-3):
    mb = Multibody()
    mb.add_body("hub", None, mass=10.0, inertia=[1.0, 1.0, 1.0], hinge="revolute", axis=[0.0, 0.0, 1.0],
                prescribed=True)
    mb.add_flexible_body("beam", "hub", modal=body, hinge="locked", child_grid=1, damping_ratio=0.0,
                         geometric_stiffening=stiffening)
    mb.add_node("tip", "beam", grid=N_ELEMENTS + 1)
    system = mb.compile()
    q = system.neutral_configuration()
    u = np.zeros(system.nu)
    accel = np.zeros(system.nu)

    def f(t, q, u):
        accel[0] = hub_motion(t)[2]
        return system.q_dot(q, u), system.forward_dynamics(q, u, prescribed_accel=accel)

    def deflection(q):
        p = system.node_kinematics(q, u).position[0]
        c, s = np.cos(q[0]), np.sin(q[0])
        return -s * p[0] + c * p[1]

    out = np.empty(len(t_eval))
    t = 0.0
    k = 0
    steps = int(round(t_eval[-1] / h))
    for i in range(steps + 1):
        if k < len(t_eval) and abs(t - t_eval[k]) < 0.5 * h:
            out[k] = deflection(q)
            k += 1
        if i == steps or abs(out[max(k - 1, 0)]) > 50.0:
            break
        k1 = f(t, q, u)
        k2 = f(t + h / 2, q + h / 2 * k1[0], u + h / 2 * k1[1])
        k3 = f(t + h / 2, q + h / 2 * k2[0], u + h / 2 * k2[1])
        k4 = f(t + h, q + h * k3[0], u + h * k3[1])
        q = q + h / 6 * (k1[0] + 2 * k2[0] + 2 * k3[0] + k4[0])
        u = u + h / 6 * (k1[1] + 2 * k2[1] + 2 * k3[1] + k4[1])
        t = (i + 1) * h
    return out[:k]


def test_spin_up_short_stiffened_follows_reference_and_unstiffened_departs(krb_body):
    """First 6 s (the deflection builds up to -0.47 m): engine with stiffening within 2 % of the peak of the
    finite-segment reference (20 links); without it, already 20 % off."""
    t = np.linspace(0.0, 6.0, 13)
    ref = chain_reference(t, n_links=20)
    on = engine_tip_deflection(krb_body, None, t)
    off = engine_tip_deflection(krb_body, False, t)
    peak = np.abs(ref).max()
    assert np.abs(on - ref).max() < 0.02 * peak, (on, ref)
    assert np.abs(off - ref).max() > 0.2 * peak, (off, ref)


@pytest.mark.slow
def test_spin_up_full_run_bounded_with_stiffening_divergent_without(krb_body):
    t = np.linspace(0.0, 20.0, 41)
    ref = chain_reference(t, n_links=40)
    on = engine_tip_deflection(krb_body, None, t)
    assert on.size == t.size
    peak = np.abs(ref).max()
    assert 0.5 < peak < 0.65, peak
    assert np.abs(on - ref).max() < 0.02 * peak, np.abs(on - ref).max() / peak
    off = engine_tip_deflection(krb_body, False, t)
    assert np.abs(off).max() > 10.0 * peak, np.abs(off).max()
