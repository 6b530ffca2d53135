"""Fill numba's on-disk cache for the in-house engine's cells, the compile work split across
processes so that each compiles different kernels.

Why: the in-house kernels are compiled on first use and cached on disk (``cache=True``,
sim/_jit.py); a cold compile of the 3D velocity-level contact step alone takes about two minutes.
Under pytest-xdist both workers reach the same kernels at about the same time and, numba having no
lock between processes, both compile them: the CPU is paid twice and the second core does nothing
useful. ``warm(parts=2)`` instead runs the cells of the case files, one step each, in two
processes that take disjoint families of kernels (3D velocity-level and impulse_lcp contact,
which share the 3D detection; everything else), so both cores compile different code and every
later process loads it from the cache (the same scenes through the same adapter give the same
type signatures, hence the same cache index keys). Nothing here is checked: a cell that fails to
open or step is printed and left to the tests, which run it for real (the repository's top-level
conftest.py calls this before the xdist workers start). Kernels only the tests call with their
own signatures (e.g. tests/collide's direct box_box) are still compiled by the tests.

``python -m crosscheck.warmup`` warms everything in this process; ``--part i/n`` only the cells
of part i; ``--parallel n`` runs the n parts as child processes and waits for them.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

CASES = Path(__file__).resolve().parents[2] / "cases"

# Families of cells whose kernels are shared (an in-house run's base dimension and contact model;
# the velocity-level models sequential_impulse and soft_step step through one kernel each per
# dimension), in the order of two parts. The 3D detection (collide.detect3d, about half of the
# cold compile) is shared by every 3D contact model: the first part compiles it with the
# velocity-level step, the second does everything else and the 3D penalty model last, when it
# finds detect3d in the cache. Other part counts take the families round-robin in this order.
PARTS = (("3d-velocity", "3d-impulse_lcp"),
         ("2d-velocity", "2d-impulse_lcp", "2d-penalty", "2d-free", "fluid", "native", "3d-free",
          "3d-penalty"))
VELOCITY_MODELS = ("soft_step", "sequential_impulse")
NATIVE = ("mujoco", "pymunk")


def family(scene, engine: str, integrator: str) -> str:
    """The family of kernels a cell compiles (PARTS)."""
    from crosscheck.names import split_run

    if engine != "inhouse":
        return "native"
    if scene.fluid is not None:
        return "fluid"
    _, model = split_run(integrator)
    if model in VELOCITY_MODELS:
        model = "velocity"
    return f"{scene.dimension}d-{model or 'free'}"


def cells(case_dir: Path = CASES) -> list[tuple[str, object, str, str, float]]:
    """(family, scene, engine, integrator, dt) of every in-house cell of the case files under
    case_dir, and of one cell per dimension of the engines stepped by compiled loops
    (engines/_native.py: MuJoCo, Pymunk), in file order."""
    from crosscheck.runner.plan import build_matrix
    from crosscheck.scene.loader import is_case_file, load_case

    if not Path(case_dir).is_dir():
        return []
    scenes = [load_case(p) for p in sorted(Path(case_dir).rglob("*.toml")) if is_case_file(p)]
    by_file = {str(s.source): s for s in scenes}
    with tempfile.TemporaryDirectory() as tmp:  # references are planned, never run here
        matrix = build_matrix(scenes, engines=["inhouse", *NATIVE], cost=False, out=tmp)
    out, native = [], set()
    for cell in matrix.cells:
        scene = by_file[str(cell["case_file"])]
        engine = cell["engine"]
        if engine != "inhouse":
            if (engine, scene.dimension) in native or scene.fluid is not None:
                continue
            native.add((engine, scene.dimension))
        out.append((family(scene, engine, cell["integrator"]), scene, engine,
                    cell["integrator"], cell["dt"]))
    return out


def split(families: list[str], parts: int) -> list[list[str]]:
    """The families of each part, in the order they are warmed."""
    order = [f for part in PARTS for f in part]
    order += sorted(set(families) - set(order))
    if parts == len(PARTS):
        extra = [f for f in order if not any(f in p for p in PARTS)]
        return [list(PARTS[0]), list(PARTS[1]) + extra]
    return [order[i::parts] for i in range(parts)]


def warm_cell(engine, scene, integrator: str, dt: float) -> None:
    """Open the cell's session and take one step: compiles (or loads) what a run of it uses."""
    if engine.not_applicable(scene, integrator) is not None:
        return
    if scene.fluid is not None and not engine.maps_fluid(scene):
        session = engine.open_fluid(scene, integrator, dt)
        try:
            session.advance(1)
        finally:
            session.close()
        return
    session = engine.open(scene, integrator, dt)
    try:
        session.advance(1)
        session.read_raw()
    finally:
        session.close()


def warm_part(part: int, parts: int, case_dir: Path = CASES, verbose: bool = False) -> int:
    """Warm the cells of one part; returns the number of cells that raised."""
    from crosscheck.engines import get_engine

    todo = cells(case_dir)
    mine = split([f for f, *_ in todo], parts)[part]
    todo.sort(key=lambda cell: mine.index(cell[0]) if cell[0] in mine else len(mine))
    failed = 0
    for fam, scene, engine, integrator, dt in todo:
        if fam not in mine:
            continue
        t0 = time.perf_counter()
        try:
            warm_cell(get_engine(engine), scene, integrator, dt)
        except Exception as exc:  # left to the tests, which run the cell for real
            failed += 1
            print(f"warmup: {scene.name} {engine}-{integrator}: {type(exc).__name__}: {exc}",
                  file=sys.stderr)
        if verbose:
            print(f"warmup[{part}]: {time.perf_counter() - t0:7.2f} s  {fam:16s} {scene.name} "
                  f"{engine}-{integrator}", file=sys.stderr)
    return failed


def warm(parts: int = 2, timeout: float = 1200.0, case_dir: Path = CASES
         ) -> list[tuple[int, float, str]]:
    """Run the parts as child processes in parallel; (exit status, seconds, stderr tail) each.
    A part that outlives ``timeout`` is killed (status None)."""
    t0 = time.perf_counter()
    procs = [subprocess.Popen([sys.executable, "-m", "crosscheck.warmup", "--part",
                               f"{i}/{parts}", "--cases", str(case_dir)],
                              stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
                              env=dict(os.environ))
             for i in range(parts)]
    out = []
    for p in procs:
        try:
            _, err = p.communicate(timeout=max(1.0, timeout - (time.perf_counter() - t0)))
        except subprocess.TimeoutExpired:
            p.kill()
            _, err = p.communicate()
            p.returncode = None
        out.append((p.returncode, time.perf_counter() - t0, (err or "")[-2000:]))
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m crosscheck.warmup", description=__doc__)
    ap.add_argument("--part", default="0/1", help="i/n: warm part i of n (default: all)")
    ap.add_argument("--parallel", type=int, default=0,
                    help="run this many parts as child processes")
    ap.add_argument("--cases", default=str(CASES), help="case folder (default: the repo's)")
    ap.add_argument("-v", "--verbose", action="store_true")
    args = ap.parse_args(argv)
    if args.parallel:
        results = warm(args.parallel, case_dir=Path(args.cases))
        for i, (code, seconds, err) in enumerate(results):
            print(f"warmup part {i}: exit {code}, {seconds:.1f} s")
            if code != 0 and err:
                print(err, file=sys.stderr)
        return 0
    i, _, n = args.part.partition("/")
    failed = warm_part(int(i), int(n or 1), Path(args.cases), verbose=args.verbose)
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
