"""``flexshell plot LOG.h5 SIGNAL...``: quick-look time histories of logged signals (matplotlib).

What an engineer reads, not the raw arrays:

* legends name components: ``w, x, y, z`` for a quaternion, ``x, y, z`` for a 3-vector, ``eta1..etan``
  for modal coordinates, the body and hinge coordinate for an engine's ``q``/``u``; scalar signals that
  differ in one name element (``wheels.rw1.wheel_speed`` ... ``wheels.rw4.wheel_speed``) share a panel
  with that element (``rw1`` ... ``rw4``) as legend;
* units print as an engineer writes them (``N m``, ``kg m²``, ``rad/s²``), and dimensionless signals
  carry none (never ``1``);
* an attitude quaternion (scalar first, node -> world, docs/conventions.md) adds two derived panels: the
  attitude error ``2 atan2(|v_e|, |w_e|)`` of ``e = r^* (x) q`` against the commanded attitude ``r``
  (the controller attached to the same node, or ``--attitude-reference``, else identity), and the 3-2-1
  (yaw, pitch, roll) Euler angles of the rotation matrix R(q) (Diebel 2006, "Representing attitude",
  eq. 290: yaw = atan2(2(xy + wz), w² + x² - y² - z²), pitch = -asin(2(xz - wy)),
  roll = atan2(2(yz + wx), w² - x² - y² + z²));
* an engine's whole ``q``/``u`` is split into one panel per body's hinge coordinates and one per flexible
  body's modal coordinates, so that small modal coordinates do not vanish beside a hinge angle;
* figures keep a readable size: at most ``--per-page`` panels (default 6) per figure, further panels on
  further pages (``fig-2.png``, ... or pages of one PDF).

Labels, units and signal lookup are :mod:`shell.charts` (shared with the campaign report and the 3-D view); the
attitude error and the Euler angles are :mod:`shell.attitude`'s.
"""

from __future__ import annotations

import re
import sys
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from shell.attitude import attitude_error, euler_321
from shell.charts import FIGURE_WIDTH, PANEL_HEIGHT, PER_PAGE, component_labels, is_quaternion, pretty_unit, resolve_signal
from shell.outputs import OVERWRITE_HELP


def register(subparsers) -> None:
    parser = subparsers.add_parser("plot", help="plot logged signals of an HDF5 log",
                                   description="Plot signals of a flexshell log against time. A signal may "
                                               "be named in full or by a unique suffix (acs.attitude). "
                                               "Attitude quaternions add attitude-error and Euler-angle "
                                               "panels; more than --per-page panels go on further pages.")
    parser.add_argument("log", help="log file (HDF5) written by flexshell run")
    parser.add_argument("signals", nargs="*", help="signals to plot (default: all)")
    parser.add_argument("-o", "--output", help="image file (default: LOG stem + .png; .pdf: one page per "
                                               "figure in one file)")
    parser.add_argument("--show", action="store_true", help="open a window instead of writing a file")
    parser.add_argument("--per-page", type=int, default=PER_PAGE, help=f"panels per figure (default {PER_PAGE})")
    parser.add_argument("--attitude-reference", metavar="[W,X,Y,Z]",
                        help="commanded attitude of the attitude-error panel (default: the attitude_command "
                             "of the controller attached to the same node, else identity)")
    parser.add_argument("--no-derived", action="store_true", help="no attitude-error or Euler-angle panels")
    parser.add_argument("--overwrite", action="store_true", help=OVERWRITE_HELP)
    parser.set_defaults(func=plot)


# ----------------------------------------------------------------------------------------------------
# the reference of the attitude-error panel


