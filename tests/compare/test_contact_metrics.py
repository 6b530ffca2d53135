"""Contact metrics on hand-built Trajectories whose answers are known in closed form.

Every figure below is worked out from the geometry or the motion prescribed, not from the code under
test: depths of spheres, a box standing on a corner, boxes checked against the Minkowski
difference's convex hull (SciPy), bounces with a prescribed piecewise-parabolic motion, a slide
with constant deceleration, rolling and slipping, energy that rises or falls by a known amount.
"""

from __future__ import annotations

import math
import time

import numpy as np
import pytest
from scipy.spatial import ConvexHull

from crosscheck.compare import contact_metrics as cm
from crosscheck.compare import scales
from crosscheck.compare.metrics import MetricSet, compute_metrics
from crosscheck.quantities import total_energy
from crosscheck.rotations import axis_angle_to_quat, quat_mul, quat_to_matrix
from crosscheck.scene.loader import load_case_text
from crosscheck.state import Trajectory

G = 9.81


# -- scenes and trajectories
def case(bodies: str, *, dimension: int = 3, gravity: str | None = None, ground: str | None = "",
         statics: str = "", extra: str = "", duration: float = 1.0, sample: float = 0.01) -> str:
    if gravity is None:
        gravity = "[0, 0, -9.81]" if dimension == 3 else "[0, -9.81]"
    ground_table = "" if ground is None else f"[ground]\n{ground}\n"
    return f"""
[case]
name = "contact-metrics"
dimension = {dimension}
[run]
duration = {duration}
dt = 0.001
sample_every = {sample}
engines = ["inhouse"]
[effects]
gravity = {gravity}
contact = true
{extra}
{ground_table}
{bodies}
{statics}
"""


def body(name: str, shape: str, position="[0, 0, 0]", extra: str = "") -> str:
    return f"""
[[bodies]]
name = "{name}"
shape = {shape}
mass = 1.0
position = {position}
{extra}
"""


def load(text: str):
    return load_case_text(text, name="contact_metrics_case.toml")


def traj3(t, com, vel=None, quat=None, omega=None) -> Trajectory:
    t = np.asarray(t, float)
    com = np.asarray(com, float).reshape(len(t), -1, 3)
    n = com.shape[1]
    vel = np.zeros_like(com) if vel is None else np.asarray(vel, float).reshape(com.shape)
    omega = np.zeros_like(com) if omega is None else np.asarray(omega, float).reshape(com.shape)
    if quat is None:
        quat = np.tile([1.0, 0, 0, 0], (len(t), n, 1))
    quat = np.broadcast_to(np.asarray(quat, float), (len(t), n, 4)).copy()
    return Trajectory(t=t, com=com, vel=vel, omega=omega, quat=quat)


def traj2(t, com, vel=None, angle=None, omega=None) -> Trajectory:
    t = np.asarray(t, float)
    com = np.asarray(com, float).reshape(len(t), -1, 2)
    n = com.shape[1]
    vel = np.zeros_like(com) if vel is None else np.asarray(vel, float).reshape(com.shape)
    omega = np.zeros((len(t), n)) if omega is None else np.asarray(omega, float).reshape(len(t), n)
    if angle is None:
        angle = np.zeros((len(t), n))
    else:
        angle = np.asarray(angle, float)
        angle = (angle.reshape(len(t), n) if angle.size == len(t) * n
                 else np.broadcast_to(angle, (len(t), n)).copy())
    return Trajectory(t=t, com=com, vel=vel, omega=omega, angle=angle)


def still(scene, t, com, quat=None):
    """Every body motionless at ``com`` (N, 3) for all samples."""
    com = np.broadcast_to(np.asarray(com, float), (len(t),) + np.shape(com))
    return traj3(t, com, quat=quat)


def metrics(scene, traj):
    return compute_metrics(scene, traj).metrics


T20 = np.linspace(0.0, 1.0, 21)


# -- penetration
def test_sphere_resting_one_millimetre_into_the_ground():
    scene = load(case(body("ball", "{ sphere = { radius = 0.1 } }")))
    ms = metrics(scene, still(scene, T20, [[0.3, -0.2, 0.099]]))
    assert ms["penetration_max"].value == pytest.approx(1e-3, rel=1e-9)
    assert ms["penetration_resting_mean"].value == pytest.approx(1e-3, rel=1e-9)
    assert ms["penetration_max"].unit == "m"
    # just above the ground: no depth, and still "resting" within the contact tolerance (1e-4 m)
    ms = metrics(scene, still(scene, T20, [[0.0, 0.0, 0.10005]]))
    assert ms["penetration_max"].value == 0.0
    assert ms["penetration_resting_mean"].value == 0.0
    # well above: nothing rests
    ms = metrics(scene, still(scene, T20, [[0.0, 0.0, 0.2]]))
    assert ms["penetration_resting_mean"].value is None
    assert not ms["penetration_resting_mean"].meaningful


