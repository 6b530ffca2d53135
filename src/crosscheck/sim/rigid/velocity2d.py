"""2D velocity-level contact steps (sequential_impulse, soft_step) on the planar Baraff state
(x (N, 2), angle (N,), P (N, 2), L (N,)).

The rows are contact_rows' (3D with the plane embedded exactly); this module fills the embedded
velocities (v, 0) and (0, 0, w), the inverse inertia diag(0, 0, 1/I), kicks and drifts as
splitting2d does (the angle is a plain coordinate: both integrators are the same in 2D), and
writes back only what the contacts changed, so a body no contact touches steps bit for bit as
the contact-free kernel moves it.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit

from crosscheck.sim.collide import detect2d
from crosscheck.sim.rigid._jit import INLINE, JIT
from crosscheck.sim.rigid.contact_rows import (
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
from crosscheck.sim.rigid.forces2d import evaluate
from crosscheck.sim.rigid.splitting2d import kick


class Scratch2D(NamedTuple):
    ev: np.ndarray  # (N, 2) evaluate's scratch
    ew: np.ndarray  # (N,)
    F: np.ndarray  # (N, 2)
    T: np.ndarray  # (N,)
    v: np.ndarray  # (N, 3) embedded velocities
    w: np.ndarray  # (N, 3)
    v0: np.ndarray
    w0: np.ndarray
    inv_inertia: np.ndarray  # (N, 3, 3): zero but [2, 2] = 1 / I
    vp: np.ndarray  # (N, 3) pseudo-velocities
    wp: np.ndarray
    dp: np.ndarray  # (N, 3) motion since detection
    dR: np.ndarray  # (N, 3, 3)
    x0: np.ndarray  # (N, 2)
    angle0: np.ndarray  # (N,)


@njit(**INLINE)
def scratch2d(bodies, n):
    inv_inertia = np.zeros((n, 3, 3))
    dR = np.zeros((n, 3, 3))
    for i in range(n):
        inv_inertia[i, 2, 2] = bodies.inv_moment[i]
        dR[i, 0, 0] = dR[i, 1, 1] = dR[i, 2, 2] = 1.0
    return Scratch2D(np.empty((n, 2)), np.empty(n), np.empty((n, 2)), np.empty(n),
                     np.zeros((n, 3)), np.zeros((n, 3)), np.zeros((n, 3)), np.zeros((n, 3)),
                     inv_inertia, np.zeros((n, 3)), np.zeros((n, 3)), np.zeros((n, 3)), dR,
                     np.zeros((n, 2)), np.zeros(n))


def new_scratch2d(bodies, n: int) -> Scratch2D:
    return scratch2d.py_func(bodies, n)


@njit(**INLINE)
def body_velocities(bodies, P, L, sc):
    for i in range(P.shape[0]):
        im = bodies.inv_mass[i]
        sc.v[i, 0] = sc.v0[i, 0] = P[i, 0] * im
        sc.v[i, 1] = sc.v0[i, 1] = P[i, 1] * im
        sc.w[i, 2] = sc.w0[i, 2] = L[i] * bodies.inv_moment[i]


@njit(**INLINE)
def write_back(bodies, P, L, sc):
    for i in range(P.shape[0]):
        m = bodies.mass[i]
        P[i, 0] += m * (sc.v[i, 0] - sc.v0[i, 0])
        P[i, 1] += m * (sc.v[i, 1] - sc.v0[i, 1])
        L[i] += bodies.moment[i] * (sc.w[i, 2] - sc.w0[i, 2])


@njit(**INLINE)
def drift(bodies, x, angle, P, L, h):
    for i in range(x.shape[0]):
        for c in range(2):
            x[i, c] += h * P[i, c] * bodies.inv_mass[i]
        angle[i] += h * L[i] * bodies.inv_moment[i]


@njit(**INLINE)
def motion_since(x, angle, sc):
    for i in range(x.shape[0]):
        sc.dp[i, 0] = x[i, 0] - sc.x0[i, 0]
        sc.dp[i, 1] = x[i, 1] - sc.x0[i, 1]
        da = angle[i] - sc.angle0[i]
        c = np.cos(da)
        s = np.sin(da)
        sc.dR[i, 0, 0] = c
        sc.dR[i, 0, 1] = -s
        sc.dR[i, 1, 0] = s
        sc.dR[i, 1, 1] = c


@njit(**JIT)
def step2d(bodies, gravity, springs, drag, loads, control, contacts, rows, st, sc, x, angle, P,
           L, h):
    """One step of the model ``st.model`` on the contacts detected at (x, angle), in place."""
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
            body_velocities(bodies, P, L, sc)
            prepare_rows(contacts, rows, count, x, sc.v, sc.w, inv_mass, sc.inv_inertia)
            match_rows(contacts, rows, count, st.warm_starting)
            for i in range(n):
                sc.x0[i, 0] = x[i, 0]
                sc.x0[i, 1] = x[i, 1]
                sc.angle0[i] = angle[i]
            motion_since(x, angle, sc)
        for _ in range(k):
            evaluate(bodies, gravity, springs, drag, loads, control, None, x, angle, P, L, sc.ev,
                     sc.ew, sc.F, sc.T)
            for i in range(n):
                kick(i, hs, P, L, sc.F, sc.T)
            if count > 0:
                body_velocities(bodies, P, L, sc)
                apply_accumulated(contacts, rows, count, sc.v, sc.w, inv_mass, sc.inv_inertia)
                for _ in range(st.iterations):
                    soft_sweep(contacts, rows, count, sc.v, sc.w, inv_mass, sc.inv_inertia,
                               1.0 / hs, np.bool_(True), contact_soft, static_soft, st.push_speed)
                write_back(bodies, P, L, sc)
            drift(bodies, x, angle, P, L, hs)
            if count > 0:
                motion_since(x, angle, sc)
                move_anchors(contacts, rows, count, sc.dp, sc.dR)
                body_velocities(bodies, P, L, sc)
                for _ in range(st.relax_iterations):
                    soft_sweep(contacts, rows, count, sc.v, sc.w, inv_mass, sc.inv_inertia,
                               1.0 / hs, np.bool_(False), contact_soft, static_soft, st.push_speed)
                write_back(bodies, P, L, sc)
        if count > 0:
            body_velocities(bodies, P, L, sc)
            restitution_pass(contacts, rows, count, sc.v, sc.w, inv_mass, sc.inv_inertia,
                             st.restitution_threshold)
            write_back(bodies, P, L, sc)
            store_rows(contacts, rows, count)
        else:
            rows.prev_count[0] = 0
        return
    # sequential_impulse: rows prepared with the velocities before the kick (restitution)
    if count > 0:
        body_velocities(bodies, P, L, sc)
        prepare_rows(contacts, rows, count, x, sc.v, sc.w, inv_mass, sc.inv_inertia)
        match_rows(contacts, rows, count, st.warm_starting)
    evaluate(bodies, gravity, springs, drag, loads, control, None, x, angle, P, L, sc.ev, sc.ew,
             sc.F, sc.T)
    for i in range(n):
        kick(i, h, P, L, sc.F, sc.T)
    if count > 0:
        body_velocities(bodies, P, L, sc)
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
    drift(bodies, x, angle, P, L, h)
    if count > 0:
        for i in range(n):
            x[i, 0] += h * sc.vp[i, 0]
            x[i, 1] += h * sc.vp[i, 1]
            angle[i] += h * sc.wp[i, 2]


@njit(**JIT)
def advance2d(bodies, gravity, springs, drag, loads, control, geometry, contacts, rows, st,
              x, angle, P, L, n_steps, h):
    """n_steps steps: detect at the start of each, then ``step2d``; returns the steps taken
    (fewer when detection overflowed the buffer)."""
    sc = scratch2d(bodies, x.shape[0])
    for s in range(n_steps):
        if detect2d(geometry, x, angle, contacts) > contacts.a.shape[0]:
            return s
        step2d(bodies, gravity, springs, drag, loads, control, contacts, rows, st, sc, x, angle,
               P, L, h)
    return n_steps
