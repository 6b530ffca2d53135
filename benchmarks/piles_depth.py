"""The deepest overlap of an in-house pile at every step, not only at the accuracy pass's samples.

    .venv/bin/python benchmarks/piles_depth.py [--scene boxes] [--ground] [--n 200]
        [--duration 0.8] [--model soft_step] [--top 10]

Runs the pile of benchmarks/bench_piles.py (tests/piles/pile_scenes.py) through the in-house
adapter one step at a time and, before each step, runs detection on the state (what the solver
is given): the deepest row's depth, its pair and feature key (bit 31 of the low word: an edge
contact; otherwise reference side, reference face, incident face, point), and the rows. Prints
the deepest steps. Used to find the cubes' landing transient (docs/inhouse.md, "Speed on piles").
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests" / "piles"))

import pile_scenes  # noqa: E402

from crosscheck.engines.inhouse import InhouseEngine  # noqa: E402
from crosscheck.sim.collide import detect3d  # noqa: E402


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scene", choices=["spheres", "boxes"], default="boxes")
    ap.add_argument("--ground", action="store_true", help="the bare ground, no bin")
    ap.add_argument("--n", type=int, default=200)
    ap.add_argument("--duration", type=float, default=0.8)
    ap.add_argument("--model", default="soft_step")
    ap.add_argument("--top", type=int, default=10)
    args = ap.parse_args(argv)
    build = pile_scenes.boxes if args.scene == "boxes" else pile_scenes.spheres
    pile = build(args.n, walls=not args.ground, duration=args.duration)
    session = InhouseEngine().open(pile.scene, f"symplectic_euler+{args.model}", pile_scenes.DT)
    st = session.contact
    log = []
    for k in range(int(round(args.duration / pile_scenes.DT))):
        count = detect3d(st.geometry, session.state.x.copy(), session.state.rot.copy(),
                         st.contacts)
        c = st.contacts
        if count:
            i = int(np.argmax(c.depth[:count]))
            log.append((float(c.depth[i]), k, int(c.a[i]), int(c.b[i]),
                        int(c.feature[i]) & 0xFFFFFFFF, int(count)))
        session.advance(1)
    session.close()
    for depth, k, a, b, feature, count in sorted(log, reverse=True)[:args.top]:
        kind = "edge" if feature >> 31 else "face"
        print(f"t = {k * pile_scenes.DT:.3f} s  depth {depth * 1e3:.3f} mm  pair {a}-{b}  "
              f"{kind} feature {feature:#x}  rows {count}")


if __name__ == "__main__":
    main()
