"""3D narrow phase through the whole detection, against closed forms and the support-function
reference (collide_reference.py): depth, normal (from a to b), points between the surfaces, and
nothing beyond the margin; touching, shallow, deep, edge-edge, face-face and vertex-face
configurations, rotated and 1e4 m from the origin."""

from __future__ import annotations

import zlib
from pathlib import Path

import numpy as np
import pytest
import trimesh
from collide_reference import gap_along, signed_distance3d
from collide_scenes import body, scene, state3d, static
from scipy.spatial.transform import Rotation

from crosscheck.scene.shapes import Box, Capsule, Cylinder, Mesh, Placed, Sphere
from crosscheck.sim.collide import compile_geometry, detect3d, new_contacts
from crosscheck.sim.collide.polytope3d import EDGE_BIAS_ABS, EDGE_BIAS_REL

MARGIN = 5e-3
FAR = np.array([1e4, -1e4, 1e4])
DEEP = 0.02
DEEP_SLACK = 0.01


def quat(rot: Rotation) -> np.ndarray:
    x, y, z, w = rot.as_quat()
    return np.array([w, x, y, z])


IDENTITY = np.array([1.0, 0.0, 0.0, 0.0])


def convex_mesh(seed: int, size: float = 0.3) -> Mesh:
    pts = np.random.default_rng(seed).normal(size=(24, 3)) * size / 2
    hull = trimesh.Trimesh(pts).convex_hull
    return Mesh(path=Path(f"random-{seed}.obj"), vertices=np.asarray(hull.vertices),
                faces=np.asarray(hull.faces))


def detect_pair(sa, pa, qa, sb, pb, qb, *, b_static=False, margin=MARGIN):
    """Rows (a, b, normal, point, depth) of body A against body (or static) B."""
    bodies = [body("A", sa, pa, qa)]
    statics = []
    if b_static:
        statics.append(static("B", sb, pb, qb))
    else:
        bodies.append(body("B", sb, pb, qb))
    sc = scene(bodies, statics)
    g = compile_geometry(sc, margin)
    c = new_contacts(g)
    detect3d(g, *state3d(sc), c)
    assert c.needed[0] == c.count[0]
    return [(int(c.a[k]), int(c.b[k]), c.normal[k].copy(), c.point[k].copy(), float(c.depth[k]))
            for k in range(c.n)]


def split_edge_companion(rows):
    """(the pair's manifold, the face contact detect3d adds after a polytope pair's one-point
    edge contact): the first is every row with the first row's normal; a second normal may only
    follow one edge row."""
    first = [r for r in rows if np.array_equal(r[2], rows[0][2])]
    rest = [r for r in rows if not np.array_equal(r[2], rows[0][2])]
    assert not rest or len(first) == 1, (len(first), len(rest))
    return first, rest


