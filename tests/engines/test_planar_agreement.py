"""One 2D scene in every engine that can run it: Pymunk, PyBullet (planar joints and free
maximal-coordinate bodies), MuJoCo (planar joints) and the in-house simulator must agree, each
within the error its integrator's order and step allow.

The scene: a spinning box (centre of mass off its body origin) hanging from a world anchor by a
damped spring attached off its centre of mass, a disc (centre of mass off its origin, spinning
the other way) hanging from the box by a second spring between body points, gravity, drag on the
disc, a constant force and torque on the box. Every effect and every reference-point convention
of a 2D adapter acts.

Tolerances, derived rather than chosen:

* Reference: the Newton-Euler equations of the scene integrated by SciPy's DOP853 to 1e-12
  (``conftest.reference``, i.e. ``crosscheck.reference.newton_euler``), so its own error is
  negligible against every bound below.
* Each run's error bound comes from its order p (``conftest.scheme_of``) and two more runs at
  h/2 and h/4: with e(h) = C h^p + O(h^(p+1)), x_h - x_{h/2} = C h^p (1 - 2^-p) + ..., so
  Richardson's estimate of the error at h is B = |x_h - x_{h/2}| 2^p / (2^p - 1). The observed
  order log2(|x_h - x_{h/2}| / |x_{h/2} - x_{h/4}|) must be p (within -0.3/+0.5), which is what
  makes B trustworthy. Measured: |error| / B is 0.99 to 1.05 for every run (the O(h^(p+1)) part),
  hence the safety factor 1.25.
* Two engines then agree when their difference is within the sum of their bounds (times 1.25):
  measured up to 1.0 of the sum (Pymunk's position-first and the velocity-first schemes err in
  opposite directions, so their bounds add up exactly).
* Runs of one and the same discrete scheme must agree to round-off: measured 7e-13.
"""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from conftest import reference, scheme_of

from crosscheck.engines import get_engine
from crosscheck.scene.loader import load_case_text

SCENE = load_case_text("""
[case]
name = "planar-agreement"
description = "Spinning box on a spring from an anchor, a spinning disc on a spring below it."
dimension = 2
[run]
duration = 2.0
dt = 1e-3
sample_every = 0.02
[effects]
gravity = [0.0, -9.81]
[[effects.springs]]
a = "box"
attach_a = [0.15, 0.04]
anchor = [0.0, 1.5]
stiffness = 60.0
damping = 0.3
rest_length = 0.5
[[effects.springs]]
a = "disc"
attach_a = [0.0, 0.04]
b = "box"
attach_b = [-0.12, -0.02]
stiffness = 30.0
damping = 0.1
rest_length = 0.25
[[effects.drag]]
linear = 0.05
angular = 0.002
bodies = ["disc"]
[[effects.loads]]
body = "box"
force = [0.4, 0.0]
torque = 0.03
[[bodies]]
name = "box"
shape = { box = { size = [0.4, 0.1] } }
mass = 1.2
com = [0.05, -0.02]
position = [0.3, 1.0]
orientation = 0.4
velocity = [0.2, 0.5]
angular_velocity = 3.0
[[bodies]]
name = "disc"
shape = { circle = { radius = 0.06 } }
mass = 0.5
com = [0.01, -0.015]
position = [0.1, 0.6]
orientation = -0.3
velocity = [-0.3, 0.0]
angular_velocity = -5.0
""")

H = 1e-3
STEPS = (H, H / 2, H / 4)  # all divide the sampling interval 0.02: common sample times
SAFETY = 1.25
FLOOR = 1e-10  # absolute: round-off of the runs and the reference's own 1e-12 tolerance

# Every engine and integrator taking part (MuJoCo and in-house: a first-order and their RK4).
RUNS = [("pymunk", "position_first"), ("pybullet", "multibody"), ("pybullet", "maximal"),
        ("mujoco", "euler"), ("mujoco", "implicitfast"), ("mujoco", "rk4"),
        ("inhouse", "symplectic_euler"), ("inhouse", "rk4")]
# Pairs that run one discrete scheme (velocity-first Euler with forces from the start-of-step
# state; classic RK4) and so must agree to round-off, not just within their error bounds.
SAME_SCHEME = [(("pybullet", "multibody"), ("pybullet", "maximal")),
               (("pybullet", "multibody"), ("inhouse", "symplectic_euler")),
               (("mujoco", "rk4"), ("inhouse", "rk4"))]
