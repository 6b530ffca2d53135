"""PyBullet contact: the traps of CONTACTS.md that concern Bullet (C10, C11, C13), the pair values
under Bullet's product rule, and what must not change, as tests that fail if the adapter falls
into them (docs/engines.md, PyBullet, "Contact"; figures from benchmarks/contact_pybullet.py,
whose scenes these are).
"""

from __future__ import annotations

import json
import math

import numpy as np
import pybullet as p
import pytest

from crosscheck.engines import get_engine
from crosscheck.engines.pybullet import PybulletModel, factor_pairs
from crosscheck.scene.loader import load_case_text

G = 9.81
R = 0.1
EPS = 1e-6
SPHERE = f"{{ sphere = {{ radius = {R} }} }}"
CUBE = "{ box = { size = [0.2, 0.2, 0.2] } }"


def case(bodies, *, duration=1.0, dt=1e-3, sample=1e-3, gravity=(0.0, 0.0, -G), ground=0.5,
         contact=True, extra=""):
    g = "" if gravity is None else f"gravity = {json.dumps(list(gravity))}"
    ground_text = "" if ground is None else f"[ground]\nmaterial = {{ friction = {ground!r} }}\n"
    return load_case_text(f"""
[case]
name = "pybullet-contact"
dimension = 3
[run]
duration = {duration!r}
dt = {dt!r}
sample_every = {sample!r}
[effects]
{g}
contact = {"true" if contact else "false"}
{ground_text}{extra}{bodies}""")


def body(name, shape, position, *, mass=1.0, velocity=(0.0, 0.0, 0.0), friction=0.5,
         restitution=0.0, extra=""):
    return (f'\n[[bodies]]\nname = "{name}"\nshape = {shape}\nmass = {mass!r}\n'
            f"position = {json.dumps(list(position))}\nvelocity = {json.dumps(list(velocity))}\n"
            f"material = {{ friction = {friction!r}, restitution = {restitution!r} }}\n{extra}")


def pair(a, b, **values):
    items = "\n".join(f"{k} = {str(v).lower() if isinstance(v, bool) else repr(v)}"
                      for k, v in values.items())
    return f'\n[[contact_pairs]]\na = "{a}"\nb = "{b}"\n{items}\n'


def run(scene, integrator="multibody", dt=None):
    engine = get_engine("pybullet")
    assert engine.not_applicable(scene, integrator) is None
    traj = engine.run(scene, integrator, dt or scene.run.dt)
    assert traj.failure is None, traj.failure
    return traj


def apexes(traj):
    gap = traj.com[:, 0, 2] - R
    vz = traj.vel[:, 0, 2]
    up = np.nonzero((vz[:-1] > 0) & (vz[1:] <= 0))[0]
    return [float(gap[i:i + 2].max()) for i in up]


# -- the product rule, solved ---------------------------------------------------------------------
def test_factor_pairs_solves_what_factors_and_names_what_does_not():
    f, why = factor_pairs(["a", "ground"], [("a", "ground", 0.3)], "friction")
    assert why is None and f["a"] == pytest.approx(math.sqrt(0.3), rel=1e-15)
    assert f["a"] * f["ground"] == pytest.approx(0.3, rel=1e-14)
    # a chain a-g 0.3, b-g 0.6, a-b 0.6: factors exist (a = 0.3/g, b = 0.6/g, ab = 0.18/g^2)
    items = ["a", "b", "ground"]
    f, why = factor_pairs(items, [("a", "b", 0.18 / 0.25), ("a", "ground", 0.3),
                                  ("b", "ground", 0.6)], "friction")
    assert why is None
    # three pairs of three surfaces always factor; four surfaces with six pairs need not
    f, why = factor_pairs(items, [("a", "b", 0.3), ("a", "ground", 0.3),
                                  ("b", "ground", 0.5)], "friction")
    assert why is None
    four = ["a", "b", "c", "ground"]
    pairs = [("a", "b", 0.1), ("a", "c", 0.67), ("b", "c", 0.67), ("a", "ground", 0.5),
             ("b", "ground", 0.5), ("c", "ground", 0.67)]
    f, why = factor_pairs(four, pairs, "friction")
    assert why is not None and "do not factor" in why
    # zero on a surface whose pairs are all zero; a zero between two positive surfaces refused
    f, why = factor_pairs(items, [("a", "b", 0.0), ("a", "ground", 0.0),
                                  ("b", "ground", 0.4)], "restitution")
    assert why is None and f["a"] == 0.0 and f["b"] * f["ground"] == pytest.approx(0.4)
    f, why = factor_pairs(items, [("a", "b", 0.0), ("a", "ground", 0.2),
                                  ("b", "ground", 0.4)], "restitution")
    assert why is not None and "'a'-'b'" in why


