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
from crosscheck.sim.collide.clip3d import clip_polygon
from crosscheck.sim.collide.manifold import MAX_CANDIDATES, MAX_POINTS, reduce_to_four
from crosscheck.sim.collide.narrow3d import segment_segment

# An edge axis is taken over a face axis when it separates by more than this (absolute m, plus a
# fraction of the face separation's size): ties go to the faces, whose manifolds are stable. The
# price: near a tie the depth reported can exceed the least penetration by up to this much.
EDGE_BIAS_ABS = 1e-5
EDGE_BIAS_REL = 0.005
# Reference face: A's unless B's separates by more than this (same form): a choice that does not
# flip between A and B on round-off, at the same price.
FACE_BIAS_ABS = 1e-5
FACE_BIAS_REL = 0.005
# Parallel edges: their cross product is below this (relative to the edge lengths) and the face
# axes cover them.
PARALLEL = 1e-6


class PolytopeScratch(NamedTuple):
    """Per-call scratch of the polytope routine (and of convex3d's clipping), allocated once per
    detection."""

    va: np.ndarray  # (V, 3) world vertices of A
    vb: np.ndarray  # (V, 3) world vertices of B
    clip_in: np.ndarray  # (M, 3) polygon being clipped
    clip_out: np.ndarray  # (M, 3)
    id_in: np.ndarray  # (M,) int64 origin of each polygon vertex (feature)
    id_out: np.ndarray  # (M,) int64
    ref: np.ndarray  # (M, 3) the reference polygon
    na: np.ndarray  # (F, 4) world face planes of A: outward normal, offset
    nb: np.ndarray  # (F, 4) world face planes of B
    eb: np.ndarray  # (E, 16) B's edges, what the edge query needs of each, computed once


@njit(**JIT)
def new_polytope_scratch(max_poly_verts, max_poly_faces, max_poly_edges, max_clip):
    m = max_clip
    return PolytopeScratch(np.zeros((max_poly_verts, 3)), np.zeros((max_poly_verts, 3)),
                           np.zeros((m, 3)), np.zeros((m, 3)), np.zeros(m, np.int64),
                           np.zeros(m, np.int64), np.zeros((m, 3)),
                           np.zeros((max_poly_faces, 4)), np.zeros((max_poly_faces, 4)),
                           np.zeros((max_poly_edges, 16)))


# The routines below take the geometry's arrays, not the geometry: a NamedTuple handed to inlined
# code is copied with a reference count per field (broadphase.py's note).
@njit(**INLINE)
def _world_vertices(vertices, v0, nv, wpos, wrot, c, out):
    for v in range(nv):
        x, y, z = vertices[v0 + v, 0], vertices[v0 + v, 1], vertices[v0 + v, 2]
        for r in range(3):
            out[v, r] = wpos[c, r] + wrot[c, r, 0] * x + wrot[c, r, 1] * y + wrot[c, r, 2] * z


@njit(**INLINE)
def _world_planes(face_normal, face_offset, f0, nf, wpos, wrot, c, out):
    """out[f] = world outward normal and offset of face f0 + f of collider c."""
    for f in range(nf):
        lx, ly, lz = face_normal[f0 + f, 0], face_normal[f0 + f, 1], face_normal[f0 + f, 2]
        nx = wrot[c, 0, 0] * lx + wrot[c, 0, 1] * ly + wrot[c, 0, 2] * lz
        ny = wrot[c, 1, 0] * lx + wrot[c, 1, 1] * ly + wrot[c, 1, 2] * lz
        nz = wrot[c, 2, 0] * lx + wrot[c, 2, 1] * ly + wrot[c, 2, 2] * lz
        out[f, 0], out[f, 1], out[f, 2] = nx, ny, nz
        out[f, 3] = face_offset[f0 + f] + nx * wpos[c, 0] + ny * wpos[c, 1] + nz * wpos[c, 2]


@njit(**INLINE)
def _face_query(planes, nf, other_verts, n_other):
    """The face whose plane the other polytope is farthest outside of: (separation, face index).
    Separation = min over the other's vertices of the distance above the face's plane."""
    best = -np.inf
    best_f = 0
    for f in range(nf):
        nx, ny, nz = planes[f, 0], planes[f, 1], planes[f, 2]
        s = np.inf
        for v in range(n_other):
            s = min(s, nx * other_verts[v, 0] + ny * other_verts[v, 1] + nz * other_verts[v, 2])
        s -= planes[f, 3]
        if s > best:
            best = s
            best_f = f
    return best, best_f


