"""The event-driven ``impulse_lcp`` model (docs/inhouse.md, "Contact: impulse_lcp"): bounce apexes
e^(2k) h0 and Newton's cradle to round-off, momentum through body-body impacts without gravity,
no tunnelling, a standing stack, 2D and 3D, and bit-identical repeats."""

from __future__ import annotations

import numpy as np
import pytest
from contact_scenes import Run, box, circle, momenta, oblique_impact_bodies, scene, sphere

MATERIALS = """[materials.half]
friction = 0.5
restitution = 0.5
[materials.steel]
friction = 0.0
restitution = 1.0
[materials.rough]
friction = 0.8
restitution = 0.5
"""


def _apexes(run: Run, steps: int, h: float, axis: int) -> list[float]:
    """Heights of the centre at the local maxima of a ballistic run, sampled every step."""
    z = []
    for _ in range(steps):
        run.advance(1, h)
        z.append(run.state.x[0, axis])
    z = np.array(z)
    k = np.nonzero((z[1:-1] > z[:-2]) & (z[1:-1] >= z[2:]))[0] + 1
    return [float(z[i]) for i in k]


@pytest.mark.parametrize("dim", [3, 2])
def test_bounce_apexes_are_e_to_the_2k_times_the_drop(dim):
    # bottom 1 m above the ground, e = 0.5: apexes 0.25, 0.0625, 0.015625 m above the rest height
    make = sphere if dim == 3 else circle
    pos = [0.0, 0.0, 1.1] if dim == 3 else [0.0, 1.1]
    sc = scene(make("ball", pos, material='"half"'), dim=dim,
               ground='material = "half"', materials=MATERIALS)
    run = Run(sc, "rk4", "impulse_lcp")
    apexes = _apexes(run, 2500, 1e-3, dim - 1)
    heights = np.array(apexes[:3]) - 0.1
    truth = 0.5 ** (2 * np.arange(1, 4))
    # The impacts are found to the time-of-impact band (1e-5 m); a sampled maximum misses the
    # apex by at most g dt^2 / 8 = 1.2e-6 m.
    np.testing.assert_allclose(heights, truth, rtol=0, atol=2e-5)


@pytest.mark.parametrize("dim", [3, 2])
def test_newtons_cradle_with_gaps_is_exact(dim):
    make = sphere if dim == 3 else circle
    z = [0.0] if dim == 3 else []
    v = [1.0, 0.0] + z
    bodies = (make("a", [0.0, 0.0] + z, velocity=v, material='"steel"')
              + make("b", [0.21, 0.0] + z, material='"steel"')
              + make("c", [0.411, 0.0] + z, material='"steel"'))
    run = Run(scene(bodies, dim=dim, gravity=False, ground=None, materials=MATERIALS), "rk4",
              "impulse_lcp")
    run.advance(500, 1e-4)
    np.testing.assert_allclose(run.velocities()[:, 0], [0.0, 0.0, 1.0], rtol=0, atol=1e-14)
    np.testing.assert_allclose(run.velocities()[:, 1:], 0.0, rtol=0, atol=1e-14)


@pytest.mark.parametrize("collision, expected", [
    ("sequential", [0.0, 0.0, 1.0]),          # Baraff's propagation
    ("simultaneous", [-1 / 3, 2 / 3, 2 / 3]),  # the impulse LCP (CONTACTS.md C17)
])
def test_touching_cradle_sequential_or_simultaneous(collision, expected):
    bodies = (sphere("a", [0.0, 0.0, 0.0], velocity=[1.0, 0.0, 0.0], material='"steel"')
              + sphere("b", [0.2, 0.0, 0.0], material='"steel"')
              + sphere("c", [0.4, 0.0, 0.0], material='"steel"'))
    run = Run(scene(bodies, gravity=False, ground=None, materials=MATERIALS), "rk4",
              "impulse_lcp", {"collision": collision, "lcp_tolerance": 1e-13})
    run.advance(20, 1e-4)
    np.testing.assert_allclose(run.velocities()[:, 0], expected, rtol=0, atol=1e-9)


