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

Stepping (engine option ``stepping``). ``advance(n)`` is ``mj_step(m, d, nstep=n)`` (a Python
loop only when drag is applied per step); after it MuJoCo's warning counters are read, and any
warning (its instability check: NaN, Inf or |value| > 1e10 in qpos, qvel or qacc) ends the run
as a StepFailure. The accuracy pass records ``qpos``/``qvel`` only, converted to centre-of-mass
position and velocity and world angular velocity after the run, vectorised (MuJoCo's derived
arrays, stale after ``mj_step``, are never read):

* ``compiled`` (default): the session's fused fast path, a compiled loop (numba,
  ``engines/_native.py``) calling MuJoCo's C ``mj_step(m, d)`` k times per sample and copying
  ``qpos``/``qvel``, with no Python call per sample. ``mj_step`` is taken from the ``libmujoco``
  the bindings already loaded (``RTLD_NOLOAD``); without it (or without numba) the driver's
  generic loop records. Bit-identical to the generic loop (tests/engines/test_driver.py).
* ``nstep``: the driver's generic loop, ``advance(k)`` then a read per sample.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from crosscheck.engines.base import Capabilities, EngineBase
from crosscheck.engines.session import StepFailure
from crosscheck.errors import CaseError
from crosscheck.names import rigid_names
from crosscheck.rotations import matrix_to_quat, quat_conj, quat_mul, quat_to_matrix
from crosscheck.scene.model import Scene

try:  # the registry imports this module lazily; a missing mujoco is "not applicable"
    import mujoco
except ImportError:  # pragma: no cover - mujoco is a declared dependency
    mujoco = None

# Integrator names, MuJoCo's default (Euler) first (crosscheck.names holds them).
INTEGRATORS: tuple[str, ...] = rigid_names("mujoco")
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
    "stepping": (("compiled", "nstep"), "compiled"),
}

# A run fails at the first sample at or after which MuJoCo's own check fired (mj_checkPos,
# mj_checkVel, mj_checkAcc: NaN, Inf or a value beyond mjMAXVAL = 1e10).
_UNSTABLE = "MuJoCo flagged an instability (NaN, Inf or |value| > 1e10 in qpos, qvel or qacc)"
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


# MuJoCo's compiler refuses a moving body whose mass or a principal moment is below mjMINVAL
# (1e-15), and principal moments with A + B < C beyond an absolute slack of about mjMINVAL
# (measured: 1e-16 over passes, 1e-12 over fails). A flat plate sits exactly at A + B = C, and the
# eigen-decomposition lands there only to round-off, which for moments of order 1 kg m^2 and up
# exceeds that absolute slack.
MJ_MINVAL = 1e-15
# A + B may fall short of C by this much relative to C (a few ulps of the decomposition) and is
# then balanced by lowering C to A + B; beyond it the inertia is not MuJoCo's to take.
TRIANGLE_ROUNDOFF = 1e-12


def principal_moments(inertia) -> tuple[np.ndarray, np.ndarray]:
    """(ascending principal moments, axes as a proper rotation), with a moment tensor at the
    triangle-inequality limit balanced to exactly A + B = C when round-off put it past."""
    moments, axes = np.linalg.eigh(np.asarray(inertia, float))
    short = moments[2] - (moments[0] + moments[1])
    if 0 < short <= TRIANGLE_ROUNDOFF * moments[2]:
        moments = moments.copy()
        moments[2] = moments[0] + moments[1]
    return moments, axes


