"""Both broad phases (uniform grid, sweep and prune) against brute force on random scenes (3D and
2D), across steps that reuse the previous order, big moves, an axis change, large statics and
bodies kept out of the grid, and collide = false."""

from __future__ import annotations

import numpy as np
import pytest
from collide_scenes import STEEL, body, scene, state2d, state3d, static
from scipy.spatial.transform import Rotation

from crosscheck.scene.model import Material
from crosscheck.scene.shapes import Box, Capsule, Circle, Cylinder, Polygon, Sphere
from crosscheck.sim.collide import compile_geometry
from crosscheck.sim.collide.broadphase import brute_force_pairs, grid_pairs, sweep_and_prune
from crosscheck.sim.collide.pose import (
    bounding_boxes2d,
    bounding_boxes3d,
    world_poses2d,
    world_poses3d,
)

RUBBER = Material("rubber", friction=1.0)


def random_scene3d(rng, n, spread):
    shapes = [Sphere(0.1), Box(np.array([0.2, 0.1, 0.3])), Capsule(0.05, 0.2),
              Cylinder(0.08, 0.15)]
    bodies = []
    for i in range(n):
        q = Rotation.random(random_state=rng).as_quat()[[3, 0, 1, 2]]
        bodies.append(body(f"b{i}", shapes[i % 4], rng.uniform(-spread, spread, 3), q,
                           material=RUBBER if i % 3 == 0 else STEEL))
    statics = [static("wall", Box(np.array([0.1, 2 * spread, 1.0])), [spread, 0, 0]),
               static("post", Cylinder(0.1, 1.0), [0, 0, 0])]
    # b1 and b4 never collide, nor b0 and the wall
    overrides = [("b1", "b4", {"collide": False}), ("b0", "wall", {"collide": False})]
    return scene(bodies, statics, overrides=overrides)


def found(find, g, lo, hi):
    """(pairs, count) of a broad-phase function, on an array it fits in (a second run when the
    first array was too small, as broad_phase does)."""
    buf = np.empty((64, 2), np.int64)
    n = find(g, lo, hi, buf)
    if n > len(buf):
        buf = np.empty((n, 2), np.int64)
        assert find(g, lo, hi, buf) == n
    return buf, n


def pair_set(pairs, n):
    return {(int(pairs[k, 0]), int(pairs[k, 1])) for k in range(n)}


def boxes3d(g, x, q):
    c = len(g.kind)
    wpos, wrot = np.empty((c, 3)), np.empty((c, 3, 3))
    lo, hi = np.empty((c, 3)), np.empty((c, 3))
    world_poses3d(g, x, q, wpos, wrot)
    bounding_boxes3d(g, wpos, wrot, 0.5 * g.margin, lo, hi)
    return lo, hi


METHODS = {"grid": grid_pairs, "sweep": sweep_and_prune}


@pytest.mark.parametrize("method", list(METHODS))
def test_broad_phase_matches_brute_force_3d_over_steps(method):
    rng = np.random.default_rng(1)
    sc = random_scene3d(rng, 300, 1.5)
    find = METHODS[method]
    g = compile_geometry(sc, broadphase=method)
    x, q = state3d(sc)
    for step in range(12):
        lo, hi = boxes3d(g, x, q)
        expected, ne = found(brute_force_pairs, g, lo, hi)
        got, ng = found(find, g, lo, hi)
        assert ng == len(pair_set(got, ng))  # no pair twice
        assert pair_set(got, ng) == pair_set(expected, ne)
        assert ne > 50
        assert (1, 4) not in pair_set(got, ng)
        # the same state on a fresh geometry (no previous order): the same pairs in the same order
        fresh = compile_geometry(sc, broadphase=method)
        again, na = found(find, fresh, lo, hi)
        np.testing.assert_array_equal(again[:na], got[:ng])
        # small moves (the order is nearly kept), then a big one (it is not)
        x = x + rng.normal(scale=0.3 if step == 6 else 0.01, size=x.shape)
        if step == 8:
            x = x * np.array([0.1, 1.0, 3.0])  # the axis of largest spread changes to z


@pytest.mark.parametrize("method", list(METHODS))
def test_broad_phase_matches_brute_force_2d(method):
    rng = np.random.default_rng(2)
    tri = Polygon(np.array([[0.0, 0.0], [0.2, 0.0], [0.0, 0.15]]))
    shapes = [Circle(0.1), Box(np.array([0.2, 0.1])), tri]
    bodies = [body(f"b{i}", shapes[i % 3], rng.uniform(-2, 2, 2), [rng.uniform(-3, 3)])
              for i in range(400)]
    # a long floor (out of the grid) and a big body among small ones
    bodies.append(body("plank", Box(np.array([3.0, 0.1])), [0.0, 0.0], [0.3]))
    sc = scene(bodies, [static("floor", Box(np.array([5.0, 0.2])), [0.0, -2.2])], dimension=2)
    g = compile_geometry(sc, broadphase=method)
    assert len(g.grid_big) == 2
    x, a = state2d(sc)
    c = len(g.kind)
    for _ in range(5):
        wpos, wrot = np.empty((c, 2)), np.empty((c, 2))
        lo, hi = np.empty((c, 2)), np.empty((c, 2))
        world_poses2d(g, x, a, wpos, wrot)
        bounding_boxes2d(g, wpos, wrot, 0.5 * g.margin, lo, hi)
        expected, ne = found(brute_force_pairs, g, lo, hi)
        got, ng = found(METHODS[method], g, lo, hi)
        assert pair_set(got, ng) == pair_set(expected, ne)
        assert ne > 50
        x = x + rng.normal(scale=0.02, size=x.shape)
        a = a + rng.normal(scale=0.1, size=a.shape)


def test_bounding_boxes_are_tight_and_hold_the_shape():
    from crosscheck.scene.shapes import world_bounding_box

    rng = np.random.default_rng(3)
    sc = random_scene3d(rng, 40, 1.0)
    g = compile_geometry(sc, margin=0.0)
    x, q = state3d(sc)
    lo, hi = boxes3d(g, x, q)
    for i, b in enumerate(sc.bodies):
        elo, ehi = world_bounding_box(b.shape, b.position, b.orientation)
        np.testing.assert_allclose(lo[i], elo, atol=1e-12)
        np.testing.assert_allclose(hi[i], ehi, atol=1e-12)
