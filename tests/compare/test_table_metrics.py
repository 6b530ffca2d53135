"""A run against a table: the case's own CSV (rigid and fluid), Ghia et al. at the case's
Reynolds number, and the rule that a cell which measured nothing never passes (issue 13 point 2).
"""

from __future__ import annotations

import math
import sys
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from crosscheck.compare.evaluate import evaluate
from crosscheck.compare.fluid_metrics import cavity_centrelines, fluid_metrics
from crosscheck.compare.verdict import judge
from crosscheck.reference.fluid_data import load_table
from crosscheck.reference.spec import for_cell, reference_spec
from crosscheck.scene.loader import load_case, load_case_text

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "runner"))
from crosscheck_fakes import ExactEngine  # noqa: E402

CASES = Path(__file__).resolve().parents[2] / "cases"
G, H = 9.81, 0.01

FALL = f"""
[case]
name = "fall"
dimension = 3
[run]
duration = 1.0
dt = {H}
sample_every = 0.05
engines = ["inhouse"]
[effects]
gravity = [0, 0, -{G}]
[[bodies]]
name = "ball"
shape = {{ sphere = {{ radius = 0.1 }} }}
mass = 2.0
position = [0, 0, 10]
[reference]
kind = "table"
file = "drop.csv"
[tolerances]
table_com_z_error_max = 1e-3
"""
# z = 10 - g t^2 / 2, v = -g t, written as a user would (rounded to the printed digits)
DROP = "t,com_z,vel_z\n0.0,10.0,0.0\n0.5,8.77375,-4.905\n1.0,5.095,-9.81\n"


@pytest.fixture
def fall(tmp_path):
    (tmp_path / "drop.csv").write_text(DROP)
    return load_case_text(FALL, "fall.toml", tmp_path)


def _evaluate(scene, integrator):
    run = ExactEngine().run(scene, integrator, H)
    ref = for_cell(scene, reference_spec(scene, H), run.t)
    assert ref.missing == ""
    return evaluate(scene, run, ref, "fake", integrator)


def test_rigid_run_against_the_cases_own_table(fall):
    ev = _evaluate(fall, "exact")
    assert ev.status == "pass", ev.reason
    assert ev.metrics["table_com_z_error_max"]["value"] < 1e-9
    assert ev.metrics["table_vel_z_error_rms"]["value"] < 1e-9
    # explicit Euler lags the drop by g t h / 2 at the table's points t = 0, 0.5, 1
    ev = _evaluate(fall, "euler")
    lag = G * np.array([0.0, 0.5, 1.0]) * H / 2
    assert ev.metrics["table_com_z_error_max"]["value"] == pytest.approx(lag.max(), rel=1e-9)
    assert ev.metrics["table_com_z_error_rms"]["value"] == pytest.approx(
        np.sqrt(np.mean(lag**2)), rel=1e-9)
    assert ev.status == "fail" and "table_com_z_error_max" in ev.reason


def _record(t, series=None, u=None, v=None):
    return SimpleNamespace(t=np.asarray(t, float), series=series or {}, failure=None,
                           fields={"u": [u], "v": [v]}, field_t=np.array([t[-1]]))


CAVITY = """
[case]
name = "cavity"
dimension = 2
[run]
duration = 1.0
dt = 0.01
engines = ["inhouse"]
[fluid]
domain = [1.0, 1.0]
resolution = [16, 16]
density = 1.0
kinematic_viscosity = {nu}
lid = {{ side = "top", speed = 1.0 }}
output = {{ fields = ["u", "v"] }}
[reference]
kind = "{kind}"
{ref}
"""


def test_fluid_profile_and_series_against_the_cases_own_tables(tmp_path):
    n = 16
    dx = 1.0 / n
    u = np.tile((np.arange(n) + 0.5) * dx, (n + 1, 1))  # u = y on every x-face
    v = np.zeros((n, n + 1))
    (tmp_path / "p.csv").write_text("y,u,v\n0.25,0.25,0.0\n0.75,0.80,0.0\n")
    scene = load_case_text(CAVITY.format(nu=0.01, kind="table", ref='file = "p.csv"\nx = 0.3'),
                           "c.toml", tmp_path)
    m = fluid_metrics(scene, _record([0.0, 1.0], u=u, v=v))
    assert m["table_u_error_max"] == pytest.approx(0.05, abs=1e-12)
    assert m["table_u_error_rms"] == pytest.approx(0.05 / math.sqrt(2), abs=1e-12)
    assert m["table_v_error_max"] == 0.0
    # a series: linear in t between the run's samples, at the table's times
    (tmp_path / "s.csv").write_text("t,kinetic_energy\n0.25,0.6\n0.5,1.0\n")
    scene = load_case_text(CAVITY.format(nu=0.01, kind="table", ref='file = "s.csv"'),
                           "c.toml", tmp_path)
    rec = _record([0.0, 1.0], series={"kinetic_energy": np.array([0.0, 2.0])}, u=u, v=v)
    m = fluid_metrics(scene, rec)
    assert m["table_kinetic_energy_error_max"] == pytest.approx(0.1)
    # a run that stopped before the table's last time fails every limit on that column
    short = _record([0.0, 0.4], series={"kinetic_energy": np.array([0.0, 0.8])}, u=u, v=v)
    assert fluid_metrics(scene, short)["table_kinetic_energy_error_max"] == math.inf


