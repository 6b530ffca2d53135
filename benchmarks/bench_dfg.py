"""The DFG benchmark (Schafer & Turek 1996) with the in-house cut-cell fluid: the grid
convergence of 2D-1 (steady, Re = 20) and the periodic 2D-2 (Re = 100).

    .venv/bin/python benchmarks/bench_dfg.py [--case 2d1|2d2] [--cells 10 20 30 40]
        [--rows 41 43 ...] [--duration S] [--integrator central] [--offset F] [--out DIR]
        [--length L] [--start-from STATE.npz] [--save-state STATE.npz] [--cfl C]
        [--force-window D0 D1]

2D-1 runs ``cases/fluid/dfg_2d1.toml`` with the grid refined to ``--cells`` cells across the
cylinder (the case file has 10), to ``--duration`` (default the case's 12 s, 24 convective
times), and measures the drag and lift coefficients and the front-back pressure difference with
the case's own metrics (``compare/fluid_metrics.py``). The observed order of each quantity is
``log(e_coarse / e_fine) / log(h_coarse / h_fine)`` between successive grids, e the difference
from the FEATFLOW reference value; the Richardson order of the three finest grids (the p that
makes ``f0 + C h^p`` pass through their three values) needs no reference at all.

2D-2 builds the same channel with U_max = 1.5 (Re = 100), runs ``--duration`` (default 10 s)
sampling every 5 ms, and measures the maximum drag and lift coefficients and the Strouhal
number over the second half (the shedding has settled by then; the case metrics' default).

``--rows N [N ...]`` runs the case at the published geometry on grids of N rows across the
0.41 m channel (dx = 0.41 / N, N / 4.1 cells across the cylinder, the channel's length rounded
to whole cells: 2.2 m within dx / 2, at the outflow 2 m downstream). The case's grids (N a
multiple of 41) put the cylinder's four extreme points on grid lines; other N cut it elsewhere,
so a family of nearby N measures how much of each number is where the grid cuts the cylinder
(the scatter about the trend) apart from the grid's size (the trend). Listed under "Where the
grid cuts the cylinder", with each family's mean and spread.

``--offset F`` moves the cylinder downstream by F cells. That is another scene, not another
grid: the cylinder's distance from the inflow (2 D to its centre) changes, and the numbers
depend on it (whole-cell moves, which cut the cylinder as the case's grid does, give the 2D-1
drag -1.1 % per centimetre downstream at 10 and at 20 cells across, the 2D-2 lift maximum
-6.5 % per centimetre at 10). Listed apart, under "The cylinder moved".

``--start-from`` and ``--save-state`` make the finer grids affordable. A run at 80 cells
across from rest would take some 10 hours here (its 10 s, of which the shedding needs about 5 to
settle); started instead from a coarser run's final state (``--save-state``), interpolated onto
the finer grid, it needs about 3 s. The periodic state is an attractor: the restarted run's
period maxima approach it geometrically (by a factor of about 0.55 a period, measured), and the
limit is read from the last three by Aitken's extrapolation beside the last maximum itself. The
lift maximum's limit after 3 s, restarted from the grid with half the cells across: 0.929533 at
20 cells and 0.969526 at 40, against 0.929529 and 0.969503 from rest in 10 s. ``--length L``
shortens the channel to L m (the outflow nearer the cylinder; the published 2.2 m by default),
which halves the cost again; at 1.1 m (9 D behind the cylinder) it raises the lift maximum by
0.04 % at 20 cells and 0.03 % at 40. A steady 2D-1 state restarts the same way: at 40 cells,
4 s from the 20-cell state, c_D and dp within 2e-7 of the 12 s run from rest and c_L within 1e-4
(it still rings: 4e-4 over the run's last tenth). Restarted and shortened runs are listed apart
from the case's own.

Each run is appended to ``benchmarks/results/dfg.json`` as it finishes (a long study survives a
stop), and ``dfg.md`` is written from everything in it. Run in the background at low priority:
the finest 2D-1 grid (40 cells, 880 x 164) takes of the order of an hour on the shared machine.
"""

from __future__ import annotations

import argparse
import dataclasses
import functools
import json
import math
import os
import platform
import time
from pathlib import Path

import numpy as np

from crosscheck.compare.fluid_metrics import fluid_metrics, force_coefficients, peak
from crosscheck.compare.grid_convergence import three_grids
from crosscheck.reference.fluid_data import dfg_reference
from crosscheck.scene.loader import load_case, load_case_text
from crosscheck.sim.fluid.run import FluidRun

