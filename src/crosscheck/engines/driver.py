"""The one run driver: sampling, recording, blow-up detection and cost, the same for every engine.

A run is two passes over sessions the adapter opens (engines/session.py):

* **Accuracy pass** (:func:`record`): the scene's t = 0 state, then ``advance(k)`` and
  ``read_raw()`` at every sample of the sampling plan (or the session's fused fast path, which
  must fill the same rows), the rows converted to crosscheck's convention once at the end. A
  step the engine reports as failed, a non-finite sample, or the total energy running away
  beyond ``runaway_factor`` times what the scene can exchange ends the run there: the
  Trajectory holds the samples before it and ``meta["failure"] = {"time", "reason"}``.
* **Cost pass** (:func:`measure_cost`): fresh sessions, no recording. Each repetition opens a
  session, takes one warm-up step (compilation, caches and first-call allocations happen there,
  never in the timed region), then times ``advance(steps)`` over the steps the accuracy pass
  took, wall clock and process CPU time. Repeated until at least ``min_repeats`` runs and
  ``min_seconds`` of timed stepping (or ``budget_seconds`` of it); reported as minimum, median
  and maximum. docs/metrics.md defines cost from these figures.

The driver never raises for a blow-up: failure is data.
"""

from __future__ import annotations

import math
import statistics
import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from crosscheck.engines.base import SamplingPlan, sampling_plan
from crosscheck.engines.session import Session, StepFailure
from crosscheck.rotations import sign_continuous
from crosscheck.scene.model import Scene
from crosscheck.state import Trajectory

# |E(t) - E(0)| > RUNAWAY_FACTOR * energy_scale stops a run as a blow-up. energy_scale bounds the
# energy the scene can exchange (initial kinetic and spring energy plus the work gravity and the
# loads can do in the run), so no physical run comes near; the comparer flags blow-ups from 10x
# on, and this much larger factor only marks where a run that has already exploded is cut.
RUNAWAY_FACTOR = 1e6


class WouldTimeOut(Exception):
    """The run's steps, at the speed measured on its first ones, would take longer than the
    cell's timeout: said before the run starts, instead of being killed at the deadline."""


# Steps timed (after a warm-up step) to predict a run's length against its timeout, and the
# margin the prediction must exceed the timeout by before the run is refused (a first-steps
# speed is a guess: contact piles get slower as they settle, a fluid's steps vary).
PREDICT_STEPS = 200
PREDICT_MARGIN = 2.0


def predict_seconds(session: Session, total_steps: int) -> tuple[float, int, float]:
    """(predicted seconds for total_steps, steps timed, seconds they took), from
    ``PREDICT_STEPS`` steps after one warm-up step on a scratch session."""
    n = min(PREDICT_STEPS, total_steps)
    try:
        session.advance(1)
        t0 = time.perf_counter()
        session.advance(n)
        took = time.perf_counter() - t0
    except StepFailure:
        return 0.0, 0, 0.0
    return took / max(n, 1) * total_steps, n, took


