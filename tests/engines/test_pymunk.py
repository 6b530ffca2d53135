"""Pymunk adapter: every Pymunk trap of ENGINES.md with a test that fails if the adapter fell in.

Chipmunk computes in doubles. A state set and read back goes through one rotation of the centre
of gravity (measured: 2e-16 on the body position), so 1e-12 is round-off with a margin of ~1e3.
The step is reproduced exactly here where its update is known in closed form (free fall, springs,
drag, loads), so those tests can be tight (accumulated round-off over ~1e3 steps: ~1e-13).
"""

from __future__ import annotations

import json
import math

import numpy as np
import pymunk
import pytest

from crosscheck import quantities
from crosscheck.engines import get_engine
from crosscheck.errors import CaseError, EngineUnavailable
from crosscheck.scene.loader import load_case_text

G = 9.81
INTEGRATOR = "position_first"


def _j(x) -> str:
    return json.dumps(np.asarray(x, float).tolist())


def _rot(angle: float) -> np.ndarray:
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, -s], [s, c]])


def _body(name="plate", *, mass=1.5, com=(0.04, -0.03), position=(0.2, 1.0), angle=2.5,
          velocity=(0.0, 0.0), omega=0.0, moment=0.02, shape="box = { size = [0.3, 0.1] }"):
    return f"""
[[bodies]]
name = "{name}"
shape = {{ {shape} }}
mass = {mass!r}
inertia = {moment!r}
com = {_j(com)}
position = {_j(position)}
orientation = {angle!r}
velocity = {_j(velocity)}
angular_velocity = {omega!r}
"""


def _scene(duration, dt, bodies, effects="", sample_every=None, extra="", dimension=2):
    return load_case_text(f"""
[case]
name = "pymunk-test"
dimension = {dimension}
[run]
duration = {duration!r}
dt = {dt!r}
sample_every = {(sample_every or dt)!r}
[effects]
{effects}
{extra}
{bodies}""")


def _run(scene, dt=None):
    traj = get_engine("pymunk").run(scene, INTEGRATOR, dt or scene.run.dt)
    assert traj.failure is None, traj.failure
    return traj


# -- capabilities ---------------------------------------------------------------------------------
def test_pymunk_is_2d_only():
    engine = get_engine("pymunk")
    caps = engine.capabilities()
    assert caps.dimensions == {2} and caps.integrators == (INTEGRATOR,)
    scene3 = load_case_text("""
[case]
name = "three"
dimension = 3
[run]
duration = 0.01
dt = 1e-3
[[bodies]]
name = "b"
shape = { sphere = { radius = 0.1 } }
mass = 1.0
position = [0, 0, 0]
""")
    assert engine.not_applicable(scene3, INTEGRATOR) == "pymunk is 2D"
    with pytest.raises(EngineUnavailable, match="pymunk is 2D"):
        engine.run(scene3, INTEGRATOR, 1e-3)
    contact = _scene(0.01, 1e-3, _body(), effects="contact = true")
    assert engine.not_applicable(contact, INTEGRATOR) is None  # tests/engines/test_pymunk_contact
    assert engine.not_applicable(_scene(0.01, 1e-3, _body()), "euler") is not None
    assert engine.version().startswith(pymunk.version)


def test_engine_options_pinned_and_refused():
    engine = get_engine("pymunk")
    traj = _run(_scene(0.01, 1e-3, _body(), extra="[engine_options.pymunk]\niterations = 3"))
    assert traj.meta["effective"]["iterations"] == 3  # read back from the Space
    for bad in ("iterations = 0", "iterations = true", "threaded = true"):
        scene = _scene(0.01, 1e-3, _body(), extra=f"[engine_options.pymunk]\n{bad}")
        with pytest.raises(CaseError, match="engine_options.pymunk"):
            engine.not_applicable(scene, INTEGRATOR)


