"""The Newton-Euler equations of a contact-free scene, written apart from the in-house simulator.

The DOP853 reference (:mod:`crosscheck.reference.simulated`) integrates these equations, and the
engine tests use them as their engine-independent reference. They used to come from
``crosscheck.sim.rigid``'s compiled kernels, which judged the in-house engine partly against
itself: a wrong sign in a spring kernel would have moved the engine and its reference together.
This module therefore imports nothing from ``crosscheck.sim``; it is plain NumPy, written from the
conventions in ``scene/model.py`` and docs/cases.md, and a test compares its derivative with the
in-house one on random states (two implementations that agree to round-off).

State of each body (Baraff's), world frame:

* 3D: ``x`` centre of mass, ``q`` unit quaternion (w, x, y, z) of the declared body frame,
  ``P = m v`` linear momentum, ``L`` angular momentum about the centre of mass::

      x' = P / m,   q' = 1/2 (0, w) q,   P' = F,   L' = tau,   w = R I_body^-1 R^T L

  with ``R = R(q / |q|)``: between solver stages ``q`` drifts off unit length, and the rotation
  it stands for is that of the normalised quaternion.
* 2D: ``x`` (2), the planar angle ``theta`` (counter-clockwise about +z), ``P`` (2) and the scalar
  ``L``: ``theta' = w = L / I``.

Flat vector: ``[x of every body, q (or theta) of every body, P ..., L ...]``, the layout of
``crosscheck.sim.rigid``'s ``initial_state`` so the two derivatives compare entry by entry.

Forces and torques (torques about each centre of mass, world frame):

* gravity ``m g`` at the centre of mass;
* a spring between the point ``p_a = x_a + R_a (attach_a - com_a)`` of body a and ``p_b`` (the
  same on body b, or the world ``anchor``): ``d = p_a - p_b``, ``l = |d|``, ``e = d / l`` (zero
  when the points coincide), force on a ``f = -(k (l - l0) + c e . (v_pa - v_pb)) e`` at ``p_a``,
  ``-f`` on b at ``p_b``, with point velocities ``v + w x (p - x)``; each exerts ``r x f``;
* linear drag ``-c v`` and angular drag ``-c_a w``;
* constant loads: a force at the centre of mass and a torque (2D: about +z).

A 2D scene is evaluated in the z = 0 plane of 3D space (rotation about z), which keeps one force
routine for both dimensions; the planar components are read back.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from crosscheck.rotations import quat_mul, quat_normalize, quat_to_matrix
from crosscheck.scene.model import Scene
from crosscheck.state import Trajectory, TrajectoryRecorder


@dataclass(frozen=True)
class Spring:
    a: int
    b: int | None  # None: a world anchor
    ra: np.ndarray  # attachment on a minus a's centre of mass, body frame of a (3,)
    rb: np.ndarray  # the same on b, or the world anchor point (3,)
    stiffness: float
    damping: float
    rest_length: float


@dataclass(frozen=True)
class Equations:
    """A scene's bodies and effects as the arrays the right-hand side reads (3D vectors)."""

    dimension: int
    mass: np.ndarray  # (N,)
    inertia: np.ndarray  # (N, 3, 3) about the centre of mass, body frame; 2D: (N,) moments
    gravity: np.ndarray  # (3,), zero without gravity
    springs: tuple[Spring, ...]
    linear_drag: np.ndarray  # (N,) summed over the scene's drag entries
    angular_drag: np.ndarray  # (N,)
    load_force: np.ndarray  # (N, 3) summed over the scene's loads
    load_torque: np.ndarray  # (N, 3)

    @property
    def n_bodies(self) -> int:
        return len(self.mass)


def _lift(v) -> np.ndarray:
    """A 2D vector (or rows of them) in the z = 0 plane; 3D ones unchanged."""
    v = np.asarray(v, float)
    if v.shape[-1] == 3:
        return v
    return np.concatenate([v, np.zeros(v.shape[:-1] + (1,))], axis=-1)


