"""Sweeps: every integrator of every engine over a range of steps, accuracy against cost.

From the cells of one case run at steps ``dt_1 > dt_2 > ...`` (the ordinary runner, so every
cell is isolated and judged as usual), per engine and integrator:

* **error** at each step: the chosen metric (``--metric``; by default the first of
  :data:`DEFAULT_METRICS`, then the metrics the case sets limits on, that is *informative*: above
  :data:`ERROR_FLOOR` in some stable cell. A torque-free body's centre of mass never moves, so
  its position error is zero at every step and says nothing about the integrators). A stable
  cell whose metric had nothing to measure (``not_measured``, e.g. a flip period of a run that
  never flips) is reported as "not measured: why", never as a number;
* **cost**: wall seconds of stepping per simulated second (the minimum of the timed repetitions,
  docs/metrics.md "Cost");
* **floor**: a point whose error is limited by the measurement rather than by the step is left
  out of the order, with the reason (:func:`floor_reasons`): round-off (``error <=``
  :data:`ERROR_FLOOR`), the metric's own stated resolution (a ``<base>_resolution`` metric next
  to ``<base>_error``, or ``<metric>_resolution``: errors within :data:`RESOLUTION_FACTOR` of it),
  or a generic stall (from some step down to the smallest, every refinement lowered the error
  by less than half the integrator's nominal order, crosscheck.names, predicts);
* **empirical order of convergence**: the least-squares slope ``p`` of ``log(error)`` against
  ``log(dt)`` over the stable, measured points above the floor (the *asymptotic points*, listed
  in ``order_points``); with fewer than two, "order not measurable" and why. Pairwise orders
  ``log(e_k / e_{k+1}) / log(dt_k / dt_{k+1})`` over all measured points are reported too;
* **largest stable step** and the **stability frontier**: the largest step such that it and
  every smaller step run did not blow up (status ``blowup``, ``error`` or ``timeout``), and the
  smallest unstable step above it, over the sweep's steps and the frontier probes the command
  adds (crosscheck.commands.sweep: doubling, then bisection on the number of steps).

The Pareto front (error against cost, across all engines and integrators) is the set of points
no other point beats in both; the plot marks it. :func:`cheapest` answers ``--target X``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

ERROR_FLOOR = 1e-13
# An error within this factor of the metric's stated resolution is at the metric's floor.
RESOLUTION_FACTOR = 10.0
DEFAULT_METRICS = ("position_error_max", "orientation_error_max", "angular_velocity_error_max",
                   "velocity_error_max")
CONSERVATION_METRICS = ("energy_drift", "angular_momentum_drift", "linear_momentum_drift")
UNSTABLE = frozenset({"blowup", "error", "timeout", "collapsed", "gained_energy"})


# The case-suite tag of a contact structure built to stand in equilibrium (stack_10, pyramid_2d,
# mass_ratio_100, mass_ratio_1000): mass_ratio_1000 sets no tolerances at all (its drift is a
# result to report), so the tag, not a rest_drift_max limit, is what says it must stand.
STRUCTURE_TAG = "stack"
# energy_gain (docs/metrics.md: max gain over E(0) / S_E, S_E at least the work to lift every
# body by its own size) above which a standing structure without an energy_gain limit of its
# own gained energy: 1 % of that work is far above any resting integrator's error (a structure
# that stands loses energy or keeps it) and far below a structure thrown apart (order 1).
STRUCTURE_ENERGY_GAIN = 1e-2


def must_stand(scene) -> bool:
    """True for a contact structure that must stand: contact on, every body starting at rest,
    and the case either tagged :data:`STRUCTURE_TAG` or limiting ``rest_drift_max``."""
    import numpy as np

    if not scene.effects.contact:
        return False
    if any(np.any(np.asarray(b.velocity)) or np.any(np.asarray(b.angular_velocity))
           for b in scene.bodies):
        return False
    return STRUCTURE_TAG in scene.tags or "rest_drift_max" in scene.tolerances


def stability(cell: dict[str, Any], stands: bool | None = None) -> str:
    """The cell's status as far as stability goes: its own status, or, for a run that did not
    blow up, ``collapsed`` when a structure that should stand fell and ``gained_energy`` when
    it gained energy. A contact structure can fail without any value running away.

    ``stands``: the case is a structure that must stand (:func:`must_stand`); None (no scene at
    hand) takes a ``rest_drift_max`` limit on the cell as saying so. A structure fell when its
    ``collapse_time`` (measured from the settled pose at 10 % of the run) or its
    ``collapse_time_start`` (from the starting pose: a structure that falls apart inside the
    settle window, or in the first step of a large one, and lies still afterwards shows only
    there) has a value. Energy: ``energy_gain`` broke the case's limit for it, or, for a
    structure without such a limit, exceeds :data:`STRUCTURE_ENERGY_GAIN`."""
    status = cell.get("status", "")
    if status in UNSTABLE or status == "not_applicable":
        return status
    metrics = cell.get("metrics") or {}
    # Only where the case says the structure must stand: a ball dropped from rest also
    # "leaves its settled position", and that is not a collapse.
    if stands is None:
        stands = (metrics.get("rest_drift_max") or {}).get("limit") is not None
    if stands and fall_time(metrics) is not None:
        return "collapsed"
    gain = metrics.get("energy_gain") or {}
    if gain.get("passed") is False:
        return "gained_energy"
    value = gain.get("value")
    if (stands and gain.get("limit") is None and isinstance(value, int | float)
            and value > STRUCTURE_ENERGY_GAIN):
        return "gained_energy"
    return status


def fall_time(metrics: dict[str, Any]) -> float | None:
    """The earlier of ``collapse_time`` and ``collapse_time_start``, None when neither is set."""
    times = [(metrics.get(n) or {}).get("value") for n in ("collapse_time", "collapse_time_start")]
    times = [t for t in times if isinstance(t, int | float)]
    return min(times) if times else None


REL = 1e-9  # two steps within this relative difference are the same step


@dataclass
class Series:
    engine: str
    integrator: str
    dts: list[float] = field(default_factory=list)
    errors: list[float | None] = field(default_factory=list)
    costs: list[float | None] = field(default_factory=list)
    statuses: list[str] = field(default_factory=list)
    not_measured: list[str] = field(default_factory=list)  # per point: why, "" when measured
    resolutions: list[float | None] = field(default_factory=list)
    floor: list[str] = field(default_factory=list)  # per point: why it is at the floor, or ""
    nominal_order: int | None = None
    order: float | None = None
    order_points: list[float] = field(default_factory=list)  # the dts the order is fitted on
    order_note: str = ""
    pairwise: list[float | None] = field(default_factory=list)
    largest_stable_dt: float | None = None
    smallest_unstable_dt: float | None = None  # above largest_stable_dt (the frontier bracket)
    frontier: str = ""  # the frontier in words
    probes: list[dict[str, Any]] = field(default_factory=list)  # frontier cells: dt, status, ...
    # Every run (sweep steps and probes), decreasing dt: dt, stability status, and for a failed
    # run what failed when (:func:`_run_record`).
    runs: list[dict[str, Any]] = field(default_factory=list)
    not_applicable: str | None = None

    @property
    def label(self) -> str:
        return f"{self.engine}-{self.integrator}"

    def to_dict(self) -> dict[str, Any]:
        return dict(self.__dict__)


def pick_metric(cells: list[dict[str, Any]], wanted: str | None = None,
                stands: bool | None = None) -> str | None:
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
            if stability(c, stands) in UNSTABLE:
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


def pairwise_order(d1: float, e1: float, d2: float, e2: float) -> float | None:
    if e1 > 0 and e2 > 0 and d1 != d2:
        return math.log(e1 / e2) / math.log(d1 / d2)
    return None


def floor_reasons(dts: list[float], errors: list[float],
                  resolutions: list[float | None] | None = None,
                  nominal: int | None = None) -> list[str]:
    """Per point (steps in decreasing order, every error measured): why its error is at the
    metric's floor rather than set by the step, or "" for an asymptotic point.

    * round-off: ``error <= ERROR_FLOOR``;
    * resolution: ``error <= RESOLUTION_FACTOR * resolution`` (the metric states it);
    * stall: the smallest k such that every refinement from point k down to the smallest step
      has a pairwise order below ``nominal / 2`` (the error fell by less than the square root of
      the ``(dt_k / dt_k+1)^p`` the method's nominal order predicts; without a nominal order,
      below 1/4): points k .. last are at the floor. A floor is reached at the small-step end
      and stays, so a slow stretch followed by a healthy decrease (a pre-asymptotic range) is
      not a floor.
    """
    n = len(dts)
    out = [""] * n
    res = list(resolutions or [None] * n)
    for k, e in enumerate(errors):
        if e <= ERROR_FLOOR:
            out[k] = f"round-off (error <= {ERROR_FLOOR:g})"
        elif res[k] is not None and e <= RESOLUTION_FACTOR * res[k]:
            out[k] = (f"within {RESOLUTION_FACTOR:g}x of the metric's resolution "
                      f"{res[k]:.2g}")
    threshold = nominal / 2 if nominal else 0.25
    start = None
    for k in range(n - 2, -1, -1):
        p = pairwise_order(dts[k], errors[k], dts[k + 1], errors[k + 1])
        if p is not None and p >= threshold:
            break
        start = k
    if start is not None:
        for k in range(start, n):
            if not out[k]:
                p = pairwise_order(dts[k - 1], errors[k - 1], dts[k], errors[k]) if k else None
                left = (f"order {p:.2f} from the previous step" if p is not None
                        else "the error stopped falling")
                out[k] = (f"error stopped falling ({left}; refinements below it reach less "
                          f"than half the nominal order {nominal})" if nominal else
                          f"error stopped falling ({left})")
    return out


def _same(a: float, b: float) -> bool:
    return abs(a - b) <= REL * max(abs(a), abs(b))


def _resolution_of(metrics: dict[str, Any], metric: str) -> float | None:
    names = [f"{metric}_resolution"]
    if metric.endswith("_error"):
        names.insert(0, metric[: -len("_error")] + "_resolution")
    for name in names:
        v = (metrics.get(name) or {}).get("value")
        if isinstance(v, int | float) and math.isfinite(v) and v > 0:
            return float(v)
    return None


def _nominal_order(engine: str, integrator: str) -> int | None:
    from crosscheck.names import integrator_info

    try:
        return integrator_info(engine, integrator).order
    except KeyError:
        return None


def analyse(cells: list[dict[str, Any]], metric: str | None = None,
            sweep_dts: list[float] | None = None, *, cap: float | None = None,
            width: float | None = None, searched: bool = False, stands: bool | None = None,
            floor: float | None = None) -> tuple[str | None, list[Series]]:
    """Group one case's cells by engine and integrator into convergence series.

    ``sweep_dts``: the sweep's steps; cells at other steps are frontier probes (``Series.probes``)
    that count for the stability frontier and :func:`cheapest` but not for the order. ``cap``,
    ``width`` and ``searched`` describe the frontier search for the words of ``frontier``;
    ``stands``: the case is a structure that must stand (:func:`stability`).
    """
    metric = pick_metric(cells, metric, stands)
    groups: dict[tuple[str, str], Series] = {}
    everything: dict[tuple[str, str], list[tuple[float, str]]] = {}
    for c in sorted(cells, key=lambda c: (c["engine"], c["integrator"], -c["dt"])):
        key = (c["engine"], c["integrator"])
        s = groups.setdefault(key, Series(*key))
        if c["status"] == "not_applicable":
            s.not_applicable = c.get("reason") or "not applicable"
            continue
        metrics = c.get("metrics") or {}
        m = metrics.get(metric or "", {})
        status = stability(c, stands)
        stable = status not in UNSTABLE
        error = m.get("value") if stable else None
        why = (m.get("not_measured") or "") if stable and error is None else ""
        dt = float(c["dt"])
        everything.setdefault(key, []).append((dt, status))
        s.runs.append(_run_record(c, dt, status))
        if sweep_dts is not None and not any(_same(dt, d) for d in sweep_dts):
            s.probes.append({"dt": dt, "status": status, "error": error,
                             "not_measured": why, "cost": c.get("cost")})
            continue
        s.dts.append(dt)
        s.errors.append(error)
        s.costs.append(c.get("cost"))
        s.statuses.append(status)
        s.not_measured.append(why)
        s.resolutions.append(_resolution_of(metrics, metric or "") if stable else None)
    for key, s in groups.items():
        s.nominal_order = _nominal_order(*key)
        _frontier(s, sorted(everything.get(key, []), reverse=True), cap, width, searched, floor)
        _order(s)
    return metric, list(groups.values())


def _run_record(cell: dict[str, Any], dt: float, status: str) -> dict[str, Any]:
    """dt, stability status, and the evidence: ``time`` (s) of the blow-up (the driver's failure
    time or ``blowup_time``) or of the fall (:func:`fall_time`), the ``energy_gain``, the
    ``rest_drift_max`` and the cell's own status and reason."""
    from crosscheck.report.overview import blowup_time

    metrics = cell.get("metrics") or {}
    time = None
    if status in ("blowup", "error", "timeout"):
        time = blowup_time(cell)
    elif status == "collapsed":
        time = fall_time(metrics)
    return {"dt": dt, "status": status, "cell_status": cell.get("status"), "time": time,
            "energy_gain": (metrics.get("energy_gain") or {}).get("value"),
            "rest_drift_max": (metrics.get("rest_drift_max") or {}).get("value"),
            "reason": ((cell.get("reason") or "").strip().splitlines() or [""])[0][:200]}


