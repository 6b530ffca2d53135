"""Contact metrics: computed by crosscheck from the normalised Trajectory and the Scene's geometry,
never from an engine's own contact report, with the same formulas for every engine.

Bodies are placed at every sample from the Trajectory (the body frame's origin is
``x_com - R com_body``, ``R`` from the quaternion or angle) and queried through the shapes of
:mod:`crosscheck.scene.shapes`; the ground is the plane ``n . p = offset`` (``n`` out of it); the
statics are placed shapes. Only the pairs :func:`crosscheck.scene.contact.pairs` lists with
``collide = true`` are measured. ``t`` runs over the recorded samples, ``r_i`` is the body size of
docs/metrics.md (:func:`crosscheck.compare.scales.body_radius`). Everything is repeated in
docs/metrics.md, "Contact".

Gap and penetration depth of a pair (m)
    ``gap`` is signed: ``-depth`` when the two overlap, the separation when they do not;
    ``depth = max(0, -gap)``, the minimum translation that separates them. Exact (to round-off):

    * body-ground: ``gap = n . s(-n) - offset``, ``s(-n)`` the world support point of the placed
      shape in ``-n`` (every shape; a mesh by its vertices, whose lowest is its deepest point);
    * sphere-sphere, circle-circle: ``|c_a - c_b| - r_a - r_b`` (centres are body-frame origins);
    * sphere (circle) against a box, capsule, cylinder, sphere, polygon: ``sdf_B(c_a) - r_a``,
      the exact signed distance of the other shape at the sphere's centre (exact for a convex B);
    * 2D boxes and convex polygons: the separating-axis test on both shapes' edge normals,
      ``gap = -min_axes overlap`` (exact depth; when apart, a lower bound of the distance);
    * 3D box-box: the separating-axis test on the 15 axes (3 + 3 face normals, 9 edge-edge
      cross products): the minimum overlap is the exact penetration depth.

    * any other 3D pair (capsule-box, capsule-capsule, cylinder-box, a mesh against a body or a
      static, ...): FCL's signed distance (:mod:`crosscheck.compare.convex_gap`: EPA depth to
      1e-6 m; a capsule's separation refined exactly; a mesh as its convex hull, as every engine
      collides it).

    Without FCL those pairs make both penetration metrics *not measurable*: value None,
    meaningful False and the pair types named, never a silent 0. Body-body pairs are pruned
    once per sample by a NumPy sort-and-sweep on the world bounding boxes (inflated by the
    contact tolerance), so a pile of many bodies costs ``O(T (N log N + K))`` with no Python
    loop over pairs.

In contact, resting
    A pair is *in contact* at a sample when ``gap <= CONTACT_GAP_FRACTION * r`` (``r`` the
    smaller body size of the pair). It *rests* when it is in contact and its relative speed bound
    ``|v_a - v_b| + |w_a| r_a + |w_b| r_b`` (fixed geometry: 0) is below ``REST_SPEED``: no two
    material points of the pair move relative to each other faster than that, so the relative
    normal speed is below it too.

``penetration_max`` (m)
    ``max_t max_pairs depth``.
``penetration_resting_mean`` (m)
    The mean depth over the samples of each pair's *final resting stretch*: the uninterrupted run
    of resting samples that ends at the last sample, counted only for pairs that rest at every
    sample of the last ``REST_FRACTION`` of the run (``t >= t_end - REST_FRACTION (t_end - t_0)``).
    Every (pair, sample) weighs the same. Not measurable when no pair rests so.
``energy_gain`` (-)
    ``max_t max(0, E(t) - E(0)) / S_E`` with the energy and scale of ``energy_drift`` (total
    energy with ground contact, the internal energy otherwise). Contact may lose energy, never gain
    it: meaningful for every contact scene except one with a constant torque on a 3D body (which
    has no potential). Set its tolerance from the integrator's own drift on a contact-free case.
Impacts and restitution (body-ground)
    ``v_n = n . v`` (centre of mass). A sample interval ``[k, k+1]`` is a *contact interval* when
    either end is in contact, or ``v_n`` turns from approaching (``< 0``) to separating (``> 0``)
    while ``gap_k <= (max(|v_n,k|, |v_n,k+1|) + |g| dt_k) dt_k + tol`` (the body could have reached
    the ground in between). An *episode* is a maximal run of contact intervals, from sample ``s``
    to sample ``e``; it is an *impact* when ``v_n,s < 0``. With ``a_n = n . (g + F/m)`` the
    constant normal acceleration of free flight (gravity and loads; not defined with drag or a
    spring on the body), the speeds are carried to the surface by ``v^2 - 2 a_n gap`` (constant in
    free flight): ``v_in = sqrt(v_n,s^2 - 2 a_n gap_s)``, ``v_out = sqrt(v_n,e^2 - 2 a_n gap_e)``
    (0 when the body has not separated: ``v_n,e <= 0`` or still in contact at the end of the run),
    ``e = v_out / v_in``. For a body whose lowest point keeps its height relative to the centre of
    mass in flight (a sphere, a body that does not rotate) this is exact whatever the sampling.
    Without ``a_n`` the sampled velocities are used raw; for an impact at ``t_c`` with
    ``a = t_c - t_s``, ``b = t_e - t_c`` that biases ``e`` by ``|a_n| (e a - b) / (v_c - |a_n| a)``,
    at most ``|a_n| Dt / (v_c - |a_n| Dt)`` (``Dt`` the sample interval). An impact is
    *resolvable* when ``v_in >= max(RESOLVE_SPEED, 2 |a_n| Dt / max(e_pair, 0.1))``: the expected
    rebound flies at least four sample intervals, so the next impact is a separate episode.
    ``restitution_first`` (-): ``e`` of the first resolvable impact (all listed in the note);
    ``restitution_error_max`` (-): ``max |e - e_pair|`` over resolvable impacts.
Sliding and rolling (a scene of one body and a ground)
    ``v_t = v - (n . v) n``. ``stop_time`` (s): the time ``|v_t|`` crosses ``STOP_SPEED`` for the
    last time, extrapolated from the last sample above it with the deceleration of the interval
    before (exact for constant deceleration; linear in speed when it is not decelerating; the
    start when it never exceeds it); ``stop_distance`` (m): ``|P_t (x(t_stop) - x(t_0))|``
    (``P_t`` the tangential projection, ``x`` extrapolated the same way). A body still faster
    than ``STOP_SPEED`` at the end does not stop: not measurable. ``slip_velocity_max`` (m/s,
    sphere, circle, cylinder): ``max |P_t (v + w x (p - x))|`` over contact samples, ``p`` the
    support point in ``-n``. ``rolling_acceleration`` (m/s^2): the least-squares slope of
    ``u . v_t`` against time over the longest stretch (at least 3 samples) in contact with slip
    below ``ROLL_SLIP``, ``u`` the mean tangential direction of motion over it.
Resting and structures (every contact scene)
    The settled state is the first sample at or after ``t_settle = SETTLE_FRACTION * duration``.
    ``rest_drift_max`` (m): ``max_{t >= t_settle} max_i |x_i(t) - x_i(t_settle)|``, meaningful when
    the case starts at rest (every body's velocity and angular velocity zero).
    ``time_to_rest`` (s): the first sample time from which ``|v_i| + |w_i| r_i < REST_SPEED`` for
    every body at every later sample; not measurable when the run ends moving.
    ``collapse_time`` (s), in cases that start at rest: the first ``t >= t_settle`` at which some
    ``|x_i(t) - x_i(t_settle)| > COLLAPSE_FRACTION r_i``; absent when no body ever does.
    ``collapse_time_start`` (s), likewise from the starting pose: the first ``t >= t_0`` at which
    some ``|x_i(t) - x_i(t_0)| > COLLAPSE_FRACTION r_i`` (a fall inside the settle window).

The thresholds are fixed module constants (stated in every note); a case table to set them would
need loader work and is not offered yet. Helpers the analytic references call:
:func:`ground_gap`, :func:`impacts`, :func:`stop_point`, :func:`slip_velocity`,
:func:`rolling_acceleration`, :func:`penetration`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from crosscheck.compare import convex_gap, scales
from crosscheck.rotations import quat_to_matrix
from crosscheck.scene.contact import GROUND
from crosscheck.scene.model import Scene
from crosscheck.state import Trajectory

if TYPE_CHECKING:
    from crosscheck.compare.metrics import MetricSet

# -- thresholds (module constants; stated in every note) ------------------------------------------
CONTACT_GAP_FRACTION = 1e-3  # in contact: gap <= this x the (smaller) body size
REST_SPEED = 1e-3  # m/s: a pair, or every body, at rest below this speed bound
REST_FRACTION = 0.1  # a pair counts as resting when it rests over the last 10 % of the run
STOP_SPEED = 1e-3  # m/s: tangential speed at which a sliding body has stopped
ROLL_SLIP = 1e-2  # m/s: rolling while the contact point slips slower than this
RESOLVE_SPEED = 1e-2  # m/s: smallest approach speed of a resolvable impact
SETTLE_FRACTION = 0.1  # the settle window: the first 10 % of the duration
COLLAPSE_FRACTION = 0.1  # collapse: a centre of mass moves more than this x its body size

UNITS = {
    "penetration_max": "m", "penetration_resting_mean": "m", "stop_distance": "m",
    "stop_time": "s", "slip_velocity_max": "m/s", "rolling_acceleration": "m/s^2",
    "rest_drift_max": "m", "time_to_rest": "s", "collapse_time": "s",
    "collapse_time_start": "s",
}

ROUND = ("sphere", "circle")
ROLLING = ("sphere", "circle", "cylinder")
_EXACT_SDF = ("sphere", "circle", "box", "capsule", "cylinder", "polygon")  # convex, exact sdf


# -- poses and geometry ----------------------------------------------------------------------------
def body_frames(scene: Scene, traj: Trajectory) -> tuple[np.ndarray, np.ndarray]:
    """``(R, origin)``: (T, N, d, d) body-to-world rotations and (T, N, d) world positions of the
    body-frame origins, ``origin = x_com - R com_body``."""
    if scene.dimension == 2:
        c, s = np.cos(traj.angle), np.sin(traj.angle)
        rot = np.stack([np.stack([c, -s], -1), np.stack([s, c], -1)], -2)
    else:
        rot = quat_to_matrix(traj.quat)
    com_b = np.stack([np.asarray(b.com, float) for b in scene.bodies])
    origin = traj.com - np.einsum("tnij,nj->tni", rot, com_b)
    return rot, origin


def _shape_key(shape) -> tuple:
    k = shape.kind
    if k in ROUND:
        return (k, float(shape.radius))
    if k == "box":
        return (k, tuple(float(x) for x in np.asarray(shape.size, float)))
    if k in ("capsule", "cylinder"):
        return (k, float(shape.radius), float(shape.length))
    return (k, id(shape))


def _groups(shapes) -> dict[tuple, list[int]]:
    out: dict[tuple, list[int]] = {}
    for i, s in enumerate(shapes):
        out.setdefault(_shape_key(s), []).append(i)
    return out


def _support_world(shape, rot: np.ndarray, origin: np.ndarray, direction: np.ndarray):
    """World support point of ``shape`` at poses ``(rot, origin)`` (leading axes ...) along world
    ``direction`` (same leading axes or broadcastable)."""
    local = np.einsum("...ji,...j->...i", rot, np.broadcast_to(direction, origin.shape))
    return origin + np.einsum("...ij,...j->...i", rot, shape.support(local))


def _aabb(shape, rot: np.ndarray, origin: np.ndarray):
    """Tight world AABB (lo, hi) of ``shape`` at poses (..., d, d), (..., d)."""
    hi = np.sum(rot * shape.support(rot), axis=-1)  # row k of R is R^T e_k
    lo = np.sum(rot * shape.support(-rot), axis=-1)
    return origin + lo, origin + hi


def _unit_normal(scene: Scene) -> tuple[np.ndarray, float]:
    n = np.asarray(scene.ground.normal, float)  # unit already (the loader normalises it)
    return n / np.linalg.norm(n), float(scene.ground.offset)


def ground_gap(scene: Scene, traj: Trajectory, frames=None) -> tuple[np.ndarray, np.ndarray]:
    """``(gap, point)``: (T, N) signed gap of every body to the ground plane (``-depth`` when it
    penetrates) and (T, N, d) the world support point in ``-n`` (the deepest point)."""
    rot, origin = frames if frames is not None else body_frames(scene, traj)
    n, offset = _unit_normal(scene)
    gap = np.empty(origin.shape[:2])
    point = np.empty_like(origin)
    for idx in _groups([b.shape for b in scene.bodies]).values():
        shape = scene.bodies[idx[0]].shape
        p = _support_world(shape, rot[:, idx], origin[:, idx], -n)
        point[:, idx] = p
        gap[:, idx] = p @ n - offset
    return gap, point


# -- pair gaps -------------------------------------------------------------------------------------
def _pair_method(ka: str, kb: str, dimension: int) -> str | None:
    if ka in ROUND and kb in ROUND:
        return "round-round"
    if ka in ROUND and kb in _EXACT_SDF:
        return "round-sdf"
    if kb in ROUND and ka in _EXACT_SDF:
        return "sdf-round"
    if dimension == 2 and ka in ("box", "polygon") and kb in ("box", "polygon"):
        return "sat2"
    if dimension == 3 and ka == "box" and kb == "box":
        return "sat3"
    if dimension == 3 and convex_gap.available():
        return "fcl"
    return None


def _polygon_vertices(shape) -> np.ndarray:
    if shape.kind == "box":
        hx, hy = 0.5 * np.asarray(shape.size, float)
        return np.array([[-hx, -hy], [hx, -hy], [hx, hy], [-hx, hy]])
    return np.asarray(shape.vertices, float)


def _sat2(va: np.ndarray, vb: np.ndarray) -> np.ndarray:
    """Separating-axis gap of convex CCW polygons with world vertices (M, Ka, 2), (M, Kb, 2)."""
    axes = []
    for v in (va, vb):
        e = np.roll(v, -1, axis=1) - v
        nrm = np.stack([e[..., 1], -e[..., 0]], -1)
        axes.append(nrm / np.linalg.norm(nrm, axis=-1, keepdims=True))
    ax = np.concatenate(axes, axis=1)  # (M, J, 2)
    pa = np.einsum("mkd,mjd->mkj", va, ax)
    pb = np.einsum("mkd,mjd->mkj", vb, ax)
    overlap = np.minimum(pa.max(1) - pb.min(1), pb.max(1) - pa.min(1))
    return -overlap.min(axis=1)


def _sat3_boxes(ra, oa, ha, rb, ob, hb) -> np.ndarray:
    """Separating-axis gap of 3D boxes: rotations (M, 3, 3), centres (M, 3), half sizes (3,)."""
    a_axes = np.swapaxes(ra, -1, -2)  # (M, 3, 3): row k is box A's k-th axis in the world
    b_axes = np.swapaxes(rb, -1, -2)
    cross = np.cross(a_axes[:, :, None, :], b_axes[:, None, :, :]).reshape(-1, 9, 3)
    cn = np.linalg.norm(cross, axis=-1)
    ok = cn > 1e-12  # parallel edges: the direction is a face normal already tested
    cross = np.where(ok[..., None], cross / np.where(ok, cn, 1.0)[..., None], 0.0)
    axes = np.concatenate([a_axes, b_axes, cross], axis=1)  # (M, 15, 3)
    rad_a = np.abs(np.einsum("mjd,mkd->mjk", axes, a_axes)) @ ha
    rad_b = np.abs(np.einsum("mjd,mkd->mjk", axes, b_axes)) @ hb
    dist = np.abs(np.einsum("mjd,md->mj", axes, ob - oa))
    overlap = rad_a + rad_b - dist
    overlap[:, 6:][~ok] = np.inf
    return -overlap.min(axis=1)


def pair_gap(shape_a, rot_a, origin_a, shape_b, rot_b, origin_b) -> np.ndarray:
    """(M,) signed gaps of two shapes at M pose pairs (rotations (M, d, d), origins (M, d)).
    Raises ``NotImplementedError`` naming the pair type when there is no exact method."""
    d = origin_a.shape[-1]
    method = _pair_method(shape_a.kind, shape_b.kind, d)
    if method is None:
        raise NotImplementedError(f"{shape_a.kind}-{shape_b.kind}")
    if method == "sdf-round":
        return pair_gap(shape_b, rot_b, origin_b, shape_a, rot_a, origin_a)
    if method == "round-round":
        return np.linalg.norm(origin_a - origin_b, axis=-1) - shape_a.radius - shape_b.radius
    if method == "round-sdf":
        local = np.einsum("mji,mj->mi", rot_b, origin_a - origin_b)
        return shape_b.signed_distance(local) - shape_a.radius
    if method == "fcl":
        return convex_gap.gap(shape_a, rot_a, origin_a, shape_b, rot_b, origin_b)
    if method == "sat2":
        va = origin_a[:, None] + np.einsum("mij,kj->mki", rot_a, _polygon_vertices(shape_a))
        vb = origin_b[:, None] + np.einsum("mij,kj->mki", rot_b, _polygon_vertices(shape_b))
        return _sat2(va, vb)
    return _sat3_boxes(rot_a, origin_a, 0.5 * np.asarray(shape_a.size, float),
                       rot_b, origin_b, 0.5 * np.asarray(shape_b.size, float))


@dataclass
class PairRows:
    """One row per (sample, pair) examined: body ``a``, other ``b`` (a body index, a static index,
    or -1 for the ground), ``kind`` 0 body-body, 1 body-static, 2 body-ground, and the gap."""

    t: np.ndarray  # the sample's index in the Trajectory (not its time)
    a: np.ndarray
    b: np.ndarray
    kind: np.ndarray
    gap: np.ndarray
    tol: np.ndarray  # contact tolerance of the row (m)
    speed: np.ndarray  # relative speed bound of the row (m/s)


@dataclass
class Penetration:
    rows: PairRows | None  # None when not measurable
    unsupported: tuple[str, ...]  # "kind_a-kind_b (a, b)": pair types without an exact method
    n_pairs: int = 0  # colliding pairs in the scene


def _disabled(scene: Scene) -> set[frozenset]:
    return {frozenset((e.a, e.b)) for e in scene.pair_overrides if not e.collide}


@dataclass(frozen=True)
class Colliding:
    """The pairs with ``collide = true``, worked out from the scene without listing every
    body-body pair (:func:`crosscheck.scene.contact.pairs` does, with a material each: 500 000
    of them for a 1000-body pile)."""

    ground: tuple[int, ...]  # bodies that touch the ground
    statics: tuple[tuple[int, ...], ...]  # per static, the bodies that touch it
    body_body_disabled: tuple[tuple[int, int], ...]  # (i < j) with collide = false
    n_pairs: int


def colliding(scene: Scene) -> Colliding:
    names = scene.body_names
    n = len(names)
    off = _disabled(scene)
    ground = tuple(i for i, a in enumerate(names)
                   if scene.ground is not None and frozenset((a, GROUND)) not in off)
    statics = tuple(tuple(i for i, a in enumerate(names) if frozenset((a, s.name)) not in off)
                    for s in scene.statics)
    index = {a: i for i, a in enumerate(names)}
    bb = tuple(sorted((min(index[a], index[b]), max(index[a], index[b]))
                      for a, b in (tuple(p) for p in off if len(p) == 2)
                      if a in index and b in index))
    total = n * (n - 1) // 2 - len(bb) + len(ground) + sum(len(x) for x in statics)
    return Colliding(ground, statics, bb, total)


def unsupported_pairs(scene: Scene, pairs: Colliding | None = None) -> tuple[str, ...]:
    """The colliding body-body and body-static pair types with no exact depth, each named with
    one pair of that type and how many there are."""
    pairs = pairs or colliding(scene)
    d = scene.dimension
    kinds: dict[str, list[int]] = {}
    for i, b in enumerate(scene.bodies):
        kinds.setdefault(b.shape.kind, []).append(i)
    names = scene.body_names
    off = set(pairs.body_body_disabled)
    out = []
    ordered = list(kinds)
    for x, ka in enumerate(ordered):
        for kb in ordered[x:]:
            if _pair_method(ka, kb, d) is not None:
                continue
            found = [(i, j) for i in kinds[ka] for j in kinds[kb]
                     if i < j and (i, j) not in off] if ka == kb else [
                (min(i, j), max(i, j)) for i in kinds[ka] for j in kinds[kb]
                if (min(i, j), max(i, j)) not in off]
            if found:
                i, j = found[0]
                more = f", {len(found)} pairs" if len(found) > 1 else ""
                out.append(f"{scene.bodies[i].shape.kind}-{scene.bodies[j].shape.kind} "
                           f"({names[i]}, {names[j]}{more})")
    for static, bodies in zip(scene.statics, pairs.statics, strict=True):
        by_kind: dict[str, list[int]] = {}
        for i in bodies:
            by_kind.setdefault(scene.bodies[i].shape.kind, []).append(i)
        for ka, idx in by_kind.items():
            if _pair_method(ka, static.shape.kind, d) is None:
                more = f", {len(idx)} pairs" if len(idx) > 1 else ""
                out.append(f"{ka}-{static.shape.kind} ({names[idx[0]]}, {static.name}{more})")
    return tuple(out)


def _omega_norm(scene: Scene, traj: Trajectory) -> np.ndarray:
    return np.abs(traj.omega) if scene.dimension == 2 else np.linalg.norm(traj.omega, axis=-1)


def _sweep(lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Pairs (a < b) of boxes (N, d) that overlap: sort-and-sweep on the first axis, then the
    full overlap test on the candidates. NumPy only."""
    n = len(lo)
    order = np.argsort(lo[:, 0], kind="stable")
    los = lo[order, 0]
    end = np.searchsorted(los, hi[order, 0], side="right")
    counts = np.maximum(end - np.arange(n) - 1, 0)
    total = int(counts.sum())
    if total == 0:
        return np.empty(0, int), np.empty(0, int)
    ii = np.repeat(np.arange(n), counts)
    first = np.repeat(np.cumsum(counts) - counts, counts)
    jj = ii + 1 + (np.arange(total) - first)
    a, b = order[ii], order[jj]
    keep = np.all((lo[a] <= hi[b]) & (lo[b] <= hi[a]), axis=-1)
    a, b = a[keep], b[keep]
    return np.minimum(a, b), np.maximum(a, b)


