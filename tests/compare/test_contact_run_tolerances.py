"""Tolerance overrides keyed by an in-house contact run ("inhouse.rk4+penalty"): the loader accepts
them, the planner gives the cell that run name, and the verdict applies the override to that
model only (the contact cases' per-model limits, docs/cases.md "[tolerances]")."""

from __future__ import annotations

import pytest

from crosscheck.compare.verdict import judge
from crosscheck.errors import CaseError
from crosscheck.runner.plan import build_matrix
from crosscheck.scene.loader import load_case_text

CASE = """
[case]
name = "contact-run-tolerances"
dimension = 3
[run]
duration = 0.01
dt = 1e-3
engines = ["inhouse", "mujoco"]
integrators = {{ inhouse = ["symplectic_euler+soft_step", "rk4+penalty", "rk4+impulse_lcp"] }}
[effects]
gravity = [0.0, 0.0, -9.81]
contact = true
[ground]
[[bodies]]
name = "ball"
shape = {{ sphere = {{ radius = 0.1 }} }}
mass = 1.0
position = [0.0, 0.0, 0.1]
[tolerances]
m = {{ {limits} }}
"""

LIMITS = ('default = 1.0, inhouse = 2.0, rk4 = 3.0, "inhouse.rk4+penalty" = 4.0, '
          '"symplectic_euler+soft_step" = 5.0')


def _scene(limits: str = LIMITS):
    return load_case_text(CASE.format(limits=limits), name="contact-run-tolerances.toml")


def test_an_override_keyed_by_a_contact_run_applies_to_that_model_only():
    m = _scene().tolerances["m"]
    assert m.limit("inhouse", "rk4+penalty") == 4.0  # engine.run wins
    assert m.limit("inhouse", "symplectic_euler+soft_step") == 5.0  # the run name alone
    # A bare integrator key does not reach a contact run: the in-house run on a contact case is
    # named "integrator+model", so the engine's key (or the default) applies.
    assert m.limit("inhouse", "rk4+impulse_lcp") == 2.0
    assert m.limit("mujoco", "rk4") == 3.0
    assert m.limit("mujoco", "euler") == 1.0


@pytest.mark.parametrize("key", ['"inhouse.rk4+penalt"', '"inhouse.rk4+soft_step"',
                                 '"mujoco.rk4+penalty"', '"rk4+penalt"'])
def test_a_misspelt_or_unpaired_contact_run_key_is_refused(key):
    # a typo, a model with an integrator it does not pair with, a peer engine with a model
    with pytest.raises(CaseError) as info:
        _scene(f"default = 1.0, {key} = 2.0")
    assert info.value.field == f"tolerances.m.{key}"


def test_the_planner_names_the_cell_by_its_run_and_the_verdict_uses_the_runs_limit():
    scene = _scene()
    cells = build_matrix([scene], engines=["inhouse"], cost=False).cells
    assert [c["integrator"] for c in cells] == ["symplectic_euler+soft_step", "rk4+penalty",
                                                "rk4+impulse_lcp"]
    metrics = {"m": {"value": 3.5}}
    verdicts = {c["integrator"]: judge(scene, "inhouse", c["integrator"], metrics)
                for c in cells}
    assert verdicts["rk4+penalty"].status == "pass"  # 3.5 <= 4
    assert verdicts["rk4+penalty"].metrics["m"]["limit"] == 4.0
    assert verdicts["rk4+impulse_lcp"].status == "fail"  # 3.5 > the engine's 2
    assert verdicts["rk4+impulse_lcp"].metrics["m"]["limit"] == 2.0
    assert verdicts["symplectic_euler+soft_step"].status == "pass"  # 3.5 <= 5