@dataclass(frozen=True)
class CostPlan:
    """How the cost pass repeats: at least ``min_repeats`` timed runs and ``min_seconds`` of
    timed stepping, at most ``max_repeats`` runs, and no new run once ``budget_seconds`` of
    timed stepping are spent (a long fluid run is then timed fewer than min_repeats times,
    and the report says how many); and the model its spread is computed from
    (:func:`cost_spread`, docs/metrics.md "Cost")."""

    min_repeats: int = 3
    min_seconds: float = 0.2
    max_repeats: int = 50
    budget_seconds: float = 15.0
    # The runner spreads a rigid cell's cost pass over this many tasks, each timing this plan
    # later in the run in a process of its own (the local backend's cost rounds), and pools
    # them (merge_costs): a process's own timing offset (code and array placement) and the
    # machine's load at the time are then sampled inside the run instead of only between
    # runs. The driver itself times one process.
    processes: int = 3
    # The spread is the half-width of a prediction interval with this coverage for the log
    # ratio of the cell's figure in this run and in another run on the same machine
    # (cost_spread; docs/metrics.md "Cost").
    coverage: float = 0.95
    # Its prior, fitted on three sets of three fresh runs of the 80 committed rigid cells on
    # the shared 2-CPU CI machine (benchmarks/results/cost_prior.md, fit_cost_prior.py:
    # maximum likelihood 0.012 to 0.027 and 0.5 to 0.7 degrees of freedom): the standard
    # deviation of the log of one pass's figure about the cell's, as a scaled inverse
    # chi-square with ``prior_dof`` degrees of freedom (a heavy tail: some cells' passes
    # scatter by tens of per cent) that the passes' own scatter updates; and the standard
    # deviation of a whole run's log offset (the machine's state over the run, which no pass
    # of the run can see; all cells' median shift between two runs measured 0.4 to 2.6 %).
    prior_sd: float = 0.015
    prior_dof: float = 1.0
    run_sd: float = 0.012


@dataclass
class Cost:
    """Timed stepping of one run: seconds per repetition, wall and process CPU."""

    steps: int
    simulated: float  # s of simulated time the timed steps cover
    wall: list[float] = field(default_factory=list)
    cpu: list[float] = field(default_factory=list)
    note: str = ""

    def to_dict(self, plan: CostPlan | None = None, spread: bool = True) -> dict[str, Any]:
        """The figures docs/metrics.md defines ("Cost"), of this one process's pass (without
        the spread with ``spread=False``)."""
        if not self.wall or self.simulated <= 0:
            return {"steps": self.steps, "simulated_time": self.simulated, "repeats": 0,
                    "note": self.note or "nothing was timed"}
        w_min, w_med, w_max = min(self.wall), statistics.median(self.wall), max(self.wall)
        per = 1.0 / self.simulated
        spread = (cost_spread([self.wall], [self.cpu], plan=plan) if spread else
                  {"spread": None, "spread_median": None})
        return {
            "steps": self.steps,
            "simulated_time": self.simulated,
            "repeats": len(self.wall),
            "wall_min": w_min, "wall_median": w_med, "wall_max": w_max,
            "cpu_min": min(self.cpu), "cpu_median": statistics.median(self.cpu),
            "per_simulated_second": w_min * per,
            "per_simulated_second_median": w_med * per,
            "cpu_per_simulated_second": min(self.cpu) * per,
            # The spreads: half-widths of the prediction intervals of cost_spread (of the
            # minimum, and of the median), and the full range relative to the minimum.
            "spread": spread["spread"], "spread_median": spread["spread_median"],
            "spread_model": spread,
            "range": (w_max - w_min) / w_min if w_min > 0 else 0.0,
            "us_per_step": 1e6 * w_min / self.steps if self.steps else None,
            "note": self.note,
            "processes": 1,
            "wall_samples": list(self.wall),
            "cpu_samples": list(self.cpu),
        }


