"""Analytic reference solutions, by the name a case gives in ``[reference] solution``.

``SOLUTIONS[name](scene, times) -> Trajectory`` evaluates the closed-form motion of the scene's
bodies at the given times, in the Trajectory convention (centre of mass and its velocity, world;
orientation of the declared body frame; world angular velocity). Entries are NaN where a solution
does not define a quantity (the comparer skips them). A scene outside a solution's assumptions is
refused with a ValueError that says which assumption failed, never answered approximately.

``EXTRA_METRICS[name](scene, traj) -> {metric: value}`` adds derived checks for a solution (the
comparer calls the entry of the case's solution); a value ``(None, reason)`` means the quantity
could not be measured in this run (reported as not measured, never as a number), and a metric
``<base>_resolution`` next to ``<base>_error`` states the measurement's own resolution (errors
near it are at the metric's floor). ``torque_free_intermediate`` (also under the key
``flip_period``) measures the flip period of a run against the elliptic-integral period.

Solutions
---------
free_fall, projectile (one function, 2D and 3D)
    Constant acceleration a = g + F_load / m with optional linear drag c:
    v(t) = v0 e^(-kt) + a (1 - e^(-kt)) / k, x(t) = x0 + v0 phi1(t) + a phi2(t), k = c / m
    (k = 0: the parabola). Rotation: 2D always (the same law for the angle with I and the angular
    drag and load torque); 3D when the body turns about one fixed axis, i.e. its angular
    velocity (or the load torque, from rest) lies along a principal axis of I_world and any load
    torque is parallel to it: q(t) = exp(theta(t) n) q0. Otherwise orientation and angular
    velocity are NaN.
harmonic_oscillator (2D and 3D)
    Each body on one spring to a world anchor, attached at its centre of mass (no torque):
    undamped, underdamped, critically damped and overdamped (spring damping plus linear drag).
    Either the spring is linear (rest length 0, no spring damping: each coordinate oscillates
    about anchor + F_ext / k) or the motion stays on the line through the anchor (initial offset,
    velocity and external force along it): s'' + 2 beta s' + w0^2 (s - s_eq) = 0. Rotation as in
    projectile.
torque_free_axisymmetric (3D)
    I1 = I2 = I_perp, I3 = I_a about the body's symmetry axis a. L is fixed; the body precesses
    about L at |L| / I_perp while spinning about a at lambda = (1/I_a - 1/I_perp) (L . n):
    q(t) = exp(t L / I_perp) q0 exp(t lambda a),  w(t) = L / I_perp + lambda n(t),  n = R a.
torque_free_intermediate (3D)
    Euler's equations for I1 < I2 < I3 solved with Jacobi elliptic functions (Landau and Lifshitz,
    Mechanics, section 37): with 2E = sum I w^2, M^2 = sum I^2 w^2 and M^2 > 2 E I2,
    w1 = A1 cn(u), w2 = A2 sn(u), w3 = A3 dn(u), u = rate t + u0, modulus
    m = (I2 - I1)(2E I3 - M^2) / ((I3 - I2)(M^2 - 2E I1)), rate = sqrt((I3 - I2)(M^2 - 2E I1) /
    (I1 I2 I3)); for M^2 < 2 E I2 the suffixes 1 and 3 swap. The motion repeats with period
    T = 4 K(m) / rate; the intermediate component changes sign every T / 2 (the flips). The
    body-frame angular velocity is in ``extras["omega_body"]`` (declared body axes); world
    orientation and angular velocity are NaN (they need a quadrature this reference avoids).
"""

from __future__ import annotations

from collections.abc import Callable
from math import factorial

import numpy as np
from scipy import special

from crosscheck.rotations import quat_mul, quat_to_matrix, rotvec_to_quat
from crosscheck.scene.model import Scene
from crosscheck.state import Trajectory

# Relative tolerances deciding whether a scene meets a solution's assumptions. They test exact
# inputs (a case's numbers), so they sit a little above round-off of the mass-property code.
PRINCIPAL_RTOL = 1e-9  # |I n - (n.I n) n| / |I| for "n is a principal axis"
EQUAL_MOMENTS_RTOL = 1e-9  # |I_i - I_j| / I_max for "axisymmetric"
PARALLEL_RTOL = 1e-12  # |a x n| / |a| for "parallel"
AT_COM_ATOL = 1e-12  # m, |attachment - centre of mass| for "attached at the centre of mass"


