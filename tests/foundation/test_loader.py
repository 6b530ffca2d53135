"""The case loader: every key of the format understood with its unit and default, and every kind
of bad input refused with exactly one CaseError naming the file, the exact field path and what
was expected.

Cases are built as Python dicts (a valid 3D and a valid 2D case using every key), mutated, and
written to TOML by a tiny serialiser, so each bad-input test changes exactly one thing.
"""

from __future__ import annotations

import copy
import dataclasses
import hashlib
import math
import shutil
from pathlib import Path

import numpy as np
import pytest
from toml_writer import to_toml  # tests/foundation/toml_writer.py

from crosscheck.errors import CaseError
from crosscheck.names import INTEGRATOR_NAMES, all_integrator_names
from crosscheck.scene import massprops
from crosscheck.scene.loader import find_cases, is_case_file, load_case, load_case_text
from crosscheck.scene.model import ENGINE_NAMES, Scene, Tolerance

REPO = Path(__file__).resolve().parents[2]
CASES = REPO / "cases"
MESHES = CASES / "meshes"
NAME = "my_case.toml"  # the file name every error message must carry


def load(case: dict, name: str = NAME, base_dir: Path = CASES / "rigid3d") -> Scene:
    return load_case_text(to_toml(case), name=name, base_dir=base_dir)


# -- valid cases using every key ----------------------------------------------------------------
def base3d() -> dict:
    return {
        "case": {"name": "every-key", "description": "all keys", "tags": ["a", "b"],
                 "dimension": 3},
        "run": {"duration": 2.0, "dt": 1e-3, "sample_every": 0.01,
                "engines": ["inhouse", "mujoco"],
                "integrators": {"inhouse": ["rk4", "verlet"], "mujoco": ["euler"]},
                "timeout": 30.0},
        "effects": {
            "gravity": [0.0, 0.0, -9.81],
            "contact": False,
            "springs": [
                {"a": "ball", "attach_a": [0.0, 0.0, 0.1], "b": "box",
                 "attach_b": [0.1, 0.0, 0.0], "stiffness": 100.0, "damping": 0.5,
                 "rest_length": 0.3},
                {"a": "box", "anchor": [0.0, 0.0, 2.0], "stiffness": 10.0},
            ],
            "drag": [{"linear": 0.1, "angular": 0.01, "bodies": ["ball"]}, {"linear": 0.2}],
            "loads": [{"body": "ball", "force": [1.0, 0.0, 0.0], "torque": [0.0, 0.0, 0.5]}],
        },
        "materials": {"rubber": {"friction": 0.8, "restitution": 0.5}, "ice": {}},
        "ground": {"normal": [0.0, 0.0, 2.0], "offset": -1.0, "material": "ice"},
        "bodies": [
            {"name": "ball", "shape": {"sphere": {"radius": 0.1}}, "density": 1000.0,
             "position": [0.0, 0.0, 1.0], "material": "rubber"},
            {"name": "rod", "shape": {"capsule": {"radius": 0.05, "length": 0.4}}, "mass": 1.0,
             "position": [1.0, 0.0, 1.0], "orientation": {"axis": [0.0, 1.0, 1.0],
                                                           "angle": 0.7}},
            {"name": "box", "shape": {"box": {"size": [0.1, 0.4, 0.9]}}, "mass": 10.0,
             "position": [0.0, 1.0, 0.0], "orientation": [1.0, 0.0, 0.0, 0.0],
             "velocity": [0.1, 0.2, 0.3], "angular_velocity": [0.01, 5.0, 0.0]},
            {"name": "can", "shape": {"cylinder": {"radius": 0.2, "length": 0.1}},
             "mass": 2.0, "position": [2.0, 0.0, 0.0], "com": [0.0, 0.0, 0.01],
             "inertia": [[0.03, 0.001, 0.0], [0.001, 0.02, 0.0], [0.0, 0.0, 0.04]]},
            {"name": "bracket", "shape": {"mesh": {"file": "../meshes/l_bracket.obj",
                                                   "scale": 2.0}},
             "density": 2700.0, "position": [0.0, 0.0, 3.0]},
        ],
        "reference": {"kind": "fine-step", "engine": "inhouse", "integrator": "rk4",
                      "dt": 1e-4, "params": {"omega": 10.0, "label": "x", "list": [1, 2]}},
        "tolerances": {"energy_drift": {"default": 5e-2, "rk4": 1e-8, "mujoco.euler": 2e-2},
                       "position_error_max": 1e-3},
        "engine_options": {"pybullet": {"solver_iterations": 50}},
    }


def base2d() -> dict:
    return {
        "case": {"name": "flat", "dimension": 2},
        "run": {"duration": 1.0, "dt": 1e-3},
        "effects": {
            "gravity": [0.0, -9.81],
            "springs": [{"a": "disc", "attach_a": [0.1, 0.0], "anchor": [0.0, 2.0],
                         "stiffness": 5.0}],
            "loads": [{"body": "tri", "force": [0.0, 1.0], "torque": 0.25}],
        },
        "bodies": [
            {"name": "disc", "shape": {"circle": {"radius": 0.1}}, "density": 10.0,
             "position": [0.0, 1.0]},
            {"name": "plate", "shape": {"box": {"size": [0.2, 0.1]}}, "mass": 1.0,
             "position": [1.0, 1.0], "orientation": 0.3, "velocity": [1.0, 3.0],
             "angular_velocity": 4.0, "inertia": 0.05},
            {"name": "tri", "shape": {"polygon": {"vertices": [[0.0, 0.0], [0.0, 1.0],
                                                               [1.0, 0.0]]}},
             "mass": 3.0, "position": [2.0, 0.0], "com": [0.1, 0.2]},
        ],
    }


# -- mutation helpers ---------------------------------------------------------------------------
def _parse_path(path: str) -> list:
    """'bodies[2].shape.box.size[1]' -> ['bodies', 2, 'shape', 'box', 'size', 1]."""
    out: list = []
    for part in path.split("."):
        name, *idx = part.replace("]", "").split("[")
        if name:
            out.append(name)
        out.extend(int(i) for i in idx)
    return out


def _parent(case, path):
    keys = _parse_path(path)
    node = case
    for k in keys[:-1]:
        node = node[k]
    return node, keys[-1]


def setting(path: str, value):
    def mutate(case):
        node, key = _parent(case, path)
        node[key] = value
    return mutate


def deleting(path: str):
    def mutate(case):
        node, key = _parent(case, path)
        del node[key]
    return mutate


def updating(path: str, **values):
    def mutate(case):
        node, key = _parent(case, path)
        node[key].update(values)
    return mutate


def both(*mutations):
    def mutate(case):
        for m in mutations:
            m(case)
    return mutate


def refused(case: dict, field: str, expected: str, *, name: str = NAME,
            base_dir: Path = CASES / "rigid3d") -> CaseError:
    """Assert loading ``case`` raises one CaseError at exactly ``field`` mentioning ``expected``."""
    with pytest.raises(CaseError) as info:
        load(case, name=name, base_dir=base_dir)
    exc = info.value
    message = str(exc)
    assert exc.file == name
    assert exc.field == field, message
    assert message.startswith(f"{name}: {field}: expected " if field else f"{name}: expected ")
    assert expected in exc.expected, message
    assert "\n" not in message  # one line: the CLI prints it as 'error: ...'
    return exc


