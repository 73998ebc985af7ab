"""``flexshell report OUT.h5 -o DIR``: percentile tables and charts (PNG) of a campaign's results."""

from __future__ import annotations

import sys


def register(subparsers) -> None:
    parser = subparsers.add_parser("report", help="percentile tables and PNG charts of a Monte Carlo campaign",
                                   description="Write percentiles.md/.csv, metric histograms, metric-vs-draw "
                                               "scatter plots and kept-signal overlays of a campaign results file.")
    parser.add_argument("results", help="campaign results file written by flexshell montecarlo")
    parser.add_argument("-o", "--output", default="report", help="output directory (default: report)")
    parser.add_argument("--overwrite", action="store_true",
                        help="replace files of the report's names (percentiles.md, hist_*.png, ...) in the output "
                             "directory even when the report did not write them (without it they are refused)")
    parser.set_defaults(func=run)


def run(args) -> int:
    from shell.montecarlo.report import write_report
    from shell.montecarlo.results import ResultsError
    from shell.outputs import OutputError, guard_report_directory

    try:
        guard_report_directory(args.output, inputs=((args.results, "the campaign results itself"),),
                               overwrite=args.overwrite)
        written = write_report(args.results, args.output)
    except (ResultsError, OutputError, OSError) as exc:
        print(f"flexshell report: {exc}", file=sys.stderr)
        return 1
    print((args.output.rstrip("/") + "/percentiles.md"))
    print(open(written[1]).read())
    print(f"{len(written)} files in {args.output}")
    return 0
