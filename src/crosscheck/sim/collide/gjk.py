"""GJK and EPA on the colliders' support mappings: the distance between two convex shapes, and
the penetration (depth and direction) when they overlap.

Every shape is a *core* plus a radius: a sphere is its centre with radius r, a capsule its axis
segment with radius r, a box, a cylinder and a hull are themselves with radius 0. GJK runs on the
cores (Gilbert, Johnson and Keerthi 1988, with the closest point of each simplex found by its
Voronoi regions as in Ericson's Real-Time Collision Detection ch. 5; written here from those
descriptions): on polytope cores (a point, a segment, a box, a hull) it ends exactly after finitely
many steps, on a cylinder it converges to ``GJK_REL_TOL`` of the distance. When the cores overlap,
EPA (van den Bergen 2001) expands the simplex to a polytope of the Minkowski difference until the
face nearest the origin is within ``EPA_TOL`` of the surface: exact for polytope cores, within
``EPA_TOL`` (1e-9 m) of the depth for a cylinder, capped at ``EPA_MAX_ITER`` expansions.

The cylinder's support is exact (a rim point, or a cap centre when the direction is along the
axis), never a polygonal stand-in.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit

from crosscheck.sim._jit import INLINE, JIT
from crosscheck.sim.collide.geometry import BOX, CAPSULE, CYLINDER, SPHERE

GJK_MAX_ITER = 64
GJK_REL_TOL = 1e-12  # stop when the support no longer improves the distance by this (relative)
EPA_MAX_ITER = 128
EPA_TOL = 1e-9  # m: the nearest face is within this of the Minkowski difference's surface
EPA_MAX_VERTS = EPA_MAX_ITER + 8
# GJK keeps its last simplex in these rows of the scratch while it tries the next (rows 8-10 are
# _keep's; EPA, which overwrites both, starts after GJK has returned)
GJK_BACKUP = 12
# a closed triangulated surface of V vertices has 2 V - 4 faces; the horizon's new faces are added
# before the dead ones are dropped, hence the slack
EPA_MAX_FACES = 4 * EPA_MAX_VERTS


class GjkScratch(NamedTuple):
    """Simplex and EPA polytope storage, allocated once per detection: Minkowski points w and the
    support points on A and B that made them."""

    w: np.ndarray  # (EPA_MAX_VERTS, 3)
    pa: np.ndarray  # (EPA_MAX_VERTS, 3)
    pb: np.ndarray  # (EPA_MAX_VERTS, 3)
    faces: np.ndarray  # (EPA_MAX_FACES, 3) int64
    face_n: np.ndarray  # (EPA_MAX_FACES, 4): unit outward normal and distance from the origin
    alive: np.ndarray  # (EPA_MAX_FACES,) bool
    edges: np.ndarray  # (3 * EPA_MAX_FACES, 2) int64, the horizon


def new_gjk_scratch() -> GjkScratch:
    return GjkScratch(np.zeros((EPA_MAX_VERTS, 3)), np.zeros((EPA_MAX_VERTS, 3)),
                      np.zeros((EPA_MAX_VERTS, 3)), np.zeros((EPA_MAX_FACES, 3), np.int64),
                      np.zeros((EPA_MAX_FACES, 4)), np.zeros(EPA_MAX_FACES, np.bool_),
                      np.zeros((3 * EPA_MAX_FACES, 2), np.int64))


# -- support mappings -----------------------------------------------------------------------------
@njit(**INLINE)
def core_radius(geom, c):
    k = geom.kind[c]
    if k == SPHERE or k == CAPSULE:
        return geom.size[c, 0]
    return 0.0


@njit(**JIT)
def support_core(geom, wpos, wrot, c, dx, dy, dz, ox, oy, oz):
    """A point of collider c's core farthest along the world direction d (any maximiser),
    relative to the point o: GJK works about A's frame origin, so that bodies far from the
    world origin (1e4 m) lose no digits to their position."""
    k = geom.kind[c]
    px, py, pz = wpos[c, 0] - ox, wpos[c, 1] - oy, wpos[c, 2] - oz
    if k == SPHERE:
        return px, py, pz
    # d in the shape frame: R^T d
    lx = wrot[c, 0, 0] * dx + wrot[c, 1, 0] * dy + wrot[c, 2, 0] * dz
    ly = wrot[c, 0, 1] * dx + wrot[c, 1, 1] * dy + wrot[c, 2, 1] * dz
    lz = wrot[c, 0, 2] * dx + wrot[c, 1, 2] * dy + wrot[c, 2, 2] * dz
    sx, sy, sz = 0.0, 0.0, 0.0
    if k == CAPSULE:
        sz = geom.size[c, 1] if lz >= 0.0 else -geom.size[c, 1]
    elif k == BOX:
        sx = geom.size[c, 0] if lx >= 0.0 else -geom.size[c, 0]
        sy = geom.size[c, 1] if ly >= 0.0 else -geom.size[c, 1]
        sz = geom.size[c, 2] if lz >= 0.0 else -geom.size[c, 2]
    elif k == CYLINDER:
        rho = np.sqrt(lx * lx + ly * ly)
        if rho > 0.0:
            sx = geom.size[c, 0] * lx / rho
            sy = geom.size[c, 0] * ly / rho
        sz = geom.size[c, 1] if lz >= 0.0 else -geom.size[c, 1]
    else:  # hull
        p = geom.polytope[c]
        v0 = geom.poly_vert_start[p]
        best = -np.inf
        for v in range(v0, v0 + geom.poly_vert_count[p]):
            s = lx * geom.vertices[v, 0] + ly * geom.vertices[v, 1] + lz * geom.vertices[v, 2]
            if s > best:
                best = s
                sx, sy, sz = geom.vertices[v, 0], geom.vertices[v, 1], geom.vertices[v, 2]
    return (px + wrot[c, 0, 0] * sx + wrot[c, 0, 1] * sy + wrot[c, 0, 2] * sz,
            py + wrot[c, 1, 0] * sx + wrot[c, 1, 1] * sy + wrot[c, 1, 2] * sz,
            pz + wrot[c, 2, 0] * sx + wrot[c, 2, 1] * sy + wrot[c, 2, 2] * sz)


@njit(**INLINE)
def _support_into(geom, wpos, wrot, ca, cb, dx, dy, dz, s, k):
    """Slot k of the scratch: w = sA(d) - sB(-d), with the two support points (relative to A's
    frame origin)."""
    ox, oy, oz = wpos[ca, 0], wpos[ca, 1], wpos[ca, 2]
    ax, ay, az = support_core(geom, wpos, wrot, ca, dx, dy, dz, ox, oy, oz)
    bx, by, bz = support_core(geom, wpos, wrot, cb, -dx, -dy, -dz, ox, oy, oz)
    s.pa[k, 0], s.pa[k, 1], s.pa[k, 2] = ax, ay, az
    s.pb[k, 0], s.pb[k, 1], s.pb[k, 2] = bx, by, bz
    s.w[k, 0], s.w[k, 1], s.w[k, 2] = ax - bx, ay - by, az - bz


@njit(**INLINE)
def _copy_slot(s, src, dst):
    for r in range(3):
        s.w[dst, r] = s.w[src, r]
        s.pa[dst, r] = s.pa[src, r]
        s.pb[dst, r] = s.pb[src, r]


@njit(**INLINE)
def _dot(s, i, x, y, z):
    return s.w[i, 0] * x + s.w[i, 1] * y + s.w[i, 2] * z


# -- the closest point of a simplex to the origin -------------------------------------------------
@njit(**INLINE)
def _closest_segment(s, lam):
    """Simplex {0, 1}: barycentric weights of the point nearest the origin in lam; keeps only the
    vertices with weight; returns the new simplex size."""
    ex, ey, ez = s.w[1, 0] - s.w[0, 0], s.w[1, 1] - s.w[0, 1], s.w[1, 2] - s.w[0, 2]
    t = -_dot(s, 0, ex, ey, ez)
    ee = ex * ex + ey * ey + ez * ez
    if t <= 0.0 or ee <= 0.0:
        lam[0] = 1.0
        return 1
    if t >= ee:
        _copy_slot(s, 1, 0)
        lam[0] = 1.0
        return 1
    lam[1] = t / ee
    lam[0] = 1.0 - lam[1]
    return 2


@njit(**INLINE)
def _keep(s, lam, i0, i1, i2, l0, l1, l2):
    """Reorder the simplex to the vertices i0 (, i1 (, i2)) with weights l*: -1 ends the list."""
    n = 0
    idx = (i0, i1, i2)
    ls = (l0, l1, l2)
    # copy into the high slots first (the slots may overlap)
    for k in range(3):
        if idx[k] >= 0:
            for r in range(3):
                s.w[8 + k, r] = s.w[idx[k], r]
                s.pa[8 + k, r] = s.pa[idx[k], r]
                s.pb[8 + k, r] = s.pb[idx[k], r]
    for k in range(3):
        if idx[k] >= 0:
            _copy_slot(s, 8 + k, n)
            lam[n] = ls[k]
            n += 1
    return n


@njit(**INLINE)
def _closest_triangle(s, lam, i, j, k):
    """Nearest point of triangle (i, j, k) to the origin by its Voronoi regions (Ericson 5.1.5):
    returns (distance^2, the three weights) without changing the simplex."""
    ax, ay, az = s.w[i, 0], s.w[i, 1], s.w[i, 2]
    bx, by, bz = s.w[j, 0], s.w[j, 1], s.w[j, 2]
    cx, cy, cz = s.w[k, 0], s.w[k, 1], s.w[k, 2]
    abx, aby, abz = bx - ax, by - ay, bz - az
    acx, acy, acz = cx - ax, cy - ay, cz - az
    # p = origin: ap = -a
    d1 = -(abx * ax + aby * ay + abz * az)
    d2 = -(acx * ax + acy * ay + acz * az)
    if d1 <= 0.0 and d2 <= 0.0:
        u, v, w = 1.0, 0.0, 0.0
    else:
        d3 = -(abx * bx + aby * by + abz * bz)
        d4 = -(acx * bx + acy * by + acz * bz)
        if d3 >= 0.0 and d4 <= d3:
            u, v, w = 0.0, 1.0, 0.0
        else:
            vc = d1 * d4 - d3 * d2
            if vc <= 0.0 and d1 >= 0.0 and d3 <= 0.0:
                t = d1 / (d1 - d3)
                u, v, w = 1.0 - t, t, 0.0
            else:
                d5 = -(abx * cx + aby * cy + abz * cz)
                d6 = -(acx * cx + acy * cy + acz * cz)
                if d6 >= 0.0 and d5 <= d6:
                    u, v, w = 0.0, 0.0, 1.0
                else:
                    vb = d5 * d2 - d1 * d6
                    if vb <= 0.0 and d2 >= 0.0 and d6 <= 0.0:
                        t = d2 / (d2 - d6)
                        u, v, w = 1.0 - t, 0.0, t
                    else:
                        va = d3 * d6 - d5 * d4
                        if va <= 0.0 and (d4 - d3) >= 0.0 and (d5 - d6) >= 0.0:
                            t = (d4 - d3) / ((d4 - d3) + (d5 - d6))
                            u, v, w = 0.0, 1.0 - t, t
                        else:
                            den = va + vb + vc
                            if den != 0.0:
                                v = vb / den
                                w = vc / den
                            else:
                                v, w = 0.0, 0.0
                            u = 1.0 - v - w
    px = u * ax + v * bx + w * cx
    py = u * ay + v * by + w * cy
    pz = u * az + v * bz + w * cz
    return px * px + py * py + pz * pz, u, v, w


@njit(**INLINE)
def _reduce_triangle(s, lam, i, j, k):
    _, u, v, w = _closest_triangle(s, lam, i, j, k)
    return _keep(s, lam, i if u > 0.0 else -1, j if v > 0.0 else -1, k if w > 0.0 else -1,
                 u, v, w)


@njit(**INLINE)
def _outside(s, i, j, k, o):
    """The origin and vertex o lie on opposite sides of plane (i, j, k) (or the origin on it
    while o is off it): the origin is outside the tetrahedron through that face."""
    abx, aby, abz = s.w[j, 0] - s.w[i, 0], s.w[j, 1] - s.w[i, 1], s.w[j, 2] - s.w[i, 2]
    acx, acy, acz = s.w[k, 0] - s.w[i, 0], s.w[k, 1] - s.w[i, 1], s.w[k, 2] - s.w[i, 2]
    nx, ny, nz = aby * acz - abz * acy, abz * acx - abx * acz, abx * acy - aby * acx
    so = -(nx * s.w[i, 0] + ny * s.w[i, 1] + nz * s.w[i, 2])
    sd = (nx * (s.w[o, 0] - s.w[i, 0]) + ny * (s.w[o, 1] - s.w[i, 1])
          + nz * (s.w[o, 2] - s.w[i, 2]))
    return so * sd < 0.0


@njit(**INLINE)
def _closest_tetrahedron(s, lam):
    """Simplex {0, 1, 2, 3}: 4 when the origin is inside, else the nearest face's sub-simplex."""
    best = np.inf
    bi, bj, bk = -1, -1, -1
    bu, bv, bw = 0.0, 0.0, 0.0
    faces = ((0, 1, 2, 3), (0, 1, 3, 2), (0, 2, 3, 1), (1, 2, 3, 0))
    # a flat tetrahedron has no inside: its nearest face is the answer
    size2 = 0.0
    for k in range(1, 4):
        for r in range(3):
            size2 = max(size2, (s.w[k, r] - s.w[0, r]) ** 2)
    flat = abs(_volume6(s)) <= 1e-12 * size2 * np.sqrt(size2)
    for f in range(4):
        i, j, k, o = faces[f]
        if flat or _outside(s, i, j, k, o):
            d2, u, v, w = _closest_triangle(s, lam, i, j, k)
            if d2 < best:
                best = d2
                bi, bj, bk = i, j, k
                bu, bv, bw = u, v, w
    if bi < 0:
        return 4
    return _keep(s, lam, bi if bu > 0.0 else -1, bj if bv > 0.0 else -1,
                 bk if bw > 0.0 else -1, bu, bv, bw)


