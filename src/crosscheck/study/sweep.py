"""Sweeps: every integrator of every engine over a range of steps, accuracy against cost.

From the cells of one case run at steps ``dt_1 > dt_2 > ...`` (the ordinary runner, so every
cell is isolated and judged as usual), per engine and integrator:

* **error** at each step: the chosen metric (``--metric``; by default the first of
  :data:`DEFAULT_METRICS`, then the metrics the case sets limits on, that is *informative*: above
  :data:`ERROR_FLOOR` in some stable cell. A torque-free body's centre of mass never moves, so
  its position error is zero at every step and says nothing about the integrators);
* **cost**: wall seconds of stepping per simulated second;
* **empirical order of convergence**: the least-squares slope ``p`` of ``log(error)`` against
  ``log(dt)`` over the steps that stayed stable and whose error lies above the round-off floor
  (``error > 1e-12`` times the metric's scale is not known here, so an absolute floor
  :data:`ERROR_FLOOR` is used) -- for a method of order ``p``, ``error ~ C dt^p``. Pairwise orders
  ``log(e_k / e_{k+1}) / log(dt_k / dt_{k+1})`` are reported too, since a slope over a range
  where the error saturates or the asymptotic regime has not started is misleading;
* **largest stable step**: the largest step such that it and every smaller step swept did not
  blow up (status other than ``blowup``, ``error`` and ``timeout``).

The Pareto front (error against cost, across all engines and integrators) is the set of points
no other point beats in both; the plot marks it.
"""

from __future__ import annotations

import io
import math
from dataclasses import dataclass, field
from typing import Any

ERROR_FLOOR = 1e-13
DEFAULT_METRICS = ("position_error_max", "orientation_error_max", "angular_velocity_error_max",
                   "velocity_error_max")
CONSERVATION_METRICS = ("energy_drift", "angular_momentum_drift", "linear_momentum_drift")
UNSTABLE = frozenset({"blowup", "error", "timeout"})


@dataclass
class Series:
    engine: str
    integrator: str
    dts: list[float] = field(default_factory=list)
    errors: list[float | None] = field(default_factory=list)
    costs: list[float | None] = field(default_factory=list)
    statuses: list[str] = field(default_factory=list)
    order: float | None = None
    pairwise: list[float | None] = field(default_factory=list)
    largest_stable_dt: float | None = None
    not_applicable: str | None = None

    @property
    def label(self) -> str:
        return f"{self.engine}-{self.integrator}"

    def to_dict(self) -> dict[str, Any]:
        return dict(self.__dict__)


def pick_metric(cells: list[dict[str, Any]], wanted: str | None = None) -> str | None:
    """The metric a sweep plots: ``wanted``, else the first informative candidate.

    Candidates, in order: errors against the reference (:data:`DEFAULT_METRICS`), the other
    metrics the case sets limits on (e.g. ``flip_period_error``), then conservation drifts.
    """
    if wanted:
        return wanted
    limited = sorted({n for c in cells for n, m in (c.get("metrics") or {}).items()
                      if m.get("limit") is not None and n not in CONSERVATION_METRICS})
    candidates = [*DEFAULT_METRICS, *[n for n in limited if n not in DEFAULT_METRICS],
                  *CONSERVATION_METRICS]

    def values(name: str) -> list[float]:
        out = []
        for c in cells:
            if c.get("status") in UNSTABLE:
                continue
            v = (c.get("metrics") or {}).get(name, {}).get("value")
            if isinstance(v, int | float) and math.isfinite(v):
                out.append(v)
        return out

    for name in candidates:
        if any(v > ERROR_FLOOR for v in values(name)):
            return name
    return next((name for name in candidates if values(name)), None)


def fit_order(dts: list[float], errors: list[float]) -> float | None:
    """Least-squares slope of log(error) against log(dt); None with fewer than two points."""
    pts = [(math.log(d), math.log(e)) for d, e in zip(dts, errors, strict=True)
           if e is not None and e > ERROR_FLOOR]
    if len(pts) < 2:
        return None
    n = len(pts)
    mx = sum(p[0] for p in pts) / n
    my = sum(p[1] for p in pts) / n
    sxx = sum((p[0] - mx) ** 2 for p in pts)
    if sxx == 0:
        return None
    return sum((p[0] - mx) * (p[1] - my) for p in pts) / sxx


def analyse(cells: list[dict[str, Any]], metric: str | None = None
            ) -> tuple[str | None, list[Series]]:
    """Group one case's cells by engine and integrator into convergence series."""
    metric = pick_metric(cells, metric)
    groups: dict[tuple[str, str], Series] = {}
    for c in sorted(cells, key=lambda c: (c["engine"], c["integrator"], -c["dt"])):
        key = (c["engine"], c["integrator"])
        s = groups.setdefault(key, Series(*key))
        if c["status"] == "not_applicable":
            s.not_applicable = c.get("reason") or "not applicable"
            continue
        m = (c.get("metrics") or {}).get(metric or "", {})
        s.dts.append(float(c["dt"]))
        s.errors.append(m.get("value") if c["status"] not in UNSTABLE else None)
        s.costs.append(c.get("cost"))
        s.statuses.append(c["status"])
    for s in groups.values():
        stable = [st not in UNSTABLE for st in s.statuses]
        s.largest_stable_dt = None
        # Steps are in decreasing order: the largest stable step has every smaller one stable.
        for i in range(len(s.dts)):
            if all(stable[i:]):
                s.largest_stable_dt = s.dts[i]
                break
        ok = [(d, e) for d, e, st in zip(s.dts, s.errors, stable, strict=True)
              if st and e is not None]
        s.order = fit_order([d for d, _ in ok], [e for _, e in ok])
        s.pairwise = []
        for (d1, e1), (d2, e2) in zip(ok[:-1], ok[1:], strict=True):
            if e1 > ERROR_FLOOR and e2 > ERROR_FLOOR and d1 != d2:
                s.pairwise.append(math.log(e1 / e2) / math.log(d1 / d2))
            else:
                s.pairwise.append(None)
    return metric, list(groups.values())


