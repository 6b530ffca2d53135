"""The shape vocabulary (crosscheck.scene.shapes): support points, signed distances and bounding
boxes against closed forms worked out by hand, the L-bracket mesh against trimesh.

Tolerances: every query is a closed form evaluated in floating point, so the bound is round-off:
1e-12 relative to the shape's size (~1 m here), or to the coordinates (1e3 m) for bodies placed
far from the origin. Sizes are chosen so that a wrong formula is off by 1e-2 or more.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
import trimesh
from scipy.spatial.transform import Rotation

from crosscheck.scene import massprops, model
from crosscheck.scene.fluid import Layer
from crosscheck.scene.shapes import (
    Box,
    Capsule,
    Circle,
    Cylinder,
    Mesh,
    Placed,
    Polygon,
    Sphere,
    world_bounding_box,
)

L_BRACKET = Path(__file__).resolve().parents[2] / "cases" / "meshes" / "l_bracket.obj"
TOL = 1e-12  # round-off bound for shapes of size ~1 m
FAR = np.array([1.0e3, -2.0e3, 0.5e3])  # a position far from the origin
QUAT = np.array([0.8, 0.2, -0.5, 0.3]) / np.linalg.norm([0.8, 0.2, -0.5, 0.3])  # w, x, y, z
ANGLE = 0.7


def l_bracket() -> Mesh:
    raw = massprops.load_mesh(L_BRACKET)
    return Mesh(path=L_BRACKET, vertices=np.asarray(raw.vertices, float),
                faces=np.asarray(raw.faces, np.int64))


# The bracket's file rotates an L profile (x in [0, 0.3], z in [0, 0.2], wall 0.04 m, extruded
# along y in [0, 0.1]) by 30 degrees about (1, 2, 3) (see its header): undo that to reason in the
# profile's frame, where the solid is the union of two boxes.
L_ROT = Rotation.from_rotvec(math.radians(30.0) * np.array([1.0, 2.0, 3.0]) / math.sqrt(14.0))


def in_l_profile(u: np.ndarray) -> np.ndarray:
    x, y, z = u[..., 0], u[..., 1], u[..., 2]
    slab = (y > 0) & (y < 0.1) & (x > 0) & (z > 0)
    return slab & (((x < 0.3) & (z < 0.04)) | ((x < 0.04) & (z < 0.2)))


def rot3() -> np.ndarray:
    return Rotation.from_quat(QUAT, scalar_first=True).as_matrix()


def rot2() -> np.ndarray:
    c, s = math.cos(ANGLE), math.sin(ANGLE)
    return np.array([[c, -s], [s, c]])


SHAPES = {
    "sphere": Sphere(0.5),
    "box": Box(np.array([2.0, 4.0, 6.0])),
    "capsule": Capsule(0.5, 2.0),
    "cylinder": Cylinder(0.5, 2.0),
    "mesh": l_bracket(),
    "circle": Circle(0.5),
    "box2d": Box(np.array([2.0, 1.0])),
    "polygon": Polygon(np.array([[0.0, 0.0], [4.0, 0.0], [0.0, 3.0]])),  # 3-4-5, inradius 1
}


def support_function(name: str, d: np.ndarray) -> np.ndarray:
    """h(d) = max over the shape of d . x, in closed form (for the mesh: its convex hull by
    trimesh, an independent computation)."""
    n = np.linalg.norm(d, axis=-1)
    match name:
        case "sphere" | "circle":
            return 0.5 * n
        case "box":
            return np.abs(d) @ [1.0, 2.0, 3.0]
        case "box2d":
            return np.abs(d) @ [1.0, 0.5]
        case "capsule":  # segment (half length 1) + ball (0.5)
            return 0.5 * n + np.abs(d[..., 2])
        case "cylinder":  # disc of radius 0.5 + segment of half length 1
            return 0.5 * np.linalg.norm(d[..., :2], axis=-1) + np.abs(d[..., 2])
        case "polygon":
            return np.max(d @ SHAPES["polygon"].vertices.T, axis=-1)
        case "mesh":
            hull = trimesh.load(L_BRACKET, force="mesh").convex_hull
            return np.max(d @ np.asarray(hull.vertices).T, axis=-1)
    raise AssertionError(name)


# -- signed distances against closed forms --------------------------------------------------------
# (point, expected signed distance); each worked out by hand in the comment
SDF_CASES = {
    "sphere": [
        ((0, 0, 0), -0.5),            # centre
        ((0, -0.1, 0), -0.4),         # inside
        ((0.3, 0, 0.4), 0.0),         # on the surface (|p| = 0.5)
        ((0.6, 0.8, 0), 0.5),         # |p| = 1
    ],
    "box": [  # half sizes (1, 2, 3)
        ((0, 0, 0), -1.0),            # nearest face x = +-1
        ((0.5, 1.5, 2.9), -0.1),      # depths (0.5, 0.5, 0.1)
        ((0.99, 1.98, 0), -0.01),     # just inside an edge: depths (0.01, 0.02, 3)
        ((1, 0.5, -1), 0.0),          # on a face
        ((1, 2, 3), 0.0),             # on a corner
        ((3, 0, 0), 2.0),             # off a face
        ((2, 3, 0), math.sqrt(2)),    # off the edge x = 1, y = 2
        ((-1.5, -2, -3.5), math.sqrt(0.5)),  # off the edge x = -1, z = -3
        ((2, 3, 4), math.sqrt(3)),    # off the corner (1, 2, 3)
    ],
    "capsule": [  # radius 0.5, segment z in [-1, 1]
        ((0, 0, 0), -0.5),
        ((0.1, 0, 1.2), math.sqrt(0.05) - 0.5),  # in the cap: 0.2236 from (0, 0, 1)
        ((0.3, 0.4, 0.7), 0.0),       # on the side
        ((0, 0, -1.5), 0.0),          # on the tip
        ((1.0, 0, -0.2), 0.5),        # off the side
        ((0.6, 0, 1.8), 0.5),         # off the cap: 1 from (0, 0, 1)
        ((0, 0, 2), 0.5),             # beyond the tip
    ],
    "cylinder": [  # radius 0.5, z in [-1, 1]
        ((0, 0, 0), -0.5),
        ((0, 0, 0.9), -0.1),          # below the cap
        ((0.45, 0, 0.95), -0.05),     # next to the rim edge, inside: both depths 0.05
        ((0.3, 0.4, 0), 0.0),         # on the side
        ((0.3, 0.4, -1), 0.0),        # on the rim
        ((0.1, 0, 1.5), 0.5),         # above the cap
        ((2, 0, 0), 1.5),             # off the side
        ((0.6, 0.8, 1.5), math.sqrt(0.5)),  # off the rim: (0.5, 0.5) from it
    ],
    "circle": [
        ((0, 0), -0.5), ((0.1, 0), -0.4), ((0.3, -0.4), 0.0), ((3, 4), 4.5),
    ],
    "box2d": [  # half sizes (1, 0.5)
        ((0, 0), -0.5), ((0.9, 0), -0.1), ((0.95, 0.45), -0.05), ((1, 0.5), 0.0),
        ((-0.2, -0.5), 0.0), ((2, 0), 1.0), ((-1.5, -0.25), 0.5), ((4, 4.5), 5.0),  # (3, 4)
    ],
    "polygon": [  # triangle (0, 0), (4, 0), (0, 3); hypotenuse 3x + 4y = 12
        ((1, 1), -1.0),               # the incentre: inradius 1
        ((0.5, 0.25), -0.25),         # nearest the edge y = 0
        ((2, 0), 0.0),                # on an edge
        ((0, 3), 0.0),                # on a vertex
        ((4, 3), 2.4),                # off the hypotenuse: (12 + 12 - 12) / 5
        ((-1, -1), math.sqrt(2)),     # off the vertex (0, 0)
        ((5, -1), math.sqrt(2)),      # off the vertex (4, 0) (beyond both edges' ends)
        ((-2, 1), 2.0),               # off the edge x = 0
    ],
}


@pytest.mark.parametrize("name", list(SDF_CASES))
def test_signed_distance_closed_forms(name):
    shape = SHAPES[name]
    pts = np.array([p for p, _ in SDF_CASES[name]], float)
    expect = np.array([d for _, d in SDF_CASES[name]])
    got = shape.signed_distance(pts)
    np.testing.assert_allclose(got, expect, rtol=0, atol=TOL)
    # one at a time and as a (2, k/2)-batch: the same numbers
    np.testing.assert_array_equal([shape.signed_distance(p) for p in pts], got)
    if len(pts) % 2 == 0:
        np.testing.assert_array_equal(shape.signed_distance(pts.reshape(2, -1, pts.shape[1])),
                                      got.reshape(2, -1))
    # inside is strict: a surface point is not contained
    np.testing.assert_array_equal(shape.contains(pts), got < 0)
    assert not shape.contains(pts[expect == 0]).any()


def test_points_of_the_wrong_dimension_are_refused():
    with pytest.raises(ValueError, match=r"\(\.\.\., 3\)"):
        Sphere(1.0).signed_distance([1.0, 2.0])
    with pytest.raises(ValueError, match=r"\(\.\.\., 2\)"):
        Box((1.0, 1.0)).support([1.0, 2.0, 3.0])


def test_a_polygon_built_clockwise_or_flat_is_refused():
    """Clockwise, the inside test (left of every edge) holds nowhere: the triangle would have no
    inside, and a fluid obstacle or a contact made of it would silently be empty."""
    ccw = np.array([[0.0, 0.0], [4.0, 0.0], [0.0, 3.0]])
    assert Polygon(ccw).contains([[1.0, 1.0]])[0]
    with pytest.raises(ValueError, match="counter-clockwise.*-6.*reverse them"):
        Polygon(ccw[::-1])
    with pytest.raises(ValueError, match="signed area of 0"):
        Polygon(np.array([[0.0, 0.0], [1.0, 1.0], [2.0, 2.0]]))
    with pytest.raises(ValueError, match="at least 3"):
        Polygon(np.array([[0.0, 0.0], [1.0, 0.0]]))


# -- support points -------------------------------------------------------------------------------
def directions(dim: int, n: int = 400, seed: int = 3) -> np.ndarray:
    d = np.random.default_rng(seed).normal(size=(n, dim))
    # scaled copies and the axes: the support must not depend on |d|
    return np.concatenate([d, 1e-3 * d[:5], 1e3 * d[:5], np.eye(dim), -np.eye(dim)])


@pytest.mark.parametrize("name", list(SHAPES))
def test_support_attains_the_support_function_on_the_surface(name):
    """A support point s(d) lies in the shape (sdf <= 0) and d . s(d) = max over the shape of
    d . x: that is the definition, checked against h(d) in closed form."""
    shape = SHAPES[name]
    d = directions(shape.dimension)
    s = shape.support(d)
    assert s.shape == d.shape
    h = support_function(name, d)
    np.testing.assert_allclose(np.sum(d * s, axis=-1), h, rtol=TOL, atol=0)
    assert np.all(np.abs(shape.signed_distance(s)) <= TOL)  # on the surface
    # batches keep their leading shape
    np.testing.assert_array_equal(shape.support(d[:6].reshape(2, 3, -1)), s[:6].reshape(2, 3, -1))


def test_support_points_by_hand():
    np.testing.assert_array_equal(SHAPES["box"].support([1.0, -2.0, 0.5]), [1.0, -2.0, 3.0])
    np.testing.assert_array_equal(SHAPES["box2d"].support([-1.0, 1e-9]), [-1.0, 0.5])
    np.testing.assert_allclose(SHAPES["sphere"].support([0.0, 3.0, 4.0]), [0.0, 0.3, 0.4],
                               rtol=0, atol=TOL)
    np.testing.assert_array_equal(SHAPES["capsule"].support([0.0, 0.0, -2.0]), [0, 0, -1.5])
    np.testing.assert_allclose(SHAPES["capsule"].support([3.0, 0.0, 4.0]), [0.3, 0.0, 1.4],
                               rtol=0, atol=TOL)
    np.testing.assert_allclose(SHAPES["cylinder"].support([1.0, 1.0, -5.0]),
                               [0.5 / math.sqrt(2), 0.5 / math.sqrt(2), -1.0], rtol=0, atol=TOL)
    np.testing.assert_allclose(SHAPES["circle"].support([-3.0, 4.0]), [-0.3, 0.4], atol=TOL)
    np.testing.assert_array_equal(SHAPES["polygon"].support([1.0, 1.0]), [4.0, 0.0])
    np.testing.assert_array_equal(SHAPES["polygon"].support([-1.0, 1.0]), [0.0, 3.0])


@pytest.mark.parametrize("name", list(SHAPES))
def test_support_of_a_zero_direction_is_in_the_shape(name):
    shape = SHAPES[name]
    assert shape.signed_distance(shape.support(np.zeros(shape.dimension))) <= TOL


# -- bounding boxes -------------------------------------------------------------------------------
BOXES = {  # (lo, hi) by hand
    "sphere": ([-0.5] * 3, [0.5] * 3),
    "box": ([-1, -2, -3], [1, 2, 3]),
    "capsule": ([-0.5, -0.5, -1.5], [0.5, 0.5, 1.5]),
    "cylinder": ([-0.5, -0.5, -1], [0.5, 0.5, 1]),
    "circle": ([-0.5, -0.5], [0.5, 0.5]),
    "box2d": ([-1, -0.5], [1, 0.5]),
    "polygon": ([0, 0], [4, 3]),
}


@pytest.mark.parametrize("name", list(SHAPES))
def test_bounding_box_is_tight(name):
    """The box equals the support points along -+ each axis (so it is tight) and holds every
    support point (so it contains the shape)."""
    shape = SHAPES[name]
    lo, hi = shape.bounding_box()
    e = np.eye(shape.dimension)
    np.testing.assert_allclose(hi, np.diag(shape.support(e)), rtol=0, atol=TOL)
    np.testing.assert_allclose(lo, np.diag(shape.support(-e)), rtol=0, atol=TOL)
    s = shape.support(directions(shape.dimension))
    assert np.all(s >= lo - TOL) and np.all(s <= hi + TOL)
    if name in BOXES:
        np.testing.assert_allclose(lo, BOXES[name][0], rtol=0, atol=TOL)
        np.testing.assert_allclose(hi, BOXES[name][1], rtol=0, atol=TOL)
    else:  # the mesh: its vertices' extent, by trimesh
        np.testing.assert_array_equal(np.stack([lo, hi]),
                                      trimesh.load(L_BRACKET, force="mesh").bounds)


def world_box_by_hand(name: str) -> tuple[np.ndarray, np.ndarray]:
    """Half extents (or, for vertex shapes, the extent) of the rotated shape about its origin."""
    if SHAPES[name].dimension == 3:
        r, x = rot3(), FAR
    else:
        r, x = rot2(), FAR[:2]
    axis = r[:, 2] if r.shape == (3, 3) else None
    match name:
        case "sphere" | "circle":
            half = np.full(len(x), 0.5)
        case "box" | "box2d":  # |R| times the half sizes
            half = np.abs(r) @ (0.5 * np.asarray(SHAPES[name].size))
        case "capsule":  # the rotated segment, grown by the radius
            half = 1.0 * np.abs(axis) + 0.5
        case "cylinder":  # segment + a tilted disc: r sqrt(1 - a_i^2) along world axis i
            half = 1.0 * np.abs(axis) + 0.5 * np.sqrt(1.0 - axis**2)
        case "mesh" | "polygon":
            v = np.asarray(SHAPES[name].vertices) @ r.T
            return x + v.min(axis=0), x + v.max(axis=0)
    return x - half, x + half


@pytest.mark.parametrize("name", list(SHAPES))
def test_world_bounding_box_of_a_rotated_body_far_away(name):
    """The exact AABB of the rotated shape (not the AABB of its rotated body box), at 1e3 m:
    round-off relative to the coordinates."""
    shape = SHAPES[name]
    orientation = QUAT if shape.dimension == 3 else ANGLE
    position = FAR[:shape.dimension]
    lo, hi = world_bounding_box(shape, position, orientation)
    elo, ehi = world_box_by_hand(name)
    np.testing.assert_allclose(lo, elo, rtol=TOL, atol=0)
    np.testing.assert_allclose(hi, ehi, rtol=TOL, atol=0)
    placed = Placed(shape, position, orientation)
    np.testing.assert_array_equal(np.stack(placed.bounding_box()), np.stack([lo, hi]))
    # 2D orientation as Body.orientation stores it, array([angle])
    if shape.dimension == 2:
        np.testing.assert_array_equal(world_bounding_box(shape, position, np.array([ANGLE]))[1],
                                      hi)
    # no rotation: the body box shifted
    lo0, hi0 = world_bounding_box(shape, position)
    np.testing.assert_array_equal(lo0, position + shape.bounding_box()[0])
    np.testing.assert_array_equal(hi0, position + shape.bounding_box()[1])


@pytest.mark.parametrize("name", ["box", "capsule", "mesh", "box2d", "polygon"])
def test_placed_queries_transform_world_points_into_the_body_frame(name):
    """World point x + R p has the body-frame signed distance of p; the world support point is
    x + R s(R^T d). A transposed rotation fails both (the shapes are not symmetric under it)."""
    shape = SHAPES[name]
    dim = shape.dimension
    r = rot3() if dim == 3 else rot2()
    x = FAR[:dim]
    placed = Placed(shape, x, QUAT if dim == 3 else ANGLE)
    body = np.random.default_rng(5).uniform(-2.0, 2.0, size=(300, dim))
    if name == "mesh":
        body = body * 0.2 + 0.1
    world = x + body @ r.T
    # (x + R p) - x loses the digits below ulp(1e3) ~ 1e-13 m in each coordinate
    np.testing.assert_allclose(placed.signed_distance(world), shape.signed_distance(body),
                               rtol=0, atol=1e3 * TOL)
    d = directions(dim, 50)
    np.testing.assert_allclose(placed.support(d), x + shape.support(d @ r) @ r.T, rtol=TOL)
    np.testing.assert_allclose(np.sum(d * (placed.support(d) - x), axis=-1),
                               support_function(name, d @ r), rtol=TOL, atol=1e3 * TOL)


def test_orientations_are_checked():
    with pytest.raises(ValueError, match="quaternion"):
        world_bounding_box(SHAPES["box"], FAR, ANGLE)
    with pytest.raises(ValueError, match="an angle"):
        world_bounding_box(SHAPES["circle"], FAR[:2], QUAT)


# -- the mesh against trimesh ---------------------------------------------------------------------
def mesh_probe_points() -> tuple[np.ndarray, np.ndarray | None]:
    """Points all around the bracket: uniform in its grown bounding box, just off every face
    (+-1e-6 m along the normal from the centroid) and just off every vertex."""
    tm = trimesh.load(L_BRACKET, force="mesh")
    rng = np.random.default_rng(11)
    lo, hi = tm.bounds
    box = rng.uniform(lo - 0.05, hi + 0.05, size=(3000, 3))
    eps = 1e-6
    c, n = tm.triangles_center, tm.face_normals
    near_vertices = tm.vertices[rng.integers(0, len(tm.vertices), 400)] \
        + 1e-4 * rng.normal(size=(400, 3))
    return np.concatenate([box, c + eps * n, c - eps * n, near_vertices]), tm


def test_mesh_distance_against_trimesh_closest_points():
    """|sdf| equals the distance to trimesh's own closest point on the surface (every point
    against every triangle: ``trimesh.triangles.closest_point``; trimesh's
    ``proximity.signed_distance`` needs rtree, not installed). The sign is checked against the
    bracket's closed form, the union of two boxes in its profile frame: independent of the ray
    parity test the mesh uses."""
    pts, tm = mesh_probe_points()
    tri = tm.triangles
    k, f = len(pts), len(tri)
    closest = trimesh.triangles.closest_point(np.tile(tri, (k, 1, 1)), np.repeat(pts, f, axis=0))
    ref = np.linalg.norm(closest - np.repeat(pts, f, axis=0), axis=1).reshape(k, f).min(axis=1)
    got = SHAPES["mesh"].signed_distance(pts)
    np.testing.assert_allclose(np.abs(got), ref, rtol=0, atol=TOL)
    clear = ref > 1e-9  # the sign of a point on the surface is immaterial (distance 0)
    inside = in_l_profile(L_ROT.inv().apply(pts))
    np.testing.assert_array_equal((got < 0)[clear], inside[clear])
    assert inside.sum() > 100 and (~inside).sum() > 100  # the probe has points on both sides
    # face probes are exactly 1e-6 m out or in
    nf = len(tm.faces)
    np.testing.assert_allclose(got[3000:3000 + nf], 1e-6, rtol=0, atol=1e-15)
    np.testing.assert_allclose(got[3000 + nf:3000 + 2 * nf], -1e-6, rtol=0, atol=1e-15)
    # vertices are on the surface (to the round-off of a plane distance through a corner)
    np.testing.assert_allclose(SHAPES["mesh"].signed_distance(tm.vertices), 0.0, rtol=0, atol=TOL)


def test_mesh_distance_by_hand_and_not_the_convex_hull():
    """Points in the bracket's profile frame (x along the base, z up the wall, y across)."""
    cases = [
        ((0.15, 0.05, 0.02), -0.02),           # mid-base: 0.02 under its top and over its bottom
        ((0.02, 0.05, 0.15), -0.02),           # mid-wall
        ((0.15, 0.05, 0.08), 0.04),            # in the notch, above the base
        ((0.06, 0.05, 0.06), 0.02),            # in the notch, as far from the base as the wall
        ((0.32, 0.05, 0.06), math.sqrt(8e-4)),  # off the outer edge (0.3, y, 0.04)
        ((0.5, 0.05, 0.02), 0.2),              # off the end of the base
        ((0.4, 0.2, 0.1), math.sqrt(0.0236)),  # off the corner (0.3, 0.1, 0.04)
        ((0.3, 0.05, 0.02), 0.0),              # on the end face
    ]
    u = np.array([p for p, _ in cases])
    expect = np.array([d for _, d in cases])
    pts = L_ROT.apply(u)
    got = SHAPES["mesh"].signed_distance(pts)
    np.testing.assert_allclose(got, expect, rtol=0, atol=TOL)
    # the notch point is inside the convex hull: a hull-based distance would call it solid
    hull = trimesh.load(L_BRACKET, force="mesh").convex_hull
    a = np.asarray(hull.face_normals)
    b = np.sum(a * hull.triangles_center, axis=1)
    assert np.all(pts[2] @ a.T - b < -1e-3)


