"""PyBullet adapter: one DIRECT client per run, every body built from the Scene.

Model (docs/engines.md, section PyBullet, has the measurements behind each choice)
----------------------------------------------------------------------------------
* A 3D body is the base of its own ``createMultiBody``: the link frame is the declared body frame
  (``basePosition`` / ``baseOrientation``), the inertial frame sits at ``Body.com`` with the
  orientation of the principal axes ``V`` (``I_body = V diag(moments) V^T``, ``det V = +1``), and
  the principal moments go in through ``changeDynamics(mass=m, localInertiaDiagonal=moments)``:
  ``createMultiBody`` has no full-tensor argument. The mass is passed again on purpose: for a
  maximal-coordinate body ``localInertiaDiagonal`` alone sets the mass to 0 (a static body).
* Without contact: no collision shape, collision filter group and mask 0, nothing collides (with
  contact: docs/engines.md, PyBullet, "Contact"; ``_build_contact``). The pair values are
  factored into per-surface values over groups of interchangeable surfaces (material classes,
  ``surface_groups``), never over the N^2 surface pairs (``contact_plan``).
* Reading: ``getBasePositionAndOrientation`` gives the centre of mass and the orientation of the
  *inertial* frame; the declared frame's orientation is ``q_inertial * conj(q_V)``.
  ``getBaseVelocity`` gives the centre-of-mass velocity and the angular velocity, both world.
* Stepping and reading go through PyBullet's public Python API only (``stepSimulation``, one
  ``getBasePositionAndOrientation`` and one ``getBaseVelocity`` per body and sample); the run
  driver (engines/driver.py) records and times it like every engine.
* ``createMultiBody`` places the link frame, ``resetBasePositionAndOrientation`` the inertial frame
  (ENGINES.md trap 2): the adapter places bodies with the former and restores the pose PyBullet
  itself reported with the latter.

Integrators (PyBullet's two kinds of body; both semi-implicit Euler on the velocities):

* ``multibody`` (``useMaximalCoordinates=False``, PyBullet's default): Featherstone btMultiBody,
  gyroscopic term explicit (a tumbling body gains energy, ENGINES.md trap 7).
* ``maximal`` (``useMaximalCoordinates=True``): btRigidBody, gyroscopic term implicit (loses).

Neutralised and read back into ``meta["effective"]``: damping (multibody default 0.04, trap 1),
the multibody velocity clamp (``maxJointVelocity``, trap 5), sleeping, gravity, the time step and
the process-global contact breaking threshold (trap 10). PyBullet's ``getDynamicsInfo`` does not
return damping, activation state or the clamp, so the adapter measures them: one force-free probe
step at 150 m/s and 150 rad/s must leave every velocity unchanged, else the run is a failure.
A second step at rest follows: a maximal-coordinate body caches its world inverse inertia
from its last step, and neither changeDynamics nor a pose reset refreshes it.

2D scenes run in 3D in the x-y plane (y up):

* ``multibody``: a fixed base with prismatic x, prismatic y and revolute z joints through the
  centre of mass: the plane is exact; the joint coordinates are the centre of mass and the angle.
* ``maximal``: a free rigid body with the in-plane state, projected back (no planar joint exists
  for a maximal-coordinate body); it carries the isotropic inertia (I, I, I), so the gyroscopic
  term vanishes and nothing pushes it out of the plane. Contact would: 2D contact is the chain's
  only (``contact_plan``, ``MAXIMAL_2D_CONTACT``).
* Contact: each 2D shape is a prism along z on the chain's last link, the ground line a plane
  containing z (``contact_plan``; docs/engines.md, PyBullet, "Contact").

Either way the out-of-plane drift is read from PyBullet and kept in ``extras``:
``out_of_plane`` (T, N) the centre of mass' z (m), ``out_of_plane_tilt`` (T, N) the angle between
the body z axis and the world z axis (rad), ``out_of_plane_omega`` (T, N) |(omega_x, omega_y)|.

Springs, drag and loads are applied before every step from the state at the start of the step
(``applyExternalForce`` / ``applyExternalTorque`` in WORLD_FRAME at the centre of mass; 2D
multibody: generalised forces through ``TORQUE_CONTROL`` on the three joints). The force law is
the in-house simulator's (``accumulate_rows`` of sim/rigid's forces3d / forces2d: the 3D law
on the inertial frame PyBullet reports, the 2D law on the planar joints' coordinates). PyBullet
then does ``v += h a(x_n, v_n); x += h v_{n+1}``: symplectic Euler for springs, explicit in the
velocity for damping and drag. PyBullet clears applied forces after every step.
"""

from __future__ import annotations

import functools
import importlib.metadata
import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from crosscheck.engines.base import Capabilities, EngineBase
from crosscheck.engines.session import StepFailure
from crosscheck.errors import CaseError
from crosscheck.names import rigid_names
from crosscheck.rotations import matrix_to_quat, quat_conj, quat_mul, quat_to_matrix
from crosscheck.scene.model import Scene

try:  # a missing or broken pybullet makes this engine "not applicable", not an import error
    import pybullet as _p
except Exception:  # pragma: no cover
    _p = None

INTEGRATORS: tuple[str, ...] = rigid_names("pybullet")  # crosscheck.names holds them

INTEGRATOR_NOTES = {
    "multibody": "btMultiBody (Featherstone), semi-implicit Euler: v += h a(x_n, v_n), then "
                 "x += h v_{n+1}; gyroscopic term explicit (a tumbling body gains energy); "
                 "orientation by the exponential map, rotation per step capped at pi/4 rad",
    "maximal": "btRigidBody (useMaximalCoordinates), semi-implicit Euler; gyroscopic term "
               "implicit (one Newton step: a tumbling body loses energy); orientation by the "
               "exponential map, rotation per step capped at pi/4 rad",
}

# PyBullet clamps every multibody velocity component to maxJointVelocity (default 100) without
# warning. Lifted entirely: any finite cap also hides a blow-up (measured with a cap of 1e30: an
# unstable spring froze at |x| ~ 1e27 instead of overflowing to a reported non-finite state).
MAX_COORDINATE_VELOCITY = math.inf
# Bullet's own default (gContactBreakingThreshold). The value is global to the process and
# survives a new connection (ENGINES.md trap 10): set on every run so no earlier run leaks in.
CONTACT_BREAKING_THRESHOLD = 0.02
# Bullet's btTransformUtil / btMultiBody cap the rotation integrated in one step at
# ANGULAR_MOTION_THRESHOLD = pi/4 while keeping the velocity: faster spins rotate too little.
MAX_ROTATION_PER_STEP = 0.25 * math.pi
# The force-free probe step: above the default clamp of 100 per component.
PROBE_SPEED = 150.0
PROBE_SPIN = 150.0
# Relative velocity change the probe tolerates: round-off of one step is ~1e-15; the default
# damping would show 0.04 * 151 * dt (6e-3 at dt = 1e-3), the clamp a third.
PROBE_TOLERANCE = 1e-9

# Engine options a case may pin in [engine_options.pybullet]: name -> (check, default, meaning).
OPTIONS: dict[str, tuple[str, Any]] = {
    "solver_iterations": ("a positive integer", None),
    # "defaults": contact scenes keep Bullet's contact parameters and iteration count (the pair
    # values and geometry stay the adapter's): the comparison row of benchmarks/contact_pybullet
    "contact_parameters": ('"recipe" or "defaults"', "recipe"),
}

_SHAPES = ("sphere", "box", "capsule", "cylinder", "mesh", "circle", "polygon")

# Contact (docs/engines.md, PyBullet, "Contact"; measured in benchmarks/contact_pybullet.py).
# Bullet clamps a combined friction to [-10, 10] (btManifoldResult, MAX_FRICTION).
MAX_FRICTION = 10.0
# Solver iterations for a contact scene whose largest body mass ratio reaches HEAVY_RATIO
# (CONTACTS.md C18: 100 kg on 1 kg sinks 0.215 mm with PyBullet's 50, 0.034 mm with 200).
HEAVY_RATIO = 100.0
CONTACT_ITERATIONS_HEAVY = 200
# The impact recipe (every colliding pair e > 0), set with setPhysicsEngineParameter; none of
# these is readable back through getPhysicsEngineParameters in pybullet 3.2.7.
IMPACT_PARAMETERS = {"restitutionVelocityThreshold": 0.0, "contactSlop": 0.0, "contactERP": 0.0,
                     "warmStartingFactor": 0.0}
# A per-surface value must reproduce every pair's value to this relative error (round-off of
# exp / log and one product).
PAIR_TOLERANCE = 1e-12
# Why a maximal-coordinate 2D body cannot run contact, measured through the adapter with this
# refusal lifted (benchmarks/contact_pybullet_2d.py; None lifts it, for that measurement only).
MAXIMAL_2D_CONTACT: str | None = (
    "2D contact needs the planar chain (integrator multibody): a maximal-coordinate body has no "
    "joint holding it in the plane, and Bullet puts the contact points of a prism on the ground "
    "or on a circle on one face of the prism (z = +depth), so contact tilts it out of the "
    "plane. Measured through the adapter with this refusal lifted (contact cases, dt = 1e-3; "
    "cradle 1e-4): the elastic circle tumbles (tilt 3.1 rad, z 2.7 m, apex error 27 %), the "
    "box on the 35 degree incline tilts 0.71 rad (mu_eff off by 0.016), the billiard circles "
    "tilt 0.56 rad and their momentum transfer is 8.3 % off, the cradle's velocities 0.31 "
    "m/s off, the sliding box tilts 0.064 rad and stops 2.6 % short, the slipping disk's "
    "spin is 0.23 rad/s off; no prism depth from 0.1 to 10 times the adapter's avoids it. The "
    "multibody chain stays in the plane exactly (benchmarks/contact_pybullet_2d.py)")


