"""The ``penalty`` contact model: a spring-damper normal force and Coulomb friction inside the
force pass, so every explicit integrator (RK4 included) runs through contact unchanged.

At every force evaluation (``forces3d.evaluate`` / ``forces2d.evaluate`` call
:func:`penalty_wrench3d` / :func:`penalty_wrench2d` through ``contact_forces``) the contacts are
detected at the stage's positions and every row with depth ``d > 0`` adds, at its point, with
``n`` from a to b, ``v_rel`` the velocity of b's material point relative to a's and
``d' = -n . v_rel``:

* **normal force** ``f_n = max(0, k d^p + c d^((p-1)/2) d')``. With the exponent ``(p - 1)/2`` on
  the damping term (Tsuji et al. 1992 for Hertz's p = 3/2; the Kelvin-Voigt spring-dashpot for
  p = 1) the coefficient of restitution of a binary impact depends on the damping ratio
  ``zeta = c / (2 sqrt(m_eff k))`` alone, not on the impact speed (dimensional analysis), so the
  pair's restitution maps to one ``zeta(e)``: computed once per run by integrating the
  dimensionless impact (``restitution_of``) and inverting it by bisection to 1e-10 in e. Hunt and
  Crossley's damping ``c d^p d'`` (and Flores et al.'s restitution formula for it) makes e fall
  with the impact speed instead, which a Newton-restitution truth (constant e) cannot match.
  The force is clamped at 0: the surfaces never pull (the unilateral dashpot of Schwager and
  Poeschel 2007, whose e(zeta) this is for p = 1).
* **stiffness from the step**: the pair's natural angular frequency is ``omega0 = 2 pi /
  (period_steps h)``, the run's step h (the first ``advance``): ``k = m_eff omega0^2`` for p = 1
  (``m_eff`` the reduced mass, the body's mass against fixed geometry), divided among the rows of
  the pair's manifold so the pair's total stiffness does not depend on how many points it
  touches at. Explicit integrators resolve a contact oscillation only when ``h omega0`` is
  small; the stiffness is therefore set by the step, and the resting depth follows from it:
  ``d = W / (m_eff omega0^2)`` for a load W (25 um for a body on the ground at the defaults and
  h = 1e-3). For p != 1, ``k = m_eff omega0^2 d_ref^(1-p)``: the same force at ``d_ref`` (the
  resting depth of the linear law under gravity, 1e-4 m without gravity).
* **friction** (``friction_law = "anchor"``, the default): an elastic-plastic tangential spring
  (Cundall and Strack 1979): ``f_t = -k_t s - c_t v_t``, capped at ``mu f_n`` (then sliding in
  its direction); ``s`` is the tangential displacement since the contact began, kept per contact
  (feature key) and advanced once per step by the trapezoidal rule on the slip velocity (zero
  for rolling), within a step by the relative displacement of the two material points that were
  at the contact at its start (so the force is a smooth function of every stage's state), and
  cut back to ``mu f_n / k_t`` when it slides. It holds a body on an incline without creep.
  ``k_t = tangential_ratio k`` (2/7: the tangential and normal frequencies of a sphere agree),
  ``c_t`` at damping ratio ``tangential_damping``. ``friction_law = "regularised"``:
  ``f_t = -mu f_n v_t / sqrt(|v_t|^2 + v_eps^2)``, memoryless, but it creeps at about v_eps under
  a tangential load below ``mu f_n``, and its stiffness ``mu f_n / v_eps`` limits the step.
* **rolling and torsional resistance** (pair values, m): torques ``-mu_r f_n w_r / sqrt(|w_r|^2
  + w_eps^2)`` on the relative angular velocity's tangential part, and the same with ``mu_tor``
  about the normal (3D).

The model is deterministic (sequential loops, no atomics) and allocates nothing per step: the
contact buffer, the manifold counts and the friction table are made once by :func:`open_penalty`.
"""

from __future__ import annotations

import functools
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
from crosscheck.sim.rigid.math3d import quat_to_rotation

# -- parameters (par array indices) ---------------------------------------------------------------
(P_OMEGA, P_EXP, P_DREF, P_KT, P_ZT, P_LAW, P_VEPS, P_WEPS, P_H, P_EVALS, P_HC, P_ZMAX,
 P_WOLD, P_WNOW) = range(14)
N_PAR = 14
LAW_ANCHOR, LAW_REGULARISED = 0, 1
# friction table value layout: s (3), anchor on a (3, body frame), anchor on b (3, body frame or
# world for fixed geometry), v_t at the step start (3)
V_S, V_PA, V_PB, V_VT, V_VIN = 0, 3, 6, 9, 12
N_VAL = 13

