"""One look per run across a report: each engine-integrator gets a colour and a marker.

A run is named by its engine and integrator ("mujoco-rk4", "inhouse-symplectic_euler+soft_step");
the name is an opaque label here. The labels of a report are numbered in a fixed order (engine,
then the order the runs first appear) and the k-th label gets colour k and marker k: with
twenty colours and eleven markers (coprime counts) no two of the first 220 labels share both, so
runs stay distinguishable in print, for colour-blind readers and on a grey-scale screen, and a
run looks the same in every figure of the report (time series, cost, sweep).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

# matplotlib's tab10 then the light halves of tab20: qualitative, readable on white.
COLORS = ("#1f77b4", "#d62728", "#2ca02c", "#ff7f0e", "#9467bd", "#8c564b", "#e377c2",
          "#17becf", "#7f7f7f", "#bcbd22", "#393b79", "#ad494a", "#637939", "#e6550d",
          "#7b4173", "#843c39", "#3182bd", "#31a354", "#756bb1", "#636363")
MARKERS = ("o", "s", "^", "D", "v", "P", "X", "<", "*", ">", "h")
ENGINE_ORDER = ("inhouse", "mujoco", "pybullet", "pymunk")


def run_label(cell: dict[str, Any]) -> str:
    """The run's column name: engine-integrator (the integrator name may hold '+model')."""
    return f"{cell['engine']}-{cell['integrator']}"


@dataclass(frozen=True)
class Look:
    color: str
    marker: str


def _known_rank(engine: str, integrator: str) -> tuple[int, int] | None:
    """Where crosscheck.names lists the run: rigid integrators in its order, then contact runs
    (integrator+model) by their integrator, then fluid schemes; None for a name it lacks."""
    from crosscheck import names

    try:
        rigid, fluid = names.rigid_names(engine), names.fluid_names(engine)
    except (KeyError, ValueError):
        return None
    base = integrator.split(names.SEPARATOR, 1)[0]
    if integrator in rigid:
        return (0, rigid.index(integrator))
    if base in rigid:
        return (1, rigid.index(base))
    if integrator in fluid:
        return (2, fluid.index(integrator))
    return None


def ordered_labels(cells: list[dict[str, Any]]) -> list[str]:
    """Every run label of ``cells``, grouped by engine (known engines first), each engine's runs
    in crosscheck.names' order (rigid integrators, contact runs, fluid schemes), names it does
    not know (test fakes, adapters in development) after them in the order they appear."""
    first: dict[str, tuple] = {}
    for k, c in enumerate(cells):
        label = run_label(c)
        if label not in first:
            engine = c["engine"]
            rank = ENGINE_ORDER.index(engine) if engine in ENGINE_ORDER else len(ENGINE_ORDER)
            first[label] = (rank, _known_rank(engine, c["integrator"]) or (3, k), k)
    return sorted(first, key=lambda label: first[label])


class Looks:
    """Label -> Look, numbered in the order given; an unknown label gets the next free look."""

    def __init__(self, labels: list[str] | None = None):
        self._looks: dict[str, Look] = {}
        for label in labels or []:
            self[label]

    def __getitem__(self, label: str) -> Look:
        if label not in self._looks:
            k = len(self._looks)
            self._looks[label] = Look(COLORS[k % len(COLORS)], MARKERS[k % len(MARKERS)])
        return self._looks[label]

    @classmethod
    def of(cls, cells: list[dict[str, Any]]) -> Looks:
        return cls(ordered_labels(cells))