def _zero_record(n=16):
    return _record([0.0, 1.0], u=np.zeros((n + 1, n)), v=np.zeros((n, n + 1)))


def _interior_rms(table, coord, comp, profile=None):
    """RMS of run - table at the table's interior points for a run whose centreline is
    ``profile`` (positions, values); None: a fluid at rest."""
    inside = (table[coord] > 0) & (table[coord] < 1)
    run = 0.0 if profile is None else np.interp(table[coord][inside], *profile)
    return float(np.sqrt(np.mean((run - table[comp][inside]) ** 2)))


@pytest.mark.parametrize("re", [400, 1000])
def test_ghia_table_is_chosen_by_the_cases_reynolds_number(re):
    scene = load_case_text(CAVITY.format(nu=1.0 / re, kind="table", ref='table = "ghia_1982"'))
    m = cavity_centrelines(scene, _zero_record(), scene.reference.table)
    # a fluid at rest under a moving lid: u rises from 0 at the last cell centre to 1 at the lid
    lid = ([0.0, 1 - 0.5 / 16, 1.0], [0.0, 0.0, 1.0])
    tu, tv = load_table(f"ghia_1982_re{re}_u"), load_table(f"ghia_1982_re{re}_v")
    assert m["u_centreline_rms"] == pytest.approx(_interior_rms(tu, "y", "u", lid), rel=1e-12)
    assert m["v_centreline_rms"] == pytest.approx(_interior_rms(tv, "x", "v"), rel=1e-12)
    other = load_table("ghia_1982_re100_u")
    assert abs(m["u_centreline_rms"] - _interior_rms(other, "y", "u", lid)) > 0.01


def test_re100_case_metrics_unchanged():
    """The shipped Re = 100 case reads the same 17 + 17 numbers as before this change, so its
    metrics are those it always had (values of the previous data file, Ghia Table I / II)."""
    scene = load_case(CASES / "fluid" / "lid_driven_cavity.toml")
    n = scene.fluid.resolution[0]
    m = cavity_centrelines(scene, _zero_record(n), scene.reference.table)
    # at rest, u is 0 up to the last cell centre and rises linearly to the lid from there
    y_top = 1 - 0.5 / n
    u100 = [0.84123, 0.78871, 0.73722, 0.68717, 0.23151, 0.00332, -0.13641, -0.20581, -0.21090,
            -0.15662, -0.10150, -0.06434, -0.04775, -0.04192, -0.03717]
    v100 = [-0.05906, -0.07391, -0.08864, -0.10313, -0.16914, -0.22445, -0.24533, 0.05454,
            0.17527, 0.17507, 0.16077, 0.12317, 0.10890, 0.10091, 0.09233]
    y100 = [0.9766, 0.9688, 0.9609, 0.9531] + [0.0] * 11
    run = [max(0.0, (y - y_top) / (1 - y_top)) for y in y100]
    assert m["u_centreline_rms"] == pytest.approx(
        float(np.sqrt(np.mean(np.square(np.subtract(run, u100))))), rel=1e-12)
    assert m["v_centreline_rms"] == float(np.sqrt(np.mean(np.square(v100))))


# -- a cell that measured nothing ---------------------------------------------------------------
def test_a_cell_with_no_metric_fails():
    scene = load_case_text(CAVITY.format(nu=0.01, kind="none", ref=""))
    v = judge(scene, "inhouse", "maccormack", {})
    assert v.status == "fail" and v.reason.startswith("no metric could be measured")
    # the same through evaluate: an enclosed cavity without a table measures nothing
    ev = evaluate(scene, _zero_record(), None, "inhouse", "maccormack")
    assert ev.status == "fail" and "no metric could be measured" in ev.reason
    # metrics that exist but hold no value count as nothing measured, with the reason given
    v = judge(scene, "inhouse", "maccormack", {"x": {"value": None}}, missing_reason="why")
    assert v.status == "fail" and v.reason == "no metric could be measured: why"


def test_a_limited_metric_without_value_never_passes(fall):
    # (tolerances of the fall case: table_com_z_error_max <= 1e-3)
    for metrics in ({"energy_drift": {"value": 0.0}},
                    {"energy_drift": {"value": 0.0}, "table_com_z_error_max": {"value": None}}):
        v = judge(fall, "fake", "exact", metrics, missing_reason="the table was not read")
        assert v.status == "error", v
        assert "table_com_z_error_max" in v.reason and "the table was not read" in v.reason
    v = judge(fall, "fake", "exact", {"table_com_z_error_max": {"value": None,
                                                                "value_text": "nan"}})
    assert v.status == "fail"
