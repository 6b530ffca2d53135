"""The contact rows of the velocity-level models (sequential_impulse, soft_step): one
implementation of the projected Gauss-Seidel machinery both models share, for 2D and 3D.

Every row works in three dimensions. A 2D scene is embedded exactly: positions, normals and
linear velocities get a zero z, the angular velocity is (0, 0, w) and the inverse inertia is
zero but for its zz entry 1/I, so every cross product and effective mass reduces to the planar
one (products with exact zeros stay exact zeros: no round-off enters from the embedding). Only
the tangent rows differ: one in 2D (t1 in the plane), two in 3D; rolling resistance acts about z
in 2D and about the two tangents in 3D; torsional friction exists in 3D only.

A contact row c (one point of one manifold, sim/collide/contacts.py) between body a and body or
fixed collider b (b = -1) with normal n from a to b, anchors ra = p - x_a and rb = p - x_b (fixed
over the step, world-oriented at detection, Box2D v3's "fixed anchors"), holds:

* normal row: lambda_n >= 0, driving the relative normal velocity vn = (v_b + w_b x rb - v_a -
  w_a x ra) . n towards -bias; the increment is Box2D v3's soft form
  ``d = -m_n (mass_scale vn + bias) - impulse_scale lambda_n`` (mass_scale 1 and impulse_scale 0
  for a hard row), clamped so that the accumulated lambda_n stays >= 0;
* friction: the tangential impulse (a 2-vector in 3D, updated along -v_t with one isotropic
  mass, ``isotropic_mass``) projected onto the Coulomb *disc* |lambda_t| <= mu lambda_n (an
  isotropic cone, not a pyramid: CONTACTS.md trap C3), lambda_n of the current iteration;
* rolling resistance (when the pair's ``rolling_friction`` > 0, in m): an angular impulse about
  the tangent-plane axes (2D: about z) on the relative angular velocity, clamped to the disc
  rolling_friction * lambda_n; torsional friction (3D, ``torsional_friction`` > 0, in m): an
  angular impulse about n clamped to torsional_friction * lambda_n. Both are per row, so a manifold
  of k points resists with the coefficient times its total normal impulse, as one row per
  manifold would at convergence.

Impulses are applied to the body velocities (v, w) equal and opposite: +P on b at rb, -P on a at
ra (an angular impulse M: +M on b, -M on a), so linear and angular momentum are conserved by the
solver to round-off.

Warm starting: each step's accumulated impulses are kept with the rows' feature keys, sorted
(``store_rows``); the next step's rows take the impulses of the previous row with the same key
(binary search, ``match_rows``). The accumulators of a row are (normal, tangent 1, tangent 2,
rolling 1, rolling 2, torsion); the first three are also written to ``contacts.impulse``.

Every pass is a plain sequential loop over the rows in buffer order: no parallel reduction, so
results are bit-identical from run to run. Nothing here allocates but store_rows' sort order.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit

from crosscheck.sim.rigid._jit import INLINE, JIT

N_ACC = 6  # accumulated impulses per row: normal, tangent 1, tangent 2, rolling 1, 2, torsion
SEQUENTIAL_IMPULSE = 0
SOFT_STEP = 1
ROTATION_SPLITTING = 0  # symplectic_euler: exact principal-axis sub-rotations with L
ROTATION_EXP = 1  # symplectic_euler_exp: q <- exp(h w) q
MATCH_DISTANCE = 2e-3  # m: warm start by nearest anchor when a feature key is not found


class Settings(NamedTuple):
    """What the compiled step reads of a velocity-level model's parameters (all numbers)."""

    model: int  # SEQUENTIAL_IMPULSE | SOFT_STEP
    rotation: int  # ROTATION_SPLITTING | ROTATION_EXP
    warm_starting: int  # 1: start each step from the previous step's impulses
    substeps: int  # soft_step: sub-steps per step (sequential_impulse: 1)
    iterations: int  # PGS sweeps: per step (sequential_impulse), per sub-step (soft_step)
    relax_iterations: int  # soft_step: sweeps without bias after each sub-step's drift
    position_iterations: int  # sequential_impulse: split-impulse sweeps
    tolerance: float  # sequential_impulse: stop the sweeps when no row changes its velocity more
    restitution_threshold: float  # m/s: no restitution below this approach speed
    baumgarte: float  # sequential_impulse: fraction of the penetration beyond the slop removed
    slop: float  # m: penetration left uncorrected (sequential_impulse)
    contact_hertz: float  # soft_step: contact stiffness as a frequency (static contacts: twice)
    damping_ratio: float  # soft_step
    push_speed: float  # soft_step: m/s, the largest speed of the push out of penetration


