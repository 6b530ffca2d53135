"""The runner: the matrix case x engine x integrator x dt in worker processes.

Public API
    :func:`crosscheck.runner.plan.build_matrix` -> Matrix of task dicts;
    :func:`schedule` runs them on a backend (:class:`~crosscheck.runner.local.LocalBackend` or
    :class:`~crosscheck.runner.dask_backend.DaskBackend`), calling ``on_result`` as each arrives;
    :func:`crosscheck.runner.session.run_and_report` does all of it for ``crosscheck run``,
    writing the reports as results come in.

Shared references (fine-step, engine) run first; the cells that need one are dispatched when it
is ready, with its file, or with the reason it failed. A cell never waits on anything else.
Cells ready at the start go out heaviest first (``task["work"]``, plan.expected_work: a fluid
cell's grid cells times steps, a rigid cell's bodies times steps): a long cell dispatched last
runs alone at the end (the gate's Wachs disc, 52 s, was the last of 307 cells). The gate
(`crosscheck run cases --no-cost`, 2 workers, warm, one after another on 2026-12-01): 127.5 s
of wall in the matrix's order, 115.5 s with the fluid cells first, 107.3 s with the rigid ones
ordered too, against 104 s of cell time per worker. The reports keep the matrix's order
whatever the dispatch.
"""

from __future__ import annotations

from collections import defaultdict, deque
from collections.abc import Callable
from typing import Any

Result = dict[str, Any]


def schedule(tasks: list[dict[str, Any]], backend, on_result: Callable[[dict, Result], None],
             poll_interval: float = 0.5) -> None:
    """Run every task on ``backend``, respecting ``depends_on``; returns when all are done.

    KeyboardInterrupt propagates (the caller kills the backend and reports what it has).
    """
    waiting: dict[str, list[dict[str, Any]]] = defaultdict(list)
    ready: deque[dict[str, Any]] = deque()
    for task in tasks:
        if task.get("depends_on"):
            waiting[task["depends_on"]].append(task)
        else:
            ready.append(task)
    # references first (cells wait on them), then the heaviest cells (stable: ties keep order)
    ready = deque(sorted(ready, key=lambda t: (t.get("kind") != "reference",
                                               -float(t.get("work") or 0.0))))
    inflight = 0
    held: list[dict[str, Any]] = []  # extra cost passes, released once no cell is waiting
    while ready or inflight or held:
        if held and not any(t.get("kind") != "cost" for t in ready):
            # By round (runner/cell.py cost_followups), so that each worker moves to a fresh
            # process once per round (LocalBackend.submit).
            ready.extend(sorted(held, key=lambda t: t.get("process_round") or 0))
            held.clear()
        while ready and backend.free():
            backend.submit(ready.popleft())
            inflight += 1
        for task, result in backend.poll(poll_interval):
            inflight -= 1
            if task.get("kind") == "reference":
                # Dependents go to the front: they finish a case while other references run.
                for dep in reversed(waiting.pop(task["id"], [])):
                    if result.get("status") == "ok":
                        dep["reference_file"] = result["path"]
                    else:
                        first = (result.get("reason") or "").splitlines()[:1]
                        dep["reference_error"] = (f"reference run {result.get('status')}: "
                                                  + (first[0] if first else ""))
                    ready.appendleft(dep)
            if task.get("kind") == "cell":
                # More processes' cost passes of this cell, queued last so they run later and
                # in other worker processes (runner/cell.py, cost_followups).
                from crosscheck.runner.cell import cost_followups

                held.extend(cost_followups(task, result))
            on_result(task, result)
    # Anything still waiting depended on a reference that never ran (should not happen).
    for deps in waiting.values():
        for dep in deps:
            dep["reference_error"] = "reference run never completed"
            ready.append(dep)
    if ready:
        schedule(list(ready), backend, on_result, poll_interval)
