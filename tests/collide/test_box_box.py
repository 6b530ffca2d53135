"""Box-box detection: the box shortcuts of detect.py (box_box_bounds' early-out and the skipped edge
query, polytope3d.py) against the general polytope routine, which they must reproduce bit for
bit, on many seeded random pairs: rotated, 1e3 m from the origin, apart beyond the margin,
touching within it, deep, edge-edge, face-face, vertex-face, near-parallel faces; and the
feature keys under tiny motions."""

from __future__ import annotations

import numpy as np
import pytest
from collide_scenes import body, scene
from scipy.spatial.transform import Rotation

from crosscheck.scene.shapes import Box
from crosscheck.sim.collide import compile_geometry
from crosscheck.sim.collide.detect import box_box
from crosscheck.sim.collide.manifold import new_manifold
from crosscheck.sim.collide.polytope3d import (
    PARALLEL,
    box_box_bounds,
    new_polytope_scratch,
    polytope_polytope,
)

MARGIN = 5e-3
SIZES = [((0.1, 0.1, 0.1), (0.1, 0.1, 0.1)), ((0.3, 0.2, 0.25), (0.1, 0.4, 0.05)),
         ((1.0, 0.02, 0.5), (0.2, 0.2, 0.2))]


class Pair:
    """Two box bodies of the given full sizes, posed by hand (wpos, wrot of colliders 0, 1)."""

    def __init__(self, size_a, size_b):
        sc = scene([body("A", Box(np.array(size_a, float)), np.zeros(3)),
                    body("B", Box(np.array(size_b, float)), np.ones(3))])
        self.g = g = compile_geometry(sc, MARGIN)
        self.half = np.array([size_a, size_b], float) / 2
        self.scratch = new_polytope_scratch(g.max_poly_verts, g.max_poly_faces, g.max_poly_edges,
                                            2 * g.max_face_verts + 68)

    def run(self, pa, ra, pb, rb, general):
        wpos = np.array([pa, pb], float)
        wrot = np.array([ra, rb], float)
        man = new_manifold(3)
        if general:
            n = polytope_polytope(self.g, wpos, wrot, 0, 1, MARGIN, man, self.scratch, np.inf)
        else:
            n = box_box(self.g, self.g.size, wpos, wrot, 0, 1, MARGIN, man, self.scratch)
        return (n, man.normal.copy(), man.point[:max(n, 0)].copy(), man.depth[:max(n, 0)].copy(),
                man.feature[:max(n, 0)].copy())

    def bounds(self, pa, ra, pb, rb):
        return box_box_bounds(np.array([pa, pb], float), np.array([ra, rb], float), self.g.size,
                              0, 1)


def separating_axes(half_a, ra, half_b, rb):
    """The 15 SAT axes (face normals of both, then the non-degenerate cross axes) with the sum of
    both boxes' projected half extents on each (numpy, for placing pairs at a chosen gap)."""
    axes = [ra[:, i] for i in range(3)] + [rb[:, j] for j in range(3)]
    for i in range(3):
        for j in range(3):
            c = np.cross(ra[:, i], rb[:, j])
            if np.linalg.norm(c) > 1e-6:
                axes.append(c / np.linalg.norm(c))
    return [(u, np.sum(half_a * np.abs(ra.T @ u)), np.sum(half_b * np.abs(rb.T @ u)))
            for u in axes]


def sat_separation(half_a, ra, half_b, rb, t, axes=None):
    """Largest separation over the 15 axes at centre offset t (``axes``: separating_axes of the
    same boxes, computed once for many offsets; the same numbers either way)."""
    best = -np.inf
    for u, extent_a, extent_b in axes or separating_axes(half_a, ra, half_b, rb):
        s = (abs(t @ u) - extent_a - extent_b)
        best = max(best, s)
    return best


