"""Does a cell's cost hold still? (issue 13 point 6)

Runs every committed rigid case ``--runs`` times (default 3), each time as a fresh
``crosscheck run`` (new worker processes), with the cost pass spread over ``--processes`` passes
(default: the CostPlan default, 3; ``--processes 1 3`` compares), and counts, over every pair of
runs, the cells whose cost moved between the two by more than the spread the runs reported, for
the minimum (``cost``, against ``cost_spread``) and the median (``cost_median``, against
``cost_median_spread``; older results without it: ``cost_spread``), the move being
``|log(c1 / c2)|`` (the spread is a half-width in log; a relative difference
``|c1 - c2| / mean`` is never larger):

* *outside own*: counted once for each of the two runs whose spread the move exceeds (the
  spread's contract when the second run's machine is no busier: docs/metrics.md "Cost");
* *outside both*: the move exceeds the larger of the two spreads (the contract between runs
  under different load: each run's spread holds the load it measured).

One pair of runs is one draw: every pair of several runs is counted. It also fits the spread's
prior on the runs' passes (benchmarks/fit_cost_prior.py) and records the load average before
and after. Writes benchmarks/results/cost_stability.md and .json.

    python benchmarks/bench_cost_stability.py [--workers 2] [--runs 3] [--processes 3]
        [--cases DIR ...] [--keep DIR]
"""

from __future__ import annotations

import argparse
import itertools
import json
import math
import os
import platform
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(Path(__file__).resolve().parent))

from fit_cost_prior import fit_report, passes_of  # noqa: E402

FIGURES = (("cost", "cost_spread"), ("cost_median", "cost_median_spread"))


def run_once(cases: list[str], out: Path, workers: int, processes: int) -> dict:
    cmd = [sys.executable, "-m", "crosscheck.cli", "run", *cases, "--workers", str(workers),
           "--cost-processes", str(processes), "--progress", "none", "--out", str(out)]
    subprocess.run(cmd, cwd=ROOT, check=False, stdout=subprocess.DEVNULL)
    return json.loads((out / "results.json").read_text())


def compare(docs: list[dict]) -> dict:
    """Every pair of runs, every cell both timed: how far its cost moved against its spreads."""
    rows = []
    for i, j in itertools.combinations(range(len(docs)), 2):
        second = {c["id"]: c for c in docs[j]["cells"] if c.get("cost")}
        for c in docs[i]["cells"]:
            d = second.get(c["id"])
            if not c.get("cost") or d is None:
                continue
            row = {"id": c["id"], "runs": [i, j]}
            for key, spread_key in FIGURES:
                s1 = c.get(spread_key, c.get("cost_spread")) or 0.0
                s2 = d.get(spread_key, d.get("cost_spread")) or 0.0
                row[key] = {"move": abs(math.log(c[key] / d[key])), "spreads": [s1, s2]}
            rows.append(row)
    out = {"cells": len(rows), "rows": rows}
    for key, _ in FIGURES:
        moved = [r[key]["move"] for r in rows]
        spreads = [s for r in rows for s in r[key]["spreads"]]
        out[key] = {
            "outside_own": sum((r[key]["move"] > s) for r in rows for s in r[key]["spreads"]),
            "outside_both": sum(r[key]["move"] > max(r[key]["spreads"]) for r in rows),
            "worst_ratio": max((r[key]["move"] / max(r[key]["spreads"]) for r in rows
                                if max(r[key]["spreads"]) > 0), default=None),
            "median_move": statistics.median(moved) if moved else None,
            "max_move": max(moved) if moved else None,
            "median_spread": statistics.median(spreads) if spreads else None,
            "worst": sorted(({"id": r["id"], "runs": r["runs"], "move": r[key]["move"],
                              "spreads": r[key]["spreads"]} for r in rows
                             if r[key]["move"] > min(r[key]["spreads"])),
                            key=lambda x: -x["move"] / max(max(x["spreads"]), 1e-12))[:10],
        }
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cases", nargs="*", default=["cases/rigid3d", "cases/rigid2d"])
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--processes", type=int, nargs="*", default=[3])
    ap.add_argument("--keep", default=None, help="copy each run's results.json under DIR")
    ap.add_argument("--out", default=str(ROOT / "benchmarks" / "results"))
    args = ap.parse_args(argv)
    results, seconds, passes = {}, {}, {}
    load_before = os.getloadavg()
    with tempfile.TemporaryDirectory() as tmp:
        for processes in args.processes:
            docs, took = [], []
            for k in range(args.runs):
                run_dir = Path(tmp) / f"p{processes}-{k}"
                t0 = time.monotonic()
                docs.append(run_once(args.cases, run_dir, args.workers, processes))
                took.append(time.monotonic() - t0)
                if args.keep:
                    keep = Path(args.keep) / run_dir.name
                    keep.mkdir(parents=True, exist_ok=True)
                    shutil.copy(run_dir / "results.json", keep / "results.json")
            results[processes] = compare(docs)
            seconds[processes] = took
            passes[processes] = [passes_of(doc) for doc in docs]
    load_after = os.getloadavg()
    lines = [f"# Cost stability: {args.runs} fresh runs of every rigid cell, every pair", "",
             f"Machine: {platform.machine()}, {platform.python_version()}, {os.cpu_count()} "
             f"CPUs shared with other users; {args.workers} worker(s); load average (1, 5, 15 "
             f"min) {', '.join(f'{x:.1f}' for x in load_before)} before and "
             f"{', '.join(f'{x:.1f}' for x in load_after)} after; cases "
             f"{' '.join(args.cases)}. Cells = cell x pair of runs. The move of a figure is "
             "|log(c1 / c2)|; *outside own*: counted for each of the two runs whose spread it "
             "exceeds (of 2 x cells); *outside both*: it exceeds the larger spread "
             "(benchmarks/bench_cost_stability.py, docs/metrics.md \"Cost\").", "",
             "| cost passes | cells | run seconds | figure | median spread | outside own "
             "| outside both | median move | max move | worst move / larger spread |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    for processes, r in results.items():
        for key, _ in FIGURES:
            f = r[key]
            lines.append(
                f"| {processes} | {r['cells']} | "
                f"{' '.join(f'{s:.0f}' for s in seconds[processes])} | `{key}` | "
                f"{f['median_spread']:.2%} | {f['outside_own']} of {2 * r['cells']} | "
                f"{f['outside_both']} of {r['cells']} | {f['median_move']:.2%} | "
                f"{f['max_move']:.1%} | {f['worst_ratio']:.2f} |")
    for processes, r in results.items():
        lines += ["", f"Worst moves against the smaller spread ({processes} passes):", ""]
        for key, _ in FIGURES:
            for w in r[key]["worst"][:5]:
                lines.append(f"- `{key}` {w['id']} runs {w['runs']}: moved {w['move']:.1%}, "
                             f"spreads {w['spreads'][0]:.1%} / {w['spreads'][1]:.1%}")
    for processes, runs in passes.items():
        if processes > 1:
            lines += ["", *fit_report(runs, title=f"Prior fitted on these runs' passes "
                                                    f"({processes} per cell)")]
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    (out / "cost_stability.md").write_text("\n".join(lines) + "\n")
    (out / "cost_stability.json").write_text(json.dumps(
        {"load_before": load_before, "load_after": load_after, "seconds": seconds,
         "results": results}, indent=1))
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    sys.exit(main())
