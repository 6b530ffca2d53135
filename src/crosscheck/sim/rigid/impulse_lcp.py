"""The ``impulse_lcp`` contact model: Baraff's event-driven rigid contact ("Physically based
modeling", the collision and resting-contact notes), with the integrator of the run.

One step of size h from the state y (``ImpulseLcpStepper.step``), repeated until the step is
done (each pass a *sub-step*):

1. **Detect** at y. A row is *in contact* when its depth is at least ``-contact_tolerance``.
2. **Colliding contact** (rows in contact with the bodies approaching, ``v_n < 0``): impulses
   with the pair's restitution, applied at once to the velocities (``collision_impulses3d``).
   The simultaneous impulses solve the impulse LCP by projected Gauss-Seidel: normal impulses
   ``j_n >= 0`` with ``v_n+ >= -e v_n-`` (``e`` applied when ``v_n- < -bounce_threshold``, else
   0, which ends a Zeno sequence of ever smaller bounces: the default ``2 |g| h`` leaves bounces
   below ``2 e^2 g h^2`` unresolved, 20 um at h = 1e-3) complementary to each other, friction
   impulses in the Coulomb disc ``|j_t| <= mu j_n`` with target ``v_t+ = 0``, to the stated
   tolerance. ``collision = "sequential"`` resolves instead one contact at a time, the most
   approaching first, each with its own restitution (Baraff's propagation): a touching Newton's
   cradle then passes the momentum on (0, 0, 1) where the simultaneous LCP spreads it
   (-1/3, 2/3, 2/3).
3. **Resting contact**: the rows in contact after the impulses form the *active set* (by feature
   key). During the sub-step every force evaluation of the integrator solves the
   acceleration-level LCP of the active rows (re-detected at the stage's positions) with
   Coulomb friction and adds the contact forces to the smooth ones (``resting_wrench3d``):
   ``a_n >= -2 alpha v_n + alpha^2 d`` (Baumgarte's stabilisation of the constraint drift,
   ``alpha = 1 / (stabilisation_steps h)``) complementary to ``f_n >= 0``; tangential target
   ``a_t = -v_t / h`` (stick within the step) with ``|f_t| <= mu f_n`` (slides at mu f_n
   otherwise), solved by projected Gauss-Seidel warm started from the last evaluation, until the
   largest change of a force in a sweep is below ``lcp_tolerance`` times the largest force (or
   ``lcp_iterations`` sweeps).
4. **Integrate** the sub-step with the run's integrator (any explicit one; contact forces enter
   as forces, the integrator's kernels are unchanged). The sub-step is at most h and at most the
   time in which no body moves (``|v| + |w| R``) by more than ``advance_fraction`` times its
   inner radius (conservative advancement: a fast ball cannot pass a wall between two
   detections; tunnelling.toml).
5. **Time of impact**: when a row *not* in the active set ends the sub-step deeper than
   ``penetration_tolerance``, the sub-step is bisected from its start until it ends with every
   such row no deeper than that and at least one within ``contact_tolerance``: the bodies then
   touch to within that band, and step 2 of the next pass applies the collision impulse there.

Without collisions the cost is the integrator's plus one detection per sub-step and the LCP at
every force evaluation. The loop over sub-steps is Python over compiled kernels; nothing is
allocated per step. Deterministic: every loop runs in a fixed order.
"""

from __future__ import annotations

import math
from typing import Any, NamedTuple

import numpy as np
from numba import njit

from crosscheck.sim._jit import INLINE, JIT
from crosscheck.sim.rigid.contact_detect import detect2d, detect3d
from crosscheck.sim.rigid.contact_table import (
    FeatureTable,
    table_find,
    table_flip,
    table_insert,
)
from crosscheck.sim.rigid.lcp import Dense, lcp_solve
from crosscheck.sim.rigid.math3d import quat_to_rotation

# par indices
(R_TOL_C, R_TOL_P, R_ALPHA, R_BETA, R_ITER, R_LCP_TOL, R_BOUNCE, R_SEQUENTIAL,
 R_IMP_ITER, R_IMPACT) = range(10)
N_PAR = 10

PARAMETERS: dict[str, tuple[Any, str]] = {
    "contact_tolerance": (1e-5, "m: rows at least this close are in contact (impulses, active "
                                "set); the time-of-impact band's lower side"),
    "penetration_tolerance": (1e-5, "m: a new contact deeper than this at a sub-step's end is "
                                    "bisected back to its time of impact"),
    "collision": ("simultaneous", "'simultaneous' (the impulse LCP, projected Gauss-Seidel) or "
                                  "'sequential' (one contact at a time, Baraff's propagation)"),
    "bounce_threshold": (None, "m/s: restitution applies to approach speeds above it (default "
                               "2 |g| h; 0 without gravity)"),
    "stabilisation_steps": (10.0, "Baumgarte rate alpha = 1 / (this h) on the resting "
                                  "constraint's drift"),
    "lcp_iterations": (500, "largest number of projected Gauss-Seidel sweeps per solve"),
    "lcp_tolerance": (1e-6, "a solve stops when no force or impulse changes by more than this "
                             "times the largest one in a sweep"),
    "direct_rows": (128, "problems of up to this many contact rows have their normal forces "
                         "solved exactly (principal pivoting, lcp.py); larger ones by projected "
                         "Gauss-Seidel"),
    "advance_fraction": (1.0, "conservative advancement: no body moves more than this times its "
                              "inner radius in a sub-step"),
    "capacity": (0, "contact rows (0: from the scene)"),
}


class RestingContacts(NamedTuple):
    """The ``contacts`` argument of the force pass for the resting contacts (3D and 2D)."""

    geometry: Any
    buf: Any  # sim.collide.Contacts
    active: FeatureTable  # the active set; value (3): warm-start forces (n, t1, t2)
    par: np.ndarray  # (N_PAR,)
    h: np.ndarray  # (1,) the sub-step being integrated
    rows: Any  # RowScratch
    lin: np.ndarray  # (N, d) linear acceleration / velocity of the solve
    ang: np.ndarray  # (N, 3) or (N,) angular
    iinv: np.ndarray  # (N, 3, 3) world inverse inertia (3D) or (N,) (2D)
    dense: Dense  # the direct solver's scratch (lcp.py)


class RowScratch(NamedTuple):
    index: np.ndarray  # (C,) int64: buffer row of solver row k
    u: np.ndarray  # (C, 3, d): n, t1, t2 (2D: n, t)
    ra: np.ndarray  # (C, d)
    rb: np.ndarray  # (C, d)
    resp_a: np.ndarray  # (C, 3, 3) or (C, 2): I_a^-1 (r_a x u)
    resp_b: np.ndarray
    k: np.ndarray  # (C, 3): 1 / (u . effective inverse mass u)
    target: np.ndarray  # (C, 3)
    bias: np.ndarray  # (C, 3): constant part of the relative motion along u (centripetal)
    lam: np.ndarray  # (C, 3): forces or impulses
    mu: np.ndarray  # (C,)


def _scratch(capacity: int, n_bodies: int, d: int) -> RowScratch:
    c = capacity
    resp = (c, 3, 3) if d == 3 else (c, 2)
    return RowScratch(np.zeros(c, np.int64), np.zeros((c, 3, d)), np.zeros((c, d)),
                      np.zeros((c, d)), np.zeros(resp), np.zeros(resp), np.zeros((c, 3)),
                      np.zeros((c, 3)), np.zeros((c, 3)), np.zeros((c, 3)), np.zeros(c))


