"""How far a result on a finite grid is from the grid's limit: the three-grid procedure of
Celik, Ghia, Roache, Freitas, Coleman and Raad (2008, "Procedure for estimation and reporting
of uncertainty due to discretization in CFD applications", J. Fluids Eng. 130:078001), the one
the journal asks of its authors.

Three grids of spacings ``h1 < h2 < h3`` (any ratios) give values ``f1, f2, f3``. The apparent
order ``p`` is what makes ``f = f0 + C h^p`` hold through the three; ``f0`` is the Richardson
extrapolation; the grid convergence index ``GCI = Fs |f1 - f2| / |f1| / (r21^p - 1)`` (Fs = 1.25
for a three-grid study) bounds the fine grid's relative distance from the limit.

Whether the grids are in the asymptotic range cannot be read from one triple: the check often
quoted with the procedure, ``GCI_32 / (r21^p GCI_21)`` near 1, is 1 by construction when ``p``
comes from the same three values (the indices' absolute sizes are ``Fs C h2^p`` and ``Fs C
h1^p``; the relative ones differ from 1 only by ``f1 / f2``). A sequence of four grids or more
gives one triple per three neighbours, and their orders and limits agreeing is what shows the
range; :func:`grid_sequence` gives them.

Used by the benchmarks' grid studies (DFG, sedimentation); nothing here runs a simulation.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from scipy.optimize import brentq

SAFETY_FACTOR = 1.25   # Celik et al. for three grids and an apparent order (Roache 1998)
MAX_ORDER = 64.0       # beyond it a triple's finer pair has simply stopped changing


@dataclass(frozen=True)
class ThreeGrids:
    """One triple, finest first. ``kind``: ``monotone`` (the differences shrink without changing
    sign: the order, limit and indices are given), ``oscillatory`` (they change sign: only the
    order Celik's formula gives with the sign, no limit), ``divergent`` (they grow) or
    ``converged`` (the finer two agree exactly, or their difference is smaller than any order
    up to ``MAX_ORDER`` would leave: the limit is the fine value, no order or index given).
    ``divergent`` also names differences of one sign that shrink too little for any positive
    order."""

    h: tuple[float, float, float]
    f: tuple[float, float, float]
    kind: str
    order: float | None = None
    limit: float | None = None
    gci_fine: float | None = None      # relative to |f1|
    gci_coarse: float | None = None    # the pair (f2, f3), relative to |f2|


def apparent_order(h: tuple[float, float, float], f: tuple[float, float, float]) -> float | None:
    """The ``p`` of ``f0 + C h^p`` through three values (``h`` increasing), any ratios.

    Differences of one sign: the root of ``(h2^p - h1^p) / (h3^p - h2^p) = e21 / e32``, which
    falls from ``ln r21 / ln r32`` at ``p -> 0`` to 0, so there is one positive root exactly
    when ``0 < e21 / e32 < ln r21 / ln r32`` (None otherwise: the finer pair differs too much
    for any positive order; ``inf`` when the root lies beyond ``MAX_ORDER``). Differences that
    change sign: Celik et al.'s eqs. 3-4 with ``s = -1`` by fixed-point iteration, a heuristic
    the procedure itself flags (no limit follows; None when the iteration does not settle)."""
    r21, r32 = h[1] / h[0], h[2] / h[1]
    e21, e32 = f[1] - f[0], f[2] - f[1]
    if e21 * e32 > 0:
        target = e21 / e32
        if not 0.0 < target < math.log(r21) / math.log(r32):
            return None

        def gap(p: float) -> float:
            return (h[1] ** p - h[0] ** p) / (h[2] ** p - h[1] ** p) - target

        if gap(MAX_ORDER) >= 0.0:
            return math.inf
        return brentq(gap, 1e-9, MAX_ORDER, xtol=1e-14)
    p = abs(math.log(abs(e32 / e21))) / math.log(r21)   # the equal-ratio value to start from
    for _ in range(500):
        new = abs(math.log(abs(e32 / e21)) + math.log((r21 ** p + 1.0) / (r32 ** p + 1.0))
                  ) / math.log(r21)
        if abs(new - p) < 1e-12:
            return new
        p = new
    return None


def three_grids(h: tuple[float, float, float], f: tuple[float, float, float],
                safety: float = SAFETY_FACTOR) -> ThreeGrids:
    """The procedure on one triple (``h`` increasing: the finest grid first)."""
    h = tuple(float(x) for x in h)
    f = tuple(float(x) for x in f)
    if not h[0] < h[1] < h[2]:
        raise ValueError(f"grid spacings must increase, finest first; got {h}")
    e21, e32 = f[1] - f[0], f[2] - f[1]
    if e21 == 0.0:
        return ThreeGrids(h, f, "converged", limit=f[0], gci_fine=0.0)
    if e32 == 0.0:
        return ThreeGrids(h, f, "divergent")
    p = apparent_order(h, f)
    if e21 * e32 < 0:
        return ThreeGrids(h, f, "oscillatory", order=p)
    if p is None:
        # the finer pair differs by too much for any positive order
        return ThreeGrids(h, f, "divergent")
    if math.isinf(p):
        return ThreeGrids(h, f, "converged", limit=f[0])
    r21, r32 = h[1] / h[0], h[2] / h[1]
    limit = (r21 ** p * f[0] - f[1]) / (r21 ** p - 1.0)
    # relative indices, as the procedure states them (none about a zero value)
    gci_fine = safety * abs(e21 / f[0]) / (r21 ** p - 1.0) if f[0] else None
    gci_coarse = safety * abs(e32 / f[1]) / (r32 ** p - 1.0) if f[1] else None
    return ThreeGrids(h, f, "monotone", p, limit, gci_fine, gci_coarse)


def grid_sequence(h: list[float], f: list[float],
                  safety: float = SAFETY_FACTOR) -> list[ThreeGrids]:
    """Every triple of neighbouring grids of a sequence (any order in; each triple finest
    first, the triples from the coarsest to the finest)."""
    if len(h) != len(f):
        raise ValueError(f"{len(h)} spacings against {len(f)} values")
    pairs = sorted(zip(h, f, strict=True), reverse=True)   # coarsest first
    return [three_grids((c[0], b[0], a[0]), (c[1], b[1], a[1]), safety)
            for a, b, c in zip(pairs, pairs[1:], pairs[2:], strict=False)]
