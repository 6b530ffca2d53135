"""A run that checked nothing does not pass (issue 13 point 3)."""

from __future__ import annotations

import json

from crosscheck.cli import main

ONLY_PYMUNK_3D = """
[case]
name = "pymunk-cannot"
dimension = 3
[run]
duration = 0.1
dt = 1e-3
engines = ["pymunk"]
[[bodies]]
name = "b"
shape = { sphere = { radius = 0.1 } }
mass = 1.0
position = [0.0, 0.0, 1.0]
"""


def test_a_run_whose_every_cell_is_not_applicable_fails_and_says_so(tmp_path, capsys):
    case = tmp_path / "case.toml"
    case.write_text(ONLY_PYMUNK_3D)
    out = tmp_path / "out"
    status = main(["run", str(case), "--out", str(out), "--workers", "1", "--progress", "none"])
    err = capsys.readouterr().err
    assert status == 1
    assert f"{case}: nothing to run: pymunk-position_first: pymunk is 2D" in err
    doc = json.loads((out / "results.json").read_text())
    assert doc["exit_status"] == 1 and "nothing was checked" in doc["checked_nothing"]
    assert "FAILED: every cell was not applicable" in (out / "summary.md").read_text()


def test_one_runnable_cell_is_enough(tmp_path, capsys):
    case = tmp_path / "case.toml"
    # (spinning, so the in-house cell measures something: a cell that measures nothing fails)
    case.write_text(ONLY_PYMUNK_3D.replace('engines = ["pymunk"]',
                                           'engines = ["pymunk", "inhouse"]')
                    + "angular_velocity = [0.0, 0.0, 1.0]\n")
    out = tmp_path / "out"
    status = main(["run", str(case), "--out", str(out), "--workers", "1", "--progress", "none",
                   "--no-cost"])
    assert status == 0
    assert "nothing to run" not in capsys.readouterr().err
    assert "checked_nothing" not in json.loads((out / "results.json").read_text())


def test_a_run_that_would_outlast_its_timeout_says_so_before_it_starts(tmp_path, capsys):
    # 2e8 MuJoCo steps at ~1 us each take ~200 s (still 60 s on a machine three times faster);
    # a 5 s timeout cannot hold them. The cell is a
    # timeout with the prediction, said after timing the first 200 steps: the worker is not
    # left to run until it is killed at the deadline.
    case = tmp_path / "case.toml"
    case.write_text(ONLY_PYMUNK_3D.replace('engines = ["pymunk"]', 'engines = ["mujoco"]\n'
                                           'sample_every = 1.0\ntimeout = 5.0')
                    .replace("duration = 0.1", "duration = 20000.0").replace("dt = 1e-3",
                                                                              "dt = 1e-4"))
    out = tmp_path / "out"
    status = main(["run", str(case), "--out", str(out), "--workers", "1", "--progress", "none",
                   "--no-cost"])
    assert status == 1
    (cell,) = json.loads((out / "results.json").read_text())["cells"]
    assert cell["status"] == "timeout"
    assert "200000000 steps would take about" in cell["reason"]
    assert "not started" in cell["reason"]
