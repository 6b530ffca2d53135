"""``summary.md``: one Markdown table for a CI step summary (e.g. ``$GITHUB_STEP_SUMMARY``).

One row per cell (case x engine x integrator x dt), ordered regressions first, then failures
(error, timeout, blowup, fail), passes, and not-applicable cells last; each row names the cell's
worst metric (largest value / limit) with its value and limit, its cost, and for a regression the
metric that got worse with old and new values. Baseline details (improvements, new and missing
cells) follow the table.
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
    status = doc.get("exit_status")
    verdict = {0: "passed", 1: "FAILED"}.get(status, "incomplete")
    lines = [f"## crosscheck {verdict}", "", headline(doc), ""]
    lines += ["| | case | engine | integrator | dt | worst metric | value | limit | "
              "cost (s/s, min +spread) | cost / MuJoCo | note |",
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
        lines.append(
            f"| {icon} | {_esc(c['case'])} | {c['engine']} | {c['integrator']} | "
            f"{c['dt']:g} | {worst.get('metric', '')} | {_num(worst.get('value'))} | "
            f"{_num(worst.get('limit'))} | {cost_text(c)} | "
            f"{_num(ratios.get(c.get('id')))} | {_esc(note)} |")
    base = doc.get("baseline")
    if base is not None:
        lines += ["", f"### Baseline `{base.get('file', '')}`", ""]
        for title, key in (("Regressions", "regressions"), ("Improvements", "improvements"),
                           ("Other status changes", "status_changes")):
            items = base.get(key) or []
            if items:
                lines.append(f"**{title}** ({len(items)}):")
                lines += [f"- {_change(ch)}" for ch in items]
                lines.append("")
        if base.get("new"):
            lines.append(f"**New cells** ({len(base['new'])}): "
                         + ", ".join(f"`{k}`" for k in base["new"]))
            lines.append("")
        if base.get("missing"):
            lines.append(f"**Baseline cells not in this run** ({len(base['missing'])}; cases "
                         "absent: " + (", ".join(base.get("missing_cases") or []) or "none")
                         + "): " + ", ".join(f"`{k}`" for k in base["missing"]))
            lines.append("")
        if base.get("changed_cases"):
            lines.append("**Case files changed since the baseline:** "
                         + ", ".join(base["changed_cases"]))
    res = doc.get("resources") or {}
    if res:
        lines += ["", f"Peak resident memory {_num(res.get('peak_rss_total_mb'))} MiB "
                  f"({res.get('backend')}, {res.get('workers')} workers), wall time "
                  f"{_num(res.get('wall_seconds'))} s."]
    return "\n".join(lines) + "\n"


def _change(ch: dict[str, Any]) -> str:
    if ch.get("metric") is None:
        return f"`{ch['cell']}`: status {ch['old']} -> {ch['new']}"
    return (f"`{ch['cell']}`: {ch['metric']} {_num(ch['old'])} -> {_num(ch['new'])} "
            f"(slack {_num(ch.get('slack'))})")


def write(doc: dict[str, Any], outdir: str | Path) -> Path:
    from crosscheck.report.atomic import write_text

    return write_text(Path(outdir) / "summary.md", render(doc))
