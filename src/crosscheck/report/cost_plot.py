"""The accuracy-against-cost figure of a case: which run buys the most accuracy per second.

One point per run: x its cost (wall seconds per simulated second, the fastest timed repetition of
each cost pass, as in the tables), y its accuracy metric
(:func:`crosscheck.report.plots.accuracy_metric`), with the run's colour and marker. The cost
spread is a horizontal bar over the interval a rerun's cost lands in with the spread's coverage
(``cost`` x exp(+-``cost_spread``); docs/metrics.md, "Cost"), so a point whose cost a rerun may
move shows it. The Pareto front (runs
no other run beats in both) is a thick grey staircase through ringed points; the case's limits
on the metric are dashed lines. Both axes are logarithmic and labelled
(:func:`crosscheck.report.figure.log_ticks`).
"""

from __future__ import annotations

import math
from typing import Any

from crosscheck.report import pareto
from crosscheck.report.plots import FLOOR, Figure, accuracy_metric, draw_limits, limits, value
from crosscheck.report.style import Looks, run_label


def spread_bar(cell: dict[str, Any]) -> tuple[float, float] | None:
    """(low, high) of the interval a rerun's cost lands in (cost x exp(-+spread)), or None."""
    cost, spread = cell.get("cost"), cell.get("cost_spread")
    if not cost or spread is None or spread <= 0:
        return None
    return cost * math.exp(-spread), cost * math.exp(spread)


def cost_figure(case: str, cells: list[dict[str, Any]], looks: Looks | None = None
                ) -> Figure | None:
    """The figure, or None when fewer than two runs have both a cost and an accuracy value."""
    import matplotlib

    matplotlib.use("Agg", force=True)
    import matplotlib.pyplot as plt

    from crosscheck.report.figure import encode, log_ticks

    looks = looks or Looks.of(cells)
    metric = accuracy_metric(cells)
    runs = [c for c in cells if (c.get("cost") or 0) > 0 and value(c, metric) is not None]
    if len(runs) < 2:
        return None
    seen: set[str] = set()
    unit = next((c["metrics"][metric].get("unit") for c in runs
                 if c["metrics"][metric].get("unit")), "")
    fig, ax = plt.subplots(figsize=(9.6, 3.8))
    points = [(c["cost"], max(value(c, metric), FLOOR)) for c in runs]
    for c, (x, y) in zip(runs, points, strict=True):
        look = looks[run_label(c)]
        bar = spread_bar(c)
        if bar is not None:
            ax.plot(list(bar), [y, y], color=look.color, linewidth=3.5, alpha=0.45,
                    solid_capstyle="butt")
        # One legend entry per run: a run's steps share its look (a sweep's page has many).
        label = run_label(c) if run_label(c) not in seen else None
        seen.add(run_label(c))
        ax.plot([x], [y], linestyle="none", marker=look.marker, color=look.color,
                markersize=7, label=label, zorder=4)
    best = [points[i] for i in pareto.front(points)]
    ax.step([p[0] for p in best], [p[1] for p in best], where="post", color="k", alpha=0.3,
            linewidth=3, zorder=2, label="Pareto front")
    ax.plot([p[0] for p in best], [p[1] for p in best], linestyle="none", marker="o",
            markersize=13, markerfacecolor="none", markeredgecolor="k", zorder=3)
    ax.set_xscale("log")
    ax.set_yscale("log")
    draw_limits(ax, limits(cells, metric))
    ax.margins(x=0.15, y=0.2)
    ax.set_xlabel("cost: wall s per simulated s (marker: fastest repetition, geometric mean of"
                  " the passes; bar: where a rerun lands, the cost spread)", fontsize=8)
    ax.set_ylabel(f"{metric}" + (f" ({unit})" if unit else " (1)"), fontsize=8)
    ax.set_title(f"{case}: accuracy against cost (lower left is better)", fontsize=9)
    ax.tick_params(labelsize=7)
    ax.grid(True, which="major", alpha=0.3)
    ax.legend(fontsize=7, loc="center left", bbox_to_anchor=(1.01, 0.5), frameon=False)
    log_ticks(ax, "both")
    # Fixed margins (inches of a 9.6 x 3.8 in figure), the legend in the right one: cheaper
    # than tight_layout's extra draw (crosscheck.report.plots).
    fig.subplots_adjust(left=0.8 / 9.6, right=1 - 2.6 / 9.6, top=1 - 0.35 / 3.8,
                        bottom=0.6 / 3.8)
    data, mime = encode(fig)
    plt.close(fig)
    return Figure(data, mime)
