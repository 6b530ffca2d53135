"""Implicit (backward) Euler, linearised: one Newton step on the coupled system per time step.

Unknowns are the generalised velocities u = (v_i, w_i) of every body (6 per body in 3D, 3 in 2D).
Backward Euler asks for M (u1 - u0) = h f(X1, u1) with X1 = X0 + h u1 (X: centre of mass and a
small world rotation vector). Linearising f about the start of the step,

    f(X1, u1) ~ f0 + K h u1 + D (u1 - u0),    K = df/dX,  D = df/du,

gives one sparse linear system per step,

    (M - h D - h^2 K) du = h (f0 + h K u0),    u1 = u0 + du,

with M = blockdiag(m_i 1, I_i(q_n)) and K, D the spring Jacobians (12 x 12 per body-body spring,
6 x 6 per anchored spring, analytic: axial stiffness, the geometric stiffness of a stretched
spring, the torque arms and the damping along the axis) plus the drag terms. For linear springs
(rest length 0, attachments at the centres of mass) this *is* backward Euler; otherwise it is the
linearly implicit (Rosenbrock-Euler) form, first order, and stable for stiff springs at any step
(k h^2 / m = 100 in the tests) where every explicit scheme blows up.

Momenta follow exactly from the solve: P1 = P0 + m dv, L1 = L0 + I(q_n) dw (so a torque-free
body keeps L to round-off); then x1 = x0 + h P1 / m and the orientation is backward Euler too:
q1 = exp(phi) q0 with phi = h w(q1, L1), the angular velocity at the *end* of the step, solved by
Newton per body (:func:`backward_rotation`). Backward Euler dissipates the free rotor's
perturbations instead of amplifying them (explicit rotation updates grow round-off off a
principal axis by exp(n (h |w|)^2 / 2)); it is first order.

Scenes without springs have a block-diagonal system solved body by body inside one compiled
loop; scenes with springs assemble the sparse matrix in a compiled kernel and solve it with
SciPy once per step (a Python loop over *steps*, never over bodies).

The compiled pieces (assembly, Jacobians, the backward rotation, the block-diagonal step) are
here with the drivers; they call the force pass (forces3d / forces2d), the math (math3d) and
the centre-of-mass drift of the splitting family (splitting3d). numba's cache of every kernel is
stamped with the whole package's sources (sim/_jit.py), so none can call a stale helper.
"""

from __future__ import annotations

import warnings

import numpy as np
import scipy.sparse
import scipy.sparse.linalg
from numba import njit

from crosscheck.sim._jit import INLINE, JIT
from crosscheck.sim.rigid.forces2d import evaluate as evaluate_2d
from crosscheck.sim.rigid.forces2d import spring_ends as spring_ends_2d
from crosscheck.sim.rigid.forces2d import state_scratch as state_scratch_2d
from crosscheck.sim.rigid.forces3d import evaluate, force_scratch, spring_ends
from crosscheck.sim.rigid.math3d import (
    normalize_quats,
    quat_exp,
    quat_mul,
    quat_to_rotation,
    rotate_left,
    rotation_from_quat,
    skew,
    solve3,
)
from crosscheck.sim.rigid.splitting3d import drift_com

DENSE_LIMIT = 96  # unknowns up to which a dense LAPACK solve beats SciPy's sparse overhead


# -- compiled kernels, 3D then 2D ------------------------------------------------------------------
@njit(**JIT)
def _world_inertia(bodies, R, i, Iw):
    """Iw[i] = R I_body R^T."""
    for r in range(3):
        for c in range(3):
            acc = 0.0
            for a in range(3):
                for b in range(3):
                    acc += R[i, r, a] * bodies.inertia[i, a, b] * R[i, c, b]
            Iw[i, r, c] = acc


@njit(**INLINE)
def drag_coefficients(drag, i):
    """Body i's linear and angular drag coefficients (D's diagonal blocks are -c 1, -c_w 1)."""
    if drag is not None:
        return drag.linear[i], drag.angular[i]
    return 0.0, 0.0


