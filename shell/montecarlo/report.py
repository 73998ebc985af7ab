"""Campaign reports: percentile tables (Markdown and CSV) and PNG charts from a results file.

For the runs that completed (status completed or stopped):

* ``percentiles.md`` / ``percentiles.csv``: for each metric and draw column, the number of runs with a
  finite value, the number with an infinite one (a settling time that was never reached), mean,
  standard deviation, min, the 1/5/50/95/99th percentiles (numpy's linear interpolation between order
  statistics) and max of the finite values; runs that did not complete are listed with their status
  and message;
* ``hist_<column>.png``: histogram of each metric column;
* ``scatter_<metric>.png``: each metric column against every drawn component (dispersion plots), to
  see which dispersion drives it;
* ``signal_<signal>.png``: the kept signals of every run overlaid against time.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from shell.montecarlo.results import read_kept, read_results

PERCENTILES = (1, 5, 50, 95, 99)


def _file_name(text: str) -> str:
    return re.sub(r"[^A-Za-z0-9_.-]+", "_", text).strip("_")


def percentile_rows(results: dict) -> list[tuple]:
    """(column, unit, kind, n finite, n infinite, mean, std, min, p1, p5, p50, p95, p99, max) of the
    completed runs."""
    table = results["table"]
    good = np.isin(table["status"], [b"completed", b"stopped"])
    rows = []
    for kind, columns in (("metric", results["metric_columns"]), ("draw", results["draw_columns"])):
        for column in columns:
            values = table[column][good]
            infinite = int(np.isinf(values).sum())
            values = values[np.isfinite(values)]
            if values.size == 0:
                rows.append((column, results["units"][column], kind, 0, infinite) + (float("nan"),) * 9)
                continue
            rows.append((column, results["units"][column], kind, values.size, infinite, values.mean(),
                         values.std(ddof=1) if values.size > 1 else 0.0, values.min(),
                         *np.percentile(values, PERCENTILES), values.max()))
    return rows


def write_report(path, directory) -> list[Path]:
    """Write the report of results file ``path`` into ``directory``; returns the files written."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    results = read_results(path)
    table = results["table"]
    out = Path(directory)
    out.mkdir(parents=True, exist_ok=True)
    written = []
    good = np.isin(table["status"], [b"completed", b"stopped"])
    rows = percentile_rows(results)
    header = ["column", "unit", "kind", "n", "infinite", "mean", "std", "min"] + [f"p{p}" for p in PERCENTILES] + ["max"]
    with open(out / "percentiles.csv", "w") as f:
        f.write(",".join(header) + "\n")
        for row in rows:
            f.write(",".join(str(v) if isinstance(v, (str, int)) else repr(float(v)) for v in row) + "\n")
    written.append(out / "percentiles.csv")
    attrs = results["attrs"]
    statuses = {}
    for s in table["status"]:
        statuses[s.decode()] = statuses.get(s.decode(), 0) + 1
    lines = [f"# Campaign {attrs['name']}", "",
             f"{attrs['runs']} runs, master seed {attrs['seed']}, scenario `{Path(str(attrs['scenario_file'])).name}`; "
             + ", ".join(f"{n} {s}" for s, n in sorted(statuses.items())), "",
             "| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    for row in rows:
        lines.append("| " + " | ".join(v if isinstance(v, str) else str(v) if isinstance(v, (int, np.integer))
                                       else f"{v:.6g}" for v in row) + " |")
    failed = table[~good & (table["status"] != b"pending")]
    if failed.size:
        lines += ["", "## Runs that did not complete", "", "| run | status | message |", "|---|---|---|"]
        lines += [f"| {r['run']} | {r['status'].decode()} | {str(r['message']).replace('|', '/')} |" for r in failed]
    (out / "percentiles.md").write_text("\n".join(lines) + "\n")
    written.append(out / "percentiles.md")

    draw_columns = results["draw_columns"]
    for column in results["metric_columns"]:
        values = table[column][good]
        finite = np.isfinite(values)
        unit = results["units"][column]
        fig, ax = plt.subplots(figsize=(6, 4))
        ax.hist(values[finite], bins=max(5, min(50, int(np.sqrt(finite.sum())) + 1)), color="C0", edgecolor="white")
        ax.set_xlabel(f"{column} [{unit}]")
        ax.set_ylabel("runs")
        title = f"{column}: {finite.sum()} runs"
        if (~finite).any():
            title += f" ({(~finite).sum()} infinite: not settled)"
        ax.set_title(title)
        fig.tight_layout()
        name = out / f"hist_{_file_name(column)}.png"
        fig.savefig(name, dpi=90)
        plt.close(fig)
        written.append(name)
        if draw_columns:
            n = len(draw_columns)
            cols = min(4, n)
            nrows = -(-n // cols)
            fig, axes = plt.subplots(nrows, cols, figsize=(3.2 * cols, 2.6 * nrows), squeeze=False)
            for k, draw in enumerate(draw_columns):
                ax = axes[k // cols][k % cols]
                ax.plot(table[draw][good][finite], values[finite], ".", ms=3)
                ax.set_xlabel(f"{draw} [{results['units'][draw]}]", fontsize=7)
                ax.set_ylabel(f"{column} [{unit}]", fontsize=7)
                ax.tick_params(labelsize=6)
            for k in range(n, nrows * cols):
                axes[k // cols][k % cols].axis("off")
            fig.tight_layout()
            name = out / f"scatter_{_file_name(column)}.png"
            fig.savefig(name, dpi=90)
            plt.close(fig)
            written.append(name)

    kept_runs = [int(r) for r in table["run"][table["status"] != b"pending"]]
    signals = {}
    for run in kept_runs:
        for signal, item in read_kept(path, run).items():
            signals.setdefault(signal, []).append((run, item))
    for signal, items in signals.items():
        size = int(np.prod(items[0][1][1].shape[1:], dtype=int))
        fig, axes = plt.subplots(size, 1, figsize=(7, 1.8 * size + 0.8), sharex=True, squeeze=False)
        for run, (t, values, unit) in items:
            flat = values.reshape(values.shape[0], -1)
            for c in range(size):
                axes[c][0].plot(t, flat[:, c], lw=0.6, alpha=0.5)
        for c in range(size):
            axes[c][0].set_ylabel(f"[{c}] {items[0][1][2]}", fontsize=7)
        axes[0][0].set_title(f"{signal}: {len(items)} runs")
        axes[-1][0].set_xlabel("time [s]")
        fig.tight_layout()
        name = out / f"signal_{_file_name(signal)}.png"
        fig.savefig(name, dpi=90)
        plt.close(fig)
        written.append(name)
    return written
