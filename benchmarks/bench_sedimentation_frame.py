"""A disc settling in a channel, run twice: coupled (the disc falls through fluid at rest) and in
the disc's frame (the disc fixed, the fluid and the channel's walls moving past it at the disc's
speed). Issue 14, point 3: the two-way coupled solver against the fixed-obstacle solver, which
the DFG benchmark validates (docs/fluid.md), on the same physics.

    PYTHONPATH=src nice .venv/bin/python benchmarks/bench_sedimentation_frame.py
        [--frame-cells 4 8 16] [--advected-cfl 0.1] [--advected-cells 4 8]
        [--speeds 0.052 0.058 0.0692] [--coupled tall:4:0.001 ...]
        [--driven 4:0.002 ...] [--reuse] [--add [--held 4:0.002:central ...]]

The scene has the parameters of Glowinski, Pan, Hesla and Joseph's single settling disc (a
closed channel 2 cm wide, d = 0.25 cm, rho_s / rho = 1.25, nu = 0.1 cm^2/s, g = 981 cm/s^2,
here in SI). Galilean invariance: a disc falling at its terminal speed U through an endless
channel at rest is, in its own frame, a fixed disc in a uniform stream U with both walls moving
at U. So the drag the fixed solver measures at U (``force_y`` of the obstacle, gravity off)
equals the disc's reduced weight exactly at the coupled solver's terminal speed. The frame runs
give the drag at a few speeds (a steady flow, the mean over the last 0.3 s); the terminal speed
is where the drag, interpolated as a power of U between the two speeds that bracket it, equals
the weight: with ``central`` at every grid, and with ``maccormack`` (the coupled runs' default
advection, ``--advected-cfl``) at the coarser ones. A coupled or driven run names its advection
(``tall:4:0.001:central``); each is set against the frame with the same scheme where there is
one. The coupled runs release the disc from rest on the axis
of a channel 12 cm tall (y = 10 cm) and take its mean speed from 0.5 to 1 s while it is more than
8 d above the bottom (the speed wanders by about 1 % as cell rows open, so its largest value is
one of those swings) and its largest speed; and the same in the benchmark's own box (6 cm tall,
released at y = 4 cm, whose largest speed is the published "Re_max"; no window there).

The driven runs (``--driven``) separate the two parts of the coupled disc's deficit: a disc ten
thousand times denser than the water, started at a speed near the coupled disc's terminal one
with no gravity, keeps that speed (it slows by 0.2 % in the window), and its momentum change is
the fluid's force on a body moving across the grid, which Galilean invariance makes equal to the
frame's drag at that speed for any body and any step. ``--reuse`` keeps the frame
rows of the last results file (the fixed obstacle's solver is not the coupled one) and runs the
coupled and driven ones; ``--add`` keeps every row and runs only the coupled and driven runs
named, and the `maccormack` frame on the grids of ``--advected-cells`` (a finer grid added to
a study without re-running it).

Writes ``benchmarks/results/sedimentation_frame.{json,md}``.
"""

from __future__ import annotations

import argparse
import itertools
import json
import math
import os
import platform
import time
from pathlib import Path

import numpy as np

from crosscheck.scene.loader import load_case_text
from crosscheck.sim.fluid.forces import balance_after_each_step
from crosscheck.sim.fluid.run import FluidRun

ROOT = Path(__file__).resolve().parents[1]
OUT = ROOT / "benchmarks" / "results"
D = 0.0025          # m
WIDTH = 0.02        # m, 8 d
NU = 1.0e-5         # m^2/s
RHO, RHO_S, G = 1000.0, 1250.0, 9.81
WEIGHT = (RHO_S - RHO) * G * math.pi * (D / 2) ** 2   # reduced weight, N per unit depth
# the driven disc (driven_run): about the coupled disc's terminal speed at 4 cells per diameter,
# and a density that makes it slow by about 0.2 % over its window
DRIVEN_SPEED = 0.0544     # m/s
DRIVEN_DENSITY = 1.0e7    # kg/m^3


# a whole study's runs, when none are named (the results file's coupled rows lack tall:16:0.001,
# not re-run after the moving-wall remedies; --add added driven 16:0.001 and the maccormack
# frame at 16 cells)
DEFAULT_ADVECTED_CELLS = [4, 8]
DEFAULT_COUPLED = ["tall:4:0.002", "tall:4:0.001", "tall:4:0.0005", "tall:4:0.00025",
                   "tall:8:0.004", "tall:8:0.002", "tall:16:0.001", "glowinski:8:0.002",
                   "glowinski:8:0.0005"]
