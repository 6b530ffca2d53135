"""``crosscheck run PATH...``: every case on every applicable engine and integrator.

Runs the matrix case x engine x integrator x dt in worker processes (local cores, or a Dask
cluster with ``--scheduler``), prints a table of end-state differences, and writes
``results.json``, ``summary.md``, ``junit.xml`` and ``index.html`` into ``--out``.

Exit status: 0 every applicable cell passes (and nothing regressed against ``--baseline``);
1 a cell failed, blew up, errored or timed out, or a metric regressed; 2 a usage or input error
(a broken case file, an unknown engine, a missing baseline); 130 interrupted (the reports of what
ran are still written).
"""

from __future__ import annotations

import argparse
import math
import os
import sys
from pathlib import Path

from crosscheck.commands._end_table import end_state_table
from crosscheck.commands._json import add_json_flag, emit, human_output
from crosscheck.errors import CrosscheckError

ORDER = 4  # its place in crosscheck --help


def register(subparsers) -> argparse.ArgumentParser:
    p = subparsers.add_parser(
        "run", help="run cases on every applicable engine and integrator, write reports",
        description=__doc__.split("\n\n")[1] if __doc__ else None,
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog="exit status: 0 all applicable cells pass, 1 a failure or regression, "
               "2 a usage or input error, 130 interrupted")
    p.add_argument("paths", nargs="+", metavar="PATH",
                   help="case files or folders (searched recursively for *.toml case files)")
    p.add_argument("--engines", metavar="A,B",
                   help="only these engines (of those each case lists): inhouse, mujoco, "
                        "pybullet, pymunk")
    p.add_argument("--integrators", metavar="X,Y",
                   help="run these integrators instead of each case's list; 'engine.integrator' "
                        "applies to one engine")
    p.add_argument("--dt", metavar="X[,Y]", help="time step(s) instead of each case's dt")
    p.add_argument("--out", default="reports/latest", metavar="DIR",
                   help="output folder for the reports (default: reports/latest)")
    p.add_argument("--save-trajectories", action="store_true",
                   help="also write every trajectory as DIR/trajectories/<case>/"
                        "<engine>-<integrator>-dt<dt>.npz")
    p.add_argument("--no-cost", action="store_true",
                   help="skip the cost pass (timed stepping without recording): verdicts only")
    p.add_argument("--cost-repeats", type=int, default=None, metavar="N",
                   help="time each cell's stepping at least N times (default 3)")
    p.add_argument("--cost-processes", type=int, default=None, metavar="K",
                   help="spread each rigid cell's cost pass over K tasks run later in whichever "
                        "worker is free, pooled so a process's own timing offset is inside the "
                        "reported spread (default 3; 1 times the cell's own process only)")
    p.add_argument("--cost-seconds", type=float, default=None, metavar="S",
                   help="and for at least S seconds in all (default 0.2)")
    p.add_argument("--workers", type=int, default=None, metavar="N",
                   help=f"worker processes (default: the number of cores, {os.cpu_count()})")
    p.add_argument("--worker-memory", type=float, default=768.0, metavar="MB",
                   help="replace a local worker whose resident memory exceeds this after a cell "
                        "(default: 768)")
    p.add_argument("--scheduler", metavar="ADDRESS",
                   help="run on a Dask distributed cluster (e.g. tcp://host:8786)")
    p.add_argument("--baseline", metavar="FILE",
                   help="compare with a committed baseline (reports/baseline.json); "
                        "a regression exits 1")
    p.add_argument("--timeout", type=float, default=None, metavar="S",
                   help="wall seconds per cell before it is killed (default: each case's "
                        "run.timeout)")
    p.add_argument("--progress", choices=("auto", "bar", "plain", "none"), default="auto",
                   help="progress display (default: a bar on a terminal, lines otherwise)")
    p.add_argument("--engine-ref", action="append", default=[], metavar="NAME=MODULE:CLASS",
                   help="use this adapter class for engine NAME (adapters under development, "
                        "tests); repeatable")
    add_json_flag(p)
    p.set_defaults(func=run)
    return p


def _engine_refs(items: list[str]) -> dict[str, str]:
    from crosscheck.runner.plan import UsageError

    out = {}
    for item in items:
        name, _, ref = item.partition("=")
        if not name or ":" not in ref:
            raise UsageError(f"--engine-ref: expected NAME=MODULE:CLASS, got {item!r}")
        out[name.strip()] = ref.strip()
    return out


def _cost_option(args) -> bool | dict:
    """--no-cost, --cost-repeats, --cost-processes, --cost-seconds as build_matrix's ``cost``."""
    from crosscheck.runner.plan import UsageError

    if args.no_cost:
        return False
    plan = {}
    if args.cost_repeats is not None:
        if args.cost_repeats < 1:
            raise UsageError("--cost-repeats: expected a positive integer, "
                             f"got {args.cost_repeats}")
        plan["min_repeats"] = args.cost_repeats
    if args.cost_processes is not None:
        if args.cost_processes < 1:
            raise UsageError("--cost-processes: expected a positive integer, "
                             f"got {args.cost_processes}")
        plan["processes"] = args.cost_processes
    if args.cost_seconds is not None:
        if not args.cost_seconds >= 0:
            raise UsageError(f"--cost-seconds: expected seconds >= 0, got {args.cost_seconds}")
        plan["min_seconds"] = args.cost_seconds
    return plan or True