class ContactRows(NamedTuple):
    """The solver's per-row scratch, allocated once per run with the contact buffer's capacity."""

    n: np.ndarray  # (C, 3) normal from a to b (z = 0 in 2D)
    t1: np.ndarray  # (C, 3) tangents; t2 = n x t1 (unused in 2D)
    t2: np.ndarray
    ra: np.ndarray  # (C, 3) anchor on a: the contact point minus a's centre of mass, now
    rb: np.ndarray  # (C, 3) anchor on b, now (zero when b is fixed)
    ra0: np.ndarray  # (C, 3) the anchors at detection
    rb0: np.ndarray
    separation: np.ndarray  # (C,) -depth at detection (> 0: a speculative gap)
    gap: np.ndarray  # (C,) the separation now (soft_step's sub-steps move the bodies)
    normal_mass: np.ndarray  # (C,) 1 / (n . K n)
    tangent_inv: np.ndarray  # (C, 3) [0]: the tangent rows' mass (3D: isotropic_mass of the block)
    rolling_inv: np.ndarray  # (C, 3) [0]: the same for the rolling rows
    twist_mass: np.ndarray  # (C,) 1 / (n . (Ia^-1 + Ib^-1) n)
    relative_velocity: np.ndarray  # (C,) vn when the rows were prepared (restitution)
    bias: np.ndarray  # (C,) sequential_impulse: the normal row's velocity bias
    total_normal: np.ndarray  # (C,) normal impulse applied this step (soft_step restitution)
    impulse: np.ndarray  # (C, 6) accumulated impulses
    pseudo: np.ndarray  # (C, 1) split-impulse accumulators (sequential_impulse)
    prev_feature: np.ndarray  # (C,) int64: last step's keys, sorted
    prev_impulse: np.ndarray  # (C, 9): last step's impulses and anchors ra, in prev_feature's order
    prev_count: np.ndarray  # (1,) int64
    stats: np.ndarray  # (3,) int64: steps with contacts, velocity sweeps, largest sweeps in a step


def make_rows(capacity: int) -> ContactRows:
    c = int(capacity)
    z3 = lambda: np.zeros((c, 3))  # noqa: E731
    z1 = lambda: np.zeros(c)  # noqa: E731
    return ContactRows(n=z3(), t1=z3(), t2=z3(), ra=z3(), rb=z3(), ra0=z3(), rb0=z3(),
                       separation=z1(), gap=z1(),
                       normal_mass=z1(), tangent_inv=z3(), rolling_inv=z3(), twist_mass=z1(),
                       relative_velocity=z1(), bias=z1(), total_normal=z1(),
                       impulse=np.zeros((c, N_ACC)), pseudo=np.zeros((c, 1)),
                       prev_feature=np.zeros(c, np.int64), prev_impulse=np.zeros((c, N_ACC + 3)),
                       prev_count=np.zeros(1, np.int64), stats=np.zeros(3, np.int64))


# -- small vector helpers: scalars and tuples only -------------------------------------------------
# The row loops load what a row needs into scalars (Box2D's way), compute with helpers that take
# scalars and tuples only, and store the bodies' velocities back once per row. An inlined helper
# given the NamedTuples (or arrays, and branching) makes numba increment and decrement the
# reference count of every array it was given, on every row: measured 2.2 us per row and sweep
# on the 800 rows of the 2D pyramid.
ZERO3 = (0.0, 0.0, 0.0)
ZERO9 = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
EYE9 = (1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0)


@njit(**INLINE)
def add(a, b):
    return a[0] + b[0], a[1] + b[1], a[2] + b[2]


@njit(**INLINE)
def sub(a, b):
    return a[0] - b[0], a[1] - b[1], a[2] - b[2]


@njit(**INLINE)
def scale(s, a):
    return s * a[0], s * a[1], s * a[2]


@njit(**INLINE)
def dot(a, b):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


@njit(**INLINE)
def cross(a, b):
    return a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]


@njit(**INLINE)
def mv(m, x):
    """A 3 x 3 matrix (row-major 9-tuple) times x."""
    return (m[0] * x[0] + m[1] * x[1] + m[2] * x[2], m[3] * x[0] + m[4] * x[1] + m[5] * x[2],
            m[6] * x[0] + m[7] * x[1] + m[8] * x[2])


@njit(**INLINE)
def load3(arr, i):
    return arr[i, 0], arr[i, 1], arr[i, 2]


@njit(**INLINE)
def store3(arr, i, t):
    arr[i, 0] = t[0]
    arr[i, 1] = t[1]
    arr[i, 2] = t[2]


@njit(**INLINE)
def load9(arr, i):
    return (arr[i, 0, 0], arr[i, 0, 1], arr[i, 0, 2], arr[i, 1, 0], arr[i, 1, 1], arr[i, 1, 2],
            arr[i, 2, 0], arr[i, 2, 1], arr[i, 2, 2])


@njit(**INLINE)
def load6(arr, i):
    return arr[i, 0], arr[i, 1], arr[i, 2], arr[i, 3], arr[i, 4], arr[i, 5]


@njit(**INLINE)
def relative_velocity(va, wa, vb, wb, ra, rb):
    """Velocity of b's material point at the contact minus a's."""
    return sub(add(vb, cross(wb, rb)), add(va, cross(wa, ra)))


@njit(**INLINE)
def push(p, ra, rb, va, wa, vb, wb, ma, ia, mb, ib):
    """+P on b at rb, -P on a at ra: velocities change by P / m and I^-1 (r x P). For fixed
    geometry mb and ib are zero, so b's velocities stay zero (and are never stored)."""
    return (sub(va, scale(ma, p)), sub(wa, mv(ia, cross(ra, p))), add(vb, scale(mb, p)),
            add(wb, mv(ib, cross(rb, p))))


@njit(**INLINE)
def twist(m, wa, wb, ia, ib):
    """An angular impulse +M on b, -M on a."""
    return sub(wa, mv(ia, m)), add(wb, mv(ib, m))