# -- 3D rows --------------------------------------------------------------------------------------
@njit(**INLINE)
def world_inverse_inertia3d(bodies, q, iinv):
    for i in range(q.shape[0]):
        r00, r01, r02, r10, r11, r12, r20, r21, r22 = quat_to_rotation(q[i, 0], q[i, 1], q[i, 2],
                                                                       q[i, 3])
        a = bodies.inv_inertia[i]
        # R A R^T
        m00 = r00 * a[0, 0] + r01 * a[1, 0] + r02 * a[2, 0]
        m01 = r00 * a[0, 1] + r01 * a[1, 1] + r02 * a[2, 1]
        m02 = r00 * a[0, 2] + r01 * a[1, 2] + r02 * a[2, 2]
        m10 = r10 * a[0, 0] + r11 * a[1, 0] + r12 * a[2, 0]
        m11 = r10 * a[0, 1] + r11 * a[1, 1] + r12 * a[2, 1]
        m12 = r10 * a[0, 2] + r11 * a[1, 2] + r12 * a[2, 2]
        m20 = r20 * a[0, 0] + r21 * a[1, 0] + r22 * a[2, 0]
        m21 = r20 * a[0, 1] + r21 * a[1, 1] + r22 * a[2, 1]
        m22 = r20 * a[0, 2] + r21 * a[1, 2] + r22 * a[2, 2]
        iinv[i, 0, 0] = m00 * r00 + m01 * r01 + m02 * r02
        iinv[i, 0, 1] = m00 * r10 + m01 * r11 + m02 * r12
        iinv[i, 0, 2] = m00 * r20 + m01 * r21 + m02 * r22
        iinv[i, 1, 0] = m10 * r00 + m11 * r01 + m12 * r02
        iinv[i, 1, 1] = m10 * r10 + m11 * r11 + m12 * r12
        iinv[i, 1, 2] = m10 * r20 + m11 * r21 + m12 * r22
        iinv[i, 2, 0] = m20 * r00 + m21 * r01 + m22 * r02
        iinv[i, 2, 1] = m20 * r10 + m21 * r11 + m22 * r12
        iinv[i, 2, 2] = m20 * r20 + m21 * r21 + m22 * r22


@njit(**INLINE)
def _cross(ax, ay, az, bx, by, bz):
    return ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx


@njit(**INLINE)
def _mat(iinv, i, x, y, z):
    return (iinv[i, 0, 0] * x + iinv[i, 0, 1] * y + iinv[i, 0, 2] * z,
            iinv[i, 1, 0] * x + iinv[i, 1, 1] * y + iinv[i, 1, 2] * z,
            iinv[i, 2, 0] * x + iinv[i, 2, 1] * y + iinv[i, 2, 2] * z)


@njit(**INLINE)
def _point_velocity3d(x, v, w, i, px, py, pz):
    rx, ry, rz = px - x[i, 0], py - x[i, 1], pz - x[i, 2]
    return (v[i, 0] + w[i, 1] * rz - w[i, 2] * ry, v[i, 1] + w[i, 2] * rx - w[i, 0] * rz,
            v[i, 2] + w[i, 0] * ry - w[i, 1] * rx)


@njit(**INLINE)
def setup_row3d(bodies, buf, r, k, rows, x, v, w, iinv):
    """Solver row k from buffer row r: lever arms, basis (n, t1 along the slip, t2), angular
    responses and effective masses; returns the relative velocity (n, t1, t2 components)."""
    a = buf.a[r]
    b = buf.b[r]
    nx, ny, nz = buf.normal[r, 0], buf.normal[r, 1], buf.normal[r, 2]
    px, py, pz = buf.point[r, 0], buf.point[r, 1], buf.point[r, 2]
    rows.index[k] = r
    rows.mu[k] = buf.friction[r]
    rows.ra[k, 0], rows.ra[k, 1], rows.ra[k, 2] = px - x[a, 0], py - x[a, 1], pz - x[a, 2]
    vax, vay, vaz = _point_velocity3d(x, v, w, a, px, py, pz)
    vbx = vby = vbz = 0.0
    if b >= 0:
        rows.rb[k, 0], rows.rb[k, 1], rows.rb[k, 2] = px - x[b, 0], py - x[b, 1], pz - x[b, 2]
        vbx, vby, vbz = _point_velocity3d(x, v, w, b, px, py, pz)
    dvx, dvy, dvz = vbx - vax, vby - vay, vbz - vaz
    vn = dvx * nx + dvy * ny + dvz * nz
    tx, ty, tz = dvx - vn * nx, dvy - vn * ny, dvz - vn * nz
    vt = np.sqrt(tx * tx + ty * ty + tz * tz)
    if vt > 1e-12:
        tx, ty, tz = tx / vt, ty / vt, tz / vt
    else:  # any unit vector perpendicular to n
        if abs(nx) < 0.57735:
            tx, ty, tz = _cross(nx, ny, nz, 1.0, 0.0, 0.0)
        else:
            tx, ty, tz = _cross(nx, ny, nz, 0.0, 1.0, 0.0)
        s = 1.0 / np.sqrt(tx * tx + ty * ty + tz * tz)
        tx, ty, tz = tx * s, ty * s, tz * s
    sx, sy, sz = _cross(nx, ny, nz, tx, ty, tz)
    u = rows.u
    u[k, 0, 0], u[k, 0, 1], u[k, 0, 2] = nx, ny, nz
    u[k, 1, 0], u[k, 1, 1], u[k, 1, 2] = tx, ty, tz
    u[k, 2, 0], u[k, 2, 1], u[k, 2, 2] = sx, sy, sz
    ima = bodies.inv_mass[a]
    imb = bodies.inv_mass[b] if b >= 0 else 0.0
    for j in range(3):
        ux, uy, uz = u[k, j, 0], u[k, j, 1], u[k, j, 2]
        cx, cy, cz = _cross(rows.ra[k, 0], rows.ra[k, 1], rows.ra[k, 2], ux, uy, uz)
        gx, gy, gz = _mat(iinv, a, cx, cy, cz)
        rows.resp_a[k, j, 0], rows.resp_a[k, j, 1], rows.resp_a[k, j, 2] = gx, gy, gz
        kk = ima + cx * gx + cy * gy + cz * gz
        if b >= 0:
            cx, cy, cz = _cross(rows.rb[k, 0], rows.rb[k, 1], rows.rb[k, 2], ux, uy, uz)
            gx, gy, gz = _mat(iinv, b, cx, cy, cz)
            rows.resp_b[k, j, 0], rows.resp_b[k, j, 1], rows.resp_b[k, j, 2] = gx, gy, gz
            kk += imb + cx * gx + cy * gy + cz * gz
        rows.k[k, j] = 1.0 / kk
    return vn, vt, 0.0


@njit(**INLINE)
def _relative3d(buf, rows, k, j, lin, ang):
    """u_j . (motion of b's point - motion of a's point) from the bodies' lin / ang arrays."""
    r = rows.index[k]
    a = buf.a[r]
    b = buf.b[r]
    ux, uy, uz = rows.u[k, j, 0], rows.u[k, j, 1], rows.u[k, j, 2]
    ra = rows.ra[k]
    cx, cy, cz = _cross(ang[a, 0], ang[a, 1], ang[a, 2], ra[0], ra[1], ra[2])
    s = -((lin[a, 0] + cx) * ux + (lin[a, 1] + cy) * uy + (lin[a, 2] + cz) * uz)
    if b >= 0:
        rb = rows.rb[k]
        cx, cy, cz = _cross(ang[b, 0], ang[b, 1], ang[b, 2], rb[0], rb[1], rb[2])
        s += (lin[b, 0] + cx) * ux + (lin[b, 1] + cy) * uy + (lin[b, 2] + cz) * uz
    return s + rows.bias[k, j]