def _nothing_to_run(scenes, matrix) -> list[str]:
    """A line per case none of whose cells any engine can run, with each engine's reason:
    said before the run starts (the run then fails if no case has anything to run)."""
    from crosscheck.runner.cell import resolve_engine

    by_case: dict[str, list[dict]] = {}
    for task in matrix.cells:
        by_case.setdefault(task["case"], []).append(task)
    lines = []
    for scene in scenes:
        reasons = []
        for task in by_case.get(scene.name, []):
            try:
                engine = resolve_engine(task["engine"], task.get("engine_refs"))
                reason = engine.not_applicable(scene, task["integrator"])
            except Exception as exc:  # noqa: BLE001 - an unimportable engine runs nothing
                reason = f"{type(exc).__name__}: {exc}"
            if reason is None:
                break
            reasons.append(f"{task['engine']}-{task['integrator']}: {reason}")
        else:
            if reasons:
                lines.append(f"{scene.source}: nothing to run: " + "; ".join(
                    dict.fromkeys(reasons)))
    return lines


def run(args) -> int:
    with human_output(args.json):
        status, doc = _run(args)
    if args.json:
        emit(doc)
    return status


def _run(args) -> tuple[int, dict]:
    from crosscheck.baseline import load_baseline
    from crosscheck.runner.plan import UsageError, build_matrix, parse_dts, parse_list
    from crosscheck.runner.progress import make_progress
    from crosscheck.runner.session import run_and_report
    from crosscheck.scene.loader import find_cases, load_case

    if args.workers is not None and args.workers < 1:
        raise UsageError("--workers must be at least 1")
    if args.timeout is not None and not (args.timeout > 0 and math.isfinite(args.timeout)):
        raise UsageError("--timeout must be a positive number of seconds")
    for path in args.paths:
        if not Path(path).exists():
            raise UsageError(f"{path}: no such file or folder")
    files = find_cases(args.paths)
    if not files:
        raise UsageError(f"no case files under {' '.join(args.paths)}")
    refs = _engine_refs(args.engine_ref)
    # A broken case file (a misspelt integrator too) stops here: exit 2. Engines replaced by
    # --engine-ref adapters keep their own integrator names, checked when the cell runs.
    scenes = [load_case(f, unchecked_engines=refs) for f in files]
    baseline = load_baseline(args.baseline) if args.baseline else None
    matrix = build_matrix(
        scenes, engines=parse_list(args.engines), integrators=parse_list(args.integrators),
        dts=parse_dts(args.dt), out=args.out, save_trajectories=args.save_trajectories,
        timeout=args.timeout, engine_refs=refs, cost=_cost_option(args))
    if not matrix.cells:
        raise UsageError("no cells to run: no case lists any of the selected engines")
    for line in _nothing_to_run(scenes, matrix):
        print(line, file=sys.stderr)

    if args.scheduler:
        from crosscheck.runner.dask_backend import DaskBackend

        try:
            backend = DaskBackend(args.scheduler)
        except (OSError, TimeoutError) as exc:
            raise CrosscheckError(f"cannot reach the Dask scheduler {args.scheduler}: {exc}") \
                from None
    else:
        from crosscheck.runner.local import LocalBackend

        backend = LocalBackend(args.workers, max_worker_rss_mb=args.worker_memory)
    n_cells, n_refs = len(matrix.cells), len(matrix.references)
    print(f"crosscheck: {len(scenes)} case(s), {n_cells} cell(s)"
          + (f" + {n_refs} reference run(s)" if n_refs else "")
          + f" on {backend.workers} {backend.name} worker(s) -> {args.out}", flush=True)
    progress = None if args.progress == "none" else make_progress(
        n_cells + n_refs, args.progress)
    settings = {
        "backend": backend.name, "workers": backend.workers, "scheduler": args.scheduler,
        "engines": args.engines, "integrators": args.integrators, "dt": args.dt,
        "timeout": args.timeout, "out": args.out, "save_trajectories": args.save_trajectories,
        "baseline": args.baseline,
    }
    outcome = run_and_report(matrix, backend, args.out, command=sys.argv, settings=settings,
                             baseline=baseline, baseline_file=args.baseline, progress=progress)
    print()
    print(end_state_table(outcome.cells))
    if outcome.comparison is not None:
        print()
        print(f"against the baseline {args.baseline}:")
        print("\n".join(outcome.comparison.lines()))
    from crosscheck.report.markdown import headline

    res = outcome.doc.get("resources", {})
    print()
    print(headline(outcome.doc))
    print(f"peak resident memory {res.get('peak_rss_total_mb')} MiB over {res.get('workers')} "
          f"{res.get('backend')} worker(s) (largest single cell {res.get('peak_rss_worker_mb')} "
          f"MiB); wall {res.get('wall_seconds')} s")
    print(f"reports: {Path(args.out) / 'index.html'}, results.json, summary.md, junit.xml")
    return outcome.exit_status, outcome.doc
