"""A disc settling in a vertical channel four diameters wide against Wachs's (2009) published
terminal state (issue 14, point 3): the in-house two-way coupled solver's terminal velocity,
Reynolds number and drag coefficient at several grids, the observed order and a Richardson
estimate of the grid-converged value.

    PYTHONPATH=src nice .venv/bin/python benchmarks/bench_sedimentation.py
        [--runs 8 12 16 8:semi_lagrangian 8:offset 12:offset] [--tag _axis] [--markdown-only]
        [--held 8:0.02 16:0.01 12:0.01:maccormack:1e7] [--motion 12:0.02 12:0.01]
        [--placement 12:0.01 16:0.01] [--grids]

    # the committed studies: sedimentation.json (8, 12, 16 at the step 0.02 or the CFL limit,
    # 8:semi_lagrangian, 8:cfl0.5, 8:offset, 12:offset) and, with --tag _axis, the grid study
    # at dt = 0.16 dx (8:dt0.02 12:dt0.01333 16:dt0.01) and the step at 8 (8:dt0.01 8:dt0.005);
    # the same at dt = 0.08 dx (8:dt0.01 12:dt0.00667 16:dt0.005) and 12:dt0.02;
    # with --tag _offaxis the releases off the axis re-measured with the incremental coupled
    # projection (8:offset 12:offset 8:offset+dt0.01); with --tag _offaxis_remedies the
    # release at 8 with the moving-wall remedies (8:offset; 12 not re-run); with --tag _central
    # the central scheme at 8 (8:central+dt0.02 8:central+dt0.01); with --tag _offaxis_steps12
    # and _offaxis_steps16 the step study of the release off the axis in the 45 d channel
    # (12:offset+short+dt0.02 ... +dt0.005, 16:offset+short+dt0.02 +dt0.01 +dt0.006667 +dt0.005)
    # and, at the step 0.005, _offaxis_steps24 / 32 / 40 / 48 / 56 / 64 (one grid each);
    # --grids reads them all into sedimentation_offaxis_grids.md (the grid sequence)

The benchmark (reference/data/wachs2009_disc_channel_sedimentation.csv, its header has the one
public copy found): d = 1, channel w = 4 d, nu = 0.008088, g = 10, rho_s / rho = 1.5, published
terminal Re = U d / nu = 259.5 and C_D = 1.785. Each run is a case TOML built here and read by
crosscheck's own loader (``reference.table = "wachs_2009"``, the metric
``published_sedimentation`` in compare/fluid_metrics.py), the fluid's domain 30 d tall (the disc
released on the axis 3 d below the closed top, 12 s: it is within 1 % of its terminal speed after
about 4 s, 8 d of travel, and the window 5-12 s covers about 15 d ending about 3 d above the
bottom).

A run is ``<cells per diameter>[:<variant>]``: ``semi_lagrangian`` or ``central`` (that scheme
instead of MacCormack), ``dt<step>`` (the largest step and the sampling interval, default
0.02, which caps the step: CFL 0.34 at U = 2.1 and 8 cells per diameter), ``cfl<number>`` (the
fluid's CFL
number, default 1), ``offset`` (released 1 d
off the axis as in the benchmark, in a channel 100 d tall for 45 s, the window from 16 s: the
disc wanders across the axis, so the mean speed needs many diameters of travel), ``short``
with it (the same release in a channel 45 d tall, 20 s, the window from 8 s: a step study's
scene, within 0.2 % of the long run's speed over the same window at 12 cells), ``len<L>``
(the channel L diameters tall, the release still 3 d below its top: with ``short`` the window's
end nearer to or farther from the bottom); variants combine with ``+`` (``8:offset+dt0.01``).
Each finished run is appended to ``benchmarks/results/sedimentation.json`` (a long study
survives a stop) and ``sedimentation.md`` is written from everything in it.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import platform
import time
from pathlib import Path

import numpy as np
from bench_sedimentation_frame import record_held, run_table  # shared with the frame benchmark

from crosscheck.compare.fluid_metrics import fluid_metrics
from crosscheck.compare.grid_convergence import grid_sequence, three_grids
from crosscheck.reference.fluid_data import wachs_path_offsets, wachs_sedimentation
from crosscheck.scene.loader import load_case_text
from crosscheck.sim.fluid.run import FluidRun

ROOT = Path(__file__).resolve().parents[1]
OUT = ROOT / "benchmarks" / "results"
STEM = "sedimentation"
D = 1.0
NU = 0.008088
RATIO = 1.5             # rho_s / rho of every run here (Wachs's r = 1.5)
RELEASE_BELOW_TOP = 3.0  # diameters from the channel's closed top to the disc's release
KEYS = ("terminal_velocity", "terminal_velocity_reference", "terminal_velocity_error",
        "terminal_reynolds", "drag_coefficient", "drag_coefficient_reference",
        "drag_coefficient_error", "terminal_velocity_unsteadiness", "window_travel",
        "bottom_clearance", "centreline_offset", "centreline_offset_mean",
        "centreline_offset_reference", "centreline_offset_mean_reference", "energy_lost",
        "viscous_dissipation_ratio")


def case_text(cells: int, integrator: str = "maccormack", length: float = 30.0,
              duration: float = 12.0, settle: float = 5.0, offset: float = 0.0,
              cfl: float = 1.0, ratio: float = RATIO, step: float = 0.02) -> str:
    """The benchmark's scene as a case file: ``cells`` cells per diameter, the disc released
    ``offset`` diameters off the axis, 3 d below the closed top of a channel ``length`` tall."""
    width = 4.0 * D
    return f'''[case]
name = "fluid-sedimentation-wachs-{cells}"
description = "A disc {ratio:g} times as dense as the fluid in a channel 4 d wide: Wachs 2009."
tags = ["fluid", "coupling", "viscous", "sedimentation"]
dimension = 2

[run]
duration = {duration}
dt = {step}      # the largest step (sampling caps it): CFL {2.1 * step * cells:.2f} at U 2.1
sample_every = {step}
engines = ["inhouse"]
integrators = {{ inhouse = ["{integrator}"] }}

[effects]
gravity = [0.0, -10.0]

[[bodies]]
name = "disc"
shape = {{ circle = {{ radius = {D / 2} }} }}
density = {1000.0 * ratio}
position = [{width / 2 + offset * D}, {length - RELEASE_BELOW_TOP * D}]

[fluid]
domain = [{width}, {length}]
resolution = [{int(round(4 * cells))}, {int(round(length * cells))}]
density = 1000.0
kinematic_viscosity = {NU}
cfl = {cfl}

[reference]
kind = "table"
table = "wachs_2009"
params = {{ settle_time = {settle} }}
'''


HELD_SPEED = 2.1        # about the terminal speed (Wachs: 2.0988)
# the held disc's density: 10^7 times the fluid's, it drifts by under 1e-5 of the stream over a
# run. At 10^4 times (CREEP_DENSITY, the studies' setting until 2026-12-01) it crept downstream
# at up to 0.3 % of the stream, 0.24 cells over the last third of a run at 12 cells, and
# dragged 4.7 % more than held still (docs/fluid.md, "The held disc held still")
HELD_DENSITY = 1.0e10
CREEP_DENSITY = 1.0e7
HELD_DYNAMIC_PRESSURE = 0.5 * 1000.0 * HELD_SPEED ** 2 * D     # C_D's denominator per depth


def held_text(cells: int, step: float, integrator: str, duration: float, body: bool,
              density: float = HELD_DENSITY, shift: float = 0.0) -> str:
    """The disc's frame at Wachs's Reynolds number: the disc 8 d above a uniform inflow at
    ``HELD_SPEED``, both walls moving with the stream, the top open 16 d downstream, no gravity;
    ``body``: the disc a coupled body at rest (``density``), else a fixed obstacle whose
    place the fluid's momentum balance is measured on; ``shift``: the disc that many cells
    downstream of 8 d (where the grid cuts it)."""
    width, height, dx = 4.0 * D, 24.0 * D, D / cells
    y = 8.0 * D + shift * dx
    disc = (f'obstacles = [{{ name = "disc", circle = {{ center = [{width / 2}, {y!r}], '
            f'radius = {D / 2} }} }}]\noutput = {{ forces = true }}\n')
    coupled = f"""
