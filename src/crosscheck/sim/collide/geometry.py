"""The scene's colliders compiled once into arrays the detection kernels read (and, but for the
broad phase's sort cache, never write).

One collider per body (collider ``i`` is body ``i``: its shape in the body frame, placed relative
to the centre of mass), then one per static (a fixed world pose); the ground plane apart (a
half-space, never in the broad phase). Shapes:

* 3D: sphere, box, capsule, cylinder (exact: its own support, no polygonal stand-in) and mesh.
  **A mesh collides as its convex hull**: a concave mesh (the L bracket's notch) is filled in for
  contact. Boxes and hulls carry a polytope (vertices, polygonal faces with planes, edges with
  their two faces) so the polytope routines treat both.
* 2D: circle and convex polygon (a 2D box is the polygon of its four corners).

The pair values come from :func:`crosscheck.scene.contact.pair_material`, the one pair rule, by
*material class* (:func:`crosscheck.scene.contact.material_classes`, shared with the peer
adapters): colliders whose material has the same values and whose name no
``[[contact_pairs]]`` entry names share a class (the rule depends on the values only), every
named collider has a class of its own. The tables are K x K for K classes, so 5000 bodies of
one material need a 1 x 1 table, not 5000 x 5000. ``pair_collide`` is False where an entry says
``collide = false``.

``margin`` (m) is the speculative distance: pairs closer than it are reported with a negative
depth, so a velocity-level model can stop an approach before it becomes a penetration.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from crosscheck.scene.contact import material_classes
from crosscheck.scene.model import Scene
from crosscheck.scene.shapes import Box, Capsule, Circle, Cylinder, Mesh, Polygon, Sphere
from crosscheck.sim.collide.polytope import Polytope, box_polytope, hull_polytope

# Collider kinds (3D). Polytope kinds (BOX, HULL) have ``polytope >= 0``.
SPHERE, BOX, CAPSULE, CYLINDER, HULL = 0, 1, 2, 3, 4
KIND_NAMES_3D = ("sphere", "box", "capsule", "cylinder", "hull")
# Collider kinds (2D).
CIRCLE, POLYGON = 0, 1
KIND_NAMES_2D = ("circle", "polygon")

# The default speculative distance: contacts up to 5 mm apart are reported (negative depth).
DEFAULT_MARGIN = 5e-3
# Broad phases (broadphase.py): a uniform grid (the default: linear in the bodies for any pile)
# or sweep and prune along one axis (fine for spread-out scenes, O(N^(5/3)) in a compact pile).
GRID, SWEEP = 0, 1
BROADPHASES = {"grid": GRID, "sweep": SWEEP}


class Geometry3D(NamedTuple):
    """Colliders: bodies first (index = body index), then statics. Polytopes: boxes and hulls,
    shared between colliders of the same shape. Planes: the ground (0 or 1 rows)."""

    n_bodies: int
    margin: float
    kind: np.ndarray  # (C,) int64: SPHERE, BOX, CAPSULE, CYLINDER, HULL
    body: np.ndarray  # (C,) int64: body index, -1 for a static
    size: np.ndarray  # (C, 3): sphere (r, 0, 0), box half extents, capsule and cylinder
    #                   (r, half length along z, 0), hull (0, 0, 0)
    bound_radius: np.ndarray  # (C,) radius of a sphere about the shape frame's origin holding
    #                           the shape (a length scale for tolerances)
    frame_pos: np.ndarray  # (C, 3): bodies: the shape frame's origin relative to the centre of
    #                        mass, body frame (= -com); statics: world position
    frame_rot: np.ndarray  # (C, 3, 3): bodies: identity; statics: world rotation
    material_class: np.ndarray  # (C,) int64, row/column of the pair tables
    polytope: np.ndarray  # (C,) int64: index of the box's or hull's polytope, -1 otherwise
    poly_vert_start: np.ndarray  # (P,) int64 into vertices
    poly_vert_count: np.ndarray  # (P,)
    poly_face_start: np.ndarray  # (P,) into face_*
    poly_face_count: np.ndarray  # (P,)
    poly_edge_start: np.ndarray  # (P,) into edge_*
    poly_edge_count: np.ndarray  # (P,)
    poly_centroid: np.ndarray  # (P, 3) an interior point, shape frame
    vertices: np.ndarray  # (V, 3) shape frame
    face_normal: np.ndarray  # (F, 3) outward, shape frame
    face_offset: np.ndarray  # (F,) normal . p on the face
    face_vert_start: np.ndarray  # (F,) into face_verts
    face_vert_count: np.ndarray  # (F,)
    face_verts: np.ndarray  # (K,) int64: vertex indices local to the polytope, counter-clockwise
    edge_verts: np.ndarray  # (E, 2) int64: vertex indices local to the polytope
    edge_faces: np.ndarray  # (E, 2) int64: face indices local to the polytope
    plane_normal: np.ndarray  # (G, 3) unit, out of the ground
    plane_offset: np.ndarray  # (G,) normal . p = offset on the plane
    plane_class: np.ndarray  # (G,) int64
    pair_friction: np.ndarray  # (K, K)
    pair_restitution: np.ndarray  # (K, K)
    pair_rolling_friction: np.ndarray  # (K, K)
    pair_torsional_friction: np.ndarray  # (K, K)
    pair_collide: np.ndarray  # (K, K) bool
    max_poly_verts: int  # the largest polytope's vertex count (scratch sizes)
    max_face_verts: int  # the largest face's vertex count
    max_poly_faces: int  # the largest polytope's face count
    max_poly_edges: int  # the largest polytope's edge count
    # The broad phase (broadphase.py): GRID or SWEEP, and its fields. The caches (the last call's
    # sort orders) are the one thing detection writes here: they change the cost of the next
    # sort, never a result.
    broadphase: int
    sweep_order: np.ndarray  # (C,) int64, SWEEP's order of the last call
    sweep_axis: np.ndarray  # (1,) int64, its axis (-1: none yet)
    grid_cell: float  # GRID's cell size (m): the largest box of a grid member fits one cell
    grid_member: np.ndarray  # (C,) bool: in the grid; the others (large statics and bodies)
    grid_big: np.ndarray  # (L,) int64 are tried against every collider
    grid_order: np.ndarray  # (M,) int64, the members in the last call's cell order
    grid_state: np.ndarray  # (1,) int64: 0 until grid_order has been sorted once

    @property
    def n_colliders(self) -> int:
        return len(self.kind)


class Geometry2D(NamedTuple):
    """Colliders: bodies first, then statics. Polygons: vertices counter-clockwise with the
    outward normal of the edge from vertex k to k + 1. Planes: the ground line (0 or 1 rows)."""

    n_bodies: int
    margin: float
    kind: np.ndarray  # (C,) int64: CIRCLE, POLYGON
    body: np.ndarray  # (C,) int64, -1 for a static
    radius: np.ndarray  # (C,): circle radius; polygon 0
    frame_pos: np.ndarray  # (C, 2): bodies: -com (body frame); statics: world position
    frame_angle: np.ndarray  # (C,): bodies 0; statics: world angle
    material_class: np.ndarray  # (C,) int64
    polygon: np.ndarray  # (C,) int64, -1 for a circle
    poly_vert_start: np.ndarray  # (P,) int64
    poly_vert_count: np.ndarray  # (P,)
    poly_centroid: np.ndarray  # (P, 2)
    vertices: np.ndarray  # (V, 2) shape frame, counter-clockwise
    edge_normal: np.ndarray  # (V, 2) outward unit normal of the edge from vertex k to k + 1
    plane_normal: np.ndarray  # (G, 2)
    plane_offset: np.ndarray  # (G,)
    plane_class: np.ndarray  # (G,) int64
    pair_friction: np.ndarray  # (K, K)
    pair_restitution: np.ndarray  # (K, K)
    pair_rolling_friction: np.ndarray  # (K, K)
    pair_torsional_friction: np.ndarray  # (K, K)
    pair_collide: np.ndarray  # (K, K) bool
    max_poly_verts: int
    bound_radius: np.ndarray  # (C,) as Geometry3D's
    broadphase: int  # the broad phase and its fields: see Geometry3D
    sweep_order: np.ndarray
    sweep_axis: np.ndarray
    grid_cell: float
    grid_member: np.ndarray
    grid_big: np.ndarray
    grid_order: np.ndarray
    grid_state: np.ndarray

    @property
    def n_colliders(self) -> int:
        return len(self.kind)


# -- material classes -----------------------------------------------------------------------------
class PairTable(NamedTuple):
    collider_class: np.ndarray  # (C,) for bodies then statics
    plane_class: np.ndarray  # (G,)
    friction: np.ndarray
    restitution: np.ndarray
    rolling_friction: np.ndarray
    torsional_friction: np.ndarray
    collide: np.ndarray


def pair_table(scene: Scene) -> PairTable:
    """Material classes (:func:`crosscheck.scene.contact.material_classes`) and the K x K pair
    values as arrays."""
    classes = material_classes(scene)
    cls = np.array([classes.of[name] for name in classes.surfaces], dtype=np.int64)
    tables = {name: np.array([[getattr(v, name) for v in row] for row in classes.values],
                             dtype=np.float64).reshape(classes.k, classes.k)
              for name in ("friction", "restitution", "rolling_friction", "torsional_friction")}
    collide = np.array([[v.collide for v in row] for row in classes.values],
                       dtype=np.bool_).reshape(classes.k, classes.k)
    n_col = len(scene.bodies) + len(scene.statics)
    return PairTable(cls[:n_col].copy(), cls[n_col:].copy(), tables["friction"],
                     tables["restitution"], tables["rolling_friction"],
                     tables["torsional_friction"], collide)


# -- compiling ------------------------------------------------------------------------------------
def compile_geometry(scene: Scene, margin: float = DEFAULT_MARGIN,
                     broadphase: str = "grid") -> Geometry3D | Geometry2D:
    """The scene's bodies, statics and ground as collision arrays (see the module docstring);
    ``broadphase``: "grid" or "sweep" (broadphase.py)."""
    if not margin >= 0.0:
        raise ValueError(f"contact margin must be >= 0, got {margin!r}")
    if scene.dimension == 3:
        return _compile3d(scene, float(margin), broadphase)
    if scene.dimension == 2:
        return _compile2d(scene, float(margin), broadphase)
    raise ValueError(f"dimension must be 2 or 3, got {scene.dimension}")


def _placements(scene: Scene):
    """(shape, frame position, frame orientation or None, is body) for every collider."""
    for b in scene.bodies:
        yield b.shape, -np.asarray(b.com, dtype=float), None
    for s in scene.statics:
        yield s.shape, np.asarray(s.position, dtype=float), np.asarray(s.orientation, float)


def _compile3d(scene: Scene, margin: float, broadphase: str) -> Geometry3D:
    from crosscheck.rotations import quat_to_matrix

    table = pair_table(scene)
    polys: list[Polytope] = []
    poly_index: dict[tuple, int] = {}
    kind, size, fpos, frot, poly, bound = [], [], [], [], [], []
    for shape, pos, orientation in _placements(scene):
        p = -1
        lo, hi = shape.bounding_box()
        bound.append(float(np.linalg.norm(np.maximum(np.abs(lo), np.abs(hi)))))
        if isinstance(shape, Sphere):
            k, s = SPHERE, (shape.radius, 0.0, 0.0)
        elif isinstance(shape, Box):
            k, s = BOX, tuple(0.5 * np.asarray(shape.size, float))
            key = ("box", *s)
            if key not in poly_index:
                poly_index[key] = len(polys)
                polys.append(box_polytope(s))
            p = poly_index[key]
        elif isinstance(shape, Capsule):
            k, s = CAPSULE, (shape.radius, 0.5 * shape.length, 0.0)
        elif isinstance(shape, Cylinder):
            k, s = CYLINDER, (shape.radius, 0.5 * shape.length, 0.0)
        elif isinstance(shape, Mesh):
            k, s = HULL, (0.0, 0.0, 0.0)
            key = ("mesh", str(shape.path), float(shape.scale))
            if key not in poly_index:
                poly_index[key] = len(polys)
                polys.append(hull_polytope(shape.vertices))
            p = poly_index[key]
        else:
            raise ValueError(f"3D collision detection does not know shape {shape.kind!r}")
        kind.append(k)
        size.append(s)
        fpos.append(pos)
        frot.append(np.eye(3) if orientation is None else quat_to_matrix(orientation))
        poly.append(p)
    c = len(kind)
    n = len(scene.bodies)
    arrays = _polytope_arrays(polys)
    planes = _planes(scene, 3)
    return Geometry3D(
        n_bodies=n, margin=margin,
        kind=np.array(kind, dtype=np.int64).reshape(c),
        body=np.array([*range(n), *([-1] * (c - n))], dtype=np.int64).reshape(c),
        size=_f64(size, (c, 3)), bound_radius=_f64(bound, (c,)), frame_pos=_f64(fpos, (c, 3)),
        frame_rot=_f64(frot, (c, 3, 3)),
        material_class=table.collider_class, polytope=np.array(poly, dtype=np.int64).reshape(c),
        **arrays, plane_normal=planes[0], plane_offset=planes[1], plane_class=table.plane_class,
        pair_friction=table.friction, pair_restitution=table.restitution,
        pair_rolling_friction=table.rolling_friction,
        pair_torsional_friction=table.torsional_friction, pair_collide=table.collide,
        max_poly_verts=max([len(p.vertices) for p in polys], default=1),
        max_face_verts=max([len(f) for p in polys for f in p.faces], default=1),
        max_poly_faces=max([len(p.faces) for p in polys], default=1),
        max_poly_edges=max([len(p.edges) for p in polys], default=1),
        **_broadphase_fields(bound, margin, broadphase))


def _polytope_arrays(polys: list[Polytope]) -> dict[str, np.ndarray]:
    vs, fs, es = np.cumsum([0] + [len(p.vertices) for p in polys]), \
        np.cumsum([0] + [len(p.faces) for p in polys]), \
        np.cumsum([0] + [len(p.edges) for p in polys])
    face_verts = [i for p in polys for f in p.faces for i in f]
    counts = [len(f) for p in polys for f in p.faces]
    return dict(
        poly_vert_start=np.asarray(vs[:-1], np.int64), poly_vert_count=np.diff(vs).astype(np.int64),
        poly_face_start=np.asarray(fs[:-1], np.int64), poly_face_count=np.diff(fs).astype(np.int64),
        poly_edge_start=np.asarray(es[:-1], np.int64), poly_edge_count=np.diff(es).astype(np.int64),
        poly_centroid=_f64([p.centroid for p in polys], (len(polys), 3)),
        vertices=_f64([v for p in polys for v in p.vertices], (int(vs[-1]), 3)),
        face_normal=_f64([n for p in polys for n in p.normals], (int(fs[-1]), 3)),
        face_offset=_f64([o for p in polys for o in p.offsets], (int(fs[-1]),)),
        face_vert_start=np.asarray(np.cumsum([0] + counts)[:-1], np.int64),
        face_vert_count=np.asarray(counts, np.int64).reshape(-1),
        face_verts=np.asarray(face_verts, np.int64).reshape(-1),
        edge_verts=np.asarray([e for p in polys for e in p.edges], np.int64).reshape(-1, 2),
        edge_faces=np.asarray([e for p in polys for e in p.edge_faces], np.int64).reshape(-1, 2))


def _planes(scene: Scene, d: int) -> tuple[np.ndarray, np.ndarray]:
    if scene.ground is None:
        return np.zeros((0, d)), np.zeros(0)
    n = np.asarray(scene.ground.normal, dtype=float)
    norm = float(np.linalg.norm(n))
    return _f64(n / norm, (1, d)), _f64([scene.ground.offset / norm], (1,))


def _compile2d(scene: Scene, margin: float, broadphase: str) -> Geometry2D:
    table = pair_table(scene)
    polys: list[np.ndarray] = []
    poly_index: dict[tuple, int] = {}
    kind, radius, fpos, fang, poly, bound = [], [], [], [], [], []
    for shape, pos, orientation in _placements(scene):
        p = -1
        lo, hi = shape.bounding_box()
        bound.append(float(np.linalg.norm(np.maximum(np.abs(lo), np.abs(hi)))))
        if isinstance(shape, Circle):
            k, r = CIRCLE, shape.radius
        elif isinstance(shape, Box | Polygon):
            k, r = POLYGON, 0.0
            if isinstance(shape, Box):
                hx, hy = 0.5 * np.asarray(shape.size, float)
                verts = np.array([[-hx, -hy], [hx, -hy], [hx, hy], [-hx, hy]])
            else:
                verts = np.asarray(shape.vertices, float)
            key = tuple(verts.ravel())
            if key not in poly_index:
                poly_index[key] = len(polys)
                polys.append(verts)
            p = poly_index[key]
        else:
            raise ValueError(f"2D collision detection does not know shape {shape.kind!r}")
        kind.append(k)
        radius.append(r)
        fpos.append(pos)
        fang.append(0.0 if orientation is None else float(np.asarray(orientation).reshape(-1)[0]))
        poly.append(p)
    c, n = len(kind), len(scene.bodies)
    starts = np.cumsum([0] + [len(v) for v in polys])
    normals = []
    for v in polys:
        e = np.roll(v, -1, axis=0) - v
        nrm = np.stack([e[:, 1], -e[:, 0]], axis=1)  # right of a counter-clockwise edge: outward
        normals.extend(nrm / np.linalg.norm(nrm, axis=1)[:, None])
    planes = _planes(scene, 2)
    return Geometry2D(
        n_bodies=n, margin=margin, kind=np.array(kind, np.int64).reshape(c),
        body=np.array([*range(n), *([-1] * (c - n))], dtype=np.int64).reshape(c),
        radius=_f64(radius, (c,)), frame_pos=_f64(fpos, (c, 2)), frame_angle=_f64(fang, (c,)),
        material_class=table.collider_class, polygon=np.array(poly, np.int64).reshape(c),
        poly_vert_start=np.asarray(starts[:-1], np.int64),
        poly_vert_count=np.diff(starts).astype(np.int64),
        poly_centroid=_f64([v.mean(axis=0) for v in polys], (len(polys), 2)),
        vertices=_f64([x for v in polys for x in v], (int(starts[-1]), 2)),
        edge_normal=_f64(normals, (int(starts[-1]), 2)),
        plane_normal=planes[0], plane_offset=planes[1], plane_class=table.plane_class,
        pair_friction=table.friction, pair_restitution=table.restitution,
        pair_rolling_friction=table.rolling_friction,
        pair_torsional_friction=table.torsional_friction, pair_collide=table.collide,
        max_poly_verts=max([len(v) for v in polys], default=1), bound_radius=_f64(bound, (c,)),
        **_broadphase_fields(bound, margin, broadphase))


# A collider whose bounding radius exceeds this many times the median stays out of the grid (a
# wall, a long ramp): it would set a cell size that puts the whole pile in a few cells.
LARGE_FACTOR = 4.0


def _broadphase_fields(bound: list[float], margin: float, broadphase: str) -> dict:
    """The broad phase's method and its fields: the grid's cell fits the largest regular
    collider's box (twice its bounding radius, grown by the margin)."""
    if broadphase not in BROADPHASES:
        raise ValueError(f"broad phase {broadphase!r}: one of {sorted(BROADPHASES)}")
    r = np.asarray(bound, dtype=float).reshape(-1)
    c = len(r)
    limit = LARGE_FACTOR * float(np.median(r)) if c else 0.0
    member = r <= limit
    cell = 2.0 * float(r[member].max()) + margin if member.any() else 1.0
    return dict(broadphase=BROADPHASES[broadphase],
                sweep_order=np.arange(c, dtype=np.int64), sweep_axis=np.full(1, -1, np.int64),
                grid_cell=max(cell, 1e-9), grid_member=member,
                grid_big=np.flatnonzero(~member).astype(np.int64),
                grid_order=np.flatnonzero(member).astype(np.int64),
                grid_state=np.zeros(1, np.int64))


def _f64(a, shape) -> np.ndarray:
    return np.ascontiguousarray(np.asarray(a, dtype=np.float64).reshape(shape))