def commanded_attitude(scenario_text: str, signal: str):
    """``attitude_command`` of the model attached to the node of ``signal`` (``<engine>.<node>.attitude``)
    in the scenario text stored in the log, or None."""
    from shell.schema.document import ScenarioError, load_yaml

    try:
        document = load_yaml(scenario_text or "") or {}
    except ScenarioError:
        return None
    parts = signal.split(".")
    if len(parts) < 3 or not isinstance(document, dict):
        return None
    node = parts[-2]
    commands = []  # (attached to this node, command) of every model with an attitude_command
    for spec in (document.get("models") or {}).values():
        if not isinstance(spec, dict):
            continue
        attach = spec.get("attach") or {}
        command = (spec.get("parameters") or {}).get("attitude_command")
        if command is not None:
            commands.append((isinstance(attach, dict) and attach.get("node") == node, command))
    attached = [c for here, c in commands if here]
    # the controller attached to the node; else the scene's only one (wired by connections)
    chosen = attached[0] if attached else commands[0][1] if len(commands) == 1 else None
    if chosen is None:
        return None
    try:
        r = np.asarray(chosen, float).reshape(4)
    except (TypeError, ValueError):
        return None
    return r / np.linalg.norm(r) if np.isfinite(r).all() and np.linalg.norm(r) > 0 else None


# ----------------------------------------------------------------------------------------------------
# engine coordinates split per body
def coordinate_blocks(scenario_text: str, signal: str, size: int):
    """[(panel title, first index, count, labels, unit)] splitting an engine's ``q`` or ``u`` (or
    ``u_dot``) into each body's hinge coordinates and each flexible body's modal coordinates, read from
    the scenario stored in the log; None when the split cannot be made without doubt (then the signal is
    plotted whole)."""
    from dynamics.hinges import HINGE_NQ, HINGE_NU, HINGE_TYPES, hinge as hinge_record
    from shell.models.multibody import HINGE_UNITS
    from shell.schema.document import ScenarioError, load_yaml

    engine, _, leaf = signal.rpartition(".")
    if leaf not in ("q", "u", "u_dot") or "." in engine:
        return None
    try:
        document = load_yaml(scenario_text or "") or {}
    except ScenarioError:
        return None
    description = document.get("multibody") if isinstance(document, dict) else None
    if not isinstance(description, dict) or description.get("name", "multibody") != engine:
        return None
    bodies = description.get("bodies")
    if not isinstance(bodies, list) or not all(isinstance(b, dict) and "name" in b for b in bodies):
        return None
    counts = HINGE_NQ if leaf == "q" else HINGE_NU
    column = {"q": 0, "u": 1, "u_dot": 2}[leaf]
    hinge_total = sum(int(counts[HINGE_TYPES[b.get("hinge", "locked")]]) for b in bodies
                      if b.get("hinge", "locked") in HINGE_TYPES)
    flexible = [b["name"] for b in bodies if "body_file" in b]
    if len(flexible) > 1 or (not flexible and hinge_total != size) or hinge_total > size:
        return None  # several flexible bodies: their mode counts are in their body files
    blocks, start = [], 0
    for b in bodies:
        hinge = b.get("hinge", "locked")
        if hinge not in HINGE_TYPES:
            return None
        n = int(counts[HINGE_TYPES[hinge]])
        if n:
            labels = list(hinge_record(hinge).labels[0 if leaf == "q" else 1])
            blocks.append((f"{b['name']} {hinge} hinge", start, n, labels[:n] if len(labels) >= n else
                           [f"{hinge}[{k}]" for k in range(n)], HINGE_UNITS[hinge][column]))
            start += n
        if b["name"] in flexible:
            n_modes = size - hinge_total
            suffix = {"q": "", "u": "'", "u_dot": "''"}[leaf]
            blocks.append((f"{b['name']} modal coordinates", start, n_modes,
                           [f"η{k + 1}{suffix}" for k in range(n_modes)], ("", "1/s", "1/s^2")[column]))
            start += n_modes
    return blocks if start == size else None


# ----------------------------------------------------------------------------------------------------
# panels
@dataclass
class Panel:
    """One axis of a figure: curves (time, values, label) sharing a unit."""

    title: str
    unit: str
    curves: list = field(default_factory=list)


def _family(name: str):
    """(pattern, differing element) pairs under which scalar signals are grouped."""
    parts = name.split(".")
    return [(".".join(parts[:k] + ["*"] + parts[k + 1:]), parts[k]) for k in range(len(parts) - 1)]


