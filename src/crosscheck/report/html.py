"""``index.html``: the report a person reads, overview first.

Top: the verdict and headline, the run (times, crosscheck version and commit, machine, engine
versions, memory); the regressions and failures; the overview matrix (cases x runs, coloured
by verdict, :mod:`crosscheck.report.overview`); the baseline section
(:mod:`crosscheck.report.baseline_view`). Then per case: its description and reference, the
figure of the quantities that decide the verdict over time (:mod:`crosscheck.report.plots`) and
what it leaves out and why, the accuracy-against-cost figure (:mod:`crosscheck.report.cost_plot`),
a fluid run's validation plot, and a table of every cell with status, cost beside its accuracy
metrics, the worst metric and the reason.

One file with its figures embedded (``data:`` URIs, compact PNG or SVG,
:mod:`crosscheck.report.figure`), no scripts, nothing fetched. Heavy material stays out: a fluid
run's frame sheet and animation are files in the output folder, linked by relative paths.
"""

from __future__ import annotations

import base64
import html
import os
from pathlib import Path
from typing import Any

from crosscheck.report import figure_pool, overview
from crosscheck.report.markdown import headline
from crosscheck.report.overview import anchor
from crosscheck.report.results import cost_text, mujoco_cost_ratios

STATUS_COLOR = {"pass": "#e3f4e3", "fail": "#f8d0d0", "blowup": "#f3b0b0", "error": "#f0c0f0",
                "timeout": "#f0d8b0", "not_applicable": "#eeeeee"}
TABLE_METRICS = ("energy_drift", "linear_momentum_drift", "angular_momentum_drift",
                 "position_error_max", "orientation_error_max", "velocity_error_max")

CSS = """
body{font-family:system-ui,sans-serif;margin:1.5em;color:#222;max-width:1500px}
table{border-collapse:collapse;font-size:12px;margin:0.5em 0}
td,th{border:1px solid #ccc;padding:2px 6px;text-align:right}
td.l,th.l{text-align:left}
h2{border-bottom:1px solid #aaa;margin-top:2em}
.small{color:#666;font-size:12px}
img{max-width:100%;display:block;margin:0.5em 0}
.reg,li.p-regression{font-weight:bold;color:#a00}
.warn{background:#fff3cd}
nav a{margin-right:1em}
span.swatch{border:1px solid #999}
""" + overview.CSS

MIME = {".png": "image/png", ".gif": "image/gif", ".svg": "image/svg+xml", ".jpg": "image/jpeg"}


def _e(text) -> str:
    return html.escape("" if text is None else str(text))


def _num(value) -> str:
    return "" if value is None else f"{value:.3g}"


def _img(data: bytes, alt: str, mime: str = "image/png") -> str:
    return (f'<img alt="{_e(alt)}" src="data:{mime};base64,'
            f'{base64.b64encode(data).decode("ascii")}">')


def _metric_cell(cell: dict[str, Any], name: str) -> str:
    m = (cell.get("metrics") or {}).get(name)
    if not m:
        why = ("nothing was judged: " + cell["status"].replace("_", " ")
               if cell["status"] in ("not_applicable", "error", "timeout")
               else "not computed for this run")
        return f"<td class='na' title='{_e(why)}'>-</td>"
    value = m.get("value")
    text = _num(value) if value is not None else _e(m.get("value_text") or (
        "not measured" if m.get("not_measured") else "n/a"))
    style = ""
    if m.get("passed") is False:
        style = ' style="background:#f8d0d0"'
    elif m.get("meaningful") is False:
        text = f"<i>{text}</i>"
    limit = m.get("limit")
    title = _e(m.get("note", "")) + (f" (limit {limit:g})" if limit is not None else "")
    return f'<td{style} title="{title}">{text}</td>'


