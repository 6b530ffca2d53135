"""Recording overhead: bare stepping against stepping with recording at the case's interval.

For every registered adapter that can run a case, and each integrator the case lists for it:

* **bare**: the adapter's own model advanced through all of the run's steps with nothing read
  back, by the fastest stepping loop the adapter itself uses (MuJoCo: one ``mj_step(m, d,
  nstep=N)`` call; Pymunk: the compiled ``cpSpaceStep`` loop; PyBullet: the compiled loop of
  Bullet step commands through its C API, ``_native.bullet_step``, plus the disconnect, which
  costs more after stepping), minus the same with no steps;
* **recorded loop**: CPU time of ``engine.run(scene, integrator, dt)`` minus that of the same
  run cut to one sample: model build and settings read-back cancel, what remains is stepping
  between samples, copying each sample and converting them all into the Trajectory.

overhead = loop / bare - 1; the target is below 10 %. Times are the thread's CPU time (the
machine is shared; wall time under contention measures the scheduler), minimum over interleaved
repeats run until a time budget is spent.

Cases: ``free-flight`` (one body, centre of mass off its origin, full inertia, spinning at 150
rad/s for 1 s: the conformance suite's scene), ``tennis-racket`` (cases/rigid3d/tennis_racket.toml,
20 s) and, for 2D-only engines, ``free-flight-2d`` (a plate spinning at 150 rad/s for 1 s).

Variants: an adapter's alternative recorders, one extra row each on the case's first
integrator, each against its own bare loop: MuJoCo's ``stepping`` engine options, PyBullet's
recorder from Python (``PybulletEngine.compiled_recording = False``; bare: ``stepSimulation(cid)``
per step from Python, the loop that recorder steps with).

Then, to show where a 10 % target can hold and where it cannot:

* **floors**: per engine and path, the cost of one step and of the reads a sample needs, each
  measured in context (a loop stepping k = 10 steps and reading once per sample, minus the same
  loop without the reads), and the floor ratio = reads per sample x cost per read / (k x cost
  per step), with the smallest k at which that floor is under 10 %;
* **sweeps**: the full measured overhead of the free-flight case at sparser sampling (k = 10,
  20, 50, 100 steps per sample) and with more bodies (N = 1, 10, 100 free-flying bodies).

    .venv/bin/python benchmarks/bench_overhead.py [--engines mujoco,pybullet] [--budget 2]
        [--no-floors] [--no-sweeps]

writes benchmarks/results/overhead.json and overhead.md. Not a test: figures depend on the
machine; the committed ones say which machine.
"""

from __future__ import annotations

import argparse
import functools
import json
import math
import os
import platform
import statistics
import sys
import time
from collections.abc import Callable, Mapping
from contextlib import contextmanager
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from crosscheck.engines import engine_names, get_engine
from crosscheck.engines.base import sampling_plan
from crosscheck.rotations import axis_angle_to_quat, quat_to_matrix
from crosscheck.scene.loader import load_case, load_case_text
from crosscheck.scene.model import Scene

ROOT = Path(__file__).resolve().parents[1]
TARGET = 0.10


# -- cases ----------------------------------------------------------------------------------------
def _j(x) -> str:
    return json.dumps(np.asarray(x, float).tolist())


def free_flight() -> Scene:
    axes = quat_to_matrix(axis_angle_to_quat([0.3, -1.0, 0.5], 0.9))
    inertia = axes @ np.diag([0.010, 0.017, 0.022]) @ axes.T
    q0 = axis_angle_to_quat([1.0, 2.0, 3.0], 0.7)
    omega = 150.0 * quat_to_matrix(q0) @ axes[:, 2]
    return load_case_text(f"""
[case]
name = "free-flight"
dimension = 3
[run]
duration = 1.0
dt = 1e-3
sample_every = 0.01
integrators = {{ mujoco = ["euler", "rk4"], pybullet = ["multibody", "maximal"] }}
[[bodies]]
name = "spinner"
shape = {{ box = {{ size = [0.3, 0.2, 0.1] }} }}
mass = 2.0
com = [0.03, -0.02, 0.01]
inertia = {_j(inertia)}
position = [0.1, -0.2, 0.5]
orientation = {_j(q0)}
velocity = [1.0, -0.5, 0.25]
angular_velocity = {_j(omega)}
""", name="free-flight")


def free_flight_2d() -> Scene:
    return load_case_text("""
[case]
name = "free-flight-2d"
dimension = 2
[run]
duration = 1.0
dt = 1e-3
sample_every = 0.01
[[bodies]]
name = "plate"
shape = { box = { size = [0.3, 0.1] } }
mass = 1.5
com = [0.04, -0.03]
position = [0.2, 1.0]
orientation = 0.4
velocity = [1.0, -0.5]
angular_velocity = 150.0
""", name="free-flight-2d")


def cases() -> list[Scene]:
    return [free_flight(), load_case(ROOT / "cases" / "rigid3d" / "tennis_racket.toml"),
            free_flight_2d()]


