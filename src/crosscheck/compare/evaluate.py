"""One entry for a run's verdict: :func:`evaluate` (scene, run output, reference) -> Evaluation.

The runner used to assemble metrics, the reason a reference is missing and the verdict by hand,
once for rigid runs and once for fluid runs; both now go through here, so a cell's numbers and
status are decided in one place (definitions: docs/metrics.md).

* A rigid run (a Trajectory of a scene without a fluid domain): :func:`compute_metrics` against
  the reference (resampled at the run's times inside it), the reference's extra metrics (an
  analytic solution's, e.g. ``flip_period_error``), the blow-up found in the run, then
  :func:`judge`. An extra metric that raises is dropped and its error becomes the note, so a
  solution-specific check cannot sink the cell.
* A fluid run (a FluidRecord): :func:`fluid_metrics` (the fluid scene's own tables and
  solutions; the ``reference`` argument is unused), the blow-up the solver recorded, then
  :func:`judge`.
* Either, when the case gives its own table (``reference.file``): its ``table_<column>_error_*``
  metrics (:mod:`crosscheck.compare.table_metrics`) beside the others.

``Evaluation.note`` says why reference metrics may be absent; it is passed to the verdict, which
names it when a limited metric was not computed.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from crosscheck.compare.table_metrics import table_metrics
from crosscheck.compare.verdict import judge, metric_table
from crosscheck.reference.spec import Reference
from crosscheck.scene.model import Scene
from crosscheck.state import Trajectory


@dataclass
class Evaluation:
    status: str
    reason: str
    metrics: dict[str, dict[str, Any]]  # name -> value, limit, passed, meaningful, note, unit
    worst: dict[str, Any] | None
    series: dict[str, dict[str, list]] = field(default_factory=dict)  # plots (rigid runs)
    blowup_time: float | None = None
    blowup_reason: str | None = None
    note: str = ""  # why reference (or extra) metrics are missing; "" when nothing is
    reference_end: Trajectory | None = None  # the reference at the run's last sample time

    @property
    def failing(self) -> bool:
        return self.status in ("fail", "error", "blowup")

    def table(self) -> str:
        """The plain-text metric table shown for failing cells."""
        return metric_table(self.metrics)


def evaluate(scene: Scene, output, reference: Reference | None, engine: str,
             integrator: str) -> Evaluation:
    """The verdict of one run of ``engine`` / ``integrator``: a Trajectory is judged as a rigid
    run against ``reference`` (None: no reference), anything else as a fluid record."""
    if scene.fluid is None and isinstance(output, Trajectory):
        return _rigid(scene, output, reference or Reference(), engine, integrator)
    if isinstance(output, Trajectory):  # a fluid case an engine ran as a stateless medium
        return _mapped(scene, output, engine, integrator)
    return _fluid(scene, output, engine, integrator)


def _mapped(scene: Scene, traj: Trajectory, engine: str, integrator: str) -> Evaluation:
    """A fluid case run by an engine as a body in its stateless medium (MuJoCo's mapped
    cylinder, scene/medium_map.py; the model named by the run, "rk4+ellipsoid"): judged against
    the closed form of the engine's own model (reference/medium_analytic.mapped_settling_metrics),
    with the figures the report sets beside the in-house cell's. Conservation metrics are not
    computed (the medium's drag dissipates; the fluid case has no medium effect to account for
    the buoyancy's potential)."""
    from crosscheck.names import split_run
    from crosscheck.reference.medium_analytic import (
        FLUIDCOEF_DEFAULT,
        MAPPED_NOTES,
        mapped_settling_metrics,
    )

    note = ""
    values: dict[str, float | None] = {}
    _, model = split_run(integrator)
    coef = (scene.engine_options.get(engine, {}) or {}).get("fluidcoef", FLUIDCOEF_DEFAULT)
    try:
        values = mapped_settling_metrics(scene, traj, model, coef)
    except (ValueError, KeyError) as exc:
        note = f"the medium's closed form does not apply: {exc}"
    metrics = _plain(values)
    _notes(metrics, MAPPED_NOTES)
    return _judged(scene, engine, integrator, metrics, traj.failure, note)


def _rigid(scene: Scene, traj: Trajectory, reference: Reference, engine: str,
           integrator: str) -> Evaluation:
    from crosscheck.compare.interp import resample
    from crosscheck.compare.metrics import compute_metrics

    note = reference.missing
    safe_extra = None
    if reference.extra is not None:
        def safe_extra(s, t, _extra=reference.extra):
            try:
                return _extra(s, t)
            except Exception as exc:  # a solution-specific metric must not sink the cell
                nonlocal note
                note = f"extra metrics failed: {type(exc).__name__}: {exc}"
                return {}

    ref = reference.trajectory
    ms = compute_metrics(scene, traj, ref, extra=safe_extra)
    metrics = {name: m.to_dict() for name, m in ms.metrics.items()}
    metrics.update(_plain(table_metrics(scene, traj)))  # the case's own table, if any
    verdict = judge(scene, engine, integrator, metrics,
                    blowup_time=ms.blowup_time, blowup_reason=ms.blowup_reason,
                    missing_reason=note)
    ref_end = resample(ref, traj.t[-1:]) if ref is not None and len(traj.t) else None
    return Evaluation(verdict.status, verdict.reason, verdict.metrics, verdict.worst,
                      series=ms.series, blowup_time=ms.blowup_time,
                      blowup_reason=ms.blowup_reason, note=note, reference_end=ref_end)


def _judged(scene: Scene, engine: str, integrator: str, metrics: dict[str, dict[str, Any]],
            failure: dict | None, note: str | None) -> Evaluation:
    """The verdict of metrics computed outside compute_metrics (a fluid record, a mapped
    medium run), with the run's failure, if any, as its blow-up."""
    blow_t = float(failure.get("time", 0.0)) if failure else None
    blow_reason = (failure or {}).get("reason")
    verdict = judge(scene, engine, integrator, metrics, blowup_time=blow_t,
                    blowup_reason=blow_reason, missing_reason=note)
    return Evaluation(verdict.status, verdict.reason, verdict.metrics, verdict.worst,
                      blowup_time=blow_t, blowup_reason=blow_reason, note=note)


def _plain(values: dict[str, float | None]) -> dict[str, dict[str, Any]]:
    """Metric entries from plain numbers: NaN / inf become value None with ``value_text`` (JSON
    has neither; the verdict reads the text)."""
    metrics = {}
    for name, value in values.items():
        value = None if value is None else float(value)
        entry: dict[str, Any] = {"value": value if value is not None and np.isfinite(value)
                                 else None}
        if value is not None and not np.isfinite(value):
            entry["value_text"] = str(value)
        metrics[name] = entry
    return metrics


def _notes(metrics: dict[str, dict[str, Any]], notes: dict[str, str]) -> None:
    """Attach to reported metrics why they are not judged (shown beside the number)."""
    for name, text in notes.items():
        if name in metrics:
            metrics[name]["note"] = text


def _fluid(scene: Scene, record, engine: str, integrator: str) -> Evaluation:
    values: dict[str, float] = {}
    note = ""
    try:
        from crosscheck.compare.fluid_metrics import fluid_metrics

        values = fluid_metrics(scene, record)
    except ImportError as exc:
        note = f"fluid metrics unavailable: {exc}"
    metrics = _plain(values)
    from crosscheck.compare.fluid_metrics import DISC_SETTLING_NOTES

    _notes(metrics, DISC_SETTLING_NOTES)
    return _judged(scene, engine, integrator, metrics, getattr(record, "failure", None), note)
