"""Closed forms of a sphere settling or rising through a quiescent medium (``[effects] medium``).

One solution, ``medium_settling``, for 3D scenes whose bodies are spheres (or boxes moving
face-on, quadratic law only) moving along one line:
released from rest (or with a velocity along the net force) in uniform gravity, with no spin,
no springs, loads, drag entries or contact. Along the unit vector n of the net force the
velocity u = v . n obeys

    m_e du/dt = F - b u - c |u| u,    F = (m - rho_f V) |g|  (the buoyancy-reduced weight),

with ``m_e = m + C_a rho_f V`` (C_a the added-mass coefficient, ``params.added_mass_coefficient``,
default 0: MuJoCo applies no -m_A dv/dt term in either fluid model, measured in
tests/engines/test_mujoco_medium.py; 1/2 is a sphere's potential-flow value) and the drag law
chosen by ``params.drag``:

* ``"stokes"``: b = 6 pi mu r, c = 0. u(t) = u_t + (u0 - u_t) exp(-t / tau), u_t = F / b,
  tau = m_e / b; from rest u_t = 2 (rho_s - rho_f) g r^2 / (9 mu) (with m = rho_s V).
* ``"quadratic"``: b = 0, c = rho_f C_D A / 2, A = pi r^2 (a box: the face normal to the
  motion), C_D = ``params.drag_coefficient``.
  From rest u(t) = u_t tanh(t F / (m_e u_t)), u_t = sqrt(2 F / (rho_f C_D A)).
* ``"stokes+quadratic"``: both (the law MuJoCo's ellipsoid model applies to a sphere when the
  medium has both a density and a viscosity, with C_D = 2 x its blunt coefficient). Roots
  u_t = (-b + sqrt(b^2 + 4 c F)) / (2 c) > 0 > u_m = (-b - sqrt(.)) / (2 c); with
  w = (u - u_t) / (u - u_m) = w0 exp(-k t), k = c (u_t - u_m) / m_e:
  u = (u_t - u_m w) / (1 - w), s = u_t t + (m_e / c) ln((1 - w) / (1 - w0)).

Positions s(t) = integral of u are closed forms too, so the trajectory reference is exact. The
solution refuses what it does not describe (a non-sphere, spin, a velocity off the line, a
quadratic law with the body moving against the net force, where |u| u changes sign).

``EXTRA_METRICS["medium_settling"]`` adds ``terminal_velocity_error_rel``: |u_run(T) -
u_ref(T)| / |u_t| at the last sample (the closed form at that time, so a run stopped before the
approach is over is judged on what it should have reached, not on u_t), with
``terminal_velocity`` (the closed form u_t, m/s, signed along gravity: negative rises),
``terminal_velocity_measured`` and ``approach_time_constants`` (T k: how far into the approach
the run went).
"""

from __future__ import annotations

import math

import numpy as np

from crosscheck.scene.model import Scene
from crosscheck.state import Trajectory

NAME = "medium_settling"
DRAG_LAWS = ("stokes", "quadratic", "stokes+quadratic")
PARALLEL_RTOL = 1e-12


def _refuse(why: str) -> ValueError:
    return ValueError(f"analytic solution {NAME!r} does not apply: {why}")


def law(scene: Scene, i: int) -> dict:
    """The 1D law of body i: n (unit, along the net force or the initial velocity), F (N, >= 0),
    m_e, b, c, u0, the terminal velocity u_t along n, and k (1/s, the approach rate)."""
    fx = scene.effects
    if scene.dimension != 3:
        raise _refuse("it is a 3D solution")
    if fx.medium is None:
        raise _refuse("the scene has no [effects] medium")
    if fx.springs or fx.drag or fx.loads or fx.contact or scene.fluid is not None:
        raise _refuse("the scene has springs, drag entries, loads, contact or a fluid")
    params = scene.reference.params
    drag = params.get("drag")
    if drag not in DRAG_LAWS:
        raise _refuse(f"reference.params.drag must be one of {list(DRAG_LAWS)}, got {drag!r}")
    body = scene.bodies[i]
    kind = body.shape.kind
    if kind not in ("sphere", "box"):
        raise _refuse(f"{body.name!r} is a {kind}, not a sphere or a box")
    if np.linalg.norm(np.asarray(body.com, float)) > 1e-12:
        raise _refuse(f"{body.name!r} has its centre of mass off its shape's centre")
    if np.any(np.asarray(body.angular_velocity, float) != 0.0):
        raise _refuse(f"{body.name!r} spins (the solution has no rotational drag or lift)")
    rho, mu = fx.medium.density, fx.medium.viscosity
    g = fx.gravity_vector(3).astype(float)
    v0 = np.asarray(body.velocity, float)
    if kind == "sphere":
        r = float(body.shape.radius)
        volume, area = 4.0 / 3.0 * math.pi * r**3, math.pi * r * r
    else:
        size = np.asarray(body.shape.size, float)
        volume = float(np.prod(size))
        if "stokes" in drag:
            raise _refuse(f"{body.name!r} is a box: Stokes' law 6 pi mu r v is a sphere's")
        r = None
    net = (body.mass - rho * volume) * g  # weight less buoyancy
    if np.linalg.norm(net) > 0:
        n = net / np.linalg.norm(net)
    elif np.linalg.norm(v0) > 0:
        n = v0 / np.linalg.norm(v0)
    else:
        n = np.array([0.0, 0.0, -1.0])  # nothing moves
    if kind == "box":
        # Face-on only: the motion along one of the box's axes, the drag area the face normal
        # to it (a box moving obliquely has no single area, and its drag turns it).
        axes = body.rotation()
        along = np.abs(axes.T @ n)
        k_axis = int(np.argmax(along))
        if abs(along[k_axis] - 1.0) > 1e-9:
            raise _refuse(f"{body.name!r} does not move along one of its box axes")
        area = float(np.prod(np.delete(size, k_axis)))
    c_a = float(params.get("added_mass_coefficient", 0.0))
    m_e = body.mass + c_a * rho * volume
    b = 6.0 * math.pi * mu * r if "stokes" in drag else 0.0
    c = 0.0
    if "quadratic" in drag:
        if "drag_coefficient" not in params:
            raise _refuse("a quadratic law needs reference.params.drag_coefficient (C_D)")
        c = 0.5 * rho * float(params["drag_coefficient"]) * area
    if b == 0.0 and c == 0.0:
        raise _refuse("the medium exerts no drag under this law (zero viscosity for stokes, "
                      "zero density for quadratic)")
    if np.linalg.norm(v0 - (v0 @ n) * n) > PARALLEL_RTOL * max(np.linalg.norm(v0), 1e-300):
        raise _refuse(f"the initial velocity of {body.name!r} leaves the line of the net force")
    u0 = float(v0 @ n)
    force = float(np.linalg.norm(net))
    if c > 0.0 and u0 < 0.0:
        raise _refuse(f"{body.name!r} starts moving against the net force: the quadratic drag "
                      "|u| u changes sign during the run")
    if c == 0.0:
        u_t, u_m, k = force / b, None, b / m_e
    else:
        root = math.sqrt(b * b + 4.0 * c * force)
        u_t, u_m = (-b + root) / (2.0 * c), (-b - root) / (2.0 * c)
        k = root / m_e  # = c (u_t - u_m) / m_e
    return {"n": n, "force": force, "m_e": m_e, "b": b, "c": c, "u0": u0, "u_t": u_t,
            "u_m": u_m, "k": k, "drag": drag, "added_mass": m_e - body.mass}


