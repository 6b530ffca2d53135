"""MuJoCo adapter: a Scene compiled to MJCF, stepped, and read back in crosscheck's frames.

What is mapped how (docs/engines.md has the full table):

* **Bodies, 3D.** One MuJoCo body per scene body, a child of the world body with a free joint. The
  MuJoCo body frame *is* the declared body frame: ``qpos[0:3]``/``qpos[3:7]`` are the declared
  frame's origin and orientation. The inertial is explicit (``mass``, ``pos`` = the centre of mass
  in the body frame, ``quat`` + ``diaginertia`` from NumPy's eigen-decomposition of the full
  tensor), so MuJoCo never derives mass properties from geometry. With the engine option
  ``align_free = true`` the MuJoCo body frame is instead the inertial frame (centre of mass,
  principal axes), what MuJoCo's own ``freejoint align="true"`` does; the adapter converts back.
* **Bodies, 2D.** Planar joints in the x-y plane: a slide along x, a slide along y and a hinge about
  z. The hinge passes through the centre of mass, so the two slides measure the centre of mass and
  the hinge angle is the body angle. Out-of-plane moments equal the in-plane one (any positive
  values satisfying the triangle inequality would do; no out-of-plane motion exists).
* **Gravity** ``m.opt.gravity`` = the scene's, zero when the scene has none (MuJoCo's default is
  -9.81 along z). **Contact** is disabled (``mjDSBL_CONTACT``; there are no geoms either):
  contact scenes are "not applicable" until the contact issue.
* **Springs** are spatial tendons between two sites with ``stiffness``, ``damping`` and
  ``springlength = (L0, L0)``: MuJoCo's tendon force is -k (L - L0) - c dL/dt along the line of
  the sites, exactly the scene's spring, and it is evaluated inside every RK4 stage.
* **Drag** is joint damping where that is exactly the scene's drag: the slides of a 2D body (at its
  centre of mass) and the hinge; the free joint's rotational dofs (isotropic damping of the
  body-local angular velocity is -c w in any frame); its translational dofs only when they carry
  the centre-of-mass velocity (centre of mass at the body origin, or ``align_free``). Linear drag
  of a 3D body whose centre of mass is off its origin has no exact MuJoCo mechanism (the free
  joint's translational dofs are the origin's velocity): it is applied through ``xfrc_applied``,
  recomputed from the state at the start of every step and held over that step (under RK4 that
  force is constant across the four stages: first order in the drag term).
* **Loads** are constant ``xfrc_applied`` rows (force at the centre of mass, torque, world frame),
  set once.

Stepping, with no Python call per step (engine option ``stepping``):

* ``compiled`` (default): a compiled loop (numba, ``engines/_native.py``) calls MuJoCo's C
  ``mj_step(m, d)`` k times per sample and copies ``qpos``/``qvel`` from ``data``: the same steps
  as ``mj_step(m, d, nstep=k)``, without a Python call per sample (those cost ~0.8 us each
  against ~15 us of stepping between two samples of a one-body Euler scene). It stops at the
  first sample after which one of MuJoCo's warning counters is set, as ``mujoco.rollout`` does.
  ``mj_step`` is taken from the ``libmujoco`` the bindings already loaded (``RTLD_NOLOAD``);
  without it (or without numba) the adapter falls back to ``rollout`` and says so.
* ``rollout``: ``mujoco.rollout`` in chunks, keeping every k-th state (it writes every step's
  full state: ~50 ns a step).
* ``nstep``: ``mj_step(m, d, nstep=k)`` per sample.

A Python loop only for per-step drag. Only ``qpos``/``qvel`` are kept; the conversion to
centre-of-mass position and velocity and world angular velocity is done from them after the
run, vectorised (so MuJoCo's derived arrays, stale after ``mj_step``, are never read). All three
recorders give bit-identical samples (tests/engines/test_mujoco.py).
"""

from __future__ import annotations

import threading
import time
from dataclasses import dataclass
from typing import Any

import numpy as np

from crosscheck.engines.base import Capabilities, EngineBase, sampling_plan
from crosscheck.errors import CaseError
from crosscheck.rotations import matrix_to_quat, quat_conj, quat_mul, quat_to_matrix
from crosscheck.scene.model import Scene
from crosscheck.state import Trajectory, TrajectoryRecorder

try:  # the registry imports this module lazily; a missing mujoco is "not applicable"
    import mujoco
    from mujoco import rollout as _rollout
except ImportError:  # pragma: no cover - mujoco is a declared dependency
    mujoco = None
    _rollout = None

# Integrator names, MuJoCo's default (Euler) first.
INTEGRATORS: tuple[str, ...] = ("euler", "rk4", "implicit", "implicitfast", "discrete")
_MJ_INTEGRATOR = {"euler": "mjINT_EULER", "rk4": "mjINT_RK4", "implicit": "mjINT_IMPLICIT",
                  "implicitfast": "mjINT_IMPLICITFAST", "discrete": "mjINT_DISCRETE"}