def test_the_shape_is_placed_at_the_body_frame_not_the_centre_of_mass():
    # A sphere whose centre of mass is 5 cm off its centre, turned 90 degrees about y: the
    # offset (0.05, 0, 0) points down, so the centre is 0.05 above the centre of mass.
    scene = load(case(body("ball", "{ sphere = { radius = 0.1 } }",
                           extra="com = [0.05, 0.0, 0.0]")))
    q = axis_angle_to_quat(np.array([0.0, 1.0, 0.0]), math.pi / 2)
    r = quat_to_matrix(q)
    assert r @ [0.05, 0, 0] == pytest.approx([0, 0, -0.05])
    # centre at 0.098 (2 mm in), so the centre of mass at 0.048
    ms = metrics(scene, still(scene, T20, [[0.0, 0.0, 0.048]], quat=q))
    assert ms["penetration_max"].value == pytest.approx(2e-3, rel=1e-9)


def test_box_standing_on_a_corner():
    # The body diagonal of a cube of side s turned onto the vertical: the lowest corner is
    # s sqrt(3) / 2 below the centre. Turn (1, 1, 1) onto (0, 0, -1) -- then (-1, -1, -1) is up.
    s = 0.2
    scene = load(case(body("cube", f"{{ box = {{ size = [{s}, {s}, {s}] }} }}")))
    d = np.array([1.0, 1.0, 1.0]) / math.sqrt(3)
    axis = np.cross(d, [0, 0, -1.0])
    angle = math.acos(np.dot(d, [0, 0, -1.0]))
    q = axis_angle_to_quat(axis / np.linalg.norm(axis), angle)
    corners = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)]) * s / 2
    lowest = (corners @ quat_to_matrix(q).T)[:, 2].min()
    assert lowest == pytest.approx(-s * math.sqrt(3) / 2, rel=1e-12)
    height = s * math.sqrt(3) / 2 - 0.002
    ms = metrics(scene, still(scene, T20, [[1.0, 2.0, height]], quat=q))
    assert ms["penetration_max"].value == pytest.approx(0.002, rel=1e-9)
    # the orientation is used: flat, the cube is 0.071 m above the ground there; flat at 0.097
    # it is 3 mm in, where on its corner it would be 0.076 m in
    ms = metrics(scene, still(scene, T20, [[1.0, 2.0, height]]))
    assert ms["penetration_max"].value == 0.0
    ms = metrics(scene, still(scene, T20, [[1.0, 2.0, 0.097]]))
    assert ms["penetration_max"].value == pytest.approx(0.003, rel=1e-9)


def test_two_overlapping_spheres_without_a_ground():
    scene = load(case(body("a", "{ sphere = { radius = 0.1 } }")
                      + body("b", "{ sphere = { radius = 0.15 } }", "[1, 0, 0]"),
                      ground=None, gravity="[0, 0, 0]"))
    com = [[0.0, 0.0, 0.0], [0.12, 0.16, 0.0]]  # 0.2 apart: 0.05 deep
    ms = metrics(scene, still(scene, T20, com))
    assert ms["penetration_max"].value == pytest.approx(0.05, rel=1e-12)
    assert ms["penetration_resting_mean"].value == pytest.approx(0.05, rel=1e-12)
    com = [[0.0, 0.0, 0.0], [0.3, 0.0, 0.0]]
    assert metrics(scene, still(scene, T20, com))["penetration_max"].value == 0.0


def test_collide_false_pairs_are_not_measured():
    text = case(body("a", "{ sphere = { radius = 0.1 } }")
                + body("b", "{ sphere = { radius = 0.1 } }", "[1, 0, 0]"),
                ground=None, gravity="[0, 0, 0]",
                statics='[[contact_pairs]]\na = "a"\nb = "b"\ncollide = false\n')
    scene = load(text)
    ms = metrics(scene, still(scene, T20, [[0.0, 0, 0], [0.1, 0, 0]]))
    assert ms["penetration_max"].value is None  # no pair can touch at all
    assert "no pair" in ms["penetration_max"].note


