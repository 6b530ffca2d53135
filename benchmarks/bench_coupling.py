"""Cost of the coupled step (issue 14, point 6): a floating box against the same tank with the
box as a fixed obstacle and with no box, at 128^2 and 256^2, in a sloshing tank.

    PYTHONPATH=src .venv/bin/python benchmarks/bench_coupling.py [--repeats 3] [--sizes 128 256]
        [--scene floating|submerged]

The scene is ``cases/fluid/floating_box.toml``'s box (0.2 x 0.1 m, density 500, released 0.01 m
above its draft) in a square tank 1 m wide, water 0.5 m deep with its first sloshing mode
(amplitude 0.02 m) so that every variant's fluid moves (a tank at rest converges its pressure in
one CG iteration, which would compare a moving fluid's solve with none), run for 1 s, the
resolution overridden. Three variants at each grid, the same steps where the CFL allows:

* ``coupled``: the box is a ``[[bodies]]`` entry (two-way coupling);
* ``obstacle``: the box at its release pose as a fixed obstacle (cut cells, no coupling): the
  uncoupled step at the same resolution with the same solid in the water;
* ``none``: the tank alone.

``--scene submerged`` (``coupling_submerged.{json,md}``): a disc (R = 0.05 m, density 1100)
released 0.25 m below the lid of the same tank closed and full of fluid, the lid sliding at
0.2 m/s so that every variant's fluid moves; viscous only. There the body's neighbourhood has
no free surface, so the coupled step runs the convective exchange as well as the viscous one
(the floating box's does not: docs/fluid.md, "The convective exchange after a trace").

Each at two fluids: inviscid, and viscous (``kinematic_viscosity`` ``--viscosity``, 1e-4 m^2/s
by default, the implicit viscous step in all three variants). A viscous coupled step does more
than an inviscid one: the body is a moving no-slip wall of the viscous solve, the momentum that
solve puts through it is taken from the body, and the projection is incremental (the previous
pressure applied to fluid and body on the new geometry, the cells the body uncovers filled),
so its cost is measured, not inferred from the inviscid figure.

Wall time per step is the stepping time the fluid run measures (recording excluded), split into
its phases (``coupling``: the body's move and its cut cells, in coupled runs only); best of
``--repeats`` runs after a warm-up (the machine is shared: the minimum is the least disturbed),
median beside it. Writes ``benchmarks/results/coupling.{json,md}``.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
from pathlib import Path

from crosscheck.scene.loader import load_case_text
from crosscheck.sim.fluid import run_fluid

ROOT = Path(__file__).resolve().parents[1]
OUT = ROOT / "benchmarks" / "results"

# the floating box in a sloshing tank (a free surface through the body's neighbourhood: the
# convective exchange does not run there), and a disc settling in a closed tank full of fluid
# (no free surface: the viscous and the convective exchange both run, docs/fluid.md)
SCENES = {
    "floating": {
        "body": """
[[bodies]]
name = "box"
shape = { box = { size = [0.2, 0.1] } }
density = 500.0
position = [0.5, 0.51]
""",
        "obstacle": 'obstacles = [{ box = { center = [0.5, 0.51], size = [0.2, 0.1] } }]',
        "fluid": """walls = { top = "open" }
initial = [{ layer = { depth = 0.5, amplitude = 0.02, wavelength = 2.0 } }]""",
        "stem": "coupling",
    },
    "submerged": {
        "body": """
[[bodies]]
name = "disc"
shape = { circle = { radius = 0.05 } }
density = 1100.0
position = [0.5, 0.75]
""",
        "obstacle": 'obstacles = [{ circle = { center = [0.5, 0.75], radius = 0.05 } }]',
        "fluid": 'lid = [{ side = "top", speed = 0.2 }]',
        "stem": "coupling_submerged",
    },
}


def scene(variant: str, n: int, nu: float = 0.0, kind: str = "floating"):
    sc = SCENES[kind]
    text = f"""