@njit(**JIT)
def spring_jacobian_3d(springs, s, x, R, v, w, Ks, Ds):
    """K = dW/dX and D = dW/du (12 x 12) of spring s's wrench W = (f, oa x f, -f, -ob x f) on the
    local unknowns (x_a, phi_a, x_b, phi_b) and (v_a, w_a, v_b, w_b)."""
    a = springs.a[s]
    b = springs.b[s]
    oax, oay, oaz, obx, oby, obz, dx, dy, dz, dvx, dvy, dvz = spring_ends(springs, s, x, R, v, w)
    d = np.array([dx, dy, dz])
    dv = np.array([dvx, dvy, dvz])
    k = springs.stiffness[s]
    c = springs.damping[s]
    l0 = springs.rest_length[s]
    length = np.sqrt(d[0] ** 2 + d[1] ** 2 + d[2] ** 2)
    Kd = np.zeros((3, 3))
    Dd = np.zeros((3, 3))
    f = np.zeros(3)
    if length > 0.0:
        e = d / length
        rate = e[0] * dv[0] + e[1] * dv[1] + e[2] * dv[2]
        mag = -(k * (length - l0) + c * rate)
        pdv = dv - rate * e  # (1 - e e^T) dv
        for r in range(3):
            f[r] = mag * e[r]
            for col in range(3):
                proj = (1.0 if r == col else 0.0) - e[r] * e[col]
                Kd[r, col] = (-k * ((1.0 if r == col else 0.0) - l0 / length * proj)
                              - c * (e[r] * pdv[col] + rate * proj) / length)
                Dd[r, col] = -c * e[r] * e[col]
    else:
        for r in range(3):
            Kd[r, r] = -k
    # J = [1, -[oa]x, -1, [ob]x] maps local (x, phi) or (v, w) increments to d(d) or d(dv)
    J = np.zeros((3, 12))
    for r in range(3):
        J[r, r] = 1.0
        J[r, 6 + r] = -1.0
    skew(-oax, -oay, -oaz, J, 0, 3)
    skew(obx, oby, obz, J, 0, 9)
    # H: d(dv) from rotating the arms, -[wa]x[oa]x dphi_a + [wb]x[ob]x dphi_b
    H = np.zeros((3, 12))
    Sa = np.zeros((3, 3))
    Sb = np.zeros((3, 3))
    Wa = np.zeros((3, 3))
    Wb = np.zeros((3, 3))
    skew(oax, oay, oaz, Sa, 0, 0)
    skew(obx, oby, obz, Sb, 0, 0)
    skew(w[a, 0], w[a, 1], w[a, 2], Wa, 0, 0)
    if b >= 0:
        skew(w[b, 0], w[b, 1], w[b, 2], Wb, 0, 0)
    H[:, 3:6] = -(Wa @ Sa)
    H[:, 9:12] = Wb @ Sb
    Kf = Kd @ J + Dd @ H
    Ks[:, :] = J.T @ Kf
    Ds[:, :] = J.T @ (Dd @ J)
    # geometric terms of the torques: d(oa x f) from turning oa, d(-ob x f) from turning ob
    Fx = np.zeros((3, 3))
    skew(f[0], f[1], f[2], Fx, 0, 0)
    Ks[3:6, 3:6] += Fx @ Sa
    Ks[9:12, 9:12] -= Fx @ Sb


