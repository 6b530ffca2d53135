"""The contact case format: materials with rolling and torsional friction, inline materials,
[[statics]], [[contact_pairs]] (overrides and collide = false), the pair rule, the checks that tie
them to [effects] contact, and what `crosscheck show` prints of them.

Cases are Python dicts written by the tests' TOML serialiser, so every refusal test changes one
thing of a valid case.
"""

from __future__ import annotations

import copy
import dataclasses
import json
import math
from pathlib import Path

import numpy as np
import pytest
from toml_writer import to_toml  # tests/foundation/toml_writer.py

from crosscheck.cli import main
from crosscheck.compare import scales
from crosscheck.errors import CaseError
from crosscheck.scene.contact import ContactPair, PairMaterial, pair_material
from crosscheck.scene.loader import load_case_text
from crosscheck.scene.model import Scene
from crosscheck.scene.shapes import Placed

REPO = Path(__file__).resolve().parents[2]
CASES = REPO / "cases"
NAME = "contact_case.toml"


def load(case: dict) -> Scene:
    return load_case_text(to_toml(case), name=NAME, base_dir=CASES / "rigid3d")


def base3d() -> dict:
    """A 3D contact case using every new key; its pair values are worked out by hand below."""
    return {
        "case": {"name": "contact-3d", "dimension": 3},
        "run": {"duration": 1.0, "dt": 1e-3},
        "effects": {"gravity": [0.0, 0.0, -9.81], "contact": True},
        "materials": {
            "rubber": {"friction": 0.9, "restitution": 0.8, "rolling_friction": 0.004,
                       "torsional_friction": 0.001},
            "steel": {"friction": 0.4, "restitution": 0.5, "rolling_friction": 0.001,
                      "torsional_friction": 0.004},
        },
        "ground": {"material": {"friction": 0.1, "restitution": 0.2}},
        "bodies": [
            {"name": "ball", "shape": {"sphere": {"radius": 0.1}}, "mass": 1.0,
             "position": [0.0, 0.0, 1.0], "material": "rubber"},
            {"name": "block", "shape": {"box": {"size": [0.2, 0.2, 0.2]}}, "mass": 1.0,
             "position": [1.0, 0.0, 1.0], "material": "steel"},
            {"name": "puck", "shape": {"cylinder": {"radius": 0.1, "length": 0.05}},
             "mass": 1.0, "position": [2.0, 0.0, 1.0]},  # the default material
        ],
        "statics": [
            {"name": "wall", "shape": {"box": {"size": [0.1, 2.0, 1.0]}},
             "position": [3.0, 0.0, 0.5], "orientation": {"axis": [0.0, 0.0, 1.0],
                                                         "angle": math.pi / 2},
             "material": "steel"},
        ],
        "contact_pairs": [
            {"a": "ball", "b": "wall", "friction": 0.25, "restitution": 0.3},
            {"a": "puck", "b": "ball", "collide": False},
        ],
    }


def base2d() -> dict:
    return {
        "case": {"name": "contact-2d", "dimension": 2},
        "run": {"duration": 1.0, "dt": 1e-3},
        "effects": {"gravity": [0.0, -9.81], "contact": True},
        "materials": {"wood": {"friction": 0.6, "rolling_friction": 0.002}},
        "ground": {},
        "bodies": [{"name": "disc", "shape": {"circle": {"radius": 0.1}}, "mass": 1.0,
                    "position": [0.0, 1.0], "material": "wood"}],
        "statics": [
            {"name": "ramp", "shape": {"polygon": {"vertices": [[0.0, 0.0], [2.0, 0.0],
                                                                [0.0, 1.0]]}},
             "position": [-1.0, 0.0], "material": {"friction": 0.24}},
            {"name": "peg", "shape": {"circle": {"radius": 0.05}}, "position": [1.0, 0.5]},
            {"name": "step", "shape": {"box": {"size": [0.5, 0.2]}}, "position": [2.0, 0.1],
             "orientation": 0.1},
        ],
        "contact_pairs": [{"a": "disc", "b": "step", "restitution": 1.0,
                           "rolling_friction": 0.0}],
    }


