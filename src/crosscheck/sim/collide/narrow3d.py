"""Narrow phase in 3D, closed forms: the ground plane against every shape (support points), and
the pairs with an exact closest-point formula (sphere/sphere, sphere/box, sphere/capsule,
sphere/cylinder, capsule/capsule).

Every routine writes a :class:`~crosscheck.sim.collide.manifold.Manifold` for the pair (A, B):
the normal from A to B, per point the midpoint between the two surfaces along the normal, the
depth (positive overlap; negative gap, reported down to ``-margin``) and a local feature id, and
returns the number of points. Nothing is reported for a pair farther apart than the margin.

Poses come as world arrays ``wpos (C, 3)``, ``wrot (C, 3, 3)`` indexed by collider (pose.py).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from crosscheck.sim._jit import INLINE, JIT
from crosscheck.sim.collide.geometry import CAPSULE, CYLINDER, SPHERE
from crosscheck.sim.collide.manifold import MAX_CANDIDATES, put_point, reduce_to_four, set_normal

# Two capsule axes are parallel (a line contact) when the sine of their angle is below this.
SIN_PARALLEL = 0.02


# -- small vector helpers -------------------------------------------------------------------------
@njit(**INLINE)
def unit_or(x, y, z, fx, fy, fz):
    """(x, y, z) / |(x, y, z)| and the length, or the fallback direction when it has none."""
    n = np.sqrt(x * x + y * y + z * z)
    if n > 0.0:
        return x / n, y / n, z / n, n
    return fx, fy, fz, 0.0


@njit(**INLINE)
def to_world(wpos, wrot, c, px, py, pz):
    """A point of collider c's shape frame in world coordinates."""
    return (wpos[c, 0] + wrot[c, 0, 0] * px + wrot[c, 0, 1] * py + wrot[c, 0, 2] * pz,
            wpos[c, 1] + wrot[c, 1, 0] * px + wrot[c, 1, 1] * py + wrot[c, 1, 2] * pz,
            wpos[c, 2] + wrot[c, 2, 0] * px + wrot[c, 2, 1] * py + wrot[c, 2, 2] * pz)


@njit(**INLINE)
def to_local(wpos, wrot, c, px, py, pz):
    """A world point in collider c's shape frame: R^T (p - pos)."""
    dx = px - wpos[c, 0]
    dy = py - wpos[c, 1]
    dz = pz - wpos[c, 2]
    return (wrot[c, 0, 0] * dx + wrot[c, 1, 0] * dy + wrot[c, 2, 0] * dz,
            wrot[c, 0, 1] * dx + wrot[c, 1, 1] * dy + wrot[c, 2, 1] * dz,
            wrot[c, 0, 2] * dx + wrot[c, 1, 2] * dy + wrot[c, 2, 2] * dz)


@njit(**INLINE)
def rotate(wrot, c, vx, vy, vz):
    """A direction of collider c's shape frame in world axes."""
    return (wrot[c, 0, 0] * vx + wrot[c, 0, 1] * vy + wrot[c, 0, 2] * vz,
            wrot[c, 1, 0] * vx + wrot[c, 1, 1] * vy + wrot[c, 1, 2] * vz,
            wrot[c, 2, 0] * vx + wrot[c, 2, 1] * vy + wrot[c, 2, 2] * vz)


@njit(**INLINE)
def segment_of(wpos, wrot, c, half):
    """World end points of a capsule's or cylinder's axis segment (shape z from -half to half)."""
    ax, ay, az = wrot[c, 0, 2] * half, wrot[c, 1, 2] * half, wrot[c, 2, 2] * half
    return (wpos[c, 0] - ax, wpos[c, 1] - ay, wpos[c, 2] - az,
            wpos[c, 0] + ax, wpos[c, 1] + ay, wpos[c, 2] + az)


@njit(**INLINE)
def closest_on_segment(px, py, pz, ax, ay, az, bx, by, bz):
    """The point of segment a-b nearest to p, and its parameter in [0, 1]."""
    ex, ey, ez = bx - ax, by - ay, bz - az
    ee = ex * ex + ey * ey + ez * ez
    t = 0.0
    if ee > 0.0:
        t = ((px - ax) * ex + (py - ay) * ey + (pz - az) * ez) / ee
        t = min(1.0, max(0.0, t))
    return ax + t * ex, ay + t * ey, az + t * ez, t


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