def test_not_applicable_says_why():
    engine = get_engine("pybullet")
    mixed = case(body("a", SPHERE, (0, 0, 1), restitution=0.5)
                 + body("b", SPHERE, (1, 0, R - EPS)) + pair("b", "ground", restitution=0.0),
                 extra="")
    # ball a: max(0.5, 0) = 0.5 with the ground; b on the ground: 0 -> mixed (C12)
    reason = engine.not_applicable(mixed, "multibody")
    assert reason is not None and "mixed restitution" in reason and "C12" in reason
    rolling = case(body("a", SPHERE, (0, 0, 1)) + pair("a", "ground", rolling_friction=0.01))
    assert "rolling friction" in engine.not_applicable(rolling, "maximal")
    clash = case(body("a", SPHERE, (0, 0, 1)) + body("b", SPHERE, (1, 0, 1))
                 + body("c", SPHERE, (2, 0, 1), friction=0.9) + pair("a", "b", friction=0.1))
    assert "do not factor" in engine.not_applicable(clash, "multibody")


# -- C11: the restitution threshold and speculative contacts kill bounces ------------------------
def test_c11_elastic_ball_bounces_back_to_its_height():
    scene = case(body("ball", SPHERE, (0, 0, R + 1.0))
                 + pair("ball", "ground", restitution=1.0),
                 duration=3.0)
    tops = apexes(run(scene, "maximal"))[:3]
    assert len(tops) == 3 and max(abs(t - 1.0) for t in tops) < 1e-4  # measured 1.0000 x3
    eff = run(scene, "maximal").meta["effective"]["contact"]
    assert eff["kind"] == "impact" and eff["not_readable"]["restitution_velocity_threshold"] == 0
    # the trap: Bullet's defaults lose the bounce (measured 0.948, 0.354, 0.044)
    defaults = case(body("ball", SPHERE, (0, 0, R + 1.0))
                    + pair("ball", "ground", restitution=1.0), duration=3.0,
                    extra='[engine_options.pybullet]\ncontact_parameters = "defaults"\n')
    assert apexes(run(defaults, "maximal"))[2] < 0.1


def test_partial_restitution_apexes():
    scene = case(body("ball", SPHERE, (0, 0, R + 1.0)) + pair("ball", "ground", restitution=0.5),
                 duration=3.0)
    tops = apexes(run(scene, "maximal"))[:3]
    # e^(2k) less the impact depth v dt (CONTACTS.md: 0.2473, 0.0605, 0.0145 at dt = 1e-3)
    assert tops == pytest.approx([0.25, 0.0625, 0.015625], rel=0.08)


