"""Compiled cut-cell geometry of one moving body (a circle or a convex polygon) in a window of
the grid: what ``cutcell.py`` computes for the static obstacles, in closed form, every step.

``cutcell.py`` is generic (any convex shape through its signed distance: golden-section search
and bisection) and runs once at set-up; a coupled body needs its cut cells at every step, where
that costs about 100 ms on a 64 x 32 grid. Here the two kinds of 2D shape are done exactly:

* a segment against a circle: the roots of a quadratic; against a convex polygon: Cyrus-Beck
  clipping (the segment's parameter interval inside every edge's half-plane);
* the signed distance: ``|p - c| - R``; for a polygon the largest edge-line distance inside and
  the distance to the nearest edge outside;
* the solid area of a cell: a polygon clipped to the cell (Sutherland-Hodgman), exact; a
  circle by the chord length of horizontal lines across the cell, integrated in
  y with 16 Gauss-Legendre points per piece between the heights where the chord length has kinks
  (the polygon's vertices, the wall crossing the cell's vertical edges, the circle's top and
  bottom), after the substitution ``y = a + (b - a)(3 s^2 - 2 s^3)`` that smooths a circle's
  square-root ends: exact for polygons (the chord is linear between kinks), within about 1e-10
  of a cell for circles (tests/fluid/test_coupling.py compares both with ``cutcell``).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

CIRCLE, POLYGON = 0, 1
SNAP = 1e-9   # as cutcell.SNAP
_GS, _GW = np.polynomial.legendre.leggauss(16)
GAUSS_S = 0.5 * (_GS + 1.0)
GAUSS_W = 0.5 * _GW


def shape_params(placed) -> tuple[int, np.ndarray, float, np.ndarray]:
    """(kind, centre (2,), radius, world vertices (K, 2) counter-clockwise) of a placed circle,
    2D box or convex polygon."""
    inner = placed.shape
    kind = inner.kind
    pos = np.asarray(placed.position, float)
    rot = placed.rotation()
    if kind == "circle":
        return CIRCLE, pos.copy(), float(inner.radius), np.zeros((0, 2))
    if kind == "box":
        h = 0.5 * np.asarray(inner.size, float)
        local = np.array([[-h[0], -h[1]], [h[0], -h[1]], [h[0], h[1]], [-h[0], h[1]]])
    elif kind == "polygon":
        local = np.asarray(inner.vertices, float)
    else:
        raise ValueError(f"a coupled body is a circle, a box or a polygon, not a {kind!r}")
    world = local if rot is None else local @ rot.T
    return POLYGON, pos.copy(), 0.0, np.ascontiguousarray(world + pos)


@njit(cache=True)
def seg_interval(kind, c, r, verts, px, py, qx, qy):
    """Parameter interval [ta, tb] of the segment p -> q inside the shape (ta = tb: none)."""
    dx = qx - px
    dy = qy - py
    if kind == 0:
        fx = px - c[0]
        fy = py - c[1]
        a = dx * dx + dy * dy
        b = 2.0 * (fx * dx + fy * dy)
        cc = fx * fx + fy * fy - r * r
        disc = b * b - 4.0 * a * cc
        if disc <= 0.0 or a == 0.0:
            return 0.0, 0.0
        sq = math.sqrt(disc)
        t0 = (-b - sq) / (2.0 * a)
        t1 = (-b + sq) / (2.0 * a)
    else:
        t0 = -1e300
        t1 = 1e300
        k = verts.shape[0]
        for e in range(k):
            v0x = verts[e, 0]
            v0y = verts[e, 1]
            v1x = verts[(e + 1) % k, 0]
            v1y = verts[(e + 1) % k, 1]
            nx = v1y - v0y          # outward normal of a counter-clockwise edge
            ny = -(v1x - v0x)
            num = nx * (px - v0x) + ny * (py - v0y)
            den = nx * dx + ny * dy
            if den == 0.0:
                if num >= 0.0:
                    return 0.0, 0.0
                continue
            t = -num / den
            if den < 0.0:
                if t > t0:
                    t0 = t
            elif t < t1:
                t1 = t
    if t0 < 0.0:
        t0 = 0.0
    if t1 > 1.0:
        t1 = 1.0
    if t1 <= t0:
        return 0.0, 0.0
    return t0, t1


@njit(cache=True)
def _snap(f):
    if f < SNAP:
        return 0.0
    if f > 1.0 - SNAP:
        return 1.0
    return f


@njit(cache=True)
def signed_distance(kind, c, r, verts, x, y):
    if kind == 0:
        return math.hypot(x - c[0], y - c[1]) - r
    k = verts.shape[0]
    inside = -1e300
    best = 1e300
    for e in range(k):
        v0x = verts[e, 0]
        v0y = verts[e, 1]
        ex = verts[(e + 1) % k, 0] - v0x
        ey = verts[(e + 1) % k, 1] - v0y
        ln = math.hypot(ex, ey)
        d_line = (ey * (x - v0x) - ex * (y - v0y)) / ln
        if d_line > inside:
            inside = d_line
        t = ((x - v0x) * ex + (y - v0y) * ey) / (ln * ln)
        t = 0.0 if t < 0.0 else (1.0 if t > 1.0 else t)
        d = math.hypot(x - v0x - t * ex, y - v0y - t * ey)
        if d < best:
            best = d
    if inside <= 0.0:
        return inside
    return best


@njit(cache=True)
def _chord(kind, c, r, verts, y, x0, x1):
    ta, tb = seg_interval(kind, c, r, verts, x0, y, x1, y)
    return (tb - ta) * (x1 - x0)


@njit(cache=True)
def window_geometry(kind, c, r, verts, i0, j0, wi, wj, dx, gs, gw):
    """Face fractions (u (wi+1, wj), v (wi, wj+1)), the midpoints of their solid parts (in
    cells from the face's low end; 0.5 where the face is open), distances at the u, v samples
    and cell centres, and cell solid area fractions (wi, wj), for the window whose lower-left
    cell is (i0, j0)."""
    u_frac = np.zeros((wi + 1, wj))
    v_frac = np.zeros((wi, wj + 1))
    u_mid = np.full((wi + 1, wj), 0.5)
    v_mid = np.full((wi, wj + 1), 0.5)
    u_dist = np.empty((wi + 1, wj))
    v_dist = np.empty((wi, wj + 1))
    c_dist = np.empty((wi, wj))
    area = np.zeros((wi, wj))
    for a in range(wi + 1):
        x = (i0 + a) * dx
        for b in range(wj):
            y = (j0 + b) * dx
            ta, tb = seg_interval(kind, c, r, verts, x, y, x, y + dx)
            u_frac[a, b] = _snap(tb - ta)
            if u_frac[a, b] > 0.0:
                u_mid[a, b] = 0.5 * (ta + tb)
            u_dist[a, b] = signed_distance(kind, c, r, verts, x, y + 0.5 * dx)
    for a in range(wi):
        x = (i0 + a) * dx
        for b in range(wj + 1):
            y = (j0 + b) * dx
            ta, tb = seg_interval(kind, c, r, verts, x, y, x + dx, y)
            v_frac[a, b] = _snap(tb - ta)
            if v_frac[a, b] > 0.0:
                v_mid[a, b] = 0.5 * (ta + tb)
            v_dist[a, b] = signed_distance(kind, c, r, verts, x + 0.5 * dx, y)
    nk = verts.shape[0]
    brk = np.empty(2 + 4 + max(nk, 2))
    poly_a = np.empty((nk + 8, 2))
    poly_b = np.empty((nk + 8, 2))
    for a in range(wi):
        x0 = (i0 + a) * dx
        x1 = x0 + dx
        for b in range(wj):
            y0 = (j0 + b) * dx
            y1 = y0 + dx
            d = signed_distance(kind, c, r, verts, x0 + 0.5 * dx, y0 + 0.5 * dx)
            c_dist[a, b] = d
            if d <= -0.75 * dx:
                area[a, b] = 1.0
                continue
            if d >= 0.75 * dx:
                continue
            if kind == 1:
                area[a, b] = _snap(_polygon_in_box(verts, x0, y0, x1, y1, poly_a, poly_b)
                                   / (dx * dx))
                continue
            # break points of the chord length in [y0, y1]
            m = 0
            brk[m] = y0
            m += 1
            brk[m] = y1
            m += 1
            for xe in (x0, x1):
                ta, tb = seg_interval(kind, c, r, verts, xe, y0, xe, y1)
                if tb > ta:
                    brk[m] = y0 + ta * dx
                    m += 1
                    brk[m] = y0 + tb * dx
                    m += 1
            if kind == 0:
                for yk in (c[1] - r, c[1] + r):
                    brk[m] = min(max(yk, y0), y1)
                    m += 1
            else:
                for e in range(nk):
                    brk[m] = min(max(verts[e, 1], y0), y1)
                    m += 1
            pts = np.sort(brk[:m])
            acc = 0.0
            for q in range(m - 1):
                lo = pts[q]
                w = pts[q + 1] - lo
                if w <= 0.0:
                    continue
                for g in range(gs.shape[0]):
                    s = gs[g]
                    yy = lo + w * (3.0 * s * s - 2.0 * s * s * s)
                    acc += gw[g] * w * 6.0 * s * (1.0 - s) * _chord(kind, c, r, verts, yy,
                                                                      x0, x1)
            area[a, b] = _snap(acc / (dx * dx))
    return u_frac, v_frac, u_mid, v_mid, u_dist, v_dist, c_dist, area


@njit(cache=True)
def _clip_half(src, m, nx_, ny_, level, dst):
    """Sutherland-Hodgman: the first ``m`` points of ``src`` clipped to ``n . x <= level``,
    into ``dst``; returns the new count."""
    k = 0
    for e in range(m):
        ax = src[e, 0]
        ay = src[e, 1]
        bx = src[(e + 1) % m, 0]
        by = src[(e + 1) % m, 1]
        da = nx_ * ax + ny_ * ay - level
        db = nx_ * bx + ny_ * by - level
        if da <= 0.0:
            dst[k, 0] = ax
            dst[k, 1] = ay
            k += 1
        if (da < 0.0 and db > 0.0) or (da > 0.0 and db < 0.0):
            t = da / (da - db)
            dst[k, 0] = ax + t * (bx - ax)
            dst[k, 1] = ay + t * (by - ay)
            k += 1
    return k


@njit(cache=True)
def _polygon_in_box(verts, x0, y0, x1, y1, pa, pb):
    """Area of the convex polygon clipped to the box [x0, x1] x [y0, y1] (exact)."""
    m = verts.shape[0]
    for e in range(m):
        pa[e, 0] = verts[e, 0]
        pa[e, 1] = verts[e, 1]
    m = _clip_half(pa, m, 1.0, 0.0, x1, pb)
    if m < 3:
        return 0.0
    m = _clip_half(pb, m, -1.0, 0.0, -x0, pa)
    if m < 3:
        return 0.0
    m = _clip_half(pa, m, 0.0, 1.0, y1, pb)
    if m < 3:
        return 0.0
    m = _clip_half(pb, m, 0.0, -1.0, -y0, pa)
    if m < 3:
        return 0.0
    a2 = 0.0
    for e in range(m):
        a2 += pa[e, 0] * pa[(e + 1) % m, 1] - pa[(e + 1) % m, 0] * pa[e, 1]
    return 0.5 * abs(a2)


@njit(cache=True)
def clip_below(verts, nx_, ny_, level):
    """The part of the convex polygon ``verts`` where ``n . x < level`` (Sutherland-Hodgman),
    as (area, centroid x, centroid y)."""
    k = verts.shape[0]
    out = np.empty((2 * k + 2, 2))
    m = 0
    for e in range(k):
        ax = verts[e, 0]
        ay = verts[e, 1]
        bx = verts[(e + 1) % k, 0]
        by = verts[(e + 1) % k, 1]
        da = nx_ * ax + ny_ * ay - level
        db = nx_ * bx + ny_ * by - level
        if da < 0.0:
            out[m, 0] = ax
            out[m, 1] = ay
            m += 1
        if (da < 0.0) != (db < 0.0):
            t = da / (da - db)
            out[m, 0] = ax + t * (bx - ax)
            out[m, 1] = ay + t * (by - ay)
            m += 1
    if m < 3:
        return 0.0, 0.0, 0.0
    a2 = 0.0
    cx = 0.0
    cy = 0.0
    for e in range(m):
        x0 = out[e, 0]
        y0 = out[e, 1]
        x1 = out[(e + 1) % m, 0]
        y1 = out[(e + 1) % m, 1]
        cr = x0 * y1 - x1 * y0
        a2 += cr
        cx += (x0 + x1) * cr
        cy += (y0 + y1) * cr
    if a2 == 0.0:
        return 0.0, 0.0, 0.0
    return 0.5 * a2, cx / (3.0 * a2), cy / (3.0 * a2)


def wetted_moment_arm(kind: int, c: np.ndarray, r: float, verts: np.ndarray, up: np.ndarray,
                      level: float, about: np.ndarray) -> float:
    """The integral of ``(x - about) . n`` over the shape's boundary below the line ``up . x =
    level`` (n the outward normal): ``2 A_sub`` less the chord's share (the part below the line
    is closed by the chord, where ``n = up``; ``div (x - about) = 2``). The chord's length is the
    derivative of the area below the line with the level (central difference; the area is
    smooth in the level for a convex shape)."""
    area, _ = submerged(kind, c, r, verts, up, level)
    size = float(np.max(np.ptp(verts, axis=0))) if verts.size else 0.0   # a polygon's extent
    eps = 1e-7 * max(r, size, 1e-12)
    chord = (submerged(kind, c, r, verts, up, level + eps)[0]
             - submerged(kind, c, r, verts, up, level - eps)[0]) / (2.0 * eps)
    return 2.0 * area - (level - float(up @ about)) * chord


def submerged(kind: int, c: np.ndarray, r: float, verts: np.ndarray, up: np.ndarray,
              level: float) -> tuple[float, np.ndarray]:
    """Area and centroid of the shape's part below the line ``up . x = level`` (``up`` a unit
    vector against gravity): the exact displaced area of Archimedes' principle."""
    if kind == CIRCLE:
        h = level - float(up @ c)          # height of the line above the centre
        if h <= -r:
            return 0.0, c.copy()
        if h >= r:
            return math.pi * r * r, c.copy()
        # segment below the chord at signed height h: area and its centroid depth below c
        a = r * r * math.acos(h / r) - h * math.sqrt(r * r - h * h)
        area = math.pi * r * r - a          # a: the cap above the chord
        cap_centroid = 2.0 * (r * r - h * h) ** 1.5 / (3.0 * a) if a > 0 else r
        # the whole disc's moment is zero: area * z_below + a * z_cap = 0
        z = -a * cap_centroid / area if area > 0 else -r
        return area, c + z * up
    area, cx, cy = clip_below(verts, float(up[0]), float(up[1]), level)
    return float(area), np.array([cx, cy])