@njit(**INLINE)
def _edge_query(edge_verts, edge_faces, ea0, nea, eb0, neb, na, nb, va, vb, eb, ox, oy, oz):
    """The edge pair (local indices) whose axis separates most, and that separation; -inf when no
    pair spans a face of the Minkowski difference. (ox, oy, oz): an interior point of A, to orient
    each axis away from A. ``eb``: scratch for B's edges, filled here once per pair (the inner
    loop then only reads)."""
    for j in range(neb):
        # B's normals negated (the Gauss map of -B): c, d, d x c; the edge's point, direction
        fc, fd = edge_faces[eb0 + j, 0], edge_faces[eb0 + j, 1]
        cx_, cy_, cz_ = -nb[fc, 0], -nb[fc, 1], -nb[fc, 2]
        dx_, dy_, dz_ = -nb[fd, 0], -nb[fd, 1], -nb[fd, 2]
        ib0, ib1 = edge_verts[eb0 + j, 0], edge_verts[eb0 + j, 1]
        eb[j, 0], eb[j, 1], eb[j, 2] = cx_, cy_, cz_
        eb[j, 3], eb[j, 4], eb[j, 5] = dx_, dy_, dz_
        eb[j, 6] = dy_ * cz_ - dz_ * cy_
        eb[j, 7] = dz_ * cx_ - dx_ * cz_
        eb[j, 8] = dx_ * cy_ - dy_ * cx_
        eb[j, 9], eb[j, 10], eb[j, 11] = vb[ib0, 0], vb[ib0, 1], vb[ib0, 2]
        ex, ey, ez = vb[ib1, 0] - vb[ib0, 0], vb[ib1, 1] - vb[ib0, 1], vb[ib1, 2] - vb[ib0, 2]
        eb[j, 12], eb[j, 13], eb[j, 14] = ex, ey, ez
        eb[j, 15] = np.sqrt(ex * ex + ey * ey + ez * ez)
    best = -np.inf
    best_i = -1
    best_j = -1
    bax, bay, baz = 0.0, 0.0, 0.0
    for i in range(nea):
        ia0, ia1 = edge_verts[ea0 + i, 0], edge_verts[ea0 + i, 1]
        fa, fb = edge_faces[ea0 + i, 0], edge_faces[ea0 + i, 1]
        ax_, ay_, az_ = na[fa, 0], na[fa, 1], na[fa, 2]
        bx_, by_, bz_ = na[fb, 0], na[fb, 1], na[fb, 2]
        # b x a, the arc's plane normal (parallel to the edge)
        bax_, bay_, baz_ = by_ * az_ - bz_ * ay_, bz_ * ax_ - bx_ * az_, bx_ * ay_ - by_ * ax_
        pxa, pya, pza = va[ia0, 0], va[ia0, 1], va[ia0, 2]
        dxa, dya, dza = va[ia1, 0] - pxa, va[ia1, 1] - pya, va[ia1, 2] - pza
        la = np.sqrt(dxa * dxa + dya * dya + dza * dza)
        for j in range(neb):
            cba = eb[j, 0] * bax_ + eb[j, 1] * bay_ + eb[j, 2] * baz_
            dba = eb[j, 3] * bax_ + eb[j, 4] * bay_ + eb[j, 5] * baz_
            if cba * dba >= 0.0:
                continue
            adc = ax_ * eb[j, 6] + ay_ * eb[j, 7] + az_ * eb[j, 8]
            bdc = bx_ * eb[j, 6] + by_ * eb[j, 7] + bz_ * eb[j, 8]
            if adc * bdc >= 0.0 or cba * bdc <= 0.0:
                continue
            dxb, dyb, dzb = eb[j, 12], eb[j, 13], eb[j, 14]
            nx = dya * dzb - dza * dyb
            ny = dza * dxb - dxa * dzb
            nz = dxa * dyb - dya * dxb
            ln = np.sqrt(nx * nx + ny * ny + nz * nz)
            if ln <= PARALLEL * la * eb[j, 15]:
                continue
            nx, ny, nz = nx / ln, ny / ln, nz / ln
            if nx * (pxa - ox) + ny * (pya - oy) + nz * (pza - oz) < 0.0:
                nx, ny, nz = -nx, -ny, -nz
            s = nx * (eb[j, 9] - pxa) + ny * (eb[j, 10] - pya) + nz * (eb[j, 11] - pza)
            if s > best:
                best = s
                best_i = i
                best_j = j
                bax, bay, baz = nx, ny, nz
    return best, best_i, best_j, bax, bay, baz


