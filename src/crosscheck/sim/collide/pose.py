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
    for c in range(geom.kind.shape[0]):
        b = geom.body[c]
        if b < 0:
            for r in range(3):
                wpos[c, r] = geom.frame_pos[c, r]
                for k in range(3):
                    wrot[c, r, k] = geom.frame_rot[c, r, k]
            continue
        quat_rotation_into(q[b, 0], q[b, 1], q[b, 2], q[b, 3], wrot, c)
        for r in range(3):
            wpos[c, r] = (x[b, r] + wrot[c, r, 0] * geom.frame_pos[c, 0]
                          + wrot[c, r, 1] * geom.frame_pos[c, 1]
                          + wrot[c, r, 2] * geom.frame_pos[c, 2])


@njit(**JIT)
def bounding_boxes3d(geom, wpos, wrot, inflate, lo, hi):
    """lo[c], hi[c]: collider c's world AABB grown by ``inflate``."""
    for c in range(geom.kind.shape[0]):
        kind = geom.kind[c]
        for r in range(3):
            # half extent of the shape along world axis r, about its frame origin
            lo_r = 0.0
            hi_r = 0.0
            if kind == SPHERE:
                lo_r = -geom.size[c, 0]
                hi_r = geom.size[c, 0]
            elif kind == BOX:
                e = (abs(wrot[c, r, 0]) * geom.size[c, 0] + abs(wrot[c, r, 1]) * geom.size[c, 1]
                     + abs(wrot[c, r, 2]) * geom.size[c, 2])
                lo_r = -e
                hi_r = e
            elif kind == CAPSULE:
                e = abs(wrot[c, r, 2]) * geom.size[c, 1] + geom.size[c, 0]
                lo_r = -e
                hi_r = e
            elif kind == CYLINDER:
                a = wrot[c, r, 2]  # world axis r's component of the cylinder axis
                e = abs(a) * geom.size[c, 1] + geom.size[c, 0] * np.sqrt(max(0.0, 1.0 - a * a))
                lo_r = -e
                hi_r = e
            elif kind == HULL:
                p = geom.polytope[c]
                v0 = geom.poly_vert_start[p]
                lo_r = np.inf
                hi_r = -np.inf
                for v in range(v0, v0 + geom.poly_vert_count[p]):
                    s = (wrot[c, r, 0] * geom.vertices[v, 0] + wrot[c, r, 1] * geom.vertices[v, 1]
                         + wrot[c, r, 2] * geom.vertices[v, 2])
                    lo_r = min(lo_r, s)
                    hi_r = max(hi_r, s)
            lo[c, r] = wpos[c, r] + lo_r - inflate
            hi[c, r] = wpos[c, r] + hi_r + inflate


@njit(**JIT)
def world_poses2d(geom, x, angle, wpos, wrot):
    """wpos[c] (2,), wrot[c] = (cos, sin) of collider c's world angle."""
    for c in range(geom.kind.shape[0]):
        b = geom.body[c]
        if b < 0:
            wpos[c, 0] = geom.frame_pos[c, 0]
            wpos[c, 1] = geom.frame_pos[c, 1]
            wrot[c, 0] = np.cos(geom.frame_angle[c])
            wrot[c, 1] = np.sin(geom.frame_angle[c])
            continue
        co = np.cos(angle[b])
        si = np.sin(angle[b])
        wrot[c, 0] = co
        wrot[c, 1] = si
        wpos[c, 0] = x[b, 0] + co * geom.frame_pos[c, 0] - si * geom.frame_pos[c, 1]
        wpos[c, 1] = x[b, 1] + si * geom.frame_pos[c, 0] + co * geom.frame_pos[c, 1]


@njit(**JIT)
def bounding_boxes2d(geom, wpos, wrot, inflate, lo, hi):
    for c in range(geom.kind.shape[0]):
        if geom.kind[c] == CIRCLE:
            r = geom.radius[c]
            for k in range(2):
                lo[c, k] = wpos[c, k] - r - inflate
                hi[c, k] = wpos[c, k] + r + inflate
            continue
        p = geom.polygon[c]
        co = wrot[c, 0]
        si = wrot[c, 1]
        lx = np.inf
        ly = np.inf
        hx = -np.inf
        hy = -np.inf
        for v in range(geom.poly_vert_start[p], geom.poly_vert_start[p] + geom.poly_vert_count[p]):
            px = co * geom.vertices[v, 0] - si * geom.vertices[v, 1]
            py = si * geom.vertices[v, 0] + co * geom.vertices[v, 1]
            lx = min(lx, px)
            hx = max(hx, px)
            ly = min(ly, py)
            hy = max(hy, py)
        lo[c, 0] = wpos[c, 0] + lx - inflate
        lo[c, 1] = wpos[c, 1] + ly - inflate
        hi[c, 0] = wpos[c, 0] + hx + inflate
        hi[c, 1] = wpos[c, 1] + hy + inflate