# The penalty model with symplectic Euler: its kick adds equal and opposite forces at one point
# and its drift keeps x x P and L, so both momenta are kept to round-off; RK4 keeps angular
# momentum (a quadratic invariant) only to its truncation error (measured 1.4e-6 here).
@pytest.mark.parametrize("model, integrator", [("impulse_lcp", "rk4"),
                                               ("penalty", "symplectic_euler")])
@pytest.mark.parametrize("dim", [3, 2])
def test_momentum_is_conserved_through_oblique_impacts_without_gravity(model, integrator, dim):
    # an off-centre hit with friction and spin between a sphere and a box, then the box on a
    # third body: linear and angular momentum (about the origin) are kept to round-off
    bodies = oblique_impact_bodies(dim)
    run = Run(scene(bodies, dim=dim, gravity=False, ground=None, materials=MATERIALS),
              integrator, model)
    lin0, ang0 = momenta(run)
    v0 = run.velocities().copy()
    run.advance(400, 1e-3)
    lin, ang = momenta(run)
    assert not np.allclose(run.velocities(), v0)  # something was hit
    assert np.all(np.abs(run.velocities()[2]) + np.abs(run.velocities()[1]) > 0)
    np.testing.assert_allclose(lin, lin0, rtol=0, atol=1e-13)
    np.testing.assert_allclose(ang, ang0, rtol=0, atol=1e-13)


def test_a_fast_ball_does_not_tunnel_through_a_thin_wall():
    # tunnelling.toml: 200 m/s at a 1 cm wall, dt = 1e-3 (the centre jumps 0.2 m a step)
    statics = """[[statics]]
name = "wall"
shape = { box = { size = [0.01, 1.0, 1.0] } }
position = [2.1, 0.0, 0.0]
material = "half"
"""
    sc = scene(sphere("ball", [0.0, 0.0, 0.0], radius=0.05, mass=0.1, velocity=[200.0, 0, 0],
                      material='"half"'), gravity=False, ground=None, statics=statics,
               materials=MATERIALS)
    run = Run(sc, "rk4", "impulse_lcp")
    run.advance(20, 1e-3)
    assert run.state.x[0, 0] < 2.095 - 0.05
    np.testing.assert_allclose(run.velocities()[0], [-100.0, 0.0, 0.0], rtol=0, atol=1e-9)


@pytest.mark.parametrize("dim", [3, 2])
def test_a_stack_stands_still(dim):
    size = [1.0, 1.0, 1.0] if dim == 3 else [1.0, 1.0]
    z = [0.0] if dim == 3 else []
    bodies = "".join(box(f"b{k}", [0.0] + z + [0.5 + k] if dim == 3 else [0.0, 0.5 + k], size,
                         material='"half"') for k in range(5))
    run = Run(scene(bodies, dim=dim, ground='material = "half"', materials=MATERIALS), "rk4",
              "impulse_lcp")
    x0 = run.state.x.copy()
    run.advance(1000, 1e-3)
    # measured 1.4e-6 m (3D), 1e-7 (2D): friction sweeps stop at the LCP tolerance (1e-6 of the
    # largest force); the case stack_10.toml allows 1 mm in 5 s
    assert np.max(np.abs(run.state.x - x0)) < 1e-5


def test_repeated_runs_are_bit_identical():
    bodies = (sphere("a", [0.0, 0.0, 0.5], velocity=[1.0, 0.3, 0.0], angular=[1, 2, 3],
                     material='"half"')
              + box("b", [0.35, 0.05, 0.3], [0.2, 0.2, 0.2], material='"half"',
                    orientation="{ axis = [1.0, 1.0, 0.0], angle = 0.4 }"))
    digests = []
    for _ in range(2):
        run = Run(scene(bodies, ground='material = "half"', materials=MATERIALS), "rk4",
                  "impulse_lcp")
        run.advance(800, 1e-3)
        digests.append(run.digest())
    assert digests[0] == digests[1]
