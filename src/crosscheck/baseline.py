"""Committed baselines and the regression verdict (``crosscheck run --baseline FILE``).

A baseline (``reports/baseline.json``) records, for every cell ``case::engine-integrator@dt=..``
of a reference run, its status, the case file's hash and the value of every *meaningful* metric
(non-conserved quantities are left out: they carry no verdict). A later run is compared cell by
cell, in the style of pytest-regressions' per-key absolute and relative tolerances:

* a metric **regressed** when ``new > old + slack`` with ``slack = max(abs, rel * |old|)`` (for
  ``blowup_time``, where later is better, when ``new < old - slack``); it **improved** when it
  moved the other way by more than the slack; otherwise it is unchanged;
* a cell **regressed** when it passed in the baseline and does not now (fail, blowup, error,
  timeout, or not applicable: an engine that stopped importing must not turn the gate green);
* cells of the run that the baseline lacks are **new**, baseline cells the run lacks are
  **missing** (the case was removed or the run filtered it); both are reported, neither fails;
* a case whose file hash changed is flagged, since its numbers may move for that reason.

Default slack (:data:`DEFAULT_SLACK`): ``rel = 0.1`` for every metric (10 %: a run on another
machine or with another BLAS may round differently, and chaotic cases amplify that); ``abs`` is
``1e-10`` for dimensionless metrics (drifts and relative errors: a few thousand steps of
round-off, below anything a tolerance in this project resolves) and ``1e-9`` in SI units for
positions (m), orientations (rad) and velocities (m/s, rad/s); ``blowup_time`` gets ``abs`` one
sample interval's worth, 0.05 s; the round-off-seeded symmetry breaking of a settling disc
(``centreline_offset``, ``centreline_offset_mean``, ``terminal_velocity_unsteadiness``) gets
``abs`` 1e-4 (m, or diameters) and 2e-3. A baseline file may override any of them in its ``"slack"``
table (``{"metric": {"abs": .., "rel": ..}}``, or ``"default"``), and one case's metric alone
with the key ``"<case>::<metric>"`` (a chaotic case whose symmetry breaking round-off sets);
``baseline update`` keeps the table of the file it replaces.

Wall-time cost is stored for information but is **not** a regression criterion: machines differ
(a CI runner against a laptop) far more than any slack would allow, so timing is left to the
benchmarks.
"""

from __future__ import annotations

import datetime as _dt
import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from crosscheck.errors import CrosscheckError

SCHEMA = "crosscheck-baseline"
SCHEMA_VERSION = 1

DEFAULT_SLACK: dict[str, dict[str, float]] = {
    "default": {"abs": 1e-10, "rel": 0.1},
    "position_error_max": {"abs": 1e-9, "rel": 0.1},
    "position_error_rms": {"abs": 1e-9, "rel": 0.1},
    "orientation_error_max": {"abs": 1e-9, "rel": 0.1},
    "velocity_error_max": {"abs": 1e-9, "rel": 0.1},
    "angular_velocity_error_max": {"abs": 1e-9, "rel": 0.1},
    "out_of_plane_drift": {"abs": 1e-9, "rel": 0.1},
    "out_of_plane_tilt": {"abs": 1e-9, "rel": 0.1},
    "out_of_plane_angular_velocity": {"abs": 1e-9, "rel": 0.1},
    "blowup_time": {"abs": 0.05, "rel": 0.0},
    # symmetry breaking seeded by round-off (a settling disc's drift off its axis, m, or in
    # diameters for the published benchmark; the unsteadiness of its speed): a new install
    # with no change to the fluid code moved them by 15 % (docs/reports.md)
    "centreline_offset": {"abs": 1e-4, "rel": 0.1},
    "centreline_offset_mean": {"abs": 1e-4, "rel": 0.1},
    "terminal_velocity_unsteadiness": {"abs": 2e-3, "rel": 0.1},
}
HIGHER_IS_BETTER = frozenset({"blowup_time"})


class BaselineError(CrosscheckError):
    """An unreadable or incompatible baseline or results file (exit status 2)."""


def _now() -> str:
    return _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds")


def cell_key(cell: dict[str, Any]) -> str:
    return cell["id"]


def load_json(path: str | Path, what: str) -> dict[str, Any]:
    path = Path(path)
    try:
        return json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise BaselineError(f"{path}: {what} not found") from None
    except (OSError, ValueError) as exc:
        raise BaselineError(f"{path}: unreadable {what} ({exc})") from None


def load_baseline(path: str | Path) -> dict[str, Any]:
    data = load_json(path, "baseline file")
    if data.get("schema") != SCHEMA or data.get("schema_version") != SCHEMA_VERSION:
        raise BaselineError(f"{path}: not a crosscheck baseline of schema version "
                            f"{SCHEMA_VERSION} (got {data.get('schema')!r} "
                            f"{data.get('schema_version')!r})")
    return data


