"""The report's figures: labelled log ticks on every range, a distinct look per run, compact
encoding, the per-case panels, the accuracy-against-cost figure's Pareto front and spread, the
sweep figure, and the fluid animation only where the surface moves."""

from __future__ import annotations

import io
import math
import warnings

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402

from crosscheck.report import cost_plot, figure, pareto, plots  # noqa: E402
from crosscheck.report.style import Looks  # noqa: E402


def labels_shown(ax, axis="y") -> list[str]:
    """The tick labels drawn inside the axis limits."""
    ax.figure.canvas.draw()
    a = ax.yaxis if axis == "y" else ax.xaxis
    lo, hi = sorted(ax.get_ylim() if axis == "y" else ax.get_xlim())
    return [t.label1.get_text() for t in a.get_major_ticks()
            if t.label1.get_visible() and t.label1.get_text() and lo <= t.get_loc() <= hi]


@pytest.mark.parametrize("lo,hi", [(3e-4, 8e-4), (3.1e-4, 3.3e-4), (2e-4, 2.5e-3),
                                   (1e-16, 1e-2), (1e-9, 1e-6), (0.5, 40.0)])
def test_log_axes_have_at_least_two_labelled_ticks_on_any_range(lo, hi):
    fig, ax = plt.subplots()
    ax.plot([1e-4, 1e-3], [lo, hi], "o")
    ax.set_xscale("log")
    ax.set_yscale("log")
    figure.log_ticks(ax, "both")
    shown = labels_shown(ax)
    plt.close(fig)
    assert len(shown) >= 2, (lo, hi, shown)
    assert len(shown) <= 9  # readable, not overprinted
    values = [float(s) for s in shown]
    assert all(lo * 0.5 <= v <= hi * 2 for v in values)


def test_every_run_of_a_figure_has_its_own_colour_and_marker():
    labels = [f"inhouse-integrator{k}" for k in range(15)] + ["mujoco-euler",
                                                              "inhouse-symplectic_euler+soft_step"]
    looks = Looks(labels)
    pairs = {(looks[x].color, looks[x].marker) for x in labels}
    assert len(pairs) == len(labels)
    assert len({looks[x].color for x in labels[:10]}) == 10  # the first ten differ in colour
    # Engines first in a fixed order, then each engine's runs in order of appearance.
    from crosscheck.report.style import ordered_labels

    cells = [{"engine": e, "integrator": i} for e, i in
             (("pymunk", "a"), ("mujoco", "b"), ("inhouse", "c"), ("mujoco", "a"))]
    assert ordered_labels(cells) == ["inhouse-c", "mujoco-b", "mujoco-a", "pymunk-a"]


def test_palette_png_is_smaller_and_decodes():
    fig, ax = plt.subplots(figsize=(6.4, 3.2))
    t = np.linspace(0, 5, 400)
    for k in range(6):
        ax.semilogy(t, np.exp(-k * t) + 1e-6, marker="os^Dv<"[k], markevery=40)
    rgba = io.BytesIO()
    fig.savefig(rgba, format="png", dpi=figure.PNG_DPI)
    data = figure.png(fig)
    data2, mime = figure.encode(fig)
    plt.close(fig)
    from PIL import Image

    image = Image.open(io.BytesIO(data))
    assert image.size == (512, 256) and image.mode == "P"
    assert len(data) < 0.6 * len(rgba.getvalue())
    assert mime == "image/png" and data2 == data  # 2400 vertices: no SVG tried


def series_cell(engine, integrator, status="pass", cost=1e-4, spread=0.1, error=1e-3,
                energy=None, meaningful=True, limit=None):
    t = list(np.linspace(0, 1, 50))
    energy = energy if energy is not None else [1e-8 * (1 + x) for x in t]
    return {"id": f"c::{engine}-{integrator}@dt=0.01", "case": "c", "engine": engine,
            "integrator": integrator, "dt": 0.01, "status": status, "cost": cost,
            "cost_median": cost * 1.1, "cost_spread": spread,
            "metrics": {"position_error_max": {"value": error, "unit": "m", "limit": limit},
                        "energy_drift": {"value": max(energy), "meaningful": meaningful},
                        "linear_momentum_drift": {"value": 0.0}},
            "series": {"energy_drift": {"t": t, "y": energy},
                       "linear_momentum_drift": {"t": t, "y": [0.0] * len(t)},
                       "position_error": {"t": t, "y": [error * x for x in t]}}}


def test_case_panels_are_the_quantities_that_decide_and_say_why_others_are_not():
    cells = [series_cell("inhouse", "rk4", limit=0.01), series_cell("mujoco", "euler")]
    chosen, omitted = plots.panels(cells)
    assert [p[0] for p in chosen] == ["energy_drift", "position_error"]
    assert omitted == ["linear momentum drift: zero for every run"]
    for c in cells:
        c["metrics"]["energy_drift"].update(meaningful=False,
                                            note="not conserved: drag; scale S_E = 1 J")
    chosen, omitted = plots.panels(cells)
    assert [p[0] for p in chosen] == ["position_error"]
    assert "energy drift: not conserved: drag" in omitted
    fig = plots.case_figure("c", cells)
    assert fig is not None and fig.data[:4] == b"\x89PNG"
    assert plots.limits(cells, "position_error_max") == [0.01]