def penetration(scene: Scene, traj: Trajectory, frames=None) -> Penetration:
    """Every colliding pair's gap at every sample where it may be within the contact tolerance
    (body-ground at every sample; body-static and body-body pruned by bounding boxes)."""
    pairs = colliding(scene)
    unsupported = unsupported_pairs(scene, pairs)
    if unsupported:
        return Penetration(None, unsupported, pairs.n_pairs)
    n_pairs = pairs.n_pairs
    rot, origin = frames if frames is not None else body_frames(scene, traj)
    n_t, n_b = origin.shape[:2]
    radii = scales.body_radii(scene)
    tol_b = CONTACT_GAP_FRACTION * radii
    rim = _omega_norm(scene, traj) * radii  # (T, N)
    vel = traj.vel
    speed_fixed = np.linalg.norm(vel, axis=-1) + rim
    parts = []

    def add(t, a, b, kind, gap, tol, speed):
        parts.append((t, a, b, np.full(len(t), kind), gap, tol, speed))

    # ground
    ground_bodies = np.array(pairs.ground, int)
    if len(ground_bodies):
        gap, _ = ground_gap(scene, traj, (rot, origin))
        tt, aa = np.meshgrid(np.arange(n_t), ground_bodies, indexing="ij")
        tt, aa = tt.ravel(), aa.ravel()
        add(tt, aa, np.full(len(tt), -1), 2, gap[tt, aa], tol_b[aa], speed_fixed[tt, aa])

    # world boxes, inflated by the contact tolerance
    lo = np.empty_like(origin)
    hi = np.empty_like(origin)
    for idx in _groups([b.shape for b in scene.bodies]).values():
        lo[:, idx], hi[:, idx] = _aabb(scene.bodies[idx[0]].shape, rot[:, idx], origin[:, idx])
    lo -= tol_b[None, :, None]
    hi += tol_b[None, :, None]

    # statics
    for k, static in enumerate(scene.statics):
        bodies = np.array(pairs.statics[k], int)
        if not len(bodies):
            continue
        placed = static.placed()
        slo, shi = placed.bounding_box()
        near = np.all((lo[:, bodies] <= shi) & (slo <= hi[:, bodies]), axis=-1)  # (T, n)
        tt, jj = np.nonzero(near)
        aa = bodies[jj]
        srot = placed.rotation()
        if srot is None:
            srot = np.eye(scene.dimension)
        gap = np.empty(len(tt))
        for idx in _groups([scene.bodies[i].shape for i in aa]).values():
            sel = np.asarray(idx)
            m = len(sel)
            gap[sel] = pair_gap(scene.bodies[aa[sel[0]]].shape, rot[tt[sel], aa[sel]],
                                origin[tt[sel], aa[sel]], static.shape,
                                np.broadcast_to(srot, (m,) + srot.shape),
                                np.broadcast_to(np.asarray(static.position, float),
                                                (m, scene.dimension)))
        add(tt, aa, np.full(len(tt), k), 1, gap, tol_b[aa], speed_fixed[tt, aa])

    # body-body: a sort-and-sweep per sample, then every candidate at once
    if n_b > 1 and n_b * (n_b - 1) // 2 > len(pairs.body_body_disabled):
        disabled = np.array([a * n_b + b for a, b in pairs.body_body_disabled], np.int64)
        ts, as_, bs = [], [], []
        for t in range(n_t):
            a, b = _sweep(lo[t], hi[t])
            if len(a):
                ts.append(np.full(len(a), t))
                as_.append(a)
                bs.append(b)
        if ts:
            tt, aa, bb_ = np.concatenate(ts), np.concatenate(as_), np.concatenate(bs)
            keep = ~np.isin(aa.astype(np.int64) * n_b + bb_, disabled)
            tt, aa, bb_ = tt[keep], aa[keep], bb_[keep]
            gap = np.empty(len(tt))
            keys = [_shape_key(b.shape) for b in scene.bodies]
            code = {k: c for c, k in enumerate(dict.fromkeys(keys))}
            body_code = np.array([code[k] for k in keys])
            pair_code = body_code[aa] * len(code) + body_code[bb_]
            for pc in np.unique(pair_code):
                sel = np.nonzero(pair_code == pc)[0]
                i, j = aa[sel[0]], bb_[sel[0]]
                gap[sel] = pair_gap(scene.bodies[i].shape, rot[tt[sel], aa[sel]],
                                    origin[tt[sel], aa[sel]], scene.bodies[j].shape,
                                    rot[tt[sel], bb_[sel]], origin[tt[sel], bb_[sel]])
            speed = (np.linalg.norm(vel[tt, aa] - vel[tt, bb_], axis=-1) + rim[tt, aa]
                     + rim[tt, bb_])
            add(tt, aa, bb_, 0, gap, np.minimum(tol_b[aa], tol_b[bb_]), speed)

    if not parts:
        empty = np.empty(0)
        return Penetration(PairRows(empty.astype(int), empty.astype(int), empty.astype(int),
                                    empty.astype(int), empty, empty, empty), (), n_pairs)
    cols = [np.concatenate([p[k] for p in parts]) for k in range(7)]
    return Penetration(PairRows(*cols), (), n_pairs)