def check_rows(rows, sa, pa, qa, sb, pb, qb, tol, point_tol, b_index=1, bias=0.0,
               normal_tol=None):
    """Every row consistent with the reference signed distance of A and B.

    The reference's search gives a lower bound ``ref`` of the signed distance (any direction's
    gap is at most the signed distance; the search may miss the best basin of a curved pair). The
    rows must be self-consistent (the deepest depth is minus the gap along the reported normal:
    the normal realises it) and at least as good as the search. ``bias``: how much deeper than
    the least penetration a routine may report on purpose (polytope3d's preference for face axes
    near a tie). ``normal_tol``: how far the gap along the reported normal may be from the
    reported depth (GJK / EPA on a cylinder find the depth to 1e-9 m but the normal only to about
    1e-4 rad, and at a capsule's or cylinder's straight side the gap varies linearly with the
    normal's tilt)."""
    normal_tol = tol if normal_tol is None else normal_tol
    a, b = Placed(sa, pa, qa), Placed(sb, pb, qb)
    ref, _ = signed_distance3d(a, b)
    if ref > MARGIN + tol:
        assert rows == [], (ref, rows)
        return ref
    if ref < MARGIN - tol - bias:
        assert rows, ref
    if not rows:
        return ref
    rows, faces = split_edge_companion(rows)
    for _, _, nk, p, d in faces:
        # the face contact added after an edge contact (polytope3d.face_after_edge): one normal
        # of its own, within the margin, no deeper than the edge point, and each point's two
        # surface points on the surfaces (a point of one face over the other's face)
        assert abs(np.linalg.norm(nk) - 1.0) < 1e-12
        np.testing.assert_array_equal(nk, faces[0][2])
        assert -MARGIN - tol <= d <= rows[0][4] + tol
        for shape, s in ((a, 0.5), (b, -0.5)):
            sd = float(shape.signed_distance(p + s * d * nk))
            assert abs(sd) <= point_tol, (shape.shape.kind, d, sd)
    n = rows[0][2]
    assert abs(np.linalg.norm(n) - 1.0) < 1e-12
    deepest = max(r[4] for r in rows)
    along = float(gap_along(a, b, n)[0])
    # Deep overlaps (beyond DEEP, a tenth of these shapes' size): a face manifold's deepest point
    # can be shallower than the overlap along the normal (the deepest vertex lies outside the
    # reference face and is clipped away, as in every SAT-and-clipping scheme), a feature
    # manifold's a little deeper (a point's shadow on the reference plane falls beyond the face);
    # allowed: DEEP_SLACK of the depth beyond DEEP. docs/inhouse.md states it.
    slack = DEEP_SLACK * max(0.0, -along - DEEP)
    assert abs(deepest + along) <= normal_tol + slack, (deepest, -along)
    assert deepest <= -ref + tol + bias, (deepest, -ref)
    assert along >= ref - normal_tol - bias, (along, ref)
    for ra, rb, nk, p, d in rows:
        assert (ra, rb) == (0, b_index)
        np.testing.assert_array_equal(nk, n)
        assert -MARGIN - tol <= d <= deepest
        # the contact's surface points, half the depth either way along the normal, lie on the
        # surfaces: A's at p + d/2 n (its deepest point into B), B's at p - d/2 n
        for shape, s in ((a, 0.5), (b, -0.5)):
            sd = float(shape.signed_distance(p + s * d * n))
            assert abs(sd) <= point_tol, (shape.shape.kind, d, sd)
    return ref


# -- closed forms ---------------------------------------------------------------------------------
@pytest.mark.parametrize("offset", [np.zeros(3), FAR])
def test_sphere_sphere_closed_form(offset):
    for gap in (-0.05, -1e-3, 0.0, 2e-3, 6e-3):
        d = 0.1 + 0.2 + gap
        u = np.array([1.0, 2.0, -2.0]) / 3.0
        rows = detect_pair(Sphere(0.1), offset, IDENTITY, Sphere(0.2), offset + d * u, IDENTITY)
        if gap > MARGIN:
            assert rows == []
            continue
        (a, b, n, p, depth), = rows
        assert depth == pytest.approx(-gap, abs=1e-15 + 1e-15 * np.abs(offset).max())
        np.testing.assert_allclose(n, u, atol=1e-12)
        # midway between the surface points offset + 0.1 u and offset + (d - 0.2) u
        np.testing.assert_allclose(p, offset + 0.5 * (0.1 + d - 0.2) * u, atol=1e-11, rtol=0)


@pytest.mark.parametrize("offset", [np.zeros(3), FAR])
def test_sphere_box_face_edge_corner_inside(offset):
    box = Box(np.array([0.4, 0.6, 0.8]))
    rot = Rotation.from_rotvec([0.3, -0.2, 0.5])
    r = rot.as_matrix()
    q = quat(rot)
    # (local centre, expected gap, expected local outward normal from the box towards the sphere)
    cases = [
        (np.array([0.0, 0.0, 0.4 + 0.1]), 0.0, np.array([0, 0, 1.0])),          # touching face
        (np.array([0.05, 0.1, 0.4 + 0.09]), -0.01, np.array([0, 0, 1.0])),     # shallow face
        (np.array([0.2 + 0.03, 0.3 + 0.04, 0.0]), 0.05 - 0.1, np.array([0.6, 0.8, 0])),  # edge
        (np.array([0.2, 0.3, 0.4]) + 0.102 * np.array([2, 3, 6]) / 7, 0.002,
         np.array([2, 3, 6]) / 7),                                             # corner, speculative
        (np.array([0.0, 0.25, 0.0]), -(0.05 + 0.1), np.array([0, 1.0, 0])),   # centre inside
    ]
    for local, gap, normal in cases:
        centre = offset + r @ local
        rows = detect_pair(Sphere(0.1), centre, IDENTITY, box, offset, q)
        (a, b, n, p, depth), = rows
        assert depth == pytest.approx(-gap, abs=1e-12)
        # normal from the sphere (a) to the box (b): minus the box's outward normal
        np.testing.assert_allclose(n, -(r @ normal), atol=1e-12)