# -- GJK ------------------------------------------------------------------------------------------
@njit(**JIT)
def gjk(geom, wpos, wrot, ca, cb, s, lam):
    """Distance between the cores of ca and cb. Returns (distance, n): n = 4 when the cores
    overlap (the simplex then holds a tetrahedron around the origin, or fewer points when they
    merely touch: distance 0), else the simplex size with the barycentric weights in lam, from
    which :func:`witnesses` gives the closest points."""
    # start along the line between the frame origins
    dx, dy, dz = wpos[cb, 0] - wpos[ca, 0], wpos[cb, 1] - wpos[ca, 1], wpos[cb, 2] - wpos[ca, 2]
    if dx == 0.0 and dy == 0.0 and dz == 0.0:
        dx = 1.0
    _support_into(geom, wpos, wrot, ca, cb, -dx, -dy, -dz, s, 0)
    n = 1
    lam[0] = 1.0
    vx, vy, vz = s.w[0, 0], s.w[0, 1], s.w[0, 2]
    for _ in range(GJK_MAX_ITER):
        vv = vx * vx + vy * vy + vz * vz
        if vv <= 1e-30:
            return 0.0, n
        _support_into(geom, wpos, wrot, ca, cb, -vx, -vy, -vz, s, n)
        # no progress towards the origin: v is the closest point (to the tolerance)
        if vv - _dot(s, n, vx, vy, vz) <= GJK_REL_TOL * vv:
            return np.sqrt(vv), n
        duplicate = False
        for k in range(n):
            if (s.w[k, 0] == s.w[n, 0] and s.w[k, 1] == s.w[n, 1]
                    and s.w[k, 2] == s.w[n, 2]):
                duplicate = True
        if duplicate:
            return np.sqrt(vv), n
        # the simplex before the update, restored if the update brings v no closer: the weights
        # must stay those of the v whose distance is returned, or the witnesses (and the normal
        # taken from them) belong to another point. Measured: a capsule's segment beside a
        # cylinder's side, where a thin triangle's update came out 1e-6 (relative) farther; the
        # new simplex's witnesses tilted the normal 9.6e-4 rad off the side's
        n_prev = n
        for k in range(n):
            _copy_slot(s, k, GJK_BACKUP + k)
        l0, l1, l2 = lam[0], lam[1], lam[2]
        n += 1
        if n == 2:
            n = _closest_segment(s, lam)
        elif n == 3:
            n = _reduce_triangle(s, lam, 0, 1, 2)
        else:
            n = _closest_tetrahedron(s, lam)
            if n == 4:
                return 0.0, 4
        vx, vy, vz = 0.0, 0.0, 0.0
        for k in range(n):
            vx += lam[k] * s.w[k, 0]
            vy += lam[k] * s.w[k, 1]
            vz += lam[k] * s.w[k, 2]
        if vx * vx + vy * vy + vz * vz >= vv:
            # no strict decrease (round-off, or a thin triangle): the previous simplex stands
            for k in range(n_prev):
                _copy_slot(s, GJK_BACKUP + k, k)
            lam[0], lam[1], lam[2] = l0, l1, l2
            return np.sqrt(vv), n_prev
    return np.sqrt(vx * vx + vy * vy + vz * vz), n


