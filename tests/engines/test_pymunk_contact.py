"""Pymunk contact: every trap of CONTACTS.md that concerns Chipmunk, as a test that fails if the
adapter falls into it (docs/engines.md, Pymunk, "Contact"; figures from
benchmarks/contact_pymunk.py, whose scenes these are).

Tolerances are the measured values with a margin, never looser than what tells the trap apart:
the slop's resting depth (0.0100 mm) against the impact depth v dt (4.3 mm); a pair friction's
stop distance (+0.0001 % of the discrete answer) against the rule's or the product's (+6 %,
+275 %); the maximum rule's apex (0.64 m, measured 0.633) against the product's (0.16 m).
"""

from __future__ import annotations

import math

import numpy as np
import pymunk
import pytest

from crosscheck.engines import get_engine
from crosscheck.engines.base import sampling_plan
from crosscheck.engines.driver import record
from crosscheck.errors import CaseError
from crosscheck.scene.loader import load_case_text

G = 9.81
R = 0.1
EPS = 1e-6  # initial overlap of resting bodies, below the slop (a gap of exactly 0 is C17)
INTEGRATOR = "position_first"


def _case(bodies, *, duration=1.0, dt=1e-3, sample=0.01, gravity=(0.0, -G), ground=True,
          ground_extra="", contact=True, extra=""):
    grav = "" if gravity is None else f"gravity = [{gravity[0]!r}, {gravity[1]!r}]"
    return load_case_text(f"""
[case]
name = "pymunk-contact"
dimension = 2
[run]
duration = {duration!r}
dt = {dt!r}
sample_every = {sample!r}
[effects]
contact = {"true" if contact else "false"}
{grav}
{"[ground]" if ground else ""}
{ground_extra if ground else ""}
{extra}
{bodies}""")


def _body(name, shape, position, *, mass=1.0, velocity=(0.0, 0.0), omega=0.0, friction=0.5,
          restitution=0.0, extra=""):
    return f"""
[[bodies]]
name = "{name}"
shape = {{ {shape} }}
mass = {mass!r}
position = [{position[0]!r}, {position[1]!r}]
velocity = [{velocity[0]!r}, {velocity[1]!r}]
angular_velocity = {omega!r}
material = {{ friction = {friction!r}, restitution = {restitution!r} }}
{extra}
"""


def _disk(name="disk", position=(0.0, R + 1.0), **kw):
    return _body(name, f"circle = {{ radius = {R} }}", position, **kw)


def _box(name="box", position=(0.0, 0.1 - EPS), size=0.2, **kw):
    return _body(name, f"box = {{ size = [{size!r}, {size!r}] }}", position, **kw)


def _pair(a, b, **values):
    items = "\n".join(f"{k} = {str(v).lower() if isinstance(v, bool) else repr(v)}"
                      for k, v in values.items())
    return f"\n[[contact_pairs]]\na = \"{a}\"\nb = \"{b}\"\n{items}\n"


def _run(scene, dt=None):
    traj = get_engine("pymunk").run(scene, INTEGRATOR, dt or scene.run.dt)
    assert traj.failure is None, traj.failure
    return traj


# -- capabilities --------------------------------------------------------------------------------
def test_contact_is_a_capability_and_what_is_not_applicable_says_why():
    engine = get_engine("pymunk")
    assert "contact" in engine.capabilities().effects
    rolling = _case(_body("disk", f"circle = {{ radius = {R} }}", (0.0, 1.0))
                    + _pair("disk", "ground", rolling_friction=0.002))
    reason = engine.not_applicable(rolling, INTEGRATOR)
    assert reason is not None and "rolling friction" in reason and "'disk'-'ground'" in reason
    # rolling friction from the materials counts too, unless the pair never touches
    disk = _disk().replace("restitution = 0.0 }", "restitution = 0.0, rolling_friction = 0.002 }")
    rolls = "material = { rolling_friction = 0.002 }"
    assert "rolling" in engine.not_applicable(_case(disk, ground_extra=rolls), INTEGRATOR)
    apart = _case(disk + _pair("disk", "ground", collide=False), ground_extra=rolls)
    assert apart.contact_pairs()[0].material.rolling_friction == 0.002
    assert engine.not_applicable(apart, INTEGRATOR) is None
    with pytest.raises(CaseError, match="torsional"):  # 3D only: the loader refuses it in 2D
        _case(_disk() + _pair("disk", "ground", torsional_friction=0.01))


