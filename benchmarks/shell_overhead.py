"""Orchestration cost of the shell: derivative cost versus number of models, compiled and interpreted, and
the compile time of the compiled loop, cold and warm.

1. Scenes of 10, 50 and 200 trivial models (integrators x' = u, each fed back through a direct-feedthrough
   gain u = -k x, so half the models are on the output path and half on the derivative path). Per
   derivative evaluation: the interpreted plan (``Simulation.derivative``: Python loop over the kernels),
   and the compiled loop measured from a whole run (RK4, 4 evaluations per step, no sampled models: wall
   time / derivative evaluations), next to a hand-written numba function of the same equations (the floor
   any framework could reach). Target of issue 13: <= 0.1 us per model.
2. Compile time, each in fresh processes (import included): the 200-model scene with an empty numba cache
   (``NUMBA_CACHE_DIR`` pointed at a new directory: everything flexshell compiles for it, i.e. the compiled loop
   and the two block kernels), then again with that cache (warm). Targets of issue 13: cold <= 30 s, warm
   <= 2 s. Then the same for the demo scene (``configs/demo_attitude_hold.yaml``, 1 s), which also compiles
   the multibody engine (once per installation; a scene without the engine does not compile it).

Run: ``python benchmarks/shell_overhead.py [--rounds 7] [--skip-compile]``. Times are medians of
interleaved rounds on whatever load the machine has (printed); compare ratios, not absolute times.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time

import numpy as np
from numba import njit

from shell.assembly import Assembly
from shell.models.blocks import Gain, Integrator
from shell.simulation import Simulation


def trivial_scene(n_models: int) -> Assembly:
    root = Assembly("root")
    for i in range(n_models // 2):
        root.add(Integrator(f"x{i}", unit="m"))
        root.children[f"x{i}"].set_initial("x", 1.0)
        root.add(Gain(f"k{i}", unit="m", output_unit="m/s", k=f"{-1e-3 * (i + 1)} 1/s"))
        root.connect(f"x{i}.y", f"k{i}.u")
        root.connect(f"k{i}.y", f"x{i}.u")
    return root


@njit(cache=True)
def hand_written(t, y, out):
    for i in range(y.shape[0]):
        out[i] = -1e-3 * (i + 1.0) * y[i]


def compiled_per_derivative(n_models: int, steps: int = 4000) -> float:
    sim = Simulation(trivial_scene(n_models), step=1e-3)
    assert sim.mode == "compiled"
    sim.run(1e-3)  # load
    summary = sim.run(sim.t + steps * 1e-3)
    return summary.wall_time / summary.derivative_evaluations


def interpreted_per_derivative(n_models: int, calls: int = 200) -> float:
    sim = Simulation(trivial_scene(n_models), mode="interpreted")
    y = sim.x.copy()
    started = time.perf_counter()
    for _ in range(calls):
        sim.derivative(0.0, y)
    return (time.perf_counter() - started) / calls


def hand_per_derivative(n_models: int, calls: int = 20000) -> float:
    y = np.ones(n_models // 2)
    out = np.empty_like(y)
    hand_written(0.0, y, out)
    started = time.perf_counter()
    for _ in range(calls):
        hand_written(0.0, y, out)
    return (time.perf_counter() - started) / calls


SCENE_200 = """
import time
started = time.perf_counter()
from benchmarks.shell_overhead import trivial_scene
from shell.simulation import Simulation
sim = Simulation(trivial_scene(200), step=1e-3)
sim.run(0.01)
assert sim.mode == "compiled"
print(time.perf_counter() - started)
"""

SCENE_ENGINE = """
import time
started = time.perf_counter()
from shell.scenario import build_simulation, load_scenario
scenario = load_scenario("configs/demo_attitude_hold.yaml", ["stop.time=1 s"])
build_simulation(scenario).run(scenario.t_final)
print(time.perf_counter() - started)
"""


def compile_times(script: str) -> tuple[float, float]:
    """(cold, warm) wall seconds of ``script`` in fresh processes: first with an empty numba cache, then with
    the cache the first one wrote."""
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    with tempfile.TemporaryDirectory() as cache:
        env = dict(os.environ, NUMBA_CACHE_DIR=cache, PYTHONPATH=root)
        seconds = []
        for _ in range(2):
            out = subprocess.run([sys.executable, "-c", script], cwd=root, env=env, capture_output=True,
                                 text=True, check=True)
            seconds.append(float(out.stdout.strip().splitlines()[-1]))
    return seconds[0], seconds[1]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=7)
    parser.add_argument("--skip-compile", action="store_true")
    args = parser.parse_args()
    print(f"load: {os.getloadavg()[0]:.2f} (1-min average, {os.cpu_count()} cores)")
    sizes = (10, 50, 200)
    results = {n: {"compiled": [], "interpreted": [], "hand": []} for n in sizes}
    for _ in range(args.rounds):
        for n in sizes:
            results[n]["compiled"].append(compiled_per_derivative(n))
            results[n]["interpreted"].append(interpreted_per_derivative(n))
            results[n]["hand"].append(hand_per_derivative(n))
    print(f"\n{'models':>7s} {'interpreted us':>15s} {'compiled us':>12s} {'hand numba us':>14s} "
          f"{'compiled us/model':>18s} {'interpreted/compiled':>21s}")
    for n in sizes:
        med = {k: float(np.median(v)) * 1e6 for k, v in results[n].items()}
        print(f"{n:7d} {med['interpreted']:15.2f} {med['compiled']:12.3f} {med['hand']:14.3f} "
              f"{med['compiled'] / n:18.4f} {med['interpreted'] / med['compiled']:21.1f}")
    if not args.skip_compile:
        print(f"\nfresh process, import + build + compile or load + run (load {os.getloadavg()[0]:.2f}):")
        for label, script in (("200 trivial models (targets: cold <= 30 s, warm <= 2 s)", SCENE_200),
                              ("demo scene with the multibody engine", SCENE_ENGINE)):
            cold, warm = compile_times(script)
            print(f"  {label}: cold cache {cold:.1f} s, warm {warm:.1f} s")


if __name__ == "__main__":
    main()