# -- the two-sphere core: every "point with a radius" pair ends here ----------------------------
@njit(**INLINE)
def spheres(ax, ay, az, ra, bx, by, bz, rb, margin, man, k, feature, fx, fy, fz):
    """Point k of the manifold for spheres (a, ra) and (b, rb): the normal from a to b (the
    fallback (fx, fy, fz) when the centres coincide). Returns k + 1, or k when farther apart
    than the margin."""
    nx, ny, nz, dist = unit_or(bx - ax, by - ay, bz - az, fx, fy, fz)
    gap = dist - ra - rb
    if gap > margin:
        return k
    set_normal(man, nx, ny, nz)
    # midway between a's surface point a + ra n and b's b - rb n
    h = 0.5 * (ra - rb)
    put_point(man, k, 0.5 * (ax + bx) + h * nx, 0.5 * (ay + by) + h * ny,
              0.5 * (az + bz) + h * nz, -gap, feature)
    return k + 1


@njit(**INLINE)
def sphere_sphere(wpos, ca, ra, cb, rb, margin, man):
    return spheres(wpos[ca, 0], wpos[ca, 1], wpos[ca, 2], ra, wpos[cb, 0], wpos[cb, 1],
                   wpos[cb, 2], rb, margin, man, 0, 0, 0.0, 0.0, 1.0)


@njit(**INLINE)
def sphere_capsule(wpos, wrot, ca, ra, cb, rb, half_b, margin, man):
    """Sphere A against capsule B: the sphere against the nearest point of B's segment."""
    x0, y0, z0, x1, y1, z1 = segment_of(wpos, wrot, cb, half_b)
    qx, qy, qz, _ = closest_on_segment(wpos[ca, 0], wpos[ca, 1], wpos[ca, 2],
                                       x0, y0, z0, x1, y1, z1)
    # fallback (centre on the axis): B's x axis, any direction normal to the segment
    return spheres(wpos[ca, 0], wpos[ca, 1], wpos[ca, 2], ra, qx, qy, qz, rb, margin, man, 0, 0,
                   -wrot[cb, 0, 0], -wrot[cb, 1, 0], -wrot[cb, 2, 0])


@njit(**INLINE)
def _sphere_against_surface(cx, cy, cz, r, sx, sy, sz, ox, oy, oz, gap_c, margin, man):
    """Sphere (c, r) A against a solid B whose surface point nearest the centre is s, with the
    outward normal o of B there and the signed distance gap_c of the centre from B's surface.
    Returns the count (0 or 1)."""
    gap = gap_c - r
    if gap > margin:
        return 0
    set_normal(man, -ox, -oy, -oz)
    # the sphere's point c - r o and B's point s: midway
    put_point(man, 0, 0.5 * (cx - r * ox + sx), 0.5 * (cy - r * oy + sy), 0.5 * (cz - r * oz + sz),
              -gap, 0)
    return 1


@njit(**INLINE)
def sphere_box(wpos, wrot, ca, r, cb, hx, hy, hz, margin, man):
    """Sphere A against box B: clamp the centre into the box (outside), or push it out through
    the nearest face (inside)."""
    px, py, pz = to_local(wpos, wrot, cb, wpos[ca, 0], wpos[ca, 1], wpos[ca, 2])
    qx, qy, qz = min(hx, max(-hx, px)), min(hy, max(-hy, py)), min(hz, max(-hz, pz))
    dx, dy, dz = px - qx, py - qy, pz - qz
    d2 = dx * dx + dy * dy + dz * dz
    if d2 > 0.0:
        d = np.sqrt(d2)
        if d - r > margin:
            return 0
        ox, oy, oz = rotate(wrot, cb, dx / d, dy / d, dz / d)
        gap_c = d
    else:
        # inside: the face with the least depth below it
        ex, ey, ez = hx - abs(px), hy - abs(py), hz - abs(pz)
        lx, ly, lz = 0.0, 0.0, 0.0
        if ex <= ey and ex <= ez:
            lx = 1.0 if px >= 0.0 else -1.0
            qx = lx * hx
            gap_c = -ex
        elif ey <= ez:
            ly = 1.0 if py >= 0.0 else -1.0
            qy = ly * hy
            gap_c = -ey
        else:
            lz = 1.0 if pz >= 0.0 else -1.0
            qz = lz * hz
            gap_c = -ez
        ox, oy, oz = rotate(wrot, cb, lx, ly, lz)
    sx, sy, sz = to_world(wpos, wrot, cb, qx, qy, qz)
    return _sphere_against_surface(wpos[ca, 0], wpos[ca, 1], wpos[ca, 2], r, sx, sy, sz,
                                   ox, oy, oz, gap_c, margin, man)


