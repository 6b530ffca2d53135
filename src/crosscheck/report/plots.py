"""Per-case figures for the HTML report (matplotlib, Agg backend, PNG bytes).

Each case gets one figure with up to four panels, one line per cell (engine colour, integrator
line style): relative energy drift |E(t) - E(0)| / S_E; linear (solid) and angular (dashed)
momentum drift; trajectory error against the reference (centre-of-mass position error, m, and
orientation error, rad, on its own panel); and cost (wall s per simulated s) against accuracy
(the case's first available of position_error_max, orientation_error_max, energy_drift), one
point per cell. Curves are the down-sampled series the cells returned (the largest value in each
bin, so peaks survive). Values of exactly zero are drawn at 1e-17 on the log axes.
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


def case_figure(case: str, cells: list[dict[str, Any]]) -> bytes | None:
    """PNG bytes of the case's figure, or None when no cell has anything to draw."""
    import matplotlib

    matplotlib.use("Agg", force=True)
    import matplotlib.pyplot as plt

    drawn = [c for c in cells if c.get("series")]
    points = [c for c in cells if (c.get("cost") or 0) > 0 and _accuracy(c)[1] is not None]
    if not drawn and not points:
        return None
    panels = []
    if any("energy_drift" in c["series"] for c in drawn):
        panels.append(("energy", "relative energy drift"))
    if any({"linear_momentum_drift", "angular_momentum_drift"} & set(c["series"])
           for c in drawn):
        panels.append(("momentum", "momentum drift (solid: linear, dashed: angular)"))
    if any("position_error" in c["series"] for c in drawn):
        panels.append(("position", "position error vs reference (m)"))
    if any("orientation_error" in c["series"] for c in drawn):
        panels.append(("orientation", "orientation error vs reference (rad)"))
    if points:
        panels.append(("cost", "cost vs accuracy"))
    ncols = 2 if len(panels) > 1 else 1
    nrows = (len(panels) + ncols - 1) // ncols
    fig, axes = plt.subplots(nrows, ncols, figsize=(6.2 * ncols, 3.4 * nrows), squeeze=False)
    multi_dt = len({c["dt"] for c in cells}) > 1
    styles = _style_map(cells)
    for ax, (kind, title) in zip(axes.flat, panels, strict=False):
        ax.set_title(title, fontsize=9)
        if kind == "cost":
            _cost_panel(ax, points, multi_dt)
            continue
        ax.set_xlabel("t (s)", fontsize=8)
        ax.set_yscale("log")
        for c in drawn:
            color = ENGINE_COLORS.get(c["engine"], "#555555")
            style = styles[(c["engine"], c["integrator"])]
            label = _label(c, multi_dt)
            if kind == "energy":
                names = [("energy_drift", style)]
            elif kind == "momentum":
                names = [("linear_momentum_drift", "-"), ("angular_momentum_drift", "--")]
            elif kind == "position":
                names = [("position_error", style)]
            else:
                names = [("orientation_error", style)]
            for j, (name, ls) in enumerate(names):
                if name in c["series"]:
                    t, y = _xy(c["series"][name])
                    if t:
                        ax.plot(t, y, color=color, linestyle=ls, linewidth=1.1,
                                label=label if j == 0 or kind != "momentum" else None)
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


def _accuracy(cell: dict[str, Any]) -> tuple[str | None, float | None]:
    metrics = cell.get("metrics") or {}
    for name in ACCURACY_METRICS:
        m = metrics.get(name)
        if m and m.get("value") is not None and m.get("meaningful", True):
            return name, m["value"]
    return None, None


def _cost_panel(ax, cells, multi_dt):
    names = {_accuracy(c)[0] for c in cells}
    for c in cells:
        name, value = _accuracy(c)
        ax.scatter([c["cost"]], [max(value, FLOOR)], color=ENGINE_COLORS.get(c["engine"], "#555"),
                   s=18)
        ax.annotate(_label(c, multi_dt), (c["cost"], max(value, FLOOR)), fontsize=6,
                    xytext=(3, 2), textcoords="offset points")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("cost: wall s per simulated s", fontsize=8)
    ax.set_ylabel(" / ".join(sorted(n for n in names if n)), fontsize=7)
    ax.tick_params(labelsize=7)
    ax.grid(True, alpha=0.3)