# -- shared pieces --------------------------------------------------------------------------------
def _phi(t: np.ndarray, k: float) -> tuple[np.ndarray, np.ndarray]:
    """phi1 = int_0^t e^(-ks) ds and phi2 = int_0^t phi1, without cancellation for small kt."""
    if k == 0.0:
        return t.copy(), 0.5 * t * t
    z = k * t
    phi1 = -np.expm1(-z) / k
    # phi2 = t^2 sum_n (-z)^n / (n + 2)!: the series for z < 0.5 (26 terms: < 1e-30 left), the
    # closed form (t - phi1) / k above (its cancellation costs at most 2 eps / z < 4 eps).
    phi2 = (t - phi1) / k
    small = z < 0.5
    ts, zs = t[small], z[small]
    series = np.zeros_like(ts)
    term = np.ones_like(ts)
    for n in range(26):
        series += term / factorial(n + 2)
        term = term * (-zs)
    phi2[small] = ts * ts * series
    return phi1, phi2


def _relax(t: np.ndarray, y0, v0, a, k: float) -> tuple[np.ndarray, np.ndarray]:
    """y'' = a - k y' from (y0, v0): (y(t), y'(t)) for vectors (or scalars) y0, v0, a."""
    phi1, phi2 = _phi(t, k)
    y0, v0, a = (np.asarray(u, float) for u in (y0, v0, a))
    shape = (len(t),) + (1,) * y0.ndim
    phi1, phi2, decay = (p.reshape(shape) for p in (phi1, phi2, np.exp(-k * t)))
    return y0 + v0 * phi1 + a * phi2, v0 * decay + a * phi1


def _drag_of(scene: Scene, i: int) -> tuple[float, float]:
    lin = sum(d.linear for d in scene.effects.drag if i in d.bodies)
    ang = sum(d.angular for d in scene.effects.drag if i in d.bodies)
    return float(lin), float(ang)


def _loads_of(scene: Scene, i: int) -> tuple[np.ndarray, np.ndarray]:
    d = scene.dimension
    force = np.zeros(d)
    torque = np.zeros(3 if d == 3 else 1)
    for load in scene.effects.loads:
        if load.body == i:
            force += load.force
            torque += np.asarray(load.torque, float).reshape(-1)
    return force, torque


def _external_force(scene: Scene, i: int) -> np.ndarray:
    body = scene.bodies[i]
    force, _ = _loads_of(scene, i)
    return force + body.mass * scene.effects.gravity_vector(scene.dimension)


def _new(scene: Scene, times: np.ndarray, name: str) -> Trajectory:
    t = np.asarray(times, float)
    n, d = len(scene.bodies), scene.dimension
    nan = np.full((len(t), n, d), np.nan)
    traj = Trajectory(t=t.copy(), com=nan.copy(), vel=nan.copy(),
                      omega=np.full((len(t), n, 3) if d == 3 else (len(t), n), np.nan),
                      meta={"engine": "analytic", "solution": name, "case": scene.name,
                            "bodies": list(scene.body_names),
                            "masses": [b.mass for b in scene.bodies], "failure": None})
    if d == 3:
        traj.quat = np.full((len(t), n, 4), np.nan)
    else:
        traj.angle = np.full((len(t), n), np.nan)
    return traj


def _refuse(name: str, why: str) -> ValueError:
    return ValueError(f"analytic solution {name!r} does not apply: {why}")


def _require_no_springs(scene: Scene, name: str) -> None:
    if scene.effects.springs:
        raise _refuse(name, "the scene has springs")
    if scene.effects.contact or scene.fluid is not None:
        raise _refuse(name, "the scene has contact or a fluid")
    _require_no_medium(scene, name)


def _require_no_medium(scene: Scene, name: str) -> None:
    if scene.effects.medium is not None:
        raise _refuse(name, "the scene has a medium (its solution is medium_settling)")


