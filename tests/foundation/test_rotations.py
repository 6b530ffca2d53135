"""Quaternion helpers (w, x, y, z), checked against SciPy's independent implementation and against
exact values: matrix round trips through every branch of Shepperd's method, the Hamilton product
against the matrix product, the exponential map near zero, and the geodesic angle near 0 and pi.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from crosscheck.rotations import (
    angle_to_matrix,
    axis_angle_to_quat,
    matrix_to_quat,
    quat_angle_between,
    quat_conj,
    quat_mul,
    quat_normalize,
    quat_rotate,
    quat_to_matrix,
    rotvec_to_quat,
    sign_continuous,
)

RNG = np.random.default_rng(20240611)


def random_quats(n: int) -> np.ndarray:
    q = RNG.normal(size=(n, 4))
    return q / np.linalg.norm(q, axis=1, keepdims=True)


def scipy_matrix(q: np.ndarray) -> np.ndarray:
    """SciPy stores quaternions scalar-last (x, y, z, w)."""
    return Rotation.from_quat(np.asarray(q)[..., [1, 2, 3, 0]]).as_matrix()


def same_rotation(q: np.ndarray, p: np.ndarray, atol: float = 1e-14) -> bool:
    """q and -q are the same rotation."""
    return bool(np.all(np.minimum(np.abs(q - p).max(-1), np.abs(q + p).max(-1)) <= atol))


def test_quat_to_matrix_matches_scipy_and_rotates_body_into_world():
    q = random_quats(200)
    np.testing.assert_allclose(quat_to_matrix(q), scipy_matrix(q), rtol=0, atol=2e-15)
    # +90 degrees about z takes the body x axis to the world y axis
    qz = np.array([math.cos(math.pi / 4), 0.0, 0.0, math.sin(math.pi / 4)])
    np.testing.assert_allclose(quat_to_matrix(qz) @ [1.0, 0.0, 0.0], [0.0, 1.0, 0.0],
                               atol=1e-15)
    np.testing.assert_allclose(quat_rotate(qz, [1.0, 0.0, 0.0]), [0.0, 1.0, 0.0], atol=1e-15)
    # leading axes are vectorised: (5, 7, 4) -> (5, 7, 3, 3)
    assert quat_to_matrix(random_quats(35).reshape(5, 7, 4)).shape == (5, 7, 3, 3)


def test_quat_to_matrix_is_orthonormal_even_for_non_unit_input():
    q = random_quats(50) * RNG.uniform(0.5, 2.0, size=(50, 1))
    r = quat_to_matrix(q)
    np.testing.assert_allclose(np.einsum("nij,nkj->nik", r, r), np.broadcast_to(np.eye(3), r.shape),
                               atol=1e-14)
    np.testing.assert_allclose(np.linalg.det(r), 1.0, atol=1e-14)


def _near_pi_rotations() -> np.ndarray:
    """Rotations with trace near -1 (angle near pi): every non-trace branch of Shepperd."""
    out = []
    for axis in ([1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 1, 0], [0, 1, 1], [1, 0, 1], [1, 2, 3]):
        for angle in (math.pi, math.pi - 1e-9, math.pi - 1e-3, 3.0):
            out.append(axis_angle_to_quat(np.array(axis, float), angle))
    return np.array(out)


@pytest.mark.parametrize("quats", [random_quats(300), _near_pi_rotations(),
                                   np.array([[1.0, 0, 0, 0], [0, 1.0, 0, 0], [0, 0, 1.0, 0],
                                             [0, 0, 0, 1.0]])],
                         ids=["random", "near-pi", "axes"])
def test_matrix_quat_round_trip_through_every_branch(quats):
    m = quat_to_matrix(quats)
    back = matrix_to_quat(m)
    assert np.all(back[:, 0] >= 0)  # the convention of matrix_to_quat
    np.testing.assert_allclose(np.linalg.norm(back, axis=1), 1.0, atol=1e-15)
    assert same_rotation(back, quats, atol=2e-15 * 10)
    np.testing.assert_allclose(quat_to_matrix(back), m, rtol=0, atol=1e-14)
    # and against SciPy's matrix -> quaternion
    ref = Rotation.from_matrix(m).as_quat()[:, [3, 0, 1, 2]]
    assert same_rotation(back, ref, atol=1e-14)


def test_matrix_to_quat_keeps_leading_axes():
    q = random_quats(6).reshape(2, 3, 4)
    assert matrix_to_quat(quat_to_matrix(q)).shape == (2, 3, 4)


def test_hamilton_product_composes_like_matrices():
    a, b = random_quats(100), random_quats(100)
    # R(a * b) = R(a) R(b): apply b first, then a
    np.testing.assert_allclose(quat_to_matrix(quat_mul(a, b)),
                               quat_to_matrix(a) @ quat_to_matrix(b), atol=1e-14)
    # against SciPy's composition (Rotation(a) * Rotation(b) applies b first as well)
    ref = (Rotation.from_quat(a[:, [1, 2, 3, 0]]) * Rotation.from_quat(b[:, [1, 2, 3, 0]]))
    assert same_rotation(quat_mul(a, b), ref.as_quat()[:, [3, 0, 1, 2]], atol=1e-14)
    # not commutative; identity and inverse
    assert not np.allclose(quat_mul(a, b), quat_mul(b, a))
    ident = np.array([1.0, 0.0, 0.0, 0.0])
    np.testing.assert_allclose(quat_mul(a, quat_conj(a)), np.broadcast_to(ident, a.shape),
                               atol=1e-15)
    np.testing.assert_array_equal(quat_mul(ident, a), a)
    # i j = k, the Hamilton (not JPL) convention
    i, j, k = np.eye(4)[1], np.eye(4)[2], np.eye(4)[3]
    np.testing.assert_array_equal(quat_mul(i, j), k)


def test_quat_rotate_equals_conjugation():
    q, v = random_quats(50), RNG.normal(size=(50, 3))
    pure = np.concatenate([np.zeros((50, 1)), v], axis=1)
    conj = quat_mul(quat_mul(q, pure), quat_conj(q))
    np.testing.assert_allclose(quat_rotate(q, v), conj[:, 1:], atol=1e-14)
    np.testing.assert_allclose(conj[:, 0], 0.0, atol=1e-15)


def test_axis_angle_matches_scipy_rotvec():
    axis = RNG.normal(size=(100, 3)) * 3.0  # not unit: the function normalises
    angle = RNG.uniform(-2 * math.pi, 2 * math.pi, size=100)
    q = axis_angle_to_quat(axis, angle)
    unit = axis / np.linalg.norm(axis, axis=1, keepdims=True)
    ref = Rotation.from_rotvec(unit * angle[:, None]).as_quat()[:, [3, 0, 1, 2]]
    assert same_rotation(q, ref, atol=1e-14)
    np.testing.assert_allclose(q[:, 0], np.cos(angle / 2), atol=1e-15)  # exactly half-angle


def test_rotvec_to_quat_matches_scipy_at_ordinary_angles():
    v = RNG.normal(size=(100, 3))
    ref = Rotation.from_rotvec(v).as_quat()[:, [3, 0, 1, 2]]
    assert same_rotation(rotvec_to_quat(v), ref, atol=1e-15 * 4)


@pytest.mark.parametrize("theta", [0.0, 1e-300, 1e-15, 1e-10, 9.99e-9, 1e-8, 1.01e-8, 1e-6,
                                   1e-4, 1e-3])
def test_rotvec_small_angle_is_accurate_to_round_off(theta):
    # Taylor series to theta^4 are exact to ~theta^6/46080 < 1e-22 relative here.
    axis = np.array([2.0, -3.0, 6.0]) / 7.0
    q = rotvec_to_quat(axis * theta)
    w = 1 - theta**2 / 8 + theta**4 / 384
    k = 0.5 - theta**2 / 48 + theta**4 / 3840  # sin(theta/2) / theta
    assert np.all(np.isfinite(q))
    assert abs(q[0] - w) <= 2.3e-16
    np.testing.assert_allclose(q[1:], k * theta * axis, rtol=4e-16, atol=0)
    assert abs(np.linalg.norm(q) - 1.0) <= 3e-16


def test_quat_normalize():
    q = RNG.normal(size=(10, 4)) * 5
    n = quat_normalize(q)
    np.testing.assert_allclose(np.linalg.norm(n, axis=1), 1.0, atol=1e-15)
    np.testing.assert_allclose(n * np.linalg.norm(q, axis=1, keepdims=True), q, rtol=1e-15)


GEODESIC_ANGLES = [1e-12, 1e-9, 1e-6, 1e-3, 0.5, 2.0, math.pi - 1e-3, math.pi - 1e-7,
                   math.pi - 1e-10]


@pytest.mark.parametrize("theta", GEODESIC_ANGLES)
def test_geodesic_angle_from_identity_is_exact_to_round_off(theta):
    axis = RNG.normal(size=(20, 3))
    rel = axis_angle_to_quat(axis, np.full(20, theta))
    got = quat_angle_between(np.array([1.0, 0.0, 0.0, 0.0]), rel)
    # 2 acos(|w|) would give 0 at theta = 1e-9 (cos(theta/2) rounds to 1): the atan2 form keeps
    # the relative error at round-off near 0 and the absolute error at round-off near pi.
    if theta < 1:
        np.testing.assert_allclose(got, theta, rtol=4e-16 * 4, atol=0)
    else:
        np.testing.assert_allclose(got, theta, rtol=0, atol=4e-16 * 4)


@pytest.mark.parametrize("theta", GEODESIC_ANGLES)
def test_geodesic_angle_between_arbitrary_orientations(theta):
    base = random_quats(20)
    rel = axis_angle_to_quat(RNG.normal(size=(20, 3)), np.full(20, theta))
    other = quat_mul(base, rel)
    got = quat_angle_between(base, other)
    # rounding `other` costs ~1e-16 absolute; the acos form would be off by ~1e-8 here
    np.testing.assert_allclose(got, theta, rtol=0, atol=1e-15)
    # sign-blind and symmetric
    np.testing.assert_allclose(quat_angle_between(base, -other), got, rtol=0, atol=1e-15)
    np.testing.assert_allclose(quat_angle_between(other, base), got, rtol=0, atol=1e-15)


def test_geodesic_angle_is_in_zero_pi():
    q = random_quats(1)[0]
    assert quat_angle_between(q, q) <= 1e-16  # round-off of conj(q) * q
    assert quat_angle_between(q, -q) <= 1e-16
    assert quat_angle_between([0.0, 0.6, 0.8, 0.0], [0.0, 0.6, 0.8, 0.0]) == 0.0
    z = np.array([0.0, 0.0, 1.0])
    assert quat_angle_between([1.0, 0, 0, 0], axis_angle_to_quat(z, math.pi)) == math.pi
    # a rotation by pi + d is the rotation by pi - d the other way
    d = 1e-6
    got = quat_angle_between([1.0, 0, 0, 0], axis_angle_to_quat(z, math.pi + d))
    assert got == pytest.approx(math.pi - d, abs=1e-15)


def test_sign_continuous_flips_each_body_independently():
    t = np.linspace(0, 4 * math.pi, 101)  # passes 2 pi, where the quaternion changes sign
    q = np.stack([axis_angle_to_quat(np.array([0.0, 0.0, 1.0]), t),
                  axis_angle_to_quat(np.array([1.0, 1.0, 0.0]), -0.7 * t)], axis=1)  # (T, 2, 4)
    flips = RNG.choice([-1.0, 1.0], size=(101, 2, 1))
    flips[0] = 1.0
    flipped = q * flips
    given = flipped.copy()
    out = sign_continuous(flipped)
    np.testing.assert_array_equal(out, q)  # the smooth original is recovered exactly
    assert np.all(np.sum(out[1:] * out[:-1], axis=-1) > 0)
    np.testing.assert_array_equal(flipped, given)  # the input is not modified


def _sign_continuous_sequential(q):
    """The rule itself, one sample at a time: flip i when its dot with the (already signed)
    sample i-1 is negative."""
    out = np.array(q, float, copy=True)
    for i in range(1, len(out)):
        d = np.sum(out[i] * out[i - 1], axis=-1)
        out[i][d < 0] *= -1.0
    return out


@pytest.mark.parametrize("restarts", [False, True], ids=["flips-only", "zero-and-nan-dots"])
def test_sign_continuous_equals_the_sequential_rule(restarts):
    q = RNG.normal(size=(300, 3, 4))
    if restarts:  # a zero dot (orthogonal neighbours) and a NaN sample restart the rule at +1
        q[50, 0] = [0.0, 0.0, 0.0, 0.0]
        q[120, 1] = [q[119, 1, 1], -q[119, 1, 0], q[119, 1, 3], -q[119, 1, 2]]
        q[200, 2] = np.nan
    expected = _sign_continuous_sequential(q)
    np.testing.assert_array_equal(sign_continuous(q), expected)


def test_angle_to_matrix():
    np.testing.assert_allclose(angle_to_matrix(math.pi / 2) @ [1.0, 0.0], [0.0, 1.0], atol=1e-16)
    r = angle_to_matrix(0.3)
    np.testing.assert_allclose(r, Rotation.from_euler("z", 0.3).as_matrix()[:2, :2], atol=1e-16)