GROUPS = ("com", "angle", "vel", "omega")

_cache: dict = {}


def _ident(run) -> str:
    return f"{run[0]}.{run[1]}"


def _groups(traj) -> dict[str, np.ndarray]:
    return {"com": traj.com, "angle": traj.angle, "vel": traj.vel, "omega": traj.omega}


def _reference() -> dict[str, np.ndarray]:
    if "reference" not in _cache:
        t = SCENE.run.sample_times()
        ref = reference(SCENE, t)  # planar: the angle is integrated as it turns, never wrapped
        _cache["reference"] = {"t": t, **_groups(ref)}
    return _cache["reference"]


def _runs(run) -> dict:
    """The run at H, H/2 and H/4 with its order and error bound, or a skip with the reason."""
    if run in _cache:
        return _cache[run]
    name, integrator = run
    engine = get_engine(name)  # a missing adapter fails
    reason = engine.not_applicable(SCENE, integrator)
    if reason is not None:
        pytest.skip(f"{_ident(run)}: not applicable: {reason}")
    scheme = scheme_of(engine, integrator)  # crosscheck.names; KeyError (a failure) if unknown
    trajs = {}
    for h in STEPS:
        traj = engine.run(SCENE, integrator, h)
        assert traj.failure is None, (run, h, traj.failure)
        np.testing.assert_allclose(traj.t, SCENE.run.sample_times(), rtol=0, atol=1e-12)
        trajs[h] = _groups(traj)
    p = scheme.order
    d1 = {g: float(np.max(np.abs(trajs[STEPS[0]][g] - trajs[STEPS[1]][g]))) for g in GROUPS}
    d2 = {g: float(np.max(np.abs(trajs[STEPS[1]][g] - trajs[STEPS[2]][g]))) for g in GROUPS}
    bound = {g: d1[g] * 2**p / (2**p - 1) for g in GROUPS}
    _cache[run] = {"order": p, "state": trajs[H], "d1": d1, "d2": d2, "bound": bound}
    return _cache[run]


@pytest.mark.parametrize("run", RUNS, ids=_ident)
def test_each_engine_matches_the_reference_within_its_order(run):
    data = _runs(run)
    ref = _reference()
    p = data["order"]
    for g in GROUPS:
        d1, d2 = data["d1"][g], data["d2"][g]
        if d1 > 100 * FLOOR:  # above round-off the order is measurable and must be p
            observed = math.log2(d1 / d2)
            assert p - 0.3 <= observed <= p + 0.5, (run, g, observed)
        error = float(np.max(np.abs(data["state"][g] - ref[g])))
        limit = SAFETY * data["bound"][g] + FLOOR
        assert error <= limit, (run, g, error, data["bound"][g])
    # The scene is not trivially passed: the bodies swung, turned and stretched the springs.
    assert np.ptp(ref["angle"][:, 0]) > 1.0 and np.ptp(ref["com"][:, 1, 1]) > 0.1


@pytest.mark.parametrize("pair", list(itertools.combinations(RUNS, 2)),
                         ids=lambda pair: f"{_ident(pair[0])}~{_ident(pair[1])}")
def test_engines_agree_within_the_sum_of_their_bounds(pair):
    a, b = (_runs(run) for run in pair)
    for g in GROUPS:
        diff = float(np.max(np.abs(a["state"][g] - b["state"][g])))
        limit = SAFETY * (a["bound"][g] + b["bound"][g]) + FLOOR
        assert diff <= limit, (pair, g, diff, a["bound"][g], b["bound"][g])


@pytest.mark.parametrize("pair", SAME_SCHEME,
                         ids=lambda pair: f"{_ident(pair[0])}=={_ident(pair[1])}")
def test_same_scheme_gives_the_same_numbers(pair):
    # PyBullet's planar joints and its free body, and the in-house symplectic Euler, all update
    # v += h a(x_n, v_n), then x += h v_{n+1} (the angle too: a revolute joint, or a rotation
    # about the fixed z axis); MuJoCo's and the in-house RK4 are the classic tableau. Floating
    # point order differs, ~1e-16 per step, amplified by the flow over 2 s: measured 7e-13 on
    # omega; 1e-9 keeps a margin of 1e3 and is 1e6 below the first-order bounds (~1e-3).
    a, b = (_runs(run) for run in pair)
    for g in GROUPS:
        diff = float(np.max(np.abs(a["state"][g] - b["state"][g])))
        assert diff <= 1e-9, (pair, g, diff)
