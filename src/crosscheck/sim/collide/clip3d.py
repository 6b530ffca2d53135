"""Clipping a contact feature (a polygon or a segment) to the extent of a reference polygon
(Sutherland-Hodgman against the reference's side planes), with an id per resulting point that
says where it came from: an incident vertex k (``k & 0x7F``) or the crossing of reference side s
(``0x80 | 0x40 if leaving | s``). Shared by the polytope routine and the convex pairs."""

from __future__ import annotations

from numba import njit

from crosscheck.sim._jit import INLINE


@njit(**INLINE)
def clip_polygon(ref, n_ref, nx, ny, nz, poly_in, id_in, n_in, poly_out, id_out):
    """Clip the polygon ``poly_in[:n_in]`` (a segment when n_in = 2) to the prism over the
    reference polygon ``ref[:n_ref]`` (counter-clockwise about (nx, ny, nz)). The result is left
    in ``poly_in`` / ``id_in``; returns its size."""
    n_poly = n_in
    a_pts, a_ids, b_pts, b_ids = poly_in, id_in, poly_out, id_out
    in_out = False  # the current polygon is in poly_out
    for side in range(n_ref):
        if n_poly == 0:
            break
        w = (side + 1) % n_ref
        ex, ey, ez = ref[w, 0] - ref[side, 0], ref[w, 1] - ref[side, 1], ref[w, 2] - ref[side, 2]
        # outward side normal (w - u) x n
        sx, sy, sz = ey * nz - ez * ny, ez * nx - ex * nz, ex * ny - ey * nx
        so = sx * ref[side, 0] + sy * ref[side, 1] + sz * ref[side, 2]
        n_out = 0
        # a segment has one edge, not two (it is not closed)
        n_edges = 1 if n_poly == 2 else n_poly
        if n_poly == 2:
            d0 = sx * a_pts[0, 0] + sy * a_pts[0, 1] + sz * a_pts[0, 2] - so
            d1 = sx * a_pts[1, 0] + sy * a_pts[1, 1] + sz * a_pts[1, 2] - so
            if d0 > 0.0 and d1 > 0.0:
                return 0
            for e in range(2):
                de = d0 if e == 0 else d1
                if de <= 0.0:
                    for r in range(3):
                        b_pts[n_out, r] = a_pts[e, r]
                    b_ids[n_out] = a_ids[e]
                else:
                    t = d0 / (d0 - d1)
                    for r in range(3):
                        b_pts[n_out, r] = a_pts[0, r] + t * (a_pts[1, r] - a_pts[0, r])
                    b_ids[n_out] = 0x80 | (0x40 if e == 1 else 0) | (side & 0x3F)
                n_out += 1
        else:
            for k in range(n_edges):
                k1 = (k + 1) % n_poly
                d0 = sx * a_pts[k, 0] + sy * a_pts[k, 1] + sz * a_pts[k, 2] - so
                d1 = sx * a_pts[k1, 0] + sy * a_pts[k1, 1] + sz * a_pts[k1, 2] - so
                if d0 <= 0.0:
                    for r in range(3):
                        b_pts[n_out, r] = a_pts[k, r]
                    b_ids[n_out] = a_ids[k]
                    n_out += 1
                if (d0 <= 0.0) != (d1 <= 0.0):
                    t = d0 / (d0 - d1)
                    for r in range(3):
                        b_pts[n_out, r] = a_pts[k, r] + t * (a_pts[k1, r] - a_pts[k, r])
                    b_ids[n_out] = 0x80 | (0x40 if d0 <= 0.0 else 0) | (side & 0x3F)
                    n_out += 1
        a_pts, b_pts = b_pts, a_pts
        a_ids, b_ids = b_ids, a_ids
        in_out = not in_out
        n_poly = n_out
    if in_out:
        for k in range(n_poly):
            for r in range(3):
                poly_in[k, r] = a_pts[k, r]
            id_in[k] = a_ids[k]
    return n_poly
