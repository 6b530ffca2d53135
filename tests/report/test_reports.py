"""The four reports of a run: JUnit XML parses with one testcase per cell and metrics as
properties, results.json follows its versioned schema, index.html is self-contained with its
plots embedded, summary.md puts regressions first, and writes are atomic."""

from __future__ import annotations

import base64
import hashlib
import json
import os
import re
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "runner"))
from crosscheck_fakes import ALL  # noqa: E402

from crosscheck.report import atomic, markdown  # noqa: E402
from crosscheck.report.results import SCHEMA, SCHEMA_VERSION  # noqa: E402
from crosscheck.runner.local import LocalBackend  # noqa: E402
from crosscheck.runner.plan import build_matrix  # noqa: E402
from crosscheck.runner.session import run_and_report  # noqa: E402
from crosscheck.scene.loader import load_case  # noqa: E402

CASE = """
[case]
name = "{name}"
description = "free fall of a spinning ball"
dimension = 3
[run]
duration = 1.0
dt = 0.01
sample_every = 0.05
engines = ["inhouse", "mujoco"]
integrators = {{ inhouse = ["exact", "euler", "fast_spin"] }}
[effects]
gravity = [0, 0, -9.81]
[[bodies]]
name = "ball"
shape = {{ sphere = {{ radius = 0.1 }} }}
mass = 2.0
position = [0, 0, 10]
angular_velocity = [0, 0, 2.0]
[reference]
kind = "fine-step"
engine = "inhouse"
integrator = "exact"
dt = 0.001
[tolerances]
position_error_max = {{ default = 1e-9, euler = 0.05 }}
orientation_error_max = 1e-6
"""


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory):
    folder = tmp_path_factory.mktemp("reports")
    er = {"inhouse": ALL["exact"], "mujoco": ALL["missing"]}
    scenes = []
    for name in ("alpha", "beta"):
        path = folder / f"{name}.toml"
        path.write_text(CASE.format(name=name))
        # The fakes' integrator names ("exact") are accepted for the engines they replace.
        scenes.append(load_case(path, unchecked_engines=er))
    out = folder / "out"
    matrix = build_matrix(scenes, out=out, engine_refs=er)
    outcome = run_and_report(matrix, LocalBackend(2), out)
    return folder, out, outcome


def test_junit_has_one_testcase_per_cell_with_metric_properties(run_dir):
    _, out, outcome = run_dir
    root = ET.parse(out / "junit.xml").getroot()
    assert root.tag == "testsuites"
    assert root.get("tests") == "8" and root.get("failures") == "2"
    assert root.get("skipped") == "2" and root.get("errors") == "0"
    cases = root.findall("./testsuite/testcase")
    names = sorted(f"{tc.get('classname')}::{tc.get('name')}" for tc in cases)
    assert names == sorted(f"crosscheck.{c}::{e}" for c in ("alpha", "beta") for e in (
        "inhouse-exact", "inhouse-euler", "inhouse-fast_spin", "mujoco-default"))
    euler = next(tc for tc in cases if tc.get("classname") == "crosscheck.alpha"
                 and tc.get("name") == "inhouse-euler")
    props = {p.get("name"): p.get("value") for p in euler.iter("property")}
    assert float(props["metric.position_error_max"]) == pytest.approx(9.81 * 0.01 / 2, 1e-9)
    assert float(props["limit.position_error_max"]) == 0.05
    assert props["status"] == "pass"
    spin = next(tc for tc in cases if tc.get("classname") == "crosscheck.alpha"
                and tc.get("name") == "inhouse-fast_spin")
    failure = spin.find("failure")
    assert failure is not None and "orientation_error_max" in failure.get("message")
    assert "metric" in failure.text and "limit" in failure.text  # the metric table
    skipped = next(tc for tc in cases if tc.get("name") == "mujoco-default").find("skipped")
    assert "not applicable" in skipped.get("message")