def refused(case: dict, field: str, expected: str) -> CaseError:
    """Loading ``case`` raises one CaseError naming the file, exactly ``field`` and
    ``expected``."""
    with pytest.raises(CaseError) as info:
        load(case)
    exc = info.value
    message = str(exc)
    assert exc.file == NAME and exc.field == field, message
    assert message.startswith(f"{NAME}: {field}: expected "), message
    assert expected in exc.expected, message
    assert "\n" not in message
    return exc


# -- happy paths --------------------------------------------------------------------------------
def test_materials_read_rolling_and_torsional_friction_in_metres():
    s = load(base3d())
    rubber = s.materials["rubber"]
    assert (rubber.friction, rubber.restitution) == (0.9, 0.8)
    assert (rubber.rolling_friction, rubber.torsional_friction) == (0.004, 0.001)
    d = s.materials["default"]
    assert (d.friction, d.restitution, d.rolling_friction, d.torsional_friction) == \
        (0.5, 0.0, 0.0, 0.0)
    assert s.bodies[0].material is rubber and s.bodies[2].material.name == "default"


def test_an_inline_material_is_named_by_its_field_path_and_takes_the_defaults():
    s = load(base3d())
    g = s.ground.material
    assert g.name == "ground.material" and "ground.material" not in s.materials
    assert (g.friction, g.restitution, g.rolling_friction, g.torsional_friction) == \
        (0.1, 0.2, 0.0, 0.0)
    ramp = load(base2d()).statics[0].material
    assert ramp.name == "statics[0].material" and ramp.friction == 0.24
    assert ramp.restitution == 0.0
    case = base3d()
    case["bodies"][2]["material"] = {}  # an empty inline table: the defaults
    assert load(case).bodies[2].material.friction == 0.5


def test_a_static_is_placed_like_a_body_frame():
    s = load(base3d())
    (wall,) = s.statics
    assert s.static_names == ("wall",) and wall.shape.kind == "box"
    np.testing.assert_array_equal(wall.position, [3.0, 0.0, 0.5])
    np.testing.assert_allclose(wall.orientation, [math.cos(math.pi / 4), 0, 0,
                                                  math.sin(math.pi / 4)], atol=1e-15)
    assert wall.material is s.materials["steel"]
    placed = wall.placed()
    assert isinstance(placed, Placed)
    lo, hi = placed.bounding_box()  # the box turned a quarter turn about z: 2 m along x
    np.testing.assert_allclose(lo, [2.0, -0.05, 0.0], atol=1e-12)
    np.testing.assert_allclose(hi, [4.0, 0.05, 1.0], atol=1e-12)
    assert placed.signed_distance([[3.0, 0.0, 0.5]])[0] == pytest.approx(-0.05)
    for arr in (wall.position, wall.orientation):
        assert not arr.flags.writeable
    with pytest.raises(dataclasses.FrozenInstanceError):
        wall.name = "x"


@pytest.mark.parametrize("shape", [
    {"sphere": {"radius": 0.5}},
    {"capsule": {"radius": 0.1, "length": 0.5}},
    {"cylinder": {"radius": 0.2, "length": 0.3}},
    {"mesh": {"file": "../meshes/l_bracket.obj", "scale": 2.0}},
])
def test_every_3d_body_shape_makes_a_static(shape):
    case = base3d()
    case["statics"][0]["shape"] = shape
    (wall,) = load(case).statics
    assert wall.shape.kind == next(iter(shape))
    if "mesh" in shape:  # the body parser: the file relative to the case, scaled
        assert wall.shape.scale == 2.0 and wall.shape.path.name == "l_bracket.obj"


