"""``crosscheck sweep CASE``: every engine's integrators over a range of time steps.

Runs the case at ``--dts`` (default: the case's dt times 4, 2, 1, 1/2, 1/4, 1/8) through the
ordinary runner (isolated workers, the same metrics and reports in ``--out``), then writes
``sweep.md``, ``sweep.json``, ``sweep.png`` and ``sweep.html`` (the page: figure and table)
there: error against wall time (a Pareto plot), error against dt with the empirical order of
convergence, and the largest stable step of each integrator (definitions in
crosscheck.study.sweep and docs/reports.md).
"""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path

from crosscheck.commands._json import add_json_flag, emit, human_output

ORDER = 6  # its place in crosscheck --help
FRONTIER_WIDTH = 0.05  # stop bisecting when (unstable - stable) / stable is at most this
FRONTIER_ROUNDS = 16  # runner rounds of doubling and bisection, all series together
CAP_FRACTION = 0.1  # default cap of the doubling: the duration / 10
FLOOR_DIVISOR = 8.0  # default floor of the halving: the smallest sweep step / 8


def register(subparsers) -> argparse.ArgumentParser:
    p = subparsers.add_parser("sweep", help="integrators over a range of steps: accuracy, cost, "
                              "order of convergence, largest stable step",
                              description=__doc__.split("\n\n")[1])
    p.add_argument("case", metavar="CASE", help="one case file")
    p.add_argument("--dts", metavar="X,Y,...", help="steps to run (default: case dt x 4 ... /8)")
    p.add_argument("--engines", metavar="A,B")
    p.add_argument("--integrators", metavar="X,Y",
                   help="instead of the case's lists; default: every integrator each engine has")
    p.add_argument("--metric", default=None,
                   help="error metric (default: position_error_max, else orientation_error_max, "
                        "else energy_drift)")
    p.add_argument("--target", type=float, default=None, metavar="X",
                   help="name the cheapest engine, integrator and dt whose error stays <= X")
    p.add_argument("--max-dt", type=float, default=None, metavar="S",
                   help="cap of the stability search (default: the duration / 10)")
    p.add_argument("--min-dt", type=float, default=None, metavar="S",
                   help="floor of the stability search below a step that fails (default: the "
                        f"smallest sweep step / {FLOOR_DIVISOR:g})")
    p.add_argument("--no-cost", action="store_true",
                   help="skip the cost pass (timed stepping) of every cell: the frontier needs "
                        "only the verdicts; no cost axis, no --target")
    p.add_argument("--frontier-width", type=float, default=FRONTIER_WIDTH, metavar="F",
                   help="bisect the stability bracket until (unstable - stable) / stable <= F "
                        f"(default {FRONTIER_WIDTH:g})")
    p.add_argument("--frontier-rounds", type=int, default=FRONTIER_ROUNDS, metavar="N",
                   help=f"at most N runner rounds of stability search (default {FRONTIER_ROUNDS};"
                        " 0: none)")
    p.add_argument("--out", default=None, metavar="DIR",
                   help="output folder (default: reports/sweep-<case>)")
    p.add_argument("--workers", type=int, default=None, metavar="N")
    p.add_argument("--timeout", type=float, default=None, metavar="S")
    p.add_argument("--engine-ref", action="append", default=[], metavar="NAME=MODULE:CLASS",
                   help="use this adapter class for engine NAME (tests, adapters in development)")
    p.add_argument("--progress", choices=("auto", "bar", "plain", "none"), default="auto")
    add_json_flag(p)
    p.set_defaults(func=run)
    return p


def _all_integrators(scene, engines, engine_refs) -> list[str]:
    """Every integrator of every engine the case runs on, as 'engine.integrator' entries."""
    from crosscheck.runner.cell import resolve_engine

    out = []
    for name in scene.run.engines:
        if engines and name not in engines:
            continue
        try:
            engine = resolve_engine(name, engine_refs)
            caps = engine.capabilities()
        except Exception:
            continue
        # Leave out what cannot run this scene at all (fluid schemes on a rigid case).
        out += [f"{name}.{i}" for i in caps.integrators if not engine.not_applicable(scene, i)]
    return out


def _default_dts(scene) -> list[float]:
    """The case's dt times 4, 2, 1, 1/2, 1/4, 1/8; for a rigid case each rounded to the nearest
    step that divides the duration (a run takes exactly duration / dt steps)."""
    dts = [scene.run.dt * f for f in (4, 2, 1, 0.5, 0.25, 0.125)]
    if scene.fluid is not None:
        return dts
    from crosscheck.scene.model import dividing_step

    return list(dict.fromkeys(dividing_step(scene.run.duration, dt) for dt in dts))


