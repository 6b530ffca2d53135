"""MuJoCo adapter: its traps (ENGINES.md 2, 3, 4, 7, 8, 10), the model it compiles, how it maps
springs, drag and loads, its options, stepping and failure handling.

Every trap test carries a sensitivity check: the naive reading the trap invites is computed
alongside and shown to differ by far more than the tolerance, so the test would fail if the
adapter fell into the trap.
"""

from __future__ import annotations

import json
import math
from dataclasses import replace
from pathlib import Path

import mujoco
import numpy as np
import pytest

from crosscheck import quantities
from crosscheck.engines import get_engine
from crosscheck.engines.mujoco import INTEGRATORS, MujocoEngine, MujocoModel
from crosscheck.errors import CaseError
from crosscheck.rotations import axis_angle_to_quat, quat_angle_between, quat_to_matrix
from crosscheck.scene.loader import load_case, load_case_text

CASES = Path(__file__).resolve().parents[2] / "cases"
ENGINE = MujocoEngine()

AXES = quat_to_matrix(axis_angle_to_quat([0.3, -1.0, 0.5], 0.9))
INERTIA = AXES @ np.diag([0.010, 0.017, 0.022]) @ AXES.T  # full tensor in body axes
COM = [0.05, -0.03, 0.02]


def _j(x) -> str:
    return json.dumps(np.asarray(x, float).tolist())


def scene3d(duration=1.0, dt=1e-3, sample_every=0.01, com=COM, inertia=INERTIA,
            velocity=(0.4, -0.2, 0.1), omega=(3.0, -7.0, 5.0), effects="", options="",
            orientation=(1.0, 2.0, 3.0, 0.7), extra_bodies=""):
    axis_angle = f"{{ axis = {_j(orientation[:3])}, angle = {orientation[3]} }}"
    return load_case_text(f"""
[case]
name = "mujoco-test"
dimension = 3
[run]
duration = {duration}
dt = {dt}
sample_every = {sample_every}
[effects]
{effects}
[[bodies]]
name = "body"
shape = {{ box = {{ size = [0.3, 0.2, 0.1] }} }}
mass = 2.0
com = {_j(com)}
inertia = {_j(inertia)}
position = [0.1, -0.2, 0.5]
orientation = {axis_angle}
velocity = {_j(velocity)}
angular_velocity = {_j(omega)}
{extra_bodies}
{options}
""")


def fresh(sim: MujocoModel, index=0):
    """MuJoCo's own view of body ``index`` after refreshing kinematics and velocities:
    centre of mass (xipos), body-frame quaternion (xquat), and the 6D velocity at the centre of
    mass in world orientation (mj_objectVelocity, rot:lin)."""
    m, d = sim.model, sim.data
    mujoco.mj_forward(m, d)
    bid = sim.bodies[index].body_id
    vel6 = np.zeros(6)
    mujoco.mj_objectVelocity(m, d, mujoco.mjtObj.mjOBJ_BODY, bid, vel6, 0)
    return d.xipos[bid].copy(), d.xquat[bid].copy(), vel6[3:].copy(), vel6[:3].copy()


# -- the compiled model ----------------------------------------------------------------------------
def test_model_carries_the_scene_exactly():
    scene = scene3d(effects="gravity = [0.0, 0.0, -9.81]")
    sim = MujocoModel(scene, "rk4", 1e-3)
    m, bid = sim.model, sim.bodies[0].body_id
    # Values pass through MJCF text as shortest round-trip decimals: bit-exact.
    assert m.body_mass[bid] == 2.0
    np.testing.assert_array_equal(m.body_ipos[bid], COM)
    # Principal moments and axes from NumPy's eigh: the tensor comes back to round-off.
    r = quat_to_matrix(np.array(m.body_iquat[bid]))
    rebuilt = r @ np.diag(m.body_inertia[bid]) @ r.T
    np.testing.assert_allclose(rebuilt, INERTIA, rtol=0, atol=1e-16)
    assert m.ngeom == 0 and m.nq == 7 and m.nv == 6
    assert m.opt.timestep == 1e-3
    np.testing.assert_array_equal(m.opt.gravity, [0.0, 0.0, -9.81])
    flags = int(m.opt.disableflags)
    assert flags & int(mujoco.mjtDisableBit.mjDSBL_CONTACT)
    assert flags & int(mujoco.mjtDisableBit.mjDSBL_AUTORESET)
    assert not flags & int(mujoco.mjtDisableBit.mjDSBL_GRAVITY)
    eff = sim.effective()
    assert eff["bodies"][0]["inertia_rel_error"] < 1e-14
    assert eff["density"] == 0.0 and eff["viscosity"] == 0.0 and eff["wind"] == [0.0] * 3


