"""A case's own reference data: ``[reference] kind = "table"`` with ``file = "data.csv"``.

Read and checked at load (docs/cases.md, "Your own data"), so a bad file is refused before
anything runs, with the file, the field ``reference.file`` and what was wrong (the CSV line and
column when there is one). The format is the one of the shipped tables: ``#`` comment lines
(kept as the source), one header line, then rows of comma-separated numbers. The first column
says what the table is:

* ``t``: a time series (s, strictly increasing, within the run): the run is interpolated
  linearly in t to the table's times;
* ``x`` or ``y``: a fluid profile along the line ``y = reference.y`` (or ``x = reference.x``),
  m, compared with the last field snapshot, interpolated linearly in space to the table's points.

The other columns name the quantities compared (:data:`RIGID_COLUMNS`, :data:`FLUID_SERIES`,
:data:`PROFILE_COLUMNS`), SI units.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np

from crosscheck.errors import CaseError
from crosscheck.scene.fields import Fields
from crosscheck.scene.model import UserTable

RIGID_COLUMNS = {
    2: ("com_x", "com_y", "vel_x", "vel_y", "angle", "omega"),
    3: ("com_x", "com_y", "com_z", "vel_x", "vel_y", "vel_z", "omega_x", "omega_y", "omega_z"),
}
# FluidRecord.series entries that have a unit and mean the same in every run; front and
# surface_height exist only with a free surface.
FLUID_SERIES = ("volume", "kinetic_energy", "max_speed", "front", "surface_height")
SURFACE_ONLY = ("front", "surface_height")
PROFILE_COLUMNS = ("u", "v")
# A table time may pass the run's duration by this much (its own decimal rounding).
TIME_SLACK = 1e-9


def read_user_table(f: Fields, base_dir: Path, *, dimension: int, duration: float,
                    body_names: tuple[str, ...], fluid: Any) -> UserTable:
    """The table ``f["file"]`` names (relative to the case's folder), checked against the case."""
    rel = f.string("file")
    path = (base_dir / rel) if not Path(rel).is_absolute() else Path(rel)
    header, rows, source = _parse(f, path)
    axis, names = header[0], header[1:]
    if axis not in ("t", "x", "y") or not names:
        raise f.error("file", f"a CSV whose first column is t (a time series) or x / y (a fluid "
                      f"profile), followed by at least one compared column ({path})", header)
    data = {h: rows[:, i] for i, h in enumerate(header)}
    line = body = None
    if axis == "t":
        known = _series_columns(dimension, fluid)
        _check_names(f, path, names, known)
        t = data["t"]
        if np.any(np.diff(t) <= 0):
            k = int(np.flatnonzero(np.diff(t) <= 0)[0])
            raise f.error("file", f"strictly increasing t in {path}", f"t = {t[k]:g} then "
                          f"{t[k + 1]:g} (data rows {k + 1} and {k + 2})")
        if t[0] < 0 or t[-1] > duration * (1 + TIME_SLACK):
            raise f.error("file", f"times within the run, 0 to run.duration = {duration:g} s "
                          f"({path})", f"t from {t[0]:g} to {t[-1]:g}")
        if fluid is None:
            body = _body(f, body_names)
    else:
        if fluid is None:
            raise f.error("file", f"a time series (first column t) for a rigid case: profiles "
                          f"along x or y are fluid data ({path})", axis)
        _check_names(f, path, names, PROFILE_COLUMNS)
        other = "y" if axis == "x" else "x"
        line = f.number(other, unit="m")
        size = dict(zip(("x", "y"), fluid.domain, strict=True))
        if not 0 <= line <= size[other]:
            raise f.error(other, f"a line inside the domain, 0 to {size[other]:g} m", line)
        pos = data[axis]
        if pos.min() < 0 or pos.max() > size[axis]:
            raise f.error("file", f"{axis} within the domain, 0 to {size[axis]:g} m ({path})",
                          f"{axis} from {pos.min():g} to {pos.max():g}")
        missing = [c for c in names if c not in fluid.output.fields]
        if missing:
            raise CaseError(f.file, "fluid.output.fields", f"{missing} recorded: the profile in "
                            f"{path} compares them with the last field snapshot",
                            list(fluid.output.fields))
    for frozen in data.values():
        frozen.setflags(write=False)
    return UserTable(path=path, axis=axis, columns=data, line=line, body=body,
                     source=tuple(source))


def _series_columns(dimension: int, fluid: Any) -> tuple[str, ...]:
    if fluid is None:
        return RIGID_COLUMNS[dimension]
    if fluid.has_surface:
        return FLUID_SERIES
    return tuple(c for c in FLUID_SERIES if c not in SURFACE_ONLY)


def _check_names(f: Fields, path: Path, names: list[str], known: tuple[str, ...]) -> None:
    for name in names:
        if name not in known:
            raise f.error("file", f"column names this case can compare, one of {list(known)} "
                          f"({path})", f"column {name!r}")
    if len(set(names)) != len(names):
        raise f.error("file", f"each column once ({path})", names)


def _body(f: Fields, body_names: tuple[str, ...]) -> int:
    """The body a rigid series describes: ``reference.body``, needed when there are several."""
    if f.has("body") or len(body_names) != 1:
        name = f.string("body")
        if name not in body_names:
            raise f.error("body", f"the name of a body ({list(body_names)})", name)
        return body_names.index(name)
    return 0


def _parse(f: Fields, path: Path) -> tuple[list[str], np.ndarray, list[str]]:
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as exc:
        raise f.error("file", f"a readable CSV file ({path}: {exc.strerror or exc}; a relative "
                      "path starts at the case's folder)", path.name) from None
    except UnicodeDecodeError:
        raise f.error("file", f"a UTF-8 text CSV ({path})") from None
    header, rows, source = None, [], []
    for number, raw in enumerate(text.splitlines(), start=1):
        line = raw.strip()
        if not line:
            continue
        if line.startswith("#"):
            source.append(line.lstrip("# ").rstrip())
            continue
        cells = [c.strip() for c in line.split(",")]
        if header is None:
            if any(not c for c in cells):
                raise f.error("file", f"a header line of column names ({path}, line {number})",
                              raw)
            header = cells
            continue
        if len(cells) != len(header):
            raise f.error("file", f"{len(header)} comma-separated values on every row "
                          f"({path}, line {number})", raw)
        row = []
        for name, cell in zip(header, cells, strict=True):
            try:
                value = float(cell)
            except ValueError:
                raise f.error("file", f"a number in column {name!r} ({path}, line {number})",
                              cell) from None
            if not math.isfinite(value):
                raise f.error("file", f"a finite number in column {name!r} ({path}, line "
                              f"{number})", cell)
            row.append(value)
        rows.append(row)
    if header is None or not rows:
        raise f.error("file", f"a CSV with a header line and at least one row of numbers "
                      f"({path})")
    return header, np.array(rows, float), source
