"""Forward-dynamics speed of the rigid engine against Pinocchio's ``aba``, measured in the same process.

For chains and random trees of N revolute/prismatic bodies (fixed base), time one Python-level call of
``MultibodySystem.forward_dynamics(q, u, tau)`` and of ``pinocchio.aba(model, data, q, v, tau)`` on the
same URDF, report our time / Pinocchio's time, and fit the log-log slope of time versus N (1 = O(N)).
The two calls are interleaved in many short alternating batches and the minimum over batches is kept,
so load on this shared machine affects both sides alike. A third column times the engine's entry point
called from compiled code on the engine data (what the shell's compiled loop pays per derivative: the
recursion without the Python-to-numba boundary), so the difference to the Python call is its overhead.

Pinocchio's ``Data`` grows faster than N^2 in memory for long chains (1.9 GB at N = 300, 8 GB at
N = 500, measured with pin 4.1), so at N = 1000 it cannot be allocated on a 24 GB machine; above
``--pinocchio-max-n`` only flexshell is timed and the row says so.

Run: ``python benchmarks/rigid_vs_pinocchio.py [--sizes 7 30 100 300 1000] [--repeat 7]``
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np
import pinocchio as pin
from numba import njit
from threadpoolctl import threadpool_limits

from dynamics import Multibody
from dynamics import engine as E
from dynamics.samples import random_urdf


@njit(cache=True)
def compiled_calls(d, q, u, tau, node_forces, udot, tau_out, calls):
    """``calls`` forward dynamics from compiled code, the engine data borrowed as the compiled loop does."""
    d = E.borrowed(d)
    status = 0
    for _ in range(calls):
        status |= E.forward_dynamics_articulated(d, q, u, tau, node_forces, udot, tau_out)
    return status


def batch_time(fn, batch):
    t0 = time.perf_counter()
    for _ in range(batch):
        fn()
    return (time.perf_counter() - t0) / batch


def measure(n, topology, repeat, workdir, with_pinocchio):
    path = Path(workdir) / f"{topology}_{n}.urdf"
    path.write_text(random_urdf(n, topology=topology, seed=n))
    system = Multibody.from_urdf(path).compile()
    rng = np.random.default_rng(n)
    q = rng.uniform(-1, 1, system.nq)
    u = rng.standard_normal(system.nu)
    tau = rng.standard_normal(system.nu)
    batch = max(2, 300 // n)
    rounds = 40 * repeat
    ours = lambda: system.forward_dynamics(q, u, tau)  # noqa: E731
    d = E.engine_data(system)
    node_forces, udot, tau_out = np.zeros((system.nnodes, 6)), np.zeros(system.nu), np.empty(system.nu)
    compiled = lambda: compiled_calls(d, q, u, tau, node_forces, udot, tau_out, batch)  # noqa: E731
    compiled()
    if not np.array_equal(udot, ours()):
        raise AssertionError("the compiled entry point and the Python call disagree")
    if not with_pinocchio:
        t_ours = t_compiled = np.inf
        for _ in range(rounds):
            t_ours = min(t_ours, batch_time(ours, batch))
            t_compiled = min(t_compiled, batch_time(compiled, 1) / batch)
        return t_ours, t_compiled, np.nan, np.nan
    model = pin.buildModelFromUrdf(str(path))
    data = model.createData()
    # same numbers in Pinocchio's order (all joints are 1-DOF, so only a permutation)
    perm = np.array([model.joints[model.getJointId(j)].idx_q for j in system.joint_names])
    qp, vp, taup = (np.empty(model.nq) for _ in range(3))
    qp[perm], vp[perm], taup[perm] = q, u, tau
    theirs = pin.aba(model, data, qp, vp, taup)[perm]
    rel = np.linalg.norm(ours() - theirs) / np.linalg.norm(theirs)
    t_ours = t_compiled = t_pin = np.inf
    for _ in range(rounds):  # interleave so drifts in machine load hit both
        t_ours = min(t_ours, batch_time(ours, batch))
        t_compiled = min(t_compiled, batch_time(compiled, 1) / batch)
        t_pin = min(t_pin, batch_time(lambda: pin.aba(model, data, qp, vp, taup), batch))
    return t_ours, t_compiled, t_pin, rel


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[7, 30, 100, 300, 1000])
    parser.add_argument("--repeat", type=int, default=5, help="x 40 interleaved short batches")
    parser.add_argument("--pinocchio-max-n", type=int, default=500,
                        help="largest N for which Pinocchio's Data is allocated (memory, see above)")
    args = parser.parse_args(argv)
    rows = []
    with tempfile.TemporaryDirectory() as workdir, threadpool_limits(1):
        measure(7, "chain", 1, workdir, True)  # load the numba cache before timing
        for topology in ("chain", "tree"):
            for n in args.sizes:
                rows.append((topology, n) + measure(n, topology, args.repeat, workdir, n <= args.pinocchio_max_n))
    print(f"Pinocchio {pin.__version__}; per-call forward dynamics from Python, minimum over "
          f"{40 * args.repeat} interleaved batches")
    print("| topology | N | flexshell (us) | from compiled code (us) | Pinocchio aba (us) | flexshell / Pinocchio | "
          "rel. diff. |")
    print("| --- | ---: | ---: | ---: | ---: | ---: | ---: |")
    for topology, n, t_ours, t_compiled, t_pin, rel in rows:
        if np.isnan(t_pin):
            print(f"| {topology} | {n} | {t_ours * 1e6:.2f} | {t_compiled * 1e6:.2f} | not allocatable (Data > 24 GB) "
                  f"| - | - |")
        else:
            print(f"| {topology} | {n} | {t_ours * 1e6:.2f} | {t_compiled * 1e6:.2f} | {t_pin * 1e6:.2f} | "
                  f"{t_ours / t_pin:.2f} | {rel:.1e} |")
    for topology in ("chain", "tree"):
        sel = [(n, to, tp) for top, n, to, _, tp, _ in rows if top == topology and n >= 30]
        if len(sel) >= 2:
            n_arr = np.log([s[0] for s in sel])
            slope_ours = np.polyfit(n_arr, np.log([s[1] for s in sel]), 1)[0]
            timed = [s for s in sel if not np.isnan(s[2])]
            slope_pin = np.polyfit(np.log([s[0] for s in timed]), np.log([s[2] for s in timed]), 1)[0] \
                if len(timed) >= 2 else np.nan
            print(f"log-log slope of time vs N (N >= 30), {topology}: flexshell {slope_ours:.3f} "
                  f"(N = {sel[0][0]}..{sel[-1][0]}), Pinocchio {slope_pin:.3f} (N = {timed[0][0]}..{timed[-1][0]})")


if __name__ == "__main__":
    main()
