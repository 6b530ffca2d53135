"""Analytic references for contact scenes (issue #11 points 4 and 5).

Registered into ``crosscheck.reference.analytic.SOLUTIONS`` and ``EXTRA_METRICS`` under the names
below (``[reference] solution = "bounce"``). Each solution is the idealised rigid model: contact
is instantaneous and exact (no penetration, no compliance), friction is Coulomb's with the pair
value of :func:`crosscheck.scene.contact.pair_material` (static = kinetic), restitution is
Newton's with the pair value. A scene outside a solution's assumptions is refused with a
ValueError naming the assumption, never answered approximately. Notation: ``n`` the ground's unit
normal, ``g`` the magnitude of gravity, ``g_n = -gravity . n > 0`` its part pressing on the
ground and ``g_s`` its part along the ground (``g sin theta``: an incline is either a tilted
ground under vertical gravity or tilted gravity on a flat ground; both are the same here).

Solutions
---------
bounce (2D and 3D)
    One sphere (circle) falling or thrown along the normal onto the ground with pair restitution
    e. Height of the centre above its resting contact height ``h = n . x - offset - r``; from
    ``h0``, normal velocity ``w0``: impact speed ``v1 = sqrt(w0^2 + 2 g h0)``, first impact
    ``t1 = (w0 + v1) / g``; after impact k (k >= 1) the ball leaves at ``u_k = e^k v1``, so
    ``t_(k+1) = t_k + 2 u_k / g`` and the k-th apex is ``h_k = u_k^2 / (2 g) = e^(2k) H0``,
    ``H0 = h0 + w0^2 / (2 g)``; for e < 1 the bounces end at ``t1 + 2 e v1 / (g (1 - e))``, then
    the ball rests at h = 0. Motion along the ground (only when the pair is frictionless) is
    uniform; spin is constant (zero unless the pair is frictionless).
slide_to_rest (2D and 3D)
    A box (or an upright cylinder) resting on a face on flat ground (gravity along -n), launched
    along the ground at v0 with pair friction mu > 0: ``s(t) = v0 t - mu g t^2 / 2`` until
    ``t_stop = v0 / (mu g)``, then at rest at ``v0^2 / (2 mu g)``. Refused when it would tip
    (``mu h_com >= d``, d the distance from the centre of mass's foot to the edge of the face along
    the motion; CONTACTS.md trap C14) or when the run ends before it stops.
roll_incline (2D and 3D)
    A sphere, a circle, or a cylinder or capsule lying across the slope, touching an incline, with
    velocity down the slope v0 and spin omega_a about ``a = n x s`` (s the downslope direction).
    With ``k = I / (m r^2)``: rolling (contact slip ``u = v - r omega_a = 0``) has
    ``a = g_s / (1 + k)`` and needs ``mu >= mu_crit = tan(theta) k / (1 + k)``
    (``= tan(theta) / (1 + m r^2 / I)``). Slipping with sign sigma = sign(u) has
    ``a = g_s - sigma mu g_n`` and ``domega_a/dt = sigma mu g_n / (k r)``, so
    ``du/dt = g_s - sigma mu g_n (1 + 1/k)``: slip decays to zero (then rolls when
    mu >= mu_crit, else slips on with sigma = +1) or slips for ever. At most two phases.
block_incline (2D and 3D)
    A box (or upright cylinder) at rest on a face on an incline: stays at rest when
    ``tan(theta) <= mu`` (static friction holds it; drift 0), else slides down with
    ``a = g_s - mu g_n = g (sin theta - mu cos theta)``. Refused when it would tip.
billiard (2D and 3D), newtons_cradle (2D and 3D)
    Spheres (circles) in a row along one line, moving along it: sequential, instantaneous binary
    collisions with Newton restitution e (the pair value of each neighbouring pair):
    ``u1' = (m1 u1 + m2 u2 - m2 e (u1 - u2)) / (m1 + m2)``,
    ``u2' = (m1 u1 + m2 u2 + m1 e (u1 - u2)) / (m1 + m2)`` (equal masses, target at rest:
    ``(1 - e) v / 2`` and ``(1 + e) v / 2``), computed event by event. No gravity, or gravity
    with the row resting on a frictionless ground. ``billiard``: exactly two bodies, which must
    meet during the run. ``newtons_cradle``: two or more, neighbours never exactly touching (a
    touching row has no unique rigid answer, CONTACTS.md trap C17); two collisions at the same
    instant sharing a ball are refused for the same reason.

Extra metrics (``EXTRA_METRICS[name](scene, run)``), measured from the run's own samples:

* bounce: ``apex_height_error_rel``, ``impact_time_error`` (s); see :func:`bounce_metrics`.
* slide_to_rest: ``stop_distance_error_rel``, ``stop_time_error`` (s); see :func:`slide_metrics`.
* roll_incline: ``rolling_acceleration_error_rel``, ``slip_velocity_error`` (m/s).
* block_incline: ``incline_drift`` (m) when it should stay, ``effective_friction_error`` when it
  should slide.
* billiard: ``momentum_transfer_error``; newtons_cradle: ``cradle_velocity_error`` (m/s).

Discrete engines differ from these ideal answers by O(v dt) per contact event (CONTACTS.md section
1.1: the rebound starts up to v dt inside the ground, so a measured apex is about
``e^2 (h + p) - p`` with ``p <= v dt``; stop distances are off by ``+-v0 dt / 2``); tolerances
must allow for that.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from crosscheck.rotations import quat_mul, rotvec_to_quat
from crosscheck.scene.contact import GROUND, pair_material
from crosscheck.scene.model import Body, Placed, Scene
from crosscheck.state import Trajectory

# A body "touches" the ground when its lowest point is within this of the plane (m). Cases put
# bodies exactly on the plane; the slack only absorbs the round-off of a rotated placement.
TOUCH_ATOL = 1e-6
DIRECTION_RTOL = 1e-9  # |a - (a.b) b| / |a| for "a is along b"
CENTRED_ATOL = 1e-12  # m, |com| for "the centre of mass is at the shape's centre"
STOP_SPEED = 1e-3  # m/s, a run has stopped when its speed first falls below this (CONTACTS.md)
APEX_MIN = 0.01  # apexes lower than this fraction of H0 are not resolved (default)
MAX_EVENTS = 100_000


# -- shared pieces -------------------------------------------------------------------------------
def _refuse(name: str, why: str) -> ValueError:
    return ValueError(f"analytic solution {name!r} does not apply: {why}")


def _new(scene: Scene, times: np.ndarray, name: str) -> Trajectory:
    from crosscheck.reference.analytic import _new as new

    return new(scene, times, name)


def _unit(v) -> np.ndarray:
    v = np.asarray(v, float)
    return v / np.linalg.norm(v)


def _along(v, d, what: str, name: str) -> float:
    """The component of v along unit d; refused when v has any other component."""
    v = np.asarray(v, float)
    c = float(v @ d)
    if np.linalg.norm(v - c * d) > DIRECTION_RTOL * max(np.linalg.norm(v), 1e-300):
        raise _refuse(name, what)
    return c


def _lift(v) -> np.ndarray:
    """A 2D vector as a 3D one (z = 0), for cross products."""
    v = np.asarray(v, float)
    return v if len(v) == 3 else np.array([v[0], v[1], 0.0])


def _contact_only(scene: Scene, name: str, n_bodies: int | None = None,
                  statics: bool = False) -> None:
    if not scene.effects.contact:
        raise _refuse(name, "the scene has no contact ([effects] contact = true)")
    if scene.fluid is not None:
        raise _refuse(name, "the scene has a fluid")
    if scene.effects.springs or scene.effects.drag or scene.effects.loads:
        raise _refuse(name, "the scene has springs, drag or loads")
    if scene.effects.medium is not None:
        raise _refuse(name, "the scene has a medium")
    if scene.statics and not statics:
        raise _refuse(name, f"the scene has statics ({', '.join(scene.static_names)}) the "
                      "model does not know about")
    if n_bodies is not None and len(scene.bodies) != n_bodies:
        raise _refuse(name, f"it describes {n_bodies} body (the scene has {len(scene.bodies)})")


def _ground(scene: Scene, name: str) -> tuple[np.ndarray, float]:
    if scene.ground is None:
        raise _refuse(name, "the scene has no [ground]")
    return _unit(scene.ground.normal), float(scene.ground.offset)


def _gravity(scene: Scene, name: str) -> np.ndarray:
    g = scene.effects.gravity
    if g is None or not np.any(np.asarray(g) != 0):
        raise _refuse(name, "the scene has no gravity")
    return np.asarray(g, float)


def _incline(scene: Scene, name: str, flat: bool) -> dict:
    """Ground normal n, offset, g, g_n (pressing), g_s (along the ground), s (downslope)."""
    n, offset = _ground(scene, name)
    g = _gravity(scene, name)
    g_n = -float(g @ n)
    if g_n <= 0:
        raise _refuse(name, "gravity does not press bodies onto the ground (gravity . normal "
                      ">= 0)")
    g_t = g + g_n * n
    g_s = float(np.linalg.norm(g_t))
    if flat:
        if g_s > DIRECTION_RTOL * np.linalg.norm(g):
            raise _refuse(name, "gravity is not along the ground normal (an incline: use "
                          "roll_incline or block_incline)")
        return {"n": n, "offset": offset, "g": g_n, "g_n": g_n, "g_s": 0.0, "s": None}
    if g_s <= DIRECTION_RTOL * np.linalg.norm(g):
        raise _refuse(name, "gravity is along the ground normal: there is no incline")
    return {"n": n, "offset": offset, "g": float(np.linalg.norm(g)), "g_n": g_n, "g_s": g_s,
            "s": g_t / g_s, "theta": float(np.arctan2(g_s, g_n))}


def _centred(body: Body, name: str) -> None:
    if np.linalg.norm(body.com) > CENTRED_ATOL:
        raise _refuse(name, f"the centre of mass of {body.name!r} is off its shape's centre")


def _gap(body: Body, n: np.ndarray, offset: float) -> float:
    """Height of the body's lowest point above the plane (negative: inside the ground)."""
    low = Placed(body.shape, body.position, body.orientation).support(-n).reshape(-1)
    return float(low @ n - offset)