def load_results(folder_or_file: str | Path) -> dict[str, Any]:
    path = Path(folder_or_file)
    if path.is_dir():
        path = path / "results.json"
    data = load_json(path, "results file")
    from crosscheck.report.results import SCHEMA as RSCHEMA

    if data.get("schema") != RSCHEMA:
        raise BaselineError(f"{path}: not a crosscheck results file")
    return data


def baseline_from_results(results: dict[str, Any], *, source: str = "",
                          previous: dict[str, Any] | None = None, merge: bool = False
                          ) -> dict[str, Any]:
    """A baseline document from a results document (``merge``: keep previous cells not run)."""
    entries: dict[str, Any] = {}
    if merge and previous:
        entries.update(previous.get("entries", {}))
    for cell in results.get("cells", []):
        metrics = {}
        for name, m in (cell.get("metrics") or {}).items():
            if m.get("meaningful", True) is False or m.get("value") is None:
                continue
            metrics[name] = m["value"]
        entries[cell_key(cell)] = {
            "case": cell.get("case"), "engine": cell.get("engine"),
            "integrator": cell.get("integrator"), "dt": cell.get("dt"),
            "status": cell.get("status"), "case_sha256": cell.get("case_sha256"),
            "metrics": metrics, "cost": cell.get("cost"),
        }
    slack = (previous or {}).get("slack") or DEFAULT_SLACK
    engines = dict(results.get("engines") or {})
    if merge and previous:
        # the kept cells came from the engines the previous baseline recorded: a run of one
        # engine must not drop the others' versions (the reports compare them with each run's)
        engines = {**((previous.get("source") or {}).get("engines") or {}), **engines}
    return {
        "schema": SCHEMA, "schema_version": SCHEMA_VERSION, "created": _now(),
        "crosscheck_version": results.get("crosscheck_version"),
        "source": {"results": source, "started": results.get("started"),
                   "commit": results.get("commit"),
                   "machine": results.get("machine"), "engines": engines},
        "slack": slack,
        "entries": dict(sorted(entries.items())),
    }


def write_baseline(doc: dict[str, Any], path: str | Path) -> Path:
    from crosscheck.report.atomic import write_text

    return write_text(path, json.dumps(doc, indent=1, sort_keys=False) + "\n")


# -- comparison ------------------------------------------------------------------------------------
@dataclass
class Change:
    key: str
    metric: str | None  # None: a status change
    old: Any
    new: Any
    slack: float | None = None

    def describe(self) -> str:
        if self.metric is None:
            return f"{self.key}: status {self.old} -> {self.new}"
        return (f"{self.key}: {self.metric} {_fmt(self.old)} -> {_fmt(self.new)} "
                f"(slack {_fmt(self.slack)})")

    def to_dict(self) -> dict[str, Any]:
        return {"cell": self.key, "metric": self.metric, "old": self.old, "new": self.new,
                "slack": self.slack}


@dataclass
class Comparison:
    regressions: list[Change] = field(default_factory=list)
    improvements: list[Change] = field(default_factory=list)
    status_changes: list[Change] = field(default_factory=list)  # neither better nor worse
    new: list[str] = field(default_factory=list)
    missing: list[str] = field(default_factory=list)
    missing_cases: list[str] = field(default_factory=list)  # whole cases absent from the run
    changed_cases: list[str] = field(default_factory=list)  # case file hash differs
    dropped_metrics: list[Change] = field(default_factory=list)

    @property
    def regressed_cells(self) -> set[str]:
        return {c.key for c in self.regressions}

    def to_dict(self) -> dict[str, Any]:
        return {
            "regressions": [c.to_dict() for c in self.regressions],
            "improvements": [c.to_dict() for c in self.improvements],
            "status_changes": [c.to_dict() for c in self.status_changes],
            "new": self.new, "missing": self.missing, "missing_cases": self.missing_cases,
            "changed_cases": self.changed_cases,
            "dropped_metrics": [c.to_dict() for c in self.dropped_metrics],
        }

    def lines(self) -> list[str]:
        out = []
        if self.regressions:
            out.append(f"{len(self.regressions)} regression(s):")
            out += ["  REGRESSION " + c.describe() for c in self.regressions]
        if self.improvements:
            out.append(f"{len(self.improvements)} improvement(s):")
            out += ["  improved   " + c.describe() for c in self.improvements]
        if self.status_changes:
            out += ["  changed    " + c.describe() for c in self.status_changes]
        if self.dropped_metrics:
            out += ["  no longer computed: " + c.describe() for c in self.dropped_metrics]
        if self.new:
            out.append(f"{len(self.new)} new cell(s) not in the baseline:")
            out += [f"  new        {k}" for k in self.new]
        if self.missing_cases:
            out.append(f"{len(self.missing_cases)} baseline case(s) absent from this run "
                       "(removed or not selected):")
            out += [f"  missing    {k}" for k in self.missing_cases]
        other = [k for k in self.missing if k.split("::", 1)[0] not in self.missing_cases]
        if other:
            out.append(f"{len(other)} baseline cell(s) not run:")
            out += [f"  missing    {k}" for k in other]
        if self.changed_cases:
            out.append("case file(s) changed since the baseline: " + ", ".join(self.changed_cases))
        if not out:
            out.append("no change against the baseline")
        return out