@njit(**INLINE)
def _apply3d(bodies, buf, rows, k, j, dl, lin, ang):
    """The bodies' lin / ang after a change dl of row k's force (impulse) along u_j."""
    r = rows.index[k]
    a = buf.a[r]
    b = buf.b[r]
    ux, uy, uz = rows.u[k, j, 0], rows.u[k, j, 1], rows.u[k, j, 2]
    ima = bodies.inv_mass[a] * dl
    lin[a, 0] -= ima * ux
    lin[a, 1] -= ima * uy
    lin[a, 2] -= ima * uz
    ang[a, 0] -= rows.resp_a[k, j, 0] * dl
    ang[a, 1] -= rows.resp_a[k, j, 1] * dl
    ang[a, 2] -= rows.resp_a[k, j, 2] * dl
    if b >= 0:
        imb = bodies.inv_mass[b] * dl
        lin[b, 0] += imb * ux
        lin[b, 1] += imb * uy
        lin[b, 2] += imb * uz
        ang[b, 0] += rows.resp_b[k, j, 0] * dl
        ang[b, 1] += rows.resp_b[k, j, 1] * dl
        ang[b, 2] += rows.resp_b[k, j, 2] * dl


# pgs3d and friction_sweep3d are calls from solve3d, not inlined into it: the one runs once per
# solve, the other once per outer iteration, and the three compile in 19 s where solve3d with
# both inlined took 31 s (docs/inhouse.md, "Compile time"). The same holds in 2D.
@njit(**JIT)
def pgs3d(bodies, buf, rows, m, lin, ang, iterations, tol):
    """Projected Gauss-Seidel over solver rows 0..m-1: normal ``lam_n >= 0`` with relative motion
    along n at least ``target_n``, friction ``(lam_t1, lam_t2)`` towards ``target_t`` in the disc
    of radius mu lam_n; lin / ang updated with every change (they hold the effect of ``rows.lam``
    on entry: solve3d applies it). Returns the sweeps taken."""
    lam = rows.lam
    sweeps = 0
    for it in range(iterations):
        sweeps = it + 1
        change = 0.0
        largest = 0.0
        for k in range(m):
            cur = _relative3d(buf, rows, k, 0, lin, ang)
            new = lam[k, 0] + (rows.target[k, 0] - cur) * rows.k[k, 0]
            if new < 0.0:
                new = 0.0
            dl = new - lam[k, 0]
            if dl != 0.0:
                _apply3d(bodies, buf, rows, k, 0, dl, lin, ang)
                lam[k, 0] = new
            change = max(change, abs(dl))
            largest = max(largest, new)
            limit = rows.mu[k] * new
            t1 = lam[k, 1] + (rows.target[k, 1] - _relative3d(buf, rows, k, 1, lin, ang)) \
                * rows.k[k, 1]
            t2 = lam[k, 2] + (rows.target[k, 2] - _relative3d(buf, rows, k, 2, lin, ang)) \
                * rows.k[k, 2]
            mag = np.sqrt(t1 * t1 + t2 * t2)
            if mag > limit:
                s = limit / mag if mag > 0.0 else 0.0
                t1 *= s
                t2 *= s
            d1 = t1 - lam[k, 1]
            d2 = t2 - lam[k, 2]
            if d1 != 0.0:
                _apply3d(bodies, buf, rows, k, 1, d1, lin, ang)
                lam[k, 1] = t1
            if d2 != 0.0:
                _apply3d(bodies, buf, rows, k, 2, d2, lin, ang)
                lam[k, 2] = t2
            change = max(change, abs(d1), abs(d2))
        if change <= tol * largest or largest == 0.0:
            break
    return sweeps


# -- resting contact forces (3D) ------------------------------------------------------------------
@njit(**JIT)
def resting_forces3d(bodies, rc, x, q, L, v, w, F, T):
    buf = rc.buf
    par = rc.par
    rows = rc.rows
    lin = rc.lin
    ang = rc.ang
    iinv = rc.iinv
    active = rc.active
    cur = active.current[0]
    h = rc.h[0]
    alpha = 1.0 / (par[R_ALPHA] * h)
    beta = 1.0 / h
    nb = x.shape[0]
    world_inverse_inertia3d(bodies, q, iinv)
    for i in range(nb):  # free accelerations: a = F / m, dw/dt = I^-1 (tau - w x L)
        im = bodies.inv_mass[i]
        lin[i, 0], lin[i, 1], lin[i, 2] = F[i, 0] * im, F[i, 1] * im, F[i, 2] * im
        gx, gy, gz = _cross(w[i, 0], w[i, 1], w[i, 2], L[i, 0], L[i, 1], L[i, 2])
        ang[i, 0], ang[i, 1], ang[i, 2] = _mat(iinv, i, T[i, 0] - gx, T[i, 1] - gy, T[i, 2] - gz)
    m = np.int64(0)  # not a literal 0 (sim/_jit.py: "Literal arguments")
    for r in range(buf.count[0]):
        slot = table_find(active, cur, buf.feature[r])
        if slot < 0 and table_find(active, cur, pair_key(buf.feature[r])) < 0:
            continue
        vn, vt, _ = setup_row3d(bodies, buf, r, m, rows, x, v, w, iinv)
        if slot < 0 and vn < -par[R_IMPACT]:
            continue  # a new point of a touching pair that strikes: an event, not resting
        # No centripetal term w x (w x r): at a curved surface the contact point is not a
        # material point, and the gap's second derivative lacks it (a rolling sphere's contact
        # point accelerates towards the centre at w^2 r while the gap stays 0); at a vertex the
        # term is O(w^2 r) and Baumgarte's feedback takes care of it.
        rows.bias[m, 0] = rows.bias[m, 1] = rows.bias[m, 2] = 0.0
        rows.target[m, 0] = -2.0 * alpha * vn + alpha * alpha * buf.depth[r]
        rows.target[m, 1] = -beta * vt
        rows.target[m, 2] = 0.0
        # warm start from the last solve (stored per feature in the world frame's n, t1, t2
        # magnitudes: the normal force, and the friction's magnitude along the new t1)
        rows.lam[m, 0] = rows.lam[m, 1] = rows.lam[m, 2] = 0.0
        if slot >= 0:
            val = active.value[cur, slot]
            rows.lam[m, 0] = val[0]
            rows.lam[m, 1] = val[1] * rows.u[m, 1, 0] + val[2] * rows.u[m, 1, 1] \
                + val[3] * rows.u[m, 1, 2]
            rows.lam[m, 2] = val[1] * rows.u[m, 2, 0] + val[2] * rows.u[m, 2, 1] \
                + val[3] * rows.u[m, 2, 2]
        m += 1
    if m == 0:
        return
    solve3d(bodies, buf, rows, m, lin, ang, int(par[R_ITER]), par[R_LCP_TOL], rc.dense)
    for k in range(m):
        r = rows.index[k]
        a = buf.a[r]
        b = buf.b[r]
        fx = fy = fz = 0.0
        for j in range(3):
            fx += rows.lam[k, j] * rows.u[k, j, 0]
            fy += rows.lam[k, j] * rows.u[k, j, 1]
            fz += rows.lam[k, j] * rows.u[k, j, 2]
        ra = rows.ra[k]
        F[a, 0] -= fx
        F[a, 1] -= fy
        F[a, 2] -= fz
        tx, ty, tz = _cross(ra[0], ra[1], ra[2], fx, fy, fz)
        T[a, 0] -= tx
        T[a, 1] -= ty
        T[a, 2] -= tz
        if b >= 0:
            rb = rows.rb[k]
            F[b, 0] += fx
            F[b, 1] += fy
            F[b, 2] += fz
            tx, ty, tz = _cross(rb[0], rb[1], rb[2], fx, fy, fz)
            T[b, 0] += tx
            T[b, 1] += ty
            T[b, 2] += tz
        slot = table_find(active, cur, buf.feature[r])
        if slot < 0:
            continue
        active.value[cur, slot, 0] = rows.lam[k, 0]
        for c in range(3):  # the friction force, world frame (warm start of the next solve)
            active.value[cur, slot, 1 + c] = (rows.lam[k, 1] * rows.u[k, 1, c]
                                              + rows.lam[k, 2] * rows.u[k, 2, c])