@njit(**INLINE)
def linear_mass(u, s, ra, rb, ma, ia, mb, ib):
    """u . K s, K the inverse effective-mass matrix of linear rows at anchors ra, rb."""
    return ((ma + mb) * dot(u, s) + dot(cross(ra, u), mv(ia, cross(ra, s)))
            + dot(cross(rb, u), mv(ib, cross(rb, s))))


@njit(**INLINE)
def angular_mass(u, s, ia, ib):
    """u . (Ia^-1 + Ib^-1) s: the same for angular rows."""
    return dot(u, mv(ia, s)) + dot(u, mv(ib, s))


@njit(**INLINE)
def load_body(v, w, inv_mass, inv_inertia, i):
    """Body i's velocities, inverse mass and inverse world inertia. Branch-free: numba prunes the
    reference counts of the arrays a helper is given only within a basic block, so helpers that
    take arrays never branch; the row loops branch on b themselves."""
    return load3(v, i), load3(w, i), inv_mass[i], load9(inv_inertia, i)


@njit(**INLINE)
def store_body(v, w, i, vi, wi):
    store3(v, i, vi)
    store3(w, i, wi)


@njit(**INLINE)
def isotropic_mass(k11, k12, k22):
    """1 / lambda_max of the symmetric 2 x 2 block [[k11, k12], [k12, k22]] (0 if it is zero).

    The tangential rows of a contact are updated with this one scalar mass, not with the block's
    inverse: then every update is a step along -v_t, and projecting the accumulated impulse
    radially onto the Coulomb disc is the exact proximal step of an isotropic metric, so a
    sliding contact's friction opposes its slip. With the block's inverse the update is along
    K^-1 v_t, which the radial projection turns sideways wherever K is anisotropic (the corners
    of a box): measured, a box launched along x drifted 12 mm sideways, yawed 2 degrees and
    decelerated 6 % below mu g. The step 1 / lambda_max is the largest that keeps the projected
    Gauss-Seidel update a contraction; a sticking contact converges over the sweeps (and the
    warm start) instead of in one."""
    half = 0.5 * (k11 + k22)
    diff = 0.5 * (k11 - k22)
    top = half + np.sqrt(diff * diff + k12 * k12)
    return 1.0 / top if top > 0.0 else 0.0


@njit(**INLINE)
def soft_coefficients(hertz, zeta, h):
    """Box2D v3's b2MakeSoft: (bias_rate, mass_scale, impulse_scale) of a soft constraint of
    natural frequency ``hertz`` and damping ratio ``zeta`` stepped at h (implicit Euler on the
    constraint's spring-damper); hertz 0 is a rigid row."""
    if hertz == 0.0:
        return 0.0, 1.0, 0.0
    omega = 2.0 * np.pi * hertz
    a1 = 2.0 * zeta + h * omega
    a2 = h * omega * a1
    a3 = 1.0 / (1.0 + a2)
    return omega / a1, a2 * a3, a3


