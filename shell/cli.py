"""The ``flexshell`` command line.

Verbs live in :mod:`shell.commands`, one module each; a module joins the command line by defining
``register(subparsers)`` which adds its sub-parser and sets ``func`` (called with the parsed
arguments, returning an exit code). New verbs need no edit here.
"""

from __future__ import annotations

import argparse
import importlib
import pkgutil
import sys

from shell import __version__, commands
from shell.diagnostics import printed


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="flexshell",
        description="Flexible multibody simulation for guidance and control.",
    )
    parser.add_argument("--version", action="version", version=f"flexshell {__version__}")
    subparsers = parser.add_subparsers(dest="verb", metavar="VERB")
    for info in sorted(pkgutil.iter_modules(commands.__path__), key=lambda m: m.name):
        module = importlib.import_module(f"{commands.__name__}.{info.name}")
        module.register(subparsers)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    try:
        with printed(f"flexshell {args.verb}"):  # warnings as flexshell messages (shell/diagnostics.py)
            return int(args.func(args) or 0)
    except RecursionError:  # each verb reports its input's errors; these two are the input's size
        print(f"flexshell {args.verb}: the input is nested too deeply to process", file=sys.stderr)
        return 1
    except MemoryError:
        print(f"flexshell {args.verb}: out of memory (an input too large: a size, a count or a rate?)",
              file=sys.stderr)
        return 1


if __name__ == "__main__":
    sys.exit(main())