# -- C15: the slop is the resting depth ----------------------------------------------------------
def test_resting_depth_is_the_slop_not_the_impact_depth():
    # A disk dropped 1 m with e = 0 hits at 4.43 m/s and sinks v dt = 4.3 mm in the impact step.
    # With Chipmunk's slop (0.1 m) it rests there for ever; the adapter's 1e-5 m is pushed back.
    traj = _run(_case(_disk(), duration=2.0))
    eff = traj.meta["effective"]["contact"]
    assert eff["collision_slop"] == 1e-5
    gap = traj.com[:, 0, 1] - R
    assert -gap.min() > 4e-3  # the impact step did sink ~v dt
    assert 0.0 < -gap[-1] <= 1.1e-5  # measured 1.00e-5
    assert abs(traj.vel[-1, 0, 1]) < 1e-6
    default = _run(_case(_disk(), duration=2.0,
                         extra="[engine_options.pymunk]\ncollision_slop = 0.1"))
    assert -(default.com[-1, 0, 1] - R) > 4e-3  # the trap itself: 4.33 mm, never corrected


# -- the pair's values, exactly ------------------------------------------------------------------
def test_pair_friction_governs_the_slide():
    # materials 0.8 and 0.1: product 0.08 (stop 2.55 m), geometric mean 0.283 (0.72 m); the
    # pair's 0.3 stops the box at v^2 / (2 mu g) + v dt / 2 (position first), measured +1e-6.
    v0, mu, dt = 2.0, 0.3, 1e-3
    text = (_box(velocity=(v0, 0.0), friction=0.8) + _pair("box", "ground", friction=mu))
    traj = _run(_case(text, duration=1.5, dt=dt, sample=dt, ground_extra="material = "
                      "{ friction = 0.1 }"))
    speed = np.linalg.norm(traj.vel[:, 0], axis=1)
    stop = int(np.argmax(speed < 1e-3))
    d = traj.com[stop, 0, 0] - traj.com[0, 0, 0]
    assert d == pytest.approx(v0**2 / (2 * mu * G) + v0 * dt / 2, rel=1e-4)
    pair = traj.meta["effective"]["contact"]["pairs"][0]
    assert (pair["friction"], pair["restitution"], pair["source"]) == (mu, 0.0,
                                                                       "contact_pairs[0]")
    # the shapes carry sqrt of their materials (product 0.283, the rule's, not the pair's
    # 0.3), so the override needs the pair's handler, which is there
    shapes = {s["name"]: s for s in traj.meta["effective"]["contact"]["shapes"]}
    assert (shapes["box"]["friction"], shapes["ground"]["friction"]) == (math.sqrt(0.8),
                                                                         math.sqrt(0.1))
    assert pair["handler"].startswith("pre_solve")


def test_restitution_is_the_maximum_not_the_product():
    # disk 0.8 on a ground of 0.5: the rule's pair value is 0.8 (apex 0.64 m), Chipmunk's
    # product would be 0.4 (apex 0.16 m). Measured 0.633 (the impact depth v dt costs ~1 %).
    traj = _run(_case(_disk(restitution=0.8), duration=1.5, sample=1e-3,
                      ground_extra="material = { restitution = 0.5 }"))
    gap = traj.com[:, 0, 1] - R
    first = int(np.argmax(gap < 0))
    assert gap[first:].max() == pytest.approx(0.64, rel=0.02)
    assert traj.meta["effective"]["contact"]["pairs"][0]["restitution"] == 0.8


def test_elastic_bounce_keeps_its_height():
    traj = _run(_case(_disk() + _pair("disk", "ground", restitution=1.0), duration=2.0,
                      sample=1e-3))
    gap = traj.com[:, 0, 1] - R
    late = gap[traj.t > 0.5]
    assert late.max() == pytest.approx(1.0, abs=2e-4)  # measured 1.00003, 1.00005


# -- shapes never change mass properties ---------------------------------------------------------
def test_shapes_leave_mass_moment_and_centre_of_gravity_as_given():
    poly = "polygon = { vertices = [[0.0, 0.0], [0.3, 0.0], [0.2, 0.2], [0.0, 0.15]] }"
    text = (_body("p", poly, (0.0, 0.5), extra="com = [0.11, 0.05]\ninertia = 0.0123")
            + _box("b", (1.0, 0.5), extra="com = [0.02, -0.01]")
            + _disk("d", (2.0, 0.5), extra="inertia = 0.004"))
    scene = _case(text, duration=0.01)
    traj = _run(scene)  # a mismatch read back would end the run as a failure at t = 0
    eff = traj.meta["effective"]
    for entry, body in zip(eff["bodies"], scene.bodies, strict=True):
        assert entry["shapes"] == 1
        assert entry["mass"] == body.mass and entry["moment"] == body.moment
        assert entry["center_of_gravity"] == [float(body.com[0]), float(body.com[1])]
    shapes = {s["name"]: s for s in eff["contact"]["shapes"]}
    assert all(s["mass"] == 0.0 and s["density"] == 0.0 for s in shapes.values())
    # the polygon sits in the body frame: its vertices are the case's, not re-centred
    got = sorted(map(tuple, np.round(shapes["p"]["vertices"], 12)))
    assert got == sorted([(0.0, 0.0), (0.3, 0.0), (0.2, 0.2), (0.0, 0.15)])