# -- C10: maximal bodies on a multibody ground gain energy -------------------------------------
def test_c10_the_ground_has_the_bodies_kind():
    scene = case(body("ball", SPHERE, (0, 0, R + 1.0))
                 + pair("ball", "ground", restitution=1.0),
                 duration=0.01)
    for integrator, maximal in (("maximal", True), ("multibody", False)):
        model = PybulletModel(scene, integrator, 1e-3)
        try:
            ground = model.surfaces["ground"]
            # a maximal (btRigidBody) static has no joints info of a multibody base: the body
            # kind is read from getDynamicsInfo's body type field (2 rigid, 4 multibody)... use
            # the adapter's own record and the dynamics of the sensitivity check below
            assert model.maximal == maximal
            kind = p.getDynamicsInfo(ground, -1, physicsClientId=model.cid)[10]
            ball = p.getDynamicsInfo(model.bodies[0].uid, -1, physicsClientId=model.cid)[10]
            assert kind == ball
        finally:
            model.close()
    # the trap, measured: maximal ball on a multibody ground with the impact recipe climbs
    cid = p.connect(p.DIRECT)
    try:
        p.setPhysicsEngineParameter(fixedTimeStep=1e-3, restitutionVelocityThreshold=0,
                                    contactSlop=0, contactERP=0, warmStartingFactor=0,
                                    physicsClientId=cid)
        p.setGravity(0, 0, -G, physicsClientId=cid)
        plane = p.createCollisionShape(p.GEOM_PLANE, physicsClientId=cid)
        g = p.createMultiBody(0, plane, useMaximalCoordinates=False, physicsClientId=cid)
        s = p.createCollisionShape(p.GEOM_SPHERE, radius=R, physicsClientId=cid)
        b = p.createMultiBody(1.0, s, basePosition=[0, 0, R + 1.0], useMaximalCoordinates=True,
                              physicsClientId=cid)
        for uid in (g, b):
            p.changeDynamics(uid, -1, restitution=1.0, lateralFriction=0.7, linearDamping=0,
                             angularDamping=0, contactProcessingThreshold=0,
                             physicsClientId=cid)
        z, top, fell = [], 0.0, False
        for _ in range(3000):
            p.stepSimulation(physicsClientId=cid)
            zz = p.getBasePositionAndOrientation(b, physicsClientId=cid)[0][2]
            fell |= zz < 0.5
            if fell:
                top = max(top, zz - R)
            z.append(zz)
        assert top > 1.003  # measured 1.0044 on the first bounce (CONTACTS.md C10)
    finally:
        p.disconnect(cid)


# -- C13: maximal friction; the pair value governs the slide ---------------------------------------
def test_pair_friction_governs_the_slide_not_the_product():
    # materials 0.8 and 0.1: Bullet's product of them 0.08 (2.55 m), the rule 0.28 (0.72 m); the
    # pair's 0.3 stops the box at 0.6796 m (measured multibody -0.144 %, maximal -2.84 %: C13)
    v0, mu = 2.0, 0.3
    scene = case(body("box", CUBE, (0, 0, 0.1 - EPS), velocity=(v0, 0, 0), friction=0.8)
                 + pair("box", "ground", friction=mu), ground=0.1, duration=1.5)
    ideal = v0**2 / (2 * mu * G)
    for integrator, tol in (("multibody", 0.003), ("maximal", 0.035)):
        traj = run(scene, integrator)
        speed = np.linalg.norm(traj.vel[:, 0], axis=1)
        d = traj.com[int(np.argmax(speed < 1e-3)), 0, 0] - traj.com[0, 0, 0]
        assert d == pytest.approx(ideal, rel=tol)
        pairs = traj.meta["effective"]["contact"]["pairs"]
        assert pairs[0]["bullet_friction"] == pytest.approx(mu, rel=1e-12)


def test_collide_false_pairs_pass_through_each_other():
    scene = case(body("low", SPHERE, (0, 0, R - EPS)) + body("high", SPHERE, (0, 0, 3 * R))
                 + pair("low", "high", collide=False), duration=0.5)
    traj = run(scene)
    assert traj.com[-1, 1, 2] == pytest.approx(R, abs=1e-4)  # fell through onto the ground
    both = case(body("low", SPHERE, (0, 0, R - EPS)) + body("high", SPHERE, (0, 0, 3 * R)),
                duration=0.5)
    assert run(both).com[-1, 1, 2] == pytest.approx(3 * R, abs=1e-3)  # rests on the other


def test_resting_depth_and_stack():
    traj = run(case(body("ball", SPHERE, (0, 0, R + 1.0)), duration=2.0))
    gap = traj.com[:, 0, 2] - R
    assert -gap[-1] < 2e-5 and gap[int(np.argmax(gap < 0)):].max() < 1e-5  # 0.010 mm, no bounce


