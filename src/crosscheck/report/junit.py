"""``junit.xml``: one ``<testcase>`` per case x engine x integrator (x dt when several).

``<testsuite name=CASE>`` groups a case's cells; ``classname`` is ``crosscheck.CASE`` and
``name`` is ``engine-integrator`` (``engine-integrator[dt=X]`` when the run swept steps), so CI
test views show one row per cell. Every metric is a ``<property name="metric.NAME" value=..>``
(``limit.NAME`` for its limit), plus ``cost`` and ``status``. ``fail`` and ``blowup`` are
``<failure>`` with the metric table as text, ``error`` and ``timeout`` are ``<error>``, not
applicable is ``<skipped message=reason>``, a baseline regression is a ``<failure>`` too.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path
from typing import Any


def _text(value) -> str:
    if value is None:
        return ""
    if isinstance(value, float):
        return repr(value)
    return str(value)


def render(doc: dict[str, Any]) -> str:
    from crosscheck.compare.verdict import metric_table

    cells = doc.get("cells", [])
    multi_dt = {}
    for c in cells:
        multi_dt.setdefault((c["case"], c["engine"], c["integrator"]), set()).add(c["dt"])
    root = ET.Element("testsuites", name="crosscheck")
    suites: dict[str, ET.Element] = {}
    totals = {"tests": 0, "failures": 0, "errors": 0, "skipped": 0}
    per_suite: dict[str, dict[str, int]] = {}
    for c in cells:
        case = c["case"]
        if case not in suites:
            suites[case] = ET.SubElement(root, "testsuite", name=case)
            per_suite[case] = {"tests": 0, "failures": 0, "errors": 0, "skipped": 0}
        name = f"{c['engine']}-{c['integrator']}"
        if len(multi_dt[(case, c["engine"], c["integrator"])]) > 1:
            name += f"[dt={c['dt']:g}]"
        tc = ET.SubElement(suites[case], "testcase", classname=f"crosscheck.{case}", name=name,
                           time=f"{(c.get('cell_seconds') or 0.0):.3f}")
        if c.get("case_file"):
            tc.set("file", str(c["case_file"]))
        props = ET.SubElement(tc, "properties")
        ET.SubElement(props, "property", name="status", value=c["status"])
        ET.SubElement(props, "property", name="dt", value=_text(c.get("dt")))
        if c.get("cost") is not None:
            ET.SubElement(props, "property", name="cost", value=_text(c["cost"]))
        if c.get("engine_version"):
            ET.SubElement(props, "property", name="engine_version", value=c["engine_version"])
        for mname, m in sorted((c.get("metrics") or {}).items()):
            value = m.get("value")
            ET.SubElement(props, "property", name=f"metric.{mname}",
                          value=_text(value if value is not None else m.get("value_text")))
            if m.get("limit") is not None:
                ET.SubElement(props, "property", name=f"limit.{mname}", value=_text(m["limit"]))
        counts = per_suite[case]
        counts["tests"] += 1
        status = c["status"]
        reason = (c.get("reason") or "").strip()
        table = metric_table(c.get("metrics") or {}) if c.get("metrics") else ""
        if status in ("fail", "blowup") or c.get("regression"):
            message = reason.splitlines()[0] if reason else ""
            if c.get("regression"):
                message = ("regression: " + "; ".join(c["regression"]) + (
                    f"; {message}" if message else ""))
            el = ET.SubElement(tc, "failure", message=message[:500], type=status)
            el.text = (reason + "\n\n" if reason else "") + table
            counts["failures"] += 1
        elif status in ("error", "timeout"):
            el = ET.SubElement(tc, "error", message=(reason.splitlines() or [""])[0][:500],
                               type=status)
            el.text = reason + ("\n\n" + table if table else "")
            counts["errors"] += 1
        elif status == "not_applicable":
            ET.SubElement(tc, "skipped", message=("not applicable: " + reason)[:500])
            counts["skipped"] += 1
    for case, el in suites.items():
        for k, v in per_suite[case].items():
            el.set(k, str(v))
            totals[k] += v
    for k, v in totals.items():
        root.set(k, str(v))
    ET.indent(root)
    return '<?xml version="1.0" encoding="utf-8"?>\n' + ET.tostring(root, encoding="unicode") \
        + "\n"


def write(doc: dict[str, Any], outdir: str | Path) -> Path:
    from crosscheck.report.atomic import write_text

    return write_text(Path(outdir) / "junit.xml", render(doc))
