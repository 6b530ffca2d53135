"""MuJoCo on a fluid case (issue 14, point 4): the settling disc of
``cases/fluid/settling_disc.toml`` run as a long cylinder in MuJoCo's stateless medium
(scene/medium_map.py), one run per fluid model ("rk4+ellipsoid", "rk4+inertia_box").

Each MuJoCo run must equal the closed form of its own model (reference/medium_analytic.
mapped_law) to its integrator's error, and start from rest at exactly the stateless
g (1 - rho_f / rho_s): no added mass. What cannot be mapped is refused at its field; the peers
without a fluid say so. Figures: MuJoCo 4.0.0 (docs/engines.md, "MuJoCo's stateless medium
against a resolved fluid").
"""

from __future__ import annotations

import math
from pathlib import Path

import mujoco
import numpy as np
import pytest

from crosscheck.compare.evaluate import evaluate
from crosscheck.engines import get_engine
from crosscheck.engines.driver import run
from crosscheck.engines.mujoco import FLUIDCOEF_DEFAULT, MujocoEngine, MujocoModel
from crosscheck.errors import CaseError
from crosscheck.reference import medium_analytic
from crosscheck.reference.medium_analytic import mapped_law, motion
from crosscheck.scene.loader import load_case, load_case_text
from crosscheck.scene.medium_map import LENGTH_IN_RADII

CASE = Path(__file__).resolve().parents[2] / "cases" / "fluid" / "settling_disc.toml"
ENGINE = MujocoEngine()
MODELS = ("ellipsoid", "inertia_box")


@pytest.fixture(scope="module")
def scene():
    return load_case(CASE)


def test_the_reference_carries_mujocos_default_coefficients():
    assert tuple(medium_analytic.FLUIDCOEF_DEFAULT) == tuple(FLUIDCOEF_DEFAULT)


@pytest.mark.parametrize("model", MODELS)
def test_the_mapped_cylinder_follows_the_closed_form_of_its_model(scene, model):
    """RK4 at the case's 5 ms: h k = 0.035 (k = 7.0 / 6.8 1/s), error ~ (h k)^4 / 120 ~ 1e-8 of
    u_t. Measured: terminal velocity 1.30391 m/s (ellipsoid) / 1.24601 (inertia box), at T off
    the closed form by 2.4e-13 / 6.8e-12 of u_t, velocity error max 2.0e-9 / 2.3e-9 m/s."""
    ran = run(ENGINE, scene, f"rk4+{model}", scene.run.dt, cost=None)
    traj = ran.trajectory
    assert ran.fluid is None and traj.failure is None
    assert traj.com.shape[1:] == (1, 2)  # the fluid case's 2D convention, +y up
    lw = mapped_law(scene, model)
    _, u = motion(lw, traj.t)
    np.testing.assert_allclose(-traj.vel[:, 0, 1], u, rtol=0, atol=1e-7)
    np.testing.assert_allclose(traj.vel[:, 0, 0], 0.0, atol=1e-12)
    # at T = 2 s the approach is e^(-k T) = e^-14 (8e-7) from u_t: judged against the closed
    # form at T, as the metric does
    assert abs((-traj.vel[-1, 0, 1] - u[-1]) / lw["u_t"]) < 1e-6
    # the closed form is the per-unit-length law of docs/engines.md: C_D = pi C_blunt / 2 or
    # sqrt(3) / 2 on the diameter, viscous pi mu (1 + 4 R / L) or pi mu (1 + 2 sqrt(3) R / L)
    r, mu, rho = 0.05, 2.5, 1000.0
    length = LENGTH_IN_RADII * r
    cd = math.pi * FLUIDCOEF_DEFAULT[0] / 2 if model == "ellipsoid" else math.sqrt(3) / 2
    visc = 1 + (4 if model == "ellipsoid" else 2 * math.sqrt(3)) * r / length
    # (the box's half sizes come from differences of moments ~ M L^2 / 12: 1e-11 of cancellation)
    assert lw["c"] / length == pytest.approx(0.5 * rho * cd * 2 * r, rel=1e-9)
    assert lw["b"] / length == pytest.approx(math.pi * mu * visc, rel=1e-12)
    u_t = {"ellipsoid": 1.30391, "inertia_box": 1.24601}[model]
    assert lw["u_t"] == pytest.approx(u_t, abs=1e-5)
    # the cell's verdict: the case's limits on MuJoCo's metrics, all met
    ev = evaluate(scene, traj, None, "mujoco", f"rk4+{model}")
    assert ev.status == "pass", ev.table()
    assert ev.metrics["terminal_velocity_error_rel"]["passed"] is True
    assert ev.metrics["startup_acceleration_error"]["passed"] is True


