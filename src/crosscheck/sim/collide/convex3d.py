"""The pairs without a closed form or a polytope routine (sphere/hull, capsule/box, capsule/hull,
capsule/cylinder, cylinder/box, cylinder/cylinder, cylinder/hull): GJK on the cores for the
distance, EPA when the cores overlap (gjk.py), then a manifold from the two *supporting features*
along the normal.

The supporting feature of a shape along a direction is what of it faces that way: a box's or
hull's face (when its normal is within ``FEATURE_ANGLE`` of the direction), a cylinder's cap (its
rim, sampled at ``CAP_POINTS`` exact rim points) or the line of its side, a capsule's side line;
otherwise the single support point. When both features have extent, one (the *reference*: A's,
unless only B's is a polygon) bounds the other (the *incident*), which is clipped to it; each
clipped point within the margin of the reference becomes a contact point. Otherwise the manifold
is GJK's or EPA's single point. Normal and single-point depth are exact for polytope cores and
to EPA's tolerance for cylinders; the extra manifold points are exact surface points of the
incident feature, their depths measured from the reference feature's plane.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from crosscheck.sim._jit import INLINE, JIT
from crosscheck.sim.collide.clip3d import clip_polygon
from crosscheck.sim.collide.geometry import CAPSULE, CYLINDER, SPHERE
from crosscheck.sim.collide.gjk import core_radius, epa, gjk, witnesses
from crosscheck.sim.collide.manifold import MAX_CANDIDATES, put_point, reduce_to_four, set_normal

# A face (cap, side line) supports a direction when its normal is within this angle of it.
FEATURE_ANGLE = 0.02  # rad, about 1.1 degrees
COS_FEATURE = float(np.cos(FEATURE_ANGLE))
SIN_FEATURE = float(np.sin(FEATURE_ANGLE))
CAP_POINTS = 8  # rim points standing for a cylinder's cap in a manifold (all on the rim)
# GJK's exact point joins the clipped points when it is deeper than all of them by this (m)
EXACT_POINT_MARGIN = 1e-9


@njit(**INLINE)
def _polytope_face_feature(geom, wpos, wrot, c, nx, ny, nz, out):
    """The face of polytope c best aligned with n, if within FEATURE_ANGLE: its world corners
    (counter-clockwise about its normal) and the normal; else count 0."""
    p = geom.polytope[c]
    f0 = geom.poly_face_start[p]
    best = -np.inf
    bf = 0
    for f in range(geom.poly_face_count[p]):
        lx, ly, lz = geom.face_normal[f0 + f, 0], geom.face_normal[f0 + f, 1], \
            geom.face_normal[f0 + f, 2]
        mx = wrot[c, 0, 0] * lx + wrot[c, 0, 1] * ly + wrot[c, 0, 2] * lz
        my = wrot[c, 1, 0] * lx + wrot[c, 1, 1] * ly + wrot[c, 1, 2] * lz
        mz = wrot[c, 2, 0] * lx + wrot[c, 2, 1] * ly + wrot[c, 2, 2] * lz
        d = mx * nx + my * ny + mz * nz
        if d > best:
            best = d
            bf = f
    if best < COS_FEATURE:
        return 0, 0.0, 0.0, 0.0
    g = f0 + bf
    lx, ly, lz = geom.face_normal[g, 0], geom.face_normal[g, 1], geom.face_normal[g, 2]
    mx = wrot[c, 0, 0] * lx + wrot[c, 0, 1] * ly + wrot[c, 0, 2] * lz
    my = wrot[c, 1, 0] * lx + wrot[c, 1, 1] * ly + wrot[c, 1, 2] * lz
    mz = wrot[c, 2, 0] * lx + wrot[c, 2, 1] * ly + wrot[c, 2, 2] * lz
    s0 = geom.face_vert_start[g]
    v0 = geom.poly_vert_start[p]
    m = geom.face_vert_count[g]
    for k in range(m):
        v = v0 + geom.face_verts[s0 + k]
        x, y, z = geom.vertices[v, 0], geom.vertices[v, 1], geom.vertices[v, 2]
        for r in range(3):
            out[k, r] = wpos[c, r] + wrot[c, r, 0] * x + wrot[c, r, 1] * y + wrot[c, r, 2] * z
    return m, mx, my, mz


@njit(**JIT)
def supporting_feature(geom, wpos, wrot, c, nx, ny, nz, out):
    """What of collider c faces the world direction n: (count, feature normal) with the points in
    ``out`` (a polygon counter-clockwise about the feature normal, or a segment); count 0 when
    only a single point faces n (the caller then keeps GJK's point)."""
    k = geom.kind[c]
    if k == SPHERE:
        return 0, 0.0, 0.0, 0.0
    if k == CAPSULE or k == CYLINDER:
        ax, ay, az = wrot[c, 0, 2], wrot[c, 1, 2], wrot[c, 2, 2]
        r, h = geom.size[c, 0], geom.size[c, 1]
        along = ax * nx + ay * ny + az * nz
        if abs(along) < SIN_FEATURE:
            # the side line facing n: the axis pushed out by r along n's part normal to the axis
            ux, uy, uz = nx - along * ax, ny - along * ay, nz - along * az
            lu = np.sqrt(ux * ux + uy * uy + uz * uz)
            ux, uy, uz = ux / lu, uy / lu, uz / lu
            for e in range(2):
                sgn = -1.0 if e == 0 else 1.0
                out[e, 0] = wpos[c, 0] + sgn * h * ax + r * ux
                out[e, 1] = wpos[c, 1] + sgn * h * ay + r * uy
                out[e, 2] = wpos[c, 2] + sgn * h * az + r * uz
            return 2, nx, ny, nz
        if k == CYLINDER and abs(along) > COS_FEATURE:
            # the cap facing n: rim points, counter-clockwise about the cap's outward normal
            sgn = 1.0 if along > 0.0 else -1.0
            for j in range(CAP_POINTS):
                theta = 2.0 * np.pi * j / CAP_POINTS
                lx, ly = r * np.cos(theta), sgn * r * np.sin(theta)
                for q in range(3):
                    out[j, q] = (wpos[c, q] + wrot[c, q, 0] * lx + wrot[c, q, 1] * ly
                                 + wrot[c, q, 2] * sgn * h)
            return CAP_POINTS, sgn * ax, sgn * ay, sgn * az
        return 0, 0.0, 0.0, 0.0
    return _polytope_face_feature(geom, wpos, wrot, c, nx, ny, nz, out)


@njit(**INLINE)
def _copy_points(src, dst, n):
    for k in range(n):
        for r in range(3):
            dst[k, r] = src[k, r]


@njit(**INLINE)
def _segment_overlap(ref, inc, out, ids):
    """Two nearly parallel segments: the part of ``inc`` over ``ref`` (its two ends), in out;
    returns 2, or 0 when they do not overlap."""
    ex, ey, ez = ref[1, 0] - ref[0, 0], ref[1, 1] - ref[0, 1], ref[1, 2] - ref[0, 2]
    ee = ex * ex + ey * ey + ez * ez
    fx, fy, fz = inc[1, 0] - inc[0, 0], inc[1, 1] - inc[0, 1], inc[1, 2] - inc[0, 2]
    ff = fx * fx + fy * fy + fz * fz
    if ee <= 0.0 or ff <= 0.0:
        return 0
    # parallel? |e x f| small against |e| |f|
    cx, cy, cz = ey * fz - ez * fy, ez * fx - ex * fz, ex * fy - ey * fx
    if cx * cx + cy * cy + cz * cz > (SIN_FEATURE * SIN_FEATURE) * ee * ff:
        return 0
    # inc's parameter range over ref: where its points project within [0, 1] along e
    t0 = ((inc[0, 0] - ref[0, 0]) * ex + (inc[0, 1] - ref[0, 1]) * ey
          + (inc[0, 2] - ref[0, 2]) * ez) / ee
    t1 = ((inc[1, 0] - ref[0, 0]) * ex + (inc[1, 1] - ref[0, 1]) * ey
          + (inc[1, 2] - ref[0, 2]) * ez) / ee
    if t0 == t1:
        return 0
    # u: parameter along inc where the projection crosses ref's ends
    ua = (0.0 - t0) / (t1 - t0)
    ub = (1.0 - t0) / (t1 - t0)
    lo, hi = max(0.0, min(ua, ub)), min(1.0, max(ua, ub))
    if lo > hi:
        return 0
    for e in range(2):
        u = lo if e == 0 else hi
        for r in range(3):
            out[e, r] = inc[0, r] + u * (inc[1, r] - inc[0, r])
        ids[e] = e if (u == 0.0 or u == 1.0) else 0x80 | e
    return 2


@njit(**INLINE)
def _feature_manifold(geom, wpos, wrot, ca, cb, nx, ny, nz, margin, man, scratch):
    """Manifold from the supporting features of A along n and of B along -n; 0 when either is a
    single point or the clipping leaves nothing (the caller keeps the single point)."""
    n_a, ma_x, ma_y, ma_z = supporting_feature(geom, wpos, wrot, ca, nx, ny, nz, scratch.ref)
    if n_a == 0:
        return 0
    n_b, mb_x, mb_y, mb_z = supporting_feature(geom, wpos, wrot, cb, -nx, -ny, -nz,
                                               scratch.clip_in)
    if n_b == 0:
        return 0
    flipped = n_a == 2 and n_b > 2  # only B's feature is a polygon: it is the reference
    if flipped:
        # swap the roles: B's polygon into ref, A's segment into clip_in
        _copy_points(scratch.clip_in, scratch.clip_out, n_b)
        _copy_points(scratch.ref, scratch.clip_in, n_a)
        _copy_points(scratch.clip_out, scratch.ref, n_b)
        n_ref, n_inc = n_b, n_a
        mx, my, mz = mb_x, mb_y, mb_z
    else:
        n_ref, n_inc = n_a, n_b
        mx, my, mz = ma_x, ma_y, ma_z
    for k in range(n_inc):
        scratch.id_in[k] = k
    if n_ref == 2:
        count = _segment_overlap(scratch.ref, scratch.clip_in, scratch.clip_out, scratch.id_out)
        _copy_points(scratch.clip_out, scratch.clip_in, count)
        for k in range(count):
            scratch.id_in[k] = scratch.id_out[k]
    else:
        count = clip_polygon(scratch.ref, n_ref, mx, my, mz, scratch.clip_in, scratch.id_in,
                             n_inc, scratch.clip_out, scratch.id_out)
    if count == 0:
        return 0
    # each incident point's gap to the reference feature's plane (normal m), measured along the
    # contact normal n: the two surface points of a row are then the incident point and its
    # shadow on the reference plane, both exact
    off = mx * scratch.ref[0, 0] + my * scratch.ref[0, 1] + mz * scratch.ref[0, 2]
    mn = mx * nx + my * ny + mz * nz  # |mn| > cos(FEATURE_ANGLE)
    set_normal(man, nx, ny, nz)
    head = (1 << 24) if flipped else 0
    k_out = 0
    for k in range(count):
        px, py, pz = scratch.clip_in[k, 0], scratch.clip_in[k, 1], scratch.clip_in[k, 2]
        gap = (mx * px + my * py + mz * pz - off) / abs(mn)
        if gap > margin or k_out >= MAX_CANDIDATES - 1:
            continue
        # half the gap towards the reference, along n (+n from B's points, -n from A's)
        h = 0.5 * gap if flipped else -0.5 * gap
        put_point(man, k_out, px + h * nx, py + h * ny, pz + h * nz, -gap,
                  head | (scratch.id_in[k] & 0xFF))
        k_out += 1
    return k_out


@njit(**JIT)
def convex_convex(geom, wpos, wrot, ca, cb, margin, man, gs, lam, scratch):
    """Manifold of any two convex colliders by GJK / EPA on their cores and feature clipping."""
    ra = core_radius(geom, ca)
    rb = core_radius(geom, cb)
    scale = geom.bound_radius[ca] + geom.bound_radius[cb]
    dist, n = gjk(geom, wpos, wrot, ca, cb, gs, lam)
    if n == 4 or dist <= 1e-12 * scale:
        core_depth, nx, ny, nz, ax, ay, az, bx, by, bz = epa(geom, wpos, wrot, ca, cb, gs, n,
                                                              scale)
        if core_depth < 0.0:
            # the cores touch but their difference is flat: the witness of the touch, the
            # normal along the line between the frames
            ax, ay, az, bx, by, bz = witnesses(gs, lam, min(n, 3))
            dx, dy, dz = (wpos[cb, 0] - wpos[ca, 0], wpos[cb, 1] - wpos[ca, 1],
                          wpos[cb, 2] - wpos[ca, 2])
            ln = np.sqrt(dx * dx + dy * dy + dz * dz)
            nx, ny, nz = (dx / ln, dy / ln, dz / ln) if ln > 0.0 else (0.0, 0.0, 1.0)
            core_depth = 0.0
        gap = -core_depth - ra - rb
    else:
        ax, ay, az, bx, by, bz = witnesses(gs, lam, n)
        nx, ny, nz = bx - ax, by - ay, bz - az
        ln = np.sqrt(nx * nx + ny * ny + nz * nz)
        nx, ny, nz = nx / ln, ny / ln, nz / ln
        gap = dist - ra - rb
    if gap > margin:
        return 0
    # witnesses back in world coordinates
    ax, ay, az = ax + wpos[ca, 0], ay + wpos[ca, 1], az + wpos[ca, 2]
    bx, by, bz = bx + wpos[ca, 0], by + wpos[ca, 1], bz + wpos[ca, 2]
    count = _feature_manifold(geom, wpos, wrot, ca, cb, nx, ny, nz, margin, man, scratch)
    # GJK's / EPA's own point, exact: the manifold's deepest unless a clipped point is as deep
    # (a cap's rim points are samples of the rim; the deepest rim point may lie between them)
    deepest = -np.inf
    for k in range(count):
        deepest = max(deepest, man.depth[k])
    if count == 0 or -gap > deepest + EXACT_POINT_MARGIN:
        set_normal(man, nx, ny, nz)
        # surface points a + ra n and b - rb n: midway
        h = 0.5 * (ra - rb)
        put_point(man, count, 0.5 * (ax + bx) + h * nx, 0.5 * (ay + by) + h * ny,
                  0.5 * (az + bz) + h * nz, -gap, 0xFF)
        count += 1
    return reduce_to_four(man, count)
