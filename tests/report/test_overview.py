"""The overview matrix (cases x runs) and the problems listed above it, in HTML and Markdown;
the baseline section; summary.md's columns all filled."""

from __future__ import annotations

import re

from crosscheck.baseline import describe
from crosscheck.report import baseline_view, markdown, overview


def cell(case, engine, integrator, status="pass", dt=0.01, **extra):
    c = {"id": f"{case}::{engine}-{integrator}@dt={dt}", "case": case, "engine": engine,
         "integrator": integrator, "dt": dt, "status": status, "reason": "", "metrics": {}}
    c.update(extra)
    return c


def doc_of(cells, **extra):
    doc = {"cells": cells, "cases": [{"name": n, "file": f"cases/{g}/{n}.toml"} for n, g in
                                     (("fall", "rigid3d"), ("stack", "contact"))],
           "counts": {}, "exit_status": 1, "baseline": None}
    doc.update(extra)
    return doc


CELLS = [
    cell("fall", "inhouse", "rk4", worst={"metric": "position_error_max", "value": 2.1e-3,
                                          "limit": 5e-2, "ratio": 0.042}),
    cell("fall", "mujoco", "euler", "fail", reason="position_error_max = 0.2 > 0.05",
         worst={"metric": "position_error_max", "value": 0.2, "limit": 0.05, "ratio": 4}),
    cell("fall", "pybullet", "multibody", "blowup", reason="blew up at t = 1.25 s: runaway",
         failure={"time": 1.25, "reason": "runaway"}),
    cell("stack", "inhouse", "symplectic_euler+soft_step", "not_applicable",
         reason="contact model soft_step is not implemented yet"),
    cell("stack", "mujoco", "euler", worst={"metric": "penetration_max", "value": 1e-4,
                                            "limit": 5e-4, "ratio": 0.2},
         regression=["penetration_max 5e-05 -> 0.0001 (slack 5e-06)"]),
]


def test_matrix_has_an_entry_per_case_and_run_with_its_verdict():
    view = overview.build(doc_of(CELLS))
    assert [r.case for r in view.rows] == ["fall", "stack"]  # the case list's order
    # Runs grouped by engine; the contact run's name is one opaque column label.
    assert view.columns == ["inhouse-rk4", "inhouse-symplectic_euler+soft_step",
                            "mujoco-euler", "pybullet-multibody"]
    fall, stack = view.rows
    assert set(fall.entries) == set(stack.entries) == set(view.columns)
    assert (fall.entries["inhouse-rk4"].kind, fall.entries["inhouse-rk4"].text) == \
        ("pass", "0.0021 / 0.05")
    assert "position_error_max" in fall.entries["inhouse-rk4"].detail
    assert fall.entries["mujoco-euler"].kind == "fail"
    assert (fall.entries["pybullet-multibody"].kind,
            fall.entries["pybullet-multibody"].text) == ("blowup", "t=1.25 s")
    na = stack.entries["inhouse-symplectic_euler+soft_step"]
    assert na.kind == "not_applicable" and "not implemented" in na.detail
    assert stack.entries["mujoco-euler"].kind == "regression"
    assert stack.entries["pybullet-multibody"].kind == "absent"  # the case does not run it


def test_html_matrix_colours_links_and_hover():
    html = overview.matrix_html(overview.build(doc_of(CELLS)))
    rows = re.findall(r"<tr data-case='(\w+)'>(.*?)</tr>", html)
    assert [case for case, _ in rows] == ["fall", "stack"]
    for _, row in rows:
        assert len(re.findall(r"<td class='k-", row)) == 4
    stack = rows[1][1]
    assert re.search(r"<td class='k-not_applicable' title='inhouse-symplectic_euler\+soft_step: "
                     r"contact model soft_step is not implemented yet'", stack)
    assert "class='k-regression'" in stack and "href='#case-stack'" in stack
    assert "symplectic_<wbr>euler+<wbr>soft_<wbr>step" in html  # long names wrap
    assert "<tr class='group'><th colspan='5'>rigid3d</th>" in html


def test_problems_list_regressions_then_failures():
    base = {"regressions": [{"cell": CELLS[4]["id"], "metric": "penetration_max",
                             "old": 5e-5, "new": 1e-4, "slack": 5e-6}]}
    view = overview.build(doc_of(CELLS, baseline=base))
    kinds = [p.kind for p in view.problems]
    assert kinds == ["regression", "blowup", "fail"]
    assert "penetration_max 5e-05 -> 0.0001" in view.problems[0].text
    assert "t=1.25 s" in view.problems[1].text


def test_summary_md_leads_with_the_matrix_and_fills_every_column():
    text = markdown.render(doc_of(CELLS))
    matrix = text.index("| case | inhouse-rk4 |")
    assert matrix < text.index("### Every cell")
    assert "| fall | pass 0.0021 / 0.05 | - | **FAIL** 0.2 / 0.05 | **BLOW-UP** t=1.25 s |" \
        in text
    assert "- contact model soft_step is not implemented yet: stack " \
        "inhouse-symplectic_euler+soft_step" in text
    rows = [r for r in text.split("### Every cell", 1)[1].splitlines()
            if r.startswith("| ") and "---" not in r][1:]
    assert len(rows) == len(CELLS)
    for row in rows:
        fields = [f.strip() for f in row.strip().strip("|").split(" | ")]
        assert len(fields) == 11 and all(fields[:10]), row  # the note may be empty on a pass


def test_baseline_section_says_what_was_compared():
    baseline = {"created": "2026-01-01", "crosscheck_version": "0.1.0",
                "source": {"commit": "abcdef0123456789", "engines": {"mujoco": "3.2.0",
                                                                      "inhouse": "x"}},
                "entries": {CELLS[4]["id"]: {}}}
    doc = doc_of(CELLS, engines={"mujoco": "3.3.0", "inhouse": "x"})
    doc["baseline"] = {"file": "reports/baseline.json", "regressions": [
        {"cell": CELLS[4]["id"], "metric": "penetration_max", "old": 5e-5, "new": 1e-4,
         "slack": 5e-6}], "improvements": [{"cell": CELLS[0]["id"],
                                            "metric": "position_error_max", "old": 4e-3,
                                            "new": 2.1e-3, "slack": 4e-4}],
        **describe(baseline, doc)}
    assert doc["baseline"]["compared"] == 1
    assert doc["baseline"]["engine_changes"] == {"mujoco": {"baseline": "3.2.0",
                                                            "run": "3.3.0"}}
    html = baseline_view.section_html(doc)
    assert "commit abcdef012345" in html and "made 2026-01-01" in html
    assert "other engine versions than this run" in html and "mujoco 3.2.0 -&gt; 3.3.0" in html
    assert re.search(r"Regressions \(1\).*penetration_max</td><td>5e-05</td><td>0.0001</td>"
                     r"<td>x2</td>", html)
    assert re.search(r"Improvements \(1\).*position_error_max</td><td>0.004</td>", html)
    md = "\n".join(baseline_view.section_markdown(doc))
    assert "penetration_max 5e-05 -> 0.0001 (x2), slack 5e-06" in md
    assert "**The baseline was made with other engine versions than this run**" in md
    # Without a baseline the section still says something.
    assert "not compared with a baseline" in baseline_view.section_html(doc_of(CELLS))
