"""Forward-dynamics cost of flexible bodies versus their number of modes and of trees versus their size.

Part 0, a real deck's general mass: a 9 m aluminium tube (100 CBAR, PARAM COUPMASS -1) with a CONM2 carrying
rotary inertia on every grid (:func:`beam_deck`), through ``dynamics.flex.fem2modal`` at 400 free-free modes
(modal integrals: G1, F2, G2 are then summed over the 101 grids by the engine, and C1, J2 over them too where
cheaper than their tables), on a free hinge with a wheel spinning at 50 rad/s on a revolute hinge at its middle
grid; orders 0, 1 and 2, and 1 and 2 without the terms of the nodes' rotary inertia (what ``order: auto`` keeps
when the node rotations are below 1e-3), at 25, 50, 100, 196 and 400 modes (the file's first modes), one
``forward_dynamics`` call in a state deflected by a lateral tip load (1 cm at the tip), 0.05 rad/s of rate and
modal rates of a tenth of each mode's amplitude times its frequency: per call (us), the refinement passes it took
(``P_REFINEMENTS``), the log-log slope over all sizes and the ratios to order 0 (the five orders of one size
timed in interleaved batches, so that their ratios share the machine's load).
Checked against the dense ``M^-1 (tau - h)`` of the same state.

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

Part 3, the solver choice on bodies whose nodes have rotary inertia (``--solvers``): random bodies of 5 to 107 nodes
(rotary inertia and CG offsets) and 6 to 30 modes, orders 1 and 2, the terms G1, F2, G2 summed over the nodes (and
C1, J2 too on some), with or without a wheel on a node: the articulated-body recursion and the dense solve per call,
interleaved, and what ``dynamics.system.choose_solver`` picks for each.

Timing: minimum over interleaved batches of the wall time of one call (process-level ratios on a shared
machine; set OPENBLAS_NUM_THREADS=1).
Run: ``python benchmarks/flexible_scaling.py [--quick] [--deck-only] [--solvers]``.
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


def beam_deck(n_elements=100, length=9.0):
    """NASTRAN bulk data of the 9 m tube: 100 CBAR, a CONM2 of 0.5 kg with rotary inertia [0.002, 0.01,
    0.01] kg m^2 on every grid (a general mass matrix: rotary inertia at every grid)."""
    lines = ["SOL 103", "CEND", "BEGIN BULK", "PARAM,COUPMASS,-1", "MAT1,1,70.0e9,,0.33,2700.0",
             "PBAR,10,1,6.0e-4,7.0e-7,7.0e-7,1.4e-6"]
    for i in range(n_elements + 1):
        lines += [f"GRID,{i + 1},,{length * i / n_elements:.6f},0.0,0.0", f"CONM2,{1001 + i},{i + 1},,0.5,0.0,0.0,0.0",
                  ",0.002,,0.01,,,0.01"]
    lines += [f"CBAR,{101 + i},10,{i + 1},{i + 2},0.0,1.0,0.0" for i in range(n_elements)]
    return "\n".join(lines + ["ENDDATA"]) + "\n"


def tube_with_wheel(body, n, order, omit=()):
    """Part 0's system: the tube's first ``n`` modes at ``order`` (``omit`` the terms left out) on a free hinge, a
    5 kg wheel on a revolute hinge at its grid 51, articulated-body solver. Shared with
    ``benchmarks/derivative_profile.py``."""
    mb = Multibody()
    mb.add_flexible_body("tube", None, modal=body, hinge="free", modes=range(n), order=order, omit_terms=omit)
    mb.add_node("mount", "tube", grid=51)
    mb.add_body("wheel", "tube", mass=5.0, inertia=[0.1, 0.06, 0.06], hinge="revolute", axis=(1.0, 0.0, 0.0),
                parent_node="mount")
    return mb.compile(solver="aba")


def deflected_state(system, body, n, tip_deflection, rate):
    """A vibrating state of a flexible body on a free hinge (the first of ``system``'s bodies; ``q = [quaternion,
    position, eta, ...]``, ``u = [omega, v, eta_dot, ...]``): the static deflection under a lateral tip load
    (``eta_r = gamma_tip,r F / k_r``) scaled to ``tip_deflection`` m at the tip, modal rates of a tenth of that
    amplitude times each mode's frequency, and ``rate`` rad/s about z. Shared with ``benchmarks/derivative_profile.py``."""
    q, u = system.neutral_configuration(), np.zeros(system.nu)
    tip = body.translation_shapes[-1][:, :n]
    omega = 2 * np.pi * np.asarray(body.frequencies_hz[:n])
    eta = (tip[1] + tip[2]) / omega ** 2
    q[7:7 + n] = tip_deflection * eta / np.abs(tip @ eta).max()
    u[2] = rate
    u[6:6 + n] = 0.1 * omega * q[7:7 + n]
    return q, u


