"""The runner: one cell's crash, hang, exception or blow-up is that cell's result, never a lost
run; the matrix, shared references, exit statuses, interruption and Dask.

Fake adapters (crosscheck_fakes.py) stand in for engines through ``engine_refs``; the exact and
explicit-Euler free fall give known metric values, so a result that reached the report through
the worker processes can be checked, not just found.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import psutil
import pytest
from crosscheck_fakes import ALL

from crosscheck.runner.local import LocalBackend
from crosscheck.runner.plan import UsageError, build_matrix
from crosscheck.runner.session import run_and_report
from crosscheck.scene import loader
from crosscheck.state import Trajectory

HERE = Path(__file__).resolve().parent
G = 9.81

FALL = """
[case]
name = "{name}"
dimension = 3
[run]
duration = 1.0
dt = 0.01
sample_every = 0.05
engines = {engines}
integrators = {integrators}
timeout = {timeout}
[effects]
gravity = [0, 0, -9.81]
[[bodies]]
name = "ball"
shape = {{ sphere = {{ radius = 0.1 }} }}
mass = 2.0
position = [0, 0, 10]
[reference]
{reference}
[tolerances]
{tolerances}
"""


def write_case(folder: Path, name: str, engines='["inhouse"]',
               integrators='{ inhouse = ["exact", "euler"] }', timeout=600,
               reference='kind = "fine-step"\nengine = "inhouse"\nintegrator = "exact"\n'
                         'dt = 0.001',
               tolerances="position_error_max = { default = 1e-9, euler = 0.05 }") -> Path:
    path = folder / f"{name}.toml"
    path.write_text(FALL.format(name=name, engines=engines, integrators=integrators,
                                timeout=timeout, reference=reference, tolerances=tolerances))
    return path


def refs(**names) -> dict[str, str]:
    return {engine: ALL[kind] for engine, kind in names.items()}


def load_case(path: Path, engine_refs: dict[str, str]):
    """The fakes stand in for engines with integrator names of their own ("exact", "euler"),
    which the loader accepts only for the engines they replace (as ``crosscheck run`` does)."""
    return loader.load_case(path, unchecked_engines=engine_refs)


def by_id(outcome):
    return {c["id"]: c for c in outcome.doc["cells"]}


@pytest.mark.slow
def test_every_failure_mode_is_one_cells_result(tmp_path):
    case = write_case(tmp_path, "modes", engines='["inhouse", "mujoco", "pybullet", "pymunk"]',
                      integrators='{ inhouse = ["exact", "euler"], mujoco = ["exact"], '
                                  'pybullet = ["exact"], pymunk = ["exact"] }', timeout=3)
    other = write_case(tmp_path, "more", engines='["inhouse", "mujoco"]',
                       integrators='{ inhouse = ["exact"], mujoco = ["exact"] }', timeout=3)
    er = refs(inhouse="exact", mujoco="crash", pybullet="hang", pymunk="raise")
    matrix = build_matrix([load_case(case, er), load_case(other, er)], out=tmp_path / "out",
                          engine_refs=er)
    # The run's memory figure counts the orchestrating process too: here that is the pytest
    # worker, which carries whatever the tests before this one allocated (1.9 GiB once in CI),
    # and 256 MiB more held here: a worker's own peak must not include its parent's size
    # (getrusage's ru_maxrss did: Linux carries it across the spawn).
    ballast = np.ones(2**25)                      # 256 MiB, resident
    own_mb = psutil.Process().memory_info().rss / 2**20
    start = time.monotonic()
    outcome = run_and_report(matrix, LocalBackend(2), tmp_path / "out")
    elapsed = time.monotonic() - start
    cells = by_id(outcome)
    assert cells["modes::inhouse-exact@dt=0.01"]["status"] == "pass"
    euler = cells["modes::inhouse-euler@dt=0.01"]
    assert euler["status"] == "pass"
    # Explicit Euler lags the exact drop by g T h / 2 (h = 0.01, T = 1) -- computed in a worker
    # against the shared fine-step reference, which the exact fake reproduces to round-off.
    assert euler["metrics"]["position_error_max"]["value"] == pytest.approx(G * 0.01 / 2, 1e-9)
    crash = cells["modes::mujoco-exact@dt=0.01"]
    assert crash["status"] == "error" and "SIGSEGV" in crash["reason"]
    hang = cells["modes::pybullet-exact@dt=0.01"]
    assert hang["status"] == "timeout" and "3 s" in hang["reason"]
    boom = cells["modes::pymunk-exact@dt=0.01"]
    assert boom["status"] == "error" and "adapter bug" in boom["reason"]
    # The other case, run by the same pool after the crash and the kill, is intact.
    assert cells["more::inhouse-exact@dt=0.01"]["status"] == "pass"
    assert cells["more::mujoco-exact@dt=0.01"]["status"] == "error"
    assert outcome.exit_status == 1
    # The hang cost its 3 s timeout, not the case's default 600 s (the bound leaves room for
    # spawning replacement workers on a loaded machine).
    assert elapsed < 45
    doc = json.loads((tmp_path / "out" / "results.json").read_text())
    assert doc["counts"] == {"pass": 3, "error": 3, "timeout": 1}
    # Measured, and of the right size: two workers that import only the fakes (58 MiB each
    # standalone) over the orchestrator, with room for a replacement worker spawned beside them;
    # no worker anywhere near the ballast's size.
    added_mb = doc["resources"]["peak_rss_total_mb"] - own_mb
    assert 0 < doc["resources"]["peak_rss_worker_mb"] < min(added_mb, 200)
    assert added_mb < 1024
    assert ballast[-1] == 1.0
    lines = [json.loads(x) for x in (tmp_path / "out" / "cells.jsonl").read_text().splitlines()]
    runs = [r for r in lines if r.get("kind") != "cost"]
    assert len(runs) == 7 + 2  # every cell and both reference runs, as they arrived
    # and two more processes' cost passes of each timed cell (docs/metrics.md, "Cost")
    timed = sum(bool((r.get("cost_detail") or {}).get("repeats")) for r in runs)
    assert len(lines) - len(runs) == 2 * timed


def test_blowup_and_unimportable_engine(tmp_path):
    case = write_case(tmp_path, "bad", engines='["inhouse", "mujoco"]',
                      integrators='{ inhouse = ["exact"], mujoco = ["exact"] }',
                      reference='kind = "none"')
    er = refs(inhouse="blowup", mujoco="missing")
    matrix = build_matrix([load_case(case, er)], out=tmp_path / "out", engine_refs=er)
    outcome = run_and_report(matrix, LocalBackend(1), tmp_path / "out")
    cells = by_id(outcome)
    blow = cells["bad::inhouse-exact@dt=0.01"]
    assert blow["status"] == "blowup"
    assert blow["metrics"]["blowup_time"]["value"] > 0.2  # the fake runs away after 0.2 s
    na = cells["bad::mujoco-exact@dt=0.01"]
    assert na["status"] == "not_applicable"
    assert "No module named 'crosscheck_no_such_module'" in na["reason"]
    assert outcome.exit_status == 1


def test_a_failed_reference_makes_its_cells_errors_with_the_reason(tmp_path):
    case = write_case(tmp_path, "noref", engines='["inhouse"]',
                      integrators='{ inhouse = ["exact"] }',
                      reference='kind = "fine-step"\nengine = "mujoco"\nintegrator = "exact"\n'
                                'dt = 0.001')
    er = refs(inhouse="exact", mujoco="raise")
    matrix = build_matrix([load_case(case, er)], out=tmp_path / "out", engine_refs=er)
    outcome = run_and_report(matrix, LocalBackend(1), tmp_path / "out")
    cell = by_id(outcome)["noref::inhouse-exact@dt=0.01"]
    assert cell["status"] == "error"
    assert "position_error_max" in cell["reason"] and "reference run error" in cell["reason"]
    assert outcome.doc["references"][0]["status"] == "error"


def test_save_trajectories_writes_the_design_layout(tmp_path):
    case = write_case(tmp_path, "save", reference='kind = "none"', tolerances="")
    er = refs(inhouse="exact")
    matrix = build_matrix([load_case(case, er)], out=tmp_path / "out", save_trajectories=True,
                          engine_refs=er, dts=[0.01, 0.005])
    outcome = run_and_report(matrix, LocalBackend(2), tmp_path / "out")
    assert len(outcome.cells) == 4
    path = tmp_path / "out" / "trajectories" / "save" / "inhouse-euler-dt0.005.npz"
    traj = Trajectory.load(path)
    # Euler at h = 0.005 lags by g t h / 2 at t = 1: z = 10 - g/2 + g h / 2.
    assert traj.com[-1, 0, 2] == pytest.approx(10 - G / 2 + G * 0.005 / 2, abs=1e-10)
    assert traj.meta["dt"] == 0.005


def test_matrix_filters_and_overrides(tmp_path):
    er = refs(inhouse="exact", mujoco="exact")
    scene = load_case(write_case(tmp_path, "m", engines='["inhouse", "mujoco"]',
                                 integrators='{ inhouse = ["exact", "euler"] }',
                                 reference='kind = "none"', tolerances=""), er)
    ids = [t["id"] for t in build_matrix([scene], engine_refs=er).cells]
    # mujoco lists no integrators: its adapter's default (the fake's first) is used.
    assert ids == ["m::inhouse-exact@dt=0.01", "m::inhouse-euler@dt=0.01",
                   "m::mujoco-exact@dt=0.01"]
    ids = [t["id"] for t in build_matrix([scene], engines=["mujoco"], engine_refs=er,
                                         integrators=["euler", "mujoco.fast_spin"]).cells]
    assert ids == ["m::mujoco-fast_spin@dt=0.01"]
    with pytest.raises(UsageError, match="unknown engine"):
        build_matrix([scene], engines=["bullet3"])
    with pytest.raises(UsageError, match="two case files"):
        build_matrix([scene, scene])


def run_cli(args, cwd, timeout=120, **kw):
    env = dict(os.environ, PYTHONPATH=str(HERE))
    return subprocess.run([sys.executable, "-m", "crosscheck.cli", *args], cwd=cwd, env=env,
                          capture_output=True, text=True, timeout=timeout, **kw)


def test_cli_exit_statuses(tmp_path):
    # Explicit Euler gains m g^2 T h / 2 = 0.96 J of the 96 J scale: drift 0.01 <= 0.011.
    good = write_case(tmp_path, "good", reference='kind = "none"',
                      tolerances="translational_energy_drift = 0.011")
    er = ["--engine-ref", f"inhouse={ALL['exact']}"]
    ok = run_cli(["run", str(good), "--out", "o1", "--workers", "1", *er], tmp_path)
    assert ok.returncode == 0, ok.stdout + ok.stderr
    assert "good" in ok.stdout and "2 pass" in ok.stdout
    # ... and fails a limit of 0.009.
    failing = write_case(tmp_path, "failing", reference='kind = "none"',
                         tolerances="translational_energy_drift = 0.009")
    bad = run_cli(["run", str(failing), "--out", "o2", "--workers", "1", *er], tmp_path)
    assert bad.returncode == 1, bad.stdout + bad.stderr
    assert "FAIL    failing inhouse-euler" in bad.stdout
    assert "PASS    failing inhouse-exact" in bad.stdout
    broken = tmp_path / "cases" / "broken.toml"
    broken.parent.mkdir()
    broken.write_text('[case]\nname = "x"\ndimension = 4\n')
    res = run_cli(["run", str(broken.parent), "--out", "o3", *er], tmp_path)
    assert res.returncode == 2
    assert res.stderr.startswith("error: ") and "dimension" in res.stderr
    assert "Traceback" not in res.stderr
    res = run_cli(["run", str(good), "--engines", "nope", *er], tmp_path)
    assert res.returncode == 2 and "unknown engine" in res.stderr
    res = run_cli(["run", str(good), "--baseline", "missing.json", *er], tmp_path)
    assert res.returncode == 2 and "not found" in res.stderr


def test_sigterm_writes_the_reports_of_what_ran(tmp_path):
    write_case(tmp_path, "a_quick", integrators='{ inhouse = ["exact"] }',
               reference='kind = "none"', tolerances="")
    write_case(tmp_path, "b_stuck", engines='["mujoco"]', integrators='{ mujoco = ["exact"] }',
               reference='kind = "none"', tolerances="")
    env = dict(os.environ, PYTHONPATH=str(HERE))
    proc = subprocess.Popen(
        [sys.executable, "-m", "crosscheck.cli", "run", str(tmp_path), "--out", "out",
         "--workers", "1", "--engine-ref", f"inhouse={ALL['exact']}",
         "--engine-ref", f"mujoco={ALL['hang']}"],
        cwd=tmp_path, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    journal = tmp_path / "out" / "cells.jsonl"
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline and not (journal.exists() and journal.read_text()):
        time.sleep(0.2)
    time.sleep(0.5)  # the hang cell is now running
    proc.send_signal(signal.SIGTERM)
    out, err = proc.communicate(timeout=60)
    assert proc.returncode == 130, out + err
    doc = json.loads((tmp_path / "out" / "results.json").read_text())
    assert doc["interrupted"] is True
    assert [c["id"] for c in doc["cells"]] == ["a_quick::inhouse-exact@dt=0.01"]
    assert doc["not_run"] == ["b_stuck::mujoco-exact@dt=0.01"]
    assert (tmp_path / "out" / "index.html").exists()
    assert (tmp_path / "out" / "junit.xml").exists()


def test_workers_over_their_memory_cap_are_replaced(tmp_path):
    case = write_case(tmp_path, "recycle", integrators='{ inhouse = ["exact", "euler", '
                                                       '"fast_spin"] }', reference='kind = "none"',
                      tolerances="")
    er = refs(inhouse="exact")
    # (cost timed in the cell's own process only: extra cost tasks would recycle workers too)
    matrix = build_matrix([load_case(case, er)], out=tmp_path / "out", engine_refs=er,
                          cost={"processes": 1})
    backend = LocalBackend(1, max_worker_rss_mb=1.0)  # every worker is over 1 MiB
    outcome = run_and_report(matrix, backend, tmp_path / "out")
    assert [c["status"] for c in outcome.cells] == ["pass"] * 3
    assert backend.recycled == 3
    assert len({c["pid"] for c in outcome.cells}) == 3  # a fresh process for each cell
    assert outcome.doc["resources"]["workers_recycled"] == 3
