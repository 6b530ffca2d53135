"""The independent Newton-Euler equations (crosscheck.reference.newton_euler).

Each physical ingredient against a closed form or a hand computation, then the whole right-hand
side against the in-house simulator's compiled one on random states: two implementations written
apart, which must agree to round-off (a cross-check that lives here, not in src, so the reference
never depends on what it judges).
"""

from __future__ import annotations

import glob
import json
import os
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from crosscheck.quantities import kinetic_energy
from crosscheck.reference import newton_euler as ne
from crosscheck.reference.analytic import SOLUTIONS
from crosscheck.rotations import axis_angle_to_quat, quat_angle_between, quat_to_matrix
from crosscheck.scene.loader import load_case, load_case_text

CASES = Path(__file__).resolve().parents[2] / "cases"
RIGID_CASES = sorted(glob.glob(str(CASES / "rigid*" / "*.toml")))
SQ = np.sqrt(0.5)


def _j(v) -> str:
    return json.dumps(np.asarray(v, float).tolist())


def _solve(scene, times):
    return ne.solve(scene, np.asarray(times, float), rtol=1e-12, atol=1e-13)


def test_imports_nothing_from_the_simulator():
    # The point of the module: the DOP853 reference must not run on the in-house kernels.
    case = str(CASES / "rigid3d" / "two_body_spring.toml")
    code = ("import sys\n"
            "from crosscheck.reference.simulated import dop853_reference\n"
            "from crosscheck.scene.loader import load_case\n"
            f"traj = dop853_reference(load_case({case!r}))\n"
            "assert len(traj.t) > 1\n"
            "print(sorted(m for m in sys.modules if m.startswith('crosscheck.sim')))\n")
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(p for p in sys.path if p))
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env,
                         check=True)
    assert out.stdout.strip() == "[]", out.stdout


TURN = quat_to_matrix(axis_angle_to_quat([0.3, -1.0, 0.5], 0.9))  # principal axes off the body's
# Every effect with every reference point off: centres of mass off the body origins, a full
# inertia tensor, damped springs between off-centre points of two turned bodies and to an anchor,
# drag and loads on both (the committed cases leave some of these out: no case has a damped
# spring off the centre of mass).
EVERYTHING_3D = f"""
[case]
name = "everything-3d"
dimension = 3
[run]
duration = 0.01
dt = 1e-3
sample_every = 1e-3
[effects]
gravity = [0.3, -0.2, -9.81]
[[effects.springs]]
a = "p"
attach_a = [0.1, -0.05, 0.02]
b = "r"
attach_b = [-0.04, 0.03, 0.05]
stiffness = 40.0
damping = 0.7
rest_length = 0.25
[[effects.springs]]
a = "r"
attach_a = [0.05, 0.05, -0.03]
anchor = [0.5, 0.2, 1.0]
stiffness = 15.0
damping = 0.4
rest_length = 0.1
[[effects.drag]]
linear = 0.2
angular = 0.01
[[effects.loads]]
body = "p"
force = [0.4, -0.1, 0.3]
torque = [0.02, -0.01, 0.03]
[[effects.loads]]
body = "r"
torque = [-0.01, 0.02, 0.0]
[[bodies]]
name = "p"
shape = {{ box = {{ size = [0.3, 0.2, 0.1] }} }}
mass = 1.5
com = [0.03, -0.02, 0.01]
inertia = {_j(TURN @ np.diag([0.010, 0.017, 0.022]) @ TURN.T)}
position = [0.1, -0.2, 0.5]
orientation = {{ axis = [1.0, 2.0, 3.0], angle = 0.7 }}
velocity = [1.0, -0.5, 0.25]
angular_velocity = [3.0, -7.0, 5.0]
[[bodies]]
name = "r"
shape = {{ cylinder = {{ radius = 0.05, length = 0.2 }} }}
mass = 0.8
com = [0.0, 0.01, -0.02]
position = [0.4, 0.1, 0.6]
orientation = {{ axis = [0.0, 1.0, 1.0], angle = -1.1 }}
velocity = [-0.3, 0.2, 0.0]
angular_velocity = [0.5, 2.0, -1.0]
"""

