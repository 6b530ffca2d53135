"""Printed tables fill every column or say why a value is absent: `crosscheck run`'s end-state
table (the tennis racket's analytic reference has no orientation) and the sweep table."""

from __future__ import annotations

import math

from crosscheck.commands._end_table import end_state_table
from crosscheck.study.sweep import analyse, table

NAN = None  # how results carry a quantity the reference lacks (JSON has no NaN)


def end(t=20.0, rot=(1.0, 0.0, 0.0, 0.0), com=(0.0, 0.0, 0.0)):
    return {"t": t, "com": [list(com)], "rot": [list(rot)], "vel": [[0.0, 0.0, 0.0]],
            "omega": [[0.0, 5.0, 0.0]], "rot_kind": "quat"}


def racket(integrator, angle, ratio, engine="inhouse", status="pass"):
    half = angle / 2
    return {"case": "tennis-racket", "engine": engine, "integrator": integrator, "dt": 0.001,
            "status": status, "worst": {"ratio": ratio},
            "end_state": end(rot=(math.cos(half), 0.0, 0.0, math.sin(half))),
            "reference_end": end(rot=(NAN, NAN, NAN, NAN))}


def rows(text):
    return [line.split() for line in text.splitlines()]


def test_a_reference_without_orientation_is_filled_from_the_most_accurate_run():
    cells = [racket("rk4", 0.0, 0.002), racket("midpoint", 0.0161, 0.5),
             racket("euler", 1.01, 0.9, engine="mujoco"),
             {"case": "tennis-racket", "engine": "pymunk", "integrator": "default",
              "dt": 0.001, "status": "not_applicable", "reason": "3D scene"}]
    text = end_state_table(cells)
    table_rows = {r[1]: r for r in rows(text)[1:5]}
    assert table_rows["inhouse-midpoint"][-2] == "0.0161*"  # against inhouse-rk4
    assert table_rows["mujoco-euler"][-2] == "1.01*"
    assert table_rows["inhouse-rk4"][-2] == "0.0161*"  # the best run against the next best
    assert "* tennis-racket: the reference has no orientation at the end; compared with " \
        "inhouse-rk4 instead" in text
    na = next(line for line in text.splitlines() if "pymunk-default" in line)
    assert "no end state: not applicable" in na and na.split()[-3:] == ["-", "-", "-"]
    for line in text.splitlines()[1:5]:
        assert len(line.split()) >= 9, line  # no empty column


def test_without_reference_the_base_row_says_so():
    a = {"case": "c", "engine": "inhouse", "integrator": "rk4", "dt": 0.01, "status": "pass",
         "end_state": end(t=1.0)}
    b = dict(a, integrator="euler", end_state=end(t=1.0, com=(0.003, 0.0, 0.0)))
    fluid = {"case": "f", "engine": "inhouse", "integrator": "semi_lagrangian", "dt": 0.01,
             "status": "pass", "fluid": True}
    text = end_state_table([a, b, fluid])
    lines = text.splitlines()
    # Rows sorted by engine and integrator: euler is the base the others are compared with.
    assert "(the base of this case's rows)" in lines[1] and lines[1].split()[-3:] == \
        ["-", "-", "-"]
    assert lines[2].split()[-4:] == ["inhouse-euler", "0.003", "0", "0"]
    assert "a fluid run: no bodies" in lines[3]


def test_sweep_table_fills_not_applicable_rows():
    cells = [{"case": "c", "engine": "inhouse", "integrator": "rk4", "dt": dt, "status": "pass",
              "cost": 1e-4, "metrics": {"position_error_max": {"value": dt ** 4}}}
             for dt in (0.01, 0.005)]
    cells.append({"case": "c", "engine": "pymunk", "integrator": "default", "dt": 0.01,
                  "status": "not_applicable", "reason": "3D scene"})
    metric, series = analyse(cells, None, [0.01, 0.005])
    text = table(metric, series)
    row = next(line for line in text.splitlines() if line.startswith("| pymunk-default"))
    fields = [f.strip() for f in row.strip().strip("|").split("|")]
    assert all(fields) and "not applicable: 3D scene" in fields[-1]


def test_a_coupled_body_has_an_end_state_a_plot_and_a_trajectory(tmp_path):
    # The floating box, 0.1 s of it: the runner's fluid cell carries the body's end state (the
    # driver's normalised Trajectory of it), the body plot and the saved body trajectory; the
    # end-state table shows it instead of "no bodies"; the result is JSON (results.json).
    import json
    from pathlib import Path

    import numpy as np

    from crosscheck.runner.cell import execute_task
    from crosscheck.state import Trajectory

    src = Path(__file__).resolve().parents[2] / "cases" / "fluid" / "floating_box.toml"
    case = tmp_path / "floating_box.toml"
    case.write_text(src.read_text().replace("duration = 3.0", "duration = 0.1"))
    task = {"kind": "cell", "id": "fb", "case": "fluid-floating-box", "case_file": str(case),
            "engine": "inhouse", "integrator": "semi_lagrangian", "dt": 0.005, "cost": False,
            "out": str(tmp_path / "out"), "save_trajectories": True}
    cell = execute_task(task)
    assert cell["fluid"] is True and cell["bodies"] == ["box"], cell.get("reason")
    end = cell["end_state"]
    assert abs(end["t"] - 0.1) < 1e-9 and end["rot_kind"] == "angle"
    assert abs(end["com"][0][0] - 1.0) < 1e-3 and 0.2 < end["com"][0][1] < 0.26
    assert end["vel"][0][1] < 0.0  # released above its draft: it sinks at first
    from crosscheck.report.fluid_plots import embedded

    # the floating body has no validation plot: the report's page shows the body's
    assert embedded(cell["plots"]).endswith("-body.png")
    body = Trajectory.load(cell["body_trajectory_file"])
    assert body.com.shape == (cell["samples"], 1, 2) and body.angle.shape == (cell["samples"], 1)
    assert body.meta["masses"] == [0.2 * 0.1 * 500.0] and body.meta["coupled_with_fluid"]
    assert np.allclose(body.com[-1, 0], end["com"][0])
    json.dumps(cell)
    text = end_state_table([cell])
    row = text.splitlines()[1]
    assert "no bodies" not in text and "(the base of this case's rows)" in row \
        and "0.1" in row.split()  # t_end printed to 4 digits