# -- collide = false -----------------------------------------------------------------------------
def test_collide_false_pairs_pass_through_each_other():
    text = _box("low") + _box("high", (0.0, 0.5))
    stacked = _run(_case(text, duration=1.0))
    assert stacked.com[-1, 1, 1] == pytest.approx(0.3, abs=1e-4)  # rests on the lower box
    apart = _run(_case(text + _pair("low", "high", collide=False), duration=1.0))
    assert apart.com[-1, 1, 1] == pytest.approx(0.1, abs=1e-4)  # through it, onto the ground
    assert apart.com[-1, 0, 1] == pytest.approx(0.1, abs=1e-4)
    pair = apart.meta["effective"]["contact"]["pairs"][0]
    assert pair["collide"] is False and "begin rejects" in pair["handler"]


# -- statics and a tilted ground -----------------------------------------------------------------
def test_a_disk_rests_on_a_rotated_static_and_rolls_down_a_tilted_ground():
    # a static box turned 90 degrees (its 0.4 x 0.2 becomes 0.2 wide, 0.4 high) at x = 3: the
    # disk comes to rest on its top, 0.2 + r above its centre
    statics = """
[[statics]]
name = "post"
shape = { box = { size = [0.4, 0.2] } }
position = [3.0, 0.2]
orientation = 1.5707963267948966
"""
    traj = _run(_case(_disk("d", (3.0, 0.4 + R + 0.05)), duration=1.0, extra=statics))
    assert traj.com[-1, 0, 1] == pytest.approx(0.4 + R, abs=2e-5)
    # ground normal tilted 30 degrees, ordinary gravity: a disk (I = m r^2 / 2) rolls with
    # a = 2/3 g sin 30 along the slope
    th = math.radians(30.0)
    n = (-math.sin(th), math.cos(th))
    start = (R * n[0] * (1 - 1e-5), R * n[1] * (1 - 1e-5))
    tilted = _run(_case(_disk(position=start, friction=1.0), duration=1.0,
                        ground_extra=f"normal = [{n[0]!r}, {n[1]!r}]\n"
                                     "material = { friction = 1.0 }"))
    v = tilted.vel[-1, 0]
    assert np.linalg.norm(v) == pytest.approx(2.0 / 3.0 * G * math.sin(th), rel=1e-4)
    assert abs(v @ np.array(n)) < 1e-6  # along the slope


# -- a scene without contact is today's: no shapes, nothing changed ------------------------------
def test_a_scene_without_contact_has_no_shapes_and_is_unchanged():
    text = _body("plate", "box = { size = [0.3, 0.1] }", (0.2, 1.0), velocity=(1.0, 2.0),
                 omega=3.0, extra="com = [0.04, -0.03]\ninertia = 0.02")
    scene = _case(text, contact=False, ground=True, duration=0.5, sample=0.05)
    session = get_engine("pymunk").open(scene, INTEGRATOR, 1e-3)
    assert len(session.space.shapes) == 0 and not session.space._handlers
    assert session.space.iterations == 10 and session.space.collision_slop == pytest.approx(0.1)
    traj = _run(scene)
    assert traj.meta["effective"]["contact"] is None
    # bit for bit the bare Chipmunk body the adapter has always built
    b = pymunk.Body(1.0, 0.02)
    b.center_of_gravity = (0.04, -0.03)
    b.position = (0.2, 1.0)
    b.velocity = (1.0, 2.0)
    b.angular_velocity = 3.0
    space = pymunk.Space()
    space.gravity = (0.0, -G)
    space.add(b)
    for _ in range(500):
        space.step(1e-3)
    c = b.local_to_world(b.center_of_gravity)
    assert traj.com[-1, 0].tolist() == [c.x, c.y]
    assert traj.vel[-1, 0].tolist() == [b.velocity.x, b.velocity.y]
    assert traj.angle[-1, 0] == b.angle


