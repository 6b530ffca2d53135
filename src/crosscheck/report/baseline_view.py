"""The "Baseline" section of index.html and summary.md: what the run was compared against.

It says which file, made when, from which crosscheck version and commit, on which engine
versions (with a warning when this run's engines differ: numbers may move for that reason
alone), how many cells were compared, then the regressions and the improvements with old and
new values and the slack, other status changes, metrics no longer computed, new and missing
cells and case files changed since. Without a baseline it says how to get one. The comparison
itself is crosscheck.baseline's; this module only presents ``doc["baseline"]``.
"""

from __future__ import annotations

import html
from typing import Any

from crosscheck.report.overview import anchor


def _e(text) -> str:
    return html.escape("" if text is None else str(text))


def _v(value) -> str:
    if isinstance(value, bool) or value is None:
        return "none" if value is None else str(value)
    return f"{value:.4g}" if isinstance(value, int | float) else str(value)


def _factor(ch: dict[str, Any]) -> str:
    old, new = ch.get("old"), ch.get("new")
    if isinstance(old, int | float) and isinstance(new, int | float) and old and new:
        return f"x{new / old:.3g}"
    return ""


def origin(base: dict[str, Any]) -> str:
    src = base.get("source") or {}
    parts = [f"made {src.get('created') or 'at an unrecorded time'}"]
    parts.append(f"crosscheck {src.get('crosscheck_version') or '?'}")
    parts.append(f"commit {src['commit'][:12]}" if src.get("commit")
                 else "commit not recorded (a baseline from before commits were recorded)")
    machine = src.get("machine") or {}
    if machine:
        parts.append("on " + ", ".join(str(v) for v in machine.values()))
    return "; ".join(parts)


def engine_rows(base: dict[str, Any], doc: dict[str, Any]) -> list[tuple[str, str, str, bool]]:
    """(engine, baseline version, this run's version, same?) for every engine of either."""
    old = (base.get("source") or {}).get("engines") or {}
    new = doc.get("engines") or {}
    return [(name, old.get(name, "not in the baseline"), new.get(name, "not in this run"),
             old.get(name) == new.get(name)) for name in sorted(set(old) | set(new))]


def counts_text(base: dict[str, Any]) -> str:
    n = {k: len(base.get(k) or []) for k in ("regressions", "improvements", "status_changes",
                                             "new", "missing", "changed_cases")}
    compared = base.get("compared")
    return (f"{compared if compared is not None else '?'} cell(s) compared: "
            f"{n['regressions']} regression(s), {n['improvements']} improvement(s), "
            f"{n['status_changes']} other status change(s); {n['new']} new cell(s) not in the "
            f"baseline, {n['missing']} baseline cell(s) not in this run; "
            f"{n['changed_cases']} case file(s) changed since.")


def _case_of(cell_id: str) -> str:
    return cell_id.split("::", 1)[0]


# -- HTML --------------------------------------------------------------------------------------
def _changes_table(title: str, changes: list[dict[str, Any]], cls: str) -> str:
    if not changes:
        return f"<p>{_e(title)}: none.</p>"
    rows = "".join(
        f"<tr class='{cls}'><td class='l'><a href='#{_e(anchor(_case_of(ch['cell'])))}'>"
        f"{_e(ch['cell'])}</a></td><td class='l'>{_e(ch.get('metric') or 'status')}</td>"
        f"<td>{_e(_v(ch.get('old')))}</td><td>{_e(_v(ch.get('new')))}</td>"
        f"<td>{_e(_factor(ch))}</td><td>{_e(_v(ch.get('slack')) if ch.get('metric') else '')}"
        "</td></tr>" for ch in changes)
    return (f"<h3>{_e(title)} ({len(changes)})</h3><table><tr><th class='l'>cell</th>"
            "<th class='l'>metric</th><th>baseline</th><th>this run</th><th>ratio</th>"
            f"<th>slack</th></tr>{rows}</table>")


