"""Pymunk contact through crosscheck's own adapter: Chipmunk's defaults against the adapter's.

    PYTHONPATH=src .venv/bin/python benchmarks/contact_pymunk.py [--dt 1e-3 1e-4] [--quick]
                                                                [--out benchmarks/results]

Every scene is a 2D case written here as TOML, loaded by crosscheck's loader and run by the
Pymunk adapter through the one run driver (``engine.run``), exactly as a case file would be. Two
settings rows per step size:

* ``defaults``: Chipmunk's own contact settings, pinned through ``[engine_options.pymunk]``:
  ``collision_slop = 0.1``, ``iterations = 10`` (collision_bias is never changed). The pair
  values are the adapter's (the collision handler) in both rows, so the rows differ only in the
  solver settings.
* ``adapter``: what the adapter sets for contact: slop 1e-5, iterations 50, or 100 when the
  largest body mass ratio is >= 100.

Scenes (y up; g = 9.81; disks r = 0.1 m, m = 1 kg, so a disk's moment is m r^2 / 2 as the shape
gives it: a 2D disk, not a sphere (CONTACTS.md C16 is about standing in for a sphere)). Bodies
that rest on something start overlapping it by 1 um, less than the slop: a gap of exactly 0
makes no contact in Chipmunk (C17) and the adapter would warn.

* ``drop e=0`` / ``e=0.5`` / ``e=1``: a disk 1 m above the ground (the gap), pair restitution e,
  3 s. Apexes: the largest gap between two impacts (ideal e^(2k) m); resting depth: r - y at the
  end (e = 0), and the largest rebound after the first impact.
* ``slide``: a 0.2 m box at 2 m/s on the ground, pair friction 0.3 (materials 0.8 and 0.1:
  product 0.08, geometric mean 0.28: only the pair override gives 0.3), 1.5 s. Stop distance
  (where |v| first falls below 1 mm/s) against v^2 / (2 mu g) = 0.6796 m; Pymunk's
  position-first step adds v0 dt / 2.
* ``roll mu=1`` / ``roll mu=0.1``: a disk on flat ground under gravity tilted 30 degrees
  (g (sin, -cos)), 1 s. Rolling (mu >= tan(30)/3 = 0.19 for a disk): a = 2/3 g sin;
  slipping: a = g (sin - mu cos), alpha = 2 mu g cos / r. Errors of v and omega at 1 s.
* ``incline 20`` / ``incline 35``: a 0.2 m box, friction 0.5, tilted gravity, 2 s. At 20 degrees
  (tan 0.364 < 0.5) it must not move: drift in mm. At 35 degrees it slides:
  mu_eff = (g sin - 2 d / T^2) / (g cos) against 0.5.
* ``stack 10``: ten 1 m cubes of 1 kg, friction 0.5, 5 s at rest: top-box drift and total sink.
* ``pyramid``: 4-3-2-1 unit cubes, 0.1 m apart in each row, friction 0.5, 5 s: the largest
  drift of any box and the sink of the top one.
* ``cradle gap``: three disks, e = 1, mu = 0, no gravity, 1 mm gaps, disk 1 at 1 m/s, 0.5 s:
  final velocities (ideal 0, 0, 1). ``cradle touching``: the same with gaps of exactly 0 (C17:
  Chipmunk gives 0, 0, 1 where an LCP gives -1/3, 2/3, 2/3) and with 1e-9 m overlaps.
* ``mass 100:1``: a 100 kg 0.2 m box on a 1 kg one on the ground, friction 0.5, 5 s:
  box/box and box/ground penetration, top-box drift.

Wall time: the accuracy pass of each run (recording included, pair handlers included), per
simulated second. Writes ``benchmarks/results/contact_pymunk.md`` and ``.json``.
"""

from __future__ import annotations

import argparse
import json
import math
import platform
import time
from pathlib import Path

import numpy as np

from crosscheck.engines import get_engine
from crosscheck.scene.loader import load_case_text