def _order(s: Series) -> None:
    idx = [k for k, (st, e) in enumerate(zip(s.statuses, s.errors, strict=True))
           if st not in UNSTABLE and e is not None]
    dts = [s.dts[k] for k in idx]
    errs = [s.errors[k] for k in idx]
    reasons = floor_reasons(dts, errs, [s.resolutions[k] for k in idx], s.nominal_order)
    s.floor = [""] * len(s.dts)
    for k, r in zip(idx, reasons, strict=True):
        s.floor[k] = r
    s.pairwise = [pairwise_order(d1, e1, d2, e2) for d1, e1, d2, e2 in
                  zip(dts[:-1], errs[:-1], dts[1:], errs[1:], strict=True)]
    use = [(d, e) for d, e, r in zip(dts, errs, reasons, strict=True) if not r]
    s.order_points = [d for d, _ in use]
    s.order = fit_order([d for d, _ in use], [e for _, e in use]) if len(use) >= 2 else None
    if s.order is None:
        s.order_points = []
        if any(reasons):
            s.order_note = "order not measurable: floor reached"
        elif not s.dts:
            s.order_note = ""
        else:
            s.order_note = "order not measurable: fewer than two measured stable steps"
    else:
        s.order_note = ""


def _frontier(s: Series, runs: list[tuple[float, str]], cap: float | None,
              width: float | None, searched: bool, floor: float | None = None) -> None:
    """Largest stable step (it and every smaller step run stable), the smallest unstable step
    above it, and the frontier in words."""
    s.largest_stable_dt = s.smallest_unstable_dt = None
    if not runs:
        return
    stable = [st not in UNSTABLE for _, st in runs]  # runs: decreasing dt
    for i in range(len(runs)):
        if all(stable[i:]):
            s.largest_stable_dt = runs[i][0]
            if i > 0:
                s.smallest_unstable_dt = runs[i - 1][0]
            break
    if s.largest_stable_dt is None:
        s.smallest_unstable_dt = runs[-1][0]
        s.frontier = f"< {runs[-1][0]:.4g} (unstable at every step run)"
        if searched and floor is not None:
            s.frontier = (f"< {runs[-1][0]:.4g} (unstable at every step run, halving down to "
                          f"the floor {floor:.4g} s)")
    elif s.smallest_unstable_dt is not None:
        lo, hi = s.largest_stable_dt, s.smallest_unstable_dt
        s.frontier = f"between {lo:.4g} and {hi:.4g} ({(hi - lo) / lo:.1%} wide)"
        if searched and width is not None and (hi - lo) / lo > width * (1 + 1e-6):
            s.frontier += (f"; wider than {width:.0%}: no whole step count lies between, or the "
                           "round limit")
    elif searched and cap is not None and s.largest_stable_dt >= cap * (1 - REL):
        s.frontier = (f">= {s.largest_stable_dt:.4g} (no failure up to the cap "
                      f"{cap:.4g} s)")
    elif searched:
        s.frontier = (f">= {s.largest_stable_dt:.4g} (no failure up to the largest step "
                      "tried; the round limit stopped the search)")
    else:
        s.frontier = f">= {s.largest_stable_dt:.4g} (no failure up to the largest step run)"


