"""PyBullet adapter: every PyBullet trap of ENGINES.md, each with a test that fails if the adapter
fell into it, plus the traps of PyBullet's API found while writing it.

Tolerances: PyBullet is built with double precision; a state set and read back goes through a
few multiplications by rotation matrices, so it comes back within a few ulp (measured: 0 for the
centre of mass and velocities, 6e-17 for the quaternion). Stepping accumulates ~steps * ulp.
Every limit below says which of the two it is.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pybullet as p
import pytest

from crosscheck import quantities
from crosscheck.engines import get_engine
from crosscheck.engines import pybullet as pb_adapter
from crosscheck.errors import CaseError, EngineUnavailable
from crosscheck.rotations import (
    axis_angle_to_quat,
    matrix_to_quat,
    quat_angle_between,
    quat_to_matrix,
)
from crosscheck.scene.loader import load_case_text

INTEGRATORS = ("multibody", "maximal")
G = 9.81

# A body that exposes every frame convention: centre of mass off the body origin, a full inertia
# tensor whose principal axes are rotated away from the body axes, a non-identity orientation.
AXES = quat_to_matrix(axis_angle_to_quat([0.3, -1.0, 0.5], 0.9))
MOMENTS = np.array([0.010, 0.017, 0.022])
INERTIA = AXES @ np.diag(MOMENTS) @ AXES.T
COM = np.array([0.03, -0.02, 0.01])
Q0 = axis_angle_to_quat([1.0, 2.0, 3.0], 0.7)
R0 = quat_to_matrix(Q0)


def _j(x) -> str:
    return json.dumps(np.asarray(x, float).tolist())


def _body3d(name="b", *, mass=2.0, position=(0.1, -0.2, 0.5), orientation=Q0, velocity=(0, 0, 0),
            omega=(0, 0, 0), com=COM, inertia=INERTIA) -> str:
    return f"""
[[bodies]]
name = "{name}"
shape = {{ box = {{ size = [0.3, 0.2, 0.1] }} }}
mass = {mass!r}
com = {_j(com)}
inertia = {_j(inertia)}
position = {_j(position)}
orientation = {_j(orientation)}
velocity = {_j(velocity)}
angular_velocity = {_j(omega)}
"""


def _body2d(name="plate", *, mass=1.5, com=(0.04, -0.03), position=(0.2, 1.0), angle=2.5,
            velocity=(0.0, 0.0), omega=0.0, moment=0.02) -> str:
    return f"""
[[bodies]]
name = "{name}"
shape = {{ box = {{ size = [0.3, 0.1] }} }}
mass = {mass!r}
inertia = {moment!r}
com = {_j(com)}
position = {_j(position)}
orientation = {angle!r}
velocity = {_j(velocity)}
angular_velocity = {omega!r}
"""


def _scene(dimension, duration, dt, bodies, effects="", sample_every=None, extra=""):
    return load_case_text(f"""
