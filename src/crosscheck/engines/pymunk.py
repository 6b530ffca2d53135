"""Pymunk (Chipmunk2D) adapter: 2D scenes only, state in crosscheck's convention.

Model (docs/engines.md, section Pymunk)
---------------------------------------
* One ``pymunk.Body(mass, moment)`` per scene body. Without ``[effects] contact`` it has no shape
  (nothing collides). With contact each body gets one shape of mass 0 and density 0 (a shape with
  either would recompute the body's mass, moment and centre of gravity), statics get shapes on
  ``space.static_body`` and the ground is a solid quadrilateral. One collision type per material
  class (``scene.contact.material_classes``), its shapes sqrt of the class's friction and
  restitution, so that Chipmunk's product of the two shapes' values is the pair's; a handler only
  for the class pairs where it is not (``class_program``, ``_add_contact``; docs/engines.md,
  Pymunk, "Contact"). Set in this
  order: ``center_of_gravity = Body.com`` (body-frame point), ``angle``, then ``position`` = the
  body-frame origin (Chipmunk rotates about the centre of gravity and places it from the
  position), ``velocity`` = the centre-of-gravity velocity, ``angular_velocity``. ``moment`` is
  about the centre of gravity, as the Scene's.
* Reading: ``local_to_world(center_of_gravity)`` is the centre of mass, ``Body.velocity`` its
  velocity, ``Body.angle`` the angle (Chipmunk never wraps it). Energy is computed by crosscheck
  from the state, never from ``Body.kinetic_energy`` (which is m v^2 + I w^2, twice the energy).
* ``Space()`` is never threaded (``cpHastySpaceStep`` is not deterministic); ``damping = 1``,
  ``gravity`` = the scene's or (0, 0), ``sleep_time_threshold = inf``: all read back.

Integration (the only integrator, ``position_first``): Chipmunk's step first moves positions with
the old velocities, ``x_{n+1} = x_n + h v_n``, ``theta_{n+1} = theta_n + h w_n``, then updates the
velocities, ``v_{n+1} = v_n + h (g + F/m)``, and runs the constraint solver.

* Springs are ``pymunk.DampedSpring`` constraints (a world anchor is a spring to
  ``space.static_body``, whose local frame is the world frame; anchors are body-frame points
  relative to the body origin, as the Scene's). The spring force comes from the configuration
  *after* the position update (x_{n+1}): symplectic. Its damping acts on the relative velocity
  along the spring axis, as the Scene's, but as an exponential decay over the step
  (``v_rel *= exp(-c h k_eff)``, k_eff the inverse effective mass along the axis): first-order
  consistent with ``c dl/dt``. No Python runs per step for springs.
* Drag and loads are set as ``Body.force`` / ``Body.torque`` (world frame, at the centre of
  gravity) before every step from the state at the start of the step: Chipmunk resets them after
  each step. Drag is therefore explicit in the velocity. Without drag or loads the loop only
  steps.

Stepping and recording (docs/engines.md, section Pymunk, has the measurements)
------------------------------------------------------------------------------
A step is Chipmunk's ``cpSpaceStep(space, dt)``, called directly. ``Space.step`` wraps exactly
that call in Python bookkeeping (it checks bodies added since the last step, locks the space
for callbacks, then adds/removes objects queued during the step and runs post-step callbacks):
this adapter adds nothing after building, queues nothing and registers no post-step callback
(its collision handlers only set arbiter values, which needs no lock), so the direct call is the
same step at a quarter of the cost (0.17 instead of 0.68 us). The handlers are cffi callbacks
Chipmunk calls from inside ``cpSpaceStep``, also when the compiled loop calls it (they take the
GIL themselves; a test checks the compiled and Python loops give the same bits). Without
per-step forces the steps and the per-sample reads (the C getters ``cpBodyLocalToWorld`` of the
centre of gravity, ``cpBodyGetVelocity``, ``cpBodyGetAngle``, ``cpBodyGetAngularVelocity``, as
pymunk's properties call them) run in a compiled loop (``engines/_native.py``) that calls the
same C functions: a Python loop costs ~0.6 us per sample in reads against ~0.1 us per step, a
floor of 35 % recording overhead at ten steps per sample. The compiled reader is checked
against the Python one on every build (bit-identical rows) and the Python loop is used if it
differs or numba is missing; ``meta["effective"]["recording"]`` says which ran.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from crosscheck.engines.base import Capabilities, EngineBase
from crosscheck.errors import CaseError
from crosscheck.names import rigid_names
from crosscheck.scene.model import Scene

try:  # a missing or broken pymunk makes this engine "not applicable", not an import error
    import pymunk as _pm
except Exception:  # pragma: no cover
    _pm = None

try:  # Chipmunk's C functions, as pymunk itself calls them (see PymunkModel.read_raw)
    from pymunk._chipmunk_cffi import ffi as _ffi
    from pymunk._chipmunk_cffi import lib as _cp
except Exception:  # pragma: no cover
    _ffi = _cp = None

INTEGRATORS: tuple[str, ...] = rigid_names("pymunk")  # crosscheck.names holds them

INTEGRATOR_NOTES = {
    "position_first": "Chipmunk's step: x += h v_n and theta += h w_n first, then "
                      "v += h (g + F/m); springs (DampedSpring) from the updated positions, "
                      "their damping an exponential decay of the axial relative velocity; drag "
                      "and loads from the start-of-step state. First order; free fall drops "
                      "g h^2 N (N - 1) / 2",
}

# Engine options a case may pin in [engine_options.pymunk].
OPTIONS: dict[str, tuple[str, Any]] = {
    "iterations": ("a positive integer (constraint solver iterations; Chipmunk's default 10, "
                   "the adapter's 50 or 100 in contact scenes)", None),
    "collision_slop": ("a positive number, m (allowed penetration; Chipmunk's default 0.1, "
                       "the adapter's 1e-5)", None),
}

_SHAPES = ("circle", "box", "polygon")

# Contact settings (docs/engines.md, Pymunk, "Contact"; measured in benchmarks/contact_pymunk.py).
# collision_slop is the depth a resting contact keeps (CONTACTS.md C15): Chipmunk's 0.1 m leaves
# an inelastic disk at its impact depth, v dt; 1e-5 m leaves 0.0088 mm. Iterations: the PGS
# solver's convergence on a heavy body on a light one depends on the count (C18).
CONTACT_SLOP = 1e-5
CONTACT_ITERATIONS = 50
CONTACT_ITERATIONS_HEAVY = 100  # when the largest body mass ratio is >= HEAVY_RATIO
HEAVY_RATIO = 100.0
# The ground is a solid quadrilateral whose top edge is the ground line: GROUND_EXTENT m either
# side of the point of the line nearest the origin, and as deep (results do not change between
# 1e3 and 1e5 m; a Segment drifts a resting disk by 1e-13 to 5e-11 m growing with its length).
GROUND_EXTENT = 1e4
# A pair whose initial gap is within this of zero starts "touching": Chipmunk makes no contact at
# distance 0 (strict inequality, CONTACTS.md C17), so the pair stays apart unless pressed.
TOUCHING = 1e-12


def engine_options(scene: Scene) -> dict[str, Any]:
    given = dict(scene.engine_options.get("pymunk", {}))
    out: dict[str, Any] = {key: default for key, (_, default) in OPTIONS.items()}
    for key, value in given.items():
        field = f"engine_options.pymunk.{key}"
        if key not in OPTIONS:
            raise CaseError(scene.source, field,
                            f"one of the Pymunk adapter's options {sorted(OPTIONS)}",
                            f"unknown option {key!r}")
        if key == "iterations":
            ok = not isinstance(value, bool) and isinstance(value, int) and value >= 1
        else:
            ok = (not isinstance(value, bool) and isinstance(value, (int, float))
                  and 0.0 < value < math.inf)
        if not ok:
            raise CaseError(scene.source, field, OPTIONS[key][0], value)
        out[key] = value
    return out


def contact_iterations(scene: Scene) -> tuple[int, str]:
    """The PGS iteration count for a contact scene and why (CONTACTS.md C18, recipe P3/P4)."""
    masses = [float(b.mass) for b in scene.bodies]
    ratio = max(masses) / min(masses)
    if ratio >= HEAVY_RATIO:
        return CONTACT_ITERATIONS_HEAVY, (f"largest body mass ratio {ratio:.4g} >= "
                                          f"{HEAVY_RATIO:g}")
    return CONTACT_ITERATIONS, f"largest body mass ratio {ratio:.4g} < {HEAVY_RATIO:g}"


def _set_pair_values(arbiter, space, data) -> None:
    """pre_solve of every colliding pair: Chipmunk recomputes the arbiter's friction and
    restitution as the product of the two shapes' values at every step (cpArbiterUpdate), before
    this runs; the pair's own values replace them before the solver uses them."""
    arbiter.friction = data[0]
    arbiter.restitution = data[1]