def many_bodies(n: int, dimension: int, steps_per_sample: int = 10, duration: float = 1.0
                ) -> Scene:
    """``n`` copies of the free-flight body (3D) or plate (2D), on a grid, each turned and
    spinning differently, nothing between them: free flight at dt = 1e-3."""
    rng = np.random.default_rng(7)
    axes = quat_to_matrix(axis_angle_to_quat([0.3, -1.0, 0.5], 0.9))
    inertia = axes @ np.diag([0.010, 0.017, 0.022]) @ axes.T
    bodies = []
    for i in range(n):
        x, y = 0.5 * (i % 10), 0.5 * (i // 10)
        if dimension == 3:
            q0 = axis_angle_to_quat(rng.normal(size=3), float(rng.uniform(0.1, 3.0)))
            omega = 150.0 * quat_to_matrix(q0) @ axes[:, 2]
            bodies.append(f"""
[[bodies]]
name = "b{i}"
shape = {{ box = {{ size = [0.3, 0.2, 0.1] }} }}
mass = 2.0
com = [0.03, -0.02, 0.01]
inertia = {_j(inertia)}
position = [{x}, {y}, 0.5]
orientation = {_j(q0)}
velocity = [1.0, -0.5, 0.25]
angular_velocity = {_j(omega)}
""")
        else:
            bodies.append(f"""
[[bodies]]
name = "b{i}"
shape = {{ box = {{ size = [0.3, 0.1] }} }}
mass = 1.5
com = [0.04, -0.03]
position = [{x}, {y}]
orientation = {float(rng.uniform(-3, 3))}
velocity = [1.0, -0.5]
angular_velocity = 150.0
""")
    return load_case_text(f"""
[case]
name = "free-flight-x{n}"
dimension = {dimension}
[run]
duration = {float(duration)!r}
dt = 1e-3
sample_every = {steps_per_sample * 1e-3!r}
""" + "".join(bodies), name=f"free-flight-x{n}")


# -- bare steppers: (scene, integrator, dt, steps) -> CPU seconds of stepping alone ---------------
# Timed with the thread's CPU clock: this machine is shared (2 cores, other jobs), and wall time
# under contention measures the scheduler more than the engine.
CLOCK = time.thread_time


def _bare_mujoco(scene, integrator, dt, steps):
    sim = get_engine("mujoco").build(scene, integrator, dt)
    t0 = CLOCK()
    sim.advance(steps)  # one mj_step(m, d, nstep=steps) call unless forces are applied per step
    return CLOCK() - t0


def _bare_pybullet(scene, integrator, dt, steps, compiled=True):
    """compiled: the adapter's compiled loop of Bullet step commands (``_native.bullet_step``),
    the loop ``run()`` steps and records with; else ``stepSimulation(cid)`` per step from
    Python, the loop of the Python recorder."""
    from crosscheck.engines.pybullet import PybulletModel

    model = PybulletModel(scene, integrator, dt)
    try:
        poses = model.base_poses()
        model.probe()
        model.set_initial_state(poses)
        # Untimed, as in run(): checks the compiled reader against PyBullet's (once per model).
        if model.use_compiled(compiled) != compiled:
            raise RuntimeError(f"pybullet: compiled loop unavailable ({model.native_reason})")
        t0 = CLOCK()
        model.advance(steps)
    except BaseException:
        model.close()
        raise
    # Disconnecting a client that has stepped costs ~0.1 ms more than one that has not (Bullet
    # frees what stepping allocated): a run pays it, so the bare loop does too (measure() takes
    # the difference with a zero-step bare run, which cancels the disconnect itself).
    model.close()
    return CLOCK() - t0


def _bare_pymunk(scene, integrator, dt, steps):
    from crosscheck.engines.pymunk import PymunkModel

    model = PymunkModel(scene, dt)
    t0 = CLOCK()
    model.advance(steps)
    return CLOCK() - t0


@dataclass(frozen=True)
class Variant:
    """An adapter's alternative recorder: an extra row on the case's first integrator.

    ``options`` go to the engine through the scene (``[engine_options.<engine>]``);
    ``attributes`` are set on the engine instance for the variant's runs and restored after
    (a switch that is not a case option, such as PyBullet's ``compiled_recording``); ``bare``
    is the bare stepper the variant is compared with (default: the engine's, BARE)."""

    label: str
    options: Mapping[str, Any] = field(default_factory=dict)
    attributes: Mapping[str, Any] = field(default_factory=dict)
    bare: Callable[[Scene, str, float, int], float] | None = None


VARIANTS: dict[str, list[Variant]] = {
    "mujoco": [Variant("stepping=rollout", options={"stepping": "rollout"}),
               Variant("stepping=nstep", options={"stepping": "nstep"})],
    # The recorder from Python against the loop it steps with, stepSimulation(cid) per step.
    "pybullet": [Variant("recording=python", attributes={"compiled_recording": False},
                         bare=functools.partial(_bare_pybullet, compiled=False))],
}


@contextmanager
def _engine_attributes(engine, attributes: Mapping[str, Any]):
    """Set attributes on the engine instance; afterwards restore what the instance had (or
    remove them again, so the class attribute shows through)."""
    missing = object()
    saved = {name: engine.__dict__.get(name, missing) for name in attributes}
    try:
        for name, value in attributes.items():
            setattr(engine, name, value)
        yield engine
    finally:
        for name, value in saved.items():
            if value is missing:
                engine.__dict__.pop(name, None)
            else:
                setattr(engine, name, value)


BARE: dict[str, Callable[[Scene, str, float, int], float]] = {
    "mujoco": _bare_mujoco,
    "pybullet": _bare_pybullet,
    "pymunk": _bare_pymunk,
}


# -- measurement --------------------------------------------------------------------------------
def _run_cpu(engine, scene, integrator, dt):
    t0 = CLOCK()
    traj = engine.run(scene, integrator, dt)
    return CLOCK() - t0, traj


def measure(engine, scene: Scene, integrator: str, budget: float, min_repeats: int,
            max_repeats: int, bare_fn: Callable[[Scene, str, float, int], float] | None = None
            ) -> dict:
    """CPU time of the recorded loop = run(full) - run(one sample, no steps): what the two
    share (model build, settings read-back) cancels; what remains is stepping in chunks, the
    per-sample copies and the conversion of every sample. Minimum over interleaved repeats
    (the least disturbed estimate, as timeit recommends). ``bare_fn``: the bare stepper
    (default: the engine's, BARE)."""
    dt = scene.run.dt
    plan = sampling_plan(scene, dt)
    empty = replace(scene, run=replace(scene.run, duration=0.0))
    if bare_fn is None:
        bare_fn = BARE.get(engine.name)
    full, base, bare, bare0, in_run = [], [], [], [], []
    # Warm-up: imports, JIT, caches.
    warm = engine.run(scene, integrator, dt)
    if bare_fn is not None:
        try:
            bare_fn(scene, integrator, dt, plan.total_steps)
        except RuntimeError as exc:  # e.g. the compiled loop this row is about is unavailable
            return {"error": str(exc)}
    start = time.perf_counter()
    while (len(full) < min_repeats or time.perf_counter() - start < budget) \
            and len(full) < max_repeats:
        if bare_fn is not None:
            bare.append(bare_fn(scene, integrator, dt, plan.total_steps))
            bare0.append(bare_fn(scene, integrator, dt, 0))
        cpu, traj = _run_cpu(engine, scene, integrator, dt)
        if traj.failure is not None:
            return {"error": f"run failed: {traj.failure}"}
        full.append(cpu)
        in_run.append(traj.meta["wall_time_recording"] / traj.meta["wall_time"])
        base.append(_run_cpu(engine, empty, integrator, dt)[0])
    loop = min(full) - min(base)
    out = {
        "steps": plan.total_steps,
        "samples": plan.n_samples,
        "steps_per_sample": plan.steps_per_sample,
        "repeats": len(full),
        "run_cpu_min_s": min(full),
        "run_one_sample_cpu_min_s": min(base),
        "loop_cpu_s": loop,
        "in_run_recording_over_stepping_median": statistics.median(in_run),
    }
    recording = warm.meta.get("effective", {}).get("recording")
    if recording is not None:  # how the adapter recorded (PyBullet: compiled or Python, why)
        out["recording"] = recording
    if bare:
        # What a bare run with no steps still pays inside the timed region (a call, a
        # disconnect) cancels, as the one-sample run cancels it on the recorded side.
        bare_s = min(bare) - min(bare0)
        out["bare_cpu_min_s"] = bare_s
        out["bare_cpu_median_s"] = statistics.median(bare) - statistics.median(bare0)
        out["bare_zero_steps_cpu_min_s"] = min(bare0)
        out["bare_steps_per_cpu_s"] = plan.total_steps / bare_s
        out["overhead"] = loop / bare_s - 1.0
        out["overhead_per_sample_us"] = (loop - bare_s) / max(plan.n_samples - 1, 1) * 1e6
    else:
        out["overhead"] = None
    out["verdict"] = _verdict(out)
    return out


# -- floors: per-call costs in context --------------------------------------------------------
SAMPLES = 100  # per timed loop: 100 samples of k steps, the free-flight case's size
K = 10  # the cases' steps per sample


def _min_interleaved(fns: dict[str, Callable[[], float]], budget: float,
                     reset: Callable[[], None] | None = None, min_repeats: int = 20
                     ) -> dict[str, float]:
    """Minimum CPU time of each timed function over interleaved repeats (reset untimed)."""
    best = {name: math.inf for name in fns}
    for fn in fns.values():  # warm-up
        if reset is not None:
            reset()
        fn()
    start, repeats = time.perf_counter(), 0
    while repeats < min_repeats or time.perf_counter() - start < budget:
        for name, fn in fns.items():
            if reset is not None:
                reset()
            best[name] = min(best[name], fn())
        repeats += 1
    return best


def _floor_row(engine: str, path: str, n: int, step_s: float, calls: int, sample_s: float,
               note: str = "", adapter: bool = False, integrator: str | None = None) -> dict:
    """step_s: CPU seconds per step (all n bodies); sample_s: extra seconds per sample for the
    reads; calls: engine calls a sample needs beyond the stepping. adapter: the path the
    adapter records with (for ``integrator``, None: any), whose floor the sweeps quote."""
    floor = sample_s / (K * step_s)
    return {"engine": engine, "path": path, "bodies": n, "step_us": step_s * 1e6,
            "calls_per_sample": calls, "per_call_us": sample_s / calls * 1e6 if calls else None,
            "per_sample_us": sample_s * 1e6, "floor_at_k10": floor,
            "k_for_10pct": max(1, math.ceil(sample_s / (TARGET * step_s))), "note": note,
            "adapter": adapter, "integrator": integrator}


# Trivial command round trips per body and sample in the comparison loop: one (~0.1 us) would
# be ~1 % of the steps between two samples, inside the noise of a difference of two loops.
COMMANDS_PER_BODY = 10


@functools.cache
def _bullet_comparison_loops():
    """Two compiled loops for the comparison figures of the PyBullet floors (numba, built on
    first use), each SAMPLES x (k step commands, then per body one command round trip):

    * ``commands``: ``calls`` round trips of a trivial command, the one ``init(client)`` makes
      (b3InitRequestPhysicsParamCommand: the server copies a few parameters);
    * ``requests``: the actual-state request the adapter's reader sends, submitted and its
      answer not read out.

    Both return how many answers had the expected status type (a check that they ran)."""
    from numba import njit

    from crosscheck.engines import _native

    step, call_p_p, call_p_pp = _native.bullet_step, _native.call_p_p, _native.call_p_pp
    call_p_pi, call_i_p = _native.call_p_pi, _native.call_i_p

    @njit(nogil=True)
    def commands(fns, client, step_kind, init, kind, k, samples, calls):
        good = 0
        for _ in range(samples):
            step(fns, client, step_kind, k)
            for _ in range(calls):
                status = call_p_pp(fns[1], (client, call_p_p(init, (client,))))
                good += call_i_p(fns[8], (status,)) == kind
        return good

    @njit(nogil=True)
    def requests(fns, client, step_kind, uids, kind, k, samples):
        good = 0
        for _ in range(samples):
            step(fns, client, step_kind, k)
            for j in range(uids.shape[0]):
                status = call_p_pp(fns[1], (client, call_p_pi(fns[2], (client, uids[j]))))
                good += call_i_p(fns[8], (status,)) == kind
        return good

    return commands, requests


def _pybullet_costs(integrator: str, n: int, budget: float) -> dict[str, float]:
    """CPU seconds of SAMPLES x K steps of n free bodies, without and with each path's reads.

    Python path: ``stepSimulation(cid)`` per step (``keyword``: the client id as a keyword),
    then per body one or both getters. Compiled (the adapter's loop, engines/_native.py):
    ``bullet_step`` alone, ``bullet_record`` (one actual-state request per body and sample,
    read out), and the two comparison loops of _bullet_comparison_loops."""
    import ctypes

    import pybullet as p

    from crosscheck.engines import _bullet_capi, _native
    from crosscheck.engines.pybullet import PybulletModel

    model = PybulletModel(many_bodies(n, 3), integrator, 1e-3)
    try:
        poses = model.base_poses()
        model.probe()
        model.set_initial_state(poses)
        if not model.use_compiled():  # also proves the compiled reader equals PyBullet's
            raise RuntimeError(f"pybullet: compiled loop unavailable ({model.native_reason})")
        cid, uids = model.cid, [b.uid for b in model.bodies]
        step, pose, vel = p.stepSimulation, p.getBasePositionAndOrientation, p.getBaseVelocity
        steps = range(K)
        api = _bullet_capi.api()
        fns, client, kinds = api.fns, api.handle(cid), api.kinds
        native_uids = np.array(uids, np.int64)
        out = np.empty((SAMPLES + 1, n * model.row_width))
        scratch = _native.bullet_scratch()
        commands, requests = _bullet_comparison_loops()
        init = ctypes.cast(ctypes.CDLL(p.__file__).b3InitRequestPhysicsParamCommand,
                           ctypes.c_void_p).value
        command_kind = ctypes.CFUNCTYPE(ctypes.c_int, ctypes.c_void_p)(int(fns[8]))(
            ctypes.CFUNCTYPE(ctypes.c_void_p, ctypes.c_void_p, ctypes.c_void_p)(int(fns[1]))(
                client, ctypes.CFUNCTYPE(ctypes.c_void_p, ctypes.c_void_p)(init)(client)))
        answered: dict[str, int] = {}

        def bare():
            t0 = CLOCK()
            for _ in range(K * SAMPLES):
                step(cid)
            return CLOCK() - t0

        def bare_keyword():
            t0 = CLOCK()
            for _ in range(K * SAMPLES):
                step(physicsClientId=cid)
            return CLOCK() - t0

        def one_read():
            t0 = CLOCK()
            for _ in range(SAMPLES):
                for _ in steps:
                    step(cid)
                for u in uids:
                    pose(u, cid)
            return CLOCK() - t0

        def two_reads():
            t0 = CLOCK()
            for _ in range(SAMPLES):
                for _ in steps:
                    step(cid)
                for u in uids:
                    pose(u, cid)
                    vel(u, cid)
            return CLOCK() - t0

        def compiled_bare():
            t0 = CLOCK()
            code = _native.bullet_step(fns, client, kinds[0], K * SAMPLES)
            cpu = CLOCK() - t0
            answered["compiled_bare"] = int(code == _native.BULLET_OK)
            return cpu

        def compiled_record():
            # Sample 0, then SAMPLES x (K steps, one sample): SAMPLES + 1 reads.
            t0 = CLOCK()
            count, code = _native.bullet_record(fns, client, native_uids, False, kinds, K,
                                                out, scratch)
            cpu = CLOCK() - t0
            answered["compiled_record"] = int(count == SAMPLES + 1 and code == _native.BULLET_OK)
            return cpu

        def compiled_requests():
            t0 = CLOCK()
            good = requests(fns, client, kinds[0], native_uids, kinds[1], K, SAMPLES)
            cpu = CLOCK() - t0
            answered["compiled_requests"] = int(good == SAMPLES * n)
            return cpu

        def compiled_commands():
            t0 = CLOCK()
            good = commands(fns, client, kinds[0], init, command_kind, K, SAMPLES,
                            COMMANDS_PER_BODY * n)
            cpu = CLOCK() - t0
            answered["compiled_commands"] = int(good == SAMPLES * COMMANDS_PER_BODY * n)
            return cpu

        t = _min_interleaved({"bare": bare, "keyword": bare_keyword, "one": one_read,
                              "two": two_reads, "cbare": compiled_bare, "crec": compiled_record,
                              "creq": compiled_requests, "ccmd": compiled_commands}, budget,
                             reset=lambda: model.set_initial_state(poses))
        failed = sorted(name for name, ok in answered.items() if not ok)
        if failed:
            raise RuntimeError(f"pybullet floors: Bullet did not answer as expected in {failed}")
        return t
    finally:
        model.close()


def floors_pybullet(n: int, budget: float) -> list[dict]:
    rows = []
    for integrator in ("multibody", "maximal"):
        t = _pybullet_costs(integrator, n, budget)
        cstep_s = t["cbare"] / (K * SAMPLES)
        # bullet_record reads sample 0 too: SAMPLES + 1 reads.
        csample_s = (t["crec"] - t["cbare"]) / (SAMPLES + 1)
        request_s = (t["creq"] - t["cbare"]) / (SAMPLES * n)
        command_s = (t["ccmd"] - t["cbare"]) / (SAMPLES * COMMANDS_PER_BODY * n)
        rows.append(_floor_row(
            "pybullet", f"{integrator}, compiled loop (adapter): b3 step command per step; one "
            "actual-state request per body, read out", n, cstep_s, n, csample_s,
            note=f"per body: the request alone (not read out) {request_s * 1e6:.3f} us; a "
                 f"trivial command round trip (b3InitRequestPhysicsParamCommand + submit) "
                 f"{command_s * 1e6:.3f} us",
            adapter=True, integrator=integrator))
        step_s = t["bare"] / (K * SAMPLES)
        pose_s = (t["one"] - t["bare"]) / (SAMPLES * n)
        vel_s = (t["two"] - t["one"]) / (SAMPLES * n)
        rows.append(_floor_row(
            "pybullet", f"{integrator}, python: stepSimulation(cid) per step; "
            "getBasePositionAndOrientation + getBaseVelocity per body", n, step_s, 2 * n,
            (t["two"] - t["bare"]) / SAMPLES,
            note=f"per call: pose {pose_s * 1e6:.2f} us, velocity {vel_s * 1e6:.2f} us; a "
                 f"keyword client id costs {(t['keyword'] - t['bare']) / (K * SAMPLES) * 1e6:.2f}"
                 " us more per step", integrator=integrator))
    return rows


def _pybullet_substep_run(integrator: str, sub: int, budget: float) -> tuple[float, np.ndarray]:
    import pybullet as p

    from crosscheck.engines.pybullet import PybulletModel

    model = PybulletModel(free_flight(), integrator, 1e-3)
    try:
        poses = model.base_poses()
        model.probe()
        cid = model.cid
        if sub > 1:
            p.setPhysicsEngineParameter(fixedTimeStep=sub * 1e-3, numSubSteps=sub,
                                        physicsClientId=cid)

        def run():
            t0 = CLOCK()
            for _ in range(K * SAMPLES // sub):
                p.stepSimulation(cid)
            return CLOCK() - t0

        best = _min_interleaved({"run": run}, budget,
                                reset=lambda: model.set_initial_state(poses))["run"]
        model.set_initial_state(poses)
        run()
        return best, np.array(model.read_raw())
    finally:
        model.close()


def substeps_pybullet(budget: float) -> list[dict]:
    """numSubSteps = k (one stepSimulation call per sample): cost per step and whether the
    state after the free-flight second equals k single steps bit for bit. Not used by the
    adapter (docs/engines.md says why); measured so the bare loop's choice is visible."""
    out = []
    for integrator in ("multibody", "maximal"):
        single, a = _pybullet_substep_run(integrator, 1, budget / 2)
        grouped, b = _pybullet_substep_run(integrator, K, budget / 2)
        out.append({"engine": "pybullet", "integrator": integrator,
                    "step_us_single": single / (K * SAMPLES) * 1e6,
                    "step_us_substeps": grouped / (K * SAMPLES) * 1e6,
                    "bit_identical_on_free_flight": bool(np.array_equal(a, b))})
    return out


def floors_pymunk(n: int, budget: float) -> list[dict]:
    from crosscheck.engines.pymunk import PymunkModel, _cp

    model = PymunkModel(many_bodies(n, 2), 1e-3)
    native, fns, space, bodies, cogs = model.native
    dt = 1e-3
    handle = model.space._space
    cstep, read_raw, space_step = _cp.cpSpaceStep, model.read_raw, model.space.step
    steps = range(K)
    com, angle = np.empty((SAMPLES + 1, n, 2)), np.empty((SAMPLES + 1, n))
    vel, omega = np.empty((SAMPLES + 1, n, 2)), np.empty((SAMPLES + 1, n))

    def compiled_bare():
        t0 = CLOCK()
        native.chipmunk_step(fns[0], space, dt, K * SAMPLES)
        return CLOCK() - t0

    def compiled_rec():
        t0 = CLOCK()
        native.chipmunk_record(fns, space, dt, K, bodies, cogs, com, angle, vel, omega)
        return CLOCK() - t0

    def cffi_bare():
        t0 = CLOCK()
        for _ in range(K * SAMPLES):
            cstep(handle, dt)
        return CLOCK() - t0

    def cffi_rec():
        t0 = CLOCK()
        for _ in range(SAMPLES):
            for _ in steps:
                cstep(handle, dt)
            read_raw()
        return CLOCK() - t0

    def public_bare():
        t0 = CLOCK()
        for _ in range(K * SAMPLES):
            space_step(dt)
        return CLOCK() - t0

    t = _min_interleaved({"cb": compiled_bare, "cr": compiled_rec, "pb": cffi_bare,
                          "pr": cffi_rec, "sb": public_bare}, budget)
    return [
        _floor_row("pymunk", "compiled loop: cpSpaceStep and 4 C getters per body (adapter)",
                   n, t["cb"] / (K * SAMPLES), 4 * n, (t["cr"] - t["cb"]) / SAMPLES,
                   adapter=True),
        _floor_row("pymunk", "python: cpSpaceStep through cffi, 4 C getters per body via cffi",
                   n, t["pb"] / (K * SAMPLES), 4 * n, (t["pr"] - t["pb"]) / SAMPLES,
                   note=f"Space.step costs {t['sb'] / (K * SAMPLES) * 1e6:.2f} us per step; "
                        "this loop's stepping is itself slower than the compiled one's"),
    ]


def floors_mujoco(n: int, budget: float) -> list[dict]:
    import mujoco

    from crosscheck.engines.mujoco import _native_stepper

    sim = get_engine("mujoco").build(many_bodies(n, 3), "euler", 1e-3)
    m, d = sim.model, sim.data
    spec = int(mujoco.mjtState.mjSTATE_FULLPHYSICS)
    init = np.empty(mujoco.mj_stateSize(m, spec))
    mujoco.mj_getState(m, d, init, spec)
    states = np.empty((SAMPLES, init.size))
    rows_ = list(states)
    native, address, _ = _native_stepper()
    qpos, qvel = np.empty((SAMPLES + 1, m.nq)), np.empty((SAMPLES + 1, m.nv))
    step, get = mujoco.mj_step, mujoco.mj_getState

    def bare():
        t0 = CLOCK()
        step(m, d, K * SAMPLES)
        return CLOCK() - t0

    def nstep():
        t0 = CLOCK()
        for i in range(SAMPLES):
            step(m, d, K)
            get(m, d, rows_[i], spec)
        return CLOCK() - t0

    def compiled():
        t0 = CLOCK()
        native.mujoco_record(address, m._address, d._address, d.qpos, d.qvel,
                             d.warning.number, K, qpos, qvel)
        return CLOCK() - t0

    def reset():
        mujoco.mj_setState(m, d, init, spec)

    t = _min_interleaved({"bare": bare, "nstep": nstep, "compiled": compiled}, budget, reset)
    step_s = t["bare"] / (K * SAMPLES)
    return [
        _floor_row("mujoco", "compiled loop: mj_step x k, qpos/qvel copied (adapter, euler)", n,
                   step_s, 0, (t["compiled"] - t["bare"]) / SAMPLES, adapter=True,
                   integrator="euler"),
        _floor_row("mujoco", "python: mj_step(m, d, k) + mj_getState per sample (euler)", n,
                   step_s, 2, (t["nstep"] - t["bare"]) / SAMPLES, integrator="euler"),
    ]


FLOORS: dict[str, Callable[[int, float], list[dict]]] = {
    "mujoco": floors_mujoco,
    "pybullet": floors_pybullet,
    "pymunk": floors_pymunk,
}


def _predicted(floor_rows: list[dict], engine: str, integrator: str, n: int, k: int
               ) -> float | None:
    """The adapter path's floor at k steps per sample (reads / stepping; conversion aside)."""
    for row in floor_rows:
        if (row["engine"] == engine and row["bodies"] == n and row["adapter"]
                and row["integrator"] in (None, integrator)):
            return row["per_sample_us"] / (k * row["step_us"])
    return None


# -- sweeps: sparser sampling, more bodies ----------------------------------------------------
SWEEP_INTEGRATORS = {"mujoco": ("euler",), "pybullet": ("multibody", "maximal"),
                     "pymunk": ("position_first",)}
SWEEP_K = (10, 20, 50, 100)
SWEEP_N = (1, 10, 100)
SWEEP_DURATION = 5.0


def sweeps(engine, budget: float, floor_rows: list[dict]) -> list[dict]:
    name = engine.name
    dim = 3 if 3 in engine.capabilities().dimensions else 2
    rows = []
    for integrator in SWEEP_INTEGRATORS.get(name, (engine.capabilities().default_integrator,)):
        # 5 s (1 s for 100 bodies): long enough that the run's fixed costs (build, settings
        # read-back, ~2 ms for PyBullet) do not drown the difference being measured.
        runs = [("sampling", 1, k, many_bodies(1, dim, k, SWEEP_DURATION)) for k in SWEEP_K]
        runs += [("bodies", n, K, many_bodies(n, dim, K, SWEEP_DURATION if n < 100 else 1.0))
                 for n in SWEEP_N if n > 1]
        for kind, n, k, scene in runs:
            row = {"engine": name, "integrator": integrator, "sweep": kind, "bodies": n,
                   "steps_per_sample": k}
            row |= measure(engine, scene, integrator, budget, 5, 1000)
            row["floor"] = _predicted(floor_rows, name, integrator, n, k)
            rows.append(row)
            print(f"{name:9s} {integrator:14s} N={n:<3d} k={k:<3d} overhead "
                  f"{row.get('overhead', float('nan')):+.1%}", file=sys.stderr)
    return rows


def _verdict(row: dict) -> str:
    value = (row["overhead"] if row["overhead"] is not None
             else row["in_run_recording_over_stepping_median"])
    return "pass" if value < TARGET else "over target"


def machine() -> dict:
    info = {"machine": platform.machine(), "processor": platform.processor(),
            "python": platform.python_version(), "cpus": os.cpu_count(),
            "platform": platform.platform()}
    try:
        import psutil

        info["memory_gb"] = round(psutil.virtual_memory().total / 2**30, 1)
    except ImportError:  # pragma: no cover
        pass
    return info


def _pct(x) -> str:
    return "-" if x is None else f"{x:+.1%}"


def markdown(result: dict) -> str:
    lines = [
        "# Recording overhead",
        "",
        "Bare stepping (the adapter's model advanced through every step with nothing read, by "
        "the fastest stepping loop the adapter itself uses, minus the same with no steps) "
        "against `engine.run` stepping with "
        "recording at the case's sampling interval. The recorded loop is the CPU time of a full "
        "`run` minus that of a one-sample `run` of the same case, which cancels model build and "
        "settings read-back and keeps stepping between samples, per-sample reads and the "
        "conversion of every sample. Thread CPU time, minimum of interleaved repeats (the "
        "machine is shared; wall time measured the scheduler). "
        f"Target: overhead below {TARGET:.0%}. Produced by `benchmarks/bench_overhead.py`; "
        "docs/engines.md explains each engine's recorder.",
        "",
        f"Machine: {result['machine']['platform']}, {result['machine']['cpus']} CPUs, "
        f"Python {result['machine']['python']}; {result['date']}. Engines: "
        + ", ".join(f"{k} {v}" for k, v in result["versions"].items()) + ".",
        "",
        "## The cases",
        "",
        "| engine | case | integrator | steps | samples | repeats | bare ms | recorded loop ms "
        "| overhead | per sample | verdict |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for row in result["rows"]:
        if "error" in row or "not_applicable" in row:
            why = row.get("error") or "not applicable: " + row["not_applicable"]
            lines.append(f"| {row['engine']} | {row['case']} | {row['integrator']} | | | | | "
                         f"| | | {why} |")
            continue
        lines.append(
            f"| {row['engine']} | {row['case']} | {row['integrator']} | {row['steps']} | "
            f"{row['samples']} | {row['repeats']} | {row['bare_cpu_min_s'] * 1e3:.3f} | "
            f"{row['loop_cpu_s'] * 1e3:.3f} | {_pct(row['overhead'])} | "
            f"{row['overhead_per_sample_us']:.2f} us | {row['verdict']} |")
    lines += ["", "\"Per sample\" spreads the overhead over the recorded samples (it also "
              "holds per-run costs a one-sample run skips, such as converting many samples "
              "instead of one). `(stepping=...)` rows are MuJoCo's alternative recorders, kept "
              "as engine options. `(recording=python)` rows are PyBullet's recorder through "
              "its Python functions (`PybulletEngine.compiled_recording = False`; the adapter "
              "falls back to it when the compiled loop is unavailable or forces are applied "
              "per step), against the loop it steps with, `stepSimulation(cid)` per step from "
              "Python. Pymunk is 2D only: its case is the 2D free flight.", ""]

    floors = result.get("floors") or []
    if floors:
        lines += [
            "## Floors: what one sample costs against the steps between two samples",
            "",
            f"Each cost is measured in context: {SAMPLES} samples of k = {K} steps of N "
            "free-flying bodies (the free-flight body, dt = 1e-3), once with and once without "
            "the reads; the difference per sample is the reads' cost (per call: divided by the "
            "calls). floor = per-sample cost / (k x per-step cost): the overhead no recorder on "
            "that path can go below (the Trajectory conversion comes on top). \"k for 10 %\" "
            "is the smallest number of steps per sample at which the floor is under 10 %. "
            "\"(adapter)\" marks the path the adapter records with; the others are its "
            "fallbacks or the alternatives it replaced.",
            "",
            "| engine | path | N | per step us | calls per sample | per call us | per sample us "
            "| floor at k = 10 | k for 10 % | note |",
            "|---|---|---|---|---|---|---|---|---|---|",
        ]
        for r in floors:
            per_call = "-" if r["per_call_us"] is None else f"{r['per_call_us']:.3f}"
            lines.append(
                f"| {r['engine']} | {r['path']} | {r['bodies']} | {r['step_us']:.3f} | "
                f"{r['calls_per_sample']} | {per_call} | {r['per_sample_us']:.3f} | "
                f"{r['floor_at_k10']:.1%} | {r['k_for_10pct']} | {r['note']} |")
        lines.append("")
    substeps = result.get("pybullet_substeps") or []
    if substeps:
        lines += [
            f"PyBullet's `numSubSteps = {K}` (fixedTimeStep = {K} dt, one `stepSimulation` per "
            "sample), measured but not used by the adapter (docs/engines.md: Bullet decides "
            "the number of substeps per call from an internal time accumulator that PyBullet "
            "does not report, so a dropped step would go unnoticed):",
            "",
            "| integrator | per step, single steps (stepSimulation from Python) us | per step, "
            "substeps us | bit-identical on free flight |",
            "|---|---|---|---|",
        ]
        for r in substeps:
            lines.append(f"| {r['integrator']} | {r['step_us_single']:.3f} | "
                         f"{r['step_us_substeps']:.3f} | {r['bit_identical_on_free_flight']} |")
        lines += ["", "With substeps the bare loop would be that much faster and the reads, "
                  "unchanged, a larger fraction of it: the floor at k = 10 rises accordingly.",
                  ""]

    sweep_rows = result.get("sweeps") or []
    if sweep_rows:
        lines += [
            "## Sparser sampling and more bodies (measured)",
            "",
            f"The full overhead (as in the first table) of N free-flying bodies for "
            f"{SWEEP_DURATION:g} s (1 s for 100 bodies) at dt = 1e-3, sampled every k steps; "
            "\"floor\" is the prediction from the floors table (reads only).",
            "",
            "| engine | integrator | N | k | steps | samples | bare ms | recorded loop ms | "
            "overhead | floor | verdict |",
            "|---|---|---|---|---|---|---|---|---|---|---|",
        ]
        for r in sweep_rows:
            if "error" in r:
                lines.append(f"| {r['engine']} | {r['integrator']} | {r['bodies']} | "
                             f"{r['steps_per_sample']} | | | | | | | {r['error']} |")
                continue
            lines.append(
                f"| {r['engine']} | {r['integrator']} | {r['bodies']} | "
                f"{r['steps_per_sample']} | {r['steps']} | {r['samples']} | "
                f"{r['bare_cpu_min_s'] * 1e3:.3f} | {r['loop_cpu_s'] * 1e3:.3f} | "
                f"{_pct(r['overhead'])} | {_pct(r['floor'])} | {r['verdict']} |")
        lines.append("")
    lines += ["JSON (overhead.json): every figure, including medians and repeat counts.", ""]
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--engines", default=",".join(n for n in engine_names()
                                                       if n != "inhouse"),
                        help="comma-separated engine names (default: the external engines)")
    parser.add_argument("--budget", type=float, default=2.0,
                        help="seconds of repeats per engine, case and integrator")
    parser.add_argument("--min-repeats", type=int, default=5)
    parser.add_argument("--max-repeats", type=int, default=1000)
    parser.add_argument("--no-floors", action="store_true", help="skip the per-call floors")
    parser.add_argument("--no-sweeps", action="store_true",
                        help="skip the sampling-interval and body-count sweeps")
    parser.add_argument("--out", type=Path, default=ROOT / "benchmarks" / "results")
    parser.add_argument("--name", default="overhead", help="output file stem")
    args = parser.parse_args(argv)

    rows, versions, floor_rows, substeps, sweep_rows = [], {}, [], [], []
    for name in [n.strip() for n in args.engines.split(",") if n.strip()]:
        try:
            engine = get_engine(name)
        except ImportError as exc:
            print(f"{name}: skipped ({exc})", file=sys.stderr)
            continue
        versions[name] = engine.version()
        for scene in cases():
            integrators = scene.integrators_for(name) or (
                engine.capabilities().default_integrator,)
            runs = [(integrator, scene, None) for integrator in integrators]
            runs += [(integrators[0], replace(scene, engine_options={
                **scene.engine_options,
                name: {**scene.engine_options.get(name, {}), **variant.options}}), variant)
                for variant in VARIANTS.get(name, [])]
            for integrator, scene, variant in runs:
                label = f" ({variant.label})" if variant is not None else ""
                base = {"engine": name, "case": scene.name, "integrator": integrator + label,
                        "dt": scene.run.dt, "sample_every": scene.run.sample_every}
                reason = engine.not_applicable(scene, integrator)
                if reason is not None:
                    if scene.dimension == 2 and 3 in engine.capabilities().dimensions:
                        continue  # the 2D case is there for 2D-only engines
                    rows.append(base | {"not_applicable": reason})
                    continue
                with _engine_attributes(engine, variant.attributes if variant else {}):
                    row = base | measure(engine, scene, integrator, args.budget,
                                         args.min_repeats, args.max_repeats,
                                         variant.bare if variant else None)
                rows.append(row)
                shown = (f"{row['overhead']:+.1%}" if row.get("overhead") is not None
                         else row.get("error", "in-run only"))
                print(f"{name:9s} {scene.name:15s} {base['integrator']:24s} overhead {shown}",
                      file=sys.stderr)
        if not args.no_floors and name in FLOORS:
            for n in SWEEP_N:
                floor_rows += FLOORS[name](n, args.budget)
            if name == "pybullet":
                substeps = substeps_pybullet(args.budget)
        if not args.no_sweeps:
            sweep_rows += sweeps(engine, args.budget / 2, floor_rows)
    result = {"benchmark": "recording overhead", "target": TARGET, "machine": machine(),
              "versions": versions, "rows": rows, "floors": floor_rows,
              "pybullet_substeps": substeps, "sweeps": sweep_rows,
              "date": time.strftime("%Y-%m-%d %H:%M:%S %z")}
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / f"{args.name}.json").write_text(json.dumps(result, indent=1) + "\n")
    (args.out / f"{args.name}.md").write_text(markdown(result))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
