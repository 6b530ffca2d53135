"""Energies and momenta computed from a Trajectory and its Scene.

Two independent checks:

* every rigid body is replaced by a rigid cluster of six point masses with the same mass, centre
  of mass and inertia tensor (rotated, non-diagonal); kinetic energy and angular momentum are
  then plain sums of 1/2 m v^2 and m x x v over points, with rotations from SciPy -- no inertia
  tensor, no shared code;
* exact motions (projectile, harmonic oscillator, constant force and torque) must conserve the
  total energy to round-off, which pins the sign and zero of every potential.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from crosscheck import quantities as qty
from crosscheck.rotations import axis_angle_to_quat
from crosscheck.scene.loader import load_case_text
from crosscheck.state import Trajectory

RNG = np.random.default_rng(11)

SCENE_3D = load_case_text("""
[case]
name = "q3"
dimension = 3
[run]
duration = 1.0
dt = 0.01
[effects]
gravity = [0.3, -0.2, -9.81]
[[effects.springs]]
a = "A"
attach_a = [0.1, 0.2, -0.05]
b = "B"
attach_b = [0.0, -0.1, 0.1]
stiffness = 40.0
rest_length = 0.3
[[effects.springs]]
a = "B"
attach_a = [0.05, 0.0, 0.0]
anchor = [1.0, 2.0, 3.0]
stiffness = 7.0
rest_length = 0.0
[[effects.loads]]
body = "A"
force = [1.0, -2.0, 0.5]
torque = [0.3, 0.0, 0.0]
[[bodies]]
name = "A"
shape = { box = { size = [0.3, 0.2, 0.1] } }
mass = 3.0
com = [0.05, -0.02, 0.1]
inertia = [[0.05, 0.004, -0.006], [0.004, 0.03, 0.002], [-0.006, 0.002, 0.06]]
position = [0.0, 0.0, 0.0]
[[bodies]]
name = "B"
shape = { sphere = { radius = 0.1 } }
mass = 2.0
position = [0.0, 0.0, 0.0]
[[bodies]]
name = "C"
shape = { cylinder = { radius = 0.1, length = 0.5 } }
mass = 0.5
com = [0.0, 0.0, -0.2]
position = [0.0, 0.0, 0.0]
""")

SCENE_2D = load_case_text("""
[case]
name = "q2"
dimension = 2
[run]
duration = 1.0
dt = 0.01
[effects]
gravity = [0.5, -9.81]
[[effects.springs]]
a = "P"
attach_a = [0.1, 0.05]
b = "Q"
attach_b = [-0.1, 0.0]
stiffness = 12.0
rest_length = 0.2
[[effects.springs]]
a = "Q"
attach_a = [0.0, 0.1]
anchor = [0.5, 1.5]
stiffness = 3.0
rest_length = 0.1
[[effects.loads]]
body = "P"
force = [0.4, 1.0]
torque = 0.7
[[bodies]]
name = "P"
shape = { box = { size = [0.2, 0.1] } }
mass = 1.5
com = [0.02, -0.01]
position = [0.0, 0.0]
[[bodies]]
name = "Q"
shape = { circle = { radius = 0.1 } }
mass = 0.7
inertia = 0.01
position = [0.0, 0.0]
""")


def random_traj_3d(scene, t_count=6) -> Trajectory:
    n = len(scene.bodies)
    q = RNG.normal(size=(t_count, n, 4))
    return Trajectory(t=np.arange(t_count) * 0.1, com=RNG.normal(size=(t_count, n, 3)),
                      vel=RNG.normal(size=(t_count, n, 3)),
                      omega=RNG.normal(size=(t_count, n, 3)) * 3,
                      quat=q / np.linalg.norm(q, axis=-1, keepdims=True))


def random_traj_2d(scene, t_count=6) -> Trajectory:
    n = len(scene.bodies)
    return Trajectory(t=np.arange(t_count) * 0.1, com=RNG.normal(size=(t_count, n, 2)),
                      vel=RNG.normal(size=(t_count, n, 2)), omega=RNG.normal(size=(t_count, n)),
                      angle=RNG.uniform(-7, 7, size=(t_count, n)))


def rot3(q) -> np.ndarray:
    return Rotation.from_quat(np.asarray(q)[[1, 2, 3, 0]]).as_matrix()


def rot2(theta) -> np.ndarray:
    return Rotation.from_euler("z", theta).as_matrix()[:2, :2]


# -- point-mass clusters with the same mass properties ------------------------------------------
def cluster_3d(mass, inertia):
    """Six points +-a_k e_k on the principal axes, mass m/6 each: sum m p = 0 and
    sum m (|p|^2 E - p p^T) = inertia when m a_k^2 / 3 = (tr I)/2 - I_k."""
    moments, axes = np.linalg.eigh(inertia)
    second = 0.5 * moments.sum() - moments
    a = np.sqrt(3.0 * second / mass)
    pts = [s * a[k] * axes[:, k] for k in range(3) for s in (1.0, -1.0)]
    return np.array(pts), np.full(6, mass / 6.0)


def cluster_2d(mass, moment):
    a = math.sqrt(moment / mass)  # four points at distance a, m/4 each: J = m a^2
    return np.array([[a, 0.0], [-a, 0.0], [0.0, a], [0.0, -a]]), np.full(4, mass / 4.0)


def points_3d(scene, traj, k):
    """World positions, velocities and masses of every point of every body at sample k."""
    xs, vs, ms = [], [], []
    for i, body in enumerate(scene.bodies):
        p, m = cluster_3d(body.mass, body.inertia)
        r = (rot3(traj.quat[k, i]) @ p.T).T
        xs.append(traj.com[k, i] + r)
        vs.append(traj.vel[k, i] + np.cross(traj.omega[k, i], r))
        ms.append(m)
    return np.concatenate(xs), np.concatenate(vs), np.concatenate(ms)


def points_2d(scene, traj, k):
    xs, vs, ms = [], [], []
    for i, body in enumerate(scene.bodies):
        p, m = cluster_2d(body.mass, body.moment)
        r = (rot2(traj.angle[k, i]) @ p.T).T
        w = traj.omega[k, i]
        xs.append(traj.com[k, i] + r)
        vs.append(traj.vel[k, i] + w * np.stack([-r[:, 1], r[:, 0]], axis=1))
        ms.append(m)
    return np.concatenate(xs), np.concatenate(vs), np.concatenate(ms)


def test_the_clusters_have_the_bodies_mass_properties():
    for body in SCENE_3D.bodies:
        p, m = cluster_3d(body.mass, body.inertia)
        assert m.sum() == pytest.approx(body.mass, rel=1e-15)
        np.testing.assert_allclose(m @ p, 0.0, atol=1e-15)
        i = sum(mk * (pk @ pk * np.eye(3) - np.outer(pk, pk)) for pk, mk in zip(p, m,
                                                                                strict=True))
        np.testing.assert_allclose(i, body.inertia, rtol=1e-13, atol=1e-16)
    assert abs(SCENE_3D.bodies[0].inertia[0, 1]) > 0  # really a non-diagonal tensor


def test_kinetic_energy_3d_equals_the_sum_over_point_masses():
    traj = random_traj_3d(SCENE_3D)
    ke = qty.kinetic_energy(SCENE_3D, traj)
    trans = qty.translational_kinetic_energy(SCENE_3D, traj)
    rot = qty.rotational_kinetic_energy(SCENE_3D, traj)
    assert ke.shape == trans.shape == rot.shape == (len(traj.t),)
    for k in range(len(traj.t)):
        x, v, m = points_3d(SCENE_3D, traj, k)
        expected = 0.5 * np.sum(m * np.sum(v * v, axis=1))
        assert ke[k] == pytest.approx(expected, rel=1e-13)
        vc = traj.vel[k]
        t_hand = sum(0.5 * b.mass * vc[i] @ vc[i] for i, b in enumerate(SCENE_3D.bodies))
        assert trans[k] == pytest.approx(t_hand, rel=1e-14)
        assert rot[k] == pytest.approx(expected - t_hand, rel=1e-11)
        assert rot[k] > 0


def test_angular_momentum_3d_equals_the_sum_over_point_masses():
    traj = random_traj_3d(SCENE_3D)
    l_origin = qty.angular_momentum(SCENE_3D, traj)
    l_com = qty.angular_momentum(SCENE_3D, traj, about="com")
    assert l_origin.shape == l_com.shape == (len(traj.t), 3)
    for k in range(len(traj.t)):
        x, v, m = points_3d(SCENE_3D, traj, k)
        np.testing.assert_allclose(l_origin[k], np.sum(m[:, None] * np.cross(x, v), axis=0),
                                   rtol=1e-12, atol=1e-13)
        c = m @ x / m.sum()
        np.testing.assert_allclose(l_com[k], np.sum(m[:, None] * np.cross(x - c, v), axis=0),
                                   rtol=1e-12, atol=1e-13)
        np.testing.assert_allclose(qty.linear_momentum(SCENE_3D, traj)[k], m @ v, rtol=1e-13,
                                   atol=1e-14)
        np.testing.assert_allclose(qty.system_com(SCENE_3D, traj)[k], c, rtol=1e-13,
                                   atol=1e-14)


@pytest.mark.parametrize(("scene", "make"), [(SCENE_3D, random_traj_3d),
                                             (SCENE_2D, random_traj_2d)], ids=["3d", "2d"])
def test_transfer_identity_and_fixed_points(scene, make):
    traj = make(scene)
    m_tot = scene.masses.sum()
    c = qty.system_com(scene, traj)
    p = qty.linear_momentum(scene, traj)
    l_o = qty.angular_momentum(scene, traj)
    l_c = qty.angular_momentum(scene, traj, about="com")
    cross = np.cross(c, p) if scene.dimension == 3 else c[:, 0] * p[:, 1] - c[:, 1] * p[:, 0]
    # L_origin = L_com + M c x V, with M V = P
    np.testing.assert_allclose(l_o, l_c + cross, rtol=1e-12, atol=1e-13)
    assert m_tot == pytest.approx(sum(b.mass for b in scene.bodies))
    # about a fixed point s: L_s = L_origin - s x P
    s = np.array([0.3, -1.2, 2.0])[: scene.dimension]
    l_s = qty.angular_momentum(scene, traj, about=s)
    sxp = np.cross(s, p) if scene.dimension == 3 else s[0] * p[:, 1] - s[1] * p[:, 0]
    np.testing.assert_allclose(l_s, l_o - sxp, rtol=1e-12, atol=1e-13)


@pytest.mark.parametrize(("scene", "make"), [(SCENE_3D, random_traj_3d),
                                             (SCENE_2D, random_traj_2d)], ids=["3d", "2d"])
def test_galilean_shift_leaves_l_com_unchanged(scene, make):
    traj = make(scene)
    u = np.array([3.0, -1.0, 0.5])[: scene.dimension]
    x0 = np.array([10.0, 20.0, -5.0])[: scene.dimension]
    moved = Trajectory(t=traj.t, com=traj.com + x0 + u * traj.t[:, None, None],
                       vel=traj.vel + u, omega=traj.omega, quat=traj.quat, angle=traj.angle)
    np.testing.assert_allclose(qty.angular_momentum(scene, moved, about="com"),
                               qty.angular_momentum(scene, traj, about="com"),
                               rtol=1e-11, atol=1e-11)
    # while L about the origin does change, and KE changes by P.u + M u^2 / 2
    assert not np.allclose(qty.angular_momentum(scene, moved), qty.angular_momentum(scene, traj))
    m_tot = scene.masses.sum()
    p = qty.linear_momentum(scene, traj)
    np.testing.assert_allclose(qty.kinetic_energy(scene, moved),
                               qty.kinetic_energy(scene, traj) + p @ u + 0.5 * m_tot * u @ u,
                               rtol=1e-12)


def test_kinetic_energy_and_angular_momentum_2d_equal_point_sums():
    traj = random_traj_2d(SCENE_2D)
    ke = qty.kinetic_energy(SCENE_2D, traj)
    l_o = qty.angular_momentum(SCENE_2D, traj)
    rot = qty.rotational_kinetic_energy(SCENE_2D, traj)
    assert ke.shape == l_o.shape == (len(traj.t),)
    for k in range(len(traj.t)):
        x, v, m = points_2d(SCENE_2D, traj, k)
        assert ke[k] == pytest.approx(0.5 * np.sum(m * np.sum(v * v, axis=1)), rel=1e-13)
        assert l_o[k] == pytest.approx(np.sum(m * (x[:, 0] * v[:, 1] - x[:, 1] * v[:, 0])),
                                       rel=1e-12, abs=1e-13)
        j = [b.moment for b in SCENE_2D.bodies]
        assert rot[k] == pytest.approx(0.5 * np.sum(np.array(j) * traj.omega[k] ** 2),
                                       rel=1e-14)
    np.testing.assert_allclose(qty.linear_momentum(SCENE_2D, traj),
                               np.einsum("n,tnd->td", [1.5, 0.7], traj.vel), rtol=1e-14)


# -- potentials by hand ---------------------------------------------------------------------------
def _attach_world_3d(scene, traj, k, body, local):
    """Body-frame point -> world, through the body-frame origin: x_o = x_com - R com."""
    b = scene.bodies[body]
    r = rot3(traj.quat[k, body])
    origin = traj.com[k, body] - r @ b.com
    return origin + r @ np.asarray(local)


def _attach_world_2d(scene, traj, k, body, local):
    b = scene.bodies[body]
    r = rot2(traj.angle[k, body])
    return traj.com[k, body] - r @ b.com + r @ np.asarray(local)


def test_potentials_3d_by_hand():
    traj = random_traj_3d(SCENE_3D)
    g = np.array([0.3, -0.2, -9.81])
    masses = [3.0, 2.0, 0.5]
    grav = qty.gravitational_potential_energy(SCENE_3D, traj)
    spring = qty.spring_potential_energy(SCENE_3D, traj)
    load = qty.load_potential_energy(SCENE_3D, traj)
    for k in range(len(traj.t)):
        assert grav[k] == pytest.approx(-sum(m * g @ traj.com[k, i]
                                             for i, m in enumerate(masses)), rel=1e-13)
        pa = _attach_world_3d(SCENE_3D, traj, k, 0, [0.1, 0.2, -0.05])
        pb = _attach_world_3d(SCENE_3D, traj, k, 1, [0.0, -0.1, 0.1])
        pc = _attach_world_3d(SCENE_3D, traj, k, 1, [0.05, 0.0, 0.0])
        e1 = 0.5 * 40.0 * (np.linalg.norm(pa - pb) - 0.3) ** 2
        e2 = 0.5 * 7.0 * np.linalg.norm(pc - [1.0, 2.0, 3.0]) ** 2
        assert spring[k] == pytest.approx(e1 + e2, rel=1e-12)
        # a constant world force has potential -F . x_com; a 3D torque has none
        assert load[k] == pytest.approx(-np.dot([1.0, -2.0, 0.5], traj.com[k, 0]), rel=1e-13)
    np.testing.assert_allclose(qty.potential_energy(SCENE_3D, traj), grav + spring + load)
    np.testing.assert_allclose(qty.total_energy(SCENE_3D, traj),
                               qty.kinetic_energy(SCENE_3D, traj) + grav + spring + load)


def test_potentials_2d_by_hand():
    traj = random_traj_2d(SCENE_2D)
    grav = qty.gravitational_potential_energy(SCENE_2D, traj)
    spring = qty.spring_potential_energy(SCENE_2D, traj)
    load = qty.load_potential_energy(SCENE_2D, traj)
    g = np.array([0.5, -9.81])
    for k in range(len(traj.t)):
        assert grav[k] == pytest.approx(-(1.5 * g @ traj.com[k, 0] + 0.7 * g @ traj.com[k, 1]),
                                        rel=1e-13)
        pa = _attach_world_2d(SCENE_2D, traj, k, 0, [0.1, 0.05])
        pb = _attach_world_2d(SCENE_2D, traj, k, 1, [-0.1, 0.0])
        pc = _attach_world_2d(SCENE_2D, traj, k, 1, [0.0, 0.1])
        e = 0.5 * 12.0 * (np.linalg.norm(pa - pb) - 0.2) ** 2 \
            + 0.5 * 3.0 * (np.linalg.norm(pc - [0.5, 1.5]) - 0.1) ** 2
        assert spring[k] == pytest.approx(e, rel=1e-12)
        # 2D: a constant torque is conservative too, potential -tau theta
        expected = -np.dot([0.4, 1.0], traj.com[k, 0]) - 0.7 * traj.angle[k, 0]
        assert load[k] == pytest.approx(expected, rel=1e-13)


def test_no_effects_means_zero_potential():
    scene = load_case_text('[case]\nname="z"\ndimension=3\n[run]\nduration=1.0\ndt=0.1\n'
                           '[[bodies]]\nname="b"\nshape={sphere={radius=1.0}}\nmass=1.0\n'
                           'position=[0,0,0]\n')
    traj = random_traj_3d(scene)
    np.testing.assert_array_equal(qty.potential_energy(scene, traj), 0.0)


# -- conservation along exact motions -------------------------------------------------------------
def _spin_quats(axis, omega, t, q0):
    """Exact torque-free spin about a principal axis: q(t) = exp(omega t axis / 2) q0."""
    return np.array([_qmul(axis_angle_to_quat(np.asarray(axis, float), omega * ti), q0)
                     for ti in t])


def _qmul(a, b):
    r = Rotation.from_quat(a[[1, 2, 3, 0]]) * Rotation.from_quat(b[[1, 2, 3, 0]])
    return r.as_quat()[[3, 0, 1, 2]]


def test_energy_is_conserved_along_an_exact_spinning_projectile():
    scene = load_case_text("""