def _resting_mean(rows: PairRows, t: np.ndarray) -> tuple[float | None, int, int]:
    """Mean depth over each pair's final resting stretch (module docstring); returns
    ``(mean, pairs, samples)``."""
    n_t = len(t)
    resting = (rows.gap <= rows.tol) & (rows.speed < REST_SPEED)
    if not resting.any():
        return None, 0, 0
    _, key = np.unique(np.stack([rows.kind[resting], rows.a[resting], rows.b[resting]], 1),
                       axis=0, return_inverse=True)
    key = key.ravel()
    ts = rows.t[resting]
    depth = np.maximum(0.0, -rows.gap[resting])
    order = np.lexsort((-ts, key))
    key, ts, depth = key[order], ts[order], depth[order]
    start = np.r_[True, key[1:] != key[:-1]]
    group_start = np.maximum.accumulate(np.where(start, np.arange(len(key)), 0))
    rank = np.arange(len(key)) - group_start
    ok = ts == n_t - 1 - rank  # consecutive from the last sample backwards
    bad_before = np.cumsum(~ok) - np.cumsum(~ok)[group_start] + (~ok)[group_start]
    in_stretch = ok & (bad_before == 0)
    # the stretch must cover the last REST_FRACTION of the run
    cut = t[-1] - REST_FRACTION * (t[-1] - t[0])
    first_needed = int(np.searchsorted(t, cut, side="left"))
    stretch_len = np.bincount(np.cumsum(start) - 1, weights=in_stretch)
    needed = n_t - first_needed
    good_group = stretch_len >= needed
    use = in_stretch & good_group[np.cumsum(start) - 1]
    if not use.any():
        return None, 0, 0
    return float(depth[use].mean()), int(good_group.sum()), int(use.sum())