@pytest.mark.parametrize("integrator", INTEGRATORS)
def test_integrator_names_select_mujoco_integrators(integrator):
    sim = MujocoModel(scene3d(), integrator, 1e-3)
    expected = {"euler": "mjINT_EULER", "rk4": "mjINT_RK4", "implicit": "mjINT_IMPLICIT",
                "implicitfast": "mjINT_IMPLICITFAST", "discrete": "mjINT_DISCRETE"}[integrator]
    assert mujoco.mjtIntegrator(int(sim.model.opt.integrator)).name == expected
    assert sim.effective()["integrator"] == expected


def test_capabilities_and_version():
    caps = ENGINE.capabilities()
    assert caps.default_integrator == "euler"  # MuJoCo's own default
    base = {"euler", "rk4", "implicit", "implicitfast", "discrete"}
    # and each of them with a fluid model, for a fluid case mapped to MuJoCo's medium
    medium = {f"{i}+{m}" for i in base for m in ("inertia_box", "ellipsoid")}
    assert set(caps.integrators) == base | medium
    assert caps.dimensions == {2, 3}
    assert {"sphere", "box", "capsule", "cylinder", "mesh", "circle", "polygon"} <= caps.shapes
    assert "contact" in caps.effects
    assert ENGINE.version() == mujoco.__version__
    assert get_engine("mujoco").name == "mujoco"


# -- traps 2 and 3: reference point and frame of the state -----------------------------------------
@pytest.mark.parametrize("align", [False, True])
def test_initial_state_matches_mujoco_own_kinematics(align):
    # The state written into qpos/qvel, read by MuJoCo itself (xipos, xquat, mj_objectVelocity
    # at the centre of mass), is the scene's: an independent check of the set-state conversions.
    options = "[engine_options.mujoco]\nalign_free = true" if align else ""
    scene = scene3d(options=options)
    body = scene.bodies[0]
    sim = ENGINE.build(scene, "euler", 1e-3)
    com, quat, vel, omega = fresh(sim)
    np.testing.assert_allclose(com, body.com_world(), rtol=0, atol=1e-14)
    np.testing.assert_allclose(vel, body.velocity, rtol=0, atol=1e-13)
    np.testing.assert_allclose(omega, body.angular_velocity, rtol=0, atol=1e-13)
    if not align:
        # MuJoCo's body frame is the declared one: xquat is the scene's orientation.
        assert min(np.abs(quat - body.orientation).max(),
                   np.abs(quat + body.orientation).max()) < 1e-15
        # Sensitivity (trap 2): qvel[0:3] is the origin's velocity, qpos[0:3] the origin;
        # (trap 3): qvel[3:6] is body-local. Each naive reading is far off.
        q, v = sim.data.qpos, sim.data.qvel
        assert np.linalg.norm(q[0:3] - body.com_world()) > 0.05
        assert np.linalg.norm(v[0:3] - body.velocity) > 0.3
        assert np.linalg.norm(v[3:6] - body.angular_velocity) > 3.0
    # And the adapter reads it back exactly.
    c2, q2, v2, w2 = sim.state()
    np.testing.assert_allclose(c2[0], body.com_world(), rtol=0, atol=1e-14)
    assert min(np.abs(q2[0] - body.orientation).max(),
               np.abs(q2[0] + body.orientation).max()) < 1e-14
    np.testing.assert_allclose(v2[0], body.velocity, rtol=0, atol=1e-13)
    np.testing.assert_allclose(w2[0], body.angular_velocity, rtol=0, atol=1e-13)


def test_tumbling_state_is_world_frame_and_centre_of_mass():
    # Torque-free tumbling, RK4, non-identity orientation, centre of mass off the origin.
    # L = I_world w about the centre of mass is conserved by RK4 to ~1e-12 here (5th-order local
    # error at h |w| = 0.009); the linear momentum m v_com exactly. Reading qvel[3:6] as world
    # (trap 3) makes L wander by O(|L|); reading qvel[0:3] as the centre of mass velocity
    # (trap 2) makes p oscillate by m |w| |com| ~ 1.
    scene = scene3d(duration=2.0)
    traj = ENGINE.run(scene, "rk4", 1e-3)
    L = quantities.angular_momentum(scene, traj, about="com")
    p = quantities.linear_momentum(scene, traj)
    assert np.max(np.linalg.norm(L - L[0], axis=1)) <= 1e-10 * np.linalg.norm(L[0])
    assert np.max(np.linalg.norm(p - p[0], axis=1)) <= 1e-10 * np.linalg.norm(p[0])

    sim = ENGINE.build(scene, "rk4", 1e-3)
    naive_L, naive_p = [], []
    for _ in range(20):
        sim.advance(100)
        q, v = sim.data.qpos, sim.data.qvel
        r = quat_to_matrix(q[3:7])
        naive_L.append(r @ INERTIA @ r.T @ v[3:6])  # body-local omega taken as world
        naive_p.append(2.0 * v[0:3])  # origin velocity taken as the COM's
    spread = lambda a: np.max(np.linalg.norm(np.array(a) - a[0], axis=1))  # noqa: E731
    assert spread(naive_L) > 0.1 * np.linalg.norm(L[0])
    assert spread(naive_p) > 0.1