def pareto(series: list[Series]) -> list[tuple[str, float, float, float]]:
    """(label, dt, cost, error) points no other point beats in both cost and error."""
    pts = [(s.label, d, c, e) for s in series
           for d, c, e in zip(s.dts, s.costs, s.errors, strict=True)
           if c is not None and c > 0 and e is not None]
    front = [p for p in pts if not any((q[2] <= p[2] and q[3] < p[3]) or
                                       (q[2] < p[2] and q[3] <= p[3]) for q in pts)]
    return sorted(front, key=lambda p: p[2])


def figure(case: str, metric: str | None, series: list[Series]) -> bytes:
    """PNG: error against cost (Pareto), and error against dt (convergence)."""
    import matplotlib

    matplotlib.use("Agg", force=True)
    import matplotlib.pyplot as plt

    from crosscheck.report.plots import ENGINE_COLORS, FLOOR, STYLES, log_axes

    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(12.5, 4.6))
    markers = "osD^v<>ph"
    per_engine: dict[str, int] = {}
    for s in series:
        k = per_engine.get(s.engine, 0)
        per_engine[s.engine] = k + 1
        color = ENGINE_COLORS.get(s.engine, "#555555")
        pts = [(d, c, max(e, FLOOR)) for d, c, e in zip(s.dts, s.costs, s.errors, strict=True)
               if e is not None]
        if not pts:
            continue
        label = s.label + (f" (p={s.order:.2f})" if s.order is not None else "")
        cost_pts = [(c, e) for _, c, e in pts if c is not None and c > 0]
        if cost_pts:
            ax1.plot([c for c, _ in cost_pts], [e for _, e in cost_pts], color=color,
                     linestyle=STYLES[k % len(STYLES)], marker=markers[k % len(markers)],
                     markersize=4, label=label)
        ax2.plot([d for d, _, _ in pts], [e for _, _, e in pts], color=color,
                 linestyle=STYLES[k % len(STYLES)], marker=markers[k % len(markers)],
                 markersize=4, label=label)
    front = pareto(series)
    if front:
        ax1.plot([p[2] for p in front], [max(p[3], FLOOR) for p in front], color="k",
                 linewidth=2.5, alpha=0.25, label="Pareto front")
    for ax, xlabel in ((ax1, "cost: wall s per simulated s"), (ax2, "dt (s)")):
        log_axes(ax)
        ax.set_xlabel(xlabel, fontsize=8)
        ax.set_ylabel(metric or "error", fontsize=8)
        ax.grid(True, alpha=0.3)
        ax.tick_params(labelsize=7)
    ax1.set_title("accuracy against cost", fontsize=9)
    ax2.set_title("convergence (slope = order)", fontsize=9)
    if ax2.get_legend_handles_labels()[0]:
        ax2.legend(fontsize=6, loc="best")
    fig.suptitle(f"{case}: sweep", fontsize=10)
    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=80)
    plt.close(fig)
    return buf.getvalue()


def _stable(largest: float | None, dts: list[float]) -> str:
    if largest is None:
        return "none"
    # Stable at the largest step swept: the frontier lies beyond the sweep.
    return f">= {largest:g}" if dts and largest == dts[0] else f"{largest:g}"


def table(metric: str | None, series: list[Series]) -> str:
    """Markdown: per engine and integrator the errors per step, order, largest stable step."""
    dts = sorted({d for s in series for d in s.dts}, reverse=True)
    head = ("| engine-integrator | " + " | ".join(f"dt={d:g}" for d in dts)
            + " | order | pairwise | largest stable dt |")
    lines = [f"Error metric: `{metric}`", "", head, "|" + "---|" * (len(dts) + 4)]
    for s in series:
        if s.not_applicable:
            lines.append(f"| {s.label} | " + " | ".join("" for _ in dts)
                         + f" | n/a | | {s.not_applicable[:60]} |")
            continue
        by_dt = dict(zip(s.dts, zip(s.errors, s.statuses, strict=True), strict=True))
        cells = []
        for d in dts:
            e, st = by_dt.get(d, (None, ""))
            cells.append(st.upper() if st in UNSTABLE else ("" if e is None else f"{e:.3g}"))
        pw = ", ".join("-" if p is None else f"{p:.2f}" for p in s.pairwise)
        lines.append(f"| {s.label} | " + " | ".join(cells)
                     + f" | {'' if s.order is None else f'{s.order:.2f}'} | {pw} | "
                     + _stable(s.largest_stable_dt, dts)
                     + " |")
    return "\n".join(lines)
