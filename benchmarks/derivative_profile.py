"""Where one forward dynamics of a flexible body goes, kernel by kernel (issue 28): each step of
:func:`dynamics.kernels.articulated_body.forward_dynamics` timed alone, in compiled loops (no Python call per
evaluation), on the state of the deck it runs on.

Cases:

* ``hub``: the hub + arm + tube of ``benchmarks/flexible_vs_exudyn.py --case beam`` (105 grids with rotary inertia,
  20 modes, order 2: G1, F2, G2 over the nodes, the modal mass formed and factored every evaluation, C1 and J2 as
  tables), on a free hinge, spinning at 1 rad/s about z with the tube deflected by 0.3 m at its tip (the static
  shape of a lateral tip load; the benchmark's run peaks at 0.16 m) and modal rates of a tenth of each amplitude
  times its frequency, a 50 N m torque on the hub node. Rows: the whole forward dynamics; the kinematics; pass 1
  of the body (``_flexible_inertia_and_bias``) and its parts (the tables' terms ``modal_mass_and_bias``, the node
  terms with their forces ``node_inertia_terms``, the node terms of the modal mass ``node_inertia_modal_mass``);
  the node forces; the modal elimination's inertia part (Cholesky of G(eta), M_re G^-1, A''; minus the restore of
  G(eta) it needs to be repeated) and bias part; the hinge's step; the acceleration pass.
* ``tube``: the 196-mode tube with a wheel of ``benchmarks/flexible_scaling.py --deck-only`` (its state), whose
  modal mass is refined: the whole forward dynamics and the parts of one refinement pass (the bias pass and its
  modal elimination ``condense_bias``, the acceleration pass, the convergence check, the products with dG in
  double and in single precision).

Medians of interleaved batches (microseconds per call); the load average is printed (shared machine: compare rows
of one run). Run from the repository root: ``python benchmarks/derivative_profile.py [--rounds 7] [--case hub tube]``.
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from numba import njit

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from dynamics import Multibody  # noqa: E402
from dynamics import flexible_kernels as FK  # noqa: E402
from dynamics import layout as L  # noqa: E402
from dynamics.kernels import articulated_body as AB  # noqa: E402
from dynamics.kernels import body_terms as BT  # noqa: E402
from dynamics.kernels import modal_condensation as MC  # noqa: E402
from dynamics.kernels import node_inertia as NI  # noqa: E402
from dynamics.kernels.kinematics import general_kinematics  # noqa: E402
from dynamics.layout import view  # noqa: E402


@njit(cache=True)
def _forward(R, a):
    for _ in range(R):
        AB.forward_dynamics(*a)


@njit(cache=True)
def _kinematics(R, a):
    for _ in range(R):
        general_kinematics(0, a[0], a[1], a[2], a[3], a[4], a[5], a[6], a[12], a[13], a[14], a[15], True)


@njit(cache=True)
def _pass1(R, a):
    for _ in range(R):
        AB._flexible_inertia_and_bias(0, a[0], a[4], a[5], a[6], a[9], False, a[13], a[14], a[15])


@njit(cache=True)
def _tables(R, a):
    top, params, q, u, wv, wm, pool = a[0], a[4], a[5], a[6], a[13], a[14], a[15]
    n = top[0, L.N_MODES]
    qe = top[0, L.Q_START] + top[0, L.NQ_HINGE]
    ue = top[0, L.U_START] + top[0, L.NU_HINGE]
    fx = top[0, L.FLEX:L.FLEX + L.N_FX]
    pv = fx[L.FX_P_VEC]
    for _ in range(R):
        FK.modal_mass_and_bias(fx, params, n, q[qe:qe + n], wv[0, L.VEC_V], u[ue:ue + n], True, True,
                               view(pool, fx[L.FX_P_MRR], 6, 6), view(pool, fx[L.FX_P_MRE], 6, n),
                               view(pool, fx[L.FX_P_G], n, n), wv[0, L.VEC_P],
                               pool[pv + L.PV_FORCE * n:pv + (L.PV_FORCE + 1) * n], wm[0, L.MAT_IAP],
                               view(pool, fx[L.FX_P_MDRE], 6, n))


@njit(cache=True)
def _node_terms(R, a):
    top, params, q, u, wv, pool = a[0], a[4], a[5], a[6], a[13], a[15]
    n = top[0, L.N_MODES]
    qe = top[0, L.Q_START] + top[0, L.NQ_HINGE]
    ue = top[0, L.U_START] + top[0, L.NU_HINGE]
    fx = top[0, L.FLEX:L.FLEX + L.N_FX]
    pv = fx[L.FX_P_VEC]
    count = fx[L.FX_NODE_COUNT]
    for _ in range(R):
        NI.node_inertia_terms(params, fx[L.FX_NODES], count, n, fx[L.FX_NODE_TERMS], q[qe:qe + n], wv[0, L.VEC_V],
                              u[ue:ue + n], True, view(pool, fx[L.FX_P_MRE], 6, n), wv[0, L.VEC_P],
                              pool[pv + L.PV_FORCE * n:pv + (L.PV_FORCE + 1) * n],
                              pool[fx[L.FX_P_NODES]:fx[L.FX_P_NODES] + NI.NODE_STATE * count])


@njit(cache=True)
def _node_modal_mass(R, a):
    top, params, pool = a[0], a[4], a[15]
    n = top[0, L.N_MODES]
    fx = top[0, L.FLEX:L.FLEX + L.N_FX]
    count = fx[L.FX_NODE_COUNT]
    for _ in range(R):
        NI.node_inertia_modal_mass(params, fx[L.FX_NODES], count, n, fx[L.FX_NODE_TERMS],
                                   pool[fx[L.FX_P_NODES]:fx[L.FX_P_NODES] + NI.NODE_STATE * count],
                                   view(pool, fx[L.FX_P_G], n, n))


@njit(cache=True)
def _node_forces(R, a):
    for _ in range(R):
        BT.apply_node_forces(a[0], a[1], a[4], a[5], a[8], a[13], a[15], -1.0)


@njit(cache=True)
def _restore(a, G, IA):
    top, wm, pool = a[0], a[14], a[15]
    o = top[0, L.FLEX + L.FX_P_G]
    for k in range(G.size):
        pool[o + k] = G[k]
    wm[0, L.MAT_IA] = IA


@njit(cache=True)
def _restore_only(R, a, G, IA):
    for _ in range(R):
        _restore(a, G, IA)


@njit(cache=True)
def _condense_inertia(R, a, G, IA):
    for _ in range(R):
        _restore(a, G, IA)
        MC.condense_inertia(0, a[0], a[1], a[4], False, a[14], a[15])


@njit(cache=True)
def _condense_bias(R, a):
    for _ in range(R):
        MC.condense_bias(0, a[0], a[1], a[4], a[7], False, a[13], a[15])


@njit(cache=True)
def _hinge(R, a):
    for _ in range(R):
        AB._hinge_inertia(0, a[0], a[14])
        AB._hinge_bias(0, a[0], a[7], a[14], a[13])


@njit(cache=True)
def _accelerations(R, a, stop):
    ground = a[4][L.GROUND_ACCEL:L.GROUND_ACCEL + 6]
    for _ in range(R):
        AB._acceleration_pass(a[0], a[1], ground, a[7], a[10], a[11], a[12], a[13], a[14], a[15], 0, stop)


@njit(cache=True)
def _bias_pass(R, a):
    for _ in range(R):
        AB._bias_pass(a[0], a[1], a[4], a[7], False, a[12], a[13], a[14], a[15])


@njit(cache=True)
def _change(R, a):
    total = 0.0
    for _ in range(R):
        total += AB._refinement_change(a[0], a[10], a[15])[0]
    return total


@njit(cache=True)
def _products(R, a, single):
    for _ in range(R):
        AB._refinement_products(a[0], a[4], a[10], a[15], single)


def _arguments(system, q, u, node_forces):
    m, d = system.model, system.data
    return (m.topology, m.nodes, m.joint_rot, m.joint_vec, d.params, q, u, np.zeros(system.nu), node_forces,
            np.zeros((m.topology.shape[0], 6)), np.zeros(system.nu), np.zeros(system.nu), d.ws_rot, d.ws_vec,
            d.ws_mat, d.pool)


def hub_case():
    from benchmarks.flexible_scaling import deflected_state
    from benchmarks.flexible_vs_exudyn import BEAM, beam_hub_deck
    from dynamics.flex.pipeline import Fem2ModalOptions, fem2modal

    n = 20
    with tempfile.TemporaryDirectory() as tmp:
        deck = Path(tmp) / "hub.dat"
        deck.write_text("SOL 103\nCEND\nBEGIN BULK\n" + beam_hub_deck(**BEAM)[0])
        body = fem2modal(str(deck), Fem2ModalOptions(n_modes=n, modal_integrals=True))
    mb = Multibody()
    mb.add_flexible_body("boom", None, modal=body, hinge="free", order=2)
    mb.add_node("hub", "boom", grid=1)
    system = mb.compile()
    q, u = deflected_state(system, body, n, tip_deflection=0.3, rate=1.0)
    forces = np.zeros((system.nnodes, 6))
    forces[0, 2] = 50.0
    a = _arguments(system, q, u, forces)
    fx = system.topology[0, L.FLEX:]
    _forward(1, a)
    _kinematics(1, a)
    _pass1(1, a)  # the state the modal elimination starts from: G(eta) formed, IA = M_rr(eta)
    G = a[15][fx[L.FX_P_G]:fx[L.FX_P_G] + n * n].copy()
    IA = a[14][0, L.MAT_IA].copy()
    calls = {
        "forward_dynamics (whole)": lambda R: _forward(R, a),
        "kinematics": lambda R: _kinematics(R, a),
        "pass 1 of the body (_flexible_inertia_and_bias)": lambda R: _pass1(R, a),
        "  modal_mass_and_bias (tables C1, J2, R1; G0 copied)": lambda R: _tables(R, a),
        "  node_inertia_terms (G1, F2, G2 with forces)": lambda R: _node_terms(R, a),
        "  node_inertia_modal_mass (G(eta) formed)": lambda R: _node_modal_mass(R, a),
        "apply_node_forces": lambda R: _node_forces(R, a),
        "condense_inertia + restore of G(eta)": lambda R: _condense_inertia(R, a, G, IA),
        "  restore of G(eta) alone": lambda R: _restore_only(R, a, G, IA),
        "condense_bias": lambda R: _condense_bias(R, a),
        "hinge step (inertia and bias)": lambda R: _hinge(R, a),
        "acceleration pass": lambda R: _accelerations(R, a, 1),
    }
    return system, calls, a


def tube_case():
    from benchmarks.flexible_scaling import beam_deck, deflected_state, tube_with_wheel
    from dynamics.flex.pipeline import Fem2ModalOptions, fem2modal

    n = 196
    with tempfile.TemporaryDirectory() as tmp:
        path = os.path.join(tmp, "tube.dat")
        Path(path).write_text(beam_deck())
        body = fem2modal(path, Fem2ModalOptions(n_modes=n, modal_integrals=True))
    system = tube_with_wheel(body, n, 2)
    q, u = deflected_state(system, body, n, tip_deflection=0.01, rate=0.05)
    u[-1] = 50.0
    a = _arguments(system, q, u, np.zeros((system.nnodes, 6)))
    _forward(1, a)
    calls = {
        "forward_dynamics (whole)": lambda R: _forward(R, a),
        "bias pass (_bias_pass)": lambda R: _bias_pass(R, a),
        "  condense_bias": lambda R: _condense_bias(R, a),
        "acceleration pass (the tube)": lambda R: _accelerations(R, a, 1),
        "convergence check (_refinement_change)": lambda R: _change(R, a),
        "product with dG (double)": lambda R: _products(R, a, False),
        "product with dG (single, a late pass)": lambda R: _products(R, a, True),
    }
    return system, calls, a


def timed(calls, rounds, target=0.01):
    batch = {}
    for k, fn in calls.items():
        fn(1)
        t0 = time.perf_counter()
        fn(10)
        batch[k] = max(10, int(10 * target / max(time.perf_counter() - t0, 1e-7)))
    samples = {k: [] for k in calls}
    for _ in range(rounds):
        for k, fn in calls.items():
            t0 = time.perf_counter()
            fn(batch[k])
            samples[k].append((time.perf_counter() - t0) / batch[k])
    return {k: float(np.median(v)) for k, v in samples.items()}


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=7)
    parser.add_argument("--case", nargs="+", default=["hub", "tube"], choices=("hub", "tube"))
    args = parser.parse_args(argv)
    for case in args.case:
        system, calls, a = (hub_case if case == "hub" else tube_case)()
        udot = a[10]
        q, u = a[5], a[6]
        dense = np.linalg.solve(system.mass_matrix(q), -system.bias_forces(q, u, node_forces=a[8]))
        _forward(1, a)
        check = float(np.abs(udot - dense).max() / np.abs(dense).max())
        times = timed(calls, args.rounds)
        _forward(1, a)
        print(f"\n{case}: {system.topology[0, L.N_MODES]} modes, refinement passes {a[15][L.P_REFINEMENTS]:g}, "
              f"forward dynamics against the dense solve {check:.1e}; load average {os.getloadavg()[0]:.2f}")
        print("| step | us |\n| --- | ---: |")
        for k, t in times.items():
            print(f"| {k} | {t * 1e6:.2f} |")


if __name__ == "__main__":
    main()