# -- trap 4: derived arrays are stale after mj_step -----------------------------------------------
def test_samples_are_read_at_the_sample_time_not_one_step_late():
    # Uniform translation plus a spin: every integrator moves the centre of mass exactly for a
    # body whose centre of mass is at its origin, so com(t) = x0 + v t to round-off. A reader of
    # xipos right after mj_step would lag by v dt = 4.6e-4 m.
    scene = scene3d(com=[0, 0, 0], inertia=np.eye(3) * 0.01)
    body = scene.bodies[0]
    traj = ENGINE.run(scene, "euler", 1e-3)
    exact = body.com_world() + traj.t[:, None] * body.velocity
    np.testing.assert_allclose(traj.com[:, 0], exact, rtol=0, atol=1e-12)

    sim = ENGINE.build(scene, "euler", 1e-3)
    bid = sim.bodies[0].body_id
    sim.advance(10)
    stale = sim.data.xipos[bid].copy()
    com_now = sim.state()[0][0]
    assert np.linalg.norm(stale - com_now) > 0.9 * np.linalg.norm(body.velocity) * 1e-3
    refreshed = fresh(sim)[0]
    np.testing.assert_allclose(com_now, refreshed, rtol=0, atol=1e-14)


@pytest.mark.parametrize("integrator", ["euler", "rk4"])
def test_conversion_after_stepping_equals_mujoco_refreshed(integrator):
    # Throughout a tumbling run, the adapter's reading of qpos/qvel equals MuJoCo's own derived
    # quantities after mj_forward (xipos, xquat, velocity at the centre of mass in world axes).
    scene = scene3d()
    sim = ENGINE.build(scene, integrator, 1e-3)
    for _ in range(5):
        sim.advance(37)
        com, quat, vel, omega = sim.state()
        f_com, f_quat, f_vel, f_omega = fresh(sim)
        np.testing.assert_allclose(com[0], f_com, rtol=0, atol=1e-13)
        assert min(np.abs(quat[0] - f_quat).max(), np.abs(quat[0] + f_quat).max()) < 1e-14
        np.testing.assert_allclose(vel[0], f_vel, rtol=0, atol=1e-12)
        np.testing.assert_allclose(omega[0], f_omega, rtol=0, atol=1e-12)


# -- trap 7: integrator families on a tumbling body ----------------------------------------------
def test_integrator_families_on_a_tumbling_body():
    # Inertia (1, 2, 3), spin 5 rad/s about the middle axis perturbed by 0.05, 10 s at 1e-3.
    # Measured with mujoco 4.0.0 (as ENGINES.md): Euler (explicit gyroscopic term) gains 1.2 %,
    # implicit, implicitfast (gyroscopic derivatives reinstated for free bodies) and discrete
    # lose 1.2 %, RK4 keeps it to 1e-13. The signs and sizes identify the integrator that
    # actually ran: a name mapped to the wrong MuJoCo integrator fails here.
    scene = scene3d(duration=10.0, com=[0, 0, 0], inertia=np.diag([1.0, 2.0, 3.0]),
                    omega=quat_to_matrix(axis_angle_to_quat([1, 2, 3], 0.7)) @ [0.05, 5.0, 0.0])
    drift = {}
    for integrator in INTEGRATORS:
        traj = ENGINE.run(scene, integrator, 1e-3)
        e = quantities.kinetic_energy(scene, traj)
        drift[integrator] = e[-1] / e[0] - 1
    assert 0.005 < drift["euler"] < 0.03
    for name in ("implicit", "implicitfast", "discrete"):
        assert -0.03 < drift[name] < -0.005
    assert abs(drift["rk4"]) < 1e-10