def merge_costs(parts: list[dict[str, Any]], plan: CostPlan | None = None) -> dict[str, Any]:
    """One cost from the cost passes of several processes (``Cost.to_dict`` of each, with the
    ``pid`` that timed it when known). The figures are the geometric means over the passes of
    each pass's minimum and median (every pass weighs the same, however many repetitions it
    took, so a cell timed in one pass and one timed in three estimate the same thing), and the
    spread the prediction half-width of :func:`cost_spread` from the passes' scatter. Parts
    that timed nothing are left out; the repetitions are kept, pooled, in ``wall_samples``."""
    timed = [p for p in parts if p.get("repeats") and p.get("wall_samples")]
    if not timed:
        return dict(parts[0]) if parts else {}
    first = timed[0]
    cost = Cost(steps=first["steps"], simulated=first["simulated_time"],
                wall=[w for p in timed for w in p["wall_samples"]],
                cpu=[c for p in timed for c in p["cpu_samples"]],
                note="; ".join(dict.fromkeys(p["note"] for p in timed if p.get("note"))))
    out = cost.to_dict(plan, spread=False)
    walls = [p["wall_samples"] for p in timed]
    pids = [p.get("pid") for p in timed]
    minima = [min(w) for w in walls]
    medians = [statistics.median(w) for w in walls]
    w_min, w_med = _geomean(minima), _geomean(medians)
    cpu_min = _geomean([min(p["cpu_samples"]) for p in timed])
    per = 1.0 / out["simulated_time"]
    spread = cost_spread(walls, [p["cpu_samples"] for p in timed],
                         pids if all(p is not None for p in pids) else None, plan)
    out.update(processes=len(timed), wall_min=w_min, wall_median=w_med, cpu_min=cpu_min,
               per_simulated_second=w_min * per, per_simulated_second_median=w_med * per,
               cpu_per_simulated_second=cpu_min * per,
               us_per_step=1e6 * w_min / out["steps"] if out["steps"] else None,
               pooled_min=min(cost.wall), pooled_median=statistics.median(cost.wall),
               spread=spread["spread"], spread_median=spread["spread_median"],
               spread_model=spread,
               process_minima=minima, process_medians=medians, process_repeats=[
                   len(w) for w in walls], process_pids=pids)
    return out


def cost_spread(passes: list[list[float]], cpus: list[list[float]] | None = None,
                pids: list | None = None, plan: CostPlan | None = None) -> dict[str, Any]:
    """The spread of a cell's cost from its passes' timed repetitions (s, wall clock), one list
    per pass, with their process CPU times when known (docs/metrics.md "Cost", "Spread").

    For each figure (a pass's minimum, and its median), with x_j the log of pass j's figure and
    the run's figure exp(mean x_j), the model is

        x_j = true + run offset (sd ``run_sd``, the machine's state over the run, which no
              pass can see) + pass offset (process placement, load at the time; sd sigma)

    sigma^2 is estimated from the passes' scatter updated from the prior (``prior_sd`` with
    ``prior_dof`` degrees of freedom): s^2 = (dof0 prior_sd^2 + sum (x_j - mean)^2) /
    (dof0 + k - 1); for the median floored by the variance a pass's median has from its own
    repetitions' scatter ((pi/2) (IQR / 1.349 / median)^2 / n; a minimum's own noise is far
    smaller, and in the passes' scatter). The log ratio of this run's figure to an
    independent rerun's (as many passes) is then sqrt(2) run_sd Z + sqrt(2 s^2 / k_eff) T,
    Z standard normal (the run offsets) and T Student t with dof0 + k - 1 degrees of freedom
    (the passes' mean offsets, their scale estimated): the half-width is the two-sided
    ``coverage`` quantile of that sum, plus the load this run measured: the mean over passes of
    log(wall / CPU time) of the figure (time the process spent waiting for a CPU; 0 where CPU
    time is not below wall time, as with several threads), which a rerun on a quieter machine
    would not see.
    k_eff is the number of distinct processes among the passes when ``pids`` are given
    (passes in one process share its placement), else the number of passes. ``spread`` is the
    minimum's half-width and ``spread_median`` the median's, relative: a rerun's figure lies
    within a factor exp(+-spread) of this one with probability ``coverage`` under the model.
    """
    plan = plan or CostPlan()
    keep = [j for j, w in enumerate(passes) if w and min(w) > 0]
    walls = [list(passes[j]) for j in keep]
    cpus = [list(cpus[j]) for j in keep] if cpus is not None else [[] for _ in keep]
    k = len(walls)
    k_eff = max(1, min(k, len({pids[j] for j in keep}))) if pids else max(k, 1)
    dof = plan.prior_dof + max(k - 1, 0)
    floor = statistics.fmean(_median_variance(w) for w in walls) if walls else 0.0
    out: dict[str, Any] = {"passes": k, "processes": k_eff, "dof": dof,
                           "coverage": plan.coverage, "within_sd": math.sqrt(floor)}
    for name, figure in (("min", min), ("median", statistics.median)):
        x = [math.log(figure(w)) for w in walls]
        ss = sum((v - statistics.fmean(x)) ** 2 for v in x) if k > 1 else 0.0
        s2 = (plan.prior_dof * plan.prior_sd ** 2 + ss) / dof if dof > 0 else math.inf
        if name == "median":
            s2 = max(s2, floor)
        # the passes' part (Student t, its scale estimated) plus the run's (normal, known)
        half = _t_plus_normal_quantile(math.sqrt(2 * s2 / k_eff), math.sqrt(2) * plan.run_sd,
                                       dof, plan.coverage)
        load = statistics.fmean(max(0.0, math.log(figure(w) / figure(c))) if c and figure(c) > 0
                                else 0.0 for w, c in zip(walls, cpus, strict=True)) if k else 0.0
        out[f"{name}_between_sd"] = math.sqrt(ss / (k - 1)) if k > 1 else None
        out[f"{name}_load"] = load
        out[f"{name}_half_width"] = half + load
    out["spread"] = out["min_half_width"]
    out["spread_median"] = out["median_half_width"]
    return out


