"""The narrow phase's scratch manifold: what one pair of colliders touches with, before it becomes
rows of the contact buffer.

Every narrow-phase routine for a pair (A, B) writes one normal (unit, world, from A to B) and up
to ``MAX_CANDIDATES`` points, each with its depth (positive overlap, negative gap within the
margin) and a local feature id (< 2**32; which features of A and B touch), and returns the count.
:func:`reduce_to_four` keeps the four points that span the largest area (the deepest first), as
every solver wants a small, well spread manifold.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit

from crosscheck.sim._jit import INLINE, JIT

MAX_POINTS = 4  # per manifold, in the contact buffer
MAX_CANDIDATES = 64  # clipping can yield more before the reduction


class Manifold(NamedTuple):
    normal: np.ndarray  # (d,)
    point: np.ndarray  # (MAX_CANDIDATES, d)
    depth: np.ndarray  # (MAX_CANDIDATES,)
    feature: np.ndarray  # (MAX_CANDIDATES,) int64


def new_manifold(dimension: int, candidates: int = MAX_CANDIDATES) -> Manifold:
    return Manifold(np.zeros(dimension), np.zeros((candidates, dimension)),
                    np.zeros(candidates), np.zeros(candidates, np.int64))


@njit(**INLINE)
def put_point(man, k, px, py, pz, depth, feature):
    man.point[k, 0] = px
    man.point[k, 1] = py
    man.point[k, 2] = pz
    man.depth[k] = depth
    man.feature[k] = feature


@njit(**INLINE)
def set_normal(man, nx, ny, nz):
    man.normal[0] = nx
    man.normal[1] = ny
    man.normal[2] = nz


@njit(**INLINE)
def _swap(man, i, j):
    if i == j:
        return
    for r in range(man.point.shape[1]):
        t = man.point[i, r]
        man.point[i, r] = man.point[j, r]
        man.point[j, r] = t
    t = man.depth[i]
    man.depth[i] = man.depth[j]
    man.depth[j] = t
    f = man.feature[i]
    man.feature[i] = man.feature[j]
    man.feature[j] = f


@njit(**INLINE)
def _area_about_normal(man, i, j, k):
    """((p_j - p_i) x (p_k - p_i)) . n: twice the signed area of the triangle seen along n."""
    ax = man.point[j, 0] - man.point[i, 0]
    ay = man.point[j, 1] - man.point[i, 1]
    az = man.point[j, 2] - man.point[i, 2]
    bx = man.point[k, 0] - man.point[i, 0]
    by = man.point[k, 1] - man.point[i, 1]
    bz = man.point[k, 2] - man.point[i, 2]
    return ((ay * bz - az * by) * man.normal[0] + (az * bx - ax * bz) * man.normal[1]
            + (ax * by - ay * bx) * man.normal[2])


@njit(**JIT)
def reduce_to_four(man, count):
    """Keep at most four points in slots 0..3 and return how many: the deepest, the farthest from
    it, the one making the largest triangle with both, and the one adding the most area outside
    that triangle (3D manifolds). Ties go to the lower index, so the choice is deterministic."""
    if count <= MAX_POINTS:
        return count
    best = 0
    for k in range(1, count):
        if man.depth[k] > man.depth[best]:
            best = k
    _swap(man, 0, best)
    best = 1
    far = -1.0
    for k in range(1, count):
        d2 = 0.0
        for r in range(3):
            d = man.point[k, r] - man.point[0, r]
            d2 += d * d
        if d2 > far:
            far = d2
            best = k
    _swap(man, 1, best)
    best = 2
    area = -1.0
    for k in range(2, count):
        a = abs(_area_about_normal(man, 0, 1, k))
        if a > area:
            area = a
            best = k
    _swap(man, 2, best)
    # orient the triangle counter-clockwise about the normal, then take the point farthest
    # outside one of its edges
    if _area_about_normal(man, 0, 1, 2) < 0.0:
        _swap(man, 1, 2)
    best = 3
    area = -np.inf
    for k in range(3, count):
        a = max(-_area_about_normal(man, 0, 1, k), -_area_about_normal(man, 1, 2, k),
                -_area_about_normal(man, 2, 0, k))
        if a > area:
            area = a
            best = k
    _swap(man, 3, best)
    return MAX_POINTS
