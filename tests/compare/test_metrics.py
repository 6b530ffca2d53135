"""Metrics against motions whose errors are known in closed form.

The runs come from the fake adapters in tests/runner/crosscheck_fakes.py: exact free flight, and
explicit Euler for the translation, whose error after time T at step h is exactly g T h / 2 in
position and m g^2 T h / 2 in energy (x_n = g h^2 n (n - 1) / 2 against g t_n^2 / 2).
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
import pytest

from crosscheck.compare import scales
from crosscheck.compare.metrics import compute_metrics
from crosscheck.compare.verdict import judge
from crosscheck.scene.loader import load_case_text
from crosscheck.state import Trajectory

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "runner"))
from crosscheck_fakes import BlowupEngine, ExactEngine  # noqa: E402

G = 9.81


def fall_case(extra: str = "", spin: str = "[0, 0, 0]", effects: str = "gravity = [0, 0, -9.81]",
              duration: float = 1.0, dt: float = 0.01, tolerances: str = "") -> str:
    return f"""
[case]
name = "fall"
dimension = 3
[run]
duration = {duration}
dt = {dt}
sample_every = 0.05
engines = ["inhouse"]
[effects]
{effects}
{extra}
[[bodies]]
name = "ball"
shape = {{ sphere = {{ radius = 0.1 }} }}
mass = 2.0
position = [0, 0, 10]
velocity = [1.0, 0, 0]
angular_velocity = {spin}
[tolerances]
{tolerances}
"""


def run(scene, integrator, dt=None):
    return ExactEngine().run(scene, integrator, dt or scene.run.dt)


def values(ms):
    return {k: m.value for k, m in ms.metrics.items()}


def test_explicit_euler_free_fall_errors_match_closed_form():
    scene = load_case_text(fall_case())
    T, h = 1.0, 0.01
    ref = run(scene, "exact")
    ms = compute_metrics(scene, run(scene, "euler"), ref)
    v = values(ms)
    # Position lags by g T h / 2 at the end, and the lag grows linearly: the max is at T.
    assert v["position_error_max"] == pytest.approx(G * T * h / 2, rel=1e-10)
    # Velocity is exact for Euler under constant force (v_n = g t_n): only round-off.
    assert v["velocity_error_max"] < 1e-12
    # The energy gain m g^2 T h / 2 is all the centre of mass's: the internal energy (nothing
    # spins) stays 0, and the translational drift is the gain over the kinetic energy the
    # centre of mass gained, 1/2 m (g T)^2 (the 1 m/s horizontal speed, a frame's choice, is
    # not part of it): h / T.
    assert v["energy_drift"] == pytest.approx(0.0, abs=1e-12)
    assert ms.metrics["energy_drift"].meaningful
    assert v["translational_energy_drift"] == pytest.approx(h / T, rel=1e-9)
    assert ms.metrics["translational_energy_drift"].meaningful
    # Horizontal momentum is conserved exactly by both; the vertical direction is excluded.
    assert v["linear_momentum_drift"] == 0.0
    assert "orthogonal to gravity" in ms.metrics["linear_momentum_drift"].note
    # Nothing moves relative to the centre of mass (one body, no spin): no angular momentum to
    # drift in any frame, said so rather than scaled by the frame's translation.
    assert ms.metrics["angular_momentum_drift"].value is None
    assert ms.metrics["angular_momentum_drift"].note.startswith("nothing moves relative to")
    assert ms.blowup_time is None


def test_exact_run_has_round_off_errors_only():
    scene = load_case_text(fall_case(spin="[0, 0, 3.0]"))
    ms = compute_metrics(scene, run(scene, "exact"), run(scene, "exact", 0.001))
    v = values(ms)
    for name in ("position_error_max", "orientation_error_max", "velocity_error_max"):
        assert v[name] < 1e-12, name
    assert v["energy_drift"] < 1e-14  # exact energy up to round-off of ~100 J sums


def test_orientation_error_is_the_geodesic_angle():
    scene = load_case_text(fall_case(spin="[0.6, 0, 0.8]"))  # |w| = 1 rad/s, tilted axis
    ms = compute_metrics(scene, run(scene, "fast_spin"), run(scene, "exact"))
    # Spinning 1 % too fast about a fixed axis: the angle between the two is 0.01 |w| t.
    assert ms.metrics["orientation_error_max"].value == pytest.approx(0.01 * 1.0 * 1.0, rel=1e-9)
    assert ms.metrics["position_error_max"].value == 0.0


def test_two_d_orientation_error_wraps_to_the_short_way():
    text = fall_case(effects="gravity = [0, -9.81]").replace("dimension = 3", "dimension = 2")
    text = text.replace("sphere = { radius = 0.1 }", "circle = { radius = 0.1 }")
    text = text.replace("position = [0, 0, 10]", "position = [0, 10]").replace(
        "velocity = [1.0, 0, 0]", "velocity = [1.0, 0]")
    text = text.replace("angular_velocity = [0, 0, 0]", "angular_velocity = 4.0")
    scene = load_case_text(text)
    ms = compute_metrics(scene, run(scene, "fast_spin"), run(scene, "exact"))
    assert ms.metrics["orientation_error_max"].value == pytest.approx(0.04, rel=1e-9)
    ref = run(scene, "exact")
    shifted = run(scene, "exact")
    shifted.angle = shifted.angle + 2 * np.pi * 3 + 0.1  # three whole turns and 0.1 rad
    ms = compute_metrics(scene, shifted, ref)
    assert ms.metrics["orientation_error_max"].value == pytest.approx(0.1, abs=1e-12)


def test_reference_sampled_at_other_times_is_interpolated_accurately():
    # Reference at 0.05 s samples, run at 0.03 s samples: positions are Hermite-interpolated
    # with the reference's velocities, exact for this quadratic motion up to round-off.
    scene = load_case_text(fall_case())
    ref = run(scene, "exact")
    other = load_case_text(fall_case().replace("sample_every = 0.05", "sample_every = 0.03"))
    traj = run(other, "exact", 0.01)
    assert not np.allclose(traj.t[1], ref.t[1])
    ms = compute_metrics(scene, traj, ref)
    assert ms.metrics["position_error_max"].value < 1e-12
    # Velocities are interpolated linearly: exact for linear v(t).
    assert ms.metrics["velocity_error_max"].value < 1e-12


def test_non_conserved_quantities_are_reported_not_failed():
    drag = "[[effects.drag]]\nlinear = 0.5\nangular = 0.1"
    scene = load_case_text(fall_case(extra=drag, tolerances="energy_drift = 1e-15\n"
                                     "linear_momentum_drift = 1e-15"))
    ms = compute_metrics(scene, run(scene, "euler"))
    assert not ms.metrics["energy_drift"].meaningful
    assert "drag" in ms.metrics["energy_drift"].note
    assert not ms.metrics["linear_momentum_drift"].meaningful
    assert not ms.metrics["angular_momentum_drift"].meaningful
    verdict = judge(scene, "inhouse", "euler", {k: m.to_dict() for k, m in ms.metrics.items()})
    assert verdict.status == "pass"
    assert verdict.metrics["energy_drift"]["passed"] is None
    assert "tolerance ignored" in verdict.metrics["energy_drift"]["note"]


def test_conservation_rules():
    def scene_with(effects, n_bodies=1):
        text = fall_case(effects=effects)
        if n_bodies == 2:
            text += ('[[bodies]]\nname = "b2"\nshape = { sphere = { radius = 0.1 } }\n'
                     'mass = 1.0\nposition = [1, 0, 0]\n')
        return load_case_text(text)

    free = scene_with("")
    assert scales.energy_not_conserved(free) is None
    basis, _ = scales.linear_momentum_directions(free)
    assert basis.shape == (3, 3)
    anchored = scene_with('[[effects.springs]]\na = "ball"\nanchor = [0, 0, 0]\n'
                          'stiffness = 10.0\n')
    assert scales.linear_momentum_directions(anchored)[0] is None
    assert scales.angular_momentum_not_conserved(anchored)
    assert scales.energy_not_conserved(anchored) is None  # undamped spring: conservative
    damped = scene_with('[[effects.springs]]\na = "ball"\nanchor = [0, 0, 0]\n'
                        'stiffness = 10.0\ndamping = 0.1\n')
    assert "damped" in scales.energy_not_conserved(damped)
    inner = scene_with('[[effects.springs]]\na = "ball"\nb = "b2"\nstiffness = 10.0\n', 2)
    assert scales.linear_momentum_directions(inner)[0].shape == (3, 3)
    assert scales.angular_momentum_not_conserved(inner) is None
    loads = scene_with('[[effects.loads]]\nbody = "ball"\nforce = [0, 0, 1]\n', 2)
    basis, _ = scales.linear_momentum_directions(loads)
    assert basis.shape == (2, 3) and np.allclose(basis @ [0, 0, 1], 0)
    assert "torque" in scales.angular_momentum_not_conserved(loads)
    torque = scene_with('[[effects.loads]]\nbody = "ball"\ntorque = [0, 0, 1]\n')
    assert "no potential" in scales.energy_not_conserved(torque)


def test_scales_are_positive_for_a_pure_spin_and_a_body_at_rest_under_gravity():
    spin = load_case_text(fall_case(effects="", spin="[0, 0, 5.0]").replace(
        "velocity = [1.0, 0, 0]", "velocity = [0, 0, 0]"))
    traj = run(spin, "exact")
    ball = spin.bodies[0]
    # Rim momentum m |w| r = 2 * 5 * 0.1; sphere I = 2/5 m r^2, L = I w.
    assert scales.momentum_scale(spin, traj) == pytest.approx(2 * 5 * 0.1)
    assert scales.angular_momentum_scale(spin, traj) == pytest.approx(0.4 * 2 * 0.01 * 5)
    assert scales.energy_scale(spin, traj)[0] == pytest.approx(0.5 * 0.4 * 2 * 0.01 * 25)
    assert scales.body_radius(ball) == pytest.approx(0.1)
    rest = load_case_text(fall_case().replace("velocity = [1.0, 0, 0]", "velocity = [0, 0, 0]"))
    still = run(rest, "exact")
    still = Trajectory(t=still.t[:1], com=still.com[:1], vel=still.vel[:1],
                       omega=still.omega[:1], quat=still.quat[:1])
    # Nothing moves: the floor m |g| r keeps the energy scale away from zero.
    assert scales.energy_scale(rest, still)[0] == pytest.approx(2 * G * 0.1)


def test_box_radius_accounts_for_a_centre_of_mass_offset():
    text = fall_case().replace("sphere = { radius = 0.1 }", "box = { size = [2, 4, 4] }")
    text = text.replace("mass = 2.0", "mass = 2.0\ncom = [1, 0, 0]")
    body = load_case_text(text).bodies[0]
    # Farthest corner from (1, 0, 0): (-1, +-2, +-2), distance sqrt(4 + 4 + 4).
    assert scales.body_radius(body) == pytest.approx(math.sqrt(12))


def test_blowup_time_from_runaway_energy_and_from_a_non_finite_state():
    scene = load_case_text(fall_case(effects="").replace("velocity = [1.0, 0, 0]",
                                                         "velocity = [0, 0, 0]"))
    traj = BlowupEngine().run(scene, "exact", 0.01)
    ms = compute_metrics(scene, traj)
    # v0 = (1, 1, 1): T(0) = 3 J = E_avail (no forces). The speed is multiplied by 10 each step
    # after t = 0.2 s, so at t = 0.21 s, |dE| = 297 J > 10 E_avail = 30 J; the first sample at or
    # after that is t = 0.25 s.
    assert ms.blowup_time == pytest.approx(0.25)
    assert "energy" in ms.blowup_reason
    # Scales only use samples before the blow-up: before it the one body only translates, so
    # there is no internal energy to drift (the runaway itself is what blowup_time reports).
    assert ms.metrics["energy_drift"].value is None
    assert "before the blow-up" in ms.metrics["energy_drift"].note
    traj.meta["failure"] = {"time": 0.1, "reason": "non-finite state"}
    ms = compute_metrics(scene, traj)
    assert ms.blowup_time == pytest.approx(0.1)
    assert ms.blowup_reason == "non-finite state"
    verdict = judge(scene, "inhouse", "exact", {k: m.to_dict() for k, m in ms.metrics.items()},
                    blowup_time=ms.blowup_time, blowup_reason=ms.blowup_reason)
    assert verdict.status == "blowup"


def test_nan_reference_entries_are_skipped():
    scene = load_case_text(fall_case())
    ref = run(scene, "exact")
    ref.quat[:] = np.nan  # a solution that defines positions only
    ref.omega[:] = np.nan
    ms = compute_metrics(scene, run(scene, "euler"), ref)
    assert "orientation_error_max" not in ms.metrics
    assert "angular_velocity_error_max" not in ms.metrics
    assert ms.metrics["position_error_max"].value == pytest.approx(G * 0.01 / 2, rel=1e-10)
    # Without a full reference state the energy scale falls back to the run itself.
    assert "run" in ms.metrics["energy_drift"].note


def test_out_of_plane_records_become_metrics_in_their_own_units():
    scene = load_case_text(fall_case())
    traj = run(scene, "exact")
    n = len(traj.t)
    traj.extras = {"out_of_plane": np.linspace(0.0, -2e-3, n)[:, None],
                   "out_of_plane_tilt": np.full((n, 1), 0.01),
                   "out_of_plane_omega": np.zeros((n, 1))}
    ms = compute_metrics(scene, traj)
    assert ms.metrics["out_of_plane_drift"].value == pytest.approx(2e-3)
    assert ms.metrics["out_of_plane_drift"].unit == "m"
    assert ms.metrics["out_of_plane_tilt"].value == pytest.approx(0.01)
    assert ms.metrics["out_of_plane_angular_velocity"].value == 0.0
