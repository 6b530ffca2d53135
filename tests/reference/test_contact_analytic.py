"""The contact analytic references (crosscheck.reference.contact_analytic) and the contact cases.

Each solution against hand calculations (the numbers of ../shared CONTACTS.md), the bounce
against an independent time-stepped simulation of the same idealised model, refusals of scenes
outside the assumptions, and every extra metric on synthetic runs whose error is known exactly:
runs made by the same solution on a scene with one value changed (restitution, friction, inertia),
so the expected metric follows from the formulas by hand.
"""

from __future__ import annotations

import glob
import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from crosscheck.reference.analytic import EXTRA_METRICS, SOLUTIONS
from crosscheck.scene.loader import load_case, load_case_text

CASES = Path(__file__).resolve().parents[2] / "cases"
CONTACT_CASES = sorted(glob.glob(str(CASES / "contact" / "*.toml")))
G = 9.81
S30, C30 = math.sin(math.radians(30)), math.cos(math.radians(30))


def _scene(body: str, *, dim: int = 3, gravity=None, ground: str = "", extra: str = "",
           duration: float = 2.0, dt: float = 1e-3, sample: float = 0.01, material: str = "",
           solution: str = "bounce"):
    gravity = gravity if gravity is not None else ([0.0, 0.0, -G] if dim == 3 else [0.0, -G])
    grav = "" if gravity is False else f"gravity = {list(gravity)}\n"
    text = f"""
[case]
name = "t"
dimension = {dim}
[run]
duration = {duration}
dt = {dt}
sample_every = {sample}
[effects]
{grav}contact = true
{material}
{ground}
{body}
{extra}
[reference]
kind = "analytic"
solution = "{solution}"
"""
    return load_case_text(text, name="test.toml")


def _ball(z=1.1, e=0.5, mu=0.5, dim=3, velocity=None, radius=0.1, **kw):
    pos = [0.0, 0.0, z] if dim == 3 else [0.0, z]
    shape = "sphere" if dim == 3 else "circle"
    vel = f"velocity = {list(velocity)}\n" if velocity is not None else ""
    body = f"""[[bodies]]
name = "ball"
shape = {{ {shape} = {{ radius = {radius} }} }}
mass = 1.0
position = {pos}
{vel}material = {{ friction = {mu}, restitution = {e} }}
"""
    return _scene(body, dim=dim, ground="[ground]\nmaterial = { friction = 0.5 }", **kw)


def _run(scene, solution=None):
    return SOLUTIONS[solution or scene.reference.solution](scene, scene.run.sample_times())


def _metrics(scene, run):
    return EXTRA_METRICS[scene.reference.solution](scene, run)


# -- bounce ----------------------------------------------------------------------------------------
def test_bounce_by_hand():
    scene = _ball(z=1.1, e=0.5)
    t1 = math.sqrt(2 * 1.0 / G)
    v1 = G * t1
    times = np.array([0.0, 0.5 * t1, t1, t1 + 0.5 * v1 / G, t1 + v1 / G, 10.0])
    traj = SOLUTIONS["bounce"](scene, times)
    z = traj.com[:, 0, 2]
    assert z[0] == 1.1
    assert z[1] == pytest.approx(1.1 - 0.5 * G * (0.5 * t1) ** 2, rel=1e-14)
    assert z[2] == pytest.approx(0.1, abs=1e-14)
    # the first apex is e^2 h0 = 0.25 m above the contact height, at t1 + e v1 / g
    assert z[3] == pytest.approx(0.1 + 0.25, rel=1e-13)
    assert traj.vel[3, 0, 2] == pytest.approx(0.0, abs=1e-12)
    assert z[4] == pytest.approx(0.1, abs=1e-13)  # the second impact
    # Zeno: every bounce is over by t1 + 2 e v1 / (g (1 - e)) = 3 t1; then at rest
    assert z[5] == 0.1 and traj.vel[5, 0, 2] == 0.0
    np.testing.assert_array_equal(traj.com[:, 0, :2], 0.0)
    np.testing.assert_array_equal(traj.quat[:, 0], [[1, 0, 0, 0]] * len(times))
    assert traj.meta["impacts"][:2] == pytest.approx([t1, t1 + v1 / G], rel=1e-14)


