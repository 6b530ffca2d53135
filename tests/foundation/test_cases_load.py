"""Every case file under cases/ loads, and `crosscheck show --json` reports its numbers as they
follow from the file: masses, centres of mass and principal moments recomputed here from the raw
TOML (tomllib) and crosscheck.scene.massprops, not from the loader's Scene.
"""

from __future__ import annotations

import json
import math
import tomllib
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from crosscheck.cli import main
from crosscheck.scene import massprops
from crosscheck.scene.loader import find_cases, load_case

REPO = Path(__file__).resolve().parents[2]
CASE_FILES = find_cases([REPO / "cases"])
IDS = [str(p.relative_to(REPO / "cases")) for p in CASE_FILES]


def show_json(path: Path, capsys) -> dict:
    capsys.readouterr()
    assert main(["show", "--json", str(path)]) == 0
    out, err = capsys.readouterr()
    assert err == ""
    return json.loads(out)


def test_the_first_cases_of_the_foundation_issue_are_there():
    names = {load_case(p).name for p in CASE_FILES}
    assert {"free-fall", "projectile", "spring-anchor", "two-body-spring", "axisymmetric-top",
            "tennis-racket", "mesh-tumbling", "falling-box-2d"} <= names
    assert len(names) == len(CASE_FILES)  # case names are unique across the tree


def _expected_body(raw: dict, dimension: int, case_dir: Path) -> dict:
    """Mass, com (body frame), inertia about the com and world com, from the raw TOML."""
    (kind, params), = raw["shape"].items()
    if dimension == 3:
        if kind == "mesh":
            mesh = massprops.load_mesh(case_dir / params["file"])
            shape = lambda rho: massprops.mesh_mass_properties(  # noqa: E731
                np.asarray(mesh.vertices) * params.get("scale", 1.0), mesh.faces, rho)
        else:
            fn = {"box": lambda p, rho: massprops.box(p["size"], rho),
                  "sphere": lambda p, rho: massprops.sphere(p["radius"], rho),
                  "cylinder": lambda p, rho: massprops.cylinder(p["radius"], p["length"], rho),
                  "capsule": lambda p, rho: massprops.capsule(p["radius"], p["length"], rho),
                  }[kind]
            shape = lambda rho: fn(params, rho)  # noqa: E731
    else:
        fn = {"box": lambda p, rho: massprops.box2d(p["size"], rho),
              "circle": lambda p, rho: massprops.circle(p["radius"], rho),
              "polygon": lambda p, rho: massprops.polygon(p["vertices"], rho)}[kind]
        shape = lambda rho: fn(params, rho)  # noqa: E731
    if "density" in raw:
        props = shape(raw["density"])
    else:
        unit = shape(1.0)
        props = massprops.with_mass(unit, raw["mass"])
    com = np.array(raw.get("com", props.com), float)
    if "inertia" in raw:
        inertia = np.array(raw["inertia"], float)
        if dimension == 3 and inertia.ndim == 1:
            inertia = np.diag(inertia)
        inertia = np.atleast_2d(inertia)
    else:
        inertia = props.inertia if dimension == 3 else np.array([[props.moment]])
    # world com = position + R com
    if dimension == 3:
        o = raw.get("orientation", [1.0, 0.0, 0.0, 0.0])
        if isinstance(o, dict):
            axis = np.asarray(o["axis"], float)
            rot = Rotation.from_rotvec(axis / np.linalg.norm(axis) * o["angle"])
        else:
            rot = Rotation.from_quat([o[1], o[2], o[3], o[0]])
        r = rot.as_matrix()
    else:
        r = Rotation.from_euler("z", raw.get("orientation", 0.0)).as_matrix()[:2, :2]
    return {"mass": props.mass, "com": com, "inertia": inertia,
            "com_world": np.asarray(raw["position"], float) + r @ com}


@pytest.mark.parametrize("path", CASE_FILES, ids=IDS)
def test_case_loads_and_show_json_round_trips_its_numbers(path, capsys):
    raw = tomllib.loads(path.read_text())
    scene = load_case(path)
    data = show_json(path, capsys)
    assert data["name"] == raw["case"]["name"] == scene.name
    assert data["dimension"] == raw["case"]["dimension"]
    assert data["tags"] == raw["case"].get("tags", [])
    assert data["run"]["duration"] == raw["run"]["duration"]
    assert data["run"]["dt"] == raw["run"]["dt"]
    assert data["source"] == str(path)
    raw_bodies = raw.get("bodies", [])
    assert [b["name"] for b in data["bodies"]] == [b["name"] for b in raw_bodies]
    for body, rb in zip(data["bodies"], raw_bodies, strict=True):
        exp = _expected_body(rb, raw["case"]["dimension"], path.parent)
        assert body["mass"] == pytest.approx(exp["mass"], rel=1e-12)
        np.testing.assert_allclose(body["com"], exp["com"], rtol=1e-12, atol=1e-15)
        np.testing.assert_allclose(body["inertia"], exp["inertia"], rtol=1e-12, atol=1e-15)
        np.testing.assert_allclose(body["derived"]["com_world"], exp["com_world"], rtol=1e-12,
                                   atol=1e-14)
        np.testing.assert_allclose(body["position"], rb["position"], rtol=0, atol=0)
        if raw["case"]["dimension"] == 3:
            np.testing.assert_allclose(body["derived"]["principal_moments"],
                                       np.linalg.eigvalsh(exp["inertia"]), rtol=1e-12)
            # the principal axes printed diagonalise the inertia tensor, as a rotation
            axes = np.array(body["derived"]["principal_axes_body"])  # rows
            np.testing.assert_allclose(axes @ exp["inertia"] @ axes.T,
                                       np.diag(body["derived"]["principal_moments"]),
                                       rtol=0, atol=1e-12 * np.max(exp["inertia"]))
            assert np.linalg.det(axes) == pytest.approx(1.0, abs=1e-12)
            np.testing.assert_allclose(body["velocity"], rb.get("velocity", [0, 0, 0]))
            np.testing.assert_allclose(body["angular_velocity"],
                                       rb.get("angular_velocity", [0, 0, 0]))