INTEGRATOR_NOTES = {
    "euler": "semi-implicit Euler: v += h a(t), then q += h v(t+h), the quaternion through the "
             "exponential map of the body-local angular velocity; gyroscopic term explicit (a "
             "tumbling body gains energy); joint damping implicit unless eulerdamp = false",
    "rk4": "classic 4-stage Runge-Kutta on (qpos, qvel), quaternion stages by the exponential "
           "map; tendon springs and joint damping are evaluated in every stage, forces set in "
           "xfrc_applied once per step are constant across the stages",
    "implicit": "implicit-in-velocity Euler: the velocity derivatives of all smooth forces "
                "including the gyroscopic term are implicit (a tumbling body loses energy)",
    "implicitfast": "implicit-in-velocity Euler without the Coriolis derivatives, except for "
                    "standalone free bodies where MuJoCo reinstates them (same step as implicit)",
    "discrete": "velocity-stepping: implicit update with damping and stiffness in the effective "
                "inertia M + hD + h^2 K, then q += h v(t+h)",
}

# Engine options a case may pin in [engine_options.mujoco]: name -> (allowed values, default).
OPTIONS: dict[str, tuple[tuple[Any, ...], Any]] = {
    "jacobian": (("auto", "dense", "sparse"), "auto"),
    "eulerdamp": ((True, False), True),
    "align_free": ((True, False), False),
    "drag": (("auto", "per_step"), "auto"),
    "stepping": (("compiled", "rollout", "nstep"), "compiled"),
}

# A run fails at the first sample at or after which MuJoCo's own check fired (mj_checkPos,
# mj_checkVel, mj_checkAcc: NaN, Inf or a value beyond mjMAXVAL = 1e10).
_UNSTABLE = "MuJoCo flagged an instability (NaN, Inf or |value| > 1e10 in qpos, qvel or qacc)"
# Largest rollout chunk kept in memory at once (every step's state is written by rollout).
ROLLOUT_CHUNK_BYTES = 4 << 20
_SCRATCH = threading.local()


def _scratch(rows: int, width: int) -> np.ndarray:
    """A per-thread reusable (1, rows, width) array: a fresh one per run costs page faults
    comparable to stepping a small model (rollout writes every step's state into it)."""
    size = rows * width
    buf = getattr(_SCRATCH, "buf", None)
    if buf is None or buf.size < size:
        buf = np.empty(size)
        _SCRATCH.buf = buf
    return buf[:size].reshape(1, rows, width)


def _native_stepper() -> tuple[Any, int | None, str]:
    """(engines._native, address of the C ``mj_step``, "") or (None, None, why not).

    The address comes from the libmujoco that ``import mujoco`` already loaded (``RTLD_NOLOAD``
    fails rather than load a second copy), so the compiled loop steps the bindings' own model
    and data with their own library. Computed once per process.
    """
    global _NATIVE
    if _NATIVE is None:
        _NATIVE = _find_native_stepper()
    return _NATIVE


_NATIVE: tuple[Any, int | None, str] | None = None


def _find_native_stepper() -> tuple[Any, int | None, str]:
    import ctypes
    import os
    from pathlib import Path

    try:
        from crosscheck.engines import _native
    except Exception as exc:  # pragma: no cover - numba is a dependency
        return None, None, f"numba unavailable ({exc})"
    here = Path(mujoco.__file__).parent
    names = sorted(here.glob("libmujoco.so*")) + sorted(here.glob("libmujoco*.dylib")) + \
        sorted(here.glob("mujoco*.dll"))
    mode = getattr(os, "RTLD_NOLOAD", 0) | getattr(os, "RTLD_LAZY", 0)
    for path in names:
        try:
            lib = ctypes.CDLL(str(path), mode=mode)
            address = ctypes.cast(lib.mj_step, ctypes.c_void_p).value
        except (OSError, AttributeError):
            continue
        if address:
            return _native, int(address), ""
    return None, None, "the libmujoco loaded by the bindings was not found"


def _roller():
    """A per-thread mujoco.rollout runner without a thread pool (runs on the calling thread)."""
    roller = getattr(_SCRATCH, "roller", None)
    if roller is None:
        roller = _SCRATCH.roller = _rollout.Rollout(nthread=0)
    return roller


_SHAPES_3D = ("sphere", "box", "capsule", "cylinder", "mesh")
_SHAPES_2D = ("circle", "box", "polygon")


def _f(x: float) -> str:
    """Shortest decimal that parses back to exactly the same double."""
    return repr(float(x))


def _v(values) -> str:
    return " ".join(_f(x) for x in np.ravel(values))


def engine_options(scene: Scene) -> dict[str, Any]:
    """The case's [engine_options.mujoco] over the defaults; unknown keys or values refused."""
    given = dict(scene.engine_options.get("mujoco", {}))
    out = {}
    for key, value in given.items():
        if key not in OPTIONS:
            raise CaseError(scene.source, f"engine_options.mujoco.{key}",
                            f"one of the MuJoCo adapter's options {sorted(OPTIONS)}",
                            f"unknown option {key!r}")
        allowed, _ = OPTIONS[key]
        if not any(value == a and type(value) is type(a) for a in allowed):
            raise CaseError(scene.source, f"engine_options.mujoco.{key}", f"one of {list(allowed)}",
                            value)
        out[key] = value
    return {key: out.get(key, default) for key, (_, default) in OPTIONS.items()}


@dataclass
class _BodyMap:
    """How one scene body sits in the MuJoCo model."""

    body_id: int
    qadr: int
    vadr: int
    # MuJoCo body frame relative to the declared frame: x_mj = x_decl + R_decl t, R_mj = R_decl P.
    t: np.ndarray  # (3,) or (2,)
    q_p: np.ndarray  # (4,) quaternion of P (identity unless aligned)
    com_mj: np.ndarray  # centre of mass in the MuJoCo body frame (3D) / in the body frame (2D)
    drag_linear: float  # total coefficients of all drag entries naming the body
    drag_angular: float
    linear_drag_per_step: bool
    angular_drag_per_step: bool


