"""Broad phase: the pairs of colliders whose world bounding boxes overlap, at least one of them a
body, their material classes allowed to collide; and the bodies whose box reaches a ground plane.

``brute_force_pairs`` tries every pair (the reference the tests compare with, and fine for a few
bodies). Every function writes pairs into an (P, 2) int64 array it grows by doubling and returns
it with the count; a pair is (lower collider index, higher).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from crosscheck.sim._jit import INLINE, JIT


@njit(**INLINE)
def may_touch(geom, i, j):
    """Both fixed never touch; a collide = false entry forbids the pair."""
    if geom.body[i] < 0 and geom.body[j] < 0:
        return False
    return geom.pair_collide[geom.material_class[i], geom.material_class[j]]


@njit(**INLINE)
def boxes_overlap(lo, hi, i, j):
    for r in range(lo.shape[1]):
        if lo[i, r] > hi[j, r] or lo[j, r] > hi[i, r]:
            return False
    return True


@njit(**INLINE)
def push_pair(pairs, n, i, j):
    """pairs[n] = (min, max), growing the array when full; returns (pairs, n + 1)."""
    if n == pairs.shape[0]:
        bigger = np.empty((2 * pairs.shape[0] + 16, 2), dtype=np.int64)
        bigger[:n] = pairs[:n]
        pairs = bigger
    pairs[n, 0] = min(i, j)
    pairs[n, 1] = max(i, j)
    return pairs, n + 1


@njit(**JIT)
def brute_force_pairs(geom, lo, hi, pairs):
    """Every overlapping pair by trying all C (C - 1) / 2; returns (pairs, count)."""
    n = 0
    c = geom.kind.shape[0]
    for i in range(c):
        for j in range(i + 1, c):
            if may_touch(geom, i, j) and boxes_overlap(lo, hi, i, j):
                pairs, n = push_pair(pairs, n, i, j)
    return pairs, n


@njit(**INLINE)
def box_reaches_plane(geom, lo, hi, c, g, margin):
    """The corner of c's box deepest along -n is within the margin of plane g."""
    d = 0.0
    for r in range(lo.shape[1]):
        nr = geom.plane_normal[g, r]
        d += nr * (lo[c, r] if nr > 0.0 else hi[c, r])
    return d - geom.plane_offset[g] <= margin
