"""The overview matrix that leads index.html and summary.md: which run passes which case.

Rows are cases (a case run at several steps gets a row per step), columns are runs
(engine-integrator, an opaque label: an in-house contact run is "inhouse-symplectic_euler+
soft_step"), grouped by engine. Each entry is the verdict of that cell: its kind (pass, fail,
regression, blowup, error, timeout, not_applicable, or ``absent`` when the case does not run that
column at all), a short text (the worst metric's value against its limit, the blow-up time,
"n/a") and the detail a reader hovers for (the metric's name, the reason, the regression with
old and new values). Above the matrix come the problems: every regression and every cell that
failed, blew up, errored or timed out. The data is built once here and rendered as HTML (with
colour) and as Markdown (without).
"""

from __future__ import annotations

import html
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from crosscheck.report.style import ordered_labels, run_label

# Worst first: the entry of several cells (there should be one) shows the worst.
SEVERITY = {"regression": 0, "error": 1, "timeout": 1, "blowup": 2, "fail": 3, "pass": 5,
            "not_applicable": 6, "absent": 7}
FAILING = ("fail", "blowup", "error", "timeout")
COLORS = {"pass": "#bfe5bf", "fail": "#f4a6a6", "regression": "#ffb347", "blowup": "#c0392b",
          "error": "#d9a6e6", "timeout": "#f3d19c", "not_applicable": "#e6e6e6",
          "absent": "#ffffff"}
WORDS = {"pass": "pass", "fail": "FAIL", "regression": "REGRESSION", "blowup": "BLOW-UP",
         "error": "ERROR", "timeout": "TIMEOUT", "not_applicable": "n/a", "absent": "-"}


def anchor(case: str) -> str:
    return "case-" + "".join(ch if ch.isalnum() else "-" for ch in case)


def num(value) -> str:
    return "" if value is None else f"{value:.2g}"


@dataclass
class Entry:
    kind: str
    text: str  # shown in the matrix
    detail: str  # the hover text in HTML, the reason in Markdown's notes
    cell_id: str | None = None


@dataclass
class Row:
    case: str
    dt: float | None  # set when the case ran several steps
    group: str = ""  # the folder of the case file (rigid3d, contact, fluid, ...)
    entries: dict[str, Entry] = field(default_factory=dict)

    @property
    def name(self) -> str:
        return self.case + ("" if self.dt is None else f" (dt={self.dt:g})")


@dataclass
class Problem:
    case: str
    kind: str  # regression or a failing status
    text: str


@dataclass
class Overview:
    columns: list[str]
    engines: list[tuple[str, list[str]]]  # engine -> its columns, in column order
    rows: list[Row]
    problems: list[Problem]


def blowup_time(cell: dict[str, Any]) -> float | None:
    failure = cell.get("failure") or {}
    if isinstance(failure, dict) and failure.get("time") is not None:
        return float(failure["time"])
    m = (cell.get("metrics") or {}).get("blowup_time") or {}
    return m.get("value")


def _v(value) -> str:
    return f"{value:.4g}" if isinstance(value, int | float) else str(value)


def _first_line(text: str | None) -> str:
    return (text or "").strip().splitlines()[0] if (text or "").strip() else ""


def entry(cell: dict[str, Any]) -> Entry:
    """The matrix entry of one cell."""
    status = cell.get("status", "error")
    worst = cell.get("worst") or {}
    kind = "regression" if cell.get("regression") else status
    reason = _first_line(cell.get("reason"))
    if status == "blowup":
        t = blowup_time(cell)
        text = f"t={t:.3g} s" if t is not None else "blew up"
        return Entry(kind, text, reason or "blew up", cell.get("id"))
    if status in ("error", "timeout", "not_applicable"):
        return Entry(kind, WORDS[status], reason or status.replace("_", " "), cell.get("id"))
    if worst.get("value") is not None and worst.get("limit") is not None:
        text = f"{num(worst['value'])} / {num(worst['limit'])}"
        detail = f"worst: {worst.get('metric')} = {worst['value']:.3g} (limit {worst['limit']:g})"
    elif status == "pass":
        text, detail = "pass", "no metric of this run has a limit: nothing beyond a blow-up judged"
    else:
        text, detail = WORDS.get(status, status), reason
    if status == "fail" and reason and reason not in detail:
        detail += f"; {reason}"
    if cell.get("regression"):
        detail = "regression: " + "; ".join(cell["regression"]) + "; " + detail
    return Entry(kind, text, detail, cell.get("id"))