def test_sphere_capsule_and_cylinder_closed_forms():
    rot = Rotation.from_rotvec([0.0, np.pi / 2, 0.0])  # axis along world x
    q = quat(rot)
    cap = Capsule(radius=0.05, length=0.4)
    # beside the cylindrical part, beyond an end cap
    for centre, gap in (([0.1, 0.0, 0.149], -0.001), ([0.2 + 0.05 + 0.1 + 0.003, 0, 0], 0.003)):
        (_, _, n, _, depth), = detect_pair(Sphere(0.1), np.array(centre, float), IDENTITY, cap,
                                           np.zeros(3), q)
        assert depth == pytest.approx(-gap, abs=1e-14)
    cyl = Cylinder(radius=0.05, length=0.4)
    # beside the side, beyond a cap face, at the rim
    rim = np.array([0.2, 0.05, 0.0]) + 0.1 * np.array([1.0, 1.0, 0.0]) / np.sqrt(2)
    for centre, gap, normal in (([0.1, 0.0, 0.149], -0.001, [0, 0, -1.0]),
                                ([0.2 + 0.099, 0.01, 0.0], -0.001, [-1.0, 0, 0]),
                                (rim + [0.001, 0.001, 0], np.sqrt(2) * 0.001,
                                 -np.array([1.0, 1.0, 0]) / np.sqrt(2))):
        (_, _, n, _, depth), = detect_pair(Sphere(0.1), np.array(centre, float), IDENTITY, cyl,
                                           np.zeros(3), q)
        assert depth == pytest.approx(-gap, abs=1e-14)
        np.testing.assert_allclose(n, normal, atol=1e-12)


def test_capsules_parallel_line_contact_and_crossed_point():
    cap = Capsule(radius=0.05, length=0.4)
    along_x = quat(Rotation.from_rotvec([0.0, np.pi / 2, 0.0]))
    along_y = quat(Rotation.from_rotvec([np.pi / 2, 0.0, 0.0]))
    rows = detect_pair(cap, np.zeros(3), along_x, cap, np.array([0.1, 0.0, 0.099]), along_x)
    assert len(rows) == 2
    xs = sorted(r[3][0] for r in rows)
    np.testing.assert_allclose(xs, [-0.1, 0.2], atol=1e-12)
    for *_, n, _p, depth in rows:
        np.testing.assert_allclose(n, [0, 0, 1], atol=1e-12)
        assert depth == pytest.approx(0.001, abs=1e-12)
    rows = detect_pair(cap, np.zeros(3), along_x, cap, np.array([0.0, 0.0, 0.098]), along_y)
    (_, _, n, p, depth), = rows
    assert depth == pytest.approx(0.002, abs=1e-12)
    np.testing.assert_allclose(p, [0, 0, 0.049], atol=1e-12)


# -- polytopes ------------------------------------------------------------------------------------
@pytest.mark.parametrize("offset", [np.zeros(3), FAR])
def test_box_box_face_face_edge_edge_vertex_face(offset):
    cube = Box(np.array([1.0, 1.0, 1.0]))
    # face-face: four points at the overlap's corners, depth 0.01
    rows = detect_pair(cube, offset, IDENTITY, cube, offset + [0.3, 0.2, 0.99], IDENTITY)
    assert len(rows) == 4
    corners = sorted((round(p[0] - offset[0], 6), round(p[1] - offset[1], 6)) for *_, p, _ in rows)
    assert corners == [(-0.2, -0.3), (-0.2, 0.5), (0.5, -0.3), (0.5, 0.5)]
    for *_, n, _p, d in rows:
        np.testing.assert_allclose(n, [0, 0, 1], atol=1e-12)
        assert d == pytest.approx(0.01, abs=1e-10)
    # edge-edge: A's top edge along x, B's bottom edge along y, crossing 0.01 deep
    qa = quat(Rotation.from_rotvec([np.pi / 4, 0, 0]))
    qb = quat(Rotation.from_rotvec([0, np.pi / 4, 0]))
    h = np.sqrt(0.5)
    rows = detect_pair(cube, offset, qa, cube, offset + [0.1, -0.05, 2 * h - 0.01], qb)
    rows, faces = split_edge_companion(rows)
    (_, _, n, p, d), = rows
    assert all(-MARGIN <= r[4] <= d for r in faces)  # (face_after_edge's, checked above)
    np.testing.assert_allclose(n, [0, 0, 1], atol=1e-9)
    assert d == pytest.approx(0.01, abs=1e-10)
    np.testing.assert_allclose(p - offset, [0.1, 0.0, h - 0.005], atol=1e-9)
    # vertex-face: B's corner (1, 1, 1) / 2 turned to point straight down into A's top face
    corner = Rotation.align_vectors([[0, 0, -1.0]], [[1.0, 1.0, 1.0]])[0]
    rows = detect_pair(cube, offset, IDENTITY, cube, offset + [0.1, 0.2, 0.5 + np.sqrt(3) / 2
                                                                 - 0.01], quat(corner))
    (_, _, n, p, d), = rows
    np.testing.assert_allclose(n, [0, 0, 1], atol=1e-12)
    assert d == pytest.approx(0.01, abs=1e-10)
    np.testing.assert_allclose(p - offset, [0.1, 0.2, 0.495], atol=1e-9)