def factor_pairs(items: list[str], pairs: list[tuple], what: str,
                 sizes: dict[str, int] | None = None
                 ) -> tuple[dict[str, float], str | None]:
    """Per-item values ``f`` with ``f[a] * f[b] == value`` for every pair (Bullet's product
    rule), or the reason none exist.

    Zeros first: an item all of whose pairs are 0 gets 0 (it then zeroes only pairs that are 0
    anyway); a pair of 0 whose two items both have a positive pair cannot be a product. The
    positive pairs are solved in log space (least squares, minimum norm: a body alone on the
    ground gets sqrt(value) on both, CONTACTS.md's recipe) and every pair is checked to
    ``PAIR_TOLERANCE``: a set of pair values that does not factor (e.g. a-b 0.3, b-c 0.3,
    a-c 0.5 with a-b-c a triangle) is reported with the pair that misses.

    A pair is ``(a, b, value)``, or ``(a, b, value, count, shown)`` when the items are groups
    of interchangeable surfaces (``surface_groups``): ``sizes[item]`` surfaces each, the pair
    standing for ``count`` surface pairs, named ``shown`` in a reason. The least squares is then
    weighted so that it is the one over the surfaces themselves (each row weighted by its count,
    the norm by the group sizes: z = sqrt(size) log f), whose minimum-norm solution gives
    interchangeable surfaces equal values: the same factors as solving per surface, at the cost
    of the groups (with groups of one surface and one pair each, the very same matrix).
    """
    sizes = sizes or {}
    pairs = [(*q, 1, (q[0], q[1])) if len(q) == 3 else tuple(q) for q in pairs]
    out = {name: 1.0 for name in items}
    positive: dict[str, bool] = {name: False for name in items}
    for a, b, v, _, _ in pairs:
        if v > 0:
            positive[a] = positive[b] = True
    for name in items:
        if not positive[name]:
            out[name] = 0.0
    for a, b, v, _, (sa, sb) in pairs:
        if v == 0 and positive[a] and positive[b]:
            return out, (f"{what} 0 on pair {sa!r}-{sb!r} is not a product of per-surface "
                         f"values: both surfaces have pairs with {what} > 0")
    pos = [q for q in pairs if q[2] > 0]
    if pos:
        order = {n: i for i, n in enumerate(items)}
        names = sorted({n for a, b, *_ in pos for n in (a, b)}, key=order.__getitem__)
        col = {n: i for i, n in enumerate(names)}
        scale = {n: math.sqrt(sizes.get(n, 1)) for n in names}  # x = z / sqrt(size)
        m = np.zeros((len(pos), len(names)))
        rhs = np.empty(len(pos))
        for k, (a, b, v, count, _) in enumerate(pos):
            w = math.sqrt(count)  # a row standing for count equal rows
            m[k, col[a]] += w / scale[a]
            m[k, col[b]] += w / scale[b]
            rhs[k] = w * math.log(v)
        z = np.linalg.lstsq(m, rhs, rcond=None)[0]
        for n in names:
            out[n] = math.exp(float(z[col[n]]) / scale[n])
        for a, b, v, _, (sa, sb) in pos:
            got = out[a] * out[b]
            if abs(got - v) > PAIR_TOLERANCE * v:
                return out, (f"the pair values of {what} do not factor into per-surface values "
                             f"(Bullet multiplies them): pair {sa!r}-{sb!r} wants {v:g}, the best "
                             f"factors give {got:.6g}")
    return out, None


@dataclass(frozen=True)
class GroupPair:
    """Two surface groups that can touch (``surface_groups``): ``count`` surface pairs, all with
    the values ``material``; ``a``-``b`` the first of them in ``Scene.contact_pairs()`` order
    (the one a reason names, as when every pair was checked)."""

    g: int
    h: int
    count: int
    a: str
    b: str
    kind: str  # the kind of the pair a-b: "body-body", "body-static" or "body-ground"
    material: Any  # PairMaterial


def surface_groups(scene: Scene):
    """The surfaces of a contact scene in groups whose members are interchangeable for Bullet:
    the material classes (``scene.contact.material_classes``), whose members have the same
    pairs and the same values (a class is all bodies or all fixed surfaces). Returns (classes,
    groups, group pairs): the groups are the classes' members (bodies first); the group pairs
    are the class pairs that hold at least one pair that can touch, in the order of their first
    pair in ``Scene.contact_pairs()``. Their number grows with the number of classes, not of
    bodies.
    """
    from crosscheck.scene.contact import GROUND, material_classes

    classes = material_classes(scene)
    pos = {name: i for i, name in enumerate(classes.surfaces)}
    out = []
    for g, h in classes.class_pairs():
        a, b = next(classes.pairs_between(g, h))  # g <= h: a body (bodies' classes come first)
        kind = ("body-body" if not classes.fixed_class(h) else
                "body-ground" if b == GROUND else "body-static")
        out.append(GroupPair(g, h, classes.count(g, h), a, b, kind, classes.values[g][h]))
    rank = {"body-body": 0, "body-static": 1, "body-ground": 2}
    out.sort(key=lambda q: (rank[q.kind], pos[q.a], pos[q.b]))
    return classes, classes.members, out


def contact_plan(scene: Scene, integrator: str | None = None
                 ) -> tuple[dict[str, Any] | None, str | None]:
    """What the adapter gives Bullet for a contact scene, or why it cannot (not applicable).

    ``kind``: "resting" when every colliding pair has restitution 0 (CONTACTS.md recipe 6(a),
    friction / resting / stacks: default contact parameters), "impact" when every one has
    restitution > 0 (restitution threshold, slop, processing threshold, contact ERP and warm
    starting 0); a mix is not applicable (C12). ``friction`` / ``restitution``: per surface
    (body, static, "ground"), each pair's value their product. ``groups`` / ``group_pairs``
    (``surface_groups``): the checks and the factoring run over the group pairs, whose number
    does not grow with the number of bodies (a pile of N bodies of one material is a handful),
    not over the N^2 surface pairs; the per-surface values are the factoring over the surfaces
    themselves (``factor_pairs``). ``filtered``: the surface pairs of ``collide = false``.

    2D: every shape is a prism along z, ``extrusion_half_depth`` either side of the plane (a
    circle a cylinder, a box a box, a polygon the convex hull of its prism), the ground line a
    plane containing z, statics likewise, the pair values factored as in 3D. Only the planar
    chain (``multibody``: prismatic x, prismatic y, revolute z, the prism on the last link, the
    only link that collides) keeps the plane exact: the moments about x and y of contact points
    off z = 0 and friction along z fall on no joint. A ``maximal`` 2D body has no joint holding
    it in the plane, and Bullet puts a plane contact's points on one face of the prism (z =
    +depth), so contact tilts it and pushes it out of the plane: not applicable with the
    measured reason (``MAXIMAL_2D_CONTACT``; docs/engines.md, PyBullet, "Contact").
    """
    if scene.dimension == 2 and integrator == "maximal" and MAXIMAL_2D_CONTACT is not None:
        return None, MAXIMAL_2D_CONTACT
    classes, groups, group_pairs = surface_groups(scene)
    colliding = [q for q in group_pairs if q.material.collide]
    for q in colliding:  # in pair order: the first offending group pair names the first pair
        m = q.material
        if m.rolling_friction > 0 or m.torsional_friction > 0:
            what = "rolling" if m.rolling_friction > 0 else "torsional"
            value = m.rolling_friction if m.rolling_friction > 0 else m.torsional_friction
            return None, (f"{what} friction is not mapped for PyBullet (pair {q.a!r}-{q.b!r} "
                          f"has {what}_friction = {value:g} m): Bullet combines it as "
                          "r_a mu_b + r_b mu_a with the lateral frictions "
                          "(btManifoldResult::calculateCombinedRollingFriction), not a product, "
                          "and that mapping was not built or measured")
        if m.friction > MAX_FRICTION:
            return None, (f"pair {q.a!r}-{q.b!r} has friction {m.friction:g}: Bullet clamps a "
                          f"combined friction to {MAX_FRICTION:g}")
    # the groups by their first surface (unique), each standing for len(group) surfaces
    items = [grp[0] for grp in groups]
    sizes = {grp[0]: len(grp) for grp in groups}

    def rows(value: str) -> list[tuple]:
        return [(groups[q.g][0], groups[q.h][0], getattr(q.material, value), q.count,
                 (q.a, q.b)) for q in colliding]

    def per_surface(factors: dict[str, float]) -> dict[str, float]:
        return {name: factors[grp[0]] for grp in groups for name in grp}

    friction, why = factor_pairs(items, rows("friction"), "friction", sizes)
    if why is not None:
        return None, why
    bouncy = [q for q in colliding if q.material.restitution > 0]
    if bouncy and len(bouncy) < len(colliding):
        dead = next(q for q in colliding if q.material.restitution == 0)
        return None, ("mixed restitution: pair "
                      f"{bouncy[0].a!r}-{bouncy[0].b!r} has e = "
                      f"{bouncy[0].material.restitution:g} and pair {dead.a!r}-{dead.b!r} e = 0; "
                      "PyBullet has no one setting for both (CONTACTS.md C12: exact bounces need "
                      "contact ERP 0, which never corrects a resting penetration)")
    restitution, why = factor_pairs(items, rows("restitution"), "restitution", sizes)
    if why is not None:
        return None, why
    masses = [float(b.mass) for b in scene.bodies]
    ratio = max(masses) / min(masses)
    # collide = false comes from [[contact_pairs]] entries only, whose surfaces are classes of
    # their own: one filter per such pair, never per pair of a class
    filtered = [pair for q in group_pairs if not q.material.collide
                for pair in classes.pairs_between(q.g, q.h)]
    return {"kind": "impact" if bouncy else "resting", "friction": per_surface(friction),
            "restitution": per_surface(restitution), "mass_ratio": ratio,
            "iterations": CONTACT_ITERATIONS_HEAVY if ratio >= HEAVY_RATIO else None,
            "groups": groups, "group_pairs": group_pairs, "filtered": filtered}, None