def slack_for(metric: str, old: float, table: dict[str, dict[str, float]] | None,
              case: str | None = None) -> float:
    """The slack of ``metric`` (``max(abs, rel * |old|)``): the table's entry for this case's
    metric (``"<case>::<metric>"``) if it has one, else for the metric, else the default."""
    table = table or DEFAULT_SLACK
    spec = ((table.get(f"{case}::{metric}") if case else None) or table.get(metric)
            or DEFAULT_SLACK.get(metric) or table.get("default") or DEFAULT_SLACK["default"])
    return max(float(spec.get("abs", 0.0)), float(spec.get("rel", 0.0)) * abs(old))


def compare(baseline: dict[str, Any], results: dict[str, Any]) -> Comparison:
    """Cell-by-cell comparison of a results document with a baseline (module docstring)."""
    cmp = Comparison()
    entries = baseline.get("entries", {})
    slack_table = baseline.get("slack")
    run_cells = {cell_key(c): c for c in results.get("cells", [])}
    run_cases = {c.get("case") for c in run_cells.values()}
    changed = set()
    for key, cell in run_cells.items():
        old = entries.get(key)
        if old is None:
            cmp.new.append(key)
            continue
        if old.get("case_sha256") and cell.get("case_sha256") and \
                old["case_sha256"] != cell["case_sha256"]:
            changed.add(cell["case"])
        old_status, new_status = old.get("status"), cell.get("status")
        if old_status != new_status:
            change = Change(key, None, old_status, new_status)
            if old_status == "pass":
                cmp.regressions.append(change)
            elif new_status == "pass":
                cmp.improvements.append(change)
            else:
                cmp.status_changes.append(change)
        new_metrics = cell.get("metrics") or {}
        for name, old_value in (old.get("metrics") or {}).items():
            entry = new_metrics.get(name)
            if entry is None or entry.get("meaningful", True) is False:
                cmp.dropped_metrics.append(Change(key, name, old_value, None))
                continue
            value = entry.get("value")
            if value is None:
                text = entry.get("value_text")
                value = float(text) if text else None
            if value is None:
                cmp.dropped_metrics.append(Change(key, name, old_value, None))
                continue
            s = slack_for(name, old_value, slack_table, cell.get("case"))
            worse, better = (value < old_value - s, value > old_value + s) \
                if name in HIGHER_IS_BETTER else (value > old_value + s, value < old_value - s)
            if isinstance(value, float) and math.isnan(value):
                worse, better = True, False
            if worse:
                cmp.regressions.append(Change(key, name, old_value, value, s))
            elif better:
                cmp.improvements.append(Change(key, name, old_value, value, s))
    for key, old in entries.items():
        if key not in run_cells:
            cmp.missing.append(key)
            case = old.get("case") or key.split("::", 1)[0]
            if case not in run_cases and case not in cmp.missing_cases:
                cmp.missing_cases.append(case)
    cmp.changed_cases = sorted(changed)
    return cmp


def describe(baseline: dict[str, Any], results: dict[str, Any]) -> dict[str, Any]:
    """What a run was compared against, for the reports: when and from which code the baseline
    was made (created, crosscheck version, commit, the source run's start and machine), its
    engine versions, how many of the run's cells it holds, and every engine whose version
    differs from this run's (``{engine: {"baseline": old, "run": new}}``), since numbers may
    move for that reason alone. A baseline made before commits were recorded has none."""
    source = baseline.get("source") or {}
    entries = baseline.get("entries") or {}
    old_engines = source.get("engines") or {}
    new_engines = results.get("engines") or {}
    changes = {name: {"baseline": old_engines.get(name), "run": new_engines.get(name)}
               for name in sorted(set(old_engines) | set(new_engines))
               if name in old_engines and name in new_engines
               and old_engines[name] != new_engines[name]}
    machine = source.get("machine") or {}
    return {
        "source": {"created": baseline.get("created"),
                   "crosscheck_version": baseline.get("crosscheck_version"),
                   "commit": source.get("commit"), "started": source.get("started"),
                   "machine": {k: machine.get(k) for k in ("hostname", "platform")
                               if machine.get(k)},
                   "engines": old_engines},
        "compared": sum(1 for c in results.get("cells", []) if cell_key(c) in entries),
        "engine_changes": changes,
    }


def _fmt(value) -> str:
    if value is None:
        return "none"
    if isinstance(value, float):
        return f"{value:.4g}"
    return str(value)
