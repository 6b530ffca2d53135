"""Wachs's settling disc in its own frame: the fixed cut-cell solver's drag at the published
terminal speed, the symmetric wake against the shedding one (issue 14, point 3; why the grid
study of ``sedimentation_wachs`` released on the axis does not converge).

    PYTHONPATH=src nice .venv/bin/python benchmarks/bench_wachs_frame.py
        [--runs 12 16 12:off0.02 16:off0.02] [--duration 60]

Galilean invariance: a disc settling at U through a channel at rest is, in its own frame, a fixed
disc in a uniform stream U whose side walls move with the stream. The scene is the benchmark's
(d = 1, channel 4 d wide, nu = 0.008088, rho = 1000), the stream at the published terminal speed
U = 259.5 nu / d = 2.0988 entering 8 d below the disc, the outflow 16 d above it, no gravity; the
fixed-obstacle solver (`central`, CFL 0.5), which the DFG benchmark validates. Its drag
coefficient ``C_D = 2 F / (rho U^2 d)`` set against the published 1.785 says which state of the
wake the published number belongs to. ``<cells>`` runs the disc on the channel's axis (the
symmetric wake, unstable at this Reynolds number, holds until round-off grows);
``<cells>:off<x>`` moves it ``x`` d off the axis, a perturbation that starts the shedding at
once. Reported per 5 s window: the mean, least and largest C_D and the largest side-force
coefficient.

Writes ``benchmarks/results/wachs_frame.{json,md}`` (each run appended as it finishes).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import time
from pathlib import Path

import numpy as np

from crosscheck.scene.loader import load_case_text
from crosscheck.sim.fluid.run import FluidRun

OUT = Path(__file__).resolve().parents[1] / "benchmarks" / "results"
NU, RHO, D, WIDTH, HEIGHT = 0.008088, 1000.0, 1.0, 4.0, 24.0
U = 259.5 * NU / D           # the published terminal speed (Wachs 2009, Re 259.5)
CD_PUBLISHED = 1.785
WINDOW = 5.0                 # s, the reporting windows


R = D / 2


def frame_case(cells: int, offset: float, duration: float) -> str:
    """The disc fixed 8 d above the inflow (``offset`` d off the axis), a uniform stream U from
    below, both side walls moving up at U, the top open; no gravity (the drag alone)."""
    dx = D / cells
    return f'''[case]
name = "wachs-frame-{cells}-{offset:g}"
description = "Wachs's disc held in a stream at its published terminal speed, the walls moving."
dimension = 2
[run]
duration = {duration}
dt = 0.05
sample_every = 0.05
engines = ["inhouse"]
integrators = {{ inhouse = ["central"] }}
[fluid]
domain = [{WIDTH}, {HEIGHT}]
resolution = [{round(WIDTH / dx)}, {round(HEIGHT / dx)}]
density = {RHO}
kinematic_viscosity = {NU}
cfl = 0.5
walls = {{ bottom = "inflow", top = "open", left = "solid", right = "solid" }}
inflow = {{ profile = "uniform", speed = {U} }}
lid = [{{ side = "left", speed = {U} }}, {{ side = "right", speed = {U} }}]
obstacles = [{{ name = "disc", circle = {{ center = [{WIDTH / 2 + offset}, 8.0], radius = {R} }} }}]
output = {{ forces = true }}
'''


def run(spec: str, duration: float) -> dict:
    cells_text, _, variant = spec.partition(":")
    try:
        cells = int(cells_text)
        offset = float(variant[3:]) if variant else 0.0
        if variant and not variant.startswith("off"):
            raise ValueError(variant)
    except ValueError:
        raise SystemExit(f"--runs {spec!r}: expected <cells> or <cells>:off<distance in d>, "
                         "as 16 or 16:off0.02") from None
    scene = load_case_text(frame_case(cells, offset, duration), "wachs_frame.toml")
    t0 = time.perf_counter()
    rec = FluidRun(scene, "central").record()
    wall = time.perf_counter() - t0
    t = np.asarray(rec.t)
    scale = 2.0 / (RHO * U * U * D)
    cd = scale * np.asarray(rec.series["force_y.disc"])
    side = scale * np.asarray(rec.series["force_x.disc"])
    windows = []
    for a in np.arange(0.0, duration - 1e-9, WINDOW):
        m = (t > a) & (t <= a + WINDOW)
        if np.any(m):
            windows.append({"from": float(a), "to": float(a + WINDOW),
                            "cd_mean": float(cd[m].mean()), "cd_min": float(cd[m].min()),
                            "cd_max": float(cd[m].max()),
                            "side_max": float(np.abs(side[m]).max())})
    return {"run": spec, "cells_per_diameter": cells, "offset": offset, "duration": duration,
            "failure": rec.failure, "wall_s": wall, "windows": windows,
            "load": os.getloadavg()[0], "machine": platform.machine(),
            "recorded": time.strftime("%Y-%m-%d %H:%M:%S")}


def markdown(runs: list[dict]) -> str:
    lines = ["# Wachs's disc in its own frame: the symmetric wake and the shedding one", "",
             "Written by `benchmarks/bench_wachs_frame.py`. The fixed cut-cell solver "
             "(`central`, CFL 0.5): a disc (d = 1) held in a uniform stream at the published "
             f"terminal speed U = {U:.4f} (Re 259.5) in a channel 4 d wide whose walls move with "
             "the stream, nu = 0.008088. C_D = 2 F / (rho U^2 d) per 5 s window; the "
             f"published C_D is {CD_PUBLISHED} (a freely moving disc). Side: the largest "
             "side-force coefficient in the window (0: the symmetric wake; about 1: shedding).",
             "",
             "| run | d/dx | off the axis (d) | window (s) | C_D mean | C_D min-max | side max | "
             "wall (s) |", "|---|---|---|---|---|---|---|---|"]
    for r in runs:
        for w in r["windows"]:
            lines.append(f"| {r['run']} | {r['cells_per_diameter']} | {r['offset']:g} | "
                         f"{w['from']:g}-{w['to']:g} | {w['cd_mean']:.4f} | "
                         f"{w['cd_min']:.4f}-{w['cd_max']:.4f} | {w['side_max']:.4f} | "
                         f"{r['wall_s']:.0f} |")
    return "\n".join(lines) + "\n"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--runs", nargs="+", default=["12", "16", "12:off0.02", "16:off0.02"])
    ap.add_argument("--duration", type=float, default=60.0)
    ap.add_argument("--markdown-only", action="store_true")
    ap.add_argument("--stem", default="wachs_frame",
                    help="the results files' name (two studies run side by side write apart)")
    args = ap.parse_args()
    path = OUT / f"{args.stem}.json"
    data = json.loads(path.read_text()) if path.exists() else {"runs": []}
    if not args.markdown_only:
        for spec in args.runs:
            data["runs"].append(run(spec, args.duration))
            path.write_text(json.dumps(data, indent=1) + "\n")
            print(json.dumps({k: v for k, v in data["runs"][-1].items() if k != "windows"}),
                  flush=True)
    (OUT / f"{args.stem}.md").write_text(markdown(data["runs"]))


if __name__ == "__main__":
    main()