def extrusion_half_depth(scene: Scene) -> float:
    """2D contact: half the z extent of the prisms that stand in for circles, boxes and polygons
    (bodies and statics): the largest in-plane half extent of any of them, MuJoCo's rule
    (``mujoco.extrusion_half_depth``), so both engines collide the same prisms."""
    half = 0.0
    for thing in (*scene.bodies, *scene.statics):
        lo, hi = thing.shape.bounding_box()
        half = max(half, float(np.max(np.abs(np.concatenate([lo, hi])))))
    return half if half > 0 else 1.0


def engine_options(scene: Scene) -> dict[str, Any]:
    """The case's [engine_options.pybullet] checked; unknown keys or bad values are case errors."""
    given = dict(scene.engine_options.get("pybullet", {}))
    out: dict[str, Any] = {key: default for key, (_, default) in OPTIONS.items()}
    for key, value in given.items():
        field = f"engine_options.pybullet.{key}"
        if key not in OPTIONS:
            raise CaseError(scene.source, field,
                            f"one of the PyBullet adapter's options {sorted(OPTIONS)}",
                            f"unknown option {key!r}")
        if key == "solver_iterations":
            if isinstance(value, bool) or not isinstance(value, int) or value < 1:
                raise CaseError(scene.source, field, OPTIONS[key][0], value)
        if key == "contact_parameters" and value not in ("recipe", "defaults"):
            raise CaseError(scene.source, field, OPTIONS[key][0], value)
        out[key] = value
    return out


def _xyzw(q_wxyz: np.ndarray) -> list[float]:
    q = np.asarray(q_wxyz, float)
    return [float(q[1]), float(q[2]), float(q[3]), float(q[0])]


def _wxyz(q_xyzw: np.ndarray) -> np.ndarray:
    q = np.asarray(q_xyzw, float)
    return q[..., [3, 0, 1, 2]]