[case]
name = "proj"
dimension = 3
[run]
duration = 2.0
dt = 0.01
[effects]
gravity = [0.0, 0.0, -9.81]
[[bodies]]
name = "box"
shape = { box = { size = [0.1, 0.4, 0.9] } }
mass = 10.0
position = [0.0, 0.0, 0.0]
""")
    t = np.linspace(0.0, 2.0, 41)
    v0, g = np.array([3.0, 1.0, 4.0]), np.array([0.0, 0.0, -9.81])
    com = v0 * t[:, None] + 0.5 * g * t[:, None] ** 2
    vel = v0 + g * t[:, None]
    # spin about the body z axis (a principal axis) in a tilted frame: omega constant in world
    q0 = axis_angle_to_quat(np.array([1.0, 0.0, 0.0]), 0.4)
    axis = rot3(q0) @ [0.0, 0.0, 1.0]
    quat = _spin_quats(axis, 6.0, t, q0)
    traj = Trajectory(t=t, com=com[:, None], vel=vel[:, None],
                      omega=np.broadcast_to(6.0 * axis, (41, 1, 3)).copy(), quat=quat[:, None])
    e = qty.total_energy(scene, traj)
    rot = 0.5 * scene.bodies[0].inertia[2, 2] * 36.0
    assert e[0] == pytest.approx(0.5 * 10.0 * v0 @ v0 + rot, rel=1e-14)
    # exact motion: energy constant to round-off (relative 1e-13 of the ~250 J total)
    np.testing.assert_allclose(e, e[0], rtol=1e-13)
    # and the angular momentum about the com is constant and along the spin axis (|L| ~ 0.85;
    # the rotation matrices carry ~1e-16 round-off per entry)
    l_com = qty.angular_momentum(scene, traj, about="com")
    np.testing.assert_allclose(l_com, np.broadcast_to(scene.bodies[0].inertia[2, 2] * 6.0 * axis,
                                                      l_com.shape), rtol=0, atol=1e-13)


def test_energy_is_conserved_along_an_exact_spring_oscillation():
    # attach point on the spin axis, on the spring line: the spin never loads the spring
    scene = load_case_text("""
