"""Mass properties of rigid bodies: closed forms, polyhedral meshes and their approximations.

Everything is in SI units. Volumetric density is kg/m^3 (3D), areal density kg/m^2 (2D).

Conventions
-----------
The inertia tensor of a body about a point ``o`` is

    I_o = integral over the body of ( (r . r) E - r r^T ) dm,    r = x - o,

with E the 3x3 identity. Its diagonal holds the moments of inertia, its off-diagonal entries are
the *negated* products of inertia (I_xy = -integral x y dm). Unless said otherwise ``inertia``
is about the centre of mass, expressed in the shape's own frame.

Three ways of computing the inertia of a mesh are provided, the ones the course notes in
``seeds/`` compare (Baraff, SIGGRAPH 2001 course notes "Physically based modeling", the slides
"Approximating I_body: bounding boxes / point sampling; computing I_body: Green's theorem"):

* :func:`mesh_mass_properties`: exact for a closed polyhedron, by the divergence theorem in its
  signed-tetrahedron form (equivalent to Mirtich 1996, "Fast and accurate computation of
  polyhedral mass properties", J. Graphics Tools 1(2)).
* :func:`bounding_box_mass_properties`: the solid axis-aligned bounding box.
* :func:`sampled_mass_properties`: Monte Carlo point sampling of the bounding box with an
  inside test.

:func:`shape_mass_properties` dispatches a shape of :mod:`crosscheck.scene.shapes` (the one shape
vocabulary of scenes) to its closed form or to the exact mesh computation.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass

import numpy as np

from crosscheck.scene.shapes import (
    Box,
    Capsule,
    Circle,
    Cylinder,
    Mesh,
    Polygon,
    Shape,
    Sphere,
    points_inside,  # the ray-parity inside test lives with the shapes; re-exported here
)

__all__ = [
    "MassProperties2D",
    "MassProperties3D",
    "MeshError",
    "bounding_box_mass_properties",
    "box",
    "box2d",
    "capsule",
    "check_closed_volume",
    "circle",
    "cylinder",
    "load_mesh",
    "mesh_mass_properties",
    "parallel_axis",
    "points_inside",
    "polygon",
    "sampled_mass_properties",
    "shape_mass_properties",
    "sphere",
    "with_mass",
]

CLOSED_MESH_EXPECTED = "a closed, consistently oriented triangle mesh (watertight)"


class MeshError(ValueError):
    """A mesh file is missing, unreadable, or not a closed volume.

    ``str(err)`` is ``"<path>: <message>"`` when the path is known, else the message alone.
    """

    def __init__(self, message: str, path: str | os.PathLike | None = None):
        self.message = message
        self.path = None if path is None else os.fspath(path)
        super().__init__(message if self.path is None else f"{self.path}: {message}")


# --------------------------------------------------------------------------------------------
# containers
# --------------------------------------------------------------------------------------------


def _as_vec(x, n: int, name: str) -> np.ndarray:
    a = np.array(x, dtype=float).reshape(-1)
    if a.shape != (n,):
        raise ValueError(f"{name} must have {n} components, got shape {np.shape(x)}")
    return a


def _positive(x, name: str) -> float:
    x = float(x)
    if not (math.isfinite(x) and x > 0.0):
        raise ValueError(f"{name} must be a positive finite number, got {x!r}")
    return x


def parallel_axis(inertia_com, mass: float, offset) -> np.ndarray:
    """Inertia about a point displaced by ``offset`` from the centre of mass.

    Parallel-axis (Huygens-Steiner) theorem in tensor form:
    ``I_p = I_com + m ( (d . d) E - d d^T )`` with ``d = p - com`` (``offset``).
    Only valid when ``inertia_com`` is about the centre of mass.
    """
    d = _as_vec(offset, 3, "offset")
    inertia_com = np.asarray(inertia_com, dtype=float)
    return inertia_com + float(mass) * (np.dot(d, d) * np.eye(3) - np.outer(d, d))


@dataclass(frozen=True)
class MassProperties3D:
    """Mass, centre of mass and inertia about the centre of mass, in the shape's own frame."""

    mass: float
    com: np.ndarray
    inertia: np.ndarray

    def __post_init__(self):
        com = _as_vec(self.com, 3, "com")
        inertia = np.array(self.inertia, dtype=float)
        if inertia.shape != (3, 3):
            raise ValueError(f"inertia must be 3x3, got shape {inertia.shape}")
        # store a symmetric copy: the tensor is symmetric by definition, round-off aside
        inertia = 0.5 * (inertia + inertia.T)
        com.setflags(write=False)
        inertia.setflags(write=False)
        object.__setattr__(self, "mass", float(self.mass))
        object.__setattr__(self, "com", com)
        object.__setattr__(self, "inertia", inertia)

    def principal(self) -> tuple[np.ndarray, np.ndarray]:
        """Principal moments (ascending) and principal axes.

        Symmetric eigendecomposition ``inertia = axes @ diag(moments) @ axes.T``. The columns of
        ``axes`` are the principal axes; each column is signed so that its largest component is
        positive, then the last column is flipped if needed so that ``det(axes) = +1`` (a proper
        rotation from principal frame to shape frame).
        """
        moments, axes = np.linalg.eigh(self.inertia)
        axes = np.array(axes)
        for k in range(3):
            if axes[np.argmax(np.abs(axes[:, k])), k] < 0:
                axes[:, k] = -axes[:, k]
        if np.linalg.det(axes) < 0:
            axes[:, 2] = -axes[:, 2]
        return moments, axes

    def about_point(self, point) -> np.ndarray:
        """Inertia tensor about ``point`` (shape frame), by :func:`parallel_axis`."""
        return parallel_axis(self.inertia, self.mass, _as_vec(point, 3, "point") - self.com)

    def rotated(self, rotation) -> MassProperties3D:
        """The same body rotated by ``rotation`` (3x3 rotation matrix) about the frame origin.

        ``com' = R com``, ``I' = R I R^T`` (the inertia tensor is a rank-2 tensor).
        """
        R = np.asarray(rotation, dtype=float)
        if R.shape != (3, 3):
            raise ValueError(f"rotation must be 3x3, got shape {R.shape}")
        return MassProperties3D(self.mass, R @ self.com, R @ self.inertia @ R.T)

    def translated(self, translation) -> MassProperties3D:
        """The same body moved by ``translation``: the com moves, inertia about it does not."""
        return MassProperties3D(self.mass, self.com + _as_vec(translation, 3, "translation"),
                                self.inertia)


