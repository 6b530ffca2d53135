"""3D kernels: the one implementation of the in-house rigid-body physics (numba, cached).

Every kernel takes the model's ``(bodies, gravity, springs, drag, loads)`` first (see model.py);
an effect the scene does not declare is ``None`` and its ``if ... is not None`` branch is removed
when numba compiles the specialisation for that scene, so the compiled step is composed of the
declared effects' kernels alone. The state is (x, q, P, L) as in Baraff's notes:

    dx/dt = P / m,   dq/dt = 1/2 (0, w) q,   dP/dt = F,   dL/dt = tau,
    w = R I_body^-1 R^T L,   R = R(q).

Integrators (registered with their properties in integrators.py) each have one ``advance_*``
kernel that takes ``n_steps`` steps in place, so Python is entered once per recorded sample.
There is no per-body Python loop anywhere in a step; the loops over bodies are compiled.
"""

from __future__ import annotations

import numpy as np
from numba import njit

# error_model="numpy": a division by zero gives inf/nan (a blow-up the driver reports), never a
# Python exception from inside a step. No fastmath: IEEE semantics keep NaN checks valid and
# results bit-identical from run to run.
JIT = {"cache": True, "nogil": True, "error_model": "numpy"}


# -- small vector helpers (scalars in, tuples out: no allocation) ------------------------------
@njit(**JIT)
def rotation_from_quat(q, i, R):
    """R[i] = R(q[i] / |q[i]|): valid for a quaternion slightly off unit length (RK stages)."""
    w, x, y, z = q[i, 0], q[i, 1], q[i, 2], q[i, 3]
    s = 2.0 / (w * w + x * x + y * y + z * z)
    R[i, 0, 0] = 1.0 - s * (y * y + z * z)
    R[i, 0, 1] = s * (x * y - w * z)
    R[i, 0, 2] = s * (x * z + w * y)
    R[i, 1, 0] = s * (x * y + w * z)
    R[i, 1, 1] = 1.0 - s * (x * x + z * z)
    R[i, 1, 2] = s * (y * z - w * x)
    R[i, 2, 0] = s * (x * z - w * y)
    R[i, 2, 1] = s * (y * z + w * x)
    R[i, 2, 2] = 1.0 - s * (x * x + y * y)


@njit(**JIT)
def quat_exp(tx, ty, tz):
    """Unit quaternion of the rotation vector (tx, ty, tz) (exponential map), safe near zero."""
    a2 = tx * tx + ty * ty + tz * tz
    if a2 < 1e-8:
        # cos(a/2) and sin(a/2)/a by their series; the next terms are below 1e-24.
        c = 1.0 - a2 / 8.0 + a2 * a2 / 384.0
        s = 0.5 - a2 / 48.0 + a2 * a2 / 3840.0
    else:
        a = np.sqrt(a2)
        c = np.cos(0.5 * a)
        s = np.sin(0.5 * a) / a
    return c, s * tx, s * ty, s * tz


@njit(**JIT)
def quat_mul(aw, ax, ay, az, bw, bx, by, bz):
    """Hamilton product a * b."""
    return (aw * bw - ax * bx - ay * by - az * bz,
            aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw)


@njit(**JIT)
def normalize_quats(q):
    for i in range(q.shape[0]):
        s = 1.0 / np.sqrt(q[i, 0] ** 2 + q[i, 1] ** 2 + q[i, 2] ** 2 + q[i, 3] ** 2)
        for c in range(4):
            q[i, c] *= s


@njit(**JIT)
def rotate_left(q0, i, tx, ty, tz, q_out):
    """q_out[i] = exp(t) * q0[i]: rotate body i by the world rotation vector t."""
    ew, ex, ey, ez = quat_exp(tx, ty, tz)
    q_out[i, 0], q_out[i, 1], q_out[i, 2], q_out[i, 3] = quat_mul(
        ew, ex, ey, ez, q0[i, 0], q0[i, 1], q0[i, 2], q0[i, 3])