def _t_plus_normal_quantile(a: float, b: float, dof: float, coverage: float) -> float:
    """h with P(|a T + b Z| <= h) = coverage, T Student t with dof degrees of freedom and Z
    standard normal, independent: the normal integrated out by Gauss-Hermite quadrature, h
    found by bisection."""
    from scipy.special import ndtri, stdtr, stdtrit  # scipy.stats imports far more

    p = 0.5 + coverage / 2
    if not (math.isfinite(a) and dof > 0):
        return math.inf
    if b <= 0:
        return a * float(stdtrit(dof, p))
    if a <= 0:
        return b * float(ndtri(p))
    z, w = np.polynomial.hermite_e.hermegauss(32)
    w = w / w.sum()

    def miss(h: float) -> float:
        return float(np.sum(w * (stdtr(dof, (-h - b * z) / a) + 1 - stdtr(dof, (h - b * z) / a))))

    # Adding independent symmetric unimodal noise only widens: the larger of the two parts'
    # own quantiles bounds h from below, their sum (almost always) from above.
    qt, qz = a * float(stdtrit(dof, p)), b * float(ndtri(p))
    lo, hi = max(qt, qz), qt + qz
    while miss(hi) > 1 - coverage:
        lo, hi = hi, 2 * hi
    while hi - lo > 1e-4 * hi:
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if miss(mid) > 1 - coverage else (lo, mid)
    return hi


def _median_variance(wall: list[float]) -> float:
    """Variance of the log of a pass's median from its repetitions' scatter alone:
    (pi/2) sigma^2 / n with sigma = IQR / 1.349 relative to the median (0 below 2 samples)."""
    med = statistics.median(wall)
    if len(wall) < 2 or med <= 0:
        return 0.0
    sigma = _iqr(wall) / 1.349 / med
    return math.pi / 2 * sigma ** 2 / len(wall)


def _geomean(values: list[float]) -> float:
    return math.exp(statistics.fmean(math.log(v) for v in values)) if all(
        v > 0 for v in values) else statistics.fmean(values)


def _iqr(values: list[float]) -> float:
    if len(values) < 2:
        return 0.0
    q1, _, q3 = statistics.quantiles(values, n=4, method="inclusive")
    return q3 - q1


@dataclass
class RunResult:
    """What one run of one engine on one scene produced: a Trajectory (rigid bodies), a
    FluidRecord (a fluid), or both for a fluid scene with a coupled body (the body's motion
    as a normalised Trajectory beside the record, :func:`body_trajectory`); and its cost."""

    trajectory: Trajectory | None = None
    fluid: Any = None  # crosscheck.sim.fluid.FluidRecord
    cost: Cost | None = None

    @property
    def output(self):
        """The primary output: the FluidRecord of a fluid scene, else the Trajectory."""
        return self.fluid if self.fluid is not None else self.trajectory

    @property
    def failure(self) -> dict | None:
        out = self.output
        return None if out is None else getattr(out, "failure", None)