def test_sphere_against_a_rotated_static_box():
    # Box 0.4 x 0.2 x 0.2 turned 30 degrees about z; a sphere near its (+x, +y) edge, outside
    # by (a, b) from the edge in box coordinates: distance hypot(a, b), depth r - hypot(a, b).
    q = axis_angle_to_quat(np.array([0.0, 0.0, 1.0]), math.pi / 6)
    statics = f"""
[[statics]]
name = "block"
shape = {{ box = {{ size = [0.4, 0.2, 0.2] }} }}
position = [1.0, 0.5, 0.3]
orientation = [{float(q[0])!r}, {float(q[1])!r}, {float(q[2])!r}, {float(q[3])!r}]
"""
    scene = load(case(body("ball", "{ sphere = { radius = 0.1 } }"), ground=None,
                      gravity="[0, 0, 0]", statics=statics))
    a, b = 0.03, 0.04
    local = np.array([0.2 + a, 0.1 + b, 0.0])
    centre = np.array([1.0, 0.5, 0.3]) + quat_to_matrix(q) @ local
    ms = metrics(scene, still(scene, T20, [centre]))
    assert ms["penetration_max"].value == pytest.approx(0.1 - 0.05, rel=1e-9)
    # the centre inside the box, 0.03 below the +y face: depth r + 0.03
    local = np.array([0.0, 0.07, 0.0])
    centre = np.array([1.0, 0.5, 0.3]) + quat_to_matrix(q) @ local
    ms = metrics(scene, still(scene, T20, [centre]))
    assert ms["penetration_max"].value == pytest.approx(0.13, rel=1e-9)


def _hull_depth(points: np.ndarray) -> float:
    """Penetration depth from the Minkowski difference A - B (its vertices ``points``): the
    distance from the origin to the hull's boundary when the origin is inside, else 0."""
    hull = ConvexHull(points)
    offsets = -hull.equations[:, -1]  # n . x <= offset inside, n unit
    return max(0.0, float(offsets.min()))


def _random_quat(rng) -> np.ndarray:
    q = rng.normal(size=4)
    return q / np.linalg.norm(q)


def test_rotated_3d_boxes_match_the_minkowski_difference():
    ha, hb = np.array([0.3, 0.2, 0.1]), np.array([0.25, 0.15, 0.2])
    scene = load(case(body("a", "{ box = { size = [0.6, 0.4, 0.2] } }")
                      + body("b", "{ box = { size = [0.5, 0.3, 0.4] } }", "[2, 0, 0]"),
                      ground=None, gravity="[0, 0, 0]"))
    signs = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)])
    rng = np.random.default_rng(7)
    checked = 0
    for _ in range(60):
        qa, qb = _random_quat(rng), _random_quat(rng)
        xa, xb = rng.uniform(-0.1, 0.1, 3), rng.uniform(-0.45, 0.45, 3)
        ca = xa + (signs * ha) @ quat_to_matrix(qa).T
        cb = xb + (signs * hb) @ quat_to_matrix(qb).T
        expected = _hull_depth((ca[:, None] - cb[None]).reshape(-1, 3))
        traj = traj3(T20[:2], [[xa, xb]] * 2, quat=np.array([qa, qb]))
        got = metrics(scene, traj)["penetration_max"].value
        assert got == pytest.approx(expected, abs=1e-12), (qa, qb, xa, xb)
        checked += expected > 0
    assert checked > 20  # most of the draws overlap, some do not


def test_2d_boxes_and_polygons_match_the_minkowski_difference():
    tri = "{ polygon = { vertices = [[0, 0], [0.4, 0], [0.1, 0.3]] } }"
    scene = load(case(body("a", "{ box = { size = [0.6, 0.2] } }", "[0, 0]")
                      + body("b", "{ box = { size = [0.3, 0.5] } }", "[1, 0]")
                      + body("c", tri, "[3, 0]"),
                      dimension=2, ground=None, gravity="[0, 0]"))
    verts = [np.array([[-0.3, -0.1], [0.3, -0.1], [0.3, 0.1], [-0.3, 0.1]]),
             np.array([[-0.15, -0.25], [0.15, -0.25], [0.15, 0.25], [-0.15, 0.25]]),
             np.array([[0, 0], [0.4, 0], [0.1, 0.3]])]
    coms = [np.zeros(2), np.zeros(2), verts[2].mean(axis=0)]
    rng = np.random.default_rng(3)

    def world(k, x, th):
        r = np.array([[math.cos(th), -math.sin(th)], [math.sin(th), math.cos(th)]])
        return x + (verts[k] - coms[k]) @ r.T

    for _ in range(60):
        xs = [rng.uniform(-0.3, 0.3, 2) for _ in range(3)]
        ths = rng.uniform(-math.pi, math.pi, 3)
        expected = 0.0
        for i in range(3):
            for j in range(i + 1, 3):
                pts = (world(i, xs[i], ths[i])[:, None] - world(j, xs[j], ths[j])[None])
                expected = max(expected, _hull_depth(pts.reshape(-1, 2)))
        traj = traj2(T20[:2], [xs] * 2, angle=ths)
        got = metrics(scene, traj)["penetration_max"].value
        assert got == pytest.approx(expected, abs=1e-12)


WALL = """
[[statics]]
name = "wall"
shape = { box = { size = [0.1, 1, 1] } }
position = [1, 0, 0.5]
"""


