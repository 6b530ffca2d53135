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
from crosscheck.study.sweep import analyse, cheapest, fit_order, floor_reasons, pareto, table

CASES = Path(__file__).resolve().parents[2] / "cases"
SRC = Path(__file__).resolve().parents[2] / "src"
HERE = Path(__file__).resolve().parent
SWEEP_DTS = [4e-3, 2e-3, 1e-3, 5e-4, 2.5e-4, 1.25e-4]


def synthetic(errors, *, engine="inhouse", integrator="rk4", dts=SWEEP_DTS, metric="e_error",
              resolution=None, statuses=None, costs=None, not_measured=None):
    """Cells of one series with the given errors (None: not measured) at the given steps."""
    cells = []
    for k, (dt, e) in enumerate(zip(dts, errors, strict=True)):
        m = {metric: {"value": e, "limit": 1.0}}
        if e is None:
            m[metric]["not_measured"] = not_measured or "nothing to measure"
        if resolution is not None:
            m[metric.removesuffix("_error") + "_resolution"] = {"value": resolution}
        cells.append({"engine": engine, "integrator": integrator, "dt": dt,
                      "status": (statuses or ["pass"] * len(dts))[k],
                      "cost": (costs or [1e-3 / dt * 1e-3] * len(dts))[k], "metrics": m})
    return cells


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
    # This checkout's code first (the subprocess must not import another checkout's crosscheck).
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(SRC), str(HERE)]))
    res = subprocess.run(
        [sys.executable, "-m", "crosscheck.cli", "sweep", str(case), "--dts",
         "0.04,0.02,0.01,0.005", "--integrators", "euler,unstable", "--out", "sw",
         "--workers", "2", "--progress", "none", "--target", "0.03", "--json",
         "--engine-ref", f"inhouse={ALL['exact']}"],
        cwd=tmp_path, env=env, capture_output=True, text=True, timeout=300)
    assert res.returncode == 0, res.stdout + res.stderr
    data = json.loads((tmp_path / "sw" / "sweep.json").read_text())
    assert json.loads(res.stdout) == data
    series = {s["integrator"]: s for s in data["series"]}
    # The fake 'unstable' scheme blows up above dt = 0.01: 0.01 is its largest stable step,
    # and the bisection on the number of steps (1 s / N) brackets the limit to within 5 %.
    unstable = series["unstable"]
    assert unstable["largest_stable_dt"] == 0.01
    assert unstable["statuses"][:2] == ["blowup", "blowup"]
    lo, hi = unstable["largest_stable_dt"], unstable["smallest_unstable_dt"]
    assert lo <= 0.01 < hi and (hi - lo) / lo <= 0.05
    assert unstable["frontier"].startswith("between 0.01 and 0.01")
    assert {p["status"] for p in unstable["probes"]} == {"blowup"}  # all between 0.01 and 0.02
    # Explicit Euler never blows up on a free fall: doubled from 0.04 to the cap 1 s / 10.
    assert series["euler"]["largest_stable_dt"] == pytest.approx(0.1)
    assert series["euler"]["smallest_unstable_dt"] is None
    assert "no failure up to the cap 0.1" in series["euler"]["frontier"]
    assert data["frontier"]["cap"] == pytest.approx(0.1) and data["frontier"]["width"] == 0.05
    # Explicit Euler's free-fall lag g T h / 2 is exactly first order (sweep steps only).
    assert series["euler"]["order"] == pytest.approx(1.0, abs=1e-6)
    assert series["euler"]["order_points"] == [0.04, 0.02, 0.01, 0.005]
    # --target 0.03 m: the lag g T h / 2 <= 0.03 needs h <= 6.1e-3; the cheapest run that
    # reaches it is Euler at the largest such step, 0.005 (the unstable scheme at 0.005 costs
    # the same steps; either may win by timing, but no larger step qualifies).
    best = data["target"]["cheapest"]
    assert best["dt"] == 0.005 and best["error"] <= 0.03
    assert (tmp_path / "sw" / "sweep.png").read_bytes()[:4] == b"\x89PNG"
    page = (tmp_path / "sw" / "sweep.html").read_text()  # the figure and the table, one page
    assert page.count("<img ") == 1 and "<td>inhouse-unstable</td>" in page
    text = (tmp_path / "sw" / "sweep.md").read_text()
    assert "stability frontier" in text and "Target `position_error_max` <= 0.03" in text


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