DEFAULT_DRIVEN = ["4:0.002", "4:0.001", "4:0.0005", "8:0.002", "8:0.0005"]


def frame_case(speed: float, cells: int, integrator: str = "central", cfl: float = 0.5) -> str:
    """The disc fixed 8 d above the inflow, a uniform stream ``speed`` from below, both side
    walls moving up at ``speed``, the top open 16 d downstream; no gravity (the drag alone)."""
    dx = D / cells
    height = 0.06
    return f'''[case]
name = "sedimentation-frame-{cells}-{speed:g}"
description = "A disc held in a stream in a channel whose walls move with the stream."
tags = ["fluid", "viscous"]
dimension = 2

[run]
duration = 1.5
dt = 0.01
sample_every = 0.01
engines = ["inhouse"]
integrators = {{ inhouse = ["{integrator}"] }}

[fluid]
domain = [{WIDTH}, {height}]
resolution = [{round(WIDTH / dx)}, {round(height / dx)}]
density = {RHO}
kinematic_viscosity = {NU}
cfl = {cfl}
walls = {{ bottom = "inflow", top = "open", left = "solid", right = "solid" }}
inflow = {{ profile = "uniform", speed = {speed} }}
lid = [{{ side = "left", speed = {speed} }}, {{ side = "right", speed = {speed} }}]
obstacles = [{{ name = "disc", circle = {{ center = [{WIDTH / 2}, 0.02], radius = {D / 2} }} }}]
output = {{ forces = true }}
'''


def run_table(duration: float, step: float, integrator: str) -> str:
    """A generated case's ``[run]`` table: the in-house solver alone, sampled every step."""
    return f'''[run]
duration = {duration}
dt = {step}
sample_every = {step}
engines = ["inhouse"]
integrators = {{ inhouse = ["{integrator}"] }}
'''


def coupled_case(cells: int, step: float, height: float, start: float,
                 integrator: str = "maccormack", duration: float = 3.0,
                 density: float = RHO_S, speed: float = 0.0, gravity: bool = True) -> str:
    """The disc released on the channel's axis (``speed``: moving down at it from the start;
    ``gravity`` False: no gravity at all, the disc driven by its own inertia)."""
    dx = D / cells
    effects = f"[effects]\ngravity = [0.0, -{G}]\n" if gravity else ""
    return f'''[case]
name = "sedimentation-coupled-{cells}"
description = "A disc released from rest on the axis of a closed channel 8 d wide."
tags = ["fluid", "coupling", "viscous", "sedimentation"]
dimension = 2

{run_table(duration, step, integrator)}
{effects}
[[bodies]]
name = "disc"
shape = {{ circle = {{ radius = {D / 2} }} }}
density = {density}
position = [{WIDTH / 2}, {start}]
velocity = [0.0, {-speed if speed else 0.0}]

[fluid]
domain = [{WIDTH}, {height}]
resolution = [{round(WIDTH / dx)}, {round(height / dx)}]
density = {RHO}
kinematic_viscosity = {NU}
'''


def frame_run(speed: float, cells: int, integrator: str = "central", cfl: float = 0.5) -> dict:
    scene = load_case_text(frame_case(speed, cells, integrator, cfl), "frame.toml")
    t0 = time.perf_counter()
    rec = FluidRun(scene, integrator).record()
    wall = time.perf_counter() - t0
    t = np.asarray(rec.t)
    fy = np.asarray(rec.series["force_y.disc"])
    last = t > t[-1] - 0.3
    drag = float(np.mean(fy[last]))
    return {"speed": speed, "cells": cells, "integrator": integrator, "cfl": cfl,
            "re": speed * D / NU, "drag": drag,
            "drag_over_weight": drag / WEIGHT, "cd": drag / (0.5 * RHO * speed ** 2 * D),
            "unsteadiness": float(np.ptp(fy[last]) / abs(drag)), "failure": rec.failure,
            "wall_s": wall}


