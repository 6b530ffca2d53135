"""Cut-cell geometry of solid obstacles on the MAC grid, from the shapes' signed distances.

What the solver needs of a solid that does not follow the grid lines (docs/fluid.md, "Obstacles:
cut cells"):

* the **solid fraction of every face** (the part of the cell edge inside the solid): the
  variational pressure projection weights each face by its open fraction (Batty, Bertails and
  Bridson 2007; Ng, Min and Gibou 2009);
* the **signed distance at the velocity samples and cell centres**: where the segment between two
  samples crosses the wall (the ghost-fluid Dirichlet condition of the viscous step, Gibou et al.
  2002), path clipping, which cells are solid;
* the **fluid area of every cell** (measurements, the momentum in the force window).

Every 2D shape of :mod:`crosscheck.scene.shapes` (circle, box, convex polygon) is convex, and the
signed distance of a convex set is a convex function along any line. So the part of a segment
inside one shape is one interval, found by golden-section search for the minimum of the distance
along the segment and bisection for its two roots: exact to round-off (60 halvings) for any of
them, rotated or not, with no shape-specific formula. A union of obstacles is the union of the
intervals. Cell areas integrate chord lengths across the cell in y, split where the chord length
has kinks (``cell_solid_fractions``).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np

# golden-section and bisection iterations: 0.618^64 and 2^-56 of the segment, below round-off
GOLDEN_ITERATIONS = 64
BISECTION_ITERATIONS = 56
# Gauss-Legendre points across a cell for its area (chord lengths integrated in y)
AREA_POINTS = 16
# Fractions within this of 0 or 1 are snapped to it: a face that only touches a solid along its
# end (a box's side on a grid line) would otherwise be "open" by 1e-17 of its length, a fluid
# face with no flux and a meaningless velocity.
SNAP = 1e-9
_INV_PHI = (math.sqrt(5.0) - 1.0) / 2.0


def _along(shape: Any, p0: np.ndarray, d: np.ndarray, t: np.ndarray) -> np.ndarray:
    return shape.signed_distance(p0 + t[:, None] * d)


def convex_interval(shape: Any, p0: np.ndarray, p1: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The parameters ``[ta, tb]`` (in ``[0, 1]``) of the part of each segment ``p0 -> p1``
    (``(N, 2)``) strictly inside the convex ``shape`` (anything with ``signed_distance``);
    ``ta = tb = 0`` when a segment misses it (or only touches it)."""
    p0 = np.asarray(p0, float)
    d = np.asarray(p1, float) - p0
    n = p0.shape[0]
    ta = np.zeros(n)
    tb = np.zeros(n)
    if n == 0:
        return ta, tb
    # minimum of the convex function f(t) = sdf(p0 + t d) on [0, 1] by golden-section search
    lo = np.zeros(n)
    hi = np.ones(n)
    a = hi - _INV_PHI * (hi - lo)
    b = lo + _INV_PHI * (hi - lo)
    fa = _along(shape, p0, d, a)
    fb = _along(shape, p0, d, b)
    for _ in range(GOLDEN_ITERATIONS):
        left = fa < fb
        hi = np.where(left, b, hi)
        lo = np.where(left, lo, a)
        new_a = hi - _INV_PHI * (hi - lo)
        new_b = lo + _INV_PHI * (hi - lo)
        # one of the two interior points carries over; evaluating both keeps this vectorised
        a, b = new_a, new_b
        fa = _along(shape, p0, d, a)
        fb = _along(shape, p0, d, b)
    tmin = 0.5 * (lo + hi)
    fmin = _along(shape, p0, d, tmin)
    f0 = _along(shape, p0, d, np.zeros(n))
    f1 = _along(shape, p0, d, np.ones(n))
    # the end points can be lower than the interior search found (a minimum at an end)
    ends = np.minimum(f0, f1)
    tmin = np.where(ends < fmin, np.where(f0 <= f1, 0.0, 1.0), tmin)
    fmin = np.minimum(fmin, ends)
    hit = fmin < 0.0
    if not hit.any():
        return ta, tb
    idx = np.flatnonzero(hit)
    p0h, dh, tm = p0[idx], d[idx], tmin[idx]
    # entry: the root in [0, tmin] (0 if the segment starts inside)
    inside0 = f0[idx] < 0.0
    lo = np.zeros(idx.size)
    hi = tm.copy()
    for _ in range(BISECTION_ITERATIONS):
        mid = 0.5 * (lo + hi)
        out = _along(shape, p0h, dh, mid) >= 0.0
        lo = np.where(out, mid, lo)
        hi = np.where(out, hi, mid)
    ta[idx] = np.where(inside0, 0.0, 0.5 * (lo + hi))
    # exit: the root in [tmin, 1] (1 if the segment ends inside)
    inside1 = f1[idx] < 0.0
    lo = tm.copy()
    hi = np.ones(idx.size)
    for _ in range(BISECTION_ITERATIONS):
        mid = 0.5 * (lo + hi)
        out = _along(shape, p0h, dh, mid) >= 0.0
        hi = np.where(out, mid, hi)
        lo = np.where(out, lo, mid)
    tb[idx] = np.where(inside1, 1.0, 0.5 * (lo + hi))
    return ta, tb