def build_panels(info: dict, data: dict, names: list[str], *, derived: bool = True, reference=None) -> list[Panel]:
    """Panels for signals ``names`` of a log (``log_info`` and ``read_log`` results)."""
    scenario = str(info["attributes"].get("scenario", ""))
    panels: list[Panel] = []
    scalars: dict[tuple, list] = {}
    for name in names:
        meta = info["signals"][name]
        t = data[meta["time"]]
        shape = tuple(data[name].shape[1:])
        values = data[name].reshape(len(t), -1)
        description = str(meta.get("description", ""))
        if values.shape[1] == 1:
            scalars.setdefault((pretty_unit(meta["unit"]),), []).append((name, t, values[:, 0]))
            continue
        blocks = coordinate_blocks(scenario, name, values.shape[1])
        if blocks:
            for title, start, n, labels, unit in blocks:
                panel = Panel(f"{name}: {title}", unit)
                panel.curves = [(t, values[:, start + k], labels[k]) for k in range(n)]
                panels.append(panel)
            continue
        labels = component_labels(name, shape, description)
        panels.append(Panel(name, meta["unit"], [(t, values[:, k], labels[k]) for k in range(values.shape[1])]))
        if derived and is_quaternion(name, shape, description):
            r = reference if reference is not None else commanded_attitude(scenario, name)
            r = np.array([1.0, 0.0, 0.0, 0.0]) if r is None else np.asarray(r, float)
            error = Panel(f"{name}: attitude error to [{', '.join(f'{v:.4g}' for v in r)}]", "deg")
            error.curves = [(t, np.degrees(attitude_error(values, r)), "error angle")]
            euler = Panel(f"{name}: 3-2-1 Euler angles", "deg")
            angles = np.degrees(euler_321(values))
            euler.curves = [(t, angles[:, k], label) for k, label in enumerate(("yaw", "pitch", "roll"))]
            panels += [error, euler]
    # scalar signals: group those that differ in one name element and share a unit
    for (unit,), members in scalars.items():
        remaining = list(members)
        while remaining:
            name, t, y = remaining[0]
            best = None
            for pattern, _ in _family(name):
                group = [m for m in remaining if any(p == pattern for p, _ in _family(m[0]))
                         and len(m[1]) == len(t) and np.array_equal(m[1], t)]
                if len(group) > 1 and (best is None or len(group) > len(best[1])):
                    best = (pattern, group)
            if best is None:
                panels.append(Panel(name, unit, [(t, y, None)]))
                remaining.pop(0)
                continue
            pattern, group = best
            index = pattern.split(".").index("*")
            panels.append(Panel(pattern, unit, [(gt, gy, gname.split(".")[index]) for gname, gt, gy in group]))
            remaining = [m for m in remaining if m not in group]
    order = {name: k for k, name in enumerate(names)}

    def first_signal(panel):
        head = panel.title.split(":")[0]
        return min((order[n] for n in names if re.fullmatch(re.escape(head).replace(r"\*", "[^.]+"), n)),
                   default=len(names))

    panels.sort(key=first_signal)  # stable: a signal's derived panels stay right after it
    return panels


def _figure_pages(panels: list[Panel], per_page: int):
    return [panels[k:k + per_page] for k in range(0, len(panels), per_page)]