BY_HAND_2D = """
[case]
name = "by-hand-2d"
dimension = 2
[run]
duration = 0.01
dt = 1e-3
sample_every = 1e-3
[[effects.springs]]
a = "a"
attach_a = [0.1, 0.1]
b = "b"
attach_b = [0.0, -0.2]
stiffness = 5.0
damping = 1.0
rest_length = 0.3
[[effects.drag]]
linear = 0.3
angular = 0.05
bodies = ["b"]
[[effects.loads]]
body = "a"
force = [1.0, 0.0]
torque = 0.2
[[bodies]]
name = "a"
shape = { circle = { radius = 0.1 } }
mass = 1.0
inertia = 0.01
position = [0.0, 0.0]
orientation = 1.5707963267948966
[[bodies]]
name = "b"
shape = { circle = { radius = 0.1 } }
mass = 2.0
com = [0.1, 0.0]
inertia = 0.02
position = [-0.1, 1.1]
velocity = [0.0, 0.5]
angular_velocity = 1.0
"""

# -- by hand ---------------------------------------------------------------------------------------
def test_3d_spring_drag_load_and_quaternion_rate_by_hand():
    # Turned 90 degrees about z (body x -> world y, body y -> world -x), centre of mass 0.05 m off
    # the body origin, attachment 0.2 m from the centre of mass along body x, i.e. world y: the
    # attachment sits at (0.95, 0.2, 0), straight below the anchor (0.95, 0.2, 1.0).
    scene = load_case_text(f"""
[case]
name = "by-hand-3d"
dimension = 3
[run]
duration = 0.01
dt = 1e-3
sample_every = 1e-3
[effects]
gravity = [0, 0, -9.81]
[[effects.springs]]
a = "b"
attach_a = [0.2, 0.05, 0.0]
anchor = [0.95, 0.2, 1.0]
stiffness = 10.0
damping = 2.0
rest_length = 0.4
[[effects.drag]]
linear = 0.3
angular = 0.05
[[effects.loads]]
body = "b"
force = [1.0, 0.0, 0.0]
torque = [0.0, 0.0, 0.3]
[[bodies]]
name = "b"
shape = {{ box = {{ size = [0.4, 0.2, 0.1] }} }}
mass = 2.0
com = [0.0, 0.05, 0.0]
inertia = [[0.1, 0, 0], [0, 0.2, 0], [0, 0, 0.3]]
position = [1.0, 0.0, 0.0]
orientation = {_j([SQ, 0, 0, SQ])}
velocity = [0.0, 0.0, 0.5]
angular_velocity = [2.0, 0.0, 0.0]
""")
    x, _, P, L = ne.unpack(ne.equations(scene), ne.initial_state(scene))
    np.testing.assert_allclose(x[0], [0.95, 0.0, 0.0], atol=1e-15)
    np.testing.assert_allclose(P[0], [0.0, 0.0, 1.0], atol=1e-15)
    # World inertia diag(0.2, 0.1, 0.3) (the body y axis lies along world x): L = (0.4, 0, 0).
    np.testing.assert_allclose(L[0], [0.4, 0.0, 0.0], atol=1e-15)

    eq, y0 = ne.equations(scene), ne.initial_state(scene)
    dx, dq, dP, dL = ne.unpack(eq, ne.state_derivative(scene)(0.0, y0))
    # Spring: l = 1, e = (0, 0, -1), stretch 0.6 -> 6 N. The attachment moves at
    # v + w x r = (0, 0, 0.5) + (2, 0, 0) x (0, 0.2, 0) = (0, 0, 0.9), so dl/dt = -0.9 and the
    # damper takes 1.8 N off: f = (0, 0, 4.2), torque r x f = (0.84, 0, 0) about the centre of
    # mass (about the body origin it would have a y component, 0.21).
    # Gravity (0, 0, -19.62), drag -0.3 v = (0, 0, -0.15) and -0.05 w = (-0.1, 0, 0), load.
    np.testing.assert_allclose(dx[0], [0.0, 0.0, 0.5], atol=1e-15)
    np.testing.assert_allclose(dP[0], [1.0, 0.0, 4.2 - 19.62 - 0.15], atol=1e-12)
    np.testing.assert_allclose(dL[0], [0.84 - 0.1, 0.0, 0.3], atol=1e-12)
    # dq/dt = 1/2 (0, w) q with the world w = (2, 0, 0) and q = (c, 0, 0, c): (0, c, -c, 0).
    # (Body-frame w, q (0, w_body), would give (0, c, +c, 0) here.)
    np.testing.assert_allclose(dq[0], [0.0, SQ, -SQ, 0.0], atol=1e-15)