def _never(arbiter, space, data) -> None:
    """begin of a ``collide = false`` pair: ignored until the two separate (Chipmunk keeps the
    arbiter ignored, so this runs once per overlap, not per step)."""
    arbiter.process_collision = False


def _world_vertices(shape, position, angle) -> np.ndarray:
    """A box's or polygon's vertices placed at a pose (world coordinates)."""
    v = (np.asarray(shape.vertices, float) if shape.kind == "polygon"
         else 0.5 * np.asarray(shape.size, float) * np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]]))
    c, s = math.cos(angle), math.sin(angle)
    return v @ np.array([[c, s], [-s, c]]) + np.asarray(position, float)


def initial_gap(scene: Scene, a: str, b: str, things: dict | None = None) -> float:
    """The distance between a and b at t = 0 (negative: overlapping; only its closeness to zero
    is used): circle centres and radii, polygon vertices against the other's signed distance
    (between convex polygons the nearest points include a vertex), the ground's line."""
    from crosscheck.scene.contact import GROUND
    from crosscheck.scene.shapes import Placed

    def geometry(name):
        thing = (things[name] if things is not None else
                 next(t for t in (*scene.bodies, *scene.statics) if t.name == name))
        angle = float(np.asarray(thing.orientation).reshape(-1)[0])
        placed = Placed(thing.shape, thing.position, thing.orientation)
        if thing.shape.kind == "circle":
            return placed, np.asarray(thing.position, float)[None], float(thing.shape.radius)
        return placed, _world_vertices(thing.shape, thing.position, angle), 0.0

    pa, va, ra = geometry(a)
    if b == GROUND:
        n, off = np.asarray(scene.ground.normal, float), float(scene.ground.offset)
        return float(np.min(va @ n) - off - ra)
    pb, vb, rb = geometry(b)
    if ra and rb:
        return float(np.linalg.norm(va[0] - vb[0]) - ra - rb)
    if ra:  # a circle: its centre's distance to the polygon b
        return float(pb.signed_distance(va)[0]) - ra
    if rb:
        return float(pa.signed_distance(vb)[0]) - rb
    return min(float(np.min(pb.signed_distance(va))), float(np.min(pa.signed_distance(vb))))


