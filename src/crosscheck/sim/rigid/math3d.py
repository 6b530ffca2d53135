"""3D math of the in-house kernels: quaternions, rotation matrices, the exponential map, the
quaternion rate, small matrix helpers. Scalars in, tuples out (no allocation); numba, cached,
inlined into the kernels that call them (see _jit.py)."""

from __future__ import annotations

import numpy as np
from numba import njit

from crosscheck.sim._jit import INLINE, JIT


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


@njit(**INLINE)
def skew(r0, r1, r2, out, o_r, o_c):
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


@njit(**INLINE)
def solve3(A, b0, b1, b2):
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