# -- preparing the rows ---------------------------------------------------------------------------
@njit(**JIT)
def prepare_rows(contacts, rows, count, x, v, w, inv_mass, inv_inertia):
    """Frames, anchors, effective masses and the normal velocity now of every row, from the
    detected contacts, the centres of mass x and the velocities (v, w)."""
    dim = contacts.normal.shape[1]
    ca, cb, normal, point, depth = (contacts.a, contacts.b, contacts.normal, contacts.point,
                                    contacts.depth)
    rn, rt1, rt2, rra, rrb = rows.n, rows.t1, rows.t2, rows.ra, rows.rb
    rolling_friction, torsional_friction = contacts.rolling_friction, contacts.torsional_friction
    for c in range(count):
        a = ca[c]
        b = cb[c]
        if dim == 3:
            n = (normal[c, 0], normal[c, 1], normal[c, 2])
            p = (point[c, 0], point[c, 1], point[c, 2])
            ra = sub(p, load3(x, a))
            rb = sub(p, load3(x, b)) if b >= 0 else ZERO3
        else:
            n = (normal[c, 0], normal[c, 1], 0.0)
            p = (point[c, 0], point[c, 1], 0.0)
            ra = (p[0] - x[a, 0], p[1] - x[a, 1], 0.0)
            rb = (p[0] - x[b, 0], p[1] - x[b, 1], 0.0) if b >= 0 else ZERO3
        # Tangents: a fixed function of n (so the warm-start impulses of a contact whose normal
        # does not turn keep their meaning); 3D as Bullet's btPlaneSpace1. 2D: t1 is Box2D's
        # right perpendicular and t2 = z, the axis of rolling resistance.
        if dim == 3:
            if abs(n[2]) > 0.7071067811865476:
                k = 1.0 / np.sqrt(n[1] * n[1] + n[2] * n[2])
                t1 = (0.0, -n[2] * k, n[1] * k)
            else:
                k = 1.0 / np.sqrt(n[0] * n[0] + n[1] * n[1])
                t1 = (-n[1] * k, n[0] * k, 0.0)
            t2 = cross(n, t1)
        else:
            t1 = (n[1], -n[0], 0.0)
            t2 = (0.0, 0.0, 1.0)
        store3(rn, c, n)
        store3(rt1, c, t1)
        store3(rt2, c, t2)
        store3(rra, c, ra)
        store3(rrb, c, rb)
        store3(rows.ra0, c, ra)
        store3(rows.rb0, c, rb)
        va, wa, ma, ia = load_body(v, w, inv_mass, inv_inertia, a)
        if b >= 0:
            vb, wb, mb, ib = load_body(v, w, inv_mass, inv_inertia, b)
        else:
            vb, wb, mb, ib = ZERO3, ZERO3, 0.0, ZERO9
        k = linear_mass(n, n, ra, rb, ma, ia, mb, ib)
        rows.normal_mass[c] = 1.0 / k if k > 0.0 else 0.0
        k11 = linear_mass(t1, t1, ra, rb, ma, ia, mb, ib)
        if dim == 3:
            k12 = linear_mass(t1, t2, ra, rb, ma, ia, mb, ib)
            k22 = linear_mass(t2, t2, ra, rb, ma, ia, mb, ib)
            rows.tangent_inv[c, 0] = isotropic_mass(k11, k12, k22)
            # the rolling and torsion masses only where the pair has those rows (spin_update
            # reads them behind the same tests): four angular products a row otherwise
            rows.rolling_inv[c, 0] = 0.0
            rows.twist_mass[c] = 0.0
            if rolling_friction[c] > 0.0:
                rows.rolling_inv[c, 0] = isotropic_mass(angular_mass(t1, t1, ia, ib),
                                                        angular_mass(t1, t2, ia, ib),
                                                        angular_mass(t2, t2, ia, ib))
            if torsional_friction[c] > 0.0:
                k = angular_mass(n, n, ia, ib)
                rows.twist_mass[c] = 1.0 / k if k > 0.0 else 0.0
        else:
            rows.tangent_inv[c, 0] = 1.0 / k11 if k11 > 0.0 else 0.0
            rows.rolling_inv[c, 0] = 0.0
            if rolling_friction[c] > 0.0:
                k = angular_mass(t2, t2, ia, ib)
                rows.rolling_inv[c, 0] = 1.0 / k if k > 0.0 else 0.0
            rows.twist_mass[c] = 0.0
        rows.separation[c] = -depth[c]
        rows.gap[c] = -depth[c]
        rows.relative_velocity[c] = dot(relative_velocity(va, wa, vb, wb, ra, rb), n)
        rows.total_normal[c] = 0.0
        rows.pseudo[c, 0] = 0.0


# -- warm starting ------------------------------------------------------------------------------
@njit(**JIT)
def match_rows(contacts, rows, count, enabled):
    """Each row's accumulated impulses from the previous step (warm starting): the row with the
    same feature key; failing that, the row of the same pair of colliders (the key's upper 32
    bits) whose anchor on a was nearest, within ``MATCH_DISTANCE``; zero for a new contact or
    with warm starting off.

    The fallback keeps the impulses of a manifold whose feature ids change while its points
    stay (measured: two resting boxes of the same size, face on face, swap reference faces
    from step to step and renumber their four points). Without it the 1000 kg box on a 1 kg
    box restarted its impulses from zero at every step and pushed the light box out sideways."""
    m = rows.prev_count[0] if enabled else 0
    feat, pf, prev = contacts.feature, rows.prev_feature, rows.prev_impulse
    imp, ra = rows.impulse, rows.ra
    for c in range(count):
        for k in range(N_ACC):
            imp[c, k] = 0.0
        if m == 0:
            continue
        key = feat[c]
        # lower bound of key in pf[:m]
        lo = 0
        hi = m
        while lo < hi:
            mid = (lo + hi) // 2
            if pf[mid] < key:
                lo = mid + 1
            else:
                hi = mid
        best = -1
        if lo < m and pf[lo] == key:
            best = lo
        else:
            pair = key >> 32
            first = pair << 32
            lo = 0
            hi = m
            while lo < hi:
                mid = (lo + hi) // 2
                if pf[mid] < first:
                    lo = mid + 1
                else:
                    hi = mid
            nearest = MATCH_DISTANCE * MATCH_DISTANCE
            j = lo
            while j < m and (pf[j] >> 32) == pair:
                dx = prev[j, N_ACC] - ra[c, 0]
                dy = prev[j, N_ACC + 1] - ra[c, 1]
                dz = prev[j, N_ACC + 2] - ra[c, 2]
                d2 = dx * dx + dy * dy + dz * dz
                if d2 < nearest:
                    nearest = d2
                    best = j
                j += 1
        if best >= 0:
            for k in range(N_ACC):
                imp[c, k] = prev[best, k]


@njit(**JIT)
def store_rows(contacts, rows, count):
    """Keep this step's impulses and anchors by feature key for the next step's warm start, and
    write the (normal, tangent 1, tangent 2) impulses into the contact buffer."""
    prev = rows.prev_impulse
    for c in range(count):
        for k in range(3):
            contacts.impulse[c, k] = rows.impulse[c, k]
    # sorted by key: a stable merge sort of the keys (numba's, O(count log count)), then the rows
    # written in that order; the heap sort in place this replaces took 76 us on the 1180 rows of
    # the cube pile (its sift moved nine values per swap). Stable: rows with equal keys (none
    # expected: a key is the pair and the feature) keep their buffer order, deterministically.
    order = np.argsort(contacts.feature[:count], kind="mergesort")
    for i in range(count):
        c = order[i]
        rows.prev_feature[i] = contacts.feature[c]
        for k in range(N_ACC):
            prev[i, k] = rows.impulse[c, k]
        for k in range(3):
            prev[i, N_ACC + k] = rows.ra[c, k]
    rows.prev_count[0] = count