def test_a_capsule_against_a_box_is_measured_by_fcl_to_the_minkowski_depth():
    # No closed form: FCL's EPA. A capsule is a segment swelled by r, so where its segment
    # crosses the box the depth is the segment-box Minkowski depth plus r, exactly.
    r, length = 0.05, 0.2
    scene = load(case(body("pill", f"{{ capsule = {{ radius = {r}, length = {length} }} }}",
                           "[0, 0, 0.5]"), statics=WALL, ground=None, gravity="[0, 0, 0]"))
    box = np.array([[x, y, z] for x in (0.95, 1.05) for y in (-0.5, 0.5) for z in (0.0, 1.0)])
    rng = np.random.default_rng(11)
    checked = 0
    for _ in range(40):
        q = _random_quat(rng)
        # the segment's middle inside the wall: the segment crosses it
        x = np.array([rng.uniform(0.96, 1.04), rng.uniform(-0.3, 0.3), rng.uniform(0.3, 0.7)])
        axis = quat_to_matrix(q)[:, 2]
        ends = np.array([x - 0.5 * length * axis, x + 0.5 * length * axis])
        segment_depth = _hull_depth((ends[:, None] - box[None]).reshape(-1, 3))
        assert segment_depth > 0
        expected = segment_depth + r
        got = metrics(scene, still(scene, T20[:2], [x], quat=q))["penetration_max"].value
        assert got == pytest.approx(expected, abs=2e-6)  # EPA on a curved surface: 1e-6 m
        checked += 1
    assert checked == 40


def test_a_pair_type_without_a_depth_method_is_not_measurable(monkeypatch):
    from crosscheck.compare import convex_gap

    monkeypatch.setattr(convex_gap, "available", lambda: False)  # as without FCL
    scene = load(case(body("pill", "{ capsule = { radius = 0.05, length = 0.2 } }",
                           "[0, 0, 0.15]"), statics=WALL))
    ms = metrics(scene, still(scene, T20, [[0.0, 0.0, 0.15]]))
    for name in ("penetration_max", "penetration_resting_mean"):
        assert ms[name].value is None
        assert not ms[name].meaningful
        assert "capsule-box (pill, wall)" in ms[name].note
    # the capsule against the ground alone is measured (by its support point)
    scene = load(case(body("pill", "{ capsule = { radius = 0.05, length = 0.2 } }",
                           "[0, 0, 0.15]")))
    ms = metrics(scene, still(scene, T20, [[0.0, 0.0, 0.149]]))
    assert ms["penetration_max"].value == pytest.approx(1e-3, rel=1e-9)
    q = axis_angle_to_quat(np.array([1.0, 0.0, 0.0]), math.pi / 2)  # lying: radius down
    ms = metrics(scene, still(scene, T20, [[0.0, 0.0, 0.047]], quat=q))
    assert ms["penetration_max"].value == pytest.approx(3e-3, rel=1e-9)


def test_a_thousand_sphere_pile_is_not_quadratic():
    # A 10 x 10 x 10 lattice of spheres of radius 0.05 at spacing 0.099: every lattice
    # neighbour overlaps by 1 mm, diagonal ones do not; the bottom layer is 1 mm into the ground.
    r, step = 0.05, 0.099
    bodies = "".join(
        body(f"s{i}", f"{{ sphere = {{ radius = {r} }} }}", f"[{i * 0.2}, 0, 1]")
        for i in range(1000))
    scene = load(case(bodies))
    grid = np.array([[x, y, z] for x in range(10) for y in range(10) for z in range(10)], float)
    com = grid * step + [0, 0, r - 1e-3]
    t = np.linspace(0, 1, 11)
    traj = traj3(t, np.broadcast_to(com, (len(t), 1000, 3)))
    start = time.perf_counter()
    pen = cm.penetration(scene, traj)
    out = MetricSet()
    cm.contact_metrics(scene, traj, out, total_energy(scene, traj), traj)
    elapsed = time.perf_counter() - start
    depth = np.maximum(0, -pen.rows.gap)
    assert depth.max() == pytest.approx(1e-3, rel=1e-9)
    # per sample: 3 x 10 x 10 x 9 = 2700 overlapping neighbour pairs and 100 on the ground
    in_contact = pen.rows.gap <= pen.rows.tol
    assert np.count_nonzero(in_contact & (pen.rows.kind == 0)) == 2700 * len(t)
    assert np.count_nonzero(in_contact & (pen.rows.kind == 2)) == 100 * len(t)
    # the sweep examined only near pairs, not the 499 500 of the pile
    assert np.count_nonzero(pen.rows.kind == 0) < 20000 * len(t)
    assert elapsed < 3.0  # about 0.3 s; all pairs per sample in Python would take minutes
    assert out.metrics["penetration_max"].value == pytest.approx(1e-3, rel=1e-9)
    assert out.metrics["penetration_resting_mean"].value == pytest.approx(1e-3, rel=1e-9)


