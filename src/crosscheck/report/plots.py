"""The per-case figure of the HTML report: the quantities that decide the verdict, over time.

One panel per quantity, one line per engine-integrator (its colour and marker from
:mod:`crosscheck.report.style`, the same in every figure of the report): relative energy drift
``|E(t) - E(0)| / S_E``, linear and angular momentum drift (on their scales ``S_P``, ``S_L``),
position and orientation error against the reference (m, rad) and, for contact cases, the
deepest penetration (m). A panel is drawn when the quantity decides some cell's verdict (its
metric is meaningful there: a momentum under gravity is not conserved and judges nothing) and
some cell has a non-zero value; :func:`panels` names the quantities left out and why, for the
page to say. Each panel shows the limits the case sets on its metric (dashed), and a run that
blew up ends in a cross. Curves are the down-sampled series the cells returned (the largest
value in each bin, so peaks survive); zero is drawn at :data:`FLOOR` on the log axes.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from crosscheck.report.style import Looks, run_label

FLOOR = 1e-16
MARKS_PER_LINE = 10

PANELS = (  # series, metric judged on it, title, y-axis label (with the unit)
    ("energy_drift", "energy_drift", "energy drift", "|E(t) - E(0)| / S_E (1)"),
    ("linear_momentum_drift", "linear_momentum_drift", "linear momentum drift",
     "|P(t) - P(0)| / S_P (1)"),
    ("angular_momentum_drift", "angular_momentum_drift", "angular momentum drift",
     "|L(t) - L(0)| / S_L (1)"),
    ("position_error", "position_error_max", "position error against the reference",
     "distance (m)"),
    ("orientation_error", "orientation_error_max", "orientation error against the reference",
     "angle (rad)"),
    ("penetration", "penetration_max", "contact penetration, deepest pair", "depth (m)"),
)


@dataclass
class Figure:
    data: bytes
    mime: str


def _has_signal(cells, name) -> bool:
    return any(any(v for v in (c["series"][name]["y"] or []) if v is not None)
               for c in cells if name in c.get("series", {}))


def _decides(cells, metric) -> bool:
    """The metric judges some cell: present and not marked meaningless (a non-conserved
    quantity), or limited by the case."""
    for c in cells:
        m = (c.get("metrics") or {}).get(metric)
        if m and (m.get("meaningful", True) or m.get("limit") is not None):
            return True
    return False


def _why_not(cells, metric) -> str:
    for c in cells:
        note = ((c.get("metrics") or {}).get(metric) or {}).get("note") or ""
        if note:
            return note.split(";")[0]
    return "not computed"


def panels(cells: list[dict[str, Any]]) -> tuple[list[tuple], list[str]]:
    """(panels to draw, "title: why not" for the quantities with a series that are not drawn)."""
    drawn = [c for c in cells if c.get("series")]
    keep, omitted = [], []
    for panel in PANELS:
        series, metric, title = panel[:3]
        if not any(series in c.get("series", {}) for c in drawn):
            continue
        if not _decides(drawn, metric):
            omitted.append(f"{title}: {_why_not(drawn, metric)}")
        elif not _has_signal(drawn, series):
            omitted.append(f"{title}: zero for every run")
        else:
            keep.append(panel)
    return keep, omitted


def limits(cells: list[dict[str, Any]], metric: str) -> list[float]:
    """The distinct limits the case sets on ``metric`` across its cells."""
    found = {(c.get("metrics") or {}).get(metric, {}).get("limit") for c in cells}
    return sorted(v for v in found if isinstance(v, int | float) and v > 0)


def draw_limits(ax, values: list[float]) -> None:
    for v in values:
        ax.axhline(v, color="#555555", linestyle="--", linewidth=0.8, zorder=1)
        ax.annotate(f"limit {v:g}", (1.0, v), xycoords=("axes fraction", "data"),
                    xytext=(-2, 2), textcoords="offset points", ha="right", fontsize=6,
                    color="#555555")


def _xy(series):
    pairs = [(a, max(b, FLOOR)) for a, b in zip(series["t"], series["y"], strict=True)
             if b is not None]
    return [a for a, _ in pairs], [b for _, b in pairs]


def case_figure(case: str, cells: list[dict[str, Any]], looks: Looks | None = None
                ) -> Figure | None:
    """The case's figure, or None when no cell has a quantity to draw."""
    import matplotlib

    matplotlib.use("Agg", force=True)
    import matplotlib.pyplot as plt
    from matplotlib.lines import Line2D

    from crosscheck.report.figure import encode, log_ticks

    looks = looks or Looks.of(cells)
    chosen, _ = panels(cells)
    if not chosen:
        return None
    drawn = [c for c in cells if c.get("series")]
    multi_dt = len({c["dt"] for c in cells}) > 1
    ncols = 2 if len(chosen) > 1 else 1
    nrows = (len(chosen) + ncols - 1) // ncols
    labels = list(dict.fromkeys(_label(c, multi_dt) for c in drawn))
    legend_rows = (len(labels) + 3) // 4
    height = 2.5 * nrows + 0.22 * legend_rows + 0.6
    fig, axes = plt.subplots(nrows, ncols, figsize=(6.4 * ncols, height), squeeze=False)
    handles: dict[str, Any] = {}
    for ax, (series, metric, title, ylabel) in zip(axes.flat, chosen, strict=False):
        ax.set_title(title, fontsize=9)
        ax.set_xlabel("t (s)", fontsize=8)
        ax.set_ylabel(ylabel, fontsize=8)
        ax.set_yscale("log")
        runs = [c for c in drawn if series in c["series"]]
        for k, c in enumerate(runs):
            t, y = _xy(c["series"][series])
            if not t:
                continue
            look = looks[run_label(c)]
            step = max(1, len(t) // MARKS_PER_LINE)
            # Staggered marks: runs that coincide still show every marker.
            (line,) = ax.plot(t, y, color=look.color, marker=look.marker, markersize=4,
                              markevery=(k * step // max(1, len(runs)), step), linewidth=1.1)
            handles.setdefault(_label(c, multi_dt), line)
            if c.get("status") == "blowup":
                ax.plot([t[-1]], [y[-1]], marker="X", markersize=9, color=look.color,
                        markeredgecolor="k", linestyle="none", zorder=5)
                handles.setdefault("blew up (end of its line)", Line2D(
                    [], [], marker="X", color="w", markerfacecolor="#999999",
                    markeredgecolor="k", markersize=8))
        draw_limits(ax, limits(cells, metric))
        ax.tick_params(labelsize=7)
        ax.grid(True, which="major", alpha=0.3)
        log_ticks(ax, "y")
    for ax in list(axes.flat)[len(chosen):]:
        ax.set_visible(False)
    fig.legend(list(handles.values()), list(handles.keys()), loc="lower center",
               ncol=min(4, len(handles)), fontsize=7, frameon=False)
    fig.suptitle(case, fontsize=10)
    # Fixed margins in inches, not tight_layout: it draws the whole figure once more to
    # measure it, a third of the figure's time, and these labels have known sizes.
    width = 6.4 * ncols
    fig.subplots_adjust(left=0.8 / width, right=1 - 0.15 / width, top=1 - 0.55 / height,
                        bottom=(0.22 * legend_rows + 0.6) / height, wspace=0.8 * 2 / width,
                        hspace=0.75 / 2.5)
    data, mime = encode(fig)
    plt.close(fig)
    return Figure(data, mime)


def _label(cell: dict[str, Any], multi_dt: bool) -> str:
    return run_label(cell) + (f" dt={cell['dt']:g}" if multi_dt else "")


ACCURACY_METRICS = ("position_error_max", "orientation_error_max", "energy_drift")


def value(cell: dict[str, Any], name: str | None) -> float | None:
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
        if any((value(c, name) or 0) > 0 for c in cells):
            return name
    return None