[case]
name = "pybullet-test"
dimension = {dimension}
[run]
duration = {duration!r}
dt = {dt!r}
sample_every = {(sample_every or dt)!r}
[effects]
{effects}
{extra}
{bodies}""")


def _run(scene, integrator, dt=None):
    traj = get_engine("pybullet").run(scene, integrator, dt or scene.run.dt)
    assert traj.failure is None, traj.failure
    return traj


def _principal_axis_world(k: int) -> np.ndarray:
    return R0 @ AXES[:, k]


# -- capabilities ---------------------------------------------------------------------------------
def test_capabilities_and_not_applicable():
    engine = get_engine("pybullet")
    caps = engine.capabilities()
    assert caps.integrators == INTEGRATORS and caps.default_integrator == "multibody"
    assert caps.dimensions == {2, 3}
    assert "contact" in caps.effects  # tests/engines/test_pybullet_contact.py
    # 2D contact: the planar chain only (a maximal 2D body leaves the plane in contact)
    contact = _scene(2, 0.01, 1e-3, _body2d(), effects="contact = true")
    assert engine.not_applicable(contact, "multibody") is None
    assert "2D contact needs the planar chain" in engine.not_applicable(contact, "maximal")
    with pytest.raises(EngineUnavailable, match="2D contact"):
        engine.run(contact, "maximal", 1e-3)
    plain = _scene(3, 0.01, 1e-3, _body3d())
    assert "rk4" in engine.not_applicable(plain, "rk4")
    assert engine.not_applicable(plain, "maximal") is None
    assert engine.version().startswith("3.2.7") or "API" in engine.version()


def test_engine_options_pinned_and_refused():
    engine = get_engine("pybullet")
    pinned = _scene(3, 0.01, 1e-3, _body3d(),
                    extra="[engine_options.pybullet]\nsolver_iterations = 7")
    traj = _run(pinned, "multibody")
    # Read back from getPhysicsEngineParameters, not echoed from the case.
    assert traj.meta["effective"]["num_solver_iterations"] == 7
    for bad in ("solver_iterations = 0", "solver_iterations = 2.5", "substeps = 4"):
        scene = _scene(3, 0.01, 1e-3, _body3d(), extra=f"[engine_options.pybullet]\n{bad}")
        with pytest.raises(CaseError, match="engine_options.pybullet"):
            engine.not_applicable(scene, "multibody")


# -- round trip (trap 2: reference points and frames) -------------------------------------------
# Set then get through every conversion (link frame -> inertial frame on build, inertial frame
# read, restored with resetBasePositionAndOrientation after the probe step, back to the declared
# frame). PyBullet holds doubles: measured 0 on positions and velocities and 6e-17 on the
# quaternion, so the 1e-12 of the issue holds with a margin of 1e4.
@pytest.mark.parametrize("integrator", INTEGRATORS)
def test_round_trip_3d(integrator):
    scene = _scene(3, 1e-3, 1e-3, _body3d(velocity=(1.0, -0.5, 0.25), omega=(3.0, -7.0, 5.0)))
    traj = _run(scene, integrator)
    body = scene.bodies[0]
    np.testing.assert_allclose(traj.com[0, 0], body.com_world(), rtol=0, atol=1e-12)
    np.testing.assert_allclose(traj.quat[0, 0], body.orientation, rtol=0, atol=1e-12)
    np.testing.assert_allclose(traj.vel[0, 0], body.velocity, rtol=0, atol=1e-12)
    np.testing.assert_allclose(traj.omega[0, 0], body.angular_velocity, rtol=0, atol=1e-12)
    # The inertial frame PyBullet holds is the principal-axes frame at the centre of mass.
    eff = traj.meta["effective"]["bodies"][0]
    np.testing.assert_allclose(sorted(eff["principal_moments"]), MOMENTS, rtol=1e-15)
    if integrator == "multibody":  # maximal bodies: PyBullet does not report these fields
        np.testing.assert_allclose(eff["inertial_frame_position"], COM, rtol=0, atol=1e-15)


@pytest.mark.parametrize("integrator", INTEGRATORS)
def test_round_trip_2d(integrator):
    scene = _scene(2, 1e-3, 1e-3, _body2d(angle=8.5, velocity=(1.0, -2.0), omega=-7.0))
    traj = _run(scene, integrator)
    body = scene.bodies[0]
    np.testing.assert_allclose(traj.com[0, 0], body.com_world(), rtol=0, atol=1e-12)
    # The angle comes back on the scene's own turn (8.5 rad, not 8.5 - 2 pi).
    assert abs(traj.angle[0, 0] - 8.5) <= 1e-12
    np.testing.assert_allclose(traj.vel[0, 0], body.velocity, rtol=0, atol=1e-12)
    assert abs(traj.omega[0, 0] + 7.0) <= 1e-12


def test_link_frame_and_inertial_frame_placement():
    """Trap 2 measured on PyBullet itself, next to the adapter that must get it right.

    createMultiBody(basePosition, baseOrientation) places the link frame: the centre of mass
    lands at position + R com and the reported orientation is R times the inertial-frame
    rotation. resetBasePositionAndOrientation places the *inertial* frame: handing it the link
    frame's pose would move the centre of mass onto the body origin (an error of |com|).
    """
    cid = p.connect(p.DIRECT)
    try:
        q_axes = matrix_to_quat(AXES)
        pos = np.array([0.1, -0.2, 0.5])
        uid = p.createMultiBody(2.0, -1, -1, pos.tolist(), [*Q0[1:], Q0[0]],
                                baseInertialFramePosition=COM.tolist(),
                                baseInertialFrameOrientation=[*q_axes[1:], q_axes[0]],
                                physicsClientId=cid)
        got_pos, got_orn = p.getBasePositionAndOrientation(uid, physicsClientId=cid)
        np.testing.assert_allclose(got_pos, pos + R0 @ COM, rtol=0, atol=1e-15)
        got_r = quat_to_matrix(np.array([got_orn[3], *got_orn[:3]]))
        np.testing.assert_allclose(got_r, R0 @ AXES, rtol=0, atol=1e-15)
        # Reset with the link pose: PyBullet takes it as the inertial frame.
        p.resetBasePositionAndOrientation(uid, pos.tolist(), [*Q0[1:], Q0[0]],
                                          physicsClientId=cid)
        moved, _ = p.getBasePositionAndOrientation(uid, physicsClientId=cid)
        np.testing.assert_allclose(moved, pos, rtol=0, atol=1e-15)  # not pos + R com
    finally:
        p.disconnect(cid)
    # The adapter: the centre of mass it reports is position + R com, not the position.
    scene = _scene(3, 1e-3, 1e-3, _body3d())
    for integrator in INTEGRATORS:
        traj = _run(scene, integrator)
        np.testing.assert_allclose(traj.com[0, 0], pos + R0 @ COM, rtol=0, atol=1e-12)


@pytest.mark.parametrize("integrator", INTEGRATORS)
def test_full_inertia_reaches_pybullet(integrator):
    # A constant world torque along a principal axis k (in the world) from rest spins the body
    # about that fixed axis: omega_n = n h tau / I_k exactly in any velocity-first scheme. With the
    # inertia taken unrotated (the body-axes diagonal) the axis would not be principal, the
    # response would not be parallel to the torque and the magnitude would differ by ~10 %.
    h, steps, tau = 1e-3, 500, 0.02
    for k in range(3):
        axis = _principal_axis_world(k)
        scene = _scene(3, steps * h, h, _body3d(),
                       effects=f"[[effects.loads]]\nbody = \"b\"\ntorque = {_j(tau * axis)}",
                       sample_every=0.1)
        traj = _run(scene, integrator)
        n = np.rint(traj.t / h)
        expected = (n * h * tau / MOMENTS[k])[:, None] * axis
        # ~steps round-off additions on omega ~ 1: 1e-12 leaves a margin of 10.
        np.testing.assert_allclose(traj.omega[:, 0], expected, rtol=0, atol=1e-11)


@pytest.mark.parametrize("integrator", INTEGRATORS)
def test_spin_about_a_tilted_principal_axis_is_steady(integrator):
    # Steady rotation about the major principal axis of the full tensor: omega stays. If the
    # inertial frame were not the principal-axes frame, the gyroscopic term would make it wobble
    # at O(1). Round-off over 1000 steps: ~1e-13 of |omega| = 20.
    omega = 20.0 * _principal_axis_world(2)
    scene = _scene(3, 1.0, 1e-3, _body3d(omega=omega), sample_every=0.05)
    traj = _run(scene, integrator)
    np.testing.assert_allclose(traj.omega[:, 0], np.broadcast_to(omega, traj.omega[:, 0].shape),
                               rtol=0, atol=1e-10)


# -- free fall (trap 8) ---------------------------------------------------------------------------
def _velocity_first_drop(h: float, n: np.ndarray) -> np.ndarray:
    # v_k = v_{k-1} + g h = k g h, x_k = x_{k-1} + h v_k: sum_{k=1..n} k g h^2 = g h^2 n (n+1)/2.
    return G * h * h * n * (n + 1) / 2


@pytest.mark.parametrize("integrator", INTEGRATORS)
@pytest.mark.parametrize("dimension", (2, 3))
def test_free_fall_is_semi_implicit(integrator, dimension):
    h = 1e-3
    assert _velocity_first_drop(h, np.array(1000))[()] == pytest.approx(4.909905, abs=1e-12)
    if dimension == 3:
        scene = _scene(3, 1.0, h, _body3d(omega=(0, 0, 0)), effects=f"gravity = [0, 0, {-G}]",
                       sample_every=0.01)
    else:
        scene = _scene(2, 1.0, h, _body2d(omega=0.0), effects=f"gravity = [0, {-G}]",
                       sample_every=0.01)
    traj = _run(scene, integrator)
    n = np.rint(traj.t / h)
    start = scene.bodies[0].com_world()
    up = dimension - 1
    # 1000 additions on positions ~ 5: round-off ~ 1e-12; the position-first or exact answer
    # is 1e-2 or 5e-3 away.
    np.testing.assert_allclose(start[up] - traj.com[:, 0, up], _velocity_first_drop(h, n),
                               rtol=0, atol=1e-10)
    assert start[up] - traj.com[-1, 0, up] == pytest.approx(4.909905, abs=1e-10)
    np.testing.assert_allclose(traj.vel[:, 0, up], -G * n * h, rtol=0, atol=1e-11)


# -- damping (trap 1), the clamp (trap 5), sleeping --------------------------------------------
@pytest.mark.parametrize("integrator", INTEGRATORS)
def test_default_damping_is_off(integrator):
    # ENGINES.md trap 1: a multibody left with PyBullet's default damping goes from 10 m/s to
    # 6.90 m/s in 1 s. With damping off nothing acts: speed and spin stay to round-off (1000
    # steps that add nothing: exact), and the path is x0 + v t (1000 additions: ~1e-13).
    v = np.array([10.0, 0.0, 0.0])
    w = 10.0 * _principal_axis_world(0)
    scene = _scene(3, 1.0, 1e-3, _body3d(velocity=v, omega=w), sample_every=0.1)
    traj = _run(scene, integrator)
    np.testing.assert_allclose(traj.vel[:, 0], np.broadcast_to(v, (len(traj.t), 3)), rtol=0,
                               atol=1e-12)
    np.testing.assert_allclose(traj.omega[:, 0], np.broadcast_to(w, (len(traj.t), 3)), rtol=0,
                               atol=1e-11)
    start = scene.bodies[0].com_world()
    np.testing.assert_allclose(traj.com[:, 0], start + traj.t[:, None] * v, rtol=0, atol=1e-11)
    assert traj.meta["effective"]["probe"]["neutral"] is True


def test_default_damping_measured_on_raw_pybullet():
    # The trap itself, so a PyBullet upgrade that changes the default is noticed: a multibody
    # created the plain way loses speed as -m v (0.04 + 0.04 |v|).
    cid = p.connect(p.DIRECT)
    try:
        p.setPhysicsEngineParameter(fixedTimeStep=1e-3, physicsClientId=cid)
        uid = p.createMultiBody(1.0, -1, physicsClientId=cid)
        p.resetBaseVelocity(uid, [10.0, 0.0, 0.0], [0.0, 0.0, 0.0], physicsClientId=cid)
        v = 10.0
        for _ in range(1000):
            p.stepSimulation(physicsClientId=cid)
            v -= 1e-3 * 0.04 * v * (1 + v)  # the same law, explicit
        got = p.getBaseVelocity(uid, physicsClientId=cid)[0][0]
    finally:
        p.disconnect(cid)
    assert got == pytest.approx(6.90, abs=0.01)
    # Bullet's own discretisation of the law differs from this explicit one at 7e-9.
    assert got == pytest.approx(v, rel=1e-7)


@pytest.mark.parametrize("dropped", ("linearDamping", "maxJointVelocity"))
@pytest.mark.parametrize("dimension", (2, 3))
def test_probe_reports_damping_or_clamp_left_on(monkeypatch, dropped, dimension):
    # If the neutralisation ever stops reaching PyBullet (a renamed keyword, the link-index trap
    # below), the force-free probe step sees the velocities change and the run is a reported
    # failure, not a silently damped scene.
    real = p.changeDynamics

    def lossy(*args, **kwargs):
        kwargs.pop(dropped, None)
        return real(*args, **kwargs)

    monkeypatch.setattr(pb_adapter._p, "changeDynamics", lossy)
    body = _body3d(velocity=(1, 0, 0)) if dimension == 3 else _body2d(velocity=(1, 0))
    scene = _scene(dimension, 0.01, 1e-3, body)
    traj = get_engine("pybullet").run(scene, "multibody", 1e-3)
    assert traj.failure is not None and "damping or the velocity clamp" in traj.failure["reason"]
    assert len(traj.t) == 1  # nothing was stepped after the failure
    probe = traj.meta["effective"]["probe"]
    assert probe["neutral"] is False
    assert max(probe["max_relative_change_linear"], probe["max_relative_change_angular"]) > 1e-3


@pytest.mark.parametrize("integrator", INTEGRATORS)
def test_velocity_clamp_is_lifted(integrator):
    # Trap 5: a multibody is clamped to 100 per component. 150 m/s and 150 rad/s (about a
    # principal axis) must stay, exactly: nothing acts on the body.
    v = np.array([150.0, -150.0, 0.0])
    w = 150.0 * _principal_axis_world(2)
    scene = _scene(3, 1.0, 1e-3, _body3d(velocity=v, omega=w), sample_every=0.1)
    traj = _run(scene, integrator)
    np.testing.assert_allclose(traj.vel[:, 0], np.broadcast_to(v, (len(traj.t), 3)), rtol=0,
                               atol=1e-12)
    np.testing.assert_allclose(traj.omega[:, 0], np.broadcast_to(w, (len(traj.t), 3)), rtol=0,
                               atol=1e-10)
    assert traj.meta["effective"]["max_joint_velocity"]["set"] == "inf"


def test_velocity_clamp_is_lifted_on_the_planar_joints():
    # The 2D multibody's joints are multibody coordinates too: 150 m/s and 150 rad/s stay.
    scene = _scene(2, 0.5, 1e-3, _body2d(velocity=(150.0, -150.0), omega=150.0),
                   sample_every=0.1)
    traj = _run(scene, "multibody")
    np.testing.assert_allclose(traj.vel[:, 0], [[150.0, -150.0]] * len(traj.t), rtol=0,
                               atol=1e-12)
    np.testing.assert_allclose(traj.omega[:, 0], 150.0, rtol=0, atol=1e-12)
    np.testing.assert_allclose(traj.angle[:, 0], 2.5 + 150.0 * traj.t, rtol=0, atol=1e-10)


@pytest.mark.parametrize("integrator", INTEGRATORS)
def test_slow_body_never_sleeps(integrator):
    # Sleeping is disabled (ACTIVATION_STATE_DISABLE_SLEEPING); PyBullet cannot report it. A body
    # drifting at 1 cm/s and 1 mrad/s for 3 s (past Bullet's 2 s deactivation time) must keep
    # moving: x = 0.03 m. Measured: free bodies without contact did not sleep even with the
    # default activation state, so this guards the behaviour rather than proving the setting.
    v = np.array([0.01, 0.0, 0.0])
    w = 1e-3 * _principal_axis_world(1)
    scene = _scene(3, 3.0, 1e-3, _body3d(velocity=v, omega=w), sample_every=0.5)
    traj = _run(scene, integrator)
    start = scene.bodies[0].com_world()
    np.testing.assert_allclose(traj.com[:, 0], start + traj.t[:, None] * v, rtol=0, atol=1e-12)
    np.testing.assert_allclose(traj.omega[-1, 0], w, rtol=0, atol=1e-15)


# -- the contact breaking threshold (trap 10) ---------------------------------------------------
def _persisting_contacts(gap: float) -> int:
    """Contact points that survive when two touching boxes are pulled ``gap`` apart.

    Bullet keeps a manifold point until its distance exceeds the contact breaking threshold:
    an observable of the process-global threshold in a fresh client.
    """
    cid = p.connect(p.DIRECT)
    try:
        shape = p.createCollisionShape(p.GEOM_BOX, halfExtents=[0.1, 0.1, 0.1],
                                       physicsClientId=cid)
        p.createMultiBody(0.0, shape, basePosition=[0, 0, 0], physicsClientId=cid)
        top = p.createMultiBody(1.0, shape, basePosition=[0, 0, 0.199], physicsClientId=cid)
        p.performCollisionDetection(physicsClientId=cid)
        assert len(p.getContactPoints(physicsClientId=cid)) > 0  # they touch
        p.resetBasePositionAndOrientation(top, [0, 0, 0.2 + gap], [0, 0, 0, 1],
                                          physicsClientId=cid)
        p.performCollisionDetection(physicsClientId=cid)
        return len(p.getContactPoints(physicsClientId=cid))
    finally:
        p.disconnect(cid)


def test_contact_breaking_threshold_is_reset_every_run():
    # An earlier client in this process raised the global threshold; it survives disconnecting
    # (trap 10). An adapter run sets it back to Bullet's default (0.02), so the points of boxes
    # 1 cm apart are dropped again in the next fresh client.
    cid = p.connect(p.DIRECT)
    p.setPhysicsEngineParameter(contactBreakingThreshold=0.5, physicsClientId=cid)
    p.disconnect(cid)
    try:
        assert _persisting_contacts(0.01) > 0  # the leak
        traj = _run(_scene(3, 0.01, 1e-3, _body3d()), "multibody")
        assert _persisting_contacts(0.01) == 0
        assert traj.meta["effective"]["contact_breaking_threshold"]["set"] == 0.02
    finally:
        cid = p.connect(p.DIRECT)
        p.setPhysicsEngineParameter(contactBreakingThreshold=0.02, physicsClientId=cid)
        p.disconnect(cid)


# -- PyBullet API traps met while writing the adapter ------------------------------------------
def test_change_dynamics_body_wide_setters_steal_the_link_index():
    # In one changeDynamics call, activationState (like the damping and maxJointVelocity
    # setters) rewrites the command's link index to -1: a link's mass and inertia passed
    # alongside land on the base, turning a fixed base dynamic.
    cid = p.connect(p.DIRECT)
    try:
        uid = p.createMultiBody(0.0, -1, linkMasses=[1.0], linkCollisionShapeIndices=[-1],
                                linkVisualShapeIndices=[-1], linkPositions=[[0, 0, 0]],
                                linkOrientations=[[0, 0, 0, 1]],
                                linkInertialFramePositions=[[0, 0, 0]],
                                linkInertialFrameOrientations=[[0, 0, 0, 1]],
                                linkParentIndices=[0], linkJointTypes=[p.JOINT_REVOLUTE],
                                linkJointAxis=[[0, 0, 1]], physicsClientId=cid)
        p.changeDynamics(uid, 0, mass=2.0, localInertiaDiagonal=[0.3, 0.3, 0.3],
                         activationState=p.ACTIVATION_STATE_DISABLE_SLEEPING,
                         physicsClientId=cid)
        assert p.getDynamicsInfo(uid, -1, physicsClientId=cid)[0] == 2.0  # the base got it
        assert p.getDynamicsInfo(uid, 0, physicsClientId=cid)[0] == 1.0
    finally:
        p.disconnect(cid)
    # The adapter's planar chain: base fixed (mass 0), the mass and moment on the angle link.
    scene = _scene(2, 0.01, 1e-3, _body2d())
    eff = _run(scene, "multibody").meta["effective"]["bodies"][0]
    assert eff["base_mass"] == 0.0
    assert eff["mass"] == 1.5 and eff["principal_moments"] == [0.02, 0.02, 0.02]


def test_maximal_inertia_without_mass_makes_a_static_body():
    # changeDynamics(localInertiaDiagonal=...) on a maximal-coordinate body without mass= sets
    # its mass to 0; the adapter passes both and reads the mass back.
    cid = p.connect(p.DIRECT)
    try:
        uid = p.createMultiBody(2.0, -1, useMaximalCoordinates=True, physicsClientId=cid)
        p.changeDynamics(uid, -1, localInertiaDiagonal=[1.0, 2.0, 3.0], physicsClientId=cid)
        assert p.getDynamicsInfo(uid, -1, physicsClientId=cid)[0] == 0.0
    finally:
        p.disconnect(cid)
    traj = _run(_scene(3, 0.01, 1e-3, _body3d()), "maximal")
    assert traj.meta["effective"]["bodies"][0]["mass"] == 2.0


# -- rotation per step ----------------------------------------------------------------------------
def _capped_turn(turn: float) -> float:
    """Angle PyBullet turns in one step for a requested turn |omega| h (a documented measurement).

    Above ANGULAR_MOTION_THRESHOLD = pi/4 Bullet clamps the angle but keeps the axis scaled by
    the unclamped omega: q = (sin(c/2) turn/c * axis, cos(c/2)), normalised, c = pi/4.
    """
    c = math.pi / 4
    if turn <= c:
        return turn
    return 2 * math.atan2(math.sin(c / 2) * turn / c, math.cos(c / 2))


@pytest.mark.parametrize("integrator", INTEGRATORS)
def test_rotation_per_step_cap_is_measured_and_flagged(integrator):
    h = 1e-3
    for spin, warned in ((150.0, False), (1000.0, True)):
        omega = spin * _principal_axis_world(2)
        scene = _scene(3, h, h, _body3d(omega=omega))
        traj = _run(scene, integrator)
        turned = quat_angle_between(traj.quat[0, 0], traj.quat[1, 0])
        # 150 rad/s: exact exponential map (0.15 rad). 1000 rad/s: 0.9706 rad, not 1.
        assert turned == pytest.approx(_capped_turn(spin * h), abs=1e-12)
        assert bool(traj.meta["effective"]["warnings"]) is warned
    assert _capped_turn(1.0) == pytest.approx(0.97064, abs=1e-5)


# -- trap 7: the two integrators on a tumbling body ---------------------------------------------
def test_tumbling_energy_drift_by_integrator():
    # A documented measurement (ENGINES.md trap 7): inertia (1, 2, 3), spin 5 rad/s about the
    # middle axis with a 0.01 rad/s nudge, 10 s. Multibody (explicit gyroscopic term) gains
    # energy, maximal (implicit) loses it: measured +1.165 % and -1.145 % at dt = 1e-3, halving
    # with dt (first order). Energy from the trajectory (crosscheck.quantities), never PyBullet.
    body = f"""