# -- impacts ---------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Impact:
    """One body-ground contact episode that began approaching (module docstring)."""

    t_before: float  # s, the sample before the episode (s)
    t_after: float  # s, the sample after it (e)
    v_in: float  # m/s, approach speed carried to the surface
    v_out: float  # m/s, separation speed carried to the surface (0: did not separate)
    e: float  # v_out / v_in
    resolvable: bool
    separated: bool


def normal_acceleration(scene: Scene, body: int) -> float | None:
    """``n . (g + F/m)``: the constant normal acceleration of free flight, or None when a drag, a
    medium or a spring acts on the body (free flight is then not uniformly accelerated)."""
    fx = scene.effects
    if fx.medium is not None or any(body in d.bodies for d in fx.drag) or any(
            body in (s.body_a, s.body_b) for s in fx.springs):
        return None
    n, _ = _unit_normal(scene)
    acc = fx.gravity_vector(scene.dimension).astype(float).copy()
    for load in fx.loads:
        if load.body == body:
            acc = acc + np.asarray(load.force, float) / scene.bodies[body].mass
    return float(acc @ n)


def _carried(v: float, gap: float, a_n: float | None) -> float:
    """The normal speed at the surface (gap 0) of a body at normal speed ``v`` and ``gap`` in free
    flight with normal acceleration ``a_n`` (``v^2 - 2 a_n gap`` is constant); ``|v|`` without."""
    if a_n is None:
        return abs(float(v))
    return float(np.sqrt(max(0.0, v * v - 2.0 * a_n * gap)))