# -- kinematics and effects ----------------------------------------------------------------------
@njit(**JIT)
def kinematics(bodies, q, P, L, R, v, w):
    """R = R(q); v = P / m; w = R I_body^-1 R^T L (world angular velocity)."""
    inv_i = bodies.inv_inertia
    for i in range(q.shape[0]):
        rotation_from_quat(q, i, R)
        im = bodies.inv_mass[i]
        v[i, 0] = P[i, 0] * im
        v[i, 1] = P[i, 1] * im
        v[i, 2] = P[i, 2] * im
        # body-frame angular momentum R^T L
        lb0 = R[i, 0, 0] * L[i, 0] + R[i, 1, 0] * L[i, 1] + R[i, 2, 0] * L[i, 2]
        lb1 = R[i, 0, 1] * L[i, 0] + R[i, 1, 1] * L[i, 1] + R[i, 2, 1] * L[i, 2]
        lb2 = R[i, 0, 2] * L[i, 0] + R[i, 1, 2] * L[i, 1] + R[i, 2, 2] * L[i, 2]
        wb0 = inv_i[i, 0, 0] * lb0 + inv_i[i, 0, 1] * lb1 + inv_i[i, 0, 2] * lb2
        wb1 = inv_i[i, 1, 0] * lb0 + inv_i[i, 1, 1] * lb1 + inv_i[i, 1, 2] * lb2
        wb2 = inv_i[i, 2, 0] * lb0 + inv_i[i, 2, 1] * lb1 + inv_i[i, 2, 2] * lb2
        w[i, 0] = R[i, 0, 0] * wb0 + R[i, 0, 1] * wb1 + R[i, 0, 2] * wb2
        w[i, 1] = R[i, 1, 0] * wb0 + R[i, 1, 1] * wb1 + R[i, 1, 2] * wb2
        w[i, 2] = R[i, 2, 0] * wb0 + R[i, 2, 1] * wb1 + R[i, 2, 2] * wb2


@njit(**JIT)
def apply_gravity(bodies, g, F):
    """F_i += m_i g (at the centre of mass: no torque)."""
    for i in range(F.shape[0]):
        m = bodies.mass[i]
        F[i, 0] += m * g[0]
        F[i, 1] += m * g[1]
        F[i, 2] += m * g[2]


@njit(**JIT)
def spring_point(x, R, v, w, body, r):
    """World offset, position and velocity of the body-frame point r (relative to the com)."""
    ox = R[body, 0, 0] * r[0] + R[body, 0, 1] * r[1] + R[body, 0, 2] * r[2]
    oy = R[body, 1, 0] * r[0] + R[body, 1, 1] * r[1] + R[body, 1, 2] * r[2]
    oz = R[body, 2, 0] * r[0] + R[body, 2, 1] * r[1] + R[body, 2, 2] * r[2]
    px = x[body, 0] + ox
    py = x[body, 1] + oy
    pz = x[body, 2] + oz
    vx = v[body, 0] + w[body, 1] * oz - w[body, 2] * oy
    vy = v[body, 1] + w[body, 2] * ox - w[body, 0] * oz
    vz = v[body, 2] + w[body, 0] * oy - w[body, 1] * ox
    return ox, oy, oz, px, py, pz, vx, vy, vz


@njit(**JIT)
def spring_force(springs, s, x, R, v, w):
    """Force on body a of spring s and the two world offsets: -(k (l - l0) + c dl/dt) e."""
    a = springs.a[s]
    b = springs.b[s]
    oax, oay, oaz, pax, pay, paz, vax, vay, vaz = spring_point(x, R, v, w, a, springs.ra[s])
    if b >= 0:
        obx, oby, obz, pbx, pby, pbz, vbx, vby, vbz = spring_point(x, R, v, w, b, springs.rb[s])
    else:
        obx = oby = obz = 0.0
        pbx, pby, pbz = springs.rb[s, 0], springs.rb[s, 1], springs.rb[s, 2]
        vbx = vby = vbz = 0.0
    dx, dy, dz = pax - pbx, pay - pby, paz - pbz
    length = np.sqrt(dx * dx + dy * dy + dz * dz)
    if length > 0.0:
        ex, ey, ez = dx / length, dy / length, dz / length
    else:
        ex = ey = ez = 0.0  # coincident points: the direction (and the force) is undefined -> 0
    rate = ex * (vax - vbx) + ey * (vay - vby) + ez * (vaz - vbz)
    mag = -(springs.stiffness[s] * (length - springs.rest_length[s])
            + springs.damping[s] * rate)
    return mag * ex, mag * ey, mag * ez, oax, oay, oaz, obx, oby, obz


