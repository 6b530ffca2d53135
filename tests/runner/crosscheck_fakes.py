"""Tiny fake engine adapters (sessions for the run driver) for testing the runner, the comparer
and the reports.

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

from crosscheck.engines.base import Capabilities, EngineBase
from crosscheck.rotations import quat_mul, rotvec_to_quat


class FakeSession:
    """The state of ExactEngine's (or BlowupEngine's) scene after ``steps`` steps of dt."""

    fused = False

    def __init__(self, scene, integrator, dt, blowup=False):
        self.scene, self.integrator, self.dt, self.blowup = scene, integrator, dt, blowup
        n, d = len(scene.bodies), scene.dimension
        self.n, self.d = n, d
        self.g = scene.effects.gravity_vector(d)
        self.x0 = np.array([b.com_world() for b in scene.bodies], float).reshape(n, d)
        self.v0 = np.array([b.velocity for b in scene.bodies], float).reshape(n, d)
        self.w = np.array([b.angular_velocity for b in scene.bodies], float)
        if integrator == "fast_spin":
            self.w = 1.01 * self.w
        if blowup:
            self.v0 = self.v0 + 1.0
        self.x, self.v = self.x0.copy(), self.v0.copy()
        self.steps = 0
        r = 4 if d == 3 else 1
        w = 3 if d == 3 else 1
        self._sizes = (n * d, n * r, n * d, n * w)
        self.row_width = sum(self._sizes)

    def advance(self, n):
        dt = self.dt
        with np.errstate(over="ignore", invalid="ignore"):
            for _ in range(n):
                self.steps += 1
                if self.blowup:
                    if self.steps * dt > 0.2:
                        self.v = self.v * 10.0
                    self.x = self.x + self.v * dt
                elif self.integrator in ("euler", "unstable"):
                    self.x = self.x + self.v * dt
                    self.v = self.v + self.g * dt
                    if self.integrator == "unstable" and dt > 0.01:
                        self.v = self.v * 10.0

    def read_raw(self):
        scene, t = self.scene, self.steps * self.dt
        if self.blowup or self.integrator in ("euler", "unstable"):
            xs, vs = self.x, self.v
        else:
            xs, vs = self.x0 + self.v0 * t + 0.5 * self.g * t * t, self.v0 + self.g * t
        if self.blowup:
            rot = np.array([b.orientation for b in scene.bodies])
            om = np.array([b.angular_velocity for b in scene.bodies], float)
        elif self.d == 3:
            rot = np.array([quat_mul(rotvec_to_quat(self.w[k] * t), b.orientation)
                            for k, b in enumerate(scene.bodies)])
            om = np.array([b.angular_velocity for b in scene.bodies], float)
        else:
            rot = np.array([b.angle + self.w[k, 0] * t for k, b in enumerate(scene.bodies)])
            om = np.array([b.angular_velocity[0] for b in scene.bodies], float)
        return np.concatenate([np.ravel(a) for a in (xs, rot, vs, om)])

    def convert(self, rows, t):
        rows = np.asarray(rows, float)
        n, d, T = self.n, self.d, len(rows)
        parts = np.split(rows, np.cumsum(self._sizes)[:-1], axis=1)
        shapes = ((n, d), (n, 4) if d == 3 else (n,), (n, d), (n, 3) if d == 3 else (n,))
        return tuple(p.reshape((T, *s)) for p, s in zip(parts, shapes, strict=True)), {}

    def set_state(self, com, rot, vel, omega):
        raise NotImplementedError

    def check(self):
        return []

    def effective(self, arrays):
        return {"fake": True}

    def close(self):
        pass


class ExactEngine(EngineBase):
    name = "fake"

    def capabilities(self) -> Capabilities:
        return Capabilities(dimensions=frozenset({2, 3}),
                            shapes=frozenset({"sphere", "box", "circle"}),
                            effects=frozenset({"gravity", "drag"}),
                            integrators=("exact", "euler", "fast_spin", "unstable"))

    def version(self) -> str:
        return "fake-1.0"

    def open(self, scene, integrator, dt):
        return FakeSession(scene, integrator, dt)


class CrashEngine(ExactEngine):
    def open(self, scene, integrator, dt):
        os.kill(os.getpid(), signal.SIGSEGV)


class HangEngine(ExactEngine):
    def open(self, scene, integrator, dt):
        time.sleep(10_000)


class RaiseEngine(ExactEngine):
    def open(self, scene, integrator, dt):
        raise RuntimeError("adapter bug: something went wrong")


class BlowupEngine(ExactEngine):
    """Velocity times 10 every step from t = 0.2 s: non-finite after ~ 310 steps more."""

    def open(self, scene, integrator, dt):
        return FakeSession(scene, integrator, dt, blowup=True)


ALL = {
    "exact": "crosscheck_fakes:ExactEngine",
    "crash": "crosscheck_fakes:CrashEngine",
    "hang": "crosscheck_fakes:HangEngine",
    "raise": "crosscheck_fakes:RaiseEngine",
    "blowup": "crosscheck_fakes:BlowupEngine",
    "missing": "crosscheck_no_such_module:Engine",
}
