"""One cell of the matrix (case x engine x integrator x dt), run in whichever process executes it.

:func:`execute_task` never raises: an exception becomes an ``error`` result with the message and
the last lines of the traceback, a blow-up a ``blowup`` result with its time. What crosses the
process boundary is a small JSON-able dict (metrics, verdict, a few down-sampled curves for the
plots, the end state), never the trajectory, so memory stays bounded however long the run; the
trajectory itself goes to disk when ``save_trajectories`` is set.

Task dicts (built by :mod:`crosscheck.runner.plan`):

``{"kind": "cell", "id", "case", "case_file", "engine", "integrator", "dt", "timeout",
"out", "save_trajectories", "reference": spec|None, "reference_file": str|None,
"reference_error": str|None, "engine_refs": {name: "module:Class"}}``

``{"kind": "reference", "id", "case", "case_file", "spec", "path", "timeout", "engine_refs"}``

``{"kind": "cost", "id", "cell", "case_file", "engine", "integrator", "dt", "steps", "cost",
"engine_refs", "timeout"}``: one more process's cost pass of a rigid cell (:func:`cost_followups`
makes them from the cell's result; the session pools them into the cell's cost).
"""

from __future__ import annotations

import importlib
import os
import re
import sys
import time
import traceback
from pathlib import Path
from typing import Any

import numpy as np

_SCENES: dict[tuple[str, float, frozenset[str]], Any] = {}


def load_scene(path: str, engine_refs: dict[str, str] | None = None):
    """Load a case file once per process (keyed by path, modification time and the engines
    replaced through ``engine_refs``, whose integrator names the loader leaves unchecked)."""
    from crosscheck.scene.loader import load_case

    unchecked = frozenset(engine_refs or {})
    key = (str(path), os.path.getmtime(path), unchecked)
    if key not in _SCENES:
        if len(_SCENES) > 64:
            _SCENES.clear()
        _SCENES[key] = load_case(path, unchecked_engines=unchecked)
    return _SCENES[key]


def resolve_engine(name: str, engine_refs: dict[str, str] | None = None):
    """The adapter for ``name``: ``engine_refs[name]`` ("module:Class") or the registry."""
    ref = (engine_refs or {}).get(name)
    if ref:
        module, _, cls = ref.partition(":")
        return getattr(importlib.import_module(module), cls)()
    from crosscheck.engines import get_engine

    return get_engine(name)


def safe_name(text: str) -> str:
    return re.sub(r"[^A-Za-z0-9._+-]+", "_", text).strip("_") or "case"


def dt_text(dt: float) -> str:
    return f"{dt:g}"


def cell_id(case: str, engine: str, integrator: str, dt: float) -> str:
    return f"{case}::{engine}-{integrator}@dt={dt_text(dt)}"


def _peak_rss_mb() -> float | None:
    """This process's peak resident memory, MiB: ``VmHWM`` of /proc/self/status on Linux.

    Not ``getrusage``'s ``ru_maxrss``: Linux carries it across the fork and exec that spawn a
    worker, so a worker reported its parent's size at the spawn (measured: 599 MiB for a worker
    of 28 MiB spawned by a process holding 600 MiB; 901 MiB under pytest)."""
    try:
        with open("/proc/self/status", encoding="ascii") as status:
            for line in status:
                if line.startswith("VmHWM:"):
                    return int(line.split()[1]) / 1024.0          # kB
    except OSError:
        pass
    try:
        import resource

        peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    except Exception:  # pragma: no cover - non-POSIX
        return None
    return peak / 2**20 if sys.platform == "darwin" else peak / 1024.0   # bytes there, KiB else


def _error_text(exc: BaseException) -> str:
    tb = traceback.format_exception(type(exc), exc, exc.__traceback__)
    tail = "".join(tb[-3:]).strip()
    return f"{type(exc).__name__}: {exc}\n{tail}"


def base_result(task: dict[str, Any]) -> dict[str, Any]:
    return {
        "id": task["id"], "kind": task.get("kind", "cell"), "case": task.get("case"),
        "case_file": task.get("case_file"), "engine": task.get("engine"),
        "integrator": task.get("integrator"), "dt": task.get("dt"), "status": "error",
        "reason": "", "metrics": {},
    }


