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
* friction: the tangential impulse (2-vector in 3D, solved as a 2 x 2 block with the exact
  inverse of its effective-mass matrix) projected onto the Coulomb *disc* |lambda_t| <= mu lambda_n
  (an isotropic cone, not a pyramid: CONTACTS.md trap C3), lambda_n of the current iteration;
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
results are bit-identical from run to run. Nothing here allocates.
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
    ra: np.ndarray  # (C, 3) anchor on a: contact point minus a's centre of mass
    rb: np.ndarray  # (C, 3) anchor on b (zero when b is fixed)
    separation: np.ndarray  # (C,) -depth at detection (> 0: a speculative gap)
    normal_mass: np.ndarray  # (C,) 1 / (n . K n)
    tangent_inv: np.ndarray  # (C, 3) inverse of the 2 x 2 tangent block (i11, i12, i22); 2D: i11
    rolling_inv: np.ndarray  # (C, 3) the same for the rolling rows
    twist_mass: np.ndarray  # (C,) 1 / (n . (Ia^-1 + Ib^-1) n)
    relative_velocity: np.ndarray  # (C,) vn when the rows were prepared (restitution)
    bias: np.ndarray  # (C,) sequential_impulse: the normal row's velocity bias
    total_normal: np.ndarray  # (C,) normal impulse applied this step (soft_step restitution)
    impulse: np.ndarray  # (C, 6) accumulated impulses
    pseudo: np.ndarray  # (C, 1) split-impulse accumulators (sequential_impulse)
    prev_feature: np.ndarray  # (C,) int64: last step's keys, sorted
    prev_impulse: np.ndarray  # (C, 6): last step's impulses, in prev_feature's order
    prev_count: np.ndarray  # (1,) int64


def make_rows(capacity: int) -> ContactRows:
    c = int(capacity)
    z3 = lambda: np.zeros((c, 3))  # noqa: E731
    z1 = lambda: np.zeros(c)  # noqa: E731
    return ContactRows(n=z3(), t1=z3(), t2=z3(), ra=z3(), rb=z3(), separation=z1(),
                       normal_mass=z1(), tangent_inv=z3(), rolling_inv=z3(), twist_mass=z1(),
                       relative_velocity=z1(), bias=z1(), total_normal=z1(),
                       impulse=np.zeros((c, N_ACC)), pseudo=np.zeros((c, 1)),
                       prev_feature=np.zeros(c, np.int64), prev_impulse=np.zeros((c, N_ACC)),
                       prev_count=np.zeros(1, np.int64))


# -- small vector helpers (scalars in, tuples out) ------------------------------------------------
@njit(**INLINE)
def cross(ax, ay, az, bx, by, bz):
    return ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx


@njit(**INLINE)
def mat_vec(M, i, x, y, z):
    """M[i] (x, y, z) for a stack of 3 x 3 matrices."""
    return (M[i, 0, 0] * x + M[i, 0, 1] * y + M[i, 0, 2] * z,
            M[i, 1, 0] * x + M[i, 1, 1] * y + M[i, 1, 2] * z,
            M[i, 2, 0] * x + M[i, 2, 1] * y + M[i, 2, 2] * z)


@njit(**INLINE)
def relative_velocity(rows, c, a, b, v, w):
    """Velocity of b's material point at the contact minus a's (world, 3 components)."""
    cx, cy, cz = cross(w[a, 0], w[a, 1], w[a, 2], rows.ra[c, 0], rows.ra[c, 1], rows.ra[c, 2])
    dx = -(v[a, 0] + cx)
    dy = -(v[a, 1] + cy)
    dz = -(v[a, 2] + cz)
    if b >= 0:
        cx, cy, cz = cross(w[b, 0], w[b, 1], w[b, 2], rows.rb[c, 0], rows.rb[c, 1],
                           rows.rb[c, 2])
        dx += v[b, 0] + cx
        dy += v[b, 1] + cy
        dz += v[b, 2] + cz
    return dx, dy, dz


