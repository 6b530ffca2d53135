"""3D kernels: the one implementation of the in-house rigid-body physics (numba, cached).

Every kernel takes the model's ``(bodies, gravity, springs, drag, loads)`` first (see model.py),
then ``control`` (a model.Control of per-body external wrenches, or None) and ``contacts`` (the
contact model's slot: None, read by no code yet); an effect the scene does not declare is
``None`` and its ``if ... is not None`` branch is removed when numba compiles the
specialisation for that scene, so the compiled step is composed of the declared effects' kernels
alone. The state is (x, q, P, L) as in Baraff's notes:

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
# Helpers called per body or per spring (and the effect kernels inside ``evaluate``) are inlined
# at numba's IR level: a call between compiled functions pays atomic reference counting on every
# array argument (measured: 145 ns per spring evaluation as a call, 19 ns inlined). ``evaluate``
# itself stays a call, once per stage: it is then compiled once per effect set and shared by all
# integrators, which halves the cold-cache compile time (72 s instead of 145 s for tests/rigid)
# for a few percent at N = 1.
INLINE = dict(JIT, inline="always")


# -- small vector helpers (scalars in, tuples out: no allocation) ------------------------------
@njit(**INLINE)
def quat_to_rotation(w, x, y, z):
    """R(q / |q|) row-major (r00, r01, ..., r22): valid for a quaternion slightly off unit length
    (RK stages)."""
    s = 2.0 / (w * w + x * x + y * y + z * z)
    return (1.0 - s * (y * y + z * z), s * (x * y - w * z), s * (x * z + w * y),
            s * (x * y + w * z), 1.0 - s * (x * x + z * z), s * (y * z - w * x),
            s * (x * z - w * y), s * (y * z + w * x), 1.0 - s * (x * x + y * y))


@njit(**INLINE)
def rotation_from_quat(q, i, R):
    """R[i] = R(q[i] / |q[i]|)."""
    (R[i, 0, 0], R[i, 0, 1], R[i, 0, 2], R[i, 1, 0], R[i, 1, 1], R[i, 1, 2], R[i, 2, 0],
     R[i, 2, 1], R[i, 2, 2]) = quat_to_rotation(q[i, 0], q[i, 1], q[i, 2], q[i, 3])


@njit(**INLINE)
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


@njit(**INLINE)
def quat_mul(aw, ax, ay, az, bw, bx, by, bz):
    """Hamilton product a * b."""
    return (aw * bw - ax * bx - ay * by - az * bz,
            aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw)


@njit(**INLINE)
def normalize_quat(q, i):
    """q[i] /= |q[i]|."""
    s = 1.0 / np.sqrt(q[i, 0] * q[i, 0] + q[i, 1] * q[i, 1] + q[i, 2] * q[i, 2]
                      + q[i, 3] * q[i, 3])
    for c in range(4):
        q[i, c] *= s


@njit(**JIT)
def normalize_quats(q):
    for i in range(q.shape[0]):
        normalize_quat(q, i)


@njit(**INLINE)
def rotate_left(q0, i, tx, ty, tz, q_out):
    """q_out[i] = exp(t) * q0[i]: rotate body i by the world rotation vector t."""
    ew, ex, ey, ez = quat_exp(tx, ty, tz)
    q_out[i, 0], q_out[i, 1], q_out[i, 2], q_out[i, 3] = quat_mul(
        ew, ex, ey, ez, q0[i, 0], q0[i, 1], q0[i, 2], q0[i, 3])


# -- kinematics and effects ----------------------------------------------------------------------
@njit(**INLINE)
def body_kinematics(bodies, q, P, L, i):
    """Scalars of body i: R(q) (row-major), v = P / m and w = R I_body^-1 R^T L (world)."""
    r00, r01, r02, r10, r11, r12, r20, r21, r22 = quat_to_rotation(q[i, 0], q[i, 1], q[i, 2],
                                                                   q[i, 3])
    im = bodies.inv_mass[i]
    # body-frame angular momentum R^T L, body-frame w, world w
    lb0 = r00 * L[i, 0] + r10 * L[i, 1] + r20 * L[i, 2]
    lb1 = r01 * L[i, 0] + r11 * L[i, 1] + r21 * L[i, 2]
    lb2 = r02 * L[i, 0] + r12 * L[i, 1] + r22 * L[i, 2]
    a = bodies.inv_inertia
    wb0 = a[i, 0, 0] * lb0 + a[i, 0, 1] * lb1 + a[i, 0, 2] * lb2
    wb1 = a[i, 1, 0] * lb0 + a[i, 1, 1] * lb1 + a[i, 1, 2] * lb2
    wb2 = a[i, 2, 0] * lb0 + a[i, 2, 1] * lb1 + a[i, 2, 2] * lb2
    return (r00, r01, r02, r10, r11, r12, r20, r21, r22,
            P[i, 0] * im, P[i, 1] * im, P[i, 2] * im,
            r00 * wb0 + r01 * wb1 + r02 * wb2,
            r10 * wb0 + r11 * wb1 + r12 * wb2,
            r20 * wb0 + r21 * wb1 + r22 * wb2)


@njit(**JIT)
def kinematics(bodies, q, P, L, R, v, w):
    """R = R(q); v = P / m; w = R I_body^-1 R^T L (world angular velocity), for every body."""
    for i in range(q.shape[0]):
        (R[i, 0, 0], R[i, 0, 1], R[i, 0, 2], R[i, 1, 0], R[i, 1, 1], R[i, 1, 2], R[i, 2, 0],
         R[i, 2, 1], R[i, 2, 2], v[i, 0], v[i, 1], v[i, 2], w[i, 0], w[i, 1],
         w[i, 2]) = body_kinematics(bodies, q, P, L, i)


# Effect kernels. Per-body effects (gravity, drag) return the body's contribution and are
# applied inside the one pass over bodies that also computes the kinematics; interaction and
# sparse effects (springs, loads) scatter into F and T afterwards.
@njit(**INLINE)
def gravity_force(bodies, g, i):
    """m_i g, at the centre of mass: no torque."""
    m = bodies.mass[i]
    return m * g[0], m * g[1], m * g[2]


@njit(**INLINE)
def drag_wrench(drag, i, vx, vy, vz, wx, wy, wz):
    """F = -c v (centre of mass), tau = -c_w w (world)."""
    cl = drag.linear[i]
    ca = drag.angular[i]
    return -cl * vx, -cl * vy, -cl * vz, -ca * wx, -ca * wy, -ca * wz


@njit(**INLINE)
def control_wrench(control, i):
    """Body i's external wrench of the Control (force at the centre of mass, torque; world)."""
    f = control.force
    t = control.torque
    return f[i, 0], f[i, 1], f[i, 2], t[i, 0], t[i, 1], t[i, 2]


