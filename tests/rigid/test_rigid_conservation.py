"""Conservation: the tennis racket under RK4, symplectic against explicit Euler over 1000
periods, and the momenta of the isolated two-body spring.

Energies and momenta come from crosscheck.quantities (the same ruler as every engine).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from crosscheck import quantities
from crosscheck.engines import get_engine
from crosscheck.reference.analytic import EXTRA_METRICS
from crosscheck.scene.loader import load_case, load_case_text

CASES = Path(__file__).resolve().parents[2] / "cases"


def _run(scene, integrator, dt):
    traj = get_engine("inhouse").run(scene, integrator, dt)
    assert traj.failure is None, traj.failure
    return traj


# -- the tennis racket ----------------------------------------------------------------------
def test_tennis_racket_rk4_conserves_and_flips_on_time():
    scene = load_case(CASES / "rigid3d" / "tennis_racket.toml")
    assert scene.run.duration == 20.0
    traj = _run(scene, "rk4", 1e-3)
    assert traj.t[-1] == 20.0
    energy = quantities.total_energy(scene, traj)
    L = quantities.angular_momentum(scene, traj, about="com")
    # RK4's energy error per step is ~ C (h w)^5 E with h w = 5e-3, so 2e4 steps give at most a
    # few 1e-8 for C ~ 1, and C is small for this smooth motion (measured 1.9e-11). The issue's
    # bar is 1e-8. The angular momentum L is a state variable with no torque acting: it stays
    # at round-off (measured 1e-14), far inside the same bar.
    assert np.max(np.abs(energy - energy[0])) / energy[0] < 1e-8
    assert np.max(np.linalg.norm(L - L[0], axis=1)) / np.linalg.norm(L[0]) < 1e-8
    norms = np.linalg.norm(L, axis=1)
    assert np.max(np.abs(norms - norms[0])) / norms[0] < 1e-8
    # The flip period from the zero crossings of the intermediate-axis body rate, against
    # T = 4 K(m) / rate of the elliptic solution (7.71 s: five flips in 20 s). The crossings are
    # located to ~1e-7 s by interpolation and RK4's phase error is ~1e-8: the issue's 0.1 % bar
    # is met by orders of magnitude (measured 1e-11).
    metrics = EXTRA_METRICS["torque_free_intermediate"](scene, traj)
    assert 7.0 < metrics["flip_period_analytic"] < 8.5
    assert metrics["flip_period_error"] < 1e-3
    # The measurement states its own resolution: linear interpolation of the crossings between
    # 0.01 s samples errs by 2.3e-7 s (3.0e-8 of the period), RK4's floor in a sweep.
    assert 1e-9 < metrics["flip_period_resolution"] < 1e-7
    # The metric can fail: the explicit midpoint rule is off by 2 %.
    other = EXTRA_METRICS["torque_free_intermediate"](scene, _run(scene, "midpoint", 1e-3))
    assert other["flip_period_error"] > 1e-2, other
    # And it can have nothing to measure: explicit Euler's rotation gains energy (|w| 5 -> 8.8
    # rad/s), the body leaves the flip for a wobble about its minor axis and the sign changes
    # come ever faster (half periods 0.55 to 1.5 s). That is not a period; it used to be
    # reported as an error of 0.79, identical to symplectic_euler_exp's (both rotate by h w_n
    # with w_n = I(q_n)^-1 L, differing only by the O((h w)^3) of the exponential map).
    other = EXTRA_METRICS["torque_free_intermediate"](scene, _run(scene, "explicit_euler", 1e-3))
    value, reason = other["flip_period_error"]
    assert value is None and reason.startswith("crossings not periodic"), other


# -- symplectic against explicit Euler over 1000 periods -------------------------------------------
OSCILLATOR = """
[case]
name = "long-oscillator"
dimension = 3
[run]
duration = {duration}
dt = 5e-4
sample_every = 0.5
[[effects.springs]]
a = "bob"
anchor = [0.0, 0.0, 0.0]
stiffness = 1.0
[[bodies]]
name = "bob"
shape = { sphere = { radius = 0.05 } }
mass = 1.0
position = [1.0, 0.0, 0.0]
"""


@pytest.mark.slow
def test_symplectic_euler_bounded_explicit_euler_grows_over_1000_periods():
    w = 1.0
    periods = 1000
    duration = periods * 2 * math.pi / w
    h = duration / round(duration / 5e-4)  # a run takes exactly duration / h steps
    scene = load_case_text(OSCILLATOR.replace("{duration}", repr(duration))
                           .replace("dt = 5e-4", f"dt = {h!r}"))
    per_period = 2 * math.pi / w / scene.run.sample_every  # samples per period, ~12.6

    # Semi-implicit Euler conserves the modified energy E~ = E - h k x v / 2 exactly (its map is
    # symplectic), so E itself only oscillates: released at rest (x v = 0, E0 = E~) the relative
    # error stays below h w / 2 = 2.5e-4 (times 1 + O(h w)) for ever. No drift: the worst error
    # of the last 100 periods is no larger than that of the first 100.
    traj = _run(scene, "symplectic_euler", h)
    energy = quantities.total_energy(scene, traj)
    err = np.abs(energy - energy[0]) / energy[0]
    assert np.max(err) <= 0.5 * h * w * (1 + 2 * h * w)
    assert np.max(err) > 0.4 * h * w  # the oscillation is there (the measurement can see it)
    window = int(100 * per_period)
    assert np.max(err[-window:]) <= 1.001 * np.max(err[:window])

    # Explicit Euler multiplies the oscillator's energy by exactly 1 + (h w)^2 every step (its
    # map has determinant 1 + (h w)^2), so E(t) / E0 = (1 + h^2 w^2)^(t / h): growing without
    # bound, e^pi = 23 after 1000 periods. Round-off over 1.26e7 steps is ~1e-9 relative.
    traj = _run(scene, "explicit_euler", h)
    energy = quantities.total_energy(scene, traj)
    predicted = energy[0] * np.exp(np.rint(traj.t / h) * np.log1p((h * w) ** 2))
    np.testing.assert_allclose(energy, predicted, rtol=1e-6)
    assert energy[-1] / energy[0] > 20.0
    assert np.all(np.diff(energy) > 0)


# -- the isolated two-body spring ------------------------------------------------------------
def test_two_body_spring_momenta_under_rk4():
    scene = load_case(CASES / "rigid3d" / "two_body_spring.toml")
    assert scene.effects.gravity is None and not scene.effects.loads and not scene.effects.drag

    def drifts(dt):
        traj = _run(scene, "rk4", dt)
        P = quantities.linear_momentum(scene, traj)
        L = quantities.angular_momentum(scene, traj, about="com")
        p_scale = float(np.sum(scene.masses * np.linalg.norm(traj.vel[0], axis=1)))
        return (np.max(np.linalg.norm(P - P[0], axis=1)) / p_scale,
                np.max(np.linalg.norm(L - L[0], axis=1)) / np.linalg.norm(L[0]))

    # Linear momentum: the spring adds f to one body and exactly -f to the other at every stage,
    # and RK4 conserves linear invariants exactly, so only the rounding of each body's own update
    # remains: ~eps per step, 5000 steps -> at most ~1e-12 even if every rounding added up
    # (measured 2e-15).
    p_drift, l_drift = drifts(1e-3)
    assert p_drift < 1e-13
    # Angular momentum (orbital plus spin, about the system's centre of mass) is a quadratic
    # invariant, which RK4 keeps only to its truncation error O(h^4): 7e-11 at the case's step
    # (the case's bar is 1e-8). That this is truncation and not a missing torque shows in its
    # h^4 scaling, and at h = 1.25e-4 it falls to the round-off floor of 40000 steps
    # (~sqrt(steps) eps |L| ~ 1e-13 relative; measured 4e-14).
    assert l_drift < 1e-9
    _, l_half = drifts(5e-4)
    assert 12.0 < l_drift / l_half < 20.0  # 2^4 = 16
    p_fine, l_fine = drifts(1.25e-4)
    assert p_fine < 1e-13
    assert l_fine < 1e-13
