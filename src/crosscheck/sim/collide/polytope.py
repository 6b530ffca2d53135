"""Convex polytopes as collision detection wants them (Python side, at compile time): vertices,
polygonal faces with outward planes, edges with their two faces, an interior point.

Boxes and meshes both become polytopes, so box/box, box/hull and hull/hull share one separating
axis test with face clipping (polytope3d.py). A mesh collides as its **convex hull**: a concave
mesh (the L bracket) is filled in for contact (its notch is solid), said so in docs/inhouse.md.
The hull comes from qhull (scipy.spatial.ConvexHull); qhull returns triangles, and coplanar
triangles are merged back into one polygon so that a flat face gives a 4-point manifold, not a
triangle's 3.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

# Coplanar triangles are merged when their unit normals differ by less than this (and their
# plane offsets by this times the hull's size): qhull's facets of one flat face agree to round-off.
COPLANAR = 1e-7


class Polytope(NamedTuple):
    vertices: np.ndarray  # (V, 3), in the shape frame
    faces: tuple[tuple[int, ...], ...]  # each counter-clockwise about its outward normal
    normals: np.ndarray  # (F, 3) outward unit normals
    offsets: np.ndarray  # (F,) normal . p = offset on the face
    edges: np.ndarray  # (E, 2) vertex indices, each undirected edge once
    edge_faces: np.ndarray  # (E, 2) the two faces meeting at the edge
    centroid: np.ndarray  # (3,) mean of the vertices: an interior point


def box_polytope(half) -> Polytope:
    """The box with half extents ``half`` centred on its origin."""
    h = np.asarray(half, dtype=float)
    signs = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)], float)
    vertices = signs * h
    # vertex index = 4 ix + 2 iy + iz with i* = 0 for -, 1 for +
    faces = ((0, 1, 3, 2), (4, 6, 7, 5),  # -x, +x
             (0, 4, 5, 1), (2, 3, 7, 6),  # -y, +y
             (0, 2, 6, 4), (1, 5, 7, 3))  # -z, +z
    return from_faces(vertices, faces)


def hull_polytope(points) -> Polytope:
    """The convex hull of ``points`` (a mesh's vertices), coplanar facets merged into polygons."""
    from scipy.spatial import ConvexHull

    p = np.asarray(points, dtype=float)
    hull = ConvexHull(p)
    scale = float(np.max(np.ptp(p, axis=0))) or 1.0
    groups: list[tuple[np.ndarray, float, set[int]]] = []
    for simplex, eq in zip(hull.simplices, hull.equations, strict=True):
        n, off = eq[:3], -eq[3]
        for gn, goff, members in groups:
            if np.max(np.abs(gn - n)) < COPLANAR and abs(goff - off) < COPLANAR * scale:
                members.update(int(i) for i in simplex)
                break
        else:
            groups.append((n.copy(), off, {int(i) for i in simplex}))
    faces = []
    for n, _, members in groups:
        faces.append(_counter_clockwise(p, sorted(members), n))
    used = sorted({i for f in faces for i in f})
    index = {old: new for new, old in enumerate(used)}
    faces = [tuple(index[i] for i in f) for f in faces]
    return from_faces(p[used], faces)


def _counter_clockwise(p: np.ndarray, members: list[int], normal: np.ndarray) -> tuple[int, ...]:
    """The members of one planar convex face, ordered counter-clockwise about ``normal``, with
    vertices lying on a straight side dropped (they are no corner of the polytope)."""
    pts = p[members]
    c = pts.mean(axis=0)
    u = pts[0] - c
    u /= np.linalg.norm(u)
    v = np.cross(normal, u)
    ang = np.arctan2((pts - c) @ v, (pts - c) @ u)
    ring = [members[k] for k in np.argsort(ang, kind="stable")]
    keep = []
    for k, i in enumerate(ring):
        a, b = p[ring[k - 1]], p[ring[(k + 1) % len(ring)]]
        turn = np.cross(p[i] - a, b - p[i]) @ normal
        if turn > 1e-12 * np.linalg.norm(p[i] - a) * np.linalg.norm(b - p[i]):
            keep.append(i)
    return tuple(keep)


def from_faces(vertices, faces) -> Polytope:
    """Planes, edges and their faces from vertices and counter-clockwise polygonal faces."""
    v = np.asarray(vertices, dtype=float)
    centroid = v.mean(axis=0)
    normals, offsets, ordered = [], [], []
    edge_faces: dict[tuple[int, int], list[int]] = {}
    for f, face in enumerate(faces):
        pts = v[list(face)]
        # Newell's normal: robust for any planar polygon
        n = np.zeros(3)
        for k in range(len(face)):
            a, b = pts[k], pts[(k + 1) % len(face)]
            n += np.cross(a, b)
        n /= np.linalg.norm(n)
        if n @ (pts.mean(axis=0) - centroid) < 0:  # given clockwise: turn it round
            face, pts, n = tuple(reversed(face)), pts[::-1], -n
        ordered.append(face)
        normals.append(n)
        offsets.append(float(np.mean(pts @ n)))
        for k in range(len(face)):
            a, b = face[k], face[(k + 1) % len(face)]
            edge_faces.setdefault((min(a, b), max(a, b)), []).append(f)
    bad = [e for e, fs in edge_faces.items() if len(fs) != 2]
    if bad:
        raise ValueError(f"not a closed convex polytope: edges {bad[:3]} do not join two faces")
    edges = np.array(sorted(edge_faces), dtype=np.int64).reshape(-1, 2)
    ef = np.array([edge_faces[tuple(e)] for e in edges], dtype=np.int64).reshape(-1, 2)
    return Polytope(v, tuple(tuple(int(i) for i in f) for f in ordered), np.array(normals),
                    np.array(offsets), edges, ef, centroid)