def test_floor_detection_keeps_the_order_of_the_asymptotic_points():
    # A fourth-order error that saturates at 3e-8 (e = C dt^4 + 3e-8): fitted over all points
    # the slope is ~2.2; the stall (refinements that gain less than half the nominal order 4)
    # marks the points from 1e-3 down, and the order over the others is ~4.
    errors = [1e-5 * (d / 4e-3) ** 4 + 3e-8 for d in SWEEP_DTS]
    assert fit_order(SWEEP_DTS, errors) < 2.5
    _, (s,) = analyse(synthetic(errors))
    assert s.nominal_order == 4
    assert s.order == pytest.approx(4.0, abs=0.1)
    assert s.order_points == [4e-3, 2e-3]
    assert [bool(r) for r in s.floor] == [False, False, True, True, True, True]
    assert all("stopped falling" in r for r in s.floor[2:])
    md = table("e_error", [s])
    assert "(floor)" in md and "left out of the order: dt=0.001: error stopped falling" in md
    # A pre-asymptotic stretch followed by a healthy decrease is not a floor.
    assert floor_reasons([4, 2, 1, 0.5], [1.0, 0.9, 0.06, 0.004], None, 4) == [""] * 4


def test_a_stated_resolution_marks_the_floor_and_order_not_measurable():
    # The metric states its resolution (flip_period_resolution for flip_period_error): errors
    # within 10x of it are at the floor even where they still seem to fall.
    errors = [3e-5, 1.9e-6, 2.5e-7, 6e-8, 3.1e-8, 3.0e-8]
    _, (s,) = analyse(synthetic(errors, metric="flip_period_error", resolution=3e-8))
    assert s.order_points == [4e-3, 2e-3]
    assert "resolution" in s.floor[2]
    assert s.order == pytest.approx(fit_order([4e-3, 2e-3], errors[:2]))
    # Every point at the floor: no order, and the table says why.
    _, (s,) = analyse(synthetic([3.0e-8] * 6, metric="flip_period_error", resolution=3e-8))
    assert s.order is None and s.order_note == "order not measurable: floor reached"
    assert "order not measurable: floor reached" in table("flip_period_error", [s])


def test_an_unmeasured_metric_is_reported_as_not_measured():
    # explicit_euler on the tennis racket: no periodic flip, so no flip-period error at all
    # (the cell fails; it did not blow up).
    why = "crossings not periodic (23 sign changes, half periods 0.553 to 1.47 s)"
    cells = (synthetic([None] * 3, integrator="explicit_euler", dts=SWEEP_DTS[:3],
                       metric="flip_period_error", statuses=["fail"] * 3, not_measured=why)
             + synthetic([3e-5, 2e-6, 1.2e-7], dts=SWEEP_DTS[:3], metric="flip_period_error"))
    metric, series = analyse(cells)
    assert metric == "flip_period_error"
    ee = next(s for s in series if s.integrator == "explicit_euler")
    assert ee.errors == [None] * 3 and ee.not_measured == [why] * 3
    assert ee.largest_stable_dt == 4e-3  # not measured is not unstable
    assert ee.order is None and "not measurable" in ee.order_note
    md = table(metric, series)
    assert md.count("not measured: crossings not periodic") == 3
    assert f"not measured at dt = 0.004, 0.002, 0.001: {why}" in md
    assert pareto(series) and all(p[0] != "inhouse-explicit_euler" for p in pareto(series))


def test_target_picks_the_cheapest_qualifying_point():
    cells = (synthetic([1e-2, 1e-3, 1e-4], integrator="euler", dts=[4e-3, 2e-3, 1e-3],
                       costs=[1.0, 2.0, 4.0])
             + synthetic([5e-4, 3e-5, 2e-6], integrator="rk4", dts=[4e-3, 2e-3, 1e-3],
                         costs=[3.0, 6.0, 12.0])
             + synthetic([1e-6, None], integrator="fast", dts=[4e-3, 2e-3],
                         statuses=["blowup", "pass"], costs=[0.1, 0.5]))
    _, series = analyse(cells)
    # <= 1e-3: euler at 2e-3 (cost 2) beats rk4 at 4e-3 (cost 3); the blown-up and the
    # unmeasured cells never qualify however cheap.
    assert cheapest(series, 1e-3) == {"engine": "inhouse", "integrator": "euler", "dt": 2e-3,
                                      "error": 1e-3, "cost": 2.0}
    assert cheapest(series, 1e-4)["integrator"] == "euler"  # cost 4 < rk4's 6
    assert cheapest(series, 5e-5)["integrator"] == "rk4"
    assert cheapest(series, 1e-9) is None
    assert "none reaches it" in table("e_error", series, target=1e-9)
    assert "cheapest is inhouse rk4 at dt = 0.002" in table("e_error", series, target=5e-5)


