"""Hypothesis: malformed case files never make the loader raise anything but CaseError, and any
file it accepts gives a physically valid Scene (finite positive masses, positive-definite finite
inertia, unit quaternions, finite state).

Malformed files are made three ways: valid case dicts mutated structurally (keys deleted,
unknown keys inserted, values replaced by values of other types / NaN / inf / negative / huge /
empty lists / nested tables, arrays truncated) and written by a small TOML serialiser; valid
TOML text cut and spliced; and random bytes. The ``[fluid]`` section has its own parser and
fuzz test beside it, so it is never inserted here.
"""

from __future__ import annotations

import copy
import math
import os
import tempfile
from pathlib import Path

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from toml_writer import to_toml  # tests/foundation/toml_writer.py

from crosscheck.errors import CaseError
from crosscheck.scene.loader import load_case, load_case_text
from crosscheck.scene.model import Scene

REPO = Path(__file__).resolve().parents[2]
BASE_DIR = REPO / "cases" / "rigid3d"  # so "../meshes/l_bracket.obj" resolves

# 150 + 150 + 30 examples, about 4 s; CROSSCHECK_FUZZ_EXAMPLES=3000 for a deeper search (~30 s).
FUZZ = settings(max_examples=int(os.environ.get("CROSSCHECK_FUZZ_EXAMPLES", "150")),
                deadline=2000,
                suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])


def test_serialiser_round_trips_through_tomllib():
    import tomllib

    case = {"a": {"b": [1, 2.5, -math.inf, "x\"y\\z\n\x7f", True, {"c": []}]}, "k.j": "é"}
    back = tomllib.loads(to_toml(case))
    assert back["k.j"] == "é"
    b = back["a"]["b"]
    assert b[:2] == [1, 2.5] and b[2] == -math.inf and b[3] == "x\"y\\z\n\x7f"
    assert b[4] is True and b[5] == {"c": []}
    assert math.isnan(tomllib.loads(to_toml({"n": math.nan}))["n"])


# -- valid starting points ------------------------------------------------------------------------
BASE_3D = {
    "case": {"name": "fuzz", "description": "d", "tags": ["t"], "dimension": 3},
    "run": {"duration": 1.0, "dt": 0.01, "sample_every": 0.1, "engines": ["inhouse", "mujoco"],
            "integrators": {"inhouse": ["rk4"]}, "timeout": 10.0},
    "effects": {"gravity": [0.0, 0.0, -9.81], "contact": False,
                "springs": [{"a": "a", "b": "b", "attach_a": [0.0, 0.0, 0.1],
                             "attach_b": [0.1, 0.0, 0.0], "stiffness": 10.0, "damping": 0.1,
                             "rest_length": 0.2},
                            {"a": "b", "anchor": [0.0, 0.0, 1.0], "stiffness": 5.0}],
                "drag": [{"linear": 0.1, "angular": 0.01, "bodies": ["a"]}],
                "loads": [{"body": "a", "force": [1.0, 0.0, 0.0], "torque": [0.0, 0.0, 1.0]}]},
    "materials": {"rubber": {"friction": 0.8, "restitution": 0.5}},
    "ground": {"normal": [0.0, 0.0, 1.0], "offset": 0.0, "material": "rubber"},
    "bodies": [
        {"name": "a", "shape": {"box": {"size": [0.1, 0.4, 0.9]}}, "mass": 10.0,
         "position": [0.0, 0.0, 0.0], "orientation": [1.0, 0.0, 0.0, 0.0],
         "velocity": [0.0, 0.0, 0.0], "angular_velocity": [0.01, 5.0, 0.0],
         "material": "rubber"},
        {"name": "b", "shape": {"cylinder": {"radius": 0.1, "length": 0.3}}, "density": 100.0,
         "position": [1.0, 0.0, 0.0], "orientation": {"axis": [0.0, 1.0, 0.0], "angle": 0.3},
         "com": [0.0, 0.0, 0.01],
         "inertia": [[0.03, 0.001, 0.0], [0.001, 0.02, 0.0], [0.0, 0.0, 0.04]]},
        {"name": "c", "shape": {"sphere": {"radius": 0.05}}, "mass": 1.0,
         "position": [0.0, 1.0, 0.0], "inertia": [0.001, 0.001, 0.001]},
        {"name": "d", "shape": {"capsule": {"radius": 0.05, "length": 0.2}}, "mass": 1.0,
         "position": [0.0, 2.0, 0.0]},
    ],
    "reference": {"kind": "analytic", "solution": "torque_free", "params": {"w": 1.0}},
    "tolerances": {"energy_drift": {"default": 0.05, "rk4": 1e-8, "mujoco.euler": 0.02},
                   "position_error_max": 0.001},
    "engine_options": {"pybullet": {"solver_iterations": 50}},
}

