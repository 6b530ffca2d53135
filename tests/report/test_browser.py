"""The report in a real browser: index.html of a small fake run (a pass, a failure, a
regression against a baseline, a blow-up, a not-applicable engine) and a sweep page, loaded in
headless Chromium. Each page loads without a console error, the overview matrix has a cell
for every case and engine-integrator, and every image decodes (naturalWidth > 0). Screenshots
of the top of each page are written beside it for the person reviewing a change."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent / "runner"))
sys.path.insert(0, str(HERE))
from browser import chromium, open_page  # noqa: E402
from crosscheck_fakes import ALL  # noqa: E402

from crosscheck.report import sweep_page  # noqa: E402
from crosscheck.runner.local import LocalBackend  # noqa: E402
from crosscheck.runner.plan import build_matrix  # noqa: E402
from crosscheck.runner.session import run_and_report  # noqa: E402
from crosscheck.scene.loader import load_case  # noqa: E402
from crosscheck.study.sweep import Series, analyse, figure, table  # noqa: E402

CASE = """
[case]
name = "{name}"
description = "free fall of a spinning ball"
dimension = 3
[run]
duration = 0.5
dt = 0.01
sample_every = 0.05
engines = ["inhouse", "mujoco", "pybullet"]
integrators = {{ inhouse = ["exact", "euler", "fast_spin"], pybullet = ["exact"] }}
[effects]
gravity = [0, 0, -9.81]
[[bodies]]
name = "ball"
shape = {{ sphere = {{ radius = 0.1 }} }}
mass = 2.0
position = [0, 0, 10]
angular_velocity = [0, 0, 2.0]
[reference]
kind = "fine-step"
engine = "inhouse"
integrator = "exact"
dt = 0.001
[tolerances]
position_error_max = {{ default = 1e-9, euler = 0.05 }}
orientation_error_max = 1e-6
"""


@pytest.fixture(scope="module")
def browser():
    executable = chromium()
    from playwright.sync_api import sync_playwright

    with sync_playwright() as p:
        # --no-sandbox: CI and the developers' machines run as root, where Chromium's sandbox
        # refuses to start.
        b = p.chromium.launch(executable_path=executable, args=["--no-sandbox"])
        yield b
        b.close()


@pytest.fixture(scope="module")
def report(tmp_path_factory):
    folder = tmp_path_factory.mktemp("browser")
    er = {"inhouse": ALL["exact"], "mujoco": ALL["missing"], "pybullet": ALL["blowup"]}
    scenes = []
    for name in ("alpha", "beta"):
        path = folder / f"{name}.toml"
        path.write_text(CASE.format(name=name))
        scenes.append(load_case(path, unchecked_engines=er))
    # A baseline in which alpha's Euler run was twice as accurate and made with another
    # version of the in-house engine: a regression and an engine-version note.
    baseline = {"created": "2026-01-01T00:00:00+00:00", "crosscheck_version": "0.0.9",
                "source": {"commit": "0123456789abcdef", "engines": {"inhouse": "fake-0.9"}},
                "entries": {"alpha::inhouse-euler@dt=0.01": {
                    "status": "pass", "metrics": {"position_error_max": 0.012}}}}
    out = folder / "out"
    # Two timed repetitions and no minimum time: a cost figure to draw, a short test.
    matrix = build_matrix(scenes, out=out, engine_refs=er,
                          cost={"min_repeats": 2, "min_seconds": 0.0})
    outcome = run_and_report(matrix, LocalBackend(1), out, baseline=baseline,
                             baseline_file="baseline.json")
    return out, outcome


def test_index_html_in_chromium(browser, report):
    out, outcome = report
    check = open_page(browser, out / "index.html", screenshot=out / "screenshot.png")
    assert check.errors == []
    assert check.title == "crosscheck FAILED"
    expected = {case: sorted(f"{c['engine']}-{c['integrator']}" for c in outcome.cells
                             if c["case"] == case) for case in ("alpha", "beta")}
    assert {case: sorted(runs) for case, runs in check.matrix.items()} == expected
    assert len(expected["alpha"]) == 5  # exact, euler, fast_spin, mujoco n/a, pybullet blow-up
    # Every image decodes: two figures per case (over time, accuracy against cost).
    assert len(check.images) == 4
    assert all(i["complete"] and i["naturalWidth"] > 0 for i in check.images), check.images
    assert (out / "screenshot.png").read_bytes()[:4] == b"\x89PNG"


def _series() -> list[Series]:
    """Two integrators of orders 1 and 4 over four steps, one with a stability bracket."""
    cells = []
    for integrator, order, unstable_above in (("euler", 1, 0.02), ("rk4", 4, None)):
        for dt in (0.04, 0.02, 0.01, 0.005):
            blew = unstable_above is not None and dt > unstable_above
            cells.append({"case": "c", "engine": "inhouse", "integrator": integrator, "dt": dt,
                          "status": "blowup" if blew else "pass", "cost": 1e-4 / dt,
                          "metrics": {"position_error_max": {"value": None if blew else
                                                             3.0 * dt ** order}}})
    return analyse(cells, "position_error_max", [0.04, 0.02, 0.01, 0.005])[1]


def test_sweep_page_in_chromium(browser, tmp_path):
    chromium()
    series = _series()
    png = figure("c", "position_error_max", series, target=1e-4)
    page = sweep_page.write(tmp_path, "c", "# Sweep of c\n\n" + table(
        "position_error_max", series, 1e-4) + "\n", png)
    check = open_page(browser, page, screenshot=tmp_path / "screenshot.png")
    assert check.errors == []
    assert len(check.images) == 1
    assert check.images[0]["complete"] and check.images[0]["naturalWidth"] > 0