def test_2d_spring_between_bodies_drag_and_load_by_hand():
    # a: at the origin, turned 90 degrees, attachment (0.1, 0.1) -> world (-0.1, 0.1).
    # b: centre of mass (0.1, 0) off its origin, at world (0, 1.1); attachment 0.2 below and 0.1
    # left of it: (-0.1, 0.9). The spring is vertical, l = 0.8.
    scene = load_case_text(BY_HAND_2D)
    eq = ne.equations(scene)
    dx, dtheta, dP, dL = ne.unpack(eq, ne.state_derivative(scene)(0.0, ne.initial_state(scene)))
    # e = (0, -1); b's attachment moves at (0, 0.5) + w x (-0.1, -0.2) = (0.2, 0.4), so
    # dl/dt = e . (v_a - v_b) = 0.4; |f| = 5 (0.8 - 0.3) + 1 * 0.4 = 2.9, pulling a up.
    np.testing.assert_allclose(dx, [[0.0, 0.0], [0.0, 0.5]], atol=1e-15)
    np.testing.assert_allclose(dtheta, [0.0, 1.0], atol=1e-15)  # L / I
    np.testing.assert_allclose(dP[0], [1.0, 2.9], atol=1e-12)  # spring + load
    np.testing.assert_allclose(dP[1], [0.0, -2.9 - 0.15], atol=1e-12)  # reaction + drag
    # Torques r x f = r_x f_y - r_y f_x: a: -0.1 * 2.9 + 0.2 (load); b: -(-0.1) * 2.9 - 0.05 w.
    np.testing.assert_allclose(dL, [-0.29 + 0.2, 0.29 - 0.05], atol=1e-12)


# -- closed forms over time ------------------------------------------------------------------------
def test_free_asymmetric_rotation_conserves_energy_and_follows_euler_elliptic():
    # The tennis racket (I1 < I2 < I3, spin near the intermediate axis) for 4 s, across its first
    # flip (t = 1.9 s): world L is a state variable, but the energy 1/2 w . L and the body-frame
    # angular velocity depend on q evolving by the world-frame rate; Jacobi's solution gives the
    # latter exactly. Measured: 3.5e-9 rad/s at rtol 1e-12, 10x less per decade of rtol (the
    # separatrix amplifies the integration error; over 6 s it reaches 1.7e-6).
    scene = load_case(CASES / "rigid3d" / "tennis_racket.toml")
    scene = replace(scene, run=replace(scene.run, duration=4.0))
    t = scene.run.sample_times()
    traj = _solve(scene, t)
    energy = kinetic_energy(scene, traj)
    assert np.max(np.abs(energy - energy[0])) / energy[0] < 1e-10
    L = np.einsum("tij,jk,tlk,tl->ti", quat_to_matrix(traj.quat[:, 0]), scene.bodies[0].inertia,
                  quat_to_matrix(traj.quat[:, 0]), traj.omega[:, 0])
    assert np.max(np.abs(np.linalg.norm(L, axis=1) - np.linalg.norm(L[0]))) \
        < 1e-10 * np.linalg.norm(L[0])
    exact = SOLUTIONS["torque_free_intermediate"](scene, t).extras["omega_body"][:, 0]
    body_w = np.einsum("tji,tj->ti", quat_to_matrix(traj.quat[:, 0]), traj.omega[:, 0])
    assert np.max(np.abs(body_w - exact)) < 2e-8
    assert np.ptp(body_w[:, 1]) > 9.0  # the intermediate component (5 rad/s) flipped sign


def test_free_axisymmetric_top_matches_its_closed_form():
    scene = load_case(CASES / "rigid3d" / "axisymmetric_top.toml")
    t = scene.run.sample_times()
    traj = _solve(scene, t)
    exact = SOLUTIONS["torque_free_axisymmetric"](scene, t)
    assert np.max(quat_angle_between(traj.quat, exact.quat)) < 1e-9
    np.testing.assert_allclose(traj.omega, exact.omega, rtol=0, atol=1e-9)
    assert np.max(quat_angle_between(traj.quat[:, 0], traj.quat[:1, 0])) > 1.0  # it turned