def points(s: Series) -> list[dict[str, Any]]:
    """Every run of a series, sweep steps and frontier probes: dt, status, error, cost."""
    out = [{"dt": d, "status": st, "error": e, "cost": c, "not_measured": nm}
           for d, st, e, c, nm in zip(s.dts, s.statuses, s.errors, s.costs, s.not_measured,
                                      strict=True)]
    return out + list(s.probes)


def cheapest(series: list[Series], target: float) -> dict[str, Any] | None:
    """The cheapest stable run whose measured error is at most ``target``: engine,
    integrator, dt, error, cost (wall s per simulated s); None when no run reaches it."""
    best = None
    for s in series:
        for p in points(s):
            e, c = p["error"], p["cost"]
            if (p["status"] in UNSTABLE or e is None or not math.isfinite(e) or e > target
                    or c is None or c <= 0):
                continue
            if best is None or c < best["cost"]:
                best = {"engine": s.engine, "integrator": s.integrator, "dt": p["dt"],
                        "error": e, "cost": c}
    return best


def pareto(series: list[Series]) -> list[tuple[str, float, float, float]]:
    """(label, dt, cost, error) points no other point beats in both cost and error."""
    from crosscheck.report.pareto import front

    pts = [(s.label, d, c, e) for s in series
           for d, c, e in zip(s.dts, s.costs, s.errors, strict=True)
           if c is not None and c > 0 and e is not None]
    return [pts[i] for i in front([(p[2], p[3]) for p in pts])]