PARAMETERS: dict[str, tuple[Any, str]] = {
    "period_steps": (10.0, "steps of the run's dt per undamped contact period 2 pi / omega0; "
                           "sets the stiffness k = m_eff omega0^2 (larger: softer, deeper, "
                           "better resolved)"),
    "exponent": (1.0, "p of the normal force k d^p + c d^((p-1)/2) d' (1: linear, 1.5: Hertz)"),
    "damping_law": ("hunt_crossley", "'hunt_crossley': k d^p (1 + beta d'), beta = B(e) / v_in "
                                     "(the contact's approach speed, kept per contact); 'tsuji': "
                                     "k d^p + c d^((p-1)/2) d' (e independent of the speed, but "
                                     "for p = 1 the dashpot jumps on at d = 0)"),
    "restitution_floor": (0.01, "hunt_crossley: restitutions below it are given it (B = 1 / "
                                "floor: e = 0 needs an infinite B)"),
    "damping_ratio_max": (None, "the largest local damping ratio (hunt_crossley: caps "
                                "k d^p beta; tsuji: caps zeta, restitution below e(zeta_max) given "
                                "that); default by integrator, DAMPING_RATIO_MAX"),
    "friction_law": ("anchor", "'anchor' (elastic-plastic tangential spring, no creep) or "
                               "'regularised' (-mu f_n v_t / sqrt(|v_t|^2 + v_eps^2))"),
    "tangential_ratio": (2.0 / 7.0, "k_t / k of the anchor spring"),
    "tangential_damping": (None, "damping ratio of the anchor spring: 0.3, 0.5 for explicit "
                                 "Euler (whose step amplifies an oscillation damped less than "
                                 "about 0.33 at h omega = 0.63); measured: 1.0 drives a limit "
                                 "cycle with the cap at dt = 1e-3, a block creeping uphill"),
    "regularisation_speed": (1e-2, "v_eps of the regularised law, m/s"),
    "spin_regularisation": (1e-2, "w_eps of rolling and torsional resistance, rad/s"),
    "capacity": (0, "contact rows (0: from the scene)"),
}


# The damping cap by integrator at the default period (h omega0 = 0.63). Stiffness-proportional
# damping gives a box's rocking modes up to sqrt(3) times the frequency and damping ratio of a
# translation, and each scheme's step is stable on a damped oscillation only up to some damping
# ratio (symplectic Euler: 1.43 at h omega = 0.63, 0.64 at 1.09; RK4: 2.3 and 1.5): measured on a
# block resting on a 20 degree incline and a tilted box dropped on the ground, the largest caps
# that leave no limit cycle (a creeping block) are these.
DAMPING_RATIO_MAX = {"rk4": 1.2, "rk4_exp": 1.2, "midpoint": 0.8, "verlet": 0.8,
                     "symplectic_euler": 0.6, "symplectic_euler_exp": 0.6, "explicit_euler": 0.6}


class PenaltyContacts(NamedTuple):
    """The ``contacts`` argument of the force pass for the penalty model (3D and 2D)."""

    geometry: Any  # the colliders (contact_detect)
    scratch: Any  # detection scratch (contact_detect)
    buf: Any  # sim.collide.Contacts
    par: np.ndarray  # (N_PAR,) float64
    restitution_key: np.ndarray  # (E,) the scene's distinct pair restitutions
    restitution_zeta: np.ndarray  # (E,) their damping ratios
    manifold_rows: np.ndarray  # (capacity,) int64 scratch: rows of each row's manifold
    table: FeatureTable  # friction anchors
    counter: np.ndarray  # (1,) int64: force evaluations so far (the first of a step: % evals)


# -- restitution -> damping ratio -----------------------------------------------------------------
@njit(**INLINE)
def _impact_force(x, v, zeta, p, q, hunt_crossley):
    """The dimensionless impact's force: Hunt-Crossley x^p (1 + zeta v) (zeta standing for
    B = beta v_in), or x^p + 2 zeta x^q v (x^0 = 1: that dashpot acts from x = 0)."""
    xp = x if x > 0.0 else 0.0
    if hunt_crossley:
        return xp ** p * (1.0 + zeta * v)
    damp = 2.0 * zeta * v * (xp ** q if q > 0.0 else 1.0)
    return xp ** p + damp


@njit(**JIT)
def restitution_of(zeta, p, hunt_crossley=False):
    """Coefficient of restitution of the dimensionless unilateral impact
    x'' = -(x^p + 2 zeta x^((p-1)/2) x'), x(0) = 0, x'(0) = 1, while that force is positive:
    RK4 with step 1e-4, the separation (force 0 with x' < 0, or x back to 0) located by linear
    interpolation within the step; accurate to about 1e-7 (tests: an independent solve)."""
    q = 0.5 * (p - 1.0)
    dt = 1e-4
    x = 0.0
    v = 1.0
    f = _impact_force(x, v, zeta, p, q, hunt_crossley)
    for _ in range(100_000_000):
        k1x, k1v = v, -_impact_force(x, v, zeta, p, q, hunt_crossley)
        k2x, k2v = v + 0.5 * dt * k1v, -_impact_force(x + 0.5 * dt * k1x, v + 0.5 * dt * k1v,
                                                      zeta, p, q, hunt_crossley)
        k3x, k3v = v + 0.5 * dt * k2v, -_impact_force(x + 0.5 * dt * k2x, v + 0.5 * dt * k2v,
                                                      zeta, p, q, hunt_crossley)
        k4x, k4v = v + dt * k3v, -_impact_force(x + dt * k3x, v + dt * k3v, zeta, p, q,
                                             hunt_crossley)
        xn = x + dt / 6.0 * (k1x + 2.0 * k2x + 2.0 * k3x + k4x)
        vn = v + dt / 6.0 * (k1v + 2.0 * k2v + 2.0 * k3v + k4v)
        if xn <= 0.0:  # back at the surface still pushed
            s = x / (x - xn)
            return -(v + s * (vn - v))
        fn = _impact_force(xn, vn, zeta, p, q, hunt_crossley)
        if vn < 0.0 and fn <= 0.0:  # the force reaches zero: free from here on
            s = f / (f - fn) if f > fn else 1.0
            return -(v + s * (vn - v))
        x, v, f = xn, vn, fn
    return -v