def execute_task(task: dict[str, Any]) -> dict[str, Any]:
    """Run one task in this process; never raises."""
    started = time.perf_counter()
    try:
        if task.get("kind") == "reference":
            result = _execute_reference(task)
        elif task.get("kind") == "cost":
            result = _execute_cost(task)
        else:
            result = _execute_cell(task)
    except Exception as exc:  # any failure of one cell is that cell's result
        result = base_result(task)
        result.update(status="error", reason=_error_text(exc))
    result["cell_seconds"] = time.perf_counter() - started
    result["peak_rss_mb"] = _peak_rss_mb()
    result["pid"] = os.getpid()
    return result


# -- references ------------------------------------------------------------------------------------
def _execute_reference(task: dict[str, Any]) -> dict[str, Any]:
    from crosscheck.reference.simulated import compute_reference

    result = base_result(task)
    scene = load_scene(task["case_file"], task.get("engine_refs"))
    traj = compute_reference(scene, task["spec"],
                             get_engine=lambda n: resolve_engine(n, task.get("engine_refs")))
    if traj.failure:
        result.update(status="blowup", reason=f"reference blew up: {traj.failure}")
        return result
    traj.save(task["path"])
    result.update(status="ok", path=task["path"], wall_time=traj.wall_time)
    return result


# -- cells -----------------------------------------------------------------------------------------
def _execute_cell(task: dict[str, Any]) -> dict[str, Any]:
    result = base_result(task)
    engine_name, integrator, dt = task["engine"], task["integrator"], float(task["dt"])
    scene = load_scene(task["case_file"], task.get("engine_refs"))
    result["case_sha256"] = scene.source_sha256
    try:
        engine = resolve_engine(engine_name, task.get("engine_refs"))
    except Exception as exc:  # a missing or broken engine package: not applicable, not a crash
        result.update(status="not_applicable",
                      reason=f"{engine_name} unavailable: {type(exc).__name__}: {exc}")
        return result
    try:
        result["engine_version"] = engine.version()
    except Exception as exc:
        result["engine_version"] = f"unknown ({type(exc).__name__})"
    reason = engine.not_applicable(scene, integrator)
    if reason:
        result.update(status="not_applicable", reason=reason)
        return result

    from crosscheck.engines.driver import CostPlan, WouldTimeOut, run

    t0 = time.perf_counter()
    cost = task.get("cost", True)  # True, False, or CostPlan fields
    plan = CostPlan(**cost) if isinstance(cost, dict) else CostPlan() if cost else None
    try:
        ran = run(engine, scene, integrator, dt, cost=plan,
                  timeout=float(task["timeout"]) if task.get("timeout") else None)
    except WouldTimeOut as exc:
        result.update(status="timeout", reason=str(exc))
        return result
    run_seconds = time.perf_counter() - t0
    result["run_seconds"] = run_seconds
    if ran.cost is not None:
        result.update(_cost_fields(ran.cost.to_dict(plan)))
    output = ran.output
    if ran.fluid is not None or not _is_trajectory(output):
        return _finish_fluid(task, scene, output, result, run_seconds, body=ran.trajectory)
    # A rigid scene, or a fluid case an engine ran as a body in its medium (MuJoCo's mapped
    # cylinder): a Trajectory, judged by compare.evaluate.
    return _finish_rigid(task, scene, output, result, run_seconds)


