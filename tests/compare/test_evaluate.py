"""``compare.evaluate``: one run, its reference (or the reason it has none) -> the verdict.

Runs come from the fake adapters in tests/runner/crosscheck_fakes.py, whose errors are known in
closed form (explicit Euler lags free fall by g t h / 2).
"""

from __future__ import annotations

import math
import sys
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from crosscheck.compare.evaluate import evaluate
from crosscheck.reference.spec import Reference, for_cell, reference_spec
from crosscheck.scene.loader import load_case, load_case_text

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "runner"))
from crosscheck_fakes import BlowupEngine, ExactEngine  # noqa: E402

CASES = Path(__file__).resolve().parents[2] / "cases"
G, H, T = 9.81, 0.01, 1.0

FALL = f"""
[case]
name = "fall"
dimension = 3
[run]
duration = {T}
dt = {H}
sample_every = 0.05
engines = ["inhouse"]
[effects]
gravity = [0, 0, -9.81]
[[bodies]]
name = "ball"
shape = {{ sphere = {{ radius = 0.1 }} }}
mass = 2.0
position = [0, 0, 10]
velocity = [1.0, 0, 0]
[reference]
kind = "analytic"
solution = "free_fall"
[tolerances]
position_error_max = 1e-3
"""


@pytest.fixture(scope="module")
def scene():
    return load_case_text(FALL)


def test_rigid_run_judged_against_its_analytic_reference(scene):
    run = ExactEngine().run(scene, "euler", H)
    ref = for_cell(scene, reference_spec(scene, H), run.t)
    assert ref.missing == "" and ref.trajectory is not None
    ev = evaluate(scene, run, ref, "fake", "euler")
    # Explicit Euler lags the exact drop by g T h / 2 = 0.049 m > 1e-3: a failure, named.
    err = ev.metrics["position_error_max"]["value"]
    assert err == pytest.approx(G * T * H / 2, rel=1e-9)
    assert ev.status == "fail" and ev.failing
    assert ev.reason == f"position_error_max = {err:.3g} > 0.001"
    assert ev.worst["metric"] == "position_error_max"
    assert "position_error_max" in ev.table()
    # The reference at the run's last time, for the end-state comparison in the report.
    assert ev.reference_end.t.tolist() == [T]
    np.testing.assert_allclose(ev.reference_end.com[0, 0, 2], 10.0 - G * T * T / 2, rtol=1e-12)
    assert set(ev.series) >= {"position_error", "energy_drift"}
    assert ev.note == "" and ev.blowup_time is None
    # The exact run passes the same limit.
    assert evaluate(scene, ExactEngine().run(scene, "exact", H), ref, "fake", "exact").status \
        == "pass"


def test_missing_reference_is_an_error_that_names_the_reason(scene):
    run = ExactEngine().run(scene, "exact", H)
    ev = evaluate(scene, run, Reference(missing="reference blew up: energy runaway"), "fake",
                  "exact")
    # Conservation metrics are still there; the limited reference metric is not, and says why.
    assert "energy_drift" in ev.metrics and "position_error_max" in ev.metrics
    assert ev.metrics["position_error_max"]["value"] is None
    assert ev.status == "error"
    assert ev.reason == ("metric(s) with a tolerance not computed: position_error_max "
                         "(reference blew up: energy runaway)")
    assert ev.note == "reference blew up: energy runaway" and ev.reference_end is None
    # No reference at all (None) is the same as an empty one.
    assert evaluate(scene, run, None, "fake", "exact").status == "error"


def test_failing_extra_metric_becomes_the_note_not_a_crash(scene):
    run = ExactEngine().run(scene, "exact", H)
    ref = for_cell(scene, reference_spec(scene, H), run.t)

    def broken(_scene, _traj):
        raise ValueError("no flip seen")

    ev = evaluate(scene, run, Reference(ref.trajectory, extra=broken), "fake", "exact")
    assert ev.status == "pass" and ev.note == "extra metrics failed: ValueError: no flip seen"
    ev = evaluate(scene, run, Reference(ref.trajectory, extra=lambda s, t: {"my_check": 0.5}),
                  "fake", "exact")
    assert ev.metrics["my_check"]["value"] == 0.5


def test_reference_for_a_cell_says_why_it_is_missing(scene, tmp_path):
    spec = {"kind": "fine-step", "engine": "inhouse", "integrator": "rk4", "dt": 1e-4}
    assert for_cell(scene, spec, np.zeros(1), error="worker crashed").missing == "worker crashed"
    assert for_cell(scene, spec, np.zeros(1)).missing == "reference unavailable"
    broken = for_cell(scene, spec, np.zeros(1), saved=str(tmp_path / "absent.npz"))
    assert broken.trajectory is None and broken.missing.startswith("reference failed: ")
    assert for_cell(scene, {"kind": "table", "table": "x"}, np.zeros(1)).missing \
        == "a rigid scene has no published table reference"
    assert for_cell(scene, None, np.zeros(1)) == Reference()
    # A saved reference is loaded as it was written.
    path = ExactEngine().run(scene, "exact", H).save(tmp_path / "ref.npz")
    assert len(for_cell(scene, spec, np.zeros(1), saved=str(path)).trajectory.t) == 21


def test_blowup_found_in_the_run(scene):
    run = BlowupEngine().run(scene, "exact", H)
    ev = evaluate(scene, run, None, "fake", "exact")
    assert ev.status == "blowup" and ev.blowup_time is not None
    assert ev.reason.startswith(f"blew up at t = {ev.blowup_time:.6g} s")


def test_fluid_record_judged_by_its_own_metrics(monkeypatch):
    scene = load_case(CASES / "fluid" / "tank_at_rest.toml")
    values = {"volume_change": 5e-4, "max_spurious_velocity": math.nan}
    from crosscheck.compare import fluid_metrics

    monkeypatch.setattr(fluid_metrics, "fluid_metrics", lambda s, r: dict(values))
    record = SimpleNamespace(t=np.array([0.0, 2.0]), failure=None, meta={})
    ev = evaluate(scene, record, None, "inhouse", "semi_lagrangian")
    # NaN fails its limit (JSON keeps its text); the finite one passes.
    assert ev.metrics["max_spurious_velocity"] == {"value": None, "value_text": "nan",
                                                   "limit": 1e-4, "passed": False}
    assert ev.metrics["volume_change"]["passed"] is True
    assert ev.status == "fail" and ev.series == {}
    record.failure = {"time": 0.75, "reason": "CFL exceeded"}
    ev = evaluate(scene, record, None, "inhouse", "semi_lagrangian")
    assert ev.status == "blowup" and ev.blowup_time == 0.75
    assert ev.reason == "blew up at t = 0.75 s: CFL exceeded"