def place(pair, ra, rb, u, gap):
    """Distance along u at which the 15-axis separation is ``gap`` (bisection; the axes and the
    boxes' extents on them do not depend on the distance and are computed once)."""
    axes = separating_axes(pair.half[0], ra, pair.half[1], rb)
    lo, hi = 0.0, 2.0 * (np.linalg.norm(pair.half[0]) + np.linalg.norm(pair.half[1])) + 1.0
    for _ in range(80):
        mid = 0.5 * (lo + hi)
        if sat_separation(pair.half[0], ra, pair.half[1], rb, mid * u, axes) > gap:
            hi = mid
        else:
            lo = mid
    return 0.5 * (lo + hi)


def random_rotation(rng, kind):
    if kind == "random":
        return Rotation.random(random_state=rng).as_matrix()
    if kind == "aligned":  # face-face: axis-aligned up to a tiny tilt (near-parallel faces)
        tilt = rng.choice([0.0, 1e-9, 1e-7, 1e-5, 1e-3])
        return Rotation.from_rotvec(tilt * rng.normal(size=3)).as_matrix()
    if kind == "edge":  # 45 degrees about a box axis: an edge leads
        axis = np.zeros(3)
        axis[rng.integers(3)] = 1.0
        return Rotation.from_rotvec(np.pi / 4 * axis + 1e-6 * rng.normal(size=3)).as_matrix()
    # vertex: a corner along the leading direction
    return Rotation.align_vectors([[0, 0, -1.0]], [[1.0, 1.0, 1.0]])[0].as_matrix()


def assert_same(fast, ref):
    n, normal, point, depth, feature = fast
    n0, normal0, point0, depth0, feature0 = ref
    assert n == n0
    if n > 0:
        assert np.array_equal(normal, normal0)
        assert np.array_equal(point, point0)
        assert np.array_equal(depth, depth0)
        assert np.array_equal(feature, feature0)