def test_resting_mean_uses_only_the_final_resting_stretch():
    # A ball rests 2 mm deep until t = 0.2, moves (3 mm deep at t = 0.3), then rests 1 mm deep
    # from t = 0.5: only the last stretch counts.
    scene = load(case(body("ball", "{ sphere = { radius = 0.1 } }")))
    t = np.linspace(0, 1, 101)
    z = np.where(t < 0.5, 0.2, 0.099)
    vz = np.where(t < 0.5, -1.0, 0.0)
    z[:21], vz[:21] = 0.098, 0.0
    z[30] = 0.097
    traj = traj3(t, np.stack([0 * t, 0 * t, z], -1), vel=np.stack([0 * t, 0 * t, vz], -1))
    ms = metrics(scene, traj)
    assert ms["penetration_max"].value == pytest.approx(3e-3, rel=1e-9)
    assert ms["penetration_resting_mean"].value == pytest.approx(1e-3, rel=1e-9)
    assert "51 samples" in ms["penetration_resting_mean"].note
    # resting only over the last 5 % (less than REST_FRACTION): not a resting pair
    z = np.where(t < 0.96, 0.2, 0.099)
    traj = traj3(t, np.stack([0 * t, 0 * t, z], -1))
    assert metrics(scene, traj)["penetration_resting_mean"].value is None


# -- energy
def test_energy_gain_zero_when_losing_and_the_gain_when_gaining():
    scene = load(case(body("ball", "{ sphere = { radius = 0.1 } }")))
    t = np.linspace(0, 1, 101)
    # sliding on the ground, losing speed: only loses energy
    v = np.stack([2.0 - t, 0 * t, 0 * t], -1)
    com = np.stack([2 * t - t**2 / 2, 0 * t, 0.1 + 0 * t], -1)
    ms = metrics(scene, traj3(t, com, vel=v))
    assert ms["energy_gain"].value == 0.0
    assert ms["energy_gain"].meaningful
    # gaining speed from 1 to 2 m/s: gain 1/2 (4 - 1) = 1.5 J on S_E = max T = 2 J
    v = np.stack([1.0 + t, 0 * t, 0 * t], -1)
    com = np.stack([t + t**2 / 2, 0 * t, 0.1 + 0 * t], -1)
    ms = metrics(scene, traj3(t, com, vel=v))
    s_e = max(2.0, 1.0 * G * 0.1)
    assert ms["energy_gain"].value == pytest.approx(1.5 / s_e, rel=1e-12)
    # a ball that ends higher than it started with the same speed: gain m g dz
    com = np.stack([0 * t, 0 * t, 0.1 + 0.05 * t], -1)
    traj = traj3(t, com, vel=np.tile([0.0, 0.0, 0.05], (len(t), 1)))
    ms = metrics(scene, traj)
    assert ms["energy_gain"].value == pytest.approx(G * 0.05 / (G * 0.1), rel=1e-9)


# -- impacts
def bounce_motion(t, h0, e, g=G, r=0.1):
    """Centre height and vertical velocity of a ball dropped from rest with its bottom h0 above
    the ground, bouncing with restitution e at gap 0 (instantaneous): piecewise parabolic."""
    z, v = np.empty_like(t), np.empty_like(t)
    t_hit, speed = math.sqrt(2 * h0 / g), math.sqrt(2 * g * h0)
    hits = [t_hit]
    start, v0, z0 = 0.0, 0.0, h0
    for k in range(len(t)):
        while t[k] >= t_hit:
            start, v0, z0 = t_hit, e * speed, 0.0
            speed *= e
            t_hit = start + 2 * v0 / g if speed > 1e-3 else math.inf  # then at rest (Zeno)
            hits.append(t_hit)
        s = t[k] - start
        z[k] = z0 + v0 * s - g * s * s / 2
        v[k] = v0 - g * s
    return z + r, v, hits


def bounce_case(extra="", e=0.5):
    return load(case(body("ball", "{ sphere = { radius = 0.1 } }"),
                     ground=f"material = {{ friction = 0.0, restitution = {e} }}",
                     extra=extra, duration=3.0))


def test_bounce_restitution_is_exact_with_the_free_flight_correction():
    scene = bounce_case()
    t = np.round(np.arange(0, 3.0 + 1e-9, 0.01), 12)
    z, vz, hits = bounce_motion(t, 1.0, 0.5)
    traj = traj3(t, np.stack([0 * t, 0 * t, z], -1), vel=np.stack([0 * t, 0 * t, vz], -1))
    found = cm.impacts(scene, traj, 0)
    resolvable = [imp for imp in found if imp.resolvable]
    # approach speeds 4.43, 2.21, 1.11, 0.55 are resolvable (>= 2 g dt / e = 0.39 m/s); 0.28 not
    assert len(resolvable) == 4
    speeds = math.sqrt(2 * G * 1.0) * 0.5 ** np.arange(4)
    for imp, v, t_hit in zip(resolvable, speeds, hits, strict=False):
        assert imp.v_in == pytest.approx(v, rel=1e-9)
        assert imp.e == pytest.approx(0.5, rel=1e-9)
        assert imp.t_before < t_hit < imp.t_after
        assert imp.t_after - imp.t_before == pytest.approx(0.01)
    ms = metrics(scene, traj)
    assert ms["restitution_first"].value == pytest.approx(0.5, rel=1e-9)
    assert ms["restitution_error_max"].value == pytest.approx(0.0, abs=1e-9)
    # the same motion judged against a pair restitution of 0.6: error 0.1
    ms = metrics(bounce_case(e=0.6), traj)
    assert ms["restitution_error_max"].value == pytest.approx(0.1, rel=1e-8)


