"""References with real engines: SciPy DOP853 on the independent Newton-Euler equations
(crosscheck.reference.newton_euler), a fine-step run, another engine, and the interpolation of a
reference sampled at other times.

The case is the tennis racket (torque-free box, I = 0.808, 0.683, 0.142 kg m^2, spin 5 rad/s
about the intermediate axis) cut to 3 s, before its first flip, where RK4's error is smooth.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

from crosscheck.compare.interp import resample, slerp
from crosscheck.compare.metrics import compute_metrics
from crosscheck.engines import get_engine
from crosscheck.reference.simulated import dop853_reference
from crosscheck.reference.spec import reference_spec
from crosscheck.rotations import quat_angle_between
from crosscheck.runner.cell import execute_task
from crosscheck.runner.plan import build_matrix
from crosscheck.scene.loader import load_case, load_case_text

CASES = Path(__file__).resolve().parents[2] / "cases"


@pytest.fixture(scope="module")
def racket_text():
    text = (CASES / "rigid3d" / "tennis_racket.toml").read_text()
    return text.replace("duration = 20.0", "duration = 3.0")


@pytest.fixture(scope="module")
def racket(racket_text):
    return load_case_text(racket_text)


@pytest.fixture(scope="module")
def dop853(racket):
    return dop853_reference(racket)


def orientation_error(scene, traj, ref):
    return compute_metrics(scene, traj, ref).metrics["orientation_error_max"].value


def test_dop853_conserves_and_rk4_converges_to_it_at_fourth_order(racket, dop853):
    ms = compute_metrics(racket, dop853)
    # rtol 1e-12 per step over ~1000 steps: energy and angular momentum to ~1e-11.
    assert ms.metrics["energy_drift"].value < 1e-10
    assert ms.metrics["angular_momentum_drift"].value < 1e-10
    inhouse = get_engine("inhouse")
    e2 = orientation_error(racket, inhouse.run(racket, "rk4", 2e-3), dop853)
    e1 = orientation_error(racket, inhouse.run(racket, "rk4", 1e-3), dop853)
    # Halving the step divides a fourth-order error by 2^4 = 16 (measured 15.4); the reference
    # is far more accurate than either run (else the ratio would collapse towards 1).
    assert 1e-10 < e1 < e2 < 1e-7
    assert 12 < e2 / e1 < 20
    # MuJoCo's RK4 on the same equations agrees with the reference at the same level.
    mj = orientation_error(racket, get_engine("mujoco").run(racket, "rk4", 1e-3), dop853)
    assert mj < 1e-9


def test_reference_resampling_on_the_rotation_group(racket_text):
    # The same RK4 run (dt = 1e-4, far below its error scale here) sampled every 0.01 s and
    # every 0.002 s: the coarse one resampled at the fine times must reproduce it.
    inhouse = get_engine("inhouse")
    coarse = inhouse.run(load_case_text(racket_text), "rk4", 1e-4)
    fine = inhouse.run(load_case_text(racket_text.replace("sample_every = 0.01",
                                                          "sample_every = 0.002")), "rk4", 1e-4)
    at = resample(coarse, fine.t)
    # Hermite on SO(3) with the angular velocities as slopes: error O(h^4) ~ (w h)^4 / 384.
    assert np.nanmax(quat_angle_between(at.quat, fine.quat)) < 1e-7
    # Plain slerp misses the nutation between samples by orders of magnitude more.
    q = slerp(coarse.t, coarse.quat, fine.t)
    assert np.nanmax(quat_angle_between(q, fine.quat)) > 1e-4
    assert np.nanmax(np.abs(at.com - fine.com)) < 1e-12  # the centre of mass stays at rest


def _run_case_through_tasks(path, tmp_path, engine, integrator):
    scene = load_case(path)
    matrix = build_matrix([scene], out=tmp_path)
    ref_task = matrix.references[0]
    ref = execute_task(ref_task)
    assert ref["status"] == "ok", ref.get("reason")
    cell = next(t for t in matrix.cells if t["engine"] == engine
                and t["integrator"] == integrator)
    cell["reference_file"] = ref["path"]
    return execute_task(cell)


def test_dop853_and_engine_references_through_the_runner_tasks(racket_text, tmp_path):
    text = racket_text.replace('kind = "analytic"\nsolution = "torque_free_intermediate"',
                               'kind = "fine-step"\nintegrator = "dop853"')
    text = text.replace("flip_period_error", "orientation_error_max")
    path = tmp_path / "racket_dop853.toml"
    path.write_text(text)
    assert reference_spec(load_case(path), 1e-3)["kind"] == "dop853"
    result = _run_case_through_tasks(path, tmp_path, "mujoco", "rk4")
    assert result["status"] == "pass", result.get("reason")
    assert result["metrics"]["orientation_error_max"]["value"] < 1e-9

    text = racket_text.replace('kind = "analytic"\nsolution = "torque_free_intermediate"',
                               'kind = "engine"\nengine = "inhouse"\nintegrator = "rk4"')
    text = re.sub(r"flip_period_error = .*", "orientation_error_max = 1e-6", text)
    path = tmp_path / "racket_engine.toml"
    path.write_text(text)
    # MuJoCo Euler against in-house RK4 at the same step: Euler's first-order error, 2e-2 rad
    # after 3 s (its energy gain changes the spin), must show up and fail the RK4-sized limit.
    result = _run_case_through_tasks(path, tmp_path, "mujoco", "euler")
    assert result["status"] == "fail"
    assert 1e-3 < result["metrics"]["orientation_error_max"]["value"] < 1.0