@functools.lru_cache(maxsize=256)
def damping_ratio(e: float, p: float, zeta_max: float, hunt_crossley: bool = False) -> float:
    """zeta (or Hunt and Crossley's B = beta v_in) with restitution_of(zeta, p) = e (bisection
    to 1e-10 in e); zeta_max when e is at or below restitution_of(zeta_max, p); 0 for e >= 1.

    Memoised per process (a pure function of its arguments): the bisection integrates the
    impact some 40 times, 0.44 s of CPU for e = 0 at the restitution floor (measured), which
    every session open paid again (the cost pass opens one per repetition)."""
    if e >= 1.0:
        return 0.0
    if e <= restitution_of(zeta_max, p, hunt_crossley):
        return zeta_max
    lo, hi = 0.0, zeta_max
    for _ in range(100):
        mid = 0.5 * (lo + hi)
        if restitution_of(mid, p, hunt_crossley) > e:
            lo = mid
        else:
            hi = mid
        if hi - lo < 1e-12:
            break
    return 0.5 * (lo + hi)


# -- the force kernels ----------------------------------------------------------------------------
@njit(**INLINE)
def _zeta_of(pc, e):
    for k in range(pc.restitution_key.shape[0]):
        if pc.restitution_key[k] == e:
            return pc.restitution_zeta[k]
    return pc.restitution_zeta[pc.restitution_zeta.shape[0] - 1]  # not reached: every pair listed


@njit(**INLINE)
def manifold_key(feature):
    """The collider pair of a row (the feature's high 32 bits): rows of one manifold share it."""
    return feature >> 32


@njit(**INLINE)
def count_manifold_rows(buf, out):
    """out[r] = number of rows of r's manifold (consecutive rows with one pair key)."""
    n = buf.count[0]
    r = 0
    while r < n:
        key = manifold_key(buf.feature[r])
        e = r + 1
        while e < n and manifold_key(buf.feature[e]) == key and buf.a[e] == buf.a[r] \
                and buf.b[e] == buf.b[r]:
            e += 1
        for k in range(r, e):
            out[k] = e - r
        r = e


@njit(**INLINE)
def impact_speed(par, d, ddot):
    """The approach speed a contact had when it began, from its depth and rate now (the spring's
    energy given back; exact for an undamped approach): sqrt(d'^2 + 2 omega0^2 d_ref^(1-p)
    d^(p+1) / (p + 1)), at least 1e-9 m/s."""
    p = par[P_EXP]
    om = par[P_OMEGA]
    v2 = ddot * ddot + 2.0 * om * om * par[P_DREF] ** (1.0 - p) * d ** (p + 1.0) / (p + 1.0)
    return max(np.sqrt(v2), 1e-9)


@njit(**INLINE)
def row_mass(m_eff, rows, inv_point):
    """The mass a row's spring and dashpot are set for: the pair's reduced mass shared among the
    manifold's rows, but at most the contact point's own effective mass along the normal (with the
    bodies' rotation, ``1 / inv_point``), so that no contact mode, a box landing on a corner
    included, oscillates faster than omega0 or is damped faster than the cap allows. A sphere:
    the reduced mass; a box resting on a face: its share, unchanged."""
    share = m_eff / rows
    point = 1.0 / inv_point
    return share if share < point else point


@njit(**INLINE)
def normal_force(par, m_row, damping, d, ddot, v_in):
    """(f_n, k_row): the clamped normal force of one row and its linear stiffness
    ``k_row = m_row omega0^2``.

    Hunt-Crossley (the default): ``k d^p (1 + beta d')`` with ``beta = B(e) / v_in``, the local
    damping ``k d^p beta`` capped at ``2 zeta_max sqrt(m_row k_loc)`` (``k_loc = p k d^(p-1)``:
    a slow or resting contact is not damped faster than an explicit step can take). Tsuji's form:
    ``k d^p + c d^((p-1)/2) d'`` with ``c = 2 zeta m_row omega0`` (times ``d_ref^((1-p)/2)``)."""
    om = par[P_OMEGA]
    p = par[P_EXP]
    k_lin = m_row * om * om
    k = k_lin if p == 1.0 else k_lin * par[P_DREF] ** (1.0 - p)
    kd = k * d if p == 1.0 else k * d ** p
    if par[P_HC] != 0.0:
        c = kd * damping / v_in
        k_loc = k if p == 1.0 else p * k * d ** (p - 1.0)
        c_max = 2.0 * par[P_ZMAX] * np.sqrt(m_row * k_loc)
        f = kd + min(c, c_max) * ddot
    elif p == 1.0:
        f = kd + 2.0 * damping * m_row * om * ddot
    else:
        c = 2.0 * damping * m_row * om * par[P_DREF] ** (0.5 * (1.0 - p))
        f = kd + c * d ** (0.5 * (p - 1.0)) * ddot
    return (f if f > 0.0 else 0.0), k_lin