# -- blow-up detection ---------------------------------------------------------------------------
def energy_scale(scene: Scene, first: Trajectory) -> float:
    """A generous bound on the energy the scene can exchange in its run (see RUNAWAY_FACTOR)."""
    from crosscheck.quantities import exchangeable_energy

    return max(exchangeable_energy(scene, first), 1e-12)


def _trajectory(scene: Scene, t: np.ndarray, arrays, extras, meta) -> Trajectory:
    com, rot, vel, omega = arrays
    traj = Trajectory(t=t, com=com, vel=vel, omega=omega, meta=meta,
                      extras={k: np.asarray(v) for k, v in (extras or {}).items()})
    if scene.dimension == 3:
        traj.quat = sign_continuous(rot)
    else:
        # The engine's accumulated (continuous) angle. No np.unwrap: it assumes less than half a
        # turn between samples and would fold a fast spin sampled coarsely back by 2 pi.
        traj.angle = rot
    return traj


def _runaway(scene: Scene, traj: Trajectory, factor: float) -> tuple[int | None, str, float]:
    """(index of the first sample whose energy ran away or None, reason, energy scale)."""
    from crosscheck.quantities import total_energy

    if not len(traj.t):
        return None, "", float("nan")
    first = Trajectory(t=traj.t[:1], com=traj.com[:1], vel=traj.vel[:1], omega=traj.omega[:1],
                       quat=None if traj.quat is None else traj.quat[:1],
                       angle=None if traj.angle is None else traj.angle[:1])
    scale = energy_scale(scene, first)
    energy = total_energy(scene, traj)
    bad = np.flatnonzero(~(np.abs(energy - energy[0]) <= factor * scale))
    if not bad.size:
        return None, "", scale
    j = int(bad[0])
    return j, (f"energy runaway: |E - E0| = {abs(energy[j] - energy[0]):.3g} J > {factor:g} x "
               f"energy scale {scale:.3g} J"), scale


# -- the accuracy pass ---------------------------------------------------------------------------
def _record_generic(session: Session, rows: np.ndarray, plan: SamplingPlan, first: int = 1
                    ) -> tuple[int, str | None]:
    """rows[first - 1] holds the current state (written here when first == 1); then the plan's
    steps and a read per row. Returns (valid rows, failure reason or None); rows from the
    failure on are not valid."""
    if first == 1:
        rows[0] = session.read_raw()
    advance, read = session.advance, session.read_raw
    isfinite = math.isfinite
    for i in range(first, len(rows)):
        try:
            advance(plan.steps_before(i))
        except StepFailure as exc:
            return i, str(exc)
        row = rows[i]
        row[:] = read()
        # One sum decides for a finite row (NaN and inf propagate); an overflow of the sum
        # itself is resolved by the exact test.
        if not isfinite(row.sum()) and not np.isfinite(row).all():
            return i, "non-finite state"
    return len(rows), None