# -- the valid cases, key by key ------------------------------------------------------------------
def test_every_key_of_a_3d_case_is_understood_with_its_units():
    s = load(base3d())
    assert (s.name, s.description, s.tags, s.dimension) == ("every-key", "all keys",
                                                             ("a", "b"), 3)
    r = s.run
    assert (r.duration, r.dt, r.sample_every, r.timeout) == (2.0, 1e-3, 0.01, 30.0)
    assert r.engines == ("inhouse", "mujoco")
    assert r.integrators == {"inhouse": ("rk4", "verlet"), "mujoco": ("euler",)}
    assert s.integrators_for("mujoco") == ("euler",) and s.integrators_for("pybullet") == ()
    assert r.n_samples() == 201 and np.allclose(r.sample_times()[[0, -1]], [0.0, 2.0])

    e = s.effects
    np.testing.assert_array_equal(e.gravity, [0.0, 0.0, -9.81])
    assert e.contact is False and e.fluid is False
    assert e.names() == ("gravity", "springs", "drag", "loads")
    names = s.body_names
    assert names == ("ball", "rod", "box", "can", "bracket")
    sp, anchor = e.springs
    assert (sp.body_a, sp.body_b) == (0, 2)
    np.testing.assert_array_equal(sp.attach_a, [0, 0, 0.1])
    np.testing.assert_array_equal(sp.attach_b, [0.1, 0, 0])
    assert (sp.stiffness, sp.damping, sp.rest_length) == (100.0, 0.5, 0.3)
    # a world anchor: body_b is None and attach_b holds the world point; defaults 0
    assert (anchor.body_a, anchor.body_b) == (2, None)
    np.testing.assert_array_equal(anchor.attach_b, [0, 0, 2.0])
    np.testing.assert_array_equal(anchor.attach_a, [0, 0, 0])
    assert (anchor.damping, anchor.rest_length) == (0.0, 0.0)
    d1, d2 = e.drag
    assert (d1.linear, d1.angular, d1.bodies) == (0.1, 0.01, (0,))
    assert (d2.linear, d2.angular, d2.bodies) == (0.2, 0.0, (0, 1, 2, 3, 4))  # default: all
    (ld,) = e.loads
    assert ld.body == 0
    np.testing.assert_array_equal(ld.force, [1, 0, 0])
    np.testing.assert_array_equal(ld.torque, [0, 0, 0.5])

    # materials: the implicit default plus the declared ones; an empty table takes defaults
    assert s.materials["default"].friction == 0.5 and s.materials["default"].restitution == 0.0
    assert (s.materials["rubber"].friction, s.materials["rubber"].restitution) == (0.8, 0.5)
    assert (s.materials["ice"].friction, s.materials["ice"].restitution) == (0.5, 0.0)
    assert s.bodies[0].material.name == "rubber" and s.bodies[1].material.name == "default"
    # ground normal is normalised
    np.testing.assert_array_equal(s.ground.normal, [0, 0, 1.0])
    assert s.ground.offset == -1.0 and s.ground.material.name == "ice"

    ref = s.reference
    assert (ref.kind, ref.engine, ref.integrator, ref.dt, ref.solution, ref.table) == (
        "fine-step", "inhouse", "rk4", 1e-4, None, None)
    assert ref.params == {"omega": 10.0, "label": "x", "list": [1, 2]}
    assert s.engine_options == {"pybullet": {"solver_iterations": 50}}
    tol = s.tolerances["energy_drift"]
    assert (tol.metric, tol.default, tol.overrides) == ("energy_drift", 5e-2,
                                                        {"rk4": 1e-8, "mujoco.euler": 2e-2})
    assert s.tolerances["position_error_max"] == Tolerance("position_error_max", 1e-3, {})


def test_body_defaults_and_initial_state():
    s = load(base3d())
    ball, rod, box = s.bodies[:3]
    # defaults: identity orientation, zero velocities, default material
    np.testing.assert_array_equal(ball.orientation, [1, 0, 0, 0])
    np.testing.assert_array_equal(ball.velocity, [0, 0, 0])
    np.testing.assert_array_equal(ball.angular_velocity, [0, 0, 0])
    np.testing.assert_array_equal(box.velocity, [0.1, 0.2, 0.3])
    np.testing.assert_array_equal(box.angular_velocity, [0.01, 5.0, 0.0])
    np.testing.assert_array_equal(box.position, [0, 1, 0])
    assert (ball.mass_source, box.mass_source) == ("density", "given")
    assert box.inertia_source == "shape" and s.bodies[3].inertia_source == "given"


def test_a_2d_case_uses_scalars_for_angles_spins_and_moments():
    s = load(base2d())
    assert s.dimension == 2
    disc, plate, tri = s.bodies
    assert plate.orientation.shape == (1,) and plate.angle == 0.3
    assert plate.angular_velocity.shape == (1,) and plate.angular_velocity[0] == 4.0
    assert plate.inertia.shape == (1, 1) and plate.moment == 0.05
    assert disc.angle == 0.0 and disc.angular_velocity[0] == 0.0
    np.testing.assert_array_equal(plate.velocity, [1, 3])
    # 2D density is per area (kg/m^2): disc mass = rho pi r^2, J = m r^2 / 2
    m = 10.0 * math.pi * 0.1**2
    assert disc.mass == pytest.approx(m, rel=1e-14)
    assert disc.moment == pytest.approx(0.5 * m * 0.01, rel=1e-14)
    # triangle (0,0),(0,1),(1,0): centroid (1/3, 1/3); the case offsets the com
    np.testing.assert_array_equal(tri.com, [0.1, 0.2])
    # given mass 3 on a right triangle with legs 1: J about centroid = m (a^2 + b^2) / 18
    assert tri.moment == pytest.approx(3.0 * 2.0 / 18.0, rel=1e-12)
    # the clockwise vertex list was stored counter-clockwise (positive signed area)
    v = tri.shape.vertices
    assert 0.5 * np.sum(v[:, 0] * np.roll(v[:, 1], -1) - np.roll(v[:, 0], -1) * v[:, 1]) > 0
    (ld,) = s.effects.loads
    assert ld.torque.shape == (1,) and ld.torque[0] == 0.25
    np.testing.assert_array_equal(s.effects.gravity, [0, -9.81])
    (sp,) = s.effects.springs
    np.testing.assert_array_equal(sp.attach_a, [0.1, 0.0])
    assert s.ground is None


def test_2d_box_density_is_per_area():
    case = base2d()
    case["bodies"][1].pop("mass")
    case["bodies"][1].pop("inertia")
    case["bodies"][1]["density"] = 50.0
    plate = load(case).bodies[1]
    m = 50.0 * 0.2 * 0.1
    assert plate.mass == pytest.approx(m, rel=1e-14)
    assert plate.moment == pytest.approx(m * (0.2**2 + 0.1**2) / 12, rel=1e-14)


def test_run_defaults():
    case = base3d()
    for key in ("sample_every", "engines", "integrators", "timeout"):
        del case["run"][key]
    del case["case"]["description"]
    del case["case"]["tags"]
    s = load(case)
    assert s.run.sample_every == s.run.dt == 1e-3  # default: every step
    assert s.run.engines == ENGINE_NAMES  # default: all four
    assert s.run.integrators == {} and s.integrators_for("inhouse") == ()  # engine defaults
    assert s.run.timeout == 600.0
    assert s.description == "" and s.tags == ()


def test_absent_sections_take_their_defaults():
    case = base3d()
    for key in ("effects", "materials", "ground", "reference", "tolerances", "engine_options"):
        del case[key]
    del case["bodies"][0]["material"]
    s = load(case)
    assert s.effects.gravity is None and s.effects.names() == ()
    np.testing.assert_array_equal(s.effects.gravity_vector(3), [0, 0, 0])
    assert s.ground is None
    assert s.reference.kind == "none" and s.reference.params == {}
    assert s.tolerances == {} and s.engine_options == {}
    assert list(s.materials) == ["default"]