def impacts(scene: Scene, traj: Trajectory, body: int = 0, gap: np.ndarray | None = None
            ) -> list[Impact]:
    """The body-ground impacts of ``body``, in time order (module docstring, "Impacts")."""
    if gap is None:
        gap = ground_gap(scene, traj)[0][:, body]
    n, _ = _unit_normal(scene)
    t = traj.t
    if len(t) < 2:
        return []
    vn = traj.vel[:, body] @ n
    tol = CONTACT_GAP_FRACTION * scales.body_radius(scene.bodies[body])
    a_n = normal_acceleration(scene, body)
    g_abs = float(np.linalg.norm(scene.effects.gravity_vector(scene.dimension)))
    dt = np.diff(t)
    contact = gap <= tol
    reach = (np.maximum(np.abs(vn[:-1]), np.abs(vn[1:])) + g_abs * dt) * dt + tol
    turn = (vn[:-1] < 0) & (vn[1:] > 0) & (gap[:-1] <= reach)
    interval = contact[:-1] | contact[1:] | turn
    e_pair = scene.pair_material(scene.bodies[body].name, GROUND).restitution
    acc = abs(a_n) if a_n is not None else g_abs
    out = []
    k = 0
    n_i = len(interval)
    while k < n_i:
        if not interval[k]:
            k += 1
            continue
        s = k
        while k < n_i and interval[k]:
            k += 1
        e = k  # the episode spans samples s..e
        if vn[s] >= 0 or (s == 0 and contact[0]):
            continue
        v_in = _carried(vn[s], gap[s], a_n)
        separated = vn[e] > 0 and not contact[e]
        v_out = _carried(vn[e], gap[e], a_n) if separated else 0.0
        sample = float(np.max(dt[max(s - 1, 0):e + 1]))
        threshold = max(RESOLVE_SPEED, 2.0 * acc * sample / max(e_pair, 0.1))
        out.append(Impact(float(t[s]), float(t[e]), v_in, v_out,
                          v_out / v_in if v_in > 0 else float("nan"),
                          bool(v_in >= threshold), bool(separated)))
    return out


