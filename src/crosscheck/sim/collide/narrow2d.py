"""Narrow phase in 2D: circle/circle, circle/polygon, polygon/polygon (separating axes with the
incident edge clipped to the reference edge, up to two points), and each against the ground line.

The conventions of narrow3d.py: a routine for (A, B) writes the normal from A to B, per point the
midpoint between the surfaces, the depth (positive overlap, negative gap down to ``-margin``) and
a local feature id into a 2D :class:`~crosscheck.sim.collide.manifold.Manifold`, and returns the
count. Poses: ``wpos (C, 2)``, ``wrot (C, 2)`` = (cos, sin) of each collider's world angle.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from crosscheck.sim._jit import INLINE, JIT
from crosscheck.sim.collide.geometry import CIRCLE


@njit(**INLINE)
def put2(man, k, px, py, depth, feature):
    man.point[k, 0] = px
    man.point[k, 1] = py
    man.depth[k] = depth
    man.feature[k] = feature


@njit(**INLINE)
def normal2(man, nx, ny):
    man.normal[0] = nx
    man.normal[1] = ny


@njit(**INLINE)
def vertex_world(geom, wpos, wrot, c, v):
    """World position of polygon vertex v (global index) of collider c."""
    co, si = wrot[c, 0], wrot[c, 1]
    x, y = geom.vertices[v, 0], geom.vertices[v, 1]
    return wpos[c, 0] + co * x - si * y, wpos[c, 1] + si * x + co * y


@njit(**INLINE)
def normal_world(geom, wrot, c, v):
    """World outward normal of the edge from vertex v to v + 1 of collider c."""
    co, si = wrot[c, 0], wrot[c, 1]
    x, y = geom.edge_normal[v, 0], geom.edge_normal[v, 1]
    return co * x - si * y, si * x + co * y


@njit(**INLINE)
def circles(ax, ay, ra, bx, by, rb, margin, man, k, feature, fx, fy):
    """Point k for circles (a, ra), (b, rb), normal a to b (fallback (fx, fy) on coincident
    centres)."""
    dx, dy = bx - ax, by - ay
    dist = np.sqrt(dx * dx + dy * dy)
    nx, ny = fx, fy
    if dist > 0.0:
        nx, ny = dx / dist, dy / dist
    gap = dist - ra - rb
    if gap > margin:
        return k
    normal2(man, nx, ny)
    h = 0.5 * (ra - rb)
    put2(man, k, 0.5 * (ax + bx) + h * nx, 0.5 * (ay + by) + h * ny, -gap, feature)
    return k + 1


@njit(**JIT)
def circle_polygon(geom, wpos, wrot, ca, cb, margin, man):
    """Circle A against polygon B: the edge of B the centre is farthest outside of, then the
    centre's Voronoi region of that edge (the edge itself or one of its end vertices)."""
    r = geom.radius[ca]
    cx, cy = wpos[ca, 0], wpos[ca, 1]
    p = geom.polygon[cb]
    v0, nv = geom.poly_vert_start[p], geom.poly_vert_count[p]
    best = -np.inf
    e = 0
    for k in range(nv):
        px, py = vertex_world(geom, wpos, wrot, cb, v0 + k)
        nx, ny = normal_world(geom, wrot, cb, v0 + k)
        s = nx * (cx - px) + ny * (cy - py)
        if s > best:
            best = s
            e = k
    if best - r > margin:
        return 0
    x1, y1 = vertex_world(geom, wpos, wrot, cb, v0 + e)
    x2, y2 = vertex_world(geom, wpos, wrot, cb, v0 + (e + 1) % nv)
    nx, ny = normal_world(geom, wrot, cb, v0 + e)
    if best > 0.0:
        # outside: a vertex region when the centre projects beyond an end of the edge
        if (cx - x1) * (x2 - x1) + (cy - y1) * (y2 - y1) < 0.0:
            return circles(cx, cy, r, x1, y1, 0.0, margin, man, 0, 1 + e, -nx, -ny)
        if (cx - x2) * (x1 - x2) + (cy - y2) * (y1 - y2) < 0.0:
            return circles(cx, cy, r, x2, y2, 0.0, margin, man, 0, 1 + (e + 1) % nv, -nx, -ny)
    # the edge's region (or inside): the normal is the edge's, from the circle into B
    gap = best - r
    normal2(man, -nx, -ny)
    # circle point c - r n, polygon point c - best n: midway
    put2(man, 0, cx - (0.5 * (r + best)) * nx, cy - (0.5 * (r + best)) * ny, -gap,
         0x10000 | e)
    return 1


@njit(**INLINE)
def _max_separation(geom, wpos, wrot, c1, c2):
    """The edge of polygon c1 that polygon c2 is farthest outside of (min over c2's vertices of
    the distance above the edge): (separation, edge index local to c1)."""
    p1, p2 = geom.polygon[c1], geom.polygon[c2]
    s1, n1 = geom.poly_vert_start[p1], geom.poly_vert_count[p1]
    s2, n2 = geom.poly_vert_start[p2], geom.poly_vert_count[p2]
    best = -np.inf
    edge = 0
    for i in range(n1):
        nx, ny = normal_world(geom, wrot, c1, s1 + i)
        px, py = vertex_world(geom, wpos, wrot, c1, s1 + i)
        s = np.inf
        for j in range(n2):
            qx, qy = vertex_world(geom, wpos, wrot, c2, s2 + j)
            s = min(s, nx * (qx - px) + ny * (qy - py))
        if s > best:
            best = s
            edge = i
    return best, edge