@njit(**INLINE)
def point_inverse_masses3d(bodies, q, i, rx, ry, rz, nx, ny, nz):
    """(1/m + (r x n) . I^-1 (r x n), 1/m + |r|^2 / I_min) of body i's point at r: its inverse
    effective mass along the normal, and a bound over tangential directions."""
    cx, cy, cz = ry * nz - rz * ny, rz * nx - rx * nz, rx * ny - ry * nx
    r00, r01, r02, r10, r11, r12, r20, r21, r22 = quat_to_rotation(q[i, 0], q[i, 1], q[i, 2],
                                                                   q[i, 3])
    bx = r00 * cx + r10 * cy + r20 * cz  # R^T (r x n): body frame
    by = r01 * cx + r11 * cy + r21 * cz
    bz = r02 * cx + r12 * cy + r22 * cz
    a = bodies.inv_inertia[i]
    quad = (bx * (a[0, 0] * bx + a[0, 1] * by + a[0, 2] * bz)
            + by * (a[1, 0] * bx + a[1, 1] * by + a[1, 2] * bz)
            + bz * (a[2, 0] * bx + a[2, 1] * by + a[2, 2] * bz))
    im = bodies.inv_mass[i]
    return im + quad, im + (rx * rx + ry * ry + rz * rz) / bodies.principal_moments[i, 0]


@njit(**INLINE)
def _cap(fx, fy, fz, limit):
    m = np.sqrt(fx * fx + fy * fy + fz * fz)
    if m > limit:
        s = limit / m
        return fx * s, fy * s, fz * s, True
    return fx, fy, fz, False