@dataclass(frozen=True)
class MassProperties2D:
    """Planar body: mass, centre of mass (x, y) and moment about the out-of-plane axis through
    the centre of mass, ``moment = integral of |r - com|^2 dm``."""

    mass: float
    com: np.ndarray
    moment: float

    def __post_init__(self):
        com = _as_vec(self.com, 2, "com")
        com.setflags(write=False)
        object.__setattr__(self, "mass", float(self.mass))
        object.__setattr__(self, "com", com)
        object.__setattr__(self, "moment", float(self.moment))

    def about_point(self, point) -> float:
        """Moment about the out-of-plane axis through ``point``: ``J_com + m |p - com|^2``."""
        d = _as_vec(point, 2, "point") - self.com
        return self.moment + self.mass * float(d @ d)

    def rotated(self, angle: float) -> MassProperties2D:
        """Rotated by ``angle`` (rad, counter-clockwise) about the origin; the moment is a scalar
        and does not change."""
        c, s = math.cos(angle), math.sin(angle)
        return MassProperties2D(self.mass, np.array([[c, -s], [s, c]]) @ self.com, self.moment)

    def translated(self, translation) -> MassProperties2D:
        return MassProperties2D(self.mass, self.com + _as_vec(translation, 2, "translation"),
                                self.moment)


