"""Largest stable step of every engine on the contact structures (issue 11, point 6).

    PYTHONPATH=src .venv/bin/python benchmarks/stability_frontier.py [--run CASE ...]
                                                                    [--out benchmarks/results]

``--run CASE``: run ``crosscheck sweep`` on that case (a stem of :data:`CASES`; ``all`` for every
one) with the options below and copy its ``sweep.md`` and ``sweep.json`` to
``benchmarks/results/stability/<case>/``. Without ``--run``, nothing is run. Either way the
summary ``benchmarks/results/stability.md`` (and ``.json``) is rebuilt from every committed
``sweep.json`` there: per case and engine/integrator the largest stable step, the smallest
failing step, what failed there (blow-up, collapse, energy gain, error) and when (the blow-up's
or the fall's time, s), and the bracket's relative width. Every figure comes from the sweeps.

Why these options (the sweep's own, docs/reports.md "crosscheck sweep"):

* ``--dts 1e-3``: the cases' own step is the one sweep step; the frontier search doubles from it
  (up to the cap, the duration / 10: 0.5 s for the stack, 0.2 s for the mass ratios, 0.1 s for
  the pyramid) and halves below it when it already fails (down to 1.25e-4 s), then bisects on
  the number of steps to ``--frontier-width 0.05``: the reported bracket is at most 5 % wide
  unless whole step counts are adjacent (said in the table).
* ``--no-cost``: the frontier needs verdicts only; the cost pass would time every probe three
  times more on a machine shared by four engineers (one running a speed benchmark).
* ``--workers 1``: the same reason.
* integrators: every MuJoCo integrator and both PyBullet modes on the 3D cases (cheap: a few
  bodies); the in-house engine one pairing per contact model (its first pairing, the one a bare
  model name runs: ``symplectic_euler+soft_step``, ``symplectic_euler+sequential_impulse``,
  ``rk4+penalty``, ``rk4+impulse_lcp``), not all 18 pairings: the other integrators change the
  smooth part of the step, not the contact model whose stability is measured, and 18 x 4
  searches do not fit the CPU at hand. The 210-box pyramid: MuJoCo ``euler`` only (the default;
  its other integrators differ in the smooth dynamics), PyBullet multibody (the only mode in
  2D), Pymunk, and the four in-house pairings.
* the stack's ``rk4+impulse_lcp`` is a sweep of its own (``stack_10+impulse_lcp``: from 32 ms,
  at most 3 rounds; see ``EXTRA``), and the stack and the pyramid have a 300 s cell limit
  (``TIMEOUT``; the mass ratios the default 600 s): a cell that does not finish counts as a
  failure (timeout).
"""

from __future__ import annotations

import argparse
import json
import shutil
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
INHOUSE = ["inhouse.symplectic_euler+soft_step", "inhouse.symplectic_euler+sequential_impulse",
           "inhouse.rk4+penalty", "inhouse.rk4+impulse_lcp"]
MUJOCO_ALL = ["mujoco.euler", "mujoco.implicitfast", "mujoco.implicit", "mujoco.rk4",
              "mujoco.discrete"]
PYBULLET_3D = ["pybullet.multibody", "pybullet.maximal"]
CASES = {
    # The stack's rk4+impulse_lcp runs as a sweep of its own: its runs of the 5 s stack take
    # minutes from dt = 32 ms up (202 s there), and one round of the shared sweep waits for it.
    "stack_10": [*[i for i in INHOUSE if not i.endswith("impulse_lcp")], *MUJOCO_ALL,
                 *PYBULLET_3D],
    "stack_10+impulse_lcp": ["inhouse.rk4+impulse_lcp"],
    # its bracket narrowed: the first sweep's round limit left 64.1 - 86.2 ms (34.5 %)
    "stack_10+impulse_lcp_narrowed": ["inhouse.rk4+impulse_lcp"],
    "mass_ratio_100": [*INHOUSE, *MUJOCO_ALL, *PYBULLET_3D],
    "mass_ratio_1000": [*INHOUSE, *MUJOCO_ALL, *PYBULLET_3D],
    "pyramid_2d": [*INHOUSE, "mujoco.euler", "pybullet.multibody", "pymunk.position_first"],
}
# Per-cell wall limit (s) where the default 600 s would cost too much: a cell that does not
# finish counts as failing (status timeout). In-house rk4+impulse_lcp on the 1000:1 ratio ran 5 s
# at dt = 2e-3 and did not finish in 600 s at 4e-3 (mass_ratio_1000/sweep.json); at these limits
# a normal run of the case takes at most about a third of it on the loaded machine (the 1 s
# pyramid at 1e-3: 43 s quiet, docs/inhouse.md).
TIMEOUT = {"pyramid_2d": 300, "stack_10": 300}
# The stack's impulse_lcp starts at 32 ms with at most 3 search rounds: its runs of the 5 s
# stack took 5 s at 8 ms, 134 s at 16 ms and 202 s at 32 ms (all standing) in a first, shared
# sweep that was stopped in its sixth round for time (its reports are not kept), and a round
# above 32 ms may take the whole 300 s cell limit. The steps below 32 ms are not rerun here.
EXTRA = {"stack_10+impulse_lcp": ["--dts", "0.03205128205128205", "--frontier-rounds", "3"],
         "stack_10+impulse_lcp_narrowed": ["--dts", "0.0641025641025641,0.08620689655172414",
                                           "--frontier-rounds", "4"]}