def test_ground_defaults_to_the_up_plane_through_the_origin():
    case = base3d()
    case["ground"] = {}
    g = load(case).ground
    np.testing.assert_array_equal(g.normal, [0, 0, 1])
    assert g.offset == 0.0 and g.material.name == "default"
    case2 = base2d()
    case2["ground"] = {}
    np.testing.assert_array_equal(load(case2).ground.normal, [0, 1])


def test_axis_angle_and_quaternion_give_the_same_orientation():
    a = load(base3d()).bodies[1].orientation
    half = 0.35
    expected = [math.cos(half), 0.0, math.sin(half) / math.sqrt(2), math.sin(half) / math.sqrt(2)]
    np.testing.assert_allclose(a, expected, rtol=0, atol=1e-15)
    case = base3d()
    case["bodies"][1]["orientation"] = [float(x) for x in expected]
    np.testing.assert_allclose(load(case).bodies[1].orientation, a, rtol=0, atol=1e-15)
    # the axis need not be unit length
    case["bodies"][1]["orientation"] = {"axis": [0.0, 3.0, 3.0], "angle": 0.7}
    np.testing.assert_allclose(load(case).bodies[1].orientation, a, rtol=0, atol=1e-15)


def test_quaternion_within_tolerance_is_normalised():
    case = base3d()
    case["bodies"][2]["orientation"] = [1.0 + 5e-7, 0.0, 0.0, 0.0]
    q = load(case).bodies[2].orientation
    assert np.linalg.norm(q) == pytest.approx(1.0, abs=1e-15)


def test_density_and_mass_give_the_same_body():
    rho, size = 700.0, [0.1, 0.4, 0.9]
    case = base3d()
    case["bodies"][2].pop("mass")
    case["bodies"][2]["density"] = rho
    by_density = load(case).bodies[2]
    m = rho * 0.1 * 0.4 * 0.9
    case["bodies"][2].pop("density")
    case["bodies"][2]["mass"] = m
    by_mass = load(case).bodies[2]
    assert by_density.mass == pytest.approx(m, rel=1e-14)
    assert by_mass.mass == m
    np.testing.assert_allclose(by_mass.inertia, by_density.inertia, rtol=1e-13, atol=0)
    a, b, c = size  # closed form: I_xx = m (b^2 + c^2) / 12, cyclically
    expected = np.diag([b * b + c * c, a * a + c * c, a * a + b * b]) * m / 12
    np.testing.assert_allclose(by_mass.inertia, expected, rtol=1e-13, atol=1e-16)


def test_sphere_density_is_per_volume():
    ball = load(base3d()).bodies[0]
    m = 1000.0 * 4.0 / 3.0 * math.pi * 0.1**3
    assert ball.mass == pytest.approx(m, rel=1e-14)
    np.testing.assert_allclose(ball.inertia, np.eye(3) * 0.4 * m * 0.01, rtol=1e-14)
    np.testing.assert_array_equal(ball.com, [0, 0, 0])


def test_com_offset_keeps_the_shapes_inertia_about_the_com():
    case = base3d()
    plain = load(case).bodies[2]
    case["bodies"][2]["com"] = [0.02, -0.1, 0.3]
    case["bodies"][2]["orientation"] = {"axis": [0.0, 0.0, 1.0], "angle": math.pi / 2}
    shifted = load(case).bodies[2]
    np.testing.assert_array_equal(shifted.inertia, plain.inertia)
    np.testing.assert_array_equal(shifted.com, [0.02, -0.1, 0.3])
    assert shifted.mass == plain.mass
    # the com in the world: body-frame origin + R com; R is +90 deg about z: (x, y) -> (-y, x)
    np.testing.assert_allclose(shifted.com_world(), [0.1, 1.02, 0.3], atol=1e-15)


def test_explicit_full_inertia_is_kept_exactly():
    can = load(base3d()).bodies[3]
    np.testing.assert_array_equal(can.inertia, [[0.03, 0.001, 0.0], [0.001, 0.02, 0.0],
                                                [0.0, 0.0, 0.04]])
    assert can.mass == 2.0
    np.testing.assert_array_equal(can.com, [0, 0, 0.01])
    case = base3d()
    case["bodies"][3]["inertia"] = [0.3, 0.2, 0.4]
    np.testing.assert_array_equal(load(case).bodies[3].inertia, np.diag([0.3, 0.2, 0.4]))


def test_inertia_triangle_equality_is_accepted():
    # a flat plate has I1 + I2 = I3 exactly: the limit of the triangle inequality is valid
    case = base3d()
    case["bodies"][3]["inertia"] = [1.0, 2.0, 3.0]
    np.testing.assert_array_equal(load(case).bodies[3].inertia, np.diag([1.0, 2.0, 3.0]))


def test_mesh_resolves_relative_to_the_case_file_and_scales(tmp_path):
    # load_case: relative to the file's folder, wherever the process runs
    (tmp_path / "sub").mkdir()
    (tmp_path / "meshes").mkdir()
    shutil.copy(MESHES / "l_bracket.obj", tmp_path / "meshes" / "l_bracket.obj")
    case_file = tmp_path / "sub" / "c.toml"
    case_file.write_text(to_toml(base3d()))
    s = load_case(case_file)
    bracket = s.bodies[4]
    assert bracket.shape.path == (tmp_path / "meshes" / "l_bracket.obj").resolve()
    assert bracket.shape.path.is_absolute() and bracket.shape.scale == 2.0
    raw = massprops.load_mesh(MESHES / "l_bracket.obj")
    np.testing.assert_array_equal(bracket.shape.vertices, np.asarray(raw.vertices) * 2.0)
    np.testing.assert_array_equal(bracket.shape.faces, raw.faces)
    # density: mass properties of the scaled mesh (volume x 8)
    exact = massprops.mesh_mass_properties(np.asarray(raw.vertices) * 2.0, raw.faces, 2700.0)
    assert bracket.mass == pytest.approx(exact.mass, rel=1e-12)
    assert bracket.mass == pytest.approx(
        8 * massprops.mesh_mass_properties(raw.vertices, raw.faces, 2700.0).mass, rel=1e-12)
    np.testing.assert_allclose(bracket.com, exact.com, rtol=1e-12)
    np.testing.assert_allclose(bracket.inertia, exact.inertia, rtol=1e-12, atol=1e-18)
    # the L-bracket is rotated in its file: its inertia is not diagonal in the body frame
    assert abs(bracket.inertia[0, 1]) > 1e-3 * bracket.inertia[0, 0]
    # the same text elsewhere: the mesh is not found, and the error names the resolved path
    exc = refused(base3d(), "bodies[4].shape.mesh.file", "closed", base_dir=tmp_path)
    assert str((tmp_path.parent / "meshes" / "l_bracket.obj").resolve()) in str(exc)
    assert "not found" in str(exc)


def test_source_and_hash_identify_the_file(tmp_path):
    f = tmp_path / "x.toml"
    f.write_text(to_toml(base2d()))
    s = load_case(f)
    assert s.source == f
    assert s.source_sha256 == hashlib.sha256(f.read_bytes()).hexdigest()
    t = load_case_text(to_toml(base2d()))
    assert t.source_sha256 == s.source_sha256