def figure(case: str, metric: str | None, series: list[Series],
           target: float | None = None) -> bytes:
    """PNG: error against cost (with the Pareto front) and error against dt (the slope is the
    order), one colour and marker per engine-integrator (crosscheck.report.style). Points at
    the metric's floor are hollow and the floor itself is drawn (the round-off floor, and
    RESOLUTION_FACTOR x a metric's stated resolution); each series' stability frontier is a
    dotted vertical line at its largest stable step, and a strip under the dt panel brackets
    it (:func:`_frontiers`). Both axes of both panels are logarithmic with labelled ticks."""
    import matplotlib

    matplotlib.use("Agg", force=True)
    import matplotlib.pyplot as plt
    from matplotlib.lines import Line2D

    from crosscheck.report.figure import log_ticks, png
    from crosscheck.report.plots import FLOOR
    from crosscheck.report.style import Looks

    looks = Looks([s.label for s in series])
    strip = max(0.9, 0.16 * len(series))  # the stability strip: a row per series
    height = 4.6 + strip
    fig = plt.figure(figsize=(13.0, height))
    grid = fig.add_gridspec(2, 2, height_ratios=(4.0, strip))
    ax1 = fig.add_subplot(grid[:, 0])
    ax2 = fig.add_subplot(grid[0, 1])
    ax3 = fig.add_subplot(grid[1, 1], sharex=ax2)
    handles: dict[str, Any] = {}
    drawn = []
    for s in series:
        look = looks[s.label]
        pts = [(d, c, max(e, FLOOR), bool(f)) for d, c, e, f in
               zip(s.dts, s.costs, s.errors, s.floor or [""] * len(s.dts), strict=True)
               if e is not None]
        label = s.label + (f" (p={s.order:.2f})" if s.order is not None else "")
        handles[label] = Line2D([], [], color=look.color, marker=look.marker, markersize=5)
        for ax, xs in ((ax1, [c for _, c, _, _ in pts]), (ax2, [d for d, _, _, _ in pts])):
            keep = [(x, e, f) for x, (_, _, e, f) in zip(xs, pts, strict=True)
                    if x is not None and x > 0]
            if not keep:
                continue
            ax.plot([x for x, _, _ in keep], [e for _, e, _ in keep], color=look.color,
                    linewidth=1.2)
            for x, e, f in keep:
                ax.plot([x], [e], linestyle="none", marker=look.marker, markersize=6,
                        color=look.color, markerfacecolor="none" if f else look.color)
            drawn += [e for _, e, _ in keep]
    front = pareto(series)
    if front:
        ax1.step([p[2] for p in front], [max(p[3], FLOOR) for p in front], where="post",
                 color="k", linewidth=3, alpha=0.25)
        handles["Pareto front"] = Line2D([], [], color="k", linewidth=3, alpha=0.25)
    if target is not None:
        ax1.axhline(target, color="k", linestyle=":", linewidth=1)
        handles[f"target {target:g}"] = Line2D([], [], color="k", linestyle=":")
    for lo, hi, text in _floors(series, drawn):
        for ax in (ax1, ax2):
            if hi > lo:
                ax.axhspan(lo, hi, color="#999999", alpha=0.2, linewidth=0)
            else:
                ax.axhline(lo, color="#777777", linestyle="-.", linewidth=0.9)
        ax2.annotate(text, (0.0, hi), xycoords=("axes fraction", "data"), xytext=(3, 3),
                     textcoords="offset points", fontsize=7, color="#555555")
    _frontiers(ax2, ax3, series, looks)
    if any(s.largest_stable_dt for s in series):
        handles["largest stable dt (the stability frontier)"] = Line2D(
            [], [], color="#555555", linestyle=":")
    for ax, xlabel in ((ax1, "cost: wall s per simulated s"), (ax2, "dt (s)")):
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel(xlabel, fontsize=8)
        ax.set_ylabel(metric or "error", fontsize=8)
        ax.grid(True, which="major", alpha=0.3)
        ax.tick_params(labelsize=7)
        ax.margins(x=0.08, y=0.12)
    ax2.set_xlim(*_dt_range(series, ax2.get_xlim()))
    ax2.set_xlabel("")
    ax2.tick_params(labelbottom=False)
    ax3.set_xlabel("dt (s)", fontsize=8)
    for ax in (ax1, ax2):
        log_ticks(ax, "both")
    ax1.set_title("accuracy against cost (hollow: at the metric's floor)", fontsize=9)
    ax2.set_title("convergence: slope = order", fontsize=9)
    fig.legend(list(handles.values()), list(handles.keys()), loc="lower center",
               ncol=min(4, len(handles)), fontsize=7, frameon=False)
    rows = (len(handles) + 3) // 4
    fig.suptitle(f"{case}: sweep", fontsize=10)
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        fig.tight_layout(rect=(0, (0.2 * rows + 0.1) / height, 1, 1))
    data = png(fig, 90)
    plt.close(fig)
    return data


