"""MuJoCo contact through crosscheck's own adapter, on the canonical contact scenes, against
their analytic answers: the adapter's settings next to MuJoCo's contact defaults.

Every scene is a small case written inline below (TOML), loaded by crosscheck's loader and run by
crosscheck's run driver on ``MujocoEngine`` (the MJCF, the explicit pairs and the settings of
``crosscheck.engines.mujoco``). The variant "mujoco defaults" is the same compiled model with
MuJoCo's own contact defaults put back on every pair and option (pyramidal cone, impratio 1,
solref (0.02, 1), solimp (0.9, 0.95, 0.001, 0.5, 2)); the pair friction and condim stay the
adapter's, so the two rows differ only by the settings the adapter chose. Writes the table to
stdout and, with --out, to a Markdown file (benchmarks/results/contact_mujoco.md is its output).

    PYTHONPATH=src python benchmarks/contact_mujoco.py [--out benchmarks/results/contact_mujoco.md]

Scenes (g = 9.81; "touching" means started at zero gap, as CONTACTS.md's study did):
  drop      sphere r = 0.1 m, 1 kg, bottom 1 m above the plane; apexes of the gap vs e^(2k) h0;
            e = 0: highest gap after the first impact (truth 0) and resting depth (truth 0)
  slide     0.2 m cube, 1 kg, touching, launched at 2 m/s along x or at 45 deg, mu = 0.3: stop
            distance vs v0^2 / (2 mu g) = 0.6796 m; hop = highest rise of the box
  roll      sphere r = 0.1 m on a 30 deg incline (tilted gravity), 1 s: mu = 1 rolls,
            v = g sin / (1 + 2/5) t; mu = 0.1 slips, v = g (sin - mu cos) t,
            w = 5 mu g cos t / (2 r)
  incline   0.2 m cube, mu = 0.5 (friction angle 26.57 deg), tilted gravity, 2 s: 20 and 25 deg
            drift (truth 0), 35 deg distance vs (g sin - mu g cos) T^2 / 2 and mu_eff
  stack     n unit cubes (1 m, 1 kg), mu = 0.5, 5 s: top box horizontal drift and total sink
  cradle    three spheres r = 0.1, 1 kg, e = 1, mu = 0, no gravity, 1 mm gaps, ball 1 at 1 m/s:
            final velocities vs (0, 0, 1)
  ratio     100 kg 0.2 m cube on a 1 kg one on the plane, mu = 0.5, 5 s: penetrations (truth 0)
  2d        the 2D forms (prisms along z, planar joints): slide of a 2D box at mu = 0.3 and a
            circle on a 30 deg incline at mu = 1, rolling as a disc: v = g sin / (1 + 1/2) t
"""

from __future__ import annotations

import argparse
import math
import platform
import sys
import time
from pathlib import Path

import mujoco
import numpy as np

from crosscheck.engines.driver import run
from crosscheck.engines.mujoco import MujocoEngine
from crosscheck.scene.loader import load_case_text

G = 9.81
ROOT = Path(__file__).resolve().parents[1]


# -- variants: the adapter as built, or MuJoCo's contact defaults put back ------------------------
def _mujoco_defaults(model) -> None:
    m = model.model
    m.opt.cone = int(mujoco.mjtCone.mjCONE_PYRAMIDAL)
    m.opt.impratio = 1.0
    # the values sit on the geoms (MuJoCo's own collision) or on explicit pairs: both
    for table in ("pair", "geom"):
        getattr(m, f"{table}_solref")[:] = [0.02, 1.0]
        getattr(m, f"{table}_solimp")[:] = [0.9, 0.95, 0.001, 0.5, 2.0]


class VariantEngine(MujocoEngine):
    """The adapter, with an optional change to the compiled model before the run."""

    def __init__(self, tweak=None):
        self.tweak = tweak

    def open(self, scene, integrator, dt):
        model = self.build(scene, integrator, dt)
        if self.tweak is not None:
            self.tweak(model)
        return model


VARIANTS = {"adapter": VariantEngine(), "mujoco defaults": VariantEngine(_mujoco_defaults)}


