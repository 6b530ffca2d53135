"""A run against the case's own table (``reference.file``; format in docs/cases.md).

For every compared column c: ``table_<c>_error_max`` and ``table_<c>_error_rms``, the largest
and the root-mean-square absolute difference run - table over the table's points, in c's units.
The table says where the comparison is made: the run is interpolated to its points (linearly in
t for a series, linearly in space on the staggered grid for a profile); the run is never
extrapolated. A series point after the run's last sample (a run that stopped early) makes both
metrics of that column infinite, so such a run fails any tolerance on them.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from crosscheck.scene.model import UserTable


def table_metrics(scene: Any, output: Any) -> dict[str, float]:
    """The metrics of ``output`` (a Trajectory or a FluidRecord) against ``scene``'s own table;
    empty when the case has none."""
    table = scene.reference.data
    if table is None:
        return {}
    if table.axis == "t":
        t = np.asarray(output.t, float)
        return _errors(table, lambda name, at: _series(scene, output, table, name, t, at),
                       covered=(table.columns["t"] <= (t[-1] if len(t) else -math.inf)))
    return _errors(table, lambda name, at: _profile(scene, output, table, name, at),
                   covered=np.ones(len(table.columns[table.axis]), bool))


def _errors(table: UserTable, run_at, covered: np.ndarray) -> dict[str, float]:
    out = {}
    at = table.columns[table.axis]
    for name in table.compared:
        if not np.all(covered):
            out[f"table_{name}_error_max"] = out[f"table_{name}_error_rms"] = math.inf
            continue
        diff = run_at(name, at) - table.columns[name]
        out[f"table_{name}_error_max"] = float(np.max(np.abs(diff)))
        out[f"table_{name}_error_rms"] = float(np.sqrt(np.mean(diff**2)))
    return out


def _series(scene: Any, output: Any, table: UserTable, name: str, t: np.ndarray,
            at: np.ndarray) -> np.ndarray:
    if scene.fluid is not None:
        y = np.asarray(output.series[name], float)
    else:
        y = _rigid_column(output, table.body, name)
    return np.interp(at, t, y)


def _rigid_column(traj: Any, body: int, name: str) -> np.ndarray:
    axis = {"x": 0, "y": 1, "z": 2}
    quantity, _, component = name.partition("_")
    if name == "angle":
        return np.asarray(traj.angle[:, body], float)
    if name == "omega":  # 2D: the scalar angular velocity
        return np.asarray(traj.omega[:, body], float)
    source = {"com": traj.com, "vel": traj.vel, "omega": traj.omega}[quantity]
    return np.asarray(source[:, body, axis[component]], float)


def _profile(scene: Any, record: Any, table: UserTable, name: str, at: np.ndarray) -> np.ndarray:
    """``name`` (u or v) of the last field snapshot at the table's points on its line.

    The grid is staggered (u on x-faces at (i dx, (j + 1/2) dx), v on y-faces at
    ((i + 1/2) dx, j dx)): bilinear interpolation in index space of each component's own
    lattice, clamped at the outermost samples (the wall values lie half a cell beyond u's first
    and last rows, so a point on a wall takes the nearest interior value)."""
    from scipy.ndimage import map_coordinates

    dx = scene.fluid.dx
    field = np.asarray(record.fields[name][-1], float)
    xs = at if table.axis == "x" else np.full_like(at, table.line)
    ys = at if table.axis == "y" else np.full_like(at, table.line)
    if name == "u":
        gi, gj = xs / dx, ys / dx - 0.5
    else:
        gi, gj = xs / dx - 0.5, ys / dx
    return map_coordinates(field, [gi, gj], order=1, mode="nearest")