ROOT = Path(__file__).resolve().parents[1]
CASE = ROOT / "cases" / "fluid" / "dfg_2d1.toml"
OUT = ROOT / "benchmarks" / "results"
ALIGNED_ROWS = 41            # rows across the channel at the case's grid (10 cells across D)
FAMILY_EDGES = (13.5, 17.5, 25.0, 35.0)    # cells/D: families near 10, 15, 20, 30 and 40
PUBLISHED_LENGTH = 2.2          # m, the DFG channel
FRONT_X, CENTRE_Y = 0.15, 0.2   # the published cylinder's front point and centre height (m)
QUANTITIES = {"2d1": ("drag_coefficient", "lift_coefficient", "pressure_difference"),
              "2d2": ("drag_coefficient_max", "lift_coefficient_max", "strouhal_number")}


def scene_for(case: str, cells: int | None, duration: float | None, offset: float = 0.0,
              rows: int | None = None, length: float | None = None, cfl: float | None = None,
              force_window: tuple[float, float] | None = None):
    """The DFG scene at ``cells`` cells across the cylinder (a multiple of 10: the case's grid
    refined), or on ``rows`` rows across the channel (any number: the published geometry, the
    channel's length rounded to whole cells); ``offset``: the cylinder moved downstream by that
    many cells (another scene: its distance from the inflow changes); ``length``: the channel
    cut to that length (m, rounded to whole cells; the outflow nearer the cylinder); ``cfl``
    and ``force_window`` replace the case's CFL number and the force's weighting ring (checks
    of the step and of the measurement)."""
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
    base_nx, base_ny = scene.fluid.resolution
    if rows is None:
        rows = round(base_ny * cells / 10)
    if rows % base_ny == 0:
        # the case's grid refined: the cylinder's extreme points stay on grid lines
        k = rows // base_ny
        fluid = dataclasses.replace(scene.fluid, resolution=(base_nx * k, rows))
    else:
        length, height = scene.fluid.domain
        dx = height / rows
        nx = round(length / dx)
        fluid = dataclasses.replace(scene.fluid, resolution=(nx, rows), domain=(nx * dx, height))
    if length is not None:
        nx = round(length / fluid.dx)
        fluid = dataclasses.replace(fluid, resolution=(nx, fluid.resolution[1]),
                                    domain=(nx * fluid.dx, fluid.domain[1]))
    if cfl is not None:
        fluid = dataclasses.replace(fluid, cfl=cfl, cfl_limit=max(fluid.cfl_limit, 2.0 * cfl))
    if force_window is not None:
        out = fluid.output
        fluid = dataclasses.replace(fluid, output=dataclasses.replace(
            out, forces=dataclasses.replace(out.forces, window=tuple(force_window))))
    if offset:
        # past the loader, which holds the case to the benchmark's geometry exactly
        ob = fluid.obstacles[0]
        moved = dataclasses.replace(ob, position=np.asarray(ob.position, float)
                                    + np.array([offset * fluid.dx, 0.0]))
        fluid = dataclasses.replace(fluid, obstacles=(moved,) + tuple(fluid.obstacles[1:]))
    run = scene.run if duration is None else dataclasses.replace(scene.run, duration=duration)
    return dataclasses.replace(scene, fluid=fluid, run=run)


def _face_grids(nx: int, ny: int, dx: float) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Where the MAC grid keeps u (vertical faces), v (horizontal faces) and p (centres)."""
    xc, yc = (np.arange(nx) + 0.5) * dx, (np.arange(ny) + 0.5) * dx
    return {"u": (np.arange(nx + 1) * dx, yc), "v": (xc, np.arange(ny + 1) * dx), "p": (xc, yc)}


def save_state(st, path: Path) -> None:
    """The fluid's velocity and pressure and its cell size, for ``start_from``."""
    np.savez(path, u=st.u, v=st.v, p=st.p, dx=st.dx)


def read_state(path: Path) -> dict:
    """A state written by ``save_state``, checked: ``u``, ``v``, ``p`` on one MAC grid and a
    positive ``dx`` (and ``file``, its name, for the run's entry); ValueError naming the file and
    what is wrong otherwise."""
    try:
        with np.load(path) as z:
            state = {k: np.asarray(z[k]) for k in ("u", "v", "p", "dx")}
    except (OSError, ValueError, KeyError, TypeError, AttributeError) as exc:
        raise ValueError(f"{path}: not a saved state (expected an .npz with u, v, p and dx, "
                         f"as --save-state writes): {exc}") from exc
    nx, ny = state["p"].shape if state["p"].ndim == 2 else (0, 0)
    if (nx < 2 or ny < 2 or state["u"].shape != (nx + 1, ny) or state["v"].shape != (nx, ny + 1)
            or not float(state["dx"]) > 0.0):
        raise ValueError(f"{path}: expected p (nx, ny), u (nx + 1, ny), v (nx, ny + 1) and dx > 0; "
                         f"got p {state['p'].shape}, u {state['u'].shape}, v {state['v'].shape}, "
                         f"dx {float(state['dx']):g}")
    state["file"] = path.name
    return state