@pytest.mark.parametrize("model", MODELS)
def test_mujoco_starts_at_the_stateless_acceleration_exactly(scene, model):
    """At rest neither model has a force but the buoyancy (gravcomp): the disc starts at
    g (1 - rho_f / rho_s) = 4.905 m/s^2, to round-off; the resolved fluid's added mass
    (rho pi R^2 per unit length) would give g (rho_s - rho_f) / (rho_s + rho_f) = 3.27."""
    m = MujocoModel(scene, f"rk4+{model}", scene.run.dt)
    m.set_initial_state()
    mujoco.mj_forward(m.model, m.data)
    g = 9.81
    assert m.data.qacc[1] == pytest.approx(-g * (1 - 1000.0 / 2000.0), rel=1e-12)
    acc = medium_analytic.settling_accelerations(scene)
    assert acc["stateless"] == pytest.approx(4.905) and acc["added_mass"] == pytest.approx(3.27)
    eff = m.effective()
    assert eff["fluid_case"]["length_in_radii"] == LENGTH_IN_RADII
    assert eff["fluid_case"]["gravcomp"] == pytest.approx(0.5, rel=1e-12)
    body = eff["medium"]["bodies"][0]
    if model == "inertia_box":  # MuJoCo's box of the cylinder: sqrt(3) R / 2, sqrt(3) R / 2, L / 2
        np.testing.assert_allclose(body["box_half_sizes"],
                                   [math.sqrt(3) / 2 * 0.05, math.sqrt(3) / 2 * 0.05, 25.0],
                                   rtol=1e-9)
    else:
        np.testing.assert_allclose(body["semi_axes"], [0.05, 0.05, 25.0], rtol=1e-12)


FLUID = """
[case]
name = "t"
dimension = 2
[run]
duration = 0.1
dt = 0.005
integrators = {{ mujoco = ["rk4+ellipsoid"] }}
[effects]
gravity = [0.0, -9.81]
[[bodies]]
name = "disc"
shape = {shape}
density = 2000.0
position = [0.5, 0.5]
[fluid]
domain = [1.0, 1.0]
resolution = [32, 32]
kinematic_viscosity = 1e-3
{fluid}
"""
CIRCLE = "{ circle = { radius = 0.05 } }"


@pytest.mark.parametrize(("shape", "fluid", "field", "expected"), [
    (CIRCLE, 'initial = [{ layer = { depth = 0.8 } }]', "fluid.initial", "no free surface"),
    ("{ box = { size = [0.1, 0.1] } }", "", "bodies[0].shape", "a circle"),
    (CIRCLE, 'obstacles = [{ circle = { center = [0.2, 0.2], radius = 0.05 } }]',
     "fluid.obstacles", "no obstacles"),
    (CIRCLE, 'walls = { top = "open" }', "fluid.walls", "closed solid sides"),
    (CIRCLE, 'lid = { side = "top", speed = 1.0 }', "fluid.lid", "no moving side"),
])
def test_what_cannot_be_mapped_is_refused_at_its_field(shape, fluid, field, expected):
    with pytest.raises(CaseError) as info:
        load_case_text(FLUID.format(shape=shape, fluid=fluid), "t.toml")
    exc = info.value
    assert exc.field == field, str(exc)
    assert expected in exc.expected and "stateless medium" in exc.expected, str(exc)
    assert str(exc).startswith(f"t.toml: {field}: expected ")


def test_not_applicable_reasons(scene):
    # the peers have no fluid at all
    for name in ("pybullet", "pymunk"):
        engine = get_engine(name)
        reason = engine.not_applicable(scene, engine.capabilities().default_integrator)
        assert "no fluid" in reason and "no buoyancy, no fluid drag" in reason
    # MuJoCo needs the model named on a fluid case, and a fluid case it can map
    assert "integrator+model" in ENGINE.not_applicable(scene, "rk4")
    assert ENGINE.not_applicable(scene, "rk4+ellipsoid") is None
    surface = load_case(CASE.parents[0] / "floating_box.toml")
    assert "no free surface" in ENGINE.not_applicable(surface, "rk4+ellipsoid")
    # a medium model run on a rigid case is not applicable, with the route the medium takes
    rigid = load_case(CASE.parents[1] / "medium" / "rising_sphere.toml")
    assert "fluid_model" in ENGINE.not_applicable(rigid, "rk4+ellipsoid")
    # the model is the run's: a fluid case may not pin it as an engine option
    pinned = load_case_text(FLUID.format(shape=CIRCLE, fluid="") + """
[engine_options.mujoco]
fluid_model = "ellipsoid"
""", "t.toml")
    with pytest.raises(CaseError) as info:
        ENGINE.not_applicable(pinned, "rk4+ellipsoid")
    assert info.value.field == "engine_options.mujoco.fluid_model"


