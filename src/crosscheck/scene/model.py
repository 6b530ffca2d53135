"""The Scene: a static, frozen, engine-neutral description of one case.

Conventions (the same for every engine adapter; see docs/architecture.md):

* SI units. 3D: z is up. 2D: the plane is x-y, y is up, angles counter-clockwise about +z.
* Every body has a *body frame*: the frame its shape is declared in (a box centred on its origin,
  a mesh in its file's coordinates). ``Body.position`` and ``Body.orientation`` place that frame in
  the world at t = 0. The centre of mass sits at ``Body.com`` in the body frame (zero for the
  primitives unless the case offsets it), and ``Body.inertia`` is the inertia tensor about the
  centre of mass, expressed in the body frame (full 3x3, not necessarily diagonal).
* Velocities are of the centre of mass, in the world frame; angular velocities are in the world
  frame. Trajectories report the same quantities, plus the centre of mass in world coordinates.
* Quaternions are (w, x, y, z), unit length, rotating body-frame vectors into the world frame.
* 2D bodies use arrays of length 2 and scalar angle, angular velocity and moment of inertia.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

# The shapes live in their own module, shared with the fluid and mass properties; re-exported here
# so that ``from crosscheck.scene.model import Box`` keeps working.
from crosscheck.scene.shapes import (  # noqa: F401
    Box,
    Capsule,
    Circle,
    Cylinder,
    Mesh,
    Placed,
    Polygon,
    Shape,
    Sphere,
)

ENGINE_NAMES = ("inhouse", "mujoco", "pybullet", "pymunk")


@dataclass(frozen=True)
class Material:
    """What a surface is made of. Engines never see these values directly: every pair of surfaces
    that can touch gets one set of pair values from :func:`crosscheck.scene.contact.pair_material`
    (docs/cases.md, "Contact")."""

    name: str  # the [materials] name, or the field path of an inline table (bodies[0].material)
    friction: float = 0.5  # Coulomb coefficient
    restitution: float = 0.0  # coefficient of restitution, in [0, 1]
    rolling_friction: float = 0.0  # m: resisting torque = rolling_friction * normal force
    torsional_friction: float = 0.0  # m: torque about the normal = this * normal force (3D only)


# -- bodies ---------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Body:
    """One rigid body at t = 0. See the module docstring for frames and conventions."""

    name: str
    shape: Shape
    mass: float
    com: np.ndarray  # centre of mass in the body frame, (3,) or (2,)
    inertia: np.ndarray  # about the centre of mass in the body frame: (3, 3), or (1, 1) in 2D
    position: np.ndarray  # world position of the body-frame origin
    orientation: np.ndarray  # 3D: quaternion (w, x, y, z); 2D: array([angle])
    velocity: np.ndarray  # of the centre of mass, world frame
    angular_velocity: np.ndarray  # world frame; 2D: array([omega])
    material: Material
    mass_source: str = "given"  # "given" | "density"
    inertia_source: str = "shape"  # "shape" | "given"

    @property
    def dimension(self) -> int:
        return len(self.position)

    @property
    def angle(self) -> float:
        """2D orientation angle in radians."""
        return float(self.orientation[0])

    @property
    def moment(self) -> float:
        """2D moment of inertia about the centre of mass."""
        return float(self.inertia[0, 0])

    def rotation(self) -> np.ndarray:
        """Rotation matrix of the body frame at t = 0 (3x3, or 2x2 in 2D)."""
        from crosscheck.rotations import angle_to_matrix, quat_to_matrix

        if self.dimension == 2:
            return angle_to_matrix(self.angle)
        return quat_to_matrix(self.orientation)

    def com_world(self) -> np.ndarray:
        """Centre of mass in world coordinates at t = 0."""
        return self.position + self.rotation() @ self.com

    def inertia_world(self) -> np.ndarray:
        """Inertia tensor about the centre of mass in world axes at t = 0 (3D)."""
        r = self.rotation()
        return r @ self.inertia @ r.T


# -- effects --------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Spring:
    """Linear spring-damper between two attachment points.

    Force on body a: ``-(k (l - rest_length) + c dl/dt) * e`` with ``e`` the unit vector from the
    point on b to the point on a, ``l`` their distance. Body b gets the opposite force; the torque
    of each follows from its attachment point relative to its centre of mass.
    """

    body_a: int  # body index
    attach_a: np.ndarray  # body-frame point on a
    body_b: int | None  # body index, or None for a world anchor
    attach_b: np.ndarray  # body-frame point on b, or the world anchor point
    stiffness: float  # N/m
    damping: float  # N s/m along the spring axis
    rest_length: float  # m


@dataclass(frozen=True)
class Drag:
    """Linear viscous drag: F = -linear * v (of the centre of mass), tau = -angular * omega."""

    linear: float  # N s/m
    angular: float  # N m s
    bodies: tuple[int, ...]  # indices the drag applies to


@dataclass(frozen=True)
class Load:
    """A constant force at the centre of mass and a constant torque, both in the world frame."""

    body: int
    force: np.ndarray
    torque: np.ndarray  # (3,) in 3D, (1,) in 2D


@dataclass(frozen=True)
class Medium:
    """A quiescent medium the bodies of a 3D rigid scene move through (``[effects] medium``).

    It exchanges energy with the bodies: buoyancy ``-density V g`` at each body's centre of
    buoyancy (V the shape's volume), and a drag whose law is the engine's own model (MuJoCo's
    inertia-box or ellipsoid fluid model; docs/engines.md). Only engines that model a medium run
    such a scene.
    """

    density: float = 0.0  # kg/m^3
    viscosity: float = 0.0  # Pa s (dynamic viscosity)


@dataclass(frozen=True)
class Effects:
    """Only what is listed here is simulated, in every engine."""

    gravity: np.ndarray | None = None  # None: no gravity at all
    springs: tuple[Spring, ...] = ()
    drag: tuple[Drag, ...] = ()
    loads: tuple[Load, ...] = ()
    contact: bool = False  # reserved for the contact issue
    fluid: bool = False  # set when the scene has a [fluid] domain
    medium: Medium | None = None  # a quiescent medium (3D rigid scenes only)

    def names(self) -> tuple[str, ...]:
        """The effect names the scene calls for, as engines declare them in capabilities."""
        out = []
        if self.gravity is not None:
            out.append("gravity")
        if self.springs:
            out.append("springs")
        if self.drag:
            out.append("drag")
        if self.loads:
            out.append("loads")
        if self.contact:
            out.append("contact")
        if self.fluid:
            out.append("fluid")
        if self.medium is not None:
            out.append("medium")
        return tuple(out)

    def gravity_vector(self, dimension: int) -> np.ndarray:
        return np.zeros(dimension) if self.gravity is None else self.gravity


@dataclass(frozen=True)
class Ground:
    """A static plane: points p with normal . p = offset are on it; the normal points out of it."""

    normal: np.ndarray
    offset: float
    material: Material


@dataclass(frozen=True)
class Static:
    """Fixed geometry beyond the ground plane, placed like a body's body frame: the shape in its
    own frame, then ``position`` and ``orientation`` (the conventions of :class:`Body`)."""

    name: str
    shape: Shape
    position: np.ndarray  # world position of the shape's frame origin
    orientation: np.ndarray  # 3D: quaternion (w, x, y, z); 2D: array([angle])
    material: Material

    def placed(self) -> Placed:
        """The shape at its pose, answering geometric queries in world coordinates."""
        return Placed(self.shape, self.position, self.orientation)


@dataclass(frozen=True)
class PairOverride:
    """One ``[[contact_pairs]]`` entry: explicit values for one unordered pair of names (a body,
    a static or "ground"); a value left None falls back to the pair rule."""

    index: int  # its position among the [[contact_pairs]] entries, for messages and show
    a: str
    b: str
    friction: float | None = None
    restitution: float | None = None
    rolling_friction: float | None = None
    torsional_friction: float | None = None
    collide: bool = True  # false: the two never touch (a collision filter)


# -- run, reference, tolerances -------------------------------------------------------------------
def whole_steps(duration: float, dt: float) -> int | None:
    """duration / dt when it is a whole number (to 1e-9 relative), else None: a rigid run takes
    exactly this many steps, so a step that does not divide the duration is refused."""
    n = round(duration / dt)
    if n >= 1 and abs(n * dt - duration) <= 1e-9 * duration:
        return int(n)
    return None


def dividing_step(duration: float, dt: float) -> float:
    """``dt`` if it divides ``duration``, else the nearest step that does."""
    return dt if whole_steps(duration, dt) is not None else duration / max(1, round(duration / dt))


@dataclass(frozen=True)
class RunSettings:
    duration: float  # s
    dt: float  # default step, s
    sample_every: float  # recording interval of the Trajectory, s
    engines: tuple[str, ...]
    integrators: dict[str, tuple[str, ...]]  # engine -> integrator names (empty: engine default)
    timeout: float = 600.0  # wall seconds one cell may take before it is reported as a hang

    def sample_times(self) -> np.ndarray:
        """The sample times of a run at ``dt`` (engines.base.sampling_plan): every
        round(sample_every / dt) steps, and the duration itself."""
        steps = max(1, int(round(self.sample_every / self.dt)))
        total = int(round(self.duration / self.dt))
        marks = list(range(0, total + 1, steps))
        if marks[-1] != total:
            marks.append(total)
        return np.array(marks, dtype=np.int64) * self.dt

    def n_samples(self) -> int:
        return len(self.sample_times())


@dataclass(frozen=True)
class UserTable:
    """A case's own reference data (``reference.file``), read and checked by the loader
    (crosscheck.scene.user_table). ``axis`` is the first column: "t" (a time series) or "x" / "y"
    (a fluid profile along the line at the other coordinate ``line``, m). ``columns`` holds every
    column, the axis included, SI units. ``body``: the body a rigid series describes."""

    path: Path
    axis: str
    columns: dict[str, np.ndarray]
    line: float | None = None
    body: int | None = None
    source: tuple[str, ...] = ()

    @property
    def compared(self) -> tuple[str, ...]:
        return tuple(c for c in self.columns if c != self.axis)


@dataclass(frozen=True)
class Reference:
    """What a trajectory is compared with.

    kind: "analytic" (``solution`` names a function in crosscheck.reference), "table" (a published
    data set named by ``table``, or the case's own CSV ``file``, read into ``data``), "fine-step"
    (``engine``/``integrator`` at step ``dt``), "engine" (another engine's run at the same step),
    or "none".
    """

    kind: str = "none"
    solution: str | None = None
    table: str | None = None
    file: str | None = None
    # compare=False: arrays have no truth value, and the file's name already tells tables apart
    data: UserTable | None = field(default=None, compare=False)
    engine: str | None = None
    integrator: str | None = None
    dt: float | None = None
    params: dict[str, Any] = field(default_factory=dict)


@dataclass(frozen=True)
class Tolerance:
    """Threshold on one metric: a default, overridden by integrator, engine or 'engine.integrator'.

    The most specific entry wins: ``engine.integrator`` > ``integrator`` > ``engine`` > default.
    A metric passes when ``value <= limit``.
    """

    metric: str
    default: float | None
    overrides: dict[str, float] = field(default_factory=dict)

    def limit(self, engine: str, integrator: str) -> float | None:
        for key in (f"{engine}.{integrator}", integrator, engine):
            if key in self.overrides:
                return self.overrides[key]
        return self.default


# -- the scene ------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Scene:
    name: str
    description: str
    tags: tuple[str, ...]
    dimension: int  # 2 or 3
    run: RunSettings
    effects: Effects
    bodies: tuple[Body, ...]
    ground: Ground | None
    materials: dict[str, Material]
    reference: Reference
    tolerances: dict[str, Tolerance]
    engine_options: dict[str, dict[str, Any]]  # engine -> options pinned by the case
    fluid: Any = None  # crosscheck.scene.fluid.FluidSpec, or None for rigid scenes
    statics: tuple[Static, ...] = ()  # fixed geometry besides the ground (contact cases only)
    pair_overrides: tuple[PairOverride, ...] = ()  # the [[contact_pairs]] entries
    source: Path | None = None  # the case file
    source_sha256: str | None = None

    @property
    def body_names(self) -> tuple[str, ...]:
        return tuple(b.name for b in self.bodies)

    def body_index(self, name: str) -> int:
        return self.body_names.index(name)

    @property
    def masses(self) -> np.ndarray:
        return np.array([b.mass for b in self.bodies])

    def integrators_for(self, engine: str) -> tuple[str, ...]:
        return self.run.integrators.get(engine, ())

    @property
    def static_names(self) -> tuple[str, ...]:
        return tuple(s.name for s in self.statics)

    def pair_material(self, a: str, b: str):
        """The values every engine is given for contact between a and b (a body, a static or
        "ground"): :func:`crosscheck.scene.contact.pair_material`."""
        from crosscheck.scene.contact import pair_material

        return pair_material(self, a, b)

    def contact_pairs(self):
        """Every pair that can touch, with its values: :func:`crosscheck.scene.contact.pairs`."""
        from crosscheck.scene.contact import pairs

        return pairs(self)