def test_space_settings_read_back():
    eff = _run(_scene(0.01, 1e-3, _body())).meta["effective"]
    assert eff["gravity"] == [0.0, 0.0]  # no gravity in the scene: none in the space
    assert eff["damping"] == 1.0  # Space.damping = 1: no velocity decay
    assert eff["threaded"] is False
    assert eff["sleep_time_threshold"] == math.inf
    assert eff["bodies"][0]["shapes"] == 0  # a shape with mass would override mass and moment
    eff = _run(_scene(0.01, 1e-3, _body(), effects=f"gravity = [0.5, {-G}]")).meta["effective"]
    assert eff["gravity"] == [0.5, -G]


# -- round trip: centre of gravity, moment, angle ----------------------------------------------
def test_round_trip():
    scene = _scene(1e-3, 1e-3, _body(angle=8.5, velocity=(1.0, -2.0), omega=-7.0))
    traj = _run(scene)
    body = scene.bodies[0]
    # The centre of mass, not the body origin (0.05 apart), its velocity, the scene's own turn.
    assert np.linalg.norm(body.com_world() - body.position) > 0.04
    np.testing.assert_allclose(traj.com[0, 0], body.com_world(), rtol=0, atol=1e-12)
    assert abs(traj.angle[0, 0] - 8.5) <= 1e-12
    np.testing.assert_allclose(traj.vel[0, 0], body.velocity, rtol=0, atol=1e-12)
    assert abs(traj.omega[0, 0] + 7.0) <= 1e-12
    eff = traj.meta["effective"]["bodies"][0]
    assert eff["center_of_gravity"] == [0.04, -0.03] and eff["moment"] == 0.02


def test_spinning_body_turns_about_its_centre_of_mass():
    # Free flight with spin and an offset centre of gravity: the centre of mass moves in a
    # straight line, the body turns about it. Reading the body origin (Body.position) as the
    # centre of mass would draw a circle of radius 0.05 around that line.
    v, w = np.array([1.0, -0.5]), 6.0
    scene = _scene(1.0, 1e-3, _body(velocity=v, omega=w), sample_every=0.01)
    traj = _run(scene)
    start = scene.bodies[0].com_world()
    np.testing.assert_allclose(traj.com[:, 0], start + traj.t[:, None] * v, rtol=0, atol=1e-12)
    np.testing.assert_allclose(traj.vel[:, 0], np.broadcast_to(v, traj.vel[:, 0].shape),
                               rtol=0, atol=1e-15)
    np.testing.assert_allclose(traj.angle[:, 0], 2.5 + w * traj.t, rtol=0, atol=1e-12)


def test_fast_spin_sampled_coarsely_stays_unwrapped():
    # 50 rad/s sampled every 0.1 s: 5 rad between samples. Chipmunk never wraps its angle, and
    # the adapter must not "unwrap" it either (np.unwrap would fold 5 rad back to -1.28).
    scene = _scene(1.0, 1e-3, _body(omega=50.0), sample_every=0.1)
    traj = _run(scene)
    np.testing.assert_allclose(traj.angle[:, 0], 2.5 + 50.0 * traj.t, rtol=0, atol=1e-11)


# -- free fall: position first (trap 8) ---------------------------------------------------------
def test_free_fall_is_position_first():
    # x_k = x_{k-1} + h v_{k-1}, v_k = v_{k-1} - g h: drop = g h^2 n (n - 1) / 2 (4.900095 m
    # after 1 s at h = 1e-3; velocity first would be 4.909905, exact 4.905).
    h = 1e-3
    scene = _scene(1.0, h, _body(velocity=(1.0, 0.0), omega=6.0), effects=f"gravity = [0, {-G}]",
                   sample_every=0.01)
    traj = _run(scene)
    n = np.rint(traj.t / h)
    drop = G * h * h * n * (n - 1) / 2
    assert drop[-1] == pytest.approx(4.900095, abs=1e-12)
    start = scene.bodies[0].com_world()
    # 1000 additions on values ~ 5: ~1e-12 of round-off; the other schemes are 5e-3 away.
    np.testing.assert_allclose(start[1] - traj.com[:, 0, 1], drop, rtol=0, atol=1e-10)
    np.testing.assert_allclose(traj.vel[:, 0, 1], -G * n * h, rtol=0, atol=1e-11)
    np.testing.assert_allclose(traj.com[:, 0, 0], start[0] + traj.t, rtol=0, atol=1e-12)


