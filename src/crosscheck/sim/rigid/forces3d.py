"""3D forces: kinematics and the smooth force law (gravity, drag, control, springs, loads).

The state is (x, q, P, L) as in Baraff's notes:

    dx/dt = P / m,   dq/dt = 1/2 (0, w) q,   dP/dt = F,   dL/dt = tau,
    w = R I_body^-1 R^T L,   R = R(q).

``evaluate`` is the force pass every integrator calls once per stage; ``accumulate`` is the force
law at world-frame states, shared with PyBullet's adapter (``accumulate_rows``). Every kernel takes
the model's ``(bodies, gravity, springs, drag, loads)`` first (see model.py), then ``control`` (a
model.Control of per-body external wrenches, or None) and ``contacts`` (the contact model's slot:
None, read by no code yet); an effect the scene does not declare is ``None`` and its
``if ... is not None`` branch is removed when numba compiles the specialisation for that scene,
so the compiled step is composed of the declared effects' kernels alone.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from crosscheck.sim._jit import INLINE, JIT
from crosscheck.sim.rigid.contact_forces import contact_wrench3d
from crosscheck.sim.rigid.math3d import quat_rate, quat_to_rotation


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


# Effect kernels. Per-body effects (gravity, drag, the control's wrench) return the body's
# contribution and are applied inside the one pass over bodies that also computes the kinematics;
# interaction and sparse effects (springs, loads) scatter into F and T afterwards.
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
    Gravity is the exception, never None: a scene without it passes a zero-length array,
    tested per body at run time, so that a scene with and one without gravity share one
    compiled step (RigidModel.kernel_args says why).
    ``contacts`` is a force-level contact model's argument (contact_forces.py) or None, which
    leaves no contact code in the step.
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
        if gravity.shape[0] != 0:  # no gravity: a zero-length array (RigidModel.kernel_args)
            gx, gy, gz = gravity_force(bodies, gravity, i)
            fx += gx
            fy += gy
            fz += gz
        # accumulate's per-body terms, fused into this pass (the same helper, the same order)
        if drag is not None or control is not None:
            fx, fy, fz, tx, ty, tz = body_wrench(drag, control, i, vx, vy, vz, wx, wy, wz,
                                                 fx, fy, fz, tx, ty, tz)
        F[i, 0], F[i, 1], F[i, 2], T[i, 0], T[i, 1], T[i, 2] = fx, fy, fz, tx, ty, tz
    if springs is not None or loads is not None:
        accumulate(springs, None, loads, None, x, R, v, w, F, T)
    if contacts is not None:  # a force-level contact model's forces (contact_forces.py)
        contact_wrench3d(bodies, contacts, x, q, P, L, v, w, F, T)


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


@njit(**INLINE)
def force_scratch(n):
    """What ``evaluate`` fills: R (n, 3, 3), v, w, F, T (n, 3)."""
    return (np.empty((n, 3, 3)), np.empty((n, 3)), np.empty((n, 3)), np.empty((n, 3)),
            np.empty((n, 3)))