def test_2d_statics_take_circles_boxes_polygons_and_an_angle():
    s = load(base2d())
    assert [st.shape.kind for st in s.statics] == ["polygon", "circle", "box"]
    ramp, peg, step = s.statics
    assert ramp.orientation.tolist() == [0.0] and step.orientation.tolist() == [0.1]
    assert peg.material.name == "default"
    np.testing.assert_array_equal(step.position, [2.0, 0.1])


def test_a_case_without_statics_or_pairs_has_empty_tuples():
    case = base3d()
    del case["statics"], case["contact_pairs"]
    s = load(case)
    assert s.statics == () and s.pair_overrides == ()
    assert len(s.contact_pairs()) == 3 + 3  # three body-body, three body-ground


# -- the pair rule on a hand-worked example ------------------------------------------------------
def test_pair_values_follow_the_rule_unless_an_entry_overrides_them():
    s = load(base3d())
    r = math.sqrt
    # (friction, restitution, rolling, torsional, collide, source, overridden), worked by hand:
    # friction, rolling and torsional friction by sqrt(x_a x_b), restitution by max(e_a, e_b)
    expected = {
        ("ball", "block", "body-body"): (0.6, 0.8, 0.002, 0.002, True, "rule", ()),
        ("ball", "puck", "body-body"): (r(0.45), 0.8, 0.0, 0.0, False, "contact_pairs[1]", ()),
        ("block", "puck", "body-body"): (r(0.2), 0.5, 0.0, 0.0, True, "rule", ()),
        ("ball", "wall", "body-static"): (0.25, 0.3, 0.002, 0.002, True, "contact_pairs[0]",
                                          ("friction", "restitution")),
        ("block", "wall", "body-static"): (0.4, 0.5, 0.001, 0.004, True, "rule", ()),
        ("puck", "wall", "body-static"): (r(0.2), 0.5, 0.0, 0.0, True, "rule", ()),
        ("ball", "ground", "body-ground"): (0.3, 0.8, 0.0, 0.0, True, "rule", ()),
        ("block", "ground", "body-ground"): (0.2, 0.5, 0.0, 0.0, True, "rule", ()),
        ("puck", "ground", "body-ground"): (r(0.05), 0.2, 0.0, 0.0, True, "rule", ()),
    }
    pairs = s.contact_pairs()
    assert [(p.a, p.b, p.kind) for p in pairs] == list(expected)  # the documented order
    for p in pairs:
        f, e, roll, tors, collide, source, overridden = expected[(p.a, p.b, p.kind)]
        m = p.material
        assert (m.friction, m.restitution) == pytest.approx((f, e), rel=1e-15), p
        assert (m.rolling_friction, m.torsional_friction) == pytest.approx((roll, tors),
                                                                          rel=1e-15), p
        assert (m.collide, m.source, m.overridden) == (collide, source, overridden), p
    # the same material on both sides gives exactly that material
    block_wall = s.pair_material("block", "wall")
    assert (block_wall.friction, block_wall.rolling_friction) == (0.4, 0.001)


def test_a_pair_is_unordered_and_names_must_exist():
    s = load(base3d())
    for a, b in (("ball", "wall"), ("puck", "ball"), ("block", "ground")):
        assert pair_material(s, a, b) == pair_material(s, b, a) == s.pair_material(a, b)
    with pytest.raises(ValueError, match="nobody"):
        pair_material(s, "ball", "nobody")
    case = base3d()
    del case["ground"]
    with pytest.raises(ValueError, match="no \\[ground\\]"):
        pair_material(load(case), "ball", "ground")


def test_2d_overrides_keep_the_rule_for_the_values_they_do_not_give():
    s = load(base2d())
    by_pair = {(p.a, p.b): p.material for p in s.contact_pairs()}
    assert list(by_pair) == [("disc", "ramp"), ("disc", "peg"), ("disc", "step"),
                             ("disc", "ground")]
    assert by_pair[("disc", "ramp")].friction == pytest.approx(math.sqrt(0.6 * 0.24))
    assert by_pair[("disc", "ramp")].rolling_friction == 0.0  # sqrt(0.002 * 0)
    step = by_pair[("disc", "step")]
    assert (step.restitution, step.rolling_friction) == (1.0, 0.0)
    assert step.friction == pytest.approx(math.sqrt(0.6 * 0.5))  # from the rule
    assert step.overridden == ("restitution", "rolling_friction")