# -- sliding and rolling ---------------------------------------------------------------------------
@dataclass(frozen=True)
class StopPoint:
    time: float  # s
    distance: float  # m, tangential displacement of the centre of mass from the first sample
    position: np.ndarray  # world centre of mass at that time


def _tangential(scene: Scene, v: np.ndarray) -> np.ndarray:
    n, _ = _unit_normal(scene)
    return v - (v @ n)[..., None] * n


def stop_point(scene: Scene, traj: Trajectory, body: int = 0) -> StopPoint | None:
    """Where and when ``body``'s tangential speed falls below STOP_SPEED for good; None when it
    is still faster at the last sample (module docstring, "Sliding and rolling")."""
    vt = _tangential(scene, traj.vel[:, body])
    speed = np.linalg.norm(vt, axis=-1)
    x = traj.com[:, body]
    above = np.nonzero(speed >= STOP_SPEED)[0]
    if len(above) and above[-1] == len(speed) - 1:
        return None
    if not len(above):
        return StopPoint(float(traj.t[0]), 0.0, x[0].copy())
    k = int(above[-1])
    v = traj.vel[:, body]
    h = traj.t[k + 1] - traj.t[k]
    tau = None
    if k > 0:  # the deceleration of the preceding interval, carried on: exact when constant
        acc = (v[k] - v[k - 1]) / (traj.t[k] - traj.t[k - 1])
        decel = (speed[k - 1] - speed[k]) / (traj.t[k] - traj.t[k - 1])
        if decel > 0:
            tau = min((speed[k] - STOP_SPEED) / decel, h)
            pos = x[k] + v[k] * tau + 0.5 * acc * tau**2
    if tau is None:  # linear in speed, cubic Hermite in position
        s = float(np.clip((speed[k] - STOP_SPEED) / (speed[k] - speed[k + 1]), 0.0, 1.0))
        h00, h10 = 2 * s**3 - 3 * s**2 + 1, s**3 - 2 * s**2 + s
        h01, h11 = -2 * s**3 + 3 * s**2, s**3 - s**2
        pos = h00 * x[k] + h10 * h * v[k] + h01 * x[k + 1] + h11 * h * v[k + 1]
        tau = s * h
    dist = float(np.linalg.norm(_tangential(scene, pos - x[0])))
    return StopPoint(float(traj.t[k] + tau), dist, pos)


