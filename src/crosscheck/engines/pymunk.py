"""Pymunk (Chipmunk2D) adapter: 2D scenes only, state in crosscheck's convention.

Model (docs/engines.md, section Pymunk)
---------------------------------------
* One ``pymunk.Body(mass, moment)`` per scene body, no shapes (nothing collides; a shape with a
  mass or density would also recompute the body's mass, moment and centre of gravity). Set in this
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
this adapter adds nothing after building, queues nothing and registers no callback, so the
direct call is the same step at a quarter of the cost (0.17 instead of 0.68 us). Without
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
    "iterations": ("a positive integer (constraint solver iterations, Chipmunk default 10)", None),
}

_SHAPES = ("circle", "box", "polygon")


def engine_options(scene: Scene) -> dict[str, Any]:
    given = dict(scene.engine_options.get("pymunk", {}))
    out: dict[str, Any] = {key: default for key, (_, default) in OPTIONS.items()}
    for key, value in given.items():
        field = f"engine_options.pymunk.{key}"
        if key not in OPTIONS:
            raise CaseError(scene.source, field,
                            f"one of the Pymunk adapter's options {sorted(OPTIONS)}",
                            f"unknown option {key!r}")
        if isinstance(value, bool) or not isinstance(value, int) or value < 1:
            raise CaseError(scene.source, field, OPTIONS[key][0], value)
        out[key] = value
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
        if self.options.get("iterations") is not None:
            space.iterations = int(self.options["iterations"])
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
        return {
            "recording": self.recording,
            "gravity": gravity,
            "damping": space.damping,
            "iterations": space.iterations,
            "sleep_time_threshold": space.sleep_time_threshold,
            "idle_speed_threshold": space.idle_speed_threshold,
            "threaded": bool(space.threaded),
            "bodies": bodies,
            "springs": springs,
            "forces": ("Body.force/torque per step from the start-of-step state"
                       if self.per_step else "none"),
            "options": dict(self.options),
        }, problems


class PymunkEngine(EngineBase):
    name = "pymunk"
    effect_reasons = {**EngineBase.effect_reasons,
                      "fluid": "Pymunk has no grid fluid"}

    def check_options(self, scene: Scene) -> None:
        engine_options(scene)  # raises CaseError on an unknown key

    def capabilities(self) -> Capabilities:
        return Capabilities(
            dimensions=frozenset({2}),
            shapes=frozenset(_SHAPES),
            effects=frozenset({"gravity", "springs", "drag", "loads"}),
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
        if scene.dimension != 2:
            return "pymunk is 2D"
        return super().not_applicable(scene, integrator)

    def open(self, scene: Scene, integrator: str, dt: float) -> PymunkModel:
        return PymunkModel(scene, dt)