def run(args) -> int:
    with human_output(args.json):
        status, payload = _run(args)
    if args.json:
        emit(payload)
    return status


def _steps(duration: float, dt: float) -> int:
    return max(1, round(duration / dt))


def next_probe(duration: float, stable: float | None, unstable: float | None, cap: float,
               width: float, floor: float | None = None) -> float | None:
    """The next step to try for one series, or None when its frontier is settled.

    Halving while every step run is unstable: ``dt = duration / (2 N_unstable)``, never below
    ``floor`` (None: no search below the smallest step run), so a series that fails at every
    sweep step still gets a bracket instead of "below the smallest step".

    Doubling while every step run is stable: ``dt = duration / N`` with ``N`` the whole number
    of steps nearest ``duration / (2 dt)``, never above the cap. Bisection between the largest
    stable and the smallest unstable step on the number of steps: ``N = (N_stable +
    N_unstable) // 2``, until ``(unstable - stable) / stable <= width`` or the counts are
    adjacent (no whole step lies between).
    """
    if stable is None:
        if unstable is None or floor is None or unstable <= floor * (1 + 1e-9):
            return None
        dt = duration / (2 * _steps(duration, unstable))
        return dt if dt >= floor * (1 - 1e-9) else None
    if unstable is None:
        if stable >= cap * (1 - 1e-9):
            return None
        n = max(_steps(duration, 2 * stable), math.ceil(duration / cap - 1e-9))
        dt = duration / n
        return dt if dt > stable * (1 + 1e-9) else None
    if (unstable - stable) / stable <= width * (1 + 1e-6):
        return None
    n_s, n_u = _steps(duration, stable), _steps(duration, unstable)
    if n_s - n_u <= 1:
        return None
    return duration / ((n_s + n_u) // 2)


def _probe_matrix(scene, probes, out, refs, timeout, reference_dir, cost=True):
    """One runner matrix holding just the probe cells (engine, integrator, dt)."""
    from crosscheck.runner.plan import build_matrix

    merged = None
    for engine, integrator, dt in probes:
        m = build_matrix([scene], engines=[engine], integrators=[f"{engine}.{integrator}"],
                         dts=[dt], out=out, timeout=timeout, engine_refs=refs,
                         reference_dir=reference_dir, cost=cost)
        if merged is None:
            merged = m
            continue
        have = {t["id"] for t in merged.tasks}
        merged.tasks = ([t for t in merged.tasks if t["kind"] == "reference"]
                        + [t for t in m.references if t["id"] not in have]
                        + merged.cells + m.cells)
        merged.engines += [e for e in m.engines if e not in merged.engines]
    return merged


def _run(args) -> tuple[int, dict]:
    from crosscheck.commands.run import _engine_refs
    from crosscheck.report import sweep_page
    from crosscheck.report.atomic import write_bytes, write_text
    from crosscheck.runner.cell import safe_name
    from crosscheck.runner.local import LocalBackend
    from crosscheck.runner.plan import UsageError, build_matrix, parse_dts, parse_list
    from crosscheck.runner.progress import make_progress
    from crosscheck.runner.session import run_and_report
    from crosscheck.scene.loader import load_case
    from crosscheck.study import sweep

    for flag, value, ok, expected in (
            ("--target", args.target, lambda v: v is None or (v > 0 and math.isfinite(v)),
             "a positive error"),
            ("--max-dt", args.max_dt, lambda v: v is None or (v > 0 and math.isfinite(v)),
             "a positive step in s"),
            ("--min-dt", args.min_dt, lambda v: v is None or (v > 0 and math.isfinite(v)),
             "a positive step in s"),
            ("--frontier-width", args.frontier_width, lambda v: 0 < v < 1 and math.isfinite(v),
             "a relative width between 0 and 1"),
            ("--frontier-rounds", args.frontier_rounds, lambda v: v >= 0, "rounds >= 0")):
        if not ok(value):
            raise UsageError(f"{flag}: expected {expected}, got {value}")
    if not Path(args.case).is_file():
        raise UsageError(f"{args.case}: no such case file")
    if args.no_cost and args.target is not None:
        raise UsageError("--target needs the cost pass: drop --no-cost")
    refs = _engine_refs(args.engine_ref)
    scene = load_case(args.case, unchecked_engines=refs)
    dts = parse_dts(args.dts) or _default_dts(scene)
    engines = parse_list(args.engines)
    integrators = parse_list(args.integrators) or _all_integrators(scene, engines, refs)
    out = Path(args.out or f"reports/sweep-{safe_name(scene.name)}")
    cost = not args.no_cost
    matrix = build_matrix([scene], engines=engines, integrators=integrators, dts=dts, out=out,
                          timeout=args.timeout, engine_refs=refs, cost=cost)
    # A contact structure that must stand fails by falling or gaining energy, too.
    stands = sweep.must_stand(scene)
    backend = LocalBackend(args.workers)
    print(f"crosscheck sweep: {scene.name}, {len(matrix.cells)} cell(s) at dt = "
          + ", ".join(f"{d:g}" for d in dts) + f" -> {out}", flush=True)
    progress = None if args.progress == "none" else make_progress(
        len(matrix.tasks), args.progress)
    outcome = run_and_report(matrix, backend, out, command=["crosscheck", "sweep", args.case],
                             settings={"sweep": True, "dts": dts}, progress=progress)
    cells = list(outcome.cells)
    interrupted = bool(outcome.doc.get("interrupted"))

    # The stability frontier: doubling past the largest stable step, then bisection of the
    # bracket, each round one runner matrix of the cells still needed (rigid cases only: a
    # fluid's steps are adaptive).
    duration = scene.run.duration
    cap = args.max_dt if args.max_dt is not None else CAP_FRACTION * duration
    if scene.fluid is None:
        cap = duration / math.ceil(duration / cap - 1e-9)  # a step that divides the duration
    search = scene.fluid is None and args.frontier_rounds > 0
    floor = args.min_dt if args.min_dt is not None else min(dts) / FLOOR_DIVISOR
    rounds = 0
    while search and not interrupted and rounds < args.frontier_rounds:
        _, series = sweep.analyse(cells, args.metric, stands=stands)
        probes = []
        for s in series:
            if s.not_applicable:
                continue
            dt = next_probe(duration, s.largest_stable_dt, s.smallest_unstable_dt, cap,
                            args.frontier_width, floor)
            if dt is not None and not any(sweep._same(dt, p) for p in
                                          [*s.dts, *(q["dt"] for q in s.probes)]):
                probes.append((s.engine, s.integrator, dt))
        if not probes:
            break
        rounds += 1
        where = out / "frontier" / f"round-{rounds}"
        print(f"frontier round {rounds}: " + ", ".join(
            f"{e}-{i}@{d:.4g}" for e, i, d in probes), flush=True)
        m = _probe_matrix(scene, probes, where, refs, args.timeout, out / "references", cost)
        res = run_and_report(m, backend, where, command=["crosscheck", "sweep", args.case],
                             settings={"sweep": True, "frontier_round": rounds})
        cells += res.cells
        interrupted = bool(res.doc.get("interrupted"))

    metric, series = sweep.analyse(cells, args.metric, dts, cap=cap, width=args.frontier_width,
                                   searched=search, stands=stands, floor=floor)
    text = f"# Sweep of {scene.name}\n\n" + sweep.table(metric, series, args.target) + "\n"
    if search:
        text += (f"\nStability frontier: doubling from the largest stable step up to the cap "
                 f"{cap:.4g} s (halving below a failing smallest step down to {floor:.4g} s), "
                 "then bisection on the number of steps until the bracket is "
                 f"within {args.frontier_width:.0%} or whole step counts are adjacent; "
                 f"{rounds} round(s) of at most {args.frontier_rounds}; every probe's reports "
                 f"in {out / 'frontier'}.\n")
        if stands:
            text += ("\nA structure that must stand (study.sweep.must_stand): a run is stable "
                     "only if, besides not blowing up, no body left a ball of "
                     "0.1 x its size around its starting or its settled position "
                     "(`collapse_time`, `collapse_time_start`) and its energy gain stayed "
                     f"within the case's limit (else {sweep.STRUCTURE_ENERGY_GAIN:g}).\n")
    write_text(out / "sweep.md", text)
    summary = {"case": scene.name, "metric": metric, "dts": dts,
               "frontier": {"searched": search, "cap": cap, "floor": floor, "stands": stands,
                            "width": args.frontier_width, "cost": cost,
                            "rounds": rounds, "max_rounds": args.frontier_rounds},
               "series": [s.to_dict() for s in series],
               "pareto": [dict(zip(("label", "dt", "cost", "error"), p, strict=True))
                          for p in sweep.pareto(series)]}
    if args.target is not None:
        summary["target"] = {"value": args.target, "metric": metric,
                             "cheapest": sweep.cheapest(series, args.target)}
    write_text(out / "sweep.json", json.dumps(summary, indent=1) + "\n")
    png = sweep.figure(scene.name, metric, series, args.target)
    write_bytes(out / "sweep.png", png)
    sweep_page.write(out, scene.name, text, png)
    print()
    print(text)
    print(f"page: {out / 'sweep.html'} (plots: sweep.png); every cell: {out / 'index.html'}")
    # A sweep explores: blow-ups at large steps are findings, not failures.
    return (0 if not interrupted else 130), summary