def _cross_w(scene: Scene, w: np.ndarray, r: np.ndarray) -> np.ndarray:
    if scene.dimension == 2:
        return w[..., None] * np.stack([-r[..., 1], r[..., 0]], -1)
    return np.cross(w, r)


def slip_velocity(scene: Scene, traj: Trajectory, body: int = 0) -> np.ndarray:
    """(T,) tangential speed of the contact point ``|P_t (v + w x (p - x))|``, ``p`` the support
    point in ``-n``; NaN at samples not in contact."""
    gap, point = ground_gap(scene, traj)
    gap, point = gap[:, body], point[:, body]
    r = point - traj.com[:, body]
    vp = traj.vel[:, body] + _cross_w(scene, traj.omega[:, body], r)
    slip = np.linalg.norm(_tangential(scene, vp), axis=-1)
    tol = CONTACT_GAP_FRACTION * scales.body_radius(scene.bodies[body])
    return np.where(gap <= tol, slip, np.nan)


def rolling_acceleration(scene: Scene, traj: Trajectory, body: int = 0,
                         slip: np.ndarray | None = None) -> float | None:
    """Least-squares tangential acceleration over the longest rolling stretch (in contact, slip
    below ROLL_SLIP, at least 3 samples); None when there is none."""
    if slip is None:
        slip = slip_velocity(scene, traj, body)
    rolling = np.isfinite(slip) & (slip < ROLL_SLIP)
    best, start = (0, 0), None
    for k, r in enumerate(np.r_[rolling, False]):
        if r and start is None:
            start = k
        elif not r and start is not None:
            if k - start > best[1] - best[0]:
                best = (start, k)
            start = None
    a, b = best
    if b - a < 3:
        return None
    vt = _tangential(scene, traj.vel[a:b, body])
    mean = vt.mean(axis=0)
    if np.linalg.norm(mean) == 0:
        return 0.0
    u = mean / np.linalg.norm(mean)
    slope = np.polyfit(traj.t[a:b], vt @ u, 1)[0]
    return float(slope)


# -- the metrics -----------------------------------------------------------------------------------
def _starts_at_rest(scene: Scene) -> bool:
    return all(not np.any(np.asarray(b.velocity)) and not np.any(np.asarray(b.angular_velocity))
               for b in scene.bodies)


def energy_gain(scene: Scene, traj: Trajectory, out: MetricSet, energy: np.ndarray,
                basis: Trajectory, ref: Trajectory | None):
    from crosscheck.quantities import internal_energy

    if scales.internal_energy_decouples(scene):
        e = internal_energy(scene, traj)
        scale, source = scales.energy_scale(scene, basis, ref, internal=True)
        what = "internal energy"
    else:
        e = energy
        scale, source = scales.energy_scale(scene, basis, ref)
        what = "total energy"
    if scale <= 0:
        out.add("energy_gain", None, meaningful=False, note="no energy scale: nothing moves")
        return
    gain = float(np.max(np.maximum(0.0, e - e[0]))) / scale
    note = (f"{what}, max gain over E(0); scale S_E = {scale:.6g} J (as energy_drift, {source}); "
            "contact may lose energy, never gain it")
    torque = scene.dimension == 3 and any(np.any(np.asarray(ld.torque) != 0)
                                          for ld in scene.effects.loads)
    if torque:
        out.add("energy_gain", gain, meaningful=False,
                note="not meaningful: a constant torque on a 3D body does work with no potential; "
                     + note)
    else:
        out.add("energy_gain", gain, note=note)


def _penetration_metrics(scene: Scene, traj: Trajectory, out: MetricSet, pen: Penetration):
    if pen.rows is None:
        why = ("not measurable: no exact penetration depth for the pair type(s) "
               + ", ".join(pen.unsupported))
        out.add("penetration_max", None, meaningful=False, note=why)
        out.add("penetration_resting_mean", None, meaningful=False, note=why)
        return
    rows = pen.rows
    if not pen.n_pairs:
        out.add("penetration_max", None, meaningful=False, note="no pair can touch")
        out.add("penetration_resting_mean", None, meaningful=False, note="no pair can touch")
        return
    depth = np.maximum(0.0, -rows.gap)
    out.add("penetration_max", float(depth.max()) if len(depth) else 0.0,
            note="crosscheck's own distance computation, over every sample and colliding pair")
    # The deepest pair at every sample, for the report's penetration plot.
    per_sample = np.zeros(len(traj.t))
    if len(depth):
        np.maximum.at(per_sample, rows.t.astype(np.int64), depth)  # rows.t: sample index
    out.add_series("penetration", traj.t, per_sample)
    mean, n_pairs, n_samples = _resting_mean(rows, traj.t)
    rule = (f"in contact: gap <= {CONTACT_GAP_FRACTION:g} x body size; resting: relative speed "
            f"bound < {REST_SPEED:g} m/s over the last {REST_FRACTION:.0%} of the run")
    if mean is None:
        out.add("penetration_resting_mean", None, meaningful=False,
                note=f"not measurable: no pair rests ({rule})")
    else:
        out.add("penetration_resting_mean", mean,
                note=f"{n_pairs} resting pair(s), {n_samples} samples; {rule}")