def _translate(scene: Scene, i: int, t: np.ndarray, traj: Trajectory) -> None:
    """Constant force (gravity + loads) with linear drag, into traj for body i."""
    body = scene.bodies[i]
    c_lin, _ = _drag_of(scene, i)
    a = _external_force(scene, i) / body.mass
    traj.com[:, i], traj.vel[:, i] = _relax(t, body.com_world(), body.velocity, a,
                                            c_lin / body.mass)


def _rotate(scene: Scene, i: int, t: np.ndarray, traj: Trajectory) -> None:
    """Rotation about a fixed axis under a constant parallel torque and angular drag, if any."""
    body = scene.bodies[i]
    _, c_ang = _drag_of(scene, i)
    _, torque = _loads_of(scene, i)
    if scene.dimension == 2:
        angle, omega = _relax(t, body.angle, body.angular_velocity[0], torque[0] / body.moment,
                              c_ang / body.moment)
        traj.angle[:, i], traj.omega[:, i] = angle, omega
        return
    w0 = np.asarray(body.angular_velocity, float)
    wn, tn = np.linalg.norm(w0), np.linalg.norm(torque)
    if wn == 0.0 and tn == 0.0:
        traj.quat[:, i] = body.orientation
        traj.omega[:, i] = 0.0
        return
    n = w0 / wn if wn > 0 else torque / tn
    iw = body.inertia_world()
    i_n = float(n @ iw @ n)
    principal = np.linalg.norm(iw @ n - i_n * n) <= PRINCIPAL_RTOL * np.linalg.norm(iw, 2)
    parallel = tn == 0.0 or np.linalg.norm(np.cross(torque, n)) <= PARALLEL_RTOL * tn
    if not (principal and parallel):
        return  # the spin axis moves: orientation and angular velocity stay undefined (NaN)
    theta, rate = _relax(t, 0.0, float(w0 @ n), float(torque @ n) / i_n, c_ang / i_n)
    traj.quat[:, i] = quat_mul(rotvec_to_quat(theta[:, None] * n), body.orientation)
    traj.omega[:, i] = rate[:, None] * n


# -- free fall and projectile -----------------------------------------------------------------
def projectile(scene: Scene, times: np.ndarray) -> Trajectory:
    """Gravity, constant loads and linear drag, no springs; 2D and 3D (see the module doc)."""
    _require_no_springs(scene, "projectile")
    t = np.asarray(times, float)
    traj = _new(scene, t, "projectile")
    for i in range(len(scene.bodies)):
        _translate(scene, i, t, traj)
        _rotate(scene, i, t, traj)
    return traj


# -- harmonic oscillator --------------------------------------------------------------------------
def _damped(t: np.ndarray, u0: float, v0: float, w0: float, beta: float):
    """u'' + 2 beta u' + w0^2 u = 0 from (u0, v0): (u(t), u'(t)), every damping regime."""
    if beta == 0.0:
        c, s = np.cos(w0 * t), np.sin(w0 * t)
        return u0 * c + v0 / w0 * s, v0 * c - w0 * u0 * s
    b = v0 + beta * u0
    gap = w0 * w0 - beta * beta
    if abs(gap) <= 1e-12 * w0 * w0:  # critical
        e = np.exp(-beta * t)
        return e * (u0 + b * t), e * (v0 - beta * b * t)
    if gap > 0:  # underdamped
        wd = np.sqrt(gap)
        e, c, s = np.exp(-beta * t), np.cos(wd * t), np.sin(wd * t)
        return (e * (u0 * c + b / wd * s), e * (v0 * c - (w0 * w0 * u0 + beta * v0) / wd * s))
    g = np.sqrt(-gap)  # overdamped: e^(-beta t) cosh / sinh without overflow
    ep, em = np.exp((g - beta) * t), np.exp(-(g + beta) * t)
    ch, sh = 0.5 * (ep + em), 0.5 * (ep - em)
    return (u0 * ch + b / g * sh, v0 * ch - (w0 * w0 * u0 + beta * v0) / g * sh)


