"""A disc settling in a channel four diameters wide against Wachs's (2009) published terminal
state (issue 14, point 3; cases/fluid/sedimentation_wachs.toml, reference/data/
wachs2009_disc_channel_sedimentation.csv): the inertia-dominated counterpart (Re ~ 260) of the
Stokes-regime check against Faxen in test_coupling.py.

The terminal speed is set by the reduced weight against the drag, which here is mostly the
pressure drag of the confined wake: a coupling that lost the buoyancy (U x 1.7), the pressure
force on the body or its viscous exchange would move it far outside the tolerance."""

import dataclasses
import math
from pathlib import Path

import pytest

from crosscheck.compare.fluid_metrics import fluid_metrics, published_sedimentation
from crosscheck.errors import CaseError
from crosscheck.scene.loader import load_case_text


def test_the_disc_settles_at_the_published_terminal_speed(runs):
    """Released 1 d off the axis as the benchmark releases it, at the case's grid (d / dx = 12,
    dt = 0.01333 = 0.16 dx; measured 2026-12-01): U = 2.0514, Re 253.6 against 259.5 (-2.26 %),
    C_D 1.866 against 1.785; released 1e-9 / 1e-7 d farther off, -2.30 / -2.28 %. The disc
    reaches the axis, sheds and swings about it (0.32 d at most in the window), the state the
    published number belongs to. The finer grids come closer: -1.89 / -1.85 / -1.35 / -0.83 /
    -0.14 % at 12 / 16 / 24 / 32 / 48 cells and the step 0.005 (sedimentation_offaxis_steps12.md
    ... 48.md), not shown converged: the case's 2.5 % is what this grid reaches. (Released on
    the axis, the case until 2026-12-01, the disc kept the symmetric wake, which drags about 12 %
    less: +2.12 % at this grid, and more on finer ones; benchmarks/results/wachs_frame.md.)"""
    scene, rec = runs("sedimentation_wachs", "maccormack")
    assert rec.failure is None
    m = fluid_metrics(scene, rec)
    assert m["terminal_velocity_reference"] == pytest.approx(259.5 * 0.008088, rel=1e-12)
    assert m["terminal_reynolds_reference"] == 259.5
    limit = scene.tolerances["terminal_velocity_error"].limit("inhouse", "maccormack")
    assert limit == 0.025
    assert m["terminal_velocity_error"] <= limit
    # the drag coefficient is the same measurement (C_D ~ 1 / U^2): about twice the speed's
    # error, up to the published pair's own inconsistency (Re and C_D agree through the force
    # balance to 0.12 %, the rounding of Re to four figures: 2.4e-3 in C_D at most)
    assert m["drag_coefficient_error"] == pytest.approx(
        abs((1.0 + m["terminal_velocity_error"]) ** -2 - 1.0), abs=2.5e-3)
    # terminal: the window is ~25 d of travel, ending clear of the bottom
    assert m["window_travel"] > 20.0 and m["bottom_clearance"] > 2.0
    # the benchmark's state: the disc has left its release line (1 d off the axis) and swings
    # about the axis (measured 0.32 d at most, 0.18 d on average over the window)
    assert 0.05 < m["centreline_offset_mean"] < m["centreline_offset"] < 0.6
    # beside it, Wachs's own path (fig. 5a) over the same stretch of the fall: 0.220 / 0.073 d.
    # Reported, not judged: this grid swings wider (the grids of 16-48 cells read 0.22-0.30 /
    # 0.09-0.11 d, benchmarks/results/sedimentation_offaxis_steps16.md ... 48.md)
    assert m["centreline_offset_reference"] == pytest.approx(0.220, abs=2e-3)
    assert m["centreline_offset_mean_reference"] == pytest.approx(0.073, abs=2e-3)


def _scene(fluid_case, **fluid):
    scene = fluid_case("sedimentation_wachs", duration=0.02)
    spec = dataclasses.replace(scene.fluid, **fluid)
    return dataclasses.replace(scene, fluid=spec)


@pytest.mark.parametrize("change", [
    {"domain": (5.0, 45.0)},            # w / d = 5: not the benchmark's channel
    {"kinematic_viscosity": 0.01},      # another Galileo number
    {"density": 1200.0},                # rho_s / rho = 1.25: not published
])
def test_a_scene_that_is_not_the_benchmark_is_not_measured(fluid_case, change):
    """The published number belongs to one set of groups (w / d, r, Ga). A scene built past the
    loader (as here) that is another gets an infinite error (a failure), never a comparison
    with the wrong benchmark; it is refused before the record is read."""
    scene = _scene(fluid_case, **change)
    out = published_sedimentation(scene, record=None, params={})
    assert out == {"terminal_velocity_error": math.inf}


CASE = Path(__file__).resolve().parents[2] / "cases" / "fluid" / "sedimentation_wachs.toml"


@pytest.mark.parametrize(("edits", "expected"), [
    ({"domain = [4.0,": "domain = [5.0,", "resolution = [48,": "resolution = [60,"},
     "4 diameters wide"),
    ({"kinematic_viscosity = 0.008088": "kinematic_viscosity = 0.01"}, "Galileo number"),
    ({"density = 1500.0": "density = 1250.0"}, "density ratio"),
    ({'table = "wachs_2009"': 'table = "wachs_2010"'}, "a published table crosscheck ships"),
])
def test_the_loader_refuses_a_case_that_is_not_the_benchmark(edits, expected):
    """A case naming the benchmark must be it: the loader says which group is off, in the
    file and field ``reference.table``, before any cell runs."""
    text = CASE.read_text()
    for old, new in edits.items():
        assert old in text
        text = text.replace(old, new)
    with pytest.raises(CaseError) as exc:
        load_case_text(text, CASE.name, base_dir=CASE.parent)
    assert exc.value.field == "reference.table" and expected in str(exc.value)
    assert CASE.name in str(exc.value)