@njit(**INLINE)
def _dot_columns(wrot, ca, i, cb):
    """(a_i . b_0, a_i . b_1, a_i . b_2): column i of ca's rotation against cb's columns."""
    x, y, z = wrot[ca, 0, i], wrot[ca, 1, i], wrot[ca, 2, i]
    return (x * wrot[cb, 0, 0] + y * wrot[cb, 1, 0] + z * wrot[cb, 2, 0],
            x * wrot[cb, 0, 1] + y * wrot[cb, 1, 1] + z * wrot[cb, 2, 1],
            x * wrot[cb, 0, 2] + y * wrot[cb, 1, 2] + z * wrot[cb, 2, 2])


@njit(**INLINE)
def _cross_axis(edge, sep, t1, t2, r1j, r2j, ha1, ha2, hb1, hb2, ri1, ri2):
    """Separation along a_i x b_j (in A's frame (0, -r2j, r1j) in slots (i, i1, i2)), with
    (i1, i2) and (j1, j2) the cyclic successors of i and j: t1, t2 = t_i1, t_i2; r1j, r2j =
    r[i1, j], r[i2, j]; hb1, hb2 = hb[j1], hb[j2]; ri1, ri2 = r[i, j1], r[i, j2]. Updates the
    edge bound, and the separation when the axis is well defined."""
    ln = np.sqrt(r1j * r1j + r2j * r2j)  # |a_i x b_j| without 1 - r_ij^2's cancellation
    if ln <= 0.5 * PARALLEL:
        return edge, sep
    s = (abs(t2 * r1j - t1 * r2j) - (ha1 * abs(r2j) + ha2 * abs(r1j))
         - (hb1 * abs(ri2) + hb2 * abs(ri1))) / ln
    edge = max(edge, s)
    if ln > 2.0 * PARALLEL:
        sep = max(sep, s)
    return edge, sep