@njit(**JIT)
def apply_springs(springs, x, R, v, w, F, T):
    """Spring-dampers at body-frame points: force on a and b, torque r x f about each com."""
    for s in range(springs.a.shape[0]):
        fx, fy, fz, oax, oay, oaz, obx, oby, obz = spring_force(springs, s, x, R, v, w)
        a = springs.a[s]
        F[a, 0] += fx
        F[a, 1] += fy
        F[a, 2] += fz
        T[a, 0] += oay * fz - oaz * fy
        T[a, 1] += oaz * fx - oax * fz
        T[a, 2] += oax * fy - oay * fx
        b = springs.b[s]
        if b >= 0:
            F[b, 0] -= fx
            F[b, 1] -= fy
            F[b, 2] -= fz
            T[b, 0] -= oby * fz - obz * fy
            T[b, 1] -= obz * fx - obx * fz
            T[b, 2] -= obx * fy - oby * fx


@njit(**JIT)
def apply_drag(drag, v, w, F, T):
    """F = -c v (centre of mass), tau = -c_w w (world)."""
    for i in range(F.shape[0]):
        cl = drag.linear[i]
        ca = drag.angular[i]
        for c in range(3):
            F[i, c] -= cl * v[i, c]
            T[i, c] -= ca * w[i, c]


@njit(**JIT)
def apply_loads(loads, F, T):
    for k in range(loads.body.shape[0]):
        i = loads.body[k]
        for c in range(3):
            F[i, c] += loads.force[k, c]
            T[i, c] += loads.torque[k, c]


@njit(**JIT)
def accumulate(bodies, gravity, springs, drag, loads, x, R, v, w, F, T):
    """Net force and torque from the declared effects only (None branches compile away)."""
    F[:] = 0.0
    T[:] = 0.0
    if gravity is not None:
        apply_gravity(bodies, gravity, F)
    if springs is not None:
        apply_springs(springs, x, R, v, w, F, T)
    if drag is not None:
        apply_drag(drag, v, w, F, T)
    if loads is not None:
        apply_loads(loads, F, T)


@njit(**JIT)
def evaluate(bodies, gravity, springs, drag, loads, x, q, P, L, R, v, w, F, T):
    """Kinematics then forces at the state (x, q, P, L)."""
    kinematics(bodies, q, P, L, R, v, w)
    accumulate(bodies, gravity, springs, drag, loads, x, R, v, w, F, T)


@njit(**JIT)
def quat_rate(q, w, dq):
    """dq/dt = 1/2 (0, w) * q with w in the world frame."""
    for i in range(q.shape[0]):
        qw, qx, qy, qz = q[i, 0], q[i, 1], q[i, 2], q[i, 3]
        wx, wy, wz = w[i, 0], w[i, 1], w[i, 2]
        dq[i, 0] = -0.5 * (wx * qx + wy * qy + wz * qz)
        dq[i, 1] = 0.5 * (wx * qw + wy * qz - wz * qy)
        dq[i, 2] = 0.5 * (wy * qw + wz * qx - wx * qz)
        dq[i, 3] = 0.5 * (wz * qw + wx * qy - wy * qx)


@njit(**JIT)
def derivative(bodies, gravity, springs, drag, loads, x, q, P, L, dx, dq, dP, dL):
    """The generic state derivative (dx, dq, dP, dL) = (v, 1/2 w q, F, tau) (solve_ivp etc.)."""
    n = x.shape[0]
    R = np.empty((n, 3, 3))
    w = np.empty((n, 3))
    evaluate(bodies, gravity, springs, drag, loads, x, q, P, L, R, dx, w, dP, dL)
    quat_rate(q, w, dq)


@njit(**JIT)
def observe(bodies, q, P, L, vel, omega):
    """Recorded quantities: centre-of-mass velocity and world angular velocity."""
    n = q.shape[0]
    R = np.empty((n, 3, 3))
    kinematics(bodies, q, P, L, R, vel, omega)