def simulate(variant: str, text: str, integrator: str, dt: float):
    scene = load_case_text(text)
    engine = VARIANTS[variant]
    reason = engine.not_applicable(scene, integrator)
    if reason:
        raise RuntimeError(reason)
    return run(engine, scene, integrator, dt, cost=None).output


# -- cases ----------------------------------------------------------------------------------------
def case(duration, dt, sample_every, gravity, bodies, ground=True, mu=0.5, e=0.0, dim=3,
         extra=""):
    g = "" if gravity is None else f"gravity = {list(gravity)}"
    gr = f"[ground]\nmaterial = {{ friction = {mu}, restitution = {e} }}\n" if ground else ""
    return f"""
[case]
name = "contact-bench"
dimension = {dim}
[run]
duration = {duration}
dt = {dt}
sample_every = {sample_every}
[effects]
{g}
contact = true
[materials.m]
friction = {mu}
restitution = {e}
{gr}{extra}{bodies}"""


def body(name, shape, mass, position, velocity=None, material="m"):
    v = "" if velocity is None else f"velocity = {list(velocity)}\n"
    return (f'[[bodies]]\nname = "{name}"\nshape = {shape}\nmass = {mass}\n'
            f'position = {list(position)}\n{v}material = "{material}"\n')


SPHERE = "{ sphere = { radius = 0.1 } }"
CUBE = "{ box = { size = [0.2, 0.2, 0.2] } }"


def tilted(theta_deg):
    t = math.radians(theta_deg)
    return (G * math.sin(t), 0.0, -G * math.cos(t))


# -- measurements ---------------------------------------------------------------------------------
def drop(variant, e, dt, integ):
    text = case(3.2, dt, 1e-3, (0, 0, -G), body("ball", SPHERE, 1.0, (0, 0, 1.1)), e=e)
    tr = simulate(variant, text, integ, dt)
    gap = tr.com[:, 0, 2] - 0.1
    vz = tr.vel[:, 0, 2]
    if e == 0.0:
        hit = int(np.argmax(gap <= 0.0))
        return {"rebound mm": 1e3 * float(gap[hit:].max()), "rest depth mm": -1e3 * gap[-1]}
    apex = [max(gap[i - 1], gap[i]) for i in range(1, len(vz)) if vz[i - 1] > 0 >= vz[i]]
    apex = (apex + [float("nan")] * 3)[:3]
    truth = [e ** (2 * k) for k in (1, 2, 3)]
    return {f"apex {k + 1} err": apex[k] / truth[k] - 1 for k in range(3)}


def slide(variant, dt, angle_deg=0.0, mu=0.3, v0=2.0):
    a = math.radians(angle_deg)
    v = (v0 * math.cos(a), v0 * math.sin(a), 0.0)
    text = case(1.0, dt, 1e-3, (0, 0, -G), body("box", CUBE, 1.0, (0, 0, 0.1), v), mu=mu)
    tr = simulate(variant, text, "euler", dt)
    d = float(np.linalg.norm(tr.com[-1, 0, :2] - tr.com[0, 0, :2]))
    truth = v0 ** 2 / (2 * mu * G)
    speed = np.linalg.norm(tr.vel[:, 0, :2], axis=1)
    stop = tr.t[int(np.argmax(speed < 1e-3))] if np.any(speed < 1e-3) else float("nan")
    return {"distance err": d / truth - 1, "stop time err": stop / (v0 / (mu * G)) - 1,
            "hop mm": 1e3 * float(tr.com[:, 0, 2].max() - 0.1)}


def roll(variant, dt, mu, integ="euler"):
    th = math.radians(30)
    text = case(1.0, dt, 1e-2, tilted(30), body("ball", SPHERE, 1.0, (0, 0, 0.1)), mu=mu)
    tr = simulate(variant, text, integ, dt)
    v, w = tr.vel[-1, 0, 0], tr.omega[-1, 0, 1]
    if mu * math.cos(th) * 3.5 >= math.sin(th):  # rolls: mu >= 2/7 tan
        vt = G * math.sin(th) / 1.4
        wt = vt / 0.1
    else:
        vt = G * (math.sin(th) - mu * math.cos(th))
        wt = 2.5 * mu * G * math.cos(th) / 0.1
    return {"v err": v / vt - 1, "w err": w / wt - 1, "slip mm/s": 1e3 * (v - w * 0.1),
            "truth slip mm/s": 1e3 * (vt - wt * 0.1)}