@njit(**INLINE)
def witnesses(s, lam, n):
    """The closest points on A's and B's cores from the final simplex's weights, relative to A's
    frame origin."""
    ax, ay, az, bx, by, bz = 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
    for k in range(n):
        ax += lam[k] * s.pa[k, 0]
        ay += lam[k] * s.pa[k, 1]
        az += lam[k] * s.pa[k, 2]
        bx += lam[k] * s.pb[k, 0]
        by += lam[k] * s.pb[k, 1]
        bz += lam[k] * s.pb[k, 2]
    return ax, ay, az, bx, by, bz


# -- EPA ------------------------------------------------------------------------------------------
@njit(**INLINE)
def _set_face(s, f, i, j, k, cx, cy, cz):
    """Face f = (i, j, k), oriented so that its normal points away from the interior point c."""
    abx, aby, abz = s.w[j, 0] - s.w[i, 0], s.w[j, 1] - s.w[i, 1], s.w[j, 2] - s.w[i, 2]
    acx, acy, acz = s.w[k, 0] - s.w[i, 0], s.w[k, 1] - s.w[i, 1], s.w[k, 2] - s.w[i, 2]
    nx, ny, nz = aby * acz - abz * acy, abz * acx - abx * acz, abx * acy - aby * acx
    if nx * (s.w[i, 0] - cx) + ny * (s.w[i, 1] - cy) + nz * (s.w[i, 2] - cz) < 0.0:
        j, k = k, j
        nx, ny, nz = -nx, -ny, -nz
    ln = np.sqrt(nx * nx + ny * ny + nz * nz)
    if ln > 0.0:
        nx, ny, nz = nx / ln, ny / ln, nz / ln
    s.faces[f, 0], s.faces[f, 1], s.faces[f, 2] = i, j, k
    s.face_n[f, 0], s.face_n[f, 1], s.face_n[f, 2] = nx, ny, nz
    s.face_n[f, 3] = nx * s.w[i, 0] + ny * s.w[i, 1] + nz * s.w[i, 2]
    s.alive[f] = ln > 0.0