def with_mass(props, mass: float):
    """The same shape with total mass ``mass``: mass and inertia scale by ``mass / props.mass``
    (both are linear in a uniform density), the centre of mass does not move."""
    mass = _positive(mass, "mass")
    k = mass / props.mass
    if isinstance(props, MassProperties2D):
        return MassProperties2D(mass, props.com, props.moment * k)
    return MassProperties3D(mass, props.com, props.inertia * k)


# --------------------------------------------------------------------------------------------
# closed forms, 3D (com at the origin)
# --------------------------------------------------------------------------------------------


def sphere(radius: float, density: float) -> MassProperties3D:
    """Solid sphere: ``m = 4/3 pi r^3 rho``, ``I = 2/5 m r^2`` about every axis."""
    r, rho = _positive(radius, "radius"), _positive(density, "density")
    m = 4.0 / 3.0 * math.pi * r**3 * rho
    return MassProperties3D(m, np.zeros(3), np.eye(3) * (0.4 * m * r * r))


def box(size, density: float) -> MassProperties3D:
    """Solid cuboid with full side lengths ``size = (a, b, c)``: ``m = a b c rho``,
    ``I_xx = m (b^2 + c^2) / 12`` and cyclically."""
    a, b, c = (_positive(s, "box size") for s in _as_vec(size, 3, "size"))
    m = a * b * c * _positive(density, "density")
    return MassProperties3D(m, np.zeros(3),
                            np.diag([b * b + c * c, a * a + c * c, a * a + b * b]) * (m / 12.0))


def cylinder(radius: float, length: float, density: float) -> MassProperties3D:
    """Solid cylinder, axis along z, centred: ``m = pi r^2 L rho``, ``I_zz = m r^2 / 2``,
    ``I_xx = I_yy = m (3 r^2 + L^2) / 12``."""
    r, L = _positive(radius, "radius"), _positive(length, "length")
    m = math.pi * r * r * L * _positive(density, "density")
    ixx = m * (3.0 * r * r + L * L) / 12.0
    return MassProperties3D(m, np.zeros(3), np.diag([ixx, ixx, 0.5 * m * r * r]))


def capsule(radius: float, length: float, density: float) -> MassProperties3D:
    """Capsule: cylinder of radius ``r`` and length ``L`` (axis z, centred) capped by two solid
    hemispheres of radius ``r``; total length ``L + 2 r``.

    Cylinder: ``m_c = pi r^2 L rho``, ``I_zz = m_c r^2/2``, ``I_xx = m_c (3 r^2 + L^2)/12``.
    Each hemisphere: ``m_h = 2/3 pi r^3 rho``, ``I_zz = 2/5 m_h r^2``; its centroid lies
    ``3r/8`` from its flat face, where the transverse moment is ``2/5 m_h r^2``, so about its
    centroid ``I_xx = (2/5 - 9/64) m_h r^2 = 83/320 m_h r^2``; the centroid is at
    ``d = L/2 + 3r/8`` from the capsule centre, hence (parallel axis)
    ``I_xx(cap) = 83/320 m_h r^2 + m_h d^2``.
    """
    r, L = _positive(radius, "radius"), _positive(length, "length")
    rho = _positive(density, "density")
    m_c = math.pi * r * r * L * rho
    m_h = 2.0 / 3.0 * math.pi * r**3 * rho
    d = 0.5 * L + 3.0 * r / 8.0
    izz = 0.5 * m_c * r * r + 2.0 * (0.4 * m_h * r * r)
    ixx = m_c * (3.0 * r * r + L * L) / 12.0 + 2.0 * (83.0 / 320.0 * m_h * r * r + m_h * d * d)
    return MassProperties3D(m_c + 2.0 * m_h, np.zeros(3), np.diag([ixx, ixx, izz]))


# --------------------------------------------------------------------------------------------
# closed forms, 2D
# --------------------------------------------------------------------------------------------


def circle(radius: float, density: float) -> MassProperties2D:
    """Disc: ``m = pi r^2 rho`` (areal density), ``J = m r^2 / 2``."""
    r = _positive(radius, "radius")
    m = math.pi * r * r * _positive(density, "density")
    return MassProperties2D(m, np.zeros(2), 0.5 * m * r * r)


