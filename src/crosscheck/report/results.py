"""``results.json``: the versioned, machine-readable record of one run.

Schema ``crosscheck-results``, version :data:`SCHEMA_VERSION` (bumped on any incompatible
change; docs/reports.md documents every field)::

    schema, schema_version, crosscheck_version, commit, command, started, finished, interrupted,
    exit_status, machine {hostname, platform, python, cpu_count, memory_total_mb},
    settings {backend, workers, scheduler, engines, integrators, dt, timeout, out,
              save_trajectories, baseline},
    engines {name: version | "unavailable: reason"},
    cases [{name, file, sha256, description, tags, dimension, duration, reference,
            tolerances, fluid}],
    references [{id, case, engine, integrator, dt, status, reason, path, cell_seconds}],
    cells [{id, case, case_file, case_sha256, engine, engine_version, integrator, dt,
            status (pass|fail|blowup|error|timeout|not_applicable), reason,
            metrics {name: {value, limit, passed, meaningful, note, unit, value_text}},
            worst {metric, value, limit, ratio}, cost (wall s per simulated s),
            cost_vs_mujoco (cost / MuJoCo's cost in the same run, see mujoco_cost_ratios),
            wall_time, simulated_time, cell_seconds, failure, end_state, reference_end,
            regression [..], trajectory_file, plots, peak_rss_mb,
            fluid, bodies, samples, body_trajectory_file (a fluid cell; end_state its body's)}],
    not_run [cell ids], counts {status: n},
    resources {peak_rss_total_mb, peak_rss_worker_mb, wall_seconds, backend, workers},
    baseline {file, source {created, crosscheck_version, commit, started, machine, engines},
              compared, engine_changes, regressions, improvements, status_changes, new,
              missing, missing_cases, changed_cases, dropped_metrics} | null

Non-finite numbers are written as ``null`` (JSON has no NaN); a metric that was NaN or infinite
keeps its text in ``value_text``.
"""

from __future__ import annotations

import datetime as _dt
import json
import math
import os
import platform
import socket
import sys
from pathlib import Path
from typing import Any

SCHEMA = "crosscheck-results"
SCHEMA_VERSION = 1
# Keys of a cell result that stay out of results.json (plot data lives in the journal).
HEAVY_KEYS = ("series",)


def now() -> str:
    return _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds")


def machine() -> dict[str, Any]:
    info: dict[str, Any] = {
        "hostname": socket.gethostname(), "platform": platform.platform(),
        "machine": platform.machine(), "processor": platform.processor(),
        "python": sys.version.split()[0], "cpu_count": os.cpu_count(),
    }
    try:
        import psutil

        info["memory_total_mb"] = round(psutil.virtual_memory().total / 2**20)
    except Exception:  # pragma: no cover
        pass
    return info


def source_commit() -> str | None:
    """The git commit of the crosscheck source that ran (``<sha>`` or ``<sha>+dirty`` with
    uncommitted changes to tracked files), or None outside a git checkout: a baseline and the
    report name the code their numbers came from."""
    import subprocess

    root = Path(__file__).resolve().parents[3]
    try:
        sha = subprocess.run(["git", "-C", str(root), "rev-parse", "HEAD"], capture_output=True,
                             text=True, timeout=10)
        if sha.returncode != 0:
            return None
        dirty = subprocess.run(["git", "-C", str(root), "status", "--porcelain",
                                "--untracked-files=no"], capture_output=True, text=True,
                               timeout=10)
    except (OSError, subprocess.SubprocessError):
        return None
    return sha.stdout.strip() + ("+dirty" if dirty.stdout.strip() else "")


def new_document(*, command: list[str] | None = None, settings: dict[str, Any] | None = None,
                 cases: list[dict[str, Any]] | None = None) -> dict[str, Any]:
    from crosscheck import __version__

    return {
        "schema": SCHEMA, "schema_version": SCHEMA_VERSION, "crosscheck_version": __version__,
        "commit": source_commit(), "command": list(command or []), "started": now(),
        "finished": None,
        "interrupted": False, "exit_status": None, "machine": machine(),
        "settings": dict(settings or {}), "engines": {}, "cases": list(cases or []),
        "references": [], "cells": [], "not_run": [], "counts": {}, "resources": {},
        "baseline": None,
    }


