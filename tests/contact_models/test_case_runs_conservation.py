"""Issue 12 point 3 for the runs the contact cases use (``rk4+impulse_lcp``, ``rk4+penalty``; the
velocity-level models' are in tests/contact_inhouse/test_velocity_models.py): no energy gain in a
scene that should lose it, and momentum through body-body impacts without gravity.

What was missing before: ``impulse_lcp`` had no energy test (penalty's is in test_penalty.py,
with RK4 among its integrators), and ``penalty``'s momentum test ran symplectic Euler only
(test_impulse_lcp.py), not the RK4 the cases run it with."""

from __future__ import annotations

import numpy as np
import pytest
from contact_scenes import Run, box, circle, momenta, oblique_impact_bodies, scene, sphere

MATERIALS = """[materials.dead]
friction = 0.5
restitution = 0.0
[materials.half]
friction = 0.5
restitution = 0.5
[materials.rough]
friction = 0.8
restitution = 0.5
"""

G = 9.81


def _dissipative(material: str, dim: int):
    """A tilted box and a spinning ball dropped on the ground, friction 0.5 (test_penalty.py's
    scene; in 2D a box and a disc)."""
    m = f'"{material}"'
    if dim == 3:
        bodies = (box("b", [0.0, 0.0, 0.3], [0.2, 0.3, 0.1], material=m,
                      orientation="{ axis = [1.0, 2.0, 0.5], angle = 0.5 }")
                  + sphere("s", [0.6, 0.0, 0.2], velocity=[1.0, 0.0, 0.0], angular=[0, 0, 20],
                           material=m))
    else:
        bodies = (box("b", [0.0, 0.3], [0.2, 0.1], material=m, orientation="0.5")
                  + circle("s", [0.6, 0.2], velocity=[1.0, 0.0], angular=20.0, material=m))
    return scene(bodies, dim=dim, ground=f"material = {m}", materials=MATERIALS)


@pytest.mark.parametrize("dim", [3, 2])
@pytest.mark.parametrize("material", ["dead", "half"])
def test_impulse_lcp_gains_no_energy_in_a_dissipative_scene(material, dim):
    run = Run(_dissipative(material, dim), "rk4", "impulse_lcp")
    e0 = run.energy()
    worst = -np.inf
    for _ in range(150):
        run.advance(10, 1e-3)
        worst = max(worst, run.energy() - e0)
    assert run.energy() < e0 - 1.0  # it did dissipate (measured: 3.58 J in 3D, 4.93 J in 2D)
    # Collision impulses with e <= 1 and friction in the Coulomb disc cannot add energy, and RK4
    # is exact for the free fall; what the model may add is the resting forces' stabilisation
    # pushing a body out of at most penetration_tolerance (1e-5 m): m g 1e-5 per body, 2e-4 J
    # here. Measured: 9e-15 J (round-off) in both dimensions and both materials.
    total_mass = float(run.model.bodies.mass.sum())
    assert worst <= total_mass * G * 1e-5


@pytest.mark.parametrize("dim", [3, 2])
def test_penalty_with_rk4_keeps_momentum_through_oblique_impacts_without_gravity(dim):
    # test_impulse_lcp.py's scene: an off-centre hit with friction and spin between a sphere and
    # a box, then the box on a third body
    bodies = oblique_impact_bodies(dim)
    run = Run(scene(bodies, dim=dim, gravity=False, ground=None, materials=MATERIALS), "rk4",
              "penalty")
    lin0, ang0 = momenta(run)
    v0 = run.velocities().copy()
    run.advance(400, 1e-3)
    lin, ang = momenta(run)
    assert not np.allclose(run.velocities(), v0)  # something was hit
    assert np.all(np.abs(run.velocities()[2]) > 0.1)  # the third body too
    # Every stage's contact forces are equal and opposite, so RK4's weighted sum of stages keeps
    # linear momentum to round-off (measured 6e-17 kg m/s).
    np.testing.assert_allclose(lin, lin0, rtol=0, atol=1e-13)
    # Angular momentum about the origin is quadratic in the state: RK4 keeps it only to its
    # truncation error over the contacts, h omega0 = 2 pi / 10 whatever the step (the stiffness
    # is set by the step). Measured 1.47e-6 kg m^2/s (3D, largest component) and 1.29e-6 (2D)
    # of |L| = 0.055 and 0.038; a force pair acting at two different points instead of one
    # (lever ~0.1 m, ~100 N over a 5 ms contact) would be off by ~0.05.
    np.testing.assert_allclose(ang, ang0, rtol=0, atol=5e-6)