ROOT = Path(__file__).resolve().parents[1]
G = 9.81
R = 0.1
EPS = 1e-6  # initial overlap of resting bodies (below the adapter's slop)
ROWS = {"defaults": "collision_slop = 0.1\niterations = 10", "adapter": ""}


def case(name, duration, dt, sample, body_text, gravity=(0.0, -G), ground=True, extra="",
         options=""):
    text = f"""
[case]
name = "{name}"
dimension = 2
[run]
duration = {duration!r}
dt = {dt!r}
sample_every = {sample!r}
[effects]
contact = true
{"" if gravity is None else f"gravity = [{gravity[0]!r}, {gravity[1]!r}]"}
{"[ground]" if ground else ""}
{"material = { friction = 0.1, restitution = 0.0 }" if ground else ""}
{extra}
{body_text}
"""
    if options:
        text += f"\n[engine_options.pymunk]\n{options}\n"
    return load_case_text(text)


def body(name, shape, position, *, mass=1.0, velocity=(0.0, 0.0), friction=0.8,
         restitution=0.0):
    return f"""
[[bodies]]
name = "{name}"
shape = {{ {shape} }}
mass = {mass!r}
position = [{position[0]!r}, {position[1]!r}]
velocity = [{velocity[0]!r}, {velocity[1]!r}]
material = {{ friction = {friction!r}, restitution = {restitution!r} }}
"""


def pair(a, b, **values):
    items = "\n".join(f"{k} = {v!r}" for k, v in values.items())
    return f"\n[[contact_pairs]]\na = \"{a}\"\nb = \"{b}\"\n{items}\n"


def run(scene, dt):
    t0 = time.perf_counter()
    traj = get_engine("pymunk").run(scene, "position_first", dt)
    wall = time.perf_counter() - t0
    if traj.failure is not None:
        raise RuntimeError(f"{scene.name}: {traj.failure}")
    return traj, wall / scene.run.duration


# -- scenes --------------------------------------------------------------------------------------
def drop(e, dt, options):
    scene = case(f"drop-e{e}", 3.0, dt, dt, body("disk", f"circle = {{ radius = {R} }}",
                                                  (0.0, R + 1.0))
                 + pair("disk", "ground", restitution=e, friction=0.5), options=options)
    traj, cost = run(scene, dt)
    gap = traj.com[:, 0, 1] - R
    vy = traj.vel[:, 0, 1]
    up = np.nonzero((vy[:-1] > 0) & (vy[1:] <= 0))[0]  # the last rising sample of each flight
    apexes = [float(gap[i:i + 2].max()) for i in up][:3]
    first = int(np.argmax(gap < 0))
    out = {"apexes": apexes, "rest_depth_mm": -1e3 * float(gap[-1]),
           "max_depth_mm": -1e3 * float(gap.min()),
           "rebound_mm": 1e3 * float(max(0.0, gap[first:].max())), "wall_per_s": cost}
    return out, traj


def slide(dt, options):
    mu, v0 = 0.3, 2.0
    scene = case("slide", 1.5, dt, dt, body("box", "box = { size = [0.2, 0.2] }",
                                            (0.0, 0.1 - EPS), velocity=(v0, 0.0), friction=0.8)
                 + pair("box", "ground", friction=mu), options=options)
    traj, cost = run(scene, dt)
    speed = np.linalg.norm(traj.vel[:, 0], axis=1)
    i = int(np.argmax(speed < 1e-3))
    d = float(traj.com[i, 0, 0] - traj.com[0, 0, 0])
    ideal = v0**2 / (2 * mu * G)
    return {"distance": d, "error": d / ideal - 1.0,
            "discrete_error": d / (ideal + v0 * dt / 2) - 1.0, "stop_time": float(traj.t[i]),
            "ideal_time": v0 / (mu * G), "hop_mm": 1e3 * float(np.max(traj.com[:, 0, 1]) - 0.1),
            "wall_per_s": cost}, traj