def _union_length(intervals: list[tuple[np.ndarray, np.ndarray]]) -> np.ndarray:
    """Length (in segment parameter) of the union of per-segment intervals ``[a, b]``."""
    a = np.stack([iv[0] for iv in intervals], axis=1)
    b = np.stack([iv[1] for iv in intervals], axis=1)
    if a.shape[1] == 1:
        return b[:, 0] - a[:, 0]
    order = np.argsort(a, axis=1)
    a = np.take_along_axis(a, order, axis=1)
    b = np.take_along_axis(b, order, axis=1)
    total = np.zeros(a.shape[0])
    cur_a = a[:, 0].copy()
    cur_b = b[:, 0].copy()
    for k in range(1, a.shape[1]):
        empty = b[:, k] <= a[:, k]
        gap = (a[:, k] > cur_b) & ~empty
        total += np.where(gap, cur_b - cur_a, 0.0)
        cur_a = np.where(gap, a[:, k], cur_a)
        cur_b = np.where(gap, b[:, k], np.where(empty, cur_b, np.maximum(cur_b, b[:, k])))
    return total + (cur_b - cur_a)


def _near(shape: Any, lo: np.ndarray, hi: np.ndarray, margin: float) -> np.ndarray:
    """Segments whose bounding boxes (``lo``, ``hi``: (N, 2)) meet the shape's, grown by margin."""
    blo, bhi = shape.bounding_box()
    return np.all((hi >= blo - margin) & (lo <= bhi + margin), axis=1)


def solid_length(shapes: Sequence[Any], p0: np.ndarray, p1: np.ndarray) -> np.ndarray:
    """Fraction of each segment ``p0 -> p1`` inside the union of the convex ``shapes``."""
    p0 = np.asarray(p0, float).reshape(-1, 2)
    p1 = np.asarray(p1, float).reshape(-1, 2)
    n = p0.shape[0]
    if not shapes or n == 0:
        return np.zeros(n)
    lo = np.minimum(p0, p1)
    hi = np.maximum(p0, p1)
    intervals = []
    for shape in shapes:
        ta = np.zeros(n)
        tb = np.zeros(n)
        near = np.flatnonzero(_near(shape, lo, hi, 0.0))
        if near.size:
            ta[near], tb[near] = convex_interval(shape, p0[near], p1[near])
        intervals.append((ta, tb))
    return _snap(_union_length(intervals))


def _snap(f: np.ndarray) -> np.ndarray:
    f = np.clip(f, 0.0, 1.0)
    f[f < SNAP] = 0.0
    f[f > 1.0 - SNAP] = 1.0
    return f