def test_heavy_on_light_uses_200_iterations():
    text = (body("light", CUBE, (0, 0, 0.1 - EPS))
            + body("heavy", CUBE, (0, 0, 0.3 - 2 * EPS), mass=100.0))
    traj = run(case(text, duration=1.0, sample=0.05))
    eff = traj.meta["effective"]["contact"]
    assert eff["num_solver_iterations"] == 200 and "C18" in eff["iterations_reason"]
    zl, zh = traj.com[-1, 0, 2], traj.com[-1, 1, 2]
    assert 0.2 - (zh - zl) < 1e-4


# -- geometry: placed in the body frame, no mass -------------------------------------------------
@pytest.mark.parametrize("shape,bottom", [
    (SPHERE, R), (CUBE, 0.1), ("{ capsule = { radius = 0.1, length = 0.3 } }", 0.25),
    ("{ cylinder = { radius = 0.1, length = 0.3 } }", 0.15)])
@pytest.mark.parametrize("integrator", ["multibody", "maximal"])
def test_shapes_are_where_the_scene_puts_them_and_carry_no_mass(shape, bottom, integrator):
    # body frame at z = 1, centre of mass off the origin and a given full inertia: the shape
    # must sit on the body frame (its lowest point at 1 - bottom) whatever the inertial frame
    extra = "com = [0.03, -0.02, 0.01]\ninertia = [[0.02, 0.001, 0.0], [0.001, 0.03, 0.0], " \
            "[0.0, 0.0, 0.04]]\n"
    scene = case(body("b", shape, (0.2, 0.1, 1.0), mass=3.7, extra=extra), gravity=None,
                 duration=0.01)
    model = get_engine("pybullet").open(scene, integrator, 1e-3)
    try:
        cp = p.getClosestPoints(model.bodies[0].uid, model.surfaces["ground"], 5.0,
                                physicsClientId=model.cid)
        assert min(c[8] for c in cp) == pytest.approx(1.0 - bottom, abs=1e-9)
        info = p.getDynamicsInfo(model.bodies[0].uid, -1, physicsClientId=model.cid)
        assert info[0] == pytest.approx(3.7, rel=2e-16)  # maximal: 1/(1/m), one ulp
        assert np.allclose(info[2], model.bodies[0].moments, rtol=1e-15, atol=0)
    finally:
        model.close()


# -- no contact: exactly as before ---------------------------------------------------------------
def test_a_scene_without_contact_has_no_shapes_and_no_extra_bodies():
    scene = case(body("b", SPHERE, (0, 0, 1.0), velocity=(1.0, 0, 0)), contact=False,
                 ground=None, duration=0.2)
    model = get_engine("pybullet").open(scene, "multibody", 1e-3)
    try:
        assert p.getNumBodies(physicsClientId=model.cid) == 1
        assert p.getCollisionShapeData(model.bodies[0].uid, -1, physicsClientId=model.cid) == ()
        assert model.plan is None
        assert p.getPhysicsEngineParameters(physicsClientId=model.cid)[
            "numSolverIterations"] == 50
    finally:
        model.close()
    traj = run(scene)
    assert traj.meta["effective"]["contact"] is None
    assert traj.meta["effective"]["collisions"].startswith("none")


def test_a_mesh_rests_on_the_ground_not_on_bullets_collision_margin():
    # Bullet's convex hull carries a 1 mm collision margin outside its faces: with it the
    # L-bracket case rested 0.97 mm above the ground. The adapter sets the margin to 0 for
    # meshes; the resting gap is then a penetration of a few hundredths of a millimetre.
    from pathlib import Path

    from crosscheck.compare.contact_metrics import ground_gap
    from crosscheck.scene.loader import load_case

    case = Path(__file__).resolve().parents[2] / "cases" / "contact" / "mesh_landing.toml"
    scene = load_case(case)
    traj = get_engine("pybullet").run(scene, "multibody", scene.run.dt)
    gap = float(np.asarray(ground_gap(scene, traj)[0]).ravel()[-1])
    assert -1e-4 < gap < 1e-5
