"""``flexshell montecarlo CAMPAIGN.yaml -o OUT.h5``: run a Monte Carlo campaign (serial, pool or Dask)."""

from __future__ import annotations

import importlib
import sys
import threading
import time
from pathlib import Path

from shell.outputs import OVERWRITE


def _import_quietly(name: str) -> None:
    try:
        importlib.import_module(name)
    except Exception:  # noqa: BLE001 - the executor imports it again and reports what is wrong
        pass


def register(subparsers) -> None:
    parser = subparsers.add_parser(
        "montecarlo", help="run a Monte Carlo campaign over a scenario and store draws + metrics per run",
        description="Run the N dispersed runs of a campaign (docs/montecarlo.md); each run's row is stored as "
                    "it completes, so an interrupted campaign is finished with --resume.")
    parser.add_argument("campaign", help="campaign file (YAML)")
    parser.add_argument("-o", "--output", help="results file (HDF5); default <campaign name>.h5")
    parser.add_argument("--executor", choices=("serial", "pool", "dask"), default="serial",
                        help="serial (default), pool (local processes, all cores) or dask (--scheduler ADDRESS, "
                             "else a LocalCluster)")
    parser.add_argument("--workers", type=int, help="pool / LocalCluster worker processes (default: cores)")
    parser.add_argument("--scheduler", metavar="ADDRESS", help="Dask scheduler address, e.g. tcp://host:8786")
    parser.add_argument("--resume", action="store_true", help="finish a partial campaign in OUT.h5")
    parser.add_argument("--overwrite", action="store_true",
                        help="replace an existing OUT.h5: a campaign's results (instead of finishing them with "
                             "--resume), a file of another kind, or the campaign file itself")
    parser.add_argument("--rerun", type=int, metavar="I",
                        help="run only run I again, write its full log to -o, print its draws and metrics")
    parser.add_argument("--print-overrides", type=int, metavar="I",
                        help="print the --set list that makes the scenario into run I, and exit")
    parser.add_argument("--quiet", action="store_true", help="no progress bar")
    parser.set_defaults(func=run)


class CampaignProgress:
    """Campaign progress on stderr (tqdm): runs done of the total, runs per minute, ETA, runs that did
    not complete."""

    def __init__(self, enabled: bool):
        self.enabled = enabled
        self.bad = 0
        self.bar = None

    def __call__(self, record, done: int, total: int) -> None:
        if record.status not in ("completed", "stopped"):
            self.bad += 1
        if not self.enabled:
            return
        if self.bar is None:
            from tqdm import tqdm

            # a resumed campaign starts at the runs already done: the rate and ETA count this session only
            self.bar = tqdm(total=total, initial=done - 1, unit="run", file=sys.stderr, dynamic_ncols=True,
                            smoothing=0.1, mininterval=0.2)
        self.bar.set_postfix_str(f"{self.bad} not completed", refresh=False)
        self.bar.update(done - self.bar.n)

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()
            self.bar = None


