"""The DFG benchmark (Schafer & Turek 1996) with the in-house cut-cell fluid: the grid
convergence of 2D-1 (steady, Re = 20) and the periodic 2D-2 (Re = 100).

    .venv/bin/python benchmarks/bench_dfg.py [--case 2d1|2d2] [--cells 10 20 30 40]
        [--duration S] [--integrator central] [--offset F] [--out DIR]

2D-1 runs ``cases/fluid/dfg_2d1.toml`` with the grid refined to ``--cells`` cells across the
cylinder (the case file has 10), to ``--duration`` (default the case's 6 s, 30 convective
times), and measures the drag and lift coefficients and the front-back pressure difference with
the case's own metrics (``compare/fluid_metrics.py``). The observed order of each quantity is
``log(e_coarse / e_fine) / log(h_coarse / h_fine)`` between successive grids, e the difference
from the FEATFLOW reference value; the Richardson order of the three finest grids (the p that
makes ``f0 + C h^p`` pass through their three values) needs no reference at all.

2D-2 builds the same channel with U_max = 1.5 (Re = 100), runs ``--duration`` (default 10 s)
sampling every 5 ms, and measures the maximum drag and lift coefficients and the Strouhal
number over the second half (the shedding has settled by then; the case metrics' default).

``--offset F`` moves the cylinder downstream by F cells (0 <= F < 1; the case's placement has
the cylinder's extreme points on grid lines): the runs at other offsets are listed apart, under
"Where the grid cuts the cylinder", and measure how much of each number is the placement.

Each run is appended to ``benchmarks/results/dfg.json`` as it finishes (a long study survives a
stop), and ``dfg.md`` is written from everything in it. Run in the background at low priority:
the finest 2D-1 grid (40 cells, 880 x 164) takes of the order of an hour on the shared machine.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import os
import platform
import time
from pathlib import Path

import numpy as np

from crosscheck.compare.fluid_metrics import fluid_metrics
from crosscheck.reference.fluid_data import dfg_reference
from crosscheck.scene.loader import load_case, load_case_text
from crosscheck.sim.fluid import run_fluid

ROOT = Path(__file__).resolve().parents[1]
CASE = ROOT / "cases" / "fluid" / "dfg_2d1.toml"
OUT = ROOT / "benchmarks" / "results"
QUANTITIES = {"2d1": ("drag_coefficient", "lift_coefficient", "pressure_difference"),
              "2d2": ("drag_coefficient_max", "lift_coefficient_max", "strouhal_number")}


def scene_for(case: str, cells: int, duration: float | None, offset: float = 0.0):
    """The DFG scene at ``cells`` cells across the cylinder; ``offset``: the cylinder moved
    downstream by that fraction of a cell (the grid-placement study; the channel is 22 D long,
    so a shift of a fraction of D / cells changes nothing the benchmark measures, only where the
    grid lines cut the cylinder)."""
    text = CASE.read_text()
    if case == "2d2":
        text = (text.replace('name = "fluid-dfg-2d1"', 'name = "fluid-dfg-2d2"')
                .replace("speed = 0.3 }", "speed = 1.5 }")
                .replace('table = "schafer_turek_2d1"', 'table = "schafer_turek_2d2"')
                .replace("sample_every = 0.1", "sample_every = 0.005")
                .replace("field_every = 1.0", "field_every = 100.0"))
        # the 2D-1 tolerances name 2D-1 metrics; the benchmark reports, it does not judge
        text = text.split("[tolerances]")[0]
        scene = load_case_text(text, CASE.name, base_dir=CASE.parent)
        duration = 10.0 if duration is None else duration
    else:
        scene = load_case(CASE)
    k = cells / 10
    nx, ny = (round(r * k) for r in scene.fluid.resolution)
    fluid = dataclasses.replace(scene.fluid, resolution=(nx, ny))
    if offset:
        # past the loader, which holds the case to the benchmark's geometry exactly
        ob = fluid.obstacles[0]
        moved = dataclasses.replace(ob, position=np.asarray(ob.position, float)
                                    + np.array([offset * fluid.dx, 0.0]))
        fluid = dataclasses.replace(fluid, obstacles=(moved,) + tuple(fluid.obstacles[1:]))
    run = scene.run if duration is None else dataclasses.replace(scene.run, duration=duration)
    return dataclasses.replace(scene, fluid=fluid, run=run)


def run_one(case: str, cells: int, duration: float | None, integrator: str,
            offset: float = 0.0) -> dict:
    scene = scene_for(case, cells, duration, offset)
    t0 = time.perf_counter()
    rec = run_fluid(scene, integrator)
    wall = time.perf_counter() - t0
    m = rec.meta
    metrics = fluid_metrics(scene, rec) if rec.failure is None else {}
    return {
        "case": case, "cells_per_diameter": cells, "offset": offset,
        "grid": list(scene.fluid.resolution), "dx": scene.fluid.dx,
        "duration": scene.run.duration, "integrator": integrator,
        "failure": rec.failure, "wall_s": wall, "steps": m["dt"]["steps"],
        "ms_per_step": m["ms_per_step"], "cg_iterations_mean": m["pressure_iterations"]["mean"],
        "metrics": metrics,
        "recorded": time.strftime("%Y-%m-%d %H:%M:%S"),
        "load_average": os.getloadavg()[0],
    }


def observed_orders(runs: list[dict], case: str) -> list[dict]:
    """Orders between successive grids, from the error against the reference target."""
    out = []
    runs = sorted(runs, key=lambda r: r["cells_per_diameter"])
    for a, b in zip(runs, runs[1:], strict=False):
        row = {"from": a["cells_per_diameter"], "to": b["cells_per_diameter"]}
        for q in QUANTITIES[case]:
            ea = a["metrics"].get(f"{q}_error")
            eb = b["metrics"].get(f"{q}_error")
            ok = ea and eb and math.isfinite(ea) and math.isfinite(eb) and ea > 0 and eb > 0
            row[q] = (math.log(ea / eb) / math.log(b["cells_per_diameter"]
                                                   / a["cells_per_diameter"])) if ok else None
        out.append(row)
    return out


def _order(f1: float, f2: float, f3: float, h1: float, h2: float, h3: float) -> float | None:
    """The order p with (f1 - f2) / (f2 - f3) = (h1^p - h2^p) / (h2^p - h3^p) (three grids of
    any spacings h1 > h2 > h3), by bisection on p in (0.05, 8); None when the differences do not
    shrink monotonically."""
    if (f2 - f3) == 0 or (f1 - f2) / (f2 - f3) <= 1.0:
        return None
    target = (f1 - f2) / (f2 - f3)

    def g(p: float) -> float:
        return (h1**p - h2**p) / (h2**p - h3**p) - target

    lo, hi = 0.05, 8.0
    if g(lo) * g(hi) > 0:
        return None
    for _ in range(100):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if g(lo) * g(mid) > 0 else (lo, mid)
    return 0.5 * (lo + hi)


def richardson(runs: list[dict], case: str) -> dict:
    """Order and extrapolated value from the three finest grids (no reference needed):
    ``f(h) = f0 + C h^p`` through the three points."""
    runs = sorted(runs, key=lambda r: r["cells_per_diameter"])[-3:]
    if len(runs) < 3:
        return {}
    h = [1.0 / r["cells_per_diameter"] for r in runs]
    res = {"grids": [r["cells_per_diameter"] for r in runs]}
    for q in QUANTITIES[case]:
        f = [r["metrics"].get(q) for r in runs]
        p = None if None in f else _order(*f, *h)
        if p is None:
            res[q] = None
            continue
        c = (f[1] - f[2]) / (h[1] ** p - h[2] ** p)
        res[q] = {"order": p, "extrapolated": f[2] - c * h[2] ** p}
    return res


def write_markdown(data: dict, path: Path) -> None:
    lines = ["# DFG benchmark: channel flow past a cylinder (in-house cut-cell fluid)", "",
             "Schafer & Turek (1996); reference intervals and the FEATFLOW 2D-1 values in "
             "`src/crosscheck/reference/data/schafer_turek1996_cylinder.csv`. Produced by "
             "`benchmarks/bench_dfg.py`; each row is one run of the case at that grid "
             "(`cells` across the cylinder of diameter D = 0.1 m; the case file's grid is 10). "
             f"Machine: {data.get('machine', '?')}, 2 cores shared with other work (wall "
             "times are indicative only).", ""]
    for case, title in (("2d1", "2D-1, Re = 20, steady"), ("2d2", "2D-2, Re = 100, periodic")):
        runs = sorted((r for r in data["runs"]
                       if r["case"] == case and not r.get("offset", 0.0)),
                      key=lambda r: r["cells_per_diameter"])
        if not runs:
            continue
        moved = sorted((r for r in data["runs"] if r["case"] == case),
                       key=lambda r: (r["cells_per_diameter"], r.get("offset", 0.0)))
        refs, _ = dfg_reference("2D-1" if case == "2d1" else "2D-2")
        qs = QUANTITIES[case]
        lines += [f"## {title}", "",
                  "| cells/D | grid | " + " | ".join(f"{q} (error)" for q in qs)
                  + " | steps | ms/step | CG its | wall s |",
                  "|---" * (len(qs) + 6) + "|"]
        for r in runs:
            m = r["metrics"]
            cells = []
            for q in qs:
                v, e = m.get(q), m.get(f"{q}_error")
                inside = m.get(f"{q}_interval_miss") == 0.0
                cells.append("-" if v is None else
                             f"{v:.5g} ({100 * e:.2f} %{', in' if inside else ''})")
            lines.append(f"| {r['cells_per_diameter']} | {r['grid'][0]} x {r['grid'][1]} | "
                         + " | ".join(cells)
                         + f" | {r['steps']} | {r['ms_per_step']:.1f} | "
                         f"{r['cg_iterations_mean']:.0f} | {r['wall_s']:.0f} |")
        lines += ["", "Published: " + ", ".join(
            f"{q} {refs[q].lower:g}-{refs[q].upper:g}"
            + ("" if refs[q].reference is None else f" (reference {refs[q].reference:.10g})")
            for q in qs) + ". Errors are relative to the reference value (2D-1) or to the "
            "interval's centre (2D-2); ', in' marks a value inside the published interval.", ""]
        orders = observed_orders(runs, case)
        if orders:
            lines += ["Observed order between successive grids (from the errors):", "",
                      "| grids | " + " | ".join(qs) + " |", "|---" * (len(qs) + 1) + "|"]
            for o in orders:
                lines.append(f"| {o['from']} -> {o['to']} | " + " | ".join(
                    "-" if o[q] is None else f"{o[q]:.2f}" for q in qs) + " |")
            lines.append("")
        rich = richardson(runs, case)
        if rich:
            lines += [f"Richardson (the three finest grids, {rich['grids']} cells; no reference "
                      "used): " + "; ".join(
                f"{q}: order {rich[q]['order']:.2f}, extrapolated {rich[q]['extrapolated']:.6g}"
                if rich.get(q) else f"{q}: no f0 + C h^p fits (its differences do not shrink "
                "as a power of h)" for q in qs) + ".", ""]
        if any(r.get("offset", 0.0) for r in moved):
            lines += ["Where the grid cuts the cylinder (`--offset f`: the cylinder moved "
                      "downstream by f cells, a shift that changes nothing the benchmark "
                      "measures; the grids above have the cylinder's four extreme points on "
                      "grid lines):", "",
                      "| cells/D | offset (cells) | " + " | ".join(qs) + " |",
                      "|---" * (len(qs) + 2) + "|"]
            for r in moved:
                lines.append(f"| {r['cells_per_diameter']} | {r.get('offset', 0.0):g} | "
                             + " | ".join("-" if r["metrics"].get(q) is None
                                          else f"{r['metrics'][q]:.5g}" for q in qs) + " |")
            lines.append("")
        if case == "2d2":
            lines += ["Periods measured: " + ", ".join(
                f"{r['cells_per_diameter']}: {r['metrics'].get('periods', 0):.0f}"
                for r in runs) + " (lift zero crossings in the second half of the run).", ""]
    lines += ["How: the in-house `central` scheme (second-order central convection, "
              "Adams-Bashforth 2, Crank-Nicolson viscosity with ghost-fluid no-slip walls on "
              "the cut cells, the "
              "incremental pressure projection weighted by open face fractions), CFL 0.5. Forces "
              "by the momentum balance over the smooth window 0.025-0.1 m from the cylinder "
              "(docs/fluid.md, \"Forces on a body\"); the pressure difference by least-squares "
              "quadratics through the fluid cells within three cells of the front and back "
              "points. 2D-1 is the case's final state at 12 s (c_D steady to 1e-8, c_L to about "
              "3e-4 over the last 1.2 s); 2D-2 reads the samples of the second half of its 10 s "
              "(5 ms apart; maxima refined by a parabola through the largest sample and its "
              "neighbours), the Strouhal number from the lift's upward zero crossings there.", ""]
    for note in data.get("notes", []):
        lines.append(note)
    path.write_text("\n".join(lines).rstrip() + "\n")


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--case", choices=("2d1", "2d2"), default="2d1")
    ap.add_argument("--cells", type=int, nargs="+", default=None,
                    help="cells across the cylinder (multiples of 10); default 10 20 30 40 "
                         "(2D-1) or 10 20 (2D-2)")
    ap.add_argument("--duration", type=float, default=None)
    ap.add_argument("--integrator", default="central")
    ap.add_argument("--offset", type=float, default=0.0,
                    help="move the cylinder downstream by this fraction of a cell (0 <= f < 1): "
                         "how much the result depends on where the grid cuts the cylinder")
    ap.add_argument("--out", type=Path, default=OUT)
    ap.add_argument("--report", action="store_true",
                    help="only rewrite dfg.md from dfg.json (no runs)")
    args = ap.parse_args()
    cells = args.cells or ([10, 20, 30, 40] if args.case == "2d1" else [10, 20])
    args.out.mkdir(parents=True, exist_ok=True)
    jpath = args.out / "dfg.json"
    data = json.loads(jpath.read_text()) if jpath.exists() else {"runs": []}
    data["machine"] = f"{platform.processor() or platform.machine()}, {os.cpu_count()} cpus"
    if args.report:
        write_markdown(data, args.out / "dfg.md")
        return
    for c in cells:
        if c % 10:
            raise SystemExit(f"--cells {c}: the DFG grid needs a multiple of 10 cells across D")
        entry = run_one(args.case, c, args.duration, args.integrator, args.offset)
        # read again: another study may have added its runs meanwhile
        data = json.loads(jpath.read_text()) if jpath.exists() else {"runs": []}
        data["machine"] = f"{platform.processor() or platform.machine()}, {os.cpu_count()} cpus"
        data["runs"] = [r for r in data["runs"]
                        if (r["case"], r["cells_per_diameter"], r.get("offset", 0.0))
                        != (args.case, c, args.offset)] + [entry]
        jpath.write_text(json.dumps(data, indent=1))
        write_markdown(data, args.out / "dfg.md")
        print(json.dumps({k: entry[k] for k in ("case", "cells_per_diameter", "wall_s")}),
              {q: entry["metrics"].get(q) for q in QUANTITIES[args.case]}, flush=True)


if __name__ == "__main__":
    main()