def test_bounce_thrown_up_and_sideways_when_frictionless_2d():
    scene = _ball(z=0.1, e=1.0, mu=0.0, dim=2, velocity=[0.3, 2.0])
    scene = replace(scene, ground=replace(scene.ground, material=replace(
        scene.ground.material, friction=0.0)))
    t = np.array([0.2, 2 * 2.0 / G, 2 * 2.0 / G + 0.1])
    traj = SOLUTIONS["bounce"](scene, t)
    assert traj.com[0, 0, 1] == pytest.approx(0.1 + 2.0 * 0.2 - 0.5 * G * 0.04, rel=1e-14)
    assert traj.com[1, 0, 1] == pytest.approx(0.1, abs=1e-14)  # back on the ground at 2 w0 / g
    assert traj.vel[2, 0, 1] == pytest.approx(2.0 - G * 0.1, rel=1e-13)  # e = 1: same again
    np.testing.assert_allclose(traj.com[:, 0, 0], 0.3 * t, rtol=1e-15)
    np.testing.assert_array_equal(traj.angle[:, 0], 0.0)


def _stepped_bounce(h0, e, t_out, h=1e-5):
    """An independent time-stepped model: exact ballistic steps of h, an impact located inside a
    step by its quadratic root and reflected with Newton's law; a bounce slower than g h rests."""
    t, z, w = 0.0, h0, 0.0
    out, k = [], 0
    resting = False
    for target in t_out:
        while t < target - 1e-12:
            step = min(h, target - t)
            if resting:
                t += step
                continue
            z_new = z + w * step - 0.5 * G * step * step
            if z_new < 0.0:
                tau = (w + math.sqrt(w * w + 2 * G * z)) / G
                w_hit = w - G * tau
                w = -e * w_hit
                z = 0.0
                if w < G * h:
                    resting, w = True, 0.0
                    t += step
                    continue
                rest = step - tau
                z = w * rest - 0.5 * G * rest * rest
                w -= G * rest
            else:
                z, w = z_new, w - G * step
            t += step
        out.append((z, w))
        k += 1
    return np.array(out)


def test_bounce_against_an_independent_stepped_model():
    scene = _ball(z=1.1, e=0.6, duration=2.0)
    t = np.linspace(0.0, 2.0, 81)
    traj = SOLUTIONS["bounce"](scene, t)
    ref = _stepped_bounce(1.0, 0.6, t)
    np.testing.assert_allclose(traj.com[:, 0, 2] - 0.1, ref[:, 0], atol=1e-9)
    np.testing.assert_allclose(traj.vel[:, 0, 2], ref[:, 1], atol=1e-4)  # at rest: g h


def test_bounce_metrics_on_runs_with_known_errors():
    ideal = _ball(z=1.1, e=1.0, duration=2.5)
    # the ideal run itself, sampled every 0.01 s: apexes and impacts recovered exactly
    m = _metrics(ideal, _run(ideal))
    assert m["apex_height_error_rel"] < 1e-12 and m["impact_time_error"] < 1e-12
    # a run with e = 0.98: apexes 0.98^2 and 0.98^4 of H0, impact 2 at t1 + 2 (0.98 v1) / g
    run = _run(_ball(z=1.1, e=0.98, duration=2.5))
    m = _metrics(ideal, run)
    t1 = math.sqrt(2 / G)
    assert m["apex_height_error_rel"] == pytest.approx(1 - 0.98**4, rel=1e-9)
    assert m["impact_time_error"] == pytest.approx(0.02 * 2 * t1, rel=1e-9)
    # a ball that does not bounce at all: apex 1 missed entirely, impact 2 never happens
    m = _metrics(ideal, _run(_ball(z=1.1, e=0.0, duration=2.5)))
    assert m["apex_height_error_rel"] == pytest.approx(1.0, abs=1e-12)
    assert m["impact_time_error"] == math.inf
    # an inelastic case whose run bounces to e^2 = 4 % of the drop is caught by apex 1 = 0
    dead = _ball(z=0.2, e=0.0, duration=1.0)
    m = _metrics(dead, _run(_ball(z=0.2, e=0.2, duration=1.0)))
    assert m["apex_height_error_rel"] == pytest.approx(0.04, rel=1e-9)
    assert m["impact_time_error"] < 1e-12
    # a run sampled in contact and penetrating (a soft engine): a sample 1 mm deep just after
    # the impact leaves the measured impact time and apex unchanged
    run = _run(ideal)
    j = int(np.searchsorted(run.t, t1))
    run.com[j, 0, 2] -= 1e-3 + (run.com[j, 0, 2] - 0.1)
    run.vel[j, 0, 2] = 0.0
    m = _metrics(ideal, run)
    assert m["apex_height_error_rel"] < 1e-12 and m["impact_time_error"] < 1e-12


def _symplectic_euler_bounce(h0, e, dt, every, n):
    """A velocity-first rigid engine in one dimension: w -= g dt, z += w dt, except on a step that
    starts below the contact height while approaching, where the velocity becomes -e times the
    velocity stored before the step (Chipmunk's pre-step restitution, CONTACTS.md 6(d)). The
    rebound starts up to v dt inside the ground, never corrected (CONTACTS.md 1.1)."""
    z, w, out = h0, 0.0, []
    for i in range(n + 1):
        if i % every == 0:
            out.append((z, w))
        if z < 0.0 and w < 0.0:
            w = -e * w
        else:
            w -= G * dt
        z += w * dt
    return np.array(out)