# -- trap 8: free fall and the gravity default -----------------------------------------------------
def test_free_fall_case_figures_and_gravity_default():
    scene = load_case(CASES / "rigid3d" / "free_fall.toml")
    z0 = scene.bodies[0].com_world()[2]
    drops = {i: z0 - ENGINE.run(scene, i, 1e-3).com[-1, 0, 2] for i in ("euler", "rk4")}
    assert drops["euler"] == pytest.approx(4.909905, abs=1e-9)  # g h^2 N (N+1) / 2
    assert drops["rk4"] == pytest.approx(4.905, abs=1e-9)  # g t^2 / 2
    # The same scene without gravity: MuJoCo's default -9.81 must not leak in.
    still = ENGINE.run(load_case_text("""
[case]
name = "rest"
dimension = 3
[run]
duration = 1.0
dt = 1e-3
[[bodies]]
name = "ball"
shape = { sphere = { radius = 0.1 } }
mass = 1.0
position = [0.0, 0.0, 10.0]
"""), "euler", 1e-3)
    np.testing.assert_array_equal(still.com[:, 0], np.broadcast_to([0, 0, 10.0], (1001, 3)))
    assert still.meta["effective"]["gravity"] == [0.0, 0.0, 0.0]


# -- trap 10: centre of mass off a free joint's origin ------------------------------------------
@pytest.mark.parametrize("integrator", ["euler", "implicitfast"])
def test_linear_momentum_drift_with_offset_com_is_first_order(integrator):
    # The free joint integrates the body origin; with the centre of mass off it, the
    # first-order integrators do not conserve linear momentum (MuJoCo's numerics, not the
    # adapter's reading): the drift halves with the step. RK4 keeps it to 1e-11 and the aligned
    # frame (centre of mass, principal axes; engine option align_free) to round-off.
    scene = scene3d(inertia=np.diag([1.0, 2.0, 3.0]), omega=(1.0, 3.0, -2.0))

    def drift(s, integ, dt):
        traj = ENGINE.run(s, integ, dt)
        p = quantities.linear_momentum(s, traj)
        return np.max(np.linalg.norm(p - p[0], axis=1)) / np.linalg.norm(p[0])

    coarse, fine = drift(scene, integrator, 1e-3), drift(scene, integrator, 5e-4)
    assert 1e-3 < coarse < 1e-2
    assert math.log2(coarse / fine) == pytest.approx(1.0, abs=0.05)
    assert drift(scene, "rk4", 1e-3) < 1e-11
    aligned = scene3d(inertia=np.diag([1.0, 2.0, 3.0]), omega=(1.0, 3.0, -2.0),
                      options="[engine_options.mujoco]\nalign_free = true")
    assert drift(aligned, integrator, 1e-3) < 1e-14


def test_aligned_frame_round_trips_and_tracks_reference(harness):
    # align_free changes MuJoCo's body frame, not the reported one: the declared-frame state
    # comes back exactly, and the motion (RK4) is the reference's.
    scene = scene3d(duration=1.0, options="[engine_options.mujoco]\nalign_free = true")
    body = scene.bodies[0]
    traj = ENGINE.run(scene, "rk4", 1e-3)
    np.testing.assert_allclose(traj.com[0, 0], body.com_world(), rtol=0, atol=1e-12)
    assert min(np.abs(traj.quat[0, 0] - body.orientation).max(),
               np.abs(traj.quat[0, 0] + body.orientation).max()) < 1e-12
    np.testing.assert_allclose(traj.omega[0, 0], body.angular_velocity, rtol=0, atol=1e-12)
    ref = harness.reference(scene, traj.t)
    assert np.max(np.abs(traj.com - ref.com)) < 1e-9
    assert np.max(quat_angle_between(traj.quat, ref.quat)) < 1e-9
    assert traj.meta["effective"]["bodies"][0]["frame"].startswith("aligned")


# -- springs, drag, loads against the Newton-Euler reference -------------------------------------
@pytest.fixture
def errors(harness):
    """(trajectory, max error of position and orientation against the Newton-Euler reference)."""
    return lambda scene, integrator, dt: _errors(harness.reference, scene, integrator, dt)


def _errors(reference, scene, integrator, dt):
    traj = ENGINE.run(scene, integrator, dt)
    assert traj.failure is None
    ref = reference(scene, traj.t)
    if scene.dimension == 2:
        return traj, max(np.max(np.abs(traj.com - ref.com)),
                         np.max(np.abs(traj.angle - ref.angle)))
    return traj, max(np.max(np.abs(traj.com - ref.com)),
                     np.max(quat_angle_between(traj.quat, ref.quat)))