[[bodies]]
name = "disc"
shape = {{ circle = {{ radius = {D / 2} }} }}
density = {density}
position = [{width / 2}, {y!r}]
"""
    text = f'''[case]
name = "sedimentation-held-{cells}"
description = "The Wachs disc held in a stream at its terminal speed, walls moving with it."
tags = ["fluid", "viscous"]
dimension = 2

{run_table(duration, step, integrator)}
[fluid]
domain = [{width}, {height}]
resolution = [{int(round(width / dx))}, {int(round(height / dx))}]
density = 1000.0
kinematic_viscosity = {NU}
walls = {{ bottom = "inflow", top = "open", left = "solid", right = "solid" }}
inflow = {{ profile = "uniform", speed = {HELD_SPEED} }}
lid = [{{ side = "left", speed = {HELD_SPEED} }}, {{ side = "right", speed = {HELD_SPEED} }}]
'''
    return text + (coupled if body else disc)


def held_run(cells: int, step: float, integrator: str = "maccormack",
             density: float = HELD_DENSITY, duration: float = 12.0) -> dict:
    """Newton's third law at Wachs's Reynolds number: the disc a coupled body held at rest in
    the stream (``density``), its force over the last third of the run as its momentum change
    and as the fluid's momentum balance around it (a ``ForceProbe`` on its place, as the fixed
    solver measures), beside the fixed obstacle's force in the same scene over the same window
    (the fluid solver alone: what the coupling at rest should reproduce). The disc is on the
    axis and the wake symmetric over the run."""
    q = HELD_DYNAMIC_PRESSURE
    frame = load_case_text(held_text(cells, step, integrator, duration, False), "frame.toml")
    t0 = time.perf_counter()
    fixed_rec = FluidRun(frame, integrator).record()
    fixed_wall = time.perf_counter() - t0
    t = np.asarray(fixed_rec.t)
    fixed = float(np.mean(np.asarray(fixed_rec.series["force_y.disc"])[t > t[-1] - duration / 3]))
    rec, balance, wall = record_held(
        FluidRun(load_case_text(held_text(cells, step, integrator, duration, True, density),
                                "held.toml"), integrator), frame.fluid)
    t = np.asarray(rec.t)
    start = t[-1] - duration / 3.0
    body = float(np.mean(np.asarray(rec.series["body_force_y.disc"])[t > start]))
    fluid = float(np.mean([f["disc"][1] for x, f in balance if x > start]))
    vy = np.asarray(rec.series["body_vy.disc"])
    drift = float(np.max(np.abs(vy))) / HELD_SPEED
    # how far the disc moved over the window, in cells (the samples' spacing times the speed)
    travel = float(np.sum(vy[t > start][1:] * np.diff(t[t > start]))) * cells / D
    name = f"{cells}:{step:g}:{integrator}" + ("" if density == HELD_DENSITY else f":{density:g}")
    return {"run": name, "cells_per_diameter": cells, "step": step, "density": density,
            "integrator": integrator, "duration": duration, "body_force": body,
            "fluid_balance": fluid, "third_law_gap": body / fluid - 1.0,
            "drag_coefficient": body / q, "fluid_drag_coefficient": fluid / q,
            "fixed_drag_coefficient": fixed / q, "drift": drift, "window_travel_cells": travel,
            "dt_mean": (rec.meta.get("dt") or {}).get("mean"),
            "fixed_dt_mean": (fixed_rec.meta.get("dt") or {}).get("mean"),
            "failure": rec.failure or fixed_rec.failure, "wall_s": wall,
            "fixed_wall_s": fixed_wall, "load": os.getloadavg()[0]}


def held_markdown(rows: list[dict]) -> str:
    lines = ["# Wachs's disc held in its own frame: Newton's third law at Re ~ 260", "",
             "Written by `benchmarks/bench_sedimentation.py --held`. The disc (d = 1, nu = "
             f"0.008088, Re = {HELD_SPEED * D / NU:.0f}) on the axis 8 d above a uniform inflow "
             f"at {HELD_SPEED} in a channel 4 d wide whose walls move with the stream, no "
             "gravity, a coupled body of the density in the table (the fluid's 1000): its force "
             "over the last third of the run (8-12 s) as its momentum change and by the fluid's "
             "momentum balance around it (a ForceProbe on its place). Newton's third law makes "
             "them equal. Beside it the fixed obstacle in the same scene over the same window "
             "(the fluid solver alone), which the coupling at rest should reproduce: 'held "
             "against fixed' compares the fluid's balances. At 1e+10 the disc is held still; at "
             "1e+07 (the setting of the rows before 2026-12-01, their fixed C_D from "
             "sedimentation_motion.json's same scene and step) it creeps downstream, 'travel' "
             "cells over the window. C_D here is the held disc's in a symmetric wake, not the "
             "settling benchmark's.",
             "", "| run | d/dx | step | advection | density | body force | fluid balance | gap "
             "| C_D (body) | C_D (fluid) | fixed C_D | held against fixed | drift (of the speed) "
             "| travel (cells) | wall (s) |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in sorted(rows, key=lambda r: (-r.get("density", CREEP_DENSITY), r["integrator"],
                                         r["cells_per_diameter"], -r["step"])):
        if r.get("failure"):
            lines.append(f"| {r['run']} | failed: {r['failure']} |")
            continue
        fluid_cd = r["fluid_balance"] / HELD_DYNAMIC_PRESSURE
        fixed = r.get("fixed_drag_coefficient")
        versus = "-" if fixed is None else f"{fluid_cd / fixed - 1.0:+.2%}"
        lines.append(f"| {r['run']} | {r['cells_per_diameter']} | {r['step']:g} | "
                     f"{r['integrator']} | {r.get('density', CREEP_DENSITY):g} | "
                     f"{r['body_force']:.2f} | {r['fluid_balance']:.2f} | "
                     f"{r['third_law_gap']:+.2%} | {r['drag_coefficient']:.4f} | "
                     f"{fluid_cd:.4f} | {_f(fixed, '{:.4f}')} | {versus} | "
                     f"{r['drift']:.2%} | {_f(r.get('window_travel_cells'), '{:.3f}')} | "
                     f"{r['wall_s']:.0f} |")
    return "\n".join(lines) + "\n"


PLACEMENT_SHIFTS = tuple(i / 10.0 for i in range(10))


def placement_run(cells: int, step: float, integrator: str = "maccormack") -> list[dict]:
    """The fixed obstacle of ``held_text`` at each of ``PLACEMENT_SHIFTS``, the disc moved
    downstream by that fraction of a cell: how much its drag depends on where the grid cuts
    it. A disc that moves (a settling one, or a held one that creeps) samples these placements
    in turn; one at rest keeps one of them."""
    q = HELD_DYNAMIC_PRESSURE
    rows = []
    for shift in PLACEMENT_SHIFTS:
        t0 = time.perf_counter()
        rec = FluidRun(load_case_text(held_text(cells, step, integrator, 12.0, False,
                                                shift=shift), "frame.toml"), integrator).record()
        t = np.asarray(rec.t)
        f = np.asarray(rec.series["force_y.disc"]) / q
        rows.append({"run": f"{cells}:{step:g}:{integrator}:{shift:.1f}",
                     "cells_per_diameter": cells, "step": step, "integrator": integrator,
                     "shift_cells": shift, "drag_coefficient": float(np.mean(f[t > 8.0])),
                     "drag_coefficient_early": float(np.mean(f[(t > 4.0) & (t <= 8.0)])),
                     "failure": rec.failure, "wall_s": time.perf_counter() - t0,
                     "load": os.getloadavg()[0]})
    return rows


def placement_markdown(rows: list[dict]) -> str:
    lines = ["# Where the grid cuts Wachs's disc: the fixed obstacle's drag at Re ~ 260", "",
             "Written by `benchmarks/bench_sedimentation.py --placement`. The fixed obstacle of "
             "the held study (d = 1 on the axis of a channel 4 d wide whose walls move with a "
             f"uniform stream at {HELD_SPEED}, nu = 0.008088, the wake symmetric) moved "
             "downstream by a fraction of a cell, C_D over 8-12 s (and 4-8 s). The grid, the "
             "step and the flow are the same in every row of a group; only where the cells cut "
             "the disc changes.", "",
             "| run | d/dx | step | advection | shift (cells) | C_D 8-12 s | C_D 4-8 s | "
             "wall (s) |", "|---|---|---|---|---|---|---|---|"]
    groups: dict = {}
    for r in sorted(rows, key=lambda r: (r["integrator"], r["cells_per_diameter"], -r["step"],
                                         r["shift_cells"])):
        groups.setdefault((r["cells_per_diameter"], r["step"], r["integrator"]), []).append(r)
    for (cells, step, integrator), group in groups.items():
        for r in group:
            if r.get("failure"):
                lines.append(f"| {r['run']} | failed: {r['failure']} |")
                continue
            lines.append(f"| {r['run']} | {cells} | {step:g} | {integrator} | "
                         f"{r['shift_cells']:.1f} | {r['drag_coefficient']:.4f} | "
                         f"{r['drag_coefficient_early']:.4f} | {r['wall_s']:.0f} |")
        cd = np.array([r["drag_coefficient"] for r in group if not r.get("failure")])
        if cd.size:
            lines.append(f"| **{len(cd)} placements** | {cells} | {step:g} | {integrator} | | "
                         f"{cd.mean():.4f} ± {cd.std() / cd.mean():.2%} ({cd.min():.4f} to "
                         f"{cd.max():.4f}, spread {(cd.max() - cd.min()) / cd.mean():.2%}) | | |")
    lines += ["", "Each group's last row: mean ± standard deviation over the mean (range)."]
    return "\n".join(lines) + "\n"


def placement_study(specs: list[str]) -> None:
    """``--placement cells:step[:integrator] ...``: the rows of each grid's placements added to
    (or replaced in) ``sedimentation_placement.{json,md}``, written after each grid."""
    _study("placement", _parse_cells_step("--placement", specs), placement_run,
           placement_markdown)


def held_study(specs: list[str]) -> None:
    """``--held cells:step[:integrator[:density]] ...``: rows added to (or replaced in)
    ``sedimentation_held.{json,md}``."""
    _study("held", _parse_cells_step("--held", specs, density=True), held_run, held_markdown)


def _study(name: str, parsed: list[tuple], run, markdown) -> None:
    """Run each ``run(*args)`` and add its row (or its list of rows) to the others in
    ``sedimentation_<name>.{json,md}``, replacing those of the same name, written after every
    run (a long study survives a stop). The file is read again before each write: two studies
    (say one per scheme) may run side by side."""
    path = OUT / f"{STEM}_{name}.json"
    for args in parsed:
        result = run(*args)
        new = result if isinstance(result, list) else [result]
        names = {r["run"] for r in new}
        rows = json.loads(path.read_text())["runs"] if path.exists() else []
        rows = [r for r in rows if r["run"] not in names] + new
        OUT.mkdir(parents=True, exist_ok=True)
        path.write_text(json.dumps({"runs": rows, "machine": platform.machine()}, indent=2))
        (OUT / f"{STEM}_{name}.md").write_text(markdown(rows))
        print(json.dumps(result), flush=True)


def driven_text(cells: int, step: float, integrator: str, duration: float) -> str:
    """The benchmark's channel with the disc 10^4 times denser than the fluid, started down
    its axis at ``HELD_SPEED`` through fluid at rest, no gravity: it keeps its speed (0.3 %
    lost over the run), so its momentum change is the fluid's force on a body crossing the
    grid, where the held disc (``held_text``) has the same relative flow without the motion."""
    text = case_text(cells, integrator, duration=duration, step=step, ratio=1.0e4)
    text = text.replace("[effects]\ngravity = [0.0, -10.0]\n", "")
    text = text[:text.index("[reference]")]
    start = f"position = [{2.0 * D}, {27.0 * D}]"
    assert start in text and "gravity" not in text
    return text.replace(start, f"{start}\nvelocity = [0.0, {-HELD_SPEED}]")


def motion_run(cells: int, step: float, integrator: str = "maccormack") -> dict:
    """The drag coefficient at Re ~ 260 three ways at one grid and step: the disc a fixed
    obstacle in the stream (``held_text`` without the body: the fluid solver alone), a coupled
    body held at rest in it (the coupling without motion) and a coupled body driven through
    fluid at rest (``driven_text``: the coupling with the body crossing the grid, half a cell
    a step at 12 cells and 0.02). Galilean invariance makes the three the same physics up to
    the start (the driven disc starts impulsively in still fluid) and the window (the held and
    fixed discs' last third, 8-12 s; the driven disc's 4-11 s, before the bottom); all three
    keep the symmetric wake on the axis. What differs between steps is each one's error in
    the step."""
    held = held_run(cells, step, integrator)     # the fixed obstacle's run with it
    t0 = time.perf_counter()
    rec = FluidRun(load_case_text(driven_text(cells, step, integrator, 11.5), "driven.toml"),
                   integrator).record()
    t = np.asarray(rec.t)
    window = (t >= 4.0) & (t <= 11.0)
    u = -np.asarray(rec.series["body_vy.disc"])[window]
    force = np.asarray(rec.series["body_force_y.disc"])[window]
    driven = float(np.mean(force)) / (0.5 * 1000.0 * float(np.mean(u)) ** 2 * D)
    return {"run": f"{cells}:{step:g}:{integrator}", "cells_per_diameter": cells, "step": step,
            "integrator": integrator,
            # the body's pose the advection reads the step's starting field on (a trace's
            # clipping, the central term's faces; FluidState.step): the step's start since
            # 2026-12-01; rows kept from before read "moved" (where begin_step put it)
            "advection_pose": "start",
            "fixed_cd": held["fixed_drag_coefficient"], "held_cd": held["drag_coefficient"],
            "held_density": held["density"],
            "held_third_law_gap": held["third_law_gap"], "driven_cd": driven,
            "driven_speed": float(np.mean(u)), "driven_speed_change": float(u[-1] / u[0] - 1.0),
            # the steps taken (the CFL limit cuts the largest step where the flow is fast)
            "dt_mean": {"fixed": held["fixed_dt_mean"], "held": held["dt_mean"],
                        "driven": (rec.meta.get("dt") or {}).get("mean")},
            "failure": held["failure"] or rec.failure,
            "wall_s": held["fixed_wall_s"] + held["wall_s"] + time.perf_counter() - t0,
            "load": os.getloadavg()[0]}


def motion_markdown(rows: list[dict]) -> str:
    lines = ["# The step's error with and without the body's motion, Wachs's disc at Re ~ 260", "",
             "Written by `benchmarks/bench_sedimentation.py --motion`. C_D of the disc (d = 1, nu "
             f"= 0.008088, U = {HELD_SPEED}) three ways: a fixed obstacle in the stream (the "
             "fluid solver alone), a coupled body held at rest in it (the coupling without "
             "motion; its third-law gap against the fluid's momentum balance beside it; its "
             "density in the table: at 1e+07, the rows before 2026-12-01, it creeps downstream "
             "and drags up to 4.7 % more than held still at 1e+10, sedimentation_held.md), "
             "and the same body driven at U through fluid at rest (the body "
             "crossing the grid). All on the channel's axis, the wake symmetric; the fixed and "
             "held discs over 8-12 s, the driven one over 4-11 s, so the three differ by their "
             "start and window as well; what the study reads is each one's change with the step. "
             "The mean step each run took (the CFL limit cuts the largest step where the flow is "
             "fast): '-' in rows measured before it was recorded. The advection's pose: the "
             "body's pose the advection reads the step's starting field on (the pose a "
             "semi-Lagrangian or MacCormack trace clips its paths against, the faces the "
             "central term is computed on), `start` (the step's start, the pose the field "
             "belongs to; the solver since 2026-12-01) or `moved` (where the step moves the "
             "body, the solver before; those rows are kept for the comparison, their runs "
             "named `...:moved`). "
             "Wall: the three runs together, timed beside other work (not a speed figure).",
             "", "| run | d/dx | step | step / dx | advection | advection's pose | mean step taken "
             "(fixed / held / driven) | fixed C_D | held density | held C_D | held gap "
             "| driven C_D | driven speed change | wall (s) |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in sorted(rows, key=lambda r: (r["integrator"], r.get("advection_pose") or "",
                                         r["cells_per_diameter"], -r["step"])):
        if r.get("failure"):
            lines.append(f"| {r['run']} | failed: {r['failure']} |")
            continue
        taken = r.get("dt_mean") or {}
        taken = " / ".join(_f(taken.get(k), "{:.4f}") for k in ("fixed", "held", "driven"))
        lines.append(f"| {r['run']} | {r['cells_per_diameter']} | {r['step']:g} | "
                     f"{r['step'] * r['cells_per_diameter']:.2f} | {r['integrator']} | "
                     f"{r.get('advection_pose') or '-'} | {taken} | {r['fixed_cd']:.4f} | "
                     f"{r.get('held_density', CREEP_DENSITY):g} | {r['held_cd']:.4f} | "
                     f"{r['held_third_law_gap']:+.2%} | {r['driven_cd']:.4f} | "
                     f"{r['driven_speed_change']:+.2%} | {r['wall_s']:.0f} |")
    return "\n".join(lines) + "\n"


def _parse_cells_step(flag: str, specs: list[str], density: bool = False) -> list[tuple]:
    """``cells:step[:integrator]`` (and with ``density`` a fourth field, the held disc's
    density) -> ``(cells, step[, integrator[, density]])`` each."""
    parsed = []
    form = "cells:step[:integrator[:density]]" if density else "cells:step[:integrator]"
    for spec in specs:
        parts = spec.split(":")
        try:
            if len(parts) not in ((2, 3, 4) if density else (2, 3)):
                raise ValueError
            parsed.append((int(parts[0]), float(parts[1]), *parts[2:3],
                           *(float(x) for x in parts[3:])))
        except ValueError:
            raise SystemExit(f"{flag}: expected {form}, got {spec!r}") from None
    return parsed


def motion_study(specs: list[str]) -> None:
    """``--motion cells:step[:integrator] ...``: rows added to (or replaced in)
    ``sedimentation_motion.{json,md}``."""
    _study("motion", _parse_cells_step("--motion", specs), motion_run, motion_markdown)


def parse_run(spec: str) -> dict:
    """``<cells>[:<variant>[+<variant>...]]`` -> the run's cells, integrator and case options."""
    cells, _, variants = spec.partition(":")
    run = {"cells": int(cells), "variant": variants or "maccormack", "integrator": "maccormack",
           "kw": {}}
    for variant in filter(None, variants.split("+")):
        if variant in ("semi_lagrangian", "central"):
            run["integrator"] = variant
        elif variant.startswith("dt"):
            run["kw"]["step"] = float(variant[2:])
        elif variant.startswith("cfl"):
            run["kw"]["cfl"] = float(variant[3:])
        elif variant == "offset":
            run["kw"].update(offset=-1.0, length=100.0, duration=45.0, settle=16.0)
        elif variant == "short" or variant.startswith("len"):
            pass        # below, whatever the order of the variants
        else:
            raise SystemExit(f"unknown variant {variant!r}")
    if "short" in variants.split("+"):
        # the same release in a channel 45 d tall, 20 s, the window from 8 s (about 24 d of
        # travel ending about 2.5 d above the bottom): a step study's scene
        run["kw"].update(length=45.0, duration=20.0, settle=8.0)
    for variant in variants.split("+"):
        if variant.startswith("len"):
            # the channel's length in diameters, the release still 3 d below its top: how
            # near the bottom the window may end (its clearance) without the bottom slowing it
            run["kw"]["length"] = float(variant[3:])
    return run


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--runs", nargs="+", default=["8", "12", "16"])
    ap.add_argument("--markdown-only", action="store_true")
    ap.add_argument("--tag", default="", help="write sedimentation<tag>.{json,md} (a study "
                    "beside the main one)")
    ap.add_argument("--held", nargs="+", default=None,
                    metavar="CELLS:STEP[:INTEGRATOR[:DENSITY]]",
                    help="instead: the disc held in its frame, Newton's third law "
                    "(sedimentation_held.{json,md})")
    ap.add_argument("--motion", nargs="+", default=None, metavar="CELLS:STEP[:INTEGRATOR]",
                    help="instead: C_D of the fixed, the held and the driven disc at one grid "
                    "and step (sedimentation_motion.{json,md})")
    ap.add_argument("--placement", nargs="+", default=None, metavar="CELLS:STEP[:INTEGRATOR]",
                    help="instead: the fixed disc's C_D at ten placements on the grid, a tenth "
                    "of a cell apart (sedimentation_placement.{json,md})")
    ap.add_argument("--grids", action="store_true",
                    help="instead: the grid sequence of the off-axis runs at the step 0.005 "
                    "(sedimentation_offaxis_grids.md, from the step studies' files)")
    args = ap.parse_args()
    if args.grids:
        (OUT / f"{STEM}_offaxis_grids.md").write_text(grid_sequence_markdown())
        return
    if args.held:
        held_study(args.held)
        return
    if args.motion:
        motion_study(args.motion)
        return
    if args.placement:
        placement_study(args.placement)
        return
    stem = f"{STEM}{args.tag}"
    path = OUT / f"{stem}.json"
    result = json.loads(path.read_text()) if path.exists() else {
        "benchmark": "Wachs (2009), rho_s / rho = 1.5", "runs": []}
    if not args.markdown_only:
        for spec in args.runs:
            run = parse_run(spec)
            text = case_text(run["cells"], run["integrator"], **run["kw"])
            scene = load_case_text(text, f"sedimentation_{spec}.toml")
            t0 = time.perf_counter()
            rec = FluidRun(scene, run["integrator"]).record()
            wall = time.perf_counter() - t0
            m = fluid_metrics(scene, rec)
            steps = rec.meta.get("dt") or {}
            row = {"run": spec, "cells_per_diameter": run["cells"], "variant": run["variant"],
                   "integrator": run["integrator"],
                   "grid": list(scene.fluid.resolution), "cfl": scene.fluid.cfl,
                   "dt_mean": steps.get("mean"), "dt_min": steps.get("min"),
                   "dt_max": steps.get("max"), "steps": steps.get("steps"),
                   "duration": scene.run.duration, "wall_s": wall, "failure": rec.failure,
                   "load": os.getloadavg()[0], "machine": platform.machine(),
                   **{k: m.get(k) for k in KEYS}}
            result["runs"] = [r for r in result["runs"] if r["run"] != spec] + [row]
            OUT.mkdir(parents=True, exist_ok=True)
            path.write_text(json.dumps(result, indent=2))
            (OUT / f"{stem}.md").write_text(markdown(result))
            print(json.dumps(row), flush=True)
    (OUT / f"{stem}.md").write_text(markdown(result))