def cost_followups(task: dict[str, Any], result: dict[str, Any]) -> list[dict[str, Any]]:
    """The extra cost tasks of a finished rigid cell whose cost plan asks for more than one
    process (driver.CostPlan.processes): each times the same number of steps as the cell's own
    cost pass. The scheduler queues them after every cell, by ``process_round`` (pass r + 1 has
    round r), and the local backend runs round r in worker processes started for it, so a
    cell's passes land in distinct processes (runner/local.py, LocalBackend.submit)."""
    cost = task.get("cost", True)
    if task.get("kind") != "cell" or not cost or result.get("fluid"):
        return []
    from crosscheck.engines.driver import CostPlan

    plan = CostPlan(**cost) if isinstance(cost, dict) else CostPlan()
    detail = result.get("cost_detail") or {}
    if plan.processes <= 1 or not detail.get("repeats") or not detail.get("steps"):
        return []
    # A long run (its own pass already spent a process's share of the timing budget) is timed
    # in its own process only: its process offset is small against its length, and more
    # processes would multiply the run's longest cells.
    if sum(detail.get("wall_samples") or []) > plan.budget_seconds / plan.processes:
        result["cost_detail"] = dict(detail, note="; ".join(filter(None, [
            detail.get("note"), f"timed in one process: its pass took "
            f"{sum(detail['wall_samples']):.3g} s, more than the budget's share "
            f"{plan.budget_seconds / plan.processes:.3g} s"])))
        return []
    keep = ("case", "case_file", "engine", "integrator", "dt", "timeout", "engine_refs", "cost")
    return [dict({k: task.get(k) for k in keep}, kind="cost", id=f"{task['id']}#cost{k + 2}",
                 cell=task["id"], steps=int(detail["steps"]), process_round=k + 1)
            for k in range(plan.processes - 1)]


def _execute_cost(task: dict[str, Any]) -> dict[str, Any]:
    from crosscheck.engines.driver import CostPlan, measure_cost

    result = {"kind": "cost", "id": task["id"], "cell": task["cell"], "status": "ok"}
    scene = load_scene(task["case_file"], task.get("engine_refs"))
    engine = resolve_engine(task["engine"], task.get("engine_refs"))
    integrator, dt = task["integrator"], float(task["dt"])
    cost = task.get("cost", True)
    plan = CostPlan(**cost) if isinstance(cost, dict) else CostPlan()
    # No spread here: pool_costs computes the cell's from all its passes (and a fresh worker
    # that only times is spared importing scipy for it).
    result["cost_detail"] = measure_cost(lambda: engine.open(scene, integrator, dt),
                                         int(task["steps"]), dt, plan).to_dict(plan, spread=False)
    result["pid"] = os.getpid()
    if isinstance(cost, dict):
        result["cost_plan"] = cost  # the spread's model parameters, for pool_costs
    return result


def pool_costs(cell: dict[str, Any], extra: list[dict[str, Any]]) -> None:
    """Replace a cell's cost fields by the pooled cost of its own pass and its followups'."""
    from crosscheck.engines.driver import CostPlan, merge_costs

    own = cell.get("cost_detail")
    done = [dict(e["cost_detail"], pid=e.get("pid")) for e in extra
            if e.get("status") == "ok" and e.get("cost_detail")]
    if not own or not done:
        return
    cost = next((e["cost_plan"] for e in extra if isinstance(e.get("cost_plan"), dict)), None)
    plan = CostPlan(**cost) if cost else CostPlan()
    merged = merge_costs([dict(own, pid=cell.get("pid")), *done], plan)
    merged["pids"] = sorted({p for p in [cell.get("pid"), *(e.get("pid") for e in extra)]
                             if p is not None})
    failed = [e for e in extra if e.get("status") != "ok"]
    if failed:
        merged["note"] = "; ".join(filter(None, [merged.get("note"), (
            f"{len(failed)} of {len(extra)} extra cost pass(es) failed: "
            f"{(failed[0].get('reason') or '').splitlines()[:1]}")]))
    cell.update(_cost_fields(merged))


def _cost_fields(cost: dict[str, Any]) -> dict[str, Any]:
    """results.json's cost fields from the driver's cost pass (docs/metrics.md, "Cost")."""
    return {"cost": cost.get("per_simulated_second"),
            "cost_median": cost.get("per_simulated_second_median"),
            "cost_spread": cost.get("spread"),
            "cost_median_spread": cost.get("spread_median"),
            "cpu_cost": cost.get("cpu_per_simulated_second"),
            "wall_time": cost.get("wall_min"),
            "cost_detail": cost}


def _is_trajectory(obj) -> bool:
    from crosscheck.state import Trajectory

    return isinstance(obj, Trajectory)