@njit(**JIT)
def assemble_3d(bodies, gravity, springs, drag, loads, control, contacts, x, q, P, L, h,
                R, v, w, F, T, Iw, rows, cols, vals, rhs):
    """A = M - h D - h^2 K as COO triplets and rhs = h (f0 + h K u0); returns the entry count."""
    n = x.shape[0]
    evaluate(bodies, gravity, springs, drag, loads, control, contacts, x, q, P, L, R, v, w, F, T)
    nnz = 0
    for i in range(n):
        rotation_from_quat(q, i, R)  # evaluate stores R only for springs; needed here anyway
        _world_inertia(bodies, R, i, Iw)
        cl, ca = drag_coefficients(drag, i)
        for c in range(3):
            rows[nnz] = 6 * i + c
            cols[nnz] = 6 * i + c
            vals[nnz] = bodies.mass[i] + h * cl
            nnz += 1
            rhs[6 * i + c] = h * F[i, c]
            rhs[6 * i + 3 + c] = h * T[i, c]
            for c2 in range(3):
                rows[nnz] = 6 * i + 3 + c
                cols[nnz] = 6 * i + 3 + c2
                vals[nnz] = Iw[i, c, c2] + (h * ca if c == c2 else 0.0)
                nnz += 1
    if springs is not None:
        Ks = np.empty((12, 12))
        Ds = np.empty((12, 12))
        u0 = np.zeros(12)
        dof = np.empty(12, dtype=np.int64)
        for s in range(springs.a.shape[0]):
            spring_jacobian_3d(springs, s, x, R, v, w, Ks, Ds)
            a = springs.a[s]
            b = springs.b[s]
            m = 12 if b >= 0 else 6
            for c in range(3):
                dof[c] = 6 * a + c
                dof[3 + c] = 6 * a + 3 + c
                u0[c] = v[a, c]
                u0[3 + c] = w[a, c]
                if b >= 0:
                    dof[6 + c] = 6 * b + c
                    dof[9 + c] = 6 * b + 3 + c
                    u0[6 + c] = v[b, c]
                    u0[9 + c] = w[b, c]
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
def backward_rotation(bodies, q, L, i, h, ws):
    """q[i] <- exp(phi) q[i] with phi = h w(exp(phi) q[i], L[i]): backward Euler for the
    orientation (the angular velocity of the *end* of the step). Newton on
    G(phi) = phi - h w(phi), with dw = (I_w^-1 [L]x - [w]x) dpsi for a small world rotation dpsi
    of the body and dpsi = dexp(phi) dphi, dexp(phi) = 1 + [phi]x / 2 + [phi]x^2 / 6. Converges
    quadratically from phi = 0; the iteration count is bounded for safety. ``ws`` is scratch
    space (5, 3, 3)."""
    R, M, S, D, J = ws[0], ws[1], ws[2], ws[3], ws[4]
    ibinv = bodies.inv_inertia
    q0w, q0x, q0y, q0z = q[i, 0], q[i, 1], q[i, 2], q[i, 3]
    lx, ly, lz = L[i, 0], L[i, 1], L[i, 2]
    p0 = p1 = p2 = 0.0
    for _ in range(30):
        ew, ex, ey, ez = quat_exp(p0, p1, p2)
        tw, tx, ty, tz = quat_mul(ew, ex, ey, ez, q0w, q0x, q0y, q0z)
        (R[0, 0], R[0, 1], R[0, 2], R[1, 0], R[1, 1], R[1, 2], R[2, 0], R[2, 1],
         R[2, 2]) = quat_to_rotation(tw, tx, ty, tz)
        # M = I_w^-1 = R I_body^-1 R^T (S as scratch for R I_body^-1)
        for r in range(3):
            for c in range(3):
                S[r, c] = (R[r, 0] * ibinv[i, 0, c] + R[r, 1] * ibinv[i, 1, c]
                           + R[r, 2] * ibinv[i, 2, c])
        for r in range(3):
            for c in range(3):
                M[r, c] = S[r, 0] * R[c, 0] + S[r, 1] * R[c, 1] + S[r, 2] * R[c, 2]
        wx = M[0, 0] * lx + M[0, 1] * ly + M[0, 2] * lz
        wy = M[1, 0] * lx + M[1, 1] * ly + M[1, 2] * lz
        wz = M[2, 0] * lx + M[2, 1] * ly + M[2, 2] * lz
        # S = M [L]x - [w]x
        for r in range(3):
            S[r, 0] = M[r, 1] * lz - M[r, 2] * ly
            S[r, 1] = M[r, 2] * lx - M[r, 0] * lz
            S[r, 2] = M[r, 0] * ly - M[r, 1] * lx
        S[0, 1] += wz
        S[0, 2] -= wy
        S[1, 0] -= wz
        S[1, 2] += wx
        S[2, 0] += wy
        S[2, 1] -= wx
        # D = dexp(phi) = 1 + [phi]x / 2 + [phi]x^2 / 6, [p]x^2 = p p^T - |p|^2 1
        pp = p0 * p0 + p1 * p1 + p2 * p2
        D[0, 0] = 1.0 + (p0 * p0 - pp) / 6.0
        D[1, 1] = 1.0 + (p1 * p1 - pp) / 6.0
        D[2, 2] = 1.0 + (p2 * p2 - pp) / 6.0
        D[0, 1] = -0.5 * p2 + p0 * p1 / 6.0
        D[1, 0] = 0.5 * p2 + p0 * p1 / 6.0
        D[0, 2] = 0.5 * p1 + p0 * p2 / 6.0
        D[2, 0] = -0.5 * p1 + p0 * p2 / 6.0
        D[1, 2] = -0.5 * p0 + p1 * p2 / 6.0
        D[2, 1] = 0.5 * p0 + p1 * p2 / 6.0
        # J = 1 - h S D
        for r in range(3):
            for c in range(3):
                J[r, c] = ((1.0 if r == c else 0.0)
                           - h * (S[r, 0] * D[0, c] + S[r, 1] * D[1, c] + S[r, 2] * D[2, c]))
        d0, d1, d2 = solve3(J, p0 - h * wx, p1 - h * wy, p2 - h * wz)
        p0 -= d0
        p1 -= d1
        p2 -= d2
        size = np.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
        if not size > 1e-15 * (1e-300 + np.sqrt(p0 * p0 + p1 * p1 + p2 * p2)):
            break
    rotate_left(q, i, p0, p1, p2, q)