def harmonic_oscillator(scene: Scene, times: np.ndarray) -> Trajectory:
    """Bodies on anchored springs at their centres of mass (undamped and damped)."""
    name = "harmonic_oscillator"
    if scene.effects.contact or scene.fluid is not None:
        raise _refuse(name, "the scene has contact or a fluid")
    _require_no_medium(scene, name)
    t = np.asarray(times, float)
    traj = _new(scene, t, name)
    for i, body in enumerate(scene.bodies):
        springs = [s for s in scene.effects.springs if i in (s.body_a, s.body_b)]
        if len(springs) != 1 or springs[0].body_b is not None:
            raise _refuse(name, f"body {body.name!r} must hang on exactly one spring to a world "
                          "anchor")
        s = springs[0]
        if np.linalg.norm(np.asarray(s.attach_a, float) - body.com) > AT_COM_ATOL:
            raise _refuse(name, f"the spring of {body.name!r} is not attached at its centre of "
                          "mass (it would exert a torque)")
        if s.stiffness <= 0:
            raise _refuse(name, "the spring has no stiffness")
        m, k = body.mass, s.stiffness
        c_lin, _ = _drag_of(scene, i)
        f_ext = _external_force(scene, i)
        x0 = body.com_world()
        anchor = np.asarray(s.attach_b, float)
        d0, v0 = x0 - anchor, np.asarray(body.velocity, float)
        w0 = np.sqrt(k / m)
        if s.rest_length == 0.0 and s.damping == 0.0:
            # linear spring: every coordinate is an oscillator about anchor + F_ext / k
            eq = anchor + f_ext / k
            for c in range(scene.dimension):
                u, du = _damped(t, x0[c] - eq[c], v0[c], w0, c_lin / (2 * m))
                traj.com[:, i, c], traj.vel[:, i, c] = eq[c] + u, du
        else:
            dn = np.linalg.norm(d0)
            if dn == 0.0:
                raise _refuse(name, f"{body.name!r} starts on its anchor (direction undefined)")
            n = d0 / dn
            for vec, what in ((v0, "initial velocity"), (f_ext, "external force")):
                if np.linalg.norm(vec - (vec @ n) * n) > PARALLEL_RTOL * max(np.linalg.norm(vec),
                                                                             1e-300):
                    raise _refuse(name, f"the {what} of {body.name!r} leaves the line through the "
                                  "anchor (the motion is not one-dimensional)")
            s_eq = s.rest_length + float(f_ext @ n) / k
            u, du = _damped(t, dn - s_eq, float(v0 @ n), w0, (s.damping + c_lin) / (2 * m))
            dist = s_eq + u
            if s.rest_length > 0 and np.any(dist <= 0):
                raise _refuse(name, f"{body.name!r} passes through its anchor, where the spring "
                              "direction flips")
            traj.com[:, i] = anchor + dist[:, None] * n
            traj.vel[:, i] = du[:, None] * n
        _rotate(scene, i, t, traj)
    return traj


# -- torque-free rotation --------------------------------------------------------------------------
def _torque_free_checks(scene: Scene, name: str) -> None:
    if scene.dimension != 3:
        raise _refuse(name, "it is a 3D solution")
    _require_no_springs(scene, name)
    for i, body in enumerate(scene.bodies):
        _, c_ang = _drag_of(scene, i)
        _, torque = _loads_of(scene, i)
        if c_ang != 0.0 or np.any(torque != 0.0):
            raise _refuse(name, f"{body.name!r} has an angular drag or a load torque")


def torque_free_axisymmetric(scene: Scene, times: np.ndarray) -> Trajectory:
    """Steady precession of axisymmetric bodies (closed form, see the module doc)."""
    name = "torque_free_axisymmetric"
    _torque_free_checks(scene, name)
    t = np.asarray(times, float)
    traj = _new(scene, t, name)
    for i, body in enumerate(scene.bodies):
        _translate(scene, i, t, traj)
        moments, axes = np.linalg.eigh(body.inertia)
        scale = moments[-1]
        if moments[1] - moments[0] <= EQUAL_MOMENTS_RTOL * scale:
            i_perp, i_a, a_body = 0.5 * (moments[0] + moments[1]), moments[2], axes[:, 2]
        elif moments[2] - moments[1] <= EQUAL_MOMENTS_RTOL * scale:
            i_perp, i_a, a_body = 0.5 * (moments[1] + moments[2]), moments[0], axes[:, 0]
        else:
            raise _refuse(name, f"{body.name!r} has three different principal moments "
                          f"{moments.tolist()}")
        q0 = np.asarray(body.orientation, float)
        L = body.inertia_world() @ body.angular_velocity
        n0 = quat_to_matrix(q0) @ a_body
        lam = (1.0 / i_a - 1.0 / i_perp) * float(L @ n0)
        precess = rotvec_to_quat(t[:, None] * (L / i_perp))
        spin = rotvec_to_quat(t[:, None] * lam * a_body)
        q = quat_mul(quat_mul(precess, q0), spin)
        traj.quat[:, i] = q
        traj.omega[:, i] = L / i_perp + lam * (quat_to_matrix(q) @ a_body)
    return traj