def union_distance(shapes: Sequence[Any], points: np.ndarray) -> np.ndarray:
    """Signed distance of the union of ``shapes`` at ``points`` (..., 2): the minimum of theirs
    (exact outside, and of the right sign everywhere); ``+inf`` with no shapes."""
    points = np.asarray(points, float)
    out = np.full(points.shape[:-1], np.inf)
    for shape in shapes:
        out = np.minimum(out, shape.signed_distance(points))
    return out


def face_fractions(shapes: Sequence[Any], nx: int, ny: int,
                   dx: float) -> tuple[np.ndarray, np.ndarray]:
    """Solid fraction of the x-faces ``(nx+1, ny)`` (the vertical cell edges ``x = i dx``) and of
    the y-faces ``(nx, ny+1)`` (the horizontal edges ``y = j dx``)."""
    i, j = np.meshgrid(np.arange(nx + 1), np.arange(ny), indexing="ij")
    p0 = np.stack([i * dx, j * dx], axis=-1).reshape(-1, 2)
    p1 = np.stack([i * dx, (j + 1) * dx], axis=-1).reshape(-1, 2)
    u_frac = solid_length(shapes, p0, p1).reshape(nx + 1, ny)
    i, j = np.meshgrid(np.arange(nx), np.arange(ny + 1), indexing="ij")
    p0 = np.stack([i * dx, j * dx], axis=-1).reshape(-1, 2)
    p1 = np.stack([(i + 1) * dx, j * dx], axis=-1).reshape(-1, 2)
    v_frac = solid_length(shapes, p0, p1).reshape(nx, ny + 1)
    return u_frac, v_frac


def kink_heights(shape: Any) -> np.ndarray:
    """Heights (world y) where a horizontal chord's length across ``shape`` has a kink apart from
    the cell's own edges: a polygon's or box's corners, a circle's top and bottom."""
    inner = getattr(shape, "shape", shape)
    kind = getattr(inner, "kind", None)
    pos = np.asarray(getattr(shape, "position", (0.0, 0.0)), float)
    rot = shape.rotation() if hasattr(shape, "rotation") else None
    if kind == "circle":
        return np.array([pos[1] - inner.radius, pos[1] + inner.radius], float)
    if kind == "box":
        h = 0.5 * np.asarray(inner.size, float)
        local = np.array([[-h[0], -h[1]], [h[0], -h[1]], [h[0], h[1]], [-h[0], h[1]]])
    elif kind == "polygon":
        local = np.asarray(inner.vertices, float)
    else:
        lo, hi = shape.bounding_box()
        return np.array([lo[1], hi[1]], float)
    world = local if rot is None else local @ rot.T
    return world[:, 1] + pos[1]