# Chipmunk's arbiter values are the products of the two shapes' (cpArbiterUpdate). A class pair
# whose product of the shapes' values is within this many ulp of the pair's value is left to
# Chipmunk (no handler); sqrt(x) * sqrt(y) against sqrt(x * y) differs by at most ~1 ulp.
PRODUCT_ULPS = 2


@dataclass(frozen=True)
class ClassPair:
    """Two material classes that can touch, and how Chipmunk is given their pair values:
    ``how`` "shapes" (the product of the shapes' values is the pair's: no handler), "pre_solve"
    (a handler sets the arbiter's friction and restitution) or "begin" (collide = false)."""

    i: int
    j: int
    a: str  # a pair of the two classes that can touch, for messages and the read-back
    b: str
    material: Any  # PairMaterial
    how: str
    product: tuple[float, float]  # the shapes' friction and elasticity products


def _close(x: float, y: float) -> bool:
    return abs(x - y) <= PRODUCT_ULPS * math.ulp(y)


def class_program(scene: Scene):
    """How a contact scene's pair values reach Chipmunk: (classes, per-class shape values
    (friction, elasticity), class pairs). One collision type per material class
    (``scene.contact.material_classes``), its shapes given sqrt of the class's friction and
    restitution: the product of two shapes' frictions is then the geometric mean (the pair
    rule) and that of their elasticities the pair's maximum when both classes have the same
    restitution. Handlers only for class pairs where that product is not the pair value (an
    override, or two different restitutions) or the pair does not collide: their number does
    not grow with the number of bodies."""
    from crosscheck.scene.contact import material_classes

    classes = material_classes(scene)
    # a class's values with itself are its material's (the pair rule on one material is exact)
    own = [classes.values[c][c] for c in range(classes.k)]
    shape_values = [(math.sqrt(m.friction), math.sqrt(m.restitution)) for m in own]
    out = []
    for i, j in classes.class_pairs():
        a, b = next(classes.pairs_between(i, j))
        m = classes.values[i][j]
        product = (shape_values[i][0] * shape_values[j][0],
                   shape_values[i][1] * shape_values[j][1])
        how = ("begin" if not m.collide else
               "shapes" if _close(product[0], m.friction) and _close(product[1], m.restitution)
               else "pre_solve")
        out.append(ClassPair(i, j, a, b, m, how, product))
    return classes, shape_values, out


def touching_pairs(scene: Scene) -> list[tuple[str, str, float]]:
    """The colliding pairs whose initial gap is within ``TOUCHING`` of zero (CONTACTS.md C17),
    found without measuring every pair: a gap of about zero needs the two bounding boxes at t = 0
    to touch, so only the pairs whose boxes come within 1e-9 m are measured (a sweep along x),
    and every body against the ground line. In ``Scene.contact_pairs()`` order."""
    from crosscheck.scene.contact import GROUND, material_classes

    classes = material_classes(scene)
    things = {t.name: t for t in (*scene.bodies, *scene.statics)}
    pos = {name: k for k, name in enumerate(classes.surfaces)}
    boxes = []
    for name, t in things.items():
        if t.shape.kind == "circle":
            c, r = np.asarray(t.position, float), float(t.shape.radius)
            lo, hi = c - r, c + r
        else:
            v = _world_vertices(t.shape, t.position,
                                float(np.asarray(t.orientation).reshape(-1)[0]))
            lo, hi = v.min(axis=0), v.max(axis=0)
        boxes.append((float(lo[0]) - 1e-9, float(hi[0]) + 1e-9, lo[1] - 1e-9, hi[1] + 1e-9, name))
    boxes.sort()
    candidates = []
    for k, (_, x1, y0, y1, a) in enumerate(boxes):
        for u0, _, v0, v1, b in boxes[k + 1:]:
            if u0 > x1:
                break
            if v0 <= y1 and y0 <= v1 and classes.touches(a, b):
                candidates.append((a, b) if pos[a] < pos[b] else (b, a))
    if scene.ground is not None:
        candidates += [(name, GROUND) for name in scene.body_names]
    rank = {False: 0, True: 1}  # body-body before body-static / body-ground
    candidates.sort(key=lambda q: (rank[q[1] in classes.fixed], q[1] == GROUND, pos[q[0]],
                                   pos[q[1]]))
    out = []
    for a, b in candidates:
        if classes.value(a, b).collide:
            gap = initial_gap(scene, a, b, things)
            if abs(gap) <= TOUCHING:
                out.append((a, b, gap))
    return out