def _principal(body) -> tuple[np.ndarray, np.ndarray]:
    """Ascending principal moments and right-handed principal axes (columns, body frame)."""
    moments, axes = np.linalg.eigh(np.asarray(body.inertia, float))
    if np.linalg.det(axes) < 0:
        axes[:, 2] *= -1.0
    return moments, axes


def euler_elliptic(moments: np.ndarray, w0: np.ndarray) -> dict:
    """Jacobi-elliptic solution of Euler's equations from the principal-frame w0.

    Returns the constants and ``omega(t)`` (principal frame) and ``period`` (of the motion;
    the intermediate component changes sign every period / 2).
    """
    I = np.asarray(moments, float)
    w = np.asarray(w0, float)
    if not (I[0] < I[1] < I[2]):
        raise ValueError(f"Euler's elliptic solution needs I1 < I2 < I3, got {I.tolist()}")
    two_e = float(np.sum(I * w * w))
    m2 = float(np.sum((I * w) ** 2))
    # M^2 > 2 E I2: axes as they are; otherwise suffixes 1 and 3 swap, and the middle axis flips
    # sign so the relabelled frame stays right-handed (Euler's equations keep their form).
    swap = m2 < two_e * I[1]
    perm = np.array([2, 1, 0]) if swap else np.array([0, 1, 2])
    sign = np.array([1.0, -1.0, 1.0]) if swap else np.ones(3)
    J = I[perm]
    W = w[perm] * sign
    a1 = np.sqrt(max((two_e * J[2] - m2) / (J[0] * (J[2] - J[0])), 0.0))
    a2 = np.sqrt(max((two_e * J[2] - m2) / (J[1] * (J[2] - J[1])), 0.0))
    a3 = np.sqrt(max((m2 - two_e * J[0]) / (J[2] * (J[2] - J[0])), 0.0))
    rate = np.sqrt((J[2] - J[1]) * (m2 - two_e * J[0]) / (J[0] * J[1] * J[2]))
    m = (J[1] - J[0]) * (two_e * J[2] - m2) / ((J[2] - J[1]) * (m2 - two_e * J[0]))
    # W3 = s3 A3 dn never changes sign; Euler's first equation then fixes the sign of W2 = sigma
    # A2 sn: -J1 A1 rate = (J2 - J3) sigma s3 A2 A3, so sigma = s3 sign(J3 - J2).
    s3 = 1.0 if W[2] >= 0 else -1.0
    sigma = s3 if J[2] > J[1] else -s3
    # initial phase: cn(u0) = W1 / A1, sn(u0) = sigma W2 / A2 -> amplitude, then F(amplitude | m)
    amp = np.arctan2(sigma * W[1] / a2 if a2 > 0 else 0.0, W[0] / a1 if a1 > 0 else 1.0)
    u0 = float(special.ellipkinc(amp, m))
    k_full = float(special.ellipk(m))

    def omega(t: np.ndarray) -> np.ndarray:
        sn, cn, dn, _ = special.ellipj(rate * np.asarray(t, float) + u0, m)
        out_j = np.stack([a1 * cn, sigma * a2 * sn, s3 * a3 * dn], axis=-1) * sign
        out = np.empty_like(out_j)
        out[..., perm] = out_j
        return out

    return {"two_energy": two_e, "momentum_sq": m2, "modulus": m, "rate": rate, "u0": u0,
            "quarter_period": k_full, "period": 4.0 * k_full / rate, "omega": omega,
            "swapped": bool(swap)}