def _touching(body: Body, n, offset, name: str) -> None:
    gap = _gap(body, n, offset)
    if abs(gap) > TOUCH_ATOL:
        raise _refuse(name, f"{body.name!r} does not start on the ground (its lowest point is "
                      f"{gap:.3g} m from the plane; within {TOUCH_ATOL:g} m expected)")


def _round(body: Body, name: str, kinds=("sphere", "circle")) -> float:
    if body.shape.kind not in kinds:
        raise _refuse(name, f"{body.name!r} is a {body.shape.kind}, not a "
                      f"{' or '.join(kinds)}")
    _centred(body, name)
    return float(body.shape.radius)


def _at_rest_spin(body: Body, name: str) -> None:
    if np.any(np.asarray(body.angular_velocity) != 0):
        raise _refuse(name, f"{body.name!r} starts spinning")


def _ground_pair(scene: Scene, body: Body):
    return pair_material(scene, body.name, GROUND)


def _footprint(body: Body, n: np.ndarray, name: str) -> dict:
    """A box (3D or 2D) or an upright cylinder standing on a face whose normal is n: the face's
    in-plane half extents, to find how far the centre of pressure may move before it tips."""
    r = body.rotation()
    kind = body.shape.kind
    _centred(body, name)
    if kind == "box":
        half = 0.5 * np.asarray(body.shape.size, float)
        dots = r.T @ n  # the body axes along the normal
        i = int(np.argmax(np.abs(dots)))
        if abs(abs(dots[i]) - 1.0) > DIRECTION_RTOL:
            raise _refuse(name, f"{body.name!r} does not stand on a face (no box axis along the "
                          "ground normal)")
        others = [j for j in range(len(half)) if j != i]
        return {"axes": [r[:, j] for j in others], "half": [half[j] for j in others]}
    if kind == "cylinder":
        if abs(abs(float(r[:, 2] @ n)) - 1.0) > DIRECTION_RTOL:
            raise _refuse(name, f"the cylinder {body.name!r} does not stand on its end")
        return {"radius": float(body.shape.radius)}
    raise _refuse(name, f"{body.name!r} is a {kind}: a box or an upright cylinder is needed")