# -- explicit Runge-Kutta family (additive quaternion update, renormalised after the step) -------
@njit(**JIT)
def advance_explicit_euler(bodies, gravity, springs, drag, loads, x, q, P, L, n_steps, h):
    n = x.shape[0]
    R = np.empty((n, 3, 3))
    v = np.empty((n, 3))
    w = np.empty((n, 3))
    F = np.empty((n, 3))
    T = np.empty((n, 3))
    dq = np.empty((n, 4))
    for _ in range(n_steps):
        evaluate(bodies, gravity, springs, drag, loads, x, q, P, L, R, v, w, F, T)
        quat_rate(q, w, dq)
        for i in range(n):
            for c in range(3):
                x[i, c] += h * v[i, c]
                P[i, c] += h * F[i, c]
                L[i, c] += h * T[i, c]
            for c in range(4):
                q[i, c] += h * dq[i, c]
        normalize_quats(q)


@njit(**JIT)
def advance_midpoint(bodies, gravity, springs, drag, loads, x, q, P, L, n_steps, h):
    n = x.shape[0]
    R = np.empty((n, 3, 3))
    v = np.empty((n, 3))
    w = np.empty((n, 3))
    F = np.empty((n, 3))
    T = np.empty((n, 3))
    dq = np.empty((n, 4))
    xs = np.empty((n, 3))
    qs = np.empty((n, 4))
    Ps = np.empty((n, 3))
    Ls = np.empty((n, 3))
    hh = 0.5 * h
    for _ in range(n_steps):
        evaluate(bodies, gravity, springs, drag, loads, x, q, P, L, R, v, w, F, T)
        quat_rate(q, w, dq)
        for i in range(n):
            for c in range(3):
                xs[i, c] = x[i, c] + hh * v[i, c]
                Ps[i, c] = P[i, c] + hh * F[i, c]
                Ls[i, c] = L[i, c] + hh * T[i, c]
            for c in range(4):
                qs[i, c] = q[i, c] + hh * dq[i, c]
        evaluate(bodies, gravity, springs, drag, loads, xs, qs, Ps, Ls, R, v, w, F, T)
        quat_rate(qs, w, dq)
        for i in range(n):
            for c in range(3):
                x[i, c] += h * v[i, c]
                P[i, c] += h * F[i, c]
                L[i, c] += h * T[i, c]
            for c in range(4):
                q[i, c] += h * dq[i, c]
        normalize_quats(q)


@njit(**JIT)
def advance_rk4(bodies, gravity, springs, drag, loads, x, q, P, L, n_steps, h):
    """Classical RK4 on (x, q, P, L); q renormalised once per step (a projection, O(h^5))."""
    n = x.shape[0]
    R = np.empty((n, 3, 3))
    v = np.empty((n, 3))
    w = np.empty((n, 3))
    F = np.empty((n, 3))
    T = np.empty((n, 3))
    dq = np.empty((n, 4))
    xs = np.empty((n, 3))
    qs = np.empty((n, 4))
    Ps = np.empty((n, 3))
    Ls = np.empty((n, 3))
    ax = np.empty((n, 3))
    aq = np.empty((n, 4))
    aP = np.empty((n, 3))
    aL = np.empty((n, 3))
    hh = 0.5 * h
    h6 = h / 6.0
    for _ in range(n_steps):
        # k1 at y
        evaluate(bodies, gravity, springs, drag, loads, x, q, P, L, R, v, w, F, T)
        quat_rate(q, w, dq)
        for i in range(n):
            for c in range(3):
                ax[i, c] = v[i, c]
                aP[i, c] = F[i, c]
                aL[i, c] = T[i, c]
                xs[i, c] = x[i, c] + hh * v[i, c]
                Ps[i, c] = P[i, c] + hh * F[i, c]
                Ls[i, c] = L[i, c] + hh * T[i, c]
            for c in range(4):
                aq[i, c] = dq[i, c]
                qs[i, c] = q[i, c] + hh * dq[i, c]
        # k2 at y + h/2 k1, k3 at y + h/2 k2
        for stage in range(2):
            evaluate(bodies, gravity, springs, drag, loads, xs, qs, Ps, Ls, R, v, w, F, T)
            quat_rate(qs, w, dq)
            step = hh if stage == 0 else h
            for i in range(n):
                for c in range(3):
                    ax[i, c] += 2.0 * v[i, c]
                    aP[i, c] += 2.0 * F[i, c]
                    aL[i, c] += 2.0 * T[i, c]
                    xs[i, c] = x[i, c] + step * v[i, c]
                    Ps[i, c] = P[i, c] + step * F[i, c]
                    Ls[i, c] = L[i, c] + step * T[i, c]
                for c in range(4):
                    aq[i, c] += 2.0 * dq[i, c]
                    qs[i, c] = q[i, c] + step * dq[i, c]
        # k4 at y + h k3
        evaluate(bodies, gravity, springs, drag, loads, xs, qs, Ps, Ls, R, v, w, F, T)
        quat_rate(qs, w, dq)
        for i in range(n):
            for c in range(3):
                x[i, c] += h6 * (ax[i, c] + v[i, c])
                P[i, c] += h6 * (aP[i, c] + F[i, c])
                L[i, c] += h6 * (aL[i, c] + T[i, c])
            s2 = 0.0
            for c in range(4):
                q[i, c] += h6 * (aq[i, c] + dq[i, c])
                s2 += q[i, c] * q[i, c]
            s = 1.0 / np.sqrt(s2)
            for c in range(4):
                q[i, c] *= s


