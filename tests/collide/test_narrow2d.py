"""2D narrow phase through detect2d: circle/circle, circle/polygon, polygon/polygon and the ground
line, against closed forms and the support-function reference; rotated and far from the
origin."""

from __future__ import annotations

import numpy as np
import pytest
from collide_reference import gap_along, signed_distance2d
from collide_scenes import body, scene, state2d, static
from hypothesis import given, settings
from hypothesis import strategies as st

from crosscheck.scene.shapes import Box, Circle, Placed, Polygon
from crosscheck.sim.collide import compile_geometry, detect2d, new_contacts
from crosscheck.sim.collide.narrow2d import FACE_BIAS_ABS, FACE_BIAS_REL

MARGIN = 5e-3
FAR = np.array([1e4, -1e4])


def detect_pair(sa, pa, aa, sb, pb, ab, *, b_static=False, margin=MARGIN):
    bodies = [body("A", sa, pa, [aa])]
    statics = [static("B", sb, pb, [ab])] if b_static else []
    if not b_static:
        bodies.append(body("B", sb, pb, [ab]))
    sc = scene(bodies, statics, dimension=2)
    g = compile_geometry(sc, margin)
    c = new_contacts(g)
    detect2d(g, *state2d(sc), c)
    return [(int(c.a[k]), int(c.b[k]), c.normal[k].copy(), c.point[k].copy(), float(c.depth[k]))
            for k in range(c.n)]


def check_rows(rows, sa, pa, aa, sb, pb, ab, tol, bias=0.0):
    a, b = Placed(sa, pa, [aa]), Placed(sb, pb, [ab])
    ref, _ = signed_distance2d(a, b)
    if ref > MARGIN + tol:
        assert rows == []
        return
    if ref < MARGIN - tol - bias:
        assert rows
    if not rows:
        return
    assert len(rows) <= 2
    n = rows[0][2]
    assert abs(np.hypot(*n) - 1.0) < 1e-12
    deepest = max(r[4] for r in rows)
    along = float(gap_along(a, b, n)[0])
    assert abs(deepest + along) <= tol
    assert deepest <= -ref + tol + bias
    for ra, rb, nk, p, d in rows:
        assert (ra, rb) == (0, 1)
        np.testing.assert_array_equal(nk, n)
        for shape, s in ((a, 0.5), (b, -0.5)):
            assert abs(float(shape.signed_distance(p + s * d * n))) <= tol


def test_circles_closed_form():
    for offset in (np.zeros(2), FAR):
        for gap in (-0.03, 0.0, 0.004, 0.006):
            u = np.array([0.6, -0.8])
            rows = detect_pair(Circle(0.1), offset, 0.0, Circle(0.3), offset + (0.4 + gap) * u,
                               0.0)
            if gap > MARGIN:
                assert rows == []
                continue
            (_, _, n, p, d), = rows
            assert d == pytest.approx(-gap, abs=1e-11)
            np.testing.assert_allclose(n, u, atol=1e-12)
            np.testing.assert_allclose(p, offset + (0.1 + 0.5 * gap) * u, atol=1e-11)


def test_box_on_box_two_points_and_corner_on_face():
    sq = Box(np.array([1.0, 1.0]))
    rows = detect_pair(sq, np.zeros(2), 0.0, sq, np.array([0.3, 0.99]), 0.0)
    assert len(rows) == 2
    np.testing.assert_allclose(sorted(r[3][0] for r in rows), [-0.2, 0.5], atol=1e-12)
    for *_, n, _p, d in rows:
        np.testing.assert_allclose(n, [0, 1], atol=1e-15)
        assert d == pytest.approx(0.01, abs=1e-12)
    # a corner of B pointing down into A's top face
    rows = detect_pair(sq, np.zeros(2), 0.0, sq, np.array([0.1, 0.5 + np.sqrt(0.5) - 0.01]),
                       np.pi / 4)
    (_, _, n, p, d), = rows
    np.testing.assert_allclose(n, [0, 1], atol=1e-12)
    assert d == pytest.approx(0.01, abs=1e-12)
    np.testing.assert_allclose(p, [0.1, 0.495], atol=1e-12)


SHAPES = {"circle": Circle(0.12), "box": Box(np.array([0.3, 0.2])),
          "triangle": Polygon(np.array([[0.0, 0.0], [0.3, 0.05], [0.1, 0.25]])),
          "hexagon": Polygon(np.array([[np.cos(t), np.sin(t)] for t in
                                       np.linspace(0, 2 * np.pi, 6, endpoint=False)]) * 0.15)}
PAIRS = [(a, b) for i, a in enumerate(SHAPES) for b in list(SHAPES)[i:]]