def mujoco_limits(scene: Scene) -> str | None:
    """Why MuJoCo cannot take this scene's bodies (its documented compiler limits), or None."""
    for body in scene.bodies:
        if body.mass < MJ_MINVAL:
            return (f"body {body.name!r}: mass {body.mass:g} kg is below MuJoCo's mjMINVAL "
                    f"({MJ_MINVAL:g}), which its compiler refuses for a moving body")
        if scene.dimension == 3:
            moments, _ = principal_moments(body.inertia)
        else:
            moments = np.full(3, float(body.moment))
        if moments[0] < MJ_MINVAL:
            return (f"body {body.name!r}: principal moment {moments[0]:g} kg m^2 is below "
                    f"MuJoCo's mjMINVAL ({MJ_MINVAL:g})")
        short = moments[2] - (moments[0] + moments[1])
        if short > TRIANGLE_ROUNDOFF * moments[2]:
            return (f"body {body.name!r}: principal moments {moments.tolist()} break the "
                    f"triangle inequality A + B >= C by {short:.3g} kg m^2, which MuJoCo's "
                    "compiler refuses")
    return None


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
    """One compiled MuJoCo model of one Scene, integrator and step: a session (session.py).

    ``set_initial_state()`` writes the scene's t = 0 state into ``data``; ``advance(n)`` steps;
    ``read_raw()`` is (qpos, qvel); ``convert(rows, t)`` turns such rows into crosscheck's
    convention; ``record(n, k, rows)`` is the fused fast path; ``settings()`` reads the settings
    back from the compiled model.
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
        moments, axes = principal_moments(body.inertia)
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

    def convert_q(self, qpos: np.ndarray, qvel: np.ndarray) -> tuple[np.ndarray, ...]:
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
        com, rot, vel, omega = self.convert_q(self.data.qpos[None], self.data.qvel[None])
        return com[0], rot[0], vel[0], omega[0]

    # -- session -------------------------------------------------------------------------
    @property
    def row_width(self) -> int:
        return self.model.nq + self.model.nv

    def read_raw(self) -> np.ndarray:
        return np.concatenate([self.data.qpos, self.data.qvel])

    def convert(self, rows, t=None):
        """(T, nq + nv) rows -> ((com, rot, vel, omega), no extras)."""
        rows = np.asarray(rows, float).reshape(-1, self.row_width)
        return self.convert_q(rows[:, :self.model.nq], rows[:, self.model.nq:]), {}

    def set_state(self, com, rot, vel, omega) -> None:
        """Place a normalised state: the inverse of convert for one sample."""
        d = self.data
        for i, b in enumerate(self.bodies):
            w = np.asarray(omega[i], float)
            if self.dim == 3:
                q_decl = np.asarray(rot[i], float)
                q_mj = quat_mul(q_decl, b.q_p) if self.aligned else q_decl
                r_mj = quat_to_matrix(q_mj)
                rc = r_mj @ b.com_mj
                d.qpos[b.qadr:b.qadr + 3] = np.asarray(com[i], float) - rc
                d.qpos[b.qadr + 3:b.qadr + 7] = q_mj
                d.qvel[b.vadr:b.vadr + 3] = np.asarray(vel[i], float) - np.cross(w, rc)
                d.qvel[b.vadr + 3:b.vadr + 6] = r_mj.T @ w
            else:
                d.qpos[b.qadr:b.qadr + 2] = np.asarray(com[i], float) - b.com_mj
                d.qpos[b.qadr + 2] = float(rot[i])
                d.qvel[b.vadr:b.vadr + 2] = vel[i]
                d.qvel[b.vadr + 2] = float(omega[i])
        mujoco.mj_forward(self.model, d)

    def check(self) -> list[str]:
        return []

    def close(self) -> None:
        pass

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
        """nsteps steps: one mj_step call when no force is recomputed per step. Raises
        StepFailure once any of MuJoCo's warning counters is set (they start at zero)."""
        if nsteps <= 0:
            return
        m, d = self.model, self.data
        if not self.per_step_forces:
            mujoco.mj_step(m, d, nsteps)
        else:
            step, apply = mujoco.mj_step, self._apply_step_forces
            for _ in range(nsteps):
                apply()
                step(m, d)
        if d.warning.number.any():
            raise StepFailure(_UNSTABLE)

    @property
    def fused(self) -> bool:
        """True when ``record`` (the compiled loop) is used by the driver."""
        return (not self.per_step_forces and self.options["stepping"] == "compiled"
                and _native_stepper()[0] is not None)

    @property
    def stepping_mode(self) -> str:
        if self.per_step_forces:
            return "python loop: per-step xfrc_applied drag, mj_step"
        if self.fused:
            return ("compiled loop (numba) calling mj_step(m, d) steps_per_sample times per "
                    "sample and copying qpos, qvel; cost timed on mj_step(m, d, nstep)")
        fallback = "" if self.options["stepping"] == "nstep" else (
            f" (compiled loop unavailable: {_native_stepper()[2]})")
        return "mj_step(m, d, nstep=steps_per_sample) per sample" + fallback

    def record(self, n: int, k: int, rows: np.ndarray) -> tuple[int, str | None]:
        """The fused fast path: the rows the generic loop would fill, from a compiled loop.

        Stops at the first sample after whose steps one of MuJoCo's warning counters is set,
        as ``advance`` does; returns (valid rows, failure reason or None).
        """
        m, d = self.model, self.data
        native, step, _ = _native_stepper()
        qpos = np.empty((n, m.nq))
        qvel = np.empty((n, m.nv))
        qpos[0], qvel[0] = d.qpos, d.qvel
        # d.qpos, d.qvel and d.warning.number are views of data's own memory.
        count = native.mujoco_record(step, m._address, d._address, d.qpos, d.qvel,
                                     d.warning.number, k, qpos, qvel)
        rows[:, :m.nq] = qpos
        rows[:, m.nq:] = qvel
        if count == n:
            return n, None
        return count, _UNSTABLE

    # -- read back ------------------------------------------------------------------------
    def effective(self, arrays=None) -> dict[str, Any]:
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
        return super().not_applicable(scene, integrator) or mujoco_limits(scene)

    def build(self, scene: Scene, integrator: str, dt: float) -> MujocoModel:
        """The compiled model with the scene's initial state set (also used by benchmarks)."""
        model = MujocoModel(scene, integrator, dt)
        model.set_initial_state()
        return model

    def open(self, scene: Scene, integrator: str, dt: float) -> MujocoModel:
        return self.build(scene, integrator, dt)