BASE_MESH = {
    "case": {"name": "mesh", "dimension": 3},
    "run": {"duration": 1.0, "dt": 0.01},
    "bodies": [{"name": "m", "shape": {"mesh": {"file": "../meshes/l_bracket.obj",
                                                "scale": 1.0}},
                "density": 2700.0, "position": [0.0, 0.0, 1.0]}],
}

BASE_2D = {
    "case": {"name": "flat", "dimension": 2},
    "run": {"duration": 1.0, "dt": 0.01},
    "effects": {"gravity": [0.0, -9.81],
                "springs": [{"a": "p", "anchor": [0.0, 1.0], "attach_a": [0.1, 0.0],
                             "stiffness": 3.0}],
                "loads": [{"body": "p", "force": [0.0, 1.0], "torque": 0.5}]},
    "ground": {"normal": [0.0, 1.0]},
    "bodies": [
        {"name": "p", "shape": {"polygon": {"vertices": [[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]]}},
         "mass": 1.0, "position": [0.0, 0.0], "orientation": 0.3, "angular_velocity": 1.0,
         "velocity": [1.0, 0.0]},
        {"name": "q", "shape": {"circle": {"radius": 0.1}}, "density": 10.0,
         "position": [1.0, 1.0], "inertia": 0.01},
        {"name": "r", "shape": {"box": {"size": [0.2, 0.1]}}, "mass": 2.0,
         "position": [2.0, 1.0], "com": [0.01, 0.0]},
    ],
}

BASE_CONTACT = {
    "case": {"name": "contact", "dimension": 3},
    "run": {"duration": 1.0, "dt": 0.01},
    "effects": {"gravity": [0.0, 0.0, -9.81], "contact": True},
    "materials": {"rubber": {"friction": 0.9, "restitution": 0.8, "rolling_friction": 0.001,
                             "torsional_friction": 0.002}},
    "ground": {"material": {"friction": 0.2}},
    "bodies": [
        {"name": "a", "shape": {"sphere": {"radius": 0.1}}, "mass": 1.0,
         "position": [0.0, 0.0, 1.0], "material": "rubber"},
        {"name": "b", "shape": {"box": {"size": [0.1, 0.2, 0.3]}}, "mass": 1.0,
         "position": [1.0, 0.0, 1.0], "material": {"restitution": 0.5}},
    ],
    "statics": [{"name": "s", "shape": {"mesh": {"file": "../meshes/l_bracket.obj"}},
                 "position": [0.0, 2.0, 0.0], "orientation": {"axis": [0.0, 0.0, 1.0],
                                                             "angle": 0.5},
                 "material": "rubber"},
                {"name": "t", "shape": {"capsule": {"radius": 0.1, "length": 1.0}},
                 "position": [0.0, -2.0, 0.0]}],
    "contact_pairs": [{"a": "a", "b": "s", "friction": 0.3, "torsional_friction": 0.0},
                      {"a": "b", "b": "a", "collide": False},
                      {"a": "ground", "b": "b", "restitution": 1.0}],
}

BASE_CONTACT_2D = {
    "case": {"name": "contact-2d", "dimension": 2},
    "run": {"duration": 1.0, "dt": 0.01},
    "effects": {"contact": True},
    "materials": {"wood": {"friction": 0.6, "rolling_friction": 0.01}},
    "ground": {"normal": [0.0, 1.0], "material": "wood"},
    "bodies": [{"name": "p", "shape": {"circle": {"radius": 0.1}}, "mass": 1.0,
                "position": [0.0, 1.0]}],
    "statics": [{"name": "w", "shape": {"polygon": {"vertices": [[0.0, 0.0], [1.0, 0.0],
                                                                  [0.0, 1.0]]}},
                 "position": [2.0, 0.0], "orientation": 0.2, "material": {"friction": 0.1}}],
    "contact_pairs": [{"a": "w", "b": "p", "rolling_friction": 0.0}],
}

BASES = [BASE_3D, BASE_2D, BASE_MESH, BASE_CONTACT, BASE_CONTACT_2D]