def test_the_runner_puts_mujocos_cell_beside_the_fluid_cells(scene, tmp_path):
    """A MuJoCo cell of the fluid case goes through the runner as a rigid-like cell: a verdict
    from its own closed form, its end state, no fluid plots."""
    from crosscheck.runner.cell import execute_task

    task = {"kind": "cell", "id": "x", "case": scene.name, "case_file": str(CASE),
            "engine": "mujoco", "integrator": "rk4+inertia_box", "dt": scene.run.dt,
            "timeout": 60, "out": str(tmp_path), "save_trajectories": False, "reference": None,
            "cost": False}
    result = execute_task(task)
    assert result["status"] == "pass", result.get("reason")
    assert result["metrics"]["terminal_velocity"]["value"] == pytest.approx(1.24601, abs=1e-5)
    assert result["end_state"]["rot_kind"] == "angle" and "fluid" not in result
    assert result["effective"] is None or "fluid_case" in result["effective"]


def test_mujocos_cell_of_a_fluid_case_never_builds_a_grid(scene, monkeypatch):
    """Only what is declared: MuJoCo's cell takes the rigid path (no fluid session, no grid)."""
    import crosscheck.sim.fluid.run as fluid_run

    def refuse(*args, **kwargs):
        raise AssertionError("a grid was built for MuJoCo's cell")

    monkeypatch.setattr(fluid_run.FluidRun, "__init__", refuse)
    monkeypatch.setattr(MujocoEngine, "open_fluid", refuse)
    ran = run(ENGINE, scene, "rk4+ellipsoid", scene.run.dt, cost=None)
    assert ran.fluid is None and ran.trajectory.failure is None


@pytest.mark.parametrize("model", MODELS)
def test_a_light_disc_rises_by_the_same_closed_form(scene, model):
    """The disc at 500 kg/m^3, released near the bottom: MuJoCo's cylinder rises, starting at
    g (1 - rho_f / rho_s) = -9.81 m/s^2 exactly (three times the resolved fluid's -3.27 with the
    added mass, tests/fluid/test_settling_disc.py) and following its closed form."""
    import dataclasses

    body = scene.fluid.bodies[0]
    light = dataclasses.replace(body, mass=body.mass / 4, inertia=body.inertia / 4,
                                position=np.array([1.0, 0.3]))
    sc = dataclasses.replace(scene, bodies=(light,),
                             fluid=dataclasses.replace(scene.fluid, bodies=(light,)))
    ran = run(ENGINE, sc, f"rk4+{model}", sc.run.dt, cost=None)
    traj = ran.trajectory
    lw = mapped_law(sc, model)
    np.testing.assert_allclose(lw["n"], [0.0, 1.0])
    _, u = motion(lw, traj.t)
    # RK4 at h k = 0.005 x 20 /s = 0.1: ~ (h k)^4 / 120 = 8e-7 of u_t (measured 1.07e-7 m/s)
    np.testing.assert_allclose(traj.vel[:, 0, 1], u, rtol=0, atol=1e-6)
    m = MujocoModel(sc, f"rk4+{model}", sc.run.dt)
    m.set_initial_state()
    mujoco.mj_forward(m.model, m.data)
    assert m.data.qacc[1] == pytest.approx(9.81 * (1000.0 / 500.0 - 1.0), rel=1e-12)
    acc = medium_analytic.settling_accelerations(sc)
    assert acc["stateless"] == pytest.approx(-9.81) and acc["added_mass"] == pytest.approx(-3.27)
    ev = evaluate(sc, traj, None, "mujoco", f"rk4+{model}")
    assert ev.metrics["terminal_velocity_error_rel"]["value"] < 1e-10
    assert ev.metrics["velocity_error_max"]["value"] < 1e-6
    # the three-point difference at 10 ms on an approach of rate k ~ 20 /s: ~ (k h)^2 / 3 = 1.3 %
    # (measured 0.59 %; the case's 2e-3 is for its heavy disc, k = 7 /s)
    assert ev.metrics["startup_acceleration_error"]["value"] < (lw["k"] * 0.01) ** 2 / 3