def equations(scene: Scene) -> Equations:
    """Read the scene's bodies and declared effects (see the module docstring for the rules)."""
    if scene.effects.medium is not None:
        # The medium's drag law is each engine's own model (docs/engines.md); these equations
        # have none, and a reference that left it out would be silently wrong.
        raise ValueError("the Newton-Euler equations model no medium ([effects] medium): use an "
                         "analytic reference (medium_settling) or another engine's run")
    d = scene.dimension
    n = len(scene.bodies)
    mass = np.array([b.mass for b in scene.bodies], float)
    if d == 3:
        inertia = np.array([b.inertia for b in scene.bodies], float)
    else:
        inertia = np.array([b.moment for b in scene.bodies], float)
    com = [np.asarray(b.com, float) for b in scene.bodies]
    eff = scene.effects
    springs = tuple(
        Spring(a=s.body_a, b=s.body_b, ra=_lift(np.asarray(s.attach_a, float) - com[s.body_a]),
               rb=_lift(np.asarray(s.attach_b, float)
                        - (0.0 if s.body_b is None else com[s.body_b])),
               stiffness=float(s.stiffness), damping=float(s.damping),
               rest_length=float(s.rest_length))
        for s in eff.springs)
    lin, ang = np.zeros(n), np.zeros(n)
    for entry in eff.drag:
        for i in entry.bodies:
            lin[i] += entry.linear
            ang[i] += entry.angular
    force, torque = np.zeros((n, 3)), np.zeros((n, 3))
    for load in eff.loads:
        force[load.body] += _lift(load.force)
        tau = np.asarray(load.torque, float).reshape(-1)
        torque[load.body] += tau if d == 3 else (0.0, 0.0, tau[0])
    return Equations(dimension=d, mass=mass, inertia=inertia,
                     gravity=_lift(eff.gravity_vector(d)), springs=springs, linear_drag=lin,
                     angular_drag=ang, load_force=force, load_torque=torque)


# -- the flat state ----------------------------------------------------------------------------
def unpack(eq: Equations, y: np.ndarray):
    """(x, rotation, P, L) views of the flat state: 3D (N,3) (N,4) (N,3) (N,3); 2D (N,2) (N,)
    (N,2) (N,)."""
    n, d = eq.n_bodies, eq.dimension
    r, a = (4, 3) if d == 3 else (1, 1)
    x, rot, P, L = np.split(np.asarray(y, float), np.cumsum([n * d, n * r, n * d]))
    if d == 3:
        return x.reshape(n, 3), rot.reshape(n, 4), P.reshape(n, 3), L.reshape(n, 3)
    return x.reshape(n, 2), rot, P.reshape(n, 2), L


def pack(*parts: np.ndarray) -> np.ndarray:
    return np.concatenate([np.asarray(p, float).ravel() for p in parts])


def initial_state(scene: Scene) -> np.ndarray:
    """The flat state at t = 0: centre of mass, orientation, P = m v, L = I_world w."""
    x = [b.com_world() for b in scene.bodies]
    P = [b.mass * np.asarray(b.velocity, float) for b in scene.bodies]
    if scene.dimension == 3:
        q = quat_normalize([b.orientation for b in scene.bodies])
        L = [b.inertia_world() @ np.asarray(b.angular_velocity, float) for b in scene.bodies]
        return pack(x, q, P, L)
    theta = [b.angle for b in scene.bodies]
    L = [b.moment * float(b.angular_velocity[0]) for b in scene.bodies]
    return pack(x, theta, P, L)


# -- kinematics --------------------------------------------------------------------------------
def planar_rotation(theta: np.ndarray) -> np.ndarray:
    """(N, 3, 3) rotations by theta about +z."""
    c, s = np.cos(theta), np.sin(theta)
    R = np.zeros((len(theta), 3, 3))
    R[:, 0, 0], R[:, 0, 1], R[:, 1, 0], R[:, 1, 1], R[:, 2, 2] = c, -s, s, c, 1.0
    return R


def kinematics(eq: Equations, rot: np.ndarray, P: np.ndarray, L: np.ndarray):
    """(R, v, w) with 3D vectors: R (N, 3, 3), v = P / m, w the world angular velocity."""
    v = _lift(P / eq.mass[:, None])
    if eq.dimension == 3:
        R = quat_to_matrix(rot)  # normalises q
        body_L = np.einsum("nji,nj->ni", R, L)  # R^T L
        body_w = np.linalg.solve(eq.inertia, body_L[..., None])[..., 0]
        return R, v, np.einsum("nij,nj->ni", R, body_w)
    w = np.zeros((eq.n_bodies, 3))
    w[:, 2] = L / eq.inertia
    return planar_rotation(rot), v, w


