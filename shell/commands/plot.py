"""``flexshell plot LOG.h5 SIGNAL...``: quick-look time histories of logged signals (matplotlib)."""

from __future__ import annotations

import sys
import warnings
from pathlib import Path


def register(subparsers) -> None:
    parser = subparsers.add_parser("plot", help="plot logged signals of an HDF5 log",
                                   description="Plot signals of a flexshell log against time. A signal may "
                                               "be named in full or by a unique suffix (acs.attitude).")
    parser.add_argument("log", help="log file (HDF5) written by flexshell run")
    parser.add_argument("signals", nargs="*", help="signals to plot (default: all)")
    parser.add_argument("-o", "--output", help="image file (default: LOG stem + .png)")
    parser.add_argument("--show", action="store_true", help="open a window instead of writing a file")
    parser.set_defaults(func=plot)


def _resolve(requested: str, available: list[str]) -> str:
    if requested in available:
        return requested
    matches = [name for name in available if name.endswith("." + requested)]
    if len(matches) == 1:
        return matches[0]
    if not matches:
        raise KeyError(f"no signal {requested!r} in the log; signals: {available}")
    raise KeyError(f"{requested!r} is ambiguous: {matches}")


def plot(args) -> int:
    import matplotlib

    if not args.show:
        matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from shell.log_file import LogIncompleteWarning, check_output_place, log_info, read_log

    try:
        if not args.show:
            check_output_place(args.output or str(Path(args.log).with_suffix(".png")))
        info = log_info(args.log)
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", LogIncompleteWarning)
            data = read_log(args.log)
        for warning in caught:
            print(f"flexshell plot: note: {warning.message}", file=sys.stderr)
        available = list(info["signals"])
        names = [_resolve(s, available) for s in args.signals] if args.signals else available
    except (KeyError, OSError, ValueError) as exc:
        print(f"flexshell plot: {exc.args[0] if isinstance(exc, KeyError) else exc}", file=sys.stderr)
        return 1
    figure, axes = plt.subplots(len(names), 1, sharex=True, figsize=(8, 2.2 * len(names) + 0.6), squeeze=False)
    for ax, name in zip(axes[:, 0], names):
        meta = info["signals"][name]
        t = data[meta["time"]]
        values = data[name].reshape(len(t), -1)
        for k in range(values.shape[1]):
            ax.plot(t, values[:, k], label=f"[{k}]" if values.shape[1] > 1 else None)
        ax.set_ylabel(f"{name}\n[{meta['unit'] or 'SI'}]", fontsize=8)
        ax.grid(True, alpha=0.3)
        if values.shape[1] > 1:
            ax.legend(fontsize=7, loc="upper right", ncol=min(values.shape[1], 4))
    axes[-1, 0].set_xlabel("time [s]")
    status = info["attributes"].get("status", "")
    figure.suptitle(f"{Path(args.log).name} ({status})", fontsize=10)
    figure.tight_layout()
    if args.show:
        plt.show()
        return 0
    output = args.output or str(Path(args.log).with_suffix(".png"))
    figure.savefig(output, dpi=110)
    print(f"plot: {output}")
    return 0
