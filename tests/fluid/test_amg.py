"""The multigrid pressure solve (sim/fluid/amg.py): the same answer as the direct solve and as
MIC(0)-PCG, iterations that do not grow with the grid, a hierarchy built once for a matrix that
does not change, and the case field that chooses it."""

from __future__ import annotations

import dataclasses
import sys
from pathlib import Path

import numpy as np
import pytest
import scipy.sparse.linalg as spla

from crosscheck.errors import CaseError
from crosscheck.scene.loader import load_case, load_case_text
from crosscheck.sim.fluid import INTEGRATORS, run_fluid
from crosscheck.sim.fluid import pressure as P
from crosscheck.sim.fluid.amg import StaticAMG, assemble
from crosscheck.sim.fluid.solver import FluidState

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "benchmarks"))
import bench_dfg  # noqa: E402  (the DFG scene at any grid, shared with the benchmark)


def _dfg_system(cells: int, seed: int = 0):
    """The pressure system of the DFG channel (cut-cell cylinder, inflow, open outflow) at
    ``cells`` across the cylinder, for a random velocity field."""
    scene = bench_dfg.scene_for("2d2", cells, 0.1)
    st = FluidState(scene.fluid, np.zeros(3), INTEGRATORS["central"])
    bnd = st.static_boundary
    rng = np.random.default_rng(seed)
    u = rng.standard_normal(st.u.shape)
    v = rng.standard_normal(st.v.shape)
    return P.build_system(st.phi, bnd.u_frac, bnd.v_frac, u, v, bnd.u_solid, bnd.v_solid)


def test_amg_matches_the_direct_solve_on_the_cut_cell_channel():
    index, diag, xm, xp, ym, yp, wxm, wxp, wym, wyp, b, ndir = _dfg_system(10)
    assert ndir > 0                                  # the open outflow fixes the constant
    ops = (diag, xm, xp, ym, yp, wxm, wxp, wym, wyp)
    ref = spla.spsolve(assemble(*ops).tocsc(), b)
    x = np.zeros_like(b)
    its = StaticAMG().solve(*ops, b, x, 1e-12 * np.max(np.abs(b)), 200)
    assert 0 < its <= 20
    assert np.max(np.abs(x - ref)) < 1e-9 * np.max(np.abs(ref))


def test_amg_iterations_do_not_grow_with_the_grid_and_mic0s_do():
    """The reason for the module: from zero to the runs' tolerance, MIC(0)-PCG needs more
    iterations the finer the grid (about as 1/h: 71 and 134 for this random field at 10 and 20
    cells across the cylinder), multigrid about the same number (7 and 8). Both stop on the same
    criterion, so the solutions agree to it (1.5e-7 of the largest value measured)."""
    counts = {}
    for cells in (10, 20):
        index, diag, xm, xp, ym, yp, wxm, wxp, wym, wyp, b, _ = _dfg_system(cells)
        ops = (diag, xm, xp, ym, yp, wxm, wxp, wym, wyp)
        tol = 1e-6 * np.max(np.abs(b))
        x_mic = np.zeros_like(b)
        x_amg = np.zeros_like(b)
        counts[cells] = (P.pcg(*ops, b, x_mic, tol, 5000),
                         StaticAMG().solve(*ops, b, x_amg, tol, 200))
        assert min(counts[cells]) > 0
        a = assemble(*ops)
        # each meets the criterion, and the two solutions differ by what it allows
        for x in (x_mic, x_amg):
            assert np.max(np.abs(b - a @ x)) <= tol
        assert np.max(np.abs(x_mic - x_amg)) < 1e-4 * np.max(np.abs(x_mic))
    (mic10, amg10), (mic20, amg20) = counts[10], counts[20]
    assert mic20 > 1.6 * mic10, counts
    assert amg20 <= amg10 + 2 and amg20 <= 12, counts