def _edge_distance(fp: dict, u: np.ndarray) -> float:
    """Distance from the centre of mass's foot to the face's edge along the unit direction u."""
    if "radius" in fp:
        return fp["radius"]
    limits = [h / abs(float(a @ u)) for a, h in zip(fp["axes"], fp["half"], strict=True)
              if abs(float(a @ u)) > 1e-15]
    return min(limits)


def _isotropic_spin(scene: Scene, traj: Trajectory, i: int, t: np.ndarray) -> None:
    """Constant spin of body i (no torque): 2D always; 3D when the spin axis is principal."""
    body = scene.bodies[i]
    if scene.dimension == 2:
        w = float(body.angular_velocity[0])
        traj.angle[:, i], traj.omega[:, i] = body.angle + w * t, w
        return
    w = np.asarray(body.angular_velocity, float)
    wn = np.linalg.norm(w)
    if wn == 0.0:
        traj.quat[:, i], traj.omega[:, i] = body.orientation, 0.0
        return
    iw = body.inertia_world()
    nrm = w / wn
    if np.linalg.norm(iw @ nrm - float(nrm @ iw @ nrm) * nrm) > 1e-9 * np.linalg.norm(iw, 2):
        return  # the spin axis moves: orientation and angular velocity stay NaN
    traj.quat[:, i] = quat_mul(rotvec_to_quat(t[:, None] * w), body.orientation)
    traj.omega[:, i] = w


def _samples(run: Trajectory) -> float:
    if len(run.t) < 3:
        raise ValueError("the run has fewer than three samples")
    return float(np.median(np.diff(run.t)))


def _params(scene: Scene) -> dict:
    return dict(scene.reference.params or {})


# -- bounce --------------------------------------------------------------------------------------
@dataclass(frozen=True)
class _Bounce:
    n: np.ndarray
    z_c: float  # n . x of the centre when resting on the ground
    g: float
    e: float
    h0: float
    w0: float
    v1: float  # impact speed
    impacts: np.ndarray  # t_k, k = 1, 2, ... (those before the end of the run)
    speeds: np.ndarray  # u_k: leaving speed after impact k
    t_rest: float  # the ball rests from here (inf for e = 1)

    @property
    def H0(self) -> float:  # noqa: N802 - the apex height of the docs
        return self.v1 * self.v1 / (2.0 * self.g)


def _bounce_setup(scene: Scene, name: str = "bounce") -> _Bounce:
    _contact_only(scene, name, 1)
    inc = _incline(scene, name, flat=True)
    n, g = inc["n"], inc["g"]
    body = scene.bodies[0]
    r = _round(body, name)
    pair = _ground_pair(scene, body)
    x0, v0 = body.com_world(), np.asarray(body.velocity, float)
    w0 = float(v0 @ n)
    sliding = np.linalg.norm(v0 - w0 * n) > 0 or np.any(np.asarray(body.angular_velocity) != 0)
    if sliding and (pair.friction > 0 or pair.rolling_friction > 0
                    or pair.torsional_friction > 0):
        raise _refuse(name, f"{body.name!r} moves along the ground or spins while the pair "
                      "{body, ground} has friction (the impacts would couple spin and motion)")
    z_c = inc["offset"] + r
    h0 = float(x0 @ n) - z_c
    if h0 < -TOUCH_ATOL:
        raise _refuse(name, f"{body.name!r} starts {-h0:.3g} m inside the ground")
    h0 = max(h0, 0.0)
    e = float(pair.restitution)
    v1 = float(np.sqrt(w0 * w0 + 2.0 * g * h0))
    t_end = scene.run.duration
    if v1 == 0.0:
        return _Bounce(n, z_c, g, e, h0, w0, v1, np.zeros(0), np.zeros(0), 0.0)
    t1 = (w0 + v1) / g
    t_rest = np.inf if e >= 1.0 else t1 + 2.0 * e * v1 / (g * (1.0 - e))
    impacts, speeds = [t1], [e * v1]
    while impacts[-1] <= t_end and speeds[-1] > 1e-12 * v1:
        if len(impacts) >= MAX_EVENTS:
            raise _refuse(name, f"more than {MAX_EVENTS} bounces in the run")
        impacts.append(impacts[-1] + 2.0 * speeds[-1] / g)
        speeds.append(speeds[-1] * e)
    return _Bounce(n, z_c, g, e, h0, w0, v1, np.array(impacts), np.array(speeds), t_rest)


