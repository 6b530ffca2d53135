"""medium_settling: the closed forms against a numerical integration of the same ODE, what the
solution refuses, and the energy accounting of a medium (buoyancy potential, drag dissipation,
the driver's runaway bound, drift not judged as conservation)."""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from crosscheck import quantities
from crosscheck.compare.scales import (
    angular_momentum_not_conserved,
    energy_not_conserved,
    internal_energy_decouples,
    linear_momentum_directions,
)
from crosscheck.reference.analytic import SOLUTIONS
from crosscheck.reference.medium_analytic import law, motion
from crosscheck.reference.newton_euler import equations
from crosscheck.scene.loader import load_case

CASES = Path(__file__).resolve().parents[2] / "cases" / "medium"


def _case(name: str, **params):
    scene = load_case(CASES / f"{name}.toml")
    if params:
        scene = replace(scene, reference=replace(scene.reference,
                                                 params={**scene.reference.params, **params}))
    return scene


def _numeric(lw: dict, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    def rhs(_, y):
        u = y[1]
        return [u, (lw["force"] - lw["b"] * u - lw["c"] * abs(u) * u) / lw["m_e"]]

    sol = solve_ivp(rhs, (0.0, t[-1]), [0.0, lw["u0"]], t_eval=t, method="DOP853",
                    rtol=1e-13, atol=1e-15)
    return sol.y[0], sol.y[1]


@pytest.mark.parametrize("name,params", [
    ("stokes_settling", {}),
    ("rising_sphere", {}),
    ("rising_sphere", {"drag": "stokes"}),
    ("quadratic_sphere", {}),
    ("quadratic_cube", {}),
    ("stokes_settling", {"added_mass_coefficient": 0.5}),
    ("quadratic_sphere", {"added_mass_coefficient": 0.5}),
])
def test_closed_forms_equal_the_integrated_law(name, params):
    scene = _case(name, **params)
    lw = law(scene, 0)
    t = np.linspace(0.0, scene.run.duration, 201)
    s, u = motion(lw, t)
    s_num, u_num = _numeric(lw, t)
    np.testing.assert_allclose(u, u_num, rtol=0, atol=1e-11 * lw["u_t"])
    np.testing.assert_allclose(s, s_num, rtol=0, atol=1e-11 * lw["u_t"] * t[-1])


def test_textbook_terminal_velocities():
    g = 9.81
    stokes = law(_case("stokes_settling"), 0)  # 2 (rho_s - rho_f) g r^2 / (9 mu)
    assert stokes["u_t"] == pytest.approx(2 * 1000.0 * g * 0.05**2 / (9 * 100.0), rel=1e-14)
    assert 1 / stokes["k"] == pytest.approx(2 * 2000.0 * 0.05**2 / (9 * 100.0), rel=1e-14)
    rising = law(_case("rising_sphere", drag="stokes"), 0)  # the same, upward
    assert rising["n"] @ [0, 0, 1.0] == 1.0
    assert rising["u_t"] == pytest.approx(2 * 500.0 * g * 0.1**2 / (9 * 100.0), rel=1e-14)
    quad = law(_case("quadratic_sphere"), 0)  # sqrt(2 m' g / (rho C_D A)), m' = m - rho V
    v = 4 / 3 * math.pi * 0.01**3
    assert quad["u_t"] == pytest.approx(
        math.sqrt(2 * (7800.0 - 1000.0) * v * g / (1000.0 * 0.47 * math.pi * 0.01**2)),
        rel=1e-14)
    # the tanh approach: u(t) = u_t tanh(g' t / u_t), g' = m' g / m
    t = np.linspace(0, 2, 50)
    _, u = motion(quad, t)
    g_red = (7800.0 - 1000.0) / 7800.0 * g
    np.testing.assert_allclose(u, quad["u_t"] * np.tanh(g_red * t / quad["u_t"]), rtol=1e-13,
                               atol=1e-15)
    # with added mass C_a = 1/2 the approach slows by m_e / m, the terminal velocity does not
    slow = law(_case("stokes_settling", added_mass_coefficient=0.5), 0)
    assert slow["u_t"] == stokes["u_t"] and slow["k"] == pytest.approx(stokes["k"] / 1.25)


def test_refusals():
    scene = _case("stokes_settling")
    with pytest.raises(ValueError, match="params.drag"):
        law(_case("stokes_settling", drag="newton"), 0)
    with pytest.raises(ValueError, match="drag_coefficient"):
        law(_case("stokes_settling", drag="quadratic"), 0)
    with pytest.raises(ValueError, match="Stokes' law 6 pi mu r v is a sphere's"):
        law(_case("quadratic_cube", drag="stokes"), 0)
    spun = replace(scene, bodies=(replace(scene.bodies[0],
                                          angular_velocity=np.array([0.0, 0.0, 1.0])),))
    with pytest.raises(ValueError, match="spins"):
        law(spun, 0)
    sideways = replace(scene, bodies=(replace(scene.bodies[0],
                                              velocity=np.array([0.1, 0.0, 0.0])),))
    with pytest.raises(ValueError, match="leaves the line"):
        law(sideways, 0)
    quad = _case("quadratic_sphere")
    upward = replace(quad, bodies=(replace(quad.bodies[0], velocity=np.array([0, 0, 1.0])),))
    with pytest.raises(ValueError, match="changes sign"):
        law(upward, 0)
    cube = _case("quadratic_cube")
    tilted = replace(cube, bodies=(replace(cube.bodies[0],
                                           orientation=np.array([math.cos(0.2), math.sin(0.2),
                                                                 0.0, 0.0])),))
    with pytest.raises(ValueError, match="box axes"):
        law(tilted, 0)
    # solutions that do not model a medium refuse it rather than answer without it
    for name in ("free_fall", "projectile", "torque_free"):
        with pytest.raises(ValueError, match="medium"):
            SOLUTIONS[name](scene, np.array([0.0]))
    with pytest.raises(ValueError, match="no medium"):
        equations(scene)


@pytest.mark.parametrize("name", ["stokes_settling", "rising_sphere", "quadratic_sphere"])
def test_energy_balance_with_the_buoyancy_potential(name):
    # Along the closed form, the total energy (kinetic + gravity + buoyancy potential) falls by
    # exactly the drag's work: E(0) - E(t) = int (b u^2 + c |u|^3) dt. Without the buoyancy
    # potential the balance would be off by rho_f V g s(t).
    scene = _case(name)
    lw = law(scene, 0)
    t = np.linspace(0.0, scene.run.duration, 4001)
    ref = SOLUTIONS["medium_settling"](scene, t)
    energy = quantities.total_energy(scene, ref)
    _, u = motion(lw, t)
    power = lw["b"] * u**2 + lw["c"] * np.abs(u) ** 3
    work = np.concatenate([[0.0], np.cumsum(0.5 * (power[1:] + power[:-1]) * np.diff(t))])
    scale = np.max(np.abs(energy - energy[0]))
    np.testing.assert_allclose(energy[0] - energy, work, rtol=0, atol=1e-6 * scale)
    without = energy - quantities.buoyancy_potential_energy(scene, ref)
    assert np.max(np.abs(without[0] - without - work)) > 0.1 * scale


def test_a_medium_is_not_judged_as_conservation():
    scene = _case("rising_sphere")
    assert energy_not_conserved(scene) == "the medium's drag dissipates energy"
    assert linear_momentum_directions(scene)[0] is None
    assert angular_momentum_not_conserved(scene) is not None
    assert not internal_energy_decouples(scene)


def test_the_runaway_bound_counts_the_buoyancy():
    # A sphere of 100 kg/m^3 in 1000 is pushed up by ten times its weight: the exchangeable energy
    # must bound the work of the net force 9 m g over a drag-free run, (9 m g)^2 D^2 / (2 m),
    # which a bound from the weight alone, (m g)^2 D^2 / (2 m), misses by 81x.
    scene = _case("rising_sphere")
    light = replace(scene.bodies[0], mass=100.0 * 4 / 3 * math.pi * 0.1**3)
    scene = replace(scene, bodies=(light,))
    first = SOLUTIONS["medium_settling"](scene, np.array([0.0]))
    m, d = light.mass, scene.run.duration
    assert quantities.buoyancy_forces(scene)[0] @ [0, 0, 1.0] == pytest.approx(10 * m * 9.81,
                                                                               rel=1e-12)
    free_work = (9 * m * 9.81) ** 2 * d**2 / (2 * m)
    assert quantities.exchangeable_energy(scene, first) >= free_work * (1 - 1e-12)
    assert (m * 9.81) ** 2 * d**2 / (2 * m) < free_work / 80