def _run_info(doc: dict[str, Any]) -> list[str]:
    machine = doc.get("machine") or {}
    commit = doc.get("commit")
    parts = ["<p class='small'>started " + _e(doc.get("started")) + ", finished "
             + _e(doc.get("finished")) + "; crosscheck " + _e(doc.get("crosscheck_version"))
             + (f" (commit {_e(commit[:12])}{'+dirty' if commit.endswith('+dirty') else ''})"
                if commit else "") + "; " + _e(machine.get("platform")) + ", "
             + _e(machine.get("cpu_count")) + " cores</p>"]
    engines = doc.get("engines") or {}
    if engines:
        parts.append("<p class='small'>engines: " + ", ".join(
            f"{_e(k)} {_e(v)}" for k, v in engines.items()) + "</p>")
    res = doc.get("resources") or {}
    if res:
        parts.append(f"<p class='small'>peak resident memory {_num(res.get('peak_rss_total_mb'))}"
                     f" MiB ({_e(res.get('backend'))}, {_e(res.get('workers'))} workers); "
                     f"wall time {_num(res.get('wall_seconds'))} s</p>")
    return parts


def render(doc: dict[str, Any], series_cells: list[dict[str, Any]] | None = None,
           outdir: str | Path | None = None) -> str:
    """The HTML page. ``series_cells``: cells with their ``series`` (default: doc's cells);
    ``outdir``: the folder the page is written to (linked files are relative to it)."""
    from crosscheck.report import baseline_view

    cells = series_cells if series_cells is not None else doc.get("cells", [])
    # The page's matrix and problems read the cells with the regression flags the document has.
    flags = {c.get("id"): c.get("regression") for c in doc.get("cells", [])}
    cells = [dict(c, regression=flags.get(c.get("id")) or c.get("regression")) for c in cells]
    view = overview.build(doc, cells)
    status = {0: "passed", 1: "FAILED"}.get(doc.get("exit_status"), "incomplete")
    parts = [f"<!DOCTYPE html><html lang='en'><head><meta charset='utf-8'>"
             f"<meta name='viewport' content='width=device-width'><title>crosscheck {status}"
             f"</title><style>{CSS}</style></head><body>",
             f"<h1>crosscheck {status}</h1><p>{_e(headline(doc))}</p>"]
    parts += _run_info(doc)
    parts.append("<nav><a href='#problems'>regressions and failures</a><a href='#overview'>"
                 "overview</a><a href='#baseline'>baseline</a><a href='#cases'>cases</a></nav>")
    parts.append(overview.problems_html(view))
    parts.append("<h2 id='overview-head'>Overview</h2>" + overview.legend_html()
                 + overview.matrix_html(view))
    parts.append(baseline_view.section_html(doc))
    parts.append("<h2 id='cases'>Cases</h2>")
    by_case: dict[str, list[dict[str, Any]]] = {c["name"]: [] for c in doc.get("cases", [])}
    for c in cells:
        by_case.setdefault(c["case"], []).append(c)
    case_info = {c["name"]: c for c in doc.get("cases", [])}
    groups = {case: group for case, group in by_case.items() if group}
    figures = figure_pool.draw_all(groups)
    for case, group in groups.items():
        parts += _case_section(case, group, case_info.get(case, {}), outdir, figures[case])
    parts.append("</body></html>")
    return "\n".join(parts)


def _case_section(case: str, group: list[dict[str, Any]], info: dict[str, Any],
                  outdir: str | Path | None, drawn: figure_pool.Drawn) -> list[str]:
    """``drawn``: the case's two figures (figure_pool.draw_case)."""
    from crosscheck.report.plots import panels

    parts = [f"<h2 id='{_e(anchor(case))}'>{_e(case)}</h2>",
             f"<p>{_e(info.get('description'))}<br><span class='small'>file "
             f"{_e(info.get('file'))} (sha256 {_e((info.get('sha256') or '')[:12])}); "
             f"reference: {_e(info.get('reference'))}</span></p>"]
    for k, (what, fig) in enumerate(zip(("the quantities that decide the verdict, over time",
                                         "accuracy against cost"), drawn, strict=True)):
        if isinstance(fig, str):
            parts.append(f"<p class='small'>{_e(what)}: plot failed: {_e(fig)}</p>")
        elif fig is not None:
            parts.append(_img(fig.data, f"{case}: {what}", fig.mime))
        if k == 0:
            omitted = panels(group)[1]
            if omitted:
                parts.append("<p class='small'>Not drawn: " + "; ".join(
                    _e(o) for o in omitted) + ".</p>")
    for c in group:
        parts += _fluid_plots(case, c, outdir)
    parts.append(_cell_table(group))
    return parts