# -- springs, drag, loads: their discrete form ---------------------------------------------------
def test_spring_drag_and_load_discrete_form():
    # Along x through the centre of mass: a DampedSpring to an anchor (stiffness k, damping c),
    # linear drag c_d and a load F. Chipmunk's step, as the adapter documents it:
    #   x_{n+1} = x_n + h v_n                                       (positions first)
    #   v'      = v_n + h (-k (x_{n+1} - a) + F - c_d v_n) / m      (spring at the NEW position,
    #                                                                drag and load set before
    #                                                                the step from v_n)
    #   v_{n+1} = v' exp(-c h / m)                                  (spring damping: exponential
    #                                                                decay, k_eff = 1/m here)
    # Evaluating the spring at x_n (forces applied per step) would be forward Euler: its energy
    # grows by (1 + k h^2/m) per step, 5 % over these 2000 steps; the differences below are
    # O(h) = 1e-3 per unit time against a 1e-10 round-off allowance.
    h, steps = 1e-3, 2000
    m, k, c, cd, force, anchor = 1.5, 50.0, 0.6, 0.4, 1.5, 0.5
    com2 = np.array([0.04, -0.03])
    com_w = np.array([1.0, 0.3])
    body = _body(mass=m, position=com_w - _rot(2.5) @ com2)
    scene = _scene(steps * h, h, body, sample_every=0.1, effects=f"""
[[effects.springs]]
a = "plate"
attach_a = {_j(com2)}
anchor = {_j([anchor, 0.3])}
stiffness = {k!r}
damping = {c!r}
[[effects.drag]]
linear = {cd!r}
[[effects.loads]]
body = "plate"
force = [{force!r}, 0.0]
""")
    traj = _run(scene)
    x, v = 1.0, 0.0
    xs, vs = [x], [v]
    for n in range(1, steps + 1):
        x = x + h * v
        v = (v + h * (-k * (x - anchor) + force - cd * v) / m) * math.exp(-c * h / m)
        if n % 100 == 0:
            xs.append(x)
            vs.append(v)
    np.testing.assert_allclose(traj.com[:, 0, 0], xs, rtol=0, atol=1e-10)
    np.testing.assert_allclose(traj.vel[:, 0, 0], vs, rtol=0, atol=1e-10)
    np.testing.assert_allclose(traj.com[:, 0, 1], 0.3, rtol=0, atol=1e-12)
    assert np.max(np.abs(traj.omega)) <= 1e-12


def test_angular_drag_and_load_torque_discrete_form():
    # theta_{n+1} = theta_n + h w_n, w_{n+1} = w_n + h (tau - c_a w_n) / I: forces are reset by
    # Chipmunk after every step, so the adapter sets them again from the start-of-step state.
    h, steps = 1e-3, 1000
    moment, tau, ca = 0.02, 0.05, 0.01
    scene = _scene(steps * h, h, _body(omega=3.0, moment=moment), sample_every=0.1, effects=f"""
[[effects.drag]]
angular = {ca!r}
[[effects.loads]]
body = "plate"
torque = {tau!r}
""")
    traj = _run(scene)
    th, w = 2.5, 3.0
    ths, ws = [th], [w]
    for n in range(1, steps + 1):
        th, w = th + h * w, w + h * (tau - ca * w) / moment
        if n % 100 == 0:
            ths.append(th)
            ws.append(w)
    np.testing.assert_allclose(traj.angle[:, 0], ths, rtol=0, atol=1e-11)
    np.testing.assert_allclose(traj.omega[:, 0], ws, rtol=0, atol=1e-11)
    # The torque acts about the centre of mass: it does not move it.
    start = scene.bodies[0].com_world()
    np.testing.assert_allclose(traj.com[:, 0], np.broadcast_to(start, traj.com[:, 0].shape),
                               rtol=0, atol=1e-12)


