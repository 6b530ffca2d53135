"""Baselines: per-metric absolute + relative slack, status regressions, new and missing cells,
and the CLI round trip (update, then a run that regresses exits 1 naming old and new values)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from crosscheck.baseline import baseline_from_results, compare, slack_for

HERE = Path(__file__).resolve().parent
FAKES = HERE.parent / "runner"


def cell(case, engine, status="pass", **metrics):
    return {"id": f"{case}::{engine}-rk4@dt=0.001", "case": case, "engine": engine,
            "integrator": "rk4", "dt": 0.001, "status": status, "case_sha256": "abc",
            "metrics": {k: ({"value": v} if not isinstance(v, dict) else v)
                        for k, v in metrics.items()}}


def results(*cells):
    return {"schema": "crosscheck-results", "cells": list(cells)}


def test_slack_is_the_larger_of_absolute_and_relative():
    assert slack_for("energy_drift", 1e-14, None) == 1e-10  # absolute floor (round-off)
    assert slack_for("energy_drift", 1e-3, None) == pytest.approx(1e-4)  # 10 %
    assert slack_for("position_error_max", 0.0, None) == 1e-9
    assert slack_for("energy_drift", 1.0, {"energy_drift": {"abs": 0, "rel": 0.5}}) == 0.5


def test_one_cases_metric_can_have_its_own_slack():
    """A chaotic case's symmetry breaking (the Wachs disc's drift off its axis, seeded by
    round-off) gets a slack of its own without loosening the metric for every other case."""
    table = {"centreline_offset": {"abs": 1e-4, "rel": 0.1},
             "wachs::centreline_offset": {"abs": 0.02, "rel": 0.1}}
    assert slack_for("centreline_offset", 0.002, table, "wachs") == 0.02
    assert slack_for("centreline_offset", 0.002, table, "settling") == pytest.approx(2e-4)
    assert slack_for("centreline_offset", 0.002, table) == pytest.approx(2e-4)
    base = baseline_from_results(results(cell("wachs", "inhouse", centreline_offset=0.002),
                                         cell("settling", "inhouse", centreline_offset=0.002)))
    base["slack"] = table
    now = results(cell("wachs", "inhouse", centreline_offset=0.013),
                  cell("settling", "inhouse", centreline_offset=0.013))
    worse = [c.key.split("::")[0] for c in compare(base, now).regressions]
    assert worse == ["settling"]


def test_regressions_improvements_and_unchanged():
    base = baseline_from_results(results(
        cell("a", "mujoco", energy_drift=1e-3, position_error_max=2e-3),
        cell("a", "inhouse", energy_drift=1e-14),
        cell("b", "pybullet", energy_drift={"value": 0.3, "meaningful": False})))
    # Non-conserved metrics carry no verdict and are not recorded.
    assert base["entries"]["b::pybullet-rk4@dt=0.001"]["metrics"] == {}
    now = results(
        cell("a", "mujoco", energy_drift=1.2e-3, position_error_max=1.0e-3),
        cell("a", "inhouse", energy_drift=5e-11),  # within the 1e-10 absolute slack
        cell("c", "pymunk"))
    cmp = compare(base, now)
    assert [(c.key, c.metric, c.old, c.new) for c in cmp.regressions] == [
        ("a::mujoco-rk4@dt=0.001", "energy_drift", 1e-3, 1.2e-3)]
    assert [(c.metric, c.new) for c in cmp.improvements] == [("position_error_max", 1e-3)]
    assert cmp.new == ["c::pymunk-rk4@dt=0.001"]
    assert cmp.missing == ["b::pybullet-rk4@dt=0.001"] and cmp.missing_cases == ["b"]
    text = "\n".join(cmp.lines())
    assert "REGRESSION a::mujoco-rk4@dt=0.001: energy_drift 0.001 -> 0.0012" in text
    assert "missing" in text and "new" in text


def test_a_merged_baseline_keeps_the_cells_and_engine_versions_it_did_not_rerun():
    first = dict(results(cell("a", "mujoco", energy_drift=1e-3), cell("b", "inhouse")),
                 engines={"mujoco": "4.0.0", "inhouse": "0.1.0"})
    base = baseline_from_results(first)
    rerun = dict(results(cell("b", "inhouse", energy_drift=2e-3)), engines={"inhouse": "0.1.1"})
    merged = baseline_from_results(rerun, previous=base, merge=True)
    assert set(merged["entries"]) == set(base["entries"])
    assert merged["entries"]["b::inhouse-rk4@dt=0.001"]["metrics"] == {"energy_drift": 2e-3}
    assert merged["source"]["engines"] == {"mujoco": "4.0.0", "inhouse": "0.1.1"}
    alone = baseline_from_results(rerun, previous=base)
    assert set(alone["entries"]) == {"b::inhouse-rk4@dt=0.001"}
    assert alone["source"]["engines"] == {"inhouse": "0.1.1"}


def test_status_changes():
    base = baseline_from_results(results(cell("a", "x"), cell("a", "y", "fail"),
                                         cell("a", "z")))
    now = results(cell("a", "x", "error"), cell("a", "y"), cell("a", "z", "not_applicable"))
    cmp = compare(base, now)
    # pass -> error and pass -> not applicable (an engine that stopped importing) regress.
    assert sorted((c.key[:3], c.new) for c in cmp.regressions) == [
        ("a::", "error"), ("a::", "not_applicable")]
    assert [(c.old, c.new) for c in cmp.improvements] == [("fail", "pass")]


def test_changed_case_file_is_flagged():
    base = baseline_from_results(results(cell("a", "x", energy_drift=0.1)))
    changed = cell("a", "x", energy_drift=0.1)
    changed["case_sha256"] = "def"
    assert compare(base, results(changed)).changed_cases == ["a"]


CASE = """
[case]
name = "fall"
dimension = 3
[run]
duration = {duration}
dt = 0.01
sample_every = 0.05
engines = ["inhouse"]
integrators = {{ inhouse = ["exact", "euler"] }}
[effects]
gravity = [0, 0, -9.81]
[[bodies]]
name = "ball"
shape = {{ sphere = {{ radius = 0.1 }} }}
mass = 2.0
position = [0, 0, 10]
[reference]
kind = "fine-step"
engine = "inhouse"
integrator = "exact"
dt = 0.001
[tolerances]
position_error_max = {{ default = 1e-9, euler = 0.2 }}
"""


def cli(args, cwd):
    env = dict(os.environ, PYTHONPATH=str(FAKES))
    return subprocess.run([sys.executable, "-m", "crosscheck.cli", *args], cwd=cwd, env=env,
                          capture_output=True, text=True, timeout=120)


@pytest.mark.slow
def test_update_then_regression_exits_1_with_old_and_new_values(tmp_path):
    case = tmp_path / "fall.toml"
    case.write_text(CASE.format(duration=1.0))
    er = ["--engine-ref", "inhouse=crosscheck_fakes:ExactEngine", "--workers", "1"]
    assert cli(["run", str(case), "--out", "r1", *er], tmp_path).returncode == 0
    res = cli(["baseline", "update", "--from", "r1", "--out", "base.json"], tmp_path)
    assert res.returncode == 0, res.stderr
    assert "new baseline" in res.stdout and "2 pass" in res.stdout
    base = json.loads((tmp_path / "base.json").read_text())
    euler = base["entries"]["fall::inhouse-euler@dt=0.01"]
    assert euler["metrics"]["position_error_max"] == pytest.approx(9.81 * 0.01 / 2, 1e-9)
    ok = cli(["run", str(case), "--out", "r2", "--baseline", "base.json", *er], tmp_path)
    assert ok.returncode == 0, ok.stdout + ok.stderr
    assert "no change against the baseline" in ok.stdout
    # Twice the duration: Euler's lag g T h / 2 doubles, still within its 0.2 m limit, but
    # twice the baseline value is a regression.
    case.write_text(CASE.format(duration=2.0))
    bad = cli(["run", str(case), "--out", "r3", "--baseline", "base.json", *er], tmp_path)
    assert bad.returncode == 1, bad.stdout + bad.stderr
    assert ("REGRESSION fall::inhouse-euler@dt=0.01: position_error_max 0.04905 -> 0.0981"
            in bad.stdout)
    assert "case file(s) changed since the baseline: fall" in bad.stdout
    summary = (tmp_path / "r3" / "summary.md").read_text()
    assert "**REGRESSION** | fall | inhouse | euler" in summary
    doc = json.loads((tmp_path / "r3" / "results.json").read_text())
    assert doc["baseline"]["regressions"][0]["old"] == pytest.approx(0.04905, 1e-9)
    # baseline compare gives the same verdict without running anything.
    res = cli(["baseline", "compare", "--from", "r3", "--baseline", "base.json"], tmp_path)
    assert res.returncode == 1 and "position_error_max" in res.stdout
    # Updating from the new run prints what changed.
    res = cli(["baseline", "update", "--from", "r3", "--out", "base.json"], tmp_path)
    assert res.returncode == 0 and "REGRESSION" in res.stdout
