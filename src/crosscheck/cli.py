"""The ``crosscheck`` command line: one module per command under crosscheck.commands.

Exit status: 0 success (every applicable cell passes), 1 a physics failure or regression,
2 a usage or input error (a broken case file), so CI can tell them apart.
"""

from __future__ import annotations

import argparse
import importlib
import sys

from crosscheck import __version__
from crosscheck.errors import CrosscheckError

# Each module provides register(subparsers) and sets func=run on its parser.
COMMANDS = ("list", "show", "inertia", "run", "baseline", "sweep")


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="crosscheck",
        description="Run one physics scene on several simulators and compare them honestly.",
    )
    parser.add_argument("--version", action="version", version=f"crosscheck {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name in COMMANDS:
        try:
            module = importlib.import_module(f"crosscheck.commands.{name}")
        except ModuleNotFoundError as exc:
            if exc.name == f"crosscheck.commands.{name}":
                continue  # a command not written yet
            raise
        module.register(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    try:
        return int(args.func(args) or 0)
    except CrosscheckError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    except BrokenPipeError:  # `crosscheck show --json FILE | head`: the reader left, not an error
        sys.stderr.close()
        return 0
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
