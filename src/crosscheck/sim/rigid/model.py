"""RigidModel: a Scene compiled once into arrays; RigidState: the time-varying arrays.

The model is static (masses, body-frame inertia and its inverse, principal axes, centre-of-mass
offsets, the effect arrays); the state is the Baraff state of every body as structure-of-arrays:

* 3D: ``x`` (N, 3) centre of mass, world; ``q`` (N, 4) unit quaternion (w, x, y, z) of the
  *declared body frame*; ``P`` (N, 3) linear momentum; ``L`` (N, 3) angular momentum about the
  centre of mass, world.  I(t) = R I_body R^T, omega = I(t)^-1 L, dq/dt = 1/2 (0, omega) q.
* 2D (the planar specialisation): ``x`` (N, 2), ``angle`` (N,), ``P`` (N, 2), ``L`` (N,).

Each effect is compiled into its own small NamedTuple of arrays, or ``None`` when the scene does
not declare it. The numba kernels take the effects as separate arguments and test ``is None``;
numba prunes those branches at compile time for a ``None`` argument, so the compiled step of a
scene holds the code of its declared effects only (see forces3d.accumulate and
benchmarks/bench_rigid.py, which measures that an undeclared effect costs nothing).

Spring attachment points are stored relative to the centre of mass (``attach - com``), in the body
frame: the kernels rotate them with the body, so a centre of mass off the body-frame origin and
an inertia tensor not aligned with the body frame are handled without special cases.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

from crosscheck.scene.model import Scene

EFFECT_ORDER = ("gravity", "springs", "drag", "loads")


# -- numba-facing arrays (NamedTuples of contiguous float64 / int64 arrays) -----------------------
class Bodies3D(NamedTuple):
    mass: np.ndarray  # (N,)
    inv_mass: np.ndarray  # (N,)
    inertia: np.ndarray  # (N, 3, 3) about the centre of mass, body frame
    inv_inertia: np.ndarray  # (N, 3, 3)
    principal_moments: np.ndarray  # (N, 3), ascending
    principal_axes: np.ndarray  # (N, 3, 3), column k is the body-frame axis of moment k
    com: np.ndarray  # (N, 3) centre of mass in the body frame


class Bodies2D(NamedTuple):
    mass: np.ndarray  # (N,)
    inv_mass: np.ndarray  # (N,)
    moment: np.ndarray  # (N,) about the centre of mass
    inv_moment: np.ndarray  # (N,)
    com: np.ndarray  # (N, 2) centre of mass in the body frame


class Springs(NamedTuple):
    """S springs. ``b < 0`` marks a world anchor; then ``rb`` is the anchor point (world)."""

    a: np.ndarray  # (S,) int64
    b: np.ndarray  # (S,) int64, -1 for a world anchor
    ra: np.ndarray  # (S, d) attachment on a minus a's centre of mass, body frame of a
    rb: np.ndarray  # (S, d) attachment on b minus b's centre of mass (body frame), or the anchor
    stiffness: np.ndarray  # (S,)
    damping: np.ndarray  # (S,)
    rest_length: np.ndarray  # (S,)


class Drag(NamedTuple):
    """Per-body coefficients, summed over the scene's drag entries (zero for bodies not listed)."""

    linear: np.ndarray  # (N,) N s/m
    angular: np.ndarray  # (N,) N m s


class Loads(NamedTuple):
    """K constant loads at centres of mass, world frame."""

    body: np.ndarray  # (K,) int64
    force: np.ndarray  # (K, d)
    torque: np.ndarray  # (K, 3) in 3D, (K,) in 2D


class Control(NamedTuple):
    """Per-body external wrenches for the next step(s), world frame, at the centres of mass:
    written each step by whoever drives the model (coupling, motors), read by the force pass
    after the scene's own effects. Passed to the kernels as an argument that is ``None`` when
    there is none, so a control-free step holds no control code (numba prunes the branch)."""

    force: np.ndarray  # (N, d)
    torque: np.ndarray  # (N, 3) in 3D, (N,) in 2D

    @classmethod
    def zeros(cls, model: RigidModel) -> Control:
        n, d = model.n_bodies, model.dimension
        return cls(np.zeros((n, d)), np.zeros((n, 3)) if d == 3 else np.zeros(n))


# The contact model's slot: the kernels take a ``contacts`` argument after ``control``; it is
# always None today (no contact code reads it) and each integrator's ``contact`` flag
# (crosscheck.names) says whether it may be given one.