@njit(**INLINE)
def relative_spin(a, b, w):
    """w_b - w_a (w_b = 0 for fixed geometry)."""
    if b >= 0:
        return w[b, 0] - w[a, 0], w[b, 1] - w[a, 1], w[b, 2] - w[a, 2]
    return -w[a, 0], -w[a, 1], -w[a, 2]


@njit(**INLINE)
def apply_impulse(rows, c, a, b, px, py, pz, v, w, inv_mass, inv_inertia):
    """+P on b at rb, -P on a at ra: velocities change by P / m and I^-1 (r x P)."""
    ma = inv_mass[a]
    v[a, 0] -= ma * px
    v[a, 1] -= ma * py
    v[a, 2] -= ma * pz
    tx, ty, tz = cross(rows.ra[c, 0], rows.ra[c, 1], rows.ra[c, 2], px, py, pz)
    ix, iy, iz = mat_vec(inv_inertia, a, tx, ty, tz)
    w[a, 0] -= ix
    w[a, 1] -= iy
    w[a, 2] -= iz
    if b >= 0:
        mb = inv_mass[b]
        v[b, 0] += mb * px
        v[b, 1] += mb * py
        v[b, 2] += mb * pz
        tx, ty, tz = cross(rows.rb[c, 0], rows.rb[c, 1], rows.rb[c, 2], px, py, pz)
        ix, iy, iz = mat_vec(inv_inertia, b, tx, ty, tz)
        w[b, 0] += ix
        w[b, 1] += iy
        w[b, 2] += iz


@njit(**INLINE)
def apply_angular(a, b, mx, my, mz, w, inv_inertia):
    """An angular impulse +M on b, -M on a."""
    ix, iy, iz = mat_vec(inv_inertia, a, mx, my, mz)
    w[a, 0] -= ix
    w[a, 1] -= iy
    w[a, 2] -= iz
    if b >= 0:
        ix, iy, iz = mat_vec(inv_inertia, b, mx, my, mz)
        w[b, 0] += ix
        w[b, 1] += iy
        w[b, 2] += iz


@njit(**INLINE)
def linear_mass(rows, c, a, b, ux, uy, uz, sx, sy, sz, inv_mass, inv_inertia):
    """u . K s, K the effective-mass matrix (inverse) of the linear rows at contact c."""
    k = inv_mass[a] * (ux * sx + uy * sy + uz * sz)
    rax, ray, raz = rows.ra[c, 0], rows.ra[c, 1], rows.ra[c, 2]
    cux, cuy, cuz = cross(rax, ray, raz, ux, uy, uz)
    csx, csy, csz = cross(rax, ray, raz, sx, sy, sz)
    ix, iy, iz = mat_vec(inv_inertia, a, csx, csy, csz)
    k += cux * ix + cuy * iy + cuz * iz
    if b >= 0:
        k += inv_mass[b] * (ux * sx + uy * sy + uz * sz)
        rbx, rby, rbz = rows.rb[c, 0], rows.rb[c, 1], rows.rb[c, 2]
        cux, cuy, cuz = cross(rbx, rby, rbz, ux, uy, uz)
        csx, csy, csz = cross(rbx, rby, rbz, sx, sy, sz)
        ix, iy, iz = mat_vec(inv_inertia, b, csx, csy, csz)
        k += cux * ix + cuy * iy + cuz * iz
    return k


@njit(**INLINE)
def angular_mass(a, b, ux, uy, uz, sx, sy, sz, inv_inertia):
    """u . (Ia^-1 + Ib^-1) s: the effective-mass matrix (inverse) of angular rows."""
    ix, iy, iz = mat_vec(inv_inertia, a, sx, sy, sz)
    k = ux * ix + uy * iy + uz * iz
    if b >= 0:
        ix, iy, iz = mat_vec(inv_inertia, b, sx, sy, sz)
        k += ux * ix + uy * iy + uz * iz
    return k