def roll(mu, dt, options):
    th = math.radians(30.0)
    g = (G * math.sin(th), -G * math.cos(th))
    scene = case(f"roll-mu{mu}", 1.0, dt, 0.01, body("disk", f"circle = {{ radius = {R} }}",
                                                     (0.0, R - EPS))
                 + pair("disk", "ground", friction=mu), gravity=g, options=options)
    traj, cost = run(scene, dt)
    T = 1.0
    if mu >= math.tan(th) / 3:
        a = 2.0 / 3.0 * G * math.sin(th)
        v, w = a * T, -a * T / R
    else:
        v = G * (math.sin(th) - mu * math.cos(th)) * T
        w = -2 * mu * G * math.cos(th) / R * T
    vx, om = float(traj.vel[-1, 0, 0]), float(traj.omega[-1, 0])
    return {"v": vx, "v_error": vx / v - 1, "omega": om, "omega_error": om / w - 1,
            "slip": vx + om * R, "ideal_slip": v + w * R, "wall_per_s": cost}, traj


def incline(deg, dt, options):
    th = math.radians(deg)
    g = (G * math.sin(th), -G * math.cos(th))
    scene = case(f"incline-{deg}", 2.0, dt, 0.01, body("box", "box = { size = [0.2, 0.2] }",
                                                       (0.0, 0.1 - EPS))
                 + pair("box", "ground", friction=0.5), gravity=g, options=options)
    traj, cost = run(scene, dt)
    d = float(traj.com[-1, 0, 0] - traj.com[0, 0, 0])
    T = 2.0
    mu_eff = (G * math.sin(th) - 2 * d / T**2) / (G * math.cos(th))
    return {"drift_mm": 1e3 * d, "mu_eff": mu_eff, "wall_per_s": cost}, traj


def stack(dt, options):
    n = 10
    text = "".join(body(f"b{i}", "box = { size = [1.0, 1.0] }", (0.0, 0.5 + i * (1.0 - EPS)),
                        friction=0.5) for i in range(n))
    text += pair("b0", "ground", friction=0.5)
    scene = case("stack10", 5.0, dt, 0.05, text, options=options)
    traj, cost = run(scene, dt)
    top = traj.com[:, -1]
    return {"drift_mm": 1e3 * float(np.max(np.abs(top[:, 0] - top[0, 0]))),
            "sink_mm": 1e3 * float(0.5 + (n - 1) - top[-1, 1]), "wall_per_s": cost}, traj


def pyramid(dt, options):
    text, k = "", 0
    for row, count in enumerate((4, 3, 2, 1)):
        for j in range(count):
            x = (j - (count - 1) / 2) * 1.1
            text += body(f"b{k}", "box = { size = [1.0, 1.0] }",
                         (x, 0.5 + row * (1.0 - EPS)), friction=0.5)
            k += 1
    text += "".join(pair(f"b{i}", "ground", friction=0.5) for i in range(4))
    scene = case("pyramid", 5.0, dt, 0.05, text, options=options)
    traj, cost = run(scene, dt)
    dx = np.abs(traj.com[:, :, 0] - traj.com[0, :, 0])
    return {"max_drift_mm": 1e3 * float(dx.max()),
            "top_sink_mm": 1e3 * float(3.5 - traj.com[-1, -1, 1]), "wall_per_s": cost}, traj


def cradle(gap, dt, options):
    text = ""
    for i in range(3):
        x = i * (2 * R + gap) - (1e-3 if i == 0 else 0.0)  # ball 1 arrives after 1 mm
        text += body(f"d{i}", f"circle = {{ radius = {R} }}", (x, 0.0),
                     velocity=(1.0, 0.0) if i == 0 else (0.0, 0.0), friction=0.0,
                     restitution=1.0)
    scene = case(f"cradle-{gap}", 0.5, dt, 0.01, text, gravity=None, ground=False,
                 options=options)
    traj, cost = run(scene, dt)
    warnings = traj.meta["effective"]["contact"]["warnings"]
    return {"v": [float(v) for v in traj.vel[-1, :, 0]], "warnings": len(warnings),
            "wall_per_s": cost}, traj


