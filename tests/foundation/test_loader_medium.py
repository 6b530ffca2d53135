"""[effects] medium: read, defaults, and every refusal naming the file, the field path, what was
expected and what was found (docs/cases.md, "[effects]"); the MuJoCo fluid options beside it."""

from __future__ import annotations

import pytest

from crosscheck.engines.mujoco import FLUIDCOEF_DEFAULT, engine_options
from crosscheck.errors import CaseError
from crosscheck.scene.loader import load_case_text

BODY = """
[[bodies]]
name = "ball"
shape = { sphere = { radius = 0.05 } }
density = 2000.0
position = [0.0, 0.0, 0.0]
"""


def case(medium: str = "", dimension: int = 3, extra: str = "", body: str = BODY) -> str:
    return f"""
[case]
name = "m"
dimension = {dimension}
[run]
duration = 0.1
dt = 1e-3
[effects]
gravity = {[0.0, 0.0, -9.81] if dimension == 3 else [0.0, -9.81]}
{medium}
{body}
{extra}"""


def refused(text: str) -> str:
    with pytest.raises(CaseError) as err:
        load_case_text(text, "m.toml")
    return str(err.value)


def test_medium_is_read_with_its_defaults():
    scene = load_case_text(case("medium = { density = 1000.0, viscosity = 1e-3 }"))
    assert scene.effects.medium.density == 1000.0 and scene.effects.medium.viscosity == 1e-3
    assert "medium" in scene.effects.names()
    only_density = load_case_text(case("medium = { density = 1.2 }")).effects.medium
    assert only_density.viscosity == 0.0
    assert load_case_text(case("medium = { viscosity = 2.0 }")).effects.medium.density == 0.0
    assert load_case_text(case()).effects.medium is None


@pytest.mark.parametrize("medium,path,expected", [
    ("medium = { density = -1.0 }", "effects.medium.density",
     "expected a non-negative number in kg/m^3, got -1.0"),
    ("medium = { viscosity = \"high\" }", "effects.medium.viscosity",
     "expected a number in Pa s, got 'high'"),
    ("medium = { density = 1000.0, viscosty = 1.0 }", "effects.medium.viscosty",
     "expected one of the known keys ['density', 'viscosity']"),
    ("medium = { density = 0.0, viscosity = 0.0 }", "effects.medium",
     "a density or a viscosity above zero"),
    ("medium = {}", "effects.medium", "a density or a viscosity above zero"),
    ("medium = 1000.0", "effects.medium", "expected a table, got 1000.0"),
    ("medium = { density = nan }", "effects.medium.density", "a finite number"),
])
def test_medium_refusals_name_the_field(medium, path, expected):
    message = refused(case(medium))
    assert message.startswith(f"m.toml: {path}: ")
    assert expected in message


def test_no_medium_in_2d_or_in_a_fluid_case():
    body2d = BODY.replace("sphere = { radius = 0.05 }", "circle = { radius = 0.05 }").replace(
        "[0.0, 0.0, 0.0]", "[0.0, 0.0]")
    message = refused(case("medium = { density = 1000.0 }", dimension=2, body=body2d))
    assert "m.toml: effects.medium: expected no medium in a 2D case" in message
    fluid = case("medium = { density = 1000.0 }", dimension=2, body="", extra="""
[fluid]
domain = [1.0, 1.0]
resolution = [16, 16]
""")
    assert "effects.medium: expected no medium in a [fluid] case" in refused(fluid)


def test_mujoco_fluid_options():
    scene = load_case_text(case("medium = { density = 1000.0 }", extra="""
[engine_options.mujoco]
fluid_model = "ellipsoid"
fluidcoef = [0.235, 0.25, 1.5, 1, 1]
"""))
    opts = engine_options(scene)
    assert opts["fluid_model"] == "ellipsoid" and opts["fluidcoef"] == [0.235, 0.25, 1.5, 1.0, 1.0]
    default = engine_options(load_case_text(case("medium = { density = 1000.0 }")))
    assert default["fluid_model"] == "inertia_box"
    assert default["fluidcoef"] == list(FLUIDCOEF_DEFAULT)


@pytest.mark.parametrize("medium,options,path,expected", [
    ("", 'fluid_model = "ellipsoid"', "fluid_model", "no fluid option on a scene without"),
    ("medium = { density = 1.0 }", 'fluid_model = "box"', "fluid_model",
     "one of ['inertia_box', 'ellipsoid']"),
    ("medium = { density = 1.0 }", 'fluid_model = "ellipsoid"\nfluidcoef = [1, 2]', "fluidcoef",
     "5 non-negative numbers"),
    ("medium = { density = 1.0 }", "fluidcoef = [0.5, 0.25, 1.5, 1, 1]", "fluidcoef",
     'fluid_model = "ellipsoid" beside it'),
    ("medium = { density = 1.0 }", 'fluid_model = "ellipsoid"\nfluidcoef = [-1, 0, 0, 0, 0]',
     "fluidcoef", "5 non-negative numbers"),
])
def test_mujoco_fluid_option_refusals(medium, options, path, expected):
    scene = load_case_text(case(medium, extra=f"[engine_options.mujoco]\n{options}\n"), "m.toml")
    with pytest.raises(CaseError) as err:
        engine_options(scene)
    assert f"engine_options.mujoco.{path}" in str(err.value)
    assert expected in str(err.value)