@njit(**JIT)
def finish_3d(bodies, x, q, P, L, Iw, ws, h, du):
    """P += m dv, L += I(q_n) dw, x += h P/m; q by backward Euler with the new L (``ws``:
    backward_rotation's scratch, allocated once by the caller rather than on every step)."""
    for i in range(x.shape[0]):
        for c in range(3):
            P[i, c] += bodies.mass[i] * du[6 * i + c]
            L[i, c] += (Iw[i, c, 0] * du[6 * i + 3] + Iw[i, c, 1] * du[6 * i + 4]
                        + Iw[i, c, 2] * du[6 * i + 5])
        drift_com(bodies, i, h, x, P)
        backward_rotation(bodies, q, L, i, h, ws)
    normalize_quats(q)


@njit(**JIT)
def advance_local_3d(bodies, gravity, springs, drag, loads, control, contacts,
                     x, q, P, L, n_steps, h):
    """Backward Euler without springs: the system is block-diagonal, solved body by body."""
    n = x.shape[0]
    R, v, w, F, T = force_scratch(n)
    Iw = np.empty((n, 3, 3))
    ws = np.empty((5, 3, 3))
    du = np.empty(6 * n)
    A = np.empty((3, 3))
    for _ in range(n_steps):
        evaluate(bodies, gravity, springs, drag, loads, control, contacts,
                 x, q, P, L, R, v, w, F, T)
        for i in range(n):
            rotation_from_quat(q, i, R)
            _world_inertia(bodies, R, i, Iw)
            cl, ca = drag_coefficients(drag, i)
            for c in range(3):
                du[6 * i + c] = h * F[i, c] / (bodies.mass[i] + h * cl)
                for c2 in range(3):
                    A[c, c2] = Iw[i, c, c2] + (h * ca if c == c2 else 0.0)
            du[6 * i + 3], du[6 * i + 4], du[6 * i + 5] = solve3(A, h * T[i, 0], h * T[i, 1],
                                                                  h * T[i, 2])
        finish_3d(bodies, x, q, P, L, Iw, ws, h, du)