def deck_table(sizes):
    """Part 0 (module docstring)."""
    import tempfile

    from dynamics import layout
    from dynamics.flex.pipeline import Fem2ModalOptions, fem2modal

    with tempfile.TemporaryDirectory() as tmp:
        path = os.path.join(tmp, "tube.dat")
        with open(path, "w") as fh:
            fh.write(beam_deck())
        body = fem2modal(path, Fem2ModalOptions(n_modes=max(sizes), modal_integrals=True))
    print(f"Part 0: 9 m tube, 100 CBAR + CONM2 rotary inertia on every grid, free hinge + wheel, forward dynamics "
          f"per call (us) [refinement passes]")
    print("| order | " + " | ".join(f"n = {n}" for n in sizes) + " | slope | / order 0 at 196 |")
    print("| --- | " + " | ".join("---:" for _ in sizes) + " | ---: | ---: |")
    cases = ((0, ()), (1, ()), (2, ()), (1, ("G1",)), (2, ("G1", "F2", "G2")))
    times = {case: [] for case in cases}
    passes = {case: [] for case in cases}
    for n in sizes:
        calls = []
        for order, omit in cases:
            system = tube_with_wheel(body, n, order, omit)
            q, u = deflected_state(system, body, n, tip_deflection=0.01, rate=0.05)
            u[-1] = 50.0
            tau = np.zeros(system.nu)
            got = system.forward_dynamics(q, u, tau)
            dense = np.linalg.solve(system.mass_matrix(q), tau - system.bias_forces(q, u))
            assert np.linalg.norm(got - dense) < 1e-8 * np.linalg.norm(dense), (order, n)
            passes[order, omit].append(int(system.pool[layout.P_REFINEMENTS]))
            calls.append(lambda system=system, q=q, u=u, tau=tau: system.forward_dynamics(q, u, tau))
        for case, t in zip(cases, best(calls, rounds=7)):  # the orders interleaved: ratios on a shared machine
            times[case].append(t)
    k = sizes.index(196) if 196 in sizes else -1
    for case in cases:
        order, omit = case
        row = times[case]
        fit = float(np.polyfit(np.log(sizes), np.log(row), 1)[0])
        label = f"{order}" + (f" without {', '.join(omit)}" if omit else "")
        print(f"| {label} | " + " | ".join(f"{t * 1e6:.1f} [{p}]" for t, p in zip(row, passes[case]))
              + f" | {fit:.2f} | {row[k] / times[0, ()][k]:.2f} |")


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


def node_body(n_nodes, n_modes, order, node_mass=False, seed=3):
    """FlexibleBodyData of a random body of ``n_nodes`` nodes with rotary inertia and CG offsets, the terms G1, F2, G2
    summed over the nodes and, with ``node_mass``, C1 and J2 too (the rest as tables)."""
    import dataclasses

    from dynamics.flex.modal_integrals import modal_integrals as integrals
    from dynamics.flexible_body import node_inertia_from_nodes, node_mass_from_nodes

    rng = np.random.default_rng(seed)
    mass = rng.uniform(0.5, 2.0, n_nodes)
    cg = rng.uniform(-0.05, 0.05, (n_nodes, 3))
    inertia = np.array([0.01 * (a @ a.T + 0.5 * np.eye(3)) for a in rng.standard_normal((n_nodes, 3, 3))])
    position = np.column_stack([np.linspace(0.0, 2.0, n_nodes), rng.uniform(-0.4, 0.4, (n_nodes, 2))])
    shapes = 0.3 * rng.standard_normal((n_nodes, 6, n_modes))
    omega = 2 * np.pi * np.sort(rng.uniform(0.5, 5.0, n_modes))
    mi = integrals(mass, cg, inertia, position, shapes[:, :3], shapes[:, 3:], order=order, omit=("G1", "F2", "G2"))
    data = FlexibleBodyData(n_modes=n_modes, order=order, M0=rigid_mass_block(mi), M1=None, M2=None,
                            stiffness=np.diag(omega**2), damping=np.diag(0.02 * omega),
                            grid_ids=np.arange(1, n_nodes + 1), grid_positions=position, grid_shapes=shapes,
                            frequencies_hz=omega / (2 * np.pi), terms=mass_terms_from_integrals(mi, order),
                            node_inertia=node_inertia_from_nodes(mass, cg, inertia, shapes, order))
    if node_mass:
        data = dataclasses.replace(data, terms=dataclasses.replace(data.terms, C1=None, J2=None),
                                   mass_nodes=node_mass_from_nodes(mass, cg, inertia, position, shapes, order))
    return data