@njit(**INLINE)
def resting_wrench3d(bodies, rc, x, q, L, v, w, F, T):
    detect3d(rc.geometry, x, q, rc.buf)
    resting_forces3d(bodies, rc, x, q, L, v, w, F, T)


# -- collision impulses (3D) ----------------------------------------------------------------------
@njit(**JIT)
def collision_impulses3d(bodies, rc, x, q, P, L):
    """Impulses at the rows in contact that approach (see the module docstring); P, L updated in
    place. Returns the number of colliding rows (0: nothing done)."""
    buf = rc.buf
    par = rc.par
    rows = rc.rows
    v = rc.lin
    w = rc.ang
    iinv = rc.iinv
    nb = x.shape[0]
    world_inverse_inertia3d(bodies, q, iinv)
    for i in range(nb):
        im = bodies.inv_mass[i]
        v[i, 0], v[i, 1], v[i, 2] = P[i, 0] * im, P[i, 1] * im, P[i, 2] * im
        w[i, 0], w[i, 1], w[i, 2] = _mat(iinv, i, L[i, 0], L[i, 1], L[i, 2])
    # the velocities before, kept in P / L's units for the update at the end
    tol_c = par[R_TOL_C]
    bounce = par[R_BOUNCE]
    m = np.int64(0)  # not a literal 0 (sim/_jit.py: "Literal arguments")
    colliding = 0
    for r in range(buf.count[0]):
        if buf.depth[r] < -tol_c:
            continue
        vn, vt, _ = setup_row3d(bodies, buf, r, m, rows, x, v, w, iinv)
        e = buf.restitution[r] if vn < -bounce else 0.0
        rows.target[m, 0] = -e * vn if vn < 0.0 else 0.0
        rows.target[m, 1] = 0.0
        rows.target[m, 2] = 0.0
        rows.bias[m, 0] = rows.bias[m, 1] = rows.bias[m, 2] = 0.0
        rows.lam[m, 0] = rows.lam[m, 1] = rows.lam[m, 2] = 0.0
        if vn < -par[R_IMPACT]:
            colliding += 1
        m += 1
    if colliding == 0:
        return 0
    if par[R_SEQUENTIAL] != 0.0:
        _sequential3d(bodies, buf, rows, m, v, w, bounce, int(par[R_IMP_ITER]))
    else:
        solve3d(bodies, buf, rows, m, v, w, int(par[R_IMP_ITER]), par[R_LCP_TOL], rc.dense)
    # P, L from the summed impulses (exact momentum bookkeeping: equal and opposite)
    for k in range(m):
        r = rows.index[k]
        a = buf.a[r]
        b = buf.b[r]
        jx = jy = jz = 0.0
        for j in range(3):
            jx += rows.lam[k, j] * rows.u[k, j, 0]
            jy += rows.lam[k, j] * rows.u[k, j, 1]
            jz += rows.lam[k, j] * rows.u[k, j, 2]
        if jx == 0.0 and jy == 0.0 and jz == 0.0:
            continue
        ra = rows.ra[k]
        P[a, 0] -= jx
        P[a, 1] -= jy
        P[a, 2] -= jz
        tx, ty, tz = _cross(ra[0], ra[1], ra[2], jx, jy, jz)
        L[a, 0] -= tx
        L[a, 1] -= ty
        L[a, 2] -= tz
        if b >= 0:
            rb = rows.rb[k]
            P[b, 0] += jx
            P[b, 1] += jy
            P[b, 2] += jz
            tx, ty, tz = _cross(rb[0], rb[1], rb[2], jx, jy, jz)
            L[b, 0] += tx
            L[b, 1] += ty
            L[b, 2] += tz
    return colliding


@njit(**INLINE)
def _sequential3d(bodies, buf, rows, m, v, w, bounce, iterations):
    """Baraff's propagation: repeatedly the most approaching row gets its own impulse (its
    restitution on its current approach speed, friction in the disc), until none approaches."""
    for _ in range(iterations):
        worst = -1
        worst_vn = 0.0
        for k in range(m):
            vn = _relative3d(buf, rows, k, 0, v, w)
            if vn < worst_vn:
                worst_vn = vn
                worst = k
        if worst < 0 or worst_vn > -1e-14:
            return
        k = worst
        e = buf.restitution[rows.index[k]] if worst_vn < -bounce else 0.0
        jn = -(1.0 + e) * worst_vn * rows.k[k, 0]
        _apply3d(bodies, buf, rows, k, 0, jn, v, w)
        rows.lam[k, 0] += jn
        limit = rows.mu[k] * jn
        t1 = -_relative3d(buf, rows, k, 1, v, w) * rows.k[k, 1]
        t2 = -_relative3d(buf, rows, k, 2, v, w) * rows.k[k, 2]
        mag = np.sqrt(t1 * t1 + t2 * t2)
        if mag > limit:
            s = limit / mag if mag > 0.0 else 0.0
            t1 *= s
            t2 *= s
        _apply3d(bodies, buf, rows, k, 1, t1, v, w)
        _apply3d(bodies, buf, rows, k, 2, t2, v, w)
        rows.lam[k, 1] += t1
        rows.lam[k, 2] += t2


# -- 2D -------------------------------------------------------------------------------------------
@njit(**INLINE)
def setup_row2d(bodies, buf, r, k, rows, x, v, w):
    a = buf.a[r]
    b = buf.b[r]
    nx, ny = buf.normal[r, 0], buf.normal[r, 1]
    px, py = buf.point[r, 0], buf.point[r, 1]
    rows.index[k] = r
    rows.mu[k] = buf.friction[r]
    rax, ray = px - x[a, 0], py - x[a, 1]
    rows.ra[k, 0], rows.ra[k, 1] = rax, ray
    vax, vay = v[a, 0] - w[a] * ray, v[a, 1] + w[a] * rax
    vbx = vby = 0.0
    rbx = rby = 0.0
    if b >= 0:
        rbx, rby = px - x[b, 0], py - x[b, 1]
        rows.rb[k, 0], rows.rb[k, 1] = rbx, rby
        vbx, vby = v[b, 0] - w[b] * rby, v[b, 1] + w[b] * rbx
    dvx, dvy = vbx - vax, vby - vay
    tx, ty = -ny, nx
    vn = dvx * nx + dvy * ny
    vt = dvx * tx + dvy * ty
    u = rows.u
    u[k, 0, 0], u[k, 0, 1] = nx, ny
    u[k, 1, 0], u[k, 1, 1] = tx, ty
    u[k, 2, 0], u[k, 2, 1] = 0.0, 0.0
    ima = bodies.inv_mass[a]
    for j in range(2):
        ux, uy = u[k, j, 0], u[k, j, 1]
        ca = rax * uy - ray * ux
        rows.resp_a[k, j] = bodies.inv_moment[a] * ca
        kk = ima + ca * rows.resp_a[k, j]
        if b >= 0:
            cb = rbx * uy - rby * ux
            rows.resp_b[k, j] = bodies.inv_moment[b] * cb
            kk += bodies.inv_mass[b] + cb * rows.resp_b[k, j]
        rows.k[k, j] = 1.0 / kk
    rows.k[k, 2] = 0.0
    return vn, vt


@njit(**INLINE)
def _relative2d(buf, rows, k, j, lin, ang):
    r = rows.index[k]
    a = buf.a[r]
    b = buf.b[r]
    ux, uy = rows.u[k, j, 0], rows.u[k, j, 1]
    ra = rows.ra[k]
    s = -((lin[a, 0] - ang[a] * ra[1]) * ux + (lin[a, 1] + ang[a] * ra[0]) * uy)
    if b >= 0:
        rb = rows.rb[k]
        s += (lin[b, 0] - ang[b] * rb[1]) * ux + (lin[b, 1] + ang[b] * rb[0]) * uy
    return s + rows.bias[k, j]