def test_the_hierarchy_is_built_once_and_again_when_the_matrix_changes():
    index, diag, xm, xp, ym, yp, wxm, wxp, wym, wyp, b, _ = _dfg_system(10)
    ops = (diag, xm, xp, ym, yp, wxm, wxp, wym, wyp)
    amg = StaticAMG()
    for _ in range(3):
        amg.solve(*ops, b, np.zeros_like(b), 1e-8 * np.max(np.abs(b)), 200)
    assert amg.setups == 1
    changed = diag.copy()
    changed[5] += 0.5                                 # another matrix (a face's weight moved)
    x = np.zeros_like(b)
    amg.solve(changed, *ops[1:], b, x, 1e-10 * np.max(np.abs(b)), 200)
    assert amg.setups == 2
    # and it solved that matrix, not the cached one
    assert np.max(np.abs(b - assemble(changed, *ops[1:]) @ x)) <= 1e-10 * np.max(np.abs(b))


def test_a_dfg_run_with_multigrid_matches_mic0_and_builds_one_hierarchy():
    """The 2D-2 channel at 10 cells across for 0.3 s, the pressure by each solver: the forces on
    the cylinder agree to what the solver tolerance (1e-6 of the largest divergence) lets
    through, and the multigrid run built its hierarchy once (the matrix never changed)."""
    scene = bench_dfg.scene_for("2d2", 10, 0.3)
    runs = {}
    for solver in ("mic0", "amg"):
        s = dataclasses.replace(scene, fluid=dataclasses.replace(scene.fluid,
                                                                 pressure_solver=solver))
        runs[solver] = run_fluid(s, "central")
        assert runs[solver].failure is None
    meta = runs["amg"].meta["pressure_iterations"]
    assert meta["solver"] == "amg" and meta["amg_setups"] == 1
    assert meta["mean"] < 0.2 * runs["mic0"].meta["pressure_iterations"]["mean"]
    assert runs["mic0"].meta["pressure_iterations"]["solver"] == "mic0"
    for key in ("force_x.cylinder", "force_y.cylinder"):
        a = np.asarray(runs["amg"].series[key])
        m = np.asarray(runs["mic0"].series[key])
        drag_scale = np.max(np.abs(runs["mic0"].series["force_x.cylinder"]))
        # measured 8e-7 of the drag scale: the tolerance lets through about 1e-6
        assert np.max(np.abs(a - m)) < 1e-5 * drag_scale, key


def test_auto_uses_multigrid_only_where_the_matrix_is_static_and_large():
    """One step of the DFG channel with the default solver: MIC(0) at 9 thousand unknowns
    (below the bound, no hierarchy built), multigrid at 36 thousand; none for a free surface."""
    timers = dict.fromkeys(("advection", "redistancing", "particles", "forces", "projection",
                            "extension"), 0.0)
    built = {}
    for cells in (10, 20):
        scene = bench_dfg.scene_for("2d2", cells, 0.02)
        assert scene.fluid.pressure_solver == "auto"
        st = FluidState(scene.fluid, np.zeros(3), INTEGRATORS["central"])
        st.step(1e-4, timers)
        built[cells] = st.amg.setups
    assert built == {10: 0, 20: 1}, built
    tank = load_case(ROOT / "cases" / "fluid" / "tank_at_rest.toml")   # a free surface
    assert FluidState(tank.fluid, np.array([0.0, -9.81]), INTEGRATORS["semi_lagrangian"]).amg \
        is None


def _submerged(n: int, solver: str, duration: float = 0.25):
    """``bench_coupling.py --scene submerged``: a disc settling in a closed tank whose lid
    slides, viscous, at ``n``^2 with the pressure solver ``solver``."""
    import bench_coupling
    scene = bench_coupling.scene("coupled", n, 1e-4, "submerged")
    return dataclasses.replace(scene, run=dataclasses.replace(scene.run, duration=duration),
                               fluid=dataclasses.replace(scene.fluid, pressure_solver=solver))


