"""Two-way coupling of a rigid body with the fluid (issue 14, points 3 and 5): the moving body's
cut cells, the coupled projection (the body's velocity as unknowns of the pressure solve), the
floating box against Archimedes and its heave period, volume and energy, the case format's
refusals, and that only what a case declares runs."""

from __future__ import annotations

import copy
import dataclasses
import math

import numpy as np
import pytest

from crosscheck.compare.fluid_metrics import fluid_metrics
from crosscheck.errors import CaseError
from crosscheck.scene.loader import load_case_text
from crosscheck.scene.shapes import Box, Circle, Placed, Polygon
from crosscheck.sim.fluid import bodygeom, cutcell
from crosscheck.sim.fluid.run import FluidRun
from crosscheck.sim.fluid.solver import INTEGRATORS, PHASES, FluidState


def _case(body: str, fluid: str, effects: str = 'gravity = [0.0, -9.81]',
          duration: float = 0.1, dt: float = 0.005, extra: str = ""):
    text = f"""
[case]
name = "t"
dimension = 2
[run]
duration = {duration}
dt = {dt}
sample_every = {dt}
[effects]
{effects}
{body}
[fluid]
{fluid}
{extra}
"""
    return load_case_text(text, "t.toml")


BOX = """
[[bodies]]
name = "box"
shape = { box = { size = [0.2, 0.1] } }
density = 500.0
position = [0.5, %s]
"""


def _disc(radius: float, density: float, x: float, y: float) -> str:
    """A disc body's table in a case."""
    return f"""
[[bodies]]
name = "disc"
shape = {{ circle = {{ radius = {radius} }} }}
density = {density}
position = [{x}, {y}]
"""


TANK = """
domain = [1.0, 0.5]
resolution = [64, 32]
walls = { top = "open" }
initial = [{ layer = { depth = 0.25 } }]
"""


# -- geometry ------------------------------------------------------------------------------------
@pytest.mark.parametrize("placed", [
    Placed(Circle(0.23), (0.51, 0.47)),
    Placed(Box((0.3, 0.17)), (0.5, 0.45), 0.3),
    Placed(Polygon(np.array([[0.0, 0.0], [0.3, 0.05], [0.1, 0.25]])), (0.31, 0.4), 0.7),
])
def test_moving_body_geometry_is_the_cut_cells_of_cutcell(placed):
    """The compiled closed forms (bodygeom) give what the generic cut-cell code gives: face
    fractions and distances to round-off, cell areas exactly for polygons and to 1e-9 of a cell
    for a circle (16 Gauss points per piece in both)."""
    n, dx = 40, 1.0 / 40
    kind, c, r, verts = bodygeom.shape_params(placed)
    uf, vf, um, vm, ud, vd, cd, area = bodygeom.window_geometry(kind, c, r, verts, 0, 0, n, n, dx,
                                                        bodygeom.GAUSS_S, bodygeom.GAUSS_W)
    uf2, vf2 = cutcell.face_fractions([placed], n, n, dx)
    pu, pv, pc = cutcell.sample_points(n, n, dx)
    assert np.max(np.abs(uf - uf2)) < 1e-12 and np.max(np.abs(vf - vf2)) < 1e-12
    assert np.max(np.abs(ud - placed.signed_distance(pu))) < 1e-14
    assert np.max(np.abs(vd - placed.signed_distance(pv))) < 1e-14
    assert np.max(np.abs(cd - placed.signed_distance(pc))) < 1e-14
    area2 = cutcell.cell_solid_fractions([placed], n, n, dx)
    assert np.max(np.abs(area - area2)) < 1e-9
    assert area.sum() * dx * dx == pytest.approx(cutcell.shape_area(placed), rel=1e-9)


def test_submerged_area_and_centroid_are_exact():
    # a half-immersed disc: area pi R^2 / 2, centroid 4 R / (3 pi) below the centre
    kind, c, r, v = bodygeom.shape_params(Placed(Circle(0.1), (0.5, 0.3)))
    a, cen = bodygeom.submerged(kind, c, r, v, np.array([0.0, 1.0]), 0.3)
    assert a == pytest.approx(math.pi * 0.01 / 2, rel=1e-13)
    assert cen[1] == pytest.approx(0.3 - 0.4 / (3 * math.pi), rel=1e-13)
    # a box turned by 45 degrees, immersed to its centre: half its area, centroid on the axis
    kind, c, r, v = bodygeom.shape_params(Placed(Box((0.2, 0.2)), (0.5, 0.3), math.pi / 4))
    a, cen = bodygeom.submerged(kind, c, r, v, np.array([0.0, 1.0]), 0.3)
    assert a == pytest.approx(0.02, rel=1e-13)
    assert cen[0] == pytest.approx(0.5, abs=1e-14)


# -- the coupled projection --------------------------------------------------------------------
def _weighted_divergence(st):
    b = st.boundary
    fu = (1 - b.u_frac) * st.u + b.u_frac * b.u_solid
    fv = (1 - b.v_frac) * st.v + b.v_frac * b.v_solid
    return fu[1:] - fu[:-1] + fv[:, 1:] - fv[:, :-1]