# -- tolerances -----------------------------------------------------------------------------------
def test_tolerance_precedence_engine_integrator_then_integrator_then_engine_then_default():
    case = base3d()
    case["tolerances"] = {"m": {"default": 1.0, "rk4": 2.0, "mujoco": 3.0, "mujoco.rk4": 4.0},
                          "n": {"rk4": 2.0, "mujoco": 3.0}, "o": 0.5}
    tol = load(case).tolerances
    m = tol["m"]
    assert m.limit("mujoco", "rk4") == 4.0  # engine.integrator wins
    assert m.limit("inhouse", "rk4") == 2.0  # then the integrator
    assert m.limit("mujoco", "euler") == 3.0  # then the engine
    assert m.limit("pybullet", "multibody") == 1.0  # then the default
    n = tol["n"]
    assert n.default is None
    assert n.limit("mujoco", "rk4") == 2.0  # integrator beats engine
    assert n.limit("pymunk", "euler") is None  # no limit at all
    assert tol["o"].limit("mujoco", "rk4") == 0.5 and tol["o"].overrides == {}


# -- integrator names -----------------------------------------------------------------------------
# A misspelt integrator used to load and then run as a "not applicable" cell: a regression gate
# passed without the check it was asked for. Names are now checked at load against
# crosscheck.names.INTEGRATOR_NAMES (kept equal to the adapters' by
# test_integrator_names.py); whether a known name applies to the scene stays a run-time verdict.
@pytest.mark.parametrize("engine", ENGINE_NAMES)
def test_a_misspelt_integrator_is_refused_under_every_engine(engine):
    known = INTEGRATOR_NAMES[engine]
    case = base3d()
    case["run"]["integrators"] = {"inhouse": ["rk4"], engine: [known[0], known[0] + "x"]}
    exc = refused(case, f"run.integrators.{engine}[1]", f"an integrator of {engine}, one of")
    assert exc.got == known[0] + "x"
    # The message lists that engine's names, and only those.
    assert exc.expected == f"an integrator of {engine}, one of {list(known)}"
    assert str(exc) == (f"{NAME}: run.integrators.{engine}[1]: expected an integrator of "
                        f"{engine}, one of {list(known)}, got {known[0] + 'x'!r} (str)")


def test_every_known_integrator_of_every_engine_loads():
    case = base3d()
    case["run"]["engines"] = list(ENGINE_NAMES)
    case["run"]["integrators"] = {e: list(n) for e, n in INTEGRATOR_NAMES.items()}
    case["tolerances"] = {"m": {"default": 1.0, **{f"{e}.{n}": 2.0 for e, names
                                                   in INTEGRATOR_NAMES.items() for n in names}},
                          "n": {n: 1.0 for n in all_integrator_names()}}
    s = load(case)
    assert s.run.integrators == INTEGRATOR_NAMES
    assert s.tolerances["m"].limit("pymunk", "position_first") == 2.0
    assert s.tolerances["n"].limit("pybullet", "maximal") == 1.0


def test_a_known_integrator_that_does_not_apply_still_loads_and_is_not_applicable_at_run_time():
    # A fluid scheme on a rigid case and Pymunk (2D only) on a 3D case are names the engines
    # know: the case loads and the adapter says why it cannot run them.
    from crosscheck.engines import get_engine

    case = base3d()
    case["run"]["integrators"] = {"inhouse": ["maccormack"], "pymunk": ["position_first"]}
    s = load(case)
    assert s.run.integrators["inhouse"] == ("maccormack",)
    reason = get_engine("inhouse").not_applicable(s, "maccormack")
    assert reason and "maccormack" in reason
    assert get_engine("pymunk").not_applicable(s, "position_first") == "pymunk is 2D"


def test_reference_integrator_names():
    case = base3d()
    for kind, integrator in (("fine-step", "dop853"), ("fine-step", "DOP853"),
                             ("fine-step", "RK4"), ("fine-step", "verlet")):
        case["reference"] = {"kind": kind, "integrator": integrator}
        # fine-step runs the lower-cased name (crosscheck.reference.spec), on inhouse
        assert load(case).reference.integrator == integrator
    case["reference"] = {"kind": "fine-step", "engine": "mujoco", "integrator": "implicitfast"}
    assert load(case).reference.engine == "mujoco"
    case["reference"] = {"kind": "fine-step", "engine": "mujoco", "integrator": "verlet"}
    exc = refused(case, "reference.integrator", "an integrator of mujoco, one of ['euler'")
    assert "'dop853'" in exc.expected  # fine-step also accepts SciPy's DOP853
    case["reference"] = {"kind": "engine", "engine": "pybullet", "integrator": "maximal"}
    assert load(case).reference.integrator == "maximal"
    case["reference"] = {"kind": "engine", "engine": "pybullet", "integrator": "maximum"}
    exc = refused(case, "reference.integrator", "an integrator of pybullet")
    assert exc.expected == "an integrator of pybullet, one of ['multibody', 'maximal']"
    # Kinds that run no engine ignore the integrator; it must still be some engine's name.
    case["reference"] = {"kind": "analytic", "solution": "free_fall", "integrator": "euler"}
    assert load(case).reference.integrator == "euler"


def test_tolerance_keys_name_known_integrators():
    case = base3d()
    case["tolerances"] = {"m": {"rk4": 1.0, "mujoco": 2.0, "semi_lagrangian": 3.0,
                                "pybullet.multibody": 4.0}}
    assert load(case).tolerances["m"].limit("pybullet", "multibody") == 4.0
    case["tolerances"] = {"m": {"default": 1.0, "inhouse.euler": 1.0}}  # MuJoCo's, not ours
    exc = refused(case, 'tolerances.m."inhouse.euler"', "an integrator of inhouse, one of")
    assert exc.got == "unknown key 'inhouse.euler'"
    case["tolerances"] = {"m": {"default": 1.0, "verlett": 1.0}}
    exc = refused(case, "tolerances.m.verlett", "an engine name")
    for name in ("verlet", "euler", "multibody", "position_first", "maccormack"):
        assert repr(name) in exc.expected


def test_unchecked_engines_accept_the_names_of_an_adapter_standing_in_for_them():
    # crosscheck run --engine-ref inhouse=module:Class: the stand-in brings its own names.
    case = base3d()
    case["run"]["integrators"] = {"inhouse": ["exact"], "mujoco": ["rk4"]}
    case["reference"] = {"kind": "fine-step", "engine": "inhouse", "integrator": "exact"}
    case["tolerances"] = {"m": {"exact": 1.0, "inhouse.exact": 2.0}}
    text = to_toml(case)
    s = load_case_text(text, name=NAME, base_dir=CASES / "rigid3d", unchecked_engines={"inhouse"})
    assert s.run.integrators["inhouse"] == ("exact",)
    assert s.tolerances["m"].limit("inhouse", "exact") == 2.0
    case["reference"] = {"kind": "none", "integrator": "exact"}  # no engine: any may know it
    load_case_text(to_toml(case), name=NAME, base_dir=CASES / "rigid3d",
                   unchecked_engines={"inhouse"})
    del case["reference"]["integrator"]
    with pytest.raises(CaseError) as info:  # without it, the name is refused
        load_case_text(text, name=NAME, base_dir=CASES / "rigid3d")
    assert info.value.field == "run.integrators.inhouse[0]"
    # Other engines are still checked.
    case["run"]["integrators"]["mujoco"] = ["exact"]
    with pytest.raises(CaseError) as info:
        load_case_text(to_toml(case), name=NAME, base_dir=CASES / "rigid3d",
                       unchecked_engines={"inhouse"})
    assert info.value.field == "run.integrators.mujoco[0]"


# -- immutability ---------------------------------------------------------------------------------
def _arrays(obj, path="scene"):
    if isinstance(obj, np.ndarray):
        yield path, obj
    elif dataclasses.is_dataclass(obj):
        for f in dataclasses.fields(obj):
            yield from _arrays(getattr(obj, f.name), f"{path}.{f.name}")
    elif isinstance(obj, dict):
        for k, v in obj.items():
            yield from _arrays(v, f"{path}[{k!r}]")
    elif isinstance(obj, list | tuple):
        for i, v in enumerate(obj):
            yield from _arrays(v, f"{path}[{i}]")


