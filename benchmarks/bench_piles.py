"""Steps per second on piles (issue 12 point 4): the in-house contact models beside MuJoCo,
PyBullet and Pymunk on the same scenes, in one run, with each run's soundness beside its speed.

    .venv/bin/python benchmarks/bench_piles.py [--sizes 200 1000 5000] [--repeats 3]
        [--duration 0.3] [--cap 120] [--warm-cap 900] [--accuracy-cap 300] [--peers-max-n N]
        [--only SCENE ...] [--cells LABEL ...] [--add] [--out DIR]

Scenes: tests/piles/pile_scenes.py (shared with tests/piles/test_pile_scenes.py): spheres into a
bin (200, 1000, 5000), 200 spheres onto the bare ground, 200 cubes into a bin and onto the
bare ground, a 2D pile of 200
circles and squares into a 2D bin; dt = 1e-3.

Engines, through crosscheck's adapters and run driver only (engines/driver.py):

* in-house: every registered contact model (crosscheck.names.CONTACT_MODELS) with
  ``symplectic_euler``, the one integrator all four pair with and the cheapest (one force
  evaluation per step);
* MuJoCo at the adapter's settings with its default solver (Newton) and with ``[engine_options.
  mujoco] solver = "cg"`` (its fastest sound setting on piles, CONTACTS.md 3b);
* PyBullet as the adapter runs it, both integrators (``maximal``, ``multibody``);
* Pymunk on the 2D pile (the in-house models run there too).

Per scene, every cell (engine + setting) lives in a worker process of its own for the whole
scene. Each worker first opens a session and takes one step (numba compilation or its cache,
the engines' first calls; ``--warm-cap``). Then ``--repeats`` rounds in which every cell in turn
runs one repetition of the driver's cost pass (``driver.measure_cost``: a fresh session, one
untimed warm-up step, then ``advance`` over the run's steps timed without recording:
docs/metrics.md "Cost"); the rounds interleave the cells so that the load of the shared machine
falls on all of them alike; best and median are reported, with the load average before and
after each scene. Last the driver's accuracy pass (``driver.run(..., cost=None)``, 11 samples)
gives the soundness figures (``--accuracy-cap``). A repetition longer than ``--cap`` seconds is
stopped (its worker killed) and the cell reported as capped, with the steps/s it cannot exceed.
``--peers-max-n`` leaves the peers out of larger piles (default: none left out).

Soundness at the end of the accuracy pass: no failure reported by the driver, every body finite,
inside the bin (or above the ground for the open scene), and the deepest penetration of any pair
over the samples from crosscheck's own contact metrics (compare/contact_metrics.py). "sound"
(piles_report.is_sound) means all of these, with a penetration under the committed sphere-pile
case's bound: 1 mm, MuJoCo 5 mm (its soft contact sinks by design).

Writes ``benchmarks/results/piles.json`` and ``benchmarks/results/piles.md``. ``--add`` (with
``--only`` and ``--cells``) measures those cells into the scenes already in ``--out``, keeping the
scenes' other rows: a slow model timed apart (``impulse_lcp``: minutes per scene) without
re-timing the others. Its ratios then span two invocations; the report says which rows and
under what load.
"""

from __future__ import annotations

import argparse
import json
import multiprocessing as mp
import os
import platform
import statistics
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests" / "piles"))
sys.path.insert(0, str(Path(__file__).resolve().parent))

import pile_scenes  # noqa: E402
from piles_report import report  # noqa: E402

from crosscheck.names import contact_model_names  # noqa: E402

OUT = ROOT / "benchmarks" / "results"
DT = pile_scenes.DT
PENETRATION_LOOSEST = 5e-3  # m: r / 10, the committed sphere-pile case's bound for MuJoCo
INHOUSE_INTEGRATOR = "symplectic_euler"
DEFAULT_DURATION = 0.3  # s (main: why)
# --peers-max-n leaves the peers out of larger piles, to save time only. Until 2026-11-27 it
# had to: the adapters enumerated every body pair in Python (PyBullet's plan took 160-210 s at
# N = 1000, MuJoCo got one explicit <pair> per body pair and no broad phase); all three now
# program their engines from scene.contact.material_classes (docs/engines.md, "Contact" of
# each), so by default every pile runs every engine.
PEERS_NOT_RUN = "not run: --peers-max-n {limit} leaves the peers out of piles above it"