[[bodies]]
name = "b"
shape = {{ sphere = {{ radius = 0.1 }} }}
mass = 1.0
inertia = [1.0, 2.0, 3.0]
position = [0.0, 0.0, 0.0]
orientation = {_j(Q0)}
angular_velocity = {_j(R0 @ np.array([0.01, 5.0, 0.0]))}
"""
    drift = {}
    for integrator in INTEGRATORS:
        for h in (1e-3, 5e-4):
            scene = _scene(3, 10.0, h, body, sample_every=0.1)
            traj = _run(scene, integrator, h)
            e = quantities.kinetic_energy(scene, traj)
            drift[integrator, h] = e[-1] / e[0] - 1
    assert 0.010 < drift["multibody", 1e-3] < 0.013
    assert -0.013 < drift["maximal", 1e-3] < -0.010
    for integrator in INTEGRATORS:  # first order: half the step, half the drift
        assert drift[integrator, 1e-3] / drift[integrator, 5e-4] == pytest.approx(2.0, abs=0.1)


# -- per-step forces: their time level ----------------------------------------------------------
@pytest.mark.parametrize("integrator", INTEGRATORS)
@pytest.mark.parametrize("dimension", (2, 3))
def test_spring_drag_and_load_time_levels(integrator, dimension):
    # One body, spring attached at its centre of mass to an anchor, linear drag and a constant
    # load, all along x. PyBullet's step with forces from the start-of-step state is
    #   v_{n+1} = v_n + h (-k (x_n - a) - c v_n + F) / m,   x_{n+1} = x_n + h v_{n+1},
    # reproduced here exactly; evaluating the spring at x_{n+1} or the drag at v_{n+1} differs
    # by O(h) per step (1e-4 after 2000 steps), far above the 1e-10 round-off allowance.
    h, steps = 1e-3, 2000
    k, c, force, anchor = 50.0, 0.4, 1.5, 0.5
    if dimension == 3:
        com_w = np.array([1.0, 0.0, 0.0])
        bodies = _body3d(position=com_w - R0 @ COM)
        attach, anchor_pt, load = COM, [anchor, 0.0, 0.0], [force, 0.0, 0.0]
    else:
        com_w = np.array([1.0, 0.0])
        com2 = np.array([0.04, -0.03])
        r = np.array([[math.cos(2.5), -math.sin(2.5)], [math.sin(2.5), math.cos(2.5)]])
        bodies = _body2d(position=com_w - r @ com2)
        attach, anchor_pt, load = com2, [anchor, 0.0], [force, 0.0]
    effects = f"""