[case]
name = "osc"
dimension = 3
[run]
duration = 2.0
dt = 0.01
[effects]
[[effects.springs]]
a = "block"
attach_a = [0.05, 0.0, 0.0]
anchor = [0.0, 0.0, 0.0]
stiffness = 100.0
rest_length = 0.5
[[bodies]]
name = "block"
shape = { box = { size = [0.1, 0.1, 0.2] } }
mass = 1.0
position = [0.0, 0.0, 0.0]
""")
    t = np.linspace(0.0, 2.0, 57)
    w = 10.0  # sqrt(k / m)
    x = 0.45 + 0.2 * np.cos(w * t)  # equilibrium: attach point at the rest length
    com = np.stack([x, 0 * t, 0 * t], axis=1)[:, None]
    vel = np.stack([-0.2 * w * np.sin(w * t), 0 * t, 0 * t], axis=1)[:, None]
    quat = _spin_quats([1.0, 0.0, 0.0], 3.0, t, np.array([1.0, 0.0, 0.0, 0.0]))[:, None]
    omega = np.broadcast_to([3.0, 0.0, 0.0], (57, 1, 3)).copy()
    traj = Trajectory(t=t, com=com, vel=vel, omega=omega, quat=quat)
    e = qty.total_energy(scene, traj)
    i_xx = scene.bodies[0].inertia[0, 0]
    assert e[0] == pytest.approx(0.5 * 100.0 * 0.2**2 + 0.5 * i_xx * 9.0, rel=1e-14)
    np.testing.assert_allclose(e, e[0], rtol=1e-13)


def test_energy_is_conserved_under_constant_force_and_2d_torque():
    scene = load_case_text("""
