"""A fluid scene run sample by sample: the in-house fluid's session for the run driver.

:class:`FluidRun` owns the time loop around ``FluidState.step``: the step size (CFL or fixed),
landing on the sample times, and the checks that end a run (non-finite values, a collapsed or
exceeded CFL step, lost fluid). Two ways through it, taking the same steps:

* ``record()``: the accuracy pass, measuring scalar series at every sample and field snapshots
  every ``field_every``, into a :class:`FluidRecord`;
* ``advance(n)``: n steps and nothing else, what the driver times for cost (engines/driver.py).

The steps do not depend on what is recorded (the step size depends on the state, the next
sample time and the duration only), so both passes step the same sequence.
"""

from __future__ import annotations

import math
import time
from typing import Any

import numba
import numpy as np

from crosscheck.errors import StepFailure
from crosscheck.sim.fluid.boundary import SolidStop
from crosscheck.sim.fluid.record import FluidRecord
from crosscheck.sim.fluid.solver import (
    DEFAULT_INTEGRATOR,
    INTEGRATORS,
    PHASES,
    FluidState,
    _scene_gravity,
    fluid_threads,
)


class FluidStop(Exception):
    """A run ended by one of the fluid's checks; ``time`` is when."""

    def __init__(self, time: float, reason: str):
        super().__init__(reason)
        self.time = time
        self.reason = reason


