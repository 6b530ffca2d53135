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
    R0: np.ndarray  # (N, 9) R(q0) row-major (soft_step: computed once a step, not per sub-step)


@njit(**INLINE)
def scratch3d(n):
    return Scratch3D(np.empty((n, 3, 3)), np.empty((n, 3)), np.empty((n, 3)), np.empty((n, 3)),
                     np.empty((n, 3)), np.zeros((n, 3)), np.zeros((n, 3)), np.zeros((n, 3)),
                     np.zeros((n, 3)), np.zeros((n, 3, 3)), np.zeros((n, 3, 3)),
                     np.zeros((n, 3)), np.zeros((n, 3)), np.zeros((n, 3)), np.zeros((n, 3, 3)),
                     np.zeros((n, 3)), np.zeros((n, 4)), np.zeros((n, 9)))


def new_scratch3d(n: int) -> Scratch3D:
    """The same scratch from Python (tests call ``step3d`` on hand-filled contact buffers)."""
    return scratch3d.py_func(n)


@njit(**INLINE)
def _congruence_diag(r, d0, d1, d2):
    """R diag(d) R^T (R row-major 9-tuple), written out: entry (j, k) is the general loop's sum
    over (m, p) with its zero off-diagonal terms left out, the same products added in the same
    order ((0 + t0) + t1) + t2, so the result is the general loop's bit for bit (adding an exact
    zero changes no sum that starts at +0)."""
    r00, r01, r02, r10, r11, r12, r20, r21, r22 = r
    a00 = ((0.0 + r00 * d0 * r00) + r01 * d1 * r01) + r02 * d2 * r02
    a01 = ((0.0 + r00 * d0 * r10) + r01 * d1 * r11) + r02 * d2 * r12
    a02 = ((0.0 + r00 * d0 * r20) + r01 * d1 * r21) + r02 * d2 * r22
    a10 = ((0.0 + r10 * d0 * r00) + r11 * d1 * r01) + r12 * d2 * r02
    a11 = ((0.0 + r10 * d0 * r10) + r11 * d1 * r11) + r12 * d2 * r12
    a12 = ((0.0 + r10 * d0 * r20) + r11 * d1 * r21) + r12 * d2 * r22
    a20 = ((0.0 + r20 * d0 * r00) + r21 * d1 * r01) + r22 * d2 * r02
    a21 = ((0.0 + r20 * d0 * r10) + r21 * d1 * r11) + r22 * d2 * r12
    a22 = ((0.0 + r20 * d0 * r20) + r21 * d1 * r21) + r22 * d2 * r22
    return a00, a01, a02, a10, a11, a12, a20, a21, a22


@njit(**INLINE)
def _store9(arr, i, t):
    arr[i, 0, 0], arr[i, 0, 1], arr[i, 0, 2] = t[0], t[1], t[2]
    arr[i, 1, 0], arr[i, 1, 1], arr[i, 1, 2] = t[3], t[4], t[5]
    arr[i, 2, 0], arr[i, 2, 1], arr[i, 2, 2] = t[6], t[7], t[8]


@njit(**INLINE)
def _diagonal(m, i):
    return (m[i, 0, 1] == 0.0 and m[i, 0, 2] == 0.0 and m[i, 1, 0] == 0.0 and m[i, 1, 2] == 0.0
            and m[i, 2, 0] == 0.0 and m[i, 2, 1] == 0.0)


@njit(**INLINE)
def world_inertia(bodies, q, sc):
    """World inertia and its inverse at q. A body-frame tensor that is diagonal (every body whose
    frame is its principal axes: spheres, boxes, cylinders) takes the written-out product, the
    same numbers as the general loop: that loop indexed a tuple of tuples with loop variables,
    which numba does not unroll, and cost 290 ns a body (58 us a call on 200 cubes, called ten
    times a soft step: measured); the product below costs a few ns."""
    for i in range(q.shape[0]):
        r = quat_to_rotation(q[i, 0], q[i, 1], q[i, 2], q[i, 3])
        if _diagonal(bodies.inertia, i) and _diagonal(bodies.inv_inertia, i):
            _store9(sc.inertia, i, _congruence_diag(r, bodies.inertia[i, 0, 0],
                                                    bodies.inertia[i, 1, 1],
                                                    bodies.inertia[i, 2, 2]))
            _store9(sc.inv_inertia, i, _congruence_diag(r, bodies.inv_inertia[i, 0, 0],
                                                        bodies.inv_inertia[i, 1, 1],
                                                        bodies.inv_inertia[i, 2, 2]))
            continue
        r00, r01, r02, r10, r11, r12, r20, r21, r22 = r
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


