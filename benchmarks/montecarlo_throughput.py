"""Monte Carlo throughput: serial vs process pool vs Dask LocalCluster, interleaved, medians, and where the
parallel executors lose against the machine.

Campaign: configs/campaign_attitude_hold.yaml (rigid bus, PD controller at 5-10 Hz, RK4 50 ms), shortened to
``--runs`` runs. Each round runs the campaign serially, on a process pool and on a Dask LocalCluster, one after
the other (``--rounds`` rounds, interleaved, so that the machine's drift hits every executor alike); reported
are the medians and the per-round ratios. Also measured:

* the bare loop (peer): build each run's scene from the same --set overrides and call Simulation.run without
  logging, the least any tool must do per run;
* what the machine gives this work: the same runs in this process alone, then split between forked copies of
  it with no executor (no coordinator, nothing stored). On this shared 2-core VM it scatters between 1.5 and
  2.0x: two busy cores run each process slower than one;
* CPU of all processes per campaign (the coordinator's own and its reaped children's): the executors' overhead
  over the serial campaign without the noise of the wall clock;
* importing dask.distributed, which `flexshell montecarlo --executor dask` does once per campaign: measured in
  fresh processes and added to the Dask wall time in the "with the import" ratio (the campaigns here run in one
  process, which imports it once, before the first round);
* the coordinator's cost of storing one run (journal line at once, HDF5 rows and kept signals in batches).

Usage: python benchmarks/montecarlo_throughput.py [--runs 100] [--rounds 5] [--workers 2]
"""

from __future__ import annotations

import argparse
import copy
import importlib
import os
import resource
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from shell.montecarlo.campaign import load_campaign  # noqa: E402
from shell.montecarlo.executors import run_campaign, start_worker  # noqa: E402
from shell.montecarlo.results import open_results, read_results, tables_equal  # noqa: E402
from shell.scenario import build_simulation, parse_scenario  # noqa: E402

EXECUTORS = ("serial", "pool", "dask")


def bare_loop(campaign, runs: int) -> tuple[float, float]:
    """(wall, summed Simulation.run time) of building and running each run without the campaign machinery."""
    start, simulated = time.perf_counter(), 0.0
    for i in range(runs):
        scenario = parse_scenario(campaign.scenario_text, campaign.scenario_file, campaign.overrides(i))
        summary = build_simulation(scenario).run(scenario.t_final)
        simulated += summary.wall_time
    return time.perf_counter() - start, simulated


def runs_alone(campaign, runs: int, workers: int) -> tuple[float, float]:
    """(serial wall, parallel wall) of the campaign's runs with no executor at all: this process runs them one
    after another, then ``workers`` forked copies of it split them and nothing else happens (no coordinator,
    no storing, no queue). Their ratio is what the machine itself allows for this work."""
    start = time.perf_counter()
    for i in range(runs):
        campaign.run(i)
    serial = time.perf_counter() - start
    start = time.perf_counter()
    children = []
    for w in range(workers):
        pid = os.fork()
        if pid == 0:
            try:
                for i in range(w, runs, workers):
                    campaign.run(i)
            finally:
                os._exit(0)
        children.append(pid)
    for pid in children:
        os.waitpid(pid, 0)
    return serial, time.perf_counter() - start


def cpu_seconds() -> float:
    """CPU time of this process and of its children that have ended (the pool's and the cluster's workers)."""
    own, children = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
    return own.ru_utime + own.ru_stime + children.ru_utime + children.ru_stime


def dask_import_seconds() -> float:
    """Seconds to import dask.distributed in a new process that has imported what a campaign's coordinator has."""
    import subprocess

    code = ("import time; import shell.montecarlo.executors, shell.montecarlo.results; t = time.perf_counter(); "
            "import dask.distributed; print(time.perf_counter() - t)")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT, check=True)
    return float(done.stdout.split()[-1])