# The kernels' gravity argument of a scene without gravity (RigidModel.kernel_args). Never
# written, but not flagged read-only: numba types a read-only array apart from a writable one,
# which would bring back the second specialisation this exists to avoid.
NO_GRAVITY = np.zeros(0)


@dataclass(frozen=True)
class RigidModel:
    """The compiled scene: what the kernels read and never write."""

    dimension: int
    bodies: Bodies3D | Bodies2D
    gravity: np.ndarray | None
    springs: Springs | None
    drag: Drag | None
    loads: Loads | None
    body_names: tuple[str, ...] = ()

    @property
    def n_bodies(self) -> int:
        return len(self.bodies.mass)

    @property
    def effects(self) -> tuple[str, ...]:
        """The effects compiled into the step, in kernel order."""
        present = {"gravity": self.gravity, "springs": self.springs, "drag": self.drag,
                   "loads": self.loads}
        return tuple(name for name in EFFECT_ORDER if present[name] is not None)

    def kernel_args(self) -> tuple:
        """(bodies, gravity, springs, drag, loads): the leading arguments of every kernel.

        A scene without gravity passes :data:`NO_GRAVITY` (a zero-length array, which
        ``evaluate`` tests at run time), not None. Every other undeclared effect is None and
        compiled out, but gravity costs one multiply-add per body and force pass, while a
        second specialisation on its absence compiles every kernel of a contact model a second
        time: about a sixth of the test suite's cold compile time (docs/inhouse.md, "Compile time").
        The results are bit-identical either way: the skipped gravity is skipped."""
        gravity = NO_GRAVITY if self.gravity is None else self.gravity
        return (self.bodies, gravity, self.springs, self.drag, self.loads)

    def without(self, *effects: str) -> RigidModel:
        """The same model with some effects left out (benchmarks and tests)."""
        unknown = set(effects) - set(EFFECT_ORDER)
        if unknown:
            raise ValueError(f"unknown effects {sorted(unknown)}; known: {EFFECT_ORDER}")
        kw = {name: None for name in effects}
        return RigidModel(self.dimension, self.bodies, kw.get("gravity", self.gravity),
                          kw.get("springs", self.springs), kw.get("drag", self.drag),
                          kw.get("loads", self.loads), self.body_names)