def _bounce_height(b: _Bounce, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Height above the resting contact height and normal velocity of the ideal ball."""
    h, w = np.zeros_like(t), np.zeros_like(t)
    if b.v1 == 0.0:
        return h, w
    before = t < b.impacts[0]
    h[before] = b.h0 + b.w0 * t[before] - 0.5 * b.g * t[before] ** 2
    w[before] = b.w0 - b.g * t[before]
    k = np.searchsorted(b.impacts, t, side="right") - 1
    flying = (~before) & (t < b.t_rest)
    tau = t[flying] - b.impacts[k[flying]]
    u = b.speeds[k[flying]]
    h[flying] = np.maximum(u * tau - 0.5 * b.g * tau * tau, 0.0)
    w[flying] = np.where(tau < 2.0 * u / b.g, u - b.g * tau, 0.0)
    return h, w


def bounce(scene: Scene, times: np.ndarray) -> Trajectory:
    """A sphere (circle) dropped or thrown along the ground normal (see the module doc)."""
    name = "bounce"
    b = _bounce_setup(scene, name)
    t = np.asarray(times, float)
    traj = _new(scene, t, name)
    body = scene.bodies[0]
    x0, v0 = body.com_world(), np.asarray(body.velocity, float)
    vt = v0 - float(v0 @ b.n) * b.n
    h, w = _bounce_height(b, t)
    base = x0 - float(x0 @ b.n) * b.n
    traj.com[:, 0] = base + t[:, None] * vt + (b.z_c + h)[:, None] * b.n
    traj.vel[:, 0] = vt + w[:, None] * b.n
    _isotropic_spin(scene, traj, 0, t)
    traj.meta["impacts"] = b.impacts[b.impacts <= t[-1]].tolist() if len(t) else []
    return traj


def _falling_episodes(w: np.ndarray, floor: float) -> list[tuple[int, int]]:
    """Maximal runs of samples with w < -floor: (first, last) indices."""
    falling = np.concatenate([[False], w < -floor, [False]])
    edges = np.flatnonzero(np.diff(falling.astype(int)))
    return [(int(a), int(b) - 1) for a, b in zip(edges[::2], edges[1::2], strict=True)]


def bounce_metrics(scene: Scene, run: Trajectory) -> dict[str, float]:
    """Apexes and impact times of a run against the ideal bounces.

    From the run's samples (body 0): height above the resting contact height ``h = n . x - z_c``
    and normal velocity ``w``. A *fall* is a maximal run of samples with ``w < -w_floor``; the
    k-th fall ends at the k-th impact. The impact time is extrapolated ballistically from the
    fall's last sample with h >= 0: ``t_j + (w_j + sqrt(w_j^2 + 2 g h_j)) / g``. The k-th apex is
    ``h + w^2 / (2 g)`` at the highest sample after the k-th fall and up to the start of the next
    one: the height free flight reaches from that sample, so sampling does not clip the apex,
    taken where the correction is smallest (an integrator's drift of that quantity along the
    flight, ``g dt t / 2`` for symplectic Euler, then does not count).

    Compared: apexes k >= 1 whose ideal height ``h_k = e^(2k) H0`` is at least ``h_min =
    max(apex_min H0, 2 g ds^2)`` (``reference.params.apex_min``, default 0.01; ds the sampling
    interval: a lower flight lasts fewer than four samples) and whose ideal apex time is a
    sample before the end; apex 1 always when impact 1 is at least four samples before the end
    (so an inelastic ball that bounces is caught). ``w_floor = sqrt(2 g h_min) / 4``.
    ``apex_height_error_rel = max_k |h_k,run - h_k| / H0``; ``impact_time_error = max_k
    |t_k,run - t_k|`` over the impacts preceding the compared apexes (infinite when the run lacks
    one of them).
    """
    b = _bounce_setup(scene)
    if b.v1 == 0.0:
        raise ValueError("the ball starts at rest on the ground: nothing bounces")
    ds = _samples(run)
    g, H0 = b.g, b.H0
    t = run.t
    h = run.com[:, 0] @ b.n - b.z_c
    w = run.vel[:, 0] @ b.n
    apex_min = float(_params(scene).get("apex_min", APEX_MIN))
    h_min = max(apex_min * H0, 2.0 * g * ds * ds)
    floor = 0.25 * np.sqrt(2.0 * g * h_min)
    falls = [f for f in _falling_episodes(w, floor) if f[1] < len(t) - 1]
    impacts, apexes = [], []
    for i, (first, last) in enumerate(falls):
        above = [j for j in range(last, first - 1, -1) if h[j] >= 0]
        j = above[0] if above else last
        hj = max(float(h[j]), 0.0)
        impacts.append(t[j] + (w[j] + np.sqrt(w[j] ** 2 + 2.0 * g * hj)) / g)
        stop = falls[i + 1][0] if i + 1 < len(falls) else len(t) - 1
        window = slice(last + 1, stop + 1)
        top = last + 1 + int(np.argmax(h[window]))
        apexes.append(float(h[top] + w[top] ** 2 / (2.0 * g)))
    t_last = t[-1]
    compared = []
    for k in range(1, len(b.impacts) + 1):
        t_k, u_k = b.impacts[k - 1], b.speeds[k - 1]
        h_k = u_k * u_k / (2.0 * g)
        if k == 1 and t_k + 4 * ds <= t_last:
            compared.append((k, h_k))
        elif k > 1 and h_k >= h_min and t_k + u_k / g <= t_last - ds:
            compared.append((k, h_k))
    if not compared:
        raise ValueError("the run ends before the first bounce can be measured")
    apex_err = max(abs((apexes[k - 1] if k <= len(apexes) else 0.0) - h_k) / H0
                   for k, h_k in compared)
    time_err = max(abs(impacts[k - 1] - b.impacts[k - 1]) if k <= len(impacts) else np.inf
                   for k, _ in compared)
    return {"apex_height_error_rel": float(apex_err), "impact_time_error": float(time_err)}


# -- sliding and standing boxes ------------------------------------------------------------------
def _standing_box(scene: Scene, name: str, flat: bool):
    _contact_only(scene, name, 1)
    inc = _incline(scene, name, flat=flat)
    body = scene.bodies[0]
    fp = _footprint(body, inc["n"], name)
    _touching(body, inc["n"], inc["offset"], name)
    _at_rest_spin(body, name)
    h_com = float(body.com_world() @ inc["n"]) - inc["offset"]
    return inc, body, fp, h_com, _ground_pair(scene, body)


@dataclass(frozen=True)
class _Slide:
    x0: np.ndarray
    u: np.ndarray  # direction of motion
    v0: float
    decel: float  # mu g
    t_stop: float


def _slide_setup(scene: Scene, name: str = "slide_to_rest") -> _Slide:
    inc, body, fp, h_com, pair = _standing_box(scene, name, flat=True)
    n = inc["n"]
    v = np.asarray(body.velocity, float)
    if abs(float(v @ n)) > DIRECTION_RTOL * max(np.linalg.norm(v), 1e-300):
        raise _refuse(name, f"{body.name!r} has a velocity off the ground plane")
    v0 = float(np.linalg.norm(v))
    if v0 == 0.0:
        raise _refuse(name, f"{body.name!r} starts at rest (nothing slides)")
    mu = float(pair.friction)
    if mu <= 0.0:
        raise _refuse(name, "the pair {body, ground} is frictionless: the body never stops")
    u = v / v0
    edge = _edge_distance(fp, u)
    if mu * h_com >= edge:
        raise _refuse(name, f"{body.name!r} would tip over while sliding: mu h_com = "
                      f"{mu * h_com:.4g} m >= {edge:.4g} m, the distance to the leading edge "
                      "of its face (CONTACTS.md C14)")
    decel = mu * inc["g"]
    t_stop = v0 / decel
    if scene.run.duration < t_stop:
        raise _refuse(name, f"the run ({scene.run.duration:g} s) ends before the body stops "
                      f"(t_stop = {t_stop:.4g} s)")
    return _Slide(body.com_world(), u, v0, decel, t_stop)


def slide_to_rest(scene: Scene, times: np.ndarray) -> Trajectory:
    """A box launched along flat ground stops under Coulomb friction (see the module doc)."""
    name = "slide_to_rest"
    s = _slide_setup(scene, name)
    t = np.asarray(times, float)
    traj = _new(scene, t, name)
    tau = np.minimum(t, s.t_stop)
    dist = s.v0 * tau - 0.5 * s.decel * tau * tau
    speed = np.where(t < s.t_stop, s.v0 - s.decel * tau, 0.0)
    traj.com[:, 0] = s.x0 + dist[:, None] * s.u
    traj.vel[:, 0] = speed[:, None] * s.u
    _isotropic_spin(scene, traj, 0, t)
    traj.meta["stop_time"] = s.t_stop
    traj.meta["stop_distance"] = s.v0 * s.v0 / (2.0 * s.decel)
    return traj


def _tangential(scene: Scene, run: Trajectory, n: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Displacement from the start and velocity of body 0, without their normal components."""
    x = run.com[:, 0] - scene.bodies[0].com_world()
    v = run.vel[:, 0]
    return x - np.outer(x @ n, n), v - np.outer(v @ n, n)


def slide_metrics(scene: Scene, run: Trajectory) -> dict[str, float]:
    """``stop_distance_error_rel = |d_run - d| / d``, d_run the distance along the ground between
    the start and the last sample, ``d = v0^2 / (2 mu g)``. ``stop_time_error = |t_run - t_thr|``:
    t_run is when the run's speed along the ground first falls below ``v_stop``
    (``reference.params.stop_speed``, default 1 mm/s, as CONTACTS.md), between samples j-1 and j
    located with the run's own deceleration over the interval before (linear interpolation when
    there is none); ``t_thr = (v0 - v_stop) / (mu g)`` is the same crossing in the ideal model.
    Infinite when the run never falls below v_stop."""
    s = _slide_setup(scene)
    n = np.asarray(_ground(scene, "slide_to_rest")[0])
    x, v = _tangential(scene, run, n)
    _samples(run)
    d = s.v0 * s.v0 / (2.0 * s.decel)
    out = {"stop_distance_error_rel": float(abs(np.linalg.norm(x[-1]) - d) / d)}
    thr = float(_params(scene).get("stop_speed", STOP_SPEED))
    out["stop_time_error"] = float(abs(_crossing(run.t, np.linalg.norm(v, axis=1), thr)
                                       - (s.v0 - thr) / s.decel))
    return out


def _crossing(t: np.ndarray, speed: np.ndarray, thr: float) -> float:
    below = np.flatnonzero(speed[1:] < thr)
    if len(below) == 0:
        return np.inf
    j = int(below[0]) + 1
    if j >= 2 and speed[j - 2] > speed[j - 1]:
        decel = (speed[j - 2] - speed[j - 1]) / (t[j - 1] - t[j - 2])
        return float(min(t[j - 1] + (speed[j - 1] - thr) / decel, t[j]))
    frac = (speed[j - 1] - thr) / (speed[j - 1] - speed[j])
    return float(t[j - 1] + frac * (t[j] - t[j - 1]))


@dataclass(frozen=True)
class _Block:
    x0: np.ndarray
    s: np.ndarray
    static: bool
    accel: float
    g_s: float
    g_n: float
    mu: float


def _block_setup(scene: Scene, name: str = "block_incline") -> _Block:
    inc, body, fp, h_com, pair = _standing_box(scene, name, flat=False)
    if np.any(np.asarray(body.velocity) != 0):
        raise _refuse(name, f"{body.name!r} does not start at rest")
    mu = float(pair.friction)
    g_s, g_n = inc["g_s"], inc["g_n"]
    static = g_s <= mu * g_n
    lean = g_s / g_n if static else mu  # tangential / normal contact force
    edge = _edge_distance(fp, inc["s"])
    if lean * h_com >= edge:
        raise _refuse(name, f"{body.name!r} would tip over: h_com x {lean:.4g} = "
                      f"{lean * h_com:.4g} m >= {edge:.4g} m, the distance to the downhill edge "
                      "of its face")
    return _Block(body.com_world(), inc["s"], static, 0.0 if static else g_s - mu * g_n,
                  g_s, g_n, mu)


def block_incline(scene: Scene, times: np.ndarray) -> Trajectory:
    """A box at rest on an incline: holds below the friction angle, else slides."""
    name = "block_incline"
    b = _block_setup(scene, name)
    t = np.asarray(times, float)
    traj = _new(scene, t, name)
    traj.com[:, 0] = b.x0 + (0.5 * b.accel * t * t)[:, None] * b.s
    traj.vel[:, 0] = (b.accel * t)[:, None] * b.s
    _isotropic_spin(scene, traj, 0, t)
    traj.meta["holds"] = b.static
    return traj


def block_metrics(scene: Scene, run: Trajectory) -> dict[str, float]:
    """Holding (tan theta <= mu): ``incline_drift``, the largest distance along the ground the
    run's centre of mass moved from its start (m; ideal 0). Sliding: ``effective_friction_error =
    |mu_eff - mu|``, ``mu_eff = (g_s - 2 d / T^2) / g_n`` from the distance d down the slope at
    the run's last sample T (CONTACTS.md section 1.4: near the friction angle a distance error
    is a small friction error magnified, so friction is compared, not distance)."""
    b = _block_setup(scene)
    n = np.asarray(_ground(scene, "block_incline")[0])
    x, _ = _tangential(scene, run, n)
    if b.static:
        return {"incline_drift": float(np.max(np.linalg.norm(x, axis=1)))}
    T = float(run.t[-1] - run.t[0])  # noqa: N806
    if T <= 0:
        raise ValueError("the run has no duration")
    mu_eff = (b.g_s - 2.0 * float(x[-1] @ b.s) / (T * T)) / b.g_n
    return {"effective_friction_error": float(abs(mu_eff - b.mu))}


# -- rolling -------------------------------------------------------------------------------------
@dataclass(frozen=True)
class _Roll:
    x0: np.ndarray
    s: np.ndarray
    a: np.ndarray  # rolling axis n x s (3D)
    r: float
    phases: tuple  # (t_start, accel, angular accel, kind)
    v0: float
    w0: float  # spin about a
    mu_crit: float


def _roll_setup(scene: Scene, name: str = "roll_incline") -> _Roll:
    _contact_only(scene, name, 1)
    inc = _incline(scene, name, flat=False)
    n, s = inc["n"], inc["s"]
    body = scene.bodies[0]
    kinds = ("circle",) if scene.dimension == 2 else ("sphere", "cylinder", "capsule")
    if body.shape.kind not in kinds:
        raise _refuse(name, f"{body.name!r} is a {body.shape.kind}, not a {' or '.join(kinds)}")
    _centred(body, name)
    r = float(body.shape.radius)
    a = np.cross(_lift(n), _lift(s))
    if body.shape.kind in ("cylinder", "capsule"):
        axis = body.rotation()[:, 2]
        if abs(abs(float(axis @ a)) - 1.0) > DIRECTION_RTOL:
            raise _refuse(name, f"the {body.shape.kind} {body.name!r} does not lie across the "
                          "slope (its axis must be along n x downslope)")
    _touching(body, n, inc["offset"], name)
    if scene.dimension == 3:
        iw = body.inertia_world()
        inertia = float(a @ iw @ a)
        if np.linalg.norm(iw @ a - inertia * a) > 1e-9 * np.linalg.norm(iw, 2):
            raise _refuse(name, f"the rolling axis is not a principal axis of {body.name!r}")
        w_vec = np.asarray(body.angular_velocity, float)
        w0 = float(w_vec @ a)
        if np.linalg.norm(w_vec - w0 * a) > DIRECTION_RTOL * max(np.linalg.norm(w_vec), 1e-300):
            raise _refuse(name, f"{body.name!r} spins about another axis than n x downslope")
    else:
        inertia = body.moment
        w0 = float(body.angular_velocity[0]) * float(a[2])
    v0 = _along(body.velocity, s, f"{body.name!r} has a velocity off the downslope line", name)
    pair = _ground_pair(scene, body)
    if pair.rolling_friction > 0:
        raise _refuse(name, "the pair {body, ground} has rolling friction (not in the model)")
    mu, m = float(pair.friction), body.mass
    k = inertia / (m * r * r)
    g_s, g_n = inc["g_s"], inc["g_n"]
    mu_crit = (g_s / g_n) * k / (1.0 + k)

    def slip(sig):
        return (g_s - sig * mu * g_n, sig * mu * g_n / (k * r), f"slip{'+' if sig > 0 else '-'}")

    roll = (g_s / (1.0 + k), g_s / ((1.0 + k) * r), "roll")
    u0 = v0 - r * w0
    scale = abs(v0) + r * abs(w0)
    if abs(u0) <= 1e-12 * scale or scale == 0.0:
        phases = ((0.0, *roll),) if mu >= mu_crit else ((0.0, *slip(1.0)),)
    else:
        sig = float(np.sign(u0))
        a1, al1, kind = slip(sig)
        du = a1 - r * al1
        if du * sig < 0:
            t1 = -u0 / du
            after = roll if mu >= mu_crit else slip(1.0)
            phases = ((0.0, a1, al1, kind), (t1, *after))
        else:
            phases = ((0.0, a1, al1, kind),)
    return _Roll(body.com_world(), s, a, r, phases, v0, w0, mu_crit)


def _roll_state(rl: _Roll, t: np.ndarray):
    """Distance, speed down the slope, rotation angle and spin about a, at t."""
    d, v, phi, w = (np.zeros_like(t) for _ in range(4))
    d0, v0, p0, w0 = 0.0, rl.v0, 0.0, rl.w0
    for i, (ts, acc, alpha, _) in enumerate(rl.phases):
        te = rl.phases[i + 1][0] if i + 1 < len(rl.phases) else np.inf
        sel = (t >= ts) & (t < te)
        tau = t[sel] - ts
        d[sel] = d0 + v0 * tau + 0.5 * acc * tau * tau
        v[sel] = v0 + acc * tau
        phi[sel] = p0 + w0 * tau + 0.5 * alpha * tau * tau
        w[sel] = w0 + alpha * tau
        if np.isfinite(te):
            span = te - ts
            d0 = d0 + v0 * span + 0.5 * acc * span * span
            p0 = p0 + w0 * span + 0.5 * alpha * span * span
            v0, w0 = v0 + acc * span, w0 + alpha * span
    return d, v, phi, w


def roll_incline(scene: Scene, times: np.ndarray) -> Trajectory:
    """A ball or cylinder on an incline, rolling or slipping (see the module doc)."""
    name = "roll_incline"
    rl = _roll_setup(scene, name)
    t = np.asarray(times, float)
    traj = _new(scene, t, name)
    body = scene.bodies[0]
    d, v, phi, w = _roll_state(rl, t)
    traj.com[:, 0] = rl.x0 + d[:, None] * rl.s
    traj.vel[:, 0] = v[:, None] * rl.s
    if scene.dimension == 3:
        traj.quat[:, 0] = quat_mul(rotvec_to_quat(phi[:, None] * rl.a), body.orientation)
        traj.omega[:, 0] = w[:, None] * rl.a
    else:
        traj.angle[:, 0] = body.angle + rl.a[2] * phi
        traj.omega[:, 0] = rl.a[2] * w
    traj.meta["phases"] = [[p[0], p[3]] for p in rl.phases]
    traj.meta["mu_crit"] = rl.mu_crit
    return traj


def roll_metrics(scene: Scene, run: Trajectory) -> dict[str, float]:
    """``slip_velocity_error = max_t |u_run - u|`` (m/s), u = v . s - r omega . a the velocity of
    the contact point along the slope (0 while rolling). ``rolling_acceleration_error_rel =
    |a_run - a| / |a|`` with a the centre's acceleration down the slope in the model's last phase
    (rolling, or slipping when mu < mu_crit) and a_run the least-squares slope of the run's
    v . s against t over the samples in that phase (at least three)."""
    rl = _roll_setup(scene)
    _samples(run)
    t = run.t
    v = run.vel[:, 0] @ rl.s
    w = run.omega[:, 0] @ rl.a if scene.dimension == 3 else run.omega[:, 0] * rl.a[2]
    _, v_id, _, w_id = _roll_state(rl, t)
    out = {"slip_velocity_error": float(np.max(np.abs((v - rl.r * w) - (v_id - rl.r * w_id))))}
    t_last, acc = rl.phases[-1][0], rl.phases[-1][1]
    sel = t > t_last
    if np.count_nonzero(sel) < 3:
        raise ValueError("fewer than three samples in the last phase")
    slope = np.polyfit(t[sel], v[sel], 1)[0]
    out["rolling_acceleration_error_rel"] = float(abs(slope - acc) / abs(acc))
    return out


# -- collisions in a row -------------------------------------------------------------------------
@dataclass(frozen=True)
class _Row:
    d: np.ndarray  # the line
    x0: np.ndarray  # (N, dim) centres
    s0: np.ndarray  # (N,) positions along d
    gravity: np.ndarray  # added free fall (zero when resting on the ground or no gravity)
    events: tuple  # (t, s (N,), u (N,)) after each collision, first entry t = 0


def _row_setup(scene: Scene, name: str, two: bool) -> _Row:
    _contact_only(scene, name, 2 if two else None)
    bodies = scene.bodies
    if len(bodies) < 2:
        raise _refuse(name, "it needs at least two bodies in a row")
    radii = np.array([_round(b, name) for b in bodies])
    for b in bodies:
        _at_rest_spin(b, name)
    x0 = np.array([b.com_world() for b in bodies])
    d = x0[-1] - x0[0]
    if np.linalg.norm(d) == 0:
        raise _refuse(name, "the first and last bodies start at the same place")
    d = d / np.linalg.norm(d)
    s0 = x0 @ d
    off = x0 - x0[0] - np.outer(s0 - s0[0], d)
    if np.max(np.linalg.norm(off, axis=1)) > DIRECTION_RTOL * (s0[-1] - s0[0]):
        raise _refuse(name, "the centres are not on one line")
    if np.any(np.diff(s0) <= 0):
        raise _refuse(name, "the bodies are not listed in their order along the line")
    u0 = np.array([_along(b.velocity, d, f"{b.name!r} moves off the line of centres", name)
                   for b in bodies])
    gaps = np.diff(s0) - radii[:-1] - radii[1:]
    if np.any(gaps < -TOUCH_ATOL):
        raise _refuse(name, "neighbouring bodies overlap at the start")
    if not two and np.any(gaps <= 0):
        raise _refuse(name, "neighbouring bodies touch at the start: the outcome of a touching "
                      "row is solver-defined (-1/3, 2/3, 2/3 or 0, 0, 1; CONTACTS.md C17); leave "
                      "gaps")
    g = scene.effects.gravity
    fall = np.zeros(scene.dimension)
    if scene.ground is not None:
        n, offset = _ground(scene, name)
        if abs(float(d @ n)) > DIRECTION_RTOL:
            raise _refuse(name, "the line of centres is not parallel to the ground")
        if g is not None and np.any(np.asarray(g) != 0):
            _incline(scene, name, flat=True)
            for b in bodies:
                _touching(b, n, offset, name)
                p = _ground_pair(scene, b)
                if p.friction > 0 or p.rolling_friction > 0:
                    raise _refuse(name, f"the pair {{{b.name}, ground}} has friction (the balls "
                                  "would start rolling)")
        else:
            for b in bodies:
                if _gap(b, n, offset) < -TOUCH_ATOL:
                    raise _refuse(name, f"{b.name!r} starts inside the ground")
    elif g is not None:
        fall = np.asarray(g, float)  # the whole row falls: relative motion unchanged
    masses = np.array([b.mass for b in bodies])
    e = np.array([pair_material(scene, bodies[i].name, bodies[i + 1].name).restitution
                  for i in range(len(bodies) - 1)])
    events = [(0.0, s0.copy(), u0.copy())]
    t, s, u = 0.0, s0.copy(), u0.copy()
    t_end = scene.run.duration
    while True:
        closing = u[:-1] - u[1:]
        gap = np.diff(s) - radii[:-1] - radii[1:]
        with np.errstate(divide="ignore", invalid="ignore"):
            when = np.where(closing > 0, np.maximum(gap, 0.0) / closing, np.inf)
        i = int(np.argmin(when))
        dt = float(when[i])
        if not np.isfinite(dt) or t + dt > t_end:
            break
        tie = np.flatnonzero(np.abs(when - dt) <= 1e-12 * max(1.0, t + dt))
        if np.any(np.abs(tie - i) == 1):
            raise _refuse(name, f"two collisions sharing a body happen at the same instant "
                          f"(t = {t + dt:.6g} s): the sequential answer is not unique")
        if len(events) > MAX_EVENTS:
            raise _refuse(name, f"more than {MAX_EVENTS} collisions (inelastic collapse)")
        t += dt
        s = s + u * dt
        m1, m2, ui, uj = masses[i], masses[i + 1], u[i], u[i + 1]
        p = m1 * ui + m2 * uj
        u = u.copy()
        u[i] = (p - m2 * e[i] * (ui - uj)) / (m1 + m2)
        u[i + 1] = (p + m1 * e[i] * (ui - uj)) / (m1 + m2)
        events.append((t, s.copy(), u.copy()))
    return _Row(d, x0, s0, fall, tuple(events))


def _row_trajectory(scene: Scene, times: np.ndarray, name: str, row: _Row) -> Trajectory:
    t = np.asarray(times, float)
    traj = _new(scene, t, name)
    starts = np.array([ev[0] for ev in row.events])
    k = np.maximum(np.searchsorted(starts, t, side="right") - 1, 0)
    s_ev = np.array([ev[1] for ev in row.events])[k]  # (T, N)
    u_ev = np.array([ev[2] for ev in row.events])[k]
    s = s_ev + u_ev * (t - starts[k])[:, None]
    traj.com[:] = (row.x0[None] + (s - row.s0[None])[:, :, None] * row.d
                   + 0.5 * (t * t)[:, None, None] * row.gravity)
    traj.vel[:] = u_ev[:, :, None] * row.d + t[:, None, None] * row.gravity
    for i in range(len(scene.bodies)):
        _isotropic_spin(scene, traj, i, t)
    traj.meta["collisions"] = [ev[0] for ev in row.events[1:]]
    return traj


def billiard(scene: Scene, times: np.ndarray) -> Trajectory:
    """Head-on collision of two spheres (circles): Newton restitution, momentum conserved."""
    name = "billiard"
    row = _row_setup(scene, name, two=True)
    if len(row.events) < 2:
        raise _refuse(name, "the two bodies do not meet during the run")
    return _row_trajectory(scene, times, name, row)


def newtons_cradle(scene: Scene, times: np.ndarray) -> Trajectory:
    """A row of spheres (circles) with gaps struck at one end: sequential collisions."""
    name = "newtons_cradle"
    row = _row_setup(scene, name, two=False)
    if len(row.events) < 2:
        raise _refuse(name, "no collision happens during the run")
    return _row_trajectory(scene, times, name, row)


def billiard_metrics(scene: Scene, run: Trajectory) -> dict[str, float]:
    """``momentum_transfer_error = |J_run - J| / |J|``: J the momentum the second body gains along
    the line, ``m2 (u2' - u2) = m1 m2 (1 + e) (u1 - u2) / (m1 + m2)``, J_run the same from the
    run's velocity at its last sample (free fall removed), so the case must end after the
    collision is over (a soft contact lasts a few steps)."""
    row = _row_setup(scene, "billiard", two=True)
    if len(row.events) < 2:
        raise ValueError("the bodies do not meet during the run")
    m2 = scene.bodies[1].mass
    j_ideal = m2 * (row.events[-1][2][1] - row.events[0][2][1])
    v_end = run.vel[-1, 1] - run.t[-1] * row.gravity
    j_run = m2 * (float(v_end @ row.d) - row.events[0][2][1])
    return {"momentum_transfer_error": float(abs(j_run - j_ideal) / abs(j_ideal))}


def cradle_metrics(scene: Scene, run: Trajectory) -> dict[str, float]:
    """``cradle_velocity_error = max_i |v_i,run(T) - v_i(T)|`` (m/s) at the run's last sample T:
    after the sequence the last ball leaves with the striker's speed and the others rest."""
    row = _row_setup(scene, "newtons_cradle", two=False)
    ideal = _row_trajectory(scene, run.t[-1:], "newtons_cradle", row)
    err = np.linalg.norm(run.vel[-1] - ideal.vel[0], axis=1)
    return {"cradle_velocity_error": float(np.max(err))}


SOLUTIONS: dict[str, Callable[[Scene, np.ndarray], Trajectory]] = {
    "bounce": bounce,
    "slide_to_rest": slide_to_rest,
    "roll_incline": roll_incline,
    "block_incline": block_incline,
    "billiard": billiard,
    "newtons_cradle": newtons_cradle,
}

EXTRA_METRICS: dict[str, Callable[[Scene, Trajectory], dict[str, float]]] = {
    "bounce": bounce_metrics,
    "slide_to_rest": slide_metrics,
    "roll_incline": roll_metrics,
    "block_incline": block_metrics,
    "billiard": billiard_metrics,
    "newtons_cradle": cradle_metrics,
}
