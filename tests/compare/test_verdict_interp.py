"""Verdict rules and the interpolation of references."""

from __future__ import annotations

import numpy as np
import pytest

from crosscheck.compare.interp import hermite, linear, resample, slerp
from crosscheck.compare.verdict import judge, metric_table
from crosscheck.rotations import axis_angle_to_quat, quat_angle_between
from crosscheck.scene.loader import load_case_text
from crosscheck.state import Trajectory

CASE = """
[case]
name = "v"
dimension = 3
[run]
duration = 1.0
dt = 0.01
[[bodies]]
name = "b"
shape = { sphere = { radius = 0.1 } }
mass = 1.0
position = [0, 0, 0]
[tolerances]
energy_drift = { default = 1e-2, rk4 = 1e-8, mujoco = 1e-3, "mujoco.euler" = 5e-2 }
position_error_max = 1e-3
"""


@pytest.fixture(scope="module")
def scene():
    return load_case_text(CASE)


def test_most_specific_limit_wins(scene):
    m = {"energy_drift": {"value": 2e-2}, "position_error_max": {"value": 0.0}}
    assert judge(scene, "mujoco", "euler", m).status == "pass"  # engine.integrator: 5e-2
    assert judge(scene, "mujoco", "rk4", m).metrics["energy_drift"]["limit"] == 1e-8
    v = judge(scene, "mujoco", "implicit", m)  # engine: 1e-3
    assert v.status == "fail" and v.metrics["energy_drift"]["limit"] == 1e-3
    assert "energy_drift = 0.02 > 0.001" in v.reason
    assert judge(scene, "pybullet", "multibody", m).metrics["energy_drift"]["limit"] == 1e-2


def test_value_equal_to_limit_passes_nan_fails(scene):
    assert judge(scene, "x", "y", {"energy_drift": {"value": 1e-2},
                                   "position_error_max": {"value": 1e-3}}).status == "pass"
    v = judge(scene, "x", "y", {"energy_drift": {"value": None, "value_text": "nan"},
                                "position_error_max": {"value": 0.0}})
    assert v.status == "fail"
    assert v.worst["metric"] == "energy_drift" and v.worst["ratio"] == float("inf")


def test_missing_metric_with_a_limit_is_an_error_with_the_reason(scene):
    v = judge(scene, "x", "y", {"energy_drift": {"value": 0.0}},
              missing_reason="reference run timeout")
    assert v.status == "error"
    assert "position_error_max" in v.reason and "reference run timeout" in v.reason


def test_a_metric_with_nothing_to_measure_fails_saying_why(scene):
    # A flip period of a run that never flips: physics, not a harness problem (error), and never
    # a pass; the reason says "not measured" and why, not a number.
    v = judge(scene, "x", "y", {"energy_drift": {"value": 0.0},
                                "position_error_max": {"value": None,
                                                       "not_measured": "no flip found"}})
    assert v.status == "fail"
    assert v.metrics["position_error_max"]["passed"] is False
    assert "position_error_max not measured: no flip found" in v.reason


def test_worst_metric_is_the_largest_ratio(scene):
    v = judge(scene, "x", "y", {"energy_drift": {"value": 5e-3},
                                "position_error_max": {"value": 9e-4}})
    assert v.worst["metric"] == "position_error_max" and v.worst["ratio"] == pytest.approx(0.9)
    table = metric_table(v.metrics)
    assert "position_error_max" in table and "0.0009" in table


def test_hermite_is_exact_for_cubics_and_linear_for_lines():
    t = np.linspace(0.0, 2.0, 7)
    x = t**3 - 2 * t
    v = 3 * t**2 - 2
    q = np.array([0.1, 0.77, 1.234, 1.999, 2.0])
    assert np.allclose(hermite(t, x, v, q), q**3 - 2 * q, atol=1e-13)
    assert np.allclose(linear(t, 4 * t + 1, q), 4 * q + 1, atol=1e-13)
    assert np.isnan(hermite(t, x, v, np.array([2.5]))).all()  # outside the span


def test_slerp_is_exact_for_rotation_about_a_fixed_axis():
    axis = np.array([1.0, 2.0, 2.0]) / 3.0
    t = np.linspace(0.0, 1.0, 6)
    quats = axis_angle_to_quat(np.tile(axis, (6, 1)), 2.5 * t)[:, None, :]  # (T, 1, 4)
    quats[3] *= -1  # sign-blind
    q = np.array([0.05, 0.5, 0.93])
    got = slerp(t, quats, q)
    want = axis_angle_to_quat(np.tile(axis, (3, 1)), 2.5 * q)[:, None, :]
    assert np.max(quat_angle_between(got, want)) < 1e-12


def test_resample_returns_the_samples_at_sample_times():
    t = np.linspace(0.0, 1.0, 11)
    traj = Trajectory(t=t, com=np.random.default_rng(1).normal(size=(11, 2, 3)),
                      vel=np.zeros((11, 2, 3)), omega=np.zeros((11, 2, 3)),
                      quat=np.tile([1.0, 0, 0, 0], (11, 2, 1)))
    assert resample(traj, t.copy()) is traj
    sub = resample(traj, t[::2] + 0.0)
    assert sub is traj or np.allclose(sub.com, traj.com[::2])
    mid = resample(traj, np.array([0.3]))
    assert np.allclose(mid.com[0], traj.com[3])


def test_expected_blowup_is_judged_by_its_time_alone():
    scene = load_case_text(CASE.replace("position_error_max = 1e-3",
                                        "position_error_max = 1e-3\n"
                                        "blowup_time = { euler = 0.5 }"))
    m = {"position_error_max": {"value": 37.0}, "blowup_time": {"value": 0.1}}
    v = judge(scene, "x", "euler", m, blowup_time=0.1, blowup_reason="non-finite state")
    assert v.status == "pass" and "as the case expects" in v.reason
    assert v.metrics["position_error_max"]["passed"] is None  # not judged after a blow-up
    v = judge(scene, "x", "euler", dict(m, blowup_time={"value": 0.7}), blowup_time=0.7)
    assert v.status == "fail" and "later than the case expects" in v.reason
    v = judge(scene, "x", "euler", {"position_error_max": {"value": 0.0}})
    assert v.status == "fail" and "stayed bounded" in v.reason
    # Integrators without a blowup_time limit keep the ordinary rules: a blow-up is a blow-up.
    assert judge(scene, "x", "rk4", m, blowup_time=0.1).status == "blowup"
