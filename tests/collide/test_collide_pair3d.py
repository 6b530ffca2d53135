"""collide_pair3d, the single-pair entry point, against the geometric truth and against detect3d:
one pair's rows are the same code path whichever asks (detect.py's ``_pairs3d``), including the
face contact added after a polytope pair's edge contact (polytope3d.face_after_edge)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import trimesh
from collide_scenes import body, scene, state3d
from scipy.spatial.transform import Rotation

from crosscheck.scene.shapes import Box, Capsule, Cylinder, Mesh, Sphere
from crosscheck.sim.collide import compile_geometry, detect3d, new_contacts
from crosscheck.sim.collide.detect import collide_pair3d

MARGIN = 5e-3
FIELDS = ("a", "b", "normal", "point", "depth", "friction", "restitution", "rolling_friction",
          "torsional_friction", "feature")


def quat(rot: Rotation) -> np.ndarray:
    x, y, z, w = rot.as_quat()
    return np.array([w, x, y, z])


def rows_of(c):
    n = int(c.count[0])
    assert int(c.needed[0]) == n
    return {f: getattr(c, f)[:n].copy() for f in FIELDS}


def pair_rows(g, x, q, ca, cb):
    c = new_contacts(g)
    collide_pair3d(g, x, q, ca, cb, c)
    return rows_of(c)


def assert_same_rows(r1, r2):
    for f in FIELDS:
        np.testing.assert_array_equal(r1[f], r2[f], err_msg=f)


# -- edge on edge, a neighbouring corner within the margin ----------------------------------------
H = 0.1  # both cubes' half side
PHI = np.radians(40.0)  # B turned about x: its edge (body y = z = -H) lowest, faces not tied
THETA = np.radians(3.0)  # then tilted about y: that edge descends along +x
DZ = 2e-3  # B's edge crosses A's top edge (x = z = H) this far below it
S = 0.08  # from the crossing to B's inner corner along B's edge
Y_B = 0.01  # where along A's edge


def edge_on_edge():
    """A: an axis-aligned cube at the origin. B: a cube whose lowest edge crosses A's top edge
    x = z = H at (H, Y_B, H - DZ), running down and out over A's rim; its inner corner, S back
    along the edge, is above A's top face by S sin(THETA) - DZ (2.19 mm, within the margin)."""
    rot_b = Rotation.from_euler("xy", [PHI, THETA])  # extrinsic: R_y(THETA) R_x(PHI)
    rb = rot_b.as_matrix()
    e_b = rb @ np.array([1.0, 0.0, 0.0])
    cross = np.array([H, Y_B, H - DZ])
    centre_b = cross + (H - S) * e_b - rb @ np.array([0.0, -H, -H])
    sc = scene([body("A", Box(np.full(3, 2 * H)), np.zeros(3)),
                body("B", Box(np.full(3, 2 * H)), centre_b, quat(rot_b))])
    return sc, centre_b, rb


def test_edge_contact_and_the_faces_points_through_collide_pair3d():
    sc, centre_b, rb = edge_on_edge()
    g = compile_geometry(sc, MARGIN)
    x, q = state3d(sc)
    rows = pair_rows(g, x, q, 0, 1)

    # by hand: B's lowest edge, from its inner corner b0 (x < H) to its outer corner b1
    b0 = centre_b + rb @ np.array([-H, -H, -H])
    b1 = centre_b + rb @ np.array([H, -H, -H])
    e_b = (b1 - b0) / np.linalg.norm(b1 - b0)
    np.testing.assert_allclose(e_b, [np.cos(THETA), 0.0, -np.sin(THETA)], atol=1e-15)
    assert 0.0 < b0[2] - H < MARGIN and b0[0] < H < b1[0] and b1[2] < H - DZ
    # the edge axis: A's edge (along y) x B's edge, away from A; the edges' signed distance
    # along it is -DZ cos(THETA) (the crossing point is DZ straight below A's edge)
    n_edge = np.array([np.sin(THETA), 0.0, np.cos(THETA)])
    edge_depth = DZ * np.cos(THETA)
    # the closest points of the two lines: A's (H, y, H), B's b0 + t e_b
    a0 = np.array([H, 0.0, H])
    e_a = np.array([0.0, 1.0, 0.0])
    w = a0 - b0
    bb = e_a @ e_b
    den = 1.0 - bb * bb
    s_a = (bb * (e_b @ w) - (e_a @ w)) / den
    t_b = ((e_b @ w) - bb * (e_a @ w)) / den
    pa, pb = a0 + s_a * e_a, b0 + t_b * e_b
    np.testing.assert_allclose(pb - pa, -edge_depth * n_edge, atol=1e-15)
    # the face contact: reference face A's top (z = H, normal +z from A to B); B's incident face
    # (body z = -H) clipped to it; within the margin of it are B's inner corner (gap
    # S sin(THETA) - DZ) and the clip point at x = H on B's edge (gap -DZ, deeper than the edge
    # point, so left out: face_after_edge); the face's far side is 2H sin(PHI) up
    corner_gap = S * np.sin(THETA) - DZ
    assert corner_gap == pytest.approx(b0[2] - H, abs=1e-15)
    assert DZ > edge_depth

    assert len(rows["depth"]) == 2, rows
    assert (rows["a"] == 0).all() and (rows["b"] == 1).all()
    feature = rows["feature"] & 0xFFFFFFFF
    # row 0: the edge point
    assert feature[0] >> 31 == 1
    assert rows["depth"][0] == pytest.approx(edge_depth, abs=1e-13)
    np.testing.assert_allclose(rows["normal"][0], n_edge, atol=1e-13)
    np.testing.assert_allclose(rows["point"][0], 0.5 * (pa + pb), atol=1e-13)
    # row 1: the inner corner against A's top face, its signed distance to the plane z = H
    assert feature[1] >> 31 == 0
    np.testing.assert_array_equal(rows["normal"][1], [0.0, 0.0, 1.0])
    assert rows["depth"][1] == pytest.approx(-corner_gap, abs=1e-13)
    np.testing.assert_allclose(rows["point"][1], b0 - 0.5 * corner_gap * np.array([0, 0, 1.0]),
                               atol=1e-13)
    assert rows["depth"].max() == rows["depth"][0]
    # the other order of the colliders gives the same rows (a is the lower body), and detect3d
    # the same rows
    assert_same_rows(pair_rows(g, x, q, 1, 0), rows)
    c = new_contacts(g)
    detect3d(g, x, q, c)
    assert_same_rows(rows_of(c), rows)