@njit(**INLINE)
def sphere_cylinder(wpos, wrot, ca, r, cb, rc, hc, margin, man):
    """Sphere A against cylinder B: the exact closest point of the solid cylinder, in the
    (radial, axial) half-plane where the cylinder is a rectangle."""
    px, py, pz = to_local(wpos, wrot, cb, wpos[ca, 0], wpos[ca, 1], wpos[ca, 2])
    rho = np.sqrt(px * px + py * py)
    # radial unit direction (the cylinder's x axis when the centre is on the axis)
    ux, uy = 1.0, 0.0
    if rho > 0.0:
        ux, uy = px / rho, py / rho
    er, ez = rho - rc, abs(pz) - hc
    sz_sign = 1.0 if pz >= 0.0 else -1.0
    if er > 0.0 or ez > 0.0:
        # outside: clamp (rho, z) into the rectangle
        qr, qz = min(rho, rc), min(hc, max(-hc, pz))
        dr, dz = rho - qr, pz - qz
        d = np.sqrt(dr * dr + dz * dz)
        if d - r > margin:
            return 0
        lx, ly, lz = ux * dr / d, uy * dr / d, dz / d
        qx, qy = ux * qr, uy * qr
        gap_c = d
    elif er >= ez:
        # inside, nearer the curved side
        lx, ly, lz = ux, uy, 0.0
        qx, qy, qz = ux * rc, uy * rc, pz
        gap_c = er
    else:
        # inside, nearer a cap
        lx, ly, lz = 0.0, 0.0, sz_sign
        qx, qy, qz = px, py, sz_sign * hc
        gap_c = ez
    ox, oy, oz = rotate(wrot, cb, lx, ly, lz)
    sx, sy, sz = to_world(wpos, wrot, cb, qx, qy, qz)
    return _sphere_against_surface(wpos[ca, 0], wpos[ca, 1], wpos[ca, 2], r, sx, sy, sz,
                                   ox, oy, oz, gap_c, margin, man)


@njit(**INLINE)
def capsule_capsule(wpos, wrot, ca, ra, ha, cb, rb, hb, margin, man):
    """Capsules A and B: the closest points of their axis segments (one point); when the axes
    are parallel (within SIN_PARALLEL) and overlap along their length, the two ends of the overlap
    instead, so a capsule lying along another gets a line contact."""
    a0x, a0y, a0z, a1x, a1y, a1z = segment_of(wpos, wrot, ca, ha)
    b0x, b0y, b0z, b1x, b1y, b1z = segment_of(wpos, wrot, cb, hb)
    px, py, pz, qx, qy, qz = segment_segment(a0x, a0y, a0z, a1x, a1y, a1z,
                                             b0x, b0y, b0z, b1x, b1y, b1z)
    # fallback normal (axes crossing): A's x axis
    k = spheres(px, py, pz, ra, qx, qy, qz, rb, margin, man, 0, 0,
                wrot[ca, 0, 0], wrot[ca, 1, 0], wrot[ca, 2, 0])
    if k == 0:
        return 0
    ax, ay, az = wrot[ca, 0, 2], wrot[ca, 1, 2], wrot[ca, 2, 2]
    bx, by, bz = wrot[cb, 0, 2], wrot[cb, 1, 2], wrot[cb, 2, 2]
    cx, cy, cz = ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx
    if cx * cx + cy * cy + cz * cz > SIN_PARALLEL * SIN_PARALLEL or ha <= 0.0 or hb <= 0.0:
        return k
    # B's ends projected on A's axis (parameter in [-ha, ha]), clamped to both segments
    ta0 = (b0x - wpos[ca, 0]) * ax + (b0y - wpos[ca, 1]) * ay + (b0z - wpos[ca, 2]) * az
    ta1 = (b1x - wpos[ca, 0]) * ax + (b1y - wpos[ca, 1]) * ay + (b1z - wpos[ca, 2]) * az
    lo = max(-ha, min(ta0, ta1))
    hi = min(ha, max(ta0, ta1))
    if hi - lo <= 1e-9 * (ha + hb):
        return k
    nx, ny, nz = man.normal[0], man.normal[1], man.normal[2]
    for e in range(2):
        t = lo if e == 0 else hi
        sx, sy, sz = wpos[ca, 0] + t * ax, wpos[ca, 1] + t * ay, wpos[ca, 2] + t * az
        ux, uy, uz, _ = closest_on_segment(sx, sy, sz, b0x, b0y, b0z, b1x, b1y, b1z)
        # the gap between the two surfaces along the manifold's normal
        gap = nx * (ux - sx) + ny * (uy - sy) + nz * (uz - sz) - ra - rb
        h = 0.5 * (ra - rb)
        put_point(man, e, 0.5 * (sx + ux) + h * nx, 0.5 * (sy + uy) + h * ny,
                  0.5 * (sz + uz) + h * nz, -gap, 1 + e)
    return 2 if man.depth[0] >= -margin and man.depth[1] >= -margin else _deeper_only(man)


