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

from crosscheck.names import MEDIUM_MODELS as NAMED_MEDIUM_MODELS
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


# -- a fluid case's disc as MuJoCo's long cylinder (scene/medium_map.py) -------------------------
# MuJoCo's default ellipsoid coefficients (blunt drag, slender drag, angular drag, Kutta lift,
# Magnus lift): the same numbers as engines/mujoco.FLUIDCOEF_DEFAULT (a test checks they agree);
# written here so the reference does not import MuJoCo.
FLUIDCOEF_DEFAULT = (0.5, 0.25, 1.5, 1.0, 1.0)
MEDIUM_MODELS = NAMED_MEDIUM_MODELS["mujoco"]  # the run names' models (names.py)


def mapped_law(scene: Scene, model: str, fluidcoef=FLUIDCOEF_DEFAULT) -> dict:
    """The 1D law (keys of :func:`law`) of MuJoCo's mapped cylinder in a fluid case, settling
    along gravity (-y) from the disc's initial velocity, with MuJoCo's own coefficients:

    * weight less buoyancy ``F = (m - rho_f V) g`` (the buoyancy is the adapter's gravcomp);
    * ``"inertia_box"``: MuJoCo's box from the cylinder's moments, half sizes ``r_i = sqrt(3 (I_j
      + I_k - I_i) / (2 M))`` = (sqrt(3) R / 2, sqrt(3) R / 2, L / 2); across the axis ``c = 2
      rho r_x r_z`` (= sqrt(3) / 2 rho R L: C_D = sqrt(3) / 2 on the frontal width 2 R L),
      ``b = 6 pi mu (r_x + r_y + r_z) / 3``;
    * ``"ellipsoid"``: semi-axes (R, R, L / 2); across the axis the projected area ``pi R L / 2``
      equals MuJoCo's ``A_max = pi r_max r_mid``, so the slender term vanishes and ``c =
      C_blunt rho pi R L / 2`` (C_D = pi C_blunt / 2); ``b = 6 pi mu (2 R + L / 2) / 3``;
    * no added mass (``m_e = m``): neither model has a ``-m_A dv/dt`` term.

    Exact for MuJoCo's model (its forces measured against these formulas in
    tests/engines/test_mujoco_medium.py); not a law of the resolved fluid."""
    from crosscheck.scene.medium_map import mapped_cylinder

    if model not in MEDIUM_MODELS:
        raise _refuse(f"MuJoCo's fluid model is one of {list(MEDIUM_MODELS)}, got {model!r}")
    cyl = mapped_cylinder(scene)
    body = scene.fluid.bodies[0]
    if float(body.angular_velocity[0]) != 0.0:
        raise _refuse(f"{body.name!r} spins (the closed form has no Magnus lift)")
    rho, mu, r, length, m = (cyl.fluid_density, cyl.dynamic_viscosity, cyl.radius, cyl.length,
                             cyl.mass)
    gvec = scene.effects.gravity_vector(2).astype(float)
    g = float(np.linalg.norm(gvec))
    if g == 0.0:
        raise _refuse("the fluid case has no gravity: nothing settles")
    n = gvec / g
    v0 = np.asarray(body.velocity, float)
    if np.linalg.norm(v0 - (v0 @ n) * n) > PARALLEL_RTOL * max(np.linalg.norm(v0), 1e-300):
        raise _refuse(f"the initial velocity of {body.name!r} leaves the line of gravity")
    force = (m - rho * cyl.volume) * g
    if force < 0.0:  # a light disc rises: the law along -n
        n, force = -n, -force
    u0 = float(v0 @ n)
    if model == "inertia_box":
        i = np.asarray(cyl.inertia, float)
        half = np.sqrt(np.maximum(1.5 * (i.sum() - 2.0 * i) / m, 0.0))
        c = 2.0 * rho * half[0] * half[2]
        b = 6.0 * math.pi * mu * float(np.mean(half))
    else:
        c_blunt = float(fluidcoef[0])
        c = c_blunt * rho * math.pi * r * length / 2.0
        b = 6.0 * math.pi * mu * (2.0 * r + length / 2.0) / 3.0
    if c > 0.0 and u0 < 0.0:
        raise _refuse(f"{body.name!r} starts moving against the net force")
    if b == 0.0 and c == 0.0:
        raise _refuse("the medium exerts no drag (zero viscosity and zero blunt coefficient)")
    if c == 0.0:
        u_t, u_m, k = force / b, None, b / m
    else:
        root = math.sqrt(b * b + 4.0 * c * force)
        u_t, u_m, k = (-b + root) / (2.0 * c), (-b - root) / (2.0 * c), root / m
    return {"n": n, "force": force, "m_e": m, "b": b, "c": c, "u0": u0, "u_t": u_t, "u_m": u_m,
            "k": k, "drag": model, "added_mass": 0.0, "length": length, "radius": r}


def startup_acceleration(t: np.ndarray, v: np.ndarray) -> float:
    """The acceleration at t = 0 from the first three samples of a velocity series (one-sided
    second-order difference; equal sample intervals are not assumed): exact for a quadratic
    v(t). NaN with fewer than three samples."""
    t = np.asarray(t, float)
    v = np.asarray(v, float)
    if len(t) < 3:
        return math.nan
    h1, h2 = t[1] - t[0], t[2] - t[0]
    # derivative at t0 of the parabola through (t0, v0), (t1, v1), (t2, v2)
    return float((v[1] - v[0]) * h2 / (h1 * (h2 - h1)) - (v[2] - v[0]) * h1 / (h2 * (h2 - h1)))