def section_html(doc: dict[str, Any]) -> str:
    base = doc.get("baseline")
    if base is None:
        return ("<h2 id='baseline'>Baseline</h2><p>This run was not compared with a baseline "
                "(<code>crosscheck run ... --baseline reports/baseline.json</code> compares it "
                "and fails on a regression).</p>")
    parts = [f"<h2 id='baseline'>Baseline: {_e(base.get('file'))}</h2>",
             f"<p>Compared against <code>{_e(base.get('file'))}</code>, {_e(origin(base))}."
             f"<br>{_e(counts_text(base))}</p>"]
    changes = base.get("engine_changes") or {}
    if changes:
        parts.append("<p class='warn'><b>The baseline was made with other engine versions than "
                     "this run</b> (" + _e(", ".join(
                         f"{k} {v['baseline']} -> {v['run']}" for k, v in changes.items()))
                     + "): numbers may move for that reason alone.</p>")
    parts.append("<table><tr><th class='l'>engine</th><th class='l'>baseline</th>"
                 "<th class='l'>this run</th></tr>" + "".join(
                     f"<tr{'' if same else ' class=warn'}><td class='l'>{_e(n)}</td>"
                     f"<td class='l'>{_e(o)}</td><td class='l'>{_e(r)}</td></tr>"
                     for n, o, r, same in engine_rows(base, doc)) + "</table>")
    parts.append(_changes_table("Regressions", base.get("regressions") or [], "reg"))
    parts.append(_changes_table("Improvements", base.get("improvements") or [], "imp"))
    if base.get("status_changes"):
        parts.append(_changes_table("Other status changes", base["status_changes"], ""))
    if base.get("dropped_metrics"):
        parts.append(_changes_table("Metrics no longer computed", base["dropped_metrics"], ""))
    for title, key in (("New cells (not in the baseline)", "new"),
                       ("Baseline cells not in this run", "missing")):
        items = base.get(key) or []
        if items:
            parts.append(f"<details><summary>{_e(title)} ({len(items)})</summary><p class="
                         "'small'>" + ", ".join(_e(k) for k in items) + "</p></details>")
    if base.get("changed_cases"):
        parts.append("<p>Case files changed since the baseline (their numbers may move for "
                     "that reason): " + ", ".join(_e(k) for k in base["changed_cases"]) + "</p>")
    return "\n".join(parts)


# -- Markdown ----------------------------------------------------------------------------------
def _change_line(ch: dict[str, Any]) -> str:
    if ch.get("metric") is None:
        return f"- `{ch['cell']}`: status {ch.get('old')} -> {ch.get('new')}"
    factor = _factor(ch)
    return (f"- `{ch['cell']}`: {ch['metric']} {_v(ch.get('old'))} -> {_v(ch.get('new'))}"
            + (f" ({factor})" if factor else "") + f", slack {_v(ch.get('slack'))}")


def section_markdown(doc: dict[str, Any]) -> list[str]:
    base = doc.get("baseline")
    if base is None:
        return ["### Baseline", "", "Not compared with a baseline (`--baseline FILE`)."]
    lines = [f"### Baseline `{base.get('file', '')}`", "",
             f"Compared against `{base.get('file', '')}`, {origin(base)}.", "",
             counts_text(base), ""]
    changes = base.get("engine_changes") or {}
    if changes:
        lines += ["**The baseline was made with other engine versions than this run** ("
                  + ", ".join(f"{k} {v['baseline']} -> {v['run']}" for k, v in changes.items())
                  + "): numbers may move for that reason alone.", ""]
    for title, key in (("Regressions", "regressions"), ("Improvements", "improvements"),
                       ("Other status changes", "status_changes"),
                       ("Metrics no longer computed", "dropped_metrics")):
        items = base.get(key) or []
        if items or key in ("regressions", "improvements"):
            lines.append(f"**{title}** ({len(items)})" + (":" if items else "."))
            lines += [_change_line(ch) for ch in items]
            lines.append("")
    if base.get("new"):
        lines += [f"**New cells** ({len(base['new'])}): "
                  + ", ".join(f"`{k}`" for k in base["new"]), ""]
    if base.get("missing"):
        lines += [f"**Baseline cells not in this run** ({len(base['missing'])}; cases absent: "
                  + (", ".join(base.get("missing_cases") or []) or "none") + "): "
                  + ", ".join(f"`{k}`" for k in base["missing"]), ""]
    if base.get("changed_cases"):
        lines.append("**Case files changed since the baseline:** "
                     + ", ".join(base["changed_cases"]))
    return lines
