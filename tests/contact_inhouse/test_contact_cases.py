"""The committed analytic contact cases through the cell runner (as ``crosscheck run`` runs them),
for both velocity-level models: each passes its case's tolerances, and the metrics that the
formulation pins down tighter than the cases' cross-engine tolerances are checked against the
discrete answer itself (docs/inhouse.md, "Contact", what each model measures):

* sequential_impulse reflects the pre-kick velocity, so a bounce with e = 1 keeps its apex to
  the symplectic Euler flight's own error (measured 2e-5), rolling and sliding friction are
  exact Coulomb rows (rolling acceleration to round-off; the stop distance is the discrete
  v0^2 / (2 mu g) - v0 dt / 2 of a velocity-first integrator, CONTACTS.md 1.2);
* both models exchange velocities exactly in the billiard and the cradle (e = 1, one contact at
  a time);
* soft_step's soft contact rolls with a slip of a few mm/s (its relax pass removes the bias
  velocity but the sub-steps' soft push leaves the contact compliant).
"""

from __future__ import annotations

from pathlib import Path

import pytest

from crosscheck.runner.cell import execute_task

CASES = Path(__file__).resolve().parents[2] / "cases" / "contact"
ANALYTIC = ["bounce_elastic", "bounce_elastic_2d", "bounce_resting", "bounce_resting_2d",
            "slide_to_rest", "slide_to_rest_2d", "roll_incline", "roll_incline_2d",
            "roll_incline_plane", "roll_incline_slipping", "roll_incline_slipping_2d",
            "block_incline_static", "block_incline_static_2d", "block_incline_kinetic",
            "block_incline_kinetic_2d", "billiard", "billiard_2d", "newtons_cradle",
            "newtons_cradle_2d"]
MODELS = ("sequential_impulse", "soft_step")


def _cell(case: str, run: str) -> dict:
    """One cell as ``crosscheck run`` builds and runs it (analytic references need no task)."""
    from crosscheck.runner.plan import build_matrix
    from crosscheck.scene.loader import load_case

    matrix = build_matrix([load_case(CASES / f"{case}.toml")], engines=["inhouse"],
                          integrators=[run], cost=False)
    assert not matrix.references
    (task,) = matrix.cells
    return execute_task(task)


def _value(result: dict, metric: str) -> float:
    return result["metrics"][metric]["value"]


@pytest.mark.parametrize("model", MODELS)
@pytest.mark.parametrize("case", ANALYTIC)
def test_analytic_contact_case_passes(case, model):
    result = _cell(case, f"symplectic_euler+{model}")
    assert result["status"] == "pass", (result["status"], result.get("reason"))
    assert result["effective"]["contact"]["model"] == model
    if model == "sequential_impulse":
        if case.startswith("bounce_elastic"):
            assert _value(result, "apex_height_error_rel") < 1e-4
        if case.startswith("roll_incline"):
            assert _value(result, "rolling_acceleration_error_rel") < 1e-10
            assert _value(result, "slip_velocity_error") < 1e-10
        if case.startswith("slide_to_rest"):
            v0, dt, d = 2.0, 1e-3, 2.0 ** 2 / (2 * 0.3 * 9.81)
            assert abs(_value(result, "stop_distance_error_rel") - v0 * dt / 2 / d) < 1e-6
        if case.startswith("block_incline_static"):
            assert _value(result, "incline_drift") < 1e-9
    if case.startswith("billiard"):
        assert _value(result, "momentum_transfer_error") < 1e-12
    if case.startswith("newtons_cradle"):
        assert _value(result, "cradle_velocity_error") < 1e-12


@pytest.mark.parametrize("model", MODELS)
def test_the_exponential_rotation_update_runs_the_same_cases(model):
    for case in ("roll_incline", "slide_to_rest", "block_incline_kinetic"):
        result = _cell(case, f"symplectic_euler_exp+{model}")
        assert result["status"] == "pass", (case, result.get("reason"))
        assert result["effective"]["rotation_update"] == "exp"