NOTES = {"stack_10+impulse_lcp": "Started at 32 ms with at most 3 rounds (the script's EXTRA: "
                                 "a run takes minutes there); steps below 32 ms not rerun.",
         "stack_10+impulse_lcp_narrowed": "Bisection of the bracket the sweep above left "
                                          "(64.1 - 86.2 ms), from both ends, at most 4 rounds."}
SWEEP_OPTIONS = ["--dts", "1e-3", "--no-cost", "--workers", "1", "--frontier-width", "0.05",
                 "--progress", "plain"]


def case_file(key: str) -> str:
    """The case file's stem of a CASES key ("stack_10+impulse_lcp" is stack_10)."""
    return key.split("+", 1)[0]


def run_sweep(case: str, results: Path, scratch: Path, integrators: list[str] | None) -> None:
    out = scratch / case
    cmd = [sys.executable, "-c", "import sys; from crosscheck.cli import main; "
           "sys.exit(main(sys.argv[1:]))", "sweep", f"cases/contact/{case_file(case)}.toml",
           "--integrators", ",".join(integrators or CASES[case]), "--out", str(out),
           "--engines", ",".join(dict.fromkeys(i.split(".")[0]
                                               for i in integrators or CASES[case])),
           *SWEEP_OPTIONS]
    if case_file(case) in TIMEOUT:
        cmd += ["--timeout", str(TIMEOUT[case_file(case)])]
    cmd += EXTRA.get(case, [])
    print(" ".join(cmd), flush=True)
    subprocess.run(cmd, check=True, cwd=ROOT)
    dest = results / "stability" / case
    dest.mkdir(parents=True, exist_ok=True)
    for name in ("sweep.md", "sweep.json"):
        shutil.copy(out / name, dest / name)
    # The command line that made them, next to them.
    (dest / "command.txt").write_text("crosscheck " + " ".join(cmd[3:]) + "\n")
    explain_case(case, results)


def explain_case(case: str, results: Path) -> None:
    """failures.json next to a case's sweep.json: :func:`explain` at every series' smallest
    failing step where the structure collapsed."""
    dest = results / "stability" / case
    data = json.loads((dest / "sweep.json").read_text())
    how = {}
    for s in data["series"]:
        hi = s.get("smallest_unstable_dt")
        fail = next((r for r in s.get("runs", []) if hi and abs(r["dt"] - hi) <= 1e-9 * hi), None)
        if fail and fail["status"] == "collapsed":
            how[f"{s['engine']}-{s['integrator']}"] = explain(case, s["engine"], s["integrator"],
                                                              hi)
    (dest / "failures.json").write_text(json.dumps(how, indent=1) + "\n")


def explain(case: str, engine: str, integrator: str, dt: float) -> dict:
    """Run one failing step again (the accuracy pass alone, in this process) and say how the
    structure failed: the body that moved farthest from its starting or its settled position
    (in body sizes r; the larger of the two), and that move's parts along gravity (negative:
    down, a sink) and across it (a slide or a topple), in m, at the sample where it is
    largest."""
    import numpy as np

    from crosscheck.compare import scales
    from crosscheck.engines import get_engine
    from crosscheck.scene.loader import load_case

    scene = load_case(ROOT / "cases" / "contact" / f"{case_file(case)}.toml")
    traj = get_engine(engine).run(scene, integrator, dt)
    g = np.asarray(scene.effects.gravity, float)
    down = g / np.linalg.norm(g)
    # The two poses the collapse test measures from (docs/metrics.md): the start, and the
    # settled pose at the first sample at or after 10 % of the duration.
    settle = int(np.searchsorted(traj.t, 0.1 * scene.run.duration - 1e-12))
    best = None
    for basis, k0 in (("start", 0), ("settled", settle)):
        disp = traj.com[k0:] - traj.com[k0]  # (T', N, d)
        rel = np.linalg.norm(disp, axis=-1) / scales.body_radii(scene)
        k, i = np.unravel_index(int(np.argmax(rel)), rel.shape)
        if best is None or rel[k, i] > best[0]:
            best = (float(rel[k, i]), basis, k0 + k, i, disp[k, i])
    move, basis, k, i, d = best
    return {"body": scene.bodies[i].name, "t": float(traj.t[k]), "move_r": move,
            "from": basis, "vertical_m": float(-d @ down),  # up positive
            "horizontal_m": float(np.linalg.norm(d - (d @ down) * down)),
            "t_end": float(traj.t[-1])}


