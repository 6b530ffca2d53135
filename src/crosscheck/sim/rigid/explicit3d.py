"""3D explicit Runge-Kutta family: explicit Euler, midpoint, RK4 (additive quaternion stages,
renormalised after the step) and RK4 with the Runge-Kutta-Munthe-Kaas rotation update.

Each integrator has one ``advance_*`` kernel that takes ``n_steps`` steps in place, so Python is
entered once per recorded sample; the loops over bodies are compiled. Each kernel allocates its
scratch once per call (not per step) and updates body by body inside its loops over bodies, so
one pass does a whole stage (rate, accumulator, next stage state) while the body's data are in
cache. The per-body helpers are inlined: they keep the fixed trip counts (3 and 4, unrolled) and
the exact floating-point expressions (``y + s * k``) of the hand-written loops they replaced.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from crosscheck.sim._jit import INLINE, JIT
from crosscheck.sim.rigid.forces3d import evaluate, force_scratch
from crosscheck.sim.rigid.math3d import (
    normalize_quat,
    normalize_quats,
    quat_rate,
    quat_rate_of,
    rotate_left,
)


@njit(**INLINE)
def state_scratch(n):
    """Arrays shaped like the state (x, q, P, L): a stage state or a Runge-Kutta accumulator."""
    return np.empty((n, 3)), np.empty((n, 4)), np.empty((n, 3)), np.empty((n, 3))


@njit(**INLINE)
def copy_xPL(i, dst_x, dst_P, dst_L, v, F, T):
    """(dst_x, dst_P, dst_L)[i] = (v, F, T)[i]: a Runge-Kutta accumulator's first stage."""
    for c in range(3):
        dst_x[i, c] = v[i, c]
        dst_P[i, c] = F[i, c]
        dst_L[i, c] = T[i, c]


@njit(**INLINE)
def axpy_xPL(i, s, dst_x, dst_P, dst_L, x, P, L, v, F, T):
    """(dst_x, dst_P, dst_L)[i] = (x, P, L)[i] + s (v, F, T)[i]; dst may be the source."""
    for c in range(3):
        dst_x[i, c] = x[i, c] + s * v[i, c]
        dst_P[i, c] = P[i, c] + s * F[i, c]
        dst_L[i, c] = L[i, c] + s * T[i, c]


@njit(**INLINE)
def axpy_state(i, s, dst_x, dst_q, dst_P, dst_L, x, q, P, L, v, dq, F, T):
    """Body i of dst = y + s k, the additive update of the whole state (the quaternion too) by a
    derivative k = (v, dq/dt, F, tau); dst may be y (in place) or k's accumulator. ``dq`` is the
    body's quaternion rate as a 4-tuple (kept in registers, as ``quat_rate_of`` returns it)."""
    axpy_xPL(i, s, dst_x, dst_P, dst_L, x, P, L, v, F, T)
    for c in range(4):
        dst_q[i, c] = q[i, c] + s * dq[c]


@njit(**INLINE)
def axpy_sum_state(i, s, x, q, P, L, ax, aq, aP, aL, v, dq, F, T):
    """Body i of y += s (a + k): the Runge-Kutta step from an accumulator a and the last stage k
    (``dq`` the body's quaternion rate tuple, as in ``axpy_state``)."""
    for c in range(3):
        x[i, c] += s * (ax[i, c] + v[i, c])
        P[i, c] += s * (aP[i, c] + F[i, c])
        L[i, c] += s * (aL[i, c] + T[i, c])
    for c in range(4):
        q[i, c] += s * (aq[i, c] + dq[c])


@njit(**INLINE)
def row4(a, i):
    """Row i of an (n, 4) array as a tuple (a quaternion rate for ``axpy_state``)."""
    return a[i, 0], a[i, 1], a[i, 2], a[i, 3]


