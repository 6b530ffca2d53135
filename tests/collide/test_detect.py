"""The detection as the contact models see it: geometry compiled from a scene (colliders, hulls,
material classes from the pair rule), rows (a a body, b -1 for fixed geometry), the pair's values,
collide = false, overflow never silent, bit-identical repeats, feature keys stable while the same
features touch."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from collide_scenes import STEEL, body, scene, state3d, static

from crosscheck.scene.contact import pair_material
from crosscheck.scene.loader import load_case
from crosscheck.scene.model import Material
from crosscheck.scene.shapes import Box, Sphere
from crosscheck.sim.collide import (
    Geometry2D,
    Geometry3D,
    compile_geometry,
    contact_capacity,
    detect2d,
    detect3d,
    new_contacts,
)
from crosscheck.sim.collide.geometry import BOX, HULL, SPHERE

ROOT = Path(__file__).resolve().parents[2]
ICE = Material("ice", friction=0.05, restitution=0.1)
RUBBER = Material("rubber", friction=1.0, restitution=0.8, rolling_friction=0.01)


def rows_of(c):
    return [(int(c.a[k]), int(c.b[k]), c.normal[k].copy(), c.point[k].copy(), float(c.depth[k]),
             float(c.friction[k]), float(c.restitution[k]), int(c.feature[k]))
            for k in range(c.n)]


def test_geometry_of_every_contact_case_compiles():
    for path in sorted((ROOT / "cases" / "contact").glob("*.toml")):
        sc = load_case(path)
        g = compile_geometry(sc)
        assert isinstance(g, Geometry3D if sc.dimension == 3 else Geometry2D)
        assert g.n_bodies == len(sc.bodies)
        assert len(g.kind) == len(sc.bodies) + len(sc.statics)
        c = new_contacts(g)
        if sc.dimension == 3:
            x = np.array([b.com_world() for b in sc.bodies])
            q = np.array([b.orientation for b in sc.bodies])
            detect3d(g, x, q, c)
        else:
            x = np.array([b.com_world() for b in sc.bodies])
            a = np.array([b.angle for b in sc.bodies])
            detect2d(g, x, a, c)
        assert not c.overflowed(), path.name


def test_mesh_case_is_its_convex_hull_and_offsets_are_minus_com():
    sc = load_case(ROOT / "cases" / "contact" / "mesh_landing.toml")
    g = compile_geometry(sc)
    assert g.kind[0] == HULL
    np.testing.assert_allclose(g.frame_pos[0], -sc.bodies[0].com)
    p = g.polytope[0]
    v = g.vertices[g.poly_vert_start[p]:g.poly_vert_start[p] + g.poly_vert_count[p]]
    f0, nf = g.poly_face_start[p], g.poly_face_count[p]
    # convex: every vertex on or below every face plane; closed: V - E + F = 2
    dist = v @ g.face_normal[f0:f0 + nf].T - g.face_offset[f0:f0 + nf]
    assert dist.max() < 1e-12
    assert g.poly_vert_count[p] - g.poly_edge_count[p] + nf == 2
    # the L bracket's hull has quadrilateral and larger faces (coplanar triangles merged)
    assert g.face_vert_count[f0:f0 + nf].max() >= 4


def test_pair_table_by_material_class_uses_the_pair_rule():
    bodies = [body(f"s{i}", Sphere(0.1), [3.0 * i, 0, 1.0],
                   material=[STEEL, ICE, RUBBER][i % 3]) for i in range(5000)]
    sc = scene(bodies, [static("wall", Box(np.array([1.0, 1.0, 1.0])), [0, 5, 0],
                               material=ICE)],
               ground=([0, 0, 1], 0.0), ground_material=RUBBER,
               overrides=[("s0", "ground", {"friction": 0.9}), ("s1", "s2", {"collide": False})])
    g = compile_geometry(sc)
    # the bodies' three materials, the wall (ice, but fixed: never a body's class), and a class
    # each for the named s0, s1, s2 and ground
    assert g.pair_friction.shape == (8, 8)
    assert g.material_class[5000] not in {g.material_class[i] for i in range(5000)}
    names = [b.name for b in sc.bodies] + ["wall"]
    for i, j in [(0, 3), (3, 4), (4, 5), (1, 2), (3, 5000), (0, 5000), (6, 9)]:
        pm = pair_material(sc, names[i], names[j])
        ci, cj = g.material_class[i], g.material_class[j]
        assert g.pair_friction[ci, cj] == pm.friction
        assert g.pair_restitution[ci, cj] == pm.restitution
        assert g.pair_rolling_friction[ci, cj] == pm.rolling_friction
        assert g.pair_collide[ci, cj] == pm.collide
    cg = g.plane_class[0]
    assert g.pair_friction[g.material_class[0], cg] == 0.9
    assert g.pair_friction[g.material_class[3], cg] == pair_material(sc, "s3", "ground").friction
    assert not g.pair_collide[g.material_class[1], g.material_class[2]]


def test_rows_carry_the_pair_values_and_collide_false_is_filtered():
    sc = scene([body("a", Sphere(0.1), [0, 0, 0.099], material=ICE),
                body("b", Sphere(0.1), [0.199, 0, 0.099], material=RUBBER),
                body("c", Sphere(0.1), [0.398, 0, 0.099], material=RUBBER)],
               [static("block", Box(np.array([0.2, 0.2, 0.2])), [0.597, 0, 0.099])],
               ground=([0, 0, 1], 0.0),
               overrides=[("a", "ground", {"collide": False})])
    g = compile_geometry(sc)
    c = new_contacts(g)
    detect3d(g, *state3d(sc), c)
    rows = rows_of(c)
    pairs = {(r[0], r[1]) for r in rows}
    assert pairs == {(0, 1), (1, 2), (1, -1), (2, -1)}  # a-ground filtered
    ground_or_static = [r for r in rows if r[1] == -1]
    assert len(ground_or_static) == 3  # b ground, c ground, c block
    for a, b, _n, _p, _d, mu, e, _f in rows:
        other = {(0, 1): "b", (1, 2): "c"}.get((a, b))
        if other:
            pm = pair_material(sc, "abc"[a], other)
            assert (mu, e) == (pm.friction, pm.restitution)
    block = [r for r in rows if r[0] == 2 and r[2][0] > 0.5]
    assert len(block) == 1
    assert block[0][5] == pair_material(sc, "c", "block").friction


def test_overflow_is_counted_never_silent():
    sc = scene([body(f"b{i}", Box(np.array([0.2, 0.2, 0.2])), [0.3 * i, 0, 0.099])
                for i in range(10)], ground=([0, 0, 1], 0.0))
    g = compile_geometry(sc)
    c = new_contacts(g, capacity=7)
    needed = detect3d(g, *state3d(sc), c)
    assert needed == 40 and c.needed[0] == 40
    assert c.count[0] == 7 and c.overflowed()
    big = new_contacts(g)
    assert big.capacity == contact_capacity(g)
    detect3d(g, *state3d(sc), big)
    assert not big.overflowed() and big.n == 40
    # the rows kept are the first of the full list
    for field in ("a", "b", "normal", "point", "depth", "feature"):
        np.testing.assert_array_equal(getattr(c, field)[:7], getattr(big, field)[:7])


def _pile(n=60, seed=4):
    rng = np.random.default_rng(seed)
    bodies = [body(f"b{i}", Box(np.array([0.2, 0.2, 0.2])) if i % 2 else Sphere(0.1),
                   rng.uniform([-0.5, -0.5, 0.08], [0.5, 0.5, 0.8]),
                   np.array([1.0, 0, 0, 0]) + 0.0) for i in range(n)]
    return scene(bodies, ground=([0, 0, 1], 0.0))


def test_bit_identical_repeats_and_independent_of_the_sweep_cache():
    sc = _pile()
    x, q = state3d(sc)
    g = compile_geometry(sc)
    first = new_contacts(g)
    detect3d(g, x, q, first)
    assert first.n > 20
    # other states in between change the cached sweep order; the same state gives the same rows
    detect3d(g, x + 0.3, q, new_contacts(g))
    second = new_contacts(g)
    detect3d(g, x, q, second)
    fresh_g = compile_geometry(sc)
    third = new_contacts(fresh_g)
    detect3d(fresh_g, x, q, third)
    for other in (second, third):
        assert other.n == first.n
        for field in ("a", "b", "normal", "point", "depth", "friction", "feature"):
            np.testing.assert_array_equal(getattr(other, field)[:first.n],
                                          getattr(first, field)[:first.n])


def test_feature_keys_stable_while_the_same_features_touch():
    sc = scene([body("box", Box(np.array([0.4, 0.4, 0.2])), [0, 0, 0.099]),
                body("top", Box(np.array([0.2, 0.2, 0.2])), [0.05, 0, 0.298])],
               ground=([0, 0, 1], 0.0))
    g = compile_geometry(sc)
    x, q = state3d(sc)
    c = new_contacts(g)
    detect3d(g, x, q, c)
    keys = sorted(c.feature[:c.n])
    assert len(set(keys)) == c.n == 8
    # slide and tilt a little: same faces in contact, same keys
    from scipy.spatial.transform import Rotation
    for k in range(1, 5):
        x2 = x + np.array([[0.002 * k, 0, 0], [0.003 * k, -0.002 * k, -0.0005 * k]])
        tilt = Rotation.from_rotvec([0.002 * k, -0.001 * k, 0.01 * k]).as_quat()[[3, 0, 1, 2]]
        q2 = q.copy()
        q2[1] = tilt
        detect3d(g, x2, q2, c)
        assert sorted(c.feature[:c.n]) == keys
    # keys distinguish pairs: box-ground and top-box rows differ in their pair part
    pairs = {int(k) >> 32 for k in keys}
    assert len(pairs) == 2


def test_body_frame_offset_from_the_centre_of_mass():
    # a sphere whose centre of mass sits 5 cm off its shape's centre: the shape is at x - R com
    sc = scene([body("a", Sphere(0.1), [0, 0, 0.099], com=[0.05, 0, 0])],
               ground=([0, 0, 1], 0.0))
    g = compile_geometry(sc)
    x = np.array([[0.05, 0.0, 0.099]])  # the centre of mass in world, unrotated
    c = new_contacts(g)
    detect3d(g, x, np.array([[1.0, 0, 0, 0]]), c)
    np.testing.assert_allclose(c.point[0], [0, 0, -0.0005], atol=1e-15)
    # turned half a turn about z: the centre of mass stays, the shape swings to the other side
    detect3d(g, x, np.array([[0.0, 0, 0, 1.0]]), c)
    np.testing.assert_allclose(c.point[0], [0.1, 0, -0.0005], atol=1e-15)


@pytest.mark.parametrize("kind", [SPHERE, BOX])
def test_kind_codes_are_what_geometry_says(kind):
    shape = Sphere(0.1) if kind == SPHERE else Box(np.array([0.1, 0.1, 0.1]))
    g = compile_geometry(scene([body("a", shape, [0, 0, 1.0])]))
    assert g.kind[0] == kind