@njit(**JIT)
def box_box_bounds(wpos, wrot, size, ca, cb):
    """Two boxes' 15 separating axes (Gottschalk's OBB test, Ericson 4.4.1) in closed form:
    (largest separation over the 6 face axes and the 9 edge-cross axes, largest separation over
    the edge-cross axes alone, tolerance of both). A separation is the gap between the boxes'
    projections on the axis (negative when they overlap on it).

    What it is for (detect.py): the exact routine's face separations are these face
    axes' and its edge separation is, pair by pair, the separation along that pair's cross axis
    (the pair that realises an axis's support spans a face of the Minkowski difference, so the
    Gauss-map pruning keeps it), so (up to round-off, the tolerance) a separation here above the
    margin means the routine finds nothing, and the routine's edge separation is at most the
    edge bound here. Cross axes of near-parallel edges (|a_i x b_j| below PARALLEL) are left
    out, as the routine leaves them out (their direction is round-off); those between PARALLEL
    / 2 and 2 PARALLEL bound the edge separation but do not separate (the routine may or may
    not have taken them)."""
    ha0, ha1, ha2 = size[ca, 0], size[ca, 1], size[ca, 2]
    hb0, hb1, hb2 = size[cb, 0], size[cb, 1], size[cb, 2]
    tx = wpos[cb, 0] - wpos[ca, 0]
    ty = wpos[cb, 1] - wpos[ca, 1]
    tz = wpos[cb, 2] - wpos[ca, 2]
    # scalars, no scratch arrays (an allocation per pair costs as much as the test):
    # rij = a_i . b_j (the axes are wrot's columns), t0..t2 = t in A's frame
    r00, r01, r02 = _dot_columns(wrot, ca, 0, cb)
    r10, r11, r12 = _dot_columns(wrot, ca, 1, cb)
    r20, r21, r22 = _dot_columns(wrot, ca, 2, cb)
    t0 = wrot[ca, 0, 0] * tx + wrot[ca, 1, 0] * ty + wrot[ca, 2, 0] * tz
    t1 = wrot[ca, 0, 1] * tx + wrot[ca, 1, 1] * ty + wrot[ca, 2, 1] * tz
    t2 = wrot[ca, 0, 2] * tx + wrot[ca, 1, 2] * ty + wrot[ca, 2, 2] * tz
    # A's face axes, then B's
    sep = abs(t0) - ha0 - (hb0 * abs(r00) + hb1 * abs(r01) + hb2 * abs(r02))
    sep = max(sep, abs(t1) - ha1 - (hb0 * abs(r10) + hb1 * abs(r11) + hb2 * abs(r12)))
    sep = max(sep, abs(t2) - ha2 - (hb0 * abs(r20) + hb1 * abs(r21) + hb2 * abs(r22)))
    sep = max(sep, abs(t0 * r00 + t1 * r10 + t2 * r20) - hb0
              - (ha0 * abs(r00) + ha1 * abs(r10) + ha2 * abs(r20)))
    sep = max(sep, abs(t0 * r01 + t1 * r11 + t2 * r21) - hb1
              - (ha0 * abs(r01) + ha1 * abs(r11) + ha2 * abs(r21)))
    sep = max(sep, abs(t0 * r02 + t1 * r12 + t2 * r22) - hb2
              - (ha0 * abs(r02) + ha1 * abs(r12) + ha2 * abs(r22)))
    # a_i x b_j, (i, i1, i2) and (j, j1, j2) cyclic
    edge = -np.inf
    edge, sep = _cross_axis(edge, sep, t1, t2, r10, r20, ha1, ha2, hb1, hb2, r01, r02)  # a0 b0
    edge, sep = _cross_axis(edge, sep, t1, t2, r11, r21, ha1, ha2, hb2, hb0, r02, r00)  # a0 b1
    edge, sep = _cross_axis(edge, sep, t1, t2, r12, r22, ha1, ha2, hb0, hb1, r00, r01)  # a0 b2
    edge, sep = _cross_axis(edge, sep, t2, t0, r20, r00, ha2, ha0, hb1, hb2, r11, r12)  # a1 b0
    edge, sep = _cross_axis(edge, sep, t2, t0, r21, r01, ha2, ha0, hb2, hb0, r12, r10)  # a1 b1
    edge, sep = _cross_axis(edge, sep, t2, t0, r22, r02, ha2, ha0, hb0, hb1, r10, r11)  # a1 b2
    edge, sep = _cross_axis(edge, sep, t0, t1, r00, r10, ha0, ha1, hb1, hb2, r21, r22)  # a2 b0
    edge, sep = _cross_axis(edge, sep, t0, t1, r01, r11, ha0, ha1, hb2, hb0, r22, r20)  # a2 b1
    edge, sep = _cross_axis(edge, sep, t0, t1, r02, r12, ha0, ha1, hb0, hb1, r20, r21)  # a2 b2
    # The two computations round differently: the routine's plane offsets carry the world
    # positions (1e-13 m at 1e3 m from the origin), a near-parallel cross axis divides by its
    # length. 1e-9 m of the scale, far below any margin, costs nothing in early-outs.
    tol = (1e-9 * (1.0 + abs(tx) + abs(ty) + abs(tz) + ha0 + ha1 + ha2 + hb0 + hb1 + hb2)
           + 1e-12 * (abs(wpos[ca, 0]) + abs(wpos[ca, 1]) + abs(wpos[ca, 2])
                      + abs(wpos[cb, 0]) + abs(wpos[cb, 1]) + abs(wpos[cb, 2])))
    return sep, edge, tol