[[effects.springs]]
a = "{'b' if dimension == 3 else 'plate'}"
attach_a = {_j(attach)}
anchor = {_j(anchor_pt)}
stiffness = {k!r}
[[effects.drag]]
linear = {c!r}
[[effects.loads]]
body = "{'b' if dimension == 3 else 'plate'}"
force = {_j(load)}
"""
    m = 2.0 if dimension == 3 else 1.5  # the helpers' masses
    scene = _scene(dimension, steps * h, h, bodies, effects=effects, sample_every=0.1)
    traj = _run(scene, integrator)
    x, v = 1.0, 0.0
    xs, vs = [x], [v]
    for n in range(1, steps + 1):
        v = v + h * (-k * (x - anchor) - c * v + force) / m
        x = x + h * v
        if n % 100 == 0:
            xs.append(x)
            vs.append(v)
    np.testing.assert_allclose(traj.com[:, 0, 0], xs, rtol=0, atol=1e-10)
    np.testing.assert_allclose(traj.vel[:, 0, 0], vs, rtol=0, atol=1e-10)
    # Everything acts along x through the centre of mass: nothing else moves.
    np.testing.assert_allclose(traj.com[:, 0, 1:], np.broadcast_to(traj.com[0, 0, 1:],
                               traj.com[:, 0, 1:].shape), rtol=0, atol=1e-12)
    assert np.max(np.abs(traj.omega)) <= 1e-12


def _hanging_at_rest_3d():
    """A body hanging still from a spring attached off its centre of mass, rotated full inertia.

    Equilibrium: the spring holds m g at the attachment point (stretch m g / k below the anchor)
    and the centre of mass hangs straight below it. An attachment point taken in the wrong frame
    (body vs inertial vs world) puts a lever arm on the spring force: the body swings at O(1).
    """
    m, k = 2.0, 400.0
    attach = np.array([0.12, 0.05, -0.04])  # body frame
    anchor = np.array([0.3, -0.1, 2.0])
    arm = attach - COM
    # Rotation taking the arm to +z (the attachment straight above the COM), then any turn
    # about z: Rodrigues from arm to z, composed with a turn of 0.8 rad about z.
    a = arm / np.linalg.norm(arm)
    z = np.array([0.0, 0.0, 1.0])
    vx = np.cross(a, z)
    s, cth = np.linalg.norm(vx), a @ z
    kx = np.array([[0, -vx[2], vx[1]], [vx[2], 0, -vx[0]], [-vx[1], vx[0], 0]])
    r_align = np.eye(3) + kx + kx @ kx * ((1 - cth) / s**2)
    r_turn = quat_to_matrix(axis_angle_to_quat(z, 0.8))
    rot = r_turn @ r_align
    p_attach = anchor - np.array([0.0, 0.0, m * G / k])
    com_w = p_attach - np.linalg.norm(arm) * z
    position = com_w - rot @ COM
    effects = f"""