@njit(**JIT)
def penalty_rows3d(bodies, pc, x, q, v, w, F, T, first):
    """Forces of the filled contact buffer (3D), added to F, T; ``first``: the evaluation at the
    start of a step (friction anchors advance and are stored)."""
    buf = pc.buf
    par = pc.par
    n = buf.count[0]
    count_manifold_rows(buf, pc.manifold_rows)
    law = int(par[P_LAW])
    table = pc.table
    if first:
        table_flip(table)
    cur = table.current[0]
    prev = 1 - cur
    h = par[P_H]
    wo = par[P_WOLD]
    wn = par[P_WNOW]
    for r in range(n):
        d = buf.depth[r]
        if d <= 0.0:
            continue
        a = buf.a[r]
        b = buf.b[r]
        nx, ny, nz = buf.normal[r, 0], buf.normal[r, 1], buf.normal[r, 2]
        px, py, pz = buf.point[r, 0], buf.point[r, 1], buf.point[r, 2]
        rax, ray, raz = px - x[a, 0], py - x[a, 1], pz - x[a, 2]
        vax = v[a, 0] + w[a, 1] * raz - w[a, 2] * ray
        vay = v[a, 1] + w[a, 2] * rax - w[a, 0] * raz
        vaz = v[a, 2] + w[a, 0] * ray - w[a, 1] * rax
        inv = bodies.inv_mass[a]
        rbx = rby = rbz = 0.0
        vbx = vby = vbz = 0.0
        wbx = wby = wbz = 0.0
        if b >= 0:
            rbx, rby, rbz = px - x[b, 0], py - x[b, 1], pz - x[b, 2]
            vbx = v[b, 0] + w[b, 1] * rbz - w[b, 2] * rby
            vby = v[b, 1] + w[b, 2] * rbx - w[b, 0] * rbz
            vbz = v[b, 2] + w[b, 0] * rby - w[b, 1] * rbx
            wbx, wby, wbz = w[b, 0], w[b, 1], w[b, 2]
            inv += bodies.inv_mass[b]
        m_eff = 1.0 / inv
        ina, ita = point_inverse_masses3d(bodies, q, a, rax, ray, raz, nx, ny, nz)
        if b >= 0:
            inb, itb = point_inverse_masses3d(bodies, q, b, rbx, rby, rbz, nx, ny, nz)
            ina += inb
            ita += itb
        dvx, dvy, dvz = vbx - vax, vby - vay, vbz - vaz
        vn = dvx * nx + dvy * ny + dvz * nz
        rows = pc.manifold_rows[r]
        feature = buf.feature[r]
        old = -1
        if first:
            old = table_find(table, prev, feature)
            slot = table_insert(table, feature)
            if slot < 0:
                raise ValueError("penalty: contact table full")
            v_in = table.value[prev, old, V_VIN] if old >= 0 else impact_speed(par, d, -vn)
            table.value[cur, slot, V_VIN] = v_in
            fresh = True
        else:  # a stage: a contact seen for the first time is stored now, at its first depth
            slot = table_find(table, cur, feature)
            fresh = slot < 0
            if fresh:
                slot = table_insert(table, feature)
                if slot < 0:
                    raise ValueError("penalty: contact table full")
                v_in = impact_speed(par, d, -vn)
                table.value[cur, slot, V_VIN] = v_in
                for c_ in range(V_VIN):
                    table.value[cur, slot, c_] = 0.0
            else:
                v_in = table.value[cur, slot, V_VIN]
        m_row = row_mass(m_eff, rows, ina)
        fn, k_lin = normal_force(par, m_row, _zeta_of(pc, buf.restitution[r]), d, -vn, v_in)
        vtx, vty, vtz = dvx - vn * nx, dvy - vn * ny, dvz - vn * nz
        mu = buf.friction[r]
        ftx = fty = ftz = 0.0
        if law == LAW_REGULARISED:
            s = -mu * fn / np.sqrt(vtx * vtx + vty * vty + vtz * vtz
                                   + par[P_VEPS] * par[P_VEPS])
            ftx, fty, ftz = s * vtx, s * vty, s * vtz
        else:
            kt = par[P_KT] * k_lin
            ct = 2.0 * par[P_ZT] * np.sqrt(par[P_KT] * m_row / ita) * par[P_OMEGA]
            limit = mu * fn
            sx = sy = sz = 0.0
            if fresh:
                if old >= 0:
                    val = table.value[prev, old]
                    sx = val[V_S] + h * (wo * val[V_VT] + wn * vtx)
                    sy = val[V_S + 1] + h * (wo * val[V_VT + 1] + wn * vty)
                    sz = val[V_S + 2] + h * (wo * val[V_VT + 2] + wn * vtz)
                    sn = sx * nx + sy * ny + sz * nz
                    sx, sy, sz = sx - sn * nx, sy - sn * ny, sz - sn * nz
                    if kt > 0.0:
                        sx, sy, sz, _ = _cap(sx, sy, sz, limit / kt)
                val = table.value[cur, slot]
                val[V_S], val[V_S + 1], val[V_S + 2] = sx, sy, sz
                val[V_VT], val[V_VT + 1], val[V_VT + 2] = vtx, vty, vtz
                r00, r01, r02, r10, r11, r12, r20, r21, r22 = quat_to_rotation(
                    q[a, 0], q[a, 1], q[a, 2], q[a, 3])
                val[V_PA] = r00 * rax + r10 * ray + r20 * raz
                val[V_PA + 1] = r01 * rax + r11 * ray + r21 * raz
                val[V_PA + 2] = r02 * rax + r12 * ray + r22 * raz
                if b >= 0:
                    r00, r01, r02, r10, r11, r12, r20, r21, r22 = quat_to_rotation(
                        q[b, 0], q[b, 1], q[b, 2], q[b, 3])
                    val[V_PB] = r00 * rbx + r10 * rby + r20 * rbz
                    val[V_PB + 1] = r01 * rbx + r11 * rby + r21 * rbz
                    val[V_PB + 2] = r02 * rbx + r12 * rby + r22 * rbz
                else:
                    val[V_PB], val[V_PB + 1], val[V_PB + 2] = px, py, pz
            else:
                val = table.value[cur, slot]
                r00, r01, r02, r10, r11, r12, r20, r21, r22 = quat_to_rotation(
                    q[a, 0], q[a, 1], q[a, 2], q[a, 3])
                ax_ = x[a, 0] + r00 * val[V_PA] + r01 * val[V_PA + 1] + r02 * val[V_PA + 2]
                ay_ = x[a, 1] + r10 * val[V_PA] + r11 * val[V_PA + 1] + r12 * val[V_PA + 2]
                az_ = x[a, 2] + r20 * val[V_PA] + r21 * val[V_PA + 1] + r22 * val[V_PA + 2]
                if b >= 0:
                    r00, r01, r02, r10, r11, r12, r20, r21, r22 = quat_to_rotation(
                        q[b, 0], q[b, 1], q[b, 2], q[b, 3])
                    bx_ = x[b, 0] + r00 * val[V_PB] + r01 * val[V_PB + 1] \
                        + r02 * val[V_PB + 2]
                    by_ = x[b, 1] + r10 * val[V_PB] + r11 * val[V_PB + 1] \
                        + r12 * val[V_PB + 2]
                    bz_ = x[b, 2] + r20 * val[V_PB] + r21 * val[V_PB + 1] \
                        + r22 * val[V_PB + 2]
                else:
                    bx_, by_, bz_ = val[V_PB], val[V_PB + 1], val[V_PB + 2]
                sx = val[V_S] + bx_ - ax_
                sy = val[V_S + 1] + by_ - ay_
                sz = val[V_S + 2] + bz_ - az_
                sn = sx * nx + sy * ny + sz * nz
                sx, sy, sz = sx - sn * nx, sy - sn * ny, sz - sn * nz
            ftx, fty, ftz, _ = _cap(-kt * sx - ct * vtx, -kt * sy - ct * vty,
                                    -kt * sz - ct * vtz, limit)
        # force on b at the point (and its opposite on a)
        fx = fn * nx + ftx
        fy = fn * ny + fty
        fz = fn * nz + ftz
        tqx = tqy = tqz = 0.0  # rolling and torsional torque on b (its opposite on a)
        mur = buf.rolling_friction[r]
        mut = buf.torsional_friction[r]
        if mur > 0.0 or mut > 0.0:
            wrx, wry, wrz = wbx - w[a, 0], wby - w[a, 1], wbz - w[a, 2]
            wn = wrx * nx + wry * ny + wrz * nz
            eps2 = par[P_WEPS] * par[P_WEPS]
            if mur > 0.0:
                gx, gy, gz = wrx - wn * nx, wry - wn * ny, wrz - wn * nz
                s = -mur * fn / np.sqrt(gx * gx + gy * gy + gz * gz + eps2)
                tqx += s * gx
                tqy += s * gy
                tqz += s * gz
            if mut > 0.0:
                s = -mut * fn * wn / np.sqrt(wn * wn + eps2)
                tqx += s * nx
                tqy += s * ny
                tqz += s * nz
        F[a, 0] -= fx
        F[a, 1] -= fy
        F[a, 2] -= fz
        T[a, 0] -= ray * fz - raz * fy + tqx
        T[a, 1] -= raz * fx - rax * fz + tqy
        T[a, 2] -= rax * fy - ray * fx + tqz
        if b >= 0:
            F[b, 0] += fx
            F[b, 1] += fy
            F[b, 2] += fz
            T[b, 0] += rby * fz - rbz * fy + tqx
            T[b, 1] += rbz * fx - rbx * fz + tqy
            T[b, 2] += rbx * fy - rby * fx + tqz