# -- forces ------------------------------------------------------------------------------------
def wrench(eq: Equations, x: np.ndarray, R: np.ndarray, v: np.ndarray, w: np.ndarray):
    """Net force and torque about each centre of mass, (N, 3) each, at the given kinematics."""
    F = eq.mass[:, None] * eq.gravity + eq.load_force - eq.linear_drag[:, None] * v
    T = eq.load_torque - eq.angular_drag[:, None] * w
    for s in eq.springs:
        f, r_a, r_b = spring_force(s, x, R, v, w)
        F[s.a] += f
        T[s.a] += np.cross(r_a, f)
        if s.b is not None:
            F[s.b] -= f
            T[s.b] -= np.cross(r_b, f)
    return F, T


def spring_force(s: Spring, x, R, v, w):
    """(force on a, world offset of a's attachment, of b's) of one spring (module docstring)."""
    r_a = R[s.a] @ s.ra
    p_a, v_a = x[s.a] + r_a, v[s.a] + np.cross(w[s.a], r_a)
    if s.b is None:
        r_b, p_b, v_b = np.zeros(3), s.rb, np.zeros(3)
    else:
        r_b = R[s.b] @ s.rb
        p_b, v_b = x[s.b] + r_b, v[s.b] + np.cross(w[s.b], r_b)
    d = p_a - p_b
    length = float(np.linalg.norm(d))
    # Coincident points leave the direction undefined; the force is then taken as zero.
    e = d / length if length > 0.0 else np.zeros(3)
    magnitude = s.stiffness * (length - s.rest_length) + s.damping * float(e @ (v_a - v_b))
    return -magnitude * e, r_a, r_b


# -- the right-hand side -----------------------------------------------------------------------
def derivative(eq: Equations, y: np.ndarray) -> np.ndarray:
    """dy/dt of the flat state: (x', rotation', P', L') = (v, 1/2 (0, w) q or w, F, tau)."""
    x, rot, P, L = unpack(eq, y)
    R, v, w = kinematics(eq, rot, P, L)
    F, T = wrench(eq, _lift(x), R, v, w)
    if eq.dimension == 3:
        q_rate = 0.5 * quat_mul(np.concatenate([np.zeros((eq.n_bodies, 1)), w], axis=1), rot)
        return pack(v, q_rate, F, T)
    return pack(v[:, :2], w[:, 2], F[:, :2], T[:, 2])


def state_derivative(scene: Scene):
    """f(t, y) for SciPy's ``solve_ivp`` (the equations are autonomous: t is unused)."""
    eq = equations(scene)
    return lambda _t, y: derivative(eq, y)


# -- back to a Trajectory ----------------------------------------------------------------------
def state_to_trajectory(scene: Scene, t: np.ndarray, Y: np.ndarray) -> Trajectory:
    """A Trajectory from flat states ``Y`` (T, size) at times ``t``: centre of mass, orientation
    (quaternion renormalised; the recorder makes it sign-continuous), centre-of-mass velocity and
    world angular velocity. A non-finite state ends it as a recorded failure."""
    eq = equations(scene)
    t = np.asarray(t, float)
    rec = TrajectoryRecorder(len(t), eq.n_bodies, eq.dimension)
    for ti, y in zip(t, np.asarray(Y, float), strict=True):
        x, rot, P, L = unpack(eq, y)
        _, v, w = kinematics(eq, rot, P, L)
        if eq.dimension == 3:
            sample = (x, quat_normalize(rot), v, w)
        else:
            sample = (x, rot, v[:, :2], w[:, 2])
        if not rec.record(ti, *sample):
            break
    return rec.finish({"case": scene.name, "bodies": list(scene.body_names),
                       "masses": [b.mass for b in scene.bodies]})


def solve(scene: Scene, times: np.ndarray, rtol: float, atol: float) -> Trajectory:
    """SciPy ``solve_ivp(method="DOP853")`` from t = 0, dense output at ``times``."""
    from scipy.integrate import solve_ivp

    times = np.asarray(times, float)
    sol = solve_ivp(state_derivative(scene), (0.0, float(times[-1])), initial_state(scene),
                    method="DOP853", t_eval=times, rtol=rtol, atol=atol)
    if not sol.success:
        raise RuntimeError(f"solve_ivp failed: {sol.message}")
    return state_to_trajectory(scene, sol.t, sol.y.T)