def _how(ex: dict | None) -> str:
    if not ex:
        return ""
    kind = ("mostly down" if ex["vertical_m"] < 0 and abs(ex["vertical_m"]) > ex["horizontal_m"]
            else "mostly up" if ex["vertical_m"] > ex["horizontal_m"] else "mostly sideways")
    return (f"; {kind}: {ex['body']} {ex['move_r']:.2f} r from its {ex.get('from', 'start')} "
            f"pose at t = {ex['t']:.3g} s "
            f"({1e3 * ex['vertical_m']:+.1f} mm vertical, {1e3 * ex['horizontal_m']:.1f} mm "
            "horizontal)")


def _failure(run: dict) -> str:
    what = {"blowup": "blow-up", "collapsed": "collapse", "gained_energy": "energy gain",
            "error": "error", "timeout": "timeout"}.get(run["status"], run["status"])
    parts = [what]
    if run.get("time") is not None:
        parts.append(f"at t = {run['time']:.3g} s")
    if run["status"] == "gained_energy" and run.get("energy_gain") is not None:
        parts.append(f"(gain {run['energy_gain']:.3g})")
    if run["status"] in ("error", "timeout") and run.get("reason"):
        parts.append(f"({run['reason'][:60]})")
    elif run["status"] == "blowup" and run.get("reason"):
        # "blew up at t = T s: why": the time is already there, keep the why
        parts.append(f"({run['reason'].split(': ', 1)[-1][:70]})")
    return " ".join(parts)


def summarise(results: Path) -> tuple[str, dict]:
    lines = ["# Largest stable step on the contact structures",
             "",
             "Made by `benchmarks/stability_frontier.py` from the committed sweeps in "
             "`benchmarks/results/stability/<case>/sweep.json` (each folder's `command.txt` "
             "is the sweep's command line). Stable: no blow-up, error or timeout; no body "
             "left a ball of 0.1 x its size around its starting or settled position "
             "(`collapse_time_start`, `collapse_time`); energy gain within the case's limit, "
             "else 1e-2 of `S_E` (docs/reports.md, \"crosscheck sweep\"). The bracket is "
             "found by doubling from the case's dt 1e-3 s (halving below it when it fails), "
             "then bisection on the number of steps to 5 % relative width.", ""]
    doc: dict = {"cases": {}}
    for case in CASES:
        path = results / "stability" / case / "sweep.json"
        if not path.is_file():
            lines += [f"## {case}", "", "not run (no sweep.json committed)", ""]
            continue
        data = json.loads(path.read_text())
        how_path = path.parent / "failures.json"
        how = json.loads(how_path.read_text()) if how_path.is_file() else {}
        fr = data["frontier"]
        lines += [f"## {case} ({data['case']})", "",
                  f"Sweep step(s) {', '.join(f'{d:.4g}' for d in data['dts'])} s; cap "
                  f"{fr['cap']:.4g} s, floor {fr.get('floor', float('nan')):.4g} s, "
                  f"{fr['rounds']} search round(s) of at most {fr['max_rounds']}."
                  + (" " + NOTES[case] if case in NOTES else ""), "",
                  "| engine-integrator | largest stable dt (s) | smallest failing dt (s) | "
                  "what failed there | width | frontier |", "|---|---|---|---|---|---|"]
        rows = []
        for s in data["series"]:
            label = f"{s['engine']}-{s['integrator']}"
            if f"{s['engine']}.{s['integrator']}" not in CASES[case]:
                continue  # an engine's default series the sweep ran besides (no --engines)
            if s.get("not_applicable"):
                lines.append(f"| {label} | n/a | n/a | not applicable: "
                             f"{s['not_applicable'][:60]} | | |")
                continue
            lo, hi = s["largest_stable_dt"], s["smallest_unstable_dt"]
            fail = next((r for r in s.get("runs", []) if hi is not None and
                         abs(r["dt"] - hi) <= 1e-9 * hi), None)
            width = f"{(hi - lo) / lo:.1%}" if lo and hi else "-"
            lines.append(f"| {label} | {lo:.5g} | " if lo else f"| {label} | none | ")
            lines[-1] += (f"{hi:.5g} | " if hi else "none up to the cap | ")
            lines[-1] += (f"{_failure(fail)}{_how(how.get(label))} | " if fail else "- | ") \
                + f"{width} | {s['frontier']} |"
            rows.append({"series": label, "largest_stable_dt": lo, "smallest_unstable_dt": hi,
                         "failure": fail, "how": how.get(label), "frontier": s["frontier"]})
        doc["cases"][case] = {"case": data["case"], "frontier": fr, "series": rows}
        lines.append("")
    lines += _per_engine(doc)
    return "\n".join(lines), doc