def draw_pages(panels: list[Panel], title: str, per_page: int = PER_PAGE):
    """matplotlib figures (one per page of at most ``per_page`` panels)."""
    import matplotlib.pyplot as plt

    figures = []
    pages = _figure_pages(panels, per_page)
    for number, page in enumerate(pages, 1):
        figure, axes = plt.subplots(len(page), 1, sharex=True, squeeze=False,
                                    figsize=(FIGURE_WIDTH, PANEL_HEIGHT * len(page) + 0.9))
        for ax, panel in zip(axes[:, 0], page):
            labelled = False
            for t, y, label in panel.curves:
                ax.plot(t, y, lw=1.0, label=label)
                labelled |= label is not None
            ax.set_title(panel.title, fontsize=8, loc="left")
            ax.set_ylabel(pretty_unit(panel.unit) or "-", fontsize=8)
            ax.tick_params(labelsize=7)
            ax.grid(True, alpha=0.3)
            if labelled and len(panel.curves) > 1:
                ax.legend(fontsize=7, loc="upper right", ncol=min(len(panel.curves), 6))
        axes[-1, 0].set_xlabel("time [s]")
        suffix = f" (page {number} of {len(pages)})" if len(pages) > 1 else ""
        figure.suptitle(title + suffix, fontsize=10)
        figure.tight_layout()
        figures.append(figure)
    return figures


def page_paths(output: str, pages: int) -> list[str]:
    """``fig.png`` for one page; ``fig-1.png``, ``fig-2.png``, ... for several (a PDF keeps one file)."""
    path = Path(output)
    if pages == 1 or path.suffix.lower() == ".pdf":
        return [output]
    return [str(path.with_name(f"{path.stem}-{k}{path.suffix}")) for k in range(1, pages + 1)]


def _reference(text):
    if text is None:
        return None
    import yaml

    try:
        r = np.asarray(yaml.safe_load(text), float).reshape(4)
    except (ValueError, TypeError, yaml.YAMLError):
        raise ValueError(f"--attitude-reference: expected a quaternion [w, x, y, z], given {text!r}") from None
    if not np.isfinite(r).all() or abs(np.linalg.norm(r) - 1.0) > 1e-6:
        raise ValueError(f"--attitude-reference: expected a unit quaternion [w, x, y, z], given {text!r} "
                         f"(norm {np.linalg.norm(r):.6g})")
    return r


def plot(args) -> int:
    import matplotlib

    if not args.show:
        matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from shell.log_file import LogIncompleteWarning, log_info, read_log
    from shell.outputs import figure_kind, guard_output

    output = args.output or str(Path(args.log).with_suffix(".png"))
    inputs = ((args.log, "the log itself"),)
    try:
        if args.per_page < 1:
            raise ValueError(f"--per-page: expected a positive number of panels, given {args.per_page}")
        reference = _reference(args.attitude_reference)
        if not args.show:
            kind = figure_kind(output)  # the format, from the suffix: refused before the log is read
            guard_output(output, kind, inputs=inputs, overwrite=args.overwrite)
        info = log_info(args.log)
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", LogIncompleteWarning)
            data = read_log(args.log)
        for warning in caught:
            print(f"flexshell plot: note: {warning.message}", file=sys.stderr)
        available = list(info["signals"])
        names = [resolve_signal(s, available) for s in args.signals] if args.signals else available
    except (KeyError, OSError, ValueError) as exc:
        print(f"flexshell plot: {exc.args[0] if isinstance(exc, KeyError) else exc}", file=sys.stderr)
        return 1
    panels = build_panels(info, data, names, derived=not args.no_derived, reference=reference)
    status = info["attributes"].get("status", "")
    figures = draw_pages(panels, f"{Path(args.log).name} ({status})", args.per_page)
    if args.show:
        plt.show()
        return 0
    paths = page_paths(output, len(figures))
    try:  # the pages of a multi-page PNG (fig-1.png, ...) are outputs too
        for path in paths:
            guard_output(path, kind, inputs=inputs, overwrite=args.overwrite)
    except ValueError as exc:
        for figure in figures:
            plt.close(figure)
        print(f"flexshell plot: {exc}", file=sys.stderr)
        return 1
    if len(paths) == 1 and len(figures) > 1:
        from matplotlib.backends.backend_pdf import PdfPages

        with PdfPages(output) as pdf:
            for figure in figures:
                pdf.savefig(figure)
    else:
        for figure, path in zip(figures, paths):
            figure.savefig(path, dpi=110)
    for figure in figures:
        plt.close(figure)
    for path in paths:
        print(f"plot: {path}")
    return 0