def test_drag_decays_velocity_and_spin_exponentially():
    # A sphere (isotropic inertia, so w stays along its axis) with linear and angular drag:
    # v(t) = v0 exp(-c t / m), w(t) = w0 exp(-c_a t / I), x(t) = x0 + v0 m / c (1 - exp(-c t / m)).
    m, r, c, ca = 2.0, 0.1, 0.8, 0.004
    inertia = 0.4 * m * r * r
    scene = load_case_text(f"""
[case]
name = "drag"
dimension = 3
[run]
duration = 2.0
dt = 1e-3
sample_every = 0.1
[[effects.drag]]
linear = {c}
angular = {ca}
[[bodies]]
name = "ball"
shape = {{ sphere = {{ radius = {r} }} }}
mass = {m}
position = [0.0, 0.0, 0.0]
velocity = [1.0, -2.0, 0.5]
angular_velocity = [3.0, 4.0, -1.0]
""")
    t = scene.run.sample_times()
    traj = _solve(scene, t)
    v0, w0 = np.array([1.0, -2.0, 0.5]), np.array([3.0, 4.0, -1.0])
    decay = np.exp(-c * t / m)[:, None]
    np.testing.assert_allclose(traj.vel[:, 0], v0 * decay, rtol=0, atol=1e-11)
    np.testing.assert_allclose(traj.com[:, 0], v0 * m / c * (1 - decay), rtol=0, atol=1e-11)
    np.testing.assert_allclose(traj.omega[:, 0], w0 * np.exp(-ca * t / inertia)[:, None], rtol=0,
                               atol=1e-10)
    assert np.exp(-ca * t[-1] / inertia) < 0.5  # the spin really decayed


def test_trajectory_conversion_reports_com_velocity_and_world_omega():
    # A state written by hand: a quaternion off unit length, momentum and world L; the Trajectory
    # must hold the normalised quaternion, P / m and R I^-1 R^T L.
    scene = load_case(CASES / "rigid3d" / "mesh_tumbling.toml")
    body = scene.bodies[0]
    q = np.array([0.9, 0.3, -0.2, 0.4]) * 1.01
    P, L = np.array([0.3, -0.6, 1.2]), np.array([0.01, -0.02, 0.005])
    traj = ne.state_to_trajectory(scene, [0.0], ne.pack([1.0, 2.0, 3.0], q, P, L)[None])
    R = quat_to_matrix(q / np.linalg.norm(q))
    np.testing.assert_allclose(traj.com[0, 0], [1.0, 2.0, 3.0])
    np.testing.assert_allclose(traj.quat[0, 0], q / np.linalg.norm(q), rtol=1e-15)
    np.testing.assert_allclose(traj.vel[0, 0], P / body.mass, rtol=1e-15)
    np.testing.assert_allclose(R @ body.inertia @ R.T @ traj.omega[0, 0], L, rtol=1e-12)


# -- against the in-house simulator ----------------------------------------------------------------
@pytest.mark.parametrize("case", [*RIGID_CASES, "EVERYTHING_3D", "BY_HAND_2D"],
                         ids=lambda p: Path(p).stem)
def test_matches_the_inhouse_derivative_on_random_states(case):
    from crosscheck.sim import rigid

    scene = load_case_text(globals()[case]) if case.isupper() else load_case(case)
    y0 = rigid.initial_state(scene)
    np.testing.assert_array_equal(ne.initial_state(scene), y0)  # the same layout and numbers
    mine, theirs = ne.state_derivative(scene), rigid.state_derivative(scene)
    eq = ne.equations(scene)
    rng = np.random.default_rng(10)
    for _ in range(25):
        # Far from the case's own state (springs stretched and turned, quaternions off unit
        # length as between solver stages), each entry moved by its own order of magnitude.
        y = y0 + rng.normal(size=y0.shape) * (1.0 + np.abs(y0))
        for a, b in zip(ne.unpack(eq, mine(0.0, y)), ne.unpack(eq, theirs(0.0, y)), strict=True):
            scale = max(1.0, float(np.max(np.abs(b))))
            np.testing.assert_allclose(a, b, rtol=0, atol=1e-13 * scale)