def test_the_coupled_multigrid_matches_mic0_in_a_few_iterations_at_any_grid():
    """``amg.CoupledAMG`` (the static domain's V-cycle and an exact solve of the body's window,
    multiplicatively): the same body motion as MIC(0)-PCG to what the solver tolerance (1e-6
    of the largest divergence) lets through (measured: the body's speed 6e-10 and 6e-9 of its
    largest apart at 64^2 and 128^2), in a number of iterations that does not grow with the
    grid (3.3, 3.8 and, over 0.3 s at 256^2, 4.0, no fallback to MIC(0); MIC(0) 45, 72 and
    118). Forced with ``pressure_solver = "amg"`` (``"auto"`` uses it from 20 thousand
    unknowns)."""
    its = {}
    for n in (64, 128):
        runs = {s: run_fluid(_submerged(n, s), "semi_lagrangian") for s in ("mic0", "amg")}
        for rec in runs.values():
            assert rec.failure is None
        meta = runs["amg"].meta["pressure_iterations"]
        assert meta["solver"] == "amg" and meta["amg_setups"] == 1 and meta["amg_fallbacks"] == 0
        its[n] = (runs["mic0"].meta["pressure_iterations"]["mean"], meta["mean"])
        for key in ("body_vy.disc", "body_vx.disc", "body_y.disc"):
            a = np.asarray(runs["amg"].series[key])
            m = np.asarray(runs["mic0"].series[key])
            scale = np.max(np.abs(runs["mic0"].series["body_vy.disc"])) if "v" in key else 1.0
            assert np.max(np.abs(a - m)) < 1e-5 * scale, (n, key)
    (mic64, amg64), (mic128, amg128) = its[64], its[128]
    assert amg64 <= 6 and amg128 <= 6 and mic128 > 1.3 * mic64, its


def test_a_stalled_coupled_multigrid_hands_the_solve_to_mic0(monkeypatch):
    """The safety net of ``amg.CoupledAMG``: its V-cycle belongs to a nearby matrix, so CG may
    stall; past ``SCHWARZ_MAX_ITER`` iterations (here 1, forcing it) MIC(0)-PCG finishes from
    where it stands, counted in the run's meta, and the run is the same as MIC(0)'s alone."""
    from crosscheck.sim.fluid.amg import CoupledAMG

    monkeypatch.setattr(CoupledAMG, "SCHWARZ_MAX_ITER", 1)
    runs = {s: run_fluid(_submerged(64, s, 0.05), "semi_lagrangian") for s in ("mic0", "amg")}
    meta = runs["amg"].meta["pressure_iterations"]
    assert meta["solver"] == "amg" and meta["unconverged"] == 0
    assert meta["amg_fallbacks"] > 0
    a = np.asarray(runs["amg"].series["body_vy.disc"])
    m = np.asarray(runs["mic0"].series["body_vy.disc"])
    assert np.max(np.abs(a - m)) < 1e-5 * np.max(np.abs(m))


def test_auto_uses_the_coupled_multigrid_only_without_a_free_surface():
    """A coupled body: multigrid by default in a closed domain from 20 thousand unknowns (the
    submerged disc at 160^2, 25.6 thousand: one step), MIC(0) below that (128^2) and with a
    free surface (the floating box)."""
    from crosscheck.sim.fluid.amg import CoupledAMG

    timers = dict.fromkeys(("advection", "redistancing", "particles", "forces", "projection",
                            "extension", "coupling"), 0.0)
    built = {}
    for n in (128, 160):
        scene = _submerged(n, "auto", 0.005)
        st = FluidState(scene.fluid, np.array([0.0, -9.81]), INTEGRATORS["semi_lagrangian"])
        assert isinstance(st.amg, CoupledAMG)
        st.step(0.005, timers)
        built[n] = st.amg.setups
    assert built == {128: 0, 160: 1}, built
    box = load_case(ROOT / "cases" / "fluid" / "floating_box.toml")
    assert FluidState(box.fluid, np.array([0.0, -9.81]), INTEGRATORS["semi_lagrangian"]).amg \
        is None


def test_multigrid_is_refused_for_a_coupled_body_with_a_free_surface():
    """The coupled solve with a free surface (the body's velocity an unknown, the matrix
    changing with the surface) has no multigrid: asking for it is an error that names the
    field, not a silent MIC(0)."""
    text = (ROOT / "cases" / "fluid" / "floating_box.toml").read_text()
    text = text.replace("[fluid]\n", '[fluid]\npressure_solver = "amg"\n')
    with pytest.raises(CaseError) as err:
        load_case_text(text, "floating_box.toml")
    assert err.value.field == "fluid.pressure_solver", str(err.value)
    assert "no multigrid" in str(err.value)
