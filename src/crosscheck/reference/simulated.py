"""Simulated references: a fine-step run, another engine's run, or SciPy's DOP853.

These are computed, not looked up, so they sit above the engines (they run one) and below
``compare`` (which only resamples and judges what it is given). The runner computes each once
per case (and step, for ``engine``) in a worker, saves it as a Trajectory ``.npz`` and hands
the file to every cell of the case (:func:`crosscheck.reference.spec.for_cell`). What a case
asks for is described by :func:`crosscheck.reference.spec.reference_spec`.

* ``fine-step``: ``spec["engine"]`` with ``spec["integrator"]`` at ``spec["dt"]``, sampled at
  the case's interval.
* ``engine``: the same, at the step of the run being judged.
* ``dop853``: ``solve_ivp(method="DOP853")`` at rtol ``spec["rtol"]`` (default 1e-12), atol
  ``1e-3 rtol max(1, max|y0|)``, on the Newton-Euler equations of
  :mod:`crosscheck.reference.newton_euler`, written apart from the in-house simulator so the
  in-house engine is not judged against its own force kernels. Dense output at the case's sample
  times. Measured on the tennis racket (20 s, three flips near the separatrix): rtol 1e-12
  agrees with in-house RK4 at dt = 2.5e-4 to 1.9e-6 rad, about RK4's own error at dt = 1e-3; a
  stiff or chaotic case may want a smaller rtol or the fine-step RK4 reference.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from crosscheck.reference import newton_euler
from crosscheck.reference.spec import DOP853_RTOL
from crosscheck.scene.model import Scene
from crosscheck.state import Trajectory


def compute_reference(scene: Scene, spec: dict[str, Any], get_engine=None) -> Trajectory:
    """Run a simulated reference (fine-step, engine or DOP853). May take long; runs in a worker."""
    if spec["kind"] == "dop853":
        return dop853_reference(scene, rtol=spec.get("rtol", DOP853_RTOL))
    if get_engine is None:
        from crosscheck.engines import get_engine
    engine = get_engine(spec["engine"])
    integrator = spec.get("integrator") or engine.capabilities().default_integrator
    reason = engine.not_applicable(scene, integrator)
    if reason:
        raise RuntimeError(f"reference engine cannot run this case: {reason}")
    return engine.run(scene, integrator, float(spec["dt"]))


def dop853_reference(scene: Scene, rtol: float = DOP853_RTOL) -> Trajectory:
    """SciPy's DOP853 on the independent Newton-Euler equations, at the case's sample times.

    atol scales with the initial state's largest entry so that a state of large numbers (a body
    far from the origin) is not held to an absolute tolerance below its round-off.
    """
    if scene.effects.contact:
        raise RuntimeError("the DOP853 reference has no contact model")
    times = scene.run.sample_times()
    y0 = newton_euler.initial_state(scene)
    atol = 1e-3 * rtol * max(1.0, float(np.max(np.abs(y0))))
    traj = newton_euler.solve(scene, times, rtol=rtol, atol=atol)
    traj.meta.update({"engine": "scipy", "integrator": "dop853", "rtol": rtol})
    return traj