# keys that mean something somewhere in the format, so insertions make structurally plausible
# files (density next to mass, anchor next to b, ...), plus a few that mean nothing
KNOWN_KEYS = sorted({
    "case", "name", "description", "tags", "dimension", "run", "duration", "dt", "sample_every",
    "engines", "integrators", "timeout", "effects", "gravity", "contact", "springs", "a", "b",
    "attach_a", "attach_b", "anchor", "stiffness", "damping", "rest_length", "drag", "linear",
    "angular", "bodies", "loads", "body", "force", "torque", "materials", "friction",
    "restitution", "ground", "normal", "offset", "material", "shape", "box", "size", "sphere",
    "radius", "capsule", "length", "cylinder", "mesh", "file", "scale", "circle", "polygon",
    "vertices", "mass", "density", "inertia", "com", "position", "orientation", "axis", "angle",
    "velocity", "angular_velocity", "reference", "kind", "solution", "params", "engine",
    "integrator", "table", "tolerances", "default", "rk4", "mujoco", "mujoco.euler", "x.y",
    "engine_options", "pybullet", "inhouse", "pymunk", "masss", "", "statics",
    "contact_pairs", "rolling_friction", "torsional_friction", "collide",
})

scalars = st.one_of(
    st.booleans(),
    st.integers(min_value=-(2**63), max_value=2**63 - 1),
    st.sampled_from([0, -1, 1, 2, 3, 4]),
    st.floats(allow_nan=True, allow_infinity=True),
    st.sampled_from([0.0, -0.0, -1.0, 1e-300, 1e300, 1e308, -1e308, 5e-324, math.nan,
                     math.inf, -math.inf, 1.0 + 1e-7, 0.5]),
    st.text(max_size=6),
    st.sampled_from(["a", "b", "rubber", "default", "inhouse", "rk4", "analytic", "none",
                     "fine-step", "table", "engine", "../meshes/not_closed.obj",
                     "../meshes/l_bracket.obj", "../meshes", "", "\x00"]),
)
EXTREMES = st.one_of(
    st.sampled_from([0, 0.0, -0.0, -1.0, 1e-300, 1e300, 1e308, -1e308, 5e-324, 1e-200, 1e200,
                     math.nan, math.inf, -math.inf, 2**63 - 1, -(2**63)]),
    st.floats(allow_nan=False, allow_infinity=False),
)
values = st.recursive(
    scalars,
    lambda inner: st.one_of(st.lists(inner, max_size=5),
                            st.dictionaries(st.sampled_from(KNOWN_KEYS), inner, max_size=3)),
    max_leaves=8,
)


def _paths(node, prefix=()):
    """Every position in the tree: (path to container, key or index)."""
    if isinstance(node, dict):
        for k, v in node.items():
            yield prefix, k
            yield from _paths(v, prefix + (k,))
    elif isinstance(node, list):
        for i, v in enumerate(node):
            yield prefix, i
            yield from _paths(v, prefix + (i,))


def _containers(node, prefix=()):
    if isinstance(node, dict | list):
        yield prefix
        items = node.items() if isinstance(node, dict) else enumerate(node)
        for k, v in items:
            yield from _containers(v, prefix + (k,))


def _at(tree, path):
    for k in path:
        tree = tree[k]
    return tree


@st.composite
def mutated_cases(draw):
    case = copy.deepcopy(draw(st.sampled_from(BASES)))
    for _ in range(draw(st.integers(1, 4))):
        op = draw(st.sampled_from(["delete", "replace", "replace", "insert", "truncate",
                                   "empty", "number", "number"]))
        if op == "number":  # a number anywhere becomes an extreme one of the same sign rules
            leaves = [(p, k) for p, k in _paths(case)
                      if isinstance(_at(case, p)[k], int | float)
                      and not isinstance(_at(case, p)[k], bool)]
            if leaves:
                parent_path, key = draw(st.sampled_from(leaves))
                _at(case, parent_path)[key] = draw(EXTREMES)
            continue
        if op == "insert":
            where = _at(case, draw(st.sampled_from(list(_containers(case)))))
            if isinstance(where, dict):
                key = draw(st.one_of(st.sampled_from(KNOWN_KEYS), st.text(max_size=5)))
                if where is case and key == "fluid":
                    continue
                where[key] = draw(values)
            else:
                where.insert(draw(st.integers(0, len(where))), draw(values))
            continue
        paths = list(_paths(case))
        if not paths:
            break
        parent_path, key = draw(st.sampled_from(paths))
        parent = _at(case, parent_path)
        if op == "delete":
            del parent[key]
        elif op == "replace":
            parent[key] = draw(values)
        elif op == "truncate" and isinstance(parent[key], list):
            parent[key] = parent[key][: draw(st.integers(0, max(0, len(parent[key]) - 1)))]
        elif op == "empty":
            parent[key] = draw(st.sampled_from([[], {}, "", [[]], [{}]]))
    return case