@njit(**JIT)
def _dexpinv(tx, ty, tz, wx, wy, wz):
    """dexp^-1_theta(w) truncated for order 4: w - 1/2 theta x w + 1/12 theta x (theta x w)."""
    cx = ty * wz - tz * wy
    cy = tz * wx - tx * wz
    cz = tx * wy - ty * wx
    ccx = ty * cz - tz * cy
    ccy = tz * cx - tx * cz
    ccz = tx * cy - ty * cx
    return (wx - 0.5 * cx + ccx / 12.0, wy - 0.5 * cy + ccy / 12.0, wz - 0.5 * cz + ccz / 12.0)


@njit(**JIT)
def advance_rk4_exp(bodies, gravity, springs, drag, loads, x, q, P, L, n_steps, h):
    """RK4 with the Runge-Kutta-Munthe-Kaas rotation update (order 4, |q| = 1 by construction).

    x, P, L take the classical RK4 stages. The orientation is never updated additively: stage i
    sits at q_i = exp(theta_i) q_n, its angular velocity is pulled back to the Lie algebra with
    dexp^-1 (truncated after the theta^2 term, enough for order 4) and the step is
    q_{n+1} = exp(h/6 (u1 + 2 u2 + 2 u3 + u4)) q_n.
    """
    n = x.shape[0]
    R = np.empty((n, 3, 3))
    v = np.empty((n, 3))
    w = np.empty((n, 3))
    F = np.empty((n, 3))
    T = np.empty((n, 3))
    xs = np.empty((n, 3))
    qs = np.empty((n, 4))
    Ps = np.empty((n, 3))
    Ls = np.empty((n, 3))
    ax = np.empty((n, 3))
    aP = np.empty((n, 3))
    aL = np.empty((n, 3))
    au = np.empty((n, 3))
    th = np.empty((n, 3))
    hh = 0.5 * h
    h6 = h / 6.0
    for _ in range(n_steps):
        evaluate(bodies, gravity, springs, drag, loads, x, q, P, L, R, v, w, F, T)
        for i in range(n):
            for c in range(3):
                ax[i, c] = v[i, c]
                aP[i, c] = F[i, c]
                aL[i, c] = T[i, c]
                au[i, c] = w[i, c]
                xs[i, c] = x[i, c] + hh * v[i, c]
                Ps[i, c] = P[i, c] + hh * F[i, c]
                Ls[i, c] = L[i, c] + hh * T[i, c]
                th[i, c] = hh * w[i, c]
            rotate_left(q, i, th[i, 0], th[i, 1], th[i, 2], qs)
        for stage in range(3):
            evaluate(bodies, gravity, springs, drag, loads, xs, qs, Ps, Ls, R, v, w, F, T)
            weight = 2.0 if stage < 2 else 1.0
            step = hh if stage == 0 else h
            for i in range(n):
                ux, uy, uz = _dexpinv(th[i, 0], th[i, 1], th[i, 2], w[i, 0], w[i, 1], w[i, 2])
                au[i, 0] += weight * ux
                au[i, 1] += weight * uy
                au[i, 2] += weight * uz
                for c in range(3):
                    ax[i, c] += weight * v[i, c]
                    aP[i, c] += weight * F[i, c]
                    aL[i, c] += weight * T[i, c]
                if stage < 2:
                    for c in range(3):
                        xs[i, c] = x[i, c] + step * v[i, c]
                        Ps[i, c] = P[i, c] + step * F[i, c]
                        Ls[i, c] = L[i, c] + step * T[i, c]
                    th[i, 0] = step * ux
                    th[i, 1] = step * uy
                    th[i, 2] = step * uz
                    rotate_left(q, i, th[i, 0], th[i, 1], th[i, 2], qs)
        for i in range(n):
            for c in range(3):
                x[i, c] += h6 * ax[i, c]
                P[i, c] += h6 * aP[i, c]
                L[i, c] += h6 * aL[i, c]
            rotate_left(q, i, h6 * au[i, 0], h6 * au[i, 1], h6 * au[i, 2], q)
        normalize_quats(q)  # round-off only: exp maps keep |q| = 1 exactly in exact arithmetic