def box2d(size, density: float) -> MassProperties2D:
    """Rectangle with full side lengths ``(w, h)``: ``m = w h rho``, ``J = m (w^2 + h^2)/12``."""
    w, h = (_positive(s, "box size") for s in _as_vec(size, 2, "size"))
    m = w * h * _positive(density, "density")
    return MassProperties2D(m, np.zeros(2), m * (w * w + h * h) / 12.0)


def polygon(vertices, density: float) -> MassProperties2D:
    """Simple (non self-intersecting) polygon by Green's theorem, either orientation.

    With ``c_i = x_i y_{i+1} - x_{i+1} y_i`` over the closed vertex loop:
    ``A = 1/2 sum c_i``,  ``com = sum (p_i + p_{i+1}) c_i / (6 A)``,
    ``J_o = sum c_i (x_i^2 + x_i x_{i+1} + x_{i+1}^2 + y_i^2 + y_i y_{i+1} + y_{i+1}^2) / 12``
    (polar second moment about the origin; signed like ``A``). The sums are taken about the
    vertex mean to limit cancellation; ``J_com = rho |J_o| - m |com - o|^2``.
    """
    p = np.asarray(vertices, dtype=float)
    if p.ndim != 2 or p.shape[1] != 2 or len(p) < 3:
        raise ValueError(f"polygon needs an (n >= 3, 2) vertex array, got shape {p.shape}")
    rho = _positive(density, "density")
    ref = p.mean(axis=0)
    q = p - ref
    q1 = np.roll(q, -1, axis=0)
    c = q[:, 0] * q1[:, 1] - q1[:, 0] * q[:, 1]
    area2 = c.sum()
    if not (abs(area2) > 1e-300 and math.isfinite(area2)):
        raise ValueError("polygon has zero area")
    sign = 1.0 if area2 > 0 else -1.0
    area = 0.5 * abs(area2)
    com_local = ((q + q1) * c[:, None]).sum(axis=0) / (3.0 * area2)
    j_ref = sign * (c * (q[:, 0] ** 2 + q[:, 0] * q1[:, 0] + q1[:, 0] ** 2
                         + q[:, 1] ** 2 + q[:, 1] * q1[:, 1] + q1[:, 1] ** 2)).sum() / 12.0
    m = rho * area
    return MassProperties2D(m, ref + com_local, rho * j_ref - m * float(com_local @ com_local))


# --------------------------------------------------------------------------------------------
# meshes
# --------------------------------------------------------------------------------------------


def _mesh_arrays(vertices, faces) -> tuple[np.ndarray, np.ndarray]:
    v = np.asarray(vertices, dtype=float)
    f = np.asarray(faces)
    if v.ndim != 2 or v.shape[1] != 3:
        raise ValueError(f"vertices must be (n, 3), got shape {v.shape}")
    if f.ndim != 2 or f.shape[1] != 3 or not np.issubdtype(f.dtype, np.integer):
        raise ValueError(f"faces must be an (m, 3) integer array, got shape {f.shape}")
    if len(f) == 0:
        raise ValueError("mesh has no faces")
    if f.min() < 0 or f.max() >= len(v):
        raise ValueError("face index out of range")
    return v, f


