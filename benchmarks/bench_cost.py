"""Cost of every committed rigid case on every engine and integrator, as ratios in one run.

Runs ``crosscheck run`` on cases/rigid3d and cases/rigid2d with ONE worker (no other run
shares the machine while a cell is timed) and a longer cost pass than the default (at least 5
repetitions and 0.5 s of timed stepping per cell), then tabulates, per case, each cell's cost
(docs/metrics.md, "Cost": the driver's timed ``advance`` without recording, minimum over the
repetitions, with the spread) and its ratio against MuJoCo measured in the same run, both at
MuJoCo's default integrator (Euler) and at MuJoCo's fastest integrator whose cell passed the
case (its fastest sound setting). Writes benchmarks/results/cost.md and cost.json.

    python benchmarks/bench_cost.py [--cases DIR ...] [--out benchmarks/results]
"""

from __future__ import annotations

import argparse
import json
import platform
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def run_cases(cases: list[str], out: Path) -> dict:
    cmd = [sys.executable, "-m", "crosscheck.cli", "run", *cases, "--workers", "1",
           "--cost-repeats", "5", "--cost-seconds", "0.5", "--out", str(out)]
    subprocess.run(cmd, cwd=ROOT, check=False, stdout=subprocess.DEVNULL)
    return json.loads((out / "results.json").read_text())


def tabulate(doc: dict) -> list[dict]:
    rows = []
    by_case: dict[str, list[dict]] = {}
    for c in doc["cells"]:
        if c.get("cost"):
            by_case.setdefault(c["case"], []).append(c)
    for case, cells in sorted(by_case.items()):
        mj = {c["integrator"]: c for c in cells if c["engine"] == "mujoco"}
        default = mj.get("euler")
        sound = [c for c in mj.values() if c["status"] == "pass"]
        fastest = min(sound, key=lambda c: c["cost"]) if sound else None
        for c in sorted(cells, key=lambda c: c["cost"]):
            detail = c.get("cost_detail") or {}
            rows.append({
                "case": case, "engine": c["engine"], "integrator": c["integrator"],
                "status": c["status"], "cost": c["cost"], "cost_median": c.get("cost_median"),
                "spread": c.get("cost_spread"), "repeats": detail.get("repeats"),
                "us_per_step": detail.get("us_per_step"),
                "vs_mujoco_default": c["cost"] / default["cost"] if default else None,
                "vs_mujoco_fastest": c["cost"] / fastest["cost"] if fastest else None,
                "mujoco_fastest": fastest["integrator"] if fastest else None,
            })
    return rows


def _num(x, fmt="{:.3g}") -> str:
    return "" if x is None else fmt.format(x)


def markdown(rows: list[dict], machine: dict) -> str:
    lines = ["# Cost of the committed rigid cases, one run",
             "",
             f"Machine: {machine['machine']}, Python {machine['python']}, one worker. Cost: "
             "seconds of timed stepping per simulated second, minimum of at least 5 "
             "repetitions and 0.5 s (docs/metrics.md, \"Cost\"); spread = interquartile range / "
             "median of the repetitions. "
             "Ratios against MuJoCo in the same run: its default integrator (euler) and its "
             "fastest integrator that passed the case.",
             ""]
    case = None
    for r in rows:
        if r["case"] != case:
            case = r["case"]
            fastest = r["mujoco_fastest"]
            lines += ["", f"## {case} (MuJoCo's fastest sound: {fastest or 'none'})", "",
                      "| engine | integrator | status | cost (s/s) | spread | n | us/step | "
                      "/ MuJoCo euler | / MuJoCo fastest |",
                      "|---|---|---|---|---|---|---|---|---|"]
        lines.append(
            f"| {r['engine']} | {r['integrator']} | {r['status']} | {_num(r['cost'])} | "
            f"{_num(r['spread'], '{:.0%}')} | {_num(r['repeats'], '{}')} | "
            f"{_num(r['us_per_step'])} | {_num(r['vs_mujoco_default'])} | "
            f"{_num(r['vs_mujoco_fastest'])} |")
    return "\n".join(lines) + "\n"


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cases", nargs="*", default=["cases/rigid3d", "cases/rigid2d"])
    parser.add_argument("--out", default=str(ROOT / "benchmarks" / "results"))
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        doc = run_cases(args.cases, Path(tmp))
    rows = tabulate(doc)
    machine = {"machine": platform.machine(), "python": platform.python_version(),
               "engines": doc.get("engines")}
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    (out / "cost.json").write_text(json.dumps({"machine": machine, "rows": rows}, indent=1))
    (out / "cost.md").write_text(markdown(rows, machine))
    print((out / "cost.md").read_text())
    return 0


if __name__ == "__main__":
    sys.exit(main())