@njit(**JIT)
def apply_accumulated(contacts, rows, count, v, w, inv_mass, inv_inertia):
    """Warm start: apply every row's accumulated impulses to the velocities."""
    dim3 = contacts.normal.shape[1] == 3
    ca, cb, imp = contacts.a, contacts.b, rows.impulse
    rn, rt1, rt2, rra, rrb = rows.n, rows.t1, rows.t2, rows.ra, rows.rb
    for c in range(count):
        a = ca[c]
        b = cb[c]
        va, wa, ma, ia = load_body(v, w, inv_mass, inv_inertia, a)
        if b >= 0:
            vb, wb, mb, ib = load_body(v, w, inv_mass, inv_inertia, b)
        else:
            vb, wb, mb, ib = ZERO3, ZERO3, 0.0, ZERO9
        n = load3(rn, c)
        t1 = load3(rt1, c)
        t2 = load3(rt2, c)
        ln, l1, l2, r1, r2, tw = load6(imp, c)
        if not dim3:
            l2 = 0.0
        rows.total_normal[c] += ln
        if ln == 0.0 and l1 == 0.0 and l2 == 0.0 and r1 == 0.0 and r2 == 0.0 and tw == 0.0:
            continue  # nothing to apply (a new or open row): exact zeros, skipped
        p = add(add(scale(ln, n), scale(l1, t1)), scale(l2, t2))
        va, wa, vb, wb = push(p, load3(rra, c), load3(rrb, c), va, wa, vb, wb, ma, ia, mb, ib)
        if r1 != 0.0 or r2 != 0.0 or tw != 0.0:
            if dim3:
                m = add(add(scale(r1, t1), scale(r2, t2)), scale(tw, n))
            else:
                m = (0.0, 0.0, r1)
            wa, wb = twist(m, wa, wb, ia, ib)
        store_body(v, w, a, va, wa)
        if b >= 0:
            store_body(v, w, b, vb, wb)


# -- the rows -------------------------------------------------------------------------------------
@njit(**INLINE)
def normal_update(n, ra, rb, va, wa, vb, wb, ma, ia, mb, ib, normal_mass, old, bias,
                  mass_scale, impulse_scale):
    """One projected Gauss-Seidel update of a normal row: Box2D v3's soft form
    d = -m_n (mass_scale vn + bias) - impulse_scale lambda, the accumulated lambda kept >= 0.
    Returns (lambda, vn before the update, velocities).

    A row whose impulse does not change (a speculative row that stays open, a row at rest on its
    clamp) applies nothing: the push of a zero impulse would add exact zeros, so it is skipped
    (only the sign of a zero velocity component could differ; the pile states are bit-identical
    with and without the skip, checked). On the cube piles a third of the rows are open in a
    sweep."""
    vn = dot(relative_velocity(va, wa, vb, wb, ra, rb), n)
    new = old - normal_mass * (mass_scale * vn + bias) - impulse_scale * old
    if new < 0.0:
        new = 0.0
    if new != old:
        va, wa, vb, wb = push(scale(new - old, n), ra, rb, va, wa, vb, wb, ma, ia, mb, ib)
    return new, vn, va, wa, vb, wb


@njit(**INLINE)
def friction_update(dim3, t1, t2, ra, rb, va, wa, vb, wb, ma, ia, mb, ib, lam_n, o1, o2,
                    tangent_mass, mu):
    """Coulomb friction of a row: the tangential impulse updated along -v_t with the isotropic
    mass, then projected onto the disc |lambda_t| <= mu lambda_n. Returns (lambda_1, lambda_2,
    velocity change, velocities)."""
    limit = mu * lam_n
    vt = relative_velocity(va, wa, vb, wb, ra, rb)
    n1 = o1 - tangent_mass * dot(vt, t1)
    if dim3:
        n2 = o2 - tangent_mass * dot(vt, t2)
        mag2 = n1 * n1 + n2 * n2
        if mag2 > limit * limit:
            s = limit / np.sqrt(mag2)
            n1 *= s
            n2 *= s
    else:
        n2 = 0.0
        n1 = min(max(n1, -limit), limit)
    d1 = n1 - o1
    d2 = n2 - o2
    va, wa, vb, wb = push(add(scale(d1, t1), scale(d2, t2)), ra, rb, va, wa, vb, wb, ma, ia, mb,
                          ib)
    change = np.sqrt(d1 * d1 + d2 * d2) / tangent_mass if tangent_mass > 0.0 else 0.0
    return n1, n2, change, va, wa, vb, wb