# -- the fused compiled loop with Python pair handlers inside cpSpaceStep ------------------------
MIXED = (_box("b0", (0.0, 0.1 - EPS), velocity=(0.3, 0.0), friction=0.6)
         + _box("b1", (0.05, 0.3 - 2 * EPS), friction=0.6)
         + _disk("d", (0.6, 0.8), velocity=(-0.5, 0.0), omega=4.0, restitution=0.7)
         + _body("p", "polygon = { vertices = [[0.0, 0.0], [0.2, 0.0], [0.1, 0.15]] }",
                 (1.2, 0.6), omega=-2.0, restitution=0.3, mass=0.5)
         + _body("ghost", f"circle = {{ radius = {R} }}", (0.0, 1.2))
         + _pair("d", "ground", friction=0.2)
         + _pair("ghost", "b1", collide=False)
         + """
[[statics]]
name = "ramp"
shape = { box = { size = [0.8, 0.05] } }
position = [1.1, 0.25]
orientation = -0.3
""")


def test_fused_loop_equals_the_generic_loop_with_contact():
    scene = _case(MIXED, duration=1.5, sample=0.005)
    engine = get_engine("pymunk")
    plan = sampling_plan(scene, scene.run.dt)
    out = []
    for fused in (True, False):
        session = engine.open(scene, INTEGRATOR, scene.run.dt)
        assert session.fused  # the handlers do not turn the compiled loop off
        traj, _ = record(session, scene, plan, fused=fused, runaway_factor=1e6)
        session.close()
        out.append(traj)
    fused, generic = out
    assert fused.failure is None
    assert np.ptp(fused.com[:, 2, 0]) > 0.1 and np.ptp(fused.angle[:, 3]) > 0.1  # it moves
    for name in ("t", "com", "angle", "vel", "omega"):
        np.testing.assert_array_equal(getattr(fused, name), getattr(generic, name))
    # and the handlers ran inside the compiled loop: the ghost fell through b1 (whose top ends
    # at 0.4) onto b0 (top at 0.2)
    assert fused.com[-1, 4, 1] == pytest.approx(0.2 + R, abs=1e-3)


# -- C18: the 100:1 mass ratio -------------------------------------------------------------------
def test_heavy_on_light_keeps_its_depth_with_100_iterations():
    text = (_box("light") + _box("heavy", (0.0, 0.3 - 2 * EPS), mass=100.0)
            + _pair("light", "ground", friction=0.5))
    traj = _run(_case(text, duration=5.0, sample=0.05))
    eff = traj.meta["effective"]
    assert eff["iterations"] == 100 and "100" in eff["iterations_reason"]
    lo, hi = traj.com[-1, 0], traj.com[-1, 1]
    # measured at dt = 1e-3: 0.0077 mm box/box, 0.0067 mm box/ground; 10 iterations with
    # Chipmunk's slop: 0.037 / 0.13 mm
    assert lo[1] + 0.2 - hi[1] < 2e-5
    assert 0.1 - lo[1] < 2e-5
    assert np.max(np.abs(traj.com[:, 1, 0] - traj.com[0, 1, 0])) < 2e-5
    light = _run(_case(_box("a") + _box("b", (0.0, 0.3 - 2 * EPS)), duration=0.01))
    assert light.meta["effective"]["iterations"] == 50


# -- C17: touching at exactly zero distance ------------------------------------------------------
def _cradle(gap):
    text = "".join(_disk(f"d{i}", (i * (2 * R + gap) - (1e-3 if i == 0 else 0.0), 0.0),
                         velocity=(1.0, 0.0) if i == 0 else (0.0, 0.0), friction=0.0,
                         restitution=1.0) for i in range(3))
    return _run(_case(text, duration=0.5, gravity=None, ground=False))


def test_touching_start_is_warned_and_gaps_give_the_sequential_answer():
    gap = _cradle(1e-3)
    np.testing.assert_allclose(gap.vel[-1, :, 0], [0.0, 0.0, 1.0], atol=1e-4)
    assert gap.meta["effective"]["contact"]["warnings"] == []
    touching = _cradle(0.0)
    warnings = touching.meta["effective"]["contact"]["warnings"]
    assert len(warnings) == 1 and "'d1' and 'd2' start touching" in warnings[0]
    assert "C17" in warnings[0]
    overlap = _cradle(-1e-9)  # an LCP's simultaneous answer, as MuJoCo and PyBullet give
    np.testing.assert_allclose(overlap.vel[-1, :, 0], [-1 / 3, 2 / 3, 2 / 3], atol=1e-4)


