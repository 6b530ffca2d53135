"""References a run is compared with; the case's ``[reference]`` table says which.

* ``analytic``: ``crosscheck.reference.analytic.SOLUTIONS[solution](scene, times)`` evaluated at
  the run's own sample times (exact, no interpolation). NaN entries mark quantities the solution
  does not define; metrics skip them. ``EXTRA_METRICS[solution]`` adds solution-specific metrics.
* ``fine-step``: the in-house engine (or ``reference.engine``) with ``reference.integrator``
  (default ``rk4``) at ``reference.dt``, sampled at the case's interval; with ``integrator =
  "dop853"`` SciPy's ``solve_ivp`` (DOP853, rtol 1e-12 or ``reference.params.rtol``, atol
  ``1e-3 rtol max(1, max|y0|)``) on the in-house equations of motion
  (``crosscheck.sim.rigid.state_derivative``), evaluated at the case's sample times. Measured on
  the tennis racket (20 s, three flips near the separatrix): rtol 1e-12 agrees with in-house RK4
  at dt = 2.5e-4 to 1.9e-6 rad, about RK4's own error at dt = 1e-3; a stiff or chaotic case
  may want a smaller rtol or the fine-step RK4 reference.
* ``engine``: another engine's run (``reference.engine``, ``reference.integrator`` or its default)
  at the *same* step as the run being judged.
* ``table``: published data, used by fluid scenes through their own metrics.
* ``none``: only conservation metrics.

A reference sampled at other times than the run is resampled by :mod:`crosscheck.compare.interp`
(cubic Hermite for positions, slerp for orientations, linear for velocities).
Fine-step and engine references are computed once per case (and step, for ``engine``) by the
runner, saved as a Trajectory ``.npz`` and shared by every cell of the case.
"""

from __future__ import annotations

import hashlib
import json
from typing import Any

import numpy as np

from crosscheck.scene.model import Scene
from crosscheck.state import Trajectory

# Fine-step reference default: this many times finer than the case's step.
FINE_STEP_FACTOR = 100
DOP853_RTOL = 1e-12


def reference_spec(scene: Scene, dt: float) -> dict[str, Any] | None:
    """A plain description of the reference a run at step ``dt`` is compared with (or None)."""
    ref = scene.reference
    if scene.fluid is not None:
        return None  # fluid scenes compare with their tables / solutions in fluid_metrics
    if ref.kind == "analytic":
        return {"kind": "analytic", "solution": ref.solution}
    if ref.kind == "fine-step":
        integrator = (ref.integrator or "rk4").lower()
        if integrator == "dop853":
            return {"kind": "dop853", "rtol": float(ref.params.get("rtol", DOP853_RTOL))}
        return {"kind": "fine-step", "engine": ref.engine or "inhouse", "integrator": integrator,
                "dt": float(ref.dt if ref.dt is not None else scene.run.dt / FINE_STEP_FACTOR)}
    if ref.kind == "engine":
        return {"kind": "engine", "engine": ref.engine, "integrator": ref.integrator,
                "dt": float(dt)}
    if ref.kind == "table":
        return {"kind": "table", "table": ref.table}
    return None


def needs_run(spec: dict[str, Any] | None) -> bool:
    """True for references computed by a simulation (shared, run once before the cells)."""
    return spec is not None and spec["kind"] in ("fine-step", "engine", "dop853")


def reference_key(scene: Scene, spec: dict[str, Any]) -> str:
    """A file-name-safe key for a computed reference: case hash plus the spec."""
    blob = json.dumps({"case": scene.source_sha256, "name": scene.name, "spec": spec},
                      sort_keys=True)
    return hashlib.sha256(blob.encode()).hexdigest()[:20]


def describe(spec: dict[str, Any] | None) -> str:
    if spec is None:
        return "none"
    kind = spec["kind"]
    if kind == "analytic":
        return f"analytic: {spec['solution']}"
    if kind == "fine-step":
        return f"fine-step: {spec['engine']} {spec['integrator']} at dt={spec['dt']:g}"
    if kind == "engine":
        integ = spec.get("integrator") or "default"
        return f"engine: {spec['engine']} {integ} at the same dt"
    if kind == "dop853":
        return f"SciPy solve_ivp DOP853, rtol {spec['rtol']:g}"
    return f"{kind}: {spec.get('table')}"


def analytic_reference(scene: Scene, times: np.ndarray, solution: str):
    """(Trajectory, extra-metrics callable or None) of an analytic solution at ``times``."""
    from crosscheck.reference import analytic

    if solution not in analytic.SOLUTIONS:
        raise KeyError(f"no analytic solution {solution!r}; known: {sorted(analytic.SOLUTIONS)}")
    traj = analytic.SOLUTIONS[solution](scene, np.asarray(times, float))
    extra = getattr(analytic, "EXTRA_METRICS", {}).get(solution)
    return traj, extra


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


def dop853_available() -> bool:
    """True when the in-house simulator exposes its equations of motion as a state derivative."""
    try:
        from crosscheck.sim import rigid
    except ImportError:
        return False
    return hasattr(rigid, "state_derivative") and hasattr(rigid, "initial_state") \
        and hasattr(rigid, "state_to_trajectory")


def dop853_reference(scene: Scene, rtol: float = DOP853_RTOL) -> Trajectory:
    """SciPy ``solve_ivp(method="DOP853", rtol=1e-12)`` on the in-house equations of motion.

    Uses ``crosscheck.sim.rigid.initial_state(scene) -> y0``, ``state_derivative(scene) ->
    f(t, y)`` and ``state_to_trajectory(scene, t, Y) -> Trajectory`` (the same compiled kernels
    the in-house engine steps with), evaluated at the case's sample times (dense output).
    """
    if not dop853_available():
        raise RuntimeError("the DOP853 reference needs crosscheck.sim.rigid.state_derivative, "
                           "initial_state and state_to_trajectory, which the in-house "
                           "simulator does not expose yet")
    from scipy.integrate import solve_ivp

    from crosscheck.sim import rigid

    times = scene.run.sample_times()
    y0 = np.asarray(rigid.initial_state(scene), float)
    sol = solve_ivp(rigid.state_derivative(scene), (0.0, float(times[-1])), y0, method="DOP853",
                    t_eval=times, rtol=rtol,
                    atol=1e-3 * rtol * max(1.0, float(np.max(np.abs(y0)))))
    if not sol.success:
        raise RuntimeError(f"solve_ivp failed: {sol.message}")
    traj = rigid.state_to_trajectory(scene, sol.t, sol.y.T)
    traj.meta.update({"engine": "scipy", "integrator": "dop853", "rtol": rtol})
    return traj