def coupled_run(cells: int, step: float, box: str, integrator: str = "maccormack",
                duration: float = 3.0) -> dict:
    """The largest settling speed of a run (``duration`` s at most: it stops 1.5 cells above
    the bottom)."""
    height, start = {"tall": (0.12, 0.10), "glowinski": (0.06, 0.04)}[box]
    scene = load_case_text(coupled_case(cells, step, height, start, integrator, duration),
                           "coupled.toml")
    t0 = time.perf_counter()
    rec = FluidRun(scene, integrator).record()
    wall = time.perf_counter() - t0
    t = np.asarray(rec.t)
    vy = np.asarray(rec.series["body_vy.disc"])
    i = int(np.argmin(vy))
    # the mean speed from 0.5 s to 1 s: past the start-up (the speed wanders by about 1 % from
    # step to step as cell rows open behind the body), and while the disc is more than 8 d above
    # the bottom (at 6 d it is slowed by 1 %, measured in the tall box; the 6 cm box has no
    # such window)
    y = np.asarray(rec.series["body_y.disc"])
    window = (t >= 0.5) & (t <= 1.0) & (y > 8 * D)
    return {"cells": cells, "step": step, "box": box, "integrator": integrator,
            "u_mean": float(-np.mean(vy[window])) if window.any() else None,
            "u_max": float(-vy[i]), "re_max": float(-vy[i] * D / NU), "t_max": float(t[i]),
            "y_max": float(rec.series["body_y.disc"][i]),
            "stopped": None if rec.failure is None else rec.failure.get("time"),
            "wall_s": wall}


def driven_run(cells: int, step: float, speed: float = DRIVEN_SPEED,
               integrator: str = "maccormack", duration: float = 1.0) -> dict:
    """The fluid's force on a disc driven down the tall channel's axis at ``speed``: a disc
    DRIVEN_DENSITY / RHO times heavier than the water it displaces, started at ``speed``, no
    gravity, so that it slows by about 0.2 % in the window (0.5-1 s) and the fluid's force is
    its momentum change (``body_force_y``). In a steady state this is the force the fixed
    solver's drag at that speed says (Galilean invariance), for any body mass; the settling
    disc's speed adds the coupled step's splitting (the viscous step's wall moves at the
    velocity predicted before the viscous exchange), this run leaves only the fluid's own
    response to a body moving across the grid."""
    if duration <= 0.5:
        raise ValueError(f"driven_run: duration {duration:g} s leaves no window (it starts at "
                         "0.5 s)")
    scene = load_case_text(coupled_case(cells, step, 0.12, 0.10, integrator, duration,
                                        density=DRIVEN_DENSITY, speed=speed, gravity=False),
                           "driven.toml")
    t0 = time.perf_counter()
    rec = FluidRun(scene, integrator).record()
    wall = time.perf_counter() - t0
    t = np.asarray(rec.t)
    window = (t >= 0.5) & (t <= duration)
    u = -np.asarray(rec.series["body_vy.disc"])[window]
    force = np.asarray(rec.series["body_force_y.disc"])[window]
    return {"cells": cells, "step": step, "integrator": integrator, "speed_set": speed,
            "speed": float(np.mean(u)), "speed_change": float((u[-1] - u[0]) / u[0]),
            "force": float(np.mean(force)), "force_over_weight": float(np.mean(force) / WEIGHT),
            "failure": rec.failure, "wall_s": wall}


def record_held(run: FluidRun, places) -> tuple:
    """Record ``run`` (a coupled body held in a stream) with the fluid's momentum balance
    around ``places`` (a ``FluidSpec`` naming the body's place as an obstacle) measured after
    each step: ``(record, [(time, forces by name)], wall seconds of the record)``."""
    balance = balance_after_each_step(run.st, places)
    t0 = time.perf_counter()
    rec = run.record()
    return rec, balance, time.perf_counter() - t0