def incline(variant, dt, theta, mu=0.5, integ="euler"):
    text = case(2.0, dt, 1e-2, tilted(theta), body("box", CUBE, 1.0, (0, 0, 0.1)), mu=mu)
    tr = simulate(variant, text, integ, dt)
    d = float(tr.com[-1, 0, 0] - tr.com[0, 0, 0])
    th = math.radians(theta)
    if math.tan(th) <= mu:
        return {"drift mm": 1e3 * d}
    truth = 0.5 * G * (math.sin(th) - mu * math.cos(th)) * 4.0
    mu_eff = (G * math.sin(th) - 2 * d / 4.0) / (G * math.cos(th))
    return {"distance err": d / truth - 1, "mu_eff": mu_eff}


def stack(variant, dt, n):
    bodies = "".join(body(f"b{i}", "{ box = { size = [1.0, 1.0, 1.0] } }", 1.0,
                          (0, 0, i + 0.5)) for i in range(n))
    tr = simulate(variant, case(5.0, dt, 1e-2, (0, 0, -G), bodies), "euler", dt)
    top = tr.com[:, -1]
    return {"top drift mm": 1e3 * float(np.linalg.norm(top[-1, :2] - top[0, :2])),
            "sink mm": 1e3 * float(top[0, 2] - top[-1, 2])}


def cradle(variant, dt, integ, gap=1e-3):
    bodies = (body("b1", SPHERE, 1.0, (0, 0, 0), (1.0, 0, 0))
              + body("b2", SPHERE, 1.0, (0.25, 0, 0))
              + body("b3", SPHERE, 1.0, (0.45 + gap, 0, 0)))
    tr = simulate(variant, case(0.5, dt, 1e-2, None, bodies, ground=False, mu=0.0, e=1.0),
                  integ, dt)
    v = tr.vel[-1, :, 0]
    return {"v1": v[0], "v2": v[1], "v3": v[2], "KE ratio": float(np.sum(v ** 2))}


def ratio(variant, dt):
    bodies = body("low", CUBE, 1.0, (0, 0, 0.1)) + body("high", CUBE, 100.0, (0, 0, 0.3))
    tr = simulate(variant, case(5.0, dt, 1e-2, (0, 0, -G), bodies), "euler", dt)
    lo, hi = tr.com[-1, 0], tr.com[-1, 1]
    return {"box/box pen mm": 1e3 * (0.2 - (hi[2] - lo[2])),
            "box/ground pen mm": 1e3 * (0.1 - lo[2]),
            "top drift mm": 1e3 * float(np.linalg.norm(tr.com[-1, 1, :2] - tr.com[0, 1, :2]))}


def slide_2d(variant, dt, mu=0.3, v0=2.0):
    text = case(1.0, dt, 1e-3, (0, -G), body("box", "{ box = { size = [0.2, 0.2] } }", 1.0,
                                             (0, 0.1), (v0, 0)), mu=mu, dim=2)
    tr = simulate(variant, text, "euler", dt)
    d = float(tr.com[-1, 0, 0] - tr.com[0, 0, 0])
    return {"distance err": d / (v0 ** 2 / (2 * mu * G)) - 1,
            "hop mm": 1e3 * float(tr.com[:, 0, 1].max() - 0.1)}


def roll_2d(variant, dt, mu=1.0):
    th = math.radians(30)
    text = case(1.0, dt, 1e-2, (G * math.sin(th), -G * math.cos(th)),
                body("disc", "{ circle = { radius = 0.1 } }", 1.0, (0, 0.1)), mu=mu, dim=2)
    tr = simulate(variant, text, "euler", dt)
    vt = G * math.sin(th) / 1.5
    v, w = tr.vel[-1, 0, 0], tr.omega[-1, 0]
    return {"v err": v / vt - 1, "w err": -w * 0.1 / vt - 1, "slip mm/s": 1e3 * (v + w * 0.1)}


