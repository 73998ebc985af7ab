"""Forward-dynamics speed of the rigid engine against Pinocchio's ``aba``, measured in the same process.

For chains and random trees of N revolute/prismatic bodies (fixed base), time one Python-level call of
``MultibodySystem.forward_dynamics(q, u, tau)`` and of ``pinocchio.aba(model, data, q, v, tau)`` on the
same URDF, report our time / Pinocchio's time, and fit the log-log slope of time versus N (1 = O(N)).
The two calls are interleaved in alternating batches and the minimum over batches is kept, so load on
this shared machine affects both sides alike.

Run: ``python benchmarks/rigid_vs_pinocchio.py [--sizes 7 30 100 300 1000] [--repeat 7]``
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np
import pinocchio as pin

from dynamics import Multibody
from dynamics.samples import random_urdf


def best_time(fn, batch, repeat):
    best = np.inf
    for _ in range(repeat):
        t0 = time.perf_counter()
        for _ in range(batch):
            fn()
        best = min(best, (time.perf_counter() - t0) / batch)
    return best


def measure(n, topology, repeat, workdir):
    path = Path(workdir) / f"{topology}_{n}.urdf"
    path.write_text(random_urdf(n, topology=topology, seed=n))
    system = Multibody.from_urdf(path).compile()
    model = pin.buildModelFromUrdf(str(path))
    data = model.createData()
    rng = np.random.default_rng(n)
    q = rng.uniform(-1, 1, system.nq)
    u = rng.standard_normal(system.nu)
    tau = rng.standard_normal(system.nu)
    # same numbers in Pinocchio's order (all joints are 1-DOF, so only a permutation)
    perm = np.array([model.joints[model.getJointId(j)].idx_q for j in system.joint_names])
    qp, vp, taup = (np.empty(model.nq) for _ in range(3))
    qp[perm], vp[perm], taup[perm] = q, u, tau
    ours = system.forward_dynamics(q, u, tau)
    theirs = pin.aba(model, data, qp, vp, taup)[perm]
    rel = np.linalg.norm(ours - theirs) / np.linalg.norm(theirs)
    batch = max(20, 20000 // n)
    t_ours = t_pin = np.inf
    for _ in range(repeat):  # interleave so drifts in machine load hit both
        t_ours = min(t_ours, best_time(lambda: system.forward_dynamics(q, u, tau), batch, 1))
        t_pin = min(t_pin, best_time(lambda: pin.aba(model, data, qp, vp, taup), batch, 1))
    return t_ours, t_pin, rel


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[7, 30, 100, 300, 1000])
    parser.add_argument("--repeat", type=int, default=7)
    args = parser.parse_args(argv)
    rows = []
    with tempfile.TemporaryDirectory() as workdir:
        measure(7, "chain", 1, workdir)  # load the numba cache before timing
        for topology in ("chain", "tree"):
            for n in args.sizes:
                t_ours, t_pin, rel = measure(n, topology, args.repeat, workdir)
                rows.append((topology, n, t_ours, t_pin, rel))
    print(f"Pinocchio {pin.__version__}; per-call forward dynamics from Python (best of {args.repeat})")
    print("| topology | N | flexshell (us) | Pinocchio aba (us) | ratio | rel. diff. |")
    print("| --- | ---: | ---: | ---: | ---: | ---: |")
    for topology, n, t_ours, t_pin, rel in rows:
        print(f"| {topology} | {n} | {t_ours * 1e6:.2f} | {t_pin * 1e6:.2f} | {t_ours / t_pin:.2f} | {rel:.1e} |")
    for topology in ("chain", "tree"):
        sel = [(n, to, tp) for top, n, to, tp, _ in rows if top == topology and n >= 30]
        if len(sel) >= 2:
            n_arr = np.log([s[0] for s in sel])
            slope_ours = np.polyfit(n_arr, np.log([s[1] for s in sel]), 1)[0]
            slope_pin = np.polyfit(n_arr, np.log([s[2] for s in sel]), 1)[0]
            print(f"log-log slope of time vs N (N >= 30), {topology}: flexshell {slope_ours:.3f}, "
                  f"Pinocchio {slope_pin:.3f}")


if __name__ == "__main__":
    main()
