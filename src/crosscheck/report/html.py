"""``index.html``: a self-contained report (no external files, scripts or fonts).

Top: verdict, counts, machine, engine versions, resources, baseline changes. Then per case: its
description and reference, the figure of :mod:`crosscheck.report.plots` (energy drift, momentum
drift and trajectory error over time for every engine, cost against accuracy), the fluid plots
the fluid adapter produced, and a table of every cell with status, cost (wall seconds per
simulated second) beside its accuracy metrics, and the worst metric. Images are embedded as
``data:image/png;base64`` URIs (animations as ``data:image/gif``).
"""

from __future__ import annotations

import base64
import html
from pathlib import Path
from typing import Any

from crosscheck.report.markdown import ORDER, headline
from crosscheck.report.results import cost_text, mujoco_cost_ratios

STATUS_COLOR = {"pass": "#d9f2d9", "fail": "#f8d0d0", "blowup": "#f3b0b0", "error": "#f0c0f0",
                "timeout": "#f0d8b0", "not_applicable": "#eeeeee"}
TABLE_METRICS = ("energy_drift", "linear_momentum_drift", "angular_momentum_drift",
                 "position_error_max", "orientation_error_max", "velocity_error_max")

CSS = """
body{font-family:system-ui,sans-serif;margin:1.5em;color:#222;max-width:1400px}
table{border-collapse:collapse;font-size:12px;margin:0.5em 0}
td,th{border:1px solid #ccc;padding:2px 6px;text-align:right}
td.l,th.l{text-align:left}
h2{border-bottom:1px solid #aaa;margin-top:2em}
.small{color:#666;font-size:12px}
img{max-width:100%}
.reg{font-weight:bold;color:#a00}
"""


def _e(text) -> str:
    return html.escape("" if text is None else str(text))


def _num(value) -> str:
    return "" if value is None else f"{value:.3g}"


MIME = {".png": "image/png", ".gif": "image/gif", ".svg": "image/svg+xml", ".jpg": "image/jpeg"}


def _img(data: bytes, alt: str, mime: str = "image/png") -> str:
    return (f'<img alt="{_e(alt)}" src="data:{mime};base64,'
            f'{base64.b64encode(data).decode("ascii")}">')


def _metric_cell(cell: dict[str, Any], name: str) -> str:
    m = (cell.get("metrics") or {}).get(name)
    if not m:
        return "<td></td>"
    value = m.get("value")
    text = _num(value) if value is not None else _e(m.get("value_text", "n/a"))
    style = ""
    if m.get("passed") is False:
        style = ' style="background:#f8d0d0"'
    elif m.get("meaningful") is False:
        text = f"<i>{text}</i>"
    limit = m.get("limit")
    title = _e(m.get("note", "")) + (f" (limit {limit:g})" if limit is not None else "")
    return f'<td{style} title="{title}">{text}</td>'