def principal_axes(inertia: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(moments, V) with inertia = V diag(moments) V^T and V a proper rotation (det +1)."""
    moments, axes = np.linalg.eigh(np.asarray(inertia, float))
    if np.linalg.det(axes) < 0:
        axes[:, 2] *= -1.0
    return moments, axes


def _unwrap_with_rate(raw: np.ndarray, omega: np.ndarray, t: np.ndarray,
                      first: np.ndarray) -> np.ndarray:
    """Unwrap (T, N) angles in (-pi, pi] using the angular velocity to predict each increment.

    np.unwrap assumes less than half a turn between samples; a fast spin sampled coarsely turns
    more. The prediction theta_{i-1} + (omega_{i-1} + omega_i)/2 dt picks the right turn as long
    as it is within half a turn of the truth. ``first`` is the angle sample 0 should be nearest.
    """
    out = np.empty_like(raw)
    if len(raw) == 0:
        return out
    two_pi = 2.0 * math.pi
    out[0] = raw[0] + two_pi * np.round((first - raw[0]) / two_pi)
    for i in range(1, len(raw)):
        guess = out[i - 1] + 0.5 * (omega[i - 1] + omega[i]) * (t[i] - t[i - 1])
        out[i] = raw[i] + two_pi * np.round((guess - raw[i]) / two_pi)
    return out


@dataclass
class _BodyMap:
    """How one scene body sits in the PyBullet world."""

    uid: int
    moments: np.ndarray  # principal moments passed to localInertiaDiagonal
    q_axes: np.ndarray  # (4,) w,x,y,z of V: inertial frame in the body frame
    com3: np.ndarray  # (3,) centre of mass in the body frame (2D: z = 0)


def _force_law(scene: Scene, dim: int, offset) -> tuple[Any, Any, Any, list[int]] | None:
    """The scene's springs, drag and loads as the in-house kernels' arrays (model.Springs, Drag,
    Loads) for the ``dim``-dimensional force law, and the bodies they act on; None if none.

    ``offset(body, point)``: a body-frame attachment point relative to the centre of mass, in
    the frame whose rotation the adapter reads (3D: the inertial frame, see ``_local_offset``;
    planar joints: the body frame, rotated by the joint angle). A 2D scene run with the 3D law
    (maximal bodies) is embedded at z = 0, its load torques about z.
    """
    from crosscheck.sim.rigid.model import Drag, Loads, Springs

    n = len(scene.bodies)
    eff = scene.effects
    springs = drag = loads = None
    acted: set[int] = set()
    if eff.springs:
        a_idx, b_idx, ra, rb = [], [], [], []
        for s in eff.springs:
            a_idx.append(s.body_a)
            ra.append([float(x) for x in offset(s.body_a, s.attach_a)])
            acted.add(s.body_a)
            if s.body_b is None:
                anchor = [0.0] * dim
                anchor[: scene.dimension] = [float(x) for x in s.attach_b]
                b_idx.append(-1)
                rb.append(anchor)
            else:
                b_idx.append(s.body_b)
                rb.append([float(x) for x in offset(s.body_b, s.attach_b)])
                acted.add(s.body_b)
        springs = Springs(
            a=np.array(a_idx, dtype=np.int64), b=np.array(b_idx, dtype=np.int64),
            ra=np.array(ra, float).reshape(-1, dim), rb=np.array(rb, float).reshape(-1, dim),
            stiffness=np.array([float(s.stiffness) for s in eff.springs]),
            damping=np.array([float(s.damping) for s in eff.springs]),
            rest_length=np.array([float(s.rest_length) for s in eff.springs]))
    if eff.drag:
        lin, ang = np.zeros(n), np.zeros(n)
        for d in eff.drag:
            for i in d.bodies:
                lin[i] += float(d.linear)
                ang[i] += float(d.angular)
        drag = Drag(linear=lin, angular=ang)
        acted |= {i for i in range(n) if lin[i] or ang[i]}
    if eff.loads:
        k = len(eff.loads)
        force = np.zeros((k, dim))
        torque = np.zeros((k, 3)) if dim == 3 else np.zeros(k)
        for j, ld in enumerate(eff.loads):
            force[j, : scene.dimension] = [float(x) for x in ld.force]
            t = [float(x) for x in np.asarray(ld.torque, float).reshape(-1)]
            if dim == 2:
                torque[j] = t[0]
            elif scene.dimension == 3:
                torque[j] = t
            else:
                torque[j, 2] = t[0]
            acted.add(ld.body)
        loads = Loads(body=np.array([ld.body for ld in eff.loads], dtype=np.int64),
                      force=force, torque=torque)
    if not acted:
        return None
    return springs, drag, loads, sorted(acted)


class PybulletModel:
    """One PyBullet DIRECT client holding one Scene, with the state conversions.

    Build it, ``probe()`` once (measures what PyBullet does not report), ``set_initial_state()``,
    then ``advance(n)`` and ``read()``; always ``close()``.
    """

    def __init__(self, scene: Scene, integrator: str, dt: float,
                 options: dict[str, Any] | None = None):
        if _p is None:  # pragma: no cover
            raise ImportError("pybullet is not installed")
        if integrator not in INTEGRATORS:
            raise ValueError(f"unknown PyBullet integrator {integrator!r}; known: {INTEGRATORS}")
        self.scene = scene
        self.integrator = integrator
        self.maximal = integrator == "maximal"
        self.dt = float(dt)
        self.dim = scene.dimension
        self.planar_joints = self.dim == 2 and not self.maximal
        self.options = engine_options(scene) if options is None else options
        self.probe_result: dict[str, Any] | None = None
        self.contact = bool(scene.effects.contact)
        self.plan: dict[str, Any] | None = None
        # 2D contact: the prisms' half depth along z (``extrusion_half_depth``)
        self._depth = extrusion_half_depth(scene) if self.contact and self.dim == 2 else 0.0
        if self.contact:
            self.plan, reason = contact_plan(scene, integrator)
            if reason is not None:
                raise ValueError(f"PyBullet cannot run this contact scene: {reason}")
            if self.options["contact_parameters"] == "defaults":
                self.plan = {**self.plan, "iterations": None, "kind_used": "defaults"}
        self.cid = _p.connect(_p.DIRECT)
        if self.cid < 0:  # pragma: no cover
            raise RuntimeError("pybullet could not open a DIRECT client")
        try:
            self._configure()
            self._build()
            self._init_forces()
        except BaseException:
            self.close()
            raise

    # -- model ----------------------------------------------------------------------------
    def close(self) -> None:
        if self.cid is not None and self.cid >= 0:
            try:
                _p.disconnect(physicsClientId=self.cid)
            finally:
                self.cid = None

    def _configure(self) -> None:
        kw: dict[str, Any] = dict(fixedTimeStep=self.dt, numSubSteps=0,
                                  contactBreakingThreshold=CONTACT_BREAKING_THRESHOLD)
        if self.options.get("solver_iterations") is not None:
            kw["numSolverIterations"] = int(self.options["solver_iterations"])
        elif self.plan is not None and self.plan["iterations"] is not None:
            kw["numSolverIterations"] = self.plan["iterations"]  # C18: mass ratio >= 100
        if self.plan is not None and self._impact:
            # CONTACTS.md recipe 6(a), impacts: no restitution threshold (C11), no slop, no
            # Baumgarte velocity (contact ERP 0: exact bounces, penetration never corrected,
            # C12), no warm starting of the previous step's impulses.
            kw.update(IMPACT_PARAMETERS)
        _p.setPhysicsEngineParameter(physicsClientId=self.cid, **kw)
        # Gravity stays 0 until the probe step is done; set_initial_state sets the scene's.
        _p.setGravity(0.0, 0.0, 0.0, physicsClientId=self.cid)

    def _body_frame(self, body) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(position, quaternion, com, inertia) of a body as a 3D body; 2D: embedded at z = 0."""
        if self.dim == 3:
            return (np.asarray(body.position, float), np.asarray(body.orientation, float),
                    np.asarray(body.com, float), np.asarray(body.inertia, float))
        half = 0.5 * body.angle
        # Isotropic inertia: only I_zz acts on in-plane motion, and no gyroscopic term can tip
        # a free (maximal) body out of the plane.
        return (np.array([body.position[0], body.position[1], 0.0]),
                np.array([math.cos(half), 0.0, 0.0, math.sin(half)]),
                np.array([body.com[0], body.com[1], 0.0]), np.eye(3) * body.moment)

    def _neutralise(self, uid: int, links: tuple[int, ...]) -> None:
        """Damping 0, no velocity clamp, no sleeping, no collisions; joint damping 0 on links.

        Two kinds of call on purpose: PyBullet's body-wide setters (damping, activation state,
        maxJointVelocity) overwrite the command's link index with -1, so a link's mass or joint
        damping passed in the same call would silently land on the base.
        """
        cid = self.cid
        _p.changeDynamics(uid, -1, linearDamping=0.0, angularDamping=0.0,
                          maxJointVelocity=MAX_COORDINATE_VELOCITY,
                          activationState=_p.ACTIVATION_STATE_DISABLE_SLEEPING,
                          physicsClientId=cid)
        _p.setCollisionFilterGroupMask(uid, -1, 0, 0, physicsClientId=cid)
        for link in links:
            _p.changeDynamics(uid, link, jointDamping=0.0, physicsClientId=cid)
            _p.setCollisionFilterGroupMask(uid, link, 0, 0, physicsClientId=cid)

    def _set_mass(self, uid: int, link: int, mass: float, moments: np.ndarray) -> None:
        # The mass goes with the inertia: for a maximal-coordinate body localInertiaDiagonal
        # alone sets the mass to 0 (a static body). Nothing body-wide in this call (see above).
        _p.changeDynamics(uid, link, mass=float(mass),
                          localInertiaDiagonal=[float(x) for x in moments],
                          physicsClientId=self.cid)

    def _build(self) -> None:
        cid = self.cid
        self.bodies: list[_BodyMap] = []
        for body in self.scene.bodies:
            pos, quat, com, inertia = self._body_frame(body)
            moments, axes = principal_axes(inertia)
            if self.dim == 2:
                axes = np.eye(3)  # isotropic: the body axes are principal
                moments = np.full(3, body.moment)
            q_axes = matrix_to_quat(axes)
            if self.planar_joints:
                # Contact: only the last link (centred on the centre of mass, turned by the
                # angle) carries the prism, the body frame's origin at -com in it; the base and
                # the two prismatic links have no shape and keep filter group and mask 0.
                shape = (self._collision_shape(body.shape, [-com[0], -com[1], 0.0])
                         if self.contact else -1)
                uid = _p.createMultiBody(
                    baseMass=0.0, baseCollisionShapeIndex=-1, baseVisualShapeIndex=-1,
                    basePosition=[0.0, 0.0, 0.0], baseOrientation=[0.0, 0.0, 0.0, 1.0],
                    linkMasses=[0.0, 0.0, float(body.mass)],
                    linkCollisionShapeIndices=[-1, -1, shape],
                    linkVisualShapeIndices=[-1, -1, -1],
                    linkPositions=[[0.0, 0.0, 0.0]] * 3,
                    linkOrientations=[[0.0, 0.0, 0.0, 1.0]] * 3,
                    linkInertialFramePositions=[[0.0, 0.0, 0.0]] * 3,
                    linkInertialFrameOrientations=[[0.0, 0.0, 0.0, 1.0]] * 3,
                    # parent 0 is the base, k is link k-1: a chain x -> y -> angle
                    linkParentIndices=[0, 1, 2],
                    linkJointTypes=[_p.JOINT_PRISMATIC, _p.JOINT_PRISMATIC, _p.JOINT_REVOLUTE],
                    linkJointAxis=[[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
                    physicsClientId=cid)
                self._set_mass(uid, 2, body.mass, moments)
                self._neutralise(uid, (0, 1, 2))
                # Every createMultiBody joint carries a velocity motor: switch it off.
                _p.setJointMotorControlArray(uid, [0, 1, 2], _p.VELOCITY_CONTROL,
                                             forces=[0.0, 0.0, 0.0], physicsClientId=cid)
            else:
                uid = _p.createMultiBody(
                    baseMass=float(body.mass),
                    baseCollisionShapeIndex=(self._collision_shape(body.shape)
                                             if self.contact else -1),
                    baseVisualShapeIndex=-1, basePosition=pos.tolist(),
                    baseOrientation=_xyzw(quat), baseInertialFramePosition=com.tolist(),
                    baseInertialFrameOrientation=_xyzw(q_axes),
                    useMaximalCoordinates=self.maximal, physicsClientId=cid)
                self._set_mass(uid, -1, body.mass, moments)
                self._neutralise(uid, ())
            self.bodies.append(_BodyMap(uid=uid, moments=moments, q_axes=q_axes, com3=com))
        if self.contact:
            self._build_contact()
        self._q_axes = np.array([b.q_axes for b in self.bodies]).reshape(-1, 4)
        self._com3 = np.array([b.com3 for b in self.bodies]).reshape(-1, 3)

    # -- contact (docs/engines.md, PyBullet, "Contact") ---------------------------------------
    def _collision_shape(self, shape, frame_position=None) -> int:
        """A collision shape in the body frame. createMultiBody places a base's collision shape
        relative to the link frame (the declared body frame), not the inertial frame (measured:
        a box with an offset, rotated inertial frame lands centred on the body frame), so every
        shape, centred on its body-frame origin or given in body-frame coordinates, goes in at
        the identity. ``frame_position``: where the body frame's origin sits in the link frame
        (the planar chain's last link is centred on the centre of mass: ``-com``; a hull takes
        it into its vertices, an implicit shape as ``collisionFramePosition``).

        A hull (mesh, polygon prism) gets collision margin 0 on the shape itself
        (``_without_margin``), before any body uses it.

        2D shapes are prisms along z, ``self._depth`` either side of the plane: a circle a
        btCylinderShapeZ, a box a btBoxShape with that z half extent, a polygon the convex hull
        of its vertices at z = -depth and +depth (docs/engines.md, PyBullet, "Contact")."""
        cid = self.cid
        kind = shape.kind
        frame = {} if frame_position is None else {
            "collisionFramePosition": [float(x) for x in frame_position]}

        def hull(vertices) -> int:
            v = np.asarray(vertices, float)
            if frame_position is not None:
                v = v + np.asarray(frame_position, float)
            idx = _p.createCollisionShape(_p.GEOM_MESH, vertices=v.tolist(),
                                          physicsClientId=cid)
            return self._without_margin(idx) if idx >= 0 else idx
        if self.dim == 2:
            depth = self._depth
            if kind == "circle":
                idx = _p.createCollisionShape(_p.GEOM_CYLINDER, radius=float(shape.radius),
                                              height=2.0 * depth, physicsClientId=cid, **frame)
            elif kind == "box":
                w, h = (0.5 * float(x) for x in shape.size)
                idx = _p.createCollisionShape(_p.GEOM_BOX, halfExtents=[w, h, depth],
                                              physicsClientId=cid, **frame)
            elif kind == "polygon":
                v = np.asarray(shape.vertices, float)
                prism = np.concatenate([np.column_stack([v, np.full(len(v), -depth)]),
                                        np.column_stack([v, np.full(len(v), depth)])])
                idx = hull(prism)
            else:  # pragma: no cover - the loader gives 2D scenes 2D shapes only
                raise ValueError(f"no PyBullet 2D collision shape for {kind!r}")
            if idx < 0:  # pragma: no cover
                raise RuntimeError(f"pybullet refused the 2D {kind} collision shape")
            return idx
        if kind == "sphere":
            idx = _p.createCollisionShape(_p.GEOM_SPHERE, radius=float(shape.radius),
                                          physicsClientId=cid)
        elif kind == "box":
            idx = _p.createCollisionShape(_p.GEOM_BOX,
                                          halfExtents=[0.5 * float(x) for x in shape.size],
                                          physicsClientId=cid)
        elif kind == "capsule":  # btCapsuleShapeZ: height is the cylindrical part, as the scene
            idx = _p.createCollisionShape(_p.GEOM_CAPSULE, radius=float(shape.radius),
                                          height=float(shape.length), physicsClientId=cid)
        elif kind == "cylinder":  # btCylinderShapeZ: full height along z
            idx = _p.createCollisionShape(_p.GEOM_CYLINDER, radius=float(shape.radius),
                                          height=float(shape.length), physicsClientId=cid)
        elif kind == "mesh":  # vertices without indices: btConvexHullShape, the convex hull
            idx = hull(shape.vertices)
        else:  # pragma: no cover - 2D contact is not applicable (contact_plan)
            raise ValueError(f"no PyBullet collision shape for {kind!r}")
        if idx < 0:  # pragma: no cover
            raise RuntimeError(f"pybullet refused the {kind} collision shape")
        return idx

    def _without_margin(self, idx: int) -> int:
        """Collision margin 0 on the hull shape ``idx`` itself, through a temporary static body.

        A convex hull keeps Bullet's default collision margin (1 mm) outside its faces: the
        L-bracket rested 0.97 mm above the ground with it, 0.03 mm into it without. But
        changeDynamics's ``collisionMargin`` only reaches a base's top-level shape: a
        multibody link's shape is left alone (the planar chain's polygon prism, 0.1 mm into
        the ground, read 1.1 mm deep), and so is the child of the btCompoundShape that wraps a
        maximal body's shape when its inertial frame is offset (the L-bracket as a maximal
        body rested 0.97 mm high). The shape object is shared by every body built on it, so
        the margin is set on it through a throw-away base, removed at once
        (tests/engines/test_pybullet_contact.py). Implicit shapes (sphere, box, capsule,
        cylinder) keep their margin inside the surface and are left alone."""
        cid = self.cid
        holder = _p.createMultiBody(baseMass=0.0, baseCollisionShapeIndex=idx,
                                    baseVisualShapeIndex=-1, physicsClientId=cid)
        _p.setCollisionFilterGroupMask(holder, -1, 0, 0, physicsClientId=cid)
        _p.changeDynamics(holder, -1, collisionMargin=0.0, physicsClientId=cid)
        margin = _p.getDynamicsInfo(holder, -1, physicsClientId=cid)[11]
        _p.removeBody(holder, physicsClientId=cid)
        if margin != 0.0:  # pragma: no cover
            raise RuntimeError(f"a hull's collision margin read back {margin}, asked 0")
        return idx

    def _material(self, uid: int, name: str, link: int = -1) -> None:
        """The surface's factor of every pair value (Bullet multiplies the two surfaces'),
        rolling and spinning friction 0; impact scenes: contact processing threshold 0."""
        plan = self.plan
        kw: dict[str, Any] = dict(lateralFriction=plan["friction"][name],
                                  restitution=plan["restitution"][name],
                                  rollingFriction=0.0, spinningFriction=0.0)
        if self._impact:
            kw["contactProcessingThreshold"] = 0.0
        _p.changeDynamics(uid, link, physicsClientId=self.cid, **kw)

    def _build_contact(self) -> None:
        """Materials on the bodies, the ground plane and the statics as static bodies of the
        integrator's kind (maximal bodies need a maximal ground: CONTACTS.md C10), and the
        ``collide = false`` pairs filtered out. The bodies' own collision filter stays group and
        mask 0 until ``_enable_contact`` (after the probe, which must touch nothing)."""
        from crosscheck.scene.contact import GROUND

        cid = self.cid
        scene = self.scene
        self.surfaces: dict[str, int] = {}
        # the link that carries each surface's shape: the planar chain's last link, else -1
        self.surface_links: dict[str, int] = {}
        link = self._shape_link
        for b, body in zip(self.bodies, scene.bodies, strict=True):
            self._material(b.uid, body.name, link)
            self.surfaces[body.name] = b.uid
            self.surface_links[body.name] = link
        for st in scene.statics:
            if self.dim == 3:
                pos = [float(x) for x in st.position]
                quat = np.asarray(st.orientation, float)
            else:  # a 2D static: its prism at (x, y, 0), turned about z
                pos = [float(st.position[0]), float(st.position[1]), 0.0]
                half = 0.5 * float(np.ravel(st.orientation)[0])
                quat = np.array([math.cos(half), 0.0, 0.0, math.sin(half)])
            uid = _p.createMultiBody(
                baseMass=0.0, baseCollisionShapeIndex=self._collision_shape(st.shape),
                baseVisualShapeIndex=-1, basePosition=pos, baseOrientation=_xyzw(quat),
                useMaximalCoordinates=self.maximal, physicsClientId=cid)
            self._material(uid, st.name)
            _p.setCollisionFilterGroupMask(uid, -1, 1, 1, physicsClientId=cid)
            self.surfaces[st.name] = uid
            self.surface_links[st.name] = -1
        if scene.ground is not None:
            n = np.asarray(scene.ground.normal, float)
            if self.dim == 2:  # the ground line: a plane containing z, its trace the line
                n = np.array([n[0], n[1], 0.0])  # a unit normal (the loader's) stays one
            # btStaticPlaneShape(normal, 0) in the ground body's frame, the body at n * offset
            plane = _p.createCollisionShape(_p.GEOM_PLANE, planeNormal=n.tolist(),
                                            physicsClientId=cid)
            uid = _p.createMultiBody(
                baseMass=0.0, baseCollisionShapeIndex=plane, baseVisualShapeIndex=-1,
                basePosition=(n * float(scene.ground.offset)).tolist(),
                useMaximalCoordinates=self.maximal, physicsClientId=cid)
            self._material(uid, GROUND)
            # A static rigid body's default group (2) is not in the mask 1 the bodies get.
            _p.setCollisionFilterGroupMask(uid, -1, 1, 1, physicsClientId=cid)
            self.surfaces[GROUND] = uid
            self.surface_links[GROUND] = -1
        # the plan lists the collide = false pairs (from the group pairs, not from all N^2)
        for a, b in self.plan["filtered"]:
            _p.setCollisionFilterPair(self.surfaces[a], self.surfaces[b], self.surface_links[a],
                                      self.surface_links[b], 0, physicsClientId=cid)

    @property
    def _shape_link(self) -> int:
        """The link that carries a body's collision shape: the planar chain's last link (2),
        else the base (-1)."""
        return 2 if self.planar_joints else -1

    @property
    def _impact(self) -> bool:
        """The impact parameters are set (an e > 0 scene, unless pinned to Bullet's defaults)."""
        return (self.plan is not None and self.plan["kind"] == "impact"
                and self.options["contact_parameters"] == "recipe")

    def _enable_contact(self) -> None:
        """Filter group and mask 1 on the link carrying each body's shape only (the planar
        chain's base and prismatic links have none and stay 0)."""
        link = self._shape_link
        for b in self.bodies:
            _p.setCollisionFilterGroupMask(b.uid, link, 1, 1, physicsClientId=self.cid)

    def _local_offset(self, body_index: int, point) -> np.ndarray:
        """A body-frame point relative to the centre of mass, in the frame ``read_raw`` rotates.

        3D bodies: the inertial (principal-axes) frame, whose rotation PyBullet reports. 2D: the
        body frame itself (its rotation is the joint angle, or the free body's quaternion).
        """
        b = self.bodies[body_index]
        p3 = np.zeros(3)
        p3[: self.dim] = point
        rel = p3 - b.com3
        return quat_to_matrix(b.q_axes).T @ rel

    # -- state ----------------------------------------------------------------------------
    def set_initial_state(self, poses: list | None = None) -> None:
        """Write the scene's t = 0 velocities (and, after a probe, the t = 0 poses) and gravity.

        ``poses``: the (position, orientation) PyBullet reported for each base right after
        building, i.e. the inertial frame; ``resetBasePositionAndOrientation`` takes exactly
        that frame (trap 2).
        """
        cid = self.cid
        for i, (b, body) in enumerate(zip(self.bodies, self.scene.bodies, strict=True)):
            if self.planar_joints:
                com = body.com_world()
                for j, (q, qd) in enumerate(((com[0], body.velocity[0]),
                                             (com[1], body.velocity[1]),
                                             (body.angle, body.angular_velocity[0]))):
                    _p.resetJointState(b.uid, j, float(q), float(qd), physicsClientId=cid)
                continue
            if poses is not None:
                _p.resetBasePositionAndOrientation(b.uid, poses[i][0], poses[i][1],
                                                   physicsClientId=cid)
            if self.dim == 3:
                v = [float(x) for x in body.velocity]
                w = [float(x) for x in body.angular_velocity]
            else:
                v = [float(body.velocity[0]), float(body.velocity[1]), 0.0]
                w = [0.0, 0.0, float(body.angular_velocity[0])]
            _p.resetBaseVelocity(b.uid, v, w, physicsClientId=cid)
        g = self.scene.effects.gravity_vector(self.dim)
        g3 = [float(g[0]), float(g[1]), float(g[2]) if self.dim == 3 else 0.0]
        _p.setGravity(*g3, physicsClientId=cid)

    def base_poses(self) -> list:
        """The pose PyBullet reports for each base (the inertial frame); remembered for the probe.
        """
        self._build_poses = [_p.getBasePositionAndOrientation(b.uid, physicsClientId=self.cid)
                             for b in self.bodies]
        return self._build_poses

    def probe(self) -> dict[str, Any]:
        """One force-free step at high speed: every velocity must come out unchanged.

        Measures what PyBullet's API does not report back (damping, the velocity clamp, joint
        motors and joint damping of the planar chain), then takes one step at rest (``_settle``).
        Leaves the bodies to be reset by ``set_initial_state(poses)``; call it after
        ``base_poses()`` and before gravity is set (it is 0 after building).
        """
        cid = self.cid
        before = []
        for b in self.bodies:
            if self.planar_joints:
                qd = [PROBE_SPEED, -PROBE_SPEED, PROBE_SPIN]
                for j in range(3):
                    _p.resetJointState(b.uid, j, 0.0, qd[j], physicsClientId=cid)
                before.append(np.array(qd))
            else:
                _, orn = _p.getBasePositionAndOrientation(b.uid, physicsClientId=cid)
                r = quat_to_matrix(_wxyz(orn))
                # Components above the clamp in the base frame, where PyBullet clamps; the spin
                # about a principal axis, so no gyroscopic term changes it.
                v = r @ np.array([PROBE_SPEED, -PROBE_SPEED, PROBE_SPEED])
                w = r @ np.array([0.0, 0.0, PROBE_SPIN])
                _p.resetBaseVelocity(b.uid, v.tolist(), w.tolist(), physicsClientId=cid)
                before.append(np.concatenate([v, w]))
        _p.stepSimulation(physicsClientId=cid)
        lin, ang = [], []
        for b, v0 in zip(self.bodies, before, strict=True):
            if self.planar_joints:
                st = _p.getJointStates(b.uid, [0, 1, 2], physicsClientId=cid)
                v1 = np.array([s[1] for s in st])
                lin.append(np.linalg.norm(v1[:2] - v0[:2]) / np.linalg.norm(v0[:2]))
                ang.append(abs(v1[2] - v0[2]) / abs(v0[2]))
            else:
                vv, ww = _p.getBaseVelocity(b.uid, physicsClientId=cid)
                lin.append(np.linalg.norm(np.subtract(vv, v0[:3])) / np.linalg.norm(v0[:3]))
                ang.append(np.linalg.norm(np.subtract(ww, v0[3:])) / np.linalg.norm(v0[3:]))
        self._settle()
        worst_lin = float(max(lin, default=0.0))
        worst_ang = float(max(ang, default=0.0))
        return {
            "what": "one force-free step at dt with every velocity above the default clamp",
            "linear_speed_per_component": PROBE_SPEED,
            "angular_speed": PROBE_SPIN,
            "max_relative_change_linear": worst_lin,
            "max_relative_change_angular": worst_ang,
            "neutral": bool(worst_lin <= PROBE_TOLERANCE and worst_ang <= PROBE_TOLERANCE),
        }

    def _settle(self) -> None:
        """One step at rest in the build pose, to refresh what Bullet caches per body.

        A maximal-coordinate body keeps its world inverse inertia from the last step it took
        (``changeDynamics`` and ``resetBasePositionAndOrientation`` do not refresh it): after the
        probe it belongs to the probe's end pose, and before any step to the shapeless default.
        The first real step would turn torques with that stale tensor (measured: a torque about a
        principal axis lost its whole first step). At rest, with no gravity and no force, the
        step moves nothing and recomputes the tensor for the true pose.
        """
        cid = self.cid
        for b, pose in zip(self.bodies, self._build_poses, strict=True):
            if self.planar_joints:
                for j in range(3):
                    _p.resetJointState(b.uid, j, 0.0, 0.0, physicsClientId=cid)
            else:
                _p.resetBasePositionAndOrientation(b.uid, pose[0], pose[1], physicsClientId=cid)
                _p.resetBaseVelocity(b.uid, [0.0, 0.0, 0.0], [0.0, 0.0, 0.0],
                                     physicsClientId=cid)
        _p.stepSimulation(physicsClientId=cid)

    def read_raw(self) -> list[float]:
        """The current state as one flat row per body (cheap: recorded, converted later).

        3D / 2D maximal: COM (3), inertial-frame quaternion x,y,z,w (4), COM velocity (3),
        angular velocity (3). 2D multibody: joint positions (3), joint velocities (3), link COM
        (3), link orientation x,y,z,w (4), link angular velocity (3).
        """
        cid = self.cid
        row: list[float] = []
        if self.planar_joints:
            for b in self.bodies:
                st = _p.getJointStates(b.uid, [0, 1, 2], physicsClientId=cid)
                ls = _p.getLinkState(b.uid, 2, computeLinkVelocity=1,
                                     computeForwardKinematics=1, physicsClientId=cid)
                row += [st[0][0], st[1][0], st[2][0], st[0][1], st[1][1], st[2][1]]
                row += list(ls[0]) + list(ls[1]) + list(ls[7])
            return row
        for b in self.bodies:
            pos, orn = _p.getBasePositionAndOrientation(b.uid, physicsClientId=cid)
            v, w = _p.getBaseVelocity(b.uid, physicsClientId=cid)
            row += list(pos) + list(orn) + list(v) + list(w)
        return row

    @property
    def body_width(self) -> int:
        """Floats per body in a raw row."""
        return 16 if self.planar_joints else 13

    @property
    def row_width(self) -> int:
        return self.body_width * len(self.bodies)

    def convert(self, raw: np.ndarray, t: np.ndarray) -> tuple[tuple[np.ndarray, ...],
                                                                 dict[str, np.ndarray]]:
        """(T, N * width) raw rows -> (com, rot, vel, omega) in crosscheck's convention, extras."""
        n = len(self.bodies)
        raw = np.asarray(raw, float).reshape(len(raw), n, self.body_width)
        if self.planar_joints:
            com = raw[..., 0:2].copy()
            angle = raw[..., 2].copy()
            vel = raw[..., 3:5].copy()
            omega = raw[..., 5].copy()
            z = raw[..., 8]
            q_link = _wxyz(raw[..., 9:13])
            w3 = raw[..., 13:16]
            return (com, angle, vel, omega), self._out_of_plane(z, q_link, w3)
        com3 = raw[..., 0:3]
        q_in = _wxyz(raw[..., 3:7])
        v3 = raw[..., 7:10]
        w3 = raw[..., 10:13]
        # Inertial frame -> declared body frame: R_in = R_body V, so q_body = q_in conj(q_V).
        q_body = quat_mul(q_in, quat_conj(self._q_axes)[None])
        q_body /= np.linalg.norm(q_body, axis=-1, keepdims=True)
        if self.dim == 3:
            if len(q_body):
                # Same sign as the scene at t = 0, so sign_continuous keeps the scene's sign.
                ref = np.array([b.orientation for b in self.scene.bodies])
                flip = np.sum(q_body[0] * ref, axis=-1) < 0
                q_body[:, flip] *= -1.0
            return (com3.copy(), q_body, v3.copy(), w3.copy()), {}
        r = quat_to_matrix(q_body)
        raw_angle = np.arctan2(r[..., 1, 0], r[..., 0, 0])
        first = np.array([b.angle for b in self.scene.bodies])
        angle = _unwrap_with_rate(raw_angle, w3[..., 2], t, first)
        extras = self._out_of_plane(com3[..., 2], q_body, w3)
        return (com3[..., :2].copy(), angle, v3[..., :2].copy(), w3[..., 2].copy()), extras

    @staticmethod
    def _out_of_plane(z, q_wxyz, w3) -> dict[str, np.ndarray]:
        r = quat_to_matrix(q_wxyz)
        tilt = np.arctan2(np.hypot(r[..., 0, 2], r[..., 1, 2]), r[..., 2, 2])
        return {"out_of_plane": np.asarray(z, float).copy(),
                "out_of_plane_tilt": tilt,
                "out_of_plane_omega": np.hypot(w3[..., 0], w3[..., 1])}

    # -- stepping -------------------------------------------------------------------------
    def _init_forces(self) -> None:
        """The scene's springs, drag and loads for ``_apply_forces``: the in-house kernels' force
        law (forces3d.accumulate; planar joints: forces2d.accumulate), its arrays and the
        state rows and scratch it is evaluated on. ``self.forces_active`` is False without any.
        """
        dim = 2 if self.planar_joints else 3
        law = _force_law(self.scene, dim,
                         self._planar_offset if self.planar_joints else self._local_offset)
        self.forces_active = law is not None
        if law is None:
            return
        springs, drag, loads, acted = law
        if dim == 3:
            from crosscheck.sim.rigid.forces3d import accumulate_rows
        else:
            from crosscheck.sim.rigid.forces2d import accumulate_rows
        n = len(self.bodies)
        self._rows = np.zeros((n, 13 if dim == 3 else 6))
        if dim == 3:
            self._rows[:, 6] = 1.0  # a unit quaternion for the bodies never read
            scratch = (np.empty((n, 3)), np.empty((n, 3, 3)), np.empty((n, 3)), np.empty((n, 3)))
            self._F, self._T = np.empty((n, 3)), np.empty((n, 3))
        else:
            scratch = (np.empty((n, 2)), np.empty(n), np.empty((n, 2)), np.empty(n))
            self._F, self._T = np.empty((n, 2)), np.empty(n)
        self._acted = [(i, self.bodies[i].uid) for i in acted]
        self._law_args = (springs, drag, loads, self._rows, *scratch, self._F, self._T)
        self._accumulate = accumulate_rows
        self._accumulate(*self._law_args)  # compile (or load from numba's cache) now

    def _planar_offset(self, body_index: int, point) -> np.ndarray:
        """A body-frame point relative to the centre of mass (planar joints: the joint angle
        rotates the body frame)."""
        return np.asarray(point, float) - np.asarray(self.scene.bodies[body_index].com, float)

    def _apply_forces(self) -> None:
        """Springs, drag and loads from the state PyBullet reports now, applied for one step."""
        cid = self.cid
        rows = self._rows
        if self.planar_joints:
            states = _p.getJointStates
            for i, uid in self._acted:
                (x, vx, _, _), (y, vy, _, _), (th, w, _, _) = states(uid, (0, 1, 2), cid)
                rows[i] = (x, y, th, vx, vy, w)
            self._accumulate(*self._law_args)
            forces, torques = self._F.tolist(), self._T.tolist()
            control = _p.setJointMotorControlArray
            for i, uid in self._acted:
                # Joint axes through the centre of mass: the generalised forces are F_x, F_y and
                # the torque about the centre of mass.
                control(uid, (0, 1, 2), _p.TORQUE_CONTROL,
                        forces=(forces[i][0], forces[i][1], torques[i]), physicsClientId=cid)
            return
        pose, velocity = _p.getBasePositionAndOrientation, _p.getBaseVelocity
        at = {}
        for i, uid in self._acted:
            pos, orn = pose(uid, cid)
            v, w = velocity(uid, cid)
            rows[i] = pos + orn + v + w
            at[i] = pos
        self._accumulate(*self._law_args)
        forces, torques = self._F.tolist(), self._T.tolist()
        force, torque, world = _p.applyExternalForce, _p.applyExternalTorque, _p.WORLD_FRAME
        for i, uid in self._acted:
            # At the centre of mass PyBullet itself reports: its lever arm is exactly zero.
            force(uid, -1, forces[i], at[i], world, cid)
            torque(uid, -1, torques[i], world, cid)

    def advance(self, nsteps: int) -> None:
        """nsteps steps (the bare stepping loop when nothing is applied per step), the client
        id positionally: as a keyword PyBullet's argument parsing costs 0.15 us more per call,
        14 % of a one-body step."""
        step, cid = _p.stepSimulation, self.cid
        try:
            if not self.forces_active:
                for _ in range(nsteps):
                    step(cid)
                return
            apply = self._apply_forces
            for _ in range(nsteps):
                apply()
                step(cid)
        except _p.error as exc:  # pragma: no cover - pybullet raises only on misuse
            raise StepFailure(f"pybullet error: {exc}") from exc

    # -- session (engines/session.py) ----------------------------------------------------
    fused = False  # no fast path: PyBullet's public API is stepped and read from Python

    def open_at_initial_state(self) -> PybulletModel:
        """Probe once (what PyBullet does not report back), then place the t = 0 state."""
        poses = self.base_poses()
        self.probe_result = self.probe()
        if self.contact:
            self._enable_contact()
        self.set_initial_state(poses)
        return self

    def set_state(self, com, rot, vel, omega) -> None:
        """Place a normalised state: the inverse of convert for one sample."""
        cid = self.cid
        for i, b in enumerate(self.bodies):
            if self.planar_joints:
                for j, (q, qd) in enumerate(((com[i][0], vel[i][0]), (com[i][1], vel[i][1]),
                                             (rot[i], omega[i]))):
                    _p.resetJointState(b.uid, j, float(q), float(qd), physicsClientId=cid)
                continue
            if self.dim == 3:
                c3, q_body = np.asarray(com[i], float), np.asarray(rot[i], float)
                v3, w3 = np.asarray(vel[i], float), np.asarray(omega[i], float)
            else:
                c3 = np.array([com[i][0], com[i][1], 0.0])
                half = 0.5 * float(rot[i])
                q_body = np.array([math.cos(half), 0.0, 0.0, math.sin(half)])
                v3 = np.array([vel[i][0], vel[i][1], 0.0])
                w3 = np.array([0.0, 0.0, float(omega[i])])
            # PyBullet's base pose is the inertial frame: R_in = R_body V.
            q_in = quat_mul(q_body, b.q_axes)
            _p.resetBasePositionAndOrientation(b.uid, c3.tolist(), _xyzw(q_in),
                                               physicsClientId=cid)
            _p.resetBaseVelocity(b.uid, v3.tolist(), w3.tolist(), physicsClientId=cid)

    def check(self) -> list[str]:
        problems = list(self.settings()[1])
        probe = self.probe_result
        if probe is not None and not probe["neutral"]:
            problems.append(
                "a force-free step changed the velocities (relative "
                f"{probe['max_relative_change_linear']:.3g} linear, "
                f"{probe['max_relative_change_angular']:.3g} angular): damping or the velocity "
                "clamp is still on")
        return problems

    def effective(self, arrays=None) -> dict[str, Any]:
        effective = self.settings()[0]
        effective["probe"] = self.probe_result
        effective["recording"] = ("python loop over PyBullet's functions: per sample and body "
                                  "getBasePositionAndOrientation and getBaseVelocity (2D "
                                  "multibody: getJointStates and getLinkState)")
        warnings = []
        if arrays is not None and len(arrays[3]):
            omega = np.asarray(arrays[3])
            spin = float(np.max(np.linalg.norm(omega, axis=-1) if self.dim == 3
                                else np.abs(omega))) * self.dt
            if spin > MAX_ROTATION_PER_STEP:
                warnings.append(f"a sampled |omega| dt of {spin:.3g} rad exceeds PyBullet's cap "
                                "of pi/4 per step: orientations rotate too little")
        effective["warnings"] = warnings
        return effective

    # -- read back ------------------------------------------------------------------------
    def contact_settings(self, params: dict, problems: list[str]) -> dict[str, Any]:
        """The contact model read back: each surface's material (getDynamicsInfo), each pair's
        product against the pair value, and the parameters, readable or not."""
        cid = self.cid
        plan = self.plan
        surfaces = []
        read: dict[str, tuple[float, float]] = {}
        # getDynamicsInfo of a maximal-coordinate body reports a restitution that is not the
        # one set (measured: 0.0 after setting 0.3, 0.2 after setting 0; the bounce follows the
        # value set, tests/engines/test_pybullet_contact.py): only its friction is checked.
        for name, uid in self.surfaces.items():
            info = _p.getDynamicsInfo(uid, self.surface_links[name], physicsClientId=cid)
            want = (plan["friction"][name], plan["restitution"][name])
            read[name] = (info[1], want[1] if self.maximal else info[5])
            entry = {"name": name, "lateral_friction": info[1], "restitution_set": want[1],
                     "restitution_read": info[5] if not self.maximal else "not readable",
                     "collision_margin": info[11]}
            if not self.maximal:
                entry.update(rolling_friction=info[6], spinning_friction=info[7],
                             contact_damping=info[8], contact_stiffness=info[9])
                if info[6] != 0.0 or info[7] != 0.0:
                    problems.append(f"{name!r}: rolling or spinning friction read back non-zero")
            surfaces.append(entry)
            if read[name] != want:
                problems.append(f"{name!r}: friction/restitution read back {read[name]}, "
                                f"asked {want}")
        # One entry per group pair (surface_groups), not per surface pair: every surface's
        # factors were read back and checked against the plan above, and all the surfaces of a
        # group have the same, so the product of the first pair's read values is the product of
        # every pair of the group pair.
        pairs = []
        groups = plan["groups"]
        for q in plan["group_pairs"]:
            m = q.material
            entry: dict[str, Any] = {"a": q.a, "b": q.b, "kind": q.kind, "source": m.source,
                                     "collide": m.collide, "pairs": q.count,
                                     "group_sizes": [len(groups[q.g]), len(groups[q.h])]}
            if m.collide:
                fr = read[q.a][0] * read[q.b][0]
                er = read[q.a][1] * read[q.b][1]
                entry.update(friction=m.friction, restitution=m.restitution,
                             bullet_friction=fr, bullet_restitution=er)
                for what, got, want in (("friction", fr, m.friction),
                                        ("restitution", er, m.restitution)):
                    if abs(got - want) > PAIR_TOLERANCE * want:
                        problems.append(f"pair {q.a!r}-{q.b!r} ({q.count} pairs): Bullet's "
                                        f"{what} product {got!r}, pair value {want!r}")
            else:
                entry["filter"] = "setCollisionFilterPair(enable=0) on each of its pairs"
            pairs.append(entry)
        impact = self._impact
        default = "Bullet's default (not set)"
        return {
            "kind": plan["kind"],
            "parameters": self.options["contact_parameters"],
            "kind_reason": ("every colliding pair has restitution > 0" if impact else
                            "every colliding pair has restitution 0"),
            "body_kind": _contact_note(plan["kind"], self.maximal) + (
                "; 2D: the planar chain is the only kind (MAXIMAL_2D_CONTACT)"
                if self.dim == 2 else ""),
            "ground_and_statics": ("static bodies, useMaximalCoordinates="
                                   f"{self.maximal} like the bodies (CONTACTS.md C10)"),
            "shapes": ("sphere, box, capsule (cylindrical length), cylinder: Bullet's own; mesh: "
                       "btConvexHullShape of its vertices, collided as its convex hull; ground: "
                       "btStaticPlaneShape; all at the body frame" if self.dim == 3 else
                       "prisms along z, extrusion_half_depth_2d either side of the plane: "
                       "circle btCylinderShapeZ, box btBoxShape, polygon btConvexHullShape of "
                       "its prism (collision margin 0); ground line: btStaticPlaneShape with "
                       "the normal (nx, ny, 0); on the planar chain's last link (centred on "
                       "the centre of mass, the body frame at -com in it), the only link with "
                       "a shape and filter group/mask 1"),
            "extrusion_half_depth_2d": self._depth if self.dim == 2 else None,
            "combination": "Bullet multiplies the two surfaces' values; each surface carries "
                           "a factor of every pair value (solved in log space over groups of "
                           "interchangeable surfaces, checked per group pair)",
            "pairs_listed": "one entry per group pair (its first pair a-b; 'pairs' surface "
                            "pairs share its values), not per surface pair",
            "surfaces": surfaces,
            "pairs": pairs,
            "num_solver_iterations": params["numSolverIterations"],
            "iterations_reason": (
                "engine_options.pybullet.solver_iterations" if
                self.options.get("solver_iterations") is not None else
                f"largest body mass ratio {plan['mass_ratio']:.4g} "
                + (f">= {HEAVY_RATIO:g}: 200 (C18)" if plan["iterations"] else
                   f"< {HEAVY_RATIO:g}: Bullet's default")),
            "not_readable": {
                "restitution_velocity_threshold": 0.0 if impact else default,
                "contact_slop": 0.0 if impact else default,
                "contact_erp": 0.0 if impact else default,
                "warm_starting_factor": 0.0 if impact else default,
                "contact_processing_threshold": 0.0 if impact else default,
                "note": "set through setPhysicsEngineParameter / changeDynamics; pybullet 3.2.7 "
                        "reports none of them back (getPhysicsEngineParameters has only the "
                        "time step, sub-steps, solver iterations and gravity)",
            },
        }

    def settings(self) -> tuple[dict[str, Any], list[str]]:
        """Settings read back from PyBullet, and the mismatches with what the scene needs."""
        cid = self.cid
        problems: list[str] = []
        params = _p.getPhysicsEngineParameters(physicsClientId=cid)
        gravity = [params["gravityAccelerationX"], params["gravityAccelerationY"],
                   params["gravityAccelerationZ"]]
        g = self.scene.effects.gravity_vector(self.dim)
        want_g = [float(g[0]), float(g[1]), float(g[2]) if self.dim == 3 else 0.0]
        if gravity != want_g:
            problems.append(f"gravity read back {gravity}, scene has {want_g}")
        if params["fixedTimeStep"] != self.dt:
            problems.append(f"time step read back {params['fixedTimeStep']}, asked {self.dt}")
        if params["numSubSteps"] != 0:
            problems.append(f"numSubSteps read back {params['numSubSteps']}, asked 0")
        bodies = []
        for b, body in zip(self.bodies, self.scene.bodies, strict=True):
            link = 2 if self.planar_joints else -1
            info = _p.getDynamicsInfo(b.uid, link, physicsClientId=cid)
            mass, diag = info[0], list(info[2])
            entry: dict[str, Any] = {"name": body.name, "mass": mass,
                                     "principal_moments": diag}
            if mass != float(body.mass):
                problems.append(f"body {body.name!r}: mass read back {mass}, scene {body.mass}")
            if np.max(np.abs(np.subtract(diag, b.moments))) > 1e-15 * np.max(b.moments):
                problems.append(f"body {body.name!r}: principal moments read back {diag}, "
                                f"asked {b.moments.tolist()}")
            if self.planar_joints:
                entry["joints"] = "prismatic x, prismatic y, revolute z through the COM"
                base_mass = _p.getDynamicsInfo(b.uid, -1, physicsClientId=cid)[0]
                entry["base_mass"] = base_mass
                if base_mass != 0.0:
                    problems.append(f"body {body.name!r}: the planar chain's base has mass "
                                    f"{base_mass}; it must be fixed (0)")
                joints = [_p.getJointInfo(b.uid, j, physicsClientId=cid) for j in range(3)]
                entry["joint_damping"] = [j[6] for j in joints]
                entry["joint_friction"] = [j[7] for j in joints]
                entry["joint_limits"] = [[j[8], j[9]] for j in joints]
                if any(j[6] != 0.0 or j[7] != 0.0 for j in joints):
                    problems.append(f"body {body.name!r}: joint damping or friction not zero")
                if any(j[8] <= j[9] for j in joints):
                    problems.append(f"body {body.name!r}: a joint has limits")
            elif not self.maximal:
                # Multibody only: for a maximal-coordinate body PyBullet leaves these fields
                # unset (garbage); the round trip of the state checks its inertial frame.
                entry["inertial_frame_position"] = list(info[3])
                entry["inertial_frame_orientation_xyzw"] = list(info[4])
                if np.max(np.abs(np.subtract(info[3], b.com3))) > 1e-15 * (
                        1.0 + np.max(np.abs(b.com3))):
                    problems.append(f"body {body.name!r}: inertial frame position read back "
                                    f"{list(info[3])}, asked {b.com3.tolist()}")
                q_read, q_set = np.array(info[4]), np.array(_xyzw(b.q_axes))
                if min(np.max(np.abs(q_read - q_set)), np.max(np.abs(q_read + q_set))) > 1e-15:
                    problems.append(f"body {body.name!r}: inertial frame orientation read back "
                                    f"{list(info[4])}, asked {list(q_set)}")
            bodies.append(entry)
        return {
            "coordinates": self.integrator,
            "planar": (None if self.dim == 3 else
                       "prismatic x, prismatic y, revolute z joints (exact plane)"
                       if self.planar_joints else
                       "free 3D rigid body, projected; drift in extras out_of_plane*"),
            "gravity": gravity,
            "fixed_time_step": params["fixedTimeStep"],
            "num_sub_steps": params["numSubSteps"],
            "num_solver_iterations": params["numSolverIterations"],
            "bodies": bodies,
            "damping": {"set": {"linear": 0.0, "angular": 0.0, "joint": 0.0},
                        "readable": False, "checked_by": "probe"},
            "max_joint_velocity": {"set": "inf", "readable": False,
                                   "checked_by": "probe"},
            "sleeping": {"set": "ACTIVATION_STATE_DISABLE_SLEEPING", "readable": False},
            "contact_breaking_threshold": {"set": CONTACT_BREAKING_THRESHOLD, "readable": False,
                                           "note": "global to the process (ENGINES.md trap 10)"},
            "collisions": ("none: no collision shapes, collision filter group and mask 0"
                           if not self.contact else
                           "collision shapes; filter group 1, mask 1 on every body (2D: the "
                           "planar chain's last link only), static and the ground; "
                           "setCollisionFilterPair(0) on collide = false pairs"),
            "contact": self.contact_settings(params, problems) if self.contact else None,
            "max_rotation_per_step": MAX_ROTATION_PER_STEP,
            "forces": ("none" if not self.forces_active else
                       "TORQUE_CONTROL generalised forces per step from the start-of-step state"
                       if self.planar_joints else
                       "applyExternalForce/Torque WORLD_FRAME at the COM per step from the "
                       "start-of-step state"),
            "options": dict(self.options),
        }, problems


def _contact_note(kind: str, maximal: bool) -> str:
    """What the integrator's body kind costs on this kind of contact scene (measured in
    benchmarks/contact_pybullet.py; docs/engines.md, PyBullet, "Contact")."""
    if kind == "resting":
        return ("multibody bodies and ground, default contact parameters: CONTACTS.md's recipe"
                if not maximal else
                "maximal bodies and ground: runs, but friction on a sliding box is 1-3 % too "
                "strong at dt = 1e-3 (CONTACTS.md C13; the recipe for friction is multibody)")
    return ("maximal bodies and ground with the impact parameters: CONTACTS.md's bounce recipe"
            if maximal else
            "multibody bodies and ground with the impact parameters: runs, but the multibody "
            "solver has no split impulse and an elastic bounce gains height (CONTACTS.md "
            "recipe G: +0.44 % per bounce at dt = 1e-3, +0.04 % at 1e-4; the bounce recipe is "
            "maximal)")


class PybulletEngine(EngineBase):
    name = "pybullet"
    effect_reasons = {**EngineBase.effect_reasons,
                      "fluid": "PyBullet has no fluid: no grid fluid and no fluid model (no "
                               "buoyancy, no fluid drag)",
                      "medium": "PyBullet has no fluid model (no buoyancy, no fluid drag)"}

    def check_options(self, scene: Scene) -> None:
        engine_options(scene)  # raises CaseError on an unknown key

    def capabilities(self) -> Capabilities:
        return Capabilities(
            dimensions=frozenset({2, 3}),
            shapes=frozenset(_SHAPES),
            effects=frozenset({"gravity", "springs", "drag", "loads", "contact"}),
            integrators=INTEGRATORS,
            notes=dict(INTEGRATOR_NOTES),
        )

    def version(self) -> str:
        return _version()

    def not_applicable(self, scene: Scene, integrator: str) -> str | None:
        if _p is None:  # pragma: no cover
            return "the pybullet package is not installed"
        reason = super().not_applicable(scene, integrator)
        if reason is not None or not scene.effects.contact:
            return reason
        return contact_plan(scene, integrator)[1]

    def open(self, scene: Scene, integrator: str, dt: float) -> PybulletModel:
        model = PybulletModel(scene, integrator, dt)
        try:
            return model.open_at_initial_state()
        except BaseException:
            model.close()
            raise


@functools.lru_cache(maxsize=1)
def _version() -> str:
    """Once per process: the package metadata lookup costs ~150 us, every run records it."""
    if _p is None:  # pragma: no cover
        return "not installed"
    try:
        dist = importlib.metadata.version("pybullet")
    except importlib.metadata.PackageNotFoundError:  # pragma: no cover
        dist = "unknown"
    return f"{dist} (API {_p.getAPIVersion()})"