gravity = [0.0, 0.0, {-G}]
[[effects.springs]]
a = "b"
attach_a = {_j(attach)}
anchor = {_j(anchor)}
stiffness = {k!r}
"""
    return _scene(3, 1.0, 1e-3, _body3d(mass=m, position=position,
                                         orientation=matrix_to_quat(rot)),
                  effects=effects, sample_every=0.1), com_w


@pytest.mark.parametrize("integrator", INTEGRATORS)
def test_spring_attachment_frame_3d(integrator):
    scene, com_w = _hanging_at_rest_3d()
    traj = _run(scene, integrator)
    # At equilibrium every step adds forces that cancel to round-off (~1e-15 of m g): over 1000
    # steps the body moves by < 1e-12. A wrong attachment frame moves it by centimetres.
    np.testing.assert_allclose(traj.com[:, 0], np.broadcast_to(com_w, (len(traj.t), 3)), rtol=0,
                               atol=1e-10)
    assert np.max(np.abs(traj.omega)) <= 1e-9


@pytest.mark.parametrize("integrator", INTEGRATORS)
def test_spring_attachment_frame_2d(integrator):
    # The 2D version: attachment at a body-frame point off the centre of mass, the body turned
    # so that the centre of mass hangs straight below it.
    m, k, moment = 1.5, 300.0, 0.02
    com2 = np.array([0.04, -0.03])
    attach = np.array([-0.1, 0.06])
    arm = attach - com2
    angle = math.pi / 2 - math.atan2(arm[1], arm[0])  # turns the arm to +y
    anchor = np.array([0.5, 2.0])
    p_attach = anchor - np.array([0.0, m * G / k])
    com_w = p_attach - np.array([0.0, np.linalg.norm(arm)])
    r = np.array([[math.cos(angle), -math.sin(angle)], [math.sin(angle), math.cos(angle)]])
    scene = _scene(2, 1.0, 1e-3, _body2d(mass=m, moment=moment, com=com2,
                                         position=com_w - r @ com2, angle=angle),
                   effects=f"""