# -- symplectic family: kick / drift, free rotation by exact sub-rotations about principal axes --
@njit(**JIT)
def free_rotation(bodies, q, L, i, h, strang):
    """Drift of the free rotor for time h with world L fixed, by splitting (Dullweber, Reich and
    Leimkuhler 1997): T = sum_k Lb_k^2 / 2 I_k is split into the three principal-axis terms,
    each flowing exactly as a rotation of the body about its principal axis k by
    h Lb_k / I_k (Lb_k is constant along that sub-flow). Every sub-flow is a symplectic map that
    keeps |L| and the sub-energy exactly; Lie-Trotter (1, 2, 3) is first order, Strang
    (1, 2, 3, 2, 1 with half steps outside) second order and time-reversible.
    """
    w0, x0, y0, z0 = q[i, 0], q[i, 1], q[i, 2], q[i, 3]
    s = 2.0 / (w0 * w0 + x0 * x0 + y0 * y0 + z0 * z0)
    r00 = 1.0 - s * (y0 * y0 + z0 * z0)
    r01 = s * (x0 * y0 - w0 * z0)
    r02 = s * (x0 * z0 + w0 * y0)
    r10 = s * (x0 * y0 + w0 * z0)
    r11 = 1.0 - s * (x0 * x0 + z0 * z0)
    r12 = s * (y0 * z0 - w0 * x0)
    r20 = s * (x0 * z0 - w0 * y0)
    r21 = s * (y0 * z0 + w0 * x0)
    r22 = 1.0 - s * (x0 * x0 + y0 * y0)
    lb0 = r00 * L[i, 0] + r10 * L[i, 1] + r20 * L[i, 2]
    lb1 = r01 * L[i, 0] + r11 * L[i, 1] + r21 * L[i, 2]
    lb2 = r02 * L[i, 0] + r12 * L[i, 1] + r22 * L[i, 2]
    n_sub = 5 if strang else 3
    for j in range(n_sub):
        if strang:
            k = j if j < 3 else 4 - j
            frac = 1.0 if j == 2 else 0.5
        else:
            k = j
            frac = 1.0
        ax = bodies.principal_axes[i, 0, k]
        ay = bodies.principal_axes[i, 1, k]
        az = bodies.principal_axes[i, 2, k]
        along = ax * lb0 + ay * lb1 + az * lb2
        alpha = frac * h * along / bodies.principal_moments[i, k]
        c = np.cos(0.5 * alpha)
        sn = np.sin(0.5 * alpha)
        # body-frame rotation: q <- q * (cos, sin a)
        w0, x0, y0, z0 = quat_mul(w0, x0, y0, z0, c, sn * ax, sn * ay, sn * az)
        # the fixed world L seen from the rotated body turns by -alpha about a (Rodrigues)
        ca = np.cos(alpha)
        sa = np.sin(alpha)
        cx = ay * lb2 - az * lb1
        cy = az * lb0 - ax * lb2
        cz = ax * lb1 - ay * lb0
        lb0 = lb0 * ca - cx * sa + ax * along * (1.0 - ca)
        lb1 = lb1 * ca - cy * sa + ay * along * (1.0 - ca)
        lb2 = lb2 * ca - cz * sa + az * along * (1.0 - ca)
    s = 1.0 / np.sqrt(w0 * w0 + x0 * x0 + y0 * y0 + z0 * z0)
    q[i, 0] = w0 * s
    q[i, 1] = x0 * s
    q[i, 2] = y0 * s
    q[i, 3] = z0 * s