@dataclass
class RigidState:
    """The Baraff state. 3D: ``rot`` is q (N, 4); 2D: ``rot`` is the angle (N,)."""

    x: np.ndarray
    rot: np.ndarray
    P: np.ndarray
    L: np.ndarray
    meta: dict = field(default_factory=dict)

    @property
    def q(self) -> np.ndarray:
        return self.rot

    @property
    def angle(self) -> np.ndarray:
        return self.rot

    def arrays(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        return (self.x, self.rot, self.P, self.L)

    def copy(self) -> RigidState:
        return RigidState(self.x.copy(), self.rot.copy(), self.P.copy(), self.L.copy(),
                          dict(self.meta))

    def is_finite(self) -> bool:
        return all(bool(np.all(np.isfinite(a))) for a in self.arrays())

    # -- flat vector (solve_ivp and other generic ODE tools) --------------------------------
    def flat(self) -> np.ndarray:
        return np.concatenate([a.ravel() for a in self.arrays()])

    @classmethod
    def from_flat(cls, y: np.ndarray, n_bodies: int, dimension: int) -> RigidState:
        y = np.asarray(y, float)
        d, r = (3, 4) if dimension == 3 else (2, 1)
        sizes = [n_bodies * d, n_bodies * r, n_bodies * d, n_bodies * (3 if dimension == 3 else 1)]
        parts = np.split(y, np.cumsum(sizes)[:-1])
        if dimension == 3:
            return cls(parts[0].reshape(n_bodies, 3).copy(), parts[1].reshape(n_bodies, 4).copy(),
                       parts[2].reshape(n_bodies, 3).copy(), parts[3].reshape(n_bodies, 3).copy())
        return cls(parts[0].reshape(n_bodies, 2).copy(), parts[1].copy(),
                   parts[2].reshape(n_bodies, 2).copy(), parts[3].copy())


# -- compiling a Scene --------------------------------------------------------------------------
def _f64(a, shape=None) -> np.ndarray:
    out = np.ascontiguousarray(np.array(a, dtype=np.float64, copy=True))
    return out.reshape(shape) if shape is not None else out


def compile_model(scene: Scene) -> RigidModel:
    """Compile the scene's bodies and declared effects into arrays, once."""
    d = scene.dimension
    if d not in (2, 3):
        raise ValueError(f"dimension must be 2 or 3, got {d}")
    n = len(scene.bodies)
    mass = _f64([b.mass for b in scene.bodies], (n,))
    com = _f64([np.asarray(b.com, float) for b in scene.bodies], (n, d))
    if d == 3:
        inertia = _f64([np.asarray(b.inertia, float) for b in scene.bodies], (n, 3, 3))
        inertia = 0.5 * (inertia + np.transpose(inertia, (0, 2, 1)))  # exact symmetry
        moments, axes = np.linalg.eigh(inertia)
        # Right-handed principal frames, so a rotation about column k is a proper rotation.
        flip = np.linalg.det(axes) < 0
        axes[flip, :, 2] *= -1.0
        bodies: Bodies3D | Bodies2D = Bodies3D(
            mass=mass, inv_mass=1.0 / mass, inertia=inertia,
            inv_inertia=_f64(np.linalg.inv(inertia)), principal_moments=_f64(moments),
            principal_axes=_f64(axes), com=com)
    else:
        moment = _f64([float(np.asarray(b.inertia).reshape(-1)[0]) for b in scene.bodies], (n,))
        bodies = Bodies2D(mass=mass, inv_mass=1.0 / mass, moment=moment, inv_moment=1.0 / moment,
                          com=com)

    eff = scene.effects
    gravity = None if eff.gravity is None else _f64(eff.gravity, (d,))

    springs = None
    if eff.springs:
        ra, rb, a_idx, b_idx = [], [], [], []
        for s in eff.springs:
            a_idx.append(s.body_a)
            ra.append(np.asarray(s.attach_a, float) - com[s.body_a])
            if s.body_b is None:
                b_idx.append(-1)
                rb.append(np.asarray(s.attach_b, float))
            else:
                b_idx.append(s.body_b)
                rb.append(np.asarray(s.attach_b, float) - com[s.body_b])
        springs = Springs(
            a=np.array(a_idx, dtype=np.int64), b=np.array(b_idx, dtype=np.int64),
            ra=_f64(ra, (len(ra), d)), rb=_f64(rb, (len(rb), d)),
            stiffness=_f64([s.stiffness for s in eff.springs]),
            damping=_f64([s.damping for s in eff.springs]),
            rest_length=_f64([s.rest_length for s in eff.springs]))

    drag = None
    if eff.drag:
        lin = np.zeros(n)
        ang = np.zeros(n)
        for entry in eff.drag:
            for i in entry.bodies:
                lin[i] += entry.linear
                ang[i] += entry.angular
        drag = Drag(linear=lin, angular=ang)

    loads = None
    if eff.loads:
        k = len(eff.loads)
        torque_shape = (k, 3) if d == 3 else (k,)
        loads = Loads(
            body=np.array([ld.body for ld in eff.loads], dtype=np.int64),
            force=_f64([ld.force for ld in eff.loads], (k, d)),
            torque=_f64([np.asarray(ld.torque, float).reshape(-1) for ld in eff.loads],
                        torque_shape))
    return RigidModel(d, bodies, gravity, springs, drag, loads, scene.body_names)


def state_from_scene(model: RigidModel, scene: Scene) -> RigidState:
    """The Baraff state at t = 0 from the scene's bodies (centre of mass, P = m v, L = I w)."""
    n, d = model.n_bodies, model.dimension
    x = _f64([b.com_world() for b in scene.bodies], (n, d))
    P = model.bodies.mass[:, None] * _f64([b.velocity for b in scene.bodies], (n, d))
    if d == 3:
        q = _f64([b.orientation for b in scene.bodies], (n, 4))
        q /= np.linalg.norm(q, axis=1, keepdims=True)
        L = _f64([b.inertia_world() @ np.asarray(b.angular_velocity, float)
                  for b in scene.bodies], (n, 3))
        return RigidState(x, q, P, L)
    angle = _f64([b.angle for b in scene.bodies], (n,))
    L = model.bodies.moment * _f64([float(b.angular_velocity[0]) for b in scene.bodies], (n,))
    return RigidState(x, angle, P, L)