def render(doc: dict[str, Any], series_cells: list[dict[str, Any]] | None = None) -> str:
    """The HTML page. ``series_cells``: cells with their ``series`` (default: doc's cells)."""
    from crosscheck.report.plots import case_figure

    cells = series_cells if series_cells is not None else doc.get("cells", [])
    status = {0: "passed", 1: "FAILED"}.get(doc.get("exit_status"), "incomplete")
    parts = [f"<!DOCTYPE html><html><head><meta charset='utf-8'><title>crosscheck {status}"
             f"</title><style>{CSS}</style></head><body>",
             f"<h1>crosscheck {status}</h1><p>{_e(headline(doc))}</p>"]
    parts.append("<p class='small'>started " + _e(doc.get("started")) + ", finished "
                 + _e(doc.get("finished")) + "; crosscheck " + _e(doc.get("crosscheck_version"))
                 + "; " + _e((doc.get("machine") or {}).get("platform")) + ", "
                 + _e((doc.get("machine") or {}).get("cpu_count")) + " cores</p>")
    engines = doc.get("engines") or {}
    if engines:
        parts.append("<p class='small'>engines: " + ", ".join(
            f"{_e(k)} {_e(v)}" for k, v in engines.items()) + "</p>")
    res = doc.get("resources") or {}
    if res:
        parts.append(f"<p class='small'>peak resident memory {_num(res.get('peak_rss_total_mb'))}"
                     f" MiB ({_e(res.get('backend'))}, {_e(res.get('workers'))} workers); "
                     f"wall time {_num(res.get('wall_seconds'))} s</p>")
    base = doc.get("baseline")
    if base is not None:
        parts.append(f"<h2>Baseline {_e(base.get('file'))}</h2><ul>")
        for title, key in (("regression", "regressions"), ("improvement", "improvements"),
                           ("status change", "status_changes")):
            for ch in base.get(key) or []:
                what = (f"status {ch['old']} &rarr; {ch['new']}" if ch.get("metric") is None
                        else f"{_e(ch['metric'])} {_num(ch['old'])} &rarr; {_num(ch['new'])}")
                cls = " class='reg'" if key == "regressions" else ""
                parts.append(f"<li{cls}>{title}: {_e(ch['cell'])}: {what}</li>")
        for k in base.get("new") or []:
            parts.append(f"<li>new: {_e(k)}</li>")
        for k in base.get("missing") or []:
            parts.append(f"<li>in the baseline, not in this run: {_e(k)}</li>")
        parts.append("</ul>")

    by_case: dict[str, list[dict[str, Any]]] = {}
    for c in cells:
        by_case.setdefault(c["case"], []).append(c)
    case_info = {c["name"]: c for c in doc.get("cases", [])}
    parts.append("<h2>Cases</h2><ul>")
    for case in by_case:
        worst = min(ORDER.get(c["status"], 4) for c in by_case[case])
        mark = next((s for s, o in ORDER.items() if o == worst), "")
        parts.append(f"<li><a href='#{_e(_anchor(case))}'>{_e(case)}</a> ({_e(mark)})</li>")
    parts.append("</ul>")
    for case, group in by_case.items():
        info = case_info.get(case, {})
        parts.append(f"<h2 id='{_e(_anchor(case))}'>{_e(case)}</h2>")
        parts.append(f"<p>{_e(info.get('description'))}<br><span class='small'>file "
                     f"{_e(info.get('file'))} (sha256 {_e((info.get('sha256') or '')[:12])}); "
                     f"reference: {_e(info.get('reference'))}</span></p>")
        try:
            png = case_figure(case, group)
        except Exception as exc:  # a plotting failure must not lose the report
            png = None
            parts.append(f"<p class='small'>plot failed: {_e(exc)}</p>")
        if png:
            parts.append(_img(png, f"{case}: drift and error over time"))
        for c in group:
            for p in c.get("plots") or []:
                try:
                    parts.append(_img(Path(p).read_bytes(), f"{case} {Path(p).stem}",
                                      MIME.get(Path(p).suffix.lower(), "image/png")))
                except OSError:
                    parts.append(f"<p class='small'>missing plot {_e(p)}</p>")
        parts.append(_cell_table(group))
    parts.append("</body></html>")
    return "\n".join(parts)


def _anchor(case: str) -> str:
    return "case-" + "".join(ch if ch.isalnum() else "-" for ch in case)


def _cell_table(cells: list[dict[str, Any]]) -> str:
    extra = sorted({n for c in cells for n in (c.get("metrics") or {})} - set(TABLE_METRICS)
                   - {"blowup_time"})
    names = [n for n in TABLE_METRICS if any(n in (c.get("metrics") or {}) for c in cells)]
    names += extra
    head = ("<tr><th class='l'>engine</th><th class='l'>integrator</th><th>dt</th>"
            "<th class='l'>status</th><th>cost (s/s, min +spread)</th><th>cost / MuJoCo</th>"
            + "".join(f"<th>{_e(n)}</th>" for n in names)
            + "<th class='l'>worst</th><th class='l'>note</th></tr>")
    rows = [head]
    ratios = mujoco_cost_ratios(cells)
    for c in sorted(cells, key=lambda c: (c["engine"], c["integrator"], c["dt"])):
        worst = c.get("worst") or {}
        note = "; ".join(c.get("regression") or []) or (c.get("reason") or "").splitlines()[:1]
        if isinstance(note, list):
            note = note[0] if note else ""
        status = "REGRESSION" if c.get("regression") else c["status"]
        rows.append(
            f"<tr style='background:{STATUS_COLOR.get(c['status'], '#fff')}'>"
            f"<td class='l'>{_e(c['engine'])}</td><td class='l'>{_e(c['integrator'])}</td>"
            f"<td>{c['dt']:g}</td><td class='l'>{_e(status)}</td><td>{_e(cost_text(c))}</td>"
            f"<td>{_num(ratios.get(c.get('id')))}</td>"
            + "".join(_metric_cell(c, n) for n in names)
            + f"<td class='l'>{_e(worst.get('metric', ''))} {_num(worst.get('ratio'))}</td>"
            f"<td class='l'>{_e(note)[:200]}</td></tr>")
    return "<table>" + "".join(rows) + "</table>"


def write(doc: dict[str, Any], outdir: str | Path,
          series_cells: list[dict[str, Any]] | None = None) -> Path:
    from crosscheck.report.atomic import write_text

    return write_text(Path(outdir) / "index.html", render(doc, series_cells))
