"""PyBullet contact through crosscheck's own adapter: Bullet's contact defaults against the
adapter's recipe, both integrators (body kinds).

    PYTHONPATH=src .venv/bin/python benchmarks/contact_pybullet.py [--dt 1e-3] [--quick]
                                                                  [--out benchmarks/results]

Every scene is a 3D case written here as TOML, loaded by crosscheck's loader and run by the
PyBullet adapter through the one run driver (``engine.run``), exactly as a case file would be.
Rows per step size and integrator:

* ``defaults``: ``[engine_options.pybullet] contact_parameters = "defaults"``: Bullet's contact
  parameters (restitution threshold 0.2 m/s, slop, contact ERP, warm starting, processing
  threshold) and its 50 solver iterations. The geometry and the per-surface factors of the pair
  values are the adapter's in both rows, so the rows differ only in the solver settings.
* ``adapter``: what the adapter sets (docs/engines.md, PyBullet, "Contact"): e = 0 scenes keep
  Bullet's contact parameters with 200 iterations at a mass ratio >= 100; e > 0 scenes get
  restitution threshold, slop, contact ERP, warm starting and processing threshold 0.

Scenes (z up, g = 9.81; spheres r = 0.1 m, 1 kg; boxes 0.2 m cubes, 1 kg; bodies that rest on
something start overlapping it by 1 um):

* ``drop e=0`` / ``e=0.5`` / ``e=1``: a sphere whose bottom is 1 m above the ground, pair
  restitution e, 3 s. Apexes: the largest gap between impacts (ideal e^(2k) m); e = 0: resting
  depth at the end and the largest rebound after the first impact.
* ``slide``: the cube at 2 m/s along x, pair friction 0.3 from a ``[[contact_pairs]]`` entry over
  materials 0.8 and 0.1 (product 0.08, rule 0.28), 1.5 s: stop distance (|v| < 1 mm/s) against
  v^2 / (2 mu g) = 0.6796 m.
* ``roll mu=1`` / ``roll mu=0.1``: a sphere on flat ground under gravity tilted 30 degrees
  (g (sin, 0, -cos)), 1 s: rolling a = 5/7 g sin; slipping a = g (sin - mu cos),
  alpha = 5 mu g cos / (2 r). Errors of v and omega at 1 s.
* ``incline 20`` / ``incline 35``: the cube, friction 0.5, tilted gravity, 2 s: drift (mm) at 20;
  mu_eff = (g sin - 2 d / T^2) / (g cos) at 35.
* ``stack 10``: ten 1 m cubes of 1 kg, friction 0.5, 5 s: top-box drift and total sink (mm).
* ``mass 100:1``: a 100 kg cube on a 1 kg cube on the ground, friction 0.5, 5 s: box/box and
  box/ground penetration and top drift (mm).

Writes ``benchmarks/results/contact_pybullet.md`` and ``.json``.
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
EPS = 1e-6
ROWS = {"defaults": '[engine_options.pybullet]\ncontact_parameters = "defaults"', "adapter": ""}
INTEGRATORS = ("multibody", "maximal")


def case(name, duration, dt, sample, bodies, gravity=(0.0, 0.0, -G), ground_friction=0.5,
         extra="", options=""):
    return load_case_text(f"""