@njit(**INLINE)
def inverse2(k11, k12, k22):
    """(i11, i12, i22) of the inverse of the symmetric 2 x 2 matrix; zero if singular."""
    det = k11 * k22 - k12 * k12
    if det > 0.0:
        return k22 / det, -k12 / det, k11 / det
    return 0.0, 0.0, 0.0


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
    """Frames, anchors, effective masses and the pre-solve normal velocity of every row, from
    the detected contacts, the centres of mass x and the velocities (v, w) now."""
    dim = contacts.normal.shape[1]
    for c in range(count):
        a = contacts.a[c]
        b = contacts.b[c]
        nx = contacts.normal[c, 0]
        ny = contacts.normal[c, 1]
        px = contacts.point[c, 0]
        py = contacts.point[c, 1]
        if dim == 3:
            nz = contacts.normal[c, 2]
            pz = contacts.point[c, 2]
            xaz = x[a, 2]
        else:
            nz = pz = xaz = 0.0
        rows.n[c, 0], rows.n[c, 1], rows.n[c, 2] = nx, ny, nz
        rows.ra[c, 0], rows.ra[c, 1], rows.ra[c, 2] = px - x[a, 0], py - x[a, 1], pz - xaz
        if b >= 0:
            xbz = x[b, 2] if dim == 3 else 0.0
            rows.rb[c, 0], rows.rb[c, 1], rows.rb[c, 2] = px - x[b, 0], py - x[b, 1], pz - xbz
        else:
            rows.rb[c, 0] = rows.rb[c, 1] = rows.rb[c, 2] = 0.0
        # Tangents: a fixed function of n (so the warm-start impulses of a contact whose normal
        # does not turn keep their meaning); 3D as Bullet's btPlaneSpace1.
        if dim == 3:
            if abs(nz) > 0.7071067811865476:
                k = 1.0 / np.sqrt(ny * ny + nz * nz)
                t1x, t1y, t1z = 0.0, -nz * k, ny * k
            else:
                k = 1.0 / np.sqrt(nx * nx + ny * ny)
                t1x, t1y, t1z = -ny * k, nx * k, 0.0
            t2x, t2y, t2z = cross(nx, ny, nz, t1x, t1y, t1z)
        else:
            t1x, t1y, t1z = ny, -nx, 0.0  # Box2D's right perpendicular
            t2x, t2y, t2z = 0.0, 0.0, 1.0  # the rolling axis in 2D
        rows.t1[c, 0], rows.t1[c, 1], rows.t1[c, 2] = t1x, t1y, t1z
        rows.t2[c, 0], rows.t2[c, 1], rows.t2[c, 2] = t2x, t2y, t2z
        k = linear_mass(rows, c, a, b, nx, ny, nz, nx, ny, nz, inv_mass, inv_inertia)
        rows.normal_mass[c] = 1.0 / k if k > 0.0 else 0.0
        k11 = linear_mass(rows, c, a, b, t1x, t1y, t1z, t1x, t1y, t1z, inv_mass, inv_inertia)
        if dim == 3:
            k12 = linear_mass(rows, c, a, b, t1x, t1y, t1z, t2x, t2y, t2z, inv_mass, inv_inertia)
            k22 = linear_mass(rows, c, a, b, t2x, t2y, t2z, t2x, t2y, t2z, inv_mass, inv_inertia)
            rows.tangent_inv[c, 0], rows.tangent_inv[c, 1], rows.tangent_inv[c, 2] = inverse2(
                k11, k12, k22)
            j11 = angular_mass(a, b, t1x, t1y, t1z, t1x, t1y, t1z, inv_inertia)
            j12 = angular_mass(a, b, t1x, t1y, t1z, t2x, t2y, t2z, inv_inertia)
            j22 = angular_mass(a, b, t2x, t2y, t2z, t2x, t2y, t2z, inv_inertia)
            rows.rolling_inv[c, 0], rows.rolling_inv[c, 1], rows.rolling_inv[c, 2] = inverse2(
                j11, j12, j22)
            k = angular_mass(a, b, nx, ny, nz, nx, ny, nz, inv_inertia)
            rows.twist_mass[c] = 1.0 / k if k > 0.0 else 0.0
        else:
            rows.tangent_inv[c, 0] = 1.0 / k11 if k11 > 0.0 else 0.0
            rows.tangent_inv[c, 1] = rows.tangent_inv[c, 2] = 0.0
            k = angular_mass(a, b, 0.0, 0.0, 1.0, 0.0, 0.0, 1.0, inv_inertia)
            rows.rolling_inv[c, 0] = 1.0 / k if k > 0.0 else 0.0
            rows.rolling_inv[c, 1] = rows.rolling_inv[c, 2] = 0.0
            rows.twist_mass[c] = 0.0
        rows.separation[c] = -contacts.depth[c]
        dx, dy, dz = relative_velocity(rows, c, a, b, v, w)
        rows.relative_velocity[c] = dx * nx + dy * ny + dz * nz
        rows.total_normal[c] = 0.0
        rows.pseudo[c, 0] = 0.0