# -- detect3d and collide_pair3d agree ---------------------------------------------------------
def _separation(half_a, ra, half_b, rb, t):
    """Largest separation over two boxes' 15 axes (numpy)."""
    axes = [ra[:, i] for i in range(3)] + [rb[:, j] for j in range(3)]
    axes += [np.cross(ra[:, i], rb[:, j]) for i in range(3) for j in range(3)]
    best = -np.inf
    for ax in axes:
        ln = np.linalg.norm(ax)
        if ln < 1e-9:
            continue
        ax = ax / ln
        ext = np.abs(ra.T @ ax) @ half_a + np.abs(rb.T @ ax) @ half_b
        best = max(best, abs(t @ ax) - ext)
    return best


def _place(rng, half_a, ra, half_b, rb, target):
    """A centre offset for B along a random direction at which the boxes separate by target."""
    u = rng.normal(size=3)
    u /= np.linalg.norm(u)
    lo, hi = 0.0, 2.0 * (np.linalg.norm(half_a) + np.linalg.norm(half_b)) + 1.0
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        if _separation(half_a, ra, half_b, rb, mid * u) < target:
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi) * u


SIZES = [((0.1, 0.1, 0.1), (0.1, 0.1, 0.1)), ((0.3, 0.2, 0.25), (0.1, 0.4, 0.05)),
         ((1.0, 0.02, 0.5), (0.2, 0.2, 0.2))]


def test_detect3d_and_collide_pair3d_agree_on_random_box_pairs():
    """500 seeded pairs (three size pairs, 1e3 m from the origin or not, from 8 mm apart to 20 mm
    deep): detect3d's rows are collide_pair3d's, bit for bit, in both collider orders; the edge
    contacts among them carry their faces' rows."""
    rng = np.random.default_rng(20261127)
    with_companion = 0
    touching = 0
    geoms = []
    for sa, sb in SIZES:
        sc = scene([body("A", Box(np.array(sa, float)), np.zeros(3)),
                    body("B", Box(np.array(sb, float)), np.ones(3))])
        geoms.append((compile_geometry(sc, MARGIN), np.array(sa) / 2, np.array(sb) / 2))
    c = new_contacts(geoms[0][0])
    for k in range(500):
        g, half_a, half_b = geoms[k % len(geoms)]
        rot_a, rot_b = Rotation.random(2, random_state=rng)
        ra, rb = rot_a.as_matrix(), rot_b.as_matrix()
        origin = np.array([1e3, -1e3, 1e3]) if k % 2 else np.zeros(3)
        t = _place(rng, half_a, ra, half_b, rb, rng.uniform(-0.02, MARGIN + 3e-3))
        x = np.array([origin, origin + t])
        q = np.array([quat(rot_a), quat(rot_b)])
        detect3d(g, x, q, c)
        found = rows_of(c)
        assert_same_rows(pair_rows(g, x, q, 0, 1), found)
        assert_same_rows(pair_rows(g, x, q, 1, 0), found)
        n = len(found["depth"])
        touching += n > 0
        if n and not (found["normal"] == found["normal"][0]).all():
            with_companion += 1
            assert (found["feature"][0] >> 31) & 1 == 1
            assert found["depth"][1:].max() <= found["depth"][0]
    assert touching > 400, touching
    assert with_companion >= 100, with_companion


def test_detect3d_and_collide_pair3d_agree_on_every_pair_of_mixed_clusters():
    """Every shape kind (hulls too): detect3d's rows of each pair (by the feature key's pair) are
    collide_pair3d's for that pair, and a pair detect3d gives no rows has none."""
    rng = np.random.default_rng(5)
    hull = trimesh.Trimesh(rng.normal(size=(24, 3)) * 0.05).convex_hull
    mesh = Mesh(path=Path("random.obj"), vertices=np.asarray(hull.vertices),
                faces=np.asarray(hull.faces))
    shapes = [Sphere(0.05), Box(np.array([0.1, 0.08, 0.12])), Capsule(0.03, 0.1),
              Cylinder(0.04, 0.1), mesh, Box(np.array([0.2, 0.03, 0.1]))]
    for trial in range(4):
        n_bodies = 16
        bodies = [body(f"b{i}", shapes[(i + trial) % len(shapes)], rng.uniform(-0.1, 0.1, 3),
                       quat(Rotation.random(random_state=rng))) for i in range(n_bodies)]
        sc = scene(bodies)
        g = compile_geometry(sc, MARGIN)
        x, q = state3d(sc)
        c = new_contacts(g, 2048)
        detect3d(g, x, q, c)
        found = rows_of(c)
        keys = found["feature"] >> 32
        for i in range(n_bodies):
            for j in range(i + 1, n_bodies):
                mine = keys == i * n_bodies + j
                expected = {f: v[mine] for f, v in found.items()}
                assert_same_rows(pair_rows(g, x, q, i, j), expected)