GRID_SEQUENCE_RUN = "offset+short+dt0.005"   # the grid study's scene: the benchmark's release


def grid_sequence_markdown() -> str:
    """The release off the axis at the step 0.005 on every grid run (one study file per grid,
    ``sedimentation_offaxis_steps<cells>.json``) as one grid sequence: the speed on each grid,
    its change from the previous one, and Celik et al.'s three-grid procedure on every triple
    of neighbours (compare/grid_convergence.py): where their orders and limits agree, the grids
    are in the asymptotic range; where they do not, no one triple's limit can be trusted."""
    ref = wachs_sedimentation(1.5)
    u_ref = ref.reynolds * NU / D
    rows = []
    for path in sorted(OUT.glob(f"{STEM}_offaxis_steps*.json")):
        rows += [r for r in json.loads(path.read_text())["runs"]
                 if r["variant"] == GRID_SEQUENCE_RUN and not r.get("failure")
                 and r["terminal_velocity"] is not None]
    if len(rows) < 3:
        raise SystemExit(f"--grids: {len(rows)} finished `{GRID_SEQUENCE_RUN}` rows in "
                         f"{OUT}/{STEM}_offaxis_steps*.json; a grid sequence needs three")
    rows.sort(key=lambda r: r["cells_per_diameter"])
    lines = ["# The grid sequence of the disc settling against Wachs (2009)", "",
             "Written by `benchmarks/bench_sedimentation.py --grids` from the "
             f"`{GRID_SEQUENCE_RUN}` rows of `sedimentation_offaxis_steps<cells>.json` (released "
             "1 d off the axis as the benchmark is, in the 45 d channel, the window from 8 s; "
             "the largest step 0.005, cut by the CFL limit 1 where the flow is fast on the "
             "finest grids: the mean step taken is in the table; from 0.00667 or 0.0075 to 0.005 "
             "the speed moved by 0.01 % at 16 cells and 0.03 % at 32, by 0.24 % at 12). "
             "Published (one "
             f"public copy): U = {u_ref:.4f} (Re {ref.reynolds:g}).", "",
             "| d/dx | grid | mean step | U | against Wachs | change from the previous grid "
             "| change per unit of dx / d | wall (s) |", "|---|---|---|---|---|---|---|---|"]
    for i, r in enumerate(rows):
        u, cells = r["terminal_velocity"], r["cells_per_diameter"]
        change = per = "-"
        if i:
            prev = rows[i - 1]
            rel = u / prev["terminal_velocity"] - 1.0
            change = f"{rel:+.2%}"
            per = f"{rel / (1.0 / prev['cells_per_diameter'] - 1.0 / cells):+.0%}"
        lines.append(f"| {cells} | {r['grid'][0]}x{r['grid'][1]} | {_f(r['dt_mean'], '{:.4f}')} | "
                     f"{u:.4f} | {u / u_ref - 1:+.2%} | {change} | {per} | "
                     f"{r['wall_s']:.0f} |")
    triples = grid_sequence([1.0 / r["cells_per_diameter"] for r in rows],
                            [r["terminal_velocity"] for r in rows])
    lines += ["", "Every triple of neighbouring grids (Celik et al. 2008; no reference used: "
              "the order p and limit U0 of U0 + C h^p through the three, the limit against "
              "Wachs, and the grid convergence index of the finest of the three, Fs = 1.25):",
              "", "| grids (d/dx) | kind | apparent order | limit U0 | U0 against Wachs "
              "| GCI of the finest |", "|---|---|---|---|---|---|"]
    for t in triples:
        names = " / ".join(str(round(1.0 / h)) for h in reversed(t.h))
        lines.append(f"| {names} | {t.kind} | {_f(t.order, '{:.2f}')} | "
                     f"{_f(t.limit, '{:.4f}')} | "
                     f"{'-' if t.limit is None else f'{t.limit / u_ref - 1:+.2%}'} | "
                     f"{'-' if t.gci_fine is None else f'{t.gci_fine:.2%}'} |")
    return "\n".join(lines) + "\n"


