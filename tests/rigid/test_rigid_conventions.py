"""The in-house adapter's Trajectory follows the conventions (scene/model.py, state.py).

A body whose centre of mass is off the body-frame origin, whose inertia is full (principal axes
turned away from the body axes) and whose orientation is not the identity: every reference point
and frame shows in its numbers. The expected values are computed here by hand with NumPy from
the case's numbers, not with the simulator's code.
"""

from __future__ import annotations

import json

import numpy as np

from crosscheck.engines import get_engine
from crosscheck.rotations import axis_angle_to_quat, quat_mul, quat_to_matrix
from crosscheck.scene.loader import load_case_text
from crosscheck.sim.rigid import RigidSimulation, state_from_scene

AXES = quat_to_matrix(axis_angle_to_quat([0.3, -1.0, 0.5], 0.9))
INERTIA = AXES @ np.diag([0.010, 0.017, 0.022]) @ AXES.T
COM = np.array([0.03, -0.02, 0.01])
Q0 = axis_angle_to_quat([1.0, 2.0, 3.0], 0.7)
POS = np.array([0.1, -0.2, 0.5])
VEL = np.array([1.0, -0.5, 0.25])
OMEGA = np.array([3.0, -7.0, 5.0])
ATTACH = np.array([0.15, 0.05, -0.02])  # body frame, off the centre of mass
ANCHOR = np.array([0.4, 0.3, 1.0])
K, C, L0 = 30.0, 0.7, 0.2
G = np.array([0.0, 0.0, -9.81])
DRAG, DRAG_W = 0.3, 0.004
LOAD_F, LOAD_T = np.array([0.5, 0.0, -0.2]), np.array([0.01, 0.02, -0.03])
ATOL = 1e-12  # round-off of a handful of operations on numbers of order 10


def _j(v) -> str:
    return json.dumps(np.asarray(v, float).tolist())


def _scene(effects: str = "", duration: float = 1e-3):
    return load_case_text(f"""
[case]
name = "conventions"
dimension = 3
[run]
duration = {duration}
dt = 1e-3
sample_every = 1e-3
[effects]
{effects}
[[bodies]]
name = "spinner"
shape = {{ box = {{ size = [0.3, 0.2, 0.1] }} }}
mass = 2.0
com = {_j(COM)}
inertia = {_j(INERTIA)}
position = {_j(POS)}
orientation = {_j(Q0)}
velocity = {_j(VEL)}
angular_velocity = {_j(OMEGA)}
""")


ALL_EFFECTS = f"""
gravity = {_j(G)}
[[effects.springs]]
a = "spinner"
attach_a = {_j(ATTACH)}
anchor = {_j(ANCHOR)}
stiffness = {K}
damping = {C}
rest_length = {L0}
[[effects.drag]]
linear = {DRAG}
angular = {DRAG_W}
[[effects.loads]]
body = "spinner"
force = {_j(LOAD_F)}
torque = {_j(LOAD_T)}
"""


def test_recorded_state_is_com_body_frame_and_world_omega():
    scene = _scene(duration=1e-3)
    traj = get_engine("inhouse").run(scene, "rk4", 1e-3)
    R0 = quat_to_matrix(Q0)
    com_world = POS + R0 @ COM
    assert np.linalg.norm(com_world - POS) > 0.03  # the body origin is not the centre of mass
    np.testing.assert_allclose(traj.com[0, 0], com_world, rtol=0, atol=ATOL)
    np.testing.assert_allclose(traj.quat[0, 0], Q0, rtol=0, atol=ATOL)
    np.testing.assert_allclose(traj.vel[0, 0], VEL, rtol=0, atol=ATOL)
    np.testing.assert_allclose(traj.omega[0, 0], OMEGA, rtol=0, atol=ATOL)
    # one torque-free step later: the centre of mass moved by v h exactly, and the recorded
    # world omega carries the conserved angular momentum through the *current* world inertia,
    # L = R(q1) I_body R(q1)^T w1 = R(q0) I_body R(q0)^T w0.
    np.testing.assert_allclose(traj.com[1, 0], com_world + 1e-3 * VEL, rtol=0, atol=ATOL)
    L0_world = R0 @ INERTIA @ R0.T @ OMEGA
    R1 = quat_to_matrix(traj.quat[1, 0])
    np.testing.assert_allclose(R1 @ INERTIA @ R1.T @ traj.omega[1, 0], L0_world, rtol=0,
                               atol=ATOL)
    assert np.linalg.norm(traj.omega[1, 0] - OMEGA) > 1e-3  # w itself changed (full inertia)
    # the meta a reader needs, and the effective settings
    meta = traj.meta
    assert meta["engine"] == "inhouse" and meta["integrator"] == "rk4"
    np.testing.assert_allclose(meta["com_body"][0], COM)
    np.testing.assert_allclose(meta["inertia_body"][0], INERTIA)
    assert meta["steps"] == round(traj.t[-1] / 1e-3)
    eff = meta["effective"]
    assert eff["integrator"] == "rk4" and eff["order"] == 4
    assert eff["rotation_update"] == "renormalise"
    assert eff["effects_simulated"] == []


def test_state_and_derivative_by_hand():
    scene = _scene(ALL_EFFECTS)
    sim = RigidSimulation.from_scene(scene, "rk4")
    assert sim.model.effects == ("gravity", "springs", "drag", "loads")
    state = state_from_scene(sim.model, scene)
    R0 = quat_to_matrix(Q0)
    m = 2.0
    x = POS + R0 @ COM
    np.testing.assert_allclose(state.x[0], x, rtol=0, atol=ATOL)
    np.testing.assert_allclose(state.P[0], m * VEL, rtol=0, atol=ATOL)
    np.testing.assert_allclose(state.L[0], R0 @ INERTIA @ R0.T @ OMEGA, rtol=0, atol=ATOL)

    # By hand: the spring acts at the attachment point, world position POS + R0 ATTACH, moving
    # with v + w x r where r is its offset from the centre of mass.
    r = R0 @ (ATTACH - COM)
    p = x + r
    d = p - ANCHOR
    length = np.linalg.norm(d)
    e = d / length
    f_spring = -(K * (length - L0) + C * e @ (VEL + np.cross(OMEGA, r))) * e
    force = m * G + f_spring - DRAG * VEL + LOAD_F
    torque = np.cross(r, f_spring) - DRAG_W * OMEGA + LOAD_T
    deriv = sim.derivative(state)
    np.testing.assert_allclose(deriv.x[0], VEL, rtol=0, atol=ATOL)
    np.testing.assert_allclose(deriv.P[0], force, rtol=0, atol=ATOL)
    np.testing.assert_allclose(deriv.L[0], torque, rtol=0, atol=ATOL)
    # dq/dt = 1/2 (0, w) q with the world angular velocity
    np.testing.assert_allclose(deriv.q[0], 0.5 * quat_mul(np.r_[0.0, OMEGA], Q0), rtol=0,
                               atol=ATOL)
    # the torque arm matters: measured about the body origin instead, the torque is off
    assert np.linalg.norm(np.cross(R0 @ ATTACH, f_spring) - np.cross(r, f_spring)) > 1e-2