@njit(**INLINE)
def _volume6(s):
    """Six times the signed volume of the tetrahedron 0, 1, 2, 3."""
    ax, ay, az = s.w[1, 0] - s.w[0, 0], s.w[1, 1] - s.w[0, 1], s.w[1, 2] - s.w[0, 2]
    bx, by, bz = s.w[2, 0] - s.w[0, 0], s.w[2, 1] - s.w[0, 1], s.w[2, 2] - s.w[0, 2]
    cx, cy, cz = s.w[3, 0] - s.w[0, 0], s.w[3, 1] - s.w[0, 1], s.w[3, 2] - s.w[0, 2]
    return ax * (by * cz - bz * cy) + ay * (bz * cx - bx * cz) + az * (bx * cy - by * cx)


@njit(**INLINE)
def _complete_simplex(geom, wpos, wrot, ca, cb, s, n, scale):
    """Grow a simplex of n < 4 points (the cores touch) into a tetrahedron of Minkowski points by
    supports along the axes; returns the size reached (4 unless the difference is flat)."""
    tiny = 1e-12 * scale
    for axis in range(6):
        if n == 4:
            break
        dx, dy, dz = 0.0, 0.0, 0.0
        sign = 1.0 if axis % 2 == 0 else -1.0
        if axis // 2 == 0:
            dx = sign
        elif axis // 2 == 1:
            dy = sign
        else:
            dz = sign
        if n == 3:
            # along the triangle's normal, both ways
            abx, aby, abz = s.w[1, 0] - s.w[0, 0], s.w[1, 1] - s.w[0, 1], s.w[1, 2] - s.w[0, 2]
            acx, acy, acz = s.w[2, 0] - s.w[0, 0], s.w[2, 1] - s.w[0, 1], s.w[2, 2] - s.w[0, 2]
            dx, dy, dz = aby * acz - abz * acy, abz * acx - abx * acz, abx * acy - aby * acx
            dx, dy, dz = sign * dx, sign * dy, sign * dz
        _support_into(geom, wpos, wrot, ca, cb, dx, dy, dz, s, n)
        ok = True
        if n == 1:
            ex, ey, ez = s.w[1, 0] - s.w[0, 0], s.w[1, 1] - s.w[0, 1], s.w[1, 2] - s.w[0, 2]
            ok = ex * ex + ey * ey + ez * ez > tiny * tiny
        elif n == 2:
            ex, ey, ez = s.w[1, 0] - s.w[0, 0], s.w[1, 1] - s.w[0, 1], s.w[1, 2] - s.w[0, 2]
            fx, fy, fz = s.w[2, 0] - s.w[0, 0], s.w[2, 1] - s.w[0, 1], s.w[2, 2] - s.w[0, 2]
            cx, cy, cz = ey * fz - ez * fy, ez * fx - ex * fz, ex * fy - ey * fx
            ok = np.sqrt(cx * cx + cy * cy + cz * cz) > tiny * scale
        else:
            ok = abs(_volume6(s)) > tiny * scale * scale
        if ok:
            n += 1
    return n