@njit(**INLINE)
def spin_update(dim3, n, t1, t2, wa, wb, ia, ib, lam_n, o1, o2, ot, rolling_mass, twist_mass,
                rolling, torsional):
    """Rolling resistance (disc of radius rolling lambda_n about the tangent-plane axes; 2D about
    z) and torsional friction (about n, 3D) on the relative angular velocity."""
    if rolling > 0.0:
        limit = rolling * lam_n
        spin = sub(wb, wa)
        if dim3:
            n1 = o1 - rolling_mass * dot(spin, t1)
            n2 = o2 - rolling_mass * dot(spin, t2)
            mag2 = n1 * n1 + n2 * n2
            if mag2 > limit * limit:
                s = limit / np.sqrt(mag2)
                n1 *= s
                n2 *= s
            m = add(scale(n1 - o1, t1), scale(n2 - o2, t2))
        else:
            n1 = min(max(o1 - rolling_mass * spin[2], -limit), limit)
            n2 = 0.0
            m = (0.0, 0.0, n1 - o1)
        wa, wb = twist(m, wa, wb, ia, ib)
        o1 = n1
        o2 = n2
    if dim3 and torsional > 0.0:
        limit = torsional * lam_n
        nt = min(max(ot - twist_mass * dot(sub(wb, wa), n), -limit), limit)
        wa, wb = twist(scale(nt - ot, n), wa, wb, ia, ib)
        ot = nt
    return o1, o2, ot, wa, wb


@njit(**INLINE)
def solve_row(dim3, n, t1, t2, ra, rb, va, wa, vb, wb, ma, ia, mb, ib, acc, normal_mass,
              tangent_mass, rolling_mass, twist_mass, mu, rolling, torsional, bias, mass_scale,
              impulse_scale):
    """A contact's normal row, then its friction, rolling and torsion, on the two bodies'
    velocities. ``acc`` holds the six accumulated impulses. Returns (new acc, the largest
    velocity change, the normal velocity before the row's update, the velocities)."""
    ln, l1, l2, r1, r2, tw = acc
    new, vn, va, wa, vb, wb = normal_update(n, ra, rb, va, wa, vb, wb, ma, ia, mb, ib,
                                            normal_mass, ln, bias, mass_scale, impulse_scale)
    change = abs(new - ln) / normal_mass if normal_mass > 0.0 else 0.0
    # friction with no normal impulse and none of its own has a zero disc: it would project its
    # update onto zero and apply nothing (skipped, as the normal row's zero push)
    if (mu > 0.0 and new > 0.0) or l1 != 0.0 or l2 != 0.0:
        l1, l2, ch, va, wa, vb, wb = friction_update(dim3, t1, t2, ra, rb, va, wa, vb, wb, ma,
                                                     ia, mb, ib, new, l1, l2, tangent_mass, mu)
        change = max(change, ch)
    if rolling > 0.0 or torsional > 0.0:
        r1, r2, tw, wa, wb = spin_update(dim3, n, t1, t2, wa, wb, ia, ib, new, r1, r2, tw,
                                         rolling_mass, twist_mass, rolling, torsional)
    return (new, l1, l2, r1, r2, tw), change, vn, va, wa, vb, wb


@njit(**INLINE)
def store6(arr, i, t):
    arr[i, 0] = t[0]
    arr[i, 1] = t[1]
    arr[i, 2] = t[2]
    arr[i, 3] = t[3]
    arr[i, 4] = t[4]
    arr[i, 5] = t[5]


@njit(**INLINE)
def row_sweep(contacts, rows, count, v, w, inv_mass, inv_inertia, soft, inv_h, use_bias,
              contact_soft, static_soft, push_speed):
    """One sweep over the rows in buffer order, for both models. ``soft``: soft_step's bias
    from the current separation ``rows.gap``; otherwise sequential_impulse's rigid rows with
    ``rows.bias``. Returns the largest velocity change of a row (m/s)."""
    dim3 = contacts.normal.shape[1] == 3
    ca, cb, fr, rf, tf = (contacts.a, contacts.b, contacts.friction, contacts.rolling_friction,
                          contacts.torsional_friction)
    rn, rt1, rt2, rra, rrb, imp = rows.n, rows.t1, rows.t2, rows.ra, rows.rb, rows.impulse
    nmass, tmass, rmass, wmass = (rows.normal_mass, rows.tangent_inv, rows.rolling_inv,
                                  rows.twist_mass)
    gap, total, biases = rows.gap, rows.total_normal, rows.bias
    change = 0.0
    for c in range(count):
        a = ca[c]
        b = cb[c]
        va, wa, ma, ia = load_body(v, w, inv_mass, inv_inertia, a)
        n = load3(rn, c)
        ra = load3(rra, c)
        rb = load3(rrb, c)
        if b >= 0:
            vb, wb, mb, ib = load_body(v, w, inv_mass, inv_inertia, b)
        else:
            vb, wb, mb, ib = ZERO3, ZERO3, 0.0, ZERO9
        if soft:
            s = gap[c]
            if s > 0.0:
                bias, mass_scale, impulse_scale = s * inv_h, 1.0, 0.0
            elif use_bias:
                k = static_soft if b < 0 else contact_soft
                mass_scale, impulse_scale = k[1], k[2]
                bias = max(mass_scale * k[0] * s, -push_speed)
            else:
                bias, mass_scale, impulse_scale = 0.0, 1.0, 0.0
        else:
            bias, mass_scale, impulse_scale = biases[c], 1.0, 0.0
        acc = load6(imp, c)
        new, ch, vn, va, wa, vb, wb = solve_row(
            dim3, n, load3(rt1, c), load3(rt2, c), ra, rb, va, wa, vb, wb, ma, ia, mb, ib, acc,
            nmass[c], tmass[c, 0], rmass[c, 0], wmass[c], fr[c], rf[c],
            tf[c] if dim3 else 0.0, bias, mass_scale, impulse_scale)
        store6(imp, c, new)
        if soft and total[c] == 0.0 and new[0] > 0.0:
            # the normal velocity just before the row's first impulse of the step (vn of the
            # update that gave it): soft_step's restitution reflects it (see restitution_pass)
            rows.relative_velocity[c] = vn
        total[c] += new[0] - acc[0]
        change = max(change, ch)
        store_body(v, w, a, va, wa)
        if b >= 0:
            store_body(v, w, b, vb, wb)
    return change