@njit(**JIT)
def penalty_rows2d(bodies, pc, x, angle, v, w, F, T, first):
    """Forces of the filled contact buffer (2D), added to F (N, 2), T (N,)."""
    buf = pc.buf
    par = pc.par
    n = buf.count[0]
    count_manifold_rows(buf, pc.manifold_rows)
    law = int(par[P_LAW])
    table = pc.table
    if first:
        table_flip(table)
    cur = table.current[0]
    prev = 1 - cur
    h = par[P_H]
    wo = par[P_WOLD]
    wn = par[P_WNOW]
    for r in range(n):
        d = buf.depth[r]
        if d <= 0.0:
            continue
        a = buf.a[r]
        b = buf.b[r]
        nx, ny = buf.normal[r, 0], buf.normal[r, 1]
        px, py = buf.point[r, 0], buf.point[r, 1]
        rax, ray = px - x[a, 0], py - x[a, 1]
        vax = v[a, 0] - w[a] * ray
        vay = v[a, 1] + w[a] * rax
        inv = bodies.inv_mass[a]
        rbx = rby = 0.0
        vbx = vby = 0.0
        wb = 0.0
        if b >= 0:
            rbx, rby = px - x[b, 0], py - x[b, 1]
            vbx = v[b, 0] - w[b] * rby
            vby = v[b, 1] + w[b] * rbx
            wb = w[b]
            inv += bodies.inv_mass[b]
        m_eff = 1.0 / inv
        ca = rax * ny - ray * nx
        ina = bodies.inv_mass[a] + ca * ca * bodies.inv_moment[a]
        ita = bodies.inv_mass[a] + (rax * rax + ray * ray) * bodies.inv_moment[a]
        if b >= 0:
            cb = rbx * ny - rby * nx
            ina += bodies.inv_mass[b] + cb * cb * bodies.inv_moment[b]
            ita += bodies.inv_mass[b] + (rbx * rbx + rby * rby) * bodies.inv_moment[b]
        dvx, dvy = vbx - vax, vby - vay
        vn = dvx * nx + dvy * ny
        rows = pc.manifold_rows[r]
        feature = buf.feature[r]
        old = -1
        if first:
            old = table_find(table, prev, feature)
            slot = table_insert(table, feature)
            if slot < 0:
                raise ValueError("penalty: contact table full")
            v_in = table.value[prev, old, V_VIN] if old >= 0 else impact_speed(par, d, -vn)
            table.value[cur, slot, V_VIN] = v_in
            fresh = True
        else:  # a stage: a contact seen for the first time is stored now, at its first depth
            slot = table_find(table, cur, feature)
            fresh = slot < 0
            if fresh:
                slot = table_insert(table, feature)
                if slot < 0:
                    raise ValueError("penalty: contact table full")
                v_in = impact_speed(par, d, -vn)
                table.value[cur, slot, V_VIN] = v_in
                for c_ in range(V_VIN):
                    table.value[cur, slot, c_] = 0.0
            else:
                v_in = table.value[cur, slot, V_VIN]
        m_row = row_mass(m_eff, rows, ina)
        fn, k_lin = normal_force(par, m_row, _zeta_of(pc, buf.restitution[r]), d, -vn, v_in)
        vtx, vty = dvx - vn * nx, dvy - vn * ny
        mu = buf.friction[r]
        ftx = fty = 0.0
        if law == LAW_REGULARISED:
            s = -mu * fn / np.sqrt(vtx * vtx + vty * vty + par[P_VEPS] * par[P_VEPS])
            ftx, fty = s * vtx, s * vty
        else:
            kt = par[P_KT] * k_lin
            ct = 2.0 * par[P_ZT] * np.sqrt(par[P_KT] * m_row / ita) * par[P_OMEGA]
            limit = mu * fn
            sx = sy = 0.0
            if fresh:
                if old >= 0:
                    val = table.value[prev, old]
                    sx = val[V_S] + h * (wo * val[V_VT] + wn * vtx)
                    sy = val[V_S + 1] + h * (wo * val[V_VT + 1] + wn * vty)
                    sn = sx * nx + sy * ny
                    sx, sy = sx - sn * nx, sy - sn * ny
                    if kt > 0.0:
                        sx, sy, _z, _ = _cap(sx, sy, 0.0, limit / kt)
                val = table.value[cur, slot]
                val[V_S], val[V_S + 1] = sx, sy
                val[V_VT], val[V_VT + 1] = vtx, vty
                c, sn_ = np.cos(angle[a]), np.sin(angle[a])
                val[V_PA] = c * rax + sn_ * ray
                val[V_PA + 1] = -sn_ * rax + c * ray
                if b >= 0:
                    c, sn_ = np.cos(angle[b]), np.sin(angle[b])
                    val[V_PB] = c * rbx + sn_ * rby
                    val[V_PB + 1] = -sn_ * rbx + c * rby
                else:
                    val[V_PB], val[V_PB + 1] = px, py
            else:
                val = table.value[cur, slot]
                c, sn_ = np.cos(angle[a]), np.sin(angle[a])
                ax_ = x[a, 0] + c * val[V_PA] - sn_ * val[V_PA + 1]
                ay_ = x[a, 1] + sn_ * val[V_PA] + c * val[V_PA + 1]
                if b >= 0:
                    c, sn_ = np.cos(angle[b]), np.sin(angle[b])
                    bx_ = x[b, 0] + c * val[V_PB] - sn_ * val[V_PB + 1]
                    by_ = x[b, 1] + sn_ * val[V_PB] + c * val[V_PB + 1]
                else:
                    bx_, by_ = val[V_PB], val[V_PB + 1]
                sx = val[V_S] + bx_ - ax_
                sy = val[V_S + 1] + by_ - ay_
                sn = sx * nx + sy * ny
                sx, sy = sx - sn * nx, sy - sn * ny
            ftx, fty, _z, _ = _cap(-kt * sx - ct * vtx, -kt * sy - ct * vty, 0.0, limit)
        fx = fn * nx + ftx
        fy = fn * ny + fty
        tq = 0.0
        mur = buf.rolling_friction[r]
        if mur > 0.0:
            wr = wb - w[a]
            tq = -mur * fn * wr / np.sqrt(wr * wr + par[P_WEPS] * par[P_WEPS])
        F[a, 0] -= fx
        F[a, 1] -= fy
        T[a] -= rax * fy - ray * fx + tq
        if b >= 0:
            F[b, 0] += fx
            F[b, 1] += fy
            T[b] += rbx * fy - rby * fx + tq


