"""``--json`` on the commands that print results: one JSON document on stdout, people's text on
stderr, and the numbers in it are the physics (not just well-formed)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
CLI = [sys.executable, "-m", "crosscheck.cli"]


def _run(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([*CLI, *args], capture_output=True, text=True, cwd=ROOT, timeout=300)


@pytest.mark.slow
def test_run_json_carries_the_free_fall_error_of_explicit_euler(tmp_path):
    out = tmp_path / "run"
    proc = _run("run", "cases/rigid3d/free_fall.toml", "--engines", "inhouse", "--integrators",
                "explicit_euler,rk4", "--out", str(out), "--workers", "1", "--json")
    assert proc.returncode == 0, proc.stderr
    doc = json.loads(proc.stdout)  # stdout is exactly one JSON document
    assert "crosscheck:" in proc.stderr  # the human lines went to stderr
    cells = {c["integrator"]: c for c in doc["cells"]}
    # Explicit Euler's drop after T = 1 s at h = 1e-3 is short by g T h / 2 (exact: 4.905 m).
    err = cells["explicit_euler"]["metrics"]["position_error_max"]["value"]
    assert abs(err - 9.81 * 1.0 * 1e-3 / 2) < 1e-3 * 9.81 * 1e-3
    assert cells["rk4"]["metrics"]["position_error_max"]["value"] < 1e-9
    assert json.loads((out / "results.json").read_text())["counts"] == doc["counts"]


@pytest.mark.slow
def test_baseline_compare_json_lists_a_regression(tmp_path):
    out = tmp_path / "run"
    assert _run("run", "cases/rigid3d/free_fall.toml", "--engines", "inhouse", "--integrators",
                "explicit_euler", "--out", str(out), "--workers", "1").returncode == 0
    base = json.loads((out / "results.json").read_text())
    now = base["cells"][0]["metrics"]["position_error_max"]["value"]  # g T h / 2 = 4.9e-3 m
    # A baseline in which the same cell was ten times more accurate: the run is a regression.
    assert _run("baseline", "update", "--from", str(out), "--out",
                str(tmp_path / "b.json")).returncode == 0
    b = json.loads((tmp_path / "b.json").read_text())
    for entry in b["entries"].values():
        entry["metrics"]["position_error_max"] = 0.1 * now
    (tmp_path / "b.json").write_text(json.dumps(b))
    proc = _run("baseline", "compare", "--from", str(out), "--baseline", str(tmp_path / "b.json"),
                "--json")
    assert proc.returncode == 1, proc.stderr
    doc = json.loads(proc.stdout)
    assert any("position_error_max" in json.dumps(r) for r in doc["regressions"])


@pytest.mark.slow
def test_sweep_json_reports_the_order_of_symplectic_euler(tmp_path):
    proc = _run("sweep", "cases/rigid3d/spring_anchor.toml", "--engines", "inhouse",
                "--integrators", "symplectic_euler", "--dts", "4e-3,2e-3,1e-3",
                "--out", str(tmp_path / "s"), "--workers", "1", "--frontier-rounds", "0",
                "--json")
    assert proc.returncode == 0, proc.stderr
    doc = json.loads(proc.stdout)
    (series,) = doc["series"]
    # Symplectic Euler is first order in position on the oscillator.
    assert abs(series["order"] - 1.0) < 0.2
