"""Recording overhead: bare stepping against stepping with recording at the case's interval.

For every registered adapter that can run a case, and each integrator the case lists for it:

* **bare**: the adapter's own model object advanced through all of the run's steps with nothing
  read back (for MuJoCo one ``mj_step(m, d, nstep=N)`` call), timed alone;
* **recorded loop**: CPU time of ``engine.run(scene, integrator, dt)`` minus that of the same
  run cut to one sample: model build and settings read-back cancel, what remains is stepping
  between samples, copying each sample and converting them all into the Trajectory.

overhead = loop / bare - 1; the target is below 10 %. Times are the thread's CPU time (the
machine is shared; wall time under contention measures the scheduler), minimum over interleaved
repeats run until a time budget is spent. An engine with no bare stepper registered in ``BARE``
is reported with the in-run wall-clock ratio recording / stepping from its Trajectory's meta.

Cases: ``free-flight`` (one body, centre of mass off its origin, full inertia, spinning at 150
rad/s for 1 s: the conformance suite's scene), ``tennis-racket`` (cases/rigid3d/tennis_racket.toml,
20 s) and, for 2D-only engines, ``free-flight-2d`` (a plate spinning at 150 rad/s for 1 s).

    .venv/bin/python benchmarks/bench_overhead.py [--engines mujoco,pybullet] [--budget 2]

writes benchmarks/results/overhead.json and overhead.md. Not a test: figures depend on the
machine; the committed ones say which machine.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import sys
import time
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path

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


# -- bare steppers: (scene, integrator, dt, steps) -> CPU seconds of stepping alone ---------------
# Timed with the thread's CPU clock: this machine is shared (2 cores, other jobs), and wall time
# under contention measures the scheduler more than the engine.
CLOCK = time.thread_time


def _bare_mujoco(scene, integrator, dt, steps):
    sim = get_engine("mujoco").build(scene, integrator, dt)
    t0 = CLOCK()
    sim.advance(steps)  # one mj_step(m, d, nstep=steps) call unless forces are applied per step
    return CLOCK() - t0


def _bare_pybullet(scene, integrator, dt, steps):
    from crosscheck.engines.pybullet import PybulletModel

    model = PybulletModel(scene, integrator, dt)
    try:
        poses = model.base_poses()
        model.probe()
        model.set_initial_state(poses)
        t0 = CLOCK()
        model.advance(steps)
        return CLOCK() - t0
    finally:
        model.close()


def _bare_pymunk(scene, integrator, dt, steps):
    from crosscheck.engines.pymunk import PymunkModel

    model = PymunkModel(scene, dt)
    t0 = CLOCK()
    model.advance(steps)
    return CLOCK() - t0


# Extra rows: an adapter's alternative recorders, measured on the case's first integrator.
VARIANTS: dict[str, list[tuple[str, dict]]] = {
    "mujoco": [("stepping=nstep", {"stepping": "nstep"})],
}

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
            max_repeats: int) -> dict:
    """CPU time of the recorded loop = run(full) - run(one sample, no steps): what the two
    share (model build, settings read-back) cancels; what remains is stepping in chunks, the
    per-sample copies and the conversion of every sample. Minimum over interleaved repeats
    (the least disturbed estimate, as timeit recommends)."""
    dt = scene.run.dt
    plan = sampling_plan(scene, dt)
    empty = replace(scene, run=replace(scene.run, duration=0.0))
    bare_fn = BARE.get(engine.name)
    full, base, bare, in_run = [], [], [], []
    # Warm-up: imports, JIT, caches.
    engine.run(scene, integrator, dt)
    if bare_fn is not None:
        bare_fn(scene, integrator, dt, plan.total_steps)
    start = time.perf_counter()
    while (len(full) < min_repeats or time.perf_counter() - start < budget) \
            and len(full) < max_repeats:
        if bare_fn is not None:
            bare.append(bare_fn(scene, integrator, dt, plan.total_steps))
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
    if bare:
        out["bare_cpu_min_s"] = min(bare)
        out["bare_cpu_median_s"] = statistics.median(bare)
        out["bare_steps_per_cpu_s"] = plan.total_steps / min(bare)
        out["overhead"] = loop / min(bare) - 1.0
        out["overhead_per_sample_us"] = (loop - min(bare)) / max(plan.n_samples - 1, 1) * 1e6
    else:
        out["overhead"] = None
    out["verdict"] = _verdict(out)
    return out


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


def markdown(result: dict) -> str:
    lines = [
        "# Recording overhead",
        "",
        "Bare stepping (the adapter's model advanced through every step with nothing read) "
        "against `engine.run` stepping with recording at the case's sampling interval. The "
        "recorded loop is the CPU time of a full `run` minus that of a one-sample `run` of the "
        "same case, which cancels model build and settings read-back and keeps stepping in "
        "chunks, per-sample copies and the conversion of every sample. Thread CPU time, minimum "
        "of interleaved repeats (the machine is shared; wall time measured the scheduler). "
        f"Target: overhead below {TARGET:.0%}. Produced by `benchmarks/bench_overhead.py`.",
        "",
        f"Machine: {result['machine']['platform']}, {result['machine']['cpus']} CPUs, "
        f"Python {result['machine']['python']}; {result['date']}. Engines: "
        + ", ".join(f"{k} {v}" for k, v in result["versions"].items()) + ".",
        "",
        "| engine | case | integrator | steps | samples | repeats | bare ms | recorded loop ms "
        "| overhead | per sample | in-run recording / stepping | verdict |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for row in result["rows"]:
        if "error" in row or "not_applicable" in row:
            why = row.get("error") or "not applicable: " + row["not_applicable"]
            lines.append(f"| {row['engine']} | {row['case']} | {row['integrator']} | | | | | "
                         f"| | | | {why} |")
            continue
        bare = f"{row['bare_cpu_min_s'] * 1e3:.2f}" if "bare_cpu_min_s" in row else "-"
        overhead = (f"{row['overhead']:+.1%}" if row["overhead"] is not None
                    else f"({row['in_run_recording_over_stepping_median']:.1%} of stepping, "
                         "in-run wall)")
        per_sample = (f"{row['overhead_per_sample_us']:.2f} us"
                      if row.get("overhead_per_sample_us") is not None else "-")
        lines.append(
            f"| {row['engine']} | {row['case']} | {row['integrator']} | {row['steps']} | "
            f"{row['samples']} | {row['repeats']} | {bare} | {row['loop_cpu_s'] * 1e3:.2f} | "
            f"{overhead} | {per_sample} | {row['in_run_recording_over_stepping_median']:.1%} | "
            f"{row['verdict']} |")
    lines += ["", "The overhead includes stepping in chunks of `steps_per_sample` (one engine "
              "call per sample instead of one for the run) as well as the copies and the "
              "conversion; \"per sample\" spreads it over the recorded samples (it also holds "
              "per-run costs that a one-sample run skips, which weigh most in the 1 s cases). "
              "\"In-run\" is the ratio the adapter itself reports in its Trajectory "
              "(`wall_time_recording / wall_time`, wall clock, median): it leaves out the cost "
              "of stepping in chunks. A `(stepping=nstep)` row is MuJoCo's alternative "
              "recorder. JSON: every figure.", ""]
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
    parser.add_argument("--out", type=Path, default=ROOT / "benchmarks" / "results")
    parser.add_argument("--name", default="overhead", help="output file stem")
    args = parser.parse_args(argv)

    rows, versions = [], {}
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
            runs = [(integrator, scene, "") for integrator in integrators]
            runs += [(integrators[0], replace(scene, engine_options={
                **scene.engine_options, name: {**scene.engine_options.get(name, {}), **opts}}),
                label) for label, opts in VARIANTS.get(name, [])]
            for integrator, scene, label in runs:
                base = {"engine": name, "case": scene.name,
                        "integrator": integrator + (f" ({label})" if label else ""),
                        "dt": scene.run.dt, "sample_every": scene.run.sample_every}
                reason = engine.not_applicable(scene, integrator)
                if reason is not None:
                    if scene.dimension == 2 and 3 in engine.capabilities().dimensions:
                        continue  # the 2D case is there for 2D-only engines
                    rows.append(base | {"not_applicable": reason})
                    continue
                row = base | measure(engine, scene, integrator, args.budget, args.min_repeats,
                                     args.max_repeats)
                rows.append(row)
                shown = (f"{row['overhead']:+.1%}" if row.get("overhead") is not None
                         else row.get("error", "in-run only"))
                print(f"{name:9s} {scene.name:15s} {base['integrator']:24s} overhead {shown}",
                      file=sys.stderr)
    result = {"benchmark": "recording overhead", "target": TARGET, "machine": machine(),
              "versions": versions, "rows": rows,
              "date": time.strftime("%Y-%m-%d %H:%M:%S %z")}
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / f"{args.name}.json").write_text(json.dumps(result, indent=1) + "\n")
    (args.out / f"{args.name}.md").write_text(markdown(result))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