def mass_ratio(dt, options):
    text = (body("light", "box = { size = [0.2, 0.2] }", (0.0, 0.1 - EPS), friction=0.5)
            + body("heavy", "box = { size = [0.2, 0.2] }", (0.0, 0.3 - 2 * EPS), mass=100.0,
                   friction=0.5)
            + pair("light", "ground", friction=0.5))
    scene = case("mass-ratio", 5.0, dt, 0.05, text, options=options)
    traj, cost = run(scene, dt)
    lo, hi = traj.com[-1, 0], traj.com[-1, 1]
    return {"box_box_mm": 1e3 * float(lo[1] + 0.2 - hi[1]),
            "box_ground_mm": 1e3 * float(0.1 - lo[1]),
            "drift_mm": 1e3 * float(np.max(np.abs(traj.com[:, 1, 0] - traj.com[0, 1, 0]))),
            "iterations": traj.meta["effective"]["iterations"], "wall_per_s": cost}, traj


def handler_cost(dt=1e-3, steps=3000, repeats=3):
    """us per step of the 10-stack (adapter settings, advance only) with the pair handlers and
    with their pre_solve removed (friction then 0: timing only), best of ``repeats``. Since the
    adapter registers handlers per material class only where Chipmunk's product of the shapes'
    values is not the pair's, this stack of one material has none and the two rows time the same
    thing (docs/engines.md, Pymunk, "Contact")."""
    text = "".join(body(f"b{i}", "box = { size = [1.0, 1.0] }", (0.0, 0.5 + i * (1.0 - EPS)),
                        friction=0.5) for i in range(10))
    scene = case("stack10", 5.0, dt, 0.05, text)
    out = {}
    for label in ("with handlers", "without pre_solve"):
        best = math.inf
        for _ in range(repeats):
            session = get_engine("pymunk").open(scene, "position_first", dt)
            if label == "without pre_solve":
                for handler in session.space._handlers.values():
                    handler.pre_solve = None
            session.advance(10)
            t0 = time.perf_counter()
            session.advance(steps)
            best = min(best, time.perf_counter() - t0)
        out[label] = 1e6 * best / steps
    return out


def measure(dts):
    results = {}
    for dt in dts:
        for row, options in ROWS.items():
            key = f"{row} dt={dt:g}"
            r = {}
            r["drop e=0"] = drop(0.0, dt, options)[0]
            r["drop e=0.5"] = drop(0.5, dt, options)[0]
            r["drop e=1"] = drop(1.0, dt, options)[0]
            r["slide"] = slide(dt, options)[0]
            r["roll mu=1"] = roll(1.0, dt, options)[0]
            r["roll mu=0.1"] = roll(0.1, dt, options)[0]
            r["incline 20"] = incline(20, dt, options)[0]
            r["incline 35"] = incline(35, dt, options)[0]
            r["stack 10"] = stack(dt, options)[0]
            r["pyramid"] = pyramid(dt, options)[0]
            r["cradle gap 1 mm"] = cradle(1e-3, dt, options)[0]
            r["cradle touching"] = cradle(0.0, dt, options)[0]
            r["cradle overlap 1e-9"] = cradle(-1e-9, dt, options)[0]
            r["mass 100:1"] = mass_ratio(dt, options)[0]
            results[key] = r
            print(key, "done", flush=True)
    return results