def test_bounce_restitution_without_the_correction_has_the_derived_bias():
    # Drag on the ball (not in the prescribed motion) removes free flight's constant
    # acceleration: the raw sampled velocities are used, e_m = (e v_c - g b) / (v_c - g a),
    # a = t_c - t_before, b = t_after - t_c.
    scene = bounce_case('[[effects.drag]]\nlinear = 0.001\nbodies = ["ball"]')
    t = np.round(np.arange(0, 3.0 + 1e-9, 0.01), 12)
    z, vz, hits = bounce_motion(t, 1.0, 0.5)
    traj = traj3(t, np.stack([0 * t, 0 * t, z], -1), vel=np.stack([0 * t, 0 * t, vz], -1))
    found = [imp for imp in cm.impacts(scene, traj, 0) if imp.resolvable]
    assert len(found) >= 3
    v_c = math.sqrt(2 * G)
    for imp, t_c in zip(found, hits, strict=False):
        a, b = t_c - imp.t_before, imp.t_after - t_c
        expected = (0.5 * v_c - G * b) / (v_c - G * a)
        assert imp.e == pytest.approx(expected, rel=1e-9)
        assert abs(imp.e - 0.5) <= G * 0.01 / (v_c - G * 0.01) + 1e-12
        assert abs(imp.e - 0.5) > 1e-4  # a real bias, not the corrected value
        v_c *= 0.5


def test_a_ball_that_does_not_bounce_measures_zero():
    # lands at 4.43 m/s and stays: e = 0 against e_pair = 0.5
    scene = bounce_case()
    t = np.round(np.arange(0, 1.0 + 1e-9, 0.01), 12)
    t_hit = math.sqrt(2 / G)
    z = np.where(t < t_hit, 1.1 - G * t**2 / 2, 0.1)
    vz = np.where(t < t_hit, -G * t, 0.0)
    traj = traj3(t, np.stack([0 * t, 0 * t, z], -1), vel=np.stack([0 * t, 0 * t, vz], -1))
    (imp,) = cm.impacts(scene, traj, 0)
    assert imp.resolvable and not imp.separated and imp.e == 0.0
    assert metrics(scene, traj)["restitution_error_max"].value == pytest.approx(0.5)


# -- sliding and rolling
def test_box_sliding_to_rest_with_constant_deceleration():
    mu, v0 = 0.3, 2.0
    scene = load(case(body("box", "{ box = { size = [0.2, 0.2, 0.2] } }"),
                      ground=f"material = {{ friction = {mu} }}"))
    t = np.round(np.arange(0, 1.0 + 1e-9, 0.01), 12)
    dec = mu * G
    t_stop = v0 / dec
    s = np.minimum(t, t_stop)
    x = v0 * s - dec * s**2 / 2
    v = np.maximum(v0 - dec * t, 0.0)
    d = np.array([0.6, 0.8, 0.0])  # sliding at an angle to the axes
    vel = v[:, None] * d
    vel[:, 2] = 0.01 * np.cos(40 * t)  # a normal jitter that never stops: only v_t counts
    traj = traj3(t, x[:, None] * d + [0.5, 0.5, 0.1], vel=vel)
    ms = metrics(scene, traj)
    speed = cm.STOP_SPEED
    assert ms["stop_time"].value == pytest.approx((v0 - speed) / dec, rel=1e-12)
    assert ms["stop_distance"].value == pytest.approx((v0**2 - speed**2) / (2 * dec), rel=1e-12)
    assert ms["stop_distance"].value == pytest.approx(v0**2 / (2 * dec), rel=1e-6)
    assert ms["stop_distance"].unit == "m"
    assert "slip_velocity_max" not in ms  # a box does not roll
    # never stopping: not measurable
    traj = traj3(t, (v0 * t)[:, None] * d + [0.5, 0.5, 0.1], vel=np.tile(v0 * d, (len(t), 1)))
    ms = metrics(scene, traj)
    assert ms["stop_distance"].value is None and not ms["stop_distance"].meaningful


