"""Which reference a case asks for, and the reference one cell is judged against.

The case's ``[reference]`` table says which:

* ``analytic``: ``crosscheck.reference.analytic.SOLUTIONS[solution](scene, times)`` evaluated at
  the run's own sample times (exact, no interpolation). NaN entries mark quantities the solution
  does not define; metrics skip them. ``EXTRA_METRICS[solution]`` adds solution-specific metrics.
* ``fine-step``: an engine (``reference.engine``, default the in-house one) with
  ``reference.integrator`` (default ``rk4``) at ``reference.dt`` (default the case's
  ``dt / FINE_STEP_FACTOR``); with ``integrator = "dop853"`` SciPy's DOP853 on the independent
  Newton-Euler equations (:mod:`crosscheck.reference.simulated`).
* ``engine``: another engine's run at the *same* step as the run being judged.
* ``table``: published data (``table``), used by fluid scenes through their own metrics, or the
  case's own CSV (``file``, read at load into ``reference.data``), compared by
  :mod:`crosscheck.compare.table_metrics` for rigid and fluid runs alike.
* ``none``: only conservation metrics.

This module only describes and fetches references; it runs nothing. The simulated ones
(fine-step, engine, DOP853) are run once per case (and step, for ``engine``) by the runner
through :func:`crosscheck.reference.simulated.compute_reference` and saved as a Trajectory
``.npz``, which :func:`for_cell` loads. The spec functions live here rather than beside the
running code because they cover every kind (analytic, table and none too): the planner reads
them to decide what to run, a cell to decide what to load. :class:`Reference` is what
:func:`crosscheck.compare.evaluate.evaluate` takes; compare resamples it at the run's times
(:mod:`crosscheck.compare.interp`) and judges.
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from crosscheck.scene.model import Scene
from crosscheck.state import Trajectory

# Fine-step reference default: this many times finer than the case's step.
FINE_STEP_FACTOR = 100
DOP853_RTOL = 1e-12


@dataclass(frozen=True)
class Reference:
    """What one run is compared with: a Trajectory (any sampling) and an analytic solution's
    extra metrics ``(scene, traj) -> {name: value}``, or neither and ``missing`` saying why
    (empty when the case asks for no reference)."""

    trajectory: Trajectory | None = None
    extra: Callable[[Scene, Trajectory], dict[str, float]] | None = None
    missing: str = ""


def reference_spec(scene: Scene, dt: float) -> dict[str, Any] | None:
    """A plain description of the reference a run at step ``dt`` is compared with (or None)."""
    ref = scene.reference
    if scene.fluid is not None:
        return None  # fluid scenes compare with their tables / solutions in fluid_metrics
    if ref.kind == "analytic":
        return {"kind": "analytic", "solution": ref.solution}
    if ref.kind == "fine-step":
        integrator = (ref.integrator or "rk4").lower()
        if integrator == "dop853":
            return {"kind": "dop853", "rtol": float(ref.params.get("rtol", DOP853_RTOL))}
        return {"kind": "fine-step", "engine": ref.engine or "inhouse", "integrator": integrator,
                "dt": float(ref.dt if ref.dt is not None else scene.run.dt / FINE_STEP_FACTOR)}
    if ref.kind == "engine":
        return {"kind": "engine", "engine": ref.engine, "integrator": ref.integrator,
                "dt": float(dt)}
    if ref.kind == "table":
        if ref.file is not None:
            return {"kind": "table", "file": ref.file}
        return {"kind": "table", "table": ref.table}
    return None


def needs_run(spec: dict[str, Any] | None) -> bool:
    """True for references computed by a simulation (shared, run once before the cells)."""
    return spec is not None and spec["kind"] in ("fine-step", "engine", "dop853")


def reference_key(scene: Scene, spec: dict[str, Any]) -> str:
    """A file-name-safe key for a computed reference: case hash plus the spec."""
    blob = json.dumps({"case": scene.source_sha256, "name": scene.name, "spec": spec},
                      sort_keys=True)
    return hashlib.sha256(blob.encode()).hexdigest()[:20]


def describe(spec: dict[str, Any] | None) -> str:
    if spec is None:
        return "none"
    kind = spec["kind"]
    if kind == "analytic":
        return f"analytic: {spec['solution']}"
    if kind == "fine-step":
        return f"fine-step: {spec['engine']} {spec['integrator']} at dt={spec['dt']:g}"
    if kind == "engine":
        integ = spec.get("integrator") or "default"
        return f"engine: {spec['engine']} {integ} at the same dt"
    if kind == "dop853":
        return f"SciPy solve_ivp DOP853, rtol {spec['rtol']:g}"
    return f"{kind}: {spec.get('table') or spec.get('file')}"


def analytic_reference(scene: Scene, times: np.ndarray, solution: str):
    """(Trajectory, extra-metrics callable or None) of an analytic solution at ``times``."""
    from crosscheck.reference import analytic

    if solution not in analytic.SOLUTIONS:
        raise KeyError(f"no analytic solution {solution!r}; known: {sorted(analytic.SOLUTIONS)}")
    traj = analytic.SOLUTIONS[solution](scene, np.asarray(times, float))
    extra = getattr(analytic, "EXTRA_METRICS", {}).get(solution)
    return traj, extra


def for_cell(scene: Scene, spec: dict[str, Any] | None, times: np.ndarray, *,
             saved: str | None = None, error: str | None = None) -> Reference:
    """The reference of one rigid cell: the analytic solution at the run's ``times``, or the
    simulated reference the runner ``saved``, or none with the reason (``error``: why the
    runner has no saved reference). A failure here is the reason, never an exception: the cell
    still reports its conservation metrics."""
    if spec is None:
        return Reference()
    try:
        if spec["kind"] == "analytic":
            traj, extra = analytic_reference(scene, times, spec["solution"])
            return Reference(traj, extra)
        if saved:
            return Reference(Trajectory.load(saved))
        if spec["kind"] == "table" and spec.get("file"):
            return Reference()  # the case's own table: compared beside the other metrics
        if spec["kind"] == "table":
            return Reference(missing="a rigid scene has no published table reference")
        return Reference(missing=error or "reference unavailable")
    except Exception as exc:
        return Reference(missing=f"reference failed: {type(exc).__name__}: {exc}")
