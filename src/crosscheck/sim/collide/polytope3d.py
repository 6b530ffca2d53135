"""Polytope against polytope (box/box, box/hull, hull/hull): the separating axis test with face
clipping.

The candidate axes are the face normals of A, those of B, and the cross products of an edge of A
with an edge of B. Edge pairs are pruned on the Gauss map (an edge pair can only give a face of
the Minkowski difference when the great arcs of the two edges' face normals cross, Gregorius,
GDC 2013), so the test is exact without trying every pair of edges against every vertex. The
axis of least penetration (largest separation) decides the contact:

* a face axis: the *reference* face (that face) and the *incident* face of the other polytope
  (the one most anti-parallel to it); the incident polygon is clipped against the side planes of
  the reference face (Sutherland-Hodgman) and every clipped point within the margin of the
  reference plane is a contact point, midway between the point and the reference plane;
* an edge pair: one point, midway between the closest points of the two edges.

Face axes win unless an edge axis separates clearly more (``EDGE_BIAS``): a box resting on a box
gets its four face-face points, not one edge point, when the edge and face separations tie.
Feature ids: (reference side, reference face, incident face, clipped point's origin) for faces;
(edge of A, edge of B) for edges.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit

from crosscheck.sim._jit import INLINE, JIT
from crosscheck.sim.collide.manifold import MAX_CANDIDATES, put_point, reduce_to_four, set_normal

# An edge axis is taken over a face axis when it separates by more than this (absolute m, plus a
# fraction of the face separation's size): ties go to the faces, whose manifolds are stable.
EDGE_BIAS_ABS = 1e-6
EDGE_BIAS_REL = 0.05
# Reference face: A's unless B's separates by more than this (same form): a deterministic choice
# that does not flip between A and B on round-off.
FACE_BIAS_ABS = 1e-6
FACE_BIAS_REL = 0.02
# Parallel edges: their cross product is below this (relative to the edge lengths) and the face
# axes cover them.
PARALLEL = 1e-6


class PolytopeScratch(NamedTuple):
    """Per-call scratch of the polytope routine, allocated once per detection."""

    va: np.ndarray  # (V, 3) world vertices of A
    vb: np.ndarray  # (V, 3) world vertices of B
    clip_in: np.ndarray  # (M, 3) polygon being clipped
    clip_out: np.ndarray  # (M, 3)
    id_in: np.ndarray  # (M,) int64 origin of each polygon vertex (feature)
    id_out: np.ndarray  # (M,) int64


def new_polytope_scratch(max_poly_verts: int, max_face_verts: int) -> PolytopeScratch:
    m = 2 * max_face_verts + 4
    return PolytopeScratch(np.zeros((max_poly_verts, 3)), np.zeros((max_poly_verts, 3)),
                           np.zeros((m, 3)), np.zeros((m, 3)), np.zeros(m, np.int64),
                           np.zeros(m, np.int64))


@njit(**INLINE)
def _world_vertices(geom, wpos, wrot, c, out):
    p = geom.polytope[c]
    v0 = geom.poly_vert_start[p]
    for v in range(geom.poly_vert_count[p]):
        x, y, z = geom.vertices[v0 + v, 0], geom.vertices[v0 + v, 1], geom.vertices[v0 + v, 2]
        for r in range(3):
            out[v, r] = wpos[c, r] + wrot[c, r, 0] * x + wrot[c, r, 1] * y + wrot[c, r, 2] * z
    return geom.poly_vert_count[p]


@njit(**INLINE)
def _world_face(geom, wpos, wrot, c, f):
    """Outward world normal and offset of face f (global index) of collider c."""
    lx, ly, lz = geom.face_normal[f, 0], geom.face_normal[f, 1], geom.face_normal[f, 2]
    nx = wrot[c, 0, 0] * lx + wrot[c, 0, 1] * ly + wrot[c, 0, 2] * lz
    ny = wrot[c, 1, 0] * lx + wrot[c, 1, 1] * ly + wrot[c, 1, 2] * lz
    nz = wrot[c, 2, 0] * lx + wrot[c, 2, 1] * ly + wrot[c, 2, 2] * lz
    return nx, ny, nz, geom.face_offset[f] + nx * wpos[c, 0] + ny * wpos[c, 1] + nz * wpos[c, 2]


@njit(**INLINE)
def _face_query(geom, wpos, wrot, c, other_verts, n_other):
    """The face of collider c that the other polytope is farthest outside of: (separation, face
    index local to c's polytope). Separation = min over the other's vertices of the distance
    above the face's plane."""
    p = geom.polytope[c]
    f0 = geom.poly_face_start[p]
    best = -np.inf
    best_f = 0
    for f in range(geom.poly_face_count[p]):
        nx, ny, nz, off = _world_face(geom, wpos, wrot, c, f0 + f)
        s = np.inf
        for v in range(n_other):
            s = min(s, nx * other_verts[v, 0] + ny * other_verts[v, 1] + nz * other_verts[v, 2])
        s -= off
        if s > best:
            best = s
            best_f = f
    return best, best_f


@njit(**INLINE)
def _face_normal_world(geom, wrot, c, f):
    lx, ly, lz = geom.face_normal[f, 0], geom.face_normal[f, 1], geom.face_normal[f, 2]
    return (wrot[c, 0, 0] * lx + wrot[c, 0, 1] * ly + wrot[c, 0, 2] * lz,
            wrot[c, 1, 0] * lx + wrot[c, 1, 1] * ly + wrot[c, 1, 2] * lz,
            wrot[c, 2, 0] * lx + wrot[c, 2, 1] * ly + wrot[c, 2, 2] * lz)


@njit(**INLINE)
def _triple(ax, ay, az, bx, by, bz, cx, cy, cz):
    """a . (b x c)"""
    return ax * (by * cz - bz * cy) + ay * (bz * cx - bx * cz) + az * (bx * cy - by * cx)


@njit(**INLINE)
def _edge_query(geom, wpos, wrot, ca, cb, va, vb):
    """The edge pair (local to A's and B's polytopes) whose axis separates most, and that
    separation; -inf when no pair spans a face of the Minkowski difference."""
    pa = geom.polytope[ca]
    pb = geom.polytope[cb]
    ea0, fa0 = geom.poly_edge_start[pa], geom.poly_face_start[pa]
    eb0, fb0 = geom.poly_edge_start[pb], geom.poly_face_start[pb]
    # A's interior point in world, to orient each axis away from A
    cxl, cyl, czl = geom.poly_centroid[pa, 0], geom.poly_centroid[pa, 1], geom.poly_centroid[pa, 2]
    ox = wpos[ca, 0] + wrot[ca, 0, 0] * cxl + wrot[ca, 0, 1] * cyl + wrot[ca, 0, 2] * czl
    oy = wpos[ca, 1] + wrot[ca, 1, 0] * cxl + wrot[ca, 1, 1] * cyl + wrot[ca, 1, 2] * czl
    oz = wpos[ca, 2] + wrot[ca, 2, 0] * cxl + wrot[ca, 2, 1] * cyl + wrot[ca, 2, 2] * czl
    best = -np.inf
    best_i = -1
    best_j = -1
    bax, bay, baz = 0.0, 0.0, 0.0
    for i in range(geom.poly_edge_count[pa]):
        ia0, ia1 = geom.edge_verts[ea0 + i, 0], geom.edge_verts[ea0 + i, 1]
        ax_, ay_, az_ = _face_normal_world(geom, wrot, ca, fa0 + geom.edge_faces[ea0 + i, 0])
        bx_, by_, bz_ = _face_normal_world(geom, wrot, ca, fa0 + geom.edge_faces[ea0 + i, 1])
        # b x a, the arc's plane normal (parallel to the edge)
        bax_, bay_, baz_ = by_ * az_ - bz_ * ay_, bz_ * ax_ - bx_ * az_, bx_ * ay_ - by_ * ax_
        pxa, pya, pza = va[ia0, 0], va[ia0, 1], va[ia0, 2]
        dxa, dya, dza = va[ia1, 0] - pxa, va[ia1, 1] - pya, va[ia1, 2] - pza
        la = np.sqrt(dxa * dxa + dya * dya + dza * dza)
        for j in range(geom.poly_edge_count[pb]):
            # B's normals negated: the Gauss map of -B
            cx_, cy_, cz_ = _face_normal_world(geom, wrot, cb, fb0 + geom.edge_faces[eb0 + j, 0])
            dx_, dy_, dz_ = _face_normal_world(geom, wrot, cb, fb0 + geom.edge_faces[eb0 + j, 1])
            cx_, cy_, cz_, dx_, dy_, dz_ = -cx_, -cy_, -cz_, -dx_, -dy_, -dz_
            cba = cx_ * bax_ + cy_ * bay_ + cz_ * baz_
            dba = dx_ * bax_ + dy_ * bay_ + dz_ * baz_
            if cba * dba >= 0.0:
                continue
            # d x c
            dcx, dcy, dcz = dy_ * cz_ - dz_ * cy_, dz_ * cx_ - dx_ * cz_, dx_ * cy_ - dy_ * cx_
            adc = ax_ * dcx + ay_ * dcy + az_ * dcz
            bdc = bx_ * dcx + by_ * dcy + bz_ * dcz
            if adc * bdc >= 0.0 or cba * bdc <= 0.0:
                continue
            ib0, ib1 = geom.edge_verts[eb0 + j, 0], geom.edge_verts[eb0 + j, 1]
            pxb, pyb, pzb = vb[ib0, 0], vb[ib0, 1], vb[ib0, 2]
            dxb, dyb, dzb = vb[ib1, 0] - pxb, vb[ib1, 1] - pyb, vb[ib1, 2] - pzb
            lb = np.sqrt(dxb * dxb + dyb * dyb + dzb * dzb)
            nx = dya * dzb - dza * dyb
            ny = dza * dxb - dxa * dzb
            nz = dxa * dyb - dya * dxb
            ln = np.sqrt(nx * nx + ny * ny + nz * nz)
            if ln <= PARALLEL * la * lb:
                continue
            nx, ny, nz = nx / ln, ny / ln, nz / ln
            if nx * (pxa - ox) + ny * (pya - oy) + nz * (pza - oz) < 0.0:
                nx, ny, nz = -nx, -ny, -nz
            s = nx * (pxb - pxa) + ny * (pyb - pya) + nz * (pzb - pza)
            if s > best:
                best = s
                best_i = i
                best_j = j
                bax, bay, baz = nx, ny, nz
    return best, best_i, best_j, bax, bay, baz


@njit(**JIT)
def polytope_polytope(geom, wpos, wrot, ca, cb, margin, man, scratch):
    """Manifold of polytope colliders A and B (boxes or hulls); returns the point count."""
    na = _world_vertices(geom, wpos, wrot, ca, scratch.va)
    nb = _world_vertices(geom, wpos, wrot, cb, scratch.vb)
    sa, fa = _face_query(geom, wpos, wrot, ca, scratch.vb, nb)
    if sa > margin:
        return 0
    sb, fb = _face_query(geom, wpos, wrot, cb, scratch.va, na)
    if sb > margin:
        return 0
    se, ei, ej, ex, ey, ez = _edge_query(geom, wpos, wrot, ca, cb, scratch.va, scratch.vb)
    if se > margin:
        return 0
    face = max(sa, sb)
    if ei >= 0 and se > face + EDGE_BIAS_ABS + EDGE_BIAS_REL * abs(face):
        return _edge_contact(geom, ca, cb, ei, ej, ex, ey, ez, scratch.va, scratch.vb, man)
    if sb > sa + FACE_BIAS_ABS + FACE_BIAS_REL * abs(sa):
        return _face_contact(geom, wpos, wrot, cb, fb, ca, scratch.vb, scratch.va, True, margin,
                             man, scratch)
    return _face_contact(geom, wpos, wrot, ca, fa, cb, scratch.va, scratch.vb, False, margin, man,
                         scratch)


@njit(**INLINE)
def _edge_contact(geom, ca, cb, ei, ej, nx, ny, nz, va, vb, man):
    """One point midway between the closest points of edge ei of A and edge ej of B."""
    ea = geom.poly_edge_start[geom.polytope[ca]] + ei
    eb = geom.poly_edge_start[geom.polytope[cb]] + ej
    a0, a1 = geom.edge_verts[ea, 0], geom.edge_verts[ea, 1]
    b0, b1 = geom.edge_verts[eb, 0], geom.edge_verts[eb, 1]
    px, py, pz, qx, qy, qz = segment_segment(
        va[a0, 0], va[a0, 1], va[a0, 2], va[a1, 0], va[a1, 1], va[a1, 2],
        vb[b0, 0], vb[b0, 1], vb[b0, 2], vb[b1, 0], vb[b1, 1], vb[b1, 2])
    set_normal(man, nx, ny, nz)
    depth = -(nx * (qx - px) + ny * (qy - py) + nz * (qz - pz))
    put_point(man, 0, 0.5 * (px + qx), 0.5 * (py + qy), 0.5 * (pz + qz), depth,
              (1 << 31) | ((ei & 0x7FFF) << 16) | (ej & 0xFFFF))
    return 1


@njit(**INLINE)
def segment_segment(p0x, p0y, p0z, p1x, p1y, p1z, q0x, q0y, q0z, q1x, q1y, q1z):
    """Closest points of segments p0-p1 and q0-q1 (Ericson, Real-Time Collision Detection 5.1.9,
    written here from the formulas): the line parameters, clamped, re-projected once."""
    d1x, d1y, d1z = p1x - p0x, p1y - p0y, p1z - p0z
    d2x, d2y, d2z = q1x - q0x, q1y - q0y, q1z - q0z
    rx, ry, rz = p0x - q0x, p0y - q0y, p0z - q0z
    a = d1x * d1x + d1y * d1y + d1z * d1z
    e = d2x * d2x + d2y * d2y + d2z * d2z
    f = d2x * rx + d2y * ry + d2z * rz
    s = 0.0
    t = 0.0
    if a <= 0.0 and e <= 0.0:
        pass
    elif a <= 0.0:
        t = min(1.0, max(0.0, f / e))
    else:
        c = d1x * rx + d1y * ry + d1z * rz
        if e <= 0.0:
            s = min(1.0, max(0.0, -c / a))
        else:
            b = d1x * d2x + d1y * d2y + d1z * d2z
            denom = a * e - b * b
            if denom > 0.0:
                s = min(1.0, max(0.0, (b * f - c * e) / denom))
            t = (b * s + f) / e
            if t < 0.0:
                t = 0.0
                s = min(1.0, max(0.0, -c / a))
            elif t > 1.0:
                t = 1.0
                s = min(1.0, max(0.0, (b - c) / a))
    return (p0x + s * d1x, p0y + s * d1y, p0z + s * d1z,
            q0x + t * d2x, q0y + t * d2y, q0z + t * d2z)


@njit(**INLINE)
def _face_contact(geom, wpos, wrot, cr, fr, ci, vr, vi, flipped, margin, man, scratch):
    """Clip the incident face of ci against reference face fr (local) of cr. ``flipped``: the
    reference polytope is B, so the normal from A to B is minus the reference normal."""
    pr = geom.polytope[cr]
    pi = geom.polytope[ci]
    gr = geom.poly_face_start[pr] + fr
    nx, ny, nz, off = _world_face(geom, wpos, wrot, cr, gr)
    # incident face: the most anti-parallel to the reference normal
    fi0 = geom.poly_face_start[pi]
    best = np.inf
    fi = 0
    for f in range(geom.poly_face_count[pi]):
        mx, my, mz = _face_normal_world(geom, wrot, ci, fi0 + f)
        d = mx * nx + my * ny + mz * nz
        if d < best:
            best = d
            fi = f
    gi = fi0 + fi
    poly_in = scratch.clip_in
    poly_out = scratch.clip_out
    id_in = scratch.id_in
    id_out = scratch.id_out
    s0 = geom.face_vert_start[gi]
    n_poly = geom.face_vert_count[gi]
    for k in range(n_poly):
        v = geom.face_verts[s0 + k]
        for r in range(3):
            poly_in[k, r] = vi[v, r]
        id_in[k] = k & 0x7F
    # clip against the side planes of the reference face: edge u -> w, outward side normal
    # (w - u) x n (the face is counter-clockwise about n)
    r0 = geom.face_vert_start[gr]
    m = geom.face_vert_count[gr]
    for side in range(m):
        if n_poly == 0:
            break
        u = geom.face_verts[r0 + side]
        w = geom.face_verts[r0 + (side + 1) % m]
        ex, ey, ez = vr[w, 0] - vr[u, 0], vr[w, 1] - vr[u, 1], vr[w, 2] - vr[u, 2]
        sx, sy, sz = ey * nz - ez * ny, ez * nx - ex * nz, ex * ny - ey * nx
        so = sx * vr[u, 0] + sy * vr[u, 1] + sz * vr[u, 2]
        n_out = 0
        for k in range(n_poly):
            k1 = (k + 1) % n_poly
            d0 = sx * poly_in[k, 0] + sy * poly_in[k, 1] + sz * poly_in[k, 2] - so
            d1 = sx * poly_in[k1, 0] + sy * poly_in[k1, 1] + sz * poly_in[k1, 2] - so
            if d0 <= 0.0:
                for r in range(3):
                    poly_out[n_out, r] = poly_in[k, r]
                id_out[n_out] = id_in[k]
                n_out += 1
            if (d0 <= 0.0) != (d1 <= 0.0):
                t = d0 / (d0 - d1)
                for r in range(3):
                    poly_out[n_out, r] = poly_in[k, r] + t * (poly_in[k1, r] - poly_in[k, r])
                # a crossing: the side, and whether the polygon leaves or enters through it
                id_out[n_out] = 0x80 | (0x40 if d0 <= 0.0 else 0) | (side & 0x3F)
                n_out += 1
        poly_in, poly_out = poly_out, poly_in
        id_in, id_out = id_out, id_in
        n_poly = n_out
    if flipped:
        set_normal(man, -nx, -ny, -nz)
    else:
        set_normal(man, nx, ny, nz)
    head = ((1 << 24) if flipped else 0) | ((fr & 0xFF) << 16) | ((fi & 0xFF) << 8)
    count = 0
    for k in range(n_poly):
        gap = nx * poly_in[k, 0] + ny * poly_in[k, 1] + nz * poly_in[k, 2] - off
        if gap > margin or count >= MAX_CANDIDATES:
            continue
        put_point(man, count, poly_in[k, 0] - 0.5 * gap * nx, poly_in[k, 1] - 0.5 * gap * ny,
                  poly_in[k, 2] - 0.5 * gap * nz, -gap, head | (id_in[k] & 0xFF))
        count += 1
    return reduce_to_four(man, count)
