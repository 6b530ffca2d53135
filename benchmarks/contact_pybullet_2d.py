"""PyBullet 2D contact through crosscheck's own adapter: every 2D contact case against its truth
and against the 3D PyBullet run of the same scene, the maximal-coordinate body's out-of-plane
drift, and what the prisms' depth changes.

    PYTHONPATH=src .venv/bin/python benchmarks/contact_pybullet_2d.py [--quick]
                                                                     [--out benchmarks/results]

Every run goes the way ``crosscheck run`` takes a cell: the case file loaded by crosscheck's
loader, ``engine.not_applicable``, ``engine.run`` (the one run driver), then the case's analytic
reference and ``compare.evaluate``, so the metrics and limits are the report's. Sections:

* ``cases``: each 2D contact case (``cases/contact/*_2d.toml`` and ``pyramid_2d.toml``) on the
  planar chain (``multibody``, the adapter's 2D contact), every scored metric as value / limit,
  and the largest out-of-plane drift (``extras``). Beside it the 3D case of the same scene run
  by the same adapter (``multibody``): the prism on its plane against the sphere or the cube.
  ``--quick`` leaves the pyramid out (210 chains, about 13 s).
* ``maximal``: the same 2D cases as maximal-coordinate bodies with the adapter's refusal lifted
  (``pybullet.MAXIMAL_2D_CONTACT = None``, this measurement only): the largest out-of-plane z,
  tilt and |(omega_x, omega_y)|, and the scored metrics that fail. These are the figures of the
  refusal's reason.
* ``depth``: the prisms' half depth scaled by 0.1 and 10 against the adapter's (the largest
  in-plane half extent, MuJoCo's rule): the largest change of the centre of mass and velocity
  over the run, on the chain, and the maximal body's tilt at each depth.
* ``points``: how many contact points Bullet keeps per pair kind and where along z, after
  0.2 s at rest under gravity (circle, box and polygon on the ground; box on box; circle on
  circle; circle on box), at each depth.

Writes ``benchmarks/results/contact_pybullet_2d.md`` and ``.json``.
"""

from __future__ import annotations

import argparse
import json
import platform
import time
from pathlib import Path

import numpy as np
import pybullet as p

import crosscheck.engines.pybullet as pb
from crosscheck.compare.evaluate import evaluate
from crosscheck.engines import get_engine
from crosscheck.reference.spec import for_cell, reference_spec
from crosscheck.scene.loader import load_case, load_case_text

ROOT = Path(__file__).resolve().parents[1]
CASES = ROOT / "cases" / "contact"
# 2D case -> the 3D case of the same scene (None: no 3D counterpart)
PAIRS = {
    "bounce_elastic_2d": "bounce_elastic", "bounce_resting_2d": "bounce_resting",
    "slide_to_rest_2d": "slide_to_rest", "roll_incline_2d": "roll_incline",
    "roll_incline_slipping_2d": "roll_incline_slipping",
    "block_incline_static_2d": "block_incline_static",
    "block_incline_kinetic_2d": "block_incline_kinetic", "billiard_2d": "billiard",
    "newtons_cradle_2d": "newtons_cradle", "pyramid_2d": None,
}
OUT_OF_PLANE = ("out_of_plane", "out_of_plane_tilt", "out_of_plane_omega")
ENGINE = get_engine("pybullet")


def cell(scene, integrator: str) -> dict:
    """One cell as ``crosscheck run`` does it: not applicable, or the run and its verdict."""
    reason = ENGINE.not_applicable(scene, integrator)
    if reason:
        return {"status": "not_applicable", "reason": reason}
    t0 = time.perf_counter()
    traj = ENGINE.run(scene, integrator, scene.run.dt)
    seconds = time.perf_counter() - t0
    ref = for_cell(scene, reference_spec(scene, scene.run.dt), traj.t)
    verdict = evaluate(scene, traj, ref, "pybullet", integrator)
    scored = {name: {"value": m.get("value"), "limit": m.get("limit"), "passed": m.get("passed")}
              for name, m in verdict.metrics.items() if m.get("limit") is not None}
    drift = {k: float(np.max(np.abs(traj.extras[k]))) for k in OUT_OF_PLANE
             if k in traj.extras and np.size(traj.extras[k])}
    return {"status": verdict.status, "scored": scored, "out_of_plane": drift,
            "failure": traj.failure, "seconds": seconds, "traj": traj}


def measure_cases(names: list[str]) -> dict:
    out = {}
    for name in names:
        scene = load_case(CASES / f"{name}.toml")
        row = {"2d": cell(scene, "multibody")}
        three = PAIRS[name]
        if three is not None:
            row["3d"] = cell(load_case(CASES / f"{three}.toml"), "multibody")
        saved = pb.MAXIMAL_2D_CONTACT
        pb.MAXIMAL_2D_CONTACT = None  # this measurement only: the refusal's figures
        try:
            row["maximal"] = cell(scene, "maximal") if name != "pyramid_2d" else None
        finally:
            pb.MAXIMAL_2D_CONTACT = saved
        row["refused"] = ENGINE.not_applicable(scene, "maximal")
        out[name] = row
        print(f"{name}: {row['2d']['status']}", flush=True)
    return out