def settling_accelerations(scene: Scene) -> dict:
    """The start-up accelerations of a disc released from rest in a fluid case (m/s^2, along
    gravity; negative for a light disc, which rises): ``stateless`` g (1 - rho_f / rho_s), what
    a medium without added mass gives (MuJoCo: its models have no -m_A dv/dt); ``added_mass``
    g (rho_s - rho_f) / (rho_s + C_a rho_f) with the potential-flow added mass of a circular
    cylinder, C_a = 1 (Lamb, Hydrodynamics, sec. 92: rho pi R^2 per unit length), what the
    resolved fluid should give far from walls."""
    body = scene.fluid.bodies[0]
    rho = scene.fluid.density
    rho_s = body.mass / (math.pi * float(body.shape.radius) ** 2)  # a disc (medium_map)
    g = float(np.linalg.norm(scene.effects.gravity_vector(2)))
    return {"stateless": g * (1.0 - rho / rho_s),
            "added_mass": g * (rho_s - rho) / (rho_s + rho)}


# Why MuJoCo's figures beside the resolved fluid's are reported and not judged (attached to the
# metrics by compare/evaluate.py).
MAPPED_NOTES = {
    "startup_acceleration_added_mass":
        "the resolved fluid's g (rho_s - rho_f) / (rho_s + rho_f) (added mass rho pi R^2 per "
        "length): MuJoCo's models have no -m_A dv/dt, so they cannot give it",
    "drag_coefficient": "the model's C_D at its own terminal velocity (viscous term included): "
                        "a constant-coefficient law, no Reynolds dependence, no walls, no wake",
}


def mapped_settling_metrics(scene: Scene, traj: Trajectory, model: str,
                            fluidcoef=FLUIDCOEF_DEFAULT) -> dict:
    """MuJoCo's cell of a fluid case against the closed form of its own model
    (:func:`mapped_law`), and the figures the report sets beside the in-house cell's:

    * ``velocity_error_max`` (m/s) and ``position_error_max`` (m): the largest distance from
      the closed form over the run;
    * ``terminal_velocity_error_rel``: |u(T) - u_ref(T)| / u_t at the last sample;
      ``terminal_velocity`` (closed form, m/s along gravity), ``terminal_velocity_measured``;
    * ``terminal_reynolds`` 2 R u_t / nu and ``drag_coefficient`` the model's C_D on the
      diameter at its terminal velocity, 2 F / (rho u_t^2 2 R L) (viscous term included);
    * ``startup_acceleration`` from the first three samples, ``startup_acceleration_reference``
      the stateless g (1 - rho_f / rho_s) and ``startup_acceleration_error`` their relative
      difference; ``startup_acceleration_added_mass`` the resolved fluid's expectation, beside
      it (MuJoCo cannot have it: no added mass)."""
    lw = mapped_law(scene, model, fluidcoef)
    t = np.asarray(traj.t, float)
    out: dict = {}
    if not len(t) or not np.all(np.isfinite(traj.vel[-1, 0])):
        return {"terminal_velocity_error_rel": None, "velocity_error_max": None}
    s, u = motion(lw, t)
    n = lw["n"]
    body = scene.fluid.bodies[0]
    com_ref = body.com_world()[None, :] + s[:, None] * n[None, :]
    vel_ref = u[:, None] * n[None, :]
    out["velocity_error_max"] = float(np.max(np.linalg.norm(traj.vel[:, 0] - vel_ref, axis=1)))
    out["position_error_max"] = float(np.max(np.linalg.norm(traj.com[:, 0] - com_ref, axis=1)))
    u_run = traj.vel[:, 0] @ n
    out["terminal_velocity"] = lw["u_t"]
    out["terminal_velocity_measured"] = float(u_run[-1])
    out["terminal_velocity_error_rel"] = float(abs(u_run[-1] - u[-1]) / abs(lw["u_t"]))
    out["approach_time_constants"] = lw["k"] * float(t[-1])
    rho = scene.fluid.density
    nu = scene.fluid.kinematic_viscosity
    if nu > 0:
        out["terminal_reynolds"] = 2.0 * lw["radius"] * lw["u_t"] / nu
    out["drag_coefficient"] = 2.0 * lw["force"] / (rho * lw["u_t"] ** 2 * 2.0 * lw["radius"]
                                                   * lw["length"])
    acc = settling_accelerations(scene)
    if np.allclose(np.asarray(body.velocity, float), 0.0):
        # along gravity, as settling_accelerations (negative: a light disc rises)
        down = scene.effects.gravity_vector(2).astype(float)
        down = down / np.linalg.norm(down)
        a0 = startup_acceleration(t, traj.vel[:, 0] @ down)
        out["startup_acceleration"] = a0
        out["startup_acceleration_reference"] = acc["stateless"]
        out["startup_acceleration_error"] = float(abs(a0 / acc["stateless"] - 1.0))
        out["startup_acceleration_added_mass"] = acc["added_mass"]
    return out
