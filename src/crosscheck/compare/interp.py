"""Resampling a reference trajectory at a run's sample times.

A reference sampled at other times than the run (a fine-step run whose sampling interval rounds
differently, a published table) is interpolated between its two bracketing samples ``t0 <= t <=
t1``, ``h = t1 - t0``, ``s = (t - t0) / h``:

* centre-of-mass positions: cubic Hermite, ``x = h00 x0 + h10 h v0 + h01 x1 + h11 h v1`` with
  ``h00 = 2s^3 - 3s^2 + 1, h10 = s^3 - 2s^2 + s, h01 = -2s^3 + 3s^2, h11 = s^3 - s^2``, using the
  reference's own centre-of-mass velocities as the end slopes (central finite differences of the
  positions where the reference gives no velocity); error O(h^4);
* 3D orientations: spherical linear interpolation (slerp) of the sign-aligned quaternions;
* 2D angles: cubic Hermite with the angular velocity as slope, like positions;
* linear and angular velocities: linear interpolation.

At a sample time (``s = 0``) every formula returns the sample itself. Times outside the
reference's span are NaN, and metrics skip NaN samples.
"""

from __future__ import annotations

import numpy as np

from crosscheck.state import Trajectory


def _bracket(src: np.ndarray, times: np.ndarray, rtol: float = 1e-9):
    """Left index, fraction s and validity for each target time."""
    src = np.asarray(src, float)
    times = np.asarray(times, float)
    n = len(src)
    span = max(abs(src[-1]), 1.0) if n else 1.0
    tol = rtol * span
    valid = (times >= src[0] - tol) & (times <= src[-1] + tol) if n else np.zeros(len(times), bool)
    if n < 2:
        idx = np.zeros(len(times), int)
        s = np.zeros(len(times))
        valid &= np.abs(times - (src[0] if n else 0.0)) <= tol
        return idx, s, valid
    idx = np.clip(np.searchsorted(src, times, side="right") - 1, 0, n - 2)
    h = src[idx + 1] - src[idx]
    s = np.clip((times - src[idx]) / h, 0.0, 1.0)
    return idx, s, valid


def _slopes(values: np.ndarray, t: np.ndarray, given: np.ndarray | None) -> np.ndarray:
    if given is not None and np.all(np.isfinite(given)):
        return given
    if len(t) < 2:
        return np.zeros_like(values)
    return np.gradient(values, t, axis=0)


def hermite(t_src: np.ndarray, values: np.ndarray, slopes: np.ndarray | None,
            times: np.ndarray) -> np.ndarray:
    """Cubic Hermite interpolation along axis 0 (see the module docstring)."""
    idx, s, valid = _bracket(t_src, times)
    values = np.asarray(values, float)
    if len(t_src) < 2:
        out = np.repeat(values[:1], len(times), axis=0)
        out[~valid] = np.nan
        return out
    d = _slopes(values, np.asarray(t_src, float), slopes)
    h = (np.asarray(t_src)[idx + 1] - np.asarray(t_src)[idx])
    shape = (-1,) + (1,) * (values.ndim - 1)
    s_ = s.reshape(shape)
    h_ = h.reshape(shape)
    h00 = 2 * s_**3 - 3 * s_**2 + 1
    h10 = s_**3 - 2 * s_**2 + s_
    h01 = -2 * s_**3 + 3 * s_**2
    h11 = s_**3 - s_**2
    out = h00 * values[idx] + h10 * h_ * d[idx] + h01 * values[idx + 1] + h11 * h_ * d[idx + 1]
    out[~valid] = np.nan
    return out


def linear(t_src: np.ndarray, values: np.ndarray, times: np.ndarray) -> np.ndarray:
    idx, s, valid = _bracket(t_src, times)
    values = np.asarray(values, float)
    if len(t_src) < 2:
        out = np.repeat(values[:1], len(times), axis=0)
    else:
        s_ = s.reshape((-1,) + (1,) * (values.ndim - 1))
        out = (1 - s_) * values[idx] + s_ * values[idx + 1]
    out[~valid] = np.nan
    return out


def slerp(t_src: np.ndarray, quats: np.ndarray, times: np.ndarray) -> np.ndarray:
    """Slerp of (T, N, 4) quaternions at the target times (shortest arc, sign-blind)."""
    idx, s, valid = _bracket(t_src, times)
    q = np.asarray(quats, float)
    if len(t_src) < 2:
        out = np.repeat(q[:1], len(times), axis=0)
        out[~valid] = np.nan
        return out
    q0 = q[idx]
    q1 = q[idx + 1].copy()
    dot = np.sum(q0 * q1, axis=-1)
    q1[dot < 0] *= -1.0
    dot = np.clip(np.abs(dot), -1.0, 1.0)
    theta = np.arccos(dot)
    s_ = s[:, None]
    small = theta < 1e-8
    sin_t = np.where(small, 1.0, np.sin(theta))
    w0 = np.where(small, 1.0 - s_, np.sin((1.0 - s_) * theta) / sin_t)
    w1 = np.where(small, s_, np.sin(s_ * theta) / sin_t)
    out = w0[..., None] * q0 + w1[..., None] * q1
    out /= np.linalg.norm(out, axis=-1, keepdims=True)
    out[~valid] = np.nan
    return out


def same_times(a: np.ndarray, b: np.ndarray, rtol: float = 1e-9) -> bool:
    a = np.asarray(a, float)
    b = np.asarray(b, float)
    if a.shape != b.shape:
        return False
    span = max(float(np.max(np.abs(a))) if len(a) else 1.0, 1.0)
    return bool(np.all(np.abs(a - b) <= rtol * span))


def resample(ref: Trajectory, times: np.ndarray) -> Trajectory:
    """The reference at ``times`` (the module docstring gives the interpolation of each part)."""
    times = np.asarray(times, float)
    if same_times(ref.t, times):
        return ref
    t = np.asarray(ref.t, float)
    com = hermite(t, ref.com, ref.vel, times)
    vel = linear(t, ref.vel, times)
    omega = linear(t, ref.omega, times)
    quat = angle = None
    if ref.quat is not None:
        quat = slerp(t, ref.quat, times)
    if ref.angle is not None:
        angle = hermite(t, ref.angle, ref.omega, times)
    return Trajectory(t=times.copy(), com=com, vel=vel, omega=omega, quat=quat, angle=angle,
                      meta=dict(ref.meta, resampled_from=len(t)))