@pytest.mark.parametrize(("ka", "kb"), PAIRS)
def test_pairs_against_reference_random_poses(ka, kb):
    rng = np.random.default_rng(sum(map(ord, ka + kb)))
    sa, sb = SHAPES[ka], SHAPES[kb]
    polygons = ka != "circle" and kb != "circle"
    bias = FACE_BIAS_ABS + FACE_BIAS_REL * 0.2 if polygons else 0.0
    for trial in range(20):
        offset = FAR if trial % 2 else np.zeros(2)
        aa, ab = rng.uniform(-np.pi, np.pi, 2)
        t = rng.uniform(-np.pi, np.pi)
        u = np.array([np.cos(t), np.sin(t)])
        a, b = Placed(sa, np.zeros(2), [aa]), Placed(sb, np.zeros(2), [ab])
        t0 = float(u @ a.support(u) - u @ b.support(-u))
        shift = [-0.05, -0.005, 0.0, 0.003, 0.02][trial % 5]
        pa = offset + rng.normal(size=2) * 0.01
        rows = detect_pair(sa, pa, aa, sb, pa + (t0 + shift) * u, ab)
        check_rows(rows, sa, pa, aa, sb, pa + (t0 + shift) * u, ab, tol=1e-10, bias=bias)


@settings(max_examples=60, deadline=None)
@given(st.floats(-np.pi, np.pi), st.floats(-np.pi, np.pi), st.floats(-0.05, 0.02),
       st.floats(-np.pi, np.pi))
def test_box_circle_property(angle_a, angle_b, shift, direction):
    sa, sb = SHAPES["box"], SHAPES["circle"]
    u = np.array([np.cos(direction), np.sin(direction)])
    a, b = Placed(sa, np.zeros(2), [angle_a]), Placed(sb, np.zeros(2), [angle_b])
    t0 = float(u @ a.support(u) - u @ b.support(-u))
    pb = (t0 + shift) * u
    rows = detect_pair(sa, np.zeros(2), angle_a, sb, pb, angle_b)
    check_rows(rows, sa, np.zeros(2), angle_a, sb, pb, angle_b, tol=1e-10)


def test_ground_line_and_static():
    sc = scene([body("box", Box(np.array([0.2, 0.2])), FAR + [0, 0.099]),
                body("tilted", Box(np.array([0.2, 0.2])), [3.0, np.sqrt(0.02) - 0.002],
                     [np.pi / 4]),
                body("ball", Circle(0.1), [5.048, 0.5])],
               [static("wall", Box(np.array([0.1, 1.0])), [5.2, 0.5])],
               ground=([0, 1], FAR[1]), dimension=2)
    # the ground line is y = -1e4: the first box sits on it, 1e4 m from the origin
    g = compile_geometry(sc, MARGIN)
    c = new_contacts(g)
    x, ang = state2d(sc)
    detect2d(g, x, ang, c)
    rows = [(int(c.a[k]), int(c.b[k]), c.normal[k].copy(), c.point[k].copy(), float(c.depth[k]))
            for k in range(c.n)]
    ground = [r for r in rows if r[0] == 0]
    assert len(ground) == 2
    for _, b, n, _p, d in ground:
        assert b == -1
        np.testing.assert_allclose(n, [0, -1])
        assert d == pytest.approx(0.001, abs=1e-11)
    # the ball is 2 mm from the wall's left face at x = 5.15: a speculative contact
    (ball,) = [r for r in rows if r[0] == 2]
    assert ball[1] == -1
    np.testing.assert_allclose(ball[2], [1, 0], atol=1e-15)
    assert ball[4] == pytest.approx(-0.002, abs=1e-12)
    assert not [r for r in rows if r[0] == 1]


def test_ground_line_tilted_box_and_circle():
    n = np.array([0.6, 0.8])
    sc = scene([body("tilted", Box(np.array([0.2, 0.2])), n * (np.sqrt(0.02) - 0.002), [0.3]),
                body("ball", Circle(0.1), n * 0.097 + [0.8, -0.6])], ground=(n, 0.0),
               dimension=2)
    g = compile_geometry(sc, MARGIN)
    c = new_contacts(g)
    detect2d(g, *state2d(sc), c)
    rows = [(int(c.a[k]), c.normal[k].copy(), c.point[k].copy(), float(c.depth[k]))
            for k in range(c.n)]
    box_rows = [r for r in rows if r[0] == 0]
    corners = Placed(Box(np.array([0.2, 0.2])), n * (np.sqrt(0.02) - 0.002), [0.3])
    lowest = np.min(corners.support(np.array([-n]))[0] @ n)
    assert max(r[3] for r in box_rows) == pytest.approx(-lowest, abs=1e-12)
    (ball,) = [r for r in rows if r[0] == 1]
    np.testing.assert_allclose(ball[1], -n, atol=1e-15)
    assert ball[3] == pytest.approx(0.003, abs=1e-12)
