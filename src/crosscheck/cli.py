"""The ``crosscheck`` command line: one module per command under crosscheck.commands.

Commands are found, not listed: every public module of ``crosscheck.commands`` (a name not
starting with ``_``) provides ``register(subparsers)``, which sets ``func`` on its parser, and
``ORDER`` (its place in ``--help``). Adding a command is adding one module.

Exit status: 0 success (every applicable cell passes), 1 a physics failure or regression,
2 a usage or input error (a broken case file), so CI can tell them apart.
"""

from __future__ import annotations

import argparse
import importlib
import pkgutil
import sys

from crosscheck import __version__
from crosscheck.errors import CrosscheckError


def command_modules() -> list:
    """The command modules, in their ORDER (then by name)."""
    import crosscheck.commands as package

    modules = [importlib.import_module(f"{package.__name__}.{info.name}")
               for info in pkgutil.iter_modules(package.__path__)
               if not info.name.startswith("_")]
    return sorted(modules, key=lambda m: (getattr(m, "ORDER", 100), m.__name__))


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="crosscheck",
        description="Run one physics scene on several simulators and compare them honestly.",
    )
    parser.add_argument("--version", action="version", version=f"crosscheck {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for module in command_modules():
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