@pytest.mark.parametrize("slip_fraction", [0.0, 0.3])
def test_sphere_rolling_and_slipping(slip_fraction):
    # Rolling along +x on a +z ground: the contact point moves at v - w_y r, so rolling is
    # w_y = v / r. Slipping: w_y = (1 - f) v / r, slip f v.
    r, acc = 0.1, 3.5
    scene = load(case(body("ball", f"{{ sphere = {{ radius = {r} }} }}")))
    t = np.linspace(0, 1, 101)
    v = 0.5 + acc * t
    x = 0.5 * t + acc * t**2 / 2
    w = (1 - slip_fraction) * v / r
    zeros = 0 * t
    traj = traj3(t, np.stack([x, zeros, zeros + r], -1), vel=np.stack([v, zeros, zeros], -1),
                 omega=np.stack([zeros, w, zeros], -1))
    ms = metrics(scene, traj)
    assert ms["slip_velocity_max"].value == pytest.approx(slip_fraction * v[-1], abs=1e-12)
    if slip_fraction == 0:
        assert ms["rolling_acceleration"].value == pytest.approx(acc, rel=1e-9)
    else:
        assert ms["rolling_acceleration"].value is None
    slip = cm.slip_velocity(scene, traj)
    assert slip == pytest.approx(slip_fraction * v, abs=1e-12)


def test_disc_rolling_in_2d():
    r = 0.2
    scene = load(case(body("disc", f"{{ circle = {{ radius = {r} }} }}", "[0, 0.2]"),
                      dimension=2))
    t = np.linspace(0, 1, 51)
    v = 1.0 - 0.5 * t
    x = t - 0.25 * t**2
    # rolling to +x with +y up: w = -v / r (clockwise)
    traj = traj2(t, np.stack([x, 0 * t + r], -1), vel=np.stack([v, 0 * t], -1),
                 angle=-x / r, omega=-v / r)
    ms = metrics(scene, traj)
    assert ms["slip_velocity_max"].value == pytest.approx(0.0, abs=1e-12)
    assert ms["rolling_acceleration"].value == pytest.approx(-0.5, rel=1e-9)
    traj = traj2(t, np.stack([x, 0 * t + r], -1), vel=np.stack([v, 0 * t], -1), omega=v / r)
    assert metrics(scene, traj)["slip_velocity_max"].value == pytest.approx(2.0, rel=1e-12)


# -- resting and structures
def stack_case():
    return load(case("".join(body(f"b{k}", "{ box = { size = [1, 1, 1] } }", f"[0, 0, {k + 0.5}]")
                             for k in range(3)), duration=5.0))


def test_a_standing_stack_and_a_collapsing_one():
    scene = stack_case()
    t = np.linspace(0, 5, 501)
    com = np.array([[0, 0, k + 0.5] for k in range(3)], float)
    ms = metrics(scene, still(scene, t, com))
    assert ms["rest_drift_max"].value == 0.0
    assert ms["time_to_rest"].value == 0.0
    assert "collapse_time" not in ms
    assert ms["penetration_max"].value == 0.0
    assert ms["penetration_resting_mean"].value == 0.0
    # the top box creeps 2 mm sideways from t = 1 s, then slides off from t = 3 s at 0.5 m/s
    pos = np.broadcast_to(com, (len(t), 3, 3)).copy()
    vel = np.zeros_like(pos)
    creep = np.clip(t - 1.0, 0, 2.0) * 1e-3
    off = np.clip(t - 3.0, 0, None) * 0.5
    pos[:, 2, 0] += creep + off
    vel[:, 2, 0] = np.where((t > 1) & (t < 3), 1e-3, 0.0) + np.where(t > 3, 0.5, 0.0)
    ms = metrics(scene, traj3(t, pos, vel=vel))
    r = scales.body_radius(scene.bodies[2])
    assert ms["rest_drift_max"].value == pytest.approx(pos[-1, 2, 0] - pos[50, 2, 0])
    # collapse: more than 0.1 r = 0.0866 m from its position at t = 0.5 s
    k = np.nonzero(pos[:, 2, 0] - pos[50, 2, 0] > cm.COLLAPSE_FRACTION * r)[0][0]
    assert ms["collapse_time"].value == pytest.approx(t[k])
    assert 3.1 < t[k] < 3.3
    assert ms["time_to_rest"].value is None


def test_a_fall_inside_the_settle_window_shows_in_collapse_time_start():
    # The top box slides off within the first 0.3 s (the settle window is 0.5 s) and lies
    # still: measured from the settled pose nothing moves, from the start it fell.
    scene = stack_case()
    t = np.linspace(0, 5, 501)
    com = np.array([[0, 0, k + 0.5] for k in range(3)], float)
    pos = np.broadcast_to(com, (len(t), 3, 3)).copy()
    pos[:, 2, 0] += np.clip(t, 0, 0.3) * 5.0
    pos[:, 2, 2] -= np.clip(t - 0.2, 0, 0.1) * 20.0  # down onto the ground: 2.5 -> 0.5 m
    ms = metrics(scene, traj3(t, pos))
    assert "collapse_time" not in ms
    r = scales.body_radius(scene.bodies[2])
    k = np.nonzero(np.linalg.norm(pos[:, 2] - pos[0, 2], axis=-1) > cm.COLLAPSE_FRACTION * r)[0][0]
    assert ms["collapse_time_start"].value == pytest.approx(t[k])
    # A stack that stands has neither.
    assert "collapse_time_start" not in metrics(scene, still(scene, t, com))