def test_coupled_projection_added_mass_of_a_cylinder_and_momentum():
    """A disc moving at V0 through water at rest in a closed box, no gravity: one coupled
    projection leaves the fluid divergence free with the body's new velocity on its faces; the
    body keeps ``M / (M + m_a)`` of its velocity, with the potential-flow added mass of a
    circular cylinder ``m_a = rho pi R^2`` (Lamb, Hydrodynamics, sec. 92) increased by the walls
    (a cylinder on the axis of a square box of side 10 R: +2 % in the image-sum estimate
    ``1 + 2 (R / h)^2 pi^2 / 3`` with h the wall distance... bounded here by 4 %); the total
    momentum in a closed container is ``(M - rho A) V`` (the fluid moves back as the body
    displaces it: sum over the faces of open-fraction times velocity plus the body's flux
    vanishes, the discrete identity of a divergence-free field in a closed box)."""
    r = 0.1
    scene = _case(f"""
[[bodies]]
name = "disc"
shape = {{ circle = {{ radius = {r} }} }}
density = 1000.0
position = [0.5, 0.5]
velocity = [0.2, 0.0]
""", """
domain = [1.0, 1.0]
resolution = [64, 64]
""", effects="", duration=0.001, dt=0.001)
    st = FluidState(scene.fluid, np.zeros(2), INTEGRATORS["semi_lagrangian"])
    timers = {p: 0.0 for p in PHASES}
    st.step(0.001, timers)
    body = st.coupling.body
    m = body.mass
    ma = 1000.0 * math.pi * r * r
    ratio = body.v[0] / 0.2
    assert ratio == pytest.approx(m / (m + ma), rel=0.04)
    assert ratio < m / (m + ma)                  # the walls add to the added mass
    assert abs(body.v[1]) < 1e-6 * 0.2 and abs(body.omega) < 1e-6   # CG tolerance 1e-6
    div = _weighted_divergence(st)
    fluid = ~st.boundary.cells
    assert np.max(np.abs(div[fluid])) < 1e-6 * 0.2
    b = st.boundary
    flux_x = np.sum((1 - b.u_frac) * st.u + b.u_frac * b.u_solid)
    assert abs(flux_x) < 1e-6 * 0.2 * 64
    # so the fluid's momentum (open fractions times velocities) is minus the displaced water's:
    # the total is (M - rho A) V, A the body's area on the faces (interior ones: the sides
    # of the box are closed faces too)
    area = np.sum(b.u_frac[1:-1]) * st.dx ** 2     # the midpoint rule of the disc's area
    assert area == pytest.approx(math.pi * r * r, rel=0.02)
    p_fluid = 1000.0 * st.dx ** 2 * np.sum((1 - b.u_frac) * st.u)
    assert p_fluid + m * body.v[0] == pytest.approx((m - 1000.0 * area) * body.v[0],
                                                    abs=1e-6 * m * 0.2)


# -- floating ------------------------------------------------------------------------------------
def test_box_at_its_archimedes_draft_stays_there():
    # box 0.2 x 0.1 of density 500: draft 0.05 m; the layer (0.25 m) with the box in it leaves
    # the water level at 0.25 m, so the box's centre belongs at 0.25 m
    scene = _case(BOX % "0.25", TANK, duration=0.5)
    run = FluidRun(scene, "semi_lagrangian")
    rec = run.record()
    assert rec.failure is None
    y = rec.series["body_y.box"]
    assert np.max(np.abs(y - 0.25)) < 1e-9
    assert np.max(np.abs(rec.series["body_vy.box"])) < 1e-8
    assert np.max(rec.series["max_speed"]) < 1e-6


def test_floating_box_case(runs):
    """The case file: released 0.01 m above its draft (a fifth of it), the box heaves about its
    Archimedes draft (mean submerged area over the last two thirds within 1 % of M / rho: 0.74 %
    measured at this grid, 0.58 and 0.69 % at half and twice the resolution, i.e. the residual
    is the heave's nonlinearity and the waves' mean, not the grid: a 1 % draft error is
    0.03 cells of the 3.2-cell draft), its natural period within 10 % of the estimate with the
    high-frequency added mass (5.0 % measured; 2.3 and 3.2 % at half and twice), volume within
    1e-3 (1.5e-5 measured), and its energy with the level set's volume error taken out never
    grows by more than 5 % of ``M g`` times its release height (2.3 % measured; all
    2026-12-01)."""
    scene, rec = runs("floating_box", "semi_lagrangian")
    assert rec.failure is None
    m = fluid_metrics(scene, rec)
    assert m["draft_error"] < 0.01
    assert m["heave_period_error"] < 0.10
    assert 0.1 < m["heave_damping"] < 0.35        # strong radiation damping of a flat box
    assert m["volume_change"] < 1e-3
    assert m["energy_growth"] < 0.05
    assert np.max(np.abs(rec.series["body_angle.box"])) < 1e-6   # heave does not roll it
    assert abs(rec.series["body_x.box"][-1] - 1.0) < 1e-6
    for name in ("draft_error", "heave_period_error", "volume_change", "energy_growth"):
        assert m[name] <= scene.tolerances[name].limit("inhouse", "semi_lagrangian")


