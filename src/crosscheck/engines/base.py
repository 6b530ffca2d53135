"""The engine adapter protocol: what every simulator behind crosscheck implements.

An adapter builds its engine's model from a Scene (never from a hand-written model file) and
opens a session on it (engines/session.py) with one named integrator at one step size; the one
run driver (engines/driver.py) records, detects blow-ups and times every engine the same way.
An adapter declares what it can do; a scene needing more gets "not applicable: reason".
"""

from __future__ import annotations

import math
import platform
from dataclasses import dataclass, field
from typing import Any, Protocol, runtime_checkable

import numpy as np

from crosscheck.engines.session import Session
from crosscheck.scene.model import Scene, whole_steps  # noqa: F401 - re-exported
from crosscheck.state import Trajectory


@dataclass(frozen=True)
class Capabilities:
    dimensions: frozenset[int]
    shapes: frozenset[str]  # Shape.kind values
    effects: frozenset[str]  # Effects.names() values
    integrators: tuple[str, ...]  # the first is the engine's default
    notes: dict[str, str] = field(default_factory=dict)  # integrator -> what it does to rotation

    @property
    def default_integrator(self) -> str:
        return self.integrators[0]


@runtime_checkable
class Engine(Protocol):
    name: str

    def capabilities(self) -> Capabilities: ...

    def version(self) -> str: ...

    def not_applicable(self, scene: Scene, integrator: str) -> str | None:
        """None if the engine can run this scene with this integrator, else the reason."""

    def open(self, scene: Scene, integrator: str, dt: float) -> Session:
        """A session at the scene's t = 0 state (see engines/session.py)."""

    def maps_fluid(self, scene: Scene) -> bool:
        """True when the engine runs this fluid scene as a body in a stateless medium (a rigid
        run whose Trajectory is the body's), not as a grid fluid."""

    def run(self, scene: Scene, integrator: str, dt: float) -> Trajectory: ...


class EngineBase:
    """Shared behaviour: the capability check, the sampling plan and the common meta fields."""

    name = "base"
    # Why an engine lacks an effect, where a specific reason helps more than the generic one.
    effect_reasons: dict[str, str] = {
        "contact": "this engine's adapter does not map contact",
    }

    def capabilities(self) -> Capabilities:  # pragma: no cover - every adapter overrides
        raise NotImplementedError

    def version(self) -> str:  # pragma: no cover
        raise NotImplementedError

    def maps_fluid(self, scene: Scene) -> bool:
        """No engine maps a fluid scene to a medium unless it says so (MuJoCo does)."""
        return False

    def not_applicable(self, scene: Scene, integrator: str) -> str | None:
        caps = self.capabilities()
        # Effects first: a fluid scene's integrator names mean nothing to a rigid engine.
        for effect in scene.effects.names():
            if effect not in caps.effects:
                return self.effect_reasons.get(
                    effect, f"{self.name} cannot simulate the effect {effect!r}")
        if scene.dimension not in caps.dimensions:
            return f"{self.name} has no {scene.dimension}D scenes"
        if integrator not in caps.integrators:
            return f"{self.name} has no integrator {integrator!r} (it has {list(caps.integrators)})"
        for body in scene.bodies:
            if body.shape.kind not in caps.shapes:
                return f"{self.name} has no {body.shape.kind} shape (body {body.name!r})"
        self.check_options(scene)  # unknown options are a case error, not a skip
        return None

    def check_options(self, scene: Scene) -> None:
        """Raise CaseError for options the case pins for this engine that it does not know."""

    def open(self, scene: Scene, integrator: str, dt: float) -> Session:  # pragma: no cover
        raise NotImplementedError

    def runaway_factor(self, scene: Scene) -> float:
        """The driver's energy-runaway factor for this scene (engines/driver.py)."""
        from crosscheck.engines.driver import RUNAWAY_FACTOR

        return RUNAWAY_FACTOR

    def run(self, scene: Scene, integrator: str, dt: float) -> Trajectory:
        """The accuracy pass alone (no cost pass): the recorded Trajectory (or FluidRecord)."""
        from crosscheck.engines.driver import run

        return run(self, scene, integrator, dt, cost=None).output

    def open_fluid(self, scene: Scene, integrator: str, dt: float):
        """A fluid session (``record()``, ``advance(n)``, ``time``, ``dts``): in-house only."""
        from crosscheck.errors import EngineUnavailable

        raise EngineUnavailable(f"{self.name} has no grid fluid")

    def base_meta(self, scene: Scene, integrator: str, dt: float) -> dict[str, Any]:
        """Fields every Trajectory carries so its arrays can be read with NumPy alone."""
        return {
            "case": scene.name,
            "case_sha256": scene.source_sha256,
            "engine": self.name,
            "engine_version": self.version(),
            "integrator": integrator,
            "dt": dt,
            "dimension": scene.dimension,
            "bodies": list(scene.body_names),
            "masses": [b.mass for b in scene.bodies],
            "inertia_body": [np.asarray(b.inertia).tolist() for b in scene.bodies],
            "com_body": [np.asarray(b.com).tolist() for b in scene.bodies],
            "machine": platform.machine(),
        }


@dataclass(frozen=True)
class SamplingPlan:
    """Samples every ``steps_per_sample`` steps from 0 to ``total_steps``, plus a last sample at
    ``total_steps`` when the interval does not divide the run (a shorter final interval), so a
    run always ends at its duration."""

    steps_per_sample: int
    total_steps: int
    dt: float

    @property
    def sample_interval(self) -> float:
        return self.steps_per_sample * self.dt

    @property
    def n_samples(self) -> int:
        regular = self.total_steps // self.steps_per_sample + 1
        return regular + (1 if self.total_steps % self.steps_per_sample else 0)

    def steps_at(self, i: int) -> int:
        """Steps taken before sample i."""
        return min(i * self.steps_per_sample, self.total_steps)

    def steps_before(self, i: int) -> int:
        """Steps from sample i - 1 to sample i."""
        return self.steps_at(i) - self.steps_at(i - 1)

    def time(self, i: int) -> float:
        return self.steps_at(i) * self.dt

    def times(self, count: int | None = None) -> np.ndarray:
        n = self.n_samples if count is None else count
        return np.array([self.steps_at(i) for i in range(n)], dtype=np.int64) * self.dt


class TimeGridError(ValueError):
    """A step that does not divide the run's duration into a whole number of steps."""


def sampling_plan(scene: Scene, dt: float) -> SamplingPlan:
    """Record every ``round(sample_every / dt)`` steps (at least 1) up to the case's duration.

    Sample times are exact multiples of the step, so every engine is compared at the same times
    when it runs at the same dt; a reference at another dt is interpolated by the comparer. The
    run takes exactly duration / dt steps: a step that does not divide the duration is refused
    (TimeGridError), never run short; a sampling interval that does not divide it ends with a
    shorter final interval.
    """
    if not (dt > 0 and math.isfinite(dt)):
        raise ValueError(f"time step must be positive and finite, got {dt}")
    total = whole_steps(scene.run.duration, dt)
    if total is None:
        raise TimeGridError(
            f"dt = {dt:g} s does not divide the duration {scene.run.duration:g} s of case "
            f"{scene.name!r} into a whole number of steps ({scene.run.duration / dt:.6g})")
    steps = max(1, int(round(scene.run.sample_every / dt)))
    return SamplingPlan(steps_per_sample=steps, total_steps=total, dt=dt)