def test_extreme_values_combine_without_overflow():
    case = base3d()
    case["materials"]["rubber"]["friction"] = 1e300
    case["materials"]["steel"]["friction"] = 1e300
    case["materials"]["steel"]["rolling_friction"] = 5e-324
    s = load(case)
    m = s.pair_material("ball", "block")
    assert m.friction == 1e300 and math.isfinite(s.pair_material("ball", "puck").friction)
    assert 0 < m.rolling_friction < 1e-150


def test_a_scene_without_contact_has_no_pairs():
    case = base3d()
    del case["statics"], case["contact_pairs"]
    case["effects"]["contact"] = False
    assert load(case).contact_pairs() == ()


def test_conservation_follows_the_pair_values_and_statics_are_external():
    case = base3d()
    del case["contact_pairs"], case["statics"], case["ground"]
    case["materials"] = {"elastic": {"friction": 0.0, "restitution": 1.0},
                         "dead": {"friction": 0.0, "restitution": 0.0}}
    for i, body in enumerate(case["bodies"]):
        body["material"] = "elastic" if i else "dead"
    # the dead ball against the elastic bodies bounces with max(0, 1) = 1: every pair elastic
    s = load(case)
    assert scales.energy_not_conserved(s) is None
    case["statics"] = [{"name": "wall", "shape": {"sphere": {"radius": 1.0}},
                        "position": [5.0, 0.0, 0.0], "material": "elastic"}]
    del case["effects"]["gravity"]
    s = load(case)
    assert "static" in scales.linear_momentum_directions(s)[1]
    assert "static" in scales.angular_momentum_not_conserved(s)
    case["contact_pairs"] = [{"a": "ball", "b": "wall", "friction": 0.1}]
    assert "dissipates" in scales.energy_not_conserved(load(case))


def test_contact_in_a_fluid_case_loads_as_before():
    text = (CASES / "fluid" / "tank_at_rest.toml").read_text()
    s = load_case_text(text.replace("[effects]\n", "[effects]\ncontact = true\n"))
    assert s.effects.contact and s.contact_pairs() == ()


# -- refusals -------------------------------------------------------------------------------------
def _set(path: list, value):
    def mutate(case):
        node = case
        for k in path[:-1]:
            node = node[k]
        node[path[-1]] = value
    return mutate


def _del(path: list):
    def mutate(case):
        node = case
        for k in path[:-1]:
            node = node[k]
        del node[path[-1]]
    return mutate


def _no_statics_no_contact(case):
    del case["statics"]
    case["contact_pairs"] = [{"a": "ball", "b": "puck", "collide": False}]
    case["effects"]["contact"] = False


def _pair_with_ground_but_no_ground(case):
    del case["ground"]
    case["contact_pairs"][0]["b"] = "ground"