# -- the table ------------------------------------------------------------------------------------
def rows():
    out = []

    def add(scene, setting, fn, *args):
        for variant in VARIANTS:
            t0 = time.perf_counter()
            try:
                res = fn(variant, *args)
            except Exception as exc:  # a failure is a row, not the end of the table
                res = {"failed": str(exc)[:80]}
            out.append((scene, setting, variant, res, time.perf_counter() - t0))

    add("drop e=0", "euler dt 1e-3", drop, 0.0, 1e-3, "euler")
    add("drop e=0", "euler dt 1e-4", drop, 0.0, 1e-4, "euler")
    add("drop e=1", "euler dt 1e-3", drop, 1.0, 1e-3, "euler")
    add("drop e=1", "rk4 dt 1e-4", drop, 1.0, 1e-4, "rk4")
    add("drop e=0.5", "euler dt 1e-3", drop, 0.5, 1e-3, "euler")
    add("drop e=0.5", "rk4 dt 1e-4", drop, 0.5, 1e-4, "rk4")
    add("slide mu=0.3 along x", "euler dt 1e-3", slide, 1e-3)
    add("slide mu=0.3 along x", "euler dt 1e-4", slide, 1e-4)
    add("slide mu=0.3 at 45 deg", "euler dt 1e-3", slide, 1e-3, 45.0)
    add("roll 30 deg mu=1", "euler dt 1e-3", roll, 1e-3, 1.0)
    add("roll 30 deg mu=1", "euler dt 1e-4", roll, 1e-4, 1.0)
    add("slip 30 deg mu=0.1", "euler dt 1e-3", roll, 1e-3, 0.1)
    add("slip 30 deg mu=0.1", "euler dt 1e-4", roll, 1e-4, 0.1)
    add("incline box 20 deg", "euler dt 1e-3", incline, 1e-3, 20.0)
    add("incline box 25 deg", "euler dt 1e-3", incline, 1e-3, 25.0)
    add("incline box 35 deg", "euler dt 1e-3", incline, 1e-3, 35.0)
    add("incline box 35 deg", "euler dt 1e-4", incline, 1e-4, 35.0)
    add("stack 5", "euler dt 1e-3", stack, 1e-3, 5)
    add("stack 10", "euler dt 1e-3", stack, 1e-3, 10)
    add("cradle 1 mm gaps", "euler dt 1e-3", cradle, 1e-3, "euler")
    add("cradle 1 mm gaps", "rk4 dt 1e-4", cradle, 1e-4, "rk4")
    add("100:1 mass ratio", "euler dt 1e-3", ratio, 1e-3)
    add("2D box slide mu=0.3", "euler dt 1e-3", slide_2d, 1e-3)
    add("2D disc roll 30 deg mu=1", "euler dt 1e-3", roll_2d, 1e-3)
    return out


def fmt(x) -> str:
    if isinstance(x, str):
        return x
    if abs(x) >= 100 or x == 0:
        return f"{x:.4g}"
    return f"{x:+.4f}" if abs(x) >= 1e-4 else f"{x:+.2e}"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, help="also write the Markdown table here")
    args = ap.parse_args(argv)
    lines = [
        "# MuJoCo contact through crosscheck's adapter (benchmarks/contact_mujoco.py)",
        "",
        f"mujoco {mujoco.__version__}, Python {platform.python_version()}, "
        f"{platform.machine()}. Errors are relative to the analytic value (docstring of the "
        "script); mm are absolute. 'adapter' = the settings of crosscheck.engines.mujoco; "
        "'mujoco defaults' = the same model with MuJoCo's contact defaults on every pair "
        "(pyramidal cone, impratio 1, solref (0.02, 1), solimp (0.9, 0.95, 0.001, 0.5, 2)).",
        "",
        "| scene | integrator, step | variant | measured | wall s |",
        "|---|---|---|---|---|",
    ]
    for scene, setting, variant, res, wall in rows():
        measured = ", ".join(f"{k} {fmt(v)}" for k, v in res.items())
        lines.append(f"| {scene} | {setting} | {variant} | {measured} | {wall:.1f} |")
        print(lines[-1], flush=True)
    text = "\n".join(lines) + "\n"
    if args.out:
        args.out.write_text(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