def with_depth(factor: float):
    """Patch the adapter's prism depth to ``factor`` times its rule; returns the undo."""
    rule = pb.extrusion_half_depth
    pb.extrusion_half_depth = lambda scene: factor * rule(scene)
    return lambda: setattr(pb, "extrusion_half_depth", rule)


def measure_depth(names: list[str]) -> dict:
    out = {}
    for name in names:
        scene = load_case(CASES / f"{name}.toml")
        base = ENGINE.run(scene, "multibody", scene.run.dt)
        row = {"depth": pb.extrusion_half_depth(scene)}
        for factor in (0.1, 10.0):
            undo = with_depth(factor)
            saved = pb.MAXIMAL_2D_CONTACT
            try:
                chain = ENGINE.run(scene, "multibody", scene.run.dt)
                pb.MAXIMAL_2D_CONTACT = None
                free = ENGINE.run(scene, "maximal", scene.run.dt)
            finally:
                pb.MAXIMAL_2D_CONTACT = saved
                undo()
            row[f"x{factor:g}"] = {
                "dcom": float(np.max(np.abs(chain.com - base.com))),
                "dvel": float(np.max(np.abs(chain.vel - base.vel))),
                "maximal_tilt": float(np.max(free.extras["out_of_plane_tilt"])),
            }
        saved = pb.MAXIMAL_2D_CONTACT
        pb.MAXIMAL_2D_CONTACT = None
        try:
            free = ENGINE.run(scene, "maximal", scene.run.dt)
        finally:
            pb.MAXIMAL_2D_CONTACT = saved
        row["x1"] = {"maximal_tilt": float(np.max(free.extras["out_of_plane_tilt"]))}
        out[name] = row
        print(f"depth {name}", flush=True)
    return out


def _pair_scene(bodies: str):
    return load_case_text(f"""
[case]
name = "points"
dimension = 2
[run]
duration = 0.2
dt = 1e-3
sample_every = 0.01
[effects]
gravity = [0.0, -9.81]
contact = true
[materials.m]
friction = 0.5
[ground]
material = "m"
{bodies}""")


def _body(name, shape, y, x=0.0):
    return (f'[[bodies]]\nname = "{name}"\nshape = {shape}\nmass = 1.0\n'
            f'position = [{x!r}, {y!r}]\nmaterial = "m"\n')


def measure_points() -> dict:
    circle = "{ circle = { radius = 0.1 } }"
    box = "{ box = { size = [0.2, 0.2] } }"
    poly = "{ polygon = { vertices = [[-0.1, -0.1], [0.1, -0.1], [0.0, 0.1]] } }"
    low, high = 0.1 - 1e-7, 0.3 - 2e-7
    scenes = {
        "circle on ground": _body("a", circle, low),
        "box on ground": _body("a", box, low),
        # the triangle's centroid is 1/3 of its height above its base: base at y = 0
        "polygon on ground": _body("a", poly, 0.1 - 1e-7),
        "box on box": _body("a", box, low) + _body("b", box, high, 0.05),
        "circle on circle": _body("a", circle, low) + _body("b", circle, high),
        "circle on box": _body("a", box, low) + _body("b", circle, high),
    }
    out = {}
    for label, bodies in scenes.items():
        scene = _pair_scene(bodies)
        row = {}
        for factor in (0.1, 1.0, 10.0):
            undo = with_depth(factor)
            try:
                model = ENGINE.open(scene, "multibody", 1e-3)
            finally:
                undo()
            try:
                model.advance(200)
                names = list(model.surfaces)
                pairs = []
                for i, a in enumerate(names):
                    for b in names[i + 1:]:
                        cps = p.getContactPoints(model.surfaces[a], model.surfaces[b],
                                                 model.surface_links[a], model.surface_links[b],
                                                 physicsClientId=model.cid)
                        if cps:
                            z = sorted(round(c[5][2], 4) for c in cps)
                            pairs.append({"pair": f"{a}-{b}", "points": len(cps), "z": z})
                row[f"{model._depth:g}"] = pairs
            finally:
                model.close()
        out[label] = row
    return out


def _fmt(v) -> str:
    if v is None:
        return "-"
    if isinstance(v, bool):
        return str(v)
    return f"{v:.3g}"


