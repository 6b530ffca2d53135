"""Detection: colliders' world poses -> broad phase -> narrow phase per pair -> contact rows.

``detect3d(geometry, x, q, contacts)`` and ``detect2d(geometry, x, angle, contacts)`` (compiled)
refill ``contacts`` (sim/collide/contacts.py) from the bodies' state: ``x`` the centres of mass,
``q`` the body-frame quaternions (w, x, y, z) or ``angle`` the 2D angles. Rows come in a fixed
order (body-body and body-static pairs in broad-phase order, then body-ground), so the same state
gives bit-identical rows. Row orientation: ``a`` is always a body (the lower index of two
bodies), ``b`` the other body or -1 for a static or the ground; the normal points from a to b.
``collide_pair3d(geometry, x, q, ca, cb, contacts)`` fills the buffer with one pair's rows alone,
by the same compiled loop (``_pairs3d``) detect3d runs over the broad phase's pairs, so a pair
tested alone gets exactly the rows detect3d gives it (an edge contact's face rows included).

``needed`` counts every contact found, ``count = min(needed, capacity)``: when ``needed >
capacity`` the rows past the capacity are lost and the caller must fail the step (the adapter
raises StepFailure), or grow the buffer (:func:`new_contacts` with a larger capacity) and detect
again. :func:`contact_capacity` is a capacity that fits dense piles.

Feature key: ``(pair << 32) | local``, pair = ``ca * (C + G) + cb`` of the row's a- and
b-colliders (cb = C + g for ground plane g) and ``local`` the routine's id of the touching
features (< 2**32), stable while the same features touch.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from crosscheck.sim._jit import INLINE, JIT
from crosscheck.sim.collide.broadphase import box_reaches_plane, broad_phase
from crosscheck.sim.collide.contacts import Contacts
from crosscheck.sim.collide.convex3d import CAP_POINTS, convex_convex
from crosscheck.sim.collide.geometry import (
    BOX,
    CAPSULE,
    CIRCLE,
    CYLINDER,
    HULL,
    SPHERE,
    Geometry2D,
    Geometry3D,
)
from crosscheck.sim.collide.gjk import (
    EPA_MAX_FACES,
    EPA_MAX_VERTS,
    GjkScratch,
)
from crosscheck.sim.collide.manifold import MAX_CANDIDATES, Manifold
from crosscheck.sim.collide.narrow2d import circle_polygon, circles, line_collider, polygon_polygon
from crosscheck.sim.collide.narrow3d import (
    capsule_capsule,
    plane_box,
    plane_collider,
    plane_sphere,
    sphere_box,
    sphere_capsule,
    sphere_cylinder,
    sphere_sphere,
)
from crosscheck.sim.collide.polytope3d import (
    box_box_bounds,
    face_after_edge,
    is_edge_contact,
    new_polytope_scratch,
    polytope_pair,
    polytope_polytope,
)
from crosscheck.sim.collide.pose import (
    bounding_boxes2d,
    bounding_boxes3d,
    world_poses2d,
    world_poses3d,
)

# Contact rows per body a fresh buffer holds: a sphere in a dense pile touches about six others
# (three rows of its own) and a box resting on boxes has 4-point manifolds above and below.
ROWS_PER_BODY_3D = 16
ROWS_PER_BODY_2D = 8
# Broad-phase pairs per collider the first try holds (a dense pile of spheres has about 12; more
# costs a second broad-phase pass, never a loss)
PAIRS_PER_COLLIDER = 16


def contact_capacity(geometry: Geometry3D | Geometry2D) -> int:
    per_body = ROWS_PER_BODY_3D if isinstance(geometry, Geometry3D) else ROWS_PER_BODY_2D
    return max(64, per_body * (geometry.n_bodies + len(geometry.plane_offset)))


def new_contacts(geometry: Geometry3D | Geometry2D, capacity: int | None = None) -> Contacts:
    """A contact buffer for this geometry: ``contact_capacity`` rows unless told otherwise."""
    d = 3 if isinstance(geometry, Geometry3D) else 2
    return Contacts.empty(contact_capacity(geometry) if capacity is None else capacity, d)


# -- rows -----------------------------------------------------------------------------------------
# The loops below read every array through a local name taken once per detection, never through a
# NamedTuple (geometry, contacts, manifold) inside the loop: numba counts a reference on every
# field access, which cost more than the narrow phase itself (broadphase.py's note).
@njit(**INLINE)
def emit(n, m_normal, m_point, m_depth, m_feature, a, b, key, mu, e, rolling, torsional,
         out_a, out_b, out_normal, out_point, out_depth, out_mu, out_e, out_rolling,
         out_torsional, out_feature, needed):
    """Append the manifold's n points as rows (body a, body b or -1, the pair's values and
    feature key ``key``); returns the new ``needed``. Rows past the capacity are counted only."""
    cap = out_a.shape[0]
    d = out_normal.shape[1]
    for k in range(n):
        row = needed
        needed += 1
        if row >= cap:
            continue
        out_a[row] = a
        out_b[row] = b
        for r in range(d):
            out_normal[row, r] = m_normal[r]
            out_point[row, r] = m_point[k, r]
        out_depth[row] = m_depth[k]
        out_mu[row] = mu
        out_e[row] = e
        out_rolling[row] = rolling
        out_torsional[row] = torsional
        out_feature[row] = (key << 32) | (m_feature[k] & 0xFFFFFFFF)
    return needed


@njit(**INLINE)
def row_order(body, i, j):
    """(first, second): the collider whose body is row a (a body; the lower body index of two)."""
    bi, bj = body[i], body[j]
    if bi < 0 or (bj >= 0 and bj < bi):
        return j, i
    return i, j


# -- 3D -------------------------------------------------------------------------------------------
# Pairs in kind order (sphere < box < capsule < cylinder < hull): each routine takes its two
# shapes in that order, so a pair given the other way round is computed swapped and its normal
# negated. The closed forms are inlined and take arrays only; the polytope and convex routines
# are calls (they take the geometry: passing a NamedTuple into inlined code copies it, a reference
# count per field, on every pair).
@njit(**INLINE)
def closed_form_pair3d(ka, kb, size, wpos, wrot, ca, cb, margin, man):
    """Manifold of (ca, cb) with ka <= kb by a closed form; -1 when the pair has none."""
    if ka == SPHERE:
        r = size[ca, 0]
        if kb == SPHERE:
            return sphere_sphere(wpos, ca, r, cb, size[cb, 0], margin, man)
        if kb == BOX:
            return sphere_box(wpos, wrot, ca, r, cb, size[cb, 0], size[cb, 1], size[cb, 2],
                              margin, man)
        if kb == CAPSULE:
            return sphere_capsule(wpos, wrot, ca, r, cb, size[cb, 0], size[cb, 1], margin, man)
        if kb == CYLINDER:
            return sphere_cylinder(wpos, wrot, ca, r, cb, size[cb, 0], size[cb, 1], margin,
                                   man)
        return -1
    if ka == CAPSULE and kb == CAPSULE:
        return capsule_capsule(wpos, wrot, ca, size[ca, 0], size[ca, 1], cb, size[cb, 0],
                               size[cb, 1], margin, man)
    return -1


# Two boxes: their 15 axes in closed form first (box_box_bounds, ~35 ns). Measured on the
# settled pile of 200 cubes (boxes_bin_200, 841 box pairs from the broad phase, docs/inhouse.md):
# half are apart by more than the margin (a tilted cube's bounding box is up to 1.7x its size)
# and end here, 35 to 60 ns instead of the general routine's 760; of those that touch, nearly all
# rest face on face, where no edge axis separates near the faces and the routine skips its edge
# query (the Gauss-map loop over 12 x 12 edge pairs). Both only skip work whose outcome is known:
# the result is the general routine's, bit for bit (tests/collide/test_box_box.py). The loop
# below writes this out and calls the routine (polytope_pair) on the geometry's arrays.
@njit(**INLINE)
def box_box(geom, size, wpos, wrot, ca, cb, margin, man, scratch):
    """Manifold of box colliders ca and cb (polytope_polytope's, with its box shortcuts)."""
    sep, edge, tol = box_box_bounds(wpos, wrot, size, ca, cb)
    if sep > margin + tol:
        return 0
    return polytope_polytope(geom, wpos, wrot, ca, cb, margin, man, scratch, edge + tol)


@njit(**INLINE)
def _scratch3d(geom):
    """The narrow phase's scratch for one detection: (manifold, polytope scratch, GJK/EPA
    scratch, lam)."""
    man = Manifold(np.zeros(3), np.zeros((MAX_CANDIDATES, 3)), np.zeros(MAX_CANDIDATES),
                   np.zeros(MAX_CANDIDATES, np.int64))
    scratch = new_polytope_scratch(geom.max_poly_verts, geom.max_poly_faces, geom.max_poly_edges,
                                   2 * max(geom.max_face_verts, CAP_POINTS) + 4)
    gs = GjkScratch(np.zeros((EPA_MAX_VERTS, 3)), np.zeros((EPA_MAX_VERTS, 3)),
                    np.zeros((EPA_MAX_VERTS, 3)), np.zeros((EPA_MAX_FACES, 3), np.int64),
                    np.zeros((EPA_MAX_FACES, 4)), np.zeros(EPA_MAX_FACES, np.bool_),
                    np.zeros((3 * EPA_MAX_FACES, 2), np.int64))
    return man, scratch, gs, np.zeros(4)


@njit(**JIT)
def detect3d(geom, x, q, contacts):
    """Fill ``contacts`` from the state (x (N, 3), q (N, 4)); returns the rows needed."""
    c = geom.kind.shape[0]
    margin = geom.margin
    wpos = np.empty((c, 3))
    wrot = np.empty((c, 3, 3))
    lo = np.empty((c, 3))
    hi = np.empty((c, 3))
    world_poses3d(geom, x, q, wpos, wrot)
    bounding_boxes3d(geom, wpos, wrot, 0.5 * margin, lo, hi)
    man, scratch, gs, lam = _scratch3d(geom)
    pairs, n_pairs = broad_phase(geom, lo, hi, np.empty((PAIRS_PER_COLLIDER * c + 16, 2),
                                                         np.int64))
    needed = _pairs3d(geom, contacts, man, pairs, n_pairs, wpos, wrot, scratch, gs, lam)
    needed = _planes3d(geom, contacts, man, wpos, wrot, lo, hi, needed)
    contacts.needed[0] = needed
    contacts.count[0] = min(needed, contacts.a.shape[0])
    return needed


@njit(**JIT)
def collide_pair3d(geom, x, q, ca, cb, contacts):
    """Fill ``contacts`` with the rows of colliders ``ca`` and ``cb`` alone at the state (x, q),
    exactly as :func:`detect3d` writes that pair's rows (the same compiled loop, ``_pairs3d``, on a
    one-pair list; no broad phase, no planes): the pair's manifold, and after a polytope pair's
    edge contact the face contact of the same pair (polytope3d.face_after_edge), each row
    oriented as detect3d orients it (a the body of lower index, the normal from a to b).
    Returns the rows needed. For tests and tools, outside the hot loop."""
    c = geom.kind.shape[0]
    wpos = np.empty((c, 3))
    wrot = np.empty((c, 3, 3))
    world_poses3d(geom, x, q, wpos, wrot)
    man, scratch, gs, lam = _scratch3d(geom)
    pairs = np.empty((1, 2), np.int64)
    pairs[0, 0] = ca
    pairs[0, 1] = cb
    # (n_pairs an int64 as the broad phase's count, not the literal 1: a literal argument would
    # compile _pairs3d a second time, for this signature)
    needed = _pairs3d(geom, contacts, man, pairs, pairs.shape[0], wpos, wrot, scratch, gs, lam)
    contacts.needed[0] = needed
    contacts.count[0] = min(needed, contacts.a.shape[0])
    return needed


# The one code path of a pair's rows: detect3d runs it over the broad phase's pairs,
# collide_pair3d over one pair.
@njit(**JIT)
def _pairs3d(geom, contacts, man, pairs, n_pairs, wpos, wrot, scratch, gs, lam):
    """The narrow phase over ``pairs[:n_pairs]``, rows from the buffer's first on: per
    pair its manifold, and after a polytope pair's one-point edge contact the faces' contact of
    the same pair (polytope3d.face_after_edge). Returns the rows needed. (_pairs_and_planes2d is
    the same loop with the 2D routines.)"""
    body, cls = geom.body, geom.material_class
    friction, restitution = geom.pair_friction, geom.pair_restitution
    rolling, torsional = geom.pair_rolling_friction, geom.pair_torsional_friction
    m_normal, m_point, m_depth, m_feature = man.normal, man.point, man.depth, man.feature
    out_a, out_b, out_normal, out_point = contacts.a, contacts.b, contacts.normal, contacts.point
    out_depth, out_mu, out_e = contacts.depth, contacts.friction, contacts.restitution
    out_rolling, out_torsional = contacts.rolling_friction, contacts.torsional_friction
    out_feature = contacts.feature
    margin = geom.margin
    c = body.shape[0]
    n_keys = c + geom.plane_class.shape[0]
    needed = 0
    kind, size = geom.kind, geom.size
    vertices, face_normal, face_offset = geom.vertices, geom.face_normal, geom.face_offset
    polytope, poly_centroid = geom.polytope, geom.poly_centroid
    poly_vert_start, poly_vert_count = geom.poly_vert_start, geom.poly_vert_count
    poly_face_start, poly_face_count = geom.poly_face_start, geom.poly_face_count
    poly_edge_start, poly_edge_count = geom.poly_edge_start, geom.poly_edge_count
    edge_verts, edge_faces = geom.edge_verts, geom.edge_faces
    face_verts, fv_start, fv_count = geom.face_verts, geom.face_vert_start, geom.face_vert_count
    for p in range(n_pairs):
        first, second = row_order(body, pairs[p, 0], pairs[p, 1])
        ca, cb = first, second
        ka, kb = kind[ca], kind[cb]
        swapped = ka > kb
        if swapped:
            ca, cb = cb, ca
            ka, kb = kb, ka
        n = closed_form_pair3d(ka, kb, size, wpos, wrot, ca, cb, margin, man)
        if n < 0:
            if (ka == BOX or ka == HULL) and (kb == BOX or kb == HULL):
                # box_box / polytope_polytope written out, on the arrays taken above
                n = 0
                edge_bound = np.inf
                apart = False
                if ka == BOX and kb == BOX:
                    sep, edge, tol = box_box_bounds(wpos, wrot, size, ca, cb)
                    apart = sep > margin + tol
                    edge_bound = edge + tol
                if not apart:
                    n = polytope_pair(vertices, face_normal, face_offset, polytope,
                                      poly_vert_start, poly_vert_count, poly_face_start,
                                      poly_face_count, poly_edge_start, poly_edge_count,
                                      poly_centroid, edge_verts, edge_faces, face_verts,
                                      fv_start, fv_count, wpos, wrot, ca, cb, margin, man,
                                      scratch, edge_bound)
                    if is_edge_contact(n, m_feature):
                        # the edge point, then the faces' contact of the same pair
                        # (polytope3d.face_after_edge: why)
                        if swapped:
                            for r in range(3):
                                m_normal[r] = -m_normal[r]
                        k1, k2 = cls[first], cls[second]
                        needed = emit(n, m_normal, m_point, m_depth, m_feature, body[first],
                                      body[second], first * n_keys + second, friction[k1, k2],
                                      restitution[k1, k2], rolling[k1, k2], torsional[k1, k2],
                                      out_a, out_b, out_normal, out_point, out_depth, out_mu,
                                      out_e, out_rolling, out_torsional, out_feature, needed)
                        n = face_after_edge(polytope, poly_vert_count, poly_face_start,
                                            poly_face_count, face_verts, fv_start, fv_count, ca,
                                            cb, margin, man, scratch, m_depth[0])
            else:
                n = convex_convex(geom, wpos, wrot, ca, cb, margin, man, gs, lam, scratch)
        if swapped and n > 0:
            for r in range(3):
                m_normal[r] = -m_normal[r]
        if n > 0:
            k1, k2 = cls[first], cls[second]
            needed = emit(n, m_normal, m_point, m_depth, m_feature, body[first], body[second],
                          first * n_keys + second, friction[k1, k2], restitution[k1, k2],
                          rolling[k1, k2], torsional[k1, k2], out_a, out_b, out_normal,
                          out_point, out_depth, out_mu, out_e, out_rolling, out_torsional,
                          out_feature, needed)
    return needed


@njit(**JIT)
def _planes3d(geom, contacts, man, wpos, wrot, lo, hi, needed):
    """Every body against every plane, rows appended after the first ``needed``; returns the
    rows needed."""
    body, cls = geom.body, geom.material_class
    friction, restitution = geom.pair_friction, geom.pair_restitution
    rolling, torsional = geom.pair_rolling_friction, geom.pair_torsional_friction
    collide, plane_class = geom.pair_collide, geom.plane_class
    plane_normal, plane_offset = geom.plane_normal, geom.plane_offset
    m_normal, m_point, m_depth, m_feature = man.normal, man.point, man.depth, man.feature
    out_a, out_b, out_normal, out_point = contacts.a, contacts.b, contacts.normal, contacts.point
    out_depth, out_mu, out_e = contacts.depth, contacts.friction, contacts.restitution
    out_rolling, out_torsional = contacts.rolling_friction, contacts.torsional_friction
    out_feature = contacts.feature
    margin = geom.margin
    c = body.shape[0]
    n_planes = plane_class.shape[0]
    n_keys = c + n_planes
    kind, size = geom.kind, geom.size
    for g in range(n_planes):
        kg = plane_class[g]
        for b in range(geom.n_bodies):
            kb = cls[b]
            if not collide[kb, kg]:
                continue
            if not box_reaches_plane(plane_normal, plane_offset, lo, hi, b, g, margin):
                continue
            if kind[b] == SPHERE:
                n = plane_sphere(plane_normal, plane_offset, wpos, size, b, g, margin, man)
            elif kind[b] == BOX:
                n = plane_box(plane_normal, plane_offset, wpos, wrot, size, b, g, margin, man)
            else:
                n = plane_collider(geom, wpos, wrot, b, g, margin, man)
            if n > 0:
                needed = emit(n, m_normal, m_point, m_depth, m_feature, b, -1,
                              b * n_keys + c + g, friction[kb, kg], restitution[kb, kg],
                              rolling[kb, kg], torsional[kb, kg], out_a, out_b, out_normal,
                              out_point, out_depth, out_mu, out_e, out_rolling, out_torsional,
                              out_feature, needed)
    return needed


# -- 2D -------------------------------------------------------------------------------------------
@njit(**JIT)
def collide_pair2d(geom, wpos, wrot, ca, cb, margin, man):
    ka, kb = geom.kind[ca], geom.kind[cb]
    swapped = ka > kb
    if swapped:
        ca, cb = cb, ca
        ka, kb = kb, ka
    if ka == CIRCLE and kb == CIRCLE:
        n = circles(wpos[ca, 0], wpos[ca, 1], geom.radius[ca], wpos[cb, 0], wpos[cb, 1],
                    geom.radius[cb], margin, man, 0, 0, 0.0, 1.0)
    elif ka == CIRCLE:
        n = circle_polygon(geom, wpos, wrot, ca, cb, margin, man)
    else:
        n = polygon_polygon(geom, wpos, wrot, ca, cb, margin, man)
    if swapped and n > 0:
        man.normal[0] = -man.normal[0]
        man.normal[1] = -man.normal[1]
    return n


@njit(**JIT)
def detect2d(geom, x, angle, contacts):
    """Fill ``contacts`` from the state (x (N, 2), angle (N,)); returns the rows needed."""
    c = geom.kind.shape[0]
    margin = geom.margin
    wpos = np.empty((c, 2))
    wrot = np.empty((c, 2))
    lo = np.empty((c, 2))
    hi = np.empty((c, 2))
    world_poses2d(geom, x, angle, wpos, wrot)
    bounding_boxes2d(geom, wpos, wrot, 0.5 * margin, lo, hi)
    man = Manifold(np.zeros(2), np.zeros((MAX_CANDIDATES, 2)), np.zeros(MAX_CANDIDATES),
                   np.zeros(MAX_CANDIDATES, np.int64))
    pairs, n_pairs = broad_phase(geom, lo, hi, np.empty((PAIRS_PER_COLLIDER * c + 16, 2),
                                                         np.int64))
    needed = _pairs_and_planes2d(geom, contacts, man, pairs, n_pairs, wpos, wrot, lo, hi)
    contacts.needed[0] = needed
    contacts.count[0] = min(needed, contacts.a.shape[0])
    return needed


@njit(**JIT)
def _pairs_and_planes2d(geom, contacts, man, pairs, n_pairs, wpos, wrot, lo, hi):
    """_pairs3d and _planes3d in one loop, with the 2D routines."""
    body, cls = geom.body, geom.material_class
    friction, restitution = geom.pair_friction, geom.pair_restitution
    rolling, torsional = geom.pair_rolling_friction, geom.pair_torsional_friction
    collide, plane_class = geom.pair_collide, geom.plane_class
    plane_normal, plane_offset = geom.plane_normal, geom.plane_offset
    m_normal, m_point, m_depth, m_feature = man.normal, man.point, man.depth, man.feature
    out_a, out_b, out_normal, out_point = contacts.a, contacts.b, contacts.normal, contacts.point
    out_depth, out_mu, out_e = contacts.depth, contacts.friction, contacts.restitution
    out_rolling, out_torsional = contacts.rolling_friction, contacts.torsional_friction
    out_feature = contacts.feature
    margin = geom.margin
    c = body.shape[0]
    n_planes = plane_class.shape[0]
    n_keys = c + n_planes
    needed = 0
    kind, radius = geom.kind, geom.radius
    for p in range(n_pairs):
        first, second = row_order(body, pairs[p, 0], pairs[p, 1])
        ca, cb = first, second
        if kind[ca] > kind[cb]:
            ca, cb = cb, ca
        if kind[ca] == CIRCLE and kind[cb] == CIRCLE:
            n = circles(wpos[ca, 0], wpos[ca, 1], radius[ca], wpos[cb, 0], wpos[cb, 1],
                        radius[cb], margin, man, 0, 0, 0.0, 1.0)
        elif kind[ca] == CIRCLE:
            n = circle_polygon(geom, wpos, wrot, ca, cb, margin, man)
        else:
            n = polygon_polygon(geom, wpos, wrot, ca, cb, margin, man)
        if ca != first and n > 0:
            m_normal[0] = -m_normal[0]
            m_normal[1] = -m_normal[1]
        if n > 0:
            k1, k2 = cls[first], cls[second]
            needed = emit(n, m_normal, m_point, m_depth, m_feature, body[first], body[second],
                          first * n_keys + second, friction[k1, k2], restitution[k1, k2],
                          rolling[k1, k2], torsional[k1, k2], out_a, out_b, out_normal,
                          out_point, out_depth, out_mu, out_e, out_rolling, out_torsional,
                          out_feature, needed)
    for g in range(n_planes):
        kg = plane_class[g]
        for b in range(geom.n_bodies):
            kb = cls[b]
            if not collide[kb, kg]:
                continue
            if not box_reaches_plane(plane_normal, plane_offset, lo, hi, b, g, margin):
                continue
            n = line_collider(geom, wpos, wrot, b, g, margin, man)
            if n > 0:
                needed = emit(n, m_normal, m_point, m_depth, m_feature, b, -1,
                              b * n_keys + c + g, friction[kb, kg], restitution[kb, kg],
                              rolling[kb, kg], torsional[kb, kg], out_a, out_b, out_normal,
                              out_point, out_depth, out_mu, out_e, out_rolling, out_torsional,
                              out_feature, needed)
    return needed
