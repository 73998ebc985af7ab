"""Forward-dynamics cost of flexible bodies versus their number of modes and of trees versus their size.

Part 1, modes: one flexible body on a free hinge carrying a rigid wheel on a revolute hinge at one of
its nodes (so the modal elimination includes a child, as in a spacecraft), one call of
``system.forward_dynamics(q, u, tau)`` (articulated-body solver) at 10 / 50 / 200 / 1000 modes for each
set of terms of M(eta):

* order 0 (M0 only);
* order 1 with point-mass nodes (J1, p1, F1: no G1);
* order 2 with point-mass nodes (adds J2 only);
* order 1 with rotary node inertia (adds G1: O(n^3), and the modal mass is factored per call);
* order 2 with rotary node inertia (adds F2, O(n^3), and G2, O(n^4)).

The modal data come from ``dynamics.flex.modal_integrals`` (computed only up to the order used) for
random mode shapes on 400 point-mass nodes, or 100 nodes with rotary inertia and CG offsets. A size is skipped where its
tables do not fit (G1 and F2 at 1000 modes: 3e9 numbers, G2 above 50 modes: n^4), and the row says so.
Log-log slopes are fitted over the sizes >= 50 (below that the per-call Python and dispatch overhead of
a few microseconds dominates).

Part 2, bodies: chains (each body hinged at the previous one's tip node) and random trees of N = 1 .. 64
flexible bodies with 10 modes each (order 1, point-mass nodes); ABA against the dense solve
(``compile(solver="dense")``) in the same process, and the log-log slopes for N >= 4.

Timing: minimum over interleaved batches of the wall time of one call (process-level ratios on a shared
machine; set OPENBLAS_NUM_THREADS=1). Run: ``python benchmarks/flexible_scaling.py [--quick]``.
"""

from __future__ import annotations

import argparse
import os
import time

import numpy as np

from dynamics import Multibody
from dynamics.flex.modal_integrals import modal_integrals
from dynamics.flexible_body import FlexibleBodyData, mass_terms_from_integrals, rigid_mass_block


def flexible_data(n_modes, seed, order, rotary, omit=()):
    """FlexibleBodyData of a random body: ``rotary`` nodes (100, with inertia and CG offsets) or point
    masses (400 nodes); enough translational DOFs for a well-conditioned modal mass at the sizes used."""
    rng = np.random.default_rng(seed)
    n_nodes = 100 if rotary else 400
    mass = rng.uniform(0.5, 2.0, n_nodes)
    position = np.column_stack([np.linspace(0.0, 2.0, n_nodes), rng.uniform(-0.3, 0.3, (n_nodes, 2))])
    shapes = 0.2 * rng.standard_normal((n_nodes, 6, n_modes))
    if rotary:
        cg = rng.uniform(-0.02, 0.02, (n_nodes, 3))
        inertia = np.array([0.05 * np.eye(3)] * n_nodes)
    else:
        cg = np.zeros((n_nodes, 3))
        inertia = np.zeros((n_nodes, 3, 3))
    if not rotary:  # identically zero for point masses: not built (n^3, n^4 arrays of zeros)
        omit = tuple(set(omit) | {"G1", "F2", "G2"})
    mi = modal_integrals(mass, cg, inertia, position, shapes[:, :3], shapes[:, 3:], order=order, omit=omit,
                         max_g2_modes=10_000)
    omega = 2 * np.pi * np.linspace(1.0, 20.0, n_modes)
    return FlexibleBodyData(n_modes=n_modes, order=order, M0=rigid_mass_block(mi), M1=None, M2=None,
                            stiffness=np.diag(omega**2), damping=np.diag(0.02 * omega),
                            grid_ids=np.arange(1, n_nodes + 1), grid_positions=position, grid_shapes=shapes,
                            frequencies_hz=omega / (2 * np.pi), terms=mass_terms_from_integrals(mi, order))