@njit(**JIT)
def advance_explicit_euler(bodies, gravity, springs, drag, loads, control, contacts,
                           x, q, P, L, n_steps, h):
    n = x.shape[0]
    R, v, w, F, T = force_scratch(n)
    for _ in range(n_steps):
        evaluate(bodies, gravity, springs, drag, loads, control, contacts,
                 x, q, P, L, R, v, w, F, T)
        for i in range(n):  # y += h f(y)
            dq = quat_rate_of(q, i, w[i, 0], w[i, 1], w[i, 2])
            axpy_state(i, h, x, q, P, L, x, q, P, L, v, dq, F, T)
        normalize_quats(q)


@njit(**JIT)
def advance_midpoint(bodies, gravity, springs, drag, loads, control, contacts,
                     x, q, P, L, n_steps, h):
    n = x.shape[0]
    R, v, w, F, T = force_scratch(n)
    # The rates in a pass of their own, not per body inside the update loops as in the other
    # schemes: fused, this kernel's machine code moved its spilled evaluate arguments between
    # stack slots on every step (2.3x slower at N = 1 with springs, measured). dq allocated
    # before the stage state, as it always was: the other order ran 2 % slower (array layout).
    dq = np.empty((n, 4))
    xs, qs, Ps, Ls = state_scratch(n)
    hh = 0.5 * h
    for _ in range(n_steps):
        evaluate(bodies, gravity, springs, drag, loads, control, contacts,
                 x, q, P, L, R, v, w, F, T)
        quat_rate(q, w, dq)
        for i in range(n):  # ys = y + h/2 f(y)
            axpy_state(i, hh, xs, qs, Ps, Ls, x, q, P, L, v, row4(dq, i), F, T)
        evaluate(bodies, gravity, springs, drag, loads, control, contacts,
                 xs, qs, Ps, Ls, R, v, w, F, T)
        quat_rate(qs, w, dq)
        for i in range(n):  # y += h f(ys)
            axpy_state(i, h, x, q, P, L, x, q, P, L, v, row4(dq, i), F, T)
        normalize_quats(q)


@njit(**JIT)
def advance_rk4(bodies, gravity, springs, drag, loads, control, contacts, x, q, P, L, n_steps, h):
    """Classical RK4 on (x, q, P, L); q renormalised once per step (a projection, O(h^5))."""
    n = x.shape[0]
    R, v, w, F, T = force_scratch(n)
    xs, qs, Ps, Ls = state_scratch(n)  # the stage state
    ax, aq, aP, aL = state_scratch(n)  # k1 + 2 k2 + 2 k3
    hh = 0.5 * h
    h6 = h / 6.0
    for _ in range(n_steps):
        # k1 at y: a = k1; ys = y + h/2 k1
        evaluate(bodies, gravity, springs, drag, loads, control, contacts,
                 x, q, P, L, R, v, w, F, T)
        for i in range(n):
            dq = quat_rate_of(q, i, w[i, 0], w[i, 1], w[i, 2])
            copy_xPL(i, ax, aP, aL, v, F, T)
            aq[i, 0], aq[i, 1], aq[i, 2], aq[i, 3] = dq
            axpy_state(i, hh, xs, qs, Ps, Ls, x, q, P, L, v, dq, F, T)
        # k2 at y + h/2 k1, k3 at y + h/2 k2: a += 2 k; the next stage from y
        for stage in range(2):
            evaluate(bodies, gravity, springs, drag, loads, control, contacts,
                     xs, qs, Ps, Ls, R, v, w, F, T)
            step = hh if stage == 0 else h
            for i in range(n):
                dq = quat_rate_of(qs, i, w[i, 0], w[i, 1], w[i, 2])
                axpy_state(i, 2.0, ax, aq, aP, aL, ax, aq, aP, aL, v, dq, F, T)
                axpy_state(i, step, xs, qs, Ps, Ls, x, q, P, L, v, dq, F, T)
        # k4 at y + h k3; the step y += h/6 (a + k4), q renormalised
        evaluate(bodies, gravity, springs, drag, loads, control, contacts,
                 xs, qs, Ps, Ls, R, v, w, F, T)
        for i in range(n):
            dq = quat_rate_of(qs, i, w[i, 0], w[i, 1], w[i, 2])
            axpy_sum_state(i, h6, x, q, P, L, ax, aq, aP, aL, v, dq, F, T)
            normalize_quat(q, i)