@njit(**INLINE)
def normal_sweep(contacts, rows, count, v, w, inv_mass, inv_inertia, acc, split,
                 restitution_threshold):
    """Rigid normal rows alone on (v, w) with accumulators acc[:, 0]: the split impulse
    (``split``: every row, with ``rows.bias``) or soft_step's restitution (only the rows that
    approached faster than the threshold and took an impulse, driven to vn = -e vn0)."""
    ca, cb, e = contacts.a, contacts.b, contacts.restitution
    rn, rra, rrb, nmass = rows.n, rows.ra, rows.rb, rows.normal_mass
    vn0, total, biases = rows.relative_velocity, rows.total_normal, rows.bias
    for c in range(count):
        if split:
            bias = biases[c]
        else:
            if e[c] == 0.0 or vn0[c] > -restitution_threshold or total[c] == 0.0:
                continue
            bias = e[c] * vn0[c]
        a = ca[c]
        b = cb[c]
        va, wa, ma, ia = load_body(v, w, inv_mass, inv_inertia, a)
        if b >= 0:
            vb, wb, mb, ib = load_body(v, w, inv_mass, inv_inertia, b)
        else:
            vb, wb, mb, ib = ZERO3, ZERO3, 0.0, ZERO9
        old = acc[c, 0]
        new, _, va, wa, vb, wb = normal_update(load3(rn, c), load3(rra, c), load3(rrb, c), va, wa,
                                            vb, wb, ma, ia, mb, ib, nmass[c], old, bias, 1.0,
                                            0.0)
        acc[c, 0] = new
        if not split:
            total[c] += new - old
        store_body(v, w, a, va, wa)
        if b >= 0:
            store_body(v, w, b, vb, wb)


# -- the passes -----------------------------------------------------------------------------------
@njit(**JIT)
def impulse_bias(contacts, rows, count, h, threshold, v, w):
    """sequential_impulse's normal-row bias (target vn >= -bias), from the normal velocity vn0
    before this step's kick (``rows.relative_velocity``), the kicked one vn1 (v, w) and the
    separation s at detection:

    * restitution, -e vn0, when the pair has e > 0, the approach was faster than the threshold
      and the contact closes within the step (s + vn1 h <= 0). The velocity *before* the kick is
      the one reflected: then the positions after the bounce mirror those before it step for
      step (v_(k+1) = -v_k), so a bounce with e = 1 keeps its apex exactly; reflecting the kicked
      velocity gains g dt v (0.9 % of the apex per bounce at 4.4 m/s and 1 ms, measured);
    * otherwise the speculative allowance s / h for a gap (vn may approach to close it exactly);
    * otherwise 0 (a touching or penetrating row stops the approach; the penetration itself is
      removed by the split impulse, never through the velocity)."""
    ca, cb, e, sep, vn0, bias = (contacts.a, contacts.b, contacts.restitution, rows.separation,
                                 rows.relative_velocity, rows.bias)
    rn, rra, rrb = rows.n, rows.ra, rows.rb
    for c in range(count):
        s = sep[c]
        if e[c] > 0.0 and vn0[c] < -threshold:
            a = ca[c]
            b = cb[c]
            va = load3(v, a)
            wa = load3(w, a)
            if b >= 0:
                vb = load3(v, b)
                wb = load3(w, b)
            else:
                vb = ZERO3
                wb = ZERO3
            vn1 = dot(relative_velocity(va, wa, vb, wb, load3(rra, c), load3(rrb, c)),
                      load3(rn, c))
            if s + vn1 * h <= 0.0:
                bias[c] = e[c] * vn0[c]
                continue
        bias[c] = s / h if s > 0.0 else 0.0


@njit(**JIT)
def impulse_sweep(contacts, rows, count, v, w, inv_mass, inv_inertia):
    """One sequential_impulse sweep over the rows in buffer order: each row's normal (rigid, with
    its bias), friction, rolling and torsion. Returns the largest velocity change of a row
    (m/s), the convergence measure of the ``tolerance`` parameter."""
    return row_sweep(contacts, rows, count, v, w, inv_mass, inv_inertia, False, 0.0, False,
                     (0.0, 1.0, 0.0), (0.0, 1.0, 0.0), 0.0)


@njit(**JIT)
def count_sweeps(rows, sweeps):
    """Record a step's velocity sweeps (``stats``: steps, sweeps, the most in one step)."""
    rows.stats[0] += 1
    rows.stats[1] += sweeps
    rows.stats[2] = max(rows.stats[2], sweeps)