class FluidRun:
    """``scene.fluid`` with one in-house integrator, at its t = 0 state."""

    def __init__(self, scene: Any, integrator: str | None = None, dt: float | None = None):
        spec = self.spec = scene.fluid
        self.scene = scene
        name = self.name = integrator or DEFAULT_INTEGRATOR
        if name not in INTEGRATORS:
            raise ValueError(f"unknown fluid integrator {name!r}; known: {sorted(INTEGRATORS)}")
        self.scheme = INTEGRATORS[name]
        run = scene.run
        self.duration = float(run.duration)
        max_dt = float(run.dt) if getattr(run, "dt", None) else self.duration / 100.0
        if dt is not None:
            max_dt = float(dt)
        self.max_dt = max_dt
        self.fixed = spec.time_step == "fixed"
        self.sample_every = float(getattr(run, "sample_every", None) or max_dt)
        self.gravity = _scene_gravity(scene, spec.dimension)
        t_build = time.perf_counter()
        with _threads():
            self.st = FluidState(spec, self.gravity, self.scheme)
        self.build_time = time.perf_counter() - t_build
        self.timers = {p: 0.0 for p in PHASES}
        self.time = 0.0
        self.next_sample = self.sample_every
        # How close to a sample time (or the end) counts as there. The clock is a running sum
        # of steps, so it lands off the sample times by round-off that grows with the number of
        # steps: 1.5e-13 s after 12000 steps of 1.25e-4 s, which a tolerance of 1e-9 of the
        # sample interval did not cover, and the run then took a last step of 1.5e-13 s whose
        # body force (a momentum change over that step) read 1e10 N. A millionth of the
        # smaller of the step and the sample interval covers the round-off, and no real step is
        # shorter (the CFL step stops the run below a millionth of the largest step).
        self.eps = 1e-6 * min(self.sample_every, self.max_dt)
        self.g_mag = float(np.linalg.norm(self.gravity))
        self.dts: list[float] = []
        self.iters: list[int] = []
        self.cfl_seen = 0.0
        self.unconverged = 0

    # -- stepping ------------------------------------------------------------------------
    def _step_size(self) -> float:
        """The next step, or FluidStop when the state or the step forbids one."""
        st, spec, t = self.st, self.spec, self.time
        if st.unsupported:
            raise FluidStop(t, st.unsupported)
        umax = st.max_speed_faces()
        if not math.isfinite(umax) or not np.isfinite(st.phi).all():
            raise FluidStop(t, "non-finite velocity or level set")
        if not self.fixed:
            # sqrt(g dx): what the fluid can gain falling one cell, so a fluid at rest under
            # gravity does not take an unbounded first step (Bridson's estimate)
            u_est = umax + (math.sqrt(self.g_mag * st.dx) if st.has_surface else 0.0)
            h = self.max_dt if u_est == 0.0 else min(self.max_dt, spec.cfl * st.dx / u_est)
            if h < 1e-6 * self.max_dt:
                raise FluidStop(t, f"CFL time step collapsed to {h:.3g} s "
                                   f"(max speed {umax:.3g} m/s)")
            gap = min(self.next_sample, self.duration) - t
            h = gap / math.ceil(gap / h - 1e-9)
        else:
            h = min(self.max_dt, self.duration - t)
            if umax * h / st.dx > spec.cfl_limit:
                raise FluidStop(t, f"CFL bound exceeded: u_max dt/dx = "
                                   f"{umax * h / st.dx:.3g} > {spec.cfl_limit:g}")
        self.cfl_seen = max(self.cfl_seen, umax * h / st.dx)
        return h

    def _step(self) -> tuple[float, str | None]:
        """One step; returns (h, reason the fluid was lost or None)."""
        h = self._step_size()
        st, spec = self.st, self.spec
        try:
            info = st.step(h, self.timers)
        except SolidStop as exc:
            raise FluidStop(self.time, str(exc)) from exc
        self.time += h
        self.dts.append(h)
        self.iters.append(info["iterations"])
        if info["iterations"] < 0:
            self.unconverged += 1
        if st.has_surface and st.fluid_cells() < spec.min_volume_fraction * st.fluid_cells0:
            return h, ("lost its fluid: fluid cells fell below "
                       f"{spec.min_volume_fraction:g} of the initial count")
        return h, None

    @property
    def done(self) -> bool:
        return self.time >= self.duration - self.eps

    def _passed_sample(self) -> bool:
        if self.time < self.next_sample - self.eps:
            return False
        while self.next_sample <= self.time + self.eps:
            self.next_sample += self.sample_every
        return True

    def advance(self, n: int) -> None:
        """n steps, no recording (the cost pass). Stops at the end of the run."""
        with _threads():
            for _ in range(n):
                if self.done:
                    return
                try:
                    self._step()
                except FluidStop as exc:
                    raise StepFailure(exc.reason) from exc
                self._passed_sample()

    # -- the accuracy pass ---------------------------------------------------------------
    def record(self) -> FluidRecord:
        with _threads():
            return self._record()

    def _record(self) -> FluidRecord:
        st, spec = self.st, self.spec
        fe = spec.output.field_every or max(self.sample_every, self.duration / 40.0)
        field_stride = max(1, round(fe / self.sample_every))
        ts: list[float] = []
        series: dict[str, list[float]] = {}
        field_t: list[float] = []
        frames: dict[str, list[np.ndarray]] = {k: [] for k in spec.output.fields}
        n_samples = 0

        def record(t: float, last_dt: float, final: bool = False) -> None:
            nonlocal n_samples
            m = st.measure()
            m["dt"] = last_dt
            m["pressure_iterations"] = float(st.last_iterations)
            ts.append(t)
            for k, val in m.items():
                series.setdefault(k, []).append(val)
            if n_samples % field_stride == 0 or final:
                field_t.append(t)
                for k, arr in st.snapshot(spec.output.fields).items():
                    frames[k].append(arr)
            n_samples += 1

        record(0.0, 0.0)
        v0 = series["volume"][0]
        failure = None
        stepping = 0.0
        while not self.done:
            t0 = time.perf_counter()
            try:
                h, lost = self._step()
            except FluidStop as exc:
                failure = {"time": exc.time, "reason": exc.reason}
                break
            stepping += time.perf_counter() - t0
            if lost:
                failure = {"time": self.time, "reason": lost}
            final = failure is not None or self.done
            if self._passed_sample() or final:
                t = self.time
                record(t, h, final)  # the final state always has a field snapshot
                if not math.isfinite(series["max_speed"][-1]) and failure is None:
                    failure = {"time": t, "reason": "non-finite velocity"}
                if st.has_surface and failure is None and \
                        series["volume"][-1] < spec.min_volume_fraction * v0:
                    failure = {"time": t, "reason": "lost its fluid: volume fell below "
                                                    f"{spec.min_volume_fraction:g} of the initial"}
            if failure is not None:
                break
        return FluidRecord(
            t=np.array(ts), series={k: np.array(v) for k, v in series.items()},
            field_t=np.array(field_t),
            fields={k: (np.stack(v) if v else np.zeros((0,))) for k, v in frames.items()},
            meta=self._meta(stepping), failure=failure,
        )

    def _meta(self, stepping: float) -> dict[str, Any]:
        st, spec, dts, iters = self.st, self.spec, self.dts, self.iters
        n = len(dts)
        timers = self.timers
        return {
            "case": getattr(self.scene, "name", None),
            "source": str(getattr(self.scene, "source", "")),
            "engine": "inhouse",
            "integrator": self.name,
            "integrator_description": self.scheme.description,
            "grid": {"nx": st.nx, "ny": st.ny, "dx": st.dx, "domain": [st.lx, st.ly],
                     "obstacle_cells": int(st.static_boundary.cells.sum())},
            "dt_mode": "fixed" if self.fixed else "cfl",
            "dt": {"min": min(dts) if dts else None, "max": max(dts) if dts else None,
                   "mean": (sum(dts) / n) if n else None, "steps": n,
                   "max_allowed": self.max_dt},
            "cfl": spec.cfl, "cfl_limit": spec.cfl_limit, "cfl_max_realised": self.cfl_seen,
            "band_cells": st.band_cells,
            # A profile of the accuracy pass (its phases); the cost of a run is the driver's
            # timed pass without recording (docs/metrics.md, "Cost").
            "profile": {"stepping_seconds": stepping, "build_seconds": self.build_time,
                        "phase_seconds": dict(timers)},
            "wall_time_phases": dict(timers),
            "ms_per_step": 1e3 * stepping / n if n else None,
            "ms_per_step_phases": {k: 1e3 * v / n for k, v in timers.items()} if n else None,
            "pressure_iterations": {"mean": float(np.mean(iters)) if iters else 0.0,
                                    "max": int(max(iters)) if iters else 0,
                                    "unconverged": self.unconverged,
                                    # "amg" once a multigrid hierarchy solved a step, with how
                                    # many were built (1 for a matrix that never changed)
                                    "solver": ("amg" if st.amg is not None and st.amg.setups
                                               else "mic0"),
                                    "amg_setups": st.amg.setups if st.amg is not None else 0,
                                    # coupled solves the multigrid handed to MIC(0)
                                    "amg_fallbacks": getattr(st.amg, "fallbacks", 0)},
            "fluid_cells_initial": st.fluid_cells0,
            "density": spec.density, "kinematic_viscosity": spec.kinematic_viscosity,
            "gravity": self.gravity.tolist(), "sample_every": self.sample_every,
            "particles": st.particles is not None,
            "threads": fluid_threads(),
            "redistancing": spec.redistancing,
            "warnings": [w for w in (st.lid_warning, self._viscous_warning()) if w],
            **self._coupling_meta(),
        }

    def _coupling_meta(self) -> dict[str, Any]:
        c = self.st.coupling
        if c is None:
            return {}
        b = c.body
        return {"bodies": [{"name": b.name, "mass": b.mass, "inertia": b.inertia,
                            "com_body": b.com_body.tolist(), "mass_per": "metre of depth"}],
                "coupling": {"method": "variational pressure solve with the body's velocity "
                                       "as unknowns (Batty, Bertails and Bridson 2007)",
                             "viscous_exchange_number_max": c.viscous_number,
                             "convective_exchange_steps": c.convective_steps,
                             "convective_exchange_skipped_at_surface": c.surface_skips}}

    def _viscous_warning(self) -> str | None:
        c = self.st.coupling
        if c is not None and c.viscous_number > 0.5:
            return (f"the explicit viscous exchange with the body reached rho nu dt "
                    f"sum(1/theta) / M = {c.viscous_number:.3g} (stable well below 1): "
                    "take a shorter step or a heavier body")
        return None

    def close(self) -> None:
        pass


class _threads:
    """numba's thread count set to fluid_threads() for the duration, then restored."""

    def __enter__(self):
        self.previous = numba.get_num_threads()
        numba.set_num_threads(fluid_threads())

    def __exit__(self, *exc):
        numba.set_num_threads(self.previous)


def run_fluid(scene: Any, integrator: str | None = None, dt: float | None = None) -> FluidRecord:
    """Run ``scene.fluid`` with the named in-house integrator (the accuracy pass alone).

    ``dt`` is the step the engine adapter or a sweep asks for (``None``: ``run.dt``). With
    ``fluid.time_step = "cfl"`` (default) it is the *largest* step: the step taken is
    ``min(dt, cfl dx / u_max)``, shortened to land on the sample times. With ``"fixed"`` every step
    is ``dt`` and a step beyond ``fluid.cfl_limit`` is a failure (the stability frontier of a
    sweep).
    """
    return FluidRun(scene, integrator, dt).record()