@njit(**INLINE)
def _apply2d(bodies, buf, rows, k, j, dl, lin, ang):
    r = rows.index[k]
    a = buf.a[r]
    b = buf.b[r]
    ux, uy = rows.u[k, j, 0], rows.u[k, j, 1]
    ima = bodies.inv_mass[a] * dl
    lin[a, 0] -= ima * ux
    lin[a, 1] -= ima * uy
    ang[a] -= rows.resp_a[k, j] * dl
    if b >= 0:
        imb = bodies.inv_mass[b] * dl
        lin[b, 0] += imb * ux
        lin[b, 1] += imb * uy
        ang[b] += rows.resp_b[k, j] * dl


@njit(**JIT)
def pgs2d(bodies, buf, rows, m, lin, ang, iterations, tol):
    """pgs3d in 2D (lin / ang hold the effect of ``rows.lam`` on entry: solve2d applies it)."""
    lam = rows.lam
    sweeps = 0
    for it in range(iterations):
        sweeps = it + 1
        change = 0.0
        largest = 0.0
        for k in range(m):
            cur = _relative2d(buf, rows, k, 0, lin, ang)
            new = lam[k, 0] + (rows.target[k, 0] - cur) * rows.k[k, 0]
            if new < 0.0:
                new = 0.0
            dl = new - lam[k, 0]
            if dl != 0.0:
                _apply2d(bodies, buf, rows, k, 0, dl, lin, ang)
                lam[k, 0] = new
            change = max(change, abs(dl))
            largest = max(largest, new)
            limit = rows.mu[k] * new
            t1 = lam[k, 1] + (rows.target[k, 1] - _relative2d(buf, rows, k, 1, lin, ang)) \
                * rows.k[k, 1]
            if t1 > limit:
                t1 = limit
            elif t1 < -limit:
                t1 = -limit
            d1 = t1 - lam[k, 1]
            if d1 != 0.0:
                _apply2d(bodies, buf, rows, k, 1, d1, lin, ang)
                lam[k, 1] = t1
            change = max(change, abs(d1))
        if change <= tol * largest or largest == 0.0:
            break
    return sweeps


@njit(**JIT)
def resting_forces2d(bodies, rc, x, angle, L, v, w, F, T):
    buf = rc.buf
    par = rc.par
    rows = rc.rows
    lin = rc.lin
    ang = rc.ang
    active = rc.active
    cur = active.current[0]
    h = rc.h[0]
    alpha = 1.0 / (par[R_ALPHA] * h)
    beta = 1.0 / h
    for i in range(x.shape[0]):
        lin[i, 0] = F[i, 0] * bodies.inv_mass[i]
        lin[i, 1] = F[i, 1] * bodies.inv_mass[i]
        ang[i] = T[i] * bodies.inv_moment[i]
    m = np.int64(0)  # not a literal 0 (sim/_jit.py: "Literal arguments")
    for r in range(buf.count[0]):
        slot = table_find(active, cur, buf.feature[r])
        if slot < 0 and table_find(active, cur, pair_key(buf.feature[r])) < 0:
            continue
        vn, vt = setup_row2d(bodies, buf, r, m, rows, x, v, w)
        if slot < 0 and vn < -par[R_IMPACT]:
            continue
        rows.bias[m, 0] = rows.bias[m, 1] = rows.bias[m, 2] = 0.0  # no centripetal (3D)
        rows.target[m, 0] = -2.0 * alpha * vn + alpha * alpha * buf.depth[r]
        rows.target[m, 1] = -beta * vt
        rows.lam[m, 0] = rows.lam[m, 1] = rows.lam[m, 2] = 0.0
        if slot >= 0:
            rows.lam[m, 0] = active.value[cur, slot, 0]
            rows.lam[m, 1] = (active.value[cur, slot, 1] * rows.u[m, 1, 0]
                              + active.value[cur, slot, 2] * rows.u[m, 1, 1])
        m += 1
    if m == 0:
        return
    solve2d(bodies, buf, rows, m, lin, ang, int(par[R_ITER]), par[R_LCP_TOL], rc.dense)
    for k in range(m):
        r = rows.index[k]
        a = buf.a[r]
        b = buf.b[r]
        fx = rows.lam[k, 0] * rows.u[k, 0, 0] + rows.lam[k, 1] * rows.u[k, 1, 0]
        fy = rows.lam[k, 0] * rows.u[k, 0, 1] + rows.lam[k, 1] * rows.u[k, 1, 1]
        ra = rows.ra[k]
        F[a, 0] -= fx
        F[a, 1] -= fy
        T[a] -= ra[0] * fy - ra[1] * fx
        if b >= 0:
            rb = rows.rb[k]
            F[b, 0] += fx
            F[b, 1] += fy
            T[b] += rb[0] * fy - rb[1] * fx
        slot = table_find(active, cur, buf.feature[r])
        if slot < 0:
            continue
        active.value[cur, slot, 0] = rows.lam[k, 0]
        active.value[cur, slot, 1] = rows.lam[k, 1] * rows.u[k, 1, 0]
        active.value[cur, slot, 2] = rows.lam[k, 1] * rows.u[k, 1, 1]


@njit(**INLINE)
def resting_wrench2d(bodies, rc, x, angle, L, v, w, F, T):
    detect2d(rc.geometry, x, angle, rc.buf)
    resting_forces2d(bodies, rc, x, angle, L, v, w, F, T)


@njit(**JIT)
def collision_impulses2d(bodies, rc, x, angle, P, L):
    buf = rc.buf
    par = rc.par
    rows = rc.rows
    v = rc.lin
    w = rc.ang
    for i in range(x.shape[0]):
        v[i, 0] = P[i, 0] * bodies.inv_mass[i]
        v[i, 1] = P[i, 1] * bodies.inv_mass[i]
        w[i] = L[i] * bodies.inv_moment[i]
    tol_c = par[R_TOL_C]
    bounce = par[R_BOUNCE]
    m = np.int64(0)  # not a literal 0 (sim/_jit.py: "Literal arguments")
    colliding = 0
    for r in range(buf.count[0]):
        if buf.depth[r] < -tol_c:
            continue
        vn, vt = setup_row2d(bodies, buf, r, m, rows, x, v, w)
        e = buf.restitution[r] if vn < -bounce else 0.0
        rows.target[m, 0] = -e * vn if vn < 0.0 else 0.0
        rows.target[m, 1] = 0.0
        rows.target[m, 2] = 0.0
        rows.bias[m, 0] = rows.bias[m, 1] = rows.bias[m, 2] = 0.0
        rows.lam[m, 0] = rows.lam[m, 1] = rows.lam[m, 2] = 0.0
        if vn < -par[R_IMPACT]:
            colliding += 1
        m += 1
    if colliding == 0:
        return 0
    if par[R_SEQUENTIAL] != 0.0:
        _sequential2d(bodies, buf, rows, m, v, w, bounce, int(par[R_IMP_ITER]))
    else:
        solve2d(bodies, buf, rows, m, v, w, int(par[R_IMP_ITER]), par[R_LCP_TOL], rc.dense)
    for k in range(m):
        r = rows.index[k]
        a = buf.a[r]
        b = buf.b[r]
        jx = rows.lam[k, 0] * rows.u[k, 0, 0] + rows.lam[k, 1] * rows.u[k, 1, 0]
        jy = rows.lam[k, 0] * rows.u[k, 0, 1] + rows.lam[k, 1] * rows.u[k, 1, 1]
        if jx == 0.0 and jy == 0.0:
            continue
        ra = rows.ra[k]
        P[a, 0] -= jx
        P[a, 1] -= jy
        L[a] -= ra[0] * jy - ra[1] * jx
        if b >= 0:
            rb = rows.rb[k]
            P[b, 0] += jx
            P[b, 1] += jy
            L[b] += rb[0] * jy - rb[1] * jx
    return colliding


