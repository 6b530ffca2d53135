"""Does a cell's cost hold still? (issue 13 point 6)

Runs every committed rigid case ``--runs`` times (default 3), each time as a fresh
``crosscheck run`` (new worker processes), with the cost pass in one process
(``--cost-processes 1``, the old way) and pooled over three (the default), and counts, over
every pair of runs, the cells whose cost moved between the two by more than the spread the runs
reported: ``|c1 - c2| / mean(c1, c2) > max(spread1, spread2)``, for the minimum (``cost``) and
the median (``cost_median``). One pair of runs is one draw: a single pair once read 3 of 80
cells outside where three runs on the same quiet machine read 65 of 240 pairs, so every pair
of several runs is counted. Writes benchmarks/results/cost_stability.md and .json.

    python benchmarks/bench_cost_stability.py [--workers 2] [--runs 3] [--cases DIR ...]
"""

from __future__ import annotations

import argparse
import itertools
import json
import os
import platform
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def run_once(cases: list[str], out: Path, workers: int, processes: int) -> dict:
    cmd = [sys.executable, "-m", "crosscheck.cli", "run", *cases, "--workers", str(workers),
           "--cost-processes", str(processes), "--progress", "none", "--out", str(out)]
    subprocess.run(cmd, cwd=ROOT, check=False, stdout=subprocess.DEVNULL)
    return json.loads((out / "results.json").read_text())


def compare(docs: list[dict]) -> dict:
    """Every pair of runs, every cell both timed: how far its cost moved against its spread."""
    rows = []
    for i, j in itertools.combinations(range(len(docs)), 2):
        second = {c["id"]: c for c in docs[j]["cells"] if c.get("cost")}
        for c in docs[i]["cells"]:
            d = second.get(c["id"])
            if not c.get("cost") or d is None:
                continue
            spread = max(c.get("cost_spread") or 0.0, d.get("cost_spread") or 0.0)
            row = {"id": c["id"], "runs": [i, j], "spread": spread}
            for key in ("cost", "cost_median"):
                x, y = c[key], d[key]
                row[key] = abs(x - y) / (0.5 * (x + y))
            rows.append(row)
    out = {"cells": len(rows), "rows": rows}
    for key in ("cost", "cost_median"):
        moved = [r[key] for r in rows]
        out[key] = {"outside_spread": sum(r[key] > r["spread"] for r in rows),
                    "worst_ratio": max((r[key] / r["spread"] for r in rows if r["spread"]),
                                       default=None),
                    "median_move": statistics.median(moved) if moved else None,
                    "max_move": max(moved) if moved else None}
    out["median_spread"] = statistics.median(r["spread"] for r in rows) if rows else None
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cases", nargs="*", default=["cases/rigid3d", "cases/rigid2d"])
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--out", default=str(ROOT / "benchmarks" / "results"))
    args = ap.parse_args(argv)
    results = {}
    with tempfile.TemporaryDirectory() as tmp:
        for processes in (1, 3):
            docs = [run_once(args.cases, Path(tmp) / f"p{processes}-{k}", args.workers,
                             processes) for k in range(args.runs)]
            results[processes] = compare(docs)
    load = os.getloadavg()[0]
    lines = [f"# Cost stability: {args.runs} fresh runs of every rigid cell, every pair", "",
             f"Machine: {platform.machine()}, {platform.python_version()}; "
             f"{args.workers} worker(s); load average {load:.1f} at the end; cases "
             f"{' '.join(args.cases)}. Cells = cell x pair of runs. A cell *moved outside* when "
             "its cost changed between two runs by more than the larger spread the two runs "
             "reported; worst = the largest move / spread (benchmarks/bench_cost_stability.py).",
             "",
             "| cost pass | cells | median spread | min cost: outside spread | median move "
             "| max move | worst | median cost: outside spread | median move | max move | worst |",
             "|---|---|---|---|---|---|---|---|---|---|---|"]
    for processes, r in results.items():
        lines.append(
            f"| {processes} process(es) | {r['cells']} | {r['median_spread']:.2%} | "
            f"{r['cost']['outside_spread']} | {r['cost']['median_move']:.2%} | "
            f"{r['cost']['max_move']:.1%} | {r['cost']['worst_ratio']:.2f} | "
            f"{r['cost_median']['outside_spread']} | {r['cost_median']['median_move']:.2%} | "
            f"{r['cost_median']['max_move']:.1%} | {r['cost_median']['worst_ratio']:.2f} |")
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    (out / "cost_stability.md").write_text("\n".join(lines) + "\n")
    (out / "cost_stability.json").write_text(json.dumps(results, indent=1))
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    sys.exit(main())