# -- pair values by material class: Chipmunk's product where it is the pair's, handlers elsewhere
def test_every_class_pair_gets_its_pair_values_in_chipmunk_s_arbiter():
    # every surface overlapping every other at t = 0 (no gravity, one step): an arbiter for every
    # pair that can touch, read in a wildcard post_solve (after the adapter's pre_solve, the
    # values the solver used). Classes: b0 and b1 share one (its pairs with itself too); d and q
    # share a restitution (their pair by the shapes' product), d and p do not (a handler); d and
    # the ground have a friction override (a handler), ghost and b1 collide = false (never solved)
    disk = "circle = { radius = 0.3 }"
    text = (_body("b0", "box = { size = [0.4, 0.4] }", (0.0, 0.1), friction=0.6)
            + _body("b1", "box = { size = [0.3, 0.5] }", (0.05, 0.12), friction=0.6)
            + _body("d", disk, (0.02, 0.05), restitution=0.7)
            + _body("q", disk, (-0.03, 0.1), friction=0.37, restitution=0.7)
            + _body("p", "polygon = { vertices = [[-0.2, -0.2], [0.3, -0.1], [0.0, 0.3]] }",
                    (0.0, 0.08), restitution=0.3)
            + _body("ghost", disk, (0.01, 0.02), friction=0.9)
            + _pair("d", "ground", friction=0.2) + _pair("ghost", "b1", collide=False)
            + '\n[[statics]]\nname = "post"\nshape = { box = { size = [0.2, 0.2] } }\n'
              "position = [0.0, 0.0]\nmaterial = { friction = 0.8, restitution = 0.1 }\n")
    scene = _case(text, gravity=None, duration=0.001, sample=0.001,
                  ground_extra="material = { friction = 0.45 }")
    session = get_engine("pymunk").open(scene, INTEGRATOR, 1e-3)
    assert not session.check()
    name = {id(shape): n for n, shape in session.shapes.items()}
    seen = {}

    def post(arbiter, space, data):
        a, b = (name[id(s)] for s in arbiter.shapes)
        seen[frozenset((a, b))] = (arbiter.friction, arbiter.restitution)

    session.space.on_collision(None, None, post_solve=post)
    session.space.step(1e-3)
    classes = session.classes
    want = {frozenset((a, b)) for q in session.class_pairs
            for a, b in classes.pairs_between(q.i, q.j) if q.material.collide}
    assert set(seen) == want  # every colliding pair met, the collide = false one never
    how = {(q.i, q.j): q.how for q in session.class_pairs}
    assert sorted(set(how.values())) == ["begin", "pre_solve", "shapes"]
    for key, (friction, restitution) in seen.items():
        a, b = sorted(key)
        m = classes.value(a, b)
        i, j = sorted((classes.of[a], classes.of[b]))
        if how[(i, j)] == "pre_solve":  # the handler's values, exactly
            assert (friction, restitution) == (m.friction, m.restitution)
        else:  # Chipmunk's own product of the shapes' sqrt values: the rule to 2 ulp
            assert abs(friction - m.friction) <= 2 * math.ulp(m.friction), (a, b)
            assert abs(restitution - m.restitution) <= 2 * math.ulp(m.restitution), (a, b)
    # the ones that need a handler: the override, and different restitutions (max, not product)
    assert how[tuple(sorted((classes.of["d"], classes.of["ground"])))] == "pre_solve"
    assert how[tuple(sorted((classes.of["d"], classes.of["p"])))] == "pre_solve"
    assert how[tuple(sorted((classes.of["d"], classes.of["q"])))] == "shapes"
    assert how[(classes.of["b0"], classes.of["b1"])] == "shapes"


def test_collision_handlers_do_not_grow_with_the_number_of_bodies():
    # n disks of one material apart on the ground, one override and one collide = false: two
    # handlers whatever n is (before: one per pair, n (n + 1) / 2); the read-back lists class
    # pairs, and finds the one touching pair (C17) without measuring every pair
    counts = []
    for n in (5, 30):
        text = "".join(_disk(f"d{i}", (3 * R * i, R + 0.01 * (i > 0))) for i in range(n))
        text += _pair("d0", "ground", friction=0.2) + _pair("d1", "d2", collide=False)
        session = get_engine("pymunk").open(_case(text, duration=0.01), INTEGRATOR, 1e-3)
        assert not session.check()
        c = session.effective()["contact"]
        counts.append((len(session.space._handlers), c["handlers"], len(c["pairs"])))
        assert len(c["warnings"]) == 1 and "'d0' and 'ground' start touching" in c["warnings"][0]
    assert counts[0] == counts[1] and counts[0][0] == 2
