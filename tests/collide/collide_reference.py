"""An independent reference for the narrow phase: the signed distance between two convex shapes
from their support mappings alone (scene/shapes.py, not the detection code).

For convex A and B and a unit direction u (from A towards B), the gap along u is
``g(u) = min_b u . b - max_a u . a``. The signed distance between A and B (the distance when
apart, minus the penetration depth when overlapping) is ``max_u g(u)``, and a maximiser is the
contact normal. Polytopes (boxes, meshes as hulls) reach the maximum at a face normal of the
Minkowski difference: a face normal of A or B or the cross product of an edge of A with an edge
of B, all tried here (edges from trimesh's convex hull); curved shapes at a smooth maximum, found
from a dense set of directions refined by Nelder-Mead.
"""

from __future__ import annotations

import numpy as np
from scipy.optimize import minimize

from crosscheck.scene.shapes import Box, Mesh, Placed, Polygon, rotation_matrix


def gap_along(a: Placed, b: Placed, u: np.ndarray) -> np.ndarray:
    u = np.atleast_2d(u)
    return np.sum(u * b.support(-u), axis=-1) - np.sum(u * a.support(u), axis=-1)


def _sphere_directions(n: int) -> np.ndarray:
    k = np.arange(n) + 0.5
    z = 1.0 - 2.0 * k / n
    phi = np.pi * (1.0 + 5.0 ** 0.5) * k
    r = np.sqrt(1.0 - z * z)
    return np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=1)


def _polytope_axes(p: Placed) -> tuple[np.ndarray, np.ndarray] | None:
    """World face normals and edge directions of a box or mesh hull; None for curved shapes."""
    import trimesh

    shape = p.shape
    if isinstance(shape, Box) and shape.dimension == 3:
        h = 0.5 * np.asarray(shape.size, float)
        verts = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)]) * h
    elif isinstance(shape, Mesh):
        verts = np.asarray(shape.vertices, float)
    else:
        return None
    hull = trimesh.Trimesh(verts).convex_hull
    r = p.rotation()
    normals = hull.face_normals @ r.T
    edges = hull.vertices[hull.edges_unique[:, 1]] - hull.vertices[hull.edges_unique[:, 0]]
    return normals, edges @ r.T


def signed_distance3d(a: Placed, b: Placed, samples: int = 4000):
    """(max_u g(u), the maximising u)."""
    cands = [_sphere_directions(samples)]
    pa, pb = _polytope_axes(a), _polytope_axes(b)
    for p in (pa, pb):
        if p is not None:
            cands += [p[0], -p[0]]
    if pa is not None and pb is not None:
        x = np.cross(pa[1][:, None, :], pb[1][None, :, :]).reshape(-1, 3)
        ln = np.linalg.norm(x, axis=1)
        x = x[ln > 1e-9 * ln.max()] / ln[ln > 1e-9 * ln.max()][:, None]
        cands += [x, -x]
    u = np.concatenate(cands)
    g = gap_along(a, b, u)
    best = int(np.argmax(g))
    u0, g0 = u[best], float(g[best])
    if pa is not None and pb is not None:
        return g0, u0
    # g has several local maxima on the sphere (the penetration depth is not a convex problem):
    # refine from the best few sampled directions, not only the best one
    for start in np.argsort(g)[::-1][:6]:
        gv, v = _refine(a, b, u[start])
        if gv > g0:
            g0, u0 = gv, v
    return g0, u0


def _refine(a: Placed, b: Placed, u0: np.ndarray):
    """Nelder-Mead about u0: v = unit(u0 + x e1 + y e2), e1 and e2 normal to u0 (no pole in the
    way)."""
    e1 = np.cross(u0, [1.0, 0.0, 0.0] if abs(u0[0]) < 0.9 else [0.0, 1.0, 0.0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(u0, e1)

    def direction(xy):
        v = u0 + xy[0] * e1 + xy[1] * e2
        return v / np.linalg.norm(v)

    res = minimize(lambda xy: -float(gap_along(a, b, direction(xy))[0]), [0.0, 0.0],
                   method="Nelder-Mead", options={"xatol": 1e-13, "fatol": 1e-16,
                                                  "initial_simplex": [[0, 0], [0.02, 0],
                                                                      [0, 0.02]],
                                                  "maxiter": 4000})
    v = direction(res.x)
    return float(gap_along(a, b, v)[0]), v


def signed_distance2d(a: Placed, b: Placed, samples: int = 20000):
    """2D: directions on the circle, polygon edge normals exactly, curved maxima refined."""
    th = np.linspace(0, 2 * np.pi, samples, endpoint=False)
    cands = [np.stack([np.cos(th), np.sin(th)], axis=1)]
    for p in (a, b):
        if isinstance(p.shape, Box | Polygon):
            if isinstance(p.shape, Box):
                hx, hy = 0.5 * np.asarray(p.shape.size, float)
                v = np.array([[-hx, -hy], [hx, -hy], [hx, hy], [-hx, hy]])
            else:
                v = np.asarray(p.shape.vertices, float)
            e = np.roll(v, -1, axis=0) - v
            n = np.stack([e[:, 1], -e[:, 0]], axis=1)
            n = (n / np.linalg.norm(n, axis=1)[:, None]) @ rotation_matrix(p.orientation, 2).T
            cands += [n, -n]
    u = np.concatenate(cands)
    g = gap_along(a, b, u)
    best = int(np.argmax(g))
    u0, g0 = u[best], float(g[best])
    t0 = np.arctan2(u0[1], u0[0])
    res = minimize(lambda t: -float(gap_along(a, b, np.array([np.cos(t[0]), np.sin(t[0])]))[0]),
                   [t0], method="Nelder-Mead", options={"xatol": 1e-13, "fatol": 1e-16})
    v = np.array([np.cos(res.x[0]), np.sin(res.x[0])])
    gv = float(gap_along(a, b, v)[0])
    return (gv, v) if gv > g0 else (g0, u0)