class MujocoModel:
    """One compiled MuJoCo model of one Scene, integrator and step, with the state conversions.

    ``set_initial_state()`` writes the scene's t = 0 state into ``data``; ``advance(n)`` steps;
    ``record(n, k)`` steps while sampling every k steps; ``convert(qpos, qvel)`` turns (T, nq)/
    (T, nv) samples into crosscheck's convention; ``state()`` converts the current data;
    ``effective()`` reads the settings back from the compiled model.
    """

    def __init__(self, scene: Scene, integrator: str, dt: float,
                 options: dict[str, Any] | None = None):
        if mujoco is None:  # pragma: no cover
            raise ImportError("mujoco is not installed")
        if integrator not in INTEGRATORS:
            raise ValueError(f"unknown MuJoCo integrator {integrator!r}; known: {INTEGRATORS}")
        self.scene = scene
        self.integrator = integrator
        self.dt = float(dt)
        self.options = engine_options(scene) if options is None else options
        self.dim = scene.dimension
        self.aligned = bool(self.options["align_free"]) and self.dim == 3
        self.mjcf = self._mjcf()
        self.model = mujoco.MjModel.from_xml_string(self.mjcf)
        self.data = mujoco.MjData(self.model)
        self._configure()
        self._map_bodies()
        self._set_damping_and_loads()

    # -- model ----------------------------------------------------------------------------
    def _frame(self, body) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(t, q_P, inertial quaternion in the MuJoCo frame, principal moments) of a 3D body."""
        moments, axes = np.linalg.eigh(np.asarray(body.inertia, float))
        if np.linalg.det(axes) < 0:  # a proper rotation: flip one principal axis
            axes[:, 2] *= -1.0
        q_axes = matrix_to_quat(axes)
        if self.aligned:
            return np.asarray(body.com, float), q_axes, np.array([1.0, 0, 0, 0]), moments
        return np.zeros(3), np.array([1.0, 0, 0, 0]), q_axes, moments

    def _site_pos(self, body_index: int, local: np.ndarray) -> np.ndarray:
        """A declared body-frame point in its MuJoCo body frame."""
        body = self.scene.bodies[body_index]
        if self.dim == 2:
            return np.array([local[0], local[1], 0.0])
        t, q_p, _, _ = self._frame(body)
        return quat_to_matrix(q_p).T @ (np.asarray(local, float) - t)

    def _mjcf(self) -> str:
        scene = self.scene
        sites: dict[int, list[str]] = {i: [] for i in range(len(scene.bodies))}
        world_sites: list[str] = []
        tendons: list[str] = []
        for k, spring in enumerate(scene.effects.springs):
            pa = self._site_pos(spring.body_a, spring.attach_a)
            sites[spring.body_a].append(f'<site name="sa{k}" pos="{_v(pa)}"/>')
            if spring.body_b is None:
                anchor = np.asarray(spring.attach_b, float)
                if self.dim == 2:
                    anchor = np.array([anchor[0], anchor[1], 0.0])
                world_sites.append(f'<site name="sb{k}" pos="{_v(anchor)}"/>')
            else:
                pb = self._site_pos(spring.body_b, spring.attach_b)
                sites[spring.body_b].append(f'<site name="sb{k}" pos="{_v(pb)}"/>')
            # Two equal springlength values: no dead band, rest length exactly L0 (a single -1
            # would make the compiler take the length at qpos0).
            tendons.append(
                f'<spatial name="t{k}" stiffness="{_f(spring.stiffness)}" '
                f'damping="{_f(spring.damping)}" '
                f'springlength="{_f(spring.rest_length)} {_f(spring.rest_length)}">'
                f'<site site="sa{k}"/><site site="sb{k}"/></spatial>')
        bodies = []
        for i, body in enumerate(scene.bodies):
            if self.dim == 3:
                _, _, q_in, moments = self._frame(body)
                com_mj = np.zeros(3) if self.aligned else np.asarray(body.com, float)
                joints = f'<freejoint name="j{i}"/>'
                inertial = (f'<inertial pos="{_v(com_mj)}" quat="{_v(q_in)}" '
                            f'mass="{_f(body.mass)}" diaginertia="{_v(moments)}"/>')
            else:
                c = np.array([body.com[0], body.com[1], 0.0])
                moment = body.moment
                joints = (f'<joint name="j{i}x" type="slide" axis="1 0 0"/>'
                          f'<joint name="j{i}y" type="slide" axis="0 1 0"/>'
                          f'<joint name="j{i}r" type="hinge" axis="0 0 1" pos="{_v(c)}"/>')
                inertial = (f'<inertial pos="{_v(c)}" mass="{_f(body.mass)}" '
                            f'diaginertia="{_v([moment, moment, moment])}"/>')
            bodies.append(f'<body name="b{i}">{joints}{inertial}{"".join(sites[i])}</body>')
        tendon_xml = f"<tendon>{''.join(tendons)}</tendon>" if tendons else ""
        # inertiafromgeom false and no bounds: the inertial is used exactly as written.
        return (
            '<mujoco model="crosscheck">'
            '<compiler angle="radian" inertiafromgeom="false" boundmass="0" boundinertia="0" '
            'balanceinertia="false" alignfree="false"/>'
            f'<worldbody>{"".join(world_sites)}{"".join(bodies)}</worldbody>'
            f"{tendon_xml}</mujoco>"
        )

    def _configure(self) -> None:
        m = self.model
        opt = m.opt
        opt.timestep = self.dt
        opt.integrator = int(getattr(mujoco.mjtIntegrator, _MJ_INTEGRATOR[self.integrator]))
        g = self.scene.effects.gravity_vector(self.dim)
        opt.gravity[:] = [g[0], g[1], g[2] if self.dim == 3 else 0.0]
        # Explicitly zero what could add forces the scene did not ask for.
        opt.wind[:] = 0.0
        opt.magnetic[:] = 0.0
        opt.density = 0.0
        opt.viscosity = 0.0
        opt.jacobian = int(getattr(mujoco.mjtJacobian,
                                   f"mjJAC_{self.options['jacobian'].upper()}"))
        dis = mujoco.mjtDisableBit
        flags = int(opt.disableflags) | int(dis.mjDSBL_CONTACT)
        # A blow-up must stay a blow-up (NaN reaches the recorder), not a silent reset to qpos0.
        flags |= int(dis.mjDSBL_AUTORESET)
        if not self.options["eulerdamp"]:
            flags |= int(dis.mjDSBL_EULERDAMP)
        # Springs and dampers are how tendons and joint damping act: keep them on.
        flags &= ~(int(dis.mjDSBL_SPRING) | int(dis.mjDSBL_DAMPER) | int(dis.mjDSBL_GRAVITY))
        opt.disableflags = flags

    def _map_bodies(self) -> None:
        m = self.model
        scene = self.scene
        lin = np.zeros(len(scene.bodies))
        ang = np.zeros(len(scene.bodies))
        for drag in scene.effects.drag:
            for b in drag.bodies:
                lin[b] += drag.linear
                ang[b] += drag.angular
        per_step_all = self.options["drag"] == "per_step"
        self.bodies: list[_BodyMap] = []
        for i, body in enumerate(scene.bodies):
            bid = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, f"b{i}")
            if self.dim == 3:
                jid = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, f"j{i}")
                t, q_p, _, _ = self._frame(body)
                com_mj = np.zeros(3) if self.aligned else np.asarray(body.com, float)
                # Joint damping on the translational dofs damps the origin's velocity: exact only
                # when the origin is the centre of mass.
                lin_step = lin[i] > 0 and (per_step_all or bool(np.any(com_mj != 0.0)))
            else:
                jid = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, f"j{i}x")
                t, q_p = np.zeros(2), np.array([1.0, 0, 0, 0])
                com_mj = np.asarray(body.com, float)
                lin_step = lin[i] > 0 and per_step_all
            self.bodies.append(_BodyMap(
                body_id=bid, qadr=int(m.jnt_qposadr[jid]), vadr=int(m.jnt_dofadr[jid]), t=t,
                q_p=q_p, com_mj=com_mj, drag_linear=float(lin[i]), drag_angular=float(ang[i]),
                linear_drag_per_step=bool(lin_step),
                angular_drag_per_step=bool(ang[i] > 0 and per_step_all)))
        nb = len(self.bodies)
        if self.dim == 3:
            self._qidx = np.array([[b.qadr + k for k in range(7)] for b in self.bodies]).reshape(
                nb, 7)
            self._vidx = np.array([[b.vadr + k for k in range(6)] for b in self.bodies]).reshape(
                nb, 6)
        else:
            self._qidx = np.array([[b.qadr + k for k in range(3)] for b in self.bodies]).reshape(
                nb, 3)
            self._vidx = np.array([[b.vadr + k for k in range(3)] for b in self.bodies]).reshape(
                nb, 3)
        self._com_mj = np.array([b.com_mj for b in self.bodies]).reshape(nb, self.dim)
        self._q_p = np.array([b.q_p for b in self.bodies]).reshape(nb, 4)
        self._t = np.array([b.t for b in self.bodies]).reshape(nb, self.dim)

    def _set_damping_and_loads(self) -> None:
        m, d = self.model, self.data
        # Joint damping is set on the compiled model, per dof (a free joint's XML damping is one
        # value for all six dofs). MuJoCo reads dof_damping at run time.
        m.dof_damping[:] = 0.0
        m.dof_frictionloss[:] = 0.0
        m.dof_armature[:] = 0.0
        for b in self.bodies:
            if self.dim == 3:
                if not b.linear_drag_per_step:
                    m.dof_damping[b.vadr:b.vadr + 3] = b.drag_linear
                if not b.angular_drag_per_step:
                    m.dof_damping[b.vadr + 3:b.vadr + 6] = b.drag_angular
            else:
                if not b.linear_drag_per_step:
                    m.dof_damping[b.vadr:b.vadr + 2] = b.drag_linear
                if not b.angular_drag_per_step:
                    m.dof_damping[b.vadr + 2] = b.drag_angular
        # Constant loads: one xfrc_applied row per body, force at the centre of mass (xipos) and
        # torque, both world frame. mj_step never clears xfrc_applied, so setting it once is enough.
        self._loads = np.zeros((m.nbody, 6))
        for load in self.scene.effects.loads:
            bid = self.bodies[load.body].body_id
            if self.dim == 3:
                self._loads[bid, :3] += load.force
                self._loads[bid, 3:] += load.torque
            else:
                self._loads[bid, :2] += load.force
                self._loads[bid, 5] += load.torque[0]
        d.xfrc_applied[:] = self._loads
        self._has_loads = bool(np.any(self._loads))
        self._step_bodies = [i for i, b in enumerate(self.bodies)
                             if b.linear_drag_per_step or b.angular_drag_per_step]
        self.per_step_forces = bool(self._step_bodies)
        if self.per_step_forces:
            sb = self._step_bodies
            self._sb_ids = np.array([self.bodies[i].body_id for i in sb])
            self._sb_lin = np.array([self.bodies[i].drag_linear
                                     * self.bodies[i].linear_drag_per_step for i in sb])[:, None]
            self._sb_ang = np.array([self.bodies[i].drag_angular
                                     * self.bodies[i].angular_drag_per_step for i in sb])[:, None]
            self._sb_q = self._qidx[sb]
            self._sb_v = self._vidx[sb]
            self._sb_c = self._com_mj[sb]

    # -- state ----------------------------------------------------------------------------
    def set_initial_state(self) -> None:
        """Write the scene's t = 0 state (declared frames, COM velocity, world omega) to data."""
        m, d = self.model, self.data
        mujoco.mj_resetData(m, d)
        d.xfrc_applied[:] = self._loads
        for b, body in zip(self.bodies, self.scene.bodies, strict=True):
            w = np.asarray(body.angular_velocity, float)
            if self.dim == 3:
                r = quat_to_matrix(body.orientation)
                q_mj = quat_mul(body.orientation, b.q_p) if self.aligned else np.asarray(
                    body.orientation, float)
                r_mj = quat_to_matrix(q_mj)
                x_mj = np.asarray(body.position, float) + r @ b.t
                rc = r_mj @ b.com_mj  # centre of mass relative to the MuJoCo origin, world
                d.qpos[b.qadr:b.qadr + 3] = x_mj
                d.qpos[b.qadr + 3:b.qadr + 7] = q_mj
                # qvel[0:3] is the MuJoCo origin's velocity, qvel[3:6] the body-local omega.
                d.qvel[b.vadr:b.vadr + 3] = np.asarray(body.velocity, float) - np.cross(w, rc)
                d.qvel[b.vadr + 3:b.vadr + 6] = r_mj.T @ w
            else:
                # Slides carry the centre of mass minus its body-frame offset; the hinge, through
                # the centre of mass, the angle.
                d.qpos[b.qadr:b.qadr + 2] = body.com_world() - b.com_mj
                d.qpos[b.qadr + 2] = body.angle
                d.qvel[b.vadr:b.vadr + 2] = body.velocity
                d.qvel[b.vadr + 2] = w[0]
        # Derived arrays consistent with the state (not needed by the reader, which uses qpos and
        # qvel only, but anyone inspecting data sees the set state).
        mujoco.mj_forward(m, d)

    def convert(self, qpos: np.ndarray, qvel: np.ndarray) -> tuple[np.ndarray, ...]:
        """(T, nq), (T, nv) samples -> com (T,N,d), rot (T,N,4)|(T,N), vel (T,N,d), omega."""
        qpos = np.asarray(qpos, float).reshape(-1, self.model.nq)
        qvel = np.asarray(qvel, float).reshape(-1, self.model.nv)
        q = qpos[:, self._qidx]  # (T, N, 7) or (T, N, 3)
        v = qvel[:, self._vidx]
        if self.dim == 2:
            com = q[..., :2] + self._com_mj
            return com, q[..., 2], v[..., :2].copy(), v[..., 2].copy()
        quat = q[..., 3:7] / np.linalg.norm(q[..., 3:7], axis=-1, keepdims=True)
        r_mj = quat_to_matrix(quat)  # (T, N, 3, 3), MuJoCo frame to world
        omega = np.einsum("tnij,tnj->tni", r_mj, v[..., 3:6])  # body-local -> world
        rc = np.einsum("tnij,nj->tni", r_mj, self._com_mj)
        com = q[..., 0:3] + rc
        vel = v[..., 0:3] + np.cross(omega, rc)  # origin velocity -> centre-of-mass velocity
        if self.aligned:
            quat = quat_mul(quat, quat_conj(self._q_p)[None])
        return com, quat, vel, omega

    def state(self) -> tuple[np.ndarray, ...]:
        """The current state of data, (N, ...) arrays in crosscheck's convention."""
        com, rot, vel, omega = self.convert(self.data.qpos[None], self.data.qvel[None])
        return com[0], rot[0], vel[0], omega[0]

    # -- stepping -------------------------------------------------------------------------
    def _apply_step_forces(self) -> None:
        """Drag with no exact MuJoCo mechanism, from the state at the start of the step."""
        d = self.data
        q = d.qpos[self._sb_q]
        v = d.qvel[self._sb_v]
        force = self._loads[self._sb_ids].copy()
        if self.dim == 3:
            r = quat_to_matrix(q[:, 3:7])
            w = np.einsum("nij,nj->ni", r, v[:, 3:6])
            vcom = v[:, 0:3] + np.cross(w, np.einsum("nij,nj->ni", r, self._sb_c))
            force[:, :3] -= self._sb_lin * vcom
            force[:, 3:] -= self._sb_ang * w
        else:
            force[:, :2] -= self._sb_lin * v[:, 0:2]
            force[:, 5] -= self._sb_ang[:, 0] * v[:, 2]
        d.xfrc_applied[self._sb_ids] = force

    def advance(self, nsteps: int) -> None:
        """nsteps steps: one mj_step call when no force is recomputed per step."""
        if nsteps <= 0:
            return
        m, d = self.model, self.data
        if not self.per_step_forces:
            mujoco.mj_step(m, d, nsteps)
            return
        step, apply = mujoco.mj_step, self._apply_step_forces
        for _ in range(nsteps):
            apply()
            step(m, d)

    @property
    def recorder(self) -> str:
        """The recorder run() uses: "loop" (per-step forces, or nstep), "rollout", "compiled"."""
        if self.per_step_forces or self.options["stepping"] == "nstep":
            return "loop"
        if self.options["stepping"] == "compiled" and _native_stepper()[0] is not None:
            return "compiled"
        return "rollout"

    @property
    def stepping_mode(self) -> str:
        if self.per_step_forces:
            return "python loop: per-step xfrc_applied drag, mj_step"
        recorder = self.recorder
        if recorder == "compiled":
            return ("compiled loop (numba) calling mj_step(m, d) steps_per_sample times per "
                    "sample and copying qpos, qvel (the copies are inside wall_time)")
        if recorder == "rollout":
            fallback = "" if self.options["stepping"] == "rollout" else (
                f" (compiled loop unavailable: {_native_stepper()[2]})")
            return "mujoco.rollout in chunks, every steps_per_sample-th state kept" + fallback
        return "mj_step(m, d, nstep=steps_per_sample) per sample"

    def record(self, n_samples: int, k: int) -> tuple[np.ndarray, np.ndarray, float, float,
                                                      int, str | None]:
        """Step from the current state, sampling every k steps.

        Returns (qpos (n, nq), qvel (n, nv), stepping seconds, recording seconds spent in the
        loop, number of valid samples, failure reason or None). Sample 0 is the current state.
        A sample is invalid from the first one at which MuJoCo's instability check (NaN, Inf
        or |value| > 1e10 in qpos, qvel or qacc) has fired during a step leading to it, or
        the state is not finite.
        """
        recorder = self.recorder
        if recorder == "loop":
            return self._record_loop(n_samples, k)
        if recorder == "compiled":
            return self._record_compiled(n_samples, k)
        return self._record_rollout(n_samples, k)

    def _record_compiled(self, n, k):
        m, d = self.model, self.data
        native, step, _ = _native_stepper()
        qpos = np.empty((n, m.nq))
        qvel = np.empty((n, m.nv))
        qpos[0], qvel[0] = d.qpos, d.qvel
        warnings = d.warning.number
        warnings[:] = 0  # as mujoco.rollout does before stepping
        clock = time.perf_counter
        t0 = clock()
        # d.qpos, d.qvel and d.warning.number are views of data's own memory.
        count = native.mujoco_record(step, m._address, d._address, d.qpos, d.qvel, warnings, k,
                                     qpos, qvel)
        stepping = clock() - t0
        if count == n:
            # No warning: MuJoCo's checks catch NaN, Inf and |value| > 1e10 before they spread.
            return qpos, qvel, stepping, 0.0, n, None
        # Sample `count` is the first whose steps raised a warning; as in the rollout path, the
        # valid samples are those before it (and before any non-finite one).
        good = np.all(np.isfinite(qpos[:count]), axis=1) & np.all(np.isfinite(qvel[:count]),
                                                                   axis=1)
        return qpos, qvel, stepping, 0.0, int(np.argmin(np.append(good, False))), _UNSTABLE

    def _record_loop(self, n, k):
        m, d = self.model, self.data
        spec = int(mujoco.mjtState.mjSTATE_FULLPHYSICS)
        nstate = mujoco.mj_stateSize(m, spec)
        # Each sample is the full physics state [time, qpos, qvel, ...]: one C call to copy, and
        # a checkpoint the run can be replayed from.
        states = np.empty((n, nstate))
        rows, get = list(states), mujoco.mj_getState
        get(m, d, rows[0], spec)
        warning = d.warning
        flags = [int(getattr(mujoco.mjtWarning, w)) for w in
                 ("mjWARN_BADQACC", "mjWARN_BADQVEL", "mjWARN_BADQPOS")]

        def flagged() -> bool:
            return any(warning[f].number for f in flags)

        # mj_step(m, d, k) is called directly when nothing is applied per step.
        advance = self.advance if self.per_step_forces else None
        step = mujoco.mj_step
        clock = time.perf_counter
        stepping = 0.0
        done = 1
        checked = 0  # last sample known to precede any instability flag
        stopped = False
        start = clock()
        for i in range(1, n):
            t0 = clock()
            if advance is None:
                step(m, d, k)
            else:
                advance(k)
            stepping += clock() - t0
            get(m, d, rows[i], spec)
            # MuJoCo's instability counters cost ~1 us to read: every 64 samples, then the
            # exact sample is found by replaying from the last clean one.
            if not i & 63:
                if flagged():
                    done, stopped = i + 1, True
                    break
                checked = i
        else:
            done = n
        if stopped or flagged():
            advance = self.advance
            # Replay from the last clean sample, one sample at a time (deterministic: the
            # full physics state plus the applied forces determine every step).
            mujoco.mj_resetData(m, d)
            d.xfrc_applied[:] = self._loads
            mujoco.mj_setState(m, d, states[checked], spec)
            first = checked + 1
            while first < done:
                advance(k)
                if flagged():
                    break
                first += 1
            in_loop = clock() - start - stepping
            return (states[:, 1:1 + m.nq], states[:, 1 + m.nq:1 + m.nq + m.nv], stepping,
                    in_loop, first, _UNSTABLE)
        in_loop = clock() - start - stepping
        # No flag: every state is finite (MuJoCo's checks catch NaN and Inf before a step).
        return (states[:, 1:1 + m.nq], states[:, 1 + m.nq:1 + m.nq + m.nv], stepping, in_loop,
                done, None)

    def _record_rollout(self, n, k):
        m, d = self.model, self.data
        spec = int(mujoco.mjtState.mjSTATE_FULLPHYSICS)
        nstate = mujoco.mj_stateSize(m, spec)
        init = np.empty((1, nstate))
        mujoco.mj_getState(m, d, init[0], spec)
        # The full-physics state is [time, qpos, qvel, ...] (mjtState bit order).
        qs, vs = slice(1, 1 + m.nq), slice(1 + m.nq, 1 + m.nq + m.nv)
        qpos = np.empty((n, m.nq))
        qvel = np.empty((n, m.nv))
        qpos[0], qvel[0] = init[0, qs], init[0, vs]
        per_chunk = max(1, ROLLOUT_CHUNK_BYTES // (8 * nstate * k)) * k
        width = min(per_chunk, max((n - 1) * k, 1))
        out_all = _scratch(width, nstate)
        sens_all = np.empty((1, width, 0))
        # rollout is stateless: applied forces are passed as controls, here constant rows of
        # xfrc_applied. Shapes are exact, so the wrapper's checks are skipped.
        if self._has_loads:
            control_spec = int(mujoco.mjtState.mjSTATE_XFRC_APPLIED)
            control_all = np.ascontiguousarray(
                np.broadcast_to(self._loads.reshape(1, 1, -1), (1, width, self._loads.size)))
        else:
            control_spec, control_all = int(mujoco.mjtState.mjSTATE_CTRL), None
        run_chunk = _roller().rollout_.rollout
        models, datas = [m], [d]
        clock = time.perf_counter
        stepping = 0.0
        start = clock()
        filled = 1
        failure = None
        while filled < n:
            steps = min(per_chunk, (n - filled) * k)
            out = out_all[:, :steps]
            control = None if control_all is None else control_all[:, :steps]
            t0 = clock()
            run_chunk(models, datas, steps, control_spec, init, None, control, out,
                      sens_all[:, :steps], None)
            stepping += clock() - t0
            # A diverged rollout stops stepping and repeats its last state to the end of the
            # chunk: time stalls. Row j holds the state after step j + 1.
            times = out[0, :, 0]
            if times[-1] <= (times[-2] if steps > 1 else init[0, 0]):
                first = int(np.argmax(np.diff(times, prepend=init[0, 0]) <= 0))
                # Step `first` (1-based) raised MuJoCo's flag and produced row first - 1,
                # the last state stepped; samples from that step on are invalid.
                if first == 0:
                    filled -= 1  # the previous chunk's last step was the flagged one
                got = max(0, (first - 1) // k)
                failure = _UNSTABLE
            else:
                got = steps // k
            rows = out[0, k - 1:got * k:k]
            qpos[filled:filled + got] = rows[:, qs]
            qvel[filled:filled + got] = rows[:, vs]
            filled += got
            if failure is not None:
                break
            init[0] = out[0, -1]
        in_loop = clock() - start - stepping
        if failure is None and not np.all(np.isfinite(init)):  # pragma: no cover - MuJoCo
            failure = "non-finite state"  # flags NaN itself; kept as a guard
        if failure is not None:
            good = np.all(np.isfinite(qpos[:filled]), axis=1) & np.all(
                np.isfinite(qvel[:filled]), axis=1)
            return qpos, qvel, stepping, in_loop, int(np.argmin(np.append(good, False))), \
                failure
        mujoco.mj_setState(m, d, init[0], spec)  # leave data at the final state
        return qpos, qvel, stepping, in_loop, filled, None

    # -- read back ------------------------------------------------------------------------
    def effective(self) -> dict[str, Any]:
        """Settings read back from the compiled model, not from what was asked for."""
        m, d = self.model, self.data
        opt = m.opt
        dis = [name for name, bit in mujoco.mjtDisableBit.__members__.items()
               if name != "mjNDISABLE" and int(opt.disableflags) & int(bit)]
        ena = [name for name, bit in mujoco.mjtEnableBit.__members__.items()
               if name != "mjNENABLE" and int(opt.enableflags) & int(bit)]
        integ = mujoco.mjtIntegrator(int(opt.integrator)).name
        bodies = []
        for b, body in zip(self.bodies, self.scene.bodies, strict=True):
            bid = b.body_id
            moments = np.array(m.body_inertia[bid])
            r_i = quat_to_matrix(np.array(m.body_iquat[bid]))
            inertia_mj = r_i @ np.diag(moments) @ r_i.T  # about the COM, MuJoCo body axes
            dofs = slice(b.vadr, b.vadr + (6 if self.dim == 3 else 3))
            entry: dict[str, Any] = {
                "name": body.name,
                "mass": float(m.body_mass[bid]),
                "com_mujoco_frame": np.array(m.body_ipos[bid]).tolist(),
                "principal_moments": moments.tolist(),
                "dof_damping": np.array(m.dof_damping[dofs]).tolist(),
                "linear_drag": ("per-step xfrc_applied" if b.linear_drag_per_step
                                else "joint damping" if b.drag_linear > 0 else "none"),
                "angular_drag": ("per-step xfrc_applied" if b.angular_drag_per_step
                                 else "joint damping" if b.drag_angular > 0 else "none"),
            }
            if self.dim == 3:
                p = quat_to_matrix(b.q_p)
                declared = p @ inertia_mj @ p.T  # back to declared body axes
                ref = np.asarray(body.inertia, float)
                entry["joint"] = "free"
                entry["frame"] = "aligned (centre of mass, principal axes)" if self.aligned \
                    else "declared body frame"
                entry["inertia_rel_error"] = float(np.max(np.abs(declared - ref))
                                                   / np.max(np.abs(ref)))
            else:
                entry["joint"] = "planar: slide x, slide y, hinge z through the centre of mass"
                entry["inertia_rel_error"] = float(abs(moments[2] - body.moment) / body.moment)
            bodies.append(entry)
        springs = [{
            "mechanism": "spatial tendon",
            "stiffness": float(np.ravel(m.tendon_stiffness[k])[0]),
            "damping": float(m.tendon_damping[k]),
            "springlength": np.array(m.tendon_lengthspring[k]).tolist(),
        } for k in range(m.ntendon)]
        warnings = {mujoco.mjtWarning(k).name: int(d.warning[k].number)
                    for k in range(int(mujoco.mjtWarning.mjNWARNING)) if d.warning[k].number}
        return {
            "timestep": float(opt.timestep),
            "integrator": integ,
            "gravity": np.array(opt.gravity).tolist(),
            "wind": np.array(opt.wind).tolist(),
            "magnetic": np.array(opt.magnetic).tolist(),
            "density": float(opt.density),
            "viscosity": float(opt.viscosity),
            "jacobian": mujoco.mjtJacobian(int(opt.jacobian)).name,
            "disableflags": dis,
            "enableflags": ena,
            "ngeom": int(m.ngeom),
            "bodies": bodies,
            "springs": springs,
            "loads": "constant xfrc_applied (force at the centre of mass, world torque)"
                     if self.scene.effects.loads else "none",
            "stepping": self.stepping_mode,
            "warnings": warnings,
            "options": dict(self.options),
        }


class MujocoEngine(EngineBase):
    name = "mujoco"
    effect_reasons = {**EngineBase.effect_reasons,
                      "fluid": "MuJoCo has no grid fluid (its fluid forces are a drag model)"}

    def check_options(self, scene: Scene) -> None:
        engine_options(scene)  # raises CaseError on an unknown key

    def capabilities(self) -> Capabilities:
        return Capabilities(
            dimensions=frozenset({2, 3}),
            shapes=frozenset(_SHAPES_3D + _SHAPES_2D),
            effects=frozenset({"gravity", "springs", "drag", "loads"}),
            integrators=INTEGRATORS,
            notes=dict(INTEGRATOR_NOTES),
        )

    def version(self) -> str:
        return mujoco.__version__ if mujoco is not None else "not installed"

    def not_applicable(self, scene: Scene, integrator: str) -> str | None:
        if mujoco is None:  # pragma: no cover
            return "the mujoco package is not installed"
        return super().not_applicable(scene, integrator)

    def build(self, scene: Scene, integrator: str, dt: float) -> MujocoModel:
        """The compiled model with the scene's initial state set (also used by benchmarks)."""
        model = MujocoModel(scene, integrator, dt)
        model.set_initial_state()
        return model

    def run(self, scene: Scene, integrator: str, dt: float) -> Trajectory:
        reason = self.not_applicable(scene, integrator)
        if reason is not None:
            from crosscheck.errors import EngineUnavailable

            raise EngineUnavailable(f"mujoco: {reason}")
        plan = sampling_plan(scene, dt)
        sim = self.build(scene, integrator, dt)
        qpos, qvel, stepping, in_loop, good, reason = sim.record(plan.n_samples,
                                                                 plan.steps_per_sample)
        t_conv = time.perf_counter()
        traj = self._trajectory(scene, integrator, dt, plan, sim, qpos[:good], qvel[:good],
                                reason)
        conversion = time.perf_counter() - t_conv
        k = plan.steps_per_sample
        # Settings read back after the run (warning counters included); not part of recording.
        traj.meta["effective"] = sim.effective()
        traj.meta["effective"]["steps_per_sample"] = k
        traj.meta["wall_time"] = stepping
        traj.meta["wall_time_recording"] = in_loop + conversion
        return traj

    def _trajectory(self, scene, integrator, dt, plan, sim: MujocoModel, qpos, qvel,
                    reason: str | None) -> Trajectory:
        good = len(qpos)
        com, rot, vel, omega = sim.convert(qpos, qvel)
        rec = TrajectoryRecorder(plan.n_samples, len(scene.bodies), scene.dimension)
        rec.t[:good] = np.arange(good) * plan.steps_per_sample * dt
        rec.com[:good], rec.rot[:good], rec.vel[:good], rec.omega[:good] = com, rot, vel, omega
        rec.count = good
        if reason is not None:
            rec.fail(plan.time(good), reason)
        return rec.finish(self.base_meta(scene, integrator, dt))