def record(session: Session, scene: Scene, plan: SamplingPlan, *,
           runaway_factor: float = RUNAWAY_FACTOR, fused: bool = True, label: str = ""
           ) -> tuple[Trajectory, int]:
    """The accuracy pass on an open session. Returns (Trajectory, steps taken to its last
    sample); ``meta`` holds the failure, ``effective`` settings and the blow-up criterion."""
    n, k = plan.n_samples, plan.steps_per_sample
    rows = np.empty((n, session.row_width))
    problems = list(session.check())
    if problems:
        rows[0] = session.read_raw()
        count, reason = 1, f"{label or 'engine'} settings: " + "; ".join(problems)
        failure_time = 0.0
    else:
        fast = getattr(session, "record", None) if fused else None
        if fast is not None and getattr(session, "fused", False):
            # The fast path takes the whole intervals; a shorter final one is the generic
            # loop's.
            regular = plan.total_steps // k + 1
            count, reason = fast(regular, k, rows[:regular])
            finite = np.isfinite(rows[:count]).all(axis=1)
            if not finite.all():  # engines' own checks may let a non-finite sample through
                count, reason = int(np.argmin(finite)), "non-finite state"
            if reason is None and regular < n:
                count, reason = _record_generic(session, rows, plan, first=regular)
        else:
            count, reason = _record_generic(session, rows, plan)
        failure_time = plan.time(count) if reason else None
    t = plan.times(count)
    arrays, extras = session.convert(rows[:count], t)
    traj = _trajectory(scene, t, arrays, extras, {})
    j, why, scale = _runaway(scene, traj, runaway_factor)
    if j is not None:
        traj = _trajectory(scene, t[:j], tuple(a[:j] for a in arrays),
                           {key: v[:j] for key, v in extras.items()}, {})
        failure_time, reason, count = float(t[j]), why, j
    traj.meta["failure"] = (None if reason is None
                            else {"time": float(failure_time), "reason": reason})
    traj.meta["effective"] = dict(session.effective(tuple(a[:count] for a in arrays)),
                                  steps_per_sample=k)
    traj.meta["blowup_criterion"] = {
        "non_finite": "any non-finite value in a sample",
        "engine": "a step the engine reports as failed",
        "runaway_factor": runaway_factor, "energy_scale": scale}
    steps = plan.steps_at(count - 1) if count else 0
    traj.meta["steps"] = steps
    return traj, steps


# -- the cost pass -------------------------------------------------------------------------------
def measure_cost(open_session, steps: int, dt: float | None, plan: CostPlan = CostPlan()
                 ) -> Cost:
    """Time ``advance(steps)`` on fresh sessions from ``open_session()``, after a warm-up step.

    The simulated time covered is ``steps * dt``, or for a session with its own clock
    (``session.time``, adaptive steps) the span it advanced in the timed region.
    """
    cost = Cost(steps=steps, simulated=steps * dt if dt else 0.0)
    if steps <= 0:
        cost.note = "no step was taken (the run failed at its first sample)"
        return cost
    wall_clock, cpu_clock = time.perf_counter, time.process_time
    spent = 0.0
    while len(cost.wall) < plan.max_repeats:
        session = open_session()
        try:
            try:
                session.advance(1)  # warm-up: compilation and first-call work happen here
            except StepFailure:
                pass
            start = getattr(session, "time", None)
            c0, w0 = cpu_clock(), wall_clock()
            try:
                session.advance(steps)
            except StepFailure:
                pass  # the time until the engine gave up is the time this run takes
            wall, cpu = wall_clock() - w0, cpu_clock() - c0
            if start is not None:  # a session with its own clock (adaptive steps): its span
                cost.simulated = session.time - start
        finally:
            session.close()
        cost.wall.append(wall)
        cost.cpu.append(cpu)
        spent += wall
        if len(cost.wall) >= plan.min_repeats and spent >= plan.min_seconds:
            break
        if spent >= plan.budget_seconds:
            cost.note = (f"stopped after {len(cost.wall)} repetition(s): the timing budget of "
                         f"{plan.budget_seconds:g} s was spent")
            break
    return cost