@pytest.mark.parametrize("path", CASE_FILES, ids=IDS)
def test_case_shows_as_a_table(path, capsys):
    assert main(["show", str(path)]) == 0
    out = capsys.readouterr().out
    assert load_case(path).name in out


def test_tennis_racket_is_the_box_of_the_issue(capsys):
    data = show_json(REPO / "cases/rigid3d/tennis_racket.toml", capsys)
    (box,) = data["bodies"]
    assert box["mass"] == 10.0 and box["shape"]["size"] == [0.1, 0.4, 0.9]
    # I = m (b^2 + c^2) / 12 cyclically: 0.8083, 0.6833, 0.1417 kg m^2
    np.testing.assert_allclose(np.diag(box["inertia"]),
                               [10 * 0.97 / 12, 10 * 0.82 / 12, 10 * 0.17 / 12], rtol=1e-14)
    # spun at 5 rad/s about the middle (intermediate, y) axis, 0.01 rad/s perturbation
    assert box["angular_velocity"] == [0.01, 5.0, 0.0]
    moments = np.diag(box["inertia"])
    assert np.argsort(moments)[1] == 1
    assert data["effects"]["gravity"] is None


def test_mesh_case_has_an_off_origin_com_and_a_non_diagonal_inertia(capsys):
    data = show_json(REPO / "cases/rigid3d/mesh_tumbling.toml", capsys)
    (b,) = data["bodies"]
    # L profile 0.3 x 0.2 with 0.04 walls, 0.1 deep: V = (0.3*0.04 + 0.16*0.04) * 0.1 m^3
    assert b["mass"] == pytest.approx(2700.0 * (0.3 * 0.04 + 0.16 * 0.04) * 0.1, rel=1e-12)
    assert np.linalg.norm(b["com"]) > 0.05
    assert b["derived"]["inertia_diagonal_in_body_frame"] is False
    assert b["shape"]["kind"] == "mesh" and b["shape"]["file"].endswith("l_bracket.obj")


def test_two_body_spring_is_isolated_and_2d_box_is_2d(capsys):
    spring = load_case(REPO / "cases/rigid3d/two_body_spring.toml")
    assert spring.effects.names() == ("springs",)  # no gravity, no drag, no loads
    assert spring.effects.springs[0].body_b == 1
    box = load_case(REPO / "cases/rigid2d/falling_box.toml")
    assert box.dimension == 2 and box.bodies[0].angular_velocity[0] != 0
    assert math.isclose(box.effects.gravity[1], -9.81)


def _toml_blocks(markdown: str) -> list[str]:
    parts = markdown.split("```toml\n")[1:]
    return [p.split("```", 1)[0] for p in parts]


def test_the_annotated_example_in_docs_is_the_tennis_racket_case():
    from crosscheck.scene.loader import load_case_text

    blocks = _toml_blocks((REPO / "docs" / "cases.md").read_text())
    doc = load_case_text(blocks[0], name="docs/cases.md")
    real = load_case(REPO / "cases/rigid3d/tennis_racket.toml")
    for field in ("name", "description", "tags", "dimension", "run", "reference", "tolerances",
                  "engine_options", "ground", "materials"):
        assert getattr(doc, field) == getattr(real, field), field
    assert doc.effects.names() == real.effects.names() == ()
    (a,), (b,) = doc.bodies, real.bodies
    assert (a.name, a.mass, a.shape.kind) == (b.name, b.mass, b.shape.kind)
    for field in ("com", "inertia", "position", "orientation", "velocity", "angular_velocity"):
        np.testing.assert_array_equal(getattr(a, field), getattr(b, field))
    # the tolerance example of the docs is valid inside a case, with the documented precedence
    example = next(b for b in blocks[1:] if b.lstrip().startswith("[tolerances]"))
    tol = load_case_text(blocks[0].split("[tolerances]")[0] + example).tolerances
    assert tol["position_error_max"].limit("pybullet", "maximal") == 1e-3
    e = tol["energy_drift"]
    assert (e.limit("mujoco", "euler"), e.limit("mujoco", "rk4"), e.limit("mujoco", "implicit"),
            e.limit("pybullet", "maximal")) == (2e-2, 1e-8, 1e-2, 5e-2)
