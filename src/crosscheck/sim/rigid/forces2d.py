"""2D forces: the planar specialisation (scalar angle and angular momentum) of forces3d.

State (x (N, 2), angle (N,), P (N, 2), L (N,)); dx/dt = P/m, dangle/dt = L/I, dP/dt = F,
dL/dt = tau with tau = r x f = r_x f_y - r_y f_x. ``evaluate`` is the force pass of every 2D
integrator; ``accumulate`` the force law at world-frame planar states, shared with PyBullet's
adapter (``accumulate_rows``, its planar-joint bodies). Effects, ``control`` and the ``contacts``
slot are composed as in forces3d. ``state_scratch`` gives the arrays shaped like the state that
every 2D family uses.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from crosscheck.sim._jit import INLINE, JIT
from crosscheck.sim.rigid.contact_forces import contact_wrench2d


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
    """Kinematics, gravity, then ``accumulate`` (springs, drag, loads, control). No gravity is a
    zero-length ``gravity`` (RigidModel.kernel_args), tested at run time."""
    kinematics(bodies, P, L, v, w)
    F[:] = 0.0
    T[:] = 0.0
    if gravity.shape[0] != 0:  # no gravity: a zero-length array (RigidModel.kernel_args)
        apply_gravity(bodies, gravity, F)
    if springs is not None or drag is not None or loads is not None or control is not None:
        accumulate(springs, drag, loads, control, x, angle, v, w, F, T)
    if contacts is not None:  # a force-level contact model's forces (contact_forces.py)
        contact_wrench2d(bodies, contacts, x, angle, P, L, v, w, F, T)


@njit(**JIT)
def derivative(bodies, gravity, springs, drag, loads, control, contacts,
               x, angle, P, L, dx, dangle, dP, dL):
    evaluate(bodies, gravity, springs, drag, loads, control, contacts,
             x, angle, P, L, dx, dangle, dP, dL)


@njit(**JIT)
def observe(bodies, P, L, vel, omega):
    kinematics(bodies, P, L, vel, omega)


@njit(**INLINE)
def state_scratch(n):
    """Arrays shaped like the state (x, angle, P, L) and like its derivative (v, w, F, T): a
    stage state, a Runge-Kutta accumulator or what ``evaluate`` fills."""
    return np.empty((n, 2)), np.empty(n), np.empty((n, 2)), np.empty(n)