def cells_for(pile, labels: list[str] | None = None) -> list[dict]:
    """The engine settings run on a scene (label, engine, integrator, MuJoCo solver); with
    ``labels``, those only."""
    out = [{"label": f"inhouse {m}", "engine": "inhouse",
            "integrator": f"{INHOUSE_INTEGRATOR}+{m}", "solver": None}
           for m in contact_model_names("inhouse")]
    if pile.dimension == 3:
        out += [{"label": "mujoco newton (default)", "engine": "mujoco", "integrator": "euler",
                 "solver": None},
                {"label": "mujoco cg", "engine": "mujoco", "integrator": "euler", "solver": "cg"},
                {"label": "pybullet maximal", "engine": "pybullet", "integrator": "maximal",
                 "solver": None},
                {"label": "pybullet multibody", "engine": "pybullet", "integrator": "multibody",
                 "solver": None}]
    else:
        out += [{"label": "pymunk", "engine": "pymunk", "integrator": "position_first",
                 "solver": None}]
    return [c for c in out if not labels or c["label"] in labels]


def scenes(sizes: list[int], only: list[str] | None, duration: float
           ) -> list[tuple[str, callable]]:
    d = duration
    out = [(f"spheres_bin_{n}", lambda n=n: pile_scenes.spheres(n, duration=d)) for n in sizes]
    out += [("spheres_ground_200", lambda: pile_scenes.spheres(200, walls=False, duration=d)),
            ("boxes_bin_200", lambda: pile_scenes.boxes(200, duration=d)),
            ("boxes_ground_200", lambda: pile_scenes.boxes(200, walls=False, duration=d)),
            ("pile_2d_200", lambda: pile_scenes.pile_2d(200, duration=d))]
    out = [s for s in out if not only or s[0] in only]
    if d != DEFAULT_DURATION:  # another duration is another scene in the results
        out = [(f"{name}_{d:g}s", build) for name, build in out]
    return out


# -- the worker: one cell, one scene ------------------------------------------------------------
def _engine(name: str):
    if name == "inhouse":
        from crosscheck.engines.inhouse import InhouseEngine
        return InhouseEngine()
    if name == "mujoco":
        from crosscheck.engines.mujoco import MujocoEngine
        return MujocoEngine()
    if name == "pybullet":
        from crosscheck.engines.pybullet import PybulletEngine
        return PybulletEngine()
    from crosscheck.engines.pymunk import PymunkEngine
    return PymunkEngine()


def _worker(conn, pile, cell) -> None:
    """Answers "accuracy" and "cost" commands for one cell until told to stop."""
    from crosscheck.engines import driver

    scene = pile.scene
    if cell["solver"]:
        scene = pile_scenes.with_mujoco_solver(pile, cell["solver"]).scene
    engine = _engine(cell["engine"])
    # The cost pass times the whole run (the rounds come before the accuracy pass, whose steps
    # the driver would otherwise take): a run that fails part-way is timed until the engine
    # gives up, and its soundness row says so.
    steps = driver.sampling_plan(scene, DT).total_steps
    while True:
        cmd = conn.recv()
        if cmd == "stop":
            return
        try:
            if cmd == "warm":  # numba compilation (or its cache) and the engines' first calls
                t0 = time.perf_counter()
                session = engine.open(scene, cell["integrator"], DT)
                session.advance(1)
                session.close()
                conn.send({"warm_seconds": time.perf_counter() - t0})
            elif cmd == "accuracy":
                t0 = time.perf_counter()
                res = driver.run(engine, scene, cell["integrator"], DT, cost=None)
                took = time.perf_counter() - t0
                conn.send({"accuracy_wall": took,
                           "accuracy_steps": res.trajectory.meta.get("steps"),
                           **soundness(pile, res.trajectory)})
            else:
                c = driver.measure_cost(lambda: engine.open(scene, cell["integrator"], DT),
                                        steps, DT, driver.CostPlan(min_repeats=1, min_seconds=0.0,
                                                                   max_repeats=1))
                conn.send({"wall": c.wall[0], "cpu": c.cpu[0], "steps": c.steps})
        except Exception as exc:  # reported as the cell's result, never hidden
            conn.send({"error": f"{type(exc).__name__}: {exc}"[:400]})


def soundness(pile, traj) -> dict:
    from crosscheck.compare.contact_metrics import penetration

    failure = traj.failure
    com = traj.com[-1]
    finite = bool(np.all(np.isfinite(traj.com)) and np.all(np.isfinite(traj.vel)))
    out = {"failure": failure, "finite": finite, "t_end": float(traj.t[-1])}
    if not finite:
        return {**out, "in_bin": False, "escaped": None, "penetration_max": None, "sound": False}
    up = com[:, -1]
    inside = up > -pile_scenes.R  # above the ground
    if pile.inner:
        lo, hi = pile.inner[0::2], pile.inner[1::2]
        for axis in range(len(lo)):
            inside &= (com[:, axis] > lo[axis]) & (com[:, axis] < hi[axis])
    t0 = time.perf_counter()
    pen = penetration(pile.scene, traj)
    depth = None
    if pen.rows is not None and len(pen.rows.gap):
        depth = float(max(0.0, -np.min(pen.rows.gap)))
    elif pen.rows is not None:
        depth = 0.0
    v = np.linalg.norm(traj.vel[-1], axis=-1)
    # The verdict with the case's per-engine bound is the report's (piles_report.is_sound);
    # this one, at MuJoCo's 5 mm for every engine, is the loosest.
    sound = (failure is None and bool(inside.all()) and depth is not None
             and depth < PENETRATION_LOOSEST)
    return {**out, "escaped": int((~inside).sum()), "in_bin": bool(inside.all()),
            "penetration_max": depth, "penetration_seconds": time.perf_counter() - t0,
            "speed_max_end": float(v.max()), "speed_mean_end": float(v.mean()),
            "sound": bool(sound)}