def test_bounce_metrics_admit_an_idealised_velocity_first_engine():
    # the case's tolerances (0.5 % apex, 3 ms impacts at dt = 1e-3) hold for the O(v dt) offsets
    # of a rigid engine: the rebound starts up to v dt inside the ground
    scene = load_case(CASES / "contact" / "bounce_elastic.toml")
    zw = _symplectic_euler_bounce(1.0, 1.0, 1e-3, 10, 2500)
    run = _run(scene)
    run.com[:, 0, 2] = 0.1 + zw[:, 0]
    run.vel[:, 0, 2] = zw[:, 1]
    m = _metrics(scene, run)
    assert m["apex_height_error_rel"] < 5e-3 and m["impact_time_error"] < 3e-3, m


def test_bounce_refusals():
    with pytest.raises(ValueError, match="friction"):
        _run(_ball(velocity=[1.0, 0.0, 0.0]))
    with pytest.raises(ValueError, match="inside the ground"):
        _run(_ball(z=0.05))
    with pytest.raises(ValueError, match="not along the ground normal"):
        _run(_ball(gravity=[1.0, 0.0, -G]))
    with pytest.raises(ValueError, match="no gravity"):
        _run(_ball(gravity=False))
    box = _scene('[[bodies]]\nname = "b"\nshape = { box = { size = [0.2, 0.2, 0.2] } }\n'
                 'mass = 1.0\nposition = [0, 0, 1]\n', ground="[ground]")
    with pytest.raises(ValueError, match="not a sphere or circle"):
        _run(box, "bounce")
    with pytest.raises(ValueError, match="no \\[ground\\]"):
        _run(_scene('[[bodies]]\nname = "b"\nshape = { sphere = { radius = 0.1 } }\n'
                    'mass = 1.0\nposition = [0, 0, 1]\n'), "bounce")
    off = _ball()
    off = replace(off, bodies=(replace(off.bodies[0], com=np.array([0.01, 0.0, 0.0])),))
    with pytest.raises(ValueError, match="centre of mass"):
        _run(off)


# -- slide_to_rest ---------------------------------------------------------------------------------
def _box(size=(0.2, 0.2, 0.2), mu=0.3, velocity=(2.0, 0.0, 0.0), gravity=None, solution=None,
         duration=1.0, orientation=None, z=None):
    dim = len(size)
    h = size[-1] / 2 if z is None else z
    pos = [0.0, 0.0, h] if dim == 3 else [0.0, h]
    vel = list(velocity)[:dim]
    orient = f"orientation = {orientation}\n" if orientation is not None else ""
    body = f"""[[bodies]]
name = "box"
shape = {{ box = {{ size = {list(size)} }} }}
mass = 1.0
position = {pos}
velocity = {vel}
{orient}material = "m"
"""
    return _scene(body, dim=dim, gravity=gravity, ground='[ground]\nmaterial = "m"',
                  material=f"[materials.m]\nfriction = {mu}\n", duration=duration,
                  solution=solution or "slide_to_rest")


def test_slide_by_hand_3d_and_2d():
    for size in ((0.2, 0.2, 0.2), (0.2, 0.1)):
        scene = _box(size=size)
        traj = SOLUTIONS["slide_to_rest"](scene, np.array([0.0, 0.3, 2 / (0.3 * G), 1.0]))
        x = traj.com[:, 0, 0]
        assert x[1] == pytest.approx(2 * 0.3 - 0.5 * 0.3 * G * 0.09, rel=1e-14)
        assert x[2] == pytest.approx(4 / (2 * 0.3 * G), rel=1e-14)  # 0.6796 m (CONTACTS.md 1.2)
        assert x[3] == x[2] and traj.vel[3, 0, 0] == 0.0
        assert traj.meta["stop_time"] == pytest.approx(0.6796, abs=1e-4)
        assert traj.vel[1, 0, 0] == pytest.approx(2 - 0.3 * G * 0.3, rel=1e-14)


def test_slide_metrics_on_runs_with_known_errors():
    scene = _box()
    m = _metrics(scene, _run(scene))
    assert m["stop_distance_error_rel"] < 1e-14 and m["stop_time_error"] < 1e-12
    run = _run(_box(mu=0.303))  # a run 1 % too grippy
    m = _metrics(scene, run)
    assert m["stop_distance_error_rel"] == pytest.approx(1 - 0.3 / 0.303, rel=1e-9)
    thr = 1e-3
    assert m["stop_time_error"] == pytest.approx((2 - thr) / G * (1 / 0.3 - 1 / 0.303), rel=1e-9)
    run.vel[:, 0, 0] = 0.01  # never stops
    assert _metrics(scene, run)["stop_time_error"] == math.inf