@njit(**INLINE)
def _sequential2d(bodies, buf, rows, m, v, w, bounce, iterations):
    for _ in range(iterations):
        worst = -1
        worst_vn = 0.0
        for k in range(m):
            vn = _relative2d(buf, rows, k, 0, v, w)
            if vn < worst_vn:
                worst_vn = vn
                worst = k
        if worst < 0 or worst_vn > -1e-14:
            return
        k = worst
        e = buf.restitution[rows.index[k]] if worst_vn < -bounce else 0.0
        jn = -(1.0 + e) * worst_vn * rows.k[k, 0]
        _apply2d(bodies, buf, rows, k, 0, jn, v, w)
        rows.lam[k, 0] += jn
        limit = rows.mu[k] * jn
        t1 = -_relative2d(buf, rows, k, 1, v, w) * rows.k[k, 1]
        if t1 > limit:
            t1 = limit
        elif t1 < -limit:
            t1 = -limit
        _apply2d(bodies, buf, rows, k, 1, t1, v, w)
        rows.lam[k, 1] += t1


# -- the direct normal solve (small problems) -----------------------------------------------------
@njit(**INLINE)
def _sign_resp3d(buf, rows, j, body):
    """(sign, I^-1 (r x n_j) of row j on ``body``): +1 for b, -1 for a, 0 when not involved."""
    r = rows.index[j]
    if buf.a[r] == body:
        return -1.0, rows.resp_a[j, 0, 0], rows.resp_a[j, 0, 1], rows.resp_a[j, 0, 2]
    if buf.b[r] == body:
        return 1.0, rows.resp_b[j, 0, 0], rows.resp_b[j, 0, 1], rows.resp_b[j, 0, 2]
    return 0.0, 0.0, 0.0, 0.0


@njit(**INLINE)
def build_normal_matrix3d(bodies, buf, rows, m, A):
    """A[i, j] = the relative normal acceleration (velocity) at row i per unit force (impulse)
    along row j's normal: J_n M^-1 J_n^T."""
    for i in range(m):
        ri = rows.index[i]
        nx, ny, nz = rows.u[i, 0, 0], rows.u[i, 0, 1], rows.u[i, 0, 2]
        for side in range(2):
            k = buf.a[ri] if side == 0 else buf.b[ri]
            if k < 0:
                continue
            si = -1.0 if side == 0 else 1.0
            r = rows.ra[i] if side == 0 else rows.rb[i]
            cx, cy, cz = _cross(r[0], r[1], r[2], nx, ny, nz)
            for j in range(i + 1):
                sj, gx, gy, gz = _sign_resp3d(buf, rows, j, k)
                if sj == 0.0:
                    continue
                v = si * sj * ((nx * rows.u[j, 0, 0] + ny * rows.u[j, 0, 1]
                                + nz * rows.u[j, 0, 2]) * bodies.inv_mass[k]
                               + cx * gx + cy * gy + cz * gz)
                A[i, j] += v
                if j != i:
                    A[j, i] += v


@njit(**JIT)
def friction_sweep3d(bodies, buf, rows, m, lin, ang):
    """One Gauss-Seidel sweep over the friction rows (the normal forces fixed): the largest
    change."""
    lam = rows.lam
    change = 0.0
    for k in range(m):
        limit = rows.mu[k] * lam[k, 0]
        t1 = lam[k, 1] + (rows.target[k, 1] - _relative3d(buf, rows, k, 1, lin, ang)) \
            * rows.k[k, 1]
        t2 = lam[k, 2] + (rows.target[k, 2] - _relative3d(buf, rows, k, 2, lin, ang)) \
            * rows.k[k, 2]
        mag = np.sqrt(t1 * t1 + t2 * t2)
        if mag > limit:
            s = limit / mag if mag > 0.0 else 0.0
            t1 *= s
            t2 *= s
        d1 = t1 - lam[k, 1]
        d2 = t2 - lam[k, 2]
        if d1 != 0.0:
            _apply3d(bodies, buf, rows, k, 1, d1, lin, ang)
            lam[k, 1] = t1
        if d2 != 0.0:
            _apply3d(bodies, buf, rows, k, 2, d2, lin, ang)
            lam[k, 2] = t2
        change = max(change, abs(d1), abs(d2))
    return change


@njit(**JIT)
def solve3d(bodies, buf, rows, m, lin, ang, iterations, tol, dn):
    """The contact problem of rows 0..m-1 (module docstring): when it fits the dense scratch,
    the normal forces exactly (lcp.lcp_solve on J_n M^-1 J_n^T) alternating with friction sweeps
    until no force changes by more than tol times the largest; else (or if the pivoting fails)
    projected Gauss-Seidel. lin / ang end with the forces' effect added."""
    lam = rows.lam
    for k in range(m):
        for j in range(3):
            if lam[k, j] != 0.0:
                _apply3d(bodies, buf, rows, k, j, lam[k, j], lin, ang)
    if m <= dn.q.shape[0]:
        for i in range(m):
            for j in range(m):
                dn.A[i, j] = 0.0
        build_normal_matrix3d(bodies, buf, rows, m, dn.A)
        for k in range(m):
            dn.active[k] = lam[k, 0] > 0.0
        ok = True
        for _ in range(iterations):
            for k in range(m):
                if lam[k, 0] != 0.0:
                    _apply3d(bodies, buf, rows, k, 0, -lam[k, 0], lin, ang)
            for k in range(m):
                dn.q[k] = _relative3d(buf, rows, k, 0, lin, ang) - rows.target[k, 0]
            if lcp_solve(dn, m, 4 * m + 50) < 0:
                ok = False
            change = 0.0
            largest = 0.0
            for k in range(m):
                new = dn.lam[k] if (ok and dn.lam[k] > 0.0) else (lam[k, 0] if not ok else 0.0)
                change = max(change, abs(new - lam[k, 0]))
                largest = max(largest, new)
                lam[k, 0] = new
                if new != 0.0:
                    _apply3d(bodies, buf, rows, k, 0, new, lin, ang)
            if not ok:
                break
            change = max(change, friction_sweep3d(bodies, buf, rows, m, lin, ang))
            if change <= tol * largest or largest == 0.0:
                return
        if ok:
            return
    pgs3d(bodies, buf, rows, m, lin, ang, iterations, tol)


@njit(**INLINE)
def _sign_resp2d(buf, rows, j, body):
    r = rows.index[j]
    if buf.a[r] == body:
        return -1.0, rows.resp_a[j, 0]
    if buf.b[r] == body:
        return 1.0, rows.resp_b[j, 0]
    return 0.0, 0.0


@njit(**INLINE)
def build_normal_matrix2d(bodies, buf, rows, m, A):
    for i in range(m):
        ri = rows.index[i]
        nx, ny = rows.u[i, 0, 0], rows.u[i, 0, 1]
        for side in range(2):
            k = buf.a[ri] if side == 0 else buf.b[ri]
            if k < 0:
                continue
            si = -1.0 if side == 0 else 1.0
            r = rows.ra[i] if side == 0 else rows.rb[i]
            c = r[0] * ny - r[1] * nx
            for j in range(i + 1):
                sj, g = _sign_resp2d(buf, rows, j, k)
                if sj == 0.0:
                    continue
                v = si * sj * ((nx * rows.u[j, 0, 0] + ny * rows.u[j, 0, 1])
                               * bodies.inv_mass[k] + c * g)
                A[i, j] += v
                if j != i:
                    A[j, i] += v


@njit(**JIT)
def friction_sweep2d(bodies, buf, rows, m, lin, ang):
    lam = rows.lam
    change = 0.0
    for k in range(m):
        limit = rows.mu[k] * lam[k, 0]
        t1 = lam[k, 1] + (rows.target[k, 1] - _relative2d(buf, rows, k, 1, lin, ang)) \
            * rows.k[k, 1]
        if t1 > limit:
            t1 = limit
        elif t1 < -limit:
            t1 = -limit
        d1 = t1 - lam[k, 1]
        if d1 != 0.0:
            _apply2d(bodies, buf, rows, k, 1, d1, lin, ang)
            lam[k, 1] = t1
        change = max(change, abs(d1))
    return change