def mesh_mass_properties(vertices, faces, density: float) -> MassProperties3D:
    """Exact mass properties of a closed, outward-oriented triangle mesh of uniform density.

    Divergence theorem, signed-tetrahedron form (equivalent to Mirtich 1996 and to
    Eberly, "Polyhedral mass properties (revisited)"): the solid is the signed sum of the
    tetrahedra ``(o, a, b, c)`` over faces ``(a, b, c)``, for any point ``o``. For one
    tetrahedron with edge vectors ``a, b, c`` from ``o``:

    * ``V = a . (b x c) / 6``
    * ``integral r dV = V (a + b + c) / 4``
    * ``integral r r^T dV = V / 20 ( a a^T + b b^T + c c^T + s s^T )``, ``s = a + b + c``

    (the last is the covariance of a simplex, e.g. Tonon 2004, J. Math. Stat. 1(1)). Summing
    gives the volume, first moment and second-moment matrix ``C`` about ``o``; with the com at
    ``o + d``: ``C_com = rho C - m d d^T`` and ``I_com = tr(C_com) E - C_com``. ``o`` is the
    vertex mean, which keeps round-off small for meshes far from their frame origin.
    """
    v, f = _mesh_arrays(vertices, faces)
    rho = _positive(density, "density")
    o = v.mean(axis=0)
    a, b, c = (v[f[:, k]] - o for k in range(3))
    vol6 = np.einsum("ij,ij->i", a, np.cross(b, c))  # 6 V per tetrahedron
    volume = vol6.sum() / 6.0
    if not (volume > 0.0 and math.isfinite(volume)):
        raise ValueError(
            f"mesh encloses a non-positive volume ({volume:.6g} m^3): expected "
            + CLOSED_MESH_EXPECTED + " with outward normals")
    s = a + b + c
    first = (vol6[:, None] * s).sum(axis=0) / 24.0
    second = np.einsum("i,ij,ik->jk", vol6, a, a) + np.einsum("i,ij,ik->jk", vol6, b, b) \
        + np.einsum("i,ij,ik->jk", vol6, c, c) + np.einsum("i,ij,ik->jk", vol6, s, s)
    second /= 120.0
    mass = rho * volume
    d = first / volume
    cov = rho * second - mass * np.outer(d, d)
    inertia = np.trace(cov) * np.eye(3) - cov
    return MassProperties3D(mass, o + d, inertia)


def _mass_or_density(volume: float, density, mass) -> float:
    if (density is None) == (mass is None):
        raise ValueError("give exactly one of density or mass")
    if mass is not None:
        return _positive(mass, "mass")
    return _positive(density, "density") * volume


def bounding_box_mass_properties(vertices, density: float | None = None, *,
                                 mass: float | None = None) -> MassProperties3D:
    """The seeds' crudest approximation: the solid axis-aligned bounding box of ``vertices``.

    Mass is ``density * box volume`` (or ``mass`` if given), com at the box centre, inertia of a
    solid box (:func:`box`). Exact for an axis-aligned box, poor for anything else.
    """
    v = np.asarray(vertices, dtype=float).reshape(-1, 3)
    lo, hi = v.min(axis=0), v.max(axis=0)
    size = hi - lo
    m = _mass_or_density(float(np.prod(size)), density, mass)
    ext = size * size
    inertia = np.diag([ext[1] + ext[2], ext[0] + ext[2], ext[0] + ext[1]]) * (m / 12.0)
    return MassProperties3D(m, 0.5 * (lo + hi), inertia)


def _triangles(mesh) -> np.ndarray:
    if hasattr(mesh, "triangles"):
        return np.asarray(mesh.triangles, dtype=float)
    v, f = _mesh_arrays(*mesh)
    return v[f]


def sampled_mass_properties(mesh, density: float, n_samples: int = 100_000,
                            seed: int | None = 0) -> MassProperties3D:
    """Monte Carlo estimate by point sampling (the seeds' "point sampling" approximation).

    ``n_samples`` points uniform in the axis-aligned bounding box (``numpy.random.default_rng
    (seed)``, so deterministic for a given seed); inside test :func:`points_inside`. With
    ``k`` points inside: ``m = rho V_box k / N``, com = mean of the inside points,
    ``I = (m / k) sum ( |r_i|^2 E - r_i r_i^T )``, ``r_i`` from the com. The statistical error
    decreases like ``1 / sqrt(N)``. ``mesh`` is a ``trimesh.Trimesh`` (checked with
    :func:`check_closed_volume`, raises :class:`MeshError`) or a ``(vertices, faces)`` pair
    (not checked); it must be a closed volume.
    """
    rho = _positive(density, "density")
    n = int(n_samples)
    if n < 1:
        raise ValueError(f"n_samples must be >= 1, got {n_samples!r}")
    if hasattr(mesh, "is_watertight"):
        check_closed_volume(mesh)  # parity is meaningless for an open surface
    tri = _triangles(mesh)
    flat = tri.reshape(-1, 3)
    lo, hi = flat.min(axis=0), flat.max(axis=0)
    rng = np.random.default_rng(seed)
    pts = lo + rng.random((n, 3)) * (hi - lo)
    pts = pts[points_inside(tri, pts)]
    k = len(pts)
    if k == 0:
        raise ValueError(f"no sample point fell inside the mesh ({n} samples); use more")
    mass = rho * float(np.prod(hi - lo)) * k / n
    com = pts.mean(axis=0)
    r = pts - com
    cov = (mass / k) * (r.T @ r)
    return MassProperties3D(mass, com, np.trace(cov) * np.eye(3) - cov)