@njit(**JIT)
def polytope_polytope(geom, wpos, wrot, ca, cb, margin, man, scratch, edge_bound):
    """Manifold of polytope colliders A and B (boxes or hulls); returns the point count.

    ``edge_bound``: an upper bound of the edge separation known beforehand (np.inf when none;
    two boxes: box_box_bounds' edge bound plus its tolerance): when it shows that the edge query
    cannot change the outcome (no edge axis separates beyond the margin, none wins over the
    faces) the query, the routine's largest part, is skipped. The result is the same.
    (:func:`polytope_pair` with the geometry's and the scratch's arrays: detect.py's loop calls
    that directly.)"""
    return polytope_pair(geom.vertices, geom.face_normal, geom.face_offset, geom.polytope,
                         geom.poly_vert_start, geom.poly_vert_count, geom.poly_face_start,
                         geom.poly_face_count, geom.poly_edge_start, geom.poly_edge_count,
                         geom.poly_centroid, geom.edge_verts, geom.edge_faces, geom.face_verts,
                         geom.face_vert_start, geom.face_vert_count, wpos, wrot, ca, cb, margin,
                         man, scratch, edge_bound)


# polytope_pair takes the geometry's arrays, not the Geometry: a NamedTuple handed to another
# compiled function is copied with an atomic reference count per field (the Geometry has about
# 45), and every field read costs another. The small Manifold and scratch are read once per call
# into local names. It is a call from detect.py's pair loop, not inlined there, as are
# box_box_bounds and face_after_edge: inlined, numba's IR inliner made that loop's compile cost
# 92 s of its 155 (the inliner's cost grows with the size of the function it inlines into;
# docs/inhouse.md, "Compile time"), and the call costs nothing measurable on a pair's 0.1-0.7 us.
@njit(**JIT)
def polytope_pair(vertices, face_normal, face_offset, polytope, poly_vert_start, poly_vert_count,
                  poly_face_start, poly_face_count, poly_edge_start, poly_edge_count,
                  poly_centroid, edge_verts, edge_faces, face_verts, fv_start, fv_count, wpos,
                  wrot, ca, cb, margin, man, scratch, edge_bound):
    """polytope_polytope on the geometry's arrays."""
    m_normal, m_point, m_depth, m_feature = man.normal, man.point, man.depth, man.feature
    va, vb, na, nb, eb = scratch.va, scratch.vb, scratch.na, scratch.nb, scratch.eb
    clip_in, id_in, clip_out = scratch.clip_in, scratch.id_in, scratch.clip_out
    id_out, ref = scratch.id_out, scratch.ref
    pa, pb = polytope[ca], polytope[cb]
    n_va, n_vb = poly_vert_count[pa], poly_vert_count[pb]
    n_fa, n_fb = poly_face_count[pa], poly_face_count[pb]
    _world_vertices(vertices, poly_vert_start[pa], n_va, wpos, wrot, ca, va)
    _world_vertices(vertices, poly_vert_start[pb], n_vb, wpos, wrot, cb, vb)
    _world_planes(face_normal, face_offset, poly_face_start[pa], n_fa, wpos, wrot, ca, na)
    _world_planes(face_normal, face_offset, poly_face_start[pb], n_fb, wpos, wrot, cb, nb)
    sa, fa = _face_query(na, n_fa, vb, n_vb)
    if sa > margin:
        return 0
    sb, fb = _face_query(nb, n_fb, va, n_va)
    if sb > margin:
        return 0
    fa0, fb0 = poly_face_start[pa], poly_face_start[pb]
    face = max(sa, sb)
    if not (edge_bound <= margin
            and edge_bound <= face + EDGE_BIAS_ABS + EDGE_BIAS_REL * abs(face)):
        # (otherwise the query's se <= edge_bound: neither the return nor the edge contact
        # below can happen, its outcome is known and it is skipped)
        # A's interior point in world, to orient each edge axis away from A
        cx, cy, cz = poly_centroid[pa, 0], poly_centroid[pa, 1], poly_centroid[pa, 2]
        ox = wpos[ca, 0] + wrot[ca, 0, 0] * cx + wrot[ca, 0, 1] * cy + wrot[ca, 0, 2] * cz
        oy = wpos[ca, 1] + wrot[ca, 1, 0] * cx + wrot[ca, 1, 1] * cy + wrot[ca, 1, 2] * cz
        oz = wpos[ca, 2] + wrot[ca, 2, 0] * cx + wrot[ca, 2, 1] * cy + wrot[ca, 2, 2] * cz
        ea0, eb0 = poly_edge_start[pa], poly_edge_start[pb]
        se, ei, ej, ex, ey, ez = _edge_query(edge_verts, edge_faces, ea0, poly_edge_count[pa],
                                             eb0, poly_edge_count[pb], na, nb, va, vb, eb, ox,
                                             oy, oz)
        if se > margin:
            return 0
        if ei >= 0 and se > face + EDGE_BIAS_ABS + EDGE_BIAS_REL * abs(face):
            return _edge_contact(edge_verts, ea0 + ei, eb0 + ej, ei, ej, ex, ey, ez, va, vb,
                                 m_normal, m_point, m_depth, m_feature)
    # the face contact: B's face is the reference when it separates clearly more
    if sb > sa + FACE_BIAS_ABS + FACE_BIAS_REL * abs(sa):
        return _face_contact(nb, fb, fb0, na, n_fa, fa0, vb, va, face_verts, fv_start, fv_count,
                             True, margin, man, m_normal, m_point, m_depth, m_feature, clip_in,
                             id_in, clip_out, id_out, ref, np.inf)
    return _face_contact(na, fa, fa0, nb, n_fb, fb0, va, vb, face_verts, fv_start, fv_count,
                         False, margin, man, m_normal, m_point, m_depth, m_feature, clip_in,
                         id_in, clip_out, id_out, ref, np.inf)