@njit(**INLINE)
def spring_point(x, R, v, w, body, r, s):
    """World offset, position and velocity of the body-frame point r[s] (relative to the com)."""
    r0, r1, r2 = r[s, 0], r[s, 1], r[s, 2]
    ox = R[body, 0, 0] * r0 + R[body, 0, 1] * r1 + R[body, 0, 2] * r2
    oy = R[body, 1, 0] * r0 + R[body, 1, 1] * r1 + R[body, 1, 2] * r2
    oz = R[body, 2, 0] * r0 + R[body, 2, 1] * r1 + R[body, 2, 2] * r2
    px = x[body, 0] + ox
    py = x[body, 1] + oy
    pz = x[body, 2] + oz
    vx = v[body, 0] + w[body, 1] * oz - w[body, 2] * oy
    vy = v[body, 1] + w[body, 2] * ox - w[body, 0] * oz
    vz = v[body, 2] + w[body, 0] * oy - w[body, 1] * ox
    return ox, oy, oz, px, py, pz, vx, vy, vz


@njit(**INLINE)
def spring_ends(springs, s, x, R, v, w):
    """Spring s's two world offsets (from the centres of mass; zero at a world anchor) and the
    position and velocity of end a relative to end b."""
    oax, oay, oaz, pax, pay, paz, vax, vay, vaz = spring_point(x, R, v, w, springs.a[s],
                                                               springs.ra, s)
    if springs.b[s] >= 0:
        obx, oby, obz, pbx, pby, pbz, vbx, vby, vbz = spring_point(x, R, v, w, springs.b[s],
                                                                   springs.rb, s)
    else:
        obx = oby = obz = 0.0
        pbx, pby, pbz = springs.rb[s, 0], springs.rb[s, 1], springs.rb[s, 2]
        vbx = vby = vbz = 0.0
    return (oax, oay, oaz, obx, oby, obz, pax - pbx, pay - pby, paz - pbz,
            vax - vbx, vay - vby, vaz - vbz)