# Reference polygon: A's edge unless B's separates by more than this (absolute m + relative).
FACE_BIAS_ABS = 1e-6
FACE_BIAS_REL = 0.02


@njit(**JIT)
def polygon_polygon(geom, wpos, wrot, ca, cb, margin, man):
    """Separating axes of both polygons; the incident edge (the other polygon's edge most
    anti-parallel to the reference edge) clipped to the reference edge's extent; up to two points
    within the margin of the reference edge."""
    sa, ea = _max_separation(geom, wpos, wrot, ca, cb)
    if sa > margin:
        return 0
    sb, eb = _max_separation(geom, wpos, wrot, cb, ca)
    if sb > margin:
        return 0
    flip = sb > sa + FACE_BIAS_ABS + FACE_BIAS_REL * abs(sa)
    cr, ci, er = ca, cb, ea
    if flip:
        cr, ci, er = cb, ca, eb
    pr, pi = geom.polygon[cr], geom.polygon[ci]
    sr, nr = geom.poly_vert_start[pr], geom.poly_vert_count[pr]
    si, ni = geom.poly_vert_start[pi], geom.poly_vert_count[pi]
    nx, ny = normal_world(geom, wrot, cr, sr + er)
    best = np.inf
    ei = 0
    for k in range(ni):
        mx, my = normal_world(geom, wrot, ci, si + k)
        d = mx * nx + my * ny
        if d < best:
            best = d
            ei = k
    # incident segment, reference edge r1 -> r2 with tangent t
    ix1, iy1 = vertex_world(geom, wpos, wrot, ci, si + ei)
    ix2, iy2 = vertex_world(geom, wpos, wrot, ci, si + (ei + 1) % ni)
    rx1, ry1 = vertex_world(geom, wpos, wrot, cr, sr + er)
    rx2, ry2 = vertex_world(geom, wpos, wrot, cr, sr + (er + 1) % nr)
    tx, ty = rx2 - rx1, ry2 - ry1
    # keep the part of the incident segment between the two side lines t . p = t . r1, t . r2
    lo_side = tx * rx1 + ty * ry1
    hi_side = tx * rx2 + ty * ry2
    d1 = tx * ix1 + ty * iy1
    d2 = tx * ix2 + ty * iy2
    f1, f2 = 0, 1  # feature of each end: incident vertex (0, 1) or clipped at a side (2, 3)
    if d1 != d2:
        # parameter along the incident segment of the two side lines
        ta = (lo_side - d1) / (d2 - d1)
        tb = (hi_side - d1) / (d2 - d1)
        t0, t1 = min(ta, tb), max(ta, tb)
        u0, u1 = 0.0, 1.0
        if t0 > 0.0:
            u0 = t0
            f1 = 2
        if t1 < 1.0:
            u1 = t1
            f2 = 3
        if u0 > u1:
            return 0
    else:
        u0, u1 = 0.0, 1.0
        if d1 < min(lo_side, hi_side) or d1 > max(lo_side, hi_side):
            return 0
    ex, ey = ix2 - ix1, iy2 - iy1
    offset = nx * rx1 + ny * ry1
    if flip:
        normal2(man, -nx, -ny)
    else:
        normal2(man, nx, ny)
    head = ((1 << 24) if flip else 0) | ((er & 0xFF) << 16) | ((ei & 0xFF) << 8)
    count = 0
    for end in range(2):
        u = u0 if end == 0 else u1
        feature = f1 if end == 0 else f2
        px, py = ix1 + u * ex, iy1 + u * ey
        gap = nx * px + ny * py - offset
        if gap <= margin:
            put2(man, count, px - 0.5 * gap * nx, py - 0.5 * gap * ny, -gap, head | feature)
            count += 1
    return count


@njit(**JIT)
def line_collider(geom, wpos, wrot, c, g, margin, man):
    """Collider c (a body) against ground line g: a circle's lowest point; a polygon's vertices
    within the margin, the deepest two kept (normal from the body into the ground: -n)."""
    nx, ny, offset = geom.plane_normal[g, 0], geom.plane_normal[g, 1], geom.plane_offset[g]
    normal2(man, -nx, -ny)
    if geom.kind[c] == CIRCLE:
        r = geom.radius[c]
        px, py = wpos[c, 0] - r * nx, wpos[c, 1] - r * ny
        gap = nx * px + ny * py - offset
        if gap > margin:
            return 0
        put2(man, 0, px - 0.5 * gap * nx, py - 0.5 * gap * ny, -gap, 0)
        return 1
    p = geom.polygon[c]
    s0 = geom.poly_vert_start[p]
    count = 0
    for k in range(geom.poly_vert_count[p]):
        px, py = vertex_world(geom, wpos, wrot, c, s0 + k)
        gap = nx * px + ny * py - offset
        if gap > margin:
            continue
        slot = count
        if count == 2:
            # keep the two deepest: replace the shallower of the two if this one is deeper
            slot = 0 if man.depth[0] < man.depth[1] else 1
            if -gap <= man.depth[slot]:
                continue
        else:
            count += 1
        put2(man, slot, px - 0.5 * gap * nx, py - 0.5 * gap * ny, -gap, k)
    return count