@pytest.mark.parametrize("make", [base3d, base2d])
def test_scene_and_its_arrays_are_immutable(make):
    scene = load(make())
    with pytest.raises(dataclasses.FrozenInstanceError):
        scene.name = "other"
    with pytest.raises(dataclasses.FrozenInstanceError):
        scene.bodies[0].mass = 2.0
    with pytest.raises(dataclasses.FrozenInstanceError):
        scene.run.dt = 1.0
    with pytest.raises(dataclasses.FrozenInstanceError):
        scene.effects.springs[0].stiffness = 1.0
    arrays = list(_arrays(scene))
    assert len(arrays) > 20  # the walk really reached the bodies, effects and ground
    for path, arr in arrays:
        with pytest.raises(ValueError, match="read-only"):
            arr.flat[0] = 123.0
        assert not arr.flags.writeable, path


# -- finding case files ---------------------------------------------------------------------------
def test_find_cases_skips_toml_that_is_not_a_case_but_keeps_broken_ones(tmp_path):
    (tmp_path / "pyproject.toml").write_text('[project]\nname = "x"\n')
    (tmp_path / "a").mkdir()
    (tmp_path / "a" / "good.toml").write_text(to_toml(base2d()))
    (tmp_path / "a" / "broken.toml").write_text("[case\nname=")
    (tmp_path / "notes.txt").write_text("[case]")
    assert not is_case_file(tmp_path / "pyproject.toml")
    assert is_case_file(tmp_path / "a" / "broken.toml")  # so load_case can say what is wrong
    assert find_cases([tmp_path]) == [tmp_path / "a" / "broken.toml", tmp_path / "a" / "good.toml"]
    assert find_cases([tmp_path / "notes.txt"]) == [tmp_path / "notes.txt"]  # files as given


# -- bad input ------------------------------------------------------------------------------------
def _tables(node, path=""):
    """Every table of a case with its field path, except free-form ones (metric names,
    override keys, material names, solution parameters, engine options)."""
    if isinstance(node, dict):
        if path not in ("tolerances", "materials", "reference.params", "engine_options") \
                and not path.startswith(("tolerances.", "engine_options.")):
            yield path
        for k, v in node.items():
            yield from _tables(v, f"{path}.{k}" if path else k)
    elif isinstance(node, list):
        for i, v in enumerate(node):
            yield from _tables(v, f"{path}[{i}]")


_TYPO_TABLES = [(make, p) for make in (base3d, base2d) for p in _tables(make())]


@pytest.mark.parametrize(("make", "table"), _TYPO_TABLES,
                         ids=[f"{m.__name__}:{p or 'top'}" for m, p in _TYPO_TABLES])
def test_an_unknown_key_is_refused_at_every_level(make, table):
    case = make()
    node = case
    for k in _parse_path(table) if table else []:
        node = node[k]
    node["colour"] = 1.0
    if table.endswith(".shape"):  # shape = { box = {...}, colour = 1 }: exactly one kind
        refused(case, table, "a table with exactly one of")
    elif table == "run.integrators":  # keys there are engine names
        refused(case, "run.integrators.colour", "an engine name")
    else:
        field = f"{table}.colour" if table else "colour"
        exc = refused(case, field, "one of the known keys")
        assert "unknown key 'colour'" in str(exc)


def test_typo_error_lists_optional_keys_that_were_absent():
    case = base3d()
    case["bodies"][0]["inertai"] = [1.0, 1.0, 1.0]
    exc = refused(case, "bodies[0].inertai", "one of the known keys")
    for key in ("inertia", "com", "mass", "density", "orientation", "angular_velocity"):
        assert repr(key) in exc.expected
    case = base3d()
    case["reference"]["solutoin"] = "x"
    exc = refused(case, "reference.solutoin", "known keys")
    assert "'solution'" in exc.expected and "'table'" in exc.expected


def test_a_mistyped_required_key_is_named_in_the_missing_field_error():
    case = base3d()
    case["run"]["dtt"] = case["run"].pop("dt")
    exc = refused(case, "run.dt", "required field")
    assert "'dtt' a typo" in str(exc)
    case = base3d()
    case["bodies"][2]["postion"] = case["bodies"][2].pop("position")
    assert "'postion' a typo" in str(refused(case, "bodies[2].position", "required"))
    case = base3d()
    case["bodies"][2]["masss"] = case["bodies"][2].pop("mass")
    assert "'masss' a typo" in str(refused(case, "bodies[2].mass", "exactly one of mass"))


def _mesh_body(file, **extra):
    return setting("bodies[4].shape", {"mesh": {"file": file, **extra}})