def check_closed_volume(mesh):
    """Raise :class:`MeshError` unless ``mesh`` is a closed, consistently oriented triangle mesh
    enclosing a positive volume (outward normals). Returns the mesh."""
    faces = np.asarray(getattr(mesh, "faces", np.empty((0, 3))))
    if faces.ndim != 2 or len(faces) == 0:
        raise MeshError(f"no triangles found, expected {CLOSED_MESH_EXPECTED}")
    if not mesh.is_watertight:
        raise MeshError(f"mesh has open edges (holes), expected {CLOSED_MESH_EXPECTED}")
    if not mesh.is_winding_consistent:
        raise MeshError(f"face winding is inconsistent, expected {CLOSED_MESH_EXPECTED}")
    volume = float(mesh.volume)
    if not (volume > 0.0 and math.isfinite(volume)):
        raise MeshError(f"enclosed volume is {volume:.6g} m^3 (inward normals?), expected "
                        f"{CLOSED_MESH_EXPECTED} with outward normals and positive volume")
    return mesh


def load_mesh(path, *, check: bool = True):
    """Load a triangle mesh file (OBJ, STL, PLY, OFF, ... whatever trimesh reads) as one
    ``trimesh.Trimesh``; scenes are concatenated. Unless ``check=False``, also
    :func:`check_closed_volume`. Raises :class:`MeshError` naming the file."""
    import trimesh

    p = os.fspath(path)
    if not os.path.isfile(p):
        raise MeshError(f"file not found, expected {CLOSED_MESH_EXPECTED}", p)
    try:
        mesh = trimesh.load(p, force="mesh")
    except Exception as exc:  # trimesh raises many kinds for bad files
        raise MeshError(f"cannot read mesh ({type(exc).__name__}: {exc}), expected "
                        f"{CLOSED_MESH_EXPECTED}", p) from exc
    if not isinstance(mesh, trimesh.Trimesh) or len(mesh.faces) == 0:
        raise MeshError(f"no triangles found, expected {CLOSED_MESH_EXPECTED}", p)
    if check:
        try:
            check_closed_volume(mesh)
        except MeshError as exc:
            raise MeshError(exc.message, p) from None
    return mesh


# --------------------------------------------------------------------------------------------
# scene shapes
# --------------------------------------------------------------------------------------------


def shape_mass_properties(shape: Shape, density: float) -> MassProperties3D | MassProperties2D:
    """Mass, centroid and inertia about the centroid of a uniform-density scene shape: the closed
    forms above, :func:`mesh_mass_properties` for a mesh. A box is 3D or 2D by its size."""
    match shape:
        case Sphere(radius=r):
            return sphere(r, density)
        case Box(size=s) if len(s) == 3:
            return box(s, density)
        case Box(size=s):
            return box2d(s, density)
        case Capsule(radius=r, length=ln):
            return capsule(r, ln, density)
        case Cylinder(radius=r, length=ln):
            return cylinder(r, ln, density)
        case Mesh(vertices=v, faces=fc):
            return mesh_mass_properties(v, fc, density)
        case Circle(radius=r):
            return circle(r, density)
        case Polygon(vertices=v):
            return polygon(v, density)
    raise TypeError(f"no mass properties for {shape!r}")  # pragma: no cover