def _impact_metrics(scene: Scene, traj: Trajectory, out: MetricSet, gap: np.ndarray):
    if scene.ground is None:
        return
    found = []
    for i in colliding(scene).ground:
        name = scene.bodies[i].name
        e_pair = scene.pair_material(name, GROUND).restitution
        found.extend((name, e_pair, imp) for imp in impacts(scene, traj, i, gap[:, i]))
    if not found:
        return
    listed = "; ".join(
        f"{name} {imp.t_before:.4g}-{imp.t_after:.4g} s v_in {imp.v_in:.4g} m/s e {imp.e:.4g}"
        + ("" if imp.resolvable else " (unresolved)") for name, _, imp in found[:12])
    if len(found) > 12:
        listed += f"; and {len(found) - 12} more"
    good = [(e_pair, imp) for _, e_pair, imp in found if imp.resolvable]
    if not good:
        why = f"not measurable: no resolvable body-ground impact ({listed})"
        out.add("restitution_first", None, meaningful=False, note=why)
        out.add("restitution_error_max", None, meaningful=False, note=why)
        return
    out.add("restitution_first", good[0][1].e, note=f"impacts: {listed}")
    out.add("restitution_error_max", max(abs(imp.e - e_pair) for e_pair, imp in good),
            note=f"max |e - e_pair| over {len(good)} resolvable impact(s); {listed}")


def _sliding_metrics(scene: Scene, traj: Trajectory, out: MetricSet):
    if scene.ground is None or len(scene.bodies) != 1:
        return
    pair = scene.pair_material(scene.bodies[0].name, GROUND)
    if not pair.collide:
        return
    stop = stop_point(scene, traj, 0)
    if stop is None:
        why = f"not measurable: the tangential speed is still >= {STOP_SPEED:g} m/s at the end"
        out.add("stop_distance", None, meaningful=False, note=why)
        out.add("stop_time", None, meaningful=False, note=why)
    else:
        note = f"tangential speed below {STOP_SPEED:g} m/s for good"
        out.add("stop_distance", stop.distance, note=note)
        out.add("stop_time", stop.time, note=note)
    if scene.bodies[0].shape.kind not in ROLLING:
        return
    slip = slip_velocity(scene, traj, 0)
    if not np.isfinite(slip).any():
        out.add("slip_velocity_max", None, meaningful=False,
                note="not measurable: never in contact with the ground")
        return
    out.add("slip_velocity_max", float(np.nanmax(slip)),
            note="contact point |v + w x r| tangential, over samples in contact")
    acc = rolling_acceleration(scene, traj, 0, slip)
    if acc is None:
        out.add("rolling_acceleration", None, meaningful=False,
                note=f"not measurable: no 3 consecutive samples rolling (slip < {ROLL_SLIP:g} m/s)")
    else:
        out.add("rolling_acceleration", acc,
                note=f"least-squares slope over the longest rolling stretch "
                     f"(slip < {ROLL_SLIP:g} m/s)")


def _rest_metrics(scene: Scene, traj: Trajectory, out: MetricSet):
    t = traj.t
    radii = scales.body_radii(scene)
    k = int(np.searchsorted(t, SETTLE_FRACTION * scene.run.duration - 1e-12, side="left"))
    at_rest_start = _starts_at_rest(scene)
    if k < len(t):
        disp = np.linalg.norm(traj.com[k:] - traj.com[k], axis=-1)  # (T', N)
        settle = f"settled state at t = {t[k]:.6g} s (first {SETTLE_FRACTION:.0%} of the run)"
        if at_rest_start:
            out.add("rest_drift_max", float(disp.max()), note=settle)
        else:
            out.add("rest_drift_max", float(disp.max()), meaningful=False,
                    note="not meaningful: the case does not start at rest; " + settle)
        if at_rest_start:
            over = np.nonzero(np.any(disp > COLLAPSE_FRACTION * radii, axis=1))[0]
            if len(over):
                out.add("collapse_time", float(t[k + over[0]]),
                        note=f"a centre of mass left a ball of {COLLAPSE_FRACTION:g} x its body "
                             f"size around its position at t = {t[k]:.6g} s")
    if at_rest_start and len(t):
        # From the starting pose too: a structure that falls apart inside the settle window (or
        # in the first step of a large one) and lies still afterwards leaves collapse_time
        # unset, yet it did not stand (the stability frontier of crosscheck sweep needs this).
        start = np.linalg.norm(traj.com - traj.com[0], axis=-1)  # (T, N)
        over = np.nonzero(np.any(start > COLLAPSE_FRACTION * radii, axis=1))[0]
        if len(over):
            out.add("collapse_time_start", float(t[over[0]]),
                    note=f"a centre of mass left a ball of {COLLAPSE_FRACTION:g} x its body size "
                         f"around its starting position (t = {t[0]:.6g} s)")
    speed = np.linalg.norm(traj.vel, axis=-1) + _omega_norm(scene, traj) * radii
    moving = np.nonzero(np.any(speed >= REST_SPEED, axis=1))[0]
    if len(moving) and moving[-1] == len(t) - 1:
        out.add("time_to_rest", None, meaningful=False,
                note=f"not measurable: some body moves faster than {REST_SPEED:g} m/s "
                     "(|v| + |w| r) at the end")
    else:
        first = 0 if not len(moving) else int(moving[-1]) + 1
        out.add("time_to_rest", float(t[first]),
                note=f"every body's |v| + |w| r below {REST_SPEED:g} m/s from then on "
                     "(sample resolution)")


def contact_metrics(scene: Scene, traj: Trajectory, out: MetricSet, energy: np.ndarray,
                    basis: Trajectory, ref: Trajectory | None = None):
    """Add every contact metric of a scene with ``effects.contact`` to ``out``."""
    if not len(traj.t):
        return
    frames = body_frames(scene, traj)
    pen = penetration(scene, traj, frames)
    _penetration_metrics(scene, traj, out, pen)
    energy_gain(scene, traj, out, energy, basis, ref)
    if scene.ground is not None:
        gap, _ = ground_gap(scene, traj, frames)
        _impact_metrics(scene, traj, out, gap)
        _sliding_metrics(scene, traj, out)
    _rest_metrics(scene, traj, out)
