"""Forward-dynamics cost of trees of flexible bodies: the O(N) recursion against the dense reference.

For chains of N flexible bodies (each with n modes, order-2 modal integrals, hinged to the previous
body's tip node) time ``forward_dynamics`` (augmented articulated-body recursion) and the dense path
``solve(mass_matrix(q), tau - bias_forces(q, u))`` in the same process, and print the ratio and the
log-log slopes against N. Then fix N and sweep n. Run: ``python benchmarks/flexible_scaling.py``.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from dynamics import Multibody
from dynamics.flex.modal_integrals import modal_integrals
from dynamics.flexible_body import FlexibleBodyData, mass_matrix_polynomial


def flexible_data(n_modes, seed, order=2, n_nodes=10):
    rng = np.random.default_rng(seed)
    mass = rng.uniform(0.5, 2.0, n_nodes)
    cg = np.zeros((n_nodes, 3))
    inertia = np.array([0.01 * np.eye(3)] * n_nodes)
    position = np.column_stack([np.linspace(0.0, 2.0, n_nodes), rng.uniform(-0.3, 0.3, (n_nodes, 2))])
    shapes = 0.2 * rng.standard_normal((n_nodes, 6, n_modes))
    mi = modal_integrals(mass, cg, inertia, position, shapes[:, :3], shapes[:, 3:])
    M0, M1, M2 = mass_matrix_polynomial(mi, order)
    omega = 2 * np.pi * np.linspace(1.0, 20.0, n_modes)
    return FlexibleBodyData(n_modes=n_modes, order=order, M0=M0, M1=M1, M2=M2, stiffness=np.diag(omega**2),
                            damping=np.diag(0.02 * omega), grid_ids=np.arange(1, n_nodes + 1),
                            grid_positions=position, grid_shapes=shapes,
                            frequencies_hz=omega / (2 * np.pi))


def chain(n_bodies, n_modes, order=2):
    mb = Multibody()
    for i in range(n_bodies):
        kwargs = {"hinge": "free"} if i == 0 else {"hinge": "revolute", "axis": (0.0, 0.0, 1.0),
                                                   "parent_node": f"tip{i - 1}"}
        mb.add_flexible_body(f"b{i}", None if i == 0 else f"b{i - 1}", modal=flexible_data(n_modes, i, order),
                             **kwargs)
        mb.add_node(f"tip{i}", f"b{i}", grid=10)
    return mb.compile()


def best(fn, rounds=30, batch=3):
    t = np.inf
    for _ in range(rounds):
        t0 = time.perf_counter()
        for _ in range(batch):
            fn()
        t = min(t, (time.perf_counter() - t0) / batch)
    return t


def measure(system, seed=0):
    rng = np.random.default_rng(seed)
    q = system.neutral_configuration()
    q += 0.01 * rng.standard_normal(system.nq)
    system.normalize_quaternions(q)
    u = rng.standard_normal(system.nu)
    tau = rng.standard_normal(system.nu)
    aba = system.forward_dynamics(q, u, tau)
    dense = np.linalg.solve(system.mass_matrix(q), tau - system.bias_forces(q, u))
    err = np.linalg.norm(aba - dense) / np.linalg.norm(dense)
    t_aba = best(lambda: system.forward_dynamics(q, u, tau))
    t_dense = best(lambda: np.linalg.solve(system.mass_matrix(q), tau - system.bias_forces(q, u)))
    return t_aba, t_dense, err


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--bodies", type=int, nargs="+", default=[1, 2, 4, 8, 16, 32, 64])
    parser.add_argument("--modes", type=int, nargs="+", default=[2, 5, 10, 20, 40])
    args = parser.parse_args(argv)
    measure(chain(2, 2))  # compile / load the cache outside the timings
    print("| bodies N | modes n | nu | ABA (us) | dense (us) | dense / ABA | rel. diff. |")
    print("| ---: | ---: | ---: | ---: | ---: | ---: | ---: |")
    rows = []
    for N in args.bodies:
        system = chain(N, 5)
        t_aba, t_dense, err = measure(system)
        rows.append((N, t_aba, t_dense))
        print(f"| {N} | 5 | {system.nu} | {t_aba * 1e6:.1f} | {t_dense * 1e6:.1f} | {t_dense / t_aba:.2f} | {err:.1e} |")
    big = [r for r in rows if r[0] >= 8]
    if len(big) >= 2:
        logn = np.log([r[0] for r in big])
        print(f"log-log slope vs N (N >= 8): ABA {np.polyfit(logn, np.log([r[1] for r in big]), 1)[0]:.2f}, "
              f"dense {np.polyfit(logn, np.log([r[2] for r in big]), 1)[0]:.2f}")
    for n in args.modes:
        system = chain(4, n)
        t_aba, t_dense, err = measure(system)
        print(f"| 4 | {n} | {system.nu} | {t_aba * 1e6:.1f} | {t_dense * 1e6:.1f} | {t_dense / t_aba:.2f} | {err:.1e} |")


if __name__ == "__main__":
    main()
