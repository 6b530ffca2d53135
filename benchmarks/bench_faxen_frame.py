"""Faxen's channel (cases/fluid/sedimentation_channel.toml) in two frames: the Stokes drag per
unit speed of the disc held fixed in the channel, the stream and both side walls moving past it
(the fixed cut-cell solver, no body motion), and of the case's disc made 1000 times denser
(5000 times the water's density) started down the channel at Faxen's speed with no gravity
(the coupled solver; its force is its momentum change, ``body_force_y``). Galilean
invariance makes the two the same physics, and Faxen (1946) gives both:
``F / U = 4 pi mu / Lambda(k)``, k = a / h = 0.25 (10982 N s/m^2).

    PYTHONPATH=src .venv/bin/python benchmarks/bench_faxen_frame.py [--frames 4 8 16]
        [--driven 4:2.5e-4 4:1.25e-4 4:6.25e-5 8:2.5e-4 8:1.25e-4] [--held 4:5e-4 8:5e-4]

``--frames`` the fixed runs' cells per radius; ``--driven`` the driven runs'
``cells_per_radius:step``; ``--held`` the same for the third run: the fixed run's scene with
the disc a coupled body 5 10^4 times denser than the water, at rest in the stream (it drifts to
0.8 % of the stream's speed; the force is taken per unit relative speed), its force measured
twice, as the body's momentum change and by the fluid's momentum balance around it
(``forces.ForceProbe``, the fixed run's measurement): Newton's third law for the coupled step,
which it broke by 4.1 % while the viscous step weighed every face as a whole cell.

The fixed run separates the fluid solver's own convergence from the moving body's: where the
driven disc and the fixed one disagree, the difference is what moving the wall across the grid
costs (docs/fluid.md, "The settling disc in its own frame").
Writes ``benchmarks/results/faxen_frame.{json,md}``.
"""

from __future__ import annotations

import argparse
import json
import math
import platform
import time
from pathlib import Path

import numpy as np
from bench_sedimentation_frame import record_held  # a held body with the fluid's balance

from crosscheck.reference.fluid_data import faxen_channel_lambda
from crosscheck.scene.loader import load_case_text
from crosscheck.sim.fluid.run import FluidRun

ROOT = Path(__file__).resolve().parents[1]
OUT = ROOT / "benchmarks" / "results"

# the case's geometry and fluid
A = 0.1                  # m, the disc's radius
WIDTH, HEIGHT = 0.8, 2.4  # m: k = a / h = 0.25
RHO, NU = 1000.0, 0.5
SPEED = 0.112            # m/s, about Faxen's settling speed of the case's disc (Re 0.045)
FAXEN_DRAG_PER_SPEED = 4.0 * math.pi * RHO * NU / faxen_channel_lambda(2.0 * A / WIDTH)
DEFAULT_FRAMES = [4, 8, 16]
DEFAULT_DRIVEN = ["4:2.5e-4", "4:1.25e-4", "4:6.25e-5", "8:2.5e-4", "8:1.25e-4"]
DEFAULT_HELD = ["4:5e-4", "8:5e-4"]
HELD_DENSITY = 5.0e7     # kg/m^3: drifts to 0.8 % of the stream's speed over the run


def _fluid(cells_per_radius: int) -> str:
    n = round(WIDTH / A * cells_per_radius), round(HEIGHT / A * cells_per_radius)
    return f'''[fluid]
domain = [{WIDTH}, {HEIGHT}]
resolution = [{n[0]}, {n[1]}]
density = {RHO}
kinematic_viscosity = {NU}
'''


def frame_case(cells_per_radius: int, step: float = 0.002) -> str:
    """The disc fixed 0.9 m above the inflow, a uniform stream ``SPEED`` from below, both side
    walls moving up at ``SPEED``, the top open 1.5 m downstream; no gravity (the drag alone).
    Steady after about 1 s (the channel's viscous time h^2 / nu is 0.32 s)."""
    return f'''[case]
name = "faxen-frame-{cells_per_radius}"
description = "Faxen's channel in the disc's frame: the disc held fixed, stream and walls moving."
tags = ["fluid", "viscous"]
dimension = 2

[run]
duration = 1.2
dt = {step}
sample_every = {step}
engines = ["inhouse"]
integrators = {{ inhouse = ["central"] }}

{_fluid(cells_per_radius)}cfl = 0.5
walls = {{ bottom = "inflow", top = "open", left = "solid", right = "solid" }}
inflow = {{ profile = "uniform", speed = {SPEED} }}
lid = [{{ side = "left", speed = {SPEED} }}, {{ side = "right", speed = {SPEED} }}]
obstacles = [{{ name = "disc", circle = {{ center = [{WIDTH / 2}, 0.9], radius = {A} }} }}]
output = {{ forces = true }}
'''