def test_a_structure_that_collapses_or_gains_energy_is_unstable_for_the_frontier():
    # A contact stack can fail without a blow-up: it falls (collapse_time has a value) or a
    # solver pumps energy in (energy_gain over the case's limit). The frontier counts both.
    from crosscheck.study.sweep import analyse, stability

    def cell(dt, collapse=None, gain_passed=True):
        metrics = {"rest_drift_max": {"value": dt, "limit": 1.0},
                   "energy_gain": {"value": 0.0, "limit": 1e-3, "passed": gain_passed}}
        if collapse is not None:
            metrics["collapse_time"] = {"value": collapse}
        return {"engine": "mujoco", "integrator": "euler", "dt": dt, "status": "pass",
                "metrics": metrics, "cost": 1.0}

    cells = [cell(0.004, collapse=0.7), cell(0.002, gain_passed=False), cell(0.001),
             cell(0.0005)]
    assert [stability(c) for c in cells] == ["collapsed", "gained_energy", "pass", "pass"]
    _, (series,) = analyse(cells, "rest_drift_max")
    assert series.largest_stable_dt == 0.001 and series.smallest_unstable_dt == 0.002
    # A case that does not say its bodies must stand (no rest_drift_max limit): a body that
    # leaves its settled position (a dropped ball) has not collapsed.
    falling = cell(0.004, collapse=0.1)
    falling["metrics"]["rest_drift_max"].pop("limit")
    assert stability(falling) == "pass"


def test_a_structure_without_limits_still_fails_by_falling_or_gaining_energy():
    # mass_ratio_1000 sets no tolerance at all (its drift is a result to report), so no
    # rest_drift_max limit says it must stand: before must_stand, a 1000 kg box that squeezed
    # the light one out and an energy-pumping solver were both "stable" there.
    from crosscheck.study.sweep import STRUCTURE_ENERGY_GAIN, must_stand, stability

    heavy = load_case(CASES / "contact" / "mass_ratio_1000.toml")
    assert not heavy.tolerances and must_stand(heavy)
    assert must_stand(load_case(CASES / "contact" / "pyramid_2d.toml"))
    # A ball dropped from rest that bounces to rest is no structure.
    assert not must_stand(load_case(CASES / "contact" / "bounce_resting.toml"))
    assert not must_stand(load_case(CASES / "rigid3d" / "spring_anchor.toml"))

    def cell(**metrics):
        return {"engine": "pybullet", "integrator": "maximal", "dt": 0.01, "status": "pass",
                "metrics": {n: {"value": v} for n, v in metrics.items()}}

    fell = cell(energy_gain=0.0, collapse_time=0.42)
    assert stability(fell, stands=True) == "collapsed"
    assert stability(fell) == "pass"  # without the scene: no limit, no structure
    pumped = cell(energy_gain=3 * STRUCTURE_ENERGY_GAIN)
    assert stability(pumped, stands=True) == "gained_energy"
    assert stability(cell(energy_gain=0.5 * STRUCTURE_ENERGY_GAIN), stands=True) == "pass"


def test_a_fall_inside_the_settle_window_counts_as_a_collapse():
    # At a large step the settle window (the first 10 % of the run) can hold the whole fall:
    # the heavy box is on the ground by then and lies still, so collapse_time (measured from
    # the settled pose) stays unset; collapse_time_start (from the starting pose) catches it.
    from crosscheck.study.sweep import analyse, stability

    def cell(dt, start=None):
        metrics = {"rest_drift_max": {"value": 1e-5, "limit": 1.5e-3},
                   "energy_gain": {"value": 0.0}}
        if start is not None:
            metrics["collapse_time_start"] = {"value": start}
        return {"engine": "inhouse", "integrator": "rk4+penalty", "dt": dt, "status": "pass",
                "metrics": metrics}

    cells = [cell(0.04, start=0.04), cell(0.02), cell(0.01)]
    assert stability(cells[0]) == "collapsed"
    _, (series,) = analyse(cells, "rest_drift_max")
    assert (series.largest_stable_dt, series.smallest_unstable_dt) == (0.02, 0.04)
    assert series.runs[0]["status"] == "collapsed" and series.runs[0]["time"] == 0.04