def clean(value):
    """JSON-safe copy: non-finite floats become None, numpy scalars and arrays plain Python."""
    if isinstance(value, bool) or value is None or isinstance(value, str | int):
        return value
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {str(k): clean(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [clean(v) for v in value]
    if hasattr(value, "tolist"):
        return clean(value.tolist())
    if isinstance(value, Path):
        return str(value)
    return str(value)


def light(cell: dict[str, Any]) -> dict[str, Any]:
    return {k: v for k, v in cell.items() if k not in HEAVY_KEYS}


def counts(cells: list[dict[str, Any]]) -> dict[str, int]:
    out: dict[str, int] = {}
    for c in cells:
        out[c["status"]] = out.get(c["status"], 0) + 1
    return out


def engine_versions(cells: list[dict[str, Any]]) -> dict[str, str]:
    """Engine -> version, from the cells (an engine that never imported gives the reason)."""
    out: dict[str, str] = {}
    for c in cells:
        name = c.get("engine")
        if not name:
            continue
        version = c.get("engine_version")
        if version:
            out[name] = version
        elif name not in out and c.get("status") == "not_applicable" and \
                "unavailable" in (c.get("reason") or ""):
            out[name] = c["reason"].splitlines()[0]
    return dict(sorted(out.items()))


MUJOCO_DEFAULT_INTEGRATOR = "euler"


def cost_text(cell: dict[str, Any]) -> str:
    """A cell's cost for people: minimum with the spread (where a rerun's cost lands with the
    spread's coverage, docs/metrics.md "Cost") and count of its repetitions
    ("1.2e-04 ±3% n=5"), or why there is none."""
    cost = cell.get("cost")
    if cost is None:
        detail = cell.get("cost_detail") or {}
        return detail.get("note") or ""
    detail = cell.get("cost_detail") or {}
    spread = cell.get("cost_spread")
    text = f"{cost:.3g}"
    if spread is not None:
        text += f" ±{100 * spread:.0f}%"
    if detail.get("repeats"):
        text += f" n={detail['repeats']}"
    return text


def mujoco_cost_ratios(cells: list[dict[str, Any]]) -> dict[str, float]:
    """Cell id -> its cost divided by MuJoCo's cost measured in the same run.

    The MuJoCo cell compared with is the one of the same case and step with the same integrator
    name if MuJoCo ran it (rk4 against rk4), else MuJoCo's default integrator (euler), else the
    first MuJoCo cell of that case and step. Cells of a case and step MuJoCo did not run (fluid
    scenes, for one) get no ratio. Costs measured in one run share the machine and its load, so
    the ratio travels between machines far better than the seconds do.
    """
    mujoco: dict[tuple[str, float], dict[str, float]] = {}
    for c in cells:
        if c.get("engine") == "mujoco" and (c.get("cost") or 0) > 0:
            mujoco.setdefault((c["case"], c["dt"]), {})[c["integrator"]] = c["cost"]
    out: dict[str, float] = {}
    for c in cells:
        peers = mujoco.get((c.get("case"), c.get("dt")))
        cost = c.get("cost") or 0
        if not peers or cost <= 0:
            continue
        ref = (peers.get(c["integrator"]) or peers.get(MUJOCO_DEFAULT_INTEGRATOR)
               or next(iter(peers.values())))
        out[c["id"]] = cost / ref
    return out


def render(doc: dict[str, Any]) -> str:
    body = dict(doc)
    ratios = mujoco_cost_ratios(doc.get("cells", []))
    body["cells"] = [dict(light(c), cost_vs_mujoco=ratios.get(c.get("id")))
                     for c in doc.get("cells", [])]
    return json.dumps(clean(body), indent=1) + "\n"


def write(doc: dict[str, Any], outdir: str | Path) -> Path:
    from crosscheck.report.atomic import write_text

    return write_text(Path(outdir) / "results.json", render(doc))