@njit(**JIT)
def epa(geom, wpos, wrot, ca, cb, s, n, scale):
    """Penetration of the overlapping cores: (depth, nx, ny, nz, witness on A, witness on B; both
    relative to A's frame origin), the normal from A to B (B moved by depth along it separates
    the cores). ``n``: GJK's simplex size (4, or fewer when the cores touch). depth < 0 means
    the difference was flat (no volume): the caller falls back to a zero-depth contact."""
    if n < 4:
        n = _complete_simplex(geom, wpos, wrot, ca, cb, s, n, scale)
        if n < 4:
            return -1.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
    cx = 0.25 * (s.w[0, 0] + s.w[1, 0] + s.w[2, 0] + s.w[3, 0])
    cy = 0.25 * (s.w[0, 1] + s.w[1, 1] + s.w[2, 1] + s.w[3, 1])
    cz = 0.25 * (s.w[0, 2] + s.w[1, 2] + s.w[2, 2] + s.w[3, 2])
    _set_face(s, 0, 0, 1, 2, cx, cy, cz)
    _set_face(s, 1, 0, 1, 3, cx, cy, cz)
    _set_face(s, 2, 0, 2, 3, cx, cy, cz)
    _set_face(s, 3, 1, 2, 3, cx, cy, cz)
    n_faces = 4
    n_verts = 4
    best = 0
    for _ in range(EPA_MAX_ITER):
        best = -1
        dist = np.inf
        for f in range(n_faces):
            if s.alive[f] and s.face_n[f, 3] < dist:
                dist = s.face_n[f, 3]
                best = f
        if best < 0:
            break
        nx, ny, nz = s.face_n[best, 0], s.face_n[best, 1], s.face_n[best, 2]
        if n_verts >= EPA_MAX_VERTS or n_faces + 2 * n_verts + 8 >= EPA_MAX_FACES:
            break
        _support_into(geom, wpos, wrot, ca, cb, nx, ny, nz, s, n_verts)
        if _dot(s, n_verts, nx, ny, nz) - dist <= EPA_TOL:
            break
        # remove the faces the new point sees; their unshared edges form the horizon
        w = n_verts
        n_verts += 1
        n_edges = 0
        for f in range(n_faces):
            if not s.alive[f]:
                continue
            i0 = s.faces[f, 0]
            seen = (s.face_n[f, 0] * (s.w[w, 0] - s.w[i0, 0])
                    + s.face_n[f, 1] * (s.w[w, 1] - s.w[i0, 1])
                    + s.face_n[f, 2] * (s.w[w, 2] - s.w[i0, 2]))
            if seen <= 0.0:
                continue
            s.alive[f] = False
            for e in range(3):
                a, b = s.faces[f, e], s.faces[f, (e + 1) % 3]
                shared = -1
                for h in range(n_edges):
                    if s.edges[h, 0] == b and s.edges[h, 1] == a:
                        shared = h
                        break
                if shared >= 0:
                    n_edges -= 1
                    s.edges[shared, 0] = s.edges[n_edges, 0]
                    s.edges[shared, 1] = s.edges[n_edges, 1]
                else:
                    s.edges[n_edges, 0] = a
                    s.edges[n_edges, 1] = b
                    n_edges += 1
        # drop the dead faces, then add the new ones on the horizon
        kept = 0
        for f in range(n_faces):
            if s.alive[f]:
                if kept != f:
                    for r in range(3):
                        s.faces[kept, r] = s.faces[f, r]
                    for r in range(4):
                        s.face_n[kept, r] = s.face_n[f, r]
                    s.alive[kept] = True
                kept += 1
        n_faces = kept
        for h in range(n_edges):
            _set_face(s, n_faces, s.edges[h, 0], s.edges[h, 1], w, cx, cy, cz)
            n_faces += 1
    # the nearest face of the final polytope (the loop may have ended after a compaction)
    best = -1
    dist = np.inf
    for f in range(n_faces):
        if s.alive[f] and s.face_n[f, 3] < dist:
            dist = s.face_n[f, 3]
            best = f
    if best < 0:
        return -1.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
    # the origin's projection on the nearest face, in barycentric weights of its corners
    nx, ny, nz, dist = s.face_n[best, 0], s.face_n[best, 1], s.face_n[best, 2], s.face_n[best, 3]
    i, j, k = s.faces[best, 0], s.faces[best, 1], s.faces[best, 2]
    u, v, ww = _barycentric(s, i, j, k, dist * nx, dist * ny, dist * nz)
    ax = u * s.pa[i, 0] + v * s.pa[j, 0] + ww * s.pa[k, 0]
    ay = u * s.pa[i, 1] + v * s.pa[j, 1] + ww * s.pa[k, 1]
    az = u * s.pa[i, 2] + v * s.pa[j, 2] + ww * s.pa[k, 2]
    bx = u * s.pb[i, 0] + v * s.pb[j, 0] + ww * s.pb[k, 0]
    by = u * s.pb[i, 1] + v * s.pb[j, 1] + ww * s.pb[k, 1]
    bz = u * s.pb[i, 2] + v * s.pb[j, 2] + ww * s.pb[k, 2]
    return max(dist, 0.0), nx, ny, nz, ax, ay, az, bx, by, bz


@njit(**INLINE)
def _barycentric(s, i, j, k, px, py, pz):
    """Weights of p in triangle (i, j, k) (p in its plane), by areas."""
    v0x, v0y, v0z = s.w[j, 0] - s.w[i, 0], s.w[j, 1] - s.w[i, 1], s.w[j, 2] - s.w[i, 2]
    v1x, v1y, v1z = s.w[k, 0] - s.w[i, 0], s.w[k, 1] - s.w[i, 1], s.w[k, 2] - s.w[i, 2]
    v2x, v2y, v2z = px - s.w[i, 0], py - s.w[i, 1], pz - s.w[i, 2]
    d00 = v0x * v0x + v0y * v0y + v0z * v0z
    d01 = v0x * v1x + v0y * v1y + v0z * v1z
    d11 = v1x * v1x + v1y * v1y + v1z * v1z
    d20 = v2x * v0x + v2y * v0y + v2z * v0z
    d21 = v2x * v1x + v2y * v1y + v2z * v1z
    den = d00 * d11 - d01 * d01
    if den <= 0.0:
        return 1.0, 0.0, 0.0
    v = (d11 * d20 - d01 * d21) / den
    w = (d00 * d21 - d01 * d20) / den
    return 1.0 - v - w, v, w