def test_tilted_box_rolls_back():
    """A box stable by its metacentric height (GM = 0.042 m) tilted by 1e-4 rad rolls back and
    forth instead of capsizing: the restoring moment of the hydrostatic pressure is Archimedes'
    exact one (coupling.Coupling.hydrostatic); with the cell-centred pressure alone the angle
    grew from round-off to 6e-3 rad in 3 s."""
    scene = _case(BOX % "0.254" + "orientation = 0.0001\n", TANK, duration=1.0)
    rec = FluidRun(scene, "semi_lagrangian").record()
    assert rec.failure is None
    ang = rec.series["body_angle.box"]
    assert np.max(np.abs(ang)) < 2e-4
    assert np.min(ang) < -3e-5 and np.max(ang[len(ang) // 2:]) > 3e-5   # it oscillates


def test_disc_sinking_in_a_closed_box_loses_energy():
    """A disc twice as dense as the water sinking in a closed box (no free surface): the total
    energy of fluid and body (kinetic, potential of both) never grows (semi-Lagrangian
    advection and the projection only take energy out) and the body's kinetic energy is
    well below what it would have falling in vacuum."""
    scene = _case(_disc(0.05, 2000.0, 0.5, 0.7), """
domain = [1.0, 1.0]
resolution = [48, 48]
""", duration=0.3, dt=0.005)
    rec = FluidRun(scene, "semi_lagrangian").record()
    assert rec.failure is None
    e = rec.series["total_energy"]
    released = 2000.0 * math.pi * 0.05 ** 2 * 9.81 * (0.7 - rec.series["body_y.disc"][-1])
    assert released > 0
    # the fluid's potential energy weights each cut cell's open area at the cell's centre, not
    # at the open part's centroid: about rho g dx^3 / 2 per cut cell, +-0.2 J here (1 %)
    assert np.max(e - e[0]) < 0.02 * released
    assert e[-1] < e[0] - 0.0 * released
    # reduced gravity (1 - 1/2) and added mass (half the displaced mass): a = g / 3 at first
    vy = rec.series["body_vy.disc"]
    assert vy[2] / rec.t[2] == pytest.approx(-9.81 / 3, rel=0.1)


# -- the case format -----------------------------------------------------------------------------
def test_bodies_in_a_fluid_case_refuse_bad_input():
    with pytest.raises(CaseError) as exc:
        _case(BOX % "0.25" + (BOX % "0.35").replace('"box"', '"box2"'), TANK)
    assert exc.value.field == "bodies[1]"
    with pytest.raises(CaseError) as exc:     # 1 cell from the bottom (2 required)
        _case(BOX % "0.064", TANK)
    assert exc.value.field == "bodies[0].position" and "bottom" in str(exc.value)
    with pytest.raises(CaseError) as exc:     # through the open top: outside, no clearance asked
        _case(BOX % "0.47", TANK)
    assert exc.value.field == "bodies[0].position"
    assert "within its open top side" in str(exc.value) and "0.02 m outside" in str(exc.value)
    with pytest.raises(CaseError) as exc:
        _case(BOX % "0.25", TANK + 'prescribed_velocity = { rotation = { center = [0.5, 0.5], '
              'angular_velocity = 1.0 } }')
    assert exc.value.field == "fluid.prescribed_velocity"
    with pytest.raises(CaseError) as exc:
        _case(BOX % "0.25", TANK + "kinematic_viscosity = 1e-3\nno_slip = false")
    assert exc.value.field == "fluid.no_slip"
    # the same spec built in code: the solver refuses it too (it would run with no viscous
    # force on the body: no wall, no exchange)
    scene = _case(BOX % "0.25", TANK + "kinematic_viscosity = 1e-3")
    free_slip = dataclasses.replace(scene.fluid, no_slip=False)
    with pytest.raises(ValueError, match="no_slip"):
        FluidState(free_slip, np.zeros(2), INTEGRATORS["semi_lagrangian"])
    with pytest.raises(CaseError) as exc:
        _case(BOX % "0.25", TANK, effects='gravity = [0.0, -9.81]\n[[effects.loads]]\n'
              'body = "box"\nforce = [1.0, 0.0]')
    assert exc.value.field == "effects.loads"
    with pytest.raises(CaseError) as exc:
        _case(BOX % "0.25", TANK, effects='gravity = [1.0, -9.81]')
    assert exc.value.field == "effects.gravity"
    with pytest.raises(CaseError) as exc:     # 1.3 cells from an obstacle
        _case(BOX % "0.25", TANK + 'obstacles = [{ circle = { center = [0.67, 0.2], '
              'radius = 0.05 } }]')
    assert exc.value.field == "bodies[0].position"


# -- only what is declared (issue 14, point 5) ---------------------------------------------------
def test_fluid_without_bodies_runs_no_coupling_code(monkeypatch, fluid_case):
    from crosscheck.sim.fluid import coupling, pressure, solver

    def boom(*a, **k):
        raise AssertionError("coupling code ran in a fluid case without bodies")

    monkeypatch.setattr(coupling.Coupling, "__init__", boom)
    monkeypatch.setattr(solver, "project_coupled", boom)
    monkeypatch.setattr(pressure, "pcg_lowrank", boom)
    monkeypatch.setattr(bodygeom, "window_geometry", boom)
    scene = fluid_case("tank_at_rest", 0.05)
    assert not scene.fluid.bodies
    rec = FluidRun(scene, "semi_lagrangian").record()
    assert rec.failure is None
    assert not any(k.startswith("body_") for k in rec.series)
    assert "bodies" not in rec.meta and "coupling" not in rec.meta


def test_rigid_scene_never_allocates_a_grid(monkeypatch):
    from crosscheck.engines import driver, get_engine
    from crosscheck.sim.fluid import run, solver

    def boom(*a, **k):
        raise AssertionError("a rigid scene built a fluid grid")

    monkeypatch.setattr(solver.FluidState, "__init__", boom)
    monkeypatch.setattr(run.FluidRun, "__init__", boom)
    scene = load_case_text("""
[case]
name = "fall"
dimension = 2
[run]
duration = 0.1
dt = 0.01
[effects]
gravity = [0.0, -9.81]
[[bodies]]
name = "disc"
shape = { circle = { radius = 0.1 } }
mass = 1.0
position = [0.0, 1.0]
""", "fall.toml")
    result = driver.run(get_engine("inhouse"), scene, "symplectic_euler", 0.01, cost=None)
    assert result.fluid is None and result.trajectory is not None


def test_spinning_disc_feels_no_pressure_moment_and_viscosity_slows_it():
    """The flux of the body's rigid motion through a face is taken at the midpoint of the
    face's solid part, so it is exact: a circle spinning about its centre displaces no water,
    the pressure has no moment on it, and without viscosity it keeps its angular velocity (to
    the CG tolerance). With viscosity the no-slip wall's momentum exchange spins it down, and
    the fluid gains at least what it loses (the semi-Lagrangian trace near the body also drags
    the fluid along, docs/fluid.md)."""
    def spin(nu):
        scene = _case("""
[[bodies]]
name = "disc"
shape = { circle = { radius = 0.1 } }
density = 1000.0
position = [0.5, 0.5]
angular_velocity = 2.0
""", f"""
domain = [1.0, 1.0]
resolution = [48, 48]
kinematic_viscosity = {nu}
""", effects="", duration=0.1, dt=0.005)
        return FluidRun(scene, "semi_lagrangian").record()

    rec = spin(0.0)
    assert rec.failure is None
    w = rec.series["body_omega.disc"]
    assert np.max(np.abs(w - 2.0)) < 1e-6
    assert np.max(np.abs(rec.series["body_vx.disc"])) < 1e-6
    rec = spin(1e-3)
    assert rec.failure is None
    w = rec.series["body_omega.disc"]
    assert np.all(np.diff(w) < 0) and 1.0 < w[-1] < 1.8
    assert rec.meta["coupling"]["viscous_exchange_number_max"] < 0.5


@pytest.mark.parametrize("h", [-0.2, -0.05, 0.0, 0.04, 0.09, 0.2])
def test_the_wetted_walls_moment_arm_is_the_integral_over_the_wetted_boundary(h):
    """``bodygeom.wetted_moment_arm`` (the symmetric stress's moment on a body the free surface
    cuts, ``Coupling.symmetric_stress_moment``) from areas and the chord, against the integral
    of ``(x - p) . n`` over the boundary below the level done directly: on a circle's wetted
    arc ``a`` times its length plus ``(c - p)`` against the arc's normals (``-chord up``); on a
    turned box, edge by edge, each edge's distance from ``p`` times its length below the level.
    The level ``h`` from the shape's centre: above it, through it, below it, beyond it."""
    up = np.array([0.0, 1.0])
    p = np.array([0.31, 0.52])     # the point the moment is taken about (off the centre)
    c, a = np.array([0.3, 0.5]), 0.1
    level = c[1] + h
    k, cc, r, verts = bodygeom.shape_params(Placed(Circle(a), c))
    hh = float(np.clip(h, -a, a))
    arc = 2.0 * a * math.acos(-hh / a)
    chord = 2.0 * math.sqrt(a * a - hh * hh)
    direct = a * arc + float((c - p) @ (-chord * up))
    got = bodygeom.wetted_moment_arm(k, cc, r, verts, up, level, p)
    assert got == pytest.approx(direct, rel=1e-6, abs=1e-12)

    k, cc, r, verts = bodygeom.shape_params(Placed(Box((0.24, 0.12)), c, 0.4))
    direct = 0.0
    for v0, v1 in zip(verts, np.roll(verts, -1, axis=0), strict=True):
        edge = v1 - v0
        normal = np.array([edge[1], -edge[0]]) / np.linalg.norm(edge)   # outward (CCW)
        s0, s1 = v0[1] - level, v1[1] - level      # the part with y < level
        if s0 < 0.0 and s1 < 0.0:
            below = 1.0
        elif s0 < 0.0 or s1 < 0.0:
            below = -min(s0, s1) / abs(s1 - s0)
        else:
            continue
        direct += float((v0 - p) @ normal) * np.linalg.norm(edge) * below
    got = bodygeom.wetted_moment_arm(k, cc, r, verts, up, level, p)
    assert got == pytest.approx(direct, rel=1e-6, abs=1e-12)


def test_a_disc_free_to_spin_in_a_shear_flow_turns_with_the_fluid():
    """A disc in Couette flow (the top wall at +U, the bottom at -U, shear rate 2 U / H) spins
    at the fluid's own rotation rate, half the shear rate (Jeffery's torque-free rotation of a
    circular cylinder in Stokes flow), not at the rate the viscous step's ``mu du/dn`` alone
    balances: that resists even a rigid rotation of the fluid, and the disc spun at 1.986 times
    half the shear rate before ``Coupling.symmetric_stress_moment`` put back the symmetric
    stress's moment (a moment only: the force of the same term is zero).

    Re = (2 U / H) a^2 / nu = 0.01; the disc (a = 0.05 m, 4 cells per radius) on the axis of a
    channel 0.5 m wide (a / h = 0.2) and 2 m long, dense (30 times water: the explicit wall
    exchange at 0.25 of its limit), no gravity, 15 s (the channel's profile settles on H^2 /
    (pi^2 nu) = 2.5 s). Measured (2026-11-30): 0.9968 times half the shear rate (`central`
    0.9969; the channel twice as long 0.9969; 8 cells per radius 0.9910, its end state after
    20 s). The confinement slows the free rotation below the unbounded value by an amount not
    known here (the two grids point to about 1 %): bound 3 %."""
    u_wall, nu = 0.01, 0.01
    scene = _case(_disc(0.05, 30000.0, 1.0, 0.25), f"""
domain = [2.0, 0.5]
resolution = [160, 40]
kinematic_viscosity = {nu}
lid = [{{ side = "top", speed = {u_wall} }}, {{ side = "bottom", speed = {-u_wall} }}]
""", effects="", duration=15.0, dt=0.02)
    rec = FluidRun(scene, "semi_lagrangian").record()
    assert rec.failure is None
    assert rec.meta["coupling"]["viscous_exchange_number_max"] < 0.5
    half_shear = -0.5 * (2.0 * u_wall / 0.5)      # clockwise: the fluid's rotation
    w = np.asarray(rec.series["body_omega.disc"])
    assert w[-1] / half_shear == pytest.approx(1.0, abs=0.03)
    assert abs(w[-1] - w[-11]) < 1e-3 * abs(half_shear)      # settled
    assert np.max(np.abs(rec.series["body_vx.disc"])) < 1e-6     # the disc stays put
    assert np.max(np.abs(rec.series["body_vy.disc"])) < 1e-6


def _angular_momentum_given(n: int, steps: int, dt: float, nu: float = 0.01,
                            scheme: str = "central") -> float:
    """A disc (a = 0.1 m, the water's density) spinning at 2 rad/s in a closed 1 m box at rest,
    nu = 0.01 by default (Re = omega a^2 / nu = 2), `central` by default: after ``steps``
    steps, the angular momentum the fluid gained about the disc's centre over what the body
    lost. The fluid's faces are weighted as the viscous step and the projection count them: by
    their open fractions, the slivers (faces whose sample lies in the body,
    viscosity.sliver_links) by theirs."""
    from collections import defaultdict

    from crosscheck.sim.fluid.viscosity import sliver_links

    scene = _case(_disc(0.1, 1000.0, 0.5, 0.5) + "angular_velocity = 2.0\n", f"""
domain = [1.0, 1.0]
resolution = [{n}, {n}]
kinematic_viscosity = {nu}
""", effects="", duration=steps * dt, dt=dt)
    st = FluidState(scene.fluid, np.zeros(2), INTEGRATORS[scheme])
    body = st.coupling.body
    w0 = body.omega
    timers: dict = defaultdict(float)
    for _ in range(steps):
        st.step(dt, timers)
    assert st.coupling.viscous_number < 0.6
    b, dx = st.boundary, st.dx

    def weights(dist, frac, state, axis):
        link = sliver_links(state, dist, frac, axis)
        w = np.where(dist >= 0.0, 1.0 - frac, 0.0)
        return np.where(link >= 0, 1.0 - frac, w)

    wu = weights(b.u_dist, b.u_frac, st.ustate, 0)
    wv = weights(b.v_dist, b.v_frac, st.vstate, 1)
    y_u = (np.arange(n) + 0.5) * dx - 0.5
    x_v = (np.arange(n) + 0.5) * dx - 0.5
    fluid = 1000.0 * dx * dx * (np.sum(wv * x_v[:, None] * st.v)
                                - np.sum(wu * y_u[None, :] * st.u))
    lost = body.inertia * (w0 - body.omega)
    assert lost > 0.15 * body.inertia * w0              # the exchange is not small
    return fluid / lost


def test_a_spinning_disc_gives_the_fluid_the_angular_momentum_it_loses():
    """Angular momentum of fluid and body about the disc's centre, while the vortex the disc
    spins up is far from the box's walls (sqrt(nu t) 0.03 m at 0.1 s, the walls 0.4 m from the
    disc): what the fluid gains is what the body loses, to first order in the cell. The body's
    share of the viscous wall terms is that of the symmetric stress
    (``Coupling.symmetric_stress_moment``); with ``mu du/dn`` alone the exchange made angular
    momentum (the fluid gained 1.19 times what the body lost after 0.05 s, 1.26 after 0.1 s;
    1.36 at 128 cells).
    Measured (2026-11-30), after 0.1 s at 64 / 128 / 256 cells (the step halved with the cell,
    the explicit exchange at half its limit): 0.9727 / 0.9843 / 0.9944; `semi_lagrangian` at 64
    0.9703. One viscous step alone gives 0.9865 / 0.9928 / 0.9975 (the wall terms' lever: the
    fluid sample lies up to a cell from the wall point the body's share is taken at). Bounds:
    4 % at 64 cells, and the gap at 128 under 0.75 of the gap at 64 (measured 0.57)."""
    coarse = _angular_momentum_given(64, 20, 0.005)
    fine = _angular_momentum_given(128, 40, 0.0025)
    assert coarse == pytest.approx(1.0, abs=0.04)
    assert abs(1.0 - fine) < 0.75 * abs(1.0 - coarse)


@pytest.mark.parametrize("scheme", ["central", "maccormack"])
def test_the_convection_at_a_spinning_discs_wall_gives_the_body_the_moment_it_makes(scheme):
    """The same disc at Re = omega a^2 / nu = 200 (nu = 1e-4), 0.4 s, 128 cells: now the
    convection at the cut cells, not the viscous step, is what breaks the balance. It makes
    angular momentum at the wall (the fluxes between the cut faces and the body's samples), and
    ``Coupling.convective_exchange`` gives the body what it made in the band around the wall,
    the moment as well as the momentum. Measured (2026-11-30): the fluid's gain over the body's
    loss 0.9934 with `central`, 0.9932 with `maccormack` (64 cells: 0.9919 / 0.9914); with the
    momentum's balance alone 1.049 and 1.025 (0.998 / 1.012 at 64), the convection alone having
    given the fluid 0.056 and 0.032 of the body's loss. Bound 2 %: the viscous wall terms'
    first-order lever (the test above) is about 1 % at this grid."""
    assert _angular_momentum_given(128, 160, 0.0025, nu=1e-4, scheme=scheme) == \
        pytest.approx(1.0, abs=0.02)


def test_floating_disc(fluid_case):
    """A disc of half the water's density (radius 0.08 m, 5.1 cells) released at the box's
    point, 0.009 m above its half-immersed equilibrium, in the floating-box tank: the circle's
    cut cells, its exact circular-segment buoyancy and the same metrics. Measured at this grid:
    draft error 0.49 % (0.52 and 0.47 % at half and twice the resolution), volume 1e-5, energy
    growth 2.5 % (0.4 % at twice; 2026-12-01).

    Its heave against Ursell's (1949) linear theory of a half-immersed circle in deep water
    (reference.fluid_data.floating_circle_heave: added mass and damping at the body's own
    frequency, omega^2 R / g = 0.80): natural period 0.6352 s, damping ratio 0.164. Measured
    0.621 s (-2.2 %) and 0.174 (+6 %); at half and twice the resolution 0.637 / 0.622 s and
    0.211 / 0.177, so the period has converged 2 % below the theory's, whose deep water (the
    tank's depth is 3.1 R, k h = 2.5), small motion (the release is 0.11 R) and open sides (the
    fit stops before the waves come back from the walls) the run only approaches. The bounds:
    4 % on the period (the high-frequency added mass's 0.711 s is 12 % off, no added mass's
    0.503 s 21 %), 15 % on the damping ratio (the two public copies of the damping differ by
    7 % there)."""
    from crosscheck.reference.fluid_data import floating_circle_heave

    scene, rec = _floating_disc(fluid_case, 500.0)
    assert rec.failure is None
    m = _floats_as_theory_says(scene, rec)
    _, damping = floating_circle_heave(0.08, 9.81)
    assert m["heave_damping"] == pytest.approx(damping, rel=0.15)


@pytest.mark.parametrize("density", [200.0, 300.0])
def test_light_floating_discs_keep_their_water(fluid_case, density):
    """Discs of 0.2 and 0.3 the water's density (a fifth and under a third immersed) heaving
    for 3 s keep the water within 2e-3 all along: measured 4.4e-4 and 8.4e-4 (3.9e-4 and
    1.3e-4 at twice the resolution; 2026-12-01). Before the redistancing took its surface from
    the fluid only (kernels.surface_may_seed), a zero contour that the filling drew inside the
    disc was taken for the surface, drifted down to the disc's bottom wall, and the cut cells
    there read air: they lost 0.43 % and 1.8 %. The half-immersed disc and the box keep 1e-5
    either way."""
    scene, rec = _floating_disc(fluid_case, density)
    assert rec.failure is None
    v = rec.series["volume"]
    assert np.max(np.abs(v / v[0] - 1.0)) < 2e-3


def test_water_entry_keeps_the_water(fluid_case):
    """The half-density disc dropped from 0.07 m above the surface (its centre at 0.40 m) hits
    the water at 1.2 m/s, throws up a splash and floats: the water is kept within 1 % over 3 s,
    measured 0.41 % (0.37 % at twice the resolution, 2026-12-01; most of it while the splash's
    sheets fall back). Before the redistancing took its surface from the fluid only it lost
    5.2 %."""
    scene, rec = _floating_disc(fluid_case, 500.0, height=0.40)
    assert rec.failure is None
    v = rec.series["volume"]
    assert np.max(np.abs(v / v[0] - 1.0)) < 0.01
    assert rec.series["body_y.box"][-1] == pytest.approx(0.25, abs=0.01)   # afloat, half in


def test_a_viscous_floating_disc_heaves_as_theory_says_without_the_convective_exchange(
        fluid_case):
    """The half-density disc of ``test_floating_disc`` in water (kinematic viscosity 1e-6
    m^2/s, no-slip): the viscous coupled step (the incremental projection, the implicit viscous
    step and its exchange with the body through the no-slip wall) with a free surface, which the
    inviscid floating cases never take. The surface always crosses the floating body's window,
    so the convective exchange is off on every step (``window_is_wet``: air faces carry
    extrapolated velocities, not momentum), and the run's metadata says so.

    Measured (2026-12-01, dx = 1/64, 3 s): draft error 0.49 %, volume 2e-5, energy growth
    2.5 %, heave period 0.6159 s (Ursell 0.6352: -3.0 %; inviscid 0.6211, -0.8 % from it),
    damping ratio 0.1808 against 0.1738 inviscid (+4.0 %). A Stokes layer on the wetted half
    under the slip of the infinite-frequency flow (2 V cos theta) dissipates as a damper 2 pi R
    rho sqrt(nu omega / 2), which adds 0.0035 to the damping ratio (over 2 (M + A) omega). More
    viscous, the damping ratio grows about as sqrt(nu): 0.188 / 0.226 / 0.418 at 1e-5 / 1e-4 /
    1e-3, its rise above the inviscid value 1.25-2.2 times that estimate's (2.0 here)
    (the estimate leaves out the waterline, where the no-slip wall drags the surface; at 1e-3
    the draft error is 2.1 %). With the exchange forced on through the surface (a throwaway run
    at 1e-3) the air faces gave the disc -0.032 N s over the run (its weight's impulse is 296 N
    s). Bounds: ``test_floating_disc``'s (draft 1 %, water 1e-3, energy 5 %, period 4 % of
    Ursell's), the period within 2 % of the inviscid run's and the damping ratio above it (by
    at most 10 %)."""
    _, inviscid = _floating_disc(fluid_case, 500.0)
    scene, rec = _floating_disc(fluid_case, 500.0, nu=1e-6)
    assert inviscid.failure is None and rec.failure is None
    coupling = rec.meta["coupling"]
    assert coupling["convective_exchange_steps"] == 0
    assert coupling["convective_exchange_skipped_at_surface"] == rec.meta["dt"]["steps"] > 0
    assert coupling["viscous_exchange_number_max"] > 0.0      # the no-slip wall's exchange ran
    m = _floats_as_theory_says(scene, rec)
    m0 = fluid_metrics(scene, inviscid)
    assert m["heave_period"] == pytest.approx(m0["heave_period"], rel=0.02)
    assert m0["heave_damping"] < m["heave_damping"] < 1.1 * m0["heave_damping"]


def _floats_as_theory_says(scene, rec) -> dict:
    """The floating disc's checks against Archimedes and Ursell (``test_floating_disc``'s
    bounds): draft 1 %, water 1e-3, energy growth 5 %, heave period 4 %. Returns the metrics."""
    from crosscheck.reference.fluid_data import floating_circle_heave

    m = fluid_metrics(scene, rec)
    assert m["draft_error"] < 0.01
    assert m["volume_change"] < 1e-3
    assert m["energy_growth"] < 0.05
    period, _ = floating_circle_heave(0.08, 9.81)
    assert m["heave_period"] == pytest.approx(period, rel=0.04)
    return m


def _floating_disc(fluid_case, density, height=None, nu=0.0):
    """The floating-box case with its box replaced by a disc of radius 0.08 m and ``density``,
    released at the box's point or with its centre at ``height``, in a fluid of kinematic
    viscosity ``nu`` (the case's is inviscid)."""
    scene = fluid_case("floating_box")
    disc = dataclasses.replace(scene.fluid.bodies[0], shape=Circle(0.08),
                               mass=density * math.pi * 0.08 ** 2,
                               inertia=np.array([[0.5 * density * math.pi * 0.08 ** 4]]),
                               com=np.zeros(2))
    if height is not None:
        disc = dataclasses.replace(disc, position=np.array([disc.position[0], height]))
    # a viscous fluid with a body needs the no-slip wall (the case format refuses free slip)
    fluid = dataclasses.replace(scene.fluid, bodies=(disc,), kinematic_viscosity=nu,
                                no_slip=nu > 0.0)
    scene = dataclasses.replace(scene, fluid=fluid)
    key = (density, height, nu)   # the inviscid half-density run serves two tests
    if key not in _FLOATING:
        _FLOATING[key] = FluidRun(scene, "semi_lagrangian").record()
    return scene, _FLOATING[key]


_FLOATING: dict = {}


@pytest.mark.parametrize("crank_nicolson", [False, True])
def test_viscous_exchange_conserves_momentum(crank_nicolson):
    """One viscous step with the body as a no-slip wall moving at ``V*``: the
    momentum the fluid gains, each face weighted by its open fraction (the mass the projection
    gives it; a sliver by its open part), is exactly what ``Coupling.viscous_exchange`` takes
    from the body (the links between unknowns cancel in pairs; the box's walls are far and the
    fluid there at rest), and the moment it takes has the sign of the body's spin. Counted with
    whole-cell weights, as the step once counted it, the fluid's gain differs from the body's
    loss by 6 and 11 % (x, y) here (and a disc held in a Stokes stream felt 4.5 % more force
    than the fluid's momentum balance around it: test_faxen_frame.py).

    Backward Euler, and Crank-Nicolson (the central scheme's step) from a start field with a
    shear flow in it: its explicit half's wall terms are the old field's, so the exchange takes
    the mean of the old and the new field (``FluidState.step``); given the new field alone it
    misses by the difference of the two halves' wall terms."""
    from crosscheck.sim.fluid.boundary import impose
    from crosscheck.sim.fluid.viscosity import MOVING_THETA_MIN, diffuse_implicit, sliver_links

    nu, dt = 1e-3, 0.01
    scene = _case("""
[[bodies]]
name = "box"
shape = { box = { size = [0.2, 0.1] } }
density = 800.0
position = [0.5, 0.5]
orientation = 0.3
velocity = [0.2, -0.1]
angular_velocity = 1.5
""", f"""
domain = [1.0, 1.0]
resolution = [64, 64]
kinematic_viscosity = {nu}
""", effects="", duration=dt, dt=dt)
    st = FluidState(scene.fluid, np.zeros(2), INTEGRATORS["semi_lagrangian"])
    c = st.coupling
    c.predict(dt)
    b = st.boundary
    un, vn = st.u.copy(), st.v.copy()
    st.classify()
    impose(un, vn, st.ustate, st.vstate, b)
    u0, v0 = un.copy(), vn.copy()
    k = nu * dt / st.dx ** 2
    uo = vo = None
    if crank_nicolson:
        # the start of the step: a vortex around the body, at rest by the box's walls
        # (exp(-17) there), its samples inside the body set to the body's velocity
        def vortex(x, y):
            bump = np.exp(-((x - 0.5) ** 2 + (y - 0.5) ** 2) / 0.12 ** 2)
            return -0.3 * (y - 0.4) / 0.12 * bump, 0.3 * (x - 0.6) / 0.12 * bump

        i, j = np.arange(st.nx + 1), np.arange(st.ny + 1)
        uo = vortex(i[:, None] * st.dx, (j[None, :-1] + 0.5) * st.dx)[0]
        vo = vortex((i[:-1, None] + 0.5) * st.dx, j[None, :] * st.dx)[1]
        impose(uo, vo, st.ustate, st.vstate, b)
    diffuse_implicit(un, st.ustate, b.u_dist, b.u_solid, k, 0, st.gu, uo, frac=b.u_frac,
                     theta_min=MOVING_THETA_MIN)
    diffuse_implicit(vn, st.vstate, b.v_dist, b.v_solid, k, 1, st.gv, vo, frac=b.v_frac,
                     theta_min=MOVING_THETA_MIN)

    def weights(dist, frac, state, axis):
        link = sliver_links(state, dist, frac, axis)
        w = np.where(dist >= 0.0, np.maximum(1.0 - frac, 0.05), 0.0)
        return np.where(link >= 0, np.clip(1.0 - frac, 1e-6, 0.5), w), link

    wu, lu = weights(b.u_dist, b.u_frac, st.ustate, 0)
    wv, lv = weights(b.v_dist, b.v_frac, st.vstate, 1)
    assert np.count_nonzero(lu >= 0) > 0 and np.count_nonzero(lv >= 0) > 0
    da = 1000.0 * st.dx ** 2
    gained = np.array([da * np.sum(wu * (un - u0)), da * np.sum(wv * (vn - v0))])
    whole = np.array([da * np.sum((un - u0)[b.u_dist >= 0]),
                      da * np.sum((vn - v0)[b.v_dist >= 0])])
    v_before, w_before = c.body.v.copy(), c.body.omega
    if crank_nicolson:
        # the new field alone: the explicit half's wall terms are missed
        new_only = copy.deepcopy(c)
        new_only.viscous_exchange(un, vn, (lu, lv), nu, dt, MOVING_THETA_MIN, st.phi)
        assert not np.allclose(new_only.body.mass * (v_before - new_only.body.v), gained,
                               rtol=0.02)
        un, vn = 0.5 * (un + uo), 0.5 * (vn + vo)
    c.viscous_exchange(un, vn, (lu, lv), nu, dt, MOVING_THETA_MIN, st.phi)
    lost = c.body.mass * (v_before - c.body.v)
    assert np.all(np.abs(gained) > 1e-6)
    assert lost == pytest.approx(gained, rel=1e-6)
    assert not np.allclose(whole, lost, rtol=0.02)
    if not crank_nicolson:
        assert c.body.omega < w_before               # the wall's drag slows the spin


def test_body_reaching_a_wall_stops_the_run_with_the_reason():
    """No contact between a body and the walls in the fluid: a box thrown above the water at
    the side wall (0.4 m away at 3 m/s) ends the run when it comes within 1.5 cells of it, with
    that reason (failure is data), and the samples before are kept."""
    scene = _case(BOX % "0.42" + "velocity = [-3.0, 0.0]\n", TANK, duration=0.5)
    rec = FluidRun(scene, "semi_lagrangian").record()
    assert rec.failure is not None
    assert "came within 1.5 cells of a wall" in rec.failure["reason"]
    assert 0.12 < rec.failure["time"] < 0.135     # (0.4 - 1.5 / 64) m at 3 m/s: 0.126 s
    assert rec.series["body_x.box"][-1] < 0.5


@pytest.mark.parametrize("obstacle", [
    "{ circle = { center = [1.0, 0.29], radius = 0.08 } }",
    "{ box = { center = [1.0, 0.27], size = [0.2, 0.1], angle = 0.5 } }",
    "{ polygon = { vertices = [[0.9, 0.3], [1.1, 0.3], [1.0, 0.15]] } }",
])
def test_surface_piercing_obstacles_stay_at_rest(obstacle):
    """A solid whose wall slopes where the free surface meets it, in a tank at rest, stays at
    rest: the level set is extrapolated into solid cells linearly (kernels.fill_solid), not by
    the neighbours' mean, which put a fake surface half a cell off along sloping walls (before:
    0.15 to 0.22 m/s of spurious current and 0.3 to 2 % of the water gained in 3 s). A floating
    body's waterline is such a wall."""
    scene = _case("", f"""
domain = [2.0, 0.5]
resolution = [128, 32]
walls = {{ top = "open" }}
initial = [{{ layer = {{ depth = 0.25 }} }}]
obstacles = [{obstacle}]
""", duration=1.0, dt=0.005)
    rec = FluidRun(scene, "semi_lagrangian").record()
    assert rec.failure is None
    assert np.max(rec.series["max_speed"]) < 1e-6
    v = rec.series["volume"]
    assert abs(v[-1] - v[0]) / v[0] < 1e-9


# -- sedimentation and the energy audit (issue 14, point 3) --------------------------------------
def test_viscous_dissipation_of_a_shear_flow_is_exact():
    """2 mu integral of D:D of u = s y (D12 = s / 2 everywhere) over a box L x L: mu s^2 L^2,
    exact with the ghosts of the linear profile below (a wall at rest) and above (a lid)."""
    from crosscheck.sim.fluid.viscosity import viscous_dissipation

    n, L, s, mu = 16, 0.5, 3.0, 0.7
    dx = L / n
    y = (np.arange(n) + 0.5) * dx
    u = np.tile(s * y, (n + 1, 1))
    v = np.zeros((n, n + 1))
    ghosts = {"bottom": (-1.0, 0.0), "top": (-1.0, 2 * s * L),
              "left": (1.0, 0.0), "right": (1.0, 0.0)}
    got = viscous_dissipation(u, v, np.ones((n, n)), dx, mu, ghosts)
    assert got == pytest.approx(mu * s * s * L * L, rel=1e-12)


def _sedimentation(runs, dt=None):
    scene, rec = runs("sedimentation_channel", "semi_lagrangian")
    if dt is None:
        return scene, rec
    scene = dataclasses.replace(scene, run=dataclasses.replace(scene.run, dt=dt))
    return scene, FluidRun(scene, "semi_lagrangian").record()


def test_disc_settling_in_a_channel_against_faxen(runs, tmp_path):
    """cases/fluid/sedimentation_channel.toml: a disc (a = 0.1 m, five times the fluid's density)
    on the centreline of a closed channel 0.8 m wide (k = a / h = 0.25), nu = 0.5 m^2/s, Re 0.047.
    Faxen's Stokes drag gives U = 0.11225 m/s. Measured (mean speed over whole cells of travel
    after 0.2 s), relative to it, at dx = a / 4 (the case) and a / 8:

    ===========  =======================  ============================  ==================
    dt (s)       dx = a/4 (a/8)            before the weighted step      whole pressure
    ===========  =======================  ============================  ==================
    2.5e-4       +1.64 % (+0.32 %)        +2.19 % (-0.49 %)              +5.76 % (+3.96 %)
    1.25e-4      +1.64 % (+0.32 %) case   +2.61 % (-0.23 %)              +4.23 %
    6.25e-5      +1.64 %                  +2.97 % (+0.11 %)              +3.54 %
    ===========  =======================  ============================  ==================

    The coupled viscous step weighs each face's momentum by its open fraction and solves the
    slivers (cut faces whose sample is inside the body) as unknowns tied to the wall
    (viscosity.diffuse_implicit). Before, the slivers took the body's velocity and then the
    pressure's gradient, a slip proportional to the step, and the speed rose by 0.3-0.4 % with
    each halving of the step; now the three steps agree to 1e-5 and the grid's error falls
    from a / 4 to a / 8 by a factor 5 (second order). Projecting the whole pressure each step,
    as the step once did, left a slip at the wall and a first-order error above it. The test
    runs the case and the case with the step doubled: the two agree within 0.1 % (measured
    0.001 %)."""
    scene, rec = _sedimentation(runs)
    assert rec.failure is None
    m = fluid_metrics(scene, rec)
    assert m["terminal_velocity_reference"] == pytest.approx(0.11225, rel=1e-4)
    assert m["terminal_reynolds"] < 0.05 and m["centreline_offset"] < 1e-6
    assert m["terminal_velocity_error"] <= scene.tolerances["terminal_velocity_error"].limit(
        "inhouse", "semi_lagrangian") == 0.025
    assert m["terminal_velocity"] > m["terminal_velocity_reference"]  # the measured bias's sign
    scene2, rec2 = _sedimentation(runs, dt=0.00025)
    m2 = fluid_metrics(scene2, rec2)
    u_ref = m["terminal_velocity_reference"]
    assert abs(m["terminal_velocity"] - m2["terminal_velocity"]) / u_ref < 1e-3


def test_energy_lost_against_the_viscous_dissipation(runs):
    """The energy audit of fluid plus body (compare/fluid_metrics.energy_audit): the energy lost
    over a window against the integral of 2 mu integral of D:D dA measured from the fields.

    * Stokes flow, the sedimentation case (Re 0.047, t >= 0.2 s): the loss is viscous; ratio
      lost / viscous 1.117 at dx = a / 4, 1.059 at dx = a / 8: the excess halves with dx (the
      D:D quadrature is first order at the moving wall, where the rigid velocity inside the
      body is taken a fraction of a cell away). Before the coupled viscous step weighed each
      face's momentum by its open fraction: 1.081 and 1.043; bound 1.15.
    * A disc (density 2000, radius 0.05 m) sinking 0.3 s in a closed 1 m box: at nu = 1e-3 (Re
      about 61) the ratio is 4.18 at 48^2 and 2.36 at 96^2 (dt 2.5e-3; 2026-12-01): the
      semi-Lagrangian advection's own dissipation dominates, 76 % and 58 % of the loss; at nu =
      0.01 (Re 3.5) 1.30 and 1.19 (dt 1e-3, 5e-4). (Quoted before as 3.38 / 1.83 and 1.36 /
      1.13, from an earlier coupled step: the code just before the trace took the field's own
      pose read 4.23 / 2.39 at nu = 1e-3.) With the viscous exchange number beyond its stated limit
      (1.8 at nu = 0.01, dt = 5e-3) the ratio fell to 0.91: viscosity then counts more than was
      lost, so the audit only holds in the stated regime.

    What is tested is what holds: the total energy never rises above its value at the window's
    start by more than 1 % of what was lost (the potential energy of cut cells is a first-order
    quadrature), and never less is lost than the viscous integral (5 % margin for its
    quadrature); the numerical share falls with the grid."""
    scene, rec = runs("sedimentation_channel", "semi_lagrangian")
    m = fluid_metrics(scene, rec)
    assert 1.0 <= m["viscous_dissipation_ratio"] < 1.15
    assert m["energy_rise_max"] < 1e-3
    ratios = []
    for n in (48, 96):
        sc = _case("""
[[bodies]]
name = "disc"
shape = { circle = { radius = 0.05 } }
density = 2000.0
position = [0.5, 0.7]
""", f"""
domain = [1.0, 1.0]
resolution = [{n}, {n}]
kinematic_viscosity = 1e-3
""", duration=0.3, dt=0.0025)
        r = FluidRun(sc, "semi_lagrangian").record()
        assert r.failure is None
        audit = fluid_metrics(sc, r)
        assert audit["energy_lost"] > 0 and audit["energy_rise_max"] < 0.01
        assert audit["viscous_dissipation_ratio"] > 0.95
        ratios.append(audit["viscous_dissipation_ratio"])
    assert ratios[0] > 2.5 and ratios[1] < 0.7 * ratios[0]  # measured 4.18, 2.36