def test_mesh_collides_as_its_convex_hull():
    root = Path(__file__).resolve().parents[2]
    mesh = trimesh.load(root / "cases" / "meshes" / "l_bracket.obj")
    bracket = Mesh(path=root / "cases/meshes/l_bracket.obj", vertices=np.asarray(mesh.vertices),
                   faces=np.asarray(mesh.faces))
    hull = trimesh.Trimesh(mesh.vertices).convex_hull
    # points of the hull outside the mesh (in the notch), with their depth below the hull
    lo, hi = hull.bounds
    pts = np.random.default_rng(0).uniform(lo, hi, size=(20000, 3))
    offsets = (hull.face_normals * hull.triangles[:, 0]).sum(axis=1)
    depth_in_hull = np.min(offsets[:, None] - hull.face_normals @ pts.T, axis=0)
    keep = (depth_in_hull > 0) & ~Placed(bracket, np.zeros(3)).contains(pts)
    outside, depth_in_hull = pts[keep], depth_in_hull[keep]
    assert len(outside) > 0
    k = int(np.argmax(depth_in_hull))
    tiny = Sphere(1e-4)
    rows = detect_pair(tiny, outside[k], IDENTITY, bracket, np.zeros(3), IDENTITY)
    assert rows, "a sphere in the notch touches the hull"
    assert rows[0][4] == pytest.approx(depth_in_hull[k] + 1e-4, abs=1e-9)


# -- every pair against the reference, random poses -----------------------------------------------
SHAPES = {
    "sphere": Sphere(0.12),
    "box": Box(np.array([0.3, 0.2, 0.25])),
    "capsule": Capsule(radius=0.07, length=0.25),
    "cylinder": Cylinder(radius=0.1, length=0.22),
    "hull": convex_mesh(3),
}
# depth tolerance (m): closed forms and polytope SAT to round-off; GJK/EPA on polytope cores;
# cylinders to EPA's 1e-9 and the reference's optimiser
TOL = {"sphere": 1e-10, "box": 1e-9, "capsule": 1e-9, "cylinder": 1e-7, "hull": 1e-9}
PAIRS = [(a, b) for i, a in enumerate(SHAPES) for b in list(SHAPES)[i:]]


def _tolerance(a, b):
    return max(TOL[a], TOL[b])


@pytest.mark.parametrize(("ka", "kb"), PAIRS)
def test_pairs_against_reference_random_poses(ka, kb):
    rng = np.random.default_rng(zlib.crc32(f"{ka}-{kb}".encode()))
    sa, sb = SHAPES[ka], SHAPES[kb]
    tol = _tolerance(ka, kb)
    for trial in range(14):
        offset = FAR if trial % 2 else np.zeros(3)
        ra, rb = Rotation.random(random_state=rng), Rotation.random(random_state=rng)
        u = rng.normal(size=3)
        u /= np.linalg.norm(u)
        pa = offset + rng.normal(size=3) * 0.01
        # along u the two just touch at distance t0; shift for deep, shallow, touching, apart
        a, b = Placed(sa, np.zeros(3), quat(ra)), Placed(sb, np.zeros(3), quat(rb))
        t0 = float(np.sum(u * a.support(u)) - np.sum(u * b.support(-u)))
        shift = [-0.05, -0.005, 0.0, 0.003, 0.02, -0.1, -0.002][trial % 7]
        pb = pa + (t0 + shift) * u
        rows = detect_pair(sa, pa, quat(ra), sb, pb, quat(rb))
        polytopes = ka in ("box", "hull") and kb in ("box", "hull")
        bias = (EDGE_BIAS_ABS + EDGE_BIAS_REL * 0.2) if polytopes else 0.0
        curved = "cylinder" in (ka, kb) and "sphere" not in (ka, kb)
        check_rows(rows, sa, pa, quat(ra), sb, pb, quat(rb), tol, point_tol=tol, bias=bias,
                   normal_tol=3e-5 if curved else tol)