@njit(**JIT)
def advance_symplectic_euler(bodies, gravity, springs, drag, loads, x, q, P, L, n_steps, h):
    """Kick P, L by h with the forces at the start; drift x by h P/m and the orientation by the
    exact principal-axis sub-rotations (Lie-Trotter) with the new L."""
    n = x.shape[0]
    R = np.empty((n, 3, 3))
    v = np.empty((n, 3))
    w = np.empty((n, 3))
    F = np.empty((n, 3))
    T = np.empty((n, 3))
    for _ in range(n_steps):
        evaluate(bodies, gravity, springs, drag, loads, x, q, P, L, R, v, w, F, T)
        for i in range(n):
            im = bodies.inv_mass[i]
            for c in range(3):
                P[i, c] += h * F[i, c]
                L[i, c] += h * T[i, c]
                x[i, c] += h * P[i, c] * im
            free_rotation(bodies, q, L, i, h, False)


@njit(**JIT)
def advance_symplectic_euler_exp(bodies, gravity, springs, drag, loads, x, q, P, L, n_steps, h):
    """Kick then drift, the rotation drift as one exponential map q <- exp(h w) q with
    w = I(q_n)^-1 L_{n+1}: the semi-implicit Euler of game engines. Symplectic for the
    translation; the rotation is explicit in w(q) (|q| stays 1, but a tumbling asymmetric body's
    energy drifts at O(h))."""
    n = x.shape[0]
    R = np.empty((n, 3, 3))
    v = np.empty((n, 3))
    w = np.empty((n, 3))
    F = np.empty((n, 3))
    T = np.empty((n, 3))
    for _ in range(n_steps):
        evaluate(bodies, gravity, springs, drag, loads, x, q, P, L, R, v, w, F, T)
        for i in range(n):
            im = bodies.inv_mass[i]
            for c in range(3):
                P[i, c] += h * F[i, c]
                L[i, c] += h * T[i, c]
                x[i, c] += h * P[i, c] * im
        kinematics(bodies, q, P, L, R, v, w)  # w from the kicked L and the start orientation
        for i in range(n):
            rotate_left(q, i, h * w[i, 0], h * w[i, 1], h * w[i, 2], q)
        normalize_quats(q)


@njit(**JIT)
def advance_verlet(bodies, gravity, springs, drag, loads, x, q, P, L, n_steps, h):
    """Velocity Verlet: half kick, drift (x by h P/m, orientation by the Strang principal-axis
    splitting), half kick with the forces at the new configuration.

    Velocity-dependent forces (spring damping, drag) in the closing half kick use the momenta
    extrapolated to the end of the step, 2 P_half - P_n (error O(h^2), so the scheme stays second
    order with damping); without them the scheme is symplectic and time-reversible.
    """
    n = x.shape[0]
    R = np.empty((n, 3, 3))
    v = np.empty((n, 3))
    w = np.empty((n, 3))
    F = np.empty((n, 3))
    T = np.empty((n, 3))
    Pp = np.empty((n, 3))
    Lp = np.empty((n, 3))
    hh = 0.5 * h
    for _ in range(n_steps):
        evaluate(bodies, gravity, springs, drag, loads, x, q, P, L, R, v, w, F, T)
        for i in range(n):
            im = bodies.inv_mass[i]
            for c in range(3):
                p_old = P[i, c]
                l_old = L[i, c]
                P[i, c] += hh * F[i, c]
                L[i, c] += hh * T[i, c]
                Pp[i, c] = 2.0 * P[i, c] - p_old
                Lp[i, c] = 2.0 * L[i, c] - l_old
                x[i, c] += h * P[i, c] * im
            free_rotation(bodies, q, L, i, h, True)
        evaluate(bodies, gravity, springs, drag, loads, x, q, Pp, Lp, R, v, w, F, T)
        for i in range(n):
            for c in range(3):
                P[i, c] += hh * F[i, c]
                L[i, c] += hh * T[i, c]