def test_mesh_support_is_the_convex_hull_support():
    shape = SHAPES["mesh"]
    hull = trimesh.load(L_BRACKET, force="mesh").convex_hull
    d = directions(3)
    s = shape.support(d)
    np.testing.assert_allclose(np.sum(d * s, axis=1),
                               np.max(d @ np.asarray(hull.vertices).T, axis=1), rtol=TOL)
    # every support point is a vertex of the mesh
    assert all(np.any(np.all(shape.vertices == p, axis=1)) for p in s)


# -- users of the shapes --------------------------------------------------------------------------
def test_fluid_shapes_are_the_placed_shapes():
    """Obstacles and region parts of a fluid case are shapes of this module placed without
    rotation, and their distances are bit for bit the former fluid formulas (which every
    committed fluid case's masks and initial level sets were checked against)."""
    from crosscheck.scene.loader import load_case

    cases = Path(__file__).resolve().parents[2] / "cases" / "fluid"
    spec = load_case(cases / "dam_break_obstacle.toml").fluid
    (obstacle,) = spec.obstacles
    assert isinstance(obstacle, Placed) and isinstance(obstacle.shape, Box)
    assert obstacle.orientation is None
    zal = load_case(cases / "zalesak_disk.toml").fluid
    assert [type(p.shape.shape) for p in zal.initial] == [Circle, Box]
    assert isinstance(load_case(cases / "sloshing.toml").fluid.initial[0].shape, Layer)

    # a grid with cell centres on the edges of the box and on the circle (3-4-5 offsets), and
    # random points (where a sqrt(x^2 + y^2) instead of hypot would differ in the last bits)
    g = (np.arange(16) + 0.5) / 16
    x, y = np.meshgrid(g, g, indexing="ij")
    rand = np.random.default_rng(2).uniform(0.0, 1.0, size=(2, 4000))
    x, y = np.concatenate([x.ravel(), rand[0]]), np.concatenate([y.ravel(), rand[1]])
    pts = np.stack([x, y], axis=-1)
    cx, cy, w, h, r = 0.28125, 0.28125, 0.25, 0.375, 0.3125
    qx = np.abs(x - cx) - 0.5 * w
    qy = np.abs(y - cy) - 0.5 * h
    former_box = (np.hypot(np.maximum(qx, 0.0), np.maximum(qy, 0.0))
                  + np.minimum(np.maximum(qx, qy), 0.0))
    former_circle = np.hypot(x - cx, y - cy) - r
    box = Placed(Box((w, h)), (cx, cy)).signed_distance(pts)
    circle = Placed(Circle(r), (cx, cy)).signed_distance(pts)
    np.testing.assert_array_equal(box, former_box)
    np.testing.assert_array_equal(circle, former_circle)
    assert (box == 0).sum() >= 8 and (circle == 0).sum() >= 8  # ties are exercised
    np.testing.assert_array_equal(Placed(Box((w, h)), (cx, cy)).contains(pts), former_box < 0)


def test_model_and_mass_properties_use_the_same_shapes():
    assert model.Box is Box and model.Sphere is Sphere and model.Mesh is Mesh
    rho = 2.0
    assert massprops.shape_mass_properties(SHAPES["box"], rho).mass == pytest.approx(96.0)
    assert massprops.shape_mass_properties(SHAPES["box2d"], rho).mass == pytest.approx(4.0)
    assert massprops.shape_mass_properties(SHAPES["polygon"], rho).mass == pytest.approx(12.0)
    assert massprops.shape_mass_properties(SHAPES["cylinder"], rho).mass == \
        pytest.approx(math.pi * 0.25 * 2.0 * rho)
    mesh = massprops.shape_mass_properties(SHAPES["mesh"], rho)
    # the bracket's volume: base 0.3 x 0.04 plus wall 0.04 x 0.16, times 0.1 deep
    assert mesh.mass == pytest.approx(rho * (0.3 * 0.04 + 0.04 * 0.16) * 0.1, rel=1e-12)