def test_gjk_witnesses_are_the_points_whose_distance_it_returns():
    """GJK's distance and its witnesses (whose difference is the contact normal) must describe
    the same point of the Minkowski difference. The pose: a capsule's segment 0.034 m beside a
    cylinder's side, where a thin triangle's update came out farther than the last point (1e-6,
    relative) and GJK's "no strict decrease" exit returned the last distance with the new
    simplex's weights: the witnesses then lay 4.6e-7 (relative) farther apart than the distance
    said and the normal was 9.6e-4 rad off the side's (found as trial 12 of capsule/cylinder in
    test_pairs_against_reference_random_poses with numpy 2.4.6, scipy 1.17.1, numba 0.68.1).
    Bounds: the witnesses' separation equals the distance to 1e-12 (relative), the contact's
    normal is perpendicular to the cylinder's axis (the true normal is: a side contact) to 1e-6,
    and the rows agree with the reference signed distance as in the random test."""
    from crosscheck.sim.collide import gjk as G
    from crosscheck.sim.collide.detect import _scratch3d, world_poses3d

    sa, sb = SHAPES["capsule"], SHAPES["cylinder"]
    pa = np.array([-0.0008819511774354129, 0.014668256529512693, 0.013136238540047642])
    qa = np.array([0.18868259425354902, -0.3307240335535974, 0.48084631747970014,
                   -0.789814732213828])
    pb = np.array([-0.1371285154635106, 0.007033258842647012, 0.08512937881071239])
    qb = np.array([-0.28022531169238185, 0.8732057889302791, 0.22574576580876307,
                   -0.3286704642723037])
    sc = scene([body("A", sa, pa, qa), body("B", sb, pb, qb)], [])
    geom = compile_geometry(sc, MARGIN)
    x, q = state3d(sc)
    wpos, wrot = np.empty((2, 3)), np.empty((2, 3, 3))
    world_poses3d(geom, x, q, wpos, wrot)
    _, _, gs, lam = _scratch3d(geom)
    dist, n = G.gjk(geom, wpos, wrot, 0, 1, gs, lam)
    assert 0 < n < 4 and dist > 0.0   # the cores are apart: the distance is GJK's alone
    ax, ay, az, bx, by, bz = G.witnesses(gs, lam, n)
    assert np.hypot(np.hypot(bx - ax, by - ay), bz - az) == pytest.approx(dist, rel=1e-12)
    rows = detect_pair(sa, pa, qa, sb, pb, qb)
    axis_b = Placed(sb, pb, qb).rotation() @ np.array([0.0, 0.0, 1.0])
    assert abs(float(rows[0][2] @ axis_b)) < 1e-6
    check_rows(rows, sa, pa, qa, sb, pb, qb, TOL["cylinder"], point_tol=TOL["cylinder"],
               normal_tol=3e-5)


@pytest.mark.parametrize("kind", list(SHAPES))
def test_body_against_static_has_b_minus_one_and_normal_to_the_static(kind):
    wall = Box(np.array([0.05, 1.0, 1.0]))
    shape = SHAPES[kind]
    lo, hi = Placed(shape, np.zeros(3), IDENTITY).bounding_box()
    # the body's +x side 2 mm into the wall's -x face at x = 1
    pa = np.array([1.0 - hi[0] + 0.002, 0.0, 0.0])
    rows = detect_pair(shape, pa, IDENTITY, wall, np.array([1.025, 0.0, 0.0]), IDENTITY,
                       b_static=True)
    assert rows
    for a, b, n, _p, d in rows:
        assert (a, b) == (0, -1)
        np.testing.assert_allclose(n, [1, 0, 0], atol=1e-7)
        assert d == pytest.approx(0.002, abs=1e-7)


