"""The force-level ``penalty`` model (docs/inhouse.md, "Contact: penalty"): the restitution map,
the stiffness rule's resting depth, bounce apexes within the tolerance its contact time and RK4's
dissipation give, friction that holds on an incline, no energy gain in a dissipative scene for the
explicit integrators, and bit-identical repeats."""

from __future__ import annotations

import math

import numpy as np
import pytest
from contact_scenes import Run, box, circle, scene, sphere
from scipy.integrate import solve_ivp

from crosscheck.sim.rigid.penalty import damping_ratio, restitution_of

MATERIALS = """[materials.half]
friction = 0.5
restitution = 0.5
[materials.dead]
friction = 0.5
restitution = 0.0
[materials.grip]
friction = 0.5
restitution = 0.0
"""


def _independent_restitution(zeta: float, p: float) -> float:
    """The dimensionless unilateral impact solved by SciPy (DOP853 with event location)."""
    q = 0.5 * (p - 1.0)

    def force(x, v):
        xp = max(x, 0.0)
        return xp ** p + 2.0 * zeta * v * (xp ** q if q > 0 else 1.0)

    def rhs(t, y):
        return [y[1], -force(y[0], y[1])]

    def released(t, y):
        return force(y[0], y[1]) if t > 1e-9 else 1.0

    def surface(t, y):
        return y[0] if t > 1e-9 else 1.0

    released.terminal = surface.terminal = True
    released.direction = surface.direction = -1
    sol = solve_ivp(rhs, [0.0, 100.0], [0.0, 1.0], method="DOP853", rtol=1e-12, atol=1e-14,
                    events=[released, surface], max_step=0.01)
    return -float(sol.y[1, -1])


@pytest.mark.parametrize("p", [1.0, 1.5])
@pytest.mark.parametrize("zeta", [0.1, 0.5, 1.5])
def test_restitution_of_the_damping_ratio_matches_an_independent_solve(zeta, p):
    assert restitution_of(zeta, p) == pytest.approx(_independent_restitution(zeta, p), abs=1e-6)


def test_damping_ratio_inverts_the_map_and_is_capped():
    for e in (0.9, 0.5, 0.2):
        assert restitution_of(damping_ratio(e, 1.0, 1.5), 1.0) == pytest.approx(e, abs=1e-8)
    assert damping_ratio(1.0, 1.0, 1.5) == 0.0
    assert damping_ratio(0.0, 1.0, 1.5) == 1.5  # e below e(1.5) = 0.0756: the cap
    # Schwager and Poeschel's unilateral dashpot: critical damping still gives e = exp(-2)
    assert restitution_of(1.0, 1.0) == pytest.approx(math.exp(-2.0), abs=1e-7)


@pytest.mark.parametrize("dim", [3, 2])
def test_resting_depth_is_the_weight_over_the_stiffness(dim):
    make = sphere if dim == 3 else circle
    pos = [0.0, 0.0, 0.1] if dim == 3 else [0.0, 0.1]
    run = Run(scene(make("ball", pos, material='"dead"'), dim=dim, ground='material = "dead"',
                    materials=MATERIALS), "rk4", "penalty")
    run.advance(1000, 1e-3)
    omega0 = 2.0 * math.pi / (10 * 1e-3)  # period_steps 10 at dt = 1e-3
    depth = 0.1 - run.state.x[0, dim - 1]
    assert depth == pytest.approx(9.81 / omega0 ** 2, rel=1e-6)  # 24.8 um


@pytest.mark.parametrize("dim", [3, 2])
def test_bounce_apexes_within_the_models_own_tolerance(dim):
    # e = 0.5 from 1 m: apexes 0.25, 0.0625 m. Hunt and Crossley's damping with B(e) / v_in gives
    # the continuous model e exactly for an impact without gravity; with it (g acting during the
    # 5 ms contact) the continuous model's apexes are -1.3 % and -3.9 % (an independent SciPy
    # solve), and the step adds an O(h) error where the contact begins inside a step (measured
    # +6.8 % and +6.7 % at dt = 1e-3, 10 steps a contact period; -0.5 % and +1.7 % at 1e-4).
    make = sphere if dim == 3 else circle
    pos = [0.0, 0.0, 1.1] if dim == 3 else [0.0, 1.1]
    run = Run(scene(make("ball", pos, material='"half"'), dim=dim, ground='material = "half"',
                    materials=MATERIALS), "rk4", "penalty")
    z = []
    for _ in range(1800):
        run.advance(1, 1e-3)
        z.append(run.state.x[0, dim - 1])
    z = np.array(z)
    k = np.nonzero((z[1:-1] > z[:-2]) & (z[1:-1] >= z[2:]))[0] + 1
    heights = z[k[:2]] - 0.1
    np.testing.assert_allclose(heights, [0.25, 0.0625], rtol=0.1)


@pytest.mark.parametrize("law, holds", [("anchor", True), ("regularised", False)])
def test_static_friction_holds_a_block_on_an_incline(law, holds):
    # 20 degrees, mu = 0.5 (tan 20 = 0.36): the anchor law holds the block (its elastic
    # deflection only, 0.06 mm); the regularised law creeps at about v_eps (1e-2 m/s)
    g = 9.81
    text = box("b", [0.0, 0.0, 0.1], [0.2, 0.2, 0.2], material='"grip"')
    tilted = [g * math.sin(math.radians(20)), 0.0, -g * math.cos(math.radians(20))]
    sc = scene(text, gravity=tilted, ground='material = "grip"', materials=MATERIALS)
    run = Run(sc, "rk4", "penalty", {"friction_law": law})
    run.advance(1000, 1e-3)
    drift = run.state.x[0, 0]
    if holds:
        assert abs(drift) < 1e-4
        assert abs(run.velocities()[0, 0]) < 1e-9
    else:
        assert drift > 5e-3


@pytest.mark.parametrize("integrator", ["rk4", "midpoint", "symplectic_euler", "verlet"])
def test_no_energy_gain_in_a_dissipative_scene(integrator):
    # a tilted box and a spinning ball dropped on the ground (restitution 0, friction 0.5)
    bodies = (box("b", [0.0, 0.0, 0.3], [0.2, 0.3, 0.1], material='"dead"',
                  orientation="{ axis = [1.0, 2.0, 0.5], angle = 0.5 }")
              + sphere("s", [0.6, 0.0, 0.2], velocity=[1.0, 0.0, 0.0], angular=[0, 0, 20],
                       material='"dead"'))
    run = Run(scene(bodies, ground='material = "dead"', materials=MATERIALS), integrator,
              "penalty")
    e0 = run.energy()
    worst = -np.inf
    for _ in range(150):
        run.advance(5, 1e-3)
        worst = max(worst, run.energy() - e0)
    assert run.energy() < e0 - 0.1  # it did dissipate
    # contact-free, these integrators drift by at most ~1e-6 J over the fall
    assert worst < 1e-5


def test_repeated_runs_are_bit_identical():
    bodies = (box("b", [0.0, 0.0, 0.3], [0.2, 0.3, 0.1], material='"half"',
                  orientation="{ axis = [1.0, 2.0, 0.5], angle = 0.5 }")
              + sphere("s", [0.1, 0.05, 0.6], velocity=[0.0, 0.0, -1.0], material='"half"'))
    digests = []
    for _ in range(2):
        run = Run(scene(bodies, ground='material = "half"', materials=MATERIALS), "rk4",
                  "penalty")
        run.advance(700, 1e-3)
        digests.append(run.digest())
    assert digests[0] == digests[1]
