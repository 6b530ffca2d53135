"""Cost of the in-house collision detection per step, and how it grows with the number of bodies.

    .venv/bin/python benchmarks/bench_collide.py [--sizes 200 1000 5000] [--boxes 200]
                                                 [--steps 200] [--repeats 5] [--out DIR]

Scenes (built directly as Scenes; the geometry is what a case with these bodies compiles to):

* ``spheres N``: N spheres (radius 5 cm) packed as a pile in a bin: a cubic lattice 10 cm apart
  (touching neighbours, up to six contacts each) with 1 mm of random jitter, ten layers high on
  the ground, inside four static walls. Contact-dense like a settled pile.
* ``boxes 200``: 200 cubes (10 cm) stacked as a lattice of columns 8 high, each resting 0.5 mm
  deep on the one below with a random tilt of up to 1 degree: face-face manifolds of four points.

Each step detects on a new state: every body moves by a random walk of 0.1 mm and turns by
1 mrad per step, so the broad phase's insertion sort has work to do, as in a simulation. Timed:
``detect3d`` over ``--steps`` states called from compiled code (as a contact model calls it), and
the same called once per step from Python; best of ``--repeats`` (the machine is shared; the
load average is recorded). Also timed: the broad phase alone, sweep and prune against brute
force.

Writes ``benchmarks/results/collide.json`` and ``benchmarks/results/collide.md``.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import time
from pathlib import Path

import numba
import numpy as np
from numba import njit
from scipy.spatial.transform import Rotation

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests" / "collide"))

from collide_scenes import body, scene, state3d, static  # noqa: E402

from crosscheck.scene.shapes import Box, Sphere  # noqa: E402
from crosscheck.sim.collide import compile_geometry, detect3d, new_contacts  # noqa: E402
from crosscheck.sim.collide.broadphase import (  # noqa: E402
    brute_force_pairs,
    grid_pairs,
    sweep_and_prune,
)
from crosscheck.sim.collide.pose import bounding_boxes3d, world_poses3d  # noqa: E402

OUT = ROOT / "benchmarks" / "results"
R = 0.05


def sphere_pile(n: int, rng):
    layers = 10
    per_layer = int(np.ceil(n / layers))
    side = int(np.ceil(np.sqrt(per_layer)))
    bodies = []
    for i in range(n):
        layer, k = divmod(i, per_layer)
        ix, iy = divmod(k, side)
        pos = np.array([ix * 2 * R, iy * 2 * R, R + layer * 2 * R]) + rng.uniform(-1e-3, 1e-3, 3)
        bodies.append(body(f"s{i}", Sphere(R), pos))
    extent = side * 2 * R
    h = layers * 2 * R
    walls = [static("east", Box(np.array([0.05, extent + 0.1, h])), [extent, extent / 2, h / 2]),
             static("west", Box(np.array([0.05, extent + 0.1, h])), [-2 * R, extent / 2, h / 2]),
             static("north", Box(np.array([extent + 0.1, 0.05, h])), [extent / 2, extent, h / 2]),
             static("south", Box(np.array([extent + 0.1, 0.05, h])),
                    [extent / 2, -2 * R, h / 2])]
    return scene(bodies, walls, ground=([0, 0, 1], 0.0))


def box_stacks(n: int, rng):
    height = 8
    columns = int(np.ceil(n / height))
    side = int(np.ceil(np.sqrt(columns)))
    bodies = []
    for i in range(n):
        col, level = divmod(i, height)
        ix, iy = divmod(col, side)
        tilt = Rotation.from_rotvec(rng.normal(size=3) * np.radians(1.0) / np.sqrt(3))
        pos = np.array([ix * 0.15, iy * 0.15, 0.05 - 0.0005 + level * (0.1 - 0.0005)])
        bodies.append(body(f"b{i}", Box(np.array([0.1, 0.1, 0.1])), pos,
                           tilt.as_quat()[[3, 0, 1, 2]]))
    return scene(bodies, ground=([0, 0, 1], 0.0))


@njit(cache=False)
def detect_steps(g, xs, qs, c, rows):
    """detect3d on every state, from compiled code (as a contact model calls it)."""
    for k in range(xs.shape[0]):
        detect3d(g, xs[k], qs[k], c)
        rows[k] = c.count[0]


def states(sc, steps: int, rng):
    """A random walk of the bodies: 0.1 mm and 1 mrad per step."""
    x0, q0 = state3d(sc)
    xs, qs = [x0], [q0]
    for _ in range(steps - 1):
        x = xs[-1] + rng.normal(scale=1e-4 / np.sqrt(3), size=x0.shape)
        turn = Rotation.from_rotvec(rng.normal(scale=1e-3 / np.sqrt(3), size=x0.shape))
        q = (turn * Rotation.from_quat(qs[-1][:, [1, 2, 3, 0]])).as_quat()[:, [3, 0, 1, 2]]
        xs.append(np.ascontiguousarray(x))
        qs.append(np.ascontiguousarray(q))
    return np.ascontiguousarray(xs), np.ascontiguousarray(qs)


def time_detection(sc, steps, repeats, rng):
    xs, qs = states(sc, steps, rng)
    out = {}
    for method in ("grid", "sweep"):
        out[method] = _time_method(sc, method, xs, qs, steps, repeats)
    return out


def _time_method(sc, method, xs, qs, steps, repeats):
    g = compile_geometry(sc, broadphase=method)
    c = new_contacts(g)
    rows = np.zeros(steps, np.int64)
    detect_steps(g, xs[:2], qs[:2], c, rows)  # compile (or load the cache)
    best = np.inf
    for _ in range(repeats):
        t = time.perf_counter()
        detect_steps(g, xs, qs, c, rows)
        best = min(best, (time.perf_counter() - t) / steps)
        if c.overflowed():
            raise RuntimeError("contact buffer overflow in the benchmark")
    # the same from Python, one call per step (what a caller outside numba pays on top)
    best_py = np.inf
    for _ in range(repeats):
        t = time.perf_counter()
        for k in range(steps):
            detect3d(g, xs[k], qs[k], c)
        best_py = min(best_py, (time.perf_counter() - t) / steps)
    # the broad phase alone, on the first state
    nc = len(g.kind)
    wpos, wrot = np.empty((nc, 3)), np.empty((nc, 3, 3))
    lo, hi = np.empty((nc, 3)), np.empty((nc, 3))
    world_poses3d(g, xs[0], qs[0], wpos, wrot)
    bounding_boxes3d(g, wpos, wrot, 0.5 * g.margin, lo, hi)
    buf = np.empty((64 * nc, 2), np.int64)
    find = grid_pairs if method == "grid" else sweep_and_prune
    alone, n_pairs = _best(lambda: find(g, lo, hi, buf), repeats)
    brute, n_brute = _best(lambda: brute_force_pairs(g, lo, hi, buf), max(1, repeats // 2))
    assert n_pairs == n_brute
    return {"bodies": len(sc.bodies), "colliders": nc, "detect_s": best,
            "detect_python_s": best_py, "rows_mean": float(np.mean(rows)),
            "pairs": int(n_pairs), "broad_phase_s": alone, "brute_force_s": brute}


def _best(fn, repeats):
    fn()
    best = np.inf
    out = None
    for _ in range(repeats):
        t = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - t)
    return best, out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[200, 1000, 5000])
    ap.add_argument("--boxes", type=int, default=200)
    ap.add_argument("--steps", type=int, default=200)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--out", type=Path, default=OUT)
    args = ap.parse_args(argv)
    rng = np.random.default_rng(0)
    load0 = os.getloadavg()[0]
    results = []
    scenes = [(f"spheres {n}", sphere_pile(n, rng)) for n in args.sizes]
    scenes.append((f"boxes {args.boxes}", box_stacks(args.boxes, rng)))
    for name, sc in scenes:
        for method, r in time_detection(sc, args.steps, args.repeats, rng).items():
            results.append({"scene": name, "broadphase": method, **r})
            print(results[-1], flush=True)
    load1 = os.getloadavg()[0]
    meta = {"recorded": time.strftime("%Y-%m-%d %H:%M:%S"), "machine": platform.machine(),
            "cores": os.cpu_count(), "numba": numba.__version__, "steps": args.steps,
            "repeats": args.repeats, "load_before": load0, "load_after": load1}
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "collide.json").write_text(json.dumps({"meta": meta, "results": results},
                                                      indent=1))
    (args.out / "collide.md").write_text(report(meta, results))


def report(meta, results) -> str:
    lines = [
        "# In-house collision detection: cost per step",
        "",
        f"Recorded {meta['recorded']} on {meta['cores']} cores ({meta['machine']}), one thread, "
        f"numba {meta['numba']}. Best of {meta['repeats']} runs of {meta['steps']} steps each; "
        f"load average {meta['load_before']:.1f} before, {meta['load_after']:.1f} after (the "
        "machine is shared: absolute figures move from run to run). Generated by "
        "`benchmarks/bench_collide.py`; the scenes are described there.",
        "",
        "| scene | broad phase | bodies | contact rows | pairs | detect per step | per body "
        "| from Python | broad phase alone | brute force pairs |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in results:
        lines.append(
            f"| {r['scene']} | {r['broadphase']} | {r['bodies']} | {r['rows_mean']:.0f} | "
            f"{r['pairs']} | {r['detect_s'] * 1e3:.3f} ms | "
            f"{r['detect_s'] / r['bodies'] * 1e6:.2f} us | {r['detect_python_s'] * 1e3:.3f} ms | "
            f"{r['broad_phase_s'] * 1e3:.3f} ms | {r['brute_force_s'] * 1e3:.2f} ms |")
    for method in ("grid", "sweep"):
        spheres = [r for r in results
                   if r["scene"].startswith("spheres") and r["broadphase"] == method]
        if len(spheres) >= 2:
            a, b = spheres[0], spheres[-1]
            lines += [
                "",
                f"{method}: from {a['bodies']} to {b['bodies']} spheres "
                f"({b['bodies'] / a['bodies']:.0f}x the bodies): detection "
                f"{b['detect_s'] / a['detect_s']:.1f}x, broad phase alone "
                f"{b['broad_phase_s'] / a['broad_phase_s']:.1f}x, brute force "
                f"{b['brute_force_s'] / a['brute_force_s']:.0f}x.",
            ]
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    main()
