"""Stage-1 checks of the whole detection on small scenes: a box flat on the ground gives its four
corners, a box on a box four face points, spheres their closed-form depth; the 2D equivalents."""

from __future__ import annotations

import numpy as np
from collide_scenes import body, scene, state2d, state3d

from crosscheck.scene.shapes import Box, Circle, Sphere
from crosscheck.sim.collide.detect import detect2d, detect3d, new_contacts
from crosscheck.sim.collide.geometry import compile_geometry


def _rows(c):
    n = c.n
    return [(int(c.a[k]), int(c.b[k]), c.normal[k].copy(), c.point[k].copy(), float(c.depth[k]))
            for k in range(n)]


def test_box_flat_on_ground_gives_its_four_corners():
    sc = scene([body("box", Box(np.array([0.2, 0.4, 0.2])), [1.0, 2.0, 0.099])],
               ground=([0, 0, 1], 0.0))
    g = compile_geometry(sc)
    c = new_contacts(g)
    detect3d(g, *state3d(sc), c)
    rows = _rows(c)
    assert len(rows) == 4
    corners = {(round(p[0], 9), round(p[1], 9)) for _, _, _, p, _ in rows}
    assert corners == {(0.9, 1.8), (0.9, 2.2), (1.1, 1.8), (1.1, 2.2)}
    for a, b, n, p, d in rows:
        assert (a, b) == (0, -1)
        np.testing.assert_allclose(n, [0, 0, -1])
        assert abs(d - 0.001) < 1e-15
        assert abs(p[2] - (-0.0005)) < 1e-15


def test_box_on_box_four_face_points_and_spheres():
    sc = scene([body("a", Sphere(0.1), [0, 0, 1.0]), body("b", Sphere(0.2), [0.29, 0, 1.0]),
                body("c", Box(np.array([0.2, 0.2, 0.2])), [3, 0, 0.1]),
                body("d", Box(np.array([0.2, 0.2, 0.2])), [3.05, 0, 0.299])])
    g = compile_geometry(sc)
    c = new_contacts(g)
    detect3d(g, *state3d(sc), c)
    rows = _rows(c)
    spheres = [r for r in rows if r[0] == 0]
    assert len(spheres) == 1
    a, b, n, p, d = spheres[0]
    assert b == 1
    np.testing.assert_allclose(n, [1, 0, 0])
    assert abs(d - 0.01) < 1e-15
    np.testing.assert_allclose(p, [0.095, 0, 1.0], atol=1e-15)
    boxes = [r for r in rows if r[0] == 2]
    assert len(boxes) == 4
    for _, b, n, _p, d in boxes:
        assert b == 3
        np.testing.assert_allclose(n, [0, 0, 1], atol=1e-15)
        assert abs(d - 0.001) < 1e-12


def test_2d_box_on_ground_and_circle_on_box():
    sc = scene([body("box", Box(np.array([0.2, 0.2])), [0.5, 0.099]),
                body("ball", Circle(0.1), [0.5, 0.3])], ground=([0, 1], 0.0), dimension=2)
    g = compile_geometry(sc)
    c = new_contacts(g)
    detect2d(g, *state2d(sc), c)
    rows = _rows(c)
    ground = sorted(r[3][0] for r in rows if r[1] == -1 and r[0] == 0)
    np.testing.assert_allclose(ground, [0.4, 0.6])
    ball = [r for r in rows if r[0] == 0 and r[1] == 1]
    assert len(ball) == 1
    np.testing.assert_allclose(ball[0][2], [0, 1], atol=1e-15)
    assert abs(ball[0][4] + 0.001) < 1e-12  # 1 mm apart: a speculative contact
