"""The DFG benchmark's restart (benchmarks/bench_dfg.py ``--start-from``): a run continued from
a saved state is the run it continues, and the period maxima of a restarted run approaching the
periodic state are read to their limit. The finer grids of the DFG 2D-2 study (60 and 80 cells
across the cylinder) rest on both; the study itself checks the restart against runs from rest at
20 and 40 cells (benchmarks/results/dfg.md)."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from crosscheck.compare.fluid_metrics import force_coefficients
from crosscheck.sim.fluid.run import FluidRun

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "benchmarks"))
import bench_dfg  # noqa: E402  (the DFG scene and its restart, shared with the benchmark)


def _forces(run: FluidRun, scene) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    rec = run.record()
    assert rec.failure is None, rec.failure
    cd, cl = force_coefficients(scene, rec)
    return np.asarray(rec.t), cd, cl


def test_a_run_restarted_from_its_own_saved_state_continues_it(tmp_path):
    """2D-2 at 10 cells across, 0.2 s from rest, saved; the same grid restarted from the saved
    state for 0.1 s against the uninterrupted run from 0.2 to 0.3 s. On the same grid the
    interpolation is the identity, so the two differ only by the restart's first step (forward
    Euler for the convection where Adams-Bashforth 2 had the previous step's term; the previous
    pressure kept): measured 4.5e-5 of the drag in the drag, 3e-6 in the lift. The velocities
    read half a cell off (u and v each shifted along their own axis, a throwaway check) put 19 %
    of the drag into the drag and 12 % into the lift."""
    first = bench_dfg.scene_for("2d2", 10, 0.2)
    run = FluidRun(first, "central")
    _forces(run, first)
    state = tmp_path / "s.npz"
    bench_dfg.save_state(run.st, state)

    whole = bench_dfg.scene_for("2d2", 10, 0.3)
    t, cd, cl = _forces(FluidRun(whole, "central"), whole)
    later = t >= 0.2 - 1e-9

    rest = bench_dfg.scene_for("2d2", 10, 0.1)
    restarted = FluidRun(rest, "central")
    bench_dfg.start_from(restarted.st, bench_dfg.read_state(state))
    t2, cd2, cl2 = _forces(restarted, rest)

    assert t2.shape[0] == later.sum()
    # the first sample is the saved state itself, whose force needs the momentum's change:
    # compare from the second on
    drag_gap = np.abs(cd2[1:] - cd[later][1:]).max() / np.abs(cd[later]).max()
    lift_gap = np.abs(cl2[1:] - cl[later][1:]).max() / np.abs(cd[later]).max()
    assert drag_gap < 1e-3, drag_gap
    assert lift_gap < 1e-3, lift_gap


def test_the_period_maxima_of_an_oscillation_settling_geometrically_give_its_limit():
    """A lift c_L = A(t) sin(2 pi t / T) sampled every 5 ms, T = 0.333 s (the DFG 2D-2 shedding),
    whose amplitude approaches 1 by the factor 0.55 a period (what the restarted runs show):
    the period maxima are read to the sampled peak's accuracy (the parabola's, 2e-5 at 67
    samples a period) and Aitken's extrapolation of the last three gives the limit the maxima
    have not reached: the last maximum after 3 s is 2.2e-3 short, the limit 4e-6 off (bound
    1e-4)."""
    period, rate = 1.0 / 3.0, np.log(0.55) / (1.0 / 3.0)
    t = np.arange(0.0, 3.0 + 1e-9, 0.005)
    amplitude = 1.0 - 0.3 * np.exp(rate * t)
    cl = amplitude * np.sin(2 * np.pi * t / period)
    cd = 3.2 + 0.05 * amplitude * np.cos(4 * np.pi * t / period)
    maxima = bench_dfg.period_maxima(t, cd, cl)
    assert len(maxima) >= 7
    lift = [m[1] for m in maxima]
    assert all(b > a for a, b in zip(lift, lift[1:], strict=False))   # settling from below
    assert 1.0 - lift[-1] > 1e-3                                       # not there yet
    limit = bench_dfg.aitken(lift)
    assert limit is not None and abs(limit - 1.0) < 1e-4, limit
    assert abs(bench_dfg.aitken([m[2] for m in maxima]) - 3.25) < 1e-4
    # a sequence that does not converge geometrically has no limit to read
    assert bench_dfg.aitken([1.0, 1.1, 1.3]) is None
    assert bench_dfg.aitken([1.0, 1.1]) is None
