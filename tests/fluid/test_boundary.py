"""The solid boundary the fluid step takes (sim/fluid/boundary.py): built from cells, checked, and
honoured when it moves: its faces keep the solid's velocity and the fluid around it is divergence
free to the pressure solver's tolerance."""

from __future__ import annotations

import numpy as np
import pytest

from crosscheck.scene.loader import load_case_text
from crosscheck.sim.fluid.boundary import SolidBoundary, open_sides
from crosscheck.sim.fluid.pressure import SOLID
from crosscheck.sim.fluid.solver import INTEGRATORS, PHASES, FluidState

# enclosed (no `initial`: full of fluid, no free surface), inviscid, no gravity
TANK = """
[case]
name = "t"
dimension = 2
[run]
duration = 0.1
dt = 0.01
[fluid]
domain = [1.0, 1.0]
resolution = [24, 24]
pressure_tolerance = 1e-8
"""


def _state(integrator="semi_lagrangian"):
    spec = load_case_text(TANK, "t.toml").fluid
    return FluidState(spec, np.zeros(2), INTEGRATORS[integrator])


def _divergence(st):
    return st.u[1:] - st.u[:-1] + st.v[:, 1:] - st.v[:, :-1]


def test_from_cells_gives_staircase_faces_and_refuses_what_the_solver_cannot_do():
    cells = np.zeros((4, 3), bool)
    cells[1, 1] = True
    b = SolidBoundary.from_cells(cells, np.array([False, True, False, True]))
    assert b.has_cells
    assert b.u_frac[:, 1].tolist() == [1, 1, 1, 0, 0]     # closed left, the block, open right
    assert b.v_frac[1].tolist() == [1, 1, 1, 0]           # closed bottom, the block, open top
    assert b.u_frac.sum() == 3 + 2 and b.v_frac.sum() == 4 + 2
    assert not b.u_solid.any() and not b.v_solid.any()
    with pytest.raises(ValueError, match="cut"):
        SolidBoundary(cells, 0.5 * b.u_frac, b.v_frac, b.u_solid, b.v_solid)
    holed = b.u_frac.copy()
    holed[2, 1] = 0.0
    with pytest.raises(ValueError, match="next to a solid cell"):
        SolidBoundary(cells, holed, b.v_frac, b.u_solid, b.v_solid)
    with pytest.raises(ValueError, match="shape"):
        SolidBoundary(cells, b.u_frac, b.v_frac, b.u_solid[:-1], b.v_solid)


@pytest.mark.parametrize("integrator", ["semi_lagrangian", "maccormack"])
def test_a_moving_block_pushes_the_fluid_and_keeps_its_velocity(integrator):
    st = _state(integrator)
    n = st.nx
    cells = np.zeros((n, n), bool)
    cells[9:14, 8:12] = True
    U, V = 0.3, -0.2
    # the block's faces move with it, the closed sides of the tank stay at rest
    u_solid = np.zeros((n + 1, n))
    v_solid = np.zeros((n, n + 1))
    u_solid[1:-1][cells[1:] | cells[:-1]] = U
    v_solid[:, 1:-1][cells[:, 1:] | cells[:, :-1]] = V
    bnd = SolidBoundary.from_cells(cells, open_sides(st.spec), u_solid, v_solid)
    block_u = u_solid != 0.0
    block_v = v_solid != 0.0
    fluid = ~cells
    timers = {p: 0.0 for p in PHASES}
    tol = st.spec.pressure_tolerance
    for _ in range(3):
        st.step(0.01, timers, solid=bnd)
        assert st.boundary is bnd
        assert np.all(st.ustate[block_u] == SOLID) and np.all(st.vstate[block_v] == SOLID)
        # the Neumann condition: the normal velocity on the block's faces is the block's
        assert np.all(st.u[block_u] == U) and np.all(st.v[block_v] == V)
        # the fluid makes way: divergence free to the solver's tolerance (the right-hand side
        # is at most |U| + |V| per cell; the CG stops at tol times its largest entry)
        assert np.max(np.abs(_divergence(st)[fluid])) <= 2 * tol * (abs(U) + abs(V))
        # and it really moves (ignoring the solid's velocity would leave it at rest)
        assert np.max(np.abs(st.u[1:-1][fluid[1:] & fluid[:-1]])) > 0.1 * U
    assert st.fluid_cells() == np.count_nonzero(fluid)       # measurements read the boundary
    assert st.measure()["volume"] == pytest.approx(np.count_nonzero(fluid) * st.dx**2)


def test_a_tank_moving_with_its_fluid_keeps_it_uniform():
    """Galilean: walls whose normal velocity is the fluid's own uniform velocity change nothing,
    whereas walls at rest would stop the flow through them."""
    st = _state()
    U, V = 0.4, -0.25
    n = st.nx
    u_solid = np.zeros((n + 1, n))
    v_solid = np.zeros((n, n + 1))
    u_solid[[0, -1]] = U
    v_solid[:, [0, -1]] = V
    bnd = SolidBoundary.from_cells(np.zeros((n, n), bool), open_sides(st.spec), u_solid, v_solid)
    st.u[:] = U
    st.v[:] = V
    timers = {p: 0.0 for p in PHASES}
    for _ in range(5):
        st.step(0.01, timers, solid=bnd)
    tol = st.spec.pressure_tolerance
    assert np.max(np.abs(st.u - U)) <= tol * abs(U)
    assert np.max(np.abs(st.v - V)) <= tol * abs(V)

    # the same start with the tank's walls at rest (the static boundary) is not uniform
    st = _state()
    st.u[:] = U
    st.v[:] = V
    st.step(0.01, timers)
    assert np.max(np.abs(st.u - U)) > 0.1 * U
