"""One ``crosscheck run``: schedule the matrix, keep every result, write the reports.

Nothing computed is lost: each result is appended to ``OUT/cells.jsonl`` (one JSON object per
line, flushed) the moment it arrives, ``results.json`` and ``summary.md`` are rewritten
atomically at most every couple of seconds while the run goes on, and on Ctrl-C or SIGTERM the
workers are killed and every report is written from what has arrived, with ``interrupted: true``
and the cells that did not run listed.
"""

from __future__ import annotations

import json
import signal
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from crosscheck.compare.verdict import FAILING
from crosscheck.report import results as results_doc
from crosscheck.runner import schedule

EXIT_OK, EXIT_FAIL, EXIT_USAGE, EXIT_INTERRUPTED = 0, 1, 2, 130


@dataclass
class RunOutcome:
    doc: dict[str, Any]
    exit_status: int
    cells: list[dict[str, Any]] = field(default_factory=list)  # with their series
    comparison: Any = None


class _Terminated(KeyboardInterrupt):
    pass


def _on_sigterm(signum, frame):  # pragma: no cover - exercised by hand
    raise _Terminated()


def run_and_report(matrix, backend, outdir: str | Path, *, command: list[str] | None = None,
                   settings: dict[str, Any] | None = None, baseline: dict[str, Any] | None = None,
                   baseline_file: str | None = None, progress=None,
                   light_interval: float = 2.0) -> RunOutcome:
    from crosscheck.report import write_all, write_light

    outdir = Path(outdir)
    outdir.mkdir(parents=True, exist_ok=True)
    doc = results_doc.new_document(command=command, settings=settings,
                                   cases=[c.to_dict() for c in matrix.cases])
    cells: list[dict[str, Any]] = []
    extra_costs: dict[str, list[dict[str, Any]]] = {}
    journal_path = outdir / "cells.jsonl"
    journal = open(journal_path, "w", encoding="utf-8")  # noqa: SIM115 - closed in finally
    started = time.monotonic()
    last_light = [0.0]

    def on_result(task, result):
        journal.write(json.dumps(results_doc.clean(result)) + "\n")
        journal.flush()
        if task.get("kind") == "cost":  # pooled into its cell's cost at the end
            extra_costs.setdefault(task["cell"], []).append(result)
            return
        if task.get("kind") == "reference":
            doc["references"].append({k: result.get(k) for k in (
                "id", "case", "engine", "integrator", "dt", "status", "reason", "path",
                "cell_seconds", "peak_rss_mb")})
        else:
            cells.append(result)
            doc["cells"].append(results_doc.light(result))
        if progress is not None:
            progress.advance(result)
        if time.monotonic() - last_light[0] > light_interval:
            last_light[0] = time.monotonic()
            _refresh(doc, cells, backend, started)
            write_light(doc, outdir)

    previous = signal.getsignal(signal.SIGTERM)
    try:
        signal.signal(signal.SIGTERM, _on_sigterm)
    except ValueError:  # not the main thread (tests): no handler
        previous = None
    interrupted = False
    try:
        if progress is not None:
            progress.__enter__()
        try:
            schedule(matrix.tasks, backend, on_result)
        except KeyboardInterrupt:
            interrupted = True
        finally:
            if progress is not None:
                progress.__exit__(None, None, None)
            backend.shutdown(kill=interrupted)
    finally:
        journal.close()
        if previous is not None:
            signal.signal(signal.SIGTERM, previous)

    from crosscheck.runner.cell import pool_costs

    for cell in cells:
        pool_costs(cell, extra_costs.get(cell["id"], []))
    doc["cells"] = [results_doc.light(c) for c in cells]
    # Final order: the matrix's (case, engine, integrator, dt), not arrival order, so two
    # results files of the same run diff cleanly.
    order = {t["id"]: i for i, t in enumerate(matrix.tasks)}
    cells.sort(key=lambda c: order.get(c["id"], len(order)))
    doc["cells"].sort(key=lambda c: order.get(c["id"], len(order)))
    done_ids = {c["id"] for c in cells}
    doc["not_run"] = [t["id"] for t in matrix.cells if t["id"] not in done_ids]
    doc["interrupted"] = interrupted
    _refresh(doc, cells, backend, started)
    comparison = None
    if baseline is not None:
        from crosscheck.baseline import compare, describe

        comparison = compare(baseline, doc)
        doc["baseline"] = dict(comparison.to_dict(), file=baseline_file,
                               **describe(baseline, doc))
        by_cell: dict[str, list[str]] = {}
        for ch in comparison.regressions:
            by_cell.setdefault(ch.key, []).append(
                ch.describe().split(": ", 1)[1])
        for group in (doc["cells"], cells):
            for c in group:
                if c["id"] in by_cell:
                    c["regression"] = by_cell[c["id"]]
    failing = any(c["status"] in FAILING for c in cells) or bool(
        comparison and comparison.regressions)
    # A run in which no cell could run checked nothing: that is not a pass.
    if cells and all(c["status"] == "not_applicable" for c in cells):
        doc["checked_nothing"] = ("every cell was not applicable: nothing was checked "
                                  f"({len(cells)} cell(s))")
        failing = True
    if interrupted:
        status = EXIT_INTERRUPTED
    else:
        status = EXIT_FAIL if failing else EXIT_OK
    doc["exit_status"] = status
    doc["finished"] = results_doc.now()
    write_all(doc, outdir, cells)
    return RunOutcome(doc=doc, exit_status=status, cells=cells, comparison=comparison)


def _refresh(doc, cells, backend, started) -> None:
    doc["counts"] = results_doc.counts(cells)
    doc["engines"] = results_doc.engine_versions(cells)
    rss = [c.get("peak_rss_mb") for c in cells if c.get("peak_rss_mb")]
    sample = getattr(backend, "sample_memory", None)
    if sample is not None:
        try:
            sample(force=True)
        except TypeError:
            sample()
    doc["resources"] = {
        "backend": getattr(backend, "name", "?"), "workers": getattr(backend, "workers", None),
        "peak_rss_total_mb": round(float(getattr(backend, "peak_rss_total_mb", 0.0)), 1),
        "peak_rss_worker_mb": round(max(rss), 1) if rss else None,
        "wall_seconds": round(time.monotonic() - started, 2),
        "workers_recycled": getattr(backend, "recycled", None),
        "workers_started_for_cost": getattr(backend, "fresh_for_cost", None),
    }