def test_separated_beyond_the_margin_reports_nothing():
    for ka, kb in PAIRS:
        sa, sb = SHAPES[ka], SHAPES[kb]
        u = np.array([0.3, -0.4, 0.866])
        u /= np.linalg.norm(u)
        a, b = Placed(sa, np.zeros(3), IDENTITY), Placed(sb, np.zeros(3), IDENTITY)
        t0 = float(np.sum(u * a.support(u)) - np.sum(u * b.support(-u)))
        # farther than the margin along u, hence at least that far apart
        rows = detect_pair(sa, np.zeros(3), IDENTITY, sb, (t0 + MARGIN * 1.01) * u, IDENTITY)
        assert rows == [], (ka, kb)


# -- the ground plane -----------------------------------------------------------------------------
def ground_rows(shape, position, q, normal=(0.0, 0.0, 1.0), offset=0.0):
    sc = scene([body("A", shape, np.asarray(position, float), q)], ground=(normal, offset))
    g = compile_geometry(sc, MARGIN)
    c = new_contacts(g)
    detect3d(g, *state3d(sc), c)
    return [(int(c.a[k]), int(c.b[k]), c.normal[k].copy(), c.point[k].copy(), float(c.depth[k]))
            for k in range(c.n)]


def test_ground_cylinder_upright_lying_tilted():
    cyl = Cylinder(radius=0.1, length=0.4)
    rows = ground_rows(cyl, [5.0, 5.0, 0.199], IDENTITY)
    assert len(rows) == 4
    for a, b, n, p, d in rows:
        assert (a, b) == (0, -1)
        np.testing.assert_allclose(n, [0, 0, -1])
        assert d == pytest.approx(0.001, abs=1e-14)
        assert np.hypot(p[0] - 5, p[1] - 5) == pytest.approx(0.1, abs=1e-12)
    lying = quat(Rotation.from_rotvec([np.pi / 2, 0, 0]))
    rows = ground_rows(cyl, [0.0, 0.0, 0.099], lying)
    assert len(rows) == 2
    np.testing.assert_allclose(sorted(r[3][1] for r in rows), [-0.2, 0.2], atol=1e-12)
    tilted = Rotation.from_rotvec([0.3, 0, 0])
    rows = ground_rows(cyl, [0.0, 0.0, 0.2], quat(tilted))
    lowest = -Placed(cyl, np.zeros(3), quat(tilted)).support(np.array([0, 0, -1.0]))[2]
    assert len(rows) == 1
    assert rows[0][4] == pytest.approx(lowest - 0.2, abs=1e-12)


def test_ground_capsule_sphere_hull_tilted_plane():
    n = np.array([0.0, -0.6, 0.8])
    cap = Capsule(radius=0.05, length=0.3)
    # lying along x on the tilted plane (n . p = 1), both end spheres 1 mm in
    centre = n * (1.0 + 0.05 - 0.001)
    rows = ground_rows(cap, centre, quat(Rotation.from_rotvec([0, np.pi / 2, 0])), n, 1.0)
    assert len(rows) == 2
    for _, _, nn, p, d in rows:
        np.testing.assert_allclose(nn, -n, atol=1e-15)
        assert d == pytest.approx(0.001, abs=1e-12)
        assert float(n @ p) == pytest.approx(1.0 - 0.0005, abs=1e-12)
    rows = ground_rows(Sphere(0.2), n * 1.19 + [3.0, 0, 0], IDENTITY, n, 1.0)
    assert len(rows) == 1 and rows[0][4] == pytest.approx(0.01, abs=1e-12)
    hull = convex_mesh(7)
    q = quat(Rotation.from_rotvec([0.4, 0.1, -0.7]))
    low = float(np.min(Placed(hull, np.zeros(3), q).support(np.array([[0, 0, -1.0]]))[:, 2]))
    rows = ground_rows(hull, [0, 0, -low - 0.003], q)
    assert 1 <= len(rows) <= 4
    assert max(r[4] for r in rows) == pytest.approx(0.003, abs=1e-12)


def test_ground_beyond_margin_and_far_from_origin():
    assert ground_rows(Box(np.array([1.0, 1.0, 1.0])), [0, 0, 0.5 + 1.01 * MARGIN],
                       IDENTITY) == []
    rows = ground_rows(Box(np.array([1.0, 1.0, 1.0])), FAR + [0, 0, 0.499], IDENTITY,
                       (0, 0, 1), FAR[2])
    assert len(rows) == 4
    for *_, d in rows:
        assert d == pytest.approx(0.001, abs=1e-11)