def test_slide_refusals():
    with pytest.raises(ValueError, match="tip over"):  # the mu = 1 cube of CONTACTS.md C14
        _run(_box(mu=1.0))
    with pytest.raises(ValueError, match="frictionless"):
        _run(_box(mu=0.0))
    with pytest.raises(ValueError, match="ends before the body stops"):
        _run(_box(duration=0.5))
    with pytest.raises(ValueError, match="does not start on the ground"):
        _run(_box(z=0.2))
    with pytest.raises(ValueError, match="stand on a face"):
        _run(_box(orientation="{ axis = [0, 1, 0], angle = 0.3 }"))
    with pytest.raises(ValueError, match="not along the ground normal"):
        _run(_box(gravity=[1.0, 0.0, -G]))
    with pytest.raises(ValueError, match="starts at rest"):
        _run(_box(velocity=(0.0, 0.0, 0.0)))


def test_slide_along_a_diagonal_checks_tipping_against_the_corner():
    # mu h_com = 0.12 m: beyond the 0.1 m to the leading edge along x, within the 0.1 sqrt(2) m to
    # the leading corner along the diagonal; 0.15 m is beyond both
    with pytest.raises(ValueError, match="tip over"):
        _run(_box(mu=1.2, duration=1.0))
    v = 2 / math.sqrt(2)
    traj = _run(_box(mu=1.2, velocity=(v, v, 0.0), duration=1.0))
    assert traj.com[-1, 0, 0] == pytest.approx(traj.com[-1, 0, 1])
    assert np.hypot(*traj.com[-1, 0, :2]) == pytest.approx(4 / (2 * 1.2 * G), rel=1e-14)
    with pytest.raises(ValueError, match="tip over"):
        _run(_box(mu=1.5, velocity=(v, v, 0.0)))


# -- roll_incline ----------------------------------------------------------------------------------
def _roller(mu=1.0, dim=3, shape=None, velocity=None, spin=None, orientation=None, gravity=None,
            rolling=0.0, inertia=None):
    gravity = gravity or ([G * S30, 0.0, -G * C30] if dim == 3 else [G * S30, -G * C30])
    shape = shape or ("{ sphere = { radius = 0.1 } }" if dim == 3 else
                      "{ circle = { radius = 0.1 } }")
    pos = [0.0, 0.0, 0.1] if dim == 3 else [0.0, 0.1]
    lines = [f"position = {pos}"]
    if velocity is not None:
        lines.append(f"velocity = {list(velocity)}")
    if spin is not None:
        lines.append(f"angular_velocity = {spin}")
    if orientation is not None:
        lines.append(f"orientation = {orientation}")
    if inertia is not None:
        lines.append(f"inertia = {inertia}")
    body = f'[[bodies]]\nname = "ball"\nshape = {shape}\nmass = 1.0\nmaterial = "m"\n' + \
        "\n".join(lines) + "\n"
    return _scene(body, dim=dim, gravity=gravity, ground='[ground]\nmaterial = "m"',
                  material=f"[materials.m]\nfriction = {mu}\nrolling_friction = {rolling}\n",
                  duration=1.0, solution="roll_incline")


def test_roll_by_hand_at_one_second():
    # CONTACTS.md 1.3: mu = 1 rolls, v = 3.5036, omega = 35.036, d = 1.7518; mu = 0.1 slips,
    # v = 4.0554, omega = 21.239, slip 1.9315
    traj = SOLUTIONS["roll_incline"](_roller(1.0), np.array([1.0]))
    assert traj.vel[0, 0, 0] == pytest.approx(G * S30 / 1.4, rel=1e-14)
    assert traj.omega[0, 0, 1] == pytest.approx(G * S30 / 1.4 / 0.1, rel=1e-14)
    assert traj.com[0, 0, 0] == pytest.approx(0.5 * G * S30 / 1.4, rel=1e-14)
    assert traj.meta["mu_crit"] == pytest.approx(math.tan(math.radians(30)) / 3.5, rel=1e-14)
    # rotation about +y by omega t^2 / 2
    angle = 0.5 * G * S30 / 1.4 / 0.1
    np.testing.assert_allclose(traj.quat[0, 0], [math.cos(angle / 2), 0, math.sin(angle / 2), 0],
                               atol=1e-14)
    traj = SOLUTIONS["roll_incline"](_roller(0.1), np.array([1.0]))
    v, w = traj.vel[0, 0, 0], traj.omega[0, 0, 1]
    assert v == pytest.approx(G * (S30 - 0.1 * C30), rel=1e-14)
    assert w == pytest.approx(0.1 * G * C30 * 0.1 / (0.4 * 0.01), rel=1e-14)
    assert (round(v, 4), round(w, 3), round(v - 0.1 * w, 4)) == (4.0554, 21.239, 1.9315)
    # 2D disk: J = m r^2 / 2, a = g sin / 1.5, clockwise spin for rolling towards +x
    traj = SOLUTIONS["roll_incline"](_roller(1.0, dim=2), np.array([1.0]))
    assert traj.vel[0, 0, 0] == pytest.approx(G * S30 / 1.5, rel=1e-14)
    assert traj.omega[0, 0] == pytest.approx(-G * S30 / 1.5 / 0.1, rel=1e-14)
    assert traj.angle[0, 0] == pytest.approx(-0.5 * G * S30 / 1.5 / 0.1, rel=1e-14)


