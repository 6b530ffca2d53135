"""3D velocity-level contact steps (sequential_impulse, soft_step) on the Baraff state.

The rows are contact_rows'; this module holds what is three-dimensional about the bodies: the
world inertia from q, the conversion between momenta (P, L) and the solver's velocities (v, w),
the kick and the drift with the integrator's rotation update (symplectic_euler: the exact
principal-axis splitting with L; symplectic_euler_exp: q <- exp(h w) q), and the bodies' motion
since detection (soft_step's separation update).

Velocity changes go back into the state as P += m (v - v0), L += I_world (w - w0): a body no
contact touched keeps its momenta bit for bit, and steps exactly as the contact-free kernel of
the same integrator (splitting3d) would move it.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit

from crosscheck.sim.collide import detect3d
from crosscheck.sim.rigid._jit import INLINE, JIT
from crosscheck.sim.rigid.contact_rows import (
    ROTATION_SPLITTING,
    SOFT_STEP,
    apply_accumulated,
    count_sweeps,
    impulse_bias,
    impulse_sweep,
    match_rows,
    move_anchors,
    prepare_rows,
    restitution_pass,
    soft_coefficients,
    soft_sweep,
    split_sweep,
    store_rows,
)
from crosscheck.sim.rigid.forces3d import evaluate, kinematics
from crosscheck.sim.rigid.math3d import (
    normalize_quat,
    normalize_quats,
    quat_to_rotation,
    rotate_left,
)
from crosscheck.sim.rigid.splitting3d import drift_com, free_rotation, kick


class Scratch3D(NamedTuple):
    R: np.ndarray  # (N, 3, 3) evaluate's scratch
    ev: np.ndarray  # (N, 3)
    ew: np.ndarray  # (N, 3)
    F: np.ndarray  # (N, 3)
    T: np.ndarray  # (N, 3)
    v: np.ndarray  # (N, 3) the solver's velocities
    w: np.ndarray  # (N, 3)
    v0: np.ndarray  # (N, 3) the velocities before the solver touched them
    w0: np.ndarray  # (N, 3)
    inertia: np.ndarray  # (N, 3, 3) world inertia about the centre of mass
    inv_inertia: np.ndarray  # (N, 3, 3)
    vp: np.ndarray  # (N, 3) split-impulse pseudo-velocities
    wp: np.ndarray  # (N, 3)
    dp: np.ndarray  # (N, 3) motion since detection (soft_step)
    dR: np.ndarray  # (N, 3, 3)
    x0: np.ndarray  # (N, 3) state at detection (soft_step)
    q0: np.ndarray  # (N, 4)


@njit(**INLINE)
def scratch3d(n):
    return Scratch3D(np.empty((n, 3, 3)), np.empty((n, 3)), np.empty((n, 3)), np.empty((n, 3)),
                     np.empty((n, 3)), np.zeros((n, 3)), np.zeros((n, 3)), np.zeros((n, 3)),
                     np.zeros((n, 3)), np.zeros((n, 3, 3)), np.zeros((n, 3, 3)),
                     np.zeros((n, 3)), np.zeros((n, 3)), np.zeros((n, 3)), np.zeros((n, 3, 3)),
                     np.zeros((n, 3)), np.zeros((n, 4)))


def new_scratch3d(n: int) -> Scratch3D:
    """The same scratch from Python (tests call ``step3d`` on hand-filled contact buffers)."""
    return scratch3d.py_func(n)


@njit(**INLINE)
def body_velocities(bodies, q, P, L, sc):
    """World inertia and its inverse at q; v = P / m, w = I^-1 L; v0, w0 = v, w."""
    for i in range(q.shape[0]):
        r00, r01, r02, r10, r11, r12, r20, r21, r22 = quat_to_rotation(q[i, 0], q[i, 1],
                                                                       q[i, 2], q[i, 3])
        rot = ((r00, r01, r02), (r10, r11, r12), (r20, r21, r22))
        for j in range(3):
            for k in range(3):
                s = 0.0
                t = 0.0
                for m in range(3):
                    rk = rot[j][m]
                    for p in range(3):
                        s += rk * bodies.inertia[i, m, p] * rot[k][p]
                        t += rk * bodies.inv_inertia[i, m, p] * rot[k][p]
                sc.inertia[i, j, k] = s
                sc.inv_inertia[i, j, k] = t
        im = bodies.inv_mass[i]
        for c in range(3):
            sc.v[i, c] = P[i, c] * im
        for c in range(3):
            sc.w[i, c] = (sc.inv_inertia[i, c, 0] * L[i, 0] + sc.inv_inertia[i, c, 1] * L[i, 1]
                          + sc.inv_inertia[i, c, 2] * L[i, 2])
        for c in range(3):
            sc.v0[i, c] = sc.v[i, c]
            sc.w0[i, c] = sc.w[i, c]


@njit(**INLINE)
def write_back(bodies, P, L, sc):
    """P += m (v - v0), L += I (w - w0): only what the contacts changed."""
    for i in range(P.shape[0]):
        m = bodies.mass[i]
        dw0 = sc.w[i, 0] - sc.w0[i, 0]
        dw1 = sc.w[i, 1] - sc.w0[i, 1]
        dw2 = sc.w[i, 2] - sc.w0[i, 2]
        for c in range(3):
            P[i, c] += m * (sc.v[i, c] - sc.v0[i, c])
            L[i, c] += sc.inertia[i, c, 0] * dw0 + sc.inertia[i, c, 1] * dw1 + \
                sc.inertia[i, c, 2] * dw2


@njit(**INLINE)
def drift(bodies, rotation, x, q, P, L, sc, h):
    """Positions by h P / m; orientations by the integrator's rotation update with the new L."""
    n = x.shape[0]
    for i in range(n):
        drift_com(bodies, i, h, x, P)
    if rotation == ROTATION_SPLITTING:
        for i in range(n):
            free_rotation(bodies, q, L, i, h, False)
    else:
        kinematics(bodies, q, P, L, sc.R, sc.ev, sc.ew)  # w from the new L at the start q
        for i in range(n):
            rotate_left(q, i, h * sc.ew[i, 0], h * sc.ew[i, 1], h * sc.ew[i, 2], q)
        normalize_quats(q)