gravity = [0.0, {-G}]
[[effects.springs]]
a = "plate"
attach_a = {_j(attach)}
anchor = {_j(anchor)}
stiffness = {k!r}
""", sample_every=0.1)
    traj = _run(scene, integrator)
    np.testing.assert_allclose(traj.com[:, 0], np.broadcast_to(com_w, (len(traj.t), 2)), rtol=0,
                               atol=1e-10)
    np.testing.assert_allclose(traj.angle[:, 0], angle, rtol=0, atol=1e-9)


# -- 2D specifics ---------------------------------------------------------------------------------
@pytest.mark.parametrize("integrator", INTEGRATORS)
def test_2d_out_of_plane_drift_is_kept_and_zero(integrator):
    # A 2D scene with everything in-plane (gravity, a spring off the centre of mass, drag, a
    # torque, spin): the planar joints keep the plane by construction, the free maximal body
    # because every force and torque is in-plane and its isotropic inertia has no gyroscopic
    # term. The drift is read from PyBullet (link / base state) and must be round-off.
    scene = _scene(2, 1.0, 1e-3, _body2d(velocity=(0.5, 1.0), omega=3.0), effects=f"""
gravity = [0.0, {-G}]
[[effects.springs]]
a = "plate"
attach_a = [0.1, 0.05]
anchor = [0.0, 2.0]
stiffness = 40.0
damping = 0.3
rest_length = 0.3
[[effects.drag]]
linear = 0.1
angular = 0.01
[[effects.loads]]
body = "plate"
torque = 0.05
""", sample_every=0.05)
    traj = _run(scene, integrator)
    for key in ("out_of_plane", "out_of_plane_tilt", "out_of_plane_omega"):
        assert traj.extras[key].shape == (len(traj.t), 1)
        assert np.max(np.abs(traj.extras[key])) <= 1e-12, key
    # It moved: the test is not passed by a body at rest.
    assert np.linalg.norm(traj.com[-1, 0] - traj.com[0, 0]) > 0.1


def test_2d_multibody_and_maximal_agree():
    # Same scheme (velocity first, forces from the start of the step), the same forces and no
    # gyroscopic term in the plane: the two kinds of body may differ only by round-off in how
    # each integrates (joint coordinates vs quaternion). 1000 steps of a mildly unstable
    # (spring-pendulum) flow: measured 1e-13; 1e-9 allows growth.
    scene = _scene(2, 1.0, 1e-3, _body2d(velocity=(0.5, 1.0), omega=3.0), effects=f"""