def _finish_rigid(task, scene, traj, result, run_seconds):
    from crosscheck.compare.evaluate import evaluate
    from crosscheck.reference.spec import for_cell

    reference = for_cell(scene, task.get("reference"), traj.t, saved=task.get("reference_file"),
                         error=task.get("reference_error"))
    verdict = evaluate(scene, traj, reference, task["engine"], task["integrator"])
    simulated = float(traj.t[-1] - traj.t[0]) if len(traj.t) > 1 else 0.0
    result.update(
        status=verdict.status, reason=verdict.reason, metrics=verdict.metrics,
        worst=verdict.worst, simulated_time=simulated, failure=traj.failure, series=verdict.series,
        engine_version=traj.meta.get("engine_version", result.get("engine_version")),
        effective=_small(traj.meta.get("effective") or traj.meta.get("settings")),
        samples=len(traj.t),
    )
    if verdict.note:
        result["reference_note"] = verdict.note
    result["end_state"] = _end_state(traj)
    if verdict.reference_end is not None:
        result["reference_end"] = _end_state(verdict.reference_end)
    if verdict.failing:
        result["metric_table"] = verdict.table()
    if task.get("save_trajectories") and task.get("out"):
        path = trajectory_path(task)
        traj.save(path)
        result["trajectory_file"] = str(path)
    return result


def trajectory_path(task, suffix: str = ".npz") -> Path:
    """``OUT/trajectories/<case>/<engine>-<integrator>-dt<dt>.npz`` (DESIGN.md)."""
    return (Path(task["out"]) / "trajectories" / safe_name(task["case"])
            / f"{task['engine']}-{task['integrator']}-dt{dt_text(float(task['dt']))}{suffix}")


def _small(value):
    """Keep engine settings only if they are small JSON-able data."""
    import json

    if value is None:
        return None
    try:
        text = json.dumps(value, default=lambda o: o.tolist() if hasattr(o, "tolist") else str(o))
    except (TypeError, ValueError):
        return None
    return json.loads(text) if len(text) < 4000 else None


def _end_state(traj) -> dict[str, Any] | None:
    if not len(traj.t):
        return None
    rot = traj.quat if traj.quat is not None else traj.angle

    def last(a):
        return None if a is None else np.asarray(a[-1], float).tolist()

    return {"t": float(traj.t[-1]), "com": last(traj.com), "rot": last(rot),
            "vel": last(traj.vel), "omega": last(traj.omega),
            "rot_kind": "quat" if traj.quat is not None else "angle"}


def _finish_fluid(task, scene, record, result, run_seconds, body=None):
    """A fluid run's result; ``body`` the coupled body's Trajectory (driver.body_trajectory),
    whose end state the end-state table shows and whose motion is plotted beside the fluid's."""
    from crosscheck.compare.evaluate import evaluate

    verdict = evaluate(scene, record, None, task["engine"], task["integrator"])
    failure = getattr(record, "failure", None)
    meta = getattr(record, "meta", {}) or {}
    t = np.asarray(getattr(record, "t", []), float)
    simulated = float(t[-1] - t[0]) if len(t) > 1 else 0.0
    result.update(status=verdict.status, reason=verdict.reason, metrics=verdict.metrics,
                  worst=verdict.worst, simulated_time=simulated, failure=failure, fluid=True,
                  engine_version=meta.get("engine_version", result.get("engine_version")))
    if body is not None and len(body.t):
        result["end_state"] = _end_state(body)
        result["bodies"] = list(body.meta.get("bodies") or [])
        result["samples"] = len(body.t)
    if verdict.failing:
        result["metric_table"] = verdict.table()
    if task.get("out"):
        try:
            from crosscheck.report.fluid_plots import plot_fluid

            plot_dir = Path(task["out"]) / "plots" / safe_name(task["case"]) / (
                f"{task['engine']}-{task['integrator']}-dt{dt_text(float(task['dt']))}")
            result["plots"] = [str(p) for p in plot_fluid(scene, record, plot_dir, body=body)]
        except ImportError:
            pass
        except Exception as exc:  # a plot failure must not lose the numbers
            result["plot_error"] = f"{type(exc).__name__}: {exc}"
        if task.get("save_trajectories"):
            path = trajectory_path(task)
            record.save(path)
            result["trajectory_file"] = str(path)
            if body is not None:
                bpath = trajectory_path(task, "-body.npz")
                body.save(bpath)
                result["body_trajectory_file"] = str(bpath)
    return result