def test_roll_slip_then_roll_is_continuous_and_ends_rolling():
    # launched at 3 m/s without spin, mu = 0.5 >= mu_crit: slips, spins up, then rolls
    scene = _roller(0.5, velocity=[3.0, 0.0, 0.0])
    g_s, g_n, k = G * S30, G * C30, 0.4
    t1 = 3.0 / (0.5 * g_n * (1 + 1 / k) - g_s)
    traj = _run(scene)
    assert traj.meta["phases"] == [[0.0, "slip+"], [pytest.approx(t1, rel=1e-14), "roll"]]
    t = np.linspace(0, 1, 100001)
    tr = SOLUTIONS["roll_incline"](scene, t)
    v, w = tr.vel[:, 0, 0], tr.omega[:, 0, 1]
    slip = v - 0.1 * w
    assert np.all(slip[t >= t1] == pytest.approx(0.0, abs=1e-13))
    assert np.all(slip[t < t1 - 1e-3] > 0)
    # the velocity and the position are continuous at t1 and the accelerations are the phases'
    dv = np.diff(v) / np.diff(t)
    np.testing.assert_allclose(dv[t[1:] < t1], g_s - 0.5 * g_n, rtol=1e-8)
    np.testing.assert_allclose(dv[t[:-1] > t1], g_s / (1 + k), rtol=1e-8)
    # position = integral of velocity (trapezoids are exact on each quadratic piece)
    np.testing.assert_allclose(np.diff(tr.com[:, 0, 0]), 0.5 * (v[1:] + v[:-1]) * np.diff(t),
                               rtol=0, atol=1e-10)
    # the rolling speed after t1 follows from the slip phase by hand
    v1 = 3.0 + (g_s - 0.5 * g_n) * t1
    assert v[-1] == pytest.approx(v1 + g_s / (1 + k) * (1 - t1), rel=1e-12)