gravity = [0.0, {-G}]
[[effects.springs]]
a = "plate"
attach_a = [0.1, 0.05]
anchor = [0.0, 2.0]
stiffness = 40.0
rest_length = 0.3
""", sample_every=0.05)
    a, b = _run(scene, "multibody"), _run(scene, "maximal")
    np.testing.assert_allclose(a.com, b.com, rtol=0, atol=1e-9)
    np.testing.assert_allclose(a.angle, b.angle, rtol=0, atol=1e-9)
    np.testing.assert_allclose(a.omega, b.omega, rtol=0, atol=1e-8)


@pytest.mark.parametrize("integrator", INTEGRATORS)
def test_2d_fast_spin_sampled_coarsely_stays_unwrapped(integrator):
    # 50 rad/s sampled every 0.1 s turns 5 rad between samples: more than half a turn, which
    # np.unwrap would fold back to -1.28 rad. The angle must be theta0 + w t.
    scene = _scene(2, 1.0, 1e-3, _body2d(omega=50.0), sample_every=0.1)
    traj = _run(scene, integrator)
    np.testing.assert_allclose(traj.angle[:, 0], 2.5 + 50.0 * traj.t, rtol=0, atol=1e-10)


# -- failure and determinism --------------------------------------------------------------------
def test_blow_up_is_a_reported_failure():
    # Symplectic Euler on a spring is stable only for sqrt(k/m) h < 2: k/m = 1e8 at h = 1e-3 is
    # 10, so the amplitude grows ~100-fold per step and overflows within a few hundred steps.
    scene = _scene(3, 2.0, 1e-3, _body3d(), sample_every=1e-3, effects="""
