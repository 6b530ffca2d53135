"""2D explicit Runge-Kutta family: explicit Euler, midpoint, RK4.

The angle is a coordinate of a vector space, so every rotation update is exact bookkeeping (no
normalisation; the exponential map of SO(2) is the addition of angles): the 2D ``rk4_exp`` is
``advance_rk4``. As in explicit3d: scratch allocated once per call, each stage one pass over the
bodies, and the inlined helpers keep the exact floating-point expressions (``y + s * k``) of the
hand-written loops they replaced.
"""

from __future__ import annotations

from numba import njit

from crosscheck.sim._jit import INLINE, JIT
from crosscheck.sim.rigid.forces2d import evaluate, state_scratch


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