# -- the parent: interleaved rounds -------------------------------------------------------------
class Cell:
    def __init__(self, ctx, pile, spec):
        self.spec = spec
        self.parent, child = ctx.Pipe()
        self.proc = ctx.Process(target=_worker, args=(child, pile, spec), daemon=True)
        self.proc.start()
        self.result = {**spec, "walls": [], "cpus": []}
        self.alive = True

    def ask(self, cmd: str, cap: float):
        if not self.alive:
            return None
        self.parent.send(cmd)
        if not self.parent.poll(cap):
            self.proc.kill()  # our own worker, by its handle
            self.proc.join()
            self.alive = False
            self.result["capped"] = f"{cmd} ran longer than the cap of {cap:g} s: stopped"
            return None
        answer = self.parent.recv()
        if "error" in answer:
            self.result["error"] = answer["error"]
            self.stop()
            return None
        return answer

    def stop(self):
        if self.alive:
            self.parent.send("stop")
            self.proc.join(timeout=30)
            if self.proc.is_alive():
                self.proc.kill()
            self.alive = False


def run_scene(name: str, build, repeats: int, cap: float, labels=None, *,
              warm_cap: float = 900.0, accuracy_cap: float = 300.0,
              peers_max_n: int = 10**9) -> list[dict]:
    pile = build()
    specs = cells_for(pile, labels)
    skipped = [{**c, "scene": name, "n": pile.n, "dimension": pile.dimension,
                "not_run": "left out of this invocation (--cells; see the docs)"}
               for c in cells_for(pile) if c not in specs]
    if pile.n > peers_max_n:
        skipped += [{**c, "scene": name, "n": pile.n, "dimension": pile.dimension,
                     "not_run": PEERS_NOT_RUN.format(limit=peers_max_n)}
                    for c in specs if c["engine"] != "inhouse"]
        specs = [c for c in specs if c["engine"] == "inhouse"]
    ctx = mp.get_context("fork")  # the scene is inherited, not pickled (5000 bodies)
    load0 = os.getloadavg()
    cells = [Cell(ctx, pile, spec) for spec in specs]
    for cell in cells:
        ans = cell.ask("warm", warm_cap)
        if ans is not None:
            cell.result.update(ans)
    for _ in range(repeats):
        for cell in cells:
            ans = cell.ask("cost", cap)
            if ans is not None:
                cell.result["walls"].append(ans["wall"])
                cell.result["cpus"].append(ans["cpu"])
                cell.result["steps"] = ans["steps"]
    # Soundness last: a slow accuracy pass (recording, the adapters' read-back of every pair)
    # that runs over its cap then costs the cell its soundness figures, not its timing.
    for cell in cells:
        ans = cell.ask("accuracy", accuracy_cap)
        if ans is not None:
            cell.result.update(ans)
        print(name, cell.spec["label"], {k: v for k, v in cell.result.items()
                                        if k not in ("walls", "cpus")}, flush=True)
    for cell in cells:
        cell.stop()
    load1 = os.getloadavg()
    rows = []
    for cell in cells:
        r = cell.result
        r.update(scene=name, n=pile.n, dimension=pile.dimension, load_before=load0[0],
                 load_after=load1[0], recorded=time.strftime("%Y-%m-%d %H:%M:%S %Z"),
                 duration=pile.scene.run.duration)
        if r["walls"]:
            steps = r["steps"]
            r["steps_per_s"] = steps / min(r["walls"])
            r["steps_per_s_median"] = steps / statistics.median(r["walls"])
            r["repeats"] = len(r["walls"])
        elif "capped" in r:
            done = r.get("steps") or int(pile.scene.run.duration / DT)
            r["steps_per_s_below"] = done / cap
        rows.append(r)
        print(name, r["label"], r.get("steps_per_s"), r.get("capped") or r.get("error") or "",
              flush=True)
    return rows + skipped


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[200, 1000, 5000])
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--cap", type=float, default=120.0)
    # 0.3 s by default, not CONTACTS.md 3b's 1 s: the grid's gaps are 1 cm (spheres), so the
    # layers land early and most timed steps are a pile in contact (piles.md gives the speeds at
    # the end); a 5000-body pile at 1 s would hold the shared 2-core machine for an hour.
    ap.add_argument("--duration", type=float, default=DEFAULT_DURATION)
    ap.add_argument("--only", nargs="*")
    ap.add_argument("--warm-cap", type=float, default=900.0,
                    help="s for a worker's first step (a first numba compilation takes minutes)")
    ap.add_argument("--accuracy-cap", type=float, default=300.0)
    ap.add_argument("--peers-max-n", type=int, default=10**9,
                    help="peers are not run on larger piles (see PEERS_NOT_RUN)")
    ap.add_argument("--cells", nargs="*", help="labels of the cells to run (default: all)")
    ap.add_argument("--out", type=Path, default=OUT)
    ap.add_argument("--add", action="store_true",
                    help="with --only and --cells: replace only these cells' rows of the "
                         "scenes in --out's piles.json, keeping the others")
    ap.add_argument("--merge", nargs="+", type=Path,
                    help="run nothing: combine these piles.json files (a later file's scenes "
                         "replace an earlier one's) into --out")
    args = ap.parse_args(argv)
    if args.merge:
        return merge(args.merge, args.out)
    if args.add and not (args.only and args.cells and (args.out / "piles.json").exists()):
        ap.error("--add needs --only, --cells and an existing piles.json in --out")
    import numba
    meta = {"recorded": time.strftime("%Y-%m-%d %H:%M:%S %Z"), "machine": platform.machine(),
            "cores": os.cpu_count(), "python": platform.python_version(),
            "numba": numba.__version__, "repeats": args.repeats, "cap_seconds": args.cap,
            "dt": DT, "duration": args.duration, "engines": _versions(),
            "started_load": os.getloadavg()[0]}
    todo = scenes(args.sizes, args.only, args.duration)
    rows = []
    if args.only and (args.out / "piles.json").exists():
        # A run of some scenes only replaces those scenes' rows and keeps the others (each
        # scene's ratios come from one invocation; its meta is kept per row).
        old = json.loads((args.out / "piles.json").read_text())
        names = {name for name, _ in todo}
        if args.add:  # keep the scenes' other cells; the timed ones replace their old rows
            rows = [r for r in old["rows"]
                    if r["scene"] not in names or r["label"] not in args.cells]
            meta = dict(old["meta"], added=[*old["meta"].get("added", []), meta])
        else:
            rows = [r for r in old["rows"] if r["scene"] not in names]
    for name, build in todo:
        new = run_scene(name, build, args.repeats, args.cap, args.cells,
                        warm_cap=args.warm_cap, accuracy_cap=args.accuracy_cap,
                        peers_max_n=args.peers_max_n)
        if args.add:  # only the timed cells, in the scene's place, marked as added
            new = [dict(r, added=True) for r in new if not r.get("not_run")]
            at = max((i for i, r in enumerate(rows) if r["scene"] == name), default=len(rows) - 1)
            rows[at + 1:at + 1] = new
        else:
            rows += new
        _write(args.out, meta, rows)  # after every scene: a stopped run keeps what it measured
    if not args.add:
        meta["finished_load"] = os.getloadavg()[0]
    _write(args.out, meta, rows)