SPRING = """
[[effects.springs]]
a = "body"
attach_a = [0.12, 0.05, -0.04]
anchor = [0.3, 0.1, 0.9]
stiffness = 40.0
damping = 0.3
rest_length = 0.2
"""


@pytest.mark.parametrize("align", [False, True])
def test_spring_is_a_tendon_between_the_declared_points(align, errors):
    # Attachment point off the centre of mass, on a rotated body with a full inertia: the site
    # must sit at the declared body-frame point (a site placed relative to the centre of mass
    # would be 0.06 m off). Tendons act inside each RK4 stage, so the error is fourth order:
    # measured ~1e-9 at dt = 1e-3; the limit allows 100x, and the order is checked.
    options = "[engine_options.mujoco]\nalign_free = true" if align else ""
    scene = scene3d(effects=SPRING, options=options)
    traj, coarse = errors(scene, "rk4", 1e-3)
    _, fine = errors(scene, "rk4", 5e-4)
    assert coarse < 1e-7
    assert math.log2(coarse / fine) > 3.5
    spring = traj.meta["effective"]["springs"][0]
    assert spring == {"mechanism": "spatial tendon", "stiffness": 40.0, "damping": 0.3,
                      "springlength": [0.2, 0.2]}


def test_two_body_spring_case_conserves_momentum_and_converges(errors):
    # The committed case: an off-centre spring between two tumbling boxes. Tendon forces are
    # equal and opposite: linear momentum to round-off (1e-13 of ~0.5 kg m/s) for every
    # integrator; RK4 converges to the reference at fourth order.
    scene = load_case(CASES / "rigid3d" / "two_body_spring.toml")
    scene = replace(scene, run=replace(scene.run, duration=2.0))
    for integrator in INTEGRATORS:
        if integrator == "discrete":
            continue  # implicit tendon stiffness (h^2 K) is applied per dof: checked below
        traj = ENGINE.run(scene, integrator, 1e-3)
        p = quantities.linear_momentum(scene, traj)
        assert np.max(np.abs(p - p[0])) < 1e-13, integrator
    _, coarse = errors(scene, "rk4", 1e-3)
    _, fine = errors(scene, "rk4", 5e-4)
    assert coarse < 1e-4
    assert math.log2(coarse / fine) > 3.5


def test_discrete_integrator_momentum_with_tendons_is_documented_drift():
    # MuJoCo's discrete integrator folds tendon stiffness into M + h^2 K; for a tendon between
    # two free bodies the linear momentum then drifts slightly (measured 3e-9 kg m/s over 5 s).
    # Recorded so a change in MuJoCo shows up; far below any case tolerance.
    scene = load_case(CASES / "rigid3d" / "two_body_spring.toml")
    traj = ENGINE.run(scene, "discrete", 1e-3)
    p = quantities.linear_momentum(scene, traj)
    assert np.max(np.abs(p - p[0])) < 1e-7


DRAG = """
[[effects.drag]]
linear = 0.8
angular = 0.02
"""


def test_drag_on_centred_body_is_exact_joint_damping(errors):
    # Centre of mass at the origin: joint damping on the free joint is exactly -c v and -c_a w
    # (isotropic damping of the body-local omega is the same in any frame), evaluated in every
    # RK4 stage: agreement with the reference at its own 1e-12 level (measured 8e-12; the
    # per-step route errs by 1e-5 on this scene, see the next tests).
    scene = scene3d(com=[0, 0, 0], effects=DRAG)
    traj, coarse = errors(scene, "rk4", 1e-3)
    body = traj.meta["effective"]["bodies"][0]
    assert body["linear_drag"] == body["angular_drag"] == "joint damping"
    assert body["dof_damping"] == [0.8] * 3 + [0.02] * 3
    assert traj.meta["effective"]["stepping"].startswith("compiled loop")
    assert coarse < 1e-10


def test_drag_on_offset_body_is_per_step_and_first_order(errors):
    # Centre of mass off the origin: the free joint's translational dofs carry the origin's
    # velocity, so linear drag goes through xfrc_applied, computed at the start of each step and
    # held over it (also across RK4's stages): first order in the drag term, error ~ c/m h T
    # |v| / 2 ~ 1e-4; halving h halves it. With align_free the same scene is joint damping again
    # and fourth order.
    scene = scene3d(effects=DRAG)
    traj, coarse = errors(scene, "rk4", 1e-3)
    _, fine = errors(scene, "rk4", 5e-4)
    body = traj.meta["effective"]["bodies"][0]
    assert body["linear_drag"] == "per-step xfrc_applied"
    assert body["angular_drag"] == "joint damping"
    assert traj.meta["effective"]["stepping"].startswith("python loop")
    assert coarse < 1e-3
    assert math.log2(coarse / fine) == pytest.approx(1.0, abs=0.2)
    aligned = scene3d(effects=DRAG, options="[engine_options.mujoco]\nalign_free = true")
    traj, coarse = errors(aligned, "rk4", 1e-3)
    assert traj.meta["effective"]["bodies"][0]["linear_drag"] == "joint damping"
    assert coarse < 1e-8


