"""Detection: colliders' world poses -> broad phase -> narrow phase per pair -> contact rows.

``detect3d(geometry, x, q, contacts)`` and ``detect2d(geometry, x, angle, contacts)`` (compiled)
refill ``contacts`` (sim/collide/contacts.py) from the bodies' state: ``x`` the centres of mass,
``q`` the body-frame quaternions (w, x, y, z) or ``angle`` the 2D angles. Rows come in a fixed
order (body-body and body-static pairs in broad-phase order, then body-ground), so the same state
gives bit-identical rows. Row orientation: ``a`` is always a body (the lower index of two
bodies), ``b`` the other body or -1 for a static or the ground; the normal points from a to b.

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
from crosscheck.sim.collide.broadphase import box_reaches_plane, brute_force_pairs
from crosscheck.sim.collide.contacts import Contacts
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
from crosscheck.sim.collide.manifold import MAX_CANDIDATES, Manifold
from crosscheck.sim.collide.narrow2d import circle_polygon, circles, line_collider, polygon_polygon
from crosscheck.sim.collide.narrow3d import (
    plane_collider,
    sphere_box,
    sphere_capsule,
    sphere_cylinder,
    sphere_sphere,
)
from crosscheck.sim.collide.polytope3d import PolytopeScratch, polytope_polytope
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


def contact_capacity(geometry: Geometry3D | Geometry2D) -> int:
    per_body = ROWS_PER_BODY_3D if isinstance(geometry, Geometry3D) else ROWS_PER_BODY_2D
    return max(64, per_body * (geometry.n_bodies + len(geometry.plane_offset)))


def new_contacts(geometry: Geometry3D | Geometry2D, capacity: int | None = None) -> Contacts:
    """A contact buffer for this geometry: ``contact_capacity`` rows unless told otherwise."""
    d = 3 if isinstance(geometry, Geometry3D) else 2
    return Contacts.empty(contact_capacity(geometry) if capacity is None else capacity, d)


# -- rows -----------------------------------------------------------------------------------------
@njit(**INLINE)
def emit(geom, contacts, man, n, c_first, c_second, b_first, b_second, flip, pair_key,
         cls_first, cls_second, needed):
    """Append the manifold's n points as rows (a = b_first, b = b_second, the manifold's normal
    negated when ``flip``); returns the new ``needed``."""
    cap = contacts.a.shape[0]
    d = contacts.normal.shape[1]
    s = -1.0 if flip else 1.0
    for k in range(n):
        row = needed
        needed += 1
        if row >= cap:
            continue
        contacts.a[row] = b_first
        contacts.b[row] = b_second
        for r in range(d):
            contacts.normal[row, r] = s * man.normal[r]
            contacts.point[row, r] = man.point[k, r]
        contacts.depth[row] = man.depth[k]
        contacts.friction[row] = geom.pair_friction[cls_first, cls_second]
        contacts.restitution[row] = geom.pair_restitution[cls_first, cls_second]
        contacts.rolling_friction[row] = geom.pair_rolling_friction[cls_first, cls_second]
        contacts.torsional_friction[row] = geom.pair_torsional_friction[cls_first, cls_second]
        contacts.feature[row] = (pair_key << 32) | (man.feature[k] & 0xFFFFFFFF)
    return needed


@njit(**INLINE)
def row_order(geom, i, j):
    """(first, second): the collider whose body is row a (a body; the lower body index of two)."""
    bi, bj = geom.body[i], geom.body[j]
    if bi < 0 or (bj >= 0 and bj < bi):
        return j, i
    return i, j


# -- 3D -------------------------------------------------------------------------------------------
@njit(**INLINE)
def collide_pair3d(geom, wpos, wrot, ca, cb, margin, man, scratch):
    """Manifold of colliders (ca, cb), normal from ca to cb; the routines take their shapes in
    kind order, so a pair given the other way round is computed swapped and its normal negated."""
    ka, kb = geom.kind[ca], geom.kind[cb]
    swapped = ka > kb
    if swapped:
        ca, cb = cb, ca
        ka, kb = kb, ka
    n = 0
    if ka == SPHERE:
        r = geom.size[ca, 0]
        if kb == SPHERE:
            n = sphere_sphere(wpos, ca, r, cb, geom.size[cb, 0], margin, man)
        elif kb == BOX:
            n = sphere_box(wpos, wrot, ca, r, cb, geom.size[cb, 0], geom.size[cb, 1],
                           geom.size[cb, 2], margin, man)
        elif kb == CAPSULE:
            n = sphere_capsule(wpos, wrot, ca, r, cb, geom.size[cb, 0], geom.size[cb, 1],
                               margin, man)
        elif kb == CYLINDER:
            n = sphere_cylinder(wpos, wrot, ca, r, cb, geom.size[cb, 0], geom.size[cb, 1],
                                margin, man)
    elif (ka == BOX or ka == HULL) and (kb == BOX or kb == HULL):
        n = polytope_polytope(geom, wpos, wrot, ca, cb, margin, man, scratch)
    if swapped and n > 0:
        for r in range(3):
            man.normal[r] = -man.normal[r]
    return n


@njit(**JIT)
def detect3d(geom, x, q, contacts):
    """Fill ``contacts`` from the state (x (N, 3), q (N, 4)); returns the rows needed."""
    c = geom.kind.shape[0]
    n_planes = geom.plane_offset.shape[0]
    margin = geom.margin
    wpos = np.empty((c, 3))
    wrot = np.empty((c, 3, 3))
    lo = np.empty((c, 3))
    hi = np.empty((c, 3))
    world_poses3d(geom, x, q, wpos, wrot)
    bounding_boxes3d(geom, wpos, wrot, 0.5 * margin, lo, hi)
    man = Manifold(np.zeros(3), np.zeros((MAX_CANDIDATES, 3)), np.zeros(MAX_CANDIDATES),
                   np.zeros(MAX_CANDIDATES, np.int64))
    m = 2 * geom.max_face_verts + 4
    scratch = PolytopeScratch(np.zeros((geom.max_poly_verts, 3)),
                              np.zeros((geom.max_poly_verts, 3)), np.zeros((m, 3)),
                              np.zeros((m, 3)), np.zeros(m, np.int64), np.zeros(m, np.int64))
    pairs, n_pairs = brute_force_pairs(geom, lo, hi, np.empty((4 * c + 16, 2), np.int64))
    n_keys = c + n_planes
    needed = 0
    for p in range(n_pairs):
        first, second = row_order(geom, pairs[p, 0], pairs[p, 1])
        n = collide_pair3d(geom, wpos, wrot, first, second, margin, man, scratch)
        if n > 0:
            needed = emit(geom, contacts, man, n, first, second, geom.body[first],
                          geom.body[second], False, first * n_keys + second,
                          geom.material_class[first], geom.material_class[second], needed)
    for g in range(n_planes):
        for b in range(geom.n_bodies):
            if not geom.pair_collide[geom.material_class[b], geom.plane_class[g]]:
                continue
            if not box_reaches_plane(geom, lo, hi, b, g, margin):
                continue
            n = plane_collider(geom, wpos, wrot, b, g, margin, man)
            if n > 0:
                needed = emit(geom, contacts, man, n, b, c + g, b, -1, False, b * n_keys + c + g,
                              geom.material_class[b], geom.plane_class[g], needed)
    contacts.needed[0] = needed
    contacts.count[0] = min(needed, contacts.a.shape[0])
    return needed


# -- 2D -------------------------------------------------------------------------------------------
@njit(**INLINE)
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
    n_planes = geom.plane_offset.shape[0]
    margin = geom.margin
    wpos = np.empty((c, 2))
    wrot = np.empty((c, 2))
    lo = np.empty((c, 2))
    hi = np.empty((c, 2))
    world_poses2d(geom, x, angle, wpos, wrot)
    bounding_boxes2d(geom, wpos, wrot, 0.5 * margin, lo, hi)
    man = Manifold(np.zeros(2), np.zeros((MAX_CANDIDATES, 2)), np.zeros(MAX_CANDIDATES),
                   np.zeros(MAX_CANDIDATES, np.int64))
    pairs, n_pairs = brute_force_pairs(geom, lo, hi, np.empty((4 * c + 16, 2), np.int64))
    n_keys = c + n_planes
    needed = 0
    for p in range(n_pairs):
        first, second = row_order(geom, pairs[p, 0], pairs[p, 1])
        n = collide_pair2d(geom, wpos, wrot, first, second, margin, man)
        if n > 0:
            needed = emit(geom, contacts, man, n, first, second, geom.body[first],
                          geom.body[second], False, first * n_keys + second,
                          geom.material_class[first], geom.material_class[second], needed)
    for g in range(n_planes):
        for b in range(geom.n_bodies):
            if not geom.pair_collide[geom.material_class[b], geom.plane_class[g]]:
                continue
            if not box_reaches_plane(geom, lo, hi, b, g, margin):
                continue
            n = line_collider(geom, wpos, wrot, b, g, margin, man)
            if n > 0:
                needed = emit(geom, contacts, man, n, b, c + g, b, -1, False, b * n_keys + c + g,
                              geom.material_class[b], geom.plane_class[g], needed)
    contacts.needed[0] = needed
    contacts.count[0] = min(needed, contacts.a.shape[0])
    return needed
