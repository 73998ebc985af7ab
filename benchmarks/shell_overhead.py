"""Orchestration cost of the shell per derivative evaluation, next to the engine's own cost.

Measured in one process, interleaved batches, minimum over batches (shared machine):

1. 20 trivial models (10 integrators x' = u, each fed back through a direct-feedthrough gain
   u = -k x): the interpreted derivative (Simulation.derivative: Python loop over numba kernels and
   input gathers) and the same plan compiled into one function (shell.fused), against a hand-written
   numba function of the same 10 equations (the floor any framework could reach).
2. The multibody engine alone: ``forward_dynamics`` + ``q_dot`` of the demo's single free body and of a
   10-body revolute chain, called directly; then the same engines inside the shell (MultibodyModel with
   its inputs wired), alone and with the 20 trivial models added to the scene.

Run: ``python benchmarks/shell_overhead.py [--rounds 30]``; prints a table of microseconds per call.
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from numba import njit

from dynamics import Multibody
from shell.assembly import Assembly
from shell.models.blocks import Constant, Gain, Integrator
from shell.models.multibody import MultibodyModel
from shell.simulation import Simulation


def add_trivial_models(root: Assembly, pairs: int = 10) -> None:
    for i in range(pairs):
        root.add(Integrator(f"x{i}", unit="m"))
        root.add(Gain(f"k{i}", unit="m", output_unit="m/s", k=f"{-(i + 1)} 1/s"))
        root.connect(f"x{i}.y", f"k{i}.u")
        root.connect(f"k{i}.y", f"x{i}.u")


@njit(cache=True)
def hand_written(t, y, out):
    for i in range(y.shape[0]):
        out[i] = -(i + 1.0) * y[i]


def free_body():
    mb = Multibody()
    mb.add_body("bus", None, mass=500.0, inertia=np.diag([400.0, 300.0, 250.0]), hinge="free")
    mb.add_node("acs", "bus")
    return mb.compile()


def chain(n=10):
    mb = Multibody(gravity=(0.0, 0.0, -9.81))
    parent = None
    for i in range(n):
        mb.add_body(f"link{i}", parent, mass=1.0, com=(0.5, 0, 0), inertia=np.diag([1e-3, 0.1, 0.1]),
                    hinge="revolute", axis=(0, 0, 1) if i % 2 else (0, 1, 0),
                    inboard_position=(1.0, 0, 0) if parent else (0, 0, 0))
        parent = f"link{i}"
    mb.add_node("tip", parent, position=(1.0, 0, 0))
    return mb.compile()


def engine_scene(system, trivial: bool):
    root = Assembly("root")
    root.add(MultibodyModel("multibody", system))
    node = system.node_names[0]
    root.add(Constant("torque", unit="N*m", shape=(3,), value=[0.1, 0.2, 0.3]))
    root.connect("torque.y", f"multibody.{node}.torque")
    if trivial:
        add_trivial_models(root)
    return Simulation(root)


def best_time(fn, batch, rounds):
    best = np.inf
    for _ in range(rounds):
        t0 = time.perf_counter()
        for _ in range(batch):
            fn()
        best = min(best, (time.perf_counter() - t0) / batch)
    return best


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=30)
    args = parser.parse_args()
    rows = []

    def trivial_scene():
        root = Assembly("root")
        add_trivial_models(root)
        return root

    sim = Simulation(trivial_scene())
    y = np.linspace(1.0, 2.0, sim.x.size)
    t0 = time.perf_counter()
    fused = Simulation(trivial_scene(), fuse=True).rhs
    fused(0.0, y)
    compile_seconds = time.perf_counter() - t0
    assert np.array_equal(fused(0.0, y), sim.derivative(0.0, y))
    out = np.empty_like(y)
    hand_written(0.0, y, out)
    assert np.array_equal(out, sim.derivative(0.0, y))
    t_interp = best_time(lambda: sim.derivative(0.0, y), 200, args.rounds)
    t_fused = best_time(lambda: fused(0.0, y), 200, args.rounds)
    t_hand = best_time(lambda: hand_written(0.0, y, out), 200, args.rounds)
    rows += [("20 trivial models, interpreted plan", t_interp),
             ("20 trivial models, fused (one compiled function)", t_fused),
             ("same 10 equations, hand-written numba", t_hand)]

    for label, system in (("1 free body", free_body()), ("10-body revolute chain", chain())):
        q = system.neutral_configuration()
        u = np.full(system.nu, 0.01)
        forces = np.zeros((system.nnodes, 6))
        forces[0, :3] = (0.1, 0.2, 0.3)
        tau = np.zeros(system.nu)

        def engine_call():
            system.forward_dynamics(q, u, tau, forces)
            system.q_dot(q, u)

        alone = engine_scene(system, trivial=False)
        with_trivial = engine_scene(system, trivial=True)
        x = alone.x.copy()
        x[system.nq:] = 0.01
        xt = with_trivial.x.copy()
        xt[:x.size] = x
        np.testing.assert_allclose(alone.derivative(0.0, x)[system.nq:],
                                   system.forward_dynamics(x[:system.nq], x[system.nq:], tau, forces), rtol=1e-14)
        rows += [(f"engine direct: {label} (forward_dynamics + q_dot)",
                  best_time(engine_call, 100, args.rounds)),
                 (f"shell: {label} as MultibodyModel + torque source",
                  best_time(lambda: alone.derivative(0.0, x), 100, args.rounds)),
                 (f"shell: {label} + 20 trivial models",
                  best_time(lambda: with_trivial.derivative(0.0, xt), 100, args.rounds))]

    print(f"{'derivative evaluation':60s} {'us/call':>9s}")
    for label, seconds in rows:
        print(f"{label:60s} {seconds * 1e6:9.2f}")
    print(f"\norchestration per trivial model (interpreted): {t_interp / 20 * 1e6:.2f} us; "
          f"fused / interpreted = {t_fused / t_interp:.3f}; fused / hand-written = {t_fused / t_hand:.2f}; "
          f"fusion compile time {compile_seconds:.1f} s")


if __name__ == "__main__":
    main()