BAD_3D = [
    # [case]
    (deleting("case"), "case", "required"),
    (setting("case", 5), "case", "a table"),
    (setting("case.name", 5), "case.name", "a string"),
    (setting("case.name", "  "), "case.name", "a non-empty name"),
    (deleting("case.name"), "case.name", "required"),
    (deleting("case.dimension"), "case.dimension", "required"),
    (setting("case.dimension", 4), "case.dimension", "2 or 3"),
    (setting("case.dimension", 3.0), "case.dimension", "an integer"),
    (setting("case.dimension", True), "case.dimension", "an integer"),
    (setting("case.tags", "rigid"), "case.tags", "an array of strings"),
    (setting("case.tags", ["a", 1]), "case.tags", "an array of strings"),
    (setting("case.description", ["x"]), "case.description", "a string"),
    # [run]
    (deleting("run"), "run", "required"),
    (deleting("run.duration"), "run.duration", "required"),
    (deleting("run.dt"), "run.dt", "required"),
    (setting("run.dt", 0.0), "run.dt", "a positive number in s"),
    (setting("run.dt", -1e-3), "run.dt", "a positive number in s"),
    (setting("run.dt", "1e-3"), "run.dt", "a number in s"),
    (setting("run.dt", math.inf), "run.dt", "a finite number in s"),
    (setting("run.duration", math.nan), "run.duration", "a finite number in s"),
    (setting("run.duration", -math.inf), "run.duration", "a finite number in s"),
    (setting("run.dt", 3.0), "run.dt", "no longer than run.duration"),
    (setting("run.sample_every", 0.0), "run.sample_every", "a positive number"),
    (setting("run.sample_every", 5.0), "run.sample_every", "no longer than run.duration"),
    (setting("run.engines", "mujoco"), "run.engines", "an array of strings"),
    (setting("run.engines", ["inhouse", "mujocoo"]), "run.engines[1]", "one of"),
    (setting("run.integrators", {"mujocoo": ["rk4"]}), "run.integrators.mujocoo",
     "an engine name"),
    (setting("run.integrators", {"mujoco": []}), "run.integrators.mujoco",
     "at least one integrator"),
    (setting("run.integrators", {"mujoco": "rk4"}), "run.integrators.mujoco",
     "an array of strings"),
    (setting("run.integrators", ["rk4"]), "run.integrators", "a table"),
    (setting("run.integrators.mujoco", ["euler", "rk5"]), "run.integrators.mujoco[1]",
     "an integrator of mujoco, one of ['euler', 'rk4', 'implicit', 'implicitfast', 'discrete', "
     "'euler+inertia_box'"),
    (setting("run.integrators.mujoco", ["verlet"]), "run.integrators.mujoco[0]",
     "an integrator of mujoco"),  # an in-house name is not one of MuJoCo's
    (setting("run.integrators.inhouse", ["RK4"]), "run.integrators.inhouse[0]",
     "an integrator of inhouse"),  # names are case-sensitive, as the adapters compare them
    (setting("run.timeout", 0), "run.timeout", "a positive number"),
    # [materials], [ground]
    (setting("materials.rubber.friction", -0.1), "materials.rubber.friction", "non-negative"),
    (setting("materials.rubber.restitution", 1.5), "materials.rubber.restitution",
     "between 0 and 1"),
    (setting("materials.rubber", 0.5), "materials.rubber", "a table"),
    (setting("ground.normal", [0.0, 0.0, 0.0]), "ground.normal", "a non-zero normal"),
    (setting("ground.normal", [0.0, 1.0]), "ground.normal", "an array of 3"),
    (setting("ground.offset", math.nan), "ground.offset", "a finite number"),
    (setting("ground.material", "steel"), "ground.material", "a material defined under"),
    # bodies: presence, names
    (deleting("bodies"), "bodies", "at least one [[bodies]] entry"),
    (setting("bodies", []), "bodies", "at least one [[bodies]] entry"),
    (setting("bodies", [1, 2]), "bodies", "an array of tables"),
    (deleting("bodies[1].name"), "bodies[1].name", "required"),
    (setting("bodies[3].name", "ball"), "bodies[3].name", "a name no other body has"),
    # shapes
    (deleting("bodies[2].shape"), "bodies[2].shape", "required"),
    (setting("bodies[2].shape", "box"), "bodies[2].shape", "a table"),
    (setting("bodies[2].shape", {"cube": {"size": [1.0, 1.0, 1.0]}}), "bodies[2].shape",
     "exactly one of ['box', 'capsule', 'cylinder', 'mesh', 'sphere']"),
    (setting("bodies[2].shape", {}), "bodies[2].shape", "exactly one of"),
    (setting("bodies[2].shape", {"box": {"size": [1.0, 1.0, 1.0]},
                                 "sphere": {"radius": 1.0}}), "bodies[2].shape",
     "exactly one of"),
    (setting("bodies[2].shape.box", [1.0, 1.0, 1.0]), "bodies[2].shape.box", "a table"),
    (setting("bodies[2].shape.box.size", [0.1, 0.4]), "bodies[2].shape.box.size",
     "an array of 3 positive finite numbers in m"),
    (setting("bodies[2].shape.box.size", "big"), "bodies[2].shape.box.size",
     "an array of 3 positive finite numbers in m"),
    (setting("bodies[2].shape.box.size[1]", -0.4), "bodies[2].shape.box.size[1]",
     "a positive number in m"),
    (setting("bodies[2].shape.box.size[2]", 0), "bodies[2].shape.box.size[2]",
     "a positive number in m"),
    (setting("bodies[2].shape.box.size[0]", math.nan), "bodies[2].shape.box.size[0]",
     "a finite number in m"),
    (setting("bodies[2].shape.box.size[0]", math.inf), "bodies[2].shape.box.size[0]",
     "a finite number in m"),
    (setting("bodies[2].shape.box.size[0]", "0.1"), "bodies[2].shape.box.size[0]",
     "a number in m"),
    (deleting("bodies[2].shape.box.size"), "bodies[2].shape.box.size", "required"),
    (setting("bodies[0].shape.sphere.radius", 0.0), "bodies[0].shape.sphere.radius",
     "a positive number in m"),
    (setting("bodies[0].shape.sphere.radius", -1.0), "bodies[0].shape.sphere.radius",
     "a positive number in m"),
    (setting("bodies[1].shape.capsule.length", 0.0), "bodies[1].shape.capsule.length",
     "a positive number in m"),
    (deleting("bodies[3].shape.cylinder.radius"), "bodies[3].shape.cylinder.radius",
     "required"),
    (setting("bodies[2].shape", {"box": {"size": [1e200, 1e200, 1e200]}}), "bodies[2].shape",
     "finite"),  # the volume overflows
    (setting("bodies[0].shape.sphere.radius", 1e-200), "bodies[0].shape", "finite"),
    # meshes
    (_mesh_body("../meshes/not_closed.obj"), "bodies[4].shape.mesh.file", "closed"),
    (_mesh_body("../meshes/missing.obj"), "bodies[4].shape.mesh.file", "closed"),
    (_mesh_body("../meshes/l_bracket.obj", scale=0.0), "bodies[4].shape.mesh.scale",
     "a positive number"),
    (_mesh_body("../meshes/l_bracket.obj", scale=1e300), "bodies[4].shape", "finite"),
    (_mesh_body("a\x00b.obj"), "bodies[4].shape.mesh.file", "a file path"),
    (_mesh_body(5), "bodies[4].shape.mesh.file", "a string"),
    # mass / density
    (setting("bodies[2].mass", 0.0), "bodies[2].mass", "a positive number in kg"),
    (setting("bodies[2].mass", -10.0), "bodies[2].mass", "a positive number in kg"),
    (setting("bodies[2].mass", math.nan), "bodies[2].mass", "a finite number in kg"),
    (setting("bodies[2].mass", "10"), "bodies[2].mass", "a number in kg"),
    (setting("bodies[2].mass", True), "bodies[2].mass", "a number in kg"),
    (setting("bodies[2].density", 1.0), "bodies[2].mass", "exactly one of mass"),
    (deleting("bodies[2].mass"), "bodies[2].mass", "exactly one of mass"),
    (setting("bodies[0].density", 0.0), "bodies[0].density", "a positive number in kg/m^3"),
    # state
    (deleting("bodies[2].position"), "bodies[2].position", "required"),
    (setting("bodies[2].position", [0.0, 0.0]), "bodies[2].position", "an array of 3"),
    (setting("bodies[2].position", [0.0, 0.0, math.inf]), "bodies[2].position[2]",
     "a finite number in m"),
    (setting("bodies[2].velocity", [0.0, math.nan, 0.0]), "bodies[2].velocity[1]",
     "a finite number in m/s"),
    (setting("bodies[2].angular_velocity", 5.0), "bodies[2].angular_velocity",
     "an array of 3 finite numbers in rad/s"),
    (setting("bodies[2].angular_velocity", [[1.0], 0.0, 0.0]), "bodies[2].angular_velocity[0]",
     "a number"),
    # orientation
    (setting("bodies[2].orientation", [1.0, 0.0, 0.0, 0.1]), "bodies[2].orientation",
     "a unit quaternion [w, x, y, z]"),
    (setting("bodies[2].orientation", [2.0, 0.0, 0.0, 0.0]), "bodies[2].orientation",
     "a unit quaternion"),
    (setting("bodies[2].orientation", [0.0, 0.0, 0.0, 0.0]), "bodies[2].orientation",
     "a unit quaternion"),
    (setting("bodies[2].orientation", [1.0, 0.0, 0.0]), "bodies[2].orientation",
     "an array of 4"),
    (setting("bodies[2].orientation", [1.0, 0.0, 0.0, math.nan]), "bodies[2].orientation[3]",
     "a finite number"),
    (setting("bodies[2].orientation", 0.3), "bodies[2].orientation", "an array of 4"),
    (setting("bodies[1].orientation.axis", [0.0, 0.0, 0.0]), "bodies[1].orientation.axis",
     "a non-zero axis"),
    (deleting("bodies[1].orientation.angle"), "bodies[1].orientation.angle", "required"),
    (setting("bodies[1].orientation.angle", math.nan), "bodies[1].orientation.angle",
     "a finite number in rad"),
    (setting("bodies[1].orientation.axis", [1.0, 0.0]), "bodies[1].orientation.axis",
     "an array of 3"),
    # com and inertia
    (setting("bodies[3].com", [0.0, 0.0]), "bodies[3].com", "an array of 3"),
    (setting("bodies[3].com", [0.0, math.inf, 0.0]), "bodies[3].com[1]", "a finite number"),
    (setting("bodies[3].inertia", [1.0, 1.0, -1.0]), "bodies[3].inertia[2]",
     "a positive number in kg m^2"),
    (setting("bodies[3].inertia", [1.0, 1.0, 0.0]), "bodies[3].inertia[2]", "a positive number"),
    (setting("bodies[3].inertia", [1.0, 1.0, 3.0]), "bodies[3].inertia",
     "triangle inequality I1 + I2 >= I3"),
    (setting("bodies[3].inertia", [[1.0, 0.5, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]),
     "bodies[3].inertia", "a symmetric 3x3 tensor"),
    (setting("bodies[3].inertia", [[1.0, 2.0, 0.0], [2.0, 1.0, 0.0], [0.0, 0.0, 1.0]]),
     "bodies[3].inertia", "a positive definite inertia tensor"),  # eigenvalues -1, 1, 3
    (setting("bodies[3].inertia", [[0.0] * 3] * 3), "bodies[3].inertia", "positive definite"),
    # principal moments (1, 1, 3) of a rotated diagonal tensor: a full tensor is checked too
    (setting("bodies[3].inertia", [[2.0, 1.0, 0.0], [1.0, 2.0, 0.0], [0.0, 0.0, 1.0]]),
     "bodies[3].inertia", "triangle inequality"),
    (setting("bodies[3].inertia", [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0]]),
     "bodies[3].inertia[2]", "an array of 3"),
    (setting("bodies[3].inertia", [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, math.nan]]),
     "bodies[3].inertia[2][2]", "a finite number"),
    (setting("bodies[3].inertia", 1.0), "bodies[3].inertia", "an array of 3"),
    (setting("bodies[0].material", "steel"), "bodies[0].material",
     "a material defined under [materials]"),
    # [effects]
    (setting("effects", [1]), "effects", "a table"),
    (setting("effects.gravity", [0.0, -9.81]), "effects.gravity", "an array of 3"),
    (setting("effects.gravity", [0.0, 0.0, math.nan]), "effects.gravity[2]", "a finite number"),
    (setting("effects.contact", "yes"), "effects.contact", "true or false"),
    (setting("effects.springs", {"a": "ball"}), "effects.springs", "an array of tables"),
    (setting("effects.springs[0].a", "ghost"), "effects.springs[0].a", "the name of a body"),
    (deleting("effects.springs[0].a"), "effects.springs[0].a", "required"),
    (setting("effects.springs[0].b", "ghost"), "effects.springs[0].b", "the name of a body"),
    (setting("effects.springs[0].b", "ball"), "effects.springs[0].b", "a body other than a"),
    (setting("effects.springs[0].anchor", [0.0, 0.0, 0.0]), "effects.springs[0].b",
     "exactly one of b (a body) or anchor"),
    (deleting("effects.springs[1].anchor"), "effects.springs[1].b", "exactly one of b"),
    (setting("effects.springs[1].attach_b", [0.0, 0.0, 0.0]), "effects.springs[1].attach_b",
     "known keys"),  # attach_b belongs to a body b, not to an anchor
    (setting("effects.springs[0].stiffness", 0.0), "effects.springs[0].stiffness",
     "a positive number in N/m"),
    (deleting("effects.springs[0].stiffness"), "effects.springs[0].stiffness", "required"),
    (setting("effects.springs[0].damping", -1.0), "effects.springs[0].damping",
     "a non-negative number in N s/m"),
    (setting("effects.springs[0].rest_length", -0.3), "effects.springs[0].rest_length",
     "a non-negative number in m"),
    (setting("effects.springs[1].anchor", [0.0, 0.0]), "effects.springs[1].anchor",
     "an array of 3"),
    (setting("effects.springs[0].attach_a", [0.0, math.inf, 0.0]),
     "effects.springs[0].attach_a[1]", "a finite number"),
    (setting("effects.drag[0].linear", -0.1), "effects.drag[0].linear", "non-negative"),
    (setting("effects.drag[1].angular", math.nan), "effects.drag[1].angular", "finite"),
    (setting("effects.drag[0].bodies", ["ball", "ghost"]), "effects.drag[0].bodies[1]",
     "the name of a body"),
    (setting("effects.loads[0].body", "ghost"), "effects.loads[0].body", "the name of a body"),
    (setting("effects.loads[0].force", [1.0, 0.0]), "effects.loads[0].force",
     "an array of 3 finite numbers in N"),
    (setting("effects.loads[0].torque", 0.5), "effects.loads[0].torque", "an array of 3"),
    # [reference]
    (setting("reference.kind", "magic"), "reference.kind", "one of"),
    (both(setting("reference.kind", "analytic")), "reference.solution",
     "required when reference.kind = 'analytic'"),
    (setting("reference", {"kind": "table"}), "reference.table", "required when"),
    (setting("reference", {"kind": "engine"}), "reference.engine", "required when"),
    (setting("reference.engine", "bullet"), "reference.engine", "one of"),
    (setting("reference.dt", 0.0), "reference.dt", "a positive number in s"),
    (setting("reference.params", 3), "reference.params", "a table"),
    (setting("reference.integrator", "rk5"), "reference.integrator",
     "an integrator of inhouse, one of ['rk4'"),
    (setting("reference", {"kind": "engine", "engine": "mujoco", "integrator": "verlet"}),
     "reference.integrator", "an integrator of mujoco"),
    (setting("reference", {"kind": "engine", "engine": "inhouse", "integrator": "dop853"}),
     "reference.integrator", "an integrator of inhouse"),  # DOP853 is a fine-step reference
    (setting("reference", {"kind": "none", "integrator": "rk5"}), "reference.integrator",
     "an integrator name of some engine"),
    (setting("reference.params.omega", math.nan), "reference.params.omega", "a finite number"),
    (setting("reference.params.list", [1.0, math.inf]), "reference.params.list[1]",
     "a finite number"),
    # [tolerances]
    (setting("tolerances.energy_drift", -1.0), "tolerances.energy_drift", "non-negative"),
    (setting("tolerances.energy_drift", "tight"), "tolerances.energy_drift", "a number"),
    (setting("tolerances.energy_drift", math.nan), "tolerances.energy_drift", "finite"),
    (setting("tolerances.energy_drift", {}), "tolerances.energy_drift",
     "a limit, or a table with default and overrides"),
    (setting("tolerances.energy_drift.default", math.inf), "tolerances.energy_drift.default",
     "a finite number"),
    (setting("tolerances.energy_drift.rk4", -1e-8), "tolerances.energy_drift.rk4",
     "non-negative"),
    (setting("tolerances.energy_drift.rk4", {"x": 1.0}), "tolerances.energy_drift.rk4",
     "a number"),
    (setting("tolerances.energy_drift", {"default": 1.0, "mujcoo.euler": 1.0}),
     'tolerances.energy_drift."mujcoo.euler"', "'engine.integrator' with an engine in"),
    (setting("tolerances.energy_drift", {"default": 1.0, "mujoco.": 1.0}),
     'tolerances.energy_drift."mujoco."', "'engine.integrator'"),
    (setting("tolerances.energy_drift", {"default": 1.0, "mujoco.rk5": 1.0}),
     'tolerances.energy_drift."mujoco.rk5"', "'mujoco.integrator' with an integrator of mujoco"),
    (setting("tolerances.energy_drift", {"default": 1.0, "pybullet.rk4": 1.0}),
     'tolerances.energy_drift."pybullet.rk4"', "one of ['multibody', 'maximal']"),
    (setting("tolerances.energy_drift", {"default": 1.0, "rk5": 1.0}),
     "tolerances.energy_drift.rk5", "an integrator name of some engine"),
    # [engine_options], top level
    (setting("engine_options", {"bullet": {}}), "engine_options.bullet", "an engine name"),
    (setting("engine_options.pybullet", 5), "engine_options.pybullet", "a table"),
    (setting("engine_options.pybullet.erp", math.nan), "engine_options.pybullet.erp",
     "a finite number"),
    (setting("bodys", []), "bodys", "one of the known keys"),
]