[case]
name = "bench-coupling-{kind}-{variant}{'-viscous' if nu > 0 else ''}"
dimension = 2
[run]
duration = 1.0
dt = 0.005
sample_every = 0.05
[effects]
gravity = [0.0, -9.81]
{sc["body"] if variant == "coupled" else ""}
[fluid]
domain = [1.0, 1.0]
resolution = [{n}, {n}]
{sc["fluid"]}
{f'kinematic_viscosity = {nu}' if nu > 0 else ''}
{'viscosity_solver = "implicit"' if nu > 0 else ''}
{sc["obstacle"] if variant == "obstacle" else ""}
"""
    return load_case_text(text, f"bench-{variant}.toml")


def run_once(variant: str, n: int, nu: float = 0.0, kind: str = "floating") -> dict:
    rec = run_fluid(scene(variant, n, nu, kind), "semi_lagrangian")
    m = rec.meta
    return {"ms_per_step": m["ms_per_step"], "phases": m["ms_per_step_phases"],
            "steps": m["dt"]["steps"],
            "pressure_iterations_mean": m["pressure_iterations"]["mean"],
            "failure": rec.failure}


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--sizes", type=int, nargs="+", default=[128, 256])
    ap.add_argument("--viscosity", type=float, default=1e-4,
                    help="the viscous set's kinematic viscosity, m^2/s (0: inviscid only)")
    ap.add_argument("--scene", choices=sorted(SCENES), default="floating",
                    help="floating: the box in a sloshing tank (coupling.{json,md}); submerged: "
                    "a disc settling in a closed tank full of fluid, viscous only "
                    "(coupling_submerged.{json,md})")
    ap.add_argument("--out", type=Path, default=OUT)
    args = ap.parse_args()
    kind = args.scene
    fluids = [0.0] + ([args.viscosity] if args.viscosity > 0 else [])
    if kind == "submerged":
        if args.viscosity <= 0:
            raise SystemExit("--scene submerged: the exchanges it measures need a viscous "
                             "fluid (--viscosity > 0)")
        fluids = [args.viscosity]
    for nu in fluids:
        for v in ("coupled", "obstacle", "none"):      # warm-up: load or compile the kernels
            run_once(v, 32, nu, kind)
    results = []
    for nu, n in ((nu, n) for nu in fluids for n in args.sizes):
        row = {"n": n, "nu": nu}
        for v in ("coupled", "obstacle", "none"):
            runs = [run_once(v, n, nu, kind) for _ in range(args.repeats)]
            best = min(runs, key=lambda r: r["ms_per_step"])
            best["median_ms_per_step"] = statistics.median(r["ms_per_step"] for r in runs)
            row[v] = best
            print(n, nu, v, f"{best['ms_per_step']:.3f} ms/step (median "
                  f"{best['median_ms_per_step']:.3f}), steps {best['steps']}, CG "
                  f"{best['pressure_iterations_mean']:.1f}",
                  {k: round(x, 3) for k, x in best["phases"].items()}, flush=True)
        row["ratio_to_obstacle"] = row["coupled"]["ms_per_step"] / row["obstacle"]["ms_per_step"]
        row["ratio_to_none"] = row["coupled"]["ms_per_step"] / row["none"]["ms_per_step"]
        results.append(row)
    doc = {"machine": {"platform": platform.platform(), "cpus": os.cpu_count(),
                       "load_average": os.getloadavg()},
           "repeats": args.repeats, "scene": kind, "results": results}
    stem = SCENES[kind]["stem"]
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / f"{stem}.json").write_text(json.dumps(doc, indent=1, default=str))
    (args.out / f"{stem}.md").write_text(markdown(doc))
    print(markdown(doc))


def markdown(doc: dict) -> str:
    phases = ("advection", "redistancing", "forces", "projection", "extension", "coupling")
    kind = doc.get("scene", "floating")
    what = {"floating": "the floating box in a sloshing tank",
            "submerged": "a disc (R = 0.05, density 1100) settling in a closed tank full of "
                         "fluid whose lid slides at 0.2 m/s, released 0.25 m below the lid: the "
                         "viscous and the convective exchange both run"}[kind]
    lines = [f"# Coupled step cost (benchmarks/bench_coupling.py --scene {kind})", "",
             f"The scene: {what}. "
             f"Load average at the end: {doc['machine']['load_average']}; best of "
             f"{doc['repeats']} runs (median in coupling.json), one thread.", "",
             "| grid | fluid | variant | ms/step | " + " | ".join(phases) + " | CG its | steps |",
             "|---|---|---|---|" + "---|" * len(phases) + "---|---|"]
    for row in doc["results"]:
        for v in ("coupled", "obstacle", "none"):
            r = row[v]
            ph = " | ".join(f"{r['phases'].get(p, 0.0):.3f}" for p in phases)
            lines.append(f"| {row['n']}^2 | {_fluid(row)} | {v} | {r['ms_per_step']:.3f} | {ph} | "
                         f"{r['pressure_iterations_mean']:.1f} | {r['steps']} |")
    lines.append("")
    for row in doc["results"]:
        lines.append(f"* {row['n']}^2, {_fluid(row)}: coupled / obstacle = "
                     f"{row['ratio_to_obstacle']:.2f}, coupled / no body = "
                     f"{row['ratio_to_none']:.2f}")
    return "\n".join(lines) + "\n"


def _fluid(row: dict) -> str:
    nu = row.get("nu", 0.0)
    return f"nu = {nu:g}" if nu > 0 else "inviscid"


if __name__ == "__main__":
    main()