@njit(**INLINE)
def _dexpinv(tx, ty, tz, wx, wy, wz):
    """dexp^-1_theta(w) truncated for order 4: w - 1/2 theta x w + 1/12 theta x (theta x w)."""
    cx = ty * wz - tz * wy
    cy = tz * wx - tx * wz
    cz = tx * wy - ty * wx
    ccx = ty * cz - tz * cy
    ccy = tz * cx - tx * cz
    ccz = tx * cy - ty * cx
    return (wx - 0.5 * cx + ccx / 12.0, wy - 0.5 * cy + ccy / 12.0, wz - 0.5 * cz + ccz / 12.0)


@njit(**INLINE)
def _rotate_stage(q, th, i, s, ux, uy, uz, qs):
    """th[i] = s u; qs[i] = exp(th[i]) q[i]: an RKMK stage orientation."""
    th[i, 0] = s * ux
    th[i, 1] = s * uy
    th[i, 2] = s * uz
    rotate_left(q, i, th[i, 0], th[i, 1], th[i, 2], qs)


@njit(**JIT)
def advance_rk4_exp(bodies, gravity, springs, drag, loads, control, contacts,
                    x, q, P, L, n_steps, h):
    """RK4 with the Runge-Kutta-Munthe-Kaas rotation update (order 4, |q| = 1 by construction).

    x, P, L take the classical RK4 stages. The orientation is never updated additively: stage i
    sits at q_i = exp(theta_i) q_n, its angular velocity is pulled back to the Lie algebra with
    dexp^-1 (truncated after the theta^2 term, enough for order 4) and the step is
    q_{n+1} = exp(h/6 (u1 + 2 u2 + 2 u3 + u4)) q_n.
    """
    n = x.shape[0]
    R, v, w, F, T = force_scratch(n)
    xs, qs, Ps, Ls = state_scratch(n)
    ax, aP, aL = np.empty((n, 3)), np.empty((n, 3)), np.empty((n, 3))  # k1 + 2 k2 + 2 k3 + k4
    au = np.empty((n, 3))  # u1 + 2 u2 + 2 u3 + u4
    th = np.empty((n, 3))  # the stage's rotation vector theta_i
    hh = 0.5 * h
    h6 = h / 6.0
    for _ in range(n_steps):
        evaluate(bodies, gravity, springs, drag, loads, control, contacts,
                 x, q, P, L, R, v, w, F, T)
        for i in range(n):
            copy_xPL(i, ax, aP, aL, v, F, T)
            axpy_xPL(i, hh, xs, Ps, Ls, x, P, L, v, F, T)
            for c in range(3):
                au[i, c] = w[i, c]
            _rotate_stage(q, th, i, hh, w[i, 0], w[i, 1], w[i, 2], qs)
        for stage in range(3):
            evaluate(bodies, gravity, springs, drag, loads, control, contacts,
                     xs, qs, Ps, Ls, R, v, w, F, T)
            weight = 2.0 if stage < 2 else 1.0
            step = hh if stage == 0 else h
            for i in range(n):
                ux, uy, uz = _dexpinv(th[i, 0], th[i, 1], th[i, 2], w[i, 0], w[i, 1], w[i, 2])
                au[i, 0] += weight * ux
                au[i, 1] += weight * uy
                au[i, 2] += weight * uz
                axpy_xPL(i, weight, ax, aP, aL, ax, aP, aL, v, F, T)
                if stage < 2:
                    axpy_xPL(i, step, xs, Ps, Ls, x, P, L, v, F, T)
                    _rotate_stage(q, th, i, step, ux, uy, uz, qs)
        for i in range(n):
            axpy_xPL(i, h6, x, P, L, x, P, L, ax, aP, aL)
            rotate_left(q, i, h6 * au[i, 0], h6 * au[i, 1], h6 * au[i, 2], q)
        normalize_quats(q)  # round-off only: exp maps keep |q| = 1 exactly in exact arithmetic

