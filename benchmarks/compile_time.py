"""What a first run and an edit cost in compilation, and where a first run's compilation goes (issue 31).

Every measurement runs on a private copy of the sources (``dynamics/``, ``shell/``, ``configs/``, ``tests/``) with
its own empty numba cache (``NUMBA_CACHE_DIR``; dynamics/compile_cache.py keys each compiled function on its unit),
each step a fresh process running the demo, ``python3 -m shell.cli run configs/demo_attitude_hold.yaml``:

1. ``cold``: empty cache; ``warm``: again;
2. ``comment``: a comment appended to a model file the demo uses (``shell/models/pd_attitude.py``);
3. ``model edit``: that model's update kernel changed (its gain multiplied by 1.0: same numbers, new code);
4. ``kernels edit``: ``dynamics/kernels/kinematics.py``'s ``coordinate_rates`` changed (rates scaled by 1.01), which the
   engine's kernel (``shell/models/multibody.py``) calls through ``dynamics/engine.py``: the engine must recompile,
   and the analytic spin-up test (tests/shell/test_multibody_model.py) must then fail on the edited copy;
5. ``restored``: the sources back as they were: their entries are still cached.

Printed per step: wall and CPU seconds of the process and the seconds numba compiled (the run's notice). ``--rounds``
repeats steps 1 (a fresh cache each round) and reports medians; the machine's load is printed (other processes
share the 2 cores: compare CPU seconds). ``--profile``: one cold demo in this process, and the compile seconds per
function, self (without the functions it compiled) and inclusive. ``--no-inline``: a second copy with every
``inline="always"`` removed: the demo's cold compilation in both, and the run time of the Basilisk race's
reaction-wheel scene (configs/rw_attitude.yaml, 600 s) in both, interleaved (at least 5 rounds).

Run: ``python benchmarks/compile_time.py [--rounds 3] [--profile] [--no-inline]``.
"""

from __future__ import annotations

import argparse
import os
import re
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
DEMO = ["-m", "shell.cli", "run", "configs/demo_attitude_hold.yaml", "-o", "demo.h5"]  # stderr is no TTY: no bar
SPIN_UP_TEST = "tests/shell/test_multibody_model.py::test_constant_torque_spin_up_matches_the_analytic_rotation"
MODEL_FILE = "shell/models/pd_attitude.py"
KERNELS_FILE = "dynamics/kernels/kinematics.py"
KERNELS_EDIT = ("        for k in range(nm):\n            qdot[q0 + k] = u[u0 + k]\n",
                "        for k in range(nm):\n            qdot[q0 + k] = u[u0 + k]\n"
                "    for k in range(qdot.shape[0]):\n        qdot[k] *= 1.01\n")


def copy_sources(destination: Path, no_inline: bool) -> None:
    for part in ("dynamics", "shell", "configs", "tests"):
        shutil.copytree(ROOT / part, destination / part, ignore=shutil.ignore_patterns("__pycache__", "*.h5"))
    shutil.copy(ROOT / "pyproject.toml", destination / "pyproject.toml")
    if no_inline:
        for path in list((destination / "dynamics").rglob("*.py")) + list((destination / "shell").rglob("*.py")):
            text = path.read_text()
            edited = re.sub(r',\s*inline="always"', "", text)
            if edited != text:
                path.write_text(edited)


def run(source: Path, cache: Path, arguments: list[str]) -> dict:
    """Wall and CPU seconds of ``python3 arguments`` in ``source``, and the compile seconds it reported."""
    env = dict(os.environ, PYTHONPATH=str(source), NUMBA_CACHE_DIR=str(cache), PYTHONDONTWRITEBYTECODE="1",
               OMP_NUM_THREADS="1", OPENBLAS_NUM_THREADS="1", MKL_NUM_THREADS="1")
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    started = time.perf_counter()
    done = subprocess.run([sys.executable, *arguments], cwd=source, env=env, capture_output=True, text=True)
    wall = time.perf_counter() - started
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    compiled = re.search(r"compiled in (\d+) s", done.stderr)
    return {"wall": wall, "cpu": after.ru_utime + after.ru_stime - before.ru_utime - before.ru_stime,
            "compile": float(compiled.group(1)) if compiled else 0.0, "returncode": done.returncode,
            "output": done.stdout + done.stderr}


def demo(source: Path, cache: Path, extra=()) -> dict:
    result = run(source, cache, DEMO + list(extra))
    if result["returncode"] != 0:
        raise RuntimeError(result["output"])
    return result


def line(name: str, result: dict) -> str:
    return f"{name:<18} wall {result['wall']:7.1f} s   cpu {result['cpu']:7.1f} s   compiled {result['compile']:5.0f} s"


def edit(path: Path, old: str, new: str) -> None:
    text = path.read_text()
    if old not in text:
        raise RuntimeError(f"{path}: the text to edit was not found; update this benchmark")
    path.write_text(text.replace(old, new, 1))