class PymunkModel:
    """One pymunk Space holding one 2D Scene; ``advance(n)`` steps, ``read()`` samples."""

    def __init__(self, scene: Scene, dt: float, options: dict[str, Any] | None = None):
        if _pm is None:  # pragma: no cover
            raise ImportError("pymunk is not installed")
        if scene.dimension != 2:
            raise ValueError("pymunk is 2D")
        self.scene = scene
        self.dt = float(dt)
        self.options = engine_options(scene) if options is None else options
        space = _pm.Space(threaded=False)
        g = scene.effects.gravity_vector(2)
        space.gravity = (float(g[0]), float(g[1]))
        space.damping = 1.0
        space.sleep_time_threshold = math.inf
        self.iterations_reason = "Chipmunk's default"
        if scene.effects.contact:  # CONTACTS.md recipe; without contact nothing changes
            space.iterations, self.iterations_reason = contact_iterations(scene)
            space.collision_slop = CONTACT_SLOP
        if self.options.get("iterations") is not None:
            space.iterations = int(self.options["iterations"])
            self.iterations_reason = "engine_options.pymunk.iterations"
        if self.options.get("collision_slop") is not None:
            space.collision_slop = float(self.options["collision_slop"])
        self.space = space
        self.bodies: list[Any] = []
        for body in scene.bodies:
            pb = _pm.Body(float(body.mass), float(body.moment), body_type=_pm.Body.DYNAMIC)
            # Order matters: the angle rotates about the centre of gravity, and the position
            # setter places the centre of gravity from the origin with the current angle.
            pb.center_of_gravity = (float(body.com[0]), float(body.com[1]))
            pb.angle = float(body.angle)
            pb.position = (float(body.position[0]), float(body.position[1]))
            pb.velocity = (float(body.velocity[0]), float(body.velocity[1]))
            pb.angular_velocity = float(body.angular_velocity[0])
            space.add(pb)
            self.bodies.append(pb)
        self.springs: list[Any] = []
        for s in scene.effects.springs:
            a = self.bodies[s.body_a]
            b = space.static_body if s.body_b is None else self.bodies[s.body_b]
            spring = _pm.DampedSpring(a, b, (float(s.attach_a[0]), float(s.attach_a[1])),
                                      (float(s.attach_b[0]), float(s.attach_b[1])),
                                      float(s.rest_length), float(s.stiffness), float(s.damping))
            space.add(spring)
            self.springs.append(spring)
        self.shapes: dict[str, Any] = {}  # name -> its one shape (contact scenes only)
        self.collision_types: dict[str, int] = {}  # name -> its class + 1
        self.class_pairs: list[ClassPair] = []  # class_program: how each class pair is given
        if scene.effects.contact:
            self._add_contact()
        # Per-step forces: (body, linear drag, angular drag, load force, load torque).
        n = len(scene.bodies)
        lin, ang = np.zeros(n), np.zeros(n)
        for d in scene.effects.drag:
            for i in d.bodies:
                lin[i] += d.linear
                ang[i] += d.angular
        force = np.zeros((n, 2))
        torque = np.zeros(n)
        for ld in scene.effects.loads:
            force[ld.body] += ld.force
            torque[ld.body] += ld.torque[0]
        self.per_step = [(self.bodies[i], float(lin[i]), float(ang[i]), float(force[i, 0]),
                          float(force[i, 1]), float(torque[i])) for i in range(n)
                         if lin[i] or ang[i] or force[i].any() or torque[i]]
        # Space.step asserts a positive finite mass and moment of bodies added since its last
        # call; the direct C step below skips that, so the same check is made here once.
        for pb in self.bodies:
            if not (0.0 < pb.mass < math.inf and pb.moment > 0.0):
                raise ValueError(f"pymunk body with mass {pb.mass}, moment {pb.moment}")
        self._fast = None
        self._step = self.space.step
        if _cp is not None and hasattr(space, "_space") and all(
                hasattr(b, "_body") for b in self.bodies):
            self._fast = (_cp.cpBodyLocalToWorld, _cp.cpBodyGetVelocity, _cp.cpBodyGetAngle,
                          _cp.cpBodyGetAngularVelocity)
            self._handles = [(b._body, (float(body.com[0]), float(body.com[1])))
                             for b, body in zip(self.bodies, scene.bodies, strict=True)]
            handle = space._space
            step = _cp.cpSpaceStep
            self._step = lambda dt: step(handle, dt)  # noqa: E731 - see the module docstring
        self.native, self.native_reason = self._native()

    def _add_contact(self) -> None:
        """Shapes for every body, static and the ground; one collision type per material class
        and handlers for the class pairs whose values the shapes' product does not give.

        Each shape has mass 0 and density 0, so adding it leaves the body's mass, moment and
        centre of gravity as set (Chipmunk accumulates mass from shapes only when a shape has
        some; read back in ``settings``). Chipmunk multiplies the two shapes' friction and
        elasticity into the arbiter's at every step (cpArbiterUpdate), so a shape carries sqrt
        of its class's friction and restitution (``class_program``): a class pair whose product
        is the pair's value to 2 ulp needs nothing more; the others get a pre_solve that sets
        the arbiter's friction and restitution to the pair's values at every step, and a
        ``collide = false`` class pair a begin that rejects the contact. A handler per class
        pair, not per pair of surfaces: a pile of N bodies of one material has a handful
        (before: N^2 / 2, each a Python call per arbiter and step).
        """
        scene, space = self.scene, self.space
        static = space.static_body
        for pb, body in zip(self.bodies, scene.bodies, strict=True):
            self.shapes[body.name] = self._shape(pb, body.shape, (0.0, 0.0), 0.0)
        for st in scene.statics:
            self.shapes[st.name] = self._shape(static, st.shape, st.position,
                                               float(np.asarray(st.orientation).reshape(-1)[0]))
        if scene.ground is not None:
            from crosscheck.scene.contact import GROUND

            n = np.asarray(scene.ground.normal, float)
            t = np.array([n[1], -n[0]])
            p0 = n * float(scene.ground.offset)
            ext = GROUND_EXTENT
            verts = [p0 - ext * t, p0 + ext * t, p0 + ext * (t - n), p0 - ext * (t + n)]
            self.shapes[GROUND] = _pm.Poly(static, [(float(x), float(y)) for x, y in verts],
                                           radius=0.0)
        classes, self.shape_values, self.class_pairs = class_program(scene)
        self.classes = classes
        for name, shape in self.shapes.items():
            k = classes.of[name]
            shape.collision_type = k + 1  # 0 is Chipmunk's default type: keep it unused
            shape.friction, shape.elasticity = self.shape_values[k]
            self.collision_types[name] = k + 1
        space.add(*self.shapes.values())
        for q in self.class_pairs:
            types = (q.i + 1, q.j + 1)
            if q.how == "pre_solve":
                space.on_collision(*types, pre_solve=_set_pair_values,
                                   data=(float(q.material.friction),
                                         float(q.material.restitution)))
            elif q.how == "begin":
                space.on_collision(*types, begin=_never)

    @staticmethod
    def _shape(body, shape, position, angle):
        """The pymunk shape of a scene shape in ``body``'s frame, placed at (position, angle) in
        it (the identity for a body; the static's pose on the static body, whose frame is the
        world's). Mass and density 0, radius 0: the surface is the shape's own."""
        if shape.kind == "circle":
            return _pm.Circle(body, float(shape.radius),
                              offset=(float(position[0]), float(position[1])))
        verts = _world_vertices(shape, position, angle)
        return _pm.Poly(body, [(float(x), float(y)) for x, y in verts], radius=0.0)

    def _native(self) -> tuple[Any, str]:
        """The compiled stepper/reader (engines/_native.py) if it reads what read_raw reads.

        Returns (None, why) when it cannot be used: no cffi handles, a platform whose ABI for
        Chipmunk's two-double structs is not the one declared there, numba missing, or a row
        that differs from the Python getters' on this build's initial state.
        """
        if self._fast is None:
            return None, "pymunk's cffi handles are not available"
        try:
            from crosscheck.engines import _native
        except Exception as exc:  # pragma: no cover - numba is a dependency
            return None, f"numba unavailable ({exc})"
        if not _native.CHIPMUNK_ABI_OK:  # pragma: no cover - tested on x86-64 Linux
            return None, "cpVect calling convention not verified on this platform"
        def address(cdata) -> int:
            return int(_ffi.cast("uintptr_t", cdata))

        fns = tuple(address(_ffi.addressof(_cp, name)) for name in (
            "cpSpaceStep", "cpBodyLocalToWorld", "cpBodyGetVelocity", "cpBodyGetAngle",
            "cpBodyGetAngularVelocity"))
        bodies = np.array([address(b._body) for b in self.bodies], dtype=np.uintp)
        cogs = np.array([cog for _, cog in self._handles], float).reshape(-1, 2)
        n = len(self.bodies)
        com, angle, vel, omega = np.empty((1, n, 2)), np.empty((1, n)), np.empty((1, n, 2)), \
            np.empty((1, n))
        try:
            _native.chipmunk_read(fns, bodies, cogs, com, angle, vel, omega, 0)
        except Exception as exc:  # pragma: no cover - a numba failure falls back to Python
            return None, f"compiled reader failed ({type(exc).__name__}: {exc})"
        row = np.concatenate([com[0], angle[0, :, None], vel[0], omega[0, :, None]], axis=1)
        expected = np.array(self.read_raw(), float).reshape(n, 6)
        if not np.array_equal(row.view(np.uint64), expected.view(np.uint64)):
            return None, "compiled reader differs from the C getters called from Python"
        space = address(self.space._space)
        return (_native, fns, space, bodies, cogs), "compiled"

    def read_raw(self) -> list[float]:
        """One flat row: per body COM x, y, angle, COM velocity x, y, angular velocity.

        Through Chipmunk's C getters when pymunk exposes them (``cpBodyLocalToWorld`` of the
        centre of gravity, ``cpBodyGetVelocity``, ...): the same calls pymunk's properties make,
        without building a Vec2d per value (0.24 us per call through cffi). The compiled loop
        reads with the same getters and is checked against this row; this is the Python
        recorder's reader. ``read_raw_public`` is the same row through the public API.
        """
        if self._fast is None:
            return self.read_raw_public()
        to_world, vel, ang, spin = self._fast
        row: list[float] = []
        for handle, cog in self._handles:
            c = to_world(handle, cog)
            v = vel(handle)
            row += (c.x, c.y, ang(handle), v.x, v.y, spin(handle))
        return row

    def read_raw_public(self) -> list[float]:
        row: list[float] = []
        for b in self.bodies:
            c = b.local_to_world(b.center_of_gravity)
            v = b.velocity
            row += [c.x, c.y, b.angle, v.x, v.y, b.angular_velocity]
        return row

    def advance(self, nsteps: int) -> None:
        """nsteps steps: compiled when nothing is applied per step (the bare stepping loop)."""
        step, dt = self._step, self.dt
        if not self.per_step:
            if self.native is not None:
                native, fns, space, _, _ = self.native
                native.chipmunk_step(fns[0], space, dt, nsteps)
                return
            for _ in range(nsteps):
                step(dt)
            return
        forces = self.per_step
        for _ in range(nsteps):
            for body, c, ca, fx, fy, tau in forces:
                if c:
                    v = body.velocity
                    body.force = (fx - c * v.x, fy - c * v.y)
                else:
                    body.force = (fx, fy)
                body.torque = tau - ca * body.angular_velocity
            step(dt)

    @property
    def fused(self) -> bool:
        """True when the driver records through the compiled loop (``record``)."""
        return self.native is not None and not self.per_step

    @property
    def recording(self) -> str:
        if self.fused:
            return "compiled loop (numba) calling cpSpaceStep and the C getters"
        why = ("forces applied per step from Python" if self.per_step
               else f"compiled loop unavailable: {self.native_reason}")
        return f"python loop, cpSpaceStep and the C getters through cffi ({why})"

    # -- session (engines/session.py) ----------------------------------------------------
    @property
    def row_width(self) -> int:
        return 6 * len(self.bodies)

    def record(self, n_samples: int, k: int, rows: np.ndarray) -> tuple[int, str | None]:
        """The fused fast path: the rows the generic loop would fill, from the compiled loop.

        Rows from the first non-finite sample on are not valid; returns (valid rows, reason).
        """
        native, fns, space, bodies, cogs = self.native
        n = len(self.bodies)
        com, angle = np.empty((n_samples, n, 2)), np.empty((n_samples, n))
        vel, omega = np.empty((n_samples, n, 2)), np.empty((n_samples, n))
        count = native.chipmunk_record(fns, space, self.dt, k, bodies, cogs, com, angle, vel,
                                       omega)
        out = rows.reshape(n_samples, n, 6)
        out[..., 0:2], out[..., 2], out[..., 3:5], out[..., 5] = com, angle, vel, omega
        return count, (None if count == n_samples else "non-finite state")

    def convert(self, rows, t=None):
        """(T, 6N) rows -> ((com, angle, vel, omega), no extras): already crosscheck's terms
        (the centre of gravity in the world, Chipmunk's accumulated angle, never wrapped)."""
        rows = np.asarray(rows, float)
        raw = rows.reshape(len(rows), len(self.bodies), 6)
        return (raw[..., 0:2].copy(), raw[..., 2].copy(), raw[..., 3:5].copy(),
                raw[..., 5].copy()), {}

    def set_state(self, com, rot, vel, omega) -> None:
        for pb, c, a, v, w in zip(self.bodies, com, rot, vel, omega, strict=True):
            pb.angle = float(a)
            # The position setter places the body origin; the centre of gravity is rotated.
            cog = pb.center_of_gravity.rotated(float(a))
            pb.position = (float(c[0]) - cog.x, float(c[1]) - cog.y)
            pb.velocity = (float(v[0]), float(v[1]))
            pb.angular_velocity = float(w)

    def check(self) -> list[str]:
        return self.settings()[1]

    def effective(self, arrays=None) -> dict[str, Any]:
        return self.settings()[0]

    def close(self) -> None:
        pass

    def settings(self) -> tuple[dict[str, Any], list[str]]:
        """Settings read back from the Space, bodies and springs, and mismatches with the scene."""
        space = self.space
        problems: list[str] = []
        g = self.scene.effects.gravity_vector(2)
        gravity = [space.gravity.x, space.gravity.y]
        if gravity != [float(g[0]), float(g[1])]:
            problems.append(f"gravity read back {gravity}, scene has {list(g)}")
        if space.damping != 1.0:
            problems.append(f"space damping read back {space.damping}, must be 1")
        if space.threaded:
            problems.append("the space is threaded (not deterministic)")
        bodies = []
        for pb, body in zip(self.bodies, self.scene.bodies, strict=True):
            cog = [pb.center_of_gravity.x, pb.center_of_gravity.y]
            entry = {"name": body.name, "mass": pb.mass, "moment": pb.moment,
                     "center_of_gravity": cog, "shapes": len(pb.shapes),
                     "body_type": "dynamic" if pb.body_type == _pm.Body.DYNAMIC else "other"}
            if pb.mass != float(body.mass) or pb.moment != float(body.moment):
                problems.append(f"body {body.name!r}: mass/moment read back {pb.mass}/"
                                f"{pb.moment}, scene {body.mass}/{body.moment}")
            if cog != [float(body.com[0]), float(body.com[1])]:
                problems.append(f"body {body.name!r}: centre of gravity read back {cog}, "
                                f"scene {list(body.com)}")
            bodies.append(entry)
        springs = []
        for sp, s in zip(self.springs, self.scene.effects.springs, strict=True):
            springs.append({"mechanism": "DampedSpring", "stiffness": sp.stiffness,
                            "damping": sp.damping, "rest_length": sp.rest_length,
                            "anchor_a": list(sp.anchor_a), "anchor_b": list(sp.anchor_b),
                            "max_force": sp.max_force})
            if (sp.stiffness, sp.damping, sp.rest_length) != (
                    float(s.stiffness), float(s.damping), float(s.rest_length)):
                problems.append("a DampedSpring did not take the scene's parameters")
        contact = self.contact_settings(problems) if self.scene.effects.contact else None
        return {
            "recording": self.recording,
            "gravity": gravity,
            "damping": space.damping,
            "iterations": space.iterations,
            "iterations_reason": self.iterations_reason,
            "contact": contact,
            "sleep_time_threshold": space.sleep_time_threshold,
            "idle_speed_threshold": space.idle_speed_threshold,
            "threaded": bool(space.threaded),
            "bodies": bodies,
            "springs": springs,
            "forces": ("Body.force/torque per step from the start-of-step state"
                       if self.per_step else "none"),
            "options": dict(self.options),
        }, problems


    def contact_settings(self, problems: list[str]) -> dict[str, Any]:
        """The contact model read back: space settings, shapes, and every class pair with how
        Chipmunk gets its values (from the shapes and handlers pymunk holds, not from the
        scene): the product of the two classes' shapes' values, or the handler's values."""
        space = self.space
        wanted = float(self.options.get("collision_slop") or CONTACT_SLOP)
        if space.collision_slop != wanted:
            problems.append(f"collision_slop read back {space.collision_slop}, wanted {wanted}")
        shapes = []
        for name, shape in self.shapes.items():
            kind = type(shape).__name__
            k = self.classes.of[name]
            entry = {"name": name, "shape": kind, "collision_type": shape.collision_type,
                     "class": k, "mass": shape.mass, "density": shape.density,
                     "radius": shape.radius, "friction": shape.friction,
                     "elasticity": shape.elasticity, "static": shape.body is space.static_body}
            if kind == "Poly":
                entry["vertices"] = [[v.x, v.y] for v in shape.get_vertices()]
            if shape.mass != 0.0 or shape.density != 0.0:
                problems.append(f"shape of {name!r} has mass {shape.mass}, density "
                                f"{shape.density}: it would change the body's mass properties")
            if (shape.collision_type, shape.friction, shape.elasticity) != (
                    k + 1, *self.shape_values[k]):
                problems.append(f"shape of {name!r}: collision type, friction, elasticity read "
                                f"back {shape.collision_type}, {shape.friction}, "
                                f"{shape.elasticity}; class {k} wants {k + 1}, "
                                f"{self.shape_values[k]}")
            shapes.append(entry)
        # every shape of a class carries the class's values (checked above), so one shape per
        # class gives the product Chipmunk computes for every pair of a class pair
        first = {self.classes.of[name]: shape for name, shape in reversed(self.shapes.items())}
        pairs = []
        for q in self.class_pairs:
            types = (q.i + 1, q.j + 1)
            handler = space._handlers.get(types)
            m = q.material
            entry = {"a": q.a, "b": q.b, "classes": [q.i, q.j],
                     "class_sizes": [len(self.classes.members[q.i]),
                                     len(self.classes.members[q.j])],
                     "source": m.source, "collision_types": list(types), "collide": m.collide}
            if q.how == "shapes":
                sa, sb = first[q.i], first[q.j]
                fr, el = sa.friction * sb.friction, sa.elasticity * sb.elasticity
                entry.update(handler=None, mechanism="Chipmunk's product of the shapes' values",
                             friction=m.friction, restitution=m.restitution,
                             chipmunk_friction=fr, chipmunk_restitution=el)
                if handler is not None:
                    problems.append(f"class pair {q.a!r}-{q.b!r}: a handler is registered, "
                                    "none expected")
                if not (_close(fr, m.friction) and _close(el, m.restitution)):
                    problems.append(f"class pair {q.a!r}-{q.b!r}: the shapes' products "
                                    f"{(fr, el)}, pair values {(m.friction, m.restitution)}")
            elif handler is None:
                problems.append(f"no collision handler for the class pair {q.a!r}-{q.b!r}")
            elif q.how == "pre_solve":
                values = handler.data.get("pre_solve")
                entry.update(handler="pre_solve sets arbiter friction and restitution",
                             friction=values[0], restitution=values[1])
                if handler.pre_solve is not _set_pair_values or values != (
                        float(m.friction), float(m.restitution)):
                    problems.append(f"pair {q.a!r}-{q.b!r}: handler sets {values}, pair "
                                    f"values are {(m.friction, m.restitution)}")
            else:
                entry["handler"] = "begin rejects the contact (collide = false)"
                if handler.begin is not _never:
                    problems.append(f"pair {q.a!r}-{q.b!r} (collide = false) is not "
                                    "rejected")
            pairs.append(entry)
        if len(space._handlers) != sum(q.how != "shapes" for q in self.class_pairs):
            problems.append(f"{len(space._handlers)} collision handlers registered, "
                            f"{sum(q.how != 'shapes' for q in self.class_pairs)} expected")
        warnings = [
            f"{a!r} and {b!r} start touching (gap {gap:.3g} m): Chipmunk makes no contact at "
            "distance 0 (CONTACTS.md C17), so the two act as apart until something presses "
            "them into overlap (a touching cradle gives 0, 0, 1 instead of -1/3, 2/3, 2/3); "
            "start them apart or overlapping by 1e-9 m"
            for a, b, gap in touching_pairs(self.scene)]
        return {
            "collision_slop": space.collision_slop,
            "collision_bias": space.collision_bias,
            "collision_persistence": space.collision_persistence,
            "iterations": space.iterations,
            "iterations_reason": self.iterations_reason,
            "ground": (f"Poly, top edge on the ground line, {GROUND_EXTENT:g} m either side "
                       "and deep" if self.scene.ground is not None else None),
            "handler": ("one collision type per material class, its shapes sqrt of the "
                        "class's friction and restitution (Chipmunk multiplies the two); "
                        "class pairs whose product is not the pair value within "
                        f"{PRODUCT_ULPS} ulp: pre_solve sets Arbiter.friction and "
                        "Arbiter.restitution to the pair's values; collide = false: begin "
                        "sets process_collision = False"),
            "handlers": len(space._handlers),
            "shapes": shapes,
            "pairs": pairs,
            "pairs_listed": "one entry per class pair (a-b: one of its pairs), not per pair",
            "warnings": warnings,
        }