# -- one run -------------------------------------------------------------------------------------
def run(engine, scene: Scene, integrator: str, dt: float, *,
        cost: CostPlan | None = CostPlan(), fused: bool = True,
        timeout: float | None = None) -> RunResult:
    """Both passes of one engine on one scene. ``cost=None`` skips the cost pass. With a
    ``timeout`` (s), a rigid run whose steps would clearly take longer is refused before it
    starts (WouldTimeOut, with the prediction)."""
    from crosscheck.errors import EngineUnavailable

    reason = engine.not_applicable(scene, integrator)
    if reason is not None:
        raise EngineUnavailable(f"{engine.name}: {reason}")
    # A fluid scene is the grid fluid's, unless the engine stands for it by a stateless medium
    # (MuJoCo's mapped cylinder, scene/medium_map.py): then it is run as a rigid scene whose
    # Trajectory is the body's, in the fluid case's 2D convention.
    if scene.fluid is not None and not engine.maps_fluid(scene):
        return _run_fluid(engine, scene, integrator, dt, cost)
    plan = sampling_plan(scene, dt)
    # Runs of under ten times the steps the prediction takes are simply run.
    if timeout is not None and plan.total_steps > 10 * PREDICT_STEPS:
        scratch = engine.open(scene, integrator, dt)
        try:
            predicted, n, took = predict_seconds(scratch, plan.total_steps)
        finally:
            scratch.close()
        if predicted > PREDICT_MARGIN * timeout:
            raise WouldTimeOut(
                f"{plan.total_steps} steps would take about {predicted:.3g} s at the speed of "
                f"the first {n} ({1e6 * took / n:.3g} us/step), more than {PREDICT_MARGIN:g} x "
                f"the cell's timeout of {timeout:g} s: not started")
    session = engine.open(scene, integrator, dt)
    try:
        traj, steps = record(session, scene, plan, fused=fused, label=engine.name,
                             runaway_factor=engine.runaway_factor(scene))
    finally:
        session.close()
    meta = engine.base_meta(scene, integrator, dt)
    meta.update(traj.meta)
    traj.meta = meta
    result = RunResult(trajectory=traj)
    if cost is not None:
        result.cost = measure_cost(lambda: engine.open(scene, integrator, dt), steps, dt, cost)
        traj.meta["cost"] = result.cost.to_dict(cost)
    return result


def _run_fluid(engine, scene: Scene, integrator: str, dt: float, cost: CostPlan | None
               ) -> RunResult:
    """A fluid scene: the session records its own samples (adaptive steps land on them);
    the cost pass times the same number of steps without recording."""
    session = engine.open_fluid(scene, integrator, dt)
    try:
        record_ = session.record()
        steps = len(session.dts)
    finally:
        session.close()
    for key, value in engine.base_meta(scene, integrator, dt).items():
        record_.meta.setdefault(key, value)
    result = RunResult(fluid=record_, trajectory=body_trajectory(engine, scene, integrator, dt,
                                                                 record_))
    if cost is not None:
        result.cost = measure_cost(lambda: engine.open_fluid(scene, integrator, dt), steps,
                                   None, cost)
        record_.meta["cost"] = result.cost.to_dict(cost)
    return result


def body_trajectory(engine, scene: Scene, integrator: str, dt: float, record
                    ) -> Trajectory | None:
    """The coupled bodies' motion in a FluidRecord as a normalised Trajectory (None without
    bodies): the record's samples, centre of mass and its velocity (world, +y up), the
    continuous angle (rad, counter-clockwise) and the angular velocity; masses and inertias
    per metre of depth (docs/cases.md, "Bodies in a fluid case"), the run's failure."""
    names = [b["name"] for b in (record.meta.get("bodies") or [])]
    s = record.series
    if not names or any(f"body_x.{n}" not in s for n in names):
        return None

    def col(key):  # (T, N)
        return np.stack([np.asarray(s[f"body_{key}.{n}"], float) for n in names], axis=1)

    meta = engine.base_meta(scene, integrator, dt)
    meta.update(failure=record.failure, coupled_with_fluid=True, mass_per="metre of depth",
                steps=(record.meta.get("dt") or {}).get("steps"))
    return Trajectory(t=np.asarray(record.t, float),
                      com=np.stack([col("x"), col("y")], axis=-1),
                      vel=np.stack([col("vx"), col("vy")], axis=-1),
                      omega=col("omega"), angle=col("angle"), meta=meta)