@njit(**JIT)
def split_sweep(contacts, rows, count, vp, wp, inv_mass, inv_inertia, h, baumgarte, slop):
    """One sweep of the split impulse: normal rows on the pseudo-velocities (vp, wp), which move
    the positions of this step only and are then discarded (no energy enters the velocities).
    A row penetrating by more than the slop is driven to vn >= baumgarte (depth - slop) / h; a
    touching row only keeps the pseudo-velocities from pushing deeper; a gap lets them close it.
    The biases go into ``rows.bias`` (the velocity sweeps are done by then)."""
    sep, bias = rows.separation, rows.bias
    for c in range(count):
        s = sep[c]
        if s > 0.0:
            bias[c] = s / h
        else:
            excess = -s - slop
            bias[c] = -baumgarte * excess / h if excess > 0.0 else 0.0
    normal_sweep(contacts, rows, count, vp, wp, inv_mass, inv_inertia, rows.pseudo, True, 0.0)


@njit(**JIT)
def soft_sweep(contacts, rows, count, v, w, inv_mass, inv_inertia, inv_h, use_bias,
               contact_soft, static_soft, push_speed):
    """One soft_step sweep (Box2D v3's b2SolveContact): each normal row with the separation
    updated from the bodies' motion since detection (``move_anchors``): a gap gives the
    speculative bias s / h; an
    overlap, with ``use_bias``, the soft push max(mass_scale bias_rate s, -push_speed) with the
    soft mass and impulse scales (static contacts twice as stiff); without it (relax) a rigid
    row. Then the row's friction, rolling and torsion."""
    row_sweep(contacts, rows, count, v, w, inv_mass, inv_inertia, True, inv_h, use_bias,
              contact_soft, static_soft, push_speed)


@njit(**INLINE)
def rotation_vector(m):
    """sin(angle) axis of a rotation matrix (row-major 9-tuple): its skew part, the rotation
    vector to first order."""
    return 0.5 * (m[7] - m[5]), 0.5 * (m[2] - m[6]), 0.5 * (m[3] - m[1])


@njit(**JIT)
def move_anchors(contacts, rows, count, dp, dR):
    """soft_step, after a sub-step's drift: each row's separation and anchors from the bodies'
    motion since detection (dp: centre-of-mass displacement, dR = R(now) R(detection)^T).

    Separation: s = s0 + n . ((dp_b + t_b x rb0) - (dp_a + t_a x ra0)), the normal held fixed,
    t the rotation vector of dR to first order (sin(angle) axis, from dR's skew part). Box2D v3
    turns the anchors exactly, dR ra0 - ra0, which for a round body is wrong at second order:
    the material point that touched rises R (1 - cos(angle)) as the body rolls on, while the
    contact stays under it; a ball rolling at 35 rad/s then read a growing gap, let itself sink
    (13 um in 1 s and still going) and slipped 3.5 mm/s (measured). The first-order term, the
    one a tipping box's corner needs, is kept; for a ball it is zero (ra0 along n).

    Anchors: Box2D v3 keeps them fixed (world-oriented offsets from the centres of mass, right
    for rolling: the contact stays under a rolling ball, it does not turn
    with it; anchors turned with the bodies made the rolling ball 5 % slow, measured). Between
    two bodies the fixed offsets drift apart as the bodies move relative to each other, and an
    equal and opposite impulse pair at two different points changes the angular momentum (2e-5
    relative in one step of the hand-filled two-box test); so both are moved to the middle of
    the two points, ra = ra0 + d / 2, rb = rb0 - d / 2 with d = dp_b - dp_a: x_a + ra = x_b +
    rb, the impulses act at one point and angular momentum is conserved to round-off. Against
    fixed geometry the anchor stays ra0 (the world takes the reaction)."""
    ca, cb, rn = contacts.a, contacts.b, rows.n
    for c in range(count):
        a = ca[c]
        b = cb[c]
        ra0 = load3(rows.ra0, c)
        dpa = load3(dp, a)
        moved = scale(-1.0, add(dpa, cross(rotation_vector(load9(dR, a)), ra0)))
        if b >= 0:
            rb0 = load3(rows.rb0, c)
            dpb = load3(dp, b)
            moved = add(moved, add(dpb, cross(rotation_vector(load9(dR, b)), rb0)))
            half = scale(0.5, sub(dpb, dpa))
            store3(rows.ra, c, add(ra0, half))
            store3(rows.rb, c, sub(rb0, half))
        rows.gap[c] = rows.separation[c] + dot(moved, load3(rn, c))


@njit(**JIT)
def restitution_pass(contacts, rows, count, v, w, inv_mass, inv_inertia, threshold):
    """soft_step's restitution (Box2D v3, after the sub-steps): a row that approached faster
    than the threshold and took a normal impulse this step is driven to vn = -e vn0 (the
    accumulated impulse kept >= 0).

    vn0 is the normal velocity just before the row's first impulse of the step (``row_sweep``),
    the approach speed at touch to within a sub-step; a row warm started with an impulse keeps
    the velocity of the step's start. Box2D v3 reflects the velocity of the step's start always:
    a ball that meets the ground s0 below its start-of-step height then leaves the surface with
    the speed it had s0 higher, losing g s0 of energy per bounce (s0 up to v dt): measured an
    apex 0.73 % low after two bounces of the 1 m drop, against 1e-5 this way."""
    normal_sweep(contacts, rows, count, v, w, inv_mass, inv_inertia, rows.impulse, False,
                 threshold)