SOLVER_DECKS = [  # nodes, modes, order, C1 and J2 over the nodes, a wheel on a node
    (9, 6, 1, False, False), (9, 6, 2, False, False), (9, 6, 2, True, False), (5, 12, 2, True, False),
    (30, 12, 1, False, True), (107, 20, 2, False, False), (107, 20, 1, False, True), (20, 30, 2, True, False),
]


def solvers_table():
    """Part 3 (module docstring)."""
    from dynamics.system import choose_solver

    print("\nPart 3: bodies with rotary node inertia (G1, F2, G2 over the nodes), forward dynamics per call (us)")
    print("| nodes | modes | order | C1, J2 over nodes | wheel | ABA | dense | dense / ABA | chosen |")
    print("| ---: | ---: | ---: | --- | --- | ---: | ---: | ---: | --- |")
    rng = np.random.default_rng(0)
    for n_nodes, n_modes, order, node_mass, wheel in SOLVER_DECKS:
        data = node_body(n_nodes, n_modes, order, node_mass)
        systems = []
        for solver in ("aba", "dense"):
            mb = Multibody()
            mb.add_flexible_body("body", None, modal=data, hinge="free")
            if wheel:
                mb.add_node("mount", "body", grid=3)
                mb.add_body("wheel", "body", mass=4.0, inertia=[0.08, 0.05, 0.05], hinge="revolute",
                            axis=(1.0, 0.0, 0.0), parent_node="mount")
            systems.append(mb.compile(solver=solver))
        aba, dense = systems
        q = aba.neutral_configuration()
        q[7:7 + n_modes] = 0.01 * rng.standard_normal(n_modes)
        u, tau = rng.standard_normal(aba.nu), rng.standard_normal(aba.nu)
        a, d = aba.forward_dynamics(q, u, tau), dense.forward_dynamics(q, u, tau)
        assert np.linalg.norm(a - d) < 1e-9 * np.linalg.norm(d)
        t_aba, t_dense = best([lambda: aba.forward_dynamics(q, u, tau), lambda: dense.forward_dynamics(q, u, tau)])
        print(f"| {n_nodes} | {n_modes} | {order} | {'yes' if node_mass else 'no'} | {'yes' if wheel else 'no'} | "
              f"{t_aba * 1e6:.1f} | {t_dense * 1e6:.1f} | {t_dense / t_aba:.2f} | {choose_solver(aba.topology)[0]} |")


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--modes", type=int, nargs="+", default=[10, 50, 200, 1000])
    parser.add_argument("--bodies", type=int, nargs="+", default=[1, 2, 4, 8, 16, 32, 64])
    parser.add_argument("--deck-modes", type=int, nargs="+", default=[25, 50, 100, 196, 400])
    parser.add_argument("--quick", action="store_true", help="modes 10 50 200, bodies 1 4 16")
    parser.add_argument("--deck-only", action="store_true", help="part 0 only")
    parser.add_argument("--solvers", action="store_true", help="part 3 only")
    args = parser.parse_args(argv)
    if args.quick:
        args.modes, args.bodies = [10, 50, 200], [1, 4, 16]
    print(f"load average {os.getloadavg()[0]:.2f} on {os.cpu_count()} cores")
    if args.solvers:
        solvers_table()
        return
    deck_table(args.deck_modes)
    if args.deck_only:
        return
    modes_table(args.modes)
    bodies_table(args.bodies)
    solvers_table()


if __name__ == "__main__":
    main()