REFUSALS_3D = [
    # materials
    (_set(["materials", "rubber", "rolling_friction"], -0.1),
     "materials.rubber.rolling_friction", "a non-negative number in m"),
    (_set(["materials", "rubber", "torsional_friction"], "x"),
     "materials.rubber.torsional_friction", "a number in m"),
    (_set(["materials", "rubber", "torsional_friction"], math.inf),
     "materials.rubber.torsional_friction", "a finite number in m"),
    (_set(["materials", "rubber", "rolling_fricton"], 0.1),
     "materials.rubber.rolling_fricton", "one of the known keys"),
    # material references
    (_set(["bodies", 0, "material"], 3), "bodies[0].material",
     "a material name or an inline table"),
    (_set(["bodies", 0, "material"], "glass"), "bodies[0].material",
     "a material defined under [materials]"),
    (_set(["bodies", 0, "material"], {"frition": 0.3}), "bodies[0].material.frition",
     "one of the known keys"),
    (_set(["ground", "material"], {"restitution": 1.5}), "ground.material.restitution",
     "a coefficient between 0 and 1"),
    (_set(["statics", 0, "material"], {"rolling_friction": -1.0}),
     "statics[0].material.rolling_friction", "a non-negative number in m"),
    # statics and pairs need contact
    (_set(["effects", "contact"], False), "statics", "[effects] contact = true"),
    (_no_statics_no_contact, "contact_pairs",
     "[effects] contact = true in a case with [[contact_pairs]]"),
    # statics
    (_del(["statics", 0, "name"]), "statics[0].name", "this required field"),
    (_set(["statics", 0, "name"], "ball"), "statics[0].name",
     "a name no body or other static has"),
    (_set(["statics", 0, "name"], "ground"), "statics[0].name", "a name other than 'ground'"),
    (_set(["statics", 0, "shape"], {"circle": {"radius": 1.0}}), "statics[0].shape",
     "a table with exactly one of ['box', 'capsule', 'cylinder', 'mesh', 'sphere']"),
    (_set(["statics", 0, "shape", "box", "size"], [0.1, -2.0, 1.0]),
     "statics[0].shape.box.size[1]", "a positive number in m"),
    (_set(["statics", 0, "shape"], {"mesh": {"file": "../meshes/not_closed.obj"}}),
     "statics[0].shape.mesh.file", "a mesh file that is"),
    (_del(["statics", 0, "position"]), "statics[0].position", "this required field"),
    (_set(["statics", 0, "position"], [0.0, 0.0]), "statics[0].position",
     "an array of 3 finite numbers in m"),
    (_set(["statics", 0, "orientation"], [1.0, 0.1, 0.0, 0.0]), "statics[0].orientation",
     "a unit quaternion"),
    (_set(["statics", 0, "orientation"], {"axis": [0.0, 0.0, 0.0], "angle": 1.0}),
     "statics[0].orientation.axis", "a non-zero axis"),
    (_set(["statics", 0, "mass"], 1.0), "statics[0].mass", "one of the known keys"),
    (_set(["statics", 0, "velocity"], [1.0, 0.0, 0.0]), "statics[0].velocity",
     "one of the known keys"),
    (_set(["statics", 0, "material"], "glass"), "statics[0].material",
     "a material defined under [materials]"),
    (_set(["statics"], {"name": "x"}), "statics", "an array of tables"),
    # contact pairs
    (_set(["contact_pairs", 0, "a"], "nobody"), "contact_pairs[0].a",
     "the name of a body, a static or 'ground' ['ball', 'block', 'puck', 'wall', 'ground']"),
    (_del(["contact_pairs", 0, "b"]), "contact_pairs[0].b", "this required field"),
    (_set(["contact_pairs", 0, "b"], "ball"), "contact_pairs[0].b", "a name other than a"),
    (_set(["contact_pairs", 0, "a"], "ground"), "contact_pairs[0].b",
     "a pair with at least one body"),
    (_set(["contact_pairs", 1], {"a": "wall", "b": "ball", "restitution": 0.1}),
     "contact_pairs[1]", "one entry per pair (contact_pairs[0] already names 'wall' and 'ball')"),
    (_set(["contact_pairs", 0, "friction"], -0.5), "contact_pairs[0].friction",
     "a non-negative number"),
    (_set(["contact_pairs", 0, "restitution"], 1.5), "contact_pairs[0].restitution",
     "a coefficient between 0 and 1"),
    (_set(["contact_pairs", 0, "torsional_friction"], math.nan),
     "contact_pairs[0].torsional_friction", "a finite number in m"),
    (_set(["contact_pairs", 1, "friction"], 0.3), "contact_pairs[1].friction",
     "no contact values with collide = false"),
    (_set(["contact_pairs", 0], {"a": "ball", "b": "wall"}), "contact_pairs[0]",
     "at least one of friction, restitution, rolling_friction, torsional_friction or "
     "collide = false"),
    (_set(["contact_pairs", 1, "collide"], "no"), "contact_pairs[1].collide", "true or false"),
    (_set(["contact_pairs", 0, "frction"], 0.3), "contact_pairs[0].frction",
     "one of the known keys ['a', 'b', 'collide', 'friction', 'restitution', "
     "'rolling_friction', 'torsional_friction']"),
    # reserved names
    (_set(["bodies", 2, "name"], "ground"), "bodies[2].name", "a name other than 'ground'"),
    (_pair_with_ground_but_no_ground, "contact_pairs[0].b", "(this case has no [ground])"),
]