# -- warm starting ------------------------------------------------------------------------------
@njit(**INLINE)
def _sift_down(keys, vals, start, end):
    root = start
    while True:
        child = 2 * root + 1
        if child > end:
            return
        if child + 1 <= end and keys[child] < keys[child + 1]:
            child += 1
        if keys[root] < keys[child]:
            keys[root], keys[child] = keys[child], keys[root]
            for k in range(vals.shape[1]):
                vals[root, k], vals[child, k] = vals[child, k], vals[root, k]
            root = child
        else:
            return


@njit(**INLINE)
def heap_sort(keys, vals, count):
    """Sort keys[:count] ascending in place, moving the rows of vals with them (no allocation,
    O(count log count), deterministic)."""
    for start in range((count - 2) // 2, -1, -1):
        _sift_down(keys, vals, start, count - 1)
    for end in range(count - 1, 0, -1):
        keys[0], keys[end] = keys[end], keys[0]
        for k in range(vals.shape[1]):
            vals[0, k], vals[end, k] = vals[end, k], vals[0, k]
        _sift_down(keys, vals, 0, end - 1)


@njit(**JIT)
def match_rows(contacts, rows, count, enabled):
    """Each row's accumulated impulses: the previous step's for the same feature key (warm
    starting), zero for a new contact or with warm starting off."""
    m = rows.prev_count[0] if enabled else 0
    for c in range(count):
        for k in range(N_ACC):
            rows.impulse[c, k] = 0.0
        if m == 0:
            continue
        key = contacts.feature[c]
        lo = 0
        hi = m - 1
        while lo <= hi:
            mid = (lo + hi) // 2
            f = rows.prev_feature[mid]
            if f < key:
                lo = mid + 1
            elif f > key:
                hi = mid - 1
            else:
                for k in range(N_ACC):
                    rows.impulse[c, k] = rows.prev_impulse[mid, k]
                break


@njit(**JIT)
def store_rows(contacts, rows, count):
    """Keep this step's impulses by feature key for the next step's warm start, and write the
    (normal, tangent 1, tangent 2) impulses into the contact buffer."""
    for c in range(count):
        rows.prev_feature[c] = contacts.feature[c]
        for k in range(N_ACC):
            rows.prev_impulse[c, k] = rows.impulse[c, k]
        for k in range(3):
            contacts.impulse[c, k] = rows.impulse[c, k]
    heap_sort(rows.prev_feature, rows.prev_impulse, count)
    rows.prev_count[0] = count


@njit(**JIT)
def apply_accumulated(contacts, rows, count, v, w, inv_mass, inv_inertia):
    """Warm start: apply every row's accumulated impulses to the velocities."""
    dim = contacts.normal.shape[1]
    for c in range(count):
        a = contacts.a[c]
        b = contacts.b[c]
        ln = rows.impulse[c, 0]
        l1 = rows.impulse[c, 1]
        l2 = rows.impulse[c, 2] if dim == 3 else 0.0
        px = ln * rows.n[c, 0] + l1 * rows.t1[c, 0] + l2 * rows.t2[c, 0]
        py = ln * rows.n[c, 1] + l1 * rows.t1[c, 1] + l2 * rows.t2[c, 1]
        pz = ln * rows.n[c, 2] + l1 * rows.t1[c, 2] + l2 * rows.t2[c, 2]
        apply_impulse(rows, c, a, b, px, py, pz, v, w, inv_mass, inv_inertia)
        rows.total_normal[c] += ln
        r1 = rows.impulse[c, 3]
        r2 = rows.impulse[c, 4]
        tw = rows.impulse[c, 5]
        if r1 != 0.0 or r2 != 0.0 or tw != 0.0:
            if dim == 3:
                mx = r1 * rows.t1[c, 0] + r2 * rows.t2[c, 0] + tw * rows.n[c, 0]
                my = r1 * rows.t1[c, 1] + r2 * rows.t2[c, 1] + tw * rows.n[c, 1]
                mz = r1 * rows.t1[c, 2] + r2 * rows.t2[c, 2] + tw * rows.n[c, 2]
            else:
                mx, my, mz = 0.0, 0.0, r1
            apply_angular(a, b, mx, my, mz, w, inv_inertia)


# -- the rows -------------------------------------------------------------------------------------
@njit(**INLINE)
def normal_row(rows, c, a, b, v, w, inv_mass, inv_inertia, acc, col, bias, mass_scale,
               impulse_scale):
    """One projected Gauss-Seidel update of contact c's normal row on the velocities (v, w),
    accumulator acc[c, col]. Returns the applied increment."""
    nx, ny, nz = rows.n[c, 0], rows.n[c, 1], rows.n[c, 2]
    dx, dy, dz = relative_velocity(rows, c, a, b, v, w)
    vn = dx * nx + dy * ny + dz * nz
    old = acc[c, col]
    new = old - rows.normal_mass[c] * (mass_scale * vn + bias) - impulse_scale * old
    if new < 0.0:
        new = 0.0
    d = new - old
    acc[c, col] = new
    apply_impulse(rows, c, a, b, d * nx, d * ny, d * nz, v, w, inv_mass, inv_inertia)
    return d


@njit(**INLINE)
def friction_rows(contacts, rows, c, a, b, v, w, inv_mass, inv_inertia, dim):
    """Coulomb friction of contact c (disc of radius mu lambda_n), then rolling resistance and
    torsional friction when the pair has them. Returns the largest velocity change it made."""
    change = 0.0
    limit = contacts.friction[c] * rows.impulse[c, 0]
    if limit > 0.0 or rows.impulse[c, 1] != 0.0 or rows.impulse[c, 2] != 0.0:
        dx, dy, dz = relative_velocity(rows, c, a, b, v, w)
        vt1 = dx * rows.t1[c, 0] + dy * rows.t1[c, 1] + dz * rows.t1[c, 2]
        o1 = rows.impulse[c, 1]
        i11 = rows.tangent_inv[c, 0]
        if dim == 3:
            vt2 = dx * rows.t2[c, 0] + dy * rows.t2[c, 1] + dz * rows.t2[c, 2]
            i12 = rows.tangent_inv[c, 1]
            i22 = rows.tangent_inv[c, 2]
            o2 = rows.impulse[c, 2]
            n1 = o1 - (i11 * vt1 + i12 * vt2)
            n2 = o2 - (i12 * vt1 + i22 * vt2)
            mag2 = n1 * n1 + n2 * n2
            if mag2 > limit * limit:
                s = limit / np.sqrt(mag2)
                n1 *= s
                n2 *= s
            d1 = n1 - o1
            d2 = n2 - o2
            rows.impulse[c, 1] = n1
            rows.impulse[c, 2] = n2
            px = d1 * rows.t1[c, 0] + d2 * rows.t2[c, 0]
            py = d1 * rows.t1[c, 1] + d2 * rows.t2[c, 1]
            pz = d1 * rows.t1[c, 2] + d2 * rows.t2[c, 2]
            if i11 > 0.0:
                change = max(abs(d1) / i11, abs(d2) / i22)
        else:
            n1 = min(max(o1 - i11 * vt1, -limit), limit)
            d1 = n1 - o1
            rows.impulse[c, 1] = n1
            px = d1 * rows.t1[c, 0]
            py = d1 * rows.t1[c, 1]
            pz = 0.0
            if i11 > 0.0:
                change = abs(d1) / i11
        apply_impulse(rows, c, a, b, px, py, pz, v, w, inv_mass, inv_inertia)
    rolling = contacts.rolling_friction[c]
    if rolling > 0.0:
        limit = rolling * rows.impulse[c, 0]
        sx, sy, sz = relative_spin(a, b, w)
        o1 = rows.impulse[c, 3]
        if dim == 3:
            u1 = sx * rows.t1[c, 0] + sy * rows.t1[c, 1] + sz * rows.t1[c, 2]
            u2 = sx * rows.t2[c, 0] + sy * rows.t2[c, 1] + sz * rows.t2[c, 2]
            o2 = rows.impulse[c, 4]
            n1 = o1 - (rows.rolling_inv[c, 0] * u1 + rows.rolling_inv[c, 1] * u2)
            n2 = o2 - (rows.rolling_inv[c, 1] * u1 + rows.rolling_inv[c, 2] * u2)
            mag2 = n1 * n1 + n2 * n2
            if mag2 > limit * limit:
                s = limit / np.sqrt(mag2)
                n1 *= s
                n2 *= s
            d1 = n1 - o1
            d2 = n2 - o2
            rows.impulse[c, 3] = n1
            rows.impulse[c, 4] = n2
            apply_angular(a, b, d1 * rows.t1[c, 0] + d2 * rows.t2[c, 0],
                          d1 * rows.t1[c, 1] + d2 * rows.t2[c, 1],
                          d1 * rows.t1[c, 2] + d2 * rows.t2[c, 2], w, inv_inertia)
        else:
            n1 = min(max(o1 - rows.rolling_inv[c, 0] * sz, -limit), limit)
            rows.impulse[c, 3] = n1
            apply_angular(a, b, 0.0, 0.0, n1 - o1, w, inv_inertia)
    torsional = contacts.torsional_friction[c] if dim == 3 else 0.0
    if torsional > 0.0:
        limit = torsional * rows.impulse[c, 0]
        sx, sy, sz = relative_spin(a, b, w)
        u = sx * rows.n[c, 0] + sy * rows.n[c, 1] + sz * rows.n[c, 2]
        o = rows.impulse[c, 5]
        n1 = min(max(o - rows.twist_mass[c] * u, -limit), limit)
        rows.impulse[c, 5] = n1
        d = n1 - o
        apply_angular(a, b, d * rows.n[c, 0], d * rows.n[c, 1], d * rows.n[c, 2], w,
                      inv_inertia)
    return change


@njit(**INLINE)
def current_separation(rows, c, a, b, dp, dR):
    """The row's separation after the bodies moved by dp and turned by dR since detection:
    s0 + n . ((dp_b + dR_b rb - rb) - (dp_a + dR_a ra - ra)) (Box2D v3's sub-step update;
    the normal is held fixed)."""
    rax, ray, raz = rows.ra[c, 0], rows.ra[c, 1], rows.ra[c, 2]
    qx, qy, qz = mat_vec(dR, a, rax, ray, raz)
    ex = -(dp[a, 0] + qx - rax)
    ey = -(dp[a, 1] + qy - ray)
    ez = -(dp[a, 2] + qz - raz)
    if b >= 0:
        rbx, rby, rbz = rows.rb[c, 0], rows.rb[c, 1], rows.rb[c, 2]
        qx, qy, qz = mat_vec(dR, b, rbx, rby, rbz)
        ex += dp[b, 0] + qx - rbx
        ey += dp[b, 1] + qy - rby
        ez += dp[b, 2] + qz - rbz
    return rows.separation[c] + ex * rows.n[c, 0] + ey * rows.n[c, 1] + ez * rows.n[c, 2]


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
    for c in range(count):
        s = rows.separation[c]
        vn0 = rows.relative_velocity[c]
        e = contacts.restitution[c]
        if e > 0.0 and vn0 < -threshold:
            dx, dy, dz = relative_velocity(rows, c, contacts.a[c], contacts.b[c], v, w)
            vn1 = dx * rows.n[c, 0] + dy * rows.n[c, 1] + dz * rows.n[c, 2]
            if s + vn1 * h <= 0.0:
                rows.bias[c] = e * vn0
                continue
        rows.bias[c] = s / h if s > 0.0 else 0.0


@njit(**JIT)
def impulse_sweep(contacts, rows, count, v, w, inv_mass, inv_inertia):
    """One sequential_impulse sweep: every normal row (hard, with its bias), then every row's
    friction, rolling and torsion. Returns the largest velocity change of a row (m/s)."""
    dim = contacts.normal.shape[1]
    change = 0.0
    for c in range(count):
        a = contacts.a[c]
        b = contacts.b[c]
        d = normal_row(rows, c, a, b, v, w, inv_mass, inv_inertia, rows.impulse, 0,
                       rows.bias[c], 1.0, 0.0)
        if rows.normal_mass[c] > 0.0:
            change = max(change, abs(d) / rows.normal_mass[c])
    for c in range(count):
        change = max(change, friction_rows(contacts, rows, c, contacts.a[c], contacts.b[c], v, w,
                                           inv_mass, inv_inertia, dim))
    return change


@njit(**JIT)
def split_sweep(contacts, rows, count, vp, wp, inv_mass, inv_inertia, h, baumgarte, slop):
    """One sweep of the split impulse: normal rows on the pseudo-velocities (vp, wp), which move
    the positions of this step only and are then discarded (no energy enters the velocities).
    A row penetrating by more than the slop is driven to vn >= baumgarte (depth - slop) / h; a
    touching row only keeps the pseudo-velocities from pushing deeper; a gap lets them close it."""
    for c in range(count):
        s = rows.separation[c]
        if s > 0.0:
            bias = s / h
        else:
            excess = -s - slop
            bias = -baumgarte * excess / h if excess > 0.0 else 0.0
        normal_row(rows, c, contacts.a[c], contacts.b[c], vp, wp, inv_mass, inv_inertia,
                   rows.pseudo, 0, bias, 1.0, 0.0)


@njit(**JIT)
def soft_sweep(contacts, rows, count, v, w, inv_mass, inv_inertia, dp, dR, inv_h, use_bias,
               contact_soft, static_soft, push_speed):
    """One soft_step sweep (Box2D v3's b2SolveContact): each normal row with the separation
    updated from the bodies' motion since detection: a gap gives the speculative bias s / h; an
    overlap, with ``use_bias``, the soft push max(mass_scale bias_rate s, -push_speed) with the
    soft mass and impulse scales (static contacts twice as stiff); without it (relax) a rigid
    row. Then friction, rolling and torsion."""
    dim = contacts.normal.shape[1]
    for c in range(count):
        a = contacts.a[c]
        b = contacts.b[c]
        s = current_separation(rows, c, a, b, dp, dR)
        if s > 0.0:
            bias, mass_scale, impulse_scale = s * inv_h, 1.0, 0.0
        elif use_bias:
            soft = static_soft if b < 0 else contact_soft
            mass_scale, impulse_scale = soft[1], soft[2]
            bias = max(mass_scale * soft[0] * s, -push_speed)
        else:
            bias, mass_scale, impulse_scale = 0.0, 1.0, 0.0
        d = normal_row(rows, c, a, b, v, w, inv_mass, inv_inertia, rows.impulse, 0, bias,
                       mass_scale, impulse_scale)
        rows.total_normal[c] += d
    for c in range(count):
        friction_rows(contacts, rows, c, contacts.a[c], contacts.b[c], v, w, inv_mass,
                      inv_inertia, dim)


@njit(**JIT)
def restitution_pass(contacts, rows, count, v, w, inv_mass, inv_inertia, threshold):
    """soft_step's restitution (Box2D v3, after the sub-steps): a row that approached faster
    than the threshold when prepared and took a normal impulse this step is driven to
    vn = -e vn0 (the accumulated impulse kept >= 0)."""
    for c in range(count):
        e = contacts.restitution[c]
        if e == 0.0 or rows.relative_velocity[c] > -threshold or rows.total_normal[c] == 0.0:
            continue
        d = normal_row(rows, c, contacts.a[c], contacts.b[c], v, w, inv_mass, inv_inertia,
                       rows.impulse, 0, e * rows.relative_velocity[c], 1.0, 0.0)
        rows.total_normal[c] += d