@njit(**INLINE)
def motion_since(x, q, sc):
    """dp = x - x0 and dR = R(q) R(q0)^T of every body."""
    for i in range(x.shape[0]):
        for c in range(3):
            sc.dp[i, c] = x[i, c] - sc.x0[i, c]
        a = quat_to_rotation(q[i, 0], q[i, 1], q[i, 2], q[i, 3])
        b = quat_to_rotation(sc.q0[i, 0], sc.q0[i, 1], sc.q0[i, 2], sc.q0[i, 3])
        for j in range(3):
            for k in range(3):
                sc.dR[i, j, k] = (a[3 * j] * b[3 * k] + a[3 * j + 1] * b[3 * k + 1]
                                  + a[3 * j + 2] * b[3 * k + 2])


@njit(**JIT)
def step3d(bodies, gravity, springs, drag, loads, control, contacts, rows, st, sc, x, q, P, L,
           h):
    """One step of the model ``st.model`` on the contacts detected at (x, q), in place."""
    n = x.shape[0]
    count = contacts.count[0]
    inv_mass = bodies.inv_mass
    if st.model == SOFT_STEP:
        k = st.substeps
        hs = h / k
        hertz = 0.25 / hs  # Box2D v3's cap, a quarter of the sub-step rate
        if st.contact_hertz > 0.0:
            hertz = min(st.contact_hertz, hertz)
        contact_soft = soft_coefficients(hertz, st.damping_ratio, hs)
        static_soft = soft_coefficients(2.0 * hertz, st.damping_ratio, hs)
        if count > 0:
            body_velocities(bodies, q, P, L, sc)
            prepare_rows(contacts, rows, count, x, sc.v, sc.w, inv_mass, sc.inv_inertia)
            match_rows(contacts, rows, count, st.warm_starting)
            for i in range(n):
                for c in range(3):
                    sc.x0[i, c] = x[i, c]
                    sc.dp[i, c] = 0.0
                for c in range(4):
                    sc.q0[i, c] = q[i, c]
                for j in range(3):
                    for c in range(3):
                        sc.dR[i, j, c] = 1.0 if j == c else 0.0
        for _ in range(k):
            evaluate(bodies, gravity, springs, drag, loads, control, None, x, q, P, L, sc.R,
                     sc.ev, sc.ew, sc.F, sc.T)
            for i in range(n):
                kick(i, hs, P, L, sc.F, sc.T)
            if count > 0:
                body_velocities(bodies, q, P, L, sc)
                apply_accumulated(contacts, rows, count, sc.v, sc.w, inv_mass, sc.inv_inertia)
                for _ in range(st.iterations):
                    soft_sweep(contacts, rows, count, sc.v, sc.w, inv_mass, sc.inv_inertia,
                               1.0 / hs, True, contact_soft, static_soft, st.push_speed)
                write_back(bodies, P, L, sc)
            drift(bodies, st.rotation, x, q, P, L, sc, hs)
            if count > 0:
                motion_since(x, q, sc)
                move_anchors(contacts, rows, count, sc.dp, sc.dR)
                body_velocities(bodies, q, P, L, sc)
                for _ in range(st.relax_iterations):
                    soft_sweep(contacts, rows, count, sc.v, sc.w, inv_mass, sc.inv_inertia,
                               1.0 / hs, False, contact_soft, static_soft, st.push_speed)
                write_back(bodies, P, L, sc)
        if count > 0:
            body_velocities(bodies, q, P, L, sc)
            restitution_pass(contacts, rows, count, sc.v, sc.w, inv_mass, sc.inv_inertia,
                             st.restitution_threshold)
            write_back(bodies, P, L, sc)
            store_rows(contacts, rows, count)
        else:
            rows.prev_count[0] = 0
        return
    # sequential_impulse: rows prepared with the velocities before the kick (restitution)
    if count > 0:
        body_velocities(bodies, q, P, L, sc)
        prepare_rows(contacts, rows, count, x, sc.v, sc.w, inv_mass, sc.inv_inertia)
        match_rows(contacts, rows, count, st.warm_starting)
    evaluate(bodies, gravity, springs, drag, loads, control, None, x, q, P, L, sc.R, sc.ev,
             sc.ew, sc.F, sc.T)
    for i in range(n):
        kick(i, h, P, L, sc.F, sc.T)
    if count > 0:
        body_velocities(bodies, q, P, L, sc)
        impulse_bias(contacts, rows, count, h, st.restitution_threshold, sc.v, sc.w)
        apply_accumulated(contacts, rows, count, sc.v, sc.w, inv_mass, sc.inv_inertia)
        sweeps = 0
        while sweeps < st.iterations:
            sweeps += 1
            if impulse_sweep(contacts, rows, count, sc.v, sc.w, inv_mass,
                             sc.inv_inertia) <= st.tolerance:
                break
        count_sweeps(rows, sweeps)
        write_back(bodies, P, L, sc)
        sc.vp[:] = 0.0
        sc.wp[:] = 0.0
        for _ in range(st.position_iterations):
            split_sweep(contacts, rows, count, sc.vp, sc.wp, inv_mass, sc.inv_inertia, h,
                        st.baumgarte, st.slop)
        store_rows(contacts, rows, count)
    else:
        rows.prev_count[0] = 0
    drift(bodies, st.rotation, x, q, P, L, sc, h)
    if count > 0:  # the split impulse moves positions only
        for i in range(n):
            for c in range(3):
                x[i, c] += h * sc.vp[i, c]
            if sc.wp[i, 0] != 0.0 or sc.wp[i, 1] != 0.0 or sc.wp[i, 2] != 0.0:
                rotate_left(q, i, h * sc.wp[i, 0], h * sc.wp[i, 1], h * sc.wp[i, 2], q)
                normalize_quat(q, i)


@njit(**JIT)
def advance3d(bodies, gravity, springs, drag, loads, control, geometry, contacts, rows, st,
              x, q, P, L, n_steps, h):
    """n_steps steps: detect at the start of each, then ``step3d``. Returns the steps taken: fewer
    than n_steps when detection overflowed the buffer (the caller raises)."""
    sc = scratch3d(x.shape[0])
    for s in range(n_steps):
        if detect3d(geometry, x, q, contacts) > contacts.a.shape[0]:
            return s
        step3d(bodies, gravity, springs, drag, loads, control, contacts, rows, st, sc, x, q, P,
               L, h)
    return n_steps