def _check_valid(scene: Scene) -> None:
    """An accepted file must give a scene an engine can run."""
    assert scene.dimension in (2, 3)
    r = scene.run
    assert 0 < r.dt <= r.duration and 0 < r.sample_every <= r.duration and r.timeout > 0
    assert all(np.isfinite([r.dt, r.duration, r.sample_every]))
    for b in scene.bodies:
        assert np.isfinite(b.mass) and b.mass > 0, b
        d = scene.dimension
        for arr in (b.com, b.position, b.velocity, b.angular_velocity, b.orientation, b.inertia):
            assert np.all(np.isfinite(arr)), b
        assert b.position.shape == (d,) and b.velocity.shape == (d,) and b.com.shape == (d,)
        if d == 3:
            assert abs(np.linalg.norm(b.orientation) - 1.0) < 1e-9
            assert np.array_equal(b.inertia, b.inertia.T)
            assert np.linalg.eigvalsh(b.inertia / np.max(np.abs(b.inertia)))[0] > 0
        else:
            assert b.inertia.shape == (1, 1) and b.inertia[0, 0] > 0
    g = scene.effects.gravity
    assert g is None or (g.shape == (scene.dimension,) and np.all(np.isfinite(g)))
    for s in scene.effects.springs:
        assert s.stiffness > 0 and s.damping >= 0 and s.rest_length >= 0
        assert 0 <= s.body_a < len(scene.bodies)
        assert s.body_b is None or (0 <= s.body_b < len(scene.bodies) and s.body_b != s.body_a)
    def finite_plain(v):
        if isinstance(v, dict):
            return all(finite_plain(x) for x in v.values())
        if isinstance(v, list):
            return all(finite_plain(x) for x in v)
        return isinstance(v, str | int) or (isinstance(v, float) and math.isfinite(v))

    assert finite_plain(scene.reference.params) and finite_plain(scene.engine_options)
    if scene.ground is not None:
        assert abs(np.linalg.norm(scene.ground.normal) - 1.0) < 1e-12
    for st_ in scene.statics:
        assert st_.position.shape == (scene.dimension,)
        assert np.all(np.isfinite(st_.position)) and np.all(np.isfinite(st_.orientation))
    # every pair value an engine would be given is a finite, admissible number
    names = set(scene.body_names) | set(scene.static_names) | {"ground"}
    for p in scene.contact_pairs():
        m = p.material
        values = (m.friction, m.restitution, m.rolling_friction, m.torsional_friction)
        assert all(math.isfinite(v) and v >= 0 for v in values) and m.restitution <= 1, p
        assert p.a in scene.body_names and p.b in names and p.a != p.b


def _load_text(text: str) -> None:
    try:
        scene = load_case_text(text, name="fuzz.toml", base_dir=BASE_DIR)
    except CaseError as exc:
        assert str(exc).startswith("fuzz.toml")  # every refusal names the file
        return
    _check_valid(scene)


def test_the_starting_points_are_valid():
    for base in BASES:
        _check_valid(load_case_text(to_toml(base), base_dir=BASE_DIR))


@FUZZ
@given(mutated_cases())
def test_mutated_case_files_raise_only_case_errors(case):
    _load_text(to_toml(case))


@FUZZ
@given(st.sampled_from([BASE_3D, BASE_2D, BASE_CONTACT, BASE_CONTACT_2D]), st.data())
def test_cut_and_spliced_toml_raises_only_case_errors(base, data):
    text = to_toml(base)
    start = data.draw(st.integers(0, len(text)))
    stop = data.draw(st.integers(start, min(len(text), start + 40)))
    insert = data.draw(st.text(alphabet='[]{}=",.\n #abc01-+e', max_size=8))
    _load_text(text[:start] + insert + text[stop:])


@settings(max_examples=30, deadline=2000)
@given(st.binary(max_size=200))
def test_random_bytes_raise_only_case_errors(raw):
    fd, name = tempfile.mkstemp(suffix=".toml")
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(raw)
        try:
            load_case(name)
        except CaseError as exc:
            assert str(exc).startswith(name)
    finally:
        os.unlink(name)