class PymunkEngine(EngineBase):
    name = "pymunk"
    effect_reasons = {**EngineBase.effect_reasons,
                      "fluid": "Pymunk has no fluid: no grid fluid and no fluid model (no "
                               "buoyancy, no fluid drag)",
                      "medium": "Pymunk has no fluid model (no buoyancy, no fluid drag)"}

    def check_options(self, scene: Scene) -> None:
        engine_options(scene)  # raises CaseError on an unknown key

    def capabilities(self) -> Capabilities:
        return Capabilities(
            dimensions=frozenset({2}),
            shapes=frozenset(_SHAPES),
            effects=frozenset({"gravity", "springs", "drag", "loads", "contact"}),
            integrators=INTEGRATORS,
            notes=dict(INTEGRATOR_NOTES),
        )

    def version(self) -> str:
        if _pm is None:  # pragma: no cover
            return "not installed"
        return f"{_pm.version} (Chipmunk {_pm.chipmunk_version})"

    def not_applicable(self, scene: Scene, integrator: str) -> str | None:
        if _pm is None:  # pragma: no cover
            return "the pymunk package is not installed"
        if scene.effects.medium is not None:  # before the dimension: the reason that matters
            return self.effect_reasons["medium"]
        if scene.dimension != 2:
            return "pymunk is 2D"
        reason = super().not_applicable(scene, integrator)
        if reason is not None or not scene.effects.contact:
            return reason
        for st in scene.statics:
            if st.shape.kind not in _SHAPES:
                return f"pymunk has no {st.shape.kind} shape (static {st.name!r})"
        from crosscheck.scene.contact import material_classes

        classes = material_classes(scene)  # over class pairs: their number does not grow with N
        for i, j in classes.class_pairs():
            m = classes.values[i][j]
            if m.collide and (m.rolling_friction > 0 or m.torsional_friction > 0):
                a, b = next(classes.pairs_between(i, j))
                what = "rolling" if m.rolling_friction > 0 else "torsional"
                value = m.rolling_friction if m.rolling_friction > 0 else m.torsional_friction
                return (f"Chipmunk has no {what} friction (pair {a!r}-{b!r} has "
                        f"{what}_friction = {value:g} m): its contacts resist sliding only")
        return None

    def open(self, scene: Scene, integrator: str, dt: float) -> PymunkModel:
        return PymunkModel(scene, dt)