# An edge contact is one point. A tumbling cube that meets another edge on edge rotates about
# that point, and the corner next to it swings into the other's face within the step: measured
# on the 200 cubes into a bin (soft_step, 0.8 s), a corner 0.31 mm outside the face at detection
# was 2.34 mm inside it one step later (closing at 2.6 mm a step, inside the 5 mm margin), because
# no row stood for it; every landing transient over 1 mm there was this. Bullet
# (btPolyhedralContactClipping) and Jolt clip the supporting faces for an edge axis too. Here the
# edge point keeps its own axis, and the face contact the faces would give (the reference face
# chosen as when a face axis wins, its points within the margin, each gap along the reference
# normal: the exact distance to that face for a point over it) is added as a second manifold of
# the same pair (detect.py), so the corner has its speculative row before it arrives. A face
# point deeper than the edge point is left out: the edge depth is the pair's least penetration,
# which no point of one body inside the other exceeds, so a deeper reading along the face normal
# is a point near the face's rim measured the wrong way (it would be pushed out along the face
# normal, where a side face is nearer); the edge row holds the overlap itself.
@njit(**JIT)
def face_after_edge(polytope, poly_vert_count, poly_face_start, poly_face_count, face_verts,
                    fv_start, fv_count, ca, cb, margin, man, scratch, edge_depth):
    """After :func:`polytope_pair` returned an edge contact of depth ``edge_depth`` for (A, B)
    (its world vertices and planes still in ``scratch``): the face contact of the pair into
    ``man``, its points no deeper than the edge's; returns its count."""
    va, vb, na, nb = scratch.va, scratch.vb, scratch.na, scratch.nb
    m_normal, m_point, m_depth, m_feature = man.normal, man.point, man.depth, man.feature
    pa, pb = polytope[ca], polytope[cb]
    n_fa, n_fb = poly_face_count[pa], poly_face_count[pb]
    sa, fa = _face_query(na, n_fa, vb, poly_vert_count[pb])
    sb, fb = _face_query(nb, n_fb, va, poly_vert_count[pa])
    fa0, fb0 = poly_face_start[pa], poly_face_start[pb]
    if sb > sa + FACE_BIAS_ABS + FACE_BIAS_REL * abs(sa):
        return _face_contact(nb, fb, fb0, na, n_fa, fa0, vb, va, face_verts, fv_start, fv_count,
                             True, margin, man, m_normal, m_point, m_depth, m_feature,
                             scratch.clip_in, scratch.id_in, scratch.clip_out, scratch.id_out,
                             scratch.ref, edge_depth)
    return _face_contact(na, fa, fa0, nb, n_fb, fb0, va, vb, face_verts, fv_start, fv_count,
                         False, margin, man, m_normal, m_point, m_depth, m_feature,
                         scratch.clip_in, scratch.id_in, scratch.clip_out, scratch.id_out,
                         scratch.ref, edge_depth)


@njit(**INLINE)
def is_edge_contact(n, m_feature):
    """polytope_pair's result was its one-point edge contact (feature bit 31)."""
    return n == 1 and (m_feature[0] >> 31) & 1 == 1