def table(results: dict) -> str:
    lines = []
    lines.append("## Cases: the planar chain against the truth, and the 3D case by the same "
                 "adapter\n")
    lines.append("Scored metrics as value / limit (a `!` marks a miss); out-of-plane: the "
                 "largest |z| (m), tilt (rad) and |(omega_x, omega_y)| (rad/s) read back. "
                 "Seconds: wall time of the run (build and probe included).\n")
    lines.append("| case | 2D multibody | out of plane | s | 3D multibody (same scene) | s |")
    lines.append("|---|---|---|---|---|---|")
    for name, row in results["cases"].items():
        def scored(c):
            if c is None:
                return "-"
            if c["status"] == "not_applicable":
                return "not applicable"
            parts = [f"{k} {_fmt(m['value'])} / {_fmt(m['limit'])}"
                     + ("" if m["passed"] else " !") for k, m in c["scored"].items()]
            return f"**{c['status']}**: " + "; ".join(parts)
        two = row["2d"]
        drift = ", ".join(_fmt(two["out_of_plane"].get(k)) for k in OUT_OF_PLANE)
        three = row.get("3d")
        three_s = "-" if three is None else f"{three['seconds']:.2f}"
        lines.append(f"| {name} | {scored(two)} | {drift} | {two['seconds']:.2f} | "
                     f"{scored(three)} | {three_s} |")
    lines.append("\n## Maximal-coordinate 2D bodies with the refusal lifted\n")
    lines.append("What the adapter refuses (`MAXIMAL_2D_CONTACT`); its reason quotes these "
                 "figures.\n")
    lines.append("| case | status | largest z (m) | tilt (rad) | omega_xy (rad/s) | "
                 "failing metrics |")
    lines.append("|---|---|---|---|---|---|")
    for name, row in results["cases"].items():
        m = row.get("maximal")
        if m is None:
            continue
        fails = "; ".join(f"{k} {_fmt(v['value'])} / {_fmt(v['limit'])}"
                          for k, v in m["scored"].items() if not v["passed"]) or "-"
        d = m["out_of_plane"]
        lines.append(f"| {name} | {m['status']} | {_fmt(d.get('out_of_plane'))} | "
                     f"{_fmt(d.get('out_of_plane_tilt'))} | {_fmt(d.get('out_of_plane_omega'))} "
                     f"| {fails} |")
    lines.append("\n## Prism depth\n")
    lines.append("Half depth scaled by 0.1 and 10 against the adapter's: the largest change "
                 "of any centre-of-mass coordinate (m) and velocity (m/s) over the run on the "
                 "chain, and the largest tilt (rad) of the maximal body at each depth.\n")
    lines.append("| case | depth (m) | x0.1: dcom, dvel | x10: dcom, dvel | maximal tilt "
                 "x0.1 / x1 / x10 |")
    lines.append("|---|---|---|---|---|")
    for name, row in results["depth"].items():
        a, b = row["x0.1"], row["x10"]
        lines.append(f"| {name} | {row['depth']:g} | {_fmt(a['dcom'])}, {_fmt(a['dvel'])} | "
                     f"{_fmt(b['dcom'])}, {_fmt(b['dvel'])} | {_fmt(a['maximal_tilt'])} / "
                     f"{_fmt(row['x1']['maximal_tilt'])} / {_fmt(b['maximal_tilt'])} |")
    lines.append("\n## Contact points Bullet keeps (chain, 0.2 s at rest)\n")
    lines.append("| scene | depth 0.01 m | depth 0.1 m | depth 1 m |")
    lines.append("|---|---|---|---|")
    for label, row in results["points"].items():
        cols = []
        for depth in ("0.01", "0.1", "1"):
            cols.append("; ".join(f"{q['pair']}: {q['points']} at z {q['z']}"
                                  for q in row.get(depth, [])) or "none")
        lines.append(f"| {label} | " + " | ".join(cols) + " |")
    return "\n".join(lines) + "\n"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--quick", action="store_true", help="leave the pyramid out")
    ap.add_argument("--out", default=str(ROOT / "benchmarks" / "results"))
    args = ap.parse_args()
    names = [n for n in PAIRS if not (args.quick and n == "pyramid_2d")]
    results = {
        "cases": measure_cases(names),
        "depth": measure_depth(["bounce_elastic_2d", "slide_to_rest_2d",
                                "roll_incline_slipping_2d", "block_incline_kinetic_2d",
                                "billiard_2d", "newtons_cradle_2d"]),
        "points": measure_points(),
    }
    header = (f"# PyBullet 2D contact through the adapter\n\nRecorded "
              f"{time.strftime('%Y-%m-%d %H:%M:%S')}, pybullet {ENGINE.version()}, "
              f"{platform.machine()}. Generated by `benchmarks/contact_pybullet_2d.py` (its "
              "docstring defines every section). 2D contact runs on the planar chain "
              "(`multibody`); the prisms' half depth is the largest in-plane half extent of "
              "any shape of the scene.\n\n")
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    (out / "contact_pybullet_2d.md").write_text(header + table(results))
    for row in results["cases"].values():
        for key in ("2d", "3d", "maximal"):
            if row.get(key):
                row[key].pop("traj", None)
    (out / "contact_pybullet_2d.json").write_text(
        json.dumps(results, indent=1, default=lambda o: o.tolist() if hasattr(o, "tolist")
                   else str(o)))
    print(f"wrote {out / 'contact_pybullet_2d.md'}")


if __name__ == "__main__":
    main()