def held_run(cells: int, step: float, integrator: str = "central",
             speed: float = DRIVEN_SPEED, duration: float = 1.2) -> dict:
    """The frame's scene with the disc a coupled body at rest (``DRIVEN_DENSITY``, no gravity;
    it drifts to about 0.5 % of the stream's speed) at a fixed step: its force measured twice
    over the last 0.3 s, as its momentum change (``body_force_y``) and by the fluid's momentum
    balance around it (a ``ForceProbe`` on its place, as the fixed solver measures). Newton's
    third law makes them equal."""
    obstacle = (f'obstacles = [{{ name = "disc", circle = {{ center = [{WIDTH / 2}, 0.02], '
                f'radius = {D / 2} }} }}]\n')
    fixed_text = (frame_case(speed, cells, integrator).replace("cfl = 0.5\n", "")
                  .replace("dt = 0.01\n", f"dt = {step}\n")
                  .replace("duration = 1.5", f"duration = {duration}"))
    assert obstacle in fixed_text
    text = (fixed_text.replace(obstacle, "").replace("output = { forces = true }\n", "")
            .replace('name = "sedimentation-frame-', 'name = "sedimentation-held-')
            + f"""
[[bodies]]
name = "disc"
shape = {{ circle = {{ radius = {D / 2} }} }}
density = {DRIVEN_DENSITY}
position = [{WIDTH / 2}, 0.02]
""")
    fixed = load_case_text(fixed_text, "frame.toml").fluid
    rec, balance, wall = record_held(FluidRun(load_case_text(text, "held.toml"), integrator),
                                     fixed)
    t = np.asarray(rec.t)
    last = t > t[-1] - 0.3
    body = float(np.mean(np.asarray(rec.series["body_force_y.disc"])[last]))
    fluid = float(np.mean([f["disc"][1] for _, f in balance[-int(round(0.3 / step)):]]))
    return {"cells": cells, "step": step, "integrator": integrator, "speed": speed,
            "body_over_weight": body / WEIGHT, "fluid_over_weight": fluid / WEIGHT,
            "third_law_gap": body / fluid - 1.0,
            "drift": float(np.max(np.abs(np.asarray(rec.series["body_vy.disc"]))) / speed),
            "failure": rec.failure, "wall_s": wall}


def _power_laws(frames: list[dict]):
    """``(u0, d0, u1, d1, n)`` for each pair of successive frame speeds: the drag ``D = a U^n``
    through the two."""
    pts = sorted((f["speed"], f["drag"]) for f in frames if f["failure"] is None)
    for (u0, d0), (u1, d1) in itertools.pairwise(pts):
        yield u0, d0, u1, d1, math.log(d1 / d0) / math.log(u1 / u0)


def frame_drag(frames: list[dict], speed: float) -> float | None:
    """The frame's drag at ``speed``, by the power law through the two speeds that bracket it."""
    for u0, d0, u1, _, n in _power_laws(frames):
        if u0 <= speed <= u1:
            return d0 * (speed / u0) ** n
    return None


def terminal_speed(frames: list[dict]) -> float | None:
    """Where the drag equals the reduced weight, by the power law through the two bracketing
    speeds."""
    for u0, d0, _, d1, n in _power_laws(frames):
        if d0 <= WEIGHT <= d1:
            return u0 * (WEIGHT / d0) ** (1.0 / n)
    return None