def test_drag_per_step_option_matches_reference_at_first_order(errors):
    # drag = "per_step" forces the per-step route even where joint damping is exact; its
    # Euler-level error shrinks at first order toward the same reference.
    scene = scene3d(com=[0, 0, 0], effects=DRAG,
                    options='[engine_options.mujoco]\ndrag = "per_step"')
    traj, coarse = errors(scene, "euler", 1e-3)
    _, fine = errors(scene, "euler", 5e-4)
    assert traj.meta["effective"]["bodies"][0]["linear_drag"] == "per-step xfrc_applied"
    assert math.log2(coarse / fine) == pytest.approx(1.0, abs=0.2)


def test_loads_act_at_the_centre_of_mass_in_world_frame(errors):
    # A force through the centre of mass of an offset body induces no rotation (a force at the
    # origin would spin it at |com x F| / I ~ 10 rad/s after 1 s); a world torque on a body with
    # isotropic inertia gives w = tau t / I exactly, whatever the orientation (a body-frame
    # torque would point elsewhere).
    load = """
[[effects.loads]]
body = "body"
force = [1.0, -2.0, 0.5]
torque = [0.02, 0.0, -0.01]
"""
    scene = scene3d(inertia=np.eye(3) * 0.01, velocity=(0, 0, 0), omega=(0, 0, 0), effects=load)
    for integrator in ("euler", "rk4"):
        traj = ENGINE.run(scene, integrator, 1e-3)
        np.testing.assert_allclose(traj.omega[:, 0], traj.t[:, None] * [2.0, 0.0, -1.0],
                                   rtol=0, atol=1e-12)
    traj, err = errors(scene, "rk4", 1e-3)
    assert err < 1e-9  # constant loads are exact for RK4 up to the rotation coupling
    # Constant loads need no per-step Python: xfrc_applied set once (passed as constant
    # controls to mujoco.rollout).
    assert traj.meta["effective"]["stepping"].startswith("compiled loop")


# -- 2D: planar joints through the centre of mass ------------------------------------------------
def scene2d(effects="", duration=2.0):
    return load_case_text(f"""
[case]
name = "planar"
dimension = 2
[run]
duration = {duration}
dt = 1e-3
sample_every = 0.01
[effects]
{effects}
[[bodies]]
name = "plate"
shape = {{ box = {{ size = [0.3, 0.1] }} }}
mass = 1.5
com = [0.04, -0.03]
position = [0.2, 1.0]
orientation = 0.4
velocity = [1.0, -0.5]
angular_velocity = 6.0
""")


def test_planar_hinge_at_centre_of_mass_conserves_momentum():
    # Slides measure the centre of mass, so even first-order integrators move it exactly (a
    # hinge at the body origin would couple translation and rotation as a free joint does).
    scene = scene2d()
    body = scene.bodies[0]
    for integrator in INTEGRATORS:
        traj = ENGINE.run(scene, integrator, 1e-3)
        exact = body.com_world() + traj.t[:, None] * body.velocity
        np.testing.assert_allclose(traj.com[:, 0], exact, rtol=0, atol=1e-12)
        np.testing.assert_allclose(traj.angle[:, 0], 0.4 + 6.0 * traj.t, rtol=0, atol=1e-12)
    assert traj.meta["effective"]["bodies"][0]["joint"].startswith("planar")


def test_planar_spring_drag_and_load_track_reference(errors):
    effects = """
gravity = [0.0, -9.81]
[[effects.springs]]
a = "plate"
attach_a = [0.15, 0.05]
anchor = [0.0, 1.5]
stiffness = 30.0
damping = 0.2
rest_length = 0.3
[[effects.drag]]
linear = 0.5
angular = 0.01
[[effects.loads]]
body = "plate"
force = [0.5, 0.0]
torque = 0.05
"""
    scene = scene2d(effects)
    traj, coarse = errors(scene, "rk4", 1e-3)
    _, fine = errors(scene, "rk4", 5e-4)
    assert traj.meta["effective"]["bodies"][0]["linear_drag"] == "joint damping"
    assert coarse < 1e-7 and math.log2(coarse / fine) > 3.5