def build(doc: dict[str, Any], cells: list[dict[str, Any]] | None = None) -> Overview:
    """The overview of a results document (``cells``: the cells to show, default the doc's)."""
    cells = list(doc.get("cells", []) if cells is None else cells)
    columns = ordered_labels(cells)
    engines: dict[str, list[str]] = {}
    for c in cells:
        engines.setdefault(c["engine"], [])
    for label in columns:
        engine = next(c["engine"] for c in cells if run_label(c) == label)
        engines[engine].append(label)
    order = [e for e in engines if engines[e]]
    # Rows in the order of the run's case list (sorted by file, so a folder's cases are
    # together), then any case only the cells name.
    steps: dict[str, list[float]] = {c["name"]: [] for c in doc.get("cases", [])}
    group = {c["name"]: Path(c.get("file") or "").parent.name for c in doc.get("cases", [])}
    for c in cells:
        if c["dt"] not in steps.setdefault(c["case"], []):
            steps[c["case"]].append(c["dt"])
    rows: dict[tuple[str, float | None], Row] = {}
    for case, dts in steps.items():
        for dt in sorted(dts, reverse=True) if len(dts) > 1 else [None] if dts else []:
            rows[(case, dt)] = Row(case, dt, group.get(case, ""))
    for c in cells:
        row = rows.get((c["case"], c["dt"])) or rows[(c["case"], None)]
        new = entry(c)
        old = row.entries.get(run_label(c))
        if old is None or SEVERITY[new.kind] < SEVERITY[old.kind]:
            row.entries[run_label(c)] = new
    for row in rows.values():
        for label in columns:
            row.entries.setdefault(label, Entry(
                "absent", WORDS["absent"], "this case does not list this run"))
    return Overview(columns, [(e, engines[e]) for e in order], list(rows.values()),
                    problems(doc, cells))


def problems(doc: dict[str, Any], cells: list[dict[str, Any]]) -> list[Problem]:
    """Regressions (with old and new values) first, then the failing cells, worst first."""
    out = []
    by_id = {c.get("id"): c for c in cells}
    for ch in (doc.get("baseline") or {}).get("regressions") or []:
        cell = by_id.get(ch.get("cell")) or {}
        what = (f"status {ch.get('old')} -> {ch.get('new')}" if ch.get("metric") is None else
                f"{ch['metric']} {_v(ch.get('old'))} -> {_v(ch.get('new'))} "
                f"(slack {_v(ch.get('slack'))})")
        out.append(Problem(cell.get("case") or ch["cell"].split("::")[0], "regression",
                           f"{ch['cell'].split('::', 1)[-1]}: {what}"))
    failing = sorted((c for c in cells if c.get("status") in FAILING),
                     key=lambda c: (SEVERITY[c["status"]], c["case"], run_label(c)))
    for c in failing:
        e = entry(c)
        out.append(Problem(c["case"], c["status"], f"{c['id'].split('::', 1)[-1]}: "
                           f"{WORDS[c['status']]} "
                           + (e.text + "; " if c["status"] == "blowup" else "") + e.detail))
    return out


# -- HTML --------------------------------------------------------------------------------------
def _e(text) -> str:
    return html.escape("" if text is None else str(text))


CSS = """
table.overview{border-collapse:collapse;font-size:11px}
table.overview td,table.overview th{border:1px solid #bbb;padding:1px 4px;text-align:center;
white-space:nowrap}
table.overview th.case{text-align:left;position:sticky;left:0;background:#fff}
table.overview th.run{max-width:7em;white-space:normal;vertical-align:bottom}
table.overview tr.group th{text-align:left;background:#f4f4f4}
div.scroll{overflow-x:auto}
table.overview td a{color:inherit;text-decoration:none;display:block}
""" + "".join(f"td.k-{k}{{background:{c}}}" for k, c in COLORS.items()) + \
    "td.k-blowup{color:#fff}td.k-absent{color:#aaa}"


def legend_html() -> str:
    return "<p class='small'>" + " ".join(
        f"<span class='swatch' style='background:{COLORS[k]}'>&nbsp;&nbsp;&nbsp;</span> "
        f"{_e(w)}" for k, w in (("pass", "pass"), ("fail", "fail"),
                                ("regression", "regression against the baseline"),
                                ("blowup", "blew up (time)"), ("error", "error"),
                                ("timeout", "timeout"),
                                ("not_applicable", "not applicable (hover: why)"),
                                ("absent", "not run for this case"))) + \
        ". A cell shows the worst metric's value / its limit; hover for the metric.</p>"