def merge(files: list[Path], out: Path) -> None:
    """Several invocations' results as one page (e.g. two scene sets run side by side); each
    row keeps the load and time of its own scene, and every ratio is within one scene."""
    metas, rows = [], []
    for f in files:
        doc = json.loads(f.read_text())
        new = {r["scene"] for r in doc["rows"]}
        rows = [r for r in rows if r["scene"] not in new] + doc["rows"]
        metas.append(doc["meta"])
    meta = dict(metas[0])
    meta["engines"] = _versions()  # pybullet has no __version__: earlier files said None
    meta["recorded"] = ", ".join(dict.fromkeys(m["recorded"] for m in metas))
    meta["invocations"] = metas
    _write(out, meta, rows)


def _versions() -> dict:
    from importlib.metadata import PackageNotFoundError, version

    out = {}
    for dist in ("mujoco", "pybullet", "pymunk"):
        try:
            out[dist] = version(dist)
        except PackageNotFoundError:
            out[dist] = None
    return out


def _write(out: Path, meta: dict, rows: list[dict]) -> None:
    out.mkdir(parents=True, exist_ok=True)
    (out / "piles.json").write_text(json.dumps({"meta": meta, "rows": rows}, indent=1,
                                               default=str))
    (out / "piles.md").write_text(report(meta, rows))


if __name__ == "__main__":
    main()
