"""One shape vocabulary: what rigid bodies are made of and what the fluid's obstacles and initial
regions are, with the geometric queries mass properties, fluid rasterisation and (later) collision
detection share.

Every shape is declared in its own *body frame* (a box centred on its origin, a capsule's and a
cylinder's axis along z, a mesh in its file's coordinates times its scale). The queries work in
that frame and are vectorised over leading axes:

* ``support(directions)``: ``(..., d) -> (..., d)``, a point of the shape farthest along each
  direction (the support mapping of GJK/EPA). Any maximiser is a correct answer; ties (a face or an
  edge facing the direction, a zero direction) are broken deterministically but arbitrarily.
* ``signed_distance(points)``: ``(..., d) -> (...)``, the Euclidean distance to the surface,
  negative inside. Exact (to round-off) for every shape; see :class:`Mesh` for how a mesh does it.
* ``contains(points)``: ``signed_distance(points) < 0``. Strict, so a point on the surface is
  outside: the fluid's rule that a cell is solid when its centre is *inside* an obstacle.
* ``bounding_box()``: ``(lo, hi)``, the tight axis-aligned box in the body frame.

:class:`Placed` puts a shape at a pose (position, and a quaternion (w, x, y, z) in 3D or an angle in
2D) and answers the same queries in world coordinates; :func:`world_bounding_box` is its tight
world AABB. The module needs NumPy only (and :mod:`crosscheck.rotations`); it imports nothing of
the scene, the simulators or the engines, so everything above can use it.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any, ClassVar

import numpy as np

__all__ = [
    "Box",
    "Capsule",
    "Circle",
    "Cylinder",
    "Mesh",
    "Placed",
    "Polygon",
    "Shape",
    "Sphere",
    "points_inside",
    "rotation_matrix",
    "world_bounding_box",
]


# -- helpers --------------------------------------------------------------------------------------
def _norm(v: np.ndarray) -> np.ndarray:
    """Euclidean norm over the last axis by chained ``hypot``: no overflow or underflow of the
    squares, and in 2D bit for bit the ``np.hypot(x, y)`` the fluid's shapes used before they
    moved here (so the fluid's initial level sets are unchanged)."""
    out = np.hypot(v[..., 0], v[..., 1])
    for k in range(2, v.shape[-1]):
        out = np.hypot(out, v[..., k])
    return out


def _unit(v: np.ndarray) -> np.ndarray:
    """``v / |v|`` over the last axis; a zero vector stays zero (its support is any point)."""
    n = _norm(v)[..., None]
    return np.divide(v, n, out=np.zeros_like(v), where=n > 0)


def _points(points: Any, dimension: int) -> np.ndarray:
    p = np.asarray(points, dtype=float)
    if p.shape[-1:] != (dimension,):
        raise ValueError(f"expected points of shape (..., {dimension}), got {p.shape}")
    return p


def _farthest_end(d: np.ndarray, half: np.ndarray | float) -> np.ndarray:
    # the vertex of [-half, half] farthest along d; a zero component picks +half (any maximises)
    return np.where(d >= 0.0, half, -half)


def _box_sdf(q: np.ndarray) -> np.ndarray:
    """Exact signed distance of a centred box from ``q = |p| - half`` (Quilez's form): the
    distance to the nearest face, edge or corner outside, minus the depth below the nearest face
    inside."""
    return _norm(np.maximum(q, 0.0)) + np.minimum(np.max(q, axis=-1), 0.0)


def _segment_distance(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Distance from points ``p`` to segments ``a``-``b`` (broadcast together, last axis the
    coordinates): project on the line, clamp to the segment."""
    e = b - a
    ap = p - a
    ee = np.sum(e * e, axis=-1)
    along = np.sum(ap * e, axis=-1)
    t = np.divide(along, ee, out=np.zeros_like(along), where=ee > 0)  # a point-segment: t = 0
    return _norm(ap - np.clip(t, 0.0, 1.0)[..., None] * e)


class _Solid:
    """What every shape (and a placed shape) shares: the inside test built on the distance."""

    def contains(self, points) -> np.ndarray:
        """Strictly inside: a point on the surface (distance 0) is not contained."""
        return self.signed_distance(points) < 0.0


# -- 3D shapes ------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Sphere(_Solid):
    radius: float
    kind: str = "sphere"
    dimension: ClassVar[int] = 3

    def support(self, directions) -> np.ndarray:
        return self.radius * _unit(_points(directions, 3))

    def signed_distance(self, points) -> np.ndarray:
        return _norm(_points(points, 3)) - self.radius

    def bounding_box(self) -> tuple[np.ndarray, np.ndarray]:
        r = np.full(3, float(self.radius))
        return -r, r


@dataclass(frozen=True)
class Box(_Solid):
    """Box centred on its origin with full side lengths ``size``: (3,) in 3D, (2,) in 2D (the 2D
    box is the same class; the queries hold in any dimension)."""

    # full side lengths, (3,) or (2,): an array for bodies, a tuple for fluid obstacles (which
    # keeps a FluidSpec comparable with ==, as it was)
    size: Any
    kind: str = "box"

    @property
    def dimension(self) -> int:
        return len(self.size)

    def _half(self) -> np.ndarray:
        # 0.5 * size is exact in binary, as in the fluid's former box
        return 0.5 * np.asarray(self.size, dtype=float)

    def support(self, directions) -> np.ndarray:
        d = _points(directions, self.dimension)
        return _farthest_end(d, self._half())

    def signed_distance(self, points) -> np.ndarray:
        p = _points(points, self.dimension)
        return _box_sdf(np.abs(p) - self._half())

    def bounding_box(self) -> tuple[np.ndarray, np.ndarray]:
        h = self._half()
        return -h, h


@dataclass(frozen=True)
class Capsule(_Solid):
    """The points within ``radius`` of the segment from ``(0, 0, -length/2)`` to
    ``(0, 0, length/2)``: a cylinder capped by two hemispheres, ``length + 2 radius`` long."""

    radius: float
    length: float  # length of the cylindrical part, along the body z axis
    kind: str = "capsule"
    dimension: ClassVar[int] = 3

    def support(self, directions) -> np.ndarray:
        # support of a Minkowski sum = sum of supports: the segment's end plus the sphere's point
        d = _points(directions, 3)
        s = self.radius * _unit(d)
        s[..., 2] += _farthest_end(d[..., 2], 0.5 * self.length)
        return s

    def signed_distance(self, points) -> np.ndarray:
        p = _points(points, 3)
        h = 0.5 * self.length
        q = p.copy()
        q[..., 2] = p[..., 2] - np.clip(p[..., 2], -h, h)  # from the nearest point of the segment
        return _norm(q) - self.radius

    def bounding_box(self) -> tuple[np.ndarray, np.ndarray]:
        r = float(self.radius)
        hi = np.array([r, r, r + 0.5 * self.length])
        return -hi, hi


@dataclass(frozen=True)
class Cylinder(_Solid):
    """Solid circular cylinder, axis along body z, centred: radius ``radius``, height ``length``."""

    radius: float
    length: float  # along the body z axis
    kind: str = "cylinder"
    dimension: ClassVar[int] = 3

    def support(self, directions) -> np.ndarray:
        # rim point: the radial part of the direction scaled to the radius, the end cap along z
        d = _points(directions, 3)
        s = np.empty_like(d)
        s[..., :2] = self.radius * _unit(d[..., :2])
        s[..., 2] = _farthest_end(d[..., 2], 0.5 * self.length)
        return s

    def signed_distance(self, points) -> np.ndarray:
        # a box in the (radial distance, |z|) half-plane: the same exact form as the 2D box
        p = _points(points, 3)
        q = np.stack([np.hypot(p[..., 0], p[..., 1]) - self.radius,
                      np.abs(p[..., 2]) - 0.5 * self.length], axis=-1)
        return _box_sdf(q)

    def bounding_box(self) -> tuple[np.ndarray, np.ndarray]:
        r = float(self.radius)
        hi = np.array([r, r, 0.5 * self.length])
        return -hi, hi


@dataclass(frozen=True)
class Mesh(_Solid):
    """A closed, outward-oriented triangle mesh (the loader refuses any other).

    ``signed_distance`` is exact for the mesh itself, not its convex hull: the committed meshes are
    concave (the L bracket's notch would count as solid in the hull) and the fluid and collisions
    need the real surface. The magnitude is the distance to the nearest triangle (every point
    against every triangle, O(points x triangles), in blocks: fine for the small meshes of the
    cases), the sign the ray-parity inside test :func:`points_inside`. trimesh's
    ``proximity.signed_distance`` would do the same but needs rtree, which crosscheck does not
    depend on (the same reason :func:`points_inside` exists). ``support`` is the farthest vertex:
    exactly the support of the mesh, which is that of its convex hull.
    """

    path: Path  # resolved, absolute
    vertices: np.ndarray  # (V, 3) in the body frame (the file's coordinates times scale)
    faces: np.ndarray  # (F, 3) int
    scale: float = 1.0
    kind: str = "mesh"
    dimension: ClassVar[int] = 3

    # points x triangles per block of the distance computation (a few tens of MB of temporaries)
    _BLOCK: ClassVar[int] = 1 << 18

    @property
    def triangles(self) -> np.ndarray:
        """(F, 3, 3): the corners of every face."""
        return np.asarray(self.vertices, dtype=float)[np.asarray(self.faces)]

    def support(self, directions) -> np.ndarray:
        d = _points(directions, 3)
        v = np.asarray(self.vertices, dtype=float)
        return v[np.argmax(d @ v.T, axis=-1)]

    def signed_distance(self, points) -> np.ndarray:
        p = _points(points, 3)
        flat = p.reshape(-1, 3)
        tri = self.triangles
        dist = np.empty(len(flat))
        step = max(1, self._BLOCK // len(tri))
        for start in range(0, len(flat), step):
            dist[start:start + step] = _triangle_distance(flat[start:start + step], tri).min(axis=1)
        signed = np.where(points_inside(tri, flat), -dist, dist)
        return signed.reshape(p.shape[:-1])

    def bounding_box(self) -> tuple[np.ndarray, np.ndarray]:
        v = np.asarray(self.vertices, dtype=float)
        return v.min(axis=0), v.max(axis=0)


def _triangle_distance(p: np.ndarray, tri: np.ndarray) -> np.ndarray:
    """(N, F) distances from points (N, 3) to triangles (F, 3, 3).

    The nearest point of a triangle is the foot of the perpendicular when that foot falls inside
    the triangle (the point is on the inner side of all three edge planes through the normal),
    else it lies on the boundary: the nearest of the three edges. A degenerate (zero-area)
    triangle has no inside and is its edges.
    """
    pts = p[:, None, :]
    a, b, c = tri[None, :, 0], tri[None, :, 1], tri[None, :, 2]
    n = np.cross(b - a, c - a)
    nn = _norm(n)
    over = np.ones(np.broadcast_shapes(pts.shape[:-1], nn.shape), dtype=bool)
    for u, v in ((a, b), (b, c), (c, a)):
        over &= np.sum(np.cross(v - u, pts - u) * n, axis=-1) >= 0.0
    over &= nn > 0
    plane = np.abs(np.sum((pts - a) * n, axis=-1)) / np.where(nn > 0, nn, 1.0)
    edges = np.minimum(np.minimum(_segment_distance(pts, a, b), _segment_distance(pts, b, c)),
                       _segment_distance(pts, c, a))
    return np.where(over, plane, edges)


def points_inside(triangles, points) -> np.ndarray:
    """Inside test for a closed triangle mesh by ray parity.

    A ray from each point towards +z crosses the surface an odd number of times exactly when
    the point is inside. Triangles are projected on the xy-plane; a point is counted in a
    projected triangle with edge functions and the top-left rule (computed from a canonical edge
    direction so that shared edges are decided identically on both sides, and a ray through an
    edge or vertex is counted once); the crossing must lie above the point. Points are sorted by
    x and, per triangle, only those within its x- and y-extent are tested, so the cost is
    ``O(N log N + sum over triangles of the points in its extent)``. Does not use trimesh's
    ``contains`` (which needs rtree or embree).
    """
    tri = np.asarray(triangles, dtype=float).reshape(-1, 3, 3)
    pts = np.asarray(points, dtype=float).reshape(-1, 3)
    order = np.argsort(pts[:, 0], kind="stable")
    px, py, pz = pts[order, 0], pts[order, 1], pts[order, 2]
    crossings = np.zeros(len(pts), dtype=np.int64)

    # project, drop triangles with no xy-area (vertical faces), orient counter-clockwise
    area2 = ((tri[:, 1, 0] - tri[:, 0, 0]) * (tri[:, 2, 1] - tri[:, 0, 1])
             - (tri[:, 2, 0] - tri[:, 0, 0]) * (tri[:, 1, 1] - tri[:, 0, 1]))
    keep = area2 != 0.0
    tri, area2 = tri[keep], area2[keep]
    cw = area2 < 0
    tri[cw] = tri[cw][:, ::-1]
    area2 = np.abs(area2)
    lo_x, hi_x = tri[:, :, 0].min(axis=1), tri[:, :, 0].max(axis=1)
    start = np.searchsorted(px, lo_x, side="left")
    stop = np.searchsorted(px, hi_x, side="right")

    for k in np.nonzero(stop > start)[0]:
        t = tri[k]
        sl = slice(start[k], stop[k])
        x, y = px[sl], py[sl]
        sel = (y >= t[:, 1].min()) & (y <= t[:, 1].max())
        if not sel.any():
            continue
        idx = np.nonzero(sel)[0] + start[k]
        x, y = px[idx], py[idx]
        inside = np.ones(len(idx), dtype=bool)
        w = []
        for i in range(3):
            u, v = t[i], t[(i + 1) % 3]
            # edge function of u->v, computed from the lexicographically smaller endpoint
            if (u[0], u[1]) <= (v[0], v[1]):
                e = (v[0] - u[0]) * (y - u[1]) - (v[1] - u[1]) * (x - u[0])
            else:
                e = -((u[0] - v[0]) * (y - v[1]) - (u[1] - v[1]) * (x - v[0]))
            dx, dy = v[0] - u[0], v[1] - u[1]
            top_left = dy < 0 or (dy == 0 and dx < 0)
            inside &= (e > 0) | ((e == 0) & top_left)
            w.append(e)
        if not inside.any():
            continue
        # barycentric weights: edge i (t_i -> t_{i+1}) weighs the opposite vertex t_{i+2}
        z_hit = (w[1] * t[0, 2] + w[2] * t[1, 2] + w[0] * t[2, 2]) / area2[k]
        hit = inside & (z_hit > pz[idx])
        crossings[idx[hit]] += 1

    result = np.empty(len(pts), dtype=bool)
    result[order] = (crossings % 2) == 1
    return result


# -- 2D shapes ------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Circle(_Solid):
    radius: float
    kind: str = "circle"
    dimension: ClassVar[int] = 2

    def support(self, directions) -> np.ndarray:
        return self.radius * _unit(_points(directions, 2))

    def signed_distance(self, points) -> np.ndarray:
        # hypot(x, y) - r: bit for bit the fluid's former circle
        return _norm(_points(points, 2)) - self.radius

    def bounding_box(self) -> tuple[np.ndarray, np.ndarray]:
        r = np.full(2, float(self.radius))
        return -r, r


def polygon_area2(vertices: np.ndarray) -> float:
    """Twice the signed area of the polygon ``vertices`` (K, 2) (shoelace): positive when they go
    counter-clockwise."""
    v = np.asarray(vertices, dtype=float)
    return float(np.sum(v[:, 0] * np.roll(v[:, 1], -1) - np.roll(v[:, 0], -1) * v[:, 1]))


@dataclass(frozen=True)
class Polygon(_Solid):
    """Convex polygon, vertices counter-clockwise (the loader refuses others and reorders
    clockwise input; built directly, clockwise or degenerate vertices raise ValueError)."""

    vertices: np.ndarray  # (K, 2), counter-clockwise, convex
    kind: str = "polygon"
    dimension: ClassVar[int] = 2

    def __post_init__(self) -> None:
        # clockwise vertices would turn the inside test (left of every edge) into "nowhere":
        # a body with no inside and no error. The loader reorders a case's clockwise input;
        # code that builds a Polygon itself is told here.
        v = np.asarray(self.vertices, dtype=float)
        if v.ndim != 2 or v.shape[0] < 3 or v.shape[1] != 2:
            raise ValueError(f"a Polygon needs at least 3 [x, y] vertices, got shape {v.shape}")
        area2 = polygon_area2(v)
        if not area2 > 0.0:
            raise ValueError("a Polygon's vertices go counter-clockwise (positive area); these "
                             f"enclose a signed area of {0.5 * area2:.6g}"
                             + (": reverse them" if area2 < 0.0 else ""))

    def support(self, directions) -> np.ndarray:
        d = _points(directions, 2)
        v = np.asarray(self.vertices, dtype=float)
        return v[np.argmax(d @ v.T, axis=-1)]

    def signed_distance(self, points) -> np.ndarray:
        # the boundary is the union of the edges: the nearest edge gives the distance, inside or
        # out; inside a convex counter-clockwise polygon a point is left of every edge
        p = _points(points, 2)[..., None, :]
        a = np.asarray(self.vertices, dtype=float)
        b = np.roll(a, -1, axis=0)
        dist = _segment_distance(p, a, b).min(axis=-1)
        e, ap = b - a, p - a
        inside = np.all(e[:, 0] * ap[..., 1] - e[:, 1] * ap[..., 0] > 0.0, axis=-1)
        return np.where(inside, -dist, dist)

    def bounding_box(self) -> tuple[np.ndarray, np.ndarray]:
        v = np.asarray(self.vertices, dtype=float)
        return v.min(axis=0), v.max(axis=0)


Shape = Sphere | Box | Capsule | Cylinder | Mesh | Circle | Polygon


# -- placed shapes --------------------------------------------------------------------------------
def rotation_matrix(orientation: Any, dimension: int) -> np.ndarray:
    """Body-to-world rotation: a quaternion (w, x, y, z) in 3D; an angle (a number or
    ``array([angle])``, counter-clockwise, rad) in 2D. The conventions of ``Body.orientation``."""
    from crosscheck.rotations import angle_to_matrix, quat_to_matrix

    o = np.asarray(orientation, dtype=float).reshape(-1)
    if dimension == 2 and o.shape == (1,):
        return angle_to_matrix(o[0])
    if dimension == 3 and o.shape == (4,):
        return quat_to_matrix(o)
    raise ValueError(f"a {dimension}D orientation is "
                     f"{'an angle' if dimension == 2 else 'a quaternion (w, x, y, z)'}, "
                     f"got {orientation!r}")


@dataclass(frozen=True)
class Placed(_Solid):
    """A shape at a pose; every query takes and returns world coordinates.

    ``orientation`` None means the body axes are the world axes: a pure translation, so a fluid
    obstacle's distances are ``shape.signed_distance(points - position)`` with no rotation
    round-off (bit for bit what the fluid computed before its shapes moved here).
    """

    shape: Shape
    position: Any  # world position of the body-frame origin, (d,)
    orientation: Any = None  # None, a quaternion (w, x, y, z) in 3D or an angle in 2D

    @property
    def dimension(self) -> int:
        return self.shape.dimension

    def rotation(self) -> np.ndarray | None:
        if self.orientation is None:
            return None
        return rotation_matrix(self.orientation, self.dimension)

    def to_body(self, points) -> np.ndarray:
        """World points into the body frame: ``R^T (p - position)``, as row vectors."""
        local = _points(points, self.dimension) - np.asarray(self.position, dtype=float)
        r = self.rotation()
        return local if r is None else local @ r

    def signed_distance(self, points) -> np.ndarray:
        return self.shape.signed_distance(self.to_body(points))

    def support(self, directions) -> np.ndarray:
        d = _points(directions, self.dimension)
        r = self.rotation()
        if r is None:
            return np.asarray(self.position, dtype=float) + self.shape.support(d)
        return np.asarray(self.position, dtype=float) + self.shape.support(d @ r) @ r.T

    def bounding_box(self) -> tuple[np.ndarray, np.ndarray]:
        return world_bounding_box(self.shape, self.position, self.orientation)


def world_bounding_box(shape: Shape, position, orientation=None) -> tuple[np.ndarray, np.ndarray]:
    """Tight axis-aligned box of ``shape`` placed at ``position`` with ``orientation`` (see
    :class:`Placed`), in world coordinates.

    Each face comes from the support point along a world axis (``R^T e_i`` in the body frame), so
    the box is the rotated shape's own, not the bounding box of the rotated body-frame box.
    """
    x = np.asarray(position, dtype=float)
    if orientation is None:
        lo, hi = shape.bounding_box()
        return x + lo, x + hi
    r = rotation_matrix(orientation, shape.dimension)
    # row i of r is R^T e_i; world coordinate i of R s is r[i] . s
    hi = np.sum(r * shape.support(r), axis=-1)
    lo = np.sum(r * shape.support(-r), axis=-1)
    return x + lo, x + hi
