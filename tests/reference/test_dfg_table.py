"""The DFG benchmark's reference table (src/crosscheck/reference/data/
schafer_turek1996_cylinder.csv): the 2D-2 values of FEATFLOW's reference computation beside the
1996 intervals, and the script that reads them from FEATFLOW's published force series
(benchmarks/featflow_reference.py) with the project's own measurements."""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
import pytest

from crosscheck.reference.fluid_data import dfg_reference

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "benchmarks"))
import featflow_reference  # noqa: E402  (the reading the table's header describes)


def test_the_2d2_reference_computation_and_the_1996_intervals_disagree_only_on_the_lift():
    """FEATFLOW's level-6 computation (c_D max 3.22739, St 0.30184) lies inside the 1996
    intervals for the drag maximum and the Strouhal number, and its lift maximum (0.98658) 0.34 %
    below the lift's (0.99-1.01). The metrics read the error against the computation, so a
    solver converging to the benchmark's equations is not scored against the interval's centre;
    the miss from the interval is reported beside it. Should the table lose the reference (or
    the interval), the 2D-2 metrics would silently fall back to the centre: this says which
    numbers the documented study (benchmarks/results/dfg.md) was read against."""
    refs, source = dfg_reference("2D-2")
    d, lift, st = (refs[q] for q in ("drag_coefficient_max", "lift_coefficient_max",
                                      "strouhal_number"))
    assert (d.reference, lift.reference, st.reference) == (3.22739, 0.98658, 0.30184)
    assert d.lower <= d.target <= d.upper and st.lower <= st.target <= st.upper
    assert lift.target < lift.lower and (lift.lower - lift.target) / lift.lower == \
        pytest.approx(0.00345, abs=5e-5)
    # the header names where the numbers come from
    text = " ".join(source)
    assert "bdforces_q2_lv6_dt4" in text and "dt = 1/1600" in text


def _write_bdforces(path: Path, t: np.ndarray, cd: np.ndarray, cl: np.ndarray) -> None:
    """A file in FEATFLOW's ``bdforces`` layout: index, time, boundary component, c_D, c_L."""
    rows = [f"{i + 1} {ti:.10E} 2 {d:.10E} {c:.10E}"
            for i, (ti, d, c) in enumerate(zip(t, cd, cl, strict=True))]
    path.write_text("\n".join(rows) + "\n")


def test_the_reading_of_a_force_series_recovers_its_extrema_and_frequency(tmp_path):
    """A series shaped like FEATFLOW's (1600 samples over 1 s, the lift at the shedding
    frequency, the drag at twice it), with known extrema: the script returns them to the
    parabola's refinement (a sine sampled 530 times a period: the peak to 1e-6 relative) and the
    Strouhal number D f / U_mean from the lift's crossings to 1e-6. Its columns read in another
    order (drag as lift) would put the lift maximum at 3.23."""
    f = 3.01841                              # Hz: St = 0.301841 with D = 0.1, U_mean = 1
    t = 9.0 + 0.000625 * (np.arange(1600) + 0.5)
    w = 2 * math.pi * f
    cl = -0.0174 + 1.0039 * np.sin(w * (t - 9.03))
    cd = 3.1959 + 0.0315 * np.cos(2 * w * (t - 9.03))
    path = tmp_path / "bdforces"
    _write_bdforces(path, t, cd, cl)
    out = featflow_reference.featflow_values(path)
    assert out["lift_coefficient_max"] == pytest.approx(-0.0174 + 1.0039, rel=1e-6)
    assert out["lift_coefficient_min"] == pytest.approx(-0.0174 - 1.0039, rel=1e-6)
    assert out["drag_coefficient_max"] == pytest.approx(3.1959 + 0.0315, rel=1e-7)
    assert out["strouhal_number"] == pytest.approx(0.1 * f, rel=1e-6)
    assert out["lift_coefficient_mean"] == pytest.approx(-0.0174, abs=2e-3)