@njit(**INLINE)
def spring_force(springs, s, x, R, v, w):
    """Force on body a of spring s and the two world offsets: -(k (l - l0) + c dl/dt) e."""
    oax, oay, oaz, obx, oby, obz, dx, dy, dz, dvx, dvy, dvz = spring_ends(springs, s, x, R, v, w)
    length = np.sqrt(dx * dx + dy * dy + dz * dz)
    if length > 0.0:
        ex, ey, ez = dx / length, dy / length, dz / length
    else:
        ex = ey = ez = 0.0  # coincident points: the direction (and the force) is undefined -> 0
    rate = ex * dvx + ey * dvy + ez * dvz
    mag = -(springs.stiffness[s] * (length - springs.rest_length[s])
            + springs.damping[s] * rate)
    return mag * ex, mag * ey, mag * ez, oax, oay, oaz, obx, oby, obz


@njit(**INLINE)
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


@njit(**INLINE)
def apply_loads(loads, F, T):
    for k in range(loads.body.shape[0]):
        i = loads.body[k]
        for c in range(3):
            F[i, c] += loads.force[k, c]
            T[i, c] += loads.torque[k, c]


@njit(**INLINE)
def body_wrench(drag, control, i, vx, vy, vz, wx, wy, wz, fx, fy, fz, tx, ty, tz):
    """(fx, ..., tz) + body i's drag, then + its control wrench: the per-body terms of
    ``accumulate``, kept in registers (the in-house pass adds them right after gravity)."""
    if drag is not None:
        dfx, dfy, dfz, dtx, dty, dtz = drag_wrench(drag, i, vx, vy, vz, wx, wy, wz)
        fx += dfx
        fy += dfy
        fz += dfz
        tx += dtx
        ty += dty
        tz += dtz
    if control is not None:
        cfx, cfy, cfz, ctx, cty, ctz = control_wrench(control, i)
        fx += cfx
        fy += cfy
        fz += cfz
        tx += ctx
        ty += cty
        tz += ctz
    return fx, fy, fz, tx, ty, tz


@njit(**INLINE)
def accumulate(springs, drag, loads, control, x, R, v, w, F, T):
    """F, T += the smooth force law at world-frame states: the one implementation of drag, the
    control's wrench, springs and loads, shared by the in-house force pass and PyBullet's adapter.

    x (N, 3) centres of mass, R (N, 3, 3) the rotations of the frames the springs' offsets are
    stored in (read by springs only), v, w (N, 3) centre-of-mass and angular velocities, all
    world frame; F, T (N, 3) hold what came before (gravity) and are added to, per body in this
    order: drag, the control's wrench (``body_wrench``), then every spring, then every load.
    An effect given as ``None`` leaves no code (numba prunes its branch). The in-house pass adds
    the per-body terms in its kinematics loop and passes ``drag=control=None`` here.
    """
    if drag is not None or control is not None:
        for i in range(F.shape[0]):
            F[i, 0], F[i, 1], F[i, 2], T[i, 0], T[i, 1], T[i, 2] = body_wrench(
                drag, control, i, v[i, 0], v[i, 1], v[i, 2], w[i, 0], w[i, 1], w[i, 2],
                F[i, 0], F[i, 1], F[i, 2], T[i, 0], T[i, 1], T[i, 2])
    if springs is not None:
        apply_springs(springs, x, R, v, w, F, T)
    if loads is not None:
        apply_loads(loads, F, T)


@njit(**JIT)
def accumulate_rows(springs, drag, loads, rows, x, R, v, w, F, T):
    """F, T = the force law (``accumulate``, no gravity, no control) at states given as rows
    (N, 13): centre of mass (3), unit quaternion as (x, y, z, w), scalar last, the order Bullet
    reports it (4), centre-of-mass velocity (3), angular velocity (3), all world frame. x, R, v,
    w are filled from the rows (scratch for the caller: PyBullet's adapter, once per step)."""
    for i in range(rows.shape[0]):
        for c in range(3):
            x[i, c] = rows[i, c]
            v[i, c] = rows[i, 7 + c]
            w[i, c] = rows[i, 10 + c]
            F[i, c] = 0.0
            T[i, c] = 0.0
        (R[i, 0, 0], R[i, 0, 1], R[i, 0, 2], R[i, 1, 0], R[i, 1, 1], R[i, 1, 2], R[i, 2, 0],
         R[i, 2, 1], R[i, 2, 2]) = quat_to_rotation(rows[i, 6], rows[i, 3], rows[i, 4],
                                                    rows[i, 5])
    accumulate(springs, drag, loads, None, x, R, v, w, F, T)