SHORT = {"blowup": "blow-up", "collapsed": "falls", "gained_energy": "gains energy",
         "error": "error", "timeout": "timeout"}


def _per_engine(doc: dict) -> list[str]:
    """Per engine, a table of its series against the cases: the bracket (largest stable -
    smallest failing step, ms) and how it failed; docs/engines.md and docs/inhouse.md quote
    these."""
    out = ["## Per engine (dt in ms: largest stable - smallest failing)", ""]
    # A column per case file: the stack's own impulse_lcp sweep joins the stack's column.
    cases = list(dict.fromkeys(case_file(k) for k in doc["cases"]))
    engines: dict[str, dict[str, dict[str, str]]] = {}
    for key in doc["cases"]:
        case = case_file(key)
        for row in doc["cases"][key]["series"]:
            engine, integrator = row["series"].split("-", 1)
            lo, hi, fail, how = (row["largest_stable_dt"], row["smallest_unstable_dt"],
                                 row["failure"], row.get("how"))
            if hi is None:
                text = f">= {1e3 * lo:.4g} (cap)" if lo else "none"
            else:
                what = SHORT.get(fail["status"], fail["status"]) if fail else "?"
                if how and fail and fail["status"] == "collapsed":
                    what = ("falls, mostly down" if how["vertical_m"] < 0
                            and -how["vertical_m"] > how["horizontal_m"]
                            else "falls, mostly sideways")
                text = (f"{1e3 * lo:.4g} - {1e3 * hi:.4g} ({what})" if lo else
                        f"< {1e3 * hi:.4g} ({what})")
            engines.setdefault(engine, {}).setdefault(integrator, {})[case] = text
    for engine, rows in engines.items():
        out += [f"### {engine}", "", "| integrator | " + " | ".join(cases) + " |",
                "|---|" + "---|" * len(cases)]
        for integrator, by_case in rows.items():
            out.append(f"| {integrator} | " + " | ".join(by_case.get(c, "-")
                                                         for c in cases) + " |")
        out.append("")
    out += ["-: not among the case's series (Pymunk is 2D only, PyBullet's maximal mode 3D "
            "only; the pyramid runs MuJoCo's euler only). Falls: the largest move of a body "
            "from its starting or settled pose at the smallest failing step, mostly down (a "
            "sink into the body below or the ground) or mostly sideways (a slide or topple).",
            ""]
    return out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--run", nargs="*", default=[], metavar="CASE")
    ap.add_argument("--integrators", default=None, metavar="X,Y",
                    help="only these series of the case (a partial rerun)")
    ap.add_argument("--out", default=str(ROOT / "benchmarks" / "results"))
    ap.add_argument("--scratch", default=str(ROOT / "reports" / "stability"))
    ap.add_argument("--explain", nargs="*", default=[], metavar="CASE",
                    help="only rerun the failing steps of these cases' committed sweeps "
                         "(failures.json)")
    args = ap.parse_args()
    results = Path(args.out)
    for case in args.explain:
        explain_case(case, results)
    todo = list(CASES) if "all" in args.run else args.run
    for case in todo:
        if case not in CASES:
            ap.error(f"unknown case {case!r}; known: {', '.join(CASES)}")
        run_sweep(case, results, Path(args.scratch),
                  args.integrators.split(",") if args.integrators else None)
    text, doc = summarise(results)
    (results / "stability.md").write_text(text + "\n")
    (results / "stability.json").write_text(json.dumps(doc, indent=1) + "\n")
    print(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
