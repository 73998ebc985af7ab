"""Campaign reports: percentile tables (Markdown and CSV) and PNG charts from a results file.

For the runs that completed (status completed or stopped):

* ``percentiles.md`` / ``percentiles.csv``: for each metric and draw column, the number of runs with a
  finite value, the number with an infinite one (a settling time that was never reached), mean,
  standard deviation, min, the 1/5/50/95/99th percentiles (numpy's linear interpolation between order
  statistics) and max of the finite values; runs that did not complete are listed with their status
  and message;
* ``hist_<column>.png``: histogram of each metric column, with its requirement line (metric key
  ``requirement``) and the number of runs that meet it;
* ``scatter_<metric>.png``: each metric column against every drawn component (dispersion plots), to
  see which dispersion drives it: runs that miss the requirement in red, the requirement as a line, and
  runs that did not complete as red crosses on the lower edge at their draws;
* ``signal_<signal>.png``: the kept signals of every run overlaid against time, one panel per
  component named as in ``flexshell plot`` (x/y/z, w/x/y/z), with percentile envelopes across the
  completed runs (median, 5-95 % band and the 0.135-99.865 % band that a Gaussian's +-3 sigma would
  cover) and runs that did not complete drawn in red.

Percentiles are numpy's (linear interpolation between order statistics) of the runs present at each
instant of the common time grid (the longest completed run's; a run that stopped early drops out after
its last sample; runs sampled at other instants are interpolated linearly).
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from shell.charts import FIGURE_WIDTH, PANEL_HEIGHT, PER_PAGE, component_labels, pretty_unit, unit_label
from shell.montecarlo.metrics import meets, parse_requirement
from shell.montecarlo.results import read_kept, read_results

PERCENTILES = (1, 5, 50, 95, 99)
#: percentile bands of the signal overlays: 5-95 % and the +-3 sigma coverage of a Gaussian
ENVELOPE_PERCENTILES = (0.135, 5.0, 50.0, 95.0, 99.865)
GOOD = (b"completed", b"stopped")


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


def percentile_envelope(runs: list[tuple[np.ndarray, np.ndarray]], percentiles=ENVELOPE_PERCENTILES):
    """(time grid, (len(percentiles), len(grid), components) array) of the runs' ``(t, values (N, c))``.

    The grid is the time vector of the run that reaches furthest; at each instant, the percentiles are
    those of the runs whose span covers it (interpolated linearly onto the grid where their instants
    differ), so a run that stopped early does not pull the envelope after its end."""
    grid = max((t for t, _ in runs), key=lambda t: (t[-1] if t.size else -np.inf, t.size))
    components = runs[0][1].reshape(len(runs[0][0]), -1).shape[1]
    stack = np.full((len(runs), grid.size, components), np.nan)
    for k, (t, values) in enumerate(runs):
        flat = values.reshape(len(t), -1)
        if t.size == 0:
            continue
        if t.shape == grid[:t.size].shape and np.array_equal(t, grid[:t.size]):
            stack[k, :t.size] = flat
            continue
        inside = (grid >= t[0]) & (grid <= t[-1])
        for c in range(components):
            stack[k, inside, c] = np.interp(grid[inside], t, flat[:, c])
    present = np.isfinite(stack).any(axis=2).sum(axis=0)
    with np.errstate(all="ignore"):
        import warnings

        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)  # instants no run covers give NaN
            envelope = np.nanpercentile(stack, percentiles, axis=0)
    envelope[:, present == 0] = np.nan
    return grid, envelope


def requirements(results: dict) -> dict:
    """{metric column: (operator, bound in the column's unit)} from the campaign text in the results file."""
    from shell.schema.document import ScenarioError, load_yaml

    try:
        document = load_yaml(str(results["attrs"].get("campaign", ""))) or {}
    except ScenarioError:
        return {}
    found = {}
    for name, spec in ((document.get("metrics") or {}) if isinstance(document, dict) else {}).items():
        if not isinstance(spec, dict) or "requirement" not in spec:
            continue
        for column in results["metric_columns"]:
            if column == name or column.startswith(f"{name}["):
                found[column] = parse_requirement(spec["requirement"], results["units"].get(column, ""))
    return found


def write_report(path, directory) -> list[Path]:
    """Write the report of results file ``path`` into ``directory``; returns the files written."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    results = read_results(path)
    table = results["table"]
    out = Path(directory)
    out.mkdir(parents=True, exist_ok=True)
    good = np.isin(table["status"], [b"completed", b"stopped"])
    required = requirements(results)
    written = _write_tables(results, out, good, required)
    for column in results["metric_columns"]:
        written.append(_histogram(plt, results, out, column, good, required.get(column)))
        if results["draw_columns"]:
            written.append(_scatter(plt, results, out, column, good, required.get(column)))
    status = {int(r): s for r, s in zip(table["run"], table["status"])}
    kept_runs = [int(r) for r in table["run"][table["status"] != b"pending"]]
    signals = {}
    for run in kept_runs:
        for signal, item in read_kept(path, run).items():
            signals.setdefault(signal, []).append((run, item))
    for signal, items in signals.items():
        written.append(_signal_chart(plt, out, signal, items, status))
    return written


def _write_tables(results: dict, out: Path, good: np.ndarray, required: dict) -> list[Path]:
    """``percentiles.csv`` and ``percentiles.md`` (with the requirements met and the runs that did not complete)."""
    table = results["table"]
    rows = percentile_rows(results)
    header = ["column", "unit", "kind", "n", "infinite", "mean", "std", "min"] + [f"p{p}" for p in PERCENTILES] + ["max"]
    with open(out / "percentiles.csv", "w") as f:
        f.write(",".join(header) + "\n")
        for row in rows:
            f.write(",".join(str(v) if isinstance(v, (str, int)) else repr(float(v)) for v in row) + "\n")
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
    if required:
        lines += ["", "## Requirements", "", "| metric | requirement | runs meeting it | of completed runs |",
                  "|---|---|---|---|"]
        for column, (operator, bound) in required.items():
            met = int(meets(table[column][good], (operator, bound)).sum())
            unit = pretty_unit(results["units"].get(column, ""))
            lines.append(f"| {column} | {operator} {bound:g} {unit} | {met} | {int(good.sum())} |")
    failed = table[~good & (table["status"] != b"pending")]
    if failed.size:
        lines += ["", "## Runs that did not complete", "", "| run | status | message |", "|---|---|---|"]
        lines += [f"| {r['run']} | {r['status'].decode()} | {str(r['message']).replace('|', '/')} |" for r in failed]
    (out / "percentiles.md").write_text("\n".join(lines) + "\n")
    return [out / "percentiles.csv", out / "percentiles.md"]


def _histogram(plt, results: dict, out: Path, column: str, good: np.ndarray, requirement) -> Path:
    """``hist_<column>.png``: the metric's histogram with its requirement line and the runs that meet it."""
    table = results["table"]
    bad = ~good & (table["status"] != b"pending")
    values = table[column][good]
    finite = np.isfinite(values)
    label = f"{column}{unit_label(results['units'][column])}"
    fig, ax = plt.subplots(figsize=(6.4, 4))
    ax.hist(values[finite], bins=max(5, min(50, int(np.sqrt(finite.sum())) + 1)), color="C0", edgecolor="white")
    ax.set_xlabel(label)
    ax.set_ylabel("runs")
    title = f"{column}: {finite.sum()} runs"
    if (~finite).any():
        title += f" ({(~finite).sum()} infinite: not settled)"
    if bad.any():
        title += f"; {int(bad.sum())} did not complete"
    if requirement is not None:
        met = int(meets(values, requirement).sum())
        ax.axvline(requirement[1], color="C3", lw=1.5, ls="--",
                   label=f"requirement {requirement[0]} {requirement[1]:g}")
        ax.legend(fontsize=8)
        title += f"\n{met} of {values.size} completed runs meet {requirement[0]} {requirement[1]:g}"
    ax.set_title(title, fontsize=9)
    fig.tight_layout()
    name = out / f"hist_{_file_name(column)}.png"
    fig.savefig(name, dpi=90)
    plt.close(fig)
    return name


def _scatter(plt, results: dict, out: Path, column: str, good: np.ndarray, requirement) -> Path:
    """``scatter_<column>.png``: the metric against every drawn component, misses and failed runs in red."""
    table = results["table"]
    draw_columns = results["draw_columns"]
    bad = ~good & (table["status"] != b"pending")
    values = table[column][good]
    finite = np.isfinite(values)
    label = f"{column}{unit_label(results['units'][column])}"
    n = len(draw_columns)
    cols = min(4, n)
    nrows = -(-n // cols)
    fig, axes = plt.subplots(nrows, cols, figsize=(3.2 * cols, 2.6 * nrows + 0.4), squeeze=False)
    ok = meets(values, requirement) if requirement is not None else np.ones(values.size, bool)
    for k, draw in enumerate(draw_columns):
        ax = axes[k // cols][k % cols]
        x = table[draw][good]
        ax.plot(x[finite & ok], values[finite & ok], ".", ms=3, color="C0")
        if (finite & ~ok).any():
            ax.plot(x[finite & ~ok], values[finite & ~ok], ".", ms=4, color="C3", label="misses requirement")
        if requirement is not None:
            ax.axhline(requirement[1], color="C3", lw=1.0, ls="--")
        if bad.any():
            ax.plot(table[draw][bad], np.zeros(int(bad.sum())), "x", color="C3", ms=5, clip_on=False,
                    transform=ax.get_xaxis_transform(), label="did not complete")
        ax.set_xlabel(f"{draw}{unit_label(results['units'][draw])}", fontsize=7)
        ax.set_ylabel(label, fontsize=7)
        ax.tick_params(labelsize=6)
    for k in range(n, nrows * cols):
        axes[k // cols][k % cols].axis("off")
    handles = {h.get_label(): h for ax in axes.ravel() for h in ax.get_lines() if not h.get_label().startswith("_")}
    if handles:
        fig.legend(list(handles.values()), list(handles), fontsize=7, loc="upper right")
    fig.suptitle(f"{column} against the draws", fontsize=9)
    fig.tight_layout()
    name = out / f"scatter_{_file_name(column)}.png"
    fig.savefig(name, dpi=90)
    plt.close(fig)
    return name


def _signal_chart(plt, out: Path, signal: str, items: list, status: dict) -> Path:
    """Overlay of one kept signal over the runs, with percentile envelopes of the completed ones."""
    shape = items[0][1][1].shape[1:]
    size = int(np.prod(shape, dtype=int))
    unit = items[0][1][2]
    labels = component_labels(signal, shape)
    completed = [(t, values) for run, (t, values, _) in items if status[run] in GOOD]
    envelope = percentile_envelope(completed) if completed else None
    pages = -(-size // PER_PAGE)
    height = PANEL_HEIGHT * min(size, PER_PAGE) + 0.9
    fig, axes = plt.subplots(min(size, PER_PAGE), 1, figsize=(FIGURE_WIDTH, height), sharex=True, squeeze=False)
    n_bad = 0
    for run, (t, values, _) in items:
        flat = values.reshape(values.shape[0], -1)
        failed = status[run] not in GOOD
        n_bad += failed
        for c in range(min(size, PER_PAGE)):
            axes[c][0].plot(t, flat[:, c], lw=1.0 if failed else 0.5, alpha=0.9 if failed else 0.25,
                            color="C3" if failed else "0.45", zorder=3 if failed else 1)
    for c in range(min(size, PER_PAGE)):
        ax = axes[c][0]
        if envelope is not None:
            grid, env = envelope
            ax.fill_between(grid, env[0, :, c], env[4, :, c], color="C0", alpha=0.15, lw=0, label="0.135-99.865 %")
            ax.fill_between(grid, env[1, :, c], env[3, :, c], color="C0", alpha=0.3, lw=0, label="5-95 %")
            ax.plot(grid, env[2, :, c], color="C0", lw=1.2, label="median")
        ax.set_ylabel(f"{labels[c]}{unit_label(unit)}", fontsize=8)
        ax.grid(True, alpha=0.3)
        ax.tick_params(labelsize=7)
    if n_bad:
        axes[0][0].plot([], [], color="C3", lw=1.0, label="did not complete")
    axes[0][0].legend(fontsize=7, loc="upper right", ncol=4)
    title = f"{signal}: {len(items)} runs ({len(completed)} completed, {n_bad} did not complete)"
    if pages > 1:
        title += f"; first {PER_PAGE} of {size} components"
    axes[0][0].set_title(title, fontsize=9, loc="left")
    axes[-1][0].set_xlabel("time [s]")
    fig.tight_layout()
    name = out / f"signal_{_file_name(signal)}.png"
    fig.savefig(name, dpi=90)
    plt.close(fig)
    return name
