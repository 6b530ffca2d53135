"""Typed reading of one TOML table with the field path kept for error messages.

Every section parser (bodies, effects, fluid, ...) reads its table through a :class:`Fields`
cursor, so that every refusal names the file, the full field path and what was expected, and
unknown keys (typos) are refused the same way everywhere.
"""

from __future__ import annotations

import difflib
import math
import re
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import Any

import numpy as np

from crosscheck.errors import CaseError

_MISSING = object()
_BARE_KEY = re.compile(r"[A-Za-z0-9_-]+")


class Fields:
    """A cursor over a TOML table at ``path`` inside ``file``.

    Reading a key marks it as used; :meth:`done` refuses any key that was never read, which is how
    typos such as ``masss = 1`` are caught.
    """

    def __init__(self, table: Any, path: str, file: str | Path | None):
        self.file = file
        self.path = path
        if not isinstance(table, dict):
            raise CaseError(file, path, "a table", table)
        self.table = table
        self._used: set[str] = set()
        # Keys the parser looked at, read or only tested with has(): the valid keys an
        # unknown-key error lists (a key only tested for, e.g. an absent optional one, is valid).
        self._known: set[str] = set()

    # -- paths and errors -------------------------------------------------------------------
    def field(self, key: str | int) -> str:
        if isinstance(key, int):
            return f"{self.path}[{key}]"
        if not _BARE_KEY.fullmatch(key):  # written as TOML would: energy_drift."mujoco.euler"
            key = '"' + key.replace("\\", "\\\\").replace('"', '\\"') + '"'
        return f"{self.path}.{key}" if self.path else key

    def error(self, key: str | int, expected: str, got: object = None) -> CaseError:
        return CaseError(self.file, self.field(key), expected, got)

    def has(self, key: str) -> bool:
        self._known.add(key)
        return key in self.table

    def _get(self, key: str, default: Any) -> Any:
        self._used.add(key)
        self._known.add(key)
        if key in self.table:
            return self.table[key]
        if default is _MISSING:
            # a typo of a required key is reported here, before done() could call it unknown
            near = difflib.get_close_matches(key, [k for k in self.table if isinstance(k, str)],
                                             n=1, cutoff=0.75)
            hint = f"; is {near[0]!r} a typo of it?" if near else ""
            raise CaseError(self.file, self.field(key),
                            f"this required field (it is missing{hint})")
        return default

    def done(self, allowed_extra: Iterable[str] = ()) -> None:
        """Refuse keys that were never read (typos) with the list of keys that are valid here."""
        unknown = [k for k in self.table if k not in self._used and k not in set(allowed_extra)]
        if unknown:
            valid = sorted(self._known | set(allowed_extra))
            raise CaseError(
                self.file, self.field(unknown[0]), f"one of the known keys {valid}",
                f"unknown key {unknown[0]!r}",
            )

    # -- typed getters ----------------------------------------------------------------------
    def sub(self, key: str, default: Any = _MISSING) -> Fields | None:
        value = self._get(key, default)
        if value is None:
            return None
        return Fields(value, self.field(key), self.file)

    def table_list(self, key: str, default: Any = _MISSING) -> list[Fields]:
        value = self._get(key, default)
        if not isinstance(value, list) or not all(isinstance(v, dict) for v in value):
            raise self.error(key, "an array of tables ([[...]] entries)", value)
        return [Fields(v, f"{self.field(key)}[{i}]", self.file) for i, v in enumerate(value)]

    def string(self, key: str, default: Any = _MISSING,
               choices: Iterable[str] | None = None) -> str:
        value = self._get(key, default)
        if value is default and default is not _MISSING:
            return value
        if not isinstance(value, str):
            raise self.error(key, "a string", value)
        if choices is not None:
            choices = list(choices)
            if value not in choices:
                raise self.error(key, f"one of {choices}", value)
        return value

    def boolean(self, key: str, default: Any = _MISSING) -> bool:
        value = self._get(key, default)
        if not isinstance(value, bool):
            raise self.error(key, "true or false", value)
        return value

    def number(self, key: str, default: Any = _MISSING, *, positive: bool = False,
               nonnegative: bool = False, unit: str = "") -> float:
        value = self._get(key, default)
        if value is default and default is not _MISSING and value is None:
            return value
        return check_number(value, self.file, self.field(key), positive=positive,
                            nonnegative=nonnegative, unit=unit)

    def integer(self, key: str, default: Any = _MISSING, *, minimum: int | None = None) -> int:
        value = self._get(key, default)
        if isinstance(value, bool) or not isinstance(value, int):
            raise self.error(key, "an integer", value)
        if minimum is not None and value < minimum:
            raise self.error(key, f"an integer >= {minimum}", value)
        return value

    def vector(self, key: str, n: int, default: Any = _MISSING, *, positive: bool = False,
               unit: str = "") -> np.ndarray:
        value = self._get(key, default)
        if value is default and default is not _MISSING and value is None:
            return value
        return check_vector(value, n, self.file, self.field(key), positive=positive, unit=unit)

    def string_list(self, key: str, default: Any = _MISSING) -> tuple[str, ...]:
        value = self._get(key, default)
        if not isinstance(value, list) or not all(isinstance(v, str) for v in value):
            raise self.error(key, "an array of strings", value)
        return tuple(value)

    def raw(self, key: str, default: Any = _MISSING) -> Any:
        return self._get(key, default)


def _unit(unit: str) -> str:
    return f" in {unit}" if unit else ""


def check_number(value: Any, file, field: str, *, positive: bool = False,
                 nonnegative: bool = False, unit: str = "") -> float:
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise CaseError(file, field, f"a number{_unit(unit)}", value)
    value = float(value)
    if not math.isfinite(value):
        raise CaseError(file, field, f"a finite number{_unit(unit)}", value)
    if positive and value <= 0:
        raise CaseError(file, field, f"a positive number{_unit(unit)}", value)
    if nonnegative and value < 0:
        raise CaseError(file, field, f"a non-negative number{_unit(unit)}", value)
    return value


def check_vector(value: Any, n: int, file, field: str, *, positive: bool = False,
                 unit: str = "") -> np.ndarray:
    what = f"an array of {n} {'positive ' if positive else ''}finite numbers{_unit(unit)}"
    if not isinstance(value, list) or len(value) != n:
        raise CaseError(file, field, what, value)
    for i, item in enumerate(value):
        check_number(item, file, f"{field}[{i}]", positive=positive, unit=unit)
    arr = np.array(value, dtype=float)
    arr.setflags(write=False)
    return arr


def one_of(fields: Fields, key: str, options: dict[str, Callable[[Fields], Any]]) -> Any:
    """Read a table that holds exactly one of several keys, e.g. ``shape = { box = {...} }``."""
    sub = fields.sub(key)
    present = [k for k in sub.table if k in options]
    if len(present) != 1 or len(sub.table) != 1:
        raise CaseError(fields.file, fields.field(key),
                        f"a table with exactly one of {sorted(options)}",
                        sub.table)
    name = present[0]
    return name, options[name](sub.sub(name))