@njit(**JIT)
def spring_jacobian_2d(springs, s, x, angle, v, w, Ks, Ds):
    """K, D (6 x 6) of spring s's wrench (f, oa x f, -f, -ob x f) on (x_a, th_a, x_b, th_b)."""
    a = springs.a[s]
    b = springs.b[s]
    oax, oay, obx, oby, dx, dy, dvx, dvy = spring_ends_2d(springs, s, x, angle, v, w)
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
    evaluate_2d(bodies, gravity, springs, drag, loads, control, contacts,
                x, angle, P, L, v, w, F, T)
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
    v, w, F, T = state_scratch_2d(n)
    du = np.empty(3 * n)
    for _ in range(n_steps):
        evaluate_2d(bodies, gravity, springs, drag, loads, control, contacts,
                 x, angle, P, L, v, w, F, T)
        for i in range(n):
            cl, ca = drag_coefficients(drag, i)
            du[3 * i] = h * F[i, 0] / (bodies.mass[i] + h * cl)
            du[3 * i + 1] = h * F[i, 1] / (bodies.mass[i] + h * cl)
            du[3 * i + 2] = h * T[i] / (bodies.moment[i] + h * ca)
        finish_2d(bodies, x, angle, P, L, w, h, du)



# -- Python drivers (the registry's entry points) --------------------------------------------------
def _solve(rows, cols, vals, rhs, nnz):
    n = rhs.shape[0]
    with warnings.catch_warnings():
        # A singular system is a blow-up: the NaNs it produces are reported by the driver.
        warnings.simplefilter("ignore")
        if n <= DENSE_LIMIT:
            A = np.zeros((n, n))
            np.add.at(A, (rows[:nnz], cols[:nnz]), vals[:nnz])
            try:
                return np.linalg.solve(A, rhs)
            except np.linalg.LinAlgError:
                return np.full(n, np.nan)
        A = scipy.sparse.csc_matrix((vals[:nnz], (rows[:nnz], cols[:nnz])), shape=(n, n))
        return scipy.sparse.linalg.spsolve(A, rhs)


def _coupled_steps(n_steps, n_unknowns, nnz_max, assemble, assemble_args, finish, finish_args):
    """Steps with springs: assemble the sparse system into triplet buffers reused every step
    (``assemble(*assemble_args, rows, cols, vals, rhs) -> nnz``), solve it, and apply the velocity
    increment (``finish(*finish_args, du)``)."""
    coo = (np.empty(nnz_max, dtype=np.int64), np.empty(nnz_max, dtype=np.int64),
           np.empty(nnz_max), np.empty(n_unknowns))
    assemble_args = (*assemble_args, *coo)
    for _ in range(n_steps):
        nnz = assemble(*assemble_args)
        finish(*finish_args, _solve(*coo, nnz))


def advance_implicit_3d(model, state, control, contacts, n_steps: int, h: float) -> None:
    args = (*model.kernel_args(), control, contacts, *state.arrays())
    if model.springs is None:
        advance_local_3d(*args, n_steps, h)
        return
    x, q, P, L = state.arrays()
    n = x.shape[0]
    R, v, w, F, T, Iw = (np.empty((n, *s)) for s in ((3, 3), (3,), (3,), (3,), (3,), (3, 3)))
    # entries: per body 3 (mass) + 9 (world inertia), per spring one 12 x 12 block
    _coupled_steps(n_steps, 6 * n, 12 * n + 144 * len(model.springs.a),
                   assemble_3d, (*args, h, R, v, w, F, T, Iw),
                   finish_3d, (model.bodies, x, q, P, L, Iw, np.empty((5, 3, 3)), h))


def advance_implicit_2d(model, state, control, contacts, n_steps: int, h: float) -> None:
    args = (*model.kernel_args(), control, contacts, *state.arrays())
    if model.springs is None:
        advance_local_2d(*args, n_steps, h)
        return
    x, angle, P, L = state.arrays()
    n = x.shape[0]
    v, w, F, T = np.empty((n, 2)), np.empty(n), np.empty((n, 2)), np.empty(n)
    # entries: per body 2 (mass) + 1 (moment), per spring one 6 x 6 block
    _coupled_steps(n_steps, 3 * n, 3 * n + 36 * len(model.springs.a),
                   assemble_2d, (*args, h, v, w, F, T),
                   finish_2d, (model.bodies, x, angle, P, L, w, h))
