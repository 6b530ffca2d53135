"""Published fluid validation data shipped with crosscheck (``reference/data/*.csv``).

Each CSV keeps its source lines as ``#`` comments at the top; :func:`load_table` returns the
columns and those lines, so reports can cite where the numbers come from.

* ``martin_moyce_1952``: surge-front position Z = x/a against T = t sqrt(2 g / a) of a collapsing
  water column of width a = 2.25 in and height 2a (Martin & Moyce 1952, Table 2).
* ``ghia_1982_re100_u``: u along the vertical centreline x = 0.5 of the unit lid-driven cavity at
  Re = 100; ``ghia_1982_re100_v``: v along the horizontal centreline y = 0.5 (Ghia, Ghia & Shin
  1982, Tables I and II). Lid speed 1, lid at y = 1 moving in +x.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from importlib import resources

import numpy as np

TABLES = {
    "martin_moyce_1952": "martin_moyce1952_front_a2.25in.csv",
    "ghia_1982_re100_u": "ghia1982_re100_u_vertical_centreline.csv",
    "ghia_1982_re100_v": "ghia1982_re100_v_horizontal_centreline.csv",
}


@dataclass(frozen=True)
class Table:
    name: str
    columns: dict[str, np.ndarray]
    source: tuple[str, ...]

    def __getitem__(self, key: str) -> np.ndarray:
        return self.columns[key]


def load_table(name: str) -> Table:
    if name not in TABLES:
        raise KeyError(f"unknown fluid reference table {name!r}; known: {sorted(TABLES)}")
    text = resources.files("crosscheck.reference").joinpath("data", TABLES[name]).read_text()
    source = []
    rows = []
    header = None
    for line in text.splitlines():
        line = line.strip()
        if not line:
            continue
        if line.startswith("#"):
            source.append(line.lstrip("# ").rstrip())
        elif header is None:
            header = [h.strip() for h in line.split(",")]
        else:
            rows.append([float(v) for v in line.split(",")])
    data = np.array(rows)
    return Table(name, {h: data[:, i] for i, h in enumerate(header)}, tuple(source))


def sloshing_period(width: float, depth: float, g: float, mode: int = 1) -> float:
    """Linear (small-amplitude) standing-wave period in a rectangular tank:
    w^2 = g k tanh(k h) with k = mode pi / width."""
    k = mode * math.pi / width
    return 2 * math.pi / math.sqrt(g * k * math.tanh(k * depth))