def test_results_json_schema(run_dir):
    folder, out, outcome = run_dir
    doc = json.loads((out / "results.json").read_text())
    assert doc["schema"] == SCHEMA and doc["schema_version"] == SCHEMA_VERSION
    for key, kind in (("crosscheck_version", str), ("started", str), ("finished", str),
                      ("machine", dict), ("engines", dict), ("cases", list), ("cells", list),
                      ("counts", dict), ("resources", dict), ("interrupted", bool),
                      ("exit_status", int)):
        assert isinstance(doc[key], kind), key
    assert doc["engines"]["inhouse"] == "fake-1.0"
    assert {"hostname", "platform", "python", "cpu_count"} <= set(doc["machine"])
    for case in doc["cases"]:
        text = (folder / f"{case['name']}.toml").read_bytes()
        assert case["sha256"] == hashlib.sha256(text).hexdigest()
    statuses = {"pass", "fail", "blowup", "error", "timeout", "not_applicable"}
    for cell in doc["cells"]:
        assert cell["status"] in statuses
        for key in ("id", "case", "engine", "integrator", "dt", "metrics", "reason"):
            assert key in cell, key
        assert "series" not in cell  # plot data stays out of results.json
        if cell["status"] in ("pass", "fail"):
            assert cell["cost"] > 0 and cell["case_sha256"]
            for m in cell["metrics"].values():
                assert m["value"] is None or isinstance(m["value"], float)
    assert doc["counts"] == {"pass": 4, "fail": 2, "not_applicable": 2}
    assert doc["exit_status"] == 1 == outcome.exit_status


def test_html_is_self_contained_and_embeds_its_plots(run_dir):
    _, out, _ = run_dir
    html = (out / "index.html").read_text()
    images = re.findall(r"""<img [^>]*src=["']data:image/(png|svg\+xml);base64,([A-Za-z0-9+/=]+)""",
                        html)
    assert len(images) == 4  # per case: the quantities over time, accuracy against cost
    for kind, data in images:
        head = base64.b64decode(data)[:8]
        assert head == b"\x89PNG\r\n\x1a\n" if kind == "png" else head.startswith(b"<?xml")
    # Nothing loaded from elsewhere: no external scripts, styles or images (links inside the
    # page only; a fluid run would add relative links to files in the folder).
    assert not re.search(r"""(src|href)=["'](?!data:|#)""", html)
    assert "cost (s/s, min ±spread)" in html and "alpha" in html and "beta" in html


def test_summary_lists_failures_before_passes_and_regressions_first(run_dir):
    _, out, outcome = run_dir
    text = (out / "summary.md").read_text()
    # The table of every cell (the overview matrix comes first, tested in test_overview.py).
    table = text.split("### Every cell", 1)[1]
    rows = [line for line in table.splitlines() if line.startswith("| ") and "---" not in line]
    statuses = [r.split("|")[1].strip() for r in rows[1:]]
    assert statuses[:2] == ["**FAIL**", "**FAIL**"] and statuses[-1] == "n/a"
    doc = dict(outcome.doc)
    doc["cells"] = [dict(c) for c in doc["cells"]]
    target = next(c for c in doc["cells"] if c["id"] == "beta::inhouse-exact@dt=0.01")
    target["regression"] = ["position_error_max 0 -> 1"]
    table = markdown.render(doc).split("### Every cell", 1)[1]
    rows = [line for line in table.splitlines() if line.startswith("| **")]
    assert rows[0].startswith("| **REGRESSION** | beta | inhouse | exact")


def test_atomic_write_keeps_the_old_file_when_the_write_fails(tmp_path, monkeypatch):
    target = tmp_path / "results.json"
    atomic.write_text(target, "old")

    def broken_replace(src, dst):
        raise OSError("disk full")

    monkeypatch.setattr(os, "replace", broken_replace)
    with pytest.raises(OSError):
        atomic.write_text(target, "new")
    assert target.read_text() == "old"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["results.json"]  # no temp left
