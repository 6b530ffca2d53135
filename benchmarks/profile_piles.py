"""Where an in-house step's time goes on a sphere pile: detection, solve, integration.

    .venv/bin/python benchmarks/profile_piles.py [--sizes 200 1000 5000] [--models soft_step
        sequential_impulse] [--settle 0.3] [--steps 50] [--repeats 3] [--out FILE]

The velocity-level models only (their stepper exposes detection and the step kernel apart;
``penalty`` computes its contact forces inside every force evaluation, so its detection cannot
be timed apart through the same entry points). The pile of benchmarks/bench_piles.py
(tests/piles/pile_scenes.py, spheres into a bin) is run through the in-house adapter for
``--settle`` s (the benchmark's duration), so the state is the one the benchmark times at its
end; sequential_impulse's PGS sweeps per step are counted over the timed steps. From
copies of that state, best of ``--repeats``, per step:

* ``step``: the session's ``advance(steps)`` (the fused compiled detect + step loop);
* ``detect``: ``sim.collide.detect3d`` on the same state, called ``steps`` times from one
  compiled loop (as ``advance3d`` calls it), with its own scratch allocations;
* ``integrate``: ``velocity3d.step3d`` with the contact count set to 0 (forces, kick, drift: what
  the step costs with nothing to solve);
* ``solve`` = step - detect - integrate (rows prepared, warm started, swept, stored).

Writes a Markdown table to ``--out`` (benchmarks/results/piles_profile.md) and JSON beside it.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

import numpy as np
from numba import njit

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests" / "piles"))

import pile_scenes  # noqa: E402

from crosscheck.engines.inhouse import InhouseEngine  # noqa: E402
from crosscheck.sim.collide import detect3d  # noqa: E402
from crosscheck.sim.rigid import velocity3d  # noqa: E402


@njit(cache=False)
def _detect_loop(g, x, q, c, steps):
    for _ in range(steps):
        detect3d(g, x, q, c)


def _best(fn, repeats: int) -> float:
    fn()  # compile or load, first-call work
    best = np.inf
    for _ in range(repeats):
        t = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t)
    return best


def profile(n: int, model: str, settle: float, steps: int, repeats: int,
            scene: str = "spheres") -> dict:
    build = pile_scenes.spheres if scene == "spheres" else pile_scenes.boxes
    pile = build(n, duration=settle)
    session = InhouseEngine().open(pile.scene, f"symplectic_euler+{model}", pile_scenes.DT)
    session.advance(int(round(settle / pile_scenes.DT)))
    st = session.contact
    start = session.state.copy()

    def full():
        session.state = start.copy()
        session.advance(steps)

    def detect():
        _detect_loop(st.geometry, start.x, start.rot, st.contacts, steps)

    rows_detected = int(detect3d(st.geometry, start.x, start.rot, st.contacts))
    sc = velocity3d.new_scratch3d(start.x.shape[0])

    def integrate():
        s = start.copy()
        for _ in range(steps):
            st.contacts.count[0] = 0
            velocity3d.step3d(*session.sim.model.kernel_args(), None, st.contacts, st.rows,
                              st.settings, sc, s.x, s.rot, s.P, s.L, pile_scenes.DT)

    stats0 = st.rows.stats.copy()  # (steps, sweeps summed, max): sequential_impulse counts
    t_step = _best(full, repeats) / steps
    d_steps = int(st.rows.stats[0] - stats0[0])
    sweeps = float(st.rows.stats[1] - stats0[1]) / d_steps if d_steps > 0 else None
    t_detect = _best(detect, repeats) / steps
    t_int = _best(integrate, repeats) / steps
    session.close()
    return {"scene": pile.name, "n": n, "model": model, "contact_rows": rows_detected,
            "step_s": t_step,
            "detect_s": t_detect, "integrate_s": t_int,
            "solve_s": t_step - t_detect - t_int, "sweeps_per_step": sweeps,
            "sweeps_max_setting": st.settings.iterations, "load": os.getloadavg()[0]}


def _sweeps(r: dict) -> str:
    if r.get("sweeps_per_step") is None:
        return "(not counted)"
    return f"{r['sweeps_per_step']:.0f} ({r['sweeps_max_setting']})"


def markdown(meta: dict, rows: list[dict]) -> str:
    lines = ["# In-house step on the sphere pile: where the time goes", "",
             f"Recorded {meta['recorded']} by `benchmarks/profile_piles.py`: the pile of "
             f"`bench_piles.py` (the scene column) after {meta['settle']:g} s, best of "
             f"{meta['repeats']} runs of "
             f"{meta['steps']} steps from the same state (detection and integration timed "
             "alone; solve = step - detect - integrate). Shared 2-core machine: load average "
             "in the last column.", "",
             "| scene | model | N | contact rows | step ms | detect ms (%) | solve ms (%) | "
             "integrate ms (%) | us per body-step | PGS sweeps per step (cap) | load |",
             "|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        s = r["step_s"]
        pct = [f"{r[k] * 1e3:.3f} ({100 * r[k] / s:.0f} %)"
               for k in ("detect_s", "solve_s", "integrate_s")]
        lines.append(f"| {r.get('scene', 'spheres_bin')} | {r['model']} | {r['n']} | "
                     f"{r['contact_rows']} | {s * 1e3:.3f} | "
                     + " | ".join(pct) + f" | {s / r['n'] * 1e6:.2f} | {_sweeps(r)} | "
                     f"{r['load']:.1f} |")
    return "\n".join(lines) + "\n"


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[200, 1000, 5000])
    ap.add_argument("--models", nargs="+", default=["soft_step", "sequential_impulse"])
    ap.add_argument("--settle", type=float, default=0.3)
    ap.add_argument("--steps", type=int, default=50)
    ap.add_argument("--scene", choices=["spheres", "boxes"], default="spheres",
                    help="spheres into a bin, or cubes into a bin (pile_scenes.boxes)")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--out", type=Path, default=ROOT / "benchmarks" / "results"
                    / "piles_profile.md")
    args = ap.parse_args(argv)
    meta = {"recorded": time.strftime("%Y-%m-%d %H:%M:%S %Z"), "settle": args.settle,
            "steps": args.steps, "repeats": args.repeats}
    rows = []
    for model in args.models:
        for n in args.sizes:
            rows.append(profile(n, model, args.settle, args.steps, args.repeats, args.scene))
            print(rows[-1], flush=True)
            args.out.write_text(markdown(meta, rows))
            args.out.with_suffix(".json").write_text(json.dumps({"meta": meta, "rows": rows},
                                                                indent=1))


if __name__ == "__main__":
    main()