def body_with_wheel(data):
    mb = Multibody()
    mb.add_flexible_body("structure", None, modal=data, hinge="free")
    mb.add_node("mount", "structure", grid=len(data.grid_ids) // 2)
    mb.add_body("wheel", "structure", mass=10.0, inertia=[20.0, 10.0, 10.0], hinge="revolute", axis=(1.0, 0.0, 0.0),
                parent_node="mount")
    return mb.compile(solver="aba")  # the recursion's cost per body (compile() would pick dense at 10 modes)


def chain(n_bodies, n_modes, tree=False, solver=None, seed=0):
    rng = np.random.default_rng(seed)
    mb = Multibody()
    for i in range(n_bodies):
        data = flexible_data(n_modes, i, 1, rotary=False)
        parent = None if i == 0 else (f"b{int(rng.integers(i))}" if tree else f"b{i - 1}")
        kwargs = {"hinge": "free"} if i == 0 else {"hinge": "revolute", "axis": (0.0, 0.0, 1.0),
                                                   "parent_node": f"{parent}.tip"}
        mb.add_flexible_body(f"b{i}", parent, modal=data, **kwargs)
        mb.add_node(f"b{i}.tip", f"b{i}", grid=len(data.grid_ids))
    return mb.compile(solver=solver)


def state(system, seed=0):
    rng = np.random.default_rng(seed)
    q = system.neutral_configuration()
    q += 0.01 * rng.standard_normal(system.nq)
    system.normalize_quaternions(q)
    return q, rng.standard_normal(system.nu), rng.standard_normal(system.nu)


def best(fns, rounds=25, target=0.02):
    """Minimum time per call of each function, batches interleaved (``target`` s per batch)."""
    batches = []
    for fn in fns:
        fn()
        t0 = time.perf_counter()
        fn()
        batches.append(max(1, int(target / max(time.perf_counter() - t0, 1e-7))))
    out = [np.inf] * len(fns)
    for _ in range(rounds):
        for k, fn in enumerate(fns):
            t0 = time.perf_counter()
            for _ in range(batches[k]):
                fn()
            out[k] = min(out[k], (time.perf_counter() - t0) / batches[k])
    return out


def slope(xs, ts):
    pts = [(x, t) for x, t in zip(xs, ts) if x >= 50 and np.isfinite(t)]
    if len(pts) < 2:
        return float("nan")
    return float(np.polyfit(np.log([p[0] for p in pts]), np.log([p[1] for p in pts]), 1)[0])


CASES = [  # label, order, rotary nodes, omitted terms, largest size whose tables fit
    ("order 0", 0, False, (), 1000),
    ("order 1, point masses (no G1)", 1, False, (), 1000),
    ("order 2, point masses (J2 only)", 2, False, (), 1000),
    ("order 1, rotary inertia (G1)", 1, True, (), 200),
    ("order 2, rotary inertia (F2, G2)", 2, True, (), 50),
]


def modes_table(sizes):
    print("Part 1: one flexible body with a wheel at a node, forward dynamics per call (us)")
    print("| terms | " + " | ".join(f"n = {n}" for n in sizes) + " | slope (n >= 50) |")
    print("| --- | " + " | ".join("---:" for _ in sizes) + " | ---: |")
    for label, order, rotary, omit, largest in CASES:
        times = []
        for n in sizes:
            if n > largest:
                times.append(np.nan)
                continue
            system = body_with_wheel(flexible_data(n, 1, order, rotary, omit))
            q, u, tau = state(system)
            dense_ref = np.linalg.solve(system.mass_matrix(q), tau - system.bias_forces(q, u))
            got = system.forward_dynamics(q, u, tau)
            assert np.linalg.norm(got - dense_ref) < 1e-8 * np.linalg.norm(dense_ref), label
            times.append(best([lambda: system.forward_dynamics(q, u, tau)], rounds=7 if n >= 200 else 15)[0])
        cells = [f"{t * 1e6:.1f}" if np.isfinite(t) else "tables too large" for t in times]
        print(f"| {label} | " + " | ".join(cells) + f" | {slope(sizes, times):.2f} |")


def bodies_table(counts, n_modes=10):
    print(f"\nPart 2: trees of flexible bodies ({n_modes} modes each, order 1, point masses), per call (us)")
    print("| topology | N | nu | ABA | dense | dense / ABA | chosen solver |")
    print("| --- | ---: | ---: | ---: | ---: | ---: | --- |")
    for tree in (False, True):
        rows = []
        for N in counts:
            aba = chain(N, n_modes, tree, solver="aba")
            dense = chain(N, n_modes, tree, solver="dense")
            chosen = chain(N, n_modes, tree).solver
            q, u, tau = state(aba)
            a = aba.forward_dynamics(q, u, tau)
            d = dense.forward_dynamics(q, u, tau)
            assert np.linalg.norm(a - d) < 1e-9 * np.linalg.norm(d)
            t_aba, t_dense = best([lambda: aba.forward_dynamics(q, u, tau), lambda: dense.forward_dynamics(q, u, tau)])
            rows.append((N, t_aba, t_dense))
            print(f"| {'tree' if tree else 'chain'} | {N} | {aba.nu} | {t_aba * 1e6:.1f} | {t_dense * 1e6:.1f} | "
                  f"{t_dense / t_aba:.2f} | {chosen} |")
        big = [r for r in rows if r[0] >= 4]
        logn = np.log([r[0] for r in big])
        print(f"log-log slope vs N (N >= 4), {'tree' if tree else 'chain'}: ABA "
              f"{np.polyfit(logn, np.log([r[1] for r in big]), 1)[0]:.2f}, dense "
              f"{np.polyfit(logn, np.log([r[2] for r in big]), 1)[0]:.2f}")


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--modes", type=int, nargs="+", default=[10, 50, 200, 1000])
    parser.add_argument("--bodies", type=int, nargs="+", default=[1, 2, 4, 8, 16, 32, 64])
    parser.add_argument("--quick", action="store_true", help="modes 10 50 200, bodies 1 4 16")
    args = parser.parse_args(argv)
    if args.quick:
        args.modes, args.bodies = [10, 50, 200], [1, 4, 16]
    print(f"load average {os.getloadavg()[0]:.2f} on {os.cpu_count()} cores")
    modes_table(args.modes)
    bodies_table(args.bodies)


if __name__ == "__main__":
    main()