def test_figures_drawn_in_the_pool_are_those_drawn_in_process_and_a_failure_is_text():
    """report/figure_pool.py: a report of several cases draws its figures in spawned processes;
    the bytes must be the ones the calling process draws (the page does not depend on where),
    and a case whose figure fails comes back as the error's text, the others drawn."""
    from crosscheck.report import figure_pool

    groups = {f"case{k}": [series_cell("inhouse", "rk4", error=10.0 ** -k),
                           series_cell("mujoco", "euler", cost=3e-4, error=1e-2)]
              for k in range(figure_pool.POOL_FROM_CASES)}
    groups["broken"] = [dict(series_cell("inhouse", "rk4"), series={
        "energy_drift": {"t": [0.0, 1.0], "y": [1e-3]}})]   # t and y of different lengths
    here = figure_pool.draw_all(groups, workers=1)
    with warnings.catch_warnings():
        warnings.simplefilter("error")   # the pool's fallback warns: it must not be taken
        pooled = figure_pool.draw_all(groups, workers=2)
    assert list(pooled) == list(groups)
    for case in groups:
        if case == "broken":
            assert isinstance(pooled[case][0], str) and "ValueError" in pooled[case][0]
            assert pooled[case][0] == here[case][0]
            continue
        for a, b in zip(here[case], pooled[case], strict=True):
            assert a is not None and b is not None
            assert (a.mime, a.data) == (b.mime, b.data)


def test_pareto_front():
    points = [(1.0, 1e-2), (2.0, 1e-3), (3.0, 1e-3), (0.5, 1e-1), (4.0, 1e-5), (5.0, 1e-4)]
    assert pareto.front(points) == [3, 0, 1, 4]


def test_cost_figure_marks_the_front_and_the_spread():
    cells = [series_cell("inhouse", "rk4", cost=1e-4, error=1e-6),
             series_cell("inhouse", "euler", cost=5e-5, error=1e-2, spread=0.0),
             series_cell("mujoco", "rk4", cost=3e-4, error=1e-5)]
    # the bar is the cost times exp(-+spread): where a rerun's cost lands (docs/metrics.md)
    assert cost_plot.spread_bar(cells[0]) == pytest.approx((1e-4 * math.exp(-0.1),
                                                            1e-4 * math.exp(0.1)))
    assert cost_plot.spread_bar(cells[1]) is None  # no spread: no bar
    fig = cost_plot.cost_figure("c", cells)
    assert fig is not None
    assert cost_plot.cost_figure("c", cells[:1]) is None  # nothing to compare


def test_sweep_figure_distinguishes_integrators_and_labels_both_log_axes():
    from crosscheck.study import sweep

    cells = []
    for k, integrator in enumerate(["explicit_euler", "symplectic_euler", "midpoint", "rk4"]):
        for dt in (4e-3, 2e-3, 1e-3):
            cells.append({"case": "c", "engine": "inhouse", "integrator": integrator,
                          "dt": dt, "status": "pass", "cost": 1e-6 / dt,
                          "metrics": {"position_error_max": {"value": 2e-4 * (1 + k / 10)
                                                             * (dt / 1e-3) ** 0.1}}})
    metric, series = sweep.analyse(cells, None, [4e-3, 2e-3, 1e-3])
    captured = {}
    real_png = figure.png

    def keep(fig, dpi=figure.PNG_DPI):
        captured["fig"] = fig
        return real_png(fig, dpi)

    figure.png = keep
    try:
        sweep.figure("c", metric, series)
    finally:
        figure.png = real_png
    fig = captured["fig"]
    ax1, ax2, strip = fig.axes[:3]
    # The narrow error range (under a decade) still has labelled ticks on both panels; the dt
    # axis is labelled under the stability strip it shares with the convergence panel.
    for ax in (ax1, ax2):
        assert len(labels_shown(ax, "y")) >= 2
    for ax in (ax1, strip):
        assert len(labels_shown(ax, "x")) >= 2
    looks = {(line.get_color(), line.get_marker()) for line in ax2.get_lines()
             if line.get_marker() not in (None, "None", "", "|", "x", ">")}
    assert len(looks) == 4  # every integrator its own marker...
    assert len({color for color, _ in looks}) == 4  # ...and its own colour, in one engine


def test_fluid_animation_only_where_the_surface_moves():
    from crosscheck.report.fluid_plots import MOVES_CELLS, surface_motion

    class Record:
        def __init__(self, heights):
            y = np.arange(48)[None, :] + 0.5
            self.fields = {"phi": [np.broadcast_to(y - h, (64, 48)) for h in heights]}

    assert surface_motion(Record([24.0, 24.3, 23.7, 24.2])) < MOVES_CELLS  # a 5 mm wave
    assert surface_motion(Record([24.0, 20.0, 12.0, 8.0])) >= MOVES_CELLS  # a falling column
    assert math.isclose(surface_motion(Record([24.0, 21.0])), 3.0)