def cell_solid_fractions(shapes: Sequence[Any], nx: int, ny: int, dx: float,
                         points: int = AREA_POINTS) -> np.ndarray:
    """Solid area fraction of every cell (nx, ny): the chord length of the solid along
    horizontal lines across the cell, integrated in y. The chord length is smooth between the
    heights where the wall crosses the cell's vertical edges and the shapes' corners (or a
    circle's top and bottom); the integral is split there and each piece integrated with
    ``points`` Gauss-Legendre points after the substitution ``y = a + (b - a)(3 s^2 - 2 s^3)``,
    which removes the square-root end of a circle's chord at its top and bottom. Exact to
    round-off for boxes and polygons, within about 1e-12 of a cell for circles."""
    frac = np.zeros((nx, ny))
    if not shapes:
        return frac
    ci, cj = np.meshgrid(np.arange(nx), np.arange(ny), indexing="ij")
    lo = np.stack([ci * dx, cj * dx], axis=-1).reshape(-1, 2)
    hi = lo + dx
    near = np.zeros(nx * ny, bool)
    for shape in shapes:
        near |= _near(shape, lo, hi, 0.0)
    cells = np.flatnonzero(near)
    if cells.size == 0:
        return frac
    # cells the wall does not enter are wholly solid or wholly open: decided by their centre
    centre = lo[cells] + 0.5 * dx
    dist = union_distance(shapes, centre)
    cut = np.abs(dist) < 0.75 * dx            # > half the diagonal: the cell is not cut
    frac.reshape(-1)[cells[~cut & (dist < 0.0)]] = 1.0
    cells = cells[cut]
    if cells.size == 0:
        return frac
    x0 = lo[cells, 0]
    y0 = lo[cells, 1]
    y1 = y0 + dx
    # break points: where each shape's wall crosses the cell's left and right edges, and the
    # shapes' corners within the cell's height
    breaks = [y0, y1]
    for shape in shapes:
        for xe in (x0, x0 + dx):
            p0 = np.stack([xe, y0], axis=-1)
            p1 = np.stack([xe, y1], axis=-1)
            ta, tb = convex_interval(shape, p0, p1)
            breaks += [y0 + ta * dx, y0 + tb * dx]
        for yk in kink_heights(shape):
            breaks.append(np.clip(np.full(cells.size, yk), y0, y1))
    b = np.sort(np.stack(breaks, axis=1), axis=1)            # (N, K)
    sg, wg = np.polynomial.legendre.leggauss(points)
    sg = 0.5 * (sg + 1.0)
    wg = 0.5 * wg
    # y = a + (b - a) (3 s^2 - 2 s^3), dy = (b - a) 6 s (1 - s) ds
    tmap = 3 * sg**2 - 2 * sg**3
    jac = 6 * sg * (1 - sg)
    a = b[:, :-1]
    width = b[:, 1:] - a                                      # (N, K-1)
    ys = a[:, :, None] + width[:, :, None] * tmap[None, None, :]
    wts = width[:, :, None] * (wg * jac)[None, None, :]
    n_pts = ys.shape[1] * ys.shape[2]
    xs0 = np.repeat(x0, n_pts)
    p0 = np.stack([xs0, ys.reshape(-1)], axis=-1)
    p1 = np.stack([xs0 + dx, ys.reshape(-1)], axis=-1)
    lengths = solid_length(shapes, p0, p1).reshape(ys.shape)
    acc = np.sum(lengths * wts, axis=(1, 2)) / dx
    frac.reshape(-1)[cells] = _snap(acc)
    return frac


def sample_points(nx: int, ny: int, dx: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """World positions of the u samples (nx+1, ny, 2), v samples (nx, ny+1, 2) and cell centres
    (nx, ny, 2) of the MAC grid."""
    i, j = np.meshgrid(np.arange(nx + 1), np.arange(ny), indexing="ij")
    pu = np.stack([i * dx, (j + 0.5) * dx], axis=-1)
    i, j = np.meshgrid(np.arange(nx), np.arange(ny + 1), indexing="ij")
    pv = np.stack([(i + 0.5) * dx, j * dx], axis=-1)
    i, j = np.meshgrid(np.arange(nx), np.arange(ny), indexing="ij")
    pc = np.stack([(i + 0.5) * dx, (j + 0.5) * dx], axis=-1)
    return pu, pv, pc


def shape_area(shape: Any) -> float:
    """Exact area of a placed 2D shape (circle, box, convex polygon)."""
    inner = getattr(shape, "shape", shape)
    kind = getattr(inner, "kind", None)
    if kind == "circle":
        return math.pi * float(inner.radius) ** 2
    if kind == "box":
        w, h = np.asarray(inner.size, float)
        return float(w * h)
    if kind == "polygon":
        v = np.asarray(inner.vertices, float)
        x, y = v[:, 0], v[:, 1]
        return float(0.5 * abs(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1))))
    raise ValueError(f"no area for a {kind!r}")
