"""3D splitting / symplectic family: kick and drift, the free rotation by exact sub-rotations
about the principal axes (symplectic Euler, velocity Verlet), and the game engines'
semi-implicit Euler with an exponential-map rotation drift."""

from __future__ import annotations

import numpy as np
from numba import njit

from crosscheck.sim._jit import INLINE, JIT
from crosscheck.sim.rigid.forces3d import evaluate, force_scratch, kinematics
from crosscheck.sim.rigid.math3d import normalize_quats, quat_mul, quat_to_rotation, rotate_left


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
    r00, r01, r02, r10, r11, r12, r20, r21, r22 = quat_to_rotation(w0, x0, y0, z0)
    lb0 = r00 * L[i, 0] + r10 * L[i, 1] + r20 * L[i, 2]  # body-frame L = R^T L
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
        # the fixed world L seen from the rotated body turns by -alpha about a (Rodrigues;
        # cos and sin of alpha from the half angle's)
        ca = c * c - sn * sn
        sa = 2.0 * sn * c
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


@njit(**INLINE)
def kick(i, s, P, L, F, T):
    """P += s F, L += s tau for body i."""
    for c in range(3):
        P[i, c] += s * F[i, c]
        L[i, c] += s * T[i, c]


@njit(**INLINE)
def drift_com(bodies, i, h, x, P):
    """x += h P / m for body i, with the momentum it has now (after the kick)."""
    im = bodies.inv_mass[i]
    for c in range(3):
        x[i, c] += h * P[i, c] * im


@njit(**JIT)
def advance_symplectic_euler(bodies, gravity, springs, drag, loads, control, contacts,
                             x, q, P, L, n_steps, h):
    """Kick P, L by h with the forces at the start; drift x by h P/m and the orientation by the
    exact principal-axis sub-rotations (Lie-Trotter) with the new L."""
    n = x.shape[0]
    R, v, w, F, T = force_scratch(n)
    for _ in range(n_steps):
        evaluate(bodies, gravity, springs, drag, loads, control, contacts,
                 x, q, P, L, R, v, w, F, T)
        for i in range(n):
            kick(i, h, P, L, F, T)
            drift_com(bodies, i, h, x, P)
            free_rotation(bodies, q, L, i, h, np.bool_(False))


@njit(**JIT)
def advance_symplectic_euler_exp(bodies, gravity, springs, drag, loads, control, contacts,
                                 x, q, P, L, n_steps, h):
    """Kick then drift, the rotation drift as one exponential map q <- exp(h w) q with
    w = I(q_n)^-1 L_{n+1}: the semi-implicit Euler of game engines. Symplectic for the
    translation; the rotation is explicit in w(q) (|q| stays 1, but a tumbling asymmetric body's
    energy drifts at O(h))."""
    n = x.shape[0]
    R, v, w, F, T = force_scratch(n)
    for _ in range(n_steps):
        evaluate(bodies, gravity, springs, drag, loads, control, contacts,
                 x, q, P, L, R, v, w, F, T)
        for i in range(n):
            kick(i, h, P, L, F, T)
            drift_com(bodies, i, h, x, P)
        kinematics(bodies, q, P, L, R, v, w)  # w from the kicked L and the start orientation
        for i in range(n):
            rotate_left(q, i, h * w[i, 0], h * w[i, 1], h * w[i, 2], q)
        normalize_quats(q)


@njit(**JIT)
def advance_verlet(bodies, gravity, springs, drag, loads, control, contacts,
                   x, q, P, L, n_steps, h):
    """Velocity Verlet: half kick, drift (x by h P/m, orientation by the Strang principal-axis
    splitting), half kick with the forces at the new configuration.

    Velocity-dependent forces (spring damping, drag) in the closing half kick use the momenta
    extrapolated to the end of the step, 2 P_half - P_n (error O(h^2), so the scheme stays second
    order with damping); without them the scheme is symplectic and time-reversible.
    """
    n = x.shape[0]
    R, v, w, F, T = force_scratch(n)
    Pp = np.empty((n, 3))
    Lp = np.empty((n, 3))
    hh = 0.5 * h
    for _ in range(n_steps):
        evaluate(bodies, gravity, springs, drag, loads, control, contacts,
                 x, q, P, L, R, v, w, F, T)
        for i in range(n):
            for c in range(3):  # the half kick, and 2 P_half - P_n for the closing one
                p_old = P[i, c]
                l_old = L[i, c]
                P[i, c] += hh * F[i, c]
                L[i, c] += hh * T[i, c]
                Pp[i, c] = 2.0 * P[i, c] - p_old
                Lp[i, c] = 2.0 * L[i, c] - l_old
            drift_com(bodies, i, h, x, P)
            free_rotation(bodies, q, L, i, h, np.bool_(True))
        evaluate(bodies, gravity, springs, drag, loads, control, contacts,
                 x, q, Pp, Lp, R, v, w, F, T)
        for i in range(n):
            kick(i, hh, P, L, F, T)