def driven_case(cells_per_radius: int, step: float) -> str:
    """The case's disc 1000 times denser, started at ``SPEED``, no gravity; the case's
    integrator. It slows by 3.1 % over the run (1.7 % over the window 0.2-0.45 s), so the drag
    is taken per unit speed sample by sample (Stokes drag is linear in the speed)."""
    return f'''[case]
name = "faxen-driven-{cells_per_radius}"
description = "A disc driven down Faxen's channel at a constant speed."
tags = ["fluid", "coupling", "viscous"]
dimension = 2

[run]
duration = 0.45
dt = {step}
sample_every = {8 * step}
engines = ["inhouse"]
integrators = {{ inhouse = ["semi_lagrangian"] }}

[[bodies]]
name = "disc"
shape = {{ circle = {{ radius = {A} }} }}
density = 5.0e6
position = [{WIDTH / 2}, 1.5]
velocity = [0.0, {-SPEED}]

{_fluid(cells_per_radius)}'''


def frame_run(cells_per_radius: int) -> dict:
    scene = load_case_text(frame_case(cells_per_radius), "faxen_frame.toml")
    t0 = time.perf_counter()
    rec = FluidRun(scene, "central").record()
    wall = time.perf_counter() - t0
    t = np.asarray(rec.t)
    fy = np.asarray(rec.series["force_y.disc"])
    last = t > t[-1] - 0.2
    drag = float(np.mean(fy[last]))
    return {"cells_per_radius": cells_per_radius, "drag_per_speed": drag / SPEED,
            "faxen_error": drag / SPEED / FAXEN_DRAG_PER_SPEED - 1.0,
            "unsteadiness": float(np.ptp(fy[last]) / abs(drag)), "failure": rec.failure,
            "wall_s": wall}


def driven_run(cells_per_radius: int, step: float) -> dict:
    """The mean of force / speed over 0.2-0.45 s (the force varies by a few % as the disc
    crosses cell rows: 2.1-2.3 % standard deviation at a / 4, 1.3-1.5 % at a / 8)."""
    scene = load_case_text(driven_case(cells_per_radius, step), "faxen_driven.toml")
    t0 = time.perf_counter()
    rec = FluidRun(scene, "semi_lagrangian").record()
    wall = time.perf_counter() - t0
    t = np.asarray(rec.t)
    w = t >= 0.2
    u = -np.asarray(rec.series["body_vy.disc"])[w]
    f = np.asarray(rec.series["body_force_y.disc"])[w]
    per_speed = f / u
    return {"cells_per_radius": cells_per_radius, "step": step,
            "drag_per_speed": float(np.mean(per_speed)),
            "faxen_error": float(np.mean(per_speed)) / FAXEN_DRAG_PER_SPEED - 1.0,
            "spread": float(np.std(per_speed) / np.mean(per_speed)), "failure": rec.failure,
            "wall_s": wall}


def held_case(cells_per_radius: int, step: float) -> str:
    """``frame_case`` with the disc a coupled body at rest (``HELD_DENSITY``), the coupled
    solver's integrator, a fixed step; 1.2 s (steady after about 1 s)."""
    text = frame_case(cells_per_radius, step)
    obstacle = (f'obstacles = [{{ name = "disc", circle = {{ center = [{WIDTH / 2}, 0.9], '
                f'radius = {A} }} }}]\n')
    assert obstacle in text
    text = (text.replace(obstacle, "").replace("output = { forces = true }\n", "")
            .replace('["central"]', '["semi_lagrangian"]').replace("cfl = 0.5\n", "")
            .replace('name = "faxen-frame-', 'name = "faxen-held-'))
    return text + f'''
[[bodies]]
name = "disc"
shape = {{ circle = {{ radius = {A} }} }}
density = {HELD_DENSITY}
position = [{WIDTH / 2}, 0.9]
'''


def held_run(cells_per_radius: int, step: float) -> dict:
    """The held disc's force per unit speed of the stream relative to it, over the last 0.2 s:
    its momentum change (``body_force_y``) and the fluid's momentum balance around it (a
    ``ForceProbe`` on the disc's initial place, as the fixed run measures; the disc drifts to
    0.8 % of the stream's speed and moves by about 0.02 of a cell at 4 cells per radius)."""
    scene = load_case_text(held_case(cells_per_radius, step), "faxen_held.toml")
    fixed = load_case_text(frame_case(cells_per_radius, step), "faxen_frame.toml").fluid
    rec, balance, wall = record_held(FluidRun(scene, "semi_lagrangian"), fixed)
    t = np.asarray(rec.t)
    last = t > t[-1] - 0.2
    relative = SPEED - np.asarray(rec.series["body_vy.disc"])
    body = float(np.mean(np.asarray(rec.series["body_force_y.disc"])[last] / relative[last]))
    tb = np.array([b[0] for b in balance])
    fb = np.array([b[1]["disc"][1] for b in balance])
    # the fluid's balance per unit relative speed at the same instants
    rel_b = np.interp(tb, t, relative)
    lb = tb > t[-1] - 0.2
    fluid = float(np.mean(fb[lb] / rel_b[lb]))
    return {"cells_per_radius": cells_per_radius, "step": step,
            "body_drag_per_speed": body, "fluid_drag_per_speed": fluid,
            "body_faxen_error": body / FAXEN_DRAG_PER_SPEED - 1.0,
            "fluid_faxen_error": fluid / FAXEN_DRAG_PER_SPEED - 1.0,
            "third_law_gap": body / fluid - 1.0,
            "drift": float(np.max(np.abs(np.asarray(rec.series["body_vy.disc"]))) / SPEED),
            "failure": rec.failure, "wall_s": wall}