def test_the_search_halves_below_a_step_that_fails():
    # Unstable at every sweep step: halve (whole step counts) down to the floor, so the series
    # gets a bracket instead of "below the smallest step run".
    from crosscheck.commands.sweep import next_probe

    assert next_probe(1.0, None, 1e-3, 0.1, 0.05, floor=1e-4) == pytest.approx(5e-4)
    assert next_probe(1.0, None, 1e-3, 0.1, 0.05, floor=None) is None
    assert next_probe(1.0, None, 1e-4, 0.1, 0.05, floor=1e-4) is None  # at the floor
    assert next_probe(1.0, None, 1.5e-4, 0.1, 0.05, floor=1e-4) is None  # 7.5e-5 is below it


@pytest.mark.parametrize("option", [["--target", "-1"], ["--max-dt", "-0.1"],
                                    ["--frontier-width", "0"], ["--frontier-rounds", "-2"]])
def test_sweep_refuses_a_meaningless_option_before_running(option, tmp_path, capsys):
    from crosscheck.cli import main

    case = Path(__file__).resolve().parents[2] / "cases" / "rigid3d" / "free_fall.toml"
    assert main(["sweep", str(case), "--out", str(tmp_path / "s"), *option]) == 2
    assert f"error: {option[0]}: expected" in capsys.readouterr().err
    assert not (tmp_path / "s").exists()  # nothing ran


@pytest.mark.slow
def test_the_frontier_of_a_contact_structure_is_bracketed_by_bisection(tmp_path):
    # MuJoCo (no compilation) on the 100:1 mass ratio (2 s): from dt = 4e-3 the search doubles
    # until the heavy box sinks or slides more than 0.1 x its size (measured: between 0.0147 and
    # 0.0152 s), then bisects. The reported bracket must hold when the two steps are run again
    # through the ordinary runner, and be within the stated resolution.
    from crosscheck.commands.sweep import _steps
    from crosscheck.study.sweep import UNSTABLE, must_stand, stability

    case = CASES / "contact" / "mass_ratio_100.toml"
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(SRC), str(HERE)]))
    res = subprocess.run(
        [sys.executable, "-m", "crosscheck.cli", "sweep", str(case), "--engines", "mujoco",
         "--integrators", "mujoco.euler", "--dts", "4e-3", "--no-cost", "--workers", "1",
         "--frontier-width", "0.05", "--out", "sw", "--progress", "none"],
        cwd=tmp_path, env=env, capture_output=True, text=True, timeout=600)
    assert res.returncode == 0, res.stdout + res.stderr
    data = json.loads((tmp_path / "sw" / "sweep.json").read_text())
    assert data["frontier"]["stands"] is True and data["frontier"]["cost"] is False
    (series,) = data["series"]
    lo, hi = series["largest_stable_dt"], series["smallest_unstable_dt"]
    assert lo is not None and hi is not None and lo < hi
    scene = load_case(case)
    duration = scene.run.duration
    # Within the resolution, or whole step counts adjacent (nothing lies between).
    assert (hi - lo) / lo <= 0.05 * (1 + 1e-6) or _steps(duration, lo) - _steps(duration, hi) == 1
    # Bisection, not "the largest step tried": stable runs on both sides of doubling, and the
    # failing step is above the largest doubling step that held.
    assert series["frontier"].startswith("between ")
    assert any(r["dt"] > 4e-3 and r["status"] not in UNSTABLE for r in series["runs"])
    # Run both steps again: stable at the largest stable step, failing at the smallest failing.
    matrix = build_matrix([scene], engines=["mujoco"], integrators=["mujoco.euler"],
                          dts=[lo, hi], out=tmp_path / "again", cost=False)
    outcome = run_and_report(matrix, LocalBackend(1), tmp_path / "again")
    status = {c["dt"]: stability(c, must_stand(scene)) for c in outcome.cells}
    assert status[lo] not in UNSTABLE
    assert status[hi] in UNSTABLE
