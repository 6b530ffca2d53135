"""The pytest plugin: ``pytest cases/`` collects case files, one item per engine x integrator.

Runs pytest in a subprocess on a scratch project (its own pyproject.toml, a TOML file that is not
a case, a case whose explicit-Euler cell fails its position limit), with the fake adapters.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

from crosscheck_fakes import ALL

HERE = Path(__file__).resolve().parent
G = 9.81

CASE = """
[case]
name = "fall"
dimension = 3
[run]
duration = 1.0
dt = 0.01
sample_every = 0.05
engines = ["inhouse", "mujoco"]
integrators = { inhouse = ["exact", "euler"] }
[effects]
gravity = [0, 0, -9.81]
[[bodies]]
name = "ball"
shape = { sphere = { radius = 0.1 } }
mass = 2.0
position = [0, 0, 10]
[reference]
kind = "fine-step"
engine = "inhouse"
integrator = "exact"
dt = 0.001
[tolerances]
# Euler lags by g T h / 2 = 0.049 m: fails this limit, the exact run passes it.
position_error_max = 0.01
"""


def project(tmp_path: Path) -> Path:
    (tmp_path / "pyproject.toml").write_text(
        '[project]\nname = "scratch"\n[tool.pytest.ini_options]\ntestpaths = ["tests"]\n')
    cases = tmp_path / "cases" / "rigid3d"
    cases.mkdir(parents=True)
    (cases / "fall.toml").write_text(CASE)
    (tmp_path / "cases" / "notes.toml").write_text('title = "not a case"\n')
    (tmp_path / "tests").mkdir()
    (tmp_path / "tests" / "test_plain.py").write_text("def test_plain():\n    pass\n")
    return tmp_path


def pytest_run(tmp_path, *args):
    env = dict(os.environ, PYTHONPATH=str(HERE))
    env.pop("PYTEST_XDIST_WORKER", None)
    return subprocess.run(
        [sys.executable, "-m", "pytest", "-p", "no:randomly", "-rs", "-v",
         "--crosscheck-engine-ref", f"inhouse={ALL['exact']}",
         "--crosscheck-engine-ref", f"mujoco={ALL['missing']}", *args],
        cwd=tmp_path, env=env, capture_output=True, text=True, timeout=180)


def test_cases_become_items_with_verdicts(tmp_path):
    root = project(tmp_path)
    res = pytest_run(root, "cases/")
    out = res.stdout
    assert res.returncode == 1, out + res.stderr
    assert "cases/rigid3d/fall.toml::inhouse-exact PASSED" in out
    assert "cases/rigid3d/fall.toml::inhouse-euler FAILED" in out
    # An engine that does not import cannot name its default integrator: "default".
    assert "cases/rigid3d/fall.toml::mujoco-default SKIPPED" in out
    assert "No module named 'crosscheck_no_such_module'" in out  # the skip reason
    # The failure shows the metric table with the value and the limit.
    assert "fail: position_error_max = 0.0491 > 0.01" in out
    assert "position_error_max" in out and "FAIL" in out
    assert "collected 3 items" in out  # not notes.toml (no [case] table)
    assert "1 failed, 1 passed, 1 skipped" in out


def test_bare_pytest_collects_no_case_files(tmp_path):
    root = project(tmp_path)
    res = pytest_run(root)
    assert res.returncode == 0, res.stdout + res.stderr
    assert "1 passed" in res.stdout and "fall.toml" not in res.stdout
    # Given the project root, the case items join the plain test, pyproject.toml does not.
    res = pytest_run(root, ".")
    assert "collected 4 items" in res.stdout, res.stdout
    assert "pyproject.toml::" not in res.stdout and "notes.toml::" not in res.stdout


def test_works_under_xdist(tmp_path):
    root = project(tmp_path)
    res = pytest_run(root, "cases/", "-n", "2")
    assert res.returncode == 1, res.stdout + res.stderr
    assert "1 failed, 1 passed, 1 skipped" in res.stdout
    assert "[gw" in res.stdout  # really distributed
    # Both workers share one reference run through the lock file: a single file was written.
    refs = list((root / ".pytest_cache").rglob("fall-*.npz"))
    assert len(refs) == 1


def test_broken_case_is_a_collection_error_naming_the_field(tmp_path):
    root = project(tmp_path)
    (root / "cases" / "rigid3d" / "fall.toml").write_text(CASE.replace("mass = 2.0",
                                                                        "mass = -2.0"))
    res = pytest_run(root, "cases/")
    assert res.returncode == 2, res.stdout + res.stderr
    assert "bodies[0].mass" in res.stdout
    assert "Traceback" not in res.stdout
