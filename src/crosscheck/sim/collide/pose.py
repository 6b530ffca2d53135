"""World poses and world axis-aligned bounding boxes of the colliders, from the bodies' state.

A body's state holds its centre of mass ``x`` and the orientation of its declared body frame
(``q`` in 3D, ``angle`` in 2D); the collider's shape frame is the body frame, whose origin is
``x + R frame_pos`` (``frame_pos = -com``). A static's pose is fixed (``frame_pos``,
``frame_rot`` / ``frame_angle`` in world). The bounding boxes are tight for every shape (the
shape's support along the world axes) and grown by ``inflate`` on every side.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from crosscheck.sim._jit import INLINE, JIT
from crosscheck.sim.collide.geometry import BOX, CAPSULE, CIRCLE, CYLINDER, HULL, SPHERE


@njit(**INLINE)
def quat_rotation_into(w, x, y, z, R, i):
    """R[i] = R(q / |q|): the state's quaternion may be slightly off unit length (RK stages)."""
    s = 2.0 / (w * w + x * x + y * y + z * z)
    R[i, 0, 0] = 1.0 - s * (y * y + z * z)
    R[i, 0, 1] = s * (x * y - w * z)
    R[i, 0, 2] = s * (x * z + w * y)
    R[i, 1, 0] = s * (x * y + w * z)
    R[i, 1, 1] = 1.0 - s * (x * x + z * z)
    R[i, 1, 2] = s * (y * z - w * x)
    R[i, 2, 0] = s * (x * z - w * y)
    R[i, 2, 1] = s * (y * z + w * x)
    R[i, 2, 2] = 1.0 - s * (x * x + y * y)


@njit(**JIT)
def world_poses3d(geom, x, q, wpos, wrot):
    """wpos[c], wrot[c]: the world position of collider c's shape frame and its rotation."""
    # arrays through local names: a NamedTuple field read in a loop costs a reference count
    body, frame_pos, frame_rot = geom.body, geom.frame_pos, geom.frame_rot
    for c in range(body.shape[0]):
        b = body[c]
        if b < 0:
            for r in range(3):
                wpos[c, r] = frame_pos[c, r]
                for k in range(3):
                    wrot[c, r, k] = frame_rot[c, r, k]
            continue
        quat_rotation_into(q[b, 0], q[b, 1], q[b, 2], q[b, 3], wrot, c)
        for r in range(3):
            wpos[c, r] = (x[b, r] + wrot[c, r, 0] * frame_pos[c, 0]
                          + wrot[c, r, 1] * frame_pos[c, 1] + wrot[c, r, 2] * frame_pos[c, 2])


@njit(**JIT)
def bounding_boxes3d(geom, wpos, wrot, inflate, lo, hi):
    """lo[c], hi[c]: collider c's world AABB grown by ``inflate``."""
    kinds, size, polytope = geom.kind, geom.size, geom.polytope
    vert_start, vert_count, vertices = geom.poly_vert_start, geom.poly_vert_count, geom.vertices
    for c in range(kinds.shape[0]):
        kind = kinds[c]
        for r in range(3):
            # half extent of the shape along world axis r, about its frame origin
            lo_r = 0.0
            hi_r = 0.0
            if kind == SPHERE:
                lo_r = -size[c, 0]
                hi_r = size[c, 0]
            elif kind == BOX:
                e = (abs(wrot[c, r, 0]) * size[c, 0] + abs(wrot[c, r, 1]) * size[c, 1]
                     + abs(wrot[c, r, 2]) * size[c, 2])
                lo_r = -e
                hi_r = e
            elif kind == CAPSULE:
                e = abs(wrot[c, r, 2]) * size[c, 1] + size[c, 0]
                lo_r = -e
                hi_r = e
            elif kind == CYLINDER:
                a = wrot[c, r, 2]  # world axis r's component of the cylinder axis
                e = abs(a) * size[c, 1] + size[c, 0] * np.sqrt(max(0.0, 1.0 - a * a))
                lo_r = -e
                hi_r = e
            elif kind == HULL:
                p = polytope[c]
                v0 = vert_start[p]
                lo_r = np.inf
                hi_r = -np.inf
                for v in range(v0, v0 + vert_count[p]):
                    s = (wrot[c, r, 0] * vertices[v, 0] + wrot[c, r, 1] * vertices[v, 1]
                         + wrot[c, r, 2] * vertices[v, 2])
                    lo_r = min(lo_r, s)
                    hi_r = max(hi_r, s)
            lo[c, r] = wpos[c, r] + lo_r - inflate
            hi[c, r] = wpos[c, r] + hi_r + inflate


@njit(**JIT)
def world_poses2d(geom, x, angle, wpos, wrot):
    """wpos[c] (2,), wrot[c] = (cos, sin) of collider c's world angle."""
    body, frame_pos, frame_angle = geom.body, geom.frame_pos, geom.frame_angle
    for c in range(body.shape[0]):
        b = body[c]
        if b < 0:
            wpos[c, 0] = frame_pos[c, 0]
            wpos[c, 1] = frame_pos[c, 1]
            wrot[c, 0] = np.cos(frame_angle[c])
            wrot[c, 1] = np.sin(frame_angle[c])
            continue
        co = np.cos(angle[b])
        si = np.sin(angle[b])
        wrot[c, 0] = co
        wrot[c, 1] = si
        wpos[c, 0] = x[b, 0] + co * frame_pos[c, 0] - si * frame_pos[c, 1]
        wpos[c, 1] = x[b, 1] + si * frame_pos[c, 0] + co * frame_pos[c, 1]


@njit(**JIT)
def bounding_boxes2d(geom, wpos, wrot, inflate, lo, hi):
    kind, radius, polygon = geom.kind, geom.radius, geom.polygon
    vert_start, vert_count, vertices = geom.poly_vert_start, geom.poly_vert_count, geom.vertices
    for c in range(kind.shape[0]):
        if kind[c] == CIRCLE:
            r = radius[c]
            for k in range(2):
                lo[c, k] = wpos[c, k] - r - inflate
                hi[c, k] = wpos[c, k] + r + inflate
            continue
        p = polygon[c]
        co = wrot[c, 0]
        si = wrot[c, 1]
        lx = np.inf
        ly = np.inf
        hx = -np.inf
        hy = -np.inf
        for v in range(vert_start[p], vert_start[p] + vert_count[p]):
            px = co * vertices[v, 0] - si * vertices[v, 1]
            py = si * vertices[v, 0] + co * vertices[v, 1]
            lx = min(lx, px)
            hx = max(hx, px)
            ly = min(ly, py)
            hy = max(hy, py)
        lo[c, 0] = wpos[c, 0] + lx - inflate
        lo[c, 1] = wpos[c, 1] + ly - inflate
        hi[c, 0] = wpos[c, 0] + hx + inflate
        hi[c, 1] = wpos[c, 1] + hy + inflate
