"""``crosscheck baseline update|compare``: the committed baseline a run is gated against.

``update --from DIR [--out reports/baseline.json] [--merge]`` writes the baseline from a run's
``DIR/results.json`` and prints what changed against the file it replaces (regressions,
improvements, new and removed cells). ``compare --from DIR [--baseline FILE]`` prints the same
comparison without writing and exits 1 on a regression. The rules (per-metric absolute and
relative slack; wall time is not compared) are in crosscheck.baseline and docs/reports.md.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from crosscheck.commands._json import add_json_flag, emit, human_output

DEFAULT_BASELINE = "reports/baseline.json"


ORDER = 5  # its place in crosscheck --help


def register(subparsers) -> argparse.ArgumentParser:
    p = subparsers.add_parser("baseline", help="write or check the committed regression baseline",
                              description=__doc__.split("\n\n")[1])
    sub = p.add_subparsers(dest="baseline_command", metavar="ACTION", required=True)
    up = sub.add_parser("update", help="write the baseline from a run's results.json")
    up.add_argument("--from", dest="source", required=True, metavar="DIR",
                    help="output folder of a crosscheck run (or its results.json)")
    up.add_argument("--out", default=DEFAULT_BASELINE, metavar="FILE",
                    help=f"baseline file to write (default: {DEFAULT_BASELINE})")
    up.add_argument("--merge", action="store_true",
                    help="keep the old baseline's cells that this run did not run")
    up.add_argument("--allow-failures", action="store_true",
                    help="write even if cells failed (they are recorded with their status)")
    add_json_flag(up)
    up.set_defaults(func=run)
    cmp = sub.add_parser("compare", help="compare a run with the baseline; exit 1 on regression")
    cmp.add_argument("--from", dest="source", required=True, metavar="DIR")
    cmp.add_argument("--baseline", default=DEFAULT_BASELINE, metavar="FILE")
    add_json_flag(cmp)
    cmp.set_defaults(func=run)
    return p


def run(args) -> int:
    with human_output(args.json):
        status, payload = _run(args)
    if args.json:
        emit(payload)
    return status


def _run(args) -> tuple[int, dict]:
    from crosscheck.baseline import (
        BaselineError,
        baseline_from_results,
        compare,
        load_baseline,
        load_results,
        write_baseline,
    )

    results = load_results(args.source)
    if args.baseline_command == "compare":
        base = load_baseline(args.baseline)
        comparison = compare(base, results)
        print("\n".join(comparison.lines()))
        return (1 if comparison.regressions else 0), comparison.to_dict()

    if results.get("interrupted") and not args.merge:
        raise BaselineError(f"{args.source}: the run was interrupted; a baseline from it would "
                            "drop the cells it did not run (use --merge to keep the old ones)")
    bad = [c["id"] for c in results.get("cells", [])
           if c.get("status") in ("fail", "blowup", "error", "timeout")]
    if bad and not args.allow_failures:
        raise BaselineError(
            f"{len(bad)} cell(s) of that run did not pass (e.g. {bad[0]}); fix them or pass "
            "--allow-failures to record them as they are")
    out = Path(args.out)
    previous = load_baseline(out) if out.exists() else None
    comparison = None
    source = str(Path(args.source))
    doc = baseline_from_results(results, source=source, previous=previous, merge=args.merge)
    if previous is not None:
        comparison = compare(previous, results)
        print(f"changes against the previous {out}:")
        print("\n".join(comparison.lines()))
        if not args.merge and comparison.missing:
            print(f"{len(comparison.missing)} cell(s) dropped from the baseline")
    else:
        print(f"new baseline {out}")
    write_baseline(doc, out)
    statuses: dict[str, int] = {}
    for e in doc["entries"].values():
        statuses[e["status"]] = statuses.get(e["status"], 0) + 1
    print(f"wrote {out}: {len(doc['entries'])} cell(s) "
          + ", ".join(f"{n} {s}" for s, n in sorted(statuses.items())))
    return 0, {"wrote": str(out), "cells": len(doc["entries"]), "statuses": statuses,
               "changes": comparison.to_dict() if comparison is not None else None}
