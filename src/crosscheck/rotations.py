"""Quaternion and rotation helpers, vectorised over leading axes.

Quaternions are (w, x, y, z) and rotate body-frame vectors into the world frame. Every engine
adapter converts its own convention into this one through these functions, so there is a single
place where the order of components is decided.
"""

from __future__ import annotations

import numpy as np


def quat_normalize(q: np.ndarray) -> np.ndarray:
    q = np.asarray(q, dtype=float)
    return q / np.linalg.norm(q, axis=-1, keepdims=True)


def quat_mul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Hamilton product a * b (apply b first, then a)."""
    aw, ax, ay, az = np.moveaxis(np.asarray(a, float), -1, 0)
    bw, bx, by, bz = np.moveaxis(np.asarray(b, float), -1, 0)
    return np.stack([
        aw * bw - ax * bx - ay * by - az * bz,
        aw * bx + ax * bw + ay * bz - az * by,
        aw * by - ax * bz + ay * bw + az * bx,
        aw * bz + ax * by - ay * bx + az * bw,
    ], axis=-1)


def quat_conj(q: np.ndarray) -> np.ndarray:
    q = np.asarray(q, float)
    return q * np.array([1.0, -1.0, -1.0, -1.0])


def quat_to_matrix(q: np.ndarray) -> np.ndarray:
    q = quat_normalize(q)
    w, x, y, z = np.moveaxis(q, -1, 0)
    m = np.stack([
        1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y),
        2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x),
        2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y),
    ], axis=-1)
    return m.reshape(q.shape[:-1] + (3, 3))


def matrix_to_quat(m: np.ndarray) -> np.ndarray:
    """Rotation matrix to unit quaternion with w >= 0 (Shepperd's method, branch per element)."""
    m = np.asarray(m, float)
    flat = m.reshape(-1, 3, 3)
    out = np.empty((flat.shape[0], 4))
    for i, r in enumerate(flat):
        # Branch on the largest of w, x, y, z to avoid dividing by a small number.
        tr = r[0, 0] + r[1, 1] + r[2, 2]
        if tr > 0:
            s = 2.0 * np.sqrt(tr + 1.0)
            q = [0.25 * s, (r[2, 1] - r[1, 2]) / s, (r[0, 2] - r[2, 0]) / s,
                 (r[1, 0] - r[0, 1]) / s]
        elif r[0, 0] > r[1, 1] and r[0, 0] > r[2, 2]:
            s = 2.0 * np.sqrt(1.0 + r[0, 0] - r[1, 1] - r[2, 2])
            q = [(r[2, 1] - r[1, 2]) / s, 0.25 * s, (r[0, 1] + r[1, 0]) / s,
                 (r[0, 2] + r[2, 0]) / s]
        elif r[1, 1] > r[2, 2]:
            s = 2.0 * np.sqrt(1.0 + r[1, 1] - r[0, 0] - r[2, 2])
            q = [(r[0, 2] - r[2, 0]) / s, (r[0, 1] + r[1, 0]) / s, 0.25 * s,
                 (r[1, 2] + r[2, 1]) / s]
        else:
            s = 2.0 * np.sqrt(1.0 + r[2, 2] - r[0, 0] - r[1, 1])
            q = [(r[1, 0] - r[0, 1]) / s, (r[0, 2] + r[2, 0]) / s, (r[1, 2] + r[2, 1]) / s,
                 0.25 * s]
        q = np.array(q)
        out[i] = q if q[0] >= 0 else -q
    out /= np.linalg.norm(out, axis=1, keepdims=True)
    return out.reshape(m.shape[:-2] + (4,))


def axis_angle_to_quat(axis: np.ndarray, angle: float | np.ndarray) -> np.ndarray:
    axis = np.asarray(axis, float)
    axis = axis / np.linalg.norm(axis, axis=-1, keepdims=True)
    half = 0.5 * np.asarray(angle, float)[..., None]
    return np.concatenate([np.cos(half), np.sin(half) * axis], axis=-1)


def rotvec_to_quat(v: np.ndarray) -> np.ndarray:
    """Exponential map: rotation vector (axis times angle) to unit quaternion, safe near zero."""
    v = np.asarray(v, float)
    theta = np.linalg.norm(v, axis=-1, keepdims=True)
    half = 0.5 * theta
    # sin(theta/2)/theta -> 1/2 - theta^2/48 for small theta; avoids 0/0.
    small = theta < 1e-8
    k = np.where(small, 0.5 - theta**2 / 48.0, np.sin(half) / np.where(small, 1.0, theta))
    return np.concatenate([np.cos(half), k * v], axis=-1)


def quat_rotate(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Rotate vectors v (..., 3) by quaternions q (..., 4)."""
    return np.einsum("...ij,...j->...i", quat_to_matrix(q), np.asarray(v, float))


def quat_angle_between(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Geodesic angle (radians, in [0, pi]) of the rotation taking a to b; sign-blind (q ~ -q)."""
    a = quat_normalize(a)
    b = quat_normalize(b)
    d = np.abs(np.sum(a * b, axis=-1))
    # 2*acos(d) loses precision near d = 1; the atan2 form keeps it to round-off.
    rel = quat_mul(quat_conj(a), b)
    vec = np.linalg.norm(rel[..., 1:], axis=-1)
    return 2.0 * np.arctan2(vec, np.abs(rel[..., 0])) * (d >= 0)


def sign_continuous(q: np.ndarray) -> np.ndarray:
    """Flip signs along axis 0 (time) so consecutive quaternions have a non-negative dot product."""
    q = np.array(q, float, copy=True)
    if q.shape[0] < 2:
        return q
    # Vectorised (a per-sample Python loop cost more than stepping a cheap engine between
    # samples). Sample i is flipped iff its raw dot with sample i-1, times the sign given to i-1,
    # is negative: so its sign is the parity of the negative raw dots since the last zero (or NaN)
    # dot, where the sequential rule restarts at +1.
    dots = np.sum(q[1:] * q[:-1], axis=-1)
    negative = dots < 0
    if not negative.any():  # the usual case: nothing to flip (zero and NaN dots restart at +1)
        return q
    if (negative | (dots > 0)).all():  # no restart after t = 0: the parity of the flips so far
        flip = np.cumsum(negative, axis=0) % 2 == 1
        q[1:][flip] *= -1.0
        return q
    neg = np.concatenate([np.zeros_like(dots[:1], dtype=int), (dots < 0).astype(int)])
    restart = np.concatenate([np.ones_like(dots[:1], dtype=bool), ~((dots < 0) | (dots > 0))])
    count = np.cumsum(neg, axis=0)
    t = np.arange(q.shape[0]).reshape((-1,) + (1,) * (dots.ndim - 1))
    last = np.maximum.accumulate(np.where(restart, t, 0), axis=0)
    q[(count - np.take_along_axis(count, last, axis=0)) % 2 == 1] *= -1.0
    return q


def angle_to_matrix(theta: float) -> np.ndarray:
    c, s = np.cos(theta), np.sin(theta)
    return np.array([[c, -s], [s, c]])
