"""Per-case figures for the HTML report (matplotlib, Agg backend, PNG bytes).

Each case gets one figure, one line per cell (engine colour, integrator line style), with a panel
for each of: relative energy drift |E(t) - E(0)| / S_E; linear momentum drift; angular momentum
drift; position error against the reference (m); orientation error against the reference (rad);
and cost (wall s per simulated s) against accuracy, one point per cell. A panel whose series are
zero for every cell (a centre of mass at rest) is left out. The accuracy axis is the first of
position_error_max, orientation_error_max, the case's other limited metrics (e.g.
flip_period_error), energy_drift that is non-zero for some cell. Curves are the down-sampled
series the cells returned (the largest value in each bin, so peaks survive). Values of exactly
zero are drawn at 1e-17 on the log axes.
"""

from __future__ import annotations

import io
import warnings
from typing import Any

ENGINE_COLORS = {"inhouse": "#1f77b4", "mujoco": "#d62728", "pybullet": "#2ca02c",
                 "pymunk": "#9467bd"}
STYLES = ["-", "--", ":", "-.", (0, (5, 1)), (0, (3, 1, 1, 1, 1, 1))]
FLOOR = 1e-17
ACCURACY_METRICS = ("position_error_max", "orientation_error_max", "energy_drift")


def _label(cell: dict[str, Any], multi_dt: bool) -> str:
    text = f"{cell['engine']}-{cell['integrator']}"
    return text + (f" dt={cell['dt']:g}" if multi_dt else "")


def _style_map(cells):
    styles = {}
    for c in cells:
        per_engine = [k for k in styles if k[0] == c["engine"]]
        key = (c["engine"], c["integrator"])
        if key not in styles:
            styles[key] = STYLES[len(per_engine) % len(STYLES)]
    return styles


def _xy(series):
    t = [a for a, b in zip(series["t"], series["y"], strict=True) if b is not None]
    y = [max(b, FLOOR) for b in series["y"] if b is not None]
    return t, y


PANELS = (  # series name, panel title
    ("energy_drift", "relative energy drift |E(t) - E(0)| / S_E"),
    ("linear_momentum_drift", "linear momentum drift"),
    ("angular_momentum_drift", "angular momentum drift"),
    ("position_error", "position error vs reference (m)"),
    ("orientation_error", "orientation error vs reference (rad)"),
    ("penetration", "contact penetration, deepest pair (m)"),
)


def _has_signal(cells, name) -> bool:
    """A panel is drawn when some cell has a non-zero value of that series."""
    return any(any(v for v in (c["series"][name]["y"] or []) if v is not None)
               for c in cells if name in c["series"])


def case_figure(case: str, cells: list[dict[str, Any]]) -> bytes | None:
    """PNG bytes of the case's figure, or None when no cell has anything to draw."""
    import matplotlib

    matplotlib.use("Agg", force=True)
    import matplotlib.pyplot as plt

    drawn = [c for c in cells if c.get("series")]
    metric = accuracy_metric(cells)
    points = [c for c in cells if (c.get("cost") or 0) > 0 and _value(c, metric) is not None]
    panels = [(name, title) for name, title in PANELS if _has_signal(drawn, name)]
    if points:
        panels.append(("cost", f"cost vs accuracy ({metric})"))
    if not panels:
        return None
    ncols = 2 if len(panels) > 1 else 1
    nrows = (len(panels) + ncols - 1) // ncols
    fig, axes = plt.subplots(nrows, ncols, figsize=(6.2 * ncols, 3.2 * nrows), squeeze=False)
    multi_dt = len({c["dt"] for c in cells}) > 1
    styles = _style_map(cells)
    for ax, (name, title) in zip(axes.flat, panels, strict=False):
        ax.set_title(title, fontsize=9)
        if name == "cost":
            _cost_panel(ax, points, metric, multi_dt)
            continue
        ax.set_xlabel("t (s)", fontsize=8)
        ax.set_yscale("log")
        for c in drawn:
            if name not in c["series"]:
                continue
            t, y = _xy(c["series"][name])
            if t:
                ax.plot(t, y, color=ENGINE_COLORS.get(c["engine"], "#555555"),
                        linestyle=styles[(c["engine"], c["integrator"])], linewidth=1.1,
                        label=_label(c, multi_dt))
        ax.tick_params(labelsize=7)
        ax.grid(True, which="major", alpha=0.3)
        if ax.get_legend_handles_labels()[0]:
            ax.legend(fontsize=6, loc="best")
    for ax in list(axes.flat)[len(panels):]:
        ax.set_visible(False)
    fig.suptitle(case, fontsize=10)
    with warnings.catch_warnings():  # tight_layout may give up on crowded legends: cosmetic
        warnings.simplefilter("ignore")
        fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=80)
    plt.close(fig)
    return buf.getvalue()


def _value(cell: dict[str, Any], name: str | None) -> float | None:
    m = (cell.get("metrics") or {}).get(name or "")
    if m and m.get("value") is not None and m.get("meaningful", True):
        return m["value"]
    return None


def accuracy_metric(cells: list[dict[str, Any]]) -> str | None:
    """The case's accuracy axis: the first of ACCURACY_METRICS, then any other limited metric,
    that is non-zero for some cell (a centre of mass at rest makes position error useless)."""
    limited = sorted({n for c in cells for n, m in (c.get("metrics") or {}).items()
                      if m.get("limit") is not None and n not in ACCURACY_METRICS
                      and n != "blowup_time" and not n.endswith("_drift")})
    for name in (*ACCURACY_METRICS[:2], *limited, *ACCURACY_METRICS[2:]):
        if any((_value(c, name) or 0) > 0 for c in cells):
            return name
    return None


def log_axes(ax) -> None:
    """Both axes logarithmic, labelled only at 1, 2 and 5 times a power of ten.

    Matplotlib labels minor ticks when a span is under a decade, and those overprint each other.
    """
    from matplotlib import ticker

    ax.set_xscale("log")
    ax.set_yscale("log")
    for axis in (ax.xaxis, ax.yaxis):
        axis.set_major_locator(ticker.LogLocator(base=10, subs=(1.0, 2.0, 5.0)))
        axis.set_major_formatter(ticker.LogFormatterSciNotation(labelOnlyBase=False))
        axis.set_minor_formatter(ticker.NullFormatter())


def _cost_panel(ax, cells, metric, multi_dt):
    for c in cells:
        value = max(_value(c, metric), FLOOR)
        ax.scatter([c["cost"]], [value], color=ENGINE_COLORS.get(c["engine"], "#555"), s=18)
        ax.annotate(_label(c, multi_dt), (c["cost"], value), fontsize=6, xytext=(3, 2),
                    textcoords="offset points")
    log_axes(ax)
    ax.set_xlabel("cost: wall s per simulated s", fontsize=8)
    ax.set_ylabel(metric or "", fontsize=7)
    ax.tick_params(labelsize=7)
    ax.grid(True, alpha=0.3)
