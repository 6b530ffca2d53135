"""Reproducibility (DESIGN principle 6): the same matrix run twice, with one worker and with two,
gives bit-identical trajectories for every engine, so a baseline difference is never noise."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[2]
CASES = ["cases/rigid3d/two_body_spring.toml", "cases/rigid2d/falling_box.toml"]


def _run(out: Path, workers: int) -> dict[str, dict[str, np.ndarray]]:
    # --no-cost: the saved trajectories come from the recorded pass; the cost pass re-runs each
    # cell unrecorded for its wall time only, and took two thirds of this test's time.
    proc = subprocess.run(
        [sys.executable, "-m", "crosscheck.cli", "run", *CASES, "--out", str(out),
         "--workers", str(workers), "--save-trajectories", "--no-cost", "--progress", "none",
         "--integrators", "inhouse.rk4,inhouse.symplectic_euler,mujoco.rk4,mujoco.euler,"
         "pybullet.multibody,pymunk.position_first"],
        cwd=ROOT, capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-2000:]
    files = sorted((out / "trajectories").rglob("*.npz"))
    assert files, "no trajectories were saved"
    runs = {}
    for f in files:
        with np.load(f) as data:
            runs[str(f.relative_to(out))] = {k: data[k] for k in data.files if k != "meta"}
    return runs


@pytest.mark.slow
def test_runs_are_bit_identical_across_repeats_and_worker_counts(tmp_path):
    one = _run(tmp_path / "one", workers=1)
    two = _run(tmp_path / "two", workers=2)
    assert set(one) == set(two)
    engines = {Path(name).name.split("-")[0] for name in one}
    assert engines == {"inhouse", "mujoco", "pybullet", "pymunk"}
    for name, arrays in one.items():
        for key, value in arrays.items():
            # Exact equality, not allclose: a tolerance here would hide a race or an
            # uninitialised buffer that a baseline comparison would then report as a regression.
            np.testing.assert_array_equal(value, two[name][key], err_msg=f"{name}:{key}")
