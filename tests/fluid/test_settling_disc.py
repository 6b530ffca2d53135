"""The in-house side of the comparison with MuJoCo (issue 14, point 4): the disc of
``cases/fluid/settling_disc.toml`` (R = 0.05 m, rho_s / rho_f = 2, nu = 2.5e-3 m^2/s, a closed
box 20 diameters wide full of fluid) settling from rest, coupled both ways.

What the resolved fluid and MuJoCo's stateless medium both claim (the reduced weight, and a drag
that carries it at terminal speed) is checked against the published drag of a cylinder; what
they cannot share is measured: the added mass in the start-up acceleration (MuJoCo exactly
g (1 - rho_f / rho_s), tests/engines/test_mujoco_fluid_case.py) and the terminal speed MuJoCo's
constant coefficients give. Grid convergence: benchmarks/results/settling_disc.md.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from crosscheck.compare.fluid_metrics import fluid_metrics
from crosscheck.reference.fluid_data import cylinder_drag_band
from crosscheck.reference.medium_analytic import settling_accelerations, startup_acceleration
from crosscheck.sim.fluid.run import FluidRun

G = 9.81


def test_the_start_carries_the_added_mass_mujocos_does_not(fluid_case):
    """The first three 1 ms steps of the case: the disc starts at g (rho_s - rho_f) / (rho_s +
    C_a rho_f) with C_a the added mass of a cylinder, 1 in unbounded potential flow (Lamb sec.
    92) and 1.005 against the concentric tube of the box's half width (Kelvin's bound, (1 +
    (R / b)^2) / (1 - (R / b)^2), b = 1 m). Measured: 3.2761 m/s^2 (C_a = 0.994) at the case's
    R / dx = 2.4 (3.2862 before the coupled viscous step weighed each face's momentum by its
    open fraction); before that, 3.3372 (0.940) at 4 and 3.3632 (0.917) at 6.4 (benchmarks/
    results/settling_disc.md; 3.2685 / 3.2864 / 3.3084 before the incremental coupled
    projection). The
    parabola through three steps carries the viscous force that grows over them (the first step
    alone: 3.213 / 3.214 / 3.243, C_a 1.053 / 1.052 / 1.025, docs/fluid.md), so the estimate
    depends on the step and the grid, and this holds at the case's grid.
    Tolerance 3 % on the acceleration (C_a within 0.95-1.06): the kinetic energy the projection
    weights is first order at cut faces, 1-3 % on the added mass of a cylinder in a closed box
    (docs/fluid.md). MuJoCo starts at
    g / 2 = 4.905 (its models have no -m_A dv/dt): 1.5 times faster, the ratio
    (rho_s + rho_f) / rho_s the added mass makes."""
    scene = fluid_case("settling_disc")
    short = dataclasses.replace(scene, run=dataclasses.replace(
        scene.run, duration=0.01, dt=0.001, sample_every=0.001))
    rec = FluidRun(short, "semi_lagrangian").record()
    assert rec.failure is None
    a0 = -startup_acceleration(rec.t, rec.series["body_vy.disc"])
    acc = settling_accelerations(scene)
    assert acc["added_mass"] == pytest.approx(G * (2000 - 1000) / (2000 + 1000))
    assert a0 == pytest.approx(acc["added_mass"], rel=0.03)
    def added_mass_coefficient(a):   # a = g (rho_s - rho_f) / (rho_s + C_a rho_f)
        return ((2000.0 - 1000.0) * G / a - 2000.0) / 1000.0

    assert 0.95 < added_mass_coefficient(a0) < 1.06
    # The first step alone is the added mass, before any viscous history acts (the coupled
    # projection from rest is the potential-flow impulse response): measured 3.2131 m/s^2, C_a
    # 1.053, the same at a step of 0.25 ms to 4e-4; Kelvin's bound for the box 1.005. The
    # projection's kinetic energy is first order at cut faces: C_a within 1.0-1.07. Without the
    # body's term in the solve (no added mass) the step would give g / 2.
    t, vy = np.asarray(rec.t), np.asarray(rec.series["body_vy.disc"])
    first = -(vy[1] - vy[0]) / (t[1] - t[0])
    assert 1.0 < added_mass_coefficient(first) < 1.07
    # the difference MuJoCo cannot have, measured: 1.5 x (to the same 3 %)
    assert acc["stateless"] / a0 == pytest.approx(1.5, rel=0.03)
    assert acc["stateless"] == pytest.approx(G / 2)


@pytest.mark.parametrize("resolution", [(96, 144), (160, 240)])
def test_the_coupled_start_is_the_discrete_potential_flows_added_mass(fluid_case, resolution):
    """Why the first step's C_a is 2-5 % above Kelvin's 1.005: the coupled projection from rest
    (the body's velocity an unknown of the pressure solve) is the discrete potential flow's
    impulse response, so its added mass is the one the cut-cell projection's kinetic energy
    gives, whatever the coupling does. The disc of the case, inviscid, one 1 ms step from rest
    (the acceleration g (rho_s - rho_f) / (rho_s + C_a rho_f)), against the fluid's kinetic
    energy when the disc moves at 1 m/s through the resting box (``potential.
    moving_body_added_mass``: one projection of the same cut cells). Measured (2026-11-30):
    C_a 1.0537 / 1.0537 at R / dx = 2.4 (apart by 1.5e-7), 1.0533 / 1.0533 at 4 (2e-8), 1.0263 /
    1.0263 at 6.4; the viscous case's step 1.0531 / 1.0523 / 1.0248. Bound 1e-5 on C_a (the
    pressure solves' tolerance): a coupled solve that weighed the body's faces otherwise than
    the projection, or left the added mass out (C_a 0), fails it. The 2-5 % themselves are the
    cut cells' kinetic energy (docs/fluid.md: the whole disturbance energy of a fixed cylinder
    +2.9 % at 10 cells across, aligned), not the coupling; they depend on the direction of
    motion against the grid (the same disc moving sideways: C_a 0.953 at R / dx = 2.4, 1.056 at
    4)."""
    from crosscheck.scene.shapes import Circle, Placed
    from crosscheck.sim.fluid.potential import moving_body_added_mass

    scene = fluid_case("settling_disc")
    fluid = dataclasses.replace(scene.fluid, resolution=resolution, kinematic_viscosity=0.0)
    short = dataclasses.replace(scene, fluid=fluid, run=dataclasses.replace(
        scene.run, duration=0.001, dt=0.001, sample_every=0.001))
    rec = FluidRun(short, "semi_lagrangian").record()
    assert rec.failure is None
    t, vy = np.asarray(rec.t), np.asarray(rec.series["body_vy.disc"])
    a = -(vy[1] - vy[0]) / (t[1] - t[0])
    coupled = ((2000.0 - 1000.0) * G / a - 2000.0) / 1000.0
    body = scene.fluid.bodies[0]
    area = math.pi * 0.05 ** 2
    potential = moving_body_added_mass(fluid, Placed(Circle(0.05), body.position, 0.0),
                                       (0.0, -1.0)) / (1000.0 * area)
    assert 1.0 < potential < 1.07     # the cut cells' kinetic energy, first order at the wall
    assert coupled == pytest.approx(potential, abs=1e-5)


def test_a_light_disc_starts_rising_three_times_slower_than_mujocos(fluid_case):
    """The disc at 500 kg/m^3 released near the bottom of the same box: the resolved fluid
    starts it up at g (rho_f - rho_s) / (rho_s + rho_f) = 3.27 m/s^2, MuJoCo's medium at
    g (rho_f / rho_s - 1) = 9.81 (exactly: tests/engines/test_mujoco_fluid_case.py): for a light
    body the missing added mass triples the start. Measured -3.2600 m/s^2 (C_a 1.005) from the
    first three 1 ms steps at the case's grid (-3.2854 before the coupled viscous step weighed
    each face's momentum by its open fraction, -3.2625 before the incremental coupled
    projection); tolerance 3 % as for the heavy disc."""
    scene = fluid_case("settling_disc")
    body = scene.fluid.bodies[0]
    light = dataclasses.replace(body, mass=body.mass / 4, inertia=body.inertia / 4,
                                position=np.array([1.0, 0.3]))
    short = dataclasses.replace(
        scene, bodies=(light,), fluid=dataclasses.replace(scene.fluid, bodies=(light,)),
        run=dataclasses.replace(scene.run, duration=0.01, dt=0.001, sample_every=0.001))
    rec = FluidRun(short, "semi_lagrangian").record()
    assert rec.failure is None
    a0 = -startup_acceleration(rec.t, rec.series["body_vy.disc"])  # along gravity: < 0, rising
    acc = settling_accelerations(short)
    assert acc["added_mass"] == pytest.approx(-3.27) and acc["stateless"] == pytest.approx(-9.81)
    assert a0 == pytest.approx(acc["added_mass"], rel=0.03)
    assert acc["stateless"] / a0 == pytest.approx(3.0, rel=0.03)
    m = fluid_metrics(short, rec)
    assert m["startup_acceleration_error"] < 0.03
    assert 0.95 < m["added_mass_coefficient"] < 1.06


@pytest.mark.slow
def test_terminal_velocity_beside_mujoco_and_the_published_drag(runs):
    """The case (2 s, 400 steps; 38 s on the shared 2-core machine at load 9, 20 s less loaded).

    * Drag: the C_D that balances the reduced weight at the measured speed against the
      published band of a cylinder in unbounded steady flow at the measured Re
      (reference/data/cylinder_drag_steady_low_re.csv: 1.63-1.71 at Re 33.6). Measured 2.186
      at R / dx = 2.4, 27.9 % above the band (2026-12-01; 2.188, 28.0 %, before the trace took
      the field's own pose) since the convective exchange gives the body the
      momentum the semi-Lagrangian trace loses at its wall (22.3 % before it, with the
      weighted viscous step; 23.9 % with the moving-wall remedies before that, 25.2 % before
      them; 22 % before the coupled projection became incremental, whose slip at the body's
      wall took drag off); 1.911 at R / dx = 4 (15.2 %), 1.828 at 6.4 (11.3 %): converging
      from above at about second order; what stays is mostly the closed box (in a box 10
      diameters wide C_D is 10-11 % higher again; linear in the blockage, 2 C_D(0.05) -
      C_D(0.10) = 1.640 at 6.4, 1.9 % above the band), the 5 ms step (halved at R / dx = 4:
      C_D -0.5 %) and the unfinished approach (benchmarks/results/settling_disc.md,
      settling_disc_dt.md). The limit is the case grid's measured error with a margin, 32 %.
    * Force balance: at terminal speed the fluid's force on the disc carries its weight: 0.50 %
      (the speed still rises by ~2 % over the window: the 2D wake keeps growing).
    * Beside MuJoCo (closed forms of its models for the mapped cylinder, which its runs match to
      1e-12): MuJoCo settles at 1.304 (ellipsoid) / 1.246 m/s (inertia box); the resolved fluid
      at 0.840, 36 % / 33 % slower. The published band alone predicts 25-27 % / 22-24 %
      (U = sqrt((rho_s / rho - 1) pi R g / C_D)): most of the gap is MuJoCo's constant C_D
      (0.906 / 0.993 at its own terminal speed, viscous term included), the rest this grid's
      12-14 % of extra speed deficit (8-9 % before the convective exchange)."""
    scene, rec = runs("settling_disc", "semi_lagrangian")
    assert rec.failure is None
    m = fluid_metrics(scene, rec)
    assert m["centreline_offset"] < 1e-3
    assert 30 < m["terminal_reynolds"] < 40  # inside the published table's Re 20-40
    lo, hi = cylinder_drag_band(m["terminal_reynolds"])
    assert m["drag_coefficient"] > hi  # the grid's bias is too much drag
    assert m["drag_coefficient_error"] <= scene.tolerances["drag_coefficient_error"].limit(
        "inhouse", "semi_lagrangian") == 0.32
    assert m["terminal_force_balance_error"] < 0.02
    k = (2000.0 / 1000.0 - 1.0) * math.pi * 0.05 * G
    for model in ("ellipsoid", "inertia_box"):
        u_mj = m[f"terminal_velocity_mujoco_{model}"]
        gap = m[f"terminal_velocity_vs_mujoco_{model}"]
        predicted = (math.sqrt(k / hi) / u_mj - 1.0, math.sqrt(k / lo) / u_mj - 1.0)
        # MuJoCo's constant coefficients: faster than the published drag allows ...
        assert predicted[1] < -0.15
        # ... and the resolved fluid slower still by at most the grid's measured deficit
        # (C_D 32 % above the band: speed 1 / sqrt(1.32) = 0.870 of it)
        assert predicted[0] - 0.13 < gap < predicted[1]
    # MuJoCo's start and the resolved fluid's differ by the added mass (see the test above)
    assert m["startup_acceleration_stateless"] / m["startup_acceleration"] > 1.4
    e = rec.series["total_energy"]
    assert np.max(e - e[0]) < 0.02 * (e[0] - e[-1])  # energy falls; no rise beyond quadrature