@pytest.mark.parametrize(("mutate", "field", "expected"), REFUSALS_3D,
                         ids=[f"{i}:{r[1]}" for i, r in enumerate(REFUSALS_3D)])
def test_bad_contact_input_is_refused_with_file_field_and_expectation(mutate, field, expected):
    case = base3d()
    mutate(case)
    refused(case, field, expected)


REFUSALS_2D = [
    (_set(["materials", "wood", "torsional_friction"], 0.01),
     "materials.wood.torsional_friction", "no torsional_friction in a 2D case"),
    (_set(["contact_pairs", 0, "torsional_friction"], 0.0),
     "contact_pairs[0].torsional_friction", "no torsional_friction in a 2D case"),
    (_set(["statics", 1, "shape"], {"sphere": {"radius": 1.0}}), "statics[1].shape",
     "a table with exactly one of ['box', 'circle', 'polygon']"),
    (_set(["statics", 2, "shape", "box", "size"], [1.0, 1.0, 1.0]),
     "statics[2].shape.box.size", "an array of 2"),
    (_set(["statics", 0, "shape", "polygon", "vertices"], [[0, 0], [1, 1], [2, 2]]),
     "statics[0].shape.polygon.vertices", "a polygon with non-zero area"),
    (_set(["statics", 2, "orientation"], [1.0, 0.0, 0.0, 0.0]), "statics[2].orientation",
     "a number in rad"),
    (_set(["statics", 1, "position"], [0.0, 0.0, 0.0]), "statics[1].position",
     "an array of 2"),
    (_set(["statics", 2, "name"], "peg"), "statics[2].name",
     "a name no body or other static has"),
    (_set(["contact_pairs", 0, "a"], "peg"), "contact_pairs[0].b",
     "a pair with at least one body"),
]


@pytest.mark.parametrize(("mutate", "field", "expected"), REFUSALS_2D,
                         ids=[r[1] for r in REFUSALS_2D])
def test_bad_2d_contact_input_is_refused(mutate, field, expected):
    case = base2d()
    mutate(case)
    refused(case, field, expected)


def test_statics_in_a_fluid_case_are_its_obstacles():
    """Issue 14: a fluid case's statics are obstacles in the fluid (cut cells), named as the
    statics are, after the [fluid] section's own; they need no contact there."""
    text = (CASES / "fluid" / "tank_at_rest.toml").read_text() + (
        '\n[[statics]]\nname = "rock"\nshape = { circle = { radius = 0.1 } }\n'
        "position = [0.5, 0.2]\n")
    scene = load_case_text(text, name=NAME)
    assert scene.fluid.obstacle_names == ("rock",)
    assert scene.fluid.obstacles[0].signed_distance(np.array([0.5, 0.2])) == -0.1


def test_a_body_may_be_called_ground_when_nothing_collides():
    case = base3d()
    del case["statics"], case["contact_pairs"]
    case["effects"]["contact"] = False
    case["bodies"][2]["name"] = "ground"
    assert load(case).body_names[2] == "ground"


# -- crosscheck show ------------------------------------------------------------------------------
def _write(tmp_path: Path, case: dict) -> Path:
    f = tmp_path / "c.toml"
    f.write_text(to_toml(case))
    return f


