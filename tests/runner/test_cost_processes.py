"""A cell's cost pass spread over several worker tasks and pooled (issue 13 point 6)."""

from __future__ import annotations

import json
import math

import pytest

from crosscheck.cli import main

SPINNER = """
[case]
name = "cost-spread"
dimension = 3
[run]
duration = 0.2
dt = 1e-3
engines = ["inhouse"]
integrators = { inhouse = ["rk4", "explicit_euler"] }
[[bodies]]
name = "b"
shape = { box = { size = [0.3, 0.2, 0.1] } }
mass = 1.0
position = [0.0, 0.0, 1.0]
angular_velocity = [1.0, 2.0, 3.0]
"""


@pytest.mark.parametrize("processes", [1, 3])
def test_each_cell_pools_the_cost_of_the_processes_it_asked_for(tmp_path, processes):
    case = tmp_path / "case.toml"
    case.write_text(SPINNER)
    out = tmp_path / "out"
    status = main(["run", str(case), "--out", str(out), "--workers", "2", "--progress", "none",
                   "--cost-processes", str(processes), "--cost-seconds", "0.01"])
    assert status == 0
    doc = json.loads((out / "results.json").read_text())
    assert len(doc["cells"]) == 2  # the extra cost tasks are no cells of their own
    for cell in doc["cells"]:
        detail = cell["cost_detail"]
        assert detail["processes"] == processes
        assert detail["repeats"] == len(detail["wall_samples"]) >= 3 * processes
        # cost: the geometric mean over the passes of each pass's fastest repetition
        minima = detail.get("process_minima") or [min(detail["wall_samples"])]
        assert cell["cost"] == pytest.approx(math.prod(minima) ** (1 / len(minima)) / 0.2)
        assert cell["cost_spread"] == detail["spread"] > 0
        assert cell["cost_median_spread"] == detail["spread_median"] > 0
        if processes > 1:
            assert len(detail["process_medians"]) == processes
            assert sum(detail["process_repeats"]) == detail["repeats"]
            # each pass in a process of its own (the local backend's cost rounds)
            assert len(set(detail["process_pids"])) == processes
            assert detail["spread_model"]["processes"] == processes
    journal = [json.loads(x) for x in (out / "cells.jsonl").read_text().splitlines()]
    assert sum(r.get("kind") == "cost" for r in journal) == 2 * (processes - 1)
    # a worker is started afresh once per cost round at most (two workers)
    assert processes - 1 <= doc["resources"]["workers_started_for_cost"] <= 2 * (processes - 1)


def test_cost_processes_must_be_positive(tmp_path, capsys):
    case = tmp_path / "case.toml"
    case.write_text(SPINNER)
    assert main(["run", str(case), "--out", str(tmp_path / "o"), "--cost-processes", "0"]) == 2
    assert "--cost-processes: expected a positive integer" in capsys.readouterr().err
