"""The settling disc of ``cases/fluid/settling_disc.toml`` beside MuJoCo's stateless medium
(issue 14, point 4): the in-house coupled run's terminal velocity, drag coefficient and start-up
acceleration at several grids, in the case's box and in a narrower one (the wall effect), beside
the closed forms of MuJoCo's two fluid models for the mapped cylinder and MuJoCo's own runs.

    PYTHONPATH=src .venv/bin/python benchmarks/bench_settling.py [--grids 96 160 256]
        [--widths 2.0 1.0] [--duration 2.0]

Each run is the case with ``fluid.resolution`` (and ``fluid.domain`` width for the wall
variants, keeping dx) overridden; the metrics are the case's own (``disc_settling`` in
compare/fluid_metrics.py, the MuJoCo cells through compare/evaluate.py). The start-up
acceleration is also measured from a separate short run sampled every step (the first three
steps of 1 ms: the acceleration at release, before the viscous history force grows).
Writes ``benchmarks/results/settling_disc.{json,md}``.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import platform
import time
from pathlib import Path

from crosscheck.compare.evaluate import evaluate
from crosscheck.compare.fluid_metrics import fluid_metrics
from crosscheck.engines import get_engine
from crosscheck.engines.driver import run
from crosscheck.reference.medium_analytic import startup_acceleration
from crosscheck.scene.loader import load_case
from crosscheck.sim.fluid.run import FluidRun

ROOT = Path(__file__).resolve().parents[1]
CASE = ROOT / "cases" / "fluid" / "settling_disc.toml"
OUT = ROOT / "benchmarks" / "results"

KEYS = ("terminal_velocity", "terminal_reynolds", "drag_coefficient",
        "drag_coefficient_published_low", "drag_coefficient_published_high",
        "drag_coefficient_error", "terminal_force_balance_error", "startup_acceleration",
        "added_mass_coefficient", "terminal_velocity_vs_mujoco_ellipsoid",
        "terminal_velocity_vs_mujoco_inertia_box", "centreline_offset", "blockage")


def variant(scene, nx: int, width: float, duration: float | None = None, dt: float | None = None,
            sample_every: float | None = None):
    """The case at nx cells across a domain ``width`` wide (the height and the disc's height
    kept; dx = width / nx), the disc on the axis."""
    spec = scene.fluid
    dx = width / nx
    ny = int(round(spec.domain[1] / dx))
    body = dataclasses.replace(spec.bodies[0], position=(width / 2.0, spec.bodies[0].position[1]))
    fluid = dataclasses.replace(spec, domain=(width, ny * dx), resolution=(nx, ny), bodies=(body,))
    run_ = scene.run
    run_ = dataclasses.replace(run_, duration=duration or run_.duration, dt=dt or run_.dt,
                               sample_every=sample_every or run_.sample_every)
    return dataclasses.replace(scene, fluid=fluid, bodies=(body,), run=run_)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--grids", type=int, nargs="+", default=[96, 160, 256])
    ap.add_argument("--widths", type=float, nargs="+", default=[2.0, 1.0])
    ap.add_argument("--duration", type=float, default=None)
    ap.add_argument("--dt", type=float, default=None,
                    help="the fluid's largest step instead of the case's (the time step's share)")
    ap.add_argument("--tag", default="",
                    help="write settling_disc<tag>.{json,md} (a study beside the main one)")
    ap.add_argument("--markdown-only", action="store_true",
                    help="rewrite the .md from the committed .json without running")
    args = ap.parse_args()
    stem = f"settling_disc{args.tag}"
    if args.markdown_only:
        result = json.loads((OUT / f"{stem}.json").read_text())
        (OUT / f"{stem}.md").write_text(markdown(result))
        return
    base = load_case(CASE)
    rows = []
    for width in args.widths:
        for nx0 in args.grids:
            nx = int(round(nx0 * width / base.fluid.domain[0]))
            sc = variant(base, nx, width, duration=args.duration, dt=args.dt)
            t0 = time.perf_counter()
            rec = FluidRun(sc, "semi_lagrangian").record()
            wall = time.perf_counter() - t0
            m = fluid_metrics(sc, rec)
            # the acceleration at release, from a short run sampled at every 1 ms step
            short = variant(base, nx, width, duration=0.01, dt=0.001, sample_every=0.001)
            srec = FluidRun(short, "semi_lagrangian").record()
            body = short.fluid.bodies[0].name
            a_step = -startup_acceleration(srec.t, srec.series[f"body_vy.{body}"])
            row = {"width": width, "nx": nx, "ny": sc.fluid.resolution[1], "dt": sc.run.dt,
                   "cells_per_radius": sc.fluid.bodies[0].shape.radius / sc.fluid.dx,
                   "wall_s": wall, "steps": (rec.meta.get("dt") or {}).get("steps"),
                   "failure": rec.failure, "startup_acceleration_1ms": a_step,
                   **{k: m.get(k) for k in KEYS}}
            rows.append(row)
            print(json.dumps(row), flush=True)
    mujoco = []
    engine = get_engine("mujoco")
    for name in ("rk4+ellipsoid", "rk4+inertia_box"):
        ran = run(engine, base, name, base.run.dt, cost=None)
        ev = evaluate(base, ran.output, None, "mujoco", name)
        mujoco.append({"run": name, **{k: v.get("value") for k, v in ev.metrics.items()}})
        print(json.dumps(mujoco[-1]), flush=True)
    result = {"case": str(CASE.relative_to(ROOT)), "machine": platform.machine(),
              "python": platform.python_version(), "inhouse": rows, "mujoco": mujoco}
    OUT.mkdir(parents=True, exist_ok=True)
    (OUT / f"{stem}.json").write_text(json.dumps(result, indent=2))
    (OUT / f"{stem}.md").write_text(markdown(result))


def _f(x, fmt="{:.4g}"):
    return "-" if x is None else fmt.format(x)


def markdown(result: dict) -> str:
    lines = ["# Settling disc: in-house coupled run beside MuJoCo's stateless medium", "",
             f"`{result['case']}`, written by `benchmarks/bench_settling.py`.", "",
             "| width (m) | grid (largest step) | R/dx | U (m/s) | Re | C_D | published C_D "
             "| U / U_mj,ellipsoid - 1 | U / U_mj,box - 1 | a0 (samples) | a0 (1 ms steps) "
             "| C_a | drift (m) | wall (s) |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in result["inhouse"]:
        band = ("-" if r["drag_coefficient_published_low"] is None else
                f"{r['drag_coefficient_published_low']:.3f}-"
                f"{r['drag_coefficient_published_high']:.3f}")
        lines.append(
            f"| {r['width']:g} | {r['nx']}x{r['ny']} ({r.get('dt', 0.005):g} s) | "
            f"{r['cells_per_radius']:.2f} | "
            f"{_f(r['terminal_velocity'])} | {_f(r['terminal_reynolds'], '{:.1f}')} | "
            f"{_f(r['drag_coefficient'])} | {band} | "
            f"{_f(r['terminal_velocity_vs_mujoco_ellipsoid'], '{:+.3f}')} | "
            f"{_f(r['terminal_velocity_vs_mujoco_inertia_box'], '{:+.3f}')} | "
            f"{_f(r['startup_acceleration'])} | {_f(r['startup_acceleration_1ms'])} | "
            f"{_f(r['added_mass_coefficient'], '{:.3f}')} | {_f(r['centreline_offset'], '{:.2g}')} "
            f"| {r['wall_s']:.0f} |")
    lines += _walls_removed(result["inhouse"])
    lines += ["", "MuJoCo (the mapped cylinder, L = 1000 R, rk4 at the case's step):", "",
              "| run | u_t closed form (m/s) | error at T | velocity error max (m/s) | C_D | Re | "
              "a0 | a0 error |", "|---|---|---|---|---|---|---|---|"]
    for m in result["mujoco"]:
        lines.append(f"| {m['run']} | {_f(m.get('terminal_velocity'), '{:.5f}')} | "
                     f"{_f(m.get('terminal_velocity_error_rel'), '{:.2g}')} | "
                     f"{_f(m.get('velocity_error_max'), '{:.2g}')} | "
                     f"{_f(m.get('drag_coefficient'))} | {_f(m.get('terminal_reynolds'), '{:.1f}')}"
                     f" | {_f(m.get('startup_acceleration'))} | "
                     f"{_f(m.get('startup_acceleration_error'), '{:.2g}')} |")
    return "\n".join(lines) + "\n"


def _walls_removed(rows: list[dict]) -> list[str]:
    """The two boxes at each grid, extrapolated linearly in the blockage B = 2 R / W to B = 0:
    C_D(0) = (B2 C_D(B1) - B1 C_D(B2)) / (B2 - B1) (the drag of a cylinder grows with the
    blockage, about linearly at small B: an estimate of the walls' share, not a result)."""
    from crosscheck.reference.fluid_data import cylinder_drag_band

    by = {}
    for r in rows:
        by.setdefault(round(r["cells_per_radius"], 3), []).append(r)
    out = ["", "Walls removed (two boxes at each grid, linear in the blockage B to B = 0; an "
           "estimate):", "", "| R/dx | B | C_D at B = 0 | U at B = 0 (m/s) | Re | published C_D |",
           "|---|---|---|---|---|---|"]
    for cpr, pair in sorted(by.items()):
        pair = [p for p in pair if p["drag_coefficient"] is not None]
        if len(pair) != 2:
            continue
        (a, b) = sorted(pair, key=lambda p: p["blockage"])
        b1, b2 = a["blockage"], b["blockage"]
        cd0 = (b2 * a["drag_coefficient"] - b1 * b["drag_coefficient"]) / (b2 - b1)
        u0 = (b2 * a["terminal_velocity"] - b1 * b["terminal_velocity"]) / (b2 - b1)
        re0 = a["terminal_reynolds"] * u0 / a["terminal_velocity"]
        band = cylinder_drag_band(re0)
        text = "-" if band is None else f"{band[0]:.3f}-{band[1]:.3f}"
        out.append(f"| {cpr:.2f} | {b1:g}, {b2:g} | {cd0:.3f} | {u0:.4f} | {re0:.1f} | {text} |")
    return out


if __name__ == "__main__":
    main()