def test_show_prints_the_statics_and_every_pair_value(tmp_path, capsys, monkeypatch):
    monkeypatch.setenv("COLUMNS", "200")  # so that rich keeps each table row on one line
    f = _write(tmp_path, base3d())
    assert main(["show", str(f)]) == 0
    out = capsys.readouterr().out
    text = " ".join(out.split())  # rich wraps long lines
    assert "ground: normal [0, 0, 1], offset 0.0 m, material ground.material" in text
    (row,) = [line for line in out.splitlines() if "wall" in line and "box" in line]
    for cell in ("[3, 0, 0.5]", "[0.7071, 0, 0, 0.7071]", "steel",
                 "[2, -0.05, 0] .. [4, 0.05, 1]"):  # pose, material, world bounding box
        assert cell in row, row
    assert "friction geometric mean, restitution maximum" in text
    assert "[[contact_pairs]]" in text  # printed, not taken for markup
    assert ("ball - wall: friction 0.25 (contact_pairs[0]), restitution 0.3 (contact_pairs[0]), "
            "rolling_friction 0.002 m, torsional_friction 0.002 m") in text
    assert "ball - puck: no contact (collide = false, contact_pairs[1])" in text
    assert ("block - puck: friction 0.447214, restitution 0.5, rolling_friction 0 m, "
            "torsional_friction 0 m") in text
    assert "puck - ground: friction 0.223607, restitution 0.2" in text


def test_show_2d_leaves_out_torsional_friction(tmp_path, capsys):
    f = _write(tmp_path, base2d())
    assert main(["show", str(f)]) == 0
    text = " ".join(capsys.readouterr().out.split())
    assert "disc - step: friction 0.547723, restitution 1 (contact_pairs[0]), " \
           "rolling_friction 0 m (contact_pairs[0])" in text
    assert "torsional" not in text


def test_show_json_has_statics_overrides_and_pair_values(tmp_path, capsys):
    f = _write(tmp_path, base3d())
    assert main(["show", "--json", str(f)]) == 0
    data = json.loads(capsys.readouterr().out)
    (wall,) = data["statics"]
    assert wall["name"] == "wall" and wall["shape"] == {"size": [0.1, 2.0, 1.0], "kind": "box"}
    assert wall["material"]["name"] == "steel"
    np.testing.assert_allclose(wall["derived"]["bounding_box_world"],
                               [[2.0, -0.05, 0.0], [4.0, 0.05, 1.0]], atol=1e-12)
    assert data["pair_overrides"][1] == {
        "index": 1, "a": "puck", "b": "ball", "friction": None, "restitution": None,
        "rolling_friction": None, "torsional_friction": None, "collide": False}
    pairs = {(p["a"], p["b"]): p for p in data["contact_pairs"]}
    assert len(pairs) == 9
    assert pairs[("ball", "wall")] == {
        "a": "ball", "b": "wall", "kind": "body-static",
        "material": {"friction": 0.25, "restitution": 0.3,
                     "rolling_friction": pytest.approx(0.002), "torsional_friction":
                     pytest.approx(0.002), "collide": True, "source": "contact_pairs[0]",
                     "overridden": ["friction", "restitution"]}}
    assert pairs[("ball", "puck")]["material"]["collide"] is False
    assert data["bodies"][0]["material"]["rolling_friction"] == 0.004


def test_show_without_contact_prints_no_pairs(tmp_path, capsys):
    case = copy.deepcopy(base3d())
    del case["statics"], case["contact_pairs"]
    case["effects"]["contact"] = False
    f = _write(tmp_path, case)
    assert main(["show", str(f)]) == 0
    assert "contact pairs" not in capsys.readouterr().out
    assert main(["show", "--json", str(f)]) == 0
    data = json.loads(capsys.readouterr().out)
    assert data["contact_pairs"] == [] and data["statics"] == []