def _f(x, fmt="{:.4g}"):
    return "-" if x is None else fmt.format(x)


def markdown(result: dict) -> str:
    ref = wachs_sedimentation(1.5)
    u_ref = ref.reynolds * NU / D
    lines = ["# Disc settling in a channel four diameters wide against Wachs (2009)", "",
             "Written by `benchmarks/bench_sedimentation.py`. Published (one public copy, "
             "reference/data/wachs2009_disc_channel_sedimentation.csv): Re "
             f"{ref.reynolds:g}, C_D {ref.drag_coefficient:g}, U = Re nu / d = {u_ref:.4f}. "
             "d = 1, w = 4, nu = 0.008088, g = 10, rho_s / rho = 1.5.", "",
             "| run | grid | d/dx | scheme | CFL | dt mean (min-max) | U | Re | C_D | U error "
             "| C_D error | unsteadiness | window travel (d) | clearance (d) "
             "| off axis max / mean (d) | wall (s) | load |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in result["runs"]:
        if r.get("failure"):
            lines.append(f"| {r['run']} | failed: {r['failure']} |")
            continue
        err = None if r["terminal_velocity"] is None else r["terminal_velocity"] / u_ref - 1.0
        cde = (None if r["drag_coefficient"] is None
               else r["drag_coefficient"] / ref.drag_coefficient - 1.0)
        lines.append(
            f"| {r['run']} | {r['grid'][0]}x{r['grid'][1]} | {r['cells_per_diameter']} | "
            f"{r['integrator']} | {r['cfl']:g} | {_f(r['dt_mean'], '{:.4f}')} "
            f"({_f(r['dt_min'], '{:.4f}')}-{_f(r['dt_max'], '{:.4f}')}) | "
            f"{_f(r['terminal_velocity'], '{:.4f}')} | {_f(r['terminal_reynolds'], '{:.1f}')} | "
            f"{_f(r['drag_coefficient'], '{:.4f}')} | {_f(err, '{:+.2%}')} | "
            f"{_f(cde, '{:+.2%}')} | {_f(r['terminal_velocity_unsteadiness'], '{:.2%}')} | "
            f"{_f(r['window_travel'], '{:.1f}')} | {_f(r['bottom_clearance'], '{:.1f}')} | "
            f"{_f(r['centreline_offset'], '{:.3f}')} / "
            f"{_f(r.get('centreline_offset_mean'), '{:.3f}')}"
            + _path_reference(r)
            + f" | {r['wall_s']:.0f} | {r['load']:.1f} |")
    lines += _convergence(result["runs"], u_ref)
    lines += _step_studies(result["runs"], u_ref)
    return "\n".join(lines) + "\n"


def _path_reference(r: dict) -> str:
    """Wachs's path over the run's stretch of the fall (fig. 5a: its largest and mean distance
    from the axis), for a run released as the benchmark is. Recorded by the metrics since
    2026-12-01; for earlier off-axis rows recomputed from what they stored, the stretch being
    exactly the release height less the final height (the clearance and half a diameter) and
    the window's travel: the release ``RELEASE_BELOW_TOP`` below the top of a channel
    ``grid[1] / cells`` tall (:func:`case_text`)."""
    ref = r.get("centreline_offset_reference")
    mean = r.get("centreline_offset_mean_reference")
    if ref is None and "offset" in r["variant"].split("+") and r.get("window_travel"):
        length = r["grid"][1] / r["cells_per_diameter"]
        fall_end = (length - RELEASE_BELOW_TOP * D) - (r["bottom_clearance"] + 0.5) * D
        got = wachs_path_offsets(RATIO, fall_end - r["window_travel"] * D, fall_end)
        ref, mean = got if got is not None else (None, None)
    return "" if ref is None else f" (Wachs {ref:.3f} / {mean:.3f})"


def _step_studies(runs: list[dict], u_ref: float) -> list[str]:
    """Per grid, the runs of one scene at several steps (the ``short`` off-axis release): the
    speed against the step and the line ``U0 + b dt`` through the steps of at most 0.16 dx by
    least squares (a first-order remainder in the step; its residual says how well a line
    holds)."""
    out = []
    groups: dict[tuple, list[dict]] = {}
    for r in runs:
        if r.get("failure") or r["terminal_velocity"] is None or "short" not in r["variant"]:
            continue
        scene = "+".join(v for v in r["variant"].split("+") if not v.startswith("dt"))
        groups.setdefault((r["cells_per_diameter"], scene), []).append(r)
    for (cells, scene), rows in sorted(groups.items()):
        if len(rows) < 2:
            continue
        # the steps taken: the CFL limit cuts the largest step where the flow is fast
        rows.sort(key=lambda r: -r["dt_mean"])
        dts = np.array([r["dt_mean"] for r in rows])
        us = np.array([r["terminal_velocity"] for r in rows])
        out += ["", f"Step study, d/dx {cells}, {scene}:", ""]
        out += [f"* dt {r['dt_max']:.5f}, {dt:.5f} on average ({dt * cells:.2f} dx): U {u:.4f}, "
                f"{u / u_ref - 1:+.2%} from the published value"
                for r, dt, u in zip(rows, dts, us, strict=True)]
        # the line through the steps of at most 0.16 dx (CFL 0.34 at the terminal speed): the
        # coarser ones lie off it (most of the change is between 0.24-0.32 dx and 0.12-0.16 dx)
        fine = dts * cells <= 0.16 + 1e-6
        if fine.sum() >= 3:
            b, u0 = np.polyfit(dts[fine], us[fine], 1)
            resid = float(np.max(np.abs(u0 + b * dts[fine] - us[fine])) / u_ref)
            out.append(f"* the line U0 + b dt through the steps of at most 0.16 dx: U0 {u0:.4f} "
                       f"({u0 / u_ref - 1:+.2%} from the published value), b {b:.3f}, largest "
                       f"residual {resid:.2%} of the published U")
    return out


def _step_family(dt_over_dx: float):
    """Runs released on the axis whose step is ``dt_over_dx`` times the cell size."""
    return lambda r: (r["variant"].startswith("dt") and "+" not in r["variant"]
                      and abs(float(r["variant"][2:]) * r["cells_per_diameter"]
                              - dt_over_dx) < 1e-3)


FAMILIES = {
    # the grid studies: one scheme, the step refined with the grid (dt = 0.16 dx, CFL 0.34 at
    # the terminal speed, and half that) on the axis; released off the axis the step is 0.02
    # or the CFL limit
    "released on the axis, dt = 0.16 dx": _step_family(0.16),
    "released on the axis, dt = 0.08 dx": _step_family(0.08),
    "released 1 d off the axis (the benchmark's release), dt <= 0.02":
        lambda r: r["variant"] == "offset",
}


def _convergence(runs: list[dict], u_ref: float) -> list[str]:
    """Per grid study: the change between successive grids, the observed order against the
    published U (the distance to the benchmark, not to the grid limit) and the Richardson limit
    of the three finest (which needs no reference)."""
    out = []
    for title, member in FAMILIES.items():
        rows = sorted((r for r in runs if member(r) and not r.get("failure")
                       and r["terminal_velocity"] is not None),
                      key=lambda r: r["cells_per_diameter"])
        if len(rows) < 2:
            continue
        out += ["", f"Convergence, {title}:", ""]
        for a, b in zip(rows, rows[1:], strict=False):
            ea = abs(a["terminal_velocity"] / u_ref - 1.0)
            eb = abs(b["terminal_velocity"] / u_ref - 1.0)
            ratio = b["cells_per_diameter"] / a["cells_per_diameter"]
            order = math.log(ea / eb) / math.log(ratio) if ea > 0 and eb > 0 else math.nan
            out.append(f"* d/dx {a['cells_per_diameter']} -> {b['cells_per_diameter']}: U "
                       f"{a['terminal_velocity']:.4f} -> {b['terminal_velocity']:.4f} "
                       f"(change {b['terminal_velocity'] / a['terminal_velocity'] - 1:+.2%}); "
                       f"|error| {ea:.2%} -> {eb:.2%}, observed order against the published "
                       f"value {order:.2f}")
        if len(rows) >= 3:
            last = rows[-3:]
            t = three_grids(tuple(1.0 / r["cells_per_diameter"] for r in reversed(last)),
                            tuple(r["terminal_velocity"] for r in reversed(last)))
            names = ", ".join(str(r["cells_per_diameter"]) for r in last)
            if t.kind != "monotone":
                out.append(f"* Richardson (d/dx {names}): the changes are not monotone, no "
                           "estimate")
            else:
                p, f0 = t.order, t.limit
                out.append(f"* Richardson (d/dx {names}): order {p:.2f}, U -> {f0:.4f}, Re "
                           f"{f0 * D / NU:.1f}, {f0 / u_ref - 1:+.2%} from the published value")
    return out


if __name__ == "__main__":
    main()