def _floors(series: list[Series], drawn: list[float]) -> list[tuple[float, float, str]]:
    """The floors in play as (low, high, words): round-off when some point is near it (a
    line), and RESOLUTION_FACTOR x the metric's resolution (errors below it are at the floor):
    a line, or a band when the resolution differs between runs (a flip period's crossing
    interpolation resolves differently in each run)."""
    out = []
    if drawn and min(drawn) < 1e3 * ERROR_FLOOR:
        out.append((ERROR_FLOOR, ERROR_FLOOR, f"round-off floor {ERROR_FLOOR:g}"))
    res = sorted({r for s in series for r in s.resolutions if r})
    if res:
        lo, hi = RESOLUTION_FACTOR * res[0], RESOLUTION_FACTOR * res[-1]
        span = f"{lo:.2g}" if hi <= lo * 1.01 else f"{lo:.2g} to {hi:.2g}"
        out.append((lo, hi if hi > lo * 1.01 else lo,
                    f"floor: {RESOLUTION_FACTOR:g} x the metric's resolution ({span})"))
    return out


def _dt_range(series: list[Series], current: tuple[float, float]) -> tuple[float, float]:
    """The dt axis covers every step run and every frontier step, with a margin."""
    dts = [d for s in series for d in [*s.dts, *(p["dt"] for p in s.probes),
                                       s.largest_stable_dt, s.smallest_unstable_dt] if d]
    if not dts:
        return current
    return min(min(dts) / 1.3, current[0]), max(max(dts) * 1.3, current[1])