def problems_html(overview: Overview) -> str:
    n_reg = sum(p.kind == "regression" for p in overview.problems)
    head = (f"<h2 id='problems'>Regressions ({n_reg}) and failures "
            f"({len(overview.problems) - n_reg})</h2>")
    if not overview.problems:
        return head + "<p>No regression and no failing cell.</p>"
    items = [f"<li class='p-{_e(p.kind)}'><a href='#{_e(anchor(p.case))}'>{_e(p.case)}</a>: "
             f"{_e(p.text)}</li>" for p in overview.problems]
    return head + "<ul class='problems'>" + "".join(items) + "</ul>"


def _breakable(label: str) -> str:
    """Escaped, with break opportunities after '_' and '+' so long run names wrap."""
    return _e(label).replace("_", "_<wbr>").replace("+", "+<wbr>")


def matrix_html(overview: Overview) -> str:
    head1 = "<tr><th class='case' rowspan='2'>case</th>" + "".join(
        f"<th colspan='{len(cols)}'>{_e(engine)}</th>" for engine, cols in overview.engines)
    head2 = "<tr>" + "".join(
        f"<th class='run'>{_breakable(label.removeprefix(engine + '-'))}</th>"
        for engine, cols in overview.engines for label in cols) + "</tr>"
    width = 1 + sum(len(cols) for _, cols in overview.engines)
    rows, group = [], None
    for row in overview.rows:
        if row.group != group and row.group:
            rows.append(f"<tr class='group'><th colspan='{width}'>{_e(row.group)}</th></tr>")
        group = row.group
        tds = []
        for _, cols in overview.engines:
            for label in cols:
                e = row.entries[label]
                inner = _e(e.text)
                if e.kind != "absent":
                    inner = f"<a href='#{_e(anchor(row.case))}'>{inner}</a>"
                tds.append(f"<td class='k-{e.kind}' title='{_e(label)}: {_e(e.detail)}'"
                           f" data-run='{_e(label)}'>{inner}</td>")
        rows.append(f"<tr data-case='{_e(row.case)}'><th class='case'><a href='"
                    f"#{_e(anchor(row.case))}'>{_e(row.name)}</a></th>{''.join(tds)}</tr>")
    return ("<div class='scroll'><table class='overview' id='overview'>" + head1 + "</tr>"
            + head2 + "".join(rows) + "</table></div>")


# -- Markdown ----------------------------------------------------------------------------------
def _md(text: str) -> str:
    return str(text).replace("|", "\\|").replace("\n", " ")


def matrix_markdown(overview: Overview) -> list[str]:
    """The matrix without colour: the verdict in words beside the numbers; the reasons of the
    not-applicable entries, which HTML shows on hover, follow it."""
    lines = ["| case | " + " | ".join(overview.columns) + " |",
             "|---|" + "---|" * len(overview.columns)]
    why: dict[str, list[str]] = {}
    for row in overview.rows:
        out = []
        for label in overview.columns:
            e = row.entries[label]
            if e.kind in ("pass", "absent", "not_applicable"):
                text = e.text if e.kind != "pass" or e.text == "pass" else f"pass {e.text}"
            elif e.kind in ("error", "timeout"):
                text = f"**{e.text}**"
            else:
                text = f"**{WORDS[e.kind]}** {e.text}"
            if e.kind == "not_applicable":
                why.setdefault(e.detail, []).append(f"{row.name} {label}")
            out.append(_md(text))
        lines.append(f"| {_md(row.name)} | " + " | ".join(out) + " |")
    lines += ["", "Each entry: the verdict and the worst metric's value / its limit (the metric "
              "is named in the table below); `-`: the case does not run it."]
    if why:
        lines += ["", "Not applicable:"]
        lines += [f"- {_md(reason)}: {', '.join(where)}" for reason, where in why.items()]
    return lines


def problems_markdown(overview: Overview) -> list[str]:
    if not overview.problems:
        return ["No regression and no failing cell."]
    return [f"- **{WORDS.get(p.kind, p.kind)}** {_md(p.text)}" for p in overview.problems]