@pytest.mark.parametrize(("mutate", "field", "expected"), BAD_3D,
                         ids=[f"{i}:{f}" for i, (_, f, _) in enumerate(BAD_3D)])
def test_bad_3d_input_is_refused_at_its_field(mutate, field, expected):
    case = copy.deepcopy(base3d())
    mutate(case)
    refused(case, field, expected)


BAD_2D = [
    (setting("bodies[0].shape", {"sphere": {"radius": 1.0}}), "bodies[0].shape",
     "exactly one of ['box', 'circle', 'polygon']"),
    (setting("bodies[1].shape.box.size", [0.2, 0.1, 0.1]), "bodies[1].shape.box.size",
     "an array of 2"),
    (setting("bodies[0].shape.circle.radius", 0.0), "bodies[0].shape.circle.radius",
     "a positive number in m"),
    (setting("bodies[2].shape.polygon.vertices", [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0],
                                                  [0.9, 0.1], [0.0, 1.0]]),
     "bodies[2].shape.polygon.vertices", "a convex polygon"),
    (setting("bodies[2].shape.polygon.vertices", [[0.0, 0.0], [1.0, 0.0]]),
     "bodies[2].shape.polygon.vertices", "an array of at least 3 [x, y] points"),
    (setting("bodies[2].shape.polygon.vertices", [[0.0, 0.0], [1.0, 0.0], [2.0, 0.0]]),
     "bodies[2].shape.polygon.vertices", "a polygon with non-zero area"),
    (setting("bodies[2].shape.polygon.vertices[1]", [0.0, math.nan]),
     "bodies[2].shape.polygon.vertices[1][1]", "a finite number in m"),
    (setting("bodies[2].shape.polygon.vertices[1]", [0.0, 1.0, 0.0]),
     "bodies[2].shape.polygon.vertices[1]", "an array of 2"),
    (setting("bodies[1].orientation", [1.0, 0.0, 0.0, 0.0]), "bodies[1].orientation",
     "a number in rad"),
    (setting("bodies[1].orientation", {"axis": [0.0, 0.0, 1.0], "angle": 1.0}),
     "bodies[1].orientation", "a number in rad"),
    (setting("bodies[1].angular_velocity", [0.0, 0.0, 1.0]), "bodies[1].angular_velocity",
     "a number in rad/s"),
    (setting("bodies[1].inertia", [1.0, 1.0, 1.0]), "bodies[1].inertia", "a number in kg m^2"),
    (setting("bodies[1].inertia", 0.0), "bodies[1].inertia", "a positive number"),
    (setting("bodies[1].velocity", [1.0, 3.0, 0.0]), "bodies[1].velocity", "an array of 2"),
    (setting("bodies[0].density", -1.0), "bodies[0].density", "a positive number in kg/m^2"),
    (setting("bodies[0].position", [0.0, 1.0, 0.0]), "bodies[0].position", "an array of 2"),
    (setting("effects.gravity", [0.0, 0.0, -9.81]), "effects.gravity", "an array of 2"),
    (setting("effects.loads[0].torque", [0.0, 0.0, 1.0]), "effects.loads[0].torque",
     "a number in N m"),
    (setting("effects.springs[0].anchor", [0.0, 2.0, 0.0]), "effects.springs[0].anchor",
     "an array of 2"),
]


