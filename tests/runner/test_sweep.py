"""``crosscheck sweep``: empirical order of convergence and largest stable step.

The orders come from real in-house runs of the undamped oscillator (w = 10 rad/s, 5 s) against
its analytic solution; each method must show its textbook order to within 0.05 over steps where
the error is far above round-off and far below saturation (measured 4.00, 2.00, 1.01-1.06).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest
from crosscheck_fakes import ALL
from test_runner_matrix import write_case

from crosscheck.runner.local import LocalBackend
from crosscheck.runner.plan import build_matrix
from crosscheck.runner.session import run_and_report
from crosscheck.scene.loader import load_case
from crosscheck.study.sweep import analyse, fit_order, pareto

CASES = Path(__file__).resolve().parents[2] / "cases"
HERE = Path(__file__).resolve().parent


def test_fit_order_recovers_a_power_law_and_ignores_round_off():
    dts = [4e-3, 2e-3, 1e-3, 5e-4]
    assert fit_order(dts, [3.0 * d**2 for d in dts]) == pytest.approx(2.0)
    # Errors at the round-off floor carry no order information and are left out.
    assert fit_order(dts, [3.0 * dts[0], 3.0 * dts[1], 1e-16, 1e-16]) == pytest.approx(1.0)
    assert fit_order(dts, [1e-16] * 4) is None


def test_orders_of_the_in_house_integrators(tmp_path):
    scene = load_case(CASES / "rigid3d" / "spring_anchor.toml")
    matrix = build_matrix([scene], engines=["inhouse"], dts=[2e-3, 1e-3, 5e-4],
                          integrators=["rk4", "midpoint", "symplectic_euler"], out=tmp_path)
    outcome = run_and_report(matrix, LocalBackend(2), tmp_path)
    metric, series = analyse(outcome.cells)
    assert metric == "position_error_max"
    orders = {s.integrator: s.order for s in series}
    assert orders["rk4"] == pytest.approx(4.0, abs=0.05)
    assert orders["midpoint"] == pytest.approx(2.0, abs=0.05)
    assert orders["symplectic_euler"] == pytest.approx(1.0, abs=0.1)
    assert all(s.largest_stable_dt == 2e-3 for s in series)
    # The most accurate point always sits on the Pareto front: RK4 at the smallest step.
    front = pareto(series)
    best = min(front, key=lambda p: p[3])
    assert best[0] == "inhouse-rk4" and best[1] == 5e-4


def test_sweep_command_finds_the_largest_stable_step(tmp_path):
    case = write_case(tmp_path, "sweepme", integrators='{ inhouse = ["euler", "unstable"] }',
                      reference='kind = "fine-step"\nengine = "inhouse"\nintegrator = "exact"\n'
                                'dt = 0.001', tolerances="")
    env = dict(os.environ, PYTHONPATH=str(HERE))
    res = subprocess.run(
        [sys.executable, "-m", "crosscheck.cli", "sweep", str(case), "--dts",
         "0.04,0.02,0.01,0.005", "--integrators", "euler,unstable", "--out", "sw",
         "--workers", "2", "--progress", "none",
         "--engine-ref", f"inhouse={ALL['exact']}"],
        cwd=tmp_path, env=env, capture_output=True, text=True, timeout=180)
    assert res.returncode == 0, res.stdout + res.stderr
    data = json.loads((tmp_path / "sw" / "sweep.json").read_text())
    series = {s["integrator"]: s for s in data["series"]}
    # The fake 'unstable' scheme blows up above dt = 0.01: 0.01 is its largest stable step.
    assert series["unstable"]["largest_stable_dt"] == 0.01
    assert series["unstable"]["statuses"][:2] == ["blowup", "blowup"]
    # Explicit Euler's free-fall lag g T h / 2 is exactly first order.
    assert series["euler"]["order"] == pytest.approx(1.0, abs=1e-6)
    assert (tmp_path / "sw" / "sweep.png").read_bytes()[:4] == b"\x89PNG"
    assert "largest stable dt" in (tmp_path / "sw" / "sweep.md").read_text()


def test_sweep_skips_metrics_that_cannot_tell_integrators_apart():
    # A torque-free body: the centre of mass never moves (position error exactly 0 at every
    # step), the analytic reference gives no orientation (NaN), and the case limits the flip
    # period. The sweep must plot the flip period, whose error does change with the step.
    from crosscheck.study.sweep import analyse, pick_metric

    def cell(dt, flip):
        return {"engine": "x", "integrator": "y", "dt": dt, "status": "pass", "cost": 1e-3,
                "metrics": {"position_error_max": {"value": 0.0, "limit": None},
                            "orientation_error_max": {"value": float("nan"), "limit": None},
                            "flip_period_error": {"value": flip, "limit": 1e-3},
                            "energy_drift": {"value": 1e-3 * dt, "limit": 1e-2}}}

    cells = [cell(2e-3, 4e-4), cell(1e-3, 1e-4), cell(5e-4, 2.5e-5)]
    assert pick_metric(cells) == "flip_period_error"
    metric, (series,) = analyse(cells)
    assert abs(series.order - 2.0) < 1e-9  # error ~ dt^2 across the three steps
