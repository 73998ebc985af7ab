"""Where the time of the node terms goes: each pass of :mod:`dynamics.kernels.node_inertia` and
:mod:`dynamics.kernels.node_mass` timed alone on the data of the two decks of issue 28's must-shows.

Cases: the 9 m tube of ``benchmarks/flexible_scaling.py --deck-only`` (101 grids with CONM2 rotary inertia, 196
modes: G1, F2, G2 over the nodes, refined; C1 and J2 over the nodes at order 2) and the hub + arm + tube of
``benchmarks/flexible_vs_exudyn.py --case beam`` (105 grids, 20 modes: G1, F2, G2 over the nodes, the modal mass
formed and factored every evaluation), both through ``dynamics.flex.fem2modal``; the state is the tube
benchmark's (static deflection of a lateral tip load, 1 cm at the tip, modal rates a tenth of the amplitude times
each frequency, 0.05 rad/s about z). Rows: the whole kernel per call (``node_inertia_terms`` with its forces,
``node_inertia_times``, ``node_inertia_modal_mass``, ``node_mass_terms``; both kernels of one evaluation, sharing
their passes where their nodes are the same as on these decks, against ``--before``'s two apart) and the passes it
is made of (``shapes_times``: the stacked shapes times eta and the rates; the back products), in microseconds,
medians of interleaved batches; the per-node algebra is the whole minus its passes. Run from the repository root:
``python benchmarks/node_terms_passes.py [--rounds 15] [--before REF]``.
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from dynamics import layout as L  # noqa: E402
from dynamics.kernels import node_inertia as NI  # noqa: E402
from dynamics.kernels import node_mass as NM  # noqa: E402


def _bodies():
    """The tube (196 modes) and the hub beam (20 modes) through fem2modal."""
    from benchmarks.flexible_scaling import beam_deck
    from benchmarks.flexible_vs_exudyn import BEAM, beam_hub_deck
    from dynamics.flex.pipeline import Fem2ModalOptions, fem2modal

    with tempfile.TemporaryDirectory() as tmp:
        tube = Path(tmp) / "tube.dat"
        tube.write_text(beam_deck())
        hub = Path(tmp) / "hub.dat"
        hub.write_text("SOL 103\nCEND\nBEGIN BULK\n" + beam_hub_deck(**BEAM)[0])
        return (fem2modal(str(tube), Fem2ModalOptions(n_modes=196, modal_integrals=True)),
                fem2modal(str(hub), Fem2ModalOptions(n_modes=20, modal_integrals=True)))


def _case(body, n):
    shapes = np.concatenate([body.rotation_shapes[:, :, :n], body.translation_shapes[:, :, :n]], axis=1)
    tip = body.translation_shapes[-1][:, :n]
    omega = 2 * np.pi * np.asarray(body.frequencies_hz[:n])
    eta = (tip[1] + tip[2]) / omega ** 2
    eta = 0.01 * eta / np.abs(tip @ eta).max()
    e = 0.1 * omega * eta
    V = np.array([0.0, 0.0, 0.05, 0.0, 0.0, 0.0])
    sel = np.abs(body.node_inertia).reshape(len(body.node_mass), -1).max(axis=1) > 0.0
    inertia_args = (body.node_mass[sel], body.node_cm_offset[sel], body.node_inertia[sel], shapes[sel])
    mass_args = (body.node_mass, body.node_cm_offset, body.node_inertia, body.grid_positions, shapes)
    return dict(n=n, N=int(sel.sum()), Nm=len(body.node_mass), eta=eta, e=e, V=V, inertia_args=inertia_args,
                mass_args=mass_args, shared=bool(sel.all()))


def _calls(c, bits, NI, NM):
    """name -> zero-argument call, for one case, of the kernels of the modules ``NI`` (node_inertia) and ``NM``
    (node_mass); the passes a module does not have are left out."""
    n, N, Nm = c["n"], c["N"], c["Nm"]
    eta, e, V = c["eta"], c["e"], c["V"]
    ip = np.concatenate([[0.0], NI.node_params(*c["inertia_args"])])  # each version's own packing
    mp = np.concatenate([[0.0], NM.node_mass_params(*c["mass_args"])])
    state = np.zeros(NI.NODE_STATE * N)
    Mre, br, bm, G = np.zeros((6, n)), np.zeros(6), np.zeros(n), np.zeros((n, n))
    x, out = np.random.default_rng(0).standard_normal(n), np.zeros(n)
    prev = x + 1e-8 * np.random.default_rng(1).standard_normal(n)
    mstate = np.zeros(NM.MASS_NODE_STATE * Nm)
    Mrr = np.zeros((6, 6))
    width = 3 * N
    _, _, _, lam, _ = NI._layout(1, N, n)
    th, thd = np.zeros(width), np.zeros(width)
    A = np.zeros(width)
    W = np.zeros(9 * width)
    mbits = L.MASS_C1 | L.MASS_J2
    NI.node_inertia_terms(ip, 1, N, n, bits, eta, V, e, True, Mre, br, bm, state)
    calls = {
        "node_inertia_terms (forces)": lambda: NI.node_inertia_terms(ip, 1, N, n, bits, eta, V, e, True, Mre, br, bm,
                                                                     state),
        "  shapes_times Lambda (eta, e)": lambda: NI.shapes_times(ip, lam, n, width, eta, e, th, thd, True),
        "  back sweep Lambda (a, Q lambda)": lambda: NI.columns_times(ip, lam, n, width, W, A, 0, True, True, Mre, bm),
        "node_inertia_terms (no forces)": lambda: NI.node_inertia_terms(ip, 1, N, n, bits, eta, V, e, False, Mre, br,
                                                                        bm, state),
        "node_inertia_times": lambda: NI.node_inertia_times(ip, 1, N, n, bits, state, x, out),
        "node_inertia_times_single": lambda: NI.node_inertia_times_single(ip, 1, N, n, bits, state, x, prev, out),
        "  shapes_times Lambda (x)": lambda: NI.shapes_times(ip, lam, n, width, x, x, th, th, False),
        "  _shapes_dot Lambda": lambda: NI._shapes_dot(ip, lam, n, width, A, out),
        "node_inertia_modal_mass": lambda: NI.node_inertia_modal_mass(ip, 1, N, n, bits, state, G),
    }
    if hasattr(NI, "node_inertia_pass"):  # C1, J2 after node_inertia_pass, sharing its nodes where they are the same
        calls["node_mass_terms C1 J2 (forces)"] = lambda: NM.node_mass_terms(mp, 1, Nm, n, mbits, eta, V, e, True, Mrr,
                                                                             Mre, br, bm, mstate, 1, bits, state)
        if c["shared"]:
            both = np.concatenate([ip, NM.node_mass_params(*c["mass_args"], shared=True)])

            def shared():
                NI.node_inertia_pass(both, 1, N, n, bits, eta, V, e, True, br, state, True)
                NM.node_mass_terms(both, ip.size, Nm, n, mbits, eta, V, e, True, Mrr, Mre, br, bm, mstate, 1, bits,
                                   state)
            calls["node_inertia_terms + node_mass_terms (forces)"] = shared
    else:
        calls["node_mass_terms C1 J2 (forces)"] = lambda: NM.node_mass_terms(mp, 1, Nm, n, mbits, eta, V, e, True, Mrr,
                                                                             Mre, br, bm, mstate)

        def apart():
            NI.node_inertia_terms(ip, 1, N, n, bits, eta, V, e, True, Mre, br, bm, state)
            NM.node_mass_terms(mp, 1, Nm, n, mbits, eta, V, e, True, Mrr, Mre, br, bm, mstate)
        calls["node_inertia_terms + node_mass_terms (forces)"] = apart
    return {k: fn for k, fn in calls.items() if ("sweep" not in k or hasattr(NI, "columns_times"))
            and ("single" not in k or hasattr(NI, "node_inertia_times_single"))}


def _modules_at(ref):
    """node_inertia and node_mass as they are at the git revision ``ref``, imported under other names (numba
    compiles them apart from the working tree's)."""
    import importlib.util
    import subprocess

    out = Path(tempfile.mkdtemp(prefix="node_terms_"))
    mods = []
    for name in ("node_inertia", "node_mass"):
        text = subprocess.run(["git", "show", f"{ref}:dynamics/kernels/{name}.py"], cwd=ROOT, check=True,
                              capture_output=True, text=True).stdout
        text = text.replace("from dynamics.kernels.node_inertia import", "from node_inertia_at_ref import")
        path = out / f"{name}_at_ref.py"
        path.write_text(text)
        spec = importlib.util.spec_from_file_location(f"{name}_at_ref", path)
        module = importlib.util.module_from_spec(spec)
        sys.modules[f"{name}_at_ref"] = module
        spec.loader.exec_module(module)
        mods.append(module)
    return mods


def _timed(calls, rounds, target=0.01):
    names = list(calls)
    batch = {}
    for k in names:
        calls[k]()
        t0 = time.perf_counter()
        calls[k]()
        batch[k] = max(1, int(target / max(time.perf_counter() - t0, 1e-7)))
    samples = {k: [] for k in names}
    for _ in range(rounds):
        for k in names:
            fn, b = calls[k], batch[k]
            t0 = time.perf_counter()
            for _ in range(b):
                fn()
            samples[k].append((time.perf_counter() - t0) / b)
    return {k: float(np.median(v)) for k, v in samples.items()}


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=15)
    parser.add_argument("--before", metavar="REF", help="also time the kernels of git revision REF, interleaved")
    args = parser.parse_args(argv)
    tube, hub = _bodies()
    bits = L.NODE_G1 | L.NODE_F2 | L.NODE_G2
    cases = {"tube n = 196": _case(tube, 196), "hub beam n = 20": _case(hub, 20)}
    versions = {"": (NI, NM)}
    if args.before:
        versions[f"{args.before}: "] = tuple(_modules_at(args.before))
    calls = {}
    for case, c in cases.items():
        made = {label: _calls(c, bits, ni, nm) for label, (ni, nm) in versions.items()}
        for k in made[""]:
            calls.update({f"{case}: {label}{k}": fns[k] for label, fns in made.items() if k in fns})
    print(f"load average {os.getloadavg()[0]:.2f} on {os.cpu_count()} cores; nodes with rotary inertia: "
          + ", ".join(f"{case} N = {c['N']} (of {c['Nm']})" for case, c in cases.items()))
    for k, t in _timed(calls, args.rounds).items():
        print(f"{k:60s} {t * 1e6:9.2f} us")


if __name__ == "__main__":
    main()