def _frontiers(ax, strip, series: list[Series], looks) -> None:
    """The stability frontier: a dotted line on the convergence panel at each series' largest
    stable step, and in the strip below a row per series: a bar from its largest stable step
    to its smallest unstable one (x), a triangle when nothing failed up to the largest step
    tried, an x alone when every step blew up, "n/a" when it could not run."""
    for j, s in enumerate(series):
        look = looks[s.label]
        lo, hi = s.largest_stable_dt, s.smallest_unstable_dt
        if lo:
            ax.axvline(lo, color=look.color, linestyle=":", linewidth=1.2)
            strip.plot([lo], [j], marker="|", markersize=9, color=look.color)
        if lo and hi:
            strip.plot([lo, hi], [j, j], color=look.color, linewidth=4, solid_capstyle="butt")
        if hi:
            strip.plot([hi], [j], marker="x", markersize=7, color=look.color)
        elif lo:
            strip.plot([lo], [j], marker=">", markersize=7, color=look.color)
        if s.not_applicable:
            strip.annotate("n/a", (0.01, j), xycoords=("axes fraction", "data"), fontsize=6,
                           va="center")
    strip.set_yticks(range(len(series)), [s.label for s in series], fontsize=6)
    strip.set_ylim(len(series) - 0.5, -0.5)
    strip.set_ylabel("stability", fontsize=8)
    strip.tick_params(axis="x", labelsize=7)
    strip.grid(True, axis="x", alpha=0.3)