@njit(**JIT)
def evaluate(bodies, gravity, springs, drag, loads, control, contacts, x, q, P, L, R, v, w, F, T):
    """Kinematics and the net force and torque of the declared effects at (x, q, P, L).

    One pass over the bodies computes R, v, w, gravity and ``accumulate``'s per-body terms
    (drag, the control's external wrench: ``body_wrench``); ``accumulate`` then adds springs
    and loads. Every ``is not None`` test is resolved when
    numba compiles the specialisation for the scene's effects: an undeclared effect, or
    ``control=None``, leaves no code in the step (R is only stored when springs need it).
    ``contacts`` is the contact model's slot, always None today: no code reads it.
    """
    for i in range(q.shape[0]):
        (r00, r01, r02, r10, r11, r12, r20, r21, r22, vx, vy, vz, wx, wy,
         wz) = body_kinematics(bodies, q, P, L, i)
        if springs is not None:
            R[i, 0, 0], R[i, 0, 1], R[i, 0, 2] = r00, r01, r02
            R[i, 1, 0], R[i, 1, 1], R[i, 1, 2] = r10, r11, r12
            R[i, 2, 0], R[i, 2, 1], R[i, 2, 2] = r20, r21, r22
        v[i, 0], v[i, 1], v[i, 2] = vx, vy, vz
        w[i, 0], w[i, 1], w[i, 2] = wx, wy, wz
        fx = fy = fz = tx = ty = tz = 0.0
        if gravity is not None:
            gx, gy, gz = gravity_force(bodies, gravity, i)
            fx += gx
            fy += gy
            fz += gz
        # accumulate's per-body terms, fused into this pass (the same helper, the same order)
        F[i, 0], F[i, 1], F[i, 2], T[i, 0], T[i, 1], T[i, 2] = body_wrench(
            drag, control, i, vx, vy, vz, wx, wy, wz, fx, fy, fz, tx, ty, tz)
    accumulate(springs, None, loads, None, x, R, v, w, F, T)


@njit(**INLINE)
def quat_rate_of(q, i, wx, wy, wz):
    """dq/dt = 1/2 (0, w) * q for body i, w in the world frame."""
    qw, qx, qy, qz = q[i, 0], q[i, 1], q[i, 2], q[i, 3]
    return (-0.5 * (wx * qx + wy * qy + wz * qz), 0.5 * (wx * qw + wy * qz - wz * qy),
            0.5 * (wy * qw + wz * qx - wx * qz), 0.5 * (wz * qw + wx * qy - wy * qx))


@njit(**JIT)
def quat_rate(q, w, dq):
    for i in range(q.shape[0]):
        dq[i, 0], dq[i, 1], dq[i, 2], dq[i, 3] = quat_rate_of(q, i, w[i, 0], w[i, 1], w[i, 2])


@njit(**JIT)
def derivative(bodies, gravity, springs, drag, loads, control, contacts,
               x, q, P, L, dx, dq, dP, dL):
    """The generic state derivative (dx, dq, dP, dL) = (v, 1/2 w q, F, tau) (solve_ivp etc.)."""
    n = x.shape[0]
    R = np.empty((n, 3, 3))
    w = np.empty((n, 3))
    evaluate(bodies, gravity, springs, drag, loads, control, contacts, x, q, P, L, R, dx, w, dP, dL)
    quat_rate(q, w, dq)


@njit(**JIT)
def observe(bodies, q, P, L, vel, omega):
    """Recorded quantities: centre-of-mass velocity and world angular velocity."""
    n = q.shape[0]
    R = np.empty((n, 3, 3))
    kinematics(bodies, q, P, L, R, vel, omega)


# -- scratch arrays and the per-body state updates every integrator is written with ---------------
# Each kernel allocates its scratch once per call (not per step) and updates body by body inside
# its loops over bodies, so one pass does a whole stage (rate, accumulator, next stage state)
# while the body's data are in cache. The helpers are inlined: they keep the fixed trip counts (3
# and 4, unrolled) and the exact floating-point expressions (``y + s * k``) of the hand-written
# loops they replaced, so the results did not change by a bit.
@njit(**INLINE)
def force_scratch(n):
    """What ``evaluate`` fills: R (n, 3, 3), v, w, F, T (n, 3)."""
    return (np.empty((n, 3, 3)), np.empty((n, 3)), np.empty((n, 3)), np.empty((n, 3)),
            np.empty((n, 3)))


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