[case]
name = "push"
dimension = 2
[run]
duration = 1.0
dt = 0.01
[effects]
gravity = [0.0, -9.81]
[[effects.loads]]
body = "plate"
force = [2.0, 1.0]
torque = -0.3
[[bodies]]
name = "plate"
shape = { box = { size = [0.4, 0.2] } }
mass = 2.0
position = [0.0, 0.0]
""")
    j = scene.bodies[0].moment
    t = np.linspace(0.0, 3.0, 31)
    acc = np.array([2.0, 1.0]) / 2.0 + np.array([0.0, -9.81])
    v0 = np.array([1.0, 5.0])
    com = (v0 * t[:, None] + 0.5 * acc * t[:, None] ** 2)[:, None]
    vel = (v0 + acc * t[:, None])[:, None]
    alpha = -0.3 / j
    angle = (0.2 + 4.0 * t + 0.5 * alpha * t**2)[:, None]
    omega = (4.0 + alpha * t)[:, None]
    traj = Trajectory(t=t, com=com, vel=vel, omega=omega, angle=angle)
    e = qty.total_energy(scene, traj)
    assert np.ptp(qty.kinetic_energy(scene, traj)) > 10.0  # energy really moves between forms
    np.testing.assert_allclose(e, e[0], rtol=1e-13, atol=1e-12)
    # 2D angular momentum about the com changes by the torque: dL/dt = tau
    l_com = qty.angular_momentum(scene, traj, about="com")
    np.testing.assert_allclose(np.diff(l_com) / np.diff(t), -0.3, rtol=1e-12)


def test_world_inertia_rotates_the_body_tensor():
    traj = random_traj_3d(SCENE_3D, t_count=3)
    iw = qty.world_inertia(SCENE_3D, traj)
    assert iw.shape == (3, 3, 3, 3)
    for k in range(3):
        for i, b in enumerate(SCENE_3D.bodies):
            r = rot3(traj.quat[k, i])
            np.testing.assert_allclose(iw[k, i], r @ b.inertia @ r.T, rtol=1e-13, atol=1e-16)