def steps(rounds: int) -> None:
    print(f"load {os.getloadavg()}")
    with tempfile.TemporaryDirectory() as work:
        source = Path(work) / "src"
        copy_sources(source, no_inline=False)
        colds, warms = [], []
        for r in range(rounds):
            cache = Path(work) / f"cache{r}"
            colds.append(demo(source, cache))
            warms.append(demo(source, cache))
            print(line(f"cold ({r + 1})", colds[-1]))
            print(line(f"warm ({r + 1})", warms[-1]))
        for name, results in (("cold median", colds), ("warm median", warms)):
            print(f"{name:<18} wall {statistics.median(r['wall'] for r in results):7.1f} s   cpu "
                  f"{statistics.median(r['cpu'] for r in results):7.1f} s   compiled "
                  f"{statistics.median(r['compile'] for r in results):5.0f} s")
        originals = {name: (source / name).read_text() for name in (MODEL_FILE, KERNELS_FILE)}
        (source / MODEL_FILE).write_text(originals[MODEL_FILE] + "# a comment\n")
        print(line("comment", demo(source, cache)))
        edit(source / MODEL_FILE, "(-p[P.kp + i] * error[i]", "(-1.0 * p[P.kp + i] * error[i]")
        print(line("model edit", demo(source, cache)))
        (source / MODEL_FILE).write_text(originals[MODEL_FILE])
        edit(source / KERNELS_FILE, *KERNELS_EDIT)
        print(line("kernels edit", demo(source, cache)))
        test = run(source, cache, ["-m", "pytest", "-q", "-x", "-p", "no:cacheprovider", SPIN_UP_TEST])
        verdict = "fails, as it must" if test["returncode"] != 0 else "PASSES: stale engine code ran"
        print(f"{'spin-up test':<18} wall {test['wall']:7.1f} s   {verdict}")
        (source / KERNELS_FILE).write_text(originals[KERNELS_FILE])
        print(line("restored", demo(source, cache)))
    print(f"load {os.getloadavg()}")


def inlining(rounds: int) -> None:
    """Two copies, with and without ``inline="always"``: the demo's cold compilation in each, then the reaction-wheel
    race scene (configs/rw_attitude.yaml, 600 s) run warm in each, interleaved."""
    print(f"load {os.getloadavg()}")
    with tempfile.TemporaryDirectory() as work:
        copies = {}
        for name, no_inline in (("inline", False), ("no inline", True)):
            source, cache = Path(work) / name.replace(" ", "_"), Path(work) / f"cache_{name.replace(' ', '_')}"
            copy_sources(source, no_inline)
            print(line(f"cold, {name}", demo(source, cache)))
            copies[name] = (source, cache)
        race = ["-m", "shell.cli", "run", "configs/rw_attitude.yaml", "-o", "rw.h5"]
        times: dict[str, list[float]] = {name: [] for name in copies}
        for r in range(rounds + 1):  # the first round compiles the race scene's models
            for name, (source, cache) in copies.items():
                result = run(source, cache, race)
                wall = re.search(r"wall time ([0-9.]+) s", result["output"])
                if r and wall:
                    times[name].append(float(wall.group(1)))
        for name, values in times.items():
            print(f"rw_attitude 600 s, {name}: run {statistics.median(values):.3f} s (median of {len(values)}: "
                  f"{', '.join(f'{v:.3f}' for v in values)})")
        ratio = statistics.median(times["no inline"]) / statistics.median(times["inline"])
        print(f"ratio no inline / inline: {ratio:.2f}")
    print(f"load {os.getloadavg()}")


def profile() -> None:
    """A cold demo in this process: compile seconds per function (self and inclusive), and per module."""
    with tempfile.TemporaryDirectory() as cache:
        os.environ["NUMBA_CACHE_DIR"] = cache
        sys.path.insert(0, str(ROOT))
        os.chdir(ROOT)
        from numba.core import event

        stack, self_time, inclusive, count = [], {}, {}, {}

        class Listener(event.Listener):
            def on_start(self, ev):
                dispatcher = (ev.data or {}).get("dispatcher")
                name = f"{dispatcher.py_func.__module__}.{dispatcher.py_func.__qualname__}" if dispatcher else "?"
                now = time.perf_counter()
                if stack:
                    stack[-1][2] += now - stack[-1][1]  # the caller's own time so far
                stack.append([name, now, 0.0, now])

            def on_end(self, ev):
                name, resumed, own, started = stack.pop()
                now = time.perf_counter()
                self_time[name] = self_time.get(name, 0.0) + own + now - resumed
                inclusive[name] = inclusive.get(name, 0.0) + now - started
                count[name] = count.get(name, 0) + 1
                if stack:
                    stack[-1][1] = now

        event.register("numba:compile", Listener())
        started = time.perf_counter()
        from shell.scenario import build_simulation, load_scenario

        scenario = load_scenario("configs/demo_attitude_hold.yaml", [])
        build_simulation(scenario).run(scenario.t_final)
        total = time.perf_counter() - started
        print(f"load {os.getloadavg()}; cold demo in this process: {total:.0f} s, "
              f"{sum(self_time.values()):.0f} s compiling, {len(self_time)} functions")
        print(f"{'self s':>8} {'incl. s':>8}  function (top 25 by self time)")
        for name in sorted(self_time, key=self_time.get, reverse=True)[:25]:
            print(f"{self_time[name]:8.1f} {inclusive[name]:8.1f}  {name}" + (f" (x{count[name]})" if count[name] > 1
                                                                              else ""))
        modules: dict[str, float] = {}
        for name, seconds in self_time.items():
            module = name.split(".<locals>")[0].rsplit(".", 1)[0]
            modules[module] = modules.get(module, 0.0) + seconds
        print("self seconds per module: " + ", ".join(f"{m} {s:.0f}" for m, s in
                                                      sorted(modules.items(), key=lambda kv: -kv[1])))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=1)
    parser.add_argument("--profile", action="store_true")
    parser.add_argument("--no-inline", action="store_true")
    args = parser.parse_args()
    if args.profile:
        profile()
    elif args.no_inline:
        inlining(max(args.rounds, 5))
    else:
        steps(args.rounds)


if __name__ == "__main__":
    main()