@njit(**JIT)
def solve2d(bodies, buf, rows, m, lin, ang, iterations, tol, dn):
    lam = rows.lam
    for k in range(m):
        for j in range(2):
            if lam[k, j] != 0.0:
                _apply2d(bodies, buf, rows, k, j, lam[k, j], lin, ang)
    if m <= dn.q.shape[0]:
        for i in range(m):
            for j in range(m):
                dn.A[i, j] = 0.0
        build_normal_matrix2d(bodies, buf, rows, m, dn.A)
        for k in range(m):
            dn.active[k] = lam[k, 0] > 0.0
        ok = True
        for _ in range(iterations):
            for k in range(m):
                if lam[k, 0] != 0.0:
                    _apply2d(bodies, buf, rows, k, 0, -lam[k, 0], lin, ang)
            for k in range(m):
                dn.q[k] = _relative2d(buf, rows, k, 0, lin, ang) - rows.target[k, 0]
            if lcp_solve(dn, m, 4 * m + 50) < 0:
                ok = False
            change = 0.0
            largest = 0.0
            for k in range(m):
                new = dn.lam[k] if (ok and dn.lam[k] > 0.0) else (lam[k, 0] if not ok else 0.0)
                change = max(change, abs(new - lam[k, 0]))
                largest = max(largest, new)
                lam[k, 0] = new
                if new != 0.0:
                    _apply2d(bodies, buf, rows, k, 0, new, lin, ang)
            if not ok:
                break
            change = max(change, friction_sweep2d(bodies, buf, rows, m, lin, ang))
            if change <= tol * largest or largest == 0.0:
                return
        if ok:
            return
    pgs2d(bodies, buf, rows, m, lin, ang, iterations, tol)


# -- event bookkeeping (both dimensions) ----------------------------------------------------------
@njit(**JIT)
def mark_active(buf, active, tol_c):
    """The active set: the features of the rows in contact, warm-start values carried over."""
    table_flip(active)
    cur = active.current[0]
    prev = 1 - cur
    n = 0
    for r in range(buf.count[0]):
        if buf.depth[r] < -tol_c:
            continue
        old = table_find(active, prev, buf.feature[r])
        slot = table_insert(active, buf.feature[r])
        if slot < 0 or table_insert(active, pair_key(buf.feature[r])) < 0:
            raise ValueError("impulse_lcp: active-set table full")
        if old >= 0:
            for j in range(active.value.shape[2]):
                active.value[cur, slot, j] = active.value[prev, old, j]
        else:
            for j in range(active.value.shape[2]):
                active.value[cur, slot, j] = 0.0
        n += 1
    return n


@njit(**INLINE)
def pair_key(feature):
    """The active-set key of a row's collider pair (negative: never a feature)."""
    return -(feature >> 32) - 1


@njit(**INLINE)
def _is_new_event(active, cur, feature, vn, v_impact):
    """A row not in the active set is an event unless its pair touches already and it does not
    strike (a point a touching manifold adds, or a feature id that changes, while resting)."""
    if table_find(active, cur, feature) >= 0:
        return False
    if table_find(active, cur, pair_key(feature)) >= 0 and vn >= -v_impact:
        return False
    return True


@njit(**JIT)
def new_contact_depths3d(bodies, rc, x, q, P, L):
    """The largest depth among the rows that are events (``_is_new_event``), -inf if none."""
    buf = rc.buf
    active = rc.active
    cur = active.current[0]
    v = rc.lin
    w = rc.ang
    world_inverse_inertia3d(bodies, q, rc.iinv)
    for i in range(x.shape[0]):
        im = bodies.inv_mass[i]
        v[i, 0], v[i, 1], v[i, 2] = P[i, 0] * im, P[i, 1] * im, P[i, 2] * im
        w[i, 0], w[i, 1], w[i, 2] = _mat(rc.iinv, i, L[i, 0], L[i, 1], L[i, 2])
    deepest = -np.inf
    for r in range(buf.count[0]):
        if buf.depth[r] <= deepest:
            continue
        a = buf.a[r]
        b = buf.b[r]
        px, py, pz = buf.point[r, 0], buf.point[r, 1], buf.point[r, 2]
        vax, vay, vaz = _point_velocity3d(x, v, w, a, px, py, pz)
        vbx = vby = vbz = 0.0
        if b >= 0:
            vbx, vby, vbz = _point_velocity3d(x, v, w, b, px, py, pz)
        vn = ((vbx - vax) * buf.normal[r, 0] + (vby - vay) * buf.normal[r, 1]
              + (vbz - vaz) * buf.normal[r, 2])
        if _is_new_event(active, cur, buf.feature[r], vn, rc.par[R_IMPACT]):
            deepest = buf.depth[r]
    return deepest


@njit(**JIT)
def new_contact_depths2d(bodies, rc, x, angle, P, L):
    buf = rc.buf
    active = rc.active
    cur = active.current[0]
    deepest = -np.inf
    for r in range(buf.count[0]):
        if buf.depth[r] <= deepest:
            continue
        a = buf.a[r]
        b = buf.b[r]
        px, py = buf.point[r, 0], buf.point[r, 1]
        wa = L[a] * bodies.inv_moment[a]
        vax = P[a, 0] * bodies.inv_mass[a] - wa * (py - x[a, 1])
        vay = P[a, 1] * bodies.inv_mass[a] + wa * (px - x[a, 0])
        vbx = vby = 0.0
        if b >= 0:
            wb = L[b] * bodies.inv_moment[b]
            vbx = P[b, 0] * bodies.inv_mass[b] - wb * (py - x[b, 1])
            vby = P[b, 1] * bodies.inv_mass[b] + wb * (px - x[b, 0])
        vn = (vbx - vax) * buf.normal[r, 0] + (vby - vay) * buf.normal[r, 1]
        if _is_new_event(active, cur, buf.feature[r], vn, rc.par[R_IMPACT]):
            deepest = buf.depth[r]
    return deepest


@njit(**JIT)
def speed_bound3d(bodies, q, P, L, inner, outer, iinv):
    """max over bodies of (|v| + |w| R) / r_in: 1 / the time in which a body may move by its
    inner radius."""
    world_inverse_inertia3d(bodies, q, iinv)
    worst = 0.0
    for i in range(P.shape[0]):
        im = bodies.inv_mass[i]
        vs = np.sqrt((P[i, 0] * im) ** 2 + (P[i, 1] * im) ** 2 + (P[i, 2] * im) ** 2)
        wx, wy, wz = _mat(iinv, i, L[i, 0], L[i, 1], L[i, 2])
        ws = np.sqrt(wx * wx + wy * wy + wz * wz)
        s = (vs + ws * outer[i]) / inner[i]
        if s > worst:
            worst = s
    return worst


@njit(**JIT)
def speed_bound2d(bodies, P, L, inner, outer):
    worst = 0.0
    for i in range(P.shape[0]):
        im = bodies.inv_mass[i]
        vs = np.sqrt((P[i, 0] * im) ** 2 + (P[i, 1] * im) ** 2)
        ws = abs(L[i] * bodies.inv_moment[i])
        s = (vs + ws * outer[i]) / inner[i]
        if s > worst:
            worst = s
    return worst


@njit(**JIT)
def detect_state3d(geometry, x, q, buf):
    detect3d(geometry, x, q, buf)


@njit(**JIT)
def detect_state2d(geometry, x, angle, buf):
    detect2d(geometry, x, angle, buf)


