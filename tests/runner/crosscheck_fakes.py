"""Tiny fake engine adapters for testing the runner, the comparer and the reports.

They stand in for real adapters through the runner's ``engine_refs`` ("module:Class"), so they
are importable in spawned workers, Dask workers and isolated child processes (the parent's
sys.path travels with the task). Their physics is simple enough to know every metric exactly:

* ``ExactEngine``: free flight under uniform gravity in closed form (x = x0 + v0 t + g t^2 / 2,
  v = v0 + g t) and a spin about a fixed axis (q = exp(w t / 2) q0). Exact for a sphere, or for
  any body spinning about a principal axis.
* integrator ``euler``: explicit Euler for the translation (x += v dt, then v += g dt), which
  lags the exact drop by g t dt / 2 and gains energy m g^2 t dt / 2.
* integrator ``fast_spin``: exact translation, spin 1 % too fast: orientation error 0.01 |w| t.
* integrator ``unstable``: explicit Euler that is stable for dt <= 0.01 and otherwise multiplies
  the velocity by 10 every step (a stability limit at 0.01 s).
* ``CrashEngine`` kills its own process with SIGSEGV, ``HangEngine`` sleeps forever,
  ``RaiseEngine`` raises, ``BlowupEngine`` grows the velocity 10x per step until it is not finite.
"""

from __future__ import annotations

import os
import signal
import time

import numpy as np

from crosscheck.engines.base import Capabilities, EngineBase, sampling_plan
from crosscheck.rotations import quat_mul, rotvec_to_quat
from crosscheck.state import TrajectoryRecorder


class ExactEngine(EngineBase):
    name = "fake"

    def capabilities(self) -> Capabilities:
        return Capabilities(dimensions=frozenset({2, 3}),
                            shapes=frozenset({"sphere", "box", "circle"}),
                            effects=frozenset({"gravity", "drag"}),
                            integrators=("exact", "euler", "fast_spin", "unstable"))

    def version(self) -> str:
        return "fake-1.0"

    def run(self, scene, integrator, dt):
        plan = sampling_plan(scene, dt)
        n, d = len(scene.bodies), scene.dimension
        rec = TrajectoryRecorder(plan.n_samples, n, d)
        g = scene.effects.gravity_vector(d)
        x0 = np.array([b.com_world() for b in scene.bodies])
        v0 = np.array([b.velocity for b in scene.bodies], float)
        w = np.array([b.angular_velocity for b in scene.bodies], float)
        if integrator == "fast_spin":
            w = 1.01 * w
        t0 = time.perf_counter()
        x, v = x0.copy(), v0.copy()
        for i in range(plan.n_samples):
            t = plan.time(i)
            if integrator in ("euler", "unstable"):
                if i > 0:
                    for _ in range(plan.steps_per_sample):
                        x = x + v * dt
                        v = v + g * dt
                        if integrator == "unstable" and dt > 0.01:
                            v = v * 10.0
                xs, vs = x, v
                if not np.all(np.isfinite(xs)) or not np.all(np.isfinite(vs)):
                    rec.fail(t, "non-finite state")
                    break
            else:
                xs, vs = x0 + v0 * t + 0.5 * g * t * t, v0 + g * t
            if d == 3:
                rot = np.array([quat_mul(rotvec_to_quat(w[k] * t), b.orientation)
                                for k, b in enumerate(scene.bodies)])
                om = np.array([b.angular_velocity for b in scene.bodies], float)
            else:
                rot = np.array([b.angle + w[k, 0] * t for k, b in enumerate(scene.bodies)])
                om = np.array([b.angular_velocity[0] for b in scene.bodies], float)
            rec.record(t, xs, rot, vs, om)
        meta = self.base_meta(scene, integrator, dt)
        meta["wall_time"] = time.perf_counter() - t0
        return rec.finish(meta)


class CrashEngine(ExactEngine):
    def run(self, scene, integrator, dt):
        os.kill(os.getpid(), signal.SIGSEGV)


class HangEngine(ExactEngine):
    def run(self, scene, integrator, dt):
        time.sleep(10_000)


class RaiseEngine(ExactEngine):
    def run(self, scene, integrator, dt):
        raise RuntimeError("adapter bug: something went wrong")


class BlowupEngine(ExactEngine):
    """Velocity times 10 every step from t = 0.2 s: non-finite after ~ 310 steps more."""

    def run(self, scene, integrator, dt):
        plan = sampling_plan(scene, dt)
        n, d = len(scene.bodies), scene.dimension
        rec = TrajectoryRecorder(plan.n_samples, n, d)
        x = np.array([b.com_world() for b in scene.bodies])
        v = np.array([b.velocity for b in scene.bodies], float) + 1.0
        quat = np.array([b.orientation for b in scene.bodies])
        om = np.array([b.angular_velocity for b in scene.bodies], float)
        step = 0
        with np.errstate(over="ignore", invalid="ignore"):
            for i in range(plan.n_samples):
                if i > 0:
                    for _ in range(plan.steps_per_sample):
                        step += 1
                        if step * dt > 0.2:
                            v = v * 10.0
                        x = x + v * dt
                if not rec.record(plan.time(i), x, quat, v, om):
                    break
        meta = self.base_meta(scene, integrator, dt)
        meta["wall_time"] = 0.0
        return rec.finish(meta)


ALL = {
    "exact": "crosscheck_fakes:ExactEngine",
    "crash": "crosscheck_fakes:CrashEngine",
    "hang": "crosscheck_fakes:HangEngine",
    "raise": "crosscheck_fakes:RaiseEngine",
    "blowup": "crosscheck_fakes:BlowupEngine",
    "missing": "crosscheck_no_such_module:Engine",
}
