"""The HTML report's per-case figures, drawn side by side in worker processes.

Drawing is most of the report's cost: the 305-cell run of cases/ draws 41 figures over time and
18 cost figures, 20 s of one process after the last cell has finished (matplotlib's Agg draw of
axes and tick labels 12 s, the PNG encoding the rest; profiled 2026-11-30), while the machine's
other cores wait. The cases' figures are independent of each other, so a report of several cases
draws them in a pool of processes, one case per task; a small report (fewer cases than
:data:`POOL_FROM_CASES`) draws in the calling process, where starting the pool would cost more
than it saves.

Workers are started with ``spawn``, as the runner's are (runner/local.py): nothing inherited from a
parent that may hold threads (a Dask client, a progress bar). A figure that fails is returned as
its error's text and the page says so; a pool that cannot start or breaks falls back to drawing
in the calling process with a warning, so the report never depends on it.
"""

from __future__ import annotations

import os
from typing import Any

# At least this many cases, and two usable cores, before figures are drawn in a pool: a spawned
# worker takes about 1 s to import matplotlib, about three cases' drawing.
POOL_FROM_CASES = 4
MAX_WORKERS = 8

# Per case: (the figure over time, the cost figure), each a plots.Figure, None (nothing to draw)
# or the text of the error that stopped it.
Drawn = tuple[Any, Any]


def draw_case(case: str, group: list[dict[str, Any]]) -> Drawn:
    """Both figures of one case, with one look per run shared by the two."""
    from crosscheck.report.cost_plot import cost_figure
    from crosscheck.report.plots import case_figure
    from crosscheck.report.style import Looks

    looks = Looks.of(group)
    out = []
    for make in (case_figure, cost_figure):
        try:
            out.append(make(case, group, looks))
        except Exception as exc:  # a plotting failure must not lose the report
            out.append(f"{type(exc).__name__}: {exc}")
    return out[0], out[1]


def usable_cores() -> int:
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # pragma: no cover - not Linux
        return os.cpu_count() or 1


def draw_all(groups: dict[str, list[dict[str, Any]]], workers: int | None = None
             ) -> dict[str, Drawn]:
    """Every case's figures, in the order of ``groups``."""
    workers = min(workers or usable_cores(), MAX_WORKERS, len(groups))
    if workers < 2 or len(groups) < POOL_FROM_CASES:
        return {case: draw_case(case, group) for case, group in groups.items()}
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor

    try:
        with ProcessPoolExecutor(workers, mp_context=multiprocessing.get_context("spawn")) as pool:
            # the largest groups first, so that no long case is left for the end
            order = sorted(groups, key=lambda case: -len(groups[case]))
            futures = {case: pool.submit(draw_case, case, groups[case]) for case in order}
            drawn = {case: futures[case].result() for case in order}
    except Exception as exc:  # the pool itself failed (draw_case returns its own errors)
        import warnings

        warnings.warn(f"report figures drawn in one process: the pool of {workers} failed "
                      f"({type(exc).__name__}: {exc})", RuntimeWarning, stacklevel=2)
        return {case: draw_case(case, group) for case, group in groups.items()}
    return {case: drawn[case] for case in groups}
