"""``crosscheck sweep CASE``: every engine's integrators over a range of time steps.

Runs the case at ``--dts`` (default: the case's dt times 4, 2, 1, 1/2, 1/4, 1/8) through the
ordinary runner (isolated workers, the same metrics and reports in ``--out``), then writes
``sweep.md``, ``sweep.json`` and ``sweep.png`` there: error against wall time (a Pareto plot),
error against dt with the empirical order of convergence, and the largest stable step of each
integrator (definitions in crosscheck.study.sweep and docs/reports.md).
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from crosscheck.commands._json import add_json_flag, emit, human_output

ORDER = 6  # its place in crosscheck --help


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
    duration = scene.run.duration
    out = []
    for dt in dts:
        steps = max(1, round(duration / dt))
        dt = dt if abs(steps * dt - duration) <= 1e-9 * duration else duration / steps
        if dt not in out:
            out.append(dt)
    return out


def run(args) -> int:
    with human_output(args.json):
        status, payload = _run(args)
    if args.json:
        emit(payload)
    return status


def _run(args) -> tuple[int, dict]:
    from crosscheck.commands.run import _engine_refs
    from crosscheck.report.atomic import write_bytes, write_text
    from crosscheck.runner.cell import safe_name
    from crosscheck.runner.local import LocalBackend
    from crosscheck.runner.plan import UsageError, build_matrix, parse_dts, parse_list
    from crosscheck.runner.progress import make_progress
    from crosscheck.runner.session import run_and_report
    from crosscheck.scene.loader import load_case
    from crosscheck.study import sweep

    if not Path(args.case).is_file():
        raise UsageError(f"{args.case}: no such case file")
    refs = _engine_refs(args.engine_ref)
    scene = load_case(args.case, unchecked_engines=refs)
    dts = parse_dts(args.dts) or _default_dts(scene)
    engines = parse_list(args.engines)
    integrators = parse_list(args.integrators) or _all_integrators(scene, engines, refs)
    out = Path(args.out or f"reports/sweep-{safe_name(scene.name)}")
    matrix = build_matrix([scene], engines=engines, integrators=integrators, dts=dts, out=out,
                          timeout=args.timeout, engine_refs=refs)
    backend = LocalBackend(args.workers)
    print(f"crosscheck sweep: {scene.name}, {len(matrix.cells)} cell(s) at dt = "
          + ", ".join(f"{d:g}" for d in dts) + f" -> {out}", flush=True)
    progress = None if args.progress == "none" else make_progress(
        len(matrix.tasks), args.progress)
    outcome = run_and_report(matrix, backend, out, command=["crosscheck", "sweep", args.case],
                             settings={"sweep": True, "dts": dts}, progress=progress)
    metric, series = sweep.analyse(outcome.cells, args.metric)
    text = f"# Sweep of {scene.name}\n\n" + sweep.table(metric, series) + "\n"
    write_text(out / "sweep.md", text)
    summary = {"case": scene.name, "metric": metric, "dts": dts,
               "series": [s.to_dict() for s in series],
               "pareto": [dict(zip(("label", "dt", "cost", "error"), p, strict=True))
                          for p in sweep.pareto(series)]}
    write_text(out / "sweep.json", json.dumps(summary, indent=1) + "\n")
    write_bytes(out / "sweep.png", sweep.figure(scene.name, metric, series))
    print()
    print(text)
    print(f"plots: {out / 'sweep.png'}; every cell: {out / 'index.html'}")
    # A sweep explores: blow-ups at large steps are findings, not failures.
    return (0 if not outcome.doc.get("interrupted") else 130), summary