# -- the stepper ----------------------------------------------------------------------------------
def _radii(scene) -> tuple[np.ndarray, np.ndarray]:
    """(inner, outer) radius of every body: half its smallest body-frame extent, and the largest
    distance of its shape from its centre of mass."""
    inner, outer = [], []
    for body in scene.bodies:
        lo, hi = _extent(body.shape, scene.dimension)
        com = np.asarray(body.com, float)
        inner.append(max(0.5 * float(np.min(hi - lo)), 1e-9))
        corners = np.array(np.meshgrid(*zip(lo, hi, strict=True), indexing="ij")).reshape(
            scene.dimension, -1).T
        outer.append(float(np.max(np.linalg.norm(corners - com, axis=1))))
    return np.array(inner), np.array(outer)


def _extent(shape, d: int) -> tuple[np.ndarray, np.ndarray]:
    """Body-frame axis-aligned bounds of a shape (its support along the axes)."""
    lo = np.empty(d)
    hi = np.empty(d)
    for k in range(d):
        e = np.zeros(d)
        e[k] = 1.0
        hi[k] = float(np.dot(shape.support(e), e))
        lo[k] = float(np.dot(shape.support(-e), e))
    return lo, hi


class ImpulseLcpStepper:
    """The event-driven loop (module docstring) around the run's integrator."""

    def __init__(self, scene, model, integrator, parameters: dict | None = None):
        from crosscheck.sim.rigid import contact_detect

        params = dict(parameters or {})
        unknown = sorted(set(params) - set(PARAMETERS))
        if unknown:
            raise ValueError(f"impulse_lcp: unknown parameters {unknown}; known: "
                             f"{list(PARAMETERS)}")
        self.params = {k: params.get(k, v[0]) for k, v in PARAMETERS.items()}
        mode = str(self.params["collision"])
        if mode not in ("simultaneous", "sequential"):
            raise ValueError(f"impulse_lcp: collision must be 'simultaneous' or 'sequential', "
                             f"got {mode!r}")
        self.model = model
        self.integrator = integrator
        d = model.dimension
        self.dimension = d
        tol_c = float(self.params["contact_tolerance"])
        tol_p = float(self.params["penetration_tolerance"])
        if not (tol_c > 0 and tol_p > 0):
            raise ValueError("impulse_lcp: contact and penetration tolerances must be > 0")
        self.geometry, _, capacity = contact_detect.compile_colliders(
            scene, margin=tol_c, capacity=int(self.params["capacity"]))
        self.buf = contact_detect.new_contacts(capacity, d)
        self.contacts = self.buf
        n = model.n_bodies
        par = np.zeros(N_PAR)
        par[R_TOL_C] = tol_c
        par[R_TOL_P] = tol_p
        par[R_ALPHA] = float(self.params["stabilisation_steps"])
        par[R_ITER] = int(self.params["lcp_iterations"])
        par[R_IMP_ITER] = int(self.params["lcp_iterations"])
        par[R_LCP_TOL] = float(self.params["lcp_tolerance"])
        par[R_SEQUENTIAL] = 1.0 if mode == "sequential" else 0.0
        self.arg = RestingContacts(
            self.geometry, self.buf, FeatureTable.empty(capacity, 4), par, np.zeros(1),
            _scratch(capacity, n, d), np.zeros((n, d)), np.zeros((n, 3)) if d == 3
            else np.zeros(n), np.zeros((n, 3, 3)) if d == 3 else np.zeros(n),
            Dense.empty(min(capacity, int(self.params["direct_rows"]))))
        self.inner, self.outer = _radii(scene)
        self.fraction = float(self.params["advance_fraction"])
        g = model.gravity
        self.g = 0.0 if g is None else float(np.linalg.norm(g))
        self._y0 = None
        self._ylo = None
        self.stats = {"steps": 0, "sub_steps": 0, "impacts": 0, "bisections": 0,
                      "bisection_iterations": 0}

    # -- pieces ---------------------------------------------------------------------------------
    def _detect(self, state) -> None:
        if self.dimension == 3:
            detect_state3d(self.geometry, state.x, state.rot, self.buf)
        else:
            detect_state2d(self.geometry, state.x, state.rot, self.buf)

    def _impulses(self, state) -> int:
        b = self.model.bodies
        if self.dimension == 3:
            return collision_impulses3d(b, self.arg, state.x, state.rot, state.P, state.L)
        return collision_impulses2d(b, self.arg, state.x, state.rot, state.P, state.L)

    def _new_depth(self, state) -> float:
        b = self.model.bodies
        if self.dimension == 3:
            return new_contact_depths3d(b, self.arg, state.x, state.rot, state.P, state.L)
        return new_contact_depths2d(b, self.arg, state.x, state.rot, state.P, state.L)

    def _max_dt(self, state) -> float:
        b = self.model.bodies
        if self.dimension == 3:
            s = speed_bound3d(b, state.rot, state.P, state.L, self.inner, self.outer,
                              self.arg.iinv)
        else:
            s = speed_bound2d(b, state.P, state.L, self.inner, self.outer)
        return math.inf if s <= 0.0 else self.fraction / s

    def _integrate(self, state, tau: float) -> None:
        self.arg.h[0] = tau
        self.integrator.advance(self.model, state, None, self.arg, 1, tau)

    @staticmethod
    def _copy(dst, src) -> None:
        for a, b in zip(dst.arrays(), src.arrays(), strict=True):
            a[...] = b

    # -- the step -------------------------------------------------------------------------------
    def step(self, state, h: float) -> None:
        if self._y0 is None:
            self._y0 = state.copy()
            self._ylo = state.copy()
        par = self.arg.par
        bounce = self.params["bounce_threshold"]
        par[R_BOUNCE] = 2.0 * self.g * h if bounce is None else float(bounce)
        # an impulse phase runs when some contact approaches faster than this (slower drift
        # is the resting LCP's, through its Baumgarte term)
        par[R_IMPACT] = max(1e-2 * par[R_BOUNCE], 1e-9)
        tol_c, tol_p = par[R_TOL_C], par[R_TOL_P]
        left = h
        t_min = 1e-12 * h
        for _ in range(10_000):
            if left <= t_min:
                break
            self.stats["sub_steps"] += 1
            self._detect(state)
            if self._impulses(state):
                self.stats["impacts"] += 1
            mark_active(self.buf, self.arg.active, tol_c)
            tau = min(left, self._max_dt(state))
            y0, ylo = self._y0, self._ylo
            self._copy(y0, state)
            self._integrate(state, tau)
            self._detect(state)
            if self._new_depth(state) <= tol_p:
                left -= tau
                continue
            # a new contact went deeper than the tolerance: bisect back to its time of impact
            self.stats["bisections"] += 1
            lo, hi = 0.0, tau
            have_lo = False
            for _it in range(200):
                self.stats["bisection_iterations"] += 1
                mid = 0.5 * (lo + hi)
                self._copy(state, y0)
                self._integrate(state, mid)
                self._detect(state)
                deepest = self._new_depth(state)
                if deepest > tol_p:
                    hi = mid
                else:
                    lo = mid
                    self._copy(ylo, state)
                    have_lo = True
                    if deepest >= -tol_c:
                        break
                if hi - lo <= t_min:
                    break
            if have_lo and lo > 0.0:
                self._copy(state, ylo)
                left -= lo
            else:  # the band is narrower than the time resolution: take the deeper state
                self._copy(state, y0)
                self._integrate(state, hi)
                left -= hi
        else:
            raise ValueError("impulse_lcp: more than 10000 events in one step (a Zeno sequence)")
        self.stats["steps"] += 1

    def advance(self, state, n_steps: int, h: float) -> None:
        for _ in range(int(n_steps)):
            self.step(state, float(h))

    def describe(self) -> dict[str, Any]:
        par = self.arg.par
        return {"model": "impulse_lcp", "parameters": {k: v for k, v in self.params.items()},
                "bounce_threshold_used": float(par[R_BOUNCE]),
                "stabilisation_rate": "1 / (stabilisation_steps h)",
                "statistics": dict(self.stats)}


def open_impulse_lcp(scene, model, integrator, parameters: dict | None = None):
    return ImpulseLcpStepper(scene, model, integrator, parameters)