@pytest.mark.parametrize("sizes", SIZES)
def test_box_shortcuts_reproduce_the_general_routine(sizes):
    pair = Pair(*sizes)
    rng = np.random.default_rng(20261127)
    kinds = ["random", "aligned", "edge", "vertex"]
    outcomes = {"apart": 0, "early_out": 0, "face": 0, "edge": 0}
    for trial in range(600):
        ka, kb = kinds[trial % 4], kinds[(trial // 4) % 4]
        ra, rb = random_rotation(rng, ka), random_rotation(rng, kb)
        u = rng.normal(size=3)
        if trial % 3 == 0:  # along a box axis (face-face, vertex-face)
            u = ra[:, rng.integers(3)] * rng.choice([-1.0, 1.0])
        u /= np.linalg.norm(u)
        gap = rng.choice([-0.2, -0.02, -1e-3, -1e-6, 0.0, 1e-9, 0.5 * MARGIN, MARGIN - 1e-9,
                          MARGIN, MARGIN + 1e-9, MARGIN + 1e-6, 2 * MARGIN, 0.1])
        gap *= 1.0 if abs(gap) < 0.01 else min(pair.half.min(), 1.0) / 0.05
        d = place(pair, ra, rb, u, gap)
        origin = np.zeros(3) if trial % 2 else np.array([1e3, -1e3, 1e3]) * rng.uniform(0.5, 1)
        pa, pb = origin, origin + d * u
        fast = pair.run(pa, ra, pb, rb, general=False)
        ref = pair.run(pa, ra, pb, rb, general=True)
        assert_same(fast, ref)
        sep, _, tol = pair.bounds(pa, ra, pb, rb)
        if ref[0] == 0:
            outcomes["apart"] += 1
            outcomes["early_out"] += sep > MARGIN + tol
        else:
            outcomes["edge" if ref[4][0] & (1 << 31) else "face"] += 1
    # every branch taken: pairs apart (most by the early-out), face and edge contacts
    assert outcomes["early_out"] > 50 and outcomes["face"] > 50 and outcomes["edge"] > 5, outcomes


def test_bounds_match_closed_forms():
    """Aligned cubes 0.1 m apart along x: separation 0.1 m, the cross axes a_i x b_j (i != j) are
    face axes again (a_i x b_i degenerate, left out): the same 0.1 m. A cube
    turned 45 degrees about z beside an aligned one: its edge leads, the x face axis of A and
    the edge axis give the same gap."""
    pair = Pair((0.2, 0.2, 0.2), (0.2, 0.2, 0.2))
    eye = np.eye(3)
    sep, edge, tol = pair.bounds(np.zeros(3), eye, np.array([0.3, 0.0, 0.0]), eye)
    assert sep == pytest.approx(0.1, abs=1e-15)
    assert edge == pytest.approx(0.1, abs=1e-15)
    assert 0 < tol < 1e-8
    rz = Rotation.from_rotvec([0, 0, np.pi / 4]).as_matrix()
    x = 0.1 + 0.1 * np.sqrt(2) + 0.05
    sep, edge, _ = pair.bounds(np.zeros(3), eye, np.array([x, 0.0, 0.0]), rz)
    assert sep == pytest.approx(0.05, abs=1e-12)
    assert edge <= sep + 1e-12


def test_near_parallel_axes_do_not_separate():
    """A cross axis of nearly parallel edges (|a x b| below 2 PARALLEL) is round-off: it may
    bound the edge separation but never ends the pair early."""
    pair = Pair((0.1, 0.1, 0.1), (0.1, 0.1, 0.1))
    for tilt in (1e-12, 1e-9, 0.4 * PARALLEL, 1.5 * PARALLEL, 3 * PARALLEL, 1e-4):
        rb = Rotation.from_rotvec([tilt, 0.0, 0.0]).as_matrix()
        pb = np.array([0.0, 0.0, 0.1 - 1e-3])  # resting, 1 mm deep
        fast = pair.run(np.zeros(3), np.eye(3), pb, rb, general=False)
        assert_same(fast, pair.run(np.zeros(3), np.eye(3), pb, rb, general=True))
        assert fast[0] == 4


@pytest.mark.parametrize("config", ["face", "edge", "vertex"])
def test_feature_keys_stable_under_tiny_motions(config):
    pair = Pair((0.1, 0.1, 0.1), (0.1, 0.1, 0.1))
    eye = np.eye(3)
    if config == "face":
        # offset, not turned: the overlap has 4 corners. (Where clipping gives more than 4 points
        # at one depth, which 4 the reduction keeps is round-off, in the general routine too.)
        rb = np.eye(3)
        pb = np.array([0.01, 0.02, 0.1 - 2e-3])
    elif config == "edge":
        ra = Rotation.from_rotvec([np.pi / 4, 0, 0]).as_matrix()
        rb = Rotation.from_rotvec([0, np.pi / 4, 0]).as_matrix()
        eye = ra
        pb = np.array([0.01, -0.005, 0.1 * np.sqrt(0.5) * 2 - 1e-3])
    else:
        # a corner down, tilted off the symmetric pose (where B's three faces at the corner are
        # equally anti-parallel to A's and the incident face is round-off, in the general
        # routine too)
        rb = (Rotation.from_rotvec([0.1, 0.05, 0.0])
              * Rotation.align_vectors([[0, 0, -1.0]], [[1.0, 1.0, 1.0]])[0]).as_matrix()
        corners = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)]) * 0.05
        pb = np.array([0.01, 0.02, 0.05 - (corners @ rb.T)[:, 2].min() - 1e-3])
    base = pair.run(np.zeros(3), eye, pb, rb, general=False)
    assert base[0] > 0
    keys = set(base[4].tolist())
    rng = np.random.default_rng(7)
    for _ in range(50):
        dp = 1e-7 * rng.normal(size=3)
        dr = Rotation.from_rotvec(1e-7 * rng.normal(size=3)).as_matrix()
        moved = pair.run(np.zeros(3), eye, pb + dp, dr @ rb, general=False)
        assert_same(moved, pair.run(np.zeros(3), eye, pb + dp, dr @ rb, general=True))
        assert set(moved[4].tolist()) == keys
        np.testing.assert_allclose(moved[1], base[1], atol=1e-5)