def start_from(st, state: dict) -> None:
    """Set the fluid's velocity and pressure to a saved state (``read_state``) interpolated
    bilinearly onto this grid; the walls, the inflow and the cylinder's faces are imposed again,
    and the first projection makes the field divergence-free on this grid. Outside the saved
    grid (none here: the saved channel is as long or longer) the nearest values extend."""
    from scipy.interpolate import RegularGridInterpolator

    from crosscheck.sim.fluid.boundary import impose

    saved = _face_grids(*state["p"].shape, float(state["dx"]))
    here = _face_grids(st.nx, st.ny, st.dx)
    for name in ("u", "v", "p"):
        xs, ys = saved[name]
        at = RegularGridInterpolator((xs, ys), state[name])
        x, y = np.meshgrid(*here[name], indexing="ij")
        points = np.stack([np.clip(x, xs[0], xs[-1]), np.clip(y, ys[0], ys[-1])], -1)
        setattr(st, name, np.ascontiguousarray(at(points)))
    impose(st.u, st.v, st.ustate, st.vstate, st.boundary)


def period_maxima(t: np.ndarray, cd: np.ndarray, cl: np.ndarray) -> list[list[float]]:
    """[start time, lift maximum, drag maximum, lift minimum] of every whole lift period
    (between upward zero crossings of the lift about its mean over the run's second half),
    extrema refined by :func:`peak`. The minimum (the lift's other extreme, -1.0213 in the
    FEATFLOW reference series) says whether the whole cycle, not only its top, converges."""
    x = cl - cl[cl.shape[0] // 2:].mean()
    up = np.flatnonzero((x[:-1] < 0.0) & (x[1:] >= 0.0))
    return [[float(t[i]), peak(cl[i:j + 1]), peak(cd[i:j + 1]), -peak(-cl[i:j + 1])]
            for i, j in zip(up, up[1:], strict=False)]


def aitken(values: list[float]) -> float | None:
    """The limit of a geometrically converging sequence from its last three terms (Aitken's
    delta-squared); None when the last two changes do not shrink with one sign."""
    if len(values) < 3:
        return None
    a, b, c = values[-3:]
    d1, d2 = b - a, c - b
    if d1 == 0 or d2 / d1 <= 0 or d2 / d1 >= 1:
        return None
    return c - d2 * d2 / (d2 - d1)


def run_one(case: str, cells: int | None, duration: float | None, integrator: str,
            offset: float = 0.0, rows: int | None = None, length: float | None = None,
            start: dict | None = None, save: Path | None = None, cfl: float | None = None,
            force_window: tuple[float, float] | None = None) -> dict:
    """One run; ``start``: a saved state (``read_state``, read once for every grid) to start
    from instead of rest."""
    scene = scene_for(case, cells, duration, offset, rows, length, cfl, force_window)
    dx = scene.fluid.dx
    d = 2.0 * float(scene.fluid.obstacles[0].shape.radius)
    cells = cells if rows is None else round(d / dx, 4)
    run = FluidRun(scene, integrator)
    if start is not None:
        start_from(run.st, start)
    t0 = time.perf_counter()
    rec = run.record()
    wall = time.perf_counter() - t0
    saved = None
    if save is not None:
        try:
            save_state(run.st, save)
        except OSError as exc:     # the run is kept in dfg.json all the same
            saved = f"not saved: {exc}"
    m = rec.meta
    metrics = fluid_metrics(scene, rec) if rec.failure is None else {}
    entry = {
        "case": case, "cells_per_diameter": cells, "offset": offset,
        "length": scene.fluid.domain[0],
        "grid": list(scene.fluid.resolution), "dx": scene.fluid.dx,
        "duration": scene.run.duration, "integrator": integrator,
        "failure": rec.failure, "wall_s": wall, "steps": m["dt"]["steps"],
        "ms_per_step": m["ms_per_step"], "cg_iterations_mean": m["pressure_iterations"]["mean"],
        "pressure_solver": m["pressure_iterations"].get("solver", "mic0"),
        "metrics": metrics,
        "recorded": time.strftime("%Y-%m-%d %H:%M:%S"),
        "load_average": os.getloadavg()[0],
    }
    if start is not None:
        nx, ny = start["p"].shape
        entry["started_from"] = {"file": start["file"], "grid": [int(nx), int(ny)],
                                 "dx": float(start["dx"])}
    if saved is not None:
        entry["state"] = saved
        print(f"--save-state {save}: {saved}", flush=True)
    if cfl is not None:
        entry["cfl"] = cfl
    if force_window is not None:
        entry["force_window"] = list(force_window)
    if case == "2d2" and rec.failure is None:
        cd, cl = force_coefficients(scene, rec)
        entry["period_maxima"] = period_maxima(np.asarray(rec.t), cd, cl)
        entry["lift_max_aitken"] = aitken([p[1] for p in entry["period_maxima"]])
        entry["drag_max_aitken"] = aitken([p[2] for p in entry["period_maxima"]])
        entry["lift_min_aitken"] = aitken([p[3] for p in entry["period_maxima"]])
    return entry


@functools.cache
def _target(case: str, q: str) -> float:
    """The value a quantity's error is read against: the reference table's precise value (for
    2D-2 FEATFLOW's reference computation since 2026-12-01), else the interval's centre."""
    return dfg_reference("2D-1" if case == "2d1" else "2D-2")[0][q].target


def run_error(r: dict, q: str) -> float | None:
    """A run's relative error in ``q`` against the table's current target, recomputed from the
    stored value (rows recorded before 2026-12-01 stored their 2D-2 errors against the 1996
    interval's centre)."""
    v = r["metrics"].get(q)
    if v is None or not math.isfinite(v):
        return v
    t = _target(r["case"], q)
    return abs(v - t) / abs(t)


def observed_orders(runs: list[dict], case: str) -> list[dict]:
    """Orders between successive grids, from the error against the reference target."""
    out = []
    runs = sorted(runs, key=lambda r: r["cells_per_diameter"])
    for a, b in zip(runs, runs[1:], strict=False):
        row = {"from": a["cells_per_diameter"], "to": b["cells_per_diameter"]}
        for q in QUANTITIES[case]:
            ea = run_error(a, q)
            eb = run_error(b, q)
            ok = ea and eb and math.isfinite(ea) and math.isfinite(eb) and ea > 0 and eb > 0
            row[q] = (math.log(ea / eb) / math.log(b["cells_per_diameter"]
                                                   / a["cells_per_diameter"])) if ok else None
        out.append(row)
    return out


def richardson(runs: list[dict], case: str) -> dict:
    """Order and extrapolated value from the three finest grids (no reference needed):
    ``f(h) = f0 + C h^p`` through the three points (compare/grid_convergence.py); None for a
    quantity whose differences do not shrink monotonically."""
    runs = sorted(runs, key=lambda r: r["cells_per_diameter"])[-3:]
    if len(runs) < 3:
        return {}
    h = tuple(1.0 / r["cells_per_diameter"] for r in reversed(runs))   # finest first
    res = {"grids": [r["cells_per_diameter"] for r in runs]}
    for q in QUANTITIES[case]:
        f = tuple(r["metrics"].get(q) for r in reversed(runs))
        t = None if None in f else three_grids(h, f)
        res[q] = ({"order": t.order, "extrapolated": t.limit}
                  if t is not None and t.kind == "monotone" else None)
    return res


def _in_cell(x: float) -> float:
    """Where ``x`` (in cells) falls in its cell, 0 to 1; a grid line read as 0, not as 0.99999
    (0.15 m / (0.41 m / 123) is 45 less a rounding error)."""
    return round(x, 9) % 1.0


def _family_lines(placed: list[dict], qs: tuple[str, ...]) -> list[str]:
    """The runs at the published geometry in families of nearby cell sizes (edges at
    ``FAMILY_EDGES`` cells across the cylinder): each family's runs, then its mean, spread
    (standard deviation over the mean) and range, for families with runs on grids other than
    the case's."""
    bands: dict[int, list[dict]] = {}
    for r in placed:
        bands.setdefault(sum(r["cells_per_diameter"] >= e for e in FAMILY_EDGES), []).append(r)
    bands = {b: rs for b, rs in bands.items()
             if len(rs) > 1 and any(r["grid"][1] % ALIGNED_ROWS for r in rs)}
    if not bands:
        return []
    lines = ["Where the grid cuts the cylinder (`--rows N`: the published geometry on N rows "
             "across the channel; the case's grids, N a multiple of 41, have the cylinder's "
             "extreme points on grid lines, other N cut it elsewhere; `front` is where the "
             "cylinder's front point falls in its cell, `centre y` where its centre's height "
             "falls, in cells):", "",
             "| rows | cells/D | front | centre y | " + " | ".join(qs) + " |",
             "|---" * (len(qs) + 4) + "|"]
    for b in sorted(bands):
        rs = sorted(bands[b], key=lambda r: r["grid"][1])
        for r in rs:
            dx = r["dx"]
            lines.append(f"| {r['grid'][1]} | {r['cells_per_diameter']:.2f} | "
                         f"{_in_cell(FRONT_X / dx):.2f} | {_in_cell(CENTRE_Y / dx):.2f} | "
                         + " | ".join("-" if r["metrics"].get(q) is None
                                      else f"{r['metrics'][q]:.5g}" for q in qs) + " |")
        stats = []
        for q in qs:
            v = np.array([r["metrics"][q] for r in rs if r["metrics"].get(q) is not None])
            stats.append(f"{v.mean():.5g} ± {100 * v.std() / abs(v.mean()):.2g} % "
                         f"({v.min():.5g} to {v.max():.5g})" if v.size else "-")
        cells = [r["cells_per_diameter"] for r in rs]
        lines.append(f"| **{len(rs)} grids** | {min(cells):.1f} to {max(cells):.1f} | | | "
                     + " | ".join(stats) + " |")
    lines += ["", "Each family's last row: mean ± standard deviation over the mean (range).",
              ""]
    return lines + _pattern_lines(placed, qs)


def _pattern_lines(placed: list[dict], qs: tuple[str, ...]) -> list[str]:
    """N and N + 41 rows cut the cylinder in the same pattern at cell sizes in the ratio 2 : 1
    (the grid is 41 rows per 10 cells across it). For every pattern run at both sizes (N from
    42 to 52), its difference from the case's grid at the same size; the RMS over the patterns at
    each size and the order at which it falls."""
    by_rows = {r["grid"][1]: r for r in placed}
    a, b = ALIGNED_ROWS, 2 * ALIGNED_ROWS
    pats = [n for n in range(a + 1, b) if n in by_rows and n + a in by_rows]
    if a not in by_rows or b not in by_rows or len(pats) < 2:
        return []
    out = []
    for q in qs:
        d1 = [by_rows[n]["metrics"][q] - by_rows[a]["metrics"][q] for n in pats]
        d2 = [by_rows[n + a]["metrics"][q] - by_rows[b]["metrics"][q] for n in pats]
        r1, r2 = (math.sqrt(sum(x * x for x in d) / len(d)) for d in (d1, d2))
        out.append(f"{q} {r1:.3g} -> {r2:.3g} (order {math.log2(r1 / r2):.2f})"
                   if r1 > 0 and r2 > 0 else f"{q} -")
    return [f"The same cut at two cell sizes ({len(pats)} patterns: rows "
            f"{', '.join(map(str, pats))} and {', '.join(str(n + a) for n in pats)}): "
            "RMS of the difference from the case's grid at the same size, at 10 and at 20 "
            "cells across: " + "; ".join(out) + ".", ""]


def write_markdown(data: dict, path: Path) -> None:
    lines = ["# DFG benchmark: channel flow past a cylinder (in-house cut-cell fluid)", "",
             "Schafer & Turek (1996); reference intervals and the FEATFLOW 2D-1 values in "
             "`src/crosscheck/reference/data/schafer_turek1996_cylinder.csv`. Produced by "
             "`benchmarks/bench_dfg.py`; each row is one run of the case at that grid "
             "(`cells` across the cylinder of diameter D = 0.1 m; the case file's grid is 10). "
             f"Machine: {data.get('machine', '?')}, 2 cores shared with other work (wall "
             "times are indicative only).", ""]
    for case, title in (("2d1", "2D-1, Re = 20, steady"), ("2d2", "2D-2, Re = 100, periodic")):
        placed = [r for r in data["runs"] if r["case"] == case and not r.get("offset", 0.0)
                  and not _restarted_or_short(r)]
        runs = sorted((r for r in placed if r["grid"][1] % ALIGNED_ROWS == 0),
                      key=lambda r: r["cells_per_diameter"])
        if not runs:
            continue
        moved = sorted((r for r in data["runs"] if r["case"] == case and r.get("offset", 0.0)
                        and not _restarted_or_short(r)),
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
                v, e = m.get(q), run_error(r, q)
                inside = m.get(f"{q}_interval_miss") == 0.0
                cells.append("-" if v is None else
                             f"{v:.5g} ({100 * e:.2f} %{', in' if inside else ''})")
            lines.append(f"| {r['cells_per_diameter']} | {r['grid'][0]} x {r['grid'][1]} | "
                         + " | ".join(cells)
                         + f" | {r['steps']} | {r['ms_per_step']:.1f} | "
                         f"{r['cg_iterations_mean']:.0f}"
                         f"{' (amg)' if r.get('pressure_solver') == 'amg' else ''} | "
                         f"{r['wall_s']:.0f} |")
        lines += ["", "Published: " + ", ".join(
            f"{q} {refs[q].lower:g}-{refs[q].upper:g}"
            + ("" if refs[q].reference is None else f" (reference {refs[q].reference:.10g})")
            for q in qs) + ". Errors are relative to the reference value (2D-1: the FEATFLOW "
            "page's; 2D-2: FEATFLOW's reference computation, Q2 on level 6, dt 1/1600, read from "
            "its force series by `benchmarks/featflow_reference.py`; its lift maximum lies below "
            "the 1996 interval); ', in' marks a value inside the published interval.", ""]
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
        lines += _family_lines(placed, qs)
        if moved:
            lines += ["The cylinder moved (`--offset f`: downstream by f cells, f dx). This is "
                      "another scene, not another grid: the cylinder's distance from the inflow "
                      "changes, and whole-cell moves (which cut the cylinder as the case's grid "
                      "does) show how much the numbers depend on it:", "",
                      "| cells/D | offset (cells) | moved (mm) | " + " | ".join(qs) + " |",
                      "|---" * (len(qs) + 3) + "|"]
            for r in moved:
                lines.append(f"| {r['cells_per_diameter']} | {r['offset']:g} | "
                             f"{1000 * r['offset'] * r['dx']:.2f} | "
                             + " | ".join("-" if r["metrics"].get(q) is None
                                          else f"{r['metrics'][q]:.5g}" for q in qs) + " |")
            lines.append("")
        lines += (_restart_lines(data["runs"], runs) if case == "2d2"
                  else _steady_restart_lines(data["runs"], runs))
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


def _restarted_or_short(r: dict) -> bool:
    """A run off the case's own protocol: restarted, in a shortened channel, or with another
    step or force ring."""
    return ("started_from" in r or abs(_length(r) - PUBLISHED_LENGTH) > r["dx"]
            or "cfl" in r or "force_window" in r)


def _length(r: dict) -> float:
    """The run's channel length (runs recorded before ``--length`` existed have the published
    one, some of them as null)."""
    return r.get("length") or PUBLISHED_LENGTH


def _restarted_runs(all_runs: list[dict], case: str) -> list[dict]:
    """The case's runs restarted, shortened or otherwise varied (not moved), by grid, the full
    channel first."""
    return sorted((r for r in all_runs if r["case"] == case and _restarted_or_short(r)
                   and not r.get("offset", 0.0)),
                  key=lambda r: (r["cells_per_diameter"], -_length(r)))


def _restart_lines(all_runs: list[dict], case_runs: list[dict]) -> list[str]:
    """The 2D-2 runs restarted from a coarser state or in a shortened channel: the maxima over
    the second half of the run, the last period's maxima and their Aitken limits, beside the
    case's run on the same grid where there is one."""
    rs = _restarted_runs(all_runs, "2d2")
    if not rs:
        return []
    full = {r["cells_per_diameter"]: r for r in case_runs}
    lines = ["Finer grids restarted from a coarser run's final state (`--start-from`), some in a "
             "channel cut short (`--length`): the lift and drag maxima of each whole period "
             "approach the periodic state geometrically; `last` is the last period's maximum, "
             "`limit` the Aitken extrapolation of the last three (see the module's docstring), "
             "`change` the last period's change. The case's own run on the same grid (from rest, "
             "10 s, full channel) where there is one:", "",
             "| cells/D | channel (m) | grid | from | run (s) | periods | c_L max last | change "
             "| c_L max limit (vs reference) | c_D max last | c_D max limit (vs reference) | St "
             "(vs reference) | c_L min limit | case's run c_L max | ms/step | wall s |",
             "|---" * 16 + "|"]
    for r in rs:
        pm = r.get("period_maxima") or [[0.0, math.nan, math.nan]] * 2
        last_l, last_d = pm[-1][1], pm[-1][2]
        change = pm[-1][1] - pm[-2][1] if len(pm) > 1 else math.nan
        lim_l, lim_d = r.get("lift_max_aitken"), r.get("drag_max_aitken")
        # the lift minimum: recorded since 2026-12-01 (the 4th entry of each period)
        lim_m = r.get("lift_min_aitken")
        own = full.get(r["cells_per_diameter"])
        lines.append(
            f"| {r['cells_per_diameter']} | {_length(r):.3g} | {r['grid'][0]} x {r['grid'][1]} "
            f"| {_origin(r)} | {r['duration']:g} | {len(pm)} | {last_l:.5f} | {change:+.1e} | "
            + _vs_reference(lim_l, "lift_coefficient_max") + f" | {last_d:.5f} | "
            + _vs_reference(lim_d, "drag_coefficient_max")
            + " | " + _vs_reference(r["metrics"].get("strouhal_number"), "strouhal_number", 4)
            + " | " + ("-" if lim_m is None else f"{lim_m:.5f}") + " | "
            + ("-" if own is None else f"{own['metrics']['lift_coefficient_max']:.5f}")
            + f" | {r['ms_per_step']:.0f} | {r['wall_s']:.0f} |")
    ref = dfg_reference("2D-2")[0]
    lines += ["", "Reference (FEATFLOW's computation, Q2 on level 6, dt 1/1600; the reference "
              f"table): c_L max {ref['lift_coefficient_max'].target:g}, c_D max "
              f"{ref['drag_coefficient_max'].target:g}, St {ref['strouhal_number'].target:g}, "
              "c_L min -1.02129 (`benchmarks/featflow_reference.py`)."]
    return lines + [""]


def _vs_reference(v: float | None, q: str, digits: int = 5) -> str:
    """A 2D-2 value and its relative difference from the reference computation's."""
    if v is None or not math.isfinite(v):
        return "-"
    t = _target("2d2", q)
    return f"{v:.{digits}f} ({100 * (v - t) / t:+.2f} %)"


def _fmt(v: float | None, spec: str) -> str:
    """A number, or "-" where none was measured (a run too short for three lift periods)."""
    return "-" if v is None or not math.isfinite(v) else format(v, spec)


def _origin(r: dict) -> str:
    """Where a restarted run started (the saved grid, or rest) and what else it changed."""
    src = r.get("started_from")
    out = "rest" if src is None else f"{src['grid'][0]} x {src['grid'][1]}"
    if "cfl" in r:
        out += f", CFL {r['cfl']:g}"
    if "force_window" in r:
        out += ", force ring {:g}-{:g} m".format(*r["force_window"])
    return out


def _steady_restart_lines(all_runs: list[dict], case_runs: list[dict]) -> list[str]:
    """The 2D-1 runs restarted from a coarser state or in a shortened channel, beside the case's
    run on the same grid where there is one (from rest, 12 s, full channel)."""
    rs = _restarted_runs(all_runs, "2d1")
    if not rs:
        return []
    full = {r["cells_per_diameter"]: r for r in case_runs}
    qs = QUANTITIES["2d1"]
    lines = ["Finer grids restarted from a coarser run's final state (`--start-from`), some in a "
             "channel cut short (`--length`), with the case's own run on the same grid (from "
             "rest, 12 s, full channel) where there is one; `drift`: the relative change of c_D "
             "and c_L over the run's last tenth:", "",
             "| cells/D | channel (m) | grid | from | run (s) | " + " | ".join(qs)
             + " | drift c_D / c_L | case's run | ms/step | wall s |", "|---" * (len(qs) + 9) + "|"]
    for r in rs:
        m = r["metrics"]
        own = full.get(r["cells_per_diameter"])
        vals = []
        for q in qs:
            v = m.get(q)
            inside = m.get(f"{q}_interval_miss") == 0.0
            vals.append("-" if v is None else f"{v:.5g}{' (in)' if inside else ''}")
        lines.append(
            f"| {r['cells_per_diameter']} | {_length(r):.3g} | {r['grid'][0]} x {r['grid'][1]} "
            f"| {_origin(r)} | {r['duration']:g} | " + " | ".join(vals)
            + f" | {m.get('drag_coefficient_drift', math.nan):.1e} / "
            f"{m.get('lift_coefficient_drift', math.nan):.1e} | "
            + ("-" if own is None else " / ".join(f"{own['metrics'][q]:.5g}" for q in qs))
            + f" | {r['ms_per_step']:.0f} | {r['wall_s']:.0f} |")
    return lines + [""]


def _key(r: dict) -> tuple:
    src = r.get("started_from")
    return (r["case"], r["grid"][1], r.get("offset", 0.0), round(_length(r), 6),
            None if src is None else tuple(src["grid"]), r.get("cfl"),
            tuple(r.get("force_window") or ()))


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--case", choices=("2d1", "2d2"), default="2d1")
    ap.add_argument("--cells", type=int, nargs="+", default=None,
                    help="cells across the cylinder (multiples of 10); default 10 20 30 40 "
                         "(2D-1) or 10 20 (2D-2)")
    ap.add_argument("--rows", type=int, nargs="+", default=None,
                    help="rows across the channel instead (any number; 41 per 10 cells across "
                         "the cylinder): where the grid cuts the cylinder")
    ap.add_argument("--duration", type=float, default=None)
    ap.add_argument("--integrator", default="central")
    ap.add_argument("--offset", type=float, default=0.0,
                    help="move the cylinder downstream by this many cells (another scene: its "
                         "distance from the inflow changes)")
    ap.add_argument("--length", type=float, default=None,
                    help="channel length in m (default the published 2.2): the outflow nearer "
                         "the cylinder")
    ap.add_argument("--start-from", type=Path, default=None,
                    help="start from this saved state (--save-state of a coarser run), "
                         "interpolated onto the grid, instead of from rest")
    ap.add_argument("--save-state", type=Path, default=None,
                    help="save the run's final velocity and pressure here (.npz)")
    ap.add_argument("--cfl", type=float, default=None,
                    help="the CFL number instead of the case's 0.5 (a check of the step)")
    ap.add_argument("--force-window", type=float, nargs=2, default=None, metavar=("D0", "D1"),
                    help="the force's weighting ring, m from the surface, instead of the "
                         "default 0.025-0.1 (a check of the measurement)")
    ap.add_argument("--out", type=Path, default=OUT)
    ap.add_argument("--report", action="store_true",
                    help="only rewrite dfg.md from dfg.json (no runs)")
    args = ap.parse_args()
    if args.rows:
        for n in args.rows:
            if n < 4:
                raise SystemExit(f"--rows {n}: at least 4 rows across the channel (the fluid "
                                 "grid's minimum per axis)")
        grids = [(None, n) for n in args.rows]
    else:
        cells = args.cells or ([10, 20, 30, 40] if args.case == "2d1" else [10, 20])
        for c in cells:
            if c % 10:
                raise SystemExit(f"--cells {c}: the DFG grid needs a multiple of 10 cells across "
                                 "D (--rows for other grids)")
        grids = [(c, None) for c in cells]
    start = None
    if args.start_from is not None:
        if not args.start_from.is_file():
            raise SystemExit(f"--start-from {args.start_from}: no such file (write one with "
                             "--save-state)")
        try:
            start = read_state(args.start_from)
        except ValueError as exc:
            raise SystemExit(f"--start-from: {exc}") from exc
    if args.save_state is not None and not args.save_state.parent.is_dir():
        # checked before the run: a missing directory would lose an hour's run at its end
        raise SystemExit(f"--save-state {args.save_state}: no directory "
                         f"{args.save_state.parent} to write it in")
    if args.length is not None and not 0.5 <= args.length <= PUBLISHED_LENGTH:
        raise SystemExit(f"--length {args.length}: expected 0.5 to {PUBLISHED_LENGTH} m (the "
                         "cylinder's wake needs the channel to reach 3 D behind it)")
    if args.cfl is not None and not 0.0 < args.cfl <= 1.0:
        raise SystemExit(f"--cfl {args.cfl}: expected a number in (0, 1] (the central scheme's "
                         "Adams-Bashforth 2 is run at 0.5)")
    if args.force_window is not None and not 0.0 <= args.force_window[0] < args.force_window[1]:
        raise SystemExit(f"--force-window {args.force_window}: expected D0 D1 with "
                         "0 <= D0 < D1 (m from the cylinder's surface)")
    if args.save_state is not None and len(grids) > 1:
        raise SystemExit("--save-state: one grid at a time (the file holds one state)")
    args.out.mkdir(parents=True, exist_ok=True)
    jpath = args.out / "dfg.json"
    data = json.loads(jpath.read_text()) if jpath.exists() else {"runs": []}
    data["machine"] = f"{platform.processor() or platform.machine()}, {os.cpu_count()} cpus"
    if args.report:
        write_markdown(data, args.out / "dfg.md")
        return
    for c, rows in grids:
        entry = run_one(args.case, c, args.duration, args.integrator, args.offset, rows,
                        args.length, start, args.save_state, args.cfl,
                        tuple(args.force_window) if args.force_window else None)
        # read again: another study may have added its runs meanwhile
        data = json.loads(jpath.read_text()) if jpath.exists() else {"runs": []}
        data["machine"] = f"{platform.processor() or platform.machine()}, {os.cpu_count()} cpus"
        data["runs"] = [r for r in data["runs"] if _key(r) != _key(entry)] + [entry]
        jpath.write_text(json.dumps(data, indent=1))
        write_markdown(data, args.out / "dfg.md")
        print(json.dumps({k: entry[k] for k in ("case", "cells_per_diameter", "wall_s")}),
              {q: entry["metrics"].get(q) for q in QUANTITIES[args.case]}, flush=True)


if __name__ == "__main__":
    main()
