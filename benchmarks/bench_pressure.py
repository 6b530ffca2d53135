"""Cost of the pressure solve with and without multigrid on the DFG channel (sim/fluid/amg.py).

    PYTHONPATH=src .venv/bin/python benchmarks/bench_pressure.py [--cells 10 20 30 40] [--repeats 2]

The DFG 2D-2 scene (``bench_dfg.scene_for``: channel, cut-cell cylinder, inflow, open outflow;
no free surface, so the matrix never changes) at each grid, run for about 60 steps from rest
with ``pressure_solver = "mic0"`` and ``"amg"``. Reported per step: the projection phase (the
system's assembly, the solve, the pressure gradient; the multigrid set-up, done once, included
and spread over the steps), its CG iterations (warm-started from the last step's increment, as
in every run), the whole step, and the solve from zero for a random field (the worst case, the
same matrix). Best of ``--repeats`` after a warm-up run compiles everything (the machine is
shared: the minimum is the least disturbed), median beside it in the JSON. Writes
``benchmarks/results/pressure.{json,md}``.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import platform
import statistics
import time
from pathlib import Path

import bench_dfg
import numpy as np

from crosscheck.sim.fluid import INTEGRATORS, run_fluid
from crosscheck.sim.fluid import pressure as P
from crosscheck.sim.fluid.amg import StaticAMG
from crosscheck.sim.fluid.solver import FluidState

ROOT = Path(__file__).resolve().parents[1]
OUT = ROOT / "benchmarks" / "results"
STEPS = 60


def scene(cells: int, solver: str):
    sc = bench_dfg.scene_for("2d2", cells, None)
    dx = sc.fluid.dx
    # about STEPS steps at CFL 0.5 with the inflow's 1.5 m/s peak
    duration = STEPS * 0.5 * dx / 1.5
    fluid = dataclasses.replace(sc.fluid, pressure_solver=solver)
    return dataclasses.replace(sc, fluid=fluid,
                               run=dataclasses.replace(sc.run, duration=duration,
                                                       sample_every=duration / 4))


def from_zero(cells: int) -> dict:
    """One solve from zero of a random field's system, each solver (best of 3)."""
    sc = scene(cells, "mic0")
    st = FluidState(sc.fluid, np.zeros(3), INTEGRATORS["central"])
    bnd = st.static_boundary
    rng = np.random.default_rng(0)
    system = P.build_system(st.phi, bnd.u_frac, bnd.v_frac, rng.standard_normal(st.u.shape),
                            rng.standard_normal(st.v.shape), bnd.u_solid, bnd.v_solid)
    ops, b = system[1:10], system[10]
    tol = 1e-6 * float(np.max(np.abs(b)))
    out = {"unknowns": int(b.shape[0])}
    amg = StaticAMG()
    t0 = time.perf_counter()
    amg.solve(*ops, b, np.zeros_like(b), tol, 200)
    out["amg_first_solve_ms"] = 1e3 * (time.perf_counter() - t0)   # with the set-up
    for name, solve in (("mic0", lambda x: P.pcg(*ops, b, x, tol, 5000)),
                        ("amg", lambda x: amg.solve(*ops, b, x, tol, 200))):
        times = []
        for _ in range(3):
            x = np.zeros_like(b)
            t0 = time.perf_counter()
            its = solve(x)
            times.append(time.perf_counter() - t0)
        out[f"{name}_ms"] = 1e3 * min(times)
        out[f"{name}_its"] = its
    return out


def in_a_run(cells: int, solver: str, repeats: int) -> dict:
    runs = []
    for _ in range(repeats):
        rec = run_fluid(scene(cells, solver), "central")
        m = rec.meta
        runs.append({"ms_per_step": m["ms_per_step"],
                     "projection_ms": m["ms_per_step_phases"]["projection"],
                     "cg_its": m["pressure_iterations"]["mean"],
                     "solver": m["pressure_iterations"]["solver"],
                     "steps": m["dt"]["steps"]})
    best = min(runs, key=lambda r: r["ms_per_step"])
    return {**best, "median_ms_per_step": statistics.median(r["ms_per_step"] for r in runs)}


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--cells", type=int, nargs="+", default=[10, 20, 30, 40])
    ap.add_argument("--repeats", type=int, default=2)
    ap.add_argument("--out", type=Path, default=OUT)
    args = ap.parse_args()
    run_fluid(scene(10, "amg"), "central")      # compile
    run_fluid(scene(10, "mic0"), "central")
    rows = []
    for cells in args.cells:
        row = {"cells": cells, "grid": list(scene(cells, "mic0").fluid.resolution),
               "from_zero": from_zero(cells)}
        for solver in ("mic0", "amg"):
            row[solver] = in_a_run(cells, solver, args.repeats)
        rows.append(row)
        print(json.dumps(row), flush=True)
    data = {"machine": f"{platform.processor() or platform.machine()}, {os.cpu_count()} cpus",
            "load_average_end": os.getloadavg(), "recorded": time.strftime("%Y-%m-%d %H:%M"),
            "rows": rows}
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "pressure.json").write_text(json.dumps(data, indent=1))
    lines = ["# Pressure solve: MIC(0)-PCG against multigrid (benchmarks/bench_pressure.py)", "",
             f"DFG 2D-2 channel, about {STEPS} steps from rest, one thread; best of "
             f"{args.repeats} runs after a warm-up. Machine {data['machine']}, shared; load "
             f"average at the end {data['load_average_end'][0]:.2f}.", "",
             "| cells/D | grid | unknowns | step ms (mic0 / amg) | projection ms (mic0 / amg) "
             "| CG its (mic0 / amg) | projection ratio | from zero ms (mic0 / amg) | "
             "from zero its (mic0 / amg) | first amg solve ms (set-up) |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        m, a, z = r["mic0"], r["amg"], r["from_zero"]
        lines.append(
            f"| {r['cells']} | {r['grid'][0]} x {r['grid'][1]} | {z['unknowns']} | "
            f"{m['ms_per_step']:.1f} / {a['ms_per_step']:.1f} | "
            f"{m['projection_ms']:.1f} / {a['projection_ms']:.1f} | "
            f"{m['cg_its']:.0f} / {a['cg_its']:.1f} | "
            f"{m['projection_ms'] / a['projection_ms']:.1f} | "
            f"{z['mic0_ms']:.1f} / {z['amg_ms']:.1f} | {z['mic0_its']} / {z['amg_its']} | "
            f"{z['amg_first_solve_ms']:.0f} |")
    lines += ["", "The projection phase includes the system's assembly and the pressure gradient "
              "(both solvers' alike) and, for multigrid, its one set-up spread over the steps. "
              "`pressure_solver = \"auto\"` (the default) takes multigrid for a matrix that does "
              "not change (no free surface, no moving body) with at least "
              "`amg.AMG_MIN_UNKNOWNS` unknowns."]
    (args.out / "pressure.md").write_text("\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