def markdown(result: dict) -> str:
    uts = result["terminal_speed"]
    lines = [
        "# A settling disc, coupled and in its own frame",
        "",
        f"Generated by `benchmarks/bench_sedimentation_frame.py` on {result['recorded']} "
        f"({result['machine']}). Glowinski et al.'s single settling disc: channel 8 d wide, "
        "d = 2.5 mm, rho_s / rho = 1.25, nu = 1e-5 m^2/s, g = 9.81 (reduced weight "
        f"{WEIGHT:.5g} N/m). Wall times are of a shared machine (load {result['load']:.1f} at "
        "the start): they say what a run costs here, not how fast the solver is.",
        "",
        "## The disc's frame (fixed obstacle, walls moving with the stream)",
        "",
        "| advection | CFL | U (m/s) | Re | cells/d | drag (N/m) | drag / weight | C_D | "
        "wall (s) |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for f in result["frames"]:
        lines.append(f"| {f['integrator']} | {f['cfl']:g} | "
                     f"{f['speed']:g} | {f['re']:.2f} | {f['cells']} | {f['drag']:.5g} | "
                     f"{f['drag_over_weight']:.4f} | {f['cd']:.3f} | {f['wall_s']:.0f} |")
    same = result["terminal_speed_advected"]
    lines += ["", "Terminal speed where the drag equals the weight: " + ", ".join(
        f"{c} cells/d **{u:.5f} m/s, Re {u * D / NU:.2f}**" if u is not None
        else f"{c} cells/d -" for c, u in uts.items())]
    if same:
        lines += ["", "The same with the coupled runs' advection (`maccormack`, semi-Lagrangian "
                  "with a correction): " + ", ".join(
                      f"{c} cells/d {u:.5f} m/s, Re {u * D / NU:.2f}" if u is not None
                      else f"{c} cells/d -" for c, u in same.items())
                  + ". A semi-Lagrangian step's error depends on the velocity relative to the "
                  "grid, which differs between the frames (the stream moves past the grid in the "
                  "disc's frame, the disc moves across it in the coupled run): the same scheme in "
                  "the other frame is a closer comparison, not an exact one."]
    lines += ["", "## Coupled (the disc released from rest)", "",
              "| box | advection | cells/d | step (s) | CFL at U | u max (m/s) | Re max | "
              "against the frame | at t (s) | mean 0.5-1 s against the frame | "
              "mean against the frame with its advection | wall (s) |",
              "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for c in result["coupled"]:
        cfl = c["u_max"] * c["step"] / (D / c["cells"])
        ut = uts.get(str(c["cells"]))
        vs = "-" if ut is None else f"{(c['u_max'] / ut - 1) * 100:+.1f} %"
        mean = c.get("u_mean")
        vm = "-" if ut is None or mean is None else f"{(mean / ut - 1) * 100:+.1f} %"
        # the frame with the run's own advection (the frames' `central` rows are uts)
        us = {"maccormack": same.get(str(c["cells"])),
              "central": ut}.get(c["integrator"])
        va = "-" if us is None or mean is None else f"{(mean / us - 1) * 100:+.1f} %"
        lines.append(f"| {c['box']} | {c['integrator']} | {c['cells']} | {c['step']:g} | "
                     f"{cfl:.2f} | {c['u_max']:.5f} | {c['re_max']:.2f} | {vs} | "
                     f"{c['t_max']:.2f} | {vm} | {va} | {c['wall_s']:.0f} |")
    driven = result.get("driven") or []
    if driven:
        lines += ["", "## Driven at a constant speed (the fluid's force alone)", "",
                  f"A disc {DRIVEN_DENSITY / RHO:g} times denser than water, started at "
                  f"{DRIVEN_SPEED:g} m/s down the tall channel's axis with no gravity: the mean "
                  "fluid force over 0.5-1 s (its momentum change) against the frame's drag at "
                  "the same mean speed (a power law through the two frame speeds that bracket "
                  "it, each grid against its own frame). Galilean invariance makes the two equal "
                  "for any step; the settling disc's deficit is this excess plus the coupled "
                  "step's splitting (docs/fluid.md).",
                  "",
                  "| advection | cells/d | step (s) | CFL | speed (m/s) | change in window | "
                  "force / weight | frame `central` / weight | against it | "
                  "frame `maccormack` / weight | against it | wall (s) |",
                  "|---|---|---|---|---|---|---|---|---|---|---|---|"]
        for r in driven:
            cfl = r["speed"] * r["step"] / (D / r["cells"])
            cols = []
            for integ in ("central", "maccormack"):
                fd = frame_drag([f for f in result["frames"] if f["cells"] == r["cells"]
                                 and f["integrator"] == integ], r["speed"])
                cols += (["-", "-"] if fd is None else
                         [f"{fd / WEIGHT:.4f}", f"{(r['force'] / fd - 1) * 100:+.1f} %"])
            lines.append(f"| {r['integrator']} | {r['cells']} | {r['step']:g} | {cfl:.3f} | "
                         f"{r['speed']:.5f} | {r['speed_change'] * 100:+.2f} % | "
                         f"{r['force_over_weight']:.4f} | {' | '.join(cols)} | "
                         f"{r['wall_s']:.0f} |")
    held = result.get("held") or []
    if held:
        lines += ["", "## Held at rest in the frame's stream (Newton's third law)", "",
                  f"The frame's scene at {DRIVEN_SPEED:g} m/s with the disc a coupled body "
                  f"{DRIVEN_DENSITY / RHO:g} times denser than water, no gravity: its force over "
                  "the last 0.3 s of 1.2 s as its momentum change and as the fluid's momentum "
                  "balance around it (a ForceProbe on its place, the fixed solver's measurement).",
                  "",
                  "| advection | cells/d | step (s) | body / weight | fluid balance / weight | "
                  "gap | drift (of the speed) | wall (s) |",
                  "|---|---|---|---|---|---|---|---|"]
        for r in held:
            lines.append(f"| {r['integrator']} | {r['cells']} | {r['step']:g} | "
                         f"{r['body_over_weight']:.4f} | {r['fluid_over_weight']:.4f} | "
                         f"{r['third_law_gap'] * 100:+.2f} % | {r['drift'] * 100:.2f} % | "
                         f"{r['wall_s']:.0f} |")
    return "\n".join(lines) + "\n"


def _spec_key(row: dict) -> tuple:
    return (row.get("box"), row["cells"], row["step"], row["integrator"])


def _coupled_spec(spec: str) -> tuple:
    """``box:cells:step[:integrator]`` -> the arguments of ``coupled_run``."""
    parts = spec.split(":")
    try:
        if len(parts) not in (3, 4) or parts[0] not in ("tall", "glowinski"):
            raise ValueError
        return (int(parts[1]), float(parts[2]), parts[0], *parts[3:])
    except ValueError:
        raise SystemExit(f"--coupled: expected box:cells:step[:integrator] with box 'tall' or "
                         f"'glowinski', got {spec!r}") from None


def _grid_spec(spec: str, option: str) -> tuple:
    """``cells:step[:integrator]`` (of ``--driven`` or ``--held``) -> ``(cells, step,
    [integrator])``."""
    parts = spec.split(":")
    try:
        if len(parts) not in (2, 3):
            raise ValueError
        return (int(parts[0]), float(parts[1]), *parts[2:])
    except ValueError:
        raise SystemExit(f"{option}: expected cells:step[:integrator], got {spec!r}") from None


def _driven_spec(spec: str) -> tuple:
    """``cells:step[:integrator]`` -> the arguments of ``driven_run``."""
    cells, step, *integrator = _grid_spec(spec, "--driven")
    return (cells, step, DRIVEN_SPEED, *integrator)


def _write(result: dict) -> str:
    """The results file and its markdown (after each run of a long study: a stop loses none)."""
    OUT.mkdir(parents=True, exist_ok=True)
    (OUT / "sedimentation_frame.json").write_text(json.dumps(result, indent=2))
    text = markdown(result)
    (OUT / "sedimentation_frame.md").write_text(text)
    return text


def add(args: argparse.Namespace) -> None:
    """``--add``: the last results file with the named coupled and driven runs added (a run of
    the same box, grid, step and advection replaced), and the frame with the coupled runs'
    advection on the grids of ``--advected-cells``; its other rows kept, the file rewritten
    after each run. The markdown's date line gains the date of the added rows."""
    path = OUT / "sedimentation_frame.json"
    if not path.exists():
        raise SystemExit(f"--add: no results file at {path} (run without --add first)")
    result = json.loads(path.read_text())
    # every spec read before the first run: a typo costs nothing
    coupled = [_coupled_spec(s) for s in args.coupled or []]
    driven = [_driven_spec(s) for s in args.driven or []]
    held = [_grid_spec(s, "--held") for s in args.held or []]
    advected = args.advected_cells or []
    if not coupled and not driven and not held and not advected:
        raise SystemExit("--add: name the runs to add with --coupled, --driven, --held and/or "
                         "--advected-cells")
    result["recorded"] += f", {time.strftime('%Y-%m-%d %H:%M')} (added rows)"
    for cells in advected:
        # the frame with the coupled runs' advection on another grid, at every speed
        rows = [frame_run(speed, cells, "maccormack", args.advected_cfl)
                for speed in args.speeds]
        result["frames"] = [f for f in result["frames"]
                            if (f["cells"], f["integrator"]) != (cells, "maccormack")] + rows
        result.setdefault("terminal_speed_advected", {})[str(cells)] = terminal_speed(rows)
        print(json.dumps(rows), flush=True)
        _write(result)
    for key, specs, run in (("coupled", coupled, coupled_run), ("driven", driven, driven_run),
                            ("held", held, held_run)):
        for spec in specs:
            row = run(*spec)
            result[key] = [r for r in result.get(key, [])
                           if _spec_key(r) != _spec_key(row)] + [row]
            print(json.dumps(row), flush=True)
            _write(result)
    print(markdown(result))


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--frame-cells", type=int, nargs="+", default=[4, 8, 16])
    ap.add_argument("--speeds", type=float, nargs="+", default=[0.052, 0.058, 0.0692])
    ap.add_argument("--advected-cfl", type=float, default=0.1,
                    help="the CFL number of the frame runs with the coupled runs' advection "
                         "(maccormack); 0: not run")
    ap.add_argument("--advected-cells", type=int, nargs="+", default=None,
                    help="the grids of those runs (a subset of --frame-cells; default "
                         f"{' '.join(map(str, DEFAULT_ADVECTED_CELLS))})")
    ap.add_argument("--coupled", nargs="*", default=None,
                    help="box:cells:step[:integrator], box 'tall' (12 cm) or 'glowinski' "
                         "(6 cm); default the committed study's")
    ap.add_argument("--driven", nargs="*", default=None,
                    help="cells:step[:integrator] of the disc driven at a constant speed "
                         "(driven_run); default the committed study's")
    ap.add_argument("--held", nargs="*", default=None,
                    help="cells:step[:integrator] of the disc held at rest in the frame's "
                         "stream as a coupled body (held_run; with --add only)")
    ap.add_argument("--reuse", action="store_true",
                    help="keep the frame rows of the last results file (their date stays in "
                         "it) and run only the coupled and driven ones")
    ap.add_argument("--add", action="store_true",
                    help="keep every row of the last results file and run only the coupled "
                         "and driven runs named and the maccormack frames of "
                         "--advected-cells (none unless given), each replacing a row of the "
                         "same box, grid, step and advection")
    args = ap.parse_args()
    if args.add:
        add(args)
        return
    if args.held:
        ap.error("--held: with --add only (a study's held rows are added to its results)")
    # the committed study's runs, unless named
    args.advected_cells = (DEFAULT_ADVECTED_CELLS if args.advected_cells is None
                           else args.advected_cells)
    args.coupled = DEFAULT_COUPLED if args.coupled is None else args.coupled
    args.driven = DEFAULT_DRIVEN if args.driven is None else args.driven
    # every spec read before the first run: a typo costs nothing
    coupled = [_coupled_spec(s) for s in args.coupled]
    driven = [_driven_spec(s) for s in args.driven]
    result = {"recorded": time.strftime("%Y-%m-%d %H:%M"), "machine": platform.machine(),
              "load": os.getloadavg()[0], "weight": WEIGHT, "frames": [], "coupled": []}
    if args.reuse:
        path = OUT / "sedimentation_frame.json"
        last = json.loads(path.read_text()) if path.exists() else {}
        if not last.get("frames"):
            ap.error(f"--reuse: {path} has no frame rows to keep (run without --reuse first)")
        result.update({k: last[k] for k in ("frames", "terminal_speed",
                                            "terminal_speed_advected")})
        result["recorded"] = (f"{last['recorded'].split(' (')[0]} (frame rows), "
                              f"{result['recorded']} (coupled and driven rows)")
        args.frame_cells, args.advected_cfl = [], 0.0
    # (advection, CFL, grids) of the frame runs
    schemes = [("central", 0.5, args.frame_cells)] + (
        [("maccormack", args.advected_cfl, args.advected_cells)] if args.advected_cfl > 0 else [])
    for integrator, cfl, grids in schemes:
        for cells in grids:
            for speed in args.speeds:
                result["frames"].append(frame_run(speed, cells, integrator, cfl))
                print(json.dumps(result["frames"][-1]), flush=True)

    def terminal(integrator: str, grids: list[int]) -> dict:
        # the terminal speed at each grid (a coupled run is compared with its own grid's)
        return {str(c): terminal_speed([f for f in result["frames"] if f["cells"] == c
                                        and f["integrator"] == integrator])
                for c in grids}

    if not args.reuse:
        result["terminal_speed"] = terminal("central", args.frame_cells)
        result["terminal_speed_advected"] = (terminal("maccormack", args.advected_cells)
                                             if args.advected_cfl > 0 else {})
    result["driven"] = []
    for spec in coupled:
        result["coupled"].append(coupled_run(*spec))
        print(json.dumps(result["coupled"][-1]), flush=True)
        _write(result)
    for spec in driven:
        result["driven"].append(driven_run(*spec))
        print(json.dumps(result["driven"][-1]), flush=True)
        _write(result)
    print(_write(result))


if __name__ == "__main__":
    main()