# -- options, applicability, stepping, failure -----------------------------------------------------
def test_engine_options_known_applied_unknown_refused():
    scene = scene3d(options='[engine_options.mujoco]\njacobian = "dense"\neulerdamp = false')
    traj = ENGINE.run(scene, "euler", 1e-3)
    eff = traj.meta["effective"]
    assert eff["jacobian"] == "mjJAC_DENSE"
    assert "mjDSBL_EULERDAMP" in eff["disableflags"]
    with pytest.raises(CaseError, match=r"engine_options\.mujoco\.solver_iterations"):
        ENGINE.run(scene3d(options="[engine_options.mujoco]\nsolver_iterations = 50"), "euler",
                   1e-3)
    with pytest.raises(CaseError, match=r"engine_options\.mujoco\.jacobian.*one of"):
        ENGINE.not_applicable(scene3d(options='[engine_options.mujoco]\njacobian = "fast"'),
                              "euler")


def test_integrators_applicable():
    # Contact scenes are tested in test_mujoco_contact.py.
    assert ENGINE.not_applicable(scene3d(), "verlet") is not None
    assert ENGINE.not_applicable(scene3d(), "rk4") is None


LOAD = """
[[effects.loads]]
body = "body"
force = [1.0, -2.0, 0.5]
torque = [0.02, 0.0, -0.01]
"""


@pytest.mark.parametrize("effects", [SPRING, SPRING + LOAD], ids=["spring", "spring+load"])
def test_compiled_nstep_and_single_steps_are_bit_identical(effects):
    # The fused fast path (a compiled loop calling the C mj_step), the driver's generic loop
    # (mj_step(m, d, nstep=k) per sample) and k single mj_step calls are the same arithmetic:
    # bit-identical samples. Runs repeat bit for bit.
    scene = scene3d(effects=effects)
    stepped = scene3d(effects=effects, options='[engine_options.mujoco]\nstepping = "nstep"')
    a, b = ENGINE.run(scene, "rk4", 1e-3), ENGINE.run(stepped, "rk4", 1e-3)
    assert a.meta["effective"]["stepping"].startswith("compiled loop")
    assert b.meta["effective"]["stepping"].startswith("mj_step")
    for name in ("com", "quat", "vel", "omega"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name))
    again = ENGINE.run(scene, "rk4", 1e-3)
    np.testing.assert_array_equal(again.quat, a.quat)

    sim = ENGINE.build(scene, "rk4", 1e-3)
    single = ENGINE.build(scene, "rk4", 1e-3)
    sim.advance(250)
    for _ in range(250):
        mujoco.mj_step(single.model, single.data)
    np.testing.assert_array_equal(sim.data.qpos, single.data.qpos)
    np.testing.assert_array_equal(sim.data.qvel, single.data.qvel)


def test_meta_reads_settings_back():
    scene = scene3d(effects="gravity = [0.0, 0.0, -9.81]")
    traj = ENGINE.run(scene, "implicitfast", 2e-3)
    meta = traj.meta
    assert meta["engine"] == "mujoco" and meta["engine_version"] == mujoco.__version__
    assert meta["integrator"] == "implicitfast" and meta["dt"] == 2e-3
    eff = meta["effective"]
    assert eff["timestep"] == 2e-3 and eff["integrator"] == "mjINT_IMPLICITFAST"
    assert eff["steps_per_sample"] == 5 and eff["ngeom"] == 0
    assert meta["steps"] == 500 and meta["failure"] is None
    np.testing.assert_allclose(np.diff(traj.t), 0.01, rtol=1e-12)