# -- stepper --------------------------------------------------------------------------------------
def _number(parameters: dict, name: str) -> float:
    value = parameters.get(name, PARAMETERS[name][0])
    return float(value)


class PenaltyStepper:
    """Advances the state with the integrator's own kernels and the penalty forces in every force
    evaluation (sim/rigid/contact_models.py protocol)."""

    def __init__(self, scene, model, integrator, parameters: dict | None = None):
        from crosscheck.sim.rigid import contact_detect

        params = dict(parameters or {})
        unknown = sorted(set(params) - set(PARAMETERS))
        if unknown:
            raise ValueError(f"penalty: unknown parameters {unknown}; known: {list(PARAMETERS)}")
        self.model = model
        self.integrator = integrator
        self.params = {k: params.get(k, v[0]) for k, v in PARAMETERS.items()}
        law = str(self.params["friction_law"])
        if law not in ("anchor", "regularised"):
            raise ValueError(f"penalty: friction_law must be 'anchor' or 'regularised', "
                             f"got {law!r}")
        p = _number(params, "exponent")
        if not 1.0 <= p <= 3.0:
            raise ValueError(f"penalty: exponent must be in [1, 3], got {p}")
        self.geometry, self.scratch, capacity = contact_detect.compile_colliders(
            scene, margin=0.0, capacity=int(_number(params, "capacity")))
        self.buf = contact_detect.new_contacts(capacity, model.dimension)
        self.contacts = self.buf
        if self.params["damping_ratio_max"] is None:
            self.params["damping_ratio_max"] = DAMPING_RATIO_MAX.get(integrator.name, 0.6)
        if self.params["tangential_damping"] is None:
            self.params["tangential_damping"] = 0.5 if integrator.name == "explicit_euler" else 0.3
        zmax = _number(self.params, "damping_ratio_max")
        dlaw = str(self.params["damping_law"])
        if dlaw not in ("hunt_crossley", "tsuji"):
            raise ValueError(f"penalty: damping_law must be 'hunt_crossley' or 'tsuji', "
                             f"got {dlaw!r}")
        self.hunt_crossley = dlaw == "hunt_crossley"
        values = sorted({float(e) for e in contact_detect.pair_restitutions(scene)})
        if self.hunt_crossley:  # B(e), e below the floor given the floor's B (1 / floor)
            floor = _number(params, "restitution_floor")
            self.zeta = {e: damping_ratio(max(e, floor), p, 1.0 / floor, True) for e in values}
        else:
            self.zeta = {e: damping_ratio(e, p, zmax) for e in values}
        gravity = model.gravity
        self._g = 0.0 if gravity is None else float(np.linalg.norm(gravity))
        par = np.zeros(N_PAR)
        par[P_EXP] = p
        par[P_KT] = _number(params, "tangential_ratio")
        par[P_ZT] = _number(self.params, "tangential_damping")
        par[P_LAW] = LAW_ANCHOR if law == "anchor" else LAW_REGULARISED
        par[P_VEPS] = _number(params, "regularisation_speed")
        par[P_WEPS] = _number(params, "spin_regularisation")
        par[P_EVALS] = integrator.evaluations
        par[P_HC] = 1.0 if self.hunt_crossley else 0.0
        par[P_ZMAX] = zmax
        # the anchor's displacement over a step, by the integrator's own position update:
        # velocity first (x += h v_new), position first (x += h v_old), else the trapezoid
        par[P_WOLD], par[P_WNOW] = {"velocity_first": (0.0, 1.0),
                                    "position_first": (1.0, 0.0)}.get(integrator.scheme,
                                                                       (0.5, 0.5))
        self.arg = PenaltyContacts(
            self.geometry, self.scratch, self.buf, par,
            np.array(values or [0.0]), np.array([self.zeta[e] for e in values] or [0.0]),
            np.zeros(capacity, np.int64), FeatureTable.empty(capacity, N_VAL),
            np.zeros(1, np.int64))
        self.h = None

    def _set_step(self, h: float) -> None:
        """Stiffness from the first step size (kept for the run)."""
        par = self.arg.par
        if self.h is None:
            self.h = h
            par[P_OMEGA] = 2.0 * math.pi / (_number(self.params, "period_steps") * h)
            om = par[P_OMEGA]
            par[P_DREF] = self._g / (om * om) if self._g > 0 else 1e-4
        par[P_H] = h

    def advance(self, state, n_steps: int, h: float) -> None:
        self._set_step(float(h))
        self.integrator.advance(self.model, state, None, self.arg, n_steps, h)

    def describe(self) -> dict[str, Any]:
        par = self.arg.par
        return {"model": "penalty", "parameters": dict(self.params),
                "omega0": float(par[P_OMEGA]), "stiffness_rule":
                "k = m_eff omega0^2 per pair, omega0 = 2 pi / (period_steps dt)",
                "damping": {str(e): z for e, z in self.zeta.items()},
                "damping_meaning": "B = beta v_in (Hunt-Crossley)" if self.hunt_crossley
                else "damping ratio zeta (Tsuji)",
                "restitution_effective": {
                    str(e): float(restitution_of(z, float(par[P_EXP]), self.hunt_crossley))
                    for e, z in self.zeta.items()},
                "evaluations_per_step": int(par[P_EVALS])}


def open_penalty(scene, model, integrator, parameters: dict | None = None) -> PenaltyStepper:
    return PenaltyStepper(scene, model, integrator, parameters)


# -- the force pass's entry points (contact_forces dispatches here) -------------------------------
@njit(**INLINE)
def _first_evaluation(pc):
    """True at the first force evaluation of a step (evaluations are counted per step)."""
    k = pc.counter[0]
    pc.counter[0] = k + 1
    return k % np.int64(pc.par[P_EVALS]) == 0


@njit(**INLINE)
def penalty_wrench3d(bodies, pc, x, q, v, w, F, T):
    first = _first_evaluation(pc)
    detect3d(pc.geometry, x, q, pc.buf)
    penalty_rows3d(bodies, pc, x, q, v, w, F, T, first)


@njit(**INLINE)
def penalty_wrench2d(bodies, pc, x, angle, v, w, F, T):
    first = _first_evaluation(pc)
    detect2d(pc.geometry, x, angle, pc.buf)
    penalty_rows2d(bodies, pc, x, angle, v, w, F, T, first)