@njit(**INLINE)
def velocities(bodies, P, L, sc):
    """v = P / m, w = I^-1 L with the world inertia in ``sc`` (world_inertia at the current q);
    v0, w0 = v, w."""
    for i in range(P.shape[0]):
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
def body_velocities(bodies, q, P, L, sc):
    """World inertia and its inverse at q; v = P / m, w = I^-1 L; v0, w0 = v, w."""
    world_inertia(bodies, q, sc)
    velocities(bodies, P, L, sc)


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
            free_rotation(bodies, q, L, i, h, np.bool_(False))
    else:
        kinematics(bodies, q, P, L, sc.R, sc.ev, sc.ew)  # w from the new L at the start q
        for i in range(n):
            rotate_left(q, i, h * sc.ew[i, 0], h * sc.ew[i, 1], h * sc.ew[i, 2], q)
        normalize_quats(q)


@njit(**INLINE)
def motion_since(x, q, sc):
    """dp = x - x0 and dR = R(q) R(q0)^T of every body (R(q0) from ``sc.R0``, set at detection),
    written out (the same sums as a loop over j, k, without indexing a tuple by a variable)."""
    for i in range(x.shape[0]):
        for c in range(3):
            sc.dp[i, c] = x[i, c] - sc.x0[i, c]
        a00, a01, a02, a10, a11, a12, a20, a21, a22 = quat_to_rotation(q[i, 0], q[i, 1],
                                                                       q[i, 2], q[i, 3])
        b = sc.R0
        sc.dR[i, 0, 0] = a00 * b[i, 0] + a01 * b[i, 1] + a02 * b[i, 2]
        sc.dR[i, 0, 1] = a00 * b[i, 3] + a01 * b[i, 4] + a02 * b[i, 5]
        sc.dR[i, 0, 2] = a00 * b[i, 6] + a01 * b[i, 7] + a02 * b[i, 8]
        sc.dR[i, 1, 0] = a10 * b[i, 0] + a11 * b[i, 1] + a12 * b[i, 2]
        sc.dR[i, 1, 1] = a10 * b[i, 3] + a11 * b[i, 4] + a12 * b[i, 5]
        sc.dR[i, 1, 2] = a10 * b[i, 6] + a11 * b[i, 7] + a12 * b[i, 8]
        sc.dR[i, 2, 0] = a20 * b[i, 0] + a21 * b[i, 1] + a22 * b[i, 2]
        sc.dR[i, 2, 1] = a20 * b[i, 3] + a21 * b[i, 4] + a22 * b[i, 5]
        sc.dR[i, 2, 2] = a20 * b[i, 6] + a21 * b[i, 7] + a22 * b[i, 8]


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
                r = quat_to_rotation(q[i, 0], q[i, 1], q[i, 2], q[i, 3])
                for c in range(9):
                    sc.R0[i, c] = r[c]
                for j in range(3):
                    for c in range(3):
                        sc.dR[i, j, c] = 1.0 if j == c else 0.0
        for _ in range(k):
            evaluate(bodies, gravity, springs, drag, loads, control, None, x, q, P, L, sc.R,
                     sc.ev, sc.ew, sc.F, sc.T)
            for i in range(n):
                kick(i, hs, P, L, sc.F, sc.T)
            if count > 0:
                # q has not moved since the last world_inertia (the step's start or the previous
                # sub-step's drift): the velocities only
                velocities(bodies, P, L, sc)
                apply_accumulated(contacts, rows, count, sc.v, sc.w, inv_mass, sc.inv_inertia)
                for _ in range(st.iterations):
                    soft_sweep(contacts, rows, count, sc.v, sc.w, inv_mass, sc.inv_inertia,
                               1.0 / hs, np.bool_(True), contact_soft, static_soft, st.push_speed)
                write_back(bodies, P, L, sc)
            drift(bodies, st.rotation, x, q, P, L, sc, hs)
            if count > 0:
                motion_since(x, q, sc)
                move_anchors(contacts, rows, count, sc.dp, sc.dR)
                body_velocities(bodies, q, P, L, sc)
                for _ in range(st.relax_iterations):
                    soft_sweep(contacts, rows, count, sc.v, sc.w, inv_mass, sc.inv_inertia,
                               1.0 / hs, np.bool_(False), contact_soft, static_soft, st.push_speed)
                write_back(bodies, P, L, sc)
        if count > 0:
            velocities(bodies, P, L, sc)  # (q as at the last sub-step's world_inertia)
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
        velocities(bodies, P, L, sc)  # (the kick does not move q)
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