def test_time_to_rest_is_when_every_body_stays_slow():
    scene = load(case(body("ball", "{ sphere = { radius = 0.1 } }")))
    t = np.linspace(0, 1, 101)
    w = np.where(t < 0.42, 0.5, 0.001)  # rim speed 0.05, then 1e-4 m/s
    zeros = 0 * t
    traj = traj3(t, np.stack([zeros, zeros, zeros + 0.1], -1),
                 omega=np.stack([zeros, zeros, w], -1))
    assert metrics(scene, traj)["time_to_rest"].value == pytest.approx(0.42)


# -- frame invariance
def test_shifting_the_whole_scene_changes_no_figure():
    def scene_at(shift):
        n = np.array([0.0, 0.6, 0.8])
        statics = f"""
[[statics]]
name = "block"
shape = {{ box = {{ size = [0.4, 0.4, 0.4] }} }}
position = [{1.0 + shift[0]}, {shift[1]}, {0.2 + shift[2]}]
"""
        ground = (f"normal = [0, 0.6, 0.8]\noffset = {float(n @ shift)!r}\n"
                  "material = { friction = 0.2, restitution = 0.5 }")
        bodies = (body("ball", "{ sphere = { radius = 0.1 } }")
                  + body("cube", "{ box = { size = [0.2, 0.2, 0.2] } }", "[1, 0, 0]")
                  + body("cube2", "{ box = { size = [0.2, 0.3, 0.2] } }", "[2, 0, 0]"))
        return load(case(bodies, ground=ground, statics=statics, gravity="[0, -5.886, -7.848]"))

    rng = np.random.default_rng(11)
    t = np.round(np.arange(0, 1.0 + 1e-9, 0.01), 12)
    base = np.array([[0.0, 0.0, 0.3], [0.8, 0.0, 0.4], [0.7, 0.1, 0.55]])
    com = base + 0.02 * np.sin(7 * t)[:, None, None] * rng.normal(size=(3, 3))
    vel = 0.14 * np.cos(7 * t)[:, None, None] * rng.normal(size=(3, 3))
    quat = np.stack([quat_mul(_random_quat(rng), axis_angle_to_quat(np.array([0, 0, 1.0]), 0.1 * k))
                     for k in range(3)])
    omega = np.tile(rng.normal(size=(3, 3)), (len(t), 1, 1))
    traj = traj3(t, com, vel=vel, quat=quat, omega=omega)
    ref = metrics(scene_at(np.zeros(3)), traj)
    assert ref["penetration_max"].value > 0
    shift = np.array([120.0, -35.0, 7.5])
    moved = traj3(t, com + shift, vel=vel, quat=quat, omega=omega)
    got = metrics(scene_at(shift), moved)
    contact_names = [k for k in ref if k in cm.UNITS or k.startswith(("restitution", "energy_g"))]
    assert "penetration_max" in contact_names and "energy_gain" in contact_names
    for name in contact_names:
        a, b = ref[name].value, got[name].value
        if a is None:
            assert b is None, name
        else:
            assert b == pytest.approx(a, rel=1e-9, abs=1e-12), name


def test_the_penetration_series_is_the_deepest_pair_at_each_sample():
    # The report plots it: at every sample, the largest depth over the colliding pairs.
    from crosscheck.compare.metrics import compute_metrics

    scene = load_case_text(_SERIES_CASE)
    t = np.array([0.0, 0.1, 0.2])
    z = np.array([0.1005, 0.0990, 0.0997])  # sphere of radius 0.1 above, 1 mm in, 0.3 mm in
    traj = Trajectory(t=t, com=np.array([[[0.0, 0.0, zz]] for zz in z]),
                      vel=np.zeros((3, 1, 3)), omega=np.zeros((3, 1, 3)),
                      quat=np.tile([1.0, 0.0, 0.0, 0.0], (3, 1, 1)))
    series = compute_metrics(scene, traj).series["penetration"]
    np.testing.assert_allclose(series["y"], [0.0, 1e-3, 3e-4], atol=1e-12)


_SERIES_CASE = """
[case]
name = "series"
dimension = 3
[run]
duration = 0.2
dt = 1e-3
sample_every = 0.1
[effects]
contact = true
[ground]
[[bodies]]
name = "ball"
shape = { sphere = { radius = 0.1 } }
mass = 1.0
position = [0.0, 0.0, 0.1005]
"""
