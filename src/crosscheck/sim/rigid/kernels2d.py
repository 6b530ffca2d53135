"""2D kernels: the planar specialisation (scalar angle and angular momentum), numba, cached.

State (x (N, 2), angle (N,), P (N, 2), L (N,)); dx/dt = P/m, dangle/dt = L/I, dP/dt = F,
dL/dt = tau with tau = r x f = r_x f_y - r_y f_x. The angle is a coordinate of a vector space,
so every rotation update here is exact bookkeeping (no normalisation, and the exponential map of
SO(2) is the addition of angles): the 2D variants of ``rk4_exp`` and ``symplectic_euler_exp`` are
the same kernels as ``rk4`` and ``symplectic_euler``. Effects, ``control`` and the ``contacts``
slot are composed as in kernels3d.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from crosscheck.sim.rigid.kernels3d import INLINE, JIT


@njit(**JIT)
def kinematics(bodies, P, L, v, w):
    for i in range(P.shape[0]):
        v[i, 0] = P[i, 0] * bodies.inv_mass[i]
        v[i, 1] = P[i, 1] * bodies.inv_mass[i]
        w[i] = L[i] * bodies.inv_moment[i]


@njit(**JIT)
def apply_gravity(bodies, g, F):
    for i in range(F.shape[0]):
        F[i, 0] += bodies.mass[i] * g[0]
        F[i, 1] += bodies.mass[i] * g[1]


@njit(**INLINE)
def spring_point(x, angle, v, w, body, r):
    """World offset, position and velocity of the body-frame point r (relative to the com)."""
    c = np.cos(angle[body])
    s = np.sin(angle[body])
    ox = c * r[0] - s * r[1]
    oy = s * r[0] + c * r[1]
    return (ox, oy, x[body, 0] + ox, x[body, 1] + oy,
            v[body, 0] - w[body] * oy, v[body, 1] + w[body] * ox)


@njit(**INLINE)
def spring_ends(springs, s, x, angle, v, w):
    """Spring s's two world offsets (from the centres of mass; zero at a world anchor) and the
    position and velocity of end a relative to end b."""
    oax, oay, pax, pay, vax, vay = spring_point(x, angle, v, w, springs.a[s], springs.ra[s])
    if springs.b[s] >= 0:
        obx, oby, pbx, pby, vbx, vby = spring_point(x, angle, v, w, springs.b[s], springs.rb[s])
    else:
        obx = oby = 0.0
        pbx, pby = springs.rb[s, 0], springs.rb[s, 1]
        vbx = vby = 0.0
    return oax, oay, obx, oby, pax - pbx, pay - pby, vax - vbx, vay - vby


@njit(**INLINE)
def spring_force(springs, s, x, angle, v, w):
    """Force on body a of spring s and the two world offsets: -(k (l - l0) + c dl/dt) e."""
    oax, oay, obx, oby, dx, dy, dvx, dvy = spring_ends(springs, s, x, angle, v, w)
    length = np.sqrt(dx * dx + dy * dy)
    if length > 0.0:
        ex, ey = dx / length, dy / length
    else:
        ex = ey = 0.0  # coincident points: the direction (and the force) is undefined -> 0
    rate = ex * dvx + ey * dvy
    mag = -(springs.stiffness[s] * (length - springs.rest_length[s])
            + springs.damping[s] * rate)
    return mag * ex, mag * ey, oax, oay, obx, oby


@njit(**JIT)
def apply_springs(springs, x, angle, v, w, F, T):
    for s in range(springs.a.shape[0]):
        fx, fy, oax, oay, obx, oby = spring_force(springs, s, x, angle, v, w)
        a = springs.a[s]
        F[a, 0] += fx
        F[a, 1] += fy
        T[a] += oax * fy - oay * fx
        b = springs.b[s]
        if b >= 0:
            F[b, 0] -= fx
            F[b, 1] -= fy
            T[b] -= obx * fy - oby * fx


@njit(**JIT)
def apply_drag(drag, v, w, F, T):
    for i in range(F.shape[0]):
        F[i, 0] -= drag.linear[i] * v[i, 0]
        F[i, 1] -= drag.linear[i] * v[i, 1]
        T[i] -= drag.angular[i] * w[i]


@njit(**JIT)
def apply_loads(loads, F, T):
    for k in range(loads.body.shape[0]):
        i = loads.body[k]
        F[i, 0] += loads.force[k, 0]
        F[i, 1] += loads.force[k, 1]
        T[i] += loads.torque[k]


@njit(**JIT)
def apply_control(control, F, T):
    for i in range(F.shape[0]):
        F[i, 0] += control.force[i, 0]
        F[i, 1] += control.force[i, 1]
        T[i] += control.torque[i]


@njit(**JIT)
def accumulate(springs, drag, loads, control, x, angle, v, w, F, T):
    """F, T += the smooth force law at world-frame planar states: the one implementation of
    springs, drag, loads and the control's wrench in 2D, shared by the in-house force pass and
    PyBullet's adapter (its planar-joint bodies).

    x (N, 2) centres of mass, angle (N,) the rotations of the frames the springs' offsets are
    stored in, v (N, 2), w (N,) velocities, world frame; F (N, 2), T (N,) hold what came before
    (the in-house pass: gravity) and are added to in this order: springs, drag, loads, control.
    An effect given as ``None`` leaves no code (numba prunes its branch).
    """
    if springs is not None:
        apply_springs(springs, x, angle, v, w, F, T)
    if drag is not None:
        apply_drag(drag, v, w, F, T)
    if loads is not None:
        apply_loads(loads, F, T)
    if control is not None:  # external wrenches (model.Control), after the scene's effects
        apply_control(control, F, T)


@njit(**JIT)
def accumulate_rows(springs, drag, loads, rows, x, angle, v, w, F, T):
    """F, T = the force law (``accumulate``, no gravity, no control) at states given as rows
    (N, 6): centre of mass (2), angle, centre-of-mass velocity (2), angular velocity: the
    coordinates and rates of PyBullet's planar joints. x, angle, v, w are filled from the rows
    (scratch for the caller: PyBullet's adapter, once per step)."""
    for i in range(rows.shape[0]):
        x[i, 0] = rows[i, 0]
        x[i, 1] = rows[i, 1]
        angle[i] = rows[i, 2]
        v[i, 0] = rows[i, 3]
        v[i, 1] = rows[i, 4]
        w[i] = rows[i, 5]
    F[:] = 0.0
    T[:] = 0.0
    accumulate(springs, drag, loads, None, x, angle, v, w, F, T)


@njit(**JIT)
def evaluate(bodies, gravity, springs, drag, loads, control, contacts, x, angle, P, L, v, w, F, T):
    """Kinematics, gravity, then ``accumulate`` (springs, drag, loads, control)."""
    kinematics(bodies, P, L, v, w)
    F[:] = 0.0
    T[:] = 0.0
    if gravity is not None:
        apply_gravity(bodies, gravity, F)
    accumulate(springs, drag, loads, control, x, angle, v, w, F, T)


@njit(**JIT)
def derivative(bodies, gravity, springs, drag, loads, control, contacts,
               x, angle, P, L, dx, dangle, dP, dL):
    evaluate(bodies, gravity, springs, drag, loads, control, contacts,
             x, angle, P, L, dx, dangle, dP, dL)


@njit(**JIT)
def observe(bodies, P, L, vel, omega):
    kinematics(bodies, P, L, vel, omega)


# -- scratch arrays and the per-body state updates every integrator is written with ---------------
# As in kernels3d: scratch allocated once per call, each stage one pass over the bodies, and the
# inlined helpers keep the exact floating-point expressions (``y + s * k``) of the hand-written
# loops they replaced.
@njit(**INLINE)
def state_scratch(n):
    """Arrays shaped like the state (x, angle, P, L) and like its derivative (v, w, F, T): a
    stage state, a Runge-Kutta accumulator or what ``evaluate`` fills."""
    return np.empty((n, 2)), np.empty(n), np.empty((n, 2)), np.empty(n)


@njit(**INLINE)
def copy_state(i, dst_x, dst_angle, dst_P, dst_L, v, w, F, T):
    """Body i of dst = k = (v, w, F, tau): a Runge-Kutta accumulator's first stage."""
    for c in range(2):
        dst_x[i, c] = v[i, c]
        dst_P[i, c] = F[i, c]
    dst_angle[i] = w[i]
    dst_L[i] = T[i]


@njit(**INLINE)
def axpy_state(i, s, dst_x, dst_angle, dst_P, dst_L, x, angle, P, L, v, w, F, T):
    """Body i of dst = y + s k, y = (x, angle, P, L), k = (v, w, F, tau); dst may be y (in place)
    or k's accumulator."""
    for c in range(2):
        dst_x[i, c] = x[i, c] + s * v[i, c]
        dst_P[i, c] = P[i, c] + s * F[i, c]
    dst_angle[i] = angle[i] + s * w[i]
    dst_L[i] = L[i] + s * T[i]


@njit(**INLINE)
def axpy_sum_state(i, s, x, angle, P, L, ax, aA, aP, aL, v, w, F, T):
    """Body i of y += s (a + k): the Runge-Kutta step from an accumulator a and the last stage k."""
    for c in range(2):
        x[i, c] += s * (ax[i, c] + v[i, c])
        P[i, c] += s * (aP[i, c] + F[i, c])
    angle[i] += s * (aA[i] + w[i])
    L[i] += s * (aL[i] + T[i])


@njit(**INLINE)
def kick(i, s, P, L, F, T):
    """P += s F, L += s tau for body i."""
    for c in range(2):
        P[i, c] += s * F[i, c]
    L[i] += s * T[i]


@njit(**INLINE)
def kick_drift(bodies, i, h, x, angle, P, L, F, T):
    """Body i: P += h F, then x += h P / m with the new P; the same for L and the angle. (Each
    coordinate's kick and drift kept together: split into a kick and a drift pass over the body,
    the gravity-only step ran 15 % slower, measured.)"""
    for c in range(2):
        P[i, c] += h * F[i, c]
        x[i, c] += h * P[i, c] * bodies.inv_mass[i]
    L[i] += h * T[i]
    angle[i] += h * L[i] * bodies.inv_moment[i]


# -- explicit Runge-Kutta family -------------------------------------------------------------------
@njit(**JIT)
def advance_explicit_euler(bodies, gravity, springs, drag, loads, control, contacts,
                           x, angle, P, L, n_steps, h):
    n = x.shape[0]
    v, w, F, T = state_scratch(n)
    for _ in range(n_steps):
        evaluate(bodies, gravity, springs, drag, loads, control, contacts,
                 x, angle, P, L, v, w, F, T)
        for i in range(n):  # y += h f(y)
            axpy_state(i, h, x, angle, P, L, x, angle, P, L, v, w, F, T)


@njit(**JIT)
def advance_midpoint(bodies, gravity, springs, drag, loads, control, contacts,
                     x, angle, P, L, n_steps, h):
    n = x.shape[0]
    v, w, F, T = state_scratch(n)
    xs, As, Ps, Ls = state_scratch(n)
    hh = 0.5 * h
    for _ in range(n_steps):
        evaluate(bodies, gravity, springs, drag, loads, control, contacts,
                 x, angle, P, L, v, w, F, T)
        for i in range(n):  # ys = y + h/2 f(y)
            axpy_state(i, hh, xs, As, Ps, Ls, x, angle, P, L, v, w, F, T)
        evaluate(bodies, gravity, springs, drag, loads, control, contacts,
                 xs, As, Ps, Ls, v, w, F, T)
        for i in range(n):  # y += h f(ys)
            axpy_state(i, h, x, angle, P, L, x, angle, P, L, v, w, F, T)


@njit(**JIT)
def advance_rk4(bodies, gravity, springs, drag, loads, control, contacts,
                x, angle, P, L, n_steps, h):
    n = x.shape[0]
    v, w, F, T = state_scratch(n)
    xs, As, Ps, Ls = state_scratch(n)  # the stage state
    ax, aA, aP, aL = state_scratch(n)  # k1 + 2 k2 + 2 k3 (+ k4)
    hh = 0.5 * h
    h6 = h / 6.0
    for _ in range(n_steps):
        # k1 at y: a = k1; ys = y + h/2 k1
        evaluate(bodies, gravity, springs, drag, loads, control, contacts,
                 x, angle, P, L, v, w, F, T)
        for i in range(n):
            copy_state(i, ax, aA, aP, aL, v, w, F, T)
            axpy_state(i, hh, xs, As, Ps, Ls, x, angle, P, L, v, w, F, T)
        # k2 at y + h/2 k1, k3 at y + h/2 k2: a += 2 k; the next stage from y
        for stage in range(2):
            evaluate(bodies, gravity, springs, drag, loads, control, contacts,
                     xs, As, Ps, Ls, v, w, F, T)
            step = hh if stage == 0 else h
            for i in range(n):
                axpy_state(i, 2.0, ax, aA, aP, aL, ax, aA, aP, aL, v, w, F, T)
                axpy_state(i, step, xs, As, Ps, Ls, x, angle, P, L, v, w, F, T)
        # k4 at y + h k3; the step y += h/6 (a + k4)
        evaluate(bodies, gravity, springs, drag, loads, control, contacts,
                 xs, As, Ps, Ls, v, w, F, T)
        for i in range(n):
            axpy_sum_state(i, h6, x, angle, P, L, ax, aA, aP, aL, v, w, F, T)


# -- symplectic family: kick, then drift with the new momenta ----------------------------------
@njit(**JIT)
def advance_symplectic_euler(bodies, gravity, springs, drag, loads, control, contacts,
                             x, angle, P, L, n_steps, h):
    n = x.shape[0]
    v, w, F, T = state_scratch(n)
    for _ in range(n_steps):
        evaluate(bodies, gravity, springs, drag, loads, control, contacts,
                 x, angle, P, L, v, w, F, T)
        for i in range(n):
            kick_drift(bodies, i, h, x, angle, P, L, F, T)


@njit(**JIT)
def advance_verlet(bodies, gravity, springs, drag, loads, control, contacts,
                   x, angle, P, L, n_steps, h):
    """Velocity Verlet; velocity-dependent forces of the closing half kick use 2 P_half - P_n."""
    n = x.shape[0]
    v, w, F, T = state_scratch(n)
    Pp = np.empty((n, 2))
    Lp = np.empty(n)
    hh = 0.5 * h
    for _ in range(n_steps):
        evaluate(bodies, gravity, springs, drag, loads, control, contacts,
                 x, angle, P, L, v, w, F, T)
        for i in range(n):  # half kick and drift; 2 P_half - P_n for the closing half kick
            for c in range(2):
                p_old = P[i, c]
                P[i, c] += hh * F[i, c]
                Pp[i, c] = 2.0 * P[i, c] - p_old
                x[i, c] += h * P[i, c] * bodies.inv_mass[i]
            l_old = L[i]
            L[i] += hh * T[i]
            Lp[i] = 2.0 * L[i] - l_old
            angle[i] += h * L[i] * bodies.inv_moment[i]
        evaluate(bodies, gravity, springs, drag, loads, control, contacts,
                 x, angle, Pp, Lp, v, w, F, T)
        for i in range(n):
            kick(i, hh, P, L, F, T)


# -- implicit Euler (the method is described in implicit.py) -------------------------------
@njit(**INLINE)
def drag_coefficients(drag, i):
    """Body i's linear and angular drag coefficients (D's diagonal blocks are -c 1, -c_w)."""
    if drag is not None:
        return drag.linear[i], drag.angular[i]
    return 0.0, 0.0


@njit(**JIT)
def spring_jacobian_2d(springs, s, x, angle, v, w, Ks, Ds):
    """K, D (6 x 6) of spring s's wrench (f, oa x f, -f, -ob x f) on (x_a, th_a, x_b, th_b)."""
    a = springs.a[s]
    b = springs.b[s]
    oax, oay, obx, oby, dx, dy, dvx, dvy = spring_ends(springs, s, x, angle, v, w)
    d = np.array([dx, dy])
    dv = np.array([dvx, dvy])
    k = springs.stiffness[s]
    c = springs.damping[s]
    l0 = springs.rest_length[s]
    length = np.sqrt(d[0] ** 2 + d[1] ** 2)
    Kd = np.zeros((2, 2))
    Dd = np.zeros((2, 2))
    f = np.zeros(2)
    if length > 0.0:
        e = d / length
        rate = e[0] * dv[0] + e[1] * dv[1]
        mag = -(k * (length - l0) + c * rate)
        pdv = dv - rate * e
        for r in range(2):
            f[r] = mag * e[r]
            for col in range(2):
                proj = (1.0 if r == col else 0.0) - e[r] * e[col]
                Kd[r, col] = (-k * ((1.0 if r == col else 0.0) - l0 / length * proj)
                              - c * (e[r] * pdv[col] + rate * proj) / length)
                Dd[r, col] = -c * e[r] * e[col]
    else:
        Kd[0, 0] = -k
        Kd[1, 1] = -k
    # d(point) = dx + dth perp(o), perp(o) = (-o_y, o_x)
    J = np.zeros((2, 6))
    J[0, 0] = 1.0
    J[1, 1] = 1.0
    J[0, 2] = -oay
    J[1, 2] = oax
    J[0, 3] = -1.0
    J[1, 4] = -1.0
    J[0, 5] = oby
    J[1, 5] = -obx
    # turning the arm changes the point velocity w perp(o): d/dth = -w o
    H = np.zeros((2, 6))
    H[0, 2] = -w[a] * oax
    H[1, 2] = -w[a] * oay
    if b >= 0:
        H[0, 5] = w[b] * obx
        H[1, 5] = w[b] * oby
    Ks[:, :] = J.T @ (Kd @ J + Dd @ H)
    Ds[:, :] = J.T @ (Dd @ J)
    # d(oa x f)/dth_a from turning oa: -(oa . f); d(-ob x f)/dth_b: +(ob . f)
    Ks[2, 2] -= oax * f[0] + oay * f[1]
    Ks[5, 5] += obx * f[0] + oby * f[1]


@njit(**JIT)
def assemble_2d(bodies, gravity, springs, drag, loads, control, contacts, x, angle, P, L, h,
                v, w, F, T, rows, cols, vals, rhs):
    n = x.shape[0]
    evaluate(bodies, gravity, springs, drag, loads, control, contacts, x, angle, P, L, v, w, F, T)
    nnz = 0
    for i in range(n):
        cl, ca = drag_coefficients(drag, i)
        for c in range(2):
            rows[nnz] = 3 * i + c
            cols[nnz] = 3 * i + c
            vals[nnz] = bodies.mass[i] + h * cl
            nnz += 1
            rhs[3 * i + c] = h * F[i, c]
        rows[nnz] = 3 * i + 2
        cols[nnz] = 3 * i + 2
        vals[nnz] = bodies.moment[i] + h * ca
        nnz += 1
        rhs[3 * i + 2] = h * T[i]
    if springs is not None:
        Ks = np.empty((6, 6))
        Ds = np.empty((6, 6))
        u0 = np.zeros(6)
        dof = np.empty(6, dtype=np.int64)
        for s in range(springs.a.shape[0]):
            spring_jacobian_2d(springs, s, x, angle, v, w, Ks, Ds)
            a = springs.a[s]
            b = springs.b[s]
            m = 6 if b >= 0 else 3
            for c in range(2):
                dof[c] = 3 * a + c
                u0[c] = v[a, c]
                if b >= 0:
                    dof[3 + c] = 3 * b + c
                    u0[3 + c] = v[b, c]
            dof[2] = 3 * a + 2
            u0[2] = w[a]
            if b >= 0:
                dof[5] = 3 * b + 2
                u0[5] = w[b]
            for r in range(m):
                ku = 0.0
                for col in range(m):
                    ku += Ks[r, col] * u0[col]
                    rows[nnz] = dof[r]
                    cols[nnz] = dof[col]
                    vals[nnz] = -h * Ds[r, col] - h * h * Ks[r, col]
                    nnz += 1
                rhs[dof[r]] += h * h * ku
    return nnz


@njit(**JIT)
def finish_2d(bodies, x, angle, P, L, w, h, du):
    for i in range(x.shape[0]):
        for c in range(2):
            P[i, c] += bodies.mass[i] * du[3 * i + c]
            x[i, c] += h * P[i, c] * bodies.inv_mass[i]
        L[i] += bodies.moment[i] * du[3 * i + 2]
        angle[i] += h * (w[i] + du[3 * i + 2])


@njit(**JIT)
def advance_local_2d(bodies, gravity, springs, drag, loads, control, contacts,
                     x, angle, P, L, n_steps, h):
    n = x.shape[0]
    v, w, F, T = state_scratch(n)
    du = np.empty(3 * n)
    for _ in range(n_steps):
        evaluate(bodies, gravity, springs, drag, loads, control, contacts,
                 x, angle, P, L, v, w, F, T)
        for i in range(n):
            cl, ca = drag_coefficients(drag, i)
            du[3 * i] = h * F[i, 0] / (bodies.mass[i] + h * cl)
            du[3 * i + 1] = h * F[i, 1] / (bodies.mass[i] + h * cl)
            du[3 * i + 2] = h * T[i] / (bodies.moment[i] + h * ca)
        finish_2d(bodies, x, angle, P, L, w, h, du)
