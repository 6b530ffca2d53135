"""Verdicts: a cell's metrics against its case's tolerances.

A metric with a limit for this engine and integrator (``Tolerance.limit(engine, integrator)``;
``engine.integrator`` beats ``integrator`` beats ``engine`` beats ``default``) passes when
``value <= limit``; a NaN value fails. The cell's status is, in this order:

* ``blowup`` when the run blew up (non-finite state, or runaway energy; see metrics.blowup)
  -- unless the case *expects* it: a ``blowup_time`` limit for this engine and integrator means
  "must blow up no later than this" (a stability case), and then the blow-up time alone decides
  pass or fail (a run that stays bounded fails),
* ``fail`` when no metric at all has a value: nothing was measured, so nothing can have passed
  (a reference that produced nothing, a run with no samples); the reason says so,
* ``error`` when a tolerance names a metric this cell could not compute (a misspelt metric, a
  reference that failed or defines no such quantity) -- a case or harness problem, not physics,
* ``fail`` when any limited metric exceeds its limit (a NaN or infinite value exceeds any) or
  was not measured because the run gave it nothing to measure (``not_measured``: a flip period
  of a run that never flips; the reason says "not measured: why"),
* ``pass`` otherwise (including a case with no tolerances: its metrics are only reported).

A limit on a metric that is not meaningful in this scene (energy drift with drag) is ignored and
the metric says so: non-conserved quantities never fail a case. The worst metric of a cell is
the one with the largest ``value / limit``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

from crosscheck.scene.model import Scene

STATUSES = ("pass", "fail", "blowup", "error", "timeout", "not_applicable")
# Statuses that make `crosscheck run` exit 1 (not_applicable and pass do not).
FAILING = frozenset({"fail", "blowup", "error", "timeout"})


@dataclass
class Verdict:
    status: str
    reason: str = ""
    metrics: dict[str, dict[str, Any]] = field(default_factory=dict)
    worst: dict[str, Any] | None = None


def ratio(value: float | None, limit: float | None) -> float | None:
    """value / limit, inf when the limit is 0 and the value is not, NaN-safe."""
    if value is None or limit is None:
        return None
    if isinstance(value, float) and math.isnan(value):
        return math.inf
    if limit == 0:
        return 0.0 if value == 0 else math.inf
    return value / limit


def judge(scene: Scene, engine: str, integrator: str, metrics: dict[str, dict[str, Any]],
          *, blowup_time: float | None = None, blowup_reason: str | None = None,
          missing_reason: str = "") -> Verdict:
    """Attach limits to ``metrics`` (name -> Metric.to_dict()) and decide the status.

    ``missing_reason`` explains why reference metrics may be absent (e.g. the reference failed).
    """
    out = {name: dict(m) for name, m in metrics.items()}
    expect_blowup = None
    if "blowup_time" in scene.tolerances:
        expect_blowup = scene.tolerances["blowup_time"].limit(engine, integrator)
    if expect_blowup is not None:
        for name, tol in scene.tolerances.items():
            other_limit = tol.limit(engine, integrator)
            if name != "blowup_time" and other_limit is not None and name in out:
                out[name].update(limit=other_limit, passed=None,
                                 note=("not judged: the case expects a blow-up; "
                                       + out[name].get("note", "")).rstrip("; "))
        return _judge_expected_blowup(out, expect_blowup, blowup_time, blowup_reason)
    failed, missing = [], []
    for name, tol in scene.tolerances.items():
        limit = tol.limit(engine, integrator)
        if limit is None or name == "blowup_time":
            continue
        entry = out.get(name)
        if entry is not None and entry.get("not_measured"):
            # The run gave the metric nothing to measure (a flip period without flips): physics,
            # not a harness problem, and never a pass.
            entry.update(limit=limit, passed=False)
            failed.append(name)
            continue
        if entry is None or (entry.get("value") is None and "value_text" not in entry):
            note = f"tolerance {limit:g} given but the metric was not computed"
            if missing_reason:
                note += f" ({missing_reason})"
            if entry is None:
                entry = out[name] = {"value": None}
            entry.update(limit=limit, passed=False, note=(entry.get("note", "") + "; " + note)
                         .lstrip("; "))
            missing.append(name)
            continue
        entry["limit"] = limit
        if entry.get("meaningful", True) is False:
            entry["passed"] = None
            entry["note"] = "tolerance ignored: " + entry.get("note", "")
            continue
        value = entry.get("value")
        ok = value is not None and value <= limit  # NaN / inf stored as value None + value_text
        entry["passed"] = bool(ok)
        if not ok:
            failed.append(name)

    worst = None
    for name, entry in out.items():
        r = ratio(_numeric(entry), entry.get("limit")) if entry.get("passed") is not None else None
        if r is not None and (worst is None or r > worst["ratio"]):
            worst = {"metric": name, "value": _numeric(entry), "limit": entry["limit"],
                     "ratio": r}

    measured = [n for n, e in out.items()
                if e.get("value") is not None or e.get("value_text")]
    if blowup_time is not None:
        status, reason = "blowup", f"blew up at t = {blowup_time:.6g} s: {blowup_reason or ''}"
    elif not measured:
        status = "fail"
        reason = "no metric could be measured: " + (
            missing_reason or "the run and its reference gave no metric with a value")
        if missing:
            reason += f"; metric(s) with a tolerance not computed: {', '.join(missing)}"
    elif missing:
        status = "error"
        reason = f"metric(s) with a tolerance not computed: {', '.join(missing)}"
        if missing_reason:
            reason += f" ({missing_reason})"
    elif failed:
        status = "fail"
        reason = "; ".join(f"{n} not measured: {out[n]['not_measured']}"
                           if out[n].get("not_measured")
                           else f"{n} = {_fmt(_numeric(out[n]))} > {out[n]['limit']:g}"
                           for n in failed)
    else:
        status, reason = "pass", ""
    return Verdict(status=status, reason=reason.strip(), metrics=out, worst=worst)


def _judge_expected_blowup(out, limit, blowup_time, blowup_reason) -> Verdict:
    """A ``blowup_time`` limit says this run *must* blow up no later than ``limit`` seconds
    (a stability case: an explicit scheme past its step limit). Then the blow-up is the verdict
    and no other limit is judged (they would only measure how far the run ran away)."""
    entry = out.setdefault("blowup_time", {"value": blowup_time, "unit": "s"})
    entry["limit"] = limit
    if blowup_time is None:
        entry.update(value=None, passed=False,
                     note=f"the case expects a blow-up by t = {limit:g} s; the run stayed "
                          "bounded")
        return Verdict("fail", f"expected a blow-up by t = {limit:g} s (blowup_time limit), "
                       "the run stayed bounded", out,
                       {"metric": "blowup_time", "value": None, "limit": limit,
                        "ratio": math.inf})
    ok = blowup_time <= limit
    entry["passed"] = ok
    worst = {"metric": "blowup_time", "value": blowup_time, "limit": limit,
             "ratio": ratio(blowup_time, limit)}
    if ok:
        return Verdict("pass", f"blew up at t = {blowup_time:.6g} s as the case expects "
                       f"(<= {limit:g} s): {blowup_reason or ''}".strip(), out, worst)
    return Verdict("fail", f"blowup_time = {blowup_time:.6g} > {limit:g}: blew up later than "
                   "the case expects", out, worst)


def _numeric(entry: dict[str, Any]) -> float | None:
    if entry.get("value") is not None:
        return entry["value"]
    text = entry.get("value_text")
    return float(text) if text else None


def _fmt(value: float | None) -> str:
    return "n/a" if value is None else f"{value:.3g}"


def metric_table(metrics: dict[str, dict[str, Any]]) -> str:
    """A plain-text table of metrics (name, value, limit, verdict, note) for failures and logs."""
    rows = [("metric", "value", "limit", "verdict", "note")]
    for name in sorted(metrics, key=lambda n: (metrics[n].get("limit") is None, n)):
        m = metrics[name]
        value = _numeric(m)
        limit = m.get("limit")
        passed = m.get("passed")
        verdict = {True: "ok", False: "FAIL", None: "-"}[passed] if "passed" in m else "-"
        if m.get("meaningful") is False:
            verdict = "n/m"  # not meaningful in this scene
        rows.append((name, "n/a" if value is None else f"{value:.4g}" + (
            f" {m['unit']}" if m.get("unit") else ""),
            "" if limit is None else f"{limit:g}", verdict, m.get("note", "")[:90]))
    widths = [max(len(r[i]) for r in rows) for i in range(4)]
    lines = []
    for r in rows:
        lines.append("  ".join(r[i].ljust(widths[i]) for i in range(4)) + "  " + r[4])
    return "\n".join(line.rstrip() for line in lines)