def _hanging_chain():
    """Two bodies hanging still: anchor -> A (off its COM) -> B (off A's and B's COMs).

    Each attachment point lies on the vertical through its body's centre of mass, stretched by
    the weight it carries: every force and torque balances. An anchor taken relative to the
    centre of gravity instead of the body origin (Chipmunk anchors are body-origin relative, as
    the Scene's points), or in the wrong frame, puts a lever arm on a spring and the chain swings.
    """
    ma, mb, k1, k2 = 1.5, 0.8, 300.0, 200.0
    com_a, com_b = np.array([0.04, -0.03]), np.array([-0.02, 0.05])
    u = np.array([0.6, 0.8])  # A's attachment line, body frame
    pa1, pa2 = com_a + 0.1 * u, com_a - 0.08 * u
    w_dir = np.array([-0.28, 0.96])  # B's attachment direction, body frame
    pb = com_b + 0.07 * w_dir
    ang_a = math.pi / 2 - math.atan2(u[1], u[0])
    ang_b = math.pi / 2 - math.atan2(w_dir[1], w_dir[0])
    anchor = np.array([0.5, 3.0])
    up = np.array([0.0, 1.0])
    pa1_w = anchor - (ma + mb) * G / k1 * up
    com_a_w = pa1_w - 0.1 * up
    pa2_w = com_a_w - 0.08 * up
    pb_w = pa2_w - mb * G / k2 * up
    com_b_w = pb_w - 0.07 * up
    bodies = (_body("A", mass=ma, com=com_a, position=com_a_w - _rot(ang_a) @ com_a, angle=ang_a)
              + _body("B", mass=mb, com=com_b, position=com_b_w - _rot(ang_b) @ com_b,
                      angle=ang_b, moment=0.01, shape="circle = { radius = 0.05 }"))
    effects = f"""
gravity = [0.0, {-G}]
[[effects.springs]]
a = "A"
attach_a = {_j(pa1)}
anchor = {_j(anchor)}
stiffness = {k1!r}
[[effects.springs]]
a = "B"
attach_a = {_j(pb)}
b = "A"
attach_b = {_j(pa2)}
stiffness = {k2!r}
"""
    return bodies, effects, np.array([com_a_w, com_b_w]), np.array([ang_a, ang_b])


def test_spring_anchor_frames_hanging_chain():
    bodies, effects, coms, angles = _hanging_chain()
    scene = _scene(1.0, 1e-3, bodies, effects=effects, sample_every=0.1)
    traj = _run(scene)
    # Balanced to round-off (~1e-16 of each force per step): nothing moves by more than ~1e-13
    # in 1000 steps; a misplaced anchor swings the chain by centimetres.
    np.testing.assert_allclose(traj.com, np.broadcast_to(coms, traj.com.shape), rtol=0,
                               atol=1e-10)
    np.testing.assert_allclose(traj.angle, np.broadcast_to(angles, traj.angle.shape), rtol=0,
                               atol=1e-9)


def test_two_body_spring_conserves_momenta():
    # A spring between two bodies (attachments off both centres of mass), no gravity: its
    # impulses are equal and opposite along the line joining the attachment points, and free
    # motion keeps r x p, so linear momentum and angular momentum about the origin are conserved
    # to round-off by this scheme (~1e-13 after 2000 steps on values ~ 1).
    bodies = (_body("A", velocity=(0.3, 1.0), omega=4.0)
              + _body("B", mass=0.8, com=(-0.02, 0.05), position=(1.0, 0.5), angle=-0.7,
                      velocity=(-0.5, 0.2), omega=-2.0, moment=0.01,
                      shape="circle = { radius = 0.05 }"))
    scene = _scene(2.0, 1e-3, bodies, sample_every=0.05, effects="""
[[effects.springs]]
a = "A"
attach_a = [0.1, 0.02]
b = "B"
attach_b = [0.03, -0.01]
stiffness = 30.0
damping = 0.2
rest_length = 0.4
""")
    traj = _run(scene)
    p_lin = quantities.linear_momentum(scene, traj)
    np.testing.assert_allclose(p_lin, np.broadcast_to(p_lin[0], p_lin.shape), rtol=0,
                               atol=1e-12)
    ang = quantities.angular_momentum(scene, traj, about="origin")
    np.testing.assert_allclose(ang, ang[0], rtol=0, atol=1e-12)
    assert np.ptp(traj.omega[:, 0]) > 0.1  # the spring did turn the bodies