@pytest.mark.parametrize(("mutate", "field", "expected"), BAD_2D,
                         ids=[f"{i}:{f}" for i, (_, f, _) in enumerate(BAD_2D)])
def test_bad_2d_input_is_refused_at_its_field(mutate, field, expected):
    case = copy.deepcopy(base2d())
    mutate(case)
    refused(case, field, expected)


def test_the_got_part_shows_the_offending_value():
    case = base3d()
    case["bodies"][2]["shape"]["box"]["size"][1] = -0.4
    exc = refused(case, "bodies[2].shape.box.size[1]", "positive")
    assert str(exc) == (f"{NAME}: bodies[2].shape.box.size[1]: expected a positive number in m, "
                        "got -0.4 (float)")


def test_quaternion_error_reports_its_length():
    case = base3d()
    case["bodies"][2]["orientation"] = [1.0, 0.0, 0.0, 0.1]
    exc = refused(case, "bodies[2].orientation", "unit quaternion")
    assert "|q| = 1.00499" in str(exc)


def test_only_the_first_of_several_errors_is_reported():
    case = base3d()
    case["run"]["dt"] = -1.0
    case["bodies"][0]["masss"] = 1.0
    refused(case, "run.dt", "positive")


def test_toml_syntax_error_names_the_file_and_the_line():
    lines = to_toml(base3d()).splitlines()
    lines.insert(2, "oops = = 1")  # line 3
    with pytest.raises(CaseError) as info:
        load_case_text("\n".join(lines), name=NAME)
    exc = info.value
    assert exc.file == NAME and exc.field == ""
    assert str(exc).startswith(f"{NAME}: expected valid TOML (")
    assert "line 3" in str(exc)


def test_duplicate_toml_key_is_a_syntax_error():
    text = '[case]\nname = "a"\nname = "b"\n'
    with pytest.raises(CaseError, match=r"^x\.toml: expected valid TOML"):
        load_case_text(text, name="x.toml")


def test_missing_file_and_non_utf8_file(tmp_path):
    missing = tmp_path / "nope.toml"
    with pytest.raises(CaseError) as info:
        load_case(missing)
    assert str(info.value).startswith(f"{missing}: expected a readable case file")
    latin = tmp_path / "latin.toml"
    latin.write_bytes(b'[case]\nname = "caf\xe9"\n')
    with pytest.raises(CaseError) as info:
        load_case(latin)
    assert str(info.value) == f"{latin}: expected a UTF-8 text file"


def test_load_case_errors_name_the_path_given(tmp_path):
    case = base3d()
    case["bodies"][2]["shape"]["box"]["size"] = [0.1, 0.0, 0.9]
    f = tmp_path / "bad.toml"
    f.write_text(to_toml(case))
    with pytest.raises(CaseError) as info:
        load_case(f)
    assert str(info.value).startswith(f"{f}: bodies[2].shape.box.size[1]: expected a positive")


def test_the_committed_not_closed_mesh_is_refused():
    case = base3d()
    case["bodies"][4]["shape"] = {"mesh": {"file": "../meshes/not_closed.obj"}}
    exc = refused(case, "bodies[4].shape.mesh.file", "a mesh file that is a closed")
    assert "not_closed.obj" in str(exc) and "open edges" in str(exc)


def test_fine_step_reference_may_leave_its_step_to_the_comparer():
    # Without reference.dt the comparer runs the reference at run.dt / FINE_STEP_FACTOR.
    from crosscheck.reference.spec import FINE_STEP_FACTOR
    from crosscheck.scene.loader import load_case_text

    scene = load_case_text("""
[case]
name = "x"
dimension = 3
[run]
duration = 1.0
dt = 1e-3
[[bodies]]
name = "b"
shape = { sphere = { radius = 0.1 } }
mass = 1.0
position = [0, 0, 0]
[reference]
kind = "fine-step"
engine = "inhouse"
""")
    assert scene.reference.kind == "fine-step" and scene.reference.dt is None
    assert FINE_STEP_FACTOR >= 10  # a reference that is not much finer would not be one
