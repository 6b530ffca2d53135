"""``crosscheck list [PATH...]``: the case files found, with their tags and engines."""

from __future__ import annotations

import argparse
import json

from rich.console import Console
from rich.markup import escape
from rich.table import Table

from crosscheck.errors import CaseError
from crosscheck.scene.loader import find_cases, load_case

ORDER = 1  # its place in crosscheck --help


def register(subparsers) -> argparse.ArgumentParser:
    p = subparsers.add_parser("list", help="list case files with their tags")
    p.add_argument("paths", nargs="*", default=["cases"], metavar="PATH",
                   help="case files or folders (default: cases)")
    p.add_argument("--json", action="store_true", help="print JSON instead of a table")
    p.set_defaults(func=run)
    return p


def run(args) -> int:
    rows, broken = [], []
    for path in find_cases(args.paths):
        try:
            scene = load_case(path)
        except CaseError as exc:  # list the others; a broken file is still shown, with why
            broken.append({"file": str(path), "error": str(exc)})
            continue
        rows.append({"file": str(path), "name": scene.name, "dimension": scene.dimension,
                     "tags": list(scene.tags), "engines": list(scene.run.engines),
                     "description": scene.description})
    if args.json:
        print(json.dumps({"cases": rows, "errors": broken}, indent=2))
    else:
        table = Table(title=f"{len(rows)} case(s)")
        for col in ("file", "name", "dim", "tags", "engines"):
            table.add_column(col)
        for r in rows:
            # case-file text is escaped: a name or tag with "[...]" is text, not rich markup
            table.add_row(escape(r["file"]), escape(r["name"]), f"{r['dimension']}D",
                          escape(", ".join(r["tags"])), ", ".join(r["engines"]))
        console = Console()
        console.print(table)
        for b in broken:
            console.print(f"[red]error:[/red] {escape(b['error'])}", highlight=False)
    return 2 if broken else 0
