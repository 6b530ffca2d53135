"""``summary.md``: the run for a CI step summary (e.g. ``$GITHUB_STEP_SUMMARY``).

The headline, the regressions and failures, then the overview matrix (cases x runs,
crosscheck.report.overview, without colour), then one row per cell (case x engine x integrator
x dt), ordered regressions first, then failures (error, timeout, blowup, fail), passes, and
not-applicable cells last; each row names the cell's worst metric (largest value / limit) with
its value and limit, its cost, and the reason or the regression with old and new values. Every
column is filled: where a value cannot exist the entry says so ("-" with the reason in the note,
"not timed", "no MuJoCo run"). The baseline section (crosscheck.report.baseline_view) follows.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from crosscheck.report.results import cost_text, mujoco_cost_ratios

ORDER = {"error": 1, "timeout": 1, "blowup": 2, "fail": 3, "pass": 5, "not_applicable": 6}
ICON = {"pass": "pass", "fail": "**FAIL**", "blowup": "**BLOWUP**", "error": "**ERROR**",
        "timeout": "**TIMEOUT**", "not_applicable": "n/a"}


def _esc(text: str) -> str:
    return str(text).replace("|", "\\|").replace("\n", " ")


def _num(value) -> str:
    if value is None:
        return ""
    return f"{value:.3g}"


def sort_cells(cells: list[dict[str, Any]]) -> list[dict[str, Any]]:
    return sorted(cells, key=lambda c: (0 if c.get("regression") else ORDER.get(c["status"], 4),
                                        c.get("case", ""), c.get("engine", ""),
                                        c.get("integrator", ""), c.get("dt") or 0))


def headline(doc: dict[str, Any]) -> str:
    cells = doc.get("cells", [])
    counts = doc.get("counts") or {}
    parts = [f"{counts.get(s, 0)} {s.replace('_', ' ')}" for s in
             ("pass", "fail", "blowup", "error", "timeout", "not_applicable") if counts.get(s)]
    regressions = len((doc.get("baseline") or {}).get("regressions", []))
    text = f"{len(cells)} cells: " + ", ".join(parts or ["none"])
    if doc.get("baseline") is not None:
        text += f"; {regressions} regression(s) against the baseline"
    if doc.get("interrupted"):
        text += f"; INTERRUPTED, {len(doc.get('not_run', []))} cell(s) not run"
    if doc.get("checked_nothing"):
        text += f"; FAILED: {doc['checked_nothing']}"
    return text


def render(doc: dict[str, Any]) -> str:
    from crosscheck.report import baseline_view, overview

    status = doc.get("exit_status")
    verdict = {0: "passed", 1: "FAILED"}.get(status, "incomplete")
    view = overview.build(doc)
    lines = [f"## crosscheck {verdict}", "", headline(doc), ""]
    lines += overview.problems_markdown(view) + [""]
    lines += overview.matrix_markdown(view) + [""]
    lines += ["### Every cell", "",
              "| | case | engine | integrator | dt | worst metric | value | limit | "
              "cost (s/s, min ±spread) | cost / MuJoCo | note |",
              "|---|---|---|---|---|---|---|---|---|---|---|"]
    ratios = mujoco_cost_ratios(doc.get("cells", []))
    for c in sort_cells(doc.get("cells", [])):
        worst = c.get("worst") or {}
        note = ""
        if c.get("regression"):
            note = "REGRESSION: " + "; ".join(c["regression"])
        elif c["status"] != "pass":
            note = (c.get("reason") or "").splitlines()[0][:140] if c.get("reason") else ""
        icon = "**REGRESSION**" if c.get("regression") else ICON.get(c["status"], c["status"])
        metric, value, limit = _worst_columns(c, worst)
        ratio = ratios.get(c.get("id"))
        lines.append(
            f"| {icon} | {_esc(c['case'])} | {c['engine']} | {c['integrator']} | "
            f"{c['dt']:g} | {metric} | {value} | {limit} | {_esc(cost_text(c) or NO_COST)} | "
            f"{_num(ratio) if ratio is not None else _no_ratio(c)} | {_esc(note)} |")
    lines += [""] + baseline_view.section_markdown(doc)
    res = doc.get("resources") or {}
    if res:
        lines += ["", f"Peak resident memory {_num(res.get('peak_rss_total_mb'))} MiB "
                  f"({res.get('backend')}, {res.get('workers')} workers), wall time "
                  f"{_num(res.get('wall_seconds'))} s."]
    return "\n".join(lines) + "\n"


NO_COST = "not timed"


def _worst_columns(cell: dict[str, Any], worst: dict[str, Any]) -> tuple[str, str, str]:
    """(metric, value, limit) of the worst metric, or a word for why there is none."""
    if worst.get("metric"):
        value = worst.get("value")
        return (worst["metric"], _num(value) if value is not None else "not finite",
                _num(worst.get("limit")) if worst.get("limit") is not None else "none")
    if cell["status"] in ("not_applicable", "error", "timeout"):
        return "-", "-", "-"  # the note says why: nothing ran or was judged
    return "none limited", "-", "-"


def _no_ratio(cell: dict[str, Any]) -> str:
    """Why a cell has no cost / MuJoCo: no cost of its own, or no MuJoCo run to divide by."""
    return "-" if not cell.get("cost") else "no MuJoCo run"


def write(doc: dict[str, Any], outdir: str | Path) -> Path:
    from crosscheck.report.atomic import write_text

    return write_text(Path(outdir) / "summary.md", render(doc))