# -- energy: never Body.kinetic_energy ----------------------------------------------------------
def test_kinetic_energy_is_computed_not_taken_from_pymunk():
    # Pymunk's Body.kinetic_energy is m v^2 + I w^2, twice the kinetic energy. crosscheck computes
    # it from the trajectory: 1/2 m |v_com|^2 + 1/2 I w^2, conserved exactly in free flight.
    m, moment, v, w = 1.5, 0.02, np.array([1.0, -2.0]), -7.0
    raw = pymunk.Body(m, moment)
    raw.velocity, raw.angular_velocity = tuple(v), w
    expected = 0.5 * m * v @ v + 0.5 * moment * w * w
    assert raw.kinetic_energy == pytest.approx(2 * expected, rel=1e-15)
    scene = _scene(0.5, 1e-3, _body(velocity=v, omega=w), sample_every=0.05)
    traj = _run(scene)
    energy = quantities.kinetic_energy(scene, traj)
    np.testing.assert_allclose(energy, expected, rtol=1e-14)


# -- determinism, blow-up -------------------------------------------------------------------------
def test_runs_are_bit_identical():
    bodies, effects, _, _ = _hanging_chain()
    scene = _scene(0.5, 1e-3, bodies.replace("angular_velocity = 0.0",
                                             "angular_velocity = 1.0"),
                   effects=effects, sample_every=0.05)
    a, b = _run(scene), _run(scene)
    assert np.ptp(a.angle[:, 0]) > 0.01  # it moves
    assert np.array_equal(a.com, b.com) and np.array_equal(a.angle, b.angle)
    assert np.array_equal(a.vel, b.vel) and np.array_equal(a.omega, b.omega)


def test_blow_up_is_a_reported_failure():
    # The position-first spring update is stable only for sqrt(k/m) h < 2; 1e4 rad/s at
    # h = 1e-3 is 10: the state overflows within ~150 steps and the run stops there.
    scene = _scene(2.0, 1e-3, _body(shape="circle = { radius = 0.1 }", mass=2.0), effects="""
[[effects.springs]]
a = "plate"
anchor = [0.0, 0.0]
stiffness = 2e8
""")
    from crosscheck.engines.base import sampling_plan
    from crosscheck.engines.driver import record

    # The engine's own state overflows: with the driver's energy-runaway cut off, the run
    # ends at the first non-finite sample; with it on (the default), earlier.
    session = get_engine("pymunk").open(scene, INTEGRATOR, 1e-3)
    traj, _ = record(session, scene, sampling_plan(scene, 1e-3), runaway_factor=np.inf)
    session.close()
    assert traj.failure is not None and traj.failure["reason"] == "non-finite state"
    cut = get_engine("pymunk").run(scene, INTEGRATOR, 1e-3)
    assert cut.failure["reason"].startswith("energy runaway")
    assert cut.failure["time"] < traj.failure["time"]
    assert 0 < traj.failure["time"] < 0.5
    assert np.all(np.isfinite(traj.com)) and len(traj.t) < 500


def test_fast_state_read_equals_the_public_api():
    # The adapter reads samples through Chipmunk's C getters (the calls pymunk's properties
    # make) to keep recording cheap; the row must be bit-identical to the public properties'.
    from crosscheck.engines.pymunk import PymunkModel

    bodies, effects, _, _ = _hanging_chain()
    scene = _scene(0.1, 1e-3, bodies.replace("angular_velocity = 0.0", "angular_velocity = 2.0"),
                   effects=effects)
    model = PymunkModel(scene, 1e-3)
    assert model._fast is not None  # the fast path is the one in use with this pymunk
    model.advance(57)
    fast, public = model.read_raw(), model.read_raw_public()
    assert fast == public and len(fast) == 12
    assert fast[2] != _hanging_chain()[3][0]  # it turned: the rows are not the initial state