@njit(**INLINE)
def _put(m_point, m_depth, m_feature, k, px, py, pz, depth, feature):
    """manifold.put_point on the Manifold's arrays."""
    m_point[k, 0] = px
    m_point[k, 1] = py
    m_point[k, 2] = pz
    m_depth[k] = depth
    m_feature[k] = feature


@njit(**INLINE)
def _edge_contact(edge_verts, ea, eb, ei, ej, nx, ny, nz, va, vb, m_normal, m_point, m_depth,
                  m_feature):
    """One point midway between the closest points of edge ea of A and edge eb of B (global
    indices; ei, ej local, for the feature id)."""
    a0, a1 = edge_verts[ea, 0], edge_verts[ea, 1]
    b0, b1 = edge_verts[eb, 0], edge_verts[eb, 1]
    px, py, pz, qx, qy, qz = segment_segment(
        va[a0, 0], va[a0, 1], va[a0, 2], va[a1, 0], va[a1, 1], va[a1, 2],
        vb[b0, 0], vb[b0, 1], vb[b0, 2], vb[b1, 0], vb[b1, 1], vb[b1, 2])
    m_normal[0], m_normal[1], m_normal[2] = nx, ny, nz
    depth = -(nx * (qx - px) + ny * (qy - py) + nz * (qz - pz))
    _put(m_point, m_depth, m_feature, 0, 0.5 * (px + qx), 0.5 * (py + qy), 0.5 * (pz + qz), depth,
         (1 << 31) | ((ei & 0x7FFF) << 16) | (ej & 0xFFFF))
    return 1


@njit(**INLINE)
def _face_contact(nr, fr, fr0, ni, n_fi, fi0, vr, vi, face_verts, fv_start, fv_count, flipped,
                  margin, man, m_normal, m_point, m_depth, m_feature, clip_in, id_in, clip_out,
                  id_out, ref, deepest):
    """Clip the incident face (of the polytope with planes ni, faces fi0.., vertices vi) against
    reference face fr (planes nr, faces fr0.., vertices vr). ``flipped``: the reference polytope
    is B, so the normal from A to B is minus the reference normal. Points deeper than
    ``deepest`` are left out (np.inf: none; face_after_edge: why)."""
    nx, ny, nz, off = nr[fr, 0], nr[fr, 1], nr[fr, 2], nr[fr, 3]
    # incident face: the most anti-parallel to the reference normal
    best = np.inf
    fi = 0
    for f in range(n_fi):
        d = ni[f, 0] * nx + ni[f, 1] * ny + ni[f, 2] * nz
        if d < best:
            best = d
            fi = f
    gi = fi0 + fi
    gr = fr0 + fr
    s0 = fv_start[gi]
    n_poly = fv_count[gi]
    for k in range(n_poly):
        v = face_verts[s0 + k]
        for r in range(3):
            clip_in[k, r] = vi[v, r]
        id_in[k] = k & 0x7F
    r0 = fv_start[gr]
    m = fv_count[gr]
    for k in range(m):
        v = face_verts[r0 + k]
        for r in range(3):
            ref[k, r] = vr[v, r]
    n_poly = clip_polygon(ref, m, nx, ny, nz, clip_in, id_in, n_poly, clip_out, id_out)
    if flipped:
        m_normal[0], m_normal[1], m_normal[2] = -nx, -ny, -nz
    else:
        m_normal[0], m_normal[1], m_normal[2] = nx, ny, nz
    head = ((1 << 24) if flipped else 0) | ((fr & 0xFF) << 16) | ((fi & 0xFF) << 8)
    count = np.int64(0)  # not a literal 0 (sim/_jit.py: "Literal arguments")
    for k in range(n_poly):
        gap = nx * clip_in[k, 0] + ny * clip_in[k, 1] + nz * clip_in[k, 2] - off
        if gap > margin or -gap > deepest or count >= MAX_CANDIDATES:
            continue
        _put(m_point, m_depth, m_feature, count, clip_in[k, 0] - 0.5 * gap * nx,
             clip_in[k, 1] - 0.5 * gap * ny, clip_in[k, 2] - 0.5 * gap * nz, -gap,
             head | (id_in[k] & 0xFF))
        count += 1
    if count <= MAX_POINTS:  # (the reduction's own first test, without its call)
        return count
    return reduce_to_four(man, count)