def markdown(result: dict) -> str:
    lines = [
        "# Faxen's channel in two frames", "",
        f"Drag per unit speed of the disc of `sedimentation_channel` (a = {A} m, k = 0.25, "
        f"Re {2 * A * SPEED / NU:.3f}) against Faxen's {FAXEN_DRAG_PER_SPEED:.0f} N s/m^2. "
        f"{result['machine']}; `benchmarks/bench_faxen_frame.py`.", "",
        "## Fixed disc, stream and walls moving past it (`central`, dt 2 ms, steady)", "",
        "| cells per radius | F / U (N s/m^2) | against Faxen | unsteadiness | wall s |",
        "|---:|---:|---:|---:|---:|"]
    for r in result["frames"]:
        lines.append(f"| {r['cells_per_radius']} | {r['drag_per_speed']:.1f} | "
                     f"{100 * r['faxen_error']:+.2f} % | {r['unsteadiness']:.1e} | "
                     f"{r['wall_s']:.0f} |")
    lines += ["", "## Disc driven down the channel (`semi_lagrangian`, the coupled solver)", "",
              "| cells per radius | step (s) | F / U (N s/m^2) | against Faxen | "
              "spread (std) | wall s |", "|---:|---:|---:|---:|---:|---:|"]
    for r in result["driven"]:
        lines.append(f"| {r['cells_per_radius']} | {r['step']:g} | {r['drag_per_speed']:.1f} | "
                     f"{100 * r['faxen_error']:+.2f} % | {100 * r['spread']:.2f} % | "
                     f"{r['wall_s']:.0f} |")
    lines += ["", "## Disc held at rest in the stream as a coupled body (`semi_lagrangian`)", "",
              "Its force as its momentum change (the body) and as the fluid's momentum "
              "balance around it (the fluid): Newton's third law for the coupled step.", "",
              "| cells per radius | step (s) | body F / U | against Faxen | fluid F / U | "
              "against Faxen | body / fluid - 1 | wall s |",
              "|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for r in result.get("held", []):
        lines.append(f"| {r['cells_per_radius']} | {r['step']:g} | "
                     f"{r['body_drag_per_speed']:.1f} | {100 * r['body_faxen_error']:+.2f} % | "
                     f"{r['fluid_drag_per_speed']:.1f} | {100 * r['fluid_faxen_error']:+.2f} % | "
                     f"{100 * r['third_law_gap']:+.2f} % | {r['wall_s']:.0f} |")
    return "\n".join(lines) + "\n"


def _grid_steps(flag: str, specs: list[str]) -> list[tuple[int, float]]:
    out = []
    for spec in specs:
        try:
            cells, step = spec.split(":")
            out.append((int(cells), float(step)))
        except ValueError:
            raise SystemExit(f"{flag}: expected cells_per_radius:step, got {spec!r}") from None
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--frames", nargs="*", type=int, default=DEFAULT_FRAMES)
    ap.add_argument("--driven", nargs="*", default=DEFAULT_DRIVEN,
                    help="cells_per_radius:step of the driven runs")
    ap.add_argument("--held", nargs="*", default=DEFAULT_HELD,
                    help="cells_per_radius:step of the held runs")
    args = ap.parse_args()
    driven = _grid_steps("--driven", args.driven)
    held = _grid_steps("--held", args.held)
    result = {"machine": f"{platform.machine()}, {platform.python_version()}",
              "faxen_drag_per_speed": FAXEN_DRAG_PER_SPEED, "frames": [], "driven": [],
              "held": []}
    OUT.mkdir(parents=True, exist_ok=True)

    def write() -> None:
        (OUT / "faxen_frame.json").write_text(json.dumps(result, indent=1) + "\n")
        (OUT / "faxen_frame.md").write_text(markdown(result))

    jobs = [("frames", frame_run, [(cells,) for cells in args.frames]),
            ("driven", driven_run, driven), ("held", held_run, held)]
    for key, run, specs in jobs:
        for spec in specs:
            result[key].append(run(*spec))
            print(json.dumps(result[key][-1]), flush=True)
            write()


if __name__ == "__main__":
    main()