def table(results) -> str:
    def f(x, spec):
        return format(x, spec)

    lines = []
    head = ("| settings | e=0 rest depth mm (max) / rebound mm | e=0.5 apexes m (0.25, 0.0625, "
            "0.0156) | e=1 apexes m | slide mu=0.3 dist err (discrete) | roll mu=1 v, w err | "
            "roll mu=0.1 v, w err | 20 deg drift mm | 35 deg mu_eff | stack10 drift/sink mm | "
            "pyramid drift/sink mm | 100:1 box-box/ground pen mm, drift mm (iterations) | "
            "cradle v (gap 1 mm; touching; 1e-9 overlap) |")
    lines += [head, "|" + "---|" * 13]
    for key, r in results.items():
        d0, d5, d1 = r["drop e=0"], r["drop e=0.5"], r["drop e=1"]
        s, r1, r2 = r["slide"], r["roll mu=1"], r["roll mu=0.1"]
        i20, i35, st, py, mr = (r["incline 20"], r["incline 35"], r["stack 10"], r["pyramid"],
                                r["mass 100:1"])

        def vs(c):
            return ", ".join(f(v, "+.4f") for v in c["v"])

        lines.append(
            f"| {key} | {f(d0['rest_depth_mm'], '.4f')} ({f(d0['max_depth_mm'], '.3f')}) / "
            f"{f(d0['rebound_mm'], '.3f')} | "
            f"{', '.join(f(a, '.5f') for a in d5['apexes'])} | "
            f"{', '.join(f(a, '.5f') for a in d1['apexes'])} | "
            f"{f(s['error'], '+.3%')} ({f(s['discrete_error'], '+.4%')}) | "
            f"{f(r1['v_error'], '+.2e')}, {f(r1['omega_error'], '+.2e')} | "
            f"{f(r2['v_error'], '+.2e')}, {f(r2['omega_error'], '+.2e')} | "
            f"{f(i20['drift_mm'], '.4f')} | {f(i35['mu_eff'], '.5f')} | "
            f"{f(st['drift_mm'], '.4f')} / {f(st['sink_mm'], '.4f')} | "
            f"{f(py['max_drift_mm'], '.4f')} / {f(py['top_sink_mm'], '.4f')} | "
            f"{f(mr['box_box_mm'], '.4f')} / {f(mr['box_ground_mm'], '.4f')}, "
            f"{f(mr['drift_mm'], '.4f')} ({mr['iterations']}) | "
            f"{vs(r['cradle gap 1 mm'])}; {vs(r['cradle touching'])}; "
            f"{vs(r['cradle overlap 1e-9'])} |")
    lines += ["", "Wall seconds per simulated second of the accuracy pass (recording and the "
              "pair handlers included):", "",
              "| settings | " + " | ".join(next(iter(results.values()))) + " |",
              "|---|" + "---|" * len(next(iter(results.values())))]
    for key, r in results.items():
        lines.append(f"| {key} | " + " | ".join(f(v["wall_per_s"], ".4f") for v in r.values())
                     + " |")
    return "\n".join(lines)


def main() -> None:
    import pymunk

    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--dt", type=float, nargs="+", default=[1e-3, 1e-4])
    ap.add_argument("--out", type=Path, default=ROOT / "benchmarks" / "results")
    args = ap.parse_args()
    results = measure(args.dt)
    handlers = handler_cost()
    args.out.mkdir(parents=True, exist_ok=True)
    stamp = time.strftime("%Y-%m-%d %H:%M:%S")
    (args.out / "contact_pymunk.json").write_text(json.dumps(
        {"recorded": stamp, "pymunk": pymunk.version, "machine": platform.machine(),
         "results": results, "handler_cost_us_per_step": handlers}, indent=1) + "\n")
    md = (f"# Pymunk contact through the adapter: Chipmunk's defaults against the adapter's\n\n"
          f"Recorded {stamp}, pymunk {pymunk.version} (Chipmunk {pymunk.chipmunk_version}), "
          f"{platform.machine()}. Generated by `benchmarks/contact_pymunk.py` (its docstring "
          "defines every scene and column). `defaults`: collision_slop 0.1, 10 iterations "
          "(Chipmunk's); `adapter`: slop 1e-5, 50 iterations (100 for 100:1). Pair values from "
          "the adapter's handler in both. Errors are relative to the analytic value.\n\n"
          + table(results) + "\n\nCost of the pair handlers (Python pre_solve through "
          "pymunk's cffi callback, every arbiter every step), 10-stack at dt = 1e-3, "
          "50 iterations, us per step, best of 3: "
          + ", ".join(f"{k} {v:.1f}" for k, v in handlers.items()) + "\n")
    (args.out / "contact_pymunk.md").write_text(md)
    print(md)


if __name__ == "__main__":
    main()