def _relative(path: str, outdir: str | Path | None) -> str | None:
    """``path`` relative to the page's folder, or None when it lies outside it."""
    if outdir is None:
        return None
    rel = os.path.relpath(Path(path).resolve(), Path(outdir).resolve())
    return None if rel.startswith("..") else Path(rel).as_posix()


def _fluid_plots(case: str, cell: dict[str, Any], outdir) -> list[str]:
    from crosscheck.report.fluid_plots import embedded

    paths = [str(p) for p in cell.get("plots") or []]
    if not paths:
        return []
    shown = embedded(paths)
    parts = []
    if shown is not None:
        try:
            parts.append(_img(Path(shown).read_bytes(), f"{case} {Path(shown).stem}",
                              MIME.get(Path(shown).suffix.lower(), "image/png")))
        except OSError:
            parts.append(f"<p class='small'>missing plot {_e(shown)}</p>")
    links = []
    for p in paths:
        if p == shown:
            continue
        rel = _relative(p, outdir)
        kind = "animation" if p.endswith(".gif") else "frames" if "frames" in p else "figure"
        links.append(f"<a href='{_e(rel)}'>{_e(kind)}</a>" if rel else
                     f"{_e(kind)}: {_e(p)}")
    if links:
        parts.append(f"<p class='small'>{_e(cell['engine'])}-{_e(cell['integrator'])}: "
                     + ", ".join(links) + " (files in the report folder)</p>")
    return parts


def _cell_table(cells: list[dict[str, Any]]) -> str:
    extra = sorted({n for c in cells for n in (c.get("metrics") or {})} - set(TABLE_METRICS)
                   - {"blowup_time"})
    names = [n for n in TABLE_METRICS if any(n in (c.get("metrics") or {}) for c in cells)]
    names += extra
    head = ("<tr><th class='l'>engine</th><th class='l'>integrator</th><th>dt</th>"
            "<th class='l'>status</th><th>cost (s/s, min ±spread)</th><th>cost / MuJoCo</th>"
            + "".join(f"<th>{_e(n)}</th>" for n in names)
            + "<th class='l'>worst</th><th class='l'>note</th></tr>")
    rows = [head]
    ratios = mujoco_cost_ratios(cells)
    for c in sorted(cells, key=lambda c: (c["engine"], c["integrator"], c["dt"])):
        worst = c.get("worst") or {}
        note = "; ".join(c.get("regression") or []) or next(
            iter((c.get("reason") or "").splitlines()), "")
        status = "REGRESSION" if c.get("regression") else c["status"]
        ratio = ratios.get(c.get("id"))
        rows.append(
            f"<tr style='background:{STATUS_COLOR.get(c['status'], '#fff')}'>"
            f"<td class='l'>{_e(c['engine'])}</td><td class='l'>{_e(c['integrator'])}</td>"
            f"<td>{c['dt']:g}</td><td class='l'>{_e(status)}</td>"
            f"<td>{_e(cost_text(c) or 'not timed')}</td>"
            f"<td>{_num(ratio) if ratio is not None else '-'}</td>"
            + "".join(_metric_cell(c, n) for n in names)
            + f"<td class='l'>{_e(worst.get('metric', '-'))} {_num(worst.get('ratio'))}</td>"
            f"<td class='l'>{_e(note)[:200]}</td></tr>")
    return "<table>" + "".join(rows) + "</table>"


def write(doc: dict[str, Any], outdir: str | Path,
          series_cells: list[dict[str, Any]] | None = None) -> Path:
    from crosscheck.report.atomic import write_text

    return write_text(Path(outdir) / "index.html", render(doc, series_cells, outdir))