def _short(reason: str) -> str:
    return reason.split(" (")[0][:40]


def table(metric: str | None, series: list[Series], target: float | None = None) -> str:
    """Markdown: per engine and integrator the errors per step, the order over the asymptotic
    points, the stability frontier; then the notes (left-out points, unmeasured cells, probes)
    and the answer to ``--target``."""
    dts = sorted({d for s in series for d in s.dts}, reverse=True)
    head = ("| engine-integrator | " + " | ".join(f"dt={d:g}" for d in dts)
            + " | order (asymptotic points) | pairwise | stability frontier (dt) |")
    lines = [f"Error metric: `{metric}`. `(floor)`: at the metric's floor, left out of the "
             "order (see the notes).", "", head, "|" + "---|" * (len(dts) + 4)]
    notes: list[str] = []
    for s in series:
        if s.not_applicable:
            lines.append(f"| {s.label} | " + " | ".join("n/a" for _ in dts)
                         + f" | n/a | n/a | not applicable: {s.not_applicable[:60]} |")
            continue
        by_dt = {d: k for k, d in enumerate(s.dts)}
        cells = []
        for d in dts:
            k = by_dt.get(d)
            if k is None:
                cells.append("not run")
                continue
            st, e = s.statuses[k], s.errors[k]
            if st in UNSTABLE:
                cells.append(st.upper())
            elif e is None:
                why = s.not_measured[k] if k < len(s.not_measured) else ""
                cells.append(f"not measured: {_short(why)}" if why else "not measured")
            else:
                cells.append(f"{e:.3g}" + (" (floor)" if s.floor and s.floor[k] else ""))
        pw = ", ".join("-" if p is None else f"{p:.2f}" for p in s.pairwise) or \
            "none: fewer than two measured steps"
        if s.order is not None:
            order = (f"{s.order:.2f} (dt " + ", ".join(f"{d:g}" for d in s.order_points) + ")")
        else:
            order = s.order_note
        lines.append(f"| {s.label} | " + " | ".join(cells) + f" | {order or 'no steps run'} "
                     f"| {pw} | {s.frontier or 'no steps run'} |")
        left = [f"dt={d:g}: {r}" for d, r in zip(s.dts, s.floor, strict=True) if r]
        if left:
            notes.append(f"- {s.label}: left out of the order: " + "; ".join(left))
        unmeasured = sorted({r for r in s.not_measured if r})
        for r in unmeasured:
            at = [f"{d:g}" for d, x in zip(s.dts, s.not_measured, strict=True) if x == r]
            notes.append(f"- {s.label}: not measured at dt = {', '.join(at)}: {r}")
        if s.probes:
            notes.append(f"- {s.label}: frontier probes: " + ", ".join(
                f"{p['dt']:.4g} {p['status']}" for p in s.probes))
    if notes:
        lines += ["", "Notes:", "", *notes]
    if target is not None:
        lines += ["", target_text(metric, series, target)]
    return "\n".join(lines)


def target_text(metric: str | None, series: list[Series], target: float) -> str:
    best = cheapest(series, target)
    if best is None:
        return (f"Target `{metric}` <= {target:g}: none reaches it (no stable run with a "
                "measured error at or below it).")
    return (f"Target `{metric}` <= {target:g}: cheapest is {best['engine']} "
            f"{best['integrator']} at dt = {best['dt']:.4g} (error {best['error']:.3g}, "
            f"cost {best['cost']:.3g} wall s per simulated s).")