def _intermediate_solution(body) -> tuple[dict, np.ndarray]:
    moments, axes = _principal(body)
    w_body = quat_to_matrix(body.orientation).T @ np.asarray(body.angular_velocity, float)
    return euler_elliptic(moments, axes.T @ w_body), axes


def torque_free_intermediate(scene: Scene, times: np.ndarray) -> Trajectory:
    """Body angular velocity of an asymmetric free rotor (Jacobi elliptic functions)."""
    name = "torque_free_intermediate"
    _torque_free_checks(scene, name)
    t = np.asarray(times, float)
    traj = _new(scene, t, name)
    omega_body = np.full((len(t), len(scene.bodies), 3), np.nan)
    periods = []
    for i, body in enumerate(scene.bodies):
        _translate(scene, i, t, traj)
        try:
            sol, axes = _intermediate_solution(body)
        except ValueError as exc:
            raise _refuse(name, f"{body.name!r}: {exc}") from None
        omega_body[:, i] = sol["omega"](t) @ axes.T  # principal -> declared body axes
        periods.append(sol["period"])
    traj.extras["omega_body"] = omega_body
    traj.meta["flip_period"] = periods
    return traj


def torque_free(scene: Scene, times: np.ndarray) -> Trajectory:
    """Dispatch: axisymmetric bodies get the closed form, asymmetric ones the elliptic one."""
    try:
        return torque_free_axisymmetric(scene, times)
    except ValueError:
        return torque_free_intermediate(scene, times)


# -- extra metrics ---------------------------------------------------------------------------------
# The crossings of a flipping body are evenly spaced (one every half period). When consecutive
# half periods differ by more than this fraction of their mean, the run's motion changed during
# the run (an integrator's energy drift moved it to another polhode, e.g. from flipping to
# wobbling about the minor axis) and it has no period to measure.
PERIODIC_RTOL = 0.05


def flip_measurement(scene: Scene, traj: Trajectory, body: int = 0) -> dict:
    """The flip period of a run, how finely it is resolved, or why it cannot be measured.

    The flips are the sign changes of the body-frame angular velocity along the intermediate
    principal axis; each is located by linear interpolation between samples, and the period is
    twice the least-squares slope of crossing time against crossing number. Returns
    ``{"period": s or None, "resolution": s or None, "reason": ""}``:

    * ``resolution``: the interpolation error of the measured period, estimated as the
      difference from the same fit over crossings located by the cubic through the four samples
      around each crossing (the linear error is of order dt_sample^2 times the rate's third
      derivative over its first); with 0.01 s samples on the tennis racket it is 2.3e-7 s (3.0e-8
      of the period), the floor under which no integrator's period error can be seen;
    * ``period = None`` and ``reason`` when there is nothing to measure: fewer than two crossings
      ("no flip found"), or half periods that vary by more than :data:`PERIODIC_RTOL` ("crossings
      not periodic").
    """
    _, axes = _principal(scene.bodies[body])
    r = quat_to_matrix(traj.quat[:, body])  # (T, 3, 3)
    w_body = np.einsum("tji,tj->ti", r, traj.omega[:, body])
    w_mid = w_body @ axes[:, 1]
    t = traj.t
    idx = np.flatnonzero(np.sign(w_mid[:-1]) * np.sign(w_mid[1:]) < 0)
    if len(idx) < 2:
        span = float(t[-1] - t[0]) if len(t) else 0.0
        return {"period": None, "resolution": None,
                "reason": f"no flip found ({len(idx)} sign change of the intermediate-axis rate "
                          f"in {span:.4g} s)"}
    frac = w_mid[idx] / (w_mid[idx] - w_mid[idx + 1])
    crossings = t[idx] + frac * (t[idx + 1] - t[idx])
    half = np.diff(crossings)
    spread = float((half.max() - half.min()) / half.mean())
    if spread > PERIODIC_RTOL:
        return {"period": None, "resolution": None,
                "reason": f"crossings not periodic ({len(idx)} sign changes, half periods "
                          f"{half.min():.3g} to {half.max():.3g} s: the motion changed during "
                          "the run)"}
    j = np.arange(len(crossings))
    period = float(2.0 * np.polyfit(j, crossings, 1)[0])
    cubic = np.array([_cubic_root(t, w_mid, i, c) for i, c in zip(idx, crossings, strict=True)])
    resolution = abs(float(2.0 * np.polyfit(j, cubic, 1)[0]) - period)
    # Round-off of the crossing times themselves (a few ulps of t) bounds it from below.
    resolution = max(resolution, 8 * float(np.finfo(float).eps) * float(t[-1]))
    return {"period": period, "resolution": resolution, "reason": ""}