# -- explicit Runge-Kutta family (additive quaternion update, renormalised after the step) -------
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
            free_rotation(bodies, q, L, i, h, False)


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
            free_rotation(bodies, q, L, i, h, True)
        evaluate(bodies, gravity, springs, drag, loads, control, contacts,
                 x, q, Pp, Lp, R, v, w, F, T)
        for i in range(n):
            kick(i, hh, P, L, F, T)


# -- implicit Euler (the method is described in implicit.py) -------------------------------
@njit(**JIT)
def _skew(r0, r1, r2, out, o_r, o_c):
    """out[o_r:o_r+3, o_c:o_c+3] = [r]x (the cross-product matrix)."""
    out[o_r + 0, o_c + 0] = 0.0
    out[o_r + 0, o_c + 1] = -r2
    out[o_r + 0, o_c + 2] = r1
    out[o_r + 1, o_c + 0] = r2
    out[o_r + 1, o_c + 1] = 0.0
    out[o_r + 1, o_c + 2] = -r0
    out[o_r + 2, o_c + 0] = -r1
    out[o_r + 2, o_c + 1] = r0
    out[o_r + 2, o_c + 2] = 0.0


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
    _skew(-oax, -oay, -oaz, J, 0, 3)
    _skew(obx, oby, obz, J, 0, 9)
    # H: d(dv) from rotating the arms, -[wa]x[oa]x dphi_a + [wb]x[ob]x dphi_b
    H = np.zeros((3, 12))
    Sa = np.zeros((3, 3))
    Sb = np.zeros((3, 3))
    Wa = np.zeros((3, 3))
    Wb = np.zeros((3, 3))
    _skew(oax, oay, oaz, Sa, 0, 0)
    _skew(obx, oby, obz, Sb, 0, 0)
    _skew(w[a, 0], w[a, 1], w[a, 2], Wa, 0, 0)
    if b >= 0:
        _skew(w[b, 0], w[b, 1], w[b, 2], Wb, 0, 0)
    H[:, 3:6] = -(Wa @ Sa)
    H[:, 9:12] = Wb @ Sb
    Kf = Kd @ J + Dd @ H
    Ks[:, :] = J.T @ Kf
    Ds[:, :] = J.T @ (Dd @ J)
    # geometric terms of the torques: d(oa x f) from turning oa, d(-ob x f) from turning ob
    Fx = np.zeros((3, 3))
    _skew(f[0], f[1], f[2], Fx, 0, 0)
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


@njit(**INLINE)
def _solve3(A, b0, b1, b2):
    """A^-1 b for a 3 x 3 A by the adjugate."""
    c00 = A[1, 1] * A[2, 2] - A[1, 2] * A[2, 1]
    c01 = A[1, 2] * A[2, 0] - A[1, 0] * A[2, 2]
    c02 = A[1, 0] * A[2, 1] - A[1, 1] * A[2, 0]
    det = A[0, 0] * c00 + A[0, 1] * c01 + A[0, 2] * c02
    x0 = (c00 * b0 + (A[0, 2] * A[2, 1] - A[0, 1] * A[2, 2]) * b1
          + (A[0, 1] * A[1, 2] - A[0, 2] * A[1, 1]) * b2) / det
    x1 = (c01 * b0 + (A[0, 0] * A[2, 2] - A[0, 2] * A[2, 0]) * b1
          + (A[0, 2] * A[1, 0] - A[0, 0] * A[1, 2]) * b2) / det
    x2 = (c02 * b0 + (A[0, 1] * A[2, 0] - A[0, 0] * A[2, 1]) * b1
          + (A[0, 0] * A[1, 1] - A[0, 1] * A[1, 0]) * b2) / det
    return x0, x1, x2


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
        d0, d1, d2 = _solve3(J, p0 - h * wx, p1 - h * wy, p2 - h * wz)
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
            du[6 * i + 3], du[6 * i + 4], du[6 * i + 5] = _solve3(A, h * T[i, 0], h * T[i, 1],
                                                                  h * T[i, 2])
        finish_3d(bodies, x, q, P, L, Iw, ws, h, du)