def test_pair_types_are_frozen():
    m = PairMaterial(0.1, 0.2, 0.0, 0.0)
    with pytest.raises(dataclasses.FrozenInstanceError):
        m.friction = 1.0
    with pytest.raises(dataclasses.FrozenInstanceError):
        ContactPair("a", "b", "body-body", m).a = "c"


# -- the examples of docs/cases.md ----------------------------------------------------------------
def test_the_contact_examples_in_the_docs_load_with_the_documented_values():
    markdown = (REPO / "docs" / "cases.md").read_text()
    blocks = [p.split("```", 1)[0] for p in markdown.split("```toml\n")[1:]]
    (statics,) = [b for b in blocks if b.startswith("[[statics]]")]
    (contact,) = [b for b in blocks if "[[contact_pairs]]" in b]
    head = ('[case]\nname = "docs"\ndimension = 3\n[run]\nduration = 1.0\ndt = 0.001\n'
            '[[bodies]]\nname = "ball"\nshape = { sphere = { radius = 0.1 } }\nmass = 1.0\n'
            'position = [0.0, 0.0, 1.0]\nmaterial = "rubber"\n'
            '[[bodies]]\nname = "marker"\nshape = { sphere = { radius = 0.1 } }\n'
            'mass = 1.0\nposition = [1.0, 0.0, 1.0]\n')
    s = load_case_text(head + statics + contact, name="docs/cases.md")
    (ramp,) = s.statics
    lo, hi = ramp.placed().bounding_box()
    assert hi[2] - lo[2] == pytest.approx(4.0 * math.sin(0.5236) + 0.1 * math.cos(0.5236))
    pairs = {(p.a, p.b): p.material for p in s.contact_pairs()}
    assert pairs[("ball", "ramp")].friction == 0.25
    assert pairs[("ball", "marker")].collide is False
    # the worked example: rubber on the documented ground gives sqrt(0.9 x 0.1) and max(0.8, 0.2)
    assert pairs[("ball", "ground")].friction == pytest.approx(0.3)
    assert pairs[("ball", "ground")].restitution == 0.8


def test_material_classes_give_every_pair_the_rule_s_values_with_a_table_that_does_not_grow():
    """Adapters program engines from the class table, not from N^2 pairs: the table must give
    every pair exactly pair_material's values, and a pile of one material must stay one class."""
    from crosscheck.scene.contact import material_classes

    case = base3d()
    for k in range(12):  # more bodies of the existing materials, none named by an entry
        case["bodies"].append({"name": f"extra{k}", "shape": {"sphere": {"radius": 0.1}},
                               "mass": 1.0, "position": [float(k), 5.0, 1.0],
                               "material": ("rubber", "steel")[k % 2]})
    s = load(case)
    classes = material_classes(s)
    # ball, puck and wall are named by entries (own classes); steel (block, extras), rubber
    # (extras), the ground's: 6 classes for 16 surfaces
    assert classes.k == 6
    assert {len(m) for m in classes.members} == {1, 7, 6}
    listed = s.contact_pairs()
    assert len(listed) == 15 * 14 // 2 + 15 + 15
    for p in listed:
        assert classes.value(p.a, p.b) == pair_material(s, p.a, p.b), p
        assert classes.touches(p.a, p.b)
    # every touching pair is in exactly one class pair, and nothing fixed-fixed is
    from_classes = [frozenset(ab) for i, j in classes.class_pairs()
                    for ab in classes.pairs_between(i, j)]
    assert sorted(map(sorted, from_classes)) == sorted(sorted((p.a, p.b)) for p in listed)
    for i, j in classes.class_pairs():
        assert classes.count(i, j) == sum(1 for _ in classes.pairs_between(i, j))
    assert not classes.touches("wall", "ground")
    # a class is all bodies or all fixed surfaces: its members have the same pairs
    for i, members in enumerate(classes.members):
        assert {n in classes.fixed for n in members} == {classes.fixed_class(i)}
