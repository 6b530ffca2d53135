"""Signed gap of two convex 3D shapes with no closed form in contact_metrics (capsule-box,
cylinder against anything, a mesh against another body or a static, ...), from FCL.

crosscheck measures penetration with geometry code of its own or of a library made for it, never
an engine's contact report, and never the in-house engine's collision code (which it would then
be judging with itself). FCL (the Flexible Collision Library, python-fcl) computes the signed
distance of convex primitives with GJK (apart) and EPA (overlapping).

Shapes are mapped exactly: box (full sizes), sphere, capsule (radius and the length of the
cylindrical part along body z, as scene/shapes.py and FCL both define it), cylinder (radius and
full height along z), and a mesh by its convex hull. Every engine collides a mesh as its hull
(MuJoCo and PyBullet; the in-house engine says the same), so the hull is what was simulated; for
a concave mesh the gap is the hull's, not the surface's.

Accuracy, measured against the closed forms on random poses of 0.1-0.5 m shapes
(tests/compare/test_convex_gap.py): overlapping shapes to 1e-6 m (EPA on curved surfaces; 1e-13
for boxes). Separated shapes are where GJK's stopping rule costs most (up to 5e-4 m for a
capsule within 1 mm of a box, more at larger distances): a capsule is a segment swelled by its
radius, so against a shape with an exact signed distance its separation is refined exactly,
``min_t sdf_B(segment(t)) - radius`` (the signed distance of a convex B is convex along the
segment: a golden-section search to round-off). What remains on GJK alone (cylinder-box,
cylinder-cylinder, meshes) measured to 1e-6 m within 1 mm of contact, 6e-5 m within 1 cm, 6e-4
m beyond; the contact tolerance of the metrics is 1e-3 times the body size.
"""

from __future__ import annotations

import functools

import numpy as np


def available() -> bool:
    try:
        import fcl  # noqa: F401
    except ImportError:  # pragma: no cover - a dependency of crosscheck
        return False
    return True


@functools.lru_cache(maxsize=64)
def _hull(vertices_key: bytes, n: int):
    from scipy.spatial import ConvexHull

    v = np.frombuffer(vertices_key, dtype=float).reshape(n, 3)
    hull = ConvexHull(v)
    return v[hull.vertices], hull


def fcl_geometry(shape):
    """The FCL collision geometry of a crosscheck 3D shape (in its own frame)."""
    import fcl

    kind = shape.kind
    if kind == "box":
        return fcl.Box(*(float(x) for x in np.asarray(shape.size, float)))
    if kind == "sphere":
        return fcl.Sphere(float(shape.radius))
    if kind == "capsule":
        return fcl.Capsule(float(shape.radius), float(shape.length))
    if kind == "cylinder":
        return fcl.Cylinder(float(shape.radius), float(shape.length))
    if kind == "mesh":
        v = np.ascontiguousarray(np.asarray(shape.vertices, float))
        _, hull = _hull(v.tobytes(), len(v))
        # FCL's Convex takes the vertices and its faces as a flat list (count, indices...),
        # outward: ConvexHull's simplices, oriented by their outward equations.
        faces = []
        for simplex, eq in zip(hull.simplices, hull.equations, strict=True):
            a, b, c = v[simplex]
            if np.dot(np.cross(b - a, c - a), eq[:3]) < 0:
                simplex = simplex[[0, 2, 1]]
            faces.extend([3, *map(int, simplex)])
        return fcl.Convex(v, len(hull.simplices), np.array(faces, dtype=np.int64))
    raise NotImplementedError(f"no FCL geometry for a {kind!r}")


def gap(shape_a, rot_a: np.ndarray, origin_a: np.ndarray, shape_b, rot_b: np.ndarray,
        origin_b: np.ndarray) -> np.ndarray:
    """(M,) signed gaps (``-depth`` when overlapping) of two convex 3D shapes at M pose pairs:
    rotations (M, 3, 3), origins (M, 3) of the shapes' frames in the world."""
    import fcl

    geo_a, geo_b = fcl_geometry(shape_a), fcl_geometry(shape_b)
    rot_a = np.asarray(rot_a, float)
    rot_b = np.asarray(rot_b, float)
    # Relative to a's origin: a pair far from the world origin keeps its digits (measured: GJK
    # lost 5e-5 m at 1 km before this shift).
    origin_b = np.asarray(origin_b, float) - origin_a
    origin_a = np.zeros_like(origin_b)
    out = np.empty(len(origin_a))
    obj_a = fcl.CollisionObject(geo_a, fcl.Transform())
    obj_b = fcl.CollisionObject(geo_b, fcl.Transform())
    request = fcl.DistanceRequest(enable_signed_distance=True)
    for m in range(len(out)):
        obj_a.setTransform(fcl.Transform(rot_a[m], origin_a[m]))
        obj_b.setTransform(fcl.Transform(rot_b[m], origin_b[m]))
        out[m] = fcl.distance(obj_a, obj_b, request, fcl.DistanceResult())
    if shape_b.kind == "capsule" and shape_a.kind in EXACT_SDF:
        shape_a, rot_a, origin_a, shape_b, rot_b, origin_b = (
            shape_b, rot_b, origin_b, shape_a, rot_a, origin_a)
    if shape_a.kind == "capsule" and shape_b.kind in EXACT_SDF:
        apart = out > 0
        if apart.any():
            out[apart] = _capsule_separation(shape_a, rot_a[apart], origin_a[apart], shape_b,
                                             rot_b[apart], origin_b[apart])
    return out


EXACT_SDF = ("box", "capsule", "cylinder", "sphere")  # convex, exact signed_distance
_GOLDEN = 0.5 * (np.sqrt(5.0) - 1.0)


def _capsule_separation(capsule, rot_a, origin_a, shape_b, rot_b, origin_b) -> np.ndarray:
    """Exact separation of a capsule from a convex shape with an exact signed distance, where
    they are apart: ``min_t sdf_B(p(t)) - r`` over the capsule's segment p(t), t in [-h, h]."""
    h = 0.5 * float(capsule.length)
    axis = rot_a[:, :, 2]  # the capsule's body z in the world

    def sdf(t):
        p = origin_a + t[:, None] * axis
        return shape_b.signed_distance(np.einsum("mji,mj->mi", rot_b, p - origin_b))

    lo = np.full(len(origin_a), -h)
    hi = np.full(len(origin_a), h)
    for _ in range(80):  # the bracket shrinks by 0.618 per step: 80 steps reach round-off
        x1 = hi - _GOLDEN * (hi - lo)
        x2 = lo + _GOLDEN * (hi - lo)
        left = sdf(x1) <= sdf(x2)
        hi = np.where(left, x2, hi)
        lo = np.where(left, lo, x1)
    ends = np.minimum(sdf(np.full(len(lo), -h)), sdf(np.full(len(lo), h)))
    return np.minimum(sdf(0.5 * (lo + hi)), ends) - float(capsule.radius)