def run(args) -> int:
    from shell.montecarlo.campaign import load_campaign
    from shell.montecarlo.executors import SchedulerUnreachable, check_scheduler, run_campaign
    from shell.montecarlo.results import ResultsError
    from shell.outputs import CAMPAIGN, LOG, clear_for_writing
    from shell.scenario import ScenarioError
    from shell.units import UnitError

    from shell.commands.run import CompileNotice

    try:  # what can be refused without building the scene is refused first
        if args.workers is not None and args.workers < 1:
            raise ValueError(f"--workers {args.workers}: expected a positive number of worker processes")
        if args.scheduler is not None:
            if args.executor != "dask":
                raise ValueError("--scheduler needs --executor dask")
            check_scheduler(args.scheduler)
        if args.output:
            _guard(args, args.output)
    except (ValueError, SchedulerUnreachable) as exc:
        print(f"flexshell montecarlo: {exc}", file=sys.stderr)
        return 1
    if args.executor == "dask" and args.rerun is None and args.print_overrides is None:
        # dask.distributed takes ~0.25 s to import: a second core does it while this one loads the campaign
        threading.Thread(target=_import_quietly, args=("dask.distributed",), daemon=True,
                         name="flexshell-import-dask").start()
    try:
        with CompileNotice(getattr(args, "quiet", False)):  # loading runs the median scene: it compiles what runs use
            campaign = load_campaign(args.campaign)
    except (ScenarioError, UnitError, ValueError, OSError) as exc:
        print(f"flexshell montecarlo: {exc}", file=sys.stderr)
        return 1
    if args.print_overrides is not None:
        if not 0 <= args.print_overrides < campaign.runs:
            print(f"flexshell montecarlo: --print-overrides {args.print_overrides}: the campaign has runs "
                  f"0..{campaign.runs - 1}", file=sys.stderr)
            return 1
        for item in campaign.overrides(args.print_overrides):
            print(f"--set \"{item}\"")
        return 0
    output = args.output or (f"{campaign.name}_run{args.rerun}.h5" if args.rerun is not None else
                             f"{campaign.name}.h5")
    try:
        _guard(args, output)
    except ValueError as exc:
        print(f"flexshell montecarlo: {exc}", file=sys.stderr)
        return 1
    if args.overwrite and not args.resume:  # the results and log writers replace only their own kind
        clear_for_writing(output, LOG if args.rerun is not None else CAMPAIGN)
    if args.rerun is not None:
        return _rerun(campaign, args.rerun, output)
    progress = CampaignProgress(enabled=not args.quiet and sys.stderr.isatty())
    start = time.perf_counter()
    try:
        counts = run_campaign(campaign, output, args.executor, args.workers, args.scheduler, args.resume,
                              args.overwrite, progress)
    except (ResultsError, SchedulerUnreachable, ScenarioError) as exc:
        progress.close()
        print(f"flexshell montecarlo: {exc}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        progress.close()
        print(f"flexshell montecarlo: interrupted; completed runs are in {output} "
              f"(finish with --resume)", file=sys.stderr)
        return 130
    progress.close()
    wall = time.perf_counter() - start
    summary = ", ".join(f"{n} {s}" for s, n in sorted(counts.items()))
    print(f"{campaign.name}: {campaign.runs} runs ({summary}); this session {wall:.1f} s wall, "
          f"{args.executor} executor")
    _print_metric_summary(output)
    print(f"results: {output}")
    return 0 if counts.get("pending", 0) == 0 else 1


def _guard(args, output) -> None:
    """The output guard (shell.outputs): a results file, or with --rerun a log; --resume reads the output."""
    from shell.outputs import CAMPAIGN, LOG, guard_output

    if args.resume or args.print_overrides is not None:
        return
    guard_output(output, LOG if args.rerun is not None else CAMPAIGN,
                 inputs=((args.campaign, "the campaign file itself"),), overwrite=args.overwrite)
    if args.rerun is None and Path(output).exists() and not args.overwrite:
        raise ValueError(f"{output} exists; pass --resume to finish that campaign, {OVERWRITE} to replace it, "
                         "or choose another output")


def _print_metric_summary(output) -> None:
    import numpy as np

    from shell.montecarlo.results import read_results

    results = read_results(output)
    table = results["table"]
    good = np.isin(table["status"], [b"completed", b"stopped"])
    for column in results["metric_columns"]:
        values = table[column][good]
        if values.size == 0:
            continue
        p5, p50, p95 = np.percentile(values, [5, 50, 95])
        print(f"  {column:32s} [{results['units'][column]}]  p5 {p5:.4g}  median {p50:.4g}  p95 {p95:.4g}  "
              f"max {values.max():.4g}")
    for row in table[~good & (table["status"] != b"pending")]:
        print(f"  run {row['run']}: {row['status'].decode()}: {row['message']}")


def _rerun(campaign, run: int, log_path) -> int:
    if not 0 <= run < campaign.runs:
        print(f"flexshell montecarlo: --rerun {run}: the campaign has runs 0..{campaign.runs - 1}", file=sys.stderr)
        return 1
    record = campaign.run(run, log_path=log_path)
    print(f"{campaign.name} run {run}: {record.status} ({record.message}), t_end = {record.t_end:.6g} s, "
          f"wall {record.wall_time:.3f} s")
    for column, value in zip(campaign.draw_columns, record.draws):
        print(f"  draw   {column} = {value!r}")
    for column, value in zip(campaign.metric_columns, record.metrics):
        print(f"  metric {column} = {value!r}")
    print(f"log: {log_path}")
    return 0 if record.status in ("completed", "stopped") else 1