@njit(**INLINE)
def _deeper_only(man):
    """Of a two-point manifold with one point beyond the margin, keep the other."""
    if man.depth[0] < man.depth[1]:
        for r in range(3):
            man.point[0, r] = man.point[1, r]
        man.depth[0] = man.depth[1]
        man.feature[0] = man.feature[1]
    return 1


# -- the ground plane -----------------------------------------------------------------------------
@njit(**INLINE)
def plane_point(man, k, nx, ny, nz, offset, px, py, pz, margin, feature):
    """Point k for a body's support point p against the plane n . p = offset (the body is A, the
    plane B, so the normal from A to B is -n). Returns k + 1, or k beyond the margin."""
    gap = nx * px + ny * py + nz * pz - offset
    if gap > margin:
        return k
    put_point(man, k, px - 0.5 * gap * nx, py - 0.5 * gap * ny, pz - 0.5 * gap * nz, -gap,
              feature)
    return k + 1


@njit(**INLINE)
def plane_sphere(plane_normal, plane_offset, wpos, size, c, g, margin, man):
    """Sphere collider c against plane g: its lowest point (the plane collider's sphere case, for
    the detection loop, with arrays only)."""
    nx, ny, nz = plane_normal[g, 0], plane_normal[g, 1], plane_normal[g, 2]
    r = size[c, 0]
    set_normal(man, -nx, -ny, -nz)
    return plane_point(man, 0, nx, ny, nz, plane_offset[g], wpos[c, 0] - r * nx,
                       wpos[c, 1] - r * ny, wpos[c, 2] - r * nz, margin, 0)


@njit(**INLINE)
def plane_box(plane_normal, plane_offset, wpos, wrot, size, c, g, margin, man):
    """Box collider c against plane g: its corners within the margin, the four spanning the
    largest area kept (plane_collider's box case, for the detection loop, with arrays only;
    corner k has the signs of the bits of k, as the box's polytope numbers them)."""
    nx, ny, nz = plane_normal[g, 0], plane_normal[g, 1], plane_normal[g, 2]
    offset = plane_offset[g]
    set_normal(man, -nx, -ny, -nz)
    k = np.int64(0)  # not a literal 0 (sim/_jit.py: "Literal arguments")
    for v in range(8):
        sx = size[c, 0] if v & 4 else -size[c, 0]
        sy = size[c, 1] if v & 2 else -size[c, 1]
        sz = size[c, 2] if v & 1 else -size[c, 2]
        px, py, pz = to_world(wpos, wrot, c, sx, sy, sz)
        k = plane_point(man, k, nx, ny, nz, offset, px, py, pz, margin, v)
    return reduce_to_four(man, k)