@pytest.mark.parametrize("stiffness", [80804.0, 80400.5], ids=["w201", "w200.5"])
def test_blow_up_is_a_result_not_a_reset(stiffness, tmp_path, monkeypatch):
    # A spring too stiff for the step: w ~ 201 rad/s at h = 0.01 (w h ~ 2.01 > 2), so
    # semi-implicit Euler's amplitude grows by 1.15 to 1.22 per step. MuJoCo flags the state once
    # |qacc| > 1e10 (x ~ 2.5e5 m, 0.58 s or 0.93 s in). With the driver's energy-runaway cut
    # switched off, the run ends at MuJoCo's own flag, at the same sample time on the fused
    # and the generic path; it does not raise, and MuJoCo does not silently reset the state
    # (autoreset disabled). With the cut on (the default) the run ends earlier, at the first
    # sample whose energy ran away, on both paths alike.
    monkeypatch.chdir(tmp_path)  # MuJoCo writes MUJOCO_LOG.TXT into the working directory
    effects = f"""
[[effects.springs]]
a = "body"
anchor = [0.1, -0.2, 0.0]
stiffness = {stiffness}
"""
    from crosscheck.engines.base import sampling_plan
    from crosscheck.engines.driver import record

    runs, cut = {}, {}
    for stepping in ("nstep", "compiled"):
        options = f'[engine_options.mujoco]\nstepping = "{stepping}"'
        scene = scene3d(duration=3.0, dt=0.01, com=[0, 0, 0], effects=effects, omega=(0, 0, 0),
                        velocity=(0, 0, 0), options=options)
        session = ENGINE.open(scene, "euler", 0.01)
        assert session.fused == (stepping == "compiled")
        traj, _ = record(session, scene, sampling_plan(scene, 0.01), runaway_factor=np.inf)
        runs[stepping] = traj
        assert traj.failure is not None and traj.failure["reason"].startswith("MuJoCo flagged")
        assert 0.4 < traj.failure["time"] < 1.5
        assert len(traj.t) == round(traj.failure["time"] / 0.01)
        assert np.all(np.isfinite(traj.com)) and np.all(np.abs(traj.com) < 1e10)
        assert np.max(np.abs(traj.com[-1, 0] - traj.com[0, 0])) > 1e3  # it did grow
        cut[stepping] = ENGINE.run(scene, "euler", 0.01)
        assert cut[stepping].failure["reason"].startswith("energy runaway")
        assert cut[stepping].failure["time"] < traj.failure["time"]
    assert runs["nstep"].failure == runs["compiled"].failure
    assert cut["nstep"].failure == cut["compiled"].failure
    np.testing.assert_array_equal(runs["nstep"].com, runs["compiled"].com)
    # Sensitivity: with MuJoCo's default autoreset the same stepping stays finite (reset to
    # qpos0 and time 0 over and over), so no recorder could see the blow-up.
    sim = ENGINE.build(scene, "euler", 0.01)
    sim.model.opt.disableflags &= ~int(mujoco.mjtDisableBit.mjDSBL_AUTORESET)
    for _ in range(300):
        mujoco.mj_step(sim.model, sim.data)
    assert np.all(np.isfinite(sim.data.qpos)) and sim.data.time < 1.0


# -- MuJoCo's compiler limits are "not applicable", never an error (issue 13 point 4) --------------
def test_a_mass_below_mjminval_is_not_applicable_with_the_reason():
    tiny = load_case_text(_TINY.replace("{mass}", "1e-16"))
    reason = ENGINE.not_applicable(tiny, "euler")
    assert reason is not None and "mass 1e-16 kg is below MuJoCo's mjMINVAL" in reason
    assert ENGINE.not_applicable(load_case_text(_TINY.replace("{mass}", "1e-3")), "euler") is None


def test_a_flat_plate_at_the_triangle_limit_runs_balanced():
    # A 1000 kg plate of zero thickness: I_zz = I_xx + I_yy exactly in theory; the
    # eigen-decomposition of the rotated tensor misses by round-off, which at moments of order
    # 1e2 kg m^2 is far beyond MuJoCo's absolute slack of ~1e-15 (its compiler then refuses the
    # model). The adapter balances C = A + B and the run matches the tensor to round-off.
    from crosscheck.engines.mujoco import principal_moments

    plate = load_case_text(_PLATE)
    inertia = plate.bodies[0].inertia
    raw = np.linalg.eigvalsh(inertia)
    balanced, _ = principal_moments(inertia)
    assert balanced[2] == balanced[0] + balanced[1]
    assert abs(balanced[2] - raw[2]) <= 1e-12 * raw[2]
    assert ENGINE.not_applicable(plate, "rk4") is None
    traj = ENGINE.run(plate, "rk4", 1e-3)
    assert traj.failure is None
    assert traj.meta["effective"]["bodies"][0]["inertia_rel_error"] < 1e-12


_TINY = """
[case]
name = "tiny"
dimension = 3
[run]
duration = 0.01
dt = 1e-3
[[bodies]]
name = "speck"
shape = { sphere = { radius = 1e-3 } }
mass = {mass}
position = [0.0, 0.0, 0.0]
"""

_PLATE = """
[case]
name = "plate"
dimension = 3
[run]
duration = 0.1
dt = 1e-3
[[bodies]]
name = "plate"
shape = { box = { size = [1.3, 0.7, 1e-12] } }
mass = 1000.0
position = [0.0, 0.0, 0.0]
orientation = { axis = [1, 2, 3], angle = 0.9 }
angular_velocity = [0.3, 2.0, -1.0]
"""