def store_cost(campaign, directory: Path, runs: int) -> float:
    """Seconds the coordinator spends storing one run: ``runs`` records written (journal line each, HDF5 in
    batches) and the file closed, per run."""
    records = [campaign.run(i) for i in range(min(runs, 5))]
    results = open_results(directory / "store.h5", campaign)
    start = time.perf_counter()
    for i in range(runs):
        record = copy.copy(records[i % len(records)])
        record.run = i
        results.write(record)
    results.close("partial")
    return (time.perf_counter() - start) / runs


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--runs", type=int, default=100)
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument("--workers", type=int, default=os.cpu_count())
    parser.add_argument("--campaign", default=str(ROOT / "configs" / "campaign_attitude_hold.yaml"))
    args = parser.parse_args()
    campaign = load_campaign(args.campaign)
    campaign.runs = args.runs
    start_worker(campaign)  # as every executor does before its first run
    print(f"campaign {campaign.name}: {args.runs} runs, {args.workers} workers, {os.cpu_count()} cores, "
          f"{args.rounds} interleaved rounds, load average before {os.getloadavg()[0]:.2f}")
    imports = [dask_import_seconds() for _ in range(3)]
    dask_import = float(np.median(imports))
    print(f"importing dask.distributed: {dask_import:.2f} s (fresh processes that have imported flexshell's Monte "
          f"Carlo modules, median of {', '.join(f'{t:.2f}' for t in imports)}; each `flexshell montecarlo --executor "
          "dask` pays it once)")
    importlib.import_module("dask.distributed")  # every Dask campaign below finds it imported
    bare_wall, bare_sim = bare_loop(campaign, args.runs)
    print(f"bare loop (build + run, no log):  {bare_wall:6.2f} s  {60 * args.runs / bare_wall:7.0f} runs/min  "
          f"(Simulation.run {bare_sim / args.runs * 1e3:.1f} ms/run, build "
          f"{1e3 * (bare_wall - bare_sim) / args.runs:.1f} ms/run)")
    alone = []
    if hasattr(os, "fork"):
        for _ in range(3):
            serial_runs, parallel_runs = runs_alone(campaign, args.runs, args.workers)
            alone.append(serial_runs / parallel_runs)
        print(f"the runs alone (one process, then {args.workers} forked processes splitting them; no executor, "
              f"nothing stored): {np.median(alone):.2f}x (3 tries: {', '.join(f'{c:.2f}' for c in alone)}): what "
              "the machine gives this work")
    walls = {e: [] for e in EXECUTORS}
    cpus = {e: [] for e in EXECUTORS}
    timings, tables = {}, {}
    with tempfile.TemporaryDirectory() as tmp:
        for k in range(args.rounds):
            for executor in EXECUTORS:
                output = Path(tmp) / f"{executor}{k}.h5"
                cpu, start = cpu_seconds(), time.perf_counter()
                run_campaign(campaign, output, executor=executor, workers=args.workers)
                walls[executor].append(time.perf_counter() - start)
                cpus[executor].append(cpu_seconds() - cpu)
                read = read_results(output)
                tables.setdefault(executor, read["table"])
                timings.setdefault(executor, []).append(read["timing"])
            print(f"  round {k + 1}: " + ", ".join(f"{e} {walls[e][-1]:.2f} s" for e in EXECUTORS)
                  + f" (load {os.getloadavg()[0]:.2f})", flush=True)
        store = store_cost(campaign, Path(tmp), args.runs)
    for executor in EXECUTORS:
        timing = np.concatenate(timings[executor])
        in_run = timing["wall_time"] - timing["simulation_time"]
        wall = float(np.median(walls[executor]))
        print(f"{executor:7s} campaign: {wall:6.2f} s  {60 * args.runs / wall:7.0f} runs/min  all-process CPU "
              f"{np.median(cpus[executor]):.2f} s  (Simulation.run {np.median(timing['simulation_time']) * 1e3:.1f} "
              f"ms/run wall, worker CPU {np.median(timing['cpu_time']) * 1e3:.1f} ms/run, in-run overhead "
              f"{np.median(in_run) * 1e3:.1f} ms, kernels compiled in workers {int(timing['compiled_kernels'].sum())})")
    print(f"coordinator: storing one run (journal line, HDF5 in batches) {store * 1e3:.2f} ms")
    serial = np.array(walls["serial"])
    for executor in ("pool", "dask"):
        ratios = serial / np.array(walls[executor])
        print(f"{executor}: {np.median(ratios):.2f}x serial (median of rounds; rounds "
              f"{', '.join(f'{r:.2f}' for r in ratios)}); CPU of all processes {np.median(cpus[executor]):.2f} s "
              f"against {np.median(cpus['serial']):.2f} s serial")
    with_import = serial / (np.array(walls["dask"]) + dask_import)
    print(f"dask with the import of dask.distributed (+{dask_import:.2f} s, as one `flexshell montecarlo` "
          f"pays it): {np.median(with_import):.2f}x serial")
    same = all(tables_equal(tables["serial"], tables[e]) for e in ("pool", "dask"))
    print(f"tables of serial, pool and Dask identical: {same}")
    print(f"load average after {os.getloadavg()[0]:.2f} (other users' jobs share the cores: compare the CPU "
          "figures with the wall times)")


if __name__ == "__main__":
    main()