[[effects.springs]]
a = "b"
anchor = [0.0, 0.0, 0.0]
stiffness = 2e8
""")
    from crosscheck.engines.base import sampling_plan
    from crosscheck.engines.driver import record

    # The engine's own state overflows: with the driver's energy-runaway cut off, the run
    # ends at the first non-finite sample; with it on (the default), earlier.
    session = get_engine("pybullet").open(scene, "multibody", 1e-3)
    traj, _ = record(session, scene, sampling_plan(scene, 1e-3), runaway_factor=np.inf)
    session.close()
    assert traj.failure is not None and traj.failure["reason"] == "non-finite state"
    cut = get_engine("pybullet").run(scene, "multibody", 1e-3)
    assert cut.failure["reason"].startswith("energy runaway")
    assert cut.failure["time"] < traj.failure["time"]
    assert 0 < traj.failure["time"] < 2.0
    assert np.all(np.isfinite(traj.com)) and len(traj.t) < 2001


def test_runs_are_bit_identical():
    scene = _scene(3, 0.5, 1e-3, _body3d(velocity=(1, 2, 3), omega=(3.0, -7.0, 5.0)),
                   effects=f"gravity = [0, 0, {-G}]", sample_every=0.05)
    a, b = _run(scene, "multibody"), _run(scene, "multibody")
    assert np.array_equal(a.com, b.com) and np.array_equal(a.quat, b.quat)
    assert np.array_equal(a.omega, b.omega)