def motion(lw: dict, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(s(t), u(t)) along n from s = 0."""
    t = np.asarray(t, float)
    u0, u_t, k, c = lw["u0"], lw["u_t"], lw["k"], lw["c"]
    if c == 0.0:
        decay = np.exp(-k * t)
        return u_t * t + (u0 - u_t) * (-np.expm1(-k * t)) / k, u_t + (u0 - u_t) * decay
    if k == 0.0:  # F = 0 and b = 0: u' = -c u^2 / m_e
        a = c / lw["m_e"]
        return np.log1p(a * u0 * t) / a, u0 / (1.0 + a * u0 * t)
    u_m = lw["u_m"]
    w0 = (u0 - u_t) / (u0 - u_m)
    w = w0 * np.exp(-k * t)
    u = (u_t - u_m * w) / (1.0 - w)
    # ln((1 - w) / (1 - w0)) = log1p((w0 - w) / (1 - w0)), without cancellation at small t
    s = u_t * t + lw["m_e"] / c * np.log1p((w0 - w) / (1.0 - w0))
    return s, u


def medium_settling(scene: Scene, times: np.ndarray) -> Trajectory:
    """The trajectory of every body (see the module docstring)."""
    from crosscheck.reference.analytic import _new

    t = np.asarray(times, float)
    traj = _new(scene, t, NAME)
    for i, body in enumerate(scene.bodies):
        lw = law(scene, i)
        s, u = motion(lw, t)
        traj.com[:, i] = body.com_world() + s[:, None] * lw["n"]
        traj.vel[:, i] = u[:, None] * lw["n"]
        traj.quat[:, i] = body.orientation
        traj.omega[:, i] = 0.0
    return traj


def terminal_velocity_metrics(scene: Scene, traj: Trajectory) -> dict:
    """``terminal_velocity_error_rel`` (worst body) and, for the first body, the closed-form
    terminal velocity, the run's final velocity (both along gravity, m/s; negative: rising) and
    the number of approach time constants the run covered (see the module docstring)."""
    out: dict = {}
    errors = []
    first = None
    for i in range(len(scene.bodies)):
        lw = law(scene, i)
        if not len(traj.t) or not np.all(np.isfinite(traj.vel[-1, i])):
            out["terminal_velocity_error_rel"] = (None, "the run has no finite last sample")
            return out
        t_end = float(traj.t[-1])
        _, u_ref = motion(lw, np.array([t_end]))
        u_run = float(traj.vel[-1, i] @ lw["n"])
        scale = max(abs(lw["u_t"]), abs(lw["u0"]), 1e-300)
        errors.append(abs(u_run - float(u_ref[0])) / scale)
        if first is None:
            g = scene.effects.gravity_vector(3)
            down = g / np.linalg.norm(g) if np.linalg.norm(g) > 0 else lw["n"]
            sign = float(np.sign(lw["n"] @ down)) or 1.0
            first = (sign * lw["u_t"], sign * u_run, lw["k"] * t_end)
    out["terminal_velocity_error_rel"] = float(max(errors))
    out["terminal_velocity"] = first[0]
    out["terminal_velocity_measured"] = first[1]
    out["approach_time_constants"] = first[2]
    return out


SOLUTIONS = {NAME: medium_settling}
EXTRA_METRICS = {NAME: terminal_velocity_metrics}
