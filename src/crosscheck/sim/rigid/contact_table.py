"""Per-contact memory across steps, keyed by the contact buffer's ``feature``: a fixed-size,
double-buffered open-addressing hash table (numba, no allocation after it is made).

A contact model that keeps something per contact from one step to the next (the penalty model's
friction anchors, ``penalty.py``) opens a new generation at the start of every step
(:func:`table_flip`: the current table becomes the previous one and the new one is cleared), looks
each row's feature up in the previous generation (:func:`table_find`) and stores what it keeps in
the new one (:func:`table_insert`). A contact absent from one step's detection is forgotten.
Lookups and inserts visit slots in a fixed order (linear probing from a multiplicative hash), so
the result is deterministic.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit

from crosscheck.sim._jit import INLINE

EMPTY = np.iinfo(np.int64).min  # no feature takes this value (features are >= 0)


class FeatureTable(NamedTuple):
    key: np.ndarray  # (2, K) int64: the feature, EMPTY where free; K a power of two
    value: np.ndarray  # (2, K, V) float64
    current: np.ndarray  # (1,) int64: which generation (0 or 1) is being written

    @classmethod
    def empty(cls, capacity: int, width: int) -> FeatureTable:
        size = 1
        while size < 2 * max(int(capacity), 1):
            size *= 2
        return cls(np.full((2, size), EMPTY, np.int64), np.zeros((2, size, int(width))),
                   np.zeros(1, np.int64))


@njit(**INLINE)
def _slot(feature, mask):
    # Fibonacci hashing of the 64-bit key (wrapping multiplication), then the table's bits.
    h = np.uint64(feature) * np.uint64(11400714819323198485)
    return np.int64((h >> np.uint64(32)) & np.uint64(mask))


@njit(**INLINE)
def table_flip(table):
    """Start a new generation: the written one becomes the previous one; clear the new one."""
    new = 1 - table.current[0]
    table.current[0] = new
    for k in range(table.key.shape[1]):
        table.key[new, k] = EMPTY


@njit(**INLINE)
def table_find(table, generation, feature):
    """Slot of ``feature`` in ``generation`` (0/1), or -1."""
    mask = table.key.shape[1] - 1
    k = _slot(feature, mask)
    for _ in range(table.key.shape[1]):
        key = table.key[generation, k]
        if key == feature:
            return k
        if key == EMPTY:
            return -1
        k = (k + 1) & mask
    return -1


@njit(**INLINE)
def table_insert(table, feature):
    """Slot for ``feature`` in the current generation (found or newly taken); -1 when full."""
    g = table.current[0]
    mask = table.key.shape[1] - 1
    k = _slot(feature, mask)
    for _ in range(table.key.shape[1]):
        key = table.key[g, k]
        if key == feature or key == EMPTY:
            table.key[g, k] = feature
            return k
        k = (k + 1) & mask
    return -1