[case]
name = "{name}"
dimension = 3
[run]
duration = {duration!r}
dt = {dt!r}
sample_every = {sample!r}
[effects]
contact = true
gravity = {json.dumps(list(gravity))}
[ground]
material = {{ friction = {ground_friction!r} }}
{extra}
{options}
{bodies}""")


def body(name, shape, position, *, mass=1.0, velocity=(0.0, 0.0, 0.0), friction=0.5,
         restitution=0.0):
    return (f'\n[[bodies]]\nname = "{name}"\nshape = {shape}\nmass = {mass!r}\n'
            f"position = {json.dumps(list(position))}\nvelocity = {json.dumps(list(velocity))}\n"
            f"material = {{ friction = {friction!r}, restitution = {restitution!r} }}\n")


SPHERE = f"{{ sphere = {{ radius = {R} }} }}"
CUBE = "{ box = { size = [0.2, 0.2, 0.2] } }"
UNIT = "{ box = { size = [1.0, 1.0, 1.0] } }"


def pair(a, b, **values):
    items = "\n".join(f"{k} = {v!r}" for k, v in values.items())
    return f'\n[[contact_pairs]]\na = "{a}"\nb = "{b}"\n{items}\n'


def run(scene, integrator, dt):
    t0 = time.perf_counter()
    traj = get_engine("pybullet").run(scene, integrator, dt)
    wall = time.perf_counter() - t0
    if traj.failure is not None:
        raise RuntimeError(f"{scene.name}: {traj.failure}")
    return traj, wall / scene.run.duration


def drop(e, integrator, dt, options):
    scene = case(f"drop-e{e}", 3.0, dt, dt, body("ball", SPHERE, (0.0, 0.0, R + 1.0))
                 + pair("ball", "ground", restitution=e), options=options)
    traj, cost = run(scene, integrator, dt)
    gap = traj.com[:, 0, 2] - R
    vz = traj.vel[:, 0, 2]
    up = np.nonzero((vz[:-1] > 0) & (vz[1:] <= 0))[0]
    apexes = [float(gap[i:i + 2].max()) for i in up][:3]
    first = int(np.argmax(gap < 0))
    return {"apexes": apexes, "rest_depth_mm": -1e3 * float(gap[-1]),
            "max_depth_mm": -1e3 * float(gap.min()),
            "rebound_mm": 1e3 * float(max(0.0, gap[first:].max())), "wall_per_s": cost}


def slide(integrator, dt, options):
    v0, mu = 2.0, 0.3
    scene = case("slide", 1.5, dt, dt,
                 body("box", CUBE, (0.0, 0.0, 0.1 - EPS), velocity=(v0, 0.0, 0.0), friction=0.8)
                 + pair("box", "ground", friction=mu), ground_friction=0.1, options=options)
    traj, cost = run(scene, integrator, dt)
    speed = np.linalg.norm(traj.vel[:, 0], axis=1)
    stop = int(np.argmax(speed < 1e-3))
    d = float(traj.com[stop, 0, 0] - traj.com[0, 0, 0])
    ideal = v0**2 / (2 * mu * G)
    hop = float(traj.com[:, 0, 2].max() - traj.com[0, 0, 2])
    return {"distance": d, "error": d / ideal - 1.0, "hop_mm": 1e3 * hop, "wall_per_s": cost}


def _tilted(deg):
    t = math.radians(deg)
    return (G * math.sin(t), 0.0, -G * math.cos(t))


def roll(mu, integrator, dt, options):
    t = math.radians(30)
    scene = case(f"roll-{mu}", 1.0, dt, 0.01, body("ball", SPHERE, (0.0, 0.0, R - EPS),
                                                   friction=mu),
                 gravity=_tilted(30), ground_friction=mu, options=options)
    traj, cost = run(scene, integrator, dt)
    T = traj.t[-1]
    if mu >= math.tan(t) * 2 / 7:
        v, w = 5 / 7 * G * math.sin(t) * T, 5 / 7 * G * math.sin(t) * T / R
    else:
        v = G * (math.sin(t) - mu * math.cos(t)) * T
        w = 5 * mu * G * math.cos(t) / (2 * R) * T
    return {"v_error": float(traj.vel[-1, 0, 0]) / v - 1.0,
            "omega_error": float(traj.omega[-1, 0, 1]) / w - 1.0, "wall_per_s": cost}


def incline(deg, integrator, dt, options):
    scene = case(f"incline-{deg}", 2.0, dt, 0.01, body("box", CUBE, (0.0, 0.0, 0.1 - EPS)),
                 gravity=_tilted(deg), options=options)
    traj, cost = run(scene, integrator, dt)
    d = float(traj.com[-1, 0, 0] - traj.com[0, 0, 0])
    T = float(traj.t[-1])
    t = math.radians(deg)
    return {"drift_mm": 1e3 * d,
            "mu_eff": (G * math.sin(t) - 2 * d / T**2) / (G * math.cos(t)), "wall_per_s": cost}


def stack(integrator, dt, options):
    text = "".join(body(f"b{k}", UNIT, (0.0, 0.0, 0.5 + k - (k + 1) * EPS)) for k in range(10))
    scene = case("stack10", 5.0, dt, 0.05, text, options=options)
    traj, cost = run(scene, integrator, dt)
    top = traj.com[:, -1]
    return {"drift_mm": 1e3 * float(np.linalg.norm(top[-1, :2] - top[0, :2])),
            "sink_mm": 1e3 * float(9.5 - top[-1, 2]), "wall_per_s": cost}


def mass_ratio(integrator, dt, options):
    text = (body("light", CUBE, (0.0, 0.0, 0.1 - EPS))
            + body("heavy", CUBE, (0.0, 0.0, 0.3 - 2 * EPS), mass=100.0))
    scene = case("mass100", 5.0, dt, 0.05, text, options=options)
    traj, cost = run(scene, integrator, dt)
    zl, zh = traj.com[-1, 0, 2], traj.com[-1, 1, 2]
    drift = float(np.linalg.norm(traj.com[-1, 1, :2] - traj.com[0, 1, :2]))
    iters = traj.meta["effective"]["contact"]["num_solver_iterations"]
    return {"box_ground_mm": 1e3 * (0.1 - zl), "box_box_mm": 1e3 * (0.2 - (zh - zl)),
            "drift_mm": 1e3 * drift, "iterations": iters, "wall_per_s": cost}


def measure(dts, quick=False):
    results = {}
    for dt in dts:
        for integrator in INTEGRATORS:
            for row, options in ROWS.items():
                key = f"{row} {integrator} dt={dt:g}"
                r = {"drop e=0": drop(0.0, integrator, dt, options),
                     "drop e=0.5": drop(0.5, integrator, dt, options),
                     "drop e=1": drop(1.0, integrator, dt, options)}
                if not (quick and dt < 1e-3):
                    r["slide"] = slide(integrator, dt, options)
                    r["roll mu=1"] = roll(1.0, integrator, dt, options)
                    r["roll mu=0.1"] = roll(0.1, integrator, dt, options)
                    r["incline 20"] = incline(20, integrator, dt, options)
                    r["incline 35"] = incline(35, integrator, dt, options)
                    r["stack 10"] = stack(integrator, dt, options)
                    r["mass 100:1"] = mass_ratio(integrator, dt, options)
                results[key] = r
                print(key, "done", flush=True)
    return results


def table(results) -> str:
    lines = ["| settings | e=0 rest depth mm (max) / rebound mm | e=0.5 apexes m (0.25, 0.0625, "
             "0.0156) | e=1 apexes m | slide mu=0.3 dist err / hop mm | roll mu=1 v, w err | "
             "roll mu=0.1 v, w err | 20 deg drift mm | 35 deg mu_eff | stack10 drift/sink mm | "
             "100:1 box-box/ground pen mm, drift mm (iterations) |",
             "|" + "---|" * 11]
    for key, r in results.items():
        d0, d5, d1 = r["drop e=0"], r["drop e=0.5"], r["drop e=1"]
        cells = [key,
                 f"{d0['rest_depth_mm']:.4f} ({d0['max_depth_mm']:.3f}) / "
                 f"{d0['rebound_mm']:.3f}",
                 ", ".join(f"{a:.5f}" for a in d5["apexes"]) or "no bounce",
                 ", ".join(f"{a:.5f}" for a in d1["apexes"]) or "no bounce"]
        if "slide" in r:
            s, r1, r2 = r["slide"], r["roll mu=1"], r["roll mu=0.1"]
            st, mr = r["stack 10"], r["mass 100:1"]
            cells += [f"{s['error']:+.3%} / {s['hop_mm']:.3f}",
                      f"{r1['v_error']:+.2e}, {r1['omega_error']:+.2e}",
                      f"{r2['v_error']:+.2e}, {r2['omega_error']:+.2e}",
                      f"{r['incline 20']['drift_mm']:.4f}", f"{r['incline 35']['mu_eff']:.5f}",
                      f"{st['drift_mm']:.4f} / {st['sink_mm']:.4f}",
                      f"{mr['box_box_mm']:.4f} / {mr['box_ground_mm']:.4f}, "
                      f"{mr['drift_mm']:.4f} ({mr['iterations']})"]
        else:
            cells += ["-"] * 7
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)


def main() -> None:
    import pybullet

    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--dt", type=float, nargs="+", default=[1e-3, 1e-4])
    ap.add_argument("--quick", action="store_true",
                    help="at steps below 1e-3 only the drops (the other scenes take minutes)")
    ap.add_argument("--out", type=Path, default=ROOT / "benchmarks" / "results")
    args = ap.parse_args()
    results = measure(args.dt, args.quick)
    args.out.mkdir(parents=True, exist_ok=True)
    stamp = time.strftime("%Y-%m-%d %H:%M:%S")
    version = get_engine("pybullet").version()
    (args.out / "contact_pybullet.json").write_text(json.dumps(
        {"recorded": stamp, "pybullet": version, "machine": platform.machine(),
         "results": results}, indent=1) + "\n")
    del pybullet
    md = (f"# PyBullet contact through the adapter: Bullet's defaults against the recipe\n\n"
          f"Recorded {stamp}, pybullet {version}, {platform.machine()}. Generated by "
          "`benchmarks/contact_pybullet.py` (its docstring defines every scene and column). "
          "`defaults`: Bullet's contact parameters and 50 iterations; `adapter`: the recipe "
          "(e = 0: defaults, 200 iterations at 100:1; e > 0: threshold, slop, ERP, warm "
          "starting, processing threshold 0). Geometry and per-surface pair factors are the "
          "adapter's in both. Errors are relative to the analytic value.\n\n"
          + table(results) + "\n")
    (args.out / "contact_pybullet.md").write_text(md)
    print(md)


if __name__ == "__main__":
    main()
