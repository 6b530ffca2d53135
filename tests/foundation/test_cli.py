"""The command line: `crosscheck list`, `show`, `--version`, help, and how bad input is reported
(exit status 2, one line `error: ...` on stderr, never a traceback), both in-process through
crosscheck.cli.main and through the installed console script.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from crosscheck import __version__
from crosscheck.cli import main

REPO = Path(__file__).resolve().parents[2]
SCRIPT = next((p for p in (REPO / ".venv" / "bin" / "crosscheck",
                           Path(sys.executable).with_name("crosscheck")) if p.exists()), None)

GOOD = """[case]
name = "{name}"
description = "a good case"
tags = ["t1", "t2"]
dimension = 3
[run]
duration = 1.0
dt = 0.01
engines = ["inhouse", "mujoco"]
[[bodies]]
name = "ball"
shape = {{ sphere = {{ radius = 0.1 }} }}
mass = 1.0
position = [0.0, 0.0, 0.0]
"""

# (file text, the field path the error must name, a phrase of what was expected)
BAD = {
    "syntax": (GOOD.format(name="x").replace("dt = 0.01", "dt = = 0.01"), "",
               "valid TOML"),
    "typo": (GOOD.format(name="x").replace("mass = 1.0", "mass = 1.0\nvelocty = [0, 0, 0]"),
             "bodies[0].velocty", "one of the known keys"),
    "negative-size": (GOOD.format(name="x").replace("radius = 0.1", "radius = -0.1"),
                      "bodies[0].shape.sphere.radius", "a positive number in m"),
    "nan": (GOOD.format(name="x").replace("mass = 1.0", "mass = nan"), "bodies[0].mass",
            "a finite number in kg"),
    "missing-mesh": (GOOD.format(name="x").replace("sphere = { radius = 0.1 }",
                                                   'mesh = { file = "nowhere.obj" }'),
                     "bodies[0].shape.mesh.file", "a mesh file that is a closed"),
    "open-mesh": (GOOD.format(name="x").replace(
        "sphere = { radius = 0.1 }", f'mesh = {{ file = "{REPO}/cases/meshes/not_closed.obj" }}'),
        "bodies[0].shape.mesh.file", "a mesh file that is a closed"),
    "quaternion": (GOOD.format(name="x") + "orientation = [1.0, 0.2, 0.0, 0.0]\n",
                   "bodies[0].orientation", "a unit quaternion"),
    "no-bodies": (GOOD.format(name="x").split("[[bodies]]")[0], "bodies",
                  "at least one [[bodies]] entry"),
    "integrator": (GOOD.format(name="x").replace(
        'engines = ["inhouse", "mujoco"]',
        'engines = ["inhouse", "mujoco"]\nintegrators = { mujoco = ["rk5"] }'),
        "run.integrators.mujoco[0]",
        "an integrator of mujoco, one of ['euler', 'rk4', 'implicit', 'implicitfast', 'discrete', "
        "'euler+inertia_box'"),
}


def write(tmp_path: Path, name: str, text: str) -> Path:
    p = tmp_path / name
    p.write_text(text)
    return p


def run_main(argv, capsys):
    capsys.readouterr()
    code = main(argv)
    out, err = capsys.readouterr()
    return code, out, err


def assert_one_error_line(err: str, path: Path, field: str, expected: str) -> None:
    assert "Traceback" not in err
    lines = err.splitlines()
    assert len(lines) == 1, err
    where = f"{path}: {field}: " if field else f"{path}: "
    assert lines[0].startswith(f"error: {where}expected "), lines[0]
    assert expected in lines[0]


# -- version and help ---------------------------------------------------------------------------
def test_version(capsys):
    with pytest.raises(SystemExit) as info:
        main(["--version"])
    assert info.value.code == 0
    assert capsys.readouterr().out.strip() == f"crosscheck {__version__}"


def test_help_lists_the_commands(capsys):
    with pytest.raises(SystemExit) as info:
        main(["--help"])
    assert info.value.code == 0
    out = capsys.readouterr().out
    for command in ("list", "show", "inertia"):
        assert command in out
    with pytest.raises(SystemExit):
        main(["show", "--help"])
    assert "--json" in capsys.readouterr().out


def test_no_command_prints_help_and_is_a_usage_error(capsys):
    code, out, _ = run_main([], capsys)
    assert code == 2 and "usage: crosscheck" in out


def test_unknown_command_is_a_usage_error(capsys):
    with pytest.raises(SystemExit) as info:
        main(["frobnicate"])
    assert info.value.code == 2
    assert "invalid choice" in capsys.readouterr().err


# -- list ---------------------------------------------------------------------------------------
def test_list_cases_json(capsys):
    code, out, err = run_main(["list", str(REPO / "cases"), "--json"], capsys)
    assert code == 0 and err == ""
    data = json.loads(out)
    assert data["errors"] == []
    by_name = {c["name"]: c for c in data["cases"]}
    tennis = by_name["tennis-racket"]
    assert tennis["dimension"] == 3 and "torque-free" in tennis["tags"]
    assert tennis["engines"] == ["inhouse", "mujoco", "pybullet"]
    assert Path(tennis["file"]).name == "tennis_racket.toml"
    assert by_name["falling-box-2d"]["dimension"] == 2
    # every case file is listed, sorted by path
    files = [c["file"] for c in data["cases"]]
    assert files == sorted(files) and len(files) == len(list((REPO / "cases").rglob("*.toml")))


def test_list_defaults_to_the_cases_folder(capsys, monkeypatch):
    monkeypatch.chdir(REPO)
    code, out, _ = run_main(["list", "--json"], capsys)
    assert code == 0
    assert "tennis-racket" in {c["name"] for c in json.loads(out)["cases"]}


def test_list_with_a_broken_file_lists_the_others_and_exits_2(tmp_path, capsys):
    write(tmp_path, "a_good.toml", GOOD.format(name="good-one"))
    write(tmp_path, "b_bad.toml", BAD["typo"][0])
    write(tmp_path, "c_good.toml", GOOD.format(name="good [/] two"))  # markup-like text
    write(tmp_path, "d_nobody.toml", BAD["no-bodies"][0])
    code, out, _ = run_main(["list", str(tmp_path), "--json"], capsys)
    assert code == 2
    data = json.loads(out)
    assert [c["name"] for c in data["cases"]] == ["good-one", "good [/] two"]
    assert data["cases"][0]["tags"] == ["t1", "t2"]
    errors = {Path(e["file"]).name: e["error"] for e in data["errors"]}
    assert set(errors) == {"b_bad.toml", "d_nobody.toml"}
    assert errors["b_bad.toml"].startswith(f"{tmp_path / 'b_bad.toml'}: bodies[0].velocty: ")
    # the table form too: both good cases shown, the errors printed whole
    code, out, _ = run_main(["list", str(tmp_path)], capsys)
    assert code == 2
    assert "good-one" in out and "good [/] two" in out
    assert "bodies[0].velocty" in out
    assert "expected at least one [[bodies]] entry" in out  # brackets are text, not markup


def test_list_of_a_missing_path_reports_it(tmp_path, capsys):
    code, out, _ = run_main(["list", str(tmp_path / "nope.toml"), "--json"], capsys)
    assert code == 2
    (error,) = json.loads(out)["errors"]
    assert "readable case file" in error["error"]


# -- show ---------------------------------------------------------------------------------------
def test_show_json_is_the_scene(capsys, tmp_path):
    f = write(tmp_path, "g.toml", GOOD.format(name="shown"))
    code, out, err = run_main(["show", "--json", str(f)], capsys)
    assert code == 0 and err == ""
    data = json.loads(out)
    assert data["name"] == "shown" and data["run"]["engines"] == ["inhouse", "mujoco"]
    (ball,) = data["bodies"]
    assert ball["mass"] == 1.0 and ball["shape"] == {"radius": 0.1, "kind": "sphere"}
    assert ball["derived"]["principal_moments"] == pytest.approx([0.004] * 3, rel=1e-14)
    assert ball["material"] == {"name": "default", "friction": 0.5, "restitution": 0.0,
                                "rolling_friction": 0.0, "torsional_friction": 0.0}


def test_show_prints_user_text_literally(capsys, tmp_path):
    text = GOOD.format(name="n [bold]x[/bold]").replace(
        "a good case", "see [/] and [red]here[/red]").replace('name = "ball"', 'name = "b[/]"')
    f = write(tmp_path, "m.toml", text)
    code, out, err = run_main(["show", str(f)], capsys)
    assert code == 0 and err == ""
    assert "n [bold]x[/bold]" in out and "see [/] and [red]here[/red]" in out
    assert "b[/]" in out


@pytest.mark.parametrize("kind", sorted(BAD))
def test_show_bad_file_exits_2_with_one_error_line(kind, tmp_path, capsys):
    text, field, expected = BAD[kind]
    f = write(tmp_path, f"{kind}.toml", text)
    for argv in (["show", str(f)], ["show", "--json", str(f)]):
        code, out, err = run_main(argv, capsys)
        assert code == 2 and out == ""
        assert_one_error_line(err, f, field, expected)


def test_list_with_a_misspelt_integrator_exits_2(tmp_path, capsys):
    write(tmp_path, "good.toml", GOOD.format(name="good-one"))
    bad = write(tmp_path, "typo.toml", BAD["integrator"][0])
    code, out, _ = run_main(["list", str(tmp_path), "--json"], capsys)
    assert code == 2
    data = json.loads(out)
    assert [c["name"] for c in data["cases"]] == ["good-one"]
    (error,) = data["errors"]
    assert error["error"].startswith(f"{bad}: run.integrators.mujoco[0]: expected an "
                                     "integrator of mujoco")


# -- run and sweep: a misspelt integrator is an input error, not a "not applicable" cell ----------
def test_run_with_a_misspelt_integrator_in_the_case_exits_2(tmp_path, capsys):
    text, field, expected = BAD["integrator"]
    f = write(tmp_path, "typo.toml", text)
    for extra in ([], ["--json"]):
        code, out, err = run_main(["run", str(f), "--out", str(tmp_path / "out"),
                                   "--workers", "1", *extra], capsys)
        assert code == 2 and out == ""
        assert_one_error_line(err, f, field, expected)
    assert not (tmp_path / "out").exists()  # refused before anything ran


@pytest.mark.parametrize(("command", "value", "message"), [
    ("run", "rk5", "error: --integrators: no engine has an integrator 'rk5'; known: inhouse: "
                   "rk4, rk4_exp, explicit_euler"),
    ("run", "mujoco.rk5", "error: --integrators: mujoco has no integrator 'rk5'; its "
                          "integrators: euler, rk4, implicit, implicitfast, discrete"),
    ("run", "inhouse.euler", "error: --integrators: inhouse has no integrator 'euler'"),
    ("run", "mujocoo.rk4", "error: --integrators: 'mujocoo.rk4' is not 'engine.integrator' "
                           "with a known engine (inhouse, mujoco, pybullet, pymunk)"),
    ("sweep", "verlett", "error: --integrators: no engine has an integrator 'verlett'"),
    ("sweep", "pybullet.rk4", "error: --integrators: pybullet has no integrator 'rk4'; its "
                              "integrators: multibody, maximal"),
])
def test_an_unknown_integrator_option_exits_2(command, value, message, tmp_path, capsys):
    f = write(tmp_path, "good.toml", GOOD.format(name="g"))
    argv = [command, str(f), "--integrators", f"rk4,{value}", "--out", str(tmp_path / "out"),
            "--workers", "1"]
    code, out, err = run_main(argv, capsys)
    assert code == 2 and "Traceback" not in err
    (line,) = err.splitlines()
    assert line.startswith(message), line
    assert not (tmp_path / "out").exists()


def test_show_missing_file(tmp_path, capsys):
    f = tmp_path / "absent.toml"
    code, out, err = run_main(["show", str(f)], capsys)
    assert code == 2
    assert_one_error_line(err, f, "", "a readable case file")


# -- the installed console script ------------------------------------------------------------------
needs_script = pytest.mark.skipif(SCRIPT is None, reason="console script not installed")


def _script(*args, cwd=None):
    return subprocess.run([str(SCRIPT), *args], capture_output=True, text=True, timeout=120,
                          cwd=cwd)


@needs_script
@pytest.mark.parametrize("kind", ["syntax", "negative-size", "open-mesh"])
def test_console_script_bad_file(kind, tmp_path):
    text, field, expected = BAD[kind]
    f = write(tmp_path, "bad.toml", text)
    proc = _script("show", str(f))
    assert proc.returncode == 2 and proc.stdout == ""
    assert_one_error_line(proc.stderr, f, field, expected)


@needs_script
def test_console_script_version_and_list(tmp_path):
    proc = _script("--version")
    assert proc.returncode == 0 and proc.stdout.strip() == f"crosscheck {__version__}"
    write(tmp_path, "good.toml", GOOD.format(name="g"))
    write(tmp_path, "bad.toml", BAD["nan"][0])
    proc = _script("list", "--json", str(tmp_path))
    assert proc.returncode == 2 and "Traceback" not in proc.stderr
    data = json.loads(proc.stdout)
    assert [c["name"] for c in data["cases"]] == ["g"]
    assert "bodies[0].mass: expected a finite number" in data["errors"][0]["error"]