@njit(**JIT)
def plane_collider(geom, wpos, wrot, c, g, margin, man):
    """Collider c (a body) against ground plane g: its support points nearest the plane, each a
    contact point (sphere 1; capsule the two end spheres; cylinder the rim; box and hull their
    vertices, the four spanning the largest area kept)."""
    nx, ny, nz = geom.plane_normal[g, 0], geom.plane_normal[g, 1], geom.plane_normal[g, 2]
    offset = geom.plane_offset[g]
    set_normal(man, -nx, -ny, -nz)
    kind = geom.kind[c]
    k = np.int64(0)  # not a literal 0 (sim/_jit.py: "Literal arguments")
    if kind == SPHERE:
        r = geom.size[c, 0]
        k = plane_point(man, k, nx, ny, nz, offset, wpos[c, 0] - r * nx, wpos[c, 1] - r * ny,
                        wpos[c, 2] - r * nz, margin, 0)
    elif kind == CAPSULE:  # the lowest point of each end sphere
        r, half = geom.size[c, 0], geom.size[c, 1]
        x0, y0, z0, x1, y1, z1 = segment_of(wpos, wrot, c, half)
        k = plane_point(man, k, nx, ny, nz, offset, x0 - r * nx, y0 - r * ny, z0 - r * nz,
                        margin, 0)
        k = plane_point(man, k, nx, ny, nz, offset, x1 - r * nx, y1 - r * ny, z1 - r * nz,
                        margin, 1)
    elif kind == CYLINDER:
        k = _plane_cylinder(geom, wpos, wrot, c, nx, ny, nz, offset, margin, man)
    else:  # box, hull: every vertex within the margin
        p = geom.polytope[c]
        v0 = geom.poly_vert_start[p]
        vertices = geom.vertices
        for v in range(geom.poly_vert_count[p]):
            px, py, pz = to_world(wpos, wrot, c, vertices[v0 + v, 0], vertices[v0 + v, 1],
                                  vertices[v0 + v, 2])
            if k < MAX_CANDIDATES:
                k = plane_point(man, k, nx, ny, nz, offset, px, py, pz, margin, v)
            else:
                k = _replace_shallowest(man, k, nx, ny, nz, offset, px, py, pz, margin, v)
    return reduce_to_four(man, k)


@njit(**INLINE)
def _replace_shallowest(man, k, nx, ny, nz, offset, px, py, pz, margin, feature):
    """A full candidate list: a deeper vertex replaces the shallowest candidate."""
    gap = nx * px + ny * py + nz * pz - offset
    worst = 0
    for i in range(1, k):
        if man.depth[i] < man.depth[worst]:
            worst = i
    if -gap > man.depth[worst]:
        plane_point(man, worst, nx, ny, nz, offset, px, py, pz, margin, feature)
    return k


@njit(**INLINE)
def _plane_cylinder(geom, wpos, wrot, c, nx, ny, nz, offset, margin, man):
    """Rim points of a cylinder: on the cap nearer the plane, the lowest rim point and the rim
    points at 90, 180 and 270 degrees from it (a cap lying flat gives four points on its rim); on
    the other cap its lowest rim point (a cylinder lying on its side gives two, on its line of
    contact). All are exact points of the cylinder's surface."""
    r, half = geom.size[c, 0], geom.size[c, 1]
    ax, ay, az = wrot[c, 0, 2], wrot[c, 1, 2], wrot[c, 2, 2]
    # the downward direction in the cap plane: -(n minus its axial part)
    na = nx * ax + ny * ay + nz * az
    ux, uy, uz, length = unit_or(-(nx - na * ax), -(ny - na * ay), -(nz - na * az),
                                 wrot[c, 0, 0], wrot[c, 1, 0], wrot[c, 2, 0])
    if length < 1e-9:  # upright: any rim direction is lowest; the body's x axis, for stability
        ux, uy, uz = wrot[c, 0, 0], wrot[c, 1, 0], wrot[c, 2, 0]
    # v = a x u: the rim direction 90 degrees on
    vx, vy, vz = ay * uz - az * uy, az * ux - ax * uz, ax * uy - ay * ux
    # the lower cap is the one along -n: centre c - sign(n . a) half a
    s = 1.0 if na > 0.0 else -1.0
    lx, ly, lz = wpos[c, 0] - s * half * ax, wpos[c, 1] - s * half * ay, wpos[c, 2] - s * half * az
    hx, hy, hz = wpos[c, 0] + s * half * ax, wpos[c, 1] + s * half * ay, wpos[c, 2] + s * half * az
    k = np.int64(0)  # not a literal 0 (sim/_jit.py: "Literal arguments")
    k = plane_point(man, k, nx, ny, nz, offset, lx + r * ux, ly + r * uy, lz + r * uz, margin, 0)
    k = plane_point(man, k, nx, ny, nz, offset, lx + r * vx, ly + r * vy, lz + r * vz, margin, 1)
    k = plane_point(man, k, nx, ny, nz, offset, lx - r * ux, ly - r * uy, lz - r * uz, margin, 2)
    k = plane_point(man, k, nx, ny, nz, offset, lx - r * vx, ly - r * vy, lz - r * vz, margin, 3)
    k = plane_point(man, k, nx, ny, nz, offset, hx + r * ux, hy + r * uy, hz + r * uz, margin, 4)
    return k