def test_roll_cylinder_across_the_slope_and_on_a_tilted_plane():
    cyl = _roller(1.0, shape="{ cylinder = { radius = 0.1, length = 0.3 } }",
                  orientation="{ axis = [1, 0, 0], angle = 1.5707963267948966 }")
    traj = SOLUTIONS["roll_incline"](cyl, np.array([1.0]))
    assert traj.vel[0, 0, 0] == pytest.approx(G * S30 / 1.5, rel=1e-12)
    with pytest.raises(ValueError, match="does not lie across the slope"):
        _run(_roller(1.0, shape="{ cylinder = { radius = 0.1, length = 0.3 } }",
                     orientation="{ axis = [0, 1, 0], angle = 1.5707963267948966 }"))
    plane = load_case(CASES / "contact" / "roll_incline_plane.toml")
    tilted = load_case(CASES / "contact" / "roll_incline.toml")
    a, b = _run(plane), _run(tilted)
    np.testing.assert_allclose(np.linalg.norm(a.vel[:, 0], axis=1),
                               np.linalg.norm(b.vel[:, 0], axis=1), rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(a.vel[-1, 0], 3.5036 * np.array([-C30, 0, -S30]), atol=1e-4)


def test_roll_metrics_on_runs_with_known_errors():
    scene = _roller(1.0)
    m = _metrics(scene, _run(scene))
    assert m["slip_velocity_error"] < 1e-13 and m["rolling_acceleration_error_rel"] < 1e-12
    # a run of a hollow-ish ball (I = 0.5 m r^2): rolls at g_s / 1.5 instead of g_s / 1.4
    run = _run(_roller(1.0, inertia="[0.005, 0.005, 0.005]"))
    m = _metrics(scene, run)
    assert m["rolling_acceleration_error_rel"] == pytest.approx(1 - 1.4 / 1.5, rel=1e-9)
    assert m["slip_velocity_error"] < 1e-13  # it still rolls
    run.omega[:, 0, 1] += 0.03  # a creeping run: the contact point slips at -3 mm/s
    m = _metrics(scene, run)
    assert m["slip_velocity_error"] == pytest.approx(3e-3, rel=1e-9)


def test_roll_refusals():
    with pytest.raises(ValueError, match="no incline"):
        _run(_roller(gravity=[0.0, 0.0, -G]))
    with pytest.raises(ValueError, match="rolling friction"):
        _run(_roller(rolling=0.001))
    with pytest.raises(ValueError, match="off the downslope line"):
        _run(_roller(velocity=[0.0, 1.0, 0.0]))
    with pytest.raises(ValueError, match="spins about another axis"):
        _run(_roller(spin=[0.0, 0.0, 1.0]))
    with pytest.raises(ValueError, match="not a sphere or cylinder or capsule"):
        _run(_roller(shape="{ box = { size = [0.2, 0.2, 0.2] } }"))
    with pytest.raises(ValueError, match="does not press"):
        _run(_roller(gravity=[0.0, 0.0, G]))


# -- block_incline ---------------------------------------------------------------------------------
def _incline_box(deg, mu=0.5, dim=3, size=0.2):
    s, c = math.sin(math.radians(deg)), math.cos(math.radians(deg))
    grav = [G * s, 0.0, -G * c] if dim == 3 else [G * s, -G * c]
    return _box(size=(size,) * dim, mu=mu, velocity=(0.0, 0.0, 0.0), gravity=grav,
                solution="block_incline", duration=2.0)


def test_block_incline_by_hand():
    for dim in (3, 2):
        still = _run(_incline_box(20, dim=dim))
        np.testing.assert_array_equal(still.com[:, 0], still.com[:1, 0].repeat(len(still.t), 0))
        assert still.meta["holds"] is True
        slide = SOLUTIONS["block_incline"](_incline_box(35, dim=dim), np.array([2.0]))
        a = G * (math.sin(math.radians(35)) - 0.5 * math.cos(math.radians(35)))
        assert slide.com[0, 0, 0] == pytest.approx(2 * a, rel=1e-14)  # a T^2 / 2, 3.2177 m
        assert slide.vel[0, 0, 0] == pytest.approx(2 * a, rel=1e-14)
    # exactly at the friction angle it holds (tan theta <= mu)
    assert _run(_incline_box(math.degrees(math.atan(0.5)) - 1e-9)).meta["holds"] is True


def test_block_metrics_on_runs_with_known_errors():
    scene = _incline_box(20)
    run = _run(scene)
    run.com[:, 0, 0] += 1e-3 * run.t / run.t[-1]  # a run that creeps 1 mm in 2 s
    assert _metrics(scene, run) == {"incline_drift": pytest.approx(1e-3, rel=1e-12)}
    kinetic = _incline_box(35)
    assert _metrics(kinetic, _run(kinetic))["effective_friction_error"] < 1e-14
    m = _metrics(kinetic, _run(_incline_box(35, mu=0.51)))
    assert m == {"effective_friction_error": pytest.approx(0.01, rel=1e-9)}


def test_block_refusals():
    with pytest.raises(ValueError, match="tip over"):  # h_com tan 40 = 0.084 >= 0.05
        _run(_box(size=(0.1, 0.1, 0.2), mu=1.0, velocity=(0, 0, 0),
                  gravity=[G * math.sin(0.7), 0.0, -G * math.cos(0.7)], solution="block_incline"))
    with pytest.raises(ValueError, match="does not start at rest"):
        _run(_box(mu=0.5, gravity=[G * S30, 0.0, -G * C30], solution="block_incline"))
    with pytest.raises(ValueError, match="no incline"):
        _run(_box(mu=0.5, velocity=(0, 0, 0), solution="block_incline"))


# -- billiard and Newton's cradle -----------------------------------------------------------------
def _row(xs, vs, e=1.0, masses=None, dim=3, gravity=False, ground="", mu=0.0, radius=0.1,
         solution="billiard", duration=0.2, dt=1e-3):
    masses = masses or [1.0] * len(xs)
    shape = "sphere" if dim == 3 else "circle"
    bodies = ""
    for i, (x, v, m) in enumerate(zip(xs, vs, masses, strict=True)):
        pos = [x, 0.0, radius] if dim == 3 else [x, radius]
        vel = [v, 0.0, 0.0] if dim == 3 else [v, 0.0]
        bodies += (f'[[bodies]]\nname = "b{i}"\nshape = {{ {shape} = {{ radius = {radius} }} }}\n'
                   f"mass = {m}\nposition = {pos}\nvelocity = {vel}\n"
                   f"material = {{ friction = {mu}, restitution = {e} }}\n")
    return _scene(bodies, dim=dim, gravity=gravity, ground=ground, duration=duration, dt=dt,
                  sample=1e-3, solution=solution)


def test_billiard_by_hand():
    # equal masses, target at rest: (1 - e) v / 2 and (1 + e) v / 2, at t = gap / v
    for dim in (3, 2):
        for e in (1.0, 0.5, 0.0):
            traj = SOLUTIONS["billiard"](_row([0.0, 0.255], [1.0, 0.0], e=e, dim=dim),
                                         np.array([0.05, 0.06, 0.2]))
            assert traj.meta["collisions"] == [pytest.approx(0.055, rel=1e-13)]
            np.testing.assert_allclose(traj.vel[0, :, 0], [1.0, 0.0])
            np.testing.assert_allclose(traj.vel[2, :, 0], [(1 - e) / 2, (1 + e) / 2], atol=1e-15)
            x2 = 0.255 + (1 + e) / 2 * (0.2 - 0.055)
            assert traj.com[2, 1, 0] == pytest.approx(x2, rel=1e-13)
    # unequal masses moving towards each other: momentum kept, relative speed reversed times e
    traj = _run(_row([0.0, 0.3], [2.0, -1.0], e=0.8, masses=[1.0, 3.0]))
    u1, u2 = traj.vel[-1, :, 0]
    assert 1.0 * u1 + 3.0 * u2 == pytest.approx(2.0 - 3.0, rel=1e-14)
    assert u2 - u1 == pytest.approx(0.8 * 3.0, rel=1e-14)


def test_billiard_on_a_frictionless_ground_under_gravity():
    ground = "[ground]\nmaterial = { friction = 0.0 }"
    traj = _run(_row([0.0, 0.255], [1.0, 0.0], gravity=[0.0, 0.0, -G], ground=ground))
    np.testing.assert_allclose(traj.com[:, :, 2], 0.1)
    np.testing.assert_allclose(traj.vel[-1, :, 0], [0.0, 1.0], atol=1e-15)
    with pytest.raises(ValueError, match="has friction"):
        _run(_row([0.0, 0.255], [1.0, 0.0], gravity=[0.0, 0.0, -G], ground="[ground]", mu=0.5))


def test_cradle_by_hand_and_with_inelastic_balls():
    scene = load_case(CASES / "contact" / "newtons_cradle.toml")
    traj = _run(scene)
    np.testing.assert_allclose(traj.vel[-1, :, 0], [0.0, 0.0, 1.0], atol=1e-15)
    assert traj.meta["collisions"] == pytest.approx([0.010, 0.011], rel=1e-12)
    # five balls, e = 0.9: momentum kept, nobody approaches anybody at the end
    row = _row([0.0, 0.21, 0.411, 0.612, 0.813], [1.0, 0, 0, 0, 0], e=0.9,
               solution="newtons_cradle", duration=1.0)
    traj = _run(row)
    u = traj.vel[-1, :, 0]
    assert u.sum() == pytest.approx(1.0, rel=1e-13)
    assert np.all(np.diff(u) >= -1e-15)
    assert len(traj.meta["collisions"]) > 4  # later collisions as the slower balls catch up


def test_row_refusals():
    with pytest.raises(ValueError, match="do not meet"):
        _run(_row([0.0, 0.255], [-1.0, 0.0]))
    with pytest.raises(ValueError, match="touch at the start"):
        _run(_row([0.0, 0.2, 0.4], [1.0, 0.0, 0.0], solution="newtons_cradle"))
    with pytest.raises(ValueError, match="same instant"):  # two strikers on a middle ball
        _run(_row([0.0, 0.21, 0.42], [1.0, 0.0, -1.0], solution="newtons_cradle"))
    with pytest.raises(ValueError, match="describes 2 body"):
        _run(_row([0.0, 0.21, 0.42], [1.0, 0.0, 0.0]))
    with pytest.raises(ValueError, match="overlap"):
        _run(_row([0.0, 0.15], [1.0, 0.0]))
    row = _row([0.0, 0.21, 0.42], [1.0, 0.0, 0.0], solution="newtons_cradle")
    moved = replace(row.bodies[1], position=row.bodies[1].position + [0, 0.01, 0])
    with pytest.raises(ValueError, match="not on one line"):
        _run(replace(row, bodies=(row.bodies[0], moved, row.bodies[2])))
    scene = _row([0.0, 0.255], [1.0, 0.0])
    sideways = replace(scene.bodies[0], velocity=np.array([1.0, 0.1, 0.0]))
    with pytest.raises(ValueError, match="off the line"):
        _run(replace(scene, bodies=(sideways, scene.bodies[1])))


def test_row_metrics_on_runs_with_known_errors():
    scene = _row([0.0, 0.255], [1.0, 0.0])
    assert _metrics(scene, _run(scene))["momentum_transfer_error"] < 1e-15
    m = _metrics(scene, _run(_row([0.0, 0.255], [1.0, 0.0], e=0.9)))
    assert m["momentum_transfer_error"] == pytest.approx(0.05, rel=1e-12)  # (1 + 0.9) / 2 vs 1
    cradle = load_case(CASES / "contact" / "newtons_cradle.toml")
    run = _run(cradle)
    assert _metrics(cradle, run)["cradle_velocity_error"] == 0.0
    run.vel[-1, 0, 0] = 0.01
    run.vel[-1, 2, 0] = 0.995
    assert _metrics(cradle, run)["cradle_velocity_error"] == pytest.approx(0.01, rel=1e-12)


# -- common refusals -------------------------------------------------------------------------------
def test_scenes_without_contact_or_with_unknown_statics_are_refused():
    text = (CASES / "contact" / "bounce_elastic.toml").read_text()
    no_contact = load_case_text(text.replace("contact = true", "contact = false")
                                .replace('material = "superball"', "")
                                .replace("[ground]\nmaterial = { friction = 0.5, restitution = "
                                         "0.0 }   # pair restitution = max(1, 0) = 1", ""))
    with pytest.raises(ValueError, match="no contact"):
        _run(no_contact)
    with_wall = load_case_text(text + '\n[[statics]]\nname = "wall"\n'
                               'shape = { box = { size = [0.1, 1, 1] } }\n'
                               'position = [5.0, 0.0, 0.5]\n')
    with pytest.raises(ValueError, match="statics"):
        _run(with_wall)


# -- the contact cases ----------------------------------------------------------------------------
OWN_METRICS = {"apex_height_error_rel", "impact_time_error", "stop_distance_error_rel",
               "stop_time_error", "rolling_acceleration_error_rel", "slip_velocity_error",
               "incline_drift", "effective_friction_error", "momentum_transfer_error",
               "cradle_velocity_error"}
REFERENCE_METRICS = {"position_error_max", "position_error_rms", "position_error_rel",
                     "orientation_error_max", "velocity_error_max", "angular_velocity_error_max",
                     "energy_error", "energy_drift"}
# the contact-metrics module's names (compare/contact_metrics.py, written in parallel)
CONTACT_METRICS = {"penetration_max", "penetration_resting_mean", "energy_gain",
                   "restitution_error_max", "stop_distance", "stop_time", "slip_velocity_max",
                   "rolling_acceleration", "rest_drift_max", "time_to_rest", "collapse_time",
                   "collapse_time_start"}


def test_the_contact_suite_is_there():
    names = {Path(p).stem for p in CONTACT_CASES}
    assert {"bounce_elastic", "bounce_elastic_2d", "bounce_resting", "slide_to_rest",
            "roll_incline", "roll_incline_slipping", "block_incline_static",
            "block_incline_kinetic", "billiard", "newtons_cradle", "stack_10", "pyramid_2d",
            "mass_ratio_100", "mass_ratio_1000", "tunnelling", "tipping_step",
            "capsule_landing", "mesh_landing", "sphere_pile"} <= names
    for solution in ("bounce", "slide_to_rest", "roll_incline", "block_incline", "billiard",
                     "newtons_cradle"):
        for dim in (2, 3):
            assert any(load_case(p).reference.solution == solution
                       and load_case(p).dimension == dim for p in CONTACT_CASES), (solution, dim)


@pytest.mark.parametrize("path", CONTACT_CASES, ids=[Path(p).stem for p in CONTACT_CASES])
def test_contact_case_loads_and_its_solution_accepts_it(path):
    scene = load_case(path)
    assert scene.effects.contact and scene.name.startswith("contact-")
    assert scene.description and "Truth" in Path(path).read_text()
    if scene.dimension == 2:
        assert "pymunk" in scene.run.engines
    assert {"inhouse", "mujoco", "pybullet"} <= set(scene.run.engines)
    # CI budget: dt = 1e-4 cases stay short
    if scene.run.dt < 1e-3:
        assert scene.run.duration <= 0.5
    assert set(scene.tolerances) <= OWN_METRICS | REFERENCE_METRICS | CONTACT_METRICS
    if scene.reference.kind != "analytic":
        return
    traj = _run(scene)  # no ValueError: the scene is inside the solution's assumptions
    assert np.all(np.isfinite(traj.com)) and np.all(np.isfinite(traj.vel))
    metrics = _metrics(scene, traj)
    assert all(v < 1e-9 for v in metrics.values()), metrics  # the ideal run scores zero
    assert set(metrics) & set(scene.tolerances), "a case limits its solution's own metric"