def _cubic_root(t: np.ndarray, w: np.ndarray, i: int, linear: float) -> float:
    """The root in [t_i, t_i+1] of the cubic through the samples i-1 .. i+2 (the linear root
    where there are not four samples or the cubic has no root there)."""
    lo, hi = i - 1, i + 3
    if lo < 0 or hi > len(t):
        return linear
    tt = t[lo:hi] - t[i]
    roots = np.roots(np.polyfit(tt, w[lo:hi], 3))
    h = t[i + 1] - t[i]
    real = [float(z.real) for z in roots
            if abs(z.imag) <= 1e-9 * h and -1e-9 * h <= z.real <= h * (1 + 1e-9)]
    if not real:
        return linear
    return float(t[i] + min(real, key=lambda z: abs(t[i] + z - linear)))


def measured_flip_period(scene: Scene, traj: Trajectory, body: int = 0) -> float:
    """Flip period of a run (see :func:`flip_measurement`); NaN when it cannot be measured."""
    period = flip_measurement(scene, traj, body)["period"]
    return float("nan") if period is None else period


def flip_period(scene: Scene, traj: Trajectory) -> dict:
    """{"flip_period_error": |T_measured - T_elliptic| / T_elliptic} (worst body), its
    resolution ``flip_period_resolution`` (the measurement's interpolation error relative to
    T_elliptic, worst body: the sweep treats errors near it as at the metric's floor), and the
    measured and analytic periods of the first body for the report.

    When a body's period cannot be measured (:func:`flip_measurement`), the error is
    ``(None, reason)``: not measured, with the reason, never a number (a metric with a tolerance
    that was not measured fails the cell).
    """
    errors, resolutions, measured, exact, reasons = [], [], [], [], []
    for i, body in enumerate(scene.bodies):
        sol, _ = _intermediate_solution(body)
        m = flip_measurement(scene, traj, i)
        exact.append(float(sol["period"]))
        measured.append(m["period"])
        if m["period"] is None:
            who = f"{body.name!r}: " if len(scene.bodies) > 1 else ""
            reasons.append(who + m["reason"])
            continue
        errors.append(abs(m["period"] - sol["period"]) / sol["period"])
        resolutions.append(m["resolution"] / sol["period"])
    out: dict = {}
    if reasons:
        out["flip_period_error"] = (None, "; ".join(reasons))
    else:
        out["flip_period_error"] = float(max(errors))
        out["flip_period_resolution"] = float(max(resolutions))
    out["flip_period_measured"] = (measured[0] if measured[0] is not None
                                   else (None, reasons[0]))
    out["flip_period_analytic"] = exact[0]
    return out


SOLUTIONS: dict[str, Callable[[Scene, np.ndarray], Trajectory]] = {
    "free_fall": projectile,
    "projectile": projectile,
    "harmonic_oscillator": harmonic_oscillator,
    "torque_free_axisymmetric": torque_free_axisymmetric,
    "torque_free_intermediate": torque_free_intermediate,
    "torque_free": torque_free,
}

EXTRA_METRICS: dict[str, Callable[[Scene, Trajectory], dict]] = {
    "torque_free_intermediate": flip_period,
    "flip_period": flip_period,
}


# -- contact solutions (their own module; registered here so that every lookup sees them) -------
from crosscheck.reference import contact_analytic as _contact  # noqa: E402

SOLUTIONS.update(_contact.SOLUTIONS)
EXTRA_METRICS.update(_contact.EXTRA_METRICS)

# -- a sphere in a quiescent medium (its own module, registered here the same way) --------------
from crosscheck.reference import medium_analytic as _medium  # noqa: E402

SOLUTIONS.update(_medium.SOLUTIONS)
EXTRA_METRICS.update(_medium.EXTRA_METRICS)
